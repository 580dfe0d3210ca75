//! Golden-image comparison shared by the rendering tests.
//!
//! Tolerance: a pixel matches when every channel differs by at most `max_channel_diff`/255,
//! and at least `min_matching_fraction` of the pixels must match ([`Tolerance::DEFAULT`]:
//! 2/255 on 99.5 %). `UPDATE_GOLDEN=1` (re)writes the golden instead of comparing. A failure
//! writes `<target>/golden-failures/<name>.actual.png` and `<name>.diff.png` (magenta =
//! mismatch) and names them in the panic message.

use std::path::{Path, PathBuf};

/// How close an image must be to its golden.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tolerance {
    pub max_channel_diff: u8,
    pub min_matching_fraction: f64,
}

impl Tolerance {
    /// Every channel within 2/255 on at least 99.5 % of the pixels.
    pub const DEFAULT: Tolerance = Tolerance {
        max_channel_diff: 2,
        min_matching_fraction: 0.995,
    };
}

/// The workspace's target folder (`CARGO_TARGET_DIR`, else `<workspace>/target`).
pub fn target_dir() -> PathBuf {
    match std::env::var_os("CARGO_TARGET_DIR") {
        Some(dir) => PathBuf::from(dir),
        None => Path::new(env!("CARGO_MANIFEST_DIR")).join("../../target"),
    }
}

/// Writes an RGBA8 PNG, creating the folder.
pub fn save_png(path: &Path, width: u32, height: u32, rgba8: &[u8]) {
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir).expect("create directory for png");
    }
    image::save_buffer(path, rgba8, width, height, image::ColorType::Rgba8).expect("write png");
}

/// Compares an RGBA8 image with `golden_dir/<name>.png` (see the module docs).
pub fn assert_golden(
    golden_dir: &Path,
    name: &str,
    width: u32,
    height: u32,
    rgba8: &[u8],
    tolerance: Tolerance,
) {
    let path = golden_dir.join(format!("{name}.png"));
    if std::env::var("UPDATE_GOLDEN").is_ok_and(|v| v == "1") {
        save_png(&path, width, height, rgba8);
        eprintln!("wrote golden {}", path.display());
        return;
    }
    let failures = target_dir().join("golden-failures");
    let _ = std::fs::create_dir_all(&failures);
    let failures = failures.canonicalize().unwrap_or(failures);
    let actual_path = failures.join(format!("{name}.actual.png"));
    let diff_path = failures.join(format!("{name}.diff.png"));
    let golden = match image::open(&path) {
        Ok(img) => img.to_rgba8(),
        Err(e) => {
            save_png(&actual_path, width, height, rgba8);
            panic!(
                "golden {} unreadable ({e}); actual written to {}; run with UPDATE_GOLDEN=1 to create it",
                path.display(),
                actual_path.display()
            );
        }
    };
    assert_eq!(
        (golden.width(), golden.height()),
        (width, height),
        "golden {} has another size",
        path.display()
    );
    let mut diff = Vec::with_capacity(rgba8.len());
    let mut matching = 0usize;
    let mut worst = 0u8;
    for (a, g) in rgba8.chunks_exact(4).zip(golden.as_raw().chunks_exact(4)) {
        let d = a
            .iter()
            .zip(g)
            .map(|(x, y)| x.abs_diff(*y))
            .max()
            .unwrap_or(0);
        worst = worst.max(d);
        if d <= tolerance.max_channel_diff {
            matching += 1;
            diff.extend_from_slice(&[g[0] / 4, g[1] / 4, g[2] / 4, 255]);
        } else {
            diff.extend_from_slice(&[255, 0, 255, 255]);
        }
    }
    let total = (width as usize * height as usize).max(1);
    let fraction = matching as f64 / total as f64;
    eprintln!(
        "golden {name}: {:.3}% of pixels within {}/255 (worst {worst})",
        100.0 * fraction,
        tolerance.max_channel_diff
    );
    if fraction < tolerance.min_matching_fraction {
        save_png(&actual_path, width, height, rgba8);
        save_png(&diff_path, width, height, &diff);
        panic!(
            "golden {name}: only {:.3}% of pixels within {}/255 (need {:.1}%, worst diff {worst}); \
             see {} and {} (magenta = mismatch); UPDATE_GOLDEN=1 rewrites the golden",
            100.0 * fraction,
            tolerance.max_channel_diff,
            100.0 * tolerance.min_matching_fraction,
            actual_path.display(),
            diff_path.display()
        );
    }
}
