//! Loading features checked against hand-computed values: 8 influences (JOINTS_1/WEIGHTS_1),
//! sparse accessors, external .bin files with percent-encoded names, and data URIs.

use base64::Engine as _;
use glam::{Mat4, Vec3};
use pa_model::{anim::Pose, skin, LoadOptions, Model};
use serde_json::json;

fn f32_bytes(v: &[f32]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

/// One vertex at (1, 0, 0) influenced by 8 joints; joint k translates by (0, k+1, 0).
/// Weights 1/8 each, so the skinned y is the mean of 1..=8 = 4.5.
fn eight_influences_doc() -> (serde_json::Value, Vec<u8>) {
    let mut bin = Vec::new();
    bin.extend(f32_bytes(&[1.0, 0.0, 0.0])); // 0..12 position
    bin.extend([0u8, 1, 2, 3]); // 12..16 JOINTS_0
    bin.extend([4u8, 5, 6, 7]); // 16..20 JOINTS_1
    bin.extend(f32_bytes(&[0.125; 4])); // 20..36 WEIGHTS_0
    bin.extend(f32_bytes(&[0.125; 4])); // 36..52 WEIGHTS_1
    for _ in 0..8 {
        bin.extend(f32_bytes(&Mat4::IDENTITY.to_cols_array())); // 52..564 IBMs
    }
    let mut nodes = vec![json!({"mesh": 0, "skin": 0})];
    for k in 0..8 {
        nodes.push(json!({"translation": [0.0, (k + 1) as f32, 0.0]}));
    }
    let doc = json!({
        "asset": {"version": "2.0"},
        "scenes": [{"nodes": [0, 1, 2, 3, 4, 5, 6, 7, 8]}],
        "nodes": nodes,
        "skins": [{"joints": [1, 2, 3, 4, 5, 6, 7, 8], "inverseBindMatrices": 5}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "JOINTS_0": 1, "JOINTS_1": 2,
            "WEIGHTS_0": 3, "WEIGHTS_1": 4}, "mode": 0}]}],
        "buffers": [{"byteLength": bin.len(), "uri": "my%20data.bin"}],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": 12},
            {"buffer": 0, "byteOffset": 12, "byteLength": 4},
            {"buffer": 0, "byteOffset": 16, "byteLength": 4},
            {"buffer": 0, "byteOffset": 20, "byteLength": 16},
            {"buffer": 0, "byteOffset": 36, "byteLength": 16},
            {"buffer": 0, "byteOffset": 52, "byteLength": 512}
        ],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 1, "type": "VEC3",
             "min": [1, 0, 0], "max": [1, 0, 0]},
            {"bufferView": 1, "componentType": 5121, "count": 1, "type": "VEC4"},
            {"bufferView": 2, "componentType": 5121, "count": 1, "type": "VEC4"},
            {"bufferView": 3, "componentType": 5126, "count": 1, "type": "VEC4"},
            {"bufferView": 4, "componentType": 5126, "count": 1, "type": "VEC4"},
            {"bufferView": 5, "componentType": 5126, "count": 8, "type": "MAT4"}
        ]
    });
    (doc, bin)
}

#[test]
fn eight_influences_from_an_external_bin_with_an_encoded_name() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (doc, bin) = eight_influences_doc();
    std::fs::write(dir.path().join("my data.bin"), &bin).expect("write bin");
    let path = dir.path().join("eight.gltf");
    std::fs::write(&path, serde_json::to_vec(&doc).expect("json")).expect("write");
    let model = Model::load(&path).expect("loads");
    let prim = &model.meshes[0].primitives[0];
    assert_eq!(prim.joints[0], [0, 1, 2, 3, 4, 5, 6, 7]);
    assert_eq!(prim.weights[0], [0.125; 8]);
    let posed = skin::pose_meshes(&model, &Pose::rest(&model));
    let p = posed[0].positions[0];
    assert!((p - Vec3::new(1.0, 4.5, 0.0)).length() < 1e-6, "{p}");
}

#[test]
fn sparse_accessor_substitutes_values() {
    // Base positions: three vertices at x = 0, 1, 2; sparse replaces vertex 1 by (5, 6, 7).
    let mut bin = f32_bytes(&[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 2.0, 0.0, 0.0]); // 0..36
    bin.extend(1u16.to_le_bytes()); // 36..38 sparse index
    bin.extend([0u8, 0]); // pad to 40
    bin.extend(f32_bytes(&[5.0, 6.0, 7.0])); // 40..52 sparse value
    let uri = format!(
        "data:application/gltf-buffer;base64,{}",
        base64::engine::general_purpose::STANDARD.encode(&bin)
    );
    let doc = json!({
        "asset": {"version": "2.0"},
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0, "translation": [0.0, 0.0, 1.0]}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
        "buffers": [{"byteLength": bin.len(), "uri": uri}],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": 36},
            {"buffer": 0, "byteOffset": 36, "byteLength": 2},
            {"buffer": 0, "byteOffset": 40, "byteLength": 12}
        ],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
            "min": [0, 0, 0], "max": [5, 6, 7],
            "sparse": {"count": 1, "indices": {"bufferView": 1, "componentType": 5123},
                       "values": {"bufferView": 2}}}]
    });
    let bytes = serde_json::to_vec(&doc).expect("json");
    let model =
        Model::from_slice(&bytes, "sparse.gltf", None, &LoadOptions::default()).expect("loads");
    let p = &model.meshes[0].primitives[0].positions;
    assert_eq!(p[0], Vec3::ZERO);
    assert_eq!(p[1], Vec3::new(5.0, 6.0, 7.0));
    assert_eq!(p[2], Vec3::new(2.0, 0.0, 0.0));
    // A rigid node: world = node transform * p.
    let posed = skin::pose_meshes(&model, &Pose::rest(&model));
    assert_eq!(posed[0].positions[1], Vec3::new(5.0, 6.0, 8.0));
    assert_eq!(model.triangle_count(), 1);
}
