//! The take's MP4 (`--mp4`): the frames in index order at the shot's fps, and `mp4.json`, the
//! record of what was written, so a re-run knows its own file (replaced without `--force`) and
//! whether it is current (not encoded again).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use pa_video::still::StillBudget;
use pa_video::{Fps, Mp4Writer, Mp4WriterOptions};
use serde::{Deserialize, Serialize};

use crate::log::{file_stamp, write_durable, Entry};
use crate::take::absolute;
use crate::TakeError;

/// What `mp4.json` records of the MP4 a take wrote.
#[derive(Debug, Serialize, Deserialize, PartialEq)]
struct Mp4Record {
    path: String,
    bytes: u64,
    mtime_ns: u64,
    frames: u64,
    fps: f32,
    /// XXH3-64 of the frames it was made from (their indices and recorded hashes), so a
    /// re-run with nothing new knows the MP4 is current.
    #[serde(default)]
    take_hash: String,
}

/// The identity of the frames `0..n` an MP4 is made from.
pub fn take_hash(entries: &BTreeMap<usize, Entry>, n: usize) -> String {
    let mut text = String::new();
    for e in entries.values().filter(|e| e.index < n) {
        if let (Some(_), Some(w)) = (&e.output, &e.written) {
            text.push_str(&format!("{} {}\n", e.index, w[0].xxh3));
        }
    }
    format!("{:016x}", xxhash_rust::xxh3::xxh3_64(text.as_bytes()))
}

/// True when `mp4` is this take's and was made from exactly the frames it holds now.
pub fn mp4_is_current(mp4: &Path, out: &Path, hash: &str) -> bool {
    our_mp4_record(mp4, out).is_some_and(|r| r.take_hash == hash)
}

/// True when `mp4` is the file this take last wrote (same path, size and mtime).
pub fn mp4_is_ours(mp4: &Path, out: &Path) -> bool {
    our_mp4_record(mp4, out).is_some()
}

/// The take's `mp4.json`, when `mp4` is the file it records (same path, size and mtime).
fn our_mp4_record(mp4: &Path, out: &Path) -> Option<Mp4Record> {
    let text = pa_io::read_regular(&out.join("mp4.json"), 1 << 20, "mp4.json").ok()?;
    let rec = serde_json::from_slice::<Mp4Record>(&text).ok()?;
    let stamp = file_stamp(mp4).ok()?;
    (rec.path == absolute(mp4).display().to_string() && (rec.bytes, rec.mtime_ns) == stamp)
        .then_some(rec)
}

/// Refuses an `--mp4` target that is a folder, or an existing file that is not this take's,
/// before any work.
pub fn check_mp4_target(mp4: &Path, out: &Path, force: bool) -> Result<(), TakeError> {
    if mp4.is_dir() {
        return Err(TakeError::Mp4IsFolder {
            mp4: mp4.to_path_buf(),
        });
    }
    if mp4.exists() && !force && !mp4_is_ours(mp4, out) {
        return Err(TakeError::Mp4NotOurs {
            mp4: mp4.to_path_buf(),
            before_work: true,
        });
    }
    Ok(())
}

/// Removes what a killed MP4 writer left (`.NAME.PID.N.partial` beside the target).
fn remove_stale_partials(mp4: &Path) {
    let (Some(dir), Some(name)) = (mp4.parent(), mp4.file_name()) else {
        return;
    };
    let dir = if dir.as_os_str().is_empty() {
        Path::new(".")
    } else {
        dir
    };
    let prefix = format!(".{}.", name.to_string_lossy());
    if let Ok(rd) = std::fs::read_dir(dir) {
        for e in rd.flatten() {
            let n = e.file_name().to_string_lossy().into_owned();
            if n.starts_with(&prefix) && n.ends_with(".partial") {
                let _ = std::fs::remove_file(e.path());
            }
        }
    }
}

/// What [`write_mp4`] did.
#[derive(Debug, Clone, PartialEq)]
pub enum Mp4Written {
    /// The take has no frame: nothing written.
    NoFrames,
    /// The MP4 is written (and `mp4.json` records it).
    Written {
        frames: u64,
        bytes: u64,
        fps: Fps,
        /// Frames the take lacks, each holding the frame before.
        held: usize,
    },
}

impl Mp4Written {
    /// The line `propsalive run` prints after writing `mp4`.
    pub fn line(&self, mp4: &Path) -> String {
        match self {
            Mp4Written::NoFrames => "note: the take has no frame: no MP4 written".to_string(),
            Mp4Written::Written {
                frames,
                bytes,
                fps,
                held,
            } => format!(
                "mp4: {frames} frame(s) at {fps} fps, {:.1} MB, H.264 -> {}{}",
                *bytes as f64 / 1e6,
                mp4.display(),
                if *held > 0 {
                    format!(" ({held} frame(s) the take lacks hold the frame before)")
                } else {
                    String::new()
                }
            ),
        }
    }
}

/// Encodes the take's frames `0..n` in index order at `fps` as an H.264 MP4. A frame the take
/// lacks (a skipped still) holds the one before it (the first frame for a leading gap), so
/// the MP4 keeps the take's timing.
pub fn write_mp4(
    mp4: &Path,
    out: &Path,
    entries: &BTreeMap<usize, Entry>,
    n: usize,
    fps: f32,
    force: bool,
) -> Result<Mp4Written, TakeError> {
    let frames: BTreeMap<usize, PathBuf> = entries
        .values()
        .filter(|e| e.index < n)
        .filter_map(|e| Some((e.index, out.join(e.output.as_ref()?))))
        .filter(|(_, p)| p.is_file())
        .collect();
    let (Some((&first, first_path)), Some(&last)) = (frames.iter().next(), frames.keys().last())
    else {
        return Ok(Mp4Written::NoFrames);
    };
    let read = |p: &Path| -> Result<image::RgbaImage, TakeError> {
        Ok(pa_video::still::read_still(p, &StillBudget::default())
            .map_err(|source| TakeError::Mp4Read {
                path: p.to_path_buf(),
                source,
            })?
            .to_rgba8())
    };
    let first_img = read(first_path)?;
    let (w, h) = first_img.dimensions();
    let overwrite = mp4.exists() && (force || mp4_is_ours(mp4, out));
    if mp4.exists() && !overwrite {
        return Err(TakeError::Mp4NotOurs {
            mp4: mp4.to_path_buf(),
            before_work: false,
        });
    }
    if let Some(dir) = mp4.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(|source| TakeError::CreateDir {
            path: dir.to_path_buf(),
            source,
        })?;
    }
    remove_stale_partials(mp4);
    let rate = Fps::from_f64(fps as f64)?;
    let mut options = Mp4WriterOptions::new(rate);
    options.overwrite = overwrite;
    let mut writer = Mp4Writer::create(mp4, w, h, options)?;
    let mut held = 0usize;
    let mut current = first_img;
    for i in 0..=last {
        match frames.get(&i) {
            Some(p) if i != first => {
                let img = read(p)?;
                if img.dimensions() != (w, h) {
                    return Err(TakeError::Mp4FrameSize {
                        path: p.clone(),
                        width: img.width(),
                        height: img.height(),
                        first_width: w,
                        first_height: h,
                    });
                }
                current = img;
            }
            Some(_) => {}
            None => held += 1,
        }
        writer.write_frame(current.as_raw())?;
    }
    // `finish` renames the file into place and syncs its folder.
    let summary = writer.finish()?;
    let (bytes, mtime_ns) = file_stamp(mp4)?;
    let rec = Mp4Record {
        path: absolute(mp4).display().to_string(),
        bytes,
        mtime_ns,
        frames: summary.frames,
        fps,
        take_hash: take_hash(entries, n),
    };
    write_durable(
        &out.join("mp4.json"),
        serde_json::to_string_pretty(&rec)?.as_bytes(),
    )?;
    Ok(Mp4Written::Written {
        frames: summary.frames,
        bytes: summary.bytes,
        fps: rate,
        held,
    })
}
