//! The set's sun measured on the visible key prop, with the key prop's own cast shadows
//! ([`pa_raster::sun`]): the light the relighting and the fallback use when it fits.
//!
//! 1. The direction: the dominant direction of the first-order irradiance already fitted
//!    ([`crate::shading::Irradiance`]; for ambient plus one directional light its linear terms
//!    point at the light), refined by Gauss-Newton on the clamped cosine
//!    ([`refine_direction`]), then again with the key pose's own shadows along it
//!    ([`direction_on_key_pose`]).
//! 2. The key pose's shadow map along that direction says which sampled vertices the prop
//!    itself shadows.
//! 3. Per linear RGB channel, `ratio = ambient + direct * lit * max(n . l, 0)` by least
//!    squares over the samples, refitted without the 20 % largest residuals (speculars,
//!    misregistration, the occluding hand) ([`fit_sun`]).
//!
//! No sun (the first-order light stays in charge) when the samples do not separate lit from
//! unlit (a flat light, a prop seen only on its lit side), or the fit is not a light (a
//! negative direct or ambient term).

use glam::Vec3;
use pa_raster::sun::{ShadowMap, SunLight};

use crate::shading::{Irradiance, IrradianceSample, MIN_SAMPLES};

/// Smallest variance of the direct-light term `lit * max(n . l, 0)` over the samples: below
/// it the samples cannot tell the ambient from the direct light.
const MIN_DIRECT_VARIANCE: f64 = 0.01;
/// Smallest ratio of the directional terms' length to the constant (luma): a flatter light has
/// no direction worth shadowing.
const MIN_DIRECTIONALITY: f32 = 0.1;

/// Luma weights of linear RGB (Rec. 709).
const LUMA: [f32; 3] = [0.2126, 0.7152, 0.0722];

/// The unit direction towards the dominant light of a first-order irradiance (luma-weighted),
/// `None` when the light is nearly flat.
pub fn sun_direction(irradiance: &Irradiance) -> Option<Vec3> {
    let mut d = Vec3::ZERO;
    let mut constant = 0.0;
    for (r, w) in irradiance.rows.iter().zip(LUMA) {
        d += Vec3::new(r[1], r[2], r[3]) * w;
        constant += r[0] * w;
    }
    let len = d.length();
    (len.is_finite() && constant > 0.0 && len > MIN_DIRECTIONALITY * constant).then(|| d / len)
}

/// Starting from `start` (unit), the direction towards the light that best explains the
/// samples' luma as `ambient + direct * lit * max(n . l, 0)` (`lit[i]` per sample, missing:
/// 1): Gauss-Newton on ambient, direct and two angles of the direction, with samples whose
/// residual at the start exceeds 2.5 robust standard deviations left out (a specular, the
/// occluding hand, a cast shadow `lit` does not know). The first-order fit's direction is
/// pulled by the clamp (it is linear in the normal); this is not. Steps are limited to about
/// `max_step` radians; `start` comes back when the samples do not constrain a direction.
pub fn refine_direction(
    samples: &[IrradianceSample],
    lit: &[f32],
    start: Vec3,
    max_step: f32,
) -> Vec3 {
    let start = start.normalize_or_zero();
    let y: Vec<f64> = samples
        .iter()
        .map(|s| (0..3).map(|c| f64::from(s.ratio_rgb[c] * LUMA[c])).sum())
        .collect();
    let shade = |i: usize| f64::from(lit.get(i).copied().unwrap_or(1.0).clamp(0.0, 1.0));
    let x_at = |l: Vec3| -> Vec<f64> {
        samples
            .iter()
            .enumerate()
            .map(|(i, s)| shade(i) * f64::from(s.normal_world.dot(l).max(0.0)))
            .collect()
    };
    // Ambient and direct at the start by least squares, and the residuals' robust scale.
    let x = x_at(start);
    let Some((mut ambient, mut direct)) = line_fit(&x, &y, |_| true, 1e-9) else {
        return start;
    };
    let mut abs_r: Vec<f64> = x
        .iter()
        .zip(&y)
        .map(|(xi, yi)| (yi - ambient - direct * xi).abs())
        .collect();
    abs_r.sort_by(f64::total_cmp);
    let cut = 2.5 * 1.4826 * abs_r[abs_r.len() / 2].max(1e-6);
    let inliers: Vec<bool> = x
        .iter()
        .zip(&y)
        .map(|(xi, yi)| (yi - ambient - direct * xi).abs() <= cut)
        .collect();
    let mut l = start;
    for _ in 0..12 {
        let u = l.any_orthonormal_vector();
        let v = l.cross(u);
        // Normal equations of (ambient, direct, angle about u, angle about v).
        let mut jtj = glam::DMat4::ZERO;
        let mut jtr = glam::DVec4::ZERO;
        for (i, s) in samples.iter().enumerate() {
            if !inliers[i] {
                continue;
            }
            let cos = f64::from(s.normal_world.dot(l));
            let h = shade(i);
            let (xi, on) = if cos > 0.0 { (h * cos, h) } else { (0.0, 0.0) };
            let r = y[i] - ambient - direct * xi;
            let j = glam::DVec4::new(
                1.0,
                xi,
                direct * on * f64::from(s.normal_world.dot(u)),
                direct * on * f64::from(s.normal_world.dot(v)),
            );
            jtj += glam::DMat4::from_cols(j * j.x, j * j.y, j * j.z, j * j.w);
            jtr += j * r;
        }
        // A small damping keeps the angles put where the samples do not constrain them.
        let damp = 1e-6 * (jtj.x_axis.x + 1.0);
        jtj.x_axis.x += damp;
        jtj.y_axis.y += damp;
        jtj.z_axis.z += damp;
        jtj.w_axis.w += damp;
        if jtj.determinant().abs() < 1e-18 {
            break;
        }
        let d = jtj.inverse() * jtr;
        if !d.is_finite() {
            break;
        }
        let step = (d.z * d.z + d.w * d.w).sqrt() as f32;
        let scale = if step > max_step {
            max_step / step
        } else {
            1.0
        };
        ambient += d.x;
        direct = (direct + d.y).max(1e-3);
        l = (l + (u * d.z as f32 + v * d.w as f32) * scale).normalize();
        if step < 1e-3 {
            break;
        }
    }
    l
}

/// Slope-intercept least squares of `y` on `x` over the samples `keep(i)`: `(intercept,
/// slope)`, `None` with fewer than [`MIN_SAMPLES`] or with the variance of `x` at most
/// `min_variance`.
fn line_fit(
    x: &[f64],
    y: &[f64],
    keep: impl Fn(usize) -> bool,
    min_variance: f64,
) -> Option<(f64, f64)> {
    let (mut n, mut sx, mut sy, mut sxx, mut sxy) = (0.0f64, 0.0, 0.0, 0.0, 0.0);
    for (i, (&xi, &yi)) in x.iter().zip(y).enumerate() {
        if keep(i) {
            n += 1.0;
            sx += xi;
            sy += yi;
            sxx += xi * xi;
            sxy += xi * yi;
        }
    }
    let var = sxx / n - (sx / n).powi(2);
    if !(n >= MIN_SAMPLES as f64 && var > min_variance) {
        return None;
    }
    let slope = (sxy / n - sx / n * sy / n) / var;
    Some((sy / n - slope * sx / n, slope))
}

/// Fits ambient and direct light along `toward_light` to `samples`, `lit[i]` giving the
/// fraction of the light sample `i` receives (missing: 1).
pub fn fit_sun(samples: &[IrradianceSample], toward_light: Vec3, lit: &[f32]) -> Option<SunLight> {
    if samples.len() < MIN_SAMPLES {
        return None;
    }
    let x: Vec<f64> = samples
        .iter()
        .enumerate()
        .map(|(i, s)| {
            let shade = lit.get(i).copied().unwrap_or(1.0).clamp(0.0, 1.0);
            f64::from(shade * s.normal_world.dot(toward_light).max(0.0))
        })
        .collect();
    let all: Vec<usize> = (0..samples.len()).collect();
    let first = solve(samples, &x, &all)?;
    let mut residuals: Vec<(f64, usize)> = all
        .iter()
        .map(|&i| {
            let r: f64 = (0..3)
                .map(|c| {
                    (first.0[c] + first.1[c] * x[i] - f64::from(samples[i].ratio_rgb[c])).powi(2)
                })
                .sum();
            (r, i)
        })
        .collect();
    residuals.sort_by(|a, b| a.0.total_cmp(&b.0));
    let keep: Vec<usize> = residuals[..residuals.len() - residuals.len() / 5]
        .iter()
        .map(|&(_, i)| i)
        .collect();
    let (ambient, direct) = solve(samples, &x, &keep)?;
    let ok = (0..3).all(|c| ambient[c] > 0.0 && direct[c] > 0.0);
    ok.then(|| SunLight {
        toward_light,
        ambient_rgb: ambient.map(|a| a as f32),
        direct_rgb: direct.map(|d| d as f32),
    })
}

/// Per channel `(ambient, direct)` by least squares over the samples `keep`
/// ([`line_fit`]; `None` unless the direct term varies by more than [`MIN_DIRECT_VARIANCE`]
/// and every term is finite).
fn solve(samples: &[IrradianceSample], x: &[f64], keep: &[usize]) -> Option<([f64; 3], [f64; 3])> {
    let mut kept = vec![false; x.len()];
    for &i in keep {
        kept[i] = true;
    }
    let mut ambient = [0.0; 3];
    let mut direct = [0.0; 3];
    for c in 0..3 {
        let y: Vec<f64> = samples.iter().map(|s| f64::from(s.ratio_rgb[c])).collect();
        (ambient[c], direct[c]) = line_fit(x, &y, |i| kept[i], MIN_DIRECT_VARIANCE)?;
    }
    ambient
        .iter()
        .chain(&direct)
        .all(|v| v.is_finite())
        .then_some((ambient, direct))
}

/// The direction towards the sun, from the first-order light's direction `start`:
/// [`refine_direction`] without cast shadows, then again with the key pose's own shadows
/// along that direction (`key`: `(positions, indices)` per primitive, world frame).
pub fn direction_on_key_pose(
    samples: &[IrradianceSample],
    start: Vec3,
    key: &[(&[Vec3], &[u32])],
) -> Vec3 {
    let first = refine_direction(samples, &[], start, 0.3);
    refine_in_shadow(samples, first, &ShadowMap::new(first, key))
}

/// [`direction_on_key_pose`] with a shadow map of the key pose made earlier (along a
/// direction near the sun's, see `ar::sun::SunTrack`) instead of one along the frame's first
/// refinement.
pub fn direction_in_key_shadow(samples: &[IrradianceSample], start: Vec3, key: &ShadowMap) -> Vec3 {
    refine_in_shadow(samples, refine_direction(samples, &[], start, 0.3), key)
}

/// [`refine_direction`] from `first` with each sample's shadowing read from `map`.
fn refine_in_shadow(samples: &[IrradianceSample], first: Vec3, map: &ShadowMap) -> Vec3 {
    let lit: Vec<f32> = samples
        .iter()
        .map(|s| map.lit(s.position_world, s.normal_world))
        .collect();
    refine_direction(samples, &lit, first, 0.1)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Samples of a Lambertian surface under ambient plus a sun, some of them in a cast
    /// shadow: the fit recovers both terms, and the direction of the first-order fit points
    /// at the sun.
    #[test]
    fn fit_recovers_ambient_direct_and_direction() {
        let toward = Vec3::new(0.5, -0.6, 1.0).normalize();
        let (ambient, direct) = ([0.3f32, 0.32, 0.36], [0.9f32, 0.85, 0.8]);
        let mut samples = Vec::new();
        for i in 0..500 {
            let t = (i as f32 + 0.5) / 500.0;
            let z = -t;
            let r = (1.0 - z * z).sqrt();
            let a = i as f32 * 2.399_963;
            // A hemisphere facing -y (the camera there).
            let n = Vec3::new(r * a.cos(), z, r * a.sin());
            // Every third sample in a cast shadow: its position marks it.
            let shadowed = i % 3 == 0;
            let d = if shadowed {
                0.0
            } else {
                n.dot(toward).max(0.0)
            };
            samples.push(IrradianceSample {
                normal_world: n,
                position_world: Vec3::splat(if shadowed { 1.0 } else { 0.0 }),
                ratio_rgb: std::array::from_fn(|c| ambient[c] + direct[c] * d),
            });
        }
        let lit: Vec<f32> = samples.iter().map(|s| 1.0 - s.position_world.x).collect();
        let sun = fit_sun(&samples, toward, &lit).expect("fit");
        for c in 0..3 {
            assert!((sun.ambient_rgb[c] - ambient[c]).abs() < 1e-3, "{sun:?}");
            assert!((sun.direct_rgb[c] - direct[c]).abs() < 1e-3, "{sun:?}");
        }
        let unshadowed: Vec<_> = samples
            .iter()
            .filter(|s| s.position_world.x == 0.0)
            .copied()
            .collect();
        let e = Irradiance::fit(&unshadowed).expect("first order");
        let dir = sun_direction(&e).expect("direction");
        let deg = dir.dot(toward).clamp(-1.0, 1.0).acos().to_degrees();
        assert!(deg < 20.0, "{deg} degrees off");
        // The clamped cosine refined from there (the shadowed samples told by `lit`): within
        // a degree.
        let refined = refine_direction(&samples, &lit, dir, 0.3);
        let deg_refined = refined.dot(toward).clamp(-1.0, 1.0).acos().to_degrees();
        println!("first order {deg:.2} degrees off, refined {deg_refined:.3}");
        assert!(deg_refined < 1.0, "{deg_refined} degrees off");
    }

    #[test]
    fn non_finite_samples_give_no_sun_and_a_finite_direction() {
        let samples: Vec<_> = (0..100)
            .map(|i| IrradianceSample {
                normal_world: Vec3::new((i as f32).sin(), -1.0, (i as f32).cos()).normalize(),
                position_world: Vec3::ZERO,
                ratio_rgb: if i % 2 == 0 { [f32::NAN; 3] } else { [0.5; 3] },
            })
            .collect();
        let lit = vec![1.0; samples.len()];
        assert!(fit_sun(&samples, Vec3::Z, &lit).is_none());
        let l = refine_direction(&samples, &lit, Vec3::new(0.3, -0.4, 0.8).normalize(), 0.3);
        assert!(l.is_finite() && (l.length() - 1.0).abs() < 1e-4, "{l}");
    }

    #[test]
    fn flat_light_has_no_sun() {
        let samples: Vec<_> = (0..100)
            .map(|i| IrradianceSample {
                normal_world: Vec3::new((i as f32).sin(), -1.0, (i as f32).cos()).normalize(),
                position_world: Vec3::ZERO,
                ratio_rgb: [0.8; 3],
            })
            .collect();
        let e = Irradiance::fit(&samples).expect("fit");
        assert!(sun_direction(&e).is_none());
        // Every sample equally lit: nothing separates ambient from direct light.
        assert!(fit_sun(&samples, Vec3::Z, &[0.0; 100]).is_none());
        assert!(fit_sun(&samples[..MIN_SAMPLES - 1], Vec3::Z, &[]).is_none());
    }
}
