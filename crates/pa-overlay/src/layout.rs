//! Letterboxing and the mapping between window pixels, canvas pixels and animation frames.
//! Pure arithmetic, tested without a window.

/// A rectangle in pixels: origin at the top-left, +x right, +y down.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Rect {
    pub x: u32,
    pub y: u32,
    pub w: u32,
    pub h: u32,
}

/// The largest rectangle with the canvas's aspect ratio that fits the window, centred (black
/// bars on the two other sides). `None` when either size is zero (a minimised window).
pub fn letterbox(window: (u32, u32), canvas: (u32, u32)) -> Option<Rect> {
    let (ww, wh) = window;
    let (cw, ch) = canvas;
    if ww == 0 || wh == 0 || cw == 0 || ch == 0 {
        return None;
    }
    // Compare ww/wh with cw/ch without rounding: ww * ch vs wh * cw.
    let (w, h) = if (ww as u64) * (ch as u64) > (wh as u64) * (cw as u64) {
        // Window wider than the canvas: full height, bars left and right.
        let w = ((wh as u64 * cw as u64 + ch as u64 / 2) / ch as u64).max(1) as u32;
        (w.min(ww), wh)
    } else {
        let h = ((ww as u64 * ch as u64 + cw as u64 / 2) / cw as u64).max(1) as u32;
        (ww, h.min(wh))
    };
    Some(Rect {
        x: (ww - w) / 2,
        y: (wh - h) / 2,
        w,
        h,
    })
}

/// The canvas x coordinate under a window x, given the letterbox `rect` the canvas (`canvas_w`
/// pixels wide) is drawn in; not clamped (a drag may leave the image).
pub fn canvas_x_from_window(rect: Rect, canvas_w: u32, px: f64) -> f64 {
    (px - rect.x as f64) * canvas_w as f64 / rect.w.max(1) as f64
}

/// The animation frame a horizontal position selects when scrubbing: the image's width spans
/// frames `0..=last` (clamped at both ends).
pub fn scrub_frame(x: f64, width: u32, last: u32) -> u32 {
    if width <= 1 || last == 0 || !x.is_finite() {
        return 0;
    }
    let u = (x / (width - 1) as f64).clamp(0.0, 1.0);
    (u * last as f64).round() as u32
}

/// The initial window size for a canvas: the canvas itself, shrunk (aspect kept) to fit
/// `max` so that a 4K camera does not open a window larger than the screen.
pub fn initial_window(canvas: (u32, u32), max: (u32, u32)) -> (u32, u32) {
    if canvas.0 <= max.0 && canvas.1 <= max.1 {
        return canvas;
    }
    match letterbox(max, canvas) {
        Some(r) => (r.w, r.h),
        None => canvas,
    }
}

/// The camera model at a frame size (the calibration scaled when they differ).
pub fn frame_camera(camera: &pa_camera::CameraModel, w: u32, h: u32) -> pa_camera::CameraModel {
    if (camera.intrinsics.width, camera.intrinsics.height) == (w, h) {
        *camera
    } else {
        pa_camera::CameraModel {
            intrinsics: camera.intrinsics.scaled_to(w, h),
            distortion: camera.distortion,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn letterbox_same_aspect_fills_the_window() {
        assert_eq!(
            letterbox((640, 395), (640, 395)),
            Some(Rect {
                x: 0,
                y: 0,
                w: 640,
                h: 395
            })
        );
        assert_eq!(
            letterbox((1280, 720), (640, 360)),
            Some(Rect {
                x: 0,
                y: 0,
                w: 1280,
                h: 720
            })
        );
    }

    #[test]
    fn letterbox_bars_on_the_long_side() {
        // A wide window: bars left and right.
        let r = letterbox((1000, 360), (640, 360)).unwrap();
        assert_eq!((r.w, r.h), (640, 360));
        assert_eq!((r.x, r.y), (180, 0));
        // A tall window: bars top and bottom.
        let r = letterbox((640, 1000), (640, 360)).unwrap();
        assert_eq!((r.w, r.h), (640, 360));
        assert_eq!((r.x, r.y), (0, 320));
        // Odd sizes stay inside the window and keep the aspect within a pixel.
        for (ww, wh) in [(333, 777), (1921, 1079), (1, 1), (5000, 3)] {
            let r = letterbox((ww, wh), (640, 395)).unwrap();
            assert!(r.x + r.w <= ww && r.y + r.h <= wh, "{ww}x{wh}: {r:?}");
            assert!(r.w >= 1 && r.h >= 1);
            let aspect = r.w as f64 / r.h as f64;
            let want = 640.0 / 395.0;
            assert!(
                (aspect - want).abs() <= want * (1.0 / r.w as f64 + 1.0 / r.h as f64) + 1e-9,
                "{ww}x{wh}: {r:?}"
            );
        }
        assert_eq!(letterbox((0, 100), (640, 360)), None);
        assert_eq!(letterbox((100, 100), (0, 360)), None);
    }

    #[test]
    fn window_points_map_to_canvas_pixels() {
        let r = letterbox((1280, 1000), (640, 360)).unwrap();
        assert_eq!((r.x, r.y, r.w, r.h), (0, 140, 1280, 720));
        assert_eq!(canvas_x_from_window(r, 640, 640.0), 320.0);
        let r = letterbox((1000, 360), (640, 360)).unwrap();
        assert_eq!(canvas_x_from_window(r, 640, 180.0), 0.0);
        assert_eq!(canvas_x_from_window(r, 640, 100.0), -80.0);
    }

    #[test]
    fn scrubbing_spans_the_clip() {
        assert_eq!(scrub_frame(0.0, 640, 48), 0);
        assert_eq!(scrub_frame(639.0, 640, 48), 48);
        assert_eq!(scrub_frame(319.5, 640, 48), 24);
        assert_eq!(scrub_frame(-50.0, 640, 48), 0);
        assert_eq!(scrub_frame(9999.0, 640, 48), 48);
        assert_eq!(scrub_frame(f64::NAN, 640, 48), 0);
        assert_eq!(scrub_frame(100.0, 640, 0), 0);
    }

    #[test]
    fn initial_window_fits_the_screen() {
        assert_eq!(initial_window((640, 395), (1280, 800)), (640, 395));
        let (w, h) = initial_window((3840, 2195), (1280, 800));
        assert!(w <= 1280 && h <= 800);
        assert_eq!(w, 1280);
    }

    #[test]
    fn the_camera_is_scaled_to_the_frame() {
        let cam = pa_camera::CameraModel::pinhole(pa_camera::Intrinsics {
            fx: 100.0,
            fy: 100.0,
            cx: 63.5,
            cy: 47.5,
            width: 128,
            height: 96,
        });
        assert_eq!(frame_camera(&cam, 128, 96), cam);
        let half = frame_camera(&cam, 64, 48);
        assert_eq!(half.intrinsics, cam.intrinsics.scaled_to(64, 48));
        assert_eq!((half.intrinsics.width, half.intrinsics.height), (64, 48));
        assert_eq!(half.distortion, cam.distortion);
    }
}
