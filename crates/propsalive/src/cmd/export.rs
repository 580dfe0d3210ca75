//! `propsalive export MODEL --animation A (--time S | --frame N --fps F) [--scale K] --out FILE`.

use std::path::PathBuf;

use anyhow::{bail, Context, Result};
use pa_model::{anim, export, skin, Model};

#[derive(clap::Args)]
pub struct Args {
    /// The glTF 2.0 model (.glb or .gltf).
    pub model: PathBuf,
    /// Animation name or index (default: the first animation; the rest pose if none).
    #[arg(long, short)]
    pub animation: Option<String>,
    /// Animation time in seconds.
    #[arg(long, conflicts_with = "frame")]
    pub time: Option<f32>,
    /// Animation frame number (needs --fps).
    #[arg(long, requires = "fps")]
    pub frame: Option<u32>,
    /// Frames per second for --frame.
    #[arg(long)]
    pub fps: Option<f32>,
    /// Uniform scale of the model about its origin, as a shot's `[placement] scale` (the size
    /// the prop is drawn at, so the size to print it at).
    #[arg(long, default_value_t = 1.0, value_parser = parse_scale)]
    pub scale: f32,
    /// Output file: .obj, .stl or .glb (written atomically).
    #[arg(long, short)]
    pub out: PathBuf,
    /// Replace the output file if it exists.
    #[arg(long)]
    pub force: bool,
}

/// A `--scale`: a positive, finite number.
pub fn parse_scale(s: &str) -> Result<f32, String> {
    match s.trim().parse::<f32>() {
        Ok(k) if k.is_finite() && k > 0.0 => Ok(k),
        _ => Err(format!(
            "{s:?} is not a scale: it must be a positive, finite number (1 = as modelled)"
        )),
    }
}

/// Resolved configuration.
struct Config {
    animation: Option<usize>,
    time_s: f32,
}

fn resolve(args: &Args, model: &Model) -> Result<Config> {
    let time_s = match (args.time, args.frame, args.fps) {
        (Some(t), _, _) => t,
        (None, Some(f), Some(fps)) => {
            if !(fps.is_finite() && fps > 0.0) {
                bail!("--fps must be a positive number, got {fps}");
            }
            f as f32 / fps
        }
        _ => 0.0,
    };
    if !time_s.is_finite() || time_s < 0.0 {
        bail!("the time must be a finite number of seconds >= 0, got {time_s}");
    }
    let animation = match &args.animation {
        Some(a) => Some(model.find_animation(a)?),
        None if model.animations.is_empty() => None,
        None => Some(0),
    };
    if let Some(a) = animation {
        let d = model.animations[a].duration_s;
        if time_s > d + 1e-6 {
            errln!("note: time {time_s} s is past the clip's end ({d} s); the last key is held");
        }
    }
    Ok(Config { animation, time_s })
}

pub fn run(args: Args) -> Result<()> {
    if export::Format::from_path(&args.out).is_none() {
        bail!(
            "{}: unknown output extension (use .obj, .stl or .glb)",
            args.out.display()
        );
    }
    // Never a FIFO, a device or a link, --force or not (checked before the work).
    pa_io::check_replaceable(&args.out)?;
    if args.out.exists() && !args.force {
        bail!("{} exists; pass --force to replace it", args.out.display());
    }
    let model = Model::load(&args.model)?;
    let cfg = resolve(&args, &model)?;
    let pose = match cfg.animation {
        Some(a) => anim::sample(&model, a, cfg.time_s),
        None => anim::Pose::rest(&model),
    };
    let mut posed = skin::pose_meshes(&model, &pose);
    if args.scale != 1.0 {
        for v in posed.iter_mut().flat_map(|p| &mut p.positions) {
            *v *= args.scale;
        }
    }
    export::write(&model, &posed, &args.out)
        .with_context(|| format!("exporting {}", args.model.display()))?;
    let verts: usize = posed.iter().map(|p| p.positions.len()).sum();
    outln!(
        "wrote {} ({} primitives, {verts} vertices, t = {} s, scale {})",
        args.out.display(),
        posed.len(),
        cfg.time_s,
        args.scale
    );
    Ok(())
}
