//! `--scene` of `eval` and `demo`: an unknown variant is refused before anything is rendered,
//! with a message that names it and the variants that exist.

use std::process::Command;

#[test]
fn an_unknown_scene_variant_is_refused_by_eval_and_demo() {
    let dir = tempfile::tempdir().expect("temp dir");
    for cmd in ["eval", "demo"] {
        let out = dir.path().join(cmd);
        let o = Command::new(env!("CARGO_BIN_EXE_propsalive"))
            .args([cmd, "--scene", "shadows,sun", "--out"])
            .arg(&out)
            .output()
            .expect("runs");
        let e = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{cmd}: {e}");
        assert!(
            e.contains("unknown scene variant \"sun\"") && e.contains("covered-tag"),
            "{cmd}: {e}"
        );
        assert!(!e.contains("renderer:"), "{cmd} rendered first: {e}");
    }
}
