//! A picture and tags in one marker (`TrackTarget::ImageAndBoard`), against independent
//! truth: the tags are printed into the picture at their board positions, the views are
//! rendered by the exact plane-to-image mapping of `image_target::synth` at known poses, and
//! the picture's corners from the tracked pose are compared with the corners the true pose
//! projects. Either half alone must keep the marker tracked: the tags on a sheet whose
//! picture is gone (a picture-only tracker loses it there), the picture with its tags
//! painted over.

mod common;

use glam::{DVec2, DVec3};
use pa_camera::CameraModel;
use pa_track::board::BoardTag;
use pa_track::image_target::synth::{natural_picture, render_view, view_pose, Pinhole};
use pa_track::{
    family_layout, marker_cells, Board, CornerRefinement, DetectorConfig, GrayImage, ImageTarget,
    Pose, TagFamily, TrackTarget, Tracker, TrackerConfig,
};

const F: f64 = 1000.0;
const WIDTH_M: f64 = 0.25;
const PIC_W: u32 = 640;
const PIC_H: u32 = 480;
const TAG_M: f64 = 0.04;
/// Two tags in opposite corners of the picture (marker frame, metres).
const TAG_CENTRES_M: [[f64; 2]; 2] = [[-0.08, -0.055], [0.08, 0.055]];

fn pinhole() -> Pinhole {
    common::pinhole_720p()
}

fn camera() -> CameraModel {
    common::camera_720p()
}

fn board() -> Board {
    Board {
        family: TagFamily::Tag36h11,
        tags: TAG_CENTRES_M
            .iter()
            .enumerate()
            .map(|(id, c)| BoardTag {
                id: id as u32,
                center_m: DVec2::new(c[0], c[1]),
                size_m: TAG_M,
                rotation_rad: 0.0,
            })
            .collect(),
    }
}

/// The picture pixel's marker-frame point (the image target's convention).
fn marker_xy(u: u32, v: u32) -> (f64, f64) {
    let height_m = WIDTH_M * PIC_H as f64 / PIC_W as f64;
    (
        ((u as f64 + 0.5) / PIC_W as f64 - 0.5) * WIDTH_M,
        ((v as f64 + 0.5) / PIC_H as f64 - 0.5) * height_m,
    )
}

/// For each picture pixel inside a tag's printed code square: the tag's cell value there.
fn tag_value(u: u32, v: u32) -> Option<u8> {
    let layout = family_layout(TagFamily::Tag36h11).expect("layout");
    let scale = layout.total_cells as f64 / layout.border_cells as f64;
    let (x, y) = marker_xy(u, v);
    for (id, c) in TAG_CENTRES_M.iter().enumerate() {
        let half = TAG_M * scale * 0.5;
        let (dx, dy) = (x - c[0] + half, y - c[1] + half);
        if dx >= 0.0 && dy >= 0.0 && dx < 2.0 * half && dy < 2.0 * half {
            let cells = marker_cells(TagFamily::Tag36h11, id as u32).expect("cells");
            let n = cells.width as f64;
            let cx = ((dx / (2.0 * half)) * n) as usize;
            let cy = ((dy / (2.0 * half)) * n) as usize;
            let white = cells.data[cy * cells.width as usize + cx] > 127;
            return Some(if white { 245 } else { 18 });
        }
    }
    None
}

/// The procedural picture (the user's file), the sheet printed with the tags over it, the same
/// tags on a flat sheet, and the picture with the tags' squares painted flat grey.
fn sheets() -> (GrayImage, GrayImage, GrayImage, GrayImage) {
    let pic = natural_picture(PIC_W, PIC_H, 7);
    let mut with_tags = pic.clone();
    let mut tags_only = GrayImage::filled(PIC_W, PIC_H, 200);
    let mut painted = pic.clone();
    for v in 0..PIC_H {
        for u in 0..PIC_W {
            if let Some(t) = tag_value(u, v) {
                let i = (v * PIC_W + u) as usize;
                with_tags.data[i] = t;
                tags_only.data[i] = t;
                painted.data[i] = 128;
            }
        }
    }
    (pic, with_tags, tags_only, painted)
}

fn true_corners(pose: &Pose, height_m: f64) -> [DVec2; 4] {
    let (w, h) = (0.5 * WIDTH_M, 0.5 * height_m);
    [(-w, -h), (w, -h), (w, h), (-w, h)].map(|(x, y)| {
        let c = pose.transform_point(DVec3::new(x, y, 0.0));
        DVec2::new(F * c.x / c.z + pinhole().cx, F * c.y / c.z + pinhole().cy)
    })
}

fn tracker(target: TrackTarget) -> Tracker {
    Tracker::new(
        camera(),
        target,
        DetectorConfig::default(),
        TrackerConfig {
            // `render_view` blurs the picture's stored values: a camera whose values are
            // proportional to the light.
            refine_corners: CornerRefinement::Linear,
            ..TrackerConfig::per_still()
        },
    )
    .expect("tracker")
}

fn max_corner_error(got: [DVec2; 4], truth: &Pose, height_m: f64) -> f64 {
    got.iter()
        .zip(true_corners(truth, height_m))
        .map(|(a, b)| a.distance(b))
        .fold(0.0, f64::max)
}

#[test]
fn picture_and_tags_are_fitted_together_and_either_alone_keeps_the_marker() {
    let (pic, with_tags, tags_only, painted) = sheets();
    // The picture as the user has it (the tags are added to the print).
    let image = ImageTarget::new(&pic, WIDTH_M).unwrap();
    let height_m = image.height_m;
    let combined = || TrackTarget::ImageAndBoard {
        image: Box::new(image.clone()),
        board: board(),
    };
    let truth = view_pose(0.6, 30.0, 20.0, 0.02, -0.01);

    // Both seen: the tags' ids are used and the picture's corners are right.
    let frame = render_view(&with_tags, WIDTH_M, &pinhole(), &truth, 90, 0.7, 2.0, 1);
    let out = tracker(combined()).update(&frame, 0.0).unwrap();
    assert!(out.raw.is_some(), "both halves in view, not seen");
    assert_eq!(out.used_ids, vec![0, 1]);
    let e = max_corner_error(out.target_corners_px.unwrap(), &truth, height_m);
    eprintln!("both: max corner error {e:.3} px");
    assert!(e < 0.5, "both: corner error {e:.3} px");

    // The picture gone, the tags left: a picture-only tracker loses it, the combined one
    // keeps it from the tags alone.
    let frame = render_view(&tags_only, WIDTH_M, &pinhole(), &truth, 90, 0.7, 2.0, 2);
    let alone = tracker(TrackTarget::Image(Box::new(image.clone())))
        .update(&frame, 0.0)
        .unwrap();
    assert!(
        alone.raw.is_none(),
        "a picture-only tracker found a blank sheet"
    );
    let out = tracker(combined()).update(&frame, 0.0).unwrap();
    assert!(out.raw.is_some(), "tags alone: not seen");
    assert_eq!(out.used_ids, vec![0, 1]);
    let e = max_corner_error(out.target_corners_px.unwrap(), &truth, height_m);
    // The picture's corners lie beyond the two 40 mm tags: extrapolated, so looser.
    eprintln!("tags alone: max corner error {e:.3} px");
    assert!(e < 2.0, "tags alone: corner error {e:.3} px");

    // The tags painted over: the picture alone keeps it, no tag is used.
    let frame = render_view(&painted, WIDTH_M, &pinhole(), &truth, 90, 0.7, 2.0, 3);
    let out = tracker(combined()).update(&frame, 0.0).unwrap();
    assert!(out.raw.is_some(), "picture alone: not seen");
    assert!(out.used_ids.is_empty(), "{:?}", out.used_ids);
    let e = max_corner_error(out.target_corners_px.unwrap(), &truth, height_m);
    eprintln!("picture alone: max corner error {e:.3} px");
    assert!(e < 1.0, "picture alone: corner error {e:.3} px");
}
