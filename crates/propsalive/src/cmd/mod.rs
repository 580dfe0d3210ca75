//! One module per subcommand; each has `Args` (raw flags) and `run`.

pub mod bench;
pub mod calibrate;
pub mod demo;
pub mod eval;
pub mod export;
pub mod inspect;
pub mod marker;
pub mod marker_check;
pub mod marker_image;
pub mod new;
pub mod preview;
pub mod register;
pub mod render;
pub mod run;
pub mod track;

use std::path::Path;

use anyhow::{bail, Context, Result};

/// Parses `WIDTHxHEIGHT` (for example `1280x720`) with sane bounds.
pub fn parse_size(s: &str) -> Result<(u32, u32)> {
    let Some((w, h)) = s.split_once(['x', 'X']) else {
        bail!("size {s:?} must look like 1280x720");
    };
    let (w, h): (u32, u32) = (
        w.trim()
            .parse()
            .with_context(|| format!("size {s:?}: width"))?,
        h.trim()
            .parse()
            .with_context(|| format!("size {s:?}: height"))?,
    );
    if w == 0 || h == 0 || w > MAX_SIDE_PX || h > MAX_SIDE_PX || w as u64 * h as u64 > MAX_PIXELS {
        bail!(
            "size {w}x{h} is out of range: 1 to {MAX_SIDE_PX} pixels a side and at most {} Mpixel (8K UHD, 7680x4320, fits; a larger frame does not fit the renderer's read-back on a software adapter)",
            MAX_PIXELS / 1_000_000
        );
    }
    Ok((w, h))
}

/// The largest frame side a command renders, pixels.
pub const MAX_SIDE_PX: u32 = 8192;
/// The most pixels a command renders in one frame.
pub const MAX_PIXELS: u64 = 40_000_000;

/// Encodes RGBA8 as PNG and writes it atomically (temporary file, sync, rename).
pub fn write_png_atomic(path: &Path, width: u32, height: u32, rgba8: &[u8]) -> Result<()> {
    let img = image::RgbaImage::from_raw(width, height, rgba8.to_vec())
        .context("image buffer has the wrong size")?;
    let mut png = Vec::new();
    img.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)?;
    pa_model::export::write_atomic(path, &png)
        .with_context(|| format!("writing {}", path.display()))
}

/// `--board ROWSxCOLS`: rows and columns of at least 1 and at most 1000 tags in all (the
/// product is computed without overflow: `65536x65536` is refused, not wrapped to 0).
pub(crate) fn parse_grid(s: &str) -> Result<(u32, u32)> {
    let Some((r, c)) = s.split_once(['x', 'X']) else {
        bail!("--board {s:?} must look like ROWSxCOLS, e.g. 2x3");
    };
    let r: u32 = r
        .trim()
        .parse()
        .with_context(|| format!("--board {s:?}: rows"))?;
    let c: u32 = c
        .trim()
        .parse()
        .with_context(|| format!("--board {s:?}: columns"))?;
    if r == 0 || c == 0 || r.checked_mul(c).is_none_or(|n| n > 1000) {
        bail!("--board {s:?}: rows and columns must be >= 1, with at most 1000 tags in all");
    }
    Ok((r, c))
}

#[cfg(test)]
mod tests {
    use super::parse_size;

    #[test]
    fn sizes() {
        assert_eq!(parse_size("1280x720").unwrap(), (1280, 720));
        assert!(parse_size("0x720").is_err());
        assert!(parse_size("1280").is_err());
        assert!(parse_size("99999x1").is_err());
        // Regression: `render --size 16384x16384` failed late with "GPU readback failed: Wait
        // timed out"; refused up front, naming the limit.
        let e = parse_size("16384x16384").expect_err("too large");
        assert!(e.to_string().contains("8192"), "{e}");
        assert!(parse_size("7680x4320").is_ok());
    }
}
