//! Writer -> reader round trips on synthetic frames, the written MP4's box structure, and the
//! writer's file handling (atomic rename, no overwriting, no half files).
//!
//! Measured on the development machine (OpenH264 2.7; identical output with or without nasm),
//! default [`RateControl`] (`Quality { qp_min: 16, qp_max: 24 }`), 30 frames:
//! * 320x240 at 24 fps: worst frame 36.41 dB, mean 36.71 dB PSNR (RGB) against the original;
//!   45.26 dB against the original passed through the 4:2:0 conversion alone (the codec's own
//!   loss); 49.9 KB.
//! * 321x241 (odd: padded to 322x242 for coding, cropped back by `clap`) at 30000/1001 fps:
//!   worst 35.93 dB, mean 36.20 dB; 45.48 dB codec-only; 56.2 KB.
//! * `Bitrate { bps: 2_000_000 }` at 320x240: worst 36.38 dB; 44.37 dB codec-only.
//!
//! The end-to-end figure is bounded by 4:2:0 chroma on the pattern's coloured edges (the
//! conversion alone gives 36.8 dB); floors: 35 dB end to end, 42 dB codec-only.

mod common;

use std::path::Path;

use common::{psnr_rgb, read_stamp, synth_frame, temp_dir};
use pa_video::{Backend, Fps, Mp4Writer, Mp4WriterOptions, RateControl, VideoError, VideoReader};

const FRAMES: u32 = 30;

struct RoundTrip {
    /// Decoded against the original RGBA: what the user sees.
    worst_psnr: f64,
    mean_psnr: f64,
    /// Decoded against the original passed through the 4:2:0 conversion alone: the codec's
    /// own loss.
    worst_codec_psnr: f64,
    bytes: u64,
}

/// The original through RGBA -> BT.709 4:2:0 -> RGBA, without the codec.
fn via_420(rgba: &[u8], w: u32, h: u32) -> Vec<u8> {
    use pa_video::color::{i420_to_rgba, rgba_to_i420, I420Planes, YuvColor, I420};
    let mut yuv = I420::default();
    rgba_to_i420(
        rgba,
        w as usize,
        h as usize,
        YuvColor::BT709_LIMITED,
        &mut yuv,
    );
    let planes = I420Planes {
        y: &yuv.y,
        u: &yuv.u,
        v: &yuv.v,
        y_stride: yuv.width,
        uv_stride: yuv.width / 2,
        width: yuv.width,
        height: yuv.height,
    };
    let mut out = Vec::new();
    assert!(i420_to_rgba(
        &planes,
        (0, 0, w as usize, h as usize),
        YuvColor::BT709_LIMITED,
        &mut out
    ));
    out
}

fn round_trip(dir: &Path, w: u32, h: u32, fps: Fps, rate: RateControl) -> RoundTrip {
    let label = match rate {
        RateControl::Bitrate { bps } => format!("{bps}bps"),
        RateControl::Quality { qp_min, qp_max } => format!("qp{qp_min}-{qp_max}"),
    };
    let path = dir.join(format!("rt_{w}x{h}_{label}.mp4"));
    let mut opts = Mp4WriterOptions::new(fps);
    opts.rate_control = rate;
    opts.keyframe_interval = Some(12);
    let mut writer = Mp4Writer::create(&path, w, h, opts).expect("create writer");
    let originals: Vec<Vec<u8>> = (0..FRAMES).map(|i| synth_frame(w, h, i)).collect();
    for f in &originals {
        writer.write_frame(f).expect("write frame");
    }
    let summary = writer.finish().expect("finish");
    assert_eq!(summary.frames, u64::from(FRAMES));
    assert_eq!(summary.bytes, std::fs::metadata(&path).expect("stat").len());
    let expected_duration = f64::from(FRAMES) / fps.as_f64();
    assert!((summary.duration_s - expected_duration).abs() < 1e-9);

    let mut reader = VideoReader::open(&path).expect("open");
    let info = reader.info().clone();
    assert_eq!((info.width, info.height), (w, h));
    assert_eq!(info.frame_count, Some(u64::from(FRAMES)));
    assert_eq!(info.fps, Some(fps));
    assert_eq!(info.backend, Backend::OpenH264);
    assert!(info.codec.starts_with("H.264"), "{}", info.codec);

    let mut psnrs = Vec::new();
    let mut codec_psnrs = Vec::new();
    let mut count = 0u32;
    while let Some(frame) = reader.next_frame().expect("decode") {
        let i = count;
        count += 1;
        assert_eq!(frame.index, u64::from(i));
        assert_eq!((frame.width, frame.height), (w, h));
        assert_eq!(frame.rgba.len(), (w * h * 4) as usize);
        // pts = i / fps exactly: ticks * num == i * den * timescale.
        assert_eq!(
            i128::from(frame.pts.ticks) * i128::from(fps.num()),
            i128::from(i) * i128::from(fps.den()) * i128::from(frame.pts.timescale),
            "frame {i} pts {:?}",
            frame.pts
        );
        assert_eq!(
            read_stamp(&frame.rgba, w),
            i,
            "frame order (stamp) at frame {i}"
        );
        psnrs.push(psnr_rgb(&frame.rgba, &originals[i as usize]));
        codec_psnrs.push(psnr_rgb(
            &frame.rgba,
            &via_420(&originals[i as usize], w, h),
        ));
    }
    assert_eq!(count, FRAMES);
    let worst = psnrs.iter().copied().fold(f64::INFINITY, f64::min);
    let mean = psnrs.iter().sum::<f64>() / psnrs.len() as f64;
    let worst_codec_psnr = codec_psnrs.iter().copied().fold(f64::INFINITY, f64::min);
    RoundTrip {
        worst_psnr: worst,
        mean_psnr: mean,
        worst_codec_psnr,
        bytes: summary.bytes,
    }
}

#[test]
fn round_trip_even_size_24fps() {
    let dir = temp_dir("rt-even");
    let fps = Fps::new(24, 1).expect("fps");
    let r = round_trip(&dir, 320, 240, fps, RateControl::default());
    println!(
        "320x240 default quality: worst {:.2} dB, mean {:.2} dB, codec-only worst {:.2} dB, {} bytes",
        r.worst_psnr, r.mean_psnr, r.worst_codec_psnr, r.bytes
    );
    assert!(r.worst_psnr > 35.0, "worst PSNR {:.2} dB", r.worst_psnr);
    assert!(
        r.worst_codec_psnr > 42.0,
        "worst codec-only PSNR {:.2} dB",
        r.worst_codec_psnr
    );
    let r = round_trip(&dir, 320, 240, fps, RateControl::Bitrate { bps: 2_000_000 });
    println!(
        "320x240 2 Mbit/s: worst {:.2} dB, mean {:.2} dB, codec-only worst {:.2} dB, {} bytes",
        r.worst_psnr, r.mean_psnr, r.worst_codec_psnr, r.bytes
    );
    assert!(r.worst_psnr > 35.0, "worst PSNR {:.2} dB", r.worst_psnr);
    assert!(
        r.worst_codec_psnr > 42.0,
        "worst codec-only PSNR {:.2} dB",
        r.worst_codec_psnr
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn round_trip_odd_size_ntsc_rate() {
    let dir = temp_dir("rt-odd");
    let fps = Fps::new(30000, 1001).expect("fps");
    let r = round_trip(&dir, 321, 241, fps, RateControl::default());
    println!(
        "321x241 default quality: worst {:.2} dB, mean {:.2} dB, codec-only worst {:.2} dB, {} bytes",
        r.worst_psnr, r.mean_psnr, r.worst_codec_psnr, r.bytes
    );
    assert!(r.worst_psnr > 35.0, "worst PSNR {:.2} dB", r.worst_psnr);
    assert!(
        r.worst_codec_psnr > 42.0,
        "worst codec-only PSNR {:.2} dB",
        r.worst_codec_psnr
    );
    let _ = std::fs::remove_dir_all(&dir);
}

// --- Box structure -------------------------------------------------------------------------

struct Boxes {
    /// (path like "moov/trak/mdia", payload start, payload len)
    list: Vec<(String, usize, usize)>,
}

impl Boxes {
    fn find(&self, path: &str) -> Vec<(usize, usize)> {
        self.list
            .iter()
            .filter(|(p, _, _)| p == path)
            .map(|&(_, s, l)| (s, l))
            .collect()
    }
    fn one<'a>(&self, data: &'a [u8], path: &str) -> &'a [u8] {
        let found = self.find(path);
        assert_eq!(
            found.len(),
            1,
            "expected exactly one {path}, boxes: {:?}",
            self.names()
        );
        let (s, l) = found[0];
        &data[s..s + l]
    }
    fn names(&self) -> Vec<&str> {
        self.list.iter().map(|(p, _, _)| p.as_str()).collect()
    }
}

fn be32(b: &[u8], at: usize) -> u32 {
    u32::from_be_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]])
}

/// Walks the box tree, descending into containers and the `avc1` sample entry.
fn walk(
    data: &[u8],
    start: usize,
    end: usize,
    prefix: &str,
    out: &mut Vec<(String, usize, usize)>,
) {
    let mut pos = start;
    while pos < end {
        assert!(end - pos >= 8, "stray bytes at {pos} in {prefix}");
        let mut size = u64::from(be32(data, pos));
        let kind = String::from_utf8_lossy(&data[pos + 4..pos + 8]).to_string();
        let mut header = 8;
        if size == 1 {
            size = u64::from_be_bytes(data[pos + 8..pos + 16].try_into().expect("8 bytes"));
            header = 16;
        }
        let size = size as usize;
        assert!(
            size >= header && pos + size <= end,
            "box {kind} at {pos} overruns its parent"
        );
        let path = if prefix.is_empty() {
            kind.clone()
        } else {
            format!("{prefix}/{kind}")
        };
        let (ps, pe) = (pos + header, pos + size);
        out.push((path.clone(), ps, pe - ps));
        match kind.as_str() {
            "moov" | "trak" | "mdia" | "minf" | "stbl" | "dinf" | "edts" => {
                walk(data, ps, pe, &path, out)
            }
            "stsd" => walk(data, ps + 8, pe, &path, out),
            "avc1" => walk(data, ps + 78, pe, &path, out),
            _ => {}
        }
        pos += size;
    }
}

#[test]
fn written_mp4_has_a_valid_box_structure() {
    let dir = temp_dir("boxes");
    let path = dir.join("boxes.mp4");
    let fps = Fps::new(25, 1).expect("fps");
    let mut opts = Mp4WriterOptions::new(fps);
    opts.keyframe_interval = Some(10);
    let (w, h) = (161, 97);
    let mut writer = Mp4Writer::create(&path, w, h, opts).expect("create");
    let n = 24u32;
    for i in 0..n {
        writer.write_frame(&synth_frame(w, h, i)).expect("frame");
    }
    writer.finish().expect("finish");
    let data = std::fs::read(&path).expect("read");
    let mut list = Vec::new();
    walk(&data, 0, data.len(), "", &mut list);
    let boxes = Boxes { list };
    let top: Vec<&str> = boxes
        .names()
        .into_iter()
        .filter(|p| !p.contains('/'))
        .collect();
    assert_eq!(top, vec!["ftyp", "mdat", "moov"]);
    for required in [
        "moov/mvhd",
        "moov/trak/tkhd",
        "moov/trak/mdia/mdhd",
        "moov/trak/mdia/hdlr",
        "moov/trak/mdia/minf/vmhd",
        "moov/trak/mdia/minf/dinf/dref",
        "moov/trak/mdia/minf/stbl/stsd/avc1/avcC",
        "moov/trak/mdia/minf/stbl/stsd/avc1/clap",
        "moov/trak/mdia/minf/stbl/stts",
        "moov/trak/mdia/minf/stbl/stsc",
        "moov/trak/mdia/minf/stbl/stsz",
        "moov/trak/mdia/minf/stbl/stco",
        "moov/trak/mdia/minf/stbl/stss",
    ] {
        assert_eq!(
            boxes.find(required).len(),
            1,
            "missing {required}; have {:?}",
            boxes.names()
        );
    }
    let ftyp = boxes.one(&data, "ftyp");
    assert_eq!(&ftyp[0..4], b"isom");
    // avcC: version 1, 4-byte lengths, one SPS (NAL type 7) and one PPS (type 8).
    let avcc = boxes.one(&data, "moov/trak/mdia/minf/stbl/stsd/avc1/avcC");
    assert_eq!(avcc[0], 1);
    assert_eq!(avcc[4] & 3, 3);
    assert_eq!(avcc[5] & 0x1f, 1);
    let sps_len = usize::from(u16::from_be_bytes([avcc[6], avcc[7]]));
    assert_eq!(avcc[8] & 0x1f, 7);
    assert_eq!(
        &avcc[1..4],
        &avcc[9..12],
        "profile/level copied from the SPS"
    );
    let pps_at = 8 + sps_len;
    assert_eq!(avcc[pps_at], 1);
    assert_eq!(avcc[pps_at + 3] & 0x1f, 8);
    let sps = pa_video::h264::parse_sps(&avcc[8..8 + sps_len]).expect("SPS parses");
    assert_eq!(
        (sps.width, sps.height),
        (162, 98),
        "coded size is padded to even"
    );
    let vui = sps.vui.expect("VUI present");
    assert_eq!(
        (vui.matrix, vui.full_range),
        (Some(1), false),
        "BT.709 limited signalled"
    );
    // Sample entry: coded size; tkhd: display size.
    let stsd = boxes.one(&data, "moov/trak/mdia/minf/stbl/stsd");
    assert_eq!(be32(stsd, 4), 1);
    assert_eq!(&stsd[12..16], b"avc1");
    let tkhd = boxes.one(&data, "moov/trak/tkhd");
    assert_eq!(
        (
            be32(tkhd, tkhd.len() - 8) >> 16,
            be32(tkhd, tkhd.len() - 4) >> 16
        ),
        (w, h)
    );
    // mdhd timescale and stts: n samples of 1000 ticks at 25000 ticks/s.
    let mdhd = boxes.one(&data, "moov/trak/mdia/mdhd");
    assert_eq!(be32(mdhd, 12), 25000);
    assert_eq!(be32(mdhd, 16), n * 1000);
    let stts = boxes.one(&data, "moov/trak/mdia/minf/stbl/stts");
    assert_eq!((be32(stts, 4), be32(stts, 8), be32(stts, 12)), (1, n, 1000));
    // stss: keyframes at 1, 11, 21 (1-based) with an interval of 10.
    let stss = boxes.one(&data, "moov/trak/mdia/minf/stbl/stss");
    let sync: Vec<u32> = (0..be32(stss, 4) as usize)
        .map(|k| be32(stss, 8 + 4 * k))
        .collect();
    assert_eq!(sync, vec![1, 11, 21]);
    // stsz / stco: n samples, each inside mdat, contiguous, length-prefixed NAL units.
    let stsz = boxes.one(&data, "moov/trak/mdia/minf/stbl/stsz");
    assert_eq!((be32(stsz, 4), be32(stsz, 8)), (0, n));
    let stco = boxes.one(&data, "moov/trak/mdia/minf/stbl/stco");
    assert_eq!(be32(stco, 4), n);
    let (mdat_start, mdat_len) = boxes.find("mdat")[0];
    let mut expect_offset = mdat_start;
    for k in 0..n as usize {
        let size = be32(stsz, 12 + 4 * k) as usize;
        let offset = be32(stco, 8 + 4 * k) as usize;
        assert_eq!(offset, expect_offset, "sample {k} offset");
        expect_offset += size;
        let nal_len = be32(&data, offset) as usize;
        assert!(nal_len + 4 <= size, "sample {k}: first NAL fits");
        let nal_type = data[offset + 4] & 0x1f;
        let is_sync = sync.contains(&(k as u32 + 1));
        assert_eq!(
            nal_type == 5,
            is_sync,
            "sample {k}: IDR exactly at sync samples"
        );
    }
    assert_eq!(
        expect_offset,
        mdat_start + mdat_len,
        "samples fill mdat exactly"
    );
    let stsc = boxes.one(&data, "moov/trak/mdia/minf/stbl/stsc");
    assert_eq!(be32(stsc, 4), 1);

    // Independent check with ffprobe when it is installed.
    match std::process::Command::new("ffprobe")
        .args(["-v", "error", "-count_frames", "-select_streams", "v:0"])
        .args([
            "-show_entries",
            "stream=codec_name,width,height,nb_read_frames,r_frame_rate",
        ])
        .args(["-of", "default=noprint_wrappers=1"])
        .arg(&path)
        .output()
    {
        Ok(out) if out.status.success() => {
            let text = String::from_utf8_lossy(&out.stdout);
            println!("ffprobe: {}", text.replace('\n', " "));
            assert!(text.contains("codec_name=h264"), "{text}");
            assert!(text.contains(&format!("nb_read_frames={n}")), "{text}");
            assert!(text.contains("r_frame_rate=25/1"), "{text}");
            assert!(
                String::from_utf8_lossy(&out.stderr).trim().is_empty(),
                "ffprobe complained: {}",
                String::from_utf8_lossy(&out.stderr)
            );
        }
        Ok(out) => panic!(
            "ffprobe rejected the file: {}",
            String::from_utf8_lossy(&out.stderr)
        ),
        Err(_) => println!("skipped the ffprobe cross-check: ffprobe is not installed"),
    }
    let _ = std::fs::remove_dir_all(&dir);
}

// --- File handling -------------------------------------------------------------------------

fn small_options() -> Mp4WriterOptions {
    Mp4WriterOptions::new(Fps::new(12, 1).expect("fps"))
}

fn entries(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .expect("read dir")
        .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

#[test]
fn writer_refuses_to_overwrite_and_never_leaves_half_files() {
    let dir = temp_dir("files");
    let path = dir.join("take.mp4");
    std::fs::write(&path, b"precious").expect("write");
    let err = Mp4Writer::create(&path, 64, 48, small_options()).expect_err("must refuse");
    assert!(matches!(err, VideoError::AlreadyExists { .. }), "{err}");
    assert!(err.to_string().contains("take.mp4"), "{err}");
    assert_eq!(std::fs::read(&path).expect("read"), b"precious");

    // With overwrite, the old file is replaced only at finish().
    let mut opts = small_options();
    opts.overwrite = true;
    let mut w = Mp4Writer::create(&path, 64, 48, opts).expect("create");
    w.write_frame(&synth_frame(64, 48, 0)).expect("frame");
    assert_eq!(
        std::fs::read(&path).expect("read"),
        b"precious",
        "untouched until finish"
    );
    w.finish().expect("finish");
    assert_eq!(VideoReader::open(&path).expect("open").count(), 1);

    // Dropped without finish(): no file under the final name, no temporary left.
    let fresh = dir.join("dropped.mp4");
    {
        let mut w = Mp4Writer::create(&fresh, 64, 48, small_options()).expect("create");
        for i in 0..3 {
            w.write_frame(&synth_frame(64, 48, i)).expect("frame");
        }
        assert_eq!(
            entries(&dir).len(),
            2,
            "the temporary file exists while writing"
        );
    }
    assert!(!fresh.exists());
    assert_eq!(entries(&dir), vec!["take.mp4".to_string()]);

    // A file that appears under the final name while writing is not replaced; the take is
    // kept under the temporary name and the error says where.
    let racy = dir.join("racy.mp4");
    let mut w = Mp4Writer::create(&racy, 64, 48, small_options()).expect("create");
    w.write_frame(&synth_frame(64, 48, 0)).expect("frame");
    std::fs::write(&racy, b"someone else's").expect("write");
    let err = w.finish().expect_err("must refuse");
    let msg = err.to_string();
    assert!(
        matches!(err, VideoError::AlreadyExists { .. }) && msg.contains("kept as"),
        "{msg}"
    );
    assert_eq!(std::fs::read(&racy).expect("read"), b"someone else's");
    let kept: Vec<String> = entries(&dir)
        .into_iter()
        .filter(|n| n.ends_with(".partial"))
        .collect();
    assert_eq!(kept.len(), 1, "{:?}", entries(&dir));
    assert_eq!(
        VideoReader::open(dir.join(&kept[0]))
            .expect("kept file reads")
            .count(),
        1
    );

    // Wrong frame size and empty videos are typed errors; the empty one leaves no file.
    let mut w = Mp4Writer::create(dir.join("size.mp4"), 64, 48, small_options()).expect("create");
    let err = w.write_frame(&[0u8; 10]).expect_err("wrong size");
    assert!(
        matches!(
            err,
            VideoError::FrameSize {
                expected: 12288,
                actual: 10,
                ..
            }
        ),
        "{err}"
    );
    let err = w.finish().expect_err("empty");
    assert!(err.to_string().contains("no frames"), "{err}");
    assert!(!dir.join("size.mp4").exists());
    assert!(Mp4Writer::create(dir.join("big.mp4"), 4000, 3000, small_options()).is_err());
    assert!(Mp4Writer::create(dir.join("zero.mp4"), 0, 10, small_options()).is_err());
    let _ = std::fs::remove_dir_all(&dir);
}
