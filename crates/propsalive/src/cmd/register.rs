//! `propsalive register SHOT.toml --input FOLDER|VIDEO [--write] [--scale] [--max-views N]`:
//! where does the key prop stand on the marker? From frames that show the shot's present key
//! prop standing on the board (a few views from around it), refines the shot's `[placement]`
//! (`pa_pipeline::register`: the twin's outline aligned with the frames' edges over all
//! views) and prints the refined block, its residual, each view's agreement and the change
//! from the shot's values. `--write` puts it into the shot file in place (comments kept; the
//! original saved as `SHOT.toml.bak`, or `.bak.1`, ... when a backup exists).
//!
//! Decisions:
//! - Every frame is tracked on its own (stills may be moved between); untracked frames are
//!   named on stderr and left out. Of the tracked frames, at most `--max-views` evenly spaced
//!   ones are used.
//! - Refusals (exit 1, nothing written): fewer than two tracked frames, the prop at the
//!   shot's placement outside the views, its outline not found in the images, or views that
//!   do not constrain the answer (all from one direction).

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use pa_model::anim;
use pa_pipeline::register::track::{check_tracked, ViewTracker};
use pa_pipeline::register::{
    register, write, PlacementParams, RegisterSettings, RegisterView, Registration,
};
use pa_pipeline::shot::Shot;
use pa_pipeline::shot_config;
use pa_video::source::{InputSpec, Next, Pixels, Source, StillsSource, VideoSource};

#[derive(clap::Args)]
pub struct Args {
    /// The shot file; its [placement] is the start.
    pub shot: PathBuf,
    /// Frames of the key prop standing on the marker: a folder of stills or a video file.
    /// Views from around the prop (and from a little higher or lower) constrain it best.
    #[arg(long)]
    pub input: PathBuf,
    /// Write the refined placement into the shot file (comments kept, backup SHOT.bak).
    #[arg(long)]
    pub write: bool,
    /// Also refine a uniform scale of the model (written as [placement] scale).
    #[arg(long)]
    pub scale: bool,
    /// Use at most this many tracked frames, evenly spaced.
    #[arg(long, default_value_t = 10, value_name = "N")]
    pub max_views: usize,
    /// How far the search reaches from the shot's placement on the table, millimetres.
    #[arg(long, default_value_t = 12.0, value_name = "MM")]
    pub search_mm: f64,
    /// How far the search reaches in yaw, degrees.
    #[arg(long, default_value_t = 12.0, value_name = "DEG")]
    pub search_deg: f64,
}

/// A frame read: its name, width, height and RGBA8 pixels.
type ReadFrame = (String, u32, u32, Vec<u8>);

/// The frames of a folder or a video, RGBA8, at most `budget` of them (evenly spaced when
/// the count is known), each with a name.
fn read_frames(input: &Path, budget: usize) -> Result<Vec<ReadFrame>> {
    let spec = super::run::parse_input(input)?;
    let folder = matches!(spec, InputSpec::Folder(_));
    let mut source: Box<dyn Source> = match spec {
        InputSpec::Folder(dir) => Box::new(StillsSource::open(&dir)?),
        InputSpec::Video(path) => Box::new(VideoSource::open(&path)?),
        InputSpec::Camera(_) => bail!(
            "--input: register reads a folder of stills or a video file, not a camera (capture a few stills around the prop with `propsalive run` or the preview first)"
        ),
    };
    let stride = source
        .frame_count()
        .map_or(1, |n| n.div_ceil(budget.max(1)).max(1));
    let mut out = Vec::new();
    while let Next::Frame(f) = source.next()? {
        if f.index % stride != 0 {
            continue;
        }
        let (w, h, rgba) = match f.pixels {
            Pixels::Still(path) => match pa_video::still::read_still(&path, &Default::default()) {
                Ok(img) => {
                    let img = img.to_rgba8();
                    (img.width(), img.height(), img.into_raw())
                }
                Err(e) => {
                    errln!("warning: {}: skipped ({e})", path.display());
                    continue;
                }
            },
            Pixels::Frame(fr) => (fr.width, fr.height, fr.rgba),
            Pixels::Unreadable(e) => {
                errln!("warning: {} frame {}: skipped ({e})", f.name, f.index);
                continue;
            }
        };
        let name = if folder {
            f.name
        } else {
            format!("{}#{}", f.name, f.index)
        };
        out.push((name, w, h, rgba));
    }
    if out.is_empty() {
        bail!("--input {}: no readable frames", input.display());
    }
    Ok(out)
}

pub fn run(args: Args) -> Result<()> {
    if args.max_views < 2 {
        bail!("--max-views must be at least 2: one view cannot fix the prop's distance along its line of sight");
    }
    if !(args.search_mm > 0.0 && args.search_mm <= 100.0) {
        bail!("--search-mm must be in (0, 100], got {}", args.search_mm);
    }
    if !(args.search_deg > 0.0 && args.search_deg <= 90.0) {
        bail!("--search-deg must be in (0, 90], got {}", args.search_deg);
    }
    let shot = Shot::load(&args.shot)?;
    let model_path = Shot::resolve(&args.shot, &shot.model);
    let model = pa_model::Model::load(&model_path)
        .with_context(|| format!("loading the model {}", model_path.display()))?;
    let animation = shot.check_model(&args.shot, &model)?;
    let key = &shot.key_poses[shot.present_key_index()];
    let key_pose = anim::sample(&model, animation, key.frame as f32 / shot.fps);
    let board = shot_config::board_from_shot(&shot, &args.shot)?;

    let frames = read_frames(&args.input, args.max_views * 3)?;
    let (w, h) = (frames[0].1, frames[0].2);
    let camera = shot_config::camera_for_shot(&shot, &args.shot, w, h, &frames[0].0)?;
    if let Some(note) = &camera.scaled {
        errln!("{note}");
    }
    let (target, _) = super::run::marker::track_target(&shot, &args.shot, &board)?;
    let mut tracker = ViewTracker::new(camera.value, target)?;
    let total = frames.len();
    let mut views: Vec<RegisterView> = Vec::new();
    for (name, fw, fh, rgba) in frames {
        if (fw, fh) != (w, h) {
            errln!("warning: {name} is {fw}x{fh}, not {w}x{h} like the first frame: skipped");
            continue;
        }
        match tracker.view(name.clone(), rgba, fw, fh)? {
            Some(v) => views.push(v),
            None => errln!("note: {name}: marker not found, frame left out"),
        }
    }
    check_tracked(views.len(), total, 2)?;
    if views.len() > args.max_views {
        let n = views.len();
        let keep: Vec<usize> = (0..args.max_views)
            .map(|i| i * (n - 1) / (args.max_views - 1))
            .collect();
        views = views
            .into_iter()
            .enumerate()
            .filter(|(i, _)| keep.contains(i))
            .map(|(_, v)| v)
            .collect();
    }
    let start = PlacementParams::from_placement(&shot.placement);
    let settings = RegisterSettings {
        refine_scale: args.scale,
        search_mm: args.search_mm,
        search_deg: args.search_deg,
        ..Default::default()
    };
    let t0 = std::time::Instant::now();
    let r = register(&model, &key_pose, start, &views, &settings).with_context(|| {
        format!(
            "registering key prop {:?} from {}",
            key.name,
            args.input.display()
        )
    })?;
    outln!("{}", report(&r, args.scale, t0.elapsed().as_secs_f64()));
    if args.write {
        let backup = write::write_placement(&args.shot, &r.placement, args.scale)?;
        errln!(
            "wrote the placement into {} (the original is kept as {})",
            args.shot.display(),
            backup.display()
        );
    }
    Ok(())
}

/// The refined `[placement]` block, then the residual, the change and each view as comments.
pub(crate) fn report(r: &Registration, with_scale: bool, seconds: f64) -> String {
    let p = &r.placement;
    let t = p.translation_m;
    let mut s = format!(
        "[placement]\ntranslation_m = [{:.6}, {:.6}, {:.6}]\nupright = {}\nyaw_deg = {:.3}\n",
        t[0], t[1], t[2], p.upright, p.yaw_deg
    );
    if with_scale {
        s.push_str(&format!("scale = {:.5}\n", p.scale));
    }
    let d = p.change_from(&r.start);
    s.push_str(&format!(
        "\n# residual {:.2} px RMS over {} views (spanning {:.0} degrees), {:.1} s\n",
        r.residual_px,
        r.views.len(),
        r.spread_deg,
        seconds
    ));
    s.push_str(&format!(
        "# change from the shot: x {:+.2} mm, y {:+.2} mm, lift {:+.2} mm, yaw {:+.2} deg{}\n",
        d[0],
        d[1],
        d[2],
        d[3],
        if with_scale {
            format!(", scale {:+.2}%", d[4])
        } else {
            String::new()
        }
    ));
    let c = &r.conditioning;
    s.push_str(&format!(
        "# constrained: 1 mm moves the outline {:.2} px along its weakest direction ({}), {:.2} px along the strongest; 1 degree of yaw {:.2} px\n",
        c.translation_weakest, c.weakest_direction, c.translation_strongest, c.yaw_px_per_deg
    ));
    s.push_str("# view: outline points, agreement now (at the shot's placement), rms px\n");
    for v in &r.views {
        s.push_str(&format!(
            "#   {}: {} points, {:.0}% ({:.0}%), {:.2} px\n",
            v.name,
            v.points,
            v.edge_agreement * 1e2,
            v.start_agreement * 1e2,
            v.rms_px
        ));
    }
    for name in &r.skipped {
        s.push_str(&format!(
            "#   {name}: left out (the prop is not inside it)\n"
        ));
    }
    s.truncate(s.trim_end().len());
    s
}
