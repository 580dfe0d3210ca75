//! Golden images of the frame pipeline on a small generated scene: the live texturing (with
//! and without the visibility fallback, plain, relit with feathered seams and the sun (ours),
//! and relit with the first-order light; no diminishing) and each fill (the paper's rectangle, our ray fill, the clean plate, the patch
//! fill; the twin as ours), composited over the same frame.
//!
//! The scene is 192x108 (2x2 supersampled), seed 3, with the key prop of animation frame 0
//! and the in-between of frame 20 (the head turned about 38 degrees), seen from the true
//! camera pose (no tracker, so nothing depends on detection). Tolerance: every channel within
//! 2/255 on at least 99.5 % of the pixels, as the renderer's goldens (measured: lavapipe
//! against llvmpipe differ by at most 1/255 here). Both renderers of the texture stage (wgpu
//! and our CPU rasteriser) must match the same goldens. `UPDATE_GOLDEN=1` rewrites the
//! goldens in `tests/golden/`; a failure writes `target/golden-failures/<name>.{actual,diff}.png`.

use std::path::PathBuf;

use pa_pipeline::ar::{ArFrame, ArSettings, Fill, LiveLook, RenderPath, Texturing};
use pa_render::Renderer;
use pa_scene::eval::pipeline_for;
use pa_scene::{Scene, SceneSpec};
use pa_testkit::golden::{assert_golden_in, Goldens, Tolerance};

const W: u32 = 192;
const H: u32 = 108;
const FRAME: u32 = 20;

const TOLERANCE: Tolerance = Tolerance::DEFAULT;

fn run(renderer: &mut Renderer, scene: &Scene, settings: ArSettings, path: RenderPath) -> ArFrame {
    let mut p = pipeline_for(scene, renderer, settings).expect("pipeline");
    p.set_render_path(path);
    let f = scene.frame(renderer, FRAME).expect("frame");
    pa_scene::eval::process_at_true_pose(&mut p, renderer, &f).expect("process")
}

fn golden(renderer: &Renderer, name: &str, out: &ArFrame) {
    let goldens = Goldens::for_adapter(
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/golden"),
        &renderer.adapter_info(),
        renderer.is_software(),
    );
    assert_golden_in(&goldens, name, W, H, &out.rgba8, TOLERANCE);
}

#[test]
fn texturing_and_fills_match_their_goldens() {
    let mut renderer = match Renderer::new() {
        Ok(r) => r,
        Err(e) => {
            println!("skipped: no wgpu adapter ({e})");
            return;
        }
    };
    let spec = SceneSpec {
        seed: 3,
        width: W,
        height: H,
        frames: FRAME + 1,
        ..SceneSpec::default()
    };
    let scene = Scene::new(spec, &mut renderer).expect("scene");
    let ours = ArSettings::ours();
    let cases = [
        (
            "ar_texture_live_visibility",
            ArSettings {
                fill: Fill::None,
                look: LiveLook::PLAIN,
                ..ours
            },
        ),
        (
            "ar_texture_live_relit",
            ArSettings {
                fill: Fill::None,
                ..ours
            },
        ),
        (
            "ar_texture_live_first_order",
            ArSettings {
                fill: Fill::None,
                look: LiveLook {
                    sun: false,
                    ..LiveLook::RELIT_FEATHERED
                },
                ..ours
            },
        ),
        (
            "ar_texture_live_paper",
            ArSettings {
                texturing: Texturing::Live { visibility: false },
                fill: Fill::None,
                anti_alias: false,
                ..ours
            },
        ),
        ("ar_fill_rectangle", ArSettings::paper()),
        ("ar_fill_rays", ours),
        (
            "ar_fill_clean_plate",
            ArSettings {
                fill: Fill::CleanPlate,
                ..ours
            },
        ),
        (
            "ar_fill_patch",
            ArSettings {
                fill: Fill::Patch { plate: false },
                ..ours
            },
        ),
    ];
    let mut outputs = Vec::new();
    for (name, settings) in cases {
        for path in [RenderPath::Gpu, RenderPath::Cpu] {
            println!("{name}: {} path", path.name());
            let out = run(&mut renderer, &scene, settings, path);
            golden(&renderer, name, &out);
            if path == RenderPath::Cpu {
                outputs.push(out);
            }
        }
    }
    // The goldens differ where they should: the fallback changes the twin, each fill the
    // background around it (guards against a golden accidentally shared by two cases).
    let differing = |a: &ArFrame, b: &ArFrame| {
        a.rgba8
            .chunks_exact(4)
            .zip(b.rgba8.chunks_exact(4))
            .filter(|(p, q)| p.iter().zip(q.iter()).any(|(x, y)| x.abs_diff(*y) > 8))
            .count()
    };
    for i in 0..outputs.len() {
        for j in i + 1..outputs.len() {
            let d = differing(&outputs[i], &outputs[j]);
            assert!(d > 50, "cases {i} and {j} differ in only {d} pixels");
        }
    }
}
