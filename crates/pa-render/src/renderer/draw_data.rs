//! The per-frame inputs of the [`Renderer`](super::Renderer) ([`CpuCamera`], [`Lighting`],
//! [`Draw`]) and its outputs ([`RenderedFrame`], [`SkinnedVertices`]).

use glam::Mat4;

use crate::mesh::GpuMesh;
use crate::texture::GpuTexture;

/// The camera of a frame: OpenCV pinhole intrinsics and pose.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CpuCamera {
    /// Intrinsics; when the render size differs from `intrinsics.width` x `height`, they are
    /// rescaled to the render size with [`pa_camera::Intrinsics::scaled_to`].
    pub intrinsics: pa_camera::Intrinsics,
    /// OpenCV camera axes (x right, y down, z forward), metres.
    pub camera_from_world: Mat4,
    /// Near clip distance along camera z, metres (> 0).
    pub near_m: f32,
    /// Far clip distance along camera z, metres (> near).
    pub far_m: f32,
}

/// A directional light (e.g. the sun, or a key light far away).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DirectionalLight {
    /// Direction from the surface toward the light, world space (normalised internally).
    pub toward_light_world: glam::Vec3,
    /// Linear RGB radiance scale.
    pub radiance_rgb: [f32; 3],
}

/// Lambertian lighting: colour = albedo * (ambient + max(0, n . l) * radiance).
/// Pass `None` to `render` for unlit output (colour = albedo exactly).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Lighting {
    /// Linear RGB ambient term.
    pub ambient_rgb: [f32; 3],
    /// Optional directional light.
    pub directional: Option<DirectionalLight>,
}

/// One mesh to draw in a frame.
///
/// Albedo = `base_color_factor` (linear RGBA) * texture sample (sRGB decoded), white when
/// there is no texture. Triangles are double-sided (no backface culling); lighting flips the
/// normal on the back side.
#[derive(Debug, Clone, Copy)]
pub struct Draw<'a> {
    pub mesh: &'a GpuMesh,
    pub texture: Option<&'a GpuTexture>,
    pub base_color_factor: [f32; 4],
    /// Used for rigid draws (empty `joint_matrices`) only: glTF ignores the transform of a
    /// skinned mesh's node.
    pub world_from_mesh: Mat4,
    /// `joint_matrices[j] = world_from_joint[j] * inverse_bind_matrix[j]`. Empty: rigid draw
    /// with `world_from_mesh` (for a skinned mesh this draws the bind pose). Non-empty: world
    /// position = `sum_i w_i * joint_matrices[j_i] * p`.
    pub joint_matrices: &'a [Mat4],
    /// Morph target weights, applied before skinning: p = base + sum_k w_k delta_k. Empty
    /// (all zero) or one per morph target.
    pub morph_weights: &'a [f32],
}

impl<'a> Draw<'a> {
    /// A rigid, untextured, white draw of `mesh` at `world_from_mesh`.
    pub fn new(mesh: &'a GpuMesh, world_from_mesh: Mat4) -> Self {
        Self {
            mesh,
            texture: None,
            base_color_factor: [1.0; 4],
            world_from_mesh,
            joint_matrices: &[],
            morph_weights: &[],
        }
    }
}

/// The result of [`Renderer::render`](super::Renderer::render).
#[derive(Debug, Clone, PartialEq)]
pub struct RenderedFrame {
    pub width: u32,
    pub height: u32,
    /// sRGB-encoded RGBA8, row-major from the top-left, no row padding.
    pub rgba8: Vec<u8>,
    /// Camera-space z (metres) of the nearest surface per pixel, `f32::INFINITY` where nothing
    /// was drawn. Same layout as `rgba8`, one value per pixel.
    pub depth_m: Vec<f32>,
}

impl RenderedFrame {
    /// RGBA of pixel (x, y), if inside.
    pub fn pixel(&self, x: u32, y: u32) -> Option<[u8; 4]> {
        if x >= self.width || y >= self.height {
            return None;
        }
        let i = (y as usize * self.width as usize + x as usize) * 4;
        let p = self.rgba8.get(i..i + 4)?;
        Some([p[0], p[1], p[2], p[3]])
    }

    /// Camera-space z of pixel (x, y), if inside.
    pub fn depth_at(&self, x: u32, y: u32) -> Option<f32> {
        if x >= self.width || y >= self.height {
            return None;
        }
        self.depth_m
            .get(y as usize * self.width as usize + x as usize)
            .copied()
    }
}

/// Skinned vertices read back by [`Renderer::skin_gpu`](super::Renderer::skin_gpu).
#[derive(Debug, Clone, PartialEq)]
pub struct SkinnedVertices {
    /// World positions (mesh positions after morphing, for a rigid call).
    pub positions: Vec<[f32; 3]>,
    /// Unit normals, transformed like the render pipeline does.
    pub normals: Vec<[f32; 3]>,
}
