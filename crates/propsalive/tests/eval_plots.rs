//! `propsalive eval` on its smallest useful run (one seed, every 12th frame, the default
//! size, at which the tracker locks on) writes the three SVG plots next to the report, with
//! a line per series, the legend names and no NaN, and the report links them.

use std::process::Command;

/// The methods of the degradation curves (the legend of both degradation plots).
const CURVE_METHODS: [&str; 7] = [
    "paper (live, no visibility, rectangle fill)",
    "ours: live + visibility, ray fill",
    "ours, two key poses (frames 0 and 24)",
    "ours: plain look (not relit, hard seams)",
    "ours: relit, hard seams",
    "ours: feathered seams, not relit",
    "ours: first-order light (no sun, no cast shadows)",
];

/// Every method (the categories of the method chart).
const ALL_METHODS: [&str; 16] = [
    "paper (live, no visibility, rectangle fill)",
    "live + visibility, rectangle fill",
    "live, no visibility, ray fill",
    "ours: live + visibility, ray fill",
    "ours with clean plate",
    "ours with clean plate, not aligned",
    "ours, patch fill",
    "ours, patch fill with clean plate",
    "model texture (no live sampling), ray fill",
    "ours, two key poses (frames 0 and 24)",
    "tripod camera: paper",
    "tripod camera: ours",
    "ours: plain look (not relit, hard seams)",
    "ours: relit, hard seams",
    "ours: feathered seams, not relit",
    "ours: first-order light (no sun, no cast shadows)",
];

fn read(path: &std::path::Path) -> String {
    std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// The shared checks: an SVG document, no NaN or infinity written, `names` present.
fn check_svg(svg: &str, what: &str, names: &[&str]) {
    assert!(
        svg.starts_with("<svg"),
        "{what}: {}",
        &svg[..svg.len().min(200)]
    );
    assert!(svg.trim_end().ends_with("</svg>"), "{what}");
    for bad in ["NaN", "=\"inf", "=\"-inf", " inf", ",inf"] {
        assert!(!svg.contains(bad), "{what} contains {bad:?}");
    }
    for name in names {
        assert!(svg.contains(name), "{what} lacks {name:?}");
    }
}

#[test]
fn eval_writes_linked_svg_plots() {
    let dir = tempfile::tempdir().expect("tempdir");
    let out = dir.path().join("eval");
    let run = Command::new(env!("CARGO_BIN_EXE_propsalive"))
        .args(["eval", "--seeds", "1", "--stride", "12", "--out"])
        .arg(&out)
        .arg("--dump-fills")
        .arg(dir.path().join("fills"))
        .output()
        .expect("run");
    let stderr = String::from_utf8_lossy(&run.stderr);
    if !run.status.success()
        && (stderr.contains("no wgpu adapter") || stderr.contains("no suitable wgpu adapter"))
    {
        println!("skipped: no wgpu adapter ({stderr})");
        return;
    }
    assert!(run.status.success(), "{stderr}");
    let stdout = String::from_utf8_lossy(&run.stdout);

    for name in [
        "methods.svg",
        "degradation_rotation.svg",
        "degradation_translation.svg",
    ] {
        let path = out.join(name);
        assert!(path.is_file(), "{} missing", path.display());
        assert!(
            stdout.contains(&path.display().to_string()),
            "the output does not say where {name} went: {stdout}"
        );
    }

    // Degradation plots: one line per method (bin means) and the methods in the legend.
    for name in ["degradation_rotation.svg", "degradation_translation.svg"] {
        let svg = read(&out.join(name));
        check_svg(&svg, name, &CURVE_METHODS);
        // Each series is a polyline in its own colour.
        let colours: std::collections::BTreeSet<&str> = svg
            .split("<polyline")
            .skip(1)
            .filter_map(|tag| tag.split("stroke=\"").nth(1)?.split('"').next())
            .collect();
        assert!(
            colours.len() >= CURVE_METHODS.len(),
            "{name}: lines in {colours:?} for {} series",
            CURVE_METHODS.len()
        );
        assert!(!svg.contains("(no data)"), "{name}: a series without data");
    }

    // Method chart: every method, the four groups, a bar (<rect>) per method and group.
    let svg = read(&out.join("methods.svg"));
    check_svg(&svg, "methods.svg", &ALL_METHODS);
    check_svg(
        &svg,
        "methods.svg",
        &[
            "prop PSNR, Wood",
            "prop PSNR, Plain",
            "revealed PSNR, Wood",
            "revealed PSNR, Plain",
        ],
    );
    assert!(
        svg.matches("<rect").count() >= ALL_METHODS.len() * 4,
        "methods.svg: too few bars"
    );

    // The report links the plots; the JSON names them and holds the per-frame points.
    let report = read(&out.join("report.md"));
    for name in [
        "methods.svg",
        "degradation_rotation.svg",
        "degradation_translation.svg",
    ] {
        assert!(
            report.contains(&format!("]({name})")),
            "report lacks {name}"
        );
    }
    // --dump-fills: per background and seed, each frame's inputs of the fill comparison, and
    // each fill's plate once the tracker has a pose (frame 2 on); the patch fill changed
    // pixels of the fill mask and none outside it.
    for sub in ["wood_s1", "plain_s1"] {
        let d = dir.path().join("fills").join(sub);
        let png = |name: &str| {
            let path = d.join(format!("f003_{name}.png"));
            image::open(&path)
                .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
                .to_rgba8()
        };
        for name in [
            "input",
            "truth",
            "revealed",
            "fillmask",
            "fill_rectangle",
            "fill_rays",
            "fill_plate",
            "fill_patch",
            "fill_patch_plate",
        ] {
            assert_eq!(png(name).dimensions(), (480, 270), "{sub} {name}");
        }
        let (input, patch, mask) = (png("input"), png("fill_patch"), png("fillmask"));
        let (mut inside, mut outside) = (0, 0);
        for ((i, p), m) in input.pixels().zip(patch.pixels()).zip(mask.pixels()) {
            if i.0[..3] != p.0[..3] {
                if m.0[0] > 127 {
                    inside += 1;
                } else {
                    outside += 1;
                }
            }
        }
        assert!(
            inside > 100,
            "{sub}: the patch fill changed {inside} mask pixels"
        );
        assert_eq!(outside, 0, "{sub}: the patch fill wrote outside its mask");
    }
    let doc: serde_json::Value =
        serde_json::from_str(&read(&out.join("results.json"))).expect("results.json");
    assert_eq!(doc["plots"].as_array().map(Vec::len), Some(3));
    let frames = doc["degradation_frames"].as_array().expect("frames");
    assert!(!frames.is_empty());
    // The in-betweens move: some frame is away from its key pose in both measures.
    let max = |key: &str| {
        frames
            .iter()
            .filter_map(|f| f[key].as_f64())
            .fold(0.0, f64::max)
    };
    assert!(max("rotation_deg") > 5.0, "{}", max("rotation_deg"));
    assert!(
        max("head_displacement_prop_heights") > 0.01,
        "{}",
        max("head_displacement_prop_heights")
    );

    // No temporary file of the atomic writes is left.
    let leftovers: Vec<_> = std::fs::read_dir(&out)
        .expect("out")
        .filter_map(|e| e.ok())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.contains(".tmp"))
        .collect();
    assert!(leftovers.is_empty(), "{leftovers:?}");
}
