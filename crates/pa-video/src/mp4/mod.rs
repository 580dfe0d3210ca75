//! A small ISO base media file format (MP4 / QuickTime MOV) demuxer and muxer for one video
//! track.
//!
//! The demuxer reads only box headers and the `moov` box into memory (at most
//! [`MAX_MOOV_BYTES`]); samples are read one at a time by offset. Every size, count and offset
//! from the file is checked against the bytes that are really there before it is used, and
//! the sample table is capped at [`MAX_SAMPLES`], so a hostile file costs at most a few
//! hundred megabytes and never panics.
//!
//! The muxer writes `ftyp`, then one `mdat` (64-bit size, patched at the end), then `moov`
//! with `mvhd`, one `trak` (`tkhd`, `mdia`/`mdhd`/`hdlr`/`minf`/`vmhd`/`dinf`/`stbl` with
//! `stsd` (`avc1` + `avcC` [+ `clap`], `pasp`), `stts`, `stss`, `stsc`, `stsz`,
//! `stco`/`co64`)). One sample per chunk.

mod boxes;
mod demux;
mod error;
mod mux;

use error::Mp4Error;

pub use demux::{read_movie, read_sample, CleanAperture, Movie, Sample, SampleEntry, VideoTrack};
pub(crate) use mux::{build_moov, TrackLayout};

/// Largest `moov` box read into memory.
pub const MAX_MOOV_BYTES: u64 = 64 << 20;
/// Most samples (frames) a track may have: 46 hours at 24 fps.
pub const MAX_SAMPLES: u64 = 4_000_000;
/// Largest single sample (one coded frame).
pub const MAX_SAMPLE_BYTES: u64 = 64 << 20;

/// A four-character code.
pub type FourCc = [u8; 4];

/// Printable form of a four-character code.
pub fn fourcc_str(f: &FourCc) -> String {
    f.iter()
        .map(|&b| {
            if b.is_ascii_graphic() || b == b' ' {
                b as char
            } else {
                '?'
            }
        })
        .collect()
}
