//! The crate graph's invariants (ARCHITECTURE.md, "Architecture invariants"), checked on
//! `cargo metadata --no-deps`: which crates of ours each crate may depend on, which crates may
//! name `wgpu` and `winit`, and what must stay out of reach of the GPU-free crates.
//!
//! Normal and build dependencies are what the rules restrict; dev-dependencies (tests, examples,
//! benches) may use any library of ours except the fuzz targets. A failure names each offending
//! edge and the rule it breaks. A new crate fails here until it has a row in `ALLOWED`.

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;
use std::process::Command;

use serde_json::Value;

/// The binary; every other crate of ours is a library.
const BINARY: &str = "propsalive";

/// Test-only crates: no normal or build dependency of any crate may name them.
const TEST_ONLY: &[&str] = &["pa-testkit", "pa-fuzz"];

/// Per crate, the crates of ours its normal and build dependencies may name (`ANY_LIBRARY`: any
/// library of ours that is not test-only), and why. Dropping a dependency is always allowed;
/// adding one outside its row is an architecture change: change ARCHITECTURE.md with the row.
const ALLOWED: &[(&str, &[&str], &str)] = &[
    ("pa-io", &[], "safe file I/O is the bottom of the graph"),
    (
        "pa-camera",
        &["pa-io"],
        "the camera model depends only on pa-io",
    ),
    ("pa-diminish", &[], "the diminish stage is pure image math"),
    (
        "pa-raster",
        &["pa-camera"],
        "the CPU rasteriser takes plain slices",
    ),
    (
        "pa-track",
        &["pa-camera"],
        "the tracker never sees meshes or GPUs",
    ),
    (
        "pa-model",
        &["pa-io"],
        "the model knows nothing of rendering",
    ),
    (
        "pa-video",
        &["pa-io"],
        "video in/out knows nothing of the stages",
    ),
    (
        "pa-render",
        &["pa-camera", "pa-raster"],
        "the renderer takes plain CpuMesh/CpuTexture data, no glTF types",
    ),
    (
        "pa-calib",
        &["pa-camera", "pa-track", "pa-io"],
        "calibration is upstream of the tracker",
    ),
    (
        "pa-pipeline",
        &[
            "pa-camera",
            "pa-io",
            "pa-track",
            "pa-model",
            "pa-render",
            "pa-raster",
            "pa-diminish",
        ],
        "the wiring of the per-frame stages",
    ),
    (
        "pa-scene",
        &[
            "pa-camera",
            "pa-track",
            "pa-model",
            "pa-render",
            "pa-pipeline",
            "pa-diminish",
        ],
        "the scene generator drives the pipeline on the built-in set",
    ),
    (
        "pa-report",
        &["pa-io", "pa-camera", "pa-track"],
        "reports take plain numbers (and the tracker's per-frame outputs): no renderer, no pipeline",
    ),
    (
        "pa-overlay",
        &["pa-camera", "pa-track"],
        "CPU drawing for people (preview overlays, marker sheets) needs only the camera and the tag families",
    ),
    (
        "pa-take",
        &["pa-io", "pa-camera", "pa-video", "pa-track"],
        "a take on disk (log, resume, passes, camera export, MP4) needs no pipeline or GPU",
    ),
    ("pa-testkit", &[], "test helpers stand alone"),
    ("pa-fuzz", ANY_LIBRARY, "fuzz targets may call any library"),
    (BINARY, ANY_LIBRARY, "the binary wires everything"),
];

/// Marker for `ALLOWED`: any library of ours that is not test-only.
const ANY_LIBRARY: &[&str] = &["*"];

/// The stages of the per-frame pipeline in data-flow order (frame -> track -> place -> animate
/// -> texture -> diminish -> composite -> output) and the crates that implement each alone.
/// `place` and `composite` live in the wiring (`pa-pipeline`); `pa-video` is both ends.
const STAGES: &[(&str, &[&str])] = &[
    ("frame/output", &["pa-video"]),
    ("track", &["pa-track"]),
    ("animate", &["pa-model"]),
    ("texture", &["pa-render", "pa-raster"]),
    ("diminish", &["pa-diminish"]),
];

/// The only crates whose dependencies (of any kind) may name these third-party crates.
const THIRD_PARTY: &[(&str, &[&str])] = &[
    ("wgpu", &["pa-render", "pa-pipeline", BINARY]),
    ("winit", &[BINARY]),
];

/// Crates that must not reach the GPU even through other crates of ours (their normal
/// dependencies, transitively): the math of every stage is testable without a GPU.
const GPU_FREE: &[&str] = &[
    "pa-io",
    "pa-camera",
    "pa-track",
    "pa-model",
    "pa-raster",
    "pa-diminish",
    "pa-video",
    "pa-calib",
    "pa-report",
    "pa-overlay",
    "pa-take",
    "pa-testkit",
];

/// Crates nothing may reach through normal dependencies except the listed ones.
const RESTRICTED_USERS: &[(&str, &[&str], &str)] = &[
    (
        "pa-scene",
        &[BINARY, "pa-fuzz"],
        "the built-in set is for the binary and tests; the pipeline never knows it",
    ),
    (
        "pa-calib",
        &[BINARY, "pa-fuzz"],
        "nothing in the per-frame pipeline depends on calibration (it reaches the tracker as a file)",
    ),
];

/// Pairs (crate, crate of ours it must not reach through normal dependencies, transitively).
const NEVER_REACHES: &[(&str, &str, &str)] = &[
    (
        "pa-model",
        "pa-render",
        "pa-model knows nothing of rendering",
    ),
    (
        "pa-model",
        "pa-raster",
        "pa-model knows nothing of rendering",
    ),
    (
        "pa-track",
        "pa-render",
        "the tracker is testable without a GPU",
    ),
    (
        "pa-track",
        "pa-scene",
        "the tracker never knows the built-in set",
    ),
    ("pa-render", "pa-model", "no glTF types in GPU code"),
];

struct Package {
    /// Crates of ours named by normal or build dependencies.
    normal: BTreeSet<String>,
    /// Crates of ours named by dev-dependencies.
    dev: BTreeSet<String>,
    /// Every dependency's name, of any kind (third-party included).
    all: BTreeSet<String>,
    /// `publish = false`.
    unpublished: bool,
}

fn metadata() -> BTreeMap<String, Package> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let out = Command::new(env!("CARGO"))
        .args([
            "metadata",
            "--format-version",
            "1",
            "--no-deps",
            "--offline",
        ])
        .arg("--manifest-path")
        .arg(root.join("Cargo.toml"))
        .output()
        .expect("run cargo metadata");
    assert!(
        out.status.success(),
        "cargo metadata failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let meta: Value = serde_json::from_slice(&out.stdout).expect("cargo metadata's JSON");
    let packages = meta["packages"].as_array().expect("packages");
    let ours: BTreeSet<String> = packages
        .iter()
        .map(|p| p["name"].as_str().expect("package name").to_owned())
        .collect();
    let mut graph = BTreeMap::new();
    for p in packages {
        let name = p["name"].as_str().expect("package name").to_owned();
        let mut pkg = Package {
            normal: BTreeSet::new(),
            dev: BTreeSet::new(),
            all: BTreeSet::new(),
            // `publish = false` reads as an empty list of registries.
            unpublished: p["publish"].as_array().is_some_and(|r| r.is_empty()),
        };
        for d in p["dependencies"].as_array().expect("dependencies") {
            let dep = d["name"].as_str().expect("dependency name").to_owned();
            pkg.all.insert(dep.clone());
            if !ours.contains(&dep) {
                continue;
            }
            match d["kind"].as_str() {
                Some("dev") => pkg.dev.insert(dep),
                _ => pkg.normal.insert(dep),
            };
        }
        graph.insert(name, pkg);
    }
    graph
}

/// Crates of ours reachable from `from` through normal dependencies (without `from`).
fn reach(graph: &BTreeMap<String, Package>, from: &str) -> BTreeSet<String> {
    let mut seen = BTreeSet::new();
    let mut todo = vec![from.to_owned()];
    while let Some(c) = todo.pop() {
        for d in graph.get(&c).map(|p| &p.normal).into_iter().flatten() {
            if seen.insert(d.clone()) {
                todo.push(d.clone());
            }
        }
    }
    seen
}

/// A path of normal dependencies from `from` to `to`, for messages: `a -> b -> c`.
fn path(graph: &BTreeMap<String, Package>, from: &str, to: &str) -> String {
    let mut prev: BTreeMap<String, String> = BTreeMap::new();
    let mut todo = std::collections::VecDeque::from([from.to_owned()]);
    while let Some(c) = todo.pop_front() {
        if c == to {
            let mut chain = vec![c.clone()];
            let mut at = c;
            while let Some(p) = prev.get(&at) {
                chain.push(p.clone());
                at = p.clone();
            }
            chain.reverse();
            return chain.join(" -> ");
        }
        for d in graph.get(&c).map(|p| &p.normal).into_iter().flatten() {
            if d != from && !prev.contains_key(d) {
                prev.insert(d.clone(), c.clone());
                todo.push_back(d.clone());
            }
        }
    }
    format!("{from} -> ... -> {to}")
}

fn stage_of(krate: &str) -> Option<(usize, &'static str)> {
    STAGES
        .iter()
        .enumerate()
        .find(|(_, (_, crates))| crates.contains(&krate))
        .map(|(i, (stage, _))| (i, *stage))
}

fn check(graph: &BTreeMap<String, Package>) -> Vec<String> {
    let mut errors = Vec::new();
    let is_library = |c: &str| c != BINARY && !TEST_ONLY.contains(&c);

    // Every crate has a row, and every edge of ours is in its row.
    for (name, pkg) in graph {
        let Some((_, allowed, why)) = ALLOWED.iter().find(|(c, _, _)| c == name) else {
            errors.push(format!(
                "{name}: a new crate; give it a row in ALLOWED (crates/pa-testkit/tests/crate_graph.rs) \
                 and a place in ARCHITECTURE.md"
            ));
            continue;
        };
        for dep in &pkg.normal {
            let ok = if *allowed == ANY_LIBRARY {
                is_library(dep)
            } else {
                allowed.contains(&dep.as_str())
            };
            if !ok {
                errors.push(format!(
                    "{name} -> {dep}: not an allowed dependency of {name} ({why}; allowed: {})",
                    if *allowed == ANY_LIBRARY {
                        "any library that is not test-only".to_owned()
                    } else if allowed.is_empty() {
                        "no crate of ours".to_owned()
                    } else {
                        allowed.join(", ")
                    }
                ));
            }
        }
        // Dev-dependencies: any library of ours but the fuzz targets; never the binary.
        for dep in &pkg.dev {
            if dep == BINARY || dep == "pa-fuzz" {
                errors.push(format!(
                    "{name} -> {dep} (dev): tests may use the libraries and pa-testkit only"
                ));
            }
        }
    }

    // Test-only crates: nothing depends on them outside tests, and they are never published.
    for test_only in TEST_ONLY {
        for (name, pkg) in graph {
            if pkg.normal.contains(*test_only) {
                errors.push(format!(
                    "{name} -> {test_only}: {test_only} is test-only; use it from [dev-dependencies]"
                ));
            }
        }
        if graph.get(*test_only).is_some_and(|p| !p.unpublished) {
            errors.push(format!(
                "{test_only}: a test-only crate needs `publish = false`"
            ));
        }
    }

    // The pipeline flows one way: a stage's crates never depend on another stage's crates,
    // neither back up the pipeline nor down it; only the wiring (pa-pipeline) connects them.
    for name in graph.keys() {
        let Some((i, stage)) = stage_of(name) else {
            continue;
        };
        for dep in reach(graph, name) {
            let Some((j, dep_stage)) = stage_of(&dep) else {
                continue;
            };
            if i != j {
                let direction = if j < i { "back up" } else { "down" };
                errors.push(format!(
                    "{}: stage `{stage}` reaches {direction} the pipeline to stage `{dep_stage}`; \
                     stages meet only in pa-pipeline",
                    path(graph, name, &dep)
                ));
            }
        }
    }

    // Third-party crates only some crates may name.
    for (third, allowed) in THIRD_PARTY {
        for (name, pkg) in graph {
            if pkg.all.contains(*third) && !allowed.contains(&name.as_str()) {
                errors.push(format!(
                    "{name} -> {third}: only {} may depend on {third}",
                    allowed.join(", ")
                ));
            }
        }
    }

    // GPU-free crates do not reach wgpu through crates of ours either.
    for krate in GPU_FREE {
        if !graph.contains_key(*krate) {
            errors.push(format!(
                "{krate}: listed in GPU_FREE but not in the workspace"
            ));
            continue;
        }
        for dep in reach(graph, krate)
            .into_iter()
            .chain([krate.to_string()])
            .filter(|c| graph[c].all.contains("wgpu"))
        {
            errors.push(format!(
                "{} -> wgpu: {krate} must be testable without a GPU",
                path(graph, krate, &dep)
            ));
        }
    }

    for (target, users, why) in RESTRICTED_USERS {
        for (name, pkg) in graph {
            if pkg.normal.contains(*target) && !users.contains(&name.as_str()) {
                errors.push(format!(
                    "{name} -> {target}: only {} may depend on {target} ({why})",
                    users.join(", ")
                ));
            }
        }
    }

    for (from, to, why) in NEVER_REACHES {
        if reach(graph, from).contains(*to) {
            errors.push(format!("{}: {why}", path(graph, from, to)));
        }
    }
    errors
}

#[test]
fn the_crate_graph_keeps_the_architecture_invariants() {
    let graph = metadata();
    // Sanity: the metadata is this workspace's.
    for krate in ["pa-io", "pa-camera", "pa-pipeline", BINARY] {
        assert!(
            graph.contains_key(krate),
            "{krate} missing from cargo metadata"
        );
    }
    let errors = check(&graph);
    assert!(
        errors.is_empty(),
        "the crate graph breaks ARCHITECTURE.md's invariants:\n  {}",
        errors.join("\n  ")
    );
}

/// The checks catch what they claim to: a few edges that must fail, added to the real graph.
#[test]
fn forbidden_edges_are_named() {
    let cases: &[(&str, &str, &str)] = &[
        ("pa-track", "pa-render", "pa-track -> pa-render"),
        ("pa-model", "pa-raster", "pa-model -> pa-raster"),
        ("pa-io", "pa-camera", "pa-io -> pa-camera"),
        ("pa-pipeline", "pa-scene", "pa-pipeline -> pa-scene"),
        ("pa-render", "pa-testkit", "pa-render -> pa-testkit"),
        (
            "pa-diminish",
            "pa-track",
            "stage `diminish` reaches back up the pipeline",
        ),
        (
            "pa-video",
            "pa-model",
            "stage `frame/output` reaches down the pipeline",
        ),
    ];
    for (from, to, expected) in cases {
        let mut graph = metadata();
        graph
            .get_mut(*from)
            .expect("crate")
            .normal
            .insert(to.to_string());
        let errors = check(&graph);
        assert!(
            errors.iter().any(|e| e.contains(expected)),
            "{from} -> {to}: expected an error containing {expected:?}, got {errors:#?}"
        );
    }
    // Third party.
    let mut graph = metadata();
    let model = graph.get_mut("pa-model").expect("pa-model");
    model.all.insert("wgpu".into());
    model.all.insert("winit".into());
    let errors = check(&graph);
    for expected in [
        "pa-model -> wgpu: only",
        "pa-model -> winit: only",
        "pa-model -> wgpu: pa-model must be testable",
    ] {
        assert!(
            errors.iter().any(|e| e.contains(expected)),
            "expected an error containing {expected:?}, got {errors:#?}"
        );
    }
}
