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

/// A borrowed 8-bit frame (row-major, `width x height`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Frame<'a> {
    pub data: &'a [u8],
    pub width: usize,
    pub height: usize,
}

impl<'a> From<&'a Level> for Frame<'a> {
    fn from(l: &'a Level) -> Self {
        Self {
            data: &l.data,
            width: l.width,
            height: l.height,
        }
    }
}

impl<'a> From<&'a crate::GrayImage> for Frame<'a> {
    fn from(g: &'a crate::GrayImage) -> Self {
        Self {
            data: &g.data,
            width: g.width as usize,
            height: g.height as usize,
        }
    }
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
    frame: Frame<'_>,
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

/// Template side with a one-pixel rim for the gradients, inner side, inner pixels.
const SIDE: usize = (2 * HALF + 3) as usize;
const N_IN: usize = (2 * HALF + 1) as usize;
const NPX: usize = N_IN * N_IN;
/// Largest search radius (pixels); larger requests are clamped to it.
const MAX_RADIUS: i32 = 12;

/// Bilinear sample of `l` at `(x, y)`: as [`Level::sample`], without its clamping where
/// the four pixels lie inside.
#[inline]
fn bilinear(l: &Level, x: f32, y: f32) -> f32 {
    if x >= 0.0 && y >= 0.0 && x < (l.width - 1) as f32 && y < (l.height - 1) as f32 {
        let (x0, y0) = (x as usize, y as usize);
        let (fx, fy) = (x - x0 as f32, y - y0 as f32);
        let i = y0 * l.width + x0;
        let (a, b) = (l.data[i] as f32, l.data[i + 1] as f32);
        let (c, d) = (l.data[i + l.width] as f32, l.data[i + l.width + 1] as f32);
        let top = a + (b - a) * fx;
        let bot = c + (d - c) * fx;
        top + (bot - top) * fy
    } else {
        l.sample(x, y)
    }
}

/// The frame's `N_IN x N_IN` pixels at integer offsets from `(x, y)` (bilinear, one shared
/// set of weights); `None` when any lies outside.
fn frame_patch(frame: Frame<'_>, x: f32, y: f32, out: &mut [f32; NPX]) -> Option<()> {
    if !(x >= 0.0 && y >= 0.0) {
        return None;
    }
    let (x0, y0) = (x as usize, y as usize);
    if x0 + N_IN >= frame.width || y0 + N_IN >= frame.height {
        return None;
    }
    let (fx, fy) = (x - x0 as f32, y - y0 as f32);
    let w = frame.width;
    for (r, o) in out.chunks_exact_mut(N_IN).enumerate() {
        let i = (y0 + r) * w + x0;
        let (r0, r1) = (
            &frame.data[i..i + N_IN + 1],
            &frame.data[i + w..i + w + N_IN + 1],
        );
        for (k, v) in o.iter_mut().enumerate() {
            let (a, b) = (r0[k] as f32, r0[k + 1] as f32);
            let (c, d) = (r1[k] as f32, r1[k + 1] as f32);
            let top = a + (b - a) * fx;
            let bot = c + (d - c) * fx;
            *v = top + (bot - top) * fy;
        }
    }
    Some(())
}

fn track_one(
    picture: &[Level],
    frame: Frame<'_>,
    camera: &CameraModel,
    pose: &Pose,
    pt: &PatchPoint,
    mpp: DVec2,
    radius: i32,
) -> Option<(DVec2, f32)> {
    let radius = radius.clamp(0, MAX_RADIUS);
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
    // The template: the picture around the point warped into the frame's pixel grid, in
    // the level's pixels: q(kx, ky) = q0 + kx ax + ky ay.
    let s = lvl.scale as f64;
    let o0 = off - DVec2::splat((HALF + 1) as f64);
    let q0 = (pt.picture_px
        + DVec2::new(
            inv[0][0] * o0.x + inv[0][1] * o0.y,
            inv[1][0] * o0.x + inv[1][1] * o0.y,
        )
        + 0.5)
        / s
        - 0.5;
    let ax = DVec2::new(inv[0][0], inv[1][0]) / s;
    let ay = DVec2::new(inv[0][1], inv[1][1]) / s;
    let mut t = [0f32; SIDE * SIDE];
    for (ky, row) in t.chunks_exact_mut(SIDE).enumerate() {
        let r = q0 + ay * ky as f64;
        for (kx, v) in row.iter_mut().enumerate() {
            let q = r + ax * kx as f64;
            *v = bilinear(lvl, q.x as f32, q.y as f32);
        }
    }
    // Inner template, zero mean, unit norm; gradients for Lucas-Kanade.
    let inner = |k: usize| (k / N_IN + 1) * SIDE + (k % N_IN + 1);
    let mean = (0..NPX).map(|k| t[inner(k)]).sum::<f32>() / NPX as f32;
    let var = (0..NPX).map(|k| (t[inner(k)] - mean).powi(2)).sum::<f32>() / NPX as f32;
    let std = var.sqrt();
    if std < MIN_STD {
        return None;
    }
    let mut tn = [0f32; NPX];
    let mut grad = [(0f32, 0f32); NPX];
    for k in 0..NPX {
        let i = inner(k);
        tn[k] = (t[i] - mean) / std;
        grad[k] = (
            0.5 * (t[i + 1] - t[i - 1]) / std,
            0.5 * (t[i + SIDE] - t[i - SIDE]) / std,
        );
    }

    // Integer search by NCC over the frame window around the prediction.
    let (cx, cy) = (pi.x as i32, pi.y as i32);
    let best = ncc_search(frame, cx, cy, radius, &tn)?;
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
    let mut f = [0f32; NPX];
    for _ in 0..8 {
        frame_patch(
            frame,
            cx as f32 + d.0 - HALF as f32,
            cy as f32 + d.1 - HALF as f32,
            &mut f,
        )?;
        let fm = f.iter().sum::<f32>() / NPX as f32;
        let fs = (f.iter().map(|v| (v - fm).powi(2)).sum::<f32>() / NPX as f32).sqrt();
        if fs < 1e-3 {
            return None;
        }
        let (mut ex, mut ey, mut cc) = (0f32, 0f32, 0f32);
        for k in 0..NPX {
            let fv = (f[k] - fm) / fs;
            let e = fv - tn[k];
            ex += grad[k].0 * e;
            ey += grad[k].1 * e;
            cc += fv * tn[k];
        }
        ncc = cc / NPX as f32;
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

/// The best normalised cross-correlation of the zero-mean, unit-norm template `tn` over
/// integer shifts within `radius` of `(cx, cy)` (the whole window inside the frame):
/// `(ncc, sx, sy)`.
fn ncc_search(
    frame: Frame<'_>,
    cx: i32,
    cy: i32,
    radius: i32,
    tn: &[f32; NPX],
) -> Option<(f32, i32, i32)> {
    let r = radius + HALF;
    let win = (2 * r + 1) as usize;
    let (x0, y0) = (cx - r, cy - r);
    if x0 < 0 || y0 < 0 || x0 as usize + win > frame.width || y0 as usize + win > frame.height {
        return None;
    }
    let (x0, y0) = (x0 as usize, y0 as usize);
    // The window as f32, and integral images of its values and squares (exact in u32).
    let stride = win + 1;
    let mut fw = vec![0f32; win * win];
    let mut s1 = vec![0u32; stride * stride];
    let mut s2 = vec![0u32; stride * stride];
    for y in 0..win {
        let start = (y0 + y) * frame.width + x0;
        let src = &frame.data[start..start + win];
        let (mut r1, mut r2) = (0u32, 0u32);
        for (x, &v) in src.iter().enumerate() {
            fw[y * win + x] = v as f32;
            r1 += v as u32;
            r2 += v as u32 * v as u32;
            s1[(y + 1) * stride + x + 1] = s1[y * stride + x + 1] + r1;
            s2[(y + 1) * stride + x + 1] = s2[y * stride + x + 1] + r2;
        }
    }
    let box_sum = |s: &[u32], x: usize, y: usize| {
        let (a, b) = (y * stride + x, (y + N_IN) * stride + x);
        s[b + N_IN] + s[a] - s[a + N_IN] - s[b]
    };
    let n = NPX as f32;
    let mut best = (f32::NEG_INFINITY, 0i32, 0i32);
    for sy in 0..=(2 * radius) as usize {
        for sx in 0..=(2 * radius) as usize {
            let sf = box_sum(&s1, sx, sy) as f32;
            let sff = box_sum(&s2, sx, sy) as f32;
            let v = sff - sf * sf / n;
            if v <= 1e-3 {
                continue;
            }
            // One accumulator per template column (independent sums).
            let mut acc = [0f32; N_IN];
            for (ky, trow) in tn.chunks_exact(N_IN).enumerate() {
                let start = (sy + ky) * win + sx;
                let frow = &fw[start..start + N_IN];
                for k in 0..N_IN {
                    acc[k] += frow[k] * trow[k];
                }
            }
            let sft: f32 = acc.iter().sum();
            let ncc = sft / (v.sqrt() * n.sqrt());
            if ncc > best.0 {
                best = (ncc, sx as i32 - radius, sy as i32 - radius);
            }
        }
    }
    Some(best)
}
