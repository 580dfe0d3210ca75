//! Natural-feature planar targets: any printed picture as the marker.
//!
//! Computed once for the picture ([`ImageTarget::new`]): a working copy (longest side at
//! most [`WORK_MAX_SIDE`] px), its pyramid (factor sqrt 2), ORB-like keypoints and 256-bit
//! descriptors ([`features`]), and the points used for frame-to-frame tracking (the
//! keypoints spread over a grid).
//!
//! Per frame ([`ImageTarget::locate`]):
//! - **Tracking** (a predicted pose is known): each tracked point is predicted by the pose,
//!   the picture around it is warped into the frame and found by NCC plus Lucas-Kanade
//!   ([`patch`]); a first pass over 64 spread points searches +-8 px, the pose is refitted, a
//!   second pass over all points searches +-2 px. No keypoint detection on the frame.
//! - **Detection** (no prediction, or tracking found too few points): keypoints on a 4-level
//!   frame pyramid, Hamming matching with a ratio test spread over a grid ([`matching`]),
//!   RANSAC homography ([`homography`]), an IPPE pose on the inliers, then two patch
//!   refinement passes as in tracking (the keypoints' pixel-level positions become
//!   sub-pixel ones).
//!
//! Each pose comes from [`crate::pose::estimate_planar_pose`] (IPPE + Levenberg-Marquardt,
//! both planar solutions) on the point pairs, after dropping pairs whose residual exceeds
//! three times the median (and 1 px).
//!
//! Marker frame (as for tags): origin at the picture's centre, +X along its width, +Y down
//! the picture, +Z into the table, metres; the height follows from the picture's aspect.
//! A picture pixel `(u, v)` (pixel centres at integers, working resolution `W x H`) lies at
//! `X = ((u + 0.5) / W - 0.5) width_m`, `Y = ((v + 0.5) / H - 0.5) height_m`.

pub mod features;
pub mod homography;
pub mod matching;
pub mod patch;
pub mod quality;
pub mod synth;

use glam::{DVec2, DVec3};
use pa_camera::CameraModel;

use crate::pose::{estimate_planar_pose, PoseEstimate};
use crate::{GrayImage, Pose, TrackError};
use features::{Descriptor, FeatureConfig, Keypoint, Level};
use patch::{Frame, PatchPoint};

pub use quality::{assess_picture, PictureQuality, Verdict};

/// Pictures are worked on with their longest side at most this (pixels).
pub const WORK_MAX_SIDE: u32 = 1024;
/// Shortest side a picture must have (pixels).
pub const MIN_SIDE_PX: u32 = 96;
/// Keypoints a picture needs to be tracked at all.
pub const MIN_KEYPOINTS: usize = 60;
/// Pyramid levels of the picture and of a frame for detection.
const PICTURE_LEVELS: usize = 6;
const FRAME_LEVELS: usize = 4;
/// Oblique views simulated for matching at grazing angles: (direction deg, tilt), the tilt
/// being `1 / cos(viewing angle)` (2: 60 degrees).
pub const SIMULATED_VIEWS: [(f32, f32); 4] = [(0.0, 2.0), (45.0, 2.0), (90.0, 2.0), (135.0, 2.0)];
/// Keypoints each level of a simulated view keeps at least.
const SIMULATED_MIN_PER_LEVEL: usize = 100;
/// Points used for frame-to-frame tracking.
const MAX_TRACK_POINTS: usize = 400;
/// Points of the coarse (wide search) tracking pass.
const COARSE_POINTS: usize = 64;
/// Point pairs a pose needs.
const MIN_PAIRS: usize = 16;

/// A picture prepared for tracking.
#[derive(Debug, Clone, PartialEq)]
pub struct ImageTarget {
    /// Printed width and height, metres.
    pub width_m: f64,
    pub height_m: f64,
    /// Working resolution, pixels.
    pub width_px: u32,
    pub height_px: u32,
    pyramid: Vec<Level>,
    /// The picture's own keypoints first (`direct` of them), then the simulated views'.
    keypoints: Vec<Keypoint>,
    /// Their descriptors, bit-sliced for matching.
    index: matching::DescriptorIndex,
    direct: usize,
    track_points: Vec<PatchPoint>,
}

/// One frame's sighting of the picture.
#[derive(Debug, Clone, PartialEq)]
pub struct ImageObservation {
    /// Both planar pose candidates, best first.
    pub estimate: PoseEstimate,
    /// Marker-frame points and their pixels, as used for the pose.
    pub correspondences: Vec<(DVec3, DVec2)>,
    /// True when found by frame-to-frame tracking, false by a full detection.
    pub tracked: bool,
}

/// The working copy of a picture: longest side at most [`WORK_MAX_SIDE`].
pub(crate) fn working_copy(picture: &GrayImage) -> Result<Level, TrackError> {
    let (w, h) = (picture.width, picture.height);
    if w.min(h) < MIN_SIDE_PX {
        return Err(TrackError::PictureTooSmall {
            width: w,
            height: h,
            min_side: MIN_SIDE_PX,
        });
    }
    let mut l = Level::from_gray(picture);
    while l.width.max(l.height) as u32 > 2 * WORK_MAX_SIDE {
        l = l.downscaled(2.0);
    }
    let side = l.width.max(l.height) as f32;
    if side > WORK_MAX_SIDE as f32 {
        l = l.downscaled(side / WORK_MAX_SIDE as f32);
    }
    l.scale = 1.0;
    Ok(l)
}

/// The picture's pyramid, keypoints and descriptors; with `simulate`, followed by those of
/// [`SIMULATED_VIEWS`] oblique views (their positions mapped back to the picture).
pub(crate) fn picture_features(
    work: &Level,
    simulate: bool,
) -> (Vec<Level>, Vec<Keypoint>, Vec<Descriptor>, usize) {
    let img = GrayImage {
        width: work.width as u32,
        height: work.height as u32,
        data: work.data.clone(),
    };
    let (pyr, smooth) = features::pyramid_smoothed(&img, PICTURE_LEVELS);
    let cfg = FeatureConfig {
        fast_threshold: 15,
        max_keypoints: 1500,
        cell_px: 24,
        min_per_level: 0,
    };
    let (mut k, mut d) = features::detect_and_describe_smoothed(&pyr, &smooth, &cfg);
    let direct = k.len();
    if simulate {
        // At least `SIMULATED_MIN_PER_LEVEL` per level: the coarse levels of a simulated view
        // are what a distant view at a grazing angle matches.
        let cfg = FeatureConfig {
            max_keypoints: 500,
            min_per_level: SIMULATED_MIN_PER_LEVEL,
            ..cfg
        };
        for &(phi_deg, tilt) in &SIMULATED_VIEWS {
            let (k2, d2) =
                features::simulated_view_features(work, phi_deg.to_radians(), tilt, 4, &cfg);
            k.extend(k2);
            d.extend(d2);
        }
    }
    (pyr, k, d, direct)
}

impl ImageTarget {
    /// Prepares `picture` printed `width_m` metres wide. Fails for a picture smaller than
    /// [`MIN_SIDE_PX`] or with fewer than [`MIN_KEYPOINTS`] keypoints (flat, or too smooth).
    pub fn new(picture: &GrayImage, width_m: f64) -> Result<Self, TrackError> {
        if !(width_m.is_finite() && width_m > 0.0) {
            return Err(TrackError::Config(format!(
                "the picture's width must be a positive length, got {width_m} m"
            )));
        }
        if picture.data.len() != picture.width as usize * picture.height as usize {
            return Err(TrackError::BadImage {
                width: picture.width,
                height: picture.height,
                len: picture.data.len(),
            });
        }
        let work = working_copy(picture)?;
        let (pyramid, keypoints, descriptors, direct) = picture_features(&work, true);
        if direct < MIN_KEYPOINTS {
            return Err(TrackError::PictureFeatureless {
                keypoints: direct,
                min: MIN_KEYPOINTS,
            });
        }
        let height_m = width_m * picture.height as f64 / picture.width as f64;
        let mut t = Self {
            width_m,
            height_m,
            width_px: work.width as u32,
            height_px: work.height as u32,
            pyramid,
            keypoints,
            index: matching::DescriptorIndex::new(&descriptors),
            direct,
            track_points: Vec::new(),
        };
        t.track_points = t.select_track_points();
        Ok(t)
    }

    /// Number of keypoints of the picture itself (without the simulated oblique views).
    pub fn keypoint_count(&self) -> usize {
        self.direct
    }

    /// Metres per working-resolution pixel along x and y.
    fn metres_per_px(&self) -> DVec2 {
        DVec2::new(
            self.width_m / self.width_px as f64,
            self.height_m / self.height_px as f64,
        )
    }

    /// The marker-frame point of a picture pixel (working resolution).
    pub fn object_point(&self, picture_px: DVec2) -> DVec3 {
        let m = self.metres_per_px();
        DVec3::new(
            (picture_px.x + 0.5) * m.x - 0.5 * self.width_m,
            (picture_px.y + 0.5) * m.y - 0.5 * self.height_m,
            0.0,
        )
    }

    /// The picture's outer corners in the marker frame: TL, TR, BR, BL.
    pub fn corner_points(&self) -> [DVec3; 4] {
        let (w, h) = (0.5 * self.width_m, 0.5 * self.height_m);
        [
            DVec3::new(-w, -h, 0.0),
            DVec3::new(w, -h, 0.0),
            DVec3::new(w, h, 0.0),
            DVec3::new(-w, h, 0.0),
        ]
    }

    /// The picture's outer corners in the image under `pose` (TL, TR, BR, BL).
    pub fn corners_px(&self, camera: &CameraModel, pose: &Pose) -> Option<[DVec2; 4]> {
        let c = self.corner_points();
        let p = |i: usize| camera.pixel_from_camera(pose.transform_point(c[i]));
        Some([p(0)?, p(1)?, p(2)?, p(3)?])
    }

    /// Tracking points: keypoints at least 6 px apart, spread (in the keypoints' spread
    /// order, which is round robin over grid cells), at most [`MAX_TRACK_POINTS`].
    fn select_track_points(&self) -> Vec<PatchPoint> {
        let mut order: Vec<usize> = (0..self.direct).collect();
        // Round robin over 8x8 cells by strength.
        let cell = (self.width_px.max(self.height_px) as f32 / 12.0).max(8.0);
        order.sort_by(|&a, &b| self.keypoints[b].score.total_cmp(&self.keypoints[a].score));
        let mut rank = std::collections::HashMap::new();
        let mut ranked: Vec<(usize, usize)> = order
            .into_iter()
            .map(|i| {
                let k = &self.keypoints[i];
                let key = ((k.x / cell) as i32, (k.y / cell) as i32);
                let r = rank.entry(key).or_insert(0usize);
                *r += 1;
                (*r, i)
            })
            .collect();
        ranked.sort_by_key(|(r, _)| *r);
        let mut out: Vec<PatchPoint> = Vec::new();
        for (_, i) in ranked {
            let k = &self.keypoints[i];
            let p = DVec2::new(k.x as f64, k.y as f64);
            if out.iter().any(|q| q.picture_px.distance_squared(p) < 36.0) {
                continue;
            }
            out.push(PatchPoint {
                picture_px: p,
                object: self.object_point(p),
            });
            if out.len() >= MAX_TRACK_POINTS {
                break;
            }
        }
        out
    }

    /// Finds the picture in `frame`: frame-to-frame tracking from `predicted` when given,
    /// a full detection otherwise or when tracking keeps too few points.
    pub fn locate(
        &self,
        frame: &GrayImage,
        camera: &CameraModel,
        predicted: Option<&Pose>,
    ) -> Option<ImageObservation> {
        if let Some(p) = predicted {
            // Tracked on the frame's own pixels (no copy).
            let consistent = frame.data.len() == frame.width as usize * frame.height as usize;
            if let Some(o) = consistent
                .then(|| self.track_frame(frame.into(), camera, p))
                .flatten()
            {
                return Some(o);
            }
        }
        self.detect(frame, camera)
    }

    /// Frame-to-frame tracking from a predicted pose.
    pub fn track(
        &self,
        frame: &Level,
        camera: &CameraModel,
        predicted: &Pose,
    ) -> Option<ImageObservation> {
        self.track_frame(frame.into(), camera, predicted)
    }

    /// [`ImageTarget::track`] on borrowed pixels.
    fn track_frame(
        &self,
        frame: Frame<'_>,
        camera: &CameraModel,
        predicted: &Pose,
    ) -> Option<ImageObservation> {
        let coarse: Vec<PatchPoint> = self.visible(camera, predicted, frame, COARSE_POINTS);
        let t = patch::track(
            &self.pyramid,
            frame,
            camera,
            predicted,
            &coarse,
            self.metres_per_px(),
            8,
        );
        if t.len() < MIN_PAIRS / 2 {
            return None;
        }
        let pairs: Vec<(DVec3, DVec2)> = t.iter().map(|x| (coarse[x.index].object, x.px)).collect();
        let (est, _) = fit_pose(camera, &pairs, 6)?;
        let (estimate, correspondences) = self.refine(frame, camera, &est.best.pose, 2)?;
        Some(ImageObservation {
            estimate,
            correspondences,
            tracked: true,
        })
    }

    /// The tracking points predicted inside the frame, at most `max` (spread order).
    fn visible(
        &self,
        camera: &CameraModel,
        pose: &Pose,
        frame: Frame<'_>,
        max: usize,
    ) -> Vec<PatchPoint> {
        let (w, h) = (frame.width as f64, frame.height as f64);
        self.track_points
            .iter()
            .filter(|p| {
                camera
                    .pixel_from_camera(pose.transform_point(p.object))
                    .is_some_and(|q| q.x > 16.0 && q.y > 16.0 && q.x < w - 17.0 && q.y < h - 17.0)
            })
            .take(max)
            .copied()
            .collect()
    }

    /// One patch pass over all tracking points around `pose`, then a robust pose fit.
    fn refine(
        &self,
        frame: Frame<'_>,
        camera: &CameraModel,
        pose: &Pose,
        radius: i32,
    ) -> Option<(PoseEstimate, Vec<(DVec3, DVec2)>)> {
        let pts = self.visible(camera, pose, frame, MAX_TRACK_POINTS);
        let t = patch::track(
            &self.pyramid,
            frame,
            camera,
            pose,
            &pts,
            self.metres_per_px(),
            radius,
        );
        let pairs: Vec<(DVec3, DVec2)> = t.iter().map(|x| (pts[x.index].object, x.px)).collect();
        fit_pose(camera, &pairs, MIN_PAIRS)
    }

    /// Full detection: features, matching, RANSAC homography, pose, patch refinement. A frame
    /// whose buffer does not hold `width * height` bytes shows no picture.
    pub fn detect(&self, frame: &GrayImage, camera: &CameraModel) -> Option<ImageObservation> {
        if frame.data.len() != frame.width as usize * frame.height as usize {
            return None;
        }
        let (pyr, smooth) = features::pyramid_smoothed(frame, FRAME_LEVELS);
        let cfg = FeatureConfig {
            fast_threshold: 18,
            max_keypoints: 2500,
            cell_px: 32,
            min_per_level: 0,
        };
        let (fk, fd) = features::detect_and_describe_smoothed(&pyr, &smooth, &cfg);
        let m = matching::match_indexed(&fk, &fd, &self.index, &Default::default());
        let src: Vec<DVec2> = m
            .iter()
            .map(|x| {
                let k = &self.keypoints[x.picture];
                DVec2::new(k.x as f64, k.y as f64)
            })
            .collect();
        let dst: Vec<DVec2> = m
            .iter()
            .map(|x| DVec2::new(fk[x.frame].x as f64, fk[x.frame].y as f64))
            .collect();
        let (_, inl) = homography::ransac(&src, &dst, 4.0, 2000, 12)?;
        let pairs: Vec<(DVec3, DVec2)> = inl
            .iter()
            .map(|&i| (self.object_point(src[i]), dst[i]))
            .collect();
        let (est, _) = fit_pose(camera, &pairs, 8)?;
        let level = &pyr[0];
        let (est, _) = self.refine(level.into(), camera, &est.best.pose, 4)?;
        let (estimate, correspondences) = self.refine(level.into(), camera, &est.best.pose, 1)?;
        Some(ImageObservation {
            estimate,
            correspondences,
            tracked: false,
        })
    }
}

/// Pose from point pairs, dropping those with a residual above max(3 x median, 1 px) under
/// the first fit and refitting; `None` with fewer than `min_pairs` pairs.
fn fit_pose(
    camera: &CameraModel,
    pairs: &[(DVec3, DVec2)],
    min_pairs: usize,
) -> Option<(PoseEstimate, Vec<(DVec3, DVec2)>)> {
    if pairs.len() < min_pairs.max(4) {
        return None;
    }
    let (obj, img): (Vec<DVec3>, Vec<DVec2>) = pairs.iter().copied().unzip();
    let est = estimate_planar_pose(camera, &obj, &img).ok()?;
    let res: Vec<f64> = pairs
        .iter()
        .map(|(o, p)| {
            camera
                .pixel_from_camera(est.best.pose.transform_point(*o))
                .map_or(f64::INFINITY, |q| q.distance(*p))
        })
        .collect();
    let mut sorted = res.clone();
    sorted.sort_by(f64::total_cmp);
    let thr = (3.0 * sorted[sorted.len() / 2]).max(1.0);
    let kept: Vec<(DVec3, DVec2)> = pairs
        .iter()
        .zip(&res)
        .filter(|(_, r)| **r <= thr)
        .map(|(p, _)| *p)
        .collect();
    if kept.len() < min_pairs.max(4) {
        return None;
    }
    if kept.len() == pairs.len() {
        return Some((est, kept));
    }
    let (obj, img): (Vec<DVec3>, Vec<DVec2>) = kept.iter().copied().unzip();
    let est = estimate_planar_pose(camera, &obj, &img).ok()?;
    Some((est, kept))
}

#[cfg(test)]
mod tests {
    use super::synth::{natural_picture, render_view, view_pose, Pinhole};
    use super::*;
    use pa_camera::Intrinsics;

    const WIDTH_M: f64 = 0.25;

    fn pinhole() -> Pinhole {
        Pinhole {
            fx: 1000.0,
            fy: 1000.0,
            cx: 639.5,
            cy: 359.5,
            width: 1280,
            height: 720,
        }
    }

    fn camera() -> CameraModel {
        let p = pinhole();
        CameraModel::pinhole(Intrinsics {
            fx: p.fx,
            fy: p.fy,
            cx: p.cx,
            cy: p.cy,
            width: p.width,
            height: p.height,
        })
    }

    /// The picture's corners under `pose`, plain pinhole.
    fn true_corners(target: &ImageTarget, pose: &Pose) -> [DVec2; 4] {
        let p = pinhole();
        target.corner_points().map(|c| {
            let c = pose.transform_point(c);
            DVec2::new(p.fx * c.x / c.z + p.cx, p.fy * c.y / c.z + p.cy)
        })
    }

    #[test]
    fn distant_views_at_sixty_degrees_are_found() {
        // The picture small (about 280 x 100 px) and foreshortened by 2: what the simulated
        // views' coarse levels are for. These are the bench's 0.9 m, 60 degree views.
        let pic = natural_picture(640, 480, 7);
        let target = ImageTarget::new(&pic, WIDTH_M).expect("target");
        let cam = camera();
        for (j, roll) in [0.0, 100.0, 230.0].into_iter().enumerate() {
            let truth = view_pose(0.9, 60.0, roll, 0.08, 0.05 * (j as f64 - 1.0));
            let seed = 30 + j as u64 + 6000;
            let frame = render_view(&pic, WIDTH_M, &pinhole(), &truth, 90, 0.7, 2.0, seed);
            let obs = target
                .detect(&frame, &cam)
                .unwrap_or_else(|| panic!("roll {roll}: not found"));
            let got = target
                .corners_px(&cam, &obs.estimate.best.pose)
                .expect("corners");
            let want = true_corners(&target, &truth);
            for (g, w) in got.iter().zip(&want) {
                assert!(g.distance(*w) < 1.0, "roll {roll}: {g} vs {w}");
            }
        }
    }

    #[test]
    fn results_do_not_depend_on_the_thread_count() {
        let pic = natural_picture(320, 240, 5);
        let cam = camera();
        let truth = view_pose(0.6, 35.0, 20.0, 0.02, -0.03);
        let frame = render_view(&pic, WIDTH_M, &pinhole(), &truth, 90, 0.7, 2.0, 9);
        let next = view_pose(0.595, 35.5, 21.0, 0.02, -0.03);
        let frame2 = render_view(&pic, WIDTH_M, &pinhole(), &next, 90, 0.7, 2.0, 10);
        let run = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .expect("pool");
            pool.install(|| {
                let target = ImageTarget::new(&pic, WIDTH_M).expect("target");
                let det = target.detect(&frame, &cam).expect("detected");
                let trk = target
                    .locate(&frame2, &cam, Some(&det.estimate.best.pose))
                    .expect("tracked");
                (target, det, trk)
            })
        };
        let (t1, d1, k1) = run(1);
        let (t3, d3, k3) = run(3);
        assert!(k1.tracked);
        assert_eq!(t1, t3);
        assert_eq!(d1, d3);
        assert_eq!(k1, k3);
    }
}
