//! One module per subcommand; each has `Args` (raw flags) and `run`.

pub mod bench;
pub mod calibrate;
pub mod camera_export;
pub mod demo;
pub mod eval;
pub mod export;
pub mod inspect;
pub mod marker;
pub mod preview;
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
    let (w, h): (u32, u32) = (w.trim().parse()?, h.trim().parse()?);
    if w == 0 || h == 0 || w > 16384 || h > 16384 {
        bail!("size {w}x{h} is out of range (1..=16384 a side)");
    }
    Ok((w, h))
}

/// Encodes RGBA8 as PNG and writes it atomically (temporary file, sync, rename).
pub fn write_png_atomic(path: &Path, width: u32, height: u32, rgba8: &[u8]) -> Result<()> {
    let img = image::RgbaImage::from_raw(width, height, rgba8.to_vec())
        .context("image buffer has the wrong size")?;
    let mut png = Vec::new();
    img.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)?;
    pa_model::export::write_atomic(path, &png)
        .with_context(|| format!("writing {}", path.display()))
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
    }
}
