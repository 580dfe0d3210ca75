//! Camera pose from the corners of a planar marker.
//!
//! Method: corners are undistorted with the [`CameraModel`], a homography from the marker
//! plane to the normalised image plane is fitted, IPPE (Collins & Bartoli 2014,
//! "Infinitesimal Plane-based Pose Estimation") gives the two candidate rotations of the
//! planar ambiguity, translations follow by linear least squares, and each candidate is refined
//! by Levenberg-Marquardt (6 DoF, analytic Jacobian) on the pixel reprojection error. Both
//! candidates are returned, best (lowest RMS) first; [`PoseEstimate::choose_consistent`] picks
//! the one nearest a previous pose instead.
//!
//! Marker frame: see the crate docs (+X right, +Y down the printed page, +Z into the table).

use glam::{DMat3, DMat4, DQuat, DVec2, DVec3, Mat4};
use pa_camera::CameraModel;

use crate::TrackError;

/// A rigid transform `target_from_source`: `p_target = rotation * p_source + translation`.
/// Poses returned by this crate are `camera_from_marker` (metres, OpenCV camera axes).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Pose {
    pub rotation: DQuat,
    pub translation: DVec3,
}

impl Default for Pose {
    fn default() -> Self {
        Self::IDENTITY
    }
}

impl Pose {
    /// The identity transform.
    pub const IDENTITY: Pose = Pose {
        rotation: DQuat::IDENTITY,
        translation: DVec3::ZERO,
    };

    /// From a rotation matrix (orthonormalised through a quaternion) and a translation.
    pub fn from_rotation_translation(rotation: DMat3, translation: DVec3) -> Self {
        Self {
            rotation: DQuat::from_mat3(&rotation).normalize(),
            translation,
        }
    }

    /// Applies the transform to a point.
    pub fn transform_point(&self, p: DVec3) -> DVec3 {
        self.rotation * p + self.translation
    }

    /// The inverse transform (`marker_from_camera` for a `camera_from_marker`).
    pub fn inverse(&self) -> Pose {
        let r = self.rotation.conjugate();
        Pose {
            rotation: r,
            translation: -(r * self.translation),
        }
    }

    /// Composition `self * rhs` (apply `rhs` first): `a_from_c = a_from_b.mul(b_from_c)`.
    pub fn mul(&self, rhs: &Pose) -> Pose {
        Pose {
            rotation: (self.rotation * rhs.rotation).normalize(),
            translation: self.rotation * rhs.translation + self.translation,
        }
    }

    /// The 4x4 matrix (f64).
    pub fn matrix(&self) -> DMat4 {
        DMat4::from_rotation_translation(self.rotation, self.translation)
    }

    /// The 4x4 matrix (f32, for the renderer).
    pub fn to_mat4(&self) -> Mat4 {
        self.matrix().as_mat4()
    }

    /// Rotation angle between two poses in radians (0..=pi).
    pub fn rotation_angle_to(&self, other: &Pose) -> f64 {
        let d = self.rotation.dot(other.rotation).abs().min(1.0);
        2.0 * d.acos()
    }

    /// The camera centre in marker coordinates, for a `camera_from_marker` pose.
    pub fn camera_position_in_marker(&self) -> DVec3 {
        self.inverse().translation
    }
}

/// One solution of the planar pose problem.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PoseCandidate {
    /// `camera_from_marker`.
    pub pose: Pose,
    /// RMS reprojection error over all points, pixels (with lens distortion).
    pub rms_px: f64,
}

/// Both candidates of the planar ambiguity, best first.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PoseEstimate {
    pub best: PoseCandidate,
    /// The other IPPE solution, when it is in front of the camera.
    pub alternative: Option<PoseCandidate>,
}

impl PoseEstimate {
    /// `alternative.rms / best.rms`: near 1 means the two flips explain the corners equally
    /// well (small or far tags seen face-on): use temporal consistency then.
    pub fn ambiguity_ratio(&self) -> f64 {
        match self.alternative {
            Some(a) => a.rms_px / self.best.rms_px.max(1e-9),
            None => f64::INFINITY,
        }
    }

    /// The candidate whose rotation is nearest `previous`, among those whose RMS error is not
    /// much worse than the best (within 4x and 2 px); this keeps the flip of the previous
    /// frame when the two are ambiguous.
    pub fn choose_consistent(&self, previous: &Pose) -> PoseCandidate {
        let Some(alt) = self.alternative else {
            return self.best;
        };
        let acceptable = alt.rms_px <= (self.best.rms_px * 4.0).max(self.best.rms_px + 0.5)
            && alt.rms_px <= self.best.rms_px + 2.0;
        if acceptable
            && alt.pose.rotation_angle_to(previous) < self.best.pose.rotation_angle_to(previous)
        {
            alt
        } else {
            self.best
        }
    }
}

/// The corners of a tag of side `tag_size_m` in the marker frame, in detection order
/// (TL, TR, BR, BL): `(-s/2,-s/2,0)`, `(s/2,-s/2,0)`, `(s/2,s/2,0)`, `(-s/2,s/2,0)`.
pub fn tag_object_points(tag_size_m: f64) -> [DVec3; 4] {
    let h = 0.5 * tag_size_m;
    [
        DVec3::new(-h, -h, 0.0),
        DVec3::new(h, -h, 0.0),
        DVec3::new(h, h, 0.0),
        DVec3::new(-h, h, 0.0),
    ]
}

/// Pose of one tag from its four corners (detection order) and its side in metres.
pub fn estimate_tag_pose(
    camera: &CameraModel,
    corners_px: &[DVec2; 4],
    tag_size_m: f64,
) -> Result<PoseEstimate, TrackError> {
    if !(tag_size_m.is_finite() && tag_size_m > 0.0) {
        return Err(TrackError::Pose(format!(
            "tag size must be a positive length, got {tag_size_m} m"
        )));
    }
    estimate_planar_pose(camera, &tag_object_points(tag_size_m), corners_px)
}

/// Pose from N >= 4 correspondences between points on the marker plane (z = 0) and pixels.
pub fn estimate_planar_pose(
    camera: &CameraModel,
    object_points: &[DVec3],
    image_px: &[DVec2],
) -> Result<PoseEstimate, TrackError> {
    let n = object_points.len();
    if n < 4 || image_px.len() != n {
        return Err(TrackError::Pose(format!(
            "need >= 4 point pairs, got {n} object and {} image points",
            image_px.len()
        )));
    }
    if object_points
        .iter()
        .any(|p| p.z.abs() > 1e-9 || !p.is_finite())
        || image_px.iter().any(|p| !p.is_finite())
    {
        return Err(TrackError::Pose(
            "object points must lie on z = 0 and all values be finite".into(),
        ));
    }
    let k = &camera.intrinsics;
    // Undistorted normalised image points.
    let norm: Vec<DVec2> = image_px
        .iter()
        .map(|p| camera.ray_from_pixel(*p).truncate())
        .collect();
    let centre = object_points.iter().map(|p| p.truncate()).sum::<DVec2>() / n as f64;
    let model: Vec<DVec2> = object_points
        .iter()
        .map(|p| p.truncate() - centre)
        .collect();

    let h = homography(&model, &norm)
        .ok_or_else(|| TrackError::Pose("degenerate point configuration".into()))?;
    let (r1, r2) = ippe_rotations(&h)
        .ok_or_else(|| TrackError::Pose("degenerate homography (IPPE)".into()))?;

    let f = DVec2::new(k.fx, k.fy);
    let mut cands = Vec::with_capacity(2);
    for r in [r1, r2] {
        let Some(t) = translation_for(&r, &model, &norm) else {
            continue;
        };
        // Back to the marker origin: p_c = R (p - c) + t = R p + (t - R c).
        let t = t - r * centre.extend(0.0);
        let (r, t) = refine_lm(r, t, object_points, &norm, f, 30);
        if object_points.iter().any(|p| (r * *p + t).z <= 0.0) {
            continue;
        }
        let pose = Pose::from_rotation_translation(r, t);
        let rms_px = rms_error(camera, &pose, object_points, image_px);
        cands.push(PoseCandidate { pose, rms_px });
    }
    cands.sort_by(|a, b| a.rms_px.total_cmp(&b.rms_px));
    let mut it = cands.into_iter();
    let best = it
        .next()
        .ok_or_else(|| TrackError::Pose("no solution in front of the camera".into()))?;
    Ok(PoseEstimate {
        best,
        alternative: it.next(),
    })
}

/// RMS reprojection error (pixels, through the full camera model with distortion).
pub fn rms_error(
    camera: &CameraModel,
    pose: &Pose,
    object_points: &[DVec3],
    image_px: &[DVec2],
) -> f64 {
    let mut sum = 0.0;
    for (p, m) in object_points.iter().zip(image_px) {
        match camera.pixel_from_camera(pose.transform_point(*p)) {
            Some(px) => sum += px.distance_squared(*m),
            None => return f64::INFINITY,
        }
    }
    (sum / object_points.len().max(1) as f64).sqrt()
}

/// The measured noise of one pose fit, first-order: `s^2 (J^T J)^-1` at the fitted pose,
/// `J` the pinhole reprojection Jacobian in (undistorted) pixels. Kept in two factors: the
/// geometry (`(J^T J)^-1`'s diagonal: how much one pixel of corner noise moves each axis,
/// which grows as tags are hidden or small) and this fit's residual variance `s^2 =
/// RSS / (2N - 6)` per coordinate, which [`crate::PoseFilter`] averages over frames (a few
/// corners give a poor `s^2` alone). Rotation axes are a left perturbation `R <- exp(w) R`
/// in the camera frame, as [`crate::PoseFilter`] uses.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PoseNoise {
    /// Variance of each rotation axis per px^2 of corner noise (rad^2 / px^2).
    pub rotation_var: DVec3,
    /// Variance of each translation axis per px^2 of corner noise (m^2 / px^2).
    pub translation_var: DVec3,
    /// The fit's residual variance per coordinate, px^2.
    pub residual_var_px2: f64,
}

impl PoseNoise {
    /// Noise of `sigma_rad` per rotation axis and `sigma_m` per translation axis (a unit
    /// residual variance).
    pub fn isotropic(sigma_rad: f64, sigma_m: f64) -> Self {
        Self {
            rotation_var: DVec3::splat(sigma_rad * sigma_rad),
            translation_var: DVec3::splat(sigma_m * sigma_m),
            residual_var_px2: 1.0,
        }
    }

    /// Whether every value is finite and not negative.
    pub fn is_valid(&self) -> bool {
        let ok = |v: DVec3| v.is_finite() && v.min_element() >= 0.0;
        ok(self.rotation_var)
            && ok(self.translation_var)
            && self.residual_var_px2.is_finite()
            && self.residual_var_px2 >= 0.0
    }
}

/// [`PoseNoise`] of `pose` fitted to these correspondences; `None` when the Jacobian is
/// singular, a point is behind the camera or fewer than 4 points are given.
pub fn pose_noise(
    camera: &CameraModel,
    pose: &Pose,
    object_points: &[DVec3],
    image_px: &[DVec2],
) -> Option<PoseNoise> {
    let n = object_points.len();
    if n < 4 || image_px.len() != n {
        return None;
    }
    let k = &camera.intrinsics;
    let f = DVec2::new(k.fx, k.fy);
    let r = DMat3::from_quat(pose.rotation);
    let mut jtj = [[0.0f64; 6]; 6];
    let mut rss = 0.0;
    for (p, px) in object_points.iter().zip(image_px) {
        let m = camera.ray_from_pixel(*px).truncate();
        let rp = r * *p;
        let pc = rp + pose.translation;
        if pc.z <= 1e-12 {
            return None;
        }
        let iz = 1.0 / pc.z;
        rss += (f * (DVec2::new(pc.x * iz, pc.y * iz) - m)).length_squared();
        let du = DVec3::new(f.x * iz, 0.0, -f.x * pc.x * iz * iz);
        let dv = DVec3::new(0.0, f.y * iz, -f.y * pc.y * iz * iz);
        let s = skew(rp);
        for d in [du, dv] {
            let jw = -(s.transpose() * d);
            let row = [jw.x, jw.y, jw.z, d.x, d.y, d.z];
            for (i, ri) in row.iter().enumerate() {
                for (j, rj) in row.iter().enumerate() {
                    jtj[i][j] += ri * rj;
                }
            }
        }
    }
    let mut diag = [0.0f64; 6];
    for (i, d) in diag.iter_mut().enumerate() {
        let mut e = [0.0; 6];
        e[i] = 1.0;
        *d = solve::<6>(jtj, e)?[i];
    }
    let noise = PoseNoise {
        rotation_var: DVec3::new(diag[0], diag[1], diag[2]),
        translation_var: DVec3::new(diag[3], diag[4], diag[5]),
        residual_var_px2: rss / (2 * n - 6).max(1) as f64,
    };
    noise.is_valid().then_some(noise)
}

/// Homography (row-major 3x3, h22 = 1) mapping `src` to `dst`, Hartley-normalised DLT solved
/// by least squares.
pub(crate) fn homography(src: &[DVec2], dst: &[DVec2]) -> Option<[[f64; 3]; 3]> {
    let (ts, ss) = normaliser(src)?;
    let (td, sd) = normaliser(dst)?;
    let mut ata = [[0.0f64; 8]; 8];
    let mut atb = [0.0f64; 8];
    for (a, b) in src.iter().zip(dst) {
        let (x, y) = ((a.x - ts.x) * ss, (a.y - ts.y) * ss);
        let (u, v) = ((b.x - td.x) * sd, (b.y - td.y) * sd);
        let rows = [
            ([x, y, 1.0, 0.0, 0.0, 0.0, -u * x, -u * y], u),
            ([0.0, 0.0, 0.0, x, y, 1.0, -v * x, -v * y], v),
        ];
        for (r, rhs) in rows {
            for i in 0..8 {
                atb[i] += r[i] * rhs;
                for j in 0..8 {
                    ata[i][j] += r[i] * r[j];
                }
            }
        }
    }
    let hn = solve::<8>(ata, atb)?;
    let hn = [
        [hn[0], hn[1], hn[2]],
        [hn[3], hn[4], hn[5]],
        [hn[6], hn[7], 1.0],
    ];
    // H = Td^-1 * Hn * Ts
    let ts_m = [
        [ss, 0.0, -ss * ts.x],
        [0.0, ss, -ss * ts.y],
        [0.0, 0.0, 1.0],
    ];
    let td_inv = [
        [1.0 / sd, 0.0, td.x],
        [0.0, 1.0 / sd, td.y],
        [0.0, 0.0, 1.0],
    ];
    let h = mat3_mul(&mat3_mul(&td_inv, &hn), &ts_m);
    if h[2][2].abs() < 1e-12 {
        return None;
    }
    let s = 1.0 / h[2][2];
    Some(h.map(|row| row.map(|v| v * s)))
}

fn normaliser(p: &[DVec2]) -> Option<(DVec2, f64)> {
    let c = p.iter().copied().sum::<DVec2>() / p.len() as f64;
    let d = p.iter().map(|q| q.distance(c)).sum::<f64>() / p.len() as f64;
    (d > 1e-12).then(|| (c, std::f64::consts::SQRT_2 / d))
}

fn mat3_mul(a: &[[f64; 3]; 3], b: &[[f64; 3]; 3]) -> [[f64; 3]; 3] {
    let mut r = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            r[i][j] = (0..3).map(|k| a[i][k] * b[k][j]).sum();
        }
    }
    r
}

/// Gaussian elimination with partial pivoting.
#[allow(clippy::needless_range_loop)]
pub(crate) fn solve<const N: usize>(mut a: [[f64; N]; N], mut b: [f64; N]) -> Option<[f64; N]> {
    for col in 0..N {
        let piv = (col..N).max_by(|&i, &j| a[i][col].abs().total_cmp(&a[j][col].abs()))?;
        if a[piv][col].abs() < 1e-300 {
            return None;
        }
        a.swap(col, piv);
        b.swap(col, piv);
        for row in col + 1..N {
            let f = a[row][col] / a[col][col];
            if f != 0.0 {
                for k in col..N {
                    a[row][k] -= f * a[col][k];
                }
                b[row] -= f * b[col];
            }
        }
    }
    let mut x = [0.0; N];
    for i in (0..N).rev() {
        let s: f64 = (i + 1..N).map(|k| a[i][k] * x[k]).sum();
        x[i] = (b[i] - s) / a[i][i];
    }
    x.iter().all(|v| v.is_finite()).then_some(x)
}

/// The two IPPE rotations from a homography of the centred model plane.
fn ippe_rotations(h: &[[f64; 3]; 3]) -> Option<(DMat3, DMat3)> {
    // Jacobian of the homography at the model origin, and the origin's image.
    let (p, q) = (h[0][2], h[1][2]);
    let j00 = h[0][0] - h[2][0] * p;
    let j01 = h[0][1] - h[2][1] * p;
    let j10 = h[1][0] - h[2][0] * q;
    let j11 = h[1][1] - h[2][1] * q;
    // Rv: a rotation taking +Z to the direction of (p, q, 1).
    let v = DVec3::new(p, q, 1.0).normalize();
    let rv = DMat3::from_quat(DQuat::from_rotation_arc(DVec3::Z, v));
    let (c0, c1) = (rv.x_axis, rv.y_axis);
    // B = [I2 | -v] * Rv[:, 0..2]
    let b00 = c0.x - p * c0.z;
    let b01 = c1.x - p * c1.z;
    let b10 = c0.y - q * c0.z;
    let b11 = c1.y - q * c1.z;
    let det = b00 * b11 - b01 * b10;
    if det.abs() < 1e-15 {
        return None;
    }
    let (i00, i01, i10, i11) = (b11 / det, -b01 / det, -b10 / det, b00 / det);
    let a00 = i00 * j00 + i01 * j10;
    let a01 = i00 * j01 + i01 * j11;
    let a10 = i10 * j00 + i11 * j10;
    let a11 = i10 * j01 + i11 * j11;
    let ata00 = a00 * a00 + a01 * a01;
    let ata01 = a00 * a10 + a01 * a11;
    let ata11 = a10 * a10 + a11 * a11;
    let gamma2 = 0.5 * (ata00 + ata11 + ((ata00 - ata11).powi(2) + 4.0 * ata01 * ata01).sqrt());
    if gamma2.is_nan() || gamma2 <= 1e-24 {
        return None;
    }
    let g = gamma2.sqrt();
    let (r00, r01, r10, r11) = (a00 / g, a01 / g, a10 / g, a11 / g);
    let b0 = (1.0 - r00 * r00 - r10 * r10).max(0.0).sqrt();
    let mut b1 = (1.0 - r01 * r01 - r11 * r11).max(0.0).sqrt();
    if -r00 * r01 - r10 * r11 < 0.0 {
        b1 = -b1;
    }
    let build = |b0: f64, b1: f64| {
        let x = DVec3::new(r00, r10, b0);
        let y = DVec3::new(r01, r11, b1);
        rv * DMat3::from_cols(x, y, x.cross(y))
    };
    Some((build(b0, b1), build(-b0, -b1)))
}

/// Least-squares translation for a known rotation (model on z = 0, normalised image points).
fn translation_for(r: &DMat3, model: &[DVec2], norm: &[DVec2]) -> Option<DVec3> {
    let mut ata = [[0.0; 3]; 3];
    let mut atb = [0.0; 3];
    for (m, n) in model.iter().zip(norm) {
        let pc = *r * m.extend(0.0);
        // tx - u tz = u Pz - Px ; ty - v tz = v Pz - Py
        let rows = [
            ([1.0, 0.0, -n.x], n.x * pc.z - pc.x),
            ([0.0, 1.0, -n.y], n.y * pc.z - pc.y),
        ];
        for (row, rhs) in rows {
            for i in 0..3 {
                atb[i] += row[i] * rhs;
                for j in 0..3 {
                    ata[i][j] += row[i] * row[j];
                }
            }
        }
    }
    solve::<3>(ata, atb).map(|t| DVec3::new(t[0], t[1], t[2]))
}

fn skew(v: DVec3) -> DMat3 {
    DMat3::from_cols(
        DVec3::new(0.0, v.z, -v.y),
        DVec3::new(-v.z, 0.0, v.x),
        DVec3::new(v.y, -v.x, 0.0),
    )
}

/// Sum of squared pinhole reprojection errors in pixel units (undistorted image).
fn cost(r: &DMat3, t: DVec3, obj: &[DVec3], norm: &[DVec2], f: DVec2) -> f64 {
    obj.iter()
        .zip(norm)
        .map(|(p, n)| {
            let c = *r * *p + t;
            if c.z <= 1e-12 {
                return 1e30;
            }
            let e = (DVec2::new(c.x / c.z, c.y / c.z) - *n) * f;
            e.length_squared()
        })
        .sum()
}

/// Levenberg-Marquardt on (rotation increment, translation), left-multiplicative rotation
/// update `R <- exp(w) R`. Errors are in (undistorted) pixels.
pub(crate) fn refine_lm(
    mut r: DMat3,
    mut t: DVec3,
    obj: &[DVec3],
    norm: &[DVec2],
    f: DVec2,
    max_iter: usize,
) -> (DMat3, DVec3) {
    let mut lambda = 1e-3;
    let mut c = cost(&r, t, obj, norm, f);
    for _ in 0..max_iter {
        let mut jtj = [[0.0; 6]; 6];
        let mut jtr = [0.0; 6];
        for (p, n) in obj.iter().zip(norm) {
            let rp = r * *p;
            let pc = rp + t;
            if pc.z <= 1e-12 {
                return (r, t);
            }
            let iz = 1.0 / pc.z;
            let res = [f.x * (pc.x * iz - n.x), f.y * (pc.y * iz - n.y)];
            // d(pixel)/d(pc)
            let du = DVec3::new(f.x * iz, 0.0, -f.x * pc.x * iz * iz);
            let dv = DVec3::new(0.0, f.y * iz, -f.y * pc.y * iz * iz);
            // d(pc)/dw = -[Rp]x ; d(pc)/dt = I.  Row of J for u: [du^T * (-[Rp]x), du^T]
            let s = skew(rp);
            for (k, d) in [du, dv].iter().enumerate() {
                let jw = -(s.transpose() * *d); // (d^T * (-S))^T = -S^T d
                let row = [jw.x, jw.y, jw.z, d.x, d.y, d.z];
                for i in 0..6 {
                    jtr[i] += row[i] * res[k];
                    for j in 0..6 {
                        jtj[i][j] += row[i] * row[j];
                    }
                }
            }
        }
        let mut improved = false;
        for _ in 0..10 {
            let mut a = jtj;
            for (i, row) in a.iter_mut().enumerate() {
                row[i] += lambda * (jtj[i][i] + 1e-12);
            }
            let Some(d) = solve::<6>(a, jtr.map(|v| -v)) else {
                lambda *= 10.0;
                continue;
            };
            let w = DVec3::new(d[0], d[1], d[2]);
            let rn = if w.length() > 0.0 {
                DMat3::from_axis_angle(w.normalize(), w.length()) * r
            } else {
                r
            };
            let tn = t + DVec3::new(d[3], d[4], d[5]);
            let cn = cost(&rn, tn, obj, norm, f);
            if cn < c {
                let rel = (c - cn) / c.max(1e-300);
                r = rn;
                t = tn;
                c = cn;
                lambda = (lambda * 0.3).max(1e-9);
                improved = true;
                if rel < 1e-12 {
                    return (r, t);
                }
                break;
            }
            lambda *= 10.0;
        }
        if !improved || c < 1e-20 {
            break;
        }
    }
    (r, t)
}

#[cfg(test)]
mod tests {
    use super::*;
    use pa_camera::{Distortion, Intrinsics};

    fn camera(dist: bool) -> CameraModel {
        CameraModel {
            intrinsics: Intrinsics {
                fx: 900.0,
                fy: 905.0,
                cx: 639.5,
                cy: 359.5,
                width: 1280,
                height: 720,
            },
            distortion: if dist {
                Distortion {
                    k1: -0.1,
                    k2: 0.03,
                    p1: 0.001,
                    p2: -0.0007,
                    k3: 0.0,
                }
            } else {
                Distortion::default()
            },
        }
    }

    fn project(cam: &CameraModel, pose: &Pose, pts: &[DVec3]) -> Vec<DVec2> {
        pts.iter()
            .map(|p| {
                cam.pixel_from_camera(pose.transform_point(*p))
                    .expect("in front")
            })
            .collect()
    }

    fn look_pose(tilt_deg: f64, yaw_deg: f64, dist: f64, offset: DVec3) -> Pose {
        // Camera above the marker looking at it: marker +Z points away from the camera.
        let r = DQuat::from_rotation_z(yaw_deg.to_radians())
            * DQuat::from_rotation_x(tilt_deg.to_radians());
        Pose {
            rotation: r,
            translation: DVec3::new(0.0, 0.0, dist) + offset,
        }
    }

    #[test]
    fn exact_corners_give_exact_pose() {
        for dist in [false, true] {
            let cam = camera(dist);
            for (tilt, yaw, d) in [
                (0.0, 0.0, 0.5),
                (30.0, 20.0, 0.8),
                (-55.0, 170.0, 1.2),
                (65.0, -80.0, 0.4),
            ] {
                let truth = look_pose(tilt, yaw, d, DVec3::new(0.05, -0.03, 0.0));
                let pts = tag_object_points(0.1);
                let px = project(&cam, &truth, &pts);
                let est =
                    estimate_tag_pose(&cam, &[px[0], px[1], px[2], px[3]], 0.1).expect("solves");
                assert!(est.best.rms_px < 1e-6, "rms {}", est.best.rms_px);
                assert!(est.best.pose.rotation_angle_to(&truth) < 1e-6);
                assert!((est.best.pose.translation - truth.translation).length() < 1e-7);
            }
        }
    }

    #[test]
    fn marker_frame_axes() {
        // A camera 1 m straight above an upright tag (image top = printed top) sees TL at
        // the top-left of the image, and the marker's +Z points away from the camera.
        let cam = camera(false);
        let k = &cam.intrinsics;
        let s = 100.0;
        let px = [
            DVec2::new(k.cx - s, k.cy - s),
            DVec2::new(k.cx + s, k.cy - s),
            DVec2::new(k.cx + s, k.cy + s),
            DVec2::new(k.cx - s, k.cy + s),
        ];
        let est = estimate_tag_pose(&cam, &px, 0.2).expect("solves");
        let r = DMat3::from_quat(est.best.pose.rotation);
        assert!(
            r.x_axis.distance(DVec3::X) < 1e-3,
            "marker +X = camera +X (right)"
        );
        assert!(
            r.y_axis.distance(DVec3::Y) < 1e-3,
            "marker +Y = camera +Y (down the page)"
        );
        assert!(
            r.z_axis.distance(DVec3::Z) < 1e-3,
            "marker +Z = away from the camera"
        );
        assert!((est.best.pose.translation.z - 0.2 * 900.0 / 200.0).abs() < 1e-2);
    }

    #[test]
    fn both_ippe_solutions_and_consistency() {
        let cam = camera(false);
        // A small, far, nearly frontal tag: the two flips are close in error.
        let truth = look_pose(12.0, 0.0, 2.0, DVec3::ZERO);
        let pts = tag_object_points(0.05);
        let px = project(&cam, &truth, &pts);
        let mut noisy = [px[0], px[1], px[2], px[3]];
        noisy[0].x += 0.3;
        noisy[2].y -= 0.3;
        let est = estimate_tag_pose(&cam, &noisy, 0.05).expect("solves");
        let alt = est.alternative.expect("both solutions in front");
        // The two flips differ by roughly twice the tilt.
        let sep = est.best.pose.rotation_angle_to(&alt.pose).to_degrees();
        assert!(sep > 5.0, "separation {sep}");
        // Whichever is best, the consistent choice follows the previous frame.
        let chosen = est.choose_consistent(&truth);
        assert!(chosen.pose.rotation_angle_to(&truth).to_degrees() < 5.0);
        let chosen = est.choose_consistent(&alt.pose);
        assert!(chosen.pose.rotation_angle_to(&alt.pose).to_degrees() < 1e-6);
    }

    #[test]
    fn pose_noise_predicts_the_scatter_of_noisy_fits() {
        // Independent truth: the empirical variance of 400 fits of a 2x2 board whose corners
        // carry Gaussian noise of 0.5 px, against pose_noise's first-order prediction.
        let cam = camera(true);
        let truth = look_pose(35.0, 20.0, 0.7, DVec3::new(0.02, -0.01, 0.0));
        let mut obj = Vec::new();
        for (cx, cy) in [(-0.04, -0.04), (0.04, -0.04), (-0.04, 0.04), (0.04, 0.04)] {
            obj.extend(tag_object_points(0.06).map(|p| p + DVec3::new(cx, cy, 0.0)));
        }
        let exact = project(&cam, &truth, &obj);
        let mut state = 0x9E37_79B9_7F4A_7C15u64;
        let mut gauss = || {
            let mut u = || {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                ((state >> 11) as f64 + 0.5) / (1u64 << 53) as f64
            };
            let (a, b) = (u(), u());
            (-2.0 * a.ln()).sqrt() * (std::f64::consts::TAU * b).cos()
        };
        let sigma = 0.5;
        let (mut emp_r, mut emp_t) = (DVec3::ZERO, DVec3::ZERO);
        let (mut pred_r, mut pred_t) = (DVec3::ZERO, DVec3::ZERO);
        let n = 400;
        for _ in 0..n {
            let img: Vec<DVec2> = exact
                .iter()
                .map(|p| *p + DVec2::new(gauss(), gauss()) * sigma)
                .collect();
            let est = estimate_planar_pose(&cam, &obj, &img)
                .expect("fit")
                .best
                .pose;
            let w = (est.rotation * truth.rotation.conjugate()).to_scaled_axis();
            let d = est.translation - truth.translation;
            emp_r += w * w;
            emp_t += d * d;
            let noise = pose_noise(&cam, &est, &obj, &img).expect("noise");
            pred_r += noise.rotation_var * noise.residual_var_px2;
            pred_t += noise.translation_var * noise.residual_var_px2;
        }
        for (e, p) in [(emp_r, pred_r), (emp_t, pred_t)] {
            let ratio = e / p;
            eprintln!("empirical / predicted variance per axis: {ratio:.3?}");
            // Within 25 % per axis (400 samples: the variance itself scatters ~7 %).
            assert!(
                ratio.min_element() > 0.75 && ratio.max_element() < 1.25,
                "empirical / predicted variance {ratio:?}"
            );
        }
        // A singular configuration (all points the same) gives no noise estimate.
        assert!(pose_noise(&cam, &truth, &[DVec3::ZERO; 4], &[exact[0]; 4]).is_none());
    }

    #[test]
    fn pose_algebra() {
        let a = look_pose(20.0, 30.0, 1.0, DVec3::new(0.1, 0.2, 0.0));
        let p = DVec3::new(0.3, -0.2, 0.1);
        let back = a.inverse().transform_point(a.transform_point(p));
        assert!((back - p).length() < 1e-12);
        let m = a.matrix().transform_point3(p);
        assert!((m - a.transform_point(p)).length() < 1e-12);
        let b = look_pose(-10.0, 5.0, 0.5, DVec3::ZERO);
        let ab = a.mul(&b);
        assert!((ab.transform_point(p) - a.transform_point(b.transform_point(p))).length() < 1e-12);
    }

    #[test]
    fn bad_input_is_an_error() {
        let cam = camera(false);
        let px = [DVec2::ZERO; 4];
        assert!(estimate_tag_pose(&cam, &px, 0.1).is_err());
        let px = [
            DVec2::new(0.0, 0.0),
            DVec2::new(10.0, 0.0),
            DVec2::new(10.0, 10.0),
            DVec2::new(0.0, 10.0),
        ];
        assert!(estimate_tag_pose(&cam, &px, -1.0).is_err());
        assert!(estimate_tag_pose(&cam, &px, f64::NAN).is_err());
    }
}
