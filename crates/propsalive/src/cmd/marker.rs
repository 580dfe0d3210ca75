//! `propsalive marker --family tag36h11 --id 0 --size-mm 80 [--dpi 300] --out STEM_OR_DIR`:
//! a printable marker (or, with `--board ROWSxCOLS --gap-mm G --first-id N`, a board of
//! tags laid out exactly as [`pa_track::Board::grid`] expects).
//!
//! Two files are written, atomically and never over existing ones without `--force`:
//! - `STEM.svg` at true physical size (`width`/`height` in `mm`, `viewBox` in mm), with the
//!   family, ids, tag size and a "print at 100 %" note as `<text>` in the bottom margin;
//! - `STEM.png` rasterised at `--dpi`, with the DPI stored in its `pHYs` chunk (so image
//!   viewers and print dialogs know the physical size). The PNG carries **no visible text**
//!   (no font is built in); the same label is stored in its `tEXt` metadata (`Title`,
//!   `Description`) and in the file name.
//!
//! The size given is the side of the tag's black border square, the quantity the tracker's
//! `--tag-size-m` means. Board tags are centred at `(c - (cols-1)/2, r - (rows-1)/2) *
//! (size + gap)` from the board centre, ids row-major from the top-left as printed.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use pa_track::{family_layout, marker_cells, TagFamily};

#[derive(clap::Args)]
pub struct Args {
    /// Tag family (tag36h11, tag25h9, tag16h5, tagStandard41h12, ...).
    #[arg(long, default_value = "tag36h11")]
    pub family: String,
    /// Tag id (single marker).
    #[arg(long, default_value_t = 0, conflicts_with = "board")]
    pub id: u32,
    /// Side of the tag's black border square in millimetres (what the tracker calls the
    /// tag size).
    #[arg(long)]
    pub size_mm: f64,
    /// Resolution of the PNG in dots per inch.
    #[arg(long, default_value_t = 300.0)]
    pub dpi: f64,
    /// A board of ROWSxCOLS tags instead of one tag.
    #[arg(long)]
    pub board: Option<String>,
    /// Gap between the black squares of neighbouring board tags, millimetres
    /// (default: two cells of the tag).
    #[arg(long, requires = "board")]
    pub gap_mm: Option<f64>,
    /// Id of the board's top-left tag; ids run row-major.
    #[arg(long, default_value_t = 0, requires = "board")]
    pub first_id: u32,
    /// White margin around the tag(s) in millimetres (the label goes in the bottom margin).
    #[arg(long, default_value_t = 10.0)]
    pub margin_mm: f64,
    /// Output: a file stem (`out/tag0` gives out/tag0.png and out/tag0.svg; a .png or .svg
    /// extension is dropped) or an existing folder (or a path ending in `/`), in which a name
    /// is made from the family, ids and size.
    #[arg(long, short)]
    pub out: PathBuf,
    /// Replace output files that exist.
    #[arg(long)]
    pub force: bool,
}

/// A black rectangle on the page, millimetres from the page's top-left corner.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RectMm {
    pub x: f64,
    pub y: f64,
    pub w: f64,
    pub h: f64,
}

/// The resolved layout of a marker sheet.
#[derive(Debug, Clone)]
pub struct Sheet {
    pub family: TagFamily,
    pub ids: Vec<u32>,
    pub rows: u32,
    pub cols: u32,
    pub size_mm: f64,
    pub gap_mm: f64,
    pub dpi: f64,
    pub page_w_mm: f64,
    pub page_h_mm: f64,
    /// Centre of the board (the marker origin) on the page, mm.
    pub origin_mm: (f64, f64),
    pub black: Vec<RectMm>,
    pub label: Vec<String>,
    pub png: PathBuf,
    pub svg: PathBuf,
}

/// Resolves and checks the flags (nothing is written).
pub fn resolve(args: &Args) -> Result<Sheet> {
    let family: TagFamily = args.family.parse()?;
    let layout = family_layout(family)?;
    if !(args.size_mm.is_finite() && args.size_mm > 0.0 && args.size_mm <= 5000.0) {
        bail!("--size-mm must be in (0, 5000], got {}", args.size_mm);
    }
    if !(args.dpi.is_finite() && (10.0..=4800.0).contains(&args.dpi)) {
        bail!("--dpi must be in [10, 4800], got {}", args.dpi);
    }
    if !(args.margin_mm.is_finite() && args.margin_mm >= 0.0 && args.margin_mm <= 1000.0) {
        bail!("--margin-mm must be in [0, 1000], got {}", args.margin_mm);
    }
    let cell_mm = args.size_mm / layout.border_cells as f64;
    let px_per_mm = args.dpi / 25.4;
    if cell_mm * px_per_mm < 2.0 {
        bail!(
            "a {} mm {family} tag has {cell_mm:.2} mm cells, under 2 pixels at {} dpi; raise --dpi or --size-mm",
            args.size_mm,
            args.dpi
        );
    }
    let (rows, cols) = match &args.board {
        Some(b) => super::parse_grid(b)?,
        None => (1, 1),
    };
    let first_id = if args.board.is_some() {
        args.first_id
    } else {
        args.id
    };
    let count = rows * cols;
    if first_id
        .checked_add(count - 1)
        .is_none_or(|last| last >= layout.id_count)
    {
        bail!(
            "{family} has ids 0..{}; ids {first_id}..{} do not fit",
            layout.id_count,
            first_id as u64 + count as u64
        );
    }
    let ids: Vec<u32> = (first_id..first_id + count).collect();

    // Black cells of each tag, and how far its drawing reaches beyond the black border square.
    let cells: Vec<_> = ids
        .iter()
        .map(|&id| marker_cells(family, id))
        .collect::<Result<_, _>>()?;
    let n = layout.total_cells;
    let off = (n - layout.border_cells) as f64 / 2.0; // cells from image edge to border square
                                                      // White rings around the canonical image count as quiet zone.
    let quiet = (0..n / 2)
        .take_while(|&k| {
            cells.iter().all(|c| {
                (k..n - k).all(|i| {
                    [(i, k), (i, n - 1 - k), (k, i), (n - 1 - k, i)]
                        .iter()
                        .all(|&(x, y)| c.data[(y * n + x) as usize] == 255)
                })
            })
        })
        .count() as f64;
    let reach_cells = off - quiet; // drawn cells beyond the border square, each side
    let min_gap_mm = (2.0 * reach_cells + 1.0) * cell_mm;
    let gap_mm = match args.gap_mm {
        Some(g) => g,
        None => (2.0 * reach_cells + 2.0) * cell_mm,
    };
    if args.board.is_some() && !(gap_mm.is_finite() && gap_mm >= min_gap_mm - 1e-9) {
        bail!(
            "--gap-mm {gap_mm} is too small: {family} tags of {} mm need at least {min_gap_mm:.2} mm between their black squares (one white cell)",
            args.size_mm
        );
    }
    let pitch = args.size_mm + gap_mm;
    let reach_mm = reach_cells * cell_mm;
    // Content: the black squares of the grid plus what is drawn beyond them, plus one cell of
    // quiet zone that the margin must not eat into.
    let content_w = cols as f64 * args.size_mm + (cols - 1) as f64 * gap_mm + 2.0 * reach_mm;
    let content_h = rows as f64 * args.size_mm + (rows - 1) as f64 * gap_mm + 2.0 * reach_mm;
    let margin = args.margin_mm.max(cell_mm);
    let label_h = 12.0;
    let page_w_mm = content_w + 2.0 * margin;
    let page_h_mm = content_h + 2.0 * margin + label_h;
    let origin_mm = (margin + content_w / 2.0, margin + content_h / 2.0);

    let mut black = Vec::new();
    for (k, c) in cells.iter().enumerate() {
        let (r, col) = (k as u32 / cols, k as u32 % cols);
        let cx = origin_mm.0 + (col as f64 - (cols - 1) as f64 * 0.5) * pitch;
        let cy = origin_mm.1 + (r as f64 - (rows - 1) as f64 * 0.5) * pitch;
        // Top-left of the canonical image.
        let x0 = cx - args.size_mm / 2.0 - off * cell_mm;
        let y0 = cy - args.size_mm / 2.0 - off * cell_mm;
        for y in 0..n {
            let mut x = 0;
            while x < n {
                if c.data[(y * n + x) as usize] != 0 {
                    x += 1;
                    continue;
                }
                let start = x;
                while x < n && c.data[(y * n + x) as usize] == 0 {
                    x += 1;
                }
                black.push(RectMm {
                    x: x0 + start as f64 * cell_mm,
                    y: y0 + y as f64 * cell_mm,
                    w: (x - start) as f64 * cell_mm,
                    h: cell_mm,
                });
            }
        }
    }

    let mm = |v: f64| format!("{}", (v * 1000.0).round() / 1000.0);
    let mut label = Vec::new();
    if count == 1 {
        label.push(format!("{family} id {}", ids[0]));
    } else {
        label.push(format!(
            "{family} board {rows}x{cols}, ids {}..{} row-major from top-left",
            ids[0],
            ids[ids.len() - 1]
        ));
    }
    let mut line2 = format!("tag size {} mm (black square)", mm(args.size_mm));
    if count > 1 {
        line2.push_str(&format!(", gap {} mm", mm(gap_mm)));
    }
    line2.push_str(" - print at 100 %, measure the black square");
    label.push(line2);

    let stem_name = if count == 1 {
        format!("{family}_id{}_{}mm", ids[0], mm(args.size_mm))
    } else {
        format!(
            "{family}_board{rows}x{cols}_id{}_{}mm_gap{}mm",
            ids[0],
            mm(args.size_mm),
            mm(gap_mm)
        )
    };
    let out_str = args.out.to_string_lossy();
    let stem = if args.out.is_dir() || out_str.ends_with('/') || out_str.ends_with('\\') {
        args.out.join(stem_name)
    } else {
        match args.out.extension().and_then(|e| e.to_str()) {
            Some(e) if e.eq_ignore_ascii_case("png") || e.eq_ignore_ascii_case("svg") => {
                args.out.with_extension("")
            }
            _ => args.out.clone(),
        }
    };
    let with_ext = |ext: &str| {
        let mut s = stem.clone().into_os_string();
        s.push(".");
        s.push(ext);
        PathBuf::from(s)
    };
    let (png, svg) = (with_ext("png"), with_ext("svg"));
    for p in [&png, &svg] {
        if p.exists() && !args.force {
            bail!("{} exists; pass --force to replace it", p.display());
        }
    }
    let (wpx, hpx) = (page_w_mm * px_per_mm, page_h_mm * px_per_mm);
    if wpx * hpx > 400e6 {
        bail!("the PNG would be {wpx:.0}x{hpx:.0} pixels; lower --dpi");
    }
    Ok(Sheet {
        family,
        ids,
        rows,
        cols,
        size_mm: args.size_mm,
        gap_mm,
        dpi: args.dpi,
        page_w_mm,
        page_h_mm,
        origin_mm,
        black,
        label,
        png,
        svg,
    })
}

fn xml_escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

/// The SVG document, in millimetres.
pub fn svg(sheet: &Sheet) -> String {
    let f = |v: f64| format!("{:.4}", v);
    let mut s = String::new();
    s.push_str("<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n");
    s.push_str(&format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{w}mm\" height=\"{h}mm\" viewBox=\"0 0 {w} {h}\">\n",
        w = f(sheet.page_w_mm),
        h = f(sheet.page_h_mm)
    ));
    s.push_str(&format!("<title>{}</title>\n", xml_escape(&sheet.label[0])));
    s.push_str(&format!(
        "<rect x=\"0\" y=\"0\" width=\"{}\" height=\"{}\" fill=\"#ffffff\"/>\n",
        f(sheet.page_w_mm),
        f(sheet.page_h_mm)
    ));
    s.push_str("<g fill=\"#000000\" shape-rendering=\"crispEdges\">\n");
    for r in &sheet.black {
        s.push_str(&format!(
            "<rect x=\"{}\" y=\"{}\" width=\"{}\" height=\"{}\"/>\n",
            f(r.x),
            f(r.y),
            f(r.w),
            f(r.h)
        ));
    }
    s.push_str("</g>\n");
    let base = sheet.page_h_mm - 12.0 + 4.0;
    for (i, line) in sheet.label.iter().enumerate() {
        s.push_str(&format!(
            "<text x=\"{}\" y=\"{}\" font-family=\"sans-serif\" font-size=\"3.5\" fill=\"#000000\">{}</text>\n",
            f(sheet.page_w_mm.clamp(2.0, 10.0)),
            f(base + i as f64 * 5.0),
            xml_escape(line)
        ));
    }
    s.push_str("</svg>\n");
    s
}

/// The page rasterised at the sheet's DPI (8-bit grey): a pixel is black when its centre lies
/// in a black rectangle.
pub fn raster(sheet: &Sheet) -> image::GrayImage {
    let ppm = sheet.dpi / 25.4;
    let w = (sheet.page_w_mm * ppm).round().max(1.0) as u32;
    let h = (sheet.page_h_mm * ppm).round().max(1.0) as u32;
    let mut img = image::GrayImage::from_pixel(w, h, image::Luma([255]));
    // Pixel i is covered by [a, b) mm when its centre (i + 0.5) / ppm is in it.
    let span = |a: f64, b: f64, n: u32| {
        let lo = ((a * ppm - 0.5).ceil().max(0.0) as u32).min(n);
        let hi = ((b * ppm - 0.5).ceil().max(0.0) as u32).min(n);
        lo..hi
    };
    for r in &sheet.black {
        for y in span(r.y, r.y + r.h, h) {
            for x in span(r.x, r.x + r.w, w) {
                img.put_pixel(x, y, image::Luma([0]));
            }
        }
    }
    img
}

fn crc32(bytes: &[u8]) -> u32 {
    let mut crc = 0xffff_ffffu32;
    for &b in bytes {
        crc ^= b as u32;
        for _ in 0..8 {
            crc = if crc & 1 != 0 {
                (crc >> 1) ^ 0xedb8_8320
            } else {
                crc >> 1
            };
        }
    }
    !crc
}

fn png_chunk(kind: &[u8; 4], data: &[u8]) -> Vec<u8> {
    let mut c = Vec::with_capacity(12 + data.len());
    c.extend_from_slice(&(data.len() as u32).to_be_bytes());
    c.extend_from_slice(kind);
    c.extend_from_slice(data);
    c.extend_from_slice(&crc32(&c[4..]).to_be_bytes());
    c
}

/// Encodes a grey image as PNG with its DPI in a `pHYs` chunk and `tEXt` metadata.
pub fn encode_png(img: &image::GrayImage, dpi: f64, text: &[(&str, &str)]) -> Result<Vec<u8>> {
    let mut png = Vec::new();
    img.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)?;
    // The signature (8 bytes) and IHDR (4 + 4 + 13 + 4) come first; insert after IHDR.
    if png.len() < 33 || &png[12..16] != b"IHDR" {
        bail!("unexpected PNG layout from the encoder");
    }
    let ppm = (dpi / 0.0254).round() as u32;
    let mut phys = Vec::with_capacity(9);
    phys.extend_from_slice(&ppm.to_be_bytes());
    phys.extend_from_slice(&ppm.to_be_bytes());
    phys.push(1); // unit: metre
    let mut out = png[..33].to_vec();
    out.extend(png_chunk(b"pHYs", &phys));
    for (k, v) in text {
        let mut t = Vec::new();
        t.extend_from_slice(k.as_bytes());
        t.push(0);
        t.extend(v.chars().map(|c| if c.is_ascii() { c as u8 } else { b'?' }));
        out.extend(png_chunk(b"tEXt", &t));
    }
    out.extend_from_slice(&png[33..]);
    Ok(out)
}

fn write_sheet(sheet: &Sheet) -> Result<()> {
    for p in [&sheet.png, &sheet.svg] {
        if let Some(dir) = p.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir)
                .with_context(|| format!("creating folder {}", dir.display()))?;
        }
    }
    let img = raster(sheet);
    let label = sheet.label.join("; ");
    let png = encode_png(
        &img,
        sheet.dpi,
        &[
            ("Title", sheet.label[0].as_str()),
            ("Description", label.as_str()),
            ("Software", "propsalive marker"),
        ],
    )?;
    pa_model::export::write_atomic(&sheet.png, &png)
        .with_context(|| format!("writing {}", sheet.png.display()))?;
    pa_model::export::write_atomic(&sheet.svg, svg(sheet).as_bytes())
        .with_context(|| format!("writing {}", sheet.svg.display()))?;
    Ok(())
}

fn describe(sheet: &Sheet, path: &Path) -> String {
    path.display().to_string() + &format!(" ({:.1} x {:.1} mm)", sheet.page_w_mm, sheet.page_h_mm)
}

pub fn run(args: Args) -> Result<()> {
    let sheet = resolve(&args)?;
    write_sheet(&sheet)?;
    let img_w = (sheet.page_w_mm * sheet.dpi / 25.4).round();
    let img_h = (sheet.page_h_mm * sheet.dpi / 25.4).round();
    outln!("{}", sheet.label.join("\n"));
    outln!(
        "marker origin (centre of the {}) at ({:.3}, {:.3}) mm from the page's top-left; +X right, +Y down the page",
        if sheet.ids.len() > 1 { "board" } else { "tag" },
        sheet.origin_mm.0,
        sheet.origin_mm.1
    );
    outln!(
        "wrote {} and {} at {} dpi ({img_w}x{img_h} px)",
        describe(&sheet, &sheet.svg),
        sheet.png.display(),
        sheet.dpi
    );
    if sheet.ids.len() > 1 {
        outln!(
            "track it with: propsalive track INPUT --tag-size-m {} --family {} --board {}x{} --gap-m {} --first-id {}",
            sheet.size_mm / 1000.0,
            sheet.family,
            sheet.rows,
            sheet.cols,
            sheet.gap_mm / 1000.0,
            sheet.ids[0]
        );
    } else {
        outln!(
            "track it with: propsalive track INPUT --tag-size-m {} --family {} --id {}",
            sheet.size_mm / 1000.0,
            sheet.family,
            sheet.ids[0]
        );
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn crc_matches_the_png_spec_example() {
        // CRC of "IEND" with no data.
        assert_eq!(crc32(b"IEND"), 0xae42_6082);
    }
}
