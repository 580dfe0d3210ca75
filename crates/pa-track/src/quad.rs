//! Our own AprilTag quad fitting and decoding, on our binarisation and connected-component
//! clusters (`segment.rs`).
//!
//! kornia-apriltag 0.2 (a dependency until its family tables were vendored, see `family.rs`)
//! follows the AprilTag C library's pipeline but departs from it in ways that cost small,
//! tilted tags: its quad fit weights the boundary points by the gradient of the *binarised*
//! image (the C library: of the grey image), keeps duplicate boundary points, and its bit
//! sampling is half a pixel off the C library's bilinear sampling. On the conformance photos
//! its quads were 0.1-0.6 px off the C library's and 7 of 47 tags failed to decode.
//! The stages here follow the published
//! algorithm (Olson 2011, Wang & Olson 2016; AprilTag 3 `fit_quad`, `quad_decode`) in double
//! precision:
//!
//! - [`fit_quad`]: sort the cluster's boundary points by angle around the bounding-box
//!   centre, drop duplicates, weight each point by the grey-level gradient magnitude, find
//!   the four corners as maxima of a smoothed local line-fit error, fit the four lines and
//!   intersect them.
//! - [`decode`]: homography from the quad, a planar grey model of the white and black border
//!   cells, bilinear sampling of the bit cells, a small Laplacian sharpening, and a lookup of
//!   the code (in four rotations) within the family's Hamming radius.
//!
//! Coordinates here are the C library's (pixel `(0, 0)` covers `[0, 1)^2`); the caller
//! converts.

#![allow(clippy::needless_range_loop)]

use glam::DVec2;

use crate::family::{FamilyDef, QuickDecode};

/// A boundary point between a black and a white component, at twice the pixel resolution
/// (`x = 2 * px + dx`), with the direction towards white.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Pt {
    pub x: u16,
    pub y: u16,
    pub gx: i16,
    pub gy: i16,
    pub slope: f32,
}

/// Quad-fit parameters (the C library's defaults).
#[derive(Debug, Clone, Copy)]
pub(crate) struct QuadParams {
    pub max_nmaxima: usize,
    pub max_line_fit_mse: f64,
    pub cos_critical_rad: f64,
}

impl Default for QuadParams {
    fn default() -> Self {
        Self {
            max_nmaxima: 10,
            max_line_fit_mse: 10.0,
            cos_critical_rad: (10.0f64).to_radians().cos(),
        }
    }
}

/// A fitted quad: corners in the order the angular sort gives (clockwise on screen), and
/// whether the black border lies outside the white one.
#[derive(Debug, Clone, Copy)]
pub(crate) struct RawQuad {
    pub p: [DVec2; 4],
    pub reversed_border: bool,
}

/// Cumulative weighted moments of the sorted boundary points.
#[derive(Debug, Clone, Copy, Default)]
struct Moments {
    mx: f64,
    my: f64,
    mxx: f64,
    mxy: f64,
    myy: f64,
    w: f64,
}

/// Moments of the points `[i0, i1]` (inclusive, wrapping when `i1 < i0`) and their count.
#[inline]
fn range_moments(lfps: &[Moments], i0: usize, i1: usize) -> (Moments, usize) {
    let sz = lfps.len();
    if i0 < i1 {
        let mut m = lfps[i1];
        if i0 > 0 {
            let a = lfps[i0 - 1];
            m.mx -= a.mx;
            m.my -= a.my;
            m.mxx -= a.mxx;
            m.mxy -= a.mxy;
            m.myy -= a.myy;
            m.w -= a.w;
        }
        (m, i1 - i0 + 1)
    } else {
        let (last, a, b) = (lfps[sz - 1], lfps[i0 - 1], lfps[i1]);
        (
            Moments {
                mx: last.mx - a.mx + b.mx,
                my: last.my - a.my + b.my,
                mxx: last.mxx - a.mxx + b.mxx,
                mxy: last.mxy - a.mxy + b.mxy,
                myy: last.myy - a.myy + b.myy,
                w: last.w - a.w + b.w,
            },
            sz - i0 + i1 + 1,
        )
    }
}

/// Total squared error (`N * smallest eigenvalue`) of the line through `[i0, i1]`.
#[inline]
fn line_err(lfps: &[Moments], i0: usize, i1: usize) -> f64 {
    let (m, n) = range_moments(lfps, i0, i1);
    let iw = 1.0 / m.w;
    let ex = m.mx * iw;
    let ey = m.my * iw;
    let cxx = m.mxx * iw - ex * ex;
    let cxy = m.mxy * iw - ex * ey;
    let cyy = m.myy * iw - ey * ey;
    let root = (((cxx - cyy) * (cxx - cyy) + 4.0 * cxy * cxy) as f32).sqrt() as f64;
    n as f64 * 0.5 * (cxx + cyy - root)
}

/// Line through the points `[i0, i1]` (inclusive, wrapping when `i1 < i0`): `(centroid,
/// unit normal)`, total squared error (`N * smallest eigenvalue`) and mean squared error
/// (the eigenvalue).
fn fit_line(lfps: &[Moments], i0: usize, i1: usize) -> ([f64; 4], f64, f64) {
    let (m, n) = range_moments(lfps, i0, i1);
    let ex = m.mx / m.w;
    let ey = m.my / m.w;
    let cxx = m.mxx / m.w - ex * ex;
    let cxy = m.mxy / m.w - ex * ey;
    let cyy = m.myy / m.w - ey * ey;
    // The reference implementation takes this square root in single precision; we do too,
    // so that corner selection ties break the same way.
    let root = (((cxx - cyy) * (cxx - cyy) + 4.0 * cxy * cxy) as f32).sqrt() as f64;
    let eig_small = 0.5 * (cxx + cyy - root);
    let eig = 0.5 * (cxx + cyy + root);
    let (nx1, ny1) = (cxx - eig, cxy);
    let (nx2, ny2) = (cxy, cyy - eig);
    let (m1, m2) = (nx1 * nx1 + ny1 * ny1, nx2 * nx2 + ny2 * ny2);
    let (nx, ny, mm) = if m1 > m2 {
        (nx1, ny1, m1)
    } else {
        (nx2, ny2, m2)
    };
    let len = (mm as f32).sqrt() as f64;
    (
        [ex, ey, nx / len, ny / len],
        n as f64 * eig_small,
        eig_small,
    )
}

/// Reusable buffers of [`fit_quad`].
#[derive(Default)]
pub(crate) struct FitScratch {
    keys: Vec<u64>,
    sorted: Vec<Pt>,
    lfps: Vec<Moments>,
    errs: Vec<f64>,
    smooth: Vec<f64>,
    maxima: Vec<usize>,
}

/// Gaussian low-pass filter of the line-fit errors (sigma 1, 7 taps, unnormalised).
const SMOOTH: [f32; 7] = [
    0.011_108_997,
    0.135_335_28,
    0.606_530_66,
    1.0,
    0.606_530_66,
    0.135_335_28,
    0.011_108_997,
];

/// The four corner indices of the sorted cluster, or `None`.
fn segment_maxima(
    lfps: &[Moments],
    params: &QuadParams,
    errs: &mut Vec<f64>,
    smooth: &mut Vec<f64>,
    maxima: &mut Vec<usize>,
) -> Option<[usize; 4]> {
    let sz = lfps.len();
    let ksz = (sz / 12).min(20);
    if ksz < 2 {
        return None;
    }
    // Local line-fit error around every point, padded by 3 on each side (circular).
    errs.clear();
    errs.extend((sz - 3..2 * sz + 3).map(|i| line_err(lfps, (i - ksz) % sz, (i + ksz) % sz)));
    smooth.clear();
    smooth.extend(errs.windows(7).map(|e| {
        let mut acc = 0.0;
        for (v, f) in e.iter().zip(SMOOTH) {
            acc += v * f as f64;
        }
        acc
    }));
    let smooth = &smooth[..];
    maxima.clear();
    maxima
        .extend((0..sz).filter(|&i| {
            smooth[i] > smooth[(i + 1) % sz] && smooth[i] > smooth[(i + sz - 1) % sz]
        }));
    if maxima.len() < 4 {
        return None;
    }
    if maxima.len() > params.max_nmaxima {
        errs.clear();
        errs.extend(maxima.iter().map(|&i| smooth[i]));
        errs.sort_by(|a, b| b.total_cmp(a));
        let thresh = errs[params.max_nmaxima];
        maxima.retain(|&i| smooth[i] > thresh);
    }
    let n = maxima.len();
    if n < 4 {
        return None;
    }
    // Line fits between every ordered pair of maxima (forward, and wrapping for the last
    // side), computed once.
    const M: usize = 16;
    if n > M {
        return None;
    }
    let mut fits = [[([0.0f64; 4], 0.0f64, 0.0f64); M]; M];
    for a in 0..n {
        for b in 0..n {
            if a != b {
                fits[a][b] = fit_line(lfps, maxima[a], maxima[b]);
            }
        }
    }
    let mut best = (f64::INFINITY, [0usize; 4]);
    let max_mse = params.max_line_fit_mse;
    for m0 in 0..n - 3 {
        for m1 in m0 + 1..n - 2 {
            let (p01, err01, mse01) = fits[m0][m1];
            if mse01 > max_mse {
                continue;
            }
            for m2 in m1 + 1..n - 1 {
                let (p12, err12, mse12) = fits[m1][m2];
                if mse12 > max_mse {
                    continue;
                }
                let dot = p01[2] * p12[2] + p01[3] * p12[3];
                if dot.abs() > params.cos_critical_rad {
                    continue;
                }
                for m3 in m2 + 1..n {
                    let (_, err23, mse23) = fits[m2][m3];
                    if mse23 > max_mse {
                        continue;
                    }
                    let (_, err30, mse30) = fits[m3][m0];
                    if mse30 > max_mse {
                        continue;
                    }
                    let err = err01 + err12 + err23 + err30;
                    if err < best.0 {
                        best = (err, [maxima[m0], maxima[m1], maxima[m2], maxima[m3]]);
                    }
                }
            }
        }
    }
    (best.0.is_finite() && best.0 / (sz as f64) < max_mse).then_some(best.1)
}

/// Sorts the points by `slope` (ties in input order, via `(order-preserving key, index)`
/// pairs) and drops repeated positions.
fn sort_by_slope_dedup(cluster: &mut Vec<Pt>, keys: &mut Vec<u64>, sorted: &mut Vec<Pt>) {
    let key = |v: f32| {
        let b = v.to_bits();
        if b >> 31 == 0 {
            b ^ 0x8000_0000
        } else {
            !b
        }
    };
    keys.clear();
    keys.extend(
        cluster
            .iter()
            .enumerate()
            .map(|(i, p)| ((key(p.slope) as u64) << 32) | i as u64),
    );
    keys.sort_unstable();
    sorted.clear();
    let mut last = (u16::MAX, u16::MAX);
    for k in keys.iter() {
        let p = cluster[(k & 0xFFFF_FFFF) as usize];
        if (p.x, p.y) != last {
            sorted.push(p);
            last = (p.x, p.y);
        }
    }
    std::mem::swap(cluster, sorted);
}

/// Fits a quad to one cluster of boundary points; `gray` is the image the points came from
/// (its gradient weights the points). `tag_width`: the smallest tag width in pixels of this
/// image (quads with less area than its square are dropped).
#[allow(clippy::too_many_arguments)]
pub(crate) fn fit_quad(
    gray: &[u8],
    width: usize,
    height: usize,
    cluster: &mut Vec<Pt>,
    tag_width: u32,
    normal_border: bool,
    reversed_border: bool,
    params: &QuadParams,
    scratch: &mut FitScratch,
) -> Option<RawQuad> {
    if cluster.len() < 24 {
        return None;
    }
    let (mut xmin, mut xmax, mut ymin, mut ymax) = (u16::MAX, 0u16, u16::MAX, 0u16);
    for p in cluster.iter() {
        xmin = xmin.min(p.x);
        xmax = xmax.max(p.x);
        ymin = ymin.min(p.y);
        ymax = ymax.max(p.y);
    }
    if ((xmax - xmin) as u32) * ((ymax - ymin) as u32) < tag_width {
        return None;
    }
    // A slightly offset centre gives the points more distinct angles.
    let cx = ((xmin as f64 + xmax as f64) * 0.5 + 0.05118) as f32;
    let cy = ((ymin as f64 + ymax as f64) * 0.5 - 0.028581) as f32;
    // Which side is black: the boundary gradients point towards white.
    let mut dot = 0.0f32;
    for p in cluster.iter() {
        dot += (p.x as f32 - cx) * p.gx as f32 + (p.y as f32 - cy) * p.gy as f32;
    }
    let reversed = dot < 0.0;
    if (reversed && !reversed_border) || (!reversed && !normal_border) {
        return None;
    }
    for p in cluster.iter_mut() {
        let mut dx = p.x as f32 - cx;
        let mut dy = p.y as f32 - cy;
        let quadrant: f32 = match (dy > 0.0, dx > 0.0) {
            (false, false) => -65536.0,
            (false, true) => 0.0,
            (true, false) => 131072.0,
            (true, true) => 65536.0,
        };
        if dy < 0.0 {
            dy = -dy;
            dx = -dx;
        }
        if dx < 0.0 {
            let t = dx;
            dx = dy;
            dy = -t;
        }
        p.slope = quadrant + dy / dx;
    }
    sort_by_slope_dedup(cluster, &mut scratch.keys, &mut scratch.sorted);
    let sz = cluster.len();
    if sz < 24 {
        return None;
    }
    // Cumulative moments, each point weighted by the grey-level gradient magnitude + 1.
    let lfps = &mut scratch.lfps;
    lfps.clear();
    let mut acc = Moments::default();
    for p in cluster.iter() {
        let x = p.x as f64 * 0.5 + 0.5;
        let y = p.y as f64 * 0.5 + 0.5;
        let (ix, iy) = (x as usize, y as usize);
        let w = if ix > 0 && ix + 1 < width && iy > 0 && iy + 1 < height {
            let gx = gray[iy * width + ix + 1] as i32 - gray[iy * width + ix - 1] as i32;
            let gy = gray[(iy + 1) * width + ix] as i32 - gray[(iy - 1) * width + ix] as i32;
            ((gx * gx + gy * gy) as f64).sqrt() + 1.0
        } else {
            1.0
        };
        acc.mx += w * x;
        acc.my += w * y;
        acc.mxx += w * x * x;
        acc.mxy += w * x * y;
        acc.myy += w * y * y;
        acc.w += w;
        lfps.push(acc);
    }
    let idx = segment_maxima(
        lfps,
        params,
        &mut scratch.errs,
        &mut scratch.smooth,
        &mut scratch.maxima,
    )?;
    let mut lines = [[0.0f64; 4]; 4];
    for i in 0..4 {
        let (l, _, mse) = fit_line(lfps, idx[i], idx[(i + 1) & 3]);
        if mse > params.max_line_fit_mse {
            return None;
        }
        lines[i] = l;
    }
    let mut p = [DVec2::ZERO; 4];
    for i in 0..4 {
        let (a, b) = (lines[i], lines[(i + 1) & 3]);
        let (a00, a01, a10, a11) = (a[3], -b[3], -a[2], b[2]);
        let (b0, b1) = (b[0] - a[0], b[1] - a[1]);
        let det = a00 * a11 - a10 * a01;
        if det.abs() < 0.001 {
            return None;
        }
        let l0 = (a11 * b0 - a01 * b1) / det;
        p[i] = DVec2::new(a[0] + l0 * a00, a[1] + l0 * a10);
    }
    let tri = |a: DVec2, b: DVec2, c: DVec2| {
        let (la, lb, lc) = (a.distance(b), b.distance(c), c.distance(a));
        let s = (la + lb + lc) / 2.0;
        (s * (s - la) * (s - lb) * (s - lc)).sqrt()
    };
    let area = tri(p[0], p[1], p[2]) + tri(p[2], p[3], p[0]);
    if area.is_nan() || area < (tag_width * tag_width) as f64 {
        return None;
    }
    for i in 0..4 {
        let d1 = p[(i + 1) & 3] - p[i];
        let d2 = p[(i + 2) & 3] - p[(i + 1) & 3];
        let cos = d1.dot(d2) / (d1.length_squared() * d2.length_squared()).sqrt();
        if cos > params.cos_critical_rad
            || cos < -params.cos_critical_rad
            || d1.x * d2.y < d1.y * d2.x
        {
            return None;
        }
    }
    Some(RawQuad {
        p,
        reversed_border: reversed,
    })
}

/// A 3x3 homography, row-major.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Homography(pub [f64; 9]);

impl Homography {
    /// The homography taking tag coordinates (-1,-1), (1,-1), (1,1), (-1,1) to `p[0..4]`
    /// (Gaussian elimination with partial pivoting on the 8x8 system).
    pub fn from_quad(p: &[DVec2; 4]) -> Option<Self> {
        let src = [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)];
        let mut a = [[0.0f64; 9]; 8];
        for i in 0..4 {
            let (x, y) = src[i];
            let (u, v) = (p[i].x, p[i].y);
            a[2 * i] = [x, y, 1.0, 0.0, 0.0, 0.0, -x * u, -y * u, u];
            a[2 * i + 1] = [0.0, 0.0, 0.0, x, y, 1.0, -x * v, -y * v, v];
        }
        for col in 0..8 {
            let (mut best, mut row) = (0.0, col);
            for (r, ar) in a.iter().enumerate().skip(col) {
                if ar[col].abs() > best {
                    best = ar[col].abs();
                    row = r;
                }
            }
            if best < 1e-10 {
                return None;
            }
            a.swap(col, row);
            for r in col + 1..8 {
                let f = a[r][col] / a[col][col];
                a[r][col] = 0.0;
                for j in col + 1..9 {
                    a[r][j] -= f * a[col][j];
                }
            }
        }
        for col in (0..8).rev() {
            let mut sum = 0.0;
            for i in col + 1..8 {
                sum += a[col][i] * a[i][8];
            }
            a[col][8] = (a[col][8] - sum) / a[col][col];
        }
        let h = [
            a[0][8], a[1][8], a[2][8], a[3][8], a[4][8], a[5][8], a[6][8], a[7][8], 1.0,
        ];
        h.iter().all(|v| v.is_finite()).then_some(Self(h))
    }

    pub fn project(&self, x: f64, y: f64) -> DVec2 {
        let h = &self.0;
        let z = h[6] * x + h[7] * y + h[8];
        DVec2::new(
            (h[0] * x + h[1] * y + h[2]) / z,
            (h[3] * x + h[4] * y + h[5]) / z,
        )
    }
}

/// A tag family's layout, code table and lookup within the detector's Hamming radius.
pub(crate) struct FamilyCodes {
    width_at_border: usize,
    total_width: usize,
    reversed_border: bool,
    nbits: usize,
    bit_x: Vec<i8>,
    bit_y: Vec<i8>,
    codes: Vec<usize>,
    quick: QuickDecode,
    max_hamming: u8,
}

impl FamilyCodes {
    pub fn new(f: &FamilyDef, max_hamming: u8) -> Self {
        let codes = f.codes();
        Self {
            width_at_border: f.width_at_border,
            total_width: f.total_width,
            reversed_border: f.reversed_border,
            nbits: f.nbits,
            bit_x: f.bit_x.to_vec(),
            bit_y: f.bit_y.to_vec(),
            quick: QuickDecode::new(f.nbits, &codes, max_hamming),
            codes,
            max_hamming,
        }
    }

    pub fn width_at_border(&self) -> usize {
        self.width_at_border
    }

    pub fn reversed_border(&self) -> bool {
        self.reversed_border
    }

    fn rotate90(&self, w: usize) -> usize {
        let n = self.nbits;
        let (p, l) = if n % 4 == 1 { (n - 1, 1) } else { (n, 0) };
        let w = ((w >> l) << (p / 4 + l)) | ((w >> (3 * p / 4 + l)) << l) | (w & l);
        w & ((1usize << n) - 1)
    }

    /// The smallest Hamming distance from `rcode`, in any of its four rotations, to a code of
    /// the family.
    fn nearest_hamming(&self, mut rcode: usize) -> u32 {
        let mut best = u32::MAX;
        for _ in 0..4 {
            for &c in &self.codes {
                best = best.min((rcode ^ c).count_ones());
            }
            rcode = self.rotate90(rcode);
        }
        best
    }

    /// `(id, hamming, rotation)` of the code, trying the four rotations.
    fn lookup(&self, mut rcode: usize) -> Option<(u16, u8, u8)> {
        for r in 0..4u8 {
            if let Some((id, hamming)) = self.quick.decode(rcode, &self.codes) {
                return Some((id, hamming, r));
            }
            rcode = self.rotate90(rcode);
        }
        None
    }
}

/// A planar model `g(x, y) = c0 x + c1 y + c2` of the grey level, fitted by least squares.
#[derive(Default)]
struct GrayModel {
    a: [[f64; 3]; 3],
    b: [f64; 3],
}

impl GrayModel {
    fn add(&mut self, x: f64, y: f64, g: f64) {
        let v = [x, y, 1.0];
        for i in 0..3 {
            for j in i..3 {
                self.a[i][j] += v[i] * v[j];
            }
            self.b[i] += v[i] * g;
        }
    }

    /// Cholesky solve of the normal equations.
    fn solve(&self) -> Option<[f64; 3]> {
        let a = &self.a;
        let l00 = a[0][0].sqrt();
        let l10 = a[0][1] / l00;
        let l20 = a[0][2] / l00;
        let l11 = (a[1][1] - l10 * l10).sqrt();
        let l21 = (a[1][2] - l10 * l20) / l11;
        let l22 = (a[2][2] - l20 * l20 - l21 * l21).sqrt();
        let y0 = self.b[0] / l00;
        let y1 = (self.b[1] - l10 * y0) / l11;
        let y2 = (self.b[2] - l20 * y0 - l21 * y1) / l22;
        let c2 = y2 / l22;
        let c1 = (y1 - l21 * c2) / l11;
        let c0 = (y0 - l10 * c1 - l20 * c2) / l00;
        let c = [c0, c1, c2];
        c.iter().all(|v| v.is_finite()).then_some(c)
    }
}

fn eval(c: &[f64; 3], x: f64, y: f64) -> f64 {
    c[0] * x + c[1] * y + c[2]
}

/// Bilinear sample with pixel centres at `+0.5`; `None` outside the image.
fn bilinear(gray: &[u8], width: usize, height: usize, p: DVec2) -> Option<f64> {
    let (fx, fy) = (p.x - 0.5, p.y - 0.5);
    let (x1, y1) = (fx.floor(), fy.floor());
    let (x2, y2) = (fx.ceil(), fy.ceil());
    if !(x1 >= 0.0 && y1 >= 0.0 && x2 < width as f64 && y2 < height as f64) {
        return None;
    }
    let (tx, ty) = (fx - x1, fy - y1);
    let (x1, y1, x2, y2) = (x1 as usize, y1 as usize, x2 as usize, y2 as usize);
    let g = |x: usize, y: usize| gray[y * width + x] as f64;
    Some(
        g(x1, y1) * (1.0 - tx) * (1.0 - ty)
            + g(x2, y1) * tx * (1.0 - ty)
            + g(x1, y2) * (1.0 - tx) * ty
            + g(x2, y2) * tx * ty,
    )
}

/// A decoded tag: id, corrected bits, decision margin, and the homography turned so that
/// tag coordinates (-1,-1), (1,-1), (1,1), (-1,1) are the printed tag's top-left, top-right,
/// bottom-right, bottom-left.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Decoded {
    pub id: u16,
    pub hamming: u8,
    pub margin: f32,
    pub h: Homography,
}

/// Bits read off a quad at corners not yet refined, more than the family's `max_hamming` from
/// every code, under which [`may_decode`] lets the quad through.
pub(crate) const UNREFINED_SLACK_BITS: u32 = 4;

/// Whether the quad may decode once refined: read at these corners, its code lies within the
/// family's `max_hamming` plus [`UNREFINED_SLACK_BITS`] of a code. Corners off by a pixel move
/// a few bits at most; a quad of noise reads as a random code, within 6 bits of one of
/// tag36h11's 587 codes in any rotation about 8 % of the time (`sum C(36, k), k <= 6` times
/// 2,348 over 2^36).
pub(crate) fn may_decode(
    gray: &[u8],
    width: usize,
    height: usize,
    fam: &FamilyCodes,
    h: &Homography,
    sharpening: f64,
) -> bool {
    read_code(gray, width, height, fam, h, sharpening).is_some_and(|(rcode, _)| {
        fam.nearest_hamming(rcode) <= fam.max_hamming as u32 + UNREFINED_SLACK_BITS
    })
}

/// Decodes the quad against one family (on the full-resolution grey image).
pub(crate) fn decode(
    gray: &[u8],
    width: usize,
    height: usize,
    fam: &FamilyCodes,
    h: &Homography,
    sharpening: f64,
) -> Option<Decoded> {
    let (rcode, margin) = read_code(gray, width, height, fam, h, sharpening)?;
    let (id, hamming, rot) = fam.lookup(rcode)?;
    // Turn the homography by the decoded rotation: H * R(rot * 90 deg).
    let (c, s) = match rot {
        0 => (1.0, 0.0),
        1 => (0.0, 1.0),
        2 => (-1.0, 0.0),
        _ => (0.0, -1.0),
    };
    let m = &h.0;
    let hr = Homography([
        m[0] * c + m[1] * s,
        -m[0] * s + m[1] * c,
        m[2],
        m[3] * c + m[4] * s,
        -m[3] * s + m[4] * c,
        m[5],
        m[6] * c + m[7] * s,
        -m[6] * s + m[7] * c,
        m[8],
    ]);
    Some(Decoded {
        id,
        hamming,
        margin,
        h: hr,
    })
}

/// The code read off the quad (bits in the family's order) and its decision margin; `None`
/// when the border's grey levels are the wrong way round or the margin is not a number.
fn read_code(
    gray: &[u8],
    width: usize,
    height: usize,
    fam: &FamilyCodes,
    h: &Homography,
    sharpening: f64,
) -> Option<(usize, f32)> {
    let wb = fam.width_at_border as f64;
    // (start x, start y, step x, step y, white) in cell units.
    let patterns = [
        (-0.5, 0.5, 0.0, 1.0, true),
        (0.5, 0.5, 0.0, 1.0, false),
        (wb + 0.5, 0.5, 0.0, 1.0, true),
        (wb - 0.5, 0.5, 0.0, 1.0, false),
        (0.5, -0.5, 1.0, 0.0, true),
        (0.5, 0.5, 1.0, 0.0, false),
        (0.5, wb + 0.5, 1.0, 0.0, true),
        (0.5, wb - 0.5, 1.0, 0.0, false),
    ];
    let (mut white, mut black) = (GrayModel::default(), GrayModel::default());
    for (sx, sy, dx, dy, is_white) in patterns {
        for i in 0..fam.width_at_border {
            let tx = 2.0 * ((sx + i as f64 * dx) / wb - 0.5);
            let ty = 2.0 * ((sy + i as f64 * dy) / wb - 0.5);
            let p = h.project(tx, ty);
            // Truncation, as the reference does (so -0.5 samples column 0).
            let (ix, iy) = (p.x as i64, p.y as i64);
            if ix < 0 || iy < 0 || ix >= width as i64 || iy >= height as i64 {
                continue;
            }
            let v = gray[iy as usize * width + ix as usize] as f64;
            if is_white {
                white.add(tx, ty, v);
            } else {
                black.add(tx, ty, v);
            }
        }
    }
    let wc = white.solve()?;
    let bc = if fam.width_at_border > 1 {
        black.solve()?
    } else {
        [0.0, 0.0, black.b[2] / 4.0]
    };
    if (eval(&wc, 0.0, 0.0) - eval(&bc, 0.0, 0.0) < 0.0) != fam.reversed_border {
        return None;
    }
    let tw = fam.total_width;
    let min_coord = (fam.width_at_border as i64 - tw as i64) / 2;
    let cell =
        |bx: i8, by: i8| ((by as i64 - min_coord) * tw as i64 + bx as i64 - min_coord) as usize;
    let mut values = vec![0.0f64; tw * tw];
    for i in 0..fam.nbits {
        let (bx, by) = (fam.bit_x[i], fam.bit_y[i]);
        let tx = 2.0 * ((bx as f64 + 0.5) / wb - 0.5);
        let ty = 2.0 * ((by as f64 + 0.5) / wb - 0.5);
        let Some(v) = bilinear(gray, width, height, h.project(tx, ty)) else {
            continue;
        };
        let thresh = (eval(&bc, tx, ty) + eval(&wc, tx, ty)) / 2.0;
        values[cell(bx, by)] = v - thresh;
    }
    // Sharpen with a 3x3 Laplacian.
    let mut sharp = vec![0.0f64; tw * tw];
    for y in 0..tw {
        for x in 0..tw {
            let mut s = 4.0 * values[y * tw + x];
            if y > 0 {
                s -= values[(y - 1) * tw + x];
            }
            if y + 1 < tw {
                s -= values[(y + 1) * tw + x];
            }
            if x > 0 {
                s -= values[y * tw + x - 1];
            }
            if x + 1 < tw {
                s -= values[y * tw + x + 1];
            }
            sharp[y * tw + x] = s;
        }
    }
    for (v, s) in values.iter_mut().zip(&sharp) {
        *v += sharpening * s;
    }
    let mut rcode = 0usize;
    let (mut ws, mut bs) = (0.0f32, 0.0f32);
    let (mut wn, mut bn) = (1.0f32, 1.0f32);
    for i in 0..fam.nbits {
        rcode <<= 1;
        let v = values[cell(fam.bit_x[i], fam.bit_y[i])];
        if v > 0.0 {
            ws += v as f32;
            wn += 1.0;
            rcode |= 1;
        } else {
            bs -= v as f32;
            bn += 1.0;
        }
    }
    let margin = (ws / wn).min(bs / bn);
    if margin.is_nan() || margin < 0.0 {
        return None;
    }
    Some((rcode, margin))
}

/// The reference library's edge refinement (`refine_edges`): for samples along each edge,
/// the gradient-weighted mean position of the edge along the normal within `range`; a line
/// through those; corners at the intersections.
pub(crate) fn refine_edges_reference(
    gray: &[u8],
    width: usize,
    height: usize,
    q: &mut RawQuad,
    range: f64,
) {
    let mut lines = [[0.0f64; 4]; 4];
    for edge in 0..4 {
        let (a, b) = (q.p[edge], q.p[(edge + 1) & 3]);
        let mut n = DVec2::new(b.y - a.y, a.x - b.x);
        let mag = n.length();
        n /= mag;
        if q.reversed_border {
            n = -n;
        }
        let nsamples = 16.max((mag / 8.0) as usize);
        let (mut mx, mut my, mut mxx, mut mxy, mut myy, mut cnt) = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
        for s in 0..nsamples {
            let alpha = (1.0 + s as f64) / (nsamples as f64 + 1.0);
            let p0 = a * alpha + b * (1.0 - alpha);
            let (mut mn, mut mc) = (0.0, 0.0);
            let steps = (2.0 * range / 0.25).round() as usize + 1;
            for k in 0..steps {
                let t = -range + 0.25 * k as f64;
                let p1 = p0 + n * (t + 1.0);
                let p2 = p0 + n * (t - 1.0);
                let (x1, y1, x2, y2) = (p1.x as i64, p1.y as i64, p2.x as i64, p2.y as i64);
                if x1 < 0
                    || y1 < 0
                    || x2 < 0
                    || y2 < 0
                    || x1 >= width as i64
                    || x2 >= width as i64
                    || y1 >= height as i64
                    || y2 >= height as i64
                {
                    continue;
                }
                let g1 = gray[y1 as usize * width + x1 as usize] as f64;
                let g2 = gray[y2 as usize * width + x2 as usize] as f64;
                if g1 < g2 {
                    continue;
                }
                let w = (g2 - g1) * (g2 - g1);
                mn += w * t;
                mc += w;
            }
            if mc <= 0.0 {
                continue;
            }
            let best = p0 + n * (mn / mc);
            mx += best.x;
            my += best.y;
            mxx += best.x * best.x;
            mxy += best.x * best.y;
            myy += best.y * best.y;
            cnt += 1.0;
        }
        let (ex, ey) = (mx / cnt, my / cnt);
        let cxx = mxx / cnt - ex * ex;
        let cxy = mxy / cnt - ex * ey;
        let cyy = myy / cnt - ey * ey;
        let theta = 0.5 * (-2.0 * cxy).atan2(cyy - cxx);
        lines[edge] = [ex, ey, theta.cos(), theta.sin()];
    }
    for i in 0..4 {
        let (a, b) = (lines[i], lines[(i + 1) & 3]);
        let (a00, a01, a10, a11) = (a[3], -b[3], -a[2], b[2]);
        let (b0, b1) = (b[0] - a[0], b[1] - a[1]);
        let det = a00 * a11 - a10 * a01;
        if det.abs() > 0.001 {
            let l0 = (a11 * b0 - a01 * b1) / det;
            let p = DVec2::new(a[0] + l0 * a00, a[1] + l0 * a10);
            if p.is_finite() {
                q.p[(i + 1) & 3] = p;
            }
        }
    }
}

#[cfg(test)]
#[path = "quad_tests.rs"]
mod tests;
