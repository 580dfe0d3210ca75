//! Live texturing from the camera frame (PRODUCT.md pipeline step 5; the paper's sections 3.2
//! and 4.2): the animated twin takes its colours from the current camera image, at the place
//! where the *same* surface point sits on the physical prop in its key pose.
//!
//! # Inputs
//!
//! A [`LiveDraw`] is a [`Draw`] (the animated pose: `joint_matrices`, `morph_weights`,
//! `world_from_mesh`) plus a [`LiveTexturing`] block: the camera frame ([`GpuTexture`] from
//! [`crate::Renderer::upload_frame`], refreshed in place with
//! [`crate::Renderer::update_texture`]), the key pose of the same mesh
//! (`key_joint_matrices`, `key_morph_weights`, `key_world_from_mesh`), the camera that took
//! the frame ([`LiveCamera`]: pose, intrinsics, OpenCV distortion), an optional visibility map
//! ([`GpuVisibility`], from [`crate::Renderer::render_visibility`]) and the fallback gain.
//!
//! # Math
//!
//! Correspondence is by vertex index (same mesh, two poses). For vertex `v` with morph deltas
//! `d_k` and influences `(w_i, j_i)`:
//!
//! * animated: `P(v) = sum_i w_i M[j_i] (p_v + sum_k m_k d_k)` (or `world_from_mesh * p` when
//!   rigid), projected by the render camera as usual;
//! * key pose: `K(v) = sum_i w_i Mkey[j_i] (p_v + sum_k mkey_k d_k)` (or
//!   `key_world_from_mesh * p` when `key_joint_matrices` is empty), and its key-pose normal
//!   `N(v)` (cofactor transform, as for the animated normal); the vertex stage outputs
//!   `Kc = camera_from_world_frame * K(v)` and `Nc = R_frame N(v)` as varyings.
//!
//! The rasteriser interpolates `Kc` and `Nc` perspective-correctly over the *animated*
//! triangle: a fragment with barycentric coordinates `b` on the animated triangle receives
//! `Kc = sum b_i Kc_i`, the point with the same barycentric coordinates on the key-pose
//! triangle, i.e. the same surface point. Per fragment:
//!
//! 1. normalised coordinates `(x, y) = (Kc.x / Kc.z, Kc.y / Kc.z)` (requires `Kc.z > 0`);
//! 2. OpenCV radial-tangential distortion (as [`pa_camera::Distortion::distort`]), with
//!    `r^2 = x^2 + y^2`:
//!    `x_d = x (1 + k1 r^2 + k2 r^4 + k3 r^6) + 2 p1 x y + p2 (r^2 + 2 x^2)`,
//!    `y_d = y (1 + k1 r^2 + k2 r^4 + k3 r^6) + p1 (r^2 + 2 y^2) + 2 p2 x y`;
//!    points beyond the first radius where the radial map folds back
//!    (`d/dr [r (1 + k1 r^2 + k2 r^4 + k3 r^6)] = 1 + 3 k1 r^2 + 5 k2 r^4 + 7 k3 r^6 <= 0`) are
//!    rejected, since they would wrap into the image;
//! 3. pixel `(u, v) = (fx x_d + cx, fy y_d + cy)` with the frame camera's intrinsics rescaled
//!    to the frame texture size ([`pa_camera::Intrinsics::scaled_to`]); OpenCV pixel centres
//!    sit at integer coordinates, so the texture coordinate is `((u + 0.5) / W, (v + 0.5) / H)`;
//! 4. the frame is sampled bilinearly at mip level 0 with clamp-to-edge addressing (in linear
//!    light: the frame is uploaded as sRGB).
//!
//! Live-textured fragments are **unlit** (the frame already carries the real lighting).
//!
//! # Validity
//!
//! A fragment's live sample is valid ([`LiveSample::Valid`]) when all hold, checked in this
//! order (the first failure is the code written):
//!
//! * [`LiveSample::Outside`]: `Kc.z > 0`, the radial map is monotonic at `r`, and
//!   `-0.5 <= u <= W - 0.5`, `-0.5 <= v <= H - 0.5` (the key-pose point is inside the frame);
//!   also when a visibility map is bound and the point is outside it or behind its camera;
//! * [`LiveSample::BackFacing`]: the key-pose normal faces the frame camera,
//!   `dot(Nc, Kc) / (|Nc| |Kc|) < -min_facing_cos` (default
//!   [`LiveTexturing::DEFAULT_MIN_FACING_COS`] = 0.05, i.e. within about 87 degrees of facing
//!   the camera);
//! * [`LiveSample::Stretched`] (only when [`LiveTexturing::max_stretch`] > 0): the animated
//!   surface faces the camera more than `max_stretch` times as squarely as the key-pose surface
//!   did (`cos_anim > max_stretch * max(cos_key, 0)`, both cosines between the normal and the
//!   direction to the camera): the few frame pixels that saw the point at a grazing angle
//!   would be smeared over a surface now seen face-on;
//! * [`LiveSample::Occluded`] (only with a visibility map): the key-pose point is the surface
//!   the frame camera sees there. The map holds, per texel, the camera-space z of the nearest
//!   key-pose surface rendered by the visibility camera (a pinhole rasterisation, so the point
//!   is projected *without* distortion for this look-up: `q = (fx' X/Z + cx', fy' Y/Z + cy')`
//!   with `(X, Y, Z) = visibility_from_frame_camera * Kc`). `z_map` is the *farthest* surface
//!   among the four texels around `q` (empty texels ignored; all empty never occludes): on a
//!   planar face at any slope it is at least the face's own depth there, so a visible point
//!   always passes, and within a pixel of an occluding edge the test leans towards "visible"
//!   (the live sample there is the edge the camera really saw, better than any fallback). The
//!   point is visible when
//!   `Z <= z_map (1 + depth_tolerance_rel) + depth_tolerance_m` (defaults 0.5% of the depth
//!   plus 1 mm: [`LiveTexturing::DEFAULT_DEPTH_TOLERANCE_REL`],
//!   [`LiveTexturing::DEFAULT_DEPTH_TOLERANCE_M`]).
//!
//! Invalid fragments take the fallback colour `albedo.rgb * E(n)` (linear), where albedo is the
//! draw's own base colour (texture sample times `base_color_factor`) and `E` is the caller's
//! estimate of the light falling on the real prop, as a first-order spherical-harmonic
//! irradiance of the world-space normal `n` of the *animated* surface:
//! `E_c(n) = max(r_c . (1, n.x, n.y, n.z), 0.02)` for each channel `c`
//! ([`LiveTexturing::fallback_irradiance`]; a constant gain is `r_c = (g_c, 0, 0, 0)`). So a
//! surface hidden in the key pose is shaded as the set lights it in the in-between pose.
//!
//! # Relighting and feathered seams
//!
//! Both are off by default and are the CPU path's `pa_raster::look` (the math and constants
//! are documented there; `live.wgsl` mirrors them). With [`LiveTexturing::relight`] a valid
//! live sample `c` is shaded at the animated normal: `c E(n_anim) / E(n_key)` per channel
//! (clamped to [0.7, 2]), `E` the fallback irradiance, both normals in the world frame. With
//! [`LiveTexturing::feather`] a valid sample's weight `w` goes smoothly to 0 towards the frame
//! edge, the back-facing limit, the stretch limit and the occlusion limit, and the fragment
//! takes `w live + (1 - w) fallback`. The code stays [`LiveSample::Valid`] wherever `w > 0`
//! is possible, so the codes are unchanged.
//!
//! The per-pixel code of the nearest surface is read back in
//! [`LiveRenderedFrame::live_valid`] (0 where no live-textured draw is visible).
//!
//! # Visibility map
//!
//! [`crate::Renderer::render_visibility`] rasterises the key-pose draws (see
//! [`LiveDraw::key_pose_draw`]) from the frame camera into a camera-z texture that stays on
//! the GPU. Render it once per frame (the camera moves) at the frame's size or larger; include
//! any other real object that can hide the prop. Without a map only the outside and
//! back-facing tests apply.

use glam::Mat4;

use crate::renderer::{CpuCamera, Draw, RenderedFrame};
use crate::texture::GpuTexture;

/// The camera that took a frame: OpenCV intrinsics (for `intrinsics.width` x `height`;
/// rescaled to the frame texture's size when it differs), distortion and pose.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LiveCamera {
    pub intrinsics: pa_camera::Intrinsics,
    pub distortion: pa_camera::Distortion,
    /// OpenCV camera axes (x right, y down, z forward), metres.
    pub camera_from_world: Mat4,
}

impl LiveCamera {
    /// A frame camera from a calibrated model and a pose.
    pub fn new(model: pa_camera::CameraModel, camera_from_world: Mat4) -> Self {
        Self {
            intrinsics: model.intrinsics,
            distortion: model.distortion,
            camera_from_world,
        }
    }

    /// The render camera as a frame camera, with the given lens distortion.
    pub fn from_render_camera(camera: &CpuCamera, distortion: pa_camera::Distortion) -> Self {
        Self {
            intrinsics: camera.intrinsics,
            distortion,
            camera_from_world: camera.camera_from_world,
        }
    }
}

/// A key-pose visibility map: camera-space z of the nearest key-pose surface per texel, seen
/// by a (pinhole) camera, kept on the GPU. Made by [`crate::Renderer::render_visibility`],
/// refreshed in place by [`crate::Renderer::update_visibility`]. Cheap to clone (clones share
/// the texture).
#[derive(Debug, Clone)]
pub struct GpuVisibility {
    pub(crate) renderer_id: u64,
    pub(crate) width: u32,
    pub(crate) height: u32,
    pub(crate) camera: CpuCamera,
    pub(crate) camera_z: wgpu::Texture,
    pub(crate) camera_z_view: wgpu::TextureView,
    pub(crate) depth_view: wgpu::TextureView,
    /// Staging buffer of [`crate::Renderer::read_visibility`], made on first use.
    pub(crate) readback: Option<wgpu::Buffer>,
}

impl GpuVisibility {
    /// Size of the map in texels.
    pub fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    /// The camera the map was rendered with (intrinsics as given, before rescaling to the map
    /// size).
    pub fn camera(&self) -> &CpuCamera {
        &self.camera
    }
}

/// How one draw is textured from the live camera frame. See the module docs for the math.
#[derive(Debug, Clone, Copy)]
pub struct LiveTexturing<'a> {
    /// The current camera frame (sRGB RGBA8; [`crate::Renderer::upload_frame`]).
    pub frame: &'a GpuTexture,
    /// The camera that took `frame`, normally the render camera plus its lens distortion.
    pub frame_camera: LiveCamera,
    /// Rigid key pose (used when `key_joint_matrices` is empty), e.g. the prop's placement on
    /// the marker.
    pub key_world_from_mesh: Mat4,
    /// Key-pose joint matrices, same rules as [`Draw::joint_matrices`]: empty for a rigid
    /// key pose with `key_world_from_mesh` (for a skinned mesh: its bind pose).
    pub key_joint_matrices: &'a [Mat4],
    /// Key-pose morph weights: empty (all zero) or one per morph target.
    pub key_morph_weights: &'a [f32],
    /// Occlusion test against this map; `None`: outside and back-facing tests only.
    pub visibility: Option<&'a GpuVisibility>,
    /// Irradiance on the draw's own albedo for fragments without a valid live sample: per
    /// linear RGB channel, `E(n) = r[0] + r[1] n.x + r[2] n.y + r[3] n.z` of the world-space
    /// normal (see the module docs).
    pub fallback_irradiance: [[f32; 4]; 3],
    /// Relative depth tolerance of the occlusion test.
    pub depth_tolerance_rel: f32,
    /// Absolute depth tolerance of the occlusion test, metres.
    pub depth_tolerance_m: f32,
    /// A key-pose normal must face the frame camera by more than this cosine.
    pub min_facing_cos: f32,
    /// Largest ratio of the animated to the key-pose facing cosine for a live sample
    /// ([`LiveSample::Stretched`]); 0 disables the test (the default).
    pub max_stretch: f32,
    /// Texture memory: per vertex of the draw's mesh, a remembered linear colour times its
    /// confidence, and the confidence (`pa_raster::memory::VertexMemory::premultiplied`).
    /// A fragment without a valid live sample takes `memory.rgb + (1 - memory.a) *
    /// fallback`. Empty (the default): the fallback alone.
    pub memory: &'a [[f32; 4]],
    /// Shade live samples at the animated normal: times `E(n_anim) / E(n_key)` of
    /// `fallback_irradiance` (see the module docs, "Relighting and feathered seams").
    pub relight: bool,
    /// Blend live and fallback colour with a continuous weight instead of a hard seam.
    pub feather: bool,
    /// The set's sun (`pa_raster::sun`): when set, it shades the fallback and relights live
    /// samples instead of `fallback_irradiance`, with `sun_lit` per vertex.
    pub sun: Option<pa_raster::sun::SunLight>,
    /// Per vertex of the draw's mesh, the fraction of the sun it receives, `[key pose,
    /// animated pose]` (empty: fully lit).
    pub sun_lit: &'a [[f32; 2]],
    /// Light reflected at grazing angles, linear RGB (`pa_raster::look`, "Grazing
    /// reflection"): with `relight`, a live sample loses the key pose's `grazing_rgb (1 -
    /// cos_key)^5` before relighting and gains the in-between's, and the fallback gains the
    /// in-between's. Zero (the default): none.
    pub grazing_rgb: [f32; 3],
}

impl<'a> LiveTexturing<'a> {
    /// Default relative depth tolerance of the occlusion test (0.5% of the depth).
    pub const DEFAULT_DEPTH_TOLERANCE_REL: f32 = 0.005;
    /// Default absolute depth tolerance of the occlusion test (1 mm).
    pub const DEFAULT_DEPTH_TOLERANCE_M: f32 = 0.001;
    /// Default back-facing margin: the key-pose normal must be within acos(0.05) = 87.1
    /// degrees of pointing at the frame camera.
    pub const DEFAULT_MIN_FACING_COS: f32 = 0.05;

    /// Live texturing from `frame`, taken by `frame_camera`, with a rigid key pose at
    /// `key_world_from_mesh`; no visibility map, fallback gain 1, default tolerances.
    pub fn new(frame: &'a GpuTexture, frame_camera: LiveCamera, key_world_from_mesh: Mat4) -> Self {
        Self {
            frame,
            frame_camera,
            key_world_from_mesh,
            key_joint_matrices: &[],
            key_morph_weights: &[],
            visibility: None,
            fallback_irradiance: [[1.0, 0.0, 0.0, 0.0]; 3],
            depth_tolerance_rel: Self::DEFAULT_DEPTH_TOLERANCE_REL,
            depth_tolerance_m: Self::DEFAULT_DEPTH_TOLERANCE_M,
            min_facing_cos: Self::DEFAULT_MIN_FACING_COS,
            max_stretch: 0.0,
            memory: &[],
            relight: false,
            feather: false,
            sun: None,
            sun_lit: &[],
            grazing_rgb: [0.0; 3],
        }
    }

    /// Sets the skinned / morphed key pose.
    pub fn with_key_pose(
        mut self,
        key_joint_matrices: &'a [Mat4],
        key_morph_weights: &'a [f32],
    ) -> Self {
        self.key_joint_matrices = key_joint_matrices;
        self.key_morph_weights = key_morph_weights;
        self
    }

    /// Sets the visibility map.
    pub fn with_visibility(mut self, visibility: &'a GpuVisibility) -> Self {
        self.visibility = Some(visibility);
        self
    }

    /// Sets a constant fallback gain (linear RGB; the same for every normal).
    pub fn with_fallback_gain(mut self, fallback_gain_rgb: [f32; 3]) -> Self {
        self.fallback_irradiance = fallback_gain_rgb.map(|g| [g, 0.0, 0.0, 0.0]);
        self
    }

    /// Sets the sun and the fraction of it per vertex ([`LiveTexturing::sun`]).
    pub fn with_sun(mut self, sun: pa_raster::sun::SunLight, sun_lit: &'a [[f32; 2]]) -> Self {
        self.sun = Some(sun);
        self.sun_lit = sun_lit;
        self
    }

    /// Sets the texture memory ([`LiveTexturing::memory`]).
    pub fn with_memory(mut self, memory: &'a [[f32; 4]]) -> Self {
        self.memory = memory;
        self
    }

    /// Sets the fallback irradiance (rows of `(constant, n.x, n.y, n.z)` per linear RGB
    /// channel, world-space normals).
    pub fn with_fallback_irradiance(mut self, rows: [[f32; 4]; 3]) -> Self {
        self.fallback_irradiance = rows;
        self
    }
}

/// A draw of [`crate::Renderer::render_live`]: a [`Draw`] (the animated pose) and, optionally,
/// its live texturing. Without it the draw shades exactly as in [`crate::Renderer::render`].
#[derive(Debug, Clone, Copy)]
pub struct LiveDraw<'a> {
    pub draw: Draw<'a>,
    pub live: Option<LiveTexturing<'a>>,
}

impl<'a> LiveDraw<'a> {
    /// The same mesh in its key pose (the key joints, morph weights and world transform; same
    /// texture), for [`crate::Renderer::render_visibility`]. The draw itself when not live.
    pub fn key_pose_draw(&self) -> Draw<'a> {
        match &self.live {
            None => self.draw,
            Some(l) => Draw {
                world_from_mesh: l.key_world_from_mesh,
                joint_matrices: l.key_joint_matrices,
                morph_weights: l.key_morph_weights,
                ..self.draw
            },
        }
    }
}

impl<'a> From<Draw<'a>> for LiveDraw<'a> {
    fn from(draw: Draw<'a>) -> Self {
        Self { draw, live: None }
    }
}

impl<'a> Draw<'a> {
    /// This draw, textured from the live camera frame.
    pub fn with_live(self, live: LiveTexturing<'a>) -> LiveDraw<'a> {
        LiveDraw {
            draw: self,
            live: Some(live),
        }
    }
}

/// What the nearest surface of a pixel of a [`LiveRenderedFrame`] took its colour from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[repr(u8)]
pub enum LiveSample {
    /// Background, or a draw without live texturing.
    None = 0,
    /// Fallback: the key-pose point projects outside the frame (or behind the camera, or
    /// outside the visibility map).
    Outside = 1,
    /// Fallback: the key-pose normal faces away from the frame camera.
    BackFacing = 2,
    /// Fallback: another key-pose surface is in front of the point in the visibility map.
    Occluded = 3,
    /// Fallback: the animated surface faces the camera far more squarely than the key-pose
    /// surface did ([`LiveTexturing::max_stretch`]).
    Stretched = 4,
    /// Live sample from the camera frame.
    Valid = 255,
}

impl LiveSample {
    /// The sample kind of a [`LiveRenderedFrame::live_valid`] code (`None` for unknown codes).
    pub fn from_code(code: u8) -> Self {
        match code {
            1 => Self::Outside,
            2 => Self::BackFacing,
            3 => Self::Occluded,
            4 => Self::Stretched,
            255 => Self::Valid,
            _ => Self::None,
        }
    }

    /// True for the fallback kinds (a live-textured draw without a valid sample).
    pub fn is_fallback(self) -> bool {
        matches!(
            self,
            Self::Outside | Self::BackFacing | Self::Occluded | Self::Stretched
        )
    }
}

/// The result of [`crate::Renderer::render_live_region`]: what [`LiveRenderedFrame`] holds,
/// for one region of the target (row-major from the region's top-left).
#[derive(Debug, Clone, PartialEq)]
pub struct LiveRegionFrame {
    /// The region read back.
    pub region: crate::PixelRegion,
    /// The whole target's (width, height).
    pub target_size: (u32, u32),
    /// sRGB RGBA8 colour of the region.
    pub rgba8: Vec<u8>,
    /// Camera-space depth (metres) of the region, `f32::INFINITY` where nothing was drawn.
    pub depth_m: Vec<f32>,
    /// [`LiveSample`] codes of the region, as in [`LiveRenderedFrame::live_valid`].
    pub live_valid: Vec<u8>,
}

impl LiveRegionFrame {
    /// Number of pixels of each kind: (valid, fallback).
    pub fn counts(&self) -> (usize, usize) {
        live_counts(&self.live_valid)
    }
}

/// Number of pixels of each kind among `codes`: (valid, fallback).
fn live_counts(codes: &[u8]) -> (usize, usize) {
    let valid = codes.iter().filter(|&&c| c == 255).count();
    let fallback = codes
        .iter()
        .filter(|&&c| LiveSample::from_code(c).is_fallback())
        .count();
    (valid, fallback)
}

/// The result of [`crate::Renderer::render_live`].
#[derive(Debug, Clone, PartialEq)]
pub struct LiveRenderedFrame {
    /// Colour and depth, as [`crate::Renderer::render`] returns them.
    pub frame: RenderedFrame,
    /// Per pixel (row-major from the top-left), the [`LiveSample`] code of the nearest
    /// surface: 255 = live sample, 1/2/3/4 = fallback (outside / back-facing / occluded /
    /// stretched),
    /// 0 = background or a draw without live texturing.
    pub live_valid: Vec<u8>,
}

impl LiveRenderedFrame {
    /// The sample kind of pixel (x, y), if inside.
    pub fn sample_at(&self, x: u32, y: u32) -> Option<LiveSample> {
        if x >= self.frame.width || y >= self.frame.height {
            return None;
        }
        self.live_valid
            .get(y as usize * self.frame.width as usize + x as usize)
            .map(|&c| LiveSample::from_code(c))
    }

    /// Number of pixels of each kind: (valid, fallback).
    pub fn counts(&self) -> (usize, usize) {
        live_counts(&self.live_valid)
    }
}
