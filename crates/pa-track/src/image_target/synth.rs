//! Synthetic pictures and views, for tests and benchmarks: a procedural "natural" picture
//! (multi-octave value noise, random discs and boxes, text-like strokes; deterministic) and
//! an exact pinhole view of a picture lying on the marker plane (each frame pixel's ray is
//! intersected with the plane: an exact homography, supersampled 3 x 3 with bilinear
//! picture samples), optionally blurred and with Gaussian noise.

use glam::{DVec2, DVec3};

use crate::{GrayImage, Pose};

/// A small deterministic generator (xorshift64*).
#[derive(Debug, Clone)]
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Self {
        Self(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1)
    }
    /// Uniform in [0, 1).
    pub fn uniform(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        (self.0.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11) as f64 / (1u64 << 53) as f64
    }
    /// Standard normal.
    pub fn normal(&mut self) -> f64 {
        let u = self.uniform().max(1e-300);
        (-2.0 * u.ln()).sqrt() * (2.0 * std::f64::consts::PI * self.uniform()).cos()
    }
}

/// A procedural picture of `width x height` pixels.
pub fn natural_picture(width: u32, height: u32, seed: u64) -> GrayImage {
    let (w, h) = (width as usize, height as usize);
    let mut rng = Rng::new(seed);
    let mut img = vec![0f64; w * h];
    // Value noise, octaves of cell 64, 32, 16, 8 px.
    for (oct, cell) in [64usize, 32, 16, 8].into_iter().enumerate() {
        let gw = w / cell + 2;
        let gh = h / cell + 2;
        let grid: Vec<f64> = (0..gw * gh).map(|_| rng.uniform() - 0.5).collect();
        let amp = 120.0 / (1 << oct) as f64;
        for y in 0..h {
            let gy = y as f64 / cell as f64;
            let (y0, fy) = (gy as usize, gy.fract());
            let sy = fy * fy * (3.0 - 2.0 * fy);
            for x in 0..w {
                let gx = x as f64 / cell as f64;
                let (x0, fx) = (gx as usize, gx.fract());
                let sx = fx * fx * (3.0 - 2.0 * fx);
                let v = |i: usize, j: usize| grid[j * gw + i];
                let top = v(x0, y0) + (v(x0 + 1, y0) - v(x0, y0)) * sx;
                let bot = v(x0, y0 + 1) + (v(x0 + 1, y0 + 1) - v(x0, y0 + 1)) * sx;
                img[y * w + x] += amp * (top + (bot - top) * sy);
            }
        }
    }
    let scale = (w.min(h) as f64 / 256.0).max(0.25);
    // Discs and boxes.
    for i in 0..(40.0 * (w * h) as f64 / 65536.0) as usize {
        let cx = rng.uniform() * w as f64;
        let cy = rng.uniform() * h as f64;
        let r = (4.0 + rng.uniform() * 22.0) * scale;
        let val = rng.uniform() * 255.0 - 127.0;
        let square = i % 2 == 0;
        let (x0, x1) = ((cx - r).max(0.0) as usize, ((cx + r) as usize).min(w - 1));
        let (y0, y1) = ((cy - r).max(0.0) as usize, ((cy + r) as usize).min(h - 1));
        for y in y0..=y1 {
            for x in x0..=x1 {
                let (dx, dy) = (x as f64 - cx, y as f64 - cy);
                if square || dx * dx + dy * dy <= r * r {
                    img[y * w + x] = 0.5 * img[y * w + x] + 0.5 * val;
                }
            }
        }
    }
    // Text-like strokes: short dark polylines in rows.
    let rows = (h as f64 / (28.0 * scale)) as usize;
    for row in 0..rows {
        if rng.uniform() < 0.5 {
            continue;
        }
        let y_base = (row as f64 + 0.5) * 28.0 * scale;
        let mut x = rng.uniform() * 0.3 * w as f64;
        let end = x + (0.2 + rng.uniform() * 0.5) * w as f64;
        while x < end.min(w as f64 - 8.0 * scale) {
            let mut p = DVec2::new(x, y_base + rng.uniform() * 6.0 * scale);
            for _ in 0..3 {
                let q = p + DVec2::new(
                    rng.uniform() * 6.0 * scale,
                    (rng.uniform() - 0.5) * 14.0 * scale,
                );
                let n = (p.distance(q) * 2.0).ceil() as usize + 1;
                for k in 0..=n {
                    let c = p.lerp(q, k as f64 / n as f64);
                    let t = (1.2 * scale).max(1.0);
                    let (xa, xb) = ((c.x - t).max(0.0) as usize, ((c.x + t) as usize).min(w - 1));
                    let (ya, yb) = ((c.y - t).max(0.0) as usize, ((c.y + t) as usize).min(h - 1));
                    for yy in ya..=yb {
                        for xx in xa..=xb {
                            img[yy * w + xx] = -110.0;
                        }
                    }
                }
                p = q;
            }
            x += (8.0 + rng.uniform() * 6.0) * scale;
        }
    }
    let data = img
        .iter()
        .map(|v| (128.0 + v).round().clamp(0.0, 255.0) as u8)
        .collect();
    GrayImage {
        width,
        height,
        data,
    }
}

/// A pinhole camera without distortion for [`render_view`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pinhole {
    pub fx: f64,
    pub fy: f64,
    pub cx: f64,
    pub cy: f64,
    pub width: u32,
    pub height: u32,
}

/// The frame seen by `camera` at `camera_from_marker`, the picture printed `width_m` wide
/// centred on the marker origin (+X along its width, +Y down it), on a plain background of
/// gray `background`; `blur_sigma_px` Gaussian blur then Gaussian noise of `noise_sigma`
/// gray levels (seeded).
#[allow(clippy::too_many_arguments)]
pub fn render_view(
    picture: &GrayImage,
    width_m: f64,
    camera: &Pinhole,
    camera_from_marker: &Pose,
    background: u8,
    blur_sigma_px: f64,
    noise_sigma: f64,
    seed: u64,
) -> GrayImage {
    let (pw, ph) = (picture.width as f64, picture.height as f64);
    let height_m = width_m * ph / pw;
    let inv = camera_from_marker.inverse();
    let origin = inv.translation;
    let (w, h) = (camera.width as usize, camera.height as usize);
    let sample = |u: f64, v: f64| -> f64 {
        let x = u.clamp(0.0, pw - 1.0);
        let y = v.clamp(0.0, ph - 1.0);
        let x0 = (x as usize).min(picture.width as usize - 2);
        let y0 = (y as usize).min(picture.height as usize - 2);
        let (fx, fy) = (x - x0 as f64, y - y0 as f64);
        let pwu = picture.width as usize;
        let p = |i: usize, j: usize| picture.data[j * pwu + i] as f64;
        let top = p(x0, y0) + (p(x0 + 1, y0) - p(x0, y0)) * fx;
        let bot = p(x0, y0 + 1) + (p(x0 + 1, y0 + 1) - p(x0, y0 + 1)) * fx;
        top + (bot - top) * fy
    };
    let mut out = vec![0f64; w * h];
    for (i, o) in out.iter_mut().enumerate() {
        let (x, y) = ((i % w) as f64, (i / w) as f64);
        let mut acc = 0.0;
        for sy in [-1.0 / 3.0, 0.0, 1.0 / 3.0] {
            for sx in [-1.0 / 3.0, 0.0, 1.0 / 3.0] {
                let ray_c = DVec3::new(
                    (x + sx - camera.cx) / camera.fx,
                    (y + sy - camera.cy) / camera.fy,
                    1.0,
                );
                let d = inv.rotation * ray_c;
                let t = -origin.z / d.z;
                let hit = origin + t * d;
                let u = (hit.x / width_m + 0.5) * pw - 0.5;
                let v = (hit.y / height_m + 0.5) * ph - 0.5;
                acc += if d.z.abs() > 1e-12
                    && t > 0.0
                    && u >= -0.5
                    && v >= -0.5
                    && u <= pw - 0.5
                    && v <= ph - 0.5
                {
                    sample(u, v)
                } else {
                    background as f64
                };
            }
        }
        *o = acc / 9.0;
    }
    if blur_sigma_px > 0.0 {
        let r = (3.0 * blur_sigma_px).ceil() as isize;
        let k: Vec<f64> = (-r..=r)
            .map(|i| (-(i * i) as f64 / (2.0 * blur_sigma_px * blur_sigma_px)).exp())
            .collect();
        let ks: f64 = k.iter().sum();
        let mut tmp = vec![0f64; w * h];
        for y in 0..h {
            for x in 0..w {
                let mut s = 0.0;
                for (j, kv) in k.iter().enumerate() {
                    let xx = (x as isize + j as isize - r).clamp(0, w as isize - 1) as usize;
                    s += kv * out[y * w + xx];
                }
                tmp[y * w + x] = s / ks;
            }
        }
        for y in 0..h {
            for x in 0..w {
                let mut s = 0.0;
                for (j, kv) in k.iter().enumerate() {
                    let yy = (y as isize + j as isize - r).clamp(0, h as isize - 1) as usize;
                    s += kv * tmp[yy * w + x];
                }
                out[y * w + x] = s / ks;
            }
        }
    }
    let mut rng = Rng::new(seed);
    let data = out
        .iter()
        .map(|v| (v + noise_sigma * rng.normal()).round().clamp(0.0, 255.0) as u8)
        .collect();
    GrayImage {
        width: camera.width,
        height: camera.height,
        data,
    }
}

/// A pose looking at the marker origin from `distance_m`, tilted `tilt_deg` from the
/// plane's normal (the camera moved towards -Y of the marker, i.e. the picture's top is
/// farther), rolled `roll_deg` about the optical axis, the picture's centre shifted by
/// `offset_px`-like normalised offsets `(ox, oy)` (in units of the distance).
pub fn view_pose(distance_m: f64, tilt_deg: f64, roll_deg: f64, ox: f64, oy: f64) -> Pose {
    use glam::{DMat3, DQuat};
    // Camera looking straight down the marker's +Z with camera axes = marker axes.
    let tilt = DQuat::from_rotation_x(-tilt_deg.to_radians());
    let roll = DQuat::from_rotation_z(roll_deg.to_radians());
    let r = roll * tilt;
    let t = DVec3::new(ox * distance_m, oy * distance_m, distance_m);
    Pose::from_rotation_translation(DMat3::from_quat(r), t)
}
