//! External sets: takes of our set rendered by another renderer (Blender's Cycles, by
//! `scripts/blender/render_set.py`), read from a folder with a manifest, and measured exactly
//! as [`crate::eval`] measures the generated scenes.
//!
//! [`kit`] writes what the renderer needs (model, board sheet, placement, key pose, camera
//! path); [`manifest`] reads what it wrote back (input frames, ground truth, masks, plate and
//! the true cameras), hostile-input safe; [`run_set`] runs the pipeline over the frames.

pub mod kit;
pub mod manifest;

use pa_camera::CameraModel;
use pa_model::Model;
use pa_pipeline::ar::{ArFrame, ArPipeline, ArSettings, FrameTimes};
use pa_pipeline::metrics::{psnr_region, ssim_region};
use pa_render::Renderer;
use pa_track::{DetectorConfig, TrackTarget, Tracker, TrackerConfig};

pub use manifest::{SetFrame, SetManifest, SetModel};

use crate::eval::{pose_error, FrameMetrics};
use crate::flicker::{flicker_region, Flicker, EDGE_MARGIN_PX};
use crate::prop::{prop_model, PropSpec};
use crate::SceneError;

/// The images of one set frame.
pub struct SetImages {
    pub input: Vec<u8>,
    pub truth: Vec<u8>,
    pub key_mask: Vec<bool>,
    pub truth_mask: Vec<bool>,
}

/// Reads a frame's images (each checked against the manifest's size).
pub fn read_frame(set: &SetManifest, f: &SetFrame) -> Result<SetImages, SceneError> {
    let (w, h) = (set.width, set.height);
    let p = |rel: &std::path::Path| set.dir.join(rel);
    Ok(SetImages {
        input: manifest::read_rgba8(&p(&f.input), w, h)?,
        truth: manifest::read_rgba8(&p(&f.truth), w, h)?,
        key_mask: manifest::read_mask(&p(&f.key_mask), w, h)?,
        truth_mask: manifest::read_mask(&p(&f.truth_mask), w, h)?,
    })
}

/// The set's model.
pub fn load_model(set: &SetManifest) -> Result<Model, SceneError> {
    Ok(match set.model_path() {
        Some(path) => Model::load(path)?,
        None => prop_model(&PropSpec::default())?,
    })
}

/// Intersection over union of two masks; None when both are empty.
pub fn iou(a: &[bool], b: &[bool]) -> Option<f64> {
    let (mut i, mut u) = (0usize, 0usize);
    for (&x, &y) in a.iter().zip(b) {
        i += usize::from(x && y);
        u += usize::from(x || y);
    }
    (u > 0).then(|| i as f64 / u as f64)
}

/// The revealed pixels of a set frame away from the in-between's edge (its masks'
/// [`flicker_region`]): where the flicker and the revealed PSNR off the edge are measured.
pub fn off_edge_region(set: &SetManifest, img: &SetImages) -> Vec<bool> {
    flicker_region(
        &img.key_mask,
        &img.truth_mask,
        set.width as usize,
        EDGE_MARGIN_PX,
    )
}

/// Measures one output against a set frame (the set's masks define the regions; `off_edge`
/// is [`off_edge_region`] of the frame).
pub fn measure_set_frame(
    set: &SetManifest,
    f: &SetFrame,
    img: &SetImages,
    out: &ArFrame,
    off_edge: &[bool],
) -> FrameMetrics {
    let (w, h) = (set.width as usize, set.height as usize);
    let revealed: Vec<bool> = img
        .key_mask
        .iter()
        .zip(&img.truth_mask)
        .map(|(&k, &t)| k && !t)
        .collect();
    let (rot_err_deg, trans_err_mm) = match out.camera_from_marker {
        Some(p) => {
            let (r, t) = pose_error(p, f.camera_from_marker);
            (Some(r), Some(t))
        }
        None => (None, None),
    };
    FrameMetrics {
        frame: f.index,
        key: 0,
        key_distance_deg: f64::NAN,
        key_distance_props: f64::NAN,
        psnr_prop: psnr_region(&out.rgba8, &img.truth, &img.truth_mask),
        ssim_prop: ssim_region(&out.rgba8, &img.truth, w, h, &img.truth_mask),
        psnr_revealed: psnr_region(&out.rgba8, &img.truth, &revealed),
        ssim_revealed: ssim_region(&out.rgba8, &img.truth, w, h, &revealed),
        psnr_revealed_off_edge: psnr_region(&out.rgba8, &img.truth, off_edge),
        rot_err_deg,
        trans_err_mm,
        tracked: out.camera_from_marker.is_some(),
        timings: out.timings,
        flicker: None,
        key_mask_iou: iou(&out.key_mask, &img.key_mask),
        twin_mask_iou: iou(&out.twin_mask, &img.truth_mask),
    }
}

/// The tracker for a set's frames: stills of a stop-motion take (the camera jumps between
/// them), tracked as `propsalive run` tracks stills (`pa_video::source`'s policy): each frame
/// alone, the first detection trusted, no region of interest, no pose filter.
pub fn stills_tracker_config() -> TrackerConfig {
    TrackerConfig::per_still()
}

/// Builds the pipeline for a set: the real tracker on the set's board (the stills policy,
/// [`stills_tracker_config`]), the set's model and placement, and its clean plate where it
/// has one.
pub fn pipeline_for_set(
    set: &SetManifest,
    renderer: &mut Renderer,
    settings: ArSettings,
) -> Result<ArPipeline, SceneError> {
    let camera = CameraModel::pinhole(set.intrinsics);
    let tracker = Tracker::new(
        camera,
        TrackTarget::Board(set.board.clone()),
        DetectorConfig::default(),
        stills_tracker_config(),
    )?;
    let mut p = ArPipeline::new(
        renderer,
        load_model(set)?,
        set.animation,
        camera,
        set.marker_from_prop,
        Some(tracker),
        settings,
    )?;
    // The kit prints the sheet at this size, centred on the marker (`board_sheet_m`).
    p.set_board_surfaces(Some(pa_pipeline::ar::BoardSurfaces::new(
        &set.board,
        Some(f64::from(crate::scene::BOARD_SHEET_M)),
    )));
    if let Some((plate, pose)) = &set.plate {
        let rgba8 = manifest::read_rgba8(&set.dir.join(plate), set.width, set.height)?;
        let plate = pa_diminish::ImageRgba8::new(set.width, set.height, rgba8)?;
        p.set_clean_plate(plate, *pose);
    }
    Ok(p)
}

/// Runs `settings` over every frame of a set, in order, each frame tracked alone (the tracker
/// is reset before each, as for stills); the flicker metric compares consecutive frames.
/// `each` sees every (frame, images, output, metrics).
pub fn run_set<E: From<SceneError>>(
    renderer: &mut Renderer,
    set: &SetManifest,
    settings: ArSettings,
    each: impl FnMut(&SetFrame, &SetImages, &ArFrame, &FrameMetrics) -> Result<(), E>,
) -> Result<Vec<FrameMetrics>, E> {
    Ok(run_set_with(renderer, set, settings, SetRun::default(), each)?.0)
}

/// [`run_set`] with the texture memory on or off (`crate::memory`): the set's key prop
/// stands still through its frames, so each frame also remembers it for the next.
pub fn run_set_memory<E: From<SceneError>>(
    renderer: &mut Renderer,
    set: &SetManifest,
    settings: ArSettings,
    memory: bool,
    each: impl FnMut(&SetFrame, &SetImages, &ArFrame, &FrameMetrics) -> Result<(), E>,
) -> Result<Vec<FrameMetrics>, E> {
    let run = SetRun {
        memory,
        ..SetRun::default()
    };
    Ok(run_set_with(renderer, set, settings, run, each)?.0)
}

/// [`run_set`] with the pipeline's shadows on or off ([`ArPipeline::set_shadows`]); also
/// returns the light the pipeline used at the end (estimated from the frames).
pub fn run_set_shadows<E: From<SceneError>>(
    renderer: &mut Renderer,
    set: &SetManifest,
    settings: ArSettings,
    shadows: bool,
    each: impl FnMut(&SetFrame, &SetImages, &ArFrame, &FrameMetrics) -> Result<(), E>,
) -> Result<(Vec<FrameMetrics>, Option<pa_pipeline::shadow::ShadowLight>), E> {
    let run = SetRun {
        shadows,
        ..SetRun::default()
    };
    run_set_with(renderer, set, settings, run, each)
}

/// What a set run switches on beyond `settings`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct SetRun {
    /// The pipeline's shadows ([`ArPipeline::set_shadows`]).
    pub shadows: bool,
    /// The texture memory ([`ArPipeline::set_texture_memory`]).
    pub memory: bool,
    /// The texture stage's render path; `None`: the one the pipeline picks for the adapter.
    pub render_path: Option<pa_pipeline::ar::RenderPath>,
}

/// [`run_set`] with `run`'s switches; also returns the light the pipeline used at the end.
pub fn run_set_with<E: From<SceneError>>(
    renderer: &mut Renderer,
    set: &SetManifest,
    settings: ArSettings,
    run: SetRun,
    mut each: impl FnMut(&SetFrame, &SetImages, &ArFrame, &FrameMetrics) -> Result<(), E>,
) -> Result<(Vec<FrameMetrics>, Option<pa_pipeline::shadow::ShadowLight>), E> {
    let mut pipeline = pipeline_for_set(set, renderer, settings)?;
    pipeline.set_shadows(run.shadows);
    pipeline.set_texture_memory(run.memory);
    if let Some(path) = run.render_path {
        pipeline.set_render_path(path);
    }
    let mut flicker = Flicker::new(set.intrinsics);
    if let Some(table_m) = set.table_m {
        flicker = flicker.with_plane_extent(f64::from(table_m) * 0.5);
    }
    let mut all = Vec::new();
    for f in &set.frames {
        let img = read_frame(set, f)?;
        // Each still tracked alone; the fill sees one take.
        pipeline.reset_tracking();
        let out = pipeline
            .process(
                renderer,
                &img.input,
                set.width,
                set.height,
                FrameTimes {
                    animation_s: f.time_s,
                    key_pose_s: f.key_time_s,
                },
                f64::from(f.index) / 24.0,
            )
            .map_err(SceneError::from)?;
        let region = off_edge_region(set, &img);
        let mut m = measure_set_frame(set, f, &img, &out, &region);
        m.flicker = flicker.step(&out.rgba8, &img.truth, &region, f.camera_from_marker);
        each(f, &img, &out, &m)?;
        all.push(m);
    }
    Ok((all, pipeline.shadow_light()))
}

#[cfg(test)]
#[path = "tests.rs"]
mod tests;
