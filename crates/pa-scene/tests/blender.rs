//! `eval --set` on a few frames another renderer made: Blender's Cycles rendered our set with
//! the built-in bust (`scripts/blender/render_set.py`, 64 samples per pixel, sun with a soft
//! shadow, procedural wood); `scripts/blender/crop_set.py` cut frames 3-6 of the take to a
//! 300x280 window (`tests/data/blender_bust`). The manifest's cameras were read back from
//! Blender's camera objects, so they are the truth our tracker is held to.

use std::path::Path;

use pa_pipeline::ar::ArSettings;
use pa_render::Renderer;
use pa_scene::set::{run_set, SetManifest};
use pa_scene::SceneError;

fn set() -> SetManifest {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/blender_bust");
    SetManifest::read(&dir).expect("manifest")
}

#[test]
fn the_tracker_agrees_with_blenders_cameras_and_the_fill_is_measured() {
    let set = set();
    assert_eq!(set.frames.len(), 4);
    assert_eq!((set.width, set.height), (300, 280));
    let mut renderer = Renderer::new().expect("renderer");
    let ms = run_set(&mut renderer, &set, ArSettings::ours(), |_, _, _, m| {
        eprintln!(
            "frame {}: tracked {} rot {:?} trans {:?} key IoU {:?} twin IoU {:?} prop {:?} revealed {:?} flicker {:?}",
            m.frame, m.tracked, m.rot_err_deg, m.trans_err_mm, m.key_mask_iou, m.twin_mask_iou,
            m.psnr_prop, m.psnr_revealed, m.flicker
        );
        Ok::<(), SceneError>(())
    })
    .expect("runs");
    // Each still is tracked alone, as `run` tracks stills.
    assert!(ms.iter().all(|m| m.tracked));
    for m in &ms {
        // Convention check: our tracked pose against the pose Blender rendered.
        let rot = m.rot_err_deg.expect("rotation error");
        let trans = m.trans_err_mm.expect("translation error");
        assert!(rot < 0.3, "frame {}: {rot} deg", m.frame);
        assert!(trans < 2.5, "frame {}: {trans} mm", m.frame);
        // Our key pose and in-between, drawn from the tracked pose, cover Blender's masks.
        let key = m.key_mask_iou.expect("key IoU");
        let twin = m.twin_mask_iou.expect("twin IoU");
        assert!(key > 0.98, "frame {}: key IoU {key}", m.frame);
        assert!(twin > 0.98, "frame {}: twin IoU {twin}", m.frame);
        let prop = m.psnr_prop.expect("prop PSNR");
        assert!(prop > 20.0, "frame {}: prop {prop} dB", m.frame);
        let revealed = m.psnr_revealed.expect("revealed PSNR");
        assert!(revealed > 20.0, "frame {}: {revealed} dB", m.frame);
    }
    // Away from the twin's edge the revealed background is the fill's alone, and there the
    // ray fill does better than over the whole region (measured: 28.05 against 26.93 dB):
    // the pixels beside the in-between's silhouette, where Cycles' truth mixes the twin's
    // edge into the background, carry most of the revealed error.
    let mean = |f: fn(&pa_scene::eval::FrameMetrics) -> Option<f64>| {
        ms.iter().map(|m| f(m).expect("measured")).sum::<f64>() / ms.len() as f64
    };
    let (whole, off_edge) = (
        mean(|m| m.psnr_revealed),
        mean(|m| m.psnr_revealed_off_edge),
    );
    assert!(
        off_edge > whole + 0.5,
        "{off_edge} dB off the edge, {whole} dB in all"
    );
    // Flicker is measured from the second frame on, for ours and the truth.
    assert!(ms[0].flicker.is_none());
    for m in &ms[1..] {
        let (ours, truth) = m.flicker.expect("flicker");
        assert!(ours.is_finite() && truth.is_finite() && ours >= 0.0 && truth > 0.0);
    }
}

/// Regression: the ray fill, the default, flickered: each frame filled its hole afresh, and
/// on these stills the filled background changed by 4.1-4.4 levels from frame to frame
/// (homography-compensated) where Cycles' truth changes by 3.1 (issue 12 allows 20 % more).
/// Each ray-filled pixel is now blended with the previous frame's result at the same table
/// point, as the patch fill's prior is (`pa_diminish::blend_with_prior`).
#[test]
fn regression_the_ray_fill_flickered_more_than_the_truth() {
    let set = set();
    let mut renderer = Renderer::new().expect("renderer");
    let ms = run_set(&mut renderer, &set, ArSettings::ours(), |_, _, _, _| {
        Ok::<(), SceneError>(())
    })
    .expect("runs");
    let flicker: Vec<(f64, f64)> = ms[1..]
        .iter()
        .map(|m| m.flicker.expect("flicker"))
        .collect();
    let ours = flicker.iter().map(|f| f.0).sum::<f64>() / flicker.len() as f64;
    let truth = flicker.iter().map(|f| f.1).sum::<f64>() / flicker.len() as f64;
    // Measured: 4.36 against 3.12 filled afresh, 1.48 blended.
    assert!(
        ours < 1.2 * truth,
        "flicker {ours:.2} against the truth's {truth:.2}"
    );
    // And the average is closer to the truth: 27.41 dB filled afresh, 29.46 blended.
    let revealed = ms
        .iter()
        .map(|m| m.psnr_revealed.expect("revealed"))
        .sum::<f64>()
        / 4.0;
    assert!(revealed > 28.5, "revealed background {revealed:.2} dB");
}

/// Regression (stop 36): the quad search put every tag's edges inside its black border
/// (where the encoded grey is halfway, a fifth of the way up in linear light), so the board
/// looked too small and too far: 0.72-1.29 mm along the line of sight on these frames, at
/// 600 mm. The tracker now finds the edges again in linear light (`pa_track::edges`):
/// measured 0.04-0.15 mm.
#[test]
fn regression_tag_corners_inside_the_black_border_put_the_board_too_far() {
    let set = set();
    let mut renderer = Renderer::new().expect("renderer");
    let ms = run_set(&mut renderer, &set, ArSettings::ours(), |_, _, _, _| {
        Ok::<(), SceneError>(())
    })
    .expect("runs");
    for m in &ms {
        let trans = m.trans_err_mm.expect("translation error");
        eprintln!("frame {}: translation error {trans:.3} mm", m.frame);
        assert!(trans < 0.4, "frame {}: {trans} mm", m.frame);
    }
}

#[test]
fn a_damaged_set_is_a_typed_error_naming_the_file() {
    let mut set = set();
    set.frames[1].truth = "truth/missing.png".into();
    let mut renderer = Renderer::new().expect("renderer");
    let e = run_set(&mut renderer, &set, ArSettings::ours(), |_, _, _, _| {
        Ok::<(), SceneError>(())
    })
    .expect_err("missing frame");
    assert!(
        matches!(&e, SceneError::Set { file, .. } if file.ends_with("truth/missing.png")),
        "{e}"
    );
}

/// The sun (issue 13): on Cycles' frames, where the bust's own parts cast shadows and a side
/// turned from the sun gets only the sky, relighting with the fitted sun and the twin's cast
/// shadows beats the first-order light against the renderer's truth. Measured: 26.20 dB
/// against 25.72 dB mean prop PSNR over the four frames (the plain look: 23.42 dB); the bound
/// asks for half that gain.
#[test]
fn the_sun_relights_closer_to_cycles_than_the_first_order_light() {
    let set = set();
    let mut renderer = Renderer::new().expect("renderer");
    let mut mean_prop = |look: pa_pipeline::ar::LiveLook| -> f64 {
        let settings = ArSettings {
            look,
            ..ArSettings::ours()
        };
        let ms = run_set(&mut renderer, &set, settings, |_, _, _, _| {
            Ok::<(), SceneError>(())
        })
        .expect("runs");
        let psnr: Vec<f64> = ms.iter().map(|m| m.psnr_prop.expect("prop PSNR")).collect();
        psnr.iter().sum::<f64>() / psnr.len() as f64
    };
    let sun = mean_prop(pa_pipeline::ar::LiveLook::RELIT_FEATHERED);
    let first_order = mean_prop(pa_pipeline::ar::LiveLook {
        sun: false,
        ..pa_pipeline::ar::LiveLook::RELIT_FEATHERED
    });
    println!("prop PSNR: sun {sun:.2} dB, first-order light {first_order:.2} dB");
    assert!(
        sun > first_order + 0.24,
        "sun {sun} first-order {first_order}"
    );
}
