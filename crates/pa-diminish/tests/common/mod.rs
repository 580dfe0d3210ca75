//! Deterministic synthetic backgrounds and props shared by the integration tests.
#![allow(dead_code)]

use pa_diminish::{ImageRgba8, Mask};

fn hash(ix: i64, iy: i64, seed: u32) -> f64 {
    let mut h = (ix as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15)
        ^ (iy as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F)
        ^ u64::from(seed).wrapping_mul(0x1656_67B1_9E37_79F9);
    h ^= h >> 31;
    h = h.wrapping_mul(0xBF58_476D_1CE4_E5B9);
    h ^= h >> 29;
    (h >> 11) as f64 / (1u64 << 53) as f64
}

/// Smooth value noise in [0, 1], lattice spacing 1.
pub fn value_noise(x: f64, y: f64, seed: u32) -> f64 {
    let (ix, iy) = (x.floor(), y.floor());
    let (fx, fy) = (x - ix, y - iy);
    let s = |t: f64| t * t * (3.0 - 2.0 * t);
    let (sx, sy) = (s(fx), s(fy));
    let (ix, iy) = (ix as i64, iy as i64);
    let a = hash(ix, iy, seed);
    let b = hash(ix + 1, iy, seed);
    let c = hash(ix, iy + 1, seed);
    let d = hash(ix + 1, iy + 1, seed);
    (a * (1.0 - sx) + b * sx) * (1.0 - sy) + (c * (1.0 - sx) + d * sx) * sy
}

/// Wood-grain-like table texture: warped sinusoidal rings plus two octaves of value noise.
/// `scale` stretches it (1 = grain period about 14 px). Returns linear-ish [0, 255] RGB.
pub fn wood(x: f64, y: f64, scale: f64) -> [f64; 3] {
    let (u, v) = (x / scale, y / scale);
    let warp = 6.0 * value_noise(u / 23.0, v / 23.0, 7);
    let grain = (std::f64::consts::TAU * (0.9 * u + 0.35 * v) / 14.0 + warp).sin();
    let n1 = value_noise(u / 9.0, v / 9.0, 1);
    let n2 = value_noise(u / 4.0, v / 4.0, 2);
    let t = 0.5 + 0.3 * grain + 0.25 * (n1 - 0.5) + 0.15 * (n2 - 0.5);
    [
        60.0 + 150.0 * t,
        40.0 + 110.0 * t,
        25.0 + 70.0 * t + 20.0 * (n2 - 0.5),
    ]
}

pub fn to_u8(v: f64) -> u8 {
    v.round().clamp(0.0, 255.0) as u8
}

pub fn image_from_rgb(w: u32, h: u32, f: impl Fn(f64, f64) -> [f64; 3]) -> ImageRgba8 {
    ImageRgba8::from_fn(w, h, |x, y| {
        let c = f(f64::from(x), f64::from(y));
        [to_u8(c[0]), to_u8(c[1]), to_u8(c[2]), 255]
    })
    .expect("valid size")
}

/// A linear colour ramp (all channels stay in range for images up to 256 x 192).
pub fn gradient(x: f64, y: f64) -> [f64; 3] {
    [
        40.0 + 0.5 * x + 0.3 * y,
        200.0 - 0.4 * x + 0.2 * y,
        100.0 + 0.25 * x - 0.35 * y,
    ]
}

/// An irregular blob (ellipse with a wobbly radius) centred at (cx, cy).
pub fn blob(w: u32, h: u32, cx: f64, cy: f64, rx: f64, ry: f64) -> Mask {
    Mask::from_fn(w, h, |x, y| {
        let dx = (f64::from(x) - cx) / rx;
        let dy = (f64::from(y) - cy) / ry;
        let a = dy.atan2(dx);
        let r = 1.0 + 0.12 * (3.0 * a).sin() + 0.06 * (5.0 * a + 1.0).cos();
        dx * dx + dy * dy <= r * r
    })
    .expect("valid size")
}

/// Paints the prop (a saturated colour) over the mask.
pub fn paint(img: &mut ImageRgba8, mask: &Mask, rgb: [u8; 3]) {
    for y in 0..mask.height() {
        for x in 0..mask.width() {
            if mask.get(x, y) {
                let a = img.get(x, y).map_or(255, |p| p[3]);
                img.set(x, y, [rgb[0], rgb[1], rgb[2], a]);
            }
        }
    }
}

/// Largest absolute channel difference over the mask.
pub fn max_abs_diff(a: &ImageRgba8, b: &ImageRgba8, mask: &Mask) -> u8 {
    let mut m = 0u8;
    for (i, (pa, pb)) in a
        .as_slice()
        .chunks_exact(4)
        .zip(b.as_slice().chunks_exact(4))
        .enumerate()
    {
        if mask.as_slice()[i] != 0 {
            for c in 0..3 {
                m = m.max(pa[c].abs_diff(pb[c]));
            }
        }
    }
    m
}

pub fn srgb_to_linear(c: f64) -> f64 {
    let c = c / 255.0;
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

pub fn linear_to_srgb(l: f64) -> f64 {
    let l = l.clamp(0.0, 1.0);
    255.0
        * if l <= 0.003_130_8 {
            12.92 * l
        } else {
            1.055 * l.powf(1.0 / 2.4) - 0.055
        }
}
