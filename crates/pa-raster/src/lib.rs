//! `pa-raster`: the CPU path of the texture stage. A small software rasteriser that renders
//! the animated twin textured from the live camera frame, the key-pose visibility map and the
//! key-pose silhouette, with the same math as `pa-render`'s GPU shaders (`live.wgsl`), so the
//! pipeline can run either and the two can be compared (`propsalive bench`).
//!
//! Why: on a machine without a GPU, wgpu runs on Mesa's software rasterisers, which pay for a
//! whole frame-sized pipeline (clears, three passes, read-back) to draw a prop that covers a
//! few percent of the frame. Here the work is proportional to the prop: triangle set-up per
//! triangle, then only the pixels the prop covers.
//!
//! - [`raster`]: triangle set-up and the visibility buffer (conventions table there).
//! - [`live`]: the per-fragment live-texturing look-up (codes as `pa_render::LiveSample`).
//! - [`memory`]: texture memory, the key prop's remembered colour per key-pose vertex.
//! - [`look`]: how a live sample becomes the twin's colour: relighting at the animated
//!   normal and the feathered seam weight.
//! - [`texture`]: mip-mapped base-colour textures and the camera-frame sampler, in linear light.
//! - [`renderer`]: [`CpuRenderer`], long-lived buffers and the per-frame passes; `shade`,
//!   its fragment stage (the twin's colour per covered pixel, a few pixels at a time).
//! - [`mesh`]: closed, outward meshes, whose back faces can be culled without changing the
//!   image.
//! - [`sun`]: the set's sun with the twin's own cast shadows (a shadow map along the light),
//!   for relighting and the fallback.
//! - [`srgb`]: the sRGB transfer functions as tables.
//!
//! Architecture invariant: depends on `pa-camera` only (no wgpu, no glTF types); callers pose
//! the meshes (`pa-model`'s CPU skinning) and pass plain slices.

pub mod error;
pub mod live;
pub mod live_lanes;
pub mod look;
pub mod memory;
pub mod mesh;
pub mod raster;
pub mod renderer;
mod shade;
pub mod srgb;
pub mod sun;
pub mod texture;

pub use error::RasterError;
pub use live::{code, FrameCamera, LiveParams};
pub use raster::{PixelRect, RasterCamera, TriSetup, VisBuffer, NO_TRIANGLE};
pub use renderer::{CpuDepthMesh, CpuLiveMesh, CpuPosedMesh, CpuRenderer, CpuTwinImage, Shading};
pub use texture::{CpuMipTexture, FrameSampler};
