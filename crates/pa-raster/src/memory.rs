//! Texture memory: the key prop's appearance per key-pose vertex, accumulated over every frame
//! in which the camera sees that vertex. The physical key prop always stands in its key pose,
//! so a key-pose vertex that passes the live look-up's tests ([`crate::live::live_lookup`]:
//! in the frame, facing the camera, not hidden in the visibility map) is a sample of its
//! colour under the set's light. The memory keeps that colour (measured on the generated
//! scene, `pa-scene/tests/texture_memory.rs`, the fallback pixels of a head turned 38
//! degrees after a scan: remembered colours +0.65 dB over the lit model texture; remembered
//! albedos, the colour over the fitted light at the key-pose normal and lit again at the
//! in-between's, +0.23 dB; the seen light over the model's albedo -5.6 dB).
//!
//! Each vertex keeps a running weighted mean and variance of its samples (linear RGB). A
//! sample's weight is the product of
//!
//! - the viewing angle: the facing cosine between the key-pose normal and the ray;
//! - the resolution: pixels per millimetre of surface at that depth (`fx / z / 1000`);
//! - the visibility margin: the share of four taps [`MARGIN_PX`] pixels away in the
//!   visibility map that hold the same surface (a vertex at the key pose's silhouette or at
//!   the edge of an occluding part mixes in other colours).
//!
//! Once a vertex is established (weight at least [`ESTABLISHED_WEIGHT`]), a sample far from
//! its mean (squared distance over [`OUTLIER_SIGMAS`]² times its variance plus
//! [`MIN_SIGMA`]²) is down-weighted by [`OUTLIER_FACTOR`]: a hand or another occluder
//! crossing the prop changes few established means. The weight is capped at [`MAX_WEIGHT`]
//! (older samples then fade as in an exponential average, so a changed light is followed).
//!
//! Both render paths read the memory as one more vertex attribute ([`VertexMemory::premultiplied`]):
//! linear RGB times the vertex's confidence, and the confidence (the weight over
//! [`FULL_WEIGHT`], at most 1), interpolated like any attribute. A fallback pixel takes
//! `memory.rgb + (1 - memory.a) * lit fallback`: the remembered colour where it is
//! known, blending into the model's lit texture where it is not.

use glam::{Mat3, Mat4, Vec3};
use rayon::prelude::*;

use crate::live::{code, live_lookup, InvDepthMap, LiveParams};
use crate::texture::FrameSampler;

/// Weight at which a vertex's remembered colour is fully trusted (confidence 1): about one
/// frame seen face-on at 1 px/mm.
pub const FULL_WEIGHT: f32 = 1.0;
/// Weight after which samples far from the mean are down-weighted.
pub const ESTABLISHED_WEIGHT: f32 = 2.0;
/// Cap of a vertex's accumulated weight (about 30 good frames).
pub const MAX_WEIGHT: f32 = 30.0;
/// A sample further than this many standard deviations from the mean is an outlier.
pub const OUTLIER_SIGMAS: f32 = 3.0;
/// Floor of the per-channel standard deviation in the outlier test (linear light).
pub const MIN_SIGMA: f32 = 0.04;
/// Weight factor of an outlier.
pub const OUTLIER_FACTOR: f32 = 0.02;
/// Distance of the visibility-margin taps, pixels.
pub const MARGIN_PX: i32 = 3;
/// Smallest facing cosine of a sample (grazing views smear a vertex's neighbourhood).
pub const MIN_SAMPLE_COS: f32 = 0.2;

/// The memory of one mesh: one entry per vertex.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct VertexMemory {
    weight: Vec<f32>,
    mean: Vec<[f32; 3]>,
    /// Weighted sum of squared deviations, per channel.
    m2: Vec<[f32; 3]>,
}

/// What one [`VertexMemory::observe`] did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ObserveCounts {
    /// Vertices that got a sample.
    pub sampled: usize,
    /// Of those, samples down-weighted as outliers.
    pub outliers: usize,
}

impl std::ops::AddAssign for ObserveCounts {
    fn add_assign(&mut self, o: Self) {
        self.sampled += o.sampled;
        self.outliers += o.outliers;
    }
}

impl VertexMemory {
    /// An empty memory of `n` vertices.
    pub fn new(n: usize) -> Self {
        Self {
            weight: vec![0.0; n],
            mean: vec![[0.0; 3]; n],
            m2: vec![[0.0; 3]; n],
        }
    }

    /// Number of vertices.
    pub fn len(&self) -> usize {
        self.weight.len()
    }

    pub fn is_empty(&self) -> bool {
        self.weight.is_empty()
    }

    /// Accumulated weight of vertex `i` (0 when never seen).
    pub fn weight(&self, i: usize) -> f32 {
        self.weight.get(i).copied().unwrap_or(0.0)
    }

    /// Remembered linear RGB of vertex `i` (None when never seen).
    pub fn colour(&self, i: usize) -> Option<[f32; 3]> {
        (self.weight(i) > 0.0).then(|| self.mean[i])
    }

    /// Per-channel weighted variance of vertex `i`.
    pub fn variance(&self, i: usize) -> [f32; 3] {
        match self.m2.get(i) {
            Some(m2) => variance_of(self.weight(i), m2),
            None => [0.0; 3],
        }
    }

    /// Confidence of vertex `i` in [0, 1]: its weight over [`FULL_WEIGHT`].
    pub fn confidence(&self, i: usize) -> f32 {
        (self.weight(i) / FULL_WEIGHT).min(1.0)
    }

    /// Adds one sample of linear colour `rgb` with weight `w` to vertex `i`; returns whether
    /// it was taken as an outlier. Ignored when `i` is out of range or `w` is not positive.
    pub fn add_sample(&mut self, i: usize, rgb: [f32; 3], w: f32) -> bool {
        if i >= self.weight.len() {
            return false;
        }
        add_to(
            (&mut self.weight[i], &mut self.mean[i], &mut self.m2[i]),
            rgb,
            w,
        )
    }

    /// Samples every vertex the frame sees (see the module docs): `positions_world` and
    /// `normals_world` the key pose (one per vertex of this memory), `key_depth` the key
    /// pose's visibility map for this camera, `params` the look-up's settings (its
    /// visibility flag and tolerances are used; the stretch test is not: the key pose is the
    /// surface sampled).
    #[allow(clippy::too_many_arguments)]
    pub fn observe(
        &mut self,
        params: &LiveParams,
        key_depth: &(impl InvDepthMap + Sync),
        frame: &FrameSampler<'_>,
        camera_from_world: Mat4,
        positions_world: &[Vec3],
        normals_world: &[Vec3],
        lut: &[f32; 256],
    ) -> ObserveCounts {
        if positions_world.len() != self.len() || normals_world.len() != self.len() {
            return ObserveCounts::default();
        }
        let mut p = *params;
        p.max_stretch = 0.0;
        p.min_facing_cos = p.min_facing_cos.max(MIN_SAMPLE_COS);
        let rotation = Mat3::from_mat4(camera_from_world);
        let cam = p.frame_camera;
        // Each vertex's sample (the look-up and the frame: read-only, in parallel), then
        // added in vertex order.
        let sample = |(&pw, &nw): (&Vec3, &Vec3)| -> Option<([f32; 3], f32)> {
            let pc = camera_from_world.transform_point3(pw);
            let nc = rotation * nw;
            let (c, pixel) = live_lookup(&p, key_depth, pc, nc, pc, nc);
            if c != code::VALID {
                return None;
            }
            let cos = {
                let len2 = nc.dot(nc) * pc.dot(pc);
                if len2 > 0.0 {
                    -nc.dot(pc) / len2.sqrt()
                } else {
                    0.0
                }
            };
            let resolution = cam.fx / pc.z / 1000.0;
            let margin = if p.visibility {
                visibility_margin(key_depth, &p, pc)
            } else {
                1.0
            };
            let w = cos * resolution * margin;
            Some((frame.sample_linear(pixel[0], pixel[1], lut), w))
        };
        // Vertices are independent: each one sampled and added in the same pass.
        self.weight
            .par_iter_mut()
            .zip(self.mean.par_iter_mut())
            .zip(self.m2.par_iter_mut())
            .zip(positions_world.par_iter().zip(normals_world.par_iter()))
            .with_min_len(1024)
            .map(|(((weight, mean), m2), vertex)| match sample(vertex) {
                Some((rgb, w)) => ObserveCounts {
                    sampled: 1,
                    outliers: usize::from(add_to((weight, mean, m2), rgb, w)),
                },
                None => ObserveCounts::default(),
            })
            .reduce(ObserveCounts::default, |mut a, b| {
                a += b;
                a
            })
    }

    /// The vertex attribute both render paths read: linear RGB times confidence, and the
    /// confidence, per vertex.
    pub fn premultiplied(&self, out: &mut Vec<[f32; 4]>) {
        out.clear();
        out.extend((0..self.len()).map(|i| {
            let c = self.confidence(i);
            let m = self.mean[i];
            [m[0] * c, m[1] * c, m[2] * c, c]
        }));
    }
}

/// Per-channel weighted variance from a vertex's weight and sum of squared deviations (0
/// when never seen).
fn variance_of(weight: f32, m2: &[f32; 3]) -> [f32; 3] {
    if weight > 0.0 {
        m2.map(|m| m / weight)
    } else {
        [0.0; 3]
    }
}

/// [`VertexMemory::add_sample`] on one vertex's `(weight, mean, m2)`.
fn add_to(
    (weight, mean, m2): (&mut f32, &mut [f32; 3], &mut [f32; 3]),
    rgb: [f32; 3],
    w: f32,
) -> bool {
    if w.is_nan() || w <= 0.0 || rgb.iter().any(|c| !c.is_finite()) {
        return false;
    }
    let mut w = w;
    let mut outlier = false;
    let wi = *weight;
    if wi >= ESTABLISHED_WEIGHT {
        let var = variance_of(wi, m2);
        let d2: f32 = (0..3).map(|c| (rgb[c] - mean[c]).powi(2)).sum();
        let v: f32 = var.iter().map(|v| v + MIN_SIGMA * MIN_SIGMA).sum();
        if d2 > OUTLIER_SIGMAS * OUTLIER_SIGMAS * v {
            w *= OUTLIER_FACTOR;
            outlier = true;
        }
    }
    // Capped: scale the history down so that old samples fade.
    if wi + w > MAX_WEIGHT && wi > 0.0 {
        let s = ((MAX_WEIGHT - w).max(0.0) / wi).min(1.0);
        *weight *= s;
        for m in m2.iter_mut() {
            *m *= s;
        }
    }
    // West's weighted incremental mean and variance.
    let total = *weight + w;
    for ((x, m), s2) in rgb.iter().zip(mean.iter_mut()).zip(m2.iter_mut()) {
        let delta = x - *m;
        *m += delta * w / total;
        *s2 += w * delta * (x - *m);
    }
    *weight = total;
    outlier
}

/// Share (0.2 to 1) of the four taps [`MARGIN_PX`] away from `pc`'s pinhole pixel in the
/// visibility map that hold the same surface (within 5 % of its depth): 1 well inside the
/// key pose's surface, less at its silhouette or next to a nearer part.
fn visibility_margin(key_depth: &impl InvDepthMap, p: &LiveParams, pc: Vec3) -> f32 {
    let cam = &p.frame_camera;
    let q = [cam.fx * pc.x / pc.z + cam.cx, cam.fy * pc.y / pc.z + cam.cy];
    let (x, y) = (q[0].round() as i32, q[1].round() as i32);
    let taps = [
        (x - MARGIN_PX, y),
        (x + MARGIN_PX, y),
        (x, y - MARGIN_PX),
        (x, y + MARGIN_PX),
    ];
    let same = taps
        .iter()
        .filter(|&&(tx, ty)| {
            let iz = key_depth.inv_z_clamped(tx, ty);
            iz > 0.0 && (pc.z * iz - 1.0).abs() < 0.05
        })
        .count();
    (1 + same) as f32 / 5.0
}

/// Memory of the fallback in the shading of both paths: `memory` the interpolated
/// [`VertexMemory::premultiplied`] attribute, `lit` the lit fallback colour (linear).
#[inline]
pub fn remembered_or(memory: [f32; 4], lit: [f32; 3]) -> [f32; 3] {
    let keep = (1.0 - memory[3]).clamp(0.0, 1.0);
    std::array::from_fn(|c| memory[c] + keep * lit[c])
}

#[cfg(test)]
#[path = "memory_tests.rs"]
mod tests;
