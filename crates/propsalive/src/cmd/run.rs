//! `propsalive run SHOT.toml --input FOLDER --out DIR`: stop-motion mode over a folder of
//! stills (PNG/JPEG/TIFF, natural order). Still `i` shows animation frame `i / exposure`
//! (`--exposure 1` = ones, `2` = twos) with the shot's present key prop in front of the camera;
//! each still goes through the real pipeline (track -> place -> animate -> texture -> diminish
//! -> composite).
//!
//! Outputs, in DIR:
//! - `frames/NNNNNN.png`: one frame per still, numbered by the still's index in sorted order,
//!   8- or 16-bit (`--bit-depth`), written atomically (temporary file, fsync, rename).
//! - `log.jsonl`: one JSON object per still: `index`, `input` (file name), `input_bytes`,
//!   `input_mtime_ns`, `anim_frame`, `key_pose`, `state`, `camera_from_marker` (16 numbers,
//!   column-major, or null), `reprojection_px`, `timings_ms` (track, animate, texture,
//!   diminish, composite, encode), `output` (`frames/NNNNNN.png`, or null), `skipped` (the
//!   reason a still was not rendered, or null), and the take's settings (`exposure`,
//!   `bit_depth`, `shot_hash`). Each line is appended and fsynced before its frame is written.
//! - `camera.gltf`: the tracked camera of every still of the take with a pose in the log, as
//!   an animated glTF 2.0 camera (see `camera_export`), rewritten atomically at the end of
//!   each run; not written (a note says so) when no still was tracked.
//!
//! Decisions:
//! - **Every still is independent.** The tracker is reset before each still, runs without
//!   temporal filtering or region-of-interest search, and needs one sighting (stills of a
//!   stop-motion take are not a video: the camera may be moved between them). So a frame
//!   depends only on its still and the shot, and a resumed take is identical to an
//!   uninterrupted one.
//! - **Resume.** A still whose log line and frame both exist (and whose file name, size and
//!   modification time match the log) is not processed again. A truncated last log line is
//!   ignored; at start the log is rewritten atomically with one line per index; at the end of
//!   a run it is compacted again if a still was redone.
//! - **Re-shot stills** (name, size or mtime differ from the log): the frame is re-rendered
//!   and stderr says `re-shot: frame N replaced`.
//! - **Never overwrite silently.** A file in `frames/` the log does not know (another take,
//!   a hand-made file) stops the run unless `--force`. A take made with another exposure,
//!   bit depth or shot file stops the run unless `--force` (which re-renders those frames).
//! - **Bad stills** are skipped, logged with the reason, and leave a gap in the numbering:
//!   an unreadable file, or a still whose size differs from the first readable still (the
//!   camera and the take have one resolution). The run goes on, exits 0 and ends with a
//!   warning summary. A folder where no still is readable is an error.
//! - **16-bit output:** the pipeline works in 8-bit sRGB. Pixels it did not change keep the
//!   still's own 16-bit values; changed pixels (the twin, the filled region) are the 8-bit
//!   result widened (`v * 257`).

use std::collections::BTreeMap;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::{Instant, UNIX_EPOCH};

use anyhow::{bail, Context, Result};
use pa_camera::{CameraModel, Intrinsics};
use pa_pipeline::ar::{ArPipeline, ArSettings, StageTimings};
use pa_pipeline::shot::Shot;
use pa_render::Renderer;
use pa_track::board::BoardTag;
use pa_track::{Board, DetectorConfig, TagFamily, TrackTarget, Tracker, TrackerConfig};
use serde::{Deserialize, Serialize};

#[derive(clap::Args)]
pub struct Args {
    /// The shot file (TOML: model, animation, fps, key poses, camera, marker, placement).
    pub shot: PathBuf,
    /// Folder of stills (.png, .jpg, .jpeg, .tif, .tiff), processed in natural order.
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
    /// Replace frames the take's log does not know, and re-render frames made with other
    /// settings.
    #[arg(long)]
    pub force: bool,
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
    pub exposure: u32,
    pub bit_depth: u8,
    pub shot_hash: String,
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
    if !path.exists() {
        return Ok(map);
    }
    let text = std::fs::read(path).with_context(|| format!("reading {}", path.display()))?;
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
                eprintln!(
                    "note: {}: ignoring a truncated last line ({e})",
                    path.display()
                );
            }
            Err(e) => eprintln!(
                "warning: {}: ignoring unreadable line {} ({e})",
                path.display(),
                n + 1
            ),
        }
    }
    Ok(map)
}

fn write_log(path: &Path, entries: &BTreeMap<usize, Entry>) -> Result<()> {
    let mut text = String::new();
    for e in entries.values() {
        text.push_str(&serde_json::to_string(e)?);
        text.push('\n');
    }
    pa_model::export::write_atomic(path, text.as_bytes())
        .with_context(|| format!("writing {}", path.display()))?;
    sync_dir(path);
    Ok(())
}

/// Makes a rename in `path`'s folder durable (best effort).
fn sync_dir(path: &Path) {
    if let Some(dir) = path.parent() {
        if let Ok(d) = std::fs::File::open(dir) {
            let _ = d.sync_all();
        }
    }
}

fn board_from_shot(shot: &Shot, shot_path: &Path) -> Result<Board> {
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

struct Config {
    stills: Vec<PathBuf>,
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
}

fn resolve(args: &Args) -> Result<Config> {
    if args.exposure == 0 || args.exposure > 1000 {
        bail!(
            "--exposure must be 1 (ones), 2 (twos), ... up to 1000, got {}",
            args.exposure
        );
    }
    if args.bit_depth != 8 && args.bit_depth != 16 {
        bail!("--bit-depth must be 8 or 16, got {}", args.bit_depth);
    }
    let shot = Shot::load(&args.shot)?;
    let shot_text =
        std::fs::read(&args.shot).with_context(|| format!("reading {}", args.shot.display()))?;
    if !args.input.is_dir() {
        bail!(
            "--input {}: not a folder (stop-motion mode takes a folder of stills)",
            args.input.display()
        );
    }
    let (stills, _) = super::track::list_frames(&args.input)?;
    let (first, (width, height)) = stills
        .iter()
        .find_map(|p| image::image_dimensions(p).ok().map(|d| (p, d)))
        .with_context(|| {
            format!(
                "{}: no readable still (tried {} file(s))",
                args.input.display(),
                stills.len()
            )
        })?;
    let camera = match (&shot.camera.calibration, shot.camera.fov_y_deg) {
        (Some(c), _) => {
            let path = Shot::resolve(&args.shot, c);
            let model = pa_camera::calib::load_calibration(&path)
                .with_context(|| format!("loading the calibration {}", path.display()))?;
            let k = super::track::fit_intrinsics(
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
                bail!(
                    "{}: [camera] fov_y_deg must be in (1, 179), got {fov}",
                    args.shot.display()
                );
            }
            CameraModel::pinhole(Intrinsics::from_fov_y(fov.to_radians(), width, height)?)
        }
        (None, None) => bail!(
            "{}: [camera] needs calibration or fov_y_deg",
            args.shot.display()
        ),
    };
    let board = board_from_shot(&shot, &args.shot)?;
    let model_path = Shot::resolve(&args.shot, &shot.model);
    let model = pa_model::Model::load(&model_path)
        .with_context(|| format!("loading the model {}", model_path.display()))?;
    let animation = shot.check_model(&args.shot, &model)?;
    let key = &shot.key_poses[shot.present_key_index()];
    Ok(Config {
        stills,
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
    })
}

/// What to do with one still.
enum Plan {
    /// Logged and present (or logged as skipped): nothing to do.
    Done,
    /// Process; the message (if any) is said on stderr first.
    Process(Option<String>),
}

/// Removes temporary files a killed run left behind (`.NAME.tmp-PID`).
fn remove_stale_temps(dir: &Path) {
    if let Ok(rd) = std::fs::read_dir(dir) {
        for e in rd.flatten() {
            let name = e.file_name().to_string_lossy().into_owned();
            if name.starts_with('.') && name.contains(".tmp-") {
                let _ = std::fs::remove_file(e.path());
            }
        }
    }
}

fn state_of(observed: bool) -> pa_track::TrackState {
    if observed {
        pa_track::TrackState::Tracked
    } else {
        pa_track::TrackState::Searching
    }
}

/// The output frame as PNG bytes.
fn encode(
    out8: &[u8],
    input: &image::DynamicImage,
    bit_depth: u8,
    w: u32,
    h: u32,
) -> Result<Vec<u8>> {
    let mut png = Vec::new();
    let mut cur = std::io::Cursor::new(&mut png);
    if bit_depth == 16 {
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

pub fn run(args: Args) -> Result<()> {
    let cfg = resolve(&args)?;
    let frames_dir = args.out.join("frames");
    std::fs::create_dir_all(&frames_dir)
        .with_context(|| format!("creating {}", frames_dir.display()))?;
    remove_stale_temps(&frames_dir);
    remove_stale_temps(&args.out);
    let log_path = args.out.join("log.jsonl");
    let mut entries = read_log(&log_path)?;

    // Settings of an existing take.
    let stale: std::collections::HashSet<usize> = entries
        .values()
        .filter(|e| {
            e.exposure != args.exposure
                || e.bit_depth != args.bit_depth
                || e.shot_hash != cfg.shot_hash
        })
        .map(|e| e.index)
        .collect();
    if !stale.is_empty() && !args.force {
        bail!(
            "{}: {} frame(s) of this take were made with another exposure, bit depth or shot file; use a new --out folder, or --force to re-render them",
            args.out.display(),
            stale.len()
        );
    }

    // Files in frames/ the log does not know.
    let known: std::collections::HashSet<String> =
        entries.values().filter_map(|e| e.output.clone()).collect();
    let mut foreign = Vec::new();
    for e in std::fs::read_dir(&frames_dir)
        .with_context(|| format!("reading {}", frames_dir.display()))?
        .flatten()
    {
        let name = e.file_name().to_string_lossy().into_owned();
        if name.starts_with('.') {
            continue;
        }
        if !known.contains(&format!("frames/{name}")) {
            foreign.push(name);
        }
    }
    foreign.sort_by(|a, b| super::track::natural_cmp(a, b));
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
                frames_dir.display(),
                foreign.len()
            );
        }
        eprintln!(
            "warning: --force: {} file(s) in {} are not from this take ({list}{more}); those a still maps to will be replaced",
            foreign.len(),
            frames_dir.display()
        );
    }

    // Plan every still.
    let n = cfg.stills.len();
    let mut plans = Vec::with_capacity(n);
    let mut stamps = Vec::with_capacity(n);
    for (i, path) in cfg.stills.iter().enumerate() {
        let name = path
            .file_name()
            .unwrap_or_default()
            .to_string_lossy()
            .into_owned();
        let stamp = file_stamp(path)?;
        stamps.push(stamp);
        let plan = match entries.get(&i) {
            None => Plan::Process(None),
            Some(_) if stale.contains(&i) => {
                Plan::Process(Some(format!("settings changed: frame {i} re-rendered")))
            }
            Some(e) if e.input != name || (e.input_bytes, e.input_mtime_ns) != stamp => {
                Plan::Process(Some(if e.output.is_some() {
                    format!("re-shot: frame {i} replaced ({name})")
                } else {
                    format!("re-shot: still {i} ({name}) was skipped before; trying again")
                }))
            }
            Some(e) => match &e.output {
                Some(o) if args.out.join(o).is_file() => Plan::Done,
                Some(_) => Plan::Process(None),
                None => Plan::Done,
            },
        };
        plans.push(plan);
    }
    // One line per index, no truncated line, before appending.
    write_log(&log_path, &entries)?;

    let todo = plans
        .iter()
        .filter(|p| matches!(p, Plan::Process(_)))
        .count();
    let resumed = n - todo;
    if resumed > 0 {
        eprintln!(
            "resuming the take in {}: {resumed} of {n} still(s) already done",
            args.out.display()
        );
    }
    let (mut processed, mut skipped_read, mut skipped_size, mut reshot) = (0, 0, 0, 0);
    if todo > 0 {
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
        let mut tracker = Tracker::new(
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
        let mut log = std::fs::OpenOptions::new()
            .append(true)
            .create(true)
            .open(&log_path)
            .with_context(|| format!("opening {}", log_path.display()))?;
        let t_start = Instant::now();
        let mut k = 0usize;
        for (i, path) in cfg.stills.iter().enumerate() {
            let Plan::Process(msg) = &plans[i] else {
                continue;
            };
            k += 1;
            if let Some(m) = msg {
                eprintln!("{m}");
                if m.starts_with("re-shot") {
                    reshot += 1;
                }
            }
            let name = path
                .file_name()
                .unwrap_or_default()
                .to_string_lossy()
                .into_owned();
            let anim_frame = (i / args.exposure as usize) as u32;
            let mut entry = Entry {
                index: i,
                input: name.clone(),
                input_bytes: stamps[i].0,
                input_mtime_ns: stamps[i].1,
                anim_frame,
                key_pose: cfg.key_name.clone(),
                state: None,
                camera_from_marker: None,
                reprojection_px: None,
                timings_ms: None,
                output: None,
                skipped: None,
                exposure: args.exposure,
                bit_depth: args.bit_depth,
                shot_hash: cfg.shot_hash.clone(),
            };
            let img = match image::open(path) {
                Ok(img) if (img.width(), img.height()) != (cfg.width, cfg.height) => {
                    skipped_size += 1;
                    let why = format!(
                        "{}x{} but the take is {}x{} (set by the first readable still)",
                        img.width(),
                        img.height(),
                        cfg.width,
                        cfg.height
                    );
                    eprintln!("warning: skipping still {i} ({name}): {why}");
                    entry.skipped = Some(format!("wrong size: {why}"));
                    None
                }
                Ok(img) => Some(img),
                Err(e) => {
                    skipped_read += 1;
                    eprintln!("warning: skipping still {i} ({name}): cannot read it: {e}");
                    entry.skipped = Some(format!("unreadable: {e}"));
                    None
                }
            };
            let png = match img {
                None => None,
                Some(img) => {
                    let rgba = img.to_rgba8();
                    let (w, h) = (cfg.width, cfg.height);
                    let t0 = Instant::now();
                    tracker.reset();
                    let gray = pa_pipeline::ar::gray_from_rgba(rgba.as_raw(), w, h)?;
                    let t_s = anim_frame as f64 / cfg.fps as f64;
                    let out = tracker.update(&gray, t_s)?;
                    let track_ms = t0.elapsed().as_secs_f64() * 1e3;
                    let pose = out.pose.map(|p| p.to_mat4());
                    let (rgba_out, mut timings) = match pose {
                        Some(p) => {
                            let f = pipeline.process_with_pose(
                                &mut renderer,
                                rgba.as_raw(),
                                w,
                                h,
                                anim_frame as f32 / cfg.fps,
                                cfg.key_time_s,
                                p,
                            )?;
                            (f.rgba8, f.timings)
                        }
                        // No pose: the still goes out untouched (as the pipeline does).
                        None => (rgba.as_raw().clone(), StageTimings::default()),
                    };
                    timings.track_ms = track_ms;
                    let t1 = Instant::now();
                    let png = encode(&rgba_out, &img, args.bit_depth, w, h)?;
                    entry.state =
                        Some(super::track::state_name(state_of(out.pose.is_some())).to_string());
                    entry.camera_from_marker = pose.map(|p| p.to_cols_array().to_vec());
                    entry.reprojection_px = out.raw.map(|r| r.rms_px);
                    entry.timings_ms = Some(Timings {
                        track: timings.track_ms,
                        animate: timings.animate_ms,
                        texture: timings.texture_ms,
                        diminish: timings.diminish_ms,
                        composite: timings.composite_ms,
                        encode: t1.elapsed().as_secs_f64() * 1e3,
                    });
                    entry.output = Some(format!("frames/{}", frame_name(i)));
                    processed += 1;
                    Some(png)
                }
            };
            // The log line first (fsynced), then the frame: a frame never exists unknown to
            // the log, and a line without its frame is redone on resume.
            let line = serde_json::to_string(&entry)?;
            writeln!(log, "{line}").with_context(|| format!("writing {}", log_path.display()))?;
            log.flush()?;
            log.sync_data()?;
            entries.insert(i, entry);
            if let Some(png) = png {
                let p = frames_dir.join(frame_name(i));
                pa_model::export::write_atomic(&p, &png)
                    .with_context(|| format!("writing {}", p.display()))?;
                sync_dir(&p);
            }
            let el = t_start.elapsed().as_secs_f64();
            let fps = k as f64 / el.max(1e-9);
            let left = (todo - k) as f64 / fps.max(1e-9);
            eprintln!(
                "frame {k}/{todo} (still {i}, {name}): {}  {fps:.2} frames/s, about {left:.0} s left",
                entries[&i]
                    .state
                    .as_deref()
                    .unwrap_or("skipped")
            );
        }
        drop(log);
        // Lines of redone stills were appended after their old ones: compact.
        write_log(&log_path, &entries)?;
    }
    let skipped_before = entries
        .values()
        .filter(|e| e.index < n && e.skipped.is_some())
        .count()
        .saturating_sub(skipped_read + skipped_size);
    let past_end = entries
        .values()
        .filter(|e| e.index >= n && e.output.is_some())
        .count();
    if past_end > 0 {
        eprintln!(
            "note: the take has {past_end} frame(s) past the last of the {n} still(s) (stills removed?); left in place"
        );
    }
    let produced = entries
        .values()
        .filter(|e| e.index < n && e.output.is_some())
        .count();
    if produced == 0 {
        bail!(
            "{}: none of the {n} still(s) could be rendered (see {})",
            args.input.display(),
            log_path.display()
        );
    }
    eprintln!(
        "run: {n} still(s): {processed} processed, {resumed} resumed from an earlier run, {} skipped{}; frames in {}, log {}",
        skipped_read + skipped_size,
        if reshot > 0 {
            format!(", {reshot} re-shot")
        } else {
            String::new()
        },
        frames_dir.display(),
        log_path.display()
    );
    let total_skipped = skipped_read + skipped_size + skipped_before;
    if total_skipped > 0 {
        eprintln!(
            "warning: {total_skipped} still(s) have no frame ({skipped_read} unreadable, {skipped_size} with another size this run; {skipped_before} skipped in an earlier run): see \"skipped\" in {}",
            log_path.display()
        );
    }
    export_camera(&args.out, &entries, n, &cfg)
}

/// Writes `camera.gltf` from the log's poses of stills `0..n` (a resumed run exports the whole
/// take). No pose at all is a note, not an error: the frames are there.
fn export_camera(
    out: &Path,
    entries: &BTreeMap<usize, Entry>,
    n: usize,
    cfg: &Config,
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
        eprintln!("note: no still of the take was tracked: no camera.gltf written");
        return Ok(());
    }
    let doc = super::camera_export::camera_gltf(&poses, &cfg.camera.intrinsics, cfg.fps)?;
    let path = out.join("camera.gltf");
    pa_model::export::write_atomic(&path, doc.json.as_bytes())
        .with_context(|| format!("writing {}", path.display()))?;
    sync_dir(&path);
    eprintln!(
        "camera: {} tracked still(s) exported to {} (glTF 2.0, Y-up, {} fps)",
        doc.keys,
        path.display(),
        cfg.fps
    );
    Ok(())
}
