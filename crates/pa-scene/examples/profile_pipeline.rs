//! Runs the frame pipeline over and over on a few generated frames, for a profiler:
//! `cargo build --release -p pa-scene --example profile_pipeline` then
//! `perf record -g target/release/examples/profile_pipeline [cpu|gpu] [WIDTHxHEIGHT] [REPEATS] [PROPS] [rays|patch|memory]`
//! (`memory`: the ray fill with the texture memory on).
//! Prints the median stage timings.

use pa_pipeline::ar::{ArSettings, Fill, RenderPath};
use pa_render::Renderer;
use pa_scene::eval::pipeline_for;
use pa_scene::{Scene, SceneSpec};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let path: RenderPath = args
        .get(1)
        .map(|s| s.parse())
        .transpose()?
        .unwrap_or(RenderPath::Cpu);
    let (w, h) = args
        .get(2)
        .and_then(|s| s.split_once('x'))
        .and_then(|(a, b)| Some((a.parse().ok()?, b.parse().ok()?)))
        .unwrap_or((1280u32, 720u32));
    let repeats: usize = args.get(3).and_then(|s| s.parse().ok()).unwrap_or(100);
    let props: usize = args.get(4).and_then(|s| s.parse().ok()).unwrap_or(1);
    let fill = match args.get(5).map(String::as_str) {
        Some("patch") => Fill::Patch { plate: false },
        _ => Fill::Rays,
    };
    let mut renderer = Renderer::new().map_err(|e| e.to_string())?;
    let spec = SceneSpec {
        seed: 1,
        width: w,
        height: h,
        frames: 8,
        props: props as u32,
        ..SceneSpec::default()
    };
    let scene = Scene::new(spec, &mut renderer)?;
    let frames: Vec<_> = (0..8)
        .map(|i| scene.frame(&mut renderer, i))
        .collect::<Result<_, _>>()
        .map_err(|e| e.to_string())?;
    // One pipeline prop per copy on the set (PROP_SPOTS), as in `propsalive bench`.
    let settings = ArSettings {
        fill,
        ..ArSettings::ours()
    };
    let mut p = pipeline_for(&scene, &mut renderer, settings)?;
    p.set_render_path(path);
    p.set_texture_memory(args.get(5).is_some_and(|a| a == "memory"));
    let mut t: Vec<[f64; 6]> = Vec::new();
    for k in 0..repeats {
        let f = &frames[k % frames.len()];
        let t0 = std::time::Instant::now();
        let mut out = p
            .process(
                &mut renderer,
                &f.input.rgba8,
                w,
                h,
                pa_pipeline::ar::FrameTimes {
                    animation_s: f.time_s,
                    key_pose_s: 0.0,
                },
                k as f64 / 24.0,
            )
            .map_err(|e| e.to_string())?;
        let s = out.timings;
        p.recycle_frame(&mut out);
        t.push([
            s.track_ms,
            s.animate_ms,
            s.texture_ms,
            s.diminish_ms,
            s.composite_ms,
            t0.elapsed().as_secs_f64() * 1e3,
        ]);
    }
    let names = [
        "track",
        "animate",
        "texture",
        "diminish",
        "composite",
        "total",
    ];
    for (i, n) in names.iter().enumerate() {
        let mut v: Vec<f64> = t.iter().skip(3).map(|r| r[i]).collect();
        v.sort_by(f64::total_cmp);
        println!("{n:>10}: {:7.2} ms median", v[v.len() / 2]);
    }
    Ok(())
}
