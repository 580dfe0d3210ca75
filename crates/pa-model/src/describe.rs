//! A human-readable description of a loaded model (what `propsalive inspect` prints): the
//! counts, the node tree with each node's mesh, skin and matrix flag, the skins with their
//! joints, the animations, the textures and the loader's warnings. Bounded: linear in the
//! model's size, names and joint lists cut short.

use std::fmt::Write as _;

use crate::{LocalTransform, Model};

/// Tree levels indented by two spaces each; deeper nodes print their depth as a number
/// instead, so every line has a bounded length and the output is linear in the model.
const MAX_INDENT_DEPTH: usize = 16;
/// Joint names listed per skin before "... and N more".
const MAX_LISTED_JOINTS: usize = 32;
/// Characters of a name printed (names are the file's text, of any length).
const MAX_NAME_CHARS: usize = 64;

/// A name from the file, cut to [`MAX_NAME_CHARS`] characters.
fn name(n: Option<&str>) -> String {
    let n = n.unwrap_or("-");
    match n.char_indices().nth(MAX_NAME_CHARS) {
        Some((cut, _)) => format!("{}...", &n[..cut]),
        None => n.to_string(),
    }
}

/// A human-readable description of a model. Its size is linear in the model's: every node is
/// printed at most once (however the scene lists it), with at most [`MAX_INDENT_DEPTH`]
/// levels of indentation, and names and joint lists are cut short.
pub fn describe(model: &Model) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "model      {}", model.path.display());
    let _ = writeln!(
        s,
        "counts     {} nodes, {} meshes, {} skins, {} animations, {} vertices, {} triangles",
        model.nodes.len(),
        model.meshes.len(),
        model.skins.len(),
        model.animations.len(),
        model.vertex_count(),
        model.triangle_count()
    );
    let _ = writeln!(s, "\nnodes");
    // Per mesh (computed once, not per node): primitives, vertices, triangles.
    let mesh_stats: Vec<(usize, usize, usize)> = model
        .meshes
        .iter()
        .map(|m| {
            let v = m.primitives.iter().map(|p| p.positions.len()).sum();
            let t = m.primitives.iter().map(|p| p.triangle_count()).sum();
            (m.primitives.len(), v, t)
        })
        .collect();
    let mut printed = vec![false; model.nodes.len()];
    let mut stack: Vec<(usize, usize)> = model.roots.iter().rev().map(|&r| (r, 0)).collect();
    while let Some((i, depth)) = stack.pop() {
        let (Some(n), Some(seen)) = (model.nodes.get(i), printed.get_mut(i)) else {
            continue;
        };
        if std::mem::replace(seen, true) {
            continue;
        }
        let mut line = String::from("  ");
        line.push_str(&"  ".repeat(depth.min(MAX_INDENT_DEPTH)));
        if depth > MAX_INDENT_DEPTH {
            let _ = write!(line, "(depth {depth}) ");
        }
        let _ = write!(line, "[{i}] {}", name(n.name.as_deref()));
        if let Some(m) = n.mesh {
            if let Some((prims, v, t)) = mesh_stats.get(m) {
                let _ = write!(
                    line,
                    "  mesh {m} ({prims} primitives, {v} vertices, {t} triangles)"
                );
            }
        }
        if let Some(sk) = n.skin {
            let _ = write!(line, "  skin {sk}");
        }
        if matches!(n.local, LocalTransform::Matrix(_)) {
            line.push_str("  (matrix)");
        }
        let _ = writeln!(s, "{line}");
        for &c in n.children.iter().rev() {
            stack.push((c, depth + 1));
        }
    }
    if !model.skins.is_empty() {
        let _ = writeln!(s, "\nskins");
        for (i, sk) in model.skins.iter().enumerate() {
            let mut names: Vec<String> = sk
                .joints
                .iter()
                .take(MAX_LISTED_JOINTS)
                .map(
                    |&j| match model.nodes.get(j).and_then(|n| n.name.as_deref()) {
                        Some(n) => name(Some(n)),
                        None => format!("[{j}]"),
                    },
                )
                .collect();
            if sk.joints.len() > MAX_LISTED_JOINTS {
                names.push(format!(
                    "... and {} more",
                    sk.joints.len() - MAX_LISTED_JOINTS
                ));
            }
            let _ = writeln!(
                s,
                "  [{i}] {}  {} joints: {}",
                name(sk.name.as_deref()),
                sk.joints.len(),
                names.join(", ")
            );
        }
    }
    let _ = writeln!(s, "\nanimations");
    if model.animations.is_empty() {
        let _ = writeln!(s, "  (none)");
    }
    for (i, a) in model.animations.iter().enumerate() {
        let _ = writeln!(
            s,
            "  [{i}] {:<24} {:>8.3} s  {} channels",
            name(a.name.as_deref()),
            a.duration_s,
            a.channels.len()
        );
    }
    if !model.images.is_empty() {
        let _ = writeln!(s, "\ntextures");
        for (i, im) in model.images.iter().enumerate() {
            let _ = writeln!(
                s,
                "  [{i}] {:<24} {}x{}",
                name(im.name.as_deref()),
                im.width,
                im.height
            );
        }
    }
    for w in &model.warnings {
        let _ = writeln!(s, "\nwarning: {w}");
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_node_tree_is_described() {
        let doc = br#"{"asset":{"version":"2.0"},"scene":0,"scenes":[{"nodes":[0]}],
            "nodes":[{"name":"root","children":[1]},{"name":"child"}]}"#;
        let model = Model::from_slice(doc, "tree.gltf", None, &Default::default())
            .expect("a glTF with two nodes");
        assert_eq!(
            describe(&model),
            "model      tree.gltf\ncounts     2 nodes, 0 meshes, 0 skins, 0 animations, 0 vertices, 0 triangles\n\nnodes\n  [0] root\n    [1] child\n\nanimations\n  (none)\n"
        );
    }

    #[test]
    fn long_names_are_cut() {
        let long = "x".repeat(MAX_NAME_CHARS + 10);
        assert_eq!(
            name(Some(&long)),
            format!("{}...", "x".repeat(MAX_NAME_CHARS))
        );
        assert_eq!(name(None), "-");
        assert_eq!(name(Some("short")), "short");
    }
}
