//! Criterion benches of the track stage on a 1280x720 frame of the generated scene (the
//! built-in prop on the eight-tag board, wood table, lit, handheld camera; rendered by
//! pa-scene): full-frame AprilTag detection (default settings, and `DetectorConfig::fast`), the board pose from those detections, and the
//! tracker's steady-state update (region-of-interest search once tracked, then pose and
//! filtering). Skips with a message when no wgpu adapter is available.
//!
//! `cargo bench -p pa-track` (add `-- --quick` for a rough figure in seconds). The detector's
//! passes run in parallel (rayon): `RAYON_NUM_THREADS=1` measures one core.

use std::time::Duration;

use criterion::{black_box, Criterion};
use pa_camera::CameraModel;
use pa_render::Renderer;
use pa_scene::{Scene, SceneSpec};
use pa_track::{Detector, DetectorConfig, GrayImage, TrackTarget, Tracker, TrackerConfig};

fn criterion() -> Criterion {
    Criterion::default()
        .sample_size(10)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(3))
        .configure_from_args()
}

fn gray(rgba8: &[u8], width: u32, height: u32) -> GrayImage {
    let data = rgba8
        .chunks_exact(4)
        .map(|p| ((77 * p[0] as u32 + 150 * p[1] as u32 + 29 * p[2] as u32 + 128) >> 8) as u8)
        .collect();
    GrayImage::new(width, height, data).expect("grey frame")
}

fn main() {
    let mut renderer = match Renderer::new() {
        Ok(r) => r,
        Err(e) => {
            println!("skipped: pa-track benches need a rendered frame: {e}");
            return;
        }
    };
    let spec = SceneSpec {
        width: 1280,
        height: 720,
        ..SceneSpec::default()
    };
    let scene = Scene::new(spec, &mut renderer).expect("scene");
    let frame = scene.frame(&mut renderer, 12).expect("frame");
    let image = gray(&frame.input.rgba8, 1280, 720);
    let camera = CameraModel::pinhole(scene.intrinsics);
    let mut detector = Detector::new(DetectorConfig::default()).expect("detector");
    let detections = detector.detect(&image).expect("detect");
    println!(
        "track benches: 1280x720 scene frame ({}), {} tags detected of {}",
        renderer.adapter_info(),
        detections.len(),
        scene.board.tags.len()
    );

    let mut c = criterion();
    let mut g = c.benchmark_group("track_1280x720");
    g.bench_function("detect_full_frame", |b| {
        b.iter(|| detector.detect(black_box(&image)).expect("detect"))
    });
    // The per-still preset: quad search at decimation 2, edges refined at full resolution.
    let mut fast = Detector::new(DetectorConfig::fast()).expect("detector");
    println!(
        "fast preset: {} tags detected",
        fast.detect(&image).expect("detect").len()
    );
    g.bench_function("detect_full_frame_fast", |b| {
        b.iter(|| fast.detect(black_box(&image)).expect("detect"))
    });
    g.bench_function("board_pose_from_detections", |b| {
        b.iter(|| {
            scene
                .board
                .estimate_pose(&camera, black_box(&detections))
                .expect("pose")
        })
    });
    let mut tracker = Tracker::new(
        camera,
        TrackTarget::Board(scene.board.clone()),
        DetectorConfig::default(),
        TrackerConfig::default(),
    )
    .expect("tracker");
    let mut t = 0.0;
    for _ in 0..4 {
        t += 1.0 / 24.0;
        tracker.update(&image, t).expect("update");
    }
    println!("tracker state before timing: {:?}", tracker.state());
    g.bench_function("tracker_update_tracked", |b| {
        b.iter(|| {
            t += 1.0 / 24.0;
            tracker.update(black_box(&image), t).expect("update")
        })
    });
    g.finish();
    c.final_summary();
}
