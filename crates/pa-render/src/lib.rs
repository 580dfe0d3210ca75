//! Headless wgpu renderer of Props Alive, with GPU linear blend skinning and morph targets.
//!
//! # Shape
//!
//! Following re_renderer: a long-lived [`Renderer`] (device, queue, pipelines, cached render
//! targets) and per-frame inputs. `Cpu*` types are what callers fill on the CPU; `Gpu*` types
//! are uploaded once by the renderer and referenced by every frame's [`Draw`]s.
//!
//! ```no_run
//! # use pa_render::*;
//! # fn demo(mesh: &CpuMesh, camera: &CpuCamera) -> Result<(), RenderError> {
//! let mut renderer = Renderer::new()?;
//! let gpu_mesh = renderer.upload_mesh(mesh)?;
//! let draw = Draw::new(&gpu_mesh, glam::Mat4::IDENTITY);
//! let frame = renderer.render(camera, None, &[draw], [0.0; 4], 640, 480)?;
//! assert_eq!(frame.rgba8.len(), 640 * 480 * 4);
//! # Ok(()) }
//! ```
//!
//! # Conventions
//!
//! * Cameras use OpenCV axes and intrinsics ([`pa_camera::Intrinsics`], pixel centres at
//!   integer coordinates); `pa_camera::Intrinsics::clip_from_camera` maps them to wgpu clip
//!   space, so a point projecting to pixel (u, v) covers the centre of pixel (u, v).
//! * Transforms are `target_from_source` (`world_from_mesh`, `camera_from_world`).
//! * Colours: textures are sRGB RGBA8, `base_color_factor` and lights are linear, output is
//!   sRGB RGBA8 (no blending: alpha is written as is), plus camera-space depth in metres.
//!
//! # GPU skinning
//!
//! Skinning and morphing run in the vertex stage (vertex pulling from storage buffers), with
//! the same WGSL function (`shaders/skinning.wgsl`) that the compute entry point behind
//! [`Renderer::skin_positions_gpu`] runs, so tests can compare the GPU against a CPU
//! reference. Up to 8 influences per vertex, [`MAX_JOINTS`] joints per draw,
//! [`MAX_MORPH_TARGETS`] morph targets per mesh.
//!
//! # Live texturing
//!
//! [`Renderer::render_live`] colours the animated twin from the current camera frame at the
//! projection (with lens distortion) of the same surface point in the key pose, with a
//! key-pose visibility map ([`Renderer::render_visibility`]) deciding where the live sample
//! is valid and a fallback elsewhere; see the [`live`] module for the formulas.
//!
//! ```no_run
//! # use pa_render::*;
//! # fn demo(r: &mut Renderer, mesh: &GpuMesh, tex: &GpuTexture, camera: &CpuCamera,
//! #         image: &CpuTexture, key: &[glam::Mat4], now: &[glam::Mat4])
//! #         -> Result<(), RenderError> {
//! let frame = r.upload_frame(image)?; // later frames: r.update_texture(&frame, image)?
//! let frame_camera = LiveCamera::from_render_camera(camera, pa_camera::Distortion::default());
//! let mut draw = Draw::new(mesh, glam::Mat4::IDENTITY);
//! draw.texture = Some(tex);
//! draw.joint_matrices = key;
//! let visibility = r.render_visibility(camera, &[draw], 640, 480)?;
//! draw.joint_matrices = now;
//! let live = LiveTexturing::new(&frame, frame_camera, glam::Mat4::IDENTITY)
//!     .with_key_pose(key, &[])
//!     .with_visibility(&visibility);
//! let out = r.render_live(camera, None, &[draw.with_live(live)], [0.0; 4], 640, 480)?;
//! assert_eq!(out.live_valid.len(), 640 * 480);
//! # Ok(()) }
//! ```
//!
//! # Backends
//!
//! `WGPU_BACKEND` selects the backend (`vulkan`, `gl`); without a GPU, Mesa's lavapipe
//! (Vulkan) or llvmpipe (GL) work. Adapters lacking storage buffers in the vertex stage are
//! rejected with [`RenderError::UnsupportedAdapter`]; with no adapter at all,
//! [`RenderError::NoAdapter`] says what to install.

mod context;
mod error;
pub mod live;
mod mesh;
mod pipeline;
mod readback;
mod renderer;
mod texture;

pub use context::adapter_rank;
pub use error::{RenderError, NO_ADAPTER_HINT};
pub use live::{
    GpuVisibility, LiveCamera, LiveDraw, LiveRegionFrame, LiveRenderedFrame, LiveSample,
    LiveTexturing,
};
pub use mesh::{CpuMesh, GpuMesh, MAX_MORPH_TARGETS};
pub use readback::{PixelRegion, ReadbackTimes};
pub use renderer::{
    CpuCamera, DirectionalLight, Draw, Lighting, RenderedFrame, Renderer, SkinnedVertices,
    MAX_JOINTS, MAX_RENDER_SIDE,
};
pub use texture::{CpuTexture, GpuTexture};

/// Re-exported so callers can name [`CpuCamera::intrinsics`] without another dependency.
pub use pa_camera::Intrinsics;
