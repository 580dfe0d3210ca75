//! `propsalive calibrate` end to end on small synthetic views (`pa_calib::synth`, a known
//! 640x480 camera with barrel distortion): chessboard and AprilTag board, skipped images
//! (no board, not an image), the written YAML loading back, no overwrite without --force,
//! mixed sizes, too few views and bad flags.

use std::path::Path;
use std::process::{Command, Output};

use pa_calib::synth::{varied_poses, PlanarPattern, RayMap, RenderSettings};
use pa_camera::{CameraModel, Distortion, Intrinsics};
use pa_track::{GrayImage, TagFamily};

fn propsalive(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_propsalive"))
        .args(args)
        .output()
        .expect("run propsalive")
}

fn text(o: &Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

fn s(p: &Path) -> &str {
    p.to_str().expect("utf-8 path")
}

fn camera() -> CameraModel {
    CameraModel {
        intrinsics: Intrinsics {
            fx: 520.0,
            fy: 520.0,
            cx: 322.0,
            cy: 236.5,
            width: 640,
            height: 480,
        },
        distortion: Distortion {
            k1: -0.15,
            k2: 0.03,
            ..Distortion::default()
        },
    }
}

fn save(img: GrayImage, path: &Path) {
    let img: image::GrayImage = img.into();
    img.save(path).expect("save png");
}

fn settings(i: usize) -> RenderSettings {
    RenderSettings {
        supersample: 8,
        seed: i as u64 + 1,
        ..RenderSettings::default()
    }
}

/// `n` rendered views of `pattern` written as `dir/view<i>.png`.
fn write_views(dir: &Path, pattern: &PlanarPattern, n: usize, seed: u64) {
    std::fs::create_dir_all(dir).expect("mkdir");
    let rays = RayMap::new(camera());
    for (i, pose) in varied_poses(&camera(), pattern.outline_m(), n, 45.0, 6.0, seed)
        .iter()
        .enumerate()
    {
        save(
            rays.render(pattern, pose, &settings(i)),
            &dir.join(format!("view{}.png", i + 1)),
        );
    }
}

#[test]
fn calibrates_a_chessboard_folder_and_refuses_to_overwrite() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let imgs = tmp.path().join("imgs");
    write_views(&imgs, &PlanarPattern::chessboard(5, 7, 0.03, 1), 6, 21);
    save(
        GrayImage::filled(640, 480, 150),
        &imgs.join("view7_blank.png"),
    );
    std::fs::write(imgs.join("view8_broken.png"), b"no image here").expect("write");
    let out = tmp.path().join("cam.yaml");
    let args = [
        "calibrate",
        s(&imgs),
        "--chessboard",
        "5x7",
        "--square-mm",
        "30",
        "--out",
        s(&out),
    ];
    let o = propsalive(&args);
    let t = text(&o);
    assert!(o.status.success(), "{t}");
    println!("{t}");
    assert!(t.contains("view1.png: 35 corners"), "{t}");
    assert!(
        t.contains("view7_blank.png: skipped (no chessboard of 5x7"),
        "{t}"
    );
    assert!(
        t.contains("view8_broken.png: skipped (cannot read the image"),
        "{t}"
    );
    assert!(t.contains("6 view(s) of 8 image(s); 2 skipped"), "{t}");
    assert!(
        t.contains("RMS reprojection error:") && t.contains("fx = "),
        "{t}"
    );
    let cam = pa_camera::load_calibration(&out).expect("the YAML loads");
    let k = cam.intrinsics;
    assert_eq!((k.width, k.height), (640, 480));
    assert!((k.fx / 520.0 - 1.0).abs() < 0.01, "fx {}", k.fx);
    assert!((k.fy / 520.0 - 1.0).abs() < 0.01, "fy {}", k.fy);
    assert!(
        (k.cx - 322.0).abs() < 3.0 && (k.cy - 236.5).abs() < 3.0,
        "{k:?}"
    );
    assert!(
        (cam.distortion.k1 + 0.15).abs() < 0.03,
        "{:?}",
        cam.distortion
    );
    let yaml = std::fs::read_to_string(&out).expect("read");
    assert!(
        yaml.contains("board_width: 7") && yaml.contains("nr_of_frames: 6"),
        "{yaml}"
    );

    // No overwrite without --force; the file is untouched.
    std::fs::write(&out, "keep me").expect("write");
    let o = propsalive(&args);
    assert!(!o.status.success());
    assert!(text(&o).contains("--force"), "{}", text(&o));
    assert_eq!(std::fs::read_to_string(&out).expect("read"), "keep me");
    let mut forced = args.to_vec();
    forced.push("--force");
    let o = propsalive(&forced);
    assert!(o.status.success(), "{}", text(&o));
    assert!(pa_camera::load_calibration(&out).is_ok());
}

#[test]
fn calibrates_from_the_tag_board() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let imgs = tmp.path().join("board");
    let (pattern, _) =
        PlanarPattern::tag_board(TagFamily::Tag36h11, 2, 3, 0.04, 0.01, 20).expect("board");
    write_views(&imgs, &pattern, 5, 22);
    let out = tmp.path().join("cam.yml");
    let o = propsalive(&[
        "calibrate",
        s(&imgs),
        "--board",
        "2x3",
        "--size-mm",
        "40",
        "--gap-mm",
        "10",
        "--first-id",
        "20",
        "--out",
        s(&out),
    ]);
    let t = text(&o);
    assert!(o.status.success(), "{t}");
    assert!(t.contains("view1.png: 24 corners"), "{t}");
    let cam = pa_camera::load_calibration(&out).expect("loads");
    assert!((cam.intrinsics.fx / 520.0 - 1.0).abs() < 0.02, "{cam:?}");
    // The wrong first id finds no tag of the board.
    let o = propsalive(&[
        "calibrate",
        s(&imgs),
        "--board",
        "2x3",
        "--size-mm",
        "40",
        "--gap-mm",
        "10",
        "--out",
        s(&tmp.path().join("other.yaml")),
    ]);
    assert!(!o.status.success());
    let t = text(&o);
    assert!(
        t.contains("0 tag(s) of the board found") && t.contains("no image shows the board"),
        "{t}"
    );
}

#[test]
fn bad_input_is_refused_with_a_reason() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let imgs = tmp.path().join("imgs");
    write_views(&imgs, &PlanarPattern::chessboard(5, 7, 0.03, 1), 2, 23);
    let view = imgs.join("view1.png");
    let out = tmp.path().join("cam.yaml");
    let run = |extra: &[&str]| {
        let mut a = vec!["calibrate"];
        a.extend_from_slice(extra);
        propsalive(&a)
    };

    // One view: below the minimum.
    let o = run(&[
        s(&view),
        "--chessboard",
        "5x7",
        "--square-mm",
        "30",
        "--out",
        s(&out),
    ]);
    assert!(!o.status.success());
    assert!(text(&o).contains("needs at least 2"), "{}", text(&o));
    assert!(!out.exists());

    // Two views: calibrates, with a warning about too few.
    let o = run(&[
        s(&imgs),
        "--chessboard",
        "5x7",
        "--square-mm",
        "30",
        "--out",
        s(&out),
    ]);
    assert!(o.status.success(), "{}", text(&o));
    assert!(
        String::from_utf8_lossy(&o.stderr).contains("warning: only 2 view(s)"),
        "{}",
        text(&o)
    );

    // Mixed sizes: an error naming both files.
    let small = tmp.path().join("small.png");
    save(GrayImage::filled(320, 240, 128), &small);
    let o = run(&[
        s(&view),
        s(&small),
        "--chessboard",
        "5x7",
        "--square-mm",
        "30",
        "--out",
        s(&tmp.path().join("mixed.yaml")),
    ]);
    assert!(!o.status.success());
    let t = text(&o);
    assert!(
        t.contains("small.png") && t.contains("view1.png") && t.contains("320x240"),
        "{t}"
    );

    // Flags.
    for (args, expect) in [
        (
            vec![s(&view), "--chessboard", "5x7", "--out", "x.yaml"],
            "--square-mm",
        ),
        (
            vec![
                s(&view),
                "--chessboard",
                "5by7",
                "--square-mm",
                "30",
                "--out",
                "x.yaml",
            ],
            "ROWSxCOLS",
        ),
        (
            vec![
                s(&view),
                "--chessboard",
                "5x7",
                "--square-mm",
                "30",
                "--out",
                "x.txt",
            ],
            ".yaml",
        ),
        (
            vec![
                s(&view),
                "--board",
                "2x3",
                "--size-mm",
                "40",
                "--out",
                "x.yaml",
            ],
            "--gap-mm",
        ),
        (
            vec![s(&view), "--square-mm", "30", "--out", "x.yaml"],
            "--chessboard",
        ),
    ] {
        let o = run(&args);
        assert!(!o.status.success(), "{args:?}");
        assert!(text(&o).contains(expect), "{args:?}: {}", text(&o));
    }
}
