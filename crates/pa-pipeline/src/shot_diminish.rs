//! The shot's `[diminish]` table: how the real prop is removed.
//!
//! ```toml
//! [diminish]
//! fill = "rays"                 # rays (default), rectangle, plate, patch, none
//! clean_plate = "plate.png"     # a still of the set without the prop (relative to the shot)
//! # plate_frames = 3            # or: the first 3 stills of the take are plate
//! dilation_px = 4               # growth of the key-pose silhouette (0..=64)
//! shadows = false               # lift the prop's cast shadow, cast the twin's
//! align_plate = true            # align the clean plate to each frame around the prop
//! ```
//!
//! Every key is optional; without the table a shot does what it did before it existed (our
//! method: ray fill, 4 px, no shadows). `fill = "plate"` needs a plate (`clean_plate` or
//! `plate_frames`); a plate without `fill` selects the plate fill. `run` and `preview` take
//! the same settings as flags, which override the shot's ([`DiminishOverrides`]).

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::ar::Fill;
use crate::shot::{Shot, ShotError};

/// The largest mask dilation accepted (pixels).
pub const MAX_DILATION_PX: i64 = 64;

/// The largest `plate_frames`.
pub const MAX_PLATE_FRAMES: u32 = 10_000;

/// The `[diminish]` table as written (see the module docs).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize, Default)]
pub struct ShotDiminish {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fill: Option<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub clean_plate: Option<PathBuf>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub plate_frames: Option<u32>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub dilation_px: Option<i64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub shadows: Option<bool>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub align_plate: Option<bool>,
}

impl ShotDiminish {
    /// Whether the table says nothing (the shot's TOML then has no `[diminish]`).
    pub fn is_empty(&self) -> bool {
        *self == Self::default()
    }
}

/// A fill by the name the shot and the flags use.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FillName {
    /// The patch-based fill (not in this build: see [`FillName::to_fill`]).
    Patch,
    Rays,
    Rectangle,
    Plate,
    None,
}

impl FillName {
    /// Every name, in the order the preview cycles them.
    pub const ALL: [FillName; 5] = [
        FillName::Rays,
        FillName::Plate,
        FillName::Patch,
        FillName::Rectangle,
        FillName::None,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Self::Patch => "patch",
            Self::Rays => "rays",
            Self::Rectangle => "rectangle",
            Self::Plate => "plate",
            Self::None => "none",
        }
    }

    /// The names, comma-separated, for messages.
    pub fn names() -> String {
        Self::ALL.map(Self::name).join(", ")
    }

    /// The pipeline's fill, or `None` where this build has none of that name. The patch fill
    /// maps without its plate; [`DiminishConfig::fill()`] adds the plate when there is one.
    pub fn to_fill(self) -> Option<Fill> {
        match self {
            Self::Patch => Some(Fill::Patch { plate: false }),
            Self::Rays => Some(Fill::Rays),
            Self::Rectangle => Some(Fill::PaperRectangle),
            Self::Plate => Some(Fill::CleanPlate),
            Self::None => Some(Fill::None),
        }
    }
}

/// A name other than those of [`FillName`].
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("fill {given:?}: expected one of {}", FillName::names())]
pub struct ParseFillError {
    pub given: String,
}

impl std::str::FromStr for FillName {
    type Err = ParseFillError;
    fn from_str(s: &str) -> Result<Self, ParseFillError> {
        Self::ALL
            .into_iter()
            .find(|f| f.name() == s)
            .ok_or_else(|| ParseFillError { given: s.into() })
    }
}

/// Where the clean plate comes from.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum PlateSource {
    /// A still of the set without the prop (a path as given, resolved against the shot).
    Still(PathBuf),
    /// The first N stills of the take are plate (the first of them is the plate).
    FirstFrames(u32),
}

/// Settings given on the command line, each overriding the shot's.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct DiminishOverrides {
    pub fill: Option<String>,
    pub clean_plate: Option<PathBuf>,
    pub plate_frames: Option<u32>,
    pub dilation_px: Option<i64>,
    pub shadows: Option<bool>,
    pub align_plate: Option<bool>,
}

impl DiminishOverrides {
    /// Whether no flag was given.
    pub fn is_empty(&self) -> bool {
        *self == Self::default()
    }
}

/// The resolved settings of the diminish stage.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DiminishConfig {
    pub fill: FillName,
    pub plate: Option<PlateSource>,
    pub dilation_px: u32,
    pub shadows: bool,
    /// Align the clean plate to each frame ([`crate::ar::ArSettings::align_plate`]).
    pub align_plate: bool,
}

impl Default for DiminishConfig {
    /// Our method's (the pipeline's `ArSettings::ours`): rays, 4 px, no plate, no shadows, a
    /// plate (when given) aligned to each frame.
    fn default() -> Self {
        Self {
            fill: FillName::Rays,
            plate: None,
            dilation_px: 4,
            shadows: false,
            align_plate: true,
        }
    }
}

impl DiminishConfig {
    /// The pipeline's fill: [`FillName::to_fill`], with the clean plate as the patch fill's
    /// preferred source when the shot has one.
    pub fn fill(&self) -> Option<Fill> {
        match self.fill.to_fill()? {
            Fill::Patch { .. } => Some(Fill::Patch {
                plate: self.plate.is_some(),
            }),
            f => Some(f),
        }
    }

    /// The settings as one line, for a take's record (`fill=rays dilation=4 ...`).
    pub fn describe(&self) -> String {
        let plate = match &self.plate {
            None => "none".to_string(),
            Some(PlateSource::Still(p)) => p.display().to_string(),
            Some(PlateSource::FirstFrames(n)) => format!("first {n} stills"),
        };
        format!(
            "fill={} plate={plate} dilation_px={} shadows={} align_plate={}",
            self.fill.name(),
            self.dilation_px,
            self.shadows,
            self.align_plate
        )
    }
}

/// Checks the table (called by [`Shot`]'s own check): names, ranges, the plate file.
pub(crate) fn check(d: &ShotDiminish, shot_path: &Path) -> Result<(), ShotError> {
    resolve(d, &DiminishOverrides::default(), shot_path).map(|_| ())
}

/// The shot's `[diminish]` with `flags` over it, checked: the fill's name (and whether this
/// build has it), the dilation's range, one plate source at most and one for the plate fill,
/// the plate file a regular file. Errors name the shot file (or the flag) and the problem.
pub fn resolve(
    d: &ShotDiminish,
    flags: &DiminishOverrides,
    shot_path: &Path,
) -> Result<DiminishConfig, ShotError> {
    let bad = |message: String| ShotError::Invalid {
        path: shot_path.into(),
        message,
    };
    let (fill_text, fill_from) = match (&flags.fill, &d.fill) {
        (Some(f), _) => (Some(f.as_str()), "--fill"),
        (None, Some(f)) => (Some(f.as_str()), "[diminish] fill"),
        (None, None) => (None, ""),
    };
    let fill = match fill_text {
        Some(t) => {
            let f: FillName = t
                .parse()
                .map_err(|e: ParseFillError| bad(format!("{fill_from}: {e}")))?;
            if f.to_fill().is_none() {
                return Err(bad(format!(
                    "{fill_from} = {:?}: not available in this build",
                    f.name()
                )));
            }
            Some(f)
        }
        None => None,
    };
    let dilation = match (flags.dilation_px, d.dilation_px) {
        (Some(v), _) => Some((v, "--dilation")),
        (None, Some(v)) => Some((v, "[diminish] dilation_px")),
        (None, None) => None,
    };
    let dilation_px = match dilation {
        Some((v, from)) if !(0..=MAX_DILATION_PX).contains(&v) => {
            return Err(bad(format!(
                "{from} must be 0..={MAX_DILATION_PX} pixels, got {v}"
            )));
        }
        Some((v, _)) => v as u32,
        None => DiminishConfig::default().dilation_px,
    };
    // A flag's plate replaces the shot's, whichever kind.
    let (still, frames, from) = if flags.clean_plate.is_some() || flags.plate_frames.is_some() {
        (
            flags.clean_plate.clone().map(|p| (p, false)),
            flags.plate_frames,
            "--clean-plate and --plate-frames",
        )
    } else {
        (
            d.clean_plate.clone().map(|p| (p, true)),
            d.plate_frames,
            "[diminish] clean_plate and plate_frames",
        )
    };
    let plate = match (still, frames) {
        (Some(_), Some(_)) => {
            return Err(bad(format!("{from}: give one of them, not both")));
        }
        (Some((p, in_shot)), None) => {
            // The shot's path is relative to the shot; a flag's to the working folder.
            let path = if in_shot {
                Shot::resolve(shot_path, &p)
            } else {
                p
            };
            match std::fs::metadata(&path) {
                Ok(m) if m.is_file() => {}
                Ok(_) => {
                    return Err(bad(format!(
                        "clean plate {} is not a regular file",
                        path.display()
                    )))
                }
                Err(e) => {
                    return Err(bad(format!("clean plate {}: {e}", path.display())));
                }
            }
            Some(PlateSource::Still(path))
        }
        (None, Some(n)) => {
            if n == 0 || n > MAX_PLATE_FRAMES {
                return Err(bad(format!(
                    "plate_frames must be 1..={MAX_PLATE_FRAMES}, got {n}"
                )));
            }
            Some(PlateSource::FirstFrames(n))
        }
        (None, None) => None,
    };
    let fill = match (fill, &plate) {
        (Some(FillName::Plate), None) => {
            return Err(bad(format!(
                "{fill_from} = \"plate\" needs a clean plate: [diminish] clean_plate = \"FILE\" or plate_frames = N (--clean-plate, --plate-frames)"
            )));
        }
        (Some(f), _) => f,
        (None, Some(_)) => FillName::Plate,
        (None, None) => FillName::Rays,
    };
    Ok(DiminishConfig {
        fill,
        plate,
        dilation_px,
        shadows: flags.shadows.or(d.shadows).unwrap_or(false),
        align_plate: flags
            .align_plate
            .or(d.align_plate)
            .unwrap_or(DiminishConfig::default().align_plate),
    })
}

#[cfg(test)]
#[path = "shot_diminish_tests.rs"]
mod tests;
