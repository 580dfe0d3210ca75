//! The diminish flags of `run` and `preview` (`--fill`, `--clean-plate`, `--plate-frames`,
//! `--dilation`, `--shadows`/`--no-shadows`, `--no-plate-align`), which override the shot's
//! `[diminish]`
//! (`pa_pipeline::shot_diminish`), and the clean plate: a still of the set without the prop,
//! tracked like any still for the camera pose it was taken from (the pipeline warps it into
//! each frame by the table-plane homography).

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use pa_camera::CameraModel;
use pa_diminish::ImageRgba8;
use pa_pipeline::ar::{ArPipeline, ArSettings};
use pa_pipeline::shot::Shot;
use pa_pipeline::shot_diminish::{resolve, DiminishConfig, DiminishOverrides, PlateSource};
use pa_track::{DetectorConfig, TrackTarget, Tracker, TrackerConfig};

/// The diminish flags (each overrides the shot's `[diminish]`).
#[derive(clap::Args, Debug, Clone, Default)]
pub struct DiminishArgs {
    /// How the real prop is removed: rays, plate, rectangle, patch or none [default: the
    /// shot's, else rays].
    #[arg(long, value_name = "NAME")]
    pub fill: Option<String>,
    /// A still of the set without the prop (the same camera and size as the take): the
    /// clean plate, warped into each frame by the table plane (selects --fill plate unless
    /// --fill says otherwise).
    #[arg(long, value_name = "FILE")]
    pub clean_plate: Option<PathBuf>,
    /// The first N stills of the take show the set without the prop: the first is the clean
    /// plate, all N go out untouched (a folder of stills only).
    #[arg(long, value_name = "N")]
    pub plate_frames: Option<u32>,
    /// Growth of the key-pose silhouette before the fill, pixels (0..=64) [default: the
    /// shot's, else 4].
    #[arg(long, value_name = "PX", allow_negative_numbers = true)]
    pub dilation: Option<i64>,
    /// Lift the key prop's cast shadow from the plate and cast the twin's (light estimated
    /// from the frame).
    #[arg(long, conflicts_with = "no_shadows")]
    pub shadows: bool,
    /// No shadow work (overrides the shot's `shadows = true`).
    #[arg(long)]
    pub no_shadows: bool,
    /// Use the clean plate where the tracked poses place it, without aligning it to each
    /// frame on the pixels around the prop (the shot's `align_plate = false`).
    #[arg(long)]
    pub no_plate_align: bool,
}

impl DiminishArgs {
    /// The flags as overrides of the shot.
    pub fn overrides(&self) -> DiminishOverrides {
        DiminishOverrides {
            fill: self.fill.clone(),
            clean_plate: self.clean_plate.clone(),
            plate_frames: self.plate_frames,
            dilation_px: self.dilation,
            shadows: match (self.shadows, self.no_shadows) {
                (true, _) => Some(true),
                (_, true) => Some(false),
                _ => None,
            },
            align_plate: self.no_plate_align.then_some(false),
        }
    }

    /// The shot's `[diminish]` with these flags over it, checked.
    pub fn resolve(&self, shot: &Shot, shot_path: &Path) -> Result<DiminishConfig> {
        Ok(resolve(&shot.diminish, &self.overrides(), shot_path)?)
    }
}

/// The pipeline's settings for `d`: our method with its fill, dilation and plate alignment.
pub fn settings(d: &DiminishConfig) -> Result<ArSettings> {
    let Some(fill) = d.fill() else {
        bail!("fill {:?}: not available in this build", d.fill.name());
    };
    Ok(ArSettings {
        fill,
        dilate_px: d.dilation_px,
        align_plate: d.align_plate,
        ..ArSettings::ours()
    })
}

/// The clean plate's file: the still named, or the first still of the take's folder for
/// `plate_frames` (`first_still`: `None` for a video or a camera, which are refused).
pub fn plate_file(d: &DiminishConfig, first_still: Option<&Path>) -> Result<Option<PathBuf>> {
    Ok(match &d.plate {
        None => None,
        Some(PlateSource::Still(p)) => Some(p.clone()),
        Some(PlateSource::FirstFrames(_)) => match first_still {
            Some(p) => Some(p.to_path_buf()),
            None => bail!(
                "plate_frames needs a folder of stills as --input; for a video or a camera give a still of the set without the prop (--clean-plate FILE or [diminish] clean_plate)"
            ),
        },
    })
}

/// How many of the first stills are plate (passed through untouched).
pub fn plate_frames(d: &DiminishConfig) -> usize {
    match d.plate {
        Some(PlateSource::FirstFrames(n)) => n as usize,
        _ => 0,
    }
}

/// Reads the clean plate still and tracks the marker in it for the pose it was taken from.
/// The plate must have the take's size and show the marker.
pub fn load_plate(
    path: &Path,
    camera: CameraModel,
    target: &TrackTarget,
    width: u32,
    height: u32,
) -> Result<(ImageRgba8, glam::Mat4)> {
    let img = pa_video::still::read_still(path, &Default::default())
        .with_context(|| format!("clean plate {}", path.display()))?
        .to_rgba8();
    if img.dimensions() != (width, height) {
        bail!(
            "clean plate {} is {}x{}, the take {width}x{height}: the plate must be a still of the same camera and size",
            path.display(),
            img.width(),
            img.height()
        );
    }
    let mut tracker = Tracker::new(
        camera,
        target.clone(),
        DetectorConfig::default(),
        TrackerConfig::per_still(),
    )?;
    let gray = pa_pipeline::ar::gray_from_rgba(img.as_raw(), width, height)?;
    let out = tracker.update(&gray, 0.0)?;
    let Some(pose) = out.pose else {
        bail!(
            "clean plate {}: the marker is not found in it (the plate needs the marker in view to be placed)",
            path.display()
        );
    };
    let plate = ImageRgba8::new(width, height, img.into_raw())?;
    Ok((plate, pose.to_mat4()))
}

/// Tells the pipeline what the board prints (its tags; the sheet's size is not in the shot),
/// as `eval` does on every set it measures: the patch fill copies paper into paper and
/// redraws a covered tag from its pattern, and the shadow estimate compares pairs of one
/// print. Nothing for a target without tags.
pub fn apply_board(pipeline: &mut ArPipeline, board: &pa_track::Board) {
    if !board.tags.is_empty() {
        pipeline.set_board_surfaces(Some(pa_pipeline::ar::BoardSurfaces::new(board, None)));
    }
}

/// Applies `d` and the plate to a pipeline.
pub fn apply(
    pipeline: &mut ArPipeline,
    d: &DiminishConfig,
    plate: Option<(ImageRgba8, glam::Mat4)>,
) -> Result<()> {
    pipeline.settings = settings(d)?;
    pipeline.set_shadows(d.shadows);
    if let Some((img, pose)) = plate {
        pipeline.set_clean_plate(img, pose);
    }
    Ok(())
}
