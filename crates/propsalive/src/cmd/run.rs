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
//!   an animated glTF 2.0 camera (see `pa_take::camera_export`), rewritten atomically at the end of
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
use std::time::{Duration, Instant};

use anyhow::{bail, Context, Result};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use pa_camera::{CameraModel, Intrinsics};
use pa_pipeline::ar::{ArPipeline, ArSettings, StageTimings};
use pa_pipeline::shot::Shot;
use pa_pipeline::shot_config;
use pa_render::Renderer;
use pa_take::mp4::{check_mp4_target, mp4_is_current, take_hash};
use pa_take::{
    camera_start_index, check_no_overlap, check_take_folders, encode, encode_masks, file_stamp,
    foreign_files, frame_name, hash_hex, lock_take, remove_stale_temps, write_durable, write_log,
    Entry, InputKind, PassSet, Plan, Take, Timings, Written, TAKE_DIRS,
};
use pa_track::{Board, DetectorConfig, TrackTarget, Tracker, TrackerConfig};
use pa_video::source::{
    CameraSource, Next as SourceNext, Pixels, Source, SourceFrame, StillsSource, VideoSource,
};
use pa_video::still::StillBudget;
use pa_video::{Fps, Mp4Writer, VideoReader};

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

/// The take's log ([`pa_take::read_log`]); the lines it ignored are said on stderr.
pub fn read_log(path: &Path) -> Result<BTreeMap<usize, Entry>> {
    let log = pa_take::read_log(path)?;
    for note in &log.notes {
        errln!("{note}");
    }
    Ok(log.entries)
}

// --- input ---------------------------------------------------------------------------------

/// What `--input` names (`pa_video::source`).
pub(crate) use pa_video::source::InputSpec;

/// Reads `--input` (`pa_video::source::parse_input`): a folder of stills, a video file or a
/// camera; the message of a bad input starts with `--input`.
pub(crate) fn parse_input(input: &Path) -> Result<InputSpec> {
    pa_video::source::parse_input(input).map_err(|e| anyhow::anyhow!("--input {e}"))
}

/// The size to ask a camera for: `--camera-size`, else the shot's calibration size, else
/// 1280x720 ([`shot_config::camera_request`]).
pub(crate) fn camera_request(
    camera_size: Option<&str>,
    shot: &Shot,
    shot_path: &Path,
) -> Result<(u32, u32)> {
    if let Some(s) = camera_size {
        return super::parse_size(s).with_context(|| format!("--camera-size {s}"));
    }
    Ok(shot_config::camera_request(shot, shot_path)?)
}

/// Opens a camera at the shot's rate (the `v4l` feature; without it, `pa-video`'s error
/// naming the feature).
pub(crate) fn open_camera(device: &Path, size: (u32, u32), fps: f32) -> Result<pa_video::Camera> {
    Ok(pa_video::source::open_camera(device, size, fps)?)
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
    match &input {
        InputSpec::Folder(p) => {
            check_no_overlap(p, InputKind::Folder, &args.out, args.mp4.as_deref())?
        }
        InputSpec::Video(p) => {
            check_no_overlap(p, InputKind::Video, &args.out, args.mp4.as_deref())?
        }
        InputSpec::Camera(_) => {}
    }
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
    let camera = shot_config::camera_for_shot(&shot, &args.shot, width, height, &first_desc)?;
    if let Some(note) = &camera.scaled {
        errln!("{note}");
    }
    let camera = camera.value;
    let board = shot_config::board_from_shot(&shot, &args.shot)?;
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
            .collect::<std::result::Result<_, _>>()?;
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

// --- the take ------------------------------------------------------------------------------
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
        let mut entry = take.new_entry(input.index, &input.name, input.stamp, anim_frame);
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

/// Writes `camera.gltf` from the log's poses of stills `0..n` ([`pa_take::camera_export`])
/// and says what it did.
fn export_camera(
    out: &Path,
    entries: &BTreeMap<usize, Entry>,
    n: usize,
    intrinsics: &Intrinsics,
    fps: f32,
) -> Result<()> {
    let exported = pa_take::camera_export::export_camera(out, entries, n, intrinsics, fps)?;
    errln!("{exported}");
    Ok(())
}

/// Encodes the take's frames `0..n` as an H.264 MP4 ([`pa_take::mp4::write_mp4`]) and says
/// what it wrote.
fn write_mp4(
    mp4: &Path,
    out: &Path,
    entries: &BTreeMap<usize, Entry>,
    n: usize,
    fps: f32,
    force: bool,
) -> Result<()> {
    let written = pa_take::mp4::write_mp4(mp4, out, entries, n, fps, force)?;
    errln!("{}", written.line(mp4));
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use pa_take::mp4::mp4_is_ours;
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
