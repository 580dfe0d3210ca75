//! The muxer's `moov` box: nested boxes built in memory, sizes patched on close.

use super::{FourCc, Mp4Error};

/// Builds nested boxes in memory, patching sizes on close.
#[derive(Default)]
pub(crate) struct BoxBuf {
    pub(crate) buf: Vec<u8>,
    open: Vec<usize>,
}

impl BoxBuf {
    pub(crate) fn begin(&mut self, kind: &FourCc) {
        self.open.push(self.buf.len());
        self.buf.extend_from_slice(&[0, 0, 0, 0]);
        self.buf.extend_from_slice(kind);
    }
    pub(crate) fn begin_full(&mut self, kind: &FourCc, version: u8, flags: u32) {
        self.begin(kind);
        self.u32((u32::from(version) << 24) | (flags & 0x00ff_ffff));
    }
    pub(crate) fn end(&mut self) -> Result<(), Mp4Error> {
        let start = self.open.pop().ok_or(Mp4Error::EndWithoutBegin)?;
        let size = u32::try_from(self.buf.len() - start).map_err(|_| Mp4Error::BoxTooLarge)?;
        self.buf[start..start + 4].copy_from_slice(&size.to_be_bytes());
        Ok(())
    }
    pub(crate) fn u8(&mut self, v: u8) {
        self.buf.push(v);
    }
    pub(crate) fn u16(&mut self, v: u16) {
        self.buf.extend_from_slice(&v.to_be_bytes());
    }
    pub(crate) fn u32(&mut self, v: u32) {
        self.buf.extend_from_slice(&v.to_be_bytes());
    }
    pub(crate) fn u64(&mut self, v: u64) {
        self.buf.extend_from_slice(&v.to_be_bytes());
    }
    pub(crate) fn bytes(&mut self, b: &[u8]) {
        self.buf.extend_from_slice(b);
    }
    pub(crate) fn zeros(&mut self, n: usize) {
        self.buf.resize(self.buf.len() + n, 0);
    }
}

/// Everything the `moov` box of a written file needs.
pub(crate) struct TrackLayout<'a> {
    /// Track timescale (ticks per second).
    pub timescale: u32,
    /// Per-sample durations in ticks, run-length encoded `(count, delta)`.
    pub durations: &'a [(u32, u32)],
    /// Sample sizes.
    pub sizes: &'a [u32],
    /// Sample offsets.
    pub offsets: &'a [u64],
    /// 1-based numbers of sync samples.
    pub sync: &'a [u32],
    /// Coded (even) size in the sample entry.
    pub coded: (u32, u32),
    /// Display size (may be odd) for `tkhd` and `clap`.
    pub display: (u32, u32),
    /// The `avcC` payload.
    pub avcc: &'a [u8],
}

const MATRIX: [u32; 9] = [0x0001_0000, 0, 0, 0, 0x0001_0000, 0, 0, 0, 0x4000_0000];
const MOVIE_TIMESCALE: u32 = 1000;

/// Serialises the `moov` box.
pub(crate) fn build_moov(t: &TrackLayout<'_>) -> Result<Vec<u8>, Mp4Error> {
    let ticks: u64 = t
        .durations
        .iter()
        .map(|&(n, d)| u64::from(n) * u64::from(d))
        .sum();
    let movie_duration =
        (u128::from(ticks) * u128::from(MOVIE_TIMESCALE) / u128::from(t.timescale.max(1))) as u64;
    let long = ticks > u64::from(u32::MAX) || movie_duration > u64::from(u32::MAX);
    let version = u8::from(long);
    let mut b = BoxBuf::default();
    b.begin(b"moov");

    b.begin_full(b"mvhd", version, 0);
    if long {
        b.u64(0);
        b.u64(0);
        b.u32(MOVIE_TIMESCALE);
        b.u64(movie_duration);
    } else {
        b.u32(0);
        b.u32(0);
        b.u32(MOVIE_TIMESCALE);
        b.u32(movie_duration as u32);
    }
    b.u32(0x0001_0000); // rate 1.0
    b.u16(0x0100); // volume 1.0
    b.zeros(10);
    for m in MATRIX {
        b.u32(m);
    }
    b.zeros(24);
    b.u32(2); // next_track_ID
    b.end()?;

    b.begin(b"trak");
    b.begin_full(b"tkhd", version, 0x3); // enabled, in movie
    if long {
        b.u64(0);
        b.u64(0);
        b.u32(1);
        b.u32(0);
        b.u64(movie_duration);
    } else {
        b.u32(0);
        b.u32(0);
        b.u32(1);
        b.u32(0);
        b.u32(movie_duration as u32);
    }
    b.zeros(8);
    b.u16(0); // layer
    b.u16(0); // alternate group
    b.u16(0); // volume
    b.u16(0);
    for m in MATRIX {
        b.u32(m);
    }
    b.u32(t.display.0 << 16);
    b.u32(t.display.1 << 16);
    b.end()?;

    b.begin(b"mdia");
    b.begin_full(b"mdhd", version, 0);
    if long {
        b.u64(0);
        b.u64(0);
        b.u32(t.timescale);
        b.u64(ticks);
    } else {
        b.u32(0);
        b.u32(0);
        b.u32(t.timescale);
        b.u32(ticks as u32);
    }
    b.u16(0x55c4); // language "und"
    b.u16(0);
    b.end()?;
    b.begin_full(b"hdlr", 0, 0);
    b.u32(0);
    b.bytes(b"vide");
    b.zeros(12);
    b.bytes(b"Props Alive video\0");
    b.end()?;

    b.begin(b"minf");
    b.begin_full(b"vmhd", 0, 1);
    b.zeros(8);
    b.end()?;
    b.begin(b"dinf");
    b.begin_full(b"dref", 0, 0);
    b.u32(1);
    b.begin_full(b"url ", 0, 1); // media in this file
    b.end()?;
    b.end()?;
    b.end()?;

    b.begin(b"stbl");
    b.begin_full(b"stsd", 0, 0);
    b.u32(1);
    b.begin(b"avc1");
    b.zeros(6);
    b.u16(1); // data_reference_index
    b.zeros(16);
    b.u16(t.coded.0 as u16);
    b.u16(t.coded.1 as u16);
    b.u32(0x0048_0000); // 72 dpi
    b.u32(0x0048_0000);
    b.u32(0);
    b.u16(1); // frame_count
    let name = b"OpenH264 (Props Alive)";
    b.u8(name.len() as u8);
    b.bytes(name);
    b.zeros(31 - name.len());
    b.u16(0x0018);
    b.u16(0xffff);
    b.begin(b"avcC");
    b.bytes(t.avcc);
    b.end()?;
    if t.display != t.coded {
        // Display the top-left display.0 x display.1 of the coded picture.
        b.begin(b"clap");
        b.u32(t.display.0);
        b.u32(1);
        b.u32(t.display.1);
        b.u32(1);
        b.u32((t.display.0 as i32 - t.coded.0 as i32) as u32);
        b.u32(2);
        b.u32((t.display.1 as i32 - t.coded.1 as i32) as u32);
        b.u32(2);
        b.end()?;
    }
    b.begin(b"pasp");
    b.u32(1);
    b.u32(1);
    b.end()?;
    b.end()?; // avc1
    b.end()?; // stsd

    b.begin_full(b"stts", 0, 0);
    b.u32(t.durations.len() as u32);
    for &(n, d) in t.durations {
        b.u32(n);
        b.u32(d);
    }
    b.end()?;

    b.begin_full(b"stss", 0, 0);
    b.u32(t.sync.len() as u32);
    for &s in t.sync {
        b.u32(s);
    }
    b.end()?;

    b.begin_full(b"stsc", 0, 0);
    if t.sizes.is_empty() {
        b.u32(0);
    } else {
        b.u32(1);
        b.u32(1);
        b.u32(1);
        b.u32(1);
    }
    b.end()?;

    b.begin_full(b"stsz", 0, 0);
    b.u32(0);
    b.u32(t.sizes.len() as u32);
    for &s in t.sizes {
        b.u32(s);
    }
    b.end()?;

    if t.offsets.iter().all(|&o| o <= u64::from(u32::MAX)) {
        b.begin_full(b"stco", 0, 0);
        b.u32(t.offsets.len() as u32);
        for &o in t.offsets {
            b.u32(o as u32);
        }
    } else {
        b.begin_full(b"co64", 0, 0);
        b.u32(t.offsets.len() as u32);
        for &o in t.offsets {
            b.u64(o);
        }
    }
    b.end()?;

    b.end()?; // stbl
    b.end()?; // minf
    b.end()?; // mdia
    b.end()?; // trak
    b.end()?; // moov
    Ok(b.buf)
}
