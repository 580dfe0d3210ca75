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
    dilate_in_bbox, CleanPlate, DilateShape, Diminisher, FillMethod, Homography, ImageRgba8, Mask,
    RayDirections, Rect,
};
use pa_model::{anim, Model};
use pa_render::{
    CpuCamera, CpuTexture, Draw, GpuTexture, GpuVisibility, LiveCamera, LiveDraw, LiveTexturing,
    RenderError, Renderer,
};
use pa_track::{GrayImage, TrackState, Tracker};

use crate::composite::{bounding_box, composite_twin_over_in};
use crate::cpu_twin::CpuTwin;
use crate::shading::{irradiance_samples, irradiance_samples_from, Irradiance, KeyDepth, KeyView};
use crate::twin::{GpuTwin, TwinFrame};

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
    #[error("CPU rendering: {0}")]
    Raster(#[from] pa_raster::RasterError),
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

/// Which renderer runs the texture stage (the key-pose depth, the visibility map and the
/// live-textured twin). Both compute the same image (`tests/cpu_gpu_parity.rs` bounds the
/// difference); `propsalive bench --render-path` compares their speed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RenderPath {
    /// wgpu ([`pa_render::Renderer`]): the GPU, or Mesa's software drivers without one.
    Gpu,
    /// Our own rasteriser ([`pa_raster`]): work proportional to the prop, not the frame.
    Cpu,
}

impl RenderPath {
    /// The faster path for this renderer: the CPU path when wgpu runs on a software
    /// rasteriser (measured: see the README's speed section), the GPU otherwise.
    /// `PROPSALIVE_RENDER_PATH=cpu|gpu` overrides.
    pub fn auto(renderer: &Renderer) -> Self {
        match std::env::var("PROPSALIVE_RENDER_PATH").ok().as_deref() {
            Some("cpu") => Self::Cpu,
            Some("gpu") => Self::Gpu,
            _ if renderer.is_software() => Self::Cpu,
            _ => Self::Gpu,
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            Self::Gpu => "gpu",
            Self::Cpu => "cpu",
        }
    }
}

/// A render path name other than `gpu` or `cpu` ([`RenderPath`]'s `FromStr`).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("render path {given:?}: expected gpu or cpu")]
pub struct ParseRenderPathError {
    /// The name given.
    pub given: String,
}

impl std::str::FromStr for RenderPath {
    type Err = ParseRenderPathError;
    fn from_str(s: &str) -> Result<Self, ParseRenderPathError> {
        match s {
            "gpu" => Ok(Self::Gpu),
            "cpu" => Ok(Self::Cpu),
            _ => Err(ParseRenderPathError { given: s.into() }),
        }
    }
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
    /// The layers of the composite, for a compositor ([`ArPipeline::set_keep_passes`]).
    pub passes: Option<ArPasses>,
}

/// The layers the composite is made of (sRGB RGBA8, full frame).
#[derive(Debug, Clone, PartialEq)]
pub struct ArPasses {
    /// The diminished plate: the frame with the real prop removed (the whole dilated key
    /// silhouette filled, also where the twin will cover it), before the twin is drawn.
    pub plate_rgba8: Vec<u8>,
    /// The twin alone with straight alpha: its colour and alpha 255 where it covers the
    /// pixel, all zero elsewhere (the composite's anti-aliased edge is not in it).
    pub twin_rgba8: Vec<u8>,
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
    render_path: RenderPath,
    /// The CPU path's twin and renderers, made on first use.
    cpu: Option<Box<CpuState>>,
    /// The fill mask, and the region of it the last frame set.
    fill_mask: Option<(Mask, Option<Rect>)>,
    keep_passes: bool,
    /// Props beside the pipeline's own ([`ArPipeline::add_prop`]).
    extra_props: Vec<ExtraProp>,
}

/// Another prop of the same frame.
struct ExtraProp {
    model: Model,
    animation: usize,
    marker_from_prop: Mat4,
    twin: GpuTwin,
}

/// One prop as the texture stage draws it.
#[derive(Clone, Copy)]
struct PropRef<'a> {
    model: &'a Model,
    animation: usize,
    marker_from_prop: Mat4,
    twin: &'a GpuTwin,
}

/// Every prop, the pipeline's own first (a function of the fields, so that the others stay
/// free to borrow mutably).
fn prop_refs<'a>(
    model: &'a Model,
    animation: usize,
    marker_from_prop: Mat4,
    twin: &'a GpuTwin,
    extras: &'a [ExtraProp],
) -> Vec<PropRef<'a>> {
    let mut v = vec![PropRef {
        model,
        animation,
        marker_from_prop,
        twin,
    }];
    v.extend(extras.iter().map(|p| PropRef {
        model: &p.model,
        animation: p.animation,
        marker_from_prop: p.marker_from_prop,
        twin: &p.twin,
    }));
    v
}

/// How far (Chebyshev, pixels) the composite looks around a twin pixel: its anti-aliasing
/// window's radius ([`crate::composite`]). A twin pixel whose neighbourhood of this radius is
/// all twin is drawn opaque, whatever the background.
const COMPOSITE_REACH_PX: usize = 4;

/// Marks as [`Mask::HIDDEN`] the set pixels of `fill` whose square neighbourhood of radius
/// `r` lies inside the twin (pixels beyond the image count as outside). Work O(bbox).
fn hide_twin_interior(fill: &mut Mask, twin: &[bool], bbox: Bbox, r: usize) {
    let (x0, y0, x1, y1) = bbox;
    let w = fill.width() as usize;
    let bw = x1 - x0 + 1;
    let bh = y1 - y0 + 1;
    // Horizontal pass: run length of twin pixels to the left and right of each pixel.
    let mut h_ok = vec![false; bw * bh];
    let mut left = vec![0usize; bw];
    for ly in 0..bh {
        let row = &twin[(y0 + ly) * w + x0..(y0 + ly) * w + x1 + 1];
        let mut run = 0usize;
        for (lx, &m) in row.iter().enumerate() {
            run = if m { run + 1 } else { 0 };
            left[lx] = run;
        }
        run = 0;
        for lx in (0..bw).rev() {
            run = if row[lx] { run + 1 } else { 0 };
            // Twin from lx - r to lx + r (the box's edges are outside the twin).
            h_ok[ly * bw + lx] = left[lx] > r && run > r;
        }
    }
    // Vertical pass over the horizontal result.
    let data = fill.as_mut_slice();
    let mut up = vec![0usize; bw];
    let mut down = vec![0usize; bw * bh];
    for ly in (0..bh).rev() {
        for lx in 0..bw {
            down[ly * bw + lx] = if h_ok[ly * bw + lx] {
                1 + if ly + 1 < bh {
                    down[(ly + 1) * bw + lx]
                } else {
                    0
                }
            } else {
                0
            };
        }
    }
    for ly in 0..bh {
        for lx in 0..bw {
            up[lx] = if h_ok[ly * bw + lx] { up[lx] + 1 } else { 0 };
            if up[lx] > r && down[ly * bw + lx] > r {
                let i = (y0 + ly) * w + x0 + lx;
                if data[i] != 0 {
                    data[i] = Mask::HIDDEN;
                }
            }
        }
    }
}

/// Clears a rectangle of a mask.
fn clear_rect(m: &mut Mask, r: Rect) {
    let w = m.width() as usize;
    let data = m.as_mut_slice();
    for y in r.y as usize..(r.y + r.height) as usize {
        data[y * w + r.x as usize..y * w + (r.x + r.width) as usize].fill(0);
    }
}

/// What the CPU path keeps between frames.
struct CpuState {
    /// One per prop, in [`ArPipeline::props`] order.
    twins: Vec<CpuTwin>,
    /// Key-pose depth (visibility map) and the animated twin.
    renderer: pa_raster::CpuRenderer,
    /// The key pose's unlit colour (the colour gain of the paper's baseline).
    key_colour: pa_raster::CpuRenderer,
}

/// The texture stage's results, whichever renderer made them (full-frame buffers).
struct Textured {
    /// Pixels covered by the key pose as the camera sees it.
    key_mask: Vec<bool>,
    /// Bounding box of `key_mask` (inclusive), `None` when empty.
    key_bbox: Option<Bbox>,
    twin_rgba: Vec<u8>,
    twin_mask: Vec<bool>,
    twin_bbox: Option<Bbox>,
    live_counts: (usize, usize),
    live_codes: Vec<u8>,
}

/// An inclusive pixel box `(x0, y0, x1, y1)`.
type Bbox = (usize, usize, usize, usize);

/// The full-frame mask of a CPU visibility buffer's surfaces, and its bounding box; work
/// proportional to the buffer's dirty rectangle (the rest is a zeroed allocation).
fn mask_of_vis(v: &pa_raster::VisBuffer) -> (Vec<bool>, Option<Bbox>) {
    let w = v.width as usize;
    let mut mask = vec![false; w * v.height as usize];
    let mut b: Option<Bbox> = None;
    if let Some(r) = v.dirty {
        for y in r.y0 as usize..=r.y1 as usize {
            let (a, e) = (y * w + r.x0 as usize, y * w + r.x1 as usize + 1);
            let (mut first, mut last) = (usize::MAX, 0);
            for (k, (m, &iz)) in mask[a..e].iter_mut().zip(&v.inv_z[a..e]).enumerate() {
                if iz > 0.0 {
                    *m = true;
                    first = first.min(k);
                    last = k;
                }
            }
            if first != usize::MAX {
                let (x0, x1) = (r.x0 as usize + first, r.x0 as usize + last);
                b = Some(match b {
                    None => (x0, y, x1, y),
                    Some((bx0, by0, bx1, _)) => (bx0.min(x0), by0, bx1.max(x1), y),
                });
            }
        }
    }
    (mask, b)
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
        let render_path = RenderPath::auto(renderer);
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
            render_path,
            cpu: None,
            fill_mask: None,
            keep_passes: false,
            extra_props: Vec::new(),
        })
    }

    /// Forgets the tracker's history (state, filter, search region) before a frame that
    /// starts a new sequence; nothing without a tracker.
    pub fn reset_tracker(&mut self) {
        if let Some(tracker) = &mut self.tracker {
            tracker.reset();
        }
    }

    /// The renderer of the texture stage ([`RenderPath::auto`] unless set).
    pub fn render_path(&self) -> RenderPath {
        self.render_path
    }

    /// Chooses the renderer of the texture stage.
    pub fn set_render_path(&mut self, path: RenderPath) {
        self.render_path = path;
    }

    /// Adds another prop to every frame (several props at once): its own model, animation
    /// and placement on the marker, at the same animation and key-pose times as the
    /// pipeline's own prop. The props are drawn together (each hides the others where it is
    /// in front, in the key pose as in the in-between), the real props are removed together
    /// and the light estimate uses all of them.
    pub fn add_prop(
        &mut self,
        renderer: &mut Renderer,
        model: Model,
        animation: usize,
        marker_from_prop: Mat4,
    ) -> Result<(), ArError> {
        if animation >= model.animations.len() && !model.animations.is_empty() {
            return Err(ArError::Config(format!("no animation {animation}")));
        }
        let twin = GpuTwin::upload(renderer, &model)?;
        self.extra_props.push(ExtraProp {
            model,
            animation,
            marker_from_prop,
            twin,
        });
        // The CPU twins are rebuilt for the new list on the next frame.
        self.cpu = None;
        Ok(())
    }

    /// Number of props drawn in every frame (1 + those added).
    pub fn prop_count(&self) -> usize {
        1 + self.extra_props.len()
    }

    /// With `true`, every frame also returns its layers ([`ArFrame::passes`]: the diminished
    /// plate and the twin alone). Costs two frame copies, and the fill then also covers the
    /// pixels the twin hides.
    pub fn set_keep_passes(&mut self, keep: bool) {
        self.keep_passes = keep;
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
                passes: None,
            });
        };
        let mut timings = StageTimings::default();
        // Place + animate (each renderer poses the model its own way: see texture_*).
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
        let view = FrameView {
            rgba8,
            width,
            height,
            camera_model,
            camera_from_marker,
            anim_time_s,
            key_time_s,
        };
        let textured = match self.render_path {
            RenderPath::Gpu => self.texture_gpu(renderer, &view, &mut timings)?,
            RenderPath::Cpu => self.texture_cpu(&view, &mut timings)?,
        };
        let Textured {
            key_mask,
            key_bbox,
            twin_rgba,
            twin_mask,
            twin_bbox,
            live_counts,
            live_codes,
        } = textured;
        let n = (width * height) as usize;
        debug_assert_eq!(twin_mask.len(), n);

        // Diminish: fill the dilated key silhouette in a copy of the frame. The fill mask is
        // kept between frames; only the region written last time is cleared.
        let t = Instant::now();
        let mut background = ImageRgba8::new(width, height, rgba8.to_vec())?;
        let fill_mask = match &mut self.fill_mask {
            Some((m, last)) if m.size() == (width, height) => {
                if let Some(r) = last.take() {
                    clear_rect(m, r);
                }
                m
            }
            slot => &mut slot.insert((Mask::zeros(width, height)?, None)).0,
        };
        let mut fill_region = None;
        if let Some((x0, y0, x1, y1)) = key_bbox {
            let w = width as usize;
            let data = fill_mask.as_mut_slice();
            for y in y0..=y1 {
                for i in y * w + x0..=y * w + x1 {
                    data[i] = if key_mask[i] { Mask::SET } else { 0 };
                }
            }
            let bbox = Rect::from_inclusive(x0 as u32, y0 as u32, x1 as u32, y1 as u32);
            fill_region = Some(if self.settings.dilate_px > 0 {
                dilate_in_bbox(fill_mask, bbox, self.settings.dilate_px, DilateShape::Disc)
            } else {
                bbox
            });
        }
        // Where the twin's interior will cover the frame opaquely the real prop needs no
        // removal: those pixels are hidden from the fill (rays pass through them, so every
        // other pixel is filled exactly as before).
        // (Not when the plate is kept as a pass: it must be clean everywhere.)
        if let (Some(tb), Some(_), false) = (twin_bbox, fill_region, self.keep_passes) {
            hide_twin_interior(fill_mask, &twin_mask, tb, COMPOSITE_REACH_PX);
        }
        if let Some((_, last)) = &mut self.fill_mask {
            *last = fill_region;
        }
        let fill_mask = match &self.fill_mask {
            Some((m, _)) => m,
            None => return Err(ArError::Config("fill mask missing".into())),
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
        if let (Some(m), Some(region)) = (method, fill_region) {
            self.diminisher
                .fill_in_bbox(&mut background, fill_mask, region, &m)?;
        }
        timings.diminish_ms = ms(t);

        let passes = self.keep_passes.then(|| ArPasses {
            plate_rgba8: background.as_slice().to_vec(),
            twin_rgba8: twin_rgba
                .chunks_exact(4)
                .zip(&twin_mask)
                .flat_map(|(p, &m)| if m { [p[0], p[1], p[2], 255] } else { [0; 4] })
                .collect(),
        });

        // Composite: twin over the diminished background.
        let t = Instant::now();
        let mut out = background.into_vec();
        composite_twin_over_in(
            &mut out,
            &twin_rgba,
            &twin_mask,
            width,
            height,
            self.settings.anti_alias,
            twin_bbox,
        );
        timings.composite_ms = ms(t);
        if let Some(cpu) = self
            .cpu
            .as_mut()
            .filter(|_| self.render_path == RenderPath::Cpu)
        {
            cpu.renderer.restore_twin_rgba(twin_rgba);
        }
        Ok(ArFrame {
            rgba8: out,
            state: TrackState::Tracked,
            camera_from_marker: Some(camera_from_marker),
            reprojection_px: None,
            timings,
            twin_mask,
            key_mask,
            live_counts,
            live_codes,
            passes,
        })
    }

    /// The texture stage on wgpu ([`RenderPath::Gpu`]).
    fn texture_gpu(
        &mut self,
        renderer: &mut Renderer,
        view: &FrameView<'_>,
        timings: &mut StageTimings,
    ) -> Result<Textured, ArError> {
        let FrameView {
            rgba8,
            width,
            height,
            camera_model,
            camera_from_marker,
            anim_time_s,
            key_time_s,
        } = *view;
        let n = (width * height) as usize;
        let t = Instant::now();
        let camera = CpuCamera {
            intrinsics: camera_model.intrinsics,
            camera_from_world: camera_from_marker,
            near_m: NEAR_M,
            far_m: FAR_M,
        };
        let props = prop_refs(
            &self.model,
            self.animation,
            self.marker_from_prop,
            &self.twin,
            &self.extra_props,
        );
        // Per prop: (key pose, in-between frame data, key-pose frame data).
        let frames: Vec<(anim::Pose, TwinFrame, TwinFrame)> = props
            .iter()
            .map(|p| {
                let anim_pose = anim::sample(p.model, p.animation, anim_time_s);
                let key_pose = anim::sample(p.model, p.animation, key_time_s);
                let a = p.twin.frame(p.model, &anim_pose, p.marker_from_prop);
                let k = p.twin.frame(p.model, &key_pose, p.marker_from_prop);
                (key_pose, a, k)
            })
            .collect();
        timings.animate_ms = ms(t);

        // Texture: the key pose as the camera sees it gives the diminish mask and the light on
        // the prop (with visibility: the visibility map, read back; without: a plain unlit
        // render, whose colours also give the baseline's colour gain); then the animated twin.
        let t = Instant::now();
        let key_draws: Vec<Draw<'_>> = props
            .iter()
            .zip(&frames)
            .flat_map(|(p, (_, _, k))| p.twin.draws(k))
            .collect();
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
        let cpu_frame = CpuTexture {
            width,
            height,
            rgba8: rgba8.to_vec(),
        };
        let (twin_rgba, twin_depth, live_counts, live_codes) = match self.settings.texturing {
            Texturing::ModelTexture => {
                let draws: Vec<Draw<'_>> = props
                    .iter()
                    .zip(&frames)
                    .flat_map(|(p, (_, a, _))| p.twin.draws(a))
                    .collect();
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
                // The fallback's shading: the set's light measured on the visible key props
                // (ours), or one colour gain (the baseline without visibility).
                let irradiance = if visibility {
                    let view = KeyView {
                        camera: &camera_model,
                        camera_from_world: camera_from_marker,
                        frame_rgba8: rgba8,
                        key_depth: KeyDepth::Metres(&key_depth_m),
                        width,
                        height,
                    };
                    let per_prop = IRRADIANCE_SAMPLES / props.len();
                    let samples: Vec<_> = props
                        .iter()
                        .zip(&frames)
                        .flat_map(|(p, (key_pose, _, _))| {
                            let posed = pa_model::skin::pose_drawn_meshes(p.model, key_pose);
                            irradiance_samples(p.model, &posed, p.marker_from_prop, &view, per_prop)
                        })
                        .collect();
                    Irradiance::fit_or_mean(&samples)
                } else {
                    Irradiance::constant(gain.unwrap_or([1.0; 3]))
                };
                let live_camera = LiveCamera::new(camera_model, camera_from_marker);
                let vis = if visibility {
                    self.visibility.as_ref()
                } else {
                    None
                };
                let mut draws: Vec<LiveDraw<'_>> = Vec::new();
                for (p, (_, anim_frame, key_frame)) in props.iter().zip(&frames) {
                    draws.extend(
                        p.twin
                            .draws(anim_frame)
                            .into_iter()
                            .zip(&p.twin.primitives)
                            .map(|(d, tp)| {
                                let key_joints: &[Mat4] = if tp.mesh.is_skinned() {
                                    &key_frame.joint_matrices[tp.node]
                                } else {
                                    &[]
                                };
                                let mut live = LiveTexturing::new(
                                    &frame_tex,
                                    live_camera,
                                    key_frame.world_from_node[tp.node],
                                )
                                .with_key_pose(key_joints, &key_frame.morph_weights[tp.node])
                                .with_fallback_irradiance(irradiance.rows);
                                if let Some(v) = vis {
                                    live = live.with_visibility(v);
                                    // The depth test decides occlusion, so grazing key-pose
                                    // normals may sample; surfaces turned to face the camera
                                    // take the lit fallback instead of a smeared sample.
                                    live.min_facing_cos = VISIBLE_MIN_FACING_COS;
                                    live.max_stretch = MAX_STRETCH;
                                }
                                d.with_live(live)
                            }),
                    );
                }
                let r = renderer.render_live(&camera, None, &draws, [0.0; 4], width, height)?;
                let counts = r.counts();
                drop(draws);
                self.frame_texture = Some(frame_tex);
                (r.frame.rgba8, r.frame.depth_m, counts, r.live_valid)
            }
        };
        timings.texture_ms = ms(t);
        let twin_mask: Vec<bool> = twin_depth.iter().map(|d| d.is_finite()).collect();
        let key_mask: Vec<bool> = key_depth_m.iter().map(|d| d.is_finite()).collect();
        Ok(Textured {
            key_bbox: bounding_box(&key_mask, width as usize, height as usize),
            key_mask,
            twin_bbox: bounding_box(&twin_mask, width as usize, height as usize),
            twin_rgba,
            twin_mask,
            live_counts,
            live_codes,
        })
    }

    /// The texture stage on our own rasteriser ([`RenderPath::Cpu`]): the same passes as
    /// [`ArPipeline::texture_gpu`], with the models posed on the CPU.
    fn texture_cpu(
        &mut self,
        view: &FrameView<'_>,
        timings: &mut StageTimings,
    ) -> Result<Textured, ArError> {
        use rayon::prelude::*;
        let FrameView {
            rgba8,
            width,
            height,
            camera_model,
            camera_from_marker,
            anim_time_s,
            key_time_s,
        } = *view;
        let n = (width * height) as usize;
        let t = Instant::now();
        let props = prop_refs(
            &self.model,
            self.animation,
            self.marker_from_prop,
            &self.twin,
            &self.extra_props,
        );
        let cpu = match &mut self.cpu {
            Some(c) => c,
            None => self.cpu.insert(Box::new(CpuState {
                twins: props
                    .iter()
                    .map(|p| CpuTwin::new(p.model))
                    .collect::<Result<_, _>>()?,
                renderer: pa_raster::CpuRenderer::new(),
                key_colour: pa_raster::CpuRenderer::new(),
            })),
        };
        // Every prop posed at both times (props in parallel; each poses its two in parallel).
        cpu.twins
            .par_iter_mut()
            .zip(props.par_iter())
            .for_each(|(twin, p)| {
                let anim_pose = anim::sample(p.model, p.animation, anim_time_s);
                let key_pose = anim::sample(p.model, p.animation, key_time_s);
                twin.pose(p.model, &anim_pose, &key_pose, p.marker_from_prop);
            });
        timings.animate_ms = ms(t);

        let t = Instant::now();
        let camera = pa_raster::RasterCamera::new(&camera_model.intrinsics, NEAR_M, FAR_M);
        let frame = pa_raster::FrameSampler::new(width, height, rgba8)?;
        let mut params = pa_raster::LiveParams::new(pa_raster::FrameCamera::new(&camera_model));
        let twins = &cpu.twins;
        let key_vis = match self.settings.texturing {
            Texturing::Live { visibility: false } => {
                // The paper's baseline: the key poses' unlit colours give one colour gain.
                let key_meshes: Vec<_> = twins
                    .iter()
                    .zip(&props)
                    .flat_map(|(tw, p)| tw.key_meshes(p.model))
                    .collect();
                cpu.key_colour.render_twin(
                    &camera,
                    camera_from_marker,
                    &key_meshes,
                    &pa_raster::Shading::Albedo,
                );
                let (mask, bbox) = mask_of_vis(cpu.key_colour.twin_depth());
                let gain = colour_gain(rgba8, &cpu.key_colour.twin_image().rgba8, &mask);
                params.fallback_irradiance = Irradiance::constant(gain).rows;
                (mask, bbox)
            }
            _ => {
                let key_meshes: Vec<_> = twins
                    .iter()
                    .zip(&props)
                    .flat_map(|(tw, p)| tw.key_depth_meshes(p.model))
                    .collect();
                cpu.renderer
                    .render_key_depth(&camera, camera_from_marker, &key_meshes);
                mask_of_vis(cpu.renderer.key_depth())
            }
        };
        let (key_mask, key_bbox) = key_vis;
        let shading = match self.settings.texturing {
            Texturing::ModelTexture => pa_raster::Shading::Albedo,
            Texturing::Live { visibility } => {
                if visibility {
                    let key_view = KeyView {
                        camera: &camera_model,
                        camera_from_world: camera_from_marker,
                        frame_rgba8: rgba8,
                        key_depth: KeyDepth::InverseMetres(&cpu.renderer.key_depth().inv_z),
                        width,
                        height,
                    };
                    let per_prop = IRRADIANCE_SAMPLES / props.len();
                    let samples: Vec<_> = twins
                        .iter()
                        .zip(&props)
                        .flat_map(|(tw, p)| {
                            // Posed in the marker frame already: the world is the model's.
                            let posed = tw.primitives.iter().zip(&tw.key).map(|(tp, k)| {
                                (
                                    tp.mesh,
                                    tp.primitive,
                                    k.positions_world.as_slice(),
                                    k.normals_world.as_slice(),
                                )
                            });
                            irradiance_samples_from(
                                p.model,
                                posed,
                                Mat4::IDENTITY,
                                &key_view,
                                per_prop,
                            )
                        })
                        .collect();
                    params.fallback_irradiance = Irradiance::fit_or_mean(&samples).rows;
                    params.visibility = true;
                    params.min_facing_cos = VISIBLE_MIN_FACING_COS;
                    params.max_stretch = MAX_STRETCH;
                }
                pa_raster::Shading::Live { frame, params }
            }
        };
        let meshes: Vec<_> = twins
            .iter()
            .zip(&props)
            .flat_map(|(tw, p)| tw.live_meshes(p.model))
            .collect();
        let image = cpu
            .renderer
            .render_twin(&camera, camera_from_marker, &meshes, &shading);
        let live_counts = image.counts();
        let live_codes = image.codes.clone();
        // Lent to the composite, given back after it (see render_frame).
        let twin_rgba = cpu.renderer.take_twin_rgba();
        let (twin_mask, twin_bbox) = mask_of_vis(cpu.renderer.twin_depth());
        debug_assert_eq!(twin_rgba.len(), n * 4);
        timings.texture_ms = ms(t);
        Ok(Textured {
            key_mask,
            key_bbox,
            twin_rgba,
            twin_mask,
            twin_bbox,
            live_counts,
            live_codes,
        })
    }
}

/// One frame and the camera that took it, as the texture stage sees it.
#[derive(Clone, Copy)]
struct FrameView<'a> {
    rgba8: &'a [u8],
    width: u32,
    height: u32,
    /// Intrinsics at the frame's size, with distortion.
    camera_model: CameraModel,
    camera_from_marker: Mat4,
    /// Animation time of the in-between shown, and of the key pose present.
    anim_time_s: f32,
    key_time_s: f32,
}

/// Milliseconds since `t`.
fn ms(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

/// Grey (Rec. 601 luma) from RGBA8 (rows in parallel).
pub fn gray_from_rgba(rgba8: &[u8], width: u32, height: u32) -> Result<GrayImage, ArError> {
    use rayon::prelude::*;
    let w = width as usize;
    let n = w * height as usize;
    if rgba8.len() != n * 4 || n == 0 {
        return Err(ArError::BadFrame {
            index: 0,
            width,
            height,
            expected: n * 4,
            got: rgba8.len(),
        });
    }
    let mut data = vec![0u8; n];
    {
        data.par_chunks_mut(w * 16)
            .zip(rgba8.par_chunks(w * 16 * 4))
            .for_each(|(g, c)| {
                for (o, p) in g.iter_mut().zip(c.chunks_exact(4)) {
                    *o = ((77 * p[0] as u32 + 150 * p[1] as u32 + 29 * p[2] as u32 + 128) >> 8)
                        as u8;
                }
            });
    }
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
                sf[c] += pa_raster::srgb::srgb_to_linear(frame[i * 4 + c]) as f64;
                sm[c] += pa_raster::srgb::srgb_to_linear(model_render[i * 4 + c]) as f64;
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
