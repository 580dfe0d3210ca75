//! `propsalive eval`: our methods against the paper's on generated scenes with ground truth,
//! and the degradation curve (quality against the in-between's distance from its key pose),
//! and the tracker alone (`tracking per still` / `tracking video filter` rows: median
//! rotation error on clean frames and on frames with sensor noise and blur).
//!
//! Runs every method on every background and seed, then hands the numbers to
//! [`pa_report::eval`], which writes `report.md`, `results.json` and three SVG plots linked
//! from the report (`methods.svg`, `degradation_rotation.svg`, `degradation_translation.svg`).
//!
//! `--set DIR` (repeatable) measures external sets instead: takes of our set rendered by
//! another renderer (`scripts/blender/render_set.py`), one row per fill; `--write-kit DIR`
//! writes what that renderer needs (see [`set`]).

mod set;

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use pa_diminish::{dilate, DilateShape, Mask};
use pa_pipeline::ar::{ArSettings, Fill};
use pa_pipeline::composite::composite_twin_over;
use pa_render::Renderer;
use pa_report::eval::{Curve, CurvePoint, EvalReport, MethodRow};
use pa_report::stats::{mean, median};
use pa_scene::eval::run_scene_shadows;
use pa_scene::memory::{memory_methods, run_scene_memory, TwinTexture};
use pa_scene::methods::{methods, Method};
use pa_scene::scene::{Background, CameraPath};
use pa_scene::tracking::{tracking_errors, SensorNoise, TrackingErrors};
use pa_scene::SceneSpec;

#[derive(clap::Args)]
pub struct Args {
    /// Output folder for report.md, results.json and the plots (SVG).
    #[arg(long, short, default_value = "out/eval")]
    pub out: PathBuf,
    /// Image size, WIDTHxHEIGHT.
    #[arg(long, default_value = "480x270")]
    pub size: String,
    /// Scene seeds (one camera path each).
    #[arg(long, value_delimiter = ',', default_value = "1,2")]
    pub seeds: Vec<u64>,
    /// Use every Nth frame of the 49-frame clip (1 = all).
    #[arg(long, default_value_t = 2)]
    pub stride: u32,
    #[command(flatten)]
    pub set: set::SetArgs,
    /// The set: `default`, or a comma-separated list of `shadows`, `edge`, `covered-tag`,
    /// `cloth`, `fill-light`, `high-camera`, `picture` (a printed picture as the
    /// marker instead of tags), or `hard` (all of them but `picture`). A variant that names a
    /// table (`cloth`) runs on that table only; otherwise on wood and plain.
    #[arg(long, default_value = "default")]
    pub scene: String,
    /// Also write, per background, seed and frame, the inputs of a fill comparison as PNGs
    /// into this folder: `input`, `truth` (ground truth), `revealed`, `offedge` (the revealed
    /// pixels 3 px or more from the in-between's silhouette) and `fillmask` (white = set),
    /// each fill's diminished plate (`fill_<name>`) and output (`out_<name>`; the fills named
    /// `_shadows` with the pipeline's shadows on), and the twin composited over black and over
    /// white (`twin_over_black`, `twin_over_white`: any other fill goes under the same twin);
    /// see `scripts/inpaint_baselines.py`.
    #[arg(long)]
    pub dump_fills: Option<PathBuf>,
}

/// The fills `--dump-fills` compares (all with our texturing, dilation and camera path), and
/// whether the pipeline's shadows are on (`_shadows`: the key prop's cast shadow lifted, the
/// twin's cast; such an output holds more than its plate under the twin).
fn dump_methods() -> Vec<(&'static str, ArSettings, bool)> {
    let ours = ArSettings::ours();
    [
        ("rectangle", Fill::PaperRectangle, false),
        ("rays", Fill::Rays, false),
        ("plate", Fill::CleanPlate, false),
        ("patch", Fill::Patch { plate: false }, false),
        ("patch_plate", Fill::Patch { plate: true }, false),
        ("rays_shadows", Fill::Rays, true),
        ("plate_shadows", Fill::CleanPlate, true),
        ("patch_shadows", Fill::Patch { plate: false }, true),
    ]
    .into_iter()
    .map(|(n, fill, shadows)| (n, ArSettings { fill, ..ours }, shadows))
    .chain([(
        "plate_unaligned",
        ArSettings {
            fill: Fill::CleanPlate,
            align_plate: false,
            ..ours
        },
        false,
    )])
    .collect()
}

/// A mask as an opaque RGBA8 image: white where set, black elsewhere.
fn mask_rgba8(mask: &[bool]) -> Vec<u8> {
    mask.iter()
        .flat_map(|&b| {
            let v = if b { 255 } else { 0 };
            [v, v, v, 255]
        })
        .collect()
}

/// Runs the fills of [`dump_methods`] with the pipeline's layers kept and writes the PNGs of
/// `--dump-fills` (layout in its help). The fill mask is the key-pose silhouette as tracked,
/// dilated as the pipeline does; the fills cover all of it (as with `--passes`).
fn dump_fills(
    renderer: &mut Renderer,
    dir: &Path,
    (w, h): (u32, u32),
    seeds: &[u64],
    frames: &[u32],
    (backgrounds, set): (&[Background], pa_scene::variant::SetOptions),
) -> Result<()> {
    let png = |path: PathBuf, rgba8: &[u8]| set::save_png(&path, w, h, rgba8);
    let gray = mask_rgba8;
    for &background in backgrounds {
        for &seed in seeds {
            let sub = dir.join(format!("{background:?}_s{seed}").to_lowercase());
            std::fs::create_dir_all(&sub).with_context(|| format!("creating {}", sub.display()))?;
            for (i, (name, settings, shadows)) in dump_methods().into_iter().enumerate() {
                errln!("dump {background:?} seed {seed}: {name}");
                let spec = SceneSpec {
                    seed,
                    width: w,
                    height: h,
                    background,
                    set,
                    ..SceneSpec::default()
                };
                run_scene_shadows(
                    renderer,
                    spec,
                    settings,
                    frames.iter().copied(),
                    true,
                    shadows,
                    |f, out, _, revealed| {
                        let stem = |what: &str| sub.join(format!("f{:03}_{what}.png", f.index));
                        if i == 0 {
                            let key = Mask::new(
                                w,
                                h,
                                out.key_mask.iter().map(|&b| u8::from(b) * 255).collect(),
                            )?;
                            let mut fill = Mask::zeros(w, h)?;
                            dilate(&key, settings.dilate_px, DilateShape::Disc, &mut fill)?;
                            let fill: Vec<bool> = fill.as_slice().iter().map(|&v| v != 0).collect();
                            png(stem("input"), &f.input.rgba8)?;
                            png(stem("truth"), &f.ground_truth.rgba8)?;
                            png(stem("revealed"), &gray(&revealed.all))?;
                            png(stem("offedge"), &gray(&revealed.off_edge))?;
                            png(stem("fillmask"), &gray(&fill))?;
                        }
                        if let Some(p) = &out.passes {
                            png(stem(&format!("fill_{name}")), &p.plate_rgba8)?;
                            png(stem(&format!("out_{name}")), &out.rgba8)?;
                            if i == 0 {
                                // The twin as the pipeline composites it (anti-aliased edge,
                                // linear light) over black and over white: another fill's
                                // plate goes under the same twin as
                                // `black + (white - black) * plate` in linear light.
                                let mask: Vec<bool> =
                                    p.twin_rgba8.chunks_exact(4).map(|px| px[3] != 0).collect();
                                for (what, level) in
                                    [("twin_over_black", 0u8), ("twin_over_white", 255)]
                                {
                                    let mut bg = [level, level, level, 255].repeat(mask.len());
                                    composite_twin_over(
                                        &mut bg,
                                        &p.twin_rgba8,
                                        &mask,
                                        w,
                                        h,
                                        settings.anti_alias,
                                    );
                                    png(stem(what), &bg)?;
                                }
                            }
                        }
                        anyhow::Ok(())
                    },
                )?;
            }
        }
    }
    Ok(())
}

pub fn run(args: Args) -> Result<()> {
    let (w, h) = super::parse_size(&args.size)?;
    // Refused, not silently raised to 1 (issue 11).
    if args.stride == 0 || args.stride > 46 {
        bail!(
            "--stride must be 1 to 46 (every Nth frame of the 49), got {}",
            args.stride
        );
    }

    if let Some(dir) = &args.set.write_kit {
        return set::write_kit(&args.set, dir);
    }
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    if !args.set.set.is_empty() {
        return set::run_sets(&args);
    }
    let variant = pa_scene::parse_variant(&args.scene)?;
    let backgrounds = match variant.background {
        Some(b) => vec![b],
        None => vec![Background::Wood, Background::Plain],
    };
    // Rows say which set they were measured on, unless it is the default set.
    let label = |b: Background| {
        if variant.set.is_default() && variant.background.is_none() {
            format!("{b:?}")
        } else {
            format!("{b:?} ({})", args.scene)
        }
    };
    let mut renderer = Renderer::new()?;
    errln!("renderer: {}", renderer.adapter_info());
    let stride = args.stride;
    // Frames 0..3 let the tracker lock on; then every `stride`-th frame.
    let frames: Vec<u32> = (0..3).chain((3..49).step_by(stride as usize)).collect();
    if let Some(dir) = &args.dump_fills {
        dump_fills(
            &mut renderer,
            dir,
            (w, h),
            &args.seeds,
            &frames,
            (&backgrounds, variant.set),
        )?;
        outln!("fill comparison PNGs in {}", dir.display());
    }
    let mut rows: Vec<MethodRow> = Vec::new();
    let mut curves: Vec<Curve> = Vec::new();
    for (bi, &background) in backgrounds.iter().enumerate() {
        // The memory rows (pa_scene::memory) after the methods, with the same measures.
        let memory_rows = memory_methods().into_iter().map(|mm| {
            let m = Method {
                name: mm.name,
                settings: mm.settings,
                key_frames: vec![0],
                camera_path: CameraPath::Handheld,
            };
            (m, (mm.mode, mm.twin))
        });
        let printed = (None, TwinTexture::AsPrinted);
        for (m, memory) in methods()
            .into_iter()
            .map(|m| (m, printed))
            .chain(memory_rows)
        {
            let mut all = Vec::new();
            let mut seed_of = Vec::new();
            for &seed in &args.seeds {
                let spec = SceneSpec {
                    seed,
                    width: w,
                    height: h,
                    background,
                    camera_path: m.camera_path,
                    key_frames: m.key_frames.clone(),
                    set: variant.set,
                    ..SceneSpec::default()
                };
                errln!("{background:?} seed {seed}: {}", m.name);
                let r = run_scene_memory(
                    &mut renderer,
                    spec,
                    m.settings,
                    memory,
                    frames.iter().copied(),
                    |_, _, _| anyhow::Ok(()),
                )?;
                seed_of.extend(std::iter::repeat_n(seed, r.len()));
                all.extend(r);
            }
            rows.push(MethodRow {
                background: label(background),
                method: m.name.to_string(),
                prop_psnr_db: mean(all.iter().map(|f| f.psnr_prop)),
                prop_ssim: mean(all.iter().map(|f| f.ssim_prop)),
                revealed_psnr_db: mean(all.iter().map(|f| f.psnr_revealed)),
                revealed_ssim: mean(all.iter().map(|f| f.ssim_revealed)),
                revealed_off_edge_psnr_db: mean(all.iter().map(|f| f.psnr_revealed_off_edge)),
                rot_err_deg_median: median(all.iter().map(|f| f.rot_err_deg)),
                texture_diminish_ms_median: median(
                    all.iter()
                        .map(|f| Some(f.timings.texture_ms + f.timings.diminish_ms)),
                ),
                flicker_ours: mean(all.iter().map(|f| f.flicker.map(|x| x.0))),
                flicker_truth: mean(all.iter().map(|f| f.flicker.map(|x| x.1))),
                frames: all.len(),
            });
            if bi == 0
                && (m.name.starts_with("ours:")
                    || m.name.starts_with("ours, two")
                    || m.name.starts_with("paper"))
            {
                let points = seed_of
                    .into_iter()
                    .zip(all)
                    .map(|(seed, f)| CurvePoint {
                        seed,
                        frame: f.frame,
                        key: f.key,
                        rotation_deg: f.key_distance_deg,
                        displacement_h: f.key_distance_props,
                        psnr_prop: f.psnr_prop,
                    })
                    .collect();
                curves.push(Curve {
                    name: m.name.to_string(),
                    points,
                });
            }
        }
    }

    // Tracking rows: the tracker alone, per still and in video mode (the pose filter), on
    // every frame of the clip (a video: consecutive frames), clean and with sensor noise.
    // At the eval's size and at the scene's default 960x540 (where per-still poses are
    // ten times better); on wood only (the board's detections do not see the table).
    let noises = [
        None,
        Some(SensorNoise::HANDHELD),
        Some(SensorNoise::HANDHELD_LENS),
    ];
    let default_size = (SceneSpec::default().width, SceneSpec::default().height);
    let mut sizes = vec![(w, h)];
    if default_size != (w, h) {
        sizes.push(default_size);
    }
    for &(tw, th) in &sizes {
        let background = Background::Wood;
        let mut acc: Vec<TrackingErrors> = vec![TrackingErrors::default(); noises.len()];
        for &seed in &args.seeds {
            let spec = SceneSpec {
                seed,
                width: tw,
                height: th,
                background,
                ..SceneSpec::default()
            };
            errln!("{background:?} seed {seed}, {tw}x{th}: tracking per still and with the video filter");
            let r = tracking_errors(&mut renderer, spec, 0..49, &noises)?;
            for (a, e) in acc.iter_mut().zip(r) {
                // Frames 0..3: the video tracker locks on.
                let skip = |v: Vec<Option<f64>>| v.into_iter().skip(3);
                a.per_still_rot_deg.extend(skip(e.per_still_rot_deg));
                a.video_rot_deg.extend(skip(e.video_rot_deg));
            }
        }
        for (noise, a) in noises.iter().zip(acc) {
            let frames_name = match noise {
                None => "clean frames".to_string(),
                Some(n) => format!(
                    "noisy frames (noise {} levels, blur {}x{})",
                    n.sigma,
                    n.blur_passes,
                    if n.linear_light {
                        " in linear light"
                    } else {
                        ""
                    }
                ),
            };
            for (mode, v) in [
                ("per still", &a.per_still_rot_deg),
                ("video filter", &a.video_rot_deg),
            ] {
                rows.push(MethodRow {
                    background: format!("{background:?}"),
                    method: format!("tracking {mode}, {tw}x{th}, {frames_name}"),
                    prop_psnr_db: None,
                    prop_ssim: None,
                    revealed_psnr_db: None,
                    revealed_ssim: None,
                    revealed_off_edge_psnr_db: None,
                    rot_err_deg_median: median(v.iter().copied()),
                    texture_diminish_ms_median: None,
                    flicker_ours: None,
                    flicker_truth: None,
                    frames: v.iter().flatten().count(),
                });
            }
        }
    }

    let files = EvalReport {
        width: w,
        height: h,
        seeds: args.seeds,
        frames: frames.len(),
        methods: rows,
        curves,
    }
    .render();
    let plot_paths = files.write(&args.out)?;
    out!("{}", files.report);
    outln!(
        "\nwrote {} and {}",
        args.out.join("report.md").display(),
        args.out.join("results.json").display()
    );
    outln!("plots:");
    for p in &plot_paths {
        outln!("  {}", p.display());
    }
    Ok(())
}
