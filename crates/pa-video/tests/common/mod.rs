//! Helpers shared by the integration tests: synthetic frames, PSNR, a frame-number stamp,
//! temporary folders and a minimal MP4 builder for hand-made (hostile) files.
#![allow(dead_code)]

use std::path::PathBuf;

/// A fresh empty folder under the target directory's tmp, unique per test.
pub fn temp_dir(name: &str) -> PathBuf {
    let base = option_env!("CARGO_TARGET_TMPDIR")
        .map(PathBuf::from)
        .unwrap_or_else(std::env::temp_dir);
    let dir = base.join(format!("pa-video-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("create temp dir");
    dir
}

/// Side of one bit block of the frame-number stamp.
pub const STAMP_BLOCK: u32 = 8;
/// Bits in the stamp.
pub const STAMP_BITS: u32 = 8;

/// A synthetic frame: a moving colour gradient, a grey checkerboard band, a moving red square,
/// and the frame number stamped in binary in the top-left corner (black/white 8x8 blocks).
pub fn synth_frame(w: u32, h: u32, i: u32) -> Vec<u8> {
    let mut out = vec![0u8; (w * h * 4) as usize];
    let (sq_x, sq_y) = ((10 + 4 * i) % w.max(1), (h / 3 + 2 * i) % h.max(1));
    for y in 0..h {
        for x in 0..w {
            let o = ((y * w + x) * 4) as usize;
            let mut p = [
                ((x + 3 * i) * 200 / w + 30).min(255) as u8,
                ((y + 2 * i) * 180 / h + 40).min(255) as u8,
                (((x + y + i) * 100 / (w + h)) + 90).min(255) as u8,
            ];
            // Checkerboard band (16 px cells) in the lower third.
            if y > 2 * h / 3 && ((x / 16) + (y / 16)) % 2 == 0 {
                let v = p[1] / 2 + 20;
                p = [v, v, v];
            }
            // Moving square.
            if x >= sq_x && x < sq_x + 40 && y >= sq_y && y < sq_y + 40 {
                p = [220, 40, 40];
            }
            // Frame-number stamp.
            if y < STAMP_BLOCK && x < STAMP_BLOCK * STAMP_BITS {
                let bit = (i >> (x / STAMP_BLOCK)) & 1;
                let v = if bit == 1 { 255 } else { 0 };
                p = [v, v, v];
            }
            out[o..o + 4].copy_from_slice(&[p[0], p[1], p[2], 255]);
        }
    }
    out
}

/// Reads the frame-number stamp back (mean of each block's central 4x4 pixels).
pub fn read_stamp(rgba: &[u8], w: u32) -> u32 {
    let mut n = 0;
    for b in 0..STAMP_BITS {
        let mut sum = 0u32;
        for y in 2..6 {
            for x in 2..6 {
                let o = ((y * w + b * STAMP_BLOCK + x) * 4) as usize;
                sum += u32::from(rgba[o]) + u32::from(rgba[o + 1]) + u32::from(rgba[o + 2]);
            }
        }
        if sum / 48 > 128 {
            n |= 1 << b;
        }
    }
    n
}

/// PSNR over R, G and B (alpha ignored), in dB.
pub fn psnr_rgb(a: &[u8], b: &[u8]) -> f64 {
    assert_eq!(a.len(), b.len());
    let mut se = 0u64;
    let mut n = 0u64;
    for (pa, pb) in a.chunks_exact(4).zip(b.chunks_exact(4)) {
        for c in 0..3 {
            let d = i64::from(pa[c]) - i64::from(pb[c]);
            se += (d * d) as u64;
            n += 1;
        }
    }
    if se == 0 {
        return f64::INFINITY;
    }
    let mse = se as f64 / n as f64;
    10.0 * (255.0f64 * 255.0 / mse).log10()
}

/// Appends a box.
pub fn mp4_box(kind: &[u8; 4], payload: &[u8]) -> Vec<u8> {
    let mut b = ((payload.len() + 8) as u32).to_be_bytes().to_vec();
    b.extend_from_slice(kind);
    b.extend_from_slice(payload);
    b
}

/// A full box (version 0, flags 0).
pub fn full_box(kind: &[u8; 4], payload: &[u8]) -> Vec<u8> {
    let mut p = vec![0, 0, 0, 0];
    p.extend_from_slice(payload);
    mp4_box(kind, &p)
}

fn be32(v: &[u32]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_be_bytes()).collect()
}

/// A minimal single-track MP4 built by hand: `ftyp`, `moov` (sample entry `entry` with the
/// given child boxes), `mdat` with `samples`. `ctts`, when given, is written as
/// `(count, offset)` entries.
pub fn minimal_mp4(
    entry: &[u8; 4],
    entry_children: &[u8],
    samples: &[Vec<u8>],
    ctts: Option<&[(u32, i32)]>,
) -> Vec<u8> {
    let ftyp = mp4_box(b"ftyp", b"isom\0\0\x02\0isomavc1");
    // mdat comes after ftyp and moov: compute moov first with placeholder offsets, then fix.
    let build_moov = |mdat_data_start: u32| -> Vec<u8> {
        let mut offsets = Vec::new();
        let mut off = mdat_data_start;
        for s in samples {
            offsets.push(off);
            off += s.len() as u32;
        }
        let mut visual = vec![0u8; 6];
        visual.extend_from_slice(&1u16.to_be_bytes());
        visual.extend_from_slice(&[0u8; 16]);
        visual.extend_from_slice(&64u16.to_be_bytes());
        visual.extend_from_slice(&48u16.to_be_bytes());
        visual.extend_from_slice(&be32(&[0x0048_0000, 0x0048_0000, 0]));
        visual.extend_from_slice(&1u16.to_be_bytes());
        visual.extend_from_slice(&[0u8; 32]);
        visual.extend_from_slice(&0x18u16.to_be_bytes());
        visual.extend_from_slice(&0xffffu16.to_be_bytes());
        visual.extend_from_slice(entry_children);
        let mut stsd = be32(&[1]);
        stsd.extend_from_slice(&mp4_box(entry, &visual));
        let n = samples.len() as u32;
        let mut stbl = full_box(b"stsd", &stsd);
        stbl.extend(full_box(b"stts", &be32(&[1, n, 1000])));
        if let Some(ctts) = ctts {
            let mut p = be32(&[ctts.len() as u32]);
            for &(c, o) in ctts {
                p.extend(be32(&[c, o as u32]));
            }
            stbl.extend(full_box(b"ctts", &p));
        }
        stbl.extend(full_box(b"stsc", &be32(&[1, 1, 1, 1])));
        let mut stsz = be32(&[0, n]);
        stsz.extend(be32(
            &samples.iter().map(|s| s.len() as u32).collect::<Vec<_>>(),
        ));
        stbl.extend(full_box(b"stsz", &stsz));
        let mut stco = be32(&[n]);
        stco.extend(be32(&offsets));
        stbl.extend(full_box(b"stco", &stco));
        let minf = mp4_box(b"minf", &mp4_box(b"stbl", &stbl));
        let mut hdlr = be32(&[0]);
        hdlr.extend_from_slice(b"vide");
        hdlr.extend_from_slice(&[0u8; 13]);
        let mut mdhd = be32(&[0, 0, 24000, n * 1000]);
        mdhd.extend_from_slice(&[0x55, 0xc4, 0, 0]);
        let mut mdia = full_box(b"mdhd", &mdhd);
        mdia.extend(full_box(b"hdlr", &hdlr));
        mdia.extend(minf);
        let trak = mp4_box(b"trak", &mp4_box(b"mdia", &mdia));
        mp4_box(b"moov", &trak)
    };
    let moov_len = build_moov(0).len() as u32;
    let data_start = ftyp.len() as u32 + moov_len + 8;
    let moov = build_moov(data_start);
    let mut mdat_payload = Vec::new();
    for s in samples {
        mdat_payload.extend_from_slice(s);
    }
    let mut file = ftyp;
    file.extend(moov);
    file.extend(mp4_box(b"mdat", &mdat_payload));
    file
}

/// MSB-first bit writer with Exp-Golomb codes, for hand-made parameter sets.
#[derive(Default)]
pub struct BitWriter {
    bits: Vec<bool>,
}

impl BitWriter {
    pub fn u(&mut self, n: u32, v: u32) {
        for i in (0..n).rev() {
            self.bits.push((v >> i) & 1 == 1);
        }
    }
    pub fn ue(&mut self, v: u32) {
        let x = u64::from(v) + 1;
        let len = 64 - x.leading_zeros();
        for _ in 0..len - 1 {
            self.bits.push(false);
        }
        for i in (0..len).rev() {
            self.bits.push((x >> i) & 1 == 1);
        }
    }
    /// RBSP trailing bits, emulation prevention, and the bytes.
    pub fn finish_nal(mut self, header: u8) -> Vec<u8> {
        self.bits.push(true);
        while !self.bits.len().is_multiple_of(8) {
            self.bits.push(false);
        }
        let raw: Vec<u8> = self
            .bits
            .chunks(8)
            .map(|c| c.iter().fold(0u8, |a, &b| (a << 1) | u8::from(b)))
            .collect();
        let mut out = vec![header];
        let mut zeros = 0;
        for b in raw {
            if zeros >= 2 && b <= 3 {
                out.push(3);
                zeros = 0;
            }
            zeros = if b == 0 { zeros + 1 } else { 0 };
            out.push(b);
        }
        out
    }
}

/// A Constrained Baseline SPS for a `w_mbs x h_mbs` macroblock picture.
pub fn baseline_sps(w_mbs: u32, h_mbs: u32) -> Vec<u8> {
    let mut w = BitWriter::default();
    w.u(8, 66);
    w.u(8, 0xc0);
    w.u(8, 52);
    w.ue(0); // sps id
    w.ue(0); // log2_max_frame_num - 4
    w.ue(2); // poc type 2
    w.ue(1); // max_num_ref_frames
    w.u(1, 0);
    w.ue(w_mbs - 1);
    w.ue(h_mbs - 1);
    w.u(1, 1); // frame_mbs_only
    w.u(1, 1); // direct_8x8
    w.u(1, 0); // cropping
    w.u(1, 0); // vui
    w.finish_nal(0x67)
}

/// An `avcC` box (with header) for one SPS and a dummy PPS.
pub fn avcc_box(sps: &[u8]) -> Vec<u8> {
    let pps = [0x68u8, 0xce, 0x38, 0x80];
    let mut p = vec![1, sps[1], sps[2], sps[3], 0xff, 0xe1];
    p.extend_from_slice(&(sps.len() as u16).to_be_bytes());
    p.extend_from_slice(sps);
    p.push(1);
    p.extend_from_slice(&(pps.len() as u16).to_be_bytes());
    p.extend_from_slice(&pps);
    mp4_box(b"avcC", &p)
}
