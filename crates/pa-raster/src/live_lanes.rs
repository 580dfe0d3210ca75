//! [`live_lookup_weighted`] of four fragments at once: the projection, the lens distortion,
//! the facing and stretch tests and their feathering in four SIMD lanes (`wide::f32x4`), then
//! each lane's visibility test on its own ([`visible_weight`]). Every lane's result equals the
//! one-fragment look-up's to the bit: the same operations in the same order (IEEE division and
//! square root are exact in SIMD too, nothing is fused), and the same order of tests for the
//! code.
//!
//! [`live_lookup_weighted`]: crate::live::live_lookup_weighted

use glam::Vec3;
use wide::f32x4;

use crate::live::{code, visible_weight, InvDepthMap, LiveParams};
use crate::look::{EDGE_FEATHER_PX, FACING_FEATHER_COS, STRETCH_FEATHER};

/// One fragment's look-up inputs: key-pose point and normal, animated point and normal, all in
/// the camera frame (as [`crate::live::live_lookup_weighted`] takes them).
pub type LookupInputs = [Vec3; 4];

/// Lane `l` of a mask is set.
#[inline(always)]
fn set(mask: f32x4, l: usize) -> bool {
    mask.to_bitmask() & (1 << l) != 0
}

/// [`crate::look::ramp`] in four lanes.
#[inline(always)]
fn ramp4(x: f32x4, width: f32x4) -> f32x4 {
    let zero = f32x4::splat(0.0);
    let one = f32x4::splat(1.0);
    let t = x / width;
    let tc = t.min(one);
    let smooth = tc * tc * (f32x4::splat(3.0) - f32x4::splat(2.0) * tc);
    let positive = t.simd_gt(zero).select(smooth, zero);
    let step = x.simd_gt(zero).select(one, zero);
    width.simd_gt(zero).select(positive, step)
}

/// `[x, y, z]` of one of the four inputs of four fragments, as lanes.
#[inline(always)]
fn lanes(inputs: &[LookupInputs; 4], k: usize) -> [f32x4; 3] {
    std::array::from_fn(|c| f32x4::from(std::array::from_fn::<f32, 4, _>(|l| inputs[l][k][c])))
}

/// `a . b` of three-lane vectors, in glam's order.
#[inline(always)]
fn dot(a: &[f32x4; 3], b: &[f32x4; 3]) -> f32x4 {
    (a[0] * b[0]) + (a[1] * b[1]) + (a[2] * b[2])
}

/// [`crate::live::facing_cos`] in four lanes.
#[inline(always)]
fn facing_cos4(p: &[f32x4; 3], n: &[f32x4; 3]) -> f32x4 {
    let len2 = dot(n, n) * dot(p, p);
    let cos = -dot(n, p) / len2.sqrt();
    len2.simd_gt(f32x4::splat(0.0))
        .select(cos, f32x4::splat(-1.0))
}

/// The look-ups of four fragments: `(code, frame pixel, weight)` each, equal to
/// [`crate::live::live_lookup_weighted`] of each.
pub fn live_lookup_weighted4(
    p: &LiveParams,
    key_depth: &impl InvDepthMap,
    inputs: &[LookupInputs; 4],
) -> [(u8, [f32; 2], f32); 4] {
    let s = f32x4::splat;
    let cam = &p.frame_camera;
    let [pcx, pcy, pcz] = lanes(inputs, 0);
    let (nc, pa, na) = (lanes(inputs, 1), lanes(inputs, 2), lanes(inputs, 3));
    let in_front = pcz.simd_gt(s(1e-6));
    let (x, y) = (pcx / pcz, pcy / pcz);
    let r2 = x * x + y * y;
    let monotonic = (s(1.0)
        + r2 * (s(3.0 * cam.k1) + r2 * (s(5.0 * cam.k2) + r2 * s(7.0) * s(cam.k3))))
    .simd_gt(s(0.0));
    let radial = s(1.0) + r2 * (s(cam.k1) + r2 * (s(cam.k2) + r2 * s(cam.k3)));
    let xd = x * radial + s(2.0 * cam.p1) * x * y + s(cam.p2) * (r2 + s(2.0) * x * x);
    let yd = y * radial + s(cam.p1) * (r2 + s(2.0) * y * y) + s(2.0 * cam.p2) * x * y;
    let (px, py) = (s(cam.fx) * xd + s(cam.cx), s(cam.fy) * yd + s(cam.cy));
    let inside = px.simd_ge(s(-0.5))
        & py.simd_ge(s(-0.5))
        & px.simd_le(s(cam.width - 0.5))
        & py.simd_le(s(cam.height - 0.5));
    let pc = [pcx, pcy, pcz];
    let cos_key = facing_cos4(&pc, &nc);
    let facing = cos_key.simd_gt(s(p.min_facing_cos));
    let mut weight = s(1.0);
    if p.feather {
        let edge = (px + s(0.5))
            .min(py + s(0.5))
            .min(s(cam.width - 0.5) - px)
            .min(s(cam.height - 0.5) - py);
        weight = ramp4(edge, s(EDGE_FEATHER_PX))
            * ramp4(cos_key - s(p.min_facing_cos), s(FACING_FEATHER_COS));
    }
    let mut stretched = s(0.0);
    if p.max_stretch > 0.0 {
        let limit = s(p.max_stretch) * cos_key.max(s(0.0));
        let cos_anim = facing_cos4(&pa, &na);
        stretched = cos_anim.simd_gt(limit);
        if p.feather {
            weight *= ramp4(limit - cos_anim, s(STRETCH_FEATHER) * limit);
        }
    }
    let (x, y, z) = (x.to_array(), y.to_array(), pcz.to_array());
    let (px, py, weight) = (px.to_array(), py.to_array(), weight.to_array());
    std::array::from_fn(|l| {
        if !set(in_front, l) || !set(monotonic, l) {
            return (code::OUTSIDE, [0.0; 2], 0.0);
        }
        let pixel = [px[l], py[l]];
        if !set(inside, l) {
            return (code::OUTSIDE, pixel, 0.0);
        }
        if !set(facing, l) {
            return (code::BACK_FACING, pixel, 0.0);
        }
        if set(stretched, l) {
            return (code::STRETCHED, pixel, 0.0);
        }
        visible_weight(p, key_depth, (x[l], y[l]), z[l], pixel, weight[l])
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::live::{live_lookup_weighted, FrameCamera};

    /// A key depth that varies per texel (so the four lanes read different texels).
    struct Ramp;
    impl InvDepthMap for Ramp {
        fn size(&self) -> (u32, u32) {
            (100, 100)
        }
        fn inv_z_clamped(&self, x: i32, y: i32) -> f32 {
            let (x, y) = (x.clamp(0, 99), y.clamp(0, 99));
            if (x + 3 * y) % 17 == 0 {
                0.0
            } else {
                0.4 + 0.01 * ((x * 7 + y * 13) % 50) as f32
            }
        }
    }

    #[test]
    fn four_lanes_equal_four_single_look_ups_to_the_bit() {
        let mut seed = 0x9e37_79b9_u32;
        let mut unit = move || {
            seed ^= seed << 13;
            seed ^= seed >> 17;
            seed ^= seed << 5;
            seed as f32 / u32::MAX as f32
        };
        let mut camera = FrameCamera::test_pinhole();
        let mut codes_seen = std::collections::BTreeSet::new();
        let mut checked = 0;
        for case in 0..16 {
            let mut p = LiveParams::new(camera);
            p.feather = case & 1 == 0;
            p.visibility = case & 2 == 0;
            p.max_stretch = if case & 4 == 0 { 1.5 } else { 0.0 };
            p.min_facing_cos = if case & 8 == 0 { -0.1 } else { 0.05 };
            if case == 8 {
                // Lens distortion, strong enough to fold back at the frame's corners.
                camera.k1 = -0.3;
                camera.k2 = 0.08;
                camera.p1 = 0.002;
                camera.p2 = -0.001;
                camera.k3 = -0.05;
            }
            for _ in 0..500 {
                let inputs: [LookupInputs; 4] = std::array::from_fn(|_| {
                    let r: [f32; 13] = std::array::from_fn(|_| unit() - 0.5);
                    let mut pc = Vec3::new(r[0] * 1.6, r[1] * 1.6, 1.4 + 2.0 * r[2]);
                    let mut nc = Vec3::new(r[3], r[4], r[5]);
                    let pa = pc + Vec3::new(r[6], r[7], r[8]) * 0.1;
                    let mut na = Vec3::new(r[9], r[10], r[11]);
                    match ((r[12] + 0.5) * 10.0) as u32 {
                        0 => pc.z = -pc.z,    // behind the camera
                        1 => nc = Vec3::ZERO, // no normal
                        2 => na = Vec3::NAN,
                        3 => pc.x = f32::NAN,
                        _ => {}
                    }
                    [pc, nc, pa, na]
                });
                let got = live_lookup_weighted4(&p, &Ramp, &inputs);
                for (l, &[pc, nc, pa, na]) in inputs.iter().enumerate() {
                    let want = live_lookup_weighted(&p, &Ramp, pc, nc, pa, na);
                    let bits = |r: (u8, [f32; 2], f32)| (r.0, r.1.map(f32::to_bits), r.2.to_bits());
                    assert_eq!(
                        bits(got[l]),
                        bits(want),
                        "case {case}, lane {l}: {inputs:?}"
                    );
                    codes_seen.insert(want.0);
                    checked += 1;
                }
            }
        }
        assert_eq!(checked, 16 * 500 * 4);
        let every = [
            code::OUTSIDE,
            code::BACK_FACING,
            code::OCCLUDED,
            code::STRETCHED,
            code::VALID,
        ];
        for c in every {
            assert!(
                codes_seen.contains(&c),
                "code {c} never produced: {codes_seen:?}"
            );
        }
    }
}
