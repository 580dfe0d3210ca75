//! Texture memory: the key prop's appearance per key-pose vertex, accumulated over every frame
//! in which the camera sees that vertex. The physical key prop always stands in its key pose,
//! so a key-pose vertex that passes the live look-up's tests ([`crate::live::live_lookup`]:
//! in the frame, facing the camera, not hidden in the visibility map) is a sample of its
//! colour under the set's light.
//!
//! **What is remembered is a gain over the model's albedo**, not the colour itself: each
//! sample is divided by the model's albedo at the vertex, read at the mip level of the frame
//! pixel's footprint on the surface ([`MemoryAlbedo`], [`FOOTPRINT_LOD_BIAS`]), and a
//! fallback pixel takes that gain times the model's albedo at the pixel. A vertex's gain
//! carries what the model's texture lacks at the scale of the mesh (the set's light as it
//! really falls there, and a paint the model does not have), while the texture keeps the
//! detail between vertices. Remembering the colours themselves (before stop 37) was a
//! blurred copy of the key prop: on the generated Wood scene, 480x270, it lowered the prop
//! PSNR from 29.56 to 28.29 dB, on Cycles' bust from 27.34 to 27.14; the gain gives 29.61 and
//! 27.52 (`pa-scene/examples/memory_rows.rs`, `propsalive eval --set`). With the model's
//! textures painted flat (their mean colour: a prop painted by hand), the memory lifts the
//! generated scene's prop from 22.17 to 24.82 dB, and to 26.44 after a scan.
//!
//! Each vertex keeps a running weighted mean and variance of its samples' gains (linear RGB).
//! A sample's weight is the product of
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
//! the gain times the vertex's confidence, and the confidence (the weight over
//! [`FULL_WEIGHT`], at most 1), interpolated like any attribute. A fallback pixel takes
//! `memory.rgb * albedo + (1 - memory.a) * lit fallback` ([`remembered_or`]): the remembered
//! gain on the model's albedo where it is known, blending into the model's lit texture where
//! it is not.

use glam::{Mat3, Mat4, Vec3};
use rayon::prelude::*;

use crate::live::{code, live_lookup, InvDepthMap, LiveParams};
use crate::texture::{CpuMipTexture, FrameSampler};

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
/// Mip levels above the one whose texel is a frame pixel at which a sample's albedo is read:
/// the frame's colour at a point spans more than a pixel (the sensor's pixel, then the
/// bilinear sample). Measured: 1.5 is best on both the generated scene (prop PSNR with the
/// memory 29.36 / 29.59 / 29.60 dB at 1 / 1.5 / 2, with a scan 29.68 / 29.85 / 29.73) and
/// Cycles' bust (27.48 / 27.52 / 27.39); on Cycles' CesiumMan 1.5 and 3 are best (24.05,
/// 24.04 against 23.57 at 0 and 23.90 at 20).
pub const FOOTPRINT_LOD_BIAS: f32 = 1.5;
/// Smallest albedo (linear) a sample's gain is taken over: near-black texels say little
/// about the light, and their gain multiplies a near-black albedo again.
pub const MIN_ALBEDO: f32 = 0.02;

/// The model's albedo at the key pose's vertices, which the samples are divided by: the
/// base-colour texture (None: white) times `factor`, at `uvs` (one per vertex; empty: all
/// (0, 0), as the render paths read them), at the mip level of each sample's footprint from
/// `texels_per_m` (one per vertex, [`texels_per_metre`]; empty or 0: level 0 plus the bias).
#[derive(Debug, Clone, Copy)]
pub struct MemoryAlbedo<'a> {
    pub texture: Option<&'a CpuMipTexture>,
    pub uvs: &'a [[f32; 2]],
    pub factor: [f32; 4],
    pub texels_per_m: &'a [f32],
}

impl MemoryAlbedo<'_> {
    /// A model without texture: the factor's colour everywhere.
    pub fn uniform(factor: [f32; 4]) -> MemoryAlbedo<'static> {
        MemoryAlbedo {
            texture: None,
            uvs: &[],
            factor,
            texels_per_m: &[],
        }
    }

    /// The albedo (linear RGB) at vertex `i` seen at `pixels_per_m` frame pixels per metre.
    fn at(&self, i: usize, pixels_per_m: f32) -> [f32; 3] {
        let texel = match self.texture {
            Some(t) => {
                let uv = self.uvs.get(i).copied().unwrap_or([0.0; 2]);
                let density = self.texels_per_m.get(i).copied().unwrap_or(0.0);
                let texels_per_px = density / pixels_per_m;
                let lod = if texels_per_px > 1.0 && texels_per_px.is_finite() {
                    texels_per_px.log2()
                } else {
                    0.0
                };
                t.sample(uv[0], uv[1], lod + FOOTPRINT_LOD_BIAS)
            }
            None => [1.0; 4],
        };
        std::array::from_fn(|c| texel[c] * self.factor[c])
    }
}

/// Texels of a `tex_size` texture per metre of surface at each vertex: the mean over the
/// triangle edges that meet there of the edge's length in texels over its length in
/// `positions` (0 where no edge has both lengths). Indices out of range are skipped.
pub fn texels_per_metre(
    positions: &[Vec3],
    uvs: &[[f32; 2]],
    indices: &[u32],
    tex_size: (u32, u32),
) -> Vec<f32> {
    let n = positions.len();
    if uvs.len() != n {
        return vec![0.0; n];
    }
    let (tw, th) = (tex_size.0 as f32, tex_size.1 as f32);
    let mut sum = vec![(0.0f32, 0u32); n];
    for t in indices.chunks_exact(3) {
        for k in 0..3 {
            let (a, b) = (t[k] as usize, t[(k + 1) % 3] as usize);
            if a >= n || b >= n {
                continue;
            }
            let (ua, ub) = (uvs[a], uvs[b]);
            let texels = ((ua[0] - ub[0]) * tw).hypot((ua[1] - ub[1]) * th);
            let metres = positions[a].distance(positions[b]);
            let d = texels / metres;
            if metres > 0.0 && d.is_finite() {
                for v in [a, b] {
                    sum[v].0 += d;
                    sum[v].1 += 1;
                }
            }
        }
    }
    sum.iter()
        .map(|&(s, k)| if k > 0 { s / k as f32 } else { 0.0 })
        .collect()
}

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

    /// Remembered gain over the model's albedo (linear RGB) of vertex `i` (None when never
    /// seen).
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

    /// Adds one sample of gain `rgb` with weight `w` to vertex `i`; returns whether
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
    /// `normals_world` the key pose (one per vertex of this memory), `albedo` the model's
    /// albedo there, `key_depth` the key pose's visibility map for this camera, `params` the
    /// look-up's settings (its visibility flag and tolerances are used; the stretch test is
    /// not: the key pose is the surface sampled).
    #[allow(clippy::too_many_arguments)]
    pub fn observe(
        &mut self,
        params: &LiveParams,
        key_depth: &(impl InvDepthMap + Sync),
        frame: &FrameSampler<'_>,
        camera_from_world: Mat4,
        positions_world: &[Vec3],
        normals_world: &[Vec3],
        albedo: &MemoryAlbedo<'_>,
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
        let sample = |i: usize, (&pw, &nw): (&Vec3, &Vec3)| -> Option<([f32; 3], f32)> {
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
            let pixels_per_m = cam.fx / pc.z;
            let resolution = pixels_per_m / 1000.0;
            let margin = if p.visibility {
                visibility_margin(key_depth, &p, pc)
            } else {
                1.0
            };
            let w = cos * resolution * margin;
            let rgb = frame.sample_linear(pixel[0], pixel[1], lut);
            let a = albedo.at(i, pixels_per_m);
            Some((std::array::from_fn(|c| rgb[c] / a[c].max(MIN_ALBEDO)), w))
        };
        // Vertices are independent: each one sampled and added in the same pass.
        self.weight
            .par_iter_mut()
            .zip(self.mean.par_iter_mut())
            .zip(self.m2.par_iter_mut())
            .zip(positions_world.par_iter().zip(normals_world.par_iter()))
            .enumerate()
            .with_min_len(1024)
            .map(
                |(i, (((weight, mean), m2), vertex))| match sample(i, vertex) {
                    Some((rgb, w)) => ObserveCounts {
                        sampled: 1,
                        outliers: usize::from(add_to((weight, mean, m2), rgb, w)),
                    },
                    None => ObserveCounts::default(),
                },
            )
            .reduce(ObserveCounts::default, |mut a, b| {
                a += b;
                a
            })
    }

    /// The vertex attribute both render paths read: the gain over the albedo times
    /// confidence, and the confidence, per vertex.
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
/// [`VertexMemory::premultiplied`] attribute (relit where the look relights), `albedo` the
/// model's albedo at the pixel and `lit` the lit fallback colour (linear).
#[inline]
pub fn remembered_or(memory: [f32; 4], albedo: [f32; 3], lit: [f32; 3]) -> [f32; 3] {
    let keep = (1.0 - memory[3]).clamp(0.0, 1.0);
    std::array::from_fn(|c| memory[c] * albedo[c] + keep * lit[c])
}

#[cfg(test)]
#[path = "memory_tests.rs"]
mod tests;
