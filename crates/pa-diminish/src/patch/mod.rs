//! Patch fill of the PixMix class (Herling and Broll): every pixel to fill copies the colour of
//! one known pixel of the frame, chosen by a nearest-neighbour field (NNF) `f` that minimises
//!
//! ```text
//! cost(p, s) = appearance(p, s) + spatial(p, s) + temporal(p, s)
//! appearance = mean over the (2r+1)^2 patch offsets v of |I(p + v) - I(s + v)|^2
//!              (target pixels that are hidden are left out)
//! spatial    = lambda / 4 * sum over the 4-neighbours n of p that are filled too of
//!              min(|s + (n - p) - f(n)|^2, tau)
//! temporal   = mu * |I(s) - prior(p)|^2          (where a prior colour exists)
//! surface    = kappa * ([L(p) != L(s)] + mean over v of [L(p + v) != L(s + v)])
//!              (where a surface map L is given)
//! ```
//!
//! The surface term keeps copies on their own surface: `L` labels every pixel with the surface
//! it shows (the table, the board's sheet, a tag: the pipeline projects them from the board
//! pose, [`PatchFill::surfaces`]), so the black of a tag is not copied into the white paper,
//! and a hole pixel near the sheet's edge prefers a source at the same place relative to an
//! edge of the same orientation: the edge is continued across the hole.
//!
//! The spatial term rewards neighbouring pixels that copy neighbouring source pixels: the
//! fill is made of coherent pieces of the surroundings, so straight structures (a sheet's
//! edge, a tag's border, wood grain) continue across the hole instead of being averaged away.
//!
//! The NNF is found coarse to fine over a pyramid (levels are added until the holes' box is
//! at most [`PatchParams::coarsest_px`]; a coarse pixel is a hole if any of its 2x2 children
//! is). The coarsest level starts greedily: its holes in onion order, from the known pixels
//! inwards, each matched against what is known or matched before it (candidates: its matched
//! neighbours' continuations, random sources, a random search around the best), so structure
//! entering the hole from its border is carried inwards; then PatchMatch sweeps
//! (propagation from the scan's previous neighbours, random search around the match,
//! alternating scan directions, a pixel's colour updated as soon as its match changes). Every
//! finer level starts from the coarser field, upsampled, and is swept again (in parallel over
//! chunks of holes when they are many, each chunk with its own seeded generator, from the
//! field as it was before the sweep). By default the finest level is not searched: its field
//! is the upsampled one, and its colours are the vote of the overlapping 3x3 matches
//! (`I(p) = mean over v of I(f(p + v) - v)`), which smooths the seams between copied pieces.
//!
//! The work is limited to the mask's bounding box grown by a margin (the sources are the known
//! pixels in it). The random search draws from seeded generators: the same input gives the
//! same output, bit for bit, whatever the number of threads.
//!
//! Temporal coherence: an optional prior (the previous frame's diminished background warped
//! into this frame by the table-plane homography, [`PatchPrior`]) is sampled on the finest
//! searched level and averaged down; it gives the coarsest start its context (the prior's
//! colour stands for a hole not matched yet) and adds the temporal term above, so the fill of
//! a background seen again follows the previous frame's instead of jumping between equally
//! good matches. It is a prior on colours, not the previous field: a static frame filled again
//! with its own result as prior is close to, not identical with, the first fill. Last, each
//! filled pixel with a prior colour is blended with it ([`PatchParams::temporal_blend`]): a
//! running average of what the fill gave the same table point over the frames.
//!
//! Cost: O(levels x sweeps x holes x candidates x patch area) on the bounding box; about half
//! of it is the finest level's bookkeeping (state, upsampling, vote), done in parallel.

mod pyramid;
mod search;
#[cfg(test)]
mod tests;

use crate::error::DiminishError;
use crate::plate::Homography;
use crate::ray_fill::{FILL, PASS};
use crate::types::{ImageRgba8, Mask, Rect};

use pyramid::{Level, HIDDEN, HOLE, KNOWN};
use rayon::prelude::*;

/// Tuning of the patch fill. [`PatchParams::default`] is what the pipeline uses.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PatchParams {
    /// Patch radius on the coarser levels (2: 5x5 patches).
    pub patch_radius: u32,
    /// Patch radius on the finest level (1: 3x3; the coarser levels have set the structure).
    pub fine_patch_radius: u32,
    /// Weight `lambda` of the spatial term (colour^2 units, per incoherent neighbour).
    pub spatial_weight: f32,
    /// Saturation `tau` of a neighbour's spatial cost (pixels^2).
    pub spatial_cap: f32,
    /// Weight `mu` of the temporal term.
    pub temporal_weight: f32,
    /// Weight `kappa` of the surface term (colour^2 units, summed over R, G, B: 100 000 is
    /// about a black-for-white difference, so a source on another surface loses against
    /// nearly any source on the same one; used with [`PatchFill::surfaces`] only).
    pub surface_weight: f32,
    /// Sources are searched in the mask's bounding box grown by this many pixels (at least;
    /// the margin also grows with the box: a quarter of its larger side).
    pub margin_px: u32,
    /// The pyramid stops when the coarsest level's hole box is at most this large (pixels,
    /// larger side).
    pub coarsest_px: u32,
    /// PatchMatch sweeps on the coarsest level, the intermediate levels and the finest level.
    pub sweeps: [u32; 3],
    /// First radius of the random search on the finest level (halved down to 1; 0: none).
    pub fine_search_px: u32,
    /// Radius of the final vote on the finest level (0: every hole keeps its match's
    /// colour; 1: the mean of the 3x3 overlapping matches' colours).
    pub vote_radius: u32,
    /// Seed of the random search.
    pub seed: u64,
    /// Temporal blend `beta` in [0, 1): a filled pixel with a prior colour takes
    /// `(1 - beta) * fill + beta * prior`, a running average of the fills of the same table
    /// point over the frames (0: the fill alone; about 3 frames' memory at the default 0.7).
    /// Measured with `eval` (revealed PSNR dB / flicker levels at 0, 0.3, 0.5, 0.7): Blender
    /// bust 25.11/6.74, 25.84/4.31, 26.25/2.99, 26.53/1.77; Blender CesiumMan 20.15/4.59,
    /// 20.49/3.54, 20.62/2.95, 20.62/2.39; generated `hard` 16.87/7.61, -, 17.07/4.14,
    /// 17.45/2.48.
    pub temporal_blend: f32,
}

impl Default for PatchParams {
    fn default() -> Self {
        Self {
            patch_radius: 2,
            fine_patch_radius: 1,
            spatial_weight: 400.0,
            spatial_cap: 1.0,
            temporal_weight: 1.0,
            surface_weight: 100_000.0,
            margin_px: 24,
            coarsest_px: 16,
            sweeps: [2, 1, 0],
            fine_search_px: 2,
            vote_radius: 1,
            seed: 0x5EED_F111,
            temporal_blend: 0.7,
        }
    }
}

impl PatchParams {
    fn check(&self) -> Result<(), DiminishError> {
        let bad = |name: &'static str, value: f64, reason: &'static str| {
            Err(DiminishError::InvalidParameter {
                name,
                value,
                reason,
            })
        };
        if self.patch_radius > 8 {
            return bad("patch_radius", f64::from(self.patch_radius), "at most 8");
        }
        if self.fine_patch_radius > 8 {
            return bad(
                "fine_patch_radius",
                f64::from(self.fine_patch_radius),
                "at most 8",
            );
        }
        for (name, v) in [
            ("spatial_weight", self.spatial_weight),
            ("spatial_cap", self.spatial_cap),
            ("temporal_weight", self.temporal_weight),
            ("surface_weight", self.surface_weight),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return bad(name, f64::from(v), "must be finite and >= 0");
            }
        }
        if !(self.temporal_blend >= 0.0 && self.temporal_blend < 1.0) {
            return bad(
                "temporal_blend",
                f64::from(self.temporal_blend),
                "must be in [0, 1)",
            );
        }
        if self.fine_search_px > 64 {
            return bad(
                "fine_search_px",
                f64::from(self.fine_search_px),
                "at most 64",
            );
        }
        if self.vote_radius > 8 {
            return bad("vote_radius", f64::from(self.vote_radius), "at most 8");
        }
        if self.coarsest_px < 4 {
            return bad("coarsest_px", f64::from(self.coarsest_px), "at least 4");
        }
        if self.sweeps.iter().any(|&s| s > 64) {
            let m = self.sweeps.iter().copied().max().unwrap_or(0);
            return bad("sweeps", f64::from(m), "at most 64 a level");
        }
        Ok(())
    }
}

/// The previous frame's result, to keep the fill steady over time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PatchPrior<'a> {
    /// The previous frame's diminished background (same size as the frame).
    pub image: &'a ImageRgba8,
    /// The previous frame's fill mask: pixels set to [`Mask::HIDDEN`] were not filled there
    /// (they still show the prop) and give no prior.
    pub mask: &'a Mask,
    /// Maps previous-frame pixel coordinates to current-frame pixel coordinates (the
    /// table-plane homography; identity for a still camera).
    pub current_from_previous: Homography,
}

/// Parameters of [`crate::FillMethod::Patch`].
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PatchFill<'a> {
    pub params: PatchParams,
    /// The previous frame's result, if any.
    pub prior: Option<PatchPrior<'a>>,
    /// A clean plate: where its sample is valid it is used (gain-matched, as
    /// [`crate::FillMethod::CleanPlate`]); the patch fill covers what it lacks.
    pub plate: Option<crate::plate::CleanPlate<'a>>,
    /// The surface each pixel shows (same size as the frame; any labels, e.g. 0 the table, 1
    /// the sheet, 2 a tag): a source on another surface than its target costs
    /// [`PatchParams::surface_weight`] (see the module docs). Labels are read in the hole too.
    pub surfaces: Option<&'a Mask>,
    /// Align the prior to the frame before using it, as a clean plate
    /// ([`crate::plate_align`]: the homography between two tracked poses is off by their
    /// errors); `None` (the default): use it as given.
    pub align_prior: Option<crate::plate_align::PlateAlign>,
}

impl<'a> PatchFill<'a> {
    /// Default parameters, no prior, no plate.
    pub fn new() -> Self {
        Self::default()
    }
}

/// Reusable buffers of the patch fill.
#[derive(Debug, Default, Clone)]
pub(crate) struct PatchScratch {
    levels: Vec<Level>,
    nnf: Vec<Vec<u32>>,
    votes: Vec<[f32; 3]>,
    next: Vec<u32>,
    /// The finest level's final colour of each hole.
    out: Vec<[u8; 3]>,
}

/// Fills the pixels of `frame` inside `bbox` whose entry in `to_fill` (local to `bbox`,
/// row-major) is [`FILL`], and clears those entries; [`PASS`] entries are neither read nor
/// written. Returns the number of pixels filled.
pub(crate) fn patch_fill_region(
    frame: &mut ImageRgba8,
    bbox: Rect,
    to_fill: &mut [u8],
    fill: &PatchFill<'_>,
    scratch: &mut PatchScratch,
) -> Result<usize, DiminishError> {
    let params = &fill.params;
    params.check()?;
    let (fw, fh) = frame.size();
    if let Some(prior) = &fill.prior {
        crate::types::ensure_same_size("prior image", (fw, fh), prior.image.size())?;
        crate::types::ensure_same_size("prior mask", (fw, fh), prior.mask.size())?;
    }
    if let Some(surfaces) = fill.surfaces {
        crate::types::ensure_same_size("surface map", (fw, fh), surfaces.size())?;
    }
    let to_do = to_fill.iter().filter(|&&v| v == FILL).count();
    if to_do == 0 {
        return Ok(0);
    }
    let margin = params.margin_px.max(bbox.width.max(bbox.height) / 4);
    let region = bbox.expand_clipped(margin, fw, fh);
    let no_boundary = DiminishError::NoBoundary {
        region: bbox,
        width: fw,
        height: fh,
    };
    let prior_from_current = match &fill.prior {
        Some(p) => Some(p.current_from_previous.inverse()?),
        None => None,
    };
    // First with the hidden pixels left out; if some pixels to fill are cut off from every
    // known pixel by hidden ones, again with the hidden pixels filled too.
    for hidden_as_hole in [false, true] {
        let state = |lx: usize, ly: usize| -> u8 {
            let x = region.x as usize + lx;
            let y = region.y as usize + ly;
            if !bbox.contains(x as u32, y as u32) {
                return KNOWN;
            }
            let bx = x - bbox.x as usize;
            let by = y - bbox.y as usize;
            match to_fill[by * bbox.width as usize + bx] {
                FILL => HOLE,
                PASS if hidden_as_hole => HOLE,
                PASS => HIDDEN,
                _ => KNOWN,
            }
        };
        pyramid::build(
            &mut scratch.levels,
            frame,
            region,
            state,
            fill.prior.as_ref().zip(prior_from_current.as_ref()),
            fill.surfaces,
            // The temporal term only matters on the levels that are searched.
            usize::from(params.sweeps[2] == 0),
            params.coarsest_px,
        );
        if scratch.levels[0].known == 0 {
            return Err(no_boundary);
        }
        let coarsest = scratch.levels.len() - 1;
        if !pyramid::onion_peel(&mut scratch.levels[coarsest]) {
            if hidden_as_hole {
                return Err(no_boundary);
            }
            continue;
        }
        search::solve(
            &mut scratch.levels,
            &mut scratch.nnf,
            &mut scratch.votes,
            &mut scratch.next,
            params,
        );
        // The finest level's colours, blended with the prior where it has one (sampled here,
        // hole by hole, unless the finest level is searched: then `build` sampled it), in
        // parallel; then written back.
        let blend = params.temporal_blend;
        let lv = &scratch.levels[0];
        let prior = fill.prior.as_ref().zip(prior_from_current.as_ref());
        let prior_at = |p: usize, x: usize, y: usize| -> Option<[f32; 3]> {
            if !lv.prior_ok.is_empty() {
                return lv.prior_ok[p].then(|| lv.prior[p]);
            }
            let (pr, hom) = prior?;
            pyramid::sample_prior(pr, hom, x as f64, y as f64)
        };
        let (rx, ry) = (region.x as usize, region.y as usize);
        scratch.out.clear();
        scratch.out.resize(lv.holes.len(), [0; 3]);
        scratch
            .out
            .par_chunks_mut(search::CHUNK)
            .zip(lv.holes.par_chunks(search::CHUNK))
            .for_each(|(out, holes)| {
                for (o, &p) in out.iter_mut().zip(holes) {
                    let p = p as usize;
                    let mut c = lv.color[p];
                    if blend > 0.0 {
                        if let Some(prior) = prior_at(p, rx + p % lv.w, ry + p / lv.w) {
                            for ch in 0..3 {
                                c[ch] += blend * (prior[ch] - c[ch]);
                            }
                        }
                    }
                    *o = c.map(|v| (v + 0.5).clamp(0.0, 255.0) as u8);
                }
            });
        let stride = fw as usize * 4;
        let data = frame.as_mut_slice();
        let bw = bbox.width as usize;
        let mut filled = 0usize;
        for (&p, c) in lv.holes.iter().zip(&scratch.out) {
            let p = p as usize;
            let (x, y) = (rx + p % lv.w, ry + p / lv.w);
            let li = (y - bbox.y as usize) * bw + (x - bbox.x as usize);
            if to_fill[li] != FILL {
                continue;
            }
            let i = y * stride + x * 4;
            data[i..i + 3].copy_from_slice(c);
            to_fill[li] = 0;
            filled += 1;
        }
        return Ok(filled);
    }
    Err(no_boundary)
}
