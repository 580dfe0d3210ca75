//! A stop-motion take on disk, as `propsalive run` writes it (see the binary's `cmd/run.rs` for
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
//! - [`camera_export`]: the tracked camera of a take as an animated glTF 2.0 camera
//!   (`camera.gltf`).
//!
//! Nothing here prints: notes for the user come back as values ([`log::LogNote`],
//! [`camera_export::Exported`], [`mp4::Mp4Written`]) and errors as [`TakeError`], whose
//! messages are the binary's. GPU-free: no pipeline, no renderer.

pub mod camera_export;
mod error;
pub mod log;
pub mod mp4;
pub mod passes;
pub mod take;

pub use error::TakeError;
pub use log::{
    file_stamp, frame_name, hash_hex, read_log, write_durable, write_durable_if_changed, write_log,
    Entry, Log, LogNote, Timings, Written,
};
pub use passes::{encode, encode_masks, PassSet};
pub use take::{
    camera_start_index, check_no_overlap, check_take_folders, foreign_files, lock_take,
    remove_stale_temps, InputKind, Plan, Take, OUTPUT_DIRS, TAKE_DIRS,
};
