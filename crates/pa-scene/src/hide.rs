//! The set without its marker: the truth of the pipeline's hiding of the board
//! (`pa_pipeline::ar::Hide`) and the demo's cover picture.
//!
//! [`TruthSheet`] says what the ground truth shows where the board's sheet lies: the board
//! (the default), the bare table (what `Hide::Plate` should give) or a picture printed on the
//! same paper over the pipeline's sheet rectangle (what `Hide::Cover` should give). The input
//! frames always show the board (the tracker needs it).

use glam::Vec2;
use pa_diminish::{CoverImage, ImageRgba8};
use pa_pipeline::ar::{ArPipeline, BoardSheet, Hide, SHEET_MARGIN_M};
use pa_render::{CpuTexture, Renderer};

use crate::scene::SheetLook;
use crate::{Scene, SceneError};

/// What the ground truth shows where the board's sheet is.
#[derive(Debug, Clone, Default, PartialEq)]
pub enum TruthSheet {
    #[default]
    Board,
    /// The table, no sheet.
    Bare,
    /// `picture` printed on the board's paper over `min_m`..`max_m` of the marker plane.
    Cover {
        picture: CpuTexture,
        min_m: Vec2,
        max_m: Vec2,
    },
}

/// Which hiding the demo shows.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum HideKind {
    Cover,
    Plate,
}

impl std::str::FromStr for HideKind {
    type Err = SceneError;
    fn from_str(s: &str) -> Result<Self, SceneError> {
        match s {
            "cover" => Ok(Self::Cover),
            "plate" => Ok(Self::Plate),
            _ => Err(SceneError::UnknownHide { given: s.into() }),
        }
    }
}

/// A 480x360 picture with structure in both directions and no symmetry (a mirrored or turned
/// cover shows): colour ramps, a disc off-centre, diagonal stripes in one corner.
pub fn cover_picture() -> CpuTexture {
    let (w, h) = (480u32, 360u32);
    let mut rgba8 = Vec::with_capacity((w * h * 4) as usize);
    for y in 0..h {
        for x in 0..w {
            let (u, v) = (x as f32 / w as f32, y as f32 / h as f32);
            let mut p = [
                (40.0 + 200.0 * u) as u8,
                (60.0 + 160.0 * v) as u8,
                (200.0 - 150.0 * u * v) as u8,
            ];
            if (u - 0.3).powi(2) + (v - 0.4).powi(2) < 0.02 {
                p = [230, 200, 40];
            }
            if u > 0.7 && v > 0.6 && ((x + y) / 12) % 2 == 0 {
                p = [30, 30, 40];
            }
            rgba8.extend_from_slice(&[p[0], p[1], p[2], 255]);
        }
    }
    CpuTexture {
        width: w,
        height: h,
        rgba8,
    }
}

/// The pipeline's sheet of the set's board (the default margin).
pub fn set_sheet(scene: &Scene) -> Result<BoardSheet, SceneError> {
    Ok(BoardSheet::from_board(&scene.board, SHEET_MARGIN_M)?)
}

/// The ground truth of `kind` on the set's board with [`cover_picture`].
pub fn truth_sheet(kind: HideKind) -> Result<TruthSheet, SceneError> {
    Ok(match kind {
        HideKind::Plate => TruthSheet::Bare,
        HideKind::Cover => {
            let sheet = BoardSheet::from_board(&crate::scene::set_board(), SHEET_MARGIN_M)?;
            TruthSheet::Cover {
                picture: cover_picture(),
                min_m: sheet.min_m.as_vec2(),
                max_m: sheet.max_m.as_vec2(),
            }
        }
    })
}

/// The pipeline's hiding of `kind`: [`cover_picture`], or the bare table seen from the clean
/// plate's view (frame 0) with that pose.
pub fn hide_for(
    scene: &Scene,
    renderer: &mut Renderer,
    kind: HideKind,
) -> Result<(Hide, BoardSheet), SceneError> {
    let sheet = set_sheet(scene)?;
    let hide = match kind {
        HideKind::Cover => {
            let p = cover_picture();
            let img = ImageRgba8::new(p.width, p.height, p.rgba8)?;
            Hide::Cover(Box::new(CoverImage::new(&img)?))
        }
        HideKind::Plate => {
            let pose = scene.camera_from_marker(0);
            let r = scene.render_with_sheet(renderer, pose, None, SheetLook::Bare)?;
            Hide::Plate {
                plate: ImageRgba8::new(r.width, r.height, r.rgba8)?,
                camera_from_marker: pose,
            }
        }
    };
    Ok((hide, sheet))
}

/// Sets the hiding of `kind` on a pipeline of `scene`.
pub fn apply(
    scene: &Scene,
    renderer: &mut Renderer,
    pipeline: &mut ArPipeline,
    kind: HideKind,
) -> Result<(), SceneError> {
    let h = hide_for(scene, renderer, kind)?;
    pipeline.set_hide(Some(h));
    Ok(())
}
