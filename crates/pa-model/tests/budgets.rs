//! Issue 11, item 7: memory is bounded by documented budgets ([`pa_model::Limits`]), checked
//! from the declared counts before anything is decoded; the error names the file, the budget
//! and what ran over it.

mod common;

use common::{budget_cases, expect_refused, load_bytes, Case};
use pa_model::{ErrorKind, LoadOptions, Model};
use serde_json::json;

fn case(name: &str) -> Case {
    budget_cases()
        .into_iter()
        .find(|c| c.name == name)
        .expect("known case")
}

#[test]
fn sparse_viewless_morph_targets_are_refused_before_allocating() {
    let e = expect_refused(&case(
        "sparse_viewless_16_morph_targets_of_2e24_vertices.gltf",
    ));
    assert!(e.contains("over the budget of 1073741824 bytes"), "{e}");
}

#[test]
fn a_huge_animation_channel_repeated_is_refused() {
    let e = expect_refused(&case("animation_channel_of_2e24_keys_repeated.gltf"));
    assert!(e.contains("over the budget of 536870912 bytes"), "{e}");
}

#[test]
fn a_large_mesh_drawn_by_many_nodes_is_refused() {
    expect_refused(&case("mesh_of_2e20_vertices_drawn_by_64_nodes.gltf"));
}

/// The shape of the 23 MB GLB: one animation (12,000 keys) repeated 3,000 times,
/// here at the default budget (a 460 KB file that would decode to 576 MB; the budget runs
/// out near copy 2,795).
#[test]
fn an_animation_repeated_3000_times_is_refused_by_the_default_budget() {
    let keys = 12_000usize;
    let mut bin = Vec::new();
    for k in 0..keys {
        bin.extend((k as f32).to_le_bytes());
    }
    for k in 0..keys {
        for x in [k as f32, 0.0, 0.0] {
            bin.extend(x.to_le_bytes());
        }
    }
    let anim = json!({
        "channels": [{"sampler": 0, "target": {"node": 0, "path": "translation"}}],
        "samplers": [{"input": 0, "output": 1}]
    });
    let doc = json!({
        "asset": {"version": "2.0"},
        "nodes": [{}],
        "buffers": [{"byteLength": bin.len()}],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": keys * 4},
            {"buffer": 0, "byteOffset": keys * 4, "byteLength": keys * 12}
        ],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": keys, "type": "SCALAR",
             "min": [0], "max": [keys - 1]},
            {"bufferView": 1, "componentType": 5126, "count": keys, "type": "VEC3"}
        ],
        "animations": vec![anim; 3000]
    });
    let mut json_bytes = serde_json::to_vec(&doc).expect("json");
    while !json_bytes.len().is_multiple_of(4) {
        json_bytes.push(b' ');
    }
    let glb = common::glb(
        None,
        &[
            (common::JSON_CHUNK, &json_bytes, None),
            (common::BIN_CHUNK, &bin, None),
        ],
    );
    let e = load_bytes(&glb, "repeated.glb").expect_err("over budget");
    assert!(
        matches!(
            e.kind,
            ErrorKind::OverBudget {
                budget: "max_animation_bytes",
                ..
            }
        ),
        "{e}"
    );
    let msg = e.to_string();
    assert!(
        msg.starts_with("repeated.glb: decoded animation data needs")
            && msg.contains("Limits::max_animation_bytes")
            && msg.contains("ran out at animation "),
        "{msg}"
    );
    // The same file with fewer copies loads.
    let mut doc = doc;
    doc["animations"] = json!(vec![doc["animations"][0].clone(); 10]);
    let mut json_bytes = serde_json::to_vec(&doc).expect("json");
    while !json_bytes.len().is_multiple_of(4) {
        json_bytes.push(b' ');
    }
    let glb = common::glb(
        None,
        &[
            (common::JSON_CHUNK, &json_bytes, None),
            (common::BIN_CHUNK, &bin, None),
        ],
    );
    let m = load_bytes(&glb, "fewer.glb").expect("10 copies fit");
    assert_eq!(m.animations.len(), 10);
}

/// Many nodes instancing a mesh with many morph targets: the node morph weights count.
#[test]
fn node_morph_weights_count_against_the_morph_budget() {
    let mut doc = common::triangle_doc();
    doc["meshes"][0]["primitives"][0]["targets"] = json!(vec![json!({}); 100]);
    doc["meshes"][0]["weights"] = json!(vec![0.5; 100_000]);
    let mut nodes = doc["nodes"].as_array().expect("nodes").clone();
    for _ in 0..1000 {
        nodes.push(json!({"mesh": 0}));
    }
    doc["nodes"] = json!(nodes);
    let bytes = serde_json::to_vec(&doc).expect("json");
    let mut options = LoadOptions::default();
    // 100 targets x 36 bytes (3 vertices) + 1001 nodes x 100 weights x 4 bytes = 404,000,
    // plus (no NORMAL) the flat-shaded copy's 100 targets x 36 bytes (3 corners) = 407,600.
    options.limits.max_morph_bytes = 400_000;
    let e = Model::from_slice(&bytes, "weights.gltf", None, &options)
        .expect_err("over the morph budget")
        .to_string();
    assert!(
        e.starts_with("weights.gltf: decoded morph target data needs")
            && e.contains("Limits::max_morph_bytes")
            && e.contains("morph weights"),
        "{e}"
    );
    options.limits.max_morph_bytes = 407_599;
    Model::from_slice(&bytes, "weights.gltf", None, &options).expect_err("one byte short");
    options.limits.max_morph_bytes = 407_600;
    let m = Model::from_slice(&bytes, "weights.gltf", None, &options).expect("fits");
    // Only the weights of the targets are kept, however long the mesh's list.
    assert!(m
        .nodes
        .iter()
        .all(|n| n.mesh.is_none() || n.morph_weights.len() == 100));
}

#[test]
fn vertex_budget_names_the_primitive_and_attribute() {
    let bytes = serde_json::to_vec(&common::triangle_doc()).expect("json");
    let mut options = LoadOptions::default();
    options.limits.max_vertex_bytes = 40;
    let e = Model::from_slice(&bytes, "tri.gltf", None, &options)
        .expect_err("over")
        .to_string();
    assert_eq!(
        e,
        "tri.gltf: decoded vertex data needs 180 bytes, over the budget of 40 bytes \
         (Limits::max_vertex_bytes); the budget ran out at mesh 0 primitive 0 JOINTS_0/WEIGHTS_0"
    );
    // Positions, joints and weights, indices, inverse bind matrices, and (no NORMAL) the
    // flat-shaded copy: 3 corners x (position 12 + normal 12 + index 4 + joints/weights 48).
    options.limits.max_vertex_bytes = 36 + 144 + 12 + 128 + 3 * (12 + 12 + 4 + 48);
    Model::from_slice(&bytes, "tri.gltf", None, &options).expect("exactly fits");
    options.limits.max_vertex_bytes -= 1;
    Model::from_slice(&bytes, "tri.gltf", None, &options).expect_err("one byte short");
}

#[test]
fn node_budget() {
    let bytes = serde_json::to_vec(&common::triangle_doc()).expect("json");
    let mut options = LoadOptions::default();
    options.limits.max_nodes = 2;
    let e = Model::from_slice(&bytes, "tri.gltf", None, &options)
        .expect_err("3 nodes")
        .to_string();
    assert!(
        e.contains("3 nodes, over the budget of 2 nodes (Limits::max_nodes)"),
        "{e}"
    );
}

/// One external file named by many buffers is read once per buffer: the total read counts.
#[test]
fn a_file_named_by_many_buffers_counts_against_the_input_budget() {
    let dir = tempfile::tempdir().expect("tempdir");
    let bin = common::triangle_bytes();
    std::fs::write(dir.path().join("data.bin"), &bin).expect("write");
    let mut doc = common::triangle_doc();
    doc["buffers"] = json!(vec![
        json!({"byteLength": bin.len(), "uri": "data.bin"});
        100
    ]);
    let path = dir.path().join("many.gltf");
    std::fs::write(&path, serde_json::to_vec(&doc).expect("json")).expect("write");
    let mut options = LoadOptions::default();
    options.limits.max_input_bytes = 50 * bin.len() as u64;
    let e = Model::load_with(&path, &options)
        .expect_err("over the input budget")
        .to_string();
    assert!(
        e.contains("many.gltf: buffer and image data read needs")
            && e.contains("Limits::max_input_bytes")
            && e.contains("file \"data.bin\""),
        "{e}"
    );
    options.limits.max_input_bytes = 100 * bin.len() as u64;
    Model::load_with(&path, &options).expect("fits");
}

/// A buffer reads only its declared length from a longer file.
#[test]
fn a_buffer_reads_only_its_declared_length() {
    let dir = tempfile::tempdir().expect("tempdir");
    let mut bin = common::triangle_bytes();
    let declared = bin.len();
    bin.resize(declared + 1_000_000, 7);
    std::fs::write(dir.path().join("long.bin"), &bin).expect("write");
    let mut doc = common::triangle_doc();
    doc["buffers"] = json!([{"byteLength": declared, "uri": "long.bin"}]);
    let path = dir.path().join("long.gltf");
    std::fs::write(&path, serde_json::to_vec(&doc).expect("json")).expect("write");
    let mut options = LoadOptions::default();
    options.limits.max_input_bytes = declared as u64;
    Model::load_with(&path, &options).expect("only the declared bytes are read");
}
