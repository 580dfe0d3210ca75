//! Picture (natural-feature) targets against independent truth: views of a procedural
//! picture rendered by an exact plane-to-image mapping (ray-plane intersection, 3x3
//! supersampled, blur and noise) at known poses; the picture's corners and rotation from
//! the estimated pose are compared with the truth.

use glam::{DVec2, DVec3};
use pa_camera::{CameraModel, Intrinsics};
use pa_track::image_target::synth::{natural_picture, render_view, view_pose, Pinhole};
use pa_track::{
    assess_picture, DetectorConfig, GrayImage, ImageTarget, Pose, TrackError, TrackState,
    TrackTarget, Tracker, TrackerConfig, Verdict,
};

const W: u32 = 1280;
const H: u32 = 720;
const F: f64 = 1000.0;
const WIDTH_M: f64 = 0.25;

fn pinhole() -> Pinhole {
    Pinhole {
        fx: F,
        fy: F,
        cx: (W as f64 - 1.0) / 2.0,
        cy: (H as f64 - 1.0) / 2.0,
        width: W,
        height: H,
    }
}

fn camera() -> CameraModel {
    let p = pinhole();
    CameraModel::pinhole(Intrinsics {
        fx: p.fx,
        fy: p.fy,
        cx: p.cx,
        cy: p.cy,
        width: W,
        height: H,
    })
}

fn picture() -> GrayImage {
    natural_picture(640, 480, 7)
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// Independent truth: the picture's corners projected by the true pose (plain pinhole).
fn true_corners(pose: &Pose, height_m: f64) -> [DVec2; 4] {
    let (w, h) = (0.5 * WIDTH_M, 0.5 * height_m);
    [(-w, -h), (w, -h), (w, h), (-w, h)].map(|(x, y)| {
        let c = pose.transform_point(DVec3::new(x, y, 0.0));
        DVec2::new(F * c.x / c.z + pinhole().cx, F * c.y / c.z + pinhole().cy)
    })
}

/// (distance m, tilt deg, roll deg, offset x, offset y)
const VIEWS: [(f64, f64, f64, f64, f64); 12] = [
    (0.45, 0.0, 0.0, 0.0, 0.0),
    (0.45, 30.0, 75.0, 0.05, -0.03),
    (0.5, 60.0, 180.0, 0.0, 0.02),
    (0.55, 45.0, 300.0, -0.08, 0.0),
    (0.6, 15.0, 140.0, 0.1, 0.05),
    (0.65, 55.0, 20.0, 0.0, -0.05),
    (0.7, 40.0, 250.0, -0.1, 0.08),
    (0.75, 0.0, 90.0, 0.15, -0.1),
    (0.8, 60.0, 330.0, 0.05, 0.0),
    (0.85, 25.0, 200.0, -0.2, 0.1),
    (0.9, 50.0, 110.0, 0.0, 0.0),
    (0.9, 10.0, 45.0, 0.25, -0.15),
];

#[test]
fn first_detection_of_synthetic_views_is_accurate() {
    let pic = picture();
    let target = ImageTarget::new(&pic, WIDTH_M).unwrap();
    let cam = camera();
    let (mut corner_err, mut rot_err) = (Vec::new(), Vec::new());
    for (i, &(d, tilt, roll, ox, oy)) in VIEWS.iter().enumerate() {
        let truth = view_pose(d, tilt, roll, ox, oy);
        let frame = render_view(&pic, WIDTH_M, &pinhole(), &truth, 90, 0.7, 2.0, i as u64);
        let obs = target
            .detect(&frame, &cam)
            .unwrap_or_else(|| panic!("view {i} {:?} not found", VIEWS[i]));
        let pose = obs.estimate.best.pose;
        let got = target.corners_px(&cam, &pose).unwrap();
        let want = true_corners(&truth, target.height_m);
        let e: Vec<f64> = got.iter().zip(&want).map(|(a, b)| a.distance(*b)).collect();
        let r = pose.rotation_angle_to(&truth).to_degrees();
        eprintln!(
            "view {i} {:?}: {} pairs, corners {:.3?} px, rotation {r:.3} deg",
            VIEWS[i],
            obs.correspondences.len(),
            e
        );
        assert!(e.iter().all(|v| *v < 3.0), "view {i}: corner errors {e:?}");
        assert!(r < 1.5, "view {i}: rotation error {r} deg");
        corner_err.extend(e);
        rot_err.push(r);
    }
    let (mc, mr) = (median(corner_err), median(rot_err));
    eprintln!("median corner error {mc:.3} px, median rotation error {mr:.3} deg");
    // The targets: corners within 1 px median, rotation within 0.5 deg median.
    assert!(mc < 1.0, "median corner error {mc} px");
    assert!(mr < 0.5, "median rotation error {mr} deg");
}

#[test]
fn marker_frame_is_the_pictures_centre_with_y_down() {
    // Face-on at 0.5 m: the analytic corners are at c -+ f (w/2, h/2) / d.
    let pic = picture();
    let target = ImageTarget::new(&pic, WIDTH_M).unwrap();
    assert!((target.height_m - WIDTH_M * 480.0 / 640.0).abs() < 1e-12);
    let truth = view_pose(0.5, 0.0, 0.0, 0.0, 0.0);
    let frame = render_view(&pic, WIDTH_M, &pinhole(), &truth, 90, 0.0, 0.0, 1);
    let obs = target.detect(&frame, &camera()).unwrap();
    let got = target
        .corners_px(&camera(), &obs.estimate.best.pose)
        .unwrap();
    let (hx, hy) = (F * 0.5 * WIDTH_M / 0.5, F * 0.5 * target.height_m / 0.5);
    let (cx, cy) = (pinhole().cx, pinhole().cy);
    let want = [
        DVec2::new(cx - hx, cy - hy),
        DVec2::new(cx + hx, cy - hy),
        DVec2::new(cx + hx, cy + hy),
        DVec2::new(cx - hx, cy + hy),
    ];
    for (g, w) in got.iter().zip(&want) {
        assert!(g.distance(*w) < 0.5, "{g} vs {w}");
    }
    // +Z into the table: away from the camera, which sits at -Z.
    let cam_in_marker = obs.estimate.best.pose.camera_position_in_marker();
    assert!(cam_in_marker.z < -0.45, "{cam_in_marker}");
}

#[test]
fn tracker_follows_a_moving_picture_by_patch_tracking() {
    let pic = picture();
    let target = ImageTarget::new(&pic, WIDTH_M).unwrap();
    let cam = camera();
    let mut tracker = Tracker::new(
        cam,
        TrackTarget::Image(Box::new(target.clone())),
        DetectorConfig::default(),
        TrackerConfig::default(),
    )
    .unwrap();
    let n = 8;
    let (mut tracked_frames, mut corner_err) = (0, Vec::new());
    for k in 0..n {
        let s = k as f64 / n as f64;
        let truth = view_pose(
            0.6 + 0.1 * s,
            20.0 + 15.0 * s,
            30.0 + 20.0 * s,
            0.05 * s,
            -0.03 * s,
        );
        let frame = render_view(&pic, WIDTH_M, &pinhole(), &truth, 90, 0.7, 2.0, 100 + k);
        let out = tracker.update(&frame, k as f64 / 24.0).unwrap();
        let raw = out.raw.unwrap_or_else(|| panic!("frame {k}: not seen"));
        if k > 0 {
            // After the first detection every frame is found by frame-to-frame tracking.
            assert!(out.used_roi, "frame {k}: fell back to detection");
            tracked_frames += 1;
        }
        let got = out.target_corners_px.unwrap();
        let want = true_corners(&truth, target.height_m);
        let want_from_raw = target.corners_px(&cam, &raw.pose).unwrap();
        assert_eq!(got, want_from_raw);
        corner_err.extend(got.iter().zip(&want).map(|(a, b)| a.distance(*b)));
        if k >= 2 {
            assert_eq!(out.state, TrackState::Tracked);
        }
    }
    assert_eq!(tracked_frames, n - 1);
    let m = median(corner_err.clone());
    let max = corner_err.iter().copied().fold(0.0, f64::max);
    eprintln!("tracked: median corner error {m:.3} px, max {max:.3}");
    assert!(m < 1.0 && max < 3.0, "median {m}, max {max}");
    // Gone: the tracker coasts, then loses it.
    let empty = GrayImage::filled(W, H, 90);
    let out = tracker.update(&empty, 1.0).unwrap();
    assert!(out.raw.is_none() && out.coasting);
}

#[test]
fn bad_pictures_give_typed_errors_and_warnings() {
    let small = natural_picture(80, 80, 3);
    assert!(matches!(
        ImageTarget::new(&small, 0.2),
        Err(TrackError::PictureTooSmall {
            width: 80,
            height: 80,
            ..
        })
    ));
    let flat = GrayImage::filled(400, 300, 128);
    assert!(matches!(
        ImageTarget::new(&flat, 0.2),
        Err(TrackError::PictureFeatureless { keypoints: 0, .. })
    ));
    let q = assess_picture(&flat).unwrap();
    assert_eq!(q.verdict, Verdict::Unusable);
    assert!(matches!(
        ImageTarget::new(&picture(), -1.0),
        Err(TrackError::Config(_))
    ));
    // A pure repeating pattern: a tiled 40 px motif.
    let motif = natural_picture(128, 128, 11);
    let mut tiled = GrayImage::filled(480, 480, 0);
    for y in 0..480usize {
        for x in 0..480usize {
            tiled.data[y * 480 + x] = motif.data[(y % 40 + 20) * 128 + x % 40 + 20];
        }
    }
    let q = assess_picture(&tiled).unwrap();
    eprintln!("tiled: {q:?}");
    assert!(q.ambiguous_fraction > 0.25, "{q:?}");
    assert!(q.warnings.iter().any(|w| w.contains("repetitive")), "{q:?}");
    assert_ne!(q.verdict, Verdict::Good);
    let q = assess_picture(&picture()).unwrap();
    eprintln!("natural: {q:?}");
    assert_eq!(q.verdict, Verdict::Good, "{q:?}");
    assert!(q.ambiguous_fraction < 0.1, "{q:?}");
}

#[test]
fn frames_without_the_picture_give_no_pose_and_no_panic() {
    let target = ImageTarget::new(&picture(), WIDTH_M).unwrap();
    let cam = camera();
    for (w, h) in [(0, 0), (1, 1), (30, 20), (1280, 720)] {
        let frame = GrayImage::filled(w, h, 90);
        assert!(target.detect(&frame, &cam).is_none(), "{w}x{h}");
        let pred = view_pose(0.6, 10.0, 0.0, 0.0, 0.0);
        assert!(
            target.locate(&frame, &cam, Some(&pred)).is_none(),
            "{w}x{h}"
        );
    }
    // Another picture in view is not this one.
    let other = natural_picture(640, 480, 99);
    let frame = render_view(
        &other,
        WIDTH_M,
        &pinhole(),
        &view_pose(0.5, 20.0, 10.0, 0.0, 0.0),
        90,
        0.7,
        2.0,
        3,
    );
    assert!(target.detect(&frame, &cam).is_none());
}

/// Regression: a `GrayImage` built by hand whose buffer does not hold `width * height` bytes
/// (its fields are public) panicked inside the full detection's pyramid; it is now no
/// picture, as for `locate`'s tracking.
#[test]
fn regression_an_inconsistent_frame_is_no_picture_not_a_panic() {
    let target = ImageTarget::new(&picture(), WIDTH_M).expect("target");
    let cam = camera();
    for len in [0usize, 10, 1280 * 720 - 1, 1280 * 720 + 7] {
        let frame = GrayImage {
            width: 1280,
            height: 720,
            data: vec![90; len],
        };
        assert!(target.detect(&frame, &cam).is_none(), "{len} bytes");
        let pred = view_pose(0.6, 10.0, 0.0, 0.0, 0.0);
        assert!(
            target.locate(&frame, &cam, Some(&pred)).is_none(),
            "{len} bytes"
        );
    }
}
