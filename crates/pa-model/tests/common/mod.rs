//! Hostile inputs shared by the tests (issue 11). Each case is a small file built in code;
//! a copy of each lies in `tests/regressions/` (see `regressions.rs`), which also holds files
//! other tools (a fuzzer) add.

#![allow(dead_code)]

use base64::Engine as _;
use pa_model::{LoadOptions, Model, ModelError};
use serde_json::{json, Value};

/// A hostile file: its name (after the bug), its bytes, and words its error must contain.
pub struct Case {
    pub name: &'static str,
    pub bytes: Vec<u8>,
    pub needles: Vec<&'static str>,
}

/// A one-triangle skinned mesh with two joints, buffers as a data URI.
/// Layout of buffer 0: positions (36 B) | joints u8 x4 (12 B) | weights f32 x4 (48 B) |
/// inverse bind matrices (128 B) | indices u16 (6 B + 2 pad).
pub fn triangle_bytes() -> Vec<u8> {
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

pub fn data_uri(bytes: &[u8]) -> String {
    format!(
        "data:application/octet-stream;base64,{}",
        base64::engine::general_purpose::STANDARD.encode(bytes)
    )
}

/// The valid skinned triangle (3 nodes, 5 accessors, 5 buffer views, 1 buffer, 1 mesh,
/// 1 skin, 1 scene) with one animation whose sampler reads accessors 3 and 0 (never decoded
/// by the cases, which are refused first).
pub fn triangle_doc() -> Value {
    let bytes = triangle_bytes();
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
        "buffers": [{"byteLength": bytes.len(), "uri": data_uri(&bytes)}],
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

fn with_animation(mut doc: Value) -> Value {
    doc["animations"] = json!([{
        "channels": [{"sampler": 0, "target": {"node": 2, "path": "translation"}}],
        "samplers": [{"input": 3, "output": 0}]
    }]);
    doc
}

fn with_texture(mut doc: Value) -> Value {
    doc["images"] = json!([{"uri": "never-read.png"}]);
    doc["textures"] = json!([{"source": 0}]);
    doc["materials"] = json!([{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}]);
    doc["meshes"][0]["primitives"][0]["material"] = json!(0);
    doc
}

fn gltf_case(name: &'static str, doc: Value, needles: &[&'static str]) -> Case {
    Case {
        name,
        bytes: serde_json::to_vec(&doc).expect("json"),
        needles: needles.to_vec(),
    }
}

/// A GLB container from a header length and raw chunks (type, bytes).
pub fn glb(declared_length: Option<u32>, chunks: &[(u32, &[u8], Option<u32>)]) -> Vec<u8> {
    let mut body = Vec::new();
    for (ty, data, len) in chunks {
        body.extend(len.unwrap_or(data.len() as u32).to_le_bytes());
        body.extend(ty.to_le_bytes());
        body.extend(*data);
    }
    let mut out = Vec::new();
    out.extend(b"glTF");
    out.extend(2u32.to_le_bytes());
    out.extend(
        declared_length
            .unwrap_or(12 + body.len() as u32)
            .to_le_bytes(),
    );
    out.extend(body);
    out
}

pub const JSON_CHUNK: u32 = 0x4E4F_534A;
pub const BIN_CHUNK: u32 = 0x004E_4942;

/// Item 5: every index the `gltf` crate trusts, out of range, and every enumerated value it
/// unwraps, unknown; plus GLB containers whose lengths lie.
pub fn reference_cases() -> Vec<Case> {
    let t = triangle_doc;
    let edit = |f: &dyn Fn(&mut Value)| {
        let mut d = t();
        f(&mut d);
        d
    };
    let prim = "/meshes/0/primitives/0";
    let set = |doc: Value, pointer: &str, v: Value| {
        // Sets (or adds) the property at a JSON pointer.
        let mut doc = doc;
        let (parent, key) = pointer.rsplit_once('/').expect("pointer");
        let parent = if parent.is_empty() {
            &mut doc
        } else {
            doc.pointer_mut(parent).expect("parent exists")
        };
        match parent {
            Value::Object(m) => {
                m.insert(key.to_string(), v);
            }
            Value::Array(a) => a[key.parse::<usize>().expect("index")] = v,
            _ => panic!("{pointer}: parent is not a container"),
        }
        doc
    };
    let anim = || with_animation(t());
    let tex = || with_texture(t());
    let json_bytes = serde_json::to_vec(&t()).expect("json");
    vec![
        gltf_case(
            "position_accessor_out_of_range.gltf",
            set(t(), &format!("{prim}/attributes/POSITION"), json!(5)),
            &[
                "mesh 0 primitive 0",
                "attributes.POSITION",
                "accessor 5",
                "there are 5 accessors",
            ],
        ),
        gltf_case(
            "normal_accessor_out_of_range.gltf",
            edit(&|d| d["meshes"][0]["primitives"][0]["attributes"]["NORMAL"] = json!(99)),
            &["mesh 0 primitive 0", "attributes.NORMAL", "accessor 99"],
        ),
        gltf_case(
            "joints_accessor_out_of_range.gltf",
            set(t(), &format!("{prim}/attributes/JOINTS_0"), json!(7)),
            &["attributes.JOINTS_0", "accessor 7"],
        ),
        gltf_case(
            "primitive_indices_out_of_range.gltf",
            set(t(), &format!("{prim}/indices"), json!(9)),
            &["mesh 0 primitive 0", "indices", "accessor 9"],
        ),
        gltf_case(
            "primitive_material_out_of_range.gltf",
            edit(&|d| d["meshes"][0]["primitives"][0]["material"] = json!(0)),
            &["mesh 0 primitive 0", "material 0", "there are 0 materials"],
        ),
        gltf_case(
            "primitive_mode_unknown.gltf",
            edit(&|d| d["meshes"][0]["primitives"][0]["mode"] = json!(9)),
            &["mesh 0 primitive 0", "mode"],
        ),
        gltf_case(
            "morph_target_position_out_of_range.gltf",
            edit(&|d| d["meshes"][0]["primitives"][0]["targets"] = json!([{"POSITION": 42}])),
            &["mesh 0 primitive 0", "targets[0].POSITION", "accessor 42"],
        ),
        gltf_case(
            "accessor_buffer_view_out_of_range.gltf",
            set(t(), "/accessors/0/bufferView", json!(5)),
            &[
                "accessor 0",
                "bufferView",
                "buffer view 5",
                "there are 5 buffer views",
            ],
        ),
        gltf_case(
            "accessor_type_unknown.gltf",
            set(t(), "/accessors/1/type", json!("VEC7")),
            &["accessor 1", "type"],
        ),
        gltf_case(
            "sparse_indices_buffer_view_out_of_range.gltf",
            set(
                t(),
                "/accessors/0/sparse",
                json!({"count": 1, "indices": {"bufferView": 9, "componentType": 5123},
                       "values": {"bufferView": 0}}),
            ),
            &["accessor 0", "sparse.indices.bufferView", "buffer view 9"],
        ),
        gltf_case(
            "sparse_values_buffer_view_out_of_range.gltf",
            set(
                t(),
                "/accessors/0/sparse",
                json!({"count": 1, "indices": {"bufferView": 4, "componentType": 5123},
                       "values": {"bufferView": 11}}),
            ),
            &["accessor 0", "sparse.values.bufferView", "buffer view 11"],
        ),
        gltf_case(
            "buffer_view_buffer_out_of_range.gltf",
            set(t(), "/bufferViews/2/buffer", json!(1)),
            &["buffer view 2", "buffer 1", "there is 1 buffer"],
        ),
        gltf_case(
            "skin_joint_out_of_range.gltf",
            set(t(), "/skins/0/joints", json!([1, 3])),
            &["skin 0", "joints[1]", "node 3", "there are 3 nodes"],
        ),
        gltf_case(
            "skin_inverse_bind_matrices_out_of_range.gltf",
            set(t(), "/skins/0/inverseBindMatrices", json!(5)),
            &["skin 0", "inverseBindMatrices", "accessor 5"],
        ),
        gltf_case(
            "skin_skeleton_out_of_range.gltf",
            edit(&|d| d["skins"][0]["skeleton"] = json!(10)),
            &["skin 0", "skeleton", "node 10"],
        ),
        gltf_case(
            "node_mesh_out_of_range.gltf",
            set(t(), "/nodes/0/mesh", json!(1)),
            &["node 0", "mesh 1", "there is 1 mesh"],
        ),
        gltf_case(
            "node_skin_out_of_range.gltf",
            set(t(), "/nodes/0/skin", json!(4)),
            &["node 0", "skin 4"],
        ),
        gltf_case(
            "node_child_out_of_range.gltf",
            set(t(), "/nodes/1/children", json!([2, 3])),
            &["node 1", "children[1]", "node 3"],
        ),
        gltf_case(
            "node_camera_out_of_range.gltf",
            edit(&|d| d["nodes"][2]["camera"] = json!(0)),
            &["node 2", "camera 0", "there are 0 cameras"],
        ),
        gltf_case(
            "scene_node_out_of_range.gltf",
            set(t(), "/scenes/0/nodes", json!([0, 3])),
            &["scene 0", "nodes[1]", "node 3"],
        ),
        gltf_case(
            "default_scene_out_of_range.gltf",
            set(t(), "/scene", json!(1)),
            &["scene", "scene 1", "there is 1 scene"],
        ),
        gltf_case(
            "texture_source_out_of_range.gltf",
            set(tex(), "/textures/0/source", json!(1)),
            &["texture 0", "source", "image 1", "there is 1 image"],
        ),
        gltf_case(
            "texture_sampler_out_of_range.gltf",
            set(tex(), "/textures/0/sampler", json!(0)),
            &["texture 0", "sampler 0", "there are 0 samplers"],
        ),
        gltf_case(
            "material_texture_out_of_range.gltf",
            set(
                tex(),
                "/materials/0/pbrMetallicRoughness/baseColorTexture/index",
                json!(2),
            ),
            &["material 0", "baseColorTexture", "texture 2"],
        ),
        gltf_case(
            "material_normal_texture_out_of_range.gltf",
            edit(&|d| {
                d["materials"] = json!([{"normalTexture": {"index": 0}}]);
            }),
            &[
                "material 0",
                "normalTexture",
                "texture 0",
                "there are 0 textures",
            ],
        ),
        gltf_case(
            "image_buffer_view_out_of_range.gltf",
            edit(&|d| d["images"] = json!([{"bufferView": 9, "mimeType": "image/png"}])),
            &["image 0", "bufferView", "buffer view 9"],
        ),
        gltf_case(
            "image_buffer_view_without_mime_type.gltf",
            edit(&|d| d["images"] = json!([{"bufferView": 0}])),
            &["image 0", "no mimeType"],
        ),
        gltf_case(
            "image_without_uri_or_buffer_view.gltf",
            edit(&|d| d["images"] = json!([{}])),
            &["image 0", "neither a uri nor a bufferView"],
        ),
        gltf_case(
            "animation_target_node_out_of_range.gltf",
            set(anim(), "/animations/0/channels/0/target/node", json!(3)),
            &[
                "animation 0 channel 0",
                "target.node",
                "node 3",
                "there are 3 nodes",
            ],
        ),
        gltf_case(
            "animation_target_path_unknown.gltf",
            set(anim(), "/animations/0/channels/0/target/path", json!("foo")),
            &["animation 0 channel 0", "target.path"],
        ),
        gltf_case(
            "animation_channel_sampler_out_of_range.gltf",
            set(anim(), "/animations/0/channels/0/sampler", json!(1)),
            &[
                "animation 0 channel 0",
                "animation sampler 1",
                "there is 1 animation sampler",
            ],
        ),
        gltf_case(
            "animation_sampler_input_out_of_range.gltf",
            set(anim(), "/animations/0/samplers/0/input", json!(5)),
            &["animation 0 sampler 0", "input", "accessor 5"],
        ),
        gltf_case(
            "animation_sampler_output_out_of_range.gltf",
            set(anim(), "/animations/0/samplers/0/output", json!(6)),
            &["animation 0 sampler 0", "output", "accessor 6"],
        ),
        gltf_case(
            "animation_sampler_interpolation_unknown.gltf",
            set(
                anim(),
                "/animations/0/samplers/0/interpolation",
                json!("SMOOTH"),
            ),
            &["animation 0 sampler 0", "interpolation"],
        ),
        Case {
            name: "glb_header_length_below_12.glb",
            bytes: glb(Some(8), &[]),
            needles: vec!["not a valid glTF", "GLB header declares 8 bytes"],
        },
        Case {
            name: "glb_header_truncated.glb",
            bytes: b"glTF\x02\x00".to_vec(),
            needles: vec!["not a valid glTF", "truncated"],
        },
        Case {
            name: "glb_chunk_length_past_the_end.glb",
            bytes: glb(None, &[(JSON_CHUNK, &json_bytes, Some(u32::MAX - 3))]),
            needles: vec!["not a valid glTF", "GLB chunk 0", "truncated"],
        },
        Case {
            name: "glb_first_chunk_not_json.glb",
            bytes: glb(None, &[(BIN_CHUNK, &json_bytes, None)]),
            needles: vec!["not a valid glTF", "not JSON"],
        },
    ]
}

/// A sparse accessor without a buffer view: `count` zeros of `ty` with one substituted
/// element (read from buffer views 0, indices, and 1, values).
fn viewless(count: u64, ty: &str) -> Value {
    let mut a = json!({"componentType": 5126, "count": count, "type": ty,
        "sparse": {"count": 1, "indices": {"bufferView": 0, "componentType": 5125},
                   "values": {"bufferView": 1}}});
    if ty == "VEC3" {
        a["min"] = json!([0, 0, 0]);
        a["max"] = json!([1, 1, 1]);
    }
    a
}

/// A tiny buffer for [`viewless`]: index 0 (u32) then 16 floats of 0.
fn viewless_buffers(doc: &mut Value) {
    let bytes = vec![0u8; 4 + 64];
    doc["buffers"] = json!([{"byteLength": bytes.len(), "uri": data_uri(&bytes)}]);
    doc["bufferViews"] = json!([
        {"buffer": 0, "byteOffset": 0, "byteLength": 4},
        {"buffer": 0, "byteOffset": 4, "byteLength": 64}
    ]);
}

/// Item 7: small files that ask for gigabytes.
pub fn budget_cases() -> Vec<Case> {
    // 2^24 vertices (sparse, no buffer view) with 16 morph targets of 2^24 deltas each.
    let mut morph = json!({
        "asset": {"version": "2.0"},
        "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0},
            "targets": vec![json!({"POSITION": 1}); 16]}]}],
        "accessors": [viewless(1 << 24, "VEC3"), viewless(1 << 24, "VEC3")]
    });
    viewless_buffers(&mut morph);

    // One animation channel of 2^24 keys (zeros: non-decreasing, so valid) repeated 8 times.
    let mut anim = json!({
        "asset": {"version": "2.0"},
        "nodes": [{}],
        "accessors": [viewless(1 << 24, "SCALAR"), viewless(1 << 24, "VEC3")],
        "animations": [{
            "channels": vec![json!({"sampler": 0, "target": {"node": 0, "path": "translation"}}); 8],
            "samplers": [{"input": 0, "output": 1}]
        }]
    });
    viewless_buffers(&mut anim);

    // A mesh of 2^20 vertices drawn by 64 nodes: 64 Mi vertices to pose.
    let mut instanced = json!({
        "asset": {"version": "2.0"},
        "nodes": vec![json!({"mesh": 0}); 64],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "mode": 0}]}],
        "accessors": [viewless(1 << 20, "VEC3")]
    });
    viewless_buffers(&mut instanced);

    vec![
        gltf_case(
            "sparse_viewless_16_morph_targets_of_2e24_vertices.gltf",
            morph,
            &[
                "decoded morph target data",
                "max_morph_bytes",
                "mesh 0 primitive 0 morph target",
            ],
        ),
        gltf_case(
            "animation_channel_of_2e24_keys_repeated.gltf",
            anim,
            &[
                "decoded animation data",
                "max_animation_bytes",
                "animation 0 channel",
            ],
        ),
        gltf_case(
            "mesh_of_2e20_vertices_drawn_by_64_nodes.gltf",
            instanced,
            &["vertices drawn", "max_instanced_vertices", "node"],
        ),
    ]
}

/// Every case with a copy in `tests/regressions/`.
pub fn all_cases() -> Vec<Case> {
    let mut v = reference_cases();
    v.extend(budget_cases());
    v
}

pub fn load_bytes(bytes: &[u8], name: &str) -> Result<Model, ModelError> {
    Model::from_slice(bytes, name, None, &LoadOptions::default())
}

/// Loads a case from memory as `hostile.<ext>` and checks its error names the file and the
/// problem.
pub fn expect_refused(case: &Case) -> String {
    let ext = case.name.rsplit('.').next().unwrap_or("gltf");
    let name = format!("hostile.{ext}");
    let e = load_bytes(&case.bytes, &name)
        .err()
        .unwrap_or_else(|| panic!("{}: must be refused", case.name))
        .to_string();
    assert!(
        e.starts_with(&format!("{name}: ")),
        "{}: message names the file: {e}",
        case.name
    );
    for n in &case.needles {
        assert!(
            e.contains(n),
            "{}: message {e:?} should mention {n:?}",
            case.name
        );
    }
    e
}
