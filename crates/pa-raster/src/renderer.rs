//! [`CpuRenderer`]: the long-lived CPU renderer of the texture stage. It keeps its buffers
//! between frames (only the rectangle a frame touched is cleared for the next), takes per-frame
//! draw data ([`CpuPosedMesh`], [`CpuLiveMesh`]: posed vertices, already skinned on the CPU)
//! and produces, for the frame's camera:
//!
//! - the key pose's depth ([`CpuRenderer::render_key_depth`]): the visibility map of live
//!   texturing, the key-pose silhouette for diminishing, the depth for the light estimate;
//! - the animated twin ([`CpuRenderer::render_twin`]), shaded with the model's albedo (unlit)
//!   or textured from the live frame with the key-pose look-up and the lit fallback, exactly
//!   as `pa-render`'s `live.wgsl` does, plus each pixel's sample code and depth.
//!
//! Work is proportional to the triangles and the pixels they cover, not to the frame: a frame
//! of a small prop costs little at any resolution. Rasterisation and shading run in parallel
//! over bands of rows (rayon).

use std::sync::atomic::{AtomicU32, Ordering};

use glam::{Mat3, Mat4, Vec3};
use rayon::prelude::*;

use crate::live::{code, live_lookup_weighted, LiveParams};
use crate::look;
use crate::raster::{PixelRect, RasterCamera, TriSetup, VisBuffer, NO_TRIANGLE};
use crate::srgb::{decode_lut, Encoder};
use crate::texture::{CpuMipTexture, FrameSampler};

/// A triangle mesh posed in world space for one frame.
#[derive(Debug, Clone, Copy)]
pub struct CpuPosedMesh<'a> {
    /// World-space positions (morphed and skinned).
    pub positions_world: &'a [Vec3],
    /// World-space unit normals, one per position (empty: the triangle's own normal).
    pub normals_world: &'a [Vec3],
    /// Texture coordinates, one per position (empty: all (0, 0)).
    pub uvs: &'a [[f32; 2]],
    /// Triangle list.
    pub indices: &'a [u32],
    /// Base-colour texture (None: white).
    pub albedo: Option<&'a CpuMipTexture>,
    pub base_color_factor: [f32; 4],
    /// The mesh's transform mirrors (negative determinant, unskinned meshes only): the GPU's
    /// `flags.x`, which swaps which side of a triangle is its front for double-sided shading.
    pub mirrored: bool,
    /// Skip back faces: exact only for closed, outward meshes seen from outside
    /// ([`crate::mesh::closed_and_outward`]).
    pub cull_back_faces: bool,
}

impl CpuPosedMesh<'_> {
    /// The winding on screen of the faces to keep, when culling.
    fn keep_ccw(&self) -> Option<bool> {
        self.cull_back_faces.then_some(!self.mirrored)
    }
}

/// A mesh drawn for its depth only (the key pose's visibility map).
#[derive(Debug, Clone, Copy)]
pub struct CpuDepthMesh<'a> {
    pub positions_world: &'a [Vec3],
    pub indices: &'a [u32],
    pub mirrored: bool,
    pub cull_back_faces: bool,
}

/// An animated mesh with its key pose (same vertices, same order): the draw of live texturing.
#[derive(Debug, Clone, Copy)]
pub struct CpuLiveMesh<'a> {
    pub mesh: CpuPosedMesh<'a>,
    /// Key-pose world positions and normals, one per vertex of `mesh` (may be empty for
    /// [`Shading::Albedo`]).
    pub key_positions_world: &'a [Vec3],
    pub key_normals_world: &'a [Vec3],
    /// Texture memory, one [`crate::memory::VertexMemory::premultiplied`] entry per vertex
    /// (empty: none): a fallback pixel takes the remembered colour first.
    pub memory: &'a [[f32; 4]],
    /// The fraction of the sun each vertex receives, `[key pose, animated pose]`
    /// ([`crate::sun::ShadowMap::lit`]; empty: fully lit), read with
    /// [`LiveParams::sun`](crate::LiveParams::sun).
    pub sun_lit: &'a [[f32; 2]],
}

/// How the twin's pixels are coloured.
#[derive(Debug, Clone, Copy)]
pub enum Shading<'a> {
    /// The model's albedo (texture times factor), unlit.
    Albedo,
    /// Textured from the live frame (see [`crate::live`]), with the lit fallback.
    Live {
        frame: FrameSampler<'a>,
        params: LiveParams,
    },
}

/// The rendered twin: full-frame buffers of which only `rect` can be non-empty.
#[derive(Debug, Clone, Default)]
pub struct CpuTwinImage {
    pub width: u32,
    pub height: u32,
    /// sRGB RGBA8 (0 where empty).
    pub rgba8: Vec<u8>,
    /// [`code`] per pixel (`code::NONE` where empty or not live-textured).
    pub codes: Vec<u8>,
    /// Bounds of the pixels that may hold the twin.
    pub rect: Option<PixelRect>,
}

impl CpuTwinImage {
    fn reset(&mut self, width: u32, height: u32) {
        let n = width as usize * height as usize;
        if (self.width, self.height) != (width, height)
            || self.rgba8.len() != n * 4
            || self.codes.len() != n
        {
            *self = Self {
                width,
                height,
                rgba8: vec![0; n * 4],
                codes: vec![0; n],
                rect: None,
            };
            return;
        }
        if let Some(r) = self.rect.take() {
            let w = width as usize;
            for y in r.y0..=r.y1 {
                let (a, b) = (
                    y as usize * w + r.x0 as usize,
                    y as usize * w + r.x1 as usize + 1,
                );
                self.rgba8[a * 4..b * 4].fill(0);
                self.codes[a..b].fill(0);
            }
        }
    }

    /// Number of pixels of each kind: (valid live samples, fallback samples).
    pub fn counts(&self) -> (usize, usize) {
        let Some(r) = self.rect else {
            return (0, 0);
        };
        let (mut valid, mut fallback) = (0, 0);
        for y in r.y0..=r.y1 {
            let row = y as usize * self.width as usize;
            for &c in &self.codes[row + r.x0 as usize..=row + r.x1 as usize] {
                match c {
                    code::VALID => valid += 1,
                    code::NONE => {}
                    _ => fallback += 1,
                }
            }
        }
        (valid, fallback)
    }
}

/// Per-vertex attributes of a frame, in the camera's coordinates (as the GPU's varyings).
#[derive(Debug, Clone, Copy, Default)]
struct Vertex {
    /// Pixel position of `anim_camera` for triangle set-up (None in front of the near plane).
    pixel: Option<[f64; 2]>,
    anim_camera: Vec3,
    anim_normal_camera: Vec3,
    anim_normal_world: Vec3,
    key_camera: Vec3,
    key_normal_camera: Vec3,
    /// The key-pose normal in the world (the relighting's frame).
    key_normal_world: Vec3,
    uv: [f32; 2],
    /// Texture memory (premultiplied linear RGB, confidence); zero without.
    memory: [f32; 4],
    /// Fraction of the sun received, `[key pose, animated pose]`.
    sun_lit: [f32; 2],
}

/// Per-triangle data beside its set-up.
#[derive(Debug)]
struct Tri {
    /// Global vertex indices.
    v: [u32; 3],
    mesh: u32,
    /// Mip level of the albedo (from the triangle's screen-space texel footprint), as f32
    /// bits; computed by the first pixel that needs it (`LOD_UNSET` until then).
    lod_bits: AtomicU32,
}

/// `Tri::lod_bits` before it is computed (a NaN no computation produces).
const LOD_UNSET: u32 = 0x7fc0_dead;

impl Default for Tri {
    fn default() -> Self {
        Self {
            v: [0; 3],
            mesh: 0,
            lod_bits: AtomicU32::new(LOD_UNSET),
        }
    }
}

/// The CPU renderer of the texture stage; see the module docs.
#[derive(Default)]
pub struct CpuRenderer {
    key: VisBuffer,
    twin: VisBuffer,
    /// One slot per triangle (empty: culled or off-screen), filled in parallel by index.
    key_setups: Vec<Option<TriSetup>>,
    setups: Vec<Option<TriSetup>>,
    tris: Vec<Tri>,
    vertices: Vec<Vertex>,
    /// Camera-space positions of the key pose and their pixels.
    camera_positions: Vec<(Vec3, Option<[f64; 2]>)>,
    image: CpuTwinImage,
}

impl CpuRenderer {
    pub fn new() -> Self {
        Self::default()
    }

    /// Rasterises the key pose (positions in world space, triangle lists) into the key depth
    /// buffer, replacing what it held.
    pub fn render_key_depth(
        &mut self,
        camera: &RasterCamera,
        camera_from_world: Mat4,
        meshes: &[CpuDepthMesh<'_>],
    ) -> &VisBuffer {
        self.key.reset(camera.width, camera.height);
        self.key_setups.clear();
        let total: usize = meshes.iter().map(|m| m.indices.len() / 3).sum();
        self.key_setups.resize(total, None);
        let mut offset = 0;
        for m in meshes {
            self.camera_positions.clear();
            self.camera_positions
                .par_extend(m.positions_world.par_iter().with_min_len(1024).map(|p| {
                    let c = camera_from_world.transform_point3(*p);
                    (c, camera.project_for_setup(c))
                }));
            let positions = &self.camera_positions;
            let keep_ccw = m.cull_back_faces.then_some(!m.mirrored);
            let set_up = |tri: &[u32]| {
                let get = |i: u32| positions.get(i as usize).copied();
                let (a, b, c) = (get(tri[0])?, get(tri[1])?, get(tri[2])?);
                TriSetup::new_projected(camera, [a.0, b.0, c.0], [a.1, b.1, c.1], keep_ccw)
            };
            let count = m.indices.len() / 3;
            m.indices
                .par_chunks_exact(3)
                .zip(self.key_setups[offset..offset + count].par_iter_mut())
                .with_min_len(512)
                .for_each(|(tri, slot)| *slot = set_up(tri));
            offset += count;
        }
        self.key.draw(camera, &self.key_setups, 0);
        &self.key
    }

    /// The key-pose depth of the last [`CpuRenderer::render_key_depth`].
    pub fn key_depth(&self) -> &VisBuffer {
        &self.key
    }

    /// The twin's depth of the last [`CpuRenderer::render_twin`].
    pub fn twin_depth(&self) -> &VisBuffer {
        &self.twin
    }

    /// The last rendered twin.
    pub fn twin_image(&self) -> &CpuTwinImage {
        &self.image
    }

    /// Moves the last twin's colour buffer out (no copy); hand it back unchanged with
    /// [`CpuRenderer::restore_twin_rgba`] so the next frame reuses it (otherwise the next
    /// frame allocates a new one).
    pub fn take_twin_rgba(&mut self) -> Vec<u8> {
        std::mem::take(&mut self.image.rgba8)
    }

    /// Returns the buffer of [`CpuRenderer::take_twin_rgba`].
    pub fn restore_twin_rgba(&mut self, rgba8: Vec<u8>) {
        if rgba8.len() == self.image.width as usize * self.image.height as usize * 4 {
            self.image.rgba8 = rgba8;
        }
    }

    /// Renders the animated twin: nearest surface per pixel, then one shading pass over the
    /// covered pixels. With [`Shading::Live`] and `params.visibility`, the key depth of the
    /// last [`CpuRenderer::render_key_depth`] (same camera) is the visibility map.
    pub fn render_twin(
        &mut self,
        camera: &RasterCamera,
        camera_from_world: Mat4,
        meshes: &[CpuLiveMesh<'_>],
        shading: &Shading<'_>,
    ) -> &CpuTwinImage {
        let (w, h) = (camera.width, camera.height);
        self.twin.reset(w, h);
        self.image.reset(w, h);
        let total: usize = meshes.iter().map(|m| m.mesh.indices.len() / 3).sum();
        self.setups.clear();
        self.setups.resize(total, None);
        self.tris.resize_with(total, Tri::default);
        self.vertices.clear();
        let mut offset = 0;
        let rotation = Mat3::from_mat4(camera_from_world);
        let live = matches!(shading, Shading::Live { .. });
        for (mi, m) in meshes.iter().enumerate() {
            let mesh = &m.mesh;
            let base = self.vertices.len() as u32;
            let n = mesh.positions_world.len();
            let has_key = live && m.key_positions_world.len() == n;
            let vertex = |i: usize| {
                let p = mesh.positions_world[i];
                let nw = mesh.normals_world.get(i).copied().unwrap_or(Vec3::ZERO);
                let (kp, kn) = if has_key {
                    (
                        m.key_positions_world[i],
                        m.key_normals_world.get(i).copied().unwrap_or(Vec3::ZERO),
                    )
                } else {
                    (p, nw)
                };
                let anim_camera = camera_from_world.transform_point3(p);
                Vertex {
                    pixel: camera.project_for_setup(anim_camera),
                    anim_camera,
                    anim_normal_camera: rotation * nw,
                    anim_normal_world: nw,
                    key_camera: camera_from_world.transform_point3(kp),
                    key_normal_camera: rotation * kn,
                    key_normal_world: kn,
                    uv: mesh.uvs.get(i).copied().unwrap_or([0.0; 2]),
                    memory: m.memory.get(i).copied().unwrap_or([0.0; 4]),
                    sun_lit: m.sun_lit.get(i).copied().unwrap_or([1.0; 2]),
                }
            };
            self.vertices
                .par_extend((0..n).into_par_iter().with_min_len(1024).map(vertex));
            let vertices = &self.vertices;
            let keep_ccw = mesh.keep_ccw();
            // Set-ups in parallel, one slot per triangle (ties in the depth test keep the
            // first triangle, as on the GPU).
            let set_up = |tri: &[u32], slot: &mut Option<TriSetup>, t: &mut Tri| {
                *slot = None;
                if tri.iter().any(|&i| i as usize >= n) {
                    return;
                }
                let v = [base + tri[0], base + tri[1], base + tri[2]];
                let [a, b, c] = v.map(|i| vertices[i as usize]);
                *slot = TriSetup::new_projected(
                    camera,
                    [a.anim_camera, b.anim_camera, c.anim_camera],
                    [a.pixel, b.pixel, c.pixel],
                    keep_ccw,
                );
                t.v = v;
                t.mesh = mi as u32;
                *t.lod_bits.get_mut() = LOD_UNSET;
            };
            let count = mesh.indices.len() / 3;
            mesh.indices
                .par_chunks_exact(3)
                .zip(self.setups[offset..offset + count].par_iter_mut())
                .zip(self.tris[offset..offset + count].par_iter_mut())
                .with_min_len(512)
                .for_each(|((tri, slot), t)| set_up(tri, slot, t));
            offset += count;
        }
        self.twin.draw(camera, &self.setups, 0);
        let Some(rect) = self.twin.dirty else {
            return &self.image;
        };
        self.image.rect = Some(rect);
        let ctx = ShadeContext {
            setups: &self.setups,
            tris: &self.tris,
            vertices: &self.vertices,
            meshes,
            shading,
            key: &self.key,
            lut: decode_lut(),
            encoder: Encoder::new(),
        };
        let wu = w as usize;
        let start = rect.y0 as usize * wu;
        let end = (rect.y1 as usize + 1) * wu;
        let ids = &self.twin.id[start..end];
        self.image.rgba8[start * 4..end * 4]
            .par_chunks_mut(wu * 4)
            .zip(self.image.codes[start..end].par_chunks_mut(wu))
            .zip(ids.par_chunks(wu))
            .enumerate()
            .for_each(|(k, ((rgba, codes), ids))| {
                let y = rect.y0 + k as u32;
                for x in rect.x0..=rect.x1 {
                    let id = ids[x as usize];
                    if id == NO_TRIANGLE {
                        continue;
                    }
                    let (c, px) = ctx.shade(id, x, y);
                    rgba[x as usize * 4..x as usize * 4 + 4].copy_from_slice(&px);
                    codes[x as usize] = c;
                }
            });
        &self.image
    }
}

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

struct ShadeContext<'a> {
    setups: &'a [Option<TriSetup>],
    tris: &'a [Tri],
    vertices: &'a [Vertex],
    meshes: &'a [CpuLiveMesh<'a>],
    shading: &'a Shading<'a>,
    key: &'a VisBuffer,
    lut: &'static [f32; 256],
    encoder: Encoder,
}

impl ShadeContext<'_> {
    /// Colour (sRGB RGBA8) and code of the surface `id` at pixel `(x, y)`.
    #[inline]
    fn shade(&self, id: u32, x: u32, y: u32) -> (u8, [u8; 4]) {
        let Some(s) = &self.setups[id as usize] else {
            return (code::NONE, [0; 4]);
        };
        let t = &self.tris[id as usize];
        let hit = s.hit(x as f32, y as f32);
        let [b0, b1, b2] = hit.b;
        let [va, vb, vc] = t.v.map(|i| &self.vertices[i as usize]);
        let lerp3 = |f: fn(&Vertex) -> Vec3| f(va) * b0 + f(vb) * b1 + f(vc) * b2;
        let mesh = &self.meshes[t.mesh as usize].mesh;
        let uv = [
            va.uv[0] * b0 + vb.uv[0] * b1 + vc.uv[0] * b2,
            va.uv[1] * b0 + vb.uv[1] * b1 + vc.uv[1] * b2,
        ];
        let albedo = || -> [f32; 4] {
            let texel = match mesh.albedo {
                Some(tex) => {
                    let mut bits = t.lod_bits.load(Ordering::Relaxed);
                    if bits == LOD_UNSET {
                        bits = triangle_lod([*va, *vb, *vc], tex.size()).to_bits();
                        t.lod_bits.store(bits, Ordering::Relaxed);
                    }
                    tex.sample(uv[0], uv[1], f32::from_bits(bits))
                }
                None => [1.0; 4],
            };
            std::array::from_fn(|c| texel[c] * mesh.base_color_factor[c])
        };
        let opaque = mesh.base_color_factor[3] >= 1.0 && mesh.albedo.is_none_or(|t| t.is_opaque());
        let (code, rgb, a) = match self.shading {
            Shading::Albedo => {
                let a = albedo();
                (code::NONE, [a[0], a[1], a[2]], a[3])
            }
            Shading::Live { frame, params } => {
                let (code, pixel, weight) = live_lookup_weighted(
                    params,
                    self.key,
                    lerp3(|v| v.key_camera),
                    lerp3(|v| v.key_normal_camera),
                    lerp3(|v| v.anim_camera),
                    lerp3(|v| v.anim_normal_camera),
                );
                // Without vertex normals n is zero and the irradiance is its constant term.
                let normal = || {
                    let n = lerp3(|v| v.anim_normal_world).normalize_or_zero();
                    if s.ccw_on_screen == mesh.mirrored {
                        -n
                    } else {
                        n
                    }
                };
                // The remembered colour first, the lit model texture where the memory is unsure.
                let sun_lit = || -> [f32; 2] {
                    std::array::from_fn(|k| {
                        va.sun_lit[k] * b0 + vb.sun_lit[k] * b1 + vc.sun_lit[k] * b2
                    })
                };
                // Relighting from the key pose's normal to the in-between's, for what was seen
                // in the key pose: the live sample, and the remembered colour.
                let relight_factor = || -> [f32; 3] {
                    let nk = lerp3(|v| v.key_normal_world).normalize_or_zero();
                    match &params.sun {
                        Some(sun) => {
                            let lit = sun_lit();
                            sun.relight_factor(nk, lit[0], normal(), lit[1])
                        }
                        None => look::relight_factor(&params.fallback_irradiance, nk, normal()),
                    }
                };
                let fallback = |a: &[f32; 4]| -> [f32; 3] {
                    let e = match &params.sun {
                        Some(sun) => sun.irradiance(normal(), sun_lit()[1]),
                        None => look::irradiance(&params.fallback_irradiance, normal()),
                    };
                    let lit = std::array::from_fn(|c| a[c] * e[c]);
                    let mut memory: [f32; 4] = std::array::from_fn(|c| {
                        va.memory[c] * b0 + vb.memory[c] * b1 + vc.memory[c] * b2
                    });
                    if params.relight && memory[3] > 0.0 {
                        let f = relight_factor();
                        for c in 0..3 {
                            memory[c] *= f[c];
                        }
                    }
                    crate::memory::remembered_or(memory, lit)
                };
                if code == code::VALID {
                    let mut rgb = frame.sample_linear(pixel[0], pixel[1], self.lut);
                    if params.relight {
                        let f = relight_factor();
                        rgb = std::array::from_fn(|c| rgb[c] * f[c]);
                    }
                    if weight < 1.0 {
                        let a = albedo();
                        (code, look::blend(rgb, fallback(&a), weight), a[3])
                    } else {
                        // The albedo only for its alpha (the GPU writes albedo.a everywhere).
                        let a = if opaque { 1.0 } else { albedo()[3] };
                        (code, rgb, a)
                    }
                } else {
                    let a = albedo();
                    (code, fallback(&a), a[3])
                }
            }
        };
        let alpha = (a.clamp(0.0, 1.0) * 255.0 + 0.5) as u8;
        let e = &self.encoder;
        (
            code,
            [e.encode(rgb[0]), e.encode(rgb[1]), e.encode(rgb[2]), alpha],
        )
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
