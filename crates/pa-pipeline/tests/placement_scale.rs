//! Issue 16, item 5: `[placement] scale` scales the model uniformly about its origin, in
//! `marker_from_prop`, so every consumer sees it. The truth is the model with every length
//! scaled by hand (vertex positions and morph deltas, node translations, the translations of
//! the inverse bind matrices and of the animation): placed at scale 1, it must look exactly
//! like the original model placed with `scale = K`.
//!
//! - CPU path (always run): the key depth and the live-textured twin from `pa-raster`, posed
//!   by `CpuTwin`, with a normal-dependent fallback light so that a wrong normal shows;
//! - the whole frame pipeline on both render paths (only with a wgpu adapter, which renders
//!   the scene's frames): outputs of the two models within 1/255 where both cover the pixel.
//!
//! Each test also checks that it can fail: the scaled model at scale 1 against the original
//! model at scale 1 differs in most of the twin's pixels.

use glam::{Mat4, Vec3};
use pa_camera::{CameraModel, Intrinsics};
use pa_model::{anim, LoadOptions, LocalTransform, Model, Primitive, Property};
use pa_pipeline::cpu_twin::CpuTwin;
use pa_pipeline::shot::Placement;
use pa_raster::{code, CpuRenderer, FrameCamera, FrameSampler, LiveParams, RasterCamera, Shading};
use pa_scene::prop::{prop_glb, PropSpec};

const K: f32 = 0.75;
const W: u32 = 320;
const H: u32 = 240;

fn bust() -> Model {
    let glb = prop_glb(&PropSpec::default()).expect("prop");
    Model::from_slice(&glb, "bust.glb", None, &LoadOptions::default()).expect("loads")
}

fn scale_primitive(p: &mut Primitive, k: f32) {
    for v in &mut p.positions {
        *v *= k;
    }
    for t in &mut p.morph_targets {
        for d in &mut t.position_deltas {
            *d *= k;
        }
    }
    if let Some(flat) = p.flat_shaded.as_deref_mut() {
        scale_primitive(flat, k);
    }
}

/// The model with every length multiplied by `k` (the conjugation of every transform by the
/// scale): what an artist gets by scaling the model in Blender and applying the scale.
fn scaled_by_hand(model: &Model, k: f32) -> Model {
    let mut m = model.clone();
    for p in m.meshes.iter_mut().flat_map(|m| &mut m.primitives) {
        scale_primitive(p, k);
    }
    for n in &mut m.nodes {
        match &mut n.local {
            LocalTransform::Trs(t) => t.translation *= k,
            LocalTransform::Matrix(mat) => mat.w_axis = (mat.w_axis.truncate() * k).extend(1.0),
        }
    }
    for s in &mut m.skins {
        for ibm in &mut s.inverse_bind_matrices {
            ibm.w_axis = (ibm.w_axis.truncate() * k).extend(1.0);
        }
    }
    for c in m.animations.iter_mut().flat_map(|a| &mut a.channels) {
        if c.property == Property::Translation {
            for v in &mut c.sampler.values {
                *v *= k;
            }
        }
    }
    m
}

fn placement(scale: f32) -> Placement {
    Placement {
        translation_m: [0.004, -0.006, 0.0],
        yaw_deg: 25.0,
        scale,
        ..Placement::default()
    }
}

/// A camera in front of and above the prop (OpenCV axes; world = marker frame, -Z up).
fn camera_from_marker() -> Mat4 {
    let eye = Vec3::new(0.06, 0.42, -0.22);
    let target = Vec3::new(0.0, 0.0, -0.08);
    let up = Vec3::NEG_Z;
    let z = (target - eye).normalize();
    let x = z.cross(up).normalize();
    let y = z.cross(x);
    Mat4::from_cols(x.extend(0.0), y.extend(0.0), z.extend(0.0), eye.extend(1.0)).inverse()
}

/// A smooth, colourful live frame.
fn live_frame() -> Vec<u8> {
    let mut f = Vec::with_capacity((W * H * 4) as usize);
    for y in 0..H {
        for x in 0..W {
            let (x, y) = (x as f32, y as f32);
            let v = |s: f32| (128.0 + 100.0 * s.sin()).round() as u8;
            f.extend([v(x / 9.0), v(y / 7.0), v((x + y) / 13.0), 255]);
        }
    }
    f
}

/// The live-textured twin on the CPU path: (RGBA8, codes).
fn render_cpu(model: &Model, marker_from_prop: Mat4, frame: &[u8]) -> (Vec<u8>, Vec<u8>) {
    let k = Intrinsics {
        fx: 420.0,
        fy: 420.0,
        cx: f64::from(W) / 2.0 - 0.5,
        cy: f64::from(H) / 2.0 - 0.5,
        width: W,
        height: H,
    };
    let camera_from_world = camera_from_marker();
    let key = anim::sample(model, 0, 0.0);
    let animated = anim::sample(model, 0, 1.3);
    let mut twin = CpuTwin::new(model).expect("cpu twin");
    twin.pose(model, &animated, &key, marker_from_prop);
    let camera = RasterCamera::new(&k, 0.01, 50.0);
    let mut cpu = CpuRenderer::new();
    cpu.render_key_depth(&camera, camera_from_world, &twin.key_depth_meshes(model));
    let mut params = LiveParams::new(FrameCamera::new(&CameraModel::pinhole(k)));
    params.visibility = true;
    params.max_stretch = 3.0;
    // A fallback that depends on the normal, so the normals show in every pixel.
    params.fallback_irradiance = [
        [0.6, 0.2, -0.3, -0.25],
        [0.55, 0.1, -0.2, -0.3],
        [0.5, -0.1, -0.25, -0.2],
    ];
    let shading = Shading::Live {
        frame: FrameSampler::new(W, H, frame).expect("frame"),
        params,
    };
    let img = cpu.render_twin(
        &camera,
        camera_from_world,
        &twin.live_meshes(model),
        &shading,
    );
    (img.rgba8.clone(), img.codes.clone())
}

/// (pixels whose RGBA differ, largest channel difference over the pixels both images cover
/// with the same code, pixels whose code differs).
fn compare(a: &(Vec<u8>, Vec<u8>), b: &(Vec<u8>, Vec<u8>)) -> (usize, u8, usize) {
    let mut differing = 0;
    let mut worst = 0u8;
    let mut codes = 0;
    for (i, (pa, pb)) in a.0.chunks_exact(4).zip(b.0.chunks_exact(4)).enumerate() {
        differing += usize::from(pa != pb);
        if a.1[i] != b.1[i] {
            codes += 1;
        } else {
            let d = pa.iter().zip(pb).map(|(x, y)| x.abs_diff(*y)).max();
            worst = worst.max(d.unwrap_or(0));
        }
    }
    (differing, worst, codes)
}

#[test]
fn the_scaled_by_hand_model_is_the_model_scaled() {
    let model = bust();
    let scaled = scaled_by_hand(&model, K);
    for t in [0.0, 0.7, 1.3] {
        let a = pa_model::skin::pose_meshes(&model, &anim::sample(&model, 0, t));
        let b = pa_model::skin::pose_meshes(&scaled, &anim::sample(&scaled, 0, t));
        for (pa, pb) in a.iter().zip(&b) {
            for (va, vb) in pa.positions.iter().zip(&pb.positions) {
                assert!((*va * K - *vb).length() < 1e-6, "t {t}: {va} vs {vb}");
            }
            for (na, nb) in pa.normals.iter().zip(&pb.normals) {
                assert!((*na - *nb).length() < 1e-5, "t {t}: {na} vs {nb}");
            }
        }
    }
}

#[test]
fn cpu_path_scale_is_the_model_with_its_vertices_scaled() {
    let model = bust();
    let scaled = scaled_by_hand(&model, K);
    let frame = live_frame();
    let with_scale = render_cpu(&model, placement(K).marker_from_prop(), &frame);
    let by_hand = render_cpu(&scaled, placement(1.0).marker_from_prop(), &frame);
    let unscaled = render_cpu(&model, placement(1.0).marker_from_prop(), &frame);
    let twin = by_hand.1.iter().filter(|&&c| c != code::NONE).count();
    let valid = by_hand.1.iter().filter(|&&c| c == code::VALID).count();
    let (differing, worst, codes) = compare(&with_scale, &by_hand);
    let (differing_unscaled, _, codes_unscaled) = compare(&unscaled, &by_hand);
    println!(
        "CPU path, {W}x{H}, scale {K}: twin {twin} px ({valid} live samples); scale in the \
         placement vs scaled by hand: {differing} pixels differ, {codes} codes differ, max \
         channel difference {worst}/255 elsewhere; unscaled vs scaled by hand: \
         {differing_unscaled} pixels and {codes_unscaled} codes differ"
    );
    assert!(twin > 4_000, "the prop fills part of the frame ({twin} px)");
    assert!(valid > twin / 3, "live samples: {valid} of {twin}");
    assert!(codes <= twin / 500, "{codes} codes differ");
    assert!(worst <= 1, "pixels within 1/255 (max {worst})");
    // The comparison can fail: without the scale, most of the twin differs.
    assert!(differing_unscaled > twin / 2, "{differing_unscaled}");
}

/// The whole frame pipeline on the scene's frames (true camera pose, clean plate), on both
/// render paths. Needs a wgpu adapter (the scene's frames are rendered on the GPU).
#[test]
fn pipeline_output_with_scale_is_the_output_of_the_scaled_model() {
    use pa_pipeline::ar::{ArPipeline, ArSettings, FrameTimes, RenderPath};
    use pa_render::Renderer;
    use pa_scene::{Scene, SceneSpec};

    let mut renderer = match Renderer::new() {
        Ok(r) => r,
        Err(e) => {
            println!("skipped: no wgpu adapter ({e})");
            return;
        }
    };
    let spec = SceneSpec {
        width: 320,
        height: 180,
        frames: 24,
        ..SceneSpec::default()
    };
    let scene = Scene::new(spec, &mut renderer).expect("scene");
    let model = bust();
    let scaled = scaled_by_hand(&model, K);
    let camera = CameraModel::pinhole(scene.intrinsics);
    let (plate, plate_pose) = scene.clean_plate(&mut renderer).expect("plate");
    let plate =
        pa_diminish::ImageRgba8::new(plate.width, plate.height, plate.rgba8).expect("plate image");
    println!("adapter: {}", renderer.adapter_info());
    for path in [RenderPath::Cpu, RenderPath::Gpu] {
        let mut pipelines: Vec<ArPipeline> = [
            (&model, placement(K)),
            (&scaled, placement(1.0)),
            (&model, placement(1.0)),
        ]
        .into_iter()
        .map(|(m, place)| {
            let mut p = ArPipeline::new(
                &mut renderer,
                m.clone(),
                0,
                camera,
                place.marker_from_prop(),
                None,
                ArSettings::ours(),
            )
            .expect("pipeline");
            p.set_render_path(path);
            p.set_clean_plate(plate.clone(), plate_pose);
            p
        })
        .collect();
        let (mut worst, mut differing, mut codes, mut differing_unscaled, mut twin) =
            (0u8, 0usize, 0usize, 0usize, 0usize);
        for i in [6u32, 12, 18] {
            let f = scene.frame(&mut renderer, i).expect("frame");
            let key_time = scene.spec.key_frames[f.key] as f32 / scene.spec.fps;
            let outs: Vec<_> = pipelines
                .iter_mut()
                .map(|p| {
                    p.process_with_pose(
                        &mut renderer,
                        &f.input.rgba8,
                        f.input.width,
                        f.input.height,
                        FrameTimes {
                            animation_s: f.time_s,
                            key_pose_s: key_time,
                        },
                        f.camera_from_marker,
                    )
                    .expect("process")
                })
                .collect();
            let a = (outs[0].rgba8.clone(), outs[0].live_codes.clone());
            let b = (outs[1].rgba8.clone(), outs[1].live_codes.clone());
            let c = (outs[2].rgba8.clone(), outs[2].live_codes.clone());
            let (d, w, k) = compare(&a, &b);
            differing += d;
            worst = worst.max(w);
            codes += k;
            differing_unscaled += compare(&c, &b).0;
            twin += b.1.iter().filter(|&&c| c != code::NONE).count();
        }
        println!(
            "{} path, scale {K}, frames 6, 12, 18: twin {twin} px; scale in the placement vs \
             scaled by hand: {differing} pixels differ, {codes} codes differ, max channel \
             difference {worst}/255 elsewhere; unscaled vs scaled by hand: {differing_unscaled} \
             pixels differ",
            path.name()
        );
        assert!(twin > 3_000, "{}: twin {twin} px", path.name());
        assert!(codes <= twin / 200, "{}: {codes} codes differ", path.name());
        assert!(worst <= 1, "{}: max difference {worst}/255", path.name());
        assert!(
            differing_unscaled > twin / 2,
            "{}: {differing_unscaled}",
            path.name()
        );
    }
}
