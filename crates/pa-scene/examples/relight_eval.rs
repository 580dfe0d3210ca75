//! Relighting and feathered seams (issue 13, item 2) measured against ground truth:
//! `cargo run --release --example relight_eval -- [OUT_DIR] [SET_DIR]...`.
//!
//! For each look (plain, relit, feathered, both) on top of `ArSettings::ours()`: the generated
//! Wood scene at `eval`'s defaults (480x270, seeds 1 and 2, frames 0-2 then every 2nd), the
//! mean prop PSNR overall and per rotation bin of `eval`'s degradation curve; then each
//! Blender set given. With `OUT_DIR`, strips of the prop (truth | plain | relit + feathered)
//! of the generated frames farthest from the key pose are written as PNGs there.

use pa_pipeline::ar::{ArSettings, LiveLook};
use pa_render::Renderer;
use pa_scene::eval::run_scene_with;
use pa_scene::scene::Background;
use pa_scene::set::{run_set, SetManifest};
use pa_scene::SceneSpec;

const BINS: [(f64, f64); 6] = [
    (0.0, 5.0),
    (5.0, 15.0),
    (15.0, 25.0),
    (25.0, 35.0),
    (35.0, 50.0),
    (25.0, 50.0),
];

fn looks() -> [(&'static str, LiveLook); 5] {
    [
        ("plain (hard seams, no relighting)", LiveLook::PLAIN),
        (
            "relit",
            LiveLook {
                relight: true,
                feather: false,
                sun: true,
                grazing: true,
            },
        ),
        (
            "feathered",
            LiveLook {
                relight: false,
                feather: true,
                sun: false,
                grazing: false,
            },
        ),
        (
            "relit + feathered, first-order light (no sun)",
            LiveLook {
                sun: false,
                ..LiveLook::RELIT_FEATHERED
            },
        ),
        ("relit + feathered", LiveLook::RELIT_FEATHERED),
    ]
}

/// Mean of the finite values (as `eval`'s `pa_report::stats::mean`).
fn mean(v: impl Iterator<Item = f64>) -> f64 {
    let (s, n) = v
        .filter(|x| x.is_finite())
        .fold((0.0, 0usize), |(s, n), x| (s + x, n + 1));
    if n == 0 {
        f64::NAN
    } else {
        s / n as f64
    }
}

/// A crop of `rgba` (width `w`) around `bbox`, `pad` px more on each side, clamped.
fn crop(rgba: &[u8], w: u32, h: u32, bbox: (u32, u32, u32, u32), pad: u32) -> (u32, u32, Vec<u8>) {
    let x0 = bbox.0.saturating_sub(pad);
    let y0 = bbox.1.saturating_sub(pad);
    let x1 = (bbox.2 + pad).min(w - 1);
    let y1 = (bbox.3 + pad).min(h - 1);
    let (cw, ch) = (x1 - x0 + 1, y1 - y0 + 1);
    let mut out = Vec::with_capacity((cw * ch * 4) as usize);
    for y in y0..=y1 {
        let a = ((y * w + x0) * 4) as usize;
        out.extend_from_slice(&rgba[a..a + (cw * 4) as usize]);
    }
    (cw, ch, out)
}

fn bbox_of(mask: &[bool], w: u32) -> Option<(u32, u32, u32, u32)> {
    let mut b: Option<(u32, u32, u32, u32)> = None;
    for (i, _) in mask.iter().enumerate().filter(|(_, &m)| m) {
        let (x, y) = (i as u32 % w, i as u32 / w);
        b = Some(match b {
            None => (x, y, x, y),
            Some((a, c, d, e)) => (a.min(x), c.min(y), d.max(x), e.max(y)),
        });
    }
    b
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let out_dir = args.first().map(std::path::PathBuf::from);
    let sets: Vec<&String> = args.iter().skip(1).collect();
    let mut renderer = Renderer::new().map_err(|e| e.to_string())?;
    eprintln!("renderer: {}", renderer.adapter_info());
    // `RELIGHT_EVAL_FRAMES=0,14,27` and `RELIGHT_EVAL_SEEDS=5` narrow the run (quick looks).
    let list = |var: &str| -> Option<Vec<u64>> {
        let v = std::env::var(var).ok()?;
        v.split(',').map(|x| x.trim().parse().ok()).collect()
    };
    let frames: Vec<u32> = match list("RELIGHT_EVAL_FRAMES") {
        Some(f) => f.into_iter().map(|x| x as u32).collect(),
        None => (0..3).chain((3..49).step_by(2)).collect(),
    };
    let seeds = list("RELIGHT_EVAL_SEEDS").unwrap_or(vec![1, 2]);
    let strip_frames = [31u32, 35, 39, 43];
    // (frame, look index) -> crop
    let mut strips: Vec<(u32, usize, Vec<u8>, u32, u32)> = Vec::new();
    let mut truths: Vec<(u32, Vec<u8>, u32, u32)> = Vec::new();
    println!("| look | prop PSNR dB | 0-5 | 5-15 | 15-25 | 25-35 | 35-50 | 25-50 deg | texture ms (median) |");
    println!("|---|---|---|---|---|---|---|---|---|");
    // `RELIGHT_EVAL_LOOKS=0,3` runs only those looks (indices into the four).
    let only = list("RELIGHT_EVAL_LOOKS");
    for (li, (name, look)) in looks().into_iter().enumerate() {
        if only.as_ref().is_some_and(|o| !o.contains(&(li as u64))) {
            continue;
        }
        let settings = ArSettings {
            look,
            ..ArSettings::ours()
        };
        let mut all = Vec::new();
        for &seed in &seeds {
            let spec = SceneSpec {
                seed,
                width: 480,
                height: 270,
                background: Background::Wood,
                ..SceneSpec::default()
            };
            let r = run_scene_with(
                &mut renderer,
                spec,
                settings,
                frames.iter().copied(),
                false,
                |f, out, _, _| {
                    if seed == seeds[0] && strip_frames.contains(&f.index) {
                        let (w, h) = (f.input.width, f.input.height);
                        if let Some(b) = bbox_of(&out.twin_mask, w) {
                            let (cw, ch, c) = crop(&out.rgba8, w, h, b, 4);
                            strips.push((f.index, li, c, cw, ch));
                            if li == 0 {
                                let (cw, ch, c) = crop(&f.ground_truth.rgba8, w, h, b, 4);
                                truths.push((f.index, c, cw, ch));
                            }
                        }
                    }
                    Ok::<(), pa_scene::SceneError>(())
                },
            )?;
            all.extend(r);
        }
        let overall = mean(all.iter().filter_map(|f| f.psnr_prop));
        let bins: Vec<String> = BINS
            .iter()
            .map(|&(a, b)| {
                let m = mean(
                    all.iter()
                        .filter(|f| f.key_distance_deg >= a && f.key_distance_deg < b)
                        .filter_map(|f| f.psnr_prop),
                );
                format!("{m:.2}")
            })
            .collect();
        let mut tex: Vec<f64> = all.iter().map(|f| f.timings.texture_ms).collect();
        tex.sort_by(f64::total_cmp);
        let med = tex.get(tex.len() / 2).copied().unwrap_or(f64::NAN);
        println!(
            "| generated Wood: {name} | {overall:.2} | {} | {med:.1} |",
            bins.join(" | ")
        );
    }
    for dir in &sets {
        let set = SetManifest::read(std::path::Path::new(dir))?;
        for (name, look) in looks() {
            let settings = ArSettings {
                look,
                ..ArSettings::ours()
            };
            let all = run_set(&mut renderer, &set, settings, |_, _, _, _| {
                Ok::<(), pa_scene::SceneError>(())
            })?;
            let overall = mean(all.iter().filter_map(|f| f.psnr_prop));
            println!("| {dir}: {name} | {overall:.2} | | | | | | | |");
        }
    }
    if let Some(dir) = out_dir {
        std::fs::create_dir_all(&dir)?;
        for (frame, truth, tw, th) in &truths {
            // truth | plain | relit + feathered, side by side.
            let pick = |li: usize| strips.iter().find(|s| s.0 == *frame && s.1 == li);
            let (Some(plain), Some(both)) = (pick(0), pick(3)) else {
                continue;
            };
            let (w, h) = (tw * 3, *th);
            let mut img = image::RgbaImage::new(w, h);
            for (k, (data, cw)) in [(truth, *tw), (&plain.2, plain.3), (&both.2, both.3)]
                .into_iter()
                .enumerate()
            {
                for y in 0..h.min(data.len() as u32 / (cw * 4)) {
                    for x in 0..cw.min(*tw) {
                        let i = ((y * cw + x) * 4) as usize;
                        img.put_pixel(
                            k as u32 * tw + x,
                            y,
                            image::Rgba([data[i], data[i + 1], data[i + 2], 255]),
                        );
                    }
                }
            }
            let path = dir.join(format!("strip_frame{frame:02}.png"));
            img.save(&path)?;
            eprintln!("wrote {}", path.display());
        }
    }
    Ok(())
}
