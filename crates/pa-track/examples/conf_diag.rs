//! Diagnostics on the conformance photos (`../shared/conformance/markers/apriltag_swarmathon`).
//!
//! `cargo run --release -p pa-track --example conf_diag`: recall and corner difference from the
//! C library's detections for our detection modes.
//!
//! `... --example conf_diag -- --kornia`: for every tag the C library finds, what
//! kornia-apriltag 0.2's own pipeline makes of it (C-equivalent settings: decimation 1, split
//! 0.5, min_white_black_diff 5, no edge refinement): the boundary cluster, the best quad
//! near the tag (max corner distance from the C library's), and its decode. This is how the
//! misses were traced to the quad fit and the decoder (every tag has a cluster; one has no
//! quad; seven quads 0.13-0.65 px off fail to decode).

// A diagnostic tool: a failed read ends it with the panic's message.
#![allow(clippy::unwrap_used)]

use std::path::PathBuf;

use glam::DVec2;
use kornia_apriltag::{
    decoder::decode_tags,
    family::{TagFamily as KFamily, TagFamilyKind},
    quad::fit_quads,
    segmentation::{find_connected_components, find_gradient_clusters_cached},
    threshold::{adaptive_threshold_with_split, TileMinMax},
    union_find::UnionFind,
    utils::Pixel,
    DecodeTagsConfig,
};
use kornia_image::{Image, ImageSize};

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

/// Max corner distance under the best of the 8 square symmetries.
fn match_err(a: &[DVec2; 4], b: &[DVec2; 4]) -> f64 {
    let mut best = f64::INFINITY;
    for s in 0..4 {
        for dir in [1usize, 3] {
            let e = (0..4)
                .map(|i| a[i].distance(b[(s + i * dir) % 4]))
                .fold(0.0, f64::max);
            best = best.min(e);
        }
    }
    best
}

fn centre(c: &[DVec2; 4]) -> DVec2 {
    (c[0] + c[1] + c[2] + c[3]) * 0.25
}

fn qcorners(q: &kornia_apriltag::quad::Quad) -> [DVec2; 4] {
    std::array::from_fn(|i| DVec2::new(q.corners[i].x as f64, q.corners[i].y as f64))
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
    let fams = vec![(
        TagFamilyKind::Tag36H11,
        KFamily::try_from(&TagFamilyKind::Tag36H11).unwrap(),
    )];
    if !std::env::args().any(|a| a == "--kornia") {
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
        return;
    }
    if !std::env::args().any(|a| a == "--kornia") {
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
        return;
    }
    for jpg in names {
        let refs = parse_reference(&std::fs::read_to_string(jpg.with_extension("txt")).unwrap());
        let img = image::GrayImage::from(pa_track::GrayImage::from(&image::open(&jpg).unwrap()));
        let (w, h) = (img.width() as usize, img.height() as usize);
        let size = ImageSize {
            width: w,
            height: h,
        };
        let kimg = Image::<u8, 1>::new(size, img.as_raw().clone()).unwrap();
        println!("== {} ({w}x{h}), {} tags", jpg.display(), refs.len());
        let mut bin = Image::<Pixel, 1>::from_size_val(size, Pixel::Skip).unwrap();
        let mut tiles = TileMinMax::new(size, 4);
        adaptive_threshold_with_split(&kimg, &mut bin, &mut tiles, 5, 0.5).unwrap();
        let mut uf = UnionFind::new(w * h);
        find_connected_components(&bin, &mut uf).unwrap();
        let clusters = find_gradient_clusters_cached(&bin, &mut uf);
        let mut cfg = DecodeTagsConfig::new(vec![TagFamilyKind::Tag36H11]).unwrap();
        cfg.downscale_factor = 1;
        cfg.threshold_split = 0.5;
        cfg.refine_edges_enabled = false;
        let quads = fit_quads(&bin, &clusters, &cfg);
        // Merge the per-strip cluster maps.
        let mut merged: std::collections::HashMap<(usize, usize), Vec<(f64, f64)>> =
            Default::default();
        for m in &clusters {
            for (k, v) in m {
                merged.entry(*k).or_default().extend(
                    v.iter()
                        .map(|g| (g.pos.x as f64 * 0.5 + 0.5, g.pos.y as f64 * 0.5 + 0.5)),
                );
            }
        }
        for (ti, r) in refs.iter().enumerate() {
            let c = centre(r);
            let side = (0..4)
                .map(|i| r[i].distance(r[(i + 1) % 4]))
                .fold(f64::INFINITY, f64::min);
            let maxside = (0..4)
                .map(|i| r[i].distance(r[(i + 1) % 4]))
                .fold(0.0, f64::max);
            // Clusters whose points surround the reference quad's border.
            let mut cl: Vec<(usize, f64)> = Vec::new();
            for v in merged.values() {
                let near = v
                    .iter()
                    .filter(|(x, y)| {
                        let p = DVec2::new(*x, *y);
                        (0..4).any(|i| {
                            let (a, b) = (r[i], r[(i + 1) % 4]);
                            let t = ((p - a).dot(b - a) / (b - a).length_squared()).clamp(0.0, 1.0);
                            (a + (b - a) * t).distance(p) < 1.0
                        })
                    })
                    .count();
                if near * 2 > v.len() && near > 10 {
                    cl.push((v.len(), near as f64 / v.len() as f64));
                }
            }
            let mut best_q: Option<(f64, &kornia_apriltag::quad::Quad)> = None;
            for q in &quads {
                let qc = qcorners(q);
                if centre(&qc).distance(c) < 0.3 * side {
                    let e = match_err(&qc, r);
                    if best_q.is_none_or(|(be, _)| e < be) {
                        best_q = Some((e, q));
                    }
                }
            }
            let dec = best_q.map(|(_, q)| {
                let mut qs = vec![q.clone()];
                decode_tags(&kimg, &mut qs, &fams, false, 0.25, 2.0)
            });
            let ok = dec.as_ref().is_some_and(|d| d.iter().any(|d| d.id == 0));
            println!(
                "tag {ti:2} c=({:6.1},{:6.1}) side {side:5.1}-{maxside:5.1} clusters {:?} quad {} decode {}",
                c.x,
                c.y,
                cl,
                best_q.map_or("none".into(), |(e, _)| format!("err {e:.3}")),
                match &dec {
                    None => "-".into(),
                    Some(d) => format!(
                        "{:?}",
                        d.iter()
                            .map(|d| (d.id, d.hamming, d.decision_margin))
                            .collect::<Vec<_>>()
                    ),
                }
            );
            let _ = ok;
        }
    }
}
