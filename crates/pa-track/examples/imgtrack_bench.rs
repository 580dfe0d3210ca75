//! Picture-target accuracy and speed over synthetic 1280x720 views (exact plane-to-image
//! rendering, 3x3 supersampled, blur 0.7 px, noise 2 gray levels):
//! `cargo run --release --workspace --example imgtrack_bench [PICTURE ...]` (default: the
//! procedural test picture). For each view: a first detection (`ImageTarget::detect`), then
//! a second frame moved slightly (5 mm closer, 1 degree of roll, 0.5 degree of tilt) found by
//! frame-to-frame tracking from the first frame's pose (`ImageTarget::locate` with that
//! prediction). Prints per-tilt rows (views found, median corner error, median rotation
//! error) and the median times.
#![allow(clippy::unwrap_used)]

use std::time::Instant;

use glam::{DVec2, DVec3};
use pa_camera::{CameraModel, Intrinsics};
use pa_track::image_target::synth::{natural_picture, render_view, view_pose, Pinhole};
use pa_track::{GrayImage, ImageTarget, Pose};

const WIDTH_M: f64 = 0.25;

/// This process's CPU time (user + system, all threads), seconds, from /proc (Linux; 0
/// elsewhere): on a loaded machine the wall time of a call overstates its cost.
fn cpu_s() -> f64 {
    let Ok(s) = std::fs::read_to_string("/proc/self/stat") else {
        return 0.0;
    };
    let Some(rest) = s.rsplit(')').next() else {
        return 0.0;
    };
    let f: Vec<&str> = rest.split_whitespace().collect();
    let ticks = |i: usize| f.get(i).and_then(|v| v.parse::<f64>().ok()).unwrap_or(0.0);
    // Fields 14 and 15 of stat (utime, stime) are 12 and 13 after the ')'.
    (ticks(11) + ticks(12)) / 100.0
}

fn median(mut v: Vec<f64>) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn corners(pose: &Pose, cam: &Pinhole, h_m: f64) -> [DVec2; 4] {
    let (w, h) = (0.5 * WIDTH_M, 0.5 * h_m);
    [(-w, -h), (w, -h), (w, h), (-w, h)].map(|(x, y)| {
        let c = pose.transform_point(DVec3::new(x, y, 0.0));
        DVec2::new(cam.fx * c.x / c.z + cam.cx, cam.fy * c.y / c.z + cam.cy)
    })
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let pin = Pinhole {
        fx: 1000.0,
        fy: 1000.0,
        cx: 639.5,
        cy: 359.5,
        width: 1280,
        height: 720,
    };
    let cam = CameraModel::pinhole(Intrinsics {
        fx: pin.fx,
        fy: pin.fy,
        cx: pin.cx,
        cy: pin.cy,
        width: pin.width,
        height: pin.height,
    });
    let args: Vec<String> = std::env::args().skip(1).collect();
    let pictures: Vec<(String, GrayImage)> = if args.is_empty() {
        vec![("procedural 640x480".into(), natural_picture(640, 480, 7))]
    } else {
        args.iter()
            .map(|p| {
                let g = image::open(p).unwrap().to_luma8();
                (p.clone(), GrayImage::from(&g))
            })
            .collect()
    };
    let tilts = [0.0, 20.0, 40.0, 50.0, 60.0];
    let dists = [0.45, 0.6, 0.75, 0.9];
    let rolls = [0.0, 100.0, 230.0];
    println!("| picture | tilt (deg) | views | detected | corners median (px) | rotation median (deg) | tracked | tracked corners median (px) | tracked rotation median (deg) |");
    println!("|---|---|---|---|---|---|---|---|---|");
    let (mut t_det, mut t_trk, mut t_new) = (Vec::new(), Vec::new(), Vec::new());
    let (mut cpu_det, mut cpu_trk) = (0.0, 0.0);
    let (mut all_c, mut all_r, mut all_tc, mut all_tr) =
        (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    let (mut n_all, mut n_det, mut n_trk) = (0, 0, 0);
    for (name, pic) in &pictures {
        let t0 = Instant::now();
        let target = ImageTarget::new(pic, WIDTH_M)?;
        t_new.push(t0.elapsed().as_secs_f64() * 1e3);
        for &tilt in &tilts {
            let (mut ce, mut re, mut tce, mut tre) =
                (Vec::new(), Vec::new(), Vec::new(), Vec::new());
            let (mut n, mut det, mut trk) = (0, 0, 0);
            for (i, &d) in dists.iter().enumerate() {
                for (j, &roll) in rolls.iter().enumerate() {
                    n += 1;
                    let ox = 0.08 * (i as f64 - 1.5) / 1.5;
                    let oy = 0.05 * (j as f64 - 1.0);
                    let truth = view_pose(d, tilt, roll, ox, oy);
                    let seed = (i * 10 + j) as u64 + (tilt as u64) * 100;
                    let frame = render_view(pic, WIDTH_M, &pin, &truth, 90, 0.7, 2.0, seed);
                    let (t0, c0) = (Instant::now(), cpu_s());
                    let obs = target.detect(&frame, &cam);
                    t_det.push(t0.elapsed().as_secs_f64() * 1e3);
                    cpu_det += cpu_s() - c0;
                    let Some(obs) = obs else { continue };
                    det += 1;
                    let pose = obs.estimate.best.pose;
                    let want = corners(&truth, &pin, target.height_m);
                    let got = target.corners_px(&cam, &pose).unwrap();
                    ce.extend(got.iter().zip(&want).map(|(a, b)| a.distance(*b)));
                    re.push(pose.rotation_angle_to(&truth).to_degrees());
                    // The next frame: moved a little; tracked from this frame's pose.
                    let truth2 = view_pose(d - 0.005, tilt + 0.5, roll + 1.0, ox, oy);
                    let frame2 = render_view(pic, WIDTH_M, &pin, &truth2, 90, 0.7, 2.0, seed + 7);
                    let (t0, c0) = (Instant::now(), cpu_s());
                    let obs2 = target.locate(&frame2, &cam, Some(&pose));
                    let dt = t0.elapsed().as_secs_f64() * 1e3;
                    let dc = cpu_s() - c0;
                    let Some(obs2) = obs2.filter(|o| o.tracked) else {
                        continue;
                    };
                    t_trk.push(dt);
                    cpu_trk += dc;
                    trk += 1;
                    let p2 = obs2.estimate.best.pose;
                    let want = corners(&truth2, &pin, target.height_m);
                    let got = target.corners_px(&cam, &p2).unwrap();
                    tce.extend(got.iter().zip(&want).map(|(a, b)| a.distance(*b)));
                    tre.push(p2.rotation_angle_to(&truth2).to_degrees());
                }
            }
            println!(
                "| {name} | {tilt} | {n} | {det} | {:.3} | {:.3} | {trk} | {:.3} | {:.3} |",
                median(ce.clone()),
                median(re.clone()),
                median(tce.clone()),
                median(tre.clone())
            );
            n_all += n;
            n_det += det;
            n_trk += trk;
            all_c.extend(ce);
            all_r.extend(re);
            all_tc.extend(tce);
            all_tr.extend(tre);
        }
    }
    println!(
        "| all | 0-60 | {n_all} | {n_det} | {:.3} | {:.3} | {n_trk} | {:.3} | {:.3} |",
        median(all_c),
        median(all_r),
        median(all_tc),
        median(all_tr)
    );
    println!();
    println!(
        "timing (1280x720, {} threads): picture preparation median {:.1} ms; first detection median {:.1} ms (p90 {:.1}); tracked frame median {:.2} ms (p90 {:.2})",
        rayon::current_num_threads(),
        median(t_new),
        median(t_det.clone()),
        {
            let mut v = t_det.clone();
            v.sort_by(f64::total_cmp);
            v[(v.len() * 9) / 10]
        },
        median(t_trk.clone()),
        {
            let mut v = t_trk.clone();
            v.sort_by(f64::total_cmp);
            v.get((v.len() * 9) / 10).copied().unwrap_or(f64::NAN)
        }
    );
    println!(
        "CPU time (all threads, /proc ticks of 10 ms summed over the calls): first detection mean {:.1} ms, tracked frame mean {:.2} ms",
        1e3 * cpu_det / t_det.len().max(1) as f64,
        1e3 * cpu_trk / t_trk.len().max(1) as f64
    );
    Ok(())
}
