//! N props on the set (`SceneSpec::props`): every copy stands at its own spot
//! (`PROP_SPOTS`), the prop masks (the measurement's region) cover all of them, the copies
//! are spread (not stacked: the union covers many times one prop's pixels), the first copy
//! is the single prop, and a count the set has no spots for is a typed error.

use glam::{Mat4, Vec3};
use pa_render::Renderer;
use pa_scene::scene::{CameraPath, PROP_SPOTS};
use pa_scene::{Scene, SceneError, SceneSpec};

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

fn spec(props: u32) -> SceneSpec {
    SceneSpec {
        width: W,
        height: H,
        frames: 4,
        camera_path: CameraPath::Static,
        props,
        ..SceneSpec::default()
    }
}

/// Pixel of marker point `p` (None outside the frame).
fn pixel(scene: &Scene, camera_from_marker: Mat4, p: Vec3) -> Option<usize> {
    let c = camera_from_marker.transform_point3(p).as_dvec3();
    let k = scene.intrinsics;
    let u = (k.fx * c.x / c.z + k.cx).floor();
    let v = (k.fy * c.y / c.z + k.cy).floor();
    ((0.0..W as f64).contains(&u) && (0.0..H as f64).contains(&v))
        .then(|| v as usize * W as usize + u as usize)
}

#[test]
fn every_copy_stands_at_its_spot_and_the_masks_cover_them_all() {
    let Some(mut renderer) = renderer() else {
        return;
    };
    let one = Scene::new(spec(1), &mut renderer).expect("one prop");
    let all = Scene::new(spec(PROP_SPOTS.len() as u32), &mut renderer).expect("16 props");
    let view = all.camera_from_marker(0);
    assert_eq!(view, one.camera_from_marker(0));

    let placements = all.marker_from_props();
    assert_eq!(placements.len(), PROP_SPOTS.len());
    assert_eq!(placements[0], one.marker_from_prop());
    assert_eq!(one.marker_from_props(), vec![one.marker_from_prop()]);

    let mask_one = one.prop_mask(&mut renderer, view, 0.0).expect("mask");
    let mask_all = all.prop_mask(&mut renderer, view, 0.0).expect("mask");
    for (k, (m, [x, y])) in placements.iter().zip(PROP_SPOTS).enumerate() {
        // The copy's axis 0.1 m above the table (-Z is up) is its spot's point.
        let axis = m.transform_point3(Vec3::new(0.0, 0.1, 0.0));
        assert!(
            (axis - Vec3::new(x, y, -0.1)).length() < 1e-6,
            "spot {k}: {axis}"
        );
        let p = pixel(&all, view, axis).unwrap_or_else(|| panic!("spot {k} out of view"));
        assert!(mask_all[p], "spot {k}: its axis pixel is not a prop pixel");
    }
    let area = |m: &[bool]| m.iter().filter(|&&c| c).count();
    assert!(mask_one
        .iter()
        .zip(&mask_all)
        .all(|(&one, &all)| !one || all));
    // Spread, not stacked: 16 copies at one place would cover exactly one prop's pixels.
    // Behind the board they are farther (smaller) and partly hidden by the nearer ones, so
    // not 16 times (5.0 times here).
    assert!(
        area(&mask_all) > 4 * area(&mask_one),
        "{} pixels for 16 props, {} for one",
        area(&mask_all),
        area(&mask_one)
    );

    // The input shows them: at every spot's axis pixel the input differs from the clean
    // plate (the set without props, here from the same view).
    let (plate, _) = all.clean_plate(&mut renderer).expect("plate");
    let f = all.frame(&mut renderer, 0).expect("frame");
    let mut differs = 0;
    for (m, _) in placements.iter().zip(PROP_SPOTS) {
        let axis = m.transform_point3(Vec3::new(0.0, 0.1, 0.0));
        let p = pixel(&all, view, axis).expect("in view");
        let d: i32 = (0..3)
            .map(|c| (f.input.rgba8[p * 4 + c] as i32 - plate.rgba8[p * 4 + c] as i32).abs())
            .sum();
        if d > 12 {
            differs += 1;
        }
    }
    assert_eq!(differs, PROP_SPOTS.len());
}

#[test]
fn a_prop_count_without_spots_is_a_typed_error() {
    let Some(mut renderer) = renderer() else {
        return;
    };
    for props in [0, PROP_SPOTS.len() as u32 + 1] {
        match Scene::new(spec(props), &mut renderer) {
            Err(SceneError::PropCount { props: p, max }) => {
                assert_eq!((p, max), (props, PROP_SPOTS.len()));
            }
            Err(e) => panic!("{props} props: {e}"),
            Ok(_) => panic!("{props} props accepted"),
        }
    }
    let e = Scene::new(spec(0), &mut renderer).err().expect("error");
    assert_eq!(e.to_string(), "a scene holds 1 to 16 props, not 0");
}
