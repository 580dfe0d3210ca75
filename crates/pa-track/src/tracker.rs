//! Tracking over time: an explicit state machine with hysteresis, events, pose filtering and
//! region-of-interest search. Each frame's board pose rejects tags that disagree with the
//! rest (the filter's prediction decides between two); the filter weighs each pose by the
//! noise its fit measured ([`crate::pose::pose_noise`]).
//!
//! ```text
//!  Searching --seen--> Detected --seen N frames--> Tracked <------------------+
//!      ^                  |                          | missing M frames       | seen
//!      |  missing         |                          v                        | (Recovered)
//!      +------------------+           Searching <-- Lost --------------------+
//!                                   (missing M + K frames in all)
//! ```
//! While Tracked with fewer than M missing frames the last filtered pose is kept
//! (`coasting`). Events: [`TrackEvent`].

use glam::DVec2;
use pa_camera::CameraModel;

use crate::board::{Board, BoardPose};
use crate::image_target::{ImageObservation, ImageTarget};
use crate::pose::estimate_planar_pose;
use crate::{Detection, Detector, DetectorConfig, GrayImage, Pose, PoseCandidate, PoseFilter};
use crate::{PoseFilterConfig, TagFamily, TrackError};

/// An accepted pose with its point pairs and the tag ids used.
type Observed = (PoseCandidate, Vec<(glam::DVec3, DVec2)>, Vec<u32>);

/// A picture found by frame-to-frame tracking fits its hundreds of sub-pixel points to a few
/// tenths of a pixel (0.16-0.26 px on the `picture` set at 480x270); above this RMS (pixels)
/// the patches may have locked onto the wrong place (seen: a prediction 6 frames stale, 2.1 px
/// RMS and 13 mm off; after the faster patch tracker, 0.69 px and 1.9 mm off), and the picture
/// is looked for again ([`locate_checked`]; the lowest RMS of those tried is kept, so a noisy
/// frame costs a detection, never its pose).
pub const PICTURE_TRACK_MAX_RMS_PX: f64 = 0.5;

/// [`ImageTarget::locate`], checked: a tracked sighting whose fit exceeds
/// [`PICTURE_TRACK_MAX_RMS_PX`] is tracked once more from its own pose (a wrong lock near the
/// right place converges), then, if still above, replaced by a full detection; the lowest RMS
/// of those tried is kept.
fn locate_checked(
    image: &ImageTarget,
    frame: &GrayImage,
    camera: &CameraModel,
    prior: Option<&Pose>,
) -> Option<ImageObservation> {
    let first = image.locate(frame, camera, prior)?;
    let rms = |o: &ImageObservation| o.estimate.best.rms_px;
    if !first.tracked || rms(&first) <= PICTURE_TRACK_MAX_RMS_PX {
        return Some(first);
    }
    let mut best = first;
    let again = image.locate(frame, camera, Some(&best.estimate.best.pose));
    if let Some(o) = again.filter(|o| rms(o) < rms(&best)) {
        best = o;
    }
    if rms(&best) > PICTURE_TRACK_MAX_RMS_PX {
        if let Some(o) = image.detect(frame, camera).filter(|o| rms(o) < rms(&best)) {
            best = o;
        }
    }
    Some(best)
}

/// Tracking states.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
pub enum TrackState {
    /// Nothing seen recently: full-frame search.
    Searching,
    /// Seen, but for fewer than `frames_to_track` consecutive frames.
    Detected,
    /// Seen steadily; poses are reported (also while briefly missing).
    Tracked,
    /// Missing for `frames_to_lose` frames; no pose is reported.
    Lost,
}

/// Transitions a caller can react to.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
pub enum TrackEvent {
    /// Searching -> Detected: the target appeared.
    Found,
    /// Detected -> Tracked: seen long enough.
    Tracked,
    /// Detected -> Searching: it vanished before being tracked.
    Dropped,
    /// Tracked -> Lost.
    Lost,
    /// Lost -> Tracked: seen again.
    Recovered,
    /// Lost -> Searching: missing for too long.
    SearchRestarted,
}

/// What to track.
#[derive(Debug, Clone, PartialEq)]
pub enum TrackTarget {
    /// One tag centred on the marker origin.
    Tag {
        family: TagFamily,
        id: u32,
        size_m: f64,
    },
    /// A board of tags.
    Board(Board),
    /// A natural picture ([`ImageTarget`]): found by keypoint matching, then followed frame
    /// to frame by patch tracking from the predicted pose.
    Image(Box<ImageTarget>),
    /// A picture and a board of tags in one marker frame, the picture's (its centre at the
    /// origin, +X along its width, +Y down it; the tags at their board positions, as printed
    /// together): each frame's pose is fitted to the point pairs of both, so that either
    /// alone keeps the marker tracked (a hand over the tags, the picture half out of frame).
    ImageAndBoard {
        image: Box<ImageTarget>,
        board: Board,
    },
}

impl TrackTarget {
    /// The board, or an empty board for a picture.
    fn board(&self) -> Board {
        match self {
            TrackTarget::Tag { family, id, size_m } => Board::single(*family, *id, *size_m),
            TrackTarget::Board(b) => b.clone(),
            TrackTarget::Image(_) => Board {
                family: TagFamily::Tag36h11,
                tags: Vec::new(),
            },
            TrackTarget::ImageAndBoard { board, .. } => board.clone(),
        }
    }
}

/// Tracker settings.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default)]
pub struct TrackerConfig {
    /// N: consecutive frames seen to go from Detected to Tracked.
    pub frames_to_track: u32,
    /// M: consecutive frames missing to go from Tracked to Lost.
    pub frames_to_lose: u32,
    /// K: further missing frames to go from Lost back to Searching.
    pub frames_to_search: u32,
    /// Search around the last position first.
    pub use_roi: bool,
    /// Margin around the last target box, as a fraction of its larger side.
    pub roi_margin: f64,
    /// Reject poses with an RMS reprojection error above this (pixels).
    pub max_rms_px: f64,
    pub filter: PoseFilterConfig,
    /// Detect each frame's tags with the quad search at decimation 2 first
    /// ([`DetectorConfig::fast`]'s passes, with the configured families and thresholds), and
    /// run the configured detector's full-resolution passes only when that may find more:
    /// none of the board's tags found, or a board tag that lies wholly inside the frame at
    /// the pose they give is missing and smaller than [`FAST_MIN_TAG_PX`] (too small for
    /// the decimated search) and was not missed by the last full detection too (hidden), or
    /// [`FAST_RECHECK_DETECTIONS`] frames since the last full detection. Only with a
    /// detector whose first pass is at full resolution. Off by default: faster, and more
    /// accurate on sharp frames, but on noisy frames the video filter fed by it is no longer
    /// better than a still's own pose (README, "The decimated search first").
    pub fast_first: bool,
    /// Find each detected tag's edges again in linear light before the pose (module
    /// `edges`): the quad search's edges lie inside the black border on gamma-encoded frames,
    /// so the board looked a little too far away. The frames' encoding says how to get back
    /// to linear light; [`CornerRefinement::Off`] keeps the detector's corners (the AprilTag
    /// C library's).
    pub refine_corners: CornerRefinement,
}

/// How [`TrackerConfig::refine_corners`] reads the frame.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, Hash, Default, serde::Serialize, serde::Deserialize,
)]
#[serde(rename_all = "snake_case")]
pub enum CornerRefinement {
    /// The detector's corners as found.
    Off,
    /// Frames encoded with the sRGB curve, as cameras' and renderers' 8-bit output is.
    #[default]
    Srgb,
    /// Frames whose values are proportional to the light (a raw or linear camera profile,
    /// and synthetic frames blurred in their stored values).
    Linear,
}

/// Side (pixels) under which a board tag may be missed by the decimated quad search (it
/// finds tags of about 27 px and up on the conformance photos, as the AprilTag C library at
/// `quad_decimate = 2`); [`TrackerConfig::fast_first`] runs the full passes when such a tag
/// is in view and was not found.
pub const FAST_MIN_TAG_PX: f64 = 48.0;

/// With [`TrackerConfig::fast_first`], the full passes run again after this many frames
/// detected by the decimated search alone, so that a hidden small tag seen again is used.
pub const FAST_RECHECK_DETECTIONS: u32 = 12;

impl TrackerConfig {
    /// Stills of a stop-motion take (the camera jumps between them; the tracker is reset
    /// before each, `pa_video::source`'s policy): the first detection trusted, no region of
    /// interest, no pose filter.
    pub fn per_still() -> Self {
        Self {
            frames_to_track: 1,
            use_roi: false,
            filter: PoseFilterConfig {
                enabled: false,
                ..PoseFilterConfig::default()
            },
            ..Self::default()
        }
    }
}

impl Default for TrackerConfig {
    fn default() -> Self {
        Self {
            frames_to_track: 3,
            frames_to_lose: 5,
            frames_to_search: 30,
            use_roi: true,
            roi_margin: 0.5,
            max_rms_px: 3.0,
            filter: PoseFilterConfig::default(),
            fast_first: false,
            refine_corners: CornerRefinement::Srgb,
        }
    }
}

/// The result of one frame.
#[derive(Debug, Clone, PartialEq)]
pub struct TrackOutput {
    pub state: TrackState,
    /// Transitions that happened on this frame.
    pub events: Vec<TrackEvent>,
    /// Filtered `camera_from_marker` (Tracked only; the last one while coasting).
    pub pose: Option<Pose>,
    /// This frame's unfiltered pose (after the consistent choice of the planar flip).
    pub raw: Option<PoseCandidate>,
    /// True while Tracked but not seen on this frame.
    pub coasting: bool,
    /// All detections of this frame (any id).
    pub detections: Vec<Detection>,
    /// Ids of the target's tags used for the pose.
    pub used_ids: Vec<u32>,
    /// Whether the region-of-interest search found the target (no full-frame pass); for a
    /// picture, whether frame-to-frame tracking found it (no full detection).
    pub used_roi: bool,
    /// A picture target's outer corners in the image (TL, TR, BR, BL of the picture, pixel
    /// centres at integers): from this frame's measured pose when seen, from the filtered
    /// pose while coasting; `None` for tags.
    pub target_corners_px: Option<[DVec2; 4]>,
}

/// The tracker.
pub struct Tracker {
    pub config: TrackerConfig,
    camera: CameraModel,
    board: Board,
    image: Option<Box<ImageTarget>>,
    detector: Detector,
    /// The decimated detector of [`TrackerConfig::fast_first`].
    fast: Option<Detector>,
    /// Small board tags in view that the last full detection missed too (hidden); kept
    /// across [`Tracker::reset`]: what hides them (the key prop) stands on the board.
    hidden_small: Vec<u32>,
    /// Detections by the decimated search alone since the last full one.
    since_full: u32,
    filter: PoseFilter,
    state: TrackState,
    seen: u32,
    missed: u32,
    last_pose: Option<Pose>,
    last_filtered: Option<Pose>,
    roi: Option<[f64; 4]>,
}

impl Tracker {
    /// A tracker for `target` seen by `camera`.
    pub fn new(
        camera: CameraModel,
        target: TrackTarget,
        detector: DetectorConfig,
        config: TrackerConfig,
    ) -> Result<Self, TrackError> {
        camera
            .intrinsics
            .validate()
            .map_err(|e| TrackError::Config(e.to_string()))?;
        let board = target.board();
        let image = match target {
            TrackTarget::Image(i) | TrackTarget::ImageAndBoard { image: i, .. } => Some(i),
            _ => None,
        };
        if board.tags.is_empty() && image.is_none() {
            return Err(TrackError::Config("the board has no tags".into()));
        }
        let mut detector = detector;
        if !detector.families.contains(&board.family) {
            detector.families.push(board.family);
        }
        let fast = (config.fast_first && detector.decimate == 1 && !detector.upsample_pass)
            .then(|| {
                Detector::new(DetectorConfig {
                    decimate: 2,
                    second_pass_decimate: None,
                    // A frame without tags runs the full detector, fallback included.
                    fallback_decimate: None,
                    ..detector.clone()
                })
            })
            .transpose()?;
        Ok(Self {
            config,
            camera,
            board,
            image,
            fast,
            hidden_small: Vec::new(),
            since_full: 0,
            detector: Detector::new(detector)?,
            filter: PoseFilter::new(config.filter),
            state: TrackState::Searching,
            seen: 0,
            missed: 0,
            last_pose: None,
            last_filtered: None,
            roi: None,
        })
    }

    /// The current state.
    pub fn state(&self) -> TrackState {
        self.state
    }

    /// The tracked board (empty for a picture target).
    pub fn board(&self) -> &Board {
        &self.board
    }

    /// The tracked picture, for a picture target.
    pub fn image_target(&self) -> Option<&ImageTarget> {
        self.image.as_deref()
    }

    /// Back to Searching, forgetting history.
    pub fn reset(&mut self) {
        self.state = TrackState::Searching;
        self.seen = 0;
        self.missed = 0;
        self.last_pose = None;
        self.last_filtered = None;
        self.roi = None;
        self.filter.reset();
    }

    /// Processes one frame taken at `time_s` seconds.
    pub fn update(&mut self, frame: &GrayImage, time_s: f64) -> Result<TrackOutput, TrackError> {
        if frame.data.len() != frame.width as usize * frame.height as usize {
            return Err(TrackError::BadImage {
                width: frame.width,
                height: frame.height,
                len: frame.data.len(),
            });
        }
        if let Some(image) = self.image.take() {
            let out = self.update_image(&image, frame, time_s);
            self.image = Some(image);
            return out;
        }
        let (detections, used_roi) = self.detect_tags(frame)?;
        let mut out = self.update_with_detections(detections, time_s)?;
        out.used_roi = used_roi;
        Ok(out)
    }

    /// This frame's tag detections: around the last position first (when tracking and
    /// [`TrackerConfig::use_roi`]), the whole frame when that finds none of the board's tags.
    /// The flag says whether the region of interest sufficed. Corners refined as
    /// [`TrackerConfig::refine_corners`] says.
    fn detect_tags(&mut self, frame: &GrayImage) -> Result<(Vec<Detection>, bool), TrackError> {
        let (mut found, used_roi) = self.detect_tags_as_found(frame)?;
        crate::edges::refine_tag_corners(frame, self.config.refine_corners, &mut found);
        Ok((found, used_roi))
    }

    /// [`Tracker::detect_tags`] before the corners' refinement.
    fn detect_tags_as_found(
        &mut self,
        frame: &GrayImage,
    ) -> Result<(Vec<Detection>, bool), TrackError> {
        if self.config.use_roi && self.state != TrackState::Searching {
            if let Some([x0, y0, x1, y1]) = self.roi {
                let w = frame.width as f64;
                let h = frame.height as f64;
                let (x0, y0) = (x0.clamp(0.0, w - 1.0), y0.clamp(0.0, h - 1.0));
                let (x1, y1) = (x1.clamp(0.0, w), y1.clamp(0.0, h));
                if x1 - x0 >= 16.0 && y1 - y0 >= 16.0 && (x1 - x0) * (y1 - y0) < 0.6 * w * h {
                    let roi = [
                        x0 as u32,
                        y0 as u32,
                        (x1 - x0).ceil() as u32,
                        (y1 - y0).ceil() as u32,
                    ];
                    let d = self.detect_in(frame, Some(roi))?;
                    if d.iter().any(|d| self.board.contains(d)) {
                        return Ok((d, true));
                    }
                }
            }
        }
        Ok((self.detect_in(frame, None)?, false))
    }

    /// Tags in the frame (or in `roi`, `[x, y, width, height]`): the decimated search first
    /// when it suffices ([`TrackerConfig::fast_first`]), else the configured detector.
    fn detect_in(
        &mut self,
        frame: &GrayImage,
        roi: Option<[u32; 4]>,
    ) -> Result<Vec<Detection>, TrackError> {
        let run = |d: &mut Detector| match roi {
            Some([x, y, w, h]) => d.detect_roi(frame, x, y, w, h),
            None => d.detect(frame),
        };
        let (w, h) = (frame.width, frame.height);
        let Some(fast) = self.fast.as_mut() else {
            return run(&mut self.detector);
        };
        if self.since_full < FAST_RECHECK_DETECTIONS {
            let found = run(fast)?;
            let missing = self.small_missing(&found, w, h);
            if missing.is_some_and(|m| m.iter().all(|id| self.hidden_small.contains(id))) {
                self.since_full += 1;
                return Ok(found);
            }
        }
        let full = run(&mut self.detector)?;
        self.since_full = 0;
        // Small tags in view that the full passes missed too are hidden (by the prop, a
        // hand): until the next recheck the decimated search need not find them.
        self.hidden_small = self.small_missing(&full, w, h).unwrap_or_default();
        Ok(full)
    }

    /// The board's tags that `found` lacks although they lie wholly inside the `width` x
    /// `height` frame at the pose `found` gives and are under [`FAST_MIN_TAG_PX`] a side
    /// there (what the decimated search may miss); `None` when `found` gives no pose.
    fn small_missing(&self, found: &[Detection], width: u32, height: u32) -> Option<Vec<u32>> {
        let bp = self
            .board
            .estimate_pose_robust(&self.camera, found, None)
            .ok()
            .flatten()?;
        let pose = bp.estimate.best.pose;
        let (w, h) = (width as f64 - 0.5, height as f64 - 0.5);
        let seen = |id: u32| found.iter().any(|d| d.id == id && self.board.contains(d));
        let small = |tag: &crate::board::BoardTag| {
            let mut px = [DVec2::ZERO; 4];
            for (p, q) in px.iter_mut().zip(tag.object_points()) {
                // (None behind the camera.)
                match self.camera.pixel_from_camera(pose.transform_point(q)) {
                    Some(v) if v.x >= -0.5 && v.y >= -0.5 && v.x <= w && v.y <= h => *p = v,
                    // Not wholly in the frame: no pass decodes it.
                    _ => return false,
                }
            }
            crate::detect::min_side_px(&px) < FAST_MIN_TAG_PX
        };
        Some(
            self.board
                .tags
                .iter()
                .filter(|t| !seen(t.id) && small(t))
                .map(|t| t.id)
                .collect(),
        )
    }

    /// The board's pose from `detections` (`None` when too few of its tags, or degenerate
    /// corners such as a sliver of a tag: not seen).
    fn board_pose(
        &self,
        detections: &[Detection],
        time_s: f64,
    ) -> Result<Option<BoardPose>, TrackError> {
        // The pose expected on this frame decides between two disagreeing tags.
        let prior = self.filter.predict(time_s).or(self.last_pose);
        match self
            .board
            .estimate_pose_robust(&self.camera, detections, prior.as_ref())
        {
            Ok(p) => Ok(p),
            Err(TrackError::Pose(_)) => Ok(None),
            Err(e) => Err(e),
        }
    }

    /// Runs the state machine on detections made elsewhere.
    pub fn update_with_detections(
        &mut self,
        detections: Vec<Detection>,
        time_s: f64,
    ) -> Result<TrackOutput, TrackError> {
        let board_pose = self.board_pose(&detections, time_s)?;
        let observed =
            board_pose.and_then(|bp| self.accept(&bp.estimate, bp.correspondences, bp.used_ids));
        Ok(self.step(observed, detections, time_s))
    }

    /// This frame's pose from `estimate`: the planar solution consistent with the last pose,
    /// accepted when its RMS is within [`TrackerConfig::max_rms_px`].
    fn accept(
        &self,
        estimate: &crate::pose::PoseEstimate,
        pairs: Vec<(glam::DVec3, DVec2)>,
        ids: Vec<u32>,
    ) -> Option<Observed> {
        let c = match &self.last_pose {
            Some(prev) => estimate.choose_consistent(prev),
            None => estimate.best,
        };
        (c.rms_px <= self.config.max_rms_px).then_some((c, pairs, ids))
    }

    /// One frame of a picture target: tracking from the predicted pose, else detection; with
    /// tags too ([`TrackTarget::ImageAndBoard`]), the board's point pairs join the picture's
    /// in one fit.
    fn update_image(
        &mut self,
        image: &ImageTarget,
        frame: &GrayImage,
        time_s: f64,
    ) -> Result<TrackOutput, TrackError> {
        let prior = match self.state {
            TrackState::Searching => None,
            _ => self.filter.predict(time_s).or(self.last_pose),
        };
        let obs = locate_checked(image, frame, &self.camera, prior.as_ref());
        let tracked = obs.as_ref().is_some_and(|o| o.tracked);
        let (detections, board_pose) = if self.board.tags.is_empty() {
            (Vec::new(), None)
        } else {
            let (d, _) = self.detect_tags(frame)?;
            let bp = self.board_pose(&d, time_s)?;
            (d, bp)
        };
        let joint = match (obs, board_pose) {
            (Some(o), Some(bp)) => {
                let mut pairs = o.correspondences;
                pairs.extend(bp.correspondences);
                let (obj, img): (Vec<glam::DVec3>, Vec<DVec2>) = pairs.iter().copied().unzip();
                // Both sightings agree by construction of one marker frame; a failed joint fit
                // (degenerate, which the parts were not) falls back to the picture's own.
                let estimate = estimate_planar_pose(&self.camera, &obj, &img).unwrap_or(o.estimate);
                Some((estimate, pairs, bp.used_ids))
            }
            (Some(o), None) => Some((o.estimate, o.correspondences, Vec::new())),
            (None, Some(bp)) => Some((bp.estimate, bp.correspondences, bp.used_ids)),
            (None, None) => None,
        };
        let observed = joint.and_then(|(estimate, pairs, ids)| self.accept(&estimate, pairs, ids));
        let mut out = self.step(observed, detections, time_s);
        out.used_roi = tracked && out.raw.is_some();
        let corner_pose = out.raw.map(|c| c.pose).or(out.pose);
        out.target_corners_px = corner_pose.and_then(|p| image.corners_px(&self.camera, &p));
        Ok(out)
    }

    /// The state machine on this frame's accepted pose (with its point pairs and tag ids).
    fn step(
        &mut self,
        observed: Option<Observed>,
        detections: Vec<Detection>,
        time_s: f64,
    ) -> TrackOutput {
        let mut events = Vec::new();
        let n = self.config.frames_to_track.max(1);
        let m = self.config.frames_to_lose.max(1);
        let k = self.config.frames_to_search;
        let mut raw = None;
        let mut used_ids = Vec::new();
        if let Some((cand, correspondences, ids)) = observed {
            raw = Some(cand);
            used_ids = ids;
            self.missed = 0;
            self.seen += 1;
            match self.state {
                TrackState::Searching => {
                    self.seen = 1;
                    self.filter.reset();
                    self.state = TrackState::Detected;
                    events.push(TrackEvent::Found);
                    if n <= 1 {
                        self.state = TrackState::Tracked;
                        events.push(TrackEvent::Tracked);
                    }
                }
                TrackState::Detected => {
                    if self.seen >= n {
                        self.state = TrackState::Tracked;
                        events.push(TrackEvent::Tracked);
                    }
                }
                TrackState::Tracked => {}
                TrackState::Lost => {
                    self.filter.reset();
                    self.state = TrackState::Tracked;
                    events.push(TrackEvent::Recovered);
                }
            }
            self.last_pose = Some(cand.pose);
            let (obj, img): (Vec<glam::DVec3>, Vec<DVec2>) =
                correspondences.iter().copied().unzip();
            let noise = crate::pose::pose_noise(&self.camera, &cand.pose, &obj, &img);
            self.last_filtered = Some(self.filter.filter_measured(cand.pose, noise, time_s));
            self.roi = Some(self.target_box(&cand.pose, &correspondences));
        } else {
            self.seen = 0;
            self.missed += 1;
            match self.state {
                TrackState::Searching => {}
                TrackState::Detected => {
                    self.state = TrackState::Searching;
                    events.push(TrackEvent::Dropped);
                    self.last_pose = None;
                    self.roi = None;
                }
                TrackState::Tracked => {
                    if self.missed >= m {
                        self.state = TrackState::Lost;
                        events.push(TrackEvent::Lost);
                    }
                }
                TrackState::Lost => {
                    if self.missed >= m + k {
                        self.state = TrackState::Searching;
                        events.push(TrackEvent::SearchRestarted);
                        self.last_pose = None;
                        self.last_filtered = None;
                        self.roi = None;
                    }
                }
            }
        }
        let pose = match self.state {
            TrackState::Tracked => self.last_filtered,
            _ => None,
        };
        TrackOutput {
            state: self.state,
            events,
            pose,
            raw,
            coasting: self.state == TrackState::Tracked && raw.is_none(),
            detections,
            used_ids,
            used_roi: false,
            target_corners_px: None,
        }
    }

    /// Box around the whole board projected with `pose`, plus the seen corners, with margin.
    fn target_box(&self, pose: &Pose, seen: &[(glam::DVec3, DVec2)]) -> [f64; 4] {
        let mut pts: Vec<DVec2> = seen.iter().map(|(_, p)| *p).collect();
        for o in self.board.all_object_points() {
            if let Some(p) = self.camera.pixel_from_camera(pose.transform_point(o)) {
                if p.is_finite() {
                    pts.push(p);
                }
            }
        }
        let (mut lo, mut hi) = (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY));
        for p in pts {
            lo = lo.min(p);
            hi = hi.max(p);
        }
        let size = (hi - lo).max_element();
        let margin = self.config.roi_margin * size + 16.0;
        [lo.x - margin, lo.y - margin, hi.x + margin, hi.y + margin]
    }
}
