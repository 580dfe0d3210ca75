//! Prints fill times (median of 50 runs) for a 200x200 prop mask in 720p and 1080p frames.
//!
//! `cargo run --release -p pa-diminish --example fill_timing`

use pa_diminish::{
    blend_with_prior, dilate, fill, CleanPlate, DilateShape, Diminisher, FillMethod, Homography,
    ImageRgba8, Mask, PatchPrior, RayDirections,
};
use std::time::Instant;

const RUNS: usize = 50;

fn texture(x: f64, y: f64) -> [u8; 4] {
    let g = (0.45 * x + 0.2 * y + 4.0 * (0.03 * y).sin()).sin();
    let n = ((x * 12.9898 + y * 78.233).sin() * 43758.5453)
        .fract()
        .abs();
    let t = 0.5 + 0.3 * g + 0.2 * (n - 0.5);
    let c = |a: f64, b: f64| (a + b * t).round().clamp(0.0, 255.0) as u8;
    [c(60.0, 150.0), c(40.0, 110.0), c(25.0, 70.0), 255]
}

/// Runs `f` RUNS times after `setup`, returning (median ms, minimum ms). The minimum is a
/// proxy for the uncontended cost on a loaded machine.
fn time(
    mut setup: impl FnMut(),
    mut f: impl FnMut() -> Result<(), Box<dyn std::error::Error>>,
) -> Result<(f64, f64), Box<dyn std::error::Error>> {
    let mut wall = Vec::with_capacity(RUNS);
    for _ in 0..RUNS {
        setup();
        let t = Instant::now();
        f()?;
        wall.push(t.elapsed().as_secs_f64() * 1e3);
    }
    let min = wall.iter().copied().fold(f64::INFINITY, f64::min);
    Ok((median_ms(wall), min))
}

fn row(frame: &str, name: &str, t: (f64, f64), pixels: Option<usize>) {
    let px = pixels.map_or(String::new(), |p| p.to_string());
    println!("{frame:<10} {name:<30} {:>9.3} {:>9.3} {px:>8}", t.0, t.1);
}

fn median_ms(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    println!(
        "{:<10} {:<30} {:>9} {:>9} {:>8}",
        "frame", "operation (200x200 mask)", "median ms", "min ms", "pixels"
    );
    for (w, h) in [(1280u32, 720u32), (1920, 1080)] {
        let fname = format!("{w}x{h}");
        let truth = ImageRgba8::from_fn(w, h, |x, y| texture(f64::from(x), f64::from(y)))?;
        let plate = truth.clone();
        let (cx, cy) = (f64::from(w) / 2.0, f64::from(h) / 2.0);
        // A disc of diameter 200 px: bounding box 200x200.
        let mask = Mask::from_fn(w, h, |x, y| {
            let (dx, dy) = (f64::from(x) + 0.5 - cx, f64::from(y) + 0.5 - cy);
            dx * dx + dy * dy <= 100.0 * 100.0
        })?;
        let (c, s) = (3f64.to_radians().cos(), 3f64.to_radians().sin());
        let hmat = Homography::from_row_major([c, -s, 5.0, s, c, -3.0, 1e-5, 0.0, 1.0]);
        let methods = [
            ("paper rectangle", FillMethod::PaperRectangle { rect: None }),
            ("rays, 8 directions", FillMethod::Rays(RayDirections::Eight)),
            (
                "rays, 16 directions",
                FillMethod::Rays(RayDirections::Sixteen),
            ),
            (
                "clean plate (+gain)",
                FillMethod::CleanPlate(CleanPlate::new(&plate, hmat)),
            ),
        ];
        let bbox = mask.bounding_box().ok_or("empty mask")?;
        let frame = std::cell::RefCell::new(truth.clone());
        let mut dim = Diminisher::new();
        for (name, method) in &methods {
            let mut filled = 0;
            let t = time(
                || {
                    let _ = frame.borrow_mut().copy_from(&truth);
                },
                || {
                    filled = dim
                        .fill_in_bbox(&mut frame.borrow_mut(), &mask, bbox, method)?
                        .filled;
                    Ok(())
                },
            )?;
            row(&fname, name, t, Some(filled));
        }
        // The ray fill on a set whose surfaces are known: two surfaces meeting on a slanted
        // line across the mask.
        let labels: Vec<u8> = (0..h)
            .flat_map(|y| (0..w).map(move |x| u8::from(f64::from(x) + 0.5 * f64::from(y) > cx)))
            .collect();
        let labels = Mask::new(w, h, labels)?;
        for (name, dirs) in [
            ("rays 8, two surfaces", RayDirections::Eight),
            ("rays 16, two surfaces", RayDirections::Sixteen),
        ] {
            let mut filled = 0;
            let method = FillMethod::Rays(dirs);
            let t = time(
                || {
                    let _ = frame.borrow_mut().copy_from(&truth);
                },
                || {
                    let mut f = frame.borrow_mut();
                    filled = dim
                        .fill_in_bbox_on(&mut f, &mask, bbox, &method, Some(&labels))?
                        .filled;
                    Ok(())
                },
            )?;
            row(&fname, name, t, Some(filled));
        }
        // The temporal blend of a fill with the previous frame's result, warped.
        let prior_mask = Mask::zeros(w, h)?;
        let prior = PatchPrior {
            image: &plate,
            mask: &prior_mask,
            current_from_previous: hmat,
        };
        let mut blended = 0;
        let t = time(
            || {},
            || {
                let mut f = frame.borrow_mut();
                blended = blend_with_prior(&mut f, &mask, bbox, &prior, 0.7)?;
                Ok(())
            },
        )?;
        row(&fname, "temporal blend with the prior", t, Some(blended));
        // The one-shot API: bounding-box scan of the mask and fresh scratch buffers.
        let t = time(
            || {
                let _ = frame.borrow_mut().copy_from(&truth);
            },
            || {
                fill(
                    &mut frame.borrow_mut(),
                    &mask,
                    &FillMethod::Rays(RayDirections::Sixteen),
                )?;
                Ok(())
            },
        )?;
        row(&fname, "rays16 via fill() (bbox scan)", t, None);
        let mut dst = Mask::zeros(w, h)?;
        for (name, shape) in [
            ("dilate r=6 disc (+memset)", DilateShape::Disc),
            ("dilate r=6 square (+memset)", DilateShape::Square),
        ] {
            let t = time(
                || {},
                || {
                    dilate(&mask, 6, shape, &mut dst)?;
                    Ok(())
                },
            )?;
            row(&fname, name, t, None);
        }
        let t = time(
            || {},
            || {
                std::hint::black_box(mask.bounding_box());
                Ok(())
            },
        )?;
        row(&fname, "mask bounding_box scan", t, None);
    }
    Ok(())
}
