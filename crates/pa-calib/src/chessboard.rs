//! Chessboard inner-corner detection with sub-pixel refinement.
//!
//! # Method
//!
//! 1. **Candidates.** The image is smoothed (Gaussian, sigma 1.5 px; a second pass at 1 px
//!    with a smaller ring runs when the first finds no board) and the saddle response
//!    `Ixy^2 - Ixx * Iyy` (minus the Hessian determinant, large at X-junctions, near zero on
//!    edges, negative on blobs) is computed; local maxima above 2 % of the strongest become
//!    candidates. Each is refined to sub-pixel and kept only if a ring of samples around it
//!    shows an **X-junction**: four alternating dark/bright sectors, point-symmetric
//!    (`I(p + d) ~ I(p - d)`). This rejects the L-corners at the board's outer boundary and
//!    T-junctions.
//! 2. **Seed.** A candidate and two neighbours along its two grid lines, plus the fourth
//!    corner of their square, checked by the contrast across each of the four edges (a
//!    diagonal has none).
//! 3. **Growth.** The grid grows one row or column at a time. Each new corner is predicted by
//!    a homography fitted to the nearest known corners (up to 5 rows x 3 columns), so strong
//!    perspective and lens distortion are followed locally; the nearest candidate within 30 %
//!    of the local spacing is taken (or, failing that, the refined prediction if it is an
//!    X-junction). A row or column is added only when every corner of it is found.
//! 4. **Check and order.** The grid must have exactly `rows` x `cols` inner corners (or the
//!    transpose): a board cut by the image border, hidden in part or with another size gives
//!    `None`. Corners are then refined (gradient orthogonality, as OpenCV's `cornerSubPix`,
//!    on the image smoothed with sigma 1 px, with a Gaussian-weighted window of 0.4 times the
//!    local spacing, 2 to 10 px) and ordered.
//!
//! # Limits
//!
//! Measured on rendered 1280x720 views of an 8x11 board through a lens with k1 = -0.2
//! (blur 0.7 px, noise 2 grey levels): corners within 0.020 px of the truth (median; 0.14 px
//! at worst) on views tilted up to 50 degrees, all found. Tilted further: 12 of 13 views at
//! 50-60 degrees and 8 of 10 at 60-65 degrees are found (the misses are small boards whose
//! squares are sheared to a few pixels). Squares must be about 8 px or more on their short
//! side: 30 of 30 views with 9 px squares, 25 of 30 with 7.5 px, 17 of 30 with 6 px.
//!
//! # Conventions
//!
//! - Pixels: OpenCV, the centre of pixel (0, 0) at (0, 0).
//! - Order: row-major, `rows` rows of `cols` corners: corner `(r, c)` is at index
//!   `r * cols + c` and has board coordinates `(c * square, r * square, 0)`. The board frame
//!   is right-handed with +X along a row, +Y down the rows and +Z into the board (the marker
//!   frame of `pa-track`), so the order is never mirrored: in the image, going along a row and
//!   then down the rows turns clockwise. Of the orderings that satisfy this (two for
//!   `rows != cols`, four for a square board) the one whose first corner is nearest the
//!   image's top-left (smallest `x + y`) is returned. A chessboard has no marked origin, so
//!   for `rows == cols`, or for a board turned by about 180 degrees between views, the
//!   origin may differ between views; calibration does not mind (each view has its own pose).

use glam::DVec2;
use pa_track::GrayImage;

use crate::linalg::{apply_homography, homography_dlt};

/// Number of inner corners of a chessboard (where four squares meet).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
pub struct ChessboardSize {
    /// Rows of inner corners.
    pub rows: u32,
    /// Inner corners per row.
    pub cols: u32,
}

/// Smoothing before the saddle response, pixels (first pass).
const BLUR_SIGMA_PX: f64 = 1.5;
/// Smoothing of the image whose gradients refine the corners, pixels. On rendered views
/// (`tests/synthetic.rs`) it halves the corner error against none (0.026 vs 0.034 px RMS with
/// blur and noise): the central differences of a sharp image alias.
const GRADIENT_SIGMA_PX: f64 = 1.0;
/// Candidates kept at most (strongest first).
const MAX_CANDIDATES: usize = 4000;
/// Radius of the X-junction ring test, pixels (first pass).
const RING_RADIUS_PX: f64 = 4.0;
/// Minimum grey-level range on the ring (on the smoothed image).
const MIN_RING_CONTRAST: f32 = 10.0;

/// A single-channel f32 image with bilinear sampling (pixel centres at integers).
pub(crate) struct FloatImage {
    pub(crate) width: usize,
    pub(crate) height: usize,
    pub(crate) data: Vec<f32>,
}

impl FloatImage {
    fn from_gray(img: &GrayImage) -> Self {
        Self {
            width: img.width as usize,
            height: img.height as usize,
            data: img.data.iter().map(|&v| v as f32).collect(),
        }
    }

    #[inline]
    fn at(&self, x: usize, y: usize) -> f32 {
        self.data[y * self.width + x]
    }

    /// Bilinear sample; `None` outside the pixel centres' hull.
    #[inline]
    pub(crate) fn sample(&self, p: DVec2) -> Option<f32> {
        if !(p.x >= 0.0 && p.y >= 0.0) {
            return None;
        }
        let (x0, y0) = (p.x.floor() as usize, p.y.floor() as usize);
        if x0 + 1 >= self.width || y0 + 1 >= self.height {
            return None;
        }
        let (fx, fy) = ((p.x - x0 as f64) as f32, (p.y - y0 as f64) as f32);
        let i = y0 * self.width + x0;
        let top = self.data[i] + fx * (self.data[i + 1] - self.data[i]);
        let bot = self.data[i + self.width]
            + fx * (self.data[i + self.width + 1] - self.data[i + self.width]);
        Some(top + fy * (bot - top))
    }

    /// Separable Gaussian blur (edges clamped).
    fn blurred(&self, sigma: f64) -> Self {
        let r = (3.0 * sigma).ceil() as isize;
        let kernel: Vec<f32> = {
            let k: Vec<f64> = (-r..=r)
                .map(|i| (-(i * i) as f64 / (2.0 * sigma * sigma)).exp())
                .collect();
            let s: f64 = k.iter().sum();
            k.iter().map(|v| (v / s) as f32).collect()
        };
        let (w, h) = (self.width as isize, self.height as isize);
        let mut tmp = vec![0f32; self.data.len()];
        for y in 0..h {
            let row = &self.data[(y * w) as usize..((y + 1) * w) as usize];
            for x in 0..w {
                let mut acc = 0f32;
                for (k, kv) in kernel.iter().enumerate() {
                    let xx = (x + k as isize - r).clamp(0, w - 1);
                    acc += kv * row[xx as usize];
                }
                tmp[(y * w + x) as usize] = acc;
            }
        }
        let mut out = vec![0f32; self.data.len()];
        for y in 0..h {
            for x in 0..w {
                let mut acc = 0f32;
                for (k, kv) in kernel.iter().enumerate() {
                    let yy = (y + k as isize - r).clamp(0, h - 1);
                    acc += kv * tmp[(yy * w + x) as usize];
                }
                out[(y * w + x) as usize] = acc;
            }
        }
        Self {
            width: self.width,
            height: self.height,
            data: out,
        }
    }

    /// Central-difference gradients (zero on the border).
    fn gradients(&self) -> (Self, Self) {
        let (w, h) = (self.width, self.height);
        let mut gx = vec![0f32; w * h];
        let mut gy = vec![0f32; w * h];
        for y in 1..h.saturating_sub(1) {
            for x in 1..w.saturating_sub(1) {
                gx[y * w + x] = 0.5 * (self.at(x + 1, y) - self.at(x - 1, y));
                gy[y * w + x] = 0.5 * (self.at(x, y + 1) - self.at(x, y - 1));
            }
        }
        let mk = |data| Self {
            width: w,
            height: h,
            data,
        };
        (mk(gx), mk(gy))
    }
}

/// Gradient images used for sub-pixel refinement.
pub(crate) struct Gradients {
    gx: FloatImage,
    gy: FloatImage,
}

impl Gradients {
    pub(crate) fn new(img: &GrayImage) -> Self {
        let (gx, gy) = FloatImage::from_gray(img)
            .blurred(GRADIENT_SIGMA_PX)
            .gradients();
        Self { gx, gy }
    }

    /// Sub-pixel corner refinement by gradient orthogonality (OpenCV's `cornerSubPix`): the
    /// corner `p` minimises `sum_q w_q (g_q . (q - p))^2` over a `(2 hw + 1)^2` window
    /// centred on `p` with Gaussian weights, iterated. `None` when the window leaves the
    /// image, the structure tensor is singular (no corner) or the estimate runs away.
    pub(crate) fn refine_corner(&self, p0: DVec2, hw: i32) -> Option<DVec2> {
        let hw = hw.max(1);
        let inv = 1.0 / (hw as f64 * hw as f64);
        let mut p = p0;
        for _ in 0..30 {
            let (mut a11, mut a12, mut a22, mut b1, mut b2) = (0.0, 0.0, 0.0, 0.0, 0.0);
            for dy in -hw..=hw {
                for dx in -hw..=hw {
                    let (fx, fy) = (dx as f64, dy as f64);
                    let q = p + DVec2::new(fx, fy);
                    let gx = self.gx.sample(q)? as f64;
                    let gy = self.gy.sample(q)? as f64;
                    let w = (-(fx * fx + fy * fy) * inv).exp();
                    let (xx, xy, yy) = (w * gx * gx, w * gx * gy, w * gy * gy);
                    a11 += xx;
                    a12 += xy;
                    a22 += yy;
                    b1 += xx * fx + xy * fy;
                    b2 += xy * fx + yy * fy;
                }
            }
            let det = a11 * a22 - a12 * a12;
            if det.is_nan() || det <= 1e-9 * (a11 + a22) * (a11 + a22) {
                return None;
            }
            let step = DVec2::new((a22 * b1 - a12 * b2) / det, (a11 * b2 - a12 * b1) / det);
            p += step;
            if !p.is_finite() || p.distance(p0) > hw as f64 + 0.5 {
                return None;
            }
            if step.length_squared() < 1e-8 {
                break;
            }
        }
        Some(p)
    }
}

/// The X-junction test: `Some(contrast)` when a ring of radius `r` around `p` (on the
/// smoothed image) shows four alternating sectors and is point-symmetric.
fn x_junction(img: &FloatImage, p: DVec2, r: f64) -> Option<f32> {
    const N: usize = 32;
    let mut v = [0f32; N];
    for (k, vk) in v.iter_mut().enumerate() {
        let a = std::f64::consts::TAU * k as f64 / N as f64;
        *vk = img.sample(p + r * DVec2::new(a.cos(), a.sin()))?;
    }
    let (mn, mx) = v
        .iter()
        .fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), &x| {
            (a.min(x), b.max(x))
        });
    let range = mx - mn;
    if range.is_nan() || range < MIN_RING_CONTRAST {
        return None;
    }
    let mid = 0.5 * (mn + mx);
    let hyst = 0.1 * range;
    let labels: Vec<bool> = v
        .iter()
        .filter(|&&x| (x - mid).abs() > hyst)
        .map(|&x| x > mid)
        .collect();
    if labels.len() < 4 {
        return None;
    }
    let changes = (0..labels.len())
        .filter(|&k| labels[k] != labels[(k + 1) % labels.len()])
        .count();
    if changes != 4 {
        return None;
    }
    let mean = v.iter().sum::<f32>() / N as f32;
    let dev: f32 = v.iter().map(|x| (x - mean).abs()).sum();
    let asym: f32 = 2.0 * (0..N / 2).map(|k| (v[k] - v[k + N / 2]).abs()).sum::<f32>();
    (asym < 0.6 * dev).then_some(range)
}

/// Contrast across the segment `a`-`b` at its midpoint, sampled `d` pixels to either side.
fn edge_contrast(img: &FloatImage, a: DVec2, b: DVec2, d: f64) -> Option<f32> {
    let dir = (b - a).try_normalize()?;
    let m = 0.5 * (a + b);
    let n = dir.perp() * d;
    Some((img.sample(m + n)? - img.sample(m - n)?).abs())
}

struct Candidate {
    p: DVec2,
    contrast: f32,
}

struct Detector<'a> {
    smooth: &'a FloatImage,
    ring_radius_px: f64,
    min_seed_sin: f64,
    grads: &'a Gradients,
    cands: Vec<Candidate>,
    used: Vec<bool>,
}

type Grid = Vec<Vec<DVec2>>;

fn transpose(g: &Grid) -> Grid {
    let (nr, nc) = (g.len(), g[0].len());
    (0..nc)
        .map(|j| (0..nr).map(|i| g[i][j]).collect())
        .collect()
}

fn mirror_cols(g: &Grid) -> Grid {
    g.iter()
        .map(|row| row.iter().rev().copied().collect())
        .collect()
}

fn rotate180(g: &Grid) -> Grid {
    g.iter()
        .rev()
        .map(|row| row.iter().rev().copied().collect())
        .collect()
}

impl Detector<'_> {
    fn nearest(&self, p: DVec2, radius: f64) -> Option<usize> {
        let mut best = None;
        let mut best_d = radius * radius;
        for (i, c) in self.cands.iter().enumerate() {
            let d = c.p.distance_squared(p);
            if d < best_d && !self.used[i] {
                best_d = d;
                best = Some(i);
            }
        }
        best
    }

    fn edge_ok(&self, a: DVec2, b: DVec2, d: f64, min_contrast: f32) -> bool {
        edge_contrast(self.smooth, a, b, d.max(1.0)).is_some_and(|c| c >= min_contrast)
    }

    /// A 2x2 seed around candidate `si`.
    fn seed(&self, si: usize, min_contrast: f32) -> Option<(Grid, [usize; 4])> {
        let s = self.cands[si].p;
        let mut near: Vec<(f64, usize)> = self
            .cands
            .iter()
            .enumerate()
            .filter(|(i, c)| *i != si && !self.used[*i] && c.p.distance(s) > 2.0)
            .map(|(i, c)| (c.p.distance_squared(s), i))
            .collect();
        near.sort_by(|a, b| a.0.total_cmp(&b.0));
        near.truncate(8);
        let mut best: Option<(f64, Grid, [usize; 4])> = None;
        for (x, &(_, ai)) in near.iter().enumerate() {
            for &(_, bi) in &near[x + 1..] {
                let (a, b) = (self.cands[ai].p, self.cands[bi].p);
                let (da, db) = (a - s, b - s);
                let (la, lb) = (da.length(), db.length());
                let sin = da.perp_dot(db) / (la * lb);
                if sin.abs() < self.min_seed_sin || la.max(lb) > 4.0 * la.min(lb) {
                    continue;
                }
                let score = la + lb;
                if best.as_ref().is_some_and(|(sc, _, _)| *sc <= score) {
                    continue;
                }
                let d = 0.2 * la.min(lb);
                if !(self.edge_ok(s, a, d, min_contrast) && self.edge_ok(s, b, d, min_contrast)) {
                    continue;
                }
                let Some(ci) = self.nearest(a + db, 0.3 * la.min(lb)) else {
                    continue;
                };
                if ci == si || ci == ai || ci == bi {
                    continue;
                }
                let c = self.cands[ci].p;
                if !(self.edge_ok(a, c, d, min_contrast) && self.edge_ok(b, c, d, min_contrast)) {
                    continue;
                }
                best = Some((score, vec![vec![s, a], vec![b, c]], [si, ai, bi, ci]));
            }
        }
        best.map(|(_, g, ids)| (g, ids))
    }

    /// Adds a column on the right of `g` when every one of its corners is found.
    fn expand_right(&mut self, g: &mut Grid, min_contrast: f32) -> bool {
        let (nr, nc) = (g.len(), g[0].len());
        let mut new = Vec::with_capacity(nr);
        let mut taken = Vec::new();
        for i in 0..nr {
            let (r0, r1) = (i.saturating_sub(2), (i + 2).min(nr - 1));
            let c0 = nc.saturating_sub(3);
            let mut src = Vec::new();
            let mut dst = Vec::new();
            for (ii, row) in g.iter().enumerate().take(r1 + 1).skip(r0) {
                for (j, p) in row.iter().enumerate().skip(c0) {
                    src.push(DVec2::new(j as f64, ii as f64));
                    dst.push(*p);
                }
            }
            let Some(h) = homography_dlt(&src, &dst) else {
                return self.release(taken);
            };
            let Some(pred) = apply_homography(&h, DVec2::new(nc as f64, i as f64)) else {
                return self.release(taken);
            };
            let last = g[i][nc - 1];
            let spacing = pred.distance(last);
            let mut across = f64::INFINITY;
            if i > 0 {
                across = across.min(g[i - 1][nc - 1].distance(last));
            }
            if i + 1 < nr {
                across = across.min(g[i + 1][nc - 1].distance(last));
            }
            let local = spacing.min(across);
            if local.is_nan() || local <= 3.0 {
                return self.release(taken);
            }
            let found = match self.nearest(pred, 0.3 * spacing) {
                Some(ci) => {
                    self.used[ci] = true;
                    taken.push(ci);
                    Some(self.cands[ci].p)
                }
                None => {
                    let hw = (0.3 * local).round().clamp(2.0, 8.0) as i32;
                    let r = (0.35 * local).min(self.ring_radius_px);
                    self.grads
                        .refine_corner(pred, hw)
                        .filter(|p| p.distance(pred) < 0.3 * spacing)
                        .filter(|p| x_junction(self.smooth, *p, r).is_some())
                }
            };
            let Some(p) = found else {
                return self.release(taken);
            };
            if !self.edge_ok(last, p, 0.2 * local, min_contrast) {
                return self.release(taken);
            }
            new.push(p);
        }
        for (row, p) in g.iter_mut().zip(new) {
            row.push(p);
        }
        true
    }

    fn release(&mut self, taken: Vec<usize>) -> bool {
        for i in taken {
            self.used[i] = false;
        }
        false
    }

    /// Grows `g` in all four directions until it stops or exceeds `max_side`.
    fn grow(&mut self, mut g: Grid, max_side: usize, min_contrast: f32) -> Option<Grid> {
        loop {
            let mut grew = false;
            for dir in 0..4 {
                // Bring the side to grow to the right, grow, and turn back.
                let mut t = match dir {
                    0 => g.clone(),
                    1 => mirror_cols(&g),
                    2 => transpose(&g),
                    _ => mirror_cols(&transpose(&g)),
                };
                while self.expand_right(&mut t, min_contrast) {
                    grew = true;
                    if t[0].len() > max_side {
                        return None;
                    }
                }
                g = match dir {
                    0 => t,
                    1 => mirror_cols(&t),
                    2 => transpose(&t),
                    _ => transpose(&mirror_cols(&t)),
                };
            }
            if !grew {
                return Some(g);
            }
        }
    }
}

/// Refines corners to sub-pixel by gradient orthogonality, as OpenCV's `cornerSubPix`: each
/// corner moves to the point that the image's edges around it (within a Gaussian-weighted
/// window of `half_window_px`, on the image smoothed with sigma 1 px) point at. Works for
/// X-junctions and for L-corners of a dark square on a light ground; the window must not
/// reach other edges. `None` for a corner whose window leaves the image, that has no corner
/// structure, or that moves by more than the half window.
pub fn refine_corners(
    image: &GrayImage,
    corners: &[DVec2],
    half_window_px: u32,
) -> Vec<Option<DVec2>> {
    if image.data.len() != image.width as usize * image.height as usize
        || image.width < 3
        || image.height < 3
    {
        return vec![None; corners.len()];
    }
    let grads = Gradients::new(image);
    let hw = half_window_px.clamp(1, 64) as i32;
    corners
        .iter()
        .map(|p| grads.refine_corner(*p, hw))
        .collect()
}

/// Finds the `size.rows` x `size.cols` inner corners of a chessboard, refined to sub-pixel
/// and ordered as described in the module docs. `None` when the board is not found
/// completely (cut by the image border, partly hidden, too small, or another size).
pub fn find_chessboard(image: &GrayImage, size: ChessboardSize) -> Option<Vec<DVec2>> {
    let (rows, cols) = (size.rows as usize, size.cols as usize);
    if rows < 2 || cols < 2 || image.width < 16 || image.height < 16 {
        return None;
    }
    if image.data.len() != image.width as usize * image.height as usize {
        return None;
    }
    let raw = FloatImage::from_gray(image);
    let grads = Gradients::new(image);
    for scale in &SCALES {
        if let Some(corners) = find_at_scale(&raw, &grads, rows, cols, scale) {
            return Some(corners);
        }
    }
    None
}

/// One detection pass's scale.
struct Scale {
    /// Smoothing before the saddle response, pixels.
    blur_sigma_px: f64,
    /// Radius of the X-junction ring test, pixels.
    ring_radius_px: f64,
    /// Smallest |sin| of the angle between the grid's two directions at the seed.
    min_seed_sin: f64,
}

/// The passes, coarse first. The second, finer pass runs only when the first finds nothing:
/// small boards seen at grazing angles (squares a few pixels across, corners sheared to
/// acute angles).
const SCALES: [Scale; 2] = [
    Scale {
        blur_sigma_px: BLUR_SIGMA_PX,
        ring_radius_px: RING_RADIUS_PX,
        min_seed_sin: 0.5,
    },
    Scale {
        blur_sigma_px: 1.0,
        ring_radius_px: 2.5,
        min_seed_sin: 0.25,
    },
];

fn find_at_scale(
    raw: &FloatImage,
    grads: &Gradients,
    rows: usize,
    cols: usize,
    scale: &Scale,
) -> Option<Vec<DVec2>> {
    let smooth = raw.blurred(scale.blur_sigma_px);
    let cands = candidates(&smooth, grads, scale.ring_radius_px);
    if cands.len() < rows * cols {
        return None;
    }
    let n = cands.len();
    let mut det = Detector {
        smooth: &smooth,
        grads,
        cands,
        used: vec![false; n],
        ring_radius_px: scale.ring_radius_px,
        min_seed_sin: scale.min_seed_sin,
    };
    let mut tried = vec![false; n];
    let max_side = rows.max(cols);
    let mut attempts = 0;
    for si in 0..n {
        if tried[si] {
            continue;
        }
        attempts += 1;
        if attempts > 40 {
            break;
        }
        det.used.iter_mut().for_each(|u| *u = false);
        let min_contrast = (0.3 * det.cands[si].contrast).max(MIN_RING_CONTRAST * 0.5);
        let Some((seed, ids)) = det.seed(si, min_contrast) else {
            tried[si] = true;
            continue;
        };
        for &i in &ids {
            det.used[i] = true;
        }
        let grid = det.grow(seed, max_side, min_contrast);
        // Whatever happens, the candidates of this grid are not tried as seeds again.
        for (i, u) in det.used.iter().enumerate() {
            if *u {
                tried[i] = true;
            }
        }
        tried[si] = true;
        // A grid larger than the board asked for (another board, a tiled floor): go on.
        let Some(grid) = grid else {
            continue;
        };
        let (nr, nc) = (grid.len(), grid[0].len());
        if (nr, nc) == (rows, cols) || (nc, nr) == (rows, cols) {
            return Some(finish(grid, rows, cols, grads));
        }
    }
    None
}

/// Orders the grid (dimensions, handedness, first corner) and refines every corner.
fn finish(grid: Grid, rows: usize, cols: usize, grads: &Gradients) -> Vec<DVec2> {
    let mut g = if grid.len() == rows && grid[0].len() == cols {
        grid
    } else {
        transpose(&grid)
    };
    let along = g[0][cols - 1] - g[0][0];
    let down = g[rows - 1][0] - g[0][0];
    if along.perp_dot(down) < 0.0 {
        // Mirrored: flip the columns (rows stay rows).
        g = mirror_cols(&g);
    }
    let mut options = vec![rotate180(&g), g];
    if rows == cols {
        // Quarter turns: transpose then mirror keeps the handedness.
        let q = mirror_cols(&transpose(&options[1]));
        options.push(rotate180(&q));
        options.push(q);
    }
    let g = options
        .into_iter()
        .min_by(|a, b| (a[0][0].x + a[0][0].y).total_cmp(&(b[0][0].x + b[0][0].y)))
        .unwrap_or_default();
    let mut out = Vec::with_capacity(rows * cols);
    for i in 0..rows {
        for j in 0..cols {
            let p = g[i][j];
            let mut spacing = f64::INFINITY;
            for (di, dj) in [(-1i64, 0i64), (1, 0), (0, -1), (0, 1)] {
                let (ii, jj) = (i as i64 + di, j as i64 + dj);
                if ii >= 0 && jj >= 0 && (ii as usize) < rows && (jj as usize) < cols {
                    spacing = spacing.min(p.distance(g[ii as usize][jj as usize]));
                }
            }
            let hw = (0.4 * spacing).round().clamp(2.0, 10.0) as i32;
            let refined = grads
                .refine_corner(p, hw)
                .filter(|q| q.distance(p) < 0.25 * spacing);
            out.push(refined.unwrap_or(p));
        }
    }
    out
}

/// X-junction candidates: saddle-response maxima, refined and tested.
fn candidates(smooth: &FloatImage, grads: &Gradients, ring_radius_px: f64) -> Vec<Candidate> {
    let (w, h) = (smooth.width, smooth.height);
    let mut resp = vec![0f32; w * h];
    let mut max_r = 0f32;
    for y in 1..h - 1 {
        for x in 1..w - 1 {
            let c = smooth.at(x, y);
            let ixx = smooth.at(x + 1, y) + smooth.at(x - 1, y) - 2.0 * c;
            let iyy = smooth.at(x, y + 1) + smooth.at(x, y - 1) - 2.0 * c;
            let ixy = 0.25
                * (smooth.at(x + 1, y + 1) + smooth.at(x - 1, y - 1)
                    - smooth.at(x + 1, y - 1)
                    - smooth.at(x - 1, y + 1));
            let r = ixy * ixy - ixx * iyy;
            if r > 0.0 {
                resp[y * w + x] = r;
                max_r = max_r.max(r);
            }
        }
    }
    if max_r.is_nan() || max_r <= 0.0 {
        return Vec::new();
    }
    let thr = 0.02 * max_r;
    let m = ring_radius_px.ceil() as usize + 2; // the ring test needs the radius + 1
    let mut peaks: Vec<(f32, usize, usize)> = Vec::new();
    for y in m..h.saturating_sub(m) {
        for x in m..w.saturating_sub(m) {
            let r = resp[y * w + x];
            if r <= thr {
                continue;
            }
            let mut is_max = true;
            'win: for yy in y - 2..=y + 2 {
                for xx in x - 2..=x + 2 {
                    let o = resp[yy * w + xx];
                    // Ties go to the first in raster order.
                    if o > r || (o == r && (yy, xx) < (y, x)) {
                        is_max = false;
                        break 'win;
                    }
                }
            }
            if is_max {
                peaks.push((r, x, y));
            }
        }
    }
    peaks.sort_by(|a, b| b.0.total_cmp(&a.0));
    peaks.truncate(MAX_CANDIDATES);
    let mut out: Vec<Candidate> = Vec::new();
    for (_, x, y) in peaks {
        let p0 = DVec2::new(x as f64, y as f64);
        let Some(p) = grads.refine_corner(p0, 3).filter(|p| p.distance(p0) < 2.5) else {
            continue;
        };
        let Some(contrast) = x_junction(smooth, p, ring_radius_px) else {
            continue;
        };
        if out.iter().any(|c| c.p.distance_squared(p) < 2.0 * 2.0) {
            continue;
        }
        out.push(Candidate { p, contrast });
    }
    out
}
