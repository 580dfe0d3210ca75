//! The parts of H.264 (ISO/IEC 14496-10) and its MP4 binding (ISO/IEC 14496-15) this crate
//! needs: NAL unit framing (Annex B and length-prefixed), emulation prevention, the sequence
//! parameter set (what the built-in decoder can handle, the picture size, VUI colour), slice
//! types (to spot B-frames) and the `avcC` decoder configuration record.
//!
//! Everything parses untrusted bytes: every read is bounds-checked and returns `None` /
//! `Err(H264Error)` on malformed input; nothing panics.

/// What is wrong with a malformed H.264 NAL unit, sample or `avcC` record. Names no file: the
/// reader and writer wrap it in a [`crate::VideoError`] that does.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum H264Error {
    /// A length-prefixed sample ends with too few bytes for the next NAL length.
    #[error("{remaining} trailing bytes at offset {offset} are too few for a NAL length")]
    TrailingBytes { remaining: usize, offset: usize },
    /// A NAL unit's length runs past the end of its sample.
    #[error("NAL unit of {len} bytes at offset {offset} overruns the {sample_len}-byte sample")]
    NalOverrun {
        len: usize,
        offset: usize,
        sample_len: usize,
    },
    /// The NAL unit given as a sequence parameter set is of another type.
    #[error("not a sequence parameter set")]
    NotSps,
    /// The sequence parameter set ends early or its codes are malformed.
    #[error("sequence parameter set is truncated or malformed")]
    SpsTruncated,
    /// A sequence parameter set field holds a value outside its range.
    #[error("{field} {value} is out of range")]
    ValueOutOfRange { field: &'static str, value: u64 },
    /// A sequence parameter set field (or pair of fields) is outside its range.
    #[error("{field} is out of range")]
    FieldOutOfRange { field: &'static str },
    /// The coded picture is larger than 65536 pixels on a side.
    #[error("coded size {width}x{height} is out of range")]
    CodedSize { width: u64, height: u64 },
    /// The cropping window leaves no pixels.
    #[error("frame cropping removes the whole picture")]
    CropsWholePicture,
    /// The `avcC` record ends early.
    #[error("avcC record of {len} bytes is truncated")]
    AvcCTruncated { len: usize },
    /// The `avcC` record's version is not 1.
    #[error("avcC configurationVersion {0} is not 1")]
    AvcCVersion(u8),
    /// The `avcC` record announces 3-byte NAL lengths.
    #[error("avcC NAL length size of 3 bytes is invalid")]
    AvcCLengthSize,
    /// Parameter sets too short, too long or empty for an `avcC` record.
    #[error("parameter set sizes are out of range")]
    ParameterSetSizes,
}

/// NAL unit type: coded slice of a non-IDR picture.
pub const NAL_SLICE: u8 = 1;
/// NAL unit type: coded slice of an IDR picture.
pub const NAL_IDR: u8 = 5;
/// NAL unit type: sequence parameter set.
pub const NAL_SPS: u8 = 7;
/// NAL unit type: picture parameter set.
pub const NAL_PPS: u8 = 8;

/// The NAL unit type (low 5 bits of the first byte), or `None` for an empty unit.
pub fn nal_type(nal: &[u8]) -> Option<u8> {
    nal.first().map(|b| b & 0x1f)
}

/// Splits an Annex B byte stream (start codes `00 00 01` / `00 00 00 01`) into NAL units
/// (without start codes, trailing zero bytes trimmed).
pub fn split_annex_b(data: &[u8]) -> Vec<&[u8]> {
    let mut starts = Vec::new();
    let mut i = 0;
    while i + 3 <= data.len() {
        if data[i] == 0 && data[i + 1] == 0 && data[i + 2] == 1 {
            starts.push(i + 3);
            i += 3;
        } else {
            i += 1;
        }
    }
    let mut out = Vec::with_capacity(starts.len());
    for (k, &s) in starts.iter().enumerate() {
        let mut end = if k + 1 < starts.len() {
            starts[k + 1] - 3
        } else {
            data.len()
        };
        while end > s && data[end - 1] == 0 {
            end -= 1;
        }
        if end > s {
            out.push(&data[s..end]);
        }
    }
    out
}

/// Iterates over the NAL units of a length-prefixed (MP4 `avc1`) sample, with `length_size`
/// bytes (1, 2 or 4) per length. Yields `Err` with a description on a length that overruns
/// the sample.
pub fn split_length_prefixed(
    sample: &[u8],
    length_size: usize,
) -> impl Iterator<Item = Result<&[u8], H264Error>> {
    let mut pos = 0usize;
    let mut failed = false;
    std::iter::from_fn(move || {
        if failed || pos >= sample.len() {
            return None;
        }
        if sample.len() - pos < length_size {
            failed = true;
            return Some(Err(H264Error::TrailingBytes {
                remaining: sample.len() - pos,
                offset: pos,
            }));
        }
        let mut len = 0usize;
        for &b in &sample[pos..pos + length_size] {
            len = (len << 8) | usize::from(b);
        }
        pos += length_size;
        if len > sample.len() - pos {
            failed = true;
            return Some(Err(H264Error::NalOverrun {
                len,
                offset: pos,
                sample_len: sample.len(),
            }));
        }
        let nal = &sample[pos..pos + len];
        pos += len;
        Some(Ok(nal))
    })
}

/// Removes emulation prevention bytes (`00 00 03` -> `00 00`) from a NAL unit's payload.
pub fn unescape_rbsp(data: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(data.len());
    let mut zeros = 0;
    for &b in data {
        if zeros >= 2 && b == 3 {
            zeros = 0;
            continue;
        }
        zeros = if b == 0 { zeros + 1 } else { 0 };
        out.push(b);
    }
    out
}

/// MSB-first bit reader over an RBSP.
pub struct BitReader<'a> {
    data: &'a [u8],
    pos: usize,
}

impl<'a> BitReader<'a> {
    /// A reader at bit 0 of `data`.
    pub fn new(data: &'a [u8]) -> Self {
        BitReader { data, pos: 0 }
    }

    /// One bit.
    pub fn bit(&mut self) -> Option<bool> {
        let byte = *self.data.get(self.pos / 8)?;
        let b = (byte >> (7 - (self.pos % 8))) & 1;
        self.pos += 1;
        Some(b == 1)
    }

    /// `n <= 32` bits, MSB first.
    pub fn bits(&mut self, n: u32) -> Option<u32> {
        if n > 32 {
            return None;
        }
        let mut v = 0u64;
        for _ in 0..n {
            v = (v << 1) | u64::from(self.bit()?);
        }
        u32::try_from(v).ok()
    }

    /// Unsigned Exp-Golomb `ue(v)`.
    pub fn ue(&mut self) -> Option<u32> {
        let mut zeros = 0u32;
        while !self.bit()? {
            zeros += 1;
            if zeros > 31 {
                return None;
            }
        }
        let rest = self.bits(zeros)?;
        let v = (1u64 << zeros) - 1 + u64::from(rest);
        u32::try_from(v).ok()
    }

    /// Signed Exp-Golomb `se(v)`.
    pub fn se(&mut self) -> Option<i32> {
        let k = i64::from(self.ue()?);
        let v = if k % 2 == 1 { (k + 1) / 2 } else { -(k / 2) };
        i32::try_from(v).ok()
    }
}

/// What this crate needs from a sequence parameter set.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Sps {
    /// `profile_idc` (66 Baseline, 77 Main, 88 Extended, 100 High, 110 High 10, 122 High 4:2:2,
    /// 244 High 4:4:4, ...).
    pub profile_idc: u8,
    /// `constraint_set` flags byte.
    pub constraint_flags: u8,
    /// `level_idc`.
    pub level_idc: u8,
    /// `chroma_format_idc` (1 = 4:2:0).
    pub chroma_format_idc: u32,
    /// Luma bit depth.
    pub bit_depth_luma: u32,
    /// Chroma bit depth.
    pub bit_depth_chroma: u32,
    /// `frame_mbs_only_flag` (false = interlaced coding possible).
    pub frame_mbs_only: bool,
    /// `pic_order_cnt_type` (2 = output order is decode order).
    pub pic_order_cnt_type: u32,
    /// Coded width in pixels (macroblocks x 16).
    pub coded_width: u32,
    /// Coded height in pixels.
    pub coded_height: u32,
    /// Displayed width after the SPS's frame cropping.
    pub width: u32,
    /// Displayed height after the SPS's frame cropping.
    pub height: u32,
    /// Colour signalling from the VUI, if present and parsable.
    pub vui: Option<Vui>,
}

/// The VUI fields this crate uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Vui {
    /// `video_full_range_flag`.
    pub full_range: bool,
    /// `matrix_coefficients` when a colour description is present.
    pub matrix: Option<u8>,
    /// `max_num_reorder_frames` from the bitstream restriction, when present.
    pub max_num_reorder_frames: Option<u32>,
}

impl Sps {
    /// A human name for the profile, e.g. `"H.264 High profile"`.
    pub fn profile_name(&self) -> String {
        let name = match self.profile_idc {
            66 if self.constraint_flags & 0x40 != 0 => "Constrained Baseline",
            66 => "Baseline",
            77 => "Main",
            88 => "Extended",
            100 => "High",
            110 => "High 10",
            122 => "High 4:2:2",
            244 => "High 4:4:4 Predictive",
            44 => "CAVLC 4:4:4 Intra",
            118 | 128 => "Multiview High",
            83 | 86 => "Scalable",
            _ => "unknown",
        };
        format!(
            "H.264 {name} profile (profile_idc {}, level {:.1})",
            self.profile_idc,
            f64::from(self.level_idc) / 10.0
        )
    }

    /// Why the built-in (OpenH264) decoder cannot decode this stream, or `None` if it can.
    pub fn native_limitation(&self) -> Option<String> {
        if self.chroma_format_idc != 1 {
            let c = match self.chroma_format_idc {
                0 => "monochrome",
                2 => "4:2:2",
                3 => "4:4:4",
                _ => "unknown",
            };
            return Some(format!(
                "{c} chroma; the built-in decoder handles 4:2:0 only"
            ));
        }
        if self.bit_depth_luma != 8 || self.bit_depth_chroma != 8 {
            return Some(format!(
                "{}-bit samples; the built-in decoder handles 8-bit only",
                self.bit_depth_luma.max(self.bit_depth_chroma)
            ));
        }
        if !self.frame_mbs_only {
            return Some("interlaced coding; the built-in decoder handles progressive only".into());
        }
        if !matches!(self.profile_idc, 66 | 77 | 100) {
            return Some("a profile the built-in decoder does not implement".into());
        }
        if self.pic_order_cnt_type != 2 {
            if let Some(n) = self.vui.and_then(|v| v.max_num_reorder_frames) {
                if n > 0 {
                    return Some(format!("B-frames (up to {n} reordered frames)"));
                }
            }
        }
        None
    }
}

fn skip_scaling_list(r: &mut BitReader<'_>, size: usize) -> Option<()> {
    let mut last = 8i32;
    let mut next = 8i32;
    for _ in 0..size {
        if next != 0 {
            let delta = r.se()?;
            next = (last + delta + 256).rem_euclid(256);
        }
        if next != 0 {
            last = next;
        }
    }
    Some(())
}

fn skip_hrd(r: &mut BitReader<'_>) -> Option<()> {
    let cpb_cnt = r.ue()? + 1;
    if cpb_cnt > 32 {
        return None;
    }
    r.bits(8)?;
    for _ in 0..cpb_cnt {
        r.ue()?;
        r.ue()?;
        r.bit()?;
    }
    r.bits(20)?;
    Some(())
}

fn parse_vui(r: &mut BitReader<'_>) -> Option<Vui> {
    let mut vui = Vui::default();
    if r.bit()? {
        let idc = r.bits(8)?;
        if idc == 255 {
            r.bits(32)?;
        }
    }
    if r.bit()? {
        r.bit()?;
    }
    if r.bit()? {
        r.bits(3)?;
        vui.full_range = r.bit()?;
        if r.bit()? {
            r.bits(16)?;
            vui.matrix = Some(u8::try_from(r.bits(8)?).ok()?);
        }
    }
    if r.bit()? {
        r.ue()?;
        r.ue()?;
    }
    if r.bit()? {
        r.bits(32)?;
        r.bits(32)?;
        r.bit()?;
    }
    let nal_hrd = r.bit()?;
    if nal_hrd {
        skip_hrd(r)?;
    }
    let vcl_hrd = r.bit()?;
    if vcl_hrd {
        skip_hrd(r)?;
    }
    if nal_hrd || vcl_hrd {
        r.bit()?;
    }
    r.bit()?;
    if r.bit()? {
        r.bit()?; // motion_vectors_over_pic_boundaries_flag
        for _ in 0..4 {
            // max_bytes_per_pic_denom, max_bits_per_mb_denom, log2_max_mv_length_{h,v}
            r.ue()?;
        }
        vui.max_num_reorder_frames = Some(r.ue()?);
        r.ue()?;
    }
    Some(vui)
}

/// Parses a sequence parameter set NAL unit (including its one-byte NAL header).
pub fn parse_sps(nal: &[u8]) -> Result<Sps, H264Error> {
    if nal_type(nal) != Some(NAL_SPS) {
        return Err(H264Error::NotSps);
    }
    let rbsp = unescape_rbsp(&nal[1..]);
    let mut r = BitReader::new(&rbsp);
    let short = || H264Error::SpsTruncated;
    let profile_idc = r.bits(8).ok_or_else(short)? as u8;
    let constraint_flags = r.bits(8).ok_or_else(short)? as u8;
    let level_idc = r.bits(8).ok_or_else(short)? as u8;
    let sps_id = r.ue().ok_or_else(short)?;
    if sps_id > 31 {
        return Err(H264Error::ValueOutOfRange {
            field: "seq_parameter_set_id",
            value: sps_id.into(),
        });
    }
    let (mut chroma_format_idc, mut bit_depth_luma, mut bit_depth_chroma) = (1, 8, 8);
    if matches!(
        profile_idc,
        100 | 110 | 122 | 244 | 44 | 83 | 86 | 118 | 128 | 138 | 139 | 134 | 135
    ) {
        chroma_format_idc = r.ue().ok_or_else(short)?;
        if chroma_format_idc > 3 {
            return Err(H264Error::ValueOutOfRange {
                field: "chroma_format_idc",
                value: chroma_format_idc.into(),
            });
        }
        if chroma_format_idc == 3 {
            r.bit().ok_or_else(short)?;
        }
        bit_depth_luma = r.ue().ok_or_else(short)? + 8;
        bit_depth_chroma = r.ue().ok_or_else(short)? + 8;
        if bit_depth_luma > 14 || bit_depth_chroma > 14 {
            return Err(H264Error::FieldOutOfRange { field: "bit depth" });
        }
        r.bit().ok_or_else(short)?;
        if r.bit().ok_or_else(short)? {
            let lists = if chroma_format_idc == 3 { 12 } else { 8 };
            for i in 0..lists {
                if r.bit().ok_or_else(short)? {
                    skip_scaling_list(&mut r, if i < 6 { 16 } else { 64 }).ok_or_else(short)?;
                }
            }
        }
    }
    r.ue().ok_or_else(short)?; // log2_max_frame_num_minus4
    let pic_order_cnt_type = r.ue().ok_or_else(short)?;
    match pic_order_cnt_type {
        0 => {
            r.ue().ok_or_else(short)?;
        }
        1 => {
            r.bit().ok_or_else(short)?;
            r.se().ok_or_else(short)?;
            r.se().ok_or_else(short)?;
            let n = r.ue().ok_or_else(short)?;
            if n > 255 {
                return Err(H264Error::FieldOutOfRange {
                    field: "num_ref_frames_in_pic_order_cnt_cycle",
                });
            }
            for _ in 0..n {
                r.se().ok_or_else(short)?;
            }
        }
        2 => {}
        t => {
            return Err(H264Error::ValueOutOfRange {
                field: "pic_order_cnt_type",
                value: t.into(),
            })
        }
    }
    r.ue().ok_or_else(short)?; // max_num_ref_frames
    r.bit().ok_or_else(short)?; // gaps_in_frame_num_value_allowed_flag
    let width_mbs = u64::from(r.ue().ok_or_else(short)?) + 1;
    let height_map_units = u64::from(r.ue().ok_or_else(short)?) + 1;
    let frame_mbs_only = r.bit().ok_or_else(short)?;
    if !frame_mbs_only {
        r.bit().ok_or_else(short)?;
    }
    r.bit().ok_or_else(short)?; // direct_8x8_inference_flag
    let coded_width = width_mbs * 16;
    let coded_height = height_map_units * 16 * if frame_mbs_only { 1 } else { 2 };
    if coded_width > 65536 || coded_height > 65536 {
        return Err(H264Error::CodedSize {
            width: coded_width,
            height: coded_height,
        });
    }
    let (mut width, mut height) = (coded_width, coded_height);
    if r.bit().ok_or_else(short)? {
        let l = u64::from(r.ue().ok_or_else(short)?);
        let rr = u64::from(r.ue().ok_or_else(short)?);
        let t = u64::from(r.ue().ok_or_else(short)?);
        let b = u64::from(r.ue().ok_or_else(short)?);
        let (ux, uy) = match chroma_format_idc {
            1 => (2, 2),
            2 => (2, 1),
            _ => (1, 1),
        };
        let uy = uy * if frame_mbs_only { 1 } else { 2 };
        let cw = (l + rr) * ux;
        let ch = (t + b) * uy;
        if cw >= width || ch >= height {
            return Err(H264Error::CropsWholePicture);
        }
        width -= cw;
        height -= ch;
    }
    let vui = match r.bit() {
        Some(true) => parse_vui(&mut r),
        _ => None,
    };
    Ok(Sps {
        profile_idc,
        constraint_flags,
        level_idc,
        chroma_format_idc,
        bit_depth_luma,
        bit_depth_chroma,
        frame_mbs_only,
        pic_order_cnt_type,
        coded_width: coded_width as u32,
        coded_height: coded_height as u32,
        width: width as u32,
        height: height as u32,
        vui,
    })
}

/// The H.264 slice type of a slice NAL unit (type 1 or 5): 0 P, 1 B, 2 I, 3 SP, 4 SI.
pub fn slice_type(nal: &[u8]) -> Option<u32> {
    if !matches!(nal_type(nal), Some(NAL_SLICE) | Some(NAL_IDR)) {
        return None;
    }
    // The first two fields fit in a few bytes; unescape only those.
    let head = unescape_rbsp(&nal[1..nal.len().min(16)]);
    let mut r = BitReader::new(&head);
    r.ue()?; // first_mb_in_slice
    Some(r.ue()? % 5)
}

/// An `avcC` decoder configuration record.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct AvcConfig {
    /// `AVCProfileIndication`.
    pub profile: u8,
    /// `profile_compatibility`.
    pub compatibility: u8,
    /// `AVCLevelIndication`.
    pub level: u8,
    /// Bytes per NAL length in samples (1, 2 or 4).
    pub length_size: usize,
    /// Sequence parameter sets (NAL units with header).
    pub sps: Vec<Vec<u8>>,
    /// Picture parameter sets.
    pub pps: Vec<Vec<u8>>,
}

impl AvcConfig {
    /// Parses an `avcC` box payload.
    pub fn parse(data: &[u8]) -> Result<AvcConfig, H264Error> {
        let short = || H264Error::AvcCTruncated { len: data.len() };
        if data.len() < 7 {
            return Err(short());
        }
        if data[0] != 1 {
            return Err(H264Error::AvcCVersion(data[0]));
        }
        let length_size = usize::from(data[4] & 3) + 1;
        if length_size == 3 {
            return Err(H264Error::AvcCLengthSize);
        }
        let mut pos = 5;
        let read_sets = |count: usize, pos: &mut usize| -> Result<Vec<Vec<u8>>, H264Error> {
            let mut sets = Vec::new();
            for _ in 0..count {
                let len_bytes = data.get(*pos..*pos + 2).ok_or_else(short)?;
                let len = usize::from(u16::from_be_bytes([len_bytes[0], len_bytes[1]]));
                *pos += 2;
                let set = data.get(*pos..*pos + len).ok_or_else(short)?;
                *pos += len;
                sets.push(set.to_vec());
            }
            Ok(sets)
        };
        let n_sps = usize::from(data[pos] & 0x1f);
        pos += 1;
        let sps = read_sets(n_sps, &mut pos)?;
        let n_pps = usize::from(*data.get(pos).ok_or_else(short)?);
        pos += 1;
        let pps = read_sets(n_pps, &mut pos)?;
        Ok(AvcConfig {
            profile: data[1],
            compatibility: data[2],
            level: data[3],
            length_size,
            sps,
            pps,
        })
    }

    /// Serialises the record (4-byte NAL lengths), with the High-profile extension fields
    /// when the profile needs them.
    pub fn from_parameter_sets(sps: &[u8], pps: &[u8]) -> Result<Vec<u8>, H264Error> {
        let parsed = parse_sps(sps)?;
        if sps.len() < 4 || sps.len() > 65535 || pps.len() > 65535 || pps.is_empty() {
            return Err(H264Error::ParameterSetSizes);
        }
        let mut out = vec![1, sps[1], sps[2], sps[3], 0xfc | 3, 0xe0 | 1];
        out.extend_from_slice(&(sps.len() as u16).to_be_bytes());
        out.extend_from_slice(sps);
        out.push(1);
        out.extend_from_slice(&(pps.len() as u16).to_be_bytes());
        out.extend_from_slice(pps);
        if matches!(parsed.profile_idc, 100 | 110 | 122 | 144) {
            out.push(0xfc | (parsed.chroma_format_idc as u8 & 3));
            out.push(0xf8 | ((parsed.bit_depth_luma - 8) as u8 & 7));
            out.push(0xf8 | ((parsed.bit_depth_chroma - 8) as u8 & 7));
            out.push(0);
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exp_golomb() {
        // 1 | 010 | 011 | 00100 | 00101 -> 0, 1, 2, 3, 4
        let data = [0b1010_0110, 0b0100_0010, 0b1000_0000];
        let mut r = BitReader::new(&data);
        assert_eq!(
            [r.ue(), r.ue(), r.ue(), r.ue(), r.ue()],
            [Some(0), Some(1), Some(2), Some(3), Some(4)]
        );
        let data = [0b0100_1100];
        let mut r = BitReader::new(&data);
        assert_eq!((r.se(), r.se()), (Some(1), Some(-1)));
        assert_eq!(BitReader::new(&[0, 0, 0, 0, 0]).ue(), None);
    }

    #[test]
    fn annex_b_and_length_prefixed() {
        let stream = [
            0, 0, 0, 1, 0x67, 1, 2, 0, 0, 1, 0x68, 3, 0, 0, 0, 1, 0x65, 4, 0,
        ];
        let nals = split_annex_b(&stream);
        assert_eq!(
            nals,
            vec![&[0x67, 1, 2][..], &[0x68, 3][..], &[0x65, 4][..]]
        );
        let sample = [0, 0, 0, 2, 0x65, 1, 0, 0, 0, 9, 0x41];
        let parts: Vec<_> = split_length_prefixed(&sample, 4).collect();
        assert_eq!(parts[0], Ok(&[0x65, 1][..]));
        assert!(parts[1].is_err());
        assert_eq!(parts.len(), 2);
    }

    #[test]
    fn emulation_prevention() {
        assert_eq!(
            unescape_rbsp(&[0, 0, 3, 1, 0, 0, 3, 0, 3]),
            vec![0, 0, 1, 0, 0, 0, 3]
        );
    }

    #[test]
    fn sps_of_a_known_stream() {
        // x264 (ffmpeg -c:v libx264 -profile:v high -bf 2), 1280x720, VUI with a bitstream
        // restriction announcing 2 reordered frames.
        let sps = [
            0x67, 0x64, 0x00, 0x1f, 0xac, 0xd9, 0x40, 0x50, 0x05, 0xbb, 0x01, 0x10, 0x00, 0x00,
            0x03, 0x00, 0x10, 0x00, 0x00, 0x03, 0x03, 0x00, 0xf1, 0x83, 0x19, 0x60,
        ];
        let p = parse_sps(&sps).expect("parses");
        assert_eq!(
            (p.profile_idc, p.width, p.height, p.chroma_format_idc),
            (100, 1280, 720, 1)
        );
        assert!(p.frame_mbs_only);
        assert_eq!(p.vui.and_then(|v| v.max_num_reorder_frames), Some(2));
        assert!(p
            .native_limitation()
            .is_some_and(|l| l.contains("B-frames")));
        // Garbage and truncation are errors, not panics.
        assert!(parse_sps(&sps[..5]).is_err());
        assert!(parse_sps(&[0x67]).is_err());
        assert!(parse_sps(&[0x67, 0x64, 0, 0x1f, 0, 0, 0, 0]).is_err());
    }
}
