//! CPU skinning against the independent references in `../shared/conformance/skinning-refs`.
//!
//! Tolerance: 1e-5 x the bounding-box diagonal of the model's reference positions at each
//! sample (the tolerance the conformance README calls fair; the references agree with Blender
//! and three.js to ~1e-6 of the diagonal).

use pa_testkit as common;

use pa_model::{anim, skin, Model};

const REL_TOL: f64 = 1e-5;

#[test]
fn cpu_skinning_matches_every_reference() {
    let Some(root) = common::conformance_dir() else {
        return;
    };
    let refs_dir = root.join("skinning-refs");
    let mut checked_models = 0;
    let mut entries: Vec<_> = std::fs::read_dir(&refs_dir)
        .expect("skinning-refs readable")
        .filter_map(|e| e.ok())
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|x| x == "json"))
        .collect();
    entries.sort();
    for ref_path in entries {
        let reference = common::Reference::load(&ref_path);
        let model_path = common::model_file(&root, &reference.source_file);
        let model = Model::load(&model_path).unwrap_or_else(|e| panic!("{e}"));
        let mut worst_rel = 0f64;
        for sample in &reference.samples {
            let pose = anim::sample(&model, sample.animation, sample.time_s as f32);
            let posed = skin::pose_meshes(&model, &pose);
            let diag = sample.diagonal();
            for (label, expected) in &sample.positions {
                let got = posed
                    .iter()
                    .find(|p| &p.label() == label)
                    .unwrap_or_else(|| {
                        panic!("{}: no posed primitive {label}", model_path.display())
                    });
                assert_eq!(
                    got.positions.len() * 3,
                    expected.len(),
                    "{label} vertex count"
                );
                for (i, p) in got.positions.iter().enumerate() {
                    let e = &expected[i * 3..i * 3 + 3];
                    let d = ((p.x as f64 - e[0]).powi(2)
                        + (p.y as f64 - e[1]).powi(2)
                        + (p.z as f64 - e[2]).powi(2))
                    .sqrt();
                    let rel = d / diag;
                    worst_rel = worst_rel.max(rel);
                    assert!(
                        rel <= REL_TOL,
                        "{}: animation {} t={} {label} vertex {i}: got {p}, expected {e:?} \
                         (error {rel:.2e} of the diagonal > {REL_TOL:e})",
                        reference.source_file,
                        sample.animation,
                        sample.time_s
                    );
                }
            }
        }
        println!(
            "{:<24} {} samples, worst error {:.2e} of the bbox diagonal",
            reference.source_file,
            reference.samples.len(),
            worst_rel
        );
        checked_models += 1;
    }
    assert!(
        checked_models >= 8,
        "expected the 8+ reference models, found {checked_models}"
    );
}
