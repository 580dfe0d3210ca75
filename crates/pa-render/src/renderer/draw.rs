//! What the draw types of the [`Renderer`] share: validating a draw's inputs, its group 1
//! bind group (uniforms, joint matrices, morph weights) and uniforms, the pass attachments,
//! recording an indexed draw, and the camera and lighting uniforms.

use glam::Mat4;
use wgpu::util::DeviceExt;

use super::{finite_mat, mat, CpuCamera, Draw, Lighting, Renderer, MAX_JOINTS};
use crate::error::RenderError;
use crate::mesh::GpuMesh;
use crate::pipeline::DrawUniforms;
use crate::texture::GpuTexture;

impl Renderer {
    /// Checks a draw's skin and morph inputs against its mesh.
    pub(super) fn validate_deformation(
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

    /// Checks one draw (resources, deformation, finiteness).
    pub(super) fn validate_draw(&self, i: usize, d: &Draw<'_>) -> Result<(), RenderError> {
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

    /// Group 1 uniforms of a draw seen through `clip_from_world`.
    pub(super) fn draw_uniforms(
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

    /// Group 1 bind group (uniforms, joint matrices, morph weights) of one draw.
    pub(super) fn draw_bind_group(
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
    pub(super) fn draw_bind_group_with_key(
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

    pub(super) fn clear_color(clear_rgba: [f32; 4]) -> Result<wgpu::Color, RenderError> {
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
}

pub(super) fn color_attachment(
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

pub(super) fn depth_attachment(
    view: &wgpu::TextureView,
) -> wgpu::RenderPassDepthStencilAttachment<'_> {
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
pub(super) fn record_draw(
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

/// clip_from_world for a render of `width` x `height`, after validating the camera.
pub(super) fn camera_clip_from_world(
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

pub(super) type LightUniforms = ([f32; 4], [f32; 4], [f32; 4], u32);

pub(super) fn lighting_uniforms(lighting: Option<&Lighting>) -> Result<LightUniforms, RenderError> {
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
    use crate::renderer::DirectionalLight;

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
