//! Live texturing from the camera frame (`Renderer::render_live`): the animated twin takes its
//! colours from the frame at the projection of the same surface point in the key pose.
//!
//! Tolerances (8-bit sRGB channel differences; "interior" = covered pixels whose 8 neighbours
//! are covered by the same surface too, i.e. the silhouette eroded by 1 px):
//!
//! * identity (key pose = animated pose, frame = this renderer's own unlit render): on the
//!   interior, mean abs diff < 0.5/255 and 99.9% of pixels within 2/255 (the frame is sampled
//!   at its own pixel centres, so only float error remains), and >= 97% of the interior has a
//!   valid live sample;
//! * rigid motion (checker quad, frame at pose A, rendered at pose B): at every checker cell
//!   centre (cells of 8x8 texels) the live colour equals the cell colour within 3/255; over the
//!   interior the mean abs diff to the direct render at B is < 2/255 (cell edges are resampled
//!   twice, so no per-pixel bound there);
//! * skinned (smooth texture, frame at the straight key pose; direct textured render at the
//!   animated pose as ground truth): over the interior pixels with a valid live sample, mean
//!   abs diff < 1.5/255 and 99% within 6/255; with the fallback gain 1 (fallback = own
//!   texture) the whole interior has mean < 2/255. A 45 degree bend in the image plane keeps
//!   at least 97% valid; a 30 degree bend plus a 100 degree twist about the bone turns
//!   key-pose back points to the camera: 40-85% valid, the rest fallback;
//! * distortion (frame = undistorted render warped on the CPU through pa_camera's distortion):
//!   mean abs diff < 1.5/255 and 99% within 6/255 on the interior; the same frame read without
//!   the distortion model must be off by > 4x that mean (the test can see a wrong model);
//! * visibility: on interior pixels, every key-pose point hidden behind the front quad is
//!   `Occluded` and coloured albedo * gain within 1/255, every visible one `Valid` with the
//!   frame colour within 1/255; a part facing away in the key pose is all `BackFacing`, a part
//!   outside the frame in the key pose is all `Outside`.

mod common;

use std::time::Instant;

use glam::{Mat4, Vec3};
use pa_render::{
    CpuCamera, CpuMesh, CpuTexture, Draw, LiveCamera, LiveDraw, LiveRenderedFrame, LiveSample,
    LiveTexturing, RenderError, RenderedFrame, Renderer,
};

const W: u32 = 320;
const H: u32 = 240;

fn camera_320(camera_from_world: Mat4) -> CpuCamera {
    CpuCamera {
        intrinsics: common::test_intrinsics().scaled_to(W, H),
        camera_from_world,
        near_m: 0.05,
        far_m: 20.0,
    }
}

fn srgb_to_linear(c: u8) -> f32 {
    let c = c as f32 / 255.0;
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

fn linear_to_srgb(l: f32) -> u8 {
    let l = l.clamp(0.0, 1.0);
    let c = if l <= 0.003_130_8 {
        l * 12.92
    } else {
        1.055 * l.powf(1.0 / 2.4) - 0.055
    };
    (c * 255.0 + 0.5) as u8
}

/// A smooth 128x128 texture (sinusoids of 32-45 texel period), so that resampling twice
/// (frame, then live sample) changes it by far less than a one-pixel displacement would.
fn smooth_texture() -> CpuTexture {
    let n = 128u32;
    let mut rgba8 = Vec::with_capacity((n * n * 4) as usize);
    for y in 0..n {
        for x in 0..n {
            let (xf, yf) = (x as f32, y as f32);
            let tau = std::f32::consts::TAU;
            rgba8.extend_from_slice(&[
                (128.0 + 100.0 * (tau * xf / 32.0).sin()) as u8,
                (128.0 + 100.0 * (tau * yf / 32.0).sin()) as u8,
                (128.0 + 60.0 * (tau * (xf + yf) / 45.0).sin()) as u8,
                255,
            ]);
        }
    }
    CpuTexture {
        width: n,
        height: n,
        rgba8,
    }
}

/// Pixels covered by `frame` whose 8 neighbours are covered too (silhouette eroded by 1 px).
fn interior(frame: &RenderedFrame) -> Vec<bool> {
    let (w, h) = (frame.width as i64, frame.height as i64);
    let covered = |x: i64, y: i64| {
        x >= 0 && y >= 0 && x < w && y < h && frame.depth_m[(y * w + x) as usize].is_finite()
    };
    (0..h)
        .flat_map(|y| (0..w).map(move |x| (x, y)))
        .map(|(x, y)| (-1..=1).all(|dy| (-1..=1).all(|dx| covered(x + dx, y + dy))))
        .collect()
}

/// Max channel (RGB) difference of pixel `i`.
fn diff(a: &[u8], b: &[u8], i: usize) -> u8 {
    (0..3)
        .map(|c| a[i * 4 + c].abs_diff(b[i * 4 + c]))
        .max()
        .unwrap_or(0)
}

/// Mean abs RGB channel difference (in 1/255 units), fraction within `tol`, and pixel count,
/// over the pixels selected by `mask`.
fn compare(a: &[u8], b: &[u8], mask: &[bool], tol: u8) -> (f64, f64, usize) {
    let mut sum = 0u64;
    let mut within = 0usize;
    let mut n = 0usize;
    for (i, _) in mask.iter().enumerate().filter(|(_, &m)| m) {
        for c in 0..3 {
            sum += u64::from(a[i * 4 + c].abs_diff(b[i * 4 + c]));
        }
        if diff(a, b, i) <= tol {
            within += 1;
        }
        n += 1;
    }
    let n_f = n.max(1) as f64;
    (sum as f64 / (3.0 * n_f), within as f64 / n_f, n)
}

fn as_frame_texture(frame: &RenderedFrame) -> CpuTexture {
    CpuTexture {
        width: frame.width,
        height: frame.height,
        rgba8: frame.rgba8.clone(),
    }
}

fn cylinder_camera() -> CpuCamera {
    camera_320(common::look_at(
        Vec3::new(0.22, -0.05, 0.75),
        Vec3::new(0.18, 0.03, 0.0),
        Vec3::Y,
    ))
}

fn textured<'a>(draw: Draw<'a>, texture: &'a pa_render::GpuTexture) -> Draw<'a> {
    Draw {
        texture: Some(texture),
        ..draw
    }
}

/// Renders `draws` (live) and returns (live frame, the plain key-pose visibility map used).
fn render_live_with_visibility(
    renderer: &mut Renderer,
    camera: &CpuCamera,
    draws: &[LiveDraw<'_>],
) -> LiveRenderedFrame {
    renderer
        .render_live(camera, None, draws, [0.0, 0.0, 0.0, 1.0], W, H)
        .expect("live render")
}

#[test]
fn identity_pose_reproduces_the_frame() {
    let Some(mut renderer) = common::renderer_or_skip("identity_pose_reproduces_the_frame") else {
        return;
    };
    let mesh = renderer
        .upload_mesh(&common::bent_cylinder_mesh())
        .expect("mesh");
    let texture = renderer
        .upload_texture(&common::checker_texture())
        .expect("texture");
    let camera = cylinder_camera();
    let joints = common::cylinder_joint_matrices(30f32.to_radians());
    let draw = textured(
        Draw {
            joint_matrices: &joints,
            ..Draw::new(&mesh, Mat4::IDENTITY)
        },
        &texture,
    );
    let direct = renderer
        .render(&camera, None, &[draw], [0.0, 0.0, 0.0, 1.0], W, H)
        .expect("direct render");
    let frame = renderer
        .upload_frame(&as_frame_texture(&direct))
        .expect("frame upload");
    assert_eq!(frame.mip_level_count(), 1);
    let visibility = renderer
        .render_visibility(&camera, &[draw], W, H)
        .expect("visibility");
    // Fallback black: any fallback pixel would show.
    let live = LiveTexturing::new(
        &frame,
        LiveCamera::from_render_camera(&camera, Default::default()),
        Mat4::IDENTITY,
    )
    .with_key_pose(&joints, &[])
    .with_visibility(&visibility)
    .with_fallback_gain([0.0; 3]);
    let out = render_live_with_visibility(&mut renderer, &camera, &[draw.with_live(live)]);

    for (a, b) in out.frame.depth_m.iter().zip(&direct.depth_m) {
        assert!(
            a == b || (a - b).abs() <= 1e-5 * b,
            "same geometry, same depth: {a} vs {b}"
        );
    }
    let mask = interior(&direct);
    let valid: Vec<bool> = mask
        .iter()
        .zip(&out.live_valid)
        .map(|(&m, &c)| m && c == 255)
        .collect();
    let n_interior = mask.iter().filter(|&&m| m).count();
    let n_valid = valid.iter().filter(|&&m| m).count();
    let (mean, within, n) = compare(&out.frame.rgba8, &direct.rgba8, &mask, 2);
    eprintln!(
        "identity: {n} interior px, {n_valid} valid ({:.2}%), mean abs diff {mean:.3}/255, \
         {:.3}% within 2/255",
        100.0 * n_valid as f64 / n_interior as f64,
        100.0 * within
    );
    assert!(n > 3000, "cylinder covers {n} interior pixels");
    assert!(n_valid as f64 >= 0.97 * n_interior as f64);
    assert!(mean < 0.5, "mean abs diff {mean}/255");
    assert!(within >= 0.999, "only {within} within 2/255");
}

#[test]
fn texture_sticks_to_a_rigidly_moved_quad() {
    let Some(mut renderer) = common::renderer_or_skip("texture_sticks_to_a_rigidly_moved_quad")
    else {
        return;
    };
    let (qw, qh) = (0.6, 0.45);
    let mesh = renderer
        .upload_mesh(&common::quad_mesh(qw, qh))
        .expect("mesh");
    let texture = renderer
        .upload_texture(&common::checker_texture())
        .expect("texture");
    let camera = camera_320(common::look_at(
        Vec3::new(0.05, 0.1, 1.3),
        Vec3::ZERO,
        Vec3::Y,
    ));
    let pose_a =
        Mat4::from_rotation_y(-15f32.to_radians()) * Mat4::from_rotation_x(10f32.to_radians());
    let pose_b = Mat4::from_translation(Vec3::new(0.08, -0.05, 0.1))
        * Mat4::from_rotation_z(25f32.to_radians())
        * Mat4::from_rotation_y(20f32.to_radians());
    let at = |pose| textured(Draw::new(&mesh, pose), &texture);
    let frame_a = renderer
        .render(&camera, None, &[at(pose_a)], [0.0, 0.0, 0.0, 1.0], W, H)
        .expect("frame at A");
    let truth_b = renderer
        .render(&camera, None, &[at(pose_b)], [0.0, 0.0, 0.0, 1.0], W, H)
        .expect("direct render at B");
    let frame = renderer
        .upload_frame(&as_frame_texture(&frame_a))
        .expect("frame");
    let visibility = renderer
        .render_visibility(&camera, &[at(pose_a)], W, H)
        .expect("visibility");
    let live = LiveTexturing::new(
        &frame,
        LiveCamera::from_render_camera(&camera, Default::default()),
        pose_a,
    )
    .with_visibility(&visibility)
    .with_fallback_gain([0.0; 3]);
    let out = render_live_with_visibility(&mut renderer, &camera, &[at(pose_b).with_live(live)]);

    // Every checker cell centre, seen at B, has its cell's colour.
    let mut cells = 0;
    for j in 0..8u32 {
        for i in 0..8u32 {
            let uv = glam::Vec2::new((i as f32 + 0.5) / 8.0, (j as f32 + 0.5) / 8.0);
            let p_mesh = Vec3::new((uv.x - 0.5) * qw, (uv.y - 0.5) * qh, 0.0);
            let (px, _) = common::project(&camera, pose_b.transform_point3(p_mesh));
            let (x, y) = (px.x.round() as u32, px.y.round() as u32);
            let got = out.frame.pixel(x, y).expect("inside");
            let want = common::checker_cell_colour(i, j);
            let d = (0..3).map(|c| got[c].abs_diff(want[c])).max().unwrap_or(0);
            assert_eq!(
                out.sample_at(x, y),
                Some(LiveSample::Valid),
                "cell ({i}, {j})"
            );
            assert!(
                d <= 3,
                "cell ({i}, {j}) at pixel ({x}, {y}): live {got:?}, cell colour {want:?}"
            );
            cells += 1;
        }
    }
    let mask = interior(&truth_b);
    let (mean, within, n) = compare(&out.frame.rgba8, &truth_b.rgba8, &mask, 6);
    let n_valid = out.live_valid.iter().filter(|&&c| c == 255).count();
    eprintln!(
        "rigid quad: {cells} cell centres within 3/255; interior {n} px ({n_valid} valid live \
         px in all), mean abs diff {mean:.3}/255, {:.2}% within 6/255",
        100.0 * within
    );
    assert!(mean < 2.0, "mean abs diff {mean}/255");
}

/// Joint matrices of the bent cylinder with joint 1 twisted about the cylinder axis (X) by
/// `twist_rad`, then bent about +Z by `bend_rad`, both about the joint.
fn bend_and_twist(bend_rad: f32, twist_rad: f32) -> Vec<Mat4> {
    let pivot = Vec3::new(common::CYLINDER_JOINT_X, 0.0, 0.0);
    vec![
        Mat4::IDENTITY,
        Mat4::from_translation(pivot)
            * Mat4::from_rotation_z(bend_rad)
            * Mat4::from_rotation_x(twist_rad)
            * Mat4::from_translation(-pivot),
    ]
}

#[test]
fn texture_follows_a_two_bone_bend() {
    let Some(mut renderer) = common::renderer_or_skip("texture_follows_a_two_bone_bend") else {
        return;
    };
    let mesh = renderer
        .upload_mesh(&common::bent_cylinder_mesh())
        .expect("mesh");
    let texture = renderer.upload_texture(&smooth_texture()).expect("texture");
    let camera = cylinder_camera();
    let key = common::cylinder_joint_matrices(0.0);
    // A bend in the image plane keeps the visible side visible; adding a twist about the
    // cylinder's axis brings key-pose back-side points to the front, which must fall back.
    // Key-pose points seen at a grazing angle are blurred in the frame (few frame pixels per
    // surface area); when the twist turns them to the camera they are magnified, so that case
    // also asks for a stricter facing cosine (0.4: within 66 degrees of facing the camera).
    let cases = [
        (
            "bend 45 deg",
            bend_and_twist(45f32.to_radians(), 0.0),
            LiveTexturing::DEFAULT_MIN_FACING_COS,
            0.97,
            1.0,
        ),
        (
            "bend 30 deg + twist 100 deg",
            bend_and_twist(30f32.to_radians(), 100f32.to_radians()),
            0.4,
            0.4,
            0.85,
        ),
    ];
    let pose = |joints| {
        textured(
            Draw {
                joint_matrices: joints,
                ..Draw::new(&mesh, Mat4::IDENTITY)
            },
            &texture,
        )
    };
    let key_frame = renderer
        .render(&camera, None, &[pose(&key)], [0.0, 0.0, 0.0, 1.0], W, H)
        .expect("key-pose frame");
    let frame = renderer
        .upload_frame(&as_frame_texture(&key_frame))
        .expect("frame");
    let mut visibility = renderer
        .render_visibility(&camera, &[pose(&key)], W, H)
        .expect("visibility");
    // Read back, the map is the key pose's depth as a plain render of it sees it (skinned).
    let map = renderer.read_visibility(&mut visibility).expect("read map");
    assert_eq!(map.len(), key_frame.depth_m.len());
    for (i, (m, d)) in map.iter().zip(&key_frame.depth_m).enumerate() {
        assert_eq!(
            m.is_finite(),
            d.is_finite(),
            "texel {i}: map {m}, render {d}"
        );
        if m.is_finite() {
            assert!((m - d).abs() < 1e-5, "texel {i}: map {m}, render {d}");
        }
    }

    for (name, bent, min_facing_cos, min_valid, max_valid) in &cases {
        let truth = renderer
            .render(&camera, None, &[pose(bent)], [0.0, 0.0, 0.0, 1.0], W, H)
            .expect("direct render, bent");
        // Gain 1: the fallback is the model's own texture, i.e. the direct render.
        let live = LiveTexturing {
            min_facing_cos: *min_facing_cos,
            ..LiveTexturing::new(
                &frame,
                LiveCamera::from_render_camera(&camera, Default::default()),
                Mat4::IDENTITY,
            )
            .with_key_pose(&key, &[])
            .with_visibility(&visibility)
        };
        let draw = pose(bent).with_live(live);
        assert_eq!(draw.key_pose_draw().joint_matrices, &key[..]);
        let out = render_live_with_visibility(&mut renderer, &camera, &[draw]);

        let mask = interior(&truth);
        let valid: Vec<bool> = mask
            .iter()
            .zip(&out.live_valid)
            .map(|(&m, &c)| m && c == 255)
            .collect();
        let n_interior = mask.iter().filter(|&&m| m).count();
        let (mean, within, n) = compare(&out.frame.rgba8, &truth.rgba8, &valid, 6);
        let (mean_all, within_all, _) = compare(&out.frame.rgba8, &truth.rgba8, &mask, 6);
        let mut kinds = std::collections::BTreeMap::new();
        for (&m, &c) in mask.iter().zip(&out.live_valid) {
            if m {
                *kinds
                    .entry(format!("{:?}", LiveSample::from_code(c)))
                    .or_insert(0) += 1;
            }
        }
        let fraction = n as f64 / n_interior as f64;
        eprintln!(
            "skinned {name}: {n} of {n_interior} interior px valid ({:.1}%; {kinds:?}); valid px: \
             mean abs diff {mean:.3}/255, {:.2}% within 6/255; all interior px (fallback = own \
             texture): mean {mean_all:.3}/255, {:.2}% within 6/255",
            100.0 * fraction,
            100.0 * within,
            100.0 * within_all,
        );
        assert!(
            (*min_valid..=*max_valid).contains(&fraction),
            "{name}: valid fraction {fraction}"
        );
        assert!(mean < 1.5, "{name}: mean abs diff {mean}/255");
        assert!(within >= 0.99, "{name}: only {within} within 6/255");
        assert!(
            mean_all < 2.0,
            "{name}: mean abs diff {mean_all}/255 with fallback"
        );
    }
}

/// Bilinear sample (in linear light, like the GPU's sRGB sampler) of `img` at OpenCV pixel
/// coordinates `p`; black outside.
fn sample_bilinear(img: &RenderedFrame, lut: &[f32; 256], p: glam::DVec2) -> [f32; 3] {
    let (w, h) = (img.width as i64, img.height as i64);
    let x0 = p.x.floor();
    let y0 = p.y.floor();
    let (fx, fy) = ((p.x - x0) as f32, (p.y - y0) as f32);
    let (x0, y0) = (x0 as i64, y0 as i64);
    let texel = |x: i64, y: i64| -> [f32; 3] {
        if x < 0 || y < 0 || x >= w || y >= h {
            return [0.0; 3];
        }
        let i = ((y * w + x) * 4) as usize;
        [
            lut[img.rgba8[i] as usize],
            lut[img.rgba8[i + 1] as usize],
            lut[img.rgba8[i + 2] as usize],
        ]
    };
    let (a, b, c, d) = (
        texel(x0, y0),
        texel(x0 + 1, y0),
        texel(x0, y0 + 1),
        texel(x0 + 1, y0 + 1),
    );
    std::array::from_fn(|k| {
        (a[k] * (1.0 - fx) + b[k] * fx) * (1.0 - fy) + (c[k] * (1.0 - fx) + d[k] * fx) * fy
    })
}

#[test]
fn distorted_frame_is_sampled_through_the_lens_model() {
    let Some(mut renderer) =
        common::renderer_or_skip("distorted_frame_is_sampled_through_the_lens_model")
    else {
        return;
    };
    let mesh = renderer
        .upload_mesh(&common::quad_mesh(1.0, 0.75))
        .expect("mesh");
    let texture = renderer.upload_texture(&smooth_texture()).expect("texture");
    let camera = camera_320(common::look_at(
        Vec3::new(0.1, 0.05, 1.1),
        Vec3::new(0.0, 0.0, 0.0),
        Vec3::Y,
    ));
    let world_from_mesh = Mat4::from_rotation_y(20f32.to_radians());
    let draw = textured(Draw::new(&mesh, world_from_mesh), &texture);
    let undistorted = renderer
        .render(&camera, None, &[draw], [0.0, 0.0, 0.0, 1.0], W, H)
        .expect("undistorted render");

    // The frame a real lens would have taken: distorted pixel pd shows the scene at
    // K undistort(K^-1 pd).
    let distortion = pa_camera::Distortion {
        k1: -0.28,
        k2: 0.09,
        p1: 0.0015,
        p2: -0.001,
        k3: -0.01,
    };
    let k = camera.intrinsics;
    let lut: [f32; 256] = std::array::from_fn(|i| srgb_to_linear(i as u8));
    let mut rgba8 = Vec::with_capacity((W * H * 4) as usize);
    let mut max_shift_px: f64 = 0.0;
    for y in 0..H {
        for x in 0..W {
            let pd = glam::DVec2::new(x as f64, y as f64);
            let n = distortion.undistort(k.normalized_from_pixel(pd));
            let pu = k.pixel_from_normalized(n);
            max_shift_px = max_shift_px.max((pu - pd).length());
            let c = sample_bilinear(&undistorted, &lut, pu);
            rgba8.extend_from_slice(&[
                linear_to_srgb(c[0]),
                linear_to_srgb(c[1]),
                linear_to_srgb(c[2]),
                255,
            ]);
        }
    }
    let frame = renderer
        .upload_frame(&CpuTexture {
            width: W,
            height: H,
            rgba8,
        })
        .expect("frame");
    let mask = interior(&undistorted);
    let mut run = |d: pa_camera::Distortion| {
        let live = LiveTexturing::new(
            &frame,
            LiveCamera::from_render_camera(&camera, d),
            world_from_mesh,
        );
        render_live_with_visibility(&mut renderer, &camera, &[draw.with_live(live)])
    };
    let out = run(distortion);
    // Only interior pixels whose distorted projection stays inside the frame.
    let inside: Vec<bool> = mask
        .iter()
        .zip(&out.live_valid)
        .map(|(&m, &c)| m && c == 255)
        .collect();
    let (mean, within, n) = compare(&out.frame.rgba8, &undistorted.rgba8, &inside, 6);
    let wrong = run(pa_camera::Distortion::default());
    let (mean_wrong, _, _) = compare(&wrong.frame.rgba8, &undistorted.rgba8, &inside, 6);
    eprintln!(
        "distortion (up to {max_shift_px:.1} px): {n} px, mean abs diff {mean:.3}/255, \
         {:.2}% within 6/255; ignoring the distortion: mean {mean_wrong:.2}/255",
        100.0 * within
    );
    assert!(max_shift_px > 5.0, "the lens must move pixels noticeably");
    assert!(n > 20_000, "{n} pixels compared");
    assert!(mean < 1.5, "mean abs diff {mean}/255");
    assert!(within >= 0.99, "only {within} within 6/255");
    assert!(mean_wrong > 4.0 * mean, "ignoring the lens: {mean_wrong}");
}

/// Four quads, each skinned rigidly to its own joint (uv constant per quad, at the centre of
/// texel `part` of a 2x2 texture, so a direct unlit render identifies the part by colour):
/// 0 back quad, 1 front quad (0.15 m in front of part 0, hiding its middle in the key pose),
/// 2 a quad that faces away in the key pose, 3 a quad outside the view in the key pose.
fn parts_mesh() -> CpuMesh {
    let quads: [(usize, Vec3, f32, f32); 4] = [
        (0, Vec3::new(-0.1, 0.1, 0.0), 0.5, 0.35),
        (1, Vec3::new(-0.1, 0.1, 0.15), 0.2, 0.2),
        (2, Vec3::new(-0.2, -0.25, 0.0), 0.2, 0.15),
        (3, Vec3::new(0.25, -0.25, 0.0), 0.2, 0.15),
    ];
    let mut mesh = CpuMesh::default();
    for (part, c, w, h) in quads {
        let base = mesh.positions.len() as u32;
        let uv = [
            0.25 + 0.5 * (part % 2) as f32,
            0.25 + 0.5 * (part / 2) as f32,
        ];
        for (sx, sy) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
            mesh.positions
                .push([c.x + sx * w / 2.0, c.y + sy * h / 2.0, c.z]);
            mesh.normals.push([0.0, 0.0, 1.0]);
            mesh.uvs.push(uv);
            mesh.joints.push([part as u16, 0, 0, 0, 0, 0, 0, 0]);
            mesh.weights.push([1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]);
        }
        mesh.indices
            .extend_from_slice(&[base, base + 1, base + 2, base, base + 2, base + 3]);
    }
    mesh
}

const PART_COLOURS: [[u8; 4]; 4] = [
    [200, 120, 60, 255],
    [60, 200, 220, 255],
    [230, 60, 140, 255],
    [120, 90, 250, 255],
];

#[test]
fn hidden_back_facing_and_outside_key_points_fall_back() {
    let Some(mut renderer) =
        common::renderer_or_skip("hidden_back_facing_and_outside_key_points_fall_back")
    else {
        return;
    };
    let mesh = renderer.upload_mesh(&parts_mesh()).expect("mesh");
    let mut parts_texture = Vec::new();
    for c in PART_COLOURS {
        parts_texture.extend_from_slice(&c);
    }
    let texture = renderer
        .upload_texture(&CpuTexture {
            width: 2,
            height: 2,
            rgba8: parts_texture,
        })
        .expect("texture");
    let camera = camera_320(common::look_at(
        Vec3::new(0.0, 0.0, 1.2),
        Vec3::ZERO,
        Vec3::Y,
    ));
    let flip_about = |c: Vec3| {
        Mat4::from_translation(c)
            * Mat4::from_rotation_y(std::f32::consts::PI)
            * Mat4::from_translation(-c)
    };
    let key = [
        Mat4::IDENTITY,
        Mat4::IDENTITY,
        flip_about(Vec3::new(-0.2, -0.25, 0.0)),
        Mat4::from_translation(Vec3::new(5.0, 0.0, 0.0)),
    ];
    let animated = [
        Mat4::IDENTITY,
        Mat4::from_translation(Vec3::new(0.45, 0.0, 0.0)),
        Mat4::IDENTITY,
        Mat4::IDENTITY,
    ];
    let pose = |joints| {
        textured(
            Draw {
                joint_matrices: joints,
                ..Draw::new(&mesh, Mat4::IDENTITY)
            },
            &texture,
        )
    };
    let ids_key = renderer
        .render(&camera, None, &[pose(&key)], [0.0; 4], W, H)
        .expect("key-pose part ids");
    let ids_now = renderer
        .render(&camera, None, &[pose(&animated)], [0.0; 4], W, H)
        .expect("animated part ids");

    let frame_colour = [40u8, 180, 90, 255];
    let frame = renderer
        .upload_frame(&CpuTexture::solid(W, H, frame_colour))
        .expect("frame");
    // The per-frame path: rewrite the frame in place.
    renderer
        .update_texture(&frame, &CpuTexture::solid(W, H, frame_colour))
        .expect("frame update");
    // Fallback irradiance E_c(n) = r_c . (1, n): every animated quad faces +Z (towards the
    // camera), so E = (0.5, 1.0, 1.5); a normal with the wrong sign would give
    // (-0.1, -0.2, 0.5), clamped to (0.02, 0.02, 0.5).
    let irradiance = [
        [0.2f32, 0.0, 0.0, 0.3],
        [0.4, 0.0, 0.0, 0.6],
        [1.0, 0.0, 0.0, 0.5],
    ];
    let gain: [f32; 3] = std::array::from_fn(|c| irradiance[c][0] + irradiance[c][3]);
    let visibility = renderer
        .render_visibility(&camera, &[pose(&key)], W, H)
        .expect("visibility");
    let live = LiveTexturing::new(
        &frame,
        LiveCamera::from_render_camera(&camera, Default::default()),
        Mat4::IDENTITY,
    )
    .with_key_pose(&key, &[])
    .with_visibility(&visibility)
    .with_fallback_irradiance(irradiance);
    let out =
        render_live_with_visibility(&mut renderer, &camera, &[pose(&animated).with_live(live)]);

    let part_of = |f: &RenderedFrame, x: i64, y: i64| -> Option<usize> {
        if x < 0 || y < 0 || x >= W as i64 || y >= H as i64 {
            return None;
        }
        let p = f.pixel(x as u32, y as u32)?;
        PART_COLOURS
            .iter()
            .position(|c| (0..3).all(|k| c[k].abs_diff(p[k]) <= 1))
    };
    // The part of (x, y) when its whole 3x3 neighbourhood shows that part.
    let interior_part = |f: &RenderedFrame, x: i64, y: i64| -> Option<usize> {
        let p = part_of(f, x, y)?;
        (-1..=1)
            .all(|dy| (-1..=1).all(|dx| part_of(f, x + dx, y + dy) == Some(p)))
            .then_some(p)
    };
    let fallback = |part: usize| -> [u8; 3] {
        std::array::from_fn(|k| linear_to_srgb(srgb_to_linear(PART_COLOURS[part][k]) * gain[k]))
    };
    let mut counts = std::collections::BTreeMap::new();
    for y in 0..H as i64 {
        for x in 0..W as i64 {
            let Some(part) = interior_part(&ids_now, x, y) else {
                continue;
            };
            // Where was this point in the key pose? Parts 0 and 2 (after the flip about its own
            // centre, the same pixels) stay put; the back quad's point is hidden where the
            // key-pose render shows the front quad.
            let expected = match part {
                0 => match interior_part(&ids_key, x, y) {
                    Some(1) => LiveSample::Occluded,
                    Some(0) => LiveSample::Valid,
                    _ => continue, // within a pixel of the occluding edge
                },
                1 => LiveSample::Valid,
                2 => LiveSample::BackFacing,
                _ => LiveSample::Outside,
            };
            let got = out.sample_at(x as u32, y as u32).expect("inside");
            assert_eq!(got, expected, "part {part} at pixel ({x}, {y})");
            let rgb = out.frame.pixel(x as u32, y as u32).expect("inside");
            let want = if expected == LiveSample::Valid {
                [frame_colour[0], frame_colour[1], frame_colour[2]]
            } else {
                fallback(part)
            };
            let d = (0..3).map(|k| rgb[k].abs_diff(want[k])).max().unwrap_or(0);
            assert!(
                d <= 1,
                "part {part} at ({x}, {y}), {got:?}: colour {rgb:?}, expected {want:?}"
            );
            *counts.entry((part, format!("{got:?}"))).or_insert(0usize) += 1;
        }
    }
    eprintln!("visibility: interior pixel counts (part, sample): {counts:?}");
    let count = |part: usize, s: &str| counts.get(&(part, s.to_owned())).copied().unwrap_or(0);
    assert!(count(0, "Occluded") > 1000, "hidden part of the back quad");
    assert!(count(0, "Valid") > 3000, "visible part of the back quad");
    assert!(count(1, "Valid") > 1000, "moved front quad");
    assert!(
        count(2, "BackFacing") > 500,
        "quad facing away in the key pose"
    );
    assert!(
        count(3, "Outside") > 500,
        "quad outside the frame in the key pose"
    );
    // Background stays 0.
    assert_eq!(out.live_valid[0], 0);
    let (valid, fallback_px) = out.counts();
    assert!(valid > 0 && fallback_px > 0);

    // Without a visibility map the hidden points are (wrongly, by construction) live.
    let live = LiveTexturing::new(
        &frame,
        LiveCamera::from_render_camera(&camera, Default::default()),
        Mat4::IDENTITY,
    )
    .with_key_pose(&key, &[]);
    let no_map =
        render_live_with_visibility(&mut renderer, &camera, &[pose(&animated).with_live(live)]);
    assert!(
        !no_map.live_valid.contains(&3),
        "no map, no occlusion codes"
    );
}

#[test]
fn live_input_errors() {
    let Some(mut renderer) = common::renderer_or_skip("live_input_errors") else {
        return;
    };
    let mesh = renderer
        .upload_mesh(&common::quad_mesh(1.0, 1.0))
        .expect("mesh");
    assert!(LiveDraw::from(Draw::new(&mesh, Mat4::IDENTITY))
        .live
        .is_none());
    let frame = renderer
        .upload_frame(&CpuTexture::solid(4, 4, [1, 2, 3, 255]))
        .expect("frame");
    assert!(matches!(
        renderer.update_texture(&frame, &CpuTexture::solid(5, 4, [0; 4])),
        Err(RenderError::TextureSizeMismatch { .. })
    ));
    let mesh = renderer
        .upload_mesh(&common::bent_cylinder_mesh())
        .expect("mesh");
    let camera = cylinder_camera();
    let joints = common::cylinder_joint_matrices(0.0);
    let draw = Draw {
        joint_matrices: &joints,
        ..Draw::new(&mesh, Mat4::IDENTITY)
    };
    let frame_camera = LiveCamera::from_render_camera(&camera, Default::default());
    let one_joint = [Mat4::IDENTITY];
    let live =
        LiveTexturing::new(&frame, frame_camera, Mat4::IDENTITY).with_key_pose(&one_joint, &[]);
    assert!(matches!(
        renderer.render_live(&camera, None, &[draw.with_live(live)], [0.0; 4], 8, 8),
        Err(RenderError::JointIndexOutOfRange { draw: 0, .. })
    ));
    let mut live = LiveTexturing::new(&frame, frame_camera, Mat4::IDENTITY);
    live.fallback_irradiance[1][2] = f32::NAN;
    assert!(matches!(
        renderer.render_live(&camera, None, &[draw.with_live(live)], [0.0; 4], 8, 8),
        Err(RenderError::NonFiniteDrawInput { draw: 0, .. })
    ));
    let mut other =
        common::renderer_or_skip("live_input_errors (second renderer)").expect("adapter");
    let foreign = other
        .upload_frame(&CpuTexture::solid(4, 4, [0; 4]))
        .expect("frame");
    let live = LiveTexturing::new(&foreign, frame_camera, Mat4::IDENTITY);
    assert!(matches!(
        renderer.render_live(&camera, None, &[draw.with_live(live)], [0.0; 4], 8, 8),
        Err(RenderError::ForeignResource { draw: 0, .. })
    ));
    // A draw without live texturing in render_live matches render.
    let plain = renderer
        .render(&camera, None, &[draw], [0.0; 4], 32, 24)
        .expect("render");
    let via_live = renderer
        .render_live(&camera, None, &[draw.into()], [0.0; 4], 32, 24)
        .expect("render_live");
    assert_eq!(via_live.frame, plain);
    assert!(via_live.live_valid.iter().all(|&c| c == 0));
}

/// A `n` x `n` vertex grid, 1.6 x 0.9 m, skinned to two joints across its middle.
fn grid_mesh(n: usize) -> CpuMesh {
    let mut mesh = CpuMesh::default();
    for j in 0..n {
        for i in 0..n {
            let (u, v) = (i as f32 / (n - 1) as f32, j as f32 / (n - 1) as f32);
            let x = (u - 0.5) * 1.6;
            mesh.positions.push([x, (v - 0.5) * 0.9, 0.0]);
            mesh.uvs.push([u, v]);
            let w1 = ((x + 0.1) / 0.2).clamp(0.0, 1.0);
            mesh.joints.push([0, 1, 0, 0, 0, 0, 0, 0]);
            mesh.weights
                .push([1.0 - w1, w1, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]);
        }
    }
    for j in 0..n - 1 {
        for i in 0..n - 1 {
            let a = (j * n + i) as u32;
            let (b, c, d) = (a + 1, a + n as u32, a + n as u32 + 1);
            mesh.indices.extend_from_slice(&[a, b, d, a, d, c]);
        }
    }
    mesh
}

#[test]
fn timing_720p_live_vs_plain() {
    let Some(mut renderer) = common::renderer_or_skip("timing_720p_live_vs_plain") else {
        return;
    };
    let (w, h) = (1280u32, 720u32);
    let grid = grid_mesh(90);
    let mesh = renderer.upload_mesh(&grid).expect("mesh");
    let texture = renderer.upload_texture(&smooth_texture()).expect("texture");
    let camera = CpuCamera {
        intrinsics: pa_camera::Intrinsics::from_fov_y(50f32.to_radians() as f64, w, h)
            .expect("intrinsics"),
        camera_from_world: common::look_at(Vec3::new(0.0, 0.0, 1.1), Vec3::ZERO, Vec3::Y),
        near_m: 0.05,
        far_m: 20.0,
    };
    let pivot = Mat4::from_translation(Vec3::new(0.0, 0.0, 0.0));
    let key = [Mat4::IDENTITY, Mat4::IDENTITY];
    let bent = [
        Mat4::IDENTITY,
        pivot * Mat4::from_rotation_y(25f32.to_radians()) * pivot.inverse(),
    ];
    let draw = |joints| {
        textured(
            Draw {
                joint_matrices: joints,
                ..Draw::new(&mesh, Mat4::IDENTITY)
            },
            &texture,
        )
    };
    let image = renderer
        .render(&camera, None, &[draw(&key)], [0.0; 4], w, h)
        .expect("frame");
    let image = as_frame_texture(&image);
    let frame = renderer.upload_frame(&image).expect("frame");
    let frame_camera = LiveCamera::from_render_camera(
        &camera,
        pa_camera::Distortion {
            k1: -0.1,
            k2: 0.02,
            ..Default::default()
        },
    );
    let mut visibility = renderer
        .render_visibility(&camera, &[draw(&key)], w, h)
        .expect("visibility");
    let runs = 5;
    let time = |f: &mut dyn FnMut()| {
        f();
        let t = Instant::now();
        for _ in 0..runs {
            f();
        }
        t.elapsed().as_secs_f64() * 1e3 / runs as f64
    };
    let plain_ms = time(&mut || {
        renderer
            .render(&camera, None, &[draw(&bent)], [0.0; 4], w, h)
            .expect("plain");
    });
    let upload_ms = time(&mut || renderer.update_texture(&frame, &image).expect("update"));
    let visibility_ms = time(&mut || {
        renderer
            .update_visibility(&mut visibility, &camera, &[draw(&key)])
            .expect("visibility");
    });
    let mut valid = 0;
    let live_ms = time(&mut || {
        let live = LiveTexturing::new(&frame, frame_camera, Mat4::IDENTITY)
            .with_key_pose(&key, &[])
            .with_visibility(&visibility);
        let out = renderer
            .render_live(
                &camera,
                None,
                &[draw(&bent).with_live(live)],
                [0.0; 4],
                w,
                h,
            )
            .expect("live");
        valid = out.counts().0;
    });
    println!(
        "timing 1280x720, {} vertices / {} triangles on {}: plain render {plain_ms:.1} ms, \
         live render {live_ms:.1} ms (+ frame update {upload_ms:.1} ms, visibility map \
         {visibility_ms:.1} ms); {valid} live px",
        grid.positions.len(),
        grid.indices.len() / 3,
        renderer.adapter_info()
    );
    assert!(valid > 0);
}
