//! Calibration file I/O: OpenCV's calibration YAML (`%YAML:1.0`, `!!opencv-matrix`) and a
//! TOML / JSON form of [`CameraModel`] via serde.
//!
//! The OpenCV reader is a small, tolerant parser for the subset of YAML that OpenCV's
//! `FileStorage` writes (and that ROS `camera_info` files use): block mappings by indentation,
//! `!!opencv-matrix` tags, flow sequences `[ ... ]` that may span lines, flow mappings
//! `{ ... }`, quoted strings, comments, block sequences of scalars. Unknown keys are ignored.
//!
//! Keys read (aliases in brackets):
//! - `camera_matrix` (`cameraMatrix`, `K`): 3x3, no skew, last row `0 0 1`.
//! - `distortion_coefficients` (`dist_coeffs`, `distCoeffs`, `D`): a row or column vector of
//!   4, 5, 8, 12 or 14 values; k1, k2, p1, p2, k3 are taken (zeros where missing). The
//!   rational and thin-prism terms beyond k3 must be zero (they are not modelled).
//!   Optional: a missing entry means no distortion.
//! - `image_width`, `image_height` (or `cameraResolution: [w, h]`).
//!
//! Hostile input: files are read through [`pa_io`] (only regular files, at most
//! [`MAX_CALIBRATION_BYTES`]); the YAML parser nests at most [`MAX_NESTING`] levels and holds
//! at most [`MAX_NODES`] values; every number of the camera must be finite.
//!
//! Errors name the file and the problem ([`CalibError`]) and never repeat the file's text:
//! a file that is not a calibration (`--calib /etc/shadow`) is reported by line and column
//! and what was expected, not by its content.

use std::path::Path;

use crate::diag::{fmt_position, json_error, toml_error, Located};
use crate::{CameraError, CameraModel};

mod opencv;
#[cfg(test)]
mod tests;
mod yaml;

pub use opencv::{from_opencv_yaml, load_opencv_yaml, save_opencv_yaml, to_opencv_yaml};

/// The largest calibration file read (16 MiB): an OpenCV calibration with per-view
/// extrinsics of thousands of views is well under 1 MiB.
pub const MAX_CALIBRATION_BYTES: u64 = 16 << 20;

/// The deepest nesting of YAML blocks and flow collections accepted (OpenCV writes 2).
pub const MAX_NESTING: usize = 64;

/// The most values (scalars, sequences, mappings) a YAML calibration may hold.
pub const MAX_NODES: usize = 1_000_000;

/// The field names of [`CameraModel`]'s TOML and JSON forms, which parse errors may repeat.
const FIELDS: &[&str] = &[
    "intrinsics",
    "distortion",
    "fx",
    "fy",
    "cx",
    "cy",
    "width",
    "height",
    "k1",
    "k2",
    "p1",
    "p2",
    "k3",
];

/// Errors while reading or writing a calibration file. `file` is the path, or the name the
/// caller gave a string source. No message repeats the file's text.
#[derive(Debug, thiserror::Error)]
pub enum CalibError {
    /// Reading or writing the file failed (names the file): not a regular file, over
    /// [`MAX_CALIBRATION_BYTES`], not UTF-8, or an operating-system error.
    #[error(transparent)]
    Io(#[from] pa_io::IoError),
    /// A required field is absent.
    #[error("{file}: missing field `{field}`")]
    MissingField { file: String, field: &'static str },
    /// A matrix has the wrong number of rows, columns or values.
    #[error("{file}: `{field}` has the wrong size: {found} (expected {expected})")]
    WrongSize {
        file: String,
        field: String,
        found: String,
        expected: &'static str,
    },
    /// A value that must be a number is not; `found` says what it is instead.
    #[error("{file}:{line}: `{field}` is not numeric (found {found})")]
    NonNumeric {
        file: String,
        field: String,
        line: usize,
        found: &'static str,
    },
    /// A number that must be finite is NaN or infinite.
    #[error("{file}:{line}: `{field}` is not a finite number")]
    NotFinite {
        file: String,
        field: String,
        line: usize,
    },
    /// The text is not in the YAML subset OpenCV writes.
    #[error("{file}:{line}: syntax error: {message}")]
    Syntax {
        file: String,
        line: usize,
        message: String,
    },
    /// A value the camera model cannot represent (skew, extra distortion terms).
    #[error("{file}: unsupported calibration: {message}")]
    Unsupported { file: String, message: String },
    /// The values parse but do not form a valid camera.
    #[error("{file}: {source}")]
    Invalid {
        file: String,
        #[source]
        source: CameraError,
    },
    /// TOML or JSON (de)serialisation failed: `line` and `column` are 1-based (0 when
    /// unknown); `message` says what was expected, with quoted values removed.
    #[error("{file}{}: {message}", fmt_position(*line, *column))]
    Serde {
        file: String,
        line: usize,
        column: usize,
        message: String,
    },
    /// The file name does not say which format to use.
    #[error("{file}: unknown calibration format (use .yaml/.yml, .toml or .json)")]
    UnknownFormat { file: String },
}

impl CalibError {
    fn serde(file: &str, what: &str, e: Located) -> Self {
        Self::Serde {
            file: file.to_string(),
            line: e.line,
            column: e.column,
            message: format!("not a valid {what} calibration: {}", e.message),
        }
    }
}

/// Calibration file formats.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CalibFormat {
    /// OpenCV `FileStorage` YAML (`%YAML:1.0`).
    OpencvYaml,
    /// TOML serialisation of [`CameraModel`].
    Toml,
    /// JSON serialisation of [`CameraModel`].
    Json,
}

impl CalibFormat {
    /// The format for a path, by extension (`.yaml`, `.yml`, `.toml`, `.json`).
    pub fn from_path(path: &Path) -> Option<Self> {
        let ext = path.extension()?.to_str()?.to_ascii_lowercase();
        match ext.as_str() {
            "yaml" | "yml" => Some(Self::OpencvYaml),
            "toml" => Some(Self::Toml),
            "json" => Some(Self::Json),
            _ => None,
        }
    }
}

/// Reads a calibration file's text through [`pa_io`]: a regular file of at most
/// [`MAX_CALIBRATION_BYTES`] (a FIFO or a device is refused at once, not waited on).
fn read_calibration_text(path: &Path) -> Result<String, CalibError> {
    Ok(pa_io::read_to_string_regular(
        path,
        MAX_CALIBRATION_BYTES,
        "a calibration file",
    )?)
}

/// Loads a camera model from a calibration file; the format comes from the extension, or
/// from the content when the extension is unknown (`%YAML`, `{`, else TOML). Only a regular
/// file of at most [`MAX_CALIBRATION_BYTES`] is read.
pub fn load_calibration(path: impl AsRef<Path>) -> Result<CameraModel, CalibError> {
    let path = path.as_ref();
    let file = path.display().to_string();
    let text = read_calibration_text(path)?;
    let format = CalibFormat::from_path(path).unwrap_or_else(|| {
        let t = text.trim_start();
        if t.starts_with('%') || t.contains("!!opencv-matrix") {
            CalibFormat::OpencvYaml
        } else if t.starts_with('{') {
            CalibFormat::Json
        } else {
            CalibFormat::Toml
        }
    });
    parse_calibration(&text, format, &file)
}

/// Parses calibration text in the given format; `file` names the source in errors. The
/// camera is checked ([`CameraModel::validate`]): finite intrinsics and distortion, positive
/// focal lengths, a sane image size.
pub fn parse_calibration(
    text: &str,
    format: CalibFormat,
    file: &str,
) -> Result<CameraModel, CalibError> {
    let model: CameraModel = match format {
        CalibFormat::OpencvYaml => return from_opencv_yaml(text, file),
        CalibFormat::Toml => toml::from_str(text)
            .map_err(|e| CalibError::serde(file, "TOML", toml_error(text, &e, FIELDS)))?,
        CalibFormat::Json => serde_json::from_str(text)
            .map_err(|e| CalibError::serde(file, "JSON", json_error(&e, FIELDS)))?,
    };
    model.validate().map_err(|source| CalibError::Invalid {
        file: file.to_string(),
        source,
    })?;
    Ok(model)
}

/// Serialises a camera model in the given format.
pub fn format_calibration(
    model: &CameraModel,
    format: CalibFormat,
    file: &str,
) -> Result<String, CalibError> {
    let failed = |message: String| CalibError::Serde {
        file: file.to_string(),
        line: 0,
        column: 0,
        message,
    };
    match format {
        CalibFormat::OpencvYaml => Ok(to_opencv_yaml(model)),
        CalibFormat::Toml => toml::to_string_pretty(model).map_err(|e| failed(e.to_string())),
        CalibFormat::Json => serde_json::to_string_pretty(model).map_err(|e| failed(e.to_string())),
    }
}

/// Saves a camera model; the format comes from the extension. The file is written atomically
/// ([`pa_io::write_atomic`]): an existing file that is not a regular file is never replaced.
pub fn save_calibration(model: &CameraModel, path: impl AsRef<Path>) -> Result<(), CalibError> {
    let path = path.as_ref();
    let file = path.display().to_string();
    let format =
        CalibFormat::from_path(path).ok_or(CalibError::UnknownFormat { file: file.clone() })?;
    let text = format_calibration(model, format, &file)?;
    Ok(pa_io::write_atomic(path, text.as_bytes())?)
}
