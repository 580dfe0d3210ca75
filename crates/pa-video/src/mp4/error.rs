//! What is wrong with a movie's boxes: the detail of [`crate::VideoError::Corrupt`] (reading)
//! and [`crate::VideoError::Encode`] (writing). Messages name boxes, counts and offsets, never
//! the file's bytes.

use super::{fourcc_str, FourCc, MAX_SAMPLES, MAX_SAMPLE_BYTES};

/// A malformed box found by the demuxer, or a box the muxer cannot write.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub(crate) enum Mp4Error {
    /// A box's payload ends before a field.
    #[error("'{what}' box is truncated ({len} bytes, needed {need} more at byte {at})")]
    Truncated {
        /// The box (or structure) being read.
        what: &'static str,
        /// Its payload's length.
        len: usize,
        /// The bytes the field needs.
        need: usize,
        /// Where the field starts in the payload.
        at: usize,
    },
    /// A table's entry count does not fit in its box.
    #[error("'{what}' box claims {count} entries but holds only {remaining} bytes")]
    TableOverrun {
        what: &'static str,
        count: u32,
        remaining: usize,
    },
    /// Bytes after the last child box that cannot be a box.
    #[error("{count} stray bytes after the last box")]
    StrayBytes { count: usize },
    /// A 64-bit box header cut short.
    #[error("'{}' box header is truncated", fourcc_str(.kind))]
    HeaderTruncated { kind: FourCc },
    /// A child box larger than what is left of its parent.
    #[error("'{}' box claims {size} bytes but only {remaining} remain in its parent", fourcc_str(.kind))]
    BoxOverrun {
        kind: FourCc,
        size: u64,
        remaining: usize,
    },
    /// A required child box is absent; `parent` is quoted and may say `video`.
    #[error("{parent} has no '{child}' box")]
    MissingBox {
        parent: &'static str,
        child: &'static str,
    },
    #[error("the video track's timescale is 0")]
    ZeroTimescale,
    #[error("{count} samples exceed the limit of {MAX_SAMPLES}")]
    TooManySamples { count: u64 },
    #[error("{count} samples of {size} bytes do not fit in a {file_len}-byte file")]
    SamplesExceedFile {
        count: u64,
        size: u32,
        file_len: u64,
    },
    #[error("compact sample sizes ('stz2') are not supported")]
    CompactSampleSizes,
    #[error("sample {index} has zero size")]
    EmptySample { index: usize },
    #[error("sample {index} of {size} bytes exceeds the {MAX_SAMPLE_BYTES}-byte limit")]
    SampleTooLarge { index: usize, size: u32 },
    #[error("video 'stbl' has neither 'stco' nor 'co64'")]
    NoChunkOffsets,
    #[error("'stsc' first_chunk {first} is out of order")]
    ChunkOrder { first: u32 },
    #[error(
        "sample {index} at offset {offset} ({size} bytes) lies past the end of the \
         {file_len}-byte file"
    )]
    SamplePastEnd {
        index: usize,
        offset: u64,
        size: u32,
        file_len: u64,
    },
    #[error("the sample table lists {listed} samples but its chunks hold {held}")]
    ChunksShort { listed: usize, held: usize },
    #[error("decode times overflow")]
    DecodeTimeOverflow,
    /// A time table (`stts`, `ctts`) covers fewer samples than the track has.
    #[error("'{table}' covers {covered} of {samples} samples")]
    TimesShort {
        table: &'static str,
        covered: usize,
        samples: usize,
    },
    #[error("'stss' names sample {sample} of {samples}")]
    SyncSampleOutOfRange { sample: usize, samples: usize },
    #[error("'stsd' has no sample description")]
    NoSampleDescription,
    /// The muxer closed a box it never opened (a bug).
    #[error("box end without begin")]
    EndWithoutBegin,
    /// A box the muxer writes does not fit a 32-bit size.
    #[error("box over 4 GiB")]
    BoxTooLarge,
}
