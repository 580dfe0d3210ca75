//! What one frame gives back: the composite, the tracking state, stage timings, masks and
//! (on request) the layers.

use glam::Mat4;
use pa_track::TrackState;

/// The animation times of one frame, seconds on the props' animation clock.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct FrameTimes {
    /// The in-between to show: the twin is drawn posed at this time.
    pub animation_s: f32,
    /// The key pose the real prop stands in: live texturing samples the frame where the key
    /// pose projects, and diminishing removes the key pose's silhouette.
    pub key_pose_s: f32,
}

/// Milliseconds spent in each stage of one frame.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct StageTimings {
    pub track_ms: f64,
    pub animate_ms: f64,
    pub texture_ms: f64,
    pub diminish_ms: f64,
    pub composite_ms: f64,
}

impl StageTimings {
    pub fn total_ms(&self) -> f64 {
        self.track_ms + self.animate_ms + self.texture_ms + self.diminish_ms + self.composite_ms
    }
}

/// The result of one frame.
#[derive(Debug, Clone)]
pub struct ArFrame {
    /// The composited frame (sRGB RGBA8); the untouched input when there is no pose.
    pub rgba8: Vec<u8>,
    pub state: TrackState,
    /// The pose used (filtered), `camera_from_marker`.
    pub camera_from_marker: Option<Mat4>,
    /// Reprojection error of the raw pose, pixels.
    pub reprojection_px: Option<f64>,
    pub timings: StageTimings,
    /// Pixels covered by the animated twin.
    pub twin_mask: Vec<bool>,
    /// Pixels covered by the key pose as the camera sees it (before dilation).
    pub key_mask: Vec<bool>,
    /// (live samples, fallback samples) of the twin.
    pub live_counts: (usize, usize),
    /// Per pixel, the [`pa_render::LiveSample`] code of the twin's surface (255 live sample,
    /// 1/2/3 fallback, 0 none); all 0 without live texturing.
    pub live_codes: Vec<u8>,
    /// The layers of the composite, for a compositor
    /// ([`ArPipeline::set_keep_passes`](super::ArPipeline::set_keep_passes)).
    pub passes: Option<ArPasses>,
}

/// The layers the composite is made of (sRGB RGBA8, full frame).
#[derive(Debug, Clone, PartialEq)]
pub struct ArPasses {
    /// The diminished plate: the frame with the real prop removed (the whole dilated key
    /// silhouette filled, also where the twin will cover it), before the twin is drawn.
    pub plate_rgba8: Vec<u8>,
    /// The twin alone with straight alpha: its colour and alpha 255 where it covers the
    /// pixel, all zero elsewhere (the composite's anti-aliased edge is not in it).
    pub twin_rgba8: Vec<u8>,
}
