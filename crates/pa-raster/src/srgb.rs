//! sRGB transfer functions as look-up tables (the conversions a `Rgba8UnormSrgb` texture and
//! render target make on the GPU).

use std::sync::OnceLock;

/// Exact sRGB decode of one 8-bit value to linear light.
pub fn srgb_to_linear(v: u8) -> f32 {
    let c = v as f32 / 255.0;
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// Exact sRGB encode of linear light (clamped to [0, 1]) to 8 bits, rounded to nearest.
pub fn linear_to_srgb(l: f32) -> u8 {
    let l = if l.is_nan() { 0.0 } else { l.clamp(0.0, 1.0) };
    let c = if l <= 0.003_130_8 {
        12.92 * l
    } else {
        1.055 * l.powf(1.0 / 2.4) - 0.055
    };
    (c * 255.0 + 0.5) as u8
}

/// Decode table: 256 linear values.
pub fn decode_lut() -> &'static [f32; 256] {
    static LUT: OnceLock<[f32; 256]> = OnceLock::new();
    LUT.get_or_init(|| std::array::from_fn(|i| srgb_to_linear(i as u8)))
}

/// Number of entries of the encode table (linear [0, 1] quantised to 16 bits).
const ENCODE_STEPS: usize = 1 << 16;

/// Encode table over linear values quantised to 1/65535; see [`encode`].
fn encode_lut() -> &'static [u8] {
    static LUT: OnceLock<Vec<u8>> = OnceLock::new();
    LUT.get_or_init(|| {
        (0..ENCODE_STEPS)
            .map(|i| linear_to_srgb(i as f32 / (ENCODE_STEPS - 1) as f32))
            .collect()
    })
}

/// sRGB encoder through a 16-bit table (within one step of [`linear_to_srgb`]; exact except
/// where a value falls within 1/65535 of a rounding boundary).
#[derive(Clone, Copy)]
pub struct Encoder {
    lut: &'static [u8],
}

impl Encoder {
    pub fn new() -> Self {
        Self { lut: encode_lut() }
    }

    /// Linear light (clamped to [0, 1]; NaN -> 0) to 8-bit sRGB.
    #[inline]
    pub fn encode(&self, l: f32) -> u8 {
        let i = (l.clamp(0.0, 1.0) * (ENCODE_STEPS - 1) as f32 + 0.5) as usize;
        self.lut[i.min(ENCODE_STEPS - 1)]
    }
}

impl Default for Encoder {
    fn default() -> Self {
        Self::new()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_every_value() {
        let e = Encoder::new();
        for v in 0..=255u8 {
            assert_eq!(linear_to_srgb(srgb_to_linear(v)), v);
            assert_eq!(e.encode(decode_lut()[v as usize]), v);
        }
    }

    #[test]
    fn table_matches_exact_encode() {
        let e = Encoder::new();
        let mut worst = 0i32;
        for i in 0..=10_000 {
            let l = i as f32 / 10_000.0;
            worst = worst.max((e.encode(l) as i32 - linear_to_srgb(l) as i32).abs());
        }
        assert!(worst <= 1, "table off by {worst}");
        assert_eq!(e.encode(f32::NAN), 0);
        assert_eq!(e.encode(-1.0), 0);
        assert_eq!(e.encode(7.0), 255);
    }
}
