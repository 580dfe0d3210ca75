//! The harder sets of the scene generator (`pa_scene::set`): the prop's cast shadow lies where
//! the light's geometry puts it and darkens the plane by the analytic ratio; the clean plate
//! has no shadow; the fill light adds its analytic share; the variants are deterministic; and
//! the default set renders exactly as the set always did (a replica of the generator's
//! original render, and pinned hashes of its textures).

use glam::{Mat4, Vec2, Vec3};
use pa_camera::camera_from_world_look_at;
use pa_model::anim;
use pa_pipeline::GpuTwin;
use pa_render::{CpuCamera, CpuMesh, Draw, RenderedFrame, Renderer};
use pa_scene::scene::{
    board_texture, downsample, marker_from_prop, set_board, set_lighting, table_texture,
    Background, BOARD_SHEET_M, FAR_M, NEAR_M, TABLE_M,
};
use pa_scene::variant::fill_light;
use pa_scene::{parse_variant, Scene, SceneSpec, SetOptions};

const W: u32 = 320;
const H: u32 = 180;

fn renderer() -> Option<Renderer> {
    match Renderer::new() {
        Ok(r) => Some(r),
        Err(e) => {
            println!("skipped: no wgpu adapter ({e})");
            None
        }
    }
}

fn spec(set: SetOptions) -> SceneSpec {
    SceneSpec {
        width: W,
        height: H,
        frames: 25,
        set,
        ..SceneSpec::default()
    }
}

fn lin(v: u8) -> f64 {
    let c = v as f64 / 255.0;
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// Pixel of marker point `p` in a `W x H` view.
fn pixel(scene: &Scene, camera_from_marker: Mat4, p: Vec3) -> (usize, usize) {
    let c = camera_from_marker.transform_point3(p).as_dvec3();
    let k = scene.intrinsics;
    let u = k.fx * c.x / c.z + k.cx;
    let v = k.fy * c.y / c.z + k.cy;
    (u.round() as usize, v.round() as usize)
}

/// Linear RGB of `frame` at pixel `(x, y)`, averaged over the 3x3 block around it.
fn linear_at(frame: &RenderedFrame, (x, y): (usize, usize)) -> [f64; 3] {
    let mut s = [0.0; 3];
    for dy in 0..3 {
        for dx in 0..3 {
            let i = ((y + dy - 1) * frame.width as usize + x + dx - 1) * 4;
            for (c, s) in s.iter_mut().enumerate() {
                *s += lin(frame.rgba8[i + c]) / 9.0;
            }
        }
    }
    s
}

#[test]
fn the_cast_shadow_lies_where_the_light_puts_it_with_the_analytic_darkening() {
    let Some(mut r) = renderer() else { return };
    let plain = Scene::new(
        spec(SetOptions {
            shadows: true,
            ..SetOptions::default()
        }),
        &mut r,
    )
    .expect("scene");
    // Straight down from 0.6 m: the whole shadow is in view.
    let view = camera_from_world_look_at(Vec3::new(0.0, 0.0, -0.6), Vec3::ZERO, Vec3::NEG_Y)
        .expect("view");
    // The set without the prop (no shadow) and with it.
    let a = plain.render_view(&mut r, view, None).expect("render");
    let b = plain.render_view(&mut r, view, Some(0.0)).expect("render");
    // The key light: the shadow runs from the prop's axis away from the light, and a point at
    // height h on the axis (the bust is a surface of revolution about the marker's Z axis at
    // rest) casts its shadow h / tan(elevation) along it.
    let key = set_lighting().directional.expect("key light");
    let l = key.toward_light_world.normalize();
    let axis = -l.truncate().normalize();
    let tan_e = -l.z / l.truncate().length();
    let height = plain.spec.prop.height_m;
    // Plane lighting (normal -Z): ambient + radiance * cos.
    let amb = set_lighting().ambient_rgb;
    let direct = key.radiance_rgb.map(|c| c * -l.z);
    // In the umbra of the head (0.55 of the height: the head's radius there is 0.26 of the
    // height, 52 mm, four times the penumbra's half-width; on white paper just off tag 2),
    // the plane keeps its ambient share only.
    let umbra = axis * (0.55 * height / tan_e);
    let (sa, sb) = (
        linear_at(&a, pixel(&plain, view, umbra.extend(0.0))),
        linear_at(&b, pixel(&plain, view, umbra.extend(0.0))),
    );
    for c in 0..3 {
        let want = amb[c] as f64 / (amb[c] + direct[c]) as f64;
        let got = sb[c] / sa[c];
        assert!((got - want).abs() < 0.03, "channel {c}: {got} vs {want}");
    }
    // The shadow's far end: the farthest shadow of a vertex (a point at height h casts its
    // shadow h / tan(e) along the axis) under the light's lowest direction (the disc's
    // 4 deg radius). Past it, on the light's side and across the axis, beyond where the prop
    // hides the plane from this view: untouched, byte for byte.
    let tan_low = (tan_e.atan() - 4f32.to_radians()).tan();
    let tip = plain
        .prop_triangles(0.0)
        .iter()
        .flatten()
        .map(|v| v.truncate().dot(axis) + -v.z / tan_low)
        .fold(f32::MIN, f32::max);
    assert!(tip > 0.16 && tip < 0.25, "{tip}");
    for p in [
        axis * (tip + 0.005),
        axis * (tip + 0.03),
        -axis * 0.08,
        axis * (0.5 * tip) + axis.perp() * 0.09,
        axis * (0.5 * tip) - axis.perp() * 0.09,
    ] {
        let (x, y) = pixel(&plain, view, p.extend(0.0));
        let i = (y * W as usize + x) * 4;
        assert_eq!(a.rgba8[i..i + 3], b.rgba8[i..i + 3], "at {p}");
    }
    // The shadow as a whole: every darkened pixel is a plane pixel on the shadow's side of
    // the prop (its marker point projects onto the axis at -10 mm .. tip + 15 mm).
    let mut darkened = 0;
    let inv = view.inverse();
    for y in 0..H as usize {
        for x in 0..W as usize {
            let i = y * W as usize + x;
            // Pixels of the prop itself are not the plane's.
            let prop = (a.depth_m[i] - b.depth_m[i]).abs() > 1e-4;
            if prop || a.rgba8[i * 4..i * 4 + 3] == b.rgba8[i * 4..i * 4 + 3] {
                continue;
            }
            darkened += 1;
            let z = a.depth_m[i];
            let k = plain.intrinsics;
            let cam = Vec3::new(
                ((x as f64 - k.cx) / k.fx) as f32 * z,
                ((y as f64 - k.cy) / k.fy) as f32 * z,
                z,
            );
            let p = inv.transform_point3(cam);
            assert!(p.z.abs() < 0.003, "a darkened pixel off the plane at {p}");
            let along = p.truncate().dot(axis);
            // The contact shadow reaches 30 mm around the pedestal (radius 48 mm).
            let near_base = p.truncate().length() < 0.048 + 0.032;
            assert!(
                near_base || (-0.01..tip + 0.002).contains(&along),
                "darkened at {p}"
            );
            assert!(b.rgba8[i * 4..i * 4 + 3]
                .iter()
                .zip(&a.rgba8[i * 4..i * 4 + 3])
                .all(|(b, a)| b <= a));
        }
    }
    assert!(darkened > 500, "{darkened}");
}

#[test]
fn the_clean_plate_has_no_shadow_and_the_lights_add_their_analytic_share() {
    // The default set's table receives the ambient light only (its quads face into the
    // table, so the renderer flips their normal; kept as it was). A set with shadows lights
    // its table: every plane pixel of the clean plate is the default's times
    // (ambient + key) / ambient, with no shadow anywhere (no prop); with the fill light too,
    // (ambient + key + fill) / ambient.
    let Some(mut r) = renderer() else { return };
    let plain = Scene::new(spec(SetOptions::default()), &mut r).expect("scene");
    let (p0, v0) = plain.clean_plate(&mut r).expect("plate");
    let lighting = set_lighting();
    let key = lighting.directional.expect("key");
    let f = fill_light();
    let cos = |d: Vec3| f64::from(-d.normalize().z);
    for fill_on in [false, true] {
        let scene = Scene::new(
            spec(SetOptions {
                shadows: true,
                fill_light: fill_on,
                ..SetOptions::default()
            }),
            &mut r,
        )
        .expect("scene");
        let (p1, v1) = scene.clean_plate(&mut r).expect("plate");
        assert_eq!(v0, v1);
        assert!(p0
            .depth_m
            .iter()
            .zip(&p1.depth_m)
            .all(|(a, b)| a.is_finite() == b.is_finite()));
        let mut checked = 0;
        let mut worst = 0f64;
        let (w, h) = (W as usize, H as usize);
        for (i, &z) in p0.depth_m.iter().enumerate() {
            // Pixels of the table alone (a pixel at the table's far edge mixes in the
            // background, which no light changes).
            let (x, y) = (i % w, i / w);
            let inner = x > 0 && y > 0 && x + 1 < w && y + 1 < h;
            if !z.is_finite()
                || !inner
                || [i - 1, i + 1, i - w, i + w]
                    .iter()
                    .any(|&j| !p0.depth_m[j].is_finite())
            {
                continue;
            }
            for c in 0..3 {
                let a = lin(p0.rgba8[i * 4 + c]);
                if a < 0.05 {
                    continue; // too dark for a ratio of 8-bit codes
                }
                let amb = f64::from(lighting.ambient_rgb[c]);
                let mut lit = amb + f64::from(key.radiance_rgb[c]) * cos(key.toward_light_world);
                if fill_on {
                    lit += f64::from(f.radiance_rgb[c]) * cos(f.toward_light_world);
                }
                let got = lin(p1.rgba8[i * 4 + c]) / a;
                worst = worst.max((got / (lit / amb) - 1.0).abs());
                checked += 1;
            }
        }
        assert!(checked > 30_000, "{checked}");
        // 8-bit codes of values around 0.05..0.9 (linear): within 4 %.
        assert!(worst < 0.04, "fill {fill_on}: worst relative error {worst}");
    }
}

#[test]
fn every_variant_is_deterministic_and_moves_the_camera_with_the_prop() {
    let Some(mut r) = renderer() else { return };
    let hard = parse_variant("hard").expect("variant");
    let mut s = spec(hard.set);
    s.background = hard.background.expect("cloth");
    let a = Scene::new(s.clone(), &mut r).expect("scene");
    let b = Scene::new(s, &mut r).expect("scene");
    let fa = a.frame(&mut r, 9).expect("frame");
    let fb = b.frame(&mut r, 9).expect("frame");
    assert!(fa.input == fb.input);
    assert!(fa.ground_truth == fb.ground_truth);
    assert!(fa.input != fa.ground_truth);
    // The prop stands at its placement, and the camera looks at it: the prop's base centre
    // projects near the image's horizontal centre, as the default prop's does.
    let base = a.marker_from_prop().transform_point3(Vec3::ZERO);
    assert!((base.truncate() - Vec2::new(0.0, -BOARD_SHEET_M * 0.5)).length() < 1e-6);
    let (x, _) = pixel(&a, a.camera_from_marker(0), base);
    let plain = Scene::new(spec(SetOptions::default()), &mut r).expect("scene");
    let (x0, _) = pixel(&plain, plain.camera_from_marker(0), Vec3::ZERO);
    assert!((x as i64 - x0 as i64).abs() <= 1, "{x} vs {x0}");
}

/// FNV-1a, 64 bits.
fn fnv(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325, |h, &b| {
        (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3)
    })
}

fn quad(half: f32, z: f32) -> CpuMesh {
    CpuMesh {
        positions: vec![
            [-half, -half, z],
            [half, -half, z],
            [half, half, z],
            [-half, half, z],
        ],
        normals: vec![[0.0, 0.0, -1.0]; 4],
        uvs: vec![[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]],
        indices: vec![0, 1, 2, 0, 2, 3],
        ..Default::default()
    }
}

#[test]
fn the_default_set_renders_as_it_always_did() {
    // The textures of the default set, pinned (CPU code: the same bytes everywhere).
    let wood = table_texture(Background::Wood, 256, 1);
    let plain = table_texture(Background::Plain, 256, 1);
    let sheet = board_texture(&set_board(), 260).expect("board");
    assert_eq!(
        [fnv(&wood.rgba8), fnv(&plain.rgba8), fnv(&sheet.rgba8)],
        [
            0xb2da_3cff_5f7c_cfe6,
            0x220c_cdb8_6e4b_14b9,
            0xb5b0_b42e_0e24_2a3d
        ]
    );
    let Some(mut r) = renderer() else { return };
    let s = spec(SetOptions::default());
    let scene = Scene::new(s.clone(), &mut r).expect("scene");
    assert_eq!(scene.marker_from_prop(), marker_from_prop());
    // The generator's render as it was before the set's options existed: table, sheet and
    // prop under the set's light, 2x2 supersampled, box-filtered.
    let table_mesh = r.upload_mesh(&quad(TABLE_M * 0.5, 0.0005)).expect("mesh");
    let table_tex = r
        .upload_texture(&table_texture(Background::Wood, 2048, s.seed as u32))
        .expect("texture");
    let sheet_mesh = r
        .upload_mesh(&quad(BOARD_SHEET_M * 0.5, 0.0))
        .expect("mesh");
    let sheet_tex = r
        .upload_texture(&board_texture(&set_board(), 2080).expect("board"))
        .expect("texture");
    let twin = GpuTwin::upload(&mut r, &scene.model).expect("twin");
    let replica = |r: &mut Renderer, view: Mat4, t: Option<f32>| {
        let camera = CpuCamera {
            intrinsics: scene.intrinsics.scaled_to(2 * W, 2 * H),
            camera_from_world: view,
            near_m: NEAR_M,
            far_m: FAR_M,
        };
        let mut table = Draw::new(&table_mesh, Mat4::IDENTITY);
        table.texture = Some(&table_tex);
        let mut sheet = Draw::new(&sheet_mesh, Mat4::IDENTITY);
        sheet.texture = Some(&sheet_tex);
        let mut draws = vec![table, sheet];
        let frame;
        if let Some(t) = t {
            let pose = anim::sample(&scene.model, 0, t);
            frame = twin.frame(&scene.model, &pose, marker_from_prop());
            draws.extend(twin.draws(&frame));
        }
        let full = r
            .render(
                &camera,
                Some(&set_lighting()),
                &draws,
                [0.1, 0.1, 0.12, 1.0],
                2 * W,
                2 * H,
            )
            .expect("render");
        downsample(&full, 2)
    };
    let f = scene.frame(&mut r, 13).expect("frame");
    let view = scene.camera_from_marker(13);
    assert!(f.input == replica(&mut r, view, Some(0.0)));
    assert!(f.ground_truth == replica(&mut r, view, Some(13.0 / 24.0)));
    let (plate, plate_view) = scene.clean_plate(&mut r).expect("plate");
    assert!(plate == replica(&mut r, plate_view, None));
}

#[test]
fn the_tag_under_the_covered_tag_placement_still_decodes() {
    // The pedestal stands 3 mm into tag 6's printed square (its quiet zone): the detector
    // still finds tag 6 in the input frames, as it does on the default set.
    let Some(mut r) = renderer() else { return };
    let v = parse_variant("covered-tag").expect("variant");
    let scene = Scene::new(
        SceneSpec {
            width: 480,
            height: 270,
            set: v.set,
            ..SceneSpec::default()
        },
        &mut r,
    )
    .expect("scene");
    let mut det = pa_track::Detector::new(pa_track::DetectorConfig::default()).expect("detector");
    for i in [0, 24, 48] {
        let f = scene.frame(&mut r, i).expect("frame");
        let gray: Vec<u8> = f
            .input
            .rgba8
            .chunks_exact(4)
            .map(|p| {
                ((u32::from(p[0]) * 77 + u32::from(p[1]) * 150 + u32::from(p[2]) * 29) >> 8) as u8
            })
            .collect();
        let image = pa_track::GrayImage::new(480, 270, gray).expect("image");
        let ids: Vec<u32> = det
            .detect(&image)
            .expect("detect")
            .iter()
            .map(|d| d.id)
            .collect();
        assert!(ids.contains(&6), "frame {i}: {ids:?}");
    }
}
