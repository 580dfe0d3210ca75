//! The demuxer: the top-level boxes, the first video track's sample table, and samples read
//! one at a time by offset.

use std::fs::File;
use std::io::{Read, Seek, SeekFrom};
use std::path::Path;

use super::boxes::{child_boxes, find_child, Cur};
use super::{fourcc_str, FourCc, Mp4Error, MAX_MOOV_BYTES, MAX_SAMPLES, MAX_SAMPLE_BYTES};
use crate::VideoError;

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
        let (kind, payload) = b.map_err(|e| corrupt(e.to_string()))?;
        match &kind {
            b"mvex" => fragmented = true,
            b"trak" if video.is_none() => {
                video = parse_trak(payload, file_len).map_err(|e| corrupt(e.to_string()))?;
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

fn full_box_version(c: &mut Cur<'_>) -> Result<u8, Mp4Error> {
    let v = c.u8()?;
    c.skip(3)?;
    Ok(v)
}

fn parse_trak(trak: &[u8], file_len: u64) -> Result<Option<VideoTrack>, Mp4Error> {
    let missing = |parent, child| Mp4Error::MissingBox { parent, child };
    let Some(mdia) = find_child(trak, b"mdia")? else {
        return Err(missing("'trak'", "mdia"));
    };
    let Some(hdlr) = find_child(mdia, b"hdlr")? else {
        return Err(missing("'mdia'", "hdlr"));
    };
    let mut c = Cur::new(hdlr, "hdlr");
    c.skip(8)?;
    if &c.fourcc()? != b"vide" {
        return Ok(None);
    }
    let mdhd = find_child(mdia, b"mdhd")?.ok_or(missing("video 'mdia'", "mdhd"))?;
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
        return Err(Mp4Error::ZeroTimescale);
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

    let minf = find_child(mdia, b"minf")?.ok_or(missing("video 'mdia'", "minf"))?;
    let stbl = find_child(minf, b"stbl")?.ok_or(missing("video 'minf'", "stbl"))?;
    let stsd = find_child(stbl, b"stsd")?.ok_or(missing("video 'stbl'", "stsd"))?;
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
            return Err(Mp4Error::TooManySamples { count });
        }
        if constant == 0 {
            let table = c.table(n, 4)?;
            sizes = table
                .chunks_exact(4)
                .map(|b| u32::from_be_bytes([b[0], b[1], b[2], b[3]]))
                .collect();
        } else {
            if count.saturating_mul(u64::from(constant)) > file_len {
                return Err(Mp4Error::SamplesExceedFile {
                    count,
                    size: constant,
                    file_len,
                });
            }
            sizes = vec![constant; count as usize];
        }
    } else if find_child(stbl, b"stz2")?.is_some() {
        return Err(Mp4Error::CompactSampleSizes);
    } else {
        return Err(missing("video 'stbl'", "stsz"));
    }
    if let Some(i) = sizes.iter().position(|&s| s == 0) {
        return Err(Mp4Error::EmptySample { index: i });
    }
    if let Some(i) = sizes.iter().position(|&s| u64::from(s) > MAX_SAMPLE_BYTES) {
        return Err(Mp4Error::SampleTooLarge {
            index: i,
            size: sizes[i],
        });
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
        return Err(Mp4Error::NoChunkOffsets);
    };

    // Sample-to-chunk.
    let stsc = find_child(stbl, b"stsc")?.ok_or(missing("video 'stbl'", "stsc"))?;
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
            return Err(Mp4Error::ChunkOrder { first });
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
                    return Err(Mp4Error::SamplePastEnd {
                        index: i,
                        offset: off,
                        size,
                        file_len,
                    });
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
        return Err(Mp4Error::ChunksShort {
            listed: sizes.len(),
            held: samples.len(),
        });
    }

    // Decode times.
    let stts = find_child(stbl, b"stts")?.ok_or(missing("video 'stbl'", "stts"))?;
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
            dts = dts.checked_add(delta).ok_or(Mp4Error::DecodeTimeOverflow)?;
            i += 1;
        }
    }
    if i < samples.len() {
        return Err(Mp4Error::TimesShort {
            table: "stts",
            covered: i,
            samples: samples.len(),
        });
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
            return Err(Mp4Error::TimesShort {
                table: "ctts",
                covered: i,
                samples: samples.len(),
            });
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
                return Err(Mp4Error::SyncSampleOutOfRange {
                    sample: k,
                    samples: samples.len(),
                });
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

fn parse_stsd(stsd: &[u8]) -> Result<SampleEntry, Mp4Error> {
    let mut c = Cur::new(stsd, "stsd");
    full_box_version(&mut c)?;
    let n = c.u32()?;
    if n == 0 {
        return Err(Mp4Error::NoSampleDescription);
    }
    let first = child_boxes(c.rest(), false)
        .next()
        .ok_or(Mp4Error::NoSampleDescription)??;
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
}
