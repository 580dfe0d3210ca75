//! Issue 11, item 10: only regular files are read. A FIFO or a device as the model file or
//! behind a buffer or image URI is refused at once, naming it (it used to block forever, or
//! read `/dev/zero` for gigabytes). Each load runs on a thread with a generous deadline, so a
//! regression fails instead of hanging the test run.

mod common;

use std::path::{Path, PathBuf};
use std::sync::mpsc;
use std::time::Duration;

use pa_model::{Model, ModelError};
use serde_json::json;

/// Loads `path` on a thread; panics if it takes more than a minute (a blocked read).
fn load_with_deadline(path: &Path) -> Result<Model, ModelError> {
    let (tx, rx) = mpsc::channel();
    let p = path.to_path_buf();
    std::thread::spawn(move || {
        let _ = tx.send(Model::load(&p));
    });
    rx.recv_timeout(Duration::from_secs(60))
        .unwrap_or_else(|_| panic!("loading {} blocked", path.display()))
}

fn mkfifo(path: &Path) {
    let status = std::process::Command::new("mkfifo")
        .arg(path)
        .status()
        .expect("run mkfifo");
    assert!(status.success(), "mkfifo {}", path.display());
}

/// A model folder with `m.gltf` whose buffer 0 (or image 0) is `uri`.
fn model_with(dir: &Path, buffer_uri: Option<&str>, image_uri: Option<&str>) -> PathBuf {
    let mut doc = common::triangle_doc();
    if let Some(uri) = buffer_uri {
        doc["buffers"][0]["uri"] = json!(uri);
    }
    if let Some(uri) = image_uri {
        doc["images"] = json!([{"uri": uri}]);
    }
    let path = dir.join("m.gltf");
    std::fs::write(&path, serde_json::to_vec(&doc).expect("json")).expect("write");
    path
}

#[test]
fn a_fifo_as_the_model_file_is_refused_at_once() {
    let dir = tempfile::tempdir().expect("tempdir");
    let fifo = dir.path().join("pipe.glb");
    mkfifo(&fifo);
    let e = load_with_deadline(&fifo).expect_err("a FIFO").to_string();
    assert_eq!(
        e,
        format!(
            "{}: is a FIFO (named pipe), not a regular file (only regular files are read)",
            fifo.display()
        )
    );
}

#[test]
fn a_device_or_folder_as_the_model_file_is_refused() {
    let e = load_with_deadline(Path::new("/dev/zero"))
        .expect_err("a device")
        .to_string();
    assert!(
        e.starts_with("/dev/zero: is a character device, not a regular file"),
        "{e}"
    );
    let dir = tempfile::tempdir().expect("tempdir");
    let e = load_with_deadline(dir.path())
        .expect_err("a folder")
        .to_string();
    assert!(e.contains("is a folder, not a regular file"), "{e}");
}

#[test]
fn a_fifo_inside_the_folder_as_a_buffer_is_refused_at_once() {
    let dir = tempfile::tempdir().expect("tempdir");
    mkfifo(&dir.path().join("pipe.bin"));
    let path = model_with(dir.path(), Some("pipe.bin"), None);
    let e = load_with_deadline(&path).expect_err("a FIFO").to_string();
    assert!(
        e.starts_with(&format!(
            "{}: buffer 0: cannot read \"pipe.bin\": ",
            path.display()
        )) && e.contains("pipe.bin: is a FIFO (named pipe), not a regular file"),
        "{e}"
    );
}

#[test]
fn a_fifo_inside_the_folder_as_an_image_is_refused_at_once() {
    let dir = tempfile::tempdir().expect("tempdir");
    mkfifo(&dir.path().join("pipe.png"));
    let path = model_with(dir.path(), None, Some("pipe.png"));
    let e = load_with_deadline(&path).expect_err("a FIFO").to_string();
    assert!(
        e.starts_with(&format!(
            "{}: image 0: cannot read \"pipe.png\": ",
            path.display()
        )) && e.contains("is a FIFO (named pipe), not a regular file"),
        "{e}"
    );
}

#[test]
fn a_symlink_to_dev_zero_inside_the_folder_is_refused() {
    let dir = tempfile::tempdir().expect("tempdir");
    std::os::unix::fs::symlink("/dev/zero", dir.path().join("zero.bin")).expect("symlink");
    let path = model_with(dir.path(), Some("zero.bin"), None);
    let e = load_with_deadline(&path)
        .expect_err("/dev/zero")
        .to_string();
    assert!(
        e.starts_with(&format!("{}: buffer 0: ", path.display()))
            && (e.contains("escapes the model's folder") || e.contains("character device")),
        "{e}"
    );
    // The same link as an image.
    let path = model_with(dir.path(), None, Some("zero.bin"));
    let e = load_with_deadline(&path)
        .expect_err("/dev/zero")
        .to_string();
    assert!(e.contains("image 0: "), "{e}");
}

#[test]
fn a_folder_as_a_buffer_is_refused() {
    let dir = tempfile::tempdir().expect("tempdir");
    std::fs::create_dir(dir.path().join("sub.bin")).expect("mkdir");
    let path = model_with(dir.path(), Some("sub.bin"), None);
    let e = load_with_deadline(&path).expect_err("a folder").to_string();
    assert!(
        e.contains("buffer 0: cannot read \"sub.bin\"") && e.contains("is a folder"),
        "{e}"
    );
}
