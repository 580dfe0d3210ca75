//! Issue 11, item 9: deep node chains load in linear time and nothing recurses over node
//! depth (world transforms, skin joint matrices). No timing is asserted: the tests simply
//! finish (the quadratic cycle check took 12.8 s on a 100,000-node chain).

mod common;

use pa_model::{anim, skin};
use serde_json::json;

const DEPTH: usize = 100_000;

/// Node i has child i+1 and is translated by +1 in y; a skin has every node as a joint; an
/// animation moves the deepest joint.
fn chain(cyclic: bool) -> Vec<u8> {
    let nodes: Vec<_> = (0..DEPTH)
        .map(|i| {
            let mut n = json!({"translation": [0.0, 1.0, 0.0]});
            if i + 1 < DEPTH {
                n["children"] = json!([i + 1]);
            } else if cyclic {
                n["children"] = json!([0]);
            }
            n
        })
        .collect();
    let mut bin = Vec::new();
    for x in [0f32, 1.0] {
        bin.extend(x.to_le_bytes());
    }
    for x in [0f32, 0.0, 0.0, 1.0, 0.0, 0.0] {
        bin.extend(x.to_le_bytes());
    }
    let doc = json!({
        "asset": {"version": "2.0"},
        "scenes": [{"nodes": if cyclic { json!([]) } else { json!([0]) }}],
        "nodes": nodes,
        "skins": [{"joints": (0..DEPTH).collect::<Vec<_>>()}],
        "buffers": [{"byteLength": bin.len(), "uri": common::data_uri(&bin)}],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": 8},
            {"buffer": 0, "byteOffset": 8, "byteLength": 24}
        ],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 2, "type": "SCALAR",
             "min": [0], "max": [1]},
            {"bufferView": 1, "componentType": 5126, "count": 2, "type": "VEC3"}
        ],
        "animations": [{"channels": [{"sampler": 0,
            "target": {"node": DEPTH - 1, "path": "translation"}}],
            "samplers": [{"input": 0, "output": 1}]}]
    });
    serde_json::to_vec(&doc).expect("json")
}

#[test]
fn a_100k_node_chain_loads_and_poses_without_recursion() {
    let m = common::load_bytes(&chain(false), "chain.gltf").expect("a deep chain loads");
    assert_eq!(m.nodes.len(), DEPTH);
    assert_eq!(m.roots, vec![0]);
    assert_eq!(m.nodes[DEPTH - 1].parent, Some(DEPTH - 2));
    let world = anim::Pose::rest(&m).world_from_node(&m);
    let tip = world[DEPTH - 1].w_axis;
    assert_eq!(tip.y, DEPTH as f32, "{tip}");
    let joints = skin::joint_matrices(&m, 0, &world);
    assert_eq!(joints.len(), DEPTH);
    // The animation moves the tip by +1 in x at t = 1.
    let world = anim::sample(&m, 0, 1.0).world_from_node(&m);
    assert_eq!(world[DEPTH - 1].w_axis.x, 1.0);
    // Nothing to draw, nothing posed.
    assert!(skin::pose_meshes(&m, &anim::Pose::rest(&m)).is_empty());
}

#[test]
fn a_100k_node_cycle_is_refused() {
    let e = common::load_bytes(&chain(true), "cycle.gltf")
        .expect_err("a cycle")
        .to_string();
    assert!(
        e.starts_with("cycle.gltf: node hierarchy: node ") && e.contains("part of a cycle"),
        "{e}"
    );
}

#[test]
fn scene_entries_that_are_not_roots_are_ignored_with_one_warning() {
    // Listing every node of a chain as a scene root would make anything that walks from the
    // roots (inspect) visit the chain once per entry: quadratic.
    let mut doc = common::triangle_doc();
    doc["scenes"][0]["nodes"] = json!([0, 1, 2, 1, 0]);
    let m = common::load_bytes(&serde_json::to_vec(&doc).expect("json"), "s.gltf").expect("loads");
    assert_eq!(m.roots, vec![0, 1]);
    assert_eq!(m.warnings.len(), 1, "{:?}", m.warnings);
    assert!(m.warnings[0].contains("3 entries"), "{:?}", m.warnings);
}
