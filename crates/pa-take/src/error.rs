//! The take's error: each message is the one `propsalive run` prints (a wrapped cause follows
//! it after `: ` in the binary's error chain).

use std::path::PathBuf;

/// What went wrong with a take.
#[derive(Debug, thiserror::Error)]
pub enum TakeError {
    /// A file of the take (or its input) could not be read or written safely.
    #[error(transparent)]
    Io(#[from] pa_io::IoError),
    /// Decoding a still or encoding the MP4.
    #[error(transparent)]
    Video(#[from] pa_video::VideoError),
    /// Encoding a PNG.
    #[error(transparent)]
    Image(#[from] image::ImageError),
    /// Writing JSON (a log line, `mp4.json`, `camera.gltf`).
    #[error(transparent)]
    Json(#[from] serde_json::Error),
    /// The size and modification time of a file could not be read.
    #[error("reading {}", path.display())]
    Stat {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// A file of the take could not be written.
    #[error("writing {}", path.display())]
    Write {
        path: PathBuf,
        #[source]
        source: pa_io::IoError,
    },
    /// A folder could not be made.
    #[error("creating {}", path.display())]
    CreateDir {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// `--passes` names a pass that does not exist.
    #[error("--passes: unknown pass {name:?} (use plate, twin, masks or all, comma-separated)")]
    UnknownPass { name: String },
    /// An image buffer does not hold `width x height` pixels (`what`: "frame" or "mask").
    #[error("{what} buffer has the wrong size")]
    BufferSize { what: &'static str },
    /// The input and the take folder overlap (after resolving links).
    #[error(
        "--input {} and --out {} overlap ({} and {}): the take would write over its own input; write the take to a folder outside the input (with or without --force)",
        input.display(), out.display(), input_resolved.display(), out_resolved.display()
    )]
    Overlap {
        input: PathBuf,
        out: PathBuf,
        input_resolved: PathBuf,
        out_resolved: PathBuf,
    },
    /// `--mp4` is the input or lies in the input folder.
    #[error("--mp4 {} is the input or inside the input folder; name a file elsewhere", mp4.display())]
    Mp4InInput { mp4: PathBuf },
    /// Another run holds the take's lock.
    #[error("{}: another run is writing this take ({holder}); wait for it to end, or use another --out folder", out.display())]
    Locked { out: PathBuf, holder: String },
    /// One of the take's folders (`frames/`, ...) is a link or not a folder.
    #[error("{}: is {kind}, not a folder; a take's {dir}/ must be a real folder inside it", path.display())]
    NotAFolder {
        path: PathBuf,
        kind: &'static str,
        dir: &'static str,
    },
    /// One of the take's files (`log.jsonl`, ...) is not a regular file.
    #[error("{}: is {kind}, not a regular file", path.display())]
    NotAFile { path: PathBuf, kind: &'static str },
    /// `--mp4` names a folder.
    #[error("--mp4 {} is a folder; give a file name", mp4.display())]
    Mp4IsFolder { mp4: PathBuf },
    /// `--mp4` names an existing file that this take did not write (without `--force`).
    /// `before_work`: refused before the take (the message also suggests another name).
    #[error(
        "--mp4 {} exists and is not the MP4 this take wrote; pass --force to replace it{}",
        mp4.display(),
        if *before_work { ", or name another file" } else { "" }
    )]
    Mp4NotOurs { mp4: PathBuf, before_work: bool },
    /// A frame of the take could not be read for the MP4.
    #[error("reading {} for the MP4", path.display())]
    Mp4Read {
        path: PathBuf,
        #[source]
        source: pa_video::still::StillError,
    },
    /// A frame of the take has another size than its first.
    #[error(
        "{} is {width}x{height} but the take's first frame is {first_width}x{first_height}: cannot encode them in one MP4",
        path.display()
    )]
    Mp4FrameSize {
        path: PathBuf,
        width: u32,
        height: u32,
        first_width: u32,
        first_height: u32,
    },
    /// The camera export's frame rate is not positive.
    #[error("camera export: fps must be positive, got {fps}")]
    ExportFps { fps: f32 },
    /// The camera export's intrinsics cannot make a glTF camera.
    #[error("camera export: bad intrinsics (fy {fy}, {width}x{height})")]
    ExportIntrinsics { fy: f64, width: u32, height: u32 },
    /// No still of the take has a pose.
    #[error("camera export: none of the {stills} still(s) has a camera pose (no marker tracked): nothing to export")]
    ExportNoPose { stills: usize },
    /// A still has two poses.
    #[error("camera export: still {index} has two poses")]
    ExportTwoPoses { index: usize },
    /// A still's pose is not finite.
    #[error("still {index}: camera_from_marker is not finite")]
    PoseNotFinite { index: usize },
    /// A still's pose has scale or shear.
    #[error("still {index}: camera_from_marker is not a rigid transform")]
    PoseNotRigid { index: usize },
    /// A still could not be read (a frame of the take is skipped with this message).
    #[error(transparent)]
    Still(pa_video::still::StillError),
    /// A decoded frame does not hold `width x height` RGBA pixels.
    #[error("the decoder returned a {width}x{height} frame with the wrong number of bytes")]
    FrameBytes { width: u32, height: u32 },
    /// A camera source gave something other than a captured frame (`desc`: the source).
    #[error("{desc}: not a camera frame")]
    NotCameraFrame { desc: String },
    /// A captured frame does not hold `width x height` RGBA pixels (`desc`: the source).
    #[error("{desc}: a {width}x{height} frame with the wrong number of bytes")]
    CameraFrameBytes {
        desc: String,
        width: u32,
        height: u32,
    },
    /// A line could not be appended to the log.
    #[error("writing {}", path.display())]
    AppendLog {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// The log could not be flushed or synced.
    #[error(transparent)]
    SyncLog(std::io::Error),
    /// A symbolic link in the take could not be removed before writing its file.
    #[error("removing the link {}", path.display())]
    RemoveLink {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// Frames of the take were made with other settings (`live`: a camera run, which cannot
    /// re-render them).
    #[error(
        "{}: {frames} frame(s) of this take were made with another exposure, bit depth or shot file; use a new --out folder{}",
        out.display(),
        if *live { "" } else { ", or --force to re-render them" }
    )]
    StaleSettings {
        out: PathBuf,
        frames: usize,
        live: bool,
    },
    /// Files in the take's output folders that its log does not know (without `--force`).
    #[error(
        "{}: {} file(s) this take's log does not know ({}): another take? Refusing to overwrite; use a new --out folder, or --force",
        out.display(),
        files.len(),
        crate::open::first_files(files)
    )]
    ForeignFiles { out: PathBuf, files: Vec<String> },
    /// No still of a folder is readable (`first_error`: why the first one is not).
    #[error(
        "{}: no readable still (tried {tried} file(s); the first: {})",
        dir.display(),
        first_error.as_ref().map_or_else(|| "none".to_string(), |e| e.to_string())
    )]
    NoReadableStill {
        dir: PathBuf,
        tried: usize,
        first_error: Option<pa_video::still::StillError>,
    },
}
