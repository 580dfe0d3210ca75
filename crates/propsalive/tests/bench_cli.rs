//! `propsalive bench` at a tiny size, on both render paths: it prints the table and writes
//! JSON whose every configuration holds finite, positive times and a finite prop PSNR, and the
//! two paths' PSNR agree (the CPU path draws what the GPU path draws). No time is asserted.

use std::process::Command;

#[test]
fn bench_quick_writes_a_table_and_json() {
    let dir = tempfile::tempdir().expect("tempdir");
    let json_path = dir.path().join("nested").join("bench.json");
    let run = Command::new(env!("CARGO_BIN_EXE_propsalive"))
        .args([
            "bench",
            "--quick",
            "--sizes",
            "160x120",
            "--vertices",
            "2000",
            "--props",
            "1,2",
            "--frames",
            "3",
            "--render-path",
            "gpu,cpu",
            "--json",
        ])
        .arg(&json_path)
        .output()
        .expect("run");
    let stderr = String::from_utf8_lossy(&run.stderr);
    if stderr.contains("no wgpu adapter") || stderr.contains("no suitable wgpu adapter") {
        println!("skipped: no wgpu adapter ({stderr})");
        return;
    }
    assert!(run.status.success(), "{stderr}");
    let stdout = String::from_utf8_lossy(&run.stdout);
    assert!(
        stdout.contains("| path | size | vertices | props | track |"),
        "{stdout}"
    );
    assert!(stdout.contains("| cpu | 160x120 |"), "{stdout}");
    assert!(stdout.contains("| gpu | 160x120 |"), "{stdout}");

    let doc: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&json_path).expect("json written")).expect("json");
    assert!(doc["adapter"].as_str().is_some_and(|s| !s.is_empty()));
    assert!(doc["backend"].as_str().is_some_and(|s| !s.is_empty()));
    let configs = doc["configs"].as_array().expect("configs");
    let props: Vec<u64> = configs
        .iter()
        .map(|c| c["props"].as_u64().expect("props"))
        .collect();
    assert_eq!(props, vec![1, 1, 2, 2]);
    let paths: Vec<&str> = configs
        .iter()
        .map(|c| c["render_path"].as_str().expect("render_path"))
        .collect();
    assert_eq!(paths, vec!["gpu", "cpu", "gpu", "cpu"]);
    for pair in configs.chunks(2) {
        let (g, c) = (
            pair[0]["prop_psnr_db"].as_f64().unwrap_or(f64::NAN),
            pair[1]["prop_psnr_db"].as_f64().unwrap_or(f64::NAN),
        );
        assert!((g - c).abs() < 0.2, "PSNR gpu {g} vs cpu {c}");
    }
    let positive = |v: &serde_json::Value, what: &str| {
        let x = v.as_f64().unwrap_or(f64::NAN);
        assert!(x.is_finite() && x > 0.0, "{what}: {v}");
    };
    for c in configs {
        assert_eq!(c["frames"], 3);
        assert_eq!(
            (c["width"].as_u64(), c["height"].as_u64()),
            (Some(160), Some(120))
        );
        // Every stage ran; animate and composite can be below the clock's resolution, so
        // they are only required to be finite and not negative.
        // The CPU path reads nothing back from a GPU.
        let timed: &[&str] = if c["render_path"] == "gpu" {
            &["track", "texture", "diminish", "readback"]
        } else {
            &["track", "texture", "diminish"]
        };
        for stage in timed {
            for q in ["median", "p95"] {
                positive(&c["stages_ms"][stage][q], &format!("{stage} {q}"));
            }
        }
        for stage in ["animate", "composite"] {
            let x = c["stages_ms"][stage]["median"].as_f64().unwrap_or(f64::NAN);
            assert!(x.is_finite() && x >= 0.0, "{stage}: {x}");
        }
        positive(&c["end_to_end_ms"]["median"], "end to end median");
        positive(&c["end_to_end_ms"]["p95"], "end to end p95");
        positive(&c["fps"], "fps");
        let psnr = c["prop_psnr_db"].as_f64().unwrap_or(f64::NAN);
        assert!(psnr.is_finite(), "PSNR {psnr}");
    }
    // The temporary file of the atomic write is gone.
    let leftovers: Vec<_> = std::fs::read_dir(json_path.parent().expect("dir"))
        .expect("dir")
        .filter_map(|e| e.ok())
        .filter(|e| e.file_name() != "bench.json")
        .collect();
    assert!(leftovers.is_empty(), "{leftovers:?}");
}
