//! The built-in prop: a rigged, textured, head-like bust (the paper's pirate head stands in
//! for it), written as a self-contained GLB so that it goes through the same loader as a
//! user's model.
//!
//! Geometry: a closed surface of revolution from the base centre (y = 0) to the crown, with a
//! pedestal, a neck, an egg-shaped head, a nose, brows, a chin and ears. Prop space is glTF
//! (right-handed, +Y up, metres); the face looks along +Z. About 8,000 vertices by default.
//!
//! Rig: `root` (pedestal) -> `neck` (turns about +Y) -> `head` (nods about +X) -> `jaw`
//! (opens about +X). The clip "Animate" runs 2 s: the head turns, nods and opens its jaw, so
//! in-betweens move away from the rest (key) pose by known angles.

use std::f32::consts::{PI, TAU};

use glam::{Mat4, Quat, Vec2, Vec3};
use serde_json::json;

use crate::SceneError;

/// Resolution and size of the generated prop.
#[derive(Debug, Clone, Copy)]
pub struct PropSpec {
    /// Rings from base to crown (latitude).
    pub rings: u32,
    /// Segments around the axis (longitude).
    pub segments: u32,
    /// Total height in metres.
    pub height_m: f32,
    /// Side of the square base-colour texture.
    pub texture_px: u32,
}

impl Default for PropSpec {
    /// About 8,000 vertices: 90 rings x 88 segments (+ seam column).
    fn default() -> Self {
        Self {
            rings: 90,
            segments: 88,
            height_m: 0.2,
            texture_px: 512,
        }
    }
}

impl PropSpec {
    /// A spec with roughly `vertices` vertices (for benchmarks: 2k, 8k, 32k, 128k).
    pub fn with_vertex_count(vertices: u32) -> Self {
        let side = ((vertices as f32).sqrt().round() as u32).max(8);
        Self {
            rings: side,
            segments: side.saturating_sub(2).max(8),
            ..Self::default()
        }
    }

    /// Vertex count of the generated mesh.
    pub fn vertex_count(&self) -> u32 {
        (self.rings + 1) * (self.segments + 1)
    }
}

/// Joint indices in the skin.
pub const JOINT_ROOT: usize = 0;
pub const JOINT_NECK: usize = 1;
pub const JOINT_HEAD: usize = 2;
pub const JOINT_JAW: usize = 3;

/// Rest positions of the joints in prop space (metres), as fractions of the height.
fn joint_rest(h: f32) -> [Vec3; 4] {
    [
        Vec3::ZERO,
        Vec3::new(0.0, 0.16 * h, 0.0),
        Vec3::new(0.0, 0.36 * h, 0.0),
        Vec3::new(0.0, 0.47 * h, 0.012 * h),
    ]
}

const PARENT: [Option<usize>; 4] = [None, Some(0), Some(1), Some(2)];

/// The clip's duration in seconds.
pub const CLIP_DURATION_S: f32 = 2.0;

/// Neck turn about +Y, head nod about +X and jaw opening about +X, in degrees, at `t_s`.
/// Smooth, with the rest pose at t = 0 and t = 2 s.
pub fn clip_angles_deg(t_s: f32) -> (f32, f32, f32) {
    let u = (t_s / CLIP_DURATION_S).clamp(0.0, 1.0);
    let turn = 40.0 * (PI * u).sin().powi(2);
    let nod = 18.0 * (TAU * u).sin().max(0.0).powi(2);
    let jaw = 22.0 * (PI * u).sin().powi(4);
    (turn, nod, jaw)
}

fn smoothstep(e0: f32, e1: f32, x: f32) -> f32 {
    let t = ((x - e0) / (e1 - e0)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

fn gauss(d: f32, sigma: f32) -> f32 {
    (-(d * d) / (2.0 * sigma * sigma)).exp()
}

/// Wrapped angle difference in (-pi, pi].
fn dphi(a: f32, b: f32) -> f32 {
    let mut d = (a - b) % TAU;
    if d > PI {
        d -= TAU;
    }
    if d <= -PI {
        d += TAU;
    }
    d
}

/// Radius of the surface at height fraction `t` (0 base, 1 crown) and azimuth `phi`
/// (0 = front, +Z), as a fraction of the height.
fn radius(t: f32, phi: f32) -> f32 {
    // Pedestal (0..0.08), neck (0.12..0.34), head (0.30..1.0).
    let pedestal = 0.24 * (1.0 - smoothstep(0.07, 0.11, t));
    let neck = 0.13;
    let hc = 0.64; // head centre
    let hr = 0.36; // head half-height
    let e = ((t - hc) / hr).clamp(-1.0, 1.0);
    let head = 0.27 * (1.0 - e * e).max(0.0).sqrt() * (1.0 + 0.12 * e.min(0.0));
    let mut r = pedestal.max(neck * smoothstep(0.0, 0.04, t)).max(head);
    // Close the crown and the base bottom.
    if t > 0.995 {
        r *= (1.0 - t) / 0.005;
    }
    let front = dphi(phi, 0.0);
    // Face features (front, +Z).
    let nose = 0.07 * gauss(front, 0.16) * gauss(t - 0.62, 0.045);
    let brow = 0.025 * gauss(front, 0.55) * gauss(t - 0.73, 0.03);
    let chin = 0.03 * gauss(front, 0.35) * gauss(t - 0.43, 0.04);
    let ears = 0.05
        * (gauss(dphi(phi, PI / 2.0), 0.12) + gauss(dphi(phi, -PI / 2.0), 0.12))
        * gauss(t - 0.62, 0.05);
    if t > 0.3 {
        r += nose + brow + chin + ears;
    }
    r
}

/// Surface point at grid (t, phi), in metres.
fn surface(t: f32, phi: f32, h: f32) -> Vec3 {
    let t = t.clamp(0.0, 1.0);
    let r = if t <= 0.0 { 0.0 } else { radius(t, phi) } * h;
    // The very bottom ring is the base centre; the base stays flat at y = 0.
    let y = if t < 0.02 { 0.0 } else { t * h };
    Vec3::new(r * phi.sin(), y, r * phi.cos())
}

/// Skin weights (root, neck, head, jaw) at a rest position.
fn weights_at(p: Vec3, t: f32, phi: f32) -> [f32; 4] {
    let to_neck = smoothstep(0.10, 0.20, t);
    let to_head = smoothstep(0.30, 0.42, t);
    let mut w = [1.0 - to_neck, to_neck * (1.0 - to_head), to_head, 0.0];
    // Jaw: the lower front of the head, below the mouth line.
    let front = dphi(phi, 0.0).abs();
    let jaw = (1.0 - smoothstep(0.47, 0.52, t))
        * smoothstep(0.36, 0.42, t)
        * (1.0 - smoothstep(0.9, 1.4, front))
        * smoothstep(-0.01, 0.02, p.z);
    w[3] = jaw * w[2];
    w[2] -= w[3];
    w
}

/// A generated prop, before packing.
#[derive(Debug, Clone)]
pub struct PropMesh {
    pub positions: Vec<Vec3>,
    pub normals: Vec<Vec3>,
    pub uvs: Vec<Vec2>,
    pub joints: Vec<[u8; 4]>,
    pub weights: Vec<[f32; 4]>,
    pub indices: Vec<u32>,
}

/// Generates the rest-pose mesh.
pub fn prop_mesh(spec: &PropSpec) -> PropMesh {
    let (nr, ns) = (spec.rings.max(4), spec.segments.max(4));
    let h = spec.height_m;
    let mut positions = Vec::new();
    let mut uvs = Vec::new();
    let mut joints = Vec::new();
    let mut weights = Vec::new();
    for i in 0..=nr {
        // i = 0 at the crown, nr at the base centre (v grows downwards, as image rows do).
        let t = 1.0 - i as f32 / nr as f32;
        for j in 0..=ns {
            let u = j as f32 / ns as f32;
            let phi = u * TAU;
            let p = surface(t, phi, h);
            positions.push(p);
            uvs.push(Vec2::new(u, i as f32 / nr as f32));
            joints.push([0, 1, 2, 3]);
            weights.push(weights_at(p, t, phi));
        }
    }
    let row = ns + 1;
    let mut indices = Vec::new();
    for i in 0..nr {
        for j in 0..ns {
            let a = i * row + j;
            let b = a + 1;
            let c = a + row;
            let d = c + 1;
            // Counter-clockwise seen from outside.
            indices.extend_from_slice(&[a, c, b, b, c, d]);
        }
    }
    let normals = smooth_normals(&positions, &indices);
    PropMesh {
        positions,
        normals,
        uvs,
        joints,
        weights,
        indices,
    }
}

/// Area-weighted vertex normals, shared across vertices at the same position (seams, poles).
fn smooth_normals(positions: &[Vec3], indices: &[u32]) -> Vec<Vec3> {
    use std::collections::HashMap;
    let mut canon: HashMap<[u32; 3], usize> = HashMap::new();
    let ids: Vec<usize> = positions
        .iter()
        .enumerate()
        .map(|(i, p)| *canon.entry(p.to_array().map(f32::to_bits)).or_insert(i))
        .collect();
    let mut acc = vec![Vec3::ZERO; positions.len()];
    for t in indices.chunks_exact(3) {
        let (a, b, c) = (t[0] as usize, t[1] as usize, t[2] as usize);
        let n = (positions[b] - positions[a]).cross(positions[c] - positions[a]);
        for v in [a, b, c] {
            acc[ids[v]] += n;
        }
    }
    (0..positions.len())
        .map(|i| {
            let n = acc[ids[i]];
            if n.length_squared() > 0.0 {
                n.normalize()
            } else {
                Vec3::Y
            }
        })
        .collect()
}

/// Deterministic hash noise in [0, 1).
fn hash2(x: i32, y: i32, seed: u32) -> f32 {
    let mut h = (x as u32)
        .wrapping_mul(0x8da6_b343)
        .wrapping_add((y as u32).wrapping_mul(0xd816_3841))
        .wrapping_add(seed.wrapping_mul(0xcb1a_b31f));
    h ^= h >> 13;
    h = h.wrapping_mul(0x5bd1_e995);
    h ^= h >> 15;
    (h & 0x00ff_ffff) as f32 / 16_777_216.0
}

/// Smooth value noise in [0, 1) (also paints the generated set).
pub(crate) fn value_noise(x: f32, y: f32, seed: u32) -> f32 {
    let (xi, yi) = (x.floor() as i32, y.floor() as i32);
    let (fx, fy) = (x - x.floor(), y - y.floor());
    let s = |v: f32| v * v * (3.0 - 2.0 * v);
    let (sx, sy) = (s(fx), s(fy));
    let a = hash2(xi, yi, seed);
    let b = hash2(xi + 1, yi, seed);
    let c = hash2(xi, yi + 1, seed);
    let d = hash2(xi + 1, yi + 1, seed);
    a + (b - a) * sx + (c - a) * sy + (a - b - c + d) * sx * sy
}

/// The painted base-colour texture (sRGB RGBA8), in the mesh's UV layout.
pub fn prop_texture(spec: &PropSpec) -> image::RgbaImage {
    let n = spec.texture_px.max(16);
    image::RgbaImage::from_fn(n, n, |x, y| {
        let u = (x as f32 + 0.5) / n as f32;
        let v = (y as f32 + 0.5) / n as f32;
        let t = 1.0 - v;
        let phi = u * TAU;
        let front = dphi(phi, 0.0);
        let grain =
            value_noise(u * 48.0, v * 48.0, 7) * 0.5 + value_noise(u * 12.0, v * 12.0, 3) * 0.5;
        // Plaster skin tone with painted grain.
        let mut c = Vec3::new(0.86, 0.68, 0.55) * (0.85 + 0.3 * grain);
        // Pedestal: dark painted wood with rings.
        if t < 0.11 {
            let ring = (0.5 + 0.5 * (t * 300.0).sin()) * 0.25;
            c = Vec3::new(0.35, 0.2, 0.1) * (0.8 + ring + 0.2 * grain);
        } else if t < 0.34 {
            // Neck scarf: stripes.
            let stripe = ((phi * 8.0 + t * 40.0).sin() > 0.0) as i32 as f32;
            c = Vec3::new(0.2, 0.3, 0.65).lerp(Vec3::new(0.9, 0.85, 0.7), stripe)
                * (0.9 + 0.2 * grain);
        } else if t > 0.78 {
            // Bandana: red with white dots.
            let dots = value_noise(u * 30.0, v * 30.0, 11);
            c = if dots > 0.72 {
                Vec3::new(0.95, 0.95, 0.9)
            } else {
                Vec3::new(0.75, 0.08, 0.06) * (0.85 + 0.3 * grain)
            };
        }
        // Eyes.
        for side in [-1.0f32, 1.0] {
            let d = Vec2::new(dphi(phi, side * 0.32) * 1.2, (t - 0.68) * 4.0).length();
            if d < 0.12 {
                c = Vec3::new(0.97, 0.97, 0.95);
            }
            if d < 0.06 {
                c = Vec3::new(0.1, 0.25, 0.15);
            }
            if d < 0.03 {
                c = Vec3::splat(0.03);
            }
        }
        // Moustache and mouth (the mouth line sits at the jaw hinge).
        if front.abs() < 0.45 && (t - 0.555).abs() < 0.012 {
            c = Vec3::new(0.25, 0.15, 0.08);
        }
        if front.abs() < 0.3 && (t - 0.49).abs() < 0.008 {
            c = Vec3::new(0.6, 0.1, 0.1);
        }
        let to8 = |x: f32| (x.clamp(0.0, 1.0) * 255.0 + 0.5) as u8;
        image::Rgba([to8(c.x), to8(c.y), to8(c.z), 255])
    })
}

/// Samples the clip into (time, neck rotation, head rotation, jaw rotation) keys at `fps`.
fn clip_keys(fps: f32) -> Vec<(f32, Quat, Quat, Quat)> {
    let frames = (CLIP_DURATION_S * fps).round() as u32;
    (0..=frames)
        .map(|f| {
            let t = f as f32 / fps;
            let (turn, nod, jaw) = clip_angles_deg(t);
            (
                t,
                Quat::from_rotation_y(turn.to_radians()),
                Quat::from_rotation_x(nod.to_radians()),
                Quat::from_rotation_x(jaw.to_radians()),
            )
        })
        .collect()
}

/// Builds the prop as GLB bytes (mesh, texture, skin, the clip "Animate" keyed at 24 fps).
pub fn prop_glb(spec: &PropSpec) -> Result<Vec<u8>, SceneError> {
    let mesh = prop_mesh(spec);
    let h = spec.height_m;
    let rest = joint_rest(h);
    let mut bin: Vec<u8> = Vec::new();
    let mut views = Vec::new();
    let mut accessors = Vec::new();
    let mut push = |bin: &mut Vec<u8>, data: Vec<u8>, target: Option<u32>| -> usize {
        while !bin.len().is_multiple_of(4) {
            bin.push(0);
        }
        let mut v = json!({"buffer": 0, "byteOffset": bin.len(), "byteLength": data.len()});
        if let Some(t) = target {
            v["target"] = json!(t);
        }
        views.push(v);
        bin.extend(data);
        views.len() - 1
    };
    let f32s =
        |xs: &mut dyn Iterator<Item = f32>| -> Vec<u8> { xs.flat_map(f32::to_le_bytes).collect() };

    let lo = mesh
        .positions
        .iter()
        .fold(Vec3::splat(f32::MAX), |a, b| a.min(*b));
    let hi = mesh
        .positions
        .iter()
        .fold(Vec3::splat(f32::MIN), |a, b| a.max(*b));
    let n = mesh.positions.len();
    let v = push(
        &mut bin,
        f32s(&mut mesh.positions.iter().flat_map(|p| p.to_array())),
        Some(34962),
    );
    accessors.push(
        json!({"bufferView": v, "componentType": 5126, "count": n, "type": "VEC3",
        "min": lo.to_array(), "max": hi.to_array()}),
    );
    let v = push(
        &mut bin,
        f32s(&mut mesh.normals.iter().flat_map(|p| p.to_array())),
        Some(34962),
    );
    accessors.push(json!({"bufferView": v, "componentType": 5126, "count": n, "type": "VEC3"}));
    let v = push(
        &mut bin,
        f32s(&mut mesh.uvs.iter().flat_map(|p| p.to_array())),
        Some(34962),
    );
    accessors.push(json!({"bufferView": v, "componentType": 5126, "count": n, "type": "VEC2"}));
    let v = push(
        &mut bin,
        mesh.joints.iter().flatten().copied().collect(),
        Some(34962),
    );
    accessors.push(json!({"bufferView": v, "componentType": 5121, "count": n, "type": "VEC4"}));
    let v = push(
        &mut bin,
        f32s(&mut mesh.weights.iter().flatten().copied()),
        Some(34962),
    );
    accessors.push(json!({"bufferView": v, "componentType": 5126, "count": n, "type": "VEC4"}));
    let v = push(
        &mut bin,
        mesh.indices.iter().flat_map(|i| i.to_le_bytes()).collect(),
        Some(34963),
    );
    accessors.push(
        json!({"bufferView": v, "componentType": 5125, "count": mesh.indices.len(),
        "type": "SCALAR"}),
    );
    // Inverse bind matrices: joints at their rest positions, no rotation.
    let ibm: Vec<f32> = rest
        .iter()
        .flat_map(|p| Mat4::from_translation(-*p).to_cols_array())
        .collect();
    let v = push(&mut bin, f32s(&mut ibm.into_iter()), None);
    accessors.push(json!({"bufferView": v, "componentType": 5126, "count": 4, "type": "MAT4"}));
    // Texture.
    let tex = prop_texture(spec);
    let mut png = Vec::new();
    image::DynamicImage::ImageRgba8(tex)
        .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)?;
    let image_view = push(&mut bin, png, None);
    // Animation keys.
    let keys = clip_keys(24.0);
    let v = push(&mut bin, f32s(&mut keys.iter().map(|k| k.0)), None);
    accessors.push(
        json!({"bufferView": v, "componentType": 5126, "count": keys.len(),
        "type": "SCALAR", "min": [0.0], "max": [CLIP_DURATION_S]}),
    );
    let times_acc = accessors.len() - 1;
    let mut samplers = Vec::new();
    let mut channels = Vec::new();
    for (joint, pick) in [(JOINT_NECK, 1usize), (JOINT_HEAD, 2), (JOINT_JAW, 3)] {
        let vals = f32s(&mut keys.iter().flat_map(|k| {
            let q = match pick {
                1 => k.1,
                2 => k.2,
                _ => k.3,
            };
            q.to_array()
        }));
        let v = push(&mut bin, vals, None);
        accessors.push(
            json!({"bufferView": v, "componentType": 5126, "count": keys.len(),
            "type": "VEC4"}),
        );
        samplers.push(json!({"input": times_acc, "output": accessors.len() - 1,
            "interpolation": "LINEAR"}));
        // Joint j is node j + 1 (node 0 is the mesh node).
        channels.push(json!({"sampler": samplers.len() - 1,
            "target": {"node": joint + 1, "path": "rotation"}}));
    }
    // Nodes: 0 mesh (skinned), 1..=4 joints, 5 the prop root.
    let mut nodes = vec![json!({"name": "PropMesh", "mesh": 0, "skin": 0})];
    let names = ["root", "neck", "head", "jaw"];
    for j in 0..4 {
        let local = match PARENT[j] {
            Some(p) => rest[j] - rest[p],
            None => rest[j],
        };
        let children: Vec<usize> = (0..4)
            .filter(|&c| PARENT[c] == Some(j))
            .map(|c| c + 1)
            .collect();
        let mut node = json!({"name": names[j], "translation": local.to_array()});
        if !children.is_empty() {
            node["children"] = json!(children);
        }
        nodes.push(node);
    }
    nodes.push(json!({"name": "Prop", "children": [0, 1]}));
    let doc = json!({
        "asset": {"version": "2.0", "generator": "Props Alive built-in prop"},
        "scene": 0,
        "scenes": [{"nodes": [5]}],
        "nodes": nodes,
        "meshes": [{"name": "Bust", "primitives": [{"attributes": {"POSITION": 0, "NORMAL": 1,
            "TEXCOORD_0": 2, "JOINTS_0": 3, "WEIGHTS_0": 4}, "indices": 5, "material": 0}]}],
        "materials": [{"name": "PaintedPlaster", "pbrMetallicRoughness": {"baseColorTexture":
            {"index": 0}, "metallicFactor": 0.0, "roughnessFactor": 0.9}}],
        "textures": [{"source": 0, "sampler": 0}],
        "samplers": [{"magFilter": 9729, "minFilter": 9987, "wrapS": 10497, "wrapT": 33071}],
        "images": [{"bufferView": image_view, "mimeType": "image/png"}],
        "skins": [{"name": "Rig", "joints": [1, 2, 3, 4], "inverseBindMatrices": 6}],
        "animations": [{"name": "Animate", "channels": channels, "samplers": samplers}],
        "accessors": accessors,
        "bufferViews": views,
        "buffers": [{"byteLength": bin.len()}],
    });
    pa_model::export::glb_container(&doc, bin).map_err(SceneError::Glb)
}

/// The built-in prop loaded as a [`pa_model::Model`].
pub fn prop_model(spec: &PropSpec) -> Result<pa_model::Model, SceneError> {
    let glb = prop_glb(spec)?;
    Ok(pa_model::Model::from_slice(
        &glb,
        "builtin:prop.glb",
        None,
        &pa_model::LoadOptions::default(),
    )?)
}
