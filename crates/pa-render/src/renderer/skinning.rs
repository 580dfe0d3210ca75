//! Skinning as a compute pass read back to the CPU ([`Renderer::skin_gpu`]): the same WGSL
//! function as the vertex stage, so tests can compare the GPU with the CPU reference.

use glam::Mat4;

use super::{mat, Renderer, SkinnedVertices};
use crate::error::RenderError;
use crate::mesh::GpuMesh;
use crate::pipeline::{DrawUniforms, SKIN_WORKGROUP_SIZE};
use crate::readback;

impl Renderer {
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

        let data = readback::read_buffers(
            device,
            &[(&staging, staging.size())],
            &mut self.readback_times,
        )?;
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
