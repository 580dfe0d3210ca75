//! Unit tests of the patch fill's parts: the generator, the pyramid's states and the
//! onion-peel start. The fill's behaviour end to end is tested in `tests/patch_fill.rs`.

use super::pyramid::{build, onion_peel, Level, HIDDEN, HOLE, KNOWN};
use super::search::Rng;
use crate::types::{ImageRgba8, Rect};

#[test]
fn the_generator_is_uniform_and_deterministic() {
    let mut a = Rng::new(7);
    let mut b = Rng::new(7);
    let mut counts = [0usize; 10];
    for _ in 0..10_000 {
        let x = a.below(10);
        assert_eq!(x, b.below(10));
        counts[x] += 1;
    }
    // Each bucket expects 1000; 4 sigma is about 120.
    for c in counts {
        assert!((880..=1120).contains(&c), "{counts:?}");
    }
    assert_ne!(Rng::new(1).next_u64(), Rng::new(2).next_u64());
}

#[test]
fn coarse_levels_mark_a_hole_where_any_child_is_one() {
    let img = ImageRgba8::from_fn(40, 40, |x, _| [(x * 6) as u8, 0, 0, 255]).expect("image");
    let mut levels: Vec<Level> = Vec::new();
    // One hole pixel at (21, 21), a hidden pixel at (10, 10).
    let state = |x: usize, y: usize| match (x, y) {
        (21, 21) => HOLE,
        (10, 10) => HIDDEN,
        _ => KNOWN,
    };
    build(
        &mut levels,
        &img,
        Rect::new(0, 0, 40, 40),
        state,
        None,
        None,
        0,
        4,
    );
    // Hole extent 1 <= 4: a single level.
    assert_eq!(levels.len(), 1);
    assert_eq!(levels[0].holes, [21 * 40 + 21]);
    assert_eq!(levels[0].known, 40 * 40 - 2);
    assert_eq!(
        levels[0].sources.len(),
        40 * 40 - 2,
        "the coarsest level lists its sources"
    );
    // A 30-pixel-wide hole band: levels until its extent is at most 4 (30 -> 15 -> 8 -> 4).
    let state = |x: usize, y: usize| {
        if (5..35).contains(&x) && y == 20 {
            HOLE
        } else {
            KNOWN
        }
    };
    build(
        &mut levels,
        &img,
        Rect::new(0, 0, 40, 40),
        state,
        None,
        None,
        0,
        4,
    );
    assert_eq!(levels.len(), 4);
    let l1 = &levels[1];
    assert_eq!((l1.w, l1.h), (20, 20));
    // Children (4..6, 20..22) hold holes at x = 5 only: the parent (2, 10) is a hole.
    assert_eq!(l1.state[10 * 20 + 2], HOLE);
    assert_eq!(l1.state[10 * 20 + 1], KNOWN);
    // A known parent's colour is its children's mean: red 6 * (2 + 3) / 2 = 15 at x = 1.
    assert!((l1.color[10 * 20 + 1][0] - 15.0).abs() < 1e-4);
}

#[test]
fn onion_peel_reaches_every_hole_and_reports_cut_off_ones() {
    let img = ImageRgba8::filled(9, 9, [90, 30, 10, 255]).expect("image");
    let mut levels: Vec<Level> = Vec::new();
    let state = |x: usize, y: usize| {
        if (2..7).contains(&x) && (2..7).contains(&y) {
            HOLE
        } else {
            KNOWN
        }
    };
    build(
        &mut levels,
        &img,
        Rect::new(0, 0, 9, 9),
        state,
        None,
        None,
        0,
        16,
    );
    assert!(onion_peel(&mut levels[0]));
    for &p in &levels[0].holes {
        assert_eq!(levels[0].color[p as usize], [90.0, 30.0, 10.0]);
    }
    // A hole inside a ring of hidden pixels cannot be reached.
    let state = |x: usize, y: usize| match (x.abs_diff(4), y.abs_diff(4)) {
        (0, 0) => HOLE,
        (a, b) if a.max(b) == 1 => HIDDEN,
        _ => KNOWN,
    };
    build(
        &mut levels,
        &img,
        Rect::new(0, 0, 9, 9),
        state,
        None,
        None,
        0,
        16,
    );
    assert!(!onion_peel(&mut levels[0]));
}
