//! Test helpers shared by the crates: locating `../shared/conformance` and reading its
//! skinning references, and golden-image comparison ([`golden`]). Only ever a dev-dependency.

pub mod golden;
pub mod hostile;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// The conformance folder (`PROPSALIVE_CONFORMANCE`, else `<workspace>/../shared/conformance`),
/// or `None` after printing why the test is skipped.
pub fn conformance_dir() -> Option<PathBuf> {
    let dir = std::env::var_os("PROPSALIVE_CONFORMANCE")
        .map(PathBuf::from)
        .unwrap_or_else(|| {
            Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/conformance")
        });
    if dir.join("skinning-refs").is_dir() {
        Some(dir)
    } else {
        println!("skipped: conformance data not found at {}", dir.display());
        None
    }
}

/// `gltf/<Model>/glTF-Binary/<file>.glb`, else the `.gltf` (or embedded) variant.
pub fn model_file(root: &Path, source_file: &str) -> PathBuf {
    let stem = Path::new(source_file)
        .file_stem()
        .and_then(|s| s.to_str())
        .unwrap_or(source_file);
    let gltf = root.join("gltf");
    for entry in std::fs::read_dir(&gltf).expect("gltf dir").flatten() {
        for variant in ["glTF-Binary", "glTF", "glTF-Embedded"] {
            let candidate = entry.path().join(variant).join(source_file);
            if candidate.is_file() {
                return candidate;
            }
        }
    }
    panic!(
        "model {stem} ({source_file}) not found under {}",
        gltf.display()
    )
}

#[derive(serde::Deserialize)]
pub struct Reference {
    pub source_file: String,
    pub samples: Vec<Sample>,
}

#[derive(serde::Deserialize)]
pub struct Sample {
    pub animation: usize,
    pub time_s: f64,
    pub positions: BTreeMap<String, Positions>,
}

#[derive(serde::Deserialize)]
pub struct Positions {
    pub xyz: Vec<f64>,
}

impl std::ops::Deref for Positions {
    type Target = Vec<f64>;
    fn deref(&self) -> &Vec<f64> {
        &self.xyz
    }
}

impl Reference {
    pub fn load(path: &Path) -> Self {
        let text = std::fs::read_to_string(path).expect("reference readable");
        serde_json::from_str(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
    }
}

impl Sample {
    /// Bounding-box diagonal of all reference positions of this sample.
    pub fn diagonal(&self) -> f64 {
        let mut lo = [f64::MAX; 3];
        let mut hi = [f64::MIN; 3];
        for p in self.positions.values() {
            for v in p.xyz.chunks_exact(3) {
                for k in 0..3 {
                    lo[k] = lo[k].min(v[k]);
                    hi[k] = hi[k].max(v[k]);
                }
            }
        }
        ((hi[0] - lo[0]).powi(2) + (hi[1] - lo[1]).powi(2) + (hi[2] - lo[2]).powi(2)).sqrt()
    }
}
