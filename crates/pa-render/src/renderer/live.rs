//! Live texturing: [`Renderer::render_live`] colours the animated twin from the camera frame
//! (group 3: live uniforms, frame texture and sampler, visibility map); the formulas are in
//! the crate's `live` module.

use bytemuck::Zeroable;
use glam::Mat4;
use wgpu::util::DeviceExt;

use super::draw::{
    camera_clip_from_world, color_attachment, depth_attachment, lighting_uniforms, record_draw,
};
use super::frame::read_frame;
use super::{finite_mat, mat, CpuCamera, Draw, Lighting, RenderedFrame, Renderer};
use crate::error::RenderError;
use crate::live::{LiveDraw, LiveRegionFrame, LiveRenderedFrame, LiveTexturing};
use crate::pipeline::LiveUniforms;
use crate::readback::{self, LiveTargets, PixelRegion};

impl Renderer {
    /// Checks the live-texturing block of draw `i`.
    fn validate_live(
        &self,
        i: usize,
        d: &Draw<'_>,
        l: &LiveTexturing<'_>,
    ) -> Result<(), RenderError> {
        if l.frame.renderer_id != self.id {
            return Err(RenderError::ForeignResource {
                draw: i,
                what: "live frame texture",
            });
        }
        if let Some(v) = l.visibility {
            if v.renderer_id != self.id {
                return Err(RenderError::ForeignResource {
                    draw: i,
                    what: "visibility map",
                });
            }
        }
        self.validate_deformation(i, d.mesh, l.key_joint_matrices, l.key_morph_weights)?;
        if !l.memory.is_empty() && l.memory.len() != d.mesh.vertex_count() {
            return Err(RenderError::AttributeLength {
                attribute: format!("draw #{i}: live texture memory"),
                expected: d.mesh.vertex_count(),
                actual: l.memory.len(),
            });
        }
        if !l.sun_lit.is_empty() && l.sun_lit.len() != d.mesh.vertex_count() {
            return Err(RenderError::AttributeLength {
                attribute: format!("draw #{i}: live sun fraction"),
                expected: d.mesh.vertex_count(),
                actual: l.sun_lit.len(),
            });
        }
        let sun_finite = l.sun.is_none_or(|s| {
            s.toward_light.is_finite()
                && s.ambient_rgb
                    .iter()
                    .chain(&s.direct_rgb)
                    .all(|x| x.is_finite())
        });
        if !sun_finite || !l.sun_lit.iter().flatten().all(|x| x.is_finite()) {
            return Err(RenderError::NonFiniteDrawInput {
                draw: i,
                what: "live sun",
            });
        }
        if !l.memory.iter().flatten().all(|x| x.is_finite()) {
            return Err(RenderError::NonFiniteDrawInput {
                draw: i,
                what: "live texture memory",
            });
        }
        let finite_checks: [(&'static str, bool); 5] = [
            ("key_world_from_mesh", finite_mat(&l.key_world_from_mesh)),
            (
                "frame_camera.camera_from_world",
                finite_mat(&l.frame_camera.camera_from_world),
            ),
            (
                "frame_camera.distortion",
                [
                    l.frame_camera.distortion.k1,
                    l.frame_camera.distortion.k2,
                    l.frame_camera.distortion.p1,
                    l.frame_camera.distortion.p2,
                    l.frame_camera.distortion.k3,
                ]
                .iter()
                .all(|x| x.is_finite()),
            ),
            (
                "fallback_irradiance",
                l.fallback_irradiance
                    .iter()
                    .flatten()
                    .all(|x| x.is_finite()),
            ),
            (
                "live tolerances",
                [
                    l.depth_tolerance_rel,
                    l.depth_tolerance_m,
                    l.min_facing_cos,
                    l.max_stretch,
                ]
                .iter()
                .all(|x| x.is_finite()),
            ),
        ];
        for (what, ok) in finite_checks {
            if !ok {
                return Err(RenderError::NonFiniteDrawInput { draw: i, what });
            }
        }
        l.frame_camera
            .intrinsics
            .validate()
            .map_err(|e| RenderError::InvalidCamera(format!("draw #{i}: frame camera: {e}")))
    }

    /// Group 3 bind group of a draw of [`Renderer::render_live`].
    fn live_bind_group(
        &self,
        d: &Draw<'_>,
        live: Option<&LiveTexturing<'_>>,
    ) -> Result<wgpu::BindGroup, RenderError> {
        let device = &self.ctx.device;
        let mut u = LiveUniforms::zeroed();
        let (frame_view, visibility_view) = match live {
            None => (&self.white_texture.view, &self.empty_visibility_view),
            Some(l) => {
                let (fw, fh) = l.frame.size();
                let k = &l.frame_camera.intrinsics;
                let k = if (k.width, k.height) == (fw, fh) {
                    *k
                } else {
                    k.scaled_to(fw, fh)
                };
                let dist = &l.frame_camera.distortion;
                u.key_world_from_mesh = mat(&l.key_world_from_mesh);
                u.frame_camera_from_world = mat(&l.frame_camera.camera_from_world);
                u.visibility_from_frame_camera = mat(&Mat4::IDENTITY);
                u.frame_intrinsics = [k.fx as f32, k.fy as f32, k.cx as f32, k.cy as f32];
                u.frame_size = [fw as f32, fh as f32, 0.0, 0.0];
                u.distortion = [
                    dist.k1 as f32,
                    dist.k2 as f32,
                    dist.p1 as f32,
                    dist.p2 as f32,
                ];
                u.distortion_k3_tolerances = [
                    dist.k3 as f32,
                    l.min_facing_cos,
                    l.depth_tolerance_rel,
                    l.depth_tolerance_m,
                ];
                u.fallback_irradiance = l.fallback_irradiance;
                let g = l.grazing_rgb;
                u.grazing = [g[0], g[1], g[2], 0.0];
                u.stretch = [
                    l.max_stretch.max(0.0),
                    f32::from(u8::from(l.relight)),
                    f32::from(u8::from(l.feather)),
                    0.0,
                ];
                u.key_counts = [
                    d.joint_matrices.len() as u32,
                    l.key_joint_matrices.len() as u32,
                    d.morph_weights.len() as u32,
                    l.key_morph_weights.len() as u32,
                ];
                u.flags = [1, 0, 0, 0];
                let visibility_view = match l.visibility {
                    None => &self.empty_visibility_view,
                    Some(v) => {
                        let kv = &v.camera.intrinsics;
                        let kv = if (kv.width, kv.height) == (v.width, v.height) {
                            *kv
                        } else {
                            kv.scaled_to(v.width, v.height)
                        };
                        let vis_from_frame =
                            if v.camera.camera_from_world == l.frame_camera.camera_from_world {
                                Mat4::IDENTITY
                            } else {
                                (v.camera.camera_from_world.as_dmat4()
                                    * l.frame_camera.camera_from_world.as_dmat4().inverse())
                                .as_mat4()
                            };
                        if !finite_mat(&vis_from_frame) {
                            return Err(RenderError::InvalidCamera(
                                "frame camera pose is not invertible".to_owned(),
                            ));
                        }
                        u.visibility_from_frame_camera = mat(&vis_from_frame);
                        u.visibility_intrinsics =
                            [kv.fx as f32, kv.fy as f32, kv.cx as f32, kv.cy as f32];
                        u.visibility_size = [v.width as f32, v.height as f32, 0.0, 0.0];
                        u.flags[1] = 1;
                        &v.camera_z_view
                    }
                };
                (&l.frame.view, visibility_view)
            }
        };
        // Texture memory (one zero entry when the draw has none: a binding is never empty).
        let memory: &[[f32; 4]] = match live {
            Some(l) if !l.memory.is_empty() => {
                u.flags[2] = 1;
                l.memory
            }
            _ => &[[0.0; 4]],
        };
        let memory_buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("pa-render live memory"),
            contents: bytemuck::cast_slice(memory),
            usage: wgpu::BufferUsages::STORAGE,
        });
        // The sun and the fraction of it per vertex (one entry when the draw has none).
        let sun_lit: &[[f32; 2]] = match live.and_then(|l| l.sun.map(|s| (l, s))) {
            Some((l, sun)) => {
                u.flags[3] = 1;
                let t = sun.toward_light;
                u.sun_toward_light = [t.x, t.y, t.z, 0.0];
                u.sun_ambient = [
                    sun.ambient_rgb[0],
                    sun.ambient_rgb[1],
                    sun.ambient_rgb[2],
                    0.0,
                ];
                u.sun_direct = [sun.direct_rgb[0], sun.direct_rgb[1], sun.direct_rgb[2], 0.0];
                if l.sun_lit.is_empty() {
                    &[[1.0; 2]]
                } else {
                    l.sun_lit
                }
            }
            None => &[[1.0; 2]],
        };
        let sun_lit_buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("pa-render live sun"),
            contents: bytemuck::cast_slice(sun_lit),
            usage: wgpu::BufferUsages::STORAGE,
        });
        let uniform_buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("pa-render live uniforms"),
            contents: bytemuck::bytes_of(&u),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        Ok(device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("pa-render live bind group"),
            layout: &self.pipelines.live_layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: uniform_buffer.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: wgpu::BindingResource::TextureView(frame_view),
                },
                wgpu::BindGroupEntry {
                    binding: 2,
                    resource: wgpu::BindingResource::Sampler(&self.pipelines.frame_sampler),
                },
                wgpu::BindGroupEntry {
                    binding: 3,
                    resource: wgpu::BindingResource::TextureView(visibility_view),
                },
                wgpu::BindGroupEntry {
                    binding: 4,
                    resource: memory_buffer.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 5,
                    resource: sun_lit_buffer.as_entire_binding(),
                },
            ],
        }))
    }

    /// Like [`Renderer::render`], with live texturing: every [`LiveDraw`] with a
    /// [`LiveTexturing`] block takes its colours from the camera frame at the projection of
    /// the same surface point in the key pose (unlit), or its fallback colour where that
    /// sample is invalid; draws without one shade as in `render` (`lighting` applies to them
    /// only). Also reads back the per-pixel [`crate::LiveSample`] codes. See the `live` module
    /// docs for the math and the visibility test.
    pub fn render_live(
        &mut self,
        camera: &CpuCamera,
        lighting: Option<&Lighting>,
        draws: &[LiveDraw<'_>],
        clear_rgba: [f32; 4],
        width: u32,
        height: u32,
    ) -> Result<LiveRenderedFrame, RenderError> {
        let region = PixelRegion::full(width, height);
        let r =
            self.render_live_region(camera, lighting, draws, clear_rgba, width, height, region)?;
        Ok(LiveRenderedFrame {
            frame: RenderedFrame {
                width,
                height,
                rgba8: r.rgba8,
                depth_m: r.depth_m,
            },
            live_valid: r.live_valid,
        })
    }

    /// [`Renderer::render_live`] into a `width` x `height` target, reading back `region` of it
    /// only: the caller knows the draws cover nothing outside it (there the target holds
    /// `clear_rgba`, infinite depth and code 0). The transfer shrinks with the region, which
    /// on a discrete GPU is most of the frame's cost.
    #[allow(clippy::too_many_arguments)]
    pub fn render_live_region(
        &mut self,
        camera: &CpuCamera,
        lighting: Option<&Lighting>,
        draws: &[LiveDraw<'_>],
        clear_rgba: [f32; 4],
        width: u32,
        height: u32,
        region: PixelRegion,
    ) -> Result<LiveRegionFrame, RenderError> {
        self.check_render_size(width, height)?;
        region.check(width, height)?;
        if self.ctx.limits.max_color_attachments < 3 {
            return Err(RenderError::UnsupportedAdapter {
                details: format!(
                    "{} has {} colour attachments; live texturing needs 3",
                    self.adapter_info(),
                    self.ctx.limits.max_color_attachments
                ),
            });
        }
        let clip_from_world = camera_clip_from_world(camera, width, height)?;
        let light = lighting_uniforms(lighting)?;
        let clear = Self::clear_color(clear_rgba)?;
        for (i, ld) in draws.iter().enumerate() {
            self.validate_draw(i, &ld.draw)?;
            if let Some(l) = &ld.live {
                self.validate_live(i, &ld.draw, l)?;
            }
        }

        let device = &self.ctx.device;
        let validation = device.push_error_scope(wgpu::ErrorFilter::Validation);
        let oom = device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
        let targets = match self.live_targets.take() {
            Some(t) if t.base.width == width && t.base.height == height => t,
            _ => LiveTargets::new(device, width, height),
        };

        let mut bind_groups = Vec::with_capacity(draws.len());
        for ld in draws {
            let d = &ld.draw;
            let uniforms =
                Self::draw_uniforms(d, &clip_from_world, &camera.camera_from_world, &light);
            let (key_joints, key_weights) = match &ld.live {
                Some(l) => (l.key_joint_matrices, l.key_morph_weights),
                None => (&[][..], &[][..]),
            };
            let group1 = self.draw_bind_group_with_key(
                &uniforms,
                d.joint_matrices,
                d.morph_weights,
                key_joints,
                key_weights,
            );
            let group3 = self.live_bind_group(d, ld.live.as_ref())?;
            bind_groups.push((group1, group3));
        }

        let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("pa-render live frame"),
        });
        {
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("pa-render live pass"),
                color_attachments: &[
                    Some(color_attachment(&targets.base.color_view, clear)),
                    Some(color_attachment(
                        &targets.base.camera_z_view,
                        wgpu::Color::TRANSPARENT,
                    )),
                    Some(color_attachment(
                        &targets.code_view,
                        wgpu::Color::TRANSPARENT,
                    )),
                ],
                depth_stencil_attachment: Some(depth_attachment(&targets.base.depth_view)),
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            });
            pass.set_pipeline(&self.pipelines.live);
            for (ld, (group1, group3)) in draws.iter().zip(&bind_groups) {
                pass.set_bind_group(3, group3, &[]);
                record_draw(&mut pass, &ld.draw, group1, &self.white_texture);
            }
        }
        targets.record_copies(&mut encoder, region);
        self.ctx.queue.submit([encoder.finish()]);

        let oom = pollster::block_on(oom.pop());
        let validation = pollster::block_on(validation.pop());
        if let Some(e) = validation.or(oom) {
            return Err(RenderError::Gpu {
                during: "live render",
                message: e.to_string(),
            });
        }

        let frame = read_frame(device, &targets.base, region, &mut self.readback_times)?;
        let codes = readback::read_buffers(
            device,
            &[(&targets.code_readback, readback::region_bytes(region, 1))],
            &mut self.readback_times,
        )?;
        let t_unpad = std::time::Instant::now();
        let padded = readback::padded_bytes_per_row_of(region.width, 1) as usize;
        let live_valid = codes
            .first()
            .map(|c| readback::unpad_rows(c, region.width as usize, padded, region.height as usize))
            .unwrap_or_default();
        self.readback_times.copy_ms += readback::ms_since(t_unpad);
        self.live_targets = Some(targets);
        Ok(LiveRegionFrame {
            region,
            target_size: (width, height),
            rgba8: frame.rgba8,
            depth_m: frame.depth_m,
            live_valid,
        })
    }
}
