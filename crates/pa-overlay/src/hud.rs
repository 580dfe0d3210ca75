//! What the preview draws over and under the composited frame: the tracked axes, the status
//! bar (a timeline of the clip with its key poses, and two lines: fps, latency, tracking
//! state, animation frame and key pose; stage timings, overlay flags, recording), the key
//! list and short messages. The canvas is the frame with the bar below it, so the bar never
//! hides the shot.

use glam::{DVec3, Mat4, Vec3};
use pa_camera::CameraModel;

use crate::action::HELP;
use crate::draw::{fit_text, text_width, Image, Rgb, BAR, BLUE, GLYPH, GREEN, RED, WHITE, YELLOW};
use crate::state::PlacementValues;

/// The pipeline's stage timings as the status bar shows them, ms (the fields of
/// `pa_pipeline::ar::StageTimings`, which this GPU-free crate does not depend on; the preview
/// copies them over).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct StageTimings {
    pub track_ms: f64,
    pub animate_ms: f64,
    pub texture_ms: f64,
    pub diminish_ms: f64,
    pub composite_ms: f64,
}

/// Font scale for a canvas width: 1 (8 px glyphs) up to 1000 px wide, then 2, ...
pub fn text_scale(width: u32) -> u32 {
    (width / 1000 + 1).min(4)
}

/// Geometry of the status bar for a frame width (all in pixels).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BarLayout {
    pub scale: u32,
    pub pad: u32,
    /// Height of the timeline strip.
    pub timeline_h: u32,
    /// Height of one text line (glyph plus spacing).
    pub line_h: u32,
    /// Height of the whole bar.
    pub height: u32,
}

impl BarLayout {
    pub fn for_width(width: u32) -> Self {
        let scale = text_scale(width);
        let pad = 3 * scale;
        let timeline_h = 6 * scale;
        let line_h = 10 * scale;
        Self {
            scale,
            pad,
            timeline_h,
            line_h,
            height: pad + timeline_h + pad + 2 * line_h + pad,
        }
    }

    /// Top of the timeline, relative to the bar.
    pub fn timeline_y(&self) -> u32 {
        self.pad
    }

    /// Top of text line `n` (0 or 1), relative to the bar.
    pub fn line_y(&self, n: u32) -> u32 {
        self.pad + self.timeline_h + self.pad + n * self.line_h + self.scale
    }
}

/// What the status bar shows.
#[derive(Debug, Clone, PartialEq)]
pub struct Status {
    /// Frames presented per second (smoothed); None before the second frame.
    pub fps: Option<f64>,
    /// Camera-to-screen latency of the last presented frame, ms.
    pub latency_ms: Option<f64>,
    /// Tracking state (`Searching`, `Detected`, `Tracked`, `Lost`).
    pub state: String,
    pub anim_frame: u32,
    pub last_frame: u32,
    pub playing: bool,
    pub key_name: String,
    pub key_frame: u32,
    pub timings: StageTimings,
    /// Overlay flags (upper case = on), see `PreviewState::flags`.
    pub flags: String,
    /// Frames recorded so far while recording.
    pub recorded: Option<u64>,
}

/// The two text lines of the status bar, each at most `max_chars` long where possible: the
/// numbers are padded to fixed widths (so the line does not jitter) when that fits, else
/// written compactly; what still does not fit is cut by the caller.
pub fn status_lines(s: &Status, max_chars: usize) -> [String; 2] {
    let key = format!("key {}@{}", s.key_name, s.key_frame);
    let play = if s.playing { "PLAY" } else { "PAUSE" };
    let padded = {
        let fps = s
            .fps
            .map_or_else(|| "  -.-".to_string(), |f| format!("{f:5.1}"));
        let lat = s
            .latency_ms
            .map_or_else(|| "  -".to_string(), |l| format!("{l:3.0}"));
        format!(
            "{fps} fps  lat {lat} ms  {:<9} frame {}/{} {play}  {key}",
            s.state, s.anim_frame, s.last_frame
        )
    };
    let line1 = if padded.chars().count() <= max_chars {
        padded
    } else {
        let fps = s.fps.map_or_else(|| "-".to_string(), |f| format!("{f:.1}"));
        let lat = s
            .latency_ms
            .map_or_else(|| "-".to_string(), |l| format!("{l:.0}"));
        format!(
            "{fps}fps lat {lat}ms {} {}/{} {play} {key}",
            s.state, s.anim_frame, s.last_frame
        )
    };
    let t = &s.timings;
    let line2 = format!(
        "track {:.1} anim {:.1} tex {:.1} dim {:.1} comp {:.1} ms  [{}]",
        t.track_ms, t.animate_ms, t.texture_ms, t.diminish_ms, t.composite_ms, s.flags
    );
    [line1, line2]
}

/// Draws the status bar into rows `y0..` of `canvas` (as tall as [`BarLayout::height`]).
pub fn draw_bar(canvas: &mut Image, y0: u32, status: &Status, key_frames: &[u32]) {
    let l = BarLayout::for_width(canvas.width);
    let w = canvas.width;
    canvas.fill_rect(0, y0 as i64, w, l.height, BAR);
    // Timeline: the clip across the bar, key poses as yellow ticks, the frame shown in white.
    let tx = l.pad as i64;
    let tw = w.saturating_sub(2 * l.pad).max(1);
    let ty = (y0 + l.timeline_y()) as i64;
    canvas.fill_rect(tx, ty, tw, l.timeline_h, [58, 58, 64]);
    let x_of = |f: u32| {
        if status.last_frame == 0 {
            tx
        } else {
            tx + ((tw - 1) as f64 * f as f64 / status.last_frame as f64).round() as i64
        }
    };
    for &k in key_frames {
        canvas.fill_rect(
            x_of(k) - l.scale as i64 / 2,
            ty,
            l.scale,
            l.timeline_h,
            YELLOW,
        );
    }
    let cur = x_of(status.anim_frame.min(status.last_frame));
    canvas.fill_rect(cur - l.scale as i64, ty, 2 * l.scale, l.timeline_h, WHITE);

    let max = w.saturating_sub(2 * l.pad);
    let [line1, line2] = status_lines(status, (max / (GLYPH * l.scale)) as usize);
    canvas.text(
        tx,
        (y0 + l.line_y(0)) as i64,
        fit_text(&line1, max, l.scale),
        l.scale,
        WHITE,
    );
    let line2 = fit_text(&line2, max, l.scale);
    let drawn = canvas.text(tx, (y0 + l.line_y(1)) as i64, line2, l.scale, WHITE);
    if let Some(n) = status.recorded {
        let rec = format!("  REC {n}");
        if text_width(line2, l.scale) + text_width(&rec, l.scale) <= max {
            canvas.text(
                tx + drawn as i64,
                (y0 + l.line_y(1)) as i64,
                &rec,
                l.scale,
                RED,
            );
        } else {
            // No room: a red block at the bar's right end says it.
            canvas.fill_rect(
                (w - l.pad - 2 * l.line_h) as i64,
                (y0 + l.line_y(1)) as i64,
                2 * l.line_h,
                l.line_h - l.scale,
                RED,
            );
        }
    }
}

/// Draws the marker's axes (X red, Y green, Z blue: `pa-track`'s marker frame, +Z into the
/// table), `length_m` long, from the tracked `camera_from_marker`.
pub fn draw_axes(img: &mut Image, camera: &CameraModel, camera_from_marker: Mat4, length_m: f32) {
    let project = |p: Vec3| {
        let c = camera_from_marker.transform_point3(p);
        camera
            .pixel_from_camera(DVec3::new(c.x as f64, c.y as f64, c.z as f64))
            .map(|q| (q.x, q.y))
    };
    let thickness = text_scale(img.width) * 2;
    let Some(origin) = project(Vec3::ZERO) else {
        return;
    };
    for (axis, colour) in [(Vec3::X, RED), (Vec3::Y, GREEN), (Vec3::Z, BLUE)] {
        if let Some(end) = project(axis * length_m) {
            img.line(origin, end, thickness, colour);
        }
    }
    let s = thickness as i64 + 1;
    img.fill_rect(
        origin.0.round() as i64 - s / 2,
        origin.1.round() as i64 - s / 2,
        s as u32,
        s as u32,
        WHITE,
    );
}

/// A dark translucent box with lines of text, at the top-left of the image.
pub fn draw_panel(img: &mut Image, lines: &[&str], colour: Rgb) {
    let scale = text_scale(img.width);
    let pad = 4 * scale;
    let line_h = 10 * scale;
    let max = img.width.saturating_sub(4 * pad);
    let w = lines
        .iter()
        .map(|l| text_width(fit_text(l, max, scale), scale))
        .max()
        .unwrap_or(0)
        + 2 * pad;
    let h = lines.len() as u32 * line_h + 2 * pad;
    img.blend_rect(pad as i64, pad as i64, w, h, [0, 0, 0], 0.72);
    for (n, l) in lines.iter().enumerate() {
        img.text(
            2 * pad as i64,
            (2 * pad + n as u32 * line_h) as i64,
            fit_text(l, max, scale),
            scale,
            colour,
        );
    }
}

/// The key list on screen.
pub fn draw_help(img: &mut Image) {
    draw_panel(img, HELP, WHITE);
}

/// The placement overlay: the key pose's outline (pixels, computed by the caller) in yellow,
/// and a line at the bottom of the frame saying where the prop stands (and that `W` writes
/// it when it differs from the shot file).
pub fn draw_placement(
    img: &mut Image,
    outline: &[(u32, u32)],
    placement: &PlacementValues,
    edited: bool,
) {
    for &(x, y) in outline {
        img.put(x as i64, y as i64, YELLOW);
    }
    let scale = text_scale(img.width);
    let mut line = format!("placement  {}", placement.describe());
    if edited {
        line.push_str("  (W: write)");
    }
    let h = GLYPH * scale + 6;
    let y = img.height as i64 - h as i64;
    img.blend_rect(0, y, img.width, h, BAR, 0.75);
    let max = img.width.saturating_sub(8);
    img.text(4, y + 3, fit_text(&line, max, scale), scale, YELLOW);
}

#[cfg(test)]
mod tests {
    use super::*;
    use pa_camera::Intrinsics;

    fn status() -> Status {
        Status {
            fps: Some(12.34),
            latency_ms: Some(85.2),
            state: "Tracked".into(),
            anim_frame: 12,
            last_frame: 48,
            playing: true,
            key_name: "A".into(),
            key_frame: 0,
            timings: StageTimings {
                track_ms: 6.04,
                animate_ms: 0.01,
                texture_ms: 45.2,
                diminish_ms: 4.1,
                composite_ms: 1.6,
            },
            flags: "Damol".into(),
            recorded: None,
        }
    }

    #[test]
    fn status_lines_say_everything_and_fit() {
        let [l1, l2] = status_lines(&status(), 79);
        assert_eq!(
            l1,
            " 12.3 fps  lat  85 ms  Tracked   frame 12/48 PLAY  key A@0"
        );
        assert_eq!(
            l2,
            "track 6.0 anim 0.0 tex 45.2 dim 4.1 comp 1.6 ms  [Damol]"
        );
        let mut s = status();
        s.fps = None;
        s.latency_ms = None;
        s.playing = false;
        let [l1, _] = status_lines(&s, 79);
        assert!(l1.starts_with("  -.- fps  lat   - ms"), "{l1}");
        assert!(l1.contains("PAUSE"));
        // Narrow frames get the compact form, which keeps the key pose in view.
        let mut s = status();
        s.state = "Searching".into();
        s.anim_frame = 100;
        s.last_frame = 120;
        s.fps = Some(100.0);
        s.latency_ms = Some(120.4);
        let [l1, _] = status_lines(&s, 59);
        assert_eq!(l1, "100.0fps lat 120ms Searching 100/120 PLAY key A@0");
        assert!(l1.len() <= 59);
    }

    #[test]
    fn bar_layout_and_drawing() {
        let l = BarLayout::for_width(640);
        assert_eq!((l.scale, l.height), (1, 35));
        assert_eq!(BarLayout::for_width(1920).scale, 2);
        let mut canvas = Image::filled(640, 360 + l.height, [90, 120, 60]);
        let mut s = status();
        s.recorded = Some(3);
        draw_bar(&mut canvas, 360, &s, &[0, 24]);
        // The frame above is untouched.
        assert_eq!(canvas.get(10, 359), Some([90, 120, 60]));
        // The bar: dark, with white text and a timeline.
        let bar_px: Vec<Rgb> = (360..360 + l.height)
            .flat_map(|y| (0..640).map(move |x| (x, y)))
            .filter_map(|(x, y)| canvas.get(x, y))
            .collect();
        let white = bar_px.iter().filter(|p| **p == WHITE).count();
        let dark = bar_px.iter().filter(|p| **p == BAR).count();
        assert!(white > 300, "{white}");
        assert!(dark > bar_px.len() / 2, "{dark}");
        // Key pose ticks: frame 24 of 48 sits in the middle of the timeline.
        let ty = 360 + l.timeline_y() + 1;
        assert_eq!(canvas.get(3, ty), Some(YELLOW));
        let mid = 3 + ((640 - 6 - 1) as f64 * 0.5).round() as u32;
        assert_eq!(canvas.get(mid, ty), Some(YELLOW));
        // Recording is said in red.
        let red = bar_px.iter().filter(|p| **p == RED).count();
        assert!(red > 20, "{red}");
    }

    #[test]
    fn axes_are_drawn_where_the_marker_projects() {
        let k = Intrinsics::from_fov_y(45f64.to_radians(), 320, 240).unwrap();
        let camera = CameraModel::pinhole(k);
        // The marker 0.5 m in front of the camera, axes aligned with the camera's.
        let pose = Mat4::from_translation(Vec3::new(0.0, 0.0, 0.5));
        let mut img = Image::filled(320, 240, [0, 0, 0]);
        draw_axes(&mut img, &camera, pose, 0.05);
        // Origin at the principal point: white; +X to the right red; +Y down green.
        let (cx, cy) = (k.cx.round() as u32, k.cy.round() as u32);
        assert_eq!(img.get(cx, cy), Some(WHITE));
        assert_eq!(img.get(cx + 20, cy), Some(RED));
        assert_eq!(img.get(cx, cy + 20), Some(GREEN));
        // Behind the camera: nothing drawn, no panic.
        let mut img2 = Image::filled(320, 240, [0, 0, 0]);
        draw_axes(
            &mut img2,
            &camera,
            Mat4::from_translation(Vec3::new(0.0, 0.0, -1.0)),
            0.05,
        );
        assert!(img2.rgba8.chunks_exact(4).all(|p| p[..3] == [0, 0, 0]));
    }

    #[test]
    fn help_panel_shows_text() {
        let mut img = Image::filled(640, 360, [120, 120, 120]);
        draw_help(&mut img);
        let white = img
            .rgba8
            .chunks_exact(4)
            .filter(|p| p[..3] == WHITE)
            .count();
        assert!(white > 1000, "{white}");
    }

    #[test]
    fn placement_overlay_draws_the_outline_and_the_values() {
        let mut img = Image::filled(640, 360, [120, 120, 120]);
        let outline = [(100, 100), (101, 100), (300, 50)];
        let p = PlacementValues {
            translation_m: [0.001, 0.0, 0.0],
            yaw_deg: 3.0,
        };
        draw_placement(&mut img, &outline, &p, true);
        for (x, y) in outline {
            assert_eq!(img.get(x, y), Some(YELLOW));
        }
        // The line at the bottom is yellow text; nothing else in the middle changed.
        let bottom = (340..360)
            .flat_map(|y| (0..640).map(move |x| (x, y)))
            .filter(|&(x, y)| img.get(x, y) == Some(YELLOW))
            .count();
        assert!(bottom > 200, "{bottom}");
        assert_eq!(img.get(320, 200), Some([120, 120, 120]));
    }
}
