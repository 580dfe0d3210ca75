//! Clean-plate fill: the background seen without the prop, warped by the table-plane
//! homography, gain-matched to the current frame.
//!
//! For each masked pixel `p` (current frame, OpenCV pixel-centre convention), the plate
//! position is `q = plate_from_current * (p, 1)` (the inverse of `current_from_plate`); the
//! plate is sampled bilinearly at `q` (pixel centres at integer coordinates, so `q` must lie in
//! `[0, w-1] x [0, h-1]`). The plate was shot at another time, so exposure and white balance
//! differ: a per-channel gain (optionally plus offset) is fitted by least squares on a ring of
//! pixels just outside the mask (`ring_px` wide), where both the current frame and the warped
//! plate see the table, with one robust refit that drops outliers (prop shadows, moving
//! hands). By default the fit and the sampling run in linear light (`GainSpace::Linear`),
//! where an exposure change is a pure gain. Pixels whose plate sample falls outside the plate
//! are filled afterwards by the ray fill, which then also uses the plate-filled pixels.
//!
//! Cost: O(mask bbox) bilinear samples (a projective division and 4 gathers each) plus
//! O(ring) samples for the fit; the ring is found by a square dilation of the bbox grown by
//! `ring_px`.

use crate::error::DiminishError;
use crate::mask::{dilate_local, extract_into, DilateShape};
use crate::plate_align::{aligned_homography, AlignScratch, PlateAlign, PlateAlignment};
use crate::ray_fill::RayDirections;
use crate::types::{ImageRgba8, Mask, Rect};
use std::sync::OnceLock;

/// A 3x3 plane homography, row-major, acting on homogeneous pixel coordinates in the OpenCV
/// pixel-centre convention.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Homography {
    m: [f64; 9],
}

impl Homography {
    /// From a row-major 3x3 matrix (as OpenCV's `findHomography` prints it).
    pub const fn from_row_major(m: [f64; 9]) -> Self {
        Self { m }
    }

    /// From a glam matrix (glam stores columns; the conversion transposes).
    pub fn from_dmat3(m: glam::DMat3) -> Self {
        Self::from_row_major(m.transpose().to_cols_array())
    }

    /// The identity.
    pub const fn identity() -> Self {
        Self::from_row_major([1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0])
    }

    /// The row-major entries.
    pub const fn to_row_major(&self) -> [f64; 9] {
        self.m
    }

    /// As a glam matrix.
    pub fn to_dmat3(&self) -> glam::DMat3 {
        glam::DMat3::from_cols_array(&self.m).transpose()
    }

    /// Maps a point; `None` where the homogeneous coordinate vanishes (the horizon) or the
    /// result is not finite.
    pub fn apply(&self, p: [f64; 2]) -> Option<[f64; 2]> {
        let m = &self.m;
        let x = m[0] * p[0] + m[1] * p[1] + m[2];
        let y = m[3] * p[0] + m[4] * p[1] + m[5];
        let w = m[6] * p[0] + m[7] * p[1] + m[8];
        if w.abs() < 1e-12 {
            return None;
        }
        let out = [x / w, y / w];
        (out[0].is_finite() && out[1].is_finite()).then_some(out)
    }

    /// The inverse, scaled so that its entries have unit max-norm. Errors if an entry is not
    /// finite or the matrix is singular relative to its scale.
    pub fn inverse(&self) -> Result<Homography, DiminishError> {
        let m = &self.m;
        let det = m[0] * (m[4] * m[8] - m[5] * m[7]) - m[1] * (m[3] * m[8] - m[5] * m[6])
            + m[2] * (m[3] * m[7] - m[4] * m[6]);
        let scale = m.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        if !det.is_finite() || scale <= 0.0 || det.abs() <= 1e-12 * scale.powi(3) {
            return Err(DiminishError::SingularHomography { det });
        }
        let adj = [
            m[4] * m[8] - m[5] * m[7],
            m[2] * m[7] - m[1] * m[8],
            m[1] * m[5] - m[2] * m[4],
            m[5] * m[6] - m[3] * m[8],
            m[0] * m[8] - m[2] * m[6],
            m[2] * m[3] - m[0] * m[5],
            m[3] * m[7] - m[4] * m[6],
            m[1] * m[6] - m[0] * m[7],
            m[0] * m[4] - m[1] * m[3],
        ];
        let s = adj.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        let sign = if det < 0.0 { -1.0 } else { 1.0 };
        let mut out = [0.0; 9];
        for (o, a) in out.iter_mut().zip(adj) {
            *o = sign * a / s;
        }
        Ok(Homography::from_row_major(out))
    }
}

/// Which photometric model maps the warped plate onto the current frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum GainModel {
    /// Use the plate as is.
    None,
    /// `current = g_c * plate` per channel (exposure / white balance change).
    #[default]
    Gain,
    /// `current = g_c * plate + o_c` per channel (also absorbs flare and black level).
    GainOffset,
}

/// The colour space in which the plate is interpolated and the gain is fitted and applied.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum GainSpace {
    /// Linear light (sRGB decoded): an exposure change is a pure gain here.
    #[default]
    Linear,
    /// The encoded sRGB values, scaled to `[0, 1]`.
    Encoded,
}

/// Parameters of the clean-plate fill.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CleanPlate<'a> {
    /// The background without the prop, from a reference view (RGBA8 sRGB).
    pub plate: &'a ImageRgba8,
    /// Maps plate pixel coordinates to current-frame pixel coordinates (table plane).
    pub current_from_plate: Homography,
    pub gain: GainModel,
    pub gain_space: GainSpace,
    /// Width in pixels of the ring just outside the mask used to fit the gain.
    pub ring_px: u32,
    /// Ray fill for pixels whose plate sample falls outside the plate.
    pub fallback: RayDirections,
    /// Correct the homography's residual misalignment on the pixels around the mask before
    /// sampling ([`crate::plate_align`]; `None`: use it as given).
    pub align: Option<PlateAlign>,
}

impl<'a> CleanPlate<'a> {
    /// Defaults: per-channel gain in linear light, a 4-pixel ring, 8-ray fallback, the
    /// plate aligned to the frame ([`PlateAlign::default`]).
    pub fn new(plate: &'a ImageRgba8, current_from_plate: Homography) -> Self {
        Self {
            plate,
            current_from_plate,
            gain: GainModel::Gain,
            gain_space: GainSpace::Linear,
            ring_px: 4,
            fallback: RayDirections::Eight,
            align: Some(PlateAlign::default()),
        }
    }
}

/// The fitted photometric correction, `current = gain * plate + offset` per R, G, B in the
/// working space scaled to `[0, 1]`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GainEstimate {
    pub gain: [f32; 3],
    pub offset: [f32; 3],
    /// Ring pixels with a valid plate sample.
    pub samples: usize,
    /// Samples kept by the robust refit (all of them when too few for a fit).
    pub inliers: usize,
}

impl GainEstimate {
    const IDENTITY: GainEstimate = GainEstimate {
        gain: [1.0; 3],
        offset: [0.0; 3],
        samples: 0,
        inliers: 0,
    };
}

pub(crate) fn decode_lut() -> &'static [f32; 256] {
    static LUT: OnceLock<[f32; 256]> = OnceLock::new();
    LUT.get_or_init(|| {
        let mut t = [0.0f32; 256];
        for (i, v) in t.iter_mut().enumerate() {
            let c = i as f64 / 255.0;
            let l = if c <= 0.04045 {
                c / 12.92
            } else {
                ((c + 0.055) / 1.055).powf(2.4)
            };
            *v = l as f32;
        }
        t
    })
}

const ENC_N: usize = 4096;

fn encode_lut() -> &'static [f32] {
    static LUT: OnceLock<Vec<f32>> = OnceLock::new();
    LUT.get_or_init(|| {
        (0..=ENC_N)
            .map(|i| {
                let l = i as f64 / ENC_N as f64;
                let c = if l <= 0.003_130_8 {
                    12.92 * l
                } else {
                    1.055 * l.powf(1.0 / 2.4) - 0.055
                };
                (c * 255.0) as f32
            })
            .collect()
    })
}

/// Linear light in [0, 1] (clamped) to an sRGB byte, through the encoding table.
pub(crate) fn encode_linear(v: f32) -> u8 {
    let lut = encode_lut();
    let t = v.clamp(0.0, 1.0) * ENC_N as f32;
    let i = (t as usize).min(ENC_N - 1);
    let f = t - i as f32;
    (lut[i] + (lut[i + 1] - lut[i]) * f + 0.5).clamp(0.0, 255.0) as u8
}

pub(crate) struct Space {
    dec: [f32; 256],
    enc: Option<&'static [f32]>,
}

impl Space {
    pub(crate) fn new(space: GainSpace) -> Self {
        match space {
            GainSpace::Linear => Space {
                dec: *decode_lut(),
                enc: Some(encode_lut()),
            },
            GainSpace::Encoded => {
                let mut dec = [0.0f32; 256];
                for (i, d) in dec.iter_mut().enumerate() {
                    *d = i as f32 / 255.0;
                }
                Space { dec, enc: None }
            }
        }
    }

    #[inline]
    fn encode(&self, v: f32) -> u8 {
        let v = v.clamp(0.0, 1.0);
        match self.enc {
            None => (v * 255.0 + 0.5) as u8,
            Some(lut) => {
                let t = v * ENC_N as f32;
                let i = (t as usize).min(ENC_N - 1);
                let f = t - i as f32;
                let e = lut[i] + (lut[i + 1] - lut[i]) * f;
                (e + 0.5).clamp(0.0, 255.0) as u8
            }
        }
    }
}

/// Bilinear plate sample in the working space, `None` outside `[0, w-1] x [0, h-1]`.
#[inline]
pub(crate) fn sample(plate: &ImageRgba8, space: &Space, q: [f64; 2]) -> Option<[f32; 3]> {
    let (w, h) = plate.size();
    let (qx, qy) = (q[0], q[1]);
    if !(qx >= 0.0 && qy >= 0.0 && qx <= f64::from(w - 1) && qy <= f64::from(h - 1)) {
        return None;
    }
    let x0 = qx.floor() as usize;
    let y0 = qy.floor() as usize;
    let fx = (qx - x0 as f64) as f32;
    let fy = (qy - y0 as f64) as f32;
    let x1 = (x0 + 1).min(w as usize - 1);
    let y1 = (y0 + 1).min(h as usize - 1);
    let d = plate.as_slice();
    let stride = w as usize * 4;
    let (a, b) = (y0 * stride + x0 * 4, y0 * stride + x1 * 4);
    let (c, e) = (y1 * stride + x0 * 4, y1 * stride + x1 * 4);
    let mut out = [0.0f32; 3];
    for (ch, o) in out.iter_mut().enumerate() {
        let top = space.dec[d[a + ch] as usize] * (1.0 - fx) + space.dec[d[b + ch] as usize] * fx;
        let bot = space.dec[d[c + ch] as usize] * (1.0 - fx) + space.dec[d[e + ch] as usize] * fx;
        *o = top * (1.0 - fy) + bot * fy;
    }
    Some(out)
}

/// Reusable buffers of the plate fill.
#[derive(Debug, Default, Clone)]
pub(crate) struct PlateScratch {
    ring: Vec<u8>,
    inside: Vec<u8>,
    samples: Vec<[f32; 6]>,
    residuals: Vec<f32>,
    align: AlignScratch,
}

/// Fits the gain on the ring around the mask inside `bbox` (tight bbox of the mask).
fn estimate_gain(
    frame: &ImageRgba8,
    mask: &Mask,
    bbox: Rect,
    cp: &CleanPlate<'_>,
    plate_from_current: &Homography,
    space: &Space,
    scratch: &mut PlateScratch,
) -> GainEstimate {
    if cp.gain == GainModel::None || cp.ring_px == 0 {
        return GainEstimate::IDENTITY;
    }
    let (fw, fh) = frame.size();
    let ring_region = bbox.expand_clipped(cp.ring_px, fw, fh);
    extract_into(mask, ring_region, &mut scratch.ring);
    let rw = ring_region.width as usize;
    scratch.inside.clear();
    scratch.inside.extend_from_slice(&scratch.ring);
    dilate_local(
        &mut scratch.ring,
        rw,
        ring_region.height as usize,
        cp.ring_px,
        DilateShape::Square,
    );
    scratch.samples.clear();
    let stride = fw as usize * 4;
    let data = frame.as_slice();
    for (li, (&dil, &o)) in scratch.ring.iter().zip(&scratch.inside).enumerate() {
        if dil == 0 || o != 0 {
            continue;
        }
        let x = ring_region.x as usize + li % rw;
        let y = ring_region.y as usize + li / rw;
        let Some(q) = plate_from_current.apply([x as f64, y as f64]) else {
            continue;
        };
        let Some(p) = sample(cp.plate, space, q) else {
            continue;
        };
        let i = y * stride + x * 4;
        let c = [
            space.dec[data[i] as usize],
            space.dec[data[i + 1] as usize],
            space.dec[data[i + 2] as usize],
        ];
        scratch.samples.push([p[0], p[1], p[2], c[0], c[1], c[2]]);
    }
    let n = scratch.samples.len();
    if n < 8 {
        log::debug!("clean plate: only {n} ring samples, gain left at 1");
        return GainEstimate {
            samples: n,
            inliers: n,
            ..GainEstimate::IDENTITY
        };
    }
    let all = vec![true; n];
    let first = fit(&scratch.samples, &all, cp.gain);
    // Robust refit: drop samples whose residual exceeds 3 robust sigmas (and 3 levels).
    scratch.residuals.clear();
    scratch
        .residuals
        .extend(scratch.samples.iter().map(|s| residual(s, &first)));
    let mut sorted = scratch.residuals.clone();
    let mid = n / 2;
    sorted.select_nth_unstable_by(mid, f32::total_cmp);
    let med = sorted[mid];
    let thresh = (3.0 * 1.4826 * med).max(3.0 / 255.0);
    let keep: Vec<bool> = scratch.residuals.iter().map(|&r| r <= thresh).collect();
    let inliers = keep.iter().filter(|&&k| k).count();
    let est = if inliers >= 8 {
        fit(&scratch.samples, &keep, cp.gain)
    } else {
        first
    };
    GainEstimate {
        samples: n,
        inliers: if inliers >= 8 { inliers } else { n },
        ..est
    }
}

fn residual(s: &[f32; 6], g: &GainEstimate) -> f32 {
    (0..3)
        .map(|c| (s[3 + c] - (g.gain[c] * s[c] + g.offset[c])).abs())
        .sum::<f32>()
        / 3.0
}

fn fit(samples: &[[f32; 6]], keep: &[bool], model: GainModel) -> GainEstimate {
    let mut out = GainEstimate::IDENTITY;
    for c in 0..3 {
        let (mut n, mut sp, mut sc, mut spp, mut spc) = (0.0f64, 0.0, 0.0, 0.0, 0.0);
        for (s, _) in samples.iter().zip(keep).filter(|(_, &k)| k) {
            let (p, q) = (f64::from(s[c]), f64::from(s[3 + c]));
            n += 1.0;
            sp += p;
            sc += q;
            spp += p * p;
            spc += p * q;
        }
        let (mut g, mut o) = (1.0f64, 0.0f64);
        let var = spp - sp * sp / n.max(1.0);
        if model == GainModel::GainOffset && var > 1e-6 * n {
            g = (spc - sp * sc / n) / var;
            o = (sc - g * sp) / n;
        } else if spp > 1e-12 {
            g = spc / spp;
        }
        if !g.is_finite() || !o.is_finite() {
            (g, o) = (1.0, 0.0);
        }
        out.gain[c] = g.clamp(0.2, 5.0) as f32;
        out.offset[c] = o.clamp(-1.0, 1.0) as f32;
    }
    out
}

/// Fills from the plate every set pixel of `to_fill` (local to `region`) whose plate sample is
/// valid, clearing it. Returns (pixels filled, gain estimate, the alignment when asked for).
pub(crate) fn plate_fill_region(
    frame: &mut ImageRgba8,
    mask: &Mask,
    region: Rect,
    to_fill: &mut [u8],
    cp: &CleanPlate<'_>,
    scratch: &mut PlateScratch,
) -> Result<(usize, GainEstimate, Option<PlateAlignment>), DiminishError> {
    let (current_from_plate, alignment) = aligned_homography(
        frame,
        mask,
        region,
        cp.plate,
        cp.current_from_plate,
        cp.align.as_ref(),
        &mut scratch.align,
    )?;
    let aligned = CleanPlate {
        current_from_plate,
        ..*cp
    };
    let cp = &aligned;
    let plate_from_current = cp.current_from_plate.inverse()?;
    let space = Space::new(cp.gain_space);
    let est = estimate_gain(
        frame,
        mask,
        region,
        cp,
        &plate_from_current,
        &space,
        scratch,
    );
    let (fw, _) = frame.size();
    let stride = fw as usize * 4;
    let rw = region.width as usize;
    let mut filled = 0usize;
    let data = frame.as_mut_slice();
    for (ly, row) in to_fill.chunks_exact_mut(rw).enumerate() {
        let y = region.y as usize + ly;
        for (lx, t) in row.iter_mut().enumerate() {
            if *t != crate::ray_fill::FILL {
                continue;
            }
            let x = region.x as usize + lx;
            let Some(q) = plate_from_current.apply([x as f64, y as f64]) else {
                continue;
            };
            let Some(p) = sample(cp.plate, &space, q) else {
                continue;
            };
            let i = y * stride + x * 4;
            for c in 0..3 {
                data[i + c] = space.encode(est.gain[c] * p[c] + est.offset[c]);
            }
            *t = 0;
            filled += 1;
        }
    }
    Ok((filled, est, alignment))
}
