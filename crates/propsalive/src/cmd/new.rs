//! `propsalive new SHOT.toml --model M [--animation A] [--key-frames 0,24] [--board RxC
//! --size-mm S] [--scale K] [--calib F | --fov-deg D] [--force]`: a complete, commented shot
//! file for a model, with the key prop standing on the board.
//!
//! The board is `RxC` tag36h11 tags laid out as `propsalive marker --board` lays them out (the
//! same gap rule, ids row-major from 0). The placement is upright, facing the marker's +Y
//! (down the printed page), scaled by `--scale`, and translated so that the first key pose's
//! lowest points (`pa_pipeline::footprint`) touch the sheet, their outline centred on the
//! board's centre. Paths in the file are relative to the shot file's folder. The text is
//! loaded back (`Shot::parse`, `check_model`) before it is written, atomically, never over an
//! existing file without `--force`.

use std::path::{Component, Path, PathBuf};

use anyhow::{bail, Context, Result};
use pa_model::Model;
use pa_overlay::sheet::SheetScale;
use pa_pipeline::footprint;
use pa_pipeline::shot::template::{NewCamera, NewShot};
use pa_pipeline::shot::{Placement, Shot};
use pa_track::{Board, TagFamily};

#[derive(clap::Args)]
pub struct Args {
    /// The shot file to write (TOML).
    pub shot: PathBuf,
    /// The rigged glTF 2.0 model (.glb or .gltf).
    #[arg(long)]
    pub model: PathBuf,
    /// Animation name or index (default: the model's first animation).
    #[arg(long, short)]
    pub animation: Option<String>,
    /// Animation frames that exist as physical key props, comma-separated; they are named
    /// A, B, C, ... and the first is the one in front of the camera.
    #[arg(long, default_value = "0")]
    pub key_frames: String,
    /// Animation frames per second.
    #[arg(long, default_value_t = 24.0)]
    pub fps: f32,
    /// The printed board: ROWSxCOLS tag36h11 tags, ids row-major from 0, laid out as
    /// `propsalive marker --board` prints them.
    #[arg(long, default_value = "3x3")]
    pub board: String,
    /// Side of each tag's black square in millimetres.
    #[arg(long, default_value_t = 45.0)]
    pub size_mm: f64,
    /// Gap between neighbouring tags' black squares in millimetres (default: `marker`'s, two
    /// cells of the tag).
    #[arg(long)]
    pub gap_mm: Option<f64>,
    /// Uniform scale of the model about its origin (`[placement] scale`).
    #[arg(long, default_value_t = 1.0, value_parser = super::export::parse_scale)]
    pub scale: f32,
    /// The camera's calibration file (OpenCV YAML, or TOML/JSON from `propsalive calibrate`).
    #[arg(long, conflicts_with = "fov_deg")]
    pub calib: Option<PathBuf>,
    /// The camera's vertical field of view in degrees, without a calibration (default 50).
    #[arg(long)]
    pub fov_deg: Option<f64>,
    /// Replace the shot file if it exists.
    #[arg(long)]
    pub force: bool,
}

/// Key names: A..Z, then K27, K28, ...
fn key_name(i: usize) -> String {
    if i < 26 {
        char::from(b'A' + i as u8).to_string()
    } else {
        format!("K{}", i + 1)
    }
}

fn parse_key_frames(s: &str) -> Result<Vec<u32>> {
    let mut frames = Vec::new();
    for part in s.split(',') {
        let f: u32 = part.trim().parse().with_context(|| {
            format!("--key-frames {s:?}: {part:?} is not a frame number (0, 1, 2, ...)")
        })?;
        if frames.contains(&f) {
            bail!("--key-frames {s:?}: frame {f} is given twice");
        }
        frames.push(f);
    }
    if frames.len() > 256 {
        bail!("--key-frames {s:?}: at most 256 key poses");
    }
    Ok(frames)
}

/// `path` relative to the folder `base` (both absolute and normalised).
fn relative_to(path: &Path, base: &Path) -> PathBuf {
    let p: Vec<Component> = path.components().collect();
    let b: Vec<Component> = base.components().collect();
    let common = p.iter().zip(&b).take_while(|(x, y)| x == y).count();
    if common == 0 {
        return path.to_path_buf();
    }
    let mut rel = PathBuf::new();
    for _ in common..b.len() {
        rel.push("..");
    }
    for c in &p[common..] {
        rel.push(c.as_os_str());
    }
    rel
}

/// A path as the shot file names it: relative to the shot's folder, `/`-separated text.
fn shot_relative(file: &Path, shot_dir: &Path, flag: &str) -> Result<String> {
    let abs = std::fs::canonicalize(file).with_context(|| format!("{flag} {}", file.display()))?;
    let rel = relative_to(&abs, shot_dir);
    let text = rel.to_str().with_context(|| {
        format!(
            "{flag} {}: the path is not UTF-8, which a TOML file cannot hold",
            file.display()
        )
    })?;
    Ok(text.replace('\\', "/"))
}

fn plan(args: &Args, shot_dir: &Path) -> Result<(NewShot, footprint::Footprint, Model)> {
    if !(args.fps.is_finite() && args.fps > 0.0 && args.fps <= 1000.0) {
        bail!("--fps must be in (0, 1000], got {}", args.fps);
    }
    let frames = parse_key_frames(&args.key_frames)?;
    let (rows, cols) = super::parse_grid(&args.board)?;
    if let Some(fov) = args.fov_deg {
        if !(fov.is_finite() && fov > 1.0 && fov < 179.0) {
            bail!("--fov-deg must be in (1, 179), got {fov}");
        }
    }
    // The board as `marker --board` prints it (its gap rule and its checks).
    let scale = SheetScale::new(TagFamily::Tag36h11, args.size_mm, 300.0, 10.0)?;
    let sheet = scale.layout(Some((rows, cols)), 0, args.gap_mm)?;
    let board = Board::grid(
        TagFamily::Tag36h11,
        rows,
        cols,
        args.size_mm / 1000.0,
        sheet.gap_mm / 1000.0,
        0,
    )?;
    // The model: a regular file that loads, with the clip and the key frames.
    pa_io::check_regular(&args.model)
        .with_context(|| format!("--model {}", args.model.display()))?;
    let model = Model::load(&args.model)?;
    if model.animations.is_empty() {
        bail!(
            "{}: the model has no animation: there are no in-betweens to make",
            args.model.display()
        );
    }
    let anim = match &args.animation {
        Some(a) => model.find_animation(a)?,
        None => 0,
    };
    let clip = &model.animations[anim];
    let last = (clip.duration_s * args.fps).round() as u32;
    if let Some(&f) = frames.iter().find(|&&f| f > last) {
        bail!(
            "--key-frames: frame {f} is past the end of the clip {} (frame {last} at {} fps)",
            clip.name.clone().unwrap_or_else(|| anim.to_string()),
            args.fps
        );
    }
    let animation = clip.name.clone().unwrap_or_else(|| anim.to_string());
    let camera = match (&args.calib, args.fov_deg) {
        (Some(c), _) => {
            pa_io::check_regular(c).with_context(|| format!("--calib {}", c.display()))?;
            pa_camera::calib::load_calibration(c)
                .with_context(|| format!("--calib {}", c.display()))?;
            NewCamera::Calibration(shot_relative(c, shot_dir, "--calib")?)
        }
        (None, fov) => NewCamera::FovDeg(fov.unwrap_or(50.0)),
    };
    let key_time = frames[0] as f32 / args.fps;
    let start = Placement {
        scale: args.scale,
        ..Placement::default()
    };
    let (placement, footprint) = footprint::rest_on_table(&model, Some(anim), key_time, &start)
        .with_context(|| format!("{}: the model has no vertices", args.model.display()))?;
    Ok((
        NewShot {
            model: shot_relative(&args.model, shot_dir, "--model")?,
            animation,
            fps: args.fps,
            keys: frames
                .iter()
                .enumerate()
                .map(|(i, &f)| (key_name(i), f))
                .collect(),
            camera,
            board,
            rows,
            cols,
            gap_mm: sheet.gap_mm,
            placement,
        },
        footprint,
        model,
    ))
}

pub fn run(args: Args) -> Result<()> {
    let shot_path = &args.shot;
    pa_io::check_replaceable(shot_path)?;
    if shot_path.exists() && !args.force {
        bail!("{} exists; pass --force to replace it", shot_path.display());
    }
    let dir = match shot_path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    std::fs::create_dir_all(&dir).with_context(|| format!("creating folder {}", dir.display()))?;
    let shot_dir =
        std::fs::canonicalize(&dir).with_context(|| format!("folder {}", dir.display()))?;
    let (plan, fp, model) = plan(&args, &shot_dir)?;
    let text = plan.to_commented_toml();
    // What is written must load and fit the model.
    let shot = Shot::parse(&text, shot_path)?;
    shot.check_model(shot_path, &model)?;
    if args.force {
        pa_io::write_atomic(shot_path, text.as_bytes())?;
    } else if !pa_io::write_new_atomic(shot_path, text.as_bytes())? {
        bail!("{} exists; pass --force to replace it", shot_path.display());
    }
    let t = plan.placement.translation_m;
    let keys: Vec<String> = plan
        .keys
        .iter()
        .map(|(n, f)| format!("{n} (frame {f})"))
        .collect();
    outln!(
        "wrote {}: model {}, animation {:?}, key poses {}",
        shot_path.display(),
        plan.model,
        plan.animation,
        keys.join(", ")
    );
    outln!(
        "board: {}x{} tag36h11 tags of {} mm, {} mm apart; placement: scale {}, lift {:.2} mm, \
         shift ({:.2}, {:.2}) mm; key pose {} touches the sheet over {:.0} mm2 ({} vertices)",
        plan.rows,
        plan.cols,
        args.size_mm,
        plan.gap_mm,
        plan.placement.scale,
        -t[2] * 1000.0,
        t[0] * 1000.0,
        t[1] * 1000.0,
        plan.keys[0].0,
        footprint::area(&fp.outline_m) * 1e6,
        fp.contact_vertices
    );
    let covered = footprint::covered_tags(&fp, &plan.board);
    if covered.len() > 1 {
        let radius_mm = fp
            .outline_m
            .iter()
            .map(|p| (*p - fp.centre_m).length())
            .fold(0.0, f64::max)
            * 1000.0;
        let size_mm = plan.board.tags[0].size_m * 1000.0;
        errln!(
            "note: key prop {} stands on {} of the {} tags (ids {:?}); the camera tracks the tags it sees, so keep most of them clear: a gap of at least {:.0} mm (--gap-mm) or a larger board leaves the neighbours of the centre free",
            plan.keys[0].0,
            covered.len(),
            plan.board.tags.len(),
            covered,
            (radius_mm - size_mm / 2.0 + 5.0).ceil().max(0.0)
        );
    }
    let shot = shot_path.display();
    outln!("next:");
    outln!(
        "  1. print the board with the footprint, at 100 %: propsalive marker --shot {shot} --out board"
    );
    outln!(
        "     (measure a black square: {} mm), and stand key prop {} on its outline, its front along the arrow",
        args.size_mm,
        plan.keys[0].0
    );
    outln!("  2. check the set live: propsalive preview {shot}");
    outln!("  3. refine the placement from a few frames: propsalive register {shot} --input FRAMES --write");
    outln!("  4. shoot: propsalive run {shot} --input FRAMES --out take");
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn relative_paths_and_strings() {
        assert_eq!(
            relative_to(Path::new("/a/b/m.glb"), Path::new("/a/b")),
            PathBuf::from("m.glb")
        );
        assert_eq!(
            relative_to(Path::new("/a/m/x.glb"), Path::new("/a/b/c")),
            PathBuf::from("../../m/x.glb")
        );
        assert_eq!(key_name(0), "A");
        assert_eq!(key_name(25), "Z");
        assert_eq!(key_name(26), "K27");
        assert!(parse_key_frames("0, 24").is_ok_and(|f| f == vec![0, 24]));
        assert!(parse_key_frames("0,0").is_err());
        assert!(parse_key_frames("x").is_err());
        assert!(parse_key_frames("").is_err());
    }
}
