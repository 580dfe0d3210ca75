//! `propsalive run --scan`: the scan pass before a take, end to end on a small generated take
//! (its own stills, which show the key prop in its key pose, serve as the scan).

mod common;

use std::collections::BTreeMap;
use std::path::Path;

use common::{files, lock, run, stderr};

const STILLS: u32 = 6;

fn frames(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    files(dir, "frames")
}

#[test]
fn a_scan_primes_the_take_and_is_part_of_its_settings() {
    let _l = lock();
    let Some(take) = common::generate_take("run_scan_", STILLS, 320, 180) else {
        return;
    };
    let scan = take.stills.to_str().expect("utf-8 path");
    let out = take.root.join("scanned");
    let o = run(&take.shot, &take.stills, &out, &["--scan", scan]);
    let err = stderr(&o);
    assert!(o.status.success(), "{err}");
    // Progress: every scan still read, and the tracked ones remembered.
    let line = err
        .lines()
        .find(|l| l.starts_with(&format!("scan: {STILLS} frames read, ")))
        .unwrap_or_else(|| panic!("no scan summary: {err}"));
    let used: usize = line
        .split(", ")
        .nth(1)
        .and_then(|s| s.split(' ').next())
        .and_then(|n| n.parse().ok())
        .expect("count");
    assert!(used >= 1, "{line}");
    // The memory changed what the twin shows where the frame does not see the key prop.
    let with = frames(&out);
    let without = frames(&take.reference);
    assert_eq!(with.len(), without.len());
    assert!(
        with.iter().any(|(k, v)| without.get(k) != Some(v)),
        "the scan changed no frame"
    );
    // Resume with the same scan: nothing to do, the frames unchanged.
    let again = run(&take.shot, &take.stills, &out, &["--scan", scan]);
    assert!(again.status.success(), "{}", stderr(&again));
    assert!(
        stderr(&again).contains(&format!("0 processed, {STILLS} resumed")),
        "{}",
        stderr(&again)
    );
    assert_eq!(frames(&out), with);
    // Without the scan the take's settings differ: refused without --force.
    let other = run(&take.shot, &take.stills, &out, &[]);
    assert!(!other.status.success(), "{}", stderr(&other));
    // A camera is not a scan.
    let cam = run(&take.shot, &take.stills, &out, &["--scan", "camera:0"]);
    assert!(!cam.status.success());
    assert!(stderr(&cam).contains("--scan"), "{}", stderr(&cam));
}
