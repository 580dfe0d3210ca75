//! Golden-image tests: a textured quad (also checked analytically against the projected
//! corners) and a two-bone skinned cylinder at two poses.
//!
//! Tolerance for goldens: every channel within 2/255 on at least 99.5% of the pixels
//! (`common::assert_golden`). `UPDATE_GOLDEN=1 cargo test -p pa-render --test golden` rewrites
//! them; failures write `target/golden-failures/<name>.{actual,diff}.png`.

mod common;

use glam::{DVec2, Mat4, Vec3};
use pa_render::{CpuCamera, DirectionalLight, Draw, Lighting, RenderedFrame, Renderer};

const QUAD_W: f32 = 0.6;
const QUAD_H: f32 = 0.45;

fn quad_camera() -> CpuCamera {
    common::camera(
        Mat4::from_translation(Vec3::new(0.03, -0.02, 1.2))
            * Mat4::from_rotation_x(20f32.to_radians())
            * Mat4::from_rotation_y(-25f32.to_radians()),
    )
}

fn quad_world_from_mesh() -> Mat4 {
    Mat4::from_translation(Vec3::new(0.02, -0.01, 0.0)) * Mat4::from_rotation_z(10f32.to_radians())
}

/// Signed distance (pixels, positive inside) of `p` to the convex polygon `poly`, as the
/// minimum over its edge lines (exact inside; outside, a lower bound of the true distance).
fn signed_distance_convex(poly: &[DVec2], p: DVec2) -> f64 {
    let n = poly.len();
    // Orientation of the polygon (sign of its area).
    let area: f64 = (0..n).map(|i| poly[i].perp_dot(poly[(i + 1) % n])).sum();
    let sign = area.signum();
    (0..n)
        .map(|i| {
            let (a, b) = (poly[i], poly[(i + 1) % n]);
            sign * (b - a).perp_dot(p - a) / (b - a).length()
        })
        .fold(f64::INFINITY, f64::min)
}

/// Every pixel whose centre lies more than `tol_px` inside the projected quad must be covered
/// and every pixel more than `tol_px` outside must not be; returns the number of pixels checked.
fn assert_coverage(frame: &RenderedFrame, corners_px: &[DVec2], tol_px: f64) -> usize {
    let mut checked = 0;
    for y in 0..frame.height {
        for x in 0..frame.width {
            let d = signed_distance_convex(corners_px, DVec2::new(x as f64, y as f64));
            let covered = frame.depth_at(x, y).is_some_and(|z| z.is_finite());
            if d > tol_px {
                assert!(
                    covered,
                    "pixel ({x}, {y}) is {d:.3} px inside the quad but not covered"
                );
                checked += 1;
            } else if d < -tol_px {
                assert!(
                    !covered,
                    "pixel ({x}, {y}) is {:.3} px outside the quad but covered",
                    -d
                );
                checked += 1;
            }
        }
    }
    checked
}

fn render_quad(
    renderer: &mut pa_render::Renderer,
    camera: &CpuCamera,
    width: u32,
    height: u32,
) -> RenderedFrame {
    let mesh = renderer
        .upload_mesh(&common::quad_mesh(QUAD_W, QUAD_H))
        .expect("upload quad");
    let texture = renderer
        .upload_texture(&common::checker_texture())
        .expect("upload texture");
    let draw = Draw {
        texture: Some(&texture),
        ..Draw::new(&mesh, quad_world_from_mesh())
    };
    renderer
        .render(camera, None, &[draw], [0.0, 0.0, 0.0, 0.0], width, height)
        .expect("render quad")
}

fn projected_quad_corners(camera: &CpuCamera) -> Vec<DVec2> {
    let mesh = common::quad_mesh(QUAD_W, QUAD_H);
    mesh.positions
        .iter()
        .map(|p| {
            let world = quad_world_from_mesh().transform_point3(Vec3::from(*p));
            let (px, z) = common::project(camera, world);
            assert!(z > 0.1, "quad corner behind the camera");
            px
        })
        .collect()
}

#[test]
fn textured_quad_golden_and_analytic_corners() {
    let Some(mut renderer) = common::renderer_or_skip("textured_quad") else {
        return;
    };
    let camera = quad_camera();
    let frame = render_quad(&mut renderer, &camera, 160, 120);
    assert_eq!(frame.rgba8.len(), 160 * 120 * 4);

    // 1. Coverage edges against the analytically projected corners: every pixel centre more
    //    than 0.05 px away from the projected outline is classified correctly.
    let corners = projected_quad_corners(&camera);
    let checked = assert_coverage(&frame, &corners, 0.05);
    assert!(
        checked > 160 * 120 * 9 / 10,
        "only {checked} pixels were decidable"
    );

    // 2. Texture orientation and exact unlit colour: the centre of each corner cell of the
    //    checker lands on the pixel nearest its projection with that cell's colour (±1/255).
    for (i, j, u, v) in [
        (0, 0, 1.0 / 16.0, 1.0 / 16.0),
        (7, 0, 15.0 / 16.0, 1.0 / 16.0),
        (7, 7, 15.0 / 16.0, 15.0 / 16.0),
        (0, 7, 1.0 / 16.0, 15.0 / 16.0),
    ] {
        let mesh_point = Vec3::new((u - 0.5) * QUAD_W, (v - 0.5) * QUAD_H, 0.0);
        let world = quad_world_from_mesh().transform_point3(mesh_point);
        let (px, _) = common::project(&camera, world);
        let (x, y) = (px.x.round() as u32, px.y.round() as u32);
        let got = frame.pixel(x, y).expect("corner cell inside the image");
        let want = common::checker_cell_colour(i, j);
        for c in 0..4 {
            assert!(
                got[c].abs_diff(want[c]) <= 1,
                "cell ({i}, {j}) at pixel ({x}, {y}): got {got:?}, want {want:?}"
            );
        }
    }
    // Background is the clear colour (transparent black).
    assert_eq!(frame.pixel(0, 0), Some([0, 0, 0, 0]));

    common::assert_golden(&renderer, "textured_quad", &frame);
}

#[test]
fn quad_at_other_resolution_follows_scaled_intrinsics() {
    let Some(mut renderer) = common::renderer_or_skip("quad_other_resolution") else {
        return;
    };
    // Non-uniform rescale and a width that is not a multiple of 64 (row padding on readback).
    let (w, h) = (173, 97);
    let camera = quad_camera();
    let frame = render_quad(&mut renderer, &camera, w, h);
    assert_eq!((frame.width, frame.height), (w, h));
    assert_eq!(frame.rgba8.len(), (w * h * 4) as usize);
    assert_eq!(frame.depth_m.len(), (w * h) as usize);
    let scaled = CpuCamera {
        intrinsics: camera.intrinsics.scaled_to(w, h),
        ..camera
    };
    let corners = projected_quad_corners(&scaled);
    let checked = assert_coverage(&frame, &corners, 0.05);
    assert!(checked > (w * h * 9 / 10) as usize);
}

/// The skinned cylinder at `angle_deg`, and the renderer that drew it (for its goldens).
fn cylinder_frame(angle_deg: f32) -> Option<(Renderer, RenderedFrame)> {
    let mut renderer = common::renderer_or_skip("skinned_cylinder")?;
    let mesh = renderer
        .upload_mesh(&common::bent_cylinder_mesh())
        .expect("upload cylinder");
    let texture = renderer
        .upload_texture(&common::checker_texture())
        .expect("upload texture");
    let joints = common::cylinder_joint_matrices(angle_deg.to_radians());
    let draw = Draw {
        texture: Some(&texture),
        base_color_factor: [1.0, 0.9, 0.8, 1.0],
        joint_matrices: &joints,
        // Ignored for skinned draws (glTF): a wild transform must change nothing.
        world_from_mesh: Mat4::from_translation(Vec3::new(5.0, 5.0, 5.0)),
        ..Draw::new(&mesh, Mat4::IDENTITY)
    };
    let camera = common::camera(common::look_at(
        Vec3::new(0.25, -0.3, -0.75),
        Vec3::new(0.2, -0.05, 0.0),
        Vec3::new(0.0, -1.0, 0.0),
    ));
    let lighting = Lighting {
        ambient_rgb: [0.2, 0.2, 0.25],
        directional: Some(DirectionalLight {
            toward_light_world: Vec3::new(-0.3, -1.0, -0.6),
            radiance_rgb: [0.9, 0.85, 0.8],
        }),
    };
    let frame = renderer
        .render(
            &camera,
            Some(&lighting),
            &[draw],
            [0.05, 0.05, 0.08, 1.0],
            160,
            120,
        )
        .expect("render cylinder");

    // The tip of the cylinder's axis, skinned analytically, projects onto covered pixels
    // (its surface is 5 cm around it, i.e. several pixels wide).
    let tip = joints[1].transform_point3(Vec3::new(0.4, 0.0, 0.0));
    let (px, _) = common::project(&camera, tip);
    let back = joints[1].transform_point3(Vec3::new(0.38, 0.0, 0.0));
    let (px_in, _) = common::project(&camera, back);
    let inside = px + (px_in - px).normalize() * 2.0;
    let (x, y) = (inside.x.round() as u32, inside.y.round() as u32);
    assert!(
        frame.depth_at(x, y).is_some_and(f32::is_finite),
        "pixel ({x}, {y}) near the skinned tip is not covered"
    );
    Some((renderer, frame))
}

#[test]
fn skinned_cylinder_rest_pose_golden() {
    if let Some((renderer, frame)) = cylinder_frame(0.0) {
        common::assert_golden(&renderer, "skinned_cylinder_rest", &frame);
    }
}

#[test]
fn skinned_cylinder_bent_pose_golden() {
    if let Some((renderer, frame)) = cylinder_frame(-60.0) {
        common::assert_golden(&renderer, "skinned_cylinder_bent", &frame);
    }
}
