use super::*;
use crate::metrics::psnr_rgb;

/// A textured table (wood-like grain plus a fine hash noise), sRGB.
fn table(w: u32, h: u32) -> ImageRgba8 {
    ImageRgba8::from_fn(w, h, |x, y| {
        let (xf, yf) = (x as f32, y as f32);
        let grain = 0.5 + 0.18 * (0.31 * xf + 2.5 * (0.043 * yf).sin()).sin();
        let n = ((x.wrapping_mul(73_856_093) ^ y.wrapping_mul(19_349_663)) % 1000) as f32 / 1000.0;
        let v = (grain + 0.08 * (n - 0.5)).clamp(0.0, 1.0);
        [
            (255.0 * v) as u8,
            (255.0 * 0.8 * v) as u8,
            (255.0 * 0.55 * v) as u8,
            255,
        ]
    })
    .expect("image")
}

/// A quadrilateral shadow (two triangles) in a 160x120 frame.
fn quad() -> Vec<[[f32; 2]; 3]> {
    let (a, b, c, d) = ([40.0, 30.0], [110.0, 42.0], [118.0, 90.0], [52.0, 84.0]);
    vec![[a, b, c], [a, c, d]]
}

#[test]
fn triangles_cover_pixel_centres_inside() {
    // The square [10, 20] x [10, 20]: centres on the edges are in, 11 x 11 pixels.
    let t = vec![
        [[10.0, 10.0], [20.0, 10.0], [20.0, 20.0]],
        [[10.0, 10.0], [20.0, 20.0], [10.0, 20.0]],
    ];
    let m = ShadowMatte::from_triangles(&t, 3, 64, 48).expect("matte");
    assert_eq!(m.rect(), Rect::new(7, 7, 17, 17));
    assert_eq!(m.area(), 121.0);
    assert_eq!(m.at(10, 10), 1.0);
    assert_eq!(m.at(9, 15), 0.0);
    assert_eq!(m.at(21, 15), 0.0);
    // Winding does not matter.
    let flipped: Vec<_> = t.iter().map(|t| [t[0], t[2], t[1]]).collect();
    assert_eq!(
        ShadowMatte::from_triangles(&flipped, 3, 64, 48)
            .expect("matte")
            .area(),
        121.0
    );
    // Entirely outside the frame: no matte.
    let far = vec![[[-50.0, -50.0], [-40.0, -50.0], [-40.0, -40.0]]];
    assert!(ShadowMatte::from_triangles(&far, 0, 64, 48).is_none());
}

#[test]
fn soften_is_a_gaussian_of_the_given_deviation() {
    let mut w = vec![0.0f32; 81 * 81];
    w[40 * 81 + 40] = 1.0;
    let m = ShadowMatte::new(Rect::new(0, 0, 81, 81), w, 81, 81).expect("matte");
    for sigma in [1.5f32, 3.0, 6.0] {
        let s = m.soften(sigma).expect("soften");
        let (mut sum, mut var) = (0.0f64, 0.0f64);
        for y in 0..81u32 {
            for x in 0..81u32 {
                let v = f64::from(s.at(x, y));
                sum += v;
                var += v * (f64::from(x) - 40.0).powi(2);
            }
        }
        let got = (var / sum).sqrt();
        assert!((sum - 1.0).abs() < 1e-4, "mass {sum}");
        // Box passes of whole widths: within 15 % of the deviation asked for.
        assert!(
            (got - f64::from(sigma)).abs() < 0.15 * f64::from(sigma),
            "sigma {sigma}: got {got}"
        );
    }
    assert!(m.soften(-1.0).is_err());
    assert!(m.soften(f32::NAN).is_err());
}

#[test]
fn bad_matte_is_refused() {
    assert!(ShadowMatte::new(Rect::new(0, 0, 4, 4), vec![0.0; 15], 8, 8).is_err());
    assert!(ShadowMatte::new(Rect::new(6, 6, 4, 4), vec![0.0; 16], 8, 8).is_err());
    assert!(ShadowMatte::new(Rect::new(0, 0, 0, 0), vec![], 0, 8).is_err());
    let m = ShadowMatte::new(Rect::new(0, 0, 4, 4), vec![1.0; 16], 8, 8).expect("matte");
    let mut wrong = ImageRgba8::filled(9, 8, [9; 4]).expect("image");
    assert!(lift_shadow(&mut wrong, &m, [0.5; 3]).is_err());
    let mut ok = ImageRgba8::filled(8, 8, [9; 4]).expect("image");
    assert!(cast_shadow(&mut ok, &m, [f32::NAN; 3]).is_err());
}

/// The analytic case: a textured table under a known soft shadow (a quadrilateral blurred by
/// a Gaussian of 3 px, keeping 45/50/60 % of the light per channel). The measured ratio is
/// within 0.08 of the truth's, the softness within a factor of two, and lifting restores the table: PSNR against the unshadowed
/// table (over the shadow) above 35 dB, where the shadowed frame is below 22 dB.
#[test]
fn measured_lift_restores_a_known_soft_shadow() {
    let (w, h) = (160, 120);
    let truth = table(w, h);
    let hard = ShadowMatte::from_triangles(&quad(), 24, w, h).expect("matte");
    let soft = hard.soften(3.0).expect("soften");
    let ratio = [0.45, 0.5, 0.6];
    let mut shadowed = truth.clone();
    cast_shadow(&mut shadowed, &soft, ratio).expect("cast");

    let measured = measure_shadow(&shadowed, &soft, None)
        .expect("measure")
        .expect("a measurable shadow");
    for c in 0..3 {
        assert!(
            (measured.rgb[c] - ratio[c]).abs() < 0.08,
            "channel {c}: measured {:?} vs {ratio:?}",
            measured.rgb
        );
    }
    let (sigma, fitted) = fit_softness(&shadowed, &hard, &[0.5, 1.5, 3.0, 6.0, 10.0], None)
        .expect("fit")
        .expect("a softness");
    // Texture disturbs the penumbra's profile: the fit is good to a factor of two.
    assert!(
        (1.5..=6.0).contains(&sigma),
        "softness {sigma} for a truth of 3"
    );

    // Measured over the shadow and its penumbra (the rest of the frame is untouched).
    let region = Mask::from_fn(w, h, |x, y| soft.at(x, y) > 0.01).expect("mask");
    let before = psnr_rgb(&truth, &shadowed, Some(&region)).expect("psnr");
    let mut lifted = shadowed.clone();
    lift_shadow(
        &mut lifted,
        &hard.soften(sigma).expect("soften"),
        fitted.rgb,
    )
    .expect("lift");
    let after = psnr_rgb(&truth, &lifted, Some(&region)).expect("psnr");
    println!(
        "shadowed {before:.1} dB, lifted {after:.1} dB, ratio {:?}",
        fitted.rgb
    );
    assert!(before < 22.0, "shadowed {before}");
    assert!(after > before + 15.0, "lifted {after} vs shadowed {before}");
    assert!(after > 35.0, "lifted {after}");
}

#[test]
fn lift_undoes_cast_and_excluded_pixels_are_not_measured() {
    let (w, h) = (160, 120);
    let truth = table(w, h);
    let mut soft = ShadowMatte::from_triangles(&quad(), 10, w, h)
        .expect("matte")
        .soften(2.0)
        .expect("soften");
    let mut img = truth.clone();
    cast_shadow(&mut img, &soft, [0.3, 0.3, 0.3]).expect("cast");
    lift_shadow(&mut img, &soft, [0.3, 0.3, 0.3]).expect("lift");
    // 8-bit quantisation in the shadow, amplified by at most 1 / 0.3.
    let max_err = truth
        .as_slice()
        .iter()
        .zip(img.as_slice())
        .map(|(a, b)| a.abs_diff(*b))
        .max()
        .unwrap_or(0);
    assert!(max_err <= 4, "round trip error {max_err}");

    // Excluding the whole umbra leaves too few shadow samples to measure.
    let umbra = Mask::from_fn(w, h, |x, y| soft.at(x, y) >= UMBRA_WEIGHT).expect("mask");
    assert_eq!(measure_shadow(&img, &soft, Some(&umbra)).expect("m"), None);
    // An excluded mask zeroes the matte there.
    soft.exclude(&umbra).expect("exclude");
    assert!(soft.weights().iter().all(|&w| w < UMBRA_WEIGHT));
}

/// Paper printed with black squares of 14 px every 24 px (a board of small tags), sRGB.
fn print(w: u32, h: u32) -> ImageRgba8 {
    ImageRgba8::from_fn(w, h, |x, y| {
        if black_at(x as i64, y as i64) {
            [12, 12, 12, 255]
        } else {
            [232, 230, 224, 255]
        }
    })
    .expect("image")
}

fn black_at(x: i64, y: i64) -> bool {
    (x + 5).rem_euclid(24) < 14 && (y + 3).rem_euclid(24) < 14
}

/// The outline fit recovers a known penumbra and darkening where the medians cannot: on a
/// wood-like table the softness within one candidate and the ratio within 0.03; on print
/// (black squares across the shadow's outline), with the print known, the same, where
/// the medians of the region against its ring are thrown by the print. No edge: no
/// darkening (a ratio above 0.8).
#[test]
fn outline_fit_recovers_softness_and_darkening_on_texture_and_print() {
    let (w, h) = (160, 120);
    let hard = ShadowMatte::from_triangles(&quad(), 24, w, h).expect("matte");
    let candidates = [0.75, 1.5, 3.0, 6.0, 10.0];
    let ratio = [0.45, 0.5, 0.6];
    let y = |r: [f32; 3]| 0.2126 * r[0] + 0.7152 * r[1] + 0.0722 * r[2];
    // A square's edge and its 3x3 neighbourhood are one print.
    let same_print = |a: [u32; 2], b: [u32; 2]| {
        let class = |[x, y]: [u32; 2]| {
            let c = black_at(i64::from(x), i64::from(y));
            let one = (-1..=1)
                .all(|dy| (-1..=1).all(|dx| black_at(i64::from(x) + dx, i64::from(y) + dy) == c));
            one.then_some(c)
        };
        matches!((class(a), class(b)), (Some(p), Some(q)) if p == q)
    };
    for (name, lit, same) in [
        ("wood", table(w, h), None),
        ("print", print(w, h), Some(&same_print as SameSurface<'_>)),
    ] {
        let mut shadowed = lit.clone();
        cast_shadow(&mut shadowed, &hard.soften(3.0).expect("soften"), ratio).expect("cast");
        let fit = fit_outline(&shadowed, &hard, &candidates, None, same)
            .expect("fit")
            .expect("the outline in view");
        let medians = fit_softness(&shadowed, &hard, &candidates, None).expect("medians");
        println!("{name}: outline fit {fit:?}; medians {medians:?}");
        // Periodic grain biases pairs a fixed distance apart: good to a factor of two.
        assert!((1.5..=6.0).contains(&fit.softness_px), "{name}: {fit:?}");
        assert!(
            (y(fit.ratio.rgb) - y(ratio)).abs() < 0.03,
            "{name}: {fit:?}"
        );
        for (got, want) in fit.ratio.rgb.iter().zip(ratio) {
            assert!((got - want).abs() < 0.06, "{name}: {fit:?}");
        }
        let flat = fit_outline(&lit, &hard, &candidates, None, same)
            .expect("fit")
            .expect("the outline in view");
        // The grain's stripes give pairs a few pixels apart a ratio of their own (0.87 here):
        // still far from a shadow's.
        assert!(y(flat.ratio.rgb) > 0.8, "{name}, no shadow: {flat:?}");
    }
}
