//! Every public formatting function of pa-report on a small hand-made input, its output pinned
//! byte for byte (the long ones in `tests/data/`). `PA_REPORT_BLESS=1 cargo test -p pa-report
//! --test pinned` rewrites the files in `tests/data/` (then review the diff).

use std::path::{Path, PathBuf};

use pa_report::bench::{fps, table, BenchReport, BenchRow, STAGES};
use pa_report::eval::{methods_chart, methods_table, Curve, CurvePoint, EvalReport, MethodRow};
use pa_report::plot::{BarChart, BarGroup, LineChart, Series};
use pa_report::stats::{mean, median, stat, Stat};

fn data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests")
        .join("data")
        .join(name)
}

/// `actual` equals `tests/data/NAME` byte for byte.
fn pinned(name: &str, actual: &str) {
    let path = data(name);
    if std::env::var_os("PA_REPORT_BLESS").is_some() {
        std::fs::write(&path, actual).expect("bless");
        return;
    }
    let want = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{name}: {e}"));
    assert!(
        want == actual,
        "{name} changed; got:\n{actual}\n(PA_REPORT_BLESS=1 rewrites it)"
    );
}

fn row(background: &str, method: &str, psnr: f64, frames: usize) -> MethodRow {
    MethodRow {
        background: background.into(),
        method: method.into(),
        prop_psnr_db: Some(psnr),
        prop_ssim: Some(0.91234),
        revealed_psnr_db: if frames == 0 { None } else { Some(psnr - 8.0) },
        revealed_ssim: Some(0.5),
        revealed_off_edge_psnr_db: if frames == 0 { None } else { Some(psnr - 3.0) },
        rot_err_deg_median: Some(0.1234),
        texture_diminish_ms_median: Some(12.34),
        flicker_ours: if frames == 0 { None } else { Some(psnr / 10.0) },
        flicker_truth: Some(1.5),
        frames,
    }
}

fn rows() -> Vec<MethodRow> {
    vec![
        row("Wood", "paper (live)", 24.5, 4),
        row("Wood", "ours: a & b", 26.25, 4),
        row("Plain", "paper (live)", 28.0, 0),
        row("Plain", "ours: a & b", 29.125, 4),
    ]
}

fn curves() -> Vec<Curve> {
    let point =
        |frame: u32, rotation_deg: f64, displacement_h: f64, psnr: Option<f64>| CurvePoint {
            seed: 1,
            frame,
            key: 0,
            rotation_deg,
            displacement_h,
            psnr_prop: psnr,
        };
    vec![
        Curve {
            name: "paper (live)".into(),
            points: vec![
                point(0, 0.5, 0.0, Some(30.0)),
                point(12, 12.0, 0.04, Some(25.5)),
                point(24, 33.0, 0.11, None),
                point(36, 40.0, 0.147, Some(20.25)),
            ],
        },
        Curve {
            name: "ours: a & b".into(),
            points: vec![
                point(0, 1.0, 0.01, Some(31.0)),
                point(24, 30.0, 0.1, Some(27.0)),
            ],
        },
    ]
}

#[test]
fn stats_values() {
    let v = [Some(2.0), None, Some(1.0), Some(f64::NAN), Some(6.0)];
    assert_eq!(mean(v), Some(3.0));
    assert_eq!(median(v), Some(2.0));
    let s = stat(vec![4.0, 1.0, 3.0, 2.0]);
    assert_eq!((s.median, s.p95), (2.5, 4.0));
    assert_eq!(
        fps(Stat {
            median: 8.0,
            p95: 9.0
        }),
        125.0
    );
}

#[test]
fn eval_methods_table() {
    assert_eq!(
        methods_table(&rows()),
        "| background | method | prop PSNR dB | prop SSIM | revealed PSNR dB | revealed SSIM | revealed off edge dB | rot. err. deg | texture+diminish ms | flicker ours / truth |\n\
         |---|---|---|---|---|---|---|---|---|---|\n\
         | Wood | paper (live) | 24.50 | 0.912 | 16.50 | 0.500 | 21.50 | 0.123 | 12.3 | 2.45 / 1.50 |\n\
         | Wood | ours: a & b | 26.25 | 0.912 | 18.25 | 0.500 | 23.25 | 0.123 | 12.3 | 2.62 / 1.50 |\n\
         | Plain | paper (live) | 28.00 | 0.912 | - | 0.500 | - | 0.123 | 12.3 | - / 1.50 |\n\
         | Plain | ours: a & b | 29.12 | 0.912 | 21.12 | 0.500 | 26.12 | 0.123 | 12.3 | 2.91 / 1.50 |\n"
    );
    assert_eq!(
        rows()[2].json().to_string(),
        r#"{"background":"Plain","flicker_ours":null,"flicker_truth":1.5,"frames":0,"method":"paper (live)","prop_psnr_db":28.0,"prop_ssim":0.91234,"revealed_off_edge_psnr_db":null,"revealed_psnr_db":null,"revealed_ssim":0.5,"rot_err_deg_median":0.1234,"texture_diminish_ms_median":12.34}"#
    );
}

#[test]
fn eval_methods_chart() {
    let chart = methods_chart(&rows());
    assert_eq!(chart.categories, ["paper (live)", "ours: a & b"]);
    assert_eq!(chart.baseline, Some(0));
    let groups: Vec<(&str, &[Option<f64>])> = chart
        .groups
        .iter()
        .map(|g| (g.name.as_str(), g.values.as_slice()))
        .collect();
    assert_eq!(
        groups,
        [
            ("prop PSNR, Wood", &[Some(24.5), Some(26.25)][..]),
            ("prop PSNR, Plain", &[Some(28.0), Some(29.125)][..]),
            ("revealed PSNR, Wood", &[Some(16.5), Some(18.25)][..]),
            ("revealed PSNR, Plain", &[None, Some(21.125)][..]),
        ]
    );
    pinned("methods.svg", &chart.to_svg());
}

fn eval_report() -> EvalReport {
    EvalReport {
        width: 160,
        height: 120,
        seeds: vec![1, 2],
        frames: 7,
        methods: rows(),
        curves: curves(),
    }
}

#[test]
fn eval_render() {
    let files = eval_report().render();
    pinned("report.md", &files.report);
    pinned(
        "results.json",
        &serde_json::to_string_pretty(&files.results).expect("json"),
    );
    let names: Vec<&str> = files.plots.iter().map(|p| p.0).collect();
    assert_eq!(
        names,
        [
            "methods.svg",
            "degradation_rotation.svg",
            "degradation_translation.svg"
        ]
    );
    assert_eq!(files.plots[0].1, methods_chart(&rows()).to_svg());
    pinned("degradation_rotation.svg", &files.plots[1].1);
    pinned("degradation_translation.svg", &files.plots[2].1);
}

#[test]
fn eval_write() {
    let dir = tempfile::tempdir().expect("tempdir");
    let files = eval_report().render();
    let plots = files.write(dir.path()).expect("write");
    assert_eq!(plots.len(), 3);
    for (path, (name, svg)) in plots.iter().zip(&files.plots) {
        assert_eq!(path, &dir.path().join(name));
        assert_eq!(&std::fs::read_to_string(path).expect("plot"), svg);
    }
    assert_eq!(
        std::fs::read_to_string(dir.path().join("report.md")).expect("report"),
        files.report
    );
    assert_eq!(
        std::fs::read_to_string(dir.path().join("results.json")).expect("results"),
        serde_json::to_string_pretty(&files.results).expect("json")
    );
    let mut names: Vec<String> = std::fs::read_dir(dir.path())
        .expect("dir")
        .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    assert_eq!(
        names,
        [
            "degradation_rotation.svg",
            "degradation_translation.svg",
            "methods.svg",
            "report.md",
            "results.json"
        ]
    );
    // A folder in the way: the error names the plot being written.
    let blocked = tempfile::tempdir().expect("tempdir");
    std::fs::create_dir(blocked.path().join("methods.svg")).expect("mkdir");
    let e = files
        .write(blocked.path())
        .expect_err("a folder is not replaced");
    let shown = e.to_string();
    assert_eq!(
        shown,
        format!("writing {}", blocked.path().join("methods.svg").display())
    );
    // report.md in the way: pa-io's error as it is (no "writing" before it).
    let blocked = tempfile::tempdir().expect("tempdir");
    std::fs::create_dir(blocked.path().join("report.md")).expect("mkdir");
    let e = files
        .write(blocked.path())
        .expect_err("a folder is not replaced");
    assert_eq!(
        e.to_string(),
        format!(
            "{}: is a folder, not a regular file",
            blocked.path().join("report.md").display()
        )
    );
}

fn bench_row(render_path: &'static str, props: u32, base: f64) -> BenchRow {
    let s = |m: f64| Stat {
        median: m,
        p95: m * 1.5,
    };
    BenchRow {
        render_path,
        width: 160,
        height: 120,
        requested_vertices: 2000,
        actual_vertices: 2048,
        props,
        frames: 3,
        tracked: 2,
        stages: STAGES
            .iter()
            .enumerate()
            .map(|(i, n)| (*n, s(base + i as f64)))
            .collect(),
        gpu_wait: s(0.5),
        end_to_end: s(base * 10.0),
        psnr_prop: if props == 1 { Some(31.257) } else { None },
        peak_rss_mb: if props == 1 { Some(123.4) } else { None },
        rss_start_mb: Some(100.0),
        peak_scope: "timed loop",
        held_mb: 1.5,
        seconds: 2.25,
        load_start: Some(base),
        load_end: if props == 1 { Some(0.75) } else { None },
    }
}

fn bench_report() -> BenchReport {
    BenchReport {
        adapter: "llvmpipe (LLVM 19.1.7, 256 bits) (Vulkan, Cpu)".into(),
        backend: "Vulkan".into(),
        cpu: "Some CPU @ 2.00GHz".into(),
        cores: 2,
        load_start: Some(1.5),
        load_end: None,
        method: "ours (live texturing + visibility, ray fill, 4 px dilation)",
        auto_path: "cpu",
        frames: 3,
        warmup: 3,
        seed: 1,
        total_seconds: 12.5,
        rows: vec![bench_row("gpu", 1, 2.0), bench_row("cpu", 4, 1.25)],
    }
}

#[test]
fn bench_table() {
    assert_eq!(
        table(&bench_report().rows),
        "| path | size | vertices | props | track | animate | texture | diminish | composite | readback | end-to-end | fps | prop PSNR dB | peak RSS MiB | tracked | load start / end |\n\
         |---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n\
         | gpu | 160x120 | 2048 | 1 | 2.0 / 3.0 | 3.0 / 4.5 | 4.0 / 6.0 | 5.0 / 7.5 | 6.0 / 9.0 | 7.0 / 10.5 | 20.0 / 30.0 | 50.0 | 31.26 | 123 | 2/3 | 2.00 / 0.75 |\n\
         | cpu | 160x120 | 2048 | 4 | 1.2 / 1.9 | 2.2 / 3.4 | 3.2 / 4.9 | 4.2 / 6.4 | 5.2 / 7.9 | 6.2 / 9.4 | 12.5 / 18.8 | 80.0 | - | n/a | 2/3 | 1.25 / n/a |\n"
    );
}

#[test]
fn bench_markdown_and_json() {
    let report = bench_report();
    pinned("bench.md", &report.markdown());
    pinned(
        "bench.json",
        &serde_json::to_string_pretty(&report.json()).expect("json"),
    );
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("bench.json");
    report.write_json(&path).expect("write");
    assert_eq!(
        std::fs::read_to_string(&path).expect("read"),
        serde_json::to_string_pretty(&report.json()).expect("json")
    );
    let e = report.write_json(dir.path()).expect_err("a folder");
    assert_eq!(e.to_string(), format!("writing {}", dir.path().display()));
}

#[test]
fn charts() {
    let line = LineChart {
        title: "PSNR".into(),
        x_label: "rotation, deg".into(),
        y_label: "PSNR, dB".into(),
        series: vec![
            Series {
                name: "a".into(),
                points: vec![(0.0, 30.0), (10.0, 25.0)],
                scatter: vec![(5.0, 27.0)],
            },
            Series {
                name: "b <c>".into(),
                points: vec![(2.0, 28.0)],
                scatter: vec![],
            },
        ],
        x_from_zero: true,
        note: "a note".into(),
    };
    pinned("line.svg", &line.to_svg());
    let bars = BarChart {
        title: "Bars".into(),
        value_label: "dB".into(),
        categories: vec!["one".into(), "two".into()],
        groups: vec![
            BarGroup {
                name: "g1".into(),
                values: vec![Some(3.0), None],
            },
            BarGroup {
                name: "g2".into(),
                values: vec![Some(-1.5), Some(2.0)],
            },
        ],
        baseline: Some(1),
        note: String::new(),
    };
    pinned("bar.svg", &bars.to_svg());
}
