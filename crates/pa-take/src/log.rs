//! The take's log, `log.jsonl`: one JSON object per still, appended and fsynced before its
//! frame is written; read back with the last line of each index winning.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::UNIX_EPOCH;

use serde::{Deserialize, Serialize};

use crate::TakeError;

/// One line of `log.jsonl`.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct Entry {
    pub index: usize,
    pub input: String,
    pub input_bytes: u64,
    pub input_mtime_ns: u64,
    pub anim_frame: u32,
    pub key_pose: String,
    #[serde(default)]
    pub state: Option<String>,
    #[serde(default)]
    pub camera_from_marker: Option<Vec<f32>>,
    #[serde(default)]
    pub reprojection_px: Option<f64>,
    /// Ids of the board's tags the pose used, as `propsalive track` logs them (tags that
    /// disagreed with the rest and were rejected are not in it; empty when none was seen).
    /// Absent for a skipped still and in logs written before it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub used_ids: Option<Vec<u32>>,
    #[serde(default)]
    pub timings_ms: Option<Timings>,
    #[serde(default)]
    pub output: Option<String>,
    #[serde(default)]
    pub skipped: Option<String>,
    /// The pass files written with this frame (`plate/NNNNNN.png`, ...), with `--passes`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub passes: Option<Vec<String>>,
    /// What was written for this still (the frame and its passes): each file's size and
    /// XXH3-64 hash. Resume keeps a frame only when its files still match.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub written: Option<Vec<Written>>,
    pub exposure: u32,
    pub bit_depth: u8,
    pub shot_hash: String,
}

/// One file a still wrote, as the log records it.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct Written {
    /// Relative to the take folder (`frames/000003.png`).
    pub path: String,
    pub bytes: u64,
    /// XXH3-64 of the bytes, 16 hex digits.
    pub xxh3: String,
}

/// Why a logged frame's files cannot be kept (the text follows "frame N re-rendered: ").
#[derive(Debug, thiserror::Error)]
pub enum Mismatch {
    /// The log line predates the `written` record.
    #[error("the log has no record of what was written (a take of an older version)")]
    NoRecord,
    /// A file of the entry is not in its `written` record.
    #[error("the log has no record of {path}")]
    NotRecorded { path: String },
    #[error("{path} is missing")]
    Missing { path: String },
    /// A link, a folder, a FIFO...: never followed.
    #[error("{path} is {kind}")]
    NotAFile { path: String, kind: &'static str },
    #[error("{path} has {actual} bytes, {written} were written")]
    Size {
        path: String,
        actual: u64,
        written: u64,
    },
    #[error(transparent)]
    Unreadable(pa_io::IoError),
    #[error("{path} was changed after it was written")]
    Changed { path: String },
}

impl Written {
    /// The record of `bytes` written to `path` (relative to the take folder).
    pub fn of(path: String, bytes: &[u8]) -> Self {
        Self {
            path,
            bytes: bytes.len() as u64,
            xxh3: format!("{:016x}", xxhash_rust::xxh3::xxh3_64(bytes)),
        }
    }

    /// Why the file in `take` does not match the record (None when it does). A symbolic link
    /// is never followed: it does not match.
    pub fn mismatch(&self, take: &Path) -> Option<Mismatch> {
        let p = take.join(&self.path);
        let path = || self.path.clone();
        let meta = match std::fs::symlink_metadata(&p) {
            Ok(m) => m,
            Err(_) => return Some(Mismatch::Missing { path: path() }),
        };
        if !meta.is_file() {
            return Some(Mismatch::NotAFile {
                path: path(),
                kind: pa_io::kind_of(&meta),
            });
        }
        if meta.len() != self.bytes {
            return Some(Mismatch::Size {
                path: path(),
                actual: meta.len(),
                written: self.bytes,
            });
        }
        let bytes = match pa_io::read_regular(&p, self.bytes, "a frame of the take") {
            Ok(b) => b,
            Err(e) => return Some(Mismatch::Unreadable(e)),
        };
        let h = format!("{:016x}", xxhash_rust::xxh3::xxh3_64(&bytes));
        (h != self.xxh3).then(|| Mismatch::Changed { path: path() })
    }
}

/// Stage timings of one still, milliseconds.
#[derive(Debug, Clone, Copy, Serialize, Deserialize, PartialEq)]
pub struct Timings {
    pub track: f64,
    pub animate: f64,
    pub texture: f64,
    pub diminish: f64,
    pub composite: f64,
    pub encode: f64,
}

/// The file name of frame `index` (and of its passes and camera input): `NNNNNN.png`.
pub fn frame_name(index: usize) -> String {
    format!("{index:06}.png")
}

/// FNV-1a of the bytes, hex.
pub fn hash_hex(bytes: &[u8]) -> String {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for b in bytes {
        h ^= *b as u64;
        h = h.wrapping_mul(0x0100_0000_01b3);
    }
    format!("{h:016x}")
}

/// (size in bytes, modification time in ns since the epoch) of a file.
pub fn file_stamp(p: &Path) -> Result<(u64, u64), TakeError> {
    let m = std::fs::metadata(p).map_err(|source| TakeError::Stat {
        path: p.to_path_buf(),
        source,
    })?;
    let mtime = m
        .modified()
        .ok()
        .and_then(|t| t.duration_since(UNIX_EPOCH).ok())
        .map(|d| d.as_nanos() as u64)
        .unwrap_or(0);
    Ok((m.len(), mtime))
}

/// A take's log as read: the entries, and what was ignored on the way (for stderr).
#[derive(Debug, Default)]
pub struct Log {
    pub entries: BTreeMap<usize, Entry>,
    pub notes: Vec<LogNote>,
}

/// A line of the log that was ignored; the text is the line `propsalive run` prints.
#[derive(Debug, thiserror::Error)]
pub enum LogNote {
    /// The last line does not parse: a write cut short.
    #[error("note: {}: ignoring a truncated last line ({error})", path.display())]
    TruncatedLastLine {
        path: PathBuf,
        error: serde_json::Error,
    },
    /// A line before the last does not parse.
    #[error("warning: {}: ignoring unreadable line {line} ({error})", path.display())]
    UnreadableLine {
        path: PathBuf,
        /// 1-based.
        line: usize,
        error: serde_json::Error,
    },
}

/// Reads a take's log: the last line for each index wins; an unparsable last line (a write
/// cut short) is ignored, an unparsable line elsewhere is reported and ignored (both come back
/// as [`LogNote`]s, in file order). No log is an empty one.
pub fn read_log(path: &Path) -> Result<Log, TakeError> {
    let mut log = Log::default();
    if std::fs::symlink_metadata(path).is_err() {
        return Ok(log);
    }
    let text = pa_io::read_regular(path, MAX_LOG_BYTES, "a take's log")?;
    let text = String::from_utf8_lossy(&text);
    let lines: Vec<&str> = text.split('\n').collect();
    for (n, line) in lines.iter().enumerate() {
        if line.trim().is_empty() {
            continue;
        }
        match serde_json::from_str::<Entry>(line) {
            Ok(e) => {
                log.entries.insert(e.index, e);
            }
            Err(error) if n + 1 == lines.len() => {
                log.notes.push(LogNote::TruncatedLastLine {
                    path: path.to_path_buf(),
                    error,
                });
            }
            Err(error) => log.notes.push(LogNote::UnreadableLine {
                path: path.to_path_buf(),
                line: n + 1,
                error,
            }),
        }
    }
    Ok(log)
}

/// The budget for a take's log: about two million stills.
const MAX_LOG_BYTES: u64 = 1 << 30;

/// The log's text: one line per index, in index order.
fn log_text(entries: &BTreeMap<usize, Entry>) -> Result<String, TakeError> {
    let mut text = String::new();
    for e in entries.values() {
        text.push_str(&serde_json::to_string(e)?);
        text.push('\n');
    }
    Ok(text)
}

/// Rewrites the log (atomically) unless it already holds exactly this text: a run with
/// nothing to do writes nothing (a finished take on a read-only disk can be checked).
pub fn write_log(path: &Path, entries: &BTreeMap<usize, Entry>) -> Result<(), TakeError> {
    let text = log_text(entries)?;
    write_durable_if_changed(path, text.as_bytes())
}

/// [`write_durable`] unless `path` is a regular file holding exactly `bytes` already.
pub fn write_durable_if_changed(path: &Path, bytes: &[u8]) -> Result<(), TakeError> {
    let same = std::fs::symlink_metadata(path)
        .is_ok_and(|m| m.is_file() && m.len() == bytes.len() as u64)
        && pa_io::read_regular(path, bytes.len() as u64, "a file of the take")
            .is_ok_and(|old| old == bytes);
    if same {
        return Ok(());
    }
    write_durable(path, bytes)
}

/// Writes `bytes` to `path` atomically; `pa_io::write_atomic` also syncs the folder, so the
/// rename is durable.
pub fn write_durable(path: &Path, bytes: &[u8]) -> Result<(), TakeError> {
    pa_io::write_atomic(path, bytes).map_err(|source| TakeError::Write {
        path: path.to_path_buf(),
        source,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn entry(index: usize) -> Entry {
        Entry {
            index,
            input: format!("{index}.png"),
            input_bytes: 10,
            input_mtime_ns: 20,
            anim_frame: index as u32,
            key_pose: "A".into(),
            state: None,
            camera_from_marker: None,
            reprojection_px: None,
            used_ids: (index == 1).then(|| vec![4, 0, 2]),
            timings_ms: None,
            output: None,
            skipped: None,
            passes: None,
            written: None,
            exposure: 1,
            bit_depth: 8,
            shot_hash: "0".into(),
        }
    }

    #[test]
    fn the_log_reads_back_last_line_wins_and_a_truncated_tail_is_a_note() {
        let dir = tempfile::tempdir().expect("tmp");
        let path = dir.path().join("log.jsonl");
        assert!(read_log(&path).expect("no log").entries.is_empty());
        let entries: BTreeMap<usize, Entry> = (0..3).map(|i| (i, entry(i))).collect();
        write_log(&path, &entries).expect("write");
        let mut redone = entry(1);
        redone.skipped = Some("unreadable: x".into());
        let mut text = std::fs::read_to_string(&path).expect("read");
        text.push_str("not json\n");
        text.push_str(&serde_json::to_string(&redone).expect("json"));
        text.push_str("\n{\"index\": 7, \"inp");
        std::fs::write(&path, &text).expect("write");
        let log = read_log(&path).expect("read");
        assert_eq!(log.entries.keys().copied().collect::<Vec<_>>(), [0, 1, 2]);
        assert_eq!(log.entries[&1], redone);
        // used_ids round-trips in the tracker's order, and is left out when unknown (a log
        // written before the field reads back as None).
        assert_eq!(log.entries[&1].used_ids.as_deref(), Some(&[4, 0, 2][..]));
        assert!(text.contains(r#""used_ids":[4,0,2]"#));
        assert_eq!(log.entries[&0].used_ids, None);
        assert!(!serde_json::to_string(&entry(0))
            .expect("json")
            .contains("used_ids"));
        assert_eq!(log.notes.len(), 2);
        assert!(
            log.notes[0].to_string().starts_with(&format!(
                "warning: {}: ignoring unreadable line 4 (",
                path.display()
            )),
            "{}",
            log.notes[0]
        );
        assert!(
            log.notes[1].to_string().starts_with(&format!(
                "note: {}: ignoring a truncated last line (",
                path.display()
            )),
            "{}",
            log.notes[1]
        );
        // Compacted: one line per index; written again only when it changes.
        write_log(&path, &log.entries).expect("compact");
        let text = std::fs::read_to_string(&path).expect("read");
        assert_eq!(text.lines().count(), 3);
        let stamp = file_stamp(&path).expect("stamp");
        write_log(&path, &log.entries).expect("same");
        assert_eq!(file_stamp(&path).expect("stamp"), stamp);
    }

    #[test]
    fn written_files_are_checked_by_size_and_hash() {
        let dir = tempfile::tempdir().expect("tmp");
        std::fs::create_dir(dir.path().join("frames")).expect("mkdir");
        let w = Written::of("frames/000000.png".into(), b"abc");
        assert_eq!(w.bytes, 3);
        assert_eq!(
            w.mismatch(dir.path()).map(|m| m.to_string()).as_deref(),
            Some("frames/000000.png is missing")
        );
        write_durable(&dir.path().join(&w.path), b"abc").expect("write");
        assert!(w.mismatch(dir.path()).is_none());
        std::fs::write(dir.path().join(&w.path), b"abd").expect("write");
        assert_eq!(
            w.mismatch(dir.path()).map(|m| m.to_string()).as_deref(),
            Some("frames/000000.png was changed after it was written")
        );
        std::fs::write(dir.path().join(&w.path), b"abcd").expect("write");
        assert_eq!(
            w.mismatch(dir.path()).map(|m| m.to_string()).as_deref(),
            Some("frames/000000.png has 4 bytes, 3 were written")
        );
        assert_eq!(frame_name(42), "000042.png");
        assert_eq!(hash_hex(b""), "cbf29ce484222325");
    }
}
