//! `propsalive track --image-target` and `propsalive marker --check` end to end, on a
//! procedural picture and an exact synthetic view of it at a known pose.

use std::path::Path;
use std::process::{Command, Output};

use glam::{DVec2, DVec3};
use pa_track::image_target::synth::{natural_picture, render_view, view_pose, Pinhole};
use pa_track::GrayImage;

fn propsalive(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_propsalive"))
        .args(args)
        .output()
        .expect("run propsalive")
}

fn s(p: &Path) -> &str {
    p.to_str().expect("utf-8 path")
}

fn save(img: &GrayImage, path: &Path) {
    image::GrayImage::from_raw(img.width, img.height, img.data.clone())
        .expect("buffer of the image's size")
        .save(path)
        .expect("write the PNG");
}

#[test]
fn track_reports_the_pictures_corners_and_pose() {
    let dir = tempfile::tempdir().unwrap();
    let pic = natural_picture(640, 480, 7);
    let pic_path = dir.path().join("floor.png");
    save(&pic, &pic_path);
    // f = 1000 px at 720 rows: vertical FOV 2 atan(360 / 1000).
    let fov = 2.0 * (360.0f64 / 1000.0).atan().to_degrees();
    let cam = Pinhole {
        fx: 1000.0,
        fy: 1000.0,
        cx: 639.5,
        cy: 359.5,
        width: 1280,
        height: 720,
    };
    let truth = view_pose(0.6, 35.0, 60.0, 0.03, -0.02);
    let frame = render_view(&pic, 0.3, &cam, &truth, 80, 0.6, 1.5, 5);
    let frame_path = dir.path().join("frame.png");
    save(&frame, &frame_path);
    let fov_s = format!("{fov}");
    let out = propsalive(&[
        "track",
        s(&frame_path),
        "--image-target",
        s(&pic_path),
        "--target-width-m",
        "0.3",
        "--fov-deg",
        &fov_s,
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let line = String::from_utf8(out.stdout).unwrap();
    let v: serde_json::Value = serde_json::from_str(line.trim()).unwrap();
    assert_eq!(v["state"], "tracked");
    let corners = v["target_corners_px"].as_array().unwrap();
    let h = 0.5 * 0.3 * 480.0 / 640.0;
    let want = [(-0.15, -h), (0.15, -h), (0.15, h), (-0.15, h)].map(|(x, y)| {
        let c = truth.transform_point(DVec3::new(x, y, 0.0));
        DVec2::new(1000.0 * c.x / c.z + 639.5, 1000.0 * c.y / c.z + 359.5)
    });
    for (c, w) in corners.iter().zip(&want) {
        let g = DVec2::new(c[0].as_f64().unwrap(), c[1].as_f64().unwrap());
        assert!(g.distance(*w) < 1.0, "corner {g} vs {w}");
    }
    let t = &v["measured_pose"]["camera_from_marker"]["translation_m"];
    let t = DVec3::new(
        t[0].as_f64().unwrap(),
        t[1].as_f64().unwrap(),
        t[2].as_f64().unwrap(),
    );
    assert!(
        t.distance(truth.translation) < 0.005,
        "{t} vs {}",
        truth.translation
    );
    assert!(v["pose"]["camera_from_marker"]["rotation_xyzw"].is_array());
}

#[test]
fn bad_pictures_are_refused_with_the_file_named() {
    let dir = tempfile::tempdir().unwrap();
    let frame = dir.path().join("frame.png");
    save(&GrayImage::filled(320, 240, 90), &frame);
    let not_image = dir.path().join("poster.png");
    std::fs::write(&not_image, b"not a png at all").unwrap();
    let flat = dir.path().join("flat.png");
    save(&GrayImage::filled(400, 300, 128), &flat);
    for (pic, want) in [(&not_image, "not a readable image"), (&flat, "keypoints")] {
        let out = propsalive(&[
            "track",
            s(&frame),
            "--image-target",
            s(pic),
            "--target-width-m",
            "0.3",
            "--fov-deg",
            "40",
        ]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success());
        assert!(err.contains(s(pic)) && err.contains(want), "{err}");
    }
    let out = propsalive(&["marker", "--check", s(&not_image)]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("not a readable image"));
}

#[test]
fn marker_check_gives_a_verdict() {
    let dir = tempfile::tempdir().unwrap();
    let good = dir.path().join("good.png");
    save(&natural_picture(640, 480, 7), &good);
    let out = propsalive(&["marker", "--check", s(&good)]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{text}");
    assert!(text.contains("verdict: good"), "{text}");
    assert!(text.contains("keypoints: "), "{text}");

    let flat = dir.path().join("flat.png");
    save(&GrayImage::filled(400, 300, 200), &flat);
    let out = propsalive(&["marker", "--check", s(&flat)]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(!out.status.success());
    assert!(text.contains("verdict: unusable"), "{text}");

    // A tiled motif: trackable keypoints, but repetitive.
    let motif = natural_picture(128, 128, 11);
    let mut tiled = GrayImage::filled(480, 480, 0);
    for y in 0..480usize {
        for x in 0..480usize {
            tiled.data[y * 480 + x] = motif.data[(y % 40 + 20) * 128 + x % 40 + 20];
        }
    }
    let rep = dir.path().join("tiles.png");
    save(&tiled, &rep);
    let out = propsalive(&["marker", "--check", s(&rep)]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{text}");
    assert!(text.contains("warning: repetitive texture"), "{text}");
    assert!(text.contains("verdict: usable"), "{text}");
}
