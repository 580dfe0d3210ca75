//! `propsalive run SHOT.toml --input INPUT --out DIR`: a take through the pipeline. INPUT is
//! a folder of stills (PNG/JPEG/TIFF, natural order: the stop-motion norm), a video file
//! (frame `i` of the video is still `i`), or a live camera (`camera:/dev/video0`, the `v4l`
//! feature). Still `i` shows animation frame `i / exposure` (`--exposure 1` = ones, `2` =
//! twos) with the shot's present key prop in front of the camera; each still goes through the
//! real pipeline (track -> place -> animate -> texture -> diminish -> composite).
//!
//! Outputs, in DIR: the take as `pa_take` describes it (`frames/`, `log.jsonl`,
//! `camera.gltf`, the `--passes` folders, a camera's `inputs/`, and `--mp4` with `mp4.json`).
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

use std::collections::BTreeMap;
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::{bail, Context, Result};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use pa_camera::CameraModel;
use pa_pipeline::ar::{ArPipeline, ArSettings, StageTimings};
use pa_pipeline::shot::Shot;
use pa_pipeline::shot_config;
use pa_render::Renderer;
use pa_take::mp4::{check_mp4_target, mp4_is_current, take_hash};
use pa_take::{
    camera_start_index, check_no_overlap, hash_hex, open_take, write_log, FramePasses, InputKind,
    InputSource, Next, Opened, PassSet, Plan, ResolvedInput, Still, Take, TakeSettings, TakeSource,
    Tally, Timings,
};
use pa_track::{Board, TrackTarget, Tracker, TrackerConfig};
use pa_video::{Fps, Mp4Writer};

pub mod diminish;
pub mod hide;
pub mod marker;
mod scan;

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
    /// How the real prop is removed (overriding the shot's `[diminish]`).
    #[command(flatten)]
    pub diminish: diminish::DiminishArgs,
    /// What replaces the board (overriding the shot's `[marker] hide`).
    #[command(flatten)]
    pub hide: hide::HideArgs,
    /// A scan pass before the take (over the shot's `[scan] input`): a folder of stills or a
    /// video circling the key prop once. Its frames are tracked and remembered (texture
    /// memory: the twin's unseen parts take the remembered colours), no frames are written.
    #[arg(long, value_name = "FOLDER|VIDEO")]
    pub scan: Option<PathBuf>,
    /// How each still's tags are found (each still on its own either way).
    #[arg(long, value_enum, default_value_t = Tracking::Full)]
    pub tracking: Tracking,
}

/// `--tracking` of `run`, `track` and `preview` (defined with `track`).
pub use crate::cmd::track::Tracking;

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

struct Config {
    /// What one input frame is called in messages: "still" or "frame".
    unit: &'static str,
    /// The input in words, for the summary.
    input_desc: String,
    width: u32,
    height: u32,
    camera: CameraModel,
    board: Board,
    /// What the tracker follows: the board, the shot's picture, or both.
    target: TrackTarget,
    model: pa_model::Model,
    animation: usize,
    marker_from_prop: glam::Mat4,
    fps: f32,
    key_name: String,
    key_time_s: f32,
    shot_hash: String,
    passes: PassSet,
    /// The shot's `[diminish]` with the flags over it.
    diminish: pa_pipeline::shot_diminish::DiminishConfig,
    /// The clean plate still, if any.
    plate_file: Option<PathBuf>,
    /// The first stills that are plate (passed through untouched).
    plate_frames: usize,
    /// The shot's `[marker] hide` with the flags over it.
    hide: pa_pipeline::shot_hide::HideConfig,
    /// The scan pass's input (`--scan` or the shot's `[scan]`).
    scan: Option<PathBuf>,
    /// The shot's `[texture]`: relighting and feathered seams.
    look: pa_pipeline::ar::LiveLook,
    /// `--tracking`.
    tracking: Tracking,
}

fn resolve(args: &Args) -> Result<(Config, InputSource)> {
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
    let dim = args.diminish.resolve(&shot, &args.shot)?;
    let hide_cfg = args.hide.resolve(&shot, &args.shot, &dim)?;
    let mut first_still = None;
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
    let resolved = match input {
        InputSpec::Folder(dir) => {
            let (stills, _) = super::track::list_frames(&dir)?;
            first_still = stills.first().cloned();
            ResolvedInput::stills(&dir, stills)?
        }
        InputSpec::Video(path) => {
            let (resolved, note) = ResolvedInput::video(path, shot.fps)?;
            if let Some(note) = note {
                errln!("{note}");
            }
            resolved
        }
        InputSpec::Camera(device) => {
            let size = camera_request(args.camera_size.as_deref(), &shot, &args.shot)?;
            let camera = open_camera(&device, size, shot.fps)?;
            ResolvedInput::camera(camera, &device)
        }
    };
    let ResolvedInput {
        source,
        unit,
        desc: input_desc,
        width,
        height,
        first: first_desc,
    } = resolved;
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
    marker::check_hide(&board, hide_cfg.hide)?;
    let (target, picture_identity) = marker::track_target(&shot, &args.shot, &board)?;
    let model_path = Shot::resolve(&args.shot, &shot.model);
    let model = pa_model::Model::load(&model_path)
        .with_context(|| format!("loading the model {}", model_path.display()))?;
    let animation = shot.check_model(&args.shot, &model)?;
    let key = &shot.key_poses[shot.present_key_index()];
    let scan = scan::scan_input(args.scan.as_deref(), &shot, &args.shot)?;
    let scan_identity = match &scan {
        Some(s) => Some(format!("\n# scan: {}\n{}", s.display(), scan::identity(s)?)),
        None => None,
    };
    let cfg = Config {
        unit,
        input_desc,
        width,
        height,
        camera,
        board,
        target,
        model,
        animation,
        marker_from_prop: shot.placement.marker_from_prop(),
        fps: shot.fps,
        key_name: key.name.clone(),
        key_time_s: key.frame as f32 / shot.fps,
        // Flags that change the diminish stage change the take's settings too (the shot's
        // own [diminish] is in its text); without them the hash is the shot's as before.
        // The scan too (scan.rs): a changed scan re-renders the take.
        shot_hash: {
            let mut text = shot_text.clone();
            let hide_flags = args.hide.overrides() != Default::default();
            if !args.diminish.overrides().is_empty() || hide_flags {
                text.extend_from_slice(format!("\n# flags: {}", dim.describe()).as_bytes());
            }
            if hide_flags {
                text.extend_from_slice(format!(" {}", hide_cfg.describe()).as_bytes());
            }
            if let Some(s) = &scan_identity {
                text.extend_from_slice(s.as_bytes());
            }
            // The marker picture's content (a shot without one hashes as before).
            if let Some(p) = &picture_identity {
                text.extend_from_slice(p.as_bytes());
            }
            // Another detector gives other poses (the default hashes as before; a new mode
            // must name itself here).
            match args.tracking {
                Tracking::Full => {}
                Tracking::Fast => text.extend_from_slice(b"\n# tracking: fast"),
            }
            hash_hex(&text)
        },
        passes,
        plate_file: diminish::plate_file(&dim, first_still.as_deref())?,
        plate_frames: diminish::plate_frames(&dim),
        diminish: dim,
        hide: hide_cfg,
        scan,
        look: shot.texture.look(),
        tracking: args.tracking,
    };
    Ok((cfg, source))
}

/// The budget for a shot file (read again here for its hash).
const MAX_SHOT_BYTES: u64 = 4 << 20;

// --- frame processing ----------------------------------------------------------------------

/// What the pipeline made of one still.
struct Processed {
    pub rgba8: Vec<u8>,
    pub pose: Option<glam::Mat4>,
    pub reprojection_px: Option<f64>,
    /// The board's tags the pose used (empty when none was seen); `None` from a fake.
    pub used_ids: Option<Vec<u32>>,
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
        index: usize,
    ) -> Result<Processed>;
}

/// The real pipeline, started on the first still that needs it (a finished take starts no
/// renderer).
struct PipelineProcessor<'a> {
    cfg: &'a Config,
    keep_passes: bool,
    started: Option<(Renderer, Tracker, ArPipeline)>,
    /// The texture memory the scan left, given back before every still (scan.rs).
    memory: Option<pa_pipeline::ar::MemorySnapshot>,
}

impl FrameProcessor for PipelineProcessor<'_> {
    fn process(
        &mut self,
        rgba8: &[u8],
        w: u32,
        h: u32,
        anim_frame: u32,
        index: usize,
    ) -> Result<Processed> {
        let cfg = self.cfg;
        // A plate still of the take (`plate_frames`) goes out untouched.
        if index < cfg.plate_frames {
            return Ok(Processed {
                rgba8: rgba8.to_vec(),
                pose: None,
                reprojection_px: None,
                timings: StageTimings::default(),
                passes: None,
                used_ids: None,
            });
        }
        if self.started.is_none() {
            let mut renderer = Renderer::new().context("starting the renderer")?;
            let tracker_cfg = TrackerConfig::per_still();
            let tracker = Tracker::new(
                cfg.camera,
                cfg.target.clone(),
                cfg.tracking.detector(),
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
            let plate = match &cfg.plate_file {
                Some(p) => Some(diminish::load_plate(
                    p,
                    cfg.camera,
                    &cfg.target,
                    cfg.width,
                    cfg.height,
                )?),
                None => None,
            };
            let plate_pose = plate.as_ref().map(|p| p.1);
            diminish::apply(&mut pipeline, &cfg.diminish, plate)?;
            diminish::apply_board(&mut pipeline, &cfg.board);
            pipeline.settings.look = cfg.look;
            hide::apply(
                &mut pipeline,
                &cfg.hide,
                &cfg.board,
                plate_pose,
                (cfg.width, cfg.height),
            )?;
            pipeline.set_keep_passes(self.keep_passes);
            let mut tracker = tracker;
            if let Some(s) = &cfg.scan {
                pipeline.set_texture_memory(true);
                let size = (cfg.width, cfg.height);
                scan::run_scan(s, &mut tracker, &mut pipeline, size, cfg.key_time_s)?;
                self.memory = Some(pipeline.memory_snapshot());
            }
            self.started = Some((renderer, tracker, pipeline));
        }
        let Some((renderer, tracker, pipeline)) = self.started.as_mut() else {
            bail!("the pipeline did not start");
        };
        let t0 = Instant::now();
        tracker.reset();
        // Every still on its own, so that a resumed take equals an uninterrupted one: the
        // pipeline forgets what it carries between frames (the patch fill's prior, the sun's
        // running direction).
        pipeline.reset_tracker();
        if let Some(m) = &self.memory {
            pipeline.restore_memory(m);
        }
        // Every still on its own: the shadows' light is estimated again from each.
        if pipeline.shadows() {
            pipeline.set_shadow_light(None);
        }
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
                    used_ids: None,
                    timings: f.timings,
                    passes,
                }
            }
            // No pose: the still goes out untouched (as the pipeline does).
            None => Processed {
                rgba8: rgba8.to_vec(),
                pose: None,
                reprojection_px: None,
                used_ids: None,
                timings: StageTimings::default(),
                passes: None,
            },
        };
        processed.timings.track_ms = track_ms;
        processed.reprojection_px = out.raw.map(|r| r.rms_px);
        processed.used_ids = Some(out.used_ids.clone());
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
#[derive(Debug, Clone, PartialEq, Default)]
enum End {
    /// Every frame asked for was handled.
    #[default]
    Finished,
    /// Ctrl-C.
    Interrupted,
    /// The live source disappeared (its message).
    Lost(String),
}

/// What one run of the loop did.
#[derive(Debug, Default)]
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
    let mut o = Outcome::default();
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
        let img = match take.read_still(i, &name, input.pixels, &mut entry) {
            Still::Usable(img) => Some(img),
            Still::Skipped {
                wrong_size,
                warning,
            } => {
                if wrong_size {
                    o.skipped_size += 1;
                } else {
                    o.skipped_read += 1;
                }
                progress.say(&warning);
                None
            }
        };
        let mut files = Vec::new();
        if let Some(img) = img {
            let rgba = img.to_rgba8();
            let (w, h) = (take.width, take.height);
            let p = processor.process(rgba.as_raw(), w, h, anim_frame, i)?;
            let t1 = Instant::now();
            files = take.encode_frame(i, &p.rgba8, &img, rgba.as_raw(), p.passes, &mut entry)?;
            let timings = p.timings;
            entry.state =
                Some(pa_report::track::state_name(state_of(p.pose.is_some())).to_string());
            entry.camera_from_marker = p.pose.map(|m| m.to_cols_array().to_vec());
            entry.reprojection_px = p.reprojection_px;
            entry.used_ids = p.used_ids;
            entry.timings_ms = Some(Timings {
                track: timings.track_ms,
                animate: timings.animate_ms,
                texture: timings.texture_ms,
                diminish: timings.diminish_ms,
                composite: timings.composite_ms,
                encode: t1.elapsed().as_secs_f64() * 1e3,
            });
            o.processed += 1;
        }
        let state = entry.state.clone().unwrap_or_else(|| "skipped".into());
        take.commit(&mut log, entry, &files)?;
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
    let live = spec.live();
    let settings = TakeSettings {
        exposure: args.exposure,
        bit_depth: args.bit_depth,
        shot_hash: cfg.shot_hash.clone(),
        key_name: cfg.key_name.clone(),
        passes: cfg.passes,
        width: cfg.width,
        height: cfg.height,
        unit: cfg.unit,
    };
    // One run per take: the lock is held until this process ends, however it ends.
    let Opened {
        mut take,
        lock: _lock,
    } = open_take(&args.out, settings, live, args.force, &mut |note| {
        errln!("{note}")
    })?;
    let log_path = take.log_path.clone();

    let unit = cfg.unit;
    let (mut source, note) = spec.open(&take)?;
    if let Some(note) = note {
        errln!("{note}");
    }

    // Plan every frame known in advance.
    let (mut plans, todo) = take.plan_known(source.as_ref(), args.frames);
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

    let mut outcome = Outcome::default();
    if todo != Some(0) {
        install_stop_handler(live);
        let total = if live { args.frames } else { todo };
        let mut progress = Progress::new(total);
        let mut processor = PipelineProcessor {
            cfg: &cfg,
            keep_passes: cfg.passes.any(),
            started: None,
            memory: None,
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
    let Tally {
        produced,
        skipped,
        past_end,
    } = take.tally(n);
    let skipped_before = skipped.saturating_sub(o.skipped_read + o.skipped_size);
    if past_end > 0 {
        errln!(
            "note: the take has {past_end} frame(s) past the last of the {n} {unit}(s) ({unit}s removed?); left in place"
        );
    }
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
    let intrinsics = &cfg.camera.intrinsics;
    let exported =
        pa_take::camera_export::export_camera(&take.out, entries, n, intrinsics, cfg.fps)?;
    errln!("{exported}");
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
            let written = pa_take::mp4::write_mp4(mp4, &take.out, entries, n, cfg.fps, args.force)?;
            errln!("{}", written.line(mp4));
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

#[cfg(test)]
mod tests;
