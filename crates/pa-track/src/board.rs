//! Boards: several coplanar tags with a known layout on the marker, giving one pose from all
//! visible corners.
//!
//! A tag that is partly hidden (by the prop standing on the board) can still decode with
//! corners off by pixels, and would pull the pose. Before the final fit, tags whose corners
//! disagree with the rest are rejected ([`Board::estimate_pose_robust`]): while three or more
//! tags remain, the tag with the largest residual against the joint fit is tested against a
//! fit of the others, and dropped when its residual there exceeds
//! `max(REJECT_FLOOR_PX, REJECT_FACTOR * s)`, `s` the per-corner RMS of the others (the
//! measured noise of this frame). With two tags that disagree, the one that agrees with a
//! prior pose (the tracker's prediction) is kept; without a prior, or when neither agrees
//! better, both are.

use glam::{DVec2, DVec3};
use pa_camera::CameraModel;

use crate::pose::{estimate_planar_pose, rms_error, Pose, PoseEstimate};
use crate::{Detection, TagFamily, TrackError};

/// One tag of a board: its centre on the marker plane (marker frame, metres), side and
/// in-plane rotation about the marker's +Z (radians; 0 = printed upright like the board).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct BoardTag {
    pub id: u32,
    pub center_m: DVec2,
    pub size_m: f64,
    #[serde(default)]
    pub rotation_rad: f64,
}

impl BoardTag {
    /// Corners in the marker frame, detection order (TL, TR, BR, BL of the printed tag).
    pub fn object_points(&self) -> [DVec3; 4] {
        let (s, c) = self.rotation_rad.sin_cos();
        crate::pose::tag_object_points(self.size_m).map(|p| {
            DVec3::new(
                self.center_m.x + c * p.x - s * p.y,
                self.center_m.y + s * p.x + c * p.y,
                0.0,
            )
        })
    }
}

/// A set of coplanar tags on the marker plane (z = 0 of the marker frame).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Board {
    pub family: TagFamily,
    pub tags: Vec<BoardTag>,
}

/// A board pose and the tags that gave it.
#[derive(Debug, Clone, PartialEq)]
pub struct BoardPose {
    pub estimate: PoseEstimate,
    /// Ids of the board's tags used (one detection per id).
    pub used_ids: Vec<u32>,
    /// Object points and their pixels, as used.
    pub correspondences: Vec<(DVec3, DVec2)>,
    /// Ids of the board's tags seen but rejected as disagreeing with the rest.
    pub rejected_ids: Vec<u32>,
}

/// A tag is rejected only when its residual exceeds this many pixels (RMS over its corners),
/// whatever the measured noise.
pub const REJECT_FLOOR_PX: f64 = 0.5;
/// ... and this many times the per-corner RMS residual of the other tags.
pub const REJECT_FACTOR: f64 = 4.0;
/// With two tags, the one whose residual under the prior is smaller is kept only when the
/// other's is this many times larger.
const PRIOR_RATIO: f64 = 2.0;

/// RMS residual of each tag (4 corners each, in order) under `pose`.
fn tag_residuals(camera: &CameraModel, pose: &Pose, corr: &[(DVec3, DVec2)]) -> Vec<f64> {
    corr.chunks(4)
        .map(|c| {
            let (o, p): (Vec<DVec3>, Vec<DVec2>) = c.iter().copied().unzip();
            rms_error(camera, pose, &o, &p)
        })
        .collect()
}

/// Per-corner RMS residual over several tags' RMS residuals (4 corners each).
fn pooled(residuals: impl Iterator<Item = f64>) -> f64 {
    let (mut sum, mut n) = (0.0, 0usize);
    for r in residuals {
        sum += r * r;
        n += 1;
    }
    (sum / n.max(1) as f64).sqrt()
}

fn fit(camera: &CameraModel, corr: &[(DVec3, DVec2)]) -> Result<PoseEstimate, TrackError> {
    let (obj, img): (Vec<DVec3>, Vec<DVec2>) = corr.iter().copied().unzip();
    estimate_planar_pose(camera, &obj, &img)
}

impl Board {
    /// A single tag centred on the marker origin.
    pub fn single(family: TagFamily, id: u32, tag_size_m: f64) -> Self {
        Self {
            family,
            tags: vec![BoardTag {
                id,
                center_m: DVec2::ZERO,
                size_m: tag_size_m,
                rotation_rad: 0.0,
            }],
        }
    }

    /// A `rows` x `cols` grid of tags of side `tag_size_m` separated by `gap_m`, ids
    /// row-major from `first_id` starting at the top-left (as printed); the marker origin is
    /// the centre of the grid, +X along a row, +Y down the columns.
    pub fn grid(
        family: TagFamily,
        rows: u32,
        cols: u32,
        tag_size_m: f64,
        gap_m: f64,
        first_id: u32,
    ) -> Result<Self, TrackError> {
        let size_ok = tag_size_m.is_finite() && tag_size_m > 0.0;
        let gap_ok = gap_m.is_finite() && gap_m >= 0.0;
        if rows == 0 || cols == 0 || !size_ok || !gap_ok {
            return Err(TrackError::Config(format!(
                "invalid grid {rows}x{cols}, tag {tag_size_m} m, gap {gap_m} m"
            )));
        }
        // Every id must be a code of the family, computed without overflow (a huge board or
        // first id is an error, not a wrapped id).
        let count = crate::marker::family_layout(family)?.id_count;
        let last = rows
            .checked_mul(cols)
            .and_then(|n| first_id.checked_add(n - 1));
        match last {
            Some(last) if last < count => {}
            _ => {
                return Err(TrackError::UnknownId {
                    family,
                    id: last.unwrap_or(u32::MAX),
                    count,
                })
            }
        }
        let pitch = tag_size_m + gap_m;
        let mut tags = Vec::with_capacity((rows * cols) as usize);
        for r in 0..rows {
            for c in 0..cols {
                tags.push(BoardTag {
                    id: first_id + r * cols + c,
                    center_m: DVec2::new(
                        (c as f64 - (cols - 1) as f64 * 0.5) * pitch,
                        (r as f64 - (rows - 1) as f64 * 0.5) * pitch,
                    ),
                    size_m: tag_size_m,
                    rotation_rad: 0.0,
                });
            }
        }
        Ok(Self { family, tags })
    }

    /// The tag with this id.
    pub fn tag(&self, id: u32) -> Option<&BoardTag> {
        self.tags.iter().find(|t| t.id == id)
    }

    /// Whether a detection belongs to this board.
    pub fn contains(&self, d: &Detection) -> bool {
        d.family == self.family && self.tag(d.id).is_some()
    }

    /// All corners of all tags (marker frame).
    pub fn all_object_points(&self) -> Vec<DVec3> {
        self.tags.iter().flat_map(|t| t.object_points()).collect()
    }

    /// The board pose from the detections of its tags (others are ignored; for repeated
    /// ids the detection with the best decision margin is used), with disagreeing tags
    /// rejected and no prior ([`Self::estimate_pose_robust`]). `Ok(None)` when no tag of the
    /// board is visible.
    pub fn estimate_pose(
        &self,
        camera: &CameraModel,
        detections: &[Detection],
    ) -> Result<Option<BoardPose>, TrackError> {
        self.estimate_pose_robust(camera, detections, None)
    }

    /// As [`Self::estimate_pose`], with `prior` (the pose expected on this frame, e.g. the
    /// filter's prediction) deciding between two disagreeing tags. See the module docs.
    pub fn estimate_pose_robust(
        &self,
        camera: &CameraModel,
        detections: &[Detection],
        prior: Option<&Pose>,
    ) -> Result<Option<BoardPose>, TrackError> {
        let mut best: Vec<(&BoardTag, &Detection)> = Vec::new();
        for d in detections.iter().filter(|d| d.family == self.family) {
            let Some(t) = self.tag(d.id) else { continue };
            match best.iter_mut().find(|(bt, _)| bt.id == d.id) {
                Some(slot) => {
                    if d.decision_margin > slot.1.decision_margin {
                        slot.1 = d;
                    }
                }
                None => best.push((t, d)),
            }
        }
        if best.is_empty() {
            return Ok(None);
        }
        let mut correspondences = Vec::with_capacity(best.len() * 4);
        for (t, d) in &best {
            for (o, p) in t.object_points().into_iter().zip(d.corners_px) {
                correspondences.push((o, p));
            }
        }
        let mut used_ids: Vec<u32> = best.iter().map(|(t, _)| t.id).collect();
        let mut rejected_ids = Vec::new();
        let mut estimate = fit(camera, &correspondences)?;
        // Three or more tags: leave the worst out while it disagrees with the others.
        while used_ids.len() >= 3 {
            let res = tag_residuals(camera, &estimate.best.pose, &correspondences);
            let Some((worst, &r_worst)) = res.iter().enumerate().max_by(|a, b| a.1.total_cmp(b.1))
            else {
                break;
            };
            let others = pooled(
                res.iter()
                    .enumerate()
                    .filter(|(i, _)| *i != worst)
                    .map(|(_, r)| *r),
            );
            // Cheap test first: it already agrees under the joint fit.
            if r_worst <= REJECT_FLOOR_PX.max(REJECT_FACTOR * others) {
                break;
            }
            let mut rest = correspondences.clone();
            rest.drain(worst * 4..worst * 4 + 4);
            let Ok(without) = fit(camera, &rest) else {
                break;
            };
            let res_wo = tag_residuals(camera, &without.best.pose, &correspondences);
            let others_wo = pooled(
                res_wo
                    .iter()
                    .enumerate()
                    .filter(|(i, _)| *i != worst)
                    .map(|(_, r)| *r),
            );
            if res_wo[worst] <= REJECT_FLOOR_PX.max(REJECT_FACTOR * others_wo) {
                break;
            }
            rejected_ids.push(used_ids.remove(worst));
            correspondences = rest;
            estimate = without;
        }
        // Two tags that disagree: keep the one the prior agrees with.
        if used_ids.len() == 2 {
            let res = tag_residuals(camera, &estimate.best.pose, &correspondences);
            let prior_res = prior.map(|p| tag_residuals(camera, p, &correspondences));
            if let (true, Some(pr)) = (res.iter().any(|&r| r > REJECT_FLOOR_PX), prior_res) {
                let (keep, drop) = if pr[0] <= pr[1] { (0, 1) } else { (1, 0) };
                if pr[drop] > PRIOR_RATIO * pr[keep] && pr[drop] > REJECT_FLOOR_PX {
                    let rest: Vec<(DVec3, DVec2)> =
                        correspondences[keep * 4..keep * 4 + 4].to_vec();
                    if let Ok(single) = fit(camera, &rest) {
                        rejected_ids.push(used_ids.remove(drop));
                        correspondences = rest;
                        estimate = single;
                    }
                }
            }
        }
        Ok(Some(BoardPose {
            estimate,
            used_ids,
            correspondences,
            rejected_ids,
        }))
    }
}
