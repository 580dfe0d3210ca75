//! The Props Alive frame pipeline: frame -> track -> place -> animate -> texture -> diminish
//! -> composite.
//!
//! [`ArPipeline::process`] takes one camera frame (sRGB RGBA8) and its [`FrameTimes`] (the
//! animation time to show, the key pose's), and returns the composited frame with the tracking state, the pose, stage timings and the
//! masks the evaluation needs. When tracking has no pose the output is the untouched input
//! (and the log says so).
//!
//! Texturing ([`Texturing`]): `Live` is the paper's method (each fragment samples the current
//! frame at the projection of the same surface point in the key pose; sections 3.2, 4.2),
//! with or without our visibility test and fallback; `ModelTexture` draws the model's own
//! scanned texture (no live sampling), for comparison. Diminishing ([`Fill`]): the paper's
//! rectangle, our ray fill over the dilated key-pose silhouette, or a clean plate.

mod config;
mod fill;
mod frame;
mod gpu_region;
mod hide;
mod memory;
mod shadows;
mod sun;
mod surfaces;
#[cfg(test)]
mod tests;
mod texture;

use std::time::Instant;

use glam::Mat4;
use pa_camera::CameraModel;
use pa_diminish::{Diminisher, ImageRgba8, Mask, Rect};
use pa_model::{anim, Model};
use pa_render::{GpuTexture, GpuVisibility, RenderError, Renderer};
use pa_track::{GrayImage, TrackState, Tracker};

use crate::composite::composite_twin_over_in;
use crate::twin::GpuTwin;

pub use config::{ArSettings, Fill, LiveLook, ParseRenderPathError, RenderPath, Texturing};
pub use fill::{mask_from_bools, plane_homography};
pub use frame::{ArFrame, ArPasses, FrameTimes, StageTimings};
pub use hide::{BoardSheet, Hide, SHEET_MARGIN_M};
pub use memory::MemorySnapshot;
pub use shadows::RETRY_FRAMES as SHADOW_RETRY_FRAMES;
pub use surfaces::BoardSurfaces;
pub use texture::colour_gain;
use texture::{CpuState, Textured};

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
    /// The model has animations but none with this index.
    #[error("no animation {animation}")]
    NoAnimation { animation: usize },
    /// [`ArPipeline::process`] on a pipeline made without a tracker.
    #[error("no tracker: use process_with_pose")]
    NoTracker,
    /// The fill mask was not made before the fill (an internal invariant).
    #[error("fill mask missing")]
    FillMaskMissing,
    /// The board sheet to hide cannot be made ([`BoardSheet::from_board`]).
    #[error("board sheet: {reason}")]
    BadSheet { reason: &'static str },
}

/// Everything the pipeline keeps between frames.
pub struct ArPipeline {
    pub camera: CameraModel,
    pub settings: ArSettings,
    /// Every prop drawn in every frame, the one given to [`ArPipeline::new`] first (never
    /// empty).
    props: Vec<Prop>,
    tracker: Option<Tracker>,
    frame_texture: Option<GpuTexture>,
    visibility: Option<GpuVisibility>,
    /// The wgpu path's key-pose depth, read back one region a frame ([`gpu_region`]).
    gpu_key_depth: gpu_region::RegionDepth,
    /// The sun's direction over the take ([`sun::SunTrack`]); forgotten by `reset_tracker`.
    sun_track: sun::SunTrack,
    /// The key prop's grazing reflection over the take ([`crate::grazing`]); forgotten by
    /// `reset_tracker`.
    grazing_track: crate::grazing::GrazingTrack,
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
    /// Shadows: on or off, and the light ([`shadows`]).
    shadows: shadows::ShadowState,
    /// The previous frame's diminished background, the patch and ray fills' prior for the
    /// next frame ([`Fill::Patch`], [`Fill::Rays`]).
    fill_prior: Option<fill::FillPrior>,
    /// What replaces the board sheet, if anything ([`Hide`]).
    hide: Option<hide::HideState>,
    /// The key props' remembered appearance ([`memory`]); kept by `reset_tracker`.
    memory: memory::TextureMemory,
    /// The board's surfaces for the patch fill, and their label map ([`surfaces`]).
    surfaces: Option<(BoardSurfaces, Option<Mask>)>,
    /// The fill mask with the board's redrawn tag pixels known (`fill.rs`), kept for the
    /// next frame's copy.
    spare_fill_mask: Option<Mask>,
    /// Frame-sized buffers handed back by [`ArPipeline::recycle`] and
    /// [`ArPipeline::recycle_frame`], reused by the next frame (empty until then).
    spare: SpareBuffers,
}

/// Frame-sized buffers a caller handed back, for the next frame's image, masks and codes (a
/// fresh buffer costs a page fault per 4 KiB it touches).
#[derive(Default)]
pub(super) struct SpareBuffers {
    rgba8: Vec<u8>,
    masks: Vec<Vec<bool>>,
    codes: Vec<u8>,
}

/// `src` copied into the memory of `spare` (taken out of it; a new buffer when it is empty).
fn copy_into_spare<T: Copy>(spare: &mut Vec<T>, src: &[T]) -> Vec<T> {
    let mut copy = std::mem::take(spare);
    copy.clear();
    copy.extend_from_slice(src);
    copy
}

/// Keeps `v` as the spare when it holds more memory than the spare there.
fn keep_larger<T>(spare: &mut Vec<T>, v: Vec<T>) {
    if v.capacity() > spare.capacity() {
        *spare = v;
    }
}

impl SpareBuffers {
    /// A recycled mask buffer (stale contents) or an empty one.
    pub(super) fn take_mask(&mut self) -> Vec<bool> {
        self.masks.pop().unwrap_or_default()
    }

    /// A mask of `n` pixels, all false: a recycled one when there is one.
    pub(super) fn mask(&mut self, n: usize) -> Vec<bool> {
        let mut m = self.take_mask();
        m.clear();
        m.resize(n, false);
        m
    }

    /// A copy of `codes` in the recycled code buffer, or a new one.
    pub(super) fn codes_copy(&mut self, codes: &[u8]) -> Vec<u8> {
        copy_into_spare(&mut self.codes, codes)
    }
}

/// One prop drawn in every frame: its model, the animation it plays and its placement on the
/// marker, with the model uploaded for the GPU path.
pub struct Prop {
    pub model: Model,
    pub animation: usize,
    pub marker_from_prop: Mat4,
    twin: GpuTwin,
    /// Per mesh and primitive (as drawn), the coarse mesh the sun's shadow map draws
    /// ([`pa_raster::sun::coarse_mesh`] of the rest pose).
    shadow_meshes: Vec<Vec<pa_raster::sun::CoarseMesh>>,
}

impl Prop {
    /// Checks the animation and uploads the model.
    fn new(
        renderer: &mut Renderer,
        model: Model,
        animation: usize,
        marker_from_prop: Mat4,
    ) -> Result<Self, ArError> {
        if animation >= model.animations.len() && !model.animations.is_empty() {
            return Err(ArError::NoAnimation { animation });
        }
        let twin = GpuTwin::upload(renderer, &model)?;
        let shadow_meshes = model
            .meshes
            .iter()
            .map(|m| {
                m.primitives
                    .iter()
                    .map(|p| {
                        let d = p.drawn();
                        pa_raster::sun::coarse_mesh(&d.positions, &d.indices)
                    })
                    .collect()
            })
            .collect();
        Ok(Self {
            model,
            animation,
            marker_from_prop,
            twin,
            shadow_meshes,
        })
    }

    /// The prop's poses in a frame: the in-between shown and the key pose (both render
    /// paths pose from these).
    fn poses(&self, times: FrameTimes) -> (anim::Pose, anim::Pose) {
        let anim_pose = anim::sample(&self.model, self.animation, times.animation_s);
        let key_pose = anim::sample(&self.model, self.animation, times.key_pose_s);
        (anim_pose, key_pose)
    }
}

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
        let prop = Prop::new(renderer, model, animation, marker_from_prop)?;
        let render_path = RenderPath::auto(renderer);
        Ok(Self {
            camera,
            settings,
            props: vec![prop],
            tracker,
            frame_texture: None,
            visibility: None,
            gpu_key_depth: gpu_region::RegionDepth::default(),
            sun_track: sun::SunTrack::default(),
            grazing_track: crate::grazing::GrazingTrack::default(),
            diminisher: Diminisher::new(),
            plate: None,
            frame_index: 0,
            render_path,
            cpu: None,
            fill_mask: None,
            keep_passes: false,
            shadows: shadows::ShadowState::default(),
            fill_prior: None,
            hide: None,
            memory: memory::TextureMemory::default(),
            surfaces: None,
            spare_fill_mask: None,
            spare: SpareBuffers::default(),
        })
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
        let prop = Prop::new(renderer, model, animation, marker_from_prop)?;
        self.props.push(prop);
        // The CPU twins are rebuilt for the new list on the next frame.
        self.cpu = None;
        Ok(())
    }

    /// Number of props drawn in every frame (1 + those added).
    pub fn prop_count(&self) -> usize {
        self.props.len()
    }

    /// Every prop drawn in every frame, the one given to [`ArPipeline::new`] first.
    pub fn props(&self) -> &[Prop] {
        &self.props
    }

    /// The prop given to [`ArPipeline::new`] (the first of [`ArPipeline::props`]).
    pub fn first_prop(&self) -> &Prop {
        &self.props[0]
    }

    /// Moves the first prop (the preview's placing of the key prop).
    pub fn set_first_marker_from_prop(&mut self, marker_from_prop: Mat4) {
        self.props[0].marker_from_prop = marker_from_prop;
    }

    /// Forgets the tracker's history (state, filter, search region), the patch fill's previous
    /// result, the sun's direction and the grazing reflection before a frame that starts a new
    /// sequence.
    pub fn reset_tracker(&mut self) {
        self.fill_prior = None;
        self.sun_track = sun::SunTrack::default();
        self.grazing_track = crate::grazing::GrazingTrack::default();
        self.reset_tracking();
    }

    /// Forgets the tracker's history only: the next frame is tracked as a still, while the
    /// patch fill keeps the previous frame's result as its prior and the sun its direction
    /// (stills of one take, as `eval --set` measures them).
    pub fn reset_tracking(&mut self) {
        if let Some(tracker) = &mut self.tracker {
            tracker.reset();
        }
    }

    /// With `true`, every frame also returns its layers ([`ArFrame::passes`]: the diminished
    /// plate and the twin alone). Costs two frame copies, and the fill then also covers the
    /// pixels the twin hides.
    pub fn set_keep_passes(&mut self, keep: bool) {
        self.keep_passes = keep;
    }

    /// Hands a processed frame's image ([`ArFrame::rgba8`]) back so that the next frame
    /// writes its composite into the same memory. Optional; a live loop that shows or writes
    /// each frame and then drops it should give the image back instead: a fresh frame-sized
    /// buffer costs a page fault per 4 KiB on first touch (about 2 ms a frame at 1280x720 on
    /// our 2-core machine, more than the copy itself).
    pub fn recycle(&mut self, rgba8: Vec<u8>) {
        keep_larger(&mut self.spare.rgba8, rgba8);
    }

    /// Hands every frame-sized buffer of a processed frame back (its image, masks and codes,
    /// left empty in `frame`) so that the next frame reuses their memory: [`ArPipeline::recycle`]
    /// for all of them, for a loop done with a frame's buffers (keep a copy of what you
    /// still need first).
    pub fn recycle_frame(&mut self, frame: &mut ArFrame) {
        self.recycle(std::mem::take(&mut frame.rgba8));
        for m in [&mut frame.twin_mask, &mut frame.key_mask] {
            let m = std::mem::take(m);
            if self.spare.masks.len() < 2 && !m.is_empty() {
                self.spare.masks.push(m);
            }
        }
        keep_larger(&mut self.spare.codes, std::mem::take(&mut frame.live_codes));
    }

    /// A copy of `rgba8` in the recycled buffer ([`ArPipeline::recycle`]), or a new one.
    fn copy_of(&mut self, rgba8: &[u8]) -> Vec<u8> {
        copy_into_spare(&mut self.spare.rgba8, rgba8)
    }

    /// Sets the clean plate (the set without the prop) and the camera pose it was taken from.
    pub fn set_clean_plate(&mut self, plate: ImageRgba8, camera_from_marker: Mat4) {
        self.plate = Some((plate, camera_from_marker));
    }

    /// Tracks the marker in `rgba8` (taken at `capture_s`, the tracker's clock) and processes
    /// the frame.
    pub fn process(
        &mut self,
        renderer: &mut Renderer,
        rgba8: &[u8],
        width: u32,
        height: u32,
        times: FrameTimes,
        capture_s: f64,
    ) -> Result<ArFrame, ArError> {
        self.check_frame(rgba8, width, height)?;
        let t0 = Instant::now();
        let (state, pose, rms) = match &mut self.tracker {
            Some(tracker) => {
                let gray = gray_from_rgba(rgba8, width, height)?;
                let out = tracker.update(&gray, capture_s)?;
                (
                    out.state,
                    out.pose.map(|p| p.to_mat4()),
                    out.raw.map(|r| r.rms_px),
                )
            }
            None => return Err(ArError::NoTracker),
        };
        let track_ms = ms(t0);
        let mut frame = self.render_frame(renderer, rgba8, width, height, times, pose)?;
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
        times: FrameTimes,
        camera_from_marker: Mat4,
    ) -> Result<ArFrame, ArError> {
        self.check_frame(rgba8, width, height)?;
        let mut f = self.render_frame(
            renderer,
            rgba8,
            width,
            height,
            times,
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

    fn render_frame(
        &mut self,
        renderer: &mut Renderer,
        rgba8: &[u8],
        width: u32,
        height: u32,
        times: FrameTimes,
        pose: Option<Mat4>,
    ) -> Result<ArFrame, ArError> {
        let n = (width * height) as usize;
        let Some(camera_from_marker) = pose else {
            return Ok(ArFrame {
                rgba8: self.copy_of(rgba8),
                state: TrackState::Searching,
                camera_from_marker: None,
                reprojection_px: None,
                timings: StageTimings::default(),
                twin_mask: self.spare.mask(n),
                key_mask: self.spare.mask(n),
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
            times,
        };
        let textured = match self.render_path {
            RenderPath::Gpu => self.texture_gpu(renderer, &view, &mut timings)?,
            RenderPath::Cpu => self.texture_cpu(&view, &mut timings)?,
        };
        let n = (width * height) as usize;
        debug_assert_eq!(textured.twin_mask.len(), n);

        // Diminish: lift the key props' shadow (shadows.rs), then fill the dilated key
        // silhouette in a copy of the frame (fill.rs).
        let t = Instant::now();
        let shadow_tris = self.shadow_triangles(times);
        let lifted = match &shadow_tris {
            Some(tris) => self.lift_key_shadow(&view, &textured, tris)?,
            None => None,
        };
        let fill_view = match &lifted {
            Some(l) => FrameView { rgba8: l, ..view },
            None => view,
        };
        let mut background = self.diminish(&fill_view, &textured)?;
        // No marker in the final frame: the board sheet replaced (hide.rs).
        self.hide_sheet(&view, &mut background)?;
        timings.diminish_ms = ms(t);
        let Textured {
            key_mask,
            twin_rgba,
            twin_mask,
            twin_bbox,
            live_counts,
            live_codes,
            ..
        } = textured;

        let passes = self.keep_passes.then(|| ArPasses {
            plate_rgba8: background.as_slice().to_vec(),
            twin_rgba8: twin_rgba
                .chunks_exact(4)
                .zip(&twin_mask)
                .flat_map(|(p, &m)| if m { [p[0], p[1], p[2], 255] } else { [0; 4] })
                .collect(),
        });

        // Composite: the twins' shadow, then the twins, over the diminished background.
        let t = Instant::now();
        if let Some(tris) = &shadow_tris {
            self.cast_twin_shadow(&mut background, &view, tris)?;
        }
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
    /// Animation times of the in-between shown and of the key pose present.
    times: FrameTimes,
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
