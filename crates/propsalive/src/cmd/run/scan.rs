//! The scan pass of `run` (`--scan FOLDER|VIDEO`, or the shot's `[scan] input`): before the
//! take, the animator circles the key prop once with the camera; each scan frame is tracked
//! on its own (as the take's stills are) and fed to the pipeline's texture memory only (no
//! output frame). The take then runs with the memory primed.
//!
//! Resume: the memory the scan leaves is given back to the pipeline before every still
//! (`ArPipeline::restore_memory`), so a frame depends only on its still, the shot and the
//! scan, and a resumed take is identical to an uninterrupted one. The scan's identity (each
//! scan file's name, size and modification time) is part of the take's settings hash: a
//! changed scan re-renders the take's frames, as a changed shot does.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use glam::Mat4;
use pa_pipeline::ar::ArPipeline;
use pa_track::Tracker;
use pa_video::source::{InputSpec, Next, Pixels, Source, StillsSource, VideoSource};

/// The scan input: `--scan` (relative to the working folder) over the shot's `[scan] input`
/// (relative to the shot, kept inside its folder).
pub(super) fn scan_input(
    flag: Option<&Path>,
    shot: &pa_pipeline::shot::Shot,
    shot_path: &Path,
) -> Result<Option<PathBuf>> {
    match flag {
        Some(p) => Ok(Some(p.to_path_buf())),
        None => Ok(shot.scan.resolve(shot_path)?),
    }
}

/// One line per scan file, name, size and modification time: the scan's part of the take's
/// settings hash. A camera is refused (a scan is a recording).
pub(super) fn identity(scan: &Path) -> Result<String> {
    let files: Vec<PathBuf> = match pa_video::source::parse_input(scan)
        .with_context(|| format!("--scan {}", scan.display()))?
    {
        InputSpec::Folder(dir) => pa_video::source::list_stills(&dir)?,
        InputSpec::Video(p) => vec![p],
        InputSpec::Camera(_) => {
            bail!("--scan takes a folder of stills or a video file, not a camera")
        }
    };
    let mut out = String::new();
    for f in files {
        let m = std::fs::metadata(&f).with_context(|| format!("scan file {}", f.display()))?;
        let mtime = m
            .modified()
            .ok()
            .and_then(|t| t.duration_since(std::time::UNIX_EPOCH).ok())
            .map_or(0, |d| d.as_nanos());
        let name = f
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        out.push_str(&format!("{name} {} {mtime}\n", m.len()));
    }
    Ok(out)
}

/// Runs the scan: every frame of `scan` tracked on its own and remembered. Returns (frames
/// read, frames used). Frames of another size than the take's are skipped with a note.
pub(super) fn run_scan(
    scan: &Path,
    tracker: &mut Tracker,
    pipeline: &mut ArPipeline,
    (width, height): (u32, u32),
    key_time_s: f32,
) -> Result<(usize, usize)> {
    let mut source: Box<dyn Source> = match pa_video::source::parse_input(scan)? {
        InputSpec::Folder(dir) => Box::new(StillsSource::open(&dir)?),
        InputSpec::Video(p) => Box::new(VideoSource::open(&p)?),
        InputSpec::Camera(_) => {
            bail!("--scan takes a folder of stills or a video file, not a camera")
        }
    };
    let total = source.frame_count();
    let (mut read, mut used) = (0usize, 0usize);
    let budget = pa_video::still::StillBudget::default();
    while let Next::Frame(frame) = source.next()? {
        read += 1;
        let (w, h, rgba) = match frame.pixels {
            Pixels::Frame(f) => (f.width, f.height, f.rgba),
            Pixels::Still(p) => {
                let img = pa_video::still::read_still(&p, &budget)?.to_rgba8();
                (img.width(), img.height(), img.into_raw())
            }
            Pixels::Unreadable(e) => {
                errln!("scan: {} skipped: {e}", frame.name);
                continue;
            }
        };
        if (w, h) != (width, height) {
            errln!(
                "scan: {} is {w}x{h}, the take is {width}x{height}: skipped",
                frame.name
            );
            continue;
        }
        tracker.reset();
        let gray = pa_pipeline::ar::gray_from_rgba(&rgba, w, h)?;
        let out = tracker.update(&gray, 0.0)?;
        if let Some(pose) = out.pose.map(|p| p.to_mat4()) {
            if remember(pipeline, &rgba, (w, h), key_time_s, pose)? {
                used += 1;
            }
        }
        if read % 10 == 0 {
            let of = total.map_or(String::new(), |t| format!(" of {t}"));
            errln!("scan: {read}{of} frames read, {used} tracked and remembered");
        }
    }
    errln!("scan: {read} frames read, {used} tracked and remembered");
    Ok((read, used))
}

fn remember(
    pipeline: &mut ArPipeline,
    rgba: &[u8],
    (w, h): (u32, u32),
    key_time_s: f32,
    pose: Mat4,
) -> Result<bool> {
    Ok(pipeline.remember_with_pose(rgba, w, h, key_time_s, pose)?)
}
