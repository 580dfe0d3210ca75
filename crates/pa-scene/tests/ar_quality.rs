//! The AR output against ground truth on a small generated scene (deterministic seed), with
//! the real tracker: our method against the paper's, with asserted floors. The measured values
//! are printed; the floors sit below them with a margin for driver differences (lavapipe vs
//! llvmpipe). The README's table comes from `propsalive eval`.

use pa_pipeline::ar::{ArSettings, Fill, Texturing};
use pa_render::Renderer;
use pa_report::stats::{mean, median};
use pa_scene::eval::{run_scene, FrameMetrics};
use pa_scene::scene::{Background, CameraPath};
use pa_scene::SceneSpec;

fn spec() -> SceneSpec {
    SceneSpec {
        seed: 7,
        width: 480,
        height: 270,
        frames: 49,
        background: Background::Wood,
        camera_path: CameraPath::Handheld,
        ..SceneSpec::default()
    }
}

/// Frames 0..3 let the tracker lock on; then every 4th frame of the clip.
fn frames() -> Vec<u32> {
    (0..3).chain((4..=48).step_by(4)).collect()
}

fn run(renderer: &mut Renderer, settings: ArSettings) -> Vec<FrameMetrics> {
    run_scene(renderer, spec(), settings, frames(), |_, _, _| {
        Ok::<_, pa_scene::SceneError>(())
    })
    .expect("scene runs")
}

#[test]
fn ours_beats_the_paper_and_keeps_its_floors() {
    let mut renderer = match Renderer::new() {
        Ok(r) => r,
        Err(e) => {
            println!("skipped: no wgpu adapter ({e})");
            return;
        }
    };
    let ours = run(&mut renderer, ArSettings::ours());
    let paper = run(&mut renderer, ArSettings::paper());
    let no_vis = run(
        &mut renderer,
        ArSettings {
            texturing: Texturing::Live { visibility: false },
            ..ArSettings::ours()
        },
    );
    let rect = run(
        &mut renderer,
        ArSettings {
            fill: Fill::PaperRectangle,
            ..ArSettings::ours()
        },
    );
    let near = |m: &[FrameMetrics]| {
        mean(
            m.iter()
                .filter(|f| f.key_distance_deg <= 15.0)
                .map(|f| f.psnr_prop),
        )
    };
    // The turning head: in-betweens 20 degrees or more from the key pose, where the key prop
    // hides or foreshortens what the in-between shows.
    let far = |m: &[FrameMetrics]| {
        mean(
            m.iter()
                .filter(|f| f.key_distance_deg >= 20.0)
                .map(|f| f.psnr_prop),
        )
    };
    let tracked = ours.iter().filter(|m| m.tracked).count();
    let ours_prop = mean(ours.iter().map(|m| m.psnr_prop)).expect("prop psnr");
    let paper_prop = mean(paper.iter().map(|m| m.psnr_prop)).expect("prop psnr");
    let novis_prop = mean(no_vis.iter().map(|m| m.psnr_prop)).expect("prop psnr");
    let ours_rev = mean(ours.iter().map(|m| m.psnr_revealed)).expect("revealed psnr");
    let rect_rev = mean(rect.iter().map(|m| m.psnr_revealed)).expect("revealed psnr");
    let ours_off = mean(ours.iter().map(|m| m.psnr_revealed_off_edge)).expect("off edge");
    let rect_off = mean(rect.iter().map(|m| m.psnr_revealed_off_edge)).expect("off edge");
    let near_ours = near(&ours).expect("frames near the key");
    let far_ours = far(&ours).expect("frames far from the key");
    let far_novis = far(&no_vis).expect("frames far from the key");
    let rot = median(ours.iter().map(|m| m.rot_err_deg)).expect("poses");
    println!(
        "tracked {tracked}/{}; prop PSNR ours {ours_prop:.2} dB, paper {paper_prop:.2}, \
         no visibility {novis_prop:.2}; within 15 deg of the key {near_ours:.2} dB; 20 deg or \
         more: visibility {far_ours:.2} dB vs none {far_novis:.2}; revealed PSNR ray fill \
         {ours_rev:.2} dB vs rectangle {rect_rev:.2} (off the twin's edge {ours_off:.2} vs \
         {rect_off:.2}); median rotation error {rot:.3} deg",
        ours.len()
    );
    // Floors, below the values measured on lavapipe (printed above; README) by a margin for
    // driver differences.
    assert!(tracked >= ours.len() - 3, "the tracker must hold the board");
    // Regression: the One Euro filter once lagged the handheld camera by 0.7 deg (it filtered
    // the speed's magnitude, so it could not tell motion from jitter); raw poses are ~0.15.
    assert!(rot < 0.4, "median rotation error {rot} deg");
    assert!(
        near_ours > 27.0,
        "prop PSNR within 15 degrees of the key: {near_ours}"
    );
    assert!(
        ours_rev > rect_rev + 5.0,
        "ray fill {ours_rev} vs rectangle {rect_rev}"
    );
    // Off the twin's edge the truth is background alone: the ray fill does better there than
    // over the whole region, whose rim mixes the twin's edge in; the rectangle stays apart.
    assert!(
        ours_off > ours_rev && ours_off > rect_off + 5.0,
        "off the edge: ray fill {ours_off} (whole region {ours_rev}) vs rectangle {rect_off}"
    );
    // Visibility (lit fallback for hidden and foreshortened key-pose points) on the turning
    // head.
    assert!(
        far_ours > far_novis + 1.0,
        "visibility {far_ours} vs none {far_novis} at 20 degrees or more"
    );
    assert!(
        ours_prop > novis_prop + 0.4,
        "visibility {ours_prop} vs none {novis_prop}"
    );
    assert!(
        ours_prop > paper_prop + 0.3,
        "ours {ours_prop} vs paper {paper_prop}"
    );
}
