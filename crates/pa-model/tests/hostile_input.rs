//! Hostile and broken files: each case must give a `ModelError` whose message names the
//! problem (and the file), never a panic or an unbounded allocation.

use base64::Engine as _;
use pa_model::{LoadOptions, Model};
use serde_json::{json, Value};

/// A one-triangle skinned mesh with two joints, buffers as a data URI.
/// Layout of buffer 0: positions (36 B) | joints u8 x4 (12 B) | weights f32 x4 (48 B) |
/// inverse bind matrices (128 B) | indices u16 (6 B + 2 pad).
fn triangle_bytes() -> Vec<u8> {
    let mut b = Vec::new();
    for v in [[0f32, 0., 0.], [1., 0., 0.], [0., 1., 0.]] {
        for x in v {
            b.extend(x.to_le_bytes());
        }
    }
    for j in [[0u8, 1, 0, 0], [0, 1, 0, 0], [1, 0, 0, 0]] {
        b.extend(j);
    }
    for w in [[1f32, 0., 0., 0.], [0.5, 0.5, 0., 0.], [1., 0., 0., 0.]] {
        for x in w {
            b.extend(x.to_le_bytes());
        }
    }
    for _ in 0..2 {
        for x in glam::Mat4::IDENTITY.to_cols_array() {
            b.extend(x.to_le_bytes());
        }
    }
    for i in [0u16, 1, 2, 0] {
        b.extend(i.to_le_bytes());
    }
    b
}

fn doc_with(bytes: &[u8]) -> Value {
    let uri = format!(
        "data:application/octet-stream;base64,{}",
        base64::engine::general_purpose::STANDARD.encode(bytes)
    );
    json!({
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0, 1]}],
        "nodes": [
            {"mesh": 0, "skin": 0},
            {"children": [2]},
            {"translation": [0, 1, 0]}
        ],
        "skins": [{"joints": [1, 2], "inverseBindMatrices": 4}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "JOINTS_0": 1, "WEIGHTS_0": 2},
                                     "indices": 3}]}],
        "buffers": [{"byteLength": bytes.len(), "uri": uri}],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": 36},
            {"buffer": 0, "byteOffset": 36, "byteLength": 12},
            {"buffer": 0, "byteOffset": 48, "byteLength": 48},
            {"buffer": 0, "byteOffset": 96, "byteLength": 128},
            {"buffer": 0, "byteOffset": 224, "byteLength": 6}
        ],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
             "min": [0, 0, 0], "max": [1, 1, 0]},
            {"bufferView": 1, "componentType": 5121, "count": 3, "type": "VEC4"},
            {"bufferView": 2, "componentType": 5126, "count": 3, "type": "VEC4"},
            {"bufferView": 4, "componentType": 5123, "count": 3, "type": "SCALAR"},
            {"bufferView": 3, "componentType": 5126, "count": 2, "type": "MAT4"}
        ]
    })
}

fn load(doc: &Value) -> Result<Model, pa_model::ModelError> {
    let bytes = serde_json::to_vec(doc).expect("json");
    Model::from_slice(&bytes, "hostile.gltf", None, &LoadOptions::default())
}

fn expect_err(doc: &Value, needles: &[&str]) -> String {
    let e = load(doc).expect_err("must be refused").to_string();
    assert!(
        e.starts_with("hostile.gltf: "),
        "message names the file: {e}"
    );
    for n in needles {
        assert!(e.contains(n), "message {e:?} should mention {n:?}");
    }
    e
}

#[test]
fn the_valid_triangle_loads_and_skins() {
    let m = load(&doc_with(&triangle_bytes())).expect("valid file loads");
    assert_eq!(m.vertex_count(), 3);
    assert!(m.warnings.is_empty(), "{:?}", m.warnings);
    let pose = pa_model::anim::Pose::rest(&m);
    let posed = pa_model::skin::pose_meshes(&m, &pose);
    // Joint 1 is translated by +1 in y; vertex 1 is half on each joint.
    let p = posed[0].positions[1];
    assert!((p - glam::Vec3::new(1.0, 0.5, 0.0)).length() < 1e-6, "{p}");
}

#[test]
fn truncated_buffer() {
    let bytes = triangle_bytes();
    let mut doc = doc_with(&bytes[..100]);
    doc["buffers"][0]["byteLength"] = json!(bytes.len());
    expect_err(&doc, &["buffer 0", "truncated"]);
}

#[test]
fn corrupt_glb_container() {
    let mut glb = Vec::new();
    glb.extend(b"glTF");
    glb.extend(2u32.to_le_bytes());
    glb.extend(1000u32.to_le_bytes()); // claims 1000 bytes
    glb.extend(500u32.to_le_bytes()); // JSON chunk of 500 bytes that is not there
    glb.extend(b"JSON{");
    let e = Model::from_slice(&glb, "broken.glb", None, &LoadOptions::default())
        .expect_err("corrupt GLB refused")
        .to_string();
    assert!(
        e.contains("broken.glb") && e.contains("not a valid glTF"),
        "{e}"
    );
}

#[test]
fn garbage_file() {
    let e = Model::from_slice(b"\x00\x01garbage", "x.gltf", None, &LoadOptions::default())
        .expect_err("garbage refused")
        .to_string();
    assert!(e.contains("not a valid glTF"), "{e}");
}

#[test]
fn accessor_out_of_range() {
    let mut doc = doc_with(&triangle_bytes());
    doc["accessors"][0]["count"] = json!(1000);
    expect_err(&doc, &["accessor 0", "out of range"]);
    let mut doc = doc_with(&triangle_bytes());
    doc["bufferViews"][0]["byteOffset"] = json!(10_000);
    expect_err(&doc, &["outside buffer 0", "truncated or corrupt"]);
}

#[test]
fn joint_index_past_the_skin() {
    let mut bytes = triangle_bytes();
    bytes[36] = 7; // vertex 0, first joint (weight 1)
    expect_err(&doc_with(&bytes), &["joint index 7", "2 joints"]);
}

#[test]
fn nan_weights_are_refused() {
    let mut bytes = triangle_bytes();
    bytes[48..52].copy_from_slice(&f32::NAN.to_le_bytes());
    expect_err(
        &doc_with(&bytes),
        &["invalid skin weights", "vertex 0", "not a finite"],
    );
}

#[test]
fn weights_not_summing_to_one_are_normalised_with_one_warning() {
    let mut bytes = triangle_bytes();
    // Vertex 1 weights (0.5, 0.5) -> (0.5, 0.25): sum 0.75. Vertex 0 (1.0) -> 2.0.
    bytes[68..72].copy_from_slice(&0.25f32.to_le_bytes());
    bytes[48..52].copy_from_slice(&2.0f32.to_le_bytes());
    let m = load(&doc_with(&bytes)).expect("loads with a warning");
    assert_eq!(m.warnings.len(), 1, "{:?}", m.warnings);
    assert!(m.warnings[0].contains("2 vertices") && m.warnings[0].contains("normalised"));
    let w = m.meshes[0].primitives[0].weights[1];
    assert!(
        (w[0] - 2.0 / 3.0).abs() < 1e-6 && (w[1] - 1.0 / 3.0).abs() < 1e-6,
        "{w:?}"
    );
}

#[test]
fn uris_that_escape_the_model_folder() {
    let dir = tempfile::tempdir().expect("tempdir");
    let model_dir = dir.path().join("model");
    std::fs::create_dir(&model_dir).expect("mkdir");
    std::fs::write(dir.path().join("secret.bin"), triangle_bytes()).expect("write");
    for uri in [
        "../secret.bin",
        "../../etc/passwd",
        "/etc/passwd",
        "sub/../../secret.bin",
        "..%2Fsecret.bin",
        "C:\\Windows\\win.ini",
        "..\\secret.bin",
    ] {
        let mut doc = doc_with(&triangle_bytes());
        doc["buffers"][0]["uri"] = json!(uri);
        let path = model_dir.join("m.gltf");
        std::fs::write(&path, serde_json::to_vec(&doc).expect("json")).expect("write");
        let e = Model::load(&path).expect_err(uri).to_string();
        assert!(e.contains("escapes the model's folder"), "{uri}: {e}");
        assert!(e.contains("m.gltf"), "{uri}: {e}");
    }
    // A symbolic link inside the folder that points out of it is refused too.
    #[cfg(unix)]
    {
        std::os::unix::fs::symlink(dir.path().join("secret.bin"), model_dir.join("link.bin"))
            .expect("symlink");
        let mut doc = doc_with(&triangle_bytes());
        doc["buffers"][0]["uri"] = json!("link.bin");
        let path = model_dir.join("m.gltf");
        std::fs::write(&path, serde_json::to_vec(&doc).expect("json")).expect("write");
        let e = Model::load(&path).expect_err("symlink").to_string();
        assert!(e.contains("escapes"), "{e}");
    }
    // A plain relative file inside the folder is fine.
    std::fs::write(model_dir.join("ok.bin"), triangle_bytes()).expect("write");
    let mut doc = doc_with(&triangle_bytes());
    doc["buffers"][0]["uri"] = json!("ok.bin");
    let path = model_dir.join("m.gltf");
    std::fs::write(&path, serde_json::to_vec(&doc).expect("json")).expect("write");
    Model::load(&path).expect("relative URI inside the folder loads");
}

#[test]
fn remote_uris_are_not_fetched() {
    let mut doc = doc_with(&triangle_bytes());
    doc["buffers"][0]["uri"] = json!("https://example.com/x.bin");
    expect_err(&doc, &["not supported"]);
}

#[test]
fn absurd_counts_and_sizes_do_not_allocate() {
    // A sparse accessor without a buffer view, claiming 4 billion elements.
    let mut doc = doc_with(&triangle_bytes());
    doc["accessors"][0] = json!({"componentType": 5126, "count": 4_000_000_000u64,
        "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0],
        "sparse": {"count": 1, "indices": {"bufferView": 4, "componentType": 5123},
                   "values": {"bufferView": 0}}});
    expect_err(&doc, &["accessor 0", "absurd"]);
    // A buffer that claims a terabyte.
    let mut doc = doc_with(&triangle_bytes());
    doc["buffers"][0]["byteLength"] = json!(1u64 << 40);
    expect_err(&doc, &["buffer 0", "truncated"]);
    // A file over the size limit is refused before it is read.
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("big.glb");
    std::fs::write(&path, vec![0u8; 4096]).expect("write");
    let mut opts = LoadOptions::default();
    opts.limits.max_file_bytes = 1024;
    let e = Model::load_with(&path, &opts)
        .expect_err("too big")
        .to_string();
    assert!(e.contains("over the limit"), "{e}");
}

#[test]
fn index_past_the_vertices() {
    let mut bytes = triangle_bytes();
    bytes[224..226].copy_from_slice(&9u16.to_le_bytes());
    expect_err(&doc_with(&bytes), &["index 0 is 9", "past the 3 vertices"]);
}

#[test]
fn node_cycles() {
    let mut doc = doc_with(&triangle_bytes());
    doc["nodes"][2]["children"] = json!([1]);
    doc["scenes"][0]["nodes"] = json!([0]);
    // gltf's own validation or our hierarchy check must refuse it.
    let e = load(&doc).expect_err("cycle refused").to_string();
    assert!(
        e.contains("cycle") || e.contains("parent") || e.contains("not a valid"),
        "{e}"
    );
}

#[test]
fn missing_file_names_the_path() {
    let e = Model::load("/nonexistent/dir/model.glb")
        .expect_err("missing")
        .to_string();
    assert!(
        e.contains("/nonexistent/dir/model.glb") && e.contains("cannot read"),
        "{e}"
    );
}

#[test]
fn corrupt_embedded_image() {
    let mut doc = doc_with(&triangle_bytes());
    doc["images"] = json!([{"uri": "data:image/png;base64,iVBORw0KGgoAAAAN"}]);
    expect_err(&doc, &["image 0", "cannot"]);
}

#[test]
fn animation_with_bad_keys() {
    let mut bytes = triangle_bytes();
    // Key times 1.0, 0.5 (decreasing) and two translation values appended at offset 232.
    let off = bytes.len();
    for t in [1.0f32, 0.5] {
        bytes.extend(t.to_le_bytes());
    }
    for v in [0f32, 0., 0., 1., 1., 1.] {
        bytes.extend(v.to_le_bytes());
    }
    let mut doc = doc_with(&bytes);
    let views = doc["bufferViews"].as_array_mut().expect("array");
    views.push(json!({"buffer": 0, "byteOffset": off, "byteLength": 8}));
    views.push(json!({"buffer": 0, "byteOffset": off + 8, "byteLength": 24}));
    let accs = doc["accessors"].as_array_mut().expect("array");
    accs.push(
        json!({"bufferView": 5, "componentType": 5126, "count": 2, "type": "SCALAR",
                     "min": [0.5], "max": [1.0]}),
    );
    accs.push(json!({"bufferView": 6, "componentType": 5126, "count": 2, "type": "VEC3"}));
    doc["animations"] = json!([{"channels": [{"sampler": 0, "target": {"node": 2,
        "path": "translation"}}], "samplers": [{"input": 5, "output": 6}]}]);
    expect_err(&doc, &["animation 0", "not increasing"]);
}
