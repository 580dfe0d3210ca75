//! Budgets: what a document asks the loader to decode, added up from its declared counts
//! before anything is decoded (see the crate documentation for the table of budgets).
//!
//! The sums mirror what `load` allocates for [`crate::Model`]: positions 12 bytes a vertex,
//! normals 12, UVs 8, joints and weights 48 (16 + 32, for up to 8 influences), triangle
//! indices 4 bytes each (3 per index for strips and fans, an upper bound), inverse bind
//! matrices 64 bytes per joint, morph target deltas 12 bytes a vertex (positions always,
//! normals when present), morph weights 4 bytes per target per node, and per animation channel
//! its key times (4 bytes each) and values (4 bytes per component) plus a fixed overhead.
//! A primitive with triangles but no NORMAL also counts its flat normals (`crate::flat`): 12
//! bytes a vertex in place for a non-indexed triangle list, otherwise an un-welded copy of 3
//! vertices per triangle (positions, normals, an index, UVs and joints and weights when
//! present; 12 bytes of morph deltas per target), whose vertices are drawn too.
//! Arithmetic saturates, so an absurd count cannot wrap around into a small total.

use gltf::mesh::{Mode, Semantic};

use crate::accessor::component_count;
use crate::{Channel, ErrorKind, Limits};

/// A running total against one budget.
struct Tally {
    what: &'static str,
    budget: &'static str,
    unit: &'static str,
    limit: u64,
    total: u64,
}

impl Tally {
    fn new(what: &'static str, budget: &'static str, unit: &'static str, limit: u64) -> Self {
        Self {
            what,
            budget,
            unit,
            limit,
            total: 0,
        }
    }

    /// Adds `amount`, failing as soon as the total is over the limit; `at` names the object
    /// that made it run out.
    fn add(&mut self, amount: u64, at: impl FnOnce() -> String) -> Result<(), ErrorKind> {
        self.total = self.total.saturating_add(amount);
        if self.total > self.limit {
            Err(ErrorKind::OverBudget {
                what: self.what,
                budget: self.budget,
                unit: self.unit,
                needed: self.total,
                limit: self.limit,
                at: at(),
            })
        } else {
            Ok(())
        }
    }
}

/// Bytes of `count` elements of `bytes_each` bytes, saturating.
fn bytes(count: usize, bytes_each: u64) -> u64 {
    (count as u64).saturating_mul(bytes_each)
}

/// Checks the document against every budget of `limits` except the image ones (images are
/// checked as they are decoded, from their headers).
pub(crate) fn check(doc: &gltf::Document, limits: &Limits) -> Result<(), ErrorKind> {
    let node_count = doc.nodes().len();
    Tally::new("the node hierarchy", "max_nodes", "nodes", limits.max_nodes)
        .add(node_count as u64, || "the nodes array".into())?;

    let mut vertex = Tally::new(
        "decoded vertex data",
        "max_vertex_bytes",
        "bytes",
        limits.max_vertex_bytes,
    );
    let mut morph = Tally::new(
        "decoded morph target data",
        "max_morph_bytes",
        "bytes",
        limits.max_morph_bytes,
    );
    let mut anim = Tally::new(
        "decoded animation data",
        "max_animation_bytes",
        "bytes",
        limits.max_animation_bytes,
    );
    let mut instanced = Tally::new(
        "the vertices drawn (each mesh node counts its mesh's vertices)",
        "max_instanced_vertices",
        "vertices",
        limits.max_instanced_vertices,
    );

    // Per mesh: its vertex count and its largest number of morph targets.
    let mut mesh_vertices = Vec::with_capacity(doc.meshes().len());
    let mut mesh_targets = Vec::with_capacity(doc.meshes().len());
    for mesh in doc.meshes() {
        let mut vertices = 0u64;
        let mut targets = 0usize;
        for prim in mesh.primitives() {
            let at =
                |what: &str| format!("mesh {} primitive {} {what}", mesh.index(), prim.index());
            let n = prim
                .get(&Semantic::Positions)
                .map(|a| a.count())
                .unwrap_or(0);
            vertices = vertices.saturating_add(n as u64);
            vertex.add(bytes(n, 12), || at("POSITION"))?;
            if let Some(a) = prim.get(&Semantic::Normals) {
                vertex.add(bytes(a.count(), 12), || at("NORMAL"))?;
            }
            if let Some(a) = prim.get(&Semantic::TexCoords(0)) {
                vertex.add(bytes(a.count(), 8), || at("TEXCOORD_0"))?;
            }
            if prim.get(&Semantic::Joints(0)).is_some() {
                vertex.add(bytes(n, 48), || at("JOINTS_0/WEIGHTS_0"))?;
            }
            let k = prim.indices().map(|a| a.count()).unwrap_or(n);
            let per_index = match prim.mode() {
                Mode::TriangleStrip | Mode::TriangleFan => 12,
                _ => 4,
            };
            vertex.add(bytes(k, per_index), || at("indices"))?;
            let mut prim_targets = 0usize;
            for (ti, target) in prim.morph_targets().enumerate() {
                prim_targets += 1;
                morph.add(bytes(n, 12), || at(&format!("morph target {ti} POSITION")))?;
                if let Some(a) = target.normals() {
                    morph.add(bytes(a.count(), 12), || {
                        at(&format!("morph target {ti} NORMAL"))
                    })?;
                }
            }
            targets = targets.max(prim_targets);
            if prim.get(&Semantic::Normals).is_none() {
                // Flat normals (`crate::flat`): in place for a non-indexed triangle list,
                // else an un-welded copy of 3 vertices per triangle.
                let corners = match prim.mode() {
                    Mode::Triangles => k / 3 * 3,
                    Mode::TriangleStrip | Mode::TriangleFan => {
                        k.saturating_sub(2).saturating_mul(3)
                    }
                    _ => 0,
                };
                let in_place = prim.indices().is_none() && prim.mode() == Mode::Triangles;
                if corners > 0 && in_place {
                    vertex.add(bytes(n, 12), || at("flat normals"))?;
                } else if corners > 0 {
                    let mut per_corner = 12 + 12 + 4;
                    if prim.get(&Semantic::TexCoords(0)).is_some() {
                        per_corner += 8;
                    }
                    if prim.get(&Semantic::Joints(0)).is_some() {
                        per_corner += 48;
                    }
                    vertex.add(bytes(corners, per_corner), || at("flat-shaded copy"))?;
                    morph.add(
                        bytes(corners, 12).saturating_mul(prim_targets as u64),
                        || at("flat-shaded copy's morph targets"),
                    )?;
                    vertices = vertices.saturating_add(corners as u64);
                }
            }
        }
        mesh_vertices.push(vertices);
        mesh_targets.push(targets);
    }

    for skin in doc.skins() {
        if skin.inverse_bind_matrices().is_some() {
            vertex.add(bytes(skin.joints().len(), 64), || {
                format!("skin {} inverseBindMatrices", skin.index())
            })?;
        }
    }

    for node in doc.nodes() {
        if let Some(m) = node.mesh() {
            let at = || format!("node {} (mesh {})", node.index(), m.index());
            let vertices = mesh_vertices.get(m.index()).copied().unwrap_or(0);
            instanced.add(vertices, at)?;
            let targets = mesh_targets.get(m.index()).copied().unwrap_or(0);
            morph.add(bytes(targets, 4), || {
                format!("node {} morph weights", node.index())
            })?;
        }
    }

    let per_channel = std::mem::size_of::<Channel>() as u64;
    for a in doc.animations() {
        for channel in a.channels() {
            let at = || format!("animation {} channel {}", a.index(), channel.index());
            let sampler = channel.sampler();
            let output = sampler.output();
            let values = bytes(
                output.count(),
                4 * component_count(output.dimensions()) as u64,
            );
            let cost = per_channel
                .saturating_add(bytes(sampler.input().count(), 4))
                .saturating_add(values);
            anim.add(cost, at)?;
        }
    }
    Ok(())
}
