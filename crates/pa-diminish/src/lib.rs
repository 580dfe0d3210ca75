//! Diminished reality for Props Alive: hide the real prop where the animated twin no longer
//! covers it, by replacing it with (an estimate of) the background.
//!
//! # Data
//! Frames are [`ImageRgba8`] (sRGB, row-major, no padding); fills write R, G, B and keep
//! alpha. The region to fill is a [`Mask`] (`0` = keep, non-zero = fill; this crate writes
//! `0`/`255`), typically the key-pose silhouette from the renderer's depth
//! ([`mask_from_depth`]) dilated by a few pixels ([`dilate`]) to cover anti-aliasing, shadows
//! at the contact and tracking jitter. Functions write into caller-owned buffers; the
//! [`Diminisher`] keeps its scratch buffers between frames so a steady-state fill allocates
//! nothing. Every fill only reads boundary pixels that are inside the image, so masks that
//! touch the border work.
//!
//! # Methods ([`FillMethod`]) and their cost (N x M = the mask's bounding box)
//! * [`FillMethod::PaperRectangle`] - the paper's baseline (sections 3.3 and 4.3): the whole
//!   screen-space rectangle, each pixel the mean of the 4 pixels just outside it on its row
//!   and column (sides outside the image are dropped). O(N x M), the cheapest; exact for a
//!   constant background, blurry cross-shaped streaks on texture, and it also overwrites the
//!   background that was visible inside the rectangle. See [`rect_fill`].
//! * [`FillMethod::Rays`] - tight-mask fill by inverse-distance interpolation of the nearest
//!   known pixel along 8 or 16 rays; reproduces linear ramps exactly; O(N x M x rays) with one
//!   raster pass a direction. See [`ray_fill`].
//! * [`FillMethod::CleanPlate`] - the background seen without the prop, warped into the
//!   current view by the table-plane homography, aligned to the frame on a band around the
//!   mask ([`plate_align`]: the homography of two tracked poses is off by their errors),
//!   bilinearly sampled and gain-matched on a ring around the mask; correct texture, not just
//!   a smooth guess. Pixels the plate does not cover fall back to the ray fill. O(N x M)
//!   samples + O(ring + band). See [`plate`].
//! * [`FillMethod::Patch`] - PixMix-class patch fill: every pixel copies one known pixel,
//!   chosen by a nearest-neighbour field with an appearance and a spatial-coherence cost,
//!   coarse to fine, so straight structures continue across the hole; optionally seeded by
//!   the previous frame's result warped into this frame (steady over time) and preferring a
//!   clean plate where one is given. O(N x M x patch area x candidates). See [`patch`].
//!
//! # Shadows ([`shadow`])
//! A cast shadow on the table is a soft matte ([`ShadowMatte`]: pixel-space triangles from
//! the caller, blurred by a Gaussian) and one darkening ratio per channel (shadowed / lit,
//! linear light), measured by medians or across the matte's outline; [`lift_shadow`] divides
//! it out of a plate, [`cast_shadow`] lays it onto one. No meshes here: the pipeline projects
//! the prop along the light and hands the triangles in.
//!
//! Run `cargo run --release -p pa-diminish --example fill_timing` for the timings.

pub mod cover;
pub mod error;
pub mod mask;
pub mod metrics;
pub mod patch;
pub mod plate;
pub mod plate_align;
pub mod ray_fill;
pub mod rect_fill;
pub mod shadow;
pub mod temporal;
pub mod types;

pub use cover::{
    fit_shading, paste_cover, CoverImage, CoverStats, Paper, SheetCoords, SheetShading,
};
pub use error::DiminishError;
pub use mask::{dilate, dilate_in_bbox, dilate_in_place, mask_from_depth, DilateShape};
pub use metrics::{mse_rgb, psnr_rgb};
pub use patch::{PatchFill, PatchParams, PatchPrior};
pub use plate::{CleanPlate, GainEstimate, GainModel, GainSpace, Homography};
pub use plate_align::{PlateAlign, PlateAlignment};
pub use ray_fill::RayDirections;
pub use rect_fill::{baseline_rect, paper_rectangle_fill};
pub use shadow::{cast_shadow, lift_shadow, measure_shadow, ShadowMatte, ShadowRatio};
pub use temporal::blend_with_prior;
pub use types::{ImageRgba8, Mask, Rect};

use types::ensure_same_size;

/// How to fill the masked region.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum FillMethod<'a> {
    /// The paper's baseline over a rectangle: the given one (clipped to the frame; the mask
    /// is then not used), or the bounding box of the mask.
    PaperRectangle { rect: Option<Rect> },
    /// Inverse-distance ray fill over the mask only.
    Rays(RayDirections),
    /// Clean plate warped by a homography, gain-matched, with a ray-fill fallback.
    CleanPlate(CleanPlate<'a>),
    /// Patch fill (PixMix class), with an optional previous-frame prior and clean plate.
    Patch(PatchFill<'a>),
}

impl Default for FillMethod<'_> {
    fn default() -> Self {
        FillMethod::Rays(RayDirections::default())
    }
}

/// What a fill did.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct FillStats {
    /// Pixels written.
    pub filled: usize,
    /// The region worked on: the rectangle for the baseline, the mask's bounding box otherwise;
    /// `None` when nothing was to be done.
    pub bbox: Option<Rect>,
    /// Pixels taken from the clean plate.
    pub from_plate: usize,
    /// Pixels interpolated by the ray fill (all of them for `Rays`, the fallback for
    /// `CleanPlate`).
    pub interpolated: usize,
    /// Pixels copied by the patch fill (`Patch`).
    pub patched: usize,
    /// The photometric correction used by `CleanPlate` (and `Patch` with a plate).
    pub gain: Option<GainEstimate>,
    /// What the plate's alignment found (`CleanPlate` and `Patch` with a plate, when
    /// [`CleanPlate::align`] is set and the band around the mask had something to compare).
    pub plate_alignment: Option<PlateAlignment>,
    /// What the alignment of the patch fill's prior found ([`PatchFill::align_prior`]).
    pub prior_alignment: Option<PlateAlignment>,
}

/// A fill engine that keeps its scratch buffers between frames.
#[derive(Debug, Default, Clone)]
pub struct Diminisher {
    to_fill: Vec<u8>,
    rays: ray_fill::RayScratch,
    plate: plate::PlateScratch,
    patch: patch::PatchScratch,
    align: plate_align::AlignScratch,
}

impl Diminisher {
    pub fn new() -> Self {
        Self::default()
    }

    /// Fills the set pixels of `mask` in `frame` (in place). An empty mask is a no-op.
    /// Finds the mask's bounding box with one scan of the mask (O(frame) byte compares); use
    /// [`Diminisher::fill_in_bbox`] when the box is known.
    pub fn fill(
        &mut self,
        frame: &mut ImageRgba8,
        mask: &Mask,
        method: &FillMethod<'_>,
    ) -> Result<FillStats, DiminishError> {
        ensure_same_size("mask", frame.size(), mask.size())?;
        if let FillMethod::PaperRectangle { rect: Some(r) } = method {
            return self.fill_in_bbox(frame, mask, *r, method);
        }
        match mask.bounding_box() {
            None => Ok(FillStats::default()),
            Some(bbox) => self.fill_in_bbox(frame, mask, bbox, method),
        }
    }

    /// Like [`Diminisher::fill`], but only mask pixels inside `bbox` are considered (it is
    /// tightened to the set pixels inside it). All work is O(bbox area).
    pub fn fill_in_bbox(
        &mut self,
        frame: &mut ImageRgba8,
        mask: &Mask,
        bbox: Rect,
        method: &FillMethod<'_>,
    ) -> Result<FillStats, DiminishError> {
        self.fill_in_bbox_on(frame, mask, bbox, method, None)
    }

    /// [`Diminisher::fill_in_bbox`] on a set whose surfaces are known: `surfaces` gives each
    /// frame pixel a label (valid within 2 pixels of `bbox`; a mask of another size is not
    /// used), and the ray fill ([`FillMethod::Rays`], and the clean plate's fallback) takes
    /// each pixel's colour from rays that reach its own surface
    /// ([`ray_fill::OTHER_SURFACE_WEIGHT`]).
    pub fn fill_in_bbox_on(
        &mut self,
        frame: &mut ImageRgba8,
        mask: &Mask,
        bbox: Rect,
        method: &FillMethod<'_>,
        surfaces: Option<&Mask>,
    ) -> Result<FillStats, DiminishError> {
        ensure_same_size("mask", frame.size(), mask.size())?;
        let (w, h) = frame.size();
        if let FillMethod::PaperRectangle { rect: Some(r) } = method {
            let filled = paper_rectangle_fill(frame, *r)?;
            return Ok(FillStats {
                filled,
                bbox: r.clip(w, h),
                ..FillStats::default()
            });
        }
        let Some(bbox) = mask.bounding_box_in(bbox) else {
            return Ok(FillStats::default());
        };
        match method {
            FillMethod::PaperRectangle { .. } => {
                let filled = paper_rectangle_fill(frame, bbox)?;
                Ok(FillStats {
                    filled,
                    bbox: Some(bbox),
                    ..FillStats::default()
                })
            }
            FillMethod::Rays(dirs) => {
                mask::extract_into(mask, bbox, &mut self.to_fill);
                let n = ray_fill::ray_fill_region(
                    frame,
                    bbox,
                    &mut self.to_fill,
                    *dirs,
                    surfaces,
                    &mut self.rays,
                )?;
                Ok(FillStats {
                    filled: n,
                    bbox: Some(bbox),
                    interpolated: n,
                    ..FillStats::default()
                })
            }
            FillMethod::CleanPlate(cp) => {
                mask::extract_into(mask, bbox, &mut self.to_fill);
                let (from_plate, gain, plate_alignment) = plate::plate_fill_region(
                    frame,
                    mask,
                    bbox,
                    &mut self.to_fill,
                    cp,
                    &mut self.plate,
                )?;
                let interpolated = if self.to_fill.contains(&ray_fill::FILL) {
                    ray_fill::ray_fill_region(
                        frame,
                        bbox,
                        &mut self.to_fill,
                        cp.fallback,
                        surfaces,
                        &mut self.rays,
                    )?
                } else {
                    0
                };
                Ok(FillStats {
                    filled: from_plate + interpolated,
                    bbox: Some(bbox),
                    from_plate,
                    interpolated,
                    gain: Some(gain),
                    plate_alignment,
                    ..FillStats::default()
                })
            }
            FillMethod::Patch(pf) => {
                mask::extract_into(mask, bbox, &mut self.to_fill);
                let (from_plate, gain, plate_alignment) = match &pf.plate {
                    Some(cp) => {
                        let (n, g, a) = plate::plate_fill_region(
                            frame,
                            mask,
                            bbox,
                            &mut self.to_fill,
                            cp,
                            &mut self.plate,
                        )?;
                        (n, Some(g), a)
                    }
                    None => (0, None, None),
                };
                // The previous frame's result, aligned to this frame like a plate.
                let (prior, prior_alignment) = match (pf.prior, &pf.align_prior) {
                    (Some(p), Some(params)) => {
                        let (current_from_previous, a) = plate_align::aligned_homography(
                            frame,
                            mask,
                            bbox,
                            p.image,
                            p.current_from_previous,
                            Some(params),
                            &mut self.align,
                        )?;
                        let prior = PatchPrior {
                            current_from_previous,
                            ..p
                        };
                        (Some(prior), a)
                    }
                    (prior, _) => (prior, None),
                };
                let aligned = PatchFill { prior, ..*pf };
                let patched = patch::patch_fill_region(
                    frame,
                    bbox,
                    &mut self.to_fill,
                    &aligned,
                    &mut self.patch,
                )?;
                Ok(FillStats {
                    filled: from_plate + patched,
                    bbox: Some(bbox),
                    from_plate,
                    patched,
                    gain,
                    plate_alignment,
                    prior_alignment,
                    ..FillStats::default()
                })
            }
        }
    }
}

/// One-shot fill with fresh scratch buffers; see [`Diminisher::fill`].
pub fn fill(
    frame: &mut ImageRgba8,
    mask: &Mask,
    method: &FillMethod<'_>,
) -> Result<FillStats, DiminishError> {
    Diminisher::new().fill(frame, mask, method)
}
