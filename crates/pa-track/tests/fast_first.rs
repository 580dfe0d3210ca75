//! The tracker's decimated search first (`TrackerConfig::fast_first`), against independent
//! truth: frames rendered from a known pose (`common::render`) of a board of large tags and
//! one small tag. Where the decimated search finds every tag the full passes could, the frame
//! costs that search alone, and its detections are exactly those of a decimated detector;
//! a small tag in view that it misses brings in the full passes; a small tag that the full
//! passes miss too (hidden) is looked for again every `FAST_RECHECK_DETECTIONS` frames.

mod common;

use common::*;
use glam::{DVec2, DVec3};
use pa_track::board::{Board, BoardTag};
use pa_track::{
    CornerRefinement, Detection, Detector, DetectorConfig, GrayImage, Pose, TagFamily, TrackTarget,
    Tracker, TrackerConfig, FAST_MIN_TAG_PX, FAST_RECHECK_DETECTIONS,
};

/// Id of the small tag.
const SMALL: u32 = 9;

/// A 2x3 grid of 50 mm tags (ids 0..6) and, beside it, one 8 mm tag.
fn board() -> Board {
    let mut b = Board::grid(TagFamily::Tag36h11, 2, 3, 0.05, 0.015, 0).expect("board");
    b.tags.push(BoardTag {
        id: SMALL,
        center_m: DVec2::new(0.125, 0.0),
        size_m: 0.008,
        rotation_rad: 0.0,
    });
    b
}

fn truth() -> Pose {
    view_pose(25.0, 8.0, 0.5, DVec3::new(-0.02, 0.0, 0.0))
}

fn frame(board: &Board) -> GrayImage {
    let scene = Scene {
        family: board.family,
        tags: board.tags.clone(),
        background: 90,
    };
    render(&camera_720p(), &scene, &truth(), 3)
}

/// The frame with the small tag painted over (table grey).
fn hidden(board: &Board, img: &GrayImage) -> GrayImage {
    let tag = board.tag(SMALL).expect("small tag");
    let c = project_tag(&camera_720p(), &truth(), tag);
    let (lo, hi) = c
        .iter()
        .fold((c[0], c[0]), |(lo, hi), p| (lo.min(*p), hi.max(*p)));
    let mut out = img.clone();
    for y in (lo.y - 6.0) as u32..=(hi.y + 6.0) as u32 {
        for x in (lo.x - 6.0) as u32..=(hi.x + 6.0) as u32 {
            out.data[(y * img.width + x) as usize] = 90;
        }
    }
    out
}

fn tracker(board: &Board, fast_first: bool) -> Tracker {
    Tracker::new(
        camera_720p(),
        TrackTarget::Board(board.clone()),
        DetectorConfig::default(),
        TrackerConfig {
            fast_first,
            // These tests tell which search ran by comparing the tracker's detections with a
            // detector's, corner for corner: the detector's corners as found.
            refine_corners: CornerRefinement::Off,
            ..TrackerConfig::per_still()
        },
    )
    .expect("tracker")
}

/// The decimated search of `fast_first` on its own.
fn decimated(img: &GrayImage) -> Vec<Detection> {
    Detector::new(DetectorConfig {
        fallback_decimate: None,
        ..DetectorConfig::fast()
    })
    .expect("detector")
    .detect(img)
    .expect("detect")
}

fn ids(d: &[Detection]) -> Vec<u32> {
    let mut v: Vec<u32> = d.iter().map(|d| d.id).collect();
    v.sort();
    v
}

fn same(a: &[Detection], b: &[Detection]) -> bool {
    a.len() == b.len()
        && a.iter().zip(b).all(|(p, q)| {
            p.id == q.id
                && p.corners_px
                    .iter()
                    .zip(&q.corners_px)
                    .all(|(u, v)| u.distance(*v) < 1e-9)
        })
}

fn rot_err_deg(p: &Pose) -> f64 {
    p.rotation_angle_to(&truth()).to_degrees()
}

#[test]
fn a_small_tag_in_view_brings_in_the_full_passes() {
    let board = board();
    let img = frame(&board);
    let side = {
        let c = project_tag(&camera_720p(), &truth(), board.tag(SMALL).expect("tag"));
        (0..4)
            .map(|i| c[i].distance(c[(i + 1) % 4]))
            .fold(f64::INFINITY, f64::min)
    };
    println!("small tag: {side:.1} px a side");
    assert!(side < FAST_MIN_TAG_PX, "{side}");
    // The premise: the decimated search misses it, the full passes find it.
    let fast = decimated(&img);
    assert_eq!(ids(&fast), [0, 1, 2, 3, 4, 5], "decimated search");
    let mut t = tracker(&board, true);
    let o = t.update(&img, 0.0).expect("update");
    assert!(o.detections.iter().any(|d| d.id == SMALL));
    let mut used = o.used_ids.clone();
    used.sort();
    assert_eq!(used, [0, 1, 2, 3, 4, 5, SMALL]);
    let err = rot_err_deg(&o.raw.expect("seen").pose);
    println!("fast first, full passes: {err:.4} deg");
    assert!(err < 0.1, "{err}");
}

#[test]
fn large_tags_alone_cost_the_decimated_search_only() {
    // The same board without the small tag: every tag is large.
    let mut board = board();
    board.tags.retain(|t| t.id != SMALL);
    let img = frame(&board);
    let fast = decimated(&img);
    let mut on = tracker(&board, true);
    let a = on.update(&img, 0.0).expect("update");
    assert!(
        same(&a.detections, &fast),
        "not the decimated search's detections"
    );
    let mut off = tracker(&board, false);
    let b = off.update(&img, 0.0).expect("update");
    assert!(
        !same(&b.detections, &fast),
        "the full passes give other corners"
    );
    let (ea, eb) = (
        rot_err_deg(&a.raw.expect("seen").pose),
        rot_err_deg(&b.raw.expect("seen").pose),
    );
    println!("rotation error: decimated first {ea:.4} deg, full passes {eb:.4} deg");
    assert!(ea < 0.1 && eb < 0.1, "{ea} {eb}");
}

#[test]
fn a_hidden_small_tag_is_looked_for_again_at_each_recheck() {
    let board = board();
    let seen = frame(&board);
    let covered = hidden(&board, &seen);
    let mut t = tracker(&board, true);
    // First frame: the small tag is hidden; the full passes run (nothing known yet) and miss
    // it too.
    let o = t.update(&covered, 0.0).expect("update");
    assert!(!o.used_ids.contains(&SMALL));
    // It shows again, but until the recheck the decimated search alone runs (and cannot
    // find it): exactly its detections.
    let fast = decimated(&seen);
    for i in 1..=FAST_RECHECK_DETECTIONS {
        let o = t.update(&seen, i as f64 / 24.0).expect("update");
        assert!(same(&o.detections, &fast), "frame {i}");
        assert!(!o.used_ids.contains(&SMALL), "frame {i}");
    }
    // The recheck: the full passes find it.
    let o = t
        .update(&seen, (FAST_RECHECK_DETECTIONS + 1) as f64 / 24.0)
        .expect("update");
    assert!(o.used_ids.contains(&SMALL), "{:?}", o.used_ids);
    // And from then on it is looked for (not hidden): the full passes run every frame.
    let o = t.update(&seen, 1.0).expect("update");
    assert!(o.used_ids.contains(&SMALL), "{:?}", o.used_ids);
}
