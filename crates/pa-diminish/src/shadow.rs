//! Cast shadows on the table, as pure image math: a soft shadow matte over a rectangle of the
//! frame, the darkening measured under it, and the two uses of both — lifting the real prop's
//! shadow out of the plate ([`lift_shadow`]) and laying the twin's onto it ([`cast_shadow`]).
//!
//! # Model
//! A table point in the shadow receives the ambient light only; a lit one ambient plus the
//! key light. In linear light, per channel, `shadowed = s * lit` with one ratio `s` in (0, 1]
//! for the whole shadow (the table's albedo cancels). A penumbra is a partial occlusion: with
//! the matte's weight `w` in [0, 1] (1 = umbra), the observed colour is
//! `lit * (1 - w (1 - s))`. Lifting divides by that factor, casting multiplies by it.
//!
//! The matte comes from the caller (here: pixel-space triangles, [`ShadowMatte::from_triangles`],
//! which the pipeline obtains by projecting the prop along the light onto the table), softened
//! by a Gaussian of the measured width ([`ShadowMatte::soften`]). The ratio is measured on
//! the frame ([`measure_shadow`]): per channel, the median of the umbra's pixels over the
//! median of the lit ring around it, both in linear light; medians, so that the table's
//! texture and a few misregistered pixels do not move it. [`fit_softness`] picks the Gaussian
//! width that best explains the observed penumbra.
//!
//! Cost: O(rectangle) for every function but the triangle fill, which is O(triangles + the
//! pixels they cover).

use crate::error::DiminishError;
use crate::plate::{decode_lut, encode_linear};
use crate::types::{ImageRgba8, Mask, Rect};

/// A soft shadow matte: weights in [0, 1] over a rectangle of a `width x height` frame
/// (row-major over the rectangle; pixels outside it have weight 0).
#[derive(Debug, Clone, PartialEq)]
pub struct ShadowMatte {
    rect: Rect,
    weights: Vec<f32>,
    frame: (u32, u32),
}

/// What [`measure_shadow`] found: the per-channel ratio shadowed / lit (linear light) and
/// the pixels it was measured on.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ShadowRatio {
    /// Shadowed over lit, per linear RGB channel, in [`MIN_RATIO`, 1].
    pub rgb: [f32; 3],
    /// Umbra pixels measured (weight at least [`UMBRA_WEIGHT`], not excluded).
    pub shadow_samples: usize,
    /// Lit pixels measured (weight 0 inside the matte's rectangle, not excluded).
    pub lit_samples: usize,
}

impl ShadowRatio {
    /// The Rec. 709 luminance of the ratio: one number for "how much darker".
    pub fn luminance(&self) -> f32 {
        0.2126 * self.rgb[0] + 0.7152 * self.rgb[1] + 0.0722 * self.rgb[2]
    }
}

/// The smallest ratio used (a shadow that keeps 5 % of the light): lifting a darker one would
/// amplify noise twenty-fold.
pub const MIN_RATIO: f32 = 0.05;
/// Weight from which a pixel counts as umbra in [`measure_shadow`].
pub const UMBRA_WEIGHT: f32 = 0.95;
/// Weight below which a pixel counts as lit in [`measure_shadow`].
pub const LIT_WEIGHT: f32 = 0.02;
/// Fewest pixels of each kind for a measurement.
pub const MIN_SAMPLES: usize = 32;

impl ShadowMatte {
    /// A matte from its weights over `rect` (clipped to the frame by the caller: `rect` must
    /// lie inside `width x height`; weights are clamped to [0, 1], non-finite ones become 0).
    pub fn new(
        rect: Rect,
        weights: Vec<f32>,
        width: u32,
        height: u32,
    ) -> Result<Self, DiminishError> {
        if width == 0 || height == 0 {
            return Err(DiminishError::ZeroSize {
                what: "shadow frame",
                width,
                height,
            });
        }
        if !Rect::new(0, 0, width, height).contains_rect(&rect) {
            return Err(DiminishError::SizeMismatch {
                what: "shadow matte rectangle",
                expected_width: width,
                expected_height: height,
                actual_width: rect.right(),
                actual_height: rect.bottom(),
            });
        }
        if weights.len() != rect.area() {
            return Err(DiminishError::BufferLength {
                what: "shadow matte",
                width: rect.width,
                height: rect.height,
                channels: 1,
                expected: rect.area(),
                actual: weights.len(),
            });
        }
        let weights = weights
            .into_iter()
            .map(|w| {
                if w.is_finite() {
                    w.clamp(0.0, 1.0)
                } else {
                    0.0
                }
            })
            .collect();
        Ok(Self {
            rect,
            weights,
            frame: (width, height),
        })
    }

    /// The hard matte of the union of pixel-space triangles (OpenCV pixel centres: a pixel is
    /// in when its centre is), over their bounding box grown by `margin_px` and clipped to the
    /// frame. `None` when no triangle reaches the frame. Non-finite vertices drop their
    /// triangle.
    pub fn from_triangles(
        triangles: &[[[f32; 2]; 3]],
        margin_px: u32,
        width: u32,
        height: u32,
    ) -> Option<Self> {
        let finite = |t: &&[[f32; 2]; 3]| t.iter().all(|p| p[0].is_finite() && p[1].is_finite());
        let pts = triangles
            .iter()
            .filter(finite)
            .flat_map(|t| t.iter().map(|p| [f64::from(p[0]), f64::from(p[1])]));
        let rect = Rect::bounding_points(pts, f64::from(margin_px), width, height)?;
        let mut weights = vec![0.0f32; rect.area()];
        let rw = rect.width as usize;
        for t in triangles.iter().filter(finite) {
            fill_triangle(t, rect, rw, &mut weights);
        }
        Some(Self {
            rect,
            weights,
            frame: (width, height),
        })
    }

    /// The rectangle the weights cover.
    pub fn rect(&self) -> Rect {
        self.rect
    }

    /// The weights, row-major over [`ShadowMatte::rect`].
    pub fn weights(&self) -> &[f32] {
        &self.weights
    }

    /// The weight at frame pixel `(x, y)` (0 outside the rectangle).
    pub fn at(&self, x: u32, y: u32) -> f32 {
        if !self.rect.contains(x, y) {
            return 0.0;
        }
        let (lx, ly) = ((x - self.rect.x) as usize, (y - self.rect.y) as usize);
        self.weights[ly * self.rect.width as usize + lx]
    }

    /// The frame size the matte belongs to.
    pub fn frame_size(&self) -> (u32, u32) {
        self.frame
    }

    /// Sum of the weights (the shadow's area in pixels).
    pub fn area(&self) -> f64 {
        self.weights.iter().map(|&w| f64::from(w)).sum()
    }

    /// The matte blurred by a Gaussian of standard deviation `sigma_px` (three box passes),
    /// its rectangle grown by three deviations (clipped to the frame) so the penumbra fits.
    /// `sigma_px` at or below 0.25 leaves it as it is.
    pub fn soften(&self, sigma_px: f32) -> Result<Self, DiminishError> {
        if !sigma_px.is_finite() || sigma_px < 0.0 {
            return Err(DiminishError::InvalidParameter {
                name: "shadow softness",
                value: f64::from(sigma_px),
                reason: "must be a finite number of pixels, at least 0",
            });
        }
        if sigma_px <= 0.25 {
            return Ok(self.clone());
        }
        let (w, h) = self.frame;
        let grow = (3.0 * sigma_px).ceil() as u32;
        let rect = self.rect.expand_clipped(grow, w, h);
        let (rw, rh) = (rect.width as usize, rect.height as usize);
        let mut buf = vec![0.0f32; rw * rh];
        let (ox, oy) = (
            (self.rect.x - rect.x) as usize,
            (self.rect.y - rect.y) as usize,
        );
        let sw = self.rect.width as usize;
        for (ly, row) in self.weights.chunks_exact(sw).enumerate() {
            let o = (oy + ly) * rw + ox;
            buf[o..o + sw].copy_from_slice(row);
        }
        // Three box passes whose widths are chosen so that their variances add up to
        // sigma^2 (W. Jarosz's "boxes for Gauss": the lower odd width m times, then the next).
        let ideal = (12.0 * sigma_px * sigma_px / 3.0 + 1.0).sqrt();
        let mut wl = ideal.floor() as i64;
        if wl % 2 == 0 {
            wl -= 1;
        }
        let wlf = wl as f32;
        let m = ((12.0 * sigma_px * sigma_px - 3.0 * wlf * wlf - 12.0 * wlf - 9.0)
            / (-4.0 * wlf - 4.0))
            .round() as i64;
        let mut tmp = vec![0.0f32; rw.max(rh)];
        let mut col = vec![0.0f32; rh];
        for pass in 0..3 {
            let width = if pass < m { wl } else { wl + 2 };
            let b = ((width - 1) / 2).max(0) as usize;
            if b == 0 {
                continue;
            }
            for row in buf.chunks_exact_mut(rw) {
                box_1d(row, b, &mut tmp);
            }
            for x in 0..rw {
                for (y, c) in col.iter_mut().enumerate() {
                    *c = buf[y * rw + x];
                }
                box_1d(&mut col, b, &mut tmp);
                for (y, c) in col.iter().enumerate() {
                    buf[y * rw + x] = *c;
                }
            }
        }
        Ok(Self {
            rect,
            weights: buf,
            frame: self.frame,
        })
    }

    /// Zeroes the weights where `mask` is set (e.g. the prop itself, which is not table).
    pub fn exclude(&mut self, mask: &Mask) -> Result<(), DiminishError> {
        crate::types::ensure_same_size("shadow exclusion mask", self.frame, mask.size())?;
        let fw = self.frame.0 as usize;
        let rw = self.rect.width as usize;
        let m = mask.as_slice();
        for (ly, row) in self.weights.chunks_exact_mut(rw).enumerate() {
            let y = self.rect.y as usize + ly;
            let src = &m[y * fw + self.rect.x as usize..y * fw + self.rect.x as usize + rw];
            for (wt, &e) in row.iter_mut().zip(src) {
                if e != 0 {
                    *wt = 0.0;
                }
            }
        }
        Ok(())
    }
}

/// Box average of half-width `b` along a line (edges clamp: the nearest value repeats).
fn box_1d(line: &mut [f32], b: usize, tmp: &mut [f32]) {
    let n = line.len();
    if n == 0 {
        return;
    }
    let tmp = &mut tmp[..n];
    tmp.copy_from_slice(line);
    let at = |i: isize| tmp[i.clamp(0, n as isize - 1) as usize];
    let norm = 1.0 / (2 * b + 1) as f32;
    let mut sum: f32 = (-(b as isize)..=b as isize).map(at).sum();
    for (i, out) in line.iter_mut().enumerate() {
        *out = sum * norm;
        let i = i as isize;
        sum += at(i + b as isize + 1) - at(i - b as isize);
    }
}

/// Sets to 1 the weights of the pixels (centres) inside triangle `t` within `rect`.
fn fill_triangle(t: &[[f32; 2]; 3], rect: Rect, rw: usize, weights: &mut [f32]) {
    let [a, b, c] = t.map(|p| [f64::from(p[0]), f64::from(p[1])]);
    let area = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
    if area.abs() < 1e-12 {
        return;
    }
    let s = area.signum();
    let x0 = a[0].min(b[0]).min(c[0]).ceil().max(f64::from(rect.x));
    let y0 = a[1].min(b[1]).min(c[1]).ceil().max(f64::from(rect.y));
    let x1 = a[0]
        .max(b[0])
        .max(c[0])
        .floor()
        .min(f64::from(rect.right()) - 1.0);
    let y1 = a[1]
        .max(b[1])
        .max(c[1])
        .floor()
        .min(f64::from(rect.bottom()) - 1.0);
    if x1 < x0 || y1 < y0 {
        return;
    }
    let edge = |p: [f64; 2], q: [f64; 2], x: f64, y: f64| {
        s * ((q[0] - p[0]) * (y - p[1]) - (q[1] - p[1]) * (x - p[0]))
    };
    for y in y0 as u32..=y1 as u32 {
        let yf = f64::from(y);
        let row = (y - rect.y) as usize * rw;
        for x in x0 as u32..=x1 as u32 {
            let xf = f64::from(x);
            if edge(a, b, xf, yf) >= 0.0 && edge(b, c, xf, yf) >= 0.0 && edge(c, a, xf, yf) >= 0.0 {
                weights[row + (x - rect.x) as usize] = 1.0;
            }
        }
    }
}

/// Linear-light values of the matte's pixels: (weight, rgb), skipping `exclude`d pixels.
fn samples<'a>(
    image: &'a ImageRgba8,
    matte: &'a ShadowMatte,
    exclude: Option<&'a Mask>,
) -> impl Iterator<Item = (f32, [f32; 3])> + 'a {
    let lut = decode_lut();
    let fw = image.width() as usize;
    let rect = matte.rect;
    let rw = rect.width as usize;
    let px = image.as_slice();
    matte.weights.iter().enumerate().filter_map(move |(k, &w)| {
        let (lx, ly) = (k % rw, k / rw);
        let i = (rect.y as usize + ly) * fw + rect.x as usize + lx;
        if exclude.is_some_and(|m| m.as_slice()[i] != 0) {
            return None;
        }
        let p = &px[i * 4..i * 4 + 3];
        Some((
            w,
            [lut[p[0] as usize], lut[p[1] as usize], lut[p[2] as usize]],
        ))
    })
}

fn check(
    image: &ImageRgba8,
    matte: &ShadowMatte,
    exclude: Option<&Mask>,
) -> Result<(), DiminishError> {
    crate::types::ensure_same_size("shadow matte's frame", image.size(), matte.frame)?;
    if let Some(m) = exclude {
        crate::types::ensure_same_size("shadow exclusion mask", image.size(), m.size())?;
    }
    Ok(())
}

fn median(v: &mut [f32]) -> f32 {
    let mid = v.len() / 2;
    let (_, m, _) = v.select_nth_unstable_by(mid, f32::total_cmp);
    *m
}

/// The darkening under `matte` in `image`: per channel, the median of the umbra pixels
/// (weight at least [`UMBRA_WEIGHT`]) over the median of the lit pixels of the matte's
/// rectangle (weight below [`LIT_WEIGHT`]: give the matte a margin), both in linear light,
/// skipping pixels set in `exclude`. `Ok(None)` with fewer than [`MIN_SAMPLES`] of either or a
/// black lit side. The ratio is clamped to [[`MIN_RATIO`], 1].
pub fn measure_shadow(
    image: &ImageRgba8,
    matte: &ShadowMatte,
    exclude: Option<&Mask>,
) -> Result<Option<ShadowRatio>, DiminishError> {
    check(image, matte, exclude)?;
    let mut shadow: [Vec<f32>; 3] = Default::default();
    let mut lit: [Vec<f32>; 3] = Default::default();
    for (w, rgb) in samples(image, matte, exclude) {
        let dst = if w >= UMBRA_WEIGHT {
            &mut shadow
        } else if w < LIT_WEIGHT {
            &mut lit
        } else {
            continue;
        };
        for c in 0..3 {
            dst[c].push(rgb[c]);
        }
    }
    let (ns, nl) = (shadow[0].len(), lit[0].len());
    if ns < MIN_SAMPLES || nl < MIN_SAMPLES {
        return Ok(None);
    }
    let mut rgb = [1.0f32; 3];
    for c in 0..3 {
        let l = median(&mut lit[c]);
        if l <= 1e-4 {
            return Ok(None);
        }
        rgb[c] = (median(&mut shadow[c]) / l).clamp(MIN_RATIO, 1.0);
    }
    Ok(Some(ShadowRatio {
        rgb,
        shadow_samples: ns,
        lit_samples: nl,
    }))
}

/// How well `matte` with darkening `ratio` explains `image`: the mean squared error, in
/// linear luminance, between each pixel and the lit median times `1 - w (1 - s)` over the
/// matte's rectangle (pixels of `exclude` skipped). Texture adds the same variance to every
/// candidate, so the smallest error marks the matte (and softness) that fits best. `None`
/// without pixels.
pub fn shadow_fit_error(
    image: &ImageRgba8,
    matte: &ShadowMatte,
    ratio: &ShadowRatio,
    lit_luminance: f32,
    exclude: Option<&Mask>,
) -> Result<Option<f64>, DiminishError> {
    check(image, matte, exclude)?;
    let s = ratio.luminance();
    let (mut sum, mut n) = (0.0f64, 0usize);
    for (w, rgb) in samples(image, matte, exclude) {
        let y = 0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2];
        let pred = lit_luminance * (1.0 - w * (1.0 - s));
        sum += f64::from(y - pred).powi(2);
        n += 1;
    }
    Ok((n > 0).then(|| sum / n as f64))
}

/// How much of the observed darkening the umbra of `matte` explains: over its umbra pixels
/// (weight at least [`UMBRA_WEIGHT`], not excluded), in linear luminance, the sum of
/// `(Y - lit)^2 - (Y - s lit)^2` with `s` the ratio's luminance. A pixel that is really in a
/// shadow of that darkness adds, a lit pixel wrongly counted subtracts: the region that best
/// matches the real shadow scores highest.
pub fn explained_darkening(
    image: &ImageRgba8,
    matte: &ShadowMatte,
    ratio: &ShadowRatio,
    lit_luminance: f32,
    exclude: Option<&Mask>,
) -> Result<f64, DiminishError> {
    check(image, matte, exclude)?;
    let s = ratio.luminance();
    let lit = f64::from(lit_luminance);
    Ok(samples(image, matte, exclude)
        .filter(|(w, _)| *w >= UMBRA_WEIGHT)
        .map(|(_, c)| {
            let y = f64::from(0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]);
            (y - lit).powi(2) - (y - f64::from(s) * lit).powi(2)
        })
        .sum())
}

/// What [`outline_darkenings`] found.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OutlineDarkening {
    /// Median log-ratio (outside over inside luminance) times the pairs: higher = a
    /// stronger, longer shadow edge along the outline.
    pub score: f64,
    /// The mean of the pairs' clamped log-ratios: lowered by every pair without the edge,
    /// where the median ignores a minority of them.
    pub mean_log: f64,
    /// Per channel, the median of the pairs' inside / outside (clamped to
    /// [[`MIN_RATIO`], 1]); its sample counts are the pairs.
    pub ratio: ShadowRatio,
}

/// Whether two frame pixels `(x, y)` show the same surface (the same print or material), for
/// [`outline_darkenings`]'s pairs: a caller that knows the set's print (the marker board) says
/// so, and a pair across a tag's black and white is left out instead of read as a shadow.
pub type SameSurface<'a> = &'a (dyn Fn([u32; 2], [u32; 2]) -> bool + Sync);

/// The darkening across the outline of a hard matte, at each distance of `steps_px` (one
/// scan of the outline for all): at every outline pixel of `hard` (weight at least 0.5 with a
/// 4-neighbour below), the pixel `step_px` inside along the outline's normal and the one
/// `step_px` outside are compared by the log-ratio of their linear luminances,
/// `ln(outside / inside)` clamped to [-1.5, 1.5] (pairs with a pixel in `exclude`, beyond the
/// rectangle, or a black outside, are skipped, and so are those that `same_surface`, when
/// given, says straddle two surfaces). The score is the median log-ratio times the number of
/// pairs; the ratio, per channel, the median of the pairs' inside / outside. `None` at a
/// distance without pairs.
///
/// A real shadow of that outline darkens every pair alike and the score grows with the
/// visible outline; a region that is only part of the real shadow has part of its outline
/// inside it (pairs near 0), one that spills onto the lit table loses the real edge; and the
/// pairs that straddle printed high-contrast texture (a tag's squares, a sheet's edge) are a
/// minority the median ignores, where a comparison of the region's median against its
/// surroundings' would take a black tag or dark wood beside white paper for a shadow.
pub fn outline_darkenings(
    image: &ImageRgba8,
    hard: &ShadowMatte,
    steps_px: &[f32],
    exclude: Option<&Mask>,
    same_surface: Option<SameSurface<'_>>,
) -> Result<Vec<Option<OutlineDarkening>>, DiminishError> {
    Ok(outline_pairs(image, hard, steps_px, exclude, same_surface)?
        .into_iter()
        .map(|mut p| p.summary())
        .collect())
}

/// The pairs of [`outline_darkenings`], each as its clamped log-ratio and its per-channel
/// inside / outside.
#[derive(Debug, Clone, Default)]
struct OutlinePairs {
    logs: Vec<f32>,
    ratios: [Vec<f32>; 3],
}

impl OutlinePairs {
    fn len(&self) -> usize {
        self.logs.len()
    }

    fn append(&mut self, mut other: OutlinePairs) {
        self.logs.append(&mut other.logs);
        for (a, b) in self.ratios.iter_mut().zip(other.ratios.iter_mut()) {
            a.append(b);
        }
    }

    /// [`outline_darkenings`]'s summary (the pairs reordered, not changed); `None` without
    /// pairs.
    fn summary(&mut self) -> Option<OutlineDarkening> {
        let n = self.logs.len();
        if n == 0 {
            return None;
        }
        let mut rgb = [1.0f32; 3];
        for (c, r) in self.ratios.iter_mut().enumerate() {
            rgb[c] = median(r).clamp(MIN_RATIO, 1.0);
        }
        let mean_log = self.logs.iter().map(|&v| f64::from(v)).sum::<f64>() / n as f64;
        Some(OutlineDarkening {
            score: f64::from(median(&mut self.logs)) * n as f64,
            mean_log,
            ratio: ShadowRatio {
                rgb,
                shadow_samples: n,
                lit_samples: n,
            },
        })
    }
}

/// The pairs across the outline of `hard` at each of `steps_px` (one scan of the outline for
/// all): see [`outline_darkenings`].
fn outline_pairs(
    image: &ImageRgba8,
    hard: &ShadowMatte,
    steps_px: &[f32],
    exclude: Option<&Mask>,
    same_surface: Option<SameSurface<'_>>,
) -> Result<Vec<OutlinePairs>, DiminishError> {
    check(image, hard, exclude)?;
    let lut = decode_lut();
    let rect = hard.rect;
    let (rw, rh) = (rect.width as i64, rect.height as i64);
    let fw = image.width() as usize;
    let px = image.as_slice();
    let inside = |lx: i64, ly: i64| {
        lx >= 0 && ly >= 0 && lx < rw && ly < rh && hard.weights[(ly * rw + lx) as usize] >= 0.5
    };
    let rgb = |lx: i64, ly: i64| -> Option<[f32; 3]> {
        if lx < 0 || ly < 0 || lx >= rw || ly >= rh {
            return None;
        }
        let i = (rect.y as usize + ly as usize) * fw + rect.x as usize + lx as usize;
        if exclude.is_some_and(|m| m.as_slice()[i] != 0) {
            return None;
        }
        let p = &px[i * 4..i * 4 + 3];
        Some([lut[p[0] as usize], lut[p[1] as usize], lut[p[2] as usize]])
    };
    let lum = |c: [f32; 3]| 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2];
    let mut out = vec![OutlinePairs::default(); steps_px.len()];
    for ly in 0..rh {
        for lx in 0..rw {
            if !inside(lx, ly)
                || (inside(lx - 1, ly)
                    && inside(lx + 1, ly)
                    && inside(lx, ly - 1)
                    && inside(lx, ly + 1))
            {
                continue;
            }
            // The outward normal: from the centre of the inside pixels of the 5x5
            // neighbourhood toward this pixel's outside ones.
            let (mut gx, mut gy) = (0.0f32, 0.0f32);
            for dy in -2..=2i64 {
                for dx in -2..=2i64 {
                    if !inside(lx + dx, ly + dy) {
                        gx += dx as f32;
                        gy += dy as f32;
                    }
                }
            }
            let g = (gx * gx + gy * gy).sqrt();
            if g < 1e-3 {
                continue;
            }
            let (nx, ny) = (gx / g, gy / g);
            for (&step_px, pairs) in steps_px.iter().zip(out.iter_mut()) {
                let (ix, iy) = (
                    (lx as f32 - nx * step_px).round() as i64,
                    (ly as f32 - ny * step_px).round() as i64,
                );
                let (ox, oy) = (
                    (lx as f32 + nx * (step_px + 1.0)).round() as i64,
                    (ly as f32 + ny * (step_px + 1.0)).round() as i64,
                );
                if !inside(ix, iy) || inside(ox, oy) {
                    continue;
                }
                let (Some(ci), Some(co)) = (rgb(ix, iy), rgb(ox, oy)) else {
                    continue;
                };
                let at = |lx: i64, ly: i64| [rect.x + lx as u32, rect.y + ly as u32];
                if same_surface.is_some_and(|same| !same(at(ix, iy), at(ox, oy))) {
                    continue;
                }
                let (yi, yo) = (lum(ci), lum(co));
                if yo < 1e-3 {
                    continue;
                }
                pairs.logs.push((yo / yi.max(1e-4)).ln().clamp(-1.5, 1.5));
                for (c, r) in pairs.ratios.iter_mut().enumerate() {
                    r.push(if co[c] > 1e-4 { ci[c] / co[c] } else { 1.0 });
                }
            }
        }
    }
    Ok(out)
}

/// The median linear luminance of the lit pixels of the matte's rectangle (weight below
/// [`LIT_WEIGHT`], not excluded); `None` without any.
pub fn lit_luminance(
    image: &ImageRgba8,
    matte: &ShadowMatte,
    exclude: Option<&Mask>,
) -> Result<Option<f32>, DiminishError> {
    check(image, matte, exclude)?;
    let mut v: Vec<f32> = samples(image, matte, exclude)
        .filter(|(w, _)| *w < LIT_WEIGHT)
        .map(|(_, c)| 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2])
        .collect();
    Ok((!v.is_empty()).then(|| median(&mut v)))
}

/// The Gaussian softness (standard deviation, pixels) among `candidates_px` that best explains
/// the observed shadow under the hard matte `hard` ([`shadow_fit_error`] of the softened
/// matte with the ratio measured on it). `Ok(None)` when no candidate can be measured.
pub fn fit_softness(
    image: &ImageRgba8,
    hard: &ShadowMatte,
    candidates_px: &[f32],
    exclude: Option<&Mask>,
) -> Result<Option<(f32, ShadowRatio)>, DiminishError> {
    let mut best: Option<(f64, f32, ShadowRatio)> = None;
    // Every candidate is compared over the same pixels: the widest candidate's rectangle.
    let widest = hard.soften(candidates_px.iter().copied().fold(0.0, f32::max))?;
    for &sigma in candidates_px {
        let soft = hard.soften(sigma)?;
        let (Some(ratio), Some(lit)) = (
            measure_shadow(image, &soft, exclude)?,
            lit_luminance(image, &soft, exclude)?,
        ) else {
            continue;
        };
        let soft_wide = reframe(&soft, widest.rect);
        if let Some(e) = shadow_fit_error(image, &soft_wide, &ratio, lit, exclude)? {
            if best.as_ref().is_none_or(|b| e < b.0) {
                best = Some((e, sigma, ratio));
            }
        }
    }
    Ok(best.map(|(_, s, r)| (s, r)))
}

/// Distances (pixels past the outline) at which [`fit_outline`] compares pairs.
pub const OUTLINE_FIT_STEPS_PX: [f32; 8] = [1.0, 2.0, 3.0, 4.0, 6.0, 8.0, 11.0, 15.0];

/// Fewest pairs, over all of [`OUTLINE_FIT_STEPS_PX`], for [`fit_outline`].
pub const MIN_OUTLINE_FIT_PAIRS: usize = 48;

/// Fewest pairs past the penumbra for [`fit_outline`] to take the darkening from them.
pub const MIN_OUTLINE_PAST_PAIRS: usize = 16;

/// What [`fit_outline`] found.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OutlineFit {
    /// Gaussian standard deviation of the penumbra, pixels.
    pub softness_px: f32,
    /// Shadowed over lit, per channel: the median of the pairs past the penumbra, else the
    /// fitted luminance ratio; its sample counts are all the pairs compared.
    pub ratio: ShadowRatio,
}

/// The standard normal distribution function (Abramowitz and Stegun 7.1.26, error below
/// 1.5e-7).
fn normal_cdf(x: f64) -> f64 {
    let z = x.abs() / std::f64::consts::SQRT_2;
    let t = 1.0 / (1.0 + 0.327_591_1 * z);
    let poly = t
        * (0.254_829_592
            + t * (-0.284_496_736
                + t * (1.421_413_741 + t * (-1.453_152_027 + t * 1.061_405_429))));
    let erf = 1.0 - poly * (-z * z).exp();
    0.5 * (1.0 + if x < 0.0 { -erf } else { erf })
}

/// The softness and darkening of the shadow under the hard matte `hard`, from its outline
/// alone: the median ratio of the pairs across it ([`outline_darkenings`]) at each distance of
/// [`OUTLINE_FIT_STEPS_PX`] follows, for a Gaussian penumbra of deviation `sigma` and a
/// darkening `s`, `(1 - (1 - s) P(d / sigma)) / (1 - (1 - s) P(-d / sigma))` (`P` the normal
/// distribution, `d` the distance from the edge); the candidate of `candidates_px` and the `s`
/// (steps of 0.01) that fit the medians best in the log, each weighted by its pairs, win; the
/// darkening is then the median of all pairs past the penumbra, where there are
/// [`MIN_OUTLINE_PAST_PAIRS`] of them.
/// Every pair compares one surface with itself a few pixels away (with `same_surface`, the
/// same print), so the fit does not care what the table's albedo is, where the medians of
/// [`fit_softness`] compare the shadow's surfaces with the lit ring's. `None` with fewer than
/// [`MIN_OUTLINE_FIT_PAIRS`] pairs.
pub fn fit_outline(
    image: &ImageRgba8,
    hard: &ShadowMatte,
    candidates_px: &[f32],
    exclude: Option<&Mask>,
    same_surface: Option<SameSurface<'_>>,
) -> Result<Option<OutlineFit>, DiminishError> {
    // Per distance with pairs: the distance from the edge, the median luminance ratio, the
    // pair count, and the pairs.
    let mut steps: Vec<(f64, f64, usize, OutlinePairs)> = Vec::new();
    let all = outline_pairs(image, hard, &OUTLINE_FIT_STEPS_PX, exclude, same_surface)?;
    for (&d, mut p) in OUTLINE_FIT_STEPS_PX.iter().zip(all) {
        if let Some(o) = p.summary() {
            let r = f64::from(o.ratio.luminance()).clamp(f64::from(MIN_RATIO), 1.0);
            // The outline pixel is inside: the edge lies half a pixel beyond it.
            steps.push((f64::from(d) + 0.5, r, o.ratio.shadow_samples, p));
        }
    }
    let pairs: usize = steps.iter().map(|s| s.2).sum();
    if pairs < MIN_OUTLINE_FIT_PAIRS {
        return Ok(None);
    }
    let mut best: Option<(f64, f32, f64)> = None;
    for &sigma in candidates_px {
        let sigma64 = f64::from(sigma.max(1e-3));
        for k in 5..=99 {
            let s = f64::from(k) * 0.01;
            let err: f64 = steps
                .iter()
                .map(|&(d, r, n, _)| {
                    let p = normal_cdf(d / sigma64);
                    let pred = (1.0 - (1.0 - s) * p) / (1.0 - (1.0 - s) * (1.0 - p));
                    n as f64 * (r.ln() - pred.ln()).powi(2)
                })
                .sum();
            if best.is_none_or(|b| err < b.0) {
                best = Some((err, sigma, s));
            }
        }
    }
    let Some((_, softness_px, s)) = best else {
        return Ok(None);
    };
    // The darkening from all pairs past the penumbra (three deviations) pooled, where there
    // are enough of them: there the shadow is its full darkness, and one median over every
    // distance is not pulled by a texture that darkens the pairs of one distance. Else the
    // fitted ratio, in every channel.
    let mut past = OutlinePairs::default();
    for (d, _, _, p) in steps {
        if d >= 3.0 * f64::from(softness_px) {
            past.append(p);
        }
    }
    let rgb = if past.len() >= MIN_OUTLINE_PAST_PAIRS {
        past.summary().map_or([s as f32; 3], |o| o.ratio.rgb)
    } else {
        [s as f32; 3]
    };
    Ok(Some(OutlineFit {
        softness_px,
        ratio: ShadowRatio {
            rgb,
            shadow_samples: pairs,
            lit_samples: pairs,
        },
    }))
}

/// `matte` over a larger rectangle `rect` (which contains its own), zero outside.
fn reframe(matte: &ShadowMatte, rect: Rect) -> ShadowMatte {
    let rw = rect.width as usize;
    let mut weights = vec![0.0f32; rect.area()];
    let sw = matte.rect.width as usize;
    for (ly, row) in matte.weights.chunks_exact(sw).enumerate() {
        let y = (matte.rect.y - rect.y) as usize + ly;
        let o = y * rw + (matte.rect.x - rect.x) as usize;
        weights[o..o + sw].copy_from_slice(row);
    }
    ShadowMatte {
        rect,
        weights,
        frame: matte.frame,
    }
}

/// Applies the factor `f(w, c)` (linear light) to the matte's pixels of `image`.
fn scale(
    image: &mut ImageRgba8,
    matte: &ShadowMatte,
    ratio: [f32; 3],
    lift: bool,
) -> Result<usize, DiminishError> {
    crate::types::ensure_same_size("shadow matte's frame", image.size(), matte.frame)?;
    if ratio.iter().any(|r| !r.is_finite()) {
        return Err(DiminishError::InvalidParameter {
            name: "shadow ratio",
            value: f64::from(ratio[0] + ratio[1] + ratio[2]),
            reason: "must be finite",
        });
    }
    let ratio = ratio.map(|r| r.clamp(MIN_RATIO, 1.0));
    let lut = decode_lut();
    let fw = image.width() as usize;
    let rect = matte.rect;
    let rw = rect.width as usize;
    let px = image.as_mut_slice();
    let mut n = 0;
    for (k, &w) in matte.weights.iter().enumerate() {
        if w <= 0.0 {
            continue;
        }
        let (lx, ly) = (k % rw, k / rw);
        let i = (rect.y as usize + ly) * fw + rect.x as usize + lx;
        for c in 0..3 {
            let f = 1.0 - w * (1.0 - ratio[c]);
            let v = lut[px[i * 4 + c] as usize];
            px[i * 4 + c] = encode_linear(if lift { v / f } else { v * f });
        }
        n += 1;
    }
    Ok(n)
}

/// Lifts the shadow `matte` out of `image` (in place): each pixel's linear colour divided by
/// `1 - w (1 - s)` per channel, `s` the ratio shadowed / lit (clamped to [[`MIN_RATIO`], 1];
/// values beyond white clip). Returns the pixels changed.
pub fn lift_shadow(
    image: &mut ImageRgba8,
    matte: &ShadowMatte,
    ratio: [f32; 3],
) -> Result<usize, DiminishError> {
    scale(image, matte, ratio, true)
}

/// Casts the shadow `matte` onto `image` (in place): each pixel's linear colour times
/// `1 - w (1 - s)` per channel, the inverse of [`lift_shadow`]. Returns the pixels changed.
pub fn cast_shadow(
    image: &mut ImageRgba8,
    matte: &ShadowMatte,
    ratio: [f32; 3],
) -> Result<usize, DiminishError> {
    scale(image, matte, ratio, false)
}

#[cfg(test)]
#[path = "shadow_tests.rs"]
mod tests;
