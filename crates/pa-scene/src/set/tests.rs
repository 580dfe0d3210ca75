//! The manifest reader on valid and hostile input.

use std::path::{Path, PathBuf};

use serde_json::{json, Value};

use super::manifest::*;
use super::*;
use crate::SetProblem;

fn valid() -> Value {
    let cam = json!([
        [1, 0, 0, 0.01],
        [0, 0, -1, 0.02],
        [0, 1, 0, 0.5],
        [0, 0, 0, 1]
    ]);
    json!({
        "format": "propsalive-set/1", "renderer": "test",
        "width": 8, "height": 6,
        "intrinsics": {"fx": 10.0, "fy": 10.0, "cx": 3.5, "cy": 2.5},
        "model": {"builtin": "bust"},
        "marker_from_prop": [[1, 0, 0, 0], [0, 0, 1, 0], [0, -1, 0, 0], [0, 0, 0, 1]],
        "board": {"family": "tag36h11", "tags": [
            {"id": 3, "center_m": [0.1, -0.1], "size_m": 0.045}]},
        "plate": {"image": "plate/0000.png", "camera_from_marker": cam},
        "table_m": 1.6,
        "frames": [{"index": 0, "time_s": 0.5, "key_time_s": 0.0,
                    "camera_from_marker": cam, "input": "input/0000.png",
                    "truth": "truth/0000.png", "key_mask": "mask_key/0000.png",
                    "truth_mask": "mask_truth/0000.png", "plate": "plate/0000.png"}]
    })
}

fn parse(v: &Value) -> Result<SetManifest, crate::SceneError> {
    let bytes = serde_json::to_vec(v).expect("json");
    SetManifest::parse(&bytes, Path::new("set"), Path::new("set/manifest.json"))
}

/// The error's field, asserting it names the file.
fn field_of(e: crate::SceneError) -> String {
    match e {
        crate::SceneError::Set { file, problem } => {
            assert_eq!(file, PathBuf::from("set/manifest.json"));
            match problem {
                SetProblem::Field { field, .. } => field,
                other => format!("{other:?}"),
            }
        }
        other => panic!("not a set error: {other}"),
    }
}

#[test]
fn a_valid_manifest_reads_every_field() {
    let m = parse(&valid()).expect("valid");
    assert_eq!((m.width, m.height), (8, 6));
    assert_eq!(m.model, SetModel::BuiltinBust);
    assert_eq!(m.intrinsics.fx, 10.0);
    assert_eq!(m.board.tags[0].id, 3);
    assert_eq!(m.table_m, Some(1.6));
    assert_eq!(m.board.tags[0].center_m.y, -0.1);
    let f = &m.frames[0];
    assert_eq!(f.time_s, 0.5);
    // Row-major: the translation is the last column.
    let t = f.camera_from_marker.w_axis;
    assert_eq!((t.x, t.y, t.z), (0.01, 0.02, 0.5));
    assert_eq!(f.camera_from_marker.transform_point3(glam::Vec3::Y).z, 1.5);
    assert_eq!(f.plate.as_deref(), Some(Path::new("plate/0000.png")));
    assert_eq!(
        m.plate.as_ref().map(|p| p.0.clone()),
        Some("plate/0000.png".into())
    );
    // The matrix writer is the reader's inverse.
    let mut v = valid();
    v["frames"][0]["camera_from_marker"] = matrix_json(f.camera_from_marker);
    assert_eq!(
        parse(&v).expect("back").frames[0].camera_from_marker,
        f.camera_from_marker
    );
    // A last row a float writer left a hair off reads as exact.
    v["frames"][0]["camera_from_marker"][3] = json!([-0.0, 0.0, -0.0, 0.99999994]);
    let m2 = parse(&v).expect("f32 last row");
    assert_eq!(m2.frames[0].camera_from_marker.row(3), glam::Vec4::W);
}

#[test]
fn hostile_manifests_are_refused_naming_the_field() {
    type Edit = fn(&mut Value);
    let cases: Vec<(&str, Edit)> = vec![
        ("format", |v| v["format"] = json!("propsalive-set/2")),
        ("width", |v| v["width"] = json!(-3)),
        ("width", |v| v["width"] = json!(100_000)),
        ("height", |v| {
            v.as_object_mut().expect("object").remove("height");
        }),
        ("intrinsics.fx", |v| v["intrinsics"]["fx"] = json!("ten")),
        ("intrinsics", |v| v["intrinsics"]["fx"] = json!(-1.0)),
        ("model", |v| v["model"] = json!({})),
        ("model.builtin", |v| {
            v["model"] = json!({"builtin": "teapot"})
        }),
        ("marker_from_prop", |v| {
            v["marker_from_prop"] = json!([[1, 0, 0, 0]])
        }),
        ("marker_from_prop", |v| {
            v["marker_from_prop"][3] = json!([0, 0, 1, 1])
        }),
        ("marker_from_prop", |v| {
            v["marker_from_prop"][0] = json!([0, 0, 0, 0])
        }),
        ("board.family", |v| v["board"]["family"] = json!("tag99h99")),
        ("board.tags", |v| v["board"]["tags"] = json!([])),
        ("board.tags[0].size_m", |v| {
            v["board"]["tags"][0]["size_m"] = json!(0)
        }),
        ("board.tags[0].center_m", |v| {
            v["board"]["tags"][0]["center_m"] = json!([1])
        }),
        ("plate.image", |v| {
            v["plate"]["image"] = json!("../../etc/passwd")
        }),
        ("table_m", |v| v["table_m"] = json!(-1.6)),
        ("frames", |v| v["frames"] = json!([])),
        ("frames", |v| v["frames"] = json!({"0": 1})),
        ("frames[0].input", |v| {
            v["frames"][0]["input"] = json!("/etc/passwd")
        }),
        ("frames[0].truth", |v| {
            v["frames"][0]["truth"] = json!("a/../../b.png")
        }),
        ("frames[0].key_mask", |v| {
            v["frames"][0]["key_mask"] = json!(7)
        }),
        ("frames[0].time_s", |v| {
            v["frames"][0]["time_s"] = json!(-1.0)
        }),
        ("frames[0].key_time_s", |v| {
            v["frames"][0]
                .as_object_mut()
                .expect("object")
                .remove("key_time_s");
        }),
        ("frames[0].index", |v| v["frames"][0]["index"] = json!(1.5)),
        // A camera with a scaled or mirrored rotation is not a pose.
        ("frames[0].camera_from_marker", |v| {
            v["frames"][0]["camera_from_marker"][0] = json!([2, 0, 0, 0]);
        }),
        ("frames[0].camera_from_marker", |v| {
            v["frames"][0]["camera_from_marker"][0] = json!([-1, 0, 0, 0]);
        }),
        ("frames[0].camera_from_marker", |v| {
            v["frames"][0]["camera_from_marker"][1][3] = json!(1e300);
        }),
    ];
    for (field, edit) in cases {
        let mut v = valid();
        edit(&mut v);
        let e = parse(&v).expect_err(field);
        let msg = e.to_string();
        assert!(msg.starts_with("set/manifest.json: "), "{msg}");
        assert_eq!(field_of(e), field, "{msg}");
    }
}

#[test]
fn non_json_and_wrong_files_are_typed_errors() {
    let e = SetManifest::parse(
        b"{\"format\": ",
        Path::new("s"),
        Path::new("s/manifest.json"),
    )
    .expect_err("truncated");
    assert!(matches!(
        e,
        crate::SceneError::Set {
            problem: SetProblem::Json { line: 1, .. },
            ..
        }
    ));
    let tmp = tempfile::Builder::new()
        .prefix("pa-set-test-")
        .tempdir()
        .expect("temp dir");
    let dir = tmp.path();
    std::fs::create_dir_all(dir.join("manifest.json")).expect("dir");
    let e = SetManifest::read(dir).expect_err("a folder");
    assert!(
        matches!(&e, crate::SceneError::Set { problem: SetProblem::NotAFile, file } if file.ends_with("manifest.json")),
        "{e}"
    );
    let e = SetManifest::read(&dir.join("missing")).expect_err("missing");
    assert!(e.to_string().contains("missing/manifest.json"), "{e}");
    // An image of the wrong size or that is no image.
    let png = dir.join("x.png");
    image::RgbaImage::new(4, 3).save(&png).expect("png");
    let e = read_rgba8(&png, 8, 6).expect_err("size");
    assert!(
        matches!(
            &e,
            crate::SceneError::Set {
                problem: SetProblem::ImageSize {
                    width: 4,
                    height: 3,
                    ..
                },
                ..
            }
        ),
        "{e}"
    );
    assert_eq!(read_rgba8(&png, 4, 3).expect("reads").len(), 48);
    let junk = dir.join("junk.png");
    std::fs::write(&junk, b"\x89PNG\r\n\x1a\nnot really").expect("junk");
    let e = read_mask(&junk, 4, 3).expect_err("junk");
    assert!(
        e.to_string().starts_with(&junk.display().to_string()),
        "{e}"
    );
    let e = read_bounded(&junk, 4).expect_err("budget");
    assert!(matches!(
        &e,
        crate::SceneError::Set {
            problem: SetProblem::TooLarge { limit: 4, .. },
            ..
        }
    ));
}

#[test]
fn iou_counts_overlap_over_union() {
    assert_eq!(
        iou(&[true, true, false], &[true, false, true]),
        Some(1.0 / 3.0)
    );
    assert_eq!(iou(&[false], &[false]), None);
}

#[test]
fn the_kit_lists_a_path_around_the_set_and_the_bust() {
    let kit = kit::kit(&kit::KitSpec {
        frames: 4,
        ..kit::KitSpec::default()
    })
    .expect("kit");
    let names: Vec<_> = kit.files.iter().map(|f| f.0).collect();
    assert_eq!(names, ["prop.glb", "board.png", "kit.json"]);
    let json: Value = serde_json::from_slice(&kit.files[2].1).expect("json");
    assert_eq!(json["frames"].as_array().map(Vec::len), Some(4));
    // The kit's frames read back as manifest frames (same matrix form).
    let mut man = valid();
    man["frames"][0]["camera_from_marker"] = json["frames"][3]["camera_from_marker"].clone();
    man["board"] = json["board"].clone();
    let m = parse(&man).expect("kit camera is a pose");
    assert_eq!(m.board.tags.len(), 8);
    // Every camera sees the board's centre in front of it, inside the image.
    let k = pa_camera::Intrinsics::from_fov_y(45f64.to_radians(), 640, 360).expect("k");
    for f in json["frames"].as_array().expect("frames") {
        man["frames"][0]["camera_from_marker"] = f["camera_from_marker"].clone();
        let c = parse(&man).expect("pose").frames[0].camera_from_marker;
        let p = c.transform_point3(glam::Vec3::ZERO).as_dvec3();
        assert!(p.z > 0.4 && p.z < 0.8, "{p}");
        let (u, v) = (k.fx * p.x / p.z + k.cx, k.fy * p.y / p.z + k.cy);
        assert!(
            (0.0..640.0).contains(&u) && (0.0..360.0).contains(&v),
            "{u} {v}"
        );
    }
}
