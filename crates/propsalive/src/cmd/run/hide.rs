//! The hide flags of `run` and `preview` (`--hide none|cover|plate`, `--cover FILE`), which
//! override the shot's `[marker] hide` and `cover` (`pa_pipeline::shot_hide`), and the cover
//! picture: read as a still (budgeted), checked for size, handed to the pipeline
//! (`pa_pipeline::ar::Hide`) with the board's sheet.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use pa_diminish::{CoverImage, ImageRgba8};
use pa_pipeline::ar::{ArPipeline, BoardSheet, Hide, SHEET_MARGIN_M};
use pa_pipeline::shot::Shot;
use pa_pipeline::shot_diminish::DiminishConfig;
use pa_pipeline::shot_hide::{resolve, HideConfig, HideName, HideOverrides};
use pa_track::Board;

/// The hide flags (each overrides the shot's `[marker]` keys).
#[derive(clap::Args, Debug, Clone, Default)]
pub struct HideArgs {
    /// What replaces the board in the final frames: none (the board stays), cover (a
    /// picture, --cover) or plate (a still of the bare table, --cover, posed by the clean
    /// plate) [default: the shot's [marker] hide, else none].
    #[arg(long, value_name = "MODE")]
    pub hide: Option<String>,
    /// The picture over the board (--hide cover), or the still of the table without the
    /// board from the clean plate's position (--hide plate).
    #[arg(long, value_name = "FILE")]
    pub cover: Option<PathBuf>,
}

impl HideArgs {
    pub fn overrides(&self) -> HideOverrides {
        HideOverrides {
            hide: self.hide.clone(),
            cover: self.cover.clone(),
        }
    }

    /// The shot's `[marker] hide` and `cover` with these flags over them, checked against
    /// the resolved diminish settings (the plate needs a clean plate).
    pub fn resolve(&self, shot: &Shot, shot_path: &Path, d: &DiminishConfig) -> Result<HideConfig> {
        Ok(resolve(
            shot.marker.hide.as_deref(),
            shot.marker.cover.as_deref(),
            &self.overrides(),
            shot_path,
            d.plate.is_some(),
        )?)
    }
}

/// The smallest cover side accepted, pixels.
pub const MIN_COVER_PX: u32 = 8;

/// Reads a cover picture (or the bare-table still): an image file of at least
/// [`MIN_COVER_PX`] a side and at most `pa_diminish::cover::MAX_COVER_PIXELS`.
pub fn read_cover(path: &Path) -> Result<ImageRgba8> {
    let img = pa_video::still::read_still(path, &Default::default())
        .with_context(|| format!("cover {}", path.display()))?
        .to_rgba8();
    let (w, h) = img.dimensions();
    if w < MIN_COVER_PX || h < MIN_COVER_PX {
        bail!(
            "cover {}: {w}x{h} is too small a picture (at least {MIN_COVER_PX}x{MIN_COVER_PX})",
            path.display()
        );
    }
    if w as u64 * h as u64 > pa_diminish::cover::MAX_COVER_PIXELS {
        bail!(
            "cover {}: {w}x{h} is too large a picture (at most 4096x4096 pixels; scale it down)",
            path.display()
        );
    }
    Ok(ImageRgba8::new(w, h, img.into_raw())?)
}

/// Sets the pipeline's hiding for `h` over `board`'s sheet. `plate_pose`: the clean plate's
/// `camera_from_marker` (the bare-table still was taken from there); `size`: the take's frame
/// size, which the bare-table still must have.
pub fn apply(
    pipeline: &mut ArPipeline,
    h: &HideConfig,
    board: &Board,
    plate_pose: Option<glam::Mat4>,
    size: (u32, u32),
) -> Result<()> {
    let hide = match (h.hide, &h.cover) {
        (HideName::None, _) => {
            pipeline.set_hide(None);
            return Ok(());
        }
        (HideName::Cover, Some(c)) => {
            let img = read_cover(c)?;
            Hide::Cover(Box::new(CoverImage::new(&img)?))
        }
        (HideName::Plate, Some(c)) => {
            let Some(pose) = plate_pose else {
                bail!("--hide plate needs the clean plate's pose (a clean plate with the board in view)");
            };
            let plate = read_cover(c)?;
            if plate.size() != size {
                bail!(
                    "bare-table still {} is {}x{}, the take {}x{}: it must come from the same camera and size as the clean plate",
                    c.display(),
                    plate.width(),
                    plate.height(),
                    size.0,
                    size.1
                );
            }
            Hide::Plate {
                plate,
                camera_from_marker: pose,
            }
        }
        (_, None) => bail!("--hide {} needs --cover FILE", h.hide.name()),
    };
    let sheet = BoardSheet::from_board(board, SHEET_MARGIN_M)?;
    pipeline.set_hide(Some((hide, sheet)));
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A fresh folder, removed with everything in it when dropped.
    fn dir() -> tempfile::TempDir {
        tempfile::Builder::new()
            .prefix("pa-run-hide-")
            .tempdir()
            .expect("dir")
    }

    #[test]
    fn bad_covers_are_refused_with_the_file_named() {
        let tmp = dir();
        let d = tmp.path();
        let text = d.join("notes.png");
        std::fs::write(&text, b"not a picture at all").expect("write");
        let e = format!("{:#}", read_cover(&text).expect_err("not an image"));
        assert!(e.contains("notes.png"), "{e}");
        let missing = d.join("missing.png");
        let e = format!("{:#}", read_cover(&missing).expect_err("missing"));
        assert!(e.contains("missing.png"), "{e}");
        let tiny = d.join("tiny.png");
        image::RgbaImage::new(4, 4).save(&tiny).expect("save");
        let e = format!("{:#}", read_cover(&tiny).expect_err("tiny"));
        assert!(e.contains("too small"), "{e}");
        let big = d.join("big.png");
        image::GrayImage::new(4097, 4097).save(&big).expect("save");
        let e = format!("{:#}", read_cover(&big).expect_err("big"));
        assert!(e.contains("too large"), "{e}");
        let ok = d.join("ok.png");
        image::RgbaImage::from_pixel(16, 8, image::Rgba([1, 2, 3, 255]))
            .save(&ok)
            .expect("save");
        let img = read_cover(&ok).expect("a picture");
        assert_eq!(img.size(), (16, 8));
        assert_eq!(img.get(3, 3), Some([1, 2, 3, 255]));
    }
}
