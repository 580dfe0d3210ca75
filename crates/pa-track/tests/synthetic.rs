//! Synthetic accuracy: tags rendered on the CPU from known poses (supersampled inverse
//! mapping), optionally blurred and noisy; pose errors against the truth.

mod common;

use common::*;
use glam::{DVec2, DVec3};
use pa_track::board::BoardTag;
use pa_track::{estimate_tag_pose, Detector, DetectorConfig, TagFamily};

const TAG_M: f64 = 0.1;

fn median(v: &mut [f64]) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

#[test]
fn pose_accuracy_table() {
    let cam = camera_720p();
    let f = cam.intrinsics.fx;
    let sizes_px = [40.0, 80.0, 160.0, 400.0];
    let tilts = [0.0, 30.0, 50.0, 70.0];
    let yaws = [10.0, 100.0, 215.0];
    let mut det = Detector::new(DetectorConfig::default()).expect("detector");
    let mut rng = Rng(0x5EED);
    println!(
        "\nsynthetic pose accuracy (1280x720, f = 1000 px, tag 0.1 m, 3x3 supersampling; noisy = blur 0.8 px + noise 3 grey levels)"
    );
    println!(
        "{:>8} {:>5} | {:>5} {:>9} {:>8} {:>8} | {:>5} {:>9} {:>8} {:>8}",
        "size_px",
        "tilt",
        "found",
        "rot_deg",
        "trans_%",
        "rms_px",
        "found",
        "rot_deg",
        "trans_%",
        "rms_px"
    );
    let mut all_rot = Vec::new();
    let mut all_trans = Vec::new();
    let mut big_rot = Vec::new();
    let mut found_total = 0;
    let mut cases = 0;
    for &size in &sizes_px {
        for &tilt in &tilts {
            let mut row = String::new();
            for noisy in [false, true] {
                let (mut rot, mut trans, mut rms) = (Vec::new(), Vec::new(), Vec::new());
                let mut found = 0;
                for (i, &yaw) in yaws.iter().enumerate() {
                    let dist = TAG_M * f / size;
                    let off = DVec3::new(0.02 * (i as f64 - 1.0), -0.01, 0.0) * dist;
                    let truth = view_pose(tilt, yaw, dist, off);
                    let scene = Scene {
                        family: TagFamily::Tag36h11,
                        tags: vec![BoardTag {
                            id: 7 + i as u32,
                            center_m: DVec2::ZERO,
                            size_m: TAG_M,
                            rotation_rad: 0.0,
                        }],
                        background: 120,
                    };
                    let mut img = render(&cam, &scene, &truth, 3);
                    if noisy {
                        img = blur(&img, 0.8);
                        add_noise(&mut img, 3.0, &mut rng);
                    }
                    let dets = det.detect(&img).expect("detect");
                    cases += 1;
                    let Some(d) = dets.iter().find(|d| d.id == 7 + i as u32) else {
                        continue;
                    };
                    found += 1;
                    found_total += 1;
                    let est = estimate_tag_pose(&cam, &d.corners_px, TAG_M).expect("pose");
                    let r = est.best.pose.rotation_angle_to(&truth).to_degrees();
                    let t = (est.best.pose.translation - truth.translation).length()
                        / truth.translation.length()
                        * 100.0;
                    rot.push(r);
                    trans.push(t);
                    rms.push(est.best.rms_px);
                    all_rot.push(r);
                    all_trans.push(t);
                    if size >= 80.0 && tilt >= 30.0 {
                        big_rot.push(r);
                    }
                }
                row += &format!(
                    " | {:>3}/{} {:>9.3} {:>8.3} {:>8.3}",
                    found,
                    yaws.len(),
                    median(&mut rot),
                    median(&mut trans),
                    median(&mut rms)
                );
            }
            println!("{size:>8} {tilt:>5}{row}");
        }
    }
    let med_rot = median(&mut all_rot);
    let med_trans = median(&mut all_trans);
    let med_big = median(&mut big_rot);
    println!(
        "overall: found {found_total}/{cases}, median rotation error {med_rot:.3} deg, median translation error {med_trans:.3} %; tags >= 80 px tilted >= 30 deg: {med_big:.3} deg"
    );
    assert!(
        found_total as f64 >= 0.8 * cases as f64,
        "found {found_total}/{cases}"
    );
    assert!(med_rot < 1.0, "median rotation error {med_rot} deg");
    assert!(med_trans < 1.0, "median translation error {med_trans} %");
    assert!(
        med_big < 0.5,
        "median rotation error (>= 80 px, tilted) {med_big} deg"
    );
}
