//! A picture printed at true size (`propsalive marker --image PICTURE --width-mm W`): the
//! picture `W` mm wide (its height from its aspect), a white margin, and below it a thin
//! scale bar (the longest of 100, 50, 20, 10 mm that fits the picture's width; ticks every
//! 10 mm, every 5 mm on a 20 mm bar, every 2 mm on a 10 mm bar) and a label with the width,
//! so that a print at the wrong scale is seen with a ruler.
//!
//! Two renderings, as the tag sheets ([`crate::sheet`]): an SVG at physical size (`width`,
//! `height` in mm; the picture embedded as a PNG data URI, the bar as lines, the label as
//! `<text>`), and a PNG at a DPI (`pHYs`), the label drawn with the 8x8 bitmap font.

use crate::draw::{Image, Rgb};
use crate::sheet::with_png_metadata;
use crate::OverlayError;

/// Height of the band under the picture for the bar and the label, mm.
const BAND_MM: f64 = 14.0;
/// Bar line thickness, mm.
const BAR_LINE_MM: f64 = 0.3;
const INK: Rgb = [0, 0, 0];

/// The page of a printed picture, millimetres from its top-left.
#[derive(Debug, Clone, PartialEq)]
pub struct PictureSheet {
    /// The picture's size in pixels.
    pub picture_px: (u32, u32),
    /// The picture's printed size, mm.
    pub width_mm: f64,
    pub height_mm: f64,
    pub margin_mm: f64,
    pub dpi: f64,
    pub page_w_mm: f64,
    pub page_h_mm: f64,
    /// The scale bar's length and tick spacing, mm.
    pub bar_mm: f64,
    pub tick_mm: f64,
    /// The label under the bar.
    pub label: String,
}

impl PictureSheet {
    /// Checks and lays out: `width_mm` in [10, 5000], `dpi` in [10, 4800], `margin_mm` in
    /// [0, 1000], the picture at least 16 pixels a side and at most 100 million, the PNG at
    /// most 400 million pixels.
    pub fn new(
        picture_px: (u32, u32),
        width_mm: f64,
        dpi: f64,
        margin_mm: f64,
        name: &str,
    ) -> Result<Self, OverlayError> {
        if !(width_mm.is_finite() && (10.0..=5000.0).contains(&width_mm)) {
            return Err(OverlayError::WidthOutOfRange { width_mm });
        }
        if !(dpi.is_finite() && (10.0..=4800.0).contains(&dpi)) {
            return Err(OverlayError::DpiOutOfRange { dpi });
        }
        if !(margin_mm.is_finite() && (0.0..=1000.0).contains(&margin_mm)) {
            return Err(OverlayError::MarginOutOfRange { margin_mm });
        }
        let (w, h) = picture_px;
        if w < 16 || h < 16 || w as u64 * h as u64 > 100_000_000 {
            return Err(OverlayError::PictureSize {
                width: w,
                height: h,
            });
        }
        let height_mm = width_mm * h as f64 / w as f64;
        let margin = margin_mm.max(5.0);
        let page_w_mm = width_mm + 2.0 * margin;
        let page_h_mm = height_mm + 2.0 * margin + BAND_MM;
        let px = dpi / 25.4;
        if page_w_mm * px * page_h_mm * px > 400e6 {
            return Err(OverlayError::PngTooLarge {
                width_px: page_w_mm * px,
                height_px: page_h_mm * px,
            });
        }
        let bar_mm = [100.0, 50.0, 20.0, 10.0]
            .into_iter()
            .find(|&b| b <= width_mm)
            .unwrap_or(10.0);
        let tick_mm = match bar_mm as u32 {
            10 => 2.0,
            20 => 5.0,
            _ => 10.0,
        };
        let label = format!(
            "{name}: {} x {} mm; bar {} mm; print at 100 %",
            num(width_mm),
            num(height_mm),
            num(bar_mm)
        );
        Ok(Self {
            picture_px,
            width_mm,
            height_mm,
            margin_mm: margin,
            dpi,
            page_w_mm,
            page_h_mm,
            bar_mm,
            tick_mm,
            label,
        })
    }

    /// The bar's segments, mm: the bar itself and its ticks (end ticks taller).
    fn bar_segments(&self) -> Vec<((f64, f64), (f64, f64))> {
        let x0 = self.margin_mm;
        let y = self.margin_mm + self.height_mm + 5.0;
        let mut segs = vec![((x0, y), (x0 + self.bar_mm, y))];
        let n = (self.bar_mm / self.tick_mm).round() as u32;
        for i in 0..=n {
            let x = x0 + i as f64 * self.tick_mm;
            let len = if i == 0 || i == n { 3.0 } else { 1.5 };
            segs.push(((x, y - len), (x, y)));
        }
        segs
    }

    /// The label's top-left, mm.
    fn label_at(&self) -> (f64, f64) {
        (self.margin_mm, self.margin_mm + self.height_mm + 7.0)
    }
}

fn num(v: f64) -> String {
    let s = format!("{v:.2}");
    s.trim_end_matches('0').trim_end_matches('.').to_string()
}

/// The page at `sheet.dpi`: `picture` (RGBA8, alpha over white) resized to its printed size,
/// the bar and the label.
pub fn picture_raster(sheet: &PictureSheet, picture: &image::RgbaImage) -> image::RgbImage {
    let px = sheet.dpi / 25.4;
    let (pw, ph) = (
        (sheet.page_w_mm * px).round().max(1.0) as u32,
        (sheet.page_h_mm * px).round().max(1.0) as u32,
    );
    let mut page = Image::filled(pw, ph, [255, 255, 255]);
    let (x0, y0) = (
        (sheet.margin_mm * px).round() as i64,
        (sheet.margin_mm * px).round() as i64,
    );
    let (tw, th) = (
        (sheet.width_mm * px).round().max(1.0) as u32,
        (sheet.height_mm * px).round().max(1.0) as u32,
    );
    let resized = image::imageops::resize(picture, tw, th, image::imageops::FilterType::Triangle);
    for (x, y, p) in resized.enumerate_pixels() {
        let a = p[3] as f32 / 255.0;
        let c = [0, 1, 2].map(|k| (p[k] as f32 * a + 255.0 * (1.0 - a)).round() as u8);
        page.put(x0 + x as i64, y0 + y as i64, c);
    }
    let thick = (BAR_LINE_MM * px).round().max(1.0) as u32;
    for (a, b) in sheet.bar_segments() {
        page.line((a.0 * px, a.1 * px), (b.0 * px, b.1 * px), thick, INK);
    }
    // Text about 2.5 mm tall, smaller where the page is narrow (cut at one font pixel).
    let avail = ((sheet.page_w_mm - 2.0 * sheet.margin_mm) * px).max(0.0) as u32;
    let fit = avail / crate::draw::text_width(&sheet.label, 1).max(1);
    let scale = (((2.5 * px) / 8.0).round() as u32).min(fit).max(1);
    let (lx, ly) = sheet.label_at();
    page.text(
        (lx * px).round() as i64,
        (ly * px).round() as i64,
        crate::draw::fit_text(&sheet.label, avail, scale),
        scale,
        INK,
    );
    let rgb: Vec<u8> = page
        .rgba8
        .chunks_exact(4)
        .flat_map(|p| [p[0], p[1], p[2]])
        .collect();
    image::RgbImage::from_raw(pw, ph, rgb).unwrap_or_else(|| image::RgbImage::new(pw, ph))
}

/// The PNG of [`picture_raster`] with its DPI and the label in `tEXt`.
pub fn picture_png(
    sheet: &PictureSheet,
    raster: &image::RgbImage,
) -> Result<Vec<u8>, OverlayError> {
    let mut png = Vec::new();
    raster.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)?;
    with_png_metadata(
        png,
        sheet.dpi,
        &[
            ("Title", sheet.label.as_str()),
            ("Software", "propsalive marker --image"),
        ],
    )
}

/// The SVG at physical size, `picture_png` (the picture's own PNG bytes) embedded.
pub fn picture_svg(sheet: &PictureSheet, picture_png: &[u8]) -> String {
    let f = |v: f64| format!("{v:.4}");
    let mut s = String::new();
    s.push_str("<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n");
    s.push_str(&format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{w}mm\" height=\"{h}mm\" viewBox=\"0 0 {w} {h}\">\n",
        w = f(sheet.page_w_mm),
        h = f(sheet.page_h_mm)
    ));
    s.push_str(&format!(
        "<rect x=\"0\" y=\"0\" width=\"{}\" height=\"{}\" fill=\"#fff\"/>\n",
        f(sheet.page_w_mm),
        f(sheet.page_h_mm)
    ));
    s.push_str(&format!(
        "<image x=\"{m}\" y=\"{m}\" width=\"{}\" height=\"{}\" preserveAspectRatio=\"none\" href=\"data:image/png;base64,{}\"/>\n",
        f(sheet.width_mm),
        f(sheet.height_mm),
        base64(picture_png),
        m = f(sheet.margin_mm),
    ));
    for (a, b) in sheet.bar_segments() {
        s.push_str(&format!(
            "<line x1=\"{}\" y1=\"{}\" x2=\"{}\" y2=\"{}\" stroke=\"#000\" stroke-width=\"{}\"/>\n",
            f(a.0),
            f(a.1),
            f(b.0),
            f(b.1),
            f(BAR_LINE_MM)
        ));
    }
    let (lx, ly) = sheet.label_at();
    s.push_str(&format!(
        "<text x=\"{}\" y=\"{}\" font-family=\"sans-serif\" font-size=\"2.5\">{}</text>\n",
        f(lx),
        f(ly + 2.5),
        sheet
            .label
            .replace('&', "&amp;")
            .replace('<', "&lt;")
            .replace('>', "&gt;")
    ));
    s.push_str("</svg>\n");
    s
}

/// Standard base64 with padding.
fn base64(data: &[u8]) -> String {
    const T: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::with_capacity(data.len().div_ceil(3) * 4);
    for c in data.chunks(3) {
        let b = [c[0], *c.get(1).unwrap_or(&0), *c.get(2).unwrap_or(&0)];
        let n = (b[0] as u32) << 16 | (b[1] as u32) << 8 | b[2] as u32;
        for i in 0..4 {
            if i <= c.len() {
                out.push(T[(n >> (18 - 6 * i) & 63) as usize] as char);
            } else {
                out.push('=');
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_matches_the_rfc_vectors() {
        for (i, o) in [
            ("", ""),
            ("f", "Zg=="),
            ("fo", "Zm8="),
            ("foo", "Zm9v"),
            ("foob", "Zm9vYg=="),
            ("fooba", "Zm9vYmE="),
            ("foobar", "Zm9vYmFy"),
        ] {
            assert_eq!(base64(i.as_bytes()), o);
        }
    }

    #[test]
    fn the_picture_prints_at_its_width_with_a_true_scale_bar() {
        // 200 x 100 px picture, 150 mm wide at 254 dpi (10 px a mm), 10 mm margin.
        let sheet = PictureSheet::new((200, 100), 150.0, 254.0, 10.0, "rug.png").expect("ok");
        assert_eq!(
            (sheet.height_mm, sheet.bar_mm, sheet.tick_mm),
            (75.0, 100.0, 10.0)
        );
        assert_eq!(
            (sheet.page_w_mm, sheet.page_h_mm),
            (170.0, 75.0 + 20.0 + BAND_MM)
        );
        let pic = image::RgbaImage::from_pixel(200, 100, image::Rgba([200, 30, 30, 255]));
        let r = picture_raster(&sheet, &pic);
        assert_eq!(r.dimensions(), (1700, 1090));
        // The picture covers exactly [100, 1600) x [100, 850) px.
        assert_eq!(r.get_pixel(100, 100).0, [200, 30, 30]);
        assert_eq!(r.get_pixel(1599, 849).0, [200, 30, 30]);
        assert_eq!(r.get_pixel(99, 100).0, [255, 255, 255]);
        assert_eq!(r.get_pixel(1600, 849).0, [255, 255, 255]);
        assert_eq!(r.get_pixel(100, 850).0, [255, 255, 255]);
        // The bar: 100 mm = 1000 px of black on its row (y = 10 + 75 + 5 mm = 900 px).
        let row: Vec<u32> = (0..1700)
            .filter(|&x| r.get_pixel(x, 900).0 == [0, 0, 0])
            .collect();
        let (first, last) = (row[0], *row.last().expect("bar"));
        assert!(
            (first as i64 - 100).abs() <= 2 && (last as i64 - 1100).abs() <= 2,
            "{first}..{last}"
        );
        // Eleven ticks above it (y = 890 px, 1 mm up).
        let ticks = (0..1700)
            .filter(|&x| {
                r.get_pixel(x, 890).0 == [0, 0, 0]
                    && r.get_pixel(x.saturating_sub(1), 890).0 != [0, 0, 0]
            })
            .count();
        assert_eq!(ticks, 11);
        // The label is drawn and stays out of the right margin.
        let ink = |x0: u32, x1: u32| {
            (x0..x1)
                .flat_map(|x| (920..1090).map(move |y| (x, y)))
                .filter(|&(x, y)| r.get_pixel(x, y).0 == [0, 0, 0])
                .count()
        };
        assert!(ink(100, 1600) > 500);
        assert_eq!(ink(1600, 1700), 0);
        // A narrow page shrinks its label to fit.
        let narrow =
            PictureSheet::new((200, 100), 40.0, 254.0, 5.0, "a_long_picture_name.png").expect("ok");
        let rn = picture_raster(&narrow, &pic);
        let w = rn.width();
        let right: usize = (w - 50..w)
            .flat_map(|x| (0..rn.height()).map(move |y| (x, y)))
            .filter(|&(x, y)| rn.get_pixel(x, y).0 == [0, 0, 0])
            .count();
        assert_eq!(right, 0, "nothing drawn in the right margin");
        let png = picture_png(&sheet, &r).expect("png");
        // pHYs: 10000 px a metre.
        let at = png.windows(4).position(|w| w == b"pHYs").expect("pHYs");
        assert_eq!(&png[at + 4..at + 8], &10_000u32.to_be_bytes());
        let svg = picture_svg(&sheet, b"abc");
        assert!(svg.contains("width=\"170.0000mm\"") && svg.contains("base64,YWJj"));
        assert!(svg.contains("rug.png: 150 x 75 mm; bar 100 mm"));
    }

    #[test]
    fn absurd_sizes_are_refused() {
        for w in [0.0, 5.0, 5001.0, f64::NAN] {
            assert!(matches!(
                PictureSheet::new((100, 100), w, 300.0, 10.0, "p"),
                Err(OverlayError::WidthOutOfRange { .. })
            ));
        }
        assert!(matches!(
            PictureSheet::new((8, 100), 100.0, 300.0, 10.0, "p"),
            Err(OverlayError::PictureSize { .. })
        ));
        assert!(matches!(
            PictureSheet::new((100, 100), 5000.0, 4800.0, 10.0, "p"),
            Err(OverlayError::PngTooLarge { .. })
        ));
        assert!(matches!(
            PictureSheet::new((100, 100), 100.0, 5.0, 10.0, "p"),
            Err(OverlayError::DpiOutOfRange { .. })
        ));
    }
}
