//! `propsalive inspect MODEL`.

use std::fmt::Write as _;
use std::path::PathBuf;

use anyhow::Result;
use pa_model::{LocalTransform, Model};

#[derive(clap::Args)]
pub struct Args {
    /// The glTF 2.0 model (.glb or .gltf).
    pub model: PathBuf,
}

pub fn run(args: Args) -> Result<()> {
    let model = Model::load(&args.model)?;
    out!("{}", describe(&model));
    Ok(())
}

/// A human-readable description of a model.
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
    let mut stack: Vec<(usize, usize)> = model.roots.iter().rev().map(|&r| (r, 0)).collect();
    while let Some((i, depth)) = stack.pop() {
        let n = &model.nodes[i];
        let mut line = format!(
            "  {}[{i}] {}",
            "  ".repeat(depth),
            n.name.as_deref().unwrap_or("-")
        );
        if let Some(m) = n.mesh {
            let prims = &model.meshes[m].primitives;
            let v: usize = prims.iter().map(|p| p.positions.len()).sum();
            let t: usize = prims.iter().map(|p| p.triangle_count()).sum();
            let _ = write!(
                line,
                "  mesh {m} ({} primitives, {v} vertices, {t} triangles)",
                prims.len()
            );
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
            let names: Vec<String> = sk
                .joints
                .iter()
                .map(|&j| {
                    model.nodes[j]
                        .name
                        .clone()
                        .unwrap_or_else(|| format!("[{j}]"))
                })
                .collect();
            let _ = writeln!(
                s,
                "  [{i}] {}  {} joints: {}",
                sk.name.as_deref().unwrap_or("-"),
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
            a.name.as_deref().unwrap_or("-"),
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
                im.name.as_deref().unwrap_or("-"),
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
