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

use std::fs::File;
use std::io::{Read, Seek, SeekFrom};
use std::path::Path;

use crate::VideoError;

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

/// Bounds-checked big-endian reader over a byte slice.
pub(crate) struct Cur<'a> {
    data: &'a [u8],
    pos: usize,
    what: &'static str,
}

impl<'a> Cur<'a> {
    pub(crate) fn new(data: &'a [u8], what: &'static str) -> Self {
        Cur { data, pos: 0, what }
    }
    fn take(&mut self, n: usize) -> Result<&'a [u8], String> {
        if self.data.len() - self.pos < n {
            return Err(format!(
                "'{}' box is truncated ({} bytes, needed {} more at byte {})",
                self.what,
                self.data.len(),
                n,
                self.pos
            ));
        }
        let s = &self.data[self.pos..self.pos + n];
        self.pos += n;
        Ok(s)
    }
    pub(crate) fn skip(&mut self, n: usize) -> Result<(), String> {
        self.take(n).map(|_| ())
    }
    pub(crate) fn u8(&mut self) -> Result<u8, String> {
        Ok(self.take(1)?[0])
    }
    pub(crate) fn u16(&mut self) -> Result<u16, String> {
        let b = self.take(2)?;
        Ok(u16::from_be_bytes([b[0], b[1]]))
    }
    pub(crate) fn u32(&mut self) -> Result<u32, String> {
        let b = self.take(4)?;
        Ok(u32::from_be_bytes([b[0], b[1], b[2], b[3]]))
    }
    pub(crate) fn u64(&mut self) -> Result<u64, String> {
        let b = self.take(8)?;
        let mut a = [0u8; 8];
        a.copy_from_slice(b);
        Ok(u64::from_be_bytes(a))
    }
    fn fourcc(&mut self) -> Result<FourCc, String> {
        let b = self.take(4)?;
        Ok([b[0], b[1], b[2], b[3]])
    }
    fn remaining(&self) -> usize {
        self.data.len() - self.pos
    }
    fn rest(&mut self) -> &'a [u8] {
        let s = &self.data[self.pos..];
        self.pos = self.data.len();
        s
    }
    /// Reads a table of `count` entries of `entry_bytes` each, refusing counts that do not fit
    /// in the box (so nothing is allocated for entries that are not there).
    fn table(&mut self, count: u32, entry_bytes: usize) -> Result<&'a [u8], String> {
        let need = (count as usize).checked_mul(entry_bytes);
        match need {
            Some(n) if n <= self.remaining() => self.take(n),
            _ => Err(format!(
                "'{}' box claims {count} entries but holds only {} bytes",
                self.what,
                self.remaining()
            )),
        }
    }
}

/// Iterates over the child boxes packed in `data` as `(type, payload)`.
///
/// With `lenient`, trailing bytes too short for a box header and a zero-size terminator end
/// the list quietly (QuickTime sample entries have them); otherwise they are errors.
pub(crate) fn child_boxes(
    data: &[u8],
    lenient: bool,
) -> impl Iterator<Item = Result<(FourCc, &[u8]), String>> {
    let mut pos = 0usize;
    let mut done = false;
    std::iter::from_fn(move || {
        if done || pos >= data.len() {
            return None;
        }
        let rest = &data[pos..];
        if rest.len() < 8 {
            done = true;
            return if lenient || rest.iter().all(|&b| b == 0) {
                None
            } else {
                Some(Err(format!(
                    "{} stray bytes after the last box",
                    rest.len()
                )))
            };
        }
        let size32 = u32::from_be_bytes([rest[0], rest[1], rest[2], rest[3]]) as u64;
        let kind: FourCc = [rest[4], rest[5], rest[6], rest[7]];
        let (size, header) = match size32 {
            0 if lenient => {
                done = true;
                return None;
            }
            0 => (rest.len() as u64, 8u64),
            1 => {
                if rest.len() < 16 {
                    done = true;
                    return Some(Err(format!(
                        "'{}' box header is truncated",
                        fourcc_str(&kind)
                    )));
                }
                let mut a = [0u8; 8];
                a.copy_from_slice(&rest[8..16]);
                (u64::from_be_bytes(a), 16u64)
            }
            s => (s, 8u64),
        };
        if size < header || size > rest.len() as u64 {
            done = true;
            return Some(Err(format!(
                "'{}' box claims {size} bytes but only {} remain in its parent",
                fourcc_str(&kind),
                rest.len()
            )));
        }
        let payload = &rest[header as usize..size as usize];
        pos += size as usize;
        Some(Ok((kind, payload)))
    })
}

fn find_child<'a>(data: &'a [u8], kind: &FourCc) -> Result<Option<&'a [u8]>, String> {
    for b in child_boxes(data, false) {
        let (k, payload) = b?;
        if &k == kind {
            return Ok(Some(payload));
        }
    }
    Ok(None)
}

/// One coded frame of the video track, in decode order.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Sample {
    /// Absolute file offset.
    pub offset: u64,
    /// Size in bytes (> 0).
    pub size: u32,
    /// Presentation time in track ticks (decode time + composition offset - edit list start).
    pub pts: i64,
    /// Sync sample (random access point).
    pub sync: bool,
}

/// An MPEG-4 clean aperture (`clap`): the displayed part of the coded picture.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CleanAperture {
    /// Width (numerator, denominator).
    pub width: (u32, u32),
    /// Height.
    pub height: (u32, u32),
    /// Horizontal offset of the aperture's centre from the picture's centre.
    pub h_offset: (i32, u32),
    /// Vertical offset.
    pub v_offset: (i32, u32),
}

impl CleanAperture {
    /// The aperture as an integer crop `(left, top, width, height)` of a `w x h` picture, or
    /// `None` if it is fractional or does not fit.
    pub fn crop(&self, w: u32, h: u32) -> Option<(u32, u32, u32, u32)> {
        let int = |(n, d): (u32, u32)| {
            if d != 0 && n % d == 0 {
                Some(n / d)
            } else {
                None
            }
        };
        let cw = int(self.width)?;
        let ch = int(self.height)?;
        // left = (w - cw) / 2 + h_off: work in halves.
        let left2 = |full: u32, part: u32, (on, od): (i32, u32)| -> Option<u32> {
            if od == 0 || part == 0 || part > full {
                return None;
            }
            let twice_off = 2 * i64::from(on);
            if twice_off % i64::from(od) != 0 {
                return None;
            }
            let l2 = i64::from(full - part) + twice_off / i64::from(od);
            if l2 < 0 || l2 % 2 != 0 || l2 / 2 + i64::from(part) > i64::from(full) {
                return None;
            }
            u32::try_from(l2 / 2).ok()
        };
        let left = left2(w, cw, self.h_offset)?;
        let top = left2(h, ch, self.v_offset)?;
        Some((left, top, cw, ch))
    }
}

/// The first sample description of the video track.
#[derive(Debug, Clone)]
pub struct SampleEntry {
    /// The codec's four-character code (`avc1`, `hvc1`, ...).
    pub fourcc: FourCc,
    /// Width stored in the entry.
    pub width: u16,
    /// Height stored in the entry.
    pub height: u16,
    /// The `avcC` payload, for H.264.
    pub avcc: Option<Vec<u8>>,
    /// The clean aperture, if any.
    pub clap: Option<CleanAperture>,
    /// For `encv`: the original format from `sinf/frma`.
    pub original_format: Option<FourCc>,
}

/// The video track of a movie.
#[derive(Debug, Clone)]
pub struct VideoTrack {
    /// Ticks per second of the track's times.
    pub timescale: u32,
    /// The (first) sample description.
    pub entry: SampleEntry,
    /// More than one sample description is used.
    pub multiple_entries: bool,
    /// Samples in decode order.
    pub samples: Vec<Sample>,
    /// A `ctts` box is present.
    pub has_ctts: bool,
    /// Presentation order differs from decode order (B-frames).
    pub reordered: bool,
    /// Display size from `tkhd`, rounded to pixels.
    pub display: (u32, u32),
}

/// What the demuxer found.
#[derive(Debug, Clone)]
pub struct Movie {
    /// `ftyp` major brand (`isom`, `qt  `, ...), if there is an `ftyp`.
    pub major_brand: Option<FourCc>,
    /// The first video track, if any.
    pub video: Option<VideoTrack>,
    /// Fragmented MP4 (`mvex` / `moof`): samples live in fragments this demuxer does not read.
    pub fragmented: bool,
}

/// Reads the top-level boxes and the first video track's sample table.
pub fn read_movie(file: &mut File, file_len: u64, path: &Path) -> Result<Movie, VideoError> {
    let corrupt = |d: String| VideoError::corrupt(path, d);
    let io = |e| VideoError::io(path, "read", e);
    let mut pos = 0u64;
    let mut moov: Option<Vec<u8>> = None;
    let mut major_brand = None;
    let mut fragmented = false;
    let mut saw_mdat = false;
    while pos < file_len {
        let remaining = file_len - pos;
        if remaining < 8 {
            return Err(corrupt(format!(
                "the file ends {remaining} bytes into a box header at offset {pos}"
            )));
        }
        file.seek(SeekFrom::Start(pos)).map_err(io)?;
        let mut head = [0u8; 16];
        let head_len = remaining.min(16) as usize;
        file.read_exact(&mut head[..head_len]).map_err(io)?;
        let size32 = u32::from_be_bytes([head[0], head[1], head[2], head[3]]) as u64;
        let kind: FourCc = [head[4], head[5], head[6], head[7]];
        let (size, header) = match size32 {
            0 => (remaining, 8),
            1 => {
                if head_len < 16 {
                    return Err(corrupt(format!(
                        "the file ends inside the header of box at {pos}"
                    )));
                }
                let mut a = [0u8; 8];
                a.copy_from_slice(&head[8..16]);
                (u64::from_be_bytes(a), 16)
            }
            s => (s, 8),
        };
        if size < header {
            return Err(corrupt(format!(
                "box '{}' at offset {pos} has an impossible size of {size} bytes",
                fourcc_str(&kind)
            )));
        }
        if size > remaining {
            return Err(corrupt(format!(
                "box '{}' at offset {pos} claims {size} bytes but the file has only {remaining} \
                 left (truncated?)",
                fourcc_str(&kind)
            )));
        }
        match &kind {
            b"moov" => {
                if moov.is_some() {
                    return Err(corrupt("more than one 'moov' box".into()));
                }
                let len = size - header;
                if len > MAX_MOOV_BYTES {
                    return Err(corrupt(format!(
                        "'moov' box of {len} bytes exceeds the {MAX_MOOV_BYTES}-byte limit"
                    )));
                }
                let mut buf = vec![0u8; len as usize];
                file.seek(SeekFrom::Start(pos + header)).map_err(io)?;
                file.read_exact(&mut buf).map_err(io)?;
                moov = Some(buf);
            }
            b"ftyp" if size >= header + 4 && head_len >= header as usize + 4 => {
                let h = header as usize;
                major_brand = Some([head[h], head[h + 1], head[h + 2], head[h + 3]]);
            }
            b"moof" => fragmented = true,
            b"mdat" => saw_mdat = true,
            _ => {}
        }
        pos += size;
    }
    let Some(moov) = moov else {
        return Err(corrupt(if saw_mdat {
            "there is media data but no 'moov' box (the recording was not finished?)".into()
        } else {
            "no 'moov' box".into()
        }));
    };
    let mut video = None;
    for b in child_boxes(&moov, false) {
        let (kind, payload) = b.map_err(corrupt)?;
        match &kind {
            b"mvex" => fragmented = true,
            b"trak" if video.is_none() => {
                video = parse_trak(payload, file_len).map_err(corrupt)?;
            }
            _ => {}
        }
    }
    Ok(Movie {
        major_brand,
        video,
        fragmented,
    })
}

fn full_box_version(c: &mut Cur<'_>) -> Result<u8, String> {
    let v = c.u8()?;
    c.skip(3)?;
    Ok(v)
}

fn parse_trak(trak: &[u8], file_len: u64) -> Result<Option<VideoTrack>, String> {
    let Some(mdia) = find_child(trak, b"mdia")? else {
        return Err("'trak' has no 'mdia' box".into());
    };
    let Some(hdlr) = find_child(mdia, b"hdlr")? else {
        return Err("'mdia' has no 'hdlr' box".into());
    };
    let mut c = Cur::new(hdlr, "hdlr");
    c.skip(8)?;
    if &c.fourcc()? != b"vide" {
        return Ok(None);
    }
    let mdhd = find_child(mdia, b"mdhd")?.ok_or("video 'mdia' has no 'mdhd' box")?;
    let mut c = Cur::new(mdhd, "mdhd");
    let timescale = match full_box_version(&mut c)? {
        1 => {
            c.skip(16)?;
            c.u32()?
        }
        _ => {
            c.skip(8)?;
            c.u32()?
        }
    };
    if timescale == 0 {
        return Err("the video track's timescale is 0".into());
    }

    let mut display = (0, 0);
    if let Some(tkhd) = find_child(trak, b"tkhd")? {
        if tkhd.len() >= 8 {
            let t = &tkhd[tkhd.len() - 8..];
            let w = u32::from_be_bytes([t[0], t[1], t[2], t[3]]);
            let h = u32::from_be_bytes([t[4], t[5], t[6], t[7]]);
            // 16.16 fixed point, rounded; widened so 0xffff8000 and up cannot overflow.
            let round = |v: u32| ((u64::from(v) + 0x8000) >> 16) as u32;
            display = (round(w), round(h));
        }
    }

    // Edit list: the media time at which presentation starts.
    let mut edit_start: i64 = 0;
    if let Some(edts) = find_child(trak, b"edts")? {
        if let Some(elst) = find_child(edts, b"elst")? {
            let mut c = Cur::new(elst, "elst");
            let version = full_box_version(&mut c)?;
            let count = c.u32()?;
            let entry = if version == 1 { 20 } else { 12 };
            let table = c.table(count, entry)?;
            let mut t = Cur::new(table, "elst");
            for _ in 0..count {
                let media_time = if version == 1 {
                    t.skip(8)?;
                    t.u64()? as i64
                } else {
                    t.skip(4)?;
                    i64::from(t.u32()? as i32)
                };
                t.skip(4)?;
                if media_time >= 0 {
                    edit_start = media_time;
                    break;
                }
            }
        }
    }

    let minf = find_child(mdia, b"minf")?.ok_or("video 'mdia' has no 'minf' box")?;
    let stbl = find_child(minf, b"stbl")?.ok_or("video 'minf' has no 'stbl' box")?;
    let stsd = find_child(stbl, b"stsd")?.ok_or("video 'stbl' has no 'stsd' box")?;
    let entry = parse_stsd(stsd)?;

    // Sample sizes.
    let sizes: Vec<u32>;
    let count: u64;
    if let Some(stsz) = find_child(stbl, b"stsz")? {
        let mut c = Cur::new(stsz, "stsz");
        full_box_version(&mut c)?;
        let constant = c.u32()?;
        let n = c.u32()?;
        count = u64::from(n);
        if count > MAX_SAMPLES {
            return Err(format!("{count} samples exceed the limit of {MAX_SAMPLES}"));
        }
        if constant == 0 {
            let table = c.table(n, 4)?;
            sizes = table
                .chunks_exact(4)
                .map(|b| u32::from_be_bytes([b[0], b[1], b[2], b[3]]))
                .collect();
        } else {
            if count.saturating_mul(u64::from(constant)) > file_len {
                return Err(format!(
                    "{count} samples of {constant} bytes do not fit in a {file_len}-byte file"
                ));
            }
            sizes = vec![constant; count as usize];
        }
    } else if find_child(stbl, b"stz2")?.is_some() {
        return Err("compact sample sizes ('stz2') are not supported".into());
    } else {
        return Err("video 'stbl' has no 'stsz' box".into());
    }
    if let Some(i) = sizes.iter().position(|&s| s == 0) {
        return Err(format!("sample {i} has zero size"));
    }
    if let Some(i) = sizes.iter().position(|&s| u64::from(s) > MAX_SAMPLE_BYTES) {
        return Err(format!(
            "sample {i} of {} bytes exceeds the {MAX_SAMPLE_BYTES}-byte limit",
            sizes[i]
        ));
    }

    // Chunk offsets.
    let offsets: Vec<u64> = if let Some(stco) = find_child(stbl, b"stco")? {
        let mut c = Cur::new(stco, "stco");
        full_box_version(&mut c)?;
        let n = c.u32()?;
        c.table(n, 4)?
            .chunks_exact(4)
            .map(|b| u64::from(u32::from_be_bytes([b[0], b[1], b[2], b[3]])))
            .collect()
    } else if let Some(co64) = find_child(stbl, b"co64")? {
        let mut c = Cur::new(co64, "co64");
        full_box_version(&mut c)?;
        let n = c.u32()?;
        c.table(n, 8)?
            .chunks_exact(8)
            .map(|b| {
                let mut a = [0u8; 8];
                a.copy_from_slice(b);
                u64::from_be_bytes(a)
            })
            .collect()
    } else {
        return Err("video 'stbl' has neither 'stco' nor 'co64'".into());
    };

    // Sample-to-chunk.
    let stsc = find_child(stbl, b"stsc")?.ok_or("video 'stbl' has no 'stsc' box")?;
    let mut c = Cur::new(stsc, "stsc");
    full_box_version(&mut c)?;
    let n = c.u32()?;
    let table = c.table(n, 12)?;
    let mut stsc_entries = Vec::with_capacity(n as usize);
    let mut multiple_entries = false;
    for e in table.chunks_exact(12) {
        let first = u32::from_be_bytes([e[0], e[1], e[2], e[3]]);
        let per = u32::from_be_bytes([e[4], e[5], e[6], e[7]]);
        let desc = u32::from_be_bytes([e[8], e[9], e[10], e[11]]);
        if first == 0 || stsc_entries.last().is_some_and(|&(f, _)| first <= f) {
            return Err(format!("'stsc' first_chunk {first} is out of order"));
        }
        if desc != 1 {
            multiple_entries = true;
        }
        stsc_entries.push((first, per));
    }

    let mut samples: Vec<Sample> = Vec::with_capacity(sizes.len());
    'outer: for (k, &(first, per)) in stsc_entries.iter().enumerate() {
        let end_chunk = match stsc_entries.get(k + 1) {
            Some(&(next, _)) => u64::from(next),
            None => offsets.len() as u64 + 1,
        };
        let mut chunk = u64::from(first);
        while chunk < end_chunk {
            let Some(&chunk_offset) = offsets.get((chunk - 1) as usize) else {
                break 'outer;
            };
            let mut off = chunk_offset;
            for _ in 0..per {
                let i = samples.len();
                if i >= sizes.len() {
                    break 'outer;
                }
                let size = sizes[i];
                let end = off.checked_add(u64::from(size)).filter(|&e| e <= file_len);
                let Some(end) = end else {
                    return Err(format!(
                        "sample {i} at offset {off} ({size} bytes) lies past the end of the \
                         {file_len}-byte file"
                    ));
                };
                samples.push(Sample {
                    offset: off,
                    size,
                    pts: 0,
                    sync: true,
                });
                off = end;
            }
            chunk += 1;
        }
    }
    if samples.len() != sizes.len() {
        return Err(format!(
            "the sample table lists {} samples but its chunks hold {}",
            sizes.len(),
            samples.len()
        ));
    }

    // Decode times.
    let stts = find_child(stbl, b"stts")?.ok_or("video 'stbl' has no 'stts' box")?;
    let mut c = Cur::new(stts, "stts");
    full_box_version(&mut c)?;
    let n = c.u32()?;
    let table = c.table(n, 8)?;
    let mut i = 0usize;
    let mut dts: i64 = 0;
    for e in table.chunks_exact(8) {
        let cnt = u32::from_be_bytes([e[0], e[1], e[2], e[3]]);
        let delta = i64::from(u32::from_be_bytes([e[4], e[5], e[6], e[7]]));
        for _ in 0..cnt {
            if i >= samples.len() {
                break;
            }
            samples[i].pts = dts;
            dts = dts.checked_add(delta).ok_or("decode times overflow")?;
            i += 1;
        }
    }
    if i < samples.len() {
        return Err(format!("'stts' covers {i} of {} samples", samples.len()));
    }

    // Composition offsets.
    let mut has_ctts = false;
    if let Some(ctts) = find_child(stbl, b"ctts")? {
        has_ctts = true;
        let mut c = Cur::new(ctts, "ctts");
        full_box_version(&mut c)?;
        let n = c.u32()?;
        let table = c.table(n, 8)?;
        let mut i = 0usize;
        for e in table.chunks_exact(8) {
            let cnt = u32::from_be_bytes([e[0], e[1], e[2], e[3]]);
            // Version 0 is unsigned by the letter of the standard, signed in practice.
            let off = i64::from(i32::from_be_bytes([e[4], e[5], e[6], e[7]]));
            for _ in 0..cnt {
                if i >= samples.len() {
                    break;
                }
                samples[i].pts += off;
                i += 1;
            }
        }
        if i < samples.len() {
            return Err(format!("'ctts' covers {i} of {} samples", samples.len()));
        }
    }
    for s in &mut samples {
        s.pts -= edit_start;
    }
    let reordered = samples.windows(2).any(|w| w[1].pts < w[0].pts);

    // Sync samples.
    if let Some(stss) = find_child(stbl, b"stss")? {
        let mut c = Cur::new(stss, "stss");
        full_box_version(&mut c)?;
        let n = c.u32()?;
        let table = c.table(n, 4)?;
        for s in &mut samples {
            s.sync = false;
        }
        for e in table.chunks_exact(4) {
            let k = u32::from_be_bytes([e[0], e[1], e[2], e[3]]) as usize;
            if k == 0 || k > samples.len() {
                return Err(format!("'stss' names sample {k} of {}", samples.len()));
            }
            samples[k - 1].sync = true;
        }
    }

    Ok(Some(VideoTrack {
        timescale,
        entry,
        multiple_entries,
        samples,
        has_ctts,
        reordered,
        display,
    }))
}

fn parse_stsd(stsd: &[u8]) -> Result<SampleEntry, String> {
    let mut c = Cur::new(stsd, "stsd");
    full_box_version(&mut c)?;
    let n = c.u32()?;
    if n == 0 {
        return Err("'stsd' has no sample description".into());
    }
    let first = child_boxes(c.rest(), false)
        .next()
        .ok_or("'stsd' has no sample description")??;
    let (fourcc, payload) = first;
    let mut entry = SampleEntry {
        fourcc,
        width: 0,
        height: 0,
        avcc: None,
        clap: None,
        original_format: None,
    };
    if payload.len() < 78 {
        // Not a visual sample entry we can read: report the codec only.
        return Ok(entry);
    }
    let mut c = Cur::new(payload, "visual sample entry");
    c.skip(24)?;
    entry.width = c.u16()?;
    entry.height = c.u16()?;
    c.skip(50)?;
    for b in child_boxes(c.rest(), true) {
        let (kind, data) = b?;
        match &kind {
            b"avcC" => entry.avcc = Some(data.to_vec()),
            b"clap" => {
                let mut c = Cur::new(data, "clap");
                let v: Vec<u32> = (0..8).map(|_| c.u32()).collect::<Result<_, _>>()?;
                entry.clap = Some(CleanAperture {
                    width: (v[0], v[1]),
                    height: (v[2], v[3]),
                    h_offset: (v[4] as i32, v[5]),
                    v_offset: (v[6] as i32, v[7]),
                });
            }
            b"sinf" => {
                if let Some(frma) = find_child(data, b"frma")? {
                    if frma.len() >= 4 {
                        entry.original_format = Some([frma[0], frma[1], frma[2], frma[3]]);
                    }
                }
            }
            _ => {}
        }
    }
    Ok(entry)
}

/// Reads one sample's bytes into `buf` (resized).
pub fn read_sample(
    file: &mut File,
    sample: &Sample,
    buf: &mut Vec<u8>,
    path: &Path,
) -> Result<(), VideoError> {
    buf.resize(sample.size as usize, 0);
    file.seek(SeekFrom::Start(sample.offset))
        .map_err(|e| VideoError::io(path, "read", e))?;
    file.read_exact(buf)
        .map_err(|e| VideoError::io(path, "read", e))
}

// ---------------------------------------------------------------------------------------
// Writing

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
    pub(crate) fn end(&mut self) -> Result<(), String> {
        let start = self.open.pop().ok_or("box end without begin")?;
        let size = u32::try_from(self.buf.len() - start).map_err(|_| "box over 4 GiB")?;
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
pub(crate) fn build_moov(t: &TrackLayout<'_>) -> Result<Vec<u8>, String> {
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn clean_aperture_crop() {
        let clap = CleanAperture {
            width: (321, 1),
            height: (241, 1),
            h_offset: (-1, 2),
            v_offset: (-1, 2),
        };
        assert_eq!(clap.crop(322, 242), Some((0, 0, 321, 241)));
        let centred = CleanAperture {
            width: (300, 1),
            height: (200, 1),
            h_offset: (0, 1),
            v_offset: (0, 1),
        };
        assert_eq!(centred.crop(320, 240), Some((10, 20, 300, 200)));
        let too_big = CleanAperture {
            width: (400, 1),
            height: (200, 1),
            h_offset: (0, 1),
            v_offset: (0, 1),
        };
        assert_eq!(too_big.crop(320, 240), None);
        let zero_den = CleanAperture {
            width: (300, 0),
            height: (200, 1),
            h_offset: (0, 1),
            v_offset: (0, 1),
        };
        assert_eq!(zero_den.crop(320, 240), None);
    }

    #[test]
    fn child_boxes_reject_overruns() {
        let data = [0, 0, 0, 16, b'f', b'r', b'e', b'e', 0, 0, 0, 0];
        let r: Vec<_> = child_boxes(&data, false).collect();
        assert!(r[0].as_ref().is_err_and(|e| e.contains("claims 16 bytes")));
        let data = [0, 0, 0, 4, b'f', b'r', b'e', b'e'];
        assert!(child_boxes(&data, false).next().is_some_and(|r| r.is_err()));
        let data = [0, 0, 0, 8, b'f', b'r', b'e', b'e', 0, 0, 0, 0];
        let r: Vec<_> = child_boxes(&data, true).collect();
        assert_eq!(r.len(), 1);
    }
}
