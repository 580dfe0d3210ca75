use super::*;

/// A closed axis-aligned box standing on the plane: x in [-hx, hx], y in [-hy, hy], height
/// `height` (z from 0 up to -height).
fn standing_box(hx: f32, hy: f32, height: f32) -> Vec<[Vec3; 3]> {
    let c = |i: usize| {
        Vec3::new(
            if i & 1 == 0 { -hx } else { hx },
            if i & 2 == 0 { -hy } else { hy },
            if i & 4 == 0 { 0.0 } else { -height },
        )
    };
    let quads = [
        [0, 1, 3, 2],
        [4, 5, 7, 6],
        [0, 1, 5, 4],
        [2, 3, 7, 6],
        [0, 2, 6, 4],
        [1, 3, 7, 5],
    ];
    quads
        .iter()
        .flat_map(|q| [[c(q[0]), c(q[1]), c(q[2])], [c(q[0]), c(q[2]), c(q[3])]])
        .collect()
}

fn toward(elevation_deg: f32, azimuth_deg: f32) -> Vec3 {
    let (e, a) = (elevation_deg.to_radians(), azimuth_deg.to_radians());
    Vec3::new(e.cos() * a.cos(), e.cos() * a.sin(), -e.sin())
}

#[test]
fn a_hard_shadow_of_a_pole_has_the_analytic_length_and_direction() {
    // A 10 mm square pole 100 mm tall under a point light at infinity, elevation 35 deg,
    // azimuth 120 deg: the shadow runs from the pole away from the light, H / tan(e) long.
    let (hw, height, e, az) = (0.005, 0.1, 35.0f32, 120.0f32);
    let l = toward(e, az);
    let light = AreaLight {
        toward_light: l,
        angular_radius_rad: 0.0,
        samples: 1,
    };
    let s = PlaneShadows::compute(&standing_box(hw, hw, height), &[light], None);
    let len = height / e.to_radians().tan();
    let axis = -l.truncate().normalize();
    let side = axis.perp();
    // The top face projects to a square of half-diagonal hw * sqrt 2 around `len * axis`.
    let reach = hw * 2f32.sqrt();
    for f in [0.15, 0.3, 0.5, 0.7, 0.9] {
        let p = axis * (len * f);
        assert!(
            s.light_visibility(0, p) < 0.01,
            "f {f}: {}",
            s.light_visibility(0, p)
        );
        for sign in [-1.0, 1.0] {
            let q = p + side * sign * (reach + 0.002);
            assert!(s.light_visibility(0, q) > 0.99, "beside f {f}");
        }
    }
    // Just short of the tip: dark; past it: lit; and nothing on the light's side.
    assert!(s.light_visibility(0, axis * (len - 0.002)) < 0.01);
    assert!(s.light_visibility(0, axis * (len + reach + 0.002)) > 0.99);
    assert!(s.light_visibility(0, -axis * 0.03) > 0.99);
    // No contact shadow asked for: the sky is fully visible.
    assert_eq!(s.ambient_visibility(Vec2::new(hw + 0.001, 0.0)), 1.0);
}

#[test]
fn an_area_light_gives_the_analytic_penumbra() {
    // A thin wall (2 mm thick, 300 mm wide, 80 mm tall) across the light's azimuth; the
    // light's disc has a 4 deg angular radius at 40 deg elevation. A point at distance d
    // behind the wall is in the umbra when even the disc's top is below the wall's far top
    // edge: d < hw + H / tan(e + R); fully lit when d > hw + H / tan(e - R); and sees half the
    // disc at d = hw + H / tan(e).
    let (hw, wide, height, e, r) = (0.001, 0.15, 0.08, 40f32, 4f32);
    let light = AreaLight {
        toward_light: toward(e, 0.0),
        angular_radius_rad: r.to_radians(),
        samples: 256,
    };
    let s = PlaneShadows::compute(&standing_box(hw, wide, height), &[light], None);
    let d = |el: f32| hw + height / el.to_radians().tan();
    let at = |dist: f32| s.light_visibility(0, Vec2::new(-dist, 0.0));
    let (umbra, mid, lit) = (d(e + r), d(e), d(e - r));
    assert!(at(umbra - 0.001) < 0.02, "umbra {}", at(umbra - 0.001));
    assert!(at(lit + 0.001) > 0.98, "lit {}", at(lit + 0.001));
    assert!((at(mid) - 0.5).abs() < 0.06, "half {}", at(mid));
    // Monotonic across the penumbra.
    let steps: Vec<f32> = (0..=20)
        .map(|k| at(umbra + (lit - umbra) * k as f32 / 20.0))
        .collect();
    assert!(steps.windows(2).all(|p| p[1] >= p[0] - 0.02), "{steps:?}");
    // The penumbra is wider than a hard edge: values strictly between 0.1 and 0.9 span at
    // least half of the analytic width.
    let soft = steps.iter().filter(|v| (0.1..0.9).contains(*v)).count();
    assert!(soft >= 10, "{steps:?}");
}

#[test]
fn the_contact_shadow_darkens_the_foot_of_a_wall_and_fades_within_the_radius() {
    // A tall wide wall: at its foot it hides half of the cosine-weighted sky (a vertical
    // plane through the point splits the hemisphere's projected disc in half); beyond the
    // radius it hides nothing.
    let radius = 0.03;
    let contact = ContactShadow {
        radius_m: radius,
        samples: 512,
    };
    let s = PlaneShadows::compute(&standing_box(0.005, 0.2, 0.15), &[], Some(&contact));
    let at = |d: f32| s.ambient_visibility(Vec2::new(-0.005 - d, 0.0));
    assert!((at(0.0008) - 0.5).abs() < 0.06, "foot {}", at(0.0008));
    assert!(at(radius + 0.002) > 0.999, "beyond {}", at(radius + 0.002));
    let ramp: Vec<f32> = (1..=15).map(|k| at(k as f32 * 0.002)).collect();
    assert!(ramp.windows(2).all(|p| p[1] >= p[0] - 0.01), "{ramp:?}");
    assert!(ramp[0] < 0.6 && ramp[14] > 0.95, "{ramp:?}");
    // No light asked for: light 0 is fully visible.
    assert_eq!(s.light_visibility(0, Vec2::new(-0.006, 0.0)), 1.0);
}

#[test]
fn no_occluder_no_shadow_and_the_result_is_deterministic() {
    let light = AreaLight {
        toward_light: toward(50.0, 30.0),
        angular_radius_rad: 0.05,
        samples: 16,
    };
    let contact = ContactShadow {
        radius_m: 0.03,
        samples: 16,
    };
    let empty = PlaneShadows::compute(&[], &[light], Some(&contact));
    for p in [Vec2::ZERO, Vec2::new(0.1, -0.2)] {
        assert_eq!(empty.light_visibility(0, p), 1.0);
        assert_eq!(empty.ambient_visibility(p), 1.0);
    }
    let tris = standing_box(0.02, 0.03, 0.07);
    let a = PlaneShadows::compute(&tris, &[light], Some(&contact));
    let b = PlaneShadows::compute(&tris, &[light], Some(&contact));
    assert_eq!(a.lights, b.lights);
    assert_eq!(a.ambient, b.ambient);
    assert!(a.lights[0].iter().any(|&v| v < 0.01));
}
