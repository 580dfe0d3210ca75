//! A stop-motion take on disk, as `propsalive run` writes it (see the binary's `cmd/run/mod.rs` for
//! the command and its decisions): the take folder, its log and what resume knows from it.
//!
//! - [`log`]: `log.jsonl`, one [`Entry`] per still (its input's identity, the pose, timings,
//!   the files [`Written`] with their sizes and XXH3 hashes), read back tolerating a truncated
//!   last line, rewritten atomically; durable (atomic) writes of the take's files.
//! - [`passes`]: the `--passes` set (plate, twin, masks) and the PNG encoding of a frame and
//!   its passes at 8 or 16 bits per channel.
//! - [`take`]: the take being written ([`Take`]): what to do with each still ([`Plan`]: done,
//!   or process with a message), files the log does not know, the take's lock, its folders,
//!   stale temporaries, where a camera run numbers on, and the refusal of a take that would
//!   write over its own input.
//! - [`mp4`]: the take's MP4 (`--mp4`) and `mp4.json`, the record that tells this take's MP4
//!   from someone else's file and whether it is current.
//! - [`input`]: the take's input frame after frame ([`TakeSource`]: stills, a video, a
//!   camera whose frames are saved as `inputs/NNNNNN.png`), with the identity the log records.
//! - [`open`]: opening a take for a run ([`open_take`]): folders, lock, log, and the refusals
//!   of other settings and of files the log does not know.
//! - [`frame`]: one still into the take: read and checked ([`Take::read_still`]), its frame
//!   and passes encoded, its log line appended and fsynced, then its files written
//!   ([`Take::encode_frame`], [`Take::commit`]).
//! - [`camera_export`]: the tracked camera of a take as an animated glTF 2.0 camera
//!   (`camera.gltf`).
//!
//! Nothing here prints: notes for the user come back as values ([`log::LogNote`],
//! [`camera_export::Exported`], [`mp4::Mp4Written`], or handed to [`open_take`]'s `say` as
//! they come) and errors as [`TakeError`], whose messages are the binary's. GPU-free: no
//! pipeline, no renderer.
//!
//! The take on disk, as `propsalive run SHOT.toml --input INPUT --out DIR` writes it in DIR:
//! - `frames/NNNNNN.png`: one frame per still, numbered by the still's index in sorted order
//!   (the video's frame index; the camera's capture index), 8- or 16-bit (`--bit-depth`),
//!   written atomically (temporary file, fsync, rename).
//! - `log.jsonl`: one JSON object per still: `index`, `input` (file name; the video's file
//!   name for every frame of a video; `inputs/NNNNNN.png` for a camera), `input_bytes`,
//!   `input_mtime_ns`, `anim_frame`, `key_pose`, `state`, `camera_from_marker` (16 numbers,
//!   column-major, or null), `reprojection_px`, `timings_ms` (track, animate, texture,
//!   diminish, composite, encode), `output` (`frames/NNNNNN.png`, or null), `skipped` (the
//!   reason a still was not rendered, or null), `passes` (the pass files, with `--passes`),
//!   and the take's settings (`exposure`, `bit_depth`, `shot_hash`). Each line is appended and
//!   fsynced before its frame is written.
//! - `camera.gltf`: the tracked camera of every still of the take with a pose in the log, as
//!   an animated glTF 2.0 camera (see [`camera_export`]), rewritten atomically at the end of
//!   each run; not written (a note says so) when no still was tracked.
//! - With `--passes plate,twin,masks`: `plate/NNNNNN.png` (the diminished plate: the frame
//!   with the real prop removed, before the twin is drawn; at the take's bit depth),
//!   `twin/NNNNNN.png` (the twin alone, RGBA with straight alpha: 255 where it covers the
//!   pixel, 0 elsewhere; at the take's bit depth), `masks/NNNNNN.png` (8-bit RGB: R = the key
//!   pose's silhouette as the camera sees it, G = the twin's). An untracked still has a plate
//!   equal to the still, an empty twin and empty masks.
//! - With a camera: `inputs/NNNNNN.png`, every captured frame as it came from the camera
//!   (saved atomically before it is processed), so the take can be rendered again later
//!   (`--input DIR/inputs`).
//! - With `--mp4 FILE`: the take's frames in index order, at the shot's fps, as an H.264 MP4
//!   (`pa-video`), written after the run (also after a resumed run: always the whole take)
//!   under a temporary name and renamed; `mp4.json` in DIR records what was written.

pub mod camera_export;
mod error;
pub mod frame;
pub mod input;
pub mod log;
pub mod mp4;
pub mod open;
pub mod passes;
pub mod take;

pub use error::TakeError;
pub use frame::{FrameFile, FramePasses, Still};
pub use input::{
    decode_pixels, InputFrame, InputSource, Next, ResolvedInput, TakeCamera, TakeSource,
    TakeStills, TakeVideo,
};
pub use log::{
    file_stamp, frame_name, hash_hex, read_log, write_durable, write_durable_if_changed, write_log,
    Entry, Log, LogNote, Timings, Written,
};
pub use open::{open_take, Opened, TakeSettings};
pub use passes::{encode, encode_masks, PassSet};
pub use take::{
    camera_start_index, check_no_overlap, check_take_folders, foreign_files, lock_take,
    remove_stale_temps, InputKind, Plan, Take, Tally, OUTPUT_DIRS, TAKE_DIRS,
};
