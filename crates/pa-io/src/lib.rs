//! Safe file input and output for every crate of Props Alive.
//!
//! - **Reading** ([`read_regular`], [`read_to_string_regular`], [`open_regular`]): only regular
//!   files are opened. A FIFO, a device (`/dev/zero`), a socket or a folder is refused at once
//!   with an error naming what it is, instead of blocking forever or reading gigabytes. The
//!   open is non-blocking and the check is made on the opened file (`fstat`), so a FIFO swapped
//!   in after a check cannot block. Whole-file reads take a size budget and refuse a larger
//!   file before reading it.
//! - **Writing** ([`write_atomic`], [`write_new_atomic`]): a temporary file beside the target,
//!   written and synced, then renamed (or hard-linked) onto the name, and the folder synced. An
//!   existing target that is not a regular file (a FIFO, a device node, a folder, a symbolic
//!   link) is never replaced: the write fails naming it.
//! - **Locking** ([`FileLock`]): an exclusive OS lock on a file, released by the OS when the
//!   process dies, with the holder's description written into the file so a second process
//!   can name it.
//!
//! Every error names the file and the problem ([`IoError`]).

use std::fs::{File, Metadata, OpenOptions};
use std::io::{Read, Seek, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// What went wrong with a file; every variant names it.
#[derive(Debug, thiserror::Error)]
pub enum IoError {
    /// The path exists but is not a regular file.
    #[error("{}: is {kind}, not a regular file", path.display())]
    NotRegular { path: PathBuf, kind: &'static str },
    /// The file is larger than the budget for this kind of input.
    #[error("{}: {size} bytes, over the limit of {limit} bytes for {what}", path.display())]
    TooLarge {
        path: PathBuf,
        size: u64,
        limit: u64,
        what: &'static str,
    },
    /// The file is not UTF-8 text.
    #[error("{}: not UTF-8 text (byte {offset})", path.display())]
    NotText { path: PathBuf, offset: usize },
    /// Another process holds the lock.
    #[error("{}: locked by another process ({holder})", path.display())]
    Locked { path: PathBuf, holder: String },
    /// An operating-system error.
    #[error("{}: cannot {op}: {source}", path.display())]
    Io {
        path: PathBuf,
        op: &'static str,
        #[source]
        source: std::io::Error,
    },
}

impl IoError {
    /// The file the error is about.
    pub fn path(&self) -> &Path {
        match self {
            Self::NotRegular { path, .. }
            | Self::TooLarge { path, .. }
            | Self::NotText { path, .. }
            | Self::Locked { path, .. }
            | Self::Io { path, .. } => path,
        }
    }

    /// True for "the file does not exist".
    pub fn is_not_found(&self) -> bool {
        matches!(self, Self::Io { source, .. } if source.kind() == std::io::ErrorKind::NotFound)
    }

    fn io(path: &Path, op: &'static str, source: std::io::Error) -> Self {
        Self::Io {
            path: path.to_path_buf(),
            op,
            source,
        }
    }
}

impl From<IoError> for std::io::Error {
    fn from(e: IoError) -> Self {
        let kind = match &e {
            IoError::Io { source, .. } => source.kind(),
            IoError::NotRegular { .. } | IoError::NotText { .. } => {
                std::io::ErrorKind::InvalidInput
            }
            IoError::TooLarge { .. } => std::io::ErrorKind::FileTooLarge,
            IoError::Locked { .. } => std::io::ErrorKind::WouldBlock,
        };
        std::io::Error::new(kind, e)
    }
}

/// Words for a file type that is not a regular file.
pub fn kind_of(meta: &Metadata) -> &'static str {
    use std::os::unix::fs::FileTypeExt;
    let t = meta.file_type();
    if t.is_file() {
        "a regular file"
    } else if t.is_dir() {
        "a folder"
    } else if t.is_symlink() {
        "a symbolic link"
    } else if t.is_fifo() {
        "a FIFO (named pipe)"
    } else if t.is_char_device() {
        "a character device"
    } else if t.is_block_device() {
        "a block device"
    } else if t.is_socket() {
        "a socket"
    } else {
        "a special file"
    }
}

/// Opens `path` for reading if it is a regular file (following symbolic links), never
/// blocking on a FIFO or a device.
pub fn open_regular(path: &Path) -> Result<File, IoError> {
    use std::os::unix::fs::OpenOptionsExt;
    let file = OpenOptions::new()
        .read(true)
        .custom_flags(libc::O_NONBLOCK)
        .open(path)
        .map_err(|e| IoError::io(path, "open", e))?;
    let meta = file
        .metadata()
        .map_err(|e| IoError::io(path, "read the metadata of", e))?;
    if !meta.is_file() {
        return Err(IoError::NotRegular {
            path: path.to_path_buf(),
            kind: kind_of(&meta),
        });
    }
    Ok(file)
}

/// Checks that `path` names a regular file (following symbolic links) without opening it.
pub fn check_regular(path: &Path) -> Result<Metadata, IoError> {
    let meta = std::fs::metadata(path).map_err(|e| IoError::io(path, "read", e))?;
    if !meta.is_file() {
        return Err(IoError::NotRegular {
            path: path.to_path_buf(),
            kind: kind_of(&meta),
        });
    }
    Ok(meta)
}

/// Reads a whole regular file of at most `limit` bytes; `what` names the kind of input in the
/// error ("a glTF file", "a calibration file").
pub fn read_regular(path: &Path, limit: u64, what: &'static str) -> Result<Vec<u8>, IoError> {
    let file = open_regular(path)?;
    let size = file
        .metadata()
        .map_err(|e| IoError::io(path, "read the metadata of", e))?
        .len();
    if size > limit {
        return Err(IoError::TooLarge {
            path: path.to_path_buf(),
            size,
            limit,
            what,
        });
    }
    let mut bytes = Vec::with_capacity(size as usize);
    // Read at most one byte past the budget: a file that grew after the check is caught too.
    file.take(limit + 1)
        .read_to_end(&mut bytes)
        .map_err(|e| IoError::io(path, "read", e))?;
    if bytes.len() as u64 > limit {
        return Err(IoError::TooLarge {
            path: path.to_path_buf(),
            size: bytes.len() as u64,
            limit,
            what,
        });
    }
    Ok(bytes)
}

/// [`read_regular`] for UTF-8 text.
pub fn read_to_string_regular(
    path: &Path,
    limit: u64,
    what: &'static str,
) -> Result<String, IoError> {
    let bytes = read_regular(path, limit, what)?;
    String::from_utf8(bytes).map_err(|e| IoError::NotText {
        path: path.to_path_buf(),
        offset: e.utf8_error().valid_up_to(),
    })
}

/// Fails if `path` exists and is not a regular file (a symbolic link counts as not regular:
/// replacing it would not write where it points).
pub fn check_replaceable(path: &Path) -> Result<(), IoError> {
    match std::fs::symlink_metadata(path) {
        Ok(meta) if meta.is_file() => Ok(()),
        Ok(meta) => Err(IoError::NotRegular {
            path: path.to_path_buf(),
            kind: kind_of(&meta),
        }),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(()),
        Err(e) => Err(IoError::io(path, "read", e)),
    }
}

/// The folder of `path` (`.` for a bare name).
fn folder_of(path: &Path) -> &Path {
    match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    }
}

/// A temporary name beside `path`: `.NAME.tmp-PID-N`, unique within this process.
pub fn temp_path_beside(path: &Path) -> PathBuf {
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "out".into());
    let n = COUNTER.fetch_add(1, Ordering::Relaxed);
    folder_of(path).join(format!(".{name}.tmp-{}-{n}", std::process::id()))
}

/// True for a name [`temp_path_beside`] makes (`.NAME.tmp-...`), for clean-up of temporary
/// files a killed process left.
pub fn is_temp_name(name: &str) -> bool {
    name.starts_with('.') && name.contains(".tmp-")
}

/// Creates `path` (which must not exist) with `bytes` and syncs it.
fn write_synced(path: &Path, bytes: &[u8]) -> Result<(), IoError> {
    let mut f = OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(path)
        .map_err(|e| IoError::io(path, "create", e))?;
    f.write_all(bytes)
        .and_then(|()| f.sync_all())
        .map_err(|e| IoError::io(path, "write", e))
}

/// Syncs a folder so a rename in it is durable (best effort: not every file system allows it).
pub fn sync_folder(dir: &Path) {
    if let Ok(d) = File::open(dir) {
        let _ = d.sync_all();
    }
}

/// Writes a file atomically: a temporary file in the same folder, synced, then renamed over
/// `path`, and the folder synced. Refuses (before writing anything) when `path` exists and is
/// not a regular file.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), IoError> {
    check_replaceable(path)?;
    let tmp = temp_path_beside(path);
    let result = write_synced(&tmp, bytes).and_then(|()| {
        // Checked again just before the rename, so the window for a swap is small.
        check_replaceable(path)?;
        std::fs::rename(&tmp, path).map_err(|e| IoError::io(path, "replace", e))
    });
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    } else {
        sync_folder(folder_of(path));
    }
    result
}

/// Like [`write_atomic`], but only if nothing has the name `path`: the synced temporary file is
/// hard-linked to its name, which fails if the name is taken (where the file system has no
/// hard links, renamed after a check). Returns false when the name was taken.
pub fn write_new_atomic(path: &Path, bytes: &[u8]) -> Result<bool, IoError> {
    if std::fs::symlink_metadata(path).is_ok() {
        return Ok(false);
    }
    let tmp = temp_path_beside(path);
    let result = write_synced(&tmp, bytes).and_then(|()| match std::fs::hard_link(&tmp, path) {
        Ok(()) => Ok(true),
        Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => Ok(false),
        Err(_) => {
            if std::fs::symlink_metadata(path).is_ok() {
                return Ok(false);
            }
            std::fs::rename(&tmp, path).map_err(|e| IoError::io(path, "create", e))?;
            Ok(true)
        }
    });
    let _ = std::fs::remove_file(&tmp);
    if let Ok(true) = result {
        sync_folder(folder_of(path));
    }
    result
}

/// An exclusive lock on a file, held until dropped or until the process ends (the OS releases
/// it then, however the process died). The file holds a description of the holder.
#[derive(Debug)]
pub struct FileLock {
    file: File,
    path: PathBuf,
}

impl FileLock {
    /// Takes the lock on `path` (created if missing) without waiting. When another process
    /// holds it, fails with [`IoError::Locked`] naming the holder as that process described
    /// itself. `holder` describes this process (for example "propsalive run, pid 1234").
    pub fn try_acquire(path: &Path, holder: &str) -> Result<Self, IoError> {
        check_replaceable(path)?;
        let mut file = OpenOptions::new()
            .read(true)
            .write(true)
            .create(true)
            .truncate(false)
            .open(path)
            .map_err(|e| IoError::io(path, "open the lock file", e))?;
        match file.try_lock() {
            Ok(()) => {}
            Err(std::fs::TryLockError::WouldBlock) => {
                let mut text = String::new();
                let _ = (&file).take(4096).read_to_string(&mut text);
                let holder = text.trim();
                return Err(IoError::Locked {
                    path: path.to_path_buf(),
                    holder: if holder.is_empty() {
                        "unknown holder".into()
                    } else {
                        holder.to_string()
                    },
                });
            }
            Err(std::fs::TryLockError::Error(e)) => {
                return Err(IoError::io(path, "lock", e));
            }
        }
        let write = |f: &mut File| -> std::io::Result<()> {
            f.set_len(0)?;
            f.rewind()?;
            f.write_all(holder.as_bytes())?;
            f.write_all(b"\n")?;
            f.sync_data()
        };
        write(&mut file).map_err(|e| IoError::io(path, "write the lock file", e))?;
        Ok(Self {
            file,
            path: path.to_path_buf(),
        })
    }

    /// The lock file.
    pub fn path(&self) -> &Path {
        &self.path
    }
}

impl Drop for FileLock {
    fn drop(&mut self) {
        let _ = self.file.unlock();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A fresh folder, removed with everything in it when dropped.
    fn tmpdir(name: &str) -> tempfile::TempDir {
        tempfile::Builder::new()
            .prefix(&format!("pa-io-{name}-"))
            .tempdir()
            .expect("temp dir")
    }

    fn mkfifo(p: &Path) {
        use std::os::unix::ffi::OsStrExt;
        let c = std::ffi::CString::new(p.as_os_str().as_bytes()).expect("path");
        // SAFETY: a valid NUL-terminated path; mkfifo has no other preconditions.
        #[allow(unsafe_code)] // FFI (test only): std has no mkfifo.
        let rc = unsafe { libc::mkfifo(c.as_ptr(), 0o644) };
        assert_eq!(rc, 0, "mkfifo");
    }

    #[test]
    fn reading_a_fifo_fails_at_once_naming_it() {
        let tmp = tmpdir("fifo-read");
        let d = tmp.path();
        let fifo = d.join("model.gltf");
        mkfifo(&fifo);
        let e = read_regular(&fifo, 1 << 20, "a glTF file").expect_err("a FIFO");
        assert!(matches!(e, IoError::NotRegular { .. }), "{e}");
        let msg = e.to_string();
        assert!(msg.contains("model.gltf") && msg.contains("FIFO"), "{msg}");
    }

    #[test]
    fn reading_a_device_or_folder_fails() {
        let e = read_regular(Path::new("/dev/zero"), 1 << 20, "x").expect_err("device");
        assert!(e.to_string().contains("character device"), "{e}");
        let tmp = tmpdir("dir-read");
        let d = tmp.path();
        let e = read_regular(d, 1 << 20, "x").expect_err("folder");
        assert!(e.to_string().contains("folder"), "{e}");
    }

    #[test]
    fn a_file_over_the_budget_is_refused_before_reading() {
        let tmp = tmpdir("budget");
        let d = tmp.path();
        let p = d.join("big.yaml");
        std::fs::write(&p, vec![b'a'; 1000]).expect("write");
        let e = read_regular(&p, 999, "a calibration file").expect_err("too large");
        assert!(
            matches!(
                e,
                IoError::TooLarge {
                    size: 1000,
                    limit: 999,
                    ..
                }
            ),
            "{e}"
        );
        assert_eq!(read_regular(&p, 1000, "x").expect("fits").len(), 1000);
    }

    #[test]
    fn atomic_write_never_replaces_a_fifo_or_symlink() {
        let tmp = tmpdir("write");
        let d = tmp.path();
        let fifo = d.join("out.json");
        mkfifo(&fifo);
        let e = write_atomic(&fifo, b"{}").expect_err("a FIFO is kept");
        assert!(matches!(e, IoError::NotRegular { .. }), "{e}");
        let meta = std::fs::symlink_metadata(&fifo).expect("still there");
        use std::os::unix::fs::FileTypeExt;
        assert!(meta.file_type().is_fifo());
        let target = d.join("target.txt");
        std::fs::write(&target, b"keep").expect("write");
        let link = d.join("link.txt");
        std::os::unix::fs::symlink(&target, &link).expect("symlink");
        assert!(write_atomic(&link, b"new").is_err());
        assert_eq!(std::fs::read(&target).expect("read"), b"keep");
        // No temporary files are left behind.
        let left: Vec<_> = std::fs::read_dir(d)
            .expect("list")
            .filter_map(|e| e.ok())
            .filter(|e| is_temp_name(&e.file_name().to_string_lossy()))
            .collect();
        assert!(left.is_empty(), "{left:?}");
    }

    #[test]
    fn atomic_write_replaces_a_regular_file() {
        let tmp = tmpdir("replace");
        let d = tmp.path();
        let p = d.join("a.txt");
        write_atomic(&p, b"one").expect("first");
        write_atomic(&p, b"two").expect("second");
        assert_eq!(std::fs::read(&p).expect("read"), b"two");
        assert!(!write_new_atomic(&p, b"three").expect("taken"));
        assert_eq!(std::fs::read(&p).expect("read"), b"two");
        assert!(write_new_atomic(&d.join("b.txt"), b"b").expect("new"));
    }

    #[test]
    fn a_second_lock_fails_naming_the_holder() {
        let tmp = tmpdir("lock");
        let d = tmp.path();
        let p = d.join(".lock");
        let first = FileLock::try_acquire(&p, "propsalive run, pid 1").expect("first");
        let e = FileLock::try_acquire(&p, "propsalive run, pid 2").expect_err("held");
        assert!(e.to_string().contains("pid 1"), "{e}");
        drop(first);
        FileLock::try_acquire(&p, "pid 3").expect("released on drop");
    }
}
