//! Tracking state machine, board occlusion and region-of-interest search.

mod common;

use common::*;
use glam::DVec3;
use pa_track::{
    Board, Detection, DetectorConfig, GrayImage, TagFamily, TrackEvent, TrackState, TrackTarget,
    Tracker, TrackerConfig,
};

fn detections_for(board: &Board, ids: &[u32], pose: &pa_track::Pose) -> Vec<Detection> {
    let cam = camera_720p();
    ids.iter()
        .map(|id| Detection {
            family: board.family,
            id: *id,
            corners_px: project_tag(&cam, pose, board.tag(*id).expect("id on board")),
            hamming: 0,
            decision_margin: 100.0,
        })
        .collect()
}

#[test]
fn state_machine_transitions_with_hysteresis() {
    let board = Board::single(TagFamily::Tag36h11, 3, 0.1);
    let config = TrackerConfig {
        frames_to_track: 3,
        frames_to_lose: 4,
        frames_to_search: 5,
        ..Default::default()
    };
    let mut tr = Tracker::new(
        camera_720p(),
        TrackTarget::Board(board.clone()),
        DetectorConfig::default(),
        config,
    )
    .expect("tracker");
    let pose = view_pose(30.0, 20.0, 0.8, DVec3::ZERO);
    let seen = || detections_for(&board, &[3], &pose);
    let mut t = 0.0;
    let mut step = |tr: &mut Tracker, d: Vec<Detection>| {
        t += 1.0 / 30.0;
        tr.update_with_detections(d, t).expect("update")
    };
    // Nothing: Searching, no error.
    let o = step(&mut tr, vec![]);
    assert_eq!((o.state, o.events.clone()), (TrackState::Searching, vec![]));
    // Seen once, then gone before N frames: Dropped back to Searching.
    assert_eq!(step(&mut tr, seen()).events, vec![TrackEvent::Found]);
    let o = step(&mut tr, vec![]);
    assert_eq!(
        (o.state, o.events),
        (TrackState::Searching, vec![TrackEvent::Dropped])
    );
    // Seen N = 3 frames: Found, then Tracked on the third.
    assert_eq!(step(&mut tr, seen()).state, TrackState::Detected);
    assert_eq!(step(&mut tr, seen()).state, TrackState::Detected);
    let o = step(&mut tr, seen());
    assert_eq!(
        (o.state, o.events.clone()),
        (TrackState::Tracked, vec![TrackEvent::Tracked])
    );
    let p = o.pose.expect("pose while tracked");
    assert!(p.rotation_angle_to(&pose).to_degrees() < 0.01);
    // Missing M - 1 = 3 frames: still Tracked, coasting on the last pose.
    for _ in 0..3 {
        let o = step(&mut tr, vec![]);
        assert_eq!(o.state, TrackState::Tracked);
        assert!(o.coasting && o.pose.is_some());
    }
    // The M-th missing frame: Lost, no pose.
    let o = step(&mut tr, vec![]);
    assert_eq!(
        (o.state, o.events.clone()),
        (TrackState::Lost, vec![TrackEvent::Lost])
    );
    assert!(o.pose.is_none());
    // Reappears: Recovered straight to Tracked.
    let o = step(&mut tr, seen());
    assert_eq!(
        (o.state, o.events),
        (TrackState::Tracked, vec![TrackEvent::Recovered])
    );
    // Gone for M + K frames: Lost, then Searching.
    let mut events = Vec::new();
    for _ in 0..(4 + 5) {
        events.extend(step(&mut tr, vec![]).events);
    }
    assert_eq!(events, vec![TrackEvent::Lost, TrackEvent::SearchRestarted]);
    assert_eq!(tr.state(), TrackState::Searching);
}

#[test]
fn partly_occluded_board_stays_tracked() {
    let board = Board::grid(TagFamily::Tag36h11, 2, 3, 0.04, 0.01, 10).expect("grid");
    assert_eq!(board.tags.len(), 6);
    assert_eq!(board.tags[0].id, 10);
    // Top-left tag is left of and above the origin (+X right, +Y down the page).
    assert!(board.tags[0].center_m.x < 0.0 && board.tags[0].center_m.y < 0.0);
    let mut tr = Tracker::new(
        camera_720p(),
        TrackTarget::Board(board.clone()),
        DetectorConfig::default(),
        TrackerConfig {
            frames_to_track: 2,
            ..Default::default()
        },
    )
    .expect("tracker");
    let pose = view_pose(40.0, -15.0, 0.6, DVec3::new(0.02, 0.01, 0.0));
    let all: Vec<u32> = (10..16).collect();
    for (i, ids) in [
        all.clone(),
        all.clone(),
        vec![10, 15],
        vec![12],
        vec![11, 13, 14],
    ]
    .iter()
    .enumerate()
    {
        let mut dets = detections_for(&board, ids, &pose);
        // A tag of another family/id is ignored.
        dets.push(Detection {
            id: 99,
            ..dets[0].clone()
        });
        let o = tr
            .update_with_detections(dets, i as f64 / 30.0)
            .expect("update");
        if i >= 1 {
            assert_eq!(o.state, TrackState::Tracked, "frame {i} ids {ids:?}");
            assert!(!o.coasting);
            let raw = o.raw.expect("seen");
            assert!(raw.pose.rotation_angle_to(&pose).to_degrees() < 0.01);
            assert!((raw.pose.translation - pose.translation).length() < 1e-5);
            let mut used = o.used_ids.clone();
            used.sort();
            assert_eq!(&used, ids);
        }
    }
}

#[test]
fn tracks_rendered_frames_with_roi_and_handles_empty_frames() {
    let cam = camera_720p();
    let scene = Scene {
        family: TagFamily::Tag36h11,
        tags: vec![pa_track::board::BoardTag {
            id: 5,
            center_m: glam::DVec2::ZERO,
            size_m: 0.08,
            rotation_rad: 0.0,
        }],
        background: 110,
    };
    let mut tr = Tracker::new(
        cam,
        TrackTarget::Tag {
            family: TagFamily::Tag36h11,
            id: 5,
            size_m: 0.08,
        },
        DetectorConfig::default(),
        TrackerConfig::default(),
    )
    .expect("tracker");
    let empty = GrayImage::filled(1280, 720, 110);
    let o = tr.update(&empty, 0.0).expect("empty frame is fine");
    assert_eq!(o.state, TrackState::Searching);
    assert!(o.detections.is_empty() && o.pose.is_none());
    let mut roi_frames = 0;
    for i in 0..8 {
        let t = (i + 1) as f64 / 30.0;
        // Moving sideways at 0.3 m/s, turning slowly.
        let truth = view_pose(
            35.0,
            5.0 + 3.0 * i as f64,
            0.7,
            DVec3::new(-0.1 + 0.01 * i as f64, 0.0, 0.0),
        );
        let img = render(&cam, &scene, &truth, 2);
        let o = tr.update(&img, t).expect("update");
        let raw = o.raw.expect("tag seen");
        assert!(
            raw.pose.rotation_angle_to(&truth).to_degrees() < 1.0,
            "frame {i}"
        );
        if o.used_roi {
            roi_frames += 1;
        }
        if i >= 2 {
            assert_eq!(o.state, TrackState::Tracked);
            let p = o.pose.expect("filtered pose");
            assert!(
                (p.translation - truth.translation).length() < 0.01,
                "frame {i}"
            );
        }
    }
    assert!(roi_frames >= 6, "ROI used on {roi_frames} of 8 frames");
}
