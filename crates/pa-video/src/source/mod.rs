//! Frame sources: where a command's camera frames come from, one family for `run`, `track`
//! and `preview`.
//!
//! * [`InputSpec`] / [`parse_input`]: what an `--input` names: a folder of stills, a video
//!   file, or a camera device (`camera:/dev/video0`, `camera:N`, `/dev/video*`).
//! * [`list_stills`]: a folder's stills (`.png`, `.jpg`, `.jpeg`, `.tif`, `.tiff`) in
//!   natural order ([`natural_cmp`]: `f2` before `f10`), the stop-motion norm.
//! * [`StillsSource`], [`VideoSource`], [`CameraSource`]: the frames of a folder of stills,
//!   a video file and a live camera, one at a time, all through the [`Source`] trait. Each
//!   gives a [`SourceFrame`]: its index in the input, a name for logs, its [`Pixels`] (a still
//!   is read only when the caller wants it) and whether it starts a new sequence. A video
//!   frame the decoder rejects is an [`Pixels::Unreadable`] frame (the reader goes on with
//!   the next) until [`MAX_VIDEO_ERRORS_IN_ROW`] in a row; a camera that disappears is
//!   [`Next::Lost`] (keep what was captured and end cleanly).
//! * [`SeekableVideo`]: a video file read at random (any frame, forwards or back; back
//!   rewinds), with each frame's pixels or why the decoder rejected it ([`SeekFrame`]).
//!
//! # The tracker policy
//!
//! [`SourceFrame::starts_sequence`] tells the tracker what to do with its history:
//! - **Stills: the tracker is reset before each still.** Every still starts a new sequence:
//!   stills of a stop-motion take are not a video (the camera may be moved between them), so
//!   a still's tracking depends on that still alone.
//! - **Video and camera frames: the tracker is kept across frames.** They are one sequence;
//!   only the first frame (the first of a video read from its start, the first captured)
//!   starts one.
//!
//! A command may treat *more* frames as independent than this (`propsalive run` resets the
//! tracker before every frame of any input, so that a resumed take is identical to an
//! uninterrupted one), never fewer.

mod camera;
mod seek;
mod stills;
mod video;

use std::cmp::Ordering;
use std::path::{Path, PathBuf};

pub use camera::{open_camera, CameraSource};
pub use seek::{SeekFrame, SeekableVideo, UnreadableFrame};
pub use stills::StillsSource;
pub use video::{VideoSource, MAX_VIDEO_ERRORS_IN_ROW};

use crate::{Frame, VideoError};

/// The file extensions of stills (compared case-insensitively).
pub const STILL_EXTS: &[&str] = &["png", "jpg", "jpeg", "tif", "tiff"];

/// True when `p` has one of `exts` as its extension (case-insensitive).
pub fn has_ext(p: &Path, exts: &[&str]) -> bool {
    p.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| exts.iter().any(|x| e.eq_ignore_ascii_case(x)))
}

/// What an `--input` names.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum InputSpec {
    /// A folder of stills.
    Folder(PathBuf),
    /// A video file.
    Video(PathBuf),
    /// A live camera (a Video4Linux device).
    Camera(PathBuf),
}

/// Reads an input: an existing folder is a folder of stills; `camera:DEVICE`, `camera:N`
/// (= /dev/videoN), `camera` (= /dev/video0) or a `/dev/video*` path is a camera; any other
/// existing file is a video (the reader tells what it is). Anything else (a FIFO, a missing
/// path) is [`VideoError::NotAnInput`] / [`VideoError::NoSuchInput`].
pub fn parse_input(input: &Path) -> Result<InputSpec, VideoError> {
    if input.is_dir() {
        return Ok(InputSpec::Folder(input.to_path_buf()));
    }
    let s = input.to_string_lossy();
    if let Some(rest) = s.strip_prefix("camera:") {
        let device = if rest.is_empty() {
            "/dev/video0".to_string()
        } else if rest.bytes().all(|b| b.is_ascii_digit()) {
            format!("/dev/video{rest}")
        } else {
            rest.to_string()
        };
        return Ok(InputSpec::Camera(PathBuf::from(device)));
    }
    if s == "camera" && !input.exists() {
        return Ok(InputSpec::Camera(PathBuf::from("/dev/video0")));
    }
    if s.starts_with("/dev/video") {
        return Ok(InputSpec::Camera(input.to_path_buf()));
    }
    if input.is_file() {
        return Ok(InputSpec::Video(input.to_path_buf()));
    }
    if let Ok(meta) = std::fs::metadata(input) {
        return Err(VideoError::NotAnInput {
            path: input.to_path_buf(),
            kind: pa_io::kind_of(&meta).to_string(),
        });
    }
    Err(VideoError::NoSuchInput {
        path: input.to_path_buf(),
    })
}

/// The stills of a folder (regular files with a [`STILL_EXTS`] extension), in natural order
/// of their file names; none is [`VideoError::NoStills`].
pub fn list_stills(dir: &Path) -> Result<Vec<PathBuf>, VideoError> {
    let mut stills: Vec<PathBuf> = std::fs::read_dir(dir)
        .map_err(|source| VideoError::ReadFolder {
            path: dir.to_path_buf(),
            source,
        })?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.is_file() && has_ext(p, STILL_EXTS))
        .collect();
    stills.sort_by(|a, b| natural_cmp(&file_name(a), &file_name(b)));
    if stills.is_empty() {
        return Err(VideoError::NoStills {
            path: dir.to_path_buf(),
        });
    }
    Ok(stills)
}

/// A path's file name as text (lossy), empty for none.
pub(crate) fn file_name(p: &Path) -> String {
    p.file_name()
        .unwrap_or_default()
        .to_string_lossy()
        .into_owned()
}

/// Natural order: digit runs compare by value ("f2" < "f10"), the rest case-insensitively.
pub fn natural_cmp(a: &str, b: &str) -> Ordering {
    let (mut a, mut b) = (a.as_bytes(), b.as_bytes());
    loop {
        match (a.first(), b.first()) {
            (None, None) => return Ordering::Equal,
            (None, _) => return Ordering::Less,
            (_, None) => return Ordering::Greater,
            (Some(x), Some(y)) if x.is_ascii_digit() && y.is_ascii_digit() => {
                let na = a.iter().take_while(|c| c.is_ascii_digit()).count();
                let nb = b.iter().take_while(|c| c.is_ascii_digit()).count();
                let (da, db) = (&a[..na], &b[..nb]);
                let ta: &[u8] = {
                    let z = da.iter().take_while(|c| **c == b'0').count();
                    &da[z.min(na.saturating_sub(1))..]
                };
                let tb: &[u8] = {
                    let z = db.iter().take_while(|c| **c == b'0').count();
                    &db[z.min(nb.saturating_sub(1))..]
                };
                let o = ta.len().cmp(&tb.len()).then(ta.cmp(tb)).then(na.cmp(&nb));
                if o != Ordering::Equal {
                    return o;
                }
                a = &a[na..];
                b = &b[nb..];
            }
            (Some(x), Some(y)) => {
                let o = x.to_ascii_lowercase().cmp(&y.to_ascii_lowercase());
                if o != Ordering::Equal {
                    return o;
                }
                a = &a[1..];
                b = &b[1..];
            }
        }
    }
}

/// The pixels of one input frame.
#[derive(Debug)]
pub enum Pixels {
    /// A decoded or captured RGBA8 frame (video, camera).
    Frame(Frame),
    /// A still, not read yet: read it with [`crate::still::read_still`] when the frame is
    /// to be processed.
    Still(PathBuf),
    /// The frame could not be decoded (the source goes on with the next one): why.
    Unreadable(VideoError),
}

/// One frame of an input.
#[derive(Debug)]
pub struct SourceFrame {
    /// Its place in the input: a still's in natural order, a video frame's in presentation
    /// order, a camera frame's in capture order (0-based).
    pub index: usize,
    /// A name for logs: the still's file name, the video's file name, the camera's
    /// description.
    pub name: String,
    /// True when the frame starts a new sequence, so the tracker is reset before it (see the
    /// module docs): every still; the first frame of a video or a camera.
    pub starts_sequence: bool,
    /// Its pixels.
    pub pixels: Pixels,
}

/// What a source gives next.
#[derive(Debug)]
pub enum Next {
    /// A frame.
    Frame(SourceFrame),
    /// No more frames.
    End,
    /// A live source disappeared ([`VideoError::is_source_lost`]): keep what was captured
    /// and end cleanly.
    Lost(VideoError),
}

/// A folder of stills, a video file or a camera, frame after frame in index order.
pub trait Source {
    /// Frames the source holds, when known (a camera: `None`; a video: the container's
    /// count until the end is reached, then the frames really decoded).
    fn frame_count(&self) -> Option<usize>;
    /// True for a live source (a camera: its frames are new ones).
    fn live(&self) -> bool {
        false
    }
    /// The next frame; an error ends the input (a damaged video frame is not an error but
    /// an [`Pixels::Unreadable`] frame).
    fn next(&mut self) -> Result<Next, VideoError>;
    /// One line saying what the source is.
    fn describe(&self) -> String;
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn natural_order() {
        let mut v = vec!["f10.png", "f2.png", "F1.png", "f02.png", "a.png"];
        v.sort_by(|a, b| natural_cmp(a, b));
        assert_eq!(v, ["a.png", "F1.png", "f2.png", "f02.png", "f10.png"]);
    }

    #[test]
    fn inputs_parse() {
        let dir = tempfile::tempdir().expect("tmp");
        assert_eq!(
            parse_input(dir.path()).expect("folder"),
            InputSpec::Folder(dir.path().to_path_buf())
        );
        let video = dir.path().join("take.mp4");
        std::fs::write(&video, b"x").expect("write");
        assert_eq!(
            parse_input(&video).expect("video"),
            InputSpec::Video(video.clone())
        );
        assert_eq!(
            parse_input(Path::new("camera:/dev/video2")).expect("camera"),
            InputSpec::Camera("/dev/video2".into())
        );
        assert_eq!(
            parse_input(Path::new("camera:1")).expect("camera"),
            InputSpec::Camera("/dev/video1".into())
        );
        assert_eq!(
            parse_input(Path::new("/dev/video3")).expect("camera"),
            InputSpec::Camera("/dev/video3".into())
        );
        let err = parse_input(&dir.path().join("nope.mp4")).expect_err("missing");
        assert!(err.to_string().contains("no such file"), "{err}");
    }

    #[test]
    fn stills_are_listed_in_natural_order() {
        let dir = tempfile::tempdir().expect("tmp");
        for n in ["s10.png", "s2.JPG", "s1.tif", "notes.txt"] {
            std::fs::write(dir.path().join(n), b"x").expect("write");
        }
        std::fs::create_dir(dir.path().join("sub.png")).expect("mkdir");
        let names: Vec<String> = list_stills(dir.path())
            .expect("stills")
            .iter()
            .map(|p| file_name(p))
            .collect();
        assert_eq!(names, ["s1.tif", "s2.JPG", "s10.png"]);
        let empty = tempfile::tempdir().expect("tmp");
        let err = list_stills(empty.path()).expect_err("no stills");
        assert!(matches!(err, VideoError::NoStills { .. }), "{err}");
        assert!(err.to_string().contains("no images"), "{err}");
    }
}
