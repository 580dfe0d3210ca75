//! GPU skinning (the renderer's vertex-stage WGSL function, read back through its compute
//! entry point) matches the CPU reference of `pa-model` on every conformance model and the
//! built-in prop, at every reference time.
//!
//! Tolerance: 1e-5 x the bounding-box diagonal of the posed model (f32 on both sides; the
//! GPU sums the weighted matrices in another order).

use pa_model::{anim, skin, Model};
use pa_pipeline::GpuTwin;
use pa_render::Renderer;

const REL_TOL: f32 = 1e-5;

fn renderer() -> Option<Renderer> {
    match Renderer::new() {
        Ok(r) => Some(r),
        Err(e) => {
            println!("skipped: no wgpu adapter ({e})");
            None
        }
    }
}

/// Compares GPU and CPU posing of `model` at `times`; returns the worst relative error.
fn compare(renderer: &mut Renderer, model: &Model, animation: usize, times: &[f32]) -> f32 {
    let twin = GpuTwin::upload(renderer, model).expect("upload");
    let mut worst = 0f32;
    for &t in times {
        let pose = anim::sample(model, animation, t);
        // The twin uploads each primitive as drawn (a flat-shaded copy for files without
        // normals, whose posing `pa-model` checks against the file-order posing).
        let cpu = skin::pose_drawn_meshes(model, &pose);
        let (lo, hi) = skin::bounds(&cpu).expect("vertices");
        let diag = (hi - lo).length().max(1e-6);
        let frame = twin.frame(model, &pose, glam::Mat4::IDENTITY);
        for p in &twin.primitives {
            let skinned = p.mesh.is_skinned();
            let joints: &[glam::Mat4] = if skinned {
                &frame.joint_matrices[p.node]
            } else {
                &[]
            };
            let gpu = renderer
                .skin_positions_gpu(&p.mesh, joints, &frame.morph_weights[p.node])
                .expect("gpu skinning");
            let expected = cpu
                .iter()
                .find(|c| c.node == p.node && c.primitive == p.primitive)
                .expect("cpu primitive");
            assert_eq!(gpu.len(), expected.positions.len());
            for (i, (g, e)) in gpu.iter().zip(&expected.positions).enumerate() {
                let mut g = glam::Vec3::from_array(*g);
                if !skinned {
                    g = frame.world_from_node[p.node].transform_point3(g);
                }
                let rel = (g - *e).length() / diag;
                worst = worst.max(rel);
                assert!(
                    rel <= REL_TOL,
                    "{} t={t} node {} prim {} vertex {i}: gpu {g} cpu {e} ({rel:.2e})",
                    model.path.display(),
                    p.node,
                    p.primitive
                );
            }
        }
    }
    worst
}

#[test]
fn gpu_skinning_matches_cpu_on_conformance_models() {
    let Some(root) = pa_testkit::conformance_dir() else {
        return;
    };
    let Some(mut renderer) = renderer() else {
        return;
    };
    println!("adapter: {}", renderer.adapter_info());
    let mut refs: Vec<_> = std::fs::read_dir(root.join("skinning-refs"))
        .expect("refs")
        .flatten()
        .map(|e| e.path())
        .collect();
    refs.sort();
    for r in refs {
        let reference = pa_testkit::Reference::load(&r);
        let model = Model::load(pa_testkit::model_file(&root, &reference.source_file))
            .expect("model loads");
        let mut by_anim: std::collections::BTreeMap<usize, Vec<f32>> = Default::default();
        for s in &reference.samples {
            by_anim
                .entry(s.animation)
                .or_default()
                .push(s.time_s as f32);
        }
        let mut worst = 0f32;
        for (a, times) in by_anim {
            worst = worst.max(compare(&mut renderer, &model, a, &times));
        }
        println!(
            "{:<24} worst GPU-CPU error {worst:.2e} of the diagonal",
            reference.source_file
        );
    }
}

#[test]
fn gpu_skinning_matches_cpu_on_the_builtin_prop() {
    let Some(mut renderer) = renderer() else {
        return;
    };
    let model = pa_scene::prop_model(&pa_scene::PropSpec::default()).expect("prop");
    let times: Vec<f32> = (0..=8).map(|k| k as f32 * 0.25).collect();
    let worst = compare(&mut renderer, &model, 0, &times);
    println!("built-in prop: worst GPU-CPU error {worst:.2e} of the diagonal");
}
