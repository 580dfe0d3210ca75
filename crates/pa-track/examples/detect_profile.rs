//! Profiling loop (e.g. under `perf record`) for the full-frame search, detection only:
//! `cargo run --release -p pa-track --example detect_profile -- [W H ITER [d|c|t]]`
//! (`d` default settings, `c` c_reference, `t` thorough). Frames as in `track_bench`: a tilted
//! tag on a mildly textured, noisy background.

use std::time::Instant;

use glam::{DMat3, DVec2, DVec3};
use pa_camera::{CameraModel, Intrinsics};
use pa_track::{
    estimate_tag_pose, family_layout, marker_cells, Detector, DetectorConfig, GrayImage, Pose,
    TagFamily,
};

struct Rng(u64);
impl Rng {
    fn next(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((self.0 >> 11) as f64) / ((1u64 << 53) as f64)
    }
}

/// Renders `frame` with a tag of side `size_m` (black square) at `pose`.
fn render(cam: &CameraModel, pose: &Pose, size_m: f64, seed: u64) -> GrayImage {
    let k = cam.intrinsics;
    let (w, h) = (k.width, k.height);
    let mut rng = Rng(seed);
    // Background: shading + a few soft blotches + noise.
    let blobs: Vec<(f64, f64, f64, f64)> = (0..12)
        .map(|_| {
            (
                rng.next() * w as f64,
                rng.next() * h as f64,
                30.0 + rng.next() * 120.0,
                rng.next() * 50.0 - 25.0,
            )
        })
        .collect();
    let cells = marker_cells(TagFamily::Tag36h11, 0).expect("tag");
    let layout = family_layout(TagFamily::Tag36h11).expect("layout");
    let n = layout.total_cells as f64;
    let cell_m = size_m / layout.border_cells as f64;
    let rt = DMat3::from_quat(pose.rotation).transpose();
    let o = rt * (-pose.translation);
    let mut data = vec![0u8; (w * h) as usize];
    for y in 0..h {
        for x in 0..w {
            let (xf, yf) = (x as f64, y as f64);
            let mut v = 110.0 + 40.0 * xf / w as f64 + 20.0 * yf / h as f64;
            for (bx, by, r, a) in &blobs {
                let d2 = ((xf - bx).powi(2) + (yf - by).powi(2)) / (r * r);
                if d2 < 4.0 {
                    v += a * (-d2).exp();
                }
            }
            // The tag (2x2 supersampled), where the ray hits its canonical image.
            let mut acc = 0.0;
            let mut hits = 0;
            for (sx, sy) in [(-0.25, -0.25), (0.25, -0.25), (-0.25, 0.25), (0.25, 0.25)] {
                let nrm = k.normalized_from_pixel(DVec2::new(xf + sx, yf + sy));
                let d = rt * DVec3::new(nrm.x, nrm.y, 1.0);
                if d.z.abs() < 1e-12 {
                    continue;
                }
                let lam = -o.z / d.z;
                let p = o + d * lam;
                let (cx, cy) = (p.x / cell_m + n / 2.0, p.y / cell_m + n / 2.0);
                if cx >= 0.0 && cy >= 0.0 && cx < n && cy < n {
                    let c = cells.data[cy as usize * n as usize + cx as usize] as f64;
                    acc += 25.0 + c * (215.0 / 255.0);
                    hits += 1;
                } else {
                    acc += v;
                }
            }
            if hits > 0 {
                v = acc / 4.0;
            }
            v += (rng.next() - 0.5) * 6.0;
            data[(y * w + x) as usize] = v.clamp(0.0, 255.0) as u8;
        }
    }
    GrayImage::new(w, h, data).expect("size")
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let w: u32 = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(1280);
    let h: u32 = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(720);
    let iters: usize = args.get(3).and_then(|s| s.parse().ok()).unwrap_or(200);
    let cfg = match args.get(4).map(|s| s.as_str()) {
        Some("c") => DetectorConfig::c_reference(),
        Some("t") => DetectorConfig::default().thorough(),
        _ => DetectorConfig::default(),
    };
    let f = 0.9 * w as f64;
    let cam = CameraModel::pinhole(Intrinsics {
        fx: f,
        fy: f,
        cx: (w as f64 - 1.0) / 2.0,
        cy: (h as f64 - 1.0) / 2.0,
        width: w,
        height: h,
    });
    let size_m = 0.08;
    let z = f * size_m / (h as f64 / 4.0);
    let mut rng = Rng(w as u64);
    let frames: Vec<GrayImage> = (0..4)
        .map(|i| {
            let tilt = (20.0 + 20.0 * rng.next()).to_radians();
            let rot = glam::DQuat::from_rotation_z(rng.next() * std::f64::consts::TAU)
                * glam::DQuat::from_rotation_x(tilt);
            let t = DVec3::new(
                (rng.next() - 0.5) * 0.6 * z,
                (rng.next() - 0.5) * 0.4 * z,
                z,
            );
            render(
                &cam,
                &Pose {
                    rotation: rot,
                    translation: t,
                },
                size_m,
                i as u64 + 7,
            )
        })
        .collect();
    let mut det = Detector::new(cfg)?;
    let mut n = 0;
    let t0 = Instant::now();
    for i in 0..iters {
        n += det.detect(&frames[i % frames.len()])?.len();
    }
    println!(
        "{w}x{h}: {:.3} ms per frame, {n} detections",
        t0.elapsed().as_secs_f64() * 1e3 / iters as f64
    );
    let _ = (estimate_tag_pose, DVec2::ZERO);
    Ok(())
}
