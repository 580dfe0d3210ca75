//! Automatic camera framing: a camera that sees an axis-aligned box whole.

use glam::{Mat4, Vec3};
use pa_camera::{camera_from_world_look_at, Intrinsics};

/// A camera that frames the box `lo..hi` from the front (+Z) and slightly above, with the given
/// intrinsics: every corner of the box projects inside the image shrunk by `margin` (> 1; 1.1
/// leaves a 10% border). Returns (`camera_from_world`, near_m, far_m).
pub fn frame_bounds(lo: Vec3, hi: Vec3, intrinsics: &Intrinsics, margin: f32) -> (Mat4, f32, f32) {
    let centre = (lo + hi) * 0.5;
    let radius = ((hi - lo).length() * 0.5).max(1e-4);
    let dir = Vec3::new(0.0, 0.25, 1.0).normalize();
    // Camera basis at the centre: (right, down, forward) in world space.
    let view = camera_from_world_look_at(centre + dir, centre, Vec3::Y).unwrap_or(Mat4::IDENTITY);
    let tan_x = 0.5 * intrinsics.width as f32 / intrinsics.fx as f32 / margin;
    let tan_y = 0.5 * intrinsics.height as f32 / intrinsics.fy as f32 / margin;
    // For a corner at camera coordinates (x, y, z) relative to the centre seen from distance d,
    // it fits when |x| <= tan_x * (d + z) and |y| <= tan_y * (d + z).
    let mut distance = 0f32;
    for i in 0..8 {
        let corner = Vec3::new(
            if i & 1 == 0 { lo.x } else { hi.x },
            if i & 2 == 0 { lo.y } else { hi.y },
            if i & 4 == 0 { lo.z } else { hi.z },
        );
        let c = view.transform_vector3(corner - centre);
        distance = distance
            .max(c.x.abs() / tan_x - c.z)
            .max(c.y.abs() / tan_y - c.z);
    }
    let distance = distance.max(radius * 1.05);
    let eye = centre + dir * distance;
    let camera_from_world =
        camera_from_world_look_at(eye, centre, Vec3::Y).unwrap_or(Mat4::IDENTITY);
    let near = (distance - radius * 1.5).max(distance * 0.01);
    let far = distance + radius * 1.5;
    (camera_from_world, near, far)
}

#[cfg(test)]
mod tests {
    use super::*;
    use pa_camera::CameraModel;

    #[test]
    fn every_corner_lands_inside_the_shrunk_image_and_one_touches_it() {
        let k = Intrinsics::from_fov_y(40f64.to_radians(), 640, 480).expect("valid");
        let cam = CameraModel::pinhole(k);
        for (lo, hi) in [
            (Vec3::new(-0.1, 0.0, -0.1), Vec3::new(0.1, 0.2, 0.1)),
            (Vec3::new(-1.0, 0.0, -0.2), Vec3::new(1.0, 3.0, 0.3)),
            (Vec3::new(5.0, 5.0, 5.0), Vec3::new(9.0, 6.0, 5.5)),
        ] {
            let (m, near, far) = frame_bounds(lo, hi, &k, 1.1);
            let mut worst = 0f64;
            for i in 0..8 {
                let c = Vec3::new(
                    if i & 1 == 0 { lo.x } else { hi.x },
                    if i & 2 == 0 { lo.y } else { hi.y },
                    if i & 4 == 0 { lo.z } else { hi.z },
                );
                let pc = m.transform_point3(c);
                assert!(pc.z > near && pc.z < far);
                let px = cam.pixel_from_camera(pc.as_dvec3()).expect("in front");
                let fx = ((px.x - k.cx) / (k.width as f64 / 2.0 / 1.1)).abs();
                let fy = ((px.y - k.cy) / (k.height as f64 / 2.0 / 1.1)).abs();
                assert!(fx <= 1.001 && fy <= 1.001, "corner {c} at {px}");
                worst = worst.max(fx).max(fy);
            }
            assert!(worst > 0.98, "the box should fill the frame: {worst}");
        }
    }
}
