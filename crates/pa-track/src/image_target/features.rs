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
        if (factor - 2.0).abs() < 1e-6 && self.width >= 2 && self.height >= 2 {
            self.halved()
        } else {
            self.blurred().resampled(factor, self.scale)
        }
    }

    /// Area average of 2 x 2 blocks.
    fn halved(&self) -> Self {
        let sw = self.width;
        let w = sw / 2;
        let h = self.height / 2;
        let mut data = vec![0u8; w * h];
        data.par_chunks_mut(w)
            .zip(self.data.par_chunks_exact(2 * sw))
            .with_min_len(16)
            .for_each(|(row, src)| {
                let (r0, r1) = src.split_at(sw);
                for ((out, a), b) in row
                    .iter_mut()
                    .zip(r0.chunks_exact(2))
                    .zip(r1.chunks_exact(2))
                {
                    let s = a[0] as u16 + a[1] as u16 + b[0] as u16 + b[1] as u16;
                    *out = ((s + 2) / 4) as u8;
                }
            });
        Self {
            width: w,
            height: h,
            data,
            scale: self.scale * 2.0,
        }
    }

    /// This (already smoothed) level sampled bilinearly at `(x + 0.5) factor - 0.5`, with
    /// level-0 scale `scale * factor`; as [`Level::sample`] per pixel.
    fn resampled(&self, factor: f32, scale: f32) -> Self {
        let w = ((self.width as f32 / factor).floor() as usize).max(1);
        let h = ((self.height as f32 / factor).floor() as usize).max(1);
        let mut data = vec![0u8; w * h];
        if self.width > 0 && self.height > 0 {
            // (first source index, fraction) along one axis, as `sample` clamps them.
            let taps = |n: usize, len: usize| -> Vec<(usize, f32)> {
                let max = (len - 1) as f32;
                (0..n)
                    .map(|i| {
                        let s = ((i as f32 + 0.5) * factor - 0.5).clamp(0.0, max);
                        let i0 = (s as usize).min(len.saturating_sub(2));
                        (i0, s - i0 as f32)
                    })
                    .collect()
            };
            let (cols, rows) = (taps(w, self.width), taps(h, self.height));
            let sw = self.width;
            let dx = usize::from(sw > 1);
            let dy = usize::from(self.height > 1);
            data.par_chunks_mut(w)
                .zip(rows.par_iter())
                .with_min_len(16)
                .for_each(|(row, &(y0, fy))| {
                    let r0 = &self.data[y0 * sw..(y0 + 1) * sw];
                    let r1 = &self.data[(y0 + dy) * sw..(y0 + dy + 1) * sw];
                    for (out, &(x0, fx)) in row.iter_mut().zip(&cols) {
                        let (a, b) = (r0[x0] as f32, r0[x0 + dx] as f32);
                        let (c, d) = (r1[x0] as f32, r1[x0 + dx] as f32);
                        let top = a + (b - a) * fx;
                        let bot = c + (d - c) * fx;
                        *out = (top + (bot - top) * fy + 0.5) as u8;
                    }
                });
        }
        Self {
            width: w,
            height: h,
            data,
            scale: scale * factor,
        }
    }

    /// A [1 4 6 4 1] / 16 separable blur (border pixels replicated).
    pub fn blurred(&self) -> Self {
        let (w, h) = (self.width, self.height);
        if w < 5 || h < 5 {
            return self.blurred_small();
        }
        // Per output row: the vertical pass into a row of u16 (at most 16 x 255), then the
        // horizontal one (at most 256 x 255 + 128).
        let mut data = vec![0u8; w * h];
        data.par_chunks_mut(w)
            .enumerate()
            .with_min_len(16)
            .for_each_init(
                || vec![0u16; w],
                |col, (y, out)| {
                    let r = |dy: isize| {
                        let yy = (y as isize + dy).clamp(0, h as isize - 1) as usize;
                        &self.data[yy * w..(yy + 1) * w]
                    };
                    let (a, b, c, d, e) = (r(-2), r(-1), r(0), r(1), r(2));
                    for i in 0..w {
                        col[i] = a[i] as u16
                            + 4 * b[i] as u16
                            + 6 * c[i] as u16
                            + 4 * d[i] as u16
                            + e[i] as u16;
                    }
                    let n = w - 4;
                    let (ca, cb, cc) = (&col[..n], &col[1..n + 1], &col[2..n + 2]);
                    let (cd, ce) = (&col[3..n + 3], &col[4..n + 4]);
                    let o = &mut out[2..n + 2];
                    for i in 0..n {
                        let s = ca[i] + 4 * cb[i] + 6 * cc[i] + 4 * cd[i] + ce[i];
                        o[i] = ((s + 128) >> 8) as u8;
                    }
                    for x in [0, 1, w - 2, w - 1] {
                        let g =
                            |dx: isize| col[(x as isize + dx).clamp(0, w as isize - 1) as usize];
                        let s = g(-2) + 4 * g(-1) + 6 * g(0) + 4 * g(1) + g(2);
                        out[x] = ((s + 128) >> 8) as u8;
                    }
                },
            );
        Self {
            width: w,
            height: h,
            data,
            scale: self.scale,
        }
    }

    /// [`Level::blurred`] for levels narrower or lower than 5 pixels.
    fn blurred_small(&self) -> Self {
        let (w, h) = (self.width, self.height);
        if w == 0 || h == 0 {
            return self.clone();
        }
        let mut tmp = vec![0u32; w * h];
        for y in 0..h {
            for x in 0..w {
                let g = |dx: isize| {
                    self.data[y * w + (x as isize + dx).clamp(0, w as isize - 1) as usize] as u32
                };
                tmp[y * w + x] = g(-2) + 4 * g(-1) + 6 * g(0) + 4 * g(1) + g(2);
            }
        }
        let mut data = vec![0u8; w * h];
        for y in 0..h {
            for x in 0..w {
                let g =
                    |dy: isize| tmp[(y as isize + dy).clamp(0, h as isize - 1) as usize * w + x];
                let s = g(-2) + 4 * g(-1) + 6 * g(0) + 4 * g(1) + g(2);
                data[y * w + x] = ((s + 128) / 256) as u8;
            }
        }
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
    pyramid_smoothed(img, levels).0
}

/// An image pyramid and the smoothed copy of each level ([`Level::blurred`], which the
/// descriptors sample); level 1 is resampled from level 0's smoothed copy.
pub fn pyramid_smoothed(img: &GrayImage, levels: usize) -> (Vec<Level>, Vec<Level>) {
    let mut out = vec![Level::from_gray(img)];
    let mut smooth = vec![out[0].blurred()];
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
            smooth[0].resampled(LEVEL_SCALE, out[0].scale)
        };
        if next.width < min_side || next.height < min_side {
            break;
        }
        smooth.push(next.blurred());
        out.push(next);
    }
    (out, smooth)
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
    /// Keypoints each level may keep at least (on top of its share of `max_keypoints`).
    pub min_per_level: usize,
}

impl Default for FeatureConfig {
    fn default() -> Self {
        Self {
            fast_threshold: 18,
            max_keypoints: 1500,
            cell_px: 32,
            min_per_level: 0,
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

/// Harris response on a 7x7 window (Sobel gradients), k = 0.04, at `(x, y)` at least 4
/// pixels inside `l`.
fn harris(l: &Level, x: usize, y: usize) -> f32 {
    let w = l.width;
    let mut p = [[0i32; 9]; 9];
    for (r, pr) in p.iter_mut().enumerate() {
        let row = &l.data[(y + r - 4) * w + x - 4..(y + r - 4) * w + x + 5];
        for (v, s) in pr.iter_mut().zip(row) {
            *v = *s as i32;
        }
    }
    // Vertical [1 2 1] sums (for gx) and horizontal ones (for gy).
    let mut vs = [[0i32; 9]; 7];
    let mut hs = [[0i32; 7]; 9];
    for r in 0..7 {
        for c in 0..9 {
            vs[r][c] = p[r][c] + 2 * p[r + 1][c] + p[r + 2][c];
        }
    }
    for r in 0..9 {
        for c in 0..7 {
            hs[r][c] = p[r][c] + 2 * p[r][c + 1] + p[r][c + 2];
        }
    }
    // Exact in i32: |g| <= 1020, 49 g^2 < 2^31.
    let (mut a, mut b, mut c) = (0i32, 0i32, 0i32);
    for r in 0..7 {
        for q in 0..7 {
            let gx = vs[r][q + 2] - vs[r][q];
            let gy = hs[r + 2][q] - hs[r][q];
            a += gx * gx;
            b += gy * gy;
            c += gx * gy;
        }
    }
    let (a, b, c) = (a as f64, b as f64, c as f64);
    let det = a * b - c * c;
    let tr = a + b;
    ((det - 0.04 * tr * tr) / (49.0 * 49.0 * 16.0)) as f32
}

/// FAST-9 corners of row `y` (all rows `y - 3 ..= y + 3` inside `l`, `x` in
/// `BORDER .. width - BORDER`) with their Harris scores, in x order.
fn fast_row(l: &Level, y: usize, t: u8) -> Vec<(i32, f32)> {
    let w = l.width;
    let b = BORDER as usize;
    let n = w - 2 * b;
    let row = |dy: i32| {
        let yy = (y as i32 + dy) as usize;
        &l.data[yy * w..(yy + 1) * w]
    };
    let rows: [&[u8]; 7] = [row(-3), row(-2), row(-1), row(0), row(1), row(2), row(3)];
    // Any 9-arc holds two of the four compass points (0, 4, 8, 12) and two of the four
    // diagonal ones (2, 6, 10, 14): a branch-free test over the row first.
    let (c, up, dn) = (&rows[3][b..b + n], &rows[0][b..b + n], &rows[6][b..b + n]);
    let (rt, lt) = (&rows[3][b + 3..b + 3 + n], &rows[3][b - 3..b - 3 + n]);
    let (ur, dr) = (&rows[1][b + 2..b + 2 + n], &rows[5][b + 2..b + 2 + n]);
    let (dl, ul) = (&rows[5][b - 2..b - 2 + n], &rows[1][b - 2..b - 2 + n]);
    let mut flag = vec![0u8; n];
    for i in 0..n {
        let (hi, lo) = (c[i].saturating_add(t), c[i].saturating_sub(t));
        let br = (up[i] > hi) as u8 + (dn[i] > hi) as u8 + (rt[i] > hi) as u8 + (lt[i] > hi) as u8;
        let dk = (up[i] < lo) as u8 + (dn[i] < lo) as u8 + (rt[i] < lo) as u8 + (lt[i] < lo) as u8;
        let bd = (ur[i] > hi) as u8 + (dr[i] > hi) as u8 + (dl[i] > hi) as u8 + (ul[i] > hi) as u8;
        let dd = (ur[i] < lo) as u8 + (dr[i] < lo) as u8 + (dl[i] < lo) as u8 + (ul[i] < lo) as u8;
        flag[i] = ((br >= 2) & (bd >= 2)) as u8 | ((dk >= 2) & (dd >= 2)) as u8;
    }
    let mut out = Vec::new();
    for (i, _) in flag.iter().enumerate().filter(|(_, f)| **f != 0) {
        let x = b + i;
        let cv = c[i] as i16;
        let t = t as i16;
        let (mut mb, mut md) = (0u32, 0u32);
        for (k, &(dx, dy)) in CIRCLE.iter().enumerate() {
            let p = rows[(dy + 3) as usize][(x as i32 + dx) as usize] as i16;
            mb |= ((p > cv + t) as u32) << k;
            md |= ((p < cv - t) as u32) << k;
        }
        if has_arc9(mb) || has_arc9(md) {
            out.push((x as i32, harris(l, x, y)));
        }
    }
    out
}

/// Whether a corner of `row` within one pixel of `x` outscores `s` (or equals it, with
/// `ties`).
fn outscored(row: &[(i32, f32)], x: i32, s: f32, ties: bool) -> bool {
    let from = row.partition_point(|p| p.0 < x - 1);
    row[from..]
        .iter()
        .take_while(|p| p.0 <= x + 1)
        .any(|p| p.1 > s || (ties && p.1 == s))
}

/// FAST-9 corners of one level with their Harris scores after 3x3 non-maximum suppression
/// (of two equal scores, the one earlier in raster order wins).
fn fast_level(l: &Level, threshold: u8) -> Vec<(i32, i32, f32)> {
    let (w, h) = (l.width as i32, l.height as i32);
    if w <= 2 * BORDER || h <= 2 * BORDER {
        return Vec::new();
    }
    let rows: Vec<Vec<(i32, f32)>> = (BORDER..h - BORDER)
        .into_par_iter()
        .with_min_len(8)
        .map(|y| fast_row(l, y as usize, threshold))
        .collect();
    let mut out = Vec::new();
    for (ri, r) in rows.iter().enumerate() {
        let y = BORDER + ri as i32;
        for (k, &(x, s)) in r.iter().enumerate() {
            if s <= 0.0 {
                continue;
            }
            let beaten = (k > 0 && r[k - 1].0 == x - 1 && r[k - 1].1 >= s)
                || (k + 1 < r.len() && r[k + 1].0 == x + 1 && r[k + 1].1 > s)
                || (ri > 0 && outscored(&rows[ri - 1], x, s, true))
                || (ri + 1 < rows.len() && outscored(&rows[ri + 1], x, s, false));
            if !beaten {
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

/// Half widths of the orientation disc's rows (`dy = -R ..= R`): `dx^2 + dy^2 <= R^2`.
const fn disc_half_widths() -> [usize; (2 * ORIENT_RADIUS + 1) as usize] {
    let mut out = [0usize; (2 * ORIENT_RADIUS + 1) as usize];
    let mut i = 0;
    while i < out.len() {
        let dy = i as i32 - ORIENT_RADIUS;
        let mut hw = 0;
        while (hw + 1) * (hw + 1) + dy * dy <= ORIENT_RADIUS * ORIENT_RADIUS {
            hw += 1;
        }
        out[i] = hw as usize;
        i += 1;
    }
    out
}

/// Orientation by the intensity centroid of a disc (at least [`ORIENT_RADIUS`] pixels
/// inside `l`).
fn orientation(l: &Level, x: usize, y: usize) -> f32 {
    const HW: [usize; (2 * ORIENT_RADIUS + 1) as usize] = disc_half_widths();
    let w = l.width;
    // Exact in i32: |moment| <= 12 x 255 x 625.
    let (mut mx, mut my) = (0i32, 0i32);
    for (k, &hw) in HW.iter().enumerate() {
        let dy = k as i32 - ORIENT_RADIUS;
        let start = (y as i32 + dy) as usize * w + x - hw;
        let row = &l.data[start..start + 2 * hw + 1];
        let (mut s, mut sx) = (0i32, 0i32);
        for (i, &v) in row.iter().enumerate() {
            s += v as i32;
            sx += (i as i32 - hw as i32) * v as i32;
        }
        mx += sx;
        my += dy * s;
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

/// Orientations the test pattern is steered to (the keypoint's angle is rounded to one).
const ANGLE_BINS: usize = 256;

/// The test pattern rotated to each of [`ANGLE_BINS`] angles: per pair `[ax, ay, bx, by]`
/// (pixel offsets, rounded).
fn steered_patterns() -> &'static [[[i8; 4]; 256]] {
    static P: std::sync::OnceLock<Vec<[[i8; 4]; 256]>> = std::sync::OnceLock::new();
    P.get_or_init(|| {
        (0..ANGLE_BINS)
            .map(|bin| {
                let angle = bin as f32 * std::f32::consts::TAU / ANGLE_BINS as f32;
                let (s, c) = angle.sin_cos();
                let rot = |p: (f32, f32)| {
                    (
                        (c * p.0 - s * p.1).round() as i8,
                        (s * p.0 + c * p.1).round() as i8,
                    )
                };
                let mut out = [[0i8; 4]; 256];
                for (o, [a, b]) in out.iter_mut().zip(pattern().iter()) {
                    let (ra, rb) = (rot(*a), rot(*b));
                    *o = [ra.0, ra.1, rb.0, rb.1];
                }
                out
            })
            .collect()
    })
}

/// Steered BRIEF descriptor on a smoothed level (the pattern steered to the nearest of
/// [`ANGLE_BINS`] angles), at `(x, y)` at least [`PATCH_RADIUS`] pixels inside.
fn describe(smooth: &Level, x: usize, y: usize, angle: f32) -> Descriptor {
    let bins = ANGLE_BINS as f32;
    let bin = ((angle / std::f32::consts::TAU * bins).round() as i32).rem_euclid(ANGLE_BINS as i32);
    let pairs = &steered_patterns()[bin as usize];
    let w = smooth.width as isize;
    let centre = (y * smooth.width + x) as isize;
    let at = |dx: i8, dy: i8| smooth.data[(centre + dy as isize * w + dx as isize) as usize];
    let mut d = [0u64; 4];
    for (word, chunk) in d.iter_mut().zip(pairs.chunks_exact(64)) {
        for (bit, q) in chunk.iter().enumerate() {
            *word |= ((at(q[0], q[1]) < at(q[2], q[3])) as u64) << bit;
        }
    }
    d
}

/// Keypoints and descriptors over a pyramid.
pub fn detect_and_describe(pyr: &[Level], cfg: &FeatureConfig) -> (Vec<Keypoint>, Vec<Descriptor>) {
    let smooth: Vec<Level> = pyr.iter().map(Level::blurred).collect();
    detect_and_describe_smoothed(pyr, &smooth, cfg)
}

/// Keypoints and descriptors over a pyramid whose smoothed levels are given.
pub fn detect_and_describe_smoothed(
    pyr: &[Level],
    smooth: &[Level],
    cfg: &FeatureConfig,
) -> (Vec<Keypoint>, Vec<Descriptor>) {
    // Budget per level proportional to its area.
    let total_area: f32 = pyr.iter().map(|l| (l.width * l.height) as f32).sum();
    let mut kps = Vec::new();
    let mut descs = Vec::new();
    for (li, (l, sm)) in pyr.iter().zip(smooth).enumerate() {
        let budget =
            (((cfg.max_keypoints as f32) * (l.width * l.height) as f32 / total_area).ceil()
                as usize)
                .max(cfg.min_per_level);
        let fl = fast_level(l, cfg.fast_threshold);
        let corners = spread(fl, l.width, cfg.cell_px, budget);
        let found: Vec<(Keypoint, Descriptor)> = corners
            .par_iter()
            .with_min_len(32)
            .map(|&(x, y, score)| {
                let (xu, yu) = (x as usize, y as usize);
                let angle = orientation(l, xu, yu);
                let kp = Keypoint {
                    x: (x as f32 + 0.5) * l.scale - 0.5,
                    y: (y as f32 + 0.5) * l.scale - 0.5,
                    level: li as u8,
                    angle,
                    score,
                };
                (kp, describe(sm, xu, yu, angle))
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
    let (pyr, smooth) = pyramid_smoothed(&img, levels);
    let (kps, desc) = detect_and_describe_smoothed(&pyr, &smooth, cfg);
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

    fn test_level(w: u32, h: u32, seed: u64) -> Level {
        Level::from_gray(&super::super::synth::natural_picture(w, h, seed))
    }

    #[test]
    fn fast_rows_match_the_plain_segment_test() {
        let l = test_level(200, 120, 5);
        let t = 15u8;
        let mut found = 0;
        for y in BORDER as usize..l.height - BORDER as usize {
            let got: Vec<i32> = fast_row(&l, y, t).iter().map(|c| c.0).collect();
            let want: Vec<i32> = (BORDER..l.width as i32 - BORDER)
                .filter(|&x| {
                    let c = l.at(x, y as i32) as i16;
                    let (mut mb, mut md) = (0u32, 0u32);
                    for (k, (dx, dy)) in CIRCLE.iter().enumerate() {
                        let p = l.at(x + dx, y as i32 + dy) as i16;
                        if p > c + t as i16 {
                            mb |= 1 << k;
                        }
                        if p < c - t as i16 {
                            md |= 1 << k;
                        }
                    }
                    has_arc9(mb) || has_arc9(md)
                })
                .collect();
            assert_eq!(got, want, "row {y}");
            found += want.len();
        }
        assert!(found > 100, "{found} corners");
    }

    #[test]
    fn harris_matches_the_float_sum() {
        let l = test_level(64, 64, 9);
        for (x, y) in [(10, 10), (30, 21), (50, 40)] {
            let (mut a, mut b, mut c) = (0f64, 0f64, 0f64);
            for v in y - 3..=y + 3 {
                for u in x - 3..=x + 3 {
                    let p = |du: i32, dv: i32| l.at(u + du, v + dv) as f64;
                    let gx = (p(1, -1) + 2.0 * p(1, 0) + p(1, 1))
                        - (p(-1, -1) + 2.0 * p(-1, 0) + p(-1, 1));
                    let gy = (p(-1, 1) + 2.0 * p(0, 1) + p(1, 1))
                        - (p(-1, -1) + 2.0 * p(0, -1) + p(1, -1));
                    a += gx * gx;
                    b += gy * gy;
                    c += gx * gy;
                }
            }
            let want = ((a * b - c * c - 0.04 * (a + b) * (a + b)) / (49.0 * 49.0 * 16.0)) as f32;
            let got = harris(&l, x as usize, y as usize);
            assert!(
                (got - want).abs() <= 1e-4 * want.abs().max(1.0),
                "{got} vs {want}"
            );
        }
    }

    #[test]
    fn blur_and_resampling_match_their_plain_forms() {
        let l = test_level(97, 61, 3);
        // The row-slice blur against the per-pixel clamped one.
        assert_eq!(l.blurred(), l.blurred_small());
        // Resampling against Level::sample.
        let s = l.blurred();
        let r = s.resampled(LEVEL_SCALE, 1.0);
        assert_eq!((r.width, r.height), (68, 43));
        for y in 0..r.height {
            for x in 0..r.width {
                let sx = (x as f32 + 0.5) * LEVEL_SCALE - 0.5;
                let sy = (y as f32 + 0.5) * LEVEL_SCALE - 0.5;
                assert_eq!(r.at(x as i32, y as i32), (s.sample(sx, sy) + 0.5) as u8);
            }
        }
        // Halving: 2 x 2 means, rounded.
        let hf = l.downscaled(2.0);
        assert_eq!((hf.width, hf.height, hf.scale), (48, 30, 2.0));
        let m = |x: i32, y: i32| l.at(x, y) as u32;
        assert_eq!(
            hf.at(7, 5) as u32,
            (m(14, 10) + m(15, 10) + m(14, 11) + m(15, 11) + 2) / 4
        );
    }

    #[test]
    fn orientation_follows_the_brighter_side() {
        // A ramp brightening towards +x, then towards +y.
        let ramp = |f: &dyn Fn(usize, usize) -> u8| Level {
            width: 40,
            height: 40,
            data: (0..1600).map(|i| f(i % 40, i / 40)).collect(),
            scale: 1.0,
        };
        let a = orientation(&ramp(&|x, _| (x * 6) as u8), 20, 20);
        assert!(a.abs() < 1e-3, "{a}");
        let a = orientation(&ramp(&|_, y| (y * 6) as u8), 20, 20);
        assert!((a - std::f32::consts::FRAC_PI_2).abs() < 1e-3, "{a}");
    }

    #[test]
    fn descriptors_of_a_rotated_picture_match() {
        // The same point of a picture and of the picture turned by 90 degrees: the steered
        // descriptors agree far better than those of different points.
        let l = test_level(120, 120, 21);
        let n = l.width;
        let rot = Level {
            width: n,
            height: n,
            // rot(x, y) = l(y, n - 1 - x): the picture turned by 90 degrees.
            data: (0..n * n)
                .map(|i| l.data[(n - 1 - i % n) * n + i / n])
                .collect(),
            scale: 1.0,
        };
        let (ls, rs) = (l.blurred(), rot.blurred());
        let (x, y) = (50usize, 64usize);
        // Where (x, y) of l lies in rot: rot(x', y') = l(y', n - 1 - x') = l(x, y).
        let (xr, yr) = (n - 1 - y, x);
        let d1 = describe(&ls, x, y, orientation(&l, x, y));
        let d2 = describe(&rs, xr, yr, orientation(&rot, xr, yr));
        let d3 = describe(&ls, 70, 40, orientation(&l, 70, 40));
        assert!(hamming(&d1, &d2) < 30, "{}", hamming(&d1, &d2));
        assert!(hamming(&d1, &d3) > 70, "{}", hamming(&d1, &d3));
    }

    #[test]
    fn circle_has_radius_three() {
        for (dx, dy) in CIRCLE {
            let r = ((dx * dx + dy * dy) as f32).sqrt();
            assert!((2.8..=3.2).contains(&r), "({dx},{dy})");
        }
    }
}
