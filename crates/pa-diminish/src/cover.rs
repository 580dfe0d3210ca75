//! Covering a printed sheet in the frame with another picture, lit like the sheet.
//!
//! The caller (the pipeline, which knows the camera) hands in [`SheetCoords`]: for every pixel
//! of a rectangle of the frame, where its centre falls on the sheet, as sheet coordinates
//! `(s, t)` in `[0, 1]^2` (`s` along the sheet's width, `t` down it; NaN where the pixel sees
//! no point of the plane). Everything here is generic image work:
//!
//! - **Light.** The sheet's white paper (sheet coordinates outside the `not_paper` rectangles,
//!   the tags, and away from the sheet's edge) is sampled in the current frame, in linear
//!   light, and a per-channel affine shading `L(s, t) = a + b s + c t` is fitted by least
//!   squares with one robust refit (residuals beyond 3 robust sigmas dropped: the prop's
//!   shadow, a hand). Paper is taken as the cover's white: a cover pixel of linear value `c`
//!   becomes `c * L(s, t)`, as the picture printed on that paper would be under that light.
//! - **Picture.** The cover is kept as a linear-light mip chain ([`CoverImage`]); each pixel
//!   samples it trilinearly at `(s, t)` with the level chosen from the pixel's footprint on
//!   the cover (the finite-difference Jacobian of the coordinates), so a large picture seen
//!   small does not alias.
//! - **Edge.** The pixel's coverage is its signed distance to the sheet's nearest edge in
//!   pixels, plus one half, clamped to `[0, 1]` (the edge's distance is the coordinate over
//!   its gradient's length); edge pixels blend cover and frame in linear light.
//!
//! Work is O(rectangle) with one pass for the fit and one for the paste.

use crate::error::DiminishError;
use crate::plate::{decode_lut, encode_linear};
use crate::types::{ImageRgba8, Mask, Rect};

/// The largest cover accepted, pixels (its linear mip chain takes about 16 bytes a pixel).
pub const MAX_COVER_PIXELS: u64 = 4096 * 4096;

/// Sheet coordinates of each pixel of a rectangle of the frame (see the module docs).
#[derive(Debug, Clone, PartialEq)]
pub struct SheetCoords {
    /// The rectangle, in frame pixels.
    pub rect: Rect,
    /// `(s, t)` per pixel of `rect`, row-major; NaN where the pixel sees no sheet plane.
    pub st: Vec<[f32; 2]>,
}

impl SheetCoords {
    fn at(&self, x: i64, y: i64) -> Option<[f32; 2]> {
        let r = &self.rect;
        if x < r.x as i64 || y < r.y as i64 || x >= r.right() as i64 || y >= r.bottom() as i64 {
            return None;
        }
        let i = (y - r.y as i64) as usize * r.width as usize + (x - r.x as i64) as usize;
        self.st
            .get(i)
            .copied()
            .filter(|p| p[0].is_finite() && p[1].is_finite())
    }

    /// `(s, t)` at `(x, y)` and its derivatives along x and y (central differences where both
    /// neighbours are known, one-sided otherwise; zero where neither is).
    fn with_jacobian(&self, x: i64, y: i64) -> Option<([f32; 2], [f32; 2], [f32; 2])> {
        let p = self.at(x, y)?;
        let d = |a: Option<[f32; 2]>, b: Option<[f32; 2]>| match (a, b) {
            (Some(a), Some(b)) => [(b[0] - a[0]) * 0.5, (b[1] - a[1]) * 0.5],
            (None, Some(b)) => [b[0] - p[0], b[1] - p[1]],
            (Some(a), None) => [p[0] - a[0], p[1] - a[1]],
            (None, None) => [0.0, 0.0],
        };
        let dx = d(self.at(x - 1, y), self.at(x + 1, y));
        let dy = d(self.at(x, y - 1), self.at(x, y + 1));
        Some((p, dx, dy))
    }

    /// The fraction of the pixel at `(x, y)` that the sheet covers (see the module docs).
    pub fn coverage(&self, x: i64, y: i64) -> f32 {
        match self.with_jacobian(x, y) {
            Some((p, dx, dy)) => coverage(p, dx, dy),
            None => 0.0,
        }
    }

    /// The pixels the sheet covers at all (coverage > 0), as a mask of a `width x height`
    /// frame, and their bounding box.
    pub fn mask(&self, width: u32, height: u32) -> Result<(Mask, Option<Rect>), DiminishError> {
        let mut m = Mask::zeros(width, height)?;
        let mut bbox: Option<(u32, u32, u32, u32)> = None;
        let r = self.rect;
        for y in r.y..r.bottom().min(height) {
            for x in r.x..r.right().min(width) {
                if self.coverage(x as i64, y as i64) > 0.0 {
                    m.as_mut_slice()[(y * width + x) as usize] = Mask::SET;
                    bbox = Some(match bbox {
                        None => (x, y, x, y),
                        Some((a, b, c, d)) => (a.min(x), b.min(y), c.max(x), d.max(y)),
                    });
                }
            }
        }
        Ok((m, bbox.map(|(a, b, c, d)| Rect::from_inclusive(a, b, c, d))))
    }
}

/// Coverage of a pixel whose centre is at sheet coordinates `p` with derivatives `dx`, `dy`.
fn coverage(p: [f32; 2], dx: [f32; 2], dy: [f32; 2]) -> f32 {
    let gs = (dx[0] * dx[0] + dy[0] * dy[0]).sqrt();
    let gt = (dx[1] * dx[1] + dy[1] * dy[1]).sqrt();
    if gs <= 0.0 || gt <= 0.0 {
        let inside = (0.0..=1.0).contains(&p[0]) && (0.0..=1.0).contains(&p[1]);
        return if inside { 1.0 } else { 0.0 };
    }
    let d = (p[0] / gs)
        .min((1.0 - p[0]) / gs)
        .min(p[1] / gt)
        .min((1.0 - p[1]) / gt);
    (d + 0.5).clamp(0.0, 1.0)
}

/// A cover picture as a linear-light RGB mip chain (level 0 the picture, each next level a
/// 2x2 box average of the one before, down to one pixel).
#[derive(Debug, Clone, PartialEq)]
pub struct CoverImage {
    levels: Vec<(u32, u32, Vec<[f32; 3]>)>,
}

impl CoverImage {
    /// Decodes `picture` (sRGB; alpha ignored: the cover is printed opaque) and builds the
    /// chain. Errors when it has more than [`MAX_COVER_PIXELS`] pixels.
    pub fn new(picture: &ImageRgba8) -> Result<Self, DiminishError> {
        let (w, h) = picture.size();
        let n = w as u64 * h as u64;
        if n > MAX_COVER_PIXELS {
            return Err(DiminishError::InvalidParameter {
                name: "cover pixels",
                value: n as f64,
                reason: "the cover picture is larger than 4096x4096 pixels",
            });
        }
        let lut = decode_lut();
        let base: Vec<[f32; 3]> = picture
            .as_slice()
            .chunks_exact(4)
            .map(|p| [lut[p[0] as usize], lut[p[1] as usize], lut[p[2] as usize]])
            .collect();
        let mut levels = vec![(w, h, base)];
        while let Some((lw, lh, prev)) = levels.last() {
            if *lw == 1 && *lh == 1 {
                break;
            }
            let (nw, nh) = ((lw / 2).max(1), (lh / 2).max(1));
            let mut next = Vec::with_capacity((nw * nh) as usize);
            for y in 0..nh {
                for x in 0..nw {
                    let mut acc = [0.0f32; 3];
                    for (sx, sy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                        let px = (2 * x + sx).min(lw - 1);
                        let py = (2 * y + sy).min(lh - 1);
                        let v = prev[(py * lw + px) as usize];
                        for c in 0..3 {
                            acc[c] += v[c] * 0.25;
                        }
                    }
                    next.push(acc);
                }
            }
            levels.push((nw, nh, next));
        }
        Ok(Self { levels })
    }

    /// The picture's size, pixels.
    pub fn size(&self) -> (u32, u32) {
        (self.levels[0].0, self.levels[0].1)
    }

    /// Bilinear sample of one level at `(s, t)` in `[0, 1]^2` (texel centres at half
    /// integers, clamped at the edges).
    fn bilinear(&self, level: usize, s: f32, t: f32) -> [f32; 3] {
        let (w, h, data) = &self.levels[level.min(self.levels.len() - 1)];
        let x = (s * *w as f32 - 0.5).clamp(0.0, (*w - 1) as f32);
        let y = (t * *h as f32 - 0.5).clamp(0.0, (*h - 1) as f32);
        let (x0, y0) = (x.floor() as u32, y.floor() as u32);
        let (x1, y1) = ((x0 + 1).min(w - 1), (y0 + 1).min(h - 1));
        let (fx, fy) = (x - x0 as f32, y - y0 as f32);
        let at = |xx: u32, yy: u32| data[(yy * w + xx) as usize];
        let (a, b, c, d) = (at(x0, y0), at(x1, y0), at(x0, y1), at(x1, y1));
        let mut out = [0.0; 3];
        for k in 0..3 {
            let top = a[k] + (b[k] - a[k]) * fx;
            let bottom = c[k] + (d[k] - c[k]) * fx;
            out[k] = top + (bottom - top) * fy;
        }
        out
    }

    /// Trilinear sample at `(s, t)` for a pixel whose footprint spans `texels` cover pixels.
    pub fn sample(&self, s: f32, t: f32, texels: f32) -> [f32; 3] {
        let lod = texels.max(1.0).log2().min((self.levels.len() - 1) as f32);
        let l0 = lod.floor() as usize;
        let f = lod - l0 as f32;
        let a = self.bilinear(l0, s, t);
        if f <= 0.0 {
            return a;
        }
        let b = self.bilinear(l0 + 1, s, t);
        [
            a[0] + (b[0] - a[0]) * f,
            a[1] + (b[1] - a[1]) * f,
            a[2] + (b[2] - a[2]) * f,
        ]
    }
}

/// The sheet's light: per channel `a + b s + c t` in linear light.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SheetShading {
    pub coeffs: [[f32; 3]; 3],
    /// Paper pixels sampled, and kept by the robust refit.
    pub samples: usize,
    pub inliers: usize,
}

impl SheetShading {
    /// Uniform light of linear value `v` in every channel.
    pub fn uniform(v: f32) -> Self {
        Self {
            coeffs: [[v, 0.0, 0.0]; 3],
            samples: 0,
            inliers: 0,
        }
    }

    /// The light at `(s, t)`, per channel.
    pub fn at(&self, s: f32, t: f32) -> [f32; 3] {
        self.coeffs.map(|c| (c[0] + c[1] * s + c[2] * t).max(0.0))
    }
}

/// Fewest paper samples for the affine fit (fewer: the mean, or nothing).
const MIN_FIT_SAMPLES: usize = 30;

/// Where the paper is, in sheet coordinates: outside `not_paper` (each `[s0, t0, s1, t1]`) and
/// at least `edge_guard` (in `s`, `t`) from the sheet's edges.
#[derive(Debug, Clone, PartialEq)]
pub struct Paper {
    pub not_paper: Vec<[f32; 4]>,
    pub edge_guard: [f32; 2],
}

impl Paper {
    fn contains(&self, p: [f32; 2]) -> bool {
        let g = self.edge_guard;
        p[0] >= g[0]
            && p[0] <= 1.0 - g[0]
            && p[1] >= g[1]
            && p[1] <= 1.0 - g[1]
            && !self
                .not_paper
                .iter()
                .any(|r| p[0] >= r[0] && p[0] <= r[2] && p[1] >= r[1] && p[1] <= r[3])
    }
}

/// Fits the sheet's light from its paper as `frame` shows it (see the module docs). `None`
/// when no paper pixel is visible.
pub fn fit_shading(
    frame: &ImageRgba8,
    coords: &SheetCoords,
    paper: &Paper,
) -> Option<SheetShading> {
    let lut = decode_lut();
    let (w, h) = frame.size();
    let data = frame.as_slice();
    let r = coords.rect;
    // Rows in parallel, concatenated in row order: the same samples in the same order as a
    // serial scan, so the fit does not depend on the thread count.
    use rayon::prelude::*;
    let samples: Vec<([f32; 2], [f32; 3])> = (r.y..r.bottom().min(h))
        .into_par_iter()
        .map(|y| {
            let mut row = Vec::new();
            for x in r.x..r.right().min(w) {
                let Some(p) = coords.at(x as i64, y as i64) else {
                    continue;
                };
                if !paper.contains(p) {
                    continue;
                }
                let i = (y * w + x) as usize * 4;
                row.push((
                    p,
                    [
                        lut[data[i] as usize],
                        lut[data[i + 1] as usize],
                        lut[data[i + 2] as usize],
                    ],
                ));
            }
            row
        })
        .flatten()
        .collect();
    if samples.is_empty() {
        return None;
    }
    let all: Vec<usize> = (0..samples.len()).collect();
    let first = fit_affine(&samples, &all);
    // One robust refit: drop residuals beyond 3 robust sigmas (median absolute deviation of
    // the luminance residual), at least 0.01 linear.
    let resid: Vec<f32> = samples
        .iter()
        .map(|(p, v)| {
            let l = first.at(p[0], p[1]);
            (v[0] - l[0] + v[1] - l[1] + v[2] - l[2]) / 3.0
        })
        .collect();
    let mut abs: Vec<f32> = resid.iter().map(|r| r.abs()).collect();
    // The median by selection (the same element a full sort puts there).
    let mid = abs.len() / 2;
    let (_, &mut mad, _) = abs.select_nth_unstable_by(mid, f32::total_cmp);
    let limit = (3.0 * 1.4826 * mad).max(0.01);
    let kept: Vec<usize> = (0..samples.len())
        .filter(|&i| resid[i].abs() <= limit)
        .collect();
    let mut fit = if kept.len() >= MIN_FIT_SAMPLES.min(samples.len()) && !kept.is_empty() {
        fit_affine(&samples, &kept)
    } else {
        first
    };
    fit.samples = samples.len();
    fit.inliers = if kept.is_empty() {
        samples.len()
    } else {
        kept.len()
    };
    Some(fit)
}

/// Least squares `v = a + b s + c t` per channel over `idx` (the mean when too few samples or
/// too narrow a spread).
fn fit_affine(samples: &[([f32; 2], [f32; 3])], idx: &[usize]) -> SheetShading {
    let n = idx.len().max(1) as f64;
    let mut mean = [0.0f64; 3];
    let (mut ms, mut mt) = (0.0f64, 0.0f64);
    for &i in idx {
        let (p, v) = samples[i];
        ms += p[0] as f64;
        mt += p[1] as f64;
        for c in 0..3 {
            mean[c] += v[c] as f64;
        }
    }
    ms /= n;
    mt /= n;
    mean = mean.map(|m| m / n);
    // Centred normal equations of the slopes.
    let (mut sss, mut sst, mut stt) = (0.0f64, 0.0f64, 0.0f64);
    let mut sv = [[0.0f64; 2]; 3];
    for &i in idx {
        let (p, v) = samples[i];
        let (ds, dt) = (p[0] as f64 - ms, p[1] as f64 - mt);
        sss += ds * ds;
        sst += ds * dt;
        stt += dt * dt;
        for c in 0..3 {
            let dv = v[c] as f64 - mean[c];
            sv[c][0] += ds * dv;
            sv[c][1] += dt * dv;
        }
    }
    let det = sss * stt - sst * sst;
    let coeffs = std::array::from_fn(|c| {
        if idx.len() < MIN_FIT_SAMPLES || det <= 1e-12 * n * n {
            return [mean[c] as f32, 0.0, 0.0];
        }
        let b = (stt * sv[c][0] - sst * sv[c][1]) / det;
        let cc = (sss * sv[c][1] - sst * sv[c][0]) / det;
        [(mean[c] - b * ms - cc * mt) as f32, b as f32, cc as f32]
    });
    SheetShading {
        coeffs,
        samples: idx.len(),
        inliers: idx.len(),
    }
}

/// What [`paste_cover`] did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CoverStats {
    /// Pixels written (coverage > 0).
    pub pasted: usize,
    /// The light used.
    pub shading: SheetShading,
}

/// Lays `cover` over the sheet in `frame`, lit by `shading` (from [`fit_shading`]), with
/// anti-aliased edges (see the module docs).
pub fn paste_cover(
    frame: &mut ImageRgba8,
    coords: &SheetCoords,
    cover: &CoverImage,
    shading: &SheetShading,
) -> Result<CoverStats, DiminishError> {
    let (w, h) = frame.size();
    if coords.st.len() != coords.rect.area() {
        return Err(DiminishError::BufferLength {
            what: "sheet coordinates",
            width: coords.rect.width,
            height: coords.rect.height,
            channels: 1,
            expected: coords.rect.area(),
            actual: coords.st.len(),
        });
    }
    let lut = decode_lut();
    let (cw, ch) = cover.size();
    let r = coords.rect;
    let data = frame.as_mut_slice();
    // Rows in parallel: each pixel depends on the coordinates and the cover only, so the
    // result is the same for any thread count.
    use rayon::prelude::*;
    let (y0, y1) = (r.y.min(h), r.bottom().min(h));
    let pasted = data
        .par_chunks_mut(w as usize * 4)
        .enumerate()
        .skip(y0 as usize)
        .take((y1 - y0) as usize)
        .map(|(y, row)| {
            let mut pasted = 0usize;
            for x in r.x..r.right().min(w) {
                let Some((p, dx, dy)) = coords.with_jacobian(x as i64, y as i64) else {
                    continue;
                };
                let cov = coverage(p, dx, dy);
                if cov <= 0.0 {
                    continue;
                }
                let (s, t) = (p[0].clamp(0.0, 1.0), p[1].clamp(0.0, 1.0));
                let fx = ((dx[0] * cw as f32).powi(2) + (dx[1] * ch as f32).powi(2)).sqrt();
                let fy = ((dy[0] * cw as f32).powi(2) + (dy[1] * ch as f32).powi(2)).sqrt();
                let c = cover.sample(s, t, fx.max(fy));
                let light = shading.at(s, t);
                let i = x as usize * 4;
                for k in 0..3 {
                    let bg = lut[row[i + k] as usize];
                    let v = c[k] * light[k];
                    row[i + k] = encode_linear(cov * v + (1.0 - cov) * bg);
                }
                pasted += 1;
            }
            pasted
        })
        .sum();
    Ok(CoverStats {
        pasted,
        shading: *shading,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An axis-aligned sheet over pixels [x0, x0 + n) x [y0, y0 + n) (pixel edges), in a
    /// rectangle one pixel larger each side.
    fn square_coords(x0: u32, y0: u32, n: u32) -> SheetCoords {
        let rect = Rect::new(x0 - 2, y0 - 2, n + 4, n + 4);
        let mut st = Vec::new();
        for y in rect.y..rect.bottom() {
            for x in rect.x..rect.right() {
                st.push([
                    (x as f32 + 0.5 - x0 as f32) / n as f32,
                    (y as f32 + 0.5 - y0 as f32) / n as f32,
                ]);
            }
        }
        SheetCoords { rect, st }
    }

    #[test]
    fn uniform_cover_on_uniform_paper_takes_the_papers_light() {
        // Frame: paper of linear 0.5 on a black table; cover: white. The result is the paper.
        let (w, h) = (64, 64);
        let paper_byte = encode_linear(0.5);
        let coords = square_coords(10, 12, 40);
        let mut frame = ImageRgba8::from_fn(w, h, |x, y| {
            if (10..50).contains(&x) && (12..52).contains(&y) {
                [paper_byte, paper_byte, paper_byte, 255]
            } else {
                [0, 0, 0, 255]
            }
        })
        .expect("frame");
        let paper = Paper {
            not_paper: vec![[0.4, 0.4, 0.6, 0.6]],
            edge_guard: [0.05, 0.05],
        };
        let shading = fit_shading(&frame, &coords, &paper).expect("paper seen");
        for c in shading.coeffs {
            assert!((c[0] - 0.5).abs() < 0.01 && c[1].abs() < 0.01 && c[2].abs() < 0.01);
        }
        let cover = CoverImage::new(&ImageRgba8::filled(8, 8, [255, 255, 255, 255]).expect("c"))
            .expect("cover");
        let stats = paste_cover(&mut frame, &coords, &cover, &shading).expect("paste");
        assert_eq!(stats.pasted, 40 * 40, "exactly the sheet's pixels");
        for y in 0..h {
            for x in 0..w {
                let inside = (10..50).contains(&x) && (12..52).contains(&y);
                let v = frame.get(x, y).expect("pixel")[0];
                let want = if inside { paper_byte } else { 0 };
                assert!(v.abs_diff(want) <= 1, "({x}, {y}): {v} vs {want}");
            }
        }
    }

    #[test]
    fn shading_gradient_is_recovered_despite_a_dark_occluder() {
        // Paper lit by 0.3 + 0.4 s (linear), with a black blob over a tenth of it.
        let (w, h) = (80, 80);
        let coords = square_coords(10, 10, 60);
        let frame = ImageRgba8::from_fn(w, h, |x, y| {
            let s = (x as f32 + 0.5 - 10.0) / 60.0;
            if (20..30).contains(&x) && (20..50).contains(&y) {
                return [0, 0, 0, 255];
            }
            let v = encode_linear(0.3 + 0.4 * s);
            [v, v, v, 255]
        })
        .expect("frame");
        let paper = Paper {
            not_paper: vec![],
            edge_guard: [0.03, 0.03],
        };
        let sh = fit_shading(&frame, &coords, &paper).expect("paper");
        assert!(sh.inliers < sh.samples, "the blob is rejected");
        for c in sh.coeffs {
            assert!((c[0] - 0.3).abs() < 0.01, "{c:?}");
            assert!((c[1] - 0.4).abs() < 0.015, "{c:?}");
            assert!(c[2].abs() < 0.01, "{c:?}");
        }
    }

    #[test]
    fn half_covered_edge_pixels_blend_half() {
        // A sheet whose left edge lies on pixel 10's centre: that column is half covered.
        let rect = Rect::new(5, 5, 20, 20);
        let mut st = Vec::new();
        for y in rect.y..rect.bottom() {
            for x in rect.x..rect.right() {
                st.push([(x as f32 - 10.0) / 10.0, (y as f32 - 7.3) / 10.0]);
            }
        }
        let coords = SheetCoords { rect, st };
        assert!((coords.coverage(10, 12) - 0.5).abs() < 1e-5);
        assert_eq!(coords.coverage(9, 12), 0.0);
        assert_eq!(coords.coverage(12, 12), 1.0);
        let (mask, bbox) = coords.mask(40, 40).expect("mask");
        // Columns 10..=20 (half at both ends), rows 7 (a fifth) ..=17.
        assert!((coords.coverage(12, 7) - 0.2).abs() < 1e-5);
        assert_eq!(bbox, Some(Rect::from_inclusive(10, 7, 20, 17)));
        assert_eq!(mask.as_slice().iter().filter(|&&v| v != 0).count(), 11 * 11);
    }

    #[test]
    fn mip_chain_averages_a_checkerboard_to_grey() {
        let img = ImageRgba8::from_fn(64, 64, |x, y| {
            let v = if (x + y) % 2 == 0 { 255 } else { 0 };
            [v, v, v, 255]
        })
        .expect("img");
        let c = CoverImage::new(&img).expect("cover");
        // Seen 16 texels to a pixel: the average, 0.5 linear.
        let v = c.sample(0.5, 0.5, 16.0);
        assert!((v[0] - 0.5).abs() < 1e-3, "{v:?}");
        // Seen 1:1 at a texel centre: the texel.
        let t = c.sample(0.5 / 64.0, 0.5 / 64.0, 1.0);
        assert!((t[0] - 1.0).abs() < 1e-6, "{t:?}");
    }

    #[test]
    fn too_large_a_cover_is_refused() {
        let big = ImageRgba8::filled(4097, 4096, [0, 0, 0, 255]).expect("img");
        assert!(matches!(
            CoverImage::new(&big),
            Err(DiminishError::InvalidParameter { .. })
        ));
    }
}
