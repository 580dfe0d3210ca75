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
//! A shot's board ([`SheetScale::layout_tags`]: tags anywhere, each of its own size) may carry
//! the footprints of its key props ([`Footprint`]): the outline of where each touches the
//! table, its name and an arrow to its front, drawn in grey over the page (SVG and PNG, the
//! PNG's label in the 8x8 bitmap font of [`crate::draw`]), so that the animator stands the
//! print, and the prop on it, where the shot says.
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

/// One tag of a board by its centre, marker frame millimetres (+X right, +Y down the page).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TagAt {
    pub id: u32,
    pub center_mm: (f64, f64),
    /// Side of the tag's black border square, mm.
    pub size_mm: f64,
}

/// A key prop's contact with the table, to print: marker frame millimetres.
#[derive(Debug, Clone, PartialEq)]
pub struct Footprint {
    /// The key pose's name, printed beside the outline.
    pub name: String,
    /// The outline (a closed polygon; one or two points print as a dot or a line).
    pub outline_mm: Vec<(f64, f64)>,
    /// Where the front arrow starts (the outline's centre).
    pub centre_mm: (f64, f64),
    /// The prop's front on the table (unit; zero: no arrow).
    pub front: (f64, f64),
    /// The label's line below the outline (0, 1, ...: key props that stand in one place
    /// get a line each).
    pub label_line: u32,
}

/// Grey of the footprints on the page (visible on white and on a tag's black).
pub const FOOTPRINT_GREY: u8 = 128;
/// Width of a footprint's lines, mm.
pub const FOOTPRINT_LINE_MM: f64 = 0.5;

impl Footprint {
    /// The front arrow, marker mm: (tail, tip, the two ends of the head); `None` without a
    /// front. It runs from the centre to the outline (at least 8 mm), so that it lies under
    /// the prop and marks no tag the camera sees.
    pub fn arrow_mm(&self) -> Option<[(f64, f64); 4]> {
        let (fx, fy) = self.front;
        let len = (fx * fx + fy * fy).sqrt();
        if len.is_nan() || len <= 1e-9 {
            return None;
        }
        let (fx, fy) = (fx / len, fy / len);
        let (cx, cy) = self.centre_mm;
        let reach = self
            .outline_mm
            .iter()
            .map(|&(x, y)| (x - cx) * fx + (y - cy) * fy)
            .fold(0.0, f64::max);
        let l = reach.max(8.0);
        let tip = (cx + fx * l, cy + fy * l);
        let head = 4.0;
        let (bx, by) = (tip.0 - fx * head, tip.1 - fy * head);
        let (px, py) = (-fy * head * 0.6, fx * head * 0.6);
        Some([(cx, cy), tip, (bx + px, by + py), (bx - px, by - py)])
    }

    /// Where the label's top-left goes, marker mm: inside the outline (under the prop, so
    /// that it marks no tag the camera sees), centred above the centre (the arrow goes to the
    /// front), 5 mm higher per [`Footprint::label_line`].
    pub fn label_mm(&self) -> (f64, f64) {
        let chars = self.label().chars().count() as f64;
        (
            self.centre_mm.0 - 2.1 * chars,
            self.centre_mm.1 - 6.0 - 5.0 * f64::from(self.label_line),
        )
    }

    /// The printed label: `key NAME`.
    pub fn label(&self) -> String {
        format!("key {}", self.name)
    }

    /// Every point the footprint draws (outline, arrow, label box), marker mm.
    fn extent_mm(&self) -> Vec<(f64, f64)> {
        let mut pts = self.outline_mm.clone();
        pts.push(self.centre_mm);
        pts.extend(self.arrow_mm().into_iter().flatten());
        let (lx, ly) = self.label_mm();
        pts.push((lx, ly));
        pts.push((lx + 4.2 * self.label().chars().count() as f64, ly + 4.0));
        pts
    }
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
    /// Key props' footprints (marker frame; empty for a plain marker or grid).
    pub footprints: Vec<Footprint>,
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
        let (cells, off, reach_cells) = self.cells(&ids)?;
        let n = self.layout.total_cells;
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
            tag_rects(&c.data, n, (cx, cy), self.size_mm, off, cell_mm, &mut black);
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
            footprints: Vec::new(),
        })
    }

    /// The cells of each tag of `ids`, the cells from the image edge to the border square, and
    /// the cells drawn beyond the border square on each side (white rings around the canonical
    /// image count as quiet zone).
    #[allow(clippy::type_complexity)]
    fn cells(&self, ids: &[u32]) -> Result<(Vec<pa_track::GrayImage>, f64, f64), OverlayError> {
        let cells: Vec<_> = ids
            .iter()
            .map(|&id| marker_cells(self.family, id))
            .collect::<Result<_, _>>()?;
        let n = self.layout.total_cells;
        let off = (n - self.layout.border_cells) as f64 / 2.0;
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
        Ok((cells, off, off - quiet))
    }

    /// A board of tags anywhere (a shot's `[[marker.tags]]`: centres and sizes of its own,
    /// marker frame mm) with the key props' `footprints`; `title` is the label's first line.
    /// The scale's `size_mm` must be the smallest tag's (its cells are checked against the
    /// DPI); every tag must be an id of the family, appear once, and have a finite centre and
    /// a size in (0, 5000] mm.
    pub fn layout_tags(
        &self,
        tags: &[TagAt],
        footprints: Vec<Footprint>,
        title: &str,
    ) -> Result<Sheet, OverlayError> {
        let family = self.family;
        if tags.is_empty() {
            return Err(OverlayError::EmptyBoard { rows: 0, cols: 0 });
        }
        let ids: Vec<u32> = tags.iter().map(|t| t.id).collect();
        for t in tags {
            if !(t.size_mm.is_finite() && t.size_mm > 0.0 && t.size_mm <= 5000.0) {
                return Err(OverlayError::SizeOutOfRange { size_mm: t.size_mm });
            }
            if t.size_mm < self.size_mm - 1e-9 {
                return Err(OverlayError::SizeOutOfRange { size_mm: t.size_mm });
            }
            if t.id >= self.layout.id_count {
                return Err(OverlayError::IdsOutOfRange {
                    family,
                    id_count: self.layout.id_count,
                    first_id: t.id,
                    end: t.id as u64 + 1,
                });
            }
        }
        let (cells, off, reach_cells) = self.cells(&ids)?;
        let n = self.layout.total_cells;
        // Everything drawn, marker mm: each tag's reach, the footprints.
        let mut pts: Vec<(f64, f64)> = Vec::new();
        for t in tags {
            let half = t.size_mm / 2.0 + reach_cells * t.size_mm / self.layout.border_cells as f64;
            pts.push((t.center_mm.0 - half, t.center_mm.1 - half));
            pts.push((t.center_mm.0 + half, t.center_mm.1 + half));
        }
        for f in &footprints {
            pts.extend(f.extent_mm());
        }
        let (mut lo, mut hi) = (
            (f64::INFINITY, f64::INFINITY),
            (f64::NEG_INFINITY, f64::NEG_INFINITY),
        );
        for &(x, y) in &pts {
            if !(x.is_finite() && y.is_finite()) || x.abs() > 5e6 || y.abs() > 5e6 {
                return Err(OverlayError::SizeOutOfRange {
                    size_mm: x.abs().max(y.abs()),
                });
            }
            lo = (lo.0.min(x), lo.1.min(y));
            hi = (hi.0.max(x), hi.1.max(y));
        }
        let margin = self
            .margin_mm
            .max(self.size_mm / self.layout.border_cells as f64);
        let label_h = 12.0;
        let page_w_mm = hi.0 - lo.0 + 2.0 * margin;
        let page_h_mm = hi.1 - lo.1 + 2.0 * margin + label_h;
        let origin_mm = (margin - lo.0, margin - lo.1);
        let mut black = Vec::new();
        for (t, c) in tags.iter().zip(&cells) {
            let centre = (origin_mm.0 + t.center_mm.0, origin_mm.1 + t.center_mm.1);
            let cell_mm = t.size_mm / self.layout.border_cells as f64;
            tag_rects(&c.data, n, centre, t.size_mm, off, cell_mm, &mut black);
        }
        let mm = |v: f64| format!("{}", (v * 1000.0).round() / 1000.0);
        let sizes: Vec<String> = {
            let mut s: Vec<String> = tags.iter().map(|t| mm(t.size_mm)).collect();
            s.dedup();
            s
        };
        let mut line2 = format!(
            "{family}, {} tag{} ({} mm black squares)",
            tags.len(),
            if tags.len() == 1 { "" } else { "s" },
            sizes.join("/")
        );
        if !footprints.is_empty() {
            let names: Vec<&str> = footprints.iter().map(|f| f.name.as_str()).collect();
            line2.push_str(&format!(
                ", footprint of {} (arrow: front)",
                names.join(", ")
            ));
        }
        line2.push_str(" - print at 100 %");
        Ok(Sheet {
            family,
            ids,
            rows: 1,
            cols: tags.len() as u32,
            size_mm: self.size_mm,
            gap_mm: 0.0,
            dpi: self.dpi,
            page_w_mm,
            page_h_mm,
            origin_mm,
            black,
            label: vec![title.to_string(), line2],
            file_stem: format!("{family}_shot_{}tags", tags.len()),
            footprints,
        })
    }
}

/// The black rectangles of one tag's canonical image (`n` x `n` cells of `cell_mm`, `off`
/// cells from its edge to the border square), centred at `centre` on the page (mm).
fn tag_rects(
    data: &[u8],
    n: u32,
    centre: (f64, f64),
    size_mm: f64,
    off: f64,
    cell_mm: f64,
    black: &mut Vec<RectMm>,
) {
    // Top-left of the canonical image.
    let x0 = centre.0 - size_mm / 2.0 - off * cell_mm;
    let y0 = centre.1 - size_mm / 2.0 - off * cell_mm;
    for y in 0..n {
        let mut x = 0;
        while x < n {
            if data[(y * n + x) as usize] != 0 {
                x += 1;
                continue;
            }
            let start = x;
            while x < n && data[(y * n + x) as usize] == 0 {
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
    let page = |p: (f64, f64)| (sheet.origin_mm.0 + p.0, sheet.origin_mm.1 + p.1);
    let grey = format!("#{0:02x}{0:02x}{0:02x}", FOOTPRINT_GREY);
    for fp in &sheet.footprints {
        let pts: Vec<String> = fp
            .outline_mm
            .iter()
            .map(|&p| {
                let (x, y) = page(p);
                format!("{},{}", f(x), f(y))
            })
            .collect();
        s.push_str(&format!(
            "<polygon points=\"{}\" fill=\"none\" stroke=\"{grey}\" stroke-width=\"{}\" stroke-linejoin=\"round\"/>\n",
            pts.join(" "),
            f(FOOTPRINT_LINE_MM)
        ));
        if let Some([tail, tip, h1, h2]) = fp.arrow_mm() {
            let [tail, tip, h1, h2] = [tail, tip, h1, h2].map(page);
            s.push_str(&format!(
                "<path d=\"M {} {} L {} {} M {} {} L {} {} L {} {}\" fill=\"none\" stroke=\"{grey}\" stroke-width=\"{}\"/>\n",
                f(tail.0), f(tail.1), f(tip.0), f(tip.1),
                f(h1.0), f(h1.1), f(tip.0), f(tip.1), f(h2.0), f(h2.1),
                f(FOOTPRINT_LINE_MM)
            ));
        }
        let (lx, ly) = page(fp.label_mm());
        s.push_str(&format!(
            "<text x=\"{}\" y=\"{}\" font-family=\"sans-serif\" font-size=\"3.5\" fill=\"{grey}\">{}</text>\n",
            f(lx),
            f(ly + 3.5),
            xml_escape(&fp.label())
        ));
    }
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
    if !sheet.footprints.is_empty() {
        draw_footprints(sheet, &mut img);
    }
    img
}

/// The footprints in grey over the page: outline, front arrow and the key's name (8x8 font,
/// 3.5 mm high).
fn draw_footprints(sheet: &Sheet, img: &mut image::GrayImage) {
    let ppm = sheet.dpi / 25.4;
    let mut canvas = crate::draw::Image::filled(img.width(), img.height(), crate::draw::WHITE);
    for (px, d) in img.pixels().zip(canvas.rgba8.chunks_exact_mut(4)) {
        d[..3].fill(px.0[0]);
    }
    // Page mm -> pixel coordinates (pixel centres at integers).
    let at = |p: (f64, f64)| {
        (
            (sheet.origin_mm.0 + p.0) * ppm - 0.5,
            (sheet.origin_mm.1 + p.1) * ppm - 0.5,
        )
    };
    let grey = [FOOTPRINT_GREY; 3];
    let width = (FOOTPRINT_LINE_MM * ppm).round().max(1.0) as u32;
    for fp in &sheet.footprints {
        let pts: Vec<(f64, f64)> = fp.outline_mm.iter().map(|&p| at(p)).collect();
        for (i, &a) in pts.iter().enumerate() {
            let b = pts[(i + 1) % pts.len()];
            canvas.line(a, b, width, grey);
        }
        if let Some([tail, tip, h1, h2]) = fp.arrow_mm() {
            canvas.line(at(tail), at(tip), width, grey);
            canvas.line(at(h1), at(tip), width, grey);
            canvas.line(at(h2), at(tip), width, grey);
        }
        let scale = (3.5 * ppm / crate::draw::GLYPH as f64).round().max(1.0) as u32;
        let (lx, ly) = at(fp.label_mm());
        canvas.text(
            lx.round() as i64,
            ly.round() as i64,
            &fp.label(),
            scale,
            grey,
        );
    }
    for (px, s) in img.pixels_mut().zip(canvas.rgba8.chunks_exact(4)) {
        px.0[0] = s[0];
    }
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
    with_png_metadata(png, dpi, text)
}

/// Inserts the DPI (`pHYs`) and `tEXt` metadata after an encoded PNG's `IHDR`.
pub(crate) fn with_png_metadata(
    png: Vec<u8>,
    dpi: f64,
    text: &[(&str, &str)],
) -> Result<Vec<u8>, OverlayError> {
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
