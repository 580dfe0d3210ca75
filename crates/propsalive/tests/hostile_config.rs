//! Hostile configuration through the binary (issue 11): `calibrate --board` with ids past the
//! family's codes (or a `--first-id` so large the ids would wrap), a FIFO given as
//! `track --calib` or `run --shot` (refused at once, not waited on), and a file that is not
//! ours given as either (the error names the file and the line, never its content).

use std::path::Path;
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

const SHADOW: &str = "root:$6$SECRETHASH$abcdefghijklmnop:19000:0:99999:7:::\n\
                      daemon:*:19000:0:99999:7:::\n";

/// Runs the binary, killing it (and failing the test) after 60 s.
fn propsalive(args: &[&str]) -> Output {
    let mut child = Command::new(env!("CARGO_BIN_EXE_propsalive"))
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("run propsalive");
    let start = Instant::now();
    while child.try_wait().expect("wait").is_none() {
        if start.elapsed() > Duration::from_secs(60) {
            let _ = child.kill();
            let _ = child.wait();
            panic!("propsalive {args:?}: still running after 60 s");
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    child.wait_with_output().expect("output")
}

fn failure(args: &[&str]) -> String {
    let o = propsalive(args);
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(!o.status.success(), "{args:?} succeeded: {text}");
    assert!(
        !text.contains("panicked"),
        "{args:?} panicked instead of failing: {text}"
    );
    text
}

fn s(p: &Path) -> &str {
    p.to_str().expect("utf-8 path")
}

fn mkfifo(p: &Path) {
    let ok = Command::new("mkfifo")
        .arg(p)
        .status()
        .expect("run mkfifo")
        .success();
    assert!(ok, "mkfifo {}", p.display());
}

fn calibrate_board(dir: &Path, board: &str, first_id: &str) -> String {
    let out = dir.join("cam.yaml");
    let images = dir.join("no-such-images");
    failure(&[
        "calibrate",
        s(&images),
        "--board",
        board,
        "--size-mm",
        "30",
        "--gap-mm",
        "6",
        "--first-id",
        first_id,
        "--out",
        s(&out),
    ])
}

#[test]
fn calibrate_refuses_board_ids_past_the_family() {
    let dir = tempfile::tempdir().expect("tempdir");
    // tag36h11 has 587 codes (ids 0..=586).
    for (board, first_id) in [("30x20", "0"), ("1x3", "585"), ("2x2", "4294967295")] {
        let e = calibrate_board(dir.path(), board, first_id);
        assert!(
            e.contains("587 codes") && e.contains(board) && e.contains(first_id),
            "--board {board} --first-id {first_id}: {e}"
        );
    }
    // 1000x1000 tags from a large first id: rows * cols + first id overflows u32.
    let e = calibrate_board(dir.path(), "1000x1000", "4294000000");
    assert!(e.contains("587 codes"), "{e}");
    // The last code fits: the flags pass and the (missing) images are the problem.
    let e = calibrate_board(dir.path(), "1x3", "584");
    assert!(!e.contains("codes"), "{e}");
    assert!(e.contains("no-such-images"), "{e}");
}

/// A small PNG for `track` to read the frame size from.
fn frame(dir: &Path) -> std::path::PathBuf {
    let p = dir.join("frame.png");
    image::GrayImage::from_pixel(64, 48, image::Luma([200u8]))
        .save(&p)
        .expect("save png");
    p
}

#[test]
fn track_refuses_a_fifo_calibration_at_once() {
    let dir = tempfile::tempdir().expect("tempdir");
    let img = frame(dir.path());
    let fifo = dir.path().join("calib.yaml");
    mkfifo(&fifo);
    let e = failure(&[
        "track",
        s(&img),
        "--calib",
        s(&fifo),
        "--tag-size-m",
        "0.05",
    ]);
    assert!(e.contains("calib.yaml") && e.contains("FIFO"), "{e}");
}

#[test]
fn track_never_prints_a_foreign_calibration_file() {
    let dir = tempfile::tempdir().expect("tempdir");
    let img = frame(dir.path());
    for name in ["shadow", "shadow.yaml", "shadow.toml", "shadow.json"] {
        let secret = dir.path().join(name);
        std::fs::write(&secret, format!("SECRETHASH on a line\n{SHADOW}")).expect("write");
        let e = failure(&[
            "track",
            s(&img),
            "--calib",
            s(&secret),
            "--tag-size-m",
            "0.05",
        ]);
        assert!(
            !e.contains("SECRETHASH") && !e.contains("19000"),
            "{name}: {e}"
        );
        assert!(e.contains(&format!("{name}:1")), "{name}: {e}");
    }
}

#[test]
fn run_refuses_a_fifo_shot_at_once_and_never_prints_a_foreign_shot() {
    let dir = tempfile::tempdir().expect("tempdir");
    let out = dir.path().join("take");
    let fifo = dir.path().join("shot.toml");
    mkfifo(&fifo);
    let e = failure(&["run", s(&fifo), "--input", "frames", "--out", s(&out)]);
    assert!(e.contains("shot.toml") && e.contains("FIFO"), "{e}");

    let secret = dir.path().join("shadow");
    std::fs::write(&secret, SHADOW).expect("write");
    let e = failure(&["run", s(&secret), "--input", "frames", "--out", s(&out)]);
    assert!(!e.contains("SECRETHASH") && !e.contains("19000"), "{e}");
    assert!(e.contains("shadow:1:"), "{e}");
}
