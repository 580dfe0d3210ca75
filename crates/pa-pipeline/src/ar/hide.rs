//! No marker in the final frames: after the diminish stage and before the twin is composited,
//! the printed board sheet in the background is replaced by a cover picture or by the clean
//! plate ([`Hide`]).
//!
//! **The sheet.** A [`Board`] knows its tags, not its paper. The sheet hidden is the bounding
//! rectangle of the tags' printed squares (each tag's whole code square, its white quiet
//! border included: `size_m * total_cells / border_cells`, rotated tags by their corners)
//! grown by a margin on every side ([`BoardSheet::from_board`], [`SHEET_MARGIN_M`] by
//! default: the `marker` command's 10 mm paper margin and its label, with room to spare).
//! Covering a little table around a sheet is harmless; leaving paper visible is not.
//!
//! **Cover.** Every pixel of the sheet's image (bounded by the sheet's outline projected with
//! the lens distortion) is unprojected through the camera model (distortion removed) onto
//! the marker plane z = 0, giving its sheet coordinates; `pa_diminish::cover` fits the light
//! on the sheet's visible white paper (outside the tags) in this frame and lays the picture,
//! stretched over the sheet rectangle (+X along the picture's width, +Y down it, as printed),
//! with that light and anti-aliased edges.
//!
//! **Plate.** The sheet's pixels (those it covers at all) are filled from a plate of the
//! table *without the board*, warped by the table-plane homography and gain-matched on a ring
//! of table just outside the sheet, as the clean-plate fill does (`pa_diminish::plate`).
//!
//! **Occluders.** Whatever stands over the sheet in the frame (a hand, another object; the
//! real prop is already removed) is replaced too: the sheet's whole image is overwritten.
//! The twin is composited on top afterwards, as usual. A hand reaching over the board is
//! therefore cut where it crosses the sheet; the paper fit ignores it (robust refit).

use glam::{DVec2, DVec3, Mat4};
use pa_camera::CameraModel;
use pa_diminish::{
    fit_shading, paste_cover, CoverImage, FillMethod, Homography, ImageRgba8, Paper, Rect,
    SheetCoords, SheetShading,
};
use pa_track::Board;

use super::fill::{clean_plate, plane_homography};
use super::{ArError, ArPipeline, FrameView};

/// The default margin of paper around the tags' printed squares, metres.
pub const SHEET_MARGIN_M: f64 = 0.02;

/// The printed sheet of a board on the marker plane (marker metres) and where its tags are.
#[derive(Debug, Clone, PartialEq)]
pub struct BoardSheet {
    /// Corner of least x and y (top-left as printed), metres.
    pub min_m: DVec2,
    /// Corner of greatest x and y, metres.
    pub max_m: DVec2,
    /// The tags' printed squares (axis-aligned bounds, `[x0, y0, x1, y1]` metres): not paper.
    pub tags_m: Vec<[f64; 4]>,
}

impl BoardSheet {
    /// The sheet of `board`: the tags' printed squares' bounds grown by `margin_m`.
    pub fn from_board(board: &Board, margin_m: f64) -> Result<Self, ArError> {
        if board.tags.is_empty() || !(margin_m.is_finite() && margin_m >= 0.0) {
            return Err(ArError::BadSheet {
                reason: "a board needs at least one tag and a finite, non-negative margin",
            });
        }
        let layout = pa_track::family_layout(board.family)?;
        let scale = layout.total_cells as f64 / layout.border_cells as f64;
        let mut tags_m = Vec::with_capacity(board.tags.len());
        let mut lo = DVec2::splat(f64::INFINITY);
        let mut hi = DVec2::splat(f64::NEG_INFINITY);
        for t in &board.tags {
            let (mut a, mut b) = (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY));
            for p in t.object_points() {
                let q = t.center_m + (p.truncate() - t.center_m) * scale;
                a = a.min(q);
                b = b.max(q);
            }
            tags_m.push([a.x, a.y, b.x, b.y]);
            lo = lo.min(a);
            hi = hi.max(b);
        }
        Ok(Self {
            min_m: lo - DVec2::splat(margin_m),
            max_m: hi + DVec2::splat(margin_m),
            tags_m,
        })
    }

    /// A sheet given by its corners (no tags: all paper).
    pub fn rect(min_m: DVec2, max_m: DVec2) -> Self {
        Self {
            min_m,
            max_m,
            tags_m: Vec::new(),
        }
    }

    fn size(&self) -> DVec2 {
        self.max_m - self.min_m
    }

    /// Where the paper is, in sheet coordinates: outside the tags (grown by 1.5 mm against
    /// blur) and 3 mm in from the edges.
    fn paper(&self) -> Paper {
        let size = self.size();
        let guard = 0.0015;
        Paper {
            not_paper: self
                .tags_m
                .iter()
                .map(|r| {
                    [
                        ((r[0] - guard - self.min_m.x) / size.x) as f32,
                        ((r[1] - guard - self.min_m.y) / size.y) as f32,
                        ((r[2] + guard - self.min_m.x) / size.x) as f32,
                        ((r[3] + guard - self.min_m.y) / size.y) as f32,
                    ]
                })
                .collect(),
            edge_guard: [(0.003 / size.x) as f32, (0.003 / size.y) as f32],
        }
    }

    /// Sheet coordinates of every pixel around the sheet's image (`None`: it is not in view).
    pub fn coords(
        &self,
        camera: &CameraModel,
        camera_from_marker: Mat4,
        width: u32,
        height: u32,
    ) -> Option<SheetCoords> {
        let m = camera_from_marker.as_dmat4();
        // The outline, projected with the distortion (edges bend), bounds the work.
        let (mut lo, mut hi) = (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY));
        let size = self.size();
        const STEPS: usize = 16;
        for k in 0..4 * STEPS {
            let f = (k % STEPS) as f64 / STEPS as f64;
            let (s, t) = match k / STEPS {
                0 => (f, 0.0),
                1 => (1.0, f),
                2 => (1.0 - f, 1.0),
                _ => (0.0, 1.0 - f),
            };
            let p = DVec3::new(self.min_m.x + s * size.x, self.min_m.y + t * size.y, 0.0);
            // A corner behind the camera: the sheet is cut by the image plane; work over the
            // whole frame.
            match camera.pixel_from_camera(m.transform_point3(p)) {
                Some(px) if px.is_finite() => {
                    lo = lo.min(px);
                    hi = hi.max(px);
                }
                _ => {
                    lo = DVec2::ZERO;
                    hi = DVec2::new(width as f64, height as f64);
                }
            }
        }
        let x0 = (lo.x.floor() - 2.0).max(0.0);
        let y0 = (lo.y.floor() - 2.0).max(0.0);
        let x1 = (hi.x.ceil() + 2.0).min(width as f64 - 1.0);
        let y1 = (hi.y.ceil() + 2.0).min(height as f64 - 1.0);
        if x0 > x1 || y0 > y1 {
            return None;
        }
        let rect = Rect::from_inclusive(x0 as u32, y0 as u32, x1 as u32, y1 as u32);
        let marker_from_camera = m.inverse();
        let origin = marker_from_camera.transform_point3(DVec3::ZERO);
        let mut st = vec![[f32::NAN; 2]; rect.area()];
        {
            use rayon::prelude::*;
            st.par_chunks_mut(rect.width as usize)
                .enumerate()
                .for_each(|(ly, row)| {
                    let y = (rect.y as usize + ly) as f64;
                    for (lx, o) in row.iter_mut().enumerate() {
                        let x = (rect.x as usize + lx) as f64;
                        let ray = camera.ray_from_pixel(DVec2::new(x, y));
                        let d = marker_from_camera.transform_vector3(ray);
                        if d.z.abs() < 1e-12 {
                            continue;
                        }
                        let lambda = -origin.z / d.z;
                        if lambda <= 0.0 {
                            continue;
                        }
                        let p = origin + d * lambda;
                        *o = [
                            ((p.x - self.min_m.x) / size.x) as f32,
                            ((p.y - self.min_m.y) / size.y) as f32,
                        ];
                    }
                });
        }
        Some(SheetCoords { rect, st })
    }
}

/// What replaces the board sheet in the final frames.
#[derive(Debug, Clone)]
pub enum Hide {
    /// A picture printed over the sheet, lit like the sheet's paper.
    Cover(Box<CoverImage>),
    /// A still of the table without the board and the pose it was taken from
    /// (`camera_from_marker`).
    Plate {
        plate: ImageRgba8,
        camera_from_marker: Mat4,
    },
}

/// The pipeline's hiding: what, over which sheet, and the last frame's light.
pub(super) struct HideState {
    pub hide: Hide,
    pub sheet: BoardSheet,
    /// The last light fitted (kept when a frame shows no paper).
    pub shading: Option<SheetShading>,
    /// False while the preview shows the board ([`ArPipeline::set_hide_enabled`]).
    pub enabled: bool,
}

impl ArPipeline {
    /// Hides the board `sheet` in every frame from now on (`None`: shows it, the default).
    pub fn set_hide(&mut self, hide: Option<(Hide, BoardSheet)>) {
        self.hide = hide.map(|(hide, sheet)| HideState {
            hide,
            sheet,
            shading: None,
            enabled: true,
        });
    }

    /// Whether a hiding is set ([`Self::set_hide`]), on or off.
    pub fn has_hide(&self) -> bool {
        self.hide.is_some()
    }

    /// Switches the hiding set by [`Self::set_hide`] off (the board shows) or back on, keeping
    /// it (the preview's `B`).
    pub fn set_hide_enabled(&mut self, on: bool) {
        if let Some(h) = &mut self.hide {
            h.enabled = on;
        }
    }

    /// Replaces the sheet in the diminished `background` (a no-op without [`Hide`]).
    pub(super) fn hide_sheet(
        &mut self,
        view: &FrameView<'_>,
        background: &mut ImageRgba8,
    ) -> Result<(), ArError> {
        let align_plate = self.settings.align_plate;
        let Some(state) = self.hide.as_mut().filter(|h| h.enabled) else {
            return Ok(());
        };
        let (w, h) = (view.width, view.height);
        let Some(coords) = state
            .sheet
            .coords(&view.camera_model, view.camera_from_marker, w, h)
        else {
            return Ok(());
        };
        match &state.hide {
            Hide::Cover(cover) => {
                let shading = fit_shading(background, &coords, &state.sheet.paper())
                    .or(state.shading)
                    .unwrap_or_else(|| SheetShading::uniform(1.0));
                state.shading = Some(shading);
                paste_cover(background, &coords, cover, &shading)?;
            }
            Hide::Plate {
                plate,
                camera_from_marker,
            } => {
                let (mask, Some(bbox)) = coords.mask(w, h)? else {
                    return Ok(());
                };
                let hmat = plane_homography(
                    &view.camera_model,
                    view.camera_from_marker,
                    *camera_from_marker,
                );
                let method = FillMethod::CleanPlate(clean_plate(
                    plate,
                    Homography::from_dmat3(hmat),
                    align_plate,
                ));
                self.diminisher
                    .fill_in_bbox(background, &mask, bbox, &method)?;
            }
        }
        Ok(())
    }
}
