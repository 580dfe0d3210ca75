//! How a live sample becomes the twin's colour: relighting and feathered seams. The same math
//! as `live.wgsl`'s `live_weight` and `relight_factor` (see `pa_render::live`).
//!
//! **Relighting.** The frame's colour `c` at a key-pose surface point with normal `n_k` is the
//! prop's albedo times the set's irradiance there, `c = a E(n_k)` (Lambertian). The in-between
//! turns that point to the normal `n_i`, where the same light gives `a E(n_i)`, so the twin
//! shows `c E(n_i) / E(n_k)`, the ratio clamped to [[`RELIGHT_MIN`], [`RELIGHT_MAX`]] per
//! channel. `E` is the light the pipeline estimates on the visible key prop
//! (`LiveParams::fallback_irradiance`, first-order spherical harmonics of a marker-frame
//! normal: the light is fixed to the set, so both normals are in the marker frame), each
//! channel floored at [`MIN_IRRADIANCE`] as for the fallback.
//!
//! **Feathered seams.** A live sample carries a weight in [0, 1] that is the product of one
//! smooth ramp per fallback test, each reaching 0 exactly where its test fails (so the blend
//! is continuous across the seam) and 1 a margin inside it:
//!
//! * frame edge: the distance `d` (pixels) from the sample to the frame's border,
//!   `ramp(d, EDGE_FEATHER_PX)`;
//! * facing: `ramp(cos_key - min_facing_cos, FACING_FEATHER_COS)`;
//! * stretch (when tested): with `L = max_stretch * max(cos_key, 0)`,
//!   `ramp(L - cos_anim, STRETCH_FEATHER * L)` (1 up to `1 - STRETCH_FEATHER` of the limit);
//! * visibility map (when tested): with the depth tolerance `t = rel + abs / z_map` and the
//!   margin `m = 1 + t - z / z_map`, `ramp(m, t)` (1 on the visible surface itself, 0 at the
//!   occlusion limit).
//!
//! `ramp(x, w) = s(clamp(x / w, 0, 1))` with `s(t) = t^2 (3 - 2 t)`; `w <= 0` gives a step
//! (`x > 0`); a product of at least [`FULL_WEIGHT_MIN`] counts as 1. The twin's colour is
//! `w live + (1 - w) fallback` (linear light).
//!
//! **Grazing reflection.** A glossy prop reflects its surroundings more where the camera sees
//! it edge-on (Fresnel): the frame's colour is `c = a E(n_k) + S g(cos_k)`, with Schlick's
//! factor `g(cos) = (1 - cos)^5` of the cosine between the normal and the direction to the
//! camera, and `S` the reflected light per channel (`LiveParams::grazing_rgb`, fitted on the
//! key frame by the pipeline; zero for a matte prop). The twin subtracts the key pose's
//! reflection before relighting and adds the in-between's: `max(c - S g_k, 0) E(n_i) / E(n_k)
//! + S g_i`, and its fallback gets `+ S g_i` too. Applied with relighting only.

use glam::Vec3;

/// Schlick's grazing factor `(1 - cos)^5` at a surface point `p` with normal `n`, both in the
/// camera frame (`cos` the facing cosine; 1 where either is zero).
#[inline]
pub fn grazing(p: Vec3, n: Vec3) -> f32 {
    let len2 = n.dot(n) * p.dot(p);
    schlick(if len2 > 0.0 {
        -n.dot(p) / len2.sqrt()
    } else {
        0.0
    })
}

/// Schlick's factor `(1 - cos)^5` of a facing cosine, clamped to [0, 1].
#[inline]
pub fn schlick(cos: f32) -> f32 {
    let t = 1.0 - cos.clamp(0.0, 1.0);
    let t2 = t * t;
    t2 * t2 * t
}

/// Smallest relighting ratio `E(n_i) / E(n_k)` per channel (measured on the generated scene,
/// frames 25-50 degrees from the key: 0.25, 0.5, 0.7, 0.85 and 1 gave 25.79, 26.00, 26.26,
/// 25.71 and 23.97 dB; the first-order fit overstates the darkening of a turned-away side).
pub const RELIGHT_MIN: f32 = 0.7;
/// Largest relighting ratio per channel.
pub const RELIGHT_MAX: f32 = 2.0;
/// Floor of the irradiance (linear) in the ratio and the fallback.
pub const MIN_IRRADIANCE: f32 = 0.02;
/// Width of the frame-edge ramp, pixels.
pub const EDGE_FEATHER_PX: f32 = 6.0;
/// Width of the facing ramp, in cosine.
pub const FACING_FEATHER_COS: f32 = 0.25;
/// Width of the stretch ramp, as a fraction of the limit (measured: 0.25, 0.5, 0.75 and 1
/// gave 27.05, 27.19, 27.13 and 26.88 dB over the generated scene's frames; 0.5 leaves the
/// frames near the key pose unchanged).
pub const STRETCH_FEATHER: f32 = 0.5;

/// A live sample's weight at or above this counts as 1: the blend would move its colour by at
/// most 1/512 of the live-fallback difference, and the fallback (a model-texture sample) is
/// not computed. On the visible surface the depth ramp sits just under 1 wherever the map's
/// depth and the surface's differ by rounding (measured: up to 40 % of a 720p twin's live
/// pixels in some frames).
pub const FULL_WEIGHT_MIN: f32 = 1.0 - 1.0 / 512.0;

/// Smooth ramp from 0 at `x <= 0` to 1 at `x >= width` (a step at 0 when `width <= 0`).
#[inline]
pub fn ramp(x: f32, width: f32) -> f32 {
    if width > 0.0 {
        let t = x / width;
        // (NaN gives 0.)
        if t > 0.0 {
            let t = t.min(1.0);
            t * t * (3.0 - 2.0 * t)
        } else {
            0.0
        }
    } else if x > 0.0 {
        1.0
    } else {
        0.0
    }
}

/// First-order spherical-harmonic irradiance `(constant, n.x, n.y, n.z)` per linear RGB
/// channel at `n`, floored at [`MIN_IRRADIANCE`].
#[inline]
pub fn irradiance(rows: &[[f32; 4]; 3], n: Vec3) -> [f32; 3] {
    std::array::from_fn(|c| {
        let r = rows[c];
        (r[0] + r[1] * n.x + r[2] * n.y + r[3] * n.z).max(MIN_IRRADIANCE)
    })
}

/// The relighting factor `E(n_anim) / E(n_key)` per channel, clamped to
/// [[`RELIGHT_MIN`], [`RELIGHT_MAX`]]. Normals unit length (or zero: the constant term).
#[inline]
pub fn relight_factor(rows: &[[f32; 4]; 3], n_key: Vec3, n_anim: Vec3) -> [f32; 3] {
    let (ek, ea) = (irradiance(rows, n_key), irradiance(rows, n_anim));
    std::array::from_fn(|c| (ea[c] / ek[c]).clamp(RELIGHT_MIN, RELIGHT_MAX))
}

/// `w a + (1 - w) b` per channel.
#[inline]
pub fn blend(a: [f32; 3], b: [f32; 3], w: f32) -> [f32; 3] {
    std::array::from_fn(|c| b[c] + w * (a[c] - b[c]))
}

#[cfg(test)]
mod tests;
