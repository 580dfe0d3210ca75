//! Aligning the clean plate to the frame before it fills the hole.
//!
//! The table-plane homography between the plate's view and the frame comes from two tracked
//! poses, so it carries both poses' errors: at 480x270 on the generated `hard` set (0.45
//! degrees of tracking error) the plate lands about a pixel off, and a pixel is half a check
//! of a woven cloth: the revealed region then loses 2-3 dB against the same plate shifted
//! into place. This module measures that residual misalignment on the pixels around the mask,
//! where the frame and the warped plate both see the background, and corrects the homography:
//!
//! ```text
//! Y(x + e(x)) = g * P(x) + b        for band pixels x (luma, encoded 0..255)
//! e(x) = (a1 u + a2 v + a3, a4 u + a5 v + a6),   (u, v) = (x - c) / s   (the band's box)
//! ```
//!
//! with `Y` the frame, `P` the plate warped by the tracked homography and `g`, `b` a luma gain
//! and offset (exposure; the colour gain is fitted afterwards as before). First the best
//! integer translation within `search_px` (normalised correlation), then Gauss-Newton on all
//! eight parameters with Huber weights (the key prop's own cast shadow, a hand, a reflection
//! are in the frame but not in the plate), then a gate: the correction is kept only if it
//! lowers the robust cost by [`PlateAlign::min_gain`], moves no corner of the band's box by
//! more than `search_px + 1` pixels, and the fit is well conditioned (a textureless band
//! cannot pin a shift: the tracked homography is kept). The corrected homography is
//! `current_from_plate' = A * current_from_plate` with `A: x -> x + e(x)`.
//!
//! Cost: one luma image over the band's box (grown by the search), at most
//! [`PlateAlign::max_samples`] band pixels, `(2 search_px + 1)^2` correlations on half of
//! them and a few 8x8 solves: 1.1-1.3 ms for a bust-sized mask at 1280x720, on top of the
//! plate fill's 4.5-4.8 ms (one core; measured alternately in the same minutes).

use crate::error::DiminishError;
use crate::plate::{sample, GainSpace, Homography, Space};
use crate::types::{ImageRgba8, Mask, Rect};
use rayon::prelude::*;

/// Settings of the plate's alignment ([`crate::CleanPlate::align`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlateAlign {
    /// Width (pixels) of the band around the mask's box whose unmasked pixels are compared.
    pub band_px: u32,
    /// Unmasked pixels within this distance of the mask are left out (the prop's blurred
    /// edge and contact shadow).
    pub gap_px: u32,
    /// The integer search covers translations of up to this many pixels; the final correction
    /// may move a corner of the band's box by at most this plus one.
    pub search_px: u32,
    /// Gauss-Newton iterations at most.
    pub iterations: u32,
    /// Band pixels used at most (a regular subsample beyond).
    pub max_samples: usize,
    /// The correction is kept only if it lowers the robust cost by at least this fraction
    /// (and by more than the sampling noise, 0.02 robust sigma^2).
    pub min_gain: f64,
}

impl Default for PlateAlign {
    fn default() -> Self {
        Self {
            band_px: 16,
            gap_px: 2,
            search_px: 3,
            iterations: 8,
            max_samples: 2048,
            min_gain: 0.03,
        }
    }
}

/// What the alignment found.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlateAlignment {
    /// The corrected `current_from_plate` (the input one when `applied` is false).
    pub current_from_plate: Homography,
    /// Whether the correction passed the gate and is used.
    pub applied: bool,
    /// The largest displacement of the band box's corners by the correction, pixels.
    pub shift_px: f64,
    /// Band pixels compared.
    pub samples: usize,
    /// Robust cost (mean Huber loss) with the tracked homography and with the correction.
    pub cost_before: f64,
    pub cost_after: f64,
}

/// Reusable buffers of the alignment.
#[derive(Debug, Default, Clone)]
pub(crate) struct AlignScratch {
    /// Luma over the band's box (grown by the search).
    luma: Vec<f32>,
    /// Per sample: frame x, y (pixels), normalised u, v, the plate's luma.
    samples: Vec<[f32; 5]>,
    residuals: Vec<f32>,
}

/// Luma of an RGBA8 pixel (Rec. 601 weights on the encoded values).
fn luma(px: &[u8]) -> f32 {
    0.299 * f32::from(px[0]) + 0.587 * f32::from(px[1]) + 0.114 * f32::from(px[2])
}

/// A luma image over a rectangle of the frame, sampled bilinearly with its gradient.
struct LumaImage<'a> {
    data: &'a [f32],
    rect: Rect,
}

impl LumaImage<'_> {
    /// Fills `out` with the luma of `frame` over `rect` (rows in parallel).
    fn build(frame: &ImageRgba8, rect: Rect, out: &mut Vec<f32>) {
        let stride = frame.width() as usize * 4;
        let data = frame.as_slice();
        let w = rect.width as usize;
        out.clear();
        out.resize(w * rect.height as usize, 0.0);
        if w == 0 {
            return;
        }
        out.par_chunks_mut(w).enumerate().for_each(|(r, dst)| {
            let y = rect.y as usize + r;
            let row =
                &data[y * stride + rect.x as usize * 4..y * stride + rect.right() as usize * 4];
            for (d, px) in dst.iter_mut().zip(row.chunks_exact(4)) {
                *d = luma(px);
            }
        });
    }

    /// Luma and its gradient (central differences, interpolated like the luma) at frame
    /// position `(x, y)`, `None` within two pixels of the rectangle's edge.
    fn sample(&self, x: f32, y: f32) -> Option<(f32, f32, f32)> {
        let lx = x - self.rect.x as f32;
        let ly = y - self.rect.y as f32;
        let (w, h) = (self.rect.width as usize, self.rect.height as usize);
        if !(lx >= 1.0 && ly >= 1.0 && lx < (w - 2) as f32 && ly < (h - 2) as f32) {
            return None;
        }
        let (x0, y0) = (lx as usize, ly as usize);
        let (fx, fy) = (lx - x0 as f32, ly - y0 as f32);
        let d = self.data;
        let i = y0 * w + x0;
        let corners = [i, i + 1, i + w, i + w + 1];
        let lerp = |v: [f32; 4]| {
            let top = v[0] + fx * (v[1] - v[0]);
            let bot = v[2] + fx * (v[3] - v[2]);
            top + fy * (bot - top)
        };
        let value = corners.map(|k| d[k]);
        let gx = corners.map(|k| 0.5 * (d[k + 1] - d[k - 1]));
        let gy = corners.map(|k| 0.5 * (d[k + w] - d[k - w]));
        Some((lerp(value), lerp(gx), lerp(gy)))
    }

    /// Luma at integer frame position `(x, y)`, `None` outside the rectangle.
    fn at(&self, x: i64, y: i64) -> Option<f32> {
        let lx = x - i64::from(self.rect.x);
        let ly = y - i64::from(self.rect.y);
        let (w, h) = (i64::from(self.rect.width), i64::from(self.rect.height));
        (lx >= 0 && ly >= 0 && lx < w && ly < h).then(|| self.data[(ly * w + lx) as usize])
    }
}

/// The plate's luma at frame pixel `(x, y)` through `plate_from_current` (the plate fill's
/// bilinear sample, in the encoded values), `None` outside the plate.
fn plate_luma(
    plate: &ImageRgba8,
    encoded: &Space,
    plate_from_current: &Homography,
    x: f64,
    y: f64,
) -> Option<f32> {
    let c = sample(plate, encoded, plate_from_current.apply([x, y])?)?;
    Some(255.0 * (0.299 * c[0] + 0.587 * c[1] + 0.114 * c[2]))
}

/// Huber loss and IRLS weight of a residual `r` at scale `sigma` (threshold 1.345 sigma).
fn huber(r: f64, sigma: f64) -> (f64, f64) {
    let k = 1.345 * sigma;
    let a = r.abs();
    if a <= k {
        (0.5 * r * r, 1.0)
    } else {
        (k * (a - 0.5 * k), k / a)
    }
}

/// Tukey's biweight IRLS weight of a residual `r` at scale `sigma` (zero beyond 4.685
/// sigma): the last iterations ignore what the plate does not show at all.
fn tukey(r: f64, sigma: f64) -> f64 {
    let c = 4.685 * sigma;
    let t = r / c;
    if t.abs() >= 1.0 {
        0.0
    } else {
        (1.0 - t * t).powi(2)
    }
}

/// Solves the symmetric positive definite system `a x = b` (8x8) by Cholesky; `None` when it
/// is not positive definite or the pivots span more than 1e10 (ill conditioned).
#[allow(clippy::needless_range_loop)] // dense linear algebra: indices read as the maths does
fn solve8(a: &[[f64; 8]; 8], b: &[f64; 8]) -> Option<[f64; 8]> {
    let mut l = [[0.0f64; 8]; 8];
    let (mut dmin, mut dmax) = (f64::INFINITY, 0.0f64);
    for i in 0..8 {
        for j in 0..=i {
            let mut s = a[i][j];
            for k in 0..j {
                s -= l[i][k] * l[j][k];
            }
            if i == j {
                if s.is_nan() || s <= 0.0 || !s.is_finite() {
                    return None;
                }
                dmin = dmin.min(s);
                dmax = dmax.max(s);
                l[i][i] = s.sqrt();
            } else {
                l[i][j] = s / l[j][j];
            }
        }
    }
    if dmax > 1e10 * dmin {
        return None;
    }
    let mut y = [0.0f64; 8];
    for i in 0..8 {
        let mut s = b[i];
        for k in 0..i {
            s -= l[i][k] * y[k];
        }
        y[i] = s / l[i][i];
    }
    let mut x = [0.0f64; 8];
    for i in (0..8).rev() {
        let mut s = y[i];
        for k in i + 1..8 {
            s -= l[k][i] * x[k];
        }
        x[i] = s / l[i][i];
    }
    x.iter().all(|v| v.is_finite()).then_some(x)
}

/// The displacement `e` of a sample at normalised `(u, v)` under parameters `t`.
fn displacement(t: &[f64; 8], u: f64, v: f64) -> (f64, f64) {
    (t[0] * u + t[1] * v + t[2], t[3] * u + t[4] * v + t[5])
}

/// Residuals `Y(x + e) - g P - b` of every sample under `t` into `out` (NaN where the frame
/// is not available there).
fn residuals(samples: &[[f32; 5]], luma: &LumaImage<'_>, t: &[f64; 8], out: &mut Vec<f32>) {
    out.clear();
    out.extend(samples.iter().map(|s| {
        let (ex, ey) = displacement(t, f64::from(s[2]), f64::from(s[3]));
        match luma.sample(s[0] + ex as f32, s[1] + ey as f32) {
            Some((y, _, _)) => (f64::from(y) - t[6] * f64::from(s[4]) - t[7]) as f32,
            None => f32::NAN,
        }
    }));
}

/// Mean Huber loss of the finite residuals (and their count).
fn robust_cost(res: &[f32], sigma: f64) -> (f64, usize) {
    let (mut sum, mut n) = (0.0, 0usize);
    for &r in res.iter().filter(|r| r.is_finite()) {
        sum += huber(f64::from(r), sigma).0;
        n += 1;
    }
    (if n > 0 { sum / n as f64 } else { f64::INFINITY }, n)
}

/// Least-squares gain and offset of `Y(x + shift) ~ g P + b` over every `every`-th sample;
/// with the normalised correlation of the two (`None` when either side is flat).
fn fit_gain(
    samples: &[[f32; 5]],
    luma: &LumaImage<'_>,
    shift: (i64, i64),
    every: usize,
) -> Option<(f64, f64, f64)> {
    let (mut n, mut sy, mut sp, mut syy, mut spp, mut syp) = (0.0f64, 0.0, 0.0, 0.0, 0.0, 0.0);
    for s in samples.iter().step_by(every.max(1)) {
        let Some(y) = luma.at(s[0] as i64 + shift.0, s[1] as i64 + shift.1) else {
            continue;
        };
        let (y, p) = (f64::from(y), f64::from(s[4]));
        n += 1.0;
        sy += y;
        sp += p;
        syy += y * y;
        spp += p * p;
        syp += y * p;
    }
    if n < 16.0 {
        return None;
    }
    let vy = syy - sy * sy / n;
    let vp = spp - sp * sp / n;
    let cov = syp - sy * sp / n;
    if vy <= 1e-6 * n || vp <= 1e-6 * n {
        return None;
    }
    let g = cov / vp;
    let b = (sy - g * sp) / n;
    Some((g, b, cov / (vy * vp).sqrt()))
}

/// The normal equations `J^T W J` (lower triangle accumulated, then mirrored).
#[allow(clippy::needless_range_loop)] // dense linear algebra: indices read as the maths does
fn accumulate(a: &mut [[f64; 8]; 8], rhs: &mut [f64; 8], j: &[f64; 8], w: f64, r: f64) {
    for i in 0..8 {
        rhs[i] -= w * j[i] * r;
        for k in 0..=i {
            a[i][k] += w * j[i] * j[k];
        }
    }
}

#[allow(clippy::needless_range_loop)]
fn mirror(a: &mut [[f64; 8]; 8]) {
    for i in 0..8 {
        for k in 0..i {
            a[k][i] = a[i][k];
        }
    }
}

/// `current_from_plate`, aligned with `params` when given ([`align_plate`]), and what the
/// alignment found. A singular homography is an error before any work (the fills' own check).
pub(crate) fn aligned_homography(
    frame: &ImageRgba8,
    mask: &Mask,
    bbox: Rect,
    plate: &ImageRgba8,
    current_from_plate: Homography,
    params: Option<&PlateAlign>,
    scratch: &mut AlignScratch,
) -> Result<(Homography, Option<PlateAlignment>), DiminishError> {
    current_from_plate.inverse()?;
    let alignment = params.and_then(|params| {
        align_plate(
            frame,
            mask,
            bbox,
            plate,
            current_from_plate,
            params,
            scratch,
        )
    });
    if let Some(a) = &alignment {
        log::debug!(
            "plate alignment {} (moves {:.2} px; robust cost {:.2} -> {:.2} on {} px)",
            if a.applied { "applied" } else { "rejected" },
            a.shift_px,
            a.cost_before,
            a.cost_after,
            a.samples
        );
    }
    Ok((
        alignment.map_or(current_from_plate, |a| a.current_from_plate),
        alignment,
    ))
}

/// Measures and, when it passes the gate, corrects the misalignment of the plate against
/// `frame` around the set pixels of `mask` inside `bbox` (see the module docs). `None` when
/// there is nothing to compare (no band pixels, a flat band, the plate out of view).
fn align_plate(
    frame: &ImageRgba8,
    mask: &Mask,
    bbox: Rect,
    plate: &ImageRgba8,
    current_from_plate: Homography,
    params: &PlateAlign,
    scratch: &mut AlignScratch,
) -> Option<PlateAlignment> {
    let (fw, fh) = frame.size();
    let search = params.search_px.min(16);
    let band = bbox.expand_clipped(params.band_px + params.gap_px, fw, fh);
    // The frame's luma over the band's box, grown by the search and the gradient's reach.
    let reach = band.expand_clipped(search + 3, fw, fh);
    LumaImage::build(frame, reach, &mut scratch.luma);
    let luma_img = LumaImage {
        data: &scratch.luma,
        rect: reach,
    };
    // Band pixels: a regular grid over the band's box (the band is about half of it), those
    // with no mask pixel within the gap (Chebyshev).
    let step = ((band.area() as f64 / (2 * params.max_samples.max(1)) as f64)
        .sqrt()
        .ceil() as usize)
        .max(1);
    let gap = i64::from(params.gap_px.min(64));
    let (mw, mh) = (i64::from(fw), i64::from(fh));
    let mdata = mask.as_slice();
    let clear = |x: i64, y: i64| {
        (y - gap..=y + gap).all(|yy| {
            (x - gap..=x + gap).all(|xx| {
                xx < 0 || yy < 0 || xx >= mw || yy >= mh || mdata[(yy * mw + xx) as usize] == 0
            })
        })
    };
    let plate_from_current = current_from_plate.inverse().ok()?;
    let encoded = Space::new(GainSpace::Encoded);
    let (cx, cy) = (
        f64::from(band.x) + f64::from(band.width) / 2.0,
        f64::from(band.y) + f64::from(band.height) / 2.0,
    );
    let scale = (f64::from(band.width.max(band.height)) / 2.0).max(1.0);
    scratch.samples.clear();
    for y in (band.y..band.bottom()).step_by(step) {
        for x in (band.x..band.right()).step_by(step) {
            if !clear(i64::from(x), i64::from(y)) {
                continue;
            }
            let (x, y) = (f64::from(x), f64::from(y));
            let Some(p) = plate_luma(plate, &encoded, &plate_from_current, x, y) else {
                continue;
            };
            scratch.samples.push([
                x as f32,
                y as f32,
                ((x - cx) / scale) as f32,
                ((y - cy) / scale) as f32,
                p,
            ]);
        }
    }
    let samples = &scratch.samples;
    // The tracked homography's fit, and the best integer translation (on every other sample:
    // the search only picks the basin the Gauss-Newton steps start in).
    let (g0, b0, _) = fit_gain(samples, &luma_img, (0, 0), 1)?;
    let (_, _, ncc0) = fit_gain(samples, &luma_img, (0, 0), 2)?;
    let mut start = (0i32, 0i32, g0, b0, ncc0);
    let s = search as i32;
    for dy in -s..=s {
        for dx in -s..=s {
            if (dx, dy) == (0, 0) {
                continue;
            }
            if let Some((g, b, ncc)) =
                fit_gain(samples, &luma_img, (i64::from(dx), i64::from(dy)), 2)
            {
                if ncc > start.4 {
                    start = (dx, dy, g, b, ncc);
                }
            }
        }
    }
    let identity = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, g0, b0];
    residuals(samples, &luma_img, &identity, &mut scratch.residuals);
    // The robust scale: from the tracked fit's residuals (MAD), at least 2 levels.
    let sigma = {
        let mut abs: Vec<f32> = scratch
            .residuals
            .iter()
            .filter(|r| r.is_finite())
            .map(|r| r.abs())
            .collect();
        if abs.len() < 16 {
            return None;
        }
        let mid = abs.len() / 2;
        abs.select_nth_unstable_by(mid, f32::total_cmp);
        (1.4826 * f64::from(abs[mid])).max(2.0)
    };
    let (cost_before, n) = robust_cost(&scratch.residuals, sigma);
    let unchanged = PlateAlignment {
        current_from_plate,
        applied: false,
        shift_px: 0.0,
        samples: n,
        cost_before,
        cost_after: cost_before,
    };
    // Gauss-Newton with Huber weights from the best translation.
    let mut t = [
        0.0,
        0.0,
        f64::from(start.0),
        0.0,
        0.0,
        f64::from(start.1),
        start.2,
        start.3,
    ];
    for it in 0..params.iterations {
        // Huber weights to converge from the integer start, Tukey's biweight from the
        // fourth iteration on (a cast shadow's soft edge no longer pulls).
        let redescend = it >= 3;
        let mut a = [[0.0f64; 8]; 8];
        let mut rhs = [0.0f64; 8];
        for s in samples {
            let (u, v) = (f64::from(s[2]), f64::from(s[3]));
            let (ex, ey) = displacement(&t, u, v);
            let Some((y, gx, gy)) = luma_img.sample(s[0] + ex as f32, s[1] + ey as f32) else {
                continue;
            };
            let p = f64::from(s[4]);
            let r = f64::from(y) - t[6] * p - t[7];
            let w = if redescend {
                tukey(r, sigma)
            } else {
                huber(r, sigma).1
            };
            let (gx, gy) = (f64::from(gx), f64::from(gy));
            let j = [gx * u, gx * v, gx, gy * u, gy * v, gy, -p, -1.0];
            accumulate(&mut a, &mut rhs, &j, w, r);
        }
        mirror(&mut a);
        let Some(delta) = solve8(&a, &rhs) else {
            return Some(unchanged);
        };
        for (ti, di) in t.iter_mut().zip(delta) {
            *ti += di;
        }
        let moved = [(-1.0, -1.0), (1.0, -1.0), (-1.0, 1.0), (1.0, 1.0)]
            .iter()
            .map(|&(u, v)| {
                let (dx, dy) = displacement(&delta, u, v);
                dx.hypot(dy)
            })
            .fold(0.0f64, f64::max);
        if moved < 0.01 && redescend {
            break;
        }
    }
    residuals(samples, &luma_img, &t, &mut scratch.residuals);
    let (cost_after, _) = robust_cost(&scratch.residuals, sigma);
    // The box's corners in normalised coordinates: the largest displacement.
    let (hu, hv) = (
        f64::from(band.width) / 2.0 / scale,
        f64::from(band.height) / 2.0 / scale,
    );
    let shift_px = [(-hu, -hv), (hu, -hv), (-hu, hv), (hu, hv)]
        .iter()
        .map(|&(u, v)| {
            let (dx, dy) = displacement(&t, u, v);
            dx.hypot(dy)
        })
        .fold(0.0f64, f64::max);
    // Better by the fraction asked for and by more than the noise a fit of these samples
    // removes by chance (0.02 sigma^2 of mean loss: an aligned plate stays where it is).
    let better = cost_after < (1.0 - params.min_gain) * cost_before - 0.02 * sigma * sigma;
    if !(better && shift_px.is_finite() && shift_px <= f64::from(search) + 1.0) {
        return Some(PlateAlignment {
            shift_px,
            cost_after,
            ..unchanged
        });
    }
    // A: x -> x + e(x) in frame pixels.
    let (a1, a2, a3) = (t[0] / scale, t[1] / scale, t[2]);
    let (a4, a5, a6) = (t[3] / scale, t[4] / scale, t[5]);
    let a = Homography::from_row_major([
        1.0 + a1,
        a2,
        a3 - a1 * cx - a2 * cy,
        a4,
        1.0 + a5,
        a6 - a4 * cx - a5 * cy,
        0.0,
        0.0,
        1.0,
    ]);
    Some(PlateAlignment {
        current_from_plate: Homography::from_dmat3(a.to_dmat3() * current_from_plate.to_dmat3()),
        applied: true,
        shift_px,
        samples: n,
        cost_before,
        cost_after,
    })
}
