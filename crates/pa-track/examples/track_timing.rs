//! Times detection + pose on 1280x720 frames: `cargo run --release -p pa-track --example track_timing`.

use std::time::Instant;

use pa_camera::{CameraModel, Intrinsics};
use pa_track::{estimate_tag_pose, marker_image, Detector, DetectorConfig, GrayImage, TagFamily};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let cam = CameraModel::pinhole(Intrinsics {
        fx: 1000.0,
        fy: 1000.0,
        cx: 639.5,
        cy: 359.5,
        width: 1280,
        height: 720,
    });
    // A frame with three tags of 100, 160 and 240 px on a mid-grey background with texture.
    let mut frame = GrayImage::filled(1280, 720, 120);
    // Smooth shading (a table under uneven light); per-pixel noise makes the detector's
    // connected-components stage much slower (see the report).
    for (i, v) in frame.data.iter_mut().enumerate() {
        let (x, y) = (i % 1280, i / 1280);
        *v = (90 + x / 20 + y / 20) as u8;
    }
    for (id, size, x0, y0) in [
        (1u32, 100u32, 100u32, 100u32),
        (2, 160, 500, 300),
        (3, 240, 950, 200),
    ] {
        let tag = marker_image(TagFamily::Tag36h11, id, size)?;
        for y in 0..size {
            for x in 0..size {
                frame.data[((y0 + y) * 1280 + x0 + x) as usize] = tag.data[(y * size + x) as usize];
            }
        }
    }
    for (name, cfg) in [
        (
            "default (decimate 1 + 2nd pass at 2)",
            DetectorConfig::default(),
        ),
        (
            "single pass decimate 1",
            DetectorConfig {
                second_pass_decimate: None,
                ..Default::default()
            },
        ),
        (
            "single pass decimate 2",
            DetectorConfig {
                decimate: 2,
                second_pass_decimate: None,
                ..Default::default()
            },
        ),
    ] {
        let mut det = Detector::new(cfg)?;
        let _ = det.detect(&frame)?; // warm-up (decoder allocation)
        let n = 50;
        let t0 = Instant::now();
        let mut found = 0;
        let mut pose_s = 0.0;
        for _ in 0..n {
            let dets = det.detect(&frame)?;
            found = dets.len();
            let t1 = Instant::now();
            for d in &dets {
                let _ = estimate_tag_pose(&cam, &d.corners_px, 0.08)?;
            }
            pose_s += t1.elapsed().as_secs_f64();
        }
        let total = t0.elapsed().as_secs_f64() / n as f64;
        println!(
            "{name}: {found} tags, detect + pose {:.2} ms/frame (pose {:.3} ms for all tags)",
            total * 1e3,
            pose_s / n as f64 * 1e3
        );
        // ROI detection around one tag.
        let t0 = Instant::now();
        for _ in 0..n {
            let _ = det.detect_roi(&frame, 450, 250, 260, 260)?;
        }
        println!(
            "   ROI 260x260: {:.2} ms",
            t0.elapsed().as_secs_f64() / n as f64 * 1e3
        );
    }
    Ok(())
}
