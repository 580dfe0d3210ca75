//! The long-lived [`Renderer`] and the per-frame inputs ([`CpuCamera`], [`Lighting`],
//! [`Draw`]) and output ([`RenderedFrame`]).

use std::sync::atomic::{AtomicU64, Ordering};

use bytemuck::Zeroable;
use glam::Mat4;
use wgpu::util::DeviceExt;

use crate::context::{describe, GpuContext};
use crate::error::RenderError;
use crate::live::{GpuVisibility, LiveDraw, LiveRenderedFrame, LiveTexturing};
use crate::mesh::{self, CpuMesh, GpuMesh};
use crate::pipeline::{
    DrawUniforms, LiveUniforms, Pipelines, CAMERA_Z_FORMAT, DEPTH_FORMAT, SKIN_WORKGROUP_SIZE,
};
use crate::readback::{self, LiveTargets, ReadbackTimes, Targets};
use crate::texture::{self, CpuTexture, GpuTexture};

/// Most joint matrices per draw.
pub const MAX_JOINTS: usize = 4096;
/// Largest render target side in pixels (further bounded by the device limit).
pub const MAX_RENDER_SIDE: u32 = 16_384;

static NEXT_RENDERER_ID: AtomicU64 = AtomicU64::new(1);

/// The camera of a frame: OpenCV pinhole intrinsics and pose.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CpuCamera {
    /// Intrinsics; when the render size differs from `intrinsics.width` x `height`, they are
    /// rescaled to the render size with [`pa_camera::Intrinsics::scaled_to`].
    pub intrinsics: pa_camera::Intrinsics,
    /// OpenCV camera axes (x right, y down, z forward), metres.
    pub camera_from_world: Mat4,
    /// Near clip distance along camera z, metres (> 0).
    pub near_m: f32,
    /// Far clip distance along camera z, metres (> near).
    pub far_m: f32,
}

/// A directional light (e.g. the sun, or a key light far away).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DirectionalLight {
    /// Direction from the surface toward the light, world space (normalised internally).
    pub toward_light_world: glam::Vec3,
    /// Linear RGB radiance scale.
    pub radiance_rgb: [f32; 3],
}

/// Lambertian lighting: colour = albedo * (ambient + max(0, n . l) * radiance).
/// Pass `None` to `render` for unlit output (colour = albedo exactly).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Lighting {
    /// Linear RGB ambient term.
    pub ambient_rgb: [f32; 3],
    /// Optional directional light.
    pub directional: Option<DirectionalLight>,
}

/// One mesh to draw in a frame.
///
/// Albedo = `base_color_factor` (linear RGBA) * texture sample (sRGB decoded), white when
/// there is no texture. Triangles are double-sided (no backface culling); lighting flips the
/// normal on the back side.
#[derive(Debug, Clone, Copy)]
pub struct Draw<'a> {
    pub mesh: &'a GpuMesh,
    pub texture: Option<&'a GpuTexture>,
    pub base_color_factor: [f32; 4],
    /// Used for rigid draws (empty `joint_matrices`) only: glTF ignores the transform of a
    /// skinned mesh's node.
    pub world_from_mesh: Mat4,
    /// `joint_matrices[j] = world_from_joint[j] * inverse_bind_matrix[j]`. Empty: rigid draw
    /// with `world_from_mesh` (for a skinned mesh this draws the bind pose). Non-empty: world
    /// position = `sum_i w_i * joint_matrices[j_i] * p`.
    pub joint_matrices: &'a [Mat4],
    /// Morph target weights, applied before skinning: p = base + sum_k w_k delta_k. Empty
    /// (all zero) or one per morph target.
    pub morph_weights: &'a [f32],
}

impl<'a> Draw<'a> {
    /// A rigid, untextured, white draw of `mesh` at `world_from_mesh`.
    pub fn new(mesh: &'a GpuMesh, world_from_mesh: Mat4) -> Self {
        Self {
            mesh,
            texture: None,
            base_color_factor: [1.0; 4],
            world_from_mesh,
            joint_matrices: &[],
            morph_weights: &[],
        }
    }
}

/// The result of [`Renderer::render`].
#[derive(Debug, Clone, PartialEq)]
pub struct RenderedFrame {
    pub width: u32,
    pub height: u32,
    /// sRGB-encoded RGBA8, row-major from the top-left, no row padding.
    pub rgba8: Vec<u8>,
    /// Camera-space z (metres) of the nearest surface per pixel, `f32::INFINITY` where nothing
    /// was drawn. Same layout as `rgba8`, one value per pixel.
    pub depth_m: Vec<f32>,
}

impl RenderedFrame {
    /// RGBA of pixel (x, y), if inside.
    pub fn pixel(&self, x: u32, y: u32) -> Option<[u8; 4]> {
        if x >= self.width || y >= self.height {
            return None;
        }
        let i = (y as usize * self.width as usize + x as usize) * 4;
        let p = self.rgba8.get(i..i + 4)?;
        Some([p[0], p[1], p[2], p[3]])
    }

    /// Camera-space z of pixel (x, y), if inside.
    pub fn depth_at(&self, x: u32, y: u32) -> Option<f32> {
        if x >= self.width || y >= self.height {
            return None;
        }
        self.depth_m
            .get(y as usize * self.width as usize + x as usize)
            .copied()
    }
}

/// Skinned vertices read back by [`Renderer::skin_gpu`].
#[derive(Debug, Clone, PartialEq)]
pub struct SkinnedVertices {
    /// World positions (mesh positions after morphing, for a rigid call).
    pub positions: Vec<[f32; 3]>,
    /// Unit normals, transformed like the render pipeline does.
    pub normals: Vec<[f32; 3]>,
}

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

    /// Checks a draw's skin and morph inputs against its mesh.
    fn validate_deformation(
        &self,
        draw: usize,
        mesh: &GpuMesh,
        joint_matrices: &[Mat4],
        morph_weights: &[f32],
    ) -> Result<(), RenderError> {
        if mesh.renderer_id != self.id {
            return Err(RenderError::ForeignResource { draw, what: "mesh" });
        }
        if joint_matrices.len() > MAX_JOINTS {
            return Err(RenderError::TooManyJoints {
                draw,
                count: joint_matrices.len(),
                max: MAX_JOINTS,
            });
        }
        if !joint_matrices.is_empty() {
            if !mesh.skinned {
                return Err(RenderError::JointsForRigidMesh {
                    draw,
                    count: joint_matrices.len(),
                });
            }
            if let Some((joint, vertex)) = mesh.skin.max_joint {
                if joint as usize >= joint_matrices.len() {
                    return Err(RenderError::JointIndexOutOfRange {
                        draw,
                        vertex,
                        joint,
                        joint_count: joint_matrices.len(),
                    });
                }
            }
            if !joint_matrices.iter().all(finite_mat) {
                return Err(RenderError::NonFiniteDrawInput {
                    draw,
                    what: "joint_matrices",
                });
            }
        }
        if !morph_weights.is_empty() && morph_weights.len() != mesh.morph_target_count() {
            return Err(RenderError::MorphWeightCount {
                draw,
                expected: mesh.morph_target_count(),
                actual: morph_weights.len(),
            });
        }
        if !morph_weights.iter().all(|w| w.is_finite()) {
            return Err(RenderError::NonFiniteDrawInput {
                draw,
                what: "morph_weights",
            });
        }
        Ok(())
    }

    /// Group 1 bind group (uniforms, joint matrices, morph weights) of one draw.
    fn draw_bind_group(
        &self,
        uniforms: &DrawUniforms,
        joint_matrices: &[Mat4],
        morph_weights: &[f32],
    ) -> wgpu::BindGroup {
        self.draw_bind_group_with_key(uniforms, joint_matrices, morph_weights, &[], &[])
    }

    /// Group 1 bind group of a draw whose key pose (live texturing) follows its own joint
    /// matrices and morph weights in the same buffers: key joints start at index
    /// `joint_matrices.len()`, key weights at `morph_weights.len()`.
    fn draw_bind_group_with_key(
        &self,
        uniforms: &DrawUniforms,
        joint_matrices: &[Mat4],
        morph_weights: &[f32],
        key_joint_matrices: &[Mat4],
        key_morph_weights: &[f32],
    ) -> wgpu::BindGroup {
        let device = &self.ctx.device;
        let uniform_buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("pa-render draw uniforms"),
            contents: bytemuck::bytes_of(uniforms),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        // Storage bindings must not be empty: pad with an identity / a zero.
        let mut joints: Vec<[[f32; 4]; 4]> = joint_matrices
            .iter()
            .chain(key_joint_matrices)
            .map(mat)
            .collect();
        if joints.is_empty() {
            joints.push(mat(&Mat4::IDENTITY));
        }
        let joint_buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("pa-render joint matrices"),
            contents: bytemuck::cast_slice(&joints),
            usage: wgpu::BufferUsages::STORAGE,
        });
        let mut weights: Vec<f32> = morph_weights
            .iter()
            .chain(key_morph_weights)
            .copied()
            .collect();
        if weights.is_empty() {
            weights.push(0.0);
        }
        let weight_buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("pa-render morph weights"),
            contents: bytemuck::cast_slice(&weights),
            usage: wgpu::BufferUsages::STORAGE,
        });
        device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("pa-render draw bind group"),
            layout: &self.pipelines.draw_layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: uniform_buffer.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: joint_buffer.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 2,
                    resource: weight_buffer.as_entire_binding(),
                },
            ],
        })
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

    /// Checks one draw (resources, deformation, finiteness).
    fn validate_draw(&self, i: usize, d: &Draw<'_>) -> Result<(), RenderError> {
        self.validate_deformation(i, d.mesh, d.joint_matrices, d.morph_weights)?;
        if let Some(t) = d.texture {
            if t.renderer_id != self.id {
                return Err(RenderError::ForeignResource {
                    draw: i,
                    what: "texture",
                });
            }
        }
        if !finite_mat(&d.world_from_mesh) {
            return Err(RenderError::NonFiniteDrawInput {
                draw: i,
                what: "world_from_mesh",
            });
        }
        if !d.base_color_factor.iter().all(|c| c.is_finite()) {
            return Err(RenderError::NonFiniteDrawInput {
                draw: i,
                what: "base_color_factor",
            });
        }
        Ok(())
    }

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

    /// Group 1 uniforms of a draw seen through `clip_from_world`.
    fn draw_uniforms(
        d: &Draw<'_>,
        clip_from_world: &Mat4,
        camera_from_world: &Mat4,
        light: &LightUniforms,
    ) -> DrawUniforms {
        let (toward_light, light_rgb, ambient_rgb, lit) = *light;
        let skinned = !d.joint_matrices.is_empty();
        let mirrored = !skinned && d.world_from_mesh.determinant() < 0.0;
        DrawUniforms {
            clip_from_world: mat(clip_from_world),
            camera_from_world: mat(camera_from_world),
            world_from_mesh: mat(&d.world_from_mesh),
            base_color_factor: d.base_color_factor,
            toward_light_world: toward_light,
            light_rgb,
            ambient_rgb,
            counts: [
                d.joint_matrices.len() as u32,
                d.morph_weights.len() as u32,
                d.mesh.vertex_count,
                lit,
            ],
            flags: [u32::from(mirrored), 0, 0, 0],
        }
    }

    fn clear_color(clear_rgba: [f32; 4]) -> Result<wgpu::Color, RenderError> {
        if !clear_rgba.iter().all(|c| c.is_finite()) {
            return Err(RenderError::InvalidLighting(format!(
                "clear colour {clear_rgba:?} is not finite"
            )));
        }
        Ok(wgpu::Color {
            r: f64::from(clear_rgba[0]),
            g: f64::from(clear_rgba[1]),
            b: f64::from(clear_rgba[2]),
            a: f64::from(clear_rgba[3]),
        })
    }

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
        targets.record_copies(&mut encoder);
        self.ctx.queue.submit([encoder.finish()]);

        let oom = pollster::block_on(oom.pop());
        let validation = pollster::block_on(validation.pop());
        if let Some(e) = validation.or(oom) {
            return Err(RenderError::Gpu {
                during: "render",
                message: e.to_string(),
            });
        }

        let frame = read_frame(device, &targets, &mut self.readback_times)?;
        self.targets = Some(targets);
        Ok(frame)
    }

    /// Renders the key-pose visibility map: the camera-space z of the nearest surface of
    /// `draws` seen by `camera` (pinhole: rasterisation has no lens distortion; the map is
    /// looked up with the undistorted projection), `width` x `height` texels, kept on the GPU
    /// for [`LiveTexturing::visibility`]. `draws` are normally the key poses of the live draws
    /// ([`LiveDraw::key_pose_draw`]) plus any real occluder, and `camera` the frame camera
    /// (same pose and intrinsics; its near/far clip the map).
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
        if visibility.renderer_id != self.id {
            return Err(RenderError::ForeignResource {
                draw: 0,
                what: "visibility map",
            });
        }
        let (width, height) = (visibility.width, visibility.height);
        let padded_row = readback::padded_bytes_per_row(width);
        let device = &self.ctx.device;
        let buffer = visibility.readback.get_or_insert_with(|| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("pa-render visibility readback"),
                size: u64::from(padded_row) * u64::from(height),
                usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
                mapped_at_creation: false,
            })
        });
        let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("pa-render visibility readback"),
        });
        encoder.copy_texture_to_buffer(
            visibility.camera_z.as_image_copy(),
            wgpu::TexelCopyBufferInfo {
                buffer,
                layout: wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(padded_row),
                    rows_per_image: Some(height),
                },
            },
            wgpu::Extent3d {
                width,
                height,
                depth_or_array_layers: 1,
            },
        );
        self.ctx.queue.submit([encoder.finish()]);
        let data = readback::read_buffers(device, &[buffer], &mut self.readback_times);
        let t = std::time::Instant::now();
        let bytes = match data.as_deref() {
            Ok([bytes]) => readback::unpad_rows(
                bytes,
                width as usize * 4,
                padded_row as usize,
                height as usize,
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
                u.stretch = [l.max_stretch.max(0.0), 0.0, 0.0, 0.0];
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
        self.check_render_size(width, height)?;
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
        targets.record_copies(&mut encoder);
        self.ctx.queue.submit([encoder.finish()]);

        let oom = pollster::block_on(oom.pop());
        let validation = pollster::block_on(validation.pop());
        if let Some(e) = validation.or(oom) {
            return Err(RenderError::Gpu {
                during: "live render",
                message: e.to_string(),
            });
        }

        let frame = read_frame(device, &targets.base, &mut self.readback_times)?;
        let codes =
            readback::read_buffers(device, &[&targets.code_readback], &mut self.readback_times)?;
        let t_unpad = std::time::Instant::now();
        let padded = readback::padded_bytes_per_row_of(width, 1) as usize;
        let live_valid = codes
            .first()
            .map(|c| readback::unpad_rows(c, width as usize, padded, height as usize))
            .unwrap_or_default();
        self.readback_times.copy_ms += readback::ms_since(t_unpad);
        self.live_targets = Some(targets);
        Ok(LiveRenderedFrame { frame, live_valid })
    }

    /// Skinned (and morphed) world positions of every vertex of `mesh`, computed on the GPU by
    /// the same WGSL function the vertex stage uses. With empty `joint_matrices` the positions
    /// are the morphed mesh-space positions.
    pub fn skin_positions_gpu(
        &mut self,
        mesh: &GpuMesh,
        joint_matrices: &[Mat4],
        morph_weights: &[f32],
    ) -> Result<Vec<[f32; 3]>, RenderError> {
        Ok(self
            .skin_gpu(mesh, joint_matrices, morph_weights)?
            .positions)
    }

    /// Like [`Renderer::skin_positions_gpu`], also returning the transformed unit normals.
    pub fn skin_gpu(
        &mut self,
        mesh: &GpuMesh,
        joint_matrices: &[Mat4],
        morph_weights: &[f32],
    ) -> Result<SkinnedVertices, RenderError> {
        self.validate_deformation(0, mesh, joint_matrices, morph_weights)?;
        let device = &self.ctx.device;
        let vertex_count = mesh.vertex_count;
        let output_bytes = u64::from(vertex_count) * 32;
        let limit = self
            .ctx
            .limits
            .max_storage_buffer_binding_size
            .min(self.ctx.limits.max_buffer_size);
        if output_bytes > limit {
            return Err(RenderError::MeshTooLarge {
                buffer: "skinned output",
                bytes: output_bytes,
                limit,
            });
        }
        let groups = vertex_count.div_ceil(SKIN_WORKGROUP_SIZE).max(1);
        let max_groups = self.ctx.limits.max_compute_workgroups_per_dimension.max(1);
        let groups_x = groups.min(max_groups);
        let groups_y = groups.div_ceil(groups_x);

        let validation = device.push_error_scope(wgpu::ErrorFilter::Validation);
        let uniforms = DrawUniforms {
            clip_from_world: mat(&Mat4::IDENTITY),
            camera_from_world: mat(&Mat4::IDENTITY),
            world_from_mesh: mat(&Mat4::IDENTITY),
            base_color_factor: [1.0; 4],
            toward_light_world: [0.0; 4],
            light_rgb: [0.0; 4],
            ambient_rgb: [0.0; 4],
            counts: [
                joint_matrices.len() as u32,
                morph_weights.len() as u32,
                vertex_count,
                0,
            ],
            flags: [0, 0, groups_x * SKIN_WORKGROUP_SIZE, 0],
        };
        let draw_bind_group = self.draw_bind_group(&uniforms, joint_matrices, morph_weights);
        let output = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("pa-render skinned output"),
            size: output_bytes.max(32),
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let staging = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("pa-render skinned readback"),
            size: output_bytes.max(32),
            usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
            mapped_at_creation: false,
        });
        let output_bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("pa-render skinned output bind group"),
            layout: &self.pipelines.skin_output_layout,
            entries: &[wgpu::BindGroupEntry {
                binding: 0,
                resource: output.as_entire_binding(),
            }],
        });
        let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("pa-render skinning"),
        });
        {
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("pa-render skinning pass"),
                timestamp_writes: None,
            });
            pass.set_pipeline(&self.pipelines.skin);
            pass.set_bind_group(0, &mesh.bind_group, &[]);
            pass.set_bind_group(1, &draw_bind_group, &[]);
            pass.set_bind_group(2, &output_bind_group, &[]);
            pass.dispatch_workgroups(groups_x, groups_y, 1);
        }
        encoder.copy_buffer_to_buffer(&output, 0, &staging, 0, output_bytes.max(32));
        self.ctx.queue.submit([encoder.finish()]);
        self.pop_scope(validation, "GPU skinning")?;

        let data = readback::read_buffers(device, &[&staging], &mut self.readback_times)?;
        let floats: Vec<f32> = data
            .first()
            .map(|d| {
                d.chunks_exact(4)
                    .map(|b| f32::from_ne_bytes([b[0], b[1], b[2], b[3]]))
                    .collect()
            })
            .unwrap_or_default();
        let mut positions = Vec::with_capacity(vertex_count as usize);
        let mut normals = Vec::with_capacity(vertex_count as usize);
        for v in floats.chunks_exact(8).take(vertex_count as usize) {
            positions.push([v[0], v[1], v[2]]);
            normals.push([v[4], v[5], v[6]]);
        }
        Ok(SkinnedVertices { positions, normals })
    }
}

fn color_attachment(
    view: &wgpu::TextureView,
    clear: wgpu::Color,
) -> wgpu::RenderPassColorAttachment<'_> {
    wgpu::RenderPassColorAttachment {
        view,
        depth_slice: None,
        resolve_target: None,
        ops: wgpu::Operations {
            load: wgpu::LoadOp::Clear(clear),
            store: wgpu::StoreOp::Store,
        },
    }
}

fn depth_attachment(view: &wgpu::TextureView) -> wgpu::RenderPassDepthStencilAttachment<'_> {
    wgpu::RenderPassDepthStencilAttachment {
        view,
        depth_ops: Some(wgpu::Operations {
            load: wgpu::LoadOp::Clear(1.0),
            store: wgpu::StoreOp::Discard,
        }),
        stencil_ops: None,
    }
}

/// Binds groups 0-2 of one draw (mesh, per-draw uniforms and joints, texture; white when the
/// draw has none) and records its indexed draw. Shared by the main, visibility and live passes.
fn record_draw(
    pass: &mut wgpu::RenderPass<'_>,
    d: &Draw<'_>,
    draw_group: &wgpu::BindGroup,
    white_texture: &GpuTexture,
) {
    let texture = d.texture.unwrap_or(white_texture);
    pass.set_bind_group(0, &d.mesh.bind_group, &[]);
    pass.set_bind_group(1, draw_group, &[]);
    pass.set_bind_group(2, &texture.bind_group, &[]);
    pass.set_index_buffer(d.mesh.index_buffer.slice(..), wgpu::IndexFormat::Uint32);
    pass.draw_indexed(0..d.mesh.index_count, 0, 0..1);
}

/// Maps the colour and camera-z readback buffers of `targets` (copies already submitted).
fn read_frame(
    device: &wgpu::Device,
    targets: &Targets,
    times: &mut ReadbackTimes,
) -> Result<RenderedFrame, RenderError> {
    let (width, height) = (targets.width, targets.height);
    let data = readback::read_buffers(
        device,
        &[&targets.color_readback, &targets.camera_z_readback],
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

/// clip_from_world for a render of `width` x `height`, after validating the camera.
fn camera_clip_from_world(
    camera: &CpuCamera,
    width: u32,
    height: u32,
) -> Result<Mat4, RenderError> {
    camera
        .intrinsics
        .validate()
        .map_err(|e| RenderError::InvalidCamera(e.to_string()))?;
    let (near, far) = (camera.near_m, camera.far_m);
    if !(near.is_finite() && far.is_finite() && near > 0.0 && far > near) {
        return Err(RenderError::InvalidCamera(format!(
            "near_m = {near}, far_m = {far}: need 0 < near < far, both finite"
        )));
    }
    if !finite_mat(&camera.camera_from_world) {
        return Err(RenderError::InvalidCamera(
            "camera_from_world is not finite".to_owned(),
        ));
    }
    let k = &camera.intrinsics;
    let k = if (k.width, k.height) == (width, height) {
        *k
    } else {
        k.scaled_to(width, height)
    };
    Ok(k.clip_from_camera(near, far) * camera.camera_from_world)
}

type LightUniforms = ([f32; 4], [f32; 4], [f32; 4], u32);

fn lighting_uniforms(lighting: Option<&Lighting>) -> Result<LightUniforms, RenderError> {
    let Some(l) = lighting else {
        return Ok(([0.0; 4], [0.0; 4], [0.0; 4], 0));
    };
    let rgb4 = |what: &str, c: [f32; 3]| {
        if c.iter().all(|x| x.is_finite()) {
            Ok([c[0], c[1], c[2], 0.0])
        } else {
            Err(RenderError::InvalidLighting(format!(
                "{what} {c:?} is not finite"
            )))
        }
    };
    let ambient = rgb4("ambient_rgb", l.ambient_rgb)?;
    let (toward, radiance) = match &l.directional {
        None => ([0.0; 4], [0.0; 4]),
        Some(d) => {
            let Some(dir) = d.toward_light_world.try_normalize() else {
                return Err(RenderError::InvalidLighting(format!(
                    "toward_light_world {} has no direction",
                    d.toward_light_world
                )));
            };
            (
                dir.extend(0.0).to_array(),
                rgb4("radiance_rgb", d.radiance_rgb)?,
            )
        }
    };
    Ok((toward, radiance, ambient, 1))
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

    #[test]
    fn unlit_lighting_uniforms() {
        let (_, _, _, lit) = lighting_uniforms(None).expect("unlit");
        assert_eq!(lit, 0);
        let bad = Lighting {
            ambient_rgb: [0.1; 3],
            directional: Some(DirectionalLight {
                toward_light_world: glam::Vec3::ZERO,
                radiance_rgb: [1.0; 3],
            }),
        };
        assert!(lighting_uniforms(Some(&bad)).is_err());
    }
}
