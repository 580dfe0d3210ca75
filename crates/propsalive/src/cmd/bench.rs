//! `propsalive bench`: the whole frame pipeline on generated frames, timed per stage.
//!
//! For every configuration (frame size x prop vertex count x props per frame) it generates the
//! built-in scene's frames first (input and ground truth, kept in memory), then runs the
//! pipeline on them with no disk I/O and no measurement inside the timed loop, and only then
//! measures the output against the ground truth (prop PSNR), so that speed work can be checked
//! against quality.
//!
//! What is timed, per frame:
//! - **track**: grey conversion, AprilTag detection and board pose by the real tracker, once
//!   per frame;
//! - **animate**, **texture**, **diminish**, **composite**: the [`ArPipeline`] stages (all
//!   props of the frame);
//! - **readback**: mapping the GPU results and copying them to CPU memory (row padding,
//!   depth decoding), taken out of texture, where the pipeline counts it. Texture keeps the
//!   wait for the GPU to finish, which on a software rasteriser is the rasterisation itself
//!   (reported as `gpu_wait` in the JSON);
//! - **end-to-end**: the wall time of the whole frame (all props).
//!
//! "N props" means one `ArPipeline` drawing N props in every frame (`ArPipeline::add_prop`):
//! the frame is tracked, filled and composited once; every prop is posed, placed and drawn
//! (key-pose depth and live-textured twin, with the depth test between props). The N props
//! are copies of the bust standing at distinct spots of the set (`SceneSpec::props`,
//! `pa_scene::scene::PROP_SPOTS`: the board's centre, beside the board, rows behind it): the
//! input shows all N at the key pose, the ground truth all N at the in-between, and the prop
//! PSNR covers all N (the first prop stands where the single prop does, so `--props 1`
//! measures what it always did).
//!
//! Every configuration records the 1-minute load average at its start and end.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{bail, Context, Result};
use indicatif::{ProgressBar, ProgressStyle};
use pa_pipeline::ar::{ArFrame, ArPipeline, ArSettings, Fill, RenderPath, StageTimings};
use pa_render::Renderer;
use pa_report::bench::{fps, BenchReport, BenchRow};
use pa_report::stats::{mean, stat};
use pa_report::system::{cpu_description, load_average, reset_peak_rss, status_mib};
use pa_scene::eval::{measure, pipeline_for};
use pa_scene::scene::PROP_SPOTS;
use pa_scene::{PropSpec, Scene, SceneFrame, SceneSpec};

/// The long help of `propsalive bench` (what is timed and what "N props" means).
pub const LONG_ABOUT: &str = "\
Time the whole pipeline per stage on generated frames (no disk I/O in the timed loop).

The built-in scene's frames (input and ground truth) are generated first and kept in memory; \
the pipeline then runs on them (warm-up frames untimed), and the output's prop PSNR against \
the ground truth is measured afterwards, outside the timed loop.

By default the configurations vary one axis at a time around 1280x720, an 8,000-vertex prop \
and one prop per frame: sizes 640x480, 1280x720, 1920x1080; props of 2k, 8k, 32k, 128k \
vertices; 1, 4 and 16 props per frame (8 configurations). --grid runs every combination.

\"N props\" = one pipeline drawing N props in every frame (ArPipeline::add_prop): tracking, \
the fill and the composite once a frame, posing and drawing per prop, with the depth test \
between props. The N props are copies of the bust at distinct spots of the set (the board's \
centre, beside the board, rows behind it; at most 16); the ground truth has all N at the \
in-between and the prop PSNR covers all N. Frames the tracker loses are still \
rendered, at the true pose, so every stage is timed; the `tracked` column counts the frames \
it did track.

\"readback\" is the CPU side of reading GPU results back (map, copy, unpad, decode); \
\"texture\" excludes it but includes waiting for the GPU, which on a software rasteriser is \
the rasterisation itself (gpu_wait in the JSON). Times are median / 95th percentile in ms; \
fps = 1000 / median end-to-end. Peak RSS is the process's high-water mark during the timed \
loop (reset before it where Linux allows) and includes the frames the bench holds in memory \
(held_frames_mib in the JSON). The JSON (written atomically) also names the adapter, backend, \
CPU and the load average before and after the run; the table and the JSON give each \
configuration's 1-minute load average at its start and end.";

#[derive(clap::Args)]
pub struct Args {
    /// Frame sizes, WIDTHxHEIGHT, comma-separated [default: 640x480,1280x720,1920x1080;
    /// --quick: 640x480,1280x720].
    #[arg(long, value_delimiter = ',')]
    pub sizes: Option<Vec<String>>,
    /// Prop vertex counts (approximate: the generated bust's grid is rounded)
    /// [default: 2000,8000,32000,128000; --quick: 2000,8000].
    #[arg(long, value_delimiter = ',')]
    pub vertices: Option<Vec<u32>>,
    /// Props per frame, each at its own spot on the set (1..=16) [default: 1,4,16; --quick: 1,4].
    #[arg(long, value_delimiter = ',')]
    pub props: Option<Vec<u32>>,
    /// Timed frames per configuration [default: 24; --quick: 8].
    #[arg(long)]
    pub frames: Option<u32>,
    /// Untimed warm-up frames per configuration (the tracker needs 3 to lock on).
    #[arg(long, default_value_t = 3)]
    pub warmup: u32,
    /// Every combination of sizes x vertices x props instead of one axis at a time.
    #[arg(long)]
    pub grid: bool,
    /// Fewer frames and configurations (see the defaults of each flag).
    #[arg(long)]
    pub quick: bool,
    /// Pipeline settings to time.
    #[arg(long, value_enum, default_value_t = Method::Ours)]
    pub method: Method,
    /// Scene seed (camera path, table texture).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Where to write the results as JSON (atomically).
    #[arg(long, default_value = "out/bench/bench.json")]
    pub json: PathBuf,
    /// Renderers of the texture stage to time, comma-separated: cpu (our rasteriser), gpu
    /// (wgpu: the GPU, or Mesa's software drivers). Every configuration runs once per path.
    /// Default: the path the pipeline picks for this machine (cpu on a software adapter), plus
    /// the other path at the base configuration, so the two are compared in every run.
    #[arg(long, value_delimiter = ',')]
    pub render_path: Option<Vec<RenderPath>>,
}

/// Which pipeline settings the bench times.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Method {
    /// Live texturing with visibility, relit with feathered seams, ray fill, 4 px dilation
    /// (ArSettings::ours).
    Ours,
    /// The paper's: live texturing without visibility, rectangle fill.
    Paper,
    /// Ours with the clean-plate fill.
    Plate,
    /// Ours with the patch fill (seeded by the previous frame's result from the second frame).
    Patch,
    /// Ours with the plain look: live samples not relit, hard seams (the default before
    /// relighting and feathered seams became ours).
    Plain,
    /// Ours with the texture memory on (updated in the texture stage from every tracked frame).
    Memory,
    /// Ours with the board hidden under a cover picture (`[marker] hide = "cover"`).
    HideCover,
    /// Ours on the `picture` set: a printed picture as the marker, tracked by its natural
    /// features (frame to frame after the first detection).
    Picture,
}

impl Method {
    fn settings(self) -> ArSettings {
        match self {
            Method::Ours => ArSettings::ours(),
            Method::Paper => ArSettings::paper(),
            Method::Plate => ArSettings {
                fill: Fill::CleanPlate,
                ..ArSettings::ours()
            },
            Method::Patch => ArSettings {
                fill: Fill::Patch { plate: false },
                ..ArSettings::ours()
            },
            Method::Plain => ArSettings {
                look: pa_pipeline::ar::LiveLook::PLAIN,
                ..ArSettings::ours()
            },
            Method::Memory | Method::HideCover | Method::Picture => ArSettings::ours(),
        }
    }

    /// The board hidden under a cover, if this method hides it.
    fn hide(self) -> Option<pa_scene::HideKind> {
        matches!(self, Method::HideCover).then_some(pa_scene::HideKind::Cover)
    }

    /// Whether the texture memory is on ([`ArPipeline::set_texture_memory`]).
    fn memory(self) -> bool {
        matches!(self, Method::Memory)
    }

    fn describe(self) -> &'static str {
        match self {
            Method::Ours => {
                "ours (live texturing + visibility, relit, feathered seams, ray fill, 4 px dilation)"
            }
            Method::Paper => "paper (live texturing, no visibility, rectangle fill)",
            Method::Plate => "ours with clean plate (live + visibility, plate fill)",
            Method::Patch => "ours with the patch fill (live + visibility, patch fill)",
            Method::Plain => "ours with the plain look (not relit, hard seams)",
            Method::Memory => "ours with the texture memory (live + visibility, ray fill)",
            Method::HideCover => "ours with the board hidden under a cover picture",
            Method::Picture => "ours on a picture marker (natural-feature tracking)",
        }
    }
}

/// One configuration to time.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Config {
    width: u32,
    height: u32,
    vertices: u32,
    props: u32,
    path: RenderPath,
}

/// The checked settings of a run.
struct Plan {
    configs: Vec<Config>,
    frames: u32,
    warmup: u32,
    method: Method,
    seed: u64,
    json: PathBuf,
    /// `--render-path`, or None for the machine's choice plus the other at the base.
    paths: Option<Vec<RenderPath>>,
}

const MAX_PROPS: u32 = PROP_SPOTS.len() as u32;
const MIN_VERTICES: u32 = 100;
const MAX_VERTICES: u32 = 2_000_000;
const MAX_FRAMES: u32 = 10_000;

fn plan(args: Args) -> Result<Plan> {
    let quick = args.quick;
    let sizes = args.sizes.unwrap_or_else(|| {
        let s: &[&str] = if quick {
            &["640x480", "1280x720"]
        } else {
            &["640x480", "1280x720", "1920x1080"]
        };
        s.iter().map(|s| s.to_string()).collect()
    });
    let sizes: Vec<(u32, u32)> = sizes
        .iter()
        .map(|s| super::parse_size(s).with_context(|| format!("--sizes {s:?}")))
        .collect::<Result<_>>()?;
    let vertices = args.vertices.unwrap_or_else(|| {
        if quick {
            vec![2_000, 8_000]
        } else {
            vec![2_000, 8_000, 32_000, 128_000]
        }
    });
    let props = args
        .props
        .unwrap_or_else(|| if quick { vec![1, 4] } else { vec![1, 4, 16] });
    let frames = args.frames.unwrap_or(if quick { 8 } else { 24 });
    if sizes.is_empty() || vertices.is_empty() || props.is_empty() {
        bail!("--sizes, --vertices and --props each need at least one value");
    }
    if let Some(v) = vertices
        .iter()
        .find(|&&v| !(MIN_VERTICES..=MAX_VERTICES).contains(&v))
    {
        bail!("--vertices {v} is out of range ({MIN_VERTICES}..={MAX_VERTICES})");
    }
    if let Some(p) = props.iter().find(|&&p| !(1..=MAX_PROPS).contains(&p)) {
        bail!("--props {p} is out of range (1..={MAX_PROPS})");
    }
    if !(1..=MAX_FRAMES).contains(&frames) {
        bail!("--frames {frames} is out of range (1..={MAX_FRAMES})");
    }
    if args.render_path.as_ref().is_some_and(|p| p.is_empty()) {
        bail!("--render-path needs at least one of cpu, gpu");
    }
    if args.warmup > MAX_FRAMES {
        bail!(
            "--warmup {} is out of range (0..={MAX_FRAMES})",
            args.warmup
        );
    }
    let configs = if args.grid {
        let mut c = Vec::new();
        for &(width, height) in &sizes {
            for &v in &vertices {
                for &p in &props {
                    c.push(Config {
                        width,
                        height,
                        vertices: v,
                        props: p,
                        path: RenderPath::Gpu,
                    });
                }
            }
        }
        c
    } else {
        axes(&sizes, &vertices, &props)
    };
    // Checked before minutes of timing: never a FIFO, a device or a link.
    pa_io::check_replaceable(&args.json)?;
    Ok(Plan {
        configs,
        frames,
        warmup: args.warmup,
        method: args.method,
        seed: args.seed,
        json: args.json,
        paths: args.render_path,
    })
}

/// Every configuration once per render path: `paths`, or `auto` everywhere plus the other
/// path right after the first (base) configuration.
fn with_paths(configs: &[Config], paths: Option<&[RenderPath]>, auto: RenderPath) -> Vec<Config> {
    match paths {
        Some(paths) => configs
            .iter()
            .flat_map(|c| paths.iter().map(move |&path| Config { path, ..*c }))
            .collect(),
        None => {
            let other = match auto {
                RenderPath::Cpu => RenderPath::Gpu,
                RenderPath::Gpu => RenderPath::Cpu,
            };
            let mut out = Vec::with_capacity(configs.len() + 1);
            for (i, c) in configs.iter().enumerate() {
                out.push(Config { path: auto, ..*c });
                if i == 0 {
                    out.push(Config { path: other, ..*c });
                }
            }
            out
        }
    }
}

/// One axis at a time around a base configuration (1280x720, 8,000 vertices, 1 prop where
/// they are listed, else the first value of each list), without repeats.
fn axes(sizes: &[(u32, u32)], vertices: &[u32], props: &[u32]) -> Vec<Config> {
    let base_size = if sizes.contains(&(1280, 720)) {
        (1280, 720)
    } else {
        sizes[0]
    };
    let base_v = if vertices.contains(&8_000) {
        8_000
    } else {
        vertices[0]
    };
    let base_p = if props.contains(&1) { 1 } else { props[0] };
    let config = |(width, height): (u32, u32), vertices: u32, props: u32| Config {
        width,
        height,
        vertices,
        props,
        path: RenderPath::Gpu,
    };
    let mut out: Vec<Config> = vec![config(base_size, base_v, base_p)];
    let candidates = sizes
        .iter()
        .map(|&s| config(s, base_v, base_p))
        .chain(vertices.iter().map(|&v| config(base_size, v, base_p)))
        .chain(props.iter().map(|&p| config(base_size, base_v, p)));
    for c in candidates {
        if !out.contains(&c) {
            out.push(c);
        }
    }
    out
}

/// The timings of one frame (all props).
#[derive(Debug, Clone, Copy, Default)]
struct Sample {
    track: f64,
    animate: f64,
    texture: f64,
    diminish: f64,
    composite: f64,
    readback: f64,
    gpu_wait: f64,
    end_to_end: f64,
    tracked: bool,
}

/// Runs one frame through the pipeline (all its props).
fn run_frame(
    pipe: &mut ArPipeline,
    renderer: &mut Renderer,
    scene: &Scene,
    f: &SceneFrame,
) -> Result<(ArFrame, Sample)> {
    let (w, h) = (f.input.width, f.input.height);
    let key_time = scene.spec.key_frames[f.key] as f32 / scene.spec.fps;
    let frame_time = f.index as f64 / scene.spec.fps as f64;
    let rb0 = renderer.readback_times();
    let t0 = Instant::now();
    let mut out = pipe.process(
        renderer,
        &f.input.rgba8,
        w,
        h,
        pa_pipeline::ar::FrameTimes {
            animation_s: f.time_s,
            key_pose_s: key_time,
        },
        frame_time,
    )?;
    let tracked = out.camera_from_marker.is_some();
    if !tracked {
        // Lost: render at the true pose so that every stage is still timed.
        let track_ms = out.timings.track_ms;
        pipe.recycle(std::mem::take(&mut out.rgba8));
        out = pipe.process_with_pose(
            renderer,
            &f.input.rgba8,
            w,
            h,
            pa_pipeline::ar::FrameTimes {
                animation_s: f.time_s,
                key_pose_s: key_time,
            },
            f.camera_from_marker,
        )?;
        out.timings.track_ms = track_ms;
    }
    let end_to_end = ms(t0);
    let rb = renderer.readback_times().since(&rb0);
    let t: StageTimings = out.timings;
    Ok((
        out,
        Sample {
            track: t.track_ms,
            animate: t.animate_ms,
            texture: (t.texture_ms - rb.copy_ms).max(0.0),
            diminish: t.diminish_ms,
            composite: t.composite_ms,
            readback: rb.copy_ms,
            gpu_wait: rb.wait_ms,
            end_to_end,
            tracked,
        },
    ))
}

fn ms(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

fn run_config(
    renderer: &mut Renderer,
    plan: &Plan,
    config: Config,
    label: &str,
) -> Result<BenchRow> {
    let started = Instant::now();
    let load_start = load_average();
    let total = plan.warmup + plan.frames;
    let spec = SceneSpec {
        seed: plan.seed,
        width: config.width,
        height: config.height,
        frames: total.max(SceneSpec::default().frames),
        prop: PropSpec::with_vertex_count(config.vertices),
        props: config.props,
        set: pa_scene::SetOptions {
            picture_marker: plan.method == Method::Picture,
            ..Default::default()
        },
        ..SceneSpec::default()
    };
    let bar = ProgressBar::new(u64::from(total) * 2 + u64::from(plan.frames));
    bar.set_style(
        ProgressStyle::with_template("{prefix} {bar:30} {pos}/{len} {msg}")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    bar.set_prefix(label.to_string());
    bar.set_message("building the scene");
    let scene = Scene::new(spec, renderer).map_err(anyhow::Error::msg)?;
    let actual_vertices = scene.model.vertex_count();

    // Every frame is generated before the timed loop.
    bar.set_message("generating frames");
    let mut frames = Vec::with_capacity(total as usize);
    for i in 0..total {
        let mut f = scene.frame(renderer, i)?;
        // Depth is not needed; do not hold it.
        f.input.depth_m = Vec::new();
        f.ground_truth.depth_m = Vec::new();
        frames.push(f);
        bar.inc(1);
    }

    let settings = plan.method.settings();
    // One pipeline prop per prop on the set, each at its spot.
    let mut pipe = pipeline_for(&scene, renderer, settings).map_err(anyhow::Error::msg)?;
    pipe.set_render_path(config.path);
    pipe.set_texture_memory(plan.method.memory());
    if let Some(kind) = plan.method.hide() {
        pa_scene::hide::apply(&scene, renderer, &mut pipe, kind).map_err(anyhow::Error::msg)?;
    }

    bar.set_message("warming up");
    for f in &frames[..plan.warmup as usize] {
        let (mut out, _) = run_frame(&mut pipe, renderer, &scene, f)?;
        pipe.recycle_frame(&mut out);
        bar.inc(1);
    }

    // The timed loop: no I/O, no measurement.
    bar.set_message("timing");
    let rss_start = status_mib("VmRSS");
    let peak_scope = if reset_peak_rss() {
        "timed loop"
    } else {
        "process"
    };
    // Where the timed loop keeps its outputs, touched before it (a copy of each input).
    let mut held_images = frames[plan.warmup as usize..]
        .iter()
        .map(|f| f.input.rgba8.clone())
        .collect::<Vec<_>>()
        .into_iter();
    let mut samples = Vec::with_capacity(plan.frames as usize);
    let mut outputs = Vec::with_capacity(plan.frames as usize);
    for f in &frames[plan.warmup as usize..] {
        let (mut out, sample) = run_frame(&mut pipe, renderer, &scene, f)?;
        // Keep what the measurement needs (a copy of the image, and the pose), and hand the
        // image, masks and codes back as a live loop that shows the frame would.
        let kept = match held_images.next() {
            Some(mut image) => {
                image.copy_from_slice(&out.rgba8);
                image
            }
            None => std::mem::take(&mut out.rgba8),
        };
        pipe.recycle_frame(&mut out);
        out.rgba8 = kept;
        outputs.push(out);
        samples.push(sample);
        bar.inc(1);
    }
    let peak = status_mib("VmHWM");
    let held_bytes: usize = frames
        .iter()
        .map(|f| f.input.rgba8.len() + f.ground_truth.rgba8.len())
        .sum::<usize>()
        + outputs.iter().map(|o| o.rgba8.len()).sum::<usize>();
    drop(pipe);

    // Quality, outside the timed loop.
    bar.set_message("measuring");
    let mut psnr = Vec::new();
    for (f, out) in frames[plan.warmup as usize..].iter().zip(&outputs) {
        let m = measure(&scene, renderer, f, out).map_err(anyhow::Error::msg)?;
        psnr.push(m.psnr_prop);
        bar.inc(1);
    }
    bar.finish_and_clear();

    let col = |f: fn(&Sample) -> f64| stat(samples.iter().map(f).collect());
    let stages = vec![
        ("track", col(|s| s.track)),
        ("animate", col(|s| s.animate)),
        ("texture", col(|s| s.texture)),
        ("diminish", col(|s| s.diminish)),
        ("composite", col(|s| s.composite)),
        ("readback", col(|s| s.readback)),
    ];
    Ok(BenchRow {
        render_path: config.path.name(),
        width: config.width,
        height: config.height,
        requested_vertices: config.vertices,
        actual_vertices,
        props: config.props,
        frames: samples.len(),
        tracked: samples.iter().filter(|s| s.tracked).count(),
        stages,
        gpu_wait: col(|s| s.gpu_wait),
        end_to_end: col(|s| s.end_to_end),
        psnr_prop: mean(psnr),
        peak_rss_mb: peak,
        rss_start_mb: rss_start,
        peak_scope,
        held_mb: held_bytes as f64 / (1024.0 * 1024.0),
        seconds: started.elapsed().as_secs_f64(),
        load_start,
        load_end: load_average(),
    })
}

pub fn run(args: Args) -> Result<()> {
    let started = Instant::now();
    let mut plan = plan(args)?;
    if let Some(dir) = plan.json.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    let mut renderer = Renderer::new()?;
    let adapter = renderer.adapter_info();
    let backend = format!("{:?}", renderer.backend());
    let (cpu, cores) = cpu_description();
    let load_start = load_average();
    let auto = RenderPath::auto(&renderer);
    plan.configs = with_paths(&plan.configs, plan.paths.as_deref(), auto);
    errln!(
        "renderer: {adapter}\n{} configurations, {} warm-up + {} timed frames each",
        plan.configs.len(),
        plan.warmup,
        plan.frames
    );
    let mut rows = Vec::new();
    for (k, &c) in plan.configs.iter().enumerate() {
        let label = format!(
            "[{}/{}] {} path, {}x{}, {} vertices, {} prop{}",
            k + 1,
            plan.configs.len(),
            c.path.name(),
            c.width,
            c.height,
            c.vertices,
            c.props,
            if c.props == 1 { "" } else { "s" }
        );
        let row = run_config(&mut renderer, &plan, c, &label)
            .with_context(|| format!("configuration {label}"))?;
        errln!(
            "{label}: {:.1} ms end-to-end median, {:.1} fps ({:.0} s)",
            row.end_to_end.median,
            fps(row.end_to_end),
            row.seconds
        );
        rows.push(row);
    }
    let total_s = started.elapsed().as_secs_f64();
    let load_end = load_average();

    let report = BenchReport {
        adapter,
        backend,
        cpu,
        cores,
        load_start,
        load_end,
        method: plan.method.describe(),
        auto_path: auto.name(),
        frames: plan.frames,
        warmup: plan.warmup,
        seed: plan.seed,
        total_seconds: total_s,
        rows,
    };
    let out = report.markdown();
    report.write_json(&plan.json)?;
    out!("{out}");
    outln!("\nwrote {} ({:.0} s in all)", plan.json.display(), total_s);
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn axes_vary_one_thing_at_a_time() {
        let c = axes(
            &[(640, 480), (1280, 720), (1920, 1080)],
            &[2_000, 8_000, 32_000, 128_000],
            &[1, 4, 16],
        );
        assert_eq!(c.len(), 8);
        assert_eq!((c[0].width, c[0].vertices, c[0].props), (1280, 8_000, 1));
        let p = with_paths(&c, None, RenderPath::Cpu);
        assert_eq!(p.len(), 9);
        assert_eq!((p[0].path, p[1].path), (RenderPath::Cpu, RenderPath::Gpu));
        assert_eq!(p[0].vertices, p[1].vertices);
        assert!(p[2..].iter().all(|c| c.path == RenderPath::Cpu));
        let both = with_paths(
            &c,
            Some(&[RenderPath::Gpu, RenderPath::Cpu]),
            RenderPath::Cpu,
        );
        assert_eq!(both.len(), 16);
        assert!(c.iter().all(|c| {
            let base = [
                (c.width, c.height) == (1280, 720),
                c.vertices == 8_000,
                c.props == 1,
            ];
            base.iter().filter(|b| !**b).count() <= 1
        }));
        let one = axes(&[(160, 120)], &[2_000], &[1, 2]);
        assert_eq!(one.len(), 2);
    }
}
