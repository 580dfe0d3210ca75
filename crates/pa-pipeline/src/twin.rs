//! The digital twin on the GPU: a model's primitives and textures uploaded once, and the
//! per-frame data (joint matrices, morph weights, node transforms) built from a pose.

use glam::Mat4;
use pa_model::{anim::Pose, skin, Model, Primitive};
use pa_render::{CpuMesh, CpuTexture, Draw, GpuMesh, GpuTexture, RenderError, Renderer};

/// Converts a model primitive, as it is drawn ([`Primitive::drawn`]: flat-shaded when the
/// file has no normals), to the renderer's plain mesh type.
pub fn cpu_mesh_from_primitive(prim: &Primitive) -> CpuMesh {
    let prim = prim.drawn();
    let v3 = |v: &Vec<glam::Vec3>| v.iter().map(|p| p.to_array()).collect::<Vec<_>>();
    CpuMesh {
        positions: v3(&prim.positions),
        normals: v3(&prim.normals),
        uvs: prim.uvs.clone(),
        joints: prim.joints.clone(),
        weights: prim.weights.clone(),
        indices: prim.indices.clone(),
        morph_position_deltas: prim
            .morph_targets
            .iter()
            .map(|t| v3(&t.position_deltas))
            .collect(),
        morph_normal_deltas: prim
            .morph_targets
            .iter()
            .map(|t| v3(&t.normal_deltas))
            .collect(),
    }
}

/// One uploaded primitive of a mesh node.
pub struct TwinPrimitive {
    pub node: usize,
    pub primitive: usize,
    pub mesh: GpuMesh,
    /// Index into [`GpuTwin::textures`].
    pub texture: Option<usize>,
    pub base_color_factor: [f32; 4],
}

/// A model uploaded to a renderer.
pub struct GpuTwin {
    pub primitives: Vec<TwinPrimitive>,
    pub textures: Vec<GpuTexture>,
}

/// Per-frame data of a twin: what a pose means for the GPU.
pub struct TwinFrame {
    /// `world_from_node` per node (placement applied).
    pub world_from_node: Vec<Mat4>,
    /// Skinning matrices per node that has a skin (empty for the others).
    pub joint_matrices: Vec<Vec<Mat4>>,
    /// Morph weights per node.
    pub morph_weights: Vec<Vec<f32>>,
}

impl GpuTwin {
    /// Uploads every primitive of every mesh node, and every image.
    pub fn upload(renderer: &mut Renderer, model: &Model) -> Result<Self, RenderError> {
        let mut textures = Vec::with_capacity(model.images.len());
        for im in &model.images {
            textures.push(renderer.upload_texture(&CpuTexture {
                width: im.width,
                height: im.height,
                rgba8: im.rgba8.clone(),
            })?);
        }
        let mut primitives = Vec::new();
        for (ni, node) in model.mesh_nodes() {
            let Some(mi) = node.mesh else { continue };
            for (pi, prim) in model.meshes[mi].primitives.iter().enumerate() {
                if prim.indices.is_empty() {
                    continue;
                }
                let material = prim.material.and_then(|m| model.materials.get(m));
                primitives.push(TwinPrimitive {
                    node: ni,
                    primitive: pi,
                    mesh: renderer.upload_mesh(&cpu_mesh_from_primitive(prim))?,
                    texture: material
                        .and_then(|m| m.base_color_image)
                        .filter(|&i| i < textures.len()),
                    base_color_factor: material.map(|m| m.base_color_factor).unwrap_or([1.0; 4]),
                });
            }
        }
        Ok(Self {
            primitives,
            textures,
        })
    }

    /// Builds the frame data for `pose`, placed by `world_from_model` (for AR:
    /// `world_from_marker * marker_from_prop`).
    pub fn frame(&self, model: &Model, pose: &Pose, world_from_model: Mat4) -> TwinFrame {
        let world_from_node: Vec<Mat4> = pose
            .world_from_node(model)
            .into_iter()
            .map(|m| world_from_model * m)
            .collect();
        let joint_matrices = model
            .nodes
            .iter()
            .map(|n| match n.skin {
                Some(s) => skin::joint_matrices(model, s, &world_from_node),
                None => Vec::new(),
            })
            .collect();
        TwinFrame {
            world_from_node,
            joint_matrices,
            morph_weights: pose.morph_weights.clone(),
        }
    }

    /// The draws of one frame.
    pub fn draws<'a>(&'a self, frame: &'a TwinFrame) -> Vec<Draw<'a>> {
        self.primitives
            .iter()
            .map(|p| Draw {
                mesh: &p.mesh,
                texture: p.texture.map(|t| &self.textures[t]),
                base_color_factor: p.base_color_factor,
                world_from_mesh: frame.world_from_node[p.node],
                joint_matrices: if p.mesh.is_skinned() {
                    &frame.joint_matrices[p.node]
                } else {
                    &[]
                },
                morph_weights: &frame.morph_weights[p.node],
            })
            .collect()
    }
}
