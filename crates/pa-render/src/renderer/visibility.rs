//! The key-pose visibility map of live texturing ([`GpuVisibility`]): rendered, re-rendered
//! in place and read back by the [`Renderer`].

use super::draw::{
    camera_clip_from_world, color_attachment, depth_attachment, lighting_uniforms, record_draw,
};
use super::{CpuCamera, Draw, Renderer};
use crate::error::RenderError;
use crate::live::GpuVisibility;
use crate::pipeline::{CAMERA_Z_FORMAT, DEPTH_FORMAT};
use crate::readback::{self, PixelRegion};

impl Renderer {
    /// Renders the key-pose visibility map: the camera-space z of the nearest surface of
    /// `draws` seen by `camera` (pinhole: rasterisation has no lens distortion; the map is
    /// looked up with the undistorted projection), `width` x `height` texels, kept on the GPU
    /// for [`LiveTexturing::visibility`](crate::LiveTexturing::visibility). `draws` are
    /// normally the key poses of the live draws
    /// ([`LiveDraw::key_pose_draw`](crate::LiveDraw::key_pose_draw)) plus any real occluder,
    /// and `camera` the frame camera (same pose and intrinsics; its near/far clip the map).
    pub fn render_visibility(
        &mut self,
        camera: &CpuCamera,
        draws: &[Draw<'_>],
        width: u32,
        height: u32,
    ) -> Result<GpuVisibility, RenderError> {
        self.check_render_size(width, height)?;
        let device = &self.ctx.device;
        let scope = device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
        let size = wgpu::Extent3d {
            width,
            height,
            depth_or_array_layers: 1,
        };
        let make = |label, format, usage| {
            device.create_texture(&wgpu::TextureDescriptor {
                label: Some(label),
                size,
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format,
                usage,
                view_formats: &[],
            })
        };
        let camera_z = make(
            "pa-render visibility map",
            CAMERA_Z_FORMAT,
            wgpu::TextureUsages::RENDER_ATTACHMENT
                | wgpu::TextureUsages::TEXTURE_BINDING
                | wgpu::TextureUsages::COPY_SRC,
        );
        let depth = make(
            "pa-render visibility depth buffer",
            DEPTH_FORMAT,
            wgpu::TextureUsages::RENDER_ATTACHMENT,
        );
        self.pop_scope(scope, "visibility map allocation")?;
        let mut visibility = GpuVisibility {
            renderer_id: self.id,
            width,
            height,
            camera: *camera,
            camera_z_view: camera_z.create_view(&Default::default()),
            camera_z,
            depth_view: depth.create_view(&Default::default()),
            readback: None,
        };
        self.update_visibility(&mut visibility, camera, draws)?;
        Ok(visibility)
    }

    /// Re-renders an existing visibility map (same size, no allocation) for a new camera pose
    /// or key pose. See [`Renderer::render_visibility`].
    pub fn update_visibility(
        &mut self,
        visibility: &mut GpuVisibility,
        camera: &CpuCamera,
        draws: &[Draw<'_>],
    ) -> Result<(), RenderError> {
        if visibility.renderer_id != self.id {
            return Err(RenderError::ForeignResource {
                draw: 0,
                what: "visibility map",
            });
        }
        let (width, height) = (visibility.width, visibility.height);
        let clip_from_world = camera_clip_from_world(camera, width, height)?;
        for (i, d) in draws.iter().enumerate() {
            self.validate_draw(i, d)?;
        }
        let light = lighting_uniforms(None)?;
        let device = &self.ctx.device;
        let validation = device.push_error_scope(wgpu::ErrorFilter::Validation);
        let bind_groups: Vec<wgpu::BindGroup> = draws
            .iter()
            .map(|d| {
                let uniforms =
                    Self::draw_uniforms(d, &clip_from_world, &camera.camera_from_world, &light);
                self.draw_bind_group(&uniforms, d.joint_matrices, d.morph_weights)
            })
            .collect();
        let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("pa-render visibility"),
        });
        {
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("pa-render visibility pass"),
                color_attachments: &[Some(color_attachment(
                    &visibility.camera_z_view,
                    wgpu::Color::TRANSPARENT,
                ))],
                depth_stencil_attachment: Some(depth_attachment(&visibility.depth_view)),
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            });
            pass.set_pipeline(&self.pipelines.visibility);
            for (d, bind_group) in draws.iter().zip(&bind_groups) {
                record_draw(&mut pass, d, bind_group, &self.white_texture);
            }
        }
        self.ctx.queue.submit([encoder.finish()]);
        self.pop_scope(validation, "visibility map")?;
        visibility.camera = *camera;
        Ok(())
    }

    /// Reads a visibility map back: per texel (row-major from the top-left), the camera-space z
    /// (metres) of the nearest surface, `f32::INFINITY` where empty. One map instead of a
    /// second render when the caller also needs the key-pose silhouette on the CPU.
    pub fn read_visibility(
        &mut self,
        visibility: &mut GpuVisibility,
    ) -> Result<Vec<f32>, RenderError> {
        let region = PixelRegion::full(visibility.width, visibility.height);
        self.read_visibility_region(visibility, region)
    }

    /// [`Renderer::read_visibility`] of `region` of the map only (row-major from the region's
    /// top-left): the caller knows the key pose covers nothing outside it.
    pub fn read_visibility_region(
        &mut self,
        visibility: &mut GpuVisibility,
        region: PixelRegion,
    ) -> Result<Vec<f32>, RenderError> {
        if visibility.renderer_id != self.id {
            return Err(RenderError::ForeignResource {
                draw: 0,
                what: "visibility map",
            });
        }
        let (width, height) = (visibility.width, visibility.height);
        region.check(width, height)?;
        let device = &self.ctx.device;
        let buffer = visibility.readback.get_or_insert_with(|| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("pa-render visibility readback"),
                size: u64::from(readback::padded_bytes_per_row(width)) * u64::from(height),
                usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
                mapped_at_creation: false,
            })
        });
        let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("pa-render visibility readback"),
        });
        readback::record_region_copy(&mut encoder, &visibility.camera_z, buffer, 4, region);
        self.ctx.queue.submit([encoder.finish()]);
        let data = readback::read_buffers(
            device,
            &[(buffer, readback::region_bytes(region, 4))],
            &mut self.readback_times,
        );
        let t = std::time::Instant::now();
        let bytes = match data.as_deref() {
            Ok([bytes]) => readback::unpad_rows(
                bytes,
                region.width as usize * 4,
                readback::padded_bytes_per_row(region.width) as usize,
                region.height as usize,
            ),
            _ => {
                return Err(data.err().unwrap_or_else(|| {
                    RenderError::Readback("unexpected readback buffer count".to_owned())
                }))
            }
        };
        let depth = bytes
            .chunks_exact(4)
            .map(|b| {
                let z = f32::from_bits(u32::from_ne_bytes([b[0], b[1], b[2], b[3]]));
                if z > 0.0 && z.is_finite() {
                    z
                } else {
                    f32::INFINITY
                }
            })
            .collect();
        self.readback_times.copy_ms += readback::ms_since(t);
        Ok(depth)
    }
}
