//! Frames to registration views: each frame tracked on its own (the tracker reset before it,
//! one sighting, no filtering), untracked frames counted and left out.

use pa_camera::CameraModel;
use pa_track::{DetectorConfig, TrackTarget, Tracker, TrackerConfig};

use super::{RegisterError, RegisterView};

/// Tracks frames one by one for registration.
pub struct ViewTracker {
    tracker: Tracker,
    camera: CameraModel,
    /// Frames offered.
    pub frames: usize,
}

impl ViewTracker {
    /// A tracker of `target` (a board, a picture or both) seen by `camera` that treats every
    /// frame as a new sequence.
    pub fn new(camera: CameraModel, target: TrackTarget) -> Result<Self, RegisterError> {
        let config = TrackerConfig::per_still();
        let tracker = Tracker::new(camera, target, DetectorConfig::default(), config)?;
        Ok(Self {
            tracker,
            camera,
            frames: 0,
        })
    }

    /// The view of one frame, or `None` when the marker is not found in it.
    pub fn view(
        &mut self,
        name: String,
        rgba8: Vec<u8>,
        width: u32,
        height: u32,
    ) -> Result<Option<RegisterView>, RegisterError> {
        self.frames += 1;
        let expected = width as usize * height as usize * 4;
        if rgba8.len() != expected || width == 0 || height == 0 {
            return Err(RegisterError::BadFrame {
                index: self.frames - 1,
                width,
                height,
                expected,
                got: rgba8.len(),
            });
        }
        let gray = crate::ar::gray_from_rgba(&rgba8, width, height).map_err(|_| {
            RegisterError::BadFrame {
                index: self.frames - 1,
                width,
                height,
                expected,
                got: rgba8.len(),
            }
        })?;
        self.tracker.reset();
        let out = self.tracker.update(&gray, 0.0)?;
        Ok(out.pose.map(|p| RegisterView {
            name,
            width,
            height,
            rgba8,
            camera: self.camera,
            camera_from_marker: p.to_mat4(),
        }))
    }
}

/// Checks that enough of `frames` frames were tracked (`tracked` of them).
pub fn check_tracked(tracked: usize, frames: usize, needed: usize) -> Result<(), RegisterError> {
    if tracked < needed {
        return Err(RegisterError::NotTracked {
            tracked,
            frames,
            needed,
        });
    }
    Ok(())
}
