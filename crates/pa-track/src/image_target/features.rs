//! Keypoints and binary descriptors (ORB-like, our own): FAST-9 corners ranked by a Harris
//! score with 3x3 non-maximum suppression, kept spread over a grid, on an image pyramid
//! (factor sqrt 2); orientation by the intensity centroid; 256-bit steered BRIEF descriptors
//! on a smoothed copy of each level.

use rayon::prelude::*;

use crate::GrayImage;

/// Pyramid scale step between levels.
pub const LEVEL_SCALE: f32 = std::f32::consts::SQRT_2;
/// Half side of the descriptor patch; pairs lie within this radius after rotation.
const PATCH_RADIUS: i32 = 13;
/// Keypoints keep this distance (pixels of their level) from the level's border.
pub const BORDER: i32 = 20;
/// Radius of the orientation (intensity centroid) disc.
const ORIENT_RADIUS: i32 = 12;

/// A 256-bit binary descriptor.
pub type Descriptor = [u64; 4];

/// Hamming distance of two descriptors.
#[inline]
pub fn hamming(a: &Descriptor, b: &Descriptor) -> u32 {
    (a[0] ^ b[0]).count_ones()
        + (a[1] ^ b[1]).count_ones()
        + (a[2] ^ b[2]).count_ones()
        + (a[3] ^ b[3]).count_ones()
}

/// An 8-bit image level.
#[derive(Debug, Clone, PartialEq)]
pub struct Level {
    pub width: usize,
    pub height: usize,
    pub data: Vec<u8>,
    /// Level-0 pixels per pixel of this level.
    pub scale: f32,
}

impl Level {
    #[inline]
    pub fn at(&self, x: i32, y: i32) -> u8 {
        self.data[y as usize * self.width + x as usize]
    }

    /// Bilinear sample at (x, y) (pixel centres at integers), clamped at the border.
    #[inline]
    pub fn sample(&self, x: f32, y: f32) -> f32 {
        if self.width == 0 || self.height == 0 {
            return 0.0;
        }
        let xm = (self.width - 1) as f32;
        let ym = (self.height - 1) as f32;
        let x = x.clamp(0.0, xm);
        let y = y.clamp(0.0, ym);
        let x0 = (x as usize).min(self.width.saturating_sub(2));
        let y0 = (y as usize).min(self.height.saturating_sub(2));
        let fx = x - x0 as f32;
        let fy = y - y0 as f32;
        let i = y0 * self.width + x0;
        let x1 = if self.width > 1 { 1 } else { 0 };
        let y1 = if self.height > 1 { self.width } else { 0 };
        let a = self.data[i] as f32;
        let b = self.data[i + x1] as f32;
        let c = self.data[i + y1] as f32;
        let d = self.data[i + x1 + y1] as f32;
        let top = a + (b - a) * fx;
        let bot = c + (d - c) * fx;
        top + (bot - top) * fy
    }

    /// From a gray image.
    pub fn from_gray(img: &GrayImage) -> Self {
        Self {
            width: img.width as usize,
            height: img.height as usize,
            data: img.data.clone(),
            scale: 1.0,
        }
    }

    /// This level resampled by `1 / factor` (area-averaging for factor 2, bilinear with a
    /// pre-blur otherwise).
    pub fn downscaled(&self, factor: f32) -> Self {
        let w = ((self.width as f32 / factor).floor() as usize).max(1);
        let h = ((self.height as f32 / factor).floor() as usize).max(1);
        let mut data = vec![0u8; w * h];
        if (factor - 2.0).abs() < 1e-6 {
            data.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
                let r0 = 2 * y * self.width;
                let r1 = r0 + self.width;
                for (x, out) in row.iter_mut().enumerate() {
                    let s = self.data[r0 + 2 * x] as u32
                        + self.data[r0 + 2 * x + 1] as u32
                        + self.data[r1 + 2 * x] as u32
                        + self.data[r1 + 2 * x + 1] as u32;
                    *out = ((s + 2) / 4) as u8;
                }
            });
        } else {
            let src = self.blurred();
            data.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
                let sy = (y as f32 + 0.5) * factor - 0.5;
                for (x, out) in row.iter_mut().enumerate() {
                    let sx = (x as f32 + 0.5) * factor - 0.5;
                    *out = (src.sample(sx, sy) + 0.5) as u8;
                }
            });
        }
        Self {
            width: w,
            height: h,
            data,
            scale: self.scale * factor,
        }
    }

    /// A [1 4 6 4 1] / 16 separable blur (border pixels replicated).
    pub fn blurred(&self) -> Self {
        let (w, h) = (self.width, self.height);
        if w == 0 || h == 0 {
            return self.clone();
        }
        let mut tmp = vec![0u16; w * h];
        tmp.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
            let src = &self.data[y * w..(y + 1) * w];
            for (x, out) in row.iter_mut().enumerate() {
                let g = |dx: isize| src[(x as isize + dx).clamp(0, w as isize - 1) as usize] as u16;
                *out = g(-2) + 4 * g(-1) + 6 * g(0) + 4 * g(1) + g(2);
            }
        });
        let mut data = vec![0u8; w * h];
        data.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
            let g = |dy: isize, x: usize| {
                tmp[(y as isize + dy).clamp(0, h as isize - 1) as usize * w + x] as u32
            };
            for (x, out) in row.iter_mut().enumerate() {
                let s = g(-2, x) + 4 * g(-1, x) + 6 * g(0, x) + 4 * g(1, x) + g(2, x);
                *out = ((s + 128) / 256) as u8;
            }
        });
        Self {
            width: w,
            height: h,
            data,
            scale: self.scale,
        }
    }
}

/// An image pyramid with factor [`LEVEL_SCALE`] between levels.
pub fn pyramid(img: &GrayImage, levels: usize) -> Vec<Level> {
    let mut out = vec![Level::from_gray(img)];
    let min_side = 2 * BORDER as usize + 8;
    while out.len() < levels.max(1) {
        let n = out.len();
        let last = &out[n - 1];
        if (last.width.min(last.height) as f32 / LEVEL_SCALE) < min_side as f32 {
            break;
        }
        // Even levels from the level two below (factor 2, exact), odd ones from level 0.
        let next = if n >= 2 {
            out[n - 2].downscaled(2.0)
        } else {
            out[0].downscaled(LEVEL_SCALE)
        };
        if next.width < min_side || next.height < min_side {
            break;
        }
        out.push(next);
    }
    out
}

/// A keypoint in level-0 pixels (pixel centres at integers).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Keypoint {
    pub x: f32,
    pub y: f32,
    pub level: u8,
    /// Orientation, radians.
    pub angle: f32,
    /// Harris response (larger is stronger).
    pub score: f32,
}

/// Detector settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FeatureConfig {
    /// FAST intensity threshold.
    pub fast_threshold: u8,
    /// Keypoints kept over all levels (spread over a grid per level).
    pub max_keypoints: usize,
    /// Grid cell side (pixels of the level) for the spread.
    pub cell_px: usize,
}

impl Default for FeatureConfig {
    fn default() -> Self {
        Self {
            fast_threshold: 18,
            max_keypoints: 1500,
            cell_px: 32,
        }
    }
}

/// The 16 offsets of the radius-3 Bresenham circle, clockwise from the top.
const CIRCLE: [(i32, i32); 16] = [
    (0, -3),
    (1, -3),
    (2, -2),
    (3, -1),
    (3, 0),
    (3, 1),
    (2, 2),
    (1, 3),
    (0, 3),
    (-1, 3),
    (-2, 2),
    (-3, 1),
    (-3, 0),
    (-3, -1),
    (-2, -3 + 1),
    (-1, -3),
];

#[inline]
fn has_arc9(mask: u32) -> bool {
    let m = mask | (mask << 16);
    let mut r = m;
    for s in 1..9 {
        r &= m >> s;
    }
    r != 0
}

/// Harris response on a 7x7 window (Sobel gradients), k = 0.04.
fn harris(l: &Level, x: i32, y: i32) -> f32 {
    let (mut a, mut b, mut c) = (0f32, 0f32, 0f32);
    for v in y - 3..=y + 3 {
        for u in x - 3..=x + 3 {
            let p = |du: i32, dv: i32| l.at(u + du, v + dv) as f32;
            let gx = (p(1, -1) + 2.0 * p(1, 0) + p(1, 1)) - (p(-1, -1) + 2.0 * p(-1, 0) + p(-1, 1));
            let gy = (p(-1, 1) + 2.0 * p(0, 1) + p(1, 1)) - (p(-1, -1) + 2.0 * p(0, -1) + p(1, -1));
            a += gx * gx;
            b += gy * gy;
            c += gx * gy;
        }
    }
    let det = a * b - c * c;
    let tr = a + b;
    (det - 0.04 * tr * tr) / (49.0 * 49.0 * 16.0)
}

/// FAST-9 corners of one level with their Harris scores after 3x3 non-maximum suppression.
fn fast_level(l: &Level, threshold: u8) -> Vec<(i32, i32, f32)> {
    let (w, h) = (l.width as i32, l.height as i32);
    if w <= 2 * BORDER || h <= 2 * BORDER {
        return Vec::new();
    }
    let t = threshold as i16;
    let offs: Vec<isize> = CIRCLE
        .iter()
        .map(|&(dx, dy)| dy as isize * w as isize + dx as isize)
        .collect();
    let rows: Vec<Vec<(i32, i32, f32)>> = (BORDER..h - BORDER)
        .into_par_iter()
        .map(|y| {
            let mut out = Vec::new();
            for x in BORDER..w - BORDER {
                let i = (y * w + x) as isize;
                let c = l.data[i as usize] as i16;
                let px = |k: usize| l.data[(i + offs[k]) as usize] as i16;
                // Any 9-arc holds two of the four compass points.
                let (p0, p4, p8, p12) = (px(0), px(4), px(8), px(12));
                let br = (p0 > c + t) as u8
                    + (p4 > c + t) as u8
                    + (p8 > c + t) as u8
                    + (p12 > c + t) as u8;
                let dk = (p0 < c - t) as u8
                    + (p4 < c - t) as u8
                    + (p8 < c - t) as u8
                    + (p12 < c - t) as u8;
                if br < 2 && dk < 2 {
                    continue;
                }
                let (mut mb, mut md) = (0u32, 0u32);
                for k in 0..16 {
                    let p = px(k);
                    if p > c + t {
                        mb |= 1 << k;
                    } else if p < c - t {
                        md |= 1 << k;
                    }
                }
                if has_arc9(mb) || has_arc9(md) {
                    out.push((x, y, harris(l, x, y)));
                }
            }
            out
        })
        .collect();
    // 3x3 non-maximum suppression on the corner scores.
    let mut score = vec![f32::NEG_INFINITY; (w * h) as usize];
    for r in &rows {
        for &(x, y, s) in r {
            score[(y * w + x) as usize] = s;
        }
    }
    let mut out = Vec::new();
    for r in rows {
        for (x, y, s) in r {
            if s <= 0.0 {
                continue;
            }
            let mut is_max = true;
            'n: for dy in -1..=1 {
                for dx in -1..=1 {
                    if (dx, dy) != (0, 0) {
                        let o = score[((y + dy) * w + x + dx) as usize];
                        if o > s || (o == s && (dy, dx) < (0, 0)) {
                            is_max = false;
                            break 'n;
                        }
                    }
                }
            }
            if is_max {
                out.push((x, y, s));
            }
        }
    }
    out
}

/// Keeps at most `budget` corners, the strongest of each grid cell first (round robin over
/// cells by rank), so that they spread over the image.
fn spread(
    mut c: Vec<(i32, i32, f32)>,
    w: usize,
    cell: usize,
    budget: usize,
) -> Vec<(i32, i32, f32)> {
    if c.len() <= budget {
        return c;
    }
    c.sort_by(|a, b| b.2.total_cmp(&a.2));
    let gw = w.div_ceil(cell);
    let mut rank_in_cell = std::collections::HashMap::new();
    let mut ranked: Vec<(usize, (i32, i32, f32))> = c
        .into_iter()
        .map(|p| {
            let key = (p.1 as usize / cell) * gw + p.0 as usize / cell;
            let r = rank_in_cell.entry(key).or_insert(0usize);
            *r += 1;
            (*r, p)
        })
        .collect();
    // Stable: within one rank, stronger first.
    ranked.sort_by_key(|(r, _)| *r);
    ranked.into_iter().take(budget).map(|(_, p)| p).collect()
}

/// Orientation by the intensity centroid of a disc.
fn orientation(l: &Level, x: i32, y: i32) -> f32 {
    let (mut mx, mut my) = (0i64, 0i64);
    let r2 = ORIENT_RADIUS * ORIENT_RADIUS;
    for dy in -ORIENT_RADIUS..=ORIENT_RADIUS {
        for dx in -ORIENT_RADIUS..=ORIENT_RADIUS {
            if dx * dx + dy * dy <= r2 {
                let v = l.at(x + dx, y + dy) as i64;
                mx += dx as i64 * v;
                my += dy as i64 * v;
            }
        }
    }
    (my as f32).atan2(mx as f32)
}

/// The 256 test pairs: a fixed pseudo-random (Gaussian, sigma = patch / 5) pattern.
fn pattern() -> &'static [[(f32, f32); 2]; 256] {
    static P: std::sync::OnceLock<[[(f32, f32); 2]; 256]> = std::sync::OnceLock::new();
    P.get_or_init(|| {
        let mut s: u64 = 0x9E37_79B9_7F4A_7C15;
        let mut uniform = || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            ((s >> 11) as f64 + 0.5) / (1u64 << 53) as f64
        };
        let sigma = (2 * PATCH_RADIUS + 1) as f64 / 5.0;
        let mut gauss = || loop {
            let g = (-2.0 * uniform().ln()).sqrt()
                * (2.0 * std::f64::consts::PI * uniform()).cos()
                * sigma;
            if g.abs() <= PATCH_RADIUS as f64 {
                return g as f32;
            }
        };
        let mut p = [[(0.0, 0.0); 2]; 256];
        for pair in p.iter_mut() {
            *pair = [(gauss(), gauss()), (gauss(), gauss())];
        }
        p
    })
}

/// Steered BRIEF descriptor on a smoothed level.
fn describe(smooth: &Level, x: i32, y: i32, angle: f32) -> Descriptor {
    let (s, c) = angle.sin_cos();
    let mut d = [0u64; 4];
    for (i, [a, b]) in pattern().iter().enumerate() {
        let rot = |p: (f32, f32)| {
            let u = (c * p.0 - s * p.1).round() as i32;
            let v = (s * p.0 + c * p.1).round() as i32;
            smooth.at(x + u, y + v)
        };
        if rot(*a) < rot(*b) {
            d[i / 64] |= 1 << (i % 64);
        }
    }
    d
}

/// Keypoints and descriptors over a pyramid.
pub fn detect_and_describe(pyr: &[Level], cfg: &FeatureConfig) -> (Vec<Keypoint>, Vec<Descriptor>) {
    // Budget per level proportional to its area.
    let total_area: f32 = pyr.iter().map(|l| (l.width * l.height) as f32).sum();
    let mut kps = Vec::new();
    let mut descs = Vec::new();
    for (li, l) in pyr.iter().enumerate() {
        let budget =
            ((cfg.max_keypoints as f32) * (l.width * l.height) as f32 / total_area).ceil() as usize;
        let corners = spread(
            fast_level(l, cfg.fast_threshold),
            l.width,
            cfg.cell_px,
            budget,
        );
        let smooth = l.blurred();
        let found: Vec<(Keypoint, Descriptor)> = corners
            .par_iter()
            .map(|&(x, y, score)| {
                let angle = orientation(l, x, y);
                let kp = Keypoint {
                    x: (x as f32 + 0.5) * l.scale - 0.5,
                    y: (y as f32 + 0.5) * l.scale - 0.5,
                    level: li as u8,
                    angle,
                    score,
                };
                (kp, describe(&smooth, x, y, angle))
            })
            .collect();
        for (k, d) in found {
            kps.push(k);
            descs.push(d);
        }
    }
    (kps, descs)
}

/// Keypoints and descriptors of a simulated oblique view of `l` (ASIFT-style affine
/// simulation): the image rotated by `phi` and compressed by `1 / tilt` along the rotated x
/// axis (after an anti-aliasing blur), so that a picture seen at a grazing angle still
/// matches. Keypoint positions are mapped back to `l`'s pixels; keypoints whose descriptor
/// patch would reach outside the picture are dropped.
pub fn simulated_view_features(
    l: &Level,
    phi: f32,
    tilt: f32,
    levels: usize,
    cfg: &FeatureConfig,
) -> (Vec<Keypoint>, Vec<Descriptor>) {
    let (s, c) = phi.sin_cos();
    // Forward: p' = diag(1/tilt, 1) R(phi) p.
    let fwd = |x: f32, y: f32| ((c * x - s * y) / tilt, s * x + c * y);
    let (w, h) = ((l.width - 1) as f32, (l.height - 1) as f32);
    let corners = [fwd(0.0, 0.0), fwd(w, 0.0), fwd(w, h), fwd(0.0, h)];
    let minx = corners.iter().map(|p| p.0).fold(f32::INFINITY, f32::min);
    let miny = corners.iter().map(|p| p.1).fold(f32::INFINITY, f32::min);
    let maxx = corners
        .iter()
        .map(|p| p.0)
        .fold(f32::NEG_INFINITY, f32::max);
    let maxy = corners
        .iter()
        .map(|p| p.1)
        .fold(f32::NEG_INFINITY, f32::max);
    let ow = (maxx - minx).ceil() as usize + 1;
    let oh = (maxy - miny).ceil() as usize + 1;
    // Inverse: p = R(-phi) diag(tilt, 1) (p' + min).
    let inv = move |x: f32, y: f32| {
        let (u, v) = ((x + minx) * tilt, y + miny);
        (c * u + s * v, -s * u + c * v)
    };
    let src = l.blurred().blurred();
    let mut data = vec![128u8; ow * oh];
    data.par_chunks_mut(ow).enumerate().for_each(|(y, row)| {
        for (x, out) in row.iter_mut().enumerate() {
            let (u, v) = inv(x as f32, y as f32);
            if u >= 0.0 && v >= 0.0 && u <= w && v <= h {
                *out = (src.sample(u, v) + 0.5) as u8;
            }
        }
    });
    let img = GrayImage {
        width: ow as u32,
        height: oh as u32,
        data,
    };
    let pyr = pyramid(&img, levels);
    let (kps, desc) = detect_and_describe(&pyr, cfg);
    let mut out_k = Vec::new();
    let mut out_d = Vec::new();
    for (k, d) in kps.into_iter().zip(desc) {
        let (u, v) = inv(k.x, k.y);
        let m = 1.5 * (PATCH_RADIUS + 2) as f32 * LEVEL_SCALE.powi(k.level as i32) * tilt;
        if u >= m && v >= m && u <= w - m && v <= h - m {
            out_k.push(Keypoint { x: u, y: v, ..k });
            out_d.push(d);
        }
    }
    (out_k, out_d)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn arc_detection() {
        assert!(has_arc9(0b1_1111_1111));
        assert!(!has_arc9(0b1111_1111));
        // Wrapping around bit 15 -> bit 0.
        assert!(has_arc9(0b1111_0000_0000_0000 | 0b1_1111));
        assert!(!has_arc9(0b0101_0101_0101_0101));
    }

    #[test]
    fn circle_has_radius_three() {
        for (dx, dy) in CIRCLE {
            let r = ((dx * dx + dy * dy) as f32).sqrt();
            assert!((2.8..=3.2).contains(&r), "({dx},{dy})");
        }
    }
}
