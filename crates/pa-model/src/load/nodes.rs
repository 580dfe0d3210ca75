//! Skins and the node hierarchy: transforms, the cycle check, the scene's roots, and the
//! skinned nodes checked against their skins.

use glam::{Mat4, Quat, Vec3};
use gltf::accessor::Dimensions;

use super::Loader;
use crate::accessor::{expect_dims, read_f32_prefix};
use crate::{ErrorKind, LocalTransform, Mesh, Node, Skin, Trs};

impl<'a> Loader<'a> {
    pub(super) fn load_skins(&mut self) -> Result<Vec<Skin>, ErrorKind> {
        let mut skins = Vec::new();
        for skin in self.doc.skins() {
            let index = skin.index();
            let joints: Vec<usize> = skin.joints().map(|j| j.index()).collect();
            if joints.is_empty() {
                return Err(ErrorKind::Skin {
                    index,
                    message: "has no joints".into(),
                });
            }
            let inverse_bind_matrices = match skin.inverse_bind_matrices() {
                Some(acc) => {
                    expect_dims(&acc, &[Dimensions::Mat4], "inverseBindMatrices")?;
                    if acc.count() < joints.len() {
                        return Err(ErrorKind::Skin {
                            index,
                            message: format!(
                                "has {} joints but only {} inverse bind matrices",
                                joints.len(),
                                acc.count()
                            ),
                        });
                    }
                    // Only the matrices of the joints are decoded (a budget counts them).
                    let v = read_f32_prefix(&acc, &self.buffers, joints.len())?;
                    let mats: Vec<Mat4> = v.chunks_exact(16).map(Mat4::from_cols_slice).collect();
                    if mats.iter().any(|m| !m.is_finite()) {
                        return Err(ErrorKind::Skin {
                            index,
                            message: "an inverse bind matrix is not finite".into(),
                        });
                    }
                    mats
                }
                None => vec![Mat4::IDENTITY; joints.len()],
            };
            skins.push(Skin {
                name: skin.name().map(str::to_string),
                joints,
                inverse_bind_matrices,
            });
        }
        Ok(skins)
    }

    /// Nodes with their parents, checked to form a forest. `mesh_targets` is the number of
    /// morph targets of each mesh. Linear in the number of nodes and children.
    pub(super) fn load_nodes(&mut self, mesh_targets: &[usize]) -> Result<Vec<Node>, ErrorKind> {
        let count = self.doc.nodes().len();
        let mut nodes = Vec::with_capacity(count);
        for node in self.doc.nodes() {
            let local = match node.transform() {
                gltf::scene::Transform::Matrix { matrix } => {
                    let m = Mat4::from_cols_array_2d(&matrix);
                    if !m.is_finite() {
                        return Err(ErrorKind::Hierarchy(format!(
                            "node {} has a non-finite matrix",
                            node.index()
                        )));
                    }
                    LocalTransform::Matrix(m)
                }
                gltf::scene::Transform::Decomposed {
                    translation,
                    rotation,
                    scale,
                } => {
                    let t = Trs {
                        translation: Vec3::from(translation),
                        rotation: normalise_quat(Quat::from_array(rotation)),
                        scale: Vec3::from(scale),
                    };
                    if !(t.translation.is_finite() && t.scale.is_finite()) {
                        return Err(ErrorKind::Hierarchy(format!(
                            "node {} has a non-finite transform",
                            node.index()
                        )));
                    }
                    LocalTransform::Trs(t)
                }
            };
            let target_count = node
                .mesh()
                .and_then(|m| mesh_targets.get(m.index()))
                .copied()
                .unwrap_or(0);
            // Only the weights that are used are copied (the budget counts those).
            let mut morph_weights: Vec<f32> = node
                .weights()
                .or_else(|| node.mesh().and_then(|m| m.weights()))
                .map(|w| w.iter().take(target_count).copied().collect())
                .unwrap_or_default();
            morph_weights.resize(target_count, 0.0);
            nodes.push(Node {
                name: node.name().map(str::to_string),
                parent: None,
                children: node.children().map(|c| c.index()).collect(),
                local,
                mesh: node.mesh().map(|m| m.index()),
                skin: node.skin().map(|s| s.index()),
                morph_weights,
            });
        }
        for i in 0..count {
            for k in 0..nodes[i].children.len() {
                let c = nodes[i].children[k];
                if c == i {
                    return Err(ErrorKind::Hierarchy(format!("node {i} is its own child")));
                }
                if let Some(p) = nodes[c].parent {
                    return Err(ErrorKind::Hierarchy(format!(
                        "node {c} has two parents ({p} and {i})"
                    )));
                }
                nodes[c].parent = Some(i);
            }
        }
        let parents: Vec<Option<usize>> = nodes.iter().map(|n| n.parent).collect();
        if let Some(n) = find_cycle(&parents, &mut 0) {
            return Err(ErrorKind::Hierarchy(format!("node {n} is part of a cycle")));
        }
        Ok(nodes)
    }

    /// The root nodes of the default scene (the first scene when none is named; every
    /// parentless node when there is no scene). A scene's entries that are not roots (the
    /// spec requires roots) or that repeat one are dropped with one warning, so that nothing
    /// walking from the roots visits a node twice.
    pub(super) fn roots(&mut self, nodes: &[Node]) -> Vec<usize> {
        let scene = self
            .doc
            .default_scene()
            .or_else(|| self.doc.scenes().next());
        let Some(scene) = scene else {
            return (0..nodes.len())
                .filter(|&i| nodes[i].parent.is_none())
                .collect();
        };
        let mut listed = vec![false; nodes.len()];
        let mut roots = Vec::new();
        let mut dropped = 0usize;
        for n in scene.nodes().map(|n| n.index()) {
            match listed.get_mut(n) {
                Some(seen) if !*seen && nodes[n].parent.is_none() => {
                    *seen = true;
                    roots.push(n);
                }
                _ => dropped += 1,
            }
        }
        if dropped > 0 {
            self.warn(format!(
                "scene {}: {dropped} entries of its node list are repeated or not root nodes; \
                 they were ignored",
                scene.index()
            ));
        }
        roots
    }
}

/// Finds a node on a cycle of the parent links (each node has at most one parent), or
/// `None`. Linear: every node is entered once and finished once (`steps` counts the loop
/// iterations, for tests).
fn find_cycle(parents: &[Option<usize>], steps: &mut usize) -> Option<usize> {
    const NEW: u8 = 0;
    const ON_WALK: u8 = 1;
    const DONE: u8 = 2;
    let mut state = vec![NEW; parents.len()];
    for start in 0..parents.len() {
        if state[start] != NEW {
            continue;
        }
        // Walk up until a root or a node already known to reach one.
        let mut at = start;
        loop {
            *steps += 1;
            match state[at] {
                ON_WALK => return Some(at),
                DONE => break,
                _ => {}
            }
            state[at] = ON_WALK;
            match parents[at] {
                Some(p) => at = p,
                None => break,
            }
        }
        // Everything on this walk reaches a root.
        let mut at = start;
        while state[at] == ON_WALK {
            *steps += 1;
            state[at] = DONE;
            match parents[at] {
                Some(p) => at = p,
                None => break,
            }
        }
    }
    None
}

/// Checks every skinned node's primitives against its skin. Linear: the largest joint each
/// primitive uses is found once, and a node's primitives are scanned vertex by vertex only to
/// report the first bad vertex.
pub(super) fn check_skinned_nodes(
    nodes: &[Node],
    meshes: &[Mesh],
    skins: &[Skin],
) -> Result<(), ErrorKind> {
    // Per mesh, per primitive: the largest joint index with a non-zero weight.
    let max_joint: Vec<Vec<Option<u16>>> = meshes
        .iter()
        .map(|m| {
            m.primitives
                .iter()
                .map(|p| {
                    p.joints
                        .iter()
                        .zip(&p.weights)
                        .flat_map(|(j, w)| (0..8).filter(|&k| w[k] > 0.0).map(move |k| j[k]))
                        .max()
                })
                .collect()
        })
        .collect();
    for (ni, node) in nodes.iter().enumerate() {
        let (Some(mi), Some(si)) = (node.mesh, node.skin) else {
            continue;
        };
        let (Some(mesh), Some(skin)) = (meshes.get(mi), skins.get(si)) else {
            continue;
        };
        let joint_count = skin.joints.len();
        for (pi, prim) in mesh.primitives.iter().enumerate() {
            let fits = match max_joint[mi][pi] {
                Some(j) => (j as usize) < joint_count,
                None => true,
            };
            if fits {
                continue;
            }
            for (v, (j, w)) in prim.joints.iter().zip(&prim.weights).enumerate() {
                for k in 0..8 {
                    if w[k] > 0.0 && j[k] as usize >= joint_count {
                        return Err(ErrorKind::JointOutOfRange {
                            node: ni,
                            mesh: mi,
                            primitive: pi,
                            vertex: v,
                            joint: j[k] as u32,
                            joint_count,
                        });
                    }
                }
            }
        }
    }
    Ok(())
}

fn normalise_quat(q: Quat) -> Quat {
    let len = q.length();
    if len.is_finite() && len > 1e-12 {
        q / len
    } else {
        Quat::IDENTITY
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_cycle_check_is_linear_on_a_deep_chain() {
        // Node i's parent is i - 1: visiting from every node used to walk to the root each
        // time (n^2 / 2 steps); now each node is entered and finished once.
        let n: usize = 100_000;
        let parents: Vec<Option<usize>> = (0..n).map(|i| i.checked_sub(1)).collect();
        let mut steps = 0;
        assert_eq!(find_cycle(&parents, &mut steps), None);
        assert!(steps <= 3 * n, "{steps} steps for {n} nodes");
        // Children listed before their parents (the chain reversed) too.
        let parents: Vec<Option<usize>> = (0..n).map(|i| (i + 1 < n).then_some(i + 1)).collect();
        let mut steps = 0;
        assert_eq!(find_cycle(&parents, &mut steps), None);
        assert!(steps <= 3 * n, "{steps} steps for {n} nodes");
    }

    #[test]
    fn the_cycle_check_finds_cycles_anywhere() {
        // 0 <- 1 <- 2 <- 0 (a cycle), 3 a root, 4 <- 3.
        let parents = [Some(2), Some(0), Some(1), None, Some(3)];
        let found = find_cycle(&parents, &mut 0).expect("a cycle");
        assert!(found < 3, "{found}");
        // A tail leading into a cycle: 5 -> 6 -> 7 -> 6.
        let parents = [None, Some(0), None, None, None, Some(6), Some(7), Some(6)];
        let found = find_cycle(&parents, &mut 0).expect("a cycle");
        assert!(found == 6 || found == 7, "{found}");
        assert_eq!(find_cycle(&[None, Some(0), Some(0), Some(2)], &mut 0), None);
    }
}
