//! Issue 11, item 5: indices and enumerated values the `gltf` crate trusts (and would panic
//! on) are checked first; each bad one gives a `ModelError` naming the file, where the
//! reference is and what it names.

mod common;

use common::{expect_refused, reference_cases, Case};

fn case(name: &str) -> Case {
    reference_cases()
        .into_iter()
        .find(|c| c.name == name)
        .expect("known case")
}

#[test]
fn position_accessor_out_of_range() {
    let e = expect_refused(&case("position_accessor_out_of_range.gltf"));
    assert_eq!(
        e,
        "hostile.gltf: mesh 0 primitive 0: attributes.POSITION names accessor 5, which does \
         not exist (there are 5 accessors)"
    );
}

#[test]
fn animation_target_node_out_of_range() {
    let e = expect_refused(&case("animation_target_node_out_of_range.gltf"));
    assert_eq!(
        e,
        "hostile.gltf: animation 0 channel 0: target.node names node 3, which does not exist \
         (there are 3 nodes)"
    );
}

#[test]
fn animation_target_path_unknown() {
    let e = expect_refused(&case("animation_target_path_unknown.gltf"));
    assert!(e.contains("translation, rotation, scale or weights"), "{e}");
}

#[test]
fn image_sources_the_gltf_crate_unwraps() {
    expect_refused(&case("image_buffer_view_without_mime_type.gltf"));
    expect_refused(&case("image_without_uri_or_buffer_view.gltf"));
}

#[test]
fn glb_lengths_that_lie() {
    for name in [
        "glb_header_length_below_12.glb",
        "glb_header_truncated.glb",
        "glb_chunk_length_past_the_end.glb",
        "glb_first_chunk_not_json.glb",
    ] {
        expect_refused(&case(name));
    }
}

/// The whole class: every index field and enumerated value, one case each, none panics.
#[test]
fn every_bad_reference_is_refused_naming_it() {
    let mut failures = Vec::new();
    for c in reference_cases() {
        let outcome = std::panic::catch_unwind(|| expect_refused(&c));
        if outcome.is_err() {
            failures.push(c.name);
        }
    }
    assert!(failures.is_empty(), "failed or panicked: {failures:?}");
}

/// The same references, valid, still load (the checks refuse only what is wrong).
#[test]
fn the_valid_documents_behind_the_cases_load() {
    let m = common::load_bytes(
        &serde_json::to_vec(&common::triangle_doc()).expect("json"),
        "ok.gltf",
    )
    .expect("valid triangle loads");
    assert_eq!(m.roots, vec![0, 1]);
    // A GLB whose chunks are right loads, with an unknown chunk type skipped.
    let mut doc = common::triangle_doc();
    let bin = common::triangle_bytes();
    doc["buffers"] = serde_json::json!([{"byteLength": bin.len()}]);
    let json = serde_json::to_vec(&doc).expect("json");
    let mut json_padded = json.clone();
    while !json_padded.len().is_multiple_of(4) {
        json_padded.push(b' ');
    }
    let glb = common::glb(
        None,
        &[
            (common::JSON_CHUNK, &json_padded, None),
            (common::BIN_CHUNK, &bin, None),
            (0x1234_5678, b"skip", None),
        ],
    );
    let m = common::load_bytes(&glb, "ok.glb").expect("GLB loads");
    assert_eq!(m.vertex_count(), 3);
}

/// Deeply nested JSON in extras or an unknown property is skipped without recursion (and a
/// deeply nested value where a glTF property is expected hits the parser's depth limit): no
/// stack overflow either way.
#[test]
fn deeply_nested_json_does_not_overflow_the_stack() {
    let deep = format!("{}{}", "[".repeat(100_000), "]".repeat(100_000));
    for at in ["extras", "unknownProperty"] {
        let text = format!(r#"{{"asset": {{"version": "2.0"}}, "nodes": [{{"{at}": {deep}}}]}}"#);
        let m = common::load_bytes(text.as_bytes(), "deep.gltf").expect("skipped");
        assert_eq!(m.nodes.len(), 1);
    }
    let text =
        format!(r#"{{"asset": {{"version": "2.0"}}, "nodes": [{{"translation": {deep}}}]}}"#);
    let e = common::load_bytes(text.as_bytes(), "deep.gltf")
        .expect_err("not a translation")
        .to_string();
    assert!(e.starts_with("deep.gltf: not a valid glTF"), "{e}");
}
