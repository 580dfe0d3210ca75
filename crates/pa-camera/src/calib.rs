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

use std::fmt::Write as _;
use std::path::Path;

use crate::diag::{fmt_position, json_error, toml_error, Located};
use crate::{CameraError, CameraModel, Distortion, Intrinsics};

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

/// Writes the model as OpenCV calibration YAML (readable by `cv::FileStorage`).
/// Numbers are written in the shortest form that reads back exactly.
pub fn to_opencv_yaml(model: &CameraModel) -> String {
    let k = &model.intrinsics;
    let d = &model.distortion;
    let mut s = String::from("%YAML:1.0\n---\n");
    let _ = writeln!(s, "image_width: {}", k.width);
    let _ = writeln!(s, "image_height: {}", k.height);
    let mat = |s: &mut String, name: &str, rows: usize, cols: usize, data: &[f64]| {
        let _ = writeln!(s, "{name}: !!opencv-matrix");
        let _ = writeln!(s, "   rows: {rows}");
        let _ = writeln!(s, "   cols: {cols}");
        let _ = writeln!(s, "   dt: d");
        let items: Vec<String> = data.iter().map(|v| fmt_f64(*v)).collect();
        let mut line = String::from("   data: [ ");
        for (i, it) in items.iter().enumerate() {
            line.push_str(it);
            if i + 1 < items.len() {
                line.push_str(", ");
                if i % 4 == 3 {
                    let _ = writeln!(s, "{}", line.trim_end());
                    line = String::from("       ");
                }
            }
        }
        let _ = writeln!(s, "{line} ]");
    };
    mat(
        &mut s,
        "camera_matrix",
        3,
        3,
        &[k.fx, 0.0, k.cx, 0.0, k.fy, k.cy, 0.0, 0.0, 1.0],
    );
    mat(
        &mut s,
        "distortion_coefficients",
        5,
        1,
        &[d.k1, d.k2, d.p1, d.p2, d.k3],
    );
    s
}

fn fmt_f64(v: f64) -> String {
    if v.is_nan() {
        ".Nan".into()
    } else if v.is_infinite() {
        if v > 0.0 { ".Inf" } else { "-.Inf" }.into()
    } else {
        // Debug gives the shortest round-trip form and always a '.' or an exponent.
        format!("{v:?}")
    }
}

/// Loads an OpenCV calibration YAML file (a regular file of at most
/// [`MAX_CALIBRATION_BYTES`]).
pub fn load_opencv_yaml(path: impl AsRef<Path>) -> Result<CameraModel, CalibError> {
    let path = path.as_ref();
    let text = read_calibration_text(path)?;
    from_opencv_yaml(&text, &path.display().to_string())
}

/// Saves a camera model as OpenCV calibration YAML, atomically ([`pa_io::write_atomic`]).
pub fn save_opencv_yaml(model: &CameraModel, path: impl AsRef<Path>) -> Result<(), CalibError> {
    Ok(pa_io::write_atomic(
        path.as_ref(),
        to_opencv_yaml(model).as_bytes(),
    )?)
}

/// Parses OpenCV calibration YAML text; `file` names the source in errors.
pub fn from_opencv_yaml(text: &str, file: &str) -> Result<CameraModel, CalibError> {
    let root = parse_yaml(text, file)?;
    let f = || file.to_string();
    let get = |names: &[&str]| -> Option<&Node> { names.iter().find_map(|n| root.get(n)) };

    let km = get(&["camera_matrix", "cameraMatrix", "K"]).ok_or(CalibError::MissingField {
        file: f(),
        field: "camera_matrix",
    })?;
    let (rows, cols, kd) = matrix(km, "camera_matrix", file)?;
    if rows != 3 || cols != 3 {
        return Err(CalibError::WrongSize {
            file: f(),
            field: "camera_matrix".into(),
            found: format!("{rows}x{cols}"),
            expected: "3x3",
        });
    }
    finite(&kd, "camera_matrix", km.line, file)?;
    let scale = kd[8];
    if (kd[6].abs() > 1e-12) || (kd[7].abs() > 1e-12) || (scale - 1.0).abs() > 1e-9 {
        return Err(CalibError::Unsupported {
            file: f(),
            message: format!(
                "camera_matrix last row is [{}, {}, {}], expected [0, 0, 1]",
                kd[6], kd[7], kd[8]
            ),
        });
    }
    if kd[3].abs() > 1e-12 {
        return Err(CalibError::Unsupported {
            file: f(),
            message: format!("camera_matrix[1][0] = {} (expected 0)", kd[3]),
        });
    }
    if kd[1].abs() > 1e-9 * kd[0].abs().max(1.0) {
        return Err(CalibError::Unsupported {
            file: f(),
            message: format!("skew camera_matrix[0][1] = {} is not modelled", kd[1]),
        });
    }

    let mut dist = Distortion::default();
    if let Some(dn) = get(&["distortion_coefficients", "dist_coeffs", "distCoeffs", "D"]) {
        let (r, c, dd) = matrix(dn, "distortion_coefficients", file)?;
        finite(&dd, "distortion_coefficients", dn.line, file)?;
        let n = dd.len();
        if !(r == 1 || c == 1) || ![4usize, 5, 8, 12, 14].contains(&n) {
            return Err(CalibError::WrongSize {
                file: f(),
                field: "distortion_coefficients".into(),
                found: format!("{r}x{c}"),
                expected: "a 1xN or Nx1 vector, N in {4, 5, 8, 12, 14}",
            });
        }
        if let Some(extra) = dd.iter().skip(5).find(|v| **v != 0.0) {
            return Err(CalibError::Unsupported {
                file: f(),
                message: format!(
                    "distortion term beyond k3 is {extra} (rational/thin-prism/tilt models are \
                     not supported)"
                ),
            });
        }
        let at = |i: usize| dd.get(i).copied().unwrap_or(0.0);
        dist = Distortion {
            k1: at(0),
            k2: at(1),
            p1: at(2),
            p2: at(3),
            k3: at(4),
        };
    }

    let (width, height) = match (root.get("image_width"), root.get("image_height")) {
        (Some(w), Some(h)) => (
            integer(w, "image_width", file)?,
            integer(h, "image_height", file)?,
        ),
        (w, h) => {
            if let Some(res) = root.get("cameraResolution") {
                let v = numbers(res, "cameraResolution", file)?;
                if v.len() != 2 {
                    return Err(CalibError::WrongSize {
                        file: f(),
                        field: "cameraResolution".into(),
                        found: format!("{} values", v.len()),
                        expected: "[width, height]",
                    });
                }
                (
                    to_u32(v[0], "cameraResolution", res.line, file)?,
                    to_u32(v[1], "cameraResolution", res.line, file)?,
                )
            } else {
                return Err(CalibError::MissingField {
                    file: f(),
                    field: if w.is_none() {
                        "image_width"
                    } else {
                        debug_assert!(h.is_none());
                        "image_height"
                    },
                });
            }
        }
    };

    let intrinsics = Intrinsics {
        fx: kd[0],
        fy: kd[4],
        cx: kd[2],
        cy: kd[5],
        width,
        height,
    };
    let model = CameraModel {
        intrinsics,
        distortion: dist,
    };
    model
        .validate()
        .map_err(|source| CalibError::Invalid { file: f(), source })?;
    Ok(model)
}

/// Fails naming the first element of `values` (a matrix's data, row-major) that is NaN or
/// infinite.
fn finite(values: &[f64], field: &str, line: usize, file: &str) -> Result<(), CalibError> {
    match values.iter().position(|v| !v.is_finite()) {
        Some(i) => Err(CalibError::NotFinite {
            file: file.into(),
            field: format!("{field}.data[{i}]"),
            line,
        }),
        None => Ok(()),
    }
}

fn to_u32(v: f64, field: &str, line: usize, file: &str) -> Result<u32, CalibError> {
    if v.fract() == 0.0 && v >= 0.0 && v <= u32::MAX as f64 {
        Ok(v as u32)
    } else {
        Err(CalibError::NonNumeric {
            file: file.into(),
            field: field.into(),
            line,
            found: "a number that is not a pixel count",
        })
    }
}

/// What a node holds, for errors that must not repeat the file's text.
fn kind(v: &Value) -> &'static str {
    match v {
        Value::Scalar(_) => "text",
        Value::Seq(_) => "a sequence",
        Value::Map(_) => "a mapping",
    }
}

fn integer(n: &Node, field: &str, file: &str) -> Result<u32, CalibError> {
    let bad = |found| CalibError::NonNumeric {
        file: file.into(),
        field: field.into(),
        line: n.line,
        found,
    };
    match &n.value {
        Value::Scalar(s) => s
            .trim()
            .parse::<u32>()
            .map_err(|_| bad("text that is not a whole number in 0..=4294967295")),
        v => Err(bad(kind(v))),
    }
}

fn number(s: &str, field: &str, line: usize, file: &str) -> Result<f64, CalibError> {
    let t = s.trim();
    let v = match t {
        ".Inf" | ".inf" | "+.Inf" => Some(f64::INFINITY),
        "-.Inf" | "-.inf" => Some(f64::NEG_INFINITY),
        ".NaN" | ".nan" | ".Nan" => Some(f64::NAN),
        _ => t.parse::<f64>().ok(),
    };
    v.ok_or_else(|| CalibError::NonNumeric {
        file: file.into(),
        field: field.into(),
        line,
        found: "text",
    })
}

fn numbers(n: &Node, field: &str, file: &str) -> Result<Vec<f64>, CalibError> {
    match &n.value {
        Value::Seq(items) => items
            .iter()
            .map(|it| match &it.value {
                Value::Scalar(s) => number(s, field, it.line, file),
                v => Err(CalibError::NonNumeric {
                    file: file.into(),
                    field: field.into(),
                    line: it.line,
                    found: kind(v),
                }),
            })
            .collect(),
        v => Err(CalibError::NonNumeric {
            file: file.into(),
            field: field.into(),
            line: n.line,
            found: kind(v),
        }),
    }
}

/// A matrix node: `!!opencv-matrix` (or an untagged mapping) with rows, cols, data, or a
/// plain sequence (taken as a column vector).
fn matrix(n: &Node, field: &str, file: &str) -> Result<(usize, usize, Vec<f64>), CalibError> {
    match &n.value {
        Value::Map(_) => {
            let sub = |k: &str| -> Result<&Node, CalibError> {
                n.get(k).ok_or_else(|| CalibError::Syntax {
                    file: file.into(),
                    line: n.line,
                    message: format!("`{field}` has no `{k}`"),
                })
            };
            let rows = integer(sub("rows")?, &format!("{field}.rows"), file)? as usize;
            let cols = integer(sub("cols")?, &format!("{field}.cols"), file)? as usize;
            let data = numbers(sub("data")?, &format!("{field}.data"), file)?;
            if rows.checked_mul(cols) != Some(data.len()) {
                return Err(CalibError::WrongSize {
                    file: file.into(),
                    field: field.into(),
                    found: format!("{rows}x{cols} with {} values", data.len()),
                    expected: "rows*cols values",
                });
            }
            Ok((rows, cols, data))
        }
        _ => {
            let data = numbers(n, field, file)?;
            let len = data.len();
            if field == "camera_matrix" && len == 9 {
                Ok((3, 3, data))
            } else {
                Ok((len, 1, data))
            }
        }
    }
}

// ---------------------------------------------------------------------------------------
// A minimal YAML-subset parser.

#[derive(Debug, Clone)]
struct Node {
    line: usize,
    value: Value,
}

#[derive(Debug, Clone)]
enum Value {
    Scalar(String),
    Seq(Vec<Node>),
    Map(Vec<(String, Node)>),
}

impl Node {
    fn get(&self, key: &str) -> Option<&Node> {
        match &self.value {
            Value::Map(entries) => entries.iter().find(|(k, _)| k == key).map(|(_, v)| v),
            _ => None,
        }
    }
}

struct Line<'a> {
    number: usize,
    indent: usize,
    text: &'a str,
}

/// Removes a `#` comment (outside quotes).
fn strip_comment(s: &str) -> &str {
    let mut in_single = false;
    let mut in_double = false;
    let mut prev_space = true;
    for (i, c) in s.char_indices() {
        match c {
            '\'' if !in_double => in_single = !in_single,
            '"' if !in_single => in_double = !in_double,
            '#' if !in_single && !in_double && prev_space => return &s[..i],
            _ => {}
        }
        prev_space = c.is_whitespace() || c == ',' || c == '[' || c == '{';
    }
    s
}

fn parse_yaml(text: &str, file: &str) -> Result<Node, CalibError> {
    let mut lines = Vec::new();
    for (i, raw) in text.lines().enumerate() {
        let raw = raw.trim_end_matches('\r');
        let t = raw.trim_start();
        if t.starts_with('%') || t == "---" || t == "..." || t.starts_with("--- ") {
            continue;
        }
        let no_comment = strip_comment(raw).trim_end();
        if no_comment.trim().is_empty() {
            continue;
        }
        if raw.starts_with('\t') {
            return Err(CalibError::Syntax {
                file: file.into(),
                line: i + 1,
                message: "tab indentation is not allowed in YAML".into(),
            });
        }
        let indent = no_comment.len() - no_comment.trim_start().len();
        if lines.len() >= MAX_NODES {
            return Err(CalibError::Syntax {
                file: file.into(),
                line: i + 1,
                message: format!("more than {MAX_NODES} lines with values"),
            });
        }
        lines.push(Line {
            number: i + 1,
            indent,
            text: no_comment.trim_start(),
        });
    }
    let mut p = Parser {
        lines,
        pos: 0,
        file,
        depth: 0,
        nodes: 0,
    };
    if p.lines.is_empty() {
        return Ok(Node {
            line: 1,
            value: Value::Map(Vec::new()),
        });
    }
    let indent = p.lines[0].indent;
    let node = p.block(indent)?;
    if p.pos < p.lines.len() {
        return Err(p.err(p.lines[p.pos].number, "unexpected indentation"));
    }
    Ok(node)
}

/// A recursive-descent parser over the lines. Recursion (blocks nested by indentation, flow
/// collections nested by brackets) is bounded by [`MAX_NESTING`] and the values made by
/// [`MAX_NODES`], so no input overflows the stack or amplifies into gigabytes.
struct Parser<'a> {
    lines: Vec<Line<'a>>,
    pos: usize,
    file: &'a str,
    /// Blocks and flow collections open now.
    depth: usize,
    /// Values made so far.
    nodes: usize,
}

impl<'a> Parser<'a> {
    fn err(&self, line: usize, message: impl Into<String>) -> CalibError {
        CalibError::Syntax {
            file: self.file.into(),
            line,
            message: message.into(),
        }
    }

    /// Enters a block or flow collection opened on `line`; pair with [`Parser::leave`].
    fn enter(&mut self, line: usize) -> Result<(), CalibError> {
        if self.depth >= MAX_NESTING {
            return Err(self.err(line, format!("nested deeper than {MAX_NESTING} levels")));
        }
        self.depth += 1;
        Ok(())
    }

    fn leave(&mut self) {
        self.depth -= 1;
    }

    /// Counts a new value made on `line`.
    fn count(&mut self, line: usize) -> Result<(), CalibError> {
        self.nodes += 1;
        if self.nodes > MAX_NODES {
            return Err(self.err(line, format!("more than {MAX_NODES} values")));
        }
        Ok(())
    }

    /// Parses a block (mapping or sequence) whose lines have exactly `indent`.
    fn block(&mut self, indent: usize) -> Result<Node, CalibError> {
        let line = self.lines[self.pos].number;
        self.enter(line)?;
        let node = self.block_inner(indent);
        self.leave();
        node
    }

    fn block_inner(&mut self, indent: usize) -> Result<Node, CalibError> {
        self.count(self.lines[self.pos].number)?;
        let first = &self.lines[self.pos];
        let line = first.number;
        if first.text.starts_with("- ") || first.text == "-" {
            let mut items = Vec::new();
            while self.pos < self.lines.len() && self.lines[self.pos].indent == indent {
                let l = &self.lines[self.pos];
                let Some(rest) = l.text.strip_prefix('-') else {
                    return Err(self.err(l.number, "expected `- ` sequence item"));
                };
                let rest = rest.trim();
                let number = l.number;
                self.pos += 1;
                if rest.is_empty() {
                    items.push(self.nested(indent, number)?);
                } else {
                    items.push(self.inline_value(rest, number)?);
                }
            }
            return Ok(Node {
                line,
                value: Value::Seq(items),
            });
        }
        let mut entries = Vec::new();
        while self.pos < self.lines.len() && self.lines[self.pos].indent == indent {
            let l = &self.lines[self.pos];
            let number = l.number;
            // The line is not repeated: the file may not be ours.
            let (key, rest) = split_key(l.text)
                .ok_or_else(|| self.err(number, "expected `key: value` (a colon and a space)"))?;
            self.pos += 1;
            let mut rest = rest.trim();
            // Tags such as `!!opencv-matrix` or `!<tag:yaml.org,2002:opencv-matrix>`.
            if rest.starts_with('!') {
                rest = rest
                    .split_once(char::is_whitespace)
                    .map(|(_, r)| r.trim())
                    .unwrap_or("");
            }
            let value = if rest.is_empty() {
                self.nested(indent, number)?
            } else {
                self.inline_value(rest, number)?
            };
            entries.push((key, value));
        }
        Ok(Node {
            line,
            value: Value::Map(entries),
        })
    }

    /// The block nested under a key at `indent`, or an empty scalar.
    fn nested(&mut self, indent: usize, line: usize) -> Result<Node, CalibError> {
        if self.pos < self.lines.len() && self.lines[self.pos].indent > indent {
            let ind = self.lines[self.pos].indent;
            self.block(ind)
        } else {
            self.count(line)?;
            Ok(Node {
                line,
                value: Value::Scalar(String::new()),
            })
        }
    }

    /// A value that starts on the key's line; flow collections may continue on later lines.
    fn inline_value(&mut self, rest: &str, line: usize) -> Result<Node, CalibError> {
        if rest.starts_with('[') || rest.starts_with('{') {
            let mut text = rest.to_string();
            // Scanned once, piece by piece: rescanning the whole text for each added line
            // would be quadratic in the file's size.
            let mut balance = FlowBalance::default();
            balance.feed(rest);
            while !balance.closed() {
                if self.pos >= self.lines.len() {
                    return Err(self.err(line, "unterminated flow collection (missing `]` or `}`)"));
                }
                let next = self.lines[self.pos].text;
                text.push(' ');
                text.push_str(next);
                balance.feed(" ");
                balance.feed(next);
                self.pos += 1;
            }
            let chars: Vec<char> = text.chars().collect();
            let mut i = 0;
            let node = self.flow(&chars, &mut i, line)?;
            skip_ws(&chars, &mut i);
            if i < chars.len() {
                return Err(self.err(line, "unexpected text after flow collection"));
            }
            Ok(node)
        } else {
            self.count(line)?;
            Ok(Node {
                line,
                value: Value::Scalar(unquote(rest)),
            })
        }
    }

    /// A flow value at `c[*i]`: a sequence, a mapping or a scalar.
    fn flow(&mut self, c: &[char], i: &mut usize, line: usize) -> Result<Node, CalibError> {
        skip_ws(c, i);
        match c.get(*i) {
            Some('[' | '{') => {
                self.enter(line)?;
                let node = self.flow_collection(c, i, line);
                self.leave();
                node
            }
            Some(']' | '}') => {
                Err(self.err(line, "a flow collection closes where a value was expected"))
            }
            Some(_) => {
                self.count(line)?;
                Ok(Node {
                    line,
                    value: Value::Scalar(self.flow_scalar(c, i, false)),
                })
            }
            None => Err(self.err(line, "missing value")),
        }
    }

    /// The sequence or mapping opening at `c[*i]`.
    fn flow_collection(
        &mut self,
        c: &[char],
        i: &mut usize,
        line: usize,
    ) -> Result<Node, CalibError> {
        self.count(line)?;
        let open = c[*i];
        *i += 1;
        if open == '[' {
            let mut items = Vec::new();
            loop {
                skip_ws(c, i);
                match c.get(*i) {
                    Some(']') => {
                        *i += 1;
                        break;
                    }
                    Some(',') => {
                        *i += 1;
                    }
                    Some('}') => return Err(self.err(line, "`}` closes a `[` sequence")),
                    Some(_) => items.push(self.flow(c, i, line)?),
                    None => return Err(self.err(line, "missing `]`")),
                }
            }
            return Ok(Node {
                line,
                value: Value::Seq(items),
            });
        }
        let mut entries = Vec::new();
        loop {
            skip_ws(c, i);
            match c.get(*i) {
                Some('}') => {
                    *i += 1;
                    break;
                }
                Some(',') => {
                    *i += 1;
                }
                Some(']') => return Err(self.err(line, "`]` closes a `{` mapping")),
                Some(_) => {
                    let key = self.flow_scalar(c, i, true);
                    skip_ws(c, i);
                    if c.get(*i) != Some(&':') {
                        return Err(self.err(line, "expected `:` in flow mapping"));
                    }
                    *i += 1;
                    skip_ws(c, i);
                    if c.get(*i) == Some(&'!') {
                        while *i < c.len() && !c[*i].is_whitespace() {
                            *i += 1;
                        }
                    }
                    // An empty value (`{a: }`, `{a: ,b: 1}`) is an empty scalar.
                    let v = match c.get(*i) {
                        Some('}' | ',') => {
                            self.count(line)?;
                            Node {
                                line,
                                value: Value::Scalar(String::new()),
                            }
                        }
                        _ => self.flow(c, i, line)?,
                    };
                    entries.push((key, v));
                }
                None => return Err(self.err(line, "missing `}`")),
            }
        }
        Ok(Node {
            line,
            value: Value::Map(entries),
        })
    }

    fn flow_scalar(&self, c: &[char], i: &mut usize, is_key: bool) -> String {
        skip_ws(c, i);
        if let Some(&q) = c.get(*i).filter(|q| **q == '"' || **q == '\'') {
            *i += 1;
            let mut s = String::new();
            while *i < c.len() && c[*i] != q {
                s.push(c[*i]);
                *i += 1;
            }
            *i += 1;
            return s;
        }
        let mut s = String::new();
        while *i < c.len() {
            let ch = c[*i];
            if ch == ',' || ch == ']' || ch == '}' || (is_key && ch == ':') {
                break;
            }
            s.push(ch);
            *i += 1;
        }
        s.trim().to_string()
    }
}

fn skip_ws(c: &[char], i: &mut usize) {
    while *i < c.len() && c[*i].is_whitespace() {
        *i += 1;
    }
}

/// Whether the brackets of a flow collection, fed piece by piece, are closed (quotes
/// respected).
#[derive(Default)]
struct FlowBalance {
    depth: i64,
    quote: Option<char>,
}

impl FlowBalance {
    fn feed(&mut self, s: &str) {
        for ch in s.chars() {
            match self.quote {
                Some(q) if ch == q => self.quote = None,
                Some(_) => {}
                None => match ch {
                    '"' | '\'' => self.quote = Some(ch),
                    '[' | '{' => self.depth += 1,
                    ']' | '}' => self.depth -= 1,
                    _ => {}
                },
            }
        }
    }

    fn closed(&self) -> bool {
        self.depth <= 0
    }
}

/// Splits `key: rest` (the colon must be followed by whitespace or end the line).
fn split_key(text: &str) -> Option<(String, &str)> {
    let (key, rest) = if let Some(q) = text.chars().next().filter(|c| *c == '"' || *c == '\'') {
        let end = text[1..].find(q)? + 1;
        let key = text[1..end].to_string();
        let after = text[end + 1..].trim_start();
        (key, after.strip_prefix(':')?)
    } else {
        let mut idx = None;
        for (i, ch) in text.char_indices() {
            if ch == ':' {
                let next = text[i + 1..].chars().next();
                if next.is_none() || next.is_some_and(char::is_whitespace) {
                    idx = Some(i);
                    break;
                }
            }
        }
        let i = idx?;
        (text[..i].trim().to_string(), &text[i + 1..])
    };
    if key.is_empty() {
        return None;
    }
    Some((key, rest))
}

fn unquote(s: &str) -> String {
    let t = s.trim();
    if t.len() >= 2
        && ((t.starts_with('"') && t.ends_with('"')) || (t.starts_with('\'') && t.ends_with('\'')))
    {
        t[1..t.len() - 1].to_string()
    } else {
        t.to_string()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// As written by OpenCV 4's `calibrateCamera` sample (`calibration.cpp`), abridged.
    const OPENCV_SAMPLE: &str = r#"%YAML:1.0
---
calibration_time: "Mon 22 Jan 2024 10:11:12 AM CET"
nr_of_frames: 25
image_width: 1280
image_height: 720
board_width: 9
board_height: 6
square_size: 2.5000000372529030e-02
# flags:  +fix_principal_point +zero_tangent_dist
flags: 12
camera_matrix: !!opencv-matrix
   rows: 3
   cols: 3
   dt: d
   data: [ 9.1556072719327040e+02, 0., 6.4026410578793567e+02, 0.,
       9.1429342327341998e+02, 3.5729108937919355e+02, 0., 0., 1. ]
distortion_coefficients: !!opencv-matrix
   rows: 5
   cols: 1
   dt: d
   data: [ 1.1580118323040527e-01, -2.0795383813316446e-01,
       -1.2342e-03, 5.1e-04, -4.8005366072463378e-01 ]
avg_reprojection_error: 3.9231004394962567e-01
per_view_reprojection_errors: !!opencv-matrix
   rows: 3
   cols: 1
   dt: f
   data: [ 3.53928119e-01, 4.17041391e-01, 3.99213135e-01 ]
extrinsic_parameters: !!opencv-matrix
   rows: 2
   cols: 6
   dt: d
   data: [ -6.9e-02, 1.2e-01, 1.5, -1.0e-01, -5.2e-02, 4.2e-01,
       -6.9e-02, 1.2e-01, 1.5, -1.0e-01, -5.2e-02, 4.2e-01 ]
"#;

    // The literals are copied from the OpenCV-written text on purpose.
    #[allow(clippy::excessive_precision)]
    fn sample_model() -> CameraModel {
        CameraModel {
            intrinsics: Intrinsics {
                fx: 915.5607271932704,
                fy: 914.29342327341998,
                cx: 640.26410578793567,
                cy: 357.29108937919355,
                width: 1280,
                height: 720,
            },
            distortion: Distortion {
                k1: 0.11580118323040527,
                k2: -0.20795383813316446,
                p1: -1.2342e-03,
                p2: 5.1e-04,
                k3: -0.48005366072463378,
            },
        }
    }

    #[test]
    fn reads_opencv_written_sample() {
        let m = from_opencv_yaml(OPENCV_SAMPLE, "calib.yaml").expect("parses");
        assert_eq!(m, sample_model());
    }

    #[test]
    fn opencv_yaml_round_trip_is_exact() {
        let m = sample_model();
        let text = to_opencv_yaml(&m);
        assert!(text.starts_with("%YAML:1.0\n---\n"));
        assert!(text.contains("camera_matrix: !!opencv-matrix"));
        let back = from_opencv_yaml(&text, "mem").expect("parses");
        assert_eq!(back, m);
        // Also zero distortion and odd values.
        let mut m2 = m;
        m2.distortion = Distortion::default();
        m2.intrinsics.fx = 1e-3;
        m2.intrinsics.cx = -12.25;
        let back = from_opencv_yaml(&to_opencv_yaml(&m2), "mem").expect("parses");
        assert_eq!(back, m2);
    }

    #[test]
    fn distortion_vector_shapes() {
        let base = |dist: &str| {
            format!(
                "%YAML:1.0\nimage_width: 640\nimage_height: 480\ncamera_matrix: !!opencv-matrix\n   \
                 rows: 3\n   cols: 3\n   dt: d\n   data: [ 500., 0., 319.5, 0., 500., 239.5, 0., 0., 1. ]\n{dist}"
            )
        };
        let cases = [
            ("rows: 1\n   cols: 4\n   dt: d\n   data: [ 0.1, -0.2, 0.01, 0.02 ]", [0.1, -0.2, 0.01, 0.02, 0.0]),
            ("rows: 1\n   cols: 5\n   dt: d\n   data: [ 0.1, -0.2, 0.01, 0.02, 0.3 ]", [0.1, -0.2, 0.01, 0.02, 0.3]),
            ("rows: 5\n   cols: 1\n   dt: d\n   data: [ 0.1, -0.2,\n  0.01, 0.02,\n 0.3 ]", [0.1, -0.2, 0.01, 0.02, 0.3]),
            ("rows: 1\n   cols: 8\n   dt: d\n   data: [ 0.1, -0.2, 0.01, 0.02, 0.3, 0., 0., 0. ]", [0.1, -0.2, 0.01, 0.02, 0.3]),
        ];
        for (d, want) in cases {
            let text = base(&format!(
                "distortion_coefficients: !!opencv-matrix\n   {d}\n"
            ));
            let m = from_opencv_yaml(&text, "d.yaml").unwrap_or_else(|e| panic!("{e}\n{text}"));
            let got = [
                m.distortion.k1,
                m.distortion.k2,
                m.distortion.p1,
                m.distortion.p2,
                m.distortion.k3,
            ];
            assert_eq!(got, want);
        }
        // No distortion entry at all: zero distortion.
        let m = from_opencv_yaml(&base(""), "d.yaml").expect("parses");
        assert!(m.distortion.is_zero());
        assert_eq!(m.intrinsics.cx, 319.5);
    }

    #[test]
    fn ros_style_untagged_matrices() {
        let text = "image_width: 640\nimage_height: 480\ncamera_name: cam\ncamera_matrix:\n  rows: 3\n  cols: 3\n  data: [500.0, 0.0, 320.0, 0.0, 510.0, 240.0, 0.0, 0.0, 1.0]\ndistortion_model: plumb_bob\ndistortion_coefficients:\n  rows: 1\n  cols: 5\n  data: [-0.1, 0.01, 0.0, 0.0, 0.0]\n";
        let m = from_opencv_yaml(text, "ros.yaml").expect("parses");
        assert_eq!(m.intrinsics.fy, 510.0);
        assert_eq!(m.distortion.k1, -0.1);
    }

    #[test]
    fn errors_name_file_and_problem() {
        let no_k = "%YAML:1.0\nimage_width: 640\nimage_height: 480\n";
        let e = from_opencv_yaml(no_k, "a.yaml").unwrap_err();
        assert!(
            matches!(
                e,
                CalibError::MissingField {
                    field: "camera_matrix",
                    ..
                }
            ),
            "{e}"
        );
        assert!(e.to_string().contains("a.yaml") && e.to_string().contains("camera_matrix"));

        let bad_size = "image_width: 640\nimage_height: 480\ncamera_matrix: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n   data: [ 1., 2., 3. ]\n";
        let e = from_opencv_yaml(bad_size, "b.yaml").unwrap_err();
        assert!(matches!(e, CalibError::WrongSize { .. }), "{e}");
        assert!(e.to_string().starts_with("b.yaml"));

        let two_by_two = "image_width: 640\nimage_height: 480\ncamera_matrix: !!opencv-matrix\n   rows: 2\n   cols: 2\n   dt: d\n   data: [ 1., 2., 3., 4. ]\n";
        let e = from_opencv_yaml(two_by_two, "b2.yaml").unwrap_err();
        assert!(matches!(e, CalibError::WrongSize { .. }), "{e}");

        let nan = "image_width: 640\nimage_height: 480\ncamera_matrix: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n   data: [ 500., 0., abc, 0., 500., 240., 0., 0., 1. ]\n";
        let e = from_opencv_yaml(nan, "c.yaml").unwrap_err();
        match &e {
            CalibError::NonNumeric { found, line, .. } => {
                assert_eq!(*found, "text");
                assert_eq!(*line, 7);
            }
            other => panic!("unexpected {other}"),
        }
        assert!(e.to_string().contains("c.yaml"));
        assert!(!e.to_string().contains("abc"), "{e}");

        let no_w =
            "image_height: 480\ncamera_matrix: [500., 0., 320., 0., 500., 240., 0., 0., 1.]\n";
        let e = from_opencv_yaml(no_w, "d.yaml").unwrap_err();
        assert!(
            matches!(
                e,
                CalibError::MissingField {
                    field: "image_width",
                    ..
                }
            ),
            "{e}"
        );

        let bad_w = "image_width: wide\nimage_height: 480\ncamera_matrix: [500., 0., 320., 0., 500., 240., 0., 0., 1.]\n";
        let e = from_opencv_yaml(bad_w, "e.yaml").unwrap_err();
        assert!(matches!(e, CalibError::NonNumeric { .. }), "{e}");

        let unterminated =
            "camera_matrix: !!opencv-matrix\n   rows: 3\n   cols: 3\n   data: [ 1., 2.,\n";
        let e = from_opencv_yaml(unterminated, "f.yaml").unwrap_err();
        assert!(matches!(e, CalibError::Syntax { .. }), "{e}");

        let dist_bad = "image_width: 640\nimage_height: 480\ncamera_matrix: [500., 0., 320., 0., 500., 240., 0., 0., 1.]\ndistortion_coefficients: !!opencv-matrix\n   rows: 2\n   cols: 3\n   dt: d\n   data: [ 0., 0., 0., 0., 0., 0. ]\n";
        let e = from_opencv_yaml(dist_bad, "g.yaml").unwrap_err();
        assert!(matches!(e, CalibError::WrongSize { .. }), "{e}");

        let neg_f = "image_width: 640\nimage_height: 480\ncamera_matrix: [-500., 0., 320., 0., 500., 240., 0., 0., 1.]\n";
        let e = from_opencv_yaml(neg_f, "h.yaml").unwrap_err();
        assert!(matches!(e, CalibError::Invalid { .. }), "{e}");
    }

    #[test]
    fn toml_and_json_round_trip_and_files() {
        let m = sample_model();
        for fmt in [
            CalibFormat::Toml,
            CalibFormat::Json,
            CalibFormat::OpencvYaml,
        ] {
            let text = format_calibration(&m, fmt, "mem").expect("formats");
            let back = parse_calibration(&text, fmt, "mem").expect("parses");
            assert_eq!(back, m, "{fmt:?}\n{text}");
        }
        let dir = std::env::temp_dir().join(format!("pa-camera-calib-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("temp dir");
        for name in ["c.yaml", "c.yml", "c.toml", "c.json"] {
            let p = dir.join(name);
            save_calibration(&m, &p).expect("saves");
            assert_eq!(load_calibration(&p).expect("loads"), m, "{name}");
        }
        let e = save_calibration(&m, dir.join("c.txt")).unwrap_err();
        assert!(matches!(e, CalibError::UnknownFormat { .. }));
        let e = load_calibration(dir.join("missing.yaml")).unwrap_err();
        assert!(matches!(e, CalibError::Io(_)) && e.to_string().contains("missing.yaml"));
        let _ = std::fs::remove_dir_all(&dir);
    }
}
