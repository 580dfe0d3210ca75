//! Commands against hostile flags and streams (issue 11); each test is named after the defect
//! it pins and failed before its fix. None needs a renderer.

use std::path::PathBuf;
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

fn propsalive(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_propsalive"))
        .args(args)
        .output()
        .expect("runs")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn tmp(name: &str) -> PathBuf {
    let d = PathBuf::from(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("cli_hostile_{name}_{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).expect("mkdir");
    d
}

#[test]
fn regression_board_65536x65536_is_refused_not_wrapped() {
    // rows * cols wrapped to 0 in u32: `track` built 2^32 tags, `marker` said "ids 0..0".
    let d = tmp("board");
    let img = d.join("f.png");
    image::GrayImage::from_pixel(64, 48, image::Luma([200]))
        .save(&img)
        .expect("png");
    let t0 = Instant::now();
    let o = propsalive(&[
        "track",
        img.to_str().expect("utf-8"),
        "--fov-deg",
        "50",
        "--tag-size-m",
        "0.04",
        "--board",
        "65536x65536",
        "--gap-m",
        "0.01",
    ]);
    let e = stderr(&o);
    assert!(
        !o.status.success() && e.contains("at most 1000 tags"),
        "{e}"
    );
    assert!(t0.elapsed() < Duration::from_secs(60));
    // A first id past the family's codes (wrapped in `Board::grid` before): refused.
    let o = propsalive(&[
        "track",
        img.to_str().expect("utf-8"),
        "--fov-deg",
        "50",
        "--tag-size-m",
        "0.04",
        "--board",
        "2x2",
        "--gap-m",
        "0.01",
        "--first-id",
        "4294967295",
    ]);
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{e}");
    assert!(e.contains("has no id"), "{e}");
    let o = propsalive(&[
        "marker",
        "--board",
        "65536x65536",
        "--size-mm",
        "20",
        "--gap-mm",
        "5",
        "--out",
        d.join("m").to_str().expect("utf-8"),
    ]);
    let e = stderr(&o);
    assert!(
        !o.status.success() && e.contains("at most 1000 tags"),
        "{e}"
    );
    assert!(!e.contains("ids 0..0"), "{e}");
}

#[test]
fn regression_render_size_16384_is_refused_up_front() {
    // It failed after the work with "GPU readback failed: Wait timed out".
    let o = propsalive(&[
        "render",
        "nonexistent.glb",
        "--size",
        "16384x16384",
        "--out",
        "x",
    ]);
    let e = stderr(&o);
    assert!(!o.status.success(), "{e}");
    assert!(e.contains("16384x16384") && e.contains("8192"), "{e}");
    assert!(!e.contains("readback"), "{e}");
}

#[test]
fn regression_eval_stride_0_is_refused() {
    let d = tmp("eval");
    let o = propsalive(&["eval", "--stride", "0", "--out", d.to_str().expect("utf-8")]);
    let e = stderr(&o);
    assert!(!o.status.success() && e.contains("--stride"), "{e}");
}

#[test]
fn regression_preview_without_display_names_no_source_path() {
    let o = Command::new(env!("CARGO_BIN_EXE_propsalive"))
        .arg("preview")
        .env_remove("DISPLAY")
        .env_remove("WAYLAND_DISPLAY")
        .output()
        .expect("runs");
    let e = stderr(&o);
    assert!(!o.status.success(), "{e}");
    assert!(e.contains("display") && e.contains("xvfb-run"), "{e}");
    assert!(!e.contains(".rs:") && !e.contains("winit"), "{e}");
}

#[test]
fn regression_closed_stdout_does_not_panic() {
    // `propsalive marker ... | head -c0`: println! on a closed pipe panicked ("failed printing
    // to stdout", exit 101).
    let d = tmp("stdout");
    let mut child = Command::new(env!("CARGO_BIN_EXE_propsalive"))
        .args([
            "marker",
            "--size-mm",
            "40",
            "--out",
            d.join("m").to_str().expect("utf-8"),
        ])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("spawn");
    drop(child.stdout.take()); // the reader goes away before anything is printed
    let o = child.wait_with_output().expect("wait");
    let e = stderr(&o);
    assert_ne!(o.status.code(), Some(101), "{e}");
    assert!(!e.contains("panicked"), "{e}");
    // A full stdout: an error, not a panic.
    let full = std::fs::OpenOptions::new().write(true).open("/dev/full");
    if let Ok(full) = full {
        let o = Command::new(env!("CARGO_BIN_EXE_propsalive"))
            .args([
                "marker",
                "--size-mm",
                "40",
                "--force",
                "--out",
                d.join("m2").to_str().expect("utf-8"),
            ])
            .stdout(full)
            .output()
            .expect("runs");
        let e = stderr(&o);
        assert!(!e.contains("panicked"), "{e}");
        if !o.status.success() {
            assert!(e.contains("standard output"), "{e}");
        }
    } else {
        println!("skipped the full-disk half: /dev/full not available");
    }
}

#[test]
fn regression_bench_json_never_replaces_a_fifo() {
    // `bench --json` renamed its table over a FIFO, even without --force.
    use std::os::unix::fs::FileTypeExt;
    let d = tmp("bench_fifo");
    let fifo = d.join("bench.json");
    let ok = Command::new("mkfifo").arg(&fifo).status().expect("mkfifo");
    assert!(ok.success());
    let o = propsalive(&["bench", "--quick", "--json", fifo.to_str().expect("utf-8")]);
    let e = stderr(&o);
    assert!(!o.status.success() && e.contains("FIFO"), "{e}");
    let meta = std::fs::symlink_metadata(&fifo).expect("still there");
    assert!(meta.file_type().is_fifo());
}
