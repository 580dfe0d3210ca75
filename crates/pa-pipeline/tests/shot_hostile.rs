//! Shot files from someone else (issue 11): a FIFO, a device or a huge file is refused at
//! once, every float of the schema must be finite, fixed-size vectors must have their exact
//! length, tag ids must be codes of the family and appear once, and no error repeats the
//! file's text.
//!
//! `tests/regressions/` keeps a small copy of each hostile shot (named after its bug);
//! [`every_regression_file_is_refused`] loads them all.

use std::path::{Path, PathBuf};
use std::time::Duration;

use pa_pipeline::shot::Shot;

/// The shot budget documented by `pa_pipeline::shot::MAX_SHOT_BYTES`.
const BUDGET: u64 = 4 << 20;

fn regressions() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/regressions")
}

/// Runs `f` on its own thread; fails the test if it does not return within 20 s.
fn within<T: Send + 'static>(what: &str, f: impl FnOnce() -> T + Send + 'static) -> T {
    pa_testkit::hostile::within(what, Duration::from_secs(20), f)
}

fn load_err(path: &Path) -> String {
    let p = path.to_path_buf();
    let name = path.display().to_string();
    within(&name, move || Shot::load(&p).map(|_| ()))
        .expect_err(&name)
        .to_string()
}

#[test]
fn every_regression_file_is_refused() {
    pa_testkit::hostile::assert_every_file_refused(&regressions(), 10, load_err);
}

/// Every float of the schema: NaN and infinities (and f32 overflow) name the field.
#[test]
fn non_finite_numbers_are_refused_naming_the_field() {
    for (file, needle) in [
        ("nan_translation_m.toml", "translation_m[1]"),
        ("inf_translation_m.toml", "translation_m[0]"),
        ("overflowing_translation_m.toml", "translation_m[2]"),
        ("nan_yaw_deg.toml", "yaw_deg"),
        ("inf_yaw_deg.toml", "yaw_deg"),
        ("nan_center_m.toml", "center_m[1]"),
        ("inf_center_m.toml", "center_m[0]"),
        ("nan_size_m.toml", "size_m"),
        ("nan_fov_y_deg.toml", "fov_y_deg"),
        ("inf_fps.toml", "fps"),
    ] {
        let msg = load_err(&regressions().join(file));
        assert!(msg.contains(file) && msg.contains(needle), "{file}: {msg}");
    }
}

/// `center_m = [x, y, z]` was read as [x, y] without a word; every fixed-size vector must
/// have exactly its length.
#[test]
fn fixed_size_vectors_need_their_exact_length() {
    for (file, needle, line) in [
        (
            "center_m_three_numbers.toml",
            "`center_m` needs exactly 2 numbers, found 3",
            26,
        ),
        (
            "center_m_one_number.toml",
            "`center_m` needs exactly 2 numbers, found 1",
            26,
        ),
        (
            "translation_m_four_numbers.toml",
            "`translation_m` needs exactly 3 numbers, found 4",
            30,
        ),
        (
            "translation_m_two_numbers.toml",
            "`translation_m` needs exactly 3 numbers, found 2",
            30,
        ),
    ] {
        let msg = load_err(&regressions().join(file));
        assert!(msg.contains(needle), "{file}: {msg}");
        assert!(msg.contains(&format!("{file}:{line}:")), "{file}: {msg}");
    }
}

#[test]
fn tag_ids_must_be_codes_of_the_family_and_unique() {
    for (file, needle) in [
        ("duplicate_tag_ids.toml", "tag id 0 is on the board twice"),
        ("tag_id_past_family.toml", "has no id 587 (ids 0..=586)"),
        ("unknown_family.toml", "family is not a tag family"),
        (
            "duplicate_marker_id.toml",
            "marker_id 7 is used by another key pose",
        ),
        (
            "marker_id_is_a_board_tag.toml",
            "marker_id 1 is also a tag of the board",
        ),
        ("duplicate_key_pose_names.toml", "named twice"),
    ] {
        let msg = load_err(&regressions().join(file));
        assert!(msg.contains(needle), "{file}: {msg}");
    }
    // The family's name from the file is not repeated either.
    let msg = load_err(&regressions().join("unknown_family.toml"));
    assert!(!msg.contains("tag99h99"), "{msg}");
}

#[test]
fn parse_errors_never_show_the_file() {
    for (file, position) in [
        ("secret_leak_shadow.toml", ":1:"),
        ("secret_leak_shadow", ":1:"),
        ("secret_leak_quoted_value.toml", ":3:"),
        ("secret_leak_quoted_family.toml", ":17:"),
    ] {
        let msg = load_err(&regressions().join(file));
        assert!(!msg.contains("SECRETHASH"), "{file}: {msg}");
        assert!(!msg.contains("19000"), "{file}: {msg}");
        assert!(msg.contains(&format!("{file}{position}")), "{file}: {msg}");
        assert!(msg.contains("not a valid shot file"), "{file}: {msg}");
    }
    let msg = load_err(&regressions().join("secret_leak_quoted_value.toml"));
    assert!(msg.contains("expected f32"), "{msg}");
}

#[test]
fn a_fifo_is_refused_at_once() {
    let dir = tempfile::tempdir().expect("tempdir");
    let fifo = dir.path().join("shot.toml");
    let ok = std::process::Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .expect("run mkfifo")
        .success();
    assert!(ok, "mkfifo");
    let msg = load_err(&fifo);
    assert!(msg.contains("shot.toml") && msg.contains("FIFO"), "{msg}");
}

#[test]
fn a_device_or_a_folder_is_refused_at_once() {
    let dir = tempfile::tempdir().expect("tempdir");
    let msg = load_err(Path::new("/dev/zero"));
    assert!(
        msg.contains("/dev/zero") && msg.contains("character device"),
        "{msg}"
    );
    let msg = load_err(dir.path());
    assert!(msg.contains("folder"), "{msg}");
}

/// A file over the budget is refused before it is read (a sparse file: no disk is used).
#[test]
fn a_shot_over_the_budget_is_refused_unread() {
    let dir = tempfile::tempdir().expect("tempdir");
    for (name, size) in [("big.toml", BUDGET + 1), ("huge.toml", 1 << 30)] {
        let p = dir.path().join(name);
        std::fs::File::create(&p)
            .expect("create")
            .set_len(size)
            .expect("sparse file");
        let msg = load_err(&p);
        assert!(
            msg.contains(name) && msg.contains("over the limit"),
            "{msg}"
        );
        assert!(msg.contains(&BUDGET.to_string()), "{msg}");
    }
}

/// The regression shots differ from a valid one only in the hostile part.
#[test]
fn the_valid_base_shot_loads() {
    let text = std::fs::read_to_string(regressions().join("nan_yaw_deg.toml"))
        .expect("read")
        .replace("yaw_deg = nan", "yaw_deg = 0.0");
    let shot = Shot::parse(&text, Path::new("base.toml")).expect("valid");
    assert_eq!(shot.marker.tags.len(), 2);
}

/// A key this version does not know is never dropped (issue 16): it is refused with its dotted
/// name, its line and column, and the format the file claims; a misspelling gets the closest
/// known key.
#[test]
fn unknown_keys_are_refused_not_dropped() {
    for (file, want) in [
        (
            "unknown_key_marker_picture.toml",
            ":18:1: unknown key `marker.picture` in [marker]: the file is shot format 1, which has \
             no such key ([marker] knows family, tags, image, width_m, hide, cover)",
        ),
        (
            "misspelt_section_placment.toml",
            ":29:2: unknown key `placment` in the top level: the file is shot format 1, which has \
             no such key; did you mean `placement`?",
        ),
        (
            "misspelt_key_yaw_degs.toml",
            ":32:1: unknown key `placement.yaw_degs` in [placement]: the file is shot format 1, \
             which has no such key; did you mean `yaw_deg`? ([placement] knows translation_m, \
             upright, yaw_deg, scale)",
        ),
        (
            "unknown_key_in_tag.toml",
            ":26:1: unknown key `marker.tags.rotation_deg` in [marker.tags]",
        ),
    ] {
        let msg = load_err(&regressions().join(file));
        assert!(msg.contains(&format!("{file}{want}")), "{file}: {msg}");
    }
}

#[test]
fn a_newer_or_nonsense_format_is_refused() {
    let msg = load_err(&regressions().join("newer_format.toml"));
    assert!(
        msg.ends_with(
            "newer_format.toml:1:1: written for shot format 2; this propsalive reads format 1"
        ),
        "{msg}"
    );
    let msg = load_err(&regressions().join("format_zero.toml"));
    assert!(
        msg.contains("format_zero.toml:1:1:")
            && msg.contains("`format` is the shot format's version"),
        "{msg}"
    );
}

#[test]
fn the_scale_must_be_positive_and_finite() {
    for file in ["zero_scale.toml", "nan_scale.toml"] {
        let msg = load_err(&regressions().join(file));
        assert!(
            msg.contains(file) && msg.contains("[placement] scale must be a positive finite"),
            "{file}: {msg}"
        );
    }
}
