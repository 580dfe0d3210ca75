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
use pa_pipeline::shot::{Placement, Shot, SHOT_FORMAT};
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

/// A TOML basic string.
fn toml_string(s: &str) -> String {
    let mut out = String::from("\"");
    for c in s.chars() {
        match c {
            '"' => out.push_str("\\\""),
            '\\' => out.push_str("\\\\"),
            c if c.is_control() => out.push_str(&format!("\\u{:04X}", c as u32)),
            c => out.push(c),
        }
    }
    out.push('"');
    out
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

/// What the shot file says, before it is written out as commented text.
struct Plan {
    model: String,
    animation: String,
    fps: f32,
    keys: Vec<(String, u32)>,
    camera: String,
    board: Board,
    rows: u32,
    cols: u32,
    gap_mm: f64,
    placement: Placement,
    footprint: footprint::Footprint,
}

fn plan(args: &Args, shot_dir: &Path) -> Result<(Plan, Model)> {
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
            format!(
                "calibration = {}",
                toml_string(&shot_relative(c, shot_dir, "--calib")?)
            )
        }
        (None, fov) => format!("fov_y_deg = {}", num(fov.unwrap_or(50.0))),
    };
    let key_time = frames[0] as f32 / args.fps;
    let start = Placement {
        scale: args.scale,
        ..Placement::default()
    };
    let (placement, footprint) = footprint::rest_on_table(&model, Some(anim), key_time, &start)
        .with_context(|| format!("{}: the model has no vertices", args.model.display()))?;
    Ok((
        Plan {
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
            footprint,
        },
        model,
    ))
}

/// A number as TOML writes it, rounded to micrometres for lengths.
fn num(v: f64) -> String {
    let r = (v * 1e6).round() / 1e6;
    // No negative zero.
    let r = if r == 0.0 { 0.0 } else { r };
    let s = format!("{r}");
    if s.contains(['.', 'e', 'E', 'n', 'i']) {
        s
    } else {
        format!("{s}.0")
    }
}

/// The commented shot file.
fn shot_text(p: &Plan) -> String {
    let mut text = String::new();
    let mut line = |s: &str| {
        text.push_str(s);
        text.push('\n');
    };
    line("# A Props Alive shot, written by `propsalive new`. Paths are relative to this file.");
    line("# An unknown key is refused, never ignored; `format` is the version of this layout.");
    line(&format!("format = {SHOT_FORMAT}"));
    line("");
    line("# The rigged glTF 2.0 model of the prop, and the clip whose in-betweens are drawn.");
    line(&format!("model = {}", toml_string(&p.model)));
    line(&format!("animation = {}", toml_string(&p.animation)));
    line("# Animation frames per second (frame N of the clip is at N / fps seconds).");
    line(&format!("fps = {}", num(f64::from(p.fps))));
    line("# The key prop in front of the camera (a name of [[key_poses]]).");
    line(&format!("present_key = {}", toml_string(&p.keys[0].0)));
    line("");
    line("# The key poses: animation frames that exist as physical (printed) props. A key prop");
    line("# may carry its own tag on its base (marker_id = N, not a tag of the board).");
    for (name, frame) in &p.keys {
        line("[[key_poses]]");
        line(&format!("name = {}", toml_string(name)));
        line(&format!("frame = {frame}"));
        line("");
    }
    line("# The camera: a calibration file (`propsalive calibrate`), or a vertical field of");
    line("# view in degrees when there is none (calibrate for a placement to the millimetre).");
    line("[camera]");
    line(&p.camera);
    line("");
    line(&format!(
        "# The printed board: {}x{} tag36h11 tags of {} mm (black square), {} mm apart, ids",
        p.rows,
        p.cols,
        num(p.board.tags[0].size_m * 1000.0),
        num(p.gap_mm)
    ));
    line("# row-major from the top-left as printed. The marker frame's origin is the board's");
    line("# centre, +X to the right and +Y down the printed page, +Z into the table (metres).");
    line("# Print it with the prop's footprint: propsalive marker --shot THIS_FILE --out STEM");
    line("[marker]");
    line(&format!("family = {}", toml_string("tag36h11")));
    for tag in &p.board.tags {
        line("[[marker.tags]]");
        line(&format!("id = {}", tag.id));
        line(&format!(
            "center_m = [{}, {}]",
            num(tag.center_m.x),
            num(tag.center_m.y)
        ));
        line(&format!("size_m = {}", num(tag.size_m)));
    }
    line("");
    let pl = &p.placement;
    let t = pl.translation_m;
    line("# Where the prop stands on the marker (marker_from_prop): scaled about the model's");
    line("# origin, turned by yaw_deg about its up axis, stood upright (model +Y up, its front");
    line("# +Z along the marker's +Y), then moved by translation_m. `propsalive new` put the");
    line(&format!(
        "# key pose's lowest points on the sheet (lift {} mm) and centred their outline on the",
        num(-f64::from(t[2]) * 1000.0)
    ));
    line("# board; `propsalive register` refines this from camera frames.");
    line("[placement]");
    line(&format!(
        "translation_m = [{}, {}, {}]",
        num(f64::from(t[0])),
        num(f64::from(t[1])),
        num(f64::from(t[2]))
    ));
    line(&format!("upright = {}", pl.upright));
    line(&format!("yaw_deg = {}", num(f64::from(pl.yaw_deg))));
    line(&format!("scale = {}", num(f64::from(pl.scale))));
    text
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
    let (plan, model) = plan(&args, &shot_dir)?;
    let text = shot_text(&plan);
    // What is written must load and fit the model.
    let shot = Shot::parse(&text, shot_path)?;
    shot.check_model(shot_path, &model)?;
    if args.force {
        pa_io::write_atomic(shot_path, text.as_bytes())?;
    } else if !pa_io::write_new_atomic(shot_path, text.as_bytes())? {
        bail!("{} exists; pass --force to replace it", shot_path.display());
    }
    let t = plan.placement.translation_m;
    let fp = &plan.footprint;
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
        num(args.size_mm),
        num(plan.gap_mm),
        plan.placement.scale,
        -t[2] * 1000.0,
        t[0] * 1000.0,
        t[1] * 1000.0,
        plan.keys[0].0,
        footprint::area(&fp.outline_m) * 1e6,
        fp.contact_vertices
    );
    let covered = covered_tags(&plan);
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
        num(args.size_mm),
        plan.keys[0].0
    );
    outln!("  2. check the set live: propsalive preview {shot}");
    outln!("  3. refine the placement from a few frames: propsalive register {shot} --input FRAMES --write");
    outln!("  4. shoot: propsalive run {shot} --input FRAMES --out take");
    Ok(())
}

/// The ids of the board's tags whose black square overlaps the key prop's footprint (the
/// outline's bounding box, in the marker frame).
fn covered_tags(plan: &Plan) -> Vec<u32> {
    let o = &plan.footprint.outline_m;
    let (lo, hi) = o.iter().fold(
        (
            glam::DVec2::splat(f64::INFINITY),
            glam::DVec2::splat(f64::NEG_INFINITY),
        ),
        |(l, h), p| (l.min(*p), h.max(*p)),
    );
    plan.board
        .tags
        .iter()
        .filter(|t| {
            let r = t.size_m / 2.0;
            t.center_m.x + r > lo.x
                && t.center_m.x - r < hi.x
                && t.center_m.y + r > lo.y
                && t.center_m.y - r < hi.y
        })
        .map(|t| t.id)
        .collect()
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
        assert_eq!(toml_string("a\"b\\c\n"), "\"a\\\"b\\\\c\\u000A\"");
        assert_eq!(key_name(0), "A");
        assert_eq!(key_name(25), "Z");
        assert_eq!(key_name(26), "K27");
        assert_eq!(num(0.0), "0.0");
        assert_eq!(num(-0.0009), "-0.0009");
        assert_eq!(num(45.0), "45.0");
        assert_eq!(num(-0.0), "0.0");
        assert_eq!(num(-1e-9), "0.0");
        assert!(parse_key_frames("0, 24").is_ok_and(|f| f == vec![0, 24]));
        assert!(parse_key_frames("0,0").is_err());
        assert!(parse_key_frames("x").is_err());
        assert!(parse_key_frames("").is_err());
    }
}
