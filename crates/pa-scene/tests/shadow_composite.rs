//! Shadows through the whole frame pipeline, on both render paths: the in-between twin's cast
//! shadow lands where its posed geometry projected along the light says, both paths agree,
//! and the composite matches its golden image (`ar_shadow_cast`); and the key prop's own cast
//! shadow, added to a generated frame with a known light, is found and lifted.
//!
//! The scene is golden_ar.rs's (192x108, seed 3, key pose frame 0, in-between frame 20 with
//! the head turned), seen from the true camera pose. The light is the set's key light
//! (`pa_scene::scene::set_lighting`). Tolerance of the golden: `Tolerance::DEFAULT` (2/255 on
//! 99.5 % of the pixels). `UPDATE_GOLDEN=1` rewrites it.

use std::path::PathBuf;

use pa_diminish::shadow::cast_shadow;
use pa_diminish::{psnr_rgb, ImageRgba8, Mask};
use pa_model::anim;
use pa_pipeline::ar::{ArFrame, ArSettings, FrameTimes, RenderPath};
use pa_pipeline::shadow::{hard_matte, posed_triangles, soft_matte, ShadowLight};
use pa_render::Renderer;
use pa_scene::eval::pipeline_for;
use pa_scene::scene::{marker_from_prop, set_lighting};
use pa_scene::{Scene, SceneSpec};
use pa_testkit::golden::{assert_golden_in, Goldens, Tolerance};

const W: u32 = 192;
const H: u32 = 108;
const FRAME: u32 = 20;
/// The key-shadow case's frame size: its outline pairs need a few pixels of one surface.
const KW: u32 = 480;
const KH: u32 = 270;

fn light() -> ShadowLight {
    let toward = set_lighting()
        .directional
        .expect("the set has a key light")
        .toward_light_world
        .normalize();
    ShadowLight {
        toward_light: toward,
        softness_px: 1.5,
        ratio_rgb: [0.5, 0.52, 0.56],
    }
}

struct Case {
    renderer: Renderer,
    scene: Scene,
    width: u32,
    height: u32,
}

fn case() -> Option<Case> {
    case_at(W, H)
}

fn case_at(width: u32, height: u32) -> Option<Case> {
    let mut renderer = match Renderer::new() {
        Ok(r) => r,
        Err(e) => {
            println!("skipped: no wgpu adapter ({e})");
            return None;
        }
    };
    let spec = SceneSpec {
        seed: 3,
        width,
        height,
        frames: FRAME + 1,
        ..SceneSpec::default()
    };
    let scene = Scene::new(spec, &mut renderer).expect("scene");
    Some(Case {
        renderer,
        scene,
        width,
        height,
    })
}

/// One frame through the pipeline: `shadows` on or off, `light` given or estimated, the
/// input possibly replaced.
fn run(
    c: &mut Case,
    path: RenderPath,
    shadows: bool,
    light: Option<ShadowLight>,
    input: Option<&[u8]>,
) -> (ArFrame, Option<ShadowLight>) {
    let mut p = pipeline_for(&c.scene, &mut c.renderer, ArSettings::ours()).expect("pipeline");
    p.set_render_path(path);
    p.set_shadows(shadows);
    p.set_shadow_light(light);
    let f = c.scene.frame(&mut c.renderer, FRAME).expect("frame");
    let out = p
        .process_with_pose(
            &mut c.renderer,
            input.unwrap_or(&f.input.rgba8),
            c.width,
            c.height,
            FrameTimes {
                animation_s: f.time_s,
                key_pose_s: 0.0,
            },
            f.camera_from_marker,
        )
        .expect("process");
    (out, p.shadow_light())
}

fn luma(p: &[u8]) -> i32 {
    (77 * i32::from(p[0]) + 150 * i32::from(p[1]) + 29 * i32::from(p[2])) >> 8
}

#[test]
fn twin_shadow_lands_where_geometry_says_on_both_paths() {
    let Some(mut c) = case() else { return };
    let f = c.scene.frame(&mut c.renderer, FRAME).expect("frame");
    let pose = anim::sample(&c.scene.model, 0, f.time_s);
    let tris = posed_triangles(&c.scene.model, &pose, marker_from_prop());
    let camera = pa_camera::CameraModel::pinhole(c.scene.intrinsics);
    let hard = hard_matte(
        &tris,
        light().toward_light,
        &camera,
        f.camera_from_marker,
        0,
        W,
        H,
    )
    .expect("the shadow is in view");
    // Reach of the softened edge: three deviations and a pixel.
    let near = |x: u32, y: u32| {
        let r = 6i64;
        (-r..=r).any(|dy| {
            (-r..=r).any(|dx| {
                let (xx, yy) = (i64::from(x) + dx, i64::from(y) + dy);
                xx >= 0
                    && yy >= 0
                    && xx < i64::from(W)
                    && yy < i64::from(H)
                    && hard.at(xx as u32, yy as u32) > 0.5
            })
        })
    };
    let mut darkened_sets = Vec::new();
    for path in [RenderPath::Gpu, RenderPath::Cpu] {
        let (off, _) = run(&mut c, path, false, None, None);
        let (on, _) = run(&mut c, path, true, Some(light()), None);
        let (mut dark, mut dark_near, mut umbra, mut umbra_dark) = (0, 0, 0, 0);
        let mut set = vec![false; (W * H) as usize];
        for y in 0..H {
            for x in 0..W {
                let i = (y * W + x) as usize;
                // The twin and its anti-aliased edge (one pixel around it): with shadows on the
                // twin is relit along the shadows' light (the sun), so its own pixels may differ.
                let by_twin = (-1i64..=1).any(|dy| {
                    (-1i64..=1).any(|dx| {
                        let (xx, yy) = (i64::from(x) + dx, i64::from(y) + dy);
                        if xx < 0 || yy < 0 || xx >= i64::from(W) || yy >= i64::from(H) {
                            return false;
                        }
                        let j = (yy * i64::from(W) + xx) as usize;
                        on.twin_mask[j] || off.twin_mask[j]
                    })
                });
                if by_twin {
                    continue;
                }
                let d = luma(&off.rgba8[i * 4..]) - luma(&on.rgba8[i * 4..]) > 4;
                set[i] = d;
                if d {
                    dark += 1;
                    dark_near += usize::from(near(x, y));
                }
                // The umbra: the hard shadow two pixels in from its edge.
                let inner = (-2i64..=2).all(|dy| {
                    (-2i64..=2).all(|dx| {
                        let (xx, yy) = (i64::from(x) + dx, i64::from(y) + dy);
                        xx >= 0
                            && yy >= 0
                            && xx < i64::from(W)
                            && yy < i64::from(H)
                            && hard.at(xx as u32, yy as u32) > 0.5
                    })
                });
                if inner {
                    umbra += 1;
                    umbra_dark += usize::from(d);
                }
            }
        }
        println!(
            "{}: {dark} darkened pixels, {dark_near} near the geometric shadow; umbra {umbra_dark}/{umbra}",
            path.name()
        );
        assert!(umbra > 100, "the umbra is in view ({umbra} px)");
        assert!(
            umbra_dark as f64 >= 0.95 * umbra as f64,
            "umbra darkened {umbra_dark}/{umbra}"
        );
        assert!(
            dark_near == dark,
            "{dark_near}/{dark} darkened near the shadow"
        );
        darkened_sets.push(set);
        // The golden of the shadow composite, the same on both paths.
        assert_golden_in(
            &Goldens::for_adapter(
                PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/golden"),
                &c.renderer.adapter_info(),
                c.renderer.is_software(),
            ),
            "ar_shadow_cast",
            W,
            H,
            &on.rgba8,
            Tolerance::DEFAULT,
        );
    }
    let (a, b) = (&darkened_sets[0], &darkened_sets[1]);
    let inter = a.iter().zip(b).filter(|(x, y)| **x && **y).count();
    let union = a.iter().zip(b).filter(|(x, y)| **x || **y).count();
    assert!(
        inter as f64 >= 0.97 * union as f64,
        "paths agree on {inter}/{union} darkened pixels"
    );
}

/// The key prop's cast shadow (added to a 480x270 generated frame: the key pose projected along a
/// known light, softened by 1.5 px, keeping about half the light) is lifted before the fill
/// with that light's direction and softness given and its darkening measured on the frame:
/// the output's background agrees with the frame without the shadow far better than with
/// shadows off, on both paths. (The direction is estimated from the frame in
/// `pa-pipeline`'s analytic tests; here the shadow straddles the sheet's corner, its tags and
/// the wood, where the estimate is not reliable: see the README.)
#[test]
fn key_shadow_is_lifted_with_a_measured_ratio() {
    let Some(mut c) = case_at(KW, KH) else { return };
    let f = c.scene.frame(&mut c.renderer, FRAME).expect("frame");
    let key = anim::sample(&c.scene.model, 0, 0.0);
    let tris = posed_triangles(&c.scene.model, &key, marker_from_prop());
    let camera = pa_camera::CameraModel::pinhole(c.scene.intrinsics);
    // From the front left: the shadow falls across the sheet, its tags and the wood.
    let truth = ShadowLight {
        toward_light: glam::Vec3::new(0.5, -0.6, -1.0).normalize(),
        ..light()
    };
    let matte = soft_matte(&tris, &truth, &camera, f.camera_from_marker, KW, KH)
        .expect("soften")
        .expect("the shadow is in view");
    let clean = ImageRgba8::new(KW, KH, f.input.rgba8.clone()).expect("image");
    let mut shadowed = clean.clone();
    cast_shadow(&mut shadowed, &matte, truth.ratio_rgb).expect("cast");
    for path in [RenderPath::Gpu, RenderPath::Cpu] {
        let (off, _) = run(&mut c, path, false, None, Some(shadowed.as_slice()));
        // Direction and softness given; the ratio starts wrong and is measured on the frame.
        let given = ShadowLight {
            ratio_rgb: [0.9; 3],
            ..truth
        };
        let (on, est) = run(&mut c, path, true, Some(given), Some(shadowed.as_slice()));
        // The reference: the same pipeline on the frame without the key shadow (nothing to
        // lift there; the twin casts the same shadow with the same light).
        let (reference, _) = run(&mut c, path, true, est, None);
        let est = est.expect("the light");
        // Compared where the shadow was, away from the twin.
        let region = Mask::from_fn(KW, KH, |x, y| {
            let i = (y * KW + x) as usize;
            matte.at(x, y) > 0.05 && !on.twin_mask[i] && !reference.twin_mask[i]
        })
        .expect("mask");
        let img = |f: &ArFrame| ImageRgba8::new(KW, KH, f.rgba8.clone()).expect("image");
        let r = img(&reference);
        let p_off = psnr_rgb(&r, &img(&off), Some(&region)).expect("psnr");
        let p_on = psnr_rgb(&r, &img(&on), Some(&region)).expect("psnr");
        println!(
            "{}: measured ratio {:?}; shadow region {p_off:.1} dB -> {p_on:.1} dB",
            path.name(),
            est.ratio_rgb
        );
        assert!(region.count() > 100, "the shadow is in view");
        assert!(p_on > p_off + 8.0, "{p_on} vs {p_off}");
        assert!(p_on > 30.0, "lifted {p_on}");
    }
}

/// Regression (the generated `shadows` set, seed 1): the key prop's cast shadow falls across
/// the sheet and a tag beside the pedestal, and no light was ever found: the softness was
/// fitted on the medians of the region against its ring, which the tag's black made equal,
/// and every candidate direction was vetoed. Now (pairs of one print across the outline, at
/// several distances; the direction polished where the outline is sharpest) the light of a
/// frame at the true pose is found within 6 degrees of the set's key light, with a darkening
/// of a real shadow, on both paths.
#[test]
fn regression_the_light_is_found_where_the_shadow_crosses_a_tag() {
    let mut renderer = match Renderer::new() {
        Ok(r) => r,
        Err(e) => {
            println!("skipped: no wgpu adapter ({e})");
            return;
        }
    };
    let variant = pa_scene::parse_variant("shadows").expect("variant");
    let spec = SceneSpec {
        seed: 1,
        width: KW,
        height: KH,
        set: variant.set,
        ..SceneSpec::default()
    };
    let scene = Scene::new(spec, &mut renderer).expect("scene");
    let f = scene.frame(&mut renderer, 2).expect("frame");
    let truth = light().toward_light;
    for path in [RenderPath::Gpu, RenderPath::Cpu] {
        let mut p = pipeline_for(&scene, &mut renderer, ArSettings::ours()).expect("pipeline");
        p.set_render_path(path);
        p.set_shadows(true);
        p.process_with_pose(
            &mut renderer,
            &f.input.rgba8,
            KW,
            KH,
            FrameTimes {
                animation_s: f.time_s,
                key_pose_s: 0.0,
            },
            f.camera_from_marker,
        )
        .expect("process");
        let est = p.shadow_light().expect("a light");
        let off = est.toward_light.angle_between(truth).to_degrees();
        let y = 0.2126 * est.ratio_rgb[0] + 0.7152 * est.ratio_rgb[1] + 0.0722 * est.ratio_rgb[2];
        println!("{}: {est:?}, {off:.1} degrees off", path.name());
        assert!(off < 6.0, "{off} degrees off");
        assert!((0.2..0.7).contains(&y), "darkening {y}");
    }
}
