//! The `ffmpeg` feature: phone-style footage (H.264 with B-frames, HEVC) and other containers
//! decode through FFmpeg, in presentation order. Clips are made with the `ffmpeg` command from
//! our synthetic frames; without the command (or its libx264/libx265 encoders) each test
//! prints that it is skipped.
#![cfg(feature = "ffmpeg")]

mod common;

use std::path::Path;
use std::process::Command;

use common::{psnr_rgb, read_stamp, synth_frame, temp_dir};
use pa_video::{Backend, VideoError, VideoReader};

const W: u32 = 320;
const H: u32 = 240;
const N: u32 = 24;

/// Encodes the synthetic frames with the ffmpeg CLI; `false` (and a printed reason) when that
/// is not possible here.
fn make_clip(dir: &Path, out: &Path, codec_args: &[&str]) -> bool {
    let raw = dir.join("frames.rgba");
    let mut data = Vec::new();
    for i in 0..N {
        data.extend(synth_frame(W, H, i));
    }
    std::fs::write(&raw, data).expect("write raw frames");
    let status = Command::new("ffmpeg")
        .args([
            "-hide_banner",
            "-loglevel",
            "error",
            "-y",
            "-f",
            "rawvideo",
            "-pix_fmt",
            "rgba",
        ])
        .args(["-s", &format!("{W}x{H}"), "-r", "24", "-i"])
        .arg(&raw)
        .args(codec_args)
        .args(["-pix_fmt", "yuv420p"])
        .arg(out)
        .status();
    match status {
        Ok(s) if s.success() => true,
        Ok(s) => {
            println!(
                "skipped: ffmpeg could not make {} ({s}); is the encoder available?",
                out.display()
            );
            false
        }
        Err(_) => {
            println!("skipped: the ffmpeg command is not installed");
            false
        }
    }
}

fn check_decodes_in_order(path: &Path, min_psnr: f64) {
    let reader = VideoReader::open(path).expect("opens through FFmpeg");
    assert_eq!(reader.info().backend, Backend::Ffmpeg);
    assert_eq!((reader.info().width, reader.info().height), (W, H));
    println!("{}: {}", path.display(), reader.info().codec);
    let mut last_pts = f64::NEG_INFINITY;
    let mut n = 0;
    let mut worst = f64::INFINITY;
    for frame in reader {
        let frame = frame.expect("frame");
        assert_eq!(frame.index, u64::from(n));
        assert_eq!(read_stamp(&frame.rgba, W), n, "presentation order");
        let t = frame.pts.as_secs_f64();
        assert!(t > last_pts, "timestamps increase");
        assert!((t - f64::from(n) / 24.0).abs() < 1e-3, "frame {n} at {t} s");
        last_pts = t;
        worst = worst.min(psnr_rgb(&frame.rgba, &synth_frame(W, H, n)));
        n += 1;
    }
    assert_eq!(n, N);
    println!("{}: {n} frames, worst PSNR {worst:.2} dB", path.display());
    assert!(worst > min_psnr, "worst PSNR {worst:.2} dB");
}

#[test]
fn h264_with_b_frames_decodes_in_presentation_order() {
    let dir = temp_dir("ff-bframes");
    let path = dir.join("phone_h264.mp4");
    if !make_clip(
        &dir,
        &path,
        &[
            "-c:v",
            "libx264",
            "-profile:v",
            "high",
            "-bf",
            "3",
            "-crf",
            "12",
        ],
    ) {
        return;
    }
    // The built-in decoder refuses it and names the feature ...
    let err = VideoReader::open_with(&path, Some(Backend::OpenH264)).expect_err("B-frames");
    assert!(matches!(err, VideoError::NeedsFeature { .. }), "{err}");
    // ... the automatic choice uses FFmpeg.
    check_decodes_in_order(&path, 32.0);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn hevc_decodes() {
    let dir = temp_dir("ff-hevc");
    let path = dir.join("phone_hevc.mp4");
    if !make_clip(
        &dir,
        &path,
        &[
            "-c:v",
            "libx265",
            "-tag:v",
            "hvc1",
            "-x265-params",
            "log-level=error:crf=12",
        ],
    ) {
        return;
    }
    check_decodes_in_order(&path, 32.0);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn matroska_decodes_and_garbage_is_a_typed_error() {
    let dir = temp_dir("ff-mkv");
    let path = dir.join("clip.mkv");
    if make_clip(&dir, &path, &["-c:v", "libx264", "-bf", "2", "-crf", "12"]) {
        check_decodes_in_order(&path, 32.0);
    }
    let bad = dir.join("bad.mkv");
    let mut data = vec![0x1a, 0x45, 0xdf, 0xa3];
    data.extend_from_slice(&[0x42; 200]);
    std::fs::write(&bad, data).expect("write");
    let err = VideoReader::open(&bad).expect_err("garbage");
    assert!(err.to_string().contains("bad.mkv"), "{err}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn our_mp4s_decode_identically_through_ffmpeg() {
    use pa_video::{Fps, Mp4Writer, Mp4WriterOptions};
    let dir = temp_dir("ff-ours");
    let path = dir.join("ours.mp4");
    let mut w = Mp4Writer::create(
        &path,
        W,
        H,
        Mp4WriterOptions::new(Fps::new(24, 1).expect("fps")),
    )
    .expect("create");
    for i in 0..N {
        w.write_frame(&synth_frame(W, H, i)).expect("frame");
    }
    w.finish().expect("finish");
    let native: Vec<_> = VideoReader::open_with(&path, Some(Backend::OpenH264))
        .expect("native")
        .collect::<Result<_, _>>()
        .expect("native frames");
    let ff: Vec<_> = VideoReader::open_with(&path, Some(Backend::Ffmpeg))
        .expect("ffmpeg")
        .collect::<Result<_, _>>()
        .expect("ffmpeg frames");
    assert_eq!(native.len(), N as usize);
    assert_eq!(ff.len(), N as usize);
    for (a, b) in native.iter().zip(&ff) {
        assert_eq!(a.index, b.index);
        assert_eq!(
            a.pts.as_secs_f64(),
            b.pts.as_secs_f64(),
            "frame {}",
            a.index
        );
        // Same H.264 decoding (both are conforming decoders), same colour conversion.
        assert!(
            a.rgba == b.rgba,
            "frame {} differs: {:.2} dB",
            a.index,
            psnr_rgb(&a.rgba, &b.rgba)
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}
