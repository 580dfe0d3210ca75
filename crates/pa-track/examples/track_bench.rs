//! Detection + pose time per frame, as a table (median and p95 over 30 frames):
//! `cargo run --release -p pa-track --example track_bench [-- --frames N]`.
//!
//! Frames: a tilted tag36h11 tag (about a quarter of the frame height, 20-40 degrees of tilt,
//! varying per frame) ray-traced onto a mildly textured background (smooth shading, blotches
//! and +-3 grey levels of noise), like a prop on a table. "full" is a full-frame search with the
//! default detector (decimation 1 + 2, min_white_black_diff 20); "region" is the tracker's region-of-interest search (the
//! last box plus 50 % margin); "thorough" adds the 2x-upsampled pass. Pose = IPPE + LM for the
//! one tag. The detector runs on one thread (the two passes of a frame may run in parallel);
//! `RAYON_NUM_THREADS=1` is harmless and keeps the comparison with older runs fair.

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

fn percentile(v: &mut [f64], p: f64) -> f64 {
    v.sort_by(f64::total_cmp);
    v[((v.len() - 1) as f64 * p).round() as usize]
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let frames: usize = args
        .iter()
        .position(|a| a == "--frames")
        .and_then(|i| args.get(i + 1))
        .and_then(|s| s.parse().ok())
        .unwrap_or(30);
    println!("detection + pose per frame, ms (median / p95 over {frames} frames), one thread");
    println!(
        "| resolution | tag px | full search (default) | region search | full, thorough | full, min_white_black_diff 5 (C value) | region, min_white_black_diff 5 | found (same order) |"
    );
    println!("|---|---|---|---|---|---|---|---|");
    for (w, h) in [(640u32, 480u32), (1280, 720), (1920, 1080)] {
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
        // Tag about h / 4 wide: z = f * s / (h / 4).
        let z = f * size_m / (h as f64 / 4.0);
        let mut rng = Rng(w as u64);
        let scenes: Vec<(GrayImage, Pose)> = (0..frames)
            .map(|i| {
                let tilt = (20.0 + 20.0 * rng.next()).to_radians();
                let rot = glam::DQuat::from_rotation_z(rng.next() * std::f64::consts::TAU)
                    * glam::DQuat::from_rotation_x(tilt);
                let t = DVec3::new(
                    (rng.next() - 0.5) * 0.6 * z,
                    (rng.next() - 0.5) * 0.4 * z,
                    z,
                );
                let pose = Pose {
                    rotation: rot,
                    translation: t,
                };
                (render(&cam, &pose, size_m, i as u64 + 7), pose)
            })
            .collect();
        let run = |cfg: DetectorConfig,
                   roi: bool|
         -> Result<(f64, f64, usize), Box<dyn std::error::Error>> {
            let mut det = Detector::new(cfg)?;
            let mut times = Vec::new();
            let mut found = 0;
            for (img, pose) in &scenes {
                // The region the tracker would search: the tag's box + 50 % + 16 px.
                let pts: Vec<DVec2> = pa_track::tag_object_points(size_m)
                    .iter()
                    .filter_map(|p| cam.pixel_from_camera(pose.transform_point(*p)))
                    .collect();
                let lo = pts.iter().fold(DVec2::splat(f64::MAX), |a, p| a.min(*p));
                let hi = pts.iter().fold(DVec2::splat(f64::MIN), |a, p| a.max(*p));
                let m = 0.5 * (hi - lo).max_element() + 16.0;
                let (x0, y0) = ((lo.x - m).max(0.0), (lo.y - m).max(0.0));
                let (x1, y1) = ((hi.x + m).min(w as f64), (hi.y + m).min(h as f64));
                // Warm-up (decoder allocation per size) outside the timing.
                if roi {
                    det.detect_roi(
                        img,
                        x0 as u32,
                        y0 as u32,
                        (x1 - x0) as u32,
                        (y1 - y0) as u32,
                    )?;
                } else {
                    det.detect(img)?;
                }
                let t0 = Instant::now();
                let dets = if roi {
                    det.detect_roi(
                        img,
                        x0 as u32,
                        y0 as u32,
                        (x1 - x0) as u32,
                        (y1 - y0) as u32,
                    )?
                } else {
                    det.detect(img)?
                };
                if let Some(d) = dets.iter().find(|d| d.id == 0) {
                    let _ = estimate_tag_pose(&cam, &d.corners_px, size_m)?;
                    found += 1;
                }
                times.push(t0.elapsed().as_secs_f64() * 1e3);
            }
            let med = percentile(&mut times, 0.5);
            let p95 = percentile(&mut times, 0.95);
            Ok((med, p95, found))
        };
        let full = run(DetectorConfig::default(), false)?;
        let region = run(DetectorConfig::default(), true)?;
        let thorough = run(DetectorConfig::default().thorough(), false)?;
        let contrast = run(
            DetectorConfig {
                min_white_black_diff: 5,
                ..Default::default()
            },
            false,
        )?;
        let contrast_roi = run(
            DetectorConfig {
                min_white_black_diff: 5,
                ..Default::default()
            },
            true,
        )?;
        println!(
            "| {w}x{h} | ~{} | {:.2} / {:.2} | {:.2} / {:.2} | {:.2} / {:.2} | {:.2} / {:.2} | {:.2} / {:.2} | {}/{}/{}/{}/{} of {frames} |",
            h / 4,
            full.0,
            full.1,
            region.0,
            region.1,
            thorough.0,
            thorough.1,
            contrast.0,
            contrast.1,
            contrast_roi.0,
            contrast_roi.1,
            full.2,
            region.2,
            thorough.2,
            contrast.2,
            contrast_roi.2
        );
    }
    Ok(())
}
