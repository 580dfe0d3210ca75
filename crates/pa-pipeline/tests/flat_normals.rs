//! Issue 13, item 0: a model without normals gets live texturing, drawn with the flat normals
//! glTF prescribes, exactly as the same model with those flat normals written into the file.
//!
//! The built-in prop (`pa_scene::prop`) three ways: as generated (smooth normals), with its
//! NORMAL attribute removed from the GLB's JSON, and un-welded with its flat normals written
//! out (computed here, independently of the loader). The last two must give the same output:
//!
//! - on the CPU path (always run): the key depth and the live-textured twin from `pa-raster`,
//!   posed by `CpuTwin`, on a synthetic frame; identical codes and pixels within 1/255;
//! - through the whole frame pipeline on both render paths (only with a wgpu adapter, which
//!   renders the scene's frames): outputs within 1/255, and the prop PSNR against the ground
//!   truth printed next to the untouched frame's.
//!
//! Before the fix the CPU path drew the model without normals with zero normals (every
//! fragment back-facing: no live sample at all); the first test measures that too, by drawing
//! the loaded model with its flat-shaded copy removed.

use glam::{DVec3, Mat4, Vec3};
use pa_camera::{CameraModel, Intrinsics};
use pa_model::{anim, LoadOptions, Model};
use pa_pipeline::cpu_twin::CpuTwin;
use pa_pipeline::metrics::psnr_region;
use pa_raster::{code, CpuRenderer, FrameCamera, FrameSampler, LiveParams, RasterCamera, Shading};
use pa_scene::prop::{prop_glb, prop_mesh, PropSpec};
use pa_scene::scene::marker_from_prop;
use serde_json::{json, Value};

/// The GLB's JSON and binary chunk.
fn split_glb(glb: &[u8]) -> (Value, Vec<u8>) {
    let u32_at = |at: usize| u32::from_le_bytes(glb[at..at + 4].try_into().expect("4 bytes"));
    let json_len = u32_at(12) as usize;
    let doc = serde_json::from_slice(&glb[20..20 + json_len]).expect("json chunk");
    let bin_at = 20 + json_len;
    let bin_len = u32_at(bin_at) as usize;
    (doc, glb[bin_at + 8..bin_at + 8 + bin_len].to_vec())
}

fn load(glb: &[u8], name: &str) -> Model {
    Model::from_slice(glb, name, None, &LoadOptions::default()).expect("loads")
}

/// The built-in prop: (smooth normals, NORMAL removed, un-welded with flat normals written).
fn three_props(spec: &PropSpec) -> (Model, Model, Model) {
    let glb = prop_glb(spec).expect("prop");
    let smooth = load(&glb, "smooth.glb");
    let (doc, bin) = split_glb(&glb);

    let mut without = doc.clone();
    let attributes = &mut without["meshes"][0]["primitives"][0]["attributes"];
    attributes
        .as_object_mut()
        .expect("attributes")
        .remove("NORMAL")
        .expect("the prop has NORMAL");
    let without =
        pa_model::export::glb_container(&without, bin.clone()).expect("GLB without normals");

    // Un-welded: corner k of triangle t is vertex 3t + k, with the triangle's normal.
    let mesh = prop_mesh(spec);
    let corners: Vec<usize> = mesh.indices.iter().map(|&i| i as usize).collect();
    let positions: Vec<Vec3> = corners.iter().map(|&i| mesh.positions[i]).collect();
    let normals: Vec<Vec3> = positions
        .chunks_exact(3)
        .flat_map(|t| {
            let [a, b, c] = [t[0], t[1], t[2]].map(|p| p.as_dvec3());
            // The pole fans have degenerate triangles: +Z there, the loader's convention.
            let n: DVec3 = (b - a).cross(c - a).try_normalize().unwrap_or(DVec3::Z);
            [n.as_vec3(); 3]
        })
        .collect();
    let mut flat = doc;
    let mut bin = bin;
    let mut add = |doc: &mut Value, data: Vec<u8>, accessor: Value| -> usize {
        while !bin.len().is_multiple_of(4) {
            bin.push(0);
        }
        let views = doc["bufferViews"].as_array_mut().expect("views");
        views.push(json!({"buffer": 0, "byteOffset": bin.len(), "byteLength": data.len()}));
        let view = views.len() - 1;
        bin.extend(data);
        let mut accessor = accessor;
        accessor["bufferView"] = json!(view);
        let accessors = doc["accessors"].as_array_mut().expect("accessors");
        accessors.push(accessor);
        accessors.len() - 1
    };
    let f32s = |xs: Vec<f32>| -> Vec<u8> { xs.into_iter().flat_map(f32::to_le_bytes).collect() };
    let n = corners.len();
    let (lo, hi) = positions.iter().fold(
        (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN)),
        |(l, h), p| (l.min(*p), h.max(*p)),
    );
    let pos = add(
        &mut flat,
        f32s(positions.iter().flat_map(|p| p.to_array()).collect()),
        json!({"componentType": 5126, "count": n, "type": "VEC3",
            "min": lo.to_array(), "max": hi.to_array()}),
    );
    let nrm = add(
        &mut flat,
        f32s(normals.iter().flat_map(|p| p.to_array()).collect()),
        json!({"componentType": 5126, "count": n, "type": "VEC3"}),
    );
    let uv = add(
        &mut flat,
        f32s(
            corners
                .iter()
                .flat_map(|&i| mesh.uvs[i].to_array())
                .collect(),
        ),
        json!({"componentType": 5126, "count": n, "type": "VEC2"}),
    );
    let joints = add(
        &mut flat,
        corners.iter().flat_map(|&i| mesh.joints[i]).collect(),
        json!({"componentType": 5121, "count": n, "type": "VEC4"}),
    );
    let weights = add(
        &mut flat,
        f32s(corners.iter().flat_map(|&i| mesh.weights[i]).collect()),
        json!({"componentType": 5126, "count": n, "type": "VEC4"}),
    );
    let indices = add(
        &mut flat,
        (0..n as u32).flat_map(u32::to_le_bytes).collect(),
        json!({"componentType": 5125, "count": n, "type": "SCALAR"}),
    );
    flat["meshes"][0]["primitives"][0]["attributes"] = json!({"POSITION": pos, "NORMAL": nrm,
        "TEXCOORD_0": uv, "JOINTS_0": joints, "WEIGHTS_0": weights});
    flat["meshes"][0]["primitives"][0]["indices"] = json!(indices);
    flat["buffers"][0]["byteLength"] = json!(bin.len());
    let flat = pa_model::export::glb_container(&flat, bin).expect("GLB with flat normals");
    (
        smooth,
        load(&without, "without_normals.glb"),
        load(&flat, "flat_normals_written.glb"),
    )
}

/// What the renderers drew before the fix: the primitive's own (welded) vertices without
/// normals (the CPU path: zero normals; the GPU path: `pa-render`'s smooth normals).
fn before_the_fix(model: &Model) -> Model {
    let mut old = model.clone();
    for p in old.meshes.iter_mut().flat_map(|m| &mut m.primitives) {
        p.flat_shaded = None;
    }
    old
}

const W: u32 = 320;
const H: u32 = 240;

/// A camera in front of and above the prop (OpenCV axes; world = marker frame, -Z up).
fn camera_from_marker() -> Mat4 {
    let eye = Vec3::new(0.06, 0.42, -0.22);
    let target = Vec3::new(0.0, 0.0, -0.1);
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
fn render_cpu(model: &Model, frame: &[u8]) -> (Vec<u8>, Vec<u8>) {
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
    twin.pose(model, &animated, &key, marker_from_prop());
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

fn max_channel_diff(a: &[u8], b: &[u8]) -> u8 {
    a.iter()
        .zip(b)
        .map(|(x, y)| x.abs_diff(*y))
        .max()
        .unwrap_or(0)
}

fn count(codes: &[u8], c: u8) -> usize {
    codes.iter().filter(|&&x| x == c).count()
}

#[test]
fn cpu_path_draws_a_model_without_normals_as_with_flat_normals_written_out() {
    let spec = PropSpec::default();
    let (smooth, without, flat) = three_props(&spec);

    // The loader's flat-shaded copy is the file with flat normals written, vertex for vertex.
    let d = without.meshes[0].primitives[0].drawn();
    let f = &flat.meshes[0].primitives[0];
    assert!(without.meshes[0].primitives[0].flat_shaded.is_some());
    assert_eq!(d.positions, f.positions);
    assert_eq!(d.uvs, f.uvs);
    assert_eq!(d.joints, f.joints);
    assert_eq!(d.weights, f.weights);
    assert_eq!(d.indices, f.indices);
    let normal_diff = d
        .normals
        .iter()
        .zip(&f.normals)
        .map(|(a, b)| (*a - *b).length())
        .fold(0f32, f32::max);
    assert!(normal_diff < 1e-6, "normals differ by {normal_diff}");

    let frame = live_frame();
    let (rgba_without, codes_without) = render_cpu(&without, &frame);
    let (rgba_flat, codes_flat) = render_cpu(&flat, &frame);
    let (rgba_smooth, codes_smooth) = render_cpu(&smooth, &frame);

    let (rgba_old, codes_old) = render_cpu(&before_the_fix(&without), &frame);

    let twin: Vec<bool> = codes_flat.iter().map(|&c| c != code::NONE).collect();
    let pixels = twin.iter().filter(|&&t| t).count();
    let valid = count(&codes_flat, code::VALID);
    let differing = rgba_without
        .chunks_exact(4)
        .zip(rgba_flat.chunks_exact(4))
        .filter(|(a, b)| a != b)
        .count();
    let max_diff = max_channel_diff(&rgba_without, &rgba_flat);
    let psnr_same = psnr_region(&rgba_without, &rgba_flat, &twin);
    let psnr_old = psnr_region(&rgba_old, &rgba_flat, &twin);
    let psnr_smooth = psnr_region(&rgba_smooth, &rgba_flat, &twin);
    println!(
        "CPU path, {W}x{H}: twin {pixels} px, live samples {valid} (without normals {}, \
         before the fix {}, smooth normals {}); without vs written flat: {differing} pixels \
         differ, max channel difference {max_diff}/255, PSNR {psnr_same:?} dB; before the fix \
         vs written flat: PSNR {psnr_old:?} dB; smooth vs flat: PSNR {psnr_smooth:?} dB",
        count(&codes_without, code::VALID),
        count(&codes_old, code::VALID),
        count(&codes_smooth, code::VALID),
    );
    assert!(
        pixels > 5_000,
        "the prop fills part of the frame ({pixels} px)"
    );
    assert!(valid > pixels / 3, "live samples: {valid} of {pixels}");
    assert_eq!(codes_without, codes_flat, "the same sample codes");
    assert!(max_diff <= 1, "pixels within 1/255 (max {max_diff})");
    // The bug this fixes: without normals, no live sample at all.
    assert_eq!(count(&codes_old, code::VALID), 0);
}

/// The whole frame pipeline on the scene's frames (true camera pose, clean plate), on both
/// render paths: the model without normals gives the output of the model with the flat
/// normals written out. Needs a wgpu adapter (the scene's frames are rendered on the GPU).
#[test]
fn pipeline_output_without_normals_is_the_output_with_flat_normals_written_out() {
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
    let (smooth, without, flat) = three_props(&PropSpec::default());
    let camera = CameraModel::pinhole(scene.intrinsics);
    let (plate, plate_pose) = scene.clean_plate(&mut renderer).expect("plate");
    let plate =
        pa_diminish::ImageRgba8::new(plate.width, plate.height, plate.rgba8).expect("plate image");
    let old = before_the_fix(&without);
    println!("adapter: {}", renderer.adapter_info());
    for path in [RenderPath::Cpu, RenderPath::Gpu] {
        let mut pipelines: Vec<ArPipeline> = [&without, &flat, &smooth, &old]
            .into_iter()
            .map(|m| {
                let mut p = ArPipeline::new(
                    &mut renderer,
                    m.clone(),
                    0,
                    camera,
                    marker_from_prop(),
                    None,
                    ArSettings::ours(),
                )
                .expect("pipeline");
                p.set_render_path(path);
                p.set_clean_plate(plate.clone(), plate_pose);
                p
            })
            .collect();
        let (mut worst, mut differing, mut same_codes) = (0u8, 0usize, true);
        let mut psnr = [0f64; 5];
        let frames = [6u32, 12, 18];
        for &i in &frames {
            let f = scene.frame(&mut renderer, i).expect("frame");
            let key_time = scene.spec.key_frames[f.key] as f32 / scene.spec.fps;
            let truth = scene
                .prop_mask(&mut renderer, f.camera_from_marker, f.time_s)
                .expect("mask");
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
            worst = worst.max(max_channel_diff(&outs[0].rgba8, &outs[1].rgba8));
            differing += outs[0]
                .rgba8
                .chunks_exact(4)
                .zip(outs[1].rgba8.chunks_exact(4))
                .filter(|(a, b)| a != b)
                .count();
            same_codes &= outs[0].live_codes == outs[1].live_codes;
            let gt = &f.ground_truth.rgba8;
            let images = outs.iter().map(|o| &o.rgba8).chain([&f.input.rgba8]);
            for (k, rgba) in images.enumerate() {
                psnr[k] += psnr_region(rgba, gt, &truth).unwrap_or(f64::INFINITY);
            }
        }
        let m = psnr.map(|s| s / frames.len() as f64);
        println!(
            "{} path, frames {frames:?}: without vs written flat normals: {differing} pixels \
             differ, max channel difference {worst}/255, same codes {same_codes}; mean prop \
             PSNR: without normals {:.3} dB, flat normals written {:.3} dB, smooth normals \
             {:.3} dB, before the fix {:.3} dB, untouched input {:.3} dB",
            path.name(),
            m[0],
            m[1],
            m[2],
            m[3],
            m[4]
        );
        assert!(worst <= 1, "{}: max difference {worst}/255", path.name());
        assert!(same_codes, "{}: the same sample codes", path.name());
        assert!(
            (m[0] - m[1]).abs() < 0.05,
            "{}: PSNR {:.2} vs {:.2}",
            path.name(),
            m[0],
            m[1]
        );
    }
}
