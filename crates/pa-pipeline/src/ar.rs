//! The Props Alive frame pipeline: frame -> track -> place -> animate -> texture -> diminish
//! -> composite.
//!
//! [`ArPipeline::process`] takes one camera frame (sRGB RGBA8) and the animation time to show,
//! and returns the composited frame with the tracking state, the pose, stage timings and the
//! masks the evaluation needs. When tracking has no pose the output is the untouched input
//! (and the log says so).
//!
//! Texturing ([`Texturing`]): `Live` is the paper's method (each fragment samples the current
//! frame at the projection of the same surface point in the key pose; sections 3.2, 4.2),
//! with or without our visibility test and fallback; `ModelTexture` draws the model's own
//! scanned texture (no live sampling), for comparison. Diminishing ([`Fill`]): the paper's
//! rectangle, our ray fill over the dilated key-pose silhouette, or a clean plate.

use std::time::Instant;

use glam::{DMat3, DVec3, Mat4};
use pa_camera::CameraModel;
use pa_diminish::{
    dilate, mask_from_depth, CleanPlate, DilateShape, Diminisher, FillMethod, Homography,
    ImageRgba8, Mask, RayDirections,
};
use pa_model::{anim, Model};
use pa_render::{
    CpuCamera, CpuTexture, GpuTexture, GpuVisibility, LiveCamera, LiveDraw, LiveTexturing,
    RenderError, Renderer,
};
use pa_track::{GrayImage, TrackState, Tracker};

use crate::composite::composite_twin_over;
use crate::shading::{irradiance_samples, Irradiance, KeyView};
use crate::twin::GpuTwin;

/// Errors of the frame pipeline.
#[derive(Debug, thiserror::Error)]
pub enum ArError {
    #[error("frame {index}: {width}x{height} RGBA8 needs {expected} bytes, got {got}")]
    BadFrame {
        index: u64,
        width: u32,
        height: u32,
        expected: usize,
        got: usize,
    },
    #[error("rendering: {0}")]
    Render(#[from] RenderError),
    #[error("tracking: {0}")]
    Track(#[from] pa_track::TrackError),
    #[error("diminishing: {0}")]
    Diminish(#[from] pa_diminish::DiminishError),
    #[error("{0}")]
    Config(String),
}

/// How the twin is textured.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Texturing {
    /// Sampled from the live frame at the key-pose projection. With `visibility`, key-pose
    /// points hidden from the camera (occluded, facing away, or seen so obliquely that the
    /// in-between would stretch their few pixels) take the model's texture, shaded by the
    /// set's light as measured on the visible key prop ([`crate::shading`]); without, they
    /// sample whatever the frame shows there (the paper; back-facing and outside points take
    /// the model's texture times one colour gain).
    Live { visibility: bool },
    /// The model's own base-colour texture (no live sampling).
    ModelTexture,
}

/// How the real prop is removed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Fill {
    /// The paper's screen-space rectangle with boundary averages.
    PaperRectangle,
    /// Inverse-distance ray fill over the dilated key-pose silhouette.
    Rays,
    /// The clean plate warped by the table-plane homography (ray fill where it has no data).
    CleanPlate,
    /// No diminishing (the real prop stays visible).
    None,
}

/// Settings of the frame pipeline.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ArSettings {
    pub texturing: Texturing,
    pub fill: Fill,
    /// Dilation of the key-pose silhouette, pixels.
    pub dilate_px: u32,
    /// Anti-aliased twin edges ([`crate::composite`]).
    pub anti_alias: bool,
}

impl ArSettings {
    /// Our method: live texturing with visibility, ray fill, 4 px dilation, anti-aliased edges.
    pub fn ours() -> Self {
        Self {
            texturing: Texturing::Live { visibility: true },
            fill: Fill::Rays,
            dilate_px: 4,
            anti_alias: true,
        }
    }

    /// The paper's method: live texturing without visibility, rectangle fill.
    pub fn paper() -> Self {
        Self {
            texturing: Texturing::Live { visibility: false },
            fill: Fill::PaperRectangle,
            dilate_px: 0,
            anti_alias: false,
        }
    }
}

/// Milliseconds spent in each stage of one frame.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct StageTimings {
    pub track_ms: f64,
    pub animate_ms: f64,
    pub texture_ms: f64,
    pub diminish_ms: f64,
    pub composite_ms: f64,
}

impl StageTimings {
    pub fn total_ms(&self) -> f64 {
        self.track_ms + self.animate_ms + self.texture_ms + self.diminish_ms + self.composite_ms
    }
}

/// The result of one frame.
#[derive(Debug, Clone)]
pub struct ArFrame {
    /// The composited frame (sRGB RGBA8); the untouched input when there is no pose.
    pub rgba8: Vec<u8>,
    pub state: TrackState,
    /// The pose used (filtered), `camera_from_marker`.
    pub camera_from_marker: Option<Mat4>,
    /// Reprojection error of the raw pose, pixels.
    pub reprojection_px: Option<f64>,
    pub timings: StageTimings,
    /// Pixels covered by the animated twin.
    pub twin_mask: Vec<bool>,
    /// Pixels covered by the key pose as the camera sees it (before dilation).
    pub key_mask: Vec<bool>,
    /// (live samples, fallback samples) of the twin.
    pub live_counts: (usize, usize),
    /// Per pixel, the [`pa_render::LiveSample`] code of the twin's surface (255 live sample,
    /// 1/2/3 fallback, 0 none); all 0 without live texturing.
    pub live_codes: Vec<u8>,
}

/// Everything the pipeline keeps between frames.
pub struct ArPipeline {
    pub model: Model,
    pub animation: usize,
    pub camera: CameraModel,
    pub marker_from_prop: Mat4,
    pub settings: ArSettings,
    twin: GpuTwin,
    tracker: Option<Tracker>,
    frame_texture: Option<GpuTexture>,
    visibility: Option<GpuVisibility>,
    diminisher: Diminisher,
    /// Clean plate image and its `camera_from_marker`.
    plate: Option<(ImageRgba8, Mat4)>,
    frame_index: u64,
}

/// Key-pose vertices sampled for the fallback's irradiance fit (at most about this many).
const IRRADIANCE_SAMPLES: usize = 3000;

/// With a visibility map: the smallest facing cosine of a key-pose normal for a live sample
/// (slightly back-facing interpolated normals at a silhouette are still seen).
const VISIBLE_MIN_FACING_COS: f32 = -0.3;
/// With a visibility map: a surface that now faces the camera more than twice as squarely as
/// in the key pose takes the lit fallback (measured on the generated scene with 2, 2.5, 4 and
/// off: 2 was best on frames 20-40 degrees from the key, and equal near it).
const MAX_STRETCH: f32 = 2.0;

/// Clip planes of the AR camera.
const NEAR_M: f32 = 0.01;
const FAR_M: f32 = 50.0;

impl ArPipeline {
    /// Uploads the model and prepares the stages. `tracker` None means the caller gives the
    /// pose ([`ArPipeline::process_with_pose`]).
    pub fn new(
        renderer: &mut Renderer,
        model: Model,
        animation: usize,
        camera: CameraModel,
        marker_from_prop: Mat4,
        tracker: Option<Tracker>,
        settings: ArSettings,
    ) -> Result<Self, ArError> {
        if animation >= model.animations.len() && !model.animations.is_empty() {
            return Err(ArError::Config(format!("no animation {animation}")));
        }
        let twin = GpuTwin::upload(renderer, &model)?;
        Ok(Self {
            model,
            animation,
            camera,
            marker_from_prop,
            settings,
            twin,
            tracker,
            frame_texture: None,
            visibility: None,
            diminisher: Diminisher::new(),
            plate: None,
            frame_index: 0,
        })
    }

    /// Sets the clean plate (the set without the prop) and the camera pose it was taken from.
    pub fn set_clean_plate(&mut self, plate: ImageRgba8, camera_from_marker: Mat4) {
        self.plate = Some((plate, camera_from_marker));
    }

    /// Tracks the marker in `rgba8` and processes the frame.
    pub fn process(
        &mut self,
        renderer: &mut Renderer,
        rgba8: &[u8],
        width: u32,
        height: u32,
        anim_time_s: f32,
        key_time_s: f32,
        frame_time_s: f64,
    ) -> Result<ArFrame, ArError> {
        self.check_frame(rgba8, width, height)?;
        let t0 = Instant::now();
        let (state, pose, rms) = match &mut self.tracker {
            Some(tracker) => {
                let gray = gray_from_rgba(rgba8, width, height)?;
                let out = tracker.update(&gray, frame_time_s)?;
                (
                    out.state,
                    out.pose.map(|p| p.to_mat4()),
                    out.raw.map(|r| r.rms_px),
                )
            }
            None => return Err(ArError::Config("no tracker: use process_with_pose".into())),
        };
        let track_ms = ms(t0);
        let mut frame = self.render_frame(
            renderer,
            rgba8,
            width,
            height,
            anim_time_s,
            key_time_s,
            pose,
        )?;
        frame.state = state;
        frame.reprojection_px = rms;
        frame.timings.track_ms = track_ms;
        Ok(frame)
    }

    /// Processes a frame with a known `camera_from_marker` (no tracking).
    pub fn process_with_pose(
        &mut self,
        renderer: &mut Renderer,
        rgba8: &[u8],
        width: u32,
        height: u32,
        anim_time_s: f32,
        key_time_s: f32,
        camera_from_marker: Mat4,
    ) -> Result<ArFrame, ArError> {
        self.check_frame(rgba8, width, height)?;
        let mut f = self.render_frame(
            renderer,
            rgba8,
            width,
            height,
            anim_time_s,
            key_time_s,
            Some(camera_from_marker),
        )?;
        f.state = TrackState::Tracked;
        Ok(f)
    }

    fn check_frame(&mut self, rgba8: &[u8], width: u32, height: u32) -> Result<(), ArError> {
        self.frame_index += 1;
        let expected = width as usize * height as usize * 4;
        if rgba8.len() != expected || width == 0 || height == 0 {
            return Err(ArError::BadFrame {
                index: self.frame_index - 1,
                width,
                height,
                expected,
                got: rgba8.len(),
            });
        }
        Ok(())
    }

    #[allow(clippy::too_many_arguments)]
    fn render_frame(
        &mut self,
        renderer: &mut Renderer,
        rgba8: &[u8],
        width: u32,
        height: u32,
        anim_time_s: f32,
        key_time_s: f32,
        pose: Option<Mat4>,
    ) -> Result<ArFrame, ArError> {
        let n = (width * height) as usize;
        let Some(camera_from_marker) = pose else {
            return Ok(ArFrame {
                rgba8: rgba8.to_vec(),
                state: TrackState::Searching,
                camera_from_marker: None,
                reprojection_px: None,
                timings: StageTimings::default(),
                twin_mask: vec![false; n],
                key_mask: vec![false; n],
                live_counts: (0, 0),
                live_codes: vec![0; n],
            });
        };
        let mut timings = StageTimings::default();
        // Place + animate.
        let t = Instant::now();
        let intrinsics =
            if (self.camera.intrinsics.width, self.camera.intrinsics.height) == (width, height) {
                self.camera.intrinsics
            } else {
                self.camera.intrinsics.scaled_to(width, height)
            };
        let camera_model = CameraModel {
            intrinsics,
            distortion: self.camera.distortion,
        };
        let camera = CpuCamera {
            intrinsics,
            camera_from_world: camera_from_marker,
            near_m: NEAR_M,
            far_m: FAR_M,
        };
        let anim_pose = anim::sample(&self.model, self.animation, anim_time_s);
        let key_pose = anim::sample(&self.model, self.animation, key_time_s);
        let anim_frame = self
            .twin
            .frame(&self.model, &anim_pose, self.marker_from_prop);
        let key_frame = self
            .twin
            .frame(&self.model, &key_pose, self.marker_from_prop);
        timings.animate_ms = ms(t);

        // Texture: the key pose as the camera sees it gives the diminish mask and the light on
        // the prop (with visibility: the visibility map, read back; without: a plain unlit
        // render, whose colours also give the baseline's colour gain); then the animated twin.
        let t = Instant::now();
        let key_draws = self.twin.draws(&key_frame);
        let (key_depth_m, gain) = match self.settings.texturing {
            Texturing::Live { visibility: true } => {
                let map = match self.visibility.as_mut() {
                    Some(v) if v.size() == (width, height) => {
                        renderer.update_visibility(v, &camera, &key_draws)?;
                        v
                    }
                    _ => self
                        .visibility
                        .insert(renderer.render_visibility(&camera, &key_draws, width, height)?),
                };
                (renderer.read_visibility(map)?, None)
            }
            _ => {
                let r = renderer.render(&camera, None, &key_draws, [0.0; 4], width, height)?;
                let mask: Vec<bool> = r.depth_m.iter().map(|d| d.is_finite()).collect();
                let gain = colour_gain(rgba8, &r.rgba8, &mask);
                (r.depth_m, Some(gain))
            }
        };
        let key_mask_bool: Vec<bool> = key_depth_m.iter().map(|d| d.is_finite()).collect();
        let cpu_frame = CpuTexture {
            width,
            height,
            rgba8: rgba8.to_vec(),
        };
        let (twin_rgba, twin_depth, live_counts, live_codes) = match self.settings.texturing {
            Texturing::ModelTexture => {
                let draws = self.twin.draws(&anim_frame);
                let r = renderer.render(&camera, None, &draws, [0.0; 4], width, height)?;
                (r.rgba8, r.depth_m, (0, 0), vec![0; n])
            }
            Texturing::Live { visibility } => {
                let frame_tex = match self.frame_texture.take() {
                    Some(t) if t.size() == (width, height) => {
                        renderer.update_texture(&t, &cpu_frame)?;
                        t
                    }
                    _ => renderer.upload_frame(&cpu_frame)?,
                };
                // The fallback's shading: the set's light measured on the visible key prop
                // (ours), or one colour gain (the baseline without visibility).
                let irradiance = if visibility {
                    let posed = pa_model::skin::pose_meshes(&self.model, &key_pose);
                    let view = KeyView {
                        camera: &camera_model,
                        camera_from_world: camera_from_marker,
                        frame_rgba8: rgba8,
                        key_depth_m: &key_depth_m,
                        width,
                        height,
                    };
                    let samples = irradiance_samples(
                        &self.model,
                        &posed,
                        self.marker_from_prop,
                        &view,
                        IRRADIANCE_SAMPLES,
                    );
                    Irradiance::fit(&samples).unwrap_or_else(|| Irradiance::mean(&samples))
                } else {
                    Irradiance::constant(gain.unwrap_or([1.0; 3]))
                };
                let live_camera = LiveCamera::new(camera_model, camera_from_marker);
                let vis = if visibility {
                    self.visibility.as_ref()
                } else {
                    None
                };
                let draws: Vec<LiveDraw<'_>> = self
                    .twin
                    .draws(&anim_frame)
                    .into_iter()
                    .zip(&self.twin.primitives)
                    .map(|(d, p)| {
                        let key_joints: &[Mat4] = if p.mesh.is_skinned() {
                            &key_frame.joint_matrices[p.node]
                        } else {
                            &[]
                        };
                        let mut live = LiveTexturing::new(
                            &frame_tex,
                            live_camera,
                            key_frame.world_from_node[p.node],
                        )
                        .with_key_pose(key_joints, &key_frame.morph_weights[p.node])
                        .with_fallback_irradiance(irradiance.rows);
                        if let Some(v) = vis {
                            live = live.with_visibility(v);
                            // The depth test decides occlusion, so grazing key-pose normals
                            // may sample; surfaces turned to face the camera take the lit
                            // fallback instead of a smeared sample.
                            live.min_facing_cos = VISIBLE_MIN_FACING_COS;
                            live.max_stretch = MAX_STRETCH;
                        }
                        d.with_live(live)
                    })
                    .collect();
                let r = renderer.render_live(&camera, None, &draws, [0.0; 4], width, height)?;
                let counts = r.counts();
                drop(draws);
                self.frame_texture = Some(frame_tex);
                (r.frame.rgba8, r.frame.depth_m, counts, r.live_valid)
            }
        };
        timings.texture_ms = ms(t);

        // Diminish: fill the dilated key silhouette in a copy of the frame.
        let t = Instant::now();
        let mut background = ImageRgba8::new(width, height, rgba8.to_vec())?;
        let mut key_mask = Mask::zeros(width, height)?;
        let bbox = mask_from_depth(&key_depth_m, width, height, &mut key_mask)?;
        let fill_mask = if self.settings.dilate_px > 0 && bbox.is_some() {
            let mut dilated = Mask::zeros(width, height)?;
            dilate(
                &key_mask,
                self.settings.dilate_px,
                DilateShape::Disc,
                &mut dilated,
            )?;
            dilated
        } else {
            key_mask
        };
        let plate_h = match (&self.plate, self.settings.fill) {
            (Some((_, plate_pose)), Fill::CleanPlate) => Some(Homography::from_dmat3(
                plane_homography(&camera_model, camera_from_marker, *plate_pose),
            )),
            _ => None,
        };
        let method = match self.settings.fill {
            Fill::PaperRectangle => Some(FillMethod::PaperRectangle { rect: None }),
            Fill::Rays => Some(FillMethod::Rays(RayDirections::default())),
            Fill::CleanPlate => match (&self.plate, plate_h) {
                (Some((plate, _)), Some(h)) => {
                    Some(FillMethod::CleanPlate(CleanPlate::new(plate, h)))
                }
                _ => Some(FillMethod::Rays(RayDirections::default())),
            },
            Fill::None => None,
        };
        if let Some(m) = method {
            self.diminisher.fill(&mut background, &fill_mask, &m)?;
        }
        timings.diminish_ms = ms(t);

        // Composite: twin over the diminished background.
        let t = Instant::now();
        let mut out = background.into_vec();
        let twin_mask: Vec<bool> = twin_depth.iter().map(|d| d.is_finite()).collect();
        composite_twin_over(
            &mut out,
            &twin_rgba,
            &twin_mask,
            width,
            height,
            self.settings.anti_alias,
        );
        timings.composite_ms = ms(t);
        Ok(ArFrame {
            rgba8: out,
            state: TrackState::Tracked,
            camera_from_marker: Some(camera_from_marker),
            reprojection_px: None,
            timings,
            twin_mask,
            key_mask: key_mask_bool,
            live_counts,
            live_codes,
        })
    }
}

/// Milliseconds since `t`.
fn ms(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

/// Grey (Rec. 601 luma) from RGBA8.
pub fn gray_from_rgba(rgba8: &[u8], width: u32, height: u32) -> Result<GrayImage, ArError> {
    let data = rgba8
        .chunks_exact(4)
        .map(|p| ((77 * p[0] as u32 + 150 * p[1] as u32 + 29 * p[2] as u32 + 128) >> 8) as u8)
        .collect();
    Ok(GrayImage::new(width, height, data)?)
}

/// Per-channel gain that maps the model's texture (as rendered, unlit) to the live frame over
/// the key-pose silhouette: the colour match of the fallback. Clamped to [0.25, 4].
pub fn colour_gain(frame: &[u8], model_render: &[u8], mask: &[bool]) -> [f32; 3] {
    let mut sf = [0f64; 3];
    let mut sm = [0f64; 3];
    for (i, &m) in mask.iter().enumerate() {
        if m {
            for c in 0..3 {
                sf[c] += srgb_to_linear(frame[i * 4 + c]) as f64;
                sm[c] += srgb_to_linear(model_render[i * 4 + c]) as f64;
            }
        }
    }
    let mut g = [1f32; 3];
    for c in 0..3 {
        if sm[c] > 1e-6 {
            g[c] = ((sf[c] / sm[c]) as f32).clamp(0.25, 4.0);
        }
    }
    g
}

fn srgb_to_linear(v: u8) -> f32 {
    let c = v as f32 / 255.0;
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// The homography of the marker plane (z = 0) from the plate view's pixels to the current
/// view's pixels: `H = K [r1 r2 t]_current ([r1 r2 t]_plate)^-1 K^-1` (pinhole; distortion is
/// ignored here).
pub fn plane_homography(camera: &CameraModel, current: Mat4, plate: Mat4) -> DMat3 {
    let k = camera.intrinsics.matrix();
    let plane = |m: Mat4| {
        let m = m.as_dmat4();
        DMat3::from_cols(
            m.x_axis.truncate(),
            m.y_axis.truncate(),
            DVec3::new(m.w_axis.x, m.w_axis.y, m.w_axis.z),
        )
    };
    k * plane(current) * plane(plate).inverse() * k.inverse()
}

/// The key mask as a [`Mask`] (for callers that want pa-diminish types).
pub fn mask_from_bools(width: u32, height: u32, m: &[bool]) -> Result<Mask, ArError> {
    Ok(Mask::new(
        width,
        height,
        m.iter().map(|&b| if b { 255 } else { 0 }).collect(),
    )?)
}
