//! Helpers for hostile-input tests (issue 11), shared by every crate's regression tests.

use std::path::{Path, PathBuf};
use std::sync::mpsc::{self, RecvTimeoutError};
use std::time::Duration;

/// Runs `f` on its own thread and fails the test if it does not return within `timeout` (a
/// read that blocks forever on a FIFO must fail the test, not hang it).
pub fn within<T: Send + 'static>(
    what: &str,
    timeout: Duration,
    f: impl FnOnce() -> T + Send + 'static,
) -> T {
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        let _ = tx.send(f());
    });
    match rx.recv_timeout(timeout) {
        Ok(v) => v,
        Err(RecvTimeoutError::Timeout) => {
            panic!("{what}: still blocked after {} s", timeout.as_secs())
        }
        Err(RecvTimeoutError::Disconnected) => panic!("{what}: panicked"),
    }
}

/// Makes a FIFO (named pipe) at `p` with the system's `mkfifo`.
pub fn mkfifo(p: &Path) {
    let ok = std::process::Command::new("mkfifo")
        .arg(p)
        .status()
        .expect("run mkfifo")
        .success();
    assert!(ok, "mkfifo {}", p.display());
}

/// Loads every regular file of `dir` with `load_err` (which returns the error message of a
/// refused file) and asserts each message names the file and never repeats the marker
/// `SECRETHASH` the regression files carry; at least `at_least` files must be there.
pub fn assert_every_file_refused(dir: &Path, at_least: usize, load_err: impl Fn(&Path) -> String) {
    let mut n = 0;
    for entry in std::fs::read_dir(dir).expect("regressions folder") {
        let path: PathBuf = entry.expect("entry").path();
        if !path.is_file() {
            continue;
        }
        let msg = load_err(&path);
        let name = path
            .file_name()
            .expect("name")
            .to_string_lossy()
            .into_owned();
        assert!(
            msg.contains(&name),
            "{name}: the error must name the file: {msg}"
        );
        assert!(!msg.contains("SECRETHASH"), "{name}: leaks the file: {msg}");
        n += 1;
    }
    assert!(n >= at_least, "only {n} regression files");
}
