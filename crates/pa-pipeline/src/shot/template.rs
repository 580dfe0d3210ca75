//! The commented shot file that `propsalive new` writes: every section explained in
//! comments, `format` first, lengths rounded to micrometres. The caller decides what goes in
//! ([`NewShot`]: paths already relative to the shot file, the board, the placement) and loads
//! the text back with [`super::Shot::parse`] before writing it.

use pa_track::Board;

use super::{Placement, SHOT_FORMAT};

/// The camera of a new shot.
#[derive(Debug, Clone, PartialEq)]
pub enum NewCamera {
    /// A calibration file, as the shot names it (relative to the shot file).
    Calibration(String),
    /// A vertical field of view, degrees.
    FovDeg(f64),
}

/// What a new shot file says.
#[derive(Debug, Clone)]
pub struct NewShot {
    /// The model, as the shot names it (relative to the shot file).
    pub model: String,
    pub animation: String,
    pub fps: f32,
    /// Key poses: name and animation frame; the first is the one in front of the camera.
    pub keys: Vec<(String, u32)>,
    pub camera: NewCamera,
    /// The board (a grid of `rows` x `cols` tags `gap_mm` apart, for the comments).
    pub board: Board,
    pub rows: u32,
    pub cols: u32,
    pub gap_mm: f64,
    pub placement: Placement,
}

/// A TOML basic string.
pub fn toml_string(s: &str) -> String {
    let mut out = String::from("\"");
    for c in s.chars() {
        match c {
            '"' => out.push_str("\\\""),
            '\\' => out.push_str("\\\\"),
            c if c.is_control() => out.push_str(&format!("\\u{:04X}", c as u32)),
            c => out.push(c),
        }
    }
    out.push('"');
    out
}

/// A number as TOML writes it, rounded to micrometres for lengths.
pub fn num(v: f64) -> String {
    let r = (v * 1e6).round() / 1e6;
    // No negative zero.
    let r = if r == 0.0 { 0.0 } else { r };
    let s = format!("{r}");
    if s.contains(['.', 'e', 'E', 'n', 'i']) {
        s
    } else {
        format!("{s}.0")
    }
}

impl NewShot {
    /// The commented shot file: every section explained, `format` first.
    pub fn to_commented_toml(&self) -> String {
        let p = self;
        let mut text = String::new();
        let mut line = |s: &str| {
            text.push_str(s);
            text.push('\n');
        };
        line("# A Props Alive shot, written by `propsalive new`. Paths are relative to this file.");
        line("# An unknown key is refused, never ignored; `format` is the version of this layout.");
        line(&format!("format = {SHOT_FORMAT}"));
        line("");
        line("# The rigged glTF 2.0 model of the prop, and the clip whose in-betweens are drawn.");
        line(&format!("model = {}", toml_string(&p.model)));
        line(&format!("animation = {}", toml_string(&p.animation)));
        line("# Animation frames per second (frame N of the clip is at N / fps seconds).");
        line(&format!("fps = {}", num(f64::from(p.fps))));
        line("# The key prop in front of the camera (a name of [[key_poses]]).");
        line(&format!("present_key = {}", toml_string(&p.keys[0].0)));
        line("");
        line(
            "# The key poses: animation frames that exist as physical (printed) props. A key prop",
        );
        line("# may carry its own tag on its base (marker_id = N, not a tag of the board).");
        for (name, frame) in &p.keys {
            line("[[key_poses]]");
            line(&format!("name = {}", toml_string(name)));
            line(&format!("frame = {frame}"));
            line("");
        }
        line("# The camera: a calibration file (`propsalive calibrate`), or a vertical field of");
        line("# view in degrees when there is none (calibrate for a placement to the millimetre).");
        line("[camera]");
        line(&match &p.camera {
            NewCamera::Calibration(path) => format!("calibration = {}", toml_string(path)),
            NewCamera::FovDeg(fov) => format!("fov_y_deg = {}", num(*fov)),
        });
        line("");
        line(&format!(
            "# The printed board: {}x{} tag36h11 tags of {} mm (black square), {} mm apart, ids",
            p.rows,
            p.cols,
            num(p.board.tags[0].size_m * 1000.0),
            num(p.gap_mm)
        ));
        line("# row-major from the top-left as printed. The marker frame's origin is the board's");
        line("# centre, +X to the right and +Y down the printed page, +Z into the table (metres).");
        line("# Print it with the prop's footprint: propsalive marker --shot THIS_FILE --out STEM");
        line("[marker]");
        line(&format!("family = {}", toml_string("tag36h11")));
        line("# No board in the final frames: hide = \"cover\" lays a picture over the sheet (lit");
        line("# like it); hide = \"plate\" the table without the board (see the README).");
        line("# hide = \"cover\"");
        line("# cover = \"rug.png\"");
        line("# A printed picture as the marker, alone (remove the tags) or with the tags: the");
        line("# marker frame is then the picture's (origin at its centre, +X along its width, +Y");
        line("# down it); check it first with propsalive marker --check floor.png.");
        line("# image = \"floor.png\"");
        line("# width_m = 0.3");
        for tag in &p.board.tags {
            line("[[marker.tags]]");
            line(&format!("id = {}", tag.id));
            line(&format!(
                "center_m = [{}, {}]",
                num(tag.center_m.x),
                num(tag.center_m.y)
            ));
            line(&format!("size_m = {}", num(tag.size_m)));
        }
        line("");
        let pl = &p.placement;
        let t = pl.translation_m;
        line("# Where the prop stands on the marker (marker_from_prop): scaled about the model's");
        line(
            "# origin, turned by yaw_deg about its up axis, stood upright (model +Y up, its front",
        );
        line("# +Z along the marker's +Y), then moved by translation_m. `propsalive new` put the");
        line(&format!(
            "# key pose's lowest points on the sheet (lift {} mm) and centred their outline on the",
            num(-f64::from(t[2]) * 1000.0)
        ));
        line("# board; `propsalive register` refines this from camera frames.");
        line("[placement]");
        line(&format!(
            "translation_m = [{}, {}, {}]",
            num(f64::from(t[0])),
            num(f64::from(t[1])),
            num(f64::from(t[2]))
        ));
        line(&format!("upright = {}", pl.upright));
        line(&format!("yaw_deg = {}", num(f64::from(pl.yaw_deg))));
        line(&format!("scale = {}", num(f64::from(pl.scale))));
        line("");
        line("# How the real prop is removed where the twin no longer covers it (optional; `run`");
        line(
            "# and `preview` flags override it): fill = \"rays\" (default), \"patch\", \"plate\",",
        );
        line("# \"rectangle\" or \"none\"; clean_plate = \"plate.png\" (a still of the set without the");
        line("# prop) or plate_frames = N (the take's first N stills); dilation_px = 4; shadows = false;");
        line("# align_plate = true (the plate aligned to each frame around the prop).");
        line("# [diminish]");
        line("# fill = \"rays\"");
        line("");
        line("# A scan pass before the take (optional; `run --scan` overrides it): a folder of");
        line(
            "# stills or a video circling the key prop once, inside this shot's folder; the twin's",
        );
        line("# parts the current frame cannot see take the colours remembered from it.");
        line("# [scan]");
        line("# input = \"scan\"");
        line("");
        line(
            "# How the live texture becomes the twin's colour (optional; all on by default): relight",
        );
        line("# shades it at the in-between's normals with the set's light; sun models that light");
        line("# as a sun with the twin's own cast shadows where the key prop's shading fits one;");
        line("# feather softens the seams between live and fallback colour; grazing adds the");
        line("# reflection a glossy prop shows edge-on (zero for a matte one). false switches one off.");
        line("# [texture]");
        line("# relight = false");
        line("# sun = false");
        line("# feather = false");
        line("# grazing = false");
        text
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn strings_and_numbers() {
        assert_eq!(toml_string("a\"b\\c\n"), "\"a\\\"b\\\\c\\u000A\"");
        assert_eq!(num(0.0), "0.0");
        assert_eq!(num(-0.0009), "-0.0009");
        assert_eq!(num(45.0), "45.0");
        assert_eq!(num(-0.0), "0.0");
        assert_eq!(num(-1e-9), "0.0");
    }

    /// The text loads back as the shot it describes, comments and all.
    #[test]
    fn the_commented_text_loads_back() {
        let board = Board::grid(pa_track::TagFamily::Tag36h11, 2, 2, 0.04, 0.01, 3).expect("grid");
        let shot = NewShot {
            model: "props/a \"b\".glb".into(),
            animation: "Walk".into(),
            fps: 12.5,
            keys: vec![("A".into(), 0), ("B".into(), 7)],
            camera: NewCamera::FovDeg(52.5),
            board,
            rows: 2,
            cols: 2,
            gap_mm: 10.0,
            placement: Placement {
                translation_m: [0.001, -0.002, -0.0009],
                scale: 0.5,
                ..Placement::default()
            },
        };
        let text = shot.to_commented_toml();
        let back =
            super::super::Shot::parse(&text, std::path::Path::new("new.toml")).expect("loads");
        assert_eq!(back.model, std::path::PathBuf::from("props/a \"b\".glb"));
        assert_eq!(back.animation.as_deref(), Some("Walk"));
        assert_eq!(back.fps, 12.5);
        assert_eq!(back.key_poses.len(), 2);
        assert_eq!(back.key_poses[1].frame, 7);
        assert_eq!(back.present_key.as_deref(), Some("A"));
        assert_eq!(back.camera.fov_y_deg, Some(52.5));
        assert_eq!(back.marker.tags.len(), 4);
        assert_eq!(back.marker.tags[0].id, 3);
        assert!((back.marker.tags[0].center_m[0] + 0.025).abs() < 1e-9);
        assert_eq!(back.placement, shot.placement);
        assert!(text.lines().filter(|l| l.starts_with('#')).count() >= 15);
        let cal = NewShot {
            camera: NewCamera::Calibration("../cam.yaml".into()),
            ..shot
        };
        let back =
            super::super::Shot::parse(&cal.to_commented_toml(), std::path::Path::new("n.toml"))
                .expect("loads");
        assert_eq!(
            back.camera.calibration,
            Some(std::path::PathBuf::from("../cam.yaml"))
        );
    }
}
