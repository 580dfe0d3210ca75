//! Golden-image comparison shared by the rendering tests.
//!
//! Tolerance: a pixel matches when every channel differs by at most `max_channel_diff`/255,
//! and at least `min_matching_fraction` of the pixels must match ([`Tolerance::DEFAULT`]:
//! 2/255 on 99.5 %). `UPDATE_GOLDEN=1` (re)writes the golden instead of comparing. A failure
//! writes `<target>/golden-failures/<name>.actual.png` and `<name>.diff.png` (magenta =
//! mismatch) and names them in the panic message.
//!
//! Goldens are drawn on the software rasterisers CI has (Mesa llvmpipe / lavapipe). A hardware
//! GPU filters textures a little differently (seen on an NVIDIA H200: 98.5-99.4 % of pixels
//! within 2/255, worst 13-39, on the board's tags and the texture's cells), and the AR tests'
//! input frames are rendered on the same adapter. So a hardware adapter may have its own
//! goldens, `<golden_dir>/<vendor>/<name>.png` ([`Goldens::for_adapter`]), checked with the same
//! tolerance; where none exists the shared golden applies. On a hardware adapter,
//! `UPDATE_GOLDEN=1` writes the vendor's golden only where the shared one does not hold (and
//! removes it where the shared one now holds).

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

/// Where a test's goldens are read: the shared folder, and the adapter's own variant
/// (`None` on a software rasteriser).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Goldens {
    pub dir: PathBuf,
    pub variant: Option<String>,
}

impl Goldens {
    /// The goldens for an adapter described as `pa_render::Renderer::adapter_info` does (its
    /// name first): a hardware adapter's variant is the first word of its name, lower-cased
    /// ("NVIDIA H200 (Vulkan, ...)" -> `nvidia`).
    pub fn for_adapter(dir: PathBuf, adapter_info: &str, software: bool) -> Self {
        let variant = (!software)
            .then(|| adapter_info.split_whitespace().next())
            .flatten()
            .map(|w| {
                w.chars()
                    .filter(|c| c.is_ascii_alphanumeric())
                    .collect::<String>()
                    .to_ascii_lowercase()
            })
            .filter(|w| !w.is_empty());
        Self { dir, variant }
    }

    fn shared_path(&self, name: &str) -> PathBuf {
        self.dir.join(format!("{name}.png"))
    }

    fn variant_path(&self, name: &str) -> Option<PathBuf> {
        let v = self.variant.as_ref()?;
        Some(self.dir.join(v).join(format!("{name}.png")))
    }
}

/// How many pixels of `rgba8` are within `max_channel_diff` of `golden` (same size), the
/// worst channel difference, and the diff image (golden darkened; magenta = mismatch).
fn compare(rgba8: &[u8], golden: &[u8], max_channel_diff: u8) -> (usize, u8, Vec<u8>) {
    let mut diff = Vec::with_capacity(rgba8.len());
    let mut matching = 0usize;
    let mut worst = 0u8;
    for (a, g) in rgba8.chunks_exact(4).zip(golden.chunks_exact(4)) {
        let d = a
            .iter()
            .zip(g)
            .map(|(x, y)| x.abs_diff(*y))
            .max()
            .unwrap_or(0);
        worst = worst.max(d);
        if d <= max_channel_diff {
            matching += 1;
            diff.extend_from_slice(&[g[0] / 4, g[1] / 4, g[2] / 4, 255]);
        } else {
            diff.extend_from_slice(&[255, 0, 255, 255]);
        }
    }
    (matching, worst, diff)
}

/// Reads a golden as RGBA8 of the expected size.
fn read_golden(path: &Path, width: u32, height: u32) -> Result<Vec<u8>, String> {
    let img = image::open(path).map_err(|e| e.to_string())?.to_rgba8();
    if (img.width(), img.height()) != (width, height) {
        return Err(format!(
            "{}x{}, expected {width}x{height}",
            img.width(),
            img.height()
        ));
    }
    Ok(img.into_raw())
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

/// Compares an RGBA8 image with its golden in `goldens`: the variant's where one exists, else
/// the shared one (see the module docs).
pub fn assert_golden_in(
    goldens: &Goldens,
    name: &str,
    width: u32,
    height: u32,
    rgba8: &[u8],
    tolerance: Tolerance,
) {
    let total = (width as usize * height as usize).max(1);
    let holds = |golden: &[u8]| {
        let (matching, worst, diff) = compare(rgba8, golden, tolerance.max_channel_diff);
        let fraction = matching as f64 / total as f64;
        (
            fraction >= tolerance.min_matching_fraction,
            fraction,
            worst,
            diff,
        )
    };
    let shared = goldens.shared_path(name);
    let variant = goldens.variant_path(name);
    if std::env::var("UPDATE_GOLDEN").is_ok_and(|v| v == "1") {
        // A variant is written only where the shared golden does not hold for this adapter.
        let target = match &variant {
            Some(v) => match read_golden(&shared, width, height) {
                Ok(g) if holds(&g).0 => {
                    // A variant left from before would still be read: it goes.
                    let removed = std::fs::remove_file(v).is_ok();
                    eprintln!(
                        "golden {name}: the shared golden holds on this adapter; no {} {}",
                        v.display(),
                        if removed { "(removed)" } else { "written" }
                    );
                    return;
                }
                _ => v.clone(),
            },
            None => shared,
        };
        save_png(&target, width, height, rgba8);
        eprintln!("wrote golden {}", target.display());
        return;
    }
    let path = match variant {
        Some(v) if v.exists() => v,
        _ => shared,
    };
    let failures = target_dir().join("golden-failures");
    let _ = std::fs::create_dir_all(&failures);
    let failures = failures.canonicalize().unwrap_or(failures);
    let actual_path = failures.join(format!("{name}.actual.png"));
    let diff_path = failures.join(format!("{name}.diff.png"));
    let golden = match read_golden(&path, width, height) {
        Ok(g) => g,
        Err(e) => {
            save_png(&actual_path, width, height, rgba8);
            panic!(
                "golden {} unreadable ({e}); actual written to {}; run with UPDATE_GOLDEN=1 to create it",
                path.display(),
                actual_path.display()
            );
        }
    };
    let (ok, fraction, worst, diff) = holds(&golden);
    eprintln!(
        "golden {name} ({}): {:.3}% of pixels within {}/255 (worst {worst})",
        path.display(),
        100.0 * fraction,
        tolerance.max_channel_diff
    );
    if !ok {
        save_png(&actual_path, width, height, rgba8);
        save_png(&diff_path, width, height, &diff);
        panic!(
            "golden {name}: only {:.3}% of pixels within {}/255 of {} (need {:.1}%, worst diff \
             {worst}); see {} and {} (magenta = mismatch); UPDATE_GOLDEN=1 rewrites the golden",
            100.0 * fraction,
            tolerance.max_channel_diff,
            path.display(),
            100.0 * tolerance.min_matching_fraction,
            actual_path.display(),
            diff_path.display()
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(test: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("pa-testkit-{test}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).expect("scratch dir");
        dir
    }

    #[test]
    fn a_hardware_adapter_names_its_vendor_and_a_software_one_none() {
        let nvidia = "NVIDIA H200 (Vulkan, DiscreteGpu, NVIDIA 580.159.04)";
        let g = Goldens::for_adapter(PathBuf::from("g"), nvidia, false);
        assert_eq!(g.variant.as_deref(), Some("nvidia"));
        let llvmpipe = "llvmpipe (LLVM 15.0.6, 256 bits) (Gl, Cpu, 4.5 (Core Profile) Mesa 22.3.6)";
        assert_eq!(
            Goldens::for_adapter(PathBuf::from("g"), llvmpipe, true).variant,
            None
        );
        assert_eq!(
            Goldens::for_adapter(PathBuf::from("g"), "", false).variant,
            None
        );
    }

    #[test]
    fn the_variant_golden_is_read_where_it_exists_and_the_shared_one_elsewhere() {
        let dir = scratch("variant");
        let (grey, white) = ([128u8, 128, 128, 255].repeat(4), [255u8; 16].to_vec());
        save_png(&dir.join("probe_a.png"), 2, 2, &grey);
        save_png(&dir.join("nvidia/probe_a.png"), 2, 2, &white);
        save_png(&dir.join("probe_b.png"), 2, 2, &white);
        let g = Goldens::for_adapter(dir.clone(), "NVIDIA H200", false);
        // `a` has a variant (white): white passes, grey (the shared golden) fails.
        assert_golden_in(&g, "probe_a", 2, 2, &white, Tolerance::DEFAULT);
        let grey_fails = std::panic::catch_unwind(|| {
            assert_golden_in(&g, "probe_a", 2, 2, &grey, Tolerance::DEFAULT);
        });
        assert!(
            grey_fails.is_err(),
            "the variant golden must be the one read"
        );
        // `b` has none: the shared golden applies, also to the software adapter.
        assert_golden_in(&g, "probe_b", 2, 2, &white, Tolerance::DEFAULT);
        let software = Goldens::for_adapter(dir.clone(), "llvmpipe", true);
        assert_golden_in(&software, "probe_a", 2, 2, &grey, Tolerance::DEFAULT);
        let _ = std::fs::remove_dir_all(&dir);
    }
}
