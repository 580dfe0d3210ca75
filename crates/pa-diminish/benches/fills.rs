//! Criterion benches of the diminish stage at 1280x720: each fill over a bust-shaped prop mask
//! (about 320 px tall, the built-in prop's size in the generated scene), dilated by 4 px as
//! the pipeline does (the patch fill alone and with a previous-frame prior too), plus the
//! dilation and the depth-to-mask step.
//!
//! `cargo bench -p pa-diminish` (add `-- --quick` for a rough figure in seconds).

use std::time::Duration;

use criterion::{black_box, BatchSize, Criterion};
use pa_diminish::{
    dilate, mask_from_depth, CleanPlate, DilateShape, Diminisher, FillMethod, Homography,
    ImageRgba8, Mask, PatchFill, PatchPrior, RayDirections,
};

const W: u32 = 1280;
const H: u32 = 720;

/// A wood-like texture with grain and noise (as the diminish tests use).
fn texture(x: f64, y: f64) -> [u8; 4] {
    let g = (0.45 * x + 0.2 * y + 4.0 * (0.03 * y).sin()).sin();
    let n = ((x * 12.9898 + y * 78.233).sin() * 43758.5453)
        .fract()
        .abs();
    let t = 0.5 + 0.3 * g + 0.2 * (n - 0.5);
    let c = |a: f64, b: f64| (a + b * t).round().clamp(0.0, 255.0) as u8;
    [c(60.0, 150.0), c(40.0, 110.0), c(25.0, 70.0), 255]
}

/// A bust silhouette: head, neck and shoulders, about 320 px tall, centred in the frame.
fn in_bust(x: f64, y: f64) -> bool {
    let cx = f64::from(W) / 2.0;
    let e = |x0: f64, y0: f64, rx: f64, ry: f64| {
        ((x - x0) / rx).powi(2) + ((y - y0) / ry).powi(2) <= 1.0
    };
    let head = e(cx, 270.0, 62.0, 82.0);
    let jaw = e(cx + 8.0, 330.0, 45.0, 30.0);
    let neck = (x - cx).abs() <= 32.0 && (330.0..=420.0).contains(&y);
    let shoulders = e(cx, 455.0, 125.0, 70.0) && y <= 520.0;
    head || jaw || neck || shoulders
}

fn criterion() -> Criterion {
    Criterion::default()
        .sample_size(10)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(2))
        .configure_from_args()
}

fn main() {
    let mut c = criterion();
    let frame =
        ImageRgba8::from_fn(W, H, |x, y| texture(f64::from(x), f64::from(y))).expect("frame");
    let plate = frame.clone();
    let depth: Vec<f32> = (0..H)
        .flat_map(|y| (0..W).map(move |x| (x, y)))
        .map(|(x, y)| {
            if in_bust(f64::from(x), f64::from(y)) {
                0.55
            } else {
                f32::INFINITY
            }
        })
        .collect();
    let mut key_mask = Mask::zeros(W, H).expect("mask");
    mask_from_depth(&depth, W, H, &mut key_mask).expect("mask from depth");
    let mut fill_mask = Mask::zeros(W, H).expect("mask");
    dilate(&key_mask, 4, DilateShape::Disc, &mut fill_mask).expect("dilate");
    let (co, si) = (2f64.to_radians().cos(), 2f64.to_radians().sin());
    let h = Homography::from_row_major([co, -si, 6.0, si, co, -4.0, 1e-5, 0.0, 1.0]);
    println!(
        "diminish benches: {W}x{H} frame, bust mask of {} px ({} px after 4 px dilation)",
        key_mask.count(),
        fill_mask.count()
    );

    let mut g = c.benchmark_group("fill_1280x720_bust");
    let methods = [
        ("paper_rectangle", FillMethod::PaperRectangle { rect: None }),
        ("rays_8", FillMethod::Rays(RayDirections::Eight)),
        ("rays_16", FillMethod::Rays(RayDirections::Sixteen)),
        (
            "clean_plate",
            FillMethod::CleanPlate(CleanPlate::new(&plate, h)),
        ),
    ];
    for (name, method) in &methods {
        let mut dim = Diminisher::new();
        g.bench_function(*name, |b| {
            b.iter_batched_ref(
                || frame.clone(),
                |f| {
                    dim.fill(f, &fill_mask, method).expect("fill");
                },
                BatchSize::LargeInput,
            )
        });
    }
    // The patch fill alone, and as the pipeline runs it from the second frame on: with the
    // previous result (here the same view's first fill) warped through a homography as prior.
    let patch = FillMethod::Patch(PatchFill::new());
    let mut first = frame.clone();
    Diminisher::new()
        .fill(&mut first, &fill_mask, &patch)
        .expect("fill");
    let shift = Homography::from_row_major([1.0, 0.0, 1.5, 0.0, 1.0, -1.0, 0.0, 0.0, 1.0]);
    let with_prior = FillMethod::Patch(PatchFill {
        prior: Some(PatchPrior {
            image: &first,
            mask: &fill_mask,
            current_from_previous: shift,
        }),
        ..PatchFill::new()
    });
    for (name, method) in [("patch", &patch), ("patch_with_prior", &with_prior)] {
        let mut dim = Diminisher::new();
        g.bench_function(name, |b| {
            b.iter_batched_ref(
                || frame.clone(),
                |f| {
                    dim.fill(f, &fill_mask, method).expect("fill");
                },
                BatchSize::LargeInput,
            )
        });
    }
    g.finish();

    let mut g = c.benchmark_group("mask_1280x720");
    let mut dst = Mask::zeros(W, H).expect("mask");
    g.bench_function("dilate_r4_disc", |b| {
        b.iter(|| dilate(black_box(&key_mask), 4, DilateShape::Disc, &mut dst).expect("dilate"))
    });
    let mut m = Mask::zeros(W, H).expect("mask");
    g.bench_function("mask_from_depth", |b| {
        b.iter(|| mask_from_depth(black_box(&depth), W, H, &mut m).expect("mask"))
    });
    g.finish();
    c.final_summary();
}
