//! No marker in the final frames (`pa_pipeline::ar::Hide`), against truth rendered by the
//! scene generator: the same view with the board sheet replaced by the cover picture printed
//! on the same paper (`Scene::cover_sheet`), or with no sheet at all (`SheetLook::Bare`).
//!
//! The pipeline runs from the true camera pose (no tracker: the hiding is measured, not the
//! detection), on the handheld path's frames. The region measured is the sheet's image (every
//! pixel it covers at all, anti-aliased edge included) minus the twin and the true in-between
//! prop, each grown by 2 px (the composite's edge and the live texture are measured elsewhere).
//! Floors sit below the printed measurements with a margin for driver differences.
//!
//! Golden images of the hidden-board composite (cover and plate) on both render paths, as
//! `golden_ar.rs` (same scene, tolerance and update switch).

use std::path::PathBuf;

use glam::{Mat4, Vec2};
use pa_diminish::{CoverImage, ImageRgba8};
use pa_pipeline::ar::{ArFrame, ArSettings, BoardSheet, FrameTimes, Hide, RenderPath};
use pa_pipeline::metrics::psnr_region;
use pa_render::{CpuTexture, Renderer};
use pa_scene::eval::pipeline_for;
use pa_scene::{Scene, SceneSpec, SheetLook};
use pa_testkit::golden::{assert_golden_in, Goldens, Tolerance};

use pa_scene::hide::cover_picture as picture;

fn image(t: &CpuTexture) -> ImageRgba8 {
    ImageRgba8::new(t.width, t.height, t.rgba8.clone()).expect("picture")
}

fn renderer() -> Option<Renderer> {
    match Renderer::new() {
        Ok(r) => Some(r),
        Err(e) => {
            println!("skipped: no wgpu adapter ({e})");
            None
        }
    }
}

fn process(
    renderer: &mut Renderer,
    scene: &Scene,
    hide: Option<(Hide, BoardSheet)>,
    path: RenderPath,
    frame: u32,
) -> ArFrame {
    let mut p = pipeline_for(scene, renderer, ArSettings::ours()).expect("pipeline");
    p.set_render_path(path);
    p.set_hide(hide);
    let f = scene.frame(renderer, frame).expect("frame");
    pa_scene::eval::process_at_true_pose(&mut p, renderer, &f).expect("process")
}

/// Grows a mask by `r` pixels (square).
fn grow(m: &[bool], w: usize, h: usize, r: usize) -> Vec<bool> {
    let mut out = vec![false; m.len()];
    for y in 0..h {
        for x in 0..w {
            if m[y * w + x] {
                for yy in y.saturating_sub(r)..(y + r + 1).min(h) {
                    for xx in x.saturating_sub(r)..(x + r + 1).min(w) {
                        out[yy * w + xx] = true;
                    }
                }
            }
        }
    }
    out
}

/// The measured region of a frame: the sheet's pixels minus the (grown) twin and true prop.
fn region(
    renderer: &mut Renderer,
    scene: &Scene,
    sheet: &BoardSheet,
    out: &ArFrame,
    frame: u32,
) -> Vec<bool> {
    let (w, h) = (scene.spec.width, scene.spec.height);
    let pose = scene.camera_from_marker(frame);
    let camera = pa_camera::CameraModel::pinhole(scene.intrinsics);
    let coords = sheet.coords(&camera, pose, w, h).expect("sheet in view");
    let (mask, _) = coords.mask(w, h).expect("mask");
    let prop = scene
        .prop_mask(renderer, pose, scene.time_s(frame))
        .expect("prop mask");
    let not = |m: &[bool]| grow(m, w as usize, h as usize, 2);
    let (twin, prop) = (not(&out.twin_mask), not(&prop));
    mask.as_slice()
        .iter()
        .enumerate()
        .map(|(i, &v)| v != 0 && !twin[i] && !prop[i])
        .collect()
}

fn spec(width: u32, height: u32, frames: u32) -> SceneSpec {
    SceneSpec {
        seed: 3,
        width,
        height,
        frames,
        ..SceneSpec::default()
    }
}

fn sheet_of(scene: &Scene) -> BoardSheet {
    BoardSheet::from_board(&scene.board, pa_pipeline::ar::SHEET_MARGIN_M).expect("sheet")
}

fn cover_truth(renderer: &mut Renderer, scene: &Scene, sheet: &BoardSheet, frame: u32) -> Vec<u8> {
    let cs = scene
        .cover_sheet(
            renderer,
            &picture(),
            Vec2::new(sheet.min_m.x as f32, sheet.min_m.y as f32),
            Vec2::new(sheet.max_m.x as f32, sheet.max_m.y as f32),
        )
        .expect("cover sheet");
    scene
        .render_with_sheet(
            renderer,
            scene.camera_from_marker(frame),
            Some(scene.time_s(frame)),
            SheetLook::Cover(&cs),
        )
        .expect("truth")
        .rgba8
}

/// The table without the board, from the clean plate's view (frame 0), and that pose.
fn bare_plate(renderer: &mut Renderer, scene: &Scene) -> (ImageRgba8, Mat4) {
    let pose = scene.camera_from_marker(0);
    let r = scene
        .render_with_sheet(renderer, pose, None, SheetLook::Bare)
        .expect("plate");
    (
        ImageRgba8::new(scene.spec.width, scene.spec.height, r.rgba8).expect("plate"),
        pose,
    )
}

const FRAMES: [u32; 4] = [8, 20, 32, 44];

#[test]
fn cover_and_plate_match_the_rendered_truth_over_the_sheet() {
    let Some(mut renderer) = renderer() else {
        return;
    };
    let scene = Scene::new(spec(480, 270, 49), &mut renderer).expect("scene");
    let sheet = sheet_of(&scene);
    let cover = CoverImage::new(&image(&picture())).expect("cover");
    let (plate, plate_pose) = bare_plate(&mut renderer, &scene);
    let mut worst = [f64::INFINITY; 3];
    for frame in FRAMES {
        let shown = process(&mut renderer, &scene, None, RenderPath::Cpu, frame);
        let covered = process(
            &mut renderer,
            &scene,
            Some((Hide::Cover(Box::new(cover.clone())), sheet.clone())),
            RenderPath::Cpu,
            frame,
        );
        let plated = process(
            &mut renderer,
            &scene,
            Some((
                Hide::Plate {
                    plate: plate.clone(),
                    camera_from_marker: plate_pose,
                },
                sheet.clone(),
            )),
            RenderPath::Cpu,
            frame,
        );
        let pose = scene.camera_from_marker(frame);
        let t = Some(scene.time_s(frame));
        let bare_truth = scene
            .render_with_sheet(&mut renderer, pose, t, SheetLook::Bare)
            .expect("truth")
            .rgba8;
        let cover_truth = cover_truth(&mut renderer, &scene, &sheet, frame);
        let reg = region(&mut renderer, &scene, &sheet, &covered, frame);
        let n = reg.iter().filter(|&&b| b).count();
        let p_cover = psnr_region(&covered.rgba8, &cover_truth, &reg).expect("cover psnr");
        let p_plate = psnr_region(&plated.rgba8, &bare_truth, &reg).expect("plate psnr");
        // The board left in place, against the bare table: how far the truth is from today.
        let p_shown = psnr_region(&shown.rgba8, &bare_truth, &reg).expect("shown psnr");
        println!(
            "frame {frame}: {n} px, cover {p_cover:.2} dB, plate {p_plate:.2} dB, board shown vs bare table {p_shown:.2} dB"
        );
        worst[0] = worst[0].min(p_cover);
        worst[1] = worst[1].min(p_plate);
        worst[2] = worst[2].min(p_shown);
        assert!(n > 5_000, "frame {frame}: the sheet covers only {n} px");
    }
    println!(
        "worst: cover {:.2} dB, plate {:.2} dB, board shown {:.2} dB",
        worst[0], worst[1], worst[2]
    );
    assert!(worst[0] > 30.0, "cover: {:.2} dB", worst[0]);
    assert!(worst[1] > 30.0, "plate: {:.2} dB", worst[1]);
    // The board itself is far from either truth (the measurement can tell).
    assert!(worst[2] < 15.0, "board shown: {:.2} dB", worst[2]);
}

#[test]
fn no_hide_is_byte_identical_and_a_cover_can_be_taken_back() {
    let Some(mut renderer) = renderer() else {
        return;
    };
    let scene = Scene::new(spec(192, 108, 21), &mut renderer).expect("scene");
    let sheet = sheet_of(&scene);
    let cover = CoverImage::new(&image(&picture())).expect("cover");
    for path in [RenderPath::Cpu, RenderPath::Gpu] {
        let plain = process(&mut renderer, &scene, None, path, 20);
        let mut p = pipeline_for(&scene, &mut renderer, ArSettings::ours()).expect("pipeline");
        p.set_render_path(path);
        let f = scene.frame(&mut renderer, 20).expect("frame");
        let times = FrameTimes {
            animation_s: f.time_s,
            key_pose_s: 0.0,
        };
        let run = |p: &mut pa_pipeline::ar::ArPipeline, r: &mut Renderer| {
            p.process_with_pose(r, &f.input.rgba8, 192, 108, times, f.camera_from_marker)
                .expect("process")
        };
        p.set_hide(Some((Hide::Cover(Box::new(cover.clone())), sheet.clone())));
        let hidden = run(&mut p, &mut renderer);
        // The preview's `B`: switched off, the board shows as without a hide; back on, the
        // same cover as before.
        p.set_hide_enabled(false);
        assert!(p.has_hide());
        let shown = run(&mut p, &mut renderer);
        assert_eq!(
            shown.rgba8,
            plain.rgba8,
            "{}: hide switched off",
            path.name()
        );
        p.set_hide_enabled(true);
        let again = run(&mut p, &mut renderer);
        assert_eq!(
            again.rgba8,
            hidden.rgba8,
            "{}: hide switched on",
            path.name()
        );
        p.set_hide(None);
        assert!(!p.has_hide());
        let back = run(&mut p, &mut renderer);
        assert_eq!(back.rgba8, plain.rgba8, "{}: hide off = today", path.name());
        let differ = hidden
            .rgba8
            .iter()
            .zip(&plain.rgba8)
            .filter(|(a, b)| a.abs_diff(**b) > 8)
            .count();
        assert!(
            differ > 1000,
            "{}: the cover changed {differ} bytes",
            path.name()
        );
    }
}

#[test]
fn hidden_board_composites_match_their_goldens() {
    let Some(mut renderer) = renderer() else {
        return;
    };
    let scene = Scene::new(spec(192, 108, 21), &mut renderer).expect("scene");
    let sheet = sheet_of(&scene);
    let cover = CoverImage::new(&image(&picture())).expect("cover");
    let (plate, plate_pose) = bare_plate(&mut renderer, &scene);
    let goldens = Goldens::for_adapter(
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/golden"),
        &renderer.adapter_info(),
        renderer.is_software(),
    );
    for path in [RenderPath::Gpu, RenderPath::Cpu] {
        let cases = [
            ("ar_hide_cover", Hide::Cover(Box::new(cover.clone()))),
            (
                "ar_hide_plate",
                Hide::Plate {
                    plate: plate.clone(),
                    camera_from_marker: plate_pose,
                },
            ),
        ];
        for (name, hide) in cases {
            println!("{name}: {} path", path.name());
            let out = process(&mut renderer, &scene, Some((hide, sheet.clone())), path, 20);
            assert_golden_in(&goldens, name, 192, 108, &out.rgba8, Tolerance::DEFAULT);
        }
    }
}
