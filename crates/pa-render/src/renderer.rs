//! The long-lived [`Renderer`] and the per-frame inputs ([`CpuCamera`], [`Lighting`],
//! [`Draw`]) and output ([`RenderedFrame`]).

use std::sync::atomic::{AtomicU64, Ordering};

use glam::Mat4;
use wgpu::util::DeviceExt;

use crate::context::{describe, GpuContext};
use crate::error::RenderError;
use crate::mesh::{self, CpuMesh, GpuMesh};
use crate::pipeline::{DrawUniforms, Pipelines, SKIN_WORKGROUP_SIZE};
use crate::readback::{self, Targets};
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
    /// position = sum_i w_i * joint_matrices[j_i] * p.
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
    targets: Option<Targets>,
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
        )?;
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
            targets: None,
        })
    }

    /// Adapter name, backend, device type and driver, for logs.
    pub fn adapter_info(&self) -> String {
        describe(&self.ctx.info)
    }

    /// The wgpu backend in use.
    pub fn backend(&self) -> wgpu::Backend {
        self.ctx.info.backend
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
        );
        self.pop_scope(scope, "texture upload")?;
        result
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
        let device = &self.ctx.device;
        let uniform_buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("pa-render draw uniforms"),
            contents: bytemuck::bytes_of(uniforms),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        // Storage bindings must not be empty: pad with an identity / a zero.
        let joints: Vec<[[f32; 4]; 4]> = if joint_matrices.is_empty() {
            vec![mat(&Mat4::IDENTITY)]
        } else {
            joint_matrices.iter().map(mat).collect()
        };
        let joint_buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("pa-render joint matrices"),
            contents: bytemuck::cast_slice(&joints),
            usage: wgpu::BufferUsages::STORAGE,
        });
        let weights: &[f32] = if morph_weights.is_empty() {
            &[0.0]
        } else {
            morph_weights
        };
        let weight_buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("pa-render morph weights"),
            contents: bytemuck::cast_slice(weights),
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
        let clip_from_world = camera_clip_from_world(camera, width, height)?;
        let (toward_light, light_rgb, ambient_rgb, lit) = lighting_uniforms(lighting)?;
        if !clear_rgba.iter().all(|c| c.is_finite()) {
            return Err(RenderError::InvalidLighting(format!(
                "clear colour {clear_rgba:?} is not finite"
            )));
        }

        // Validate everything before touching the GPU.
        for (i, d) in draws.iter().enumerate() {
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
                let skinned = !d.joint_matrices.is_empty();
                let mirrored = !skinned && d.world_from_mesh.determinant() < 0.0;
                let uniforms = DrawUniforms {
                    clip_from_world: mat(&clip_from_world),
                    camera_from_world: mat(&camera.camera_from_world),
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
                };
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
                    Some(wgpu::RenderPassColorAttachment {
                        view: &targets.color_view,
                        depth_slice: None,
                        resolve_target: None,
                        ops: wgpu::Operations {
                            load: wgpu::LoadOp::Clear(wgpu::Color {
                                r: f64::from(clear_rgba[0]),
                                g: f64::from(clear_rgba[1]),
                                b: f64::from(clear_rgba[2]),
                                a: f64::from(clear_rgba[3]),
                            }),
                            store: wgpu::StoreOp::Store,
                        },
                    }),
                    Some(wgpu::RenderPassColorAttachment {
                        view: &targets.camera_z_view,
                        depth_slice: None,
                        resolve_target: None,
                        ops: wgpu::Operations {
                            // Bits 0 = 0.0 = nothing drawn (drawn surfaces have z >= near > 0).
                            load: wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT),
                            store: wgpu::StoreOp::Store,
                        },
                    }),
                ],
                depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                    view: &targets.depth_view,
                    depth_ops: Some(wgpu::Operations {
                        load: wgpu::LoadOp::Clear(1.0),
                        store: wgpu::StoreOp::Discard,
                    }),
                    stencil_ops: None,
                }),
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            });
            pass.set_pipeline(&self.pipelines.render);
            for (d, bind_group) in draws.iter().zip(&bind_groups) {
                let texture = d.texture.unwrap_or(&self.white_texture);
                pass.set_bind_group(0, &d.mesh.bind_group, &[]);
                pass.set_bind_group(1, bind_group, &[]);
                pass.set_bind_group(2, &texture.bind_group, &[]);
                pass.set_index_buffer(d.mesh.index_buffer.slice(..), wgpu::IndexFormat::Uint32);
                pass.draw_indexed(0..d.mesh.index_count, 0, 0..1);
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

        let data = readback::read_buffers(
            device,
            &[&targets.color_readback, &targets.camera_z_readback],
        );
        let (color, camera_z) = match data.as_deref() {
            Ok([color, camera_z]) => (color, camera_z),
            _ => {
                return Err(data.err().unwrap_or_else(|| {
                    RenderError::Readback("unexpected readback buffer count".to_owned())
                }));
            }
        };
        let row = width as usize * 4;
        let padded_row = padded_row as usize;
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
        self.targets = Some(targets);
        Ok(RenderedFrame {
            width,
            height,
            rgba8,
            depth_m,
        })
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

        let data = readback::read_buffers(device, &[&staging])?;
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
