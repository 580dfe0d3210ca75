//! `propsalive register` end to end: generated views of the built-in prop on its board (the
//! true placement is `pa_scene::scene::marker_from_prop`, the origin, yaw 0), a shot whose
//! placement is 8 mm and 7 degrees off, the refined block on stdout, `--write` in place with
//! numbered backups, and each refusal.

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use common::{bin, fresh_root, lock, stderr, write_prop_and_shot};
use glam::{Mat4, Vec3};
use pa_scene::SceneSpec;

const W: u32 = 640;
const H: u32 = 360;

fn view_pose(i: usize, n: usize) -> Mat4 {
    let u = i as f32 / (n - 1) as f32;
    let az = (-40.0 + 80.0 * u).to_radians();
    let el = (30.0f32 + if i.is_multiple_of(2) { -5.0 } else { 5.0 }).to_radians();
    let d = 0.55;
    let eye = Vec3::new(
        d * el.cos() * az.sin(),
        d * el.cos() * az.cos(),
        -d * el.sin(),
    );
    pa_camera::camera_from_world_look_at(eye, Vec3::new(0.0, 0.0, -0.08), Vec3::NEG_Z)
        .expect("view")
}

/// `root/views` (6 PNG views around the prop), `root/prop.glb` and `root/shot.toml` with a
/// perturbed, commented placement. None without a renderer.
fn setup(prefix: &str) -> Option<(PathBuf, PathBuf, PathBuf)> {
    let mut renderer = match pa_render::Renderer::new() {
        Ok(r) => r,
        Err(e) => {
            println!("skipped: no renderer ({e})");
            return None;
        }
    };
    let root = fresh_root(prefix);
    let views = root.join("views");
    std::fs::create_dir_all(&views).expect("mkdir");
    let spec = SceneSpec {
        width: W,
        height: H,
        frames: 2,
        ..SceneSpec::default()
    };
    let scene = pa_scene::Scene::new(spec.clone(), &mut renderer).expect("scene");
    for i in 0..6 {
        let f = scene
            .render_view(&mut renderer, view_pose(i, 6), Some(0.0))
            .expect("render");
        let img = image::RgbaImage::from_raw(W, H, f.rgba8).expect("size");
        img.save(views.join(format!("v{i}.png"))).expect("save");
    }
    let shot = write_prop_and_shot(&root, &spec);
    let text = std::fs::read_to_string(&shot).expect("shot");
    let text = text.replace(
        "[placement]\nupright = true\nyaw_deg = 0.0\n",
        "[placement]\n# measured with a ruler\ntranslation_m = [0.006, -0.005, 0.001]\nupright = true\nyaw_deg = 7.0  # roughly\n",
    );
    assert!(text.contains("# measured with a ruler"));
    std::fs::write(&shot, text).expect("write");
    Some((root, views, shot))
}

fn register(shot: &Path, input: &Path, extra: &[&str]) -> Output {
    Command::new(bin())
        .arg("register")
        .arg(shot)
        .arg("--input")
        .arg(input)
        .args(extra)
        .output()
        .expect("runs")
}

/// The placement of TOML text (stdout, or the shot file): `translation_m` and `yaw_deg`.
fn placement(text: &str) -> ([f64; 3], f64) {
    let value = |key: &str| -> &str {
        let line = text
            .lines()
            .find(|l| l.starts_with(key))
            .unwrap_or_else(|| panic!("{key} in {text}"));
        let v = line.split_once('=').expect("=").1;
        v.split('#').next().expect("value").trim()
    };
    let t: Vec<f64> = value("translation_m")
        .trim_matches(['[', ']'])
        .split(',')
        .map(|x| x.trim().parse().expect("number"))
        .collect();
    ([t[0], t[1], t[2]], value("yaw_deg").parse().expect("yaw"))
}

#[test]
fn register_refines_prints_and_writes_in_place() {
    let _l = lock();
    let Some((root, views, shot)) = setup("register_cli_") else {
        return;
    };
    let original = std::fs::read_to_string(&shot).expect("shot");
    let o = register(&shot, &views, &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = String::from_utf8(o.stdout).expect("utf8");
    // stdout is the [placement] block with comments: valid TOML, close to the truth.
    let (t, yaw) = placement(&out);
    assert!((t[0].hypot(t[1])) < 0.5e-3, "{out}");
    assert!(t[2].abs() < 0.5e-3, "{out}");
    assert!(yaw.abs() < 1.5, "{out}");
    assert!(out.contains("# residual "), "{out}");
    assert!(out.contains("# change from the shot: x -"), "{out}");
    assert!(out.contains("v0.png: "), "{out}");
    // Without --write the shot is untouched and no backup is made.
    assert_eq!(std::fs::read_to_string(&shot).expect("shot"), original);
    assert!(!root.join("shot.toml.bak").exists());

    let o = register(&shot, &views, &["--write"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(
        std::fs::read_to_string(root.join("shot.toml.bak")).expect("backup"),
        original
    );
    let written = std::fs::read_to_string(&shot).expect("shot");
    assert!(
        written.contains("# measured with a ruler\ntranslation_m = ["),
        "{written}"
    );
    assert!(written.contains("  # roughly\n"), "{written}");
    let (t2, yaw2) = placement(&written);
    assert!(
        (t2[0] - t[0]).abs() < 2e-6 && (yaw2 - yaw).abs() < 2e-3,
        "{written}\n{out}"
    );
    pa_pipeline::shot::Shot::load(&shot).expect("still a valid shot");

    // A second write keeps the first backup.
    let o = register(&shot, &views, &["--write"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(
        std::fs::read_to_string(root.join("shot.toml.bak")).expect("backup"),
        original
    );
    assert_eq!(
        std::fs::read_to_string(root.join("shot.toml.bak.1")).expect("backup 1"),
        written
    );

    // --scale refines the size too and writes it into [placement].
    let o = register(&shot, &views, &["--scale", "--write"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = String::from_utf8(o.stdout).expect("utf8");
    assert!(
        out.contains("\nscale = ") && out.contains(", scale "),
        "{out}"
    );
    assert!(root.join("shot.toml.bak.2").exists());
    let written = std::fs::read_to_string(&shot).expect("shot");
    let line = written
        .lines()
        .find(|l| l.starts_with("scale = "))
        .unwrap_or_else(|| panic!("{written}"));
    let scale: f64 = line["scale = ".len()..].trim().parse().expect("number");
    assert!((scale - 1.0).abs() < 0.01, "{written}");
}

#[test]
fn register_refuses_what_cannot_be_registered() {
    let _l = lock();
    let Some((root, views, shot)) = setup("register_cli_refuse_") else {
        return;
    };
    let fail = |o: &Output, needle: &str| {
        assert!(!o.status.success(), "{needle}");
        let e = stderr(o);
        assert!(e.contains(needle), "{needle}: {e}");
    };
    // One view.
    let one = root.join("one");
    std::fs::create_dir_all(&one).expect("mkdir");
    std::fs::copy(views.join("v0.png"), one.join("v0.png")).expect("copy");
    fail(
        &register(&shot, &one, &[]),
        "the marker was tracked in 1 of 1 frames; registration needs at least 2",
    );
    // No marker in the frames.
    let blank = root.join("blank");
    std::fs::create_dir_all(&blank).expect("mkdir");
    for i in 0..3 {
        image::RgbaImage::from_pixel(W, H, image::Rgba([128, 128, 128, 255]))
            .save(blank.join(format!("b{i}.png")))
            .expect("save");
    }
    let o = register(&shot, &blank, &[]);
    fail(&o, "the marker was tracked in 0 of 3 frames");
    assert!(
        stderr(&o).contains("b0.png: marker not found"),
        "{}",
        stderr(&o)
    );
    // The prop placed a metre above the table is in no view.
    let far = root.join("far.toml");
    let text = std::fs::read_to_string(&shot).expect("shot").replace(
        "translation_m = [0.006, -0.005, 0.001]",
        "translation_m = [0.0, 0.0, -1.0]",
    );
    std::fs::write(&far, text).expect("write");
    fail(&register(&far, &views, &[]), "is inside only 0 of 6 views");
    assert!(!root.join("far.toml.bak").exists());
    // Flags.
    fail(
        &register(&shot, &views, &["--max-views", "1"]),
        "--max-views must be at least 2",
    );
    fail(
        &register(&shot, Path::new("camera:0"), &[]),
        "register reads a folder of stills or a video file",
    );
}
