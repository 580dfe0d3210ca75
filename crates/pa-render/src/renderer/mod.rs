//! The long-lived [`Renderer`]: device, queue, pipelines, the resources every draw shares (a
//! white texture, an empty visibility map), uploads, and the render targets cached between
//! frames. As in re_renderer, the long-lived state stays apart from the per-frame draw data,
//! and each draw type adds its own `impl Renderer` block over this one context:
//!
//! * `draw_data`: the per-frame inputs ([`CpuCamera`], [`Lighting`], [`Draw`]) and outputs
//!   ([`RenderedFrame`], [`SkinnedVertices`]);
//! * `draw`: what the draw types share: validating a draw, its group 1 bind group and
//!   uniforms, recording an indexed draw, the camera and lighting uniforms;
//! * `frame`: the main pass ([`Renderer::render`]) and reading a frame back;
//! * `visibility`: the key-pose visibility map ([`Renderer::render_visibility`],
//!   [`Renderer::update_visibility`], [`Renderer::read_visibility`]);
//! * `live`: live texturing ([`Renderer::render_live`]);
//! * `skinning`: the compute pass of skinning read back ([`Renderer::skin_gpu`]).

mod draw;
mod draw_data;
mod frame;
mod live;
mod skinning;
mod visibility;

pub use draw_data::{CpuCamera, DirectionalLight, Draw, Lighting, RenderedFrame, SkinnedVertices};

use std::sync::atomic::{AtomicU64, Ordering};

use glam::Mat4;

use crate::context::{describe, GpuContext};
use crate::error::RenderError;
use crate::mesh::{self, CpuMesh, GpuMesh};
use crate::pipeline::{Pipelines, CAMERA_Z_FORMAT};
use crate::readback::{self, LiveTargets, PixelRegion, ReadbackTimes, Targets};
use crate::texture::{self, CpuTexture, GpuTexture};

/// Most joint matrices per draw.
pub const MAX_JOINTS: usize = 4096;
/// Largest render target side in pixels (further bounded by the device limit).
pub const MAX_RENDER_SIDE: u32 = 16_384;

static NEXT_RENDERER_ID: AtomicU64 = AtomicU64::new(1);

/// A headless renderer: device, queue, pipelines, and cached render targets.
pub struct Renderer {
    id: u64,
    ctx: GpuContext,
    pipelines: Pipelines,
    white_texture: GpuTexture,
    /// 1x1 empty R32Uint map bound as the visibility map of draws without one.
    empty_visibility_view: wgpu::TextureView,
    targets: Option<Targets>,
    live_targets: Option<LiveTargets>,
    /// Cumulative readback timings (for benchmarks).
    readback_times: ReadbackTimes,
}

fn mat(m: &Mat4) -> [[f32; 4]; 4] {
    m.to_cols_array_2d()
}

fn finite_mat(m: &Mat4) -> bool {
    m.to_cols_array().iter().all(|x| x.is_finite())
}

impl Renderer {
    /// Creates the device (honouring `WGPU_BACKEND` and `WGPU_ADAPTER_NAME`) and pipelines.
    pub fn new() -> Result<Self, RenderError> {
        let ctx = GpuContext::new()?;
        let scope = ctx.device.push_error_scope(wgpu::ErrorFilter::Validation);
        let pipelines = Pipelines::new(&ctx.device);
        let id = NEXT_RENDERER_ID.fetch_add(1, Ordering::Relaxed);
        let white_texture = texture::upload(
            &ctx.device,
            &ctx.queue,
            ctx.limits.max_texture_dimension_2d,
            &pipelines.texture_layout,
            &pipelines.sampler,
            id,
            &CpuTexture::solid(1, 1, [255; 4]),
            true,
        )?;
        let empty_visibility_view = ctx
            .device
            .create_texture(&wgpu::TextureDescriptor {
                label: Some("pa-render empty visibility map"),
                size: wgpu::Extent3d {
                    width: 1,
                    height: 1,
                    depth_or_array_layers: 1,
                },
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format: CAMERA_Z_FORMAT,
                usage: wgpu::TextureUsages::TEXTURE_BINDING,
                view_formats: &[],
            })
            .create_view(&Default::default());
        if let Some(e) = pollster::block_on(scope.pop()) {
            return Err(RenderError::Gpu {
                during: "pipeline creation",
                message: e.to_string(),
            });
        }
        Ok(Self {
            id,
            ctx,
            pipelines,
            white_texture,
            empty_visibility_view,
            targets: None,
            live_targets: None,
            readback_times: ReadbackTimes::default(),
        })
    }

    /// Adapter name, backend, device type and driver, for logs.
    pub fn adapter_info(&self) -> String {
        describe(&self.ctx.info)
    }

    /// True when the adapter is a software rasteriser (Mesa llvmpipe / lavapipe, WARP): the
    /// pipeline's own CPU path is then faster than this renderer.
    pub fn is_software(&self) -> bool {
        self.ctx.info.device_type == wgpu::DeviceType::Cpu
    }

    /// The wgpu backend in use.
    pub fn backend(&self) -> wgpu::Backend {
        self.ctx.info.backend
    }

    /// Cumulative time this renderer spent reading results back from the GPU since it was
    /// created: waiting for submitted work, and copying the mapped buffers out. Take two
    /// snapshots and [`ReadbackTimes::since`] to time a piece of work.
    pub fn readback_times(&self) -> ReadbackTimes {
        self.readback_times
    }

    /// Largest accepted render width/height.
    pub fn max_render_side(&self) -> u32 {
        self.ctx
            .limits
            .max_texture_dimension_2d
            .min(MAX_RENDER_SIDE)
    }

    /// Validates and uploads a mesh (once; draw it every frame).
    pub fn upload_mesh(&mut self, mesh: &CpuMesh) -> Result<GpuMesh, RenderError> {
        let scope = self
            .ctx
            .device
            .push_error_scope(wgpu::ErrorFilter::OutOfMemory);
        let result = mesh::upload(
            &self.ctx.device,
            &self.ctx.limits,
            &self.pipelines.mesh_layout,
            self.id,
            mesh,
        );
        self.pop_scope(scope, "mesh upload")?;
        result
    }

    /// Validates and uploads a texture (with a mip chain built on the CPU).
    pub fn upload_texture(&mut self, texture: &CpuTexture) -> Result<GpuTexture, RenderError> {
        let scope = self
            .ctx
            .device
            .push_error_scope(wgpu::ErrorFilter::OutOfMemory);
        let result = texture::upload(
            &self.ctx.device,
            &self.ctx.queue,
            self.ctx.limits.max_texture_dimension_2d,
            &self.pipelines.texture_layout,
            &self.pipelines.sampler,
            self.id,
            texture,
            true,
        );
        self.pop_scope(scope, "texture upload")?;
        result
    }

    /// Uploads a camera frame for live texturing: one mip level (sampled bilinearly at level
    /// 0 with clamp-to-edge by [`Renderer::render_live`]). Refresh it every frame with
    /// [`Renderer::update_texture`] rather than uploading anew.
    pub fn upload_frame(&mut self, frame: &CpuTexture) -> Result<GpuTexture, RenderError> {
        let scope = self
            .ctx
            .device
            .push_error_scope(wgpu::ErrorFilter::OutOfMemory);
        let result = texture::upload(
            &self.ctx.device,
            &self.ctx.queue,
            self.ctx.limits.max_texture_dimension_2d,
            &self.pipelines.texture_layout,
            &self.pipelines.sampler,
            self.id,
            frame,
            false,
        );
        self.pop_scope(scope, "frame upload")?;
        result
    }

    /// Overwrites the contents of `texture` (from [`Renderer::upload_frame`] or
    /// [`Renderer::upload_texture`]; the mip chain, if any, is rebuilt on the CPU) with `data`
    /// of the same size. No GPU allocation: the per-frame path for camera frames.
    pub fn update_texture(
        &mut self,
        texture: &GpuTexture,
        data: &CpuTexture,
    ) -> Result<(), RenderError> {
        if texture.renderer_id != self.id {
            return Err(RenderError::ForeignResource {
                draw: 0,
                what: "texture",
            });
        }
        data.validate(self.ctx.limits.max_texture_dimension_2d)?;
        if (data.width, data.height) != (texture.width, texture.height) {
            return Err(RenderError::TextureSizeMismatch {
                expected: (texture.width, texture.height),
                actual: (data.width, data.height),
            });
        }
        texture::write_levels(&self.ctx.queue, &texture.texture, data);
        Ok(())
    }

    /// Overwrites `region` of a camera-frame texture (from [`Renderer::upload_frame`]: one
    /// mip level) with that region of `rgba8`, a whole `width` x `height` sRGB RGBA8 frame of
    /// the texture's size; the rest of the texture keeps its earlier contents. Only the
    /// region's rows travel: the per-frame path when the caller knows which pixels the live
    /// samples can reach.
    pub fn update_frame_region(
        &mut self,
        texture: &GpuTexture,
        rgba8: &[u8],
        width: u32,
        height: u32,
        region: PixelRegion,
    ) -> Result<(), RenderError> {
        if texture.renderer_id != self.id {
            return Err(RenderError::ForeignResource {
                draw: 0,
                what: "texture",
            });
        }
        if (width, height) != (texture.width, texture.height) {
            return Err(RenderError::TextureSizeMismatch {
                expected: (texture.width, texture.height),
                actual: (width, height),
            });
        }
        let expected = width as usize * height as usize * 4;
        if rgba8.len() != expected {
            return Err(RenderError::TextureDataLength {
                width,
                height,
                expected,
                actual: rgba8.len(),
            });
        }
        region.check(width, height)?;
        if texture.mip_level_count() != 1 {
            return Err(RenderError::Gpu {
                during: "frame region update",
                message: "the texture has a mip chain; use update_texture".to_owned(),
            });
        }
        self.ctx.queue.write_texture(
            wgpu::TexelCopyTextureInfo {
                texture: &texture.texture,
                mip_level: 0,
                origin: wgpu::Origin3d {
                    x: region.x,
                    y: region.y,
                    z: 0,
                },
                aspect: wgpu::TextureAspect::All,
            },
            rgba8,
            wgpu::TexelCopyBufferLayout {
                offset: (u64::from(region.y) * u64::from(width) + u64::from(region.x)) * 4,
                bytes_per_row: Some(4 * width),
                rows_per_image: Some(height),
            },
            wgpu::Extent3d {
                width: region.width,
                height: region.height,
                depth_or_array_layers: 1,
            },
        );
        Ok(())
    }

    fn pop_scope(
        &self,
        scope: wgpu::ErrorScopeGuard,
        during: &'static str,
    ) -> Result<(), RenderError> {
        match pollster::block_on(scope.pop()) {
            None => Ok(()),
            Some(e) => Err(RenderError::Gpu {
                during,
                message: e.to_string(),
            }),
        }
    }

    /// Checks a render target size against the device limits.
    fn check_render_size(&self, width: u32, height: u32) -> Result<(), RenderError> {
        let max = self.max_render_side();
        let padded_row = u64::from(readback::padded_bytes_per_row(width));
        if width == 0
            || height == 0
            || width > max
            || height > max
            || padded_row * u64::from(height) > self.ctx.limits.max_buffer_size
        {
            return Err(RenderError::InvalidRenderSize { width, height, max });
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn assert_send_sync<T: Send + Sync>() {}

    #[test]
    fn types_cross_threads() {
        assert_send_sync::<Renderer>();
        assert_send_sync::<GpuMesh>();
        assert_send_sync::<GpuTexture>();
        assert_send_sync::<RenderError>();
    }
}
