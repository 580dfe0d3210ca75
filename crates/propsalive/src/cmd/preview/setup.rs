//! What the preview runs, resolved before the window opens: the renderer, the frame
//! pipeline, the frame source and the initial state, for the built-in scene or for a shot
//! with a folder of stills, a video file or a live camera.

use std::path::Path;

use pa_pipeline::ar::Fill;
use pa_pipeline::shot_diminish::{DiminishConfig, FillName};

use anyhow::{bail, Context, Result};
use pa_pipeline::ar::{ArPipeline, ArSettings};
use pa_pipeline::shot::Shot;
use pa_pipeline::shot_config;
use pa_render::Renderer;
use pa_track::{Tracker, TrackerConfig};

use super::source::{CameraSource, FrameSource, SceneSource, StillsSource, VideoSource};
use super::state::{KeyPose, PreviewState};
use crate::cmd::run::diminish::{self, DiminishArgs};
use crate::cmd::run::{self, InputSpec};

/// The pipeline's fill of a name of the preview's fill list (`None`: not in this build).
pub fn fill_named(name: &str) -> Option<Fill> {
    name.parse::<FillName>().ok().and_then(FillName::to_fill)
}

/// The fills `F` cycles through: those this build has, the plate only with a plate; the
/// resolved fill first in use.
fn fills(d: &DiminishConfig, has_plate: bool) -> (Vec<String>, usize) {
    let names: Vec<String> = FillName::ALL
        .into_iter()
        .filter(|f| f.to_fill().is_some() && *f != FillName::None)
        .filter(|f| has_plate || *f != FillName::Plate)
        .map(|f| f.name().to_string())
        .collect();
    let current = names.iter().position(|n| n == d.fill.name()).unwrap_or(0);
    (names, current)
}

/// Applies the resolved settings to the pipeline and the state.
fn apply(
    pipeline: &mut ArPipeline,
    state: PreviewState,
    d: &DiminishConfig,
    plate: Option<(pa_diminish::ImageRgba8, glam::Mat4)>,
    has_plate: bool,
) -> Result<PreviewState> {
    diminish::apply(pipeline, d, plate)?;
    let (names, current) = fills(d, has_plate);
    let mut state = state.with_fills(names, current);
    state.shadows = d.shadows;
    // `fill = "none"` starts with diminishing off (D turns it on with the first fill).
    state.diminish = d.fill != FillName::None;
    Ok(state)
}

/// Everything the preview runs, before the window opens.
pub struct Setup {
    pub renderer: Renderer,
    pub pipeline: ArPipeline,
    pub source: Box<dyn FrameSource>,
    pub state: PreviewState,
    /// Animation frames per second.
    pub fps: f32,
    /// Length of the drawn marker axes, metres.
    pub axes_len_m: f32,
    /// Size of the camera frames.
    pub frame_size: (u32, u32),
}

/// The clip's last frame at `fps`.
fn last_frame(model: &pa_model::Model, animation: usize, fps: f32) -> u32 {
    model
        .animations
        .get(animation)
        .map_or(0, |a| (a.duration_s * fps).round().max(0.0) as u32)
}

/// The built-in scene: generated on the fly, key poses at frames 0 and 24.
pub fn setup_scene(size: Option<&str>, flags: &DiminishArgs) -> Result<Setup> {
    let (w, h) = crate::cmd::parse_size(size.unwrap_or("640x360"))?;
    let overrides = flags.overrides();
    if overrides.clean_plate.is_some() || overrides.plate_frames.is_some() {
        bail!("--clean-plate and --plate-frames are for a shot: the built-in scene has its own clean plate");
    }
    let d = pa_pipeline::shot_diminish::resolve(
        &Default::default(),
        &overrides,
        Path::new("the built-in scene"),
    )?;
    let mut renderer = Renderer::new().context("starting the renderer")?;
    outln!("renderer: {}", renderer.adapter_info());
    let spec = pa_scene::SceneSpec {
        width: w,
        height: h,
        key_frames: vec![0, 24],
        // One sample a pixel: the preview is about speed (eval measures with 2x2).
        supersample: 1,
        ..pa_scene::SceneSpec::default()
    };
    let fps = spec.fps;
    let scene = pa_scene::Scene::new(spec, &mut renderer).map_err(anyhow::Error::msg)?;
    let mut pipeline = pa_scene::eval::pipeline_for(&scene, &mut renderer, ArSettings::ours())
        .map_err(anyhow::Error::msg)?;
    let last = last_frame(&scene.model, 0, fps);
    let keys = scene
        .spec
        .key_frames
        .iter()
        .zip(["A", "B", "C", "D"].iter().cycle())
        .map(|(&frame, name)| KeyPose {
            name: (*name).into(),
            frame,
        })
        .collect();
    let axes_len_m = scene
        .board
        .tags
        .iter()
        .map(|t| t.size_m as f32)
        .fold(0.0, f32::max)
        * 1.5;
    // The scene's pipeline has the set's clean plate.
    let state = apply(
        &mut pipeline,
        PreviewState::new(last, keys, 0),
        &d,
        None,
        true,
    )?;
    Ok(Setup {
        renderer,
        pipeline,
        source: Box::new(SceneSource::new(scene)),
        state,
        fps,
        axes_len_m,
        frame_size: (w, h),
    })
}

/// A shot and its input: a folder of stills, a video file (frame i = animation frame i, as
/// `propsalive run` pairs them) or a live camera.
pub fn setup_shot(
    shot_path: &Path,
    input: &Path,
    camera_size: Option<&str>,
    flags: &DiminishArgs,
    hide_flags: &run::hide::HideArgs,
    tracking: run::Tracking,
) -> Result<Setup> {
    let shot = Shot::load(shot_path)?;
    let d = flags.resolve(&shot, shot_path)?;
    let hide = hide_flags.resolve(&shot, shot_path, &d)?;
    let mut first_still = None;
    let spec = run::parse_input(input)?;
    if camera_size.is_some() && !matches!(spec, InputSpec::Camera(_)) {
        bail!("--camera-size is for a camera input (--input camera:/dev/videoN)");
    }
    // The source first: it knows the frame size the camera model needs.
    let (source, width, height, first, live): (Box<dyn FrameSource>, u32, u32, String, bool) =
        match spec {
            InputSpec::Folder(dir) => {
                let (stills, _) = crate::cmd::track::list_frames(&dir)?;
                first_still = stills.first().cloned();
                let (first, (width, height)) = stills
                    .iter()
                    .find_map(|p| {
                        pa_video::still::still_dimensions(p, &Default::default())
                            .ok()
                            .map(|d| (p.clone(), d))
                    })
                    .with_context(|| {
                        format!(
                            "{}: no readable still (tried {} file(s))",
                            dir.display(),
                            stills.len()
                        )
                    })?;
                let source = StillsSource::new(stills, width, height, shot.fps)?;
                (
                    Box::new(source),
                    width,
                    height,
                    first.display().to_string(),
                    false,
                )
            }
            InputSpec::Video(path) => {
                let source = VideoSource::open(&path, shot.fps)?;
                let (w, h) = source.size();
                (Box::new(source), w, h, path.display().to_string(), false)
            }
            InputSpec::Camera(device) => {
                let size = run::camera_request(camera_size, &shot, shot_path)?;
                let camera = run::open_camera(&device, size, shot.fps)?;
                let source = CameraSource::new(camera);
                let (w, h) = source.size();
                (Box::new(source), w, h, device.display().to_string(), true)
            }
        };
    let camera = shot_config::camera_for_shot(&shot, shot_path, width, height, &first)?;
    if let Some(note) = &camera.scaled {
        errln!("{note}");
    }
    let camera = camera.value;
    let board = shot_config::board_from_shot(&shot, shot_path)?;
    run::marker::check_hide(&board, hide.hide)?;
    let (target, _) = run::marker::track_target(&shot, shot_path, &board)?;
    // The axes: 1.5 tag sides, or a fifth of a picture marker's width.
    let axes_len_m = match board
        .tags
        .iter()
        .map(|t| t.size_m as f32)
        .fold(0.0, f32::max)
    {
        s if s > 0.0 => 1.5 * s,
        _ => shot.marker.width_m.map_or(0.05, |w| 0.2 * w as f32),
    };
    let model_path = Shot::resolve(shot_path, &shot.model);
    let model = pa_model::Model::load(&model_path)
        .with_context(|| format!("loading the model {}", model_path.display()))?;
    let animation = shot.check_model(shot_path, &model)?;
    let mut renderer = Renderer::new().context("starting the renderer")?;
    outln!("renderer: {}", renderer.adapter_info());
    // Stills (and the frames of a video file, still i = animation frame i) are not a video to
    // the tracker: the camera may move between them, so every one is tracked on its own, as
    // `propsalive run` does. A live camera is a video: temporal tracking (filter, search
    // region) steadies the view.
    let tracker_cfg = if live {
        TrackerConfig::default()
    } else {
        TrackerConfig::per_still()
    };
    let board_for_plate = board.clone();
    let tracker = Tracker::new(camera, target.clone(), tracking.detector(), tracker_cfg)?;
    let last = last_frame(&model, animation, shot.fps);
    let plate = match diminish::plate_file(&d, first_still.as_deref())? {
        Some(p) => Some(diminish::load_plate(&p, camera, &target, width, height)?),
        None => None,
    };
    let has_plate = plate.is_some();
    let plate_pose = plate.as_ref().map(|p| p.1);
    let mut pipeline = ArPipeline::new(
        &mut renderer,
        model,
        animation,
        camera,
        shot.placement.marker_from_prop(),
        Some(tracker),
        ArSettings::ours(),
    )?;
    run::hide::apply(
        &mut pipeline,
        &hide,
        &board_for_plate,
        plate_pose,
        (width, height),
    )?;
    run::diminish::apply_board(&mut pipeline, &board_for_plate);
    let keys = shot
        .key_poses
        .iter()
        .map(|k| KeyPose {
            name: k.name.clone(),
            frame: k.frame,
        })
        .collect();
    let state = apply(
        &mut pipeline,
        PreviewState::new(last, keys, shot.present_key_index()),
        &d,
        plate,
        has_plate,
    )?;
    // After `apply`, which sets the diminish settings over ours.
    pipeline.settings.look = shot.texture.look();
    Ok(Setup {
        renderer,
        pipeline,
        source,
        state,
        fps: shot.fps,
        axes_len_m,
        frame_size: (width, height),
    })
}
