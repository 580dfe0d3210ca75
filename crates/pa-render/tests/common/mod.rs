//! Shared helpers of the pa-render integration tests: renderer creation (skipping when no
//! adapter exists at all), golden-image comparison, and small scene builders.

#![allow(dead_code)]

use std::path::PathBuf;

use glam::Mat4;
use pa_render::{CpuCamera, Intrinsics, RenderError, RenderedFrame, Renderer};

/// A renderer, or `None` (after printing "skipped: ...") when the machine has no adapter.
pub fn renderer_or_skip(test: &str) -> Option<Renderer> {
    match Renderer::new() {
        Ok(r) => {
            eprintln!("{test}: rendering on {}", r.adapter_info());
            Some(r)
        }
        Err(e @ RenderError::NoAdapter { .. }) => {
            println!("skipped: no wgpu adapter ({e})");
            None
        }
        Err(e) => panic!("{test}: renderer creation failed: {e}"),
    }
}

/// The 160x120 test camera: fx = fy = 150, principal point slightly off-centre.
pub fn test_intrinsics() -> Intrinsics {
    Intrinsics {
        fx: 150.0,
        fy: 150.0,
        cx: 79.5 + 2.25,
        cy: 59.5 - 1.75,
        width: 160,
        height: 120,
    }
}

pub fn camera(camera_from_world: Mat4) -> CpuCamera {
    CpuCamera {
        intrinsics: test_intrinsics(),
        camera_from_world,
        near_m: 0.05,
        far_m: 20.0,
    }
}

/// Golden tolerance: a pixel matches when every channel differs by at most this much...
pub const GOLDEN_MAX_CHANNEL_DIFF: u8 = 2;
/// ...and at least this fraction of pixels must match.
pub const GOLDEN_MIN_MATCHING_FRACTION: f64 = 0.995;

/// Compares `frame` against `tests/golden/<name>.png`, or the adapter's own variant
/// ([`pa_testkit::golden::assert_golden_in`]:
/// every channel within [`GOLDEN_MAX_CHANNEL_DIFF`]/255 on at least
/// [`GOLDEN_MIN_MATCHING_FRACTION`] of the pixels; `UPDATE_GOLDEN=1` rewrites it; failures
/// write `target/golden-failures/<name>.{actual,diff}.png`).
pub fn assert_golden(renderer: &Renderer, name: &str, frame: &RenderedFrame) {
    pa_testkit::golden::assert_golden_in(
        &pa_testkit::golden::Goldens::for_adapter(
            PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/golden"),
            &renderer.adapter_info(),
            renderer.is_software(),
        ),
        name,
        frame.width,
        frame.height,
        &frame.rgba8,
        pa_testkit::golden::Tolerance {
            max_channel_diff: GOLDEN_MAX_CHANNEL_DIFF,
            min_matching_fraction: GOLDEN_MIN_MATCHING_FRACTION,
        },
    );
}

/// A 64x64 sRGB texture of 8x8 cells of 8x8 texels: cell (i, j) (column i, row j from the top)
/// is (32 i, 32 j, 128 or 255 alternating, 255). Every cell is uniform, so cell centres sample
/// exactly that colour with linear filtering.
pub fn checker_texture() -> pa_render::CpuTexture {
    let mut rgba8 = Vec::with_capacity(64 * 64 * 4);
    for y in 0..64u32 {
        for x in 0..64u32 {
            rgba8.extend_from_slice(&checker_cell_colour(x / 8, y / 8));
        }
    }
    pa_render::CpuTexture {
        width: 64,
        height: 64,
        rgba8,
    }
}

/// Colour of cell (i, j) of [`checker_texture`].
pub fn checker_cell_colour(i: u32, j: u32) -> [u8; 4] {
    let b = if (i + j).is_multiple_of(2) { 128 } else { 255 };
    [(32 * i) as u8, (32 * j) as u8, b, 255]
}

/// A quad in the mesh's XY plane, `w` x `h` metres centred on the origin; uv (0, 0) at
/// (-w/2, -h/2), (1, 1) at (w/2, h/2). Normals +Z.
pub fn quad_mesh(w: f32, h: f32) -> pa_render::CpuMesh {
    let (x, y) = (w / 2.0, h / 2.0);
    pa_render::CpuMesh {
        positions: vec![[-x, -y, 0.0], [x, -y, 0.0], [x, y, 0.0], [-x, y, 0.0]],
        normals: vec![[0.0, 0.0, 1.0]; 4],
        uvs: vec![[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]],
        indices: vec![0, 1, 2, 0, 2, 3],
        ..Default::default()
    }
}

/// Bind-pose position of the second joint of [`bent_cylinder_mesh`] along +X.
pub const CYLINDER_JOINT_X: f32 = 0.2;

/// A cylinder along +X from 0 to 0.4 m, radius 0.05 m, 17 rings of 24 vertices, skinned to two
/// joints: joint 0 at the origin, joint 1 at x = 0.2. Weights blend linearly over
/// x in [0.15, 0.25]; each vertex lists 8 influences (joint 0, joint 1, then zero-weight
/// padding). uv = (x / 0.4, angle / 2 pi), capped ends are left open.
pub fn bent_cylinder_mesh() -> pa_render::CpuMesh {
    let rings = 17usize;
    let segments = 24usize;
    let mut mesh = pa_render::CpuMesh::default();
    for r in 0..rings {
        let t = r as f32 / (rings - 1) as f32;
        let x = 0.4 * t;
        let w1 = ((x - 0.15) / 0.1).clamp(0.0, 1.0);
        for s in 0..segments {
            let a = s as f32 / segments as f32 * std::f32::consts::TAU;
            let (sin, cos) = a.sin_cos();
            mesh.positions.push([x, 0.05 * cos, 0.05 * sin]);
            mesh.normals.push([0.0, cos, sin]);
            mesh.uvs.push([t, s as f32 / segments as f32]);
            mesh.joints.push([0, 1, 0, 0, 0, 0, 0, 0]);
            mesh.weights
                .push([1.0 - w1, w1, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]);
        }
    }
    for r in 0..rings - 1 {
        for s in 0..segments {
            let a = (r * segments + s) as u32;
            let b = (r * segments + (s + 1) % segments) as u32;
            let c = a + segments as u32;
            let d = b + segments as u32;
            mesh.indices.extend_from_slice(&[a, b, d, a, d, c]);
        }
    }
    mesh
}

/// Joint matrices of [`bent_cylinder_mesh`] with joint 1 bent by `angle_rad` about +Z.
pub fn cylinder_joint_matrices(angle_rad: f32) -> Vec<Mat4> {
    let pivot = glam::Vec3::new(CYLINDER_JOINT_X, 0.0, 0.0);
    vec![
        Mat4::IDENTITY,
        Mat4::from_translation(pivot)
            * Mat4::from_rotation_z(angle_rad)
            * Mat4::from_translation(-pivot),
    ]
}

/// camera_from_world for an OpenCV camera at `eye` looking at `target` (`up` is world up; the
/// camera's +Y points down).
pub fn look_at(eye: glam::Vec3, target: glam::Vec3, up: glam::Vec3) -> Mat4 {
    let forward = (target - eye).normalize();
    let right = (-up).cross(forward).normalize();
    let down = forward.cross(right);
    let world_from_camera = Mat4::from_cols(
        right.extend(0.0),
        down.extend(0.0),
        forward.extend(0.0),
        eye.extend(1.0),
    );
    world_from_camera.inverse()
}

/// Projects a world point to OpenCV pixel coordinates (and returns camera z).
pub fn project(camera: &CpuCamera, world: glam::Vec3) -> (glam::DVec2, f64) {
    let c = camera.camera_from_world.transform_point3(world).as_dvec3();
    let px = camera
        .intrinsics
        .pixel_from_normalized(glam::DVec2::new(c.x / c.z, c.y / c.z));
    (px, c.z)
}
