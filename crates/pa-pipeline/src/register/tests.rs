use super::edges::distance_transform;
use super::*;
use glam::Vec3;
use pa_camera::camera_from_world_look_at;
use pa_render::Renderer;
use pa_scene::{Scene, SceneSpec};

#[test]
fn distance_transform_is_exact() {
    let (w, h) = (23, 17);
    let mut seeds = vec![false; w * h];
    for (i, s) in seeds.iter_mut().enumerate() {
        *s = (i * 7919 + 13) % 37 == 0;
    }
    let d = distance_transform(&seeds, w, h);
    for y in 0..h {
        for x in 0..w {
            let mut best = f64::INFINITY;
            for (j, _) in seeds.iter().enumerate().filter(|(_, s)| **s) {
                let (sx, sy) = ((j % w) as f64, (j / w) as f64);
                best = best.min(((sx - x as f64).powi(2) + (sy - y as f64).powi(2)).sqrt());
            }
            assert!((d[y * w + x] as f64 - best).abs() < 1e-4, "{x},{y}");
        }
    }
}

#[test]
fn eigen_and_cholesky_solve_known_systems() {
    let mut a = [[0.0; 5]; 5];
    // diag(1, 4, 9) rotated by 30 degrees in the (0, 1) plane.
    let (c, s) = (30f64.to_radians().cos(), 30f64.to_radians().sin());
    a[0][0] = c * c + 4.0 * s * s;
    a[1][1] = s * s + 4.0 * c * c;
    a[0][1] = (4.0 - 1.0) * c * s;
    a[1][0] = a[0][1];
    a[2][2] = 9.0;
    let (values, vectors) = jacobi_eigen(&a, 3);
    let mut v: Vec<f64> = values[..3].to_vec();
    v.sort_by(f64::total_cmp);
    for (got, want) in v.iter().zip([1.0, 4.0, 9.0]) {
        assert!((got - want).abs() < 1e-9, "{values:?}");
    }
    let k = (0..3).find(|&k| (values[k] - 1.0).abs() < 1e-9).expect("1");
    assert!((vectors[k][0].abs() - c).abs() < 1e-9 && (vectors[k][1].abs() - s).abs() < 1e-9);
    let x = solve::solve_spd(&a, &[1.0, 2.0, 3.0, 0.0, 0.0], 3).expect("spd");
    for (i, row) in a.iter().enumerate().take(3) {
        let r: f64 = (0..3).map(|j| row[j] * x[j]).sum();
        assert!((r - [1.0, 2.0, 3.0][i]).abs() < 1e-12);
    }
    // Translation block (x, y, lift) without yaw: the weakest direction is eigenvalue 1.
    let mut h = [[0.0; 5]; 5];
    for i in 0..3 {
        for j in 0..3 {
            h[i][j] = a[i][j];
        }
    }
    h[3][3] = 16.0;
    let k = conditioning(&h, 4, 4);
    assert!((k.translation_weakest - 0.5).abs() < 1e-9, "{k:?}");
    assert!((k.translation_strongest - 1.5).abs() < 1e-9, "{k:?}");
    assert!((k.yaw_px_per_deg - 2.0).abs() < 1e-9, "{k:?}");
    assert!(k.weakest_direction.starts_with("x 75%"), "{k:?}");
    // Marginalising a correlated parameter removes what it explains.
    h[0][3] = 2.0;
    h[3][0] = 2.0;
    let cond = conditioning(&h, 4, 1);
    // yaw: 16 - 2 * (A^-1)_00 * 2, with (A^-1)_00 = c^2 / 1 + s^2 / 4.
    let want = (16.0 - 4.0 * (c * c + s * s / 4.0)).sqrt();
    assert!((cond.yaw_px_per_deg - want).abs() < 1e-9, "{cond:?} {want}");
}

#[test]
fn placement_params_match_the_shot_placement() {
    let p = Placement {
        translation_m: [0.003, -0.004, -0.0009],
        upright: true,
        yaw_deg: 25.0,
        scale: 1.0,
    };
    let q = PlacementParams::from_placement(&p);
    let a = p.marker_from_prop();
    let b = q.marker_from_prop_f32();
    assert!(a.abs_diff_eq(b, 1e-6), "{a} {b}");
    assert_eq!(q.to_placement(), p);
    // The shot's scale is the same transform's.
    let scaled = Placement { scale: 0.75, ..p };
    let qs = PlacementParams::from_placement(&scaled);
    let (a, b) = (scaled.marker_from_prop(), qs.marker_from_prop_f32());
    assert!(a.abs_diff_eq(b, 1e-6), "{a} {b}");
    assert_eq!(qs.to_placement(), scaled);
    let moved = q.with_delta(&[1.0, 2.0, 3.0, 4.0, 5.0]);
    let d = moved.change_from(&q);
    for (got, want) in d.iter().zip([1.0, 2.0, 3.0, 4.0, 5.0]) {
        assert!((got - want).abs() < 1e-9, "{d:?}");
    }
}

/// The built-in set at 640x360, views around the prop at the true placement.
struct Set {
    renderer: Renderer,
    scene: Scene,
}

fn set() -> Set {
    let mut renderer = Renderer::new().expect("renderer");
    let spec = SceneSpec {
        width: 640,
        height: 360,
        frames: 2,
        ..Default::default()
    };
    let scene = Scene::new(spec, &mut renderer).expect("scene");
    Set { renderer, scene }
}

fn view_pose(i: usize, n: usize, spread_deg: f32) -> Mat4 {
    let u = if n > 1 {
        i as f32 / (n - 1) as f32
    } else {
        0.5
    };
    let az = (-spread_deg / 2.0 + spread_deg * u).to_radians();
    let el = (30.0f32 + if i.is_multiple_of(2) { -5.0 } else { 5.0 }).to_radians();
    let d = 0.55;
    let eye = Vec3::new(
        d * el.cos() * az.sin(),
        d * el.cos() * az.cos(),
        -d * el.sin(),
    );
    camera_from_world_look_at(eye, Vec3::new(0.0, 0.0, -0.08), Vec3::NEG_Z).expect("view")
}

/// `n` tracked views spread over `spread_deg` of azimuth (with the prop, or without it).
fn views(set: &mut Set, n: usize, spread_deg: f32, with_prop: bool) -> Vec<RegisterView> {
    let camera = CameraModel::pinhole(set.scene.intrinsics);
    let mut tracker = track::ViewTracker::new(
        camera,
        pa_track::TrackTarget::Board(set.scene.board.clone()),
    )
    .expect("tracker");
    let mut out = Vec::new();
    for i in 0..n {
        let pose = view_pose(i, n, spread_deg);
        let f = set
            .scene
            .render_view(&mut set.renderer, pose, with_prop.then_some(0.0))
            .expect("render");
        let v = tracker
            .view(format!("view{i}"), f.rgba8, f.width, f.height)
            .expect("track")
            .expect("the board is tracked");
        // The tracked pose is the true one (within the tracker's accuracy).
        let err = (v.camera_from_marker.w_axis - pose.w_axis).length();
        assert!(err < 0.003, "view {i}: tracked {err} m from the truth");
        out.push(v);
    }
    out
}

fn truth() -> PlacementParams {
    PlacementParams {
        translation_m: [0.0; 3],
        yaw_deg: 0.0,
        scale: 1.0,
        upright: true,
    }
}

/// Recovery on 6 views at 640x360 from starts 8-10 mm and 8-10 degrees off the truth
/// (`pa_scene`'s `marker_from_prop`). Tolerances at this size (a pixel is about 1.3 mm at
/// the prop): 0.5 mm on the table, 0.5 mm in lift, 1.5 degrees in yaw (the bust is nearly a
/// surface of revolution: only the nose, ears and chin turn its outline).
#[test]
fn recovers_the_true_placement_from_a_perturbed_start() {
    let mut set = set();
    let vs = views(&mut set, 6, 80.0, true);
    let model = &set.scene.model;
    let key = pa_model::anim::sample(model, 0, 0.0);
    for delta in [[8.0, -6.0, 2.0, 9.0, 0.0], [-7.0, -5.0, -2.5, -8.0, 0.0]] {
        let start = truth().with_delta(&delta);
        let r = register(model, &key, start, &vs, &RegisterSettings::default()).expect("register");
        let d = r.placement.change_from(&truth());
        assert!((d[0] * d[0] + d[1] * d[1]).sqrt() < 0.5, "{d:?}");
        assert!(d[2].abs() < 0.5, "{d:?}");
        assert!(d[3].abs() < 1.5, "{d:?}");
        assert_eq!(r.views.len(), 6);
        for v in &r.views {
            assert!(
                v.edge_agreement > 0.6 && v.edge_agreement > v.start_agreement,
                "{v:?}"
            );
        }
        assert!(r.residual_px < 1.0, "{}", r.residual_px);
        assert!(r.spread_deg > 60.0, "{}", r.spread_deg);
    }
}

/// With `refine_scale`, a model 2.5% too large is brought back to its true size.
#[test]
fn refines_the_scale_when_asked() {
    let mut set = set();
    let vs = views(&mut set, 6, 80.0, true);
    let model = &set.scene.model;
    let key = pa_model::anim::sample(model, 0, 0.0);
    let start = truth().with_delta(&[4.0, -3.0, 1.0, 4.0, 2.5]);
    let settings = RegisterSettings {
        refine_scale: true,
        ..Default::default()
    };
    let r = register(model, &key, start, &vs, &settings).expect("register");
    let d = r.placement.change_from(&truth());
    assert!(d[4].abs() < 0.5, "scale off by {}%: {d:?}", d[4]);
    assert!((d[0] * d[0] + d[1] * d[1]).sqrt() < 0.5, "{d:?}");
    assert!(d[2].abs() < 0.7, "{d:?}");
    let c = &r.conditioning;
    assert!(c.scale_px_per_pct.is_some_and(|s| s > 0.1), "{c:?}");
    // From one direction, size and distance trade off: refused.
    let same = vec![vs[1].clone(), vs[1].clone(), vs[1].clone()];
    let e = register(model, &key, start, &same, &settings).expect_err("one direction");
    assert!(matches!(e, RegisterError::Unconstrained { .. }), "{e}");
}

#[test]
fn refusals_say_why() {
    let mut set = set();
    let vs = views(&mut set, 3, 60.0, true);
    let model = set.scene.model.clone();
    let key = pa_model::anim::sample(&model, 0, 0.0);
    let settings = RegisterSettings::default();
    let start = truth().with_delta(&[3.0, 3.0, 0.0, 3.0, 0.0]);

    // One view.
    let e = register(&model, &key, start, &vs[..1], &settings).expect_err("one view");
    assert!(
        matches!(e, RegisterError::TooFewViews { got: 1, needed: 2 }),
        "{e}"
    );
    assert!(e.to_string().contains("line of sight"), "{e}");

    // The prop placed a metre away is in no view.
    let far = truth().with_delta(&[1000.0, 0.0, 0.0, 0.0, 0.0]);
    let e = register(&model, &key, far, &vs, &settings).expect_err("not visible");
    assert!(
        matches!(
            e,
            RegisterError::PropNotVisible {
                visible: 0,
                views: 3,
                ..
            }
        ),
        "{e}"
    );

    // Frames without the prop: nothing matches its outline.
    let empty = views(&mut set, 3, 60.0, false);
    let e = register(&model, &key, start, &empty, &settings).expect_err("no prop");
    assert!(matches!(e, RegisterError::NoMatch { .. }), "{e}");

    // The same view three times: one direction.
    let same = vec![vs[1].clone(), vs[1].clone(), vs[1].clone()];
    let e = register(&model, &key, start, &same, &settings).expect_err("one direction");
    assert!(
        matches!(e, RegisterError::Unconstrained { spread_deg, .. } if spread_deg < 1.0),
        "{e}"
    );
    assert!(
        e.to_string().contains("add views from other directions"),
        "{e}"
    );

    // The marker tracked in too few frames.
    let e = track::check_tracked(1, 5, 2).expect_err("untracked");
    assert_eq!(
        e.to_string(),
        "the marker was tracked in 1 of 5 frames; registration needs at least 2 tracked frames (show the whole board, in focus)"
    );
    assert!(track::check_tracked(2, 5, 2).is_ok());

    // A frame of the wrong size.
    let mut bad = vs.clone();
    bad[0].rgba8.pop();
    let e = register(&model, &key, start, &bad, &settings).expect_err("bad frame");
    assert!(matches!(e, RegisterError::BadFrame { index: 0, .. }), "{e}");
}

#[test]
fn outline_pixels_surround_the_projected_prop() {
    let mut set = set();
    let vs = views(&mut set, 2, 40.0, true);
    let model = &set.scene.model;
    let key = pa_model::anim::sample(model, 0, 0.0);
    let outline = TwinOutline::new(model, &key).expect("outline");
    let v = &vs[0];
    let px = outline.pixels(&v.camera, v.camera_from_marker, &truth(), v.width, v.height);
    assert!(px.len() > 300, "{}", px.len());
    // The prop's base centre projects inside the outline's box.
    let base = v
        .camera
        .pixel_from_camera(
            v.camera_from_marker
                .as_dmat4()
                .transform_point3(DVec3::ZERO),
        )
        .expect("in front");
    let (x0, x1) = (
        px.iter().map(|p| p.0).min().expect("px"),
        px.iter().map(|p| p.0).max().expect("px"),
    );
    let (y0, y1) = (
        px.iter().map(|p| p.1).min().expect("px"),
        px.iter().map(|p| p.1).max().expect("px"),
    );
    assert!(
        (x0 as f64) < base.x && base.x < x1 as f64,
        "{x0} {x1} {base}"
    );
    assert!(
        (y0 as f64) < base.y && base.y <= y1 as f64 + 2.0,
        "{y0} {y1} {base}"
    );
    // Moved 10 mm along marker +X, the outline moves right in this frontal view.
    let moved = truth().with_delta(&[10.0, 0.0, 0.0, 0.0, 0.0]);
    let px2 = outline.pixels(&v.camera, v.camera_from_marker, &moved, v.width, v.height);
    let mean_x = |p: &[(u32, u32)]| p.iter().map(|q| q.0 as f64).sum::<f64>() / p.len() as f64;
    let dx = mean_x(&px2) - mean_x(&px);
    assert!(dx.abs() > 5.0, "{dx}");
}

const SHOT: &str = r#"# my shot
model = "prop.glb"   # the bust
fps = 24.0

[[key_poses]]
name = "A"
frame = 0

[camera]
fov_y_deg = 45.0

[marker]
[[marker.tags]]
id = 0
center_m = [0.0, 0.0]
size_m = 0.05

# where the prop stands
[placement]
translation_m = [0.0, 0.0, 0.0]  # measured by hand
upright = true
yaw_deg = 0.0 # facing the camera
"#;

#[test]
fn write_keeps_comments_and_backs_up_without_overwriting() {
    let dir = tempfile::tempdir().expect("tmp");
    let path = dir.path().join("shot.toml");
    std::fs::write(&path, SHOT).expect("write");
    let p = PlacementParams {
        translation_m: [0.0031, -0.0042, -0.0009],
        yaw_deg: 25.5,
        scale: 1.02,
        upright: true,
    };
    let backup = write::write_placement(&path, &p, false).expect("written");
    assert_eq!(backup, dir.path().join("shot.toml.bak"));
    assert_eq!(std::fs::read_to_string(&backup).expect("bak"), SHOT);
    let text = std::fs::read_to_string(&path).expect("shot");
    let want = SHOT
        .replace(
            "translation_m = [0.0, 0.0, 0.0]  # measured by hand",
            "translation_m = [0.0031, -0.0042, -0.0009]  # measured by hand",
        )
        .replace("yaw_deg = 0.0 # facing", "yaw_deg = 25.5 # facing");
    assert_eq!(text, want);
    let shot = Shot::load(&path).expect("valid shot");
    assert_eq!(shot.placement.translation_m, [0.0031, -0.0042, -0.0009]);
    assert_eq!(shot.placement.yaw_deg, 25.5);

    // A second write keeps the first backup and numbers the next one; scale is added.
    let backup2 = write::write_placement(&path, &p, true).expect("written again");
    assert_eq!(backup2, dir.path().join("shot.toml.bak.1"));
    assert_eq!(std::fs::read_to_string(&backup).expect("bak"), SHOT);
    assert_eq!(std::fs::read_to_string(&backup2).expect("bak1"), want);
    let text = std::fs::read_to_string(&path).expect("shot");
    assert!(
        text.contains("yaw_deg = 25.5 # facing the camera\nscale = 1.02\n"),
        "{text}"
    );

    assert_eq!(write::placement_scale(&text), Some(1.02));
    assert_eq!(write::placement_scale(SHOT), None);

    // A shot without [placement] gets one; a broken file is refused and left alone.
    let no_placement = &SHOT[..SHOT.find("# where").expect("placement")];
    let edited = write::placement_edited(no_placement, &path, &p, false).expect("edited");
    assert!(edited.starts_with(no_placement), "{edited}");
    assert!(
        edited
            .contains("[placement]\ntranslation_m = [0.0031, -0.0042, -0.0009]\nyaw_deg = 25.5\n"),
        "{edited}"
    );
    let broken = dir.path().join("broken.toml");
    std::fs::write(&broken, "model = [").expect("write");
    let e = write::write_placement(&broken, &p, false).expect_err("broken");
    assert!(
        e.to_string()
            .contains("broken.toml: cannot update [placement]"),
        "{e}"
    );
    assert!(!dir.path().join("broken.toml.bak").exists());
    assert_eq!(std::fs::read_to_string(&broken).expect("same"), "model = [");
}

use crate::shot::Shot;
