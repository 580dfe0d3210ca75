//! Export of posed meshes (world space, metres) as OBJ, STL or GLB, written atomically.
//!
//! - OBJ keeps every primitive's vertices in glTF order, unwelded, one `o node<N>_prim<P>`
//!   group per primitive, so it can be compared vertex by vertex with other tools.
//! - STL (binary) welds vertices that share a rest position within a primitive, so a
//!   watertight source stays watertight after skinning (split UV/normal seams do not crack).
//! - GLB is a static glTF 2.0 mesh: positions, normals, UVs, indices and the base colour.

use std::collections::HashMap;
use std::fmt::Write as _;
use std::path::Path;

use glam::Vec3;

use crate::skin::PosedPrimitive;
use crate::{ErrorKind, Model, ModelError};

/// The output format, chosen from a file extension.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    Obj,
    Stl,
    Glb,
}

impl Format {
    /// The format for a path's extension (case-insensitive).
    pub fn from_path(path: &Path) -> Option<Self> {
        let ext = path.extension()?.to_str()?.to_ascii_lowercase();
        match ext.as_str() {
            "obj" => Some(Self::Obj),
            "stl" => Some(Self::Stl),
            "glb" => Some(Self::Glb),
            _ => None,
        }
    }
}

/// Writes posed primitives to `path` in the format its extension names.
pub fn write(model: &Model, posed: &[PosedPrimitive], path: &Path) -> Result<(), ModelError> {
    let export_err = |m: String| ModelError::new(path, ErrorKind::Export(m));
    let format = Format::from_path(path).ok_or_else(|| {
        export_err("unknown output extension (use .obj, .stl or .glb)".to_string())
    })?;
    let bytes = match format {
        Format::Obj => obj_bytes(model, posed).into_bytes(),
        Format::Stl => stl_bytes(model, posed),
        Format::Glb => glb_bytes(model, posed).map_err(|e| export_err(e.to_string()))?,
    };
    write_atomic(path, &bytes).map_err(|e| ModelError::new(path, ErrorKind::Io(e)))
}

/// Writes a file atomically (see [`pa_io::write_atomic`]): never replaces a file that is not a
/// regular file.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    pa_io::write_atomic(path, bytes).map_err(Into::into)
}

/// Like [`write_atomic`], but only if nothing has the name `path` (see
/// [`pa_io::write_new_atomic`]). Returns false when the name was taken.
pub fn write_new_atomic(path: &Path, bytes: &[u8]) -> std::io::Result<bool> {
    pa_io::write_new_atomic(path, bytes).map_err(Into::into)
}

/// Wavefront OBJ text.
pub fn obj_bytes(model: &Model, posed: &[PosedPrimitive]) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "# Props Alive posed mesh, world space (glTF axes, metres)\n# source: {}",
        model.path.display()
    );
    let mut base = 1usize;
    for p in posed {
        let prim = &model.meshes[p.mesh].primitives[p.primitive];
        let _ = writeln!(s, "o {}", p.label());
        for v in &p.positions {
            let _ = writeln!(s, "v {} {} {}", v.x, v.y, v.z);
        }
        let has_uv = prim.uvs.len() == p.positions.len();
        let has_n = p.normals.len() == p.positions.len();
        if has_uv {
            for uv in &prim.uvs {
                let _ = writeln!(s, "vt {} {}", uv[0], 1.0 - uv[1]);
            }
        }
        if has_n {
            for n in &p.normals {
                let _ = writeln!(s, "vn {} {} {}", n.x, n.y, n.z);
            }
        }
        for t in prim.indices.chunks_exact(3) {
            let f = |i: u32| {
                let k = base + i as usize;
                match (has_uv, has_n) {
                    (true, true) => format!("{k}/{k}/{k}"),
                    (true, false) => format!("{k}/{k}"),
                    (false, true) => format!("{k}//{k}"),
                    (false, false) => format!("{k}"),
                }
            };
            let _ = writeln!(s, "f {} {} {}", f(t[0]), f(t[1]), f(t[2]));
        }
        base += p.positions.len();
    }
    s
}

/// Canonical vertex per rest position (bitwise) within a primitive.
fn weld_map(rest: &[Vec3]) -> Vec<u32> {
    let mut first: HashMap<[u32; 3], u32> = HashMap::new();
    rest.iter()
        .enumerate()
        .map(|(i, p)| {
            *first
                .entry([p.x.to_bits(), p.y.to_bits(), p.z.to_bits()])
                .or_insert(i as u32)
        })
        .collect()
}

/// Binary STL, welded per primitive.
pub fn stl_bytes(model: &Model, posed: &[PosedPrimitive]) -> Vec<u8> {
    let mut tris: Vec<[Vec3; 3]> = Vec::new();
    for p in posed {
        let prim = &model.meshes[p.mesh].primitives[p.primitive];
        let weld = weld_map(&prim.positions);
        for t in prim.indices.chunks_exact(3) {
            let v = |i: u32| p.positions[weld[i as usize] as usize];
            tris.push([v(t[0]), v(t[1]), v(t[2])]);
        }
    }
    let mut out = Vec::with_capacity(84 + tris.len() * 50);
    let mut header = [0u8; 80];
    let h = b"Props Alive posed mesh (metres, glTF axes)";
    header[..h.len()].copy_from_slice(h);
    out.extend_from_slice(&header);
    out.extend_from_slice(&(tris.len() as u32).to_le_bytes());
    for [a, b, c] in tris {
        let n = (b - a).cross(c - a).normalize_or_zero();
        for v in [n, a, b, c] {
            for x in v.to_array() {
                out.extend_from_slice(&x.to_le_bytes());
            }
        }
        out.extend_from_slice(&0u16.to_le_bytes());
    }
    out
}

/// A static GLB of the posed mesh; [`ErrorKind::NoTriangles`] when no primitive has any.
pub fn glb_bytes(model: &Model, posed: &[PosedPrimitive]) -> Result<Vec<u8>, ErrorKind> {
    use serde_json::json;
    let mut bin: Vec<u8> = Vec::new();
    let mut views = Vec::new();
    let mut accessors = Vec::new();
    let mut meshes = Vec::new();
    let mut nodes = Vec::new();
    let mut materials = Vec::new();
    let mut push_view = |bin: &mut Vec<u8>, data: &[u8], target: u32| -> usize {
        while !bin.len().is_multiple_of(4) {
            bin.push(0);
        }
        views.push(
            json!({"buffer": 0, "byteOffset": bin.len(), "byteLength": data.len(),
                          "target": target}),
        );
        bin.extend_from_slice(data);
        views.len() - 1
    };
    for p in posed {
        let prim = &model.meshes[p.mesh].primitives[p.primitive];
        if prim.indices.is_empty() || p.positions.is_empty() {
            continue;
        }
        let f32s = |v: &mut Vec<u8>, xs: &[f32]| xs.iter().for_each(|x| v.extend(x.to_le_bytes()));
        let mut attrs = serde_json::Map::new();
        let mut buf = Vec::new();
        for v in &p.positions {
            f32s(&mut buf, &v.to_array());
        }
        let lo = p
            .positions
            .iter()
            .fold(Vec3::splat(f32::MAX), |a, b| a.min(*b));
        let hi = p
            .positions
            .iter()
            .fold(Vec3::splat(f32::MIN), |a, b| a.max(*b));
        let view = push_view(&mut bin, &buf, 34962);
        accessors.push(
            json!({"bufferView": view, "componentType": 5126, "count": p.positions.len(),
            "type": "VEC3", "min": lo.to_array(), "max": hi.to_array()}),
        );
        attrs.insert("POSITION".into(), json!(accessors.len() - 1));
        if p.normals.len() == p.positions.len() {
            buf.clear();
            for n in &p.normals {
                f32s(&mut buf, &n.to_array());
            }
            let view = push_view(&mut bin, &buf, 34962);
            accessors.push(json!({"bufferView": view, "componentType": 5126,
                "count": p.normals.len(), "type": "VEC3"}));
            attrs.insert("NORMAL".into(), json!(accessors.len() - 1));
        }
        if prim.uvs.len() == p.positions.len() {
            buf.clear();
            for uv in &prim.uvs {
                f32s(&mut buf, uv);
            }
            let view = push_view(&mut bin, &buf, 34962);
            accessors.push(json!({"bufferView": view, "componentType": 5126,
                "count": prim.uvs.len(), "type": "VEC2"}));
            attrs.insert("TEXCOORD_0".into(), json!(accessors.len() - 1));
        }
        buf.clear();
        for i in &prim.indices {
            buf.extend(i.to_le_bytes());
        }
        let view = push_view(&mut bin, &buf, 34963);
        accessors.push(json!({"bufferView": view, "componentType": 5125,
            "count": prim.indices.len(), "type": "SCALAR"}));
        let indices = accessors.len() - 1;
        let color = prim
            .material
            .and_then(|m| model.materials.get(m))
            .map(|m| m.base_color_factor)
            .unwrap_or([1.0; 4]);
        materials.push(json!({"pbrMetallicRoughness": {"baseColorFactor": color,
            "metallicFactor": 0.0, "roughnessFactor": 1.0}, "doubleSided": true}));
        meshes.push(
            json!({"name": p.label(), "primitives": [{"attributes": attrs,
            "indices": indices, "material": materials.len() - 1}]}),
        );
        nodes.push(json!({"name": p.label(), "mesh": meshes.len() - 1}));
    }
    if meshes.is_empty() {
        return Err(ErrorKind::NoTriangles);
    }
    let node_ids: Vec<usize> = (0..nodes.len()).collect();
    let doc = json!({
        "asset": {"version": "2.0", "generator": "Props Alive export"},
        "scene": 0, "scenes": [{"nodes": node_ids}], "nodes": nodes, "meshes": meshes,
        "materials": materials, "accessors": accessors, "bufferViews": views,
        "buffers": [{"byteLength": bin.len()}],
    });
    glb_container(&doc, bin)
}

/// Packs a glTF JSON document and its binary buffer into a GLB container (4-byte aligned
/// chunks, JSON padded with spaces, BIN with zeros). Fails with [`ErrorKind::GlbJson`] or
/// [`ErrorKind::GlbTooLarge`].
pub fn glb_container(doc: &serde_json::Value, mut bin: Vec<u8>) -> Result<Vec<u8>, ErrorKind> {
    let mut json_bytes = serde_json::to_vec(doc).map_err(ErrorKind::GlbJson)?;
    while !json_bytes.len().is_multiple_of(4) {
        json_bytes.push(b' ');
    }
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let total = 12 + 8 + json_bytes.len() + 8 + bin.len();
    let total32 = u32::try_from(total).map_err(|_| ErrorKind::GlbTooLarge { bytes: total })?;
    let mut out = Vec::with_capacity(total);
    out.extend(b"glTF");
    out.extend(2u32.to_le_bytes());
    out.extend(total32.to_le_bytes());
    out.extend((json_bytes.len() as u32).to_le_bytes());
    out.extend(b"JSON");
    out.extend(&json_bytes);
    out.extend((bin.len() as u32).to_le_bytes());
    out.extend(b"BIN\0");
    out.extend(&bin);
    Ok(out)
}
