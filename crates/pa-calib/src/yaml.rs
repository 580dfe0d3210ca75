//! OpenCV calibration YAML for a [`Calibration`]: `pa_camera::to_opencv_yaml`'s
//! `image_width`, `image_height`, `camera_matrix` and `distortion_coefficients` (what the
//! tracker reads), followed by the fields OpenCV's `calibration.cpp` sample writes:
//! `nr_of_frames`, `flags`, the chessboard's `board_width` (inner corners per row),
//! `board_height` and `square_size` (metres), `avg_reprojection_error` (px),
//! `per_view_reprojection_errors` (px) and `extrinsic_parameters` (one row per view: rotation
//! vector, translation in metres, `camera_from_board`).

use std::fmt::Write;

use crate::{Calibration, Target};

fn num(v: f64) -> String {
    if v.is_finite() {
        // Debug gives the shortest form that reads back exactly, always with '.' or 'e'.
        format!("{v:?}")
    } else if v.is_nan() {
        ".Nan".into()
    } else if v > 0.0 {
        ".Inf".into()
    } else {
        "-.Inf".into()
    }
}

fn matrix(s: &mut String, name: &str, rows: usize, cols: usize, data: &[f64]) {
    let _ = writeln!(s, "{name}: !!opencv-matrix");
    let _ = writeln!(s, "   rows: {rows}");
    let _ = writeln!(s, "   cols: {cols}");
    let _ = writeln!(s, "   dt: d");
    let mut line = String::from("   data: [ ");
    for (i, v) in data.iter().enumerate() {
        line.push_str(&num(*v));
        if i + 1 < data.len() {
            line.push_str(", ");
            if i % 6 == 5 {
                let _ = writeln!(s, "{}", line.trim_end());
                line = String::from("       ");
            }
        }
    }
    let _ = writeln!(s, "{line} ]");
}

/// The calibration as OpenCV `FileStorage` YAML (see the module docs). `target` adds the
/// chessboard's fields when it is a chessboard.
pub fn to_opencv_yaml(cal: &Calibration, target: Option<&Target>) -> String {
    let mut s = pa_camera::to_opencv_yaml(&cal.camera);
    let _ = writeln!(
        s,
        "# propsalive calibrate: {} views, {} points; k3 {}, tangential {}",
        cal.views.len(),
        cal.points(),
        if cal.options.fix_k3 {
            "fixed at 0"
        } else {
            "estimated"
        },
        if cal.options.fix_tangential {
            "fixed at 0"
        } else {
            "estimated"
        },
    );
    let _ = writeln!(s, "nr_of_frames: {}", cal.views.len());
    let _ = writeln!(s, "flags: {}", cal.options.opencv_flags());
    if let Some(Target::Chessboard { size, square_m }) = target {
        let _ = writeln!(s, "board_width: {}", size.cols);
        let _ = writeln!(s, "board_height: {}", size.rows);
        let _ = writeln!(s, "square_size: {}", num(*square_m));
    }
    let _ = writeln!(s, "avg_reprojection_error: {}", num(cal.rms_px));
    let errs: Vec<f64> = cal.views.iter().map(|v| v.rms_px).collect();
    matrix(&mut s, "per_view_reprojection_errors", errs.len(), 1, &errs);
    let ext: Vec<f64> = cal
        .views
        .iter()
        .flat_map(|v| {
            let (r, t) = (v.rotation_vector, v.translation_m);
            [r.x, r.y, r.z, t.x, t.y, t.z]
        })
        .collect();
    matrix(&mut s, "extrinsic_parameters", cal.views.len(), 6, &ext);
    s
}
