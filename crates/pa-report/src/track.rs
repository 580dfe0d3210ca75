//! The JSON lines of `propsalive track`: one record per frame (state, events, detections, the
//! filtered and the measured pose), with the numbers rounded so that the lines are stable
//! across platforms. Pure: the caller times the frame and writes the lines.

use pa_track::{Detection, Pose, TrackEvent, TrackOutput, TrackState};
use serde_json::{json, Value};

/// The tracking state as the JSON names it: `searching`, `detected`, `tracked`, `lost`.
pub fn state_name(s: TrackState) -> &'static str {
    match s {
        TrackState::Searching => "searching",
        TrackState::Detected => "detected",
        TrackState::Tracked => "tracked",
        TrackState::Lost => "lost",
    }
}

/// A tracker event as the JSON names it (`found`, `tracked`, `dropped`, `lost`, `recovered`,
/// `search_restarted`).
pub fn event_name(e: TrackEvent) -> &'static str {
    match e {
        TrackEvent::Found => "found",
        TrackEvent::Tracked => "tracked",
        TrackEvent::Dropped => "dropped",
        TrackEvent::Lost => "lost",
        TrackEvent::Recovered => "recovered",
        TrackEvent::SearchRestarted => "search_restarted",
    }
}

/// `v` rounded to `digits` decimals.
pub fn round(v: f64, digits: i32) -> f64 {
    let s = 10f64.powi(digits);
    (v * s).round() / s
}

/// A pose as `rotation_xyzw` (8 decimals) and `translation_m` (7), plus
/// `reprojection_rms_px` (4) when given.
pub fn pose_json(p: &Pose, rms: Option<f64>) -> Value {
    let q = p.rotation;
    let t = p.translation;
    let mut v = json!({
        "rotation_xyzw": [round(q.x, 8), round(q.y, 8), round(q.z, 8), round(q.w, 8)],
        "translation_m": [round(t.x, 7), round(t.y, 7), round(t.z, 7)],
    });
    if let Some(r) = rms {
        v["reprojection_rms_px"] = json!(round(r, 4));
    }
    v
}

/// One detection: `family`, `id`, `corners_px` (4 decimals), `hamming`, `decision_margin`.
pub fn detection_json(d: &Detection) -> Value {
    json!({
        "family": d.family.name(),
        "id": d.id,
        "corners_px": d.corners_px.iter().map(|c| [round(c.x, 4), round(c.y, 4)]).collect::<Vec<_>>(),
        "hamming": d.hamming,
        "decision_margin": round(d.decision_margin as f64, 2),
    })
}

/// One frame's JSON record.
pub fn frame_json(index: usize, file: &str, w: u32, h: u32, out: &TrackOutput, ms: f64) -> Value {
    let rms = out.raw.map(|r| r.rms_px);
    json!({
        "frame": index,
        "file": file,
        "width": w,
        "height": h,
        "state": state_name(out.state),
        "events": out.events.iter().map(|e| event_name(*e)).collect::<Vec<_>>(),
        "detections": out.detections.iter().map(detection_json).collect::<Vec<_>>(),
        "pose": out.pose.map(|p| {
            let mut v = json!({ "camera_from_marker": pose_json(&p, None) });
            v["reprojection_rms_px"] = rms.map(|r| json!(round(r, 4))).unwrap_or(Value::Null);
            v
        }),
        "measured_pose": out.raw.map(|r| json!({ "camera_from_marker": pose_json(&r.pose, Some(r.rms_px)) })),
        "used_ids": out.used_ids,
        "coasting": out.coasting,
        "used_roi": out.used_roi,
        "time_ms": round(ms, 3),
    })
}

#[cfg(test)]
mod tests;
