use glam::{DQuat, DVec2, DVec3};
use pa_track::{Detection, Pose, PoseCandidate, TagFamily, TrackEvent, TrackOutput, TrackState};

use super::*;

fn detection() -> Detection {
    Detection {
        family: TagFamily::Tag36h11,
        id: 3,
        corners_px: [
            DVec2::new(10.123456, 20.0),
            DVec2::new(30.0, 20.00004),
            DVec2::new(30.0, 40.0),
            DVec2::new(10.0, 40.0),
        ],
        hamming: 1,
        decision_margin: 42.125,
    }
}

fn pose() -> Pose {
    Pose {
        rotation: DQuat::from_xyzw(0.0, 0.0, 0.0, 1.0),
        translation: DVec3::new(0.1, -0.023456789, 1.5),
    }
}

#[test]
fn names_are_pinned() {
    let states = [
        TrackState::Searching,
        TrackState::Detected,
        TrackState::Tracked,
        TrackState::Lost,
    ];
    let names: Vec<_> = states.into_iter().map(state_name).collect();
    assert_eq!(names, ["searching", "detected", "tracked", "lost"]);
    let events = [
        TrackEvent::Found,
        TrackEvent::Tracked,
        TrackEvent::Dropped,
        TrackEvent::Lost,
        TrackEvent::Recovered,
        TrackEvent::SearchRestarted,
    ];
    let names: Vec<_> = events.into_iter().map(event_name).collect();
    assert_eq!(
        names,
        [
            "found",
            "tracked",
            "dropped",
            "lost",
            "recovered",
            "search_restarted"
        ]
    );
}

#[test]
fn round_keeps_the_digits() {
    assert_eq!(round(1.23456, 2), 1.23);
    assert_eq!(round(-0.0000051, 5), -0.00001);
    assert_eq!(round(2.5, 0), 3.0);
}

#[test]
fn pose_json_is_pinned() {
    let s = serde_json::to_string(&pose_json(&pose(), Some(0.123456))).unwrap();
    assert_eq!(
        s,
        r#"{"reprojection_rms_px":0.1235,"rotation_xyzw":[0.0,0.0,0.0,1.0],"translation_m":[0.1,-0.0234568,1.5]}"#
    );
    let s = serde_json::to_string(&pose_json(&pose(), None)).unwrap();
    assert!(!s.contains("reprojection_rms_px"));
}

#[test]
fn detection_json_is_pinned() {
    let s = serde_json::to_string(&detection_json(&detection())).unwrap();
    assert_eq!(
        s,
        r#"{"corners_px":[[10.1235,20.0],[30.0,20.0],[30.0,40.0],[10.0,40.0]],"decision_margin":42.13,"family":"tag36h11","hamming":1,"id":3}"#
    );
}

#[test]
fn frame_json_is_pinned() {
    let out = TrackOutput {
        state: TrackState::Tracked,
        events: vec![TrackEvent::Found, TrackEvent::Tracked],
        pose: Some(pose()),
        raw: Some(PoseCandidate {
            pose: pose(),
            rms_px: 0.25,
        }),
        coasting: false,
        detections: vec![detection()],
        used_ids: vec![3],
        used_roi: true,
        target_corners_px: None,
    };
    let s = serde_json::to_string(&frame_json(7, "a.png", 640, 480, &out, 1.23456)).unwrap();
    assert_eq!(
        s,
        concat!(
            r#"{"coasting":false,"detections":[{"corners_px":[[10.1235,20.0],[30.0,20.0],[30.0,40.0],[10.0,40.0]],"decision_margin":42.13,"family":"tag36h11","hamming":1,"id":3}],"#,
            r#""events":["found","tracked"],"file":"a.png","frame":7,"height":480,"#,
            r#""measured_pose":{"camera_from_marker":{"reprojection_rms_px":0.25,"rotation_xyzw":[0.0,0.0,0.0,1.0],"translation_m":[0.1,-0.0234568,1.5]}},"#,
            r#""pose":{"camera_from_marker":{"rotation_xyzw":[0.0,0.0,0.0,1.0],"translation_m":[0.1,-0.0234568,1.5]},"reprojection_rms_px":0.25},"#,
            r#""state":"tracked","time_ms":1.235,"used_ids":[3],"used_roi":true,"width":640}"#
        )
    );
    let empty = TrackOutput {
        state: TrackState::Searching,
        events: vec![],
        pose: None,
        raw: None,
        coasting: false,
        detections: vec![],
        used_ids: vec![],
        used_roi: false,
        target_corners_px: None,
    };
    let s = serde_json::to_string(&frame_json(0, "b.png", 0, 0, &empty, 0.0)).unwrap();
    assert_eq!(
        s,
        r#"{"coasting":false,"detections":[],"events":[],"file":"b.png","frame":0,"height":0,"measured_pose":null,"pose":null,"state":"searching","time_ms":0.0,"used_ids":[],"used_roi":false,"width":0}"#
    );
}
