//! The paper's baseline: fill a screen-space rectangle from its boundary (Props Alive 3.3/4.3).
//!
//! Each pixel `(x, y)` of the rectangle `[x0, x1) x [y0, y1)` becomes the mean of the pixels
//! just outside the rectangle on its row and column:
//!
//! ```text
//! left = (x0 - 1, y)   right = (x1, y)   top = (x, y0 - 1)   bottom = (x, y1)
//! out(x, y) = round((left + right + top + bottom) / 4)      per R, G, B channel
//! ```
//!
//! Sides outside the image are dropped and the mean is taken over the available ones (so a
//! rectangle touching the left border uses right, top and bottom: `/ 3`). Rounding is
//! half-up on integer sums, so a constant background is reproduced exactly. Alpha is kept.
//! Cost: O(N x M) for an N x M rectangle, a handful of integer ops a pixel.

use crate::error::DiminishError;
use crate::types::{ImageRgba8, Mask, Rect};

/// The paper's rectangle for a mask: its bounding box grown by `margin_px` (clipped to the
/// mask). Errors with [`DiminishError::EmptyMask`] for an empty mask.
pub fn baseline_rect(mask: &Mask, margin_px: u32) -> Result<Rect, DiminishError> {
    let bbox = mask.bounding_box().ok_or(DiminishError::EmptyMask {
        what: "baseline rectangle",
    })?;
    Ok(bbox.expand_clipped(margin_px, mask.width(), mask.height()))
}

/// Fills `rect` (clipped to the frame) with the paper's row/column boundary average. Returns
/// the number of pixels written (0 if the rectangle lies outside the frame). Errors with
/// [`DiminishError::NoBoundary`] if the rectangle covers the whole frame.
pub fn paper_rectangle_fill(frame: &mut ImageRgba8, rect: Rect) -> Result<usize, DiminishError> {
    let (w, h) = frame.size();
    let Some(r) = rect.clip(w, h) else {
        return Ok(0);
    };
    let has_left = r.x > 0;
    let has_right = r.right() < w;
    let has_top = r.y > 0;
    let has_bottom = r.bottom() < h;
    let n = u32::from(has_left) + u32::from(has_right) + u32::from(has_top) + u32::from(has_bottom);
    if n == 0 {
        return Err(DiminishError::NoBoundary {
            region: r,
            width: w,
            height: h,
        });
    }
    let stride = w as usize * 4;
    let data = frame.as_mut_slice();
    let (x0, x1) = (r.x as usize, r.right() as usize);
    let (y0, y1) = (r.y as usize, r.bottom() as usize);
    // Column sums (top + bottom) for every x of the rectangle, copied once.
    let mut col = vec![[0u32; 3]; x1 - x0];
    for (i, c) in col.iter_mut().enumerate() {
        let x = x0 + i;
        for (ok, yy) in [(has_top, y0.wrapping_sub(1)), (has_bottom, y1)] {
            if ok {
                let p = yy * stride + x * 4;
                for ch in 0..3 {
                    c[ch] += u32::from(data[p + ch]);
                }
            }
        }
    }
    // Half-up rounding of sum / n as a float multiply: for n in 1..=4 and sums up to 1020,
    // sum / n + 0.5 is exact or its fractional part is at least 1/6 away from an integer,
    // so this equals the integer (sum + n / 2) / n without an integer division per channel.
    let inv_n = 1.0 / n as f32;
    for y in y0..y1 {
        let mut row = [0u32; 3];
        for (ok, xx) in [(has_left, x0.wrapping_sub(1)), (has_right, x1)] {
            if ok {
                let p = y * stride + xx * 4;
                for ch in 0..3 {
                    row[ch] += u32::from(data[p + ch]);
                }
            }
        }
        let line = &mut data[y * stride + x0 * 4..y * stride + x1 * 4];
        for (px, c) in line.chunks_exact_mut(4).zip(&col) {
            for ch in 0..3 {
                // <= 255.5 since every term is <= 255; the cast truncates.
                px[ch] = ((row[ch] + c[ch]) as f32 * inv_n + 0.5) as u8;
            }
        }
    }
    Ok(r.area())
}

#[cfg(test)]
mod tests {
    #[test]
    fn float_rounding_equals_integer_rounding() {
        for n in 1u32..=4 {
            let inv_n = 1.0 / n as f32;
            for sum in 0..=255 * n {
                assert_eq!(
                    (sum as f32 * inv_n + 0.5) as u32,
                    (sum + n / 2) / n,
                    "{sum}/{n}"
                );
            }
        }
    }
}
