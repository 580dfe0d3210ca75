//! `propsalive render MODEL --animation A --fps 24 --size 1280x720 [--scale K] --out DIR`: one
//! PNG per animation frame, the camera framing the animated model's bounds unless given.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use glam::{Mat4, Vec3};
use indicatif::{ProgressBar, ProgressStyle};
use pa_camera::{camera_from_world_look_at, Intrinsics};
use pa_model::{anim, skin, Model};
use pa_pipeline::GpuTwin;
use pa_render::{CpuCamera, DirectionalLight, Lighting, Renderer};

#[derive(clap::Args)]
pub struct Args {
    /// The glTF 2.0 model (.glb or .gltf).
    pub model: PathBuf,
    /// Animation name or index (default: the first; the rest pose when there is none).
    #[arg(long, short)]
    pub animation: Option<String>,
    /// Frames per second of the rendered sequence.
    #[arg(long, default_value_t = 24.0)]
    pub fps: f32,
    /// Image size, WIDTHxHEIGHT.
    #[arg(long, default_value = "1280x720")]
    pub size: String,
    /// Output folder for frame_NNNN.png.
    #[arg(long, short)]
    pub out: PathBuf,
    /// Vertical field of view in degrees (ignored with --intrinsics).
    #[arg(long, default_value_t = 40.0)]
    pub fov_deg: f64,
    /// OpenCV intrinsics "fx,fy,cx,cy" in pixels of --size.
    #[arg(long)]
    pub intrinsics: Option<String>,
    /// Camera position "x,y,z" in the model's world (glTF axes, metres); default: framed.
    #[arg(long)]
    pub eye: Option<String>,
    /// Point the camera looks at, "x,y,z"; default: the centre of the animated bounds.
    #[arg(long)]
    pub target: Option<String>,
    /// Uniform scale of the model about its origin, as a shot's `[placement] scale`; --eye and
    /// --target are in the scaled model's world.
    #[arg(long, default_value_t = 1.0, value_parser = super::export::parse_scale)]
    pub scale: f32,
    /// Render albedo only (no lighting).
    #[arg(long)]
    pub unlit: bool,
    /// Replace frames that already exist in the output folder.
    #[arg(long)]
    pub force: bool,
}

fn parse_vec3(s: &str, what: &str) -> Result<Vec3> {
    let v: Vec<f32> = s
        .split(',')
        .map(|x| x.trim().parse::<f32>())
        .collect::<Result<_, _>>()
        .with_context(|| format!("{what} {s:?} must be three numbers x,y,z"))?;
    match v.as_slice() {
        [x, y, z] if v.iter().all(|c| c.is_finite()) => Ok(Vec3::new(*x, *y, *z)),
        _ => bail!("{what} {s:?} must be three finite numbers x,y,z"),
    }
}

/// The resolved configuration of a render.
pub struct Config {
    pub animation: Option<usize>,
    pub frame_count: u32,
    pub fps: f32,
    pub intrinsics: Intrinsics,
    pub camera_from_world: Mat4,
    pub near_m: f32,
    pub far_m: f32,
    pub lighting: Option<Lighting>,
    /// `world_from_model`: the uniform `--scale`.
    pub world_from_model: Mat4,
}

/// Bounds of the model over every frame of the animation.
fn animated_bounds(
    model: &Model,
    animation: Option<usize>,
    frames: u32,
    fps: f32,
) -> Result<(Vec3, Vec3)> {
    let mut lo = Vec3::splat(f32::MAX);
    let mut hi = Vec3::splat(f32::MIN);
    for f in 0..frames {
        let pose = match animation {
            Some(a) => anim::sample(model, a, f as f32 / fps),
            None => anim::Pose::rest(model),
        };
        if let Some((l, h)) = skin::bounds(&skin::pose_meshes(model, &pose)) {
            lo = lo.min(l);
            hi = hi.max(h);
        }
    }
    if lo.x > hi.x {
        bail!(
            "{}: the model has no vertices to render",
            model.path.display()
        );
    }
    Ok((lo, hi))
}

/// The default key light: from the upper front left, plus ambient.
pub fn default_lighting() -> Lighting {
    Lighting {
        ambient_rgb: [0.35; 3],
        directional: Some(DirectionalLight {
            toward_light_world: Vec3::new(-0.4, 0.8, 0.6),
            radiance_rgb: [0.75; 3],
        }),
    }
}

pub fn resolve(args: &Args, model: &Model) -> Result<Config> {
    if !(args.fps.is_finite() && args.fps > 0.0 && args.fps <= 1000.0) {
        bail!("--fps must be in (0, 1000], got {}", args.fps);
    }
    let (w, h) = super::parse_size(&args.size)?;
    let animation = match &args.animation {
        Some(a) => Some(model.find_animation(a)?),
        None if model.animations.is_empty() => None,
        None => Some(0),
    };
    let duration = animation
        .map(|a| model.animations[a].duration_s)
        .unwrap_or(0.0);
    let frame_count = (duration * args.fps).floor() as u32 + 1;
    let intrinsics = match &args.intrinsics {
        Some(s) => {
            let v: Vec<f64> = s
                .split(',')
                .map(|x| x.trim().parse::<f64>())
                .collect::<Result<_, _>>()
                .with_context(|| format!("--intrinsics {s:?} must be fx,fy,cx,cy"))?;
            let [fx, fy, cx, cy] = v[..] else {
                bail!("--intrinsics {s:?} must be four numbers fx,fy,cx,cy");
            };
            let k = Intrinsics {
                fx,
                fy,
                cx,
                cy,
                width: w,
                height: h,
            };
            k.validate()?;
            k
        }
        None => Intrinsics::from_fov_y(args.fov_deg.to_radians(), w, h)?,
    };
    let (lo, hi) = animated_bounds(model, animation, frame_count, args.fps)?;
    let (lo, hi) = (lo * args.scale, hi * args.scale);
    let (mut camera_from_world, mut near_m, mut far_m) =
        pa_pipeline::framing::frame_bounds(lo, hi, &intrinsics, 1.1);
    if args.eye.is_some() || args.target.is_some() {
        let target = match &args.target {
            Some(t) => parse_vec3(t, "--target")?,
            None => (lo + hi) * 0.5,
        };
        let eye = match &args.eye {
            Some(e) => parse_vec3(e, "--eye")?,
            None => camera_from_world.inverse().transform_point3(Vec3::ZERO),
        };
        camera_from_world = camera_from_world_look_at(eye, target, Vec3::Y)
            .with_context(|| format!("the camera at {eye} cannot look at {target}"))?;
        let radius = (hi - lo).length() * 0.5;
        let d = (eye - (lo + hi) * 0.5).length();
        near_m = (d - radius * 2.0).max(d * 1e-3).max(1e-4);
        far_m = d + radius * 2.0;
    }
    Ok(Config {
        animation,
        frame_count,
        fps: args.fps,
        intrinsics,
        camera_from_world,
        near_m,
        far_m,
        lighting: (!args.unlit).then(default_lighting),
        world_from_model: Mat4::from_scale(Vec3::splat(args.scale)),
    })
}

pub fn run(args: Args) -> Result<()> {
    // The flags first (the size is refused before a large model is read).
    super::parse_size(&args.size)?;
    let model = Model::load(&args.model)?;
    let cfg = resolve(&args, &model)?;
    let mut renderer = Renderer::new()?;
    errln!("rendering on {}", renderer.adapter_info());
    let written = render_frames(&mut renderer, &model, &cfg, &args.out, args.force)?;
    outln!(
        "wrote {written} frames ({}x{}) to {}",
        cfg.intrinsics.width,
        cfg.intrinsics.height,
        args.out.display()
    );
    Ok(())
}

/// The file name of frame `i`.
pub fn frame_name(i: u32) -> String {
    format!("frame_{i:04}.png")
}

/// Renders every frame of `cfg` into `out`, atomically, refusing to replace existing frames
/// unless `force`. Returns the number of frames written.
pub fn render_frames(
    renderer: &mut Renderer,
    model: &Model,
    cfg: &Config,
    out: &Path,
    force: bool,
) -> Result<u32> {
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    if !force {
        if let Some(existing) = (0..cfg.frame_count)
            .map(|i| out.join(frame_name(i)))
            .find(|p| p.exists())
        {
            bail!(
                "{} already exists; pass --force to replace the frames in {}",
                existing.display(),
                out.display()
            );
        }
    }
    let twin = GpuTwin::upload(renderer, model)?;
    let camera = CpuCamera {
        intrinsics: cfg.intrinsics,
        camera_from_world: cfg.camera_from_world,
        near_m: cfg.near_m,
        far_m: cfg.far_m,
    };
    let bar = ProgressBar::new(cfg.frame_count as u64);
    bar.set_style(
        ProgressStyle::with_template("{bar:40} {pos}/{len} frames  {per_sec}  eta {eta}")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    for i in 0..cfg.frame_count {
        let pose = match cfg.animation {
            Some(a) => anim::sample(model, a, i as f32 / cfg.fps),
            None => anim::Pose::rest(model),
        };
        let frame = twin.frame(model, &pose, cfg.world_from_model);
        let draws = twin.draws(&frame);
        let img = renderer.render(
            &camera,
            cfg.lighting.as_ref(),
            &draws,
            [0.02, 0.02, 0.025, 1.0],
            cfg.intrinsics.width,
            cfg.intrinsics.height,
        )?;
        super::write_png_atomic(&out.join(frame_name(i)), img.width, img.height, &img.rgba8)?;
        bar.inc(1);
    }
    bar.finish_and_clear();
    Ok(cfg.frame_count)
}
