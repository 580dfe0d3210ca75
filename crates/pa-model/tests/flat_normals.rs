//! Issue 13, item 0: a primitive without NORMAL gets flat normals at load (glTF 2.0: "When
//! normals are not specified, client implementations MUST calculate flat normals"), for both
//! render paths, while its own vertices stay the file's (posing, export and the conformance
//! references compare them by index).

use base64::Engine as _;
use glam::{Quat, Vec3};
use pa_model::{anim, skin, LoadOptions, Model, Primitive};
use serde_json::{json, Value};

/// A square pyramid: base corners 0..4 at y = 0, apex 4 at y = 1; 4 sides and 2 base
/// triangles, counter-clockwise seen from outside.
const PYRAMID_POSITIONS: [[f32; 3]; 5] = [
    [-0.5, 0.0, -0.5],
    [0.5, 0.0, -0.5],
    [0.5, 0.0, 0.5],
    [-0.5, 0.0, 0.5],
    [0.0, 1.0, 0.0],
];
const PYRAMID_UVS: [[f32; 2]; 5] = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0], [0.5, 0.5]];
const PYRAMID_INDICES: [u32; 18] = [0, 4, 1, 1, 4, 2, 2, 4, 3, 3, 4, 0, 0, 1, 2, 0, 2, 3];

fn f32_bytes(v: impl IntoIterator<Item = f32>) -> Vec<u8> {
    v.into_iter().flat_map(f32::to_le_bytes).collect()
}

/// A one-mesh glTF (buffer as a data URI) with `positions`, `uvs`, optional `normals` and
/// optional `indices`, drawn in `mode`, on a node with `node` properties.
fn doc(
    positions: &[[f32; 3]],
    uvs: &[[f32; 2]],
    normals: Option<&[[f32; 3]]>,
    indices: Option<&[u32]>,
    mode: u32,
    node: Value,
) -> Vec<u8> {
    let mut bin = Vec::new();
    let mut views = Vec::new();
    let mut accessors: Vec<Value> = Vec::new();
    let mut push = |bin: &mut Vec<u8>, data: Vec<u8>, mut accessor: Value| {
        views.push(json!({"buffer": 0, "byteOffset": bin.len(), "byteLength": data.len()}));
        bin.extend(data);
        accessor["bufferView"] = json!(views.len() - 1);
        accessors.push(accessor);
        accessors.len() - 1
    };
    let n = positions.len();
    // POSITION needs its bounds.
    let lo = positions
        .iter()
        .fold([f32::MAX; 3], |a, p| [0, 1, 2].map(|k| a[k].min(p[k])));
    let hi = positions
        .iter()
        .fold([f32::MIN; 3], |a, p| [0, 1, 2].map(|k| a[k].max(p[k])));
    let pos = push(
        &mut bin,
        f32_bytes(positions.iter().flatten().copied()),
        json!({"componentType": 5126, "count": n, "type": "VEC3", "min": lo, "max": hi}),
    );
    let uv = push(
        &mut bin,
        f32_bytes(uvs.iter().flatten().copied()),
        json!({"componentType": 5126, "count": n, "type": "VEC2"}),
    );
    let mut attributes = json!({"POSITION": pos, "TEXCOORD_0": uv});
    if let Some(nrm) = normals {
        let a = push(
            &mut bin,
            f32_bytes(nrm.iter().flatten().copied()),
            json!({"componentType": 5126, "count": n, "type": "VEC3"}),
        );
        attributes["NORMAL"] = json!(a);
    }
    let mut primitive = json!({"attributes": attributes, "mode": mode});
    if let Some(idx) = indices {
        let a = push(
            &mut bin,
            idx.iter().flat_map(|i| i.to_le_bytes()).collect(),
            json!({"componentType": 5125, "count": idx.len(), "type": "SCALAR"}),
        );
        primitive["indices"] = json!(a);
    }
    let mut node = node;
    node["mesh"] = json!(0);
    let doc = json!({
        "asset": {"version": "2.0"},
        "scenes": [{"nodes": [0]}],
        "nodes": [node],
        "meshes": [{"primitives": [primitive]}],
        "buffers": [{"byteLength": bin.len(), "uri": format!(
            "data:application/octet-stream;base64,{}",
            base64::engine::general_purpose::STANDARD.encode(&bin))}],
        "bufferViews": views,
        "accessors": accessors,
    });
    serde_json::to_vec(&doc).expect("json")
}

fn load(bytes: &[u8]) -> Model {
    Model::from_slice(bytes, "flat.gltf", None, &LoadOptions::default()).expect("loads")
}

fn only_primitive(m: &Model) -> &Primitive {
    &m.meshes[0].primitives[0]
}

/// The triangle's normal, computed here independently of the loader.
fn expected_normal(a: Vec3, b: Vec3, c: Vec3) -> Vec3 {
    (b - a).cross(c - a).normalize()
}

/// Every triangle of `p` has its own three vertices, each holding the triangle's unit normal.
fn assert_flat(p: &Primitive) {
    assert_eq!(p.normals.len(), p.positions.len());
    let mut owner = vec![usize::MAX; p.positions.len()];
    for (t, tri) in p.indices.chunks_exact(3).enumerate() {
        let [a, b, c] = [tri[0], tri[1], tri[2]].map(|i| p.positions[i as usize]);
        let want = expected_normal(a, b, c);
        for &i in tri {
            let n = p.normals[i as usize];
            assert!((n.length() - 1.0).abs() < 1e-6, "unit normal, got {n}");
            assert!(
                (n - want).length() < 1e-6,
                "triangle {t} vertex {i}: {n}, want {want}"
            );
            // No vertex is shared with another triangle (whose normal may differ).
            assert!(
                owner[i as usize] == usize::MAX || owner[i as usize] == t,
                "vertex {i} is shared by triangles {} and {t}",
                owner[i as usize]
            );
            owner[i as usize] = t;
        }
    }
}

#[test]
fn an_indexed_pyramid_without_normals_is_drawn_with_unit_face_normals() {
    let m = load(&doc(
        &PYRAMID_POSITIONS,
        &PYRAMID_UVS,
        None,
        Some(&PYRAMID_INDICES),
        4,
        json!({}),
    ));
    let p = only_primitive(&m);
    // The file's vertices are kept as they are (export and conformance compare by index).
    assert_eq!(p.positions.len(), 5);
    assert!(p.normals.is_empty());
    assert_eq!(p.indices, PYRAMID_INDICES);
    // The drawn copy: 6 triangles, 18 vertices of their own.
    let d = p.drawn();
    assert!(p.flat_shaded.is_some());
    assert_eq!(d.positions.len(), 18);
    assert_eq!(d.indices, (0..18).collect::<Vec<u32>>());
    assert_flat(d);
    // Each corner copies the vertex it stands for (position and UV).
    for (c, &src) in PYRAMID_INDICES.iter().enumerate() {
        assert_eq!(d.positions[c], Vec3::from(PYRAMID_POSITIONS[src as usize]));
        assert_eq!(d.uvs[c], PYRAMID_UVS[src as usize]);
    }
    // Outward: every face normal points away from the pyramid's inside.
    let inside = Vec3::new(0.0, 0.25, 0.0);
    for tri in d.indices.chunks_exact(3) {
        let centre = tri.iter().map(|&i| d.positions[i as usize]).sum::<Vec3>() / 3.0;
        assert!(d.normals[tri[0] as usize].dot(centre - inside) > 0.0);
    }
    // The base's two triangles share the plane: both -Y.
    assert_eq!(d.normals[12], -Vec3::Y);
    assert_eq!(d.normals[15], -Vec3::Y);
}

#[test]
fn a_non_indexed_list_gets_its_flat_normals_in_place() {
    let positions: Vec<[f32; 3]> = PYRAMID_INDICES
        .iter()
        .map(|&i| PYRAMID_POSITIONS[i as usize])
        .collect();
    let uvs: Vec<[f32; 2]> = PYRAMID_INDICES
        .iter()
        .map(|&i| PYRAMID_UVS[i as usize])
        .collect();
    let m = load(&doc(&positions, &uvs, None, None, 4, json!({})));
    let p = only_primitive(&m);
    // Vertices are already per face: same order as the file, normals filled, no copy.
    assert!(p.flat_shaded.is_none());
    assert!(std::ptr::eq(p.drawn(), p));
    assert_eq!(p.positions.len(), 18);
    for (v, q) in positions.iter().enumerate() {
        assert_eq!(p.positions[v], Vec3::from(*q));
    }
    assert_flat(p);
}

#[test]
fn strips_and_fans_are_unwelded_too() {
    // A quad folded along its diagonal, as a strip (0 1 2, then 2 1 3 after the winding
    // swap) and as a fan (0 1 2, 0 2 3).
    let positions = [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [1.0, 1.0, 1.0],
    ];
    let uvs = [[0.0; 2]; 4];
    for (mode, want_tris) in [
        (5u32, [[0u32, 1, 2], [2, 1, 3]]),
        (6, [[0, 1, 2], [0, 2, 3]]),
    ] {
        let m = load(&doc(&positions, &uvs, None, None, mode, json!({})));
        let p = only_primitive(&m);
        assert!(p.normals.is_empty(), "mode {mode}");
        let d = p.drawn();
        assert_eq!(d.positions.len(), 6, "mode {mode}");
        assert_flat(d);
        for (t, tri) in want_tris.iter().enumerate() {
            let [a, b, c] = tri.map(|i| Vec3::from(positions[i as usize]));
            assert_eq!(&d.positions[t * 3..t * 3 + 3], &[a, b, c], "mode {mode}");
        }
    }
}

#[test]
fn a_file_with_normals_is_drawn_as_it_is() {
    let normals = [[0.0, 1.0, 0.0]; 5];
    let m = load(&doc(
        &PYRAMID_POSITIONS,
        &PYRAMID_UVS,
        Some(&normals),
        Some(&PYRAMID_INDICES),
        4,
        json!({}),
    ));
    let p = only_primitive(&m);
    assert!(p.flat_shaded.is_none());
    assert!(std::ptr::eq(p.drawn(), p));
    assert_eq!(p.normals, vec![Vec3::Y; 5]);
}

/// Posed (here by a rotated, unevenly scaled, mirrored node) the flat normals stay the posed
/// faces' normals: exact for a rigid part.
#[test]
fn posed_flat_normals_are_the_posed_faces_normals() {
    let r = Quat::from_euler(glam::EulerRot::XYZ, 0.3, -1.1, 0.7);
    let node = json!({"rotation": r.to_array(), "scale": [2.0, 0.5, -1.5],
        "translation": [0.1, 0.2, 0.3]});
    let m = load(&doc(
        &PYRAMID_POSITIONS,
        &PYRAMID_UVS,
        None,
        Some(&PYRAMID_INDICES),
        4,
        node,
    ));
    let pose = anim::Pose::rest(&m);
    let file_order = skin::pose_meshes(&m, &pose);
    let drawn = skin::pose_drawn_meshes(&m, &pose);
    assert!(file_order[0].normals.is_empty());
    let d = &drawn[0];
    assert_eq!(d.positions.len(), 18);
    for (c, &src) in PYRAMID_INDICES.iter().enumerate() {
        assert_eq!(d.positions[c], file_order[0].positions[src as usize]);
    }
    for (t, tri) in d.positions.chunks_exact(3).enumerate() {
        // The node mirrors (negative determinant): the posed winding is reversed, and the
        // inverse-transpose normal is the posed face's outward normal, its negative winding.
        let want = -expected_normal(tri[0], tri[1], tri[2]);
        for n in &d.normals[t * 3..t * 3 + 3] {
            assert!((*n - want).length() < 1e-5, "{n} vs {want}");
        }
    }
}

/// The Khronos samples without NORMAL (SimpleSkin, RecursiveSkeletons, SimpleMorph): their
/// file-order posing is what the references check (unchanged, no normals), and the drawn
/// copy posed at the same times is exactly that posing, corner by corner, with unit normals.
#[test]
fn conformance_models_without_normals_pose_the_same_vertices_when_drawn() {
    let Some(root) = pa_testkit::conformance_dir() else {
        return;
    };
    let mut checked = 0;
    for file in [
        "SimpleSkin.gltf",
        "RecursiveSkeletons.glb",
        "SimpleMorph.gltf",
    ] {
        let path = pa_testkit::model_file(&root, file);
        let m = Model::load(&path).unwrap_or_else(|e| panic!("{e}"));
        let anims = m.animations.len().max(1);
        for a in 0..anims {
            let duration = m.animations.get(a).map(|x| x.duration_s).unwrap_or(0.0);
            for t in [0.0, 0.37 * duration, duration] {
                let pose = if m.animations.is_empty() {
                    anim::Pose::rest(&m)
                } else {
                    anim::sample(&m, a, t)
                };
                let file_order = skin::pose_meshes(&m, &pose);
                let drawn = skin::pose_drawn_meshes(&m, &pose);
                assert_eq!(file_order.len(), drawn.len());
                for (f, d) in file_order.iter().zip(&drawn) {
                    let prim = &m.meshes[f.mesh].primitives[f.primitive];
                    assert!(prim.normals.is_empty(), "{file}: the file has no NORMAL");
                    assert!(f.normals.is_empty());
                    assert!(prim.flat_shaded.is_some(), "{file}: indexed, so a copy");
                    assert_eq!(d.positions.len(), prim.indices.len());
                    for (c, &src) in prim.indices.iter().enumerate() {
                        assert_eq!(d.positions[c], f.positions[src as usize], "{file} {c}");
                        let n = d.normals[c];
                        assert!((n.length() - 1.0).abs() < 1e-5, "{file}: {n}");
                    }
                }
                checked += 1;
            }
        }
    }
    assert!(checked >= 3);
}
