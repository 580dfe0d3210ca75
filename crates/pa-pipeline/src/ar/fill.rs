//! The diminish stage's wiring: the fill mask from the key-pose silhouette (dilated, minus the
//! twin's opaque interior), the fill method of the settings, and the clean plate's homography.

use glam::{DMat3, DVec3, Mat4};
use pa_camera::CameraModel;
use pa_diminish::{
    dilate_in_bbox, CleanPlate, DilateShape, FillMethod, Homography, ImageRgba8, Mask, PatchFill,
    PatchParams, PatchPrior, PlateAlign, RayDirections, Rect,
};

use super::surfaces::PaintTags;
use super::texture::{Bbox, Textured};
use super::{ArError, ArPipeline, Fill, FrameView};

impl ArPipeline {
    /// Diminish: fills the dilated key silhouette in a copy of the frame. The fill mask is
    /// kept between frames; only the region written last time is cleared.
    pub(super) fn diminish(
        &mut self,
        view: &FrameView<'_>,
        textured: &Textured,
    ) -> Result<ImageRgba8, ArError> {
        let FrameView {
            rgba8,
            width,
            height,
            camera_model,
            camera_from_marker,
            ..
        } = *view;
        let Textured {
            key_mask,
            key_bbox,
            twin_mask,
            twin_bbox,
            ..
        } = textured;
        let (key_bbox, twin_bbox) = (*key_bbox, *twin_bbox);
        let mut background = ImageRgba8::new(width, height, self.copy_of(rgba8))?;
        let fill_mask = match &mut self.fill_mask {
            Some((m, last)) if m.size() == (width, height) => {
                if let Some(r) = last.take() {
                    clear_rect(m, r);
                }
                m
            }
            slot => &mut slot.insert((Mask::zeros(width, height)?, None)).0,
        };
        let mut fill_region = None;
        if let Some((x0, y0, x1, y1)) = key_bbox {
            let w = width as usize;
            let data = fill_mask.as_mut_slice();
            for y in y0..=y1 {
                for i in y * w + x0..=y * w + x1 {
                    data[i] = if key_mask[i] { Mask::SET } else { 0 };
                }
            }
            let bbox = Rect::from_inclusive(x0 as u32, y0 as u32, x1 as u32, y1 as u32);
            fill_region = Some(if self.settings.dilate_px > 0 {
                dilate_in_bbox(fill_mask, bbox, self.settings.dilate_px, DilateShape::Disc)
            } else {
                bbox
            });
        }
        // Where the twin's interior will cover the frame opaquely the real prop needs no
        // removal: those pixels are hidden from the fill (rays pass through them, so every
        // other pixel is filled exactly as before).
        // (Not when the plate is kept as a pass: it must be clean everywhere.)
        if let (Some(tb), Some(_), false) = (twin_bbox, fill_region, self.keep_passes) {
            hide_twin_interior(fill_mask, twin_mask, tb, COMPOSITE_REACH_PX);
        }
        if let Some((_, last)) = &mut self.fill_mask {
            *last = fill_region;
        }
        let fill_mask = match &self.fill_mask {
            Some((m, _)) => m,
            None => return Err(ArError::FillMaskMissing),
        };
        let plate_h = match (&self.plate, self.settings.fill) {
            (Some((_, plate_pose)), Fill::CleanPlate | Fill::Patch { plate: true }) => {
                Some(Homography::from_dmat3(plane_homography(
                    &camera_model,
                    camera_from_marker,
                    *plate_pose,
                )))
            }
            _ => None,
        };
        if let Fill::Patch { .. } = self.settings.fill {
            return self.patch_fill(view, background, fill_region, plate_h);
        }
        let method = match self.settings.fill {
            Fill::PaperRectangle => Some(FillMethod::PaperRectangle { rect: None }),
            Fill::Rays => Some(FillMethod::Rays(RayDirections::default())),
            Fill::CleanPlate => match (&self.plate, plate_h) {
                (Some((plate, _)), Some(h)) => Some(FillMethod::CleanPlate(clean_plate(
                    plate,
                    h,
                    self.settings.align_plate,
                ))),
                _ => Some(FillMethod::Rays(RayDirections::default())),
            },
            Fill::Patch { .. } | Fill::None => None,
        };
        if let (Some(m), Some(region)) = (method, fill_region) {
            // The ray fill invents what it does not see: tag pixels are redrawn from the
            // board's print first (a clean plate shows them already), and each pixel takes
            // the rays that reach its own surface of the board (the table, the sheet).
            let mut surfaces = self.surfaces.take();
            let mut spare = self.spare_fill_mask.take();
            let (labels, painted) = match m {
                FillMethod::Rays(_) => {
                    let work = (region, RAY_FILL_TAG_MARGIN_PX, PaintTags::SetAndHidden);
                    let bg = &mut background;
                    paint_known_tags(&mut surfaces, view, bg, fill_mask, work, &mut spare)
                }
                _ => (None, false),
            };
            let mask = match (&spare, painted) {
                (Some(s), true) => s,
                _ => fill_mask,
            };
            let filled = self
                .diminisher
                .fill_in_bbox_on(&mut background, mask, region, &m, labels);
            let blended = match (filled, m) {
                (Ok(_), FillMethod::Rays(_)) => {
                    // A running average of what the fill gave each table point.
                    let prior = self.fill_prior.as_ref().map(|s| s.prior(view));
                    match prior.filter(|p| p.image.size() == background.size()) {
                        Some(p) => {
                            let blend = RAY_FILL_TEMPORAL_BLEND;
                            pa_diminish::blend_with_prior(&mut background, mask, region, &p, blend)
                                .map(|_| ())
                        }
                        None => Ok(()),
                    }
                }
                (filled, _) => filled.map(|_| ()),
            };
            self.surfaces = surfaces;
            self.spare_fill_mask = spare;
            blended?;
            if let FillMethod::Rays(_) = m {
                // The next frame samples its prior around the same table region: the region
                // and a quarter of its size (at least 32 pixels) around it.
                let margin = (region.width.max(region.height) / 4).max(32);
                let window = region.expand_clipped(margin, width, height);
                keep_prior(
                    &mut self.fill_prior,
                    &background,
                    fill_mask,
                    view,
                    Some(window),
                )?;
            }
        }
        Ok(background)
    }
}

/// How far each ray-filled pixel moves toward the previous frame's result at its table point
/// ([`pa_diminish::blend_with_prior`]), as the patch fill's
/// [`PatchParams::temporal_blend`](pa_diminish::PatchParams::temporal_blend). Measured
/// (revealed dB / flicker, truth's flicker in brackets) with 0, 0.5 and 0.7: Cycles bust 27.41
/// / 4.36, 28.96 / 2.27, 29.46 / 1.48 (3.12); Cycles CesiumMan, 16 stills, with shadows 24.67
/// / 7.97, 24.98 / 6.82, 25.05 / 6.44 (7.32); generated Wood, seed 1, every 6th frame 26.02,
/// -, 26.85 dB.
const RAY_FILL_TEMPORAL_BLEND: f32 = 0.7;

/// Keeps `background`, its fill mask and the frame's pose as the next frame's prior: all of
/// it, or only `window` (the rest of the prior's mask [`Mask::HIDDEN`]: no prior there), which
/// copies a fraction of the frame.
fn keep_prior(
    slot: &mut Option<FillPrior>,
    background: &ImageRgba8,
    fill_mask: &Mask,
    view: &FrameView<'_>,
    window: Option<Rect>,
) -> Result<(), ArError> {
    let (w, h) = background.size();
    let window = window.and_then(|r| r.clip(w, h));
    let s = match slot {
        Some(s) if s.image.size() == background.size() => s,
        slot => slot.insert(FillPrior {
            image: background.clone(),
            mask: fill_mask.clone(),
            camera_from_marker: view.camera_from_marker,
            window: None,
        }),
    };
    s.camera_from_marker = view.camera_from_marker;
    let Some(win) = window else {
        s.image.copy_from(background)?;
        s.mask.as_mut_slice().copy_from_slice(fill_mask.as_slice());
        s.window = None;
        return Ok(());
    };
    // What was the prior's own before is hidden now (all of it when all was).
    let hide = s.window.unwrap_or(Rect::new(0, 0, w, h));
    for_rows(hide, w, |_, m| s.mask.as_mut_slice()[m].fill(Mask::HIDDEN));
    let (src, dst) = (background.as_slice(), s.image.as_mut_slice());
    for_rows(win, w, |px, m| {
        dst[px.clone()].copy_from_slice(&src[px]);
        s.mask.as_mut_slice()[m.clone()].copy_from_slice(&fill_mask.as_slice()[m]);
    });
    s.window = Some(win);
    Ok(())
}

/// Calls `f` with each row of `r` (inside an image `w` pixels wide) as the ranges of its RGBA
/// bytes and of its pixels.
fn for_rows(r: Rect, w: u32, mut f: impl FnMut(std::ops::Range<usize>, std::ops::Range<usize>)) {
    let (w, x0, x1) = (w as usize, r.x as usize, r.right() as usize);
    for y in r.y as usize..r.bottom() as usize {
        f((y * w + x0) * 4..(y * w + x1) * 4, y * w + x0..y * w + x1);
    }
}

/// Pixels around the ray fill's region where the tags' black and white levels are measured
/// (the patch fill measures them over its own, larger work region).
const RAY_FILL_TAG_MARGIN_PX: u32 = 16;

/// Redraws the board's tags into `background` where `fill_mask` would have them invented
/// ([`BoardSurfaces::paint_tags`](super::surfaces::BoardSurfaces::paint_tags)), over the fill
/// `region` grown by `margin` (its known tag pixels give the black and white levels).
/// Returns the surface labels of that work region (None without board surfaces) and whether
/// any pixel was painted; if so, `spare` holds a copy of the fill mask with those pixels
/// known (the buffer is reused from frame to frame).
fn paint_known_tags<'s>(
    surfaces: &'s mut Option<(super::BoardSurfaces, Option<Mask>)>,
    view: &FrameView<'_>,
    background: &mut ImageRgba8,
    fill_mask: &Mask,
    (region, margin, which): (Rect, u32, PaintTags),
    spare: &mut Option<Mask>,
) -> (Option<&'s Mask>, bool) {
    let Some((s, buf)) = surfaces.as_mut() else {
        return (None, false);
    };
    let (w, h) = background.size();
    let work = region.expand_clipped(margin, w, h);
    let (camera, pose) = (&view.camera_model, view.camera_from_marker);
    let Some(labels) = super::surfaces::surface_labels(s, buf, camera, pose, (w, h), work) else {
        return (None, false);
    };
    if !s.has_tags_to_paint(work, labels, fill_mask, which) {
        return (Some(labels), false);
    }
    // The copy reuses the last frame's buffer.
    match &mut *spare {
        Some(m) if m.size() == fill_mask.size() => {
            m.as_mut_slice().copy_from_slice(fill_mask.as_slice())
        }
        slot => *slot = Some(fill_mask.clone()),
    }
    let Some(m) = spare.as_mut() else {
        return (Some(labels), false);
    };
    let img = background.as_mut_slice();
    let painted = s.paint_tags_found(camera, pose, work, labels, img, m, which) > 0;
    (Some(labels), painted)
}

/// What the patch and ray fills keep from one frame for the next: the diminished background,
/// its fill mask (hidden pixels were not filled) and the pose it was seen from.
pub(super) struct FillPrior {
    image: ImageRgba8,
    mask: Mask,
    camera_from_marker: Mat4,
    /// The part of `image` and `mask` kept from the last frame (None: all of it); the mask is
    /// [`Mask::HIDDEN`] elsewhere.
    window: Option<Rect>,
}

impl FillPrior {
    /// This state as the prior of the frame `view`: warped by the table plane's homography
    /// from its pose to the frame's.
    fn prior(&self, view: &FrameView<'_>) -> PatchPrior<'_> {
        PatchPrior {
            image: &self.image,
            mask: &self.mask,
            current_from_previous: Homography::from_dmat3(plane_homography(
                &view.camera_model,
                view.camera_from_marker,
                self.camera_from_marker,
            )),
        }
    }
}

/// The clean plate's fill settings: `current_from_plate` `h`, aligned to the frame with
/// `align` ([`super::ArSettings::align_plate`]).
pub(super) fn clean_plate(plate: &ImageRgba8, h: Homography, align: bool) -> CleanPlate<'_> {
    CleanPlate {
        align: align.then(PlateAlign::default),
        ..CleanPlate::new(plate, h)
    }
}

impl ArPipeline {
    /// The patch fill ([`Fill::Patch`]): the previous frame's result, warped through the
    /// table-plane homography, as prior; the clean plate first where `plate_h` is given. Keeps
    /// this frame's result for the next.
    fn patch_fill(
        &mut self,
        view: &FrameView<'_>,
        mut background: ImageRgba8,
        fill_region: Option<Rect>,
        plate_h: Option<Homography>,
    ) -> Result<ImageRgba8, ArError> {
        let fill_mask = match &self.fill_mask {
            Some((m, _)) => m,
            None => return Err(ArError::FillMaskMissing),
        };
        let Some(region) = fill_region else {
            return Ok(background);
        };
        let prior = self
            .fill_prior
            .as_ref()
            .filter(|s| s.image.size() == background.size())
            .map(|s| s.prior(view));
        let plate = match (&self.plate, plate_h) {
            (Some((plate, _)), Some(h)) => Some(clean_plate(plate, h, self.settings.align_plate)),
            _ => None,
        };
        // The surfaces over the patch fill's work region (its margin, and a pixel more).
        let mut surfaces = self.surfaces.take();
        let params = PatchParams::default();
        let margin = params.margin_px.max(region.width.max(region.height) / 4) + 1;
        let mut spare = self.spare_fill_mask.take();
        let (labels, painted) = paint_known_tags(
            &mut surfaces,
            view,
            &mut background,
            fill_mask,
            (region, margin, PaintTags::Set),
            &mut spare,
        );
        let method = FillMethod::Patch(PatchFill {
            params,
            prior,
            plate,
            surfaces: labels,
            align_prior: self.settings.align_plate.then(PlateAlign::default),
        });
        let mask = match (&spare, painted) {
            (Some(m), true) => m,
            _ => fill_mask,
        };
        let filled = self
            .diminisher
            .fill_in_bbox(&mut background, mask, region, &method);
        self.surfaces = surfaces;
        self.spare_fill_mask = spare;
        filled?;
        keep_prior(&mut self.fill_prior, &background, fill_mask, view, None)?;
        Ok(background)
    }
}

/// How far (Chebyshev, pixels) the composite looks around a twin pixel: its anti-aliasing
/// window's radius ([`crate::composite`]). A twin pixel whose neighbourhood of this radius is
/// all twin is drawn opaque, whatever the background.
const COMPOSITE_REACH_PX: usize = 4;

/// Marks as [`Mask::HIDDEN`] the set pixels of `fill` whose square neighbourhood of radius
/// `r` lies inside the twin (pixels beyond the image count as outside). Work O(bbox): a
/// sliding window along the rows, then down the columns, both in parallel (rows, then bands
/// of rows).
pub(super) fn hide_twin_interior(fill: &mut Mask, twin: &[bool], bbox: Bbox, r: usize) {
    use rayon::prelude::*;
    let (x0, y0, x1, y1) = bbox;
    let w = fill.width() as usize;
    let bw = x1 - x0 + 1;
    let bh = y1 - y0 + 1;
    let win = 2 * r + 1;
    // The twin lies inside its box: a window wider than the box is never all twin.
    if bw < win || bh < win {
        return;
    }
    // Horizontal: twin from lx - r to lx + r (the box's edges are outside the twin).
    let mut h_ok = vec![false; bw * bh];
    h_ok.par_chunks_mut(bw).enumerate().for_each(|(ly, out)| {
        let row = &twin[(y0 + ly) * w + x0..(y0 + ly) * w + x1 + 1];
        let mut count = row[..win - 1].iter().filter(|&&t| t).count();
        for lx in r..bw - r {
            count += usize::from(row[lx + r]);
            out[lx] = count == win;
            count -= usize::from(row[lx - r]);
        }
    });
    // Vertical, over the horizontal result: rows r..bh - r of the box, in bands.
    const BAND: usize = 32;
    let first = (y0 + r) * w;
    let rows = bh - 2 * r;
    let h_ok = &h_ok;
    fill.as_mut_slice()[first..first + rows * w]
        .par_chunks_mut(BAND * w)
        .enumerate()
        .for_each(|(band, data)| {
            let ly0 = r + band * BAND;
            // Rows ly0 - r .. ly0 + r - 1 counted; each row adds its bottom and drops its top.
            let mut count = vec![0usize; bw];
            for y in ly0 - r..ly0 + r {
                for (c, &ok) in count.iter_mut().zip(&h_ok[y * bw..(y + 1) * bw]) {
                    *c += usize::from(ok);
                }
            }
            for (k, row) in data.chunks_mut(w).enumerate() {
                let ly = ly0 + k;
                let add = &h_ok[(ly + r) * bw..(ly + r + 1) * bw];
                let drop = &h_ok[(ly - r) * bw..(ly - r + 1) * bw];
                let cells = &mut row[x0..x0 + bw];
                for (((c, &a), &d), m) in count.iter_mut().zip(add).zip(drop).zip(cells) {
                    *c += usize::from(a);
                    if *c == win && *m != 0 {
                        *m = Mask::HIDDEN;
                    }
                    *c -= usize::from(d);
                }
            }
        });
}

/// Clears a rectangle of a mask.
pub(super) fn clear_rect(m: &mut Mask, r: Rect) {
    let w = m.width() as usize;
    let data = m.as_mut_slice();
    for y in r.y as usize..(r.y + r.height) as usize {
        data[y * w + r.x as usize..y * w + (r.x + r.width) as usize].fill(0);
    }
}

/// The homography of the marker plane (z = 0) from the plate view's pixels to the current
/// view's pixels: `H = K [r1 r2 t]_current ([r1 r2 t]_plate)^-1 K^-1` (pinhole; distortion is
/// ignored here).
pub fn plane_homography(camera: &CameraModel, current: Mat4, plate: Mat4) -> DMat3 {
    let k = camera.intrinsics.matrix();
    let plane = |m: Mat4| {
        let m = m.as_dmat4();
        DMat3::from_cols(
            m.x_axis.truncate(),
            m.y_axis.truncate(),
            DVec3::new(m.w_axis.x, m.w_axis.y, m.w_axis.z),
        )
    };
    k * plane(current) * plane(plate).inverse() * k.inverse()
}

/// The key mask as a [`Mask`] (for callers that want pa-diminish types).
pub fn mask_from_bools(width: u32, height: u32, m: &[bool]) -> Result<Mask, ArError> {
    Ok(Mask::new(
        width,
        height,
        m.iter().map(|&b| if b { 255 } else { 0 }).collect(),
    )?)
}
