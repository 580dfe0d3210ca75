//! The flicker metric on an analytic case: a static textured plane seen by a moving camera.

use glam::{Mat4, Vec3};
use pa_camera::{camera_from_world_look_at, Intrinsics};

use super::*;
use crate::scene::Rng;

const W: u32 = 320;
const H: u32 = 240;

/// The plane's texture (8-bit levels, smooth enough for bilinear interpolation).
fn texture(x: f64, y: f64) -> [f64; 3] {
    let base = 128.0 + 40.0 * (40.0 * x).sin() + 30.0 * (33.0 * y).cos();
    [
        base + 20.0 * (200.0 * x + 3.0 * y).sin(),
        base - 15.0 * (170.0 * y).sin(),
        base + 10.0 * (120.0 * (x + y)).cos(),
    ]
}

/// Renders the plane z = 0 (marker frame) from `camera_from_marker` exactly (ray cast at each
/// pixel centre), plus Gaussian noise of `sigma` levels; the region is where the ray meets the
/// plane within 0.3 m of the origin.
fn render(k: &Intrinsics, camera_from_marker: Mat4, sigma: f64, seed: u64) -> (Vec<u8>, Vec<bool>) {
    let marker_from_camera = camera_from_marker.inverse().as_dmat4();
    let origin = marker_from_camera.transform_point3(glam::DVec3::ZERO);
    let mut rng = Rng::new(seed);
    let mut gauss = || {
        let u1 = (f64::from(rng.f32()) + 1e-9).min(1.0);
        let u2 = f64::from(rng.f32());
        (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
    };
    let mut img = Vec::new();
    let mut region = Vec::new();
    for y in 0..H {
        for x in 0..W {
            let d_cam = glam::DVec3::new(
                (f64::from(x) - k.cx) / k.fx,
                (f64::from(y) - k.cy) / k.fy,
                1.0,
            );
            let d = marker_from_camera.transform_vector3(d_cam);
            let t = -origin.z / d.z;
            let p = origin + d * t;
            let inside = t > 0.0 && p.x.abs() < 0.3 && p.y.abs() < 0.3;
            region.push(inside);
            let c = if inside { texture(p.x, p.y) } else { [0.0; 3] };
            for v in c {
                let v = v + sigma * gauss();
                img.push(v.round().clamp(0.0, 255.0) as u8);
            }
            img.push(255);
        }
    }
    (img, region)
}

fn cameras() -> (Intrinsics, Mat4, Mat4) {
    let k = Intrinsics::from_fov_y(50f64.to_radians(), W, H).expect("intrinsics");
    let a = camera_from_world_look_at(
        Vec3::new(-0.05, 0.35, -0.3),
        Vec3::ZERO,
        Vec3::new(0.0, 0.0, -1.0),
    )
    .expect("camera a");
    let b = camera_from_world_look_at(
        Vec3::new(0.04, 0.33, -0.32),
        Vec3::new(0.01, -0.01, 0.0),
        Vec3::new(0.02, 0.0, -1.0).normalize(),
    )
    .expect("camera b");
    (k, a, b)
}

#[test]
fn a_static_plane_has_no_flicker_once_the_camera_is_compensated() {
    let (k, a, b) = cameras();
    let (ia, ra) = render(&k, a, 0.0, 1);
    let (ib, rb) = render(&k, b, 0.0, 2);
    let mut f = Flicker::new(k);
    assert_eq!(f.step(&ia, &ia, &ra, a), None, "first frame has no change");
    let (ours, truth) = f.step(&ib, &ib, &rb, b).expect("regions overlap");
    // Only the rounding of both images to 8 bits and bilinear interpolation remain.
    assert!(ours < 0.6, "{ours}");
    assert_eq!(ours, truth);
    // Without the compensation the same pair changes a lot: the metric can fail.
    let (raw, n) =
        plane_change(&ia, &ib, W as usize, H as usize, DMat3::IDENTITY, &ra, &rb).expect("overlap");
    assert!(raw > 8.0, "{raw}");
    assert!(n > (W * H / 2) as usize, "{n}");
}

#[test]
fn noise_in_one_frame_gives_its_mean_absolute_value() {
    let (k, a, b) = cameras();
    let sigma = 8.0;
    let (ia, ra) = render(&k, a, 0.0, 1);
    let (ib_clean, rb) = render(&k, b, 0.0, 2);
    let (ib, _) = render(&k, b, sigma, 3);
    let mut f = Flicker::new(k);
    f.step(&ia, &ia, &ra, a);
    let (ours, truth) = f.step(&ib, &ib_clean, &rb, b).expect("overlap");
    // E|N(0, s)| = s sqrt(2 / pi); the rounding adds about 0.3 levels of its own in quadrature.
    let expected = (sigma * sigma + 0.15).sqrt() * (2.0 / std::f64::consts::PI).sqrt();
    assert!((ours - expected).abs() < 0.15, "{ours} vs {expected}");
    assert!(truth < 0.6, "{truth}");
    // reset forgets the previous frame.
    f.reset();
    assert_eq!(f.step(&ib, &ib, &rb, b), None);
}

#[test]
fn mismatched_sizes_measure_nothing() {
    let img = vec![0u8; 16];
    let r = vec![true; 4];
    assert!(plane_change(&img, &img[..12], 2, 2, DMat3::IDENTITY, &r, &r).is_none());
    assert!(plane_change(&img, &img, 2, 2, DMat3::IDENTITY, &r[..3], &r).is_none());
    let (d, n) = plane_change(&img, &img, 2, 2, DMat3::IDENTITY, &r, &r).expect("same");
    assert_eq!((d, n), (0.0, 4));
}

#[test]
fn pixels_beyond_the_table_do_not_count() {
    let (k, a, b) = cameras();
    let (ia, _) = render(&k, a, 0.0, 1);
    let (ib, rb) = render(&k, b, 0.0, 2);
    // Frame b's pixels off the 0.3 m plane get a different colour (not on the plane): with
    // the extent they are left out, so the change stays at the rounding floor.
    let mut ib2 = ib.clone();
    let all = vec![true; (W * H) as usize];
    for (i, r) in rb.iter().enumerate() {
        if !r {
            ib2[i * 4] = 255;
        }
    }
    let mut f = Flicker::new(k).with_plane_extent(0.3);
    f.step(&ia, &ia, &all, a);
    let (ours, _) = f.step(&ib2, &ib2, &all, b).expect("overlap");
    assert!(ours < 0.6, "{ours}");
    // A too small extent leaves out everything but the centre, still measured.
    let mut f = Flicker::new(k).with_plane_extent(0.05);
    f.step(&ia, &ia, &all, a);
    assert!(f.step(&ib, &ib, &all, b).is_some());
    // Without the extent the off-plane pixels count (the region is all pixels here).
    let mut f = Flicker::new(k);
    f.step(&ia, &ia, &all, a);
    let (ours, _) = f.step(&ib2, &ib2, &all, b).expect("overlap");
    assert!(ours > 1.0, "{ours}");
}

#[test]
fn the_flicker_region_keeps_away_from_the_in_betweens_edge() {
    // 7x5, the key covers everything, the truth one pixel at (3, 2).
    let (w, h) = (7usize, 5usize);
    let key = vec![true; w * h];
    let mut truth = vec![false; w * h];
    truth[2 * w + 3] = true;
    let r = flicker_region(&key, &truth, w, 2);
    for y in 0..h {
        for x in 0..w {
            let near = x.abs_diff(3) <= 2 && y.abs_diff(2) <= 2;
            assert_eq!(r[y * w + x], !near, "({x}, {y})");
        }
    }
    // Margin 0: revealed = key and not truth.
    let r0 = flicker_region(&key, &truth, w, 0);
    assert_eq!(r0.iter().filter(|&&b| !b).count(), 1);
    // Not in the key, not in the region.
    assert!(!flicker_region(&[false; 4], &[false; 4], 2, 1)
        .iter()
        .any(|&b| b));
}
