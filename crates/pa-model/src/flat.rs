//! Flat normals for primitives without a `NORMAL` attribute.
//!
//! glTF 2.0 (3.7.2.1, "Meshes"): "When normals are not specified, client implementations MUST
//! calculate flat normals". A flat normal is the normal of the triangle's plane, the same at
//! its three corners, so a vertex shared by triangles that are not coplanar cannot hold one.
//! The loader computes them once, for both render paths:
//!
//! - A non-indexed triangle list already has its own three vertices per triangle: its
//!   `normals` are filled in place and nothing else changes (the vertex order is the file's).
//! - Any other primitive with triangles (indexed lists, strips and fans, whose triangles share
//!   vertices) keeps the file's vertices untouched (posing, export and the conformance
//!   references compare vertices by their index in the file) and gets a separate, un-welded
//!   copy for drawing ([`Primitive::flat_shaded`], reached through [`Primitive::drawn`]):
//!   triangle `t`'s corners are vertices `3t`, `3t + 1`, `3t + 2` of the copy (indices
//!   `0, 1, 2, ...`), each carrying every per-vertex attribute of the vertex it copies (UVs,
//!   joints and weights, morph target position deltas) and the triangle's normal.
//!
//! Approximations, as for any mesh with per-vertex normals:
//!
//! - Morph targets move positions, not the flat normals: the copy has no morph normal deltas
//!   (a file without `NORMAL` has no base normals for them to change), so a morphed face keeps
//!   its rest-pose normal.
//! - Skinning and node transforms carry each corner's rest normal through that corner's
//!   blended matrix (`pa_model::skin`, `pa-pipeline`'s `cpu_twin`, `pa-render`'s
//!   `skinning.wgsl`), so a face whose corners have the same influences (a rigid part) keeps
//!   an exact flat normal; where the influences differ across a face, the three posed normals
//!   differ slightly and are interpolated, as smooth normals are.
//!
//! A degenerate triangle (no area, or non-finite corners) has no plane; its normal is +Z, an
//! arbitrary unit vector (it covers no pixels in the rest pose).

use glam::{DVec3, Vec3};

use crate::{MorphTarget, Primitive};

/// The unit normal of the triangle `a, b, c`, facing the side from which it winds
/// counter-clockwise (glTF's front face); +Z when the triangle is degenerate.
pub(crate) fn face_normal(a: Vec3, b: Vec3, c: Vec3) -> Vec3 {
    let (a, b, c) = (a.as_dvec3(), b.as_dvec3(), c.as_dvec3());
    let n: DVec3 = (b - a).cross(c - a);
    let len = n.length();
    if len.is_finite() && len > 0.0 {
        (n / len).as_vec3()
    } else {
        Vec3::Z
    }
}

/// The normal of each triangle of `indices` (indices were checked against `positions`).
fn triangle_normals<'a>(
    positions: &'a [Vec3],
    indices: &'a [u32],
) -> impl Iterator<Item = Vec3> + 'a {
    indices.chunks_exact(3).map(move |t| {
        let p = |i: u32| positions.get(i as usize).copied().unwrap_or(Vec3::ZERO);
        face_normal(p(t[0]), p(t[1]), p(t[2]))
    })
}

/// Fills `prim.normals` when no two triangles share a vertex, as in a non-indexed triangle
/// list (indices `0, 1, 2, ...`): each vertex gets its triangle's normal, vertices on no
/// triangle +Z. The caller decides that the primitive is such a list.
pub(crate) fn fill_in_place(prim: &mut Primitive) {
    let mut normals = vec![Vec3::Z; prim.positions.len()];
    for (t, n) in triangle_normals(&prim.positions, &prim.indices).enumerate() {
        for &v in &prim.indices[t * 3..t * 3 + 3] {
            if let Some(slot) = normals.get_mut(v as usize) {
                *slot = n;
            }
        }
    }
    prim.normals = normals;
}

/// The un-welded, flat-shaded copy of `prim` (see the module documentation); `None` when the
/// copy would have more vertices than a `u32` index can name.
pub(crate) fn unwelded(prim: &Primitive) -> Option<Primitive> {
    let corners = prim.indices.len() / 3 * 3;
    let count = u32::try_from(corners).ok()?;
    let idx = &prim.indices[..corners];
    // Indices were checked against the vertex count at load; the default never shows.
    fn gather<T: Copy + Default>(values: &[T], idx: &[u32]) -> Vec<T> {
        if values.is_empty() {
            return Vec::new();
        }
        idx.iter()
            .map(|&i| values.get(i as usize).copied().unwrap_or_default())
            .collect()
    }
    let normals: Vec<Vec3> = triangle_normals(&prim.positions, idx)
        .flat_map(|n| [n; 3])
        .collect();
    let morph_targets = prim
        .morph_targets
        .iter()
        .map(|t| MorphTarget {
            position_deltas: gather(&t.position_deltas, idx),
            normal_deltas: Vec::new(),
        })
        .collect();
    Some(Primitive {
        positions: gather(&prim.positions, idx),
        normals,
        uvs: gather(&prim.uvs, idx),
        joints: gather(&prim.joints, idx),
        weights: gather(&prim.weights, idx),
        indices: (0..count).collect(),
        material: prim.material,
        morph_targets,
        flat_shaded: None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn face_normal_follows_the_counter_clockwise_winding() {
        let n = face_normal(Vec3::ZERO, Vec3::X, Vec3::Y);
        assert_eq!(n, Vec3::Z);
        let n = face_normal(Vec3::ZERO, Vec3::Y, Vec3::X);
        assert_eq!(n, -Vec3::Z);
        // Tiny triangles still have a unit normal (computed in f64).
        let s = 1e-20;
        let n = face_normal(Vec3::ZERO, Vec3::new(0.0, s, 0.0), Vec3::new(0.0, 0.0, s));
        assert!((n - Vec3::X).length() < 1e-6, "{n}");
        // Degenerate and non-finite triangles get +Z.
        assert_eq!(face_normal(Vec3::ZERO, Vec3::X, Vec3::X * 2.0), Vec3::Z);
        assert_eq!(face_normal(Vec3::NAN, Vec3::X, Vec3::Y), Vec3::Z);
    }

    /// Two triangles sharing an edge, folded at a right angle, with a morph target.
    fn folded() -> Primitive {
        Primitive {
            positions: vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z],
            uvs: vec![[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [0.5, 0.5]],
            joints: vec![[1, 0, 0, 0, 0, 0, 0, 0]; 4],
            weights: vec![[1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]; 4],
            indices: vec![0, 1, 2, 0, 3, 1],
            material: Some(0),
            morph_targets: vec![MorphTarget {
                position_deltas: vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z],
                normal_deltas: Vec::new(),
            }],
            ..Primitive::default()
        }
    }

    #[test]
    fn unwelding_copies_every_attribute_per_corner() {
        let p = folded();
        let f = unwelded(&p).expect("small");
        assert_eq!(f.indices, vec![0, 1, 2, 3, 4, 5]);
        let src = [0usize, 1, 2, 0, 3, 1];
        for (k, &s) in src.iter().enumerate() {
            assert_eq!(f.positions[k], p.positions[s]);
            assert_eq!(f.uvs[k], p.uvs[s]);
            assert_eq!(f.joints[k], p.joints[s]);
            assert_eq!(f.weights[k], p.weights[s]);
            assert_eq!(
                f.morph_targets[0].position_deltas[k],
                p.morph_targets[0].position_deltas[s]
            );
        }
        assert!(f.morph_targets[0].normal_deltas.is_empty());
        assert_eq!(&f.normals[..3], &[Vec3::Z; 3]);
        assert_eq!(&f.normals[3..], &[Vec3::Y; 3]);
        assert_eq!(f.material, Some(0));
        assert!(f.flat_shaded.is_none());
    }

    #[test]
    fn absent_attributes_stay_absent() {
        let p = Primitive {
            uvs: Vec::new(),
            joints: Vec::new(),
            weights: Vec::new(),
            morph_targets: Vec::new(),
            ..folded()
        };
        let f = unwelded(&p).expect("small");
        assert!(f.uvs.is_empty() && f.joints.is_empty() && f.weights.is_empty());
        assert_eq!(f.positions.len(), 6);
        assert_eq!(f.normals.len(), 6);
    }

    #[test]
    fn in_place_fills_each_vertex_with_its_triangle_normal() {
        let mut p = Primitive {
            positions: vec![
                Vec3::ZERO,
                Vec3::X,
                Vec3::Y,
                Vec3::ZERO,
                Vec3::new(0.0, 0.0, 1.0),
                Vec3::X,
                Vec3::splat(7.0),
            ],
            indices: vec![0, 1, 2, 3, 4, 5],
            ..Primitive::default()
        };
        fill_in_place(&mut p);
        assert_eq!(
            p.normals,
            vec![
                Vec3::Z,
                Vec3::Z,
                Vec3::Z,
                Vec3::Y,
                Vec3::Y,
                Vec3::Y,
                // On no triangle.
                Vec3::Z
            ]
        );
    }
}
