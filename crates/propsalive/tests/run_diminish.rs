//! `propsalive run` with the shot's `[diminish]` and the diminish flags on a small generated
//! take (4 stills, 320x180) with the scene's clean plate: the plate fill reaches the take and
//! reveals the background (where the fills differ, away from the twin) of the still shot from
//! the plate's own view far closer to it than the ray fill; flags override the
//! shot; plate stills go out untouched; bad settings are refused before the take.

mod common;

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use common::{
    fresh_root, lock, log, renderer_or_skip, run, scene_stills, stderr, write_prop_and_shot,
};

const STILLS: u32 = 4;
const W: u32 = 320;
const H: u32 = 180;

struct Set {
    root: PathBuf,
    stills: PathBuf,
    /// The shot with `[diminish] clean_plate = "plate.png"`.
    shot: PathBuf,
}

fn set() -> Option<&'static Set> {
    static S: OnceLock<Option<Set>> = OnceLock::new();
    S.get_or_init(make).as_ref()
}

fn make() -> Option<Set> {
    let mut renderer = renderer_or_skip()?;
    let root = fresh_root("run_diminish_");
    let (scene, spec, stills) = scene_stills(&mut renderer, &root, STILLS, W, H);
    let (plate, _) = scene.clean_plate(&mut renderer).expect("plate");
    image::RgbaImage::from_raw(W, H, plate.rgba8)
        .expect("size")
        .save(root.join("plate.png"))
        .expect("save");
    let shot = write_prop_and_shot(&root, &spec);
    let mut text = std::fs::read_to_string(&shot).expect("shot");
    text.push_str("\n[diminish]\nclean_plate = \"plate.png\"\ndilation_px = 4\n");
    std::fs::write(&shot, text).expect("write shot");
    Some(Set { root, stills, shot })
}

fn frame(dir: &Path, i: u32) -> Vec<u8> {
    image::open(dir.join(format!("frames/{i:06}.png")))
        .expect("frame")
        .to_rgba8()
        .into_raw()
}

/// The twin's pixels of a take's frame (`--passes masks`: G = twin), grown by 2 px (its
/// anti-aliased edge).
fn twin_mask(dir: &Path, i: u32) -> Vec<bool> {
    let m = image::open(dir.join(format!("masks/{i:06}.png")))
        .expect("mask")
        .to_rgba8();
    let (w, h) = (W as i64, H as i64);
    (0..h)
        .flat_map(|y| (0..w).map(move |x| (x, y)))
        .map(|(x, y)| {
            (-2..=2i64).any(|dy| {
                (-2..=2i64).any(|dx| {
                    let (xx, yy) = (x + dx, y + dy);
                    xx >= 0
                        && yy >= 0
                        && xx < w
                        && yy < h
                        && m.get_pixel(xx as u32, yy as u32)[1] > 0
                })
            })
        })
        .collect()
}

/// PSNR (RGB) over the pixels where `a` and `b` differ outside `skip`, of each against
/// `truth`.
fn psnr_where_they_differ(a: &[u8], b: &[u8], truth: &[u8], skip: &[bool]) -> (f64, f64, usize) {
    let (mut ea, mut eb, mut n) = (0.0f64, 0.0f64, 0usize);
    for (((pa, pb), pt), &sk) in a
        .chunks_exact(4)
        .zip(b.chunks_exact(4))
        .zip(truth.chunks_exact(4))
        .zip(skip)
    {
        if pa[..3] == pb[..3] || sk {
            continue;
        }
        n += 1;
        for c in 0..3 {
            ea += (f64::from(pa[c]) - f64::from(pt[c])).powi(2);
            eb += (f64::from(pb[c]) - f64::from(pt[c])).powi(2);
        }
    }
    let p = |e: f64| 10.0 * (255.0f64 * 255.0 / (e / (3 * n.max(1)) as f64)).log10();
    (p(ea), p(eb), n)
}

#[test]
fn the_shots_clean_plate_reaches_the_take_and_beats_the_ray_fill() {
    let _l = lock();
    let Some(s) = set() else { return };
    let plate_out = s.root.join("out_plate");
    let o = run(&s.shot, &s.stills, &plate_out, &["--passes", "masks"]);
    assert!(o.status.success(), "{}", stderr(&o));
    // The flag overrides the shot's plate fill.
    let rays_out = s.root.join("out_rays");
    let o = run(
        &s.shot,
        &s.stills,
        &rays_out,
        &["--fill", "rays", "--passes", "masks"],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let l = log(&plate_out);
    assert_eq!(l[&0]["state"], "tracked");
    // Still 0 was shot from the plate's own view: there the plate is the background's truth.
    let truth = image::open(s.root.join("plate.png"))
        .expect("plate")
        .to_rgba8()
        .into_raw();
    let (a, b) = (frame(&plate_out, 0), frame(&rays_out, 0));
    // The revealed background: where the fills differ, away from the twin.
    let skip = twin_mask(&plate_out, 0);
    let (p_plate, p_rays, n) = psnr_where_they_differ(&a, &b, &truth, &skip);
    println!("still 0: {n} pixels differ; plate {p_plate:.1} dB, rays {p_rays:.1} dB");
    assert!(n > 100, "the fills differ in only {n} pixels");
    assert!(p_plate > 30.0, "plate fill {p_plate} dB");
    assert!(p_plate > p_rays + 3.0, "plate {p_plate} vs rays {p_rays}");
}

#[test]
fn plate_frames_go_out_untouched_and_shadows_run() {
    let _l = lock();
    let Some(s) = set() else { return };
    // s0.png (the plate) sorts first.
    let dir = s.root.join("with_plate_still");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("mkdir");
    std::fs::copy(s.root.join("plate.png"), dir.join("s0.png")).expect("copy");
    for i in 1..=2 {
        std::fs::copy(
            s.stills.join(format!("s{i}.png")),
            dir.join(format!("s{i}.png")),
        )
        .expect("copy");
    }
    let out = s.root.join("out_plate_frames");
    let o = run(
        &s.shot,
        &dir,
        &out,
        &["--plate-frames", "1", "--shadows", "--dilation", "6"],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let plate = image::open(dir.join("s0.png"))
        .expect("plate")
        .to_rgba8()
        .into_raw();
    assert_eq!(frame(&out, 0), plate, "the plate still goes out untouched");
    let l = log(&out);
    assert_eq!(l.len(), 3);
    assert_ne!(l[&1]["state"], serde_json::Value::Null);
    assert_ne!(
        frame(&out, 1),
        image::open(dir.join("s1.png"))
            .expect("still")
            .to_rgba8()
            .into_raw()
    );
}

#[test]
fn bad_diminish_settings_are_refused_before_the_take() {
    let _l = lock();
    let Some(s) = set() else { return };
    for (args, needle) in [
        (
            vec!["--fill", "smudge"],
            "--fill: fill \"smudge\": expected one of",
        ),
        (
            vec!["--dilation", "-3"],
            "--dilation must be 0..=64 pixels, got -3",
        ),
        (
            vec!["--clean-plate", "/nonexistent/plate.png"],
            "clean plate /nonexistent/plate.png",
        ),
        (
            vec!["--clean-plate", "/nonexistent/p.png", "--plate-frames", "2"],
            "not both",
        ),
    ] {
        let out = s.root.join("refused");
        let o = run(&s.shot, &s.stills, &out, &args);
        let e = stderr(&o);
        assert!(!o.status.success(), "{args:?} was accepted");
        assert!(e.contains(needle), "{args:?}: {e}");
        assert!(!out.join("frames").exists(), "{args:?} started a take");
    }
}
