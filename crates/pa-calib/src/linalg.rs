//! Small dense linear algebra for calibration: the symmetric eigen-decomposition (cyclic
//! Jacobi), Cholesky factorisation, nearest rotation, and the normalised-DLT homography.
//! Matrices are row-major `&[f64]` slices of `n * n` values.

use glam::{DMat3, DVec2, DVec3};

/// Eigenvalues and eigenvectors of a symmetric `n` x `n` matrix (row-major). Returns
/// `(values, vectors)` where `vectors[i * n + k]` is component `i` of the eigenvector of
/// `values[k]`. Values are not sorted.
pub(crate) fn symmetric_eigen(a: &[f64], n: usize) -> (Vec<f64>, Vec<f64>) {
    let mut a = a.to_vec();
    let mut v = vec![0.0; n * n];
    for i in 0..n {
        v[i * n + i] = 1.0;
    }
    let norm: f64 = a.iter().map(|x| x * x).sum::<f64>().sqrt();
    for _sweep in 0..100 {
        let mut off = 0.0;
        for p in 0..n {
            for q in p + 1..n {
                off += a[p * n + q] * a[p * n + q];
            }
        }
        if off.sqrt() <= 1e-15 * norm || off == 0.0 {
            break;
        }
        for p in 0..n {
            for q in p + 1..n {
                let apq = a[p * n + q];
                if apq.abs() <= f64::MIN_POSITIVE {
                    continue;
                }
                let theta = (a[q * n + q] - a[p * n + p]) / (2.0 * apq);
                let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
                let c = 1.0 / (t * t + 1.0).sqrt();
                let s = t * c;
                for k in 0..n {
                    let (akp, akq) = (a[k * n + p], a[k * n + q]);
                    a[k * n + p] = c * akp - s * akq;
                    a[k * n + q] = s * akp + c * akq;
                }
                for k in 0..n {
                    let (apk, aqk) = (a[p * n + k], a[q * n + k]);
                    a[p * n + k] = c * apk - s * aqk;
                    a[q * n + k] = s * apk + c * aqk;
                }
                for k in 0..n {
                    let (vkp, vkq) = (v[k * n + p], v[k * n + q]);
                    v[k * n + p] = c * vkp - s * vkq;
                    v[k * n + q] = s * vkp + c * vkq;
                }
            }
        }
    }
    let values = (0..n).map(|i| a[i * n + i]).collect();
    (values, v)
}

/// The eigenvector of the smallest eigenvalue of a symmetric matrix, with the two smallest
/// eigenvalues (for a degeneracy test).
pub(crate) fn smallest_eigenvector(a: &[f64], n: usize) -> (Vec<f64>, f64, f64) {
    let (values, vectors) = symmetric_eigen(a, n);
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&i, &j| values[i].total_cmp(&values[j]));
    let k = order[0];
    let vec = (0..n).map(|i| vectors[i * n + k]).collect();
    let second = if n > 1 {
        values[order[1]]
    } else {
        f64::INFINITY
    };
    (vec, values[k], second)
}

/// Cholesky factor `L` (lower, row-major) of a symmetric positive definite matrix.
pub(crate) fn cholesky(a: &[f64], n: usize) -> Option<Vec<f64>> {
    let mut l = vec![0.0; n * n];
    for i in 0..n {
        for j in 0..=i {
            let mut s = a[i * n + j];
            for k in 0..j {
                s -= l[i * n + k] * l[j * n + k];
            }
            if i == j {
                if !(s > 0.0 && s.is_finite()) {
                    return None;
                }
                l[i * n + i] = s.sqrt();
            } else {
                l[i * n + j] = s / l[j * n + j];
            }
        }
    }
    Some(l)
}

/// Solves `L L^T x = b` given the Cholesky factor.
pub(crate) fn cholesky_solve(l: &[f64], n: usize, b: &[f64]) -> Vec<f64> {
    let mut y = b.to_vec();
    for i in 0..n {
        let mut s = y[i];
        for k in 0..i {
            s -= l[i * n + k] * y[k];
        }
        y[i] = s / l[i * n + i];
    }
    for i in (0..n).rev() {
        let mut s = y[i];
        for k in i + 1..n {
            s -= l[k * n + i] * y[k];
        }
        y[i] = s / l[i * n + i];
    }
    y
}

/// The inverse of a symmetric positive definite matrix, or `None` when it is not.
pub(crate) fn spd_inverse(a: &[f64], n: usize) -> Option<Vec<f64>> {
    let l = cholesky(a, n)?;
    let mut inv = vec![0.0; n * n];
    let mut e = vec![0.0; n];
    for k in 0..n {
        e.iter_mut().for_each(|x| *x = 0.0);
        e[k] = 1.0;
        let col = cholesky_solve(&l, n, &e);
        for i in 0..n {
            inv[i * n + k] = col[i];
        }
    }
    Some(inv)
}

/// The rotation nearest to `m` in the Frobenius norm (polar decomposition), or `None` when
/// `m` is singular or a reflection.
pub(crate) fn nearest_rotation(m: DMat3) -> Option<DMat3> {
    let mtm = m.transpose() * m;
    let a = mtm.transpose().to_cols_array(); // row-major of a symmetric matrix
    let (values, vectors) = symmetric_eigen(&a, 3);
    if values.iter().any(|v| v.is_nan() || *v <= 1e-300) {
        return None;
    }
    // (M^T M)^(-1/2) = V diag(1 / sqrt(s)) V^T.
    let mut inv_sqrt = DMat3::ZERO;
    for (k, s) in values.iter().enumerate() {
        let e = DVec3::new(vectors[k], vectors[3 + k], vectors[6 + k]);
        let outer = DMat3::from_cols(e * e.x, e * e.y, e * e.z);
        inv_sqrt += outer * (1.0 / s.sqrt());
    }
    let r = m * inv_sqrt;
    (r.determinant() > 0.0 && r.is_finite()).then_some(r)
}

/// Similarity that moves the centroid of `pts` to the origin and their mean distance to
/// sqrt(2) (Hartley's normalisation).
fn normalisation(pts: &[DVec2]) -> Option<DMat3> {
    let n = pts.len() as f64;
    let c = pts.iter().copied().sum::<DVec2>() / n;
    let mean = pts.iter().map(|p| p.distance(c)).sum::<f64>() / n;
    if !(mean > 1e-300 && mean.is_finite()) {
        return None;
    }
    let s = std::f64::consts::SQRT_2 / mean;
    Some(DMat3::from_cols(
        DVec3::new(s, 0.0, 0.0),
        DVec3::new(0.0, s, 0.0),
        DVec3::new(-s * c.x, -s * c.y, 1.0),
    ))
}

/// The homography `dst ~ H * src` from four or more point pairs (normalised DLT), or `None`
/// for fewer than four pairs or a degenerate configuration (collinear points).
pub(crate) fn homography_dlt(src: &[DVec2], dst: &[DVec2]) -> Option<DMat3> {
    if src.len() < 4 || src.len() != dst.len() {
        return None;
    }
    let ts = normalisation(src)?;
    let td = normalisation(dst)?;
    let mut ata = [0.0f64; 81];
    for (s, d) in src.iter().zip(dst) {
        let s = ts * s.extend(1.0);
        let d = td * d.extend(1.0);
        let (x, y, u, v) = (s.x, s.y, d.x, d.y);
        let r1 = [-x, -y, -1.0, 0.0, 0.0, 0.0, u * x, u * y, u];
        let r2 = [0.0, 0.0, 0.0, -x, -y, -1.0, v * x, v * y, v];
        for i in 0..9 {
            for j in i..9 {
                ata[i * 9 + j] += r1[i] * r1[j] + r2[i] * r2[j];
            }
        }
    }
    for i in 0..9 {
        for j in 0..i {
            ata[i * 9 + j] = ata[j * 9 + i];
        }
    }
    let (h, smallest, second) = smallest_eigenvector(&ata, 9);
    let largest = (0..9).map(|i| ata[i * 9 + i]).sum::<f64>();
    if second.is_nan() || second <= 1e-12 * largest || !smallest.is_finite() {
        return None;
    }
    // Row-major h -> glam (column-major).
    let hn =
        DMat3::from_cols_array(&[h[0], h[1], h[2], h[3], h[4], h[5], h[6], h[7], h[8]]).transpose();
    let hm = td.inverse() * hn * ts;
    let scale = if hm.z_axis.z.abs() > 1e-12 {
        hm.z_axis.z
    } else {
        hm.to_cols_array().iter().map(|x| x * x).sum::<f64>().sqrt()
    };
    let hm = hm * (1.0 / scale);
    hm.is_finite().then_some(hm)
}

/// Applies a homography to a point.
pub(crate) fn apply_homography(h: &DMat3, p: DVec2) -> Option<DVec2> {
    let q = *h * p.extend(1.0);
    (q.z.abs() > 1e-300).then(|| DVec2::new(q.x / q.z, q.y / q.z))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn eigen_of_known_matrix() {
        // [[2, 1], [1, 2]] has eigenvalues 1 and 3.
        let (v, _, second) = smallest_eigenvector(&[2.0, 1.0, 1.0, 2.0], 2);
        assert!((second - 3.0).abs() < 1e-12);
        assert!((v[0] + v[1]).abs() < 1e-12 && (v[0].abs() - 0.5f64.sqrt()).abs() < 1e-12);
    }

    #[test]
    fn cholesky_inverse_round_trip() {
        let a = [4.0, 2.0, 0.6, 2.0, 5.0, 1.0, 0.6, 1.0, 3.0];
        let inv = spd_inverse(&a, 3).expect("spd");
        for i in 0..3 {
            for j in 0..3 {
                let s: f64 = (0..3).map(|k| a[i * 3 + k] * inv[k * 3 + j]).sum();
                assert!((s - if i == j { 1.0 } else { 0.0 }).abs() < 1e-12);
            }
        }
        assert!(cholesky(&[1.0, 2.0, 2.0, 1.0], 2).is_none());
    }

    #[test]
    fn homography_recovers_a_projective_map() {
        let h = DMat3::from_cols(
            DVec3::new(800.0, 20.0, 0.1),
            DVec3::new(-30.0, 780.0, -0.05),
            DVec3::new(640.0, 360.0, 1.0),
        );
        let src: Vec<DVec2> = (0..20)
            .map(|i| DVec2::new((i % 5) as f64 * 0.1, (i / 5) as f64 * 0.1))
            .collect();
        let dst: Vec<DVec2> = src
            .iter()
            .map(|p| apply_homography(&h, *p).expect("finite"))
            .collect();
        let est = homography_dlt(&src, &dst).expect("solvable");
        for (s, d) in src.iter().zip(&dst) {
            let p = apply_homography(&est, *s).expect("finite");
            assert!(p.distance(*d) < 1e-8, "{p} vs {d}");
        }
        let line: Vec<DVec2> = (0..6)
            .map(|i| DVec2::new(i as f64, 2.0 * i as f64))
            .collect();
        assert!(homography_dlt(&line, &line).is_none());
    }

    #[test]
    fn nearest_rotation_of_a_noisy_rotation() {
        let r = DMat3::from_axis_angle(DVec3::new(1.0, 2.0, 3.0).normalize(), 0.7);
        let noisy = r + DMat3::from_cols_array(&[1e-3, 0.0, 2e-3, 0.0, -1e-3, 0.0, 0.0, 0.0, 1e-3]);
        let n = nearest_rotation(noisy).expect("rotation");
        assert!((n.determinant() - 1.0).abs() < 1e-12);
        assert!((n.transpose() * n - DMat3::IDENTITY).abs_diff_eq(DMat3::ZERO, 1e-12));
        assert!(n.abs_diff_eq(r, 3e-3));
    }
}
