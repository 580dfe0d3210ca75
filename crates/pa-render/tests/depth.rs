//! Depth readback: `RenderedFrame::depth_m` is camera-space z in metres.
//!
//! Tolerances: 1e-5 m for a fronto-parallel plane, 1e-4 m for a tilted plane (against the
//! ray-plane intersection through each pixel centre), exact INFINITY where nothing is drawn.

mod common;

use glam::{DVec3, Mat4, Vec3};
use pa_render::{CpuCamera, Draw};

#[test]
fn fronto_parallel_plane_depth_and_occlusion() {
    let Some(mut renderer) = common::renderer_or_skip("depth_plane") else {
        return;
    };
    let camera = common::camera(Mat4::IDENTITY);
    let big = renderer
        .upload_mesh(&common::quad_mesh(4.0, 4.0))
        .expect("upload");
    let small = renderer
        .upload_mesh(&common::quad_mesh(0.2, 0.2))
        .expect("upload");
    let plane = Draw {
        base_color_factor: [0.0, 0.0, 1.0, 1.0],
        ..Draw::new(&big, Mat4::from_translation(Vec3::new(0.0, 0.0, 1.7)))
    };
    // Drawn after the plane but in front of it: must win the depth test.
    let front = Draw {
        base_color_factor: [1.0, 0.0, 0.0, 1.0],
        ..Draw::new(&small, Mat4::from_translation(Vec3::new(0.0, 0.0, 1.0)))
    };
    // Drawn after the plane and behind it: must lose.
    let behind = Draw {
        base_color_factor: [0.0, 1.0, 0.0, 1.0],
        ..Draw::new(&big, Mat4::from_translation(Vec3::new(0.0, 0.0, 3.0)))
    };
    let frame = renderer
        .render(&camera, None, &[plane, front, behind], [0.0; 4], 160, 120)
        .expect("render");
    let k = camera.intrinsics;
    let (cx, cy) = (k.cx.round() as u32, k.cy.round() as u32);
    assert!((frame.depth_at(cx, cy).unwrap_or(f32::NAN) - 1.0).abs() <= 1e-5);
    assert_eq!(frame.pixel(cx, cy), Some([255, 0, 0, 255]));
    for (x, y) in [(0, 0), (159, 119), (5, 100), (150, 10)] {
        let z = frame.depth_at(x, y).unwrap_or(f32::NAN);
        assert!(
            (z - 1.7).abs() <= 1e-5,
            "pixel ({x}, {y}): depth {z}, want 1.7"
        );
        assert_eq!(frame.pixel(x, y), Some([0, 0, 255, 255]));
    }

    // Only the small quad: everything else is INFINITY.
    let frame = renderer
        .render(&camera, None, &[front], [0.0; 4], 160, 120)
        .expect("render");
    assert_eq!(frame.depth_at(0, 0), Some(f32::INFINITY));
    assert!((frame.depth_at(cx, cy).unwrap_or(f32::NAN) - 1.0).abs() <= 1e-5);
}

#[test]
fn tilted_plane_depth_matches_ray_intersection() {
    let Some(mut renderer) = common::renderer_or_skip("depth_tilted") else {
        return;
    };
    // A general camera pose and a plane tilted 35 degrees.
    let camera_from_world = common::look_at(
        Vec3::new(0.3, -0.4, -1.2),
        Vec3::new(0.0, 0.0, 0.3),
        Vec3::new(0.0, -1.0, 0.0),
    );
    let camera = CpuCamera {
        near_m: 0.1,
        far_m: 10.0,
        ..common::camera(camera_from_world)
    };
    let world_from_mesh =
        Mat4::from_translation(Vec3::new(0.0, 0.0, 0.3)) * Mat4::from_rotation_y(0.61);
    let mesh = renderer
        .upload_mesh(&common::quad_mesh(6.0, 6.0))
        .expect("upload");
    let frame = renderer
        .render(
            &camera,
            None,
            &[Draw::new(&mesh, world_from_mesh)],
            [0.0; 4],
            160,
            120,
        )
        .expect("render");

    // The plane in camera space: point c0 and normal nrm.
    let camera_from_mesh = (camera_from_world * world_from_mesh).as_dmat4();
    let c0 = camera_from_mesh.transform_point3(DVec3::ZERO);
    let nrm = camera_from_mesh.transform_vector3(DVec3::Z);
    let k = camera.intrinsics;
    let mut checked = 0;
    for y in (0..120).step_by(7) {
        for x in (0..160).step_by(7) {
            let ray = DVec3::new((x as f64 - k.cx) / k.fx, (y as f64 - k.cy) / k.fy, 1.0);
            let want = nrm.dot(c0) / nrm.dot(ray);
            let got = frame.depth_at(x, y).unwrap_or(f32::NAN) as f64;
            // Where does the ray hit the plane, in the quad's own coordinates (3 m half side)?
            let hit = camera_from_mesh.inverse().transform_point3(ray * want);
            let inside = hit.x.abs().max(hit.y.abs());
            if want <= 0.1 || want.is_nan() || inside > 3.01 {
                assert_eq!(got, f64::INFINITY, "pixel ({x}, {y}) misses the quad");
                continue;
            }
            if inside > 2.99 {
                continue;
            }
            assert!(
                (got - want).abs() <= 1e-4,
                "pixel ({x}, {y}): depth {got}, ray-plane intersection {want}"
            );
            checked += 1;
        }
    }
    assert!(checked > 300);
}
