//! OpenCV calibration YAML: writing it, and reading the camera out of the parsed YAML.

use std::fmt::Write as _;
use std::path::Path;

use super::yaml::{parse_yaml, Node, Value};
use super::{read_calibration_text, CalibError};
use crate::{CameraModel, Distortion, Intrinsics};

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
