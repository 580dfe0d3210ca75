//! The shot's marker as the tracker's target, shared by `run`, `preview` and `register`: the
//! board of `[[marker.tags]]`, the picture of `[marker] image` (read as a still, budgeted,
//! prepared once: keypoints at several scales), or both in one marker frame
//! (`pa_pipeline::shot_config::track_target`). The picture's bytes are part of a take's
//! settings: a changed picture tracks differently, so the take is rendered anew.

use std::path::Path;

use anyhow::{Context, Result};
use pa_pipeline::shot::Shot;
use pa_pipeline::shot_config;
use pa_track::{Board, GrayImage, ImageTarget, TrackTarget};

/// The most bytes a marker picture file may have (a 300 dpi A3 print is ~50 MB as PNG).
const MAX_PICTURE_BYTES: u64 = 256 << 20;

/// The tracker's target for `shot` with its `board`, and (for a picture) a line that
/// identifies the picture's content, for the take's settings hash.
pub fn track_target(
    shot: &Shot,
    shot_path: &Path,
    board: &Board,
) -> Result<(TrackTarget, Option<String>)> {
    let Some((path, width_m)) = shot_config::marker_picture(shot, shot_path)? else {
        return Ok((TrackTarget::Board(board.clone()), None));
    };
    // Read once: the same bytes are decoded and hashed.
    let budget = pa_video::still::StillBudget::default();
    let bytes = pa_io::read_regular(&path, MAX_PICTURE_BYTES, "a marker picture")
        .with_context(|| format!("{}: [marker] image", shot_path.display()))?;
    let img = pa_video::still::decode_still(&path, &bytes, &budget)
        .with_context(|| format!("marker picture {}", path.display()))?
        .to_luma8();
    let gray = GrayImage::from(&img);
    let target = ImageTarget::new(&gray, width_m).with_context(|| {
        format!(
            "marker picture {}: cannot be tracked (`propsalive marker --check {}` says why)",
            path.display(),
            path.display()
        )
    })?;
    let identity = format!(
        "\n# marker picture: {} {}",
        path.display(),
        pa_take::hash_hex(&bytes)
    );
    Ok((
        shot_config::track_target(board.clone(), Some(target)),
        Some(identity),
    ))
}

/// Refuses hiding the marker when it has no tags: `hide` replaces a board's printed sheet;
/// a picture marker is part of the set and stays.
pub fn check_hide(board: &Board, hide: pa_pipeline::shot_hide::HideName) -> Result<()> {
    if board.tags.is_empty() && hide != pa_pipeline::shot_hide::HideName::None {
        anyhow::bail!(
            "hide = \"{}\" replaces a board of tags, and this marker is a picture only (it is part of the set and stays in the frames): use hide = \"none\"",
            hide.name()
        );
    }
    Ok(())
}
