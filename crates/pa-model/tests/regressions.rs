//! Every file in `tests/regressions/` (hostile inputs of past bugs, named after the bug, and
//! files a fuzzer adds) must be refused with an error, never a panic.
//!
//! `PA_MODEL_WRITE_REGRESSIONS=1 cargo test -p pa-model --test regressions` (re)writes the
//! copies of the cases built in `common`.

mod common;

use std::path::PathBuf;

fn folder() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/regressions")
}

#[test]
fn the_cases_built_in_code_have_their_copy_in_the_folder() {
    let write = std::env::var_os("PA_MODEL_WRITE_REGRESSIONS").is_some();
    for case in common::all_cases() {
        let path = folder().join(case.name);
        if write {
            std::fs::write(&path, &case.bytes).expect("write regression file");
        }
        let stored = std::fs::read(&path).unwrap_or_else(|e| {
            panic!(
                "{}: {e} (run with PA_MODEL_WRITE_REGRESSIONS=1 to write it)",
                path.display()
            )
        });
        assert!(
            stored == case.bytes,
            "{} differs from its case",
            path.display()
        );
    }
}

#[test]
fn every_file_in_the_regressions_folder_is_refused_without_a_panic() {
    let mut entries: Vec<PathBuf> = std::fs::read_dir(folder())
        .expect("tests/regressions")
        .filter_map(|e| e.ok())
        .map(|e| e.path())
        .filter(|p| p.is_file())
        .collect();
    entries.sort();
    assert!(!entries.is_empty());
    let mut failures = Vec::new();
    for path in &entries {
        let outcome = std::panic::catch_unwind(|| pa_model::Model::load(path));
        match outcome {
            Ok(Err(e)) => {
                let msg = e.to_string();
                assert!(
                    msg.contains(&*path.to_string_lossy()),
                    "names the file: {msg}"
                );
            }
            Ok(Ok(_)) => failures.push(format!("{}: loaded", path.display())),
            Err(_) => failures.push(format!("{}: panicked", path.display())),
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}
