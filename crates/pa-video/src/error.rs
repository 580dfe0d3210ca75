//! The crate's error type.

use std::path::PathBuf;

/// Everything that can go wrong reading, writing or capturing video.
///
/// Every variant that concerns a file or a device names it (`path` / `device`), so the
/// message alone tells the user what to fix. Variants are grouped: input files, output files,
/// settings, cameras.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum VideoError {
    /// The operating system refused an operation on a file (missing, permissions, disk full).
    #[error("{path}: cannot {action}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// What was being done (`"open"`, `"read"`, `"write"`, `"rename into place"`...).
        action: &'static str,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },

    /// The file is not a container this build recognises (or not a video at all).
    #[error("{path}: {container} is not a video container this build can read{hint}")]
    UnsupportedContainer {
        /// The file.
        path: PathBuf,
        /// What the file looks like (`"Matroska/WebM"`, `"AVI"`, `"an unrecognised format"`).
        container: String,
        /// What to do instead: `"; rebuild with `--features ffmpeg`..."` when FFmpeg could read
        /// it, advice for stills, or empty.
        hint: String,
    },

    /// The container is fine but the video stream needs a decoder this build lacks.
    #[error(
        "{path}: {codec} cannot be decoded by this build ({reason}); \
         rebuild with `--features {feature}` to decode it through FFmpeg"
    )]
    NeedsFeature {
        /// The file.
        path: PathBuf,
        /// The codec and profile, e.g. `"HEVC (hvc1)"`, `"H.264 High profile"`.
        codec: String,
        /// Why the built-in decoder cannot handle it, e.g. `"B-frames (frame reordering)"`.
        reason: String,
        /// The cargo feature that would handle it (`"ffmpeg"`).
        feature: &'static str,
    },

    /// The stream is a kind no decoder of this crate supports, with any feature.
    #[error("{path}: unsupported video: {detail}")]
    Unsupported {
        /// The file.
        path: PathBuf,
        /// What is unsupported.
        detail: String,
    },

    /// The file is damaged, truncated or built to mislead (sizes that do not fit, missing
    /// tables, counts that disagree).
    #[error("{path}: corrupt or truncated video: {detail}")]
    Corrupt {
        /// The file.
        path: PathBuf,
        /// What is wrong, with offsets where known.
        detail: String,
    },

    /// The frame size is beyond what this crate accepts (it would need an absurd allocation or
    /// exceeds the codec's limits).
    #[error("{path}: frame size {width}x{height} is too large (limit {limit})")]
    TooLarge {
        /// The file.
        path: PathBuf,
        /// Width in pixels.
        width: u64,
        /// Height in pixels.
        height: u64,
        /// The limit that was exceeded, in words.
        limit: String,
    },

    /// The decoder rejected a frame.
    #[error("{path}: cannot decode frame {frame}: {detail}")]
    Decode {
        /// The file.
        path: PathBuf,
        /// Index of the frame (decode order) that failed.
        frame: u64,
        /// The decoder's message.
        detail: String,
    },

    /// The encoder rejected a frame or its settings.
    #[error("{path}: cannot encode frame {frame}: {detail}")]
    Encode {
        /// The output file.
        path: PathBuf,
        /// Index of the frame that failed.
        frame: u64,
        /// The encoder's message.
        detail: String,
    },

    /// The output file exists and the writer was not told to replace it.
    #[error("{path} already exists and replacing it was not allowed{kept}")]
    AlreadyExists {
        /// The final output path.
        path: PathBuf,
        /// `" - the finished video was kept as <temporary path>"` when the file appeared while
        /// writing, so that the take is not lost; else empty.
        kept: String,
    },

    /// A frame given to the writer does not match the writer's size.
    #[error("{path}: frame {frame} has {actual} bytes, expected {width}x{height}x4 = {expected}")]
    FrameSize {
        /// The output file.
        path: PathBuf,
        /// Index of the offending frame.
        frame: u64,
        /// The writer's width.
        width: u32,
        /// The writer's height.
        height: u32,
        /// Bytes expected.
        expected: usize,
        /// Bytes given.
        actual: usize,
    },

    /// A setting is out of range.
    #[error("invalid setting {name} = {value}: {reason}")]
    InvalidSetting {
        /// The setting.
        name: &'static str,
        /// Its value, as given.
        value: String,
        /// The allowed range or the reason.
        reason: String,
    },

    /// A feature of this crate is needed that the build does not have (e.g. cameras).
    #[error("{what} is not available in this build; rebuild with `--features {feature}`")]
    FeatureDisabled {
        /// What was asked for, e.g. `"camera capture (/dev/video0)"`.
        what: String,
        /// The cargo feature.
        feature: &'static str,
    },

    /// The camera device does not exist.
    #[error("camera {device} not found (is it plugged in? `ls /dev/video*` lists cameras)")]
    DeviceNotFound {
        /// The device path.
        device: PathBuf,
    },

    /// The camera is used by another program.
    #[error("camera {device} is busy: another program is using it (close it and try again)")]
    DeviceBusy {
        /// The device path.
        device: PathBuf,
    },

    /// The camera disappeared while streaming (unplugged, cable, driver reset). Frames
    /// captured before remain valid: keep the take and end the run cleanly.
    #[error("camera {device} disconnected after {frames} frames; frames captured before are kept")]
    DeviceLost {
        /// The device path.
        device: PathBuf,
        /// Frames delivered before the loss.
        frames: u64,
    },

    /// The camera offers no format this crate can convert, or refused the requested one.
    #[error("camera {device}: {detail}")]
    DeviceFormat {
        /// The device path.
        device: PathBuf,
        /// What was offered / refused.
        detail: String,
    },

    /// A still could not be used (unreadable, truncated, too large...); the message is the
    /// still's own and names the file.
    #[error(transparent)]
    Still(#[from] crate::still::StillError),

    /// An input is neither a folder of stills, a video file nor a camera (a FIFO, a
    /// device, a socket...).
    #[error(
        "{path}: is {kind}, not a folder of stills, a video file or a camera (camera:/dev/videoN)"
    )]
    NotAnInput {
        /// The input as given.
        path: PathBuf,
        /// What it is, in words (`"a FIFO"`).
        kind: String,
    },

    /// An input does not exist.
    #[error(
        "{path}: no such file or folder (give a folder of stills, a video file, or camera:/dev/videoN)"
    )]
    NoSuchInput {
        /// The input as given.
        path: PathBuf,
    },

    /// A folder of stills holds no still.
    #[error("{path}: no images (.png, .jpg, .jpeg, .tif, .tiff) in this folder")]
    NoStills {
        /// The folder.
        path: PathBuf,
    },

    /// A video read at random ([`crate::source::SeekableVideo`]) turned out to have no frames.
    #[error("{path}: the video has no frames")]
    NoFrames {
        /// The video file.
        path: PathBuf,
    },

    /// A frame a seek asked for could not be reached (the video ended before it, with no
    /// frame decoded on the way).
    #[error("{path}: cannot reach frame {frame}")]
    FrameOutOfReach {
        /// The video file.
        path: PathBuf,
        /// The frame asked for.
        frame: usize,
    },

    /// A folder of stills cannot be listed.
    #[error("reading folder {path}")]
    ReadFolder {
        /// The folder.
        path: PathBuf,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },

    /// Any other failure talking to the camera.
    #[error("camera {device}: cannot {action}: {source}")]
    Device {
        /// The device path.
        device: PathBuf,
        /// What was being done.
        action: &'static str,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
}

impl VideoError {
    /// True when the error means "the live source is gone": the frames captured so far are
    /// good, so the caller should keep the take and finish cleanly rather than fail.
    pub fn is_source_lost(&self) -> bool {
        matches!(self, VideoError::DeviceLost { .. })
    }

    /// True when rebuilding with a cargo feature would get past this error.
    pub fn needs_feature(&self) -> Option<&'static str> {
        match self {
            VideoError::NeedsFeature { feature, .. }
            | VideoError::FeatureDisabled { feature, .. } => Some(feature),
            VideoError::UnsupportedContainer { hint, .. } if hint.contains("--features ffmpeg") => {
                Some("ffmpeg")
            }
            _ => None,
        }
    }

    pub(crate) fn io(path: &std::path::Path, action: &'static str, source: std::io::Error) -> Self {
        VideoError::Io {
            path: path.to_path_buf(),
            action,
            source,
        }
    }

    pub(crate) fn corrupt(path: &std::path::Path, detail: impl Into<String>) -> Self {
        VideoError::Corrupt {
            path: path.to_path_buf(),
            detail: detail.into(),
        }
    }
}
