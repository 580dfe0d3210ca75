//! Tests of calibration files: OpenCV YAML, TOML and JSON.

use super::*;
use crate::{Distortion, Intrinsics};

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
        (
            "rows: 1\n   cols: 4\n   dt: d\n   data: [ 0.1, -0.2, 0.01, 0.02 ]",
            [0.1, -0.2, 0.01, 0.02, 0.0],
        ),
        (
            "rows: 1\n   cols: 5\n   dt: d\n   data: [ 0.1, -0.2, 0.01, 0.02, 0.3 ]",
            [0.1, -0.2, 0.01, 0.02, 0.3],
        ),
        (
            "rows: 5\n   cols: 1\n   dt: d\n   data: [ 0.1, -0.2,\n  0.01, 0.02,\n 0.3 ]",
            [0.1, -0.2, 0.01, 0.02, 0.3],
        ),
        (
            "rows: 1\n   cols: 8\n   dt: d\n   data: [ 0.1, -0.2, 0.01, 0.02, 0.3, 0., 0., 0. ]",
            [0.1, -0.2, 0.01, 0.02, 0.3],
        ),
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

    let no_w = "image_height: 480\ncamera_matrix: [500., 0., 320., 0., 500., 240., 0., 0., 1.]\n";
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
    let tmp = tempfile::Builder::new()
        .prefix("pa-camera-calib-")
        .tempdir()
        .expect("temp dir");
    let dir = tmp.path();
    for name in ["c.yaml", "c.yml", "c.toml", "c.json"] {
        let p = dir.join(name);
        save_calibration(&m, &p).expect("saves");
        assert_eq!(load_calibration(&p).expect("loads"), m, "{name}");
    }
    let e = save_calibration(&m, dir.join("c.txt")).unwrap_err();
    assert!(matches!(e, CalibError::UnknownFormat { .. }));
    let e = load_calibration(dir.join("missing.yaml")).unwrap_err();
    assert!(matches!(e, CalibError::Io(_)) && e.to_string().contains("missing.yaml"));
}
