//! Ground-truth tests of the fills. Each test states its tolerance.

mod common;

use common::*;
use pa_diminish::*;

const PROP: [u8; 3] = [230, 20, 200];

fn all_methods<'a>(plate: &'a ImageRgba8, h: Homography) -> Vec<(&'static str, FillMethod<'a>)> {
    vec![
        ("rect", FillMethod::PaperRectangle { rect: None }),
        ("rays8", FillMethod::Rays(RayDirections::Eight)),
        ("rays16", FillMethod::Rays(RayDirections::Sixteen)),
        ("plate", FillMethod::CleanPlate(CleanPlate::new(plate, h))),
    ]
}

/// Linear ramp background, blob prop well inside: the ray fill reproduces the ramp within
/// 1 level (u8 rounding of the background and of the result); the paper's rectangle does not.
#[test]
fn rays_reproduce_linear_gradient() {
    let (w, h) = (256, 192);
    let truth = image_from_rgb(w, h, gradient);
    let mut mask = blob(w, h, 120.0, 90.0, 45.0, 35.0);
    dilate_in_place(&mut mask, 2, DilateShape::Disc).unwrap();
    for dirs in [RayDirections::Eight, RayDirections::Sixteen] {
        let mut frame = truth.clone();
        paint(&mut frame, &mask, PROP);
        let stats = fill(&mut frame, &mask, &FillMethod::Rays(dirs)).unwrap();
        assert_eq!(stats.filled, mask.count());
        let err = max_abs_diff(&frame, &truth, &mask);
        println!("rays {dirs:?}: max abs error on gradient = {err}");
        assert!(err <= 1, "{dirs:?}: max error {err} > 1");
    }
    let mut frame = truth.clone();
    paint(&mut frame, &mask, PROP);
    fill(
        &mut frame,
        &mask,
        &FillMethod::PaperRectangle { rect: None },
    )
    .unwrap();
    let err = max_abs_diff(&frame, &truth, &mask);
    println!("paper rectangle: max abs error on gradient = {err}");
    assert!(
        err > 1,
        "the baseline is not expected to be exact on a ramp"
    );
}

/// Constant background: every method reproduces it exactly (plate: within 1 level, for the
/// sRGB round trip through linear light), also for masks touching each image border and corner.
#[test]
fn constant_background_all_methods_and_borders() {
    let (w, h) = (120, 90);
    let bg = [90u8, 140, 60, 77];
    let truth = ImageRgba8::filled(w, h, bg).unwrap();
    let plate = ImageRgba8::filled(w, h, [90, 140, 60, 255]).unwrap();
    let cases = [
        ("inside", 60.0, 45.0),
        ("left", 0.0, 45.0),
        ("right", 119.0, 45.0),
        ("top", 60.0, 0.0),
        ("bottom", 60.0, 89.0),
        ("top-left corner", 0.0, 0.0),
        ("bottom-right corner", 119.0, 89.0),
    ];
    for (name, cx, cy) in cases {
        let mask = blob(w, h, cx, cy, 20.0, 15.0);
        let bbox = mask.bounding_box().unwrap();
        for (mname, method) in all_methods(&plate, Homography::identity()) {
            let mut frame = truth.clone();
            paint(&mut frame, &mask, PROP);
            let stats = fill(&mut frame, &mask, &method)
                .unwrap_or_else(|e| panic!("{mname} / {name}: {e}"));
            assert_eq!(stats.bbox, Some(bbox), "{mname} / {name}");
            let tol = if mname == "plate" { 1 } else { 0 };
            let check = if mname == "rect" {
                Mask::from_fn(w, h, |x, y| bbox.contains(x, y)).unwrap()
            } else {
                mask.clone()
            };
            assert_eq!(stats.filled, check.count(), "{mname} / {name}");
            let err = max_abs_diff(&frame, &truth, &check);
            assert!(err <= tol, "{mname} / {name}: error {err} > {tol}");
            // Alpha is kept everywhere.
            assert!(frame.as_slice().chunks_exact(4).all(|p| p[3] == 77));
        }
    }
}

/// Textured (wood-grain) background: PSNR against the true background over the revealed
/// region (the dilated prop mask), and over the baseline's rectangle (which the baseline
/// overwrites entirely, destroying background that was visible). Measured (320x240, three
/// props): over the mask, rect 18.80/19.04/19.15 dB, rays8 19.51/19.30/19.43 dB, rays16
/// 20.14/19.45/19.98 dB (means 18.99 / 19.41 / 19.86); over the rectangle, means 19.07 /
/// 20.65 / 21.10 dB. Asserted: rays16 beats rect by at least 0.3 dB for every prop, by at
/// least 0.7 dB on average over the mask and by at least 1.5 dB on average over the
/// rectangle; rays8 beats rect by at least 0.2 dB for every prop. On a texture with a 14 px grain under an 80 px
/// prop no interpolator can do much better: that is what the clean plate is for.
#[test]
fn textured_background_rays_beat_rectangle() {
    let (w, h) = (320, 240);
    let truth = image_from_rgb(w, h, |x, y| wood(x, y, 1.0));
    let mut mean_mask = [0.0f64; 3];
    let mut mean_rect = [0.0f64; 3];
    let props = [
        (160.0, 120.0, 40.0, 30.0),
        (90.0, 80.0, 25.0, 45.0),
        (230.0, 150.0, 50.0, 25.0),
    ];
    for (cx, cy, rx, ry) in props {
        let mut mask = blob(w, h, cx, cy, rx, ry);
        dilate_in_place(&mut mask, 3, DilateShape::Disc).unwrap();
        let rect = baseline_rect(&mask, 0).unwrap();
        let rect_mask = Mask::from_fn(w, h, |x, y| rect.contains(x, y)).unwrap();
        let mut on_mask = [0.0f64; 3];
        let mut on_rect = [0.0f64; 3];
        for (i, method) in [
            FillMethod::PaperRectangle { rect: None },
            FillMethod::Rays(RayDirections::Eight),
            FillMethod::Rays(RayDirections::Sixteen),
        ]
        .iter()
        .enumerate()
        {
            let mut frame = truth.clone();
            paint(&mut frame, &mask, PROP);
            fill(&mut frame, &mask, method).unwrap();
            on_mask[i] = psnr_rgb(&frame, &truth, Some(&mask)).unwrap();
            on_rect[i] = psnr_rgb(&frame, &truth, Some(&rect_mask)).unwrap();
            mean_mask[i] += on_mask[i] / props.len() as f64;
            mean_rect[i] += on_rect[i] / props.len() as f64;
        }
        println!(
            "prop at ({cx},{cy}): PSNR over mask: rect {:.2} dB, rays8 {:.2} dB, rays16 {:.2} dB; \
             over rectangle: rect {:.2} dB, rays8 {:.2} dB, rays16 {:.2} dB",
            on_mask[0], on_mask[1], on_mask[2], on_rect[0], on_rect[1], on_rect[2]
        );
        assert!(on_mask[1] >= on_mask[0] + 0.2, "rays8 vs rect: {on_mask:?}");
        assert!(
            on_mask[2] >= on_mask[0] + 0.3,
            "rays16 vs rect: {on_mask:?}"
        );
    }
    println!(
        "mean PSNR over mask: rect {:.2} dB, rays8 {:.2} dB, rays16 {:.2} dB; over rectangle: \
         rect {:.2} dB, rays8 {:.2} dB, rays16 {:.2} dB",
        mean_mask[0], mean_mask[1], mean_mask[2], mean_rect[0], mean_rect[1], mean_rect[2]
    );
    assert!(
        mean_mask[2] >= mean_mask[0] + 0.7,
        "mean over mask: {mean_mask:?}"
    );
    assert!(
        mean_rect[2] >= mean_rect[0] + 1.5,
        "mean over rect: {mean_rect:?}"
    );
}

/// Clean plate: a textured table plane seen in the plate (identity plane-to-plate map) and in
/// the current view through a known homography with perspective, darkened by a linear-light
/// gain of 0.8, with a prop painted in. Asserted: PSNR over the mask > 35 dB, estimated gain
/// within 2 % of 0.8 for every channel, every masked pixel filled from the plate.
#[test]
fn clean_plate_recovers_warped_texture_and_gain() {
    let (w, h) = (320, 240);
    // Texture on the plane, in plate pixel units; smooth enough for bilinear sampling.
    let tex = |x: f64, y: f64| wood(x, y, 1.6);
    let plate = image_from_rgb(w, h, tex);
    // current_from_plate: rotation ~8 deg, scale 1.1, shift, mild perspective.
    let (c, s) = (8.0f64.to_radians().cos(), 8.0f64.to_radians().sin());
    let current_from_plate = Homography::from_row_major([
        1.1 * c,
        -1.1 * s,
        20.0,
        1.1 * s,
        1.1 * c,
        -15.0,
        2e-4,
        1e-4,
        1.0,
    ]);
    let plate_from_current = current_from_plate.inverse().unwrap();
    let gain = 0.8;
    let truth = image_from_rgb(w, h, |x, y| {
        let q = plate_from_current.apply([x, y]).unwrap();
        let t = tex(q[0], q[1]);
        t.map(|v| linear_to_srgb(gain * srgb_to_linear(v)))
    });
    let mut mask = blob(w, h, 170.0, 120.0, 45.0, 35.0);
    dilate_in_place(&mut mask, 3, DilateShape::Disc).unwrap();
    let mut frame = truth.clone();
    paint(&mut frame, &mask, PROP);
    let method = FillMethod::CleanPlate(CleanPlate::new(&plate, current_from_plate));
    let stats = fill(&mut frame, &mask, &method).unwrap();
    let psnr = psnr_rgb(&frame, &truth, Some(&mask)).unwrap();
    let g = stats.gain.unwrap();
    println!(
        "clean plate: PSNR over mask {psnr:.2} dB, gain {:?}, stats {stats:?}",
        g.gain
    );
    assert_eq!(stats.from_plate, mask.count());
    assert_eq!(stats.interpolated, 0);
    assert!(psnr > 35.0, "PSNR {psnr:.2} dB <= 35 dB");
    for gc in g.gain {
        assert!(
            (f64::from(gc) / gain - 1.0).abs() < 0.02,
            "gain {:?}",
            g.gain
        );
    }
    // Without gain matching the error is much larger (a sanity check of the test itself).
    let mut frame2 = truth.clone();
    paint(&mut frame2, &mask, PROP);
    let mut cp = CleanPlate::new(&plate, current_from_plate);
    cp.gain = GainModel::None;
    fill(&mut frame2, &mask, &FillMethod::CleanPlate(cp)).unwrap();
    let psnr_raw = psnr_rgb(&frame2, &truth, Some(&mask)).unwrap();
    println!("clean plate without gain: PSNR over mask {psnr_raw:.2} dB");
    assert!(psnr_raw < psnr - 10.0);
}

/// The plate covers only part of the masked region: the rest falls back to the ray fill,
/// which uses the plate-filled pixels as known. Asserted: both counts > 0, they sum to the mask
/// area, and the PSNR over the mask is above the pure ray fill's.
#[test]
fn clean_plate_falls_back_outside_the_plate() {
    let (w, h) = (200, 160);
    let tex = |x: f64, y: f64| wood(x, y, 1.6);
    let truth = image_from_rgb(w, h, tex);
    // The plate holds only columns 0..100 of the scene (identity map, smaller plate).
    let plate = image_from_rgb(100, h, tex);
    let mut mask = blob(w, h, 100.0, 80.0, 30.0, 25.0);
    dilate_in_place(&mut mask, 2, DilateShape::Disc).unwrap();
    let mut frame = truth.clone();
    paint(&mut frame, &mask, PROP);
    let method = FillMethod::CleanPlate(CleanPlate::new(&plate, Homography::identity()));
    let stats = fill(&mut frame, &mask, &method).unwrap();
    let psnr = psnr_rgb(&frame, &truth, Some(&mask)).unwrap();
    let mut rays = truth.clone();
    paint(&mut rays, &mask, PROP);
    fill(&mut rays, &mask, &FillMethod::Rays(RayDirections::Sixteen)).unwrap();
    let psnr_rays = psnr_rgb(&rays, &truth, Some(&mask)).unwrap();
    println!("plate+fallback {psnr:.2} dB vs rays {psnr_rays:.2} dB, {stats:?}");
    assert!(stats.from_plate > 0 && stats.interpolated > 0);
    assert_eq!(stats.from_plate + stats.interpolated, mask.count());
    assert!(psnr > psnr_rays);
}

/// The paper's rectangle on a hand-made 4x4 example: every value below is computed by hand.
#[test]
fn paper_rectangle_hand_example() {
    // R channel (X = inside the rectangle x 1..3, y 1..3):
    //   0  10  20   0
    //  30   X   X  60
    //  90   X   X 120
    //   0 200 250   0
    let r = [
        [0u8, 10, 20, 0],
        [30, 99, 99, 60],
        [90, 99, 99, 120],
        [0, 200, 250, 0],
    ];
    // G: rounding is half-up on the integer sum, out = (sum + 2) / 4.
    let g = [[0u8, 0, 0, 0], [1, 9, 9, 2], [3, 9, 9, 4], [0, 1, 0, 0]];
    let mut img = ImageRgba8::from_fn(4, 4, |x, y| {
        [r[y as usize][x as usize], g[y as usize][x as usize], 7, 42]
    })
    .unwrap();
    let n = paper_rectangle_fill(&mut img, Rect::new(1, 1, 2, 2)).unwrap();
    assert_eq!(n, 4);
    // (1,1): (30 + 60 + 10 + 200) / 4 = 75;  (2,1): (30 + 60 + 20 + 250) / 4 = 90
    // (1,2): (90 + 120 + 10 + 200) / 4 = 105; (2,2): (90 + 120 + 20 + 250) / 4 = 120
    // G (1,1): 1 + 2 + 0 + 1 = 4 -> 1.0 -> 1;  (2,1): 1 + 2 + 0 + 0 = 3 -> 0.75 -> 1
    // G (1,2): 3 + 4 + 0 + 1 = 8 -> 2.0 -> 2;  (2,2): 3 + 4 + 0 + 0 = 7 -> 1.75 -> 2
    assert_eq!(img.get(1, 1), Some([75, 1, 7, 42]));
    assert_eq!(img.get(2, 1), Some([90, 1, 7, 42]));
    assert_eq!(img.get(1, 2), Some([105, 2, 7, 42]));
    assert_eq!(img.get(2, 2), Some([120, 2, 7, 42]));
    // Pixels outside the rectangle are untouched.
    assert_eq!(img.get(0, 1), Some([30, 1, 7, 42]));

    // Touching the left border: only right, top and bottom exist, so the mean is over 3.
    let mut img = ImageRgba8::from_fn(3, 3, |x, y| match (x, y) {
        (0, 0) => [30, 0, 0, 255],
        (1, 1) => [90, 0, 0, 255],
        (0, 2) => [61, 0, 0, 255],
        _ => [0, 0, 0, 255],
    })
    .unwrap();
    paper_rectangle_fill(&mut img, Rect::new(0, 1, 1, 1)).unwrap();
    // (0,1): (right 90 + top 30 + bottom 61) / 3 = 181 / 3 = 60.33 -> 60
    assert_eq!(img.get(0, 1), Some([60, 0, 0, 255]));
    // A rectangle covering the whole image has no boundary.
    let err = paper_rectangle_fill(&mut img, Rect::new(0, 0, 3, 3)).unwrap_err();
    assert!(matches!(err, DiminishError::NoBoundary { .. }), "{err}");
}

/// An empty mask is a no-op for every method (frame unchanged, nothing filled).
#[test]
fn empty_mask_is_noop() {
    let img = image_from_rgb(64, 48, |x, y| wood(x, y, 1.0));
    let mask = Mask::zeros(64, 48).unwrap();
    for (name, method) in all_methods(&img, Homography::identity()) {
        let mut frame = img.clone();
        let stats = fill(&mut frame, &mask, &method).unwrap();
        assert_eq!(stats.filled, 0, "{name}");
        assert_eq!(stats.bbox, None, "{name}");
        assert_eq!(frame, img, "{name}");
    }
    assert!(matches!(
        baseline_rect(&mask, 2),
        Err(DiminishError::EmptyMask { .. })
    ));
}

/// Size mismatches, zero sizes and bad buffer lengths are typed errors naming the sizes.
#[test]
fn size_errors_are_typed() {
    let mut frame = ImageRgba8::filled(12, 10, [0, 0, 0, 255]).unwrap();
    let mask = Mask::zeros(10, 10).unwrap();
    let err = fill(&mut frame, &mask, &FillMethod::default()).unwrap_err();
    assert!(matches!(
        err,
        DiminishError::SizeMismatch {
            expected_width: 12,
            expected_height: 10,
            actual_width: 10,
            actual_height: 10,
            ..
        }
    ));
    let msg = err.to_string();
    assert!(msg.contains("10x10") && msg.contains("12x10"), "{msg}");

    let err = ImageRgba8::new(0, 5, vec![]).unwrap_err();
    assert!(matches!(
        err,
        DiminishError::ZeroSize {
            width: 0,
            height: 5,
            ..
        }
    ));
    assert!(err.to_string().contains("0x5"), "{err}");
    let err = Mask::new(4, 4, vec![0; 15]).unwrap_err();
    assert!(matches!(
        err,
        DiminishError::BufferLength {
            expected: 16,
            actual: 15,
            ..
        }
    ));
    assert!(err.to_string().contains("4x4"), "{err}");

    let mut dst = Mask::zeros(9, 10).unwrap();
    let err = dilate(&mask, 1, DilateShape::Disc, &mut dst).unwrap_err();
    assert!(err.to_string().contains("9x10"), "{err}");
    let err = mask_from_depth(&[0.0; 99], 10, 10, &mut dst).unwrap_err();
    assert!(matches!(
        err,
        DiminishError::BufferLength {
            expected: 100,
            actual: 99,
            ..
        }
    ));
    let err = psnr_rgb(&frame, &ImageRgba8::filled(3, 3, [0; 4]).unwrap(), None).unwrap_err();
    assert!(err.to_string().contains("3x3"), "{err}");
    let sing = Homography::from_row_major([1.0, 2.0, 3.0, 2.0, 4.0, 6.0, 0.0, 0.0, 1.0]);
    assert!(matches!(
        sing.inverse(),
        Err(DiminishError::SingularHomography { .. })
    ));
}

/// Dilating one pixel by r: `Disc` gives the digital disc dx^2 + dy^2 <= r^2 (29 pixels for
/// r = 3, 81 for r = 5, in a (2r+1)^2 box), `Square` the full (2r+1) x (2r+1) square;
/// both clip at the image border.
#[test]
fn dilate_single_pixel() {
    let disc_count = |r: i64| {
        (-r..=r)
            .flat_map(|dy| (-r..=r).map(move |dx| (dx, dy)))
            .filter(|(dx, dy)| dx * dx + dy * dy <= r * r)
            .count()
    };
    assert_eq!(disc_count(3), 29);
    for r in [1u32, 3, 5] {
        let mut src = Mask::zeros(40, 30).unwrap();
        src.set(20, 15, true);
        let mut dst = Mask::zeros(40, 30).unwrap();
        let bb = dilate(&src, r, DilateShape::Disc, &mut dst)
            .unwrap()
            .unwrap();
        assert_eq!(bb, Rect::new(20 - r, 15 - r, 2 * r + 1, 2 * r + 1));
        assert_eq!(dst.bounding_box(), Some(bb));
        assert_eq!(dst.count(), disc_count(i64::from(r)));
        for y in 0..30u32 {
            for x in 0..40u32 {
                let (dx, dy) = (i64::from(x) - 20, i64::from(y) - 15);
                assert_eq!(dst.get(x, y), dx * dx + dy * dy <= i64::from(r * r));
            }
        }
        let bb = dilate(&src, r, DilateShape::Square, &mut dst)
            .unwrap()
            .unwrap();
        assert_eq!(bb, Rect::new(20 - r, 15 - r, 2 * r + 1, 2 * r + 1));
        assert_eq!(dst.count(), ((2 * r + 1) * (2 * r + 1)) as usize);
    }
    // At the corner: the quarter disc / square that lies inside the image.
    let mut m = Mask::zeros(10, 10).unwrap();
    m.set(0, 0, true);
    let mut sq = m.clone();
    dilate_in_place(&mut sq, 3, DilateShape::Square).unwrap();
    assert_eq!(sq.count(), 16);
    dilate_in_place(&mut m, 3, DilateShape::Disc).unwrap();
    assert_eq!(m.count(), 11); // (dx, dy) >= 0 with dx^2 + dy^2 <= 9
                               // Empty stays empty.
    let mut e = Mask::zeros(5, 5).unwrap();
    assert_eq!(dilate_in_place(&mut e, 2, DilateShape::Disc).unwrap(), None);
}

/// `mask_from_depth` sets exactly the finite depths and returns their bounding box.
#[test]
fn mask_from_depth_marks_finite() {
    let (w, h) = (8u32, 6u32);
    let mut depth = vec![f32::INFINITY; 48];
    depth[2 * 8 + 3] = 0.5;
    depth[4 * 8 + 6] = 1.0;
    depth[5 * 8] = f32::NAN;
    let mut m = Mask::zeros(w, h).unwrap();
    let bb = mask_from_depth(&depth, w, h, &mut m).unwrap();
    assert_eq!(bb, Some(Rect::from_inclusive(3, 2, 6, 4)));
    assert_eq!(m.count(), 2);
    assert!(m.get(3, 2) && m.get(6, 4) && !m.get(0, 5));
    assert_eq!(m.as_slice()[2 * 8 + 3], 255);
}

/// Homography helpers: inverse round trip (1e-9 px), glam conversion, and the baseline
/// rectangle from projected points (rounded outwards to pixels, clipped).
#[test]
fn homography_and_rect_helpers() {
    let hm = Homography::from_row_major([1.1, -0.2, 20.0, 0.15, 0.95, -7.0, 1e-4, -2e-4, 1.0]);
    let inv = hm.inverse().unwrap();
    for p in [[0.0, 0.0], [100.0, 50.0], [-30.0, 400.0]] {
        let q = hm.apply(p).unwrap();
        let back = inv.apply(q).unwrap();
        assert!((back[0] - p[0]).abs() < 1e-9 && (back[1] - p[1]).abs() < 1e-9);
    }
    let g = hm.to_dmat3();
    assert_eq!(Homography::from_dmat3(g), hm);
    let v = g * glam::DVec3::new(100.0, 50.0, 1.0);
    let q = hm.apply([100.0, 50.0]).unwrap();
    assert!((v.x / v.z - q[0]).abs() < 1e-12);

    let r = Rect::bounding_points([[10.2, 5.6], [30.7, 20.4], [f64::NAN, 0.0]], 2.0, 32, 24);
    // x: 10.2 - 2 = 8.2 -> 8, 30.7 + 2 = 32.7 -> clipped to 31; y: 3.6 -> 4, 22.4 -> 22.
    assert_eq!(r, Some(Rect::from_inclusive(8, 4, 31, 22)));
    assert_eq!(Rect::bounding_points([[-50.0, -50.0]], 1.0, 32, 24), None);
}

/// Reusing a `Diminisher` and restricting to a known bbox gives the same result as a
/// one-shot fill; mask pixels outside the given bbox are ignored.
#[test]
fn diminisher_reuse_and_bbox() {
    let (w, h) = (160, 120);
    let truth = image_from_rgb(w, h, |x, y| wood(x, y, 1.0));
    let mut mask = blob(w, h, 60.0, 60.0, 20.0, 20.0);
    mask.set(150, 10, true); // a stray pixel far away
    let mut d = Diminisher::new();
    let bb = blob(w, h, 60.0, 60.0, 20.0, 20.0).bounding_box().unwrap();
    for _ in 0..2 {
        let mut a = truth.clone();
        paint(&mut a, &mask, PROP);
        let mut b = a.clone();
        let method = FillMethod::Rays(RayDirections::Sixteen);
        let sa = d.fill_in_bbox(&mut a, &mask, bb, &method).unwrap();
        assert_eq!(sa.bbox, Some(bb));
        assert_eq!(a.get(150, 10).map(|p| [p[0], p[1], p[2]]), Some(PROP));
        let mut only = mask.clone();
        only.set(150, 10, false);
        fill(&mut b, &only, &method).unwrap();
        assert_eq!(a, b);
    }
}

/// Hidden pixels (`Mask::HIDDEN`: the part of the mask something opaque will cover) are left
/// as they are, and every other pixel is filled exactly as if the whole mask were filled
/// (rays pass through hidden pixels): byte-identical outside the hidden set, for the ray fill
/// and the clean plate. A mask whose hidden part walls a pixel off from every known pixel
/// still fills (the hidden pixels are then filled too).
#[test]
fn hidden_pixels_are_skipped_without_changing_the_rest() {
    let (w, h) = (200, 150);
    let truth = image_from_rgb(w, h, |x, y| wood(x, y, 1.0));
    let mask = blob(w, h, 100.0, 75.0, 50.0, 40.0);
    // The hidden part: an inner blob.
    let inner = blob(w, h, 95.0, 78.0, 30.0, 22.0);
    let mut with_hidden = mask.clone();
    for y in 0..h {
        for x in 0..w {
            if inner.get(x, y) && mask.get(x, y) {
                with_hidden.as_mut_slice()[(y * w + x) as usize] = Mask::HIDDEN;
            }
        }
    }
    let plate = truth.clone();
    let methods = [
        FillMethod::Rays(RayDirections::Eight),
        FillMethod::Rays(RayDirections::Sixteen),
        FillMethod::CleanPlate(CleanPlate::new(&plate, Homography::identity())),
    ];
    for m in methods {
        let mut a = truth.clone();
        paint(&mut a, &mask, PROP);
        let mut b = a.clone();
        let sa = fill(&mut a, &mask, &m).unwrap();
        let sb = fill(&mut b, &with_hidden, &m).unwrap();
        let hidden = with_hidden
            .as_slice()
            .iter()
            .filter(|&&v| v == Mask::HIDDEN)
            .count();
        assert!(hidden > 1000);
        assert_eq!(sb.filled + hidden, sa.filled, "{m:?}");
        for y in 0..h {
            for x in 0..w {
                let i = (y * w + x) as usize;
                if with_hidden.as_slice()[i] == Mask::HIDDEN {
                    assert_eq!(b.get(x, y).unwrap()[..3], PROP, "hidden pixel written");
                } else {
                    assert_eq!(a.get(x, y), b.get(x, y), "{m:?} at ({x}, {y})");
                }
            }
        }
    }
    // A band across the whole image: the hidden rows wall the filled ones off from the known
    // pixels above and below except through the hidden rows themselves.
    let mut band = Mask::zeros(w, h).unwrap();
    for y in 40..110 {
        for x in 0..w {
            let v = if (60..90).contains(&y) {
                Mask::SET
            } else {
                Mask::HIDDEN
            };
            band.as_mut_slice()[(y * w + x) as usize] = v;
        }
    }
    let mut c = truth.clone();
    let stats = fill(&mut c, &band, &FillMethod::Rays(RayDirections::Eight)).unwrap();
    assert!(stats.filled >= 30 * w as usize);
}
