//! The twin's colour per covered pixel (the fragment stage of [`CpuRenderer::render_twin`]):
//! the model's albedo, or the live frame's colour at the key-pose point with relighting, the
//! feathered blend with the lit fallback and the remembered colour, exactly as `live.wgsl`.
//! Each quantity is computed at most once per pixel, and only where the pixel's colour needs
//! it (the fallback's normal, sunlight fraction and remembered colour only where the live
//! sample is missing or partly trusted). The relighting ratio `E(n_anim) / E(n_key)` is
//! computed once per vertex ([`relight_at_vertices`]) and interpolated, as `live.wgsl`'s
//! vertex stage does; a triangle seen from its back (its normal flipped) computes it per
//! pixel.
//!
//! [`CpuRenderer::render_twin`]: crate::CpuRenderer::render_twin

use std::sync::atomic::Ordering;

use glam::Vec3;

use crate::live::{code, live_lookup_weighted};
use crate::live_lanes::{live_lookup_weighted4, LookupInputs};
use crate::look;
use crate::raster::{TriSetup, VisBuffer, NO_TRIANGLE};
use crate::renderer::{CpuLiveMesh, CpuPosedMesh, Shading, Tri, Vertex, LOD_UNSET};
use crate::srgb::Encoder;
use crate::texture::FrameSampler;
use crate::LiveParams;

/// Mip level of a triangle's albedo: log2 of the larger screen-space derivative of its
/// texel coordinates (the GPU's per-quad derivative, taken once per triangle).
fn triangle_lod(v: [Vertex; 3], tex_size: (u32, u32)) -> f32 {
    let (Some([x0, y0]), Some([x1, y1]), Some([x2, y2])) = (v[0].pixel, v[1].pixel, v[2].pixel)
    else {
        return 0.0;
    };
    let (p0, p1, p2) = ((x0, y0), (x1, y1), (x2, y2));
    let (tw, th) = (tex_size.0 as f64, tex_size.1 as f64);
    let t = v.map(|v| (v.uv[0] as f64 * tw, v.uv[1] as f64 * th));
    // [dt1 dt2] = J [dp1 dp2]  =>  J = [dt1 dt2] [dp1 dp2]^-1.
    let (a, b, c, d) = (p1.0 - p0.0, p2.0 - p0.0, p1.1 - p0.1, p2.1 - p0.1);
    let det = a * d - b * c;
    if det.abs() < 1e-9 {
        return 0.0;
    }
    let (ia, ib, ic, id) = (d / det, -b / det, -c / det, a / det);
    let (s1, s2) = (
        (t[1].0 - t[0].0, t[1].1 - t[0].1),
        (t[2].0 - t[0].0, t[2].1 - t[0].1),
    );
    // Columns of J: d(texel)/dx and d(texel)/dy.
    let jx = (s1.0 * ia + s2.0 * ic, s1.1 * ia + s2.1 * ic);
    let jy = (s1.0 * ib + s2.0 * id, s1.1 * ib + s2.1 * id);
    let rho = (jx.0 * jx.0 + jx.1 * jx.1)
        .max(jy.0 * jy.0 + jy.1 * jy.1)
        .sqrt();
    if rho > 1.0 && rho.is_finite() {
        fast_log2(rho as f32).max(0.0)
    } else {
        0.0
    }
}

/// log2 of a positive normal float within 0.0015 (exponent plus a cubic in the mantissa,
/// least-squares fit), without the library call: enough for a mip level.
fn fast_log2(x: f32) -> f32 {
    let bits = x.to_bits();
    let exponent = ((bits >> 23) & 0xff) as i32 - 127;
    let m = f32::from_bits((bits & 0x007f_ffff) | 0x3f80_0000) - 1.0;
    exponent as f32 + m * (1.423_485_3 + m * (-0.587_733_8 + m * 0.165_558_8))
}

/// The relighting ratio `E(n_anim) / E(n_key)` ([`SunLight::relight_factor`] with the
/// vertex's sunlight fractions, or [`look::relight_factor`] with the first-order light) at
/// each of `vertices`, into `out` (emptied when `shading` does not relight). `mesh_bases`
/// gives each mesh's first vertex, `meshes` their `sun_lit`. The ratio of the vertices'
/// unflipped normals: the one of a triangle's front side.
///
/// Per vertex, not per pixel: it costs 8k evaluations instead of one per covered pixel
/// (60-80k for the generated bust at 1280x720), and the interpolated ratio measured the same
/// (prop PSNR within 0.03 dB on the generated scene and Cycles' bust and CesiumMan).
///
/// [`SunLight::relight_factor`]: crate::sun::SunLight::relight_factor
pub(crate) fn relight_at_vertices(
    vertices: &[Vertex],
    mesh_bases: &[u32],
    meshes: &[CpuLiveMesh<'_>],
    shading: &Shading<'_>,
    out: &mut Vec<[f32; 3]>,
) {
    use rayon::prelude::*;
    out.clear();
    let params = match shading {
        Shading::Live { params, .. } if params.relight => params,
        _ => return,
    };
    out.par_extend(
        (0..vertices.len())
            .into_par_iter()
            .with_min_len(1024)
            .map(|i| {
                let v = &vertices[i];
                let n = v.anim_normal_world.normalize_or_zero();
                let nk = v.key_normal_world.normalize_or_zero();
                let lit = match params.sun {
                    Some(_) => {
                        // The mesh of vertex i: the last whose first vertex is at most i.
                        let m = mesh_bases
                            .partition_point(|&b| b as usize <= i)
                            .saturating_sub(1);
                        match (meshes.get(m), mesh_bases.get(m)) {
                            (Some(mesh), Some(&base)) => mesh
                                .sun_lit
                                .get(i - base as usize)
                                .copied()
                                .unwrap_or([1.0; 2]),
                            _ => [1.0; 2],
                        }
                    }
                    None => [1.0; 2],
                };
                relight_ratio(params, nk, n, lit)
            }),
    );
}

/// The relighting ratio `E(n_anim) / E(n_key)` of unit world-space normals (zero: none),
/// with the sunlight fractions `[key pose, in-between]` when `params` has a sun; the
/// first-order light's otherwise (`live.wgsl`'s `relight_ratio`).
#[inline]
fn relight_ratio(params: &LiveParams, n_key: Vec3, n_anim: Vec3, lit: [f32; 2]) -> [f32; 3] {
    match &params.sun {
        Some(sun) => sun.relight_factor(n_key, lit[0], n_anim, lit[1]),
        None => look::relight_factor(&params.fallback_irradiance, n_key, n_anim),
    }
}

/// `b0 a + b1 b + b2 c` per component: a per-vertex value at a pixel with barycentrics `b`.
#[inline(always)]
fn blend<const N: usize>([a, b, c]: [[f32; N]; 3], [b0, b1, b2]: [f32; 3]) -> [f32; N] {
    std::array::from_fn(|k| a[k] * b0 + b[k] * b1 + c[k] * b2)
}

/// What the fragment stage reads: the frame's set-ups, triangles and vertices.
pub(crate) struct ShadeContext<'a> {
    /// [`relight_at_vertices`] of `vertices` (empty: relit per pixel, or not at all).
    pub vertex_relight: &'a [[f32; 3]],
    pub setups: &'a [Option<TriSetup>],
    pub tris: &'a [Tri],
    pub vertices: &'a [Vertex],
    /// Index in `vertices` of each mesh's first vertex.
    pub mesh_bases: &'a [u32],
    pub meshes: &'a [CpuLiveMesh<'a>],
    pub shading: &'a Shading<'a>,
    pub key: &'a VisBuffer,
    pub lut: &'static [f32; 256],
    pub encoder: Encoder,
}

/// One covered pixel: its triangle, vertices and perspective-correct barycentrics.
struct Fragment<'a> {
    s: &'a TriSetup,
    t: &'a Tri,
    v: [&'a Vertex; 3],
    b: [f32; 3],
    mesh: &'a CpuPosedMesh<'a>,
}

impl Fragment<'_> {
    /// A per-vertex attribute interpolated at the pixel.
    #[inline(always)]
    fn lerp3(&self, f: impl Fn(&Vertex) -> Vec3) -> Vec3 {
        let ([va, vb, vc], [b0, b1, b2]) = (self.v, self.b);
        f(va) * b0 + f(vb) * b1 + f(vc) * b2
    }

    /// `N` interpolated scalars.
    #[inline(always)]
    fn lerp<const N: usize>(&self, f: impl Fn(&Vertex) -> [f32; N]) -> [f32; N] {
        blend(self.v.map(f), self.b)
    }

    /// The inputs of the live look-up: key-pose point and normal, animated point and normal.
    #[inline(always)]
    fn lookup_inputs(&self) -> [Vec3; 4] {
        [
            self.lerp3(|v| v.key_camera),
            self.lerp3(|v| v.key_normal_camera),
            self.lerp3(|v| v.anim_camera),
            self.lerp3(|v| v.anim_normal_camera),
        ]
    }
}

impl ShadeContext<'_> {
    #[inline(always)]
    fn fragment(&self, id: u32, x: u32, y: u32) -> Option<Fragment<'_>> {
        let s = self.setups[id as usize].as_ref()?;
        let t = &self.tris[id as usize];
        let v = t.v.map(|i| &self.vertices[i as usize]);
        Some(Fragment {
            s,
            t,
            v,
            b: s.hit(x as f32, y as f32).b,
            mesh: &self.meshes.get(t.mesh as usize)?.mesh,
        })
    }

    /// The model's colour (texture times factor), linear RGBA.
    #[inline]
    fn albedo(&self, f: &Fragment<'_>) -> [f32; 4] {
        let mesh = f.mesh;
        let texel = match mesh.albedo {
            Some(tex) => {
                let uv = f.lerp(|v| v.uv);
                let mut bits = f.t.lod_bits.load(Ordering::Relaxed);
                if bits == LOD_UNSET {
                    bits = triangle_lod(f.v.map(|v| *v), tex.size()).to_bits();
                    f.t.lod_bits.store(bits, Ordering::Relaxed);
                }
                tex.sample(uv[0], uv[1], f32::from_bits(bits))
            }
            None => [1.0; 4],
        };
        std::array::from_fn(|c| texel[c] * mesh.base_color_factor[c])
    }

    /// The fraction of the sun the fragment receives, `[key pose, animated pose]`, from its
    /// mesh's [`CpuLiveMesh::sun_lit`] (fully lit where missing).
    #[inline]
    fn sun_lit(&self, f: &Fragment<'_>) -> [f32; 2] {
        let m = f.t.mesh as usize;
        let (Some(mesh), Some(&base)) = (self.meshes.get(m), self.mesh_bases.get(m)) else {
            return [1.0; 2];
        };
        let at = |k: usize| {
            let i = f.t.v[k].wrapping_sub(base) as usize;
            mesh.sun_lit.get(i).copied().unwrap_or([1.0; 2])
        };
        blend([at(0), at(1), at(2)], f.b)
    }

    /// sRGB RGBA8 of a linear colour and alpha.
    #[inline(always)]
    fn encode(&self, rgb: [f32; 3], a: f32) -> [u8; 4] {
        let alpha = (a.clamp(0.0, 1.0) * 255.0 + 0.5) as u8;
        let e = &self.encoder;
        [e.encode(rgb[0]), e.encode(rgb[1]), e.encode(rgb[2]), alpha]
    }

    /// Colour (sRGB RGBA8) and code of the surface `id` at pixel `(x, y)`.
    #[inline]
    pub fn shade(&self, id: u32, x: u32, y: u32) -> (u8, [u8; 4]) {
        let Some(f) = self.fragment(id, x, y) else {
            return (code::NONE, [0; 4]);
        };
        match self.shading {
            Shading::Albedo => {
                let a = self.albedo(&f);
                (code::NONE, self.encode([a[0], a[1], a[2]], a[3]))
            }
            Shading::Live { frame, params } => self.live_alone(&f, frame, params),
        }
    }

    /// The code and sRGB RGBA8 of a live-textured fragment, looked up on its own.
    #[inline(always)]
    fn live_alone(
        &self,
        f: &Fragment<'_>,
        frame: &FrameSampler<'_>,
        params: &LiveParams,
    ) -> (u8, [u8; 4]) {
        let inputs = f.lookup_inputs();
        let [pc, nc, pa, na] = inputs;
        let looked = live_lookup_weighted(params, self.key, pc, nc, pa, na);
        self.live_pixel(f, frame, params, &inputs, looked)
    }

    /// The code and sRGB RGBA8 of a live-textured fragment given its look-up's inputs
    /// ([`Fragment::lookup_inputs`]) and result `(code, frame pixel, weight)`.
    #[inline(always)]
    fn live_pixel(
        &self,
        f: &Fragment<'_>,
        frame: &FrameSampler<'_>,
        params: &LiveParams,
        inputs: &LookupInputs,
        (code, pixel, weight): (u8, [f32; 2], f32),
    ) -> (u8, [u8; 4]) {
        let (rgb, a) = self.live_colour(f, frame, params, inputs, code, pixel, weight);
        (code, self.encode(rgb, a))
    }

    /// Shades the covered pixels of row `y` (`ids` the row's surface ids, columns `x0..=x1`)
    /// into the row's `rgba` and `codes`, exactly as [`ShadeContext::shade`] pixel by pixel.
    /// With [`Shading::Live`], four covered pixels at a time share one four-lane look-up
    /// ([`live_lookup_weighted4`]); the row's last one to three pixels are looked up alone.
    pub fn shade_row(
        &self,
        y: u32,
        (x0, x1): (u32, u32),
        ids: &[u32],
        rgba: &mut [u8],
        codes: &mut [u8],
    ) {
        let mut put = |x: u32, (c, px): (u8, [u8; 4])| {
            rgba[x as usize * 4..x as usize * 4 + 4].copy_from_slice(&px);
            codes[x as usize] = c;
        };
        let Shading::Live { frame, params } = self.shading else {
            for x in x0..=x1 {
                let id = ids[x as usize];
                if id != NO_TRIANGLE {
                    put(x, self.shade(id, x, y));
                }
            }
            return;
        };
        // Up to four fragments waiting for their look-up. (`None` is only the array's first
        // value: a full group holds four; this layout measured faster than an
        // `Option<(u32, Fragment)>` per slot.)
        let mut group: [(u32, Option<Fragment<'_>>); 4] =
            [(0, None), (0, None), (0, None), (0, None)];
        let mut n = 0;
        for x in x0..=x1 {
            let id = ids[x as usize];
            if id == NO_TRIANGLE {
                continue;
            }
            let Some(f) = self.fragment(id, x, y) else {
                put(x, (code::NONE, [0; 4]));
                continue;
            };
            group[n] = (x, Some(f));
            n += 1;
            if n < 4 {
                continue;
            }
            n = 0;
            let inputs: [LookupInputs; 4] = std::array::from_fn(|l| match &group[l].1 {
                Some(f) => f.lookup_inputs(),
                None => [Vec3::ZERO; 4],
            });
            let looked = live_lookup_weighted4(params, self.key, &inputs);
            for (((x, f), looked), inputs) in group.iter().zip(looked).zip(&inputs) {
                if let Some(f) = f {
                    put(*x, self.live_pixel(f, frame, params, inputs, looked));
                }
            }
        }
        for (x, f) in &group[..n] {
            if let Some(f) = f {
                put(*x, self.live_alone(f, frame, params));
            }
        }
    }

    /// The live-textured colour (linear) and alpha of a fragment given its look-up's inputs
    /// and result.
    #[inline(always)]
    fn live_colour(
        &self,
        f: &Fragment<'_>,
        frame: &FrameSampler<'_>,
        params: &LiveParams,
        inputs: &LookupInputs,
        code: u8,
        pixel: [f32; 2],
        weight: f32,
    ) -> ([f32; 3], f32) {
        let mesh = f.mesh;
        let opaque = mesh.base_color_factor[3] >= 1.0 && mesh.albedo.is_none_or(|t| t.is_opaque());
        let valid = code == code::VALID;
        // The fallback (lit model texture, or the remembered colour first) where the live
        // sample is missing or only partly trusted.
        let fallback = !valid || weight < 1.0;
        let memory: [f32; 4] = if fallback {
            f.lerp(|v| v.memory)
        } else {
            [0.0; 4]
        };
        // Relighting from the key pose's normal to the in-between's, for what was seen in the
        // key pose: the live sample, and the remembered colour.
        let relight = params.relight && (valid || memory[3] > 0.0);
        // The triangle's back side: its normal flipped, its ratio not the vertices'.
        let flipped = f.s.ccw_on_screen == mesh.mirrored;
        let ratio_at_vertices = !flipped && !self.vertex_relight.is_empty();
        // Each of these at most once per pixel.
        let (normal, lit) = if fallback || (relight && !ratio_at_vertices) {
            // Without vertex normals n is zero and the irradiance is its constant term.
            let n = f.lerp3(|v| v.anim_normal_world).normalize_or_zero();
            let n = if flipped { -n } else { n };
            let lit: [f32; 2] = match params.sun {
                Some(_) => self.sun_lit(f),
                None => [1.0; 2],
            };
            (n, lit)
        } else {
            (Vec3::ZERO, [1.0; 2])
        };
        let factor = if relight && ratio_at_vertices {
            blend(f.t.v.map(|i| self.vertex_relight[i as usize]), f.b)
        } else if relight {
            let nk = f.lerp3(|v| v.key_normal_world).normalize_or_zero();
            relight_ratio(params, nk, normal, lit)
        } else {
            [1.0; 3]
        };
        // The reflection at grazing angles, at the key pose and the in-between (look.rs).
        let grazing = params.relight && params.grazing_rgb != [0.0; 3];
        let (g_key, g_anim) = if grazing {
            let [pc, nc, pa, na] = *inputs;
            (look::grazing(pc, nc), look::grazing(pa, na))
        } else {
            (0.0, 0.0)
        };
        let s = params.grazing_rgb;
        let fallback_rgb = |a: &[f32; 4]| -> [f32; 3] {
            let e = match &params.sun {
                Some(sun) => sun.irradiance(normal, lit[1]),
                None => look::irradiance(&params.fallback_irradiance, normal),
            };
            let lit = std::array::from_fn(|c| a[c] * e[c]);
            let mut memory = memory;
            if params.relight && memory[3] > 0.0 {
                for c in 0..3 {
                    memory[c] *= factor[c];
                }
            }
            let rgb = crate::memory::remembered_or(memory, [a[0], a[1], a[2]], lit);
            if grazing {
                std::array::from_fn(|c| rgb[c] + s[c] * g_anim)
            } else {
                rgb
            }
        };
        if valid {
            let mut rgb = frame.sample_linear(pixel[0], pixel[1], self.lut);
            if grazing {
                rgb = std::array::from_fn(|c| {
                    (rgb[c] - s[c] * g_key).max(0.0) * factor[c] + s[c] * g_anim
                });
            } else if params.relight {
                rgb = std::array::from_fn(|c| rgb[c] * factor[c]);
            }
            if weight < 1.0 {
                let a = self.albedo(f);
                (look::blend(rgb, fallback_rgb(&a), weight), a[3])
            } else {
                // The albedo only for its alpha (the GPU writes albedo.a everywhere).
                let a = if opaque { 1.0 } else { self.albedo(f)[3] };
                (rgb, a)
            }
        } else {
            let a = self.albedo(f);
            (fallback_rgb(&a), a[3])
        }
    }
}

#[cfg(test)]
mod tests {
    use super::fast_log2;

    #[test]
    fn fast_log2_is_close() {
        let mut x = 1.0f32;
        while x < 1e6 {
            assert!((fast_log2(x) - x.log2()).abs() < 0.0015, "{x}");
            x *= 1.013;
        }
    }
}
