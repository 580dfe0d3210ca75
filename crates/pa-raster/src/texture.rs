//! Textures for the CPU path: the model's base-colour image with its mip chain (sampled
//! trilinearly with repeat wrapping) and the camera frame (sampled bilinearly at level 0 with
//! clamp-to-edge), both in linear light, as the GPU samples `Rgba8UnormSrgb` textures.

use crate::error::RasterError;
use crate::srgb::{decode_lut, linear_to_srgb};

/// `floor(v)` as an integer without a library call (`f32::floor` is one on CPUs built
/// without SSE4.1); saturates far outside the i64 range, NaN gives 0.
#[inline(always)]
pub(crate) fn floor_i64(v: f32) -> i64 {
    let t = v as i64;
    t - i64::from((t as f32) > v)
}

/// A base-colour texture: linear RGBA (alpha straight) per mip level, level 0 first.
#[derive(Debug, Clone)]
pub struct CpuMipTexture {
    levels: Vec<Level>,
    /// Every texel's alpha is 1.
    opaque: bool,
}

#[derive(Debug, Clone)]
struct Level {
    width: u32,
    height: u32,
    /// Linear RGBA, row-major from the top-left.
    texels: Vec<[f32; 4]>,
}

impl Level {
    fn from_srgb8(width: u32, height: u32, rgba8: &[u8]) -> Self {
        let lut = decode_lut();
        let texels = rgba8
            .chunks_exact(4)
            .map(|p| {
                [
                    lut[p[0] as usize],
                    lut[p[1] as usize],
                    lut[p[2] as usize],
                    p[3] as f32 / 255.0,
                ]
            })
            .collect();
        Self {
            width,
            height,
            texels,
        }
    }

    /// Bilinear sample with repeat wrapping at normalised `(u, v)`.
    #[inline]
    fn bilinear_repeat(&self, u: f32, v: f32) -> [f32; 4] {
        let (w, h) = (self.width as i64, self.height as i64);
        let x = u * w as f32 - 0.5;
        let y = v * h as f32 - 0.5;
        if !(x.is_finite() && y.is_finite()) {
            return self.texels[0];
        }
        let (x0, y0) = (floor_i64(x), floor_i64(y));
        let (fx, fy) = (x - x0 as f32, y - y0 as f32);
        // Repeat wrapping; the division only for coordinates outside [0, 1).
        let wrap = |v: i64, n: i64| {
            if (0..n).contains(&v) {
                v as usize
            } else {
                v.rem_euclid(n) as usize
            }
        };
        let (xa, ya) = (wrap(x0, w), wrap(y0, h));
        let xb = if xa + 1 == w as usize { 0 } else { xa + 1 };
        let yb = if ya + 1 == h as usize { 0 } else { ya + 1 };
        let row = self.width as usize;
        let t = |x: usize, y: usize| self.texels[y * row + x];
        let (p00, p10, p01, p11) = (t(xa, ya), t(xb, ya), t(xa, yb), t(xb, yb));
        std::array::from_fn(|c| {
            let top = p00[c] + (p10[c] - p00[c]) * fx;
            let bottom = p01[c] + (p11[c] - p01[c]) * fx;
            top + (bottom - top) * fy
        })
    }
}

/// The next mip level: 2x2 box filter in linear light, re-encoded to 8-bit sRGB (alpha: the
/// rounded mean); odd sides clamp the last row/column. The same chain as the GPU path's
/// upload builds, so both sample the same texels.
pub fn downsample_srgb8(width: u32, height: u32, rgba8: &[u8]) -> (u32, u32, Vec<u8>) {
    let lut = decode_lut();
    let (w2, h2) = ((width / 2).max(1), (height / 2).max(1));
    let mut out = Vec::with_capacity(w2 as usize * h2 as usize * 4);
    let texel = |x: u32, y: u32, c: usize| -> u8 {
        let i = (y.min(height - 1) as usize * width as usize + x.min(width - 1) as usize) * 4 + c;
        rgba8.get(i).copied().unwrap_or(0)
    };
    for y in 0..h2 {
        for x in 0..w2 {
            for c in 0..4 {
                let s = [
                    texel(2 * x, 2 * y, c),
                    texel(2 * x + 1, 2 * y, c),
                    texel(2 * x, 2 * y + 1, c),
                    texel(2 * x + 1, 2 * y + 1, c),
                ];
                if c == 3 {
                    let sum: u32 = s.iter().map(|&v| v as u32).sum();
                    out.push(((sum + 2) / 4) as u8);
                } else {
                    let sum: f32 = s.iter().map(|&v| lut[v as usize]).sum();
                    out.push(linear_to_srgb(sum * 0.25));
                }
            }
        }
    }
    (w2, h2, out)
}

/// Largest side of a texture the CPU path accepts.
pub const MAX_TEXTURE_SIDE: u32 = 16384;

impl CpuMipTexture {
    /// Builds the texture and its full mip chain from sRGB RGBA8 (row-major, no padding).
    pub fn from_srgb8(width: u32, height: u32, rgba8: &[u8]) -> Result<Self, RasterError> {
        if width == 0 || height == 0 || width > MAX_TEXTURE_SIDE || height > MAX_TEXTURE_SIDE {
            return Err(RasterError::TextureSize { width, height });
        }
        let expected = width as usize * height as usize * 4;
        if rgba8.len() != expected {
            return Err(RasterError::DataLength {
                what: "texture",
                expected,
                got: rgba8.len(),
            });
        }
        let count = 32 - width.max(height).leading_zeros();
        let mut levels = Vec::with_capacity(count as usize);
        let (mut w, mut h) = (width, height);
        let mut data = std::borrow::Cow::Borrowed(rgba8);
        for level in 0..count {
            levels.push(Level::from_srgb8(w, h, &data));
            if level + 1 < count {
                let (w2, h2, next) = downsample_srgb8(w, h, &data);
                (w, h) = (w2, h2);
                data = std::borrow::Cow::Owned(next);
            }
        }
        let opaque = rgba8.chunks_exact(4).all(|p| p[3] == 255);
        Ok(Self { levels, opaque })
    }

    /// True when every texel is opaque (alpha 1 at every level).
    pub fn is_opaque(&self) -> bool {
        self.opaque
    }

    /// A 1x1 white texture (untextured materials sample white, as on the GPU).
    pub fn white() -> Self {
        Self {
            levels: vec![Level {
                width: 1,
                height: 1,
                texels: vec![[1.0; 4]],
            }],
            opaque: true,
        }
    }

    /// Size of level 0.
    pub fn size(&self) -> (u32, u32) {
        (self.levels[0].width, self.levels[0].height)
    }

    /// Number of mip levels.
    pub fn level_count(&self) -> usize {
        self.levels.len()
    }

    /// Trilinear sample (linear RGBA) at normalised `(u, v)` with repeat wrapping, at mip
    /// level `lod` (clamped to the chain; fractional levels blend the two nearest).
    #[inline]
    pub fn sample(&self, u: f32, v: f32, lod: f32) -> [f32; 4] {
        let max = (self.levels.len() - 1) as f32;
        let lod = if lod.is_finite() {
            lod.clamp(0.0, max)
        } else {
            0.0
        };
        let l0 = floor_i64(lod) as f32;
        let f = lod - l0;
        let a = self.levels[l0 as usize].bilinear_repeat(u, v);
        if f <= 0.0 {
            return a;
        }
        let b = self.levels[(l0 as usize + 1).min(self.levels.len() - 1)].bilinear_repeat(u, v);
        std::array::from_fn(|c| a[c] + (b[c] - a[c]) * f)
    }
}

/// A camera frame (sRGB RGBA8) sampled bilinearly in linear light with clamp-to-edge
/// addressing at OpenCV pixel coordinates (texel centres at integers).
#[derive(Debug, Clone, Copy)]
pub struct FrameSampler<'a> {
    pub width: u32,
    pub height: u32,
    pub rgba8: &'a [u8],
}

impl<'a> FrameSampler<'a> {
    /// Checks the data length.
    pub fn new(width: u32, height: u32, rgba8: &'a [u8]) -> Result<Self, RasterError> {
        let expected = width as usize * height as usize * 4;
        if width == 0 || height == 0 || rgba8.len() != expected {
            return Err(RasterError::DataLength {
                what: "camera frame",
                expected,
                got: rgba8.len(),
            });
        }
        Ok(Self {
            width,
            height,
            rgba8,
        })
    }

    /// Linear RGB at pixel `(px, py)` (OpenCV convention: the centre of pixel `(i, j)` is the
    /// point `(i, j)`).
    #[inline(always)]
    pub fn sample_linear(&self, px: f32, py: f32, lut: &[f32; 256]) -> [f32; 3] {
        let (w, h) = (self.width as i32, self.height as i32);
        let (x0, y0) = (floor_i64(px) as i32, floor_i64(py) as i32);
        let (fx, fy) = (px - x0 as f32, py - y0 as f32);
        let cx = |x: i32| x.clamp(0, w - 1) as usize;
        let cy = |y: i32| y.clamp(0, h - 1) as usize;
        let (xa, xb, ya, yb) = (cx(x0), cx(x0 + 1), cy(y0), cy(y0 + 1));
        let row = self.width as usize;
        // The four texels' RGB (one bounds check each).
        let texel = |x: usize, y: usize| -> [u8; 3] {
            let o = (y * row + x) * 4;
            match self.rgba8.get(o..o + 3) {
                Some(&[r, g, b]) => [r, g, b],
                _ => [0; 3],
            }
        };
        let (t00, t10, t01, t11) = (texel(xa, ya), texel(xb, ya), texel(xa, yb), texel(xb, yb));
        let mut out = [0.0; 3];
        for c in 0..3 {
            let (a, b) = (lut[t00[c] as usize], lut[t10[c] as usize]);
            let (d, e) = (lut[t01[c] as usize], lut[t11[c] as usize]);
            let top = a + (b - a) * fx;
            let bottom = d + (e - d) * fx;
            out[c] = top + (bottom - top) * fy;
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mip_chain_of_a_checker_is_grey_in_linear_light() {
        // 4x4 checker of black and white: level 2 is the linear mean, 0.5, i.e. sRGB 188.
        let mut data = Vec::new();
        for y in 0..4 {
            for x in 0..4 {
                let v = if (x + y) % 2 == 0 { 255 } else { 0 };
                data.extend_from_slice(&[v, v, v, 255]);
            }
        }
        let t = CpuMipTexture::from_srgb8(4, 4, &data).unwrap();
        assert_eq!(t.level_count(), 3);
        let s = t.sample(0.5, 0.5, 2.0);
        assert!((s[0] - decode_lut()[188]).abs() < 1e-6, "{s:?}");
        // Level 0 at a texel centre is the texel.
        let s0 = t.sample(0.125, 0.125, 0.0);
        assert_eq!(s0[0], 1.0);
        // Repeat wrapping: u = 1.125 is u = 0.125.
        assert_eq!(t.sample(1.125, 0.125, 0.0), s0);
    }

    #[test]
    fn frame_sampler_is_bilinear_with_clamp() {
        let data = [0u8, 0, 0, 255, 255, 255, 255, 255];
        let f = FrameSampler::new(2, 1, &data).unwrap();
        let lut = decode_lut();
        assert_eq!(f.sample_linear(0.0, 0.0, lut)[0], 0.0);
        assert!((f.sample_linear(0.5, 0.0, lut)[0] - 0.5).abs() < 1e-6);
        assert_eq!(f.sample_linear(-3.0, 7.0, lut)[0], 0.0);
        assert_eq!(f.sample_linear(9.0, 0.0, lut)[0], 1.0);
        assert!(FrameSampler::new(3, 1, &data).is_err());
        assert!(CpuMipTexture::from_srgb8(0, 1, &[]).is_err());
        assert!(CpuMipTexture::from_srgb8(2, 2, &data).is_err());
    }
}
