//! `propsalive inspect` on hostile models (issue 11): its output is linear in the model (a
//! 100,000-node chain used to print 10^10 bytes of indentation), and a refused file gives a
//! clear error, not a panic.

use std::process::Command;

use serde_json::json;

fn bin() -> &'static str {
    env!("CARGO_BIN_EXE_propsalive")
}

#[test]
fn inspect_of_a_100k_node_chain_is_linear() {
    let depth = 100_000usize;
    let nodes: Vec<_> = (0..depth)
        .map(|i| {
            if i + 1 < depth {
                json!({"name": format!("joint{i}"), "children": [i + 1]})
            } else {
                json!({"name": "tip"})
            }
        })
        .collect();
    let doc = json!({
        "asset": {"version": "2.0"},
        "scenes": [{"nodes": [0]}],
        "nodes": nodes,
        "skins": [{"joints": (0..depth).collect::<Vec<_>>()}]
    });
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("chain.gltf");
    std::fs::write(&path, serde_json::to_vec(&doc).expect("json")).expect("write");
    let out = Command::new(bin())
        .arg("inspect")
        .arg(&path)
        .output()
        .expect("run propsalive inspect");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8(out.stdout).expect("utf-8");
    // One line per node, each of bounded length: far below depth^2.
    let node_lines = text
        .lines()
        .filter(|l| l.contains("] joint") || l.contains("] tip"));
    assert_eq!(node_lines.count(), depth, "every node once");
    assert!(text.len() < 100 * depth, "{} bytes", text.len());
    assert!(
        text.contains("(depth 99999) [99999] tip"),
        "deep nodes print their depth"
    );
    assert!(text.contains("100000 joints: joint0, joint1"));
    assert!(text.contains("... and 99968 more"));
}

#[test]
fn inspect_of_a_hostile_file_fails_clearly() {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("bad.gltf");
    let doc = json!({
        "asset": {"version": "2.0"},
        "nodes": [{}],
        "animations": [{"channels": [{"sampler": 0, "target": {"node": 1, "path": "foo"}}],
                        "samplers": []}]
    });
    std::fs::write(&path, serde_json::to_vec(&doc).expect("json")).expect("write");
    let out = Command::new(bin())
        .arg("inspect")
        .arg(&path)
        .output()
        .expect("run propsalive inspect");
    assert_eq!(out.status.code(), Some(1), "an error, not a panic (101)");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("bad.gltf") && err.contains("animation 0 channel 0"),
        "{err}"
    );
}
