//! Boards: several coplanar tags with a known layout on the marker, giving one pose from all
//! visible corners.

use glam::{DVec2, DVec3};
use pa_camera::CameraModel;

use crate::pose::{estimate_planar_pose, PoseEstimate};
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
    /// ids the detection with the best decision margin is used). `Ok(None)` when no tag of
    /// the board is visible.
    pub fn estimate_pose(
        &self,
        camera: &CameraModel,
        detections: &[Detection],
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
        let (obj, img): (Vec<DVec3>, Vec<DVec2>) = correspondences.iter().copied().unzip();
        let estimate = estimate_planar_pose(camera, &obj, &img)?;
        Ok(Some(BoardPose {
            estimate,
            used_ids: best.iter().map(|(t, _)| t.id).collect(),
            correspondences,
        }))
    }
}
