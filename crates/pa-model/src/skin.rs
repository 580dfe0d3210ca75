//! CPU reference of morphing and linear blend skinning, in glTF world space.
//!
//! For a skinned node, `p_world = sum_i w_i * (world_from_joint_i * joint_from_bind_i) * p`,
//! where `p = base + sum_k m_k * delta_k` (morph targets first); the skinned node's own
//! transform is ignored, as the glTF spec says. For an unskinned node,
//! `p_world = world_from_node * p`. Normals use the inverse transpose of the same (blended)
//! matrix and are renormalised. Flat normals (primitives without NORMAL in the file, see
//! [`crate::Primitive::drawn`]) are the rest pose's face normals carried the same way, per
//! corner: exact for a face whose corners share their influences, approximate otherwise, and
//! unchanged by morph targets.

use glam::{Mat3, Mat4, Vec3};

use crate::anim::Pose;
use crate::{Model, Primitive};

/// A primitive posed in world space.
#[derive(Debug, Clone)]
pub struct PosedPrimitive {
    pub node: usize,
    pub mesh: usize,
    pub primitive: usize,
    /// World-space positions in glTF vertex order ([`pose_drawn_meshes`]: the order of the
    /// primitive as drawn).
    pub positions: Vec<Vec3>,
    /// World-space unit normals (empty when the primitive has none).
    pub normals: Vec<Vec3>,
}

impl PosedPrimitive {
    /// The name used by OBJ export and the conformance references: `node<N>_prim<P>`.
    pub fn label(&self) -> String {
        format!("node{}_prim{}", self.node, self.primitive)
    }
}

/// The skinning matrices of a skin: `world_from_joint * joint_from_bind` per joint.
pub fn joint_matrices(model: &Model, skin: usize, world_from_node: &[Mat4]) -> Vec<Mat4> {
    let skin = &model.skins[skin];
    skin.joints
        .iter()
        .zip(&skin.inverse_bind_matrices)
        .map(|(&j, ibm)| world_from_node[j] * *ibm)
        .collect()
}

/// Applies morph targets: returns morphed (positions, normals) in the primitive's local space.
pub fn morph(prim: &Primitive, weights: &[f32]) -> (Vec<Vec3>, Vec<Vec3>) {
    let mut positions = prim.positions.clone();
    let mut normals = prim.normals.clone();
    for (target, &w) in prim.morph_targets.iter().zip(weights) {
        if w == 0.0 {
            continue;
        }
        for (p, d) in positions.iter_mut().zip(&target.position_deltas) {
            *p += w * *d;
        }
        if !normals.is_empty() {
            for (n, d) in normals.iter_mut().zip(&target.normal_deltas) {
                *n += w * *d;
            }
        }
    }
    (positions, normals)
}

/// Skins positions and normals in place with 8-influence linear blend skinning.
pub fn skin_in_place(
    prim: &Primitive,
    joint_matrices: &[Mat4],
    positions: &mut [Vec3],
    normals: &mut [Vec3],
) {
    for (v, p) in positions.iter_mut().enumerate() {
        let m = blended_matrix(&prim.joints[v], &prim.weights[v], joint_matrices);
        *p = m.transform_point3(*p);
        if let Some(n) = normals.get_mut(v) {
            *n = transform_normal(&m, *n);
        }
    }
}

/// `sum_i w_i M_i` over the non-zero influences (joint indices were checked at load).
pub fn blended_matrix(joints: &[u16; 8], weights: &[f32; 8], joint_matrices: &[Mat4]) -> Mat4 {
    let mut m = Mat4::ZERO;
    for k in 0..8 {
        let w = weights[k];
        if w != 0.0 {
            if let Some(jm) = joint_matrices.get(joints[k] as usize) {
                m += *jm * w;
            }
        }
    }
    m
}

fn transform_normal(m: &Mat4, n: Vec3) -> Vec3 {
    let linear = Mat3::from_mat4(*m);
    let it = if linear.determinant().abs() > 1e-20 {
        linear.inverse().transpose()
    } else {
        linear
    };
    (it * n).normalize_or_zero()
}

/// Poses every mesh node of the model: morph, then skin (or the node transform). Vertices
/// in the file's order (what export and the conformance references use); a primitive whose
/// file has no normals has none here unless they fit in place (see [`Primitive::normals`]).
pub fn pose_meshes(model: &Model, pose: &Pose) -> Vec<PosedPrimitive> {
    pose_with(model, pose, |p| p)
}

/// [`pose_meshes`] of the primitives as they are drawn ([`Primitive::drawn`]): a primitive
/// without normals in the file is posed as its flat-shaded copy (its vertices in that copy's
/// order), so every primitive with triangles has normals. The flat normals are the rest
/// pose's, carried by each corner's matrix like any normal (exact for a rigid part).
pub fn pose_drawn_meshes(model: &Model, pose: &Pose) -> Vec<PosedPrimitive> {
    pose_with(model, pose, Primitive::drawn)
}

fn pose_with(
    model: &Model,
    pose: &Pose,
    pick: impl Fn(&Primitive) -> &Primitive,
) -> Vec<PosedPrimitive> {
    let world = pose.world_from_node(model);
    let mut out = Vec::new();
    for (ni, node) in model.mesh_nodes() {
        let Some(mi) = node.mesh else { continue };
        let skin_mats = node.skin.map(|s| joint_matrices(model, s, &world));
        for (pi, prim) in model.meshes[mi].primitives.iter().enumerate() {
            let prim = pick(prim);
            let (mut positions, mut normals) = morph(prim, &pose.morph_weights[ni]);
            match &skin_mats {
                Some(jm) if !prim.joints.is_empty() => {
                    skin_in_place(prim, jm, &mut positions, &mut normals);
                }
                _ => {
                    let m = world[ni];
                    for p in positions.iter_mut() {
                        *p = m.transform_point3(*p);
                    }
                    for n in normals.iter_mut() {
                        *n = transform_normal(&m, *n);
                    }
                }
            }
            out.push(PosedPrimitive {
                node: ni,
                mesh: mi,
                primitive: pi,
                positions,
                normals,
            });
        }
    }
    out
}

/// Axis-aligned bounds (min, max) of posed primitives; `None` when there are no vertices.
pub fn bounds(posed: &[PosedPrimitive]) -> Option<(Vec3, Vec3)> {
    let mut it = posed.iter().flat_map(|p| p.positions.iter());
    let first = *it.next()?;
    Some(it.fold((first, first), |(lo, hi), p| (lo.min(*p), hi.max(*p))))
}
