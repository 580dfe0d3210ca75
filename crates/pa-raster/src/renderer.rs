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

use std::sync::atomic::AtomicU32;

use glam::{Mat3, Mat4, Vec3};
use rayon::prelude::*;

use crate::live::{code, LiveParams};
use crate::raster::{PixelRect, RasterCamera, TriSetup, VisBuffer};
use crate::shade::ShadeContext;
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

    /// Number of pixels of each kind: (valid live samples, fallback samples). Rows in
    /// parallel, each counted without branches.
    pub fn counts(&self) -> (usize, usize) {
        let Some(r) = self.rect else {
            return (0, 0);
        };
        let w = self.width as usize;
        let rows = &self.codes[r.y0 as usize * w..(r.y1 as usize + 1) * w];
        let (x0, x1) = (r.x0 as usize, r.x1 as usize);
        rows.par_chunks(w)
            .map(|row| {
                row[x0..=x1].iter().fold((0, 0), |(valid, fallback), &c| {
                    (
                        valid + usize::from(c == code::VALID),
                        fallback + usize::from(c != code::VALID && c != code::NONE),
                    )
                })
            })
            .reduce(|| (0, 0), |a, b| (a.0 + b.0, a.1 + b.1))
    }
}

/// Per-vertex attributes of a frame, in the camera's coordinates (as the GPU's varyings).
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct Vertex {
    /// Pixel position of `anim_camera` for triangle set-up (None in front of the near plane).
    pub(crate) pixel: Option<[f64; 2]>,
    pub(crate) anim_camera: Vec3,
    pub(crate) anim_normal_camera: Vec3,
    pub(crate) anim_normal_world: Vec3,
    pub(crate) key_camera: Vec3,
    pub(crate) key_normal_camera: Vec3,
    /// The key-pose normal in the world (the relighting's frame).
    pub(crate) key_normal_world: Vec3,
    pub(crate) uv: [f32; 2],
    /// Texture memory (premultiplied linear RGB, confidence); zero without.
    pub(crate) memory: [f32; 4],
}

/// Per-triangle data beside its set-up.
#[derive(Debug)]
pub(crate) struct Tri {
    /// Global vertex indices.
    pub(crate) v: [u32; 3],
    pub(crate) mesh: u32,
    /// Mip level of the albedo (from the triangle's screen-space texel footprint), as f32
    /// bits; computed by the first pixel that needs it (`LOD_UNSET` until then).
    pub(crate) lod_bits: AtomicU32,
}

/// `Tri::lod_bits` before it is computed (a NaN no computation produces).
pub(crate) const LOD_UNSET: u32 = 0x7fc0_dead;

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
    /// Index in `vertices` of each twin mesh's first vertex.
    mesh_bases: Vec<u32>,
    /// Camera-space positions of the key pose and their pixels.
    camera_positions: Vec<(Vec3, Option<[f64; 2]>)>,
    /// The relighting ratio at each of `vertices` (empty without relighting;
    /// [`crate::shade::relight_at_vertices`]).
    vertex_relight: Vec<[f32; 3]>,
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
        let total: usize = meshes.iter().map(|m| m.indices.len() / 3).sum();
        // Every slot is written below: the list is only resized (not cleared) between frames.
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
    /// covered pixels ([`CpuRenderer::rasterise_twin_beside`], then
    /// [`CpuRenderer::shade_twin`]). With [`Shading::Live`] and `params.visibility`, the key
    /// depth of the last [`CpuRenderer::render_key_depth`] (same camera) is the visibility map.
    pub fn render_twin(
        &mut self,
        camera: &RasterCamera,
        camera_from_world: Mat4,
        meshes: &[CpuLiveMesh<'_>],
        shading: &Shading<'_>,
    ) -> &CpuTwinImage {
        let live = matches!(shading, Shading::Live { .. });
        self.rasterise_twin_beside(camera, camera_from_world, meshes, live, |_| ());
        self.shade_twin(meshes, shading)
    }

    /// The first half of [`CpuRenderer::render_twin`]: the animated twin's nearest surface
    /// per pixel (`live`: the meshes' key poses are read, as [`Shading::Live`] needs; their
    /// `sun_lit` is not). Meanwhile `beside` runs on the thread pool with the key depth of
    /// the last [`CpuRenderer::render_key_depth`] (work the rasterisation does not wait for,
    /// such as the set's light); its result is returned.
    pub fn rasterise_twin_beside<R: Send>(
        &mut self,
        camera: &RasterCamera,
        camera_from_world: Mat4,
        meshes: &[CpuLiveMesh<'_>],
        live: bool,
        beside: impl FnOnce(&VisBuffer) -> R + Send,
    ) -> R {
        let twin = TwinBuffers {
            twin: &mut self.twin,
            setups: &mut self.setups,
            tris: &mut self.tris,
            vertices: &mut self.vertices,
            mesh_bases: &mut self.mesh_bases,
            image: &mut self.image,
        };
        let key = &self.key;
        rayon::join(
            || beside(key),
            || twin.rasterise(camera, camera_from_world, meshes, live),
        )
        .0
    }

    /// The second half of [`CpuRenderer::render_twin`]: shades the covered pixels of the last
    /// [`CpuRenderer::rasterise_twin_beside`], whose `meshes` these must be, in the same order
    /// (now with their `sun_lit`; a triangle of a mesh missing here is left empty).
    pub fn shade_twin(
        &mut self,
        meshes: &[CpuLiveMesh<'_>],
        shading: &Shading<'_>,
    ) -> &CpuTwinImage {
        let Some(rect) = self.twin.dirty else {
            return &self.image;
        };
        self.image.rect = Some(rect);
        crate::shade::relight_at_vertices(
            &self.vertices,
            &self.mesh_bases,
            meshes,
            shading,
            &mut self.vertex_relight,
        );
        let ctx = ShadeContext {
            vertex_relight: &self.vertex_relight,
            setups: &self.setups,
            tris: &self.tris,
            vertices: &self.vertices,
            mesh_bases: &self.mesh_bases,
            meshes,
            shading,
            key: &self.key,
            lut: decode_lut(),
            encoder: Encoder::new(),
        };
        let wu = self.image.width as usize;
        let start = rect.y0 as usize * wu;
        let end = (rect.y1 as usize + 1) * wu;
        let ids = &self.twin.id[start..end];
        self.image.rgba8[start * 4..end * 4]
            .par_chunks_mut(wu * 4)
            .zip(self.image.codes[start..end].par_chunks_mut(wu))
            .zip(ids.par_chunks(wu))
            .enumerate()
            .for_each(|(k, ((rgba, codes), ids))| {
                ctx.shade_row(rect.y0 + k as u32, (rect.x0, rect.x1), ids, rgba, codes);
            });
        &self.image
    }
}

/// The animated twin's buffers, borrowed apart from the key depth.
struct TwinBuffers<'a> {
    twin: &'a mut VisBuffer,
    setups: &'a mut Vec<Option<TriSetup>>,
    tris: &'a mut Vec<Tri>,
    vertices: &'a mut Vec<Vertex>,
    mesh_bases: &'a mut Vec<u32>,
    image: &'a mut CpuTwinImage,
}

impl TwinBuffers<'_> {
    /// Vertices, triangle set-ups and the nearest surface per pixel.
    fn rasterise(
        self,
        camera: &RasterCamera,
        camera_from_world: Mat4,
        meshes: &[CpuLiveMesh<'_>],
        live: bool,
    ) {
        let (w, h) = (camera.width, camera.height);
        self.twin.reset(w, h);
        self.image.reset(w, h);
        let total: usize = meshes.iter().map(|m| m.mesh.indices.len() / 3).sum();
        // Every slot is written below: the lists are only resized (not cleared) between frames.
        self.setups.resize(total, None);
        self.tris.resize_with(total, Tri::default);
        self.vertices.clear();
        self.mesh_bases.clear();
        let mut offset = 0;
        let rotation = Mat3::from_mat4(camera_from_world);
        for (mi, m) in meshes.iter().enumerate() {
            let mesh = &m.mesh;
            let base = self.vertices.len() as u32;
            self.mesh_bases.push(base);
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
                }
            };
            self.vertices
                .par_extend((0..n).into_par_iter().with_min_len(1024).map(vertex));
            let vertices = &*self.vertices;
            let keep_ccw = mesh.keep_ccw();
            // Set-ups in parallel, one slot per triangle (ties in the depth test keep the
            // first triangle, as on the GPU).
            let set_up = |tri: &[u32], slot: &mut Option<TriSetup>, t: &mut Tri| {
                *slot = None;
                if tri.iter().any(|&i| i as usize >= n) {
                    return;
                }
                let v = [base + tri[0], base + tri[1], base + tri[2]];
                let [a, b, c] = v.map(|i| &vertices[i as usize]);
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
        self.twin.draw(camera, self.setups, 0);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 64x48 camera, f = 60 px, principal point `(cx, cy)`, and a triangle 1 m in front of
    /// it, 0.6 m wide.
    fn camera_and_triangle(cx: f64, cy: f64) -> (pa_camera::Intrinsics, RasterCamera, [Vec3; 3]) {
        let k = pa_camera::Intrinsics {
            fx: 60.0,
            fy: 60.0,
            cx,
            cy,
            width: 64,
            height: 48,
        };
        let positions = [
            Vec3::new(-0.3, -0.3, 1.0),
            Vec3::new(0.3, -0.3, 1.0),
            Vec3::new(0.0, 0.3, 1.0),
        ];
        (k, RasterCamera::new(&k, 0.01, 10.0), positions)
    }

    /// The two halves of `render_twin`: `beside` sees the key depth and its result comes
    /// back; shading the same meshes gives `render_twin`'s image, shading without them (a
    /// caller's mistake) leaves the twin empty instead of panicking.
    #[test]
    fn rasterise_beside_then_shade_equals_render_twin() {
        let (_, camera, positions) = camera_and_triangle(31.5, 23.5);
        let mesh = CpuPosedMesh {
            positions_world: &positions,
            normals_world: &[],
            uvs: &[],
            indices: &[0, 1, 2],
            albedo: None,
            base_color_factor: [0.5, 0.25, 1.0, 1.0],
            mirrored: false,
            cull_back_faces: false,
        };
        let meshes = [CpuLiveMesh {
            mesh,
            key_positions_world: &[],
            key_normals_world: &[],
            memory: &[],
            sun_lit: &[],
        }];
        let mut one = CpuRenderer::new();
        let whole = one
            .render_twin(&camera, Mat4::IDENTITY, &meshes, &Shading::Albedo)
            .clone();
        assert!(whole.rgba8.chunks(4).filter(|p| p[3] == 255).count() > 300);
        let mut two = CpuRenderer::new();
        let seen =
            two.rasterise_twin_beside(&camera, Mat4::IDENTITY, &meshes, false, |key| key.width);
        assert_eq!(seen, 0, "no key depth rendered yet");
        assert_eq!(two.shade_twin(&meshes, &Shading::Albedo).rgba8, whole.rgba8);
        let mut three = CpuRenderer::new();
        three.rasterise_twin_beside(&camera, Mat4::IDENTITY, &meshes, false, |_| ());
        let empty = three.shade_twin(&[], &Shading::Albedo);
        assert!(empty.rgba8.iter().all(|&v| v == 0));
    }

    /// The relighting ratio is the vertices' ratios interpolated on a triangle's front side
    /// (`relight_at_vertices`, as `live.wgsl`'s vertex stage) and computed per pixel from the
    /// flipped normal on its back side. One triangle facing the camera, its key normals
    /// toward the camera and its in-between normals tilted 64 degrees three ways, under a sun
    /// behind the camera: at the centroid the interpolated ratio is 0.61 where the ratio of
    /// the interpolated normal would be 0.88, and the back side gets the ambient's 0.3.
    #[test]
    fn relighting_ratio_is_the_vertices_on_the_front_and_per_pixel_on_the_back() {
        use crate::sun::SunLight;
        use crate::{FrameCamera, FrameSampler, LiveParams};
        // Pixels (14, 6), (50, 6), (32, 42): the centroid is pixel (32, 18).
        let (k, camera, positions) = camera_and_triangle(32.0, 24.0);
        let anim_normals = [
            Vec3::new(0.9, 0.0, -0.44),
            Vec3::new(-0.9, 0.0, -0.44),
            Vec3::new(0.0, 0.9, -0.44),
        ];
        let key_normals = [Vec3::NEG_Z; 3];
        let sun_lit = [[1.0f32; 2]; 3];
        let sun = SunLight {
            toward_light: Vec3::NEG_Z,
            ambient_rgb: [0.3; 3],
            direct_rgb: [0.7; 3],
        };
        let grey = vec![128u8; 64 * 48 * 4];
        let frame = FrameSampler::new(64, 48, &grey).expect("frame");
        let mut params = LiveParams::new(FrameCamera::new(&pa_camera::CameraModel::pinhole(k)));
        params.relight = true;
        params.sun = Some(sun);
        let shading = Shading::Live { frame, params };
        let centroid = |indices: &[u32; 3]| -> u8 {
            let mesh = CpuPosedMesh {
                positions_world: &positions,
                normals_world: &anim_normals,
                uvs: &[],
                indices,
                albedo: None,
                base_color_factor: [1.0; 4],
                mirrored: false,
                cull_back_faces: false,
            };
            let meshes = [CpuLiveMesh {
                mesh,
                key_positions_world: &positions,
                key_normals_world: &key_normals,
                memory: &[],
                sun_lit: &sun_lit,
            }];
            let mut r = CpuRenderer::new();
            let image = r.render_twin(&camera, Mat4::IDENTITY, &meshes, &shading);
            let i = 18 * 64 + 32;
            assert_eq!(image.codes[i], crate::live::code::VALID);
            image.rgba8[i * 4]
        };
        let grey_linear = crate::srgb::srgb_to_linear(128);
        let at_vertex = sun.relight_factor(Vec3::NEG_Z, 1.0, anim_normals[0].normalize(), 1.0)[0];
        let mean_normal = (anim_normals[0] + anim_normals[1] + anim_normals[2]).normalize();
        let per_pixel = sun.relight_factor(Vec3::NEG_Z, 1.0, mean_normal, 1.0)[0];
        let back = sun.relight_factor(Vec3::NEG_Z, 1.0, -mean_normal, 1.0)[0];
        assert!((at_vertex - 0.607).abs() < 0.01, "{at_vertex}");
        assert!((per_pixel - 0.878).abs() < 0.01, "{per_pixel}");
        assert!((back - 0.3).abs() < 1e-6, "{back}");
        let want = |ratio: f32| i32::from(crate::srgb::linear_to_srgb(grey_linear * ratio));
        // (0, 2, 1) winds counter-clockwise on screen: the front side faces the camera.
        let front = i32::from(centroid(&[0, 2, 1]));
        assert!(
            (front - want(at_vertex)).abs() <= 1,
            "{front} vs {}",
            want(at_vertex)
        );
        let back_side = i32::from(centroid(&[0, 1, 2]));
        assert!(
            (back_side - want(back)).abs() <= 1,
            "{back_side} vs {}",
            want(back)
        );
    }
}
