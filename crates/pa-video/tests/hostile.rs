//! Bad input: truncated, garbage and hand-made hostile files, codecs the default build cannot
//! decode, and cameras that are not there. Everything must be a typed error that names the
//! file; nothing may panic or allocate absurdly.

mod common;

use std::path::{Path, PathBuf};

use common::{avcc_box, baseline_sps, minimal_mp4, synth_frame, temp_dir};
use pa_video::{Backend, Camera, Fps, Mp4Writer, Mp4WriterOptions, VideoError, VideoReader};

/// A small valid MP4 written by our writer.
fn valid_mp4(dir: &Path, name: &str, frames: u32) -> (PathBuf, Vec<u8>) {
    let path = dir.join(name);
    let mut w = Mp4Writer::create(
        &path,
        64,
        48,
        Mp4WriterOptions::new(Fps::new(24, 1).expect("fps")),
    )
    .expect("create");
    for i in 0..frames {
        w.write_frame(&synth_frame(64, 48, i)).expect("frame");
    }
    w.finish().expect("finish");
    let bytes = std::fs::read(&path).expect("read");
    (path, bytes)
}

/// Opens and decodes everything, returning the first error (frames are counted).
fn read_all(path: &Path) -> Result<usize, VideoError> {
    let mut reader = VideoReader::open(path)?;
    let mut n = 0;
    while reader.next_frame()?.is_some() {
        n += 1;
    }
    Ok(n)
}

fn find(data: &[u8], tag: &[u8; 4]) -> usize {
    data.windows(4).position(|w| w == tag).expect("tag present") - 4
}

#[test]
fn truncated_files_are_typed_errors() {
    let dir = temp_dir("truncated");
    let (_, bytes) = valid_mp4(&dir, "whole.mp4", 6);
    let moov = find(&bytes, b"moov");
    for cut in [
        1,
        7,
        20,
        40,
        bytes.len() / 2,
        moov + 4,
        moov + 100,
        bytes.len() - 1,
    ] {
        let path = dir.join(format!("cut{cut}.mp4"));
        std::fs::write(&path, &bytes[..cut]).expect("write");
        let err = read_all(&path).expect_err("truncated file must fail");
        let msg = err.to_string();
        assert!(
            msg.contains(&format!("cut{cut}.mp4")),
            "error names the file: {msg}"
        );
        assert!(
            matches!(
                err,
                VideoError::Corrupt { .. } | VideoError::UnsupportedContainer { .. }
            ),
            "cut at {cut}: {err:?}"
        );
    }
    // The mdat box claiming more than the file: "claims ... bytes".
    let path = dir.join("cut_mdat.mp4");
    std::fs::write(&path, &bytes[..moov - 8]).expect("write");
    let msg = read_all(&path).expect_err("fails").to_string();
    assert!(msg.contains("claims") || msg.contains("no 'moov'"), "{msg}");
    let path = dir.join("empty.mp4");
    std::fs::write(&path, b"").expect("write");
    assert!(matches!(read_all(&path), Err(VideoError::Corrupt { .. })));
    let missing = dir.join("missing.mp4");
    let err = read_all(&missing).expect_err("missing");
    assert!(
        matches!(err, VideoError::Io { .. }) && err.to_string().contains("missing.mp4"),
        "{err}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn garbage_and_mutated_files_never_panic() {
    let dir = temp_dir("garbage");
    // Pseudo-random garbage, with and without a plausible MP4 header.
    let mut state = 0x2545_f491_4f6c_dd1du64;
    let mut rand = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        state
    };
    let garbage: Vec<u8> = (0..20_000).map(|_| rand() as u8).collect();
    let path = dir.join("garbage.bin");
    std::fs::write(&path, &garbage).expect("write");
    let err = read_all(&path).expect_err("garbage");
    assert!(
        matches!(err, VideoError::UnsupportedContainer { .. }),
        "{err:?}"
    );
    let mut fake = b"\0\0\0\x14ftypisom\0\0\0\0isom".to_vec();
    fake.extend_from_slice(&garbage);
    std::fs::write(&path, &fake).expect("write");
    assert!(matches!(read_all(&path), Err(VideoError::Corrupt { .. })));

    // Byte mutations of a valid file's index (moov): every outcome is Ok or a typed error.
    let (_, bytes) = valid_mp4(&dir, "base.mp4", 4);
    let moov = find(&bytes, b"moov");
    let (mut ok, mut errors) = (0, 0);
    for k in 0..300 {
        let mut m = bytes.clone();
        for _ in 0..1 + k % 4 {
            let at = moov + (rand() as usize) % (bytes.len() - moov);
            m[at] = match rand() % 4 {
                0 => 0xff,
                1 => 0,
                _ => rand() as u8,
            };
        }
        let path = dir.join("mutated.mp4");
        std::fs::write(&path, &m).expect("write");
        match read_all(&path) {
            Ok(_) => ok += 1,
            Err(e) => {
                assert!(e.to_string().contains("mutated.mp4"), "{e}");
                errors += 1;
            }
        }
    }
    println!("300 mutated files: {ok} read, {errors} typed errors");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn hostile_sizes_and_tables_are_refused() {
    let dir = temp_dir("hostile");
    let (_, bytes) = valid_mp4(&dir, "base.mp4", 3);
    let write = |name: &str, data: &[u8]| {
        let p = dir.join(name);
        std::fs::write(&p, data).expect("write");
        p
    };
    let expect_corrupt = |path: &Path, needle: &str| {
        let err = read_all(path).expect_err("must fail");
        let msg = err.to_string();
        assert!(matches!(err, VideoError::Corrupt { .. }), "{msg}");
        assert!(msg.contains(needle), "expected '{needle}' in: {msg}");
    };

    // A top-level box larger than the file (mdat uses a 64-bit size).
    let mut m = bytes.clone();
    let mdat = find(&m, b"mdat");
    m[mdat + 8..mdat + 16].copy_from_slice(&u64::MAX.to_be_bytes());
    expect_corrupt(&write("big_box.mp4", &m), "claims");
    // A moov child claiming more than its parent.
    let mut m = bytes.clone();
    let trak = find(&m, b"trak");
    m[trak..trak + 4].copy_from_slice(&0x7fff_fff0u32.to_be_bytes());
    expect_corrupt(&write("big_child.mp4", &m), "claims");
    // A sample-size table claiming 4 billion entries: refused without allocating them.
    let mut m = bytes.clone();
    let stsz = find(&m, b"stsz");
    m[stsz + 16..stsz + 20].copy_from_slice(&0xffff_fff0u32.to_be_bytes());
    expect_corrupt(&write("huge_count.mp4", &m), "exceed");
    // Constant sample size times a large count beyond the file.
    let mut m = bytes.clone();
    m[stsz + 12..stsz + 16].copy_from_slice(&1_000_000u32.to_be_bytes());
    m[stsz + 16..stsz + 20].copy_from_slice(&1000u32.to_be_bytes());
    expect_corrupt(&write("constant_size.mp4", &m), "do not fit");
    // A chunk offset past the end of the file.
    let mut m = bytes.clone();
    let stco = find(&m, b"stco");
    m[stco + 16..stco + 20].copy_from_slice(&0x7fff_0000u32.to_be_bytes());
    expect_corrupt(&write("past_end.mp4", &m), "past the end");
    // A zero-size frame.
    let mut m = bytes.clone();
    m[stsz + 20..stsz + 24].copy_from_slice(&0u32.to_be_bytes());
    expect_corrupt(&write("zero_size.mp4", &m), "zero size");
    // Huge dimensions: an SPS for 8192x8192 (262,144 macroblocks).
    let avcc = avcc_box(&baseline_sps(512, 512));
    let file = minimal_mp4(b"avc1", &avcc, &[vec![0, 0, 0, 2, 0x65, 0x88]], None);
    let err = read_all(&write("huge_dims.mp4", &file)).expect_err("too large");
    assert!(
        matches!(
            err,
            VideoError::TooLarge {
                width: 8192,
                height: 8192,
                ..
            }
        ),
        "{err:?}"
    );
    // A NAL length running past its sample.
    let avcc = avcc_box(&baseline_sps(4, 3));
    let file = minimal_mp4(b"avc1", &avcc, &[vec![0, 0, 1, 0, 0x65, 0x88]], None);
    let err = read_all(&write("nal_overrun.mp4", &file)).expect_err("overrun");
    assert!(err.to_string().contains("overruns"), "{err}");
    let _ = std::fs::remove_dir_all(&dir);
}

fn assert_needs_ffmpeg(err: &VideoError, file: &str, codec: &str) {
    let msg = err.to_string();
    assert!(
        matches!(
            err,
            VideoError::NeedsFeature {
                feature: "ffmpeg",
                ..
            }
        ),
        "{err:?}"
    );
    assert!(msg.contains("--features ffmpeg"), "{msg}");
    assert!(msg.contains(file), "{msg}");
    assert!(msg.contains(codec), "{msg}");
    assert_eq!(err.needs_feature(), Some("ffmpeg"));
}

#[test]
fn undecodable_streams_name_the_feature() {
    let dir = temp_dir("needs");
    let write = |name: &str, data: &[u8]| {
        let p = dir.join(name);
        std::fs::write(&p, data).expect("write");
        p
    };
    let sample = vec![0, 0, 0, 2, 0x26, 0x01];
    // HEVC: a hand-built MP4 whose sample entry is hvc1 (and hev1).
    for fourcc in [b"hvc1", b"hev1"] {
        let hvcc = common::mp4_box(b"hvcC", &[1; 23]);
        let file = minimal_mp4(fourcc, &hvcc, &[sample.clone(), sample.clone()], None);
        let name = format!("phone_{}.mp4", String::from_utf8_lossy(fourcc));
        let path = write(&name, &file);
        let err = VideoReader::open_with(&path, Some(Backend::OpenH264)).expect_err("HEVC");
        assert_needs_ffmpeg(&err, &name, "HEVC");
        if !cfg!(feature = "ffmpeg") {
            assert_needs_ffmpeg(&VideoReader::open(&path).expect_err("HEVC"), &name, "HEVC");
        }
    }
    // H.264 with B-frames: composition offsets (ctts) that reorder I P B B.
    let avcc = avcc_box(&baseline_sps(4, 3));
    let samples = vec![sample.clone(); 4];
    let ctts = [(1, 1000), (1, 3000), (1, 0), (1, 0)];
    let file = minimal_mp4(b"avc1", &avcc, &samples, Some(&ctts));
    let path = write("bframes.mp4", &file);
    let err = VideoReader::open_with(&path, Some(Backend::OpenH264)).expect_err("B-frames");
    assert_needs_ffmpeg(&err, "bframes.mp4", "H.264");
    assert!(err.to_string().contains("B-frames"), "{err}");
    // An SPS announcing reordering (VUI bitstream restriction) is caught from the SPS alone.
    let reorder_sps = [
        0x67, 0x64, 0x00, 0x1f, 0xac, 0xd9, 0x40, 0x50, 0x05, 0xbb, 0x01, 0x10, 0x00, 0x00, 0x03,
        0x00, 0x10, 0x00, 0x00, 0x03, 0x03, 0x00, 0xf1, 0x83, 0x19, 0x60,
    ];
    let file = minimal_mp4(b"avc1", &avcc_box(&reorder_sps), &samples, None);
    let err = VideoReader::open_with(write("x264_high.mp4", &file), Some(Backend::OpenH264))
        .expect_err("B");
    assert_needs_ffmpeg(&err, "x264_high.mp4", "High profile");
    // Other codecs.
    let file = minimal_mp4(b"av01", &[], std::slice::from_ref(&sample), None);
    let err = VideoReader::open_with(write("clip_av1.mp4", &file), Some(Backend::OpenH264))
        .expect_err("AV1");
    assert_needs_ffmpeg(&err, "clip_av1.mp4", "AV1");
    // Other containers: named, and the feature is suggested (default build).
    if !cfg!(feature = "ffmpeg") {
        let mut mkv = vec![0x1a, 0x45, 0xdf, 0xa3];
        mkv.extend_from_slice(&[0x42; 64]);
        let err = read_all(&write("clip.mkv", &mkv)).expect_err("mkv");
        let msg = err.to_string();
        assert!(
            matches!(err, VideoError::UnsupportedContainer { .. }),
            "{msg}"
        );
        assert!(
            msg.contains("Matroska")
                && msg.contains("--features ffmpeg")
                && msg.contains("clip.mkv"),
            "{msg}"
        );
        let avi = b"RIFF\x10\0\0\0AVI LIST\0\0\0\0".to_vec();
        let msg = read_all(&write("clip.avi", &avi))
            .expect_err("avi")
            .to_string();
        assert!(
            msg.contains("AVI") && msg.contains("--features ffmpeg"),
            "{msg}"
        );
        let err = VideoReader::open_with(write("x.mp4", &mkv), Some(Backend::Ffmpeg))
            .expect_err("no ffmpeg");
        assert!(
            matches!(
                err,
                VideoError::FeatureDisabled {
                    feature: "ffmpeg",
                    ..
                }
            ),
            "{err}"
        );
    }
    // A still image is not a video.
    let msg = read_all(&write("still.png", b"\x89PNG\r\n\x1a\n\0\0\0\rIHDR"))
        .expect_err("png")
        .to_string();
    assert!(
        msg.contains("PNG") && msg.contains("folder of stills"),
        "{msg}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_missing_camera_is_a_clear_error() {
    let err = Camera::open("/dev/video97", 640, 480, 30).expect_err("no such camera");
    let msg = err.to_string();
    assert!(msg.contains("/dev/video97"), "{msg}");
    if cfg!(all(feature = "v4l", target_os = "linux")) {
        assert!(matches!(err, VideoError::DeviceNotFound { .. }), "{err:?}");
        assert!(msg.contains("not found"), "{msg}");
    } else {
        assert!(matches!(err, VideoError::FeatureDisabled { .. }), "{err:?}");
        assert!(msg.contains("--features v4l"), "{msg}");
    }
    assert!(!err.is_source_lost());
    // A file that is not a camera.
    if cfg!(all(feature = "v4l", target_os = "linux")) {
        let err = Camera::open("/dev/null", 640, 480, 30).expect_err("not a camera");
        assert!(err.to_string().contains("/dev/null"), "{err}");
    }
    let err = Camera::open("/dev/video0", 0, 480, 30).expect_err("bad request");
    assert!(matches!(err, VideoError::InvalidSetting { .. }), "{err:?}");
}

/// Regression (issue 11): an MP4 below 16x16 failed inside OpenH264 after the whole take; the
/// size is refused when the writer is made (and by `check_frame_size` before a take).
#[test]
fn regression_frames_below_16x16_are_refused_up_front() {
    let e = pa_video::Mp4Writer::check_frame_size(12, 12).expect_err("too small");
    assert!(e.to_string().contains("16x16"), "{e}");
    assert!(pa_video::Mp4Writer::check_frame_size(16, 16).is_ok());
    let tmp = tempfile::Builder::new()
        .prefix("pa_video_small_")
        .tempdir()
        .expect("mkdir");
    let dir = tmp.path();
    let opts = pa_video::Mp4WriterOptions::new(pa_video::Fps::new(24, 1).expect("fps"));
    assert!(pa_video::Mp4Writer::create(dir.join("s.mp4"), 8, 8, opts).is_err());
}

/// Regression (issue 11): an MP4 written with `overwrite` renamed a regular file over a FIFO.
#[test]
fn regression_overwrite_never_replaces_a_fifo() {
    use std::os::unix::fs::FileTypeExt;
    let tmp = tempfile::Builder::new()
        .prefix("pa_video_fifo_")
        .tempdir()
        .expect("mkdir");
    let dir = tmp.path();
    let fifo = dir.join("out.mp4");
    let ok = std::process::Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .expect("mkfifo");
    assert!(ok.success());
    let mut opts = pa_video::Mp4WriterOptions::new(pa_video::Fps::new(24, 1).expect("fps"));
    opts.overwrite = true;
    let mut w = pa_video::Mp4Writer::create(&fifo, 32, 32, opts).expect("create");
    w.write_frame(&vec![128u8; 32 * 32 * 4]).expect("frame");
    let e = w.finish().expect_err("a FIFO is not replaced");
    assert!(e.to_string().contains("FIFO"), "{e}");
    let meta = std::fs::symlink_metadata(&fifo).expect("still there");
    assert!(meta.file_type().is_fifo());
}

/// Regression (issue 11): a FIFO named like a video blocked `track` forever in `open`.
#[test]
fn regression_a_fifo_as_a_video_is_refused_at_once() {
    let tmp = tempfile::Builder::new()
        .prefix("pa_video_fifo_in_")
        .tempdir()
        .expect("mkdir");
    let dir = tmp.path();
    let fifo = dir.join("take.mp4");
    let ok = std::process::Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .expect("mkfifo");
    assert!(ok.success());
    let e = pa_video::VideoReader::open(&fifo).expect_err("a FIFO");
    assert!(
        e.to_string().contains("take.mp4") && e.to_string().contains("FIFO"),
        "{e}"
    );
}
