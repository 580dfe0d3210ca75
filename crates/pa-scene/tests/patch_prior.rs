//! The pipeline's patch fill keeps the previous frame's result as its prior and forgets it
//! with the tracker: on a generated scene seen by a handheld camera, the second frame's fill,
//! compared with the first frame's warped into it by the table-plane homography, changes less
//! than an independent fill of the second frame does, and after `reset_tracker` the pipeline
//! fills exactly as a fresh one.

use pa_camera::CameraModel;
use pa_pipeline::ar::{plane_homography, ArFrame, ArPipeline, ArSettings, Fill, RenderPath};
use pa_render::Renderer;
use pa_scene::eval::pipeline_for;
use pa_scene::scene::{CameraPath, SceneFrame};
use pa_scene::{Scene, SceneSpec};

const W: u32 = 192;
const H: u32 = 108;

fn process(p: &mut ArPipeline, renderer: &mut Renderer, f: &SceneFrame) -> ArFrame {
    pa_scene::eval::process_at_true_pose(p, renderer, f).expect("process")
}

/// Mean squared difference over R, G, B of the pixels where `mask` is set.
fn mse(a: &[u8], b: &[u8], mask: &[bool]) -> f64 {
    let (mut sum, mut n) = (0.0, 0usize);
    for ((p, q), &m) in a.chunks_exact(4).zip(b.chunks_exact(4)).zip(mask) {
        if m {
            for c in 0..3 {
                let d = f64::from(p[c]) - f64::from(q[c]);
                sum += d * d;
            }
            n += 1;
        }
    }
    sum / (3 * n.max(1)) as f64
}

#[test]
fn the_patch_fill_is_steady_over_frames_and_forgets_with_the_tracker() {
    let mut renderer = match Renderer::new() {
        Ok(r) => r,
        Err(e) => {
            println!("skipped: no wgpu adapter ({e})");
            return;
        }
    };
    let spec = SceneSpec {
        seed: 5,
        width: W,
        height: H,
        frames: 24,
        camera_path: CameraPath::Handheld,
        ..SceneSpec::default()
    };
    let scene = Scene::new(spec, &mut renderer).expect("scene");
    let settings = ArSettings {
        fill: Fill::Patch { plate: false },
        ..ArSettings::ours()
    };
    // Frames 20 and 21: the camera and the twin moved a little.
    let f20 = scene.frame(&mut renderer, 20).expect("frame");
    let f21 = scene.frame(&mut renderer, 21).expect("frame");
    let mut p = pipeline_for(&scene, &mut renderer, settings).expect("pipeline");
    p.set_render_path(RenderPath::Cpu);
    p.set_keep_passes(true);
    let a = process(&mut p, &mut renderer, &f20);
    let with_prior = process(&mut p, &mut renderer, &f21);
    // The same frame 21 filled without a prior: a fresh pipeline.
    let mut fresh = pipeline_for(&scene, &mut renderer, settings).expect("pipeline");
    fresh.set_render_path(RenderPath::Cpu);
    fresh.set_keep_passes(true);
    let alone = process(&mut fresh, &mut renderer, &f21);
    let plate = |f: &ArFrame| f.passes.as_ref().expect("passes").plate_rgba8.clone();
    // Frame 20's plate seen from frame 21 (nearest pixel through the table-plane homography),
    // on the pixels both frames filled.
    let camera = CameraModel::pinhole(scene.intrinsics);
    let h = plane_homography(&camera, f21.camera_from_marker, f20.camera_from_marker).inverse();
    let (p20, w) = (plate(&a), W as usize);
    let mut warped = vec![0u8; p20.len()];
    let mut both = vec![false; (W * H) as usize];
    for y in 0..H as usize {
        for x in 0..w {
            let q = h * glam::DVec3::new(x as f64, y as f64, 1.0);
            let (sx, sy) = ((q.x / q.z).round(), (q.y / q.z).round());
            if !(0.0..W as f64).contains(&sx) || !(0.0..H as f64).contains(&sy) {
                continue;
            }
            let s = sy as usize * w + sx as usize;
            let i = y * w + x;
            both[i] = a.key_mask[s] && with_prior.key_mask[i];
            warped[i * 4..i * 4 + 4].copy_from_slice(&p20[s * 4..s * 4 + 4]);
        }
    }
    assert!(
        both.iter().filter(|&&b| b).count() > 500,
        "the prop covers the scene"
    );
    let steady = mse(&warped, &plate(&with_prior), &both);
    let independent = mse(&warped, &plate(&alone), &both);
    println!(
        "frame-to-frame change of the fill (MSE): with prior {steady:.1}, without {independent:.1}"
    );
    assert!(
        steady * 2.0 < independent,
        "with prior {steady:.1} is not half of without {independent:.1}"
    );
    // After the reset the pipeline has no prior: frame 21 is filled as by a fresh pipeline.
    p.reset_tracker();
    let after_reset = process(&mut p, &mut renderer, &f21);
    assert_eq!(plate(&after_reset), plate(&alone));
}
