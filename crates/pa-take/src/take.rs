//! The take being written: its folder, its log and settings, what to do with each still
//! ([`Plan`]), and the checks that keep a take from writing over anything it does not own.

use std::collections::{BTreeMap, HashSet};
use std::path::{Path, PathBuf};
use std::time::UNIX_EPOCH;

use crate::log::{frame_name, Entry, Mismatch};
use crate::{PassSet, TakeError};

/// What to do with one still.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Plan {
    /// Logged and present (or logged as skipped): nothing to do.
    Done,
    /// Process; the message (if any) is said on stderr first.
    Process(Option<String>),
}

/// A take being written: its folder, its log and its settings.
#[derive(Debug, Clone)]
pub struct Take {
    pub out: PathBuf,
    pub log_path: PathBuf,
    pub entries: BTreeMap<usize, Entry>,
    /// Indices logged with other settings (re-rendered with --force).
    pub stale: HashSet<usize>,
    pub exposure: u32,
    pub bit_depth: u8,
    pub shot_hash: String,
    pub key_name: String,
    pub passes: PassSet,
    pub width: u32,
    pub height: u32,
    /// "still" or "frame".
    pub unit: &'static str,
}

/// The folders of a take that hold numbered files.
pub const TAKE_DIRS: [&str; 5] = ["frames", "inputs", "plate", "twin", "masks"];
/// Those a run writes over: a file there the log does not know is refused without --force.
/// (`inputs/` is written only by a camera run, which numbers on after every file there.)
pub const OUTPUT_DIRS: [&str; 4] = ["frames", "plate", "twin", "masks"];

impl Take {
    /// Whether the passes asked for exist for a logged frame.
    fn has_passes(&self, e: &Entry) -> bool {
        let dirs = self.passes.dirs();
        if dirs.is_empty() {
            return true;
        }
        let have = e.passes.as_deref().unwrap_or(&[]);
        dirs.iter().all(|d| {
            let p = format!("{d}/{}", frame_name(e.index));
            have.contains(&p) && self.out.join(&p).is_file()
        })
    }

    /// Why the files of a logged frame cannot be kept (None when every one matches what the
    /// log records as written).
    fn mismatch(&self, e: &Entry) -> Option<Mismatch> {
        let Some(written) = &e.written else {
            return Some(Mismatch::NoRecord);
        };
        let recorded = |p: &String| written.iter().any(|w| &w.path == p);
        if let Some(p) = e
            .output
            .iter()
            .chain(e.passes.iter().flatten())
            .find(|p| !recorded(p))
        {
            return Some(Mismatch::NotRecorded { path: p.clone() });
        }
        written.iter().find_map(|w| w.mismatch(&self.out))
    }

    /// What to do with still `i`, whose input is `name` with `stamp` (bytes, mtime ns).
    pub fn plan(&self, i: usize, name: &str, stamp: (u64, u64)) -> Plan {
        match self.entries.get(&i) {
            None => Plan::Process(None),
            Some(_) if self.stale.contains(&i) => {
                Plan::Process(Some(format!("settings changed: frame {i} re-rendered")))
            }
            Some(e) if e.input != name || (e.input_bytes, e.input_mtime_ns) != stamp => {
                Plan::Process(Some(if e.output.is_some() {
                    format!("re-shot: frame {i} replaced ({name})")
                } else {
                    format!(
                        "re-shot: {} {i} ({name}) was skipped before; trying again",
                        self.unit
                    )
                }))
            }
            Some(e) => match &e.output {
                Some(o) if self.out.join(o).is_file() && self.has_passes(e) => {
                    match self.mismatch(e) {
                        None => Plan::Done,
                        Some(why) => Plan::Process(Some(format!("frame {i} re-rendered: {why}"))),
                    }
                }
                Some(_) => Plan::Process(None),
                None => Plan::Done,
            },
        }
    }

    /// A new log entry for still `index` (input `name`, `stamp`) with the take's settings;
    /// the caller fills in what processing gave.
    pub fn new_entry(&self, index: usize, name: &str, stamp: (u64, u64), anim_frame: u32) -> Entry {
        Entry {
            index,
            input: name.to_string(),
            input_bytes: stamp.0,
            input_mtime_ns: stamp.1,
            anim_frame,
            key_pose: self.key_name.clone(),
            state: None,
            camera_from_marker: None,
            reprojection_px: None,
            used_ids: None,
            timings_ms: None,
            output: None,
            skipped: None,
            passes: None,
            written: None,
            exposure: self.exposure,
            bit_depth: self.bit_depth,
            shot_hash: self.shot_hash.clone(),
        }
    }
}

/// What the log says of a take of `n` stills ([`Take::tally`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Tally {
    /// Stills `0..n` with a frame.
    pub produced: usize,
    /// Stills `0..n` logged as skipped.
    pub skipped: usize,
    /// Frames past the last still (stills removed since).
    pub past_end: usize,
}

impl Take {
    /// What the log says of stills `0..n`.
    pub fn tally(&self, n: usize) -> Tally {
        let count = |f: &dyn Fn(&Entry) -> bool| self.entries.values().filter(|e| f(e)).count();
        Tally {
            produced: count(&|e| e.index < n && e.output.is_some()),
            skipped: count(&|e| e.index < n && e.skipped.is_some()),
            past_end: count(&|e| e.index >= n && e.output.is_some()),
        }
    }
}

/// Files in the take's output folders that the log does not know, in natural order.
pub fn foreign_files(take: &Take) -> Result<Vec<String>, TakeError> {
    let mut known: HashSet<String> = HashSet::new();
    for e in take.entries.values() {
        known.extend(e.output.iter().cloned());
        known.extend(e.passes.iter().flatten().cloned());
    }
    let mut foreign = Vec::new();
    for dir in OUTPUT_DIRS {
        let path = take.out.join(dir);
        let Ok(rd) = std::fs::read_dir(&path) else {
            continue;
        };
        for e in rd.flatten() {
            let name = e.file_name().to_string_lossy().into_owned();
            if name.starts_with('.') {
                continue;
            }
            let rel = format!("{dir}/{name}");
            if !known.contains(&rel) {
                foreign.push(rel);
            }
        }
    }
    foreign.sort_by(|a, b| pa_video::source::natural_cmp(a, b));
    Ok(foreign)
}

/// The highest index of the `NNNNNN.png` files in `dir`.
fn last_numbered(dir: &Path) -> Option<usize> {
    std::fs::read_dir(dir)
        .ok()?
        .flatten()
        .filter_map(|e| {
            let name = e.file_name().to_string_lossy().into_owned();
            let stem = name.strip_suffix(".png")?;
            (stem.len() == 6 && stem.bytes().all(|b| b.is_ascii_digit()))
                .then(|| stem.parse().ok())
                .flatten()
        })
        .max()
}

/// Where a camera run starts numbering: after the take's last logged frame and after every
/// captured input (a capture cut short may have saved an input it never logged: kept).
pub fn camera_start_index(take: &Take) -> usize {
    let logged = take.entries.keys().next_back().map(|i| i + 1);
    let saved = last_numbered(&take.out.join("inputs")).map(|i| i + 1);
    logged.max(saved).unwrap_or(0)
}

/// Takes the take's lock (`DIR/.lock`), or fails naming the run that holds it. On a
/// read-only file system no run can write the take: no lock is needed (and none can be made).
pub fn lock_take(out: &Path) -> Result<Option<pa_io::FileLock>, TakeError> {
    let holder = format!(
        "propsalive run, pid {}, started at unix time {}",
        std::process::id(),
        std::time::SystemTime::now()
            .duration_since(UNIX_EPOCH)
            .map_or(0, |d| d.as_secs())
    );
    match pa_io::FileLock::try_acquire(&out.join(".lock"), &holder) {
        Ok(lock) => Ok(Some(lock)),
        Err(pa_io::IoError::Locked { holder, .. }) => Err(TakeError::Locked {
            out: out.to_path_buf(),
            holder,
        }),
        Err(pa_io::IoError::Io { source, .. })
            if source.kind() == std::io::ErrorKind::ReadOnlyFilesystem =>
        {
            Ok(None)
        }
        Err(e) => Err(e.into()),
    }
}

/// Refuses a take whose folders (`frames/`, ...) are symbolic links or not folders: a take
/// never follows a link out of itself.
pub fn check_take_folders(out: &Path) -> Result<(), TakeError> {
    for d in TAKE_DIRS {
        let p = out.join(d);
        if let Ok(meta) = std::fs::symlink_metadata(&p) {
            if !meta.is_dir() {
                return Err(TakeError::NotAFolder {
                    path: p,
                    kind: pa_io::kind_of(&meta),
                    dir: d,
                });
            }
        }
    }
    for f in ["log.jsonl", "camera.gltf", "mp4.json"] {
        let p = out.join(f);
        if let Ok(meta) = std::fs::symlink_metadata(&p) {
            if !meta.is_file() {
                return Err(TakeError::NotAFile {
                    path: p,
                    kind: pa_io::kind_of(&meta),
                });
            }
        }
    }
    Ok(())
}

/// Removes temporary files a killed run left behind (`.NAME.tmp-PID`).
pub fn remove_stale_temps(dir: &Path) {
    if let Ok(rd) = std::fs::read_dir(dir) {
        for e in rd.flatten() {
            let name = e.file_name().to_string_lossy().into_owned();
            if pa_io::is_temp_name(&name) {
                let _ = std::fs::remove_file(e.path());
            }
        }
    }
}

/// What a take's input on disk is (a camera has nothing on disk to overlap).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum InputKind {
    /// A folder of stills.
    Folder,
    /// A video file.
    Video,
}

/// `p` made absolute (the current folder prepended), not resolved.
pub(crate) fn absolute(p: &Path) -> PathBuf {
    std::path::absolute(p).unwrap_or_else(|_| p.to_path_buf())
}

/// `p` made absolute with every symbolic link resolved as far as the path exists (the rest,
/// not yet created, appended as written).
fn resolved(p: &Path) -> PathBuf {
    let abs = absolute(p);
    let mut existing = abs.as_path();
    let mut rest = Vec::new();
    loop {
        if let Ok(c) = existing.canonicalize() {
            let mut out = c;
            for r in rest.iter().rev() {
                out.push(r);
            }
            return out;
        }
        match (existing.parent(), existing.file_name()) {
            (Some(parent), Some(name)) => {
                rest.push(name.to_os_string());
                existing = parent;
            }
            _ => return abs,
        }
    }
}

/// Refuses a take whose outputs could overwrite its inputs: the input (a folder of stills or
/// a video file) inside the take folder or the take folder inside the input folder, after
/// resolving links, and an `--mp4` that is the input or lies in the input folder. Checked
/// with or without `--force`.
pub fn check_no_overlap(
    input: &Path,
    kind: InputKind,
    out: &Path,
    mp4: Option<&Path>,
) -> Result<(), TakeError> {
    let input_path = resolved(input);
    let out_path = resolved(out);
    if input_path.starts_with(&out_path) || out_path.starts_with(&input_path) {
        return Err(TakeError::Overlap {
            input: input.to_path_buf(),
            out: out.to_path_buf(),
            input_resolved: input_path,
            out_resolved: out_path,
        });
    }
    if let Some(mp4) = mp4 {
        let mp4_path = resolved(mp4);
        if mp4_path == input_path
            || (kind == InputKind::Folder && mp4_path.starts_with(&input_path))
        {
            return Err(TakeError::Mp4InInput {
                mp4: mp4.to_path_buf(),
            });
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests;
