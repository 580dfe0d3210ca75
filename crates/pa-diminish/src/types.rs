//! Typed images, masks and rectangles (row-major, no padding).

use crate::error::DiminishError;
use std::fmt;

/// An axis-aligned pixel rectangle: columns `x..x + width`, rows `y..y + height` (exclusive
/// right and bottom edges).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct Rect {
    pub x: u32,
    pub y: u32,
    pub width: u32,
    pub height: u32,
}

impl fmt::Display for Rect {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}x{}+{}+{}", self.width, self.height, self.x, self.y)
    }
}

impl Rect {
    /// A rectangle from its top-left corner and size.
    pub const fn new(x: u32, y: u32, width: u32, height: u32) -> Self {
        Self {
            x,
            y,
            width,
            height,
        }
    }

    /// The smallest rectangle containing the inclusive pixel range `x0..=x1`, `y0..=y1`.
    pub fn from_inclusive(x0: u32, y0: u32, x1: u32, y1: u32) -> Self {
        let (x0, x1) = (x0.min(x1), x0.max(x1));
        let (y0, y1) = (y0.min(y1), y0.max(y1));
        Self::new(x0, y0, x1 - x0 + 1, y1 - y0 + 1)
    }

    /// Exclusive right edge, `x + width` (saturating).
    pub const fn right(&self) -> u32 {
        self.x.saturating_add(self.width)
    }

    /// Exclusive bottom edge, `y + height` (saturating).
    pub const fn bottom(&self) -> u32 {
        self.y.saturating_add(self.height)
    }

    /// Whether the rectangle has no pixels.
    pub const fn is_empty(&self) -> bool {
        self.width == 0 || self.height == 0
    }

    /// Number of pixels.
    pub const fn area(&self) -> usize {
        self.width as usize * self.height as usize
    }

    /// Whether pixel `(x, y)` lies inside.
    pub const fn contains(&self, x: u32, y: u32) -> bool {
        x >= self.x && x < self.right() && y >= self.y && y < self.bottom()
    }

    /// Whether `other` lies wholly inside `self`.
    pub const fn contains_rect(&self, other: &Rect) -> bool {
        other.x >= self.x
            && other.y >= self.y
            && other.right() <= self.right()
            && other.bottom() <= self.bottom()
    }

    /// The intersection, or `None` if it is empty.
    pub fn intersect(&self, other: &Rect) -> Option<Rect> {
        let x0 = self.x.max(other.x);
        let y0 = self.y.max(other.y);
        let x1 = self.right().min(other.right());
        let y1 = self.bottom().min(other.bottom());
        (x1 > x0 && y1 > y0).then(|| Rect::new(x0, y0, x1 - x0, y1 - y0))
    }

    /// The rectangle clipped to a `width x height` image, or `None` if nothing is left.
    pub fn clip(&self, width: u32, height: u32) -> Option<Rect> {
        self.intersect(&Rect::new(0, 0, width, height))
    }

    /// The rectangle grown by `r` pixels on every side, clipped to a `width x height` image.
    pub fn expand_clipped(&self, r: u32, width: u32, height: u32) -> Rect {
        let x0 = self.x.saturating_sub(r);
        let y0 = self.y.saturating_sub(r);
        let x1 = self.right().saturating_add(r).min(width);
        let y1 = self.bottom().saturating_add(r).min(height);
        Rect::new(x0, y0, x1.saturating_sub(x0), y1.saturating_sub(y0))
    }

    /// The bounding rectangle of a set of (sub)pixel points, grown by `margin_px`, rounded
    /// outwards to whole pixels and clipped to the image. Non-finite points are ignored.
    /// Returns `None` if no finite point lies near the image. Use it to build the paper's
    /// screen-space rectangle from the projected corners of the prop's bounding box.
    pub fn bounding_points(
        points: impl IntoIterator<Item = [f64; 2]>,
        margin_px: f64,
        width: u32,
        height: u32,
    ) -> Option<Rect> {
        let (mut x0, mut y0) = (f64::INFINITY, f64::INFINITY);
        let (mut x1, mut y1) = (f64::NEG_INFINITY, f64::NEG_INFINITY);
        for [x, y] in points {
            if x.is_finite() && y.is_finite() {
                x0 = x0.min(x);
                y0 = y0.min(y);
                x1 = x1.max(x);
                y1 = y1.max(y);
            }
        }
        if !x0.is_finite() {
            return None;
        }
        let m = if margin_px.is_finite() {
            margin_px.max(0.0)
        } else {
            0.0
        };
        // Pixel i covers [i - 0.5, i + 0.5]: the first pixel touched by coordinate c is round(c).
        let fx0 = (x0 - m).round().max(0.0);
        let fy0 = (y0 - m).round().max(0.0);
        let fx1 = (x1 + m).round().min(f64::from(width) - 1.0);
        let fy1 = (y1 + m).round().min(f64::from(height) - 1.0);
        if fx1 < fx0 || fy1 < fy0 {
            return None;
        }
        // In range [0, width - 1] by construction, so the casts are exact.
        Some(Rect::from_inclusive(
            fx0 as u32, fy0 as u32, fx1 as u32, fy1 as u32,
        ))
    }
}

fn check_len(
    what: &'static str,
    width: u32,
    height: u32,
    channels: u32,
    actual: usize,
) -> Result<(), DiminishError> {
    if width == 0 || height == 0 {
        return Err(DiminishError::ZeroSize {
            what,
            width,
            height,
        });
    }
    let expected = width as usize * height as usize * channels as usize;
    if expected != actual {
        return Err(DiminishError::BufferLength {
            what,
            width,
            height,
            channels,
            expected,
            actual,
        });
    }
    Ok(())
}

/// An 8-bit RGBA image, sRGB-encoded, row-major, 4 bytes a pixel, no row padding (the
/// pipeline's frame format). Fills write R, G and B and leave alpha untouched.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ImageRgba8 {
    width: u32,
    height: u32,
    data: Vec<u8>,
}

impl ImageRgba8 {
    /// Wraps a buffer of `width * height * 4` bytes.
    pub fn new(width: u32, height: u32, data: Vec<u8>) -> Result<Self, DiminishError> {
        check_len("image", width, height, 4, data.len())?;
        Ok(Self {
            width,
            height,
            data,
        })
    }

    /// An image with every pixel set to `rgba`.
    pub fn filled(width: u32, height: u32, rgba: [u8; 4]) -> Result<Self, DiminishError> {
        check_len(
            "image",
            width,
            height,
            4,
            width as usize * height as usize * 4,
        )?;
        let data = rgba
            .iter()
            .copied()
            .cycle()
            .take(width as usize * height as usize * 4)
            .collect();
        Ok(Self {
            width,
            height,
            data,
        })
    }

    /// An image whose pixel `(x, y)` is `f(x, y)`.
    pub fn from_fn(
        width: u32,
        height: u32,
        mut f: impl FnMut(u32, u32) -> [u8; 4],
    ) -> Result<Self, DiminishError> {
        check_len(
            "image",
            width,
            height,
            4,
            width as usize * height as usize * 4,
        )?;
        let mut data = Vec::with_capacity(width as usize * height as usize * 4);
        for y in 0..height {
            for x in 0..width {
                data.extend_from_slice(&f(x, y));
            }
        }
        Ok(Self {
            width,
            height,
            data,
        })
    }

    pub fn width(&self) -> u32 {
        self.width
    }

    pub fn height(&self) -> u32 {
        self.height
    }

    /// `(width, height)`.
    pub fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    pub fn as_slice(&self) -> &[u8] {
        &self.data
    }

    pub fn as_mut_slice(&mut self) -> &mut [u8] {
        &mut self.data
    }

    pub fn into_vec(self) -> Vec<u8> {
        self.data
    }

    /// The pixel at `(x, y)`, or `None` outside the image.
    pub fn get(&self, x: u32, y: u32) -> Option<[u8; 4]> {
        if x >= self.width || y >= self.height {
            return None;
        }
        let i = (y as usize * self.width as usize + x as usize) * 4;
        let p = &self.data[i..i + 4];
        Some([p[0], p[1], p[2], p[3]])
    }

    /// Sets the pixel at `(x, y)`; does nothing outside the image.
    pub fn set(&mut self, x: u32, y: u32, rgba: [u8; 4]) {
        if x < self.width && y < self.height {
            let i = (y as usize * self.width as usize + x as usize) * 4;
            self.data[i..i + 4].copy_from_slice(&rgba);
        }
    }

    /// Copies all pixels of `src` (same size) into `self`, reusing the allocation.
    pub fn copy_from(&mut self, src: &ImageRgba8) -> Result<(), DiminishError> {
        ensure_same_size("source image", self.size(), src.size())?;
        self.data.copy_from_slice(&src.data);
        Ok(())
    }
}

pub(crate) fn ensure_same_size(
    what: &'static str,
    expected: (u32, u32),
    actual: (u32, u32),
) -> Result<(), DiminishError> {
    if expected != actual {
        return Err(DiminishError::SizeMismatch {
            what,
            expected_width: expected.0,
            expected_height: expected.1,
            actual_width: actual.0,
            actual_height: actual.1,
        });
    }
    Ok(())
}

/// A binary mask, one byte a pixel, row-major, no padding.
///
/// Convention: `0` = keep (background, known), **any non-zero value** = set (unknown). Among
/// set pixels, [`Mask::HIDDEN`] marks those that need no fill because something opaque will
/// be drawn over them (the twin's interior): the fills neither read them as known background
/// nor write them, and rays pass through them, so every other pixel is filled exactly as if
/// they were filled too. Everything this crate writes uses `0` and `255`, so masks can be
/// saved as greyscale images.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Mask {
    width: u32,
    height: u32,
    data: Vec<u8>,
}

impl Mask {
    /// The value written for set pixels.
    pub const SET: u8 = 255;
    /// A set pixel that need not be filled (see the type's docs).
    pub const HIDDEN: u8 = 128;

    /// Wraps a buffer of `width * height` bytes (non-zero = set).
    pub fn new(width: u32, height: u32, data: Vec<u8>) -> Result<Self, DiminishError> {
        check_len("mask", width, height, 1, data.len())?;
        Ok(Self {
            width,
            height,
            data,
        })
    }

    /// An empty (all-zero) mask.
    pub fn zeros(width: u32, height: u32) -> Result<Self, DiminishError> {
        Self::new(width, height, vec![0; width as usize * height as usize])
    }

    /// A mask whose pixel `(x, y)` is set where `f(x, y)` is true.
    pub fn from_fn(
        width: u32,
        height: u32,
        mut f: impl FnMut(u32, u32) -> bool,
    ) -> Result<Self, DiminishError> {
        check_len("mask", width, height, 1, width as usize * height as usize)?;
        let mut data = Vec::with_capacity(width as usize * height as usize);
        for y in 0..height {
            for x in 0..width {
                data.push(if f(x, y) { Self::SET } else { 0 });
            }
        }
        Ok(Self {
            width,
            height,
            data,
        })
    }

    pub fn width(&self) -> u32 {
        self.width
    }

    pub fn height(&self) -> u32 {
        self.height
    }

    /// `(width, height)`.
    pub fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    pub fn as_slice(&self) -> &[u8] {
        &self.data
    }

    pub fn as_mut_slice(&mut self) -> &mut [u8] {
        &mut self.data
    }

    pub fn into_vec(self) -> Vec<u8> {
        self.data
    }

    /// Whether `(x, y)` is set; `false` outside the mask.
    pub fn get(&self, x: u32, y: u32) -> bool {
        x < self.width
            && y < self.height
            && self.data[y as usize * self.width as usize + x as usize] != 0
    }

    /// Sets or clears `(x, y)`; does nothing outside the mask.
    pub fn set(&mut self, x: u32, y: u32, on: bool) {
        if x < self.width && y < self.height {
            self.data[y as usize * self.width as usize + x as usize] =
                if on { Self::SET } else { 0 };
        }
    }

    /// Clears every pixel.
    pub fn clear(&mut self) {
        self.data.fill(0);
    }

    /// Number of set pixels (O(frame)).
    pub fn count(&self) -> usize {
        self.data.iter().filter(|&&v| v != 0).count()
    }

    /// Whether no pixel is set (O(frame), stops at the first set pixel).
    pub fn is_empty(&self) -> bool {
        self.data.iter().all(|&v| v == 0)
    }

    /// The tight bounding box of the set pixels, `None` if the mask is empty.
    ///
    /// Cost: one pass over the rows (O(frame) byte compares, ~0.1 ms at 720p); pass a known
    /// box to [`crate::Diminisher::fill_in_bbox`] to skip it.
    pub fn bounding_box(&self) -> Option<Rect> {
        let w = self.width as usize;
        let rows = self.data.chunks_exact(w);
        let mut y0 = None;
        let mut y1 = 0;
        let mut x0 = usize::MAX;
        let mut x1 = 0;
        for (y, row) in rows.enumerate() {
            if let Some(first) = row.iter().position(|&v| v != 0) {
                let last = row.iter().rposition(|&v| v != 0).unwrap_or(first);
                y0.get_or_insert(y);
                y1 = y;
                x0 = x0.min(first);
                x1 = x1.max(last);
            }
        }
        // Indices are below width/height, which are u32.
        y0.map(|y0| Rect::from_inclusive(x0 as u32, y0 as u32, x1 as u32, y1 as u32))
    }

    /// The bounding box of the set pixels inside `region` only (clipped to the mask).
    pub fn bounding_box_in(&self, region: Rect) -> Option<Rect> {
        let r = region.clip(self.width, self.height)?;
        let w = self.width as usize;
        let mut out: Option<(usize, usize, usize, usize)> = None;
        for y in r.y as usize..r.bottom() as usize {
            let row = &self.data[y * w + r.x as usize..y * w + r.right() as usize];
            if let Some(first) = row.iter().position(|&v| v != 0) {
                let last = row.iter().rposition(|&v| v != 0).unwrap_or(first);
                let (fx, lx) = (first + r.x as usize, last + r.x as usize);
                out = Some(match out {
                    None => (fx, y, lx, y),
                    Some((a, b, c, _)) => (a.min(fx), b, c.max(lx), y),
                });
            }
        }
        out.map(|(a, b, c, d)| Rect::from_inclusive(a as u32, b as u32, c as u32, d as u32))
    }
}
