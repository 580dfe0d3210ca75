//! The text summary of a calibration that `propsalive calibrate` prints after solving: the
//! per-view RMS reprojection errors, the intrinsics and the distortion each with one standard
//! deviation (parameters the options fix say "(fixed)"), and the overall RMS error. Pure.

use std::fmt::Write as _;

use crate::{CalibOptions, Calibration};

/// The summary, one line per `\n` (the last line ends with one too). `options`: the options
/// the calibration was solved with (what was fixed).
pub fn summary(result: &Calibration, options: &CalibOptions) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "per-view RMS reprojection error (px):");
    for v in &result.views {
        let _ = writeln!(
            s,
            "  {}: {:.3} (max {:.3}) over {} corners",
            v.name, v.rms_px, v.max_px, v.points
        );
    }
    let (k, d, sd) = (
        result.camera.intrinsics,
        result.camera.distortion,
        result.std_dev,
    );
    let _ = writeln!(
        s,
        "camera {}x{} (value +- one standard deviation):",
        k.width, k.height
    );
    let _ = writeln!(
        s,
        "  fx = {:.3} +- {:.3} px, fy = {:.3} +- {:.3} px",
        k.fx, sd.fx, k.fy, sd.fy
    );
    let _ = writeln!(
        s,
        "  cx = {:.3} +- {:.3} px, cy = {:.3} +- {:.3} px",
        k.cx, sd.cx, k.cy, sd.cy
    );
    let fixed = |v: f64, sd: f64, is_fixed: bool| {
        if is_fixed {
            format!("{v} (fixed)")
        } else {
            format!("{v:.6} +- {sd:.6}")
        }
    };
    let _ = writeln!(
        s,
        "  distortion k1 = {}, k2 = {}",
        fixed(d.k1, sd.k1, false),
        fixed(d.k2, sd.k2, false)
    );
    let _ = writeln!(
        s,
        "             p1 = {}, p2 = {}, k3 = {}",
        fixed(d.p1, sd.p1, options.fix_tangential),
        fixed(d.p2, sd.p2, options.fix_tangential),
        fixed(d.k3, sd.k3, options.fix_k3)
    );
    let _ = writeln!(
        s,
        "RMS reprojection error: {:.4} px over {} corners in {} views ({} iterations)",
        result.rms_px,
        result.points(),
        result.views.len(),
        result.iterations
    );
    s
}

#[cfg(test)]
mod tests {
    use glam::DVec3;
    use pa_camera::{CameraModel, Distortion, Intrinsics};

    use super::*;
    use crate::{IntrinsicsStdDev, ViewResult};

    #[test]
    fn summary_is_pinned() {
        let view = |name: &str, rms_px: f64| ViewResult {
            name: name.into(),
            points: 54,
            rms_px,
            max_px: 2.0 * rms_px,
            rotation_vector: DVec3::ZERO,
            translation_m: DVec3::Z,
        };
        let options = CalibOptions::default();
        let result = Calibration {
            camera: CameraModel {
                intrinsics: Intrinsics {
                    fx: 800.12345,
                    fy: 801.5,
                    cx: 319.5,
                    cy: 239.25,
                    width: 640,
                    height: 480,
                },
                distortion: Distortion {
                    k1: -0.1234567,
                    k2: 0.05,
                    p1: 0.001,
                    p2: -0.002,
                    k3: 0.0,
                },
            },
            rms_px: 0.12345,
            views: vec![view("a.png", 0.1), view("b.png", 0.25)],
            std_dev: IntrinsicsStdDev {
                fx: 1.5,
                fy: 1.25,
                cx: 0.5,
                cy: 0.75,
                k1: 0.001,
                k2: 0.002,
                p1: 0.0001,
                p2: 0.0002,
                k3: 0.0,
            },
            options,
            iterations: 12,
            warnings: vec![],
        };
        assert_eq!(
            summary(&result, &options),
            "per-view RMS reprojection error (px):\n\
             \x20 a.png: 0.100 (max 0.200) over 54 corners\n\
             \x20 b.png: 0.250 (max 0.500) over 54 corners\n\
             camera 640x480 (value +- one standard deviation):\n\
             \x20 fx = 800.123 +- 1.500 px, fy = 801.500 +- 1.250 px\n\
             \x20 cx = 319.500 +- 0.500 px, cy = 239.250 +- 0.750 px\n\
             \x20 distortion k1 = -0.123457 +- 0.001000, k2 = 0.050000 +- 0.002000\n\
             \x20            p1 = 0.001000 +- 0.000100, p2 = -0.002000 +- 0.000200, k3 = 0 (fixed)\n\
             RMS reprojection error: 0.1235 px over 108 corners in 2 views (12 iterations)\n"
        );
    }
}
