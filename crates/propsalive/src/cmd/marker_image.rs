//! `propsalive marker --image PICTURE --width-mm W [--dpi D] [--margin-mm M] --out STEM`: a
//! picture printed at true size (`pa_overlay::sheet_image`): `STEM.svg` at physical size
//! (the picture embedded) and `STEM.png` at `--dpi` (DPI in `pHYs`), each with a thin scale
//! bar and the width on the margin; written atomically, never over existing files without
//! `--force`.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use pa_overlay::sheet_image::{picture_png, picture_raster, picture_svg, PictureSheet};

/// The files of `--out` for a picture: a stem, a `.png`/`.svg` path (extension dropped) or a
/// folder (the picture's stem is used).
fn outputs(out: &Path, picture: &Path, force: bool) -> Result<(PathBuf, PathBuf)> {
    let name = picture
        .file_stem()
        .map_or_else(|| "picture".into(), |s| s.to_string_lossy().into_owned());
    let (png, svg) = super::marker::output_pair(out, &format!("{name}_print"), force)?;
    for p in [&png, &svg] {
        if p == picture {
            anyhow::bail!(
                "{} is the picture itself; choose another --out",
                p.display()
            );
        }
    }
    Ok((png, svg))
}

/// Prints `picture` `width_mm` wide.
pub fn run(
    picture: &Path,
    width_mm: f64,
    dpi: f64,
    margin_mm: f64,
    out: &Path,
    force: bool,
) -> Result<()> {
    let img = pa_video::still::read_still(picture, &Default::default())
        .with_context(|| format!("picture {}", picture.display()))?
        .to_rgba8();
    let name = picture
        .file_name()
        .map_or_else(|| "picture".into(), |n| n.to_string_lossy().into_owned());
    let sheet = PictureSheet::new(img.dimensions(), width_mm, dpi, margin_mm, &name)
        .with_context(|| format!("picture {}", picture.display()))?;
    let (png_path, svg_path) = outputs(out, picture, force)?;
    let raster = picture_raster(&sheet, &img);
    let png = picture_png(&sheet, &raster)?;
    // The SVG embeds the picture as it is (its own pixels, re-encoded as PNG).
    let mut own = Vec::new();
    image::DynamicImage::ImageRgba8(img)
        .write_to(&mut std::io::Cursor::new(&mut own), image::ImageFormat::Png)
        .with_context(|| format!("encoding {}", picture.display()))?;
    for p in [&png_path, &svg_path] {
        if let Some(dir) = p.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir)
                .with_context(|| format!("creating folder {}", dir.display()))?;
        }
    }
    pa_model::export::write_atomic(&png_path, &png)
        .with_context(|| format!("writing {}", png_path.display()))?;
    pa_model::export::write_atomic(&svg_path, picture_svg(&sheet, &own).as_bytes())
        .with_context(|| format!("writing {}", svg_path.display()))?;
    outln!("{}", sheet.label);
    outln!(
        "wrote {} ({:.1} x {:.1} mm) and {} at {} dpi ({}x{} px); check the {} mm bar with a ruler after printing",
        svg_path.display(),
        sheet.page_w_mm,
        sheet.page_h_mm,
        png_path.display(),
        sheet.dpi,
        raster.width(),
        raster.height(),
        sheet.bar_mm
    );
    Ok(())
}
