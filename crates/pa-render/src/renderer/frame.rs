//! The main pass: [`Renderer::render`] draws lit or unlit meshes and reads back colour and
//! camera-space depth ([`RenderedFrame`]).

use super::draw::{
    camera_clip_from_world, color_attachment, depth_attachment, lighting_uniforms, record_draw,
};
use super::{CpuCamera, Draw, Lighting, RenderedFrame, Renderer};
use crate::error::RenderError;
use crate::readback::{self, PixelRegion, ReadbackTimes, Targets};

impl Renderer {
    /// Renders `draws` seen by `camera` into a `width` x `height` image and reads back colour
    /// (sRGB RGBA8) and camera-space depth. `clear_rgba` is the background in linear RGB with
    /// straight alpha (alpha 0 for compositing). `lighting: None` renders unlit.
    pub fn render(
        &mut self,
        camera: &CpuCamera,
        lighting: Option<&Lighting>,
        draws: &[Draw<'_>],
        clear_rgba: [f32; 4],
        width: u32,
        height: u32,
    ) -> Result<RenderedFrame, RenderError> {
        self.check_render_size(width, height)?;
        let clip_from_world = camera_clip_from_world(camera, width, height)?;
        let light = lighting_uniforms(lighting)?;
        let clear = Self::clear_color(clear_rgba)?;

        // Validate everything before touching the GPU.
        for (i, d) in draws.iter().enumerate() {
            self.validate_draw(i, d)?;
        }

        let device = &self.ctx.device;
        let validation = device.push_error_scope(wgpu::ErrorFilter::Validation);
        let oom = device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);

        // Reuse the targets while the size does not change; they are put back on success only
        // (a failed frame may leave a readback buffer mapped).
        let targets = match self.targets.take() {
            Some(t) if t.width == width && t.height == height => t,
            _ => Targets::new(device, width, height),
        };

        let bind_groups: Vec<wgpu::BindGroup> = draws
            .iter()
            .map(|d| {
                let uniforms =
                    Self::draw_uniforms(d, &clip_from_world, &camera.camera_from_world, &light);
                self.draw_bind_group(&uniforms, d.joint_matrices, d.morph_weights)
            })
            .collect();

        let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("pa-render frame"),
        });
        {
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("pa-render main pass"),
                color_attachments: &[
                    Some(color_attachment(&targets.color_view, clear)),
                    // Bits 0 = 0.0 = nothing drawn (drawn surfaces have z >= near > 0).
                    Some(color_attachment(
                        &targets.camera_z_view,
                        wgpu::Color::TRANSPARENT,
                    )),
                ],
                depth_stencil_attachment: Some(depth_attachment(&targets.depth_view)),
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            });
            pass.set_pipeline(&self.pipelines.render);
            for (d, bind_group) in draws.iter().zip(&bind_groups) {
                record_draw(&mut pass, d, bind_group, &self.white_texture);
            }
        }
        let region = PixelRegion::full(width, height);
        targets.record_copies(&mut encoder, region);
        self.ctx.queue.submit([encoder.finish()]);

        let oom = pollster::block_on(oom.pop());
        let validation = pollster::block_on(validation.pop());
        if let Some(e) = validation.or(oom) {
            return Err(RenderError::Gpu {
                during: "render",
                message: e.to_string(),
            });
        }

        let frame = read_frame(device, &targets, region, &mut self.readback_times)?;
        self.targets = Some(targets);
        Ok(frame)
    }
}

/// Maps the colour and camera-z readback buffers of `targets` (copies of `region` already
/// submitted): a frame of the region's size.
pub(super) fn read_frame(
    device: &wgpu::Device,
    targets: &Targets,
    region: PixelRegion,
    times: &mut ReadbackTimes,
) -> Result<RenderedFrame, RenderError> {
    let (width, height) = (region.width, region.height);
    let data = readback::read_buffers(
        device,
        &[
            (&targets.color_readback, readback::region_bytes(region, 4)),
            (
                &targets.camera_z_readback,
                readback::region_bytes(region, 4),
            ),
        ],
        times,
    );
    let t_unpad = std::time::Instant::now();
    let (color, camera_z) = match data.as_deref() {
        Ok([color, camera_z]) => (color, camera_z),
        _ => {
            return Err(data.err().unwrap_or_else(|| {
                RenderError::Readback("unexpected readback buffer count".to_owned())
            }));
        }
    };
    let row = width as usize * 4;
    let padded_row = readback::padded_bytes_per_row(width) as usize;
    let rgba8 = readback::unpad_rows(color, row, padded_row, height as usize);
    let depth_m = readback::unpad_rows(camera_z, row, padded_row, height as usize)
        .chunks_exact(4)
        .map(|b| {
            let z = f32::from_ne_bytes([b[0], b[1], b[2], b[3]]);
            if z > 0.0 && z.is_finite() {
                z
            } else {
                f32::INFINITY
            }
        })
        .collect();
    times.copy_ms += readback::ms_since(t_unpad);
    Ok(RenderedFrame {
        width,
        height,
        rgba8,
        depth_m,
    })
}
