//! The digital twin for the CPU path ([`pa_raster`]): the model's base-colour images as
//! mip-mapped linear textures (built once), and per frame the model posed on the CPU
//! (`pa_model::skin`) into reusable buffers, placed on the marker, as draw data.
//!
//! The counterpart of [`crate::twin::GpuTwin`]: the same primitives, the same order, the same
//! placement (`world` is the marker frame: `world_from_model = marker_from_prop`). Both draw
//! each primitive as [`pa_model::Primitive::drawn`] (flat-shaded when the file has no
//! normals).

use glam::{Mat3, Mat4, Vec3};
use pa_model::{anim::Pose, skin, Model};
use pa_raster::{CpuDepthMesh, CpuLiveMesh, CpuMipTexture, CpuPosedMesh, RasterError};

/// One posed primitive: world positions and normals.
#[derive(Debug, Clone, Default)]
pub struct PosedBuffers {
    pub positions_world: Vec<Vec3>,
    pub normals_world: Vec<Vec3>,
    pub mirrored: bool,
}

/// A primitive of a mesh node, as the CPU path draws it.
#[derive(Debug, Clone)]
pub struct CpuTwinPrimitive {
    pub node: usize,
    pub mesh: usize,
    pub primitive: usize,
    pub texture: Option<usize>,
    pub base_color_factor: [f32; 4],
    /// Closed and outward in the bind pose: back faces are culled (the image is unchanged).
    pub closed: bool,
}

/// A model prepared for the CPU renderer.
pub struct CpuTwin {
    pub primitives: Vec<CpuTwinPrimitive>,
    pub textures: Vec<CpuMipTexture>,
    /// Animated pose, per primitive.
    pub anim: Vec<PosedBuffers>,
    /// Key pose, per primitive.
    pub key: Vec<PosedBuffers>,
}

impl CpuTwin {
    /// The key pose's primitives in the world (marker) frame, as
    /// [`crate::shading::irradiance_samples_from`] takes them: `(mesh, primitive, positions,
    /// normals)`.
    pub fn key_parts(&self) -> impl Iterator<Item = (usize, usize, &[Vec3], &[Vec3])> + Clone {
        self.primitives.iter().zip(&self.key).map(|(tp, k)| {
            (
                tp.mesh,
                tp.primitive,
                k.positions_world.as_slice(),
                k.normals_world.as_slice(),
            )
        })
    }

    /// Builds the textures' mip chains and lists the drawable primitives (those with
    /// triangles), in [`crate::twin::GpuTwin::upload`]'s order.
    pub fn new(model: &Model) -> Result<Self, RasterError> {
        let textures = model
            .images
            .iter()
            .map(|im| CpuMipTexture::from_srgb8(im.width, im.height, &im.rgba8))
            .collect::<Result<Vec<_>, _>>()?;
        let mut primitives = Vec::new();
        for (ni, node) in model.mesh_nodes() {
            let Some(mi) = node.mesh else { continue };
            for (pi, prim) in model.meshes[mi].primitives.iter().enumerate() {
                let prim = prim.drawn();
                if prim.indices.is_empty() {
                    continue;
                }
                let material = prim.material.and_then(|m| model.materials.get(m));
                primitives.push(CpuTwinPrimitive {
                    node: ni,
                    mesh: mi,
                    primitive: pi,
                    texture: material
                        .and_then(|m| m.base_color_image)
                        .filter(|&i| i < textures.len()),
                    base_color_factor: material.map(|m| m.base_color_factor).unwrap_or([1.0; 4]),
                    closed: pa_raster::mesh::closed_and_outward(&prim.positions, &prim.indices),
                });
            }
        }
        let n = primitives.len();
        Ok(Self {
            primitives,
            textures,
            anim: vec![PosedBuffers::default(); n],
            key: vec![PosedBuffers::default(); n],
        })
    }

    /// Poses the model at `anim` and `key` and places both by `world_from_model`.
    pub fn pose(&mut self, model: &Model, anim: &Pose, key: &Pose, world_from_model: Mat4) {
        let prims = &self.primitives;
        let (a, k) = (&mut self.anim, &mut self.key);
        rayon::join(
            || pose_into(model, prims, anim, world_from_model, a),
            || pose_into(model, prims, key, world_from_model, k),
        );
    }

    /// The draw data of the posed frame (animated pose with its key pose).
    pub fn live_meshes<'a>(&'a self, model: &'a Model) -> Vec<CpuLiveMesh<'a>> {
        self.meshes_at(model, &self.anim)
    }

    /// The key pose drawn as a plain mesh (key positions for both poses).
    pub fn key_meshes<'a>(&'a self, model: &'a Model) -> Vec<CpuLiveMesh<'a>> {
        self.meshes_at(model, &self.key)
    }

    /// Draw data of the primitives posed as `posed`, each with its key pose.
    fn meshes_at<'a>(
        &'a self,
        model: &'a Model,
        posed: &'a [PosedBuffers],
    ) -> Vec<CpuLiveMesh<'a>> {
        self.primitives
            .iter()
            .zip(posed.iter().zip(&self.key))
            .map(|(p, (pose, key))| CpuLiveMesh {
                mesh: self.posed_mesh(model, p, pose),
                key_positions_world: &key.positions_world,
                key_normals_world: &key.normals_world,
                memory: &[],
                sun_lit: &[],
            })
            .collect()
    }

    /// The key pose for its depth (the visibility map).
    pub fn key_depth_meshes<'a>(&'a self, model: &'a Model) -> Vec<CpuDepthMesh<'a>> {
        self.primitives
            .iter()
            .enumerate()
            .map(|(i, p)| CpuDepthMesh {
                positions_world: &self.key[i].positions_world,
                indices: &model.meshes[p.mesh].primitives[p.primitive].drawn().indices,
                mirrored: self.key[i].mirrored,
                cull_back_faces: p.closed,
            })
            .collect()
    }

    fn posed_mesh<'a>(
        &'a self,
        model: &'a Model,
        p: &CpuTwinPrimitive,
        posed: &'a PosedBuffers,
    ) -> CpuPosedMesh<'a> {
        let prim = model.meshes[p.mesh].primitives[p.primitive].drawn();
        CpuPosedMesh {
            positions_world: &posed.positions_world,
            normals_world: &posed.normals_world,
            uvs: &prim.uvs,
            indices: &prim.indices,
            albedo: p.texture.map(|t| &self.textures[t]),
            base_color_factor: p.base_color_factor,
            mirrored: posed.mirrored,
            cull_back_faces: p.closed,
        }
    }
}

/// Morphs and skins (or transforms) each primitive at `pose`, into `out` (reused buffers,
/// no allocation once they have grown). The same arithmetic as the GPU path's vertex stage
/// (`skinning.wgsl`): morph, blend the joint matrices of the 8 influences, transform the
/// position, and the normal by the blended matrix's cofactor (sign-corrected, normalised;
/// `(0, 0, 1)` when it vanishes); unskinned nodes use their world matrix and its inverse
/// transpose.
fn pose_into(
    model: &Model,
    primitives: &[CpuTwinPrimitive],
    pose: &Pose,
    world_from_model: Mat4,
    out: &mut [PosedBuffers],
) {
    let world_from_node: Vec<Mat4> = pose
        .world_from_node(model)
        .into_iter()
        .map(|m| world_from_model * m)
        .collect();
    let mut skin_cache: Vec<Option<Vec<Mat4>>> = vec![None; model.nodes.len()];
    for (p, buf) in primitives.iter().zip(out.iter_mut()) {
        let prim = model.meshes[p.mesh].primitives[p.primitive].drawn();
        let node = &model.nodes[p.node];
        let weights = pose
            .morph_weights
            .get(p.node)
            .map(Vec::as_slice)
            .unwrap_or(&[]);
        let morphed = weights.iter().any(|&w| w != 0.0) && !prim.morph_targets.is_empty();
        let (positions, normals): (std::borrow::Cow<'_, [Vec3]>, std::borrow::Cow<'_, [Vec3]>) =
            if morphed {
                let (p, n) = skin::morph(prim, weights);
                (p.into(), n.into())
            } else {
                (
                    prim.positions.as_slice().into(),
                    prim.normals.as_slice().into(),
                )
            };
        let n = positions.len();
        buf.positions_world.resize(n, Vec3::ZERO);
        buf.normals_world.resize(normals.len(), Vec3::ZERO);
        match node.skin {
            Some(s) if !prim.joints.is_empty() => {
                let joints = skin_cache[p.node]
                    .get_or_insert_with(|| skin::joint_matrices(model, s, &world_from_node));
                for v in 0..n {
                    let m = skin::blended_matrix(&prim.joints[v], &prim.weights[v], joints);
                    buf.positions_world[v] = m.transform_point3(positions[v]);
                    if let Some(nrm) = normals.get(v) {
                        buf.normals_world[v] = cofactor_normal(&m, *nrm);
                    }
                }
                buf.mirrored = false;
            }
            _ => {
                let m = world_from_node[p.node];
                let linear = Mat3::from_mat4(m);
                let it = if linear.determinant().abs() > 1e-20 {
                    linear.inverse().transpose()
                } else {
                    linear
                };
                for (o, q) in buf.positions_world.iter_mut().zip(positions.iter()) {
                    *o = m.transform_point3(*q);
                }
                for (o, q) in buf.normals_world.iter_mut().zip(normals.iter()) {
                    *o = (it * *q).normalize_or_zero();
                }
                buf.mirrored = m.determinant() < 0.0;
            }
        }
    }
}

/// The normal transformed by the cofactor of `m`'s linear part (the inverse transpose times
/// the determinant), flipped for a negative determinant, normalised; `(0, 0, 1)` when it
/// vanishes (as `transform_normal` in `skinning.wgsl`).
#[inline]
fn cofactor_normal(m: &Mat4, n: Vec3) -> Vec3 {
    let (c0, c1, c2) = (
        m.x_axis.truncate(),
        m.y_axis.truncate(),
        m.z_axis.truncate(),
    );
    let cof = Mat3::from_cols(c1.cross(c2), c2.cross(c0), c0.cross(c1));
    let det = c0.dot(cof.x_axis);
    let t = if det < 0.0 { -(cof * n) } else { cof * n };
    let len2 = t.length_squared();
    if len2 > 1e-30 {
        t / len2.sqrt()
    } else {
        Vec3::Z
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cofactor_normal_is_the_inverse_transpose_direction() {
        let m = Mat4::from_scale_rotation_translation(
            Vec3::new(1.0, 2.0, 0.5),
            glam::Quat::from_rotation_y(0.7),
            Vec3::new(1.0, 2.0, 3.0),
        );
        let n = Vec3::new(0.3, -0.5, 0.8).normalize();
        let it = Mat3::from_mat4(m).inverse().transpose();
        let want = (it * n).normalize();
        assert!((cofactor_normal(&m, n) - want).length() < 1e-5);
        // Mirrored: still the outward direction of the inverse transpose.
        let mm = Mat4::from_scale(Vec3::new(-1.0, 1.0, 1.0)) * m;
        let want = (Mat3::from_mat4(mm).inverse().transpose() * n).normalize();
        assert!((cofactor_normal(&mm, n) - want).length() < 1e-5);
        assert_eq!(cofactor_normal(&Mat4::ZERO, n), Vec3::Z);
    }
}
