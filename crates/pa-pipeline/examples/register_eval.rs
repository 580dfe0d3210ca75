//! Measures `propsalive register` (pa_pipeline::register) on generated views of the built-in
//! set, where the true placement is known (`pa_scene::scene::marker_from_prop`).
//!
//! For each trial the placement is perturbed (x/y within a 10 mm disc, lift within
//! +-`--lift-mm` (3), yaw within +-10 degrees, seeded), views are rendered around the prop (azimuths spread over
//! `--spread` degrees, elevations alternating +-5 degrees around `--elevation`), tracked with
//! the real tracker, and registered; the error against the truth is printed.
//!
//! ```text
//! cargo run --release -p pa-pipeline --example register_eval -- [--size 1280x720]
//!     [--views 10] [--trials 5] [--elevation 30] [--spread 80] [--curve views|elevation]
//!     [--psnr] [--scale] [--lift-mm 3]
//! ```
//!
//! `--curve views` repeats the measurement for 2..=10 views (1 view is refused); `--curve
//! elevation` for elevations 10..=60 degrees. `--psnr` also runs the frame pipeline over the
//! scene's in-betweens with the start, registered and true placements and prints the prop
//! PSNR of each.
#![allow(clippy::unwrap_used, clippy::print_stdout, clippy::print_stderr)]

use std::time::Instant;

use glam::{Mat4, Vec3};
use pa_camera::{camera_from_world_look_at, CameraModel};
use pa_model::anim;
use pa_pipeline::ar::{ArPipeline, ArSettings, FrameTimes};
use pa_pipeline::register::{
    register, track::ViewTracker, PlacementParams, RegisterSettings, RegisterView,
};
use pa_render::Renderer;
use pa_scene::scene::{marker_from_prop, Rng};
use pa_scene::{Scene, SceneSpec};

struct Opts {
    width: u32,
    height: u32,
    views: usize,
    trials: usize,
    elevation: f32,
    spread: f32,
    curve: Option<String>,
    psnr: bool,
    scale: bool,
    lift_mm: f64,
}

fn opts() -> Opts {
    let mut o = Opts {
        width: 1280,
        height: 720,
        views: 10,
        trials: 5,
        elevation: 30.0,
        spread: 80.0,
        curve: None,
        psnr: false,
        scale: false,
        lift_mm: 3.0,
    };
    let args: Vec<String> = std::env::args().skip(1).collect();
    let mut i = 0;
    while i < args.len() {
        let v = args.get(i + 1).cloned().unwrap_or_default();
        match args[i].as_str() {
            "--size" => {
                let (w, h) = v.split_once('x').unwrap();
                (o.width, o.height) = (w.parse().unwrap(), h.parse().unwrap());
            }
            "--views" => o.views = v.parse().unwrap(),
            "--trials" => o.trials = v.parse().unwrap(),
            "--elevation" => o.elevation = v.parse().unwrap(),
            "--spread" => o.spread = v.parse().unwrap(),
            "--curve" => o.curve = Some(v),
            "--lift-mm" => o.lift_mm = v.parse().unwrap(),
            "--psnr" => {
                o.psnr = true;
                i += 1;
                continue;
            }
            "--scale" => {
                o.scale = true;
                i += 1;
                continue;
            }
            other => panic!("unknown flag {other}"),
        }
        i += 2;
    }
    o
}

/// The view `i` of `n`: azimuth spread over `spread` degrees in front of the prop, elevation
/// alternating +-5 degrees around `elevation`, 0.55 m away.
fn view_pose(i: usize, n: usize, elevation: f32, spread: f32) -> Mat4 {
    let u = if n > 1 {
        i as f32 / (n - 1) as f32
    } else {
        0.5
    };
    let az = (-spread / 2.0 + spread * u).to_radians();
    let el = (elevation + if i.is_multiple_of(2) { -5.0 } else { 5.0 })
        .clamp(5.0, 85.0)
        .to_radians();
    let d = 0.55;
    let eye = Vec3::new(
        d * el.cos() * az.sin(),
        d * el.cos() * az.cos(),
        -d * el.sin(),
    );
    camera_from_world_look_at(eye, Vec3::new(0.0, 0.0, -0.08), Vec3::NEG_Z).unwrap()
}

/// The true placement of the scene.
fn truth() -> PlacementParams {
    let m = marker_from_prop();
    assert!((m.w_axis.truncate()).length() < 1e-9);
    PlacementParams {
        translation_m: [0.0; 3],
        yaw_deg: 0.0,
        scale: 1.0,
        upright: true,
    }
}

fn perturbed(rng: &mut Rng, lift_mm: f64) -> PlacementParams {
    let r = 10.0 * rng.f32().sqrt() as f64;
    let a = rng.f32() as f64 * std::f64::consts::TAU;
    truth().with_delta(&[
        r * a.cos(),
        r * a.sin(),
        (rng.f32() as f64 - 0.5) * 2.0 * lift_mm,
        (rng.f32() as f64 - 0.5) * 20.0,
        0.0,
    ])
}

struct Trial {
    err_xy_mm: f64,
    err_z_mm: f64,
    err_yaw_deg: f64,
    seconds: f64,
    /// CPU seconds (all threads) of the registration.
    cpu_s: f64,
    result: Result<PlacementParams, String>,
}

fn trial(
    scene: &Scene,
    renderer: &mut Renderer,
    o: &Opts,
    views: usize,
    elevation: f32,
    seed: u64,
) -> (Trial, PlacementParams) {
    let camera = CameraModel::pinhole(scene.intrinsics);
    let mut tracker =
        ViewTracker::new(camera, pa_track::TrackTarget::Board(scene.board.clone())).unwrap();
    let mut vs: Vec<RegisterView> = Vec::new();
    for i in 0..views {
        let pose = view_pose(i, views, elevation, o.spread);
        let f = scene.render_view(renderer, pose, Some(0.0)).unwrap();
        if let Some(v) = tracker
            .view(format!("view{i}"), f.rgba8, f.width, f.height)
            .unwrap()
        {
            vs.push(v);
        }
    }
    let mut rng = Rng::new(seed);
    let start = perturbed(&mut rng, o.lift_mm);
    let model = &scene.model;
    let key = anim::sample(model, 0, 0.0);
    let settings = RegisterSettings {
        refine_scale: o.scale,
        ..Default::default()
    };
    let t0 = Instant::now();
    let c0 = cpu_seconds();
    let r = register(model, &key, start, &vs, &settings);
    let seconds = t0.elapsed().as_secs_f64();
    let cpu_s = cpu_seconds() - c0;
    let t = truth();
    match r {
        Ok(reg) => {
            let d = reg.placement.change_from(&t);
            (
                Trial {
                    err_xy_mm: (d[0] * d[0] + d[1] * d[1]).sqrt(),
                    err_z_mm: d[2].abs(),
                    err_yaw_deg: d[3].abs(),
                    seconds,
                    cpu_s,
                    result: Ok(reg.placement),
                },
                start,
            )
        }
        Err(e) => (
            Trial {
                err_xy_mm: f64::NAN,
                err_z_mm: f64::NAN,
                err_yaw_deg: f64::NAN,
                seconds,
                cpu_s,
                result: Err(e.to_string()),
            },
            start,
        ),
    }
}

/// CPU time of this process (user + system, all threads), seconds, from /proc/self/stat
/// (clock ticks of 1/100 s); NaN where it cannot be read.
fn cpu_seconds() -> f64 {
    let Ok(stat) = std::fs::read_to_string("/proc/self/stat") else {
        return f64::NAN;
    };
    let Some((_, rest)) = stat.rsplit_once(')') else {
        return f64::NAN;
    };
    let f: Vec<&str> = rest.split_whitespace().collect();
    let ticks = |i: usize| {
        f.get(i)
            .and_then(|v| v.parse::<f64>().ok())
            .unwrap_or(f64::NAN)
    };
    // Fields 14 and 15 of the line (utime, stime) are 11 and 12 after the name.
    (ticks(11) + ticks(12)) / 100.0
}

fn median(mut v: Vec<f64>) -> f64 {
    v.retain(|x| x.is_finite());
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn max(v: &[f64]) -> f64 {
    v.iter().copied().fold(f64::NAN, f64::max)
}

/// Mean prop PSNR of the pipeline over the scene's in-betweens with a placement.
fn prop_psnr(scene: &Scene, renderer: &mut Renderer, placement: &PlacementParams) -> f64 {
    let camera = CameraModel::pinhole(scene.intrinsics);
    let mut p = ArPipeline::new(
        renderer,
        scene.model.clone(),
        0,
        camera,
        placement.marker_from_prop_f32(),
        None,
        ArSettings::ours(),
    )
    .unwrap();
    let (plate, plate_pose) = scene.clean_plate(renderer).unwrap();
    let plate = pa_diminish::ImageRgba8::new(plate.width, plate.height, plate.rgba8).unwrap();
    p.set_clean_plate(plate, plate_pose);
    let mut psnr = Vec::new();
    for i in (0..scene.spec.frames).step_by(4) {
        let f = scene.frame(renderer, i).unwrap();
        let out = p
            .process_with_pose(
                renderer,
                &f.input.rgba8,
                f.input.width,
                f.input.height,
                FrameTimes {
                    animation_s: f.time_s,
                    key_pose_s: 0.0,
                },
                f.camera_from_marker,
            )
            .unwrap();
        let m = pa_scene::eval::measure(scene, renderer, &f, &out).unwrap();
        psnr.extend(m.psnr_prop);
    }
    psnr.iter().sum::<f64>() / psnr.len() as f64
}

fn main() {
    let o = opts();
    let mut renderer = Renderer::new().unwrap();
    let spec = SceneSpec {
        width: o.width,
        height: o.height,
        frames: 49,
        ..Default::default()
    };
    let scene = Scene::new(spec, &mut renderer).unwrap();
    let rows: Vec<(usize, f32)> = match o.curve.as_deref() {
        Some("views") => (1..=10).map(|n| (n, o.elevation)).collect(),
        Some("elevation") => [10.0, 20.0, 30.0, 40.0, 50.0, 60.0]
            .into_iter()
            .map(|e| (o.views, e))
            .collect(),
        _ => vec![(o.views, o.elevation)],
    };
    println!(
        "{}x{}, {} trials per row, azimuth spread {} deg, perturbation: x/y <= 10 mm, lift +-{} mm, yaw +-10 deg{}",
        o.width,
        o.height,
        o.trials,
        o.spread,
        o.lift_mm,
        if o.scale { ", scale refined" } else { "" }
    );
    println!("| views | elevation (deg) | recovered | median xy (mm) | max xy (mm) | median lift (mm) | max lift (mm) | median yaw (deg) | max yaw (deg) | median time (s) | median CPU (s) |");
    println!("|---|---|---|---|---|---|---|---|---|---|---|");
    let mut last = None;
    for (views, elevation) in rows {
        let mut ts = Vec::new();
        for k in 0..o.trials {
            let (t, start) = trial(&scene, &mut renderer, &o, views, elevation, 1000 + k as u64);
            if let Err(e) = &t.result {
                eprintln!("views {views} elevation {elevation} trial {k}: {e}");
            }
            if let Ok(p) = &t.result {
                last = Some((start, *p));
            }
            ts.push(t);
        }
        let ok = ts.iter().filter(|t| t.result.is_ok()).count();
        let xy: Vec<f64> = ts.iter().map(|t| t.err_xy_mm).collect();
        let z: Vec<f64> = ts.iter().map(|t| t.err_z_mm).collect();
        let yaw: Vec<f64> = ts.iter().map(|t| t.err_yaw_deg).collect();
        println!(
            "| {views} | {elevation} | {ok}/{} | {:.3} | {:.3} | {:.3} | {:.3} | {:.3} | {:.3} | {:.2} | {:.2} |",
            ts.len(),
            median(xy.clone()),
            max(&xy),
            median(z.clone()),
            max(&z),
            median(yaw.clone()),
            max(&yaw),
            median(ts.iter().map(|t| t.seconds).collect()),
            median(ts.iter().map(|t| t.cpu_s).collect()),
        );
    }
    if o.psnr {
        if let Some((start, reg)) = last {
            let t = truth();
            let p_true = prop_psnr(&scene, &mut renderer, &t);
            let p_reg = prop_psnr(&scene, &mut renderer, &reg);
            let p_start = prop_psnr(&scene, &mut renderer, &start);
            println!(
                "prop PSNR over the in-betweens (every 4th of 49 frames): true placement {p_true:.2} dB, registered {p_reg:.2} dB ({:+.2}), perturbed start {p_start:.2} dB ({:+.2})",
                p_reg - p_true,
                p_start - p_true
            );
        }
    }
}
