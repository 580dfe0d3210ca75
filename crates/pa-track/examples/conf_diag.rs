//! Diagnostics on the conformance photos (`../shared/conformance/markers/apriltag_swarmathon`).
//!
//! `cargo run --release -p pa-track --example conf_diag`: recall and corner difference from the
//! C library's detections for our detection modes. (Its former `--kornia` mode ran
//! kornia-apriltag 0.2's own pipeline on the same tags, which traced that library's misses to
//! its quad fit and decoder; it went with the dependency, see git history.)

// A diagnostic tool: a failed read ends it with the panic's message.
#![allow(clippy::unwrap_used)]

use std::path::PathBuf;

use glam::DVec2;

fn parse_reference(text: &str) -> Vec<[DVec2; 4]> {
    text.lines()
        .filter(|l| !l.trim().is_empty())
        .map(|l| {
            let v: Vec<f64> = l
                .replace(['(', ')', ','], " ")
                .split_whitespace()
                .map(|t| t.parse::<f64>().unwrap())
                .collect();
            let p = |i: usize| DVec2::new(v[1 + 2 * i], v[2 + 2 * i]);
            [p(0), p(1), p(2), p(3)]
        })
        .collect()
}

/// Found (max corner error < 2 px) and median corner error of a configuration over all
/// photos, grey = Rec. 601 luma.
fn summary(names: &[PathBuf], name: &str, cfg: pa_track::DetectorConfig) {
    let mut det = pa_track::Detector::new(cfg).unwrap();
    let (mut found, mut total, mut errs, mut misses) = (0, 0, Vec::new(), Vec::new());
    for jpg in names {
        let refs = parse_reference(&std::fs::read_to_string(jpg.with_extension("txt")).unwrap());
        let g = pa_track::GrayImage::from(&image::open(jpg).unwrap());
        let dets = det.detect(&g).unwrap();
        for (ti, r) in refs.iter().enumerate() {
            total += 1;
            let r2 = r.map(|p| p - DVec2::splat(0.5));
            // Our order is the C library's [p3, p2, p1, p0].
            let want = [r2[3], r2[2], r2[1], r2[0]];
            let best = dets
                .iter()
                .map(|d| {
                    (0..4)
                        .map(|i| d.corners_px[i].distance(want[i]))
                        .collect::<Vec<_>>()
                })
                .min_by(|a, b| {
                    a.iter()
                        .cloned()
                        .fold(0.0, f64::max)
                        .total_cmp(&b.iter().cloned().fold(0.0, f64::max))
                });
            match best {
                Some(e) if e.iter().cloned().fold(0.0, f64::max) < 2.0 => {
                    found += 1;
                    errs.extend(e);
                }
                _ => misses.push(format!(
                    "{}#{ti}",
                    jpg.file_name()
                        .unwrap()
                        .to_string_lossy()
                        .chars()
                        .take(5)
                        .collect::<String>()
                )),
            }
        }
    }
    errs.sort_by(f64::total_cmp);
    let med = errs.get(errs.len() / 2).copied().unwrap_or(f64::NAN);
    let p90 = errs.get(errs.len() * 9 / 10).copied().unwrap_or(f64::NAN);
    println!(
        "{name:40} found {found}/{total}, median {med:.4} px, p90 {p90:.3} px, missed {misses:?}"
    );
}

fn main() {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../../shared/conformance/markers/apriltag_swarmathon");
    if !dir.is_dir() {
        println!("skipped: conformance data not found at {}", dir.display());
        return;
    }
    let mut names: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap()
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "jpg"))
        .collect();
    names.sort();
    {
        use pa_track::DetectorConfig as C;
        let d = C::default;
        for (n, c) in [
            ("default", d()),
            ("default thorough", d().thorough()),
            (
                "default, no 2nd pass",
                C {
                    second_pass_decimate: None,
                    ..d()
                },
            ),
            (
                "default, no refine",
                C {
                    refine_edges: false,
                    ..d()
                },
            ),
            (
                "default, no refine, no 2nd",
                C {
                    refine_edges: false,
                    second_pass_decimate: None,
                    ..d()
                },
            ),
            (
                "default, no refine, thorough",
                C {
                    refine_edges: false,
                    ..d()
                }
                .thorough(),
            ),
            ("c_reference", C::c_reference()),
            ("c_reference thorough", C::c_reference().thorough()),
            (
                "default wb5",
                C {
                    min_white_black_diff: 5,
                    ..d()
                },
            ),
            (
                "default dec 2 only",
                C {
                    decimate: 2,
                    second_pass_decimate: None,
                    ..d()
                },
            ),
        ] {
            summary(&names, n, c);
        }
    }
}
