//! Printable marker sheets: one tag or a board of tags laid out exactly as
//! [`pa_track::Board::grid`] expects, as an SVG at true physical size and a PNG rasterised at a
//! given DPI (the DPI in its `pHYs` chunk, the label in `tEXt` metadata). Pure: the caller
//! (`propsalive marker`) chooses the file names and writes the bytes.
//!
//! The size given is the side of the tag's black border square, the quantity the tracker's
//! `--tag-size-m` means. Board tags are centred at `(c - (cols-1)/2, r - (rows-1)/2) *
//! (size + gap)` from the board centre, ids row-major from the top-left as printed. The SVG has
//! the family, ids, tag size and a "print at 100 %" note as `<text>` in the bottom margin; the
//! PNG carries no visible text (no font is built in).
//!
//! Checks name the `propsalive marker` flags they come from (`--size-mm`, `--dpi`, ...).

use pa_track::{family_layout, marker_cells, FamilyLayout, TagFamily};

use crate::OverlayError;

/// A black rectangle on the page, millimetres from the page's top-left corner.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RectMm {
    pub x: f64,
    pub y: f64,
    pub w: f64,
    pub h: f64,
}

/// The checked scale of a sheet: the tag family, the tag size, the PNG's resolution and the
/// margin. [`SheetScale::layout`] lays out the tags.
#[derive(Debug, Clone, Copy)]
pub struct SheetScale {
    pub family: TagFamily,
    pub layout: FamilyLayout,
    /// Side of the tag's black border square, mm.
    pub size_mm: f64,
    /// Resolution of the PNG, dots per inch.
    pub dpi: f64,
    /// White margin around the tag(s), mm (the label goes in the bottom margin).
    pub margin_mm: f64,
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
    /// A file name (without extension) made from the family, ids and sizes.
    pub file_stem: String,
}

impl SheetScale {
    /// Checks the sizes (`size_mm` in (0, 5000], `dpi` in [10, 4800], `margin_mm` in
    /// [0, 1000], and cells of at least 2 pixels).
    pub fn new(
        family: TagFamily,
        size_mm: f64,
        dpi: f64,
        margin_mm: f64,
    ) -> Result<Self, OverlayError> {
        let layout = family_layout(family)?;
        if !(size_mm.is_finite() && size_mm > 0.0 && size_mm <= 5000.0) {
            return Err(OverlayError::SizeOutOfRange { size_mm });
        }
        if !(dpi.is_finite() && (10.0..=4800.0).contains(&dpi)) {
            return Err(OverlayError::DpiOutOfRange { dpi });
        }
        if !(margin_mm.is_finite() && (0.0..=1000.0).contains(&margin_mm)) {
            return Err(OverlayError::MarginOutOfRange { margin_mm });
        }
        let cell_mm = size_mm / layout.border_cells as f64;
        let px_per_mm = dpi / 25.4;
        if cell_mm * px_per_mm < 2.0 {
            return Err(OverlayError::CellsTooSmall {
                family,
                size_mm,
                cell_mm,
                dpi,
            });
        }
        Ok(Self {
            family,
            layout,
            size_mm,
            dpi,
            margin_mm,
        })
    }

    /// Lays out one tag (`board` None: the tag `first_id`) or a board of `rows x cols` tags
    /// with ids from `first_id` row-major, `gap_mm` apart (default: two cells of the tag).
    pub fn layout(
        &self,
        board: Option<(u32, u32)>,
        first_id: u32,
        gap_mm: Option<f64>,
    ) -> Result<Sheet, OverlayError> {
        let family = self.family;
        let cell_mm = self.size_mm / self.layout.border_cells as f64;
        let (rows, cols) = board.unwrap_or((1, 1));
        if rows == 0 || cols == 0 || rows.checked_mul(cols).is_none() {
            return Err(OverlayError::EmptyBoard { rows, cols });
        }
        let count = rows * cols;
        if first_id
            .checked_add(count - 1)
            .is_none_or(|last| last >= self.layout.id_count)
        {
            return Err(OverlayError::IdsOutOfRange {
                family,
                id_count: self.layout.id_count,
                first_id,
                end: first_id as u64 + count as u64,
            });
        }
        let ids: Vec<u32> = (first_id..first_id + count).collect();

        // Black cells of each tag, and how far its drawing reaches beyond the black border square.
        let cells: Vec<_> = ids
            .iter()
            .map(|&id| marker_cells(family, id))
            .collect::<Result<_, _>>()?;
        let n = self.layout.total_cells;
        // Cells from the image edge to the border square.
        let off = (n - self.layout.border_cells) as f64 / 2.0;
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
        let gap_mm = match gap_mm {
            Some(g) => g,
            None => (2.0 * reach_cells + 2.0) * cell_mm,
        };
        if board.is_some() && !(gap_mm.is_finite() && gap_mm >= min_gap_mm - 1e-9) {
            return Err(OverlayError::GapTooSmall {
                gap_mm,
                family,
                size_mm: self.size_mm,
                min_gap_mm,
            });
        }
        let pitch = self.size_mm + gap_mm;
        let reach_mm = reach_cells * cell_mm;
        // Content: the black squares of the grid plus what is drawn beyond them, plus one cell of
        // quiet zone that the margin must not eat into.
        let content_w = cols as f64 * self.size_mm + (cols - 1) as f64 * gap_mm + 2.0 * reach_mm;
        let content_h = rows as f64 * self.size_mm + (rows - 1) as f64 * gap_mm + 2.0 * reach_mm;
        let margin = self.margin_mm.max(cell_mm);
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
            let x0 = cx - self.size_mm / 2.0 - off * cell_mm;
            let y0 = cy - self.size_mm / 2.0 - off * cell_mm;
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
        let mut line2 = format!("tag size {} mm (black square)", mm(self.size_mm));
        if count > 1 {
            line2.push_str(&format!(", gap {} mm", mm(gap_mm)));
        }
        line2.push_str(" - print at 100 %, measure the black square");
        label.push(line2);

        let file_stem = if count == 1 {
            format!("{family}_id{}_{}mm", ids[0], mm(self.size_mm))
        } else {
            format!(
                "{family}_board{rows}x{cols}_id{}_{}mm_gap{}mm",
                ids[0],
                mm(self.size_mm),
                mm(gap_mm)
            )
        };
        Ok(Sheet {
            family,
            ids,
            rows,
            cols,
            size_mm: self.size_mm,
            gap_mm,
            dpi: self.dpi,
            page_w_mm,
            page_h_mm,
            origin_mm,
            black,
            label,
            file_stem,
        })
    }
}

impl Sheet {
    /// Refuses a PNG of more than 400 million pixels.
    pub fn check_png_size(&self) -> Result<(), OverlayError> {
        let px_per_mm = self.dpi / 25.4;
        let (wpx, hpx) = (self.page_w_mm * px_per_mm, self.page_h_mm * px_per_mm);
        if wpx * hpx > 400e6 {
            return Err(OverlayError::PngTooLarge {
                width_px: wpx,
                height_px: hpx,
            });
        }
        Ok(())
    }
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
pub fn encode_png(
    img: &image::GrayImage,
    dpi: f64,
    text: &[(&str, &str)],
) -> Result<Vec<u8>, OverlayError> {
    let mut png = Vec::new();
    img.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)?;
    // The signature (8 bytes) and IHDR (4 + 4 + 13 + 4) come first; insert after IHDR.
    if png.len() < 33 || &png[12..16] != b"IHDR" {
        return Err(OverlayError::PngLayout);
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn crc_matches_the_png_spec_example() {
        // CRC of "IEND" with no data.
        assert_eq!(crc32(b"IEND"), 0xae42_6082);
    }
}
