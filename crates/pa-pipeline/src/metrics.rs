//! Image quality metrics over a region: PSNR and SSIM against ground truth.
//!
//! Images are sRGB RGBA8, row-major; metrics use the RGB channels as stored (8-bit values),
//! the way published PSNR/SSIM figures on 8-bit images are computed. SSIM uses the luma
//! (Rec. 601) with Gaussian windows (sigma 1.5, 11x11), constants K1 = 0.01, K2 = 0.03
//! (Wang et al. 2004), averaged over the window centres inside the region.

/// PSNR in dB over the pixels where `region` is true (`f64::INFINITY` for identical images,
/// `None` for an empty region).
pub fn psnr_region(a: &[u8], b: &[u8], region: &[bool]) -> Option<f64> {
    let mut se = 0f64;
    let mut n = 0usize;
    for (i, &r) in region.iter().enumerate() {
        if !r {
            continue;
        }
        for c in 0..3 {
            let d = a[i * 4 + c] as f64 - b[i * 4 + c] as f64;
            se += d * d;
        }
        n += 3;
    }
    if n == 0 {
        return None;
    }
    let mse = se / n as f64;
    Some(if mse == 0.0 {
        f64::INFINITY
    } else {
        10.0 * (255.0f64 * 255.0 / mse).log10()
    })
}

fn luma(img: &[u8], width: usize, height: usize) -> Vec<f32> {
    (0..width * height)
        .map(|i| {
            0.299 * img[i * 4] as f32
                + 0.587 * img[i * 4 + 1] as f32
                + 0.114 * img[i * 4 + 2] as f32
        })
        .collect()
}

/// Separable Gaussian blur (sigma 1.5, radius 5) with clamped borders.
fn blur(src: &[f32], width: usize, height: usize) -> Vec<f32> {
    let k: Vec<f32> = (-5i32..=5)
        .map(|x| (-(x * x) as f32 / (2.0 * 1.5 * 1.5)).exp())
        .collect();
    let sum: f32 = k.iter().sum();
    let k: Vec<f32> = k.iter().map(|v| v / sum).collect();
    let mut tmp = vec![0f32; src.len()];
    for y in 0..height {
        for x in 0..width {
            let mut acc = 0.0;
            for (j, w) in k.iter().enumerate() {
                let xx = (x as i64 + j as i64 - 5).clamp(0, width as i64 - 1) as usize;
                acc += w * src[y * width + xx];
            }
            tmp[y * width + x] = acc;
        }
    }
    let mut out = vec![0f32; src.len()];
    for y in 0..height {
        for x in 0..width {
            let mut acc = 0.0;
            for (j, w) in k.iter().enumerate() {
                let yy = (y as i64 + j as i64 - 5).clamp(0, height as i64 - 1) as usize;
                acc += w * tmp[yy * width + x];
            }
            out[y * width + x] = acc;
        }
    }
    out
}

/// Mean SSIM (luma) over the pixels where `region` is true; `None` for an empty region.
/// Only the bounding box of the region is processed.
pub fn ssim_region(
    a: &[u8],
    b: &[u8],
    width: usize,
    height: usize,
    region: &[bool],
) -> Option<f64> {
    let (mut x0, mut y0, mut x1, mut y1) = (usize::MAX, usize::MAX, 0, 0);
    for (i, &r) in region.iter().enumerate() {
        if r {
            let (x, y) = (i % width, i / width);
            x0 = x0.min(x);
            y0 = y0.min(y);
            x1 = x1.max(x);
            y1 = y1.max(y);
        }
    }
    if x0 == usize::MAX {
        return None;
    }
    // Crop with a margin for the window.
    let (cx0, cy0) = (x0.saturating_sub(6), y0.saturating_sub(6));
    let (cx1, cy1) = ((x1 + 6).min(width - 1), (y1 + 6).min(height - 1));
    let (cw, ch) = (cx1 - cx0 + 1, cy1 - cy0 + 1);
    let crop = |img: &[u8]| {
        let mut out = Vec::with_capacity(cw * ch * 4);
        for y in cy0..=cy1 {
            out.extend_from_slice(&img[(y * width + cx0) * 4..(y * width + cx1 + 1) * 4]);
        }
        out
    };
    let (la, lb) = (luma(&crop(a), cw, ch), luma(&crop(b), cw, ch));
    let prod = |p: &[f32], q: &[f32]| p.iter().zip(q).map(|(x, y)| x * y).collect::<Vec<f32>>();
    let mu_a = blur(&la, cw, ch);
    let mu_b = blur(&lb, cw, ch);
    let s_aa = blur(&prod(&la, &la), cw, ch);
    let s_bb = blur(&prod(&lb, &lb), cw, ch);
    let s_ab = blur(&prod(&la, &lb), cw, ch);
    let (c1, c2) = ((0.01f32 * 255.0).powi(2), (0.03f32 * 255.0).powi(2));
    let mut total = 0f64;
    let mut n = 0usize;
    for y in cy0..=cy1 {
        for x in cx0..=cx1 {
            if !region[y * width + x] {
                continue;
            }
            let i = (y - cy0) * cw + (x - cx0);
            let (ma, mb) = (mu_a[i], mu_b[i]);
            let va = s_aa[i] - ma * ma;
            let vb = s_bb[i] - mb * mb;
            let cov = s_ab[i] - ma * mb;
            let s = ((2.0 * ma * mb + c1) * (2.0 * cov + c2))
                / ((ma * ma + mb * mb + c1) * (va + vb + c2));
            total += s as f64;
            n += 1;
        }
    }
    Some(total / n as f64)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn img(w: usize, h: usize, f: impl Fn(usize, usize) -> u8) -> Vec<u8> {
        let mut v = Vec::new();
        for y in 0..h {
            for x in 0..w {
                let c = f(x, y);
                v.extend_from_slice(&[c, c, c, 255]);
            }
        }
        v
    }

    #[test]
    fn psnr_of_a_known_error() {
        let a = img(8, 8, |_, _| 100);
        let b = img(8, 8, |_, _| 110); // MSE 100 -> 10 log10(65025/100) = 28.13 dB
        let all = vec![true; 64];
        let p = psnr_region(&a, &b, &all).expect("region");
        assert!((p - 28.1308).abs() < 1e-3, "{p}");
        assert_eq!(psnr_region(&a, &a, &all), Some(f64::INFINITY));
        assert_eq!(psnr_region(&a, &b, &[false; 64]), None);
    }

    #[test]
    fn ssim_is_one_for_identity_and_drops_with_noise() {
        let (w, h) = (40, 30);
        let a = img(w, h, |x, y| ((x * 7 + y * 13) % 256) as u8);
        let noisy = img(w, h, |x, y| {
            (((x * 7 + y * 13) % 256) as u8).wrapping_add(((x * y) % 23) as u8)
        });
        let region = vec![true; w * h];
        let s = ssim_region(&a, &a, w, h, &region).expect("region");
        assert!((s - 1.0).abs() < 1e-6, "{s}");
        let s2 = ssim_region(&a, &noisy, w, h, &region).expect("region");
        assert!(s2 < 0.95, "{s2}");
    }
}
