//! `propsalive eval`: our methods against the paper's on generated scenes with ground truth,
//! and the degradation curve (quality against the in-between's distance from its key pose).

use std::fmt::Write as _;
use std::path::PathBuf;

use anyhow::{Context, Result};
use pa_pipeline::ar::{ArSettings, Fill, Texturing};
use pa_render::Renderer;
use pa_scene::eval::{mean, median, run_scene, FrameMetrics};
use pa_scene::scene::{Background, CameraPath};
use pa_scene::SceneSpec;

#[derive(clap::Args)]
pub struct Args {
    /// Output folder for report.md and results.json.
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
}

struct Method {
    name: &'static str,
    settings: ArSettings,
    key_frames: Vec<u32>,
}

fn methods() -> Vec<Method> {
    let ours = ArSettings::ours();
    vec![
        Method {
            name: "paper (live, no visibility, rectangle fill)",
            settings: ArSettings::paper(),
            key_frames: vec![0],
        },
        Method {
            name: "live + visibility, rectangle fill",
            settings: ArSettings {
                fill: Fill::PaperRectangle,
                ..ours
            },
            key_frames: vec![0],
        },
        Method {
            name: "live, no visibility, ray fill",
            settings: ArSettings {
                texturing: Texturing::Live { visibility: false },
                ..ours
            },
            key_frames: vec![0],
        },
        Method {
            name: "ours: live + visibility, ray fill",
            settings: ours,
            key_frames: vec![0],
        },
        Method {
            name: "ours with clean plate",
            settings: ArSettings {
                fill: Fill::CleanPlate,
                ..ours
            },
            key_frames: vec![0],
        },
        Method {
            name: "model texture (no live sampling), ray fill",
            settings: ArSettings {
                texturing: Texturing::ModelTexture,
                ..ours
            },
            key_frames: vec![0],
        },
        Method {
            name: "ours, two key poses (frames 0 and 24)",
            settings: ours,
            key_frames: vec![0, 24],
        },
    ]
}

fn fmt(v: Option<f64>, digits: usize) -> String {
    v.map(|x| format!("{x:.digits$}"))
        .unwrap_or_else(|| "-".into())
}

pub fn run(args: Args) -> Result<()> {
    let (w, h) = super::parse_size(&args.size)?;
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    let mut renderer = Renderer::new()?;
    eprintln!("renderer: {}", renderer.adapter_info());
    let stride = args.stride.max(1);
    // Frames 0..3 let the tracker lock on; then every `stride`-th frame.
    let frames: Vec<u32> = (0..3).chain((3..49).step_by(stride as usize)).collect();
    let mut table = String::new();
    let mut json_rows = Vec::new();
    let _ = writeln!(
        table,
        "| background | method | prop PSNR dB | prop SSIM | revealed PSNR dB | revealed SSIM | rot. err. deg | texture+diminish ms |\n|---|---|---|---|---|---|---|---|"
    );
    let mut curves: Vec<(String, Vec<FrameMetrics>)> = Vec::new();
    for background in [Background::Wood, Background::Plain] {
        for m in methods() {
            let mut all = Vec::new();
            for &seed in &args.seeds {
                let spec = SceneSpec {
                    seed,
                    width: w,
                    height: h,
                    background,
                    camera_path: CameraPath::Handheld,
                    key_frames: m.key_frames.clone(),
                    ..SceneSpec::default()
                };
                eprintln!("{background:?} seed {seed}: {}", m.name);
                let r = run_scene(
                    &mut renderer,
                    spec,
                    m.settings,
                    frames.iter().copied(),
                    |_, _, _| Ok(()),
                )
                .map_err(anyhow::Error::msg)?;
                all.extend(r);
            }
            let row = [
                mean(all.iter().map(|f| f.psnr_prop)),
                mean(all.iter().map(|f| f.ssim_prop)),
                mean(all.iter().map(|f| f.psnr_revealed)),
                mean(all.iter().map(|f| f.ssim_revealed)),
                median(all.iter().map(|f| f.rot_err_deg)),
                median(
                    all.iter()
                        .map(|f| Some(f.timings.texture_ms + f.timings.diminish_ms)),
                ),
            ];
            let _ = writeln!(
                table,
                "| {background:?} | {} | {} | {} | {} | {} | {} | {} |",
                m.name,
                fmt(row[0], 2),
                fmt(row[1], 3),
                fmt(row[2], 2),
                fmt(row[3], 3),
                fmt(row[4], 3),
                fmt(row[5], 1)
            );
            json_rows.push(serde_json::json!({
                "background": format!("{background:?}"), "method": m.name,
                "prop_psnr_db": row[0], "prop_ssim": row[1], "revealed_psnr_db": row[2],
                "revealed_ssim": row[3], "rot_err_deg_median": row[4],
                "texture_diminish_ms_median": row[5], "frames": all.len(),
            }));
            if background == Background::Wood
                && (m.name.starts_with("ours:")
                    || m.name.starts_with("ours, two")
                    || m.name.starts_with("paper"))
            {
                curves.push((m.name.to_string(), all));
            }
        }
    }
    // Degradation curve: prop PSNR by distance of the in-between from its key pose.
    let bins = [
        (0.0, 5.0),
        (5.0, 15.0),
        (15.0, 25.0),
        (25.0, 35.0),
        (35.0, 50.0),
    ];
    let mut curve = String::from("| method | ");
    for (a, b) in bins {
        let _ = write!(curve, "{a:.0}-{b:.0} deg | ");
    }
    curve.push_str("\n|---|");
    curve.push_str(&"---|".repeat(bins.len()));
    curve.push('\n');
    let mut json_curves = Vec::new();
    for (name, all) in &curves {
        let _ = write!(curve, "| {name} | ");
        let mut points = Vec::new();
        for (a, b) in bins {
            let sel: Vec<&FrameMetrics> = all
                .iter()
                .filter(|f| f.key_distance_deg >= a && f.key_distance_deg < b)
                .collect();
            let v = mean(sel.iter().map(|f| f.psnr_prop));
            let _ = write!(curve, "{} (n={}) | ", fmt(v, 2), sel.len());
            points.push(serde_json::json!({"from_deg": a, "to_deg": b, "prop_psnr_db": v, "frames": sel.len()}));
        }
        curve.push('\n');
        json_curves.push(serde_json::json!({"method": name, "bins": points}));
    }
    let report = format!(
        "# Props Alive evaluation\n\nGenerated scenes at {w}x{h}, seeds {:?}, {} frames each, \
         real tracker, ground truth = the in-between rendered as if printed.\n\n## Methods\n\n{table}\n\
         ## Degradation: prop PSNR against the head's rotation from the key pose (wood table)\n\n{curve}",
        args.seeds,
        frames.len()
    );
    let json = serde_json::json!({"size": [w, h], "seeds": args.seeds, "methods": json_rows, "degradation": json_curves});
    pa_model::export::write_atomic(&args.out.join("report.md"), report.as_bytes())?;
    pa_model::export::write_atomic(
        &args.out.join("results.json"),
        serde_json::to_string_pretty(&json)?.as_bytes(),
    )?;
    print!("{report}");
    println!(
        "\nwrote {} and {}",
        args.out.join("report.md").display(),
        args.out.join("results.json").display()
    );
    Ok(())
}
