//! Criterion benches of the texture stage at 1280x720 on a frame of the generated scene:
//! texture projection (`Renderer::render_live` of the animated built-in prop, every fragment
//! sampling the live frame at its key-pose projection, with the visibility test) for props of
//! 8k and 128k vertices, and the other GPU work of the stage (the key-pose silhouette render,
//! the visibility map update, the frame upload), plus one whole `ArPipeline` frame with a
//! known pose for scale. Every render includes its GPU -> CPU readback. Skips with a message
//! when no wgpu adapter is available.
//!
//! The CPU path (`pa-raster`) of the same work, side by side: `cpu_key_depth_{8k,128k}` (the
//! key pose's depth: visibility map and silhouette), `cpu_render_live_{8k,128k}` (the
//! live-textured twin with the visibility test), and `ar_frame_with_pose_ours_8k_{gpu,cpu}`.
//!
//! `cargo bench -p pa-pipeline` (add `-- --quick` for a rough figure in seconds).

use std::time::Duration;

use criterion::Criterion;
use glam::Mat4;
use pa_camera::CameraModel;
use pa_model::{anim, Model};
use pa_pipeline::ar::{ArPipeline, ArSettings, FrameTimes, RenderPath};
use pa_pipeline::cpu_twin::CpuTwin;
use pa_pipeline::GpuTwin;
use pa_raster::{CpuRenderer, FrameCamera, FrameSampler, LiveParams, RasterCamera, Shading};
use pa_render::{CpuCamera, CpuTexture, LiveCamera, LiveDraw, LiveTexturing, Renderer};
use pa_scene::scene::marker_from_prop;
use pa_scene::{PropSpec, Scene, SceneSpec};

const W: u32 = 1280;
const H: u32 = 720;

fn criterion() -> Criterion {
    Criterion::default()
        .sample_size(10)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(3))
        .configure_from_args()
}

fn main() {
    let mut r = match Renderer::new() {
        Ok(r) => r,
        Err(e) => {
            println!("skipped: pa-pipeline benches need a wgpu adapter: {e}");
            return;
        }
    };
    let spec = SceneSpec {
        width: W,
        height: H,
        ..SceneSpec::default()
    };
    let scene = Scene::new(spec, &mut r).expect("scene");
    let f = scene.frame(&mut r, 12).expect("frame");
    let camera_from_marker = f.camera_from_marker;
    let camera = CpuCamera {
        intrinsics: scene.intrinsics,
        camera_from_world: camera_from_marker,
        near_m: 0.01,
        far_m: 50.0,
    };
    let camera_model = CameraModel::pinhole(scene.intrinsics);
    let cpu_frame = CpuTexture {
        width: W,
        height: H,
        rgba8: f.input.rgba8.clone(),
    };
    let frame_tex = r.upload_frame(&cpu_frame).expect("upload");
    println!("texture benches: {W}x{H}, {}", r.adapter_info());

    let mut c = criterion();
    let mut g = c.benchmark_group("texture_1280x720");
    g.bench_function("frame_upload", |b| {
        b.iter(|| r.update_texture(&frame_tex, &cpu_frame).expect("update"))
    });

    let big = pa_scene::prop_model(&PropSpec::with_vertex_count(128_000)).expect("prop");
    for (label, model) in [("8k", &scene.model), ("128k", &big)] {
        let model: &Model = model;
        let twin = GpuTwin::upload(&mut r, model).expect("twin");
        let key_pose = anim::sample(model, 0, 0.0);
        let anim_pose = anim::sample(model, 0, f.time_s);
        let key_frame = twin.frame(model, &key_pose, marker_from_prop());
        let anim_frame = twin.frame(model, &anim_pose, marker_from_prop());
        let key_draws = twin.draws(&key_frame);
        if label == "8k" {
            g.bench_function("key_silhouette_render_8k", |b| {
                b.iter(|| {
                    r.render(&camera, None, &key_draws, [0.0; 4], W, H)
                        .expect("render")
                })
            });
        }
        let mut vis = r
            .render_visibility(&camera, &key_draws, W, H)
            .expect("visibility");
        if label == "8k" {
            g.bench_function("visibility_update_8k", |b| {
                b.iter(|| {
                    r.update_visibility(&mut vis, &camera, &key_draws)
                        .expect("visibility")
                })
            });
        }
        let live_camera = LiveCamera::new(camera_model, camera_from_marker);
        let draws: Vec<LiveDraw<'_>> = twin
            .draws(&anim_frame)
            .into_iter()
            .zip(&twin.primitives)
            .map(|(d, p)| {
                let key_joints: &[Mat4] = if p.mesh.is_skinned() {
                    &key_frame.joint_matrices[p.node]
                } else {
                    &[]
                };
                let live =
                    LiveTexturing::new(&frame_tex, live_camera, key_frame.world_from_node[p.node])
                        .with_key_pose(key_joints, &key_frame.morph_weights[p.node])
                        .with_visibility(&vis);
                d.with_live(live)
            })
            .collect();
        g.bench_function(format!("render_live_{label}"), |b| {
            b.iter(|| {
                r.render_live(&camera, None, &draws, [0.0; 4], W, H)
                    .expect("render_live")
            })
        });

        // The same on the CPU path: posed on the CPU, key depth, then the live twin.
        let mut cpu_twin = CpuTwin::new(model).expect("cpu twin");
        cpu_twin.pose(model, &anim_pose, &key_pose, marker_from_prop());
        let raster_camera = RasterCamera::new(&scene.intrinsics, 0.01, 50.0);
        let mut cpu = CpuRenderer::new();
        let key_meshes = cpu_twin.key_depth_meshes(model);
        g.bench_function(format!("cpu_key_depth_{label}"), |b| {
            b.iter(|| {
                cpu.render_key_depth(&raster_camera, camera_from_marker, &key_meshes);
            })
        });
        let mut params = LiveParams::new(FrameCamera::new(&camera_model));
        params.visibility = true;
        let shading = Shading::Live {
            frame: FrameSampler::new(W, H, &f.input.rgba8).expect("frame"),
            params,
        };
        let meshes = cpu_twin.live_meshes(model);
        g.bench_function(format!("cpu_render_live_{label}"), |b| {
            b.iter(|| {
                cpu.render_twin(&raster_camera, camera_from_marker, &meshes, &shading)
                    .counts()
            })
        });
    }

    for path in [RenderPath::Gpu, RenderPath::Cpu] {
        let mut pipeline = ArPipeline::new(
            &mut r,
            scene.model.clone(),
            0,
            camera_model,
            marker_from_prop(),
            None,
            ArSettings::ours(),
        )
        .expect("pipeline");
        pipeline.set_render_path(path);
        g.bench_function(format!("ar_frame_with_pose_ours_8k_{}", path.name()), |b| {
            b.iter(|| {
                pipeline
                    .process_with_pose(
                        &mut r,
                        &f.input.rgba8,
                        W,
                        H,
                        FrameTimes {
                            animation_s: f.time_s,
                            key_pose_s: 0.0,
                        },
                        camera_from_marker,
                    )
                    .expect("frame")
            })
        });
    }
    g.finish();
    c.final_summary();
}
