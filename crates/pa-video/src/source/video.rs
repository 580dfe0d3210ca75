//! A video file as a source.

use std::path::{Path, PathBuf};

use super::{file_name, Next, Pixels, Source, SourceFrame};
use crate::{FrameSource, VideoError, VideoInfo, VideoReader};

/// Decode errors in a row after which a video is given up (a file that is damaged through).
pub const MAX_VIDEO_ERRORS_IN_ROW: usize = 25;

/// A video file: frame `i` (presentation order) is frame `i` of the input; the frames are one
/// sequence, started by frame 0. A frame the decoder rejects ([`VideoError::Decode`],
/// [`VideoError::Corrupt`]) is an [`Pixels::Unreadable`] frame and the reader goes on with the
/// next one, until [`MAX_VIDEO_ERRORS_IN_ROW`] in a row, which is an error. Generic over the
/// reader so that tests can feed it a fake.
pub struct VideoSource<S: FrameSource = VideoReader> {
    reader: S,
    path: PathBuf,
    name: String,
    count: Option<usize>,
    next_index: usize,
    errors_in_row: usize,
}

impl VideoSource<VideoReader> {
    /// Opens a video file (`pa-video`'s errors name the file, the codec and the feature).
    pub fn open(path: &Path) -> Result<Self, VideoError> {
        let reader = VideoReader::open(path)?;
        let count = reader.info().frame_count.map(|c| c as usize);
        Ok(Self::new(reader, path, count))
    }

    /// The video's container and stream.
    pub fn info(&self) -> &VideoInfo {
        self.reader.info()
    }

    /// Back to frame 0: the file is opened again (a video is not seekable frame by frame).
    /// The frame count learnt so far is kept.
    pub fn rewind(&mut self) -> Result<(), VideoError> {
        self.reader = VideoReader::open(&self.path)?;
        self.next_index = 0;
        self.errors_in_row = 0;
        Ok(())
    }
}

impl<S: FrameSource> VideoSource<S> {
    /// Frames from `reader`, which reads the file `path`; `count`: the frames the container
    /// announces, when it does.
    pub fn new(reader: S, path: &Path, count: Option<usize>) -> Self {
        Self {
            reader,
            path: path.to_path_buf(),
            name: file_name(path),
            count,
            next_index: 0,
            errors_in_row: 0,
        }
    }

    /// The reader.
    pub fn reader(&self) -> &S {
        &self.reader
    }

    /// The video file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The video's file name (what logs call each of its frames).
    pub fn name(&self) -> &str {
        &self.name
    }

    /// The index of the frame [`Source::next`] gives next.
    pub fn next_index(&self) -> usize {
        self.next_index
    }

    /// Starts counting damaged frames in a row from zero again (a caller that reads the
    /// video in short runs, as the preview does, gives each run the full allowance).
    pub fn reset_error_run(&mut self) {
        self.errors_in_row = 0;
    }
}

impl<S: FrameSource> Source for VideoSource<S> {
    fn frame_count(&self) -> Option<usize> {
        self.count
    }

    fn next(&mut self) -> Result<Next, VideoError> {
        let index = self.next_index;
        let pixels = match self.reader.next_frame() {
            Ok(Some(f)) => {
                self.errors_in_row = 0;
                Pixels::Frame(f)
            }
            Ok(None) => {
                // The frames really in the file (the container's count may differ).
                self.count = Some(index);
                return Ok(Next::End);
            }
            Err(e) if e.is_source_lost() => return Ok(Next::Lost(e)),
            // One damaged frame: given as unreadable; the reader goes on with the next one.
            Err(e @ (VideoError::Decode { .. } | VideoError::Corrupt { .. }))
                if self.errors_in_row < MAX_VIDEO_ERRORS_IN_ROW =>
            {
                self.errors_in_row += 1;
                Pixels::Unreadable(e)
            }
            Err(e) => return Err(e),
        };
        self.next_index += 1;
        if self.count.is_some_and(|n| self.next_index > n) {
            self.count = Some(self.next_index);
        }
        Ok(Next::Frame(SourceFrame {
            index,
            name: self.name.clone(),
            starts_sequence: index == 0,
            pixels,
        }))
    }

    fn describe(&self) -> String {
        self.reader.describe()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Fps, Frame, Timestamp};

    /// Frames 0.. with a decode error at the given indices.
    struct FakeVideo {
        frames: usize,
        bad: Vec<usize>,
        at: usize,
    }

    impl FrameSource for FakeVideo {
        fn next_frame(&mut self) -> Result<Option<Frame>, VideoError> {
            let i = self.at;
            if i >= self.frames {
                return Ok(None);
            }
            self.at += 1;
            if self.bad.contains(&i) {
                return Err(VideoError::Decode {
                    path: "clip.mp4".into(),
                    frame: i as u64,
                    detail: "damaged slice".into(),
                });
            }
            Ok(Some(Frame {
                index: i as u64,
                pts: Timestamp {
                    ticks: i as i64,
                    timescale: 24,
                },
                width: 2,
                height: 2,
                rgba: vec![i as u8; 16],
            }))
        }
        fn frame_size(&self) -> (u32, u32) {
            (2, 2)
        }
        fn fps(&self) -> Option<Fps> {
            Fps::new(24, 1).ok()
        }
        fn describe(&self) -> String {
            "fake video".into()
        }
    }

    #[test]
    fn damaged_frames_are_unreadable_and_the_count_is_learnt() {
        let fake = FakeVideo {
            frames: 4,
            bad: vec![1],
            at: 0,
        };
        let mut s = VideoSource::new(fake, Path::new("dir/clip.mp4"), Some(9));
        let mut seen = Vec::new();
        while let Next::Frame(f) = s.next().expect("next") {
            assert_eq!(f.name, "clip.mp4");
            assert_eq!(f.starts_sequence, f.index == 0);
            seen.push(match f.pixels {
                Pixels::Frame(fr) => fr.rgba[0] as i32,
                Pixels::Unreadable(e) => {
                    assert!(e.to_string().contains("damaged slice"), "{e}");
                    -1
                }
                Pixels::Still(_) => panic!("a still from a video"),
            });
        }
        assert_eq!(seen, [0, -1, 2, 3]);
        assert_eq!(s.frame_count(), Some(4), "the frames really in the file");
    }

    #[test]
    fn a_video_damaged_through_is_given_up() {
        let fake = FakeVideo {
            frames: 100,
            bad: (0..100).collect(),
            at: 0,
        };
        let mut s = VideoSource::new(fake, Path::new("clip.mp4"), None);
        for _ in 0..MAX_VIDEO_ERRORS_IN_ROW {
            assert!(matches!(
                s.next(),
                Ok(Next::Frame(SourceFrame {
                    pixels: Pixels::Unreadable(_),
                    ..
                }))
            ));
        }
        assert!(s.next().is_err());
        s.reset_error_run();
        assert!(s.next().is_ok());
    }
}
