//! Measuring the AR output against ground truth on generated scenes.
//!
//! For every camera frame the generator renders the physical key prop (input) and the
//! in-between as if printed (ground truth). The frame pipeline runs on the input through the
//! real tracker; its output is compared with the ground truth:
//!
//! - **prop region**: pixels where the ground-truth in-between prop is (PSNR, SSIM);
//! - **revealed region**: pixels where the key prop stood in the input but the in-between
//!   does not (the background the diminishing must invent);
//! - **pose error**: the tracked `camera_from_marker` against the true one;
//! - **distance from the key pose**: the head's rotation (degrees) and displacement (prop
//!   heights) between the in-between and the key pose present, for the degradation curve.

use glam::{Mat4, Quat};
use pa_camera::CameraModel;
use pa_model::{anim, skin};
use pa_pipeline::ar::{ArFrame, ArPipeline, ArSettings, FrameTimes, StageTimings};
use pa_pipeline::metrics::{psnr_region, ssim_region};
use pa_render::Renderer;
use pa_track::{DetectorConfig, Tracker, TrackerConfig};

use crate::flicker::{flicker_region, Flicker, EDGE_MARGIN_PX};
use crate::prop::{JOINT_HEAD, JOINT_JAW};
use crate::scene::{Scene, SceneFrame, SceneSpec};
use crate::SceneError;

/// Metrics of one frame.
#[derive(Debug, Clone, Default)]
pub struct FrameMetrics {
    pub frame: u32,
    pub key: usize,
    /// Head rotation between the in-between and the key pose, degrees.
    pub key_distance_deg: f64,
    /// Mean displacement of the head's surface between the in-between and the key pose, in
    /// prop heights.
    pub key_distance_props: f64,
    pub psnr_prop: Option<f64>,
    pub ssim_prop: Option<f64>,
    pub psnr_revealed: Option<f64>,
    pub ssim_revealed: Option<f64>,
    /// PSNR over the revealed pixels at least [`EDGE_MARGIN_PX`] + 1 pixels (Chebyshev) from
    /// the in-between's silhouette (the flicker metric's region): the fill alone. Nearer
    /// pixels mix the twin's edge into the background in the truth, and on thin revealed
    /// slivers they carry almost all of the revealed error whatever the fill (stop 34: 98 %
    /// on the generated `shadows` set with the clean plate). None where no such pixel.
    pub psnr_revealed_off_edge: Option<f64>,
    /// Tracking: rotation error (degrees) and translation error (mm); None when lost.
    pub rot_err_deg: Option<f64>,
    pub trans_err_mm: Option<f64>,
    pub tracked: bool,
    pub timings: StageTimings,
    /// Frame-to-frame change of the revealed region after camera compensation, 8-bit levels:
    /// (ours, ground truth) ([`crate::flicker`]); None on a sequence's first frame.
    pub flicker: Option<(f64, f64)>,
    /// External sets: IoU of the pipeline's key-pose mask (tracked camera) with the set's key
    /// mask, and of the twin's mask with the set's in-between mask (a convention check).
    pub key_mask_iou: Option<f64>,
    pub twin_mask_iou: Option<f64>,
}

/// The head joint's world transform at `time_s`.
fn head_world(scene: &Scene, time_s: f32) -> Mat4 {
    let pose = anim::sample(&scene.model, 0, time_s);
    let world = pose.world_from_node(&scene.model);
    let head_node = scene.model.skins[0].joints[JOINT_HEAD];
    world[head_node]
}

/// (rotation degrees, displacement in prop heights) of the head between two times: the head
/// joint's rotation, and the mean distance the head's surface moves (its vertices weighted
/// mostly to the head or jaw joint; the joint's own origin sits on the neck's turn axis and
/// barely moves).
pub fn key_distance(scene: &Scene, time_s: f32, key_time_s: f32) -> (f64, f64) {
    let a = head_world(scene, time_s);
    let b = head_world(scene, key_time_s);
    let (_, ra, _) = a.to_scale_rotation_translation();
    let (_, rb, _) = b.to_scale_rotation_translation();
    let rel: Quat = ra * rb.inverse();
    let angle = 2.0 * rel.w.abs().clamp(-1.0, 1.0).acos() as f64;
    let model = &scene.model;
    let pa = skin::pose_meshes(model, &anim::sample(model, 0, time_s));
    let pb = skin::pose_meshes(model, &anim::sample(model, 0, key_time_s));
    let (mut sum, mut n) = (0.0f64, 0usize);
    for (p, q) in pa.iter().zip(&pb) {
        let prim = &model.meshes[p.mesh].primitives[p.primitive];
        for (v, (j, w)) in prim.joints.iter().zip(&prim.weights).enumerate() {
            let k = (0..8).max_by(|&x, &y| w[x].total_cmp(&w[y])).unwrap_or(0);
            if [JOINT_HEAD, JOINT_JAW].contains(&(j[k] as usize)) {
                sum += f64::from((p.positions[v] - q.positions[v]).length());
                n += 1;
            }
        }
    }
    let displacement = if n > 0 {
        sum / n as f64 / f64::from(scene.spec.prop.height_m)
    } else {
        f64::NAN
    };
    (angle.to_degrees(), displacement)
}

/// Rotation (degrees) and translation (mm) error between two `camera_from_marker` poses.
///
/// In f64, the angle from the relative rotation's vector part (`atan2(|xyz|, |w|)`): the f32
/// `acos(w)` this replaced could not tell 0.02 degrees from 0 (its steps near zero are about
/// 0.04 degrees), so a median error below that read 0.000.
pub fn pose_error(estimated: Mat4, truth: Mat4) -> (f64, f64) {
    let (_, re, te) = estimated.as_dmat4().to_scale_rotation_translation();
    pose_error_of(re, te, truth)
}

/// [`pose_error`] of an estimate given as a rotation and a translation in f64 (the
/// tracker's own pose, [`crate::tracking::pose_error_f64`]).
pub(crate) fn pose_error_of(
    rotation: glam::DQuat,
    translation: glam::DVec3,
    truth: Mat4,
) -> (f64, f64) {
    let (_, rt, tt) = truth.as_dmat4().to_scale_rotation_translation();
    let rel = rotation * rt.inverse();
    let angle = 2.0 * rel.xyz().length().atan2(rel.w.abs());
    (angle.to_degrees(), (translation - tt).length() * 1000.0)
}

/// Compares one pipeline output with the frame's ground truth.
pub fn measure(
    scene: &Scene,
    renderer: &mut Renderer,
    frame: &SceneFrame,
    out: &ArFrame,
) -> Result<FrameMetrics, SceneError> {
    Ok(measure_revealed(scene, renderer, frame, out)?.0)
}

/// [`measure`], also returning the revealed regions it measured ([`Revealed`]).
pub fn measure_revealed(
    scene: &Scene,
    renderer: &mut Renderer,
    frame: &SceneFrame,
    out: &ArFrame,
) -> Result<(FrameMetrics, Revealed), SceneError> {
    let (w, h) = (scene.spec.width as usize, scene.spec.height as usize);
    let key_time = scene.spec.key_frames[frame.key] as f32 / scene.spec.fps;
    let truth_mask = scene.prop_mask(renderer, frame.camera_from_marker, frame.time_s)?;
    let key_mask = scene.prop_mask(renderer, frame.camera_from_marker, key_time)?;
    let revealed: Vec<bool> = key_mask
        .iter()
        .zip(&truth_mask)
        .map(|(&k, &t)| k && !t)
        .collect();
    let gt = &frame.ground_truth.rgba8;
    let (dist_deg, dist_props) = key_distance(scene, frame.time_s, key_time);
    let (rot_err_deg, trans_err_mm) = match out.camera_from_marker {
        Some(p) => {
            let (r, t) = pose_error(p, frame.camera_from_marker);
            (Some(r), Some(t))
        }
        None => (None, None),
    };
    let off_edge = flicker_region(&key_mask, &truth_mask, w, EDGE_MARGIN_PX);
    let m = FrameMetrics {
        frame: frame.index,
        key: frame.key,
        key_distance_deg: dist_deg,
        key_distance_props: dist_props,
        psnr_prop: psnr_region(&out.rgba8, gt, &truth_mask),
        ssim_prop: ssim_region(&out.rgba8, gt, w, h, &truth_mask),
        psnr_revealed: psnr_region(&out.rgba8, gt, &revealed),
        ssim_revealed: ssim_region(&out.rgba8, gt, w, h, &revealed),
        psnr_revealed_off_edge: psnr_region(&out.rgba8, gt, &off_edge),
        rot_err_deg,
        trans_err_mm,
        tracked: out.camera_from_marker.is_some(),
        timings: out.timings,
        flicker: None,
        key_mask_iou: None,
        twin_mask_iou: None,
    };
    Ok((
        m,
        Revealed {
            all: revealed,
            off_edge,
        },
    ))
}

/// A frame's revealed background as [`measure_revealed`] finds it, both silhouettes at the
/// true pose: `all` = in the key pose's silhouette and not in the in-between's; `off_edge` = the part of it at least
/// [`EDGE_MARGIN_PX`] + 1 pixels (Chebyshev) from the in-between's silhouette (the region of
/// [`FrameMetrics::psnr_revealed_off_edge`] and of the flicker metric). One value per pixel.
pub struct Revealed {
    pub all: Vec<bool>,
    pub off_edge: Vec<bool>,
}

/// The twin's model against the prop as printed on the set.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum TwinTexture {
    /// The model the prop was printed from, texture and all (the generated scene's truth).
    #[default]
    AsPrinted,
    /// The same model with each texture replaced by its mean colour: a print painted by hand
    /// (or a model whose texture was never made), so the model knows the prop's shape and
    /// overall colour but not its paint.
    FlatColour,
}

/// `model` with each image replaced by its mean colour (the mean in linear light, encoded
/// again; alpha the rounded mean), at the image's size.
pub fn flat_textures(model: &pa_model::Model) -> pa_model::Model {
    let lut = crate::variant::srgb_lut();
    let mut m = model.clone();
    for image in &mut m.images {
        let n = image.rgba8.len() / 4;
        if n == 0 {
            continue;
        }
        let mut sum = [0f64; 4];
        for p in image.rgba8.chunks_exact(4) {
            for c in 0..3 {
                sum[c] += f64::from(lut[p[c] as usize]);
            }
            sum[3] += f64::from(p[3]);
        }
        let mean: [u8; 4] = std::array::from_fn(|c| {
            let v = sum[c] / n as f64;
            if c == 3 {
                v.round().clamp(0.0, 255.0) as u8
            } else {
                crate::variant::srgb_encode(v as f32)
            }
        });
        for p in image.rgba8.chunks_exact_mut(4) {
            p.copy_from_slice(&mean);
        }
    }
    m
}

/// Builds the frame pipeline for a scene: the real tracker on the scene's board, one prop of
/// the pipeline per copy of the prop on the set ([`crate::SceneSpec::props`]).
pub fn pipeline_for(
    scene: &Scene,
    renderer: &mut Renderer,
    settings: ArSettings,
) -> Result<ArPipeline, SceneError> {
    pipeline_for_twin(scene, renderer, settings, TwinTexture::AsPrinted)
}

/// [`pipeline_for`] with the twin's model as `twin` says.
pub fn pipeline_for_twin(
    scene: &Scene,
    renderer: &mut Renderer,
    settings: ArSettings,
    twin: TwinTexture,
) -> Result<ArPipeline, SceneError> {
    let model = match twin {
        TwinTexture::AsPrinted => scene.model.clone(),
        TwinTexture::FlatColour => flat_textures(&scene.model),
    };
    let camera = CameraModel::pinhole(scene.intrinsics);
    let tracker = Tracker::new(
        camera,
        scene.track_target()?,
        DetectorConfig::default(),
        TrackerConfig::default(),
    )?;
    let mut p = ArPipeline::new(
        renderer,
        model.clone(),
        0,
        camera,
        scene.marker_from_prop(),
        Some(tracker),
        settings,
    )?;
    // Every further copy of the prop on the set is a prop of the pipeline, at its spot.
    for m in scene.marker_from_props().into_iter().skip(1) {
        p.add_prop(renderer, model.clone(), 0, m)?;
    }
    p.set_board_surfaces(Some(pa_pipeline::ar::BoardSurfaces::new(
        &scene.board,
        Some(f64::from(scene.spec.set.sheet_side_m())),
    )));
    let (plate, plate_pose) = scene.clean_plate(renderer)?;
    let plate = pa_diminish::ImageRgba8::new(plate.width, plate.height, plate.rgba8)?;
    p.set_clean_plate(plate, plate_pose);
    Ok(p)
}

/// `pipeline` on a scene frame's input at its true pose, the key pose at time 0 (the tracker
/// left out: what the tests of one stage compare).
pub fn process_at_true_pose(
    pipeline: &mut ArPipeline,
    renderer: &mut Renderer,
    f: &SceneFrame,
) -> Result<ArFrame, pa_pipeline::ar::ArError> {
    pipeline.process_with_pose(
        renderer,
        &f.input.rgba8,
        f.input.width,
        f.input.height,
        FrameTimes {
            animation_s: f.time_s,
            key_pose_s: 0.0,
        },
        f.camera_from_marker,
    )
}

/// Runs `settings` over the frames `frames` of a scene built from `spec`; `each` sees every
/// (frame, output, metrics). The caller's error type `E` takes the scene's errors too, and an
/// error from `each` ends the run.
pub fn run_scene<E: From<SceneError>>(
    renderer: &mut Renderer,
    spec: SceneSpec,
    settings: ArSettings,
    frames: impl IntoIterator<Item = u32>,
    mut each: impl FnMut(&SceneFrame, &ArFrame, &FrameMetrics) -> Result<(), E>,
) -> Result<Vec<FrameMetrics>, E> {
    run_scene_with(renderer, spec, settings, frames, false, |f, out, m, _| {
        each(f, out, m)
    })
}

/// [`run_scene`] with the pipeline's layers kept (`keep_passes`: [`ArFrame::passes`], and the
/// fill then covers the whole dilated key silhouette), and `each` also given the revealed
/// region measured ([`measure_revealed`]).
pub fn run_scene_with<E: From<SceneError>>(
    renderer: &mut Renderer,
    spec: SceneSpec,
    settings: ArSettings,
    frames: impl IntoIterator<Item = u32>,
    keep_passes: bool,
    each: impl FnMut(&SceneFrame, &ArFrame, &FrameMetrics, &Revealed) -> Result<(), E>,
) -> Result<Vec<FrameMetrics>, E> {
    run_scene_setup(
        renderer,
        spec,
        settings,
        frames,
        keep_passes,
        |_, _, _| Ok(()),
        each,
    )
}

/// [`run_scene_with`] with the pipeline's shadows on or off ([`ArPipeline::set_shadows`]).
pub fn run_scene_shadows<E: From<SceneError>>(
    renderer: &mut Renderer,
    spec: SceneSpec,
    settings: ArSettings,
    frames: impl IntoIterator<Item = u32>,
    keep_passes: bool,
    shadows: bool,
    each: impl FnMut(&SceneFrame, &ArFrame, &FrameMetrics, &Revealed) -> Result<(), E>,
) -> Result<Vec<FrameMetrics>, E> {
    run_scene_setup(
        renderer,
        spec,
        settings,
        frames,
        keep_passes,
        |_, _, p| {
            p.set_shadows(shadows);
            Ok(())
        },
        each,
    )
}

/// [`run_scene_with`] with `setup` run on the pipeline once it is built (the demo's hiding of
/// the board).
pub fn run_scene_setup<E: From<SceneError>>(
    renderer: &mut Renderer,
    spec: SceneSpec,
    settings: ArSettings,
    frames: impl IntoIterator<Item = u32>,
    keep_passes: bool,
    setup: impl FnOnce(&Scene, &mut Renderer, &mut ArPipeline) -> Result<(), SceneError>,
    each: impl FnMut(&SceneFrame, &ArFrame, &FrameMetrics, &Revealed) -> Result<(), E>,
) -> Result<Vec<FrameMetrics>, E> {
    run_scene_twin(
        renderer,
        spec,
        settings,
        TwinTexture::AsPrinted,
        frames,
        keep_passes,
        setup,
        each,
    )
}

/// [`run_scene_setup`] with the twin's model as `twin` says ([`pipeline_for_twin`]).
#[allow(clippy::too_many_arguments)]
pub fn run_scene_twin<E: From<SceneError>>(
    renderer: &mut Renderer,
    spec: SceneSpec,
    settings: ArSettings,
    twin: TwinTexture,
    frames: impl IntoIterator<Item = u32>,
    keep_passes: bool,
    setup: impl FnOnce(&Scene, &mut Renderer, &mut ArPipeline) -> Result<(), SceneError>,
    mut each: impl FnMut(&SceneFrame, &ArFrame, &FrameMetrics, &Revealed) -> Result<(), E>,
) -> Result<Vec<FrameMetrics>, E> {
    let scene = Scene::new(spec, renderer)?;
    let mut pipeline = pipeline_for_twin(&scene, renderer, settings, twin)?;
    pipeline.set_keep_passes(keep_passes);
    setup(&scene, renderer, &mut pipeline)?;
    let mut all = Vec::new();
    let mut flicker =
        Flicker::new(scene.intrinsics).with_plane_extent(f64::from(crate::scene::TABLE_M) * 0.5);
    for i in frames {
        let f = scene.frame(renderer, i).map_err(SceneError::from)?;
        let key_time = scene.spec.key_frames[f.key] as f32 / scene.spec.fps;
        let mut out = pipeline
            .process(
                renderer,
                &f.input.rgba8,
                f.input.width,
                f.input.height,
                FrameTimes {
                    animation_s: f.time_s,
                    key_pose_s: key_time,
                },
                i as f64 / scene.spec.fps as f64,
            )
            .map_err(SceneError::from)?;
        let (mut m, revealed) = measure_revealed(&scene, renderer, &f, &out)?;
        m.flicker = flicker.step(
            &out.rgba8,
            &f.ground_truth.rgba8,
            &revealed.off_edge,
            f.camera_from_marker,
        );
        each(&f, &out, &m, &revealed)?;
        all.push(m);
        // Written and measured: its buffers are the next frame's.
        pipeline.recycle_frame(&mut out);
    }
    Ok(all)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The flat-painted twin keeps each image's size and its mean colour in linear light: a
    /// black and white pair is mid grey (linear 0.5, sRGB 188), not sRGB 128.
    #[test]
    fn flat_textures_are_the_mean_colour_in_linear_light() {
        let image = |rgba8: Vec<u8>, width| pa_model::Image {
            name: None,
            width,
            height: 1,
            rgba8,
        };
        let model = pa_model::Model {
            path: "test.glb".into(),
            nodes: vec![],
            roots: vec![],
            meshes: vec![],
            skins: vec![],
            materials: vec![],
            images: vec![
                image(vec![0, 0, 0, 255, 255, 255, 255, 255], 2),
                image(vec![200, 10, 90, 100], 1),
                image(vec![], 0),
            ],
            animations: vec![],
            warnings: vec![],
        };
        let flat = flat_textures(&model);
        assert_eq!(
            flat.images[0].rgba8,
            [188, 188, 188, 255, 188, 188, 188, 255]
        );
        assert_eq!(flat.images[1].rgba8, model.images[1].rgba8);
        assert!(flat.images[2].rgba8.is_empty());
    }

    /// Regression: the demo's median rotation error read "0.000 deg" once the tracker got
    /// below the f32 `acos` step (about 0.04 degrees); small angles must be resolved.
    #[test]
    fn pose_error_resolves_hundredths_of_a_degree() {
        let truth = Mat4::from_rotation_translation(
            Quat::from_rotation_x(0.6),
            glam::Vec3::new(0.01, 0.02, 0.5),
        );
        for deg in [0.0f32, 0.005, 0.02, 0.1, 2.0] {
            let est = Mat4::from_rotation_translation(
                Quat::from_rotation_y(deg.to_radians()) * Quat::from_rotation_x(0.6),
                glam::Vec3::new(0.01, 0.02, 0.503),
            );
            let (r, t) = pose_error(est, truth);
            assert!((r - f64::from(deg)).abs() < 1e-3, "{deg} deg read as {r}");
            assert!((t - 3.0).abs() < 1e-3, "{t} mm");
        }
    }
}
