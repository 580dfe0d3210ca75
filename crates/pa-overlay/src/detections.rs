//! The debug drawing of `propsalive track --draw`: a grey frame turned RGB with each
//! detection's outline (green when the tracker used it, amber otherwise), a magenta dot on
//! the printed top-left corner, and the marker's axes (X red, Y green, Z blue) from this
//! frame's measured pose, else the filtered one.

use glam::{DVec2, DVec3};
use pa_camera::CameraModel;
use pa_track::TrackOutput;

fn put(img: &mut image::RgbImage, x: i64, y: i64, c: [u8; 3]) {
    if x >= 0 && y >= 0 && (x as u32) < img.width() && (y as u32) < img.height() {
        img.put_pixel(x as u32, y as u32, image::Rgb(c));
    }
}

fn dot(img: &mut image::RgbImage, p: DVec2, r: i64, c: [u8; 3]) {
    let (cx, cy) = (p.x.round() as i64, p.y.round() as i64);
    for dy in -r..=r {
        for dx in -r..=r {
            if dx * dx + dy * dy <= r * r {
                put(img, cx + dx, cy + dy, c);
            }
        }
    }
}

fn line(img: &mut image::RgbImage, a: DVec2, b: DVec2, thick: i64, c: [u8; 3]) {
    if !(a.is_finite() && b.is_finite()) {
        return;
    }
    let n = (a.distance(b).ceil() as usize).clamp(1, 20_000);
    for i in 0..=n {
        let p = a.lerp(b, i as f64 / n as f64);
        dot(img, p, thick, c);
    }
}

/// `gray` as RGB with `out`'s detections and the marker axes (`axis_m` metres long) drawn
/// through `camera`.
pub fn draw_frame(
    gray: &image::GrayImage,
    out: &TrackOutput,
    camera: &CameraModel,
    axis_m: f64,
) -> image::RgbImage {
    let mut img = image::DynamicImage::ImageLuma8(gray.clone()).to_rgb8();
    let thick = ((gray.width().max(gray.height()) as f64 / 800.0).round() as i64).max(1);
    for d in &out.detections {
        let used = out.used_ids.contains(&d.id);
        let col = if used { [0, 230, 0] } else { [255, 200, 0] };
        for i in 0..4 {
            line(
                &mut img,
                d.corners_px[i],
                d.corners_px[(i + 1) % 4],
                thick,
                col,
            );
        }
        // The printed top-left corner.
        dot(&mut img, d.corners_px[0], 2 * thick + 1, [255, 0, 255]);
    }
    let pose = out.raw.map(|r| r.pose).or(out.pose);
    if let Some(p) = pose {
        let o = camera.pixel_from_camera(p.transform_point(DVec3::ZERO));
        for (axis, col) in [
            (DVec3::X, [255, 0, 0]),
            (DVec3::Y, [0, 255, 0]),
            (DVec3::Z, [0, 90, 255]),
        ] {
            let e = camera.pixel_from_camera(p.transform_point(axis * axis_m));
            if let (Some(o), Some(e)) = (o, e) {
                line(&mut img, o, e, thick, col);
            }
        }
    }
    img
}

#[cfg(test)]
mod tests {
    use super::*;
    use pa_camera::Intrinsics;
    use pa_track::{Detection, TagFamily, TrackState};

    fn output(detections: Vec<Detection>, used_ids: Vec<u32>) -> TrackOutput {
        TrackOutput {
            state: TrackState::Detected,
            events: vec![],
            pose: None,
            raw: None,
            coasting: false,
            detections,
            used_ids,
            used_roi: false,
            target_corners_px: None,
        }
    }

    fn camera() -> CameraModel {
        CameraModel::pinhole(Intrinsics {
            fx: 50.0,
            fy: 50.0,
            cx: 31.5,
            cy: 23.5,
            width: 64,
            height: 48,
        })
    }

    #[test]
    fn outlines_and_corner_dot() {
        let gray = image::GrayImage::from_pixel(64, 48, image::Luma([100]));
        let d = Detection {
            family: TagFamily::Tag36h11,
            id: 5,
            corners_px: [
                DVec2::new(10.0, 10.0),
                DVec2::new(30.0, 10.0),
                DVec2::new(30.0, 30.0),
                DVec2::new(10.0, 30.0),
            ],
            hamming: 0,
            decision_margin: 50.0,
        };
        let img = draw_frame(&gray, &output(vec![d.clone()], vec![5]), &camera(), 0.1);
        assert_eq!((img.width(), img.height()), (64, 48));
        assert_eq!(img.get_pixel(20, 30).0, [0, 230, 0]);
        assert_eq!(img.get_pixel(30, 20).0, [0, 230, 0]);
        assert_eq!(img.get_pixel(10, 10).0, [255, 0, 255]);
        assert_eq!(img.get_pixel(20, 20).0, [100, 100, 100]);
        let img = draw_frame(&gray, &output(vec![d], vec![]), &camera(), 0.1);
        assert_eq!(img.get_pixel(20, 30).0, [255, 200, 0]);
    }

    #[test]
    fn off_image_and_non_finite_points_are_ignored() {
        let gray = image::GrayImage::from_pixel(8, 8, image::Luma([7]));
        let d = Detection {
            family: TagFamily::Tag36h11,
            id: 0,
            corners_px: [
                DVec2::new(-100.0, -100.0),
                DVec2::new(f64::NAN, 0.0),
                DVec2::new(200.0, 200.0),
                DVec2::new(-5.0, 300.0),
            ],
            hamming: 0,
            decision_margin: 1.0,
        };
        let img = draw_frame(&gray, &output(vec![d], vec![]), &camera(), 0.1);
        assert_eq!((img.width(), img.height()), (8, 8));
    }
}
