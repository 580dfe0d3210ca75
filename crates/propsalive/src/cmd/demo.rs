//! `propsalive demo`: the built-in default job, with nothing downloaded.
//!
//! Generates the built-in prop (a rigged, textured bust of about 8,000 vertices), writes it as
//! `prop.glb`, and renders its animation clip to `frames/` with the GPU renderer (skinning in
//! the vertex stage). The AR pipeline (tracking, live texturing, diminished reality) joins this
//! command as it lands.

use std::path::PathBuf;

use anyhow::{Context, Result};
use pa_model::Model;
use pa_render::Renderer;
use pa_scene::PropSpec;

#[derive(clap::Args)]
pub struct Args {
    /// Output folder (its demo files are replaced on every run).
    #[arg(long, short, default_value = "out/demo")]
    pub out: PathBuf,
    /// Image size, WIDTHxHEIGHT.
    #[arg(long, default_value = "960x540")]
    pub size: String,
}

pub fn run(args: Args) -> Result<()> {
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    let spec = PropSpec::default();
    let glb = pa_scene::prop_glb(&spec).map_err(anyhow::Error::msg)?;
    let glb_path = args.out.join("prop.glb");
    pa_model::export::write_atomic(&glb_path, &glb)
        .with_context(|| format!("writing {}", glb_path.display()))?;
    let model = Model::load(&glb_path)?;
    println!(
        "built-in prop: {} vertices, {} triangles, {} joints, clip {:.2} s -> {}",
        model.vertex_count(),
        model.triangle_count(),
        model.skins[0].joints.len(),
        model.animations[0].duration_s,
        glb_path.display()
    );
    let render_args = super::render::Args {
        model: glb_path.clone(),
        animation: Some("Animate".into()),
        fps: 24.0,
        size: args.size.clone(),
        out: args.out.join("frames"),
        fov_deg: 35.0,
        intrinsics: None,
        eye: None,
        target: None,
        unlit: false,
        force: true,
    };
    let cfg = super::render::resolve(&render_args, &model)?;
    let mut renderer = Renderer::new()?;
    println!("renderer: {}", renderer.adapter_info());
    let t0 = std::time::Instant::now();
    let n = super::render::render_frames(&mut renderer, &model, &cfg, &render_args.out, true)?;
    let secs = t0.elapsed().as_secs_f64();
    println!(
        "rendered {n} frames at {} in {secs:.1} s ({:.1} ms a frame incl. PNG encoding) -> {}",
        args.size,
        secs * 1e3 / n.max(1) as f64,
        render_args.out.display()
    );
    println!("next: propsalive inspect {}", glb_path.display());
    Ok(())
}
