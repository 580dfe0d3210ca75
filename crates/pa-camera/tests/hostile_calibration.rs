//! Calibration files from someone else (issue 11): every hostile input is refused with an
//! error naming the file and the problem, at once, without repeating the file's text.
//!
//! `tests/regressions/` keeps a small copy of each hostile file (named after its bug);
//! [`every_regression_file_is_refused`] loads them all. Large inputs are made here instead.

use std::path::{Path, PathBuf};
use std::time::Duration;

use pa_camera::calib::{load_calibration, parse_calibration, save_calibration, CalibFormat};
use pa_camera::{CameraModel, Intrinsics};

/// The calibration budget documented by `pa_camera::calib::MAX_CALIBRATION_BYTES`.
const BUDGET: u64 = 16 << 20;

fn regressions() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/regressions")
}

/// A fresh folder, removed with everything in it when dropped.
fn tmpdir(name: &str) -> tempfile::TempDir {
    tempfile::Builder::new()
        .prefix(&format!("pa-camera-hostile-{name}-"))
        .tempdir()
        .expect("temp dir")
}

/// Runs `f` on its own thread and fails the test if it does not return within 20 s (a read
/// that blocks forever on a FIFO must fail the test, not hang it).
fn within<T: Send + 'static>(what: &str, f: impl FnOnce() -> T + Send + 'static) -> T {
    pa_testkit::hostile::within(what, Duration::from_secs(20), f)
}

fn load_err(path: &Path) -> String {
    let p = path.to_path_buf();
    let name = path.display().to_string();
    within(&name, move || load_calibration(&p))
        .expect_err(&name)
        .to_string()
}

#[test]
fn every_regression_file_is_refused() {
    pa_testkit::hostile::assert_every_file_refused(&regressions(), 10, load_err);
}

/// 50,000 nested brackets overflowed the parser's stack (the process aborted).
#[test]
fn deep_bracket_nesting_is_refused_not_a_stack_overflow() {
    let path = regressions().join("stack_overflow_nested_brackets_50000.yaml");
    let msg = load_err(&path);
    assert!(msg.contains("nested deeper than 64"), "{msg}");
    // Mappings nest the same way.
    let text = format!(
        "camera_matrix: {}{}\n",
        "{a: ".repeat(10_000),
        "}".repeat(10_000)
    );
    let e = parse_calibration(&text, CalibFormat::OpencvYaml, "braces.yaml").expect_err("deep");
    assert!(e.to_string().contains("nested deeper than 64"), "{e}");
}

/// Blocks nested by indentation are the parser's other recursion.
#[test]
fn deep_indentation_is_refused() {
    let mut text = String::new();
    for i in 0..200 {
        text.push_str(&" ".repeat(i));
        text.push_str("a:\n");
    }
    let e = parse_calibration(&text, CalibFormat::OpencvYaml, "indent.yaml").expect_err("deep");
    let msg = e.to_string();
    assert!(
        msg.contains("indent.yaml") && msg.contains("nested deeper than 64"),
        "{msg}"
    );
    // 64 levels of OpenCV-like nesting are fine (the camera is still missing).
    let mut text = String::new();
    for i in 0..60 {
        text.push_str(&" ".repeat(i));
        text.push_str("a:\n");
    }
    let e = parse_calibration(&text, CalibFormat::OpencvYaml, "ok.yaml").expect_err("no camera");
    assert!(e.to_string().contains("missing field"), "{e}");
}

/// `[ ... } ]` made the flow parser loop forever, growing a vector until memory ran out.
#[test]
fn a_brace_closing_a_bracket_does_not_loop_forever() {
    let msg = load_err(&regressions().join("infinite_loop_brace_closes_bracket.yaml"));
    assert!(msg.contains("syntax error"), "{msg}");
    for text in [
        "K: [ } ]",
        "K: { a: ] }",
        "K: [ 1, { b: 2 ] }",
        "K: [[[ }}} ]]]",
    ] {
        let t = text.to_string();
        let r = within(text, move || {
            parse_calibration(&t, CalibFormat::OpencvYaml, "flow.yaml")
        });
        assert!(r.is_err(), "{text}");
    }
}

/// A flow collection spread over many lines was rescanned whole for each line (quadratic).
#[test]
fn a_long_multiline_flow_sequence_parses_in_linear_time() {
    let mut text = String::from("camera_matrix: [ 500., 0., 320., 0., 500., 240., 0., 0., 1.,\n");
    for _ in 0..200_000 {
        text.push_str("  0.,\n");
    }
    text.push_str("]\nimage_width: 640\nimage_height: 480\n");
    let start = std::time::Instant::now();
    let e = within("long flow", move || {
        parse_calibration(&text, CalibFormat::OpencvYaml, "long.yaml")
    })
    .expect_err("wrong size");
    assert!(e.to_string().contains("wrong size"), "{e}");
    assert!(
        start.elapsed() < Duration::from_secs(10),
        "{:?}",
        start.elapsed()
    );
}

#[test]
fn a_fifo_is_refused_at_once() {
    let tmp = tmpdir("fifo");
    let d = tmp.path();
    for name in ["calib.yaml", "calib.toml", "calib.json", "calib"] {
        let fifo = d.join(name);
        pa_testkit::hostile::mkfifo(&fifo);
        let msg = load_err(&fifo);
        assert!(msg.contains(name) && msg.contains("FIFO"), "{msg}");
    }
    let fifo = d.join("out.yaml");
    pa_testkit::hostile::mkfifo(&fifo);
    let model = CameraModel::pinhole(Intrinsics::from_fov_y(1.0, 640, 480).expect("valid"));
    let f = fifo.clone();
    let e = within("save onto a FIFO", move || save_calibration(&model, &f))
        .expect_err("a FIFO is not replaced");
    assert!(e.to_string().contains("FIFO"), "{e}");
    use std::os::unix::fs::FileTypeExt;
    assert!(std::fs::symlink_metadata(&fifo)
        .expect("still there")
        .file_type()
        .is_fifo());
}

#[test]
fn a_device_or_folder_is_refused() {
    let msg = load_err(Path::new("/dev/zero"));
    assert!(
        msg.contains("/dev/zero") && msg.contains("character device"),
        "{msg}"
    );
    let tmp = tmpdir("folder");
    let d = tmp.path();
    let msg = load_err(d);
    assert!(msg.contains("folder"), "{msg}");
}

/// A file over the budget is refused before it is read (a sparse file: no disk is used).
#[test]
fn a_file_over_the_budget_is_refused_unread() {
    let tmp = tmpdir("budget");
    let d = tmp.path();
    for (name, size) in [("big.yaml", BUDGET + 1), ("huge.toml", 1 << 30)] {
        let p = d.join(name);
        let f = std::fs::File::create(&p).expect("create");
        f.set_len(size).expect("sparse file");
        let msg = load_err(&p);
        assert!(
            msg.contains(name) && msg.contains("over the limit"),
            "{msg}"
        );
        assert!(msg.contains(&BUDGET.to_string()), "{msg}");
    }
}

/// NaN, infinities, non-positive focal lengths and absurd sizes, in every format, name the
/// field.
#[test]
fn non_finite_or_absurd_cameras_are_refused_naming_the_field() {
    for (file, needle) in [
        ("nan_focal_length.yaml", "camera_matrix.data[0]"),
        ("nan_camera_matrix_last_row.yaml", "camera_matrix.data[6]"),
        ("inf_distortion_k1.yaml", "distortion_coefficients.data[0]"),
        (
            "nan_distortion_beyond_k3.yaml",
            "distortion_coefficients.data[5]",
        ),
        ("absurd_image_size.yaml", "image size"),
        ("nan_distortion_k2.toml", "k2"),
        ("inf_focal_length.toml", "fx"),
        ("negative_fy.toml", "fy"),
        ("absurd_image_size.json", "image size"),
        ("overflowing_focal_length.json", "out of range"),
    ] {
        let msg = load_err(&regressions().join(file));
        assert!(msg.contains(file) && msg.contains(needle), "{file}: {msg}");
    }
    // Each distortion coefficient, in TOML (which has `nan` and `inf`).
    for field in ["k1", "k2", "p1", "p2", "k3"] {
        for bad in ["nan", "inf", "-inf"] {
            let mut text = String::from(
                "[intrinsics]\nfx = 500.0\nfy = 500.0\ncx = 320.0\ncy = 240.0\nwidth = 640\n\
                 height = 480\n[distortion]\n",
            );
            for f in ["k1", "k2", "p1", "p2", "k3"] {
                text.push_str(&format!("{f} = {}\n", if f == field { bad } else { "0.0" }));
            }
            let e = parse_calibration(&text, CalibFormat::Toml, "d.toml").expect_err(field);
            assert!(e.to_string().contains(field), "{field} = {bad}: {e}");
        }
    }
    for (field, bad) in [("fx", "0.0"), ("fy", "-1.0"), ("cx", "nan"), ("cy", "inf")] {
        let mut text = String::from("[intrinsics]\n");
        for (f, v) in [
            ("fx", "500.0"),
            ("fy", "500.0"),
            ("cx", "320.0"),
            ("cy", "240.0"),
        ] {
            text.push_str(&format!("{f} = {}\n", if f == field { bad } else { v }));
        }
        text.push_str("width = 640\nheight = 480\n");
        let e = parse_calibration(&text, CalibFormat::Toml, "k.toml").expect_err(field);
        assert!(e.to_string().contains(field), "{field} = {bad}: {e}");
    }
}

/// `track --calib /etc/shadow` printed the password hash: no format's error may repeat the
/// file, and each reports the position.
#[test]
fn parse_errors_never_show_the_file() {
    for (file, position) in [
        ("secret_leak_shadow", ":1:"),
        ("secret_leak_shadow.toml", ":1:"),
        ("secret_leak_shadow.json", ":1:"),
        ("secret_leak_shadow.yaml", ":1:"),
        ("secret_leak_quoted_value.yaml", ":5:"),
        ("secret_leak_quoted_width.yaml", ":1:"),
        ("secret_leak_quoted_value.toml", ":2:"),
        ("secret_leak_quoted_value.json", ":1:"),
    ] {
        let msg = load_err(&regressions().join(file));
        assert!(!msg.contains("SECRETHASH"), "{file}: {msg}");
        assert!(!msg.contains("19000"), "{file}: {msg}");
        assert!(msg.contains(&format!("{file}{position}")), "{file}: {msg}");
    }
    // The message still says what was expected.
    let msg = load_err(&regressions().join("secret_leak_quoted_value.toml"));
    assert!(msg.contains("expected f64"), "{msg}");
}
