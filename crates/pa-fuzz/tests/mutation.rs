//! The fuzz targets as a bounded, deterministic mutation test (part of `cargo test`).
//!
//! For each target: every seed of `corpus/<target>/` and every regression file of
//! `regressions/<target>/` must run without a panic; then a fixed number of mutants of them
//! (fixed seed: the same inputs on every run) must too. Regressions listed in
//! `regressions/OPEN.txt` (crashes not fixed yet) are skipped, with a line saying so, and a
//! mutant that panics where an open regression panics (an entry whose note starts with
//! `panicked at`) counts as known, not as a failure.
//!
//! A new crash fails the test: the input, minimised, is written to
//! `target/pa-fuzz-crashes/<target>/<name>` and the failure says how to keep it as a
//! regression file. `PA_FUZZ_EXECS=N` runs N mutants per target instead of the default (for
//! a longer local run); `PA_FUZZ_SEED=N` changes the mutation seed.

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::time::{Duration, Instant};

use pa_fuzz::harness::{self, Crash};
use pa_fuzz::mutate::{parse_dictionary, Mutator};

/// Mutants per target in a plain `cargo test` (a few seconds in the test profile).
fn default_execs(target: &str) -> usize {
    match target {
        "gltf" => 50_000,
        "shot" => 25_000,
        "calibration" => 50_000,
        "mp4" => 25_000,
        "still" => 25_000,
        _ => 1000,
    }
}

/// Slower than this, one input is reported (not failed: debug builds vary).
const SLOW: Duration = Duration::from_secs(2);

fn target_dir() -> PathBuf {
    std::env::var_os("CARGO_TARGET_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| harness::crate_dir().join("../../target"))
}

fn env_usize(name: &str) -> Option<usize> {
    std::env::var(name).ok().and_then(|v| v.trim().parse().ok())
}

struct Report {
    failures: Vec<String>,
}

fn fuzz(name: &str) {
    let target = pa_fuzz::target(name).expect("a target of that name");
    let mut report = Report {
        failures: Vec::new(),
    };
    let open = harness::open_regressions();
    let is_open = |path: &std::path::Path| {
        let rel = format!(
            "{name}/{}",
            path.file_name().unwrap_or_default().to_string_lossy()
        );
        open.iter().find(|o| o.path == rel)
    };

    // Seeds.
    let seeds: Vec<(PathBuf, Vec<u8>)> = harness::files_in(&harness::corpus_dir(name))
        .into_iter()
        .map(|p| {
            let b = std::fs::read(&p).expect("read seed");
            (p, b)
        })
        .collect();
    assert!(
        !seeds.is_empty(),
        "no seeds in {}",
        harness::corpus_dir(name).display()
    );
    for (p, data) in &seeds {
        if let Err(c) = harness::run_caught(target, data) {
            report.failures.push(format!("seed {}: {c}", p.display()));
        }
    }

    // Regressions; the open ones give the crash locations already known.
    let mut known: BTreeMap<String, String> = BTreeMap::new();
    let mut pool: Vec<Vec<u8>> = seeds.iter().map(|(_, b)| b.clone()).collect();
    let regressions = harness::files_in(&harness::regressions_dir(name));
    let mut skipped = 0;
    for p in &regressions {
        let data = std::fs::read(p).expect("read regression");
        if let Some(o) = is_open(p) {
            skipped += 1;
            println!(
                "{name}: skipped open regression {} (OPEN.txt: {})",
                o.path, o.note
            );
            continue;
        }
        match harness::run_caught(target, &data) {
            Ok(()) => pool.push(data),
            Err(c) => report
                .failures
                .push(format!("regression {}: {c}", p.display())),
        }
    }
    // The crash sites of open regressions: the panicking ones (note `panicked at ...`) run
    // once here, caught, so that mutants reaching the same site count as known (the site is
    // taken from the code as it is, not from the note). Hangs, aborts and running out of
    // memory are never run. An entry whose file is missing is reported; a panicking one
    // that runs clean is reported as fixed.
    for o in open
        .iter()
        .filter(|o| o.path.starts_with(&format!("{name}/")))
    {
        if !o.note.starts_with("panicked at") {
            continue;
        }
        let p = harness::crate_dir().join("regressions").join(&o.path);
        match std::fs::read(&p) {
            Err(_) => println!(
                "{name}: OPEN.txt lists {} but {} does not exist",
                o.path,
                p.display()
            ),
            Ok(data) => match harness::run_caught(target, &data) {
                Ok(()) => println!(
                    "{name}: open regression {} no longer panics: take it off OPEN.txt",
                    o.path
                ),
                Err(c) => {
                    known.insert(c.location.clone(), o.path.clone());
                }
            },
        }
    }

    // Mutants.
    let execs = env_usize("PA_FUZZ_EXECS").unwrap_or_else(|| default_execs(name));
    let seed = env_usize("PA_FUZZ_SEED").unwrap_or(0) as u64
        ^ harness::content_name(name.as_bytes())
            .chars()
            .fold(0u64, |h, c| h.wrapping_mul(31).wrapping_add(c as u64));
    let dict_path = harness::crate_dir()
        .join("dict")
        .join(format!("{name}.dict"));
    let dictionary = std::fs::read_to_string(&dict_path)
        .map(|t| parse_dictionary(&t))
        .unwrap_or_default();
    let longest = pool.iter().map(Vec::len).max().unwrap_or(0);
    let mut mutator = Mutator::new(seed, dictionary, (2 * longest + 1024).min(256 << 10));
    let mut new_crashes: BTreeMap<String, (Crash, PathBuf)> = BTreeMap::new();
    let mut known_hits = 0usize;
    let mut slowest = (Duration::ZERO, 0usize);
    // The input being run, on disk: if the process dies (out of memory, stack overflow, a
    // hang killed from outside), it is there.
    let current_dir = target_dir().join("pa-fuzz-current");
    let _ = std::fs::create_dir_all(&current_dir);
    let current = current_dir.join(name);
    let started = Instant::now();
    for i in 0..execs {
        let base = &pool[i % pool.len()];
        let input = mutator.mutate(base, &pool);
        // (Unlinked first: see `scratch_file`; rewriting in place costs a flush on ext4.)
        let _ = std::fs::remove_file(&current);
        let _ = std::fs::write(&current, &input);
        let t0 = Instant::now();
        let result = harness::run_caught(target, &input);
        let took = t0.elapsed();
        if took > slowest.0 {
            slowest = (took, i);
        }
        if took > SLOW {
            let dir = target_dir().join("pa-fuzz-slow").join(name);
            let _ = std::fs::create_dir_all(&dir);
            let path = dir.join(harness::content_name(&input));
            let _ = std::fs::write(&path, &input);
            println!(
                "{name}: mutant {i} took {:.1} s (saved as {})",
                took.as_secs_f64(),
                path.display()
            );
        }
        let Err(crash) = result else { continue };
        if known.contains_key(&crash.location) {
            known_hits += 1;
            continue;
        }
        if new_crashes.contains_key(&crash.location) {
            continue;
        }
        let small = harness::minimise(target, &input, &crash, 3000);
        let dir = target_dir().join("pa-fuzz-crashes").join(name);
        std::fs::create_dir_all(&dir).expect("crash folder");
        let path = dir.join(harness::content_name(&small));
        std::fs::write(&path, &small).expect("write crash");
        println!(
            "{name}: mutant {i} {crash}; minimised to {} bytes: {}",
            small.len(),
            path.display()
        );
        new_crashes.insert(crash.location.clone(), (crash, path));
    }
    let elapsed = started.elapsed();
    let _ = std::fs::remove_file(&current);
    pa_fuzz::cleanup();
    println!(
        "{name}: {} seed(s), {} regression file(s) ({skipped} open, skipped), {execs} mutants in {:.2} s ({:.0}/s), slowest {:.0} ms (mutant {}), {known_hits} hit a known open crash, {} new crash site(s)",
        seeds.len(),
        regressions.len(),
        elapsed.as_secs_f64(),
        execs as f64 / elapsed.as_secs_f64().max(1e-9),
        slowest.0.as_secs_f64() * 1e3,
        slowest.1,
        new_crashes.len()
    );
    for (crash, path) in new_crashes.values() {
        report.failures.push(format!(
            "new crash: {crash}\n  input: {}\n  keep it: cp {} crates/pa-fuzz/regressions/{name}/<short-name>  (and list it in regressions/OPEN.txt until it is fixed)",
            path.display(),
            path.display()
        ));
    }
    assert!(
        report.failures.is_empty(),
        "{name}: {} failure(s):\n{}",
        report.failures.len(),
        report.failures.join("\n")
    );
}

#[test]
fn gltf() {
    fuzz("gltf");
}

#[test]
fn shot() {
    fuzz("shot");
}

#[test]
fn calibration() {
    fuzz("calibration");
}

#[test]
fn mp4() {
    fuzz("mp4");
}

#[test]
fn still() {
    fuzz("still");
}

/// The seeds reach the deep end of each target: they are accepted, not just survived.
#[test]
fn seeds_are_valid_inputs() {
    let seeds = |t: &str| harness::files_in(&harness::corpus_dir(t));
    for p in seeds("gltf") {
        let model = pa_fuzz::load_gltf(&std::fs::read(&p).expect("read"))
            .unwrap_or_else(|e| panic!("{}: {e}", p.display()));
        if !p.ends_with("empty.gltf") {
            assert!(model.vertex_count() > 0, "{}", p.display());
        }
    }
    for p in seeds("shot") {
        pa_pipeline::shot::Shot::load(&p).unwrap_or_else(|e| panic!("{e}"));
    }
    for p in seeds("calibration") {
        pa_camera::calib::load_calibration(&p).unwrap_or_else(|e| panic!("{e}"));
    }
    for p in seeds("mp4") {
        let frames = pa_video::VideoReader::open(&p)
            .unwrap_or_else(|e| panic!("{e}"))
            .collect::<Result<Vec<_>, _>>()
            .unwrap_or_else(|e| panic!("{e}"));
        assert!(frames.len() >= 2, "{}", p.display());
    }
    for p in seeds("still") {
        pa_fuzz::open_still(&std::fs::read(&p).expect("read"))
            .unwrap_or_else(|e| panic!("{}: {e}", p.display()));
    }
    pa_fuzz::cleanup();
}

/// Every target has a seed folder and a regression folder, and OPEN.txt names only files of
/// known targets.
#[test]
fn layout() {
    for (name, _) in pa_fuzz::TARGETS {
        assert!(harness::corpus_dir(name).is_dir(), "corpus/{name}");
        assert!(
            harness::regressions_dir(name).is_dir(),
            "regressions/{name}"
        );
    }
    for o in harness::open_regressions() {
        let target = o.path.split('/').next().unwrap_or_default();
        assert!(
            pa_fuzz::target(target).is_some(),
            "OPEN.txt: {} is not under a target's folder",
            o.path
        );
    }
}
