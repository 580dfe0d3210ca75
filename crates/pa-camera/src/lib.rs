//! Camera model and coordinate conventions for Props Alive.
//!
//! # Conventions (the single source of truth; ARCHITECTURE.md copies this table)
//!
//! | space            | axes                                   | units  | notes                                  |
//! |------------------|----------------------------------------|--------|----------------------------------------|
//! | glTF / prop      | right-handed, +Y up, +Z toward viewer  | metres | as exported by Blender/Maya            |
//! | marker           | right-handed, origin at tag centre, +X right, +Y down the printed page, +Z into the table | metres | OpenCV/ArUco object convention |
//! | camera           | OpenCV: +X right, +Y down, +Z forward  | metres | `camera_from_marker * p_marker`        |
//! | image (pixels)   | +x right, +y down                      | pixels | pixel centres at integer coordinates   |
//! | wgpu clip space  | +X right, +Y up, depth 0..1            | -      | only inside `pa-render`                |
//!
//! Transforms are named `target_from_source`, so that `camera_from_marker * p_marker` reads
//! right to left. Units are part of names (`fov_y_rad`, `tag_size_m`).
//!
//! The pixel-centre convention: the pixel with index (0, 0) covers [-0.5, 0.5] x [-0.5, 0.5]
//! and its centre is at (0, 0). The AprilTag C library reports corners in a frame where the
//! centre of pixel (0, 0) is at (0.5, 0.5); `pa-track` converts once, at its boundary.

pub mod calib;
pub mod diag;

pub use calib::{
    from_opencv_yaml, load_calibration, save_calibration, to_opencv_yaml, CalibError, CalibFormat,
    MAX_CALIBRATION_BYTES,
};

use glam::{DMat3, DVec2, DVec3, Mat4, Vec3};
use serde::{Deserialize, Serialize};

/// Errors of the camera model.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum CameraError {
    /// An intrinsic parameter is not a finite positive number where it must be.
    #[error("invalid intrinsics: {field} = {value} ({reason})")]
    InvalidIntrinsics {
        field: &'static str,
        value: f64,
        reason: &'static str,
    },
    /// The image size is zero or absurd.
    #[error("invalid image size {width}x{height} (each side must be in 1..={MAX_IMAGE_SIDE})")]
    InvalidSize { width: u32, height: u32 },
    /// A distortion coefficient is not a finite number.
    #[error("invalid distortion: {field} = {value} (must be finite)")]
    InvalidDistortion { field: &'static str, value: f64 },
}

/// The largest image side, in pixels, that intrinsics may describe.
pub const MAX_IMAGE_SIDE: u32 = 65_536;

/// OpenCV pinhole intrinsics in pixels (pixel centres at integer coordinates).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Intrinsics {
    pub fx: f64,
    pub fy: f64,
    pub cx: f64,
    pub cy: f64,
    /// Image width in pixels the intrinsics were calibrated for.
    pub width: u32,
    /// Image height in pixels the intrinsics were calibrated for.
    pub height: u32,
}

impl Intrinsics {
    /// Intrinsics with the principal point at the image centre and the given vertical field of
    /// view (square pixels).
    pub fn from_fov_y(fov_y_rad: f64, width: u32, height: u32) -> Result<Self, CameraError> {
        if !(fov_y_rad.is_finite() && fov_y_rad > 1e-3 && fov_y_rad < std::f64::consts::PI - 1e-3) {
            return Err(CameraError::InvalidIntrinsics {
                field: "fov_y_rad",
                value: fov_y_rad,
                reason: "must be in (0, pi)",
            });
        }
        let f = 0.5 * height as f64 / (0.5 * fov_y_rad).tan();
        let k = Self {
            fx: f,
            fy: f,
            cx: (width as f64 - 1.0) * 0.5,
            cy: (height as f64 - 1.0) * 0.5,
            width,
            height,
        };
        k.validate()?;
        Ok(k)
    }

    /// Checks that every parameter is usable.
    pub fn validate(&self) -> Result<(), CameraError> {
        if self.width == 0
            || self.height == 0
            || self.width > MAX_IMAGE_SIDE
            || self.height > MAX_IMAGE_SIDE
        {
            return Err(CameraError::InvalidSize {
                width: self.width,
                height: self.height,
            });
        }
        for (field, value) in [("fx", self.fx), ("fy", self.fy)] {
            if !(value.is_finite() && value > 0.0) {
                return Err(CameraError::InvalidIntrinsics {
                    field,
                    value,
                    reason: "must be finite and > 0",
                });
            }
        }
        for (field, value) in [("cx", self.cx), ("cy", self.cy)] {
            if !value.is_finite() {
                return Err(CameraError::InvalidIntrinsics {
                    field,
                    value,
                    reason: "must be finite",
                });
            }
        }
        Ok(())
    }

    /// The 3x3 camera matrix K (column-major, as glam stores it).
    pub fn matrix(&self) -> DMat3 {
        DMat3::from_cols(
            DVec3::new(self.fx, 0.0, 0.0),
            DVec3::new(0.0, self.fy, 0.0),
            DVec3::new(self.cx, self.cy, 1.0),
        )
    }

    /// Vertical field of view in radians.
    pub fn fov_y_rad(&self) -> f64 {
        2.0 * (0.5 * self.height as f64 / self.fy).atan()
    }

    /// Intrinsics for the same camera at another image resolution (pixel-centre aware).
    pub fn scaled_to(&self, width: u32, height: u32) -> Self {
        let sx = width as f64 / self.width as f64;
        let sy = height as f64 / self.height as f64;
        Self {
            fx: self.fx * sx,
            fy: self.fy * sy,
            cx: (self.cx + 0.5) * sx - 0.5,
            cy: (self.cy + 0.5) * sy - 0.5,
            width,
            height,
        }
    }

    /// Projects a point on the normalised image plane (x/z, y/z) to pixels.
    pub fn pixel_from_normalized(&self, n: DVec2) -> DVec2 {
        DVec2::new(self.fx * n.x + self.cx, self.fy * n.y + self.cy)
    }

    /// Inverse of [`Intrinsics::pixel_from_normalized`].
    pub fn normalized_from_pixel(&self, p: DVec2) -> DVec2 {
        DVec2::new((p.x - self.cx) / self.fx, (p.y - self.cy) / self.fy)
    }

    /// The projection matrix taking OpenCV camera coordinates to wgpu clip space
    /// (x, y in [-1, 1] with +y up, depth in [0, 1]) for a `width` x `height` render target.
    ///
    /// Pixel centre (u, v) in OpenCV convention maps to NDC x = (2u + 1)/W - 1,
    /// y = 1 - (2v + 1)/H. Depth is standard (near -> 0, far -> 1).
    pub fn clip_from_camera(&self, near_m: f32, far_m: f32) -> Mat4 {
        let w = self.width as f64;
        let h = self.height as f64;
        let (n, f) = (near_m as f64, far_m as f64);
        // x_ndc * z = (2 fx / W) x + ((2 cx + 1)/W - 1) z
        let a = 2.0 * self.fx / w;
        let b = (2.0 * self.cx + 1.0) / w - 1.0;
        // y_ndc * z = -(2 fy / H) y + (1 - (2 cy + 1)/H) z
        let c = -2.0 * self.fy / h;
        let d = 1.0 - (2.0 * self.cy + 1.0) / h;
        // depth * z = f/(f-n) z - f n/(f-n)
        let e = f / (f - n);
        let g = -f * n / (f - n);
        Mat4::from_cols_array(&[
            a as f32, 0.0, 0.0, 0.0, //
            0.0, c as f32, 0.0, 0.0, //
            b as f32, d as f32, e as f32, 1.0, //
            0.0, 0.0, g as f32, 0.0,
        ])
    }
}

/// OpenCV radial-tangential distortion (k1, k2, p1, p2, k3).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Distortion {
    pub k1: f64,
    pub k2: f64,
    pub p1: f64,
    pub p2: f64,
    pub k3: f64,
}

impl Distortion {
    /// True when all coefficients are zero.
    pub fn is_zero(&self) -> bool {
        *self == Self::default()
    }

    /// Checks that every coefficient is a finite number.
    pub fn validate(&self) -> Result<(), CameraError> {
        for (field, value) in [
            ("k1", self.k1),
            ("k2", self.k2),
            ("p1", self.p1),
            ("p2", self.p2),
            ("k3", self.k3),
        ] {
            if !value.is_finite() {
                return Err(CameraError::InvalidDistortion { field, value });
            }
        }
        Ok(())
    }

    /// Applies distortion to a normalised image point.
    pub fn distort(&self, n: DVec2) -> DVec2 {
        let (x, y) = (n.x, n.y);
        let r2 = x * x + y * y;
        let radial = 1.0 + r2 * (self.k1 + r2 * (self.k2 + r2 * self.k3));
        let xd = x * radial + 2.0 * self.p1 * x * y + self.p2 * (r2 + 2.0 * x * x);
        let yd = y * radial + self.p1 * (r2 + 2.0 * y * y) + 2.0 * self.p2 * x * y;
        DVec2::new(xd, yd)
    }

    /// Removes distortion from a normalised image point (fixed-point iteration, as OpenCV's
    /// `undistortPoints`, refined with a few Newton-free steps until it converges).
    pub fn undistort(&self, d: DVec2) -> DVec2 {
        if self.is_zero() {
            return d;
        }
        let mut n = d;
        for _ in 0..50 {
            let err = self.distort(n) - d;
            n -= err;
            if err.length_squared() < 1e-24 {
                break;
            }
        }
        n
    }
}

/// A calibrated camera: intrinsics plus lens distortion.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CameraModel {
    pub intrinsics: Intrinsics,
    #[serde(default)]
    pub distortion: Distortion,
}

impl CameraModel {
    /// A camera without lens distortion.
    pub fn pinhole(intrinsics: Intrinsics) -> Self {
        Self {
            intrinsics,
            distortion: Distortion::default(),
        }
    }

    /// Checks the intrinsics and the distortion ([`Intrinsics::validate`],
    /// [`Distortion::validate`]).
    pub fn validate(&self) -> Result<(), CameraError> {
        self.intrinsics.validate()?;
        self.distortion.validate()
    }

    /// Projects a point in camera coordinates (OpenCV axes, metres) to pixels.
    /// Returns `None` for points at or behind the camera plane.
    pub fn pixel_from_camera(&self, p_camera: DVec3) -> Option<DVec2> {
        if p_camera.z <= 1e-12 {
            return None;
        }
        let n = DVec2::new(p_camera.x / p_camera.z, p_camera.y / p_camera.z);
        Some(
            self.intrinsics
                .pixel_from_normalized(self.distortion.distort(n)),
        )
    }

    /// The ray direction (z = 1) in camera coordinates through a pixel.
    pub fn ray_from_pixel(&self, pixel: DVec2) -> DVec3 {
        let n = self
            .distortion
            .undistort(self.intrinsics.normalized_from_pixel(pixel));
        DVec3::new(n.x, n.y, 1.0)
    }

    /// The point in camera coordinates at depth `z_m` that projects to `pixel`.
    pub fn camera_from_pixel(&self, pixel: DVec2, z_m: f64) -> DVec3 {
        self.ray_from_pixel(pixel) * z_m
    }
}

/// `camera_from_world` (OpenCV camera axes: x right, y down, z forward) for a camera at `eye`
/// looking at `target`, with `up_world` pointing up in the image. Returns `None` when the view
/// direction is degenerate (eye at target, or looking along `up_world`).
pub fn camera_from_world_look_at(eye: Vec3, target: Vec3, up_world: Vec3) -> Option<Mat4> {
    let forward = (target - eye).try_normalize()?;
    let right = forward.cross(up_world).try_normalize()?;
    let down = forward.cross(right);
    let world_from_camera = Mat4::from_cols(
        right.extend(0.0),
        down.extend(0.0),
        forward.extend(0.0),
        eye.extend(1.0),
    );
    Some(world_from_camera.inverse())
}

/// Conversion between OpenCV camera axes and the OpenGL/glTF camera axes
/// (+X right, +Y up, looking down -Z). The matrix is its own inverse.
pub fn opencv_from_opengl() -> Mat4 {
    Mat4::from_scale(Vec3::new(1.0, -1.0, -1.0))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cam() -> CameraModel {
        CameraModel {
            intrinsics: Intrinsics {
                fx: 800.0,
                fy: 790.0,
                cx: 639.5,
                cy: 359.5,
                width: 1280,
                height: 720,
            },
            distortion: Distortion {
                k1: -0.12,
                k2: 0.05,
                p1: 0.001,
                p2: -0.0005,
                k3: -0.01,
            },
        }
    }

    #[test]
    fn project_unproject_round_trip_with_distortion() {
        let c = cam();
        for &(x, y) in &[(0.0, 0.0), (0.3, -0.2), (-0.5, 0.35), (0.7, 0.4)] {
            let p = DVec3::new(x, y, 1.0) * 2.5;
            let px = c.pixel_from_camera(p).expect("in front");
            let back = c.camera_from_pixel(px, 2.5);
            assert!((back - p).length() < 1e-9, "{p} -> {px} -> {back}");
        }
    }

    #[test]
    fn principal_point_and_pixel_centres() {
        let c = CameraModel::pinhole(cam().intrinsics);
        let px = c
            .pixel_from_camera(DVec3::new(0.0, 0.0, 3.0))
            .expect("in front");
        assert_eq!(px, DVec2::new(639.5, 359.5));
        // +x right, +y down in camera space maps to +u right, +v down in the image.
        let px = c
            .pixel_from_camera(DVec3::new(0.1, 0.1, 1.0))
            .expect("in front");
        assert!(px.x > 639.5 && px.y > 359.5);
        assert!(c.pixel_from_camera(DVec3::new(0.0, 0.0, -1.0)).is_none());
    }

    #[test]
    fn clip_matrix_maps_pixel_centres_to_ndc() {
        let k = cam().intrinsics;
        let clip = k.clip_from_camera(0.1, 100.0);
        let c = CameraModel::pinhole(k);
        for p in [
            DVec3::new(0.0, 0.0, 2.0),
            DVec3::new(0.4, -0.3, 1.5),
            DVec3::new(-1.0, 0.5, 4.0),
        ] {
            let px = c.pixel_from_camera(p).expect("in front");
            let v = clip * p.as_vec3().extend(1.0);
            let ndc = v.truncate() / v.w;
            let u = ((ndc.x as f64 + 1.0) * k.width as f64 - 1.0) * 0.5;
            let vv = ((1.0 - ndc.y as f64) * k.height as f64 - 1.0) * 0.5;
            assert!((u - px.x).abs() < 1e-3 && (vv - px.y).abs() < 1e-3);
            assert!(ndc.z > 0.0 && ndc.z < 1.0);
        }
        // Near plane -> depth 0, far plane -> depth 1.
        let n = clip * glam::Vec4::new(0.0, 0.0, 0.1, 1.0);
        let f = clip * glam::Vec4::new(0.0, 0.0, 100.0, 1.0);
        assert!((n.z / n.w).abs() < 1e-6 && (f.z / f.w - 1.0).abs() < 1e-6);
    }

    #[test]
    fn look_at_follows_opencv_axes() {
        let eye = Vec3::new(0.0, 0.0, 2.0);
        let m = camera_from_world_look_at(eye, Vec3::ZERO, Vec3::Y).expect("valid");
        // The target is straight ahead at z = 2; world +X is image right, world +Y image up.
        let t = m.transform_point3(Vec3::ZERO);
        assert!((t - Vec3::new(0.0, 0.0, 2.0)).length() < 1e-6, "{t}");
        let r = m.transform_point3(Vec3::X);
        assert!(r.x > 0.99 && r.y.abs() < 1e-6);
        let u = m.transform_point3(Vec3::Y);
        assert!(u.y < -0.99, "world up must be image up (camera -y): {u}");
        assert!(camera_from_world_look_at(eye, eye, Vec3::Y).is_none());
        assert!(camera_from_world_look_at(Vec3::Y, Vec3::ZERO, Vec3::Y).is_none());
    }

    #[test]
    fn fov_and_scaling() {
        let k = Intrinsics::from_fov_y(60f64.to_radians(), 1280, 720).expect("valid");
        assert!((k.fov_y_rad() - 60f64.to_radians()).abs() < 1e-12);
        let half = k.scaled_to(640, 360);
        assert!((half.fx - k.fx / 2.0).abs() < 1e-12);
        assert!((half.cx - 319.5).abs() < 1e-12);
        assert!(Intrinsics::from_fov_y(f64::NAN, 10, 10).is_err());
        assert!(Intrinsics::from_fov_y(1.0, 0, 10).is_err());
    }
}
