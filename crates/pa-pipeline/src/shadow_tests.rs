//! The analytic case: a box standing on a wood-textured table under an area light (a disc of
//! directions 2.5 degrees in radius around a known direction), rendered by ray casting here
//! (the table's texture, the box, and per pixel the fraction of the light the box blocks) —
//! an independent truth for the shadow's place, softness and darkness.

use glam::{DVec3, Mat4, Vec3};
use pa_camera::{camera_from_world_look_at, CameraModel};
use pa_diminish::shadow::{cast_shadow, lift_shadow};
use pa_diminish::{dilate, psnr_rgb, DilateShape, ImageRgba8, Mask};

use super::*;

const W: u32 = 320;
const H: u32 = 240;
/// Half extents of the box (x, y) and its height (metres): it stands on z = 0, up is -Z.
const HALF: f32 = 0.02;
const TALL: f32 = 0.07;
/// Shadowed / lit per channel (ambient over ambient + key).
const RATIO: [f32; 3] = [0.42, 0.47, 0.58];

fn camera() -> (CameraModel, Mat4) {
    let cam = CameraModel::pinhole(
        pa_camera::Intrinsics::from_fov_y(50f64.to_radians(), W, H).expect("camera"),
    );
    let eye = Vec3::new(0.05, 0.32, -0.26);
    let pose =
        camera_from_world_look_at(eye, Vec3::new(-0.02, -0.02, 0.0), -Vec3::Z).expect("look at");
    (cam, pose)
}

fn light() -> Vec3 {
    toward_light(200.0, 40.0)
}

fn box_triangles() -> Vec<[Vec3; 3]> {
    let c = |i: usize| {
        Vec3::new(
            if i & 1 == 0 { -HALF } else { HALF },
            if i & 2 == 0 { -HALF } else { HALF },
            if i & 4 == 0 { 0.0 } else { -TALL },
        )
    };
    let faces = [
        [0, 1, 3, 2],
        [4, 5, 7, 6],
        [0, 1, 5, 4],
        [2, 3, 7, 6],
        [0, 2, 6, 4],
        [1, 3, 7, 5],
    ];
    faces
        .iter()
        .flat_map(|f| [[c(f[0]), c(f[1]), c(f[2])], [c(f[0]), c(f[2]), c(f[3])]])
        .collect()
}

/// Ray - box (slab test): the entry distance, if any, beyond `t_min`.
fn hit_box(o: DVec3, d: DVec3, t_min: f64) -> Option<f64> {
    let lo = DVec3::new(-f64::from(HALF), -f64::from(HALF), -f64::from(TALL));
    let hi = DVec3::new(f64::from(HALF), f64::from(HALF), 0.0);
    let (mut t0, mut t1) = (t_min, f64::INFINITY);
    for k in 0..3 {
        let (o, d, lo, hi) = (o[k], d[k], lo[k], hi[k]);
        if d.abs() < 1e-12 {
            if o < lo || o > hi {
                return None;
            }
            continue;
        }
        let (a, b) = ((lo - o) / d, (hi - o) / d);
        t0 = t0.max(a.min(b));
        t1 = t1.min(a.max(b));
    }
    (t0 <= t1).then_some(t0)
}

fn wood(x: f64, y: f64) -> [f64; 3] {
    let g = 0.55 + 0.2 * (140.0 * x + 4.0 * (9.0 * y).sin()).sin() + 0.05 * (310.0 * y).sin();
    [g, 0.78 * g, 0.52 * g]
}

/// The frame with and without the shadow (linear-light shading, sRGB out), and the box's
/// pixels as a mask.
fn render() -> (ImageRgba8, ImageRgba8, Mask) {
    render_on(wood)
}

/// [`render`] with the table's albedo at marker point `(x, y)` given by `table`.
fn render_on(table: impl Fn(f64, f64) -> [f64; 3]) -> (ImageRgba8, ImageRgba8, Mask) {
    let (cam, pose) = camera();
    let marker_from_camera = pose.inverse().as_dmat4();
    let origin = marker_from_camera.transform_point3(DVec3::ZERO);
    let l = light().as_dvec3();
    // The light's disc: 32 directions within 2.5 degrees (a ring pattern, deterministic).
    let (u, v) = {
        let u = l.cross(DVec3::Z).normalize();
        (u, l.cross(u))
    };
    let dirs: Vec<DVec3> = (0..32)
        .map(|i| {
            let r = 2.5f64.to_radians() * ((i % 4) as f64 + 0.5) / 4.0;
            let a = i as f64 * 2.399_963;
            (l + r * (a.cos() * u + a.sin() * v)).normalize()
        })
        .collect();
    let enc = |c: f64| pa_raster::srgb::linear_to_srgb(c.clamp(0.0, 1.0) as f32);
    let mut lit = vec![0u8; (W * H * 4) as usize];
    let mut shadowed = lit.clone();
    let mut boxm = vec![0u8; (W * H) as usize];
    for y in 0..H {
        for x in 0..W {
            let i = (y * W + x) as usize;
            let ray = cam.ray_from_pixel(glam::DVec2::new(f64::from(x), f64::from(y)));
            let d = marker_from_camera.transform_vector3(ray).normalize();
            let t_table = -origin.z / d.z;
            let on_box = hit_box(origin, d, 0.0).is_some_and(|t| t < t_table);
            let (a, b) = if on_box {
                boxm[i] = 255;
                ([0.3; 3], [0.3; 3])
            } else {
                let p = origin + d * t_table;
                let c = table(p.x, p.y);
                let blocked = dirs
                    .iter()
                    .filter(|&&dl| hit_box(p, dl, 1e-9).is_some())
                    .count() as f64
                    / dirs.len() as f64;
                let s: [f64; 3] =
                    std::array::from_fn(|k| c[k] * (1.0 - blocked * (1.0 - f64::from(RATIO[k]))));
                (c, s)
            };
            for k in 0..3 {
                lit[i * 4 + k] = enc(a[k]);
                shadowed[i * 4 + k] = enc(b[k]);
            }
            lit[i * 4 + 3] = 255;
            shadowed[i * 4 + 3] = 255;
        }
    }
    (
        ImageRgba8::new(W, H, lit).expect("image"),
        ImageRgba8::new(W, H, shadowed).expect("image"),
        Mask::new(W, H, boxm).expect("mask"),
    )
}

/// The frame as the estimate reads it, without a known print.
fn view<'a>(
    frame: &'a ImageRgba8,
    camera: &'a CameraModel,
    camera_from_marker: Mat4,
    exclude: &'a Mask,
) -> ShadowView<'a> {
    ShadowView {
        frame,
        camera,
        camera_from_marker,
        exclude,
        same_surface: None,
    }
}

/// The mask grown by 2 px (the prop's edge is not table).
fn grown(m: &Mask) -> Mask {
    let mut out = Mask::zeros(W, H).expect("mask");
    dilate(m, 2, DilateShape::Disc, &mut out).expect("dilate");
    out
}

#[test]
fn onto_table_follows_the_light() {
    let l = toward_light(0.0, 45.0);
    // A point 1 m above the origin (z = -1) under a light 45 degrees up toward +X lands 1 m
    // toward -X.
    let s = onto_table(Vec3::new(0.0, 0.0, -1.0), l);
    assert!((s - Vec3::new(-1.0, 0.0, 0.0)).length() < 1e-5, "{s}");
    // Points on the table stay.
    assert_eq!(
        onto_table(Vec3::new(0.3, 0.2, 0.0), l),
        Vec3::new(0.3, 0.2, 0.0)
    );
    assert!(l.z < 0.0 && (l.length() - 1.0).abs() < 1e-6);
}

/// The box's shadow from its geometry covers the rendered umbra and lies within the rendered
/// penumbra: the hard matte agrees with the ray-cast shadow on at least 97 % of the pixels
/// where either is (the rest is the 2.5-degree penumbra).
#[test]
fn shadow_matte_lands_where_the_render_has_it() {
    let (cam, pose) = camera();
    let (lit, shadowed, boxm) = render();
    let m = hard_matte(&box_triangles(), light(), &cam, pose, 0, W, H).expect("matte");
    let (mut agree, mut either) = (0usize, 0usize);
    for y in 0..H {
        for x in 0..W {
            if boxm.get(x, y) {
                continue;
            }
            let (a, b) = (lit.get(x, y).expect("px"), shadowed.get(x, y).expect("px"));
            let dark = b[1] < a[1].saturating_sub(20);
            let geo = m.at(x, y) > 0.5;
            if dark || geo {
                either += 1;
                agree += usize::from(dark == geo);
            }
        }
    }
    let share = agree as f64 / either as f64;
    println!("matte vs render: {agree} / {either} = {share:.3}");
    assert!(either > 1000, "the shadow is in view ({either} px)");
    assert!(share > 0.9, "agreement {share}");
}

/// The light is estimated from the frame alone (the box's geometry and the darkening): within
/// 6 degrees of the truth, and lifting the shadow with the estimate restores the table
/// (PSNR over the shadow region against the unshadowed render above 27 dB, 11 dB better than
/// the shadowed frame).
#[test]
fn estimated_light_lifts_the_box_shadow() {
    let (cam, pose) = camera();
    let (lit, shadowed, boxm) = render();
    let exclude = grown(&boxm);
    let est = estimate_light(&view(&shadowed, &cam, pose, &exclude), &box_triangles())
        .expect("estimate")
        .expect("a light");
    let angle = est.toward_light.angle_between(light()).to_degrees();
    println!("estimated {est:?}: {angle:.1} degrees off");
    assert!(angle < 6.0, "direction {angle} degrees off");
    for (got, want) in est.ratio_rgb.iter().zip(RATIO) {
        assert!((got - want).abs() < 0.08, "{:?}", est.ratio_rgb);
    }
    let matte = soft_matte(&box_triangles(), &est, &cam, pose, W, H)
        .expect("soften")
        .expect("matte");
    let mut lifted = shadowed.clone();
    lift_shadow(&mut lifted, &matte, est.ratio_rgb).expect("lift");
    let region = Mask::from_fn(W, H, |x, y| {
        !exclude.get(x, y)
            && (matte.at(x, y) > 0.01
                || shadowed.get(x, y).map(|p| p[1]) != lit.get(x, y).map(|p| p[1]))
    })
    .expect("mask");
    let before = psnr_rgb(&lit, &shadowed, Some(&region)).expect("psnr");
    let after = psnr_rgb(&lit, &lifted, Some(&region)).expect("psnr");
    println!("shadow region: shadowed {before:.1} dB, lifted {after:.1} dB");
    assert!(after > 27.0, "lifted {after}");
    assert!(after > before + 11.0, "lifted {after} vs shadowed {before}");
}

/// A flat table without any shadow gives no light (nothing is measurably darker).
#[test]
fn no_shadow_no_light() {
    let (cam, pose) = camera();
    let (lit, _, boxm) = render();
    let exclude = grown(&boxm);
    assert_eq!(
        estimate_light(&view(&lit, &cam, pose, &exclude), &box_triangles()).expect("estimate"),
        None
    );
}

/// Casting with the true light darkens the lit frame where the render's shadow is.
#[test]
fn cast_shadow_matches_the_rendered_one() {
    let (cam, pose) = camera();
    let (lit, shadowed, boxm) = render();
    let light = ShadowLight {
        toward_light: light(),
        softness_px: 1.5,
        ratio_rgb: RATIO,
    };
    let matte = soft_matte(&box_triangles(), &light, &cam, pose, W, H)
        .expect("soften")
        .expect("matte");
    let mut cast = lit.clone();
    cast_shadow(&mut cast, &matte, light.ratio_rgb).expect("cast");
    let table = Mask::from_fn(W, H, |x, y| !boxm.get(x, y)).expect("mask");
    let with = psnr_rgb(&shadowed, &cast, Some(&table)).expect("psnr");
    let without = psnr_rgb(&shadowed, &lit, Some(&table)).expect("psnr");
    println!("cast vs rendered shadow: {with:.1} dB (no shadow: {without:.1} dB)");
    assert!(with > 30.0 && with > without + 10.0, "{with} vs {without}");
}

/// Regression (CesiumMan, Blender Cycles set): dark wood and tag print beside the prop
/// explained more darkening along another direction than the real shadow did; the outline
/// vetoed that direction and the estimate gave up, so on 13 of 16 stills no light was known
/// and nothing was lifted or cast. Now the next distinct peak of the coarse scores is tried.
/// Scores here: two smooth peaks, a higher one at (290, 40) degrees that the outline vetoes
/// and the true light's at (200, 40).
#[test]
fn regression_a_vetoed_best_direction_falls_back_to_the_next_peak() {
    let (false_peak, true_peak) = (toward_light(290.0, 40.0), toward_light(200.0, 40.0));
    let score_of = |az: f32, el: f32| -> Result<Option<f32>, ()> {
        let d = toward_light(az, el);
        let bump = |p: Vec3, h: f32| h * (-(d.angle_between(p).to_degrees() / 20.0).powi(2)).exp();
        Ok(Some(bump(false_peak, 2.0) + bump(true_peak, 1.0)))
    };
    let light_of = |az: f32, el: f32| ShadowLight {
        toward_light: toward_light(az, el),
        softness_px: 1.0,
        ratio_rgb: [0.5; 3],
    };
    let calls = std::cell::Cell::new(0);
    let vetoing = |az: f32, el: f32| -> Result<Option<ShadowLight>, ()> {
        calls.set(calls.get() + 1);
        let vetoed = toward_light(az, el).angle_between(false_peak).to_degrees() < 10.0;
        Ok((!vetoed).then(|| light_of(az, el)))
    };
    let no_edge = |_: f32, _: f32| Ok::<Option<f32>, ()>(None);
    let found = search_light(score_of, no_edge, vetoing)
        .expect("search")
        .expect("a light");
    let off = found.toward_light.angle_between(true_peak).to_degrees();
    println!(
        "found {:?}, {off:.2} degrees off, {} candidates",
        found.toward_light,
        calls.get()
    );
    assert!(off < 2.0, "{off} degrees off the true light");
    assert_eq!(calls.get(), 2, "the vetoed peak, then the true one");
    // Without a veto the higher peak wins (the fallback is what finds the true light).
    let first = search_light(score_of, no_edge, |az, el| {
        Ok::<_, ()>(Some(light_of(az, el)))
    })
    .expect("search")
    .expect("a light");
    assert!(first.toward_light.angle_between(false_peak).to_degrees() < 2.0);
    // Everything vetoed: no light, after at most MAX_LIGHT_CANDIDATES refinements.
    calls.set(0);
    let none = search_light(score_of, no_edge, |_, _| {
        calls.set(calls.get() + 1);
        Ok::<Option<ShadowLight>, ()>(None)
    })
    .expect("search");
    assert_eq!(none, None);
    assert_eq!(calls.get(), MAX_LIGHT_CANDIDATES);
}

/// A printed sheet: black squares of 16 mm every 28 mm on white paper (a board of small
/// tags at its crudest).
fn print(x: f64, y: f64) -> [f64; 3] {
    let inside = |v: f64| (v / 0.028 + 0.1).rem_euclid(1.0) < 16.0 / 28.0;
    if inside(x) && inside(y) {
        [0.04; 3]
    } else {
        [0.85, 0.84, 0.8]
    }
}

/// Whether pixels `a` and `b` show the same square of [`print`] (each away from a square's
/// edge: its 3x3 neighbours on the same square), as the board's known print says.
fn same_square(cam: &CameraModel, pose: Mat4, a: [u32; 2], b: [u32; 2]) -> bool {
    let marker_from_camera = pose.inverse().as_dmat4();
    let origin = marker_from_camera.transform_point3(DVec3::ZERO);
    let square = |[x, y]: [u32; 2]| -> Option<i64> {
        let mut seen = None;
        for (dx, dy) in (-1..=1).flat_map(|i| (-1..=1).map(move |j| (i, j))) {
            let ray = cam.ray_from_pixel(glam::DVec2::new(
                f64::from(x) + f64::from(dx),
                f64::from(y) + f64::from(dy),
            ));
            let d = marker_from_camera.transform_vector3(ray);
            let p = origin + d * (-origin.z / d.z);
            let black = print(p.x, p.y)[0] < 0.5;
            if seen.is_some_and(|s| s != black) {
                return None;
            }
            seen = Some(black);
        }
        seen.map(i64::from)
    };
    matches!((square(a), square(b)), (Some(p), Some(q)) if p == q)
}

/// Regression (the generated `shadows` set): the key prop's shadow fell across a tag's
/// print, and the light was never found. The softness was fitted on the medians of the
/// shadow region against its ring, which black print in both made equal (ratio 1, the
/// smallest softness), and the outline was then read too close to the edge: every candidate
/// was vetoed. Now the softness and the darkening are fitted on the outline's pairs at
/// several distances, and with the print known, pairs across black and white are left out.
/// On a checker print the light is found within 6 degrees with its darkening, and the
/// shadow's darkening is measured on the frame within 0.08.
#[test]
fn regression_a_shadow_across_print_is_found_with_the_print_known() {
    let (cam, pose) = camera();
    let (_, shadowed, boxm) = render_on(print);
    let exclude = grown(&boxm);
    let same = |a: [u32; 2], b: [u32; 2]| same_square(&cam, pose, a, b);
    let known = ShadowView {
        same_surface: Some(&same),
        ..view(&shadowed, &cam, pose, &exclude)
    };
    let est = estimate_light(&known, &box_triangles())
        .expect("estimate")
        .expect("a light");
    let angle = est.toward_light.angle_between(light()).to_degrees();
    println!("print known: {est:?}, {angle:.1} degrees off");
    assert!(angle < 6.0, "direction {angle} degrees off");
    let y = |r: [f32; 3]| 0.2126 * r[0] + 0.7152 * r[1] + 0.0722 * r[2];
    assert!(
        (y(est.ratio_rgb) - y(RATIO)).abs() < 0.08,
        "{:?}",
        est.ratio_rgb
    );
    let truth = ShadowLight {
        toward_light: light(),
        ..est
    };
    let measured = measure_outline(&known, &box_triangles(), &truth)
        .expect("measure")
        .expect("the outline in view");
    println!("measured on the frame: {:?}", measured.rgb);
    assert!((measured.luminance() - y(RATIO)).abs() < 0.08);
    let unknown =
        estimate_light(&view(&shadowed, &cam, pose, &exclude), &box_triangles()).expect("estimate");
    println!(
        "print not known: {unknown:?}, {:?} degrees off",
        unknown.map(|l| l.toward_light.angle_between(light()).to_degrees())
    );
}

/// Regression (`--scene hard`: cloth, a second light, a steep camera): both peaks of the
/// region score lay 15-20 degrees from the key light and were vetoed, and the light was never
/// found, though the true direction's outline is the sharpest (edge contrast 0.42 against
/// 0.24-0.32 at the vetoed ones). Now, after four region peaks, the peak of the outline's
/// sharpness is tried, among directions whose region is measurably darker: a sharp outline
/// where the region is not darker (grain, print) is never a candidate.
#[test]
fn regression_an_outline_peak_is_tried_after_the_vetoed_region_peaks() {
    let truth = toward_light(130.0, 50.0);
    let region_peaks = [toward_light(0.0, 70.0), toward_light(150.0, 50.0)];
    let grain = toward_light(240.0, 60.0);
    let bump = |d: Vec3, p: Vec3, w: f32| (-(d.angle_between(p).to_degrees() / w).powi(2)).exp();
    // The region score: two peaks, none at the light; nothing measurable around the grain.
    let score_of = |az: f32, el: f32| -> Result<Option<f32>, ()> {
        let d = toward_light(az, el);
        if d.angle_between(grain).to_degrees() < 30.0 {
            return Ok(None);
        }
        Ok(Some(
            2.0 * bump(d, region_peaks[0], 15.0) + 1.5 * bump(d, region_peaks[1], 15.0) + 0.1,
        ))
    };
    // The outline: sharpest at the grain, then at the light.
    let edge_of = |az: f32, el: f32| -> Result<Option<f32>, ()> {
        let d = toward_light(az, el);
        Ok(Some(bump(d, grain, 10.0) + 0.5 * bump(d, truth, 10.0)))
    };
    let tried = std::cell::RefCell::new(Vec::new());
    let light_at = |az: f32, el: f32| -> Result<Option<ShadowLight>, ()> {
        let d = toward_light(az, el);
        tried.borrow_mut().push(d);
        Ok(
            (d.angle_between(truth).to_degrees() < 10.0).then_some(ShadowLight {
                toward_light: d,
                softness_px: 1.0,
                ratio_rgb: [0.5; 3],
            }),
        )
    };
    let found = search_light(score_of, edge_of, light_at)
        .expect("search")
        .expect("a light");
    let tried = tried.into_inner();
    println!(
        "tried {:?}",
        tried
            .iter()
            .map(|d| d.angle_between(truth).to_degrees())
            .collect::<Vec<_>>()
    );
    assert_eq!(tried.len(), 5, "four region peaks, then the outline's");
    assert!(found.toward_light.angle_between(truth).to_degrees() < 10.0);
    assert!(
        tried
            .iter()
            .all(|d| d.angle_between(grain).to_degrees() > 30.0),
        "the grain's sharp outline is never tried"
    );
}
