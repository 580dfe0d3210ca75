//! The alignment: a robust outline-to-edge cost over all views, a coarse grid over the table
//! translation, lift and yaw, then Levenberg-Marquardt (iteratively reweighted, Tukey's
//! biweight) from coarse to fine levels, the outline re-extracted between rounds.

use glam::{DMat4, DVec3};
use pa_camera::CameraModel;
use rayon::prelude::*;

use super::edges::EdgeLevel;
use super::silhouette::{outline, project, silhouette, OutlinePoint, TwinShape};
use super::PlacementParams;

/// One view ready to align: its camera, pose and edge pyramid (finest level first).
pub(crate) struct ViewData {
    pub camera: CameraModel,
    pub camera_from_marker: DMat4,
    pub levels: Vec<EdgeLevel>,
}

/// Finite-difference step of each parameter (mm, mm, mm, degrees, percent).
const STEP: f64 = 0.05;

/// Tukey's biweight loss with cut-off `tau`.
#[inline]
fn rho(d: f64, tau: f64) -> f64 {
    if d >= tau {
        tau * tau / 6.0
    } else {
        let u = 1.0 - (d / tau) * (d / tau);
        tau * tau / 6.0 * (1.0 - u * u * u)
    }
}

/// The outline points of every view at `theta` (level `level`).
pub(crate) fn outlines(
    shape: &TwinShape,
    views: &[ViewData],
    level: usize,
    theta: &PlacementParams,
) -> Vec<Vec<OutlinePoint>> {
    let marker_from_prop = theta.marker_from_prop();
    views
        .par_iter()
        .map(|v| {
            let lv = &v.levels[level];
            let projected = project(shape, &v.camera, v.camera_from_marker * marker_from_prop);
            let mask = silhouette(shape, &projected, lv);
            outline(shape, &projected, lv, &mask)
        })
        .collect()
}

/// The level pixel of a prop-space point.
#[inline]
fn pixel(v: &ViewData, lv: &EdgeLevel, camera_from_prop: &DMat4, p: DVec3) -> Option<(f64, f64)> {
    let c = camera_from_prop.transform_point3(p);
    let px = v.camera.pixel_from_camera(c)?;
    Some(lv.to_level((px.x, px.y)))
}

/// The mean robust cost over every outline point of every view.
pub(crate) fn cost(
    views: &[ViewData],
    points: &[Vec<OutlinePoint>],
    level: usize,
    theta: &PlacementParams,
    tau: f64,
) -> f64 {
    let marker_from_prop = theta.marker_from_prop();
    let (sum, n) = views
        .iter()
        .zip(points)
        .map(|(v, pts)| {
            let lv = &v.levels[level];
            let m = v.camera_from_marker * marker_from_prop;
            let s: f64 = pts
                .iter()
                .map(|p| {
                    pixel(v, lv, &m, p.prop)
                        .and_then(|(x, y)| lv.sample(p.bin, x, y))
                        .map_or(rho(tau, tau), |(d, _, _)| rho(d, tau))
                })
                .sum();
            (s, pts.len())
        })
        .fold((0.0, 0usize), |a, b| (a.0 + b.0, a.1 + b.1));
    if n == 0 {
        f64::INFINITY
    } else {
        sum / n as f64
    }
}

/// The normal equations at `theta`: `H = sum w J J^T`, `g = sum w d J` and the inlier count.
pub(crate) fn normal_equations(
    views: &[ViewData],
    points: &[Vec<OutlinePoint>],
    level: usize,
    theta: &PlacementParams,
    n_params: usize,
    tau: f64,
) -> ([[f64; 5]; 5], [f64; 5], usize) {
    let base = theta.marker_from_prop();
    let shifted: Vec<DMat4> = (0..n_params)
        .map(|k| {
            let mut d = [0.0; 5];
            d[k] = STEP;
            theta.with_delta(&d).marker_from_prop()
        })
        .collect();
    let parts: Vec<([[f64; 5]; 5], [f64; 5], usize)> = views
        .par_iter()
        .zip(points)
        .map(|(v, pts)| {
            let lv = &v.levels[level];
            let m0 = v.camera_from_marker * base;
            let mk: Vec<DMat4> = shifted.iter().map(|s| v.camera_from_marker * *s).collect();
            let mut h = [[0.0; 5]; 5];
            let mut g = [0.0; 5];
            let mut inliers = 0;
            for p in pts {
                let Some((x, y)) = pixel(v, lv, &m0, p.prop) else {
                    continue;
                };
                let Some((d, gx, gy)) = lv.sample(p.bin, x, y) else {
                    continue;
                };
                if d >= tau {
                    continue;
                }
                let mut j = [0.0; 5];
                let mut ok = true;
                for (k, m) in mk.iter().enumerate() {
                    match pixel(v, lv, m, p.prop) {
                        Some((xk, yk)) => j[k] = (gx * (xk - x) + gy * (yk - y)) / STEP,
                        None => ok = false,
                    }
                }
                if !ok {
                    continue;
                }
                let u = 1.0 - (d / tau) * (d / tau);
                let w = u * u;
                inliers += 1;
                for a in 0..n_params {
                    g[a] += w * d * j[a];
                    for b in 0..n_params {
                        h[a][b] += w * j[a] * j[b];
                    }
                }
            }
            (h, g, inliers)
        })
        .collect();
    let mut h = [[0.0; 5]; 5];
    let mut g = [0.0; 5];
    let mut n = 0;
    for (ph, pg, pn) in parts {
        for a in 0..5 {
            g[a] += pg[a];
            for b in 0..5 {
                h[a][b] += ph[a][b];
            }
        }
        n += pn;
    }
    (h, g, n)
}

/// Solves the symmetric positive system `a x = b` of size `n` (Cholesky); `None` when it is
/// not positive definite.
#[allow(clippy::needless_range_loop)]
pub(crate) fn solve_spd(a: &[[f64; 5]; 5], b: &[f64; 5], n: usize) -> Option<[f64; 5]> {
    let mut l = [[0.0; 5]; 5];
    for i in 0..n {
        for j in 0..=i {
            let mut s = a[i][j];
            for k in 0..j {
                s -= l[i][k] * l[j][k];
            }
            if i == j {
                if s <= 0.0 || !s.is_finite() {
                    return None;
                }
                l[i][i] = s.sqrt();
            } else {
                l[i][j] = s / l[j][j];
            }
        }
    }
    let mut y = [0.0; 5];
    for i in 0..n {
        let mut s = b[i];
        for k in 0..i {
            s -= l[i][k] * y[k];
        }
        y[i] = s / l[i][i];
    }
    let mut x = [0.0; 5];
    for i in (0..n).rev() {
        let mut s = y[i];
        for k in i + 1..n {
            s -= l[k][i] * x[k];
        }
        x[i] = s / l[i][i];
    }
    Some(x)
}

/// Levenberg-Marquardt from `theta` on fixed outline points; returns the new placement and
/// its cost.
pub(crate) fn refine(
    views: &[ViewData],
    points: &[Vec<OutlinePoint>],
    level: usize,
    theta: PlacementParams,
    n_params: usize,
    tau: f64,
    iterations: usize,
) -> (PlacementParams, f64) {
    let mut theta = theta;
    let mut current = cost(views, points, level, &theta, tau);
    let mut lambda = 1e-3;
    for _ in 0..iterations {
        let (h, g, n) = normal_equations(views, points, level, &theta, n_params, tau);
        if n < n_params {
            break;
        }
        let mut improved = false;
        let mut small = false;
        for _ in 0..6 {
            let mut a = h;
            for (i, row) in a.iter_mut().enumerate().take(n_params) {
                row[i] += lambda * h[i][i] + 1e-9;
            }
            let neg_g = g.map(|v| -v);
            let Some(delta) = solve_spd(&a, &neg_g, n_params) else {
                lambda *= 10.0;
                continue;
            };
            let candidate = theta.with_delta(&delta);
            let c = cost(views, points, level, &candidate, tau);
            if c < current {
                small = delta.iter().map(|d| d * d).sum::<f64>().sqrt() < 1e-3;
                theta = candidate;
                current = c;
                lambda = (lambda / 3.0).max(1e-7);
                improved = true;
                break;
            }
            lambda *= 4.0;
        }
        if !improved || small {
            break;
        }
    }
    (theta, current)
}

/// The best `keep` placements of a grid around `start` (table x/y and yaw in `steps` steps
/// each side, the lift in one step each side), by [`cost`] on fixed outline points.
#[allow(clippy::too_many_arguments)]
pub(crate) fn grid(
    views: &[ViewData],
    points: &[Vec<OutlinePoint>],
    level: usize,
    start: &PlacementParams,
    search_mm: f64,
    search_deg: f64,
    steps: i32,
    tau: f64,
    keep: usize,
) -> Vec<(PlacementParams, f64)> {
    let mut deltas = Vec::new();
    let s = steps as f64;
    for ix in -steps..=steps {
        for iy in -steps..=steps {
            for iz in -1..=1 {
                for iw in -steps..=steps {
                    deltas.push([
                        search_mm * ix as f64 / s,
                        search_mm * iy as f64 / s,
                        search_mm * 0.4 * iz as f64,
                        search_deg * iw as f64 / s,
                        0.0,
                    ]);
                }
            }
        }
    }
    let mut scored: Vec<(PlacementParams, f64)> = deltas
        .par_iter()
        .map(|d| {
            let t = start.with_delta(d);
            let c = cost(views, points, level, &t, tau);
            (t, c)
        })
        .collect();
    scored.sort_by(|a, b| a.1.total_cmp(&b.1));
    let mut best: Vec<(PlacementParams, f64)> = Vec::new();
    let apart = search_mm / s * 1.5;
    for (t, c) in scored {
        let far = best.iter().all(|(b, _)| {
            let d = DVec3::from(t.translation_m) - DVec3::from(b.translation_m);
            d.length() * 1e3 > apart || (t.yaw_deg - b.yaw_deg).abs() > search_deg / s * 1.5
        });
        if far {
            best.push((t, c));
            if best.len() == keep {
                break;
            }
        }
    }
    best
}
