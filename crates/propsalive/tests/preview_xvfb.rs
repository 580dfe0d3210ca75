//! `propsalive preview` in a real window on a virtual X server (Xvfb): the built-in scene runs
//! through the pipeline for a few frames, the last one stays on screen, and a real X
//! screenshot (`xwd -root`) is checked against what the program says it presented
//! (`--dump-presented`): the scene region matches it, is not blank, and the status bar
//! below it is dark with bright text.
//!
//! Needs `Xvfb` (Debian: xvfb) and `xwd` (x11-apps); without them the test says why it
//! skipped and passes (CI installs both, see .ci/run).

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

/// Frames the preview presents before holding the last one.
const FRAMES: u64 = 6;
/// How long the last frame stays on screen (the screenshot is taken well within it; the
/// test checks that the preview was still running after the screenshot).
const HOLD_MS: u64 = 8000;
/// Scene region: mean absolute difference (0..255, over RGB) allowed between the screenshot
/// and the presented canvas, and the share of pixels allowed to differ by more than 4 levels.
/// The canvas is drawn 1:1 into a non-sRGB surface, so the bytes should pass through exactly;
/// the slack covers a driver that rounds through another format.
const MAX_MEAN_ABS_DIFF: f64 = 2.0;
const MAX_SHARE_OFF: f64 = 0.01;

fn bin() -> &'static str {
    env!("CARGO_BIN_EXE_propsalive")
}

/// The path of an executable on PATH.
fn which(name: &str) -> Option<PathBuf> {
    let path = std::env::var_os("PATH")?;
    std::env::split_paths(&path)
        .map(|d| d.join(name))
        .find(|p| p.is_file())
}

/// Kills and reaps a child process when dropped.
struct Reaper(Child);

impl Drop for Reaper {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// Starts Xvfb on a free display (it picks one itself and writes the number to the pipe:
/// `-displayfd`); returns the process and the display number.
fn start_xvfb(xvfb: &Path) -> (Reaper, u32) {
    let mut child = Command::new(xvfb)
        .args([
            "-displayfd",
            "1",
            "-screen",
            "0",
            "1024x768x24",
            "-nolisten",
            "tcp",
        ])
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .expect("starting Xvfb");
    let stdout = child.stdout.take().expect("Xvfb stdout");
    let reaper = Reaper(child);
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        let mut line = String::new();
        let _ = BufReader::new(stdout).read_line(&mut line);
        let _ = tx.send(line);
    });
    let line = rx
        .recv_timeout(Duration::from_secs(20))
        .expect("Xvfb did not report its display within 20 s");
    let display: u32 = line
        .trim()
        .parse()
        .unwrap_or_else(|_| panic!("Xvfb reported {line:?} instead of a display number"));
    (reaper, display)
}

/// An RGB image.
struct Rgb {
    width: u32,
    height: u32,
    data: Vec<[u8; 3]>,
}

impl Rgb {
    fn at(&self, x: u32, y: u32) -> [u8; 3] {
        self.data[(y * self.width + x) as usize]
    }
}

/// Parses an XWD dump (X Window Dump, as `xwd` writes it: a big-endian header of 25 CARD32,
/// the window name, `ncolors` 12-byte colour entries, then the pixels in the image's own byte
/// order). Handles TrueColor/DirectColor images of 16, 24 or 32 bits per pixel.
fn parse_xwd(bytes: &[u8]) -> Rgb {
    let field = |i: usize| {
        u32::from_be_bytes(
            bytes[i * 4..i * 4 + 4]
                .try_into()
                .expect("four bytes of header"),
        )
    };
    assert!(bytes.len() >= 100, "XWD too short: {} bytes", bytes.len());
    let header_size = field(0) as usize;
    assert_eq!(field(1), 7, "XWD file version");
    assert_eq!(field(2), 2, "XWD pixmap format (ZPixmap)");
    let (width, height) = (field(4), field(5));
    let byte_order_msb = field(7) == 1;
    let bits_per_pixel = field(11);
    let bytes_per_line = field(12) as usize;
    let visual_class = field(13);
    let masks = [field(14), field(15), field(16)];
    let ncolors = field(19) as usize;
    assert!(
        visual_class == 4 || visual_class == 5,
        "XWD visual class {visual_class} (want TrueColor 4 or DirectColor 5)"
    );
    assert!(
        matches!(bits_per_pixel, 16 | 24 | 32),
        "XWD bits per pixel {bits_per_pixel}"
    );
    let start = header_size + ncolors * 12;
    let bpp = (bits_per_pixel / 8) as usize;
    assert!(
        bytes.len() >= start + bytes_per_line * height as usize,
        "XWD pixels cut short"
    );
    let mut data = Vec::with_capacity((width * height) as usize);
    for y in 0..height as usize {
        let row = &bytes[start + y * bytes_per_line..];
        for x in 0..width as usize {
            let px = &row[x * bpp..x * bpp + bpp];
            let mut v = 0u32;
            for k in 0..bpp {
                let b = if byte_order_msb {
                    px[k]
                } else {
                    px[bpp - 1 - k]
                };
                v = (v << 8) | b as u32;
            }
            let mut rgb = [0u8; 3];
            for (c, &m) in masks.iter().enumerate() {
                if m == 0 {
                    continue;
                }
                let shift = m.trailing_zeros();
                let max = m >> shift;
                rgb[c] = (((v & m) >> shift) * 255 / max) as u8;
            }
            data.push(rgb);
        }
    }
    Rgb {
        width,
        height,
        data,
    }
}

fn luma(p: [u8; 3]) -> f64 {
    0.299 * p[0] as f64 + 0.587 * p[1] as f64 + 0.114 * p[2] as f64
}

/// (mean absolute difference over RGB, share of pixels off by more than 4 levels) between the
/// canvas rows `rows` and the screenshot at `origin`.
fn compare(
    shot: &Rgb,
    canvas: &image::RgbaImage,
    origin: (i64, i64),
    rows: std::ops::Range<u32>,
    step: u32,
) -> Option<(f64, f64)> {
    let (mut sum, mut off, mut n) = (0f64, 0usize, 0usize);
    for y in rows.step_by(step as usize) {
        for x in (0..canvas.width()).step_by(step as usize) {
            let (sx, sy) = (origin.0 + x as i64, origin.1 + y as i64);
            if sx < 0 || sy < 0 || sx >= shot.width as i64 || sy >= shot.height as i64 {
                return None;
            }
            let a = shot.at(sx as u32, sy as u32);
            let b = canvas.get_pixel(x, y).0;
            let mut worst = 0;
            for c in 0..3 {
                let d = (a[c] as i32 - b[c] as i32).abs();
                sum += d as f64;
                worst = worst.max(d);
            }
            off += usize::from(worst > 4);
            n += 1;
        }
    }
    (n > 0).then(|| (sum / (3 * n) as f64, off as f64 / n as f64))
}

#[test]
fn preview_window_shows_the_scene_and_the_status_line() {
    let Some(xvfb) = which("Xvfb") else {
        println!("skipped: Xvfb not found (Debian: apt-get install xvfb)");
        return;
    };
    let Some(xwd) = which("xwd") else {
        println!("skipped: xwd not found (Debian: apt-get install x11-apps)");
        return;
    };
    if let Err(e) = pa_render::Renderer::new() {
        println!("skipped: no renderer ({e})");
        return;
    }
    let t_start = Instant::now();
    // Folders of earlier runs older than an hour are removed; this run's stays for a look.
    let tmp = Path::new(env!("CARGO_TARGET_TMPDIR"));
    for e in std::fs::read_dir(tmp).into_iter().flatten().flatten() {
        let old = e
            .metadata()
            .and_then(|m| m.modified())
            .ok()
            .and_then(|t| t.elapsed().ok())
            .is_some_and(|age| age > Duration::from_secs(3600));
        if old && e.file_name().to_string_lossy().starts_with("preview_xvfb_") {
            let _ = std::fs::remove_dir_all(e.path());
        }
    }
    let dir = tmp.join(format!("preview_xvfb_{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("mkdir");
    let dump = dir.join("dump");
    let (_xvfb, display) = start_xvfb(&xvfb);
    println!("Xvfb on :{display}");

    let out_log = dir.join("stdout.txt");
    let err_log = dir.join("stderr.txt");
    let child = Command::new(bin())
        .args(["preview", "--size", "640x360"])
        .args(["--exit-after-frames", &FRAMES.to_string()])
        .args(["--hold-ms", &HOLD_MS.to_string()])
        .arg("--dump-presented")
        .arg(&dump)
        .arg("--log")
        .arg(dir.join("log.jsonl"))
        .arg("--capture-dir")
        .arg(dir.join("captures"))
        .arg("--record-dir")
        .arg(dir.join("recordings"))
        .args(["--overlays", "axes"])
        .env("DISPLAY", format!(":{display}"))
        .env_remove("WAYLAND_DISPLAY")
        .env_remove("WAYLAND_SOCKET")
        .stdin(Stdio::null())
        .stdout(std::fs::File::create(&out_log).expect("stdout file"))
        .stderr(std::fs::File::create(&err_log).expect("stderr file"))
        .spawn()
        .expect("starting propsalive preview");
    let mut app = Reaper(child);
    let outputs = || {
        format!(
            "--- stdout\n{}\n--- stderr\n{}",
            std::fs::read_to_string(&out_log).unwrap_or_default(),
            std::fs::read_to_string(&err_log).unwrap_or_default()
        )
    };

    // Wait for the last frame to be presented.
    let info_path = dump.join("presented.json");
    let deadline = Instant::now() + Duration::from_secs(120);
    let info: serde_json::Value = loop {
        if let Ok(text) = std::fs::read_to_string(&info_path) {
            if let Ok(v) = serde_json::from_str::<serde_json::Value>(&text) {
                if v["final"] == true {
                    break v;
                }
            }
        }
        if let Ok(Some(status)) = app.0.try_wait() {
            panic!("the preview exited early ({status}):\n{}", outputs());
        }
        assert!(
            Instant::now() < deadline,
            "no final frame within 120 s:\n{}",
            outputs()
        );
        std::thread::sleep(Duration::from_millis(50));
    };
    // Let the X server finish drawing, then take the screenshot.
    std::thread::sleep(Duration::from_millis(300));
    let shot = Command::new(&xwd)
        .args(["-root", "-silent", "-display", &format!(":{display}")])
        .output()
        .expect("running xwd");
    assert!(
        shot.status.success(),
        "xwd failed: {}",
        String::from_utf8_lossy(&shot.stderr)
    );
    assert!(
        matches!(app.0.try_wait(), Ok(None)),
        "the preview had already quit when the screenshot was taken (machine too slow for a {HOLD_MS} ms hold?):\n{}",
        outputs()
    );
    let screen = parse_xwd(&shot.stdout);
    let screenshot_png = dir.join("screenshot.png");
    image::RgbImage::from_raw(
        screen.width,
        screen.height,
        screen.data.iter().flatten().copied().collect(),
    )
    .expect("screenshot size")
    .save(&screenshot_png)
    .expect("saving the screenshot");
    println!("screenshot: {}", screenshot_png.display());
    println!("presented: {}", dump.join("presented.png").display());

    // The preview quits by itself after the hold.
    let status = loop {
        if let Some(s) = app.0.try_wait().expect("waiting for the preview") {
            break s;
        }
        assert!(
            Instant::now() < deadline + Duration::from_millis(HOLD_MS),
            "the preview did not quit after its hold:\n{}",
            outputs()
        );
        std::thread::sleep(Duration::from_millis(50));
    };
    assert!(
        status.success(),
        "preview failed ({status}):\n{}",
        outputs()
    );

    let canvas = image::open(dump.join("presented.png"))
        .expect("presented.png")
        .to_rgba8();
    let frame_h = info["frame_height"].as_u64().expect("frame_height") as u32;
    let bar_h = info["bar_height"].as_u64().expect("bar_height") as u32;
    assert_eq!((canvas.width(), canvas.height()), (640, 360 + bar_h));
    assert_eq!(frame_h, 360);
    let vp: Vec<i64> = info["viewport"]
        .as_array()
        .expect("viewport (the last frame was shown)")
        .iter()
        .filter_map(|v| v.as_i64())
        .collect();
    assert_eq!(
        (vp[2], vp[3]),
        (640, 360 + bar_h as i64),
        "the window should show the canvas 1:1: {info}"
    );
    let pos: Vec<i64> = info["window_position"]
        .as_array()
        .map(|a| a.iter().filter_map(|v| v.as_i64()).collect())
        .unwrap_or_else(|| vec![0, 0]);
    let expected = (pos[0] + vp[0], pos[1] + vp[1]);

    // Find the canvas on the screen near where the window says it is (within 8 px).
    let mut best: Option<((i64, i64), f64)> = None;
    for dy in -8..=8 {
        for dx in -8..=8 {
            let o = (expected.0 + dx, expected.1 + dy);
            if let Some((mad, _)) = compare(&screen, &canvas, o, 0..frame_h, 7) {
                if best.is_none_or(|(_, b)| mad < b) {
                    best = Some((o, mad));
                }
            }
        }
    }
    let (origin, _) = best.expect("the canvas lies on the screen");
    let (mad, share_off) =
        compare(&screen, &canvas, origin, 0..frame_h, 1).expect("scene region on screen");
    println!(
        "scene region at ({}, {}) (window says ({}, {})): mean abs diff {mad:.3}, {:.3}% of pixels off by > 4",
        origin.0,
        origin.1,
        expected.0,
        expected.1,
        share_off * 100.0
    );
    assert!(
        mad <= MAX_MEAN_ABS_DIFF && share_off <= MAX_SHARE_OFF,
        "the screen does not show the presented frame: mean abs diff {mad:.3} (max {MAX_MEAN_ABS_DIFF}), {:.3}% off (max {}%); see {}",
        share_off * 100.0,
        MAX_SHARE_OFF * 100.0,
        screenshot_png.display()
    );

    // Not blank: the scene has contrast and colour.
    let lumas: Vec<f64> = (0..frame_h)
        .flat_map(|y| (0..640).map(move |x| (x, y)))
        .map(|(x, y)| luma(screen.at((origin.0 + x) as u32, (origin.1 + y as i64) as u32)))
        .collect();
    let mean = lumas.iter().sum::<f64>() / lumas.len() as f64;
    let sd = (lumas.iter().map(|l| (l - mean).powi(2)).sum::<f64>() / lumas.len() as f64).sqrt();
    println!("scene region: mean luma {mean:.1}, standard deviation {sd:.1}");
    assert!(
        mean > 20.0 && mean < 235.0 && sd > 12.0,
        "the scene region looks blank"
    );

    // The status bar: dark, with bright text in the two lines below the timeline.
    let bar_y = origin.1 + frame_h as i64;
    let (mut dark, mut bright_text, mut total) = (0usize, 0usize, 0usize);
    for y in 0..bar_h as i64 {
        for x in 0..640i64 {
            let p = screen.at((origin.0 + x) as u32, (bar_y + y) as u32);
            let l = luma(p);
            total += 1;
            dark += usize::from(l < 40.0);
            // Text lines start under the timeline (top 12 px of the bar).
            if y >= 12 && p.iter().all(|&c| c >= 200) {
                bright_text += 1;
            }
        }
    }
    let dark_share = dark as f64 / total as f64;
    println!(
        "status bar: {bar_h} px tall, {:.1}% dark, {bright_text} bright text pixels",
        dark_share * 100.0
    );
    assert!(dark_share > 0.6, "the status bar is not dark");
    assert!(
        bright_text > 400 && (bright_text as f64) < 0.4 * total as f64,
        "no status text on the bar ({bright_text} bright pixels)"
    );

    // The log: one line per presented frame, with the state, timings and latency.
    let log = std::fs::read_to_string(dir.join("log.jsonl")).expect("log");
    let lines: Vec<serde_json::Value> = log
        .lines()
        .map(|l| serde_json::from_str(l).expect("a JSON line"))
        .collect();
    assert_eq!(lines.len() as u64, FRAMES, "{log}");
    for l in &lines {
        let lat = l["latency_ms"].as_f64().expect("latency_ms");
        assert!(lat > 0.0 && lat < 60_000.0, "{l}");
        assert!(l["timings_ms"]["texture"].is_number(), "{l}");
        assert!(l["anim_frame"].is_u64(), "{l}");
    }
    let last = &lines[lines.len() - 1];
    assert_eq!(
        last["state"], "Tracked",
        "the marker was not tracked: {log}"
    );
    println!(
        "last frame: state {}, latency {:.1} ms; whole test {:.1} s",
        last["state"],
        last["latency_ms"].as_f64().unwrap_or(f64::NAN),
        t_start.elapsed().as_secs_f64()
    );
}
