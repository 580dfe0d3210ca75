//! `propsalive run` with a printed picture as the marker (`[marker] image`, `width_m`), on a
//! small generated take of the `picture` set (`SetOptions::picture_marker`: the sheet is a
//! picture, no tags): every still is tracked by the picture's natural features, the logged
//! pose agrees with the scene's true camera, and bad picture settings are refused before the
//! take with the file and the problem named.

mod common;

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use common::{
    fresh_root, lock, log, pose_delta, renderer_or_skip, run, stderr, write_prop_and_shot,
};
use pa_scene::variant::SetOptions;
use pa_scene::SceneSpec;

const STILLS: u32 = 3;
const W: u32 = 640;
const H: u32 = 360;

struct Set {
    root: PathBuf,
    stills: PathBuf,
    /// The shot's text up to its `[marker]` table (model, camera, placement).
    head: String,
    truth: Vec<glam::DMat4>,
}

fn set() -> Option<&'static Set> {
    static S: OnceLock<Option<Set>> = OnceLock::new();
    S.get_or_init(make).as_ref()
}

fn make() -> Option<Set> {
    let mut renderer = renderer_or_skip()?;
    let root = fresh_root("run_picture_");
    let stills = root.join("stills");
    std::fs::create_dir_all(&stills).expect("mkdir");
    let spec = SceneSpec {
        width: W,
        height: H,
        frames: STILLS,
        set: SetOptions {
            picture_marker: true,
            ..SetOptions::default()
        },
        ..SceneSpec::default()
    };
    let scene = pa_scene::Scene::new(spec.clone(), &mut renderer).expect("scene");
    let mut truth = Vec::new();
    for i in 0..STILLS {
        let f = scene.frame(&mut renderer, i).expect("frame");
        image::RgbaImage::from_raw(W, H, f.input.rgba8)
            .expect("size")
            .save(stills.join(format!("s{}.png", i + 1)))
            .expect("save");
        truth.push(f.camera_from_marker.as_dmat4());
    }
    // The user's picture file: the pixels printed on the set's sheet.
    let pic = pa_scene::scene::marker_picture();
    image::GrayImage::from_raw(pic.width, pic.height, pic.data)
        .expect("size")
        .save(root.join("floor.png"))
        .expect("save");
    let shot = write_prop_and_shot(&root, &spec);
    let text = std::fs::read_to_string(&shot).expect("shot");
    let head = text[..text.find("[marker]").expect("[marker]")].to_string();
    Some(Set {
        root,
        stills,
        head,
        truth,
    })
}

/// Writes `name` in the set's folder: the common head and `marker` as the `[marker]` table.
fn shot(s: &Set, name: &str, marker: &str) -> PathBuf {
    let p = s.root.join(name);
    std::fs::write(&p, format!("{}[marker]\n{marker}", s.head)).expect("write shot");
    p
}

#[test]
fn a_take_on_a_picture_marker_is_tracked_at_the_true_pose() {
    let _l = lock();
    let Some(s) = set() else { return };
    let shot = shot(s, "picture.toml", "image = \"floor.png\"\nwidth_m = 0.4\n");
    let out = s.root.join("out_picture");
    let o = run(&shot, &s.stills, &out, &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    let l = log(&out);
    assert_eq!(l.len(), STILLS as usize);
    for (i, v) in &l {
        assert_eq!(v["state"], "tracked", "still {i}: {v}");
        let m: Vec<f64> = v["camera_from_marker"]
            .as_array()
            .expect("pose")
            .iter()
            .map(|x| x.as_f64().expect("number"))
            .collect();
        let got = glam::DMat4::from_cols_slice(&m);
        let (t_mm, r_deg) = pose_delta(&got, &s.truth[*i as usize]);
        eprintln!("still {i}: {t_mm:.2} mm, {r_deg:.3} deg");
        assert!(
            t_mm < 5.0 && r_deg < 0.5,
            "still {i}: {t_mm} mm, {r_deg} deg"
        );
        // No tags in this marker.
        assert_eq!(v["used_ids"], serde_json::json!([]), "still {i}");
    }
}

#[test]
fn bad_picture_markers_are_refused_before_the_take() {
    let _l = lock();
    let Some(s) = set() else { return };
    let flat = s.root.join("flat.png");
    image::GrayImage::from_pixel(400, 300, image::Luma([128]))
        .save(&flat)
        .expect("save");
    std::fs::write(s.root.join("notes.png"), b"not a picture").expect("write");
    for (name, marker, needles) in [
        (
            "flat.toml",
            "image = \"flat.png\"\nwidth_m = 0.4\n",
            &["flat.png", "cannot be tracked"][..],
        ),
        (
            "notes.toml",
            "image = \"notes.png\"\nwidth_m = 0.4\n",
            &["notes.png"][..],
        ),
        (
            "missing.toml",
            "image = \"missing.png\"\nwidth_m = 0.4\n",
            &["missing.png"][..],
        ),
        (
            "escape.toml",
            "image = \"../floor.png\"\nwidth_m = 0.4\n",
            &["inside the shot's folder"][..],
        ),
        (
            "hide.toml",
            "image = \"floor.png\"\nwidth_m = 0.4\nhide = \"cover\"\ncover = \"floor.png\"\n",
            &["picture only", "hide = \"none\""][..],
        ),
    ] {
        let shot = shot(s, name, marker);
        let out = s.root.join(format!("out_{name}"));
        let o = run(&shot, &s.stills, &out, &[]);
        let e = stderr(&o);
        assert!(!o.status.success(), "{name}: accepted");
        for n in needles {
            assert!(e.contains(n), "{name}: {n:?} not in: {e}");
        }
        assert!(!e.contains("panicked"), "{name}: {e}");
        assert!(
            !Path::new(&out).join("log.jsonl").exists(),
            "{name}: a take was started"
        );
    }
}
