//! CPU drawing into an RGBA8 image: rectangles, blending, lines, mask tints and outlines, and
//! text in an embedded 8x8 bitmap font (`font8x8`, public domain). The preview draws its
//! overlays and its status line with these before the frame is uploaded, so what is on the
//! screen is exactly one image (and the screenshot test can compare it).

/// An sRGB RGBA8 image, rows top to bottom.
#[derive(Debug, Clone, PartialEq)]
pub struct Image {
    pub width: u32,
    pub height: u32,
    pub rgba8: Vec<u8>,
}

/// An opaque colour.
pub type Rgb = [u8; 3];

pub const WHITE: Rgb = [255, 255, 255];
pub const RED: Rgb = [235, 60, 50];
pub const GREEN: Rgb = [60, 220, 80];
pub const BLUE: Rgb = [70, 120, 255];
pub const YELLOW: Rgb = [255, 205, 40];
pub const MAGENTA: Rgb = [255, 40, 200];
pub const CYAN: Rgb = [40, 220, 255];
/// The status bar's background.
pub const BAR: Rgb = [18, 18, 22];

/// Width and height of a glyph of the font, pixels (before scaling).
pub const GLYPH: u32 = 8;

impl Image {
    /// A `width x height` image of one colour.
    pub fn filled(width: u32, height: u32, c: Rgb) -> Self {
        let mut rgba8 = Vec::with_capacity(width as usize * height as usize * 4);
        for _ in 0..width as usize * height as usize {
            rgba8.extend_from_slice(&[c[0], c[1], c[2], 255]);
        }
        Self {
            width,
            height,
            rgba8,
        }
    }

    fn index(&self, x: i64, y: i64) -> Option<usize> {
        (x >= 0 && y >= 0 && x < self.width as i64 && y < self.height as i64)
            .then(|| (y as usize * self.width as usize + x as usize) * 4)
    }

    /// The colour at a pixel (None outside).
    #[cfg(test)]
    pub fn get(&self, x: u32, y: u32) -> Option<Rgb> {
        let i = self.index(x as i64, y as i64)?;
        Some([self.rgba8[i], self.rgba8[i + 1], self.rgba8[i + 2]])
    }

    /// Sets a pixel (ignored outside).
    pub fn put(&mut self, x: i64, y: i64, c: Rgb) {
        if let Some(i) = self.index(x, y) {
            self.rgba8[i..i + 4].copy_from_slice(&[c[0], c[1], c[2], 255]);
        }
    }

    /// Blends a colour over a pixel with opacity `alpha` (0..=1; ignored outside).
    pub fn blend(&mut self, x: i64, y: i64, c: Rgb, alpha: f32) {
        if let Some(i) = self.index(x, y) {
            let a = alpha.clamp(0.0, 1.0);
            for (d, &s) in self.rgba8[i..i + 3].iter_mut().zip(&c) {
                *d = (*d as f32 * (1.0 - a) + s as f32 * a + 0.5) as u8;
            }
            self.rgba8[i + 3] = 255;
        }
    }

    /// Fills a rectangle (clipped).
    pub fn fill_rect(&mut self, x: i64, y: i64, w: u32, h: u32, c: Rgb) {
        for yy in y.max(0)..(y + h as i64).min(self.height as i64) {
            for xx in x.max(0)..(x + w as i64).min(self.width as i64) {
                self.put(xx, yy, c);
            }
        }
    }

    /// Blends a colour over a rectangle (clipped).
    pub fn blend_rect(&mut self, x: i64, y: i64, w: u32, h: u32, c: Rgb, alpha: f32) {
        for yy in y.max(0)..(y + h as i64).min(self.height as i64) {
            for xx in x.max(0)..(x + w as i64).min(self.width as i64) {
                self.blend(xx, yy, c, alpha);
            }
        }
    }

    /// Copies `src` (same width, at most as tall) into rows `y0..`.
    pub fn paste_rows(&mut self, src: &Image, y0: u32) {
        if src.width != self.width {
            return;
        }
        let row = self.width as usize * 4;
        let rows = (src.height).min(self.height.saturating_sub(y0)) as usize;
        let start = y0 as usize * row;
        self.rgba8[start..start + rows * row].copy_from_slice(&src.rgba8[..rows * row]);
    }

    /// A line from `a` to `b` (pixel centres), `thickness` pixels wide, clipped to the image.
    pub fn line(&mut self, a: (f64, f64), b: (f64, f64), thickness: u32, c: Rgb) {
        let margin = thickness as f64;
        let Some((a, b)) = clip_segment(
            a,
            b,
            (-margin, -margin),
            (self.width as f64 + margin, self.height as f64 + margin),
        ) else {
            return;
        };
        let steps = (b.0 - a.0).abs().max((b.1 - a.1).abs()).ceil().max(1.0) as usize;
        let r = thickness.max(1) as i64;
        let lo = -(r - 1) / 2;
        let hi = r / 2;
        for s in 0..=steps {
            let t = s as f64 / steps as f64;
            let x = (a.0 + (b.0 - a.0) * t).round() as i64;
            let y = (a.1 + (b.1 - a.1) * t).round() as i64;
            for dy in lo..=hi {
                for dx in lo..=hi {
                    self.put(x + dx, y + dy, c);
                }
            }
        }
    }

    /// Blends `c` over the pixels where `mask` is set (a mask of the image's size).
    pub fn tint(&mut self, mask: &[bool], c: Rgb, alpha: f32) {
        if mask.len() != self.width as usize * self.height as usize {
            return;
        }
        let w = self.width as usize;
        for (i, _) in mask.iter().enumerate().filter(|(_, &m)| m) {
            self.blend((i % w) as i64, (i / w) as i64, c, alpha);
        }
    }

    /// Draws the outline of `mask` (its pixels with a neighbour outside it), two pixels wide.
    pub fn outline(&mut self, mask: &[bool], c: Rgb) {
        let (w, h) = (self.width as usize, self.height as usize);
        for i in outline_pixels(mask, w, h) {
            let (x, y) = ((i % w) as i64, (i / w) as i64);
            self.put(x, y, c);
            self.put(x + 1, y, c);
            self.put(x, y + 1, c);
        }
    }

    /// Blends `other` (same size) over the image at opacity `alpha`.
    pub fn blend_image(&mut self, other: &Image, alpha: f32) {
        if (other.width, other.height) != (self.width, self.height) {
            return;
        }
        let a = alpha.clamp(0.0, 1.0);
        for (d, s) in self
            .rgba8
            .chunks_exact_mut(4)
            .zip(other.rgba8.chunks_exact(4))
        {
            for k in 0..3 {
                d[k] = (d[k] as f32 * (1.0 - a) + s[k] as f32 * a + 0.5) as u8;
            }
            d[3] = 255;
        }
    }

    /// Draws `text` with its top-left at (x, y), each font pixel `scale` x `scale`; returns
    /// the width drawn. Characters outside printable ASCII are drawn as `?`.
    pub fn text(&mut self, x: i64, y: i64, text: &str, scale: u32, c: Rgb) -> u32 {
        let s = scale.max(1) as i64;
        let mut cx = x;
        for ch in text.chars() {
            let code = if ch.is_ascii() && !ch.is_ascii_control() {
                ch as usize
            } else {
                b'?' as usize
            };
            let glyph = font8x8::legacy::BASIC_LEGACY[code];
            for (row, bits) in glyph.iter().enumerate() {
                for col in 0..8 {
                    if bits & (1 << col) != 0 {
                        let (px, py) = (cx + col as i64 * s, y + row as i64 * s);
                        for dy in 0..s {
                            for dx in 0..s {
                                self.put(px + dx, py + dy, c);
                            }
                        }
                    }
                }
            }
            cx += GLYPH as i64 * s;
        }
        (cx - x) as u32
    }
}

/// Width of `text` in pixels at `scale`.
pub fn text_width(text: &str, scale: u32) -> u32 {
    text.chars().count() as u32 * GLYPH * scale.max(1)
}

/// `text` cut to at most `max_px` pixels at `scale`.
pub fn fit_text(text: &str, max_px: u32, scale: u32) -> &str {
    let max_chars = (max_px / (GLYPH * scale.max(1))) as usize;
    match text.char_indices().nth(max_chars) {
        Some((i, _)) => &text[..i],
        None => text,
    }
}

/// Indices of the mask's pixels that have a 4-neighbour outside the mask (or lie on the
/// image border).
pub fn outline_pixels(mask: &[bool], w: usize, h: usize) -> Vec<usize> {
    if mask.len() != w * h {
        return Vec::new();
    }
    let mut out = Vec::new();
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            if !mask[i] {
                continue;
            }
            let edge = x == 0
                || y == 0
                || x + 1 == w
                || y + 1 == h
                || !mask[i - 1]
                || !mask[i + 1]
                || !mask[i - w]
                || !mask[i + w];
            if edge {
                out.push(i);
            }
        }
    }
    out
}

/// Clips the segment `a`-`b` to the box `lo`..`hi` (Liang-Barsky); `None` when it misses.
pub fn clip_segment(
    a: (f64, f64),
    b: (f64, f64),
    lo: (f64, f64),
    hi: (f64, f64),
) -> Option<((f64, f64), (f64, f64))> {
    if ![a.0, a.1, b.0, b.1].iter().all(|v| v.is_finite()) {
        return None;
    }
    let (dx, dy) = (b.0 - a.0, b.1 - a.1);
    let (mut t0, mut t1) = (0.0f64, 1.0f64);
    for (p, q) in [
        (-dx, a.0 - lo.0),
        (dx, hi.0 - a.0),
        (-dy, a.1 - lo.1),
        (dy, hi.1 - a.1),
    ] {
        if p == 0.0 {
            if q < 0.0 {
                return None;
            }
        } else {
            let r = q / p;
            if p < 0.0 {
                t0 = t0.max(r);
            } else {
                t1 = t1.min(r);
            }
            if t0 > t1 {
                return None;
            }
        }
    }
    Some((
        (a.0 + t0 * dx, a.1 + t0 * dy),
        (a.0 + t1 * dx, a.1 + t1 * dy),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn text_draws_the_glyphs_and_clips() {
        let mut img = Image::filled(40, 10, BAR);
        let w = img.text(1, 1, "HI", 1, WHITE);
        assert_eq!(w, 16);
        let lit = img.rgba8.chunks_exact(4).filter(|p| p[0] == 255).count();
        // 'H' has 7 rows of 2 + a bar of 6: lots of pixels; 'I' too; nothing outside 1..17.
        assert!(lit > 20, "{lit}");
        for y in 0..10 {
            for x in 17..40 {
                assert_eq!(img.get(x, y), Some(BAR), "({x},{y})");
            }
        }
        // Scaled text is four times the pixels.
        let mut big = Image::filled(80, 20, BAR);
        big.text(0, 0, "HI", 2, WHITE);
        let lit2 = big.rgba8.chunks_exact(4).filter(|p| p[0] == 255).count();
        assert_eq!(lit2, lit * 4);
        // Off the image: no panic.
        img.text(-30, -3, "clipped ~\u{e9}", 3, WHITE);
        img.text(35, 8, "xyz", 1, WHITE);
    }

    #[test]
    fn fitting_text() {
        assert_eq!(text_width("abc", 2), 48);
        assert_eq!(fit_text("abcdef", 24, 1), "abc");
        assert_eq!(fit_text("ab", 24, 1), "ab");
        assert_eq!(fit_text("abcdef", 7, 1), "");
    }

    #[test]
    fn lines_are_clipped_and_drawn() {
        let mut img = Image::filled(20, 20, [0, 0, 0]);
        img.line((-100.0, 10.0), (100.0, 10.0), 1, RED);
        for x in 0..20 {
            assert_eq!(img.get(x, 10), Some(RED));
            assert_eq!(img.get(x, 9), Some([0, 0, 0]));
        }
        // Thickness 3 covers the rows around.
        img.line((5.0, 0.0), (5.0, 19.0), 3, GREEN);
        for y in 0..20 {
            for x in 4..=6 {
                assert_eq!(img.get(x, y), Some(GREEN));
            }
        }
        // A line far outside draws nothing and does not loop for long.
        let before = img.clone();
        img.line((-1e12, -1e12), (-1e12, 1e12), 2, BLUE);
        img.line((f64::NAN, 0.0), (3.0, 3.0), 2, BLUE);
        assert_eq!(img, before);
        assert_eq!(
            clip_segment((0.0, 0.0), (10.0, 0.0), (2.0, -1.0), (5.0, 1.0)),
            Some(((2.0, 0.0), (5.0, 0.0)))
        );
    }

    #[test]
    fn masks_tint_and_outline() {
        let (w, h) = (8usize, 6usize);
        let mut mask = vec![false; w * h];
        for y in 1..5 {
            for x in 2..6 {
                mask[y * w + x] = true;
            }
        }
        let edges = outline_pixels(&mask, w, h);
        // A 4x4 square has 12 border pixels.
        assert_eq!(edges.len(), 12);
        let mut img = Image::filled(w as u32, h as u32, [0, 0, 0]);
        img.tint(&mask, [200, 100, 0], 0.5);
        assert_eq!(img.get(3, 2), Some([100, 50, 0]));
        assert_eq!(img.get(0, 0), Some([0, 0, 0]));
        let mut img = Image::filled(w as u32, h as u32, [0, 0, 0]);
        img.outline(&mask, WHITE);
        assert_eq!(img.get(2, 1), Some(WHITE));
        assert_eq!(img.get(0, 0), Some([0, 0, 0]));
        // Wrong-sized masks are ignored.
        img.tint(&[true; 3], WHITE, 1.0);
        assert!(outline_pixels(&[true; 3], w, h).is_empty());
    }

    #[test]
    fn blending_images_and_pasting_rows() {
        let mut a = Image::filled(4, 2, [200, 0, 100]);
        let b = Image::filled(4, 2, [0, 200, 100]);
        a.blend_image(&b, 0.5);
        assert_eq!(a.get(1, 1), Some([100, 100, 100]));
        let mut tall = Image::filled(4, 5, [0, 0, 0]);
        tall.paste_rows(&b, 3);
        assert_eq!(tall.get(0, 2), Some([0, 0, 0]));
        assert_eq!(tall.get(0, 3), Some([0, 200, 100]));
        assert_eq!(tall.get(3, 4), Some([0, 200, 100]));
        tall.fill_rect(-2, -2, 3, 3, WHITE);
        assert_eq!(tall.get(0, 0), Some(WHITE));
        assert_eq!(tall.get(1, 1), Some([0, 0, 0]));
    }
}
