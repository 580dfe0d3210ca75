//! The texture memory's eval rows alone (wood, seeds 1 and 2, 480x270, the eval's frames):
//! ours with the memory off, on, and primed by the scan orbit, with the model as printed and
//! with its textures painted flat (their mean colour); mean prop PSNR and the
//! degradation bins at 25-35 and 35-50 degrees. `cargo run --release --example memory_rows`.
#![allow(clippy::unwrap_used)]

use pa_render::Renderer;
use pa_scene::memory::{run_scene_memory, MemoryMode, TwinTexture};
use pa_scene::SceneSpec;

fn main() {
    let mut renderer = Renderer::new().unwrap();
    let frames: Vec<u32> = (0..3).chain((3..49).step_by(2)).collect();
    let (printed, flat) = (TwinTexture::AsPrinted, TwinTexture::FlatColour);
    for (name, mode) in [
        ("memory off", (None, printed)),
        ("memory on", (Some(MemoryMode::On), printed)),
        ("memory + scan", (Some(MemoryMode::Scan), printed)),
        ("model painted flat, memory off", (None, flat)),
        (
            "model painted flat, memory on",
            (Some(MemoryMode::On), flat),
        ),
        (
            "model painted flat, memory + scan",
            (Some(MemoryMode::Scan), flat),
        ),
    ] {
        let mut all = Vec::new();
        for seed in [1, 2] {
            let spec = SceneSpec {
                seed,
                width: 480,
                height: 270,
                ..SceneSpec::default()
            };
            let r = run_scene_memory(
                &mut renderer,
                spec,
                pa_pipeline::ar::ArSettings::ours(),
                mode,
                frames.iter().copied(),
                |_, _, _| Ok::<(), pa_scene::SceneError>(()),
            )
            .unwrap();
            all.extend(r);
        }
        let mean = |f: &dyn Fn(f64) -> bool| {
            let v: Vec<f64> = all
                .iter()
                .filter(|m| f(m.key_distance_deg))
                .filter_map(|m| m.psnr_prop.filter(|p| p.is_finite()))
                .collect();
            v.iter().sum::<f64>() / v.len().max(1) as f64
        };
        let tex: Vec<f64> = all.iter().map(|m| m.timings.texture_ms).collect();
        let mut t = tex.clone();
        t.sort_by(f64::total_cmp);
        println!(
            "{name}: prop {:.2} dB; 25-35 deg {:.2}; 35-50 deg {:.2}; texture ms median {:.2}",
            mean(&|_| true),
            mean(&|d| (25.0..35.0).contains(&d)),
            mean(&|d| (35.0..=50.0).contains(&d)),
            t[t.len() / 2]
        );
    }
}
