//! Camera calibration from views of a planar target: Zhang's closed-form initialisation
//! followed by Levenberg-Marquardt bundle adjustment of the intrinsics, distortion and
//! per-view poses.
//!
//! # Model and parameters
//!
//! A board point `X` (board frame, metres, z = 0) is seen at pixel
//! `K * distort(project(R_v X + t_v))` with [`pa_camera::Intrinsics`] `K` (fx, fy, cx, cy; no
//! skew) and [`pa_camera::Distortion::distort`] (k1, k2, p1, p2, k3), OpenCV's model and
//! pixel convention (centre of pixel (0, 0) at (0, 0)). Poses are `camera_from_board`.
//!
//! # Initialisation
//!
//! Per view, the plane homography (normalised DLT). Intrinsics from Zhang's constraints
//! `h1' B h2 = 0`, `h1' B h1 = h2' B h2` with zero skew (4 unknowns: two views at different
//! angles suffice), in normalised pixel coordinates for conditioning. As OpenCV does when
//! views are few or alike, a second start puts the principal point at the image centre and
//! solves only for fx, fy. Each start's poses come from the homographies; both are refined
//! and the one with the lower final error is kept.
//!
//! # Refinement
//!
//! Levenberg-Marquardt with Marquardt's diagonal scaling on the sum of squared pixel errors.
//! Rotations are updated multiplicatively (`R <- exp([d]x) R`), reported as rotation vectors.
//! The normal equations have one 9x9 intrinsics block and one 6x6 block per view; the pose
//! blocks are eliminated (Schur complement), so a step costs O(views).

use glam::{DMat3, DQuat, DVec2, DVec3};
use pa_camera::{CameraModel, Distortion, Intrinsics};

use crate::linalg::{cholesky, cholesky_solve, homography_dlt, nearest_rotation, spd_inverse};
use crate::{CalibWarning, CalibrateError, View};

/// Which parameters the calibration estimates.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default)]
pub struct CalibOptions {
    /// Keep k3 at 0 (default **true**). The sixth-order term is poorly constrained for
    /// ordinary lenses and overfits: it bends the model where the views have no corners
    /// (image corners). Estimate it for wide-angle lenses, with views reaching the corners.
    pub fix_k3: bool,
    /// Keep p1 = p2 = 0 (default false: tangential distortion is estimated).
    pub fix_tangential: bool,
    /// Levenberg-Marquardt iterations at most.
    pub max_iterations: usize,
}

impl Default for CalibOptions {
    fn default() -> Self {
        Self {
            fix_k3: true,
            fix_tangential: false,
            max_iterations: 100,
        }
    }
}

impl CalibOptions {
    /// The OpenCV `calibrateCamera` flags these options correspond to
    /// (`CALIB_ZERO_TANGENT_DIST` = 8, `CALIB_FIX_K3` = 128).
    pub fn opencv_flags(&self) -> u32 {
        (if self.fix_tangential { 8 } else { 0 }) | (if self.fix_k3 { 128 } else { 0 })
    }

    fn free_mask(&self) -> [bool; N_INTR] {
        [
            true,
            true,
            true,
            true,
            true,
            true,
            !self.fix_tangential,
            !self.fix_tangential,
            !self.fix_k3,
        ]
    }
}

/// One standard deviation of each intrinsic parameter (pixels for fx, fy, cx, cy; unitless
/// for the distortion), from the covariance `sigma^2 (J^T J)^-1` at the solution with
/// `sigma^2` the residual variance per coordinate. Fixed parameters have 0; parameters the
/// views do not determine have infinity.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct IntrinsicsStdDev {
    pub fx: f64,
    pub fy: f64,
    pub cx: f64,
    pub cy: f64,
    pub k1: f64,
    pub k2: f64,
    pub p1: f64,
    pub p2: f64,
    pub k3: f64,
}

/// The result for one view.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ViewResult {
    /// The view's name (its file).
    pub name: String,
    /// Number of correspondences.
    pub points: usize,
    /// RMS reprojection error, pixels.
    pub rms_px: f64,
    /// Largest reprojection error, pixels.
    pub max_px: f64,
    /// `camera_from_board` rotation as a rotation vector (axis times angle, radians), as
    /// OpenCV's `rvecs`.
    pub rotation_vector: DVec3,
    /// `camera_from_board` translation, metres, as OpenCV's `tvecs`.
    pub translation_m: DVec3,
}

impl ViewResult {
    /// The pose `camera_from_board`.
    pub fn camera_from_board(&self) -> pa_track::Pose {
        pa_track::Pose {
            rotation: DQuat::from_scaled_axis(self.rotation_vector),
            translation: self.translation_m,
        }
    }
}

/// A calibration.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Calibration {
    /// The calibrated camera (image size of the views).
    pub camera: CameraModel,
    /// RMS reprojection error over all points, pixels: `sqrt(sum |e|^2 / points)`, the
    /// figure OpenCV's `calibrateCamera` returns.
    pub rms_px: f64,
    /// Per view, in the order given.
    pub views: Vec<ViewResult>,
    /// Standard deviations of the intrinsics.
    pub std_dev: IntrinsicsStdDev,
    /// What was estimated.
    pub options: CalibOptions,
    /// Levenberg-Marquardt iterations used.
    pub iterations: usize,
    /// Doubts about the result (few or alike views, poorly constrained parameters, ...).
    pub warnings: Vec<CalibWarning>,
}

impl Calibration {
    /// Total number of correspondences.
    pub fn points(&self) -> usize {
        self.views.iter().map(|v| v.points).sum()
    }
}

/// Views below which calibration is refused: Zhang's constraints give two equations per
/// view for four intrinsics.
pub const MIN_VIEWS: usize = 2;
/// Views below which a warning is given.
pub const RECOMMENDED_VIEWS: usize = 5;
/// Board normals all within this angle of each other give a warning, degrees.
pub const SIMILAR_VIEWS_DEG: f64 = 10.0;

const N_INTR: usize = 9;

#[derive(Clone)]
struct State {
    /// fx, fy, cx, cy, k1, k2, p1, p2, k3.
    intr: [f64; N_INTR],
    poses: Vec<(DMat3, DVec3)>,
}

impl State {
    fn camera(&self, width: u32, height: u32) -> CameraModel {
        let p = &self.intr;
        CameraModel {
            intrinsics: Intrinsics {
                fx: p[0],
                fy: p[1],
                cx: p[2],
                cy: p[3],
                width,
                height,
            },
            distortion: Distortion {
                k1: p[4],
                k2: p[5],
                p1: p[6],
                p2: p[7],
                k3: p[8],
            },
        }
    }
}

/// Projection of one point with its Jacobians: `(pixel, d pixel / d intrinsics (2x9),
/// d pixel / d point in camera frame (2x3))`. `None` at or behind the camera.
#[allow(clippy::type_complexity)]
fn project(intr: &[f64; N_INTR], pc: DVec3) -> Option<(DVec2, [[f64; N_INTR]; 2], [[f64; 3]; 2])> {
    if pc.z <= 1e-9 {
        return None;
    }
    let [fx, fy, _cx, _cy, k1, k2, p1, p2, k3] = *intr;
    let iz = 1.0 / pc.z;
    let (x, y) = (pc.x * iz, pc.y * iz);
    let r2 = x * x + y * y;
    let r4 = r2 * r2;
    let r6 = r4 * r2;
    let radial = 1.0 + k1 * r2 + k2 * r4 + k3 * r6;
    let xd = x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x);
    let yd = y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y;
    let px = DVec2::new(fx * xd + intr[2], fy * yd + intr[3]);
    let ji = [
        [
            xd,
            0.0,
            1.0,
            0.0,
            fx * x * r2,
            fx * x * r4,
            fx * 2.0 * x * y,
            fx * (r2 + 2.0 * x * x),
            fx * x * r6,
        ],
        [
            0.0,
            yd,
            0.0,
            1.0,
            fy * y * r2,
            fy * y * r4,
            fy * (r2 + 2.0 * y * y),
            fy * 2.0 * x * y,
            fy * y * r6,
        ],
    ];
    let dr = k1 + 2.0 * k2 * r2 + 3.0 * k3 * r4; // d radial / d r2
    let dxd_dx = radial + 2.0 * x * x * dr + 2.0 * p1 * y + 6.0 * p2 * x;
    let dxd_dy = 2.0 * x * y * dr + 2.0 * p1 * x + 2.0 * p2 * y;
    let dyd_dx = 2.0 * x * y * dr + 2.0 * p1 * x + 2.0 * p2 * y;
    let dyd_dy = radial + 2.0 * y * y * dr + 6.0 * p1 * y + 2.0 * p2 * x;
    // d(x, y) / d pc = [[iz, 0, -x iz], [0, iz, -y iz]].
    let a = [[fx * dxd_dx, fx * dxd_dy], [fy * dyd_dx, fy * dyd_dy]];
    let jp = [
        [
            a[0][0] * iz,
            a[0][1] * iz,
            -(a[0][0] * x + a[0][1] * y) * iz,
        ],
        [
            a[1][0] * iz,
            a[1][1] * iz,
            -(a[1][0] * x + a[1][1] * y) * iz,
        ],
    ];
    Some((px, ji, jp))
}

/// Sum of squared errors, or `None` when a point is behind a camera.
fn cost(state: &State, views: &[View]) -> Option<f64> {
    let mut sum = 0.0;
    for (v, (r, t)) in views.iter().zip(&state.poses) {
        for (o, m) in v.object_points_m.iter().zip(&v.image_points_px) {
            let (px, _, _) = project(&state.intr, *r * *o + *t)?;
            sum += px.distance_squared(*m);
        }
    }
    sum.is_finite().then_some(sum)
}

/// The normal equations in block form.
struct Normal {
    u: [f64; N_INTR * N_INTR],
    gi: [f64; N_INTR],
    w: Vec<[f64; N_INTR * 6]>,
    v: Vec<[f64; 36]>,
    gv: Vec<[f64; 6]>,
}

fn normal_equations(state: &State, views: &[View], free: &[bool; N_INTR]) -> Option<Normal> {
    let nv = views.len();
    let mut ne = Normal {
        u: [0.0; N_INTR * N_INTR],
        gi: [0.0; N_INTR],
        w: vec![[0.0; N_INTR * 6]; nv],
        v: vec![[0.0; 36]; nv],
        gv: vec![[0.0; 6]; nv],
    };
    for (k, (view, (r, t))) in views.iter().zip(&state.poses).enumerate() {
        for (o, m) in view.object_points_m.iter().zip(&view.image_points_px) {
            let a = *r * *o;
            let (px, mut ji, jp) = project(&state.intr, a + *t)?;
            let e = px - *m;
            for row in ji.iter_mut() {
                for (j, f) in free.iter().enumerate() {
                    if !f {
                        row[j] = 0.0;
                    }
                }
            }
            // d pc / d rotation (left increment) = -[a]x; d pc / d t = I.
            let skew = [[0.0, a.z, -a.y], [-a.z, 0.0, a.x], [a.y, -a.x, 0.0]];
            let mut jpose = [[0.0; 6]; 2];
            for row in 0..2 {
                for c in 0..3 {
                    jpose[row][c] = (0..3).map(|l| jp[row][l] * skew[l][c]).sum();
                    jpose[row][3 + c] = jp[row][c];
                }
            }
            let err = [e.x, e.y];
            for row in 0..2 {
                let (jir, jpr, er) = (&ji[row], &jpose[row], err[row]);
                for i in 0..N_INTR {
                    if jir[i] == 0.0 {
                        continue;
                    }
                    ne.gi[i] += jir[i] * er;
                    for j in i..N_INTR {
                        ne.u[i * N_INTR + j] += jir[i] * jir[j];
                    }
                    for (j, p) in jpr.iter().enumerate() {
                        ne.w[k][i * 6 + j] += jir[i] * p;
                    }
                }
                for i in 0..6 {
                    ne.gv[k][i] += jpr[i] * er;
                    for j in i..6 {
                        ne.v[k][i * 6 + j] += jpr[i] * jpr[j];
                    }
                }
            }
        }
    }
    for i in 0..N_INTR {
        for j in 0..i {
            ne.u[i * N_INTR + j] = ne.u[j * N_INTR + i];
        }
    }
    for v in ne.v.iter_mut() {
        for i in 0..6 {
            for j in 0..i {
                v[i * 6 + j] = v[j * 6 + i];
            }
        }
    }
    Some(ne)
}

/// Solves the damped system; returns the intrinsics and pose steps.
#[allow(clippy::type_complexity)]
fn solve_step(
    ne: &Normal,
    lambda: f64,
    free: &[bool; N_INTR],
    intrinsics_fixed: bool,
) -> Option<([f64; N_INTR], Vec<[f64; 6]>)> {
    let nv = ne.v.len();
    // Damped pose blocks and their inverses' actions.
    let mut vinv_l = Vec::with_capacity(nv);
    for v in &ne.v {
        let mut d = *v;
        for i in 0..6 {
            d[i * 6 + i] += lambda * v[i * 6 + i] + 1e-12;
        }
        vinv_l.push(cholesky(&d, 6)?);
    }
    let mut di = [0.0; N_INTR];
    if !intrinsics_fixed {
        // Schur complement S = U - sum W V^-1 W^T, rhs = -gi + sum W V^-1 gv.
        let mut s = ne.u;
        let mut rhs = [0.0; N_INTR];
        for i in 0..N_INTR {
            s[i * N_INTR + i] += lambda * ne.u[i * N_INTR + i] + 1e-12;
            rhs[i] = -ne.gi[i];
        }
        for (k, lk) in vinv_l.iter().enumerate() {
            // V^-1 W^T: 6 x 9, column by column.
            let mut vw = [[0.0; 6]; N_INTR];
            for (i, col) in vw.iter_mut().enumerate() {
                let wt: Vec<f64> = (0..6).map(|j| ne.w[k][i * 6 + j]).collect();
                let x = cholesky_solve(lk, 6, &wt);
                col.copy_from_slice(&x);
            }
            let vg = cholesky_solve(lk, 6, &ne.gv[k]);
            for i in 0..N_INTR {
                for j in 0..N_INTR {
                    let d: f64 = (0..6).map(|l| ne.w[k][i * 6 + l] * vw[j][l]).sum();
                    s[i * N_INTR + j] -= d;
                }
                let d: f64 = (0..6).map(|l| ne.w[k][i * 6 + l] * vg[l]).sum();
                rhs[i] += d;
            }
        }
        for i in 0..N_INTR {
            if !free[i] {
                for j in 0..N_INTR {
                    s[i * N_INTR + j] = 0.0;
                    s[j * N_INTR + i] = 0.0;
                }
                s[i * N_INTR + i] = 1.0;
                rhs[i] = 0.0;
            }
        }
        let l = cholesky(&s, N_INTR)?;
        di.copy_from_slice(&cholesky_solve(&l, N_INTR, &rhs));
    }
    let mut dv = Vec::with_capacity(nv);
    for (k, lk) in vinv_l.iter().enumerate() {
        // V dv = -gv - W^T di.
        let rhs: Vec<f64> = (0..6)
            .map(|j| -ne.gv[k][j] - (0..N_INTR).map(|i| ne.w[k][i * 6 + j] * di[i]).sum::<f64>())
            .collect();
        let x = cholesky_solve(lk, 6, &rhs);
        let mut a = [0.0; 6];
        a.copy_from_slice(&x);
        dv.push(a);
    }
    Some((di, dv))
}

fn apply(state: &State, di: &[f64; N_INTR], dv: &[[f64; 6]]) -> State {
    let mut s = state.clone();
    for (x, d) in s.intr.iter_mut().zip(di) {
        *x += d;
    }
    for ((r, t), d) in s.poses.iter_mut().zip(dv) {
        let w = DVec3::new(d[0], d[1], d[2]);
        *r = DMat3::from_quat(DQuat::from_scaled_axis(w)) * *r;
        *t += DVec3::new(d[3], d[4], d[5]);
    }
    s
}

/// Levenberg-Marquardt; returns the refined state, its cost and the iterations used.
fn levenberg_marquardt(
    mut state: State,
    views: &[View],
    free: &[bool; N_INTR],
    intrinsics_fixed: bool,
    max_iter: usize,
) -> Option<(State, f64, usize)> {
    let mut c = cost(&state, views)?;
    let mut lambda = 1e-3;
    let mut it = 0;
    while it < max_iter {
        it += 1;
        let ne = normal_equations(&state, views, free)?;
        let mut improved = false;
        let mut small_step = false;
        while lambda < 1e12 {
            let Some((di, dv)) = solve_step(&ne, lambda, free, intrinsics_fixed) else {
                lambda *= 10.0;
                continue;
            };
            let cand = apply(&state, &di, &dv);
            match cost(&cand, views) {
                Some(nc) if nc < c => {
                    let rel = (c - nc) / c.max(1e-300);
                    let step_rel = (0..N_INTR)
                        .map(|i| (di[i] / state.intr[i].abs().max(1.0)).abs())
                        .fold(0.0, f64::max);
                    small_step = rel < 1e-12 || (rel < 1e-9 && step_rel < 1e-10);
                    state = cand;
                    c = nc;
                    lambda = (lambda * 0.3).max(1e-12);
                    improved = true;
                    break;
                }
                _ => lambda *= 10.0,
            }
        }
        if !improved || small_step || c < 1e-24 {
            break;
        }
    }
    Some((state, c, it))
}

fn view_normal(r: &DMat3) -> DVec3 {
    r.z_axis
}

/// Poses from homographies for given intrinsics: `[r1 r2 t] ~ K^-1 H`.
fn poses_from_homographies(hs: &[DMat3], k: &DMat3) -> Option<Vec<(DMat3, DVec3)>> {
    let kinv = k.inverse();
    hs.iter()
        .map(|h| {
            let m = kinv * *h;
            let (a, b, c) = (m.x_axis, m.y_axis, m.z_axis);
            let mut lambda = 2.0 / (a.length() + b.length());
            if c.z * lambda < 0.0 {
                lambda = -lambda;
            }
            let (r1, r2, t) = (a * lambda, b * lambda, c * lambda);
            let r = nearest_rotation(DMat3::from_cols(r1, r2, r1.cross(r2)))?;
            (t.is_finite() && t.z > 0.0).then_some((r, t))
        })
        .collect()
}

/// Zhang's closed form with zero skew, in normalised pixel coordinates. Returns fx, fy, cx, cy.
fn zhang_intrinsics(hs: &[DMat3], norm: &DMat3, scale: f64, c0: DVec2) -> Option<[f64; 4]> {
    let mut vtv = [0.0; 25];
    for h in hs {
        let hn = *norm * *h;
        let f = hn.to_cols_array().iter().map(|x| x * x).sum::<f64>().sqrt();
        let hn = hn * (1.0 / f);
        let (h1, h2) = (hn.x_axis, hn.y_axis);
        let v = |a: DVec3, b: DVec3| {
            [
                a.x * b.x,
                a.y * b.y,
                a.x * b.z + a.z * b.x,
                a.y * b.z + a.z * b.y,
                a.z * b.z,
            ]
        };
        let v12 = v(h1, h2);
        let v11 = v(h1, h1);
        let v22 = v(h2, h2);
        let d: Vec<f64> = (0..5).map(|i| v11[i] - v22[i]).collect();
        for row in [&v12[..], &d[..]] {
            for i in 0..5 {
                for j in 0..5 {
                    vtv[i * 5 + j] += row[i] * row[j];
                }
            }
        }
    }
    let (b, _, second) = crate::linalg::smallest_eigenvector(&vtv, 5);
    let trace: f64 = (0..5).map(|i| vtv[i * 5 + i]).sum();
    if second.is_nan() || second <= 1e-14 * trace {
        return None;
    }
    let (b11, b22, b13, b23, b33) = (b[0], b[1], b[2], b[3], b[4]);
    if b11 == 0.0 || b22 == 0.0 {
        return None;
    }
    let cx = -b13 / b11;
    let cy = -b23 / b22;
    let lam = b33 - b13 * b13 / b11 - b23 * b23 / b22;
    let (fx2, fy2) = (lam / b11, lam / b22);
    if !(fx2 > 0.0 && fy2 > 0.0) {
        return None;
    }
    let (fx, fy) = (fx2.sqrt(), fy2.sqrt());
    let plausible = |f: f64| (0.05..50.0).contains(&f);
    if !(plausible(fx) && plausible(fy) && cx.abs() < 1.0 && cy.abs() < 1.0) {
        return None;
    }
    Some([fx * scale, fy * scale, cx * scale + c0.x, cy * scale + c0.y])
}

/// OpenCV-style start: principal point at the image centre, fx and fy from the orthogonality
/// constraints (square pixels when the two cannot be separated).
fn centred_intrinsics(hs: &[DMat3], norm: &DMat3, scale: f64, c0: DVec2) -> Option<[f64; 4]> {
    let mut rows: Vec<([f64; 2], f64)> = Vec::new();
    for h in hs {
        let hn = *norm * *h;
        let f = hn.to_cols_array().iter().map(|x| x * x).sum::<f64>().sqrt();
        let hn = hn * (1.0 / f);
        let (h1, h2) = (hn.x_axis, hn.y_axis);
        rows.push(([h1.x * h2.x, h1.y * h2.y], -h1.z * h2.z));
        rows.push((
            [h1.x * h1.x - h2.x * h2.x, h1.y * h1.y - h2.y * h2.y],
            -(h1.z * h1.z - h2.z * h2.z),
        ));
    }
    let (mut a00, mut a01, mut a11, mut b0, mut b1) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for (r, y) in &rows {
        a00 += r[0] * r[0];
        a01 += r[0] * r[1];
        a11 += r[1] * r[1];
        b0 += r[0] * y;
        b1 += r[1] * y;
    }
    let det = a00 * a11 - a01 * a01;
    let plausible = |f: f64| (0.05..50.0).contains(&f);
    if det > 1e-12 * (a00 + a11) * (a00 + a11) {
        let a = (a11 * b0 - a01 * b1) / det;
        let c = (a00 * b1 - a01 * b0) / det;
        if a > 0.0 && c > 0.0 {
            let (fx, fy) = (1.0 / a.sqrt(), 1.0 / c.sqrt());
            if plausible(fx) && plausible(fy) && (fx / fy - 1.0).abs() < 0.5 {
                return Some([fx * scale, fy * scale, c0.x, c0.y]);
            }
        }
    }
    // Square pixels: one unknown.
    let (mut num, mut den) = (0.0, 0.0);
    for (r, y) in &rows {
        let s = r[0] + r[1];
        num += s * y;
        den += s * s;
    }
    let a = num / den;
    if den > 0.0 && a > 0.0 {
        let f = 1.0 / a.sqrt();
        if plausible(f) {
            return Some([f * scale, f * scale, c0.x, c0.y]);
        }
    }
    None
}

/// Calibrates a camera of `width` x `height` pixels from views of a planar target.
///
/// Errors: fewer than [`MIN_VIEWS`] views, a view with fewer than 4 points, with mismatched
/// point lists or with non-planar object points ([`CalibrateError::BadView`]), or geometry
/// from which no camera can be computed ([`CalibrateError::Degenerate`]: a view whose points
/// are collinear, no start with the board in front of the camera). Views that give a camera
/// the data do not pin down (all alike, all face-on) give a result with warnings
/// ([`Calibration::warnings`]: similar views, poorly constrained parameters), so that the
/// caller decides.
pub fn calibrate_views(
    views: &[View],
    width: u32,
    height: u32,
    options: &CalibOptions,
) -> Result<Calibration, CalibrateError> {
    if views.len() < MIN_VIEWS {
        return Err(CalibrateError::TooFewViews {
            found: views.len(),
            needed: MIN_VIEWS,
        });
    }
    if width == 0 || height == 0 {
        return Err(CalibrateError::Degenerate {
            reason: format!("image size {width}x{height}"),
        });
    }
    let mut hs = Vec::with_capacity(views.len());
    for v in views {
        let bad = |reason: String| CalibrateError::BadView {
            view: v.name.clone(),
            reason,
        };
        if v.object_points_m.len() != v.image_points_px.len() {
            return Err(bad(format!(
                "{} object points but {} image points",
                v.object_points_m.len(),
                v.image_points_px.len()
            )));
        }
        if v.object_points_m.len() < 4 {
            return Err(bad(format!(
                "{} points; a view needs at least 4",
                v.object_points_m.len()
            )));
        }
        if v.object_points_m
            .iter()
            .any(|p| !p.is_finite() || p.z.abs() > 1e-9)
            || v.image_points_px.iter().any(|p| !p.is_finite())
        {
            return Err(bad(
                "object points must be finite and lie on the board plane z = 0".into(),
            ));
        }
        let src: Vec<DVec2> = v.object_points_m.iter().map(|p| p.truncate()).collect();
        let h =
            homography_dlt(&src, &v.image_points_px).ok_or_else(|| CalibrateError::Degenerate {
                reason: format!("view {}: the points do not span the plane", v.name),
            })?;
        hs.push(h);
    }

    let scale = 0.5 * (width as f64 + height as f64);
    let c0 = DVec2::new((width as f64 - 1.0) * 0.5, (height as f64 - 1.0) * 0.5);
    let norm = DMat3::from_cols(
        DVec3::new(1.0 / scale, 0.0, 0.0),
        DVec3::new(0.0, 1.0 / scale, 0.0),
        DVec3::new(-c0.x / scale, -c0.y / scale, 1.0),
    );
    let starts: Vec<[f64; 4]> = [
        zhang_intrinsics(&hs, &norm, scale, c0),
        centred_intrinsics(&hs, &norm, scale, c0),
    ]
    .into_iter()
    .flatten()
    .collect();
    let free = options.free_mask();
    let mut best: Option<(State, f64, usize)> = None;
    for k4 in starts {
        let kmat = DMat3::from_cols(
            DVec3::new(k4[0], 0.0, 0.0),
            DVec3::new(0.0, k4[1], 0.0),
            DVec3::new(k4[2], k4[3], 1.0),
        );
        let Some(poses) = poses_from_homographies(&hs, &kmat) else {
            continue;
        };
        let state = State {
            intr: [k4[0], k4[1], k4[2], k4[3], 0.0, 0.0, 0.0, 0.0, 0.0],
            poses,
        };
        // Poses alone first (cheap, block diagonal), then everything.
        let Some((state, _, _)) = levenberg_marquardt(state, views, &free, true, 20) else {
            continue;
        };
        let Some((state, c, it)) =
            levenberg_marquardt(state, views, &free, false, options.max_iterations)
        else {
            continue;
        };
        let sane = state.intr.iter().all(|v| v.is_finite())
            && state.intr[0] > 0.0
            && state.intr[1] > 0.0
            && state.camera(width, height).intrinsics.validate().is_ok();
        if sane && best.as_ref().is_none_or(|b| c < b.1) {
            best = Some((state, c, it));
        }
    }
    let Some((state, total, iterations)) = best else {
        return Err(CalibrateError::Degenerate {
            reason: "no starting camera puts the boards in front of it (are the correspondences \
                     mixed up?)"
                .into(),
        });
    };

    let camera = state.camera(width, height);
    let mut results = Vec::with_capacity(views.len());
    let mut n_points = 0usize;
    for (v, (r, t)) in views.iter().zip(&state.poses) {
        let mut sum = 0.0;
        let mut max: f64 = 0.0;
        for (o, m) in v.object_points_m.iter().zip(&v.image_points_px) {
            let e = camera
                .pixel_from_camera(*r * *o + *t)
                .map_or(f64::INFINITY, |p| p.distance(*m));
            sum += e * e;
            max = max.max(e);
        }
        n_points += v.object_points_m.len();
        results.push(ViewResult {
            name: v.name.clone(),
            points: v.object_points_m.len(),
            rms_px: (sum / v.object_points_m.len() as f64).sqrt(),
            max_px: max,
            rotation_vector: DQuat::from_mat3(r).normalize().to_scaled_axis(),
            translation_m: *t,
        });
    }
    let rms_px = (total / n_points as f64).sqrt();

    // Covariance of the intrinsics: sigma^2 S^-1 with S the undamped Schur complement.
    let n_free = free.iter().filter(|f| **f).count() + 6 * views.len();
    let dof = (2 * n_points).saturating_sub(n_free).max(1);
    let sigma2 = total / dof as f64;
    let (std_dev, unit_std) = intrinsics_std(&state, views, &free, sigma2);

    let mut warnings = Vec::new();
    if views.len() < RECOMMENDED_VIEWS {
        warnings.push(CalibWarning::FewViews {
            views: views.len(),
            recommended: RECOMMENDED_VIEWS,
        });
    }
    let mut max_angle: f64 = 0.0;
    for (i, a) in state.poses.iter().enumerate() {
        for b in &state.poses[i + 1..] {
            let c = view_normal(&a.0).dot(view_normal(&b.0)).clamp(-1.0, 1.0);
            max_angle = max_angle.max(c.acos().to_degrees());
        }
    }
    if max_angle < SIMILAR_VIEWS_DEG {
        warnings.push(CalibWarning::SimilarViews {
            max_angle_deg: max_angle,
            threshold_deg: SIMILAR_VIEWS_DEG,
        });
    }
    // Poorly determined parameters, judged at no less than 0.1 px of noise (so that
    // noiseless but degenerate views are caught too).
    let (noise, judge) = (sigma2.sqrt(), sigma2.max(0.01).sqrt());
    let k = camera.intrinsics;
    let pp_limit = PRINCIPAL_POINT_STD_LIMIT * width.max(height) as f64;
    for (name, s, limit) in [
        ("fx", unit_std[0] * judge, FOCAL_STD_LIMIT * k.fx),
        ("fy", unit_std[1] * judge, FOCAL_STD_LIMIT * k.fy),
        ("cx", unit_std[2] * judge, pp_limit),
        ("cy", unit_std[3] * judge, pp_limit),
    ] {
        if s.is_nan() || s > limit {
            warnings.push(CalibWarning::PoorlyConstrained {
                parameter: name,
                std_dev_px: s / judge * noise,
                judged_noise_px: judge,
                judged_std_dev_px: s,
                limit_px: limit,
            });
        }
    }
    let coverage = coverage(views, width, height);
    if coverage < MIN_COVERAGE {
        warnings.push(CalibWarning::LowCoverage {
            fraction: coverage,
            recommended: MIN_COVERAGE,
        });
    }
    let mut sorted: Vec<f64> = results.iter().map(|r| r.rms_px).collect();
    sorted.sort_by(f64::total_cmp);
    let median = sorted[sorted.len() / 2];
    for r in &results {
        if r.rms_px > 3.0 * median && r.rms_px > 0.5 {
            warnings.push(CalibWarning::OutlierView {
                view: r.name.clone(),
                rms_px: r.rms_px,
                median_rms_px: median,
            });
        }
    }

    Ok(Calibration {
        camera,
        rms_px,
        views: results,
        std_dev,
        options: *options,
        iterations,
        warnings,
    })
}

/// Relative standard deviation of fx, fy above which a warning is given.
pub const FOCAL_STD_LIMIT: f64 = 0.01;
/// Standard deviation of cx, cy, as a fraction of the image's larger side, above which a
/// warning is given.
pub const PRINCIPAL_POINT_STD_LIMIT: f64 = 0.005;
/// Fraction of the image (8 x 8 cells) that corners should reach.
pub const MIN_COVERAGE: f64 = 0.4;

/// Fraction of the 8 x 8 cells of the image that hold at least one corner of some view.
fn coverage(views: &[View], width: u32, height: u32) -> f64 {
    let mut cells = [false; 64];
    for v in views {
        for p in &v.image_points_px {
            let cx = ((p.x + 0.5) / width as f64 * 8.0).floor();
            let cy = ((p.y + 0.5) / height as f64 * 8.0).floor();
            if (0.0..8.0).contains(&cx) && (0.0..8.0).contains(&cy) {
                cells[cy as usize * 8 + cx as usize] = true;
            }
        }
    }
    cells.iter().filter(|c| **c).count() as f64 / 64.0
}

/// Standard deviations at the residual variance `sigma2`, and per unit noise (for the
/// warnings).
fn intrinsics_std(
    state: &State,
    views: &[View],
    free: &[bool; N_INTR],
    sigma2: f64,
) -> (IntrinsicsStdDev, [f64; N_INTR]) {
    let mut unit = [f64::INFINITY; N_INTR];
    if let Some(ne) = normal_equations(state, views, free) {
        let mut s = ne.u;
        let mut ok = true;
        for k in 0..ne.v.len() {
            let Some(l) = cholesky(&ne.v[k], 6) else {
                ok = false;
                break;
            };
            for i in 0..N_INTR {
                let wi: Vec<f64> = (0..6).map(|j| ne.w[k][i * 6 + j]).collect();
                let x = cholesky_solve(&l, 6, &wi);
                for j in 0..N_INTR {
                    let d: f64 = (0..6).map(|l| ne.w[k][j * 6 + l] * x[l]).sum();
                    s[i * N_INTR + j] -= d;
                }
            }
        }
        if ok {
            let idx: Vec<usize> = (0..N_INTR).filter(|&i| free[i]).collect();
            let m = idx.len();
            let mut sub = vec![0.0; m * m];
            for (a, &i) in idx.iter().enumerate() {
                for (b, &j) in idx.iter().enumerate() {
                    sub[a * m + b] = s[i * N_INTR + j];
                }
            }
            // Scale to unit diagonal for a better-conditioned inverse.
            let d: Vec<f64> = (0..m).map(|a| sub[a * m + a].max(1e-300).sqrt()).collect();
            for a in 0..m {
                for b in 0..m {
                    sub[a * m + b] /= d[a] * d[b];
                }
            }
            if let Some(inv) = spd_inverse(&sub, m) {
                for (a, &i) in idx.iter().enumerate() {
                    let var = inv[a * m + a] / (d[a] * d[a]);
                    unit[i] = if var.is_finite() && var >= 0.0 {
                        var.sqrt()
                    } else {
                        f64::INFINITY
                    };
                }
            }
        }
    }
    for (i, f) in free.iter().enumerate() {
        if !f {
            unit[i] = 0.0;
        }
    }
    let s = sigma2.sqrt();
    let u = unit;
    (
        IntrinsicsStdDev {
            fx: u[0] * s,
            fy: u[1] * s,
            cx: u[2] * s,
            cy: u[3] * s,
            k1: u[4] * s,
            k2: u[5] * s,
            p1: u[6] * s,
            p2: u[7] * s,
            k3: u[8] * s,
        },
        unit,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn projection_jacobians_match_finite_differences() {
        let intr = [900.0, 880.0, 650.0, 350.0, -0.2, 0.05, 0.001, -0.002, 0.01];
        let pc = DVec3::new(0.3, -0.2, 1.5);
        let (p0, ji, jp) = project(&intr, pc).expect("in front");
        for k in 0..N_INTR {
            let mut b = intr;
            let h = 1e-6 * intr[k].abs().max(1.0);
            b[k] += h;
            let (p1, _, _) = project(&b, pc).expect("in front");
            let d = (p1 - p0) / h;
            assert!(
                (d.x - ji[0][k]).abs() < 1e-3 * (1.0 + d.x.abs()),
                "intr {k} u"
            );
            assert!(
                (d.y - ji[1][k]).abs() < 1e-3 * (1.0 + d.y.abs()),
                "intr {k} v"
            );
        }
        for c in 0..3 {
            let mut q = pc;
            q[c] += 1e-7;
            let (p1, _, _) = project(&intr, q).expect("in front");
            let d = (p1 - p0) / 1e-7;
            assert!(
                (d.x - jp[0][c]).abs() < 1e-2,
                "point {c} u: {} vs {}",
                d.x,
                jp[0][c]
            );
            assert!(
                (d.y - jp[1][c]).abs() < 1e-2,
                "point {c} v: {} vs {}",
                d.y,
                jp[1][c]
            );
        }
        // Agrees with pa-camera's model.
        let cam = State {
            intr,
            poses: vec![],
        }
        .camera(1280, 720);
        let p = cam.pixel_from_camera(pc).expect("in front");
        assert!(p.distance(p0) < 1e-9);
    }
}
