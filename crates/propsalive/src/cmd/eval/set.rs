//! `propsalive eval --set DIR` and `--write-kit DIR`: external sets (takes of our set rendered
//! by another renderer, `scripts/blender/render_set.py`), measured exactly as the generated
//! scenes are, one row per fill; and the kit that renderer builds the set from.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use pa_pipeline::ar::{ArSettings, Fill};
use pa_render::Renderer;
use pa_report::eval::{methods_table, MethodRow};
use pa_report::plot::{BarChart, BarGroup};
use pa_report::stats::{mean, median};
use pa_scene::eval::{run_scene_shadows, FrameMetrics};
use pa_scene::scene::Background;
use pa_scene::set::kit::{kit, KitModel, KitSpec};
use pa_scene::set::{run_set_with, SetManifest, SetRun};
use pa_scene::SceneSpec;

use super::Args;

#[derive(clap::Args)]
pub struct SetArgs {
    /// Measure an external set (a folder with manifest.json, e.g. rendered by
    /// scripts/blender/render_set.py) instead of the generated scenes; repeatable.
    #[arg(long, value_name = "DIR")]
    pub set: Vec<PathBuf>,
    /// With --set: also measure the same fills on the generated wood scene (--seeds, --size,
    /// --stride), for rows side by side.
    #[arg(long, requires = "set")]
    pub with_generated: bool,
    /// With --set: write every output frame as PNG under OUT/<set>/<fill>/ (with
    /// --with-generated also OUT/generated_<scene>_s<seed>/<fill>/, beside its `truth` and
    /// `revealed` region).
    #[arg(long, requires = "set")]
    pub save_frames: bool,
    /// Write the kit an external renderer builds the set from (kit.json, board.png and, for
    /// the built-in bust, prop.glb) into DIR, and stop.
    #[arg(long, value_name = "DIR", conflicts_with = "set")]
    pub write_kit: Option<PathBuf>,
    /// The kit's model: a glTF file with an animation (default: the built-in bust).
    #[arg(long, requires = "write_kit")]
    pub kit_model: Option<PathBuf>,
    /// Height the kit's glTF model is scaled to, metres.
    #[arg(long, default_value_t = 0.16)]
    pub kit_height_m: f32,
    /// Turn of the kit's glTF model about the up axis, degrees.
    #[arg(long, default_value_t = 0.0)]
    pub kit_yaw_deg: f32,
    /// Frames of the kit's camera path.
    #[arg(long, default_value_t = 16)]
    pub kit_frames: u32,
    /// Image size of the kit, WIDTHxHEIGHT.
    #[arg(long, default_value = "640x360")]
    pub kit_size: String,
}

/// Writes the kit into `dir`.
pub fn write_kit(args: &SetArgs, dir: &Path) -> Result<()> {
    let (width, height) = super::super::parse_size(&args.kit_size)?;
    if args.kit_frames == 0 || args.kit_frames > 1000 {
        anyhow::bail!("--kit-frames must be 1 to 1000, got {}", args.kit_frames);
    }
    let model = match &args.kit_model {
        Some(path) => KitModel::Gltf {
            path: path.clone(),
            height_m: args.kit_height_m,
            yaw_deg: args.kit_yaw_deg,
        },
        None => KitModel::BuiltinBust,
    };
    let k = kit(&KitSpec {
        width,
        height,
        frames: args.kit_frames,
        model,
        ..KitSpec::default()
    })?;
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    for (name, bytes) in &k.files {
        pa_io::write_atomic(&dir.join(name), bytes)?;
        outln!("wrote {}", dir.join(name).display());
    }
    Ok(())
}

/// The fills compared on a set, with the generated scenes' method names.
fn fills() -> [(&'static str, ArSettings); 8] {
    let ours = ArSettings::ours();
    [
        (
            "live + visibility, rectangle fill",
            ArSettings {
                fill: Fill::PaperRectangle,
                ..ours
            },
        ),
        ("ours: live + visibility, ray fill", ours),
        (
            "ours: plain look (not relit, hard seams)",
            ArSettings {
                look: pa_pipeline::ar::LiveLook::PLAIN,
                ..ours
            },
        ),
        (
            "ours: first-order light (no sun, no cast shadows)",
            ArSettings {
                look: pa_pipeline::ar::LiveLook {
                    sun: false,
                    ..pa_pipeline::ar::LiveLook::RELIT_FEATHERED
                },
                ..ours
            },
        ),
        (
            "ours: no grazing reflection",
            ArSettings {
                look: pa_pipeline::ar::LiveLook {
                    grazing: false,
                    ..pa_pipeline::ar::LiveLook::RELIT_FEATHERED
                },
                ..ours
            },
        ),
        (
            "ours with clean plate",
            ArSettings {
                fill: Fill::CleanPlate,
                ..ours
            },
        ),
        (
            "ours with clean plate, not aligned",
            ArSettings {
                fill: Fill::CleanPlate,
                align_plate: false,
                ..ours
            },
        ),
        (
            "ours, patch fill",
            ArSettings {
                fill: Fill::Patch { plate: false },
                ..ours
            },
        ),
    ]
}

/// A fill's method name, with ", shadows" when the pipeline's shadows are on.
fn with_shadows(method: &str, shadows: bool) -> String {
    if shadows {
        format!("{method}, shadows")
    } else {
        method.to_string()
    }
}

/// The bar chart of revealed PSNR per fill (categories), one group per set and shadows off
/// or on (`fills.svg`).
fn fills_chart(rows: &[MethodRow]) -> BarChart {
    // The fills only: the rows that change ours' look alone fill as ours does.
    let ours = ArSettings::ours();
    let fills: Vec<(&str, ArSettings)> = fills()
        .into_iter()
        .filter(|(_, s)| s.look == ours.look || s.fill != ours.fill)
        .collect();
    let categories: Vec<&str> = fills.iter().map(|(m, _)| short(m)).collect();
    let mut groups: Vec<BarGroup> = Vec::new();
    let mut sets: Vec<&str> = Vec::new();
    for r in rows {
        if !sets.contains(&r.background.as_str()) {
            sets.push(&r.background);
        }
    }
    for set in sets {
        for shadows in [false, true] {
            groups.push(BarGroup {
                name: format!("{set}, shadows {}", if shadows { "on" } else { "off" }),
                values: fills
                    .iter()
                    .map(|(m, _)| {
                        let name = with_shadows(m, shadows);
                        rows.iter()
                            .find(|r| r.background == set && r.method == name)
                            .and_then(|r| r.revealed_psnr_db)
                    })
                    .collect(),
            });
        }
    }
    BarChart {
        title: "Revealed-background PSNR per fill, set and shadows".into(),
        value_label: "revealed PSNR, dB (higher is better)".into(),
        categories: categories.iter().map(|s| s.to_string()).collect(),
        groups,
        baseline: Some(0),
        note: "baseline (dashed): the paper's rectangle".into(),
    }
}

fn short(name: &str) -> &'static str {
    if name.contains("rectangle") {
        "rectangle"
    } else if name.contains("first-order") {
        "first_order"
    } else if name.contains("grazing") {
        "no_grazing"
    } else if name.contains("patch") {
        "patch"
    } else if name.contains("relit") {
        "relit"
    } else if name.contains("not aligned") {
        "plate_unaligned"
    } else if name.contains("plate") {
        "plate"
    } else if name.contains("memory") {
        "memory"
    } else {
        "rays"
    }
}

/// The folder of a fill's saved frames: its short name, `_shadows` with shadows.
fn fill_dir(method: &str, shadows: bool) -> String {
    if shadows {
        format!("{}_shadows", short(method))
    } else {
        short(method).to_string()
    }
}

fn row(background: String, method: &str, all: &[FrameMetrics]) -> MethodRow {
    MethodRow {
        background,
        method: method.to_string(),
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
    }
}

fn opt(v: Option<f64>, digits: usize) -> String {
    v.map(|x| format!("{x:.digits$}"))
        .unwrap_or_else(|| "-".into())
}

/// The per-frame table of one set and fill.
fn frame_table(all: &[FrameMetrics]) -> String {
    let mut t = String::from(
        "| frame | tracked | rot. err. deg | trans. err. mm | key mask IoU | twin mask IoU | prop PSNR dB | revealed PSNR dB | flicker ours / truth |\n|---|---|---|---|---|---|---|---|---|\n",
    );
    for f in all {
        let _ = writeln!(
            t,
            "| {} | {} | {} | {} | {} | {} | {} | {} | {} / {} |",
            f.frame,
            f.tracked,
            opt(f.rot_err_deg, 3),
            opt(f.trans_err_mm, 2),
            opt(f.key_mask_iou, 3),
            opt(f.twin_mask_iou, 3),
            opt(f.psnr_prop, 2),
            opt(f.psnr_revealed, 2),
            opt(f.flicker.map(|x| x.0), 2),
            opt(f.flicker.map(|x| x.1), 2),
        );
    }
    t
}

pub(super) fn save_png(path: &Path, width: u32, height: u32, rgba8: &[u8]) -> Result<()> {
    let img = image::RgbaImage::from_raw(width, height, rgba8.to_vec())
        .context("output frame of the wrong size")?;
    let mut png = Vec::new();
    img.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)?;
    pa_io::write_atomic(path, &png).with_context(|| format!("writing {}", path.display()))
}

/// Runs every fill over every set (and, with `--with-generated`, the generated wood scene);
/// writes `report.md` and `results.json` into `--out`.
pub fn run_sets(args: &Args) -> Result<()> {
    let mut renderer = Renderer::new()?;
    errln!("renderer: {}", renderer.adapter_info());
    let mut rows = Vec::new();
    let mut details = String::new();
    let mut json_frames = Vec::new();
    for dir in &args.set.set {
        let set = SetManifest::read(dir)?;
        let name = dir
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_else(|| dir.display().to_string());
        errln!(
            "set {name}: {} frames {}x{}, {}",
            set.frames.len(),
            set.width,
            set.height,
            set.renderer
        );
        // Every fill without and with shadows, then ours with the texture memory
        // (pa_scene::memory).
        let runs = fills()
            .into_iter()
            .flat_map(|(m, s)| {
                [false, true].map(|shadows| {
                    let run = SetRun {
                        shadows,
                        ..SetRun::default()
                    };
                    (m, s, run)
                })
            })
            .chain([(
                "ours: + texture memory",
                ArSettings::ours(),
                SetRun {
                    memory: true,
                    ..SetRun::default()
                },
            )]);
        for (method, settings, run) in runs {
            let shadows = run.shadows;
            let fill_dir = fill_dir(method, shadows);
            let method = with_shadows(method, shadows);
            let frames_dir = args.out.join(&name).join(&fill_dir);
            if args.set.save_frames {
                std::fs::create_dir_all(&frames_dir)
                    .with_context(|| format!("creating {}", frames_dir.display()))?;
            }
            let (all, light) = run_set_with(&mut renderer, &set, settings, run, |f, _, out, m| {
                errln!(
                    "  {fill_dir} frame {}: rot {} deg, trans {} mm, key IoU {}, prop {} dB, revealed {} dB",
                    f.index,
                    opt(m.rot_err_deg, 3),
                    opt(m.trans_err_mm, 2),
                    opt(m.key_mask_iou, 3),
                    opt(m.psnr_prop, 2),
                    opt(m.psnr_revealed, 2)
                );
                if args.set.save_frames {
                    save_png(
                        &frames_dir.join(format!("{:04}.png", f.index)),
                        set.width,
                        set.height,
                        &out.rgba8,
                    )?;
                }
                anyhow::Ok(())
            })?;
            if let Some(l) = light {
                let t = l.toward_light;
                errln!(
                    "  {fill_dir}: light toward ({:.3}, {:.3}, {:.3}), softness {:.2} px, ratio {:.3}/{:.3}/{:.3}",
                    t.x, t.y, t.z, l.softness_px, l.ratio_rgb[0], l.ratio_rgb[1], l.ratio_rgb[2]
                );
            }
            let _ = write!(details, "\n### {name}: {method}\n\n{}", frame_table(&all));
            for f in &all {
                json_frames.push(serde_json::json!({
                    "set": name, "method": method, "frame": f.frame, "tracked": f.tracked,
                    "rot_err_deg": f.rot_err_deg, "trans_err_mm": f.trans_err_mm,
                    "key_mask_iou": f.key_mask_iou, "twin_mask_iou": f.twin_mask_iou,
                    "prop_psnr_db": f.psnr_prop, "revealed_psnr_db": f.psnr_revealed,
                    "flicker_ours": f.flicker.map(|x| x.0),
                    "flicker_truth": f.flicker.map(|x| x.1),
                }));
            }
            rows.push(row(format!("Blender: {name}"), &method, &all));
        }
    }
    if args.set.with_generated {
        let (w, h) = super::super::parse_size(&args.size)?;
        let variant = pa_scene::parse_variant(&args.scene)?;
        let background = variant.background.unwrap_or(Background::Wood);
        let frames: Vec<u32> = (0..3)
            .chain((3..49).step_by(args.stride as usize))
            .collect();
        for (i, ((method, settings), shadows)) in fills()
            .into_iter()
            .flat_map(|f| [(f, false), (f, true)])
            .enumerate()
        {
            let fill_dir = fill_dir(method, shadows);
            let method = with_shadows(method, shadows);
            let mut all = Vec::new();
            for &seed in &args.seeds {
                errln!(
                    "generated {background:?} ({}) seed {seed}: {method}",
                    args.scene
                );
                // --save-frames: OUT/generated_<scene>_s<seed>/<fill>/NNNN.png, and beside the
                // fills the truth and the revealed region (white), written with the first fill
                // (they are the same for every fill).
                let gen_dir = args.out.join(format!(
                    "generated_{}_s{seed}",
                    args.scene.replace([',', '/'], "+")
                ));
                let frames_dir = gen_dir.join(&fill_dir);
                if args.set.save_frames {
                    for d in [
                        &frames_dir,
                        &gen_dir.join("truth"),
                        &gen_dir.join("revealed"),
                    ] {
                        std::fs::create_dir_all(d)
                            .with_context(|| format!("creating {}", d.display()))?;
                    }
                }
                let spec = SceneSpec {
                    seed,
                    width: w,
                    height: h,
                    background,
                    set: variant.set,
                    ..SceneSpec::default()
                };
                all.extend(run_scene_shadows(
                    &mut renderer,
                    spec,
                    settings,
                    frames.iter().copied(),
                    false,
                    shadows,
                    |f, out, _, revealed| {
                        if args.set.save_frames {
                            let name = format!("{:04}.png", f.index);
                            save_png(&frames_dir.join(&name), w, h, &out.rgba8)?;
                            if i == 0 {
                                let truth = gen_dir.join("truth").join(&name);
                                save_png(&truth, w, h, &f.ground_truth.rgba8)?;
                                let mask = super::mask_rgba8(&revealed.all);
                                save_png(&gen_dir.join("revealed").join(&name), w, h, &mask)?;
                            }
                        }
                        anyhow::Ok(())
                    },
                )?);
            }
            rows.push(row(
                format!("generated {background:?} ({}) {w}x{h}", args.scene),
                &method,
                &all,
            ));
        }
    }
    let report = format!(
        "# Props Alive evaluation on external sets\n\nSets: {}. Real tracker on the set's input \
         frames; ground truth = the set's in-between renders and masks; flicker = mean \
         frame-to-frame change (8-bit levels) of the revealed region after the table-plane \
         homography of the true cameras, ours / the ground truth's.\n\n## Methods\n\n{}\n\
         ## Frames\n{details}",
        args.set
            .set
            .iter()
            .map(|d| d.display().to_string())
            .collect::<Vec<_>>()
            .join(", "),
        methods_table(&rows)
    );
    let json = serde_json::json!({
        "sets": args.set.set.iter().map(|d| d.display().to_string()).collect::<Vec<_>>(),
        "methods": rows.iter().map(MethodRow::json).collect::<Vec<_>>(),
        "frames": json_frames,
    });
    pa_io::write_atomic(&args.out.join("report.md"), report.as_bytes())?;
    pa_io::write_atomic(
        &args.out.join("fills.svg"),
        fills_chart(&rows).to_svg().as_bytes(),
    )?;
    pa_io::write_atomic(
        &args.out.join("results.json"),
        serde_json::to_string_pretty(&json)?.as_bytes(),
    )?;
    out!("{}", methods_table(&rows));
    outln!(
        "\nwrote {}, {} and {}",
        args.out.join("report.md").display(),
        args.out.join("fills.svg").display(),
        args.out.join("results.json").display()
    );
    Ok(())
}
