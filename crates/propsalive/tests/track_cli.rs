//! `propsalive marker` and `propsalive track` end to end: printable markers at true size
//! whose rendering the detector reads back (board geometry = `pa_track::Board::grid`), and the
//! tracker CLI on good and bad input (corrupt frame in a folder, broken calibration files,
//! resolution mismatch, no tag, broken video, no overwrite without --force).

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use glam::DVec2;
use pa_camera::{CameraModel, Intrinsics};
use pa_track::{marker_image, Board, Detector, DetectorConfig, GrayImage, TagFamily};

fn propsalive(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_propsalive"))
        .args(args)
        .output()
        .expect("run propsalive")
}

fn s(p: &Path) -> &str {
    p.to_str().expect("utf-8 path")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// A PNG chunk's data, if present.
fn png_chunk(bytes: &[u8], kind: &[u8; 4]) -> Option<Vec<u8>> {
    let mut i = 8;
    while i + 8 <= bytes.len() {
        let len = u32::from_be_bytes(bytes[i..i + 4].try_into().ok()?) as usize;
        if &bytes[i + 4..i + 8] == kind {
            return Some(bytes[i + 8..i + 8 + len].to_vec());
        }
        i += 12 + len;
    }
    None
}

fn load_gray(p: &Path) -> GrayImage {
    let img = image::open(p).expect("decodable png").to_luma8();
    GrayImage::from(&img)
}

#[test]
fn marker_writes_true_size_svg_and_png_at_dpi() {
    let dir = tempfile::tempdir().expect("tempdir");
    let stem = dir.path().join("tag0");
    let args = [
        "marker",
        "--family",
        "tag36h11",
        "--id",
        "7",
        "--size-mm",
        "80",
        "--dpi",
        "300",
        "--out",
        s(&stem),
    ];
    let o = propsalive(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    let svg = std::fs::read_to_string(dir.path().join("tag0.svg")).expect("svg");
    // 80 mm black square, 10 mm white margins (the tag's one-cell quiet zone is part of
    // them), a 12 mm label band at the bottom.
    assert!(svg.contains("width=\"100.0000mm\""), "{svg}");
    assert!(svg.contains("height=\"112.0000mm\""), "{svg}");
    assert!(svg.contains("<text"), "{svg}");
    assert!(svg.contains("tag36h11 id 7"), "{svg}");
    assert!(svg.contains("tag size 80 mm"), "{svg}");

    let png_path = dir.path().join("tag0.png");
    let bytes = std::fs::read(&png_path).expect("png");
    let phys = png_chunk(&bytes, b"pHYs").expect("pHYs chunk");
    let ppm = u32::from_be_bytes(phys[0..4].try_into().unwrap());
    assert_eq!(ppm, (300.0f64 / 0.0254).round() as u32);
    assert_eq!(phys[8], 1, "unit metre");
    let gray = load_gray(&png_path);
    let px_per_mm: f64 = 300.0 / 25.4;
    assert_eq!(gray.width, (100.0 * px_per_mm).round() as u32);
    assert_eq!(gray.height, (112.0 * px_per_mm).round() as u32);

    // The detector reads it back: id 7, black square 80 mm wide at 300 dpi.
    let mut det = Detector::new(DetectorConfig::default()).expect("detector");
    let dets = det.detect(&gray).expect("detect");
    assert_eq!(dets.len(), 1, "{dets:?}");
    assert_eq!(dets[0].id, 7);
    let side = dets[0].corners_px[0].distance(dets[0].corners_px[1]);
    assert!(
        (side - 80.0 * px_per_mm).abs() < 1.0,
        "side {side} px vs {}",
        80.0 * px_per_mm
    );
    // TL of the printed tag at (10 mm, 10 mm) from the page corner.
    let tl = dets[0].corners_px[0];
    let want = DVec2::splat(10.0 * px_per_mm - 0.5);
    assert!(tl.distance(want) < 1.0, "TL {tl} vs {want}");

    // No overwrite without --force; with --force it works.
    let o = propsalive(&args);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("--force"), "{}", stderr(&o));
    let mut forced = args.to_vec();
    forced.push("--force");
    let o = propsalive(&forced);
    assert!(o.status.success(), "{}", stderr(&o));
}

#[test]
fn marker_board_png_gives_the_board_pose() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (dpi, size_mm, gap_mm) = (150.0, 40.0, 12.0);
    let o = propsalive(&[
        "marker",
        "--board",
        "2x3",
        "--size-mm",
        "40",
        "--gap-mm",
        "12",
        "--first-id",
        "5",
        "--dpi",
        "150",
        "--out",
        &format!("{}/", s(dir.path())),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let png = dir.path().join("tag36h11_board2x3_id5_40mm_gap12mm.png");
    let svg = std::fs::read_to_string(png.with_extension("svg")).expect("svg");
    assert!(svg.contains("board 2x3, ids 5..10"), "{svg}");
    let gray = load_gray(&png);

    let mut det = Detector::new(DetectorConfig::default()).expect("detector");
    let dets = det.detect(&gray).expect("detect");
    let mut ids: Vec<u32> = dets.iter().map(|d| d.id).collect();
    ids.sort();
    assert_eq!(ids, [5, 6, 7, 8, 9, 10]);

    // A camera looking straight at the page, at the distance where 1 px = 1 printed px.
    let f = 1000.0;
    let k = Intrinsics {
        fx: f,
        fy: f,
        cx: (gray.width as f64 - 1.0) / 2.0,
        cy: (gray.height as f64 - 1.0) / 2.0,
        width: gray.width,
        height: gray.height,
    };
    let cam = CameraModel::pinhole(k);
    let mm_per_px = 25.4 / dpi;
    let z = f * mm_per_px / 1000.0;
    let board = Board::grid(
        TagFamily::Tag36h11,
        2,
        3,
        size_mm / 1000.0,
        gap_mm / 1000.0,
        5,
    )
    .expect("board");
    let bp = board
        .estimate_pose(&cam, &dets)
        .expect("pose")
        .expect("board seen");
    assert_eq!(bp.used_ids.len(), 6);
    let best = bp.estimate.best;
    println!(
        "board pose: rms {:.3} px, t {:?}, angle {:.4} deg",
        best.rms_px,
        best.pose.translation,
        best.pose
            .rotation
            .angle_between(glam::DQuat::IDENTITY)
            .to_degrees()
    );
    // Every corner where the board geometry says: sub-pixel RMS.
    assert!(best.rms_px < 0.3, "rms {}", best.rms_px);
    assert!(
        best.pose
            .rotation
            .angle_between(glam::DQuat::IDENTITY)
            .to_degrees()
            < 0.2,
        "{:?}",
        best.pose
    );
    assert!(
        ((best.pose.translation.z - z) / z).abs() < 0.003,
        "{:?} vs z {z}",
        best.pose
    );
    // The marker origin projects to the centre of all detected corners.
    let c: DVec2 = dets.iter().flat_map(|d| d.corners_px).sum::<DVec2>() / 24.0;
    let o = cam
        .pixel_from_camera(best.pose.translation)
        .expect("in front");
    assert!(o.distance(c) < 0.3, "origin {o} vs corner centroid {c}");
}

#[test]
fn marker_rejects_bad_flags() {
    let dir = tempfile::tempdir().expect("tempdir");
    let out = dir.path().join("m");
    for (args, msg) in [
        (vec!["--size-mm", "0"], "--size-mm"),
        (
            vec!["--size-mm", "80", "--family", "tag99"],
            "unknown tag family",
        ),
        (vec!["--size-mm", "80", "--id", "587"], "ids 0..587"),
        (
            vec!["--size-mm", "40", "--board", "2x2", "--gap-mm", "1"],
            "too small",
        ),
        (vec!["--size-mm", "80", "--board", "2by2"], "ROWSxCOLS"),
    ] {
        let mut a = vec!["marker", "--out", s(&out)];
        a.extend(args);
        let o = propsalive(&a);
        assert!(!o.status.success(), "{a:?}");
        assert!(stderr(&o).contains(msg), "{a:?}: {}", stderr(&o));
    }
}

// --- track ---------------------------------------------------------------------------------

/// A 640x480 frame, mildly shaded background, with tag `id` (black square 160 px) centred on
/// pixel (319.5, 239.5) when `tag` is true.
fn frame(tag: bool, id: u32) -> image::GrayImage {
    let mut img = image::GrayImage::from_fn(640, 480, |x, y| {
        image::Luma([(100 + x / 16 + y / 16) as u8])
    });
    if tag {
        let t = marker_image(TagFamily::Tag36h11, id, 200).expect("tag");
        for y in 0..200 {
            for x in 0..200 {
                img.put_pixel(
                    220 + x,
                    140 + y,
                    image::Luma([t.data[(y * 200 + x) as usize]]),
                );
            }
        }
    }
    img
}

fn write_calib(path: &Path, w: u32, h: u32, f: f64) {
    let k = Intrinsics {
        fx: f,
        fy: f,
        cx: (w as f64 - 1.0) / 2.0,
        cy: (h as f64 - 1.0) / 2.0,
        width: w,
        height: h,
    };
    std::fs::write(
        path,
        pa_camera::calib::to_opencv_yaml(&CameraModel::pinhole(k)),
    )
    .expect("write calib");
}

fn json_lines(text: &str) -> Vec<serde_json::Value> {
    text.lines()
        .map(|l| serde_json::from_str(l).expect("json line"))
        .collect()
}

/// `track IMG --calib CALIB --tag-size-m 0.08` with `extra` arguments after them.
fn track_calibrated(img: &Path, calib: &Path, extra: &[&str]) -> Output {
    let mut args = vec!["track", s(img), "--calib", s(calib), "--tag-size-m", "0.08"];
    args.extend_from_slice(extra);
    propsalive(&args)
}

/// `track` on the one-tag shot `img` (`frame(true, 3)`, tag 3 of 0.08 m) seen by `calib`,
/// with `flag value` added and the log written to `log`: the log's lines (the run must
/// succeed).
fn track_one_tag_with(
    img: &Path,
    calib: &Path,
    flag: &str,
    value: &str,
    log: &Path,
) -> Vec<serde_json::Value> {
    let o = track_calibrated(img, calib, &["--id", "3", flag, value, "--out-log", s(log)]);
    assert!(o.status.success(), "{flag} {value}: {}", stderr(&o));
    json_lines(&std::fs::read_to_string(log).expect("log"))
}

#[test]
fn track_single_image_gives_pose_log_and_drawing() {
    let dir = tempfile::tempdir().expect("tempdir");
    let img = dir.path().join("shot.png");
    frame(true, 3).save(&img).expect("save");
    let calib = dir.path().join("cam.yaml");
    write_calib(&calib, 640, 480, 500.0);
    let log = dir.path().join("out/track.jsonl");
    let draw = dir.path().join("drawn");
    let args = [
        "track",
        s(&img),
        "--calib",
        s(&calib),
        "--tag-size-m",
        "0.08",
        "--id",
        "3",
        "--out-log",
        s(&log),
        "--draw",
        s(&draw),
    ];
    let o = propsalive(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    let lines = json_lines(&std::fs::read_to_string(&log).expect("log"));
    assert_eq!(lines.len(), 1);
    let l = &lines[0];
    println!("{l}");
    assert_eq!(l["frame"], 0);
    assert_eq!(l["file"], "shot.png");
    assert_eq!(l["state"], "tracked");
    assert_eq!(l["events"], serde_json::json!(["found", "tracked"]));
    assert_eq!(l["detections"][0]["id"], 3);
    let c0 = &l["detections"][0]["corners_px"][0];
    assert!((c0[0].as_f64().unwrap() - 239.5).abs() < 0.5, "{c0}");
    assert!((c0[1].as_f64().unwrap() - 159.5).abs() < 0.5, "{c0}");
    // Fronto-parallel, centred: t = (0, 0, f * s / px) = (0, 0, 0.25).
    let t = &l["pose"]["camera_from_marker"]["translation_m"];
    let tz = t[2].as_f64().unwrap();
    assert!((tz - 0.25).abs() < 0.002, "{t}");
    assert!(t[0].as_f64().unwrap().abs() < 0.001, "{t}");
    let q = &l["pose"]["camera_from_marker"]["rotation_xyzw"];
    assert!(q[3].as_f64().unwrap().abs() > 0.9999, "{q}");
    assert!(l["pose"]["reprojection_rms_px"].as_f64().unwrap() < 0.5);
    // The drawing exists, same size, with coloured marks.
    let drawn = image::open(draw.join("shot.png"))
        .expect("drawing")
        .to_rgb8();
    assert_eq!(drawn.dimensions(), (640, 480));
    assert!(drawn.pixels().any(|p| p.0 == [255, 0, 0]), "x axis drawn");
    assert!(drawn.pixels().any(|p| p.0 == [0, 230, 0]), "corners drawn");

    // No overwrite without --force.
    let o = propsalive(&args);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("--force"), "{}", stderr(&o));
    let mut forced = args.to_vec();
    forced.push("--force");
    assert!(propsalive(&forced).status.success());
}

#[test]
fn track_corners_flag_selects_how_corners_are_refined() {
    let dir = tempfile::tempdir().expect("tempdir");
    let img = dir.path().join("shot.png");
    frame(true, 3).save(&img).expect("save");
    let calib = dir.path().join("cam.yaml");
    write_calib(&calib, 640, 480, 500.0);
    for how in ["srgb", "linear", "off"] {
        let log = dir.path().join(format!("{how}.jsonl"));
        let lines = track_one_tag_with(&img, &calib, "--corners", how, &log);
        let c0 = &lines[0]["detections"][0]["corners_px"][0];
        // A sharp tag on pixel boundaries: every reading puts the corner there.
        assert!((c0[0].as_f64().unwrap() - 239.5).abs() < 0.1, "{how}: {c0}");
        assert!((c0[1].as_f64().unwrap() - 159.5).abs() < 0.1, "{how}: {c0}");
    }
    let o = track_calibrated(&img, &calib, &["--corners", "gamma"]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("srgb, linear, off"), "{}", stderr(&o));
}

#[test]
fn track_frame_without_tag_is_searching_not_an_error() {
    let dir = tempfile::tempdir().expect("tempdir");
    let img = dir.path().join("empty.png");
    frame(false, 0).save(&img).expect("save");
    let o = propsalive(&["track", s(&img), "--fov-deg", "50", "--tag-size-m", "0.08"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let lines = json_lines(&String::from_utf8_lossy(&o.stdout));
    assert_eq!(lines.len(), 1);
    assert_eq!(lines[0]["state"], "searching");
    assert_eq!(lines[0]["detections"], serde_json::json!([]));
    assert!(lines[0]["pose"].is_null());
}

#[test]
fn track_folder_natural_order_skips_a_corrupt_frame() {
    let dir = tempfile::tempdir().expect("tempdir");
    let frames = dir.path().join("frames");
    std::fs::create_dir(&frames).expect("mkdir");
    for i in [1u32, 3, 10, 11, 12] {
        frame(true, 0)
            .save(frames.join(format!("f{i}.png")))
            .expect("save");
    }
    std::fs::write(frames.join("f2.png"), b"this is not a png").expect("write");
    std::fs::write(frames.join("notes.txt"), b"ignored").expect("write");
    let calib = dir.path().join("cam.yaml");
    write_calib(&calib, 640, 480, 500.0);
    let o = track_calibrated(&frames, &calib, &[]);
    let err = stderr(&o);
    assert!(o.status.success(), "{err}");
    assert!(
        err.contains("warning: skipping") && err.contains("f2.png"),
        "{err}"
    );
    let lines = json_lines(&String::from_utf8_lossy(&o.stdout));
    let files: Vec<&str> = lines.iter().map(|l| l["file"].as_str().unwrap()).collect();
    assert_eq!(
        files,
        ["f1.png", "f2.png", "f3.png", "f10.png", "f11.png", "f12.png"]
    );
    assert!(lines[1]["error"].as_str().unwrap().contains("f2.png"));
    let states: Vec<&str> = lines.iter().map(|l| l["state"].as_str().unwrap()).collect();
    // f1 found, f2 unreadable (counts as unseen: Detected -> Searching), then 3 sightings.
    assert_eq!(
        states,
        [
            "detected",
            "searching",
            "detected",
            "detected",
            "tracked",
            "tracked"
        ]
    );
    assert!(lines[4]["pose"]["camera_from_marker"].is_object());
}

#[test]
fn track_reports_broken_calibration_files_by_file_and_field() {
    let dir = tempfile::tempdir().expect("tempdir");
    let img = dir.path().join("shot.png");
    frame(true, 0).save(&img).expect("save");
    let good = pa_camera::calib::to_opencv_yaml(&CameraModel::pinhole(Intrinsics {
        fx: 500.0,
        fy: 500.0,
        cx: 319.5,
        cy: 239.5,
        width: 640,
        height: 480,
    }));
    // Missing camera_matrix.
    let cut: String = {
        let start = good.find("camera_matrix").unwrap();
        let end = good.find("distortion_coefficients").unwrap();
        format!("{}{}", &good[..start], &good[end..])
    };
    // A 3x3 matrix with 8 values.
    let short = good.replacen("0.0,\n       1.0 ]", "0.0 ]", 1);
    assert_ne!(short, good, "{good}");
    // TOML without fx.
    let toml_missing =
        "[intrinsics]\nfy = 500.0\ncx = 319.5\ncy = 239.5\nwidth = 640\nheight = 480\n";
    for (name, text, field) in [
        ("missing.yaml", cut.as_str(), "camera_matrix"),
        ("short.yaml", short.as_str(), "camera_matrix"),
        ("missing.toml", toml_missing, "fx"),
    ] {
        let p = dir.path().join(name);
        std::fs::write(&p, text).expect("write");
        let o = track_calibrated(&img, &p, &[]);
        let err = stderr(&o);
        println!("{name}: {err}");
        assert!(!o.status.success(), "{name}");
        assert!(err.contains(name), "{name}: {err}");
        assert!(err.contains(field), "{name}: {err}");
    }
    let p = dir.path().join("short.yaml");
    let err = stderr(&track_calibrated(&img, &p, &[]));
    assert!(err.contains("wrong size"), "{err}");
}

#[test]
fn track_scales_intrinsics_for_same_aspect_and_refuses_other_aspect() {
    let dir = tempfile::tempdir().expect("tempdir");
    let img = dir.path().join("shot.png");
    frame(true, 0).save(&img).expect("save");
    // Calibrated at 1280x960 with f = 1000: the same camera as f = 500 at 640x480.
    let calib = dir.path().join("cam_1280.yaml");
    write_calib(&calib, 1280, 960, 1000.0);
    let o = track_calibrated(&img, &calib, &[]);
    let err = stderr(&o);
    assert!(o.status.success(), "{err}");
    assert!(err.contains("scaling the intrinsics"), "{err}");
    assert!(err.contains("1280x960"), "{err}");
    let l = &json_lines(&String::from_utf8_lossy(&o.stdout))[0];
    let tz = l["pose"]["camera_from_marker"]["translation_m"][2]
        .as_f64()
        .unwrap();
    assert!((tz - 0.25).abs() < 0.002, "{l}");

    let calib = dir.path().join("cam_wide.yaml");
    write_calib(&calib, 1280, 720, 1000.0);
    let o = track_calibrated(&img, &calib, &[]);
    let err = stderr(&o);
    assert!(!o.status.success());
    assert!(
        err.contains("aspect") && err.contains("cam_wide.yaml"),
        "{err}"
    );
}

#[test]
fn track_refuses_broken_video_and_unreadable_single_image() {
    let dir = tempfile::tempdir().expect("tempdir");
    // A video is read (run_video.rs tracks a real one); a truncated one is an error naming it.
    let video = dir.path().join("take1.mp4");
    std::fs::write(&video, b"\0\0\0\x18ftypmp42").expect("write");
    let o = propsalive(&[
        "track",
        s(&video),
        "--fov-deg",
        "50",
        "--tag-size-m",
        "0.08",
    ]);
    assert!(!o.status.success());
    assert!(
        stderr(&o).contains("take1.mp4") && stderr(&o).contains("corrupt or truncated"),
        "{}",
        stderr(&o)
    );

    let bad: PathBuf = dir.path().join("bad.jpg");
    std::fs::write(&bad, b"not a jpeg").expect("write");
    let o = propsalive(&["track", s(&bad), "--fov-deg", "50", "--tag-size-m", "0.08"]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("bad.jpg"), "{}", stderr(&o));

    let o = propsalive(&["track", s(&bad), "--tag-size-m", "0.08"]);
    assert!(!o.status.success());
}

#[test]
fn track_fast_tracking_finds_the_same_pose_and_refuses_thorough() {
    let dir = tempfile::tempdir().expect("tempdir");
    let img = dir.path().join("shot.png");
    frame(true, 3).save(&img).expect("save");
    let calib = dir.path().join("cam.yaml");
    write_calib(&calib, 640, 480, 500.0);
    let pose_of = |mode: &str| {
        let log = dir.path().join(format!("{mode}.jsonl"));
        let lines = track_one_tag_with(&img, &calib, "--tracking", mode, &log);
        assert_eq!(lines.len(), 1, "{mode}");
        assert_eq!(lines[0]["state"], "tracked", "{mode}: {}", lines[0]);
        let t = &lines[0]["pose"]["camera_from_marker"]["translation_m"];
        let t: Vec<f64> = (0..3).map(|i| t[i].as_f64().expect("t")).collect();
        let c = &lines[0]["detections"][0]["corners_px"][0];
        (t, [c[0].as_f64().expect("x"), c[1].as_f64().expect("y")])
    };
    let (t_full, c_full) = pose_of("full");
    let (t_fast, c_fast) = pose_of("fast");
    // The fast detector's corners are refined at full resolution: on this sharp, 200 px tag
    // they agree with the full passes' within a quarter pixel, and the poses within 1 mm.
    for k in 0..2 {
        assert!(
            (c_full[k] - c_fast[k]).abs() < 0.25,
            "{c_full:?} {c_fast:?}"
        );
    }
    for k in 0..3 {
        assert!(
            (t_full[k] - t_fast[k]).abs() < 0.001,
            "{t_full:?} {t_fast:?}"
        );
    }
    assert!((t_fast[2] - 0.25).abs() < 0.002, "{t_fast:?}");

    let o = track_calibrated(&img, &calib, &["--tracking", "fast", "--thorough"]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("--thorough"), "{}", stderr(&o));
}
