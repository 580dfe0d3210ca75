//! Lambertian lighting and unlit output, checked against the formula
//! colour = albedo * (ambient + max(0, n . l) * radiance), encoded to sRGB (±1/255).

mod common;

use glam::{Mat4, Vec3};
use pa_render::{DirectionalLight, Draw, Lighting};

fn srgb(linear: f32) -> u8 {
    let l = linear.clamp(0.0, 1.0);
    let c = if l <= 0.003_130_8 {
        12.92 * l
    } else {
        1.055 * l.powf(1.0 / 2.4) - 0.055
    };
    (c * 255.0).round() as u8
}

fn assert_centre_colour(frame: &pa_render::RenderedFrame, want_linear: [f32; 3], what: &str) {
    let got = frame.pixel(80, 60).expect("centre pixel");
    for c in 0..3 {
        let want = srgb(want_linear[c]);
        assert!(
            got[c].abs_diff(want) <= 1,
            "{what}: channel {c} is {}, want {want} (linear {})",
            got[c],
            want_linear[c]
        );
    }
    assert_eq!(got[3], 255, "{what}: alpha");
}

#[test]
fn lambert_double_sided_and_unlit() {
    let Some(mut renderer) = common::renderer_or_skip("lighting") else {
        return;
    };
    let camera = common::camera(Mat4::IDENTITY);
    let quad = renderer
        .upload_mesh(&common::quad_mesh(1.0, 1.0))
        .expect("upload");
    let albedo = [0.5, 0.25, 0.8];
    let at = Mat4::from_translation(Vec3::new(0.0, 0.0, 1.0));
    let draw = |world_from_mesh| Draw {
        base_color_factor: [albedo[0], albedo[1], albedo[2], 1.0],
        ..Draw::new(&quad, world_from_mesh)
    };
    let lighting = |toward: Vec3| Lighting {
        ambient_rgb: [0.2, 0.1, 0.3],
        directional: Some(DirectionalLight {
            toward_light_world: toward,
            radiance_rgb: [0.6, 0.8, 0.5],
        }),
    };
    let lit = |n_dot_l: f32| -> [f32; 3] {
        let l = lighting(Vec3::Z);
        let d = l.directional.map(|d| d.radiance_rgb).unwrap_or([0.0; 3]);
        std::array::from_fn(|c| albedo[c] * (l.ambient_rgb[c] + n_dot_l * d[c]))
    };

    // Unlit: albedo exactly.
    let frame = renderer
        .render(&camera, None, &[draw(at)], [0.0; 4], 160, 120)
        .expect("render");
    assert_centre_colour(&frame, albedo, "unlit");

    // The quad's normal (+Z) points away from the camera: the camera sees its back side,
    // whose normal is -Z. A light toward the camera (-Z) hits it head-on (n.l = 1)...
    let frame = renderer
        .render(
            &camera,
            Some(&lighting(-Vec3::Z)),
            &[draw(at)],
            [0.0; 4],
            160,
            120,
        )
        .expect("render");
    assert_centre_colour(&frame, lit(1.0), "back side lit head-on");

    // ...a light from behind the quad leaves ambient only...
    let frame = renderer
        .render(
            &camera,
            Some(&lighting(Vec3::Z)),
            &[draw(at)],
            [0.0; 4],
            160,
            120,
        )
        .expect("render");
    assert_centre_colour(&frame, lit(0.0), "light from behind");

    // ...a light at 60 degrees gives n.l = cos 60 = 0.5 (direction not normalised on input)...
    let toward = Vec3::new(
        0.0,
        -(60f32.to_radians().sin()),
        -(60f32.to_radians().cos()),
    ) * 3.0;
    let frame = renderer
        .render(
            &camera,
            Some(&lighting(toward)),
            &[draw(at)],
            [0.0; 4],
            160,
            120,
        )
        .expect("render");
    assert_centre_colour(&frame, lit(0.5), "light at 60 degrees");

    // ...and a mirroring world_from_mesh (flipped winding, flipped normal) changes nothing.
    let mirrored = at * Mat4::from_scale(Vec3::new(-1.0, 1.0, 1.0));
    let frame = renderer
        .render(
            &camera,
            Some(&lighting(-Vec3::Z)),
            &[draw(mirrored)],
            [0.0; 4],
            160,
            120,
        )
        .expect("render");
    assert_centre_colour(&frame, lit(1.0), "mirrored");
}
