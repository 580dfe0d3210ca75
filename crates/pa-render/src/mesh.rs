//! CPU meshes, their validation, and upload into GPU storage buffers.
//!
//! The vertex stage pulls vertices from a storage buffer by `vertex_index` (no vertex
//! buffers), so the render pipeline and the skinning compute entry point read exactly the same
//! data with the same WGSL function (`shaders/skinning.wgsl`).

use bytemuck::{Pod, Zeroable};
use wgpu::util::DeviceExt;

use crate::error::RenderError;

/// Most morph targets per mesh.
pub const MAX_MORPH_TARGETS: usize = 256;

/// A triangle mesh on the CPU, in mesh space (metres), as a glTF primitive provides it.
///
/// * `positions` is required; `normals` and `uvs` are either empty (then smooth area-weighted
///   normals are computed from the triangles, and uvs are (0, 0)) or one per vertex.
/// * `joints`/`weights` hold up to 8 influences per vertex (glTF `JOINTS_0`/`JOINTS_1`,
///   `WEIGHTS_0`/`WEIGHTS_1`; pad unused influences with weight 0). Both empty for a rigid
///   mesh, else one per vertex. Weights are used as given (not renormalised).
/// * `indices` is a triangle list.
/// * `morph_position_deltas[k]` is target k's position delta per vertex;
///   `morph_normal_deltas` is empty or has one entry per target, each empty (no normal
///   deltas for that target) or one per vertex.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct CpuMesh {
    pub positions: Vec<[f32; 3]>,
    pub normals: Vec<[f32; 3]>,
    pub uvs: Vec<[f32; 2]>,
    pub joints: Vec<[u16; 8]>,
    pub weights: Vec<[f32; 8]>,
    pub indices: Vec<u32>,
    pub morph_position_deltas: Vec<Vec<[f32; 3]>>,
    pub morph_normal_deltas: Vec<Vec<[f32; 3]>>,
}

/// One vertex as the shaders read it (`GpuVertex` in `skinning.wgsl`).
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub(crate) struct GpuVertex {
    pub position_u: [f32; 4],
    pub normal_v: [f32; 4],
    pub joints: [u32; 4],
    pub weights0: [f32; 4],
    pub weights1: [f32; 4],
}

/// Which joints a skinned mesh needs: per vertex, the largest joint index with a non-zero
/// weight (for the draw-time check against the number of joint matrices).
#[derive(Debug, Clone)]
pub(crate) struct SkinInfo {
    /// Largest joint index used with a non-zero weight, and the first vertex that uses it.
    pub max_joint: Option<(u16, usize)>,
}

/// A mesh uploaded to the GPU by [`crate::Renderer::upload_mesh`]. Upload once, draw every
/// frame. Cheap to clone (the buffers are reference counted).
#[derive(Debug, Clone)]
pub struct GpuMesh {
    pub(crate) renderer_id: u64,
    pub(crate) vertex_count: u32,
    pub(crate) index_count: u32,
    pub(crate) morph_target_count: u32,
    pub(crate) skinned: bool,
    pub(crate) skin: SkinInfo,
    pub(crate) index_buffer: wgpu::Buffer,
    /// Group 0 of both pipelines: vertices and morph deltas.
    pub(crate) bind_group: wgpu::BindGroup,
}

impl GpuMesh {
    /// Number of vertices.
    pub fn vertex_count(&self) -> usize {
        self.vertex_count as usize
    }
    /// Number of triangles.
    pub fn triangle_count(&self) -> usize {
        self.index_count as usize / 3
    }
    /// Number of morph targets.
    pub fn morph_target_count(&self) -> usize {
        self.morph_target_count as usize
    }
    /// True when the mesh has joints and weights (draws must give joint matrices).
    pub fn is_skinned(&self) -> bool {
        self.skinned
    }
}

fn check_len(attribute: &str, actual: usize, expected: usize) -> Result<(), RenderError> {
    if actual == expected {
        Ok(())
    } else {
        Err(RenderError::AttributeLength {
            attribute: attribute.to_owned(),
            expected,
            actual,
        })
    }
}

fn check_finite<const N: usize>(attribute: &str, values: &[[f32; N]]) -> Result<(), RenderError> {
    match values.iter().position(|v| v.iter().any(|x| !x.is_finite())) {
        None => Ok(()),
        Some(vertex) => Err(RenderError::NonFinite {
            attribute: attribute.to_owned(),
            vertex,
        }),
    }
}

impl CpuMesh {
    /// Number of vertices.
    pub fn vertex_count(&self) -> usize {
        self.positions.len()
    }

    /// Checks lengths, index ranges and finiteness. Called by `upload_mesh`.
    pub fn validate(&self) -> Result<(), RenderError> {
        let n = self.positions.len();
        if n == 0 || self.indices.is_empty() {
            return Err(RenderError::EmptyMesh {
                vertices: n,
                indices: self.indices.len(),
            });
        }
        if !self.indices.len().is_multiple_of(3) {
            return Err(RenderError::IndexCountNotTriangles {
                count: self.indices.len(),
            });
        }
        if !self.normals.is_empty() {
            check_len("normals", self.normals.len(), n)?;
        }
        if !self.uvs.is_empty() {
            check_len("uvs", self.uvs.len(), n)?;
        }
        if !self.joints.is_empty() || !self.weights.is_empty() {
            check_len("joints", self.joints.len(), n)?;
            check_len("weights", self.weights.len(), n)?;
        }
        if self.morph_position_deltas.len() > MAX_MORPH_TARGETS {
            return Err(RenderError::TooManyMorphTargets {
                count: self.morph_position_deltas.len(),
                max: MAX_MORPH_TARGETS,
            });
        }
        for (k, deltas) in self.morph_position_deltas.iter().enumerate() {
            check_len(&format!("morph_position_deltas[{k}]"), deltas.len(), n)?;
        }
        if !self.morph_normal_deltas.is_empty() {
            check_len(
                "morph_normal_deltas (targets)",
                self.morph_normal_deltas.len(),
                self.morph_position_deltas.len(),
            )?;
            for (k, deltas) in self.morph_normal_deltas.iter().enumerate() {
                if !deltas.is_empty() {
                    check_len(&format!("morph_normal_deltas[{k}]"), deltas.len(), n)?;
                }
            }
        }
        if let Some((position, &index)) = self
            .indices
            .iter()
            .enumerate()
            .find(|(_, &i)| i as usize >= n)
        {
            return Err(RenderError::IndexOutOfRange {
                position,
                index,
                vertex_count: n,
            });
        }
        check_finite("positions", &self.positions)?;
        check_finite("normals", &self.normals)?;
        check_finite("uvs", &self.uvs)?;
        check_finite("weights", &self.weights)?;
        for (k, deltas) in self.morph_position_deltas.iter().enumerate() {
            check_finite(&format!("morph_position_deltas[{k}]"), deltas)?;
        }
        for (k, deltas) in self.morph_normal_deltas.iter().enumerate() {
            check_finite(&format!("morph_normal_deltas[{k}]"), deltas)?;
        }
        Ok(())
    }

    /// Smooth, area-weighted vertex normals from the triangles ((0, 0, 1) for vertices on no
    /// triangle or on degenerate ones only). Assumes `validate` passed.
    pub fn computed_normals(&self) -> Vec<[f32; 3]> {
        let mut acc = vec![glam::Vec3::ZERO; self.positions.len()];
        for tri in self.indices.chunks_exact(3) {
            let [a, b, c] = [tri[0] as usize, tri[1] as usize, tri[2] as usize];
            let (Some(pa), Some(pb), Some(pc)) = (
                self.positions.get(a),
                self.positions.get(b),
                self.positions.get(c),
            ) else {
                continue;
            };
            let (pa, pb, pc) = (
                glam::Vec3::from(*pa),
                glam::Vec3::from(*pb),
                glam::Vec3::from(*pc),
            );
            // Cross product length = 2 * area: area weighting for free.
            let n = (pb - pa).cross(pc - pa);
            for i in [a, b, c] {
                acc[i] += n;
            }
        }
        acc.into_iter()
            .map(|n| n.try_normalize().unwrap_or(glam::Vec3::Z).to_array())
            .collect()
    }

    pub(crate) fn skin_info(&self) -> SkinInfo {
        let mut max_joint: Option<(u16, usize)> = None;
        for (vertex, (joints, weights)) in self.joints.iter().zip(&self.weights).enumerate() {
            for (&j, &w) in joints.iter().zip(weights) {
                if w != 0.0 && max_joint.is_none_or(|(m, _)| j > m) {
                    max_joint = Some((j, vertex));
                }
            }
        }
        SkinInfo { max_joint }
    }

    /// Packs vertices as the shaders read them. Assumes `validate` passed.
    pub(crate) fn packed_vertices(&self) -> Vec<GpuVertex> {
        let computed;
        let normals: &[[f32; 3]] = if self.normals.is_empty() {
            computed = self.computed_normals();
            &computed
        } else {
            &self.normals
        };
        (0..self.positions.len())
            .map(|i| {
                let p = self.positions[i];
                let n = normals.get(i).copied().unwrap_or([0.0, 0.0, 1.0]);
                let uv = self.uvs.get(i).copied().unwrap_or([0.0, 0.0]);
                let joints = self.joints.get(i).copied().unwrap_or([0; 8]);
                let w = self.weights.get(i).copied().unwrap_or([0.0; 8]);
                let pack = |k: usize| joints[2 * k] as u32 | ((joints[2 * k + 1] as u32) << 16);
                GpuVertex {
                    position_u: [p[0], p[1], p[2], uv[0]],
                    normal_v: [n[0], n[1], n[2], uv[1]],
                    joints: [pack(0), pack(1), pack(2), pack(3)],
                    weights0: [w[0], w[1], w[2], w[3]],
                    weights1: [w[4], w[5], w[6], w[7]],
                }
            })
            .collect()
    }

    /// Morph deltas laid out [target][vertex][position, normal] as vec4 (at least one
    /// element, storage bindings must not be empty). Assumes `validate` passed.
    pub(crate) fn packed_morph_deltas(&self) -> Vec<[f32; 4]> {
        let n = self.positions.len();
        let mut out = Vec::with_capacity((self.morph_position_deltas.len() * n * 2).max(2));
        for (k, positions) in self.morph_position_deltas.iter().enumerate() {
            let normals = self.morph_normal_deltas.get(k).filter(|d| !d.is_empty());
            for (i, dp) in positions.iter().enumerate() {
                let dn = normals.and_then(|d| d.get(i)).copied().unwrap_or([0.0; 3]);
                out.push([dp[0], dp[1], dp[2], 0.0]);
                out.push([dn[0], dn[1], dn[2], 0.0]);
            }
        }
        if out.is_empty() {
            out.resize(2, [0.0; 4]);
        }
        out
    }
}

/// Validates and uploads; `layout` is the mesh bind group layout (group 0).
pub(crate) fn upload(
    device: &wgpu::Device,
    limits: &wgpu::Limits,
    layout: &wgpu::BindGroupLayout,
    renderer_id: u64,
    mesh: &CpuMesh,
) -> Result<GpuMesh, RenderError> {
    mesh.validate()?;
    let vertices = mesh.packed_vertices();
    let morph = mesh.packed_morph_deltas();
    let limit = limits
        .max_storage_buffer_binding_size
        .min(limits.max_buffer_size);
    let too_large = |buffer: &'static str, bytes: u64| {
        if bytes > limit {
            Err(RenderError::MeshTooLarge {
                buffer,
                bytes,
                limit,
            })
        } else {
            Ok(())
        }
    };
    too_large(
        "vertices",
        std::mem::size_of_val(vertices.as_slice()) as u64,
    )?;
    too_large(
        "morph deltas",
        std::mem::size_of_val(morph.as_slice()) as u64,
    )?;
    too_large(
        "indices",
        std::mem::size_of_val(mesh.indices.as_slice()) as u64,
    )?;
    let vertex_count = u32::try_from(vertices.len()).map_err(|_| RenderError::MeshTooLarge {
        buffer: "vertices",
        bytes: vertices.len() as u64,
        limit: u64::from(u32::MAX),
    })?;

    let vertex_buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some("pa-render mesh vertices"),
        contents: bytemuck::cast_slice(&vertices),
        usage: wgpu::BufferUsages::STORAGE,
    });
    let morph_buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some("pa-render mesh morph deltas"),
        contents: bytemuck::cast_slice(&morph),
        usage: wgpu::BufferUsages::STORAGE,
    });
    let index_buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some("pa-render mesh indices"),
        contents: bytemuck::cast_slice(&mesh.indices),
        usage: wgpu::BufferUsages::INDEX,
    });
    let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("pa-render mesh bind group"),
        layout,
        entries: &[
            wgpu::BindGroupEntry {
                binding: 0,
                resource: vertex_buffer.as_entire_binding(),
            },
            wgpu::BindGroupEntry {
                binding: 1,
                resource: morph_buffer.as_entire_binding(),
            },
        ],
    });
    Ok(GpuMesh {
        renderer_id,
        vertex_count,
        // validate() bounded the index buffer by the binding-size limit (< 4 GiB).
        index_count: mesh.indices.len() as u32,
        morph_target_count: mesh.morph_position_deltas.len() as u32,
        skinned: !mesh.joints.is_empty(),
        skin: mesh.skin_info(),
        index_buffer,
        bind_group,
    })
}
