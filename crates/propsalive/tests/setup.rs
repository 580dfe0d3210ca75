//! From a model to a first take (issue 16): `propsalive new` writes a shot that loads, stands
//! the key prop on the sheet and refuses what it cannot use; `marker --shot` prints the board
//! with each key prop's footprint where the placement puts it; `export` and `render` take
//! `--scale`; and a `run` on a generated take works with a shot `new` wrote.

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use glam::Vec3;
use pa_model::{anim, skin, Model};
use pa_pipeline::shot::Shot;
use pa_scene::prop::{prop_glb, PropSpec};

fn exe() -> Command {
    Command::new(common::bin())
}

fn run_in(dir: &Path, args: &[&str]) -> Output {
    exe().current_dir(dir).args(args).output().expect("runs")
}

fn text(o: &Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

fn ok(o: &Output) -> String {
    assert!(o.status.success(), "{}", text(o));
    text(o)
}

fn err(o: &Output) -> String {
    assert!(!o.status.success(), "succeeded: {}", text(o));
    text(o)
}

fn write_bust(dir: &Path) -> PathBuf {
    let p = dir.join("prop.glb");
    std::fs::write(&p, prop_glb(&PropSpec::default()).expect("glb")).expect("write glb");
    p
}

/// The posed key-pose vertices of a shot's model, in the marker frame (independently of
/// `pa_pipeline::footprint`).
fn marker_points(shot: &Shot, shot_path: &Path, key: usize) -> Vec<Vec3> {
    let model = Model::load(Shot::resolve(shot_path, &shot.model)).expect("model");
    let anim = shot.check_model(shot_path, &model).expect("fits");
    let t = shot.key_poses[key].frame as f32 / shot.fps;
    let m = shot.placement.marker_from_prop();
    skin::pose_meshes(&model, &anim::sample(&model, anim, t))
        .iter()
        .flat_map(|p| {
            p.positions
                .iter()
                .map(|v| m.transform_point3(*v))
                .collect::<Vec<_>>()
        })
        .collect()
}

/// A box (x in [lo.x, hi.x], ...) as a GLB with a one-second clip that holds it still.
fn write_box(path: &Path, lo: Vec3, hi: Vec3) {
    let mut bin = Vec::new();
    for i in 0..8 {
        let p = Vec3::new(
            if i & 1 == 0 { lo.x } else { hi.x },
            if i & 2 == 0 { lo.y } else { hi.y },
            if i & 4 == 0 { lo.z } else { hi.z },
        );
        bin.extend(p.to_array().iter().flat_map(|c| c.to_le_bytes()));
    }
    let idx: [u16; 36] = [
        0, 2, 1, 1, 2, 3, 4, 5, 6, 5, 7, 6, 0, 1, 4, 1, 5, 4, 2, 6, 3, 3, 6, 7, 0, 4, 2, 2, 4, 6,
        1, 3, 5, 3, 7, 5,
    ];
    bin.extend(idx.iter().flat_map(|i| i.to_le_bytes()));
    bin.extend([0f32, 1.0].iter().flat_map(|t| t.to_le_bytes()));
    bin.extend([0f32; 6].iter().flat_map(|t| t.to_le_bytes()));
    let doc = serde_json::json!({
        "asset": {"version": "2.0"}, "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
        "buffers": [{"byteLength": bin.len()}],
        "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 96},
                        {"buffer": 0, "byteOffset": 96, "byteLength": 72},
                        {"buffer": 0, "byteOffset": 168, "byteLength": 8},
                        {"buffer": 0, "byteOffset": 176, "byteLength": 24}],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 8, "type": "VEC3",
             "min": lo.to_array(), "max": hi.to_array()},
            {"bufferView": 1, "componentType": 5123, "count": 36, "type": "SCALAR"},
            {"bufferView": 2, "componentType": 5126, "count": 2, "type": "SCALAR",
             "min": [0.0], "max": [1.0]},
            {"bufferView": 3, "componentType": 5126, "count": 2, "type": "VEC3"}],
        "animations": [{"name": "Hold", "channels": [{"sampler": 0,
            "target": {"node": 0, "path": "translation"}}],
            "samplers": [{"input": 2, "output": 3}]}]
    });
    let glb = pa_model::export::glb_container(&doc, bin).expect("glb");
    std::fs::write(path, glb).expect("write box");
}

#[test]
fn new_writes_a_commented_shot_with_the_bust_standing_on_the_board() {
    let dir = tempfile::tempdir().expect("tempdir");
    write_bust(dir.path());
    let out = ok(&run_in(
        dir.path(),
        &[
            "new",
            "shots/first.toml",
            "--model",
            "prop.glb",
            "--key-frames",
            "0,24",
            "--fov-deg",
            "45",
        ],
    ));
    println!("{out}");
    assert!(
        out.contains("propsalive marker --shot shots/first.toml")
            && out.contains("propsalive preview shots/first.toml")
            && out.contains("propsalive register shots/first.toml")
            && out.contains("propsalive run shots/first.toml"),
        "{out}"
    );
    let path = dir.path().join("shots/first.toml");
    let text = std::fs::read_to_string(&path).expect("written");
    // Every section is explained by a comment just above it.
    for section in [
        "[[key_poses]]",
        "[camera]",
        "[marker]",
        "[placement]",
        "model = ",
    ] {
        let at = text.find(section).unwrap_or_else(|| panic!("{section}"));
        let before = text[..at].trim_end().lines().last().unwrap_or_default();
        assert!(before.starts_with('#'), "{section}: {before:?}");
    }
    let shot = Shot::load(&path).expect("loads");
    assert_eq!(shot.model, PathBuf::from("../prop.glb"));
    assert_eq!(shot.format, 1);
    assert_eq!(shot.animation.as_deref(), Some("Animate"));
    let keys: Vec<(&str, u32)> = shot
        .key_poses
        .iter()
        .map(|k| (k.name.as_str(), k.frame))
        .collect();
    assert_eq!(keys, [("A", 0), ("B", 24)]);
    assert_eq!(shot.present_key_index(), 0);
    assert_eq!(shot.camera.fov_y_deg, Some(45.0));
    // The board `marker --board 3x3 --size-mm 45` prints: 45 mm tags, two 5.625 mm cells
    // apart (tag36h11: 8 cells across the black square), ids row-major from the top-left.
    let pitch = 0.045 + 2.0 * 0.045 / 8.0;
    assert_eq!(shot.marker.tags.len(), 9);
    for (i, t) in shot.marker.tags.iter().enumerate() {
        let (r, c) = ((i / 3) as f64 - 1.0, (i % 3) as f64 - 1.0);
        assert_eq!(t.id, i as u32);
        assert!((t.center_m[0] - c * pitch).abs() < 1e-6, "{t:?}");
        assert!((t.center_m[1] - r * pitch).abs() < 1e-6, "{t:?}");
        assert!((t.size_m - 0.045).abs() < 1e-9);
    }
    // The bust is modelled with its flat base at y = 0 around its axis: it stands on the
    // sheet, centred, with no shift or lift to speak of.
    let t = shot.placement.translation_m;
    assert!(t.iter().all(|v| v.abs() < 5e-4), "{t:?}");
    let pts = marker_points(&shot, &path, 0);
    let lowest = pts.iter().map(|p| p.z).fold(f32::MIN, f32::max);
    assert!(lowest.abs() < 2e-6, "lowest point at z = {lowest}");
}

/// A box whose base is not at the model's origin: the placement moves its base onto the
/// sheet and centres it (analytic), at scale 1 and 2.
#[test]
fn new_lifts_and_centres_an_offset_model() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (lo, hi) = (
        Vec3::new(-0.015, 0.01, -0.018),
        Vec3::new(0.025, 0.06, 0.012),
    );
    write_box(&dir.path().join("box.glb"), lo, hi);
    for (scale, name) in [(1.0f32, "one.toml"), (2.0, "two.toml")] {
        let k = scale.to_string();
        ok(&run_in(
            dir.path(),
            &["new", name, "--model", "box.glb", "--scale", &k],
        ));
        let path = dir.path().join(name);
        let shot = Shot::load(&path).expect("loads");
        assert_eq!(shot.placement.scale, scale);
        // Upright, yaw 0: model (x, y, z) -> marker (x, z, -y) * scale + t. The base (y = lo.y)
        // goes to z = 0, the base's centre ((lo + hi) / 2 in x and z) to the origin.
        let c = (lo + hi) * 0.5 * scale;
        let want = [-c.x, -c.z, lo.y * scale];
        let t = shot.placement.translation_m;
        for a in 0..3 {
            assert!(
                (t[a] - want[a]).abs() < 2e-6,
                "scale {scale}: {t:?} vs {want:?}"
            );
        }
    }
}

#[test]
fn new_refuses_what_it_cannot_use() {
    let dir = tempfile::tempdir().expect("tempdir");
    write_bust(dir.path());
    std::fs::create_dir(dir.path().join("folder.glb")).expect("mkdir");
    let new = |extra: &[&str]| {
        let mut a = vec!["new", "s.toml", "--model", "prop.glb"];
        a.extend_from_slice(extra);
        run_in(dir.path(), &a)
    };
    for (args, needle) in [
        (vec!["new", "s.toml", "--model", "folder.glb"], "folder"),
        (
            vec!["new", "s.toml", "--model", "missing.glb"],
            "missing.glb",
        ),
    ] {
        let e = err(&run_in(dir.path(), &args));
        assert!(e.contains(needle), "{e}");
        assert!(!dir.path().join("s.toml").exists());
    }
    for (extra, needle) in [
        (&["--animation", "Dance"][..], "Dance"),
        (&["--key-frames", "0,999"][..], "frame 999 is past the end"),
        (&["--key-frames", "0,x"][..], "--key-frames"),
        (&["--fov-deg", "40", "--calib", "c.yaml"][..], "--calib"),
        (&["--scale", "0"][..], "positive"),
        (&["--board", "0x3"][..], "--board"),
    ] {
        let e = err(&new(extra));
        assert!(e.contains(needle), "{extra:?}: {e}");
        assert!(!dir.path().join("s.toml").exists(), "{extra:?}");
    }
    ok(&new(&[]));
    let first = std::fs::read(dir.path().join("s.toml")).expect("written");
    let e = err(&new(&["--scale", "2"]));
    assert!(e.contains("exists") && e.contains("--force"), "{e}");
    assert_eq!(
        std::fs::read(dir.path().join("s.toml")).expect("kept"),
        first
    );
    ok(&new(&["--scale", "2", "--force"]));
    let shot = Shot::load(&dir.path().join("s.toml")).expect("replaced");
    assert_eq!(shot.placement.scale, 2.0);
}

/// Parses `v` lines of an OBJ.
fn obj_vertices(path: &Path) -> Vec<[f64; 3]> {
    std::fs::read_to_string(path)
        .expect("obj")
        .lines()
        .filter_map(|l| l.strip_prefix("v "))
        .map(|l| {
            let v: Vec<f64> = l
                .split_whitespace()
                .map(|x| x.parse().expect("f"))
                .collect();
            [v[0], v[1], v[2]]
        })
        .collect()
}

#[test]
fn export_scales_the_posed_model_about_its_origin() {
    let dir = tempfile::tempdir().expect("tempdir");
    write_bust(dir.path());
    for (name, scale) in [("one.obj", "1"), ("half.obj", "0.5")] {
        ok(&run_in(
            dir.path(),
            &[
                "export", "prop.glb", "--time", "0.5", "--scale", scale, "--out", name,
            ],
        ));
    }
    let (a, b) = (
        obj_vertices(&dir.path().join("one.obj")),
        obj_vertices(&dir.path().join("half.obj")),
    );
    assert!(a.len() > 1000 && a.len() == b.len());
    for (p, q) in a.iter().zip(&b) {
        for k in 0..3 {
            assert!((p[k] * 0.5 - q[k]).abs() < 1e-6, "{p:?} vs {q:?}");
        }
    }
    for bad in ["0", "-1", "nan", "inf", "x"] {
        let flag = format!("--scale={bad}");
        let e = err(&run_in(
            dir.path(),
            &["export", "prop.glb", &flag, "--out", "bad.obj"],
        ));
        assert!(e.contains("positive, finite"), "{bad}: {e}");
    }
}

/// `render --scale 2` seen from (eye, target) is the unscaled model seen from (eye / 2,
/// target / 2): the same picture (the light is directional).
#[test]
fn render_scale_is_the_model_scaled_about_its_origin() {
    let dir = tempfile::tempdir().expect("tempdir");
    write_bust(dir.path());
    let common_args = ["render", "prop.glb", "--fps", "1", "--size", "160x120"];
    let mut a = common_args.to_vec();
    a.extend([
        "--scale",
        "2",
        "--eye",
        "0.2,0.3,0.8",
        "--target",
        "0,0.2,0",
        "--out",
        "two",
    ]);
    let o = run_in(dir.path(), &a);
    if !o.status.success() && text(&o).contains("adapter") {
        println!("skipped: no wgpu adapter: {}", text(&o));
        return;
    }
    ok(&o);
    let mut b = common_args.to_vec();
    b.extend([
        "--eye",
        "0.1,0.15,0.4",
        "--target",
        "0,0.1,0",
        "--out",
        "one",
    ]);
    ok(&run_in(dir.path(), &b));
    let mut c = common_args.to_vec();
    c.extend([
        "--eye",
        "0.2,0.3,0.8",
        "--target",
        "0,0.2,0",
        "--out",
        "unscaled",
    ]);
    ok(&run_in(dir.path(), &c));
    let load = |d: &str, f: &str| {
        image::open(dir.path().join(d).join(f))
            .expect("png")
            .to_rgba8()
    };
    let mut frames = 0;
    for e in std::fs::read_dir(dir.path().join("one"))
        .expect("frames")
        .flatten()
    {
        let f = e.file_name().to_string_lossy().into_owned();
        let (x, y, z) = (load("two", &f), load("one", &f), load("unscaled", &f));
        let count = |p: &image::RgbaImage, q: &image::RgbaImage| {
            p.pixels()
                .zip(q.pixels())
                .filter(|(a, b)| a.0.iter().zip(b.0).any(|(u, v)| u.abs_diff(v) > 2))
                .count()
        };
        let (same, unscaled) = (count(&x, &y), count(&z, &y));
        println!(
            "{f}: scale 2 vs eye/2: {same} pixels differ by more than 2/255; unscaled: {unscaled}"
        );
        assert!(same <= 20, "{f}: {same} pixels differ");
        assert!(unscaled > 1000, "{f}: the test cannot tell ({unscaled})");
        frames += 1;
    }
    assert!(frames >= 2, "{frames} frames");
}

/// The printed footprint of a box is where the placement puts it: a grey rectangle of the
/// box's base, centred on the board's centre (the centre of its black squares), with the
/// front arrow pointing down the page (+Y, the model's +Z).
#[test]
fn marker_shot_prints_the_footprint_where_the_placement_puts_it() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (lo, hi) = (
        Vec3::new(-0.015, 0.01, -0.018),
        Vec3::new(0.025, 0.06, 0.012),
    );
    write_box(&dir.path().join("box.glb"), lo, hi);
    ok(&run_in(
        dir.path(),
        &["new", "s.toml", "--model", "box.glb"],
    ));
    let out = ok(&run_in(
        dir.path(),
        &[
            "marker", "--shot", "s.toml", "--out", "print", "--dpi", "100",
        ],
    ));
    println!("{out}");
    assert!(out.contains("key prop A"), "{out}");
    let svg = std::fs::read_to_string(dir.path().join("print.svg")).expect("svg");
    assert!(
        svg.contains("<polygon") && svg.contains(">key A</text>"),
        "svg"
    );
    let img = image::open(dir.path().join("print.png"))
        .expect("png")
        .to_luma8();
    let ppm = 100.0 / 25.4;
    // The board's centre: the centre of the black pixels' bounding box (3x3 tags).
    let (mut x0, mut y0, mut x1, mut y1) = (u32::MAX, u32::MAX, 0, 0);
    for (x, y, p) in img.enumerate_pixels() {
        if p.0[0] == 0 {
            (x0, y0, x1, y1) = (x0.min(x), y0.min(y), x1.max(x), y1.max(y));
        }
    }
    let (cx, cy) = ((x0 + x1) as f64 / 2.0, (y0 + y1) as f64 / 2.0);
    let board_mm = (x1 - x0 + 1) as f64 / ppm;
    let want_board = 3.0 * 45.0 + 2.0 * 2.0 * 45.0 / 8.0;
    assert!((board_mm - want_board).abs() < 0.6, "board {board_mm} mm");
    let grey = |x: f64, y: f64| {
        let (x, y) = (x.round() as u32, y.round() as u32);
        img.get_pixel(x, y).0[0] == pa_overlay::sheet::FOOTPRINT_GREY
    };
    // Along the centre row: the outline's left and right sides, 40 mm apart.
    let row: Vec<f64> = (0..img.width())
        .map(f64::from)
        .filter(|&x| grey(x, cy))
        .collect();
    let (left, right) = (row[0], row[row.len() - 1]);
    let w_mm = (right - left) / ppm;
    let mid_x = (left + right) / 2.0;
    // Along a column 5 mm right of the centre: the top and bottom sides, 30 mm apart.
    let col: Vec<f64> = (0..img.height())
        .map(f64::from)
        .filter(|&y| grey(cx + 5.0 * ppm, y))
        .collect();
    let (top, bottom) = (col[0], col[col.len() - 1]);
    let h_mm = (bottom - top) / ppm;
    let mid_y = (top + bottom) / 2.0;
    println!(
        "footprint in the PNG: {w_mm:.2} x {h_mm:.2} mm, centre ({:.2}, {:.2}) mm from the board's",
        (mid_x - cx) / ppm,
        (mid_y - cy) / ppm
    );
    // Line widths of 0.5 mm and pixels of 0.25 mm: within 1 mm.
    assert!((w_mm - 40.0).abs() < 1.0, "width {w_mm} mm");
    assert!((h_mm - 30.0).abs() < 1.0, "height {h_mm} mm");
    assert!(((mid_x - cx) / ppm).abs() < 0.6, "x offset");
    assert!(((mid_y - cy) / ppm).abs() < 0.6, "y offset");
    // The front arrow: from the centre down to the outline, nothing above the centre.
    assert!(
        (0..4).any(|d| grey(cx + f64::from(d) - 1.5, cy + 10.0 * ppm)),
        "arrow below"
    );
    assert!(
        !(0..4).any(|d| grey(cx + f64::from(d) - 1.5, cy - 10.0 * ppm)),
        "nothing above"
    );
    // Nothing grey beyond the outline: the label and the arrow lie under the prop.
    let outside = img
        .enumerate_pixels()
        .filter(|(x, y, p)| {
            p.0[0] == pa_overlay::sheet::FOOTPRINT_GREY
                && ((f64::from(*x) - cx).abs() > 21.0 * ppm
                    || (f64::from(*y) - cy).abs() > 16.0 * ppm)
        })
        .count();
    assert_eq!(outside, 0, "grey pixels outside the footprint");
}

/// A take generated by the scene, run with a shot that `new` wrote for the built-in bust: the
/// scene's board is a ring of eight tags, which `--board` cannot describe, so only the
/// `[[marker.tags]]` of the written file are replaced by the set's; the rest (model, clip,
/// key pose, camera, the placement `new` computed) is used as written. The frames equal the
/// reference run's (whose shot has the scene's true placement) within a PSNR of 40 dB.
#[test]
fn a_run_works_with_a_shot_written_by_new() {
    let _l = common::lock();
    let Some(take) = common::generate_take("setup_new", 3, 320, 240) else {
        return;
    };
    let root = &take.root;
    ok(&run_in(
        root,
        &[
            "new",
            "new.toml",
            "--model",
            "prop.glb",
            "--fov-deg",
            "45",
            "--fps",
            "24",
        ],
    ));
    let written = std::fs::read_to_string(root.join("new.toml")).expect("written");
    let reference = std::fs::read_to_string(&take.shot).expect("reference shot");
    let tags = |t: &str| t.find("[[marker.tags]]").expect("tags");
    let end = written[tags(&written)..]
        .find("\n\n")
        .map(|i| tags(&written) + i)
        .expect("end of tags");
    let ref_tags: String = reference[tags(&reference)..]
        .lines()
        .take_while(|l| !l.starts_with("[placement]"))
        .map(|l| format!("{l}\n"))
        .collect();
    let shot = format!(
        "{}{}{}",
        &written[..tags(&written)],
        ref_tags,
        &written[end..]
    );
    std::fs::write(root.join("new.toml"), shot).expect("write");
    let out = root.join("take_new");
    let o = common::run(&root.join("new.toml"), &take.stills, &out, &[]);
    assert!(o.status.success(), "{}", common::stderr(&o));
    let ours = common::files(&out, "frames");
    let refs = common::files(&take.reference, "frames");
    assert_eq!(ours.len(), 3);
    assert_eq!(
        ours.keys().collect::<Vec<_>>(),
        refs.keys().collect::<Vec<_>>()
    );
    for (name, bytes) in &ours {
        let a = image::load_from_memory(bytes).expect("png").to_rgba8();
        let b = image::load_from_memory(&refs[name])
            .expect("png")
            .to_rgba8();
        let mse: f64 = a
            .as_raw()
            .iter()
            .zip(b.as_raw())
            .map(|(x, y)| (f64::from(*x) - f64::from(*y)).powi(2))
            .sum::<f64>()
            / a.as_raw().len() as f64;
        let psnr = 10.0 * (255.0f64 * 255.0 / mse.max(1e-12)).log10();
        println!("{name}: PSNR {psnr:.1} dB against the reference run");
        assert!(psnr > 40.0, "{name}: {psnr:.1} dB");
    }
    let log = common::log(&out);
    assert!(log.values().all(|v| v["key_pose"] == "A"), "{log:?}");
    let tracked = log.values().filter(|v| v["state"] == "tracked").count();
    assert!(tracked >= 1, "no still tracked: {log:?}");
}
