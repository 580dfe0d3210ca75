//! `propsalive track INPUT --calib FILE --tag-size-m S [...]`: marker detection, camera pose
//! and the tracking state machine over an image, a folder of images (natural sort) or a
//! video file (`pa-video`: MP4/MOV H.264 without B-frames in the default build, anything
//! FFmpeg reads with `--features ffmpeg`), one JSON line per frame (stdout, or `--out-log
//! FILE.jsonl`), optionally drawing each frame with its detections and the marker axes
//! (`--draw DIR`).
//!
//! `--image-target PICTURE --target-width-m W` tracks a printed picture instead of tags
//! (`pa_track::ImageTarget`: marker origin at the picture's centre, +X along its width, +Y
//! down it, +Z into the table; the height follows from its aspect). The JSON lines are the
//! same and add `target_corners_px` (the picture's outer corners in the image, TL, TR, BR,
//! BL of the picture, pixel-centre convention); `used_roi` then says the frame was found by
//! frame-to-frame tracking rather than a full detection. A file that is not an image, or a
//! picture too small or too flat to track, is refused with its name.
//!
//! Per-frame JSON: `frame` (index), `file` (for a video: the video's name, and `time_s`, the
//! frame's presentation time), `width`, `height`, `state` (`searching`, `detected`,
//! `tracked`, `lost`), `events`, `detections` (`family`, `id`, `corners_px` as
//! `[[x, y] x4]` TL, TR, BR, BL of the printed tag, OpenCV pixel centres, `hamming`,
//! `decision_margin`), `pose` (the tracker's filtered `camera_from_marker`, present while
//! `tracked`: `rotation_xyzw` unit quaternion, `translation_m`, plus `reprojection_rms_px` of
//! this frame's measurement), `measured_pose` (this frame's unfiltered pose, whenever the
//! target was seen), `used_ids`, `coasting`, `used_roi`, `time_ms` (detection + pose).
//!
//! Decisions:
//! - A single image is one frame of a fresh track, so the state machine needs one sighting to
//!   report `tracked` (`frames_to_track = 1`); folders and videos use the tracker's defaults
//!   (temporal tracking: filter, region of interest). A video's frames are timed by their
//!   presentation times (`--fps` times a folder's frames).
//! - A file in a folder that has an image extension but cannot be decoded is **skipped**: a
//!   warning names it on stderr, its JSON line has `"error"` and no detections, and the
//!   tracker treats it as a frame without the marker. A single unreadable image, or a folder
//!   where no image decodes, is an error.
//! - Resolution: the calibration's size is compared with the first frame's. Same aspect ratio
//!   (within 0.5 %): the intrinsics are scaled ([`pa_camera::Intrinsics::scaled_to`]) and a
//!   note says so on stderr. Otherwise the command refuses. Every frame must have the first
//!   frame's size.
//! - A video frame the decoder rejects is skipped like an unreadable image (the reader goes on
//!   with the next frame). A video this build cannot decode fails at once with `pa-video`'s
//!   message, which names the file, the codec and the cargo feature to enable. `--draw` names
//!   a video's frames `<video stem>_NNNNNN.png`.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{bail, Context, Result};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use pa_camera::{CameraModel, Intrinsics};
use pa_overlay::detections::draw_frame;
use pa_report::track::state_name;
use pa_report::track::{frame_json, round};
use pa_track::{Board, DetectorConfig, TagFamily, TrackState, TrackTarget, Tracker, TrackerConfig};
use pa_video::source::{has_ext, Next, Pixels, Source, StillsSource, VideoSource};
use serde_json::{json, Value};

#[derive(clap::Args)]
pub struct Args {
    /// An image (.png, .jpg, .tif), a folder of images (processed in natural order) or a
    /// video file (.mp4, .mov; others with `--features ffmpeg`).
    pub input: PathBuf,
    /// Camera calibration: OpenCV YAML (.yaml/.yml), or pa-camera TOML/JSON.
    #[arg(long, conflicts_with = "fov_deg")]
    pub calib: Option<PathBuf>,
    /// Without a calibration: an ideal pinhole camera with this vertical field of view.
    #[arg(long)]
    pub fov_deg: Option<f64>,
    /// Side of the tag's black border square in metres.
    #[arg(long, required_unless_present = "image_target")]
    pub tag_size_m: Option<f64>,
    /// Track a printed picture (any image file) instead of tags: its centre is the marker
    /// origin, +X along its width, +Y down it (needs `--target-width-m`).
    #[arg(long, conflicts_with_all = ["board", "tag_size_m"], requires = "target_width_m")]
    pub image_target: Option<PathBuf>,
    /// Printed width of the `--image-target` picture, metres (its height follows from the
    /// picture's aspect).
    #[arg(long, requires = "image_target")]
    pub target_width_m: Option<f64>,
    /// Tag family.
    #[arg(long, default_value = "tag36h11")]
    pub family: String,
    /// Id of the tracked tag (single-tag target).
    #[arg(long, default_value_t = 0, conflicts_with = "board")]
    pub id: u32,
    /// Track a board of ROWSxCOLS tags (as `propsalive marker --board` prints it).
    #[arg(long)]
    pub board: Option<String>,
    /// Gap between the black squares of neighbouring board tags, metres.
    #[arg(long, requires = "board")]
    pub gap_m: Option<f64>,
    /// Id of the board's top-left tag.
    #[arg(long, default_value_t = 0, requires = "board")]
    pub first_id: u32,
    /// Frame rate of a folder of images (the pose filter's time base); a video's frames keep
    /// their own times.
    #[arg(long, default_value_t = 24.0)]
    pub fps: f64,
    /// Thorough detection: an extra pass on a 2x upsampled image finds small, strongly tilted
    /// tags (slower; with `--tracking full` only).
    #[arg(long)]
    pub thorough: bool,
    /// How each frame's tags are found.
    #[arg(long, value_enum, default_value_t = Tracking::Full)]
    pub tracking: Tracking,
    /// How each tag's corners are refined before the pose: its edges found again in linear
    /// light, decoding the frame as sRGB (cameras' and renderers' 8-bit output) or as linear
    /// (a raw or linear camera profile); `off` keeps the detector's corners (the AprilTag C
    /// library's).
    #[arg(long, value_enum, default_value_t = Corners::Srgb)]
    pub corners: Corners,
    /// Write the JSON lines here instead of stdout.
    #[arg(long)]
    pub out_log: Option<PathBuf>,
    /// Write each frame with detected corners and marker axes drawn, as DIR/<name>.png.
    #[arg(long)]
    pub draw: Option<PathBuf>,
    /// Replace output files that exist.
    #[arg(long)]
    pub force: bool,
}

/// `--tracking` of `track`, `run` and `preview`: the tag detector of every frame.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum Tracking {
    /// The default detector's full-resolution passes: the most accurate (on noisy 1280x720
    /// stills, corners 0.26 px off the truth, about 50 ms a still on 2 cores; on clean ones
    /// about 3 ms).
    #[default]
    Full,
    /// The quad search at half resolution, each quad's edges refined at full resolution (as
    /// the AprilTag C library at `quad_decimate = 2`): about 9 ms a noisy 1280x720 still,
    /// corners 0.33 px off the truth; tags under about 27 px a side are missed.
    Fast,
}

/// `--corners` of `track`: [`pa_track::CornerRefinement`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum Corners {
    #[default]
    Srgb,
    Linear,
    Off,
}

impl From<Corners> for pa_track::CornerRefinement {
    fn from(c: Corners) -> Self {
        match c {
            Corners::Srgb => Self::Srgb,
            Corners::Linear => Self::Linear,
            Corners::Off => Self::Off,
        }
    }
}

impl Tracking {
    /// The detector's settings for this mode.
    pub fn detector(self) -> DetectorConfig {
        match self {
            Tracking::Full => DetectorConfig::default(),
            Tracking::Fast => DetectorConfig::fast(),
        }
    }
}

const VIDEO_EXTS: &[&str] = &[
    "mp4", "mov", "avi", "mkv", "webm", "m4v", "mpg", "mpeg", "wmv", "flv", "mts", "m2ts", "3gp",
];
const IMAGE_EXTS: &[&str] = pa_video::source::STILL_EXTS;

/// The frames to track.
pub enum Input {
    /// Image files (one, or a folder's in natural order).
    Images(Vec<PathBuf>),
    /// A video file, opened.
    Video(Box<pa_video::VideoReader>),
}

impl Input {
    /// Frames, when known.
    fn len(&self) -> Option<usize> {
        match self {
            Input::Images(v) => Some(v.len()),
            Input::Video(r) => r.info().frame_count.map(|n| n as usize),
        }
    }
}

/// The resolved, checked configuration.
pub struct Config {
    pub input: Input,
    pub single_image: bool,
    pub camera: CameraModel,
    pub target: TrackTarget,
    pub detector: DetectorConfig,
    pub tracker: TrackerConfig,
    pub fps: f64,
    pub out_log: Option<PathBuf>,
    pub draw: Option<PathBuf>,
    /// Length of the drawn axes, metres.
    pub axis_m: f64,
}

pub(crate) fn list_frames(input: &Path) -> Result<(Vec<PathBuf>, bool)> {
    if !input.exists() {
        bail!("{}: no such file or folder", input.display());
    }
    if input.is_dir() {
        return Ok((pa_video::source::list_stills(input)?, false));
    }
    if has_ext(input, VIDEO_EXTS) {
        bail!(
            "{}: a video; this command reads images: extract the frames to a folder first, e.g. `ffmpeg -i {} frames/%05d.png`, and pass the folder",
            input.display(),
            input.display()
        );
    }
    if !has_ext(input, IMAGE_EXTS) {
        bail!(
            "{}: not a supported image (use .png, .jpg, .jpeg, .tif or .tiff, or a folder of them)",
            input.display()
        );
    }
    Ok((vec![input.to_path_buf()], true))
}

/// Intrinsics fitted to a frame size: equal, scaled (same aspect ratio, with a note on stderr)
/// or refused.
pub fn fit_intrinsics(
    k: &Intrinsics,
    width: u32,
    height: u32,
    calib_name: &str,
    frame_name: &str,
) -> Result<Intrinsics> {
    let fitted =
        pa_pipeline::shot_config::fit_intrinsics(k, width, height, calib_name, frame_name)?;
    if let Some(note) = &fitted.scaled {
        errln!("{note}");
    }
    Ok(fitted.value)
}

fn draw_path(dir: &Path, frame: &Path) -> PathBuf {
    let stem = frame.file_stem().unwrap_or_default().to_string_lossy();
    dir.join(format!("{stem}.png"))
}

/// Where `--draw` puts frame `index` of a video: `<video stem>_NNNNNN.png`.
fn video_draw_path(dir: &Path, video: &Path, index: usize) -> PathBuf {
    let stem = video.file_stem().unwrap_or_default().to_string_lossy();
    dir.join(format!("{stem}_{index:06}.png"))
}

/// True when INPUT is a file to open as a video: any file that is not an image by extension
/// (the reader recognises the container by its content).
fn is_video_input(input: &Path) -> bool {
    input.is_file() && !has_ext(input, IMAGE_EXTS)
}

/// Checks every flag and input before any work.
/// A picture target from an image file.
fn load_image_target(path: &Path, width_m: f64) -> Result<(TrackTarget, f64)> {
    if !(width_m.is_finite() && width_m > 0.0 && width_m < 100.0) {
        bail!("--target-width-m must be a positive length in metres, got {width_m}");
    }
    let img = image::open(path)
        .with_context(|| format!("{}: not a readable image", path.display()))?
        .to_luma8();
    let gray = pa_track::GrayImage::from(&img);
    let target = pa_track::ImageTarget::new(&gray, width_m)
        .with_context(|| format!("{}: cannot be used as an image target", path.display()))?;
    Ok((TrackTarget::Image(Box::new(target)), width_m))
}

pub fn resolve(args: &Args) -> Result<Config> {
    let family: TagFamily = args.family.parse()?;
    let tag_size_m = match (&args.image_target, args.tag_size_m) {
        (Some(_), _) => 0.0,
        (None, Some(s)) => s,
        (None, None) => {
            bail!("give --tag-size-m S (tags) or --image-target PICTURE --target-width-m W")
        }
    };
    if args.image_target.is_none()
        && !(tag_size_m.is_finite() && tag_size_m > 0.0 && tag_size_m < 100.0)
    {
        bail!(
            "--tag-size-m must be a positive length in metres, got {}",
            tag_size_m
        );
    }
    if !(args.fps.is_finite() && args.fps > 0.0 && args.fps <= 10_000.0) {
        bail!("--fps must be in (0, 10000], got {}", args.fps);
    }
    let (target, extent_m) = match (&args.image_target, &args.board) {
        (Some(p), _) => load_image_target(p, args.target_width_m.unwrap_or(f64::NAN))?,
        (None, Some(b)) => {
            let (rows, cols) = super::parse_grid(b)?;
            let gap = args
                .gap_m
                .context("--board needs --gap-m (the gap between black squares, metres)")?;
            let board = Board::grid(family, rows, cols, tag_size_m, gap, args.first_id)?;
            let ext = (rows.max(cols) as f64) * (tag_size_m + gap);
            (TrackTarget::Board(board), ext)
        }
        (None, None) => (
            TrackTarget::Tag {
                family,
                id: args.id,
                size_m: tag_size_m,
            },
            tag_size_m,
        ),
    };
    let layout = pa_track::family_layout(family)?;
    let max_id = match &target {
        TrackTarget::Tag { id, .. } => *id,
        TrackTarget::Board(b) | TrackTarget::ImageAndBoard { board: b, .. } => {
            b.tags.iter().map(|t| t.id).max().unwrap_or(0)
        }
        TrackTarget::Image(_) => 0,
    };
    if max_id >= layout.id_count {
        bail!(
            "{family} has ids 0..{}; id {max_id} does not exist",
            layout.id_count
        );
    }

    let (input, single_image, first, (width, height)) = if is_video_input(&args.input) {
        // pa-video's errors name the file, the codec and the feature: said as they are.
        let reader = match pa_video::VideoReader::open(&args.input) {
            Ok(r) => r,
            Err(e @ pa_video::VideoError::UnsupportedContainer { .. })
                if !has_ext(&args.input, VIDEO_EXTS) =>
            {
                bail!(
                    "{}: not a supported image (use .png, .jpg, .jpeg, .tif or .tiff, or a folder of them) nor a video this build reads ({e})",
                    args.input.display()
                )
            }
            Err(e) => return Err(e.into()),
        };
        let size = (reader.info().width, reader.info().height);
        let first = args.input.clone();
        (Input::Video(Box::new(reader)), false, first, size)
    } else {
        let (frames, single_image) = list_frames(&args.input)?;
        // The first frame whose header reads sets the size.
        let (first, size) = frames
            .iter()
            .find_map(|p| {
                pa_video::still::still_dimensions(p, &Default::default())
                    .ok()
                    .map(|d| (p.clone(), d))
            })
            .with_context(|| {
                format!(
                    "{}: no readable image (tried {} file(s))",
                    args.input.display(),
                    frames.len()
                )
            })?;
        (Input::Images(frames), single_image, first, size)
    };
    let camera = match (&args.calib, args.fov_deg) {
        (Some(path), _) => {
            let model = pa_camera::calib::load_calibration(path)
                .with_context(|| format!("loading the calibration {}", path.display()))?;
            let k = fit_intrinsics(
                &model.intrinsics,
                width,
                height,
                &path.display().to_string(),
                &first.display().to_string(),
            )?;
            CameraModel {
                intrinsics: k,
                distortion: model.distortion,
            }
        }
        (None, Some(fov)) => {
            if !(fov.is_finite() && fov > 1.0 && fov < 179.0) {
                bail!("--fov-deg must be in (1, 179), got {fov}");
            }
            let f = 0.5 * height as f64 / (0.5 * fov.to_radians()).tan();
            errln!(
                "note: no calibration; assuming an ideal pinhole camera, vertical FOV {fov} deg (f = {f:.1} px), no distortion: poses are approximate"
            );
            CameraModel::pinhole(Intrinsics {
                fx: f,
                fy: f,
                cx: (width as f64 - 1.0) / 2.0,
                cy: (height as f64 - 1.0) / 2.0,
                width,
                height,
            })
        }
        (None, None) => bail!(
            "give --calib FILE (a camera calibration) or --fov-deg D (an approximate pinhole camera)"
        ),
    };
    camera
        .intrinsics
        .validate()
        .context("the camera intrinsics")?;

    if let Some(log) = &args.out_log {
        if log.is_dir() {
            bail!("--out-log {} is a folder; give a file name", log.display());
        }
        // Never a FIFO, a device or a link, --force or not.
        pa_io::check_replaceable(log)?;
        if log.exists() && !args.force {
            bail!("{} exists; pass --force to replace it", log.display());
        }
        if log.is_dir() {
            bail!("--out-log {} is a folder; give a file name", log.display());
        }
    }
    if let Some(dir) = &args.draw {
        if dir.exists() && !dir.is_dir() {
            bail!("--draw {} exists and is not a folder", dir.display());
        }
        if !args.force {
            let existing = match &input {
                Input::Images(frames) => frames
                    .iter()
                    .map(|f| draw_path(dir, f))
                    .find(|p| p.exists()),
                Input::Video(r) => (0..r.info().frame_count.unwrap_or(0) as usize)
                    .map(|i| video_draw_path(dir, &args.input, i))
                    .find(|p| p.exists()),
            };
            if let Some(p) = existing {
                bail!("{} exists; pass --force to replace it", p.display());
            }
        }
    }
    if args.thorough && args.tracking != Tracking::Full {
        bail!("--thorough adds a pass to the full detector; it does not go with --tracking fast");
    }
    let mut detector = args.tracking.detector();
    if !detector.families.contains(&family) {
        detector.families = vec![family];
    }
    if args.thorough {
        detector = detector.thorough();
    }
    let mut tracker = TrackerConfig {
        refine_corners: args.corners.into(),
        ..TrackerConfig::default()
    };
    if single_image {
        tracker.frames_to_track = 1;
    }
    Ok(Config {
        input,
        single_image,
        camera,
        target,
        detector,
        tracker,
        fps: args.fps,
        out_log: args.out_log.clone(),
        draw: args.draw.clone(),
        axis_m: extent_m * 0.5,
    })
}

// --- run -----------------------------------------------------------------------------------

pub fn run(args: Args) -> Result<()> {
    let cfg = resolve(&args)?;
    if let Some(dir) = &cfg.draw {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    let mut tracker = Tracker::new(
        cfg.camera,
        cfg.target.clone(),
        cfg.detector.clone(),
        cfg.tracker,
    )?;
    let (w0, h0) = (cfg.camera.intrinsics.width, cfg.camera.intrinsics.height);
    let total = cfg.input.len();
    let bar = if cfg.single_image {
        ProgressBar::hidden()
    } else {
        let b =
            ProgressBar::with_draw_target(total.map(|n| n as u64), ProgressDrawTarget::stderr());
        b.set_style(
            ProgressStyle::with_template("{bar:40} {pos}/{len} frames {msg} ({eta})")
                .unwrap_or_else(|_| ProgressStyle::default_bar()),
        );
        b
    };
    let mut log = String::new();
    let mut stdout = std::io::stdout().lock();
    let (mut skipped, mut tracked, mut seen, mut count) = (0usize, 0usize, 0usize, 0usize);
    let mut times = Vec::new();
    let mut frames = FrameStream::new(cfg.input, &args.input);
    while let Some(f) = frames.next(cfg.fps)? {
        let TrackFrame {
            index: i,
            name,
            draw_as,
            time_s: t_s,
            pts_s,
            decoded,
        } = f;
        count += 1;
        let gray = match decoded {
            Ok(img) => img,
            Err(e) => {
                if cfg.single_image {
                    return Err(e);
                }
                bar.suspend(|| errln!("warning: skipping {:#}", e));
                skipped += 1;
                let out = tracker.update_with_detections(Vec::new(), t_s)?;
                let mut v = frame_json(i, &name, 0, 0, &out, 0.0);
                v["error"] = json!(format!("{e:#}"));
                if let Some(t) = pts_s {
                    v["time_s"] = json!(round(t, 6));
                }
                emit(&mut log, &mut stdout, cfg.out_log.is_some(), &v)?;
                bar.inc(1);
                continue;
            }
        };
        if (gray.width(), gray.height()) != (w0, h0) {
            bail!(
                "{} is {}x{} but the sequence (and camera) is {w0}x{h0}; all frames must have one size",
                draw_as.display(),
                gray.width(),
                gray.height()
            );
        }
        let frame = pa_track::GrayImage::from(&gray);
        let t0 = Instant::now();
        let out = tracker
            .update(&frame, t_s)
            .with_context(|| format!("tracking in {}", draw_as.display()))?;
        let ms = t0.elapsed().as_secs_f64() * 1e3;
        times.push(ms);
        if out.raw.is_some() {
            seen += 1;
        }
        if out.state == TrackState::Tracked {
            tracked += 1;
        }
        let mut v = frame_json(i, &name, gray.width(), gray.height(), &out, ms);
        if let Some(c) = out.target_corners_px {
            v["target_corners_px"] = json!(c
                .iter()
                .map(|p| [round(p.x, 4), round(p.y, 4)])
                .collect::<Vec<_>>());
        }
        if let Some(t) = pts_s {
            v["time_s"] = json!(round(t, 6));
        }
        emit(&mut log, &mut stdout, cfg.out_log.is_some(), &v)?;
        if let Some(dir) = &cfg.draw {
            let img = draw_frame(&gray, &out, &cfg.camera, cfg.axis_m);
            let p = match &frames {
                FrameStream::Video { .. } => video_draw_path(dir, &args.input, i),
                FrameStream::Images(_) => draw_path(dir, &draw_as),
            };
            let rgba = image::DynamicImage::ImageRgb8(img).to_rgba8();
            super::write_png_atomic(&p, rgba.width(), rgba.height(), rgba.as_raw())?;
        }
        bar.set_message(state_name(out.state));
        bar.inc(1);
    }
    bar.finish_and_clear();
    if count == 0 {
        bail!("{}: no frames", args.input.display());
    }
    if skipped == count {
        bail!(
            "{}: none of the {} frame(s) could be read",
            args.input.display(),
            skipped
        );
    }
    if let Some(p) = &cfg.out_log {
        if let Some(dir) = p.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        }
        pa_model::export::write_atomic(p, log.as_bytes())
            .with_context(|| format!("writing {}", p.display()))?;
    }
    times.sort_by(f64::total_cmp);
    let median = times.get(times.len() / 2).copied().unwrap_or(0.0);
    errln!(
        "{count} frame(s): target seen in {seen}, tracked in {tracked}, {skipped} unreadable skipped; median detection + pose {median:.2} ms/frame{}",
        cfg.out_log
            .as_ref()
            .map(|p| format!("; log {}", p.display()))
            .unwrap_or_default()
    );
    Ok(())
}

/// One frame to track.
struct TrackFrame {
    index: usize,
    /// The JSON's `file`.
    name: String,
    /// The file in messages (a still, or the video).
    draw_as: PathBuf,
    /// The tracker's time, seconds.
    time_s: f64,
    /// A video frame's presentation time.
    pts_s: Option<f64>,
    decoded: Result<image::GrayImage>,
}

/// The frames of the input, one at a time (a video is decoded as it goes), from
/// `pa_video::source`.
enum FrameStream {
    Images(StillsSource),
    Video {
        source: Box<VideoSource>,
        /// The last frame's time, seconds (a skipped frame is one frame period later).
        last_time_s: Option<f64>,
    },
}

impl FrameStream {
    fn new(input: Input, path: &Path) -> Self {
        match input {
            Input::Images(paths) => FrameStream::Images(StillsSource::new(paths)),
            Input::Video(reader) => FrameStream::Video {
                source: Box::new(VideoSource::new(*reader, path, None)),
                last_time_s: None,
            },
        }
    }

    fn next(&mut self, fps: f64) -> Result<Option<TrackFrame>> {
        match self {
            FrameStream::Images(stills) => {
                let f = match stills.next()? {
                    Next::Frame(f) => f,
                    Next::End => return Ok(None),
                    Next::Lost(e) => return Err(e.into()),
                };
                let i = f.index;
                let (decoded, draw_as) = decode(f.pixels, Path::new(""), i);
                Ok(Some(TrackFrame {
                    index: i,
                    name: f.name,
                    draw_as,
                    time_s: i as f64 / fps,
                    pts_s: None,
                    decoded,
                }))
            }
            FrameStream::Video {
                source,
                last_time_s,
            } => {
                let f = match source.next()? {
                    Next::Frame(f) => f,
                    Next::End => return Ok(None),
                    Next::Lost(e) => return Err(e.into()),
                };
                let i = f.index;
                let pts_s = match &f.pixels {
                    Pixels::Frame(fr) => Some(fr.pts.as_secs_f64()),
                    _ => None,
                };
                let (decoded, draw_as) = decode(f.pixels, source.path(), i);
                // Time for the tracker: the frame's own, else one frame period after the last.
                let period_s = 1.0 / source.info().fps.map_or(fps, |f| f.as_f64());
                let time_s = pts_s.unwrap_or(last_time_s.map_or(0.0, |t| t + period_s));
                *last_time_s = Some(time_s);
                Ok(Some(TrackFrame {
                    index: i,
                    name: f.name,
                    draw_as,
                    time_s,
                    pts_s,
                    decoded,
                }))
            }
        }
    }
}

/// A frame's pixels as a grey image (or why not), and the file that names the frame in
/// messages: the still, or the `video` it comes from.
fn decode(pixels: Pixels, video: &Path, i: usize) -> (Result<image::GrayImage>, PathBuf) {
    let decoded = match pixels {
        Pixels::Still(path) => {
            let d = pa_video::still::read_still(&path, &Default::default())
                .map(|img| img.to_luma8())
                .map_err(anyhow::Error::from);
            return (d, path);
        }
        Pixels::Frame(f) => image::RgbaImage::from_raw(f.width, f.height, f.rgba)
            .map(|img| image::DynamicImage::ImageRgba8(img).to_luma8())
            .with_context(|| {
                format!(
                    "{}: frame {i} has the wrong number of bytes",
                    video.display()
                )
            }),
        // One damaged frame: skipped; the reader goes on with the next one.
        Pixels::Unreadable(e) => Err(anyhow::Error::from(e)),
    };
    (decoded, video.to_path_buf())
}

fn emit(log: &mut String, stdout: &mut impl Write, to_file: bool, v: &Value) -> Result<()> {
    let line = serde_json::to_string(v)?;
    if to_file {
        log.push_str(&line);
        log.push('\n');
    } else {
        writeln!(stdout, "{line}")?;
    }
    Ok(())
}
