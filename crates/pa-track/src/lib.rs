//! Marker tracking and camera pose for Props Alive.
//!
//! Pipeline per frame: [`Detector::detect`] finds AprilTags (tag36h11 by default) and
//! returns corners in the project's convention; [`estimate_tag_pose`] / [`Board::estimate_pose`]
//! solve the camera pose `camera_from_marker` (IPPE, both planar solutions, refined by
//! Levenberg-Marquardt on the reprojection error through the full [`pa_camera::CameraModel`]);
//! [`Tracker`] runs the state machine (Searching -> Detected -> Tracked -> Lost) with
//! hysteresis, pose filtering weighted by the measured noise (a constant-velocity Kalman
//! filter, [`PoseFilter`]) and region-of-interest search. [`Board::estimate_pose`] rejects tags
//! whose corners disagree with the rest (a tag partly hidden by the prop) before its final fit.
//! Before the pose, the [`Tracker`] finds each tag's edges again in linear light
//! ([`refine_tag_corners`], [`TrackerConfig::refine_corners`]): the quad search, like the C
//! library, puts an edge where the encoded grey is halfway, which on a gamma-encoded frame lies
//! inside the black border and makes the board look too far away.
//!
//! # Picture targets
//!
//! [`ImageTarget`] makes any printed picture the marker (module [`image_target`]): ORB-like
//! keypoints computed once on the picture (plus affine-simulated oblique views), matched in
//! the frame, a RANSAC homography, IPPE + LM pose, then frame-to-frame patch tracking (NCC +
//! Lucas-Kanade from the predicted pose). [`TrackTarget::Image`] runs it through the same
//! [`Tracker`] statechart; [`TrackOutput::target_corners_px`] gives the picture's corners.
//! [`assess_picture`] says whether a picture can be tracked.
//!
//! # Detection modes and recall
//!
//! [`DetectorConfig::default`]: quad search at decimation 1 plus a merged pass at decimation 2
//! (for strongly defocused tags; its quads are edge-refined at full resolution), and a
//! quarter-resolution fallback pass when nothing is found (tags that fill a large frame).
//! [`DetectorConfig::thorough`] adds a pass on the frame upsampled 2x (bilinear, pixel-centre
//! aligned; corners mapped back by `x = (u + 0.5) / 2 - 0.5`) for very small tags; it costs
//! several times a normal pass. [`DetectorConfig::fast`] is the per-still speed preset: the
//! quad search at decimation 2 only, its quads edge-refined at full resolution (the C
//! library's `quad_decimate = 2`); it misses more small tags than the default. The quad fit and decoding are our own implementation of the
//! AprilTag 3 algorithm, with the AprilTag library's family code tables vendored under
//! `data/tags/` (module `family`). On the conformance photos (47 tags, C library reference,
//! JPEG luma): `default()` and `c_reference()` both find 47/47 with a median corner
//! difference of 0.0003 px.
//!
//! # Conventions
//!
//! - Pixels: OpenCV, pixel centres at integer coordinates. The AprilTag library's +0.5 px
//!   offset is removed once, in [`detect`](crate::detect).
//! - Corner order: `[top-left, top-right, bottom-right, bottom-left]` of the tag **as
//!   printed** (outer corners of the black border; the canonical apriltag-imgs picture, and
//!   what [`marker_image`] and `propsalive marker` print), clockwise on screen for a tag seen
//!   from the front. Relation to the two references, pinned by
//!   `tests/conformance.rs::corner_order_matches_c_library_and_opencv_aruco` and
//!   `swarmathon_photos_match_c_library` on the same real photos:
//!   - AprilTag C library (`det->p[0..4]`, +0.5 px pixel convention):
//!     `ours = [p3, p2, p1, p0] - (0.5, 0.5)`.
//!   - OpenCV ArUco with `DICT_APRILTAG_36h11` (`corners[0..4]`, same pixel convention as
//!     ours): `ours = [c2, c3, c0, c1]`: OpenCV's "top-left" is the printed tag's
//!     bottom-right (its dictionary code is the tag turned 180 degrees). Together these give
//!     the conformance README's `C [p0, p1, p2, p3] = OpenCV [c1, c0, c3, c2]`.
//!
//!   To feed our corners to OpenCV's `solvePnP` with ArUco's object points, reorder them
//!   back (`[ours[2], ours[3], ours[0], ours[1]]`); pa-track's own pose code uses ours.
//! - Marker frame (as in `pa-camera`'s conventions table): right-handed, origin at the tag
//!   centre, **+X right, +Y down the printed page, +Z into the table**, metres. So the corners
//!   of a tag of side `s` are TL `(-s/2, -s/2, 0)`, TR `(s/2, -s/2, 0)`,
//!   BR `(s/2, s/2, 0)`, BL `(-s/2, s/2, 0)`. (This is ArUco's frame turned 180 degrees about X:
//!   ArUco has +Y up the page and +Z out of it.) A camera looking down at the marker sees
//!   the marker's +Z pointing away from it.
//! - Poses are `camera_from_marker` ([`Pose`]): `p_camera = R * p_marker + t`.

pub mod board;
pub mod detect;
mod edges;
mod family;
pub mod filter;
pub mod image_target;
pub mod marker;
pub mod pose;
mod quad;
mod segment;
pub mod tracker;

pub use board::Board;
pub use detect::{Detection, Detector, DetectorConfig, GrayImage, TagFamily};
pub use edges::refine_tag_corners;
pub use filter::{OneEuro, PoseFilter, PoseFilterConfig};
pub use image_target::{assess_picture, ImageObservation, ImageTarget, PictureQuality, Verdict};
pub use marker::{family_layout, marker_cells, marker_image, FamilyLayout};
pub use pose::{
    estimate_tag_pose, pose_noise, tag_object_points, Pose, PoseCandidate, PoseEstimate, PoseNoise,
};
pub use tracker::{
    CornerRefinement, TrackEvent, TrackOutput, TrackState, TrackTarget, Tracker, TrackerConfig,
    FAST_MIN_TAG_PX, FAST_RECHECK_DETECTIONS,
};

/// Errors of the tracker. A frame without tags is not an error.
#[derive(Debug, thiserror::Error)]
pub enum TrackError {
    /// An image buffer whose length does not match its size.
    #[error("image buffer of {len} bytes does not match {width}x{height}")]
    BadImage { width: u32, height: u32, len: usize },
    /// An unknown tag family name.
    #[error("unknown tag family {0:?} (known: tag36h11, tag36h10, tag25h9, tag16h5, tagCircle21h7, tagCircle49h12, tagCustom48h12, tagStandard41h12, tagStandard52h13)")]
    UnknownFamily(String),
    /// An id outside the family.
    #[error("{family} has no id {id} (ids 0..{count})")]
    UnknownId {
        family: TagFamily,
        id: u32,
        count: u32,
    },
    /// Invalid settings.
    #[error("invalid configuration: {0}")]
    Config(String),
    /// A Hamming radius (other than the default 2) that could confuse two codes of a
    /// configured family: it must be at most `(min_hamming - 1) / 2`.
    #[error("AprilTag detector: max_hamming {max_hamming} exceeds safe limit for this tag family (min_hamming={min_hamming}, max safe value is {max_safe})")]
    MaxHammingTooLarge {
        max_hamming: u8,
        min_hamming: u8,
        max_safe: u8,
    },
    /// A picture target smaller than the tracker can use.
    #[error("the picture is {width}x{height} px: its shorter side must be at least {min_side} px")]
    PictureTooSmall {
        width: u32,
        height: u32,
        min_side: u32,
    },
    /// A picture target with too few keypoints (flat or smooth).
    #[error("the picture has {keypoints} keypoints, at least {min} are needed: it is too flat or smooth to track (see `propsalive marker --check`)")]
    PictureFeatureless { keypoints: usize, min: usize },
    /// Pose estimation could not run on these points.
    #[error("pose estimation failed: {0}")]
    Pose(String),
}
