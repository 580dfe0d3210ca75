//! Defined behaviour of the frame pipeline on awkward input: tracking lost mid-shot (the output
//! is the untouched input, state reported), a prop entirely outside the frame (nothing drawn,
//! nothing filled), a frame of the wrong size (a typed error naming the sizes), and an image
//! handed back for reuse (written over, whatever it held).

use glam::Vec3;
use pa_pipeline::ar::{ArError, ArSettings, FrameTimes};
use pa_render::Renderer;
use pa_scene::eval::pipeline_for;
use pa_scene::{Scene, SceneSpec};
use pa_track::TrackState;

fn setup() -> Option<(Renderer, Scene)> {
    let mut renderer = match Renderer::new() {
        Ok(r) => r,
        Err(e) => {
            println!("skipped: no wgpu adapter ({e})");
            return None;
        }
    };
    let spec = SceneSpec {
        width: 320,
        height: 180,
        frames: 8,
        ..SceneSpec::default()
    };
    let scene = Scene::new(spec, &mut renderer).expect("scene");
    Some((renderer, scene))
}

/// The in-between at `animation_s` of the key pose at 0 s.
fn times(animation_s: f32) -> FrameTimes {
    FrameTimes {
        animation_s,
        key_pose_s: 0.0,
    }
}

#[test]
fn tracking_lost_mid_shot_passes_the_frame_through() {
    let Some((mut renderer, scene)) = setup() else {
        return;
    };
    let mut p = pipeline_for(&scene, &mut renderer, ArSettings::ours()).expect("pipeline");
    // Lock on for a few frames, then the marker disappears (a blank grey frame).
    let mut had_pose = false;
    for i in 0..8u32 {
        let f = scene.frame(&mut renderer, i).expect("frame");
        let out = p
            .process(
                &mut renderer,
                &f.input.rgba8,
                320,
                180,
                times(f.time_s),
                i as f64 / 24.0,
            )
            .expect("process");
        had_pose |= out.camera_from_marker.is_some();
    }
    assert!(had_pose, "the tracker must lock on to the board first");
    let blank = vec![128u8; 320 * 180 * 4];
    let mut saw_untouched = false;
    for k in 0..40u32 {
        let out = p
            .process(
                &mut renderer,
                &blank,
                320,
                180,
                times(0.5),
                (8 + k) as f64 / 24.0,
            )
            .expect("process");
        if out.camera_from_marker.is_none() {
            assert_eq!(
                out.rgba8, blank,
                "no pose: the output is the untouched input"
            );
            assert_ne!(out.state, TrackState::Tracked);
            saw_untouched = true;
        }
    }
    assert!(
        saw_untouched,
        "the tracker must give up the pose within 40 blank frames"
    );
}

#[test]
fn prop_outside_the_frame_draws_and_fills_nothing() {
    let Some((mut renderer, scene)) = setup() else {
        return;
    };
    let mut p = pipeline_for(&scene, &mut renderer, ArSettings::ours()).expect("pipeline");
    let f = scene.frame(&mut renderer, 0).expect("frame");
    // A camera looking away from the set (the prop is behind it).
    let away = pa_camera::camera_from_world_look_at(
        Vec3::new(0.0, 0.5, -0.3),
        Vec3::new(0.0, 2.0, -0.3),
        Vec3::NEG_Z,
    )
    .expect("camera");
    let out = p
        .process_with_pose(&mut renderer, &f.input.rgba8, 320, 180, times(0.5), away)
        .expect("process");
    assert!(out.twin_mask.iter().all(|&m| !m));
    assert!(out.key_mask.iter().all(|&m| !m));
    assert_eq!(out.rgba8, f.input.rgba8);
}

#[test]
fn wrong_frame_size_is_a_typed_error() {
    let Some((mut renderer, scene)) = setup() else {
        return;
    };
    let mut p = pipeline_for(&scene, &mut renderer, ArSettings::ours()).expect("pipeline");
    let e = p
        .process(&mut renderer, &[0u8; 100], 320, 180, times(0.0), 0.0)
        .expect_err("short buffer");
    assert!(matches!(e, ArError::BadFrame { .. }));
    let msg = e.to_string();
    assert!(
        msg.contains("320x180") && msg.contains("230400") && msg.contains("100"),
        "{msg}"
    );
}

#[test]
fn a_recycled_image_is_written_over_and_changes_no_frame() {
    let Some((mut renderer, scene)) = setup() else {
        return;
    };
    let settings = ArSettings::ours();
    let mut plain = pipeline_for(&scene, &mut renderer, settings).expect("pipeline");
    let mut recycling = pipeline_for(&scene, &mut renderer, settings).expect("pipeline");
    // A stale image of garbage, a buffer too small and one too large, then the first frame's
    // own image: none of what they held may show.
    let mut spare = vec![
        vec![0xA5u8; 320 * 180 * 4],
        vec![7u8; 12],
        vec![9u8; 400 * 300 * 4],
    ];
    for i in 0..4u32 {
        let f = scene.frame(&mut renderer, i).expect("frame");
        let run = |p: &mut pa_pipeline::ar::ArPipeline, r: &mut Renderer| {
            pa_scene::eval::process_at_true_pose(p, r, &f).expect("process")
        };
        let want = run(&mut plain, &mut renderer);
        let handed_back = spare.remove(0);
        let address = handed_back.as_ptr();
        let reusable = handed_back.capacity() >= 320 * 180 * 4;
        recycling.recycle(handed_back);
        let got = run(&mut recycling, &mut renderer);
        assert!(
            got.rgba8 == want.rgba8,
            "frame {i}: the recycled buffer changed the image"
        );
        if reusable {
            assert_eq!(
                got.rgba8.as_ptr(),
                address,
                "frame {i}: the buffer was not reused"
            );
        }
        spare.push(got.rgba8);
    }
}

/// `recycle_frame` hands a frame's image, masks and codes back: poisoned before they are
/// handed back (every mask pixel set, every code garbage), none of it may show in the next
/// frames, and the buffers are reused.
#[test]
fn a_recycled_frame_changes_no_mask_code_or_image() {
    let Some((mut renderer, scene)) = setup() else {
        return;
    };
    let settings = ArSettings::ours();
    let mut plain = pipeline_for(&scene, &mut renderer, settings).expect("pipeline");
    let mut recycling = pipeline_for(&scene, &mut renderer, settings).expect("pipeline");
    // The CPU path makes its masks and codes in the recycled buffers.
    for p in [&mut plain, &mut recycling] {
        p.set_render_path(pa_pipeline::ar::RenderPath::Cpu);
    }
    let mut last: Option<pa_pipeline::ar::ArFrame> = None;
    for i in 0..4u32 {
        let f = scene.frame(&mut renderer, i).expect("frame");
        let want =
            pa_scene::eval::process_at_true_pose(&mut plain, &mut renderer, &f).expect("process");
        let mut mask_addresses = Vec::new();
        if let Some(mut old) = last.take() {
            for m in [&mut old.twin_mask, &mut old.key_mask] {
                m.fill(true);
                mask_addresses.push(m.as_ptr());
            }
            old.live_codes.fill(0xAB);
            old.rgba8.fill(0x5A);
            recycling.recycle_frame(&mut old);
            assert!(
                old.rgba8.is_empty() && old.twin_mask.is_empty() && old.live_codes.is_empty(),
                "frame {i}: the buffers stay with the frame"
            );
        }
        let got = pa_scene::eval::process_at_true_pose(&mut recycling, &mut renderer, &f)
            .expect("process");
        assert!(got.rgba8 == want.rgba8, "frame {i}: image changed");
        assert!(
            got.twin_mask == want.twin_mask,
            "frame {i}: twin mask changed"
        );
        assert!(got.key_mask == want.key_mask, "frame {i}: key mask changed");
        assert!(
            got.live_codes == want.live_codes,
            "frame {i}: codes changed"
        );
        assert_eq!(got.live_counts, want.live_counts, "frame {i}");
        assert!(
            want.twin_mask.iter().any(|&m| m),
            "frame {i}: the twin must show"
        );
        for m in [&got.twin_mask, &got.key_mask] {
            if !mask_addresses.is_empty() {
                assert!(
                    mask_addresses.contains(&m.as_ptr()),
                    "frame {i}: a mask buffer was not reused"
                );
            }
        }
        last = Some(got);
    }
}
