//! Quality and speed of the H.264 round trip on synthetic frames.
//!
//! `cargo run --release -p pa-video --example video_bench [-- --sizes 320x240,1280x720 --frames 30]`
//!
//! Prints, per size and rate-control setting: PSNR of the colour conversion alone (RGBA ->
//! BT.709 4:2:0 -> RGBA), PSNR after encoding and decoding (worst and mean frame), bytes, and
//! milliseconds a frame to encode (conversion + OpenH264 + muxing) and decode (demuxing +
//! OpenH264 + conversion).

#[path = "../tests/common/mod.rs"]
mod common;

use std::time::Instant;

use common::{psnr_rgb, synth_frame};
use pa_video::color::{i420_to_rgba, rgba_to_i420, I420Planes, YuvColor, I420};
use pa_video::{Fps, Mp4Writer, Mp4WriterOptions, RateControl, VideoReader};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let arg = |name: &str| {
        args.iter()
            .position(|a| a == name)
            .and_then(|i| args.get(i + 1))
            .cloned()
    };
    let sizes: Vec<(u32, u32)> = arg("--sizes")
        .unwrap_or_else(|| "320x240,1280x720".into())
        .split(',')
        .filter_map(|s| {
            let (w, h) = s.split_once('x')?;
            Some((w.parse().ok()?, h.parse().ok()?))
        })
        .collect();
    let frames: u32 = arg("--frames").and_then(|s| s.parse().ok()).unwrap_or(30);
    let dir = std::env::temp_dir().join(format!("pa-video-bench-{}", std::process::id()));
    std::fs::create_dir_all(&dir)?;
    let settings = [
        ("quality qp 16-24 (default)", RateControl::default()),
        (
            "quality qp 10-18",
            RateControl::Quality {
                qp_min: 10,
                qp_max: 18,
            },
        ),
        (
            "quality qp 20-28",
            RateControl::Quality {
                qp_min: 20,
                qp_max: 28,
            },
        ),
        ("bitrate 2 Mbit/s", RateControl::Bitrate { bps: 2_000_000 }),
        ("bitrate 8 Mbit/s", RateControl::Bitrate { bps: 8_000_000 }),
    ];
    println!("| size | setting | conversion-only PSNR dB | worst / mean PSNR dB | bytes | encode ms/frame | decode ms/frame |");
    println!("|---|---|---|---|---|---|---|");
    for &(w, h) in &sizes {
        let originals: Vec<Vec<u8>> = (0..frames).map(|i| synth_frame(w, h, i)).collect();
        // Conversion alone.
        let mut conv = f64::INFINITY;
        let mut yuv = I420::default();
        let mut back = Vec::new();
        let (mut to_yuv_s, mut to_rgba_s) = (0.0, 0.0);
        for f in &originals {
            let t = Instant::now();
            rgba_to_i420(f, w as usize, h as usize, YuvColor::BT709_LIMITED, &mut yuv);
            to_yuv_s += t.elapsed().as_secs_f64();
            let p = I420Planes {
                y: &yuv.y,
                u: &yuv.u,
                v: &yuv.v,
                y_stride: yuv.width,
                uv_stride: yuv.width / 2,
                width: yuv.width,
                height: yuv.height,
            };
            let t = Instant::now();
            i420_to_rgba(
                &p,
                (0, 0, w as usize, h as usize),
                YuvColor::BT709_LIMITED,
                &mut back,
            );
            to_rgba_s += t.elapsed().as_secs_f64();
            conv = conv.min(psnr_rgb(f, &back));
        }
        eprintln!(
            "{w}x{h}: RGBA -> 4:2:0 {:.2} ms, 4:2:0 -> RGBA {:.2} ms a frame",
            to_yuv_s * 1000.0 / f64::from(frames),
            to_rgba_s * 1000.0 / f64::from(frames)
        );
        for (name, rate) in settings {
            let path = dir.join(format!("bench_{w}x{h}.mp4"));
            let mut opts = Mp4WriterOptions::new(Fps::new(24, 1)?);
            opts.rate_control = rate;
            opts.overwrite = true;
            let t = Instant::now();
            let mut writer = Mp4Writer::create(&path, w, h, opts)?;
            for f in &originals {
                writer.write_frame(f)?;
            }
            let summary = writer.finish()?;
            let enc_ms = t.elapsed().as_secs_f64() * 1000.0 / f64::from(frames);
            let t = Instant::now();
            let decoded: Vec<_> = VideoReader::open(&path)?.collect::<Result<_, _>>()?;
            let dec_ms = t.elapsed().as_secs_f64() * 1000.0 / f64::from(frames);
            let psnrs: Vec<f64> = decoded
                .iter()
                .zip(&originals)
                .map(|(d, o)| psnr_rgb(&d.rgba, o))
                .collect();
            let worst = psnrs.iter().copied().fold(f64::INFINITY, f64::min);
            let mean = psnrs.iter().sum::<f64>() / psnrs.len() as f64;
            println!(
                "| {w}x{h} | {name} | {conv:.2} | {worst:.2} / {mean:.2} | {} | {enc_ms:.2} | {dec_ms:.2} |",
                summary.bytes
            );
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
    Ok(())
}
