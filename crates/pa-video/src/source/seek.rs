//! Random access to a video's frames, as the preview needs it (animation frame `i` shows
//! frame `i` of the video): playing forward decodes one frame a step; going back opens the
//! file again ([`VideoSource::rewind`]) and decodes from its start (a video is not seekable
//! frame by frame), so scrubbing backwards through a long video is slow. The last frame
//! reached is kept, so asking for it again decodes nothing.

use std::path::Path;

use super::{Next, Pixels, Source, VideoSource};
use crate::{VideoError, VideoInfo};

/// Why a frame reached by [`SeekableVideo::seek`] has no pixels (the decoder rejected it):
/// the decoder's message.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{message}")]
pub struct UnreadableFrame {
    /// The message, naming the file and the frame.
    pub message: String,
}

/// A frame reached by [`SeekableVideo::seek`].
#[derive(Debug, Clone, PartialEq)]
pub struct SeekFrame {
    /// Its index in the video.
    pub index: usize,
    /// Whether it starts the video's sequence (frame 0: the tracker policy of
    /// [`crate::source`]).
    pub starts_sequence: bool,
    /// Its RGBA8 pixels, or why the decoder rejected it.
    pub rgba: Result<Vec<u8>, UnreadableFrame>,
}

/// A video file read at random: [`SeekableVideo::seek`] decodes up to any frame.
pub struct SeekableVideo {
    video: VideoSource,
    /// Frames in the file, once the end was reached.
    count: Option<usize>,
    /// The last frame decoded.
    cache: Option<SeekFrame>,
}

impl SeekableVideo {
    /// Opens `path` (`pa-video`'s errors name the file, the codec and the feature).
    pub fn open(path: &Path) -> Result<Self, VideoError> {
        Ok(Self::new(VideoSource::open(path)?))
    }

    /// Random access to `video`, read from where it stands.
    pub fn new(video: VideoSource) -> Self {
        Self {
            video,
            count: None,
            cache: None,
        }
    }

    /// The video read in order.
    pub fn video(&self) -> &VideoSource {
        &self.video
    }

    /// The video's container and stream.
    pub fn info(&self) -> &VideoInfo {
        self.video.info()
    }

    /// The frames in the file, once a seek reached its end.
    pub fn frame_count(&self) -> Option<usize> {
        self.count
    }

    /// `frame`, or the last frame once the length is known and `frame` is past it.
    pub fn clamp(&self, frame: usize) -> usize {
        match self.count {
            Some(n) if n > 0 => frame.min(n - 1),
            _ => frame,
        }
    }

    /// Decodes up to frame `want` (or the last frame, if the video is shorter): its index,
    /// whether it starts the video's sequence, and its pixels or why they are missing. Each
    /// seek gets the full allowance of damaged frames in a row.
    pub fn seek(&mut self, want: usize) -> Result<SeekFrame, VideoError> {
        if let Some(cached) = &self.cache {
            if cached.index == want {
                return Ok(cached.clone());
            }
        }
        if want < self.video.next_index() {
            self.video.rewind()?;
        }
        // Each seek gets the full allowance of damaged frames in a row.
        self.video.reset_error_run();
        let mut last = None;
        while self.video.next_index() <= want {
            match self.video.next()? {
                Next::Frame(f) => {
                    let rgba = match f.pixels {
                        Pixels::Frame(frame) => Ok(frame.rgba),
                        Pixels::Unreadable(e) => Err(e.to_string()),
                        Pixels::Still(p) => Err(format!("{}: not a video frame", p.display())),
                    };
                    last = Some(SeekFrame {
                        index: f.index,
                        starts_sequence: f.starts_sequence,
                        rgba: rgba.map_err(|message| UnreadableFrame { message }),
                    });
                }
                Next::End => {
                    self.count = Some(self.video.next_index());
                    break;
                }
                Next::Lost(e) => return Err(e),
            }
        }
        match last {
            Some(found) => {
                self.cache = Some(found.clone());
                Ok(found)
            }
            // The end was reached before `want` with nothing new decoded: the last frame.
            None => match self.count {
                Some(0) => Err(VideoError::NoFrames {
                    path: self.video.path().to_path_buf(),
                }),
                Some(n) if want >= n => self.seek(n - 1),
                _ => Err(VideoError::FrameOutOfReach {
                    path: self.video.path().to_path_buf(),
                    frame: want,
                }),
            },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_video_is_read_at_random_forwards_and_back() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("take.mp4");
        let fps = crate::Fps::new(24, 1).unwrap();
        let mut w =
            crate::Mp4Writer::create(&path, 64, 48, crate::Mp4WriterOptions::new(fps)).unwrap();
        // Frame i is flat grey 40 + 40 i.
        for i in 0..4u8 {
            w.write_frame(&[40 + 40 * i, 40 + 40 * i, 40 + 40 * i, 255].repeat(64 * 48))
                .unwrap();
        }
        w.finish().unwrap();
        let mut s = SeekableVideo::open(&path).unwrap();
        assert_eq!((s.info().width, s.info().height), (64, 48));
        let grey = |s: &mut SeekableVideo, want: usize| -> (usize, u8) {
            let f = s.seek(want).unwrap();
            let data = f.rgba.unwrap();
            (f.index, data[64 * 24 * 4 + 32 * 4])
        };
        let near = |v: u8, want: u8| v.abs_diff(want) <= 3;
        let (i, v) = grey(&mut s, 2);
        assert!(i == 2 && near(v, 120), "{i} {v}");
        // Past the end: the last frame, and the length is known from then on.
        let (i, v) = grey(&mut s, 9);
        assert!(i == 3 && near(v, 160), "{i} {v}");
        assert_eq!(s.frame_count(), Some(4));
        assert_eq!(s.clamp(40), 3);
        // Back: the file is read again from its start.
        let (i, v) = grey(&mut s, 1);
        assert!(i == 1 && near(v, 80), "{i} {v}");
        let (i, v) = grey(&mut s, 1);
        assert!(i == 1 && near(v, 80), "cached: {i} {v}");
        // The tracker policy: a video is one sequence, started by its first frame.
        assert!(
            s.seek(0).unwrap().starts_sequence,
            "frame 0 starts the sequence"
        );
        assert!(!s.seek(2).unwrap().starts_sequence, "frame 2 continues it");
        let err = SeekableVideo::open(&dir.path().join("missing.mp4"))
            .err()
            .unwrap()
            .to_string();
        assert!(err.contains("missing.mp4"), "{err}");
    }

    #[test]
    fn seek_errors_name_the_file() {
        let e = VideoError::NoFrames {
            path: "dir/take.mp4".into(),
        };
        assert_eq!(e.to_string(), "dir/take.mp4: the video has no frames");
        let e = VideoError::FrameOutOfReach {
            path: "take.mp4".into(),
            frame: 7,
        };
        assert_eq!(e.to_string(), "take.mp4: cannot reach frame 7");
    }
}
