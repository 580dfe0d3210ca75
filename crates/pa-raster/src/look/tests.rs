use super::*;

/// An irradiance that is exactly first order (ambient 0.6, a light of 0.4 along +z: never
/// negative over the sphere), so the ratio recovers a Lambertian surface's true shading.
fn linear_light() -> [[f32; 4]; 3] {
    [
        [0.6, 0.0, 0.0, 0.4],
        [0.5, 0.1, 0.0, 0.3],
        [0.7, 0.0, -0.2, 0.2],
    ]
}

#[test]
fn ramp_is_smooth_and_clamped() {
    assert_eq!(ramp(-1.0, 2.0), 0.0);
    assert_eq!(ramp(0.0, 2.0), 0.0);
    assert_eq!(ramp(1.0, 2.0), 0.5);
    assert_eq!(ramp(2.0, 2.0), 1.0);
    assert_eq!(ramp(5.0, 2.0), 1.0);
    // Monotonic, with zero slope at both ends.
    let mut last = 0.0;
    for i in 0..=100 {
        let v = ramp(i as f32 / 50.0, 2.0);
        assert!(v >= last);
        last = v;
    }
    assert!(ramp(0.01, 2.0) < 1e-4 && ramp(1.99, 2.0) > 1.0 - 1e-4);
    // Zero width: a step that is 0 at the limit itself.
    assert_eq!(ramp(0.0, 0.0), 0.0);
    assert_eq!(ramp(1e-6, 0.0), 1.0);
    assert_eq!(ramp(f32::NAN, 1.0), 0.0);
}

/// Analytic Lambertian case: a surface point of albedo `a` seen at normal `n_k` has colour
/// `a E(n_k)`; relit to `n_i` it must equal the true shading `a E(n_i)` (exactly, to f32
/// rounding, while the ratio is inside the clamp).
#[test]
fn relighting_a_lambertian_point_gives_its_true_shading() {
    let rows = linear_light();
    let albedo = [0.8f32, 0.45, 0.2];
    let mut worst = 0.0f32;
    for i in 0..64 {
        let a = i as f32 * 0.7;
        let nk = Vec3::new(a.cos() * 0.6, a.sin() * 0.6, 0.8).normalize();
        // The in-between turned the point 40 degrees about y.
        let ni = glam::Quat::from_rotation_y(40f32.to_radians()) * nk;
        let (ek, ei) = (irradiance(&rows, nk), irradiance(&rows, ni));
        let seen: [f32; 3] = std::array::from_fn(|c| albedo[c] * ek[c]);
        let f = relight_factor(&rows, nk, ni);
        for c in 0..3 {
            let truth = albedo[c] * ei[c];
            worst = worst.max((seen[c] * f[c] - truth).abs());
        }
    }
    assert!(worst < 1e-5, "worst {worst}");
}

#[test]
fn relight_factor_is_clamped_and_one_for_a_constant_light() {
    let c = [[0.7, 0.0, 0.0, 0.0]; 3];
    assert_eq!(relight_factor(&c, Vec3::Z, -Vec3::Z), [1.0; 3]);
    // A strong directional light: turning from lit to unlit is clamped at RELIGHT_MIN, the
    // other way at RELIGHT_MAX (the irradiance floored, never divided by zero).
    let d = [[0.1, 0.0, 0.0, 1.0]; 3];
    assert_eq!(relight_factor(&d, Vec3::Z, -Vec3::Z), [RELIGHT_MIN; 3]);
    assert_eq!(relight_factor(&d, -Vec3::Z, Vec3::Z), [RELIGHT_MAX; 3]);
    // Zero normals (a model without normals) give the constant term: factor 1.
    assert_eq!(relight_factor(&d, Vec3::ZERO, Vec3::ZERO), [1.0; 3]);
}

#[test]
fn blend_weights() {
    let (a, b) = ([1.0, 0.0, 0.5], [0.0, 1.0, 0.5]);
    assert_eq!(blend(a, b, 1.0), a);
    assert_eq!(blend(a, b, 0.0), b);
    assert_eq!(blend(a, b, 0.25), [0.25, 0.75, 0.5]);
}

#[test]
fn grazing_is_zero_head_on_one_edge_on_and_schlick_between() {
    let p = Vec3::new(0.0, 0.0, 2.0);
    assert_eq!(grazing(p, Vec3::new(0.0, 0.0, -1.0)), 0.0);
    assert_eq!(grazing(p, Vec3::new(1.0, 0.0, 0.0)), 1.0);
    // Facing cosine 0.5: (1 - 0.5)^5.
    let n = Vec3::new(0.75f32.sqrt(), 0.0, -0.5);
    assert!((grazing(p, n) - 1.0 / 32.0).abs() < 1e-6);
    // Facing away clamps to edge-on; no normal counts as edge-on.
    assert_eq!(grazing(p, Vec3::new(0.0, 0.0, 1.0)), 1.0);
    assert_eq!(grazing(p, Vec3::ZERO), 1.0);
}
