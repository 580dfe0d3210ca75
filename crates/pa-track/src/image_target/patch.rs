//! Frame-to-frame refinement: each picture point is predicted in the frame by a pose, the
//! picture around it is warped into the frame by the local affine map of the projection
//! (sampled from the pyramid level that matches the frame's scale), found by normalised
//! cross-correlation over a small search window, and refined to a fraction of a pixel by
//! inverse-compositional Lucas-Kanade (translation, with gain and bias normalised).

use glam::{DVec2, DVec3};
use pa_camera::CameraModel;
use rayon::prelude::*;

use super::features::Level;
use crate::Pose;

/// Half side of the template (pixels): templates are `(2 HALF + 1)^2`.
const HALF: i32 = 4;
/// Templates flatter than this (standard deviation, gray levels) are not tracked.
const MIN_STD: f32 = 4.0;
/// Correlation a found patch must reach.
pub const MIN_NCC: f32 = 0.75;

/// One tracked point: index into the caller's list and its pixel in the frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tracked {
    pub index: usize,
    pub px: DVec2,
    pub ncc: f32,
}

/// What a point needs: its picture pixel (level 0) and its marker-frame position.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PatchPoint {
    pub picture_px: DVec2,
    pub object: DVec3,
}

/// Tracks `points` in `frame` around their projections under `pose`, searching
/// `radius` pixels. `metres_per_px` converts picture pixels to marker metres (x, y).
pub fn track(
    picture: &[Level],
    frame: &Level,
    camera: &CameraModel,
    pose: &Pose,
    points: &[PatchPoint],
    metres_per_px: DVec2,
    radius: i32,
) -> Vec<Tracked> {
    points
        .par_iter()
        .enumerate()
        .filter_map(|(i, pt)| {
            track_one(picture, frame, camera, pose, pt, metres_per_px, radius)
                .map(|(px, ncc)| Tracked { index: i, px, ncc })
        })
        .collect()
}

fn track_one(
    picture: &[Level],
    frame: &Level,
    camera: &CameraModel,
    pose: &Pose,
    pt: &PatchPoint,
    mpp: DVec2,
    radius: i32,
) -> Option<(DVec2, f32)> {
    let proj = |o: DVec3| {
        camera
            .pixel_from_camera(pose.transform_point(o))
            .filter(|p| p.is_finite())
    };
    let p = proj(pt.object)?;
    let margin = (HALF + radius + 3) as f64;
    if p.x < margin
        || p.y < margin
        || p.x > frame.width as f64 - 1.0 - margin
        || p.y > frame.height as f64 - 1.0 - margin
    {
        return None;
    }
    // Local affine map: frame pixels per picture pixel.
    let du = proj(pt.object + DVec3::new(mpp.x, 0.0, 0.0))? - p;
    let dv = proj(pt.object + DVec3::new(0.0, mpp.y, 0.0))? - p;
    let det = du.x * dv.y - du.y * dv.x;
    if det < 1e-4 {
        return None;
    }
    // Inverse: picture pixels per frame pixel.
    let inv = [[dv.y / det, -dv.x / det], [-du.y / det, du.x / det]];
    // Pyramid level whose pixel is at most one frame pixel.
    let minify = (1.0 / det.sqrt()) as f32;
    let level = picture
        .iter()
        .rposition(|l| l.scale <= minify.max(1.0))
        .unwrap_or(0);
    let lvl = &picture[level];
    let pi = DVec2::new(p.x.round(), p.y.round());
    let off = pi - p;
    let side = (2 * HALF + 3) as usize;
    let mut t = vec![0f32; side * side];
    for (k, v) in t.iter_mut().enumerate() {
        let ox = (k % side) as f64 - (HALF + 1) as f64 + off.x;
        let oy = (k / side) as f64 - (HALF + 1) as f64 + off.y;
        let q = pt.picture_px
            + DVec2::new(
                inv[0][0] * ox + inv[0][1] * oy,
                inv[1][0] * ox + inv[1][1] * oy,
            );
        let s = lvl.scale as f64;
        *v = lvl.sample(
            ((q.x + 0.5) / s - 0.5) as f32,
            ((q.y + 0.5) / s - 0.5) as f32,
        );
    }
    // Inner template, zero mean, unit norm; gradients for Lucas-Kanade.
    let n_in = (2 * HALF + 1) as usize;
    let inner = |k: usize| (k / n_in + 1) * side + (k % n_in + 1);
    let npx = n_in * n_in;
    let mean = (0..npx).map(|k| t[inner(k)]).sum::<f32>() / npx as f32;
    let var = (0..npx).map(|k| (t[inner(k)] - mean).powi(2)).sum::<f32>() / npx as f32;
    let std = var.sqrt();
    if std < MIN_STD {
        return None;
    }
    let tn: Vec<f32> = (0..npx).map(|k| (t[inner(k)] - mean) / std).collect();
    let grad: Vec<(f32, f32)> = (0..npx)
        .map(|k| {
            let i = inner(k);
            (
                0.5 * (t[i + 1] - t[i - 1]) / std,
                0.5 * (t[i + side] - t[i - side]) / std,
            )
        })
        .collect();

    // Integer search by NCC.
    let (cx, cy) = (pi.x as i32, pi.y as i32);
    let mut best = (f32::NEG_INFINITY, 0i32, 0i32);
    for sy in -radius..=radius {
        for sx in -radius..=radius {
            let (mut sf, mut sff, mut sft) = (0f32, 0f32, 0f32);
            for (k, tv) in tn.iter().enumerate() {
                let x = cx + sx + (k % n_in) as i32 - HALF;
                let y = cy + sy + (k / n_in) as i32 - HALF;
                let f = frame.at(x, y) as f32;
                sf += f;
                sff += f * f;
                sft += f * tv;
            }
            let v = sff - sf * sf / npx as f32;
            let ncc = if v > 1e-3 {
                sft / (v.sqrt() * (npx as f32).sqrt())
            } else {
                f32::NEG_INFINITY
            };
            if ncc > best.0 {
                best = (ncc, sx, sy);
            }
        }
    }
    if best.0 < MIN_NCC - 0.1 {
        return None;
    }
    // Lucas-Kanade, inverse compositional.
    let (mut a, mut b, mut c) = (0f32, 0f32, 0f32);
    for g in &grad {
        a += g.0 * g.0;
        b += g.0 * g.1;
        c += g.1 * g.1;
    }
    let hdet = a * c - b * b;
    if hdet < 1e-6 {
        return None;
    }
    let mut d = (best.1 as f32, best.2 as f32);
    let mut ncc = best.0;
    let mut f = vec![0f32; npx];
    for _ in 0..8 {
        for (k, v) in f.iter_mut().enumerate() {
            let x = cx as f32 + d.0 + (k % n_in) as f32 - HALF as f32;
            let y = cy as f32 + d.1 + (k / n_in) as f32 - HALF as f32;
            *v = frame.sample(x, y);
        }
        let fm = f.iter().sum::<f32>() / npx as f32;
        let fs = (f.iter().map(|v| (v - fm).powi(2)).sum::<f32>() / npx as f32).sqrt();
        if fs < 1e-3 {
            return None;
        }
        let (mut ex, mut ey, mut cc) = (0f32, 0f32, 0f32);
        for k in 0..npx {
            let fv = (f[k] - fm) / fs;
            let e = fv - tn[k];
            ex += grad[k].0 * e;
            ey += grad[k].1 * e;
            cc += fv * tn[k];
        }
        ncc = cc / npx as f32;
        let dx = (c * ex - b * ey) / hdet;
        let dy = (a * ey - b * ex) / hdet;
        d.0 -= dx;
        d.1 -= dy;
        if (d.0 - best.1 as f32).abs() > 2.0 || (d.1 - best.2 as f32).abs() > 2.0 {
            return None;
        }
        if dx * dx + dy * dy < 1e-4 {
            break;
        }
    }
    if ncc < MIN_NCC {
        return None;
    }
    Some((pi + DVec2::new(d.0 as f64, d.1 as f64) - off, ncc))
}
