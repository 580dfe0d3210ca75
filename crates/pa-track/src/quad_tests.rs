//! The read of a quad at unrefined corners ([`may_decode`]).

use super::*;
use crate::TagFamily;

/// Pixels per cell of the painted tags: 50 px for the black square of a 36-bit tag, near the
/// smallest the decimated search finds.
const CELL: usize = 5;
/// Where the black square starts (pixels, both axes).
const ORIGIN: usize = 20;

/// A white image with the black square of `fam` at [`ORIGIN`] and `code`'s bits in it, laid
/// out as `read_code` reads them (bit 0 of the reading is the code's most significant).
fn paint(fam: &FamilyCodes, code: usize) -> (Vec<u8>, usize) {
    let side = 2 * ORIGIN + fam.width_at_border * CELL;
    let mut img = vec![255u8; side * side];
    let fill = |img: &mut Vec<u8>, cx: usize, cy: usize, v: u8| {
        for y in 0..CELL {
            let row = (ORIGIN + cy * CELL + y) * side + ORIGIN + cx * CELL;
            img[row..row + CELL].fill(v);
        }
    };
    for cy in 0..fam.width_at_border {
        for cx in 0..fam.width_at_border {
            fill(&mut img, cx, cy, 0);
        }
    }
    for i in 0..fam.nbits {
        let bit = (code >> (fam.nbits - 1 - i)) & 1;
        let (bx, by) = (fam.bit_x[i] as usize, fam.bit_y[i] as usize);
        fill(&mut img, bx, by, if bit == 1 { 255 } else { 0 });
    }
    (img, side)
}

/// The black square's corners in the reader's order, pixel edges at integers.
fn square(fam: &FamilyCodes) -> [DVec2; 4] {
    let (a, b) = (ORIGIN as f64, (ORIGIN + fam.width_at_border * CELL) as f64);
    [
        DVec2::new(a, a),
        DVec2::new(b, a),
        DVec2::new(b, b),
        DVec2::new(a, b),
    ]
}

fn may(fam: &FamilyCodes, img: &[u8], side: usize, corners: &[DVec2; 4]) -> bool {
    let h = Homography::from_quad(corners).expect("homography");
    may_decode(img, side, side, fam, &h, 0.25)
}

#[test]
fn a_tag_read_at_unrefined_corners_may_decode_and_far_codes_do_not() {
    let fam = FamilyCodes::new(TagFamily::Tag36h11.def(), 2);
    let code = fam.codes[7];
    let (img, side) = paint(&fam, code);
    let exact = square(&fam);
    let h = Homography::from_quad(&exact).expect("homography");
    // The painting is read back exactly.
    let read = read_code(&img, side, side, &fam, &h, 0.25).map(|(c, _)| c);
    assert_eq!(read, Some(code));
    assert_eq!(fam.nearest_hamming(code), 0);
    // Corners off by up to a pixel each way (a decimate-2 fit before refinement).
    let mut seed = 0x2545_F491_4F6C_DD1Du64;
    let mut next = || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        (seed >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    };
    for trial in 0..200 {
        let moved = exact.map(|p| p + DVec2::new(next(), next()));
        assert!(may(&fam, &img, side, &moved), "trial {trial}: {moved:?}");
    }
    // Codes k bits from the tag's: they may decode exactly when no code of the family is
    // more than max_hamming + UNREFINED_SLACK_BITS away.
    let limit = 2 + UNREFINED_SLACK_BITS;
    let mut rejected = 0;
    for k in 0..=12 {
        let flipped = (0..k).fold(code, |c, i| c ^ (1 << (3 * i)));
        let nearest = fam.nearest_hamming(flipped);
        if k <= 5 {
            // Tag36h11's codes are 11 bits apart: the tag's is the nearest.
            assert_eq!(nearest, k as u32, "{k} bits flipped");
        }
        let (img, side) = paint(&fam, flipped);
        let expected = nearest <= limit;
        assert_eq!(may(&fam, &img, side, &exact), expected, "{k} bits flipped");
        rejected += usize::from(!expected);
    }
    assert!(rejected >= 3, "only {rejected} of the far codes rejected");
}
