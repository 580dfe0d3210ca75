use super::*;

/// Linear light in [0, 1] -> sRGB-encoded 8 bits.
fn encode(v: f64) -> u8 {
    let c = if v <= 0.003_130_8 {
        12.92 * v
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    };
    (c * 255.0).round().clamp(0.0, 255.0) as u8
}

/// A frame showing a tag's black border square (outer corners `corners`, convex, in order)
/// with a white square inside it (the bits, one cell in) on white, in linear light:
/// 8x8 samples per pixel, then a Gaussian blur of `sigma_px`, then sRGB-encoded.
/// `cover` may paint pixels white over it afterwards (an occluder), in linear light.
fn render(
    corners: [DVec2; 4],
    size: u32,
    sigma_px: f64,
    cover: impl Fn(DVec2) -> bool,
) -> GrayImage {
    let n = size as usize;
    let centre = corners.iter().copied().sum::<DVec2>() / 4.0;
    let inner: Vec<DVec2> = corners
        .iter()
        .map(|&c| centre + (c - centre) * (6.0 / CELLS_ACROSS))
        .collect();
    let inside = |poly: &[DVec2], p: DVec2| {
        (0..4).all(|i| (poly[(i + 1) % 4] - poly[i]).perp_dot(p - poly[i]) >= 0.0)
    };
    let mut lin = vec![0.0f64; n * n];
    for y in 0..n {
        for x in 0..n {
            let mut white = 0.0;
            for sy in 0..8 {
                for sx in 0..8 {
                    let p = DVec2::new(
                        x as f64 - 0.5 + (sx as f64 + 0.5) / 8.0,
                        y as f64 - 0.5 + (sy as f64 + 0.5) / 8.0,
                    );
                    let black = inside(&corners, p) && !inside(&inner, p);
                    white += if black { 0.03 } else { 0.85 };
                }
            }
            lin[y * n + x] = white / 64.0;
        }
    }
    // Separable Gaussian blur, clamped at the border.
    let r = (3.0 * sigma_px).ceil() as i64;
    let k: Vec<f64> = (-r..=r)
        .map(|i| (-(i as f64).powi(2) / (2.0 * sigma_px * sigma_px)).exp())
        .collect();
    let ks: f64 = k.iter().sum();
    let blur = |src: &[f64], dx: i64, dy: i64| {
        let mut out = vec![0.0; n * n];
        for y in 0..n as i64 {
            for x in 0..n as i64 {
                let mut s = 0.0;
                for (j, w) in k.iter().enumerate() {
                    let o = j as i64 - r;
                    let xx = (x + o * dx).clamp(0, n as i64 - 1);
                    let yy = (y + o * dy).clamp(0, n as i64 - 1);
                    s += w * src[(yy * n as i64 + xx) as usize];
                }
                out[(y * n as i64 + x) as usize] = s / ks;
            }
        }
        out
    };
    let lin = blur(&blur(&lin, 1, 0), 0, 1);
    let data = (0..n * n)
        .map(|i| {
            let p = DVec2::new((i % n) as f64, (i / n) as f64);
            encode(if cover(p) { 0.85 } else { lin[i] })
        })
        .collect();
    GrayImage {
        width: size,
        height: size,
        data,
    }
}

/// A tilted quad (a square seen at an angle) with corners off the pixel grid.
fn tilted() -> [DVec2; 4] {
    [
        DVec2::new(20.3, 18.7),
        DVec2::new(61.9, 22.4),
        DVec2::new(58.6, 60.2),
        DVec2::new(17.1, 55.8),
    ]
}

/// Where the encoded frame's halfway grey lies: the quad shrunk by `inset_px` toward its
/// centre (what the binarised quad search finds, about).
fn shrunk(c: [DVec2; 4], inset_px: f64) -> [DVec2; 4] {
    let centre = c.iter().copied().sum::<DVec2>() / 4.0;
    c.map(|p| p + (centre - p).normalize() * inset_px)
}

fn max_error(a: &[DVec2; 4], b: &[DVec2; 4]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(p, q)| (*p - *q).length())
        .fold(0.0, f64::max)
}

#[test]
fn blurred_edges_are_found_where_they_are_in_linear_light() {
    let truth = tilted();
    let lut = decode_lut();
    for sigma in [0.5, 0.8, 1.2] {
        let img = render(truth, 80, sigma, |_| false);
        // The encoded midpoint lies inside the black border: start from a shrunk quad.
        let start = shrunk(truth, 0.3);
        let got = refine_corners(&img, lut, &start).expect("refined");
        let e = max_error(&got, &truth);
        println!(
            "sigma {sigma}: corner error {e:.4} px (start {:.3})",
            max_error(&start, &truth)
        );
        assert!(e < 0.04, "sigma {sigma}: {e}");
    }
}

#[test]
fn the_encoded_halfway_grey_lies_inside_the_border_and_the_refinement_undoes_it() {
    // Along one row across the left edge of an axis-aligned square at x = 20.375 (midway
    // between the render's samples, so that its coverage is exact): the encoded frame's
    // halfway crossing is more than 0.1 px inside (to the right), the refined corner within
    // 0.03 px.
    let truth = [
        DVec2::new(20.375, 20.375),
        DVec2::new(59.625, 20.375),
        DVec2::new(59.625, 59.625),
        DVec2::new(20.375, 59.625),
    ];
    let img = render(truth, 80, 0.8, |_| false);
    let row = &img.data[40 * 80..41 * 80];
    let (lo, hi) = (f64::from(row[24]), f64::from(row[10]));
    let mid = 0.5 * (lo + hi);
    let x = (10..24)
        .find(|&x| f64::from(row[x + 1]) < mid)
        .map(|x| {
            let (a, b) = (f64::from(row[x]), f64::from(row[x + 1]));
            x as f64 + (a - mid) / (a - b)
        })
        .expect("crossing");
    assert!(x > 20.375 + 0.1, "encoded crossing at {x}");
    let got = refine_corners(&img, decode_lut(), &shrunk(truth, 0.2)).expect("refined");
    assert!(max_error(&got, &truth) < 0.03, "{got:?}");
}

#[test]
fn an_edge_half_covered_by_an_occluder_still_gives_its_corners() {
    let truth = tilted();
    // A white blob over the middle of the top edge (a prop in front of the tag).
    let img = render(truth, 80, 0.8, |p| {
        (p - DVec2::new(45.0, 20.0)).length() < 5.0
    });
    let got = refine_corners(&img, decode_lut(), &shrunk(truth, 0.3)).expect("refined");
    let e = max_error(&got, &truth);
    assert!(e < 0.06, "{e}");
}

#[test]
fn a_tag_too_small_or_off_the_frame_keeps_its_corners() {
    let lut = decode_lut();
    let img = render(tilted(), 80, 0.8, |_| false);
    // A 10 px tag: half a cell is under the narrowest window.
    let small = [
        DVec2::new(30.0, 30.0),
        DVec2::new(40.0, 30.0),
        DVec2::new(40.0, 40.0),
        DVec2::new(30.0, 40.0),
    ];
    assert!(refine_corners(&img, lut, &small).is_none());
    // Off the frame: no edge has enough points inside it.
    let off = tilted().map(|p| p + DVec2::new(200.0, 0.0));
    assert!(refine_corners(&img, lut, &off).is_none());
    // A flat frame: no contrast anywhere.
    let flat = GrayImage::filled(80, 80, 128);
    assert!(refine_corners(&flat, lut, &tilted()).is_none());
    // NaN corners.
    let mut nan = tilted();
    nan[2] = DVec2::NAN;
    assert!(refine_corners(&img, lut, &nan).is_none());
}

#[test]
fn refine_all_leaves_a_wrongly_sized_image_alone() {
    let mut d = vec![Detection {
        family: crate::TagFamily::Tag36h11,
        id: 3,
        corners_px: tilted(),
        hamming: 0,
        decision_margin: 50.0,
    }];
    let bad = GrayImage {
        width: 80,
        height: 80,
        data: vec![0; 10],
    };
    refine_tag_corners(&bad, CornerRefinement::Srgb, &mut d);
    assert_eq!(d[0].corners_px, tilted());
}
