//! The image side of registration: a region of interest of a frame as a grey pyramid, its
//! gradient edges (non-maximum suppressed, binned by orientation) and, per orientation bin, the
//! Euclidean distance to the nearest edge (an exact distance transform), sampled bilinearly
//! with its gradient.

/// Orientation bins of the edges (unsigned direction, 180 degrees / `BINS` each).
pub(crate) const BINS: usize = 6;

/// Edges weaker than this (Sobel magnitude on a 0..1 grey image after a 3x3 binomial blur;
/// a clean step of contrast `c` gives about `4c`) are ignored.
const EDGE_THRESHOLD: f32 = 0.06;

/// A rectangle of the full-resolution frame, pixels.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Roi {
    pub x0: u32,
    pub y0: u32,
    pub width: u32,
    pub height: u32,
}

/// One level of the pyramid: the distance to the nearest edge of each orientation bin.
pub(crate) struct EdgeLevel {
    /// Level pixels per full-resolution pixel (1, 1/2, 1/4, ...).
    pub scale: f64,
    /// The region's origin in full-resolution pixels.
    pub origin: (f64, f64),
    pub width: usize,
    pub height: usize,
    /// Distance (level pixels) to the nearest edge of each bin, row-major.
    pub dist: [Vec<f32>; BINS],
}

/// The orientation bin of an unsigned direction angle (radians).
pub(crate) fn bin_of(angle_rad: f64) -> usize {
    let a = angle_rad.rem_euclid(std::f64::consts::PI);
    ((a / std::f64::consts::PI * BINS as f64) as usize).min(BINS - 1)
}

impl EdgeLevel {
    /// Level coordinates of a full-resolution pixel (pixel centres at integers in both).
    #[inline]
    pub fn to_level(&self, p_full: (f64, f64)) -> (f64, f64) {
        (
            (p_full.0 - self.origin.0 + 0.5) * self.scale - 0.5,
            (p_full.1 - self.origin.1 + 0.5) * self.scale - 0.5,
        )
    }

    /// The distance to the nearest edge of `bin` at level coordinates `(x, y)`, bilinear, and
    /// its gradient; `None` outside the region.
    #[inline]
    pub fn sample(&self, bin: usize, x: f64, y: f64) -> Option<(f64, f64, f64)> {
        if !(x >= 0.0 && y >= 0.0) {
            return None;
        }
        let (xi, yi) = (x.floor() as usize, y.floor() as usize);
        if xi + 1 >= self.width || yi + 1 >= self.height {
            return None;
        }
        let (fx, fy) = (x - xi as f64, y - yi as f64);
        let d = &self.dist[bin];
        let i = yi * self.width + xi;
        let (a, b, c, e) = (
            d[i] as f64,
            d[i + 1] as f64,
            d[i + self.width] as f64,
            d[i + self.width + 1] as f64,
        );
        let top = a + (b - a) * fx;
        let bottom = c + (e - c) * fx;
        let v = top + (bottom - top) * fy;
        let gx = (b - a) * (1.0 - fy) + (e - c) * fy;
        let gy = bottom - top;
        Some((v, gx, gy))
    }
}

/// The grey levels (0..1, Rec. 709 luma of the sRGB values) of `roi` of an RGBA8 frame.
pub(crate) fn grey_roi(rgba8: &[u8], width: u32, roi: Roi) -> Vec<f32> {
    let mut out = Vec::with_capacity((roi.width * roi.height) as usize);
    for y in roi.y0..roi.y0 + roi.height {
        let row = (y * width) as usize;
        for x in roi.x0..roi.x0 + roi.width {
            let i = (row + x as usize) * 4;
            let (r, g, b) = (rgba8[i] as f32, rgba8[i + 1] as f32, rgba8[i + 2] as f32);
            out.push((0.2126 * r + 0.7152 * g + 0.0722 * b) / 255.0);
        }
    }
    out
}

/// Halves an image by 2x2 box filtering (odd last rows/columns dropped).
pub(crate) fn half(img: &[f32], w: usize, h: usize) -> (Vec<f32>, usize, usize) {
    let (hw, hh) = (w / 2, h / 2);
    let mut out = Vec::with_capacity(hw * hh);
    for y in 0..hh {
        for x in 0..hw {
            let i = 2 * y * w + 2 * x;
            out.push(0.25 * (img[i] + img[i + 1] + img[i + w] + img[i + w + 1]));
        }
    }
    (out, hw, hh)
}

/// The edge level of a grey image: blur, Sobel, non-maximum suppression, orientation bins,
/// distance transforms.
pub(crate) fn edge_level(
    img: &[f32],
    w: usize,
    h: usize,
    scale: f64,
    origin: (f64, f64),
) -> EdgeLevel {
    let blurred = blur3(img, w, h);
    let mut gx = vec![0f32; w * h];
    let mut gy = vec![0f32; w * h];
    let mut mag = vec![0f32; w * h];
    for y in 1..h.saturating_sub(1) {
        for x in 1..w.saturating_sub(1) {
            let p = |dx: isize, dy: isize| {
                blurred[((y as isize + dy) as usize) * w + (x as isize + dx) as usize]
            };
            let sx = (p(1, -1) + 2.0 * p(1, 0) + p(1, 1)) - (p(-1, -1) + 2.0 * p(-1, 0) + p(-1, 1));
            let sy = (p(-1, 1) + 2.0 * p(0, 1) + p(1, 1)) - (p(-1, -1) + 2.0 * p(0, -1) + p(1, -1));
            let i = y * w + x;
            gx[i] = sx;
            gy[i] = sy;
            mag[i] = (sx * sx + sy * sy).sqrt();
        }
    }
    let mut seeds: [Vec<bool>; BINS] = std::array::from_fn(|_| vec![false; w * h]);
    for y in 1..h.saturating_sub(1) {
        for x in 1..w.saturating_sub(1) {
            let i = y * w + x;
            let m = mag[i];
            if m < EDGE_THRESHOLD {
                continue;
            }
            // Non-maximum suppression across the edge (the gradient's direction, 4 sectors).
            let angle = (gy[i] as f64).atan2(gx[i] as f64);
            let sector = ((angle.rem_euclid(std::f64::consts::PI) / std::f64::consts::FRAC_PI_4)
                + 0.5) as usize
                % 4;
            let (dx, dy): (isize, isize) = match sector {
                0 => (1, 0),
                1 => (1, 1),
                2 => (0, 1),
                _ => (-1, 1),
            };
            let a = mag[(y as isize + dy) as usize * w + (x as isize + dx) as usize];
            let b = mag[(y as isize - dy) as usize * w + (x as isize - dx) as usize];
            if m < a || m <= b {
                continue;
            }
            // Its bin and the nearer neighbouring bin (a tolerance of about one bin).
            let t = angle.rem_euclid(std::f64::consts::PI) / std::f64::consts::PI * BINS as f64;
            let bin = (t as usize).min(BINS - 1);
            let other = if t - bin as f64 >= 0.5 {
                (bin + 1) % BINS
            } else {
                (bin + BINS - 1) % BINS
            };
            seeds[bin][i] = true;
            seeds[other][i] = true;
        }
    }
    let dist = seeds.map(|s| distance_transform(&s, w, h));
    EdgeLevel {
        scale,
        origin,
        width: w,
        height: h,
        dist,
    }
}

/// A 3x3 binomial blur (edges clamped).
fn blur3(img: &[f32], w: usize, h: usize) -> Vec<f32> {
    let mut tmp = vec![0f32; w * h];
    for y in 0..h {
        for x in 0..w {
            let l = img[y * w + x.saturating_sub(1)];
            let r = img[y * w + (x + 1).min(w - 1)];
            tmp[y * w + x] = 0.25 * l + 0.5 * img[y * w + x] + 0.25 * r;
        }
    }
    let mut out = vec![0f32; w * h];
    for y in 0..h {
        for x in 0..w {
            let u = tmp[y.saturating_sub(1) * w + x];
            let d = tmp[(y + 1).min(h - 1) * w + x];
            out[y * w + x] = 0.25 * u + 0.5 * tmp[y * w + x] + 0.25 * d;
        }
    }
    out
}

/// The exact Euclidean distance (pixels) to the nearest `true` pixel (Felzenszwalb and
/// Huttenlocher's separable lower envelope of parabolas); a large value where there is none.
pub(crate) fn distance_transform(seeds: &[bool], w: usize, h: usize) -> Vec<f32> {
    const FAR: f64 = 1e10;
    let mut f: Vec<f64> = seeds.iter().map(|&s| if s { 0.0 } else { FAR }).collect();
    let n = w.max(h);
    let mut buf_f = vec![0f64; n];
    let mut buf_d = vec![0f64; n];
    let mut v = vec![0usize; n];
    let mut z = vec![0f64; n + 1];
    // Columns.
    for x in 0..w {
        for y in 0..h {
            buf_f[y] = f[y * w + x];
        }
        dt_1d(&buf_f[..h], &mut buf_d[..h], &mut v, &mut z);
        for y in 0..h {
            f[y * w + x] = buf_d[y];
        }
    }
    // Rows.
    for y in 0..h {
        buf_f[..w].copy_from_slice(&f[y * w..(y + 1) * w]);
        dt_1d(&buf_f[..w], &mut buf_d[..w], &mut v, &mut z);
        f[y * w..(y + 1) * w].copy_from_slice(&buf_d[..w]);
    }
    f.iter().map(|&d| d.sqrt().min(1e4) as f32).collect()
}

/// The 1-D squared distance transform of `f` into `d`.
fn dt_1d(f: &[f64], d: &mut [f64], v: &mut [usize], z: &mut [f64]) {
    let n = f.len();
    if n == 0 {
        return;
    }
    let mut k = 0usize;
    v[0] = 0;
    z[0] = f64::NEG_INFINITY;
    z[1] = f64::INFINITY;
    for q in 1..n {
        loop {
            let p = v[k];
            let s = ((f[q] + (q * q) as f64) - (f[p] + (p * p) as f64)) / (2.0 * (q - p) as f64);
            // z[0] is minus infinity, so this stops at k = 0.
            if s <= z[k] {
                k -= 1;
                continue;
            }
            k += 1;
            v[k] = q;
            z[k] = s;
            z[k + 1] = f64::INFINITY;
            break;
        }
    }
    k = 0;
    for (q, out) in d.iter_mut().enumerate() {
        while z[k + 1] < q as f64 {
            k += 1;
        }
        let p = v[k];
        let dq = q as f64 - p as f64;
        *out = dq * dq + f[p];
    }
}
