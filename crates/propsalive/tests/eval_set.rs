//! `propsalive eval --set` on the four Blender frames committed for pa-scene's test, and
//! `--write-kit`: the report's rows, the frame table, and typed errors for a bad set.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn propsalive(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_propsalive"))
        .args(args)
        .output()
        .expect("runs")
}

fn tmp(name: &str) -> PathBuf {
    let d = PathBuf::from(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("eval_set_{name}_{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).expect("mkdir");
    d
}

fn set_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../pa-scene/tests/data/blender_bust")
}

#[test]
fn eval_set_reports_a_row_per_fill_with_flicker() {
    let out = tmp("rows");
    let o = propsalive(&[
        "eval",
        "--set",
        set_dir().to_str().expect("utf-8"),
        "--save-frames",
        "--out",
        out.to_str().expect("utf-8"),
    ]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{stderr}");
    let report = std::fs::read_to_string(out.join("report.md")).expect("report");
    for fill in [
        "| Blender: blender_bust | live + visibility, rectangle fill |",
        "| Blender: blender_bust | ours, patch fill |",
        "| Blender: blender_bust | ours: live + visibility, ray fill |",
        "| Blender: blender_bust | ours with clean plate |",
        "| Blender: blender_bust | ours with clean plate, not aligned |",
        "| Blender: blender_bust | live + visibility, rectangle fill, shadows |",
        "| Blender: blender_bust | ours, patch fill, shadows |",
        "| Blender: blender_bust | ours: live + visibility, ray fill, shadows |",
        "| Blender: blender_bust | ours with clean plate, shadows |",
        "| Blender: blender_bust | ours: plain look (not relit, hard seams) |",
        "| Blender: blender_bust | ours: no grazing reflection |",
        "| Blender: blender_bust | ours: + texture memory |",
    ] {
        let line = report
            .lines()
            .find(|l| l.starts_with(fill))
            .unwrap_or_else(|| panic!("no row {fill}:\n{report}"));
        // Every cell measured, flicker included ("ours / truth").
        let cells: Vec<&str> = line.split('|').map(str::trim).collect();
        assert_eq!(cells.len(), 12, "{line}");
        // prop PSNR, SSIM, revealed PSNR, SSIM, revealed off the twin's edge, rot. err., ms.
        assert!(
            cells[3..10].iter().all(|c| c.parse::<f64>().is_ok()),
            "{line}"
        );
        let (ours, truth) = cells[10].split_once(" / ").expect("flicker cell");
        assert!(
            ours.parse::<f64>().is_ok() && truth.parse::<f64>().is_ok(),
            "{line}"
        );
    }
    assert!(report.contains("| frame | tracked |"), "{report}");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("results.json")).expect("json"))
            .expect("parses");
    // 4 frames x (8 methods (rectangle, rays, plain look, first-order light, no grazing
    // reflection, plate aligned and not, patch) x shadows off and on, and rays with the
    // texture memory).
    assert_eq!(json["frames"].as_array().map(Vec::len), Some(68));
    assert!(out.join("blender_bust/no_grazing/0006.png").is_file());
    assert!(out.join("blender_bust/first_order/0006.png").is_file());
    assert!(out.join("blender_bust/plate/0006.png").is_file());
    assert!(out.join("blender_bust/plate_unaligned/0006.png").is_file());
    assert!(out.join("blender_bust/memory/0006.png").is_file());
    assert!(out.join("blender_bust/patch_shadows/0006.png").is_file());
    let svg = std::fs::read_to_string(out.join("fills.svg")).expect("fills.svg");
    assert!(
        svg.contains("Blender: blender_bust, shadows on") && svg.contains("patch"),
        "{svg}"
    );
}

#[test]
fn a_bad_set_is_an_error_naming_its_file() {
    let out = tmp("bad");
    let o = propsalive(&[
        "eval",
        "--set",
        out.join("nowhere").to_str().expect("utf-8"),
        "--out",
        out.to_str().expect("utf-8"),
    ]);
    assert!(!o.status.success());
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(stderr.contains("nowhere/manifest.json"), "{stderr}");
    let bad = out.join("bad");
    std::fs::create_dir_all(&bad).expect("mkdir");
    std::fs::write(
        bad.join("manifest.json"),
        br#"{"format": "propsalive-set/1"}"#,
    )
    .expect("write");
    let o = propsalive(&[
        "eval",
        "--set",
        bad.to_str().expect("utf-8"),
        "--out",
        out.to_str().expect("utf-8"),
    ]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(
        stderr.contains("bad/manifest.json: field `width` missing"),
        "{stderr}"
    );
}

#[test]
fn write_kit_writes_the_bust_board_and_path() {
    let out = tmp("kit");
    let o = propsalive(&[
        "eval",
        "--write-kit",
        out.to_str().expect("utf-8"),
        "--kit-frames",
        "5",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    for f in ["kit.json", "board.png", "prop.glb"] {
        assert!(out.join(f).is_file(), "{f}");
    }
    let kit: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("kit.json")).expect("kit"))
            .expect("json");
    assert_eq!(kit["frames"].as_array().map(Vec::len), Some(5));
    assert_eq!(kit["width"], 640);
    let o = propsalive(&[
        "eval",
        "--write-kit",
        out.to_str().expect("utf-8"),
        "--kit-frames",
        "0",
    ]);
    assert!(!o.status.success());
}
