//! The light a glossy key prop reflects where the camera sees it edge-on, measured on the key
//! frame, for `pa_raster::look`'s grazing reflection (`LiveParams::grazing_rgb`, the GPU
//! path's `LiveTexturing::grazing_rgb`).
//!
//! **Why.** A live sample carries the reflection of the key view. Where the in-between turns a
//! surface edge-on to the camera, a glossy prop (painted resin, plastic, Blender's Principled
//! BSDF) reflects more of its surroundings (Fresnel) than the key view showed, so the twin's
//! rim came out too dark: on the committed Cycles bust frames the 2nd to 6th pixel rings inside
//! the silhouette were 1-6 levels darker than the truth, more in blue and green (the sky's
//! colour), while on our Lambertian generated scene they were not.
//!
//! **Model.** At a visible key-prop vertex with albedo `a`, irradiance `E` (the fitted sun and
//! ambient with the vertex's own shadow; the pipeline measures nothing without the sun, since
//! against the first-order light alone our matte generated scene's rim gained up to 0.2) and facing cosine `c`, the frame shows `a E + S g(c)` with
//! `g(c) = (1 - c)^5` and `S = kappa A`, `A` the mean irradiance (the light's constant term).
//! Per vertex, `q = frame / (a E)` (channel mean) and `x = A g / (a E)`; without reflection `q`
//! does not depend on `c`.
//!
//! **Fit.** `kappa = 0` unless the median `q` of the rim band (facing cosine 0.2-0.3) exceeds
//! the middle band's (0.45-0.6) by [`MIN_RIM_GAIN`]; then the least-squares slope of
//! `q - q0` on `x` over the vertices with `g >= 0.02`, `q0` the median `q` of the vertices
//! facing the camera (cosine above 0.6), dropping those more than 60 % off `q0` (mixed
//! pixels, albedo mistakes), clamped to [0, [`MAX_KAPPA`]]. The rim band starts at 0.2 to stay
//! clear of the pixels the silhouette mixes with the background. Measured (per frame): rim
//! gain 0.13-0.14 on the Cycles bust (kappa 0.13-0.16) and -0.08 to 0.00 on the generated
//! scene (kappa 0); the best fixed kappa on the bust was about 0.2.
//!
//! A take's frames share one prop and one set: [`GrazingTrack`] smooths kappa over frames.

use glam::{Mat4, Vec3};
use pa_model::Model;
use pa_raster::look::schlick;

use crate::shading::{visible_vertices, KeyView};

/// Fewest vertices in each band (rim, middle, facing) for a fit.
const MIN_BAND_VERTICES: usize = 20;
/// Rim and middle bands of the facing cosine.
const RIM_BAND: (f32, f32) = (0.2, 0.3);
const MIDDLE_BAND: (f32, f32) = (0.45, 0.6);
/// Smallest facing cosine of a vertex used at all.
const MIN_FACING_COS: f64 = 0.12;
/// Rim median over middle median of `q` below which the prop counts as matte.
pub const MIN_RIM_GAIN: f32 = 0.06;
/// Largest kappa.
pub const MAX_KAPPA: f32 = 0.5;
/// Vertices visited per frame, at most about.
const MAX_VERTICES: usize = 6000;
/// Weight of the newest frame in [`GrazingTrack`].
const TRACK_WEIGHT: f32 = 0.5;

/// One vertex: `(g, q, x)` (module docs).
#[derive(Debug, Clone, Copy)]
struct Row {
    g: f32,
    q: f32,
    x: f32,
}

/// The visible key-prop vertices of one frame, gathered over its props.
#[derive(Debug, Default, Clone)]
pub struct GrazingSamples {
    rows: Vec<Row>,
}

impl GrazingSamples {
    /// Adds the visible vertices of one prop's posed key-pose primitives (as
    /// [`crate::shading::irradiance_samples_from`] takes them); `irradiance_at(primitive,
    /// vertex, normal_world)` is the fitted light there, `mean_irradiance` its constant term.
    pub fn add<'a>(
        &mut self,
        model: &Model,
        posed: impl Iterator<Item = (usize, usize, &'a [Vec3], &'a [Vec3])> + Clone,
        world_from_model: Mat4,
        view: &KeyView<'_>,
        mean_irradiance: [f32; 3],
        irradiance_at: impl Fn(usize, usize, Vec3) -> [f32; 3],
    ) {
        let each = |v: crate::shading::VisibleVertex| {
            let e = irradiance_at(v.primitive, v.vertex, v.normal_world);
            if e.iter().any(|&e| e.is_nan() || e < 0.02) {
                return None;
            }
            let g = schlick(v.facing_cos);
            let (mut q, mut x) = (0.0, 0.0);
            for c in 0..3 {
                let shaded = v.albedo[c] * e[c];
                q += v.frame_rgb[c] / shaded / 3.0;
                x += mean_irradiance[c] * g / shaded / 3.0;
            }
            (q.is_finite() && x.is_finite()).then_some(Row { g, q, x })
        };
        let rows = &mut self.rows;
        visible_vertices(
            model,
            posed,
            world_from_model,
            view,
            MAX_VERTICES,
            MIN_FACING_COS,
            |v| rows.extend(each(v)),
        );
    }

    /// Median `q` of the vertices whose facing cosine lies in `band`.
    fn band_median(&self, (lo, hi): (f32, f32)) -> Option<f32> {
        let (g_lo, g_hi) = (schlick(hi), schlick(lo));
        let mut q: Vec<f32> = self
            .rows
            .iter()
            .filter(|r| r.g >= g_lo && r.g < g_hi)
            .map(|r| r.q)
            .collect();
        median(&mut q)
    }

    /// How much brighter the rim band is than the middle band, relative (0 without data).
    pub fn rim_gain(&self) -> f32 {
        match (self.band_median(RIM_BAND), self.band_median(MIDDLE_BAND)) {
            (Some(rim), Some(middle)) => rim - middle,
            _ => 0.0,
        }
    }

    /// Kappa of this frame (module docs): 0 for a matte prop or too few vertices.
    pub fn kappa(&self) -> f32 {
        if self.rim_gain() < MIN_RIM_GAIN {
            return 0.0;
        }
        let mut facing: Vec<f32> = self
            .rows
            .iter()
            .filter(|r| r.g < schlick(MIDDLE_BAND.1))
            .map(|r| r.q)
            .collect();
        let Some(q0) = median(&mut facing) else {
            return 0.0;
        };
        let (mut sxy, mut sxx, mut n) = (0.0f64, 0.0f64, 0usize);
        for r in &self.rows {
            if r.g < 0.02 || (r.q - q0).abs() > 0.6 * q0 {
                continue;
            }
            sxy += f64::from(r.x) * f64::from(r.q - q0);
            sxx += f64::from(r.x) * f64::from(r.x);
            n += 1;
        }
        if n < MIN_BAND_VERTICES || sxx <= 0.0 {
            return 0.0;
        }
        ((sxy / sxx) as f32).clamp(0.0, MAX_KAPPA)
    }
}

/// The median of at least [`MIN_BAND_VERTICES`] values.
fn median(v: &mut [f32]) -> Option<f32> {
    if v.len() < MIN_BAND_VERTICES {
        return None;
    }
    v.sort_by(f32::total_cmp);
    Some(v[v.len() / 2])
}

/// Kappa smoothed over a take's frames.
#[derive(Debug, Default, Clone, Copy, PartialEq)]
pub struct GrazingTrack {
    kappa: Option<f32>,
}

impl GrazingTrack {
    /// Takes this frame's kappa and returns the smoothed one.
    pub fn update(&mut self, kappa: f32) -> f32 {
        let k = match self.kappa {
            Some(k) => k + TRACK_WEIGHT * (kappa - k),
            None => kappa,
        };
        self.kappa = Some(k);
        k
    }
}

/// The reflected light `S = kappa A` per channel.
pub fn grazing_rgb(kappa: f32, mean_irradiance: [f32; 3]) -> [f32; 3] {
    mean_irradiance.map(|a| kappa * a.max(0.0))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Vertices with facing cosines spread over [0.12, 1], albedo 0.25 under irradiance 0.8 and
    /// mean irradiance 0.6, with the frame showing `a E (1 + noise) + kappa A g(c)`.
    fn samples(kappa: f32, noise: f32) -> GrazingSamples {
        let mut seed = 0x2545_f491_u32;
        let mut unit = move || {
            seed ^= seed << 13;
            seed ^= seed >> 17;
            seed ^= seed << 5;
            seed as f32 / u32::MAX as f32
        };
        let (a, e, mean) = (0.25f32, 0.8f32, 0.6f32);
        let rows = (0..3000)
            .map(|_| {
                let cos = 0.12 + 0.88 * unit();
                let g = schlick(cos);
                let frame = a * e * (1.0 + noise * (unit() - 0.5)) + kappa * mean * g;
                Row {
                    g,
                    q: frame / (a * e),
                    x: mean * g / (a * e),
                }
            })
            .collect();
        GrazingSamples { rows }
    }

    #[test]
    fn a_matte_prop_reflects_nothing_even_with_noisy_albedo() {
        for noise in [0.0, 0.2, 0.5] {
            let s = samples(0.0, noise);
            assert!(
                s.rim_gain().abs() < MIN_RIM_GAIN,
                "noise {noise}: {}",
                s.rim_gain()
            );
            assert_eq!(s.kappa(), 0.0, "noise {noise}");
        }
    }

    #[test]
    fn a_glossy_prop_gives_back_its_kappa() {
        for kappa in [0.1f32, 0.2, 0.4] {
            let got = samples(kappa, 0.2).kappa();
            assert!((got - kappa).abs() < 0.03, "kappa {kappa}: fitted {got}");
        }
        // Too faint to tell from the albedo's noise: counted as matte (rim gain 0.016 here).
        assert_eq!(samples(0.02, 0.2).kappa(), 0.0);
        // Beyond the clamp.
        assert_eq!(samples(2.0, 0.0).kappa(), MAX_KAPPA);
    }

    #[test]
    fn too_few_vertices_give_no_reflection() {
        let mut s = samples(0.3, 0.0);
        s.rows.truncate(30);
        assert_eq!(s.kappa(), 0.0);
        assert_eq!(GrazingSamples::default().kappa(), 0.0);
    }

    #[test]
    fn the_track_starts_at_the_first_frame_and_moves_halfway() {
        let mut t = GrazingTrack::default();
        assert_eq!(t.update(0.2), 0.2);
        assert!((t.update(0.0) - 0.1).abs() < 1e-6);
        assert_eq!(grazing_rgb(0.5, [0.2, 0.4, -1.0]), [0.1, 0.2, 0.0]);
    }
}
