//! A live camera as a source.

use std::path::Path;

use super::{Next, Pixels, Source, SourceFrame};
use crate::{Camera, FrameSource, VideoError};

/// Opens a camera at `size` and a frame rate of `fps` rounded (1 to 1000): the `v4l`
/// feature; without it, [`VideoError::FeatureDisabled`] naming the feature.
pub fn open_camera(device: &Path, size: (u32, u32), fps: f32) -> Result<Camera, VideoError> {
    let rate = (fps.round() as u32).clamp(1, 1000);
    Camera::open(device, size.0, size.1, rate)
}

/// A live camera: the frames it delivers, in capture order, one sequence started by the
/// first. A camera that disappears is [`Next::Lost`] once. Generic over the camera so that
/// tests can feed it a fake.
pub struct CameraSource<S: FrameSource = Camera> {
    camera: S,
    name: String,
    captured: usize,
}

impl<S: FrameSource> CameraSource<S> {
    /// Frames from `camera`.
    pub fn new(camera: S) -> Self {
        let name = camera.describe();
        Self {
            camera,
            name,
            captured: 0,
        }
    }

    /// The camera.
    pub fn camera(&self) -> &S {
        &self.camera
    }
}

impl<S: FrameSource> Source for CameraSource<S> {
    fn frame_count(&self) -> Option<usize> {
        None
    }

    fn live(&self) -> bool {
        true
    }

    fn next(&mut self) -> Result<Next, VideoError> {
        let f = match self.camera.next_frame() {
            Ok(Some(f)) => f,
            Ok(None) => return Ok(Next::End),
            Err(e) if e.is_source_lost() => return Ok(Next::Lost(e)),
            Err(e) => return Err(e),
        };
        let index = self.captured;
        self.captured += 1;
        Ok(Next::Frame(SourceFrame {
            index,
            name: self.name.clone(),
            starts_sequence: index == 0,
            pixels: Pixels::Frame(f),
        }))
    }

    fn describe(&self) -> String {
        self.camera.describe()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Fps, Frame, Timestamp};

    /// `frames` frames, then "disconnected" once, then nothing.
    struct FakeCamera {
        frames: u64,
        given: u64,
        lost: bool,
    }

    impl FrameSource for FakeCamera {
        fn next_frame(&mut self) -> Result<Option<Frame>, VideoError> {
            if self.given < self.frames {
                let i = self.given;
                self.given += 1;
                return Ok(Some(Frame {
                    index: i,
                    pts: Timestamp {
                        ticks: i as i64,
                        timescale: 24,
                    },
                    width: 2,
                    height: 2,
                    rgba: vec![0; 16],
                }));
            }
            if self.lost {
                return Ok(None);
            }
            self.lost = true;
            Err(VideoError::DeviceLost {
                device: "/dev/video7".into(),
                frames: self.given,
            })
        }
        fn frame_size(&self) -> (u32, u32) {
            (2, 2)
        }
        fn fps(&self) -> Option<Fps> {
            Fps::new(24, 1).ok()
        }
        fn describe(&self) -> String {
            "fake camera".into()
        }
    }

    #[test]
    fn a_camera_is_one_sequence_then_lost_once() {
        let mut s = CameraSource::new(FakeCamera {
            frames: 2,
            given: 0,
            lost: false,
        });
        assert!(s.live() && s.frame_count().is_none());
        for i in 0..2 {
            let Ok(Next::Frame(f)) = s.next() else {
                panic!("frame {i}");
            };
            assert_eq!((f.index, f.starts_sequence), (i, i == 0));
            assert_eq!(f.name, "fake camera");
        }
        assert!(matches!(s.next(), Ok(Next::Lost(e)) if e.is_source_lost()));
        assert!(matches!(s.next(), Ok(Next::End)));
    }
}
