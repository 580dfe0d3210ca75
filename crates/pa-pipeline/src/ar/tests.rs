//! Unit tests of the frame pipeline's GPU-free parts on small analytic inputs. The pipeline
//! itself ([`ArPipeline::new`]) needs a wgpu `Renderer` (it uploads the twin), so the whole
//! frame, on either render path, is tested in `pa-scene/tests` where a renderer is made.

use glam::{DVec3, Mat4, Vec3};
use pa_camera::{CameraModel, Intrinsics};
use pa_diminish::{Mask, Rect};

use super::fill::{clear_rect, hide_twin_interior};
use super::texture::mask_from_vis;
use super::*;

#[test]
fn render_path_names_round_trip() {
    for path in [RenderPath::Gpu, RenderPath::Cpu] {
        assert_eq!(path.name().parse::<RenderPath>(), Ok(path));
    }
    let e = "GPU"
        .parse::<RenderPath>()
        .expect_err("names are lower case");
    assert_eq!(e.given, "GPU");
    assert_eq!(e.to_string(), "render path \"GPU\": expected gpu or cpu");
}

#[test]
fn settings_presets() {
    let ours = ArSettings::ours();
    assert_eq!(ours.texturing, Texturing::Live { visibility: true });
    assert_eq!(ours.fill, Fill::Rays);
    assert_eq!((ours.dilate_px, ours.anti_alias), (4, true));
    let paper = ArSettings::paper();
    assert_eq!(paper.texturing, Texturing::Live { visibility: false });
    assert_eq!(paper.fill, Fill::PaperRectangle);
    assert_eq!((paper.dilate_px, paper.anti_alias), (0, false));
}

#[test]
fn stage_total_is_the_sum_of_the_stages() {
    let t = StageTimings {
        track_ms: 1.0,
        animate_ms: 2.0,
        texture_ms: 4.0,
        diminish_ms: 8.0,
        composite_ms: 16.0,
    };
    assert_eq!(t.total_ms(), 31.0);
    assert_eq!(StageTimings::default().total_ms(), 0.0);
}

#[test]
fn grey_is_rec601_luma_rounded() {
    // 3 x 40 pixels: more than one band of 16 rows (the rows run in parallel).
    let (w, h) = (3u32, 40u32);
    let rgba: Vec<u8> = (0..w * h)
        .flat_map(|i| {
            let v = (i * 37 % 256) as u8;
            [v, 255 - v, v / 2, 7]
        })
        .collect();
    let g = gray_from_rgba(&rgba, w, h).expect("grey");
    assert_eq!((g.width, g.height), (w, h));
    for (i, p) in rgba.chunks_exact(4).enumerate() {
        let want = (77 * p[0] as u32 + 150 * p[1] as u32 + 29 * p[2] as u32 + 128) >> 8;
        assert_eq!(g.data[i] as u32, want, "pixel {i}");
    }
    let one = |c: [u8; 4]| gray_from_rgba(&c, 1, 1).expect("grey").data[0];
    assert_eq!(one([255, 255, 255, 0]), 255);
    assert_eq!(one([255, 0, 0, 255]), 77);
    assert_eq!(one([0, 255, 0, 255]), 149);
    assert_eq!(one([0, 0, 255, 255]), 29);
    assert_eq!(one([0, 0, 0, 255]), 0);
}

#[test]
fn grey_of_a_wrong_buffer_is_a_typed_error() {
    for (len, w, h) in [(11usize, 2u32, 2u32), (0, 0, 0), (4, 1, 0)] {
        let e = gray_from_rgba(&vec![0; len], w, h).expect_err("bad size");
        match e {
            ArError::BadFrame {
                index,
                width,
                height,
                expected,
                got,
            } => {
                assert_eq!((index, width, height), (0, w, h));
                assert_eq!((expected, got), (w as usize * h as usize * 4, len));
            }
            other => panic!("{other}"),
        }
    }
}

#[test]
fn colour_gain_is_the_linear_ratio_over_the_mask_clamped() {
    let lin = |v: u8| pa_raster::srgb::srgb_to_linear(v) as f64;
    // Two masked pixels and one outside the mask (which would change every ratio).
    let frame = [200, 100, 255, 255, 180, 90, 255, 255, 0, 0, 0, 255];
    let model = [100, 140, 10, 255, 120, 150, 20, 255, 255, 255, 255, 255];
    let mask = [true, true, false];
    let g = colour_gain(&frame, &model, &mask);
    let ratio = |c: usize| {
        ((lin(frame[c]) + lin(frame[4 + c])) / (lin(model[c]) + lin(model[4 + c]))) as f32
    };
    assert_eq!(g[0], ratio(0));
    assert_eq!(g[1], ratio(1));
    assert_eq!(g[2], 4.0, "clamped above");
    assert!(g[0] > 1.0 && g[1] < 1.0);
    // Clamped below; a black model gives no ratio (gain 1); an empty mask gives 1.
    let g = colour_gain(&[1, 0, 9, 0], &[255, 0, 9, 0], &[true]);
    assert_eq!(g, [0.25, 1.0, 1.0]);
    assert_eq!(colour_gain(&frame, &model, &[false; 3]), [1.0; 3]);
    assert_eq!(colour_gain(&frame, &frame, &mask), [1.0; 3]);
}

fn test_camera() -> CameraModel {
    CameraModel::pinhole(Intrinsics::from_fov_y(1.0, 320, 240).expect("intrinsics"))
}

fn look_at(eye: Vec3) -> Mat4 {
    pa_camera::camera_from_world_look_at(eye, Vec3::ZERO, Vec3::Y).expect("pose")
}

#[test]
fn plane_homography_maps_marker_points_between_views() {
    let camera = test_camera();
    let plate = look_at(Vec3::new(0.1, -0.4, 0.5));
    let current = look_at(Vec3::new(-0.3, -0.2, 0.6));
    let h = plane_homography(&camera, current, plate);
    let pixel = |pose: Mat4, p: Vec3| {
        camera
            .pixel_from_camera(pose.transform_point3(p).as_dvec3())
            .expect("in front")
    };
    for p in [
        Vec3::ZERO,
        Vec3::new(0.05, -0.03, 0.0),
        Vec3::new(-0.08, 0.06, 0.0),
    ] {
        let (from, to) = (pixel(plate, p), pixel(current, p));
        let m = h * DVec3::new(from.x, from.y, 1.0);
        let got = m.truncate() / m.z;
        assert!((got - to).length() < 1e-3, "{p}: {got} vs {to}");
    }
    // The same view: the identity.
    let same = plane_homography(&camera, current, current);
    let d = same - glam::DMat3::IDENTITY;
    assert!(d.to_cols_array().iter().all(|v| v.abs() < 1e-6), "{same}");
}

#[test]
fn mask_from_bools_sets_255() {
    let m = mask_from_bools(3, 1, &[true, false, true]).expect("mask");
    assert_eq!(m.as_slice(), &[255, 0, 255]);
    assert!(mask_from_bools(2, 2, &[true]).is_err());
}

#[test]
fn clear_rect_clears_only_the_rectangle() {
    let mut m = Mask::new(5, 4, vec![255; 20]).expect("mask");
    clear_rect(&mut m, Rect::from_inclusive(1, 1, 3, 2));
    for y in 0..4 {
        for x in 0..5 {
            let inside = (1..=3).contains(&x) && (1..=2).contains(&y);
            assert_eq!(
                m.as_slice()[y * 5 + x],
                if inside { 0 } else { 255 },
                "({x}, {y})"
            );
        }
    }
}

/// Runs `hide_twin_interior` on a fill mask of `fill_data` and checks it against the
/// definition pixel by pixel: a set fill pixel is hidden exactly when every pixel within
/// Chebyshev distance `r` lies in the image and in the twin. Returns the pixels hidden.
fn hides_exactly_the_interior(
    twin: &[bool],
    (w, h): (usize, usize),
    bbox: (usize, usize, usize, usize),
    fill_data: &[u8],
    r: usize,
) -> usize {
    let mut fill = Mask::new(w as u32, h as u32, fill_data.to_vec()).expect("mask");
    hide_twin_interior(&mut fill, twin, bbox, r);
    let ri = r as i64;
    let mut hidden = 0;
    for y in 0..h {
        for x in 0..w {
            let all_twin = (-ri..=ri).all(|dy| {
                (-ri..=ri).all(|dx| {
                    let (xx, yy) = (x as i64 + dx, y as i64 + dy);
                    (0..w as i64).contains(&xx)
                        && (0..h as i64).contains(&yy)
                        && twin[yy as usize * w + xx as usize]
                })
            });
            let i = y * w + x;
            let want = if fill_data[i] != 0 && all_twin {
                Mask::HIDDEN
            } else {
                fill_data[i]
            };
            assert_eq!(fill.as_slice()[i], want, "r {r}: ({x}, {y})");
            hidden += usize::from(want == Mask::HIDDEN);
        }
    }
    hidden
}

#[test]
fn twin_interior_is_hidden_where_the_whole_window_is_twin() {
    // An irregular twin (a disc with a notch and a hole) against the definition, pixel by
    // pixel: a set fill pixel is hidden exactly when every pixel within Chebyshev distance r
    // lies in the image and in the twin.
    let (w, h) = (24usize, 20usize);
    let twin: Vec<bool> = (0..w * h)
        .map(|i| {
            let (x, y) = ((i % w) as i32, (i / w) as i32);
            let d2 = (x - 11).pow(2) + (y - 9).pow(2);
            (d2 <= 64 && !(x > 14 && (8..=9).contains(&y)) && (x, y) != (9, 8)) || (x == 0 && y < 6)
        })
        .collect();
    let bbox = crate::composite::bounding_box(&twin, w, h).expect("twin");
    for r in [1usize, 2, 4] {
        // Fill set on the left two thirds only: unset pixels are never hidden.
        let fill_data: Vec<u8> = (0..w * h)
            .map(|i| if i % w < 16 { Mask::SET } else { 0 })
            .collect();
        let hidden = hides_exactly_the_interior(&twin, (w, h), bbox, &fill_data, r);
        assert!(r == 4 || hidden > 0, "r {r}: the test must hide something");
    }
}

/// The same definition on a twin taller than the vertical pass's bands of 32 rows (a wavy
/// blob with holes, touching the image's edge), for several radii.
#[test]
fn twin_interior_hiding_matches_the_definition_across_bands() {
    let (w, h) = (150usize, 110usize);
    let twin: Vec<bool> = (0..w * h)
        .map(|i| {
            let (x, y) = ((i % w) as f64, (i / w) as f64);
            let r = 45.0 + 8.0 * (0.3 * y).sin() + 5.0 * (0.17 * x).cos();
            let inside = (x - 70.0).powi(2) / 1.6 + (y - 50.0).powi(2) <= r * r;
            let hole = (x - 60.0).powi(2) + (y - 40.0).powi(2) < 30.0 || (i * 7919) % 1499 == 0;
            inside && !hole
        })
        .collect();
    let bbox = crate::composite::bounding_box(&twin, w, h).expect("twin");
    assert!(bbox.3 - bbox.1 > 64, "at least three bands");
    for r in [1usize, 3, 4, 6] {
        let fill_data: Vec<u8> = (0..w * h)
            .map(|i| if (i / w) % 9 == 4 { 0 } else { Mask::SET })
            .collect();
        let hidden = hides_exactly_the_interior(&twin, (w, h), bbox, &fill_data, r);
        assert!(hidden > 300, "r {r}: the test must hide much ({hidden})");
    }
}

#[test]
fn mask_from_vis_reads_only_the_dirty_rectangle() {
    let mut v = pa_raster::VisBuffer::new(6, 5);
    // A recycled buffer of another size with stale marks: made the frame's size, cleared.
    let mut mask = vec![true; 7];
    let bbox = mask_from_vis(&v, &mut mask);
    assert!(mask.len() == 30 && mask.iter().all(|&m| !m) && bbox.is_none());
    for (x, y) in [(2, 1), (4, 2), (1, 3)] {
        v.inv_z[y * 6 + x] = 0.5;
    }
    // Outside the dirty rectangle: never read.
    v.inv_z[4 * 6 + 5] = 0.5;
    v.dirty = Some(pa_raster::PixelRect {
        x0: 1,
        y0: 1,
        x1: 4,
        y1: 3,
    });
    // Stale marks of the last frame are cleared too.
    mask[0] = true;
    mask[29] = true;
    let bbox = mask_from_vis(&v, &mut mask);
    assert_eq!(bbox, Some((1, 1, 4, 3)));
    let set: Vec<usize> = (0..30).filter(|&i| mask[i]).collect();
    assert_eq!(set, vec![6 + 2, 2 * 6 + 4, 3 * 6 + 1]);
}

#[test]
fn configuration_errors_keep_their_messages() {
    assert_eq!(
        ArError::NoAnimation { animation: 3 }.to_string(),
        "no animation 3"
    );
    assert_eq!(
        ArError::NoTracker.to_string(),
        "no tracker: use process_with_pose"
    );
    assert_eq!(ArError::FillMaskMissing.to_string(), "fill mask missing");
}
