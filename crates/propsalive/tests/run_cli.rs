//! `propsalive run` (stop-motion mode) end to end on a small generated take: the real binary,
//! killed and resumed, bad stills, foreign frames, re-shot stills.

mod common;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Stdio;
use std::sync::OnceLock;
use std::time::{Duration, Instant};

use common::{command, files, lock, log, run, stderr};

const STILLS: u32 = 10;
const W: u32 = 320;
const H: u32 = 180;

type Take = common::GeneratedTake;

fn take() -> Option<&'static Take> {
    static T: OnceLock<Option<Take>> = OnceLock::new();
    T.get_or_init(|| common::generate_take("run_cli_", STILLS, W, H))
        .as_ref()
}

/// The frames of a take: name -> bytes.
fn frames(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    files(dir, "frames")
}

/// Copies the stills to a fresh folder for editing.
fn copy_stills(take: &Take, name: &str) -> PathBuf {
    let dir = take.root.join(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("mkdir");
    for e in std::fs::read_dir(&take.stills).expect("stills").flatten() {
        std::fs::copy(e.path(), dir.join(e.file_name())).expect("copy");
    }
    dir
}

#[test]
fn uninterrupted_take_is_complete_and_tracked() {
    let _l = lock();
    let Some(take) = take() else { return };
    let f = frames(&take.reference);
    let names: Vec<_> = f.keys().cloned().collect();
    let expected: Vec<_> = (0..STILLS).map(|i| format!("{i:06}.png")).collect();
    assert_eq!(names, expected);
    let l = log(&take.reference);
    assert_eq!(l.len(), STILLS as usize);
    for (i, v) in &l {
        // Natural order: still i is s{i+1}.png (s10 after s9).
        assert_eq!(v["input"], format!("s{}.png", i + 1));
        assert_eq!(v["anim_frame"], *i);
        assert_eq!(v["key_pose"], "A");
        assert!(v["skipped"].is_null());
        assert!(v["timings_ms"]["track"].as_f64().is_some());
    }
    let tracked = l.values().filter(|v| v["state"] == "tracked").count();
    assert!(tracked >= 1, "no still tracked: {l:?}");
    for v in l.values().filter(|v| v["state"] == "tracked") {
        assert_eq!(
            v["camera_from_marker"].as_array().map(|a| a.len()),
            Some(16)
        );
        // The board's tags the pose used, as `track` logs them.
        let used = v["used_ids"].as_array().expect("used_ids");
        assert!(!used.is_empty() && used.iter().all(|id| id.as_u64().is_some()));
    }
    // A tracked frame is not the untouched still (the prop was replaced by the twin).
    let (i, _) = l
        .iter()
        .find(|(_, v)| v["state"] == "tracked")
        .expect("tracked");
    let out = image::open(take.reference.join(format!("frames/{i:06}.png")))
        .expect("frame")
        .to_rgba8();
    let input = image::open(take.stills.join(format!("s{}.png", i + 1)))
        .expect("still")
        .to_rgba8();
    assert_ne!(out.as_raw(), input.as_raw());
    println!("{tracked}/{STILLS} stills tracked");

    // Running the finished take again does nothing and says so.
    let again = run(&take.shot, &take.stills, &take.reference, &[]);
    assert!(again.status.success(), "{}", stderr(&again));
    assert!(
        stderr(&again).contains(&format!("0 processed, {STILLS} resumed")),
        "{}",
        stderr(&again)
    );
    assert_eq!(frames(&take.reference), f);
}

#[test]
fn killed_take_resumes_identical_to_uninterrupted() {
    let _l = lock();
    let Some(take) = take() else { return };
    let reference = frames(&take.reference);
    let ref_log = log(&take.reference);
    let mut killed_after = Vec::new();
    // Kill at arbitrary moments (during start-up, perhaps between a log line and its frame),
    // then twice once two more frames exist, then finish.
    let out = take.root.join("killed");
    let _ = std::fs::remove_dir_all(&out);
    let count = |out: &Path| frames(out).keys().filter(|k| !k.starts_with('.')).count();
    for (ms, more) in [(40u64, 0usize), (250, 0), (0, 2), (0, 2)] {
        let want = count(&out) + more;
        let mut child = command(&take.shot, &take.stills, &out, &[])
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("spawn");
        let t0 = Instant::now();
        std::thread::sleep(Duration::from_millis(ms));
        while more > 0 && count(&out) < want && t0.elapsed() < Duration::from_secs(300) {
            if child.try_wait().expect("wait").is_some() {
                break;
            }
            std::thread::sleep(Duration::from_millis(5));
        }
        let finished = child.try_wait().expect("wait").is_some();
        child.kill().ok();
        child.wait().expect("reaped");
        killed_after.push((count(&out), finished));
    }
    println!("killed with (frames, had finished) = {killed_after:?}");
    assert!(
        killed_after
            .iter()
            .any(|(n, fin)| !fin && *n < STILLS as usize),
        "the run was never killed mid-take: {killed_after:?}"
    );
    let o = run(&take.shot, &take.stills, &out, &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    let e = stderr(&o);
    assert!(e.contains("resum"), "{e}");
    println!("{}", e.lines().last().unwrap_or_default());
    // Every frame exactly once (no temporary files left), byte-identical to the reference.
    let got = frames(&out);
    assert_eq!(
        got.keys().collect::<Vec<_>>(),
        reference.keys().collect::<Vec<_>>()
    );
    for (name, bytes) in &reference {
        assert!(
            got[name] == *bytes,
            "{name} differs from the uninterrupted run"
        );
    }
    // One log line per index, with the same tracking results.
    let l = log(&out);
    assert_eq!(
        l.keys().collect::<Vec<_>>(),
        ref_log.keys().collect::<Vec<_>>()
    );
    for (i, v) in &l {
        for k in [
            "input",
            "anim_frame",
            "state",
            "camera_from_marker",
            "reprojection_px",
            "used_ids",
            "output",
        ] {
            assert_eq!(v[k], ref_log[i][k], "index {i}, {k}");
        }
    }
}

#[test]
fn unreadable_still_is_skipped_and_logged() {
    let _l = lock();
    let Some(take) = take() else { return };
    let stills = copy_stills(take, "stills_bad");
    std::fs::write(stills.join("s4.png"), b"this is not a png at all").expect("garbage");
    let out = take.root.join("out_bad");
    let _ = std::fs::remove_dir_all(&out);
    let o = run(&take.shot, &stills, &out, &[]);
    let e = stderr(&o);
    assert!(o.status.success(), "{e}");
    assert!(
        e.contains("skipping still 3 (s4.png)") && e.contains("warning: 1 still(s) have no frame"),
        "{e}"
    );
    let l = log(&out);
    assert_eq!(l.len(), STILLS as usize);
    assert!(
        l[&3]["skipped"]
            .as_str()
            .is_some_and(|s| s.starts_with("unreadable")),
        "{:?}",
        l[&3]
    );
    assert!(l[&3]["output"].is_null());
    let f = frames(&out);
    let reference = frames(&take.reference);
    assert!(!f.contains_key("000003.png"));
    assert_eq!(f.len(), STILLS as usize - 1);
    for (name, bytes) in &f {
        assert!(reference[name] == *bytes, "{name}");
    }
    // The skipped still stays skipped on a resume; fixing it renders just that frame.
    let o = run(&take.shot, &stills, &out, &[]);
    assert!(stderr(&o).contains("0 processed"), "{}", stderr(&o));
    std::fs::copy(take.stills.join("s4.png"), stills.join("s4.png")).expect("fix");
    let o = run(&take.shot, &stills, &out, &[]);
    let e = stderr(&o);
    assert!(o.status.success() && e.contains("1 processed"), "{e}");
    assert_eq!(frames(&out), reference);
    assert_eq!(log(&out).len(), STILLS as usize);
}

#[test]
fn still_of_another_size_is_skipped_and_logged() {
    let _l = lock();
    let Some(take) = take() else { return };
    let stills = copy_stills(take, "stills_mixed");
    let small = image::open(stills.join("s6.png"))
        .expect("still")
        .resize_exact(W / 2, H / 2, image::imageops::FilterType::Triangle);
    small.save(stills.join("s6.png")).expect("save");
    let out = take.root.join("out_mixed");
    let _ = std::fs::remove_dir_all(&out);
    let o = run(&take.shot, &stills, &out, &[]);
    let e = stderr(&o);
    assert!(o.status.success(), "{e}");
    assert!(
        e.contains("skipping still 5 (s6.png): 160x90 but the take is 320x180"),
        "{e}"
    );
    let l = log(&out);
    assert!(
        l[&5]["skipped"]
            .as_str()
            .is_some_and(|s| s.starts_with("wrong size")),
        "{:?}",
        l[&5]
    );
    let f = frames(&out);
    assert!(!f.contains_key("000005.png") && f.len() == STILLS as usize - 1);
}

#[test]
fn foreign_frames_are_refused_without_force_and_reshot_stills_replaced() {
    let _l = lock();
    let Some(take) = take() else { return };
    let out = take.root.join("out_foreign");
    let _ = std::fs::remove_dir_all(&out);
    std::fs::create_dir_all(out.join("frames")).expect("mkdir");
    std::fs::write(out.join("frames/000000.png"), b"another take").expect("write");
    let o = run(&take.shot, &take.stills, &out, &[]);
    let e = stderr(&o);
    assert!(!o.status.success(), "{e}");
    assert!(
        e.contains("000000.png") && e.contains("Refusing to overwrite") && e.contains("--force"),
        "{e}"
    );
    assert_eq!(
        std::fs::read(out.join("frames/000000.png")).expect("kept"),
        b"another take"
    );
    let o = run(&take.shot, &take.stills, &out, &["--force"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(frames(&out), frames(&take.reference));

    // Re-shoot still 2 (s3.png): only its frame is rendered again, and stderr says so.
    let stills = copy_stills(take, "stills_reshot");
    let out = take.root.join("out_reshot");
    let _ = std::fs::remove_dir_all(&out);
    assert!(run(&take.shot, &stills, &out, &[]).status.success());
    let before = frames(&out);
    std::fs::copy(take.stills.join("s8.png"), stills.join("s3.png")).expect("reshoot");
    let o = run(&take.shot, &stills, &out, &[]);
    let e = stderr(&o);
    assert!(o.status.success(), "{e}");
    assert!(
        e.contains("re-shot: frame 2 replaced") && e.contains("1 processed"),
        "{e}"
    );
    let after = frames(&out);
    assert_ne!(after["000002.png"], before["000002.png"]);
    for (name, bytes) in &before {
        if name != "000002.png" {
            assert!(after[name] == *bytes, "{name}");
        }
    }
    assert_eq!(log(&out).len(), STILLS as usize);

    // 16-bit output: same frame count, 16-bit PNGs.
    let out16 = take.root.join("out16");
    let _ = std::fs::remove_dir_all(&out16);
    let o = run(
        &take.shot,
        &take.stills,
        &out16,
        &["--bit-depth", "16", "--exposure", "2"],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let img = image::open(out16.join("frames/000003.png")).expect("16-bit frame");
    assert!(matches!(img, image::DynamicImage::ImageRgba16(_)));
    assert_eq!(log(&out16)[&3]["anim_frame"], 1);
    // Changing settings on an existing take is refused.
    let o = run(&take.shot, &take.stills, &out16, &["--bit-depth", "8"]);
    assert!(
        !o.status.success() && stderr(&o).contains("another exposure, bit depth"),
        "{}",
        stderr(&o)
    );
}

#[test]
fn leftovers_of_a_crash_are_repaired() {
    let _l = lock();
    let Some(take) = take() else { return };
    // A take killed between a log line and its frame, in the middle of a log line, and in the
    // middle of writing a frame's temporary file.
    let out = take.root.join("out_crash");
    let _ = std::fs::remove_dir_all(&out);
    std::fs::create_dir_all(out.join("frames")).expect("mkdir");
    for (name, bytes) in frames(&take.reference) {
        if name != "000004.png" {
            std::fs::write(out.join("frames").join(name), bytes).expect("copy");
        }
    }
    let mut text = std::fs::read_to_string(take.reference.join("log.jsonl")).expect("log");
    text.push_str("{\"index\":4,\"inp");
    std::fs::write(out.join("log.jsonl"), text).expect("log");
    std::fs::write(out.join("frames/.000004.png.tmp-999999"), b"half a png").expect("tmp");
    let o = run(&take.shot, &take.stills, &out, &[]);
    let e = stderr(&o);
    assert!(o.status.success(), "{e}");
    assert!(
        e.contains("truncated last line") && e.contains("1 processed"),
        "{e}"
    );
    assert_eq!(frames(&out), frames(&take.reference));
    assert_eq!(log(&out).len(), STILLS as usize);
}

/// Regression (stop 26): the pipeline carried state from one still to the next (the patch
/// fill's prior, since stop 26 also the sun's running direction), so the frames rendered after
/// a resume differed from an uninterrupted take's. A take with the patch fill, its last half
/// deleted and resumed, must give the same bytes.
#[test]
fn regression_a_resumed_patch_take_equals_an_uninterrupted_one() {
    let _l = lock();
    let Some(take) = take() else { return };
    let full = take.root.join("patch_full");
    let _ = std::fs::remove_dir_all(&full);
    let o = run(&take.shot, &take.stills, &full, &["--fill", "patch"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let reference = frames(&full);
    assert_eq!(reference.len(), STILLS as usize);
    // The same take with its frames from the sixth on gone: the resume renders them again.
    let half = take.root.join("patch_half");
    let _ = std::fs::remove_dir_all(&half);
    let o = run(&take.shot, &take.stills, &half, &["--fill", "patch"]);
    assert!(o.status.success(), "{}", stderr(&o));
    for name in reference.keys().skip(STILLS as usize / 2) {
        std::fs::remove_file(half.join("frames").join(name)).expect("remove a frame");
    }
    let o = run(&take.shot, &take.stills, &half, &["--fill", "patch"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let e = stderr(&o);
    println!("{}", e.lines().last().unwrap_or_default());
    assert!(e.contains(&format!("{} processed", STILLS / 2)), "{e}");
    let got = frames(&half);
    for (name, bytes) in &reference {
        assert!(
            got.get(name) == Some(bytes),
            "{name} differs from the uninterrupted take"
        );
    }
}

/// `--tracking fast`: every still tracked on its own by the decimated detector, with poses
/// that agree with the full passes'; a take made with one detector is another take's settings
/// for the other (refused without `--force`, its frames kept), and resumes with its own.
#[test]
fn fast_tracking_is_a_setting_of_its_own() {
    let _l = lock();
    let Some(take) = take() else { return };
    let out = take.root.join("out_fast");
    let _ = std::fs::remove_dir_all(&out);
    let o = run(&take.shot, &take.stills, &out, &["--tracking", "fast"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let (fast, full) = (log(&out), log(&take.reference));
    assert_eq!(fast.len(), STILLS as usize);
    let mut both = 0;
    for (i, f) in &fast {
        let pose = |v: &serde_json::Value| -> Option<Vec<f64>> {
            v["camera_from_marker"]
                .as_array()
                .map(|a| a.iter().filter_map(|x| x.as_f64()).collect())
        };
        let (Some(a), Some(b)) = (pose(f), pose(&full[i])) else {
            continue;
        };
        both += 1;
        // Column-major: rotation in 0..3, 4..7, 8..11, translation in 12..15. The take is
        // 320x180 (tags of about 20 px, at the decimated search's limit): within 3 degrees
        // and 2 % of the distance (seen: 1.5 degrees, 7 mm at 0.52 m).
        let rot = [0, 1, 2, 4, 5, 6, 8, 9, 10]
            .iter()
            .map(|&k| (a[k] - b[k]).abs());
        let tr = [12, 13, 14].iter().map(|&k| (a[k] - b[k]).abs());
        assert!(rot.fold(0.0, f64::max) < 0.05, "still {i}: {a:?} vs {b:?}");
        let distance = (b[12] * b[12] + b[13] * b[13] + b[14] * b[14]).sqrt();
        assert!(
            tr.fold(0.0, f64::max) < 0.02 * distance,
            "still {i}: {a:?} vs {b:?}"
        );
    }
    println!("{both}/{STILLS} stills tracked by both detectors");
    assert!(
        both >= 1,
        "the fast detector tracked no still the full one did"
    );

    let before = frames(&out);
    let o = run(&take.shot, &take.stills, &out, &[]);
    assert!(
        !o.status.success() && stderr(&o).contains("another exposure, bit depth"),
        "{}",
        stderr(&o)
    );
    assert_eq!(frames(&out), before, "the refused run changed frames");
    let o = run(&take.shot, &take.stills, &out, &["--tracking", "fast"]);
    assert!(
        o.status.success() && stderr(&o).contains(&format!("0 processed, {STILLS} resumed")),
        "{}",
        stderr(&o)
    );
}
