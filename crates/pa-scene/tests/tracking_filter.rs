//! The video-mode pose filter against per-still tracking on the generated scene's handheld
//! camera (every frame of the 49-frame clip, 24 fps), clean and with sensor noise and blur
//! (of the encoded values, and in linear light as a lens blurs): the filter must not cost
//! accuracy on clean frames and must lower the error on noisy ones.
//! Truth: the scene's own camera path. `propsalive eval` reports the same rows.

use pa_render::Renderer;
use pa_report::stats::median;
use pa_scene::scene::{Background, CameraPath};
use pa_scene::tracking::{tracking_errors, SensorNoise};
use pa_scene::SceneSpec;

#[test]
fn the_filter_never_worsens_clean_frames_and_smooths_noisy_ones() {
    let mut renderer = match Renderer::new() {
        Ok(r) => r,
        Err(e) => {
            eprintln!("skipping: no wgpu adapter ({e})");
            return;
        }
    };
    let spec = SceneSpec {
        seed: 7,
        width: 480,
        height: 270,
        frames: 49,
        background: Background::Wood,
        camera_path: CameraPath::Handheld,
        ..SceneSpec::default()
    };
    let noises = [
        None,
        Some(SensorNoise::HANDHELD),
        Some(SensorNoise::HANDHELD_LENS),
    ];
    let r = tracking_errors(&mut renderer, spec, 0..49, &noises).expect("scene runs");
    let mut medians = Vec::new();
    for (name, e) in ["clean", "noisy", "noisy, lens blur"].iter().zip(&r) {
        // Frames 0..3: the video tracker locks on.
        let still = median(e.per_still_rot_deg.iter().skip(3).copied()).expect("poses");
        let video = median(e.video_rot_deg.iter().skip(3).copied()).expect("poses");
        let still_t = median(e.per_still_trans_mm.iter().skip(3).copied()).expect("poses");
        let video_t = median(e.video_trans_mm.iter().skip(3).copied()).expect("poses");
        let tracked = e.video_rot_deg.iter().skip(3).flatten().count();
        eprintln!(
            "{name}: median rotation error per still {still:.4} deg, video filter {video:.4} deg; \
             translation {still_t:.3} / {video_t:.3} mm; video tracked {tracked}/46"
        );
        assert_eq!(tracked, 46, "{name}: every frame tracked");
        medians.push((still, video));
    }
    let (clean_still, clean_video) = medians[0];
    assert!(
        clean_video <= clean_still,
        "clean: filter {clean_video} vs per still {clean_still}"
    );
    for (name, &(still, video)) in ["noisy", "noisy, lens blur"].iter().zip(&medians[1..]) {
        assert!(video < still, "{name}: filter {video} vs per still {still}");
    }
}
