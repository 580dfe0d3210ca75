//! Homographies: normalised DLT (exact for 4 points, least squares for more), RANSAC with an
//! adaptive iteration count and a least-squares refit on the inliers.

use glam::{DMat3, DVec2, DVec3};

/// Applies `h` to a point (`None` at infinity).
pub fn apply(h: &DMat3, p: DVec2) -> Option<DVec2> {
    let q = *h * DVec3::new(p.x, p.y, 1.0);
    (q.z.abs() > 1e-12).then(|| DVec2::new(q.x / q.z, q.y / q.z))
}

/// Similarity that moves the centroid to 0 and the mean distance to sqrt 2.
fn normaliser(pts: &[DVec2]) -> DMat3 {
    let n = pts.len().max(1) as f64;
    let c = pts.iter().copied().sum::<DVec2>() / n;
    let d = pts.iter().map(|p| p.distance(c)).sum::<f64>() / n;
    let s = if d > 1e-12 {
        std::f64::consts::SQRT_2 / d
    } else {
        1.0
    };
    DMat3::from_cols(
        DVec3::new(s, 0.0, 0.0),
        DVec3::new(0.0, s, 0.0),
        DVec3::new(-s * c.x, -s * c.y, 1.0),
    )
}

/// Solves the n x n system in place (Gaussian elimination, partial pivoting).
#[allow(clippy::needless_range_loop)]
fn solve<const N: usize>(mut a: [[f64; N]; N], mut b: [f64; N]) -> Option<[f64; N]> {
    for col in 0..N {
        let piv = (col..N).max_by(|&i, &j| a[i][col].abs().total_cmp(&a[j][col].abs()))?;
        if a[piv][col].abs() < 1e-12 {
            return None;
        }
        a.swap(col, piv);
        b.swap(col, piv);
        for r in col + 1..N {
            let f = a[r][col] / a[col][col];
            if f != 0.0 {
                for c in col..N {
                    a[r][c] -= f * a[col][c];
                }
                b[r] -= f * b[col];
            }
        }
    }
    let mut x = [0.0; N];
    for r in (0..N).rev() {
        let mut s = b[r];
        for c in r + 1..N {
            s -= a[r][c] * x[c];
        }
        x[r] = s / a[r][r];
    }
    x.iter().all(|v| v.is_finite()).then_some(x)
}

/// The homography mapping `src` to `dst` (least squares with h33 = 1 in normalised
/// coordinates; exact for 4 points in general position).
pub fn fit(src: &[DVec2], dst: &[DVec2]) -> Option<DMat3> {
    if src.len() < 4 || src.len() != dst.len() {
        return None;
    }
    let ts = normaliser(src);
    let td = normaliser(dst);
    let mut ata = [[0.0f64; 8]; 8];
    let mut atb = [0.0f64; 8];
    for (s, d) in src.iter().zip(dst) {
        let s = ts.transform_point2(*s);
        let d = td.transform_point2(*d);
        let rows = [
            ([s.x, s.y, 1.0, 0.0, 0.0, 0.0, -s.x * d.x, -s.y * d.x], d.x),
            ([0.0, 0.0, 0.0, s.x, s.y, 1.0, -s.x * d.y, -s.y * d.y], d.y),
        ];
        for (r, b) in rows {
            for i in 0..8 {
                atb[i] += r[i] * b;
                for j in 0..8 {
                    ata[i][j] += r[i] * r[j];
                }
            }
        }
    }
    let h = solve(ata, atb)?;
    let hn = DMat3::from_cols(
        DVec3::new(h[0], h[3], h[6]),
        DVec3::new(h[1], h[4], h[7]),
        DVec3::new(h[2], h[5], 1.0),
    );
    let out = td.inverse() * hn * ts;
    let s = out.z_axis.z;
    (s.abs() > 1e-12 && out.is_finite()).then(|| out * (1.0 / s))
}

/// Indices of the pairs whose transfer error under `h` is within `tol_px`.
pub fn inliers(h: &DMat3, src: &[DVec2], dst: &[DVec2], tol_px: f64) -> Vec<usize> {
    let t2 = tol_px * tol_px;
    (0..src.len())
        .filter(|&i| apply(h, src[i]).is_some_and(|p| p.distance_squared(dst[i]) <= t2))
        .collect()
}

/// Whether the 4 points form a convex quadrilateral with consistent orientation.
fn convex(q: &[DVec2; 4]) -> bool {
    let mut sign = 0.0;
    for i in 0..4 {
        let a = q[(i + 1) % 4] - q[i];
        let b = q[(i + 2) % 4] - q[(i + 1) % 4];
        let c = a.perp_dot(b);
        if c.abs() < 1e-9 || (sign != 0.0 && c * sign < 0.0) {
            return false;
        }
        sign = c;
    }
    true
}

/// RANSAC: the homography with the most inliers (transfer error within `tol_px`), refitted
/// on them; `None` when fewer than `min_inliers` agree. The sample order is a fixed
/// pseudo-random sequence (deterministic results).
pub fn ransac(
    src: &[DVec2],
    dst: &[DVec2],
    tol_px: f64,
    max_iter: usize,
    min_inliers: usize,
) -> Option<(DMat3, Vec<usize>)> {
    let n = src.len();
    if n < 4.max(min_inliers) {
        return None;
    }
    let mut state: u64 = 0x2545_F491_4F6C_DD1D ^ n as u64;
    let mut next = |m: usize| {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state % m as u64) as usize
    };
    let mut best: Option<(DMat3, usize)> = None;
    let mut iters = max_iter;
    let mut it = 0;
    while it < iters {
        it += 1;
        let mut idx = [0usize; 4];
        let mut k = 0;
        let mut guard = 0;
        while k < 4 && guard < 100 {
            guard += 1;
            let c = next(n);
            if !idx[..k].contains(&c) {
                idx[k] = c;
                k += 1;
            }
        }
        if k < 4 {
            continue;
        }
        let s = idx.map(|i| src[i]);
        let d = idx.map(|i| dst[i]);
        if !convex(&s) || !convex(&d) {
            continue;
        }
        let Some(h) = fit(&s, &d) else { continue };
        let count = inliers(&h, src, dst, tol_px).len();
        if best.as_ref().is_none_or(|(_, c)| count > *c) {
            best = Some((h, count));
            let w = count as f64 / n as f64;
            let p_fail = (1.0 - w.powi(4)).max(1e-12);
            if p_fail < 1.0 {
                let need = ((1.0f64 - 0.999).ln() / p_fail.ln()).ceil();
                if need.is_finite() {
                    iters = iters.min(need.max(16.0) as usize);
                }
            }
        }
    }
    let (mut h, _) = best?;
    let mut inl = inliers(&h, src, dst, tol_px);
    for _ in 0..2 {
        if inl.len() < min_inliers.max(4) {
            return None;
        }
        let s: Vec<DVec2> = inl.iter().map(|&i| src[i]).collect();
        let d: Vec<DVec2> = inl.iter().map(|&i| dst[i]).collect();
        h = fit(&s, &d)?;
        inl = inliers(&h, src, dst, tol_px);
    }
    (inl.len() >= min_inliers.max(4)).then_some((h, inl))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn four_points_exact_and_ransac_rejects_outliers() {
        let h = DMat3::from_cols(
            DVec3::new(1.1, 0.1, 0.0004),
            DVec3::new(-0.2, 0.9, 0.0002),
            DVec3::new(30.0, -12.0, 1.0),
        );
        let src: Vec<DVec2> = (0..60)
            .map(|i| DVec2::new((i * 37 % 300) as f64, (i * 53 % 200) as f64))
            .collect();
        let mut dst: Vec<DVec2> = src.iter().map(|p| apply(&h, *p).unwrap()).collect();
        let quad = [
            DVec2::new(0.0, 0.0),
            DVec2::new(300.0, 10.0),
            DVec2::new(280.0, 200.0),
            DVec2::new(-5.0, 190.0),
        ];
        let g = fit(&quad, &quad.map(|p| apply(&h, p).unwrap())).unwrap();
        for p in &src {
            assert!(apply(&g, *p).unwrap().distance(apply(&h, *p).unwrap()) < 1e-6);
        }
        for d in dst.iter_mut().step_by(3) {
            *d += DVec2::new(25.0, -40.0);
        }
        let (g, inl) = ransac(&src, &dst, 1.0, 500, 10).unwrap();
        assert_eq!(inl.len(), 40);
        for p in &src {
            assert!(apply(&g, *p).unwrap().distance(apply(&h, *p).unwrap()) < 1e-6);
        }
    }
}
