//! `propsalive run SHOT.toml --input INPUT --out DIR`: a take through the pipeline. INPUT is
//! a folder of stills (PNG/JPEG/TIFF, natural order: the stop-motion norm), a video file
//! (frame `i` of the video is still `i`), or a live camera (`camera:/dev/video0`, the `v4l`
//! feature). Still `i` shows animation frame `i / exposure` (`--exposure 1` = ones, `2` =
//! twos) with the shot's present key prop in front of the camera; each still goes through the
//! real pipeline (track -> place -> animate -> texture -> diminish -> composite).
//!
//! Outputs, in DIR:
//! - `frames/NNNNNN.png`: one frame per still, numbered by the still's index in sorted order
//!   (the video's frame index; the camera's capture index), 8- or 16-bit (`--bit-depth`),
//!   written atomically (temporary file, fsync, rename).
//! - `log.jsonl`: one JSON object per still: `index`, `input` (file name; the video's file
//!   name for every frame of a video; `inputs/NNNNNN.png` for a camera), `input_bytes`,
//!   `input_mtime_ns`, `anim_frame`, `key_pose`, `state`, `camera_from_marker` (16 numbers,
//!   column-major, or null), `reprojection_px`, `timings_ms` (track, animate, texture,
//!   diminish, composite, encode), `output` (`frames/NNNNNN.png`, or null), `skipped` (the
//!   reason a still was not rendered, or null), `passes` (the pass files, with `--passes`),
//!   and the take's settings (`exposure`, `bit_depth`, `shot_hash`). Each line is appended and
//!   fsynced before its frame is written.
//! - `camera.gltf`: the tracked camera of every still of the take with a pose in the log, as
//!   an animated glTF 2.0 camera (see `camera_export`), rewritten atomically at the end of
//!   each run; not written (a note says so) when no still was tracked.
//! - With `--passes plate,twin,masks`: `plate/NNNNNN.png` (the diminished plate: the frame
//!   with the real prop removed, before the twin is drawn; at the take's bit depth),
//!   `twin/NNNNNN.png` (the twin alone, RGBA with straight alpha: 255 where it covers the
//!   pixel, 0 elsewhere; at the take's bit depth), `masks/NNNNNN.png` (8-bit RGB: R = the key
//!   pose's silhouette as the camera sees it, G = the twin's). An untracked still has a plate
//!   equal to the still, an empty twin and empty masks.
//! - With a camera: `inputs/NNNNNN.png`, every captured frame as it came from the camera
//!   (saved atomically before it is processed), so the take can be rendered again later
//!   (`--input DIR/inputs`).
//! - With `--mp4 FILE`: the take's frames in index order, at the shot's fps, as an H.264 MP4
//!   (`pa-video`), written after the run (also after a resumed run: always the whole take)
//!   under a temporary name and renamed; `mp4.json` in DIR records what was written.
//!
//! Decisions:
//! - **Every still is independent.** The tracker is reset before each still, runs without
//!   temporal filtering or region-of-interest search, and needs one sighting (stills of a
//!   stop-motion take are not a video: the camera may be moved between them). So a frame
//!   depends only on its still and the shot, and a resumed take is identical to an
//!   uninterrupted one. Frames of a video file and of a camera are treated the same way, so a
//!   take gives the same frames from stills, from a video of them, or re-rendered from its
//!   saved camera inputs.
//! - **Resume.** A still whose log line and frame (and the passes asked for) exist, and whose
//!   file name, size and modification time match the log, is not processed again (for a
//!   video: the video file's name, size and modification time, so a changed video re-renders).
//!   A truncated last log line is ignored; at start the log is rewritten atomically with one
//!   line per index; at the end of a run it is compacted again if a still was redone. A
//!   video is decoded from its start (frames are not seekable) up to the last frame to do.
//!   A camera run adds frames after the last index of the take.
//! - **Re-shot stills** (name, size or mtime differ from the log): the frame is re-rendered
//!   and stderr says `re-shot: frame N replaced`.
//! - **Never overwrite silently.** A file in `frames/` (or `plate/`, `twin/`, `masks/`) the
//!   log does not know (another take, a hand-made file) stops the run unless `--force`. A
//!   camera run numbers its frames on after every file in `inputs/`, so no captured input is
//!   ever replaced (one saved by a capture cut short before its log line is kept). A take
//!   made with another exposure, bit depth or shot file stops the run unless `--force` (which
//!   re-renders those frames; a camera run refuses). An existing `--mp4` file is replaced only
//!   when it is the one this take wrote (as `mp4.json` records it), or with `--force`.
//! - **Bad stills** are skipped, logged with the reason, and leave a gap in the numbering:
//!   an unreadable file, or a still whose size differs from the first readable still (the
//!   camera and the take have one resolution); for a video, a frame the decoder rejects (the
//!   reader goes on with the next one). The run goes on, exits 0 and ends with a warning
//!   summary. A folder where no still is readable is an error. A video this build cannot
//!   decode fails at once with `pa-video`'s message (it names the file, the codec and the
//!   cargo feature that would decode it).
//! - **Ending a take.** Ctrl-C (SIGINT) finishes the frame being processed, keeps everything
//!   (log, frames, `camera.gltf`) and stops; a second Ctrl-C quits at once (every file is
//!   written atomically, so even that leaves no half-written frame). For a camera that is the
//!   normal end of the take (exit 0, MP4 written); for files the take is incomplete (exit 130,
//!   no MP4; run the same command again to resume). A camera that disappears mid-take ends the
//!   run cleanly: what was captured is kept, logged, exported and encoded, with a warning.
//! - **Progress**: a progress bar with frames/s and the time left on a terminal; plain lines
//!   every 10 s when stderr is not a terminal.
//! - **16-bit output:** the pipeline works in 8-bit sRGB. Pixels it did not change keep the
//!   still's own 16-bit values; changed pixels (the twin, the filled region) are the 8-bit
//!   result widened (`v * 257`). The MP4 is 8-bit.

use std::collections::{BTreeMap, HashSet};
use std::io::{IsTerminal, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant, UNIX_EPOCH};

use anyhow::{bail, Context, Result};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use pa_camera::{CameraModel, Intrinsics};
use pa_pipeline::ar::{ArPipeline, ArSettings, StageTimings};
use pa_pipeline::shot::Shot;
use pa_render::Renderer;
use pa_track::board::BoardTag;
use pa_track::{Board, DetectorConfig, TagFamily, TrackTarget, Tracker, TrackerConfig};
use pa_video::source::{
    CameraSource, Next as SourceNext, Pixels, Source, SourceFrame, StillsSource, VideoSource,
};
use pa_video::still::StillBudget;
use pa_video::{Fps, Mp4Writer, Mp4WriterOptions, VideoReader};
use serde::{Deserialize, Serialize};

#[derive(clap::Args)]
pub struct Args {
    /// The shot file (TOML: model, animation, fps, key poses, camera, marker, placement).
    pub shot: PathBuf,
    /// Where the stills come from: a folder of stills (.png, .jpg, .jpeg, .tif, .tiff,
    /// natural order), a video file (frame i = still i; MP4/MOV H.264 without B-frames in the
    /// default build, anything FFmpeg reads with `--features ffmpeg`), or a live camera
    /// `camera:/dev/video0` (`camera:N` = /dev/videoN; needs `--features v4l`).
    #[arg(long)]
    pub input: PathBuf,
    /// Take folder: frames/NNNNNN.png and log.jsonl. An interrupted take resumes here.
    #[arg(long)]
    pub out: PathBuf,
    /// Stills per animation frame: 1 = ones, 2 = twos. Still i shows frame i / exposure.
    /// Every still is tracked on its own (no temporal filtering), so a resumed take is
    /// identical to an uninterrupted one.
    #[arg(long, default_value_t = 1)]
    pub exposure: u32,
    /// Bits per channel of the output PNGs: 8 or 16.
    #[arg(long, default_value_t = 8)]
    pub bit_depth: u8,
    /// Replace frames the take's log does not know, re-render frames made with other
    /// settings, and replace an existing --mp4 file.
    #[arg(long)]
    pub force: bool,
    /// Also encode the take's frames (index order, the shot's fps) as an H.264 MP4, after the
    /// run; a resumed run encodes the whole take again.
    #[arg(long, value_name = "FILE")]
    pub mp4: Option<PathBuf>,
    /// Extra passes for a compositor, comma-separated: plate (the diminished plate alone),
    /// twin (the twin alone, RGBA with alpha), masks (R = key pose, G = twin), or all.
    #[arg(long, value_delimiter = ',', value_name = "PASSES")]
    pub passes: Vec<String>,
    /// At most this many stills: the first N of a folder or video; for a camera, capture N
    /// frames and stop (default: until Ctrl-C).
    #[arg(long, value_name = "N")]
    pub frames: Option<usize>,
    /// Camera input: the frame size to ask for, WIDTHxHEIGHT [default: the shot's
    /// calibration size, else 1280x720]. The camera's answer is what is used.
    #[arg(long, value_name = "WxH")]
    pub camera_size: Option<String>,
}

/// One line of `log.jsonl`.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct Entry {
    pub index: usize,
    pub input: String,
    pub input_bytes: u64,
    pub input_mtime_ns: u64,
    pub anim_frame: u32,
    pub key_pose: String,
    #[serde(default)]
    pub state: Option<String>,
    #[serde(default)]
    pub camera_from_marker: Option<Vec<f32>>,
    #[serde(default)]
    pub reprojection_px: Option<f64>,
    #[serde(default)]
    pub timings_ms: Option<Timings>,
    #[serde(default)]
    pub output: Option<String>,
    #[serde(default)]
    pub skipped: Option<String>,
    /// The pass files written with this frame (`plate/NNNNNN.png`, ...), with `--passes`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub passes: Option<Vec<String>>,
    /// What was written for this still (the frame and its passes): each file's size and
    /// XXH3-64 hash. Resume keeps a frame only when its files still match.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub written: Option<Vec<Written>>,
    pub exposure: u32,
    pub bit_depth: u8,
    pub shot_hash: String,
}

/// One file a still wrote, as the log records it.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct Written {
    /// Relative to the take folder (`frames/000003.png`).
    pub path: String,
    pub bytes: u64,
    /// XXH3-64 of the bytes, 16 hex digits.
    pub xxh3: String,
}

impl Written {
    fn of(path: String, bytes: &[u8]) -> Self {
        Self {
            path,
            bytes: bytes.len() as u64,
            xxh3: format!("{:016x}", xxhash_rust::xxh3::xxh3_64(bytes)),
        }
    }

    /// Why the file in `take` does not match the record (None when it does). A symbolic link
    /// is never followed: it does not match.
    fn mismatch(&self, take: &Path) -> Option<String> {
        let p = take.join(&self.path);
        let meta = match std::fs::symlink_metadata(&p) {
            Ok(m) => m,
            Err(_) => return Some(format!("{} is missing", self.path)),
        };
        if !meta.is_file() {
            return Some(format!("{} is {}", self.path, pa_io::kind_of(&meta)));
        }
        if meta.len() != self.bytes {
            return Some(format!(
                "{} has {} bytes, {} were written",
                self.path,
                meta.len(),
                self.bytes
            ));
        }
        let bytes = match pa_io::read_regular(&p, self.bytes, "a frame of the take") {
            Ok(b) => b,
            Err(e) => return Some(e.to_string()),
        };
        let h = format!("{:016x}", xxhash_rust::xxh3::xxh3_64(&bytes));
        (h != self.xxh3).then(|| format!("{} was changed after it was written", self.path))
    }
}

/// Stage timings of one still, milliseconds.
#[derive(Debug, Clone, Copy, Serialize, Deserialize, PartialEq)]
pub struct Timings {
    pub track: f64,
    pub animate: f64,
    pub texture: f64,
    pub diminish: f64,
    pub composite: f64,
    pub encode: f64,
}

fn frame_name(index: usize) -> String {
    format!("{index:06}.png")
}

/// FNV-1a of the bytes, hex.
fn hash_hex(bytes: &[u8]) -> String {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for b in bytes {
        h ^= *b as u64;
        h = h.wrapping_mul(0x0100_0000_01b3);
    }
    format!("{h:016x}")
}

/// (size in bytes, modification time in ns since the epoch) of a file.
fn file_stamp(p: &Path) -> Result<(u64, u64)> {
    let m = std::fs::metadata(p).with_context(|| format!("reading {}", p.display()))?;
    let mtime = m
        .modified()
        .ok()
        .and_then(|t| t.duration_since(UNIX_EPOCH).ok())
        .map(|d| d.as_nanos() as u64)
        .unwrap_or(0);
    Ok((m.len(), mtime))
}

/// Reads a take's log: the last line for each index wins; an unparsable last line (a write
/// cut short) is ignored, an unparsable line elsewhere is reported and ignored.
pub fn read_log(path: &Path) -> Result<BTreeMap<usize, Entry>> {
    let mut map = BTreeMap::new();
    if std::fs::symlink_metadata(path).is_err() {
        return Ok(map);
    }
    let text = pa_io::read_regular(path, MAX_LOG_BYTES, "a take's log")?;
    let text = String::from_utf8_lossy(&text);
    let lines: Vec<&str> = text.split('\n').collect();
    for (n, line) in lines.iter().enumerate() {
        if line.trim().is_empty() {
            continue;
        }
        match serde_json::from_str::<Entry>(line) {
            Ok(e) => {
                map.insert(e.index, e);
            }
            Err(e) if n + 1 == lines.len() => {
                errln!(
                    "note: {}: ignoring a truncated last line ({e})",
                    path.display()
                );
            }
            Err(e) => errln!(
                "warning: {}: ignoring unreadable line {} ({e})",
                path.display(),
                n + 1
            ),
        }
    }
    Ok(map)
}

/// The budget for a take's log: about two million stills.
const MAX_LOG_BYTES: u64 = 1 << 30;

/// The log's text: one line per index, in index order.
fn log_text(entries: &BTreeMap<usize, Entry>) -> Result<String> {
    let mut text = String::new();
    for e in entries.values() {
        text.push_str(&serde_json::to_string(e)?);
        text.push('\n');
    }
    Ok(text)
}

/// Rewrites the log (atomically) unless it already holds exactly this text: a run with
/// nothing to do writes nothing (a finished take on a read-only disk can be checked).
fn write_log(path: &Path, entries: &BTreeMap<usize, Entry>) -> Result<()> {
    let text = log_text(entries)?;
    write_durable_if_changed(path, text.as_bytes())
}

/// [`write_durable`] unless `path` is a regular file holding exactly `bytes` already.
fn write_durable_if_changed(path: &Path, bytes: &[u8]) -> Result<()> {
    let same = std::fs::symlink_metadata(path)
        .is_ok_and(|m| m.is_file() && m.len() == bytes.len() as u64)
        && pa_io::read_regular(path, bytes.len() as u64, "a file of the take")
            .is_ok_and(|old| old == bytes);
    if same {
        return Ok(());
    }
    write_durable(path, bytes)
}

/// Writes `bytes` to `path` atomically; `pa_io::write_atomic` also syncs the folder, so the
/// rename is durable.
fn write_durable(path: &Path, bytes: &[u8]) -> Result<()> {
    pa_io::write_atomic(path, bytes).with_context(|| format!("writing {}", path.display()))
}

pub(crate) fn board_from_shot(shot: &Shot, shot_path: &Path) -> Result<Board> {
    let family: TagFamily = shot
        .marker
        .family
        .parse()
        .with_context(|| format!("{}: [marker] family", shot_path.display()))?;
    let layout = pa_track::family_layout(family)?;
    let mut tags = Vec::new();
    for t in &shot.marker.tags {
        if t.id >= layout.id_count {
            bail!(
                "{}: tag id {} does not exist in {family} (ids 0..{})",
                shot_path.display(),
                t.id,
                layout.id_count
            );
        }
        tags.push(BoardTag {
            id: t.id,
            center_m: glam::DVec2::new(t.center_m[0], t.center_m[1]),
            size_m: t.size_m,
            rotation_rad: 0.0,
        });
    }
    Ok(Board { family, tags })
}

// --- input ---------------------------------------------------------------------------------

/// What `--input` names (`pa_video::source`).
pub(crate) use pa_video::source::InputSpec;

/// Reads `--input` (`pa_video::source::parse_input`): a folder of stills, a video file or a
/// camera; the message of a bad input starts with `--input`.
pub(crate) fn parse_input(input: &Path) -> Result<InputSpec> {
    pa_video::source::parse_input(input).map_err(|e| anyhow::anyhow!("--input {e}"))
}

/// The shot's camera at a frame size: its calibration (scaled to the size when the aspect
/// ratio agrees), or an ideal pinhole with its vertical field of view.
pub(crate) fn camera_for_shot(
    shot: &Shot,
    shot_path: &Path,
    width: u32,
    height: u32,
    frame_desc: &str,
) -> Result<CameraModel> {
    match (&shot.camera.calibration, shot.camera.fov_y_deg) {
        (Some(c), _) => {
            let path = Shot::resolve(shot_path, c);
            let model = pa_camera::calib::load_calibration(&path)
                .with_context(|| format!("loading the calibration {}", path.display()))?;
            let k = super::track::fit_intrinsics(
                &model.intrinsics,
                width,
                height,
                &path.display().to_string(),
                frame_desc,
            )?;
            Ok(CameraModel {
                intrinsics: k,
                distortion: model.distortion,
            })
        }
        (None, Some(fov)) => {
            if !(fov.is_finite() && fov > 1.0 && fov < 179.0) {
                bail!(
                    "{}: [camera] fov_y_deg must be in (1, 179), got {fov}",
                    shot_path.display()
                );
            }
            Ok(CameraModel::pinhole(Intrinsics::from_fov_y(
                fov.to_radians(),
                width,
                height,
            )?))
        }
        (None, None) => bail!(
            "{}: [camera] needs calibration or fov_y_deg",
            shot_path.display()
        ),
    }
}

/// The size to ask a camera for: `--camera-size`, else the shot's calibration size, else
/// 1280x720.
pub(crate) fn camera_request(
    camera_size: Option<&str>,
    shot: &Shot,
    shot_path: &Path,
) -> Result<(u32, u32)> {
    if let Some(s) = camera_size {
        return super::parse_size(s).with_context(|| format!("--camera-size {s}"));
    }
    if let Some(c) = &shot.camera.calibration {
        let path = Shot::resolve(shot_path, c);
        let model = pa_camera::calib::load_calibration(&path)
            .with_context(|| format!("loading the calibration {}", path.display()))?;
        return Ok((model.intrinsics.width, model.intrinsics.height));
    }
    Ok((1280, 720))
}

/// Opens a camera at the shot's rate (the `v4l` feature; without it, `pa-video`'s error
/// naming the feature).
pub(crate) fn open_camera(device: &Path, size: (u32, u32), fps: f32) -> Result<pa_video::Camera> {
    Ok(pa_video::source::open_camera(device, size, fps)?)
}

/// The passes asked for with `--passes`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
struct PassSet {
    pub plate: bool,
    pub twin: bool,
    pub masks: bool,
}

impl PassSet {
    fn parse(list: &[String]) -> Result<PassSet> {
        let mut p = PassSet::default();
        for item in list {
            match item.trim().to_ascii_lowercase().as_str() {
                "plate" => p.plate = true,
                "twin" => p.twin = true,
                "masks" | "mask" => p.masks = true,
                "all" => {
                    p = PassSet {
                        plate: true,
                        twin: true,
                        masks: true,
                    }
                }
                "" => {}
                other => bail!(
                    "--passes: unknown pass {other:?} (use plate, twin, masks or all, comma-separated)"
                ),
            }
        }
        Ok(p)
    }

    fn any(self) -> bool {
        self.plate || self.twin || self.masks
    }

    /// The folders of the passes asked for.
    fn dirs(self) -> Vec<&'static str> {
        [
            (self.plate, "plate"),
            (self.twin, "twin"),
            (self.masks, "masks"),
        ]
        .into_iter()
        .filter_map(|(on, d)| on.then_some(d))
        .collect()
    }
}

/// Where the stills come from, resolved.
enum SourceSpec {
    Stills(Vec<PathBuf>),
    Video {
        reader: VideoReader,
        path: PathBuf,
        stamp: (u64, u64),
    },
    Camera(pa_video::Camera),
}

struct Config {
    /// What one input frame is called in messages: "still" or "frame".
    unit: &'static str,
    /// The input in words, for the summary.
    input_desc: String,
    width: u32,
    height: u32,
    camera: CameraModel,
    board: Board,
    model: pa_model::Model,
    animation: usize,
    marker_from_prop: glam::Mat4,
    fps: f32,
    key_name: String,
    key_time_s: f32,
    shot_hash: String,
    passes: PassSet,
}

fn resolve(args: &Args) -> Result<(Config, SourceSpec)> {
    if args.exposure == 0 || args.exposure > 1000 {
        bail!(
            "--exposure must be 1 (ones), 2 (twos), ... up to 1000, got {}",
            args.exposure
        );
    }
    if args.bit_depth != 8 && args.bit_depth != 16 {
        bail!("--bit-depth must be 8 or 16, got {}", args.bit_depth);
    }
    if args.frames == Some(0) {
        bail!("--frames must be at least 1");
    }
    let passes = PassSet::parse(&args.passes)?;
    let shot = Shot::load(&args.shot)?;
    let shot_text = pa_io::read_regular(&args.shot, MAX_SHOT_BYTES, "a shot file")?;
    let input = parse_input(&args.input)?;
    check_no_overlap(&input, &args.out, args.mp4.as_deref())?;
    if let Some(mp4) = &args.mp4 {
        Fps::from_f64(shot.fps as f64)
            .with_context(|| format!("{}: fps {} for the MP4", args.shot.display(), shot.fps))?;
        check_mp4_target(mp4, &args.out, args.force)?;
    }
    if args.camera_size.is_some() && !matches!(input, InputSpec::Camera(_)) {
        bail!("--camera-size is for a camera input (--input camera:/dev/videoN)");
    }
    let (source, unit, input_desc, width, height, first_desc) = match input {
        InputSpec::Folder(dir) => {
            let (stills, _) = super::track::list_frames(&dir)?;
            let mut first_error = None;
            let found = stills.iter().find_map(|p| {
                match pa_video::still::still_dimensions(p, &StillBudget::default()) {
                    Ok(d) => Some((p, d)),
                    Err(e) => {
                        first_error.get_or_insert(e);
                        None
                    }
                }
            });
            let Some((first, (width, height))) = found else {
                bail!(
                    "{}: no readable still (tried {} file(s); the first: {})",
                    dir.display(),
                    stills.len(),
                    first_error.map_or_else(|| "none".to_string(), |e| e.to_string())
                );
            };
            let first = first.display().to_string();
            let desc = format!("{} still(s) in {}", stills.len(), dir.display());
            (
                SourceSpec::Stills(stills),
                "still",
                desc,
                width,
                height,
                first,
            )
        }
        InputSpec::Video(path) => {
            // pa-video's errors name the file, the codec and the feature: said as they are.
            let reader = VideoReader::open(&path)?;
            let info = reader.info();
            let (width, height) = (info.width, info.height);
            let desc = pa_video::FrameSource::describe(&reader);
            let stamp = file_stamp(&path)?;
            if let Some(f) = info.fps {
                if (f.as_f64() - shot.fps as f64).abs() > 1e-3 * f.as_f64() {
                    errln!(
                        "note: {} runs at {f} fps and the shot at {} fps: frame i is still i (animation frame i / exposure), whatever the video's timing",
                        path.display(),
                        shot.fps
                    );
                }
            }
            let first = path.display().to_string();
            (
                SourceSpec::Video {
                    reader,
                    path,
                    stamp,
                },
                "frame",
                desc,
                width,
                height,
                first,
            )
        }
        InputSpec::Camera(device) => {
            let size = camera_request(args.camera_size.as_deref(), &shot, &args.shot)?;
            let camera = open_camera(&device, size, shot.fps)?;
            let f = camera.format();
            let desc = pa_video::FrameSource::describe(&camera);
            (
                SourceSpec::Camera(camera),
                "frame",
                desc,
                f.width,
                f.height,
                device.display().to_string(),
            )
        }
    };
    if args.mp4.is_some() {
        // Before the take, not after it: OpenH264 refuses frames below 16x16.
        Mp4Writer::check_frame_size(width, height)
            .with_context(|| format!("--mp4 for {first_desc} ({width}x{height})"))?;
    }
    let camera = camera_for_shot(&shot, &args.shot, width, height, &first_desc)?;
    let board = board_from_shot(&shot, &args.shot)?;
    let model_path = Shot::resolve(&args.shot, &shot.model);
    let model = pa_model::Model::load(&model_path)
        .with_context(|| format!("loading the model {}", model_path.display()))?;
    let animation = shot.check_model(&args.shot, &model)?;
    let key = &shot.key_poses[shot.present_key_index()];
    let cfg = Config {
        unit,
        input_desc,
        width,
        height,
        camera,
        board,
        model,
        animation,
        marker_from_prop: shot.placement.marker_from_prop(),
        fps: shot.fps,
        key_name: key.name.clone(),
        key_time_s: key.frame as f32 / shot.fps,
        shot_hash: hash_hex(&shot_text),
        passes,
    };
    Ok((cfg, source))
}

/// The budget for a shot file (read again here for its hash).
const MAX_SHOT_BYTES: u64 = 4 << 20;

/// `p` made absolute with every symbolic link resolved as far as the path exists (the rest,
/// not yet created, appended as written).
fn resolved(p: &Path) -> PathBuf {
    let abs = absolute(p);
    let mut existing = abs.as_path();
    let mut rest = Vec::new();
    loop {
        if let Ok(c) = existing.canonicalize() {
            let mut out = c;
            for r in rest.iter().rev() {
                out.push(r);
            }
            return out;
        }
        match (existing.parent(), existing.file_name()) {
            (Some(parent), Some(name)) => {
                rest.push(name.to_os_string());
                existing = parent;
            }
            _ => return abs,
        }
    }
}

/// Refuses a take whose outputs could overwrite its inputs: the input (a folder of stills or
/// a video file) inside the take folder or the take folder inside the input folder, after
/// resolving links, and an `--mp4` that is the input or lies in the input folder. Checked
/// with or without `--force`.
fn check_no_overlap(input: &InputSpec, out: &Path, mp4: Option<&Path>) -> Result<()> {
    let input_path = match input {
        InputSpec::Folder(p) | InputSpec::Video(p) => resolved(p),
        InputSpec::Camera(_) => return Ok(()),
    };
    let out_path = resolved(out);
    if input_path.starts_with(&out_path) || out_path.starts_with(&input_path) {
        bail!(
            "--input {} and --out {} overlap ({} and {}): the take would write over its own input; write the take to a folder outside the input (with or without --force)",
            match input {
                InputSpec::Folder(p) | InputSpec::Video(p) => p.display().to_string(),
                InputSpec::Camera(p) => p.display().to_string(),
            },
            out.display(),
            input_path.display(),
            out_path.display()
        );
    }
    if let Some(mp4) = mp4 {
        let mp4_path = resolved(mp4);
        if mp4_path == input_path
            || (matches!(input, InputSpec::Folder(_)) && mp4_path.starts_with(&input_path))
        {
            bail!(
                "--mp4 {} is the input or inside the input folder; name a file elsewhere",
                mp4.display()
            );
        }
    }
    Ok(())
}

// --- frame sources -------------------------------------------------------------------------

/// One input frame of a take: the source's frame (`pa_video::source`) with what the log
/// records.
struct InputFrame {
    pub index: usize,
    /// What the log records as `input`.
    pub name: String,
    /// (bytes, mtime ns) the log records.
    pub stamp: (u64, u64),
    /// A still is read only if the frame is to be processed.
    pub pixels: Pixels,
}

/// What a source gives next.
enum Next {
    Frame(InputFrame),
    /// No more frames.
    End,
    /// A live source disappeared (the message says so): keep the take, end cleanly.
    Lost(String),
}

/// The input of a take, frame after frame, in index order: a folder of stills, a video file,
/// or a camera (`pa_video::source`'s sources, with the identity the log records). The run
/// loop only sees this, so it can be tested with a fake.
trait TakeSource {
    /// Frames the source holds, when known (a camera: `None`).
    fn len(&self) -> Option<usize>;
    /// The identity (`input` name, stamp) of frame `index`, when known without reading it:
    /// the run plans with it (which frames are done).
    fn identity(&self, index: usize) -> Option<(String, (u64, u64))>;
    /// True for a live source (its frames are new ones, appended to the take).
    fn live(&self) -> bool {
        false
    }
    fn next(&mut self) -> Result<Next>;
}

/// The source's next frame, with its stamp: `None` at the end or when the source is lost.
fn next_of(source: &mut dyn Source) -> Result<std::result::Result<SourceFrame, Next>> {
    Ok(match source.next()? {
        SourceNext::Frame(f) => Ok(f),
        SourceNext::End => Err(Next::End),
        SourceNext::Lost(e) => Err(Next::Lost(e.to_string())),
    })
}

/// A folder of stills: each still's file name and stamp is its identity.
struct TakeStills {
    source: StillsSource,
    stamps: Vec<(u64, u64)>,
}

impl TakeStills {
    fn new(stills: Vec<PathBuf>) -> Result<Self> {
        let stamps = stills
            .iter()
            .map(|p| file_stamp(p))
            .collect::<Result<_>>()?;
        Ok(Self {
            source: StillsSource::new(stills),
            stamps,
        })
    }
}

impl TakeSource for TakeStills {
    fn len(&self) -> Option<usize> {
        self.source.frame_count()
    }
    fn identity(&self, index: usize) -> Option<(String, (u64, u64))> {
        Some((self.source.name(index)?, *self.stamps.get(index)?))
    }
    fn next(&mut self) -> Result<Next> {
        let f = match next_of(&mut self.source)? {
            Ok(f) => f,
            Err(next) => return Ok(next),
        };
        Ok(Next::Frame(InputFrame {
            index: f.index,
            stamp: self.stamps[f.index],
            name: f.name,
            pixels: f.pixels,
        }))
    }
}

/// A video file: frame `i` of the video (presentation order) is still `i`; the video file's
/// name and stamp are the identity of every frame.
struct TakeVideo<S: pa_video::FrameSource> {
    source: VideoSource<S>,
    stamp: (u64, u64),
}

impl<S: pa_video::FrameSource> TakeSource for TakeVideo<S> {
    fn len(&self) -> Option<usize> {
        self.source.frame_count()
    }
    fn identity(&self, index: usize) -> Option<(String, (u64, u64))> {
        match self.source.frame_count() {
            Some(n) if index < n => Some((self.source.name().to_string(), self.stamp)),
            _ => None,
        }
    }
    fn next(&mut self) -> Result<Next> {
        let f = match next_of(&mut self.source)? {
            Ok(f) => f,
            Err(next) => return Ok(next),
        };
        Ok(Next::Frame(InputFrame {
            index: f.index,
            name: f.name,
            stamp: self.stamp,
            pixels: f.pixels,
        }))
    }
}

/// A live camera: every captured frame is saved as `inputs/NNNNNN.png` (atomically, before it
/// is processed) and appended to the take.
struct TakeCamera<S: pa_video::FrameSource> {
    source: CameraSource<S>,
    inputs_dir: PathBuf,
    next_index: usize,
}

impl<S: pa_video::FrameSource> TakeSource for TakeCamera<S> {
    fn len(&self) -> Option<usize> {
        None
    }
    fn identity(&self, _index: usize) -> Option<(String, (u64, u64))> {
        None
    }
    fn live(&self) -> bool {
        true
    }
    fn next(&mut self) -> Result<Next> {
        let f = match next_of(&mut self.source)? {
            Ok(SourceFrame {
                pixels: Pixels::Frame(f),
                ..
            }) => f,
            Ok(_) => bail!("{}: not a camera frame", self.source.describe()),
            Err(next) => return Ok(next),
        };
        let index = self.next_index;
        self.next_index += 1;
        let pa_video::Frame {
            index: captured,
            pts,
            width,
            height,
            rgba,
        } = f;
        let img = image::RgbaImage::from_raw(width, height, rgba).with_context(|| {
            format!(
                "{}: a {}x{} frame with the wrong number of bytes",
                self.source.describe(),
                width,
                height
            )
        })?;
        let img = image::DynamicImage::ImageRgba8(img);
        let name = format!("inputs/{}", frame_name(index));
        let path = self.inputs_dir.join(frame_name(index));
        let mut png = Vec::new();
        image::DynamicImage::ImageRgb8(img.to_rgb8())
            .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)?;
        write_durable(&path, &png)?;
        let f = pa_video::Frame {
            index: captured,
            pts,
            width,
            height,
            rgba: img.into_rgba8().into_raw(),
        };
        let stamp = file_stamp(&path)?;
        Ok(Next::Frame(InputFrame {
            index,
            name,
            stamp,
            pixels: Pixels::Frame(f),
        }))
    }
}

/// A frame's pixels as an image, or why it cannot be used.
fn decode_pixels(pixels: Pixels) -> std::result::Result<image::DynamicImage, String> {
    match pixels {
        Pixels::Frame(f) => match image::RgbaImage::from_raw(f.width, f.height, f.rgba) {
            Some(img) => Ok(image::DynamicImage::ImageRgba8(img)),
            None => Err(format!(
                "the decoder returned a {}x{} frame with the wrong number of bytes",
                f.width, f.height
            )),
        },
        Pixels::Still(path) => {
            pa_video::still::read_still(&path, &StillBudget::default()).map_err(|e| e.to_string())
        }
        Pixels::Unreadable(e) => Err(e.to_string()),
    }
}

// --- frame processing ----------------------------------------------------------------------

/// The layers of one frame, for `--passes`.
struct FramePasses {
    pub plate_rgba8: Vec<u8>,
    pub twin_rgba8: Vec<u8>,
    pub key_mask: Vec<bool>,
    pub twin_mask: Vec<bool>,
}

/// What the pipeline made of one still.
struct Processed {
    pub rgba8: Vec<u8>,
    pub pose: Option<glam::Mat4>,
    pub reprojection_px: Option<f64>,
    pub timings: StageTimings,
    /// With passes asked for and a pose; `None` otherwise.
    pub passes: Option<FramePasses>,
}

/// Turns one still into a frame (the real pipeline, or a fake in tests).
trait FrameProcessor {
    fn process(
        &mut self,
        rgba8: &[u8],
        width: u32,
        height: u32,
        anim_frame: u32,
    ) -> Result<Processed>;
}

/// The real pipeline, started on the first still that needs it (a finished take starts no
/// renderer).
struct PipelineProcessor<'a> {
    cfg: &'a Config,
    keep_passes: bool,
    started: Option<(Renderer, Tracker, ArPipeline)>,
}

impl FrameProcessor for PipelineProcessor<'_> {
    fn process(&mut self, rgba8: &[u8], w: u32, h: u32, anim_frame: u32) -> Result<Processed> {
        let cfg = self.cfg;
        if self.started.is_none() {
            let mut renderer = Renderer::new().context("starting the renderer")?;
            let tracker_cfg = TrackerConfig {
                frames_to_track: 1,
                use_roi: false,
                filter: pa_track::PoseFilterConfig {
                    enabled: false,
                    ..Default::default()
                },
                ..Default::default()
            };
            let tracker = Tracker::new(
                cfg.camera,
                TrackTarget::Board(cfg.board.clone()),
                DetectorConfig::default(),
                tracker_cfg,
            )?;
            let mut pipeline = ArPipeline::new(
                &mut renderer,
                cfg.model.clone(),
                cfg.animation,
                cfg.camera,
                cfg.marker_from_prop,
                None,
                ArSettings::ours(),
            )?;
            pipeline.set_keep_passes(self.keep_passes);
            self.started = Some((renderer, tracker, pipeline));
        }
        let Some((renderer, tracker, pipeline)) = self.started.as_mut() else {
            bail!("the pipeline did not start");
        };
        let t0 = Instant::now();
        tracker.reset();
        let gray = pa_pipeline::ar::gray_from_rgba(rgba8, w, h)?;
        let t_s = anim_frame as f64 / cfg.fps as f64;
        let out = tracker.update(&gray, t_s)?;
        let track_ms = t0.elapsed().as_secs_f64() * 1e3;
        let pose = out.pose.map(|p| p.to_mat4());
        let mut processed = match pose {
            Some(p) => {
                let f = pipeline.process_with_pose(
                    renderer,
                    rgba8,
                    w,
                    h,
                    pa_pipeline::ar::FrameTimes {
                        animation_s: anim_frame as f32 / cfg.fps,
                        key_pose_s: cfg.key_time_s,
                    },
                    p,
                )?;
                let passes = f.passes.map(|ps| FramePasses {
                    plate_rgba8: ps.plate_rgba8,
                    twin_rgba8: ps.twin_rgba8,
                    key_mask: f.key_mask,
                    twin_mask: f.twin_mask,
                });
                Processed {
                    rgba8: f.rgba8,
                    pose,
                    reprojection_px: None,
                    timings: f.timings,
                    passes,
                }
            }
            // No pose: the still goes out untouched (as the pipeline does).
            None => Processed {
                rgba8: rgba8.to_vec(),
                pose: None,
                reprojection_px: None,
                timings: StageTimings::default(),
                passes: None,
            },
        };
        processed.timings.track_ms = track_ms;
        processed.reprojection_px = out.raw.map(|r| r.rms_px);
        Ok(processed)
    }
}

fn state_of(observed: bool) -> pa_track::TrackState {
    if observed {
        pa_track::TrackState::Tracked
    } else {
        pa_track::TrackState::Searching
    }
}

/// PNG bytes of an RGBA8 image at `bit_depth`: 16-bit keeps `input`'s own 16-bit values
/// where the 8-bit result equals the input's 8-bit pixel, and widens (`v * 257`) elsewhere.
fn encode(
    out8: &[u8],
    input: Option<&image::DynamicImage>,
    bit_depth: u8,
    w: u32,
    h: u32,
) -> Result<Vec<u8>> {
    let mut png = Vec::new();
    let mut cur = std::io::Cursor::new(&mut png);
    if bit_depth == 16 {
        let data: Vec<u16> = match input {
            Some(input) => {
                let in16 = input.to_rgba16();
                let in8 = input.to_rgba8();
                let mut data = Vec::with_capacity(out8.len());
                for ((o, i8), i16) in out8
                    .chunks_exact(4)
                    .zip(in8.as_raw().chunks_exact(4))
                    .zip(in16.as_raw().chunks_exact(4))
                {
                    if o == i8 {
                        data.extend_from_slice(i16);
                    } else {
                        data.extend(o.iter().map(|&v| v as u16 * 257));
                    }
                }
                data
            }
            None => out8.iter().map(|&v| v as u16 * 257).collect(),
        };
        let img = image::ImageBuffer::<image::Rgba<u16>, _>::from_raw(w, h, data)
            .context("frame buffer has the wrong size")?;
        img.write_to(&mut cur, image::ImageFormat::Png)?;
    } else {
        let img = image::RgbaImage::from_raw(w, h, out8.to_vec())
            .context("frame buffer has the wrong size")?;
        img.write_to(&mut cur, image::ImageFormat::Png)?;
    }
    Ok(png)
}

/// The masks pass: 8-bit RGB, R = key pose, G = twin.
fn encode_masks(key: &[bool], twin: &[bool], w: u32, h: u32) -> Result<Vec<u8>> {
    let data: Vec<u8> = key
        .iter()
        .zip(twin)
        .flat_map(|(&k, &t)| [if k { 255 } else { 0 }, if t { 255 } else { 0 }, 0])
        .collect();
    let img = image::RgbImage::from_raw(w, h, data).context("mask buffer has the wrong size")?;
    let mut png = Vec::new();
    img.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)?;
    Ok(png)
}

// --- the take ------------------------------------------------------------------------------

/// What to do with one still.
enum Plan {
    /// Logged and present (or logged as skipped): nothing to do.
    Done,
    /// Process; the message (if any) is said on stderr first.
    Process(Option<String>),
}

/// A take being written: its folder, its log and its settings.
struct Take {
    out: PathBuf,
    log_path: PathBuf,
    entries: BTreeMap<usize, Entry>,
    /// Indices logged with other settings (re-rendered with --force).
    stale: HashSet<usize>,
    exposure: u32,
    bit_depth: u8,
    shot_hash: String,
    key_name: String,
    passes: PassSet,
    width: u32,
    height: u32,
    /// "still" or "frame".
    unit: &'static str,
}

/// The folders of a take that hold numbered files.
const TAKE_DIRS: [&str; 5] = ["frames", "inputs", "plate", "twin", "masks"];
/// Those a run writes over: a file there the log does not know is refused without --force.
/// (`inputs/` is written only by a camera run, which numbers on after every file there.)
const OUTPUT_DIRS: [&str; 4] = ["frames", "plate", "twin", "masks"];

impl Take {
    /// Whether the passes asked for exist for a logged frame.
    fn has_passes(&self, e: &Entry) -> bool {
        let dirs = self.passes.dirs();
        if dirs.is_empty() {
            return true;
        }
        let have = e.passes.as_deref().unwrap_or(&[]);
        dirs.iter().all(|d| {
            let p = format!("{d}/{}", frame_name(e.index));
            have.contains(&p) && self.out.join(&p).is_file()
        })
    }

    /// Why the files of a logged frame cannot be kept (None when every one matches what the
    /// log records as written).
    fn mismatch(&self, e: &Entry) -> Option<String> {
        let Some(written) = &e.written else {
            return Some(
                "the log has no record of what was written (a take of an older version)".into(),
            );
        };
        let recorded = |p: &String| written.iter().any(|w| &w.path == p);
        if let Some(p) = e
            .output
            .iter()
            .chain(e.passes.iter().flatten())
            .find(|p| !recorded(p))
        {
            return Some(format!("the log has no record of {p}"));
        }
        written.iter().find_map(|w| w.mismatch(&self.out))
    }

    fn plan(&self, i: usize, name: &str, stamp: (u64, u64)) -> Plan {
        match self.entries.get(&i) {
            None => Plan::Process(None),
            Some(_) if self.stale.contains(&i) => {
                Plan::Process(Some(format!("settings changed: frame {i} re-rendered")))
            }
            Some(e) if e.input != name || (e.input_bytes, e.input_mtime_ns) != stamp => {
                Plan::Process(Some(if e.output.is_some() {
                    format!("re-shot: frame {i} replaced ({name})")
                } else {
                    format!(
                        "re-shot: {} {i} ({name}) was skipped before; trying again",
                        self.unit
                    )
                }))
            }
            Some(e) => match &e.output {
                Some(o) if self.out.join(o).is_file() && self.has_passes(e) => {
                    match self.mismatch(e) {
                        None => Plan::Done,
                        Some(why) => Plan::Process(Some(format!("frame {i} re-rendered: {why}"))),
                    }
                }
                Some(_) => Plan::Process(None),
                None => Plan::Done,
            },
        }
    }

    fn new_entry(&self, input: &InputFrame, anim_frame: u32) -> Entry {
        Entry {
            index: input.index,
            input: input.name.clone(),
            input_bytes: input.stamp.0,
            input_mtime_ns: input.stamp.1,
            anim_frame,
            key_pose: self.key_name.clone(),
            state: None,
            camera_from_marker: None,
            reprojection_px: None,
            timings_ms: None,
            output: None,
            skipped: None,
            passes: None,
            written: None,
            exposure: self.exposure,
            bit_depth: self.bit_depth,
            shot_hash: self.shot_hash.clone(),
        }
    }
}

/// Files in the take's output folders that the log does not know.
fn foreign_files(take: &Take) -> Result<Vec<String>> {
    let mut known: HashSet<String> = HashSet::new();
    for e in take.entries.values() {
        known.extend(e.output.iter().cloned());
        known.extend(e.passes.iter().flatten().cloned());
    }
    let mut foreign = Vec::new();
    for dir in OUTPUT_DIRS {
        let path = take.out.join(dir);
        let Ok(rd) = std::fs::read_dir(&path) else {
            continue;
        };
        for e in rd.flatten() {
            let name = e.file_name().to_string_lossy().into_owned();
            if name.starts_with('.') {
                continue;
            }
            let rel = format!("{dir}/{name}");
            if !known.contains(&rel) {
                foreign.push(rel);
            }
        }
    }
    foreign.sort_by(|a, b| super::track::natural_cmp(a, b));
    Ok(foreign)
}

/// The highest index of the `NNNNNN.png` files in `dir`.
fn last_numbered(dir: &Path) -> Option<usize> {
    std::fs::read_dir(dir)
        .ok()?
        .flatten()
        .filter_map(|e| {
            let name = e.file_name().to_string_lossy().into_owned();
            let stem = name.strip_suffix(".png")?;
            (stem.len() == 6 && stem.bytes().all(|b| b.is_ascii_digit()))
                .then(|| stem.parse().ok())
                .flatten()
        })
        .max()
}

/// Where a camera run starts numbering: after the take's last logged frame and after every
/// captured input (a capture cut short may have saved an input it never logged: kept).
fn camera_start_index(take: &Take) -> usize {
    let logged = take.entries.keys().next_back().map(|i| i + 1);
    let saved = last_numbered(&take.out.join("inputs")).map(|i| i + 1);
    logged.max(saved).unwrap_or(0)
}

/// Takes the take's lock (`DIR/.lock`), or fails naming the run that holds it. On a
/// read-only file system no run can write the take: no lock is needed (and none can be made).
fn lock_take(out: &Path) -> Result<Option<pa_io::FileLock>> {
    let holder = format!(
        "propsalive run, pid {}, started at unix time {}",
        std::process::id(),
        std::time::SystemTime::now()
            .duration_since(UNIX_EPOCH)
            .map_or(0, |d| d.as_secs())
    );
    match pa_io::FileLock::try_acquire(&out.join(".lock"), &holder) {
        Ok(lock) => Ok(Some(lock)),
        Err(pa_io::IoError::Locked { holder, .. }) => bail!(
            "{}: another run is writing this take ({holder}); wait for it to end, or use another --out folder",
            out.display()
        ),
        Err(pa_io::IoError::Io { source, .. })
            if source.kind() == std::io::ErrorKind::ReadOnlyFilesystem =>
        {
            Ok(None)
        }
        Err(e) => Err(e.into()),
    }
}

/// Refuses a take whose folders (`frames/`, ...) are symbolic links or not folders: a take
/// never follows a link out of itself.
fn check_take_folders(out: &Path) -> Result<()> {
    for d in TAKE_DIRS {
        let p = out.join(d);
        if let Ok(meta) = std::fs::symlink_metadata(&p) {
            if !meta.is_dir() {
                bail!(
                    "{}: is {}, not a folder; a take's {d}/ must be a real folder inside it",
                    p.display(),
                    pa_io::kind_of(&meta)
                );
            }
        }
    }
    for f in ["log.jsonl", "camera.gltf", "mp4.json"] {
        let p = out.join(f);
        if let Ok(meta) = std::fs::symlink_metadata(&p) {
            if !meta.is_file() {
                bail!(
                    "{}: is {}, not a regular file",
                    p.display(),
                    pa_io::kind_of(&meta)
                );
            }
        }
    }
    Ok(())
}

/// Removes temporary files a killed run left behind (`.NAME.tmp-PID`).
fn remove_stale_temps(dir: &Path) {
    if let Ok(rd) = std::fs::read_dir(dir) {
        for e in rd.flatten() {
            let name = e.file_name().to_string_lossy().into_owned();
            if pa_io::is_temp_name(&name) {
                let _ = std::fs::remove_file(e.path());
            }
        }
    }
}

/// Progress on stderr: a bar with frames/s and the time left on a terminal, a plain line
/// every 10 s otherwise. Messages go through [`Progress::say`] so they do not tear the bar.
struct Progress {
    bar: ProgressBar,
    plain: bool,
    started: Instant,
    last_line: Option<Instant>,
    total: Option<usize>,
}

/// Seconds between plain progress lines.
const PLAIN_EVERY: Duration = Duration::from_secs(10);

impl Progress {
    fn new(total: Option<usize>) -> Self {
        let plain = !std::io::stderr().is_terminal();
        let bar = if plain {
            ProgressBar::hidden()
        } else {
            let (bar, template) = match total {
                Some(n) => (
                    ProgressBar::with_draw_target(Some(n as u64), ProgressDrawTarget::stderr()),
                    "{bar:32} {pos}/{len} frames  {msg}",
                ),
                None => (
                    ProgressBar::with_draw_target(None, ProgressDrawTarget::stderr()),
                    "{spinner} {pos} frames  {elapsed}  {msg}  (Ctrl-C ends the take)",
                ),
            };
            bar.set_style(
                ProgressStyle::with_template(template)
                    .unwrap_or_else(|_| ProgressStyle::default_bar()),
            );
            bar
        };
        Progress {
            bar,
            plain,
            started: Instant::now(),
            last_line: None,
            total,
        }
    }

    /// A silent one (tests).
    #[cfg(test)]
    fn hidden() -> Self {
        Progress {
            bar: ProgressBar::hidden(),
            plain: false,
            started: Instant::now(),
            last_line: None,
            total: None,
        }
    }

    /// A line on stderr.
    fn say(&self, msg: &str) {
        self.bar.suspend(|| errln!("{msg}"));
    }

    /// `k` frames handled; `what` is the last one in words.
    fn frame(&mut self, k: usize, what: &str) {
        let fps = k as f64 / self.started.elapsed().as_secs_f64().max(1e-9);
        let left = self
            .total
            .map(|n| {
                let s = n.saturating_sub(k) as f64 / fps.max(1e-9);
                format!(", about {s:.0} s left")
            })
            .unwrap_or_default();
        if !self.plain {
            self.bar.set_position(k as u64);
            self.bar
                .set_message(format!("{fps:.2} frames/s{left}  ({what})"));
            return;
        }
        let now = Instant::now();
        let last = self.total == Some(k);
        if self.last_line.is_some_and(|t| now - t < PLAIN_EVERY) && !last {
            return;
        }
        self.last_line = Some(now);
        let of = self.total.map(|n| format!("/{n}")).unwrap_or_default();
        errln!("frame {k}{of} ({what}): {fps:.2} frames/s{left}");
    }

    fn finish(&self) {
        self.bar.finish_and_clear();
    }
}

/// How the loop ended.
#[derive(Debug, Clone, PartialEq)]
enum End {
    /// Every frame asked for was handled.
    Finished,
    /// Ctrl-C.
    Interrupted,
    /// The live source disappeared (its message).
    Lost(String),
}

/// What one run of the loop did.
#[derive(Debug)]
struct Outcome {
    pub processed: usize,
    pub skipped_read: usize,
    pub skipped_size: usize,
    pub reshot: usize,
    pub end: End,
}

/// The run loop: each input frame that is not done goes through `processor`; its log line is
/// appended (fsynced), then its frame and passes are written atomically. Stops at the end of
/// the source, after `limit` input frames (files: the first `limit`; a live source: `limit`
/// new ones), when `stop` is set (after finishing the current frame), or when a live source
/// is lost.
fn run_take(
    take: &mut Take,
    source: &mut dyn TakeSource,
    processor: &mut dyn FrameProcessor,
    plans: &mut BTreeMap<usize, Plan>,
    todo: Option<usize>,
    limit: Option<usize>,
    stop: &AtomicBool,
    progress: &mut Progress,
) -> Result<Outcome> {
    let mut o = Outcome {
        processed: 0,
        skipped_read: 0,
        skipped_size: 0,
        reshot: 0,
        end: End::Finished,
    };
    let frames_dir = take.out.join("frames");
    let mut log = std::fs::OpenOptions::new()
        .append(true)
        .create(true)
        .open(&take.log_path)
        .with_context(|| format!("opening {}", take.log_path.display()))?;
    let unit = take.unit;
    let (mut k, mut pulled) = (0usize, 0usize);
    loop {
        if stop.load(Ordering::SeqCst) {
            o.end = End::Interrupted;
            break;
        }
        // Files: everything left is done (a video need not be decoded further).
        if !source.live() && todo.is_some_and(|t| k >= t) {
            break;
        }
        if limit.is_some_and(|l| pulled >= l) {
            break;
        }
        let input = match source.next()? {
            Next::Frame(f) => f,
            Next::End => break,
            Next::Lost(msg) => {
                o.end = End::Lost(msg);
                break;
            }
        };
        pulled += 1;
        let i = input.index;
        let plan = match plans.remove(&i) {
            Some(p) => p,
            None => take.plan(i, &input.name, input.stamp),
        };
        let Plan::Process(msg) = plan else {
            continue;
        };
        k += 1;
        if let Some(m) = msg {
            progress.say(&m);
            if m.starts_with("re-shot") {
                o.reshot += 1;
            }
        }
        let name = input.name.clone();
        let anim_frame = (i / take.exposure as usize) as u32;
        let mut entry = take.new_entry(&input, anim_frame);
        let decoded = decode_pixels(input.pixels);
        let img = match decoded {
            Ok(img) if (img.width(), img.height()) != (take.width, take.height) => {
                o.skipped_size += 1;
                let why = format!(
                    "{}x{} but the take is {}x{} (set by the first readable {unit})",
                    img.width(),
                    img.height(),
                    take.width,
                    take.height
                );
                progress.say(&format!("warning: skipping {unit} {i} ({name}): {why}"));
                entry.skipped = Some(format!("wrong size: {why}"));
                None
            }
            Ok(img) => Some(img),
            Err(e) => {
                o.skipped_read += 1;
                progress.say(&format!("warning: skipping {unit} {i} ({name}): {e}"));
                entry.skipped = Some(format!("unreadable: {e}"));
                None
            }
        };
        let mut files: Vec<(PathBuf, Vec<u8>)> = Vec::new();
        if let Some(img) = img {
            let rgba = img.to_rgba8();
            let (w, h) = (take.width, take.height);
            let p = processor.process(rgba.as_raw(), w, h, anim_frame)?;
            let t1 = Instant::now();
            files.push((
                frames_dir.join(frame_name(i)),
                encode(&p.rgba8, Some(&img), take.bit_depth, w, h)?,
            ));
            if take.passes.any() {
                let n = (w * h) as usize;
                let passes = p.passes.unwrap_or_else(|| FramePasses {
                    plate_rgba8: rgba.as_raw().clone(),
                    twin_rgba8: vec![0; n * 4],
                    key_mask: vec![false; n],
                    twin_mask: vec![false; n],
                });
                let mut names = Vec::new();
                if take.passes.plate {
                    let png = encode(&passes.plate_rgba8, Some(&img), take.bit_depth, w, h)?;
                    names.push(format!("plate/{}", frame_name(i)));
                    files.push((take.out.join("plate").join(frame_name(i)), png));
                }
                if take.passes.twin {
                    let png = encode(&passes.twin_rgba8, None, take.bit_depth, w, h)?;
                    names.push(format!("twin/{}", frame_name(i)));
                    files.push((take.out.join("twin").join(frame_name(i)), png));
                }
                if take.passes.masks {
                    let png = encode_masks(&passes.key_mask, &passes.twin_mask, w, h)?;
                    names.push(format!("masks/{}", frame_name(i)));
                    files.push((take.out.join("masks").join(frame_name(i)), png));
                }
                entry.passes = Some(names);
            }
            let timings = p.timings;
            entry.state = Some(super::track::state_name(state_of(p.pose.is_some())).to_string());
            entry.camera_from_marker = p.pose.map(|m| m.to_cols_array().to_vec());
            entry.reprojection_px = p.reprojection_px;
            entry.timings_ms = Some(Timings {
                track: timings.track_ms,
                animate: timings.animate_ms,
                texture: timings.texture_ms,
                diminish: timings.diminish_ms,
                composite: timings.composite_ms,
                encode: t1.elapsed().as_secs_f64() * 1e3,
            });
            entry.output = Some(format!("frames/{}", frame_name(i)));
            o.processed += 1;
        }
        if !files.is_empty() {
            entry.written = Some(
                files
                    .iter()
                    .map(|(path, bytes)| {
                        let rel = path.strip_prefix(&take.out).unwrap_or(path);
                        Written::of(rel.to_string_lossy().into_owned(), bytes)
                    })
                    .collect(),
            );
        }
        // The log line first (fsynced), then the files: a file never exists unknown to the
        // log, and a line without its frame (or with other bytes) is redone on resume.
        let line = serde_json::to_string(&entry)?;
        writeln!(log, "{line}").with_context(|| format!("writing {}", take.log_path.display()))?;
        log.flush()?;
        log.sync_data()?;
        let state = entry.state.clone().unwrap_or_else(|| "skipped".into());
        take.entries.insert(i, entry);
        for (path, bytes) in &files {
            // A symbolic link in the take is never followed: the link itself is replaced.
            if std::fs::symlink_metadata(path).is_ok_and(|m| m.file_type().is_symlink()) {
                std::fs::remove_file(path)
                    .with_context(|| format!("removing the link {}", path.display()))?;
            }
            write_durable(path, bytes)?;
        }
        progress.frame(k, &format!("{unit} {i}, {name}: {state}"));
    }
    Ok(o)
}

/// Set by Ctrl-C: finish the current frame and stop.
static STOP: AtomicBool = AtomicBool::new(false);

/// Ctrl-C (and SIGTERM) finish the current frame; a second one quits at once.
fn install_stop_handler(live: bool) {
    let first = if live {
        "\nCtrl-C: ending the take after this frame (Ctrl-C again quits at once)"
    } else {
        "\nCtrl-C: stopping after this frame; the take resumes from here (Ctrl-C again quits at once)"
    };
    let hits = Arc::new(AtomicBool::new(false));
    let result = ctrlc::set_handler(move || {
        if hits.swap(true, Ordering::SeqCst) {
            errln!("\ninterrupted again: quitting now (every file of the take is whole)");
            std::process::exit(130);
        }
        errln!("{first}");
        STOP.store(true, Ordering::SeqCst);
    });
    if let Err(e) = result {
        errln!("note: cannot catch Ctrl-C ({e}); it will stop the run at once");
    }
}

pub fn run(args: Args) -> Result<()> {
    let (cfg, spec) = resolve(&args)?;
    let live = matches!(spec, SourceSpec::Camera(_));
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    // One run per take: held until this process ends, however it ends.
    let _lock = lock_take(&args.out)?;
    check_take_folders(&args.out)?;
    let frames_dir = args.out.join("frames");
    std::fs::create_dir_all(&frames_dir)
        .with_context(|| format!("creating {}", frames_dir.display()))?;
    let mut dirs: Vec<&str> = cfg.passes.dirs();
    if live {
        dirs.push("inputs");
    }
    for d in &dirs {
        let p = args.out.join(d);
        std::fs::create_dir_all(&p).with_context(|| format!("creating {}", p.display()))?;
    }
    for d in TAKE_DIRS {
        remove_stale_temps(&args.out.join(d));
    }
    remove_stale_temps(&args.out);
    let log_path = args.out.join("log.jsonl");
    let entries = read_log(&log_path)?;

    // Settings of an existing take.
    let stale: HashSet<usize> = entries
        .values()
        .filter(|e| {
            e.exposure != args.exposure
                || e.bit_depth != args.bit_depth
                || e.shot_hash != cfg.shot_hash
        })
        .map(|e| e.index)
        .collect();
    if !stale.is_empty() && (live || !args.force) {
        bail!(
            "{}: {} frame(s) of this take were made with another exposure, bit depth or shot file; use a new --out folder{}",
            args.out.display(),
            stale.len(),
            if live { "" } else { ", or --force to re-render them" }
        );
    }
    let mut take = Take {
        out: args.out.clone(),
        log_path: log_path.clone(),
        entries,
        stale,
        exposure: args.exposure,
        bit_depth: args.bit_depth,
        shot_hash: cfg.shot_hash.clone(),
        key_name: cfg.key_name.clone(),
        passes: cfg.passes,
        width: cfg.width,
        height: cfg.height,
        unit: cfg.unit,
    };

    // Files the log does not know.
    let foreign = foreign_files(&take)?;
    if !foreign.is_empty() {
        let list = foreign
            .iter()
            .take(5)
            .cloned()
            .collect::<Vec<_>>()
            .join(", ");
        let more = if foreign.len() > 5 { ", ..." } else { "" };
        if !args.force {
            bail!(
                "{}: {} file(s) this take's log does not know ({list}{more}): another take? Refusing to overwrite; use a new --out folder, or --force",
                args.out.display(),
                foreign.len()
            );
        }
        errln!(
            "warning: --force: {} file(s) in {} are not from this take ({list}{more}); those a {} maps to will be replaced",
            foreign.len(),
            args.out.display(),
            cfg.unit
        );
    }

    let unit = cfg.unit;
    let mut source: Box<dyn TakeSource> = match spec {
        SourceSpec::Stills(stills) => Box::new(TakeStills::new(stills)?),
        SourceSpec::Video {
            reader,
            path,
            stamp,
        } => {
            let count = reader.info().frame_count.map(|c| c as usize);
            Box::new(TakeVideo {
                source: VideoSource::new(reader, &path, count),
                stamp,
            })
        }
        SourceSpec::Camera(camera) => {
            let next_index = camera_start_index(&take);
            let logged = take.entries.keys().next_back().map_or(0, |i| i + 1);
            if next_index > logged {
                errln!(
                    "note: {} holds captured frame(s) up to index {} that the log does not have (a capture cut short?): kept; this capture starts at {next_index}",
                    args.out.join("inputs").display(),
                    next_index - 1
                );
            }
            Box::new(TakeCamera {
                source: CameraSource::new(camera),
                inputs_dir: args.out.join("inputs"),
                next_index,
            })
        }
    };

    // Plan every frame known in advance.
    let mut plans = BTreeMap::new();
    let known = source.len().map(|n| args.frames.map_or(n, |l| n.min(l)));
    if let Some(n) = known {
        for i in 0..n {
            if let Some((name, stamp)) = source.identity(i) {
                plans.insert(i, take.plan(i, &name, stamp));
            }
        }
    }
    let todo = known.map(|_| {
        plans
            .values()
            .filter(|p| matches!(p, Plan::Process(_)))
            .count()
    });
    let resumed = plans.len() - todo.unwrap_or(0);
    // One line per index, no truncated line, before appending.
    write_log(&log_path, &take.entries)?;
    if resumed > 0 {
        errln!(
            "resuming the take in {}: {resumed} of {} {unit}(s) already done",
            args.out.display(),
            plans.len()
        );
    }
    if live {
        errln!(
            "capturing from {} into {} (from index {}){}",
            cfg.input_desc,
            args.out.display(),
            camera_start_index(&take),
            match args.frames {
                Some(n) => format!(", {n} frame(s)"),
                None => ", until Ctrl-C".into(),
            }
        );
    }

    let mut outcome = Outcome {
        processed: 0,
        skipped_read: 0,
        skipped_size: 0,
        reshot: 0,
        end: End::Finished,
    };
    if todo != Some(0) {
        install_stop_handler(live);
        let total = if live { args.frames } else { todo };
        let mut progress = Progress::new(total);
        let mut processor = PipelineProcessor {
            cfg: &cfg,
            keep_passes: cfg.passes.any(),
            started: None,
        };
        let result = run_take(
            &mut take,
            source.as_mut(),
            &mut processor,
            &mut plans,
            todo,
            args.frames,
            &STOP,
            &mut progress,
        );
        progress.finish();
        outcome = result?;
        // Lines of redone stills were appended after their old ones: compact.
        write_log(&log_path, &take.entries)?;
    }
    let n = if live {
        take.entries.keys().next_back().map_or(0, |i| i + 1)
    } else {
        source
            .len()
            .unwrap_or_else(|| take.entries.keys().next_back().map_or(0, |i| i + 1))
    };
    drop(source);
    finish(&args, &cfg, &take, &outcome, n, resumed, live)
}

/// After the loop: the summary, `camera.gltf`, the MP4, and how the run ends.
fn finish(
    args: &Args,
    cfg: &Config,
    take: &Take,
    o: &Outcome,
    n: usize,
    resumed: usize,
    live: bool,
) -> Result<()> {
    let unit = take.unit;
    let log_path = &take.log_path;
    let entries = &take.entries;
    let skipped_before = entries
        .values()
        .filter(|e| e.index < n && e.skipped.is_some())
        .count()
        .saturating_sub(o.skipped_read + o.skipped_size);
    let past_end = entries
        .values()
        .filter(|e| e.index >= n && e.output.is_some())
        .count();
    if past_end > 0 {
        errln!(
            "note: the take has {past_end} frame(s) past the last of the {n} {unit}(s) ({unit}s removed?); left in place"
        );
    }
    let produced = entries
        .values()
        .filter(|e| e.index < n && e.output.is_some())
        .count();
    if let End::Lost(msg) = &o.end {
        errln!("warning: {msg}: the take ends here; everything captured is kept");
    }
    if produced == 0 {
        bail!(
            "{}: none of the {n} {unit}(s) could be rendered (see {})",
            cfg.input_desc,
            log_path.display()
        );
    }
    let limited = match (args.frames, live) {
        (Some(l), false) if l < n => format!(", {} not asked for (--frames {l})", n - l),
        _ => String::new(),
    };
    errln!(
        "run: {n} {unit}(s): {} processed, {resumed} resumed from an earlier run, {} skipped{}{limited}; frames in {}, log {}",
        o.processed,
        o.skipped_read + o.skipped_size,
        if o.reshot > 0 {
            format!(", {} re-shot", o.reshot)
        } else {
            String::new()
        },
        take.out.join("frames").display(),
        log_path.display()
    );
    let total_skipped = o.skipped_read + o.skipped_size + skipped_before;
    if total_skipped > 0 {
        errln!(
            "warning: {total_skipped} {unit}(s) have no frame ({} unreadable, {} with another size this run; {skipped_before} skipped in an earlier run): see \"skipped\" in {}",
            o.skipped_read,
            o.skipped_size,
            log_path.display()
        );
    }
    export_camera(&take.out, entries, n, &cfg.camera.intrinsics, cfg.fps)?;
    let interrupted = o.end == End::Interrupted;
    if let Some(mp4) = &args.mp4 {
        if interrupted && !live {
            errln!(
                "note: interrupted: no MP4 written ({} is made when the take is complete)",
                mp4.display()
            );
        } else if mp4_is_current(mp4, &take.out, &take_hash(entries, n)) {
            errln!("mp4: {} is up to date", mp4.display());
        } else {
            write_mp4(mp4, &take.out, entries, n, cfg.fps, args.force)?;
        }
    }
    if interrupted && !live {
        errln!(
            "interrupted: the take in {} is kept; run the same command again to finish it",
            take.out.display()
        );
        std::process::exit(130);
    }
    Ok(())
}

/// Writes `camera.gltf` from the log's poses of stills `0..n` (a resumed run exports the whole
/// take). No pose at all is a note, not an error: the frames are there.
fn export_camera(
    out: &Path,
    entries: &BTreeMap<usize, Entry>,
    n: usize,
    intrinsics: &Intrinsics,
    fps: f32,
) -> Result<()> {
    let poses: Vec<(usize, Option<glam::Mat4>)> = entries
        .values()
        .filter(|e| e.index < n)
        .map(|e| {
            let pose = e
                .camera_from_marker
                .as_deref()
                .filter(|m| m.len() == 16)
                .map(glam::Mat4::from_cols_slice);
            (e.index, pose)
        })
        .collect();
    if !poses.iter().any(|(_, p)| p.is_some()) {
        errln!("note: no still of the take was tracked: no camera.gltf written");
        return Ok(());
    }
    let doc = super::camera_export::camera_gltf(&poses, intrinsics, fps)?;
    let path = out.join("camera.gltf");
    write_durable_if_changed(&path, doc.json.as_bytes())?;
    errln!(
        "camera: {} tracked still(s) exported to {} (glTF 2.0, Y-up, {} fps)",
        doc.keys,
        path.display(),
        fps
    );
    Ok(())
}

// --- MP4 -----------------------------------------------------------------------------------

/// What `mp4.json` records of the MP4 a take wrote.
#[derive(Debug, Serialize, Deserialize, PartialEq)]
struct Mp4Record {
    path: String,
    bytes: u64,
    mtime_ns: u64,
    frames: u64,
    fps: f32,
    /// XXH3-64 of the frames it was made from (their indices and recorded hashes), so a
    /// re-run with nothing new knows the MP4 is current.
    #[serde(default)]
    take_hash: String,
}

/// The identity of the frames `0..n` an MP4 is made from.
fn take_hash(entries: &BTreeMap<usize, Entry>, n: usize) -> String {
    let mut text = String::new();
    for e in entries.values().filter(|e| e.index < n) {
        if let (Some(_), Some(w)) = (&e.output, &e.written) {
            text.push_str(&format!("{} {}\n", e.index, w[0].xxh3));
        }
    }
    format!("{:016x}", xxhash_rust::xxh3::xxh3_64(text.as_bytes()))
}

/// True when `mp4` is this take's and was made from exactly the frames it holds now.
fn mp4_is_current(mp4: &Path, out: &Path, hash: &str) -> bool {
    our_mp4_record(mp4, out).is_some_and(|r| r.take_hash == hash)
}

fn absolute(p: &Path) -> PathBuf {
    std::path::absolute(p).unwrap_or_else(|_| p.to_path_buf())
}

/// True when `mp4` is the file this take last wrote (same path, size and mtime).
fn mp4_is_ours(mp4: &Path, out: &Path) -> bool {
    our_mp4_record(mp4, out).is_some()
}

/// The take's `mp4.json`, when `mp4` is the file it records (same path, size and mtime).
fn our_mp4_record(mp4: &Path, out: &Path) -> Option<Mp4Record> {
    let text = pa_io::read_regular(&out.join("mp4.json"), 1 << 20, "mp4.json").ok()?;
    let rec = serde_json::from_slice::<Mp4Record>(&text).ok()?;
    let stamp = file_stamp(mp4).ok()?;
    (rec.path == absolute(mp4).display().to_string() && (rec.bytes, rec.mtime_ns) == stamp)
        .then_some(rec)
}

/// Refuses an `--mp4` target that is a folder, or an existing file that is not this take's,
/// before any work.
fn check_mp4_target(mp4: &Path, out: &Path, force: bool) -> Result<()> {
    if mp4.is_dir() {
        bail!("--mp4 {} is a folder; give a file name", mp4.display());
    }
    if mp4.exists() && !force && !mp4_is_ours(mp4, out) {
        bail!(
            "--mp4 {} exists and is not the MP4 this take wrote; pass --force to replace it, or name another file",
            mp4.display()
        );
    }
    Ok(())
}

/// Removes what a killed MP4 writer left (`.NAME.PID.N.partial` beside the target).
fn remove_stale_partials(mp4: &Path) {
    let (Some(dir), Some(name)) = (mp4.parent(), mp4.file_name()) else {
        return;
    };
    let dir = if dir.as_os_str().is_empty() {
        Path::new(".")
    } else {
        dir
    };
    let prefix = format!(".{}.", name.to_string_lossy());
    if let Ok(rd) = std::fs::read_dir(dir) {
        for e in rd.flatten() {
            let n = e.file_name().to_string_lossy().into_owned();
            if n.starts_with(&prefix) && n.ends_with(".partial") {
                let _ = std::fs::remove_file(e.path());
            }
        }
    }
}

/// Encodes the take's frames `0..n` in index order at `fps` as an H.264 MP4. A frame the take
/// lacks (a skipped still) holds the one before it (the first frame for a leading gap), so
/// the MP4 keeps the take's timing.
fn write_mp4(
    mp4: &Path,
    out: &Path,
    entries: &BTreeMap<usize, Entry>,
    n: usize,
    fps: f32,
    force: bool,
) -> Result<()> {
    let frames: BTreeMap<usize, PathBuf> = entries
        .values()
        .filter(|e| e.index < n)
        .filter_map(|e| Some((e.index, out.join(e.output.as_ref()?))))
        .filter(|(_, p)| p.is_file())
        .collect();
    let (Some((&first, first_path)), Some(&last)) = (frames.iter().next(), frames.keys().last())
    else {
        errln!("note: the take has no frame: no MP4 written");
        return Ok(());
    };
    let read = |p: &Path| -> Result<image::RgbaImage> {
        Ok(pa_video::still::read_still(p, &StillBudget::default())
            .with_context(|| format!("reading {} for the MP4", p.display()))?
            .to_rgba8())
    };
    let first_img = read(first_path)?;
    let (w, h) = first_img.dimensions();
    let overwrite = mp4.exists() && (force || mp4_is_ours(mp4, out));
    if mp4.exists() && !overwrite {
        bail!(
            "--mp4 {} exists and is not the MP4 this take wrote; pass --force to replace it",
            mp4.display()
        );
    }
    if let Some(dir) = mp4.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    remove_stale_partials(mp4);
    let rate = Fps::from_f64(fps as f64)?;
    let mut options = Mp4WriterOptions::new(rate);
    options.overwrite = overwrite;
    let mut writer = Mp4Writer::create(mp4, w, h, options)?;
    let mut held = 0usize;
    let mut current = first_img;
    for i in 0..=last {
        match frames.get(&i) {
            Some(p) if i != first => {
                let img = read(p)?;
                if img.dimensions() != (w, h) {
                    bail!(
                        "{} is {}x{} but the take's first frame is {w}x{h}: cannot encode them in one MP4",
                        p.display(),
                        img.width(),
                        img.height()
                    );
                }
                current = img;
            }
            Some(_) => {}
            None => held += 1,
        }
        writer.write_frame(current.as_raw())?;
    }
    // `finish` renames the file into place and syncs its folder.
    let summary = writer.finish()?;
    let (bytes, mtime_ns) = file_stamp(mp4)?;
    let rec = Mp4Record {
        path: absolute(mp4).display().to_string(),
        bytes,
        mtime_ns,
        frames: summary.frames,
        fps,
        take_hash: take_hash(entries, n),
    };
    write_durable(
        &out.join("mp4.json"),
        serde_json::to_string_pretty(&rec)?.as_bytes(),
    )?;
    errln!(
        "mp4: {} frame(s) at {rate} fps, {:.1} MB, H.264 -> {}{}",
        summary.frames,
        summary.bytes as f64 / 1e6,
        mp4.display(),
        if held > 0 {
            format!(" ({held} frame(s) the take lacks hold the frame before)")
        } else {
            String::new()
        }
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use pa_video::{Frame, Timestamp, VideoError};

    /// A fake live camera: `frames` frames, then "disconnected" once, then nothing.
    struct FakeCamera {
        frames: u64,
        given: u64,
        lost: bool,
    }

    fn synth(i: u64, w: u32, h: u32) -> Vec<u8> {
        (0..w * h)
            .flat_map(|p| {
                [
                    (p % 251) as u8,
                    (i * 40 % 256) as u8,
                    (p / w * 3 % 256) as u8,
                    255,
                ]
            })
            .collect()
    }

    impl pa_video::FrameSource for FakeCamera {
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
                    width: 64,
                    height: 48,
                    rgba: synth(i, 64, 48),
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
            (64, 48)
        }
        fn fps(&self) -> Option<Fps> {
            Fps::new(24, 1).ok()
        }
        fn describe(&self) -> String {
            "fake camera".into()
        }
    }

    /// A fake video: frames 0.. with a decode error at the given indices.
    struct FakeVideo {
        frames: usize,
        bad: Vec<usize>,
        at: usize,
    }

    impl pa_video::FrameSource for FakeVideo {
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
                width: 64,
                height: 48,
                rgba: synth(i as u64, 64, 48),
            }))
        }
        fn frame_size(&self) -> (u32, u32) {
            (64, 48)
        }
        fn fps(&self) -> Option<Fps> {
            Fps::new(24, 1).ok()
        }
        fn describe(&self) -> String {
            "fake video".into()
        }
    }

    /// Inverts the frame, "tracks" it at 1 m (a pose moving with the index), and reports the
    /// left half as key pose and a square as twin. Sets `stop` after `stop_after` frames.
    struct FakeProcessor {
        calls: usize,
        stop_after: Option<(usize, &'static AtomicBool)>,
    }

    impl FrameProcessor for FakeProcessor {
        fn process(&mut self, rgba8: &[u8], w: u32, h: u32, anim_frame: u32) -> Result<Processed> {
            self.calls += 1;
            if let Some((n, flag)) = self.stop_after {
                if self.calls >= n {
                    flag.store(true, Ordering::SeqCst);
                }
            }
            let n = (w * h) as usize;
            let key: Vec<bool> = (0..n).map(|p| (p as u32 % w) < w / 2).collect();
            let twin: Vec<bool> = (0..n)
                .map(|p| (p as u32 % w) < 8 && (p as u32 / w) < 8)
                .collect();
            let out: Vec<u8> = rgba8
                .chunks_exact(4)
                .flat_map(|p| [255 - p[0], 255 - p[1], 255 - p[2], 255])
                .collect();
            let twin_rgba: Vec<u8> = twin
                .iter()
                .flat_map(|&t| if t { [200, 100, 50, 255] } else { [0; 4] })
                .collect();
            Ok(Processed {
                rgba8: out.clone(),
                pose: Some(glam::Mat4::from_translation(glam::Vec3::new(
                    0.01 * anim_frame as f32,
                    0.0,
                    1.0,
                ))),
                reprojection_px: Some(0.1),
                timings: StageTimings::default(),
                passes: Some(FramePasses {
                    plate_rgba8: out,
                    twin_rgba8: twin_rgba,
                    key_mask: key,
                    twin_mask: twin,
                }),
            })
        }
    }

    fn take_in(dir: &Path, passes: PassSet, unit: &'static str) -> Take {
        for d in TAKE_DIRS {
            std::fs::create_dir_all(dir.join(d)).expect("mkdir");
        }
        Take {
            out: dir.to_path_buf(),
            log_path: dir.join("log.jsonl"),
            entries: BTreeMap::new(),
            stale: HashSet::new(),
            exposure: 1,
            bit_depth: 8,
            shot_hash: "0".into(),
            key_name: "A".into(),
            passes,
            width: 64,
            height: 48,
            unit,
        }
    }

    fn all_passes() -> PassSet {
        PassSet {
            plate: true,
            twin: true,
            masks: true,
        }
    }

    #[test]
    fn a_lost_camera_ends_the_take_cleanly_and_keeps_it() {
        let dir = tempfile::tempdir().expect("tmp");
        let mut take = take_in(dir.path(), all_passes(), "frame");
        let mut source = TakeCamera {
            source: CameraSource::new(FakeCamera {
                frames: 3,
                given: 0,
                lost: false,
            }),
            inputs_dir: dir.path().join("inputs"),
            next_index: 0,
        };
        let stop = AtomicBool::new(false);
        let mut processor = FakeProcessor {
            calls: 0,
            stop_after: None,
        };
        let o = run_take(
            &mut take,
            &mut source,
            &mut processor,
            &mut BTreeMap::new(),
            None,
            None,
            &stop,
            &mut Progress::hidden(),
        )
        .expect("a lost camera is not an error");
        assert!(
            matches!(&o.end, End::Lost(m) if m.contains("/dev/video7") && m.contains("disconnected")),
            "{o:?}"
        );
        assert_eq!((o.processed, o.skipped_read), (3, 0));
        // Everything captured is in the take, known to the log.
        let log = read_log(&take.log_path).expect("log");
        assert_eq!(log.keys().copied().collect::<Vec<_>>(), [0, 1, 2]);
        for (i, e) in &log {
            assert_eq!(e.input, format!("inputs/{i:06}.png"));
            assert_eq!(
                e.output.as_deref(),
                Some(format!("frames/{i:06}.png").as_str())
            );
            let stamp = file_stamp(&dir.path().join(&e.input)).expect("input saved");
            assert_eq!((e.input_bytes, e.input_mtime_ns), stamp);
            let saved = image::open(dir.path().join(&e.input))
                .expect("png")
                .to_rgba8();
            assert_eq!(
                saved.as_raw(),
                &synth(*i as u64, 64, 48),
                "input {i} saved as captured"
            );
            for p in e.passes.as_ref().expect("passes") {
                assert!(dir.path().join(p).is_file(), "{p}");
            }
        }
        assert!(foreign_files(&take).expect("list").is_empty());
        // A capture cut short after saving an input (before its log line): kept, and the next
        // capture numbers on after it.
        std::fs::copy(
            dir.path().join("inputs/000002.png"),
            dir.path().join("inputs/000003.png"),
        )
        .expect("copy");
        assert_eq!(camera_start_index(&take), 4);
        assert!(foreign_files(&take).expect("list").is_empty());
        std::fs::remove_file(dir.path().join("inputs/000003.png")).expect("rm");
        assert_eq!(camera_start_index(&take), 3);
        // The end of the run: camera.gltf and the MP4 of what was captured.
        export_camera(
            dir.path(),
            &take.entries,
            3,
            &Intrinsics::from_fov_y(0.8, 64, 48).expect("k"),
            24.0,
        )
        .expect("camera.gltf");
        assert!(dir.path().join("camera.gltf").is_file());
        let mp4 = dir.path().join("take.mp4");
        write_mp4(&mp4, dir.path(), &take.entries, 3, 24.0, false).expect("mp4");
        let reader = VideoReader::open(&mp4).expect("reads back");
        assert_eq!(reader.info().frame_count, Some(3));
        assert_eq!(reader.info().fps, Fps::new(24, 1).ok());
        // Written again after a resumed run (it is the take's own), refused when it is not.
        assert!(mp4_is_ours(&mp4, dir.path()));
        write_mp4(&mp4, dir.path(), &take.entries, 3, 24.0, false).expect("rewrite own mp4");
        std::fs::write(&mp4, b"someone else's video").expect("replace");
        assert!(!mp4_is_ours(&mp4, dir.path()));
        let err = write_mp4(&mp4, dir.path(), &take.entries, 3, 24.0, false).expect_err("refused");
        assert!(err.to_string().contains("--force"), "{err}");
        assert!(check_mp4_target(&mp4, dir.path(), false).is_err());
        assert!(check_mp4_target(&mp4, dir.path(), true).is_ok());

        // The camera keeps going after the take's last index on the next run.
        let mut source = TakeCamera {
            source: CameraSource::new(FakeCamera {
                frames: 2,
                given: 0,
                lost: false,
            }),
            inputs_dir: dir.path().join("inputs"),
            next_index: 3,
        };
        let o = run_take(
            &mut take,
            &mut source,
            &mut processor,
            &mut BTreeMap::new(),
            None,
            Some(1),
            &stop,
            &mut Progress::hidden(),
        )
        .expect("run");
        assert_eq!(
            (o.processed, o.end),
            (1, End::Finished),
            "--frames 1 stops after one"
        );
        assert_eq!(read_log(&take.log_path).expect("log").len(), 4);
    }

    #[test]
    fn a_damaged_video_frame_is_skipped_and_logged() {
        let dir = tempfile::tempdir().expect("tmp");
        let mut take = take_in(dir.path(), PassSet::default(), "frame");
        let mut source = TakeVideo {
            source: VideoSource::new(
                FakeVideo {
                    frames: 5,
                    bad: vec![2],
                    at: 0,
                },
                Path::new("clip.mp4"),
                Some(5),
            ),
            stamp: (1000, 7),
        };
        let stop = AtomicBool::new(false);
        let mut processor = FakeProcessor {
            calls: 0,
            stop_after: None,
        };
        let o = run_take(
            &mut take,
            &mut source,
            &mut processor,
            &mut BTreeMap::new(),
            Some(5),
            None,
            &stop,
            &mut Progress::hidden(),
        )
        .expect("run");
        assert_eq!((o.processed, o.skipped_read, o.end), (4, 1, End::Finished));
        let log = read_log(&take.log_path).expect("log");
        assert_eq!(log.len(), 5);
        assert!(
            log[&2]
                .skipped
                .as_deref()
                .is_some_and(|s| s.starts_with("unreadable") && s.contains("damaged slice")),
            "{:?}",
            log[&2]
        );
        // Frame i of the video stays still i after the damaged one.
        assert_eq!(log[&3].anim_frame, 3);
        let f3 = image::open(dir.path().join("frames/000003.png"))
            .expect("frame")
            .to_rgba8();
        assert_eq!(
            f3.as_raw()[1],
            255 - 3 * 40,
            "frame 3 is the video's frame 3"
        );
        assert!(!dir.path().join("frames/000002.png").exists());
        assert!(log
            .values()
            .all(|e| e.input == "clip.mp4" && e.input_bytes == 1000));
        // A changed video (another size or mtime) re-renders every frame; the same is done.
        take.entries = log;
        assert!(matches!(take.plan(1, "clip.mp4", (1000, 7)), Plan::Done));
        assert!(matches!(take.plan(2, "clip.mp4", (1000, 7)), Plan::Done));
        assert!(
            matches!(take.plan(1, "clip.mp4", (1000, 8)), Plan::Process(Some(m)) if m.starts_with("re-shot"))
        );
        // Asking for passes re-renders frames that lack them.
        take.passes = all_passes();
        assert!(matches!(
            take.plan(1, "clip.mp4", (1000, 7)),
            Plan::Process(None)
        ));
    }

    #[test]
    fn ctrl_c_finishes_the_current_frame_and_stops() {
        static STOP_FLAG: AtomicBool = AtomicBool::new(false);
        let dir = tempfile::tempdir().expect("tmp");
        let mut take = take_in(dir.path(), PassSet::default(), "frame");
        let mut source = TakeVideo {
            source: VideoSource::new(
                FakeVideo {
                    frames: 6,
                    bad: vec![],
                    at: 0,
                },
                Path::new("clip.mp4"),
                Some(6),
            ),
            stamp: (1, 1),
        };
        let mut processor = FakeProcessor {
            calls: 0,
            stop_after: Some((2, &STOP_FLAG)),
        };
        let o = run_take(
            &mut take,
            &mut source,
            &mut processor,
            &mut BTreeMap::new(),
            Some(6),
            None,
            &STOP_FLAG,
            &mut Progress::hidden(),
        )
        .expect("run");
        assert_eq!((o.processed, o.end), (2, End::Interrupted));
        let log = read_log(&take.log_path).expect("log");
        assert_eq!(log.keys().copied().collect::<Vec<_>>(), [0, 1]);
        assert!(dir.path().join("frames/000001.png").is_file());
    }

    #[test]
    fn inputs_and_passes_parse() {
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
        let p = PassSet::parse(&["plate".into(), "masks".into()]).expect("passes");
        assert_eq!(p.dirs(), ["plate", "masks"]);
        assert_eq!(PassSet::parse(&["all".into()]).expect("all"), all_passes());
        assert!(PassSet::parse(&["depth".into()]).is_err());
        assert!(!PassSet::default().any());
    }
}
