//! The per-fragment live-texturing look-up: where the key-pose surface point sits in the
//! camera frame, and whether that sample is valid. The same math, order of tests and codes as
//! `pa-render`'s `live.wgsl` (`live_lookup`); see `pa_render::live` for the derivation.

use glam::Vec3;

/// Codes of a twin pixel's sample (the numbers of `pa_render::LiveSample`).
pub mod code {
    /// Background (no twin surface).
    pub const NONE: u8 = 0;
    /// Fallback: the key-pose point projects outside the frame, or behind the camera.
    pub const OUTSIDE: u8 = 1;
    /// Fallback: the key-pose normal faces away from the camera.
    pub const BACK_FACING: u8 = 2;
    /// Fallback: another key-pose surface hides the point (visibility map).
    pub const OCCLUDED: u8 = 3;
    /// Fallback: the animated surface faces the camera far more squarely than the key pose.
    pub const STRETCHED: u8 = 4;
    /// A live sample from the frame.
    pub const VALID: u8 = 255;
}

/// The frame camera of the look-up (f32 copies of the calibrated model at the frame's size).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FrameCamera {
    pub fx: f32,
    pub fy: f32,
    pub cx: f32,
    pub cy: f32,
    pub width: f32,
    pub height: f32,
    pub k1: f32,
    pub k2: f32,
    pub p1: f32,
    pub p2: f32,
    pub k3: f32,
}

impl FrameCamera {
    /// From a calibrated camera whose intrinsics are at the frame's size.
    pub fn new(model: &pa_camera::CameraModel) -> Self {
        let (k, d) = (&model.intrinsics, &model.distortion);
        Self {
            fx: k.fx as f32,
            fy: k.fy as f32,
            cx: k.cx as f32,
            cy: k.cy as f32,
            width: k.width as f32,
            height: k.height as f32,
            k1: d.k1 as f32,
            k2: d.k2 as f32,
            p1: d.p1 as f32,
            p2: d.p2 as f32,
            k3: d.k3 as f32,
        }
    }

    /// OpenCV radial-tangential distortion of a normalised point.
    #[inline]
    fn distort(&self, x: f32, y: f32) -> (f32, f32) {
        let r2 = x * x + y * y;
        let radial = 1.0 + r2 * (self.k1 + r2 * (self.k2 + r2 * self.k3));
        let xd = x * radial + 2.0 * self.p1 * x * y + self.p2 * (r2 + 2.0 * x * x);
        let yd = y * radial + self.p1 * (r2 + 2.0 * y * y) + 2.0 * self.p2 * x * y;
        (xd, yd)
    }

    /// The radial map is still increasing at `r^2` (beyond, points fold back into the image).
    #[inline]
    fn radial_monotonic(&self, r2: f32) -> bool {
        1.0 + r2 * (3.0 * self.k1 + r2 * (5.0 * self.k2 + r2 * 7.0 * self.k3)) > 0.0
    }
}

#[cfg(test)]
impl FrameCamera {
    /// A 100x100 pinhole camera, f = 100 px, principal point at the centre (tests).
    pub(crate) fn test_pinhole() -> Self {
        Self {
            fx: 100.0,
            fy: 100.0,
            cx: 49.5,
            cy: 49.5,
            width: 100.0,
            height: 100.0,
            k1: 0.0,
            k2: 0.0,
            p1: 0.0,
            p2: 0.0,
            k3: 0.0,
        }
    }
}

/// Settings of the look-up (the `LiveTexturing` fields of the GPU path).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LiveParams {
    pub frame_camera: FrameCamera,
    /// Occlusion test against the key-pose depth of the same camera.
    pub visibility: bool,
    pub depth_tolerance_rel: f32,
    pub depth_tolerance_m: f32,
    pub min_facing_cos: f32,
    /// 0 disables the stretch test.
    pub max_stretch: f32,
    /// Per linear RGB channel, `(constant, n.x, n.y, n.z)` of the world-space normal.
    pub fallback_irradiance: [[f32; 4]; 3],
    /// Shade live samples at the animated normal ([`crate::look::relight_factor`] with
    /// `fallback_irradiance`; normals in the world frame the irradiance is fitted in).
    pub relight: bool,
    /// Blend live and fallback colour with a continuous weight ([`crate::look`]) instead of
    /// a hard seam.
    pub feather: bool,
    /// The set's sun with the twin's cast shadows ([`crate::sun`]): when set, it shades the
    /// fallback and relights live samples instead of `fallback_irradiance`, with each
    /// vertex's [`CpuLiveMesh::sun_lit`](crate::CpuLiveMesh::sun_lit).
    pub sun: Option<crate::sun::SunLight>,
    /// Light reflected at grazing angles, linear RGB ([`crate::look`], "Grazing
    /// reflection"); zero (the default) for none. Applied with `relight` only.
    pub grazing_rgb: [f32; 3],
}

impl LiveParams {
    /// The GPU path's defaults: no visibility, tolerances 0.5% + 1 mm, facing cosine 0.05, no
    /// stretch test, fallback gain 1.
    pub fn new(frame_camera: FrameCamera) -> Self {
        Self {
            frame_camera,
            visibility: false,
            depth_tolerance_rel: 0.005,
            depth_tolerance_m: 0.001,
            min_facing_cos: 0.05,
            max_stretch: 0.0,
            fallback_irradiance: [[1.0, 0.0, 0.0, 0.0]; 3],
            relight: false,
            feather: false,
            sun: None,
            grazing_rgb: [0.0; 3],
        }
    }
}

/// Cosine between a normal and the direction from the point to the camera (at the origin).
#[inline(always)]
pub(crate) fn facing_cos(p: Vec3, n: Vec3) -> f32 {
    let len2 = n.dot(n) * p.dot(p);
    if len2 > 0.0 {
        -n.dot(p) / len2.sqrt()
    } else {
        -1.0
    }
}

/// Inverse depth at a texel of the key-pose buffer (clamped to the buffer), 0 where empty.
pub trait InvDepthMap {
    fn size(&self) -> (u32, u32);
    fn inv_z_clamped(&self, x: i32, y: i32) -> f32;
}

impl InvDepthMap for crate::raster::VisBuffer {
    fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    #[inline]
    fn inv_z_clamped(&self, x: i32, y: i32) -> f32 {
        let x = x.clamp(0, self.width as i32 - 1) as usize;
        let y = y.clamp(0, self.height as i32 - 1) as usize;
        self.inv_z[y * self.width as usize + x]
    }
}

/// The look-up of one fragment: key-pose point `pc` and normal `nc`, animated point `pa` and
/// normal `na`, all in the frame camera's coordinates. Returns the code and the frame pixel.
/// The visibility map, when used, is the key pose rasterised by the same camera (pinhole, at
/// the frame's size).
#[inline]
pub fn live_lookup(
    p: &LiveParams,
    key_depth: &impl InvDepthMap,
    pc: Vec3,
    nc: Vec3,
    pa: Vec3,
    na: Vec3,
) -> (u8, [f32; 2]) {
    let (code, pixel, _) = live_lookup_weighted(p, key_depth, pc, nc, pa, na);
    (code, pixel)
}

/// [`live_lookup`] and the live sample's weight: 0 unless [`code::VALID`]; with
/// `p.feather`, the product of the ramps of [`crate::look`] (1 without).
#[inline]
pub fn live_lookup_weighted(
    p: &LiveParams,
    key_depth: &impl InvDepthMap,
    pc: Vec3,
    nc: Vec3,
    pa: Vec3,
    na: Vec3,
) -> (u8, [f32; 2], f32) {
    use crate::look::{ramp, EDGE_FEATHER_PX, FACING_FEATHER_COS, STRETCH_FEATHER};
    let cam = &p.frame_camera;
    // (Written so that NaN fails every test.)
    let in_front = pc.z > 1e-6;
    if !in_front {
        return (code::OUTSIDE, [0.0; 2], 0.0);
    }
    let (x, y) = (pc.x / pc.z, pc.y / pc.z);
    if !cam.radial_monotonic(x * x + y * y) {
        return (code::OUTSIDE, [0.0; 2], 0.0);
    }
    let (xd, yd) = cam.distort(x, y);
    let pixel = [cam.fx * xd + cam.cx, cam.fy * yd + cam.cy];
    if !(pixel[0] >= -0.5
        && pixel[1] >= -0.5
        && pixel[0] <= cam.width - 0.5
        && pixel[1] <= cam.height - 0.5)
    {
        return (code::OUTSIDE, pixel, 0.0);
    }
    let cos_key = facing_cos(pc, nc);
    let facing = cos_key > p.min_facing_cos;
    if !facing {
        return (code::BACK_FACING, pixel, 0.0);
    }
    let mut weight = 1.0f32;
    if p.feather {
        let edge = (pixel[0] + 0.5)
            .min(pixel[1] + 0.5)
            .min(cam.width - 0.5 - pixel[0])
            .min(cam.height - 0.5 - pixel[1]);
        weight = ramp(edge, EDGE_FEATHER_PX) * ramp(cos_key - p.min_facing_cos, FACING_FEATHER_COS);
    }
    if p.max_stretch > 0.0 {
        let limit = p.max_stretch * cos_key.max(0.0);
        let cos_anim = facing_cos(pa, na);
        if cos_anim > limit {
            return (code::STRETCHED, pixel, 0.0);
        }
        if p.feather {
            weight *= ramp(limit - cos_anim, STRETCH_FEATHER * limit);
        }
    }
    visible_weight(p, key_depth, (x, y), pc.z, pixel, weight)
}

/// The end of [`live_lookup_weighted`] for a sample that passed the frame, facing and stretch
/// tests: the visibility test against the key depth at the pinhole projection `(x, y)` (the
/// normalised coordinates) of a point at depth `z`, and the weight's last factor. Shared with
/// the four-lane look-up ([`crate::live_lanes`]).
#[inline(always)]
pub(crate) fn visible_weight(
    p: &LiveParams,
    key_depth: &impl InvDepthMap,
    (x, y): (f32, f32),
    z: f32,
    pixel: [f32; 2],
    mut weight: f32,
) -> (u8, [f32; 2], f32) {
    use crate::look::{ramp, FULL_WEIGHT_MIN};
    let cam = &p.frame_camera;
    if p.visibility {
        // Pinhole projection into the map (rasterised without distortion).
        let q = [cam.fx * x + cam.cx, cam.fy * y + cam.cy];
        let (mw, mh) = key_depth.size();
        if !(q[0] >= -0.5 && q[1] >= -0.5 && q[0] <= mw as f32 - 0.5 && q[1] <= mh as f32 - 0.5) {
            return (code::OUTSIDE, pixel, 0.0);
        }
        let (x0, y0) = (
            crate::texture::floor_i64(q[0]) as i32,
            crate::texture::floor_i64(q[1]) as i32,
        );
        // The farthest surface (smallest non-zero 1/z) of the four texels around q.
        let mut inv_z = 0.0f32;
        for k in 0..4 {
            let v = key_depth.inv_z_clamped(x0 + (k & 1), y0 + (k >> 1));
            if v > 0.0 && (inv_z == 0.0 || v < inv_z) {
                inv_z = v;
            }
        }
        let tolerance = p.depth_tolerance_rel + p.depth_tolerance_m * inv_z;
        if z * inv_z > 1.0 + tolerance {
            return (code::OCCLUDED, pixel, 0.0);
        }
        if p.feather && inv_z > 0.0 {
            weight *= ramp(1.0 + tolerance - z * inv_z, tolerance);
        }
    }
    let weight = if weight >= FULL_WEIGHT_MIN {
        1.0
    } else {
        weight
    };
    (code::VALID, pixel, weight)
}

#[cfg(test)]
mod tests {
    use super::*;

    struct Flat(f32);
    impl InvDepthMap for Flat {
        fn size(&self) -> (u32, u32) {
            (100, 100)
        }
        fn inv_z_clamped(&self, _: i32, _: i32) -> f32 {
            self.0
        }
    }

    fn params() -> LiveParams {
        LiveParams::new(FrameCamera::test_pinhole())
    }

    #[test]
    fn codes_in_the_gpu_order() {
        let p = params();
        let toward = Vec3::new(0.0, 0.0, -1.0);
        let at = Vec3::new(0.0, 0.0, 1.0);
        let map = Flat(1.0);
        assert_eq!(live_lookup(&p, &map, at, toward, at, toward).0, code::VALID);
        let (c, px) = live_lookup(&p, &map, Vec3::new(0.1, -0.2, 1.0), toward, at, toward);
        assert_eq!(c, code::VALID);
        assert!((px[0] - 59.5).abs() < 1e-4 && (px[1] - 29.5).abs() < 1e-4);
        // Behind the camera, outside the image.
        assert_eq!(
            live_lookup(&p, &map, Vec3::new(0.0, 0.0, -1.0), toward, at, toward).0,
            code::OUTSIDE
        );
        assert_eq!(
            live_lookup(&p, &map, Vec3::new(2.0, 0.0, 1.0), toward, at, toward).0,
            code::OUTSIDE
        );
        // Facing away.
        assert_eq!(
            live_lookup(&p, &map, at, -toward, at, toward).0,
            code::BACK_FACING
        );
        // Occluded (with visibility) by a surface at 0.5 m; not without.
        let mut pv = p;
        pv.visibility = true;
        assert_eq!(
            live_lookup(&pv, &Flat(2.0), at, toward, at, toward).0,
            code::OCCLUDED
        );
        assert_eq!(
            live_lookup(&pv, &Flat(1.0), at, toward, at, toward).0,
            code::VALID
        );
        assert_eq!(
            live_lookup(&pv, &Flat(0.0), at, toward, at, toward).0,
            code::VALID
        );
        // Stretched: grazing in the key pose, face-on now.
        let mut ps = p;
        ps.max_stretch = 2.0;
        let grazing = Vec3::new(1.0, 0.0, -0.2).normalize();
        assert_eq!(
            live_lookup(&ps, &map, at, grazing, at, toward).0,
            code::STRETCHED
        );
    }

    /// The feathered weight: 1 well inside every test, 0 where a test fails, and continuous
    /// across each limit (the last valid sample's weight is near 0).
    #[test]
    fn feather_weight_goes_to_zero_at_each_limit() {
        let mut p = params();
        p.visibility = true;
        p.max_stretch = 2.0;
        p.min_facing_cos = -0.3;
        let toward = Vec3::NEG_Z;
        let at = Vec3::new(0.0, 0.0, 1.0);
        let map = Flat(1.0);
        let w = |p: &LiveParams, map: &Flat, pc: Vec3, nc: Vec3, pa: Vec3, na: Vec3| {
            live_lookup_weighted(p, map, pc, nc, pa, na)
        };
        // Hard seams: weight 1 wherever valid.
        assert_eq!(
            w(&p, &map, at, toward, at, toward),
            (code::VALID, [49.5, 49.5], 1.0)
        );
        p.feather = true;
        assert_eq!(w(&p, &map, at, toward, at, toward).2, 1.0);
        // Facing: a key normal tilted to a cosine just above the limit.
        let tilted = |c: f32| Vec3::new((1.0 - c * c).sqrt(), 0.0, -c);
        // (An animated normal facing away: never stretched.)
        let away = Vec3::Z;
        let (c0, _, w0) = w(&p, &map, at, tilted(-0.299), at, away);
        assert_eq!(c0, code::VALID);
        assert!(w0 < 1e-3, "{w0}");
        assert_eq!(
            w(&p, &map, at, tilted(-0.301), at, away).0,
            code::BACK_FACING
        );
        let mid = w(&p, &map, at, tilted(-0.175), at, away).2;
        assert!((mid - 0.5).abs() < 0.01, "{mid}");
        // Frame edge: 100 px wide image, the point 3 px from the right border (half the ramp).
        let edge = Vec3::new((96.5 - 49.5) / 100.0, 0.0, 1.0);
        let (c, px, we) = w(&p, &map, edge, toward, edge, toward);
        assert_eq!(c, code::VALID);
        assert!((px[0] - 96.5).abs() < 1e-4);
        assert!((we - 0.5).abs() < 0.01, "{we}");
        // Depth: tolerance 0.5 % + 1 mm at 1 m = 0.006; half-way to the occlusion limit.
        // A surface a rounding error behind the map's depth: its ramp (0.99999) counts as 1.
        let rounding = Vec3::new(0.0, 0.0, 1.000_01);
        assert_eq!(w(&p, &map, rounding, toward, rounding, toward).2, 1.0);
        let behind = Vec3::new(0.0, 0.0, 1.003);
        let wd = w(&p, &map, behind, toward, behind, toward).2;
        assert!((wd - 0.5).abs() < 0.01, "{wd}");
        let limit = Vec3::new(0.0, 0.0, 1.00599);
        assert!(w(&p, &map, limit, toward, limit, toward).2 < 1e-3);
        let past = Vec3::new(0.0, 0.0, 1.0061);
        assert_eq!(w(&p, &map, past, toward, past, toward).0, code::OCCLUDED);
        // Stretch: key cosine 0.4 (limit 0.8 for the animated cosine), ramp 0.4 wide; the
        // key-pose facing ramp is 1 there.
        let key = tilted(0.4);
        assert_eq!(w(&p, &map, at, key, at, tilted(0.35)).2, 1.0);
        let ws = w(&p, &map, at, key, at, tilted(0.6)).2;
        assert!((ws - 0.5).abs() < 0.01, "{ws}");
        assert!(w(&p, &map, at, key, at, tilted(0.7999)).2 < 1e-3);
        assert_eq!(w(&p, &map, at, key, at, tilted(0.81)).0, code::STRETCHED);
    }

    #[test]
    fn distortion_matches_pa_camera() {
        let model = pa_camera::CameraModel {
            intrinsics: pa_camera::Intrinsics {
                fx: 500.0,
                fy: 510.0,
                cx: 320.0,
                cy: 240.0,
                width: 640,
                height: 480,
            },
            distortion: pa_camera::Distortion {
                k1: -0.2,
                k2: 0.05,
                p1: 0.001,
                p2: -0.002,
                k3: 0.01,
            },
        };
        let mut p = params();
        p.frame_camera = FrameCamera::new(&model);
        let pc = Vec3::new(0.2, -0.15, 1.0);
        let (_, px) = live_lookup(&p, &Flat(0.0), pc, Vec3::NEG_Z, pc, Vec3::NEG_Z);
        let want = model.pixel_from_camera(pc.as_dvec3()).unwrap();
        assert!((px[0] as f64 - want.x).abs() < 1e-3 && (px[1] as f64 - want.y).abs() < 1e-3);
    }
}
