//! Meshes: each primitive's attributes, indices, morph targets and skin influences.

use glam::Vec3;
use gltf::accessor::{DataType, Dimensions};
use gltf::mesh::{Mode, Semantic};

use super::Loader;
use crate::accessor::{expect_dims, read_f32, read_u32, read_vec3};
use crate::{ErrorKind, Mesh, MorphTarget, Primitive};

/// Weight sums further than this from 1 are reported (they are always renormalised).
const WEIGHT_SUM_WARN: f32 = 1e-3;
impl<'a> Loader<'a> {
    pub(super) fn load_meshes(&mut self) -> Result<Vec<Mesh>, ErrorKind> {
        let mut meshes = Vec::new();
        for mesh in self.doc.meshes() {
            let mut primitives = Vec::new();
            for prim in mesh.primitives() {
                primitives.push(self.load_primitive(mesh.index(), &prim)?);
            }
            meshes.push(Mesh {
                name: mesh.name().map(str::to_string),
                primitives,
            });
        }
        Ok(meshes)
    }

    fn load_primitive(
        &mut self,
        mesh: usize,
        prim: &gltf::Primitive<'_>,
    ) -> Result<Primitive, ErrorKind> {
        let primitive = prim.index();
        let perr = |message: String| ErrorKind::Primitive {
            mesh,
            primitive,
            message,
        };
        let pos_acc = prim
            .get(&Semantic::Positions)
            .ok_or_else(|| perr("has no POSITION attribute".into()))?;
        let positions = read_vec3(&pos_acc, &self.buffers, "POSITION")?;
        let n = positions.len();
        let check_count = |acc: &gltf::Accessor<'_>, what: &str| -> Result<(), ErrorKind> {
            if acc.count() != n {
                Err(ErrorKind::Primitive {
                    mesh,
                    primitive,
                    message: format!("{what} has {} elements but POSITION has {n}", acc.count()),
                })
            } else {
                Ok(())
            }
        };

        let normals = match prim.get(&Semantic::Normals) {
            Some(acc) => {
                check_count(&acc, "NORMAL")?;
                read_vec3(&acc, &self.buffers, "NORMAL")?
            }
            None => Vec::new(),
        };
        let uvs = match prim.get(&Semantic::TexCoords(0)) {
            Some(acc) => {
                check_count(&acc, "TEXCOORD_0")?;
                expect_dims(&acc, &[Dimensions::Vec2], "TEXCOORD_0")?;
                read_f32(&acc, &self.buffers)?
                    .chunks_exact(2)
                    .map(|c| [c[0], c[1]])
                    .collect()
            }
            None => Vec::new(),
        };

        let (joints, weights) = self.load_influences(mesh, primitive, prim, n)?;

        let mut indices = match prim.indices() {
            Some(acc) => {
                expect_dims(&acc, &[Dimensions::Scalar], "indices")?;
                read_u32(&acc, &self.buffers)?
            }
            None => (0..n as u32).collect(),
        };
        if let Some((k, &bad)) = indices.iter().enumerate().find(|(_, &i)| i as usize >= n) {
            return Err(perr(format!("index {k} is {bad}, past the {n} vertices")));
        }
        indices = match prim.mode() {
            Mode::Triangles => {
                let whole = indices.len() / 3 * 3;
                indices.truncate(whole);
                indices
            }
            Mode::TriangleStrip => (2..indices.len())
                .flat_map(|i| {
                    if i % 2 == 0 {
                        [indices[i - 2], indices[i - 1], indices[i]]
                    } else {
                        [indices[i - 1], indices[i - 2], indices[i]]
                    }
                })
                .collect(),
            Mode::TriangleFan => (2..indices.len())
                .flat_map(|i| [indices[0], indices[i - 1], indices[i]])
                .collect(),
            other => {
                self.warn(format!(
                    "mesh {mesh} primitive {primitive}: mode {other:?} has no triangles; it is \
                     kept for skinning but not drawn"
                ));
                Vec::new()
            }
        };

        let mut morph_targets = Vec::new();
        for target in prim.morph_targets() {
            let position_deltas = match target.positions() {
                Some(acc) => {
                    check_count(&acc, "morph target POSITION")?;
                    read_vec3(&acc, &self.buffers, "morph target POSITION")?
                }
                None => vec![Vec3::ZERO; n],
            };
            let normal_deltas = match target.normals() {
                Some(acc) => {
                    check_count(&acc, "morph target NORMAL")?;
                    read_vec3(&acc, &self.buffers, "morph target NORMAL")?
                }
                None => Vec::new(),
            };
            morph_targets.push(MorphTarget {
                position_deltas,
                normal_deltas,
            });
        }

        let has_normals = !normals.is_empty();
        let mut out = Primitive {
            positions,
            normals,
            uvs,
            joints,
            weights,
            indices,
            material: prim.material().index(),
            morph_targets,
            flat_shaded: None,
        };
        // glTF: without NORMAL, flat normals (see `crate::flat`). The choice between in place
        // and a copy depends on the file's structure only, as the budget counted it.
        if !has_normals && !out.indices.is_empty() {
            if prim.indices().is_none() && prim.mode() == Mode::Triangles {
                crate::flat::fill_in_place(&mut out);
            } else {
                let copy = crate::flat::unwelded(&out).ok_or_else(|| {
                    perr(format!(
                        "has no NORMAL, and its {} triangles have too many corners (over \
                         2^32) for the flat-shaded copy",
                        out.triangle_count()
                    ))
                })?;
                out.flat_shaded = Some(Box::new(copy));
            }
        }
        Ok(out)
    }

    /// JOINTS_0/1 and WEIGHTS_0/1: up to 8 influences, validated and normalised.
    #[allow(clippy::type_complexity)]
    fn load_influences(
        &mut self,
        mesh: usize,
        primitive: usize,
        prim: &gltf::Primitive<'_>,
        n: usize,
    ) -> Result<(Vec<[u16; 8]>, Vec<[f32; 8]>), ErrorKind> {
        let mut joints = Vec::new();
        let mut weights = Vec::new();
        for set in 0..2u32 {
            let (j, w) = (
                prim.get(&Semantic::Joints(set)),
                prim.get(&Semantic::Weights(set)),
            );
            let (j, w) = match (j, w) {
                (None, None) => break,
                (Some(j), Some(w)) => (j, w),
                _ => {
                    return Err(ErrorKind::Primitive {
                        mesh,
                        primitive,
                        message: format!("JOINTS_{set} and WEIGHTS_{set} must come together"),
                    })
                }
            };
            for (acc, what) in [(&j, "JOINTS"), (&w, "WEIGHTS")] {
                expect_dims(acc, &[Dimensions::Vec4], what)?;
                if acc.count() != n {
                    return Err(ErrorKind::Primitive {
                        mesh,
                        primitive,
                        message: format!(
                            "{what}_{set} has {} elements but POSITION has {n}",
                            acc.count()
                        ),
                    });
                }
            }
            if !matches!(j.data_type(), DataType::U8 | DataType::U16) {
                return Err(ErrorKind::Accessor {
                    index: j.index(),
                    message: format!(
                        "JOINTS_{set} must be unsigned byte or short, found {:?}",
                        j.data_type()
                    ),
                });
            }
            let jv = read_u32(&j, &self.buffers)?;
            let wv = read_f32(&w, &self.buffers)?;
            if set == 0 {
                joints = vec![[0u16; 8]; n];
                weights = vec![[0f32; 8]; n];
            }
            let base = set as usize * 4;
            for v in 0..n {
                for k in 0..4 {
                    joints[v][base + k] = jv[v * 4 + k] as u16;
                    weights[v][base + k] = wv[v * 4 + k];
                }
            }
        }
        let mut renormalised = 0usize;
        for (v, w) in weights.iter_mut().enumerate() {
            let bad = |message: String| ErrorKind::InvalidWeights {
                mesh,
                primitive,
                vertex: v,
                message,
            };
            if let Some(x) = w.iter().find(|x| !x.is_finite()) {
                return Err(bad(format!("weight {x} is not a finite number")));
            }
            if let Some(x) = w.iter().find(|&&x| x < 0.0) {
                return Err(bad(format!("weight {x} is negative")));
            }
            let sum: f32 = w.iter().sum();
            if sum <= 1e-12 {
                return Err(bad("all weights are zero".into()));
            }
            if (sum - 1.0).abs() > WEIGHT_SUM_WARN {
                renormalised += 1;
            }
            if sum != 1.0 {
                for x in w.iter_mut() {
                    *x /= sum;
                }
            }
        }
        // Unused influence slots must not point anywhere odd: zero-weight joints are reset.
        for (j, w) in joints.iter_mut().zip(&weights) {
            for k in 0..8 {
                if w[k] == 0.0 {
                    j[k] = 0;
                }
            }
        }
        if renormalised > 0 {
            self.warn(format!(
                "mesh {mesh} primitive {primitive}: skin weights of {renormalised} vertices do \
                 not sum to 1; they were normalised"
            ));
        }
        Ok((joints, weights))
    }
}
