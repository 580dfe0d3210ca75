//! Image comparison over a mask (R, G, B only), for tests and the pipeline's evaluation.

use crate::error::DiminishError;
use crate::types::{ensure_same_size, ImageRgba8, Mask};

/// Mean squared error over R, G, B of the pixels set in `mask` (all pixels if `None`).
/// Errors with [`DiminishError::EmptyMask`] if no pixel is selected.
pub fn mse_rgb(a: &ImageRgba8, b: &ImageRgba8, mask: Option<&Mask>) -> Result<f64, DiminishError> {
    ensure_same_size("second image", a.size(), b.size())?;
    if let Some(m) = mask {
        ensure_same_size("mask", a.size(), m.size())?;
    }
    let mut sum = 0.0f64;
    let mut n = 0usize;
    for (i, (pa, pb)) in a
        .as_slice()
        .chunks_exact(4)
        .zip(b.as_slice().chunks_exact(4))
        .enumerate()
    {
        if mask.is_some_and(|m| m.as_slice()[i] == 0) {
            continue;
        }
        for c in 0..3 {
            let d = f64::from(pa[c]) - f64::from(pb[c]);
            sum += d * d;
        }
        n += 1;
    }
    if n == 0 {
        return Err(DiminishError::EmptyMask { what: "mse_rgb" });
    }
    Ok(sum / (3 * n) as f64)
}

/// PSNR in dB (peak 255) over the masked pixels; `f64::INFINITY` for identical pixels.
pub fn psnr_rgb(a: &ImageRgba8, b: &ImageRgba8, mask: Option<&Mask>) -> Result<f64, DiminishError> {
    let mse = mse_rgb(a, b, mask)?;
    Ok(if mse == 0.0 {
        f64::INFINITY
    } else {
        10.0 * (255.0f64 * 255.0 / mse).log10()
    })
}
