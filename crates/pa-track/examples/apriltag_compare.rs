//! Tracking per still against the AprilTag C library on the same frames (not part of CI; see
//! `scripts/baselines/README.md` for the whole run).
//!
//! `render DIR [--frames N] [--width W --height H] [--noise | --lens]`: renders N frames of the
//! built-in scene (the prop on the eight-tag board, wood table, handheld camera; pa-render) as
//! 8-bit PGM (`DIR/frame_NNN.pgm`, Rec. 601 luma as pa-track's benches), with the truth:
//! `truth.txt` (`frame id` and the four true corners in pa-track's convention, projected
//! from the board and the true pose), `poses.txt` (`frame` and the true `camera_from_marker`,
//! 16 column-major values), `camera.txt` (`fx fy cx cy width height`) and `board.json`.
//! `--noise` degrades each frame with pa-scene's handheld sensor noise (blur and 15 levels);
//! `--lens` does the same with the blur in linear light, as a lens blurs.
//!
//! `run DIR [--threads T] [--reps R] [--only TEXT] [--c NAME=FILE]...`: times our detector (default settings,
//! and the other settings listed below) on those frames on a rayon pool of T threads (default
//! 2), R runs per frame (default 5), and prints one table row per detector: time per frame
//! (median, p95 over all runs), tags found (of the true tags whose four corners are inside
//! the frame), the corner error against the truth (median and p95 px over the found tags'
//! corners) and the board pose's rotation error (median degrees; pa-track's board solver on
//! each detector's corners). Each `--c NAME=FILE` adds a row for the C library's output
//! (`scripts/baselines/apriltag_c`: `T frame ms` and `D frame id hamming margin x0 y0 .. x3
//! y3` lines, C corner order and pixel convention, converted here as `ours = [p3, p2, p1,
//! p0] - 0.5`).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use glam::{DVec2, Mat4};
use pa_camera::{CameraModel, Intrinsics};
use pa_render::Renderer;
use pa_scene::tracking::{pose_error_f64, SensorNoise};
use pa_scene::{Scene, SceneSpec};
use pa_track::{Board, Detection, Detector, DetectorConfig, GrayImage, TagFamily};

type Res<T> = Result<T, Box<dyn std::error::Error>>;

fn arg_value(args: &[String], name: &str) -> Option<String> {
    args.iter()
        .position(|a| a == name)
        .and_then(|i| args.get(i + 1).cloned())
}

fn main() -> Res<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (Some(cmd), Some(dir)) = (args.first(), args.get(1)) else {
        eprintln!("usage: apriltag_compare render DIR [--frames N] [--noise | --lens] | run DIR [--threads T] [--reps R] [--c NAME=FILE]...");
        std::process::exit(2);
    };
    let dir = PathBuf::from(dir);
    match cmd.as_str() {
        "render" => render(&dir, &args),
        "run" => run(&dir, &args),
        "photos" => photos(&dir, &args),
        other => Err(format!("unknown command {other:?}").into()),
    }
}

fn write_pgm(path: &Path, image: &GrayImage) -> Res<()> {
    let mut bytes = format!("P5\n{} {}\n255\n", image.width, image.height).into_bytes();
    bytes.extend_from_slice(&image.data);
    std::fs::write(path, bytes)?;
    Ok(())
}

fn read_pgm(path: &Path) -> Res<GrayImage> {
    let bytes = std::fs::read(path)?;
    // Header: "P5", width, height, maxval, each separated by one whitespace (no comments:
    // we write these files ourselves).
    let mut fields = Vec::new();
    let mut start = 0;
    let mut i = 0;
    while fields.len() < 4 && i < bytes.len() {
        if bytes[i].is_ascii_whitespace() {
            if i > start {
                fields.push(std::str::from_utf8(&bytes[start..i])?.to_string());
            }
            start = i + 1;
        }
        i += 1;
    }
    if fields.len() < 4 || fields[0] != "P5" || fields[3] != "255" {
        return Err(format!("{}: not an 8-bit binary PGM", path.display()).into());
    }
    let (w, h): (u32, u32) = (fields[1].parse()?, fields[2].parse()?);
    let data = bytes[start..].to_vec();
    Ok(GrayImage::new(w, h, data)?)
}

/// `photos SRC DIR`: the conformance photos (`SRC/*.jpg` with the C library's reference
/// detections `SRC/*.txt`) as PGM (the JPEG's luma, as `tests/conformance.rs`) and
/// `truth.txt` (the reference corners in pa-track's convention).
fn photos(src: &Path, args: &[String]) -> Res<()> {
    let dir = PathBuf::from(args.get(2).ok_or("photos SRC DIR")?);
    std::fs::create_dir_all(&dir)?;
    let mut jpgs: Vec<PathBuf> = std::fs::read_dir(src)?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "jpg"))
        .collect();
    jpgs.sort();
    if jpgs.is_empty() {
        return Err(format!("{}: no .jpg photos", src.display()).into());
    }
    let mut truth = String::new();
    for (f, jpg) in jpgs.iter().enumerate() {
        let image = GrayImage::from(&image::open(jpg)?);
        write_pgm(&dir.join(format!("frame_{f:03}.pgm")), &image)?;
        let txt = std::fs::read_to_string(jpg.with_extension("txt"))?;
        for line in txt.lines().filter(|l| !l.trim().is_empty()) {
            let v: Vec<f64> = line
                .split(|c: char| c == ',' || c == '(' || c == ')' || c.is_whitespace())
                .filter(|t| !t.is_empty())
                .map(|t| t.parse())
                .collect::<Result<_, _>>()?;
            if v.len() != 9 {
                return Err(format!("{}: bad line {line:?}", jpg.display()).into());
            }
            let p = [0, 1, 2, 3].map(|k| DVec2::new(v[1 + 2 * k], v[2 + 2 * k]));
            let _ = write!(truth, "{f} {}", v[0] as u32);
            for c in [p[3], p[2], p[1], p[0]] {
                let _ = write!(truth, " {:.6} {:.6}", c.x - 0.5, c.y - 0.5);
            }
            truth.push('\n');
        }
    }
    std::fs::write(dir.join("truth.txt"), truth)?;
    Ok(())
}

fn render(dir: &Path, args: &[String]) -> Res<()> {
    let frames: u32 = arg_value(args, "--frames").map_or(Ok(30), |v| v.parse())?;
    let width: u32 = arg_value(args, "--width").map_or(Ok(1280), |v| v.parse())?;
    let height: u32 = arg_value(args, "--height").map_or(Ok(720), |v| v.parse())?;
    let noise = if args.iter().any(|a| a == "--lens") {
        Some(SensorNoise::HANDHELD_LENS)
    } else if args.iter().any(|a| a == "--noise") {
        Some(SensorNoise::HANDHELD)
    } else {
        None
    };
    std::fs::create_dir_all(dir)?;
    let mut renderer = Renderer::new()?;
    let spec = SceneSpec {
        width,
        height,
        ..SceneSpec::default()
    };
    let scene = Scene::new(spec, &mut renderer)?;
    let k = scene.intrinsics;
    let camera = CameraModel::pinhole(k);
    std::fs::write(
        dir.join("camera.txt"),
        format!(
            "{} {} {} {} {} {}\n",
            k.fx, k.fy, k.cx, k.cy, k.width, k.height
        ),
    )?;
    std::fs::write(
        dir.join("board.json"),
        serde_json::to_string_pretty(&scene.board)?,
    )?;
    let mut truth = String::new();
    let mut poses = String::new();
    // Spread over the scene's camera path.
    let n = scene.spec.frames.max(1);
    for f in 0..frames {
        let i = (f * n) / frames.max(1);
        let frame = scene.frame(&mut renderer, i)?;
        let mut rgba = frame.input.rgba8.clone();
        if let Some(noise) = noise {
            noise.apply(&mut rgba, width, height, 1000 + u64::from(i));
        }
        let data = rgba
            .chunks_exact(4)
            .map(|p| ((77 * p[0] as u32 + 150 * p[1] as u32 + 29 * p[2] as u32 + 128) >> 8) as u8)
            .collect();
        let image = GrayImage::new(width, height, data)?;
        write_pgm(&dir.join(format!("frame_{f:03}.pgm")), &image)?;
        let m = frame.camera_from_marker;
        let md = m.as_dmat4();
        let _ = write!(poses, "{f}");
        for v in m.to_cols_array() {
            let _ = write!(poses, " {v:.9e}");
        }
        poses.push('\n');
        for t in &scene.board.tags {
            let px: Vec<DVec2> = t
                .object_points()
                .iter()
                .filter_map(|p| camera.pixel_from_camera(md.transform_point3(*p)))
                .collect();
            if px.len() != 4 {
                continue;
            }
            let _ = write!(truth, "{f} {}", t.id);
            for p in px {
                let _ = write!(truth, " {:.6} {:.6}", p.x, p.y);
            }
            truth.push('\n');
        }
        eprintln!("frame {f} (scene frame {i}) written");
    }
    std::fs::write(dir.join("truth.txt"), truth)?;
    std::fs::write(dir.join("poses.txt"), poses)?;
    Ok(())
}

struct Truth {
    frames: Vec<PathBuf>,
    /// Camera and board of the rendered frames (none for the photos).
    camera: Option<CameraModel>,
    board: Option<Board>,
    /// Per frame: (id, corners) of every true tag (ids may repeat on the photos).
    corners: Vec<Vec<(u32, [DVec2; 4])>>,
    /// True poses (none for the photos).
    poses: Option<Vec<Mat4>>,
}

fn load_truth(dir: &Path) -> Res<Truth> {
    let mut frames: Vec<PathBuf> = std::fs::read_dir(dir)?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "pgm"))
        .collect();
    frames.sort();
    let mut corners = vec![Vec::new(); frames.len()];
    for line in std::fs::read_to_string(dir.join("truth.txt"))?.lines() {
        let v: Vec<f64> = line
            .split_whitespace()
            .map(|v| v.parse())
            .collect::<Result<_, _>>()?;
        if v.len() != 10 {
            return Err(format!("truth.txt: bad line {line:?}").into());
        }
        let c = [0, 1, 2, 3].map(|k| DVec2::new(v[2 + 2 * k], v[3 + 2 * k]));
        if let Some(list) = corners.get_mut(v[0] as usize) {
            list.push((v[1] as u32, c));
        }
    }
    let (camera, board, poses) = if dir.join("poses.txt").exists() {
        let cam: Vec<f64> = std::fs::read_to_string(dir.join("camera.txt"))?
            .split_whitespace()
            .map(|v| v.parse())
            .collect::<Result<_, _>>()?;
        if cam.len() != 6 {
            return Err("camera.txt: expected fx fy cx cy width height".into());
        }
        let camera = CameraModel::pinhole(Intrinsics {
            fx: cam[0],
            fy: cam[1],
            cx: cam[2],
            cy: cam[3],
            width: cam[4] as u32,
            height: cam[5] as u32,
        });
        let board: Board = serde_json::from_str(&std::fs::read_to_string(dir.join("board.json"))?)?;
        let mut poses = Vec::new();
        for line in std::fs::read_to_string(dir.join("poses.txt"))?.lines() {
            let v: Vec<f32> = line
                .split_whitespace()
                .skip(1)
                .map(|v| v.parse())
                .collect::<Result<_, _>>()?;
            if v.len() != 16 {
                return Err(format!("poses.txt: bad line {line:?}").into());
            }
            let mut a = [0f32; 16];
            a.copy_from_slice(&v);
            poses.push(Mat4::from_cols_array(&a));
        }
        if poses.len() != frames.len() {
            return Err("poses.txt and the frames disagree".into());
        }
        (Some(camera), Some(board), Some(poses))
    } else {
        (None, None, None)
    };
    Ok(Truth {
        frames,
        camera,
        board,
        corners,
        poses,
    })
}

/// One detector's output on every frame, and its run times (ms).
struct Outcome {
    name: String,
    detections: Vec<Vec<Detection>>,
    times_ms: Vec<f64>,
}

fn percentile(v: &[f64], q: f64) -> f64 {
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    if s.is_empty() {
        return f64::NAN;
    }
    let i = ((s.len() - 1) as f64 * q).round() as usize;
    s[i]
}

fn row(truth: &Truth, o: &Outcome, images: &[GrayImage]) -> String {
    let mut corner_err = Vec::new();
    let mut rot_err = Vec::new();
    let mut trans_err = Vec::new();
    let (mut found, mut total, mut other) = (0usize, 0usize, 0usize);
    for (f, dets) in o.detections.iter().enumerate() {
        let (w, h) = (images[f].width as f64, images[f].height as f64);
        let inside = |c: &[DVec2; 4]| {
            c.iter()
                .all(|p| p.x >= 1.0 && p.y >= 1.0 && p.x <= w - 2.0 && p.y <= h - 2.0)
        };
        let tags = &truth.corners[f];
        total += tags.iter().filter(|(_, c)| inside(c)).count();
        let mut used = vec![false; tags.len()];
        for d in dets {
            // The true tag of this id nearest to the detection's centre.
            let centre = d.center_px();
            let best = tags
                .iter()
                .enumerate()
                .filter(|(i, (id, _))| *id == d.id && !used[*i])
                .map(|(i, (_, c))| {
                    let tc = (c[0] + c[1] + c[2] + c[3]) * 0.25;
                    (i, tc.distance(centre))
                })
                .min_by(|a, b| a.1.total_cmp(&b.1));
            let Some((i, dist)) = best else {
                other += 1;
                continue;
            };
            let e: Vec<f64> = (0..4)
                .map(|k| d.corners_px[k].distance(tags[i].1[k]))
                .collect();
            if dist > 20.0 || e.iter().any(|&e| e > 20.0) {
                other += 1;
                continue;
            }
            used[i] = true;
            if inside(&tags[i].1) {
                found += 1;
            }
            corner_err.extend(e);
        }
        if let (Some(board), Some(camera), Some(poses)) =
            (&truth.board, &truth.camera, &truth.poses)
        {
            if let Ok(Some(bp)) = board.estimate_pose(camera, dets) {
                let (r, t) = pose_error_f64(&bp.estimate.best.pose, poses[f]);
                rot_err.push(r);
                trans_err.push(t);
            }
        }
    }
    format!(
        "| {} | {:.2} | {:.2} | {}/{} (+{} other) | {:.4} | {:.3} | {:.4} | {:.3} | {}/{} |",
        o.name,
        percentile(&o.times_ms, 0.5),
        percentile(&o.times_ms, 0.95),
        found,
        total,
        other,
        percentile(&corner_err, 0.5),
        percentile(&corner_err, 0.95),
        percentile(&rot_err, 0.5),
        percentile(&trans_err, 0.5),
        rot_err.len(),
        o.detections.len(),
    )
}

fn read_c_output(path: &Path, n_frames: usize) -> Res<(Vec<Vec<Detection>>, Vec<f64>)> {
    let mut dets = vec![Vec::new(); n_frames];
    let mut times = Vec::new();
    for line in std::fs::read_to_string(path)?.lines() {
        let mut it = line.split_whitespace();
        match it.next() {
            Some("T") => {
                let v: Vec<f64> = it.map(|v| v.parse()).collect::<Result<_, _>>()?;
                times.push(*v.get(1).ok_or("T line: frame ms")?);
            }
            Some("D") => {
                let v: Vec<f64> = it.map(|v| v.parse()).collect::<Result<_, _>>()?;
                if v.len() != 12 {
                    return Err(format!("{}: bad D line {line:?}", path.display()).into());
                }
                let f = v[0] as usize;
                let p = [0, 1, 2, 3].map(|k| DVec2::new(v[4 + 2 * k], v[5 + 2 * k]));
                let corners = [p[3], p[2], p[1], p[0]].map(|c| c - DVec2::splat(0.5));
                if let Some(list) = dets.get_mut(f) {
                    list.push(Detection {
                        family: TagFamily::Tag36h11,
                        id: v[1] as u32,
                        corners_px: corners,
                        hamming: v[2] as u8,
                        decision_margin: v[3] as f32,
                    });
                }
            }
            _ => {}
        }
    }
    Ok((dets, times))
}

/// Runs `detect` `reps` times on every image on `pool`, after one untimed call on the first
/// (buffers sized, pages touched): the last run's detections per image, and every run's time
/// (ms).
fn time_detections(
    pool: &rayon::ThreadPool,
    images: &[GrayImage],
    reps: usize,
    mut detect: impl FnMut(&GrayImage) -> Result<Vec<Detection>, pa_track::TrackError> + Send,
) -> Result<(Vec<Vec<Detection>>, Vec<f64>), pa_track::TrackError> {
    pool.install(|| {
        detect(&images[0])?;
        let mut detections = Vec::new();
        let mut times_ms = Vec::new();
        for image in images {
            let mut last = Vec::new();
            for _ in 0..reps {
                let t = Instant::now();
                last = detect(image)?;
                times_ms.push(t.elapsed().as_secs_f64() * 1e3);
            }
            detections.push(last);
        }
        Ok((detections, times_ms))
    })
}

fn run(dir: &Path, args: &[String]) -> Res<()> {
    let threads: usize = arg_value(args, "--threads").map_or(Ok(2), |v| v.parse())?;
    let reps: usize = arg_value(args, "--reps").map_or(Ok(5), |v| v.parse())?;
    let truth = load_truth(dir)?;
    let images: Vec<GrayImage> = truth
        .frames
        .iter()
        .map(|p| read_pgm(p))
        .collect::<Res<_>>()?;
    if images.is_empty() {
        return Err(format!("{}: no frames listed in truth.txt", dir.display()).into());
    }
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()?;
    let configs: Vec<(&str, DetectorConfig)> = vec![
        ("ours default", DetectorConfig::default()),
        ("ours fast (decimate 2, refined)", DetectorConfig::fast()),
        (
            "ours fast, min_white_black_diff 5 (the C library's)",
            DetectorConfig {
                min_white_black_diff: 5,
                ..DetectorConfig::fast()
            },
        ),
        (
            "ours c_reference (decimate 1)",
            DetectorConfig::c_reference(),
        ),
    ];
    // `--only TEXT`: just the detectors whose name contains TEXT (e.g. under `perf`).
    let only = arg_value(args, "--only");
    let mut outcomes = Vec::new();
    for (name, cfg) in configs {
        if only.as_ref().is_some_and(|o| !name.contains(o.as_str())) {
            continue;
        }
        let mut detector = Detector::new(cfg)?;
        let (detections, times_ms) =
            time_detections(&pool, &images, reps, |image| detector.detect(image))?;
        outcomes.push(Outcome {
            name: format!("{name}, {threads} threads"),
            detections,
            times_ms,
        });
    }
    // The tracker per still (reset before each, as `run` tracks stills), with and without
    // the decimated search first: its detections are what the pose is fitted to.
    if let (Some(camera), Some(board)) = (&truth.camera, &truth.board) {
        for (name, fast_first) in [
            ("ours tracker per still, decimated search first", true),
            ("ours tracker per still, full passes", false),
        ] {
            if only.as_ref().is_some_and(|o| !name.contains(o.as_str())) {
                continue;
            }
            let mut tracker = pa_track::Tracker::new(
                *camera,
                pa_track::TrackTarget::Board(board.clone()),
                DetectorConfig::default(),
                pa_track::TrackerConfig {
                    fast_first,
                    ..pa_track::TrackerConfig::per_still()
                },
            )?;
            let (detections, times_ms) = time_detections(&pool, &images, reps, |image| {
                tracker.reset();
                Ok(tracker.update(image, 0.0)?.detections)
            })?;
            outcomes.push(Outcome {
                name: format!("{name}, {threads} threads"),
                detections,
                times_ms,
            });
        }
    }
    for spec in args
        .iter()
        .enumerate()
        .filter(|(_, a)| *a == "--c")
        .filter_map(|(i, _)| args.get(i + 1))
    {
        let (name, file) = spec.split_once('=').ok_or("--c NAME=FILE")?;
        let (detections, times_ms) = read_c_output(Path::new(file), images.len())?;
        outcomes.push(Outcome {
            name: name.to_string(),
            detections,
            times_ms,
        });
    }
    println!(
        "{} frames {}x{}, {} runs each; corner error against the truth (rendered frames: the true corners; photos: the C library's reference detections); rotation error of the board pose (pa-track's solver; rendered frames only)",
        images.len(),
        images[0].width,
        images[0].height,
        reps
    );
    println!("| detector | ms median | ms p95 | tags found (of whole true tags) | corner err median px | corner err p95 px | rotation err median deg | translation err median mm | frames with a pose |");
    println!("|---|---|---|---|---|---|---|---|---|");
    for o in &outcomes {
        println!("{}", row(&truth, o, &images));
    }
    Ok(())
}
