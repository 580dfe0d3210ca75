//! RGBA8 <-> Y'CbCr 4:2:0 / 4:2:2 conversion.
//!
//! Conventions:
//! * RGBA8 buffers are sRGB-encoded, row-major, `width * 4` bytes a row, no padding. Alpha is
//!   ignored on the way in and written as 255 on the way out.
//! * The matrix ([`YuvMatrix`]: BT.601 or BT.709) and range ([`YuvRange`]: limited 16-235 /
//!   16-240, or full 0-255) come from the stream's signalling. The transfer function is left
//!   alone: sRGB values are encoded as they are and tagged BT.709, as every camera and editor
//!   does for SDR video.
//! * Chroma is the mean of each 2x2 (4:2:0) or 2x1 (4:2:2) block on the way in and is
//!   upsampled bilinearly, centre-sited, on the way out (H.264's default siting is a quarter of
//!   a chroma sample to the left of that: invisible at the sizes we use, and consistent both
//!   ways).
//! * Integer arithmetic with 14-bit coefficients, rounded; results are clamped to 0..=255.

/// The Y'CbCr matrix coefficients (ITU-R BT.601 or BT.709).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum YuvMatrix {
    /// ITU-R BT.601 (SD video, JPEG, most webcams): Kr = 0.299, Kb = 0.114.
    Bt601,
    /// ITU-R BT.709 (HD video, phones): Kr = 0.2126, Kb = 0.0722.
    Bt709,
}

/// The quantisation range of Y'CbCr samples.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum YuvRange {
    /// "TV" range: Y' in 16..=235, Cb/Cr in 16..=240 (the norm for video).
    Limited,
    /// "PC" range: 0..=255 (JPEG, some phones' and screen recorders' output).
    Full,
}

/// Matrix and range of a Y'CbCr stream.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct YuvColor {
    /// Matrix coefficients.
    pub matrix: YuvMatrix,
    /// Sample range.
    pub range: YuvRange,
}

impl YuvColor {
    /// BT.709, limited range: what [`crate::Mp4Writer`] writes and signals.
    pub const BT709_LIMITED: YuvColor = YuvColor {
        matrix: YuvMatrix::Bt709,
        range: YuvRange::Limited,
    };
    /// BT.601, limited range: webcams' YUYV and SD video.
    pub const BT601_LIMITED: YuvColor = YuvColor {
        matrix: YuvMatrix::Bt601,
        range: YuvRange::Limited,
    };

    /// The colour to assume for a stream that does not signal one: BT.709 from 720 lines up,
    /// BT.601 below (what mpv and VLC assume), limited range.
    pub fn unspecified_default(height: u32) -> YuvColor {
        YuvColor {
            matrix: if height >= 720 {
                YuvMatrix::Bt709
            } else {
                YuvMatrix::Bt601
            },
            range: YuvRange::Limited,
        }
    }

    /// From H.264/HEVC VUI `matrix_coefficients` (ISO/IEC 23091-2) and `video_full_range_flag`;
    /// `None` for `matrix` means unspecified. Matrices other than 601/709 (BT.2020, ...) are
    /// approximated by BT.709.
    pub fn from_vui(matrix: Option<u8>, full_range: bool, height: u32) -> YuvColor {
        let matrix = match matrix {
            Some(1) => YuvMatrix::Bt709,
            Some(5) | Some(6) => YuvMatrix::Bt601,
            Some(0) | Some(2) | Some(3) | None => Self::unspecified_default(height).matrix,
            Some(_) => YuvMatrix::Bt709,
        };
        YuvColor {
            matrix,
            range: if full_range {
                YuvRange::Full
            } else {
                YuvRange::Limited
            },
        }
    }
}

const SHIFT: u32 = 14;
const ONE: f64 = (1u32 << SHIFT) as f64;

/// Fixed-point coefficients for RGB -> Y'CbCr.
struct Forward {
    y: [i32; 3],
    cb: [i32; 3],
    cr: [i32; 3],
    y_offset: i32,
}

impl Forward {
    fn new(color: YuvColor) -> Self {
        let (kr, kb) = kr_kb(color.matrix);
        let kg = 1.0 - kr - kb;
        let (ys, cs, yo) = match color.range {
            YuvRange::Limited => (219.0 / 255.0, 224.0 / 255.0, 16),
            YuvRange::Full => (1.0, 1.0, 0),
        };
        let r = |v: f64| (v * ONE).round() as i32;
        // Cb = cs * (B - Y') / (2 (1 - Kb)), Cr = cs * (R - Y') / (2 (1 - Kr)).
        let cbd = 2.0 * (1.0 - kb);
        let crd = 2.0 * (1.0 - kr);
        Forward {
            y: [r(ys * kr), r(ys * kg), r(ys * kb)],
            cb: [
                r(-cs * kr / cbd),
                r(-cs * kg / cbd),
                r(cs * (1.0 - kb) / cbd),
            ],
            cr: [
                r(cs * (1.0 - kr) / crd),
                r(-cs * kg / crd),
                r(-cs * kb / crd),
            ],
            y_offset: yo,
        }
    }
}

/// Fixed-point coefficients for Y'CbCr -> RGB.
struct Inverse {
    y_scale: i32,
    y_offset: i32,
    r_cr: i32,
    g_cb: i32,
    g_cr: i32,
    b_cb: i32,
}

impl Inverse {
    fn new(color: YuvColor) -> Self {
        let (kr, kb) = kr_kb(color.matrix);
        let kg = 1.0 - kr - kb;
        let (ys, cs, yo) = match color.range {
            YuvRange::Limited => (255.0 / 219.0, 255.0 / 224.0, 16),
            YuvRange::Full => (1.0, 1.0, 0),
        };
        let r = |v: f64| (v * ONE).round() as i32;
        Inverse {
            y_scale: r(ys),
            y_offset: yo,
            r_cr: r(cs * 2.0 * (1.0 - kr)),
            g_cb: r(cs * 2.0 * kb * (1.0 - kb) / kg),
            g_cr: r(cs * 2.0 * kr * (1.0 - kr) / kg),
            b_cb: r(cs * 2.0 * (1.0 - kb)),
        }
    }

    /// One pixel; `cb`/`cr` are centred (value - 128) and scaled by 16 (bilinear weights).
    #[inline(always)]
    fn pixel(&self, y: u8, cb16: i32, cr16: i32, out: &mut [u8]) {
        let yv = (i32::from(y) - self.y_offset) * self.y_scale;
        let round = 1 << (SHIFT - 1);
        // cb16/cr16 carry 4 extra bits.
        let r = yv + ((self.r_cr * cr16) >> 4) + round;
        let g = yv - ((self.g_cb * cb16 + self.g_cr * cr16) >> 4) + round;
        let b = yv + ((self.b_cb * cb16) >> 4) + round;
        out[0] = clamp_u8(r >> SHIFT);
        out[1] = clamp_u8(g >> SHIFT);
        out[2] = clamp_u8(b >> SHIFT);
        out[3] = 255;
    }
}

fn kr_kb(m: YuvMatrix) -> (f64, f64) {
    match m {
        YuvMatrix::Bt601 => (0.299, 0.114),
        YuvMatrix::Bt709 => (0.2126, 0.0722),
    }
}

#[inline(always)]
fn clamp_u8(v: i32) -> u8 {
    v.clamp(0, 255) as u8
}

/// A planar 4:2:0 picture (I420) with even dimensions, tightly packed.
#[derive(Debug, Clone, Default)]
pub struct I420 {
    /// Width in pixels (even).
    pub width: usize,
    /// Height in pixels (even).
    pub height: usize,
    /// Luma, `width * height`.
    pub y: Vec<u8>,
    /// Cb, `width/2 * height/2`.
    pub u: Vec<u8>,
    /// Cr, `width/2 * height/2`.
    pub v: Vec<u8>,
}

/// Converts an RGBA8 image of `width x height` (any size >= 1) into `dst`, padded to even
/// dimensions by repeating the last column and row.
///
/// The caller guarantees `rgba.len() == width * height * 4`.
pub fn rgba_to_i420(rgba: &[u8], width: usize, height: usize, color: YuvColor, dst: &mut I420) {
    let ew = width + (width & 1);
    let eh = height + (height & 1);
    dst.width = ew;
    dst.height = eh;
    dst.y.resize(ew * eh, 0);
    dst.u.resize(ew / 2 * eh / 2, 0);
    dst.v.resize(ew / 2 * eh / 2, 0);
    if width == 0 || height == 0 {
        return;
    }
    let f = Forward::new(color);
    let round = 1i32 << (SHIFT - 1);
    let round4 = 1i32 << (SHIFT + 1);
    let luma = |p: [i32; 3]| {
        clamp_u8(((f.y[0] * p[0] + f.y[1] * p[1] + f.y[2] * p[2] + round) >> SHIFT) + f.y_offset)
    };
    let cw = ew / 2;
    let last_x = width - 1;
    for by in 0..eh / 2 {
        // Source rows of this block row; the bottom pad row repeats the last row.
        let r0 = (2 * by).min(height - 1);
        let r1 = (2 * by + 1).min(height - 1);
        let src0 = &rgba[r0 * width * 4..(r0 + 1) * width * 4];
        let src1 = &rgba[r1 * width * 4..(r1 + 1) * width * 4];
        let (ya, yb) = dst.y[2 * by * ew..(2 * by + 2) * ew].split_at_mut(ew);
        let urow = &mut dst.u[by * cw..(by + 1) * cw];
        let vrow = &mut dst.v[by * cw..(by + 1) * cw];
        for bx in 0..cw {
            // The right pad column repeats the last column.
            let (x0, x1) = (2 * bx, (2 * bx + 1).min(last_x));
            let at = |row: &[u8], x: usize| {
                [
                    i32::from(row[x * 4]),
                    i32::from(row[x * 4 + 1]),
                    i32::from(row[x * 4 + 2]),
                ]
            };
            let (p00, p01, p10, p11) = (at(src0, x0), at(src0, x1), at(src1, x0), at(src1, x1));
            ya[2 * bx] = luma(p00);
            ya[2 * bx + 1] = luma(p01);
            yb[2 * bx] = luma(p10);
            yb[2 * bx + 1] = luma(p11);
            let sum = [
                p00[0] + p01[0] + p10[0] + p11[0],
                p00[1] + p01[1] + p10[1] + p11[1],
                p00[2] + p01[2] + p10[2] + p11[2],
            ];
            // Sums of 4 pixels: 2 more bits.
            let cb =
                (f.cb[0] * sum[0] + f.cb[1] * sum[1] + f.cb[2] * sum[2] + round4) >> (SHIFT + 2);
            let cr =
                (f.cr[0] * sum[0] + f.cr[1] * sum[1] + f.cr[2] * sum[2] + round4) >> (SHIFT + 2);
            urow[bx] = clamp_u8(cb + 128);
            vrow[bx] = clamp_u8(cr + 128);
        }
    }
}

/// Borrowed planes of a 4:2:0 picture with strides (as decoders hand them out).
#[derive(Debug, Clone, Copy)]
pub struct I420Planes<'a> {
    /// Luma plane.
    pub y: &'a [u8],
    /// Cb plane.
    pub u: &'a [u8],
    /// Cr plane.
    pub v: &'a [u8],
    /// Bytes per luma row.
    pub y_stride: usize,
    /// Bytes per chroma row (Cb and Cr).
    pub uv_stride: usize,
    /// Luma width in pixels.
    pub width: usize,
    /// Luma height in pixels.
    pub height: usize,
}

impl I420Planes<'_> {
    /// True when every row the conversion reads is inside the planes.
    pub fn is_consistent(&self) -> bool {
        let cw = self.width.div_ceil(2);
        let ch = self.height.div_ceil(2);
        self.width > 0
            && self.height > 0
            && self.y_stride >= self.width
            && self.uv_stride >= cw
            && self.y.len() >= self.y_stride * (self.height - 1) + self.width
            && self.u.len() >= self.uv_stride * (ch - 1) + cw
            && self.v.len() >= self.uv_stride * (ch - 1) + cw
    }
}

/// Converts a 4:2:0 picture into RGBA8, cropping to `crop = (left, top, width, height)` (in
/// luma pixels, within the picture). `out` is resized to `crop_w * crop_h * 4`.
///
/// Returns `false` (and writes nothing) when the planes are inconsistent or the crop does not
/// fit; decoders' outputs are checked with this rather than trusted.
pub fn i420_to_rgba(
    p: &I420Planes<'_>,
    crop: (usize, usize, usize, usize),
    color: YuvColor,
    out: &mut Vec<u8>,
) -> bool {
    let (cx, cy, cw, ch) = crop;
    if !p.is_consistent() || cw == 0 || ch == 0 || cx + cw > p.width || cy + ch > p.height {
        return false;
    }
    out.resize(cw * ch * 4, 0);
    let inv = Inverse::new(color);
    let chroma_w = p.width.div_ceil(2);
    let chroma_h = p.height.div_ceil(2);
    // Vertically blended chroma rows, x4 (weights 3/4 and 1/4), then horizontally blended to
    // full width, x16 and centred; then one branch-free pass over the pixels.
    let mut vu = vec![0i32; chroma_w];
    let mut vv = vec![0i32; chroma_w];
    let mut hu = vec![0i32; chroma_w * 2];
    let mut hv = vec![0i32; chroma_w * 2];
    for oy in 0..ch {
        let y = cy + oy;
        let j = y / 2;
        let jn = if y % 2 == 0 {
            j.saturating_sub(1)
        } else {
            (j + 1).min(chroma_h - 1)
        };
        let row = |r: usize| r * p.uv_stride..r * p.uv_stride + chroma_w;
        let (u0, u1) = (&p.u[row(j)], &p.u[row(jn)]);
        let (v0, v1) = (&p.v[row(j)], &p.v[row(jn)]);
        for (((d, &a), &b), (e, (&c, &f))) in vu
            .iter_mut()
            .zip(u0)
            .zip(u1)
            .zip(vv.iter_mut().zip(v0.iter().zip(v1)))
        {
            *d = 3 * i32::from(a) + i32::from(b);
            *e = 3 * i32::from(c) + i32::from(f);
        }
        for i in 0..chroma_w {
            let (l, r) = (i.saturating_sub(1), (i + 1).min(chroma_w - 1));
            hu[2 * i] = 3 * vu[i] + vu[l] - 128 * 16;
            hu[2 * i + 1] = 3 * vu[i] + vu[r] - 128 * 16;
            hv[2 * i] = 3 * vv[i] + vv[l] - 128 * 16;
            hv[2 * i + 1] = 3 * vv[i] + vv[r] - 128 * 16;
        }
        let yrow = &p.y[y * p.y_stride + cx..y * p.y_stride + cx + cw];
        let orow = &mut out[oy * cw * 4..(oy + 1) * cw * 4];
        for ((o, &luma), (&cb16, &cr16)) in orow
            .chunks_exact_mut(4)
            .zip(yrow)
            .zip(hu[cx..cx + cw].iter().zip(&hv[cx..cx + cw]))
        {
            inv.pixel(luma, cb16, cr16, o);
        }
    }
    true
}

/// Converts packed 4:2:2 YUYV (Y0 Cb Y1 Cr, as webcams deliver it) into RGBA8.
///
/// `stride` is bytes per source row (>= `width * 2`, `width` even or odd). Returns `false` when
/// `src` is too short for the picture.
pub fn yuyv_to_rgba(
    src: &[u8],
    width: usize,
    height: usize,
    stride: usize,
    color: YuvColor,
    out: &mut Vec<u8>,
) -> bool {
    let row_bytes = width.div_ceil(2) * 4;
    if width == 0
        || height == 0
        || stride < row_bytes
        || src.len() < stride * (height - 1) + row_bytes
    {
        return false;
    }
    out.resize(width * height * 4, 0);
    let inv = Inverse::new(color);
    let pairs = width.div_ceil(2);
    for y in 0..height {
        let row = &src[y * stride..y * stride + row_bytes];
        let orow = &mut out[y * width * 4..(y + 1) * width * 4];
        for x in 0..width {
            let pair = x / 2;
            let luma = row[pair * 4 + (x % 2) * 2];
            // Chroma sample `pair` sits at luma x = 2 pair + 0.5 (centre-sited); blend with the
            // neighbour pair on the pixel's side.
            let n = if x % 2 == 0 {
                pair.saturating_sub(1)
            } else {
                (pair + 1).min(pairs - 1)
            };
            let cb16 =
                4 * (3 * i32::from(row[pair * 4 + 1]) + i32::from(row[n * 4 + 1])) - 128 * 16;
            let cr16 =
                4 * (3 * i32::from(row[pair * 4 + 3]) + i32::from(row[n * 4 + 3])) - 128 * 16;
            inv.pixel(luma, cb16, cr16, &mut orow[x * 4..x * 4 + 4]);
        }
    }
    true
}

#[cfg(test)]
mod tests {
    use super::*;

    fn roundtrip_max_error(color: YuvColor) -> i32 {
        // Flat 2x2 blocks of every 17th colour: no chroma subsampling loss, only quantisation.
        let mut worst = 0;
        for r in (0..=255).step_by(17) {
            for g in (0..=255).step_by(17) {
                for b in (0..=255).step_by(17) {
                    let rgba: Vec<u8> = [r as u8, g as u8, b as u8, 255].repeat(4);
                    let mut yuv = I420::default();
                    rgba_to_i420(&rgba, 2, 2, color, &mut yuv);
                    let planes = I420Planes {
                        y: &yuv.y,
                        u: &yuv.u,
                        v: &yuv.v,
                        y_stride: 2,
                        uv_stride: 1,
                        width: 2,
                        height: 2,
                    };
                    let mut out = Vec::new();
                    assert!(i420_to_rgba(&planes, (0, 0, 2, 2), color, &mut out));
                    for (a, b) in rgba.iter().zip(&out) {
                        worst = worst.max((i32::from(*a) - i32::from(*b)).abs());
                    }
                }
            }
        }
        worst
    }

    #[test]
    fn flat_colours_round_trip_within_quantisation() {
        // Limited range loses about 1 code in 255/219 on luma and 255/224 on chroma.
        assert!(roundtrip_max_error(YuvColor::BT709_LIMITED) <= 3);
        assert!(roundtrip_max_error(YuvColor::BT601_LIMITED) <= 3);
        let full = YuvColor {
            matrix: YuvMatrix::Bt709,
            range: YuvRange::Full,
        };
        assert!(roundtrip_max_error(full) <= 2);
    }

    #[test]
    fn known_values_bt709_limited() {
        let mut yuv = I420::default();
        let white = [255u8, 255, 255, 255].repeat(4);
        rgba_to_i420(&white, 2, 2, YuvColor::BT709_LIMITED, &mut yuv);
        assert_eq!((yuv.y[0], yuv.u[0], yuv.v[0]), (235, 128, 128));
        let black = [0u8, 0, 0, 255].repeat(4);
        rgba_to_i420(&black, 2, 2, YuvColor::BT709_LIMITED, &mut yuv);
        assert_eq!((yuv.y[0], yuv.u[0], yuv.v[0]), (16, 128, 128));
        // BT.709 red: Y' = 16 + 219 * 0.2126 = 62.56, Cr = 128 + 112 = 240.
        let red = [255u8, 0, 0, 255].repeat(4);
        rgba_to_i420(&red, 2, 2, YuvColor::BT709_LIMITED, &mut yuv);
        assert_eq!((yuv.y[0], yuv.v[0]), (63, 240));
    }

    #[test]
    fn odd_sizes_pad_and_inconsistent_planes_are_refused() {
        let rgba = vec![200u8; 3 * 3 * 4];
        let mut yuv = I420::default();
        rgba_to_i420(&rgba, 3, 3, YuvColor::BT601_LIMITED, &mut yuv);
        assert_eq!(
            (yuv.width, yuv.height, yuv.y.len(), yuv.u.len()),
            (4, 4, 16, 4)
        );
        let planes = I420Planes {
            y: &yuv.y[..10],
            u: &yuv.u,
            v: &yuv.v,
            y_stride: 4,
            uv_stride: 2,
            width: 4,
            height: 4,
        };
        let mut out = Vec::new();
        assert!(!i420_to_rgba(
            &planes,
            (0, 0, 3, 3),
            YuvColor::BT601_LIMITED,
            &mut out
        ));
        assert!(!yuyv_to_rgba(
            &[0; 7],
            2,
            2,
            4,
            YuvColor::BT601_LIMITED,
            &mut out
        ));
    }

    #[test]
    fn yuyv_grey() {
        // Y = 126 (mid grey in limited range), neutral chroma.
        let src = [126u8, 128, 126, 128].repeat(2);
        let mut out = Vec::new();
        assert!(yuyv_to_rgba(
            &src,
            2,
            2,
            4,
            YuvColor::BT601_LIMITED,
            &mut out
        ));
        assert!(out
            .chunks(4)
            .all(|p| p[0] == p[1] && p[1] == p[2] && (127..=129).contains(&p[0])));
    }
}
