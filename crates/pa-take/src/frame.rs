//! One still into the take: read and checked ([`Take::read_still`]), its frame and passes
//! encoded as PNGs
//! ([`Take::encode_frame`]), then its log line appended and fsynced before the files are
//! written ([`Take::commit`]), so a file never exists unknown to the log.

use std::io::Write;
use std::path::PathBuf;

use pa_video::source::Pixels;

use crate::{encode, encode_masks, frame_name, write_durable, Entry, Take, TakeError, Written};

/// The layers of one frame, for `--passes`.
#[derive(Debug, Clone)]
pub struct FramePasses {
    pub plate_rgba8: Vec<u8>,
    pub twin_rgba8: Vec<u8>,
    pub key_mask: Vec<bool>,
    pub twin_mask: Vec<bool>,
}

/// A file to write: its path and its bytes.
pub type FrameFile = (PathBuf, Vec<u8>);

impl Take {
    /// The files of still `i`: its frame (`rgba8`, with the still `img` for 16-bit output),
    /// and the passes asked for (`passes`; without them, those of an untracked still: the
    /// plate is the still `still_rgba8`, the twin and masks empty). Sets `entry.passes` and
    /// `entry.output`.
    pub fn encode_frame(
        &self,
        i: usize,
        rgba8: &[u8],
        img: &image::DynamicImage,
        still_rgba8: &[u8],
        passes: Option<FramePasses>,
        entry: &mut Entry,
    ) -> Result<Vec<FrameFile>, TakeError> {
        let (w, h) = (self.width, self.height);
        let mut files: Vec<FrameFile> = Vec::new();
        files.push((
            self.out.join("frames").join(frame_name(i)),
            encode(rgba8, Some(img), self.bit_depth, w, h)?,
        ));
        if self.passes.any() {
            let n = (w * h) as usize;
            let passes = passes.unwrap_or_else(|| FramePasses {
                plate_rgba8: still_rgba8.to_vec(),
                twin_rgba8: vec![0; n * 4],
                key_mask: vec![false; n],
                twin_mask: vec![false; n],
            });
            let mut names = Vec::new();
            if self.passes.plate {
                let png = encode(&passes.plate_rgba8, Some(img), self.bit_depth, w, h)?;
                names.push(format!("plate/{}", frame_name(i)));
                files.push((self.out.join("plate").join(frame_name(i)), png));
            }
            if self.passes.twin {
                let png = encode(&passes.twin_rgba8, None, self.bit_depth, w, h)?;
                names.push(format!("twin/{}", frame_name(i)));
                files.push((self.out.join("twin").join(frame_name(i)), png));
            }
            if self.passes.masks {
                let png = encode_masks(&passes.key_mask, &passes.twin_mask, w, h)?;
                names.push(format!("masks/{}", frame_name(i)));
                files.push((self.out.join("masks").join(frame_name(i)), png));
            }
            entry.passes = Some(names);
        }
        entry.output = Some(format!("frames/{}", frame_name(i)));
        Ok(files)
    }

    /// Records `files` in `entry` (`written`), appends its line to the log (`log`, opened for
    /// appending; fsynced), keeps it as the take's entry, then writes the files atomically.
    /// The log line first: a file never exists unknown to the log, and a line without its
    /// frame (or with other bytes) is redone on resume.
    pub fn commit(
        &mut self,
        log: &mut std::fs::File,
        mut entry: Entry,
        files: &[FrameFile],
    ) -> Result<(), TakeError> {
        if !files.is_empty() {
            entry.written = Some(
                files
                    .iter()
                    .map(|(path, bytes)| {
                        let rel = path.strip_prefix(&self.out).unwrap_or(path);
                        Written::of(rel.to_string_lossy().into_owned(), bytes)
                    })
                    .collect(),
            );
        }
        let line = serde_json::to_string(&entry)?;
        writeln!(log, "{line}").map_err(|source| TakeError::AppendLog {
            path: self.log_path.clone(),
            source,
        })?;
        log.flush().map_err(TakeError::SyncLog)?;
        log.sync_data().map_err(TakeError::SyncLog)?;
        self.entries.insert(entry.index, entry);
        for (path, bytes) in files {
            // A symbolic link in the take is never followed: the link itself is replaced.
            if std::fs::symlink_metadata(path).is_ok_and(|m| m.file_type().is_symlink()) {
                std::fs::remove_file(path).map_err(|source| TakeError::RemoveLink {
                    path: path.clone(),
                    source,
                })?;
            }
            write_durable(path, bytes)?;
        }
        Ok(())
    }
}

/// A still of the take, read: usable, or skipped (logged with the reason, said as `warning`).
#[derive(Debug)]
pub enum Still {
    Usable(image::DynamicImage),
    Skipped {
        /// Readable but of another size than the take (else: unreadable).
        wrong_size: bool,
        /// The warning for stderr.
        warning: String,
    },
}

impl Take {
    /// Still `i` (input `name`) decoded from `pixels`, if it is readable and of the take's
    /// size; otherwise the reason is recorded in `entry.skipped`.
    pub fn read_still(&self, i: usize, name: &str, pixels: Pixels, entry: &mut Entry) -> Still {
        let unit = self.unit;
        match crate::decode_pixels(pixels) {
            Ok(img) if (img.width(), img.height()) != (self.width, self.height) => {
                let why = format!(
                    "{}x{} but the take is {}x{} (set by the first readable {unit})",
                    img.width(),
                    img.height(),
                    self.width,
                    self.height
                );
                entry.skipped = Some(format!("wrong size: {why}"));
                Still::Skipped {
                    wrong_size: true,
                    warning: format!("warning: skipping {unit} {i} ({name}): {why}"),
                }
            }
            Ok(img) => Still::Usable(img),
            Err(e) => {
                entry.skipped = Some(format!("unreadable: {e}"));
                Still::Skipped {
                    wrong_size: false,
                    warning: format!("warning: skipping {unit} {i} ({name}): {e}"),
                }
            }
        }
    }
}
