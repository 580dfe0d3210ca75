//! The shot: what an AR take needs to know, written as a TOML file.
//!
//! ```toml
//! format = 1                    # the shot format's version (optional; see `keys`)
//! model = "prop.glb"            # relative to the shot file
//! animation = "Animate"         # name or index
//! fps = 24.0
//! present_key = "A"             # which physical key prop is in front of the camera
//!
//! [[key_poses]]
//! name = "A"
//! frame = 0
//!
//! [camera]
//! fov_y_deg = 45.0              # or: calibration = "camera.yaml" (OpenCV YAML)
//!
//! [marker]
//! family = "tag36h11"
//! # image = "floor.png"         # a printed picture as the marker (or with the tags), relative
//! # width_m = 0.3               #   to the shot; its printed width (height from its aspect)
//! hide = "none"                 # optional: none, cover, plate (see crate::shot_hide)
//! # cover = "rug.png"           # the picture over the board (hide = cover)
//! [[marker.tags]]               # board layout, marker frame (metres); one entry = one tag
//! id = 0
//! center_m = [0.0, 0.0]
//! size_m = 0.05
//!
//! [placement]                   # marker_from_prop
//! translation_m = [0.0, 0.0, 0.0]
//! upright = true                # prop +Y up (marker -Z), prop front +Z toward marker +Y
//! yaw_deg = 0.0                 # then a turn about the prop's up axis
//! scale = 1.0                   # uniform scale of the model about its origin (first)
//!
//! [diminish]                    # optional: see crate::shot_diminish
//! fill = "rays"
//! ```
//!
//! Hostile input: the file is read through [`pa_io`] (a regular file of at most
//! [`MAX_SHOT_BYTES`]; a FIFO or a device is refused at once), every number must be finite,
//! fixed-size vectors must have exactly their length, tag ids must be codes of the family and
//! appear once, and a parse error gives the line, the column and what was expected, never the
//! file's text. A key the format does not know is refused with its dotted name and position
//! ([`keys`]), never dropped.

use std::collections::HashSet;
use std::path::{Path, PathBuf};

use glam::{Mat3, Mat4, Vec3};
use pa_camera::diag::{fmt_position, toml_error};
use serde::{Deserialize, Deserializer, Serialize};

pub use crate::shot_diminish::ShotDiminish;

/// The largest shot file read (4 MiB): a shot is a few hundred bytes, a board of every
/// tag36h11 code about 40 KiB.
pub const MAX_SHOT_BYTES: u64 = 4 << 20;

mod keys;
pub mod template;

pub use crate::shot_texture::ShotTexture;

pub use keys::{KNOWN_KEYS, SHOT_FORMAT};

/// Errors reading, checking or writing a shot, or turning it into a board or a camera
/// ([`crate::shot_config`]); each but [`ShotError::Serialize`] names the file (or the frames).
#[derive(Debug, thiserror::Error)]
pub enum ShotError {
    /// Not a regular file, over [`MAX_SHOT_BYTES`], not UTF-8, or an operating-system error.
    #[error(transparent)]
    Io(#[from] pa_io::IoError),
    /// Not TOML, or not a shot's schema: `line` and `column` are 1-based (0 when unknown) and
    /// `message` says what was expected, with quoted values removed.
    #[error("{}{}: not a valid shot file: {message}", path.display(), fmt_position(*line, *column))]
    Parse {
        path: PathBuf,
        line: usize,
        column: usize,
        message: String,
    },
    /// A key that this version of the shot format does not know (misspelt, or from a newer
    /// version). `key` is its dotted name (`None` when it is not a plain name, which is not
    /// repeated), `table` the dotted path of its table (`placement`; `""` for the top level),
    /// `format` the version the file claims, `known` the keys of that table and `suggestion`
    /// the closest one.
    #[error("{}", unknown_key_message(path, *line, *column, key.as_deref(), table, *format, known, *suggestion))]
    UnknownKey {
        path: PathBuf,
        line: usize,
        column: usize,
        key: Option<String>,
        table: &'static str,
        format: u32,
        known: &'static [&'static str],
        suggestion: Option<&'static str>,
    },
    /// The file claims a newer shot format (`format = N`, N > [`SHOT_FORMAT`]).
    #[error("{}{}: written for shot format {format}; this propsalive reads format {SHOT_FORMAT}", path.display(), fmt_position(*line, *column))]
    NewerFormat {
        path: PathBuf,
        line: usize,
        column: usize,
        format: i64,
    },
    /// The shot parses but cannot be used.
    #[error("{}: {message}", path.display())]
    Invalid { path: PathBuf, message: String },
    /// [`Shot::to_toml`] failed (no file involved).
    #[error("{0}")]
    Serialize(toml::ser::Error),
    // Turning a shot into a board or a camera (`shot_config`).
    /// `[marker] family` is not a tag family.
    #[error("{}: [marker] family", shot.display())]
    Family {
        shot: PathBuf,
        #[source]
        source: pa_track::TrackError,
    },
    /// The tracker's own error (a family without a layout).
    #[error(transparent)]
    Track(#[from] pa_track::TrackError),
    /// A tag id beyond the family's.
    #[error("{}: tag id {id} does not exist in {family} (ids 0..{id_count})", shot.display())]
    TagId {
        shot: PathBuf,
        id: u32,
        family: pa_track::TagFamily,
        id_count: u32,
    },
    /// The shot's calibration file cannot be loaded.
    #[error("loading the calibration {}", path.display())]
    Calibration {
        path: PathBuf,
        #[source]
        source: pa_camera::calib::CalibError,
    },
    /// The frames' aspect ratio is not the calibration's.
    #[error(
        "{frame_name} is {width}x{height} but the calibration {calib_name} is for {calib_width}x{calib_height} (aspect {frame_aspect:.4} vs {calib_aspect:.4}): a different aspect ratio means a crop or another camera mode; calibrate at this resolution"
    )]
    AspectRatio {
        frame_name: String,
        width: u32,
        height: u32,
        calib_name: String,
        calib_width: u32,
        calib_height: u32,
        frame_aspect: f64,
        calib_aspect: f64,
    },
    /// `[camera] fov_y_deg` out of range.
    #[error("{}: [camera] fov_y_deg must be in (1, 179), got {fov}", shot.display())]
    FieldOfView { shot: PathBuf, fov: f64 },
    /// Neither a calibration nor a field of view.
    #[error("{}: [camera] needs calibration or fov_y_deg", shot.display())]
    NoCamera { shot: PathBuf },
    /// The pinhole camera cannot be made (a frame size out of range).
    #[error(transparent)]
    Camera(#[from] pa_camera::CameraError),
}

#[allow(clippy::too_many_arguments)]
fn unknown_key_message(
    path: &Path,
    line: usize,
    column: usize,
    key: Option<&str>,
    table: &str,
    format: u32,
    known: &[&str],
    suggestion: Option<&str>,
) -> String {
    let what = match key {
        Some(k) => format!("unknown key `{k}`"),
        None => "an unknown key".into(),
    };
    let table = if table.is_empty() {
        "the top level".to_string()
    } else {
        format!("[{table}]")
    };
    let hint = suggestion.map_or(String::new(), |s| format!("; did you mean `{s}`?"));
    format!(
        "{}{}: {what} in {table}: the file is shot format {format}, which has no such key{hint} ({table} knows {})",
        path.display(),
        fmt_position(line, column),
        known.join(", ")
    )
}

/// Exactly `N` numbers (serde's arrays would silently drop extra ones from TOML).
fn exactly<'de, D, T, const N: usize>(d: D, field: &str) -> Result<[T; N], D::Error>
where
    D: Deserializer<'de>,
    T: Deserialize<'de>,
{
    let v = Vec::<T>::deserialize(d)?;
    let n = v.len();
    v.try_into().map_err(|_| {
        serde::de::Error::custom(format!("`{field}` needs exactly {N} numbers, found {n}"))
    })
}

fn center_m<'de, D: Deserializer<'de>>(d: D) -> Result<[f64; 2], D::Error> {
    exactly(d, "center_m")
}

fn translation_m<'de, D: Deserializer<'de>>(d: D) -> Result<[f32; 3], D::Error> {
    exactly(d, "translation_m")
}

/// A key pose: an animation frame that exists as a physical prop.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct KeyPose {
    pub name: String,
    pub frame: u32,
    /// When set, this key prop is recognised by a marker id on its base.
    #[serde(default)]
    pub marker_id: Option<u32>,
}

/// The camera of the shot.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
pub struct ShotCamera {
    /// OpenCV calibration YAML (or TOML/JSON), relative to the shot file.
    #[serde(default)]
    pub calibration: Option<PathBuf>,
    /// Vertical field of view when there is no calibration.
    #[serde(default)]
    pub fov_y_deg: Option<f64>,
}

/// The marker: a board of tags, a printed picture, or both in one marker frame.
///
/// With `image`, the marker frame is the picture's: origin at its centre, +X along its
/// width, +Y down it, +Z into the table; `width_m` is its printed width (the height follows
/// from its aspect) and the tags, if any, sit at their `center_m` in that frame (printed on or
/// beside the picture). `image` is relative to the shot and must stay inside its folder.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ShotMarker {
    #[serde(default = "default_family")]
    pub family: String,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub tags: Vec<ShotTag>,
    /// A printed picture tracked by its natural features.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub image: Option<PathBuf>,
    /// The picture's printed width, metres (with `image`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub width_m: Option<f64>,
    /// What replaces the board in the final frames ([`crate::shot_hide`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub hide: Option<String>,
    /// The picture over the board ([`crate::shot_hide`]), relative to the shot.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cover: Option<PathBuf>,
}

fn default_family() -> String {
    "tag36h11".into()
}

/// One tag of the board, marker frame (metres).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ShotTag {
    pub id: u32,
    #[serde(deserialize_with = "center_m")]
    pub center_m: [f64; 2],
    pub size_m: f64,
}

/// Where the prop stands on the marker.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Placement {
    #[serde(default, deserialize_with = "translation_m")]
    pub translation_m: [f32; 3],
    #[serde(default = "yes")]
    pub upright: bool,
    #[serde(default)]
    pub yaw_deg: f32,
    /// Uniform scale of the model about its origin, applied first (positive, finite).
    #[serde(default = "one")]
    pub scale: f32,
}

fn yes() -> bool {
    true
}

fn one() -> f32 {
    1.0
}

impl Default for Placement {
    fn default() -> Self {
        Self {
            translation_m: [0.0; 3],
            upright: true,
            yaw_deg: 0.0,
            scale: 1.0,
        }
    }
}

impl Placement {
    /// `marker_from_prop`: scale about the model's origin, yaw about its up axis, upright,
    /// then translation. A scale of exactly 1 leaves the matrix as it was without one.
    pub fn marker_from_prop(&self) -> Mat4 {
        let upright = if self.upright {
            Mat3::from_cols(Vec3::X, Vec3::NEG_Z, Vec3::Y)
        } else {
            Mat3::IDENTITY
        };
        let placed = Mat4::from_translation(Vec3::from(self.translation_m))
            * Mat4::from_mat3(upright)
            * Mat4::from_rotation_y(self.yaw_deg.to_radians());
        if self.scale == 1.0 {
            placed
        } else {
            placed * Mat4::from_scale(Vec3::splat(self.scale))
        }
    }
}

/// A shot file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Shot {
    /// The shot format's version the file claims (1 when it says nothing).
    #[serde(default = "format_one")]
    pub format: u32,
    pub model: PathBuf,
    #[serde(default)]
    pub animation: Option<String>,
    #[serde(default = "default_fps")]
    pub fps: f32,
    pub key_poses: Vec<KeyPose>,
    /// Name of the key prop in front of the camera (default: the first key pose).
    #[serde(default)]
    pub present_key: Option<String>,
    #[serde(default)]
    pub camera: ShotCamera,
    pub marker: ShotMarker,
    #[serde(default)]
    pub placement: Placement,
    /// How the real prop is removed ([`crate::shot_diminish`]).
    #[serde(default, skip_serializing_if = "ShotDiminish::is_empty")]
    pub diminish: ShotDiminish,
    /// The scan pass before a take ([`crate::shot_scan`]).
    #[serde(default, skip_serializing_if = "crate::shot_scan::ShotScan::is_empty")]
    pub scan: crate::shot_scan::ShotScan,
    /// How live samples become the twin's colour (`[texture]`).
    #[serde(default, skip_serializing_if = "ShotTexture::is_empty")]
    pub texture: ShotTexture,
}

fn format_one() -> u32 {
    SHOT_FORMAT
}

fn default_fps() -> f32 {
    24.0
}

impl Shot {
    /// Reads and checks a shot file (paths inside stay relative to it; see [`Shot::resolve`]).
    /// Only a regular file of at most [`MAX_SHOT_BYTES`] is read.
    pub fn load(path: &Path) -> Result<Self, ShotError> {
        let text = pa_io::read_to_string_regular(path, MAX_SHOT_BYTES, "a shot file")?;
        Self::parse(&text, path)
    }

    /// Parses and checks shot TOML; `path` names it in errors (and is where relative paths
    /// inside start from).
    pub fn parse(text: &str, path: &Path) -> Result<Self, ShotError> {
        keys::check_keys(text, path)?;
        let shot: Shot = toml::from_str(text).map_err(|e| {
            let e = toml_error(text, &e, &keys::field_names());
            ShotError::Parse {
                path: path.into(),
                line: e.line,
                column: e.column,
                message: e.message,
            }
        })?;
        shot.check(path)?;
        Ok(shot)
    }

    /// Writes the shot as TOML.
    pub fn to_toml(&self) -> Result<String, ShotError> {
        toml::to_string_pretty(self).map_err(ShotError::Serialize)
    }

    /// A path named in the shot, relative to the shot file's folder.
    pub fn resolve(shot_path: &Path, p: &Path) -> PathBuf {
        if p.is_absolute() {
            p.into()
        } else {
            shot_path.parent().unwrap_or(Path::new(".")).join(p)
        }
    }

    fn check(&self, path: &Path) -> Result<(), ShotError> {
        let bad = |message: String| ShotError::Invalid {
            path: path.into(),
            message,
        };
        if self.key_poses.is_empty() {
            return Err(bad("a shot needs at least one [[key_poses]] entry".into()));
        }
        if !(self.fps.is_finite() && self.fps > 0.0 && self.fps <= 1000.0) {
            return Err(bad(format!("fps must be in (0, 1000], got {}", self.fps)));
        }
        if let Some(k) = &self.present_key {
            if !self.key_poses.iter().any(|p| &p.name == k) {
                return Err(bad(format!(
                    "present_key {k:?} is not one of the key poses"
                )));
            }
        }
        let mut names = HashSet::new();
        for k in &self.key_poses {
            if !names.insert(k.name.as_str()) {
                return Err(bad(format!("key pose {:?} is named twice", k.name)));
            }
        }
        match (&self.marker.image, self.marker.width_m) {
            (None, None) if self.marker.tags.is_empty() => {
                return Err(bad(
                    "the marker needs at least one tag ([[marker.tags]]) or a picture ([marker] image and width_m)".into(),
                ));
            }
            (None, None) => {}
            (Some(_), None) => {
                return Err(bad(
                    "[marker] image needs width_m, the picture's printed width in metres".into(),
                ));
            }
            (None, Some(_)) => {
                return Err(bad(
                    "[marker] width_m is the width of a picture marker: give image too".into(),
                ));
            }
            (Some(_), Some(w)) => {
                if !(w.is_finite() && w > 0.0 && w <= 100.0) {
                    return Err(bad(format!(
                        "[marker] width_m must be a printed width in (0, 100] metres, got {w}"
                    )));
                }
            }
        }
        // The value is not repeated (a file that is not ours may have parsed this far).
        let family: pa_track::TagFamily = self.marker.family.parse().map_err(|_| {
            let known: Vec<&str> = pa_track::TagFamily::ALL.iter().map(|f| f.name()).collect();
            bad(format!(
                "[marker] family is not a tag family (one of {})",
                known.join(", ")
            ))
        })?;
        let codes = pa_track::family_layout(family)
            .map_err(|e| bad(format!("[marker] family: {e}")))?
            .id_count;
        let mut ids = HashSet::new();
        for (i, t) in self.marker.tags.iter().enumerate() {
            let at = format!("[[marker.tags]] {} (id {})", i + 1, t.id);
            if t.id >= codes {
                return Err(bad(format!(
                    "{at}: {family} has no id {} (ids 0..={})",
                    t.id,
                    codes.saturating_sub(1)
                )));
            }
            if !ids.insert(t.id) {
                return Err(bad(format!("{at}: tag id {} is on the board twice", t.id)));
            }
            if !(t.size_m.is_finite() && t.size_m > 0.0) {
                return Err(bad(format!("{at}: size_m is {} m", t.size_m)));
            }
            if let Some(axis) = t.center_m.iter().position(|v| !v.is_finite()) {
                return Err(bad(format!(
                    "{at}: center_m[{axis}] is not a finite number"
                )));
            }
        }
        let mut marker_ids = HashSet::new();
        for k in &self.key_poses {
            let Some(id) = k.marker_id else { continue };
            if ids.contains(&id) {
                return Err(bad(format!(
                    "key pose {:?}: marker_id {id} is also a tag of the board",
                    k.name
                )));
            }
            if !marker_ids.insert(id) {
                return Err(bad(format!(
                    "key pose {:?}: marker_id {id} is used by another key pose",
                    k.name
                )));
            }
        }
        if let Some(fov) = self.camera.fov_y_deg {
            if !(fov.is_finite() && fov > 1.0 && fov < 179.0) {
                return Err(bad(format!(
                    "[camera] fov_y_deg must be in (1, 179), got {fov}"
                )));
            }
        }
        if self.camera.calibration.is_none() && self.camera.fov_y_deg.is_none() {
            return Err(bad(
                "[camera] needs calibration = \"FILE\" or fov_y_deg".into()
            ));
        }
        let p = &self.placement;
        if let Some(axis) = p.translation_m.iter().position(|v| !v.is_finite()) {
            return Err(bad(format!(
                "[placement] translation_m[{axis}] is not a finite number"
            )));
        }
        if !p.yaw_deg.is_finite() {
            return Err(bad("[placement] yaw_deg is not a finite number".into()));
        }
        if !(p.scale.is_finite() && p.scale > 0.0) {
            return Err(bad(format!(
                "[placement] scale must be a positive finite number, got {}",
                p.scale
            )));
        }
        crate::shot_diminish::check(&self.diminish, path)?;
        crate::shot_hide::check(self, path)
    }

    /// Checks the shot against its model: the clip exists, every key frame is inside the
    /// clip, and the model has something to animate. Returns the animation index.
    pub fn check_model(&self, path: &Path, model: &pa_model::Model) -> Result<usize, ShotError> {
        let bad = |message: String| ShotError::Invalid {
            path: path.into(),
            message,
        };
        if model.animations.is_empty() {
            return Err(bad(format!(
                "model {} has no animation: there are no in-betweens to make",
                model.path.display()
            )));
        }
        let anim = match &self.animation {
            Some(a) => model.find_animation(a).map_err(|e| bad(e.to_string()))?,
            None => 0,
        };
        if model.skins.is_empty() {
            log::warn!(
                "{}: model {} has no skin; only node animation and morph targets will move it",
                path.display(),
                model.path.display()
            );
        }
        let last = (model.animations[anim].duration_s * self.fps).round() as u32;
        for k in &self.key_poses {
            if k.frame > last {
                return Err(bad(format!(
                    "key pose {:?} is at frame {}, past the clip's end (frame {last} at {} fps)",
                    k.name, k.frame, self.fps
                )));
            }
        }
        Ok(anim)
    }

    /// The index of the key pose in front of the camera.
    pub fn present_key_index(&self) -> usize {
        self.present_key
            .as_ref()
            .and_then(|k| self.key_poses.iter().position(|p| &p.name == k))
            .unwrap_or(0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const SHOT: &str = r#"
model = "prop.glb"
animation = "Animate"
fps = 24.0

[[key_poses]]
name = "A"
frame = 0

[[key_poses]]
name = "B"
frame = 24

[camera]
fov_y_deg = 45.0

[marker]
[[marker.tags]]
id = 0
center_m = [0.0, 0.0]
size_m = 0.05
"#;

    fn write(text: &str) -> (tempfile::TempDir, PathBuf) {
        let dir = tempfile::tempdir().expect("tempdir");
        let p = dir.path().join("shot.toml");
        std::fs::write(&p, text).expect("write");
        (dir, p)
    }

    #[test]
    fn round_trip_and_defaults() {
        let (_d, p) = write(SHOT);
        let shot = Shot::load(&p).expect("valid");
        assert_eq!(shot.key_poses.len(), 2);
        assert_eq!(shot.present_key_index(), 0);
        assert_eq!(shot.marker.family, "tag36h11");
        let again: Shot = toml::from_str(&shot.to_toml().expect("toml")).expect("parse");
        assert_eq!(again, shot);
        // Upright placement: prop up (+Y) is marker -Z (out of the table).
        let m = shot.placement.marker_from_prop();
        assert!((m.transform_vector3(Vec3::Y) - Vec3::NEG_Z).length() < 1e-6);
        assert!((m.transform_vector3(Vec3::Z) - Vec3::Y).length() < 1e-6);
    }

    #[test]
    fn texture_table_sets_the_look_and_refuses_unknown_keys() {
        let (_d, p) = write(SHOT);
        let lit = Shot::load(&p).expect("valid");
        assert_eq!(lit.texture.look(), crate::ar::LiveLook::RELIT_FEATHERED);
        assert!(!lit.to_toml().expect("toml").contains("[texture]"));

        let (_d, p) = write(&format!(
            "{SHOT}\n[texture]\nrelight = false\nfeather = false\n"
        ));
        let plain = Shot::load(&p).expect("valid");
        assert_eq!(plain.texture.look(), crate::ar::LiveLook::PLAIN);
        let again: Shot = toml::from_str(&plain.to_toml().expect("toml")).expect("parse");
        assert_eq!(again, plain);

        // One key alone keeps the other's default.
        let (_d, p) = write(&format!("{SHOT}\n[texture]\nfeather = false\n"));
        let relit = Shot::load(&p).expect("valid");
        assert!(relit.texture.relight && !relit.texture.feather);
        // The sun off: relit with the first-order light.
        let (_d, p) = write(&format!("{SHOT}\n[texture]\nsun = false\n"));
        let first_order = Shot::load(&p).expect("valid").texture.look();
        assert!(first_order.relight && first_order.feather && !first_order.sun);
        // The grazing reflection off; and off with relighting, which it belongs to.
        let (_d, p) = write(&format!("{SHOT}\n[texture]\ngrazing = false\n"));
        let matte = Shot::load(&p).expect("valid").texture.look();
        assert!(matte.relight && matte.sun && !matte.grazing);
        assert!(!plain.texture.look().grazing);

        let (_d, p) = write(&format!("{SHOT}\n[texture]\nrelit = true\n"));
        let err = Shot::load(&p).expect_err("unknown key").to_string();
        assert!(err.contains("texture.relit"), "{err}");
    }

    #[test]
    fn bad_shots_say_what_is_wrong() {
        for (edit, needle) in [
            (SHOT.replace("fov_y_deg = 45.0", ""), "calibration"),
            (SHOT.replace("fps = 24.0", "fps = -1.0"), "fps"),
            (format!("present_key = \"Z\"\n{SHOT}"), "present_key"),
            (SHOT.replace("size_m = 0.05", "size_m = 0.0"), "size"),
            ("model = 3".to_string(), "not a valid shot"),
        ] {
            let (_d, p) = write(&edit);
            let e = Shot::load(&p).expect_err(needle).to_string();
            assert!(e.contains(needle) && e.contains("shot.toml"), "{e}");
        }
    }

    /// Line and column (1-based) of the first occurrence of `needle` in `text`.
    fn position_of(text: &str, needle: &str) -> (usize, usize) {
        let at = text.find(needle).expect("needle in text");
        pa_camera::diag::line_column(text, at)
    }

    #[test]
    fn unknown_keys_are_refused_with_name_position_and_format() {
        let placed = format!("{SHOT}\n[placement]\nyaw_deg = 10.0\n");
        for (text, dotted, needle, hint) in [
            (
                SHOT.replace("[marker]\n", "[marker]\nimgae = \"x.png\"\n"),
                "marker.imgae",
                "imgae",
                Some("image"),
            ),
            (
                format!("{SHOT}\n[placment]\nyaw_deg = 10.0\n"),
                "placment",
                "placment",
                Some("placement"),
            ),
            (
                placed.replace("yaw_deg = 10.0", "yaw_degs = 10.0"),
                "placement.yaw_degs",
                "yaw_degs",
                Some("yaw_deg"),
            ),
            (
                SHOT.replace("frame = 24", "frame = 24\nmarkerid = 3"),
                "key_poses.markerid",
                "markerid",
                Some("marker_id"),
            ),
            (
                SHOT.replace("size_m = 0.05", "size_m = 0.05\nrotation_deg = 5.0"),
                "marker.tags.rotation_deg",
                "rotation_deg",
                None,
            ),
            (
                format!("placement.scael = 2.0\n{SHOT}"),
                "placement.scael",
                "scael",
                Some("scale"),
            ),
            (
                format!("modle = \"m.glb\"\n{SHOT}"),
                "modle",
                "modle",
                Some("model"),
            ),
        ] {
            let (_d, p) = write(&text);
            let err = Shot::load(&p).expect_err(dotted);
            let ShotError::UnknownKey {
                line,
                column,
                key,
                format,
                suggestion,
                ..
            } = &err
            else {
                panic!("{dotted}: not an unknown key: {err}");
            };
            assert_eq!(key.as_deref(), Some(dotted));
            assert_eq!((*line, *column), position_of(&text, needle), "{dotted}");
            assert_eq!(*format, 1);
            assert_eq!(*suggestion, hint, "{dotted}");
            let msg = err.to_string();
            assert!(
                msg.contains(&format!(
                    "shot.toml:{line}:{column}: unknown key `{dotted}`"
                )) && msg.contains("shot format 1"),
                "{msg}"
            );
        }
    }

    #[test]
    fn the_format_is_claimed_checked_and_kept() {
        let (_d, p) = write(&format!("format = 1\n{SHOT}"));
        let shot = Shot::load(&p).expect("format 1");
        assert_eq!(shot.format, 1);
        let (_d, p) = write(SHOT);
        assert_eq!(Shot::load(&p).expect("no format").format, 1);
        assert!(shot.to_toml().expect("toml").starts_with("format = 1\n"));
        // A newer format is refused before its keys are looked at.
        let text = format!("{SHOT}\n[shadow]\nstrength = 1.0\n").replace("fps", "format = 2\nfps");
        let (_d, p) = write(&text);
        let err = Shot::load(&p).expect_err("format 2");
        assert!(
            matches!(err, ShotError::NewerFormat { format: 2, .. }),
            "{err}"
        );
        let (line, column) = position_of(&text, "format");
        assert_eq!(
            err.to_string(),
            format!(
                "{}:{line}:{column}: written for shot format 2; this propsalive reads format 1",
                p.display()
            )
        );
        for bad in [
            "format = 0",
            "format = -3",
            "format = \"1\"",
            "format = 1.0",
        ] {
            let (_d, p) = write(&format!("{bad}\n{SHOT}"));
            let e = Shot::load(&p).expect_err(bad).to_string();
            assert!(
                e.contains("shot.toml:1:1:") && e.contains("whole number from 1 to 1"),
                "{bad}: {e}"
            );
        }
    }

    /// A file that is not a shot may parse as TOML: a key that is not a plain name is not
    /// repeated in the message.
    #[test]
    fn strange_keys_are_not_echoed() {
        let (_d, p) = write(&format!("\"root:x:0:0 secret\" = 1\n{SHOT}"));
        let e = Shot::load(&p).expect_err("unknown").to_string();
        assert!(e.contains("shot.toml:1:1: an unknown key"), "{e}");
        assert!(!e.contains("secret") && !e.contains("root"), "{e}");
    }

    #[test]
    fn scale_is_checked_and_scales_about_the_origin_first() {
        for bad in ["0.0", "-1.0", "nan", "inf"] {
            let (_d, p) = write(&format!("{SHOT}\n[placement]\nscale = {bad}\n"));
            let e = Shot::load(&p).expect_err(bad).to_string();
            assert!(
                e.contains("[placement] scale must be a positive finite"),
                "{e}"
            );
        }
        let text = format!(
            "{SHOT}\n[placement]\nscale = 2.5\nyaw_deg = 30.0\ntranslation_m = [0.01, 0.02, -0.003]\n"
        );
        let (_d, p) = write(&text);
        let shot = Shot::load(&p).expect("scaled");
        assert_eq!(shot.placement.scale, 2.5);
        let unscaled = Placement {
            scale: 1.0,
            ..shot.placement.clone()
        };
        // The scaled placement of a point is the unit placement of the scaled point.
        for q in [Vec3::ZERO, Vec3::X, Vec3::new(0.02, -0.05, 0.07)] {
            let a = shot.placement.marker_from_prop().transform_point3(q);
            let b = unscaled.marker_from_prop().transform_point3(q * 2.5);
            assert!((a - b).length() < 1e-6, "{q}: {a} vs {b}");
        }
        // The origin stays where the translation puts it.
        let o = shot
            .placement
            .marker_from_prop()
            .transform_point3(Vec3::ZERO);
        assert!((o - Vec3::new(0.01, 0.02, -0.003)).length() < 1e-7);
        // Scale 1 is the matrix without a scale, bit for bit.
        let mut m = unscaled.marker_from_prop().to_cols_array();
        let r = Mat4::from_translation(Vec3::new(0.01, 0.02, -0.003))
            * Mat4::from_mat3(Mat3::from_cols(Vec3::X, Vec3::NEG_Z, Vec3::Y))
            * Mat4::from_rotation_y(30f32.to_radians());
        assert_eq!(m, r.to_cols_array());
        m[0] = 0.0;
        assert_ne!(m, r.to_cols_array());
    }

    #[test]
    fn key_pose_past_the_clip_end_and_models_without_animation() {
        let (_d, p) = write(&SHOT.replace("frame = 24", "frame = 480"));
        let shot = Shot::load(&p).expect("valid");
        let model = tiny_animated_model();
        let e = shot
            .check_model(&p, &model)
            .expect_err("past the end")
            .to_string();
        assert!(
            e.contains("past the clip's end") && e.contains("480"),
            "{e}"
        );
        let mut still = model.clone();
        still.animations.clear();
        let e = shot
            .check_model(&p, &still)
            .expect_err("no animation")
            .to_string();
        assert!(e.contains("no animation"), "{e}");
    }

    /// A model without a skin is a defined case, not an error: node animation and morph
    /// targets still move it (a warning says so).
    #[test]
    fn model_without_skin_is_accepted() {
        let (_d, p) = write(SHOT);
        let shot = Shot::load(&p).expect("valid");
        let model = tiny_animated_model();
        assert!(model.skins.is_empty());
        assert_eq!(shot.check_model(&p, &model).expect("accepted"), 0);
    }

    /// A tiny animated model (one node, one translation channel) built from glTF JSON.
    fn tiny_animated_model() -> pa_model::Model {
        use base64::Engine as _;
        let mut bin = Vec::new();
        for v in [0f32, 0., 0., 1., 0., 0., 0., 1., 0.] {
            bin.extend(v.to_le_bytes());
        }
        for t in [0f32, 2.0] {
            bin.extend(t.to_le_bytes());
        }
        for v in [0f32, 0., 0., 1., 0., 0.] {
            bin.extend(v.to_le_bytes());
        }
        let uri = format!(
            "data:application/octet-stream;base64,{}",
            base64::engine::general_purpose::STANDARD.encode(&bin)
        );
        let doc = serde_json::json!({
            "asset": {"version": "2.0"}, "scenes": [{"nodes": [0]}],
            "nodes": [{"mesh": 0}],
            "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
            "buffers": [{"byteLength": bin.len(), "uri": uri}],
            "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 36},
                            {"buffer": 0, "byteOffset": 36, "byteLength": 8},
                            {"buffer": 0, "byteOffset": 44, "byteLength": 24}],
            "accessors": [
                {"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                 "min": [0, 0, 0], "max": [1, 1, 0]},
                {"bufferView": 1, "componentType": 5126, "count": 2, "type": "SCALAR",
                 "min": [0.0], "max": [2.0]},
                {"bufferView": 2, "componentType": 5126, "count": 2, "type": "VEC3"}],
            "animations": [{"name": "Animate", "channels": [{"sampler": 0,
                "target": {"node": 0, "path": "translation"}}],
                "samplers": [{"input": 1, "output": 2}]}]
        });
        let bytes = serde_json::to_vec(&doc).expect("json");
        pa_model::Model::from_slice(&bytes, "tiny.gltf", None, &Default::default())
            .expect("tiny model")
    }

    #[test]
    fn picture_markers_parse_alone_or_with_tags_and_bad_ones_are_refused() {
        let picture_only = SHOT.replace(
            "[marker]\n[[marker.tags]]\nid = 0\ncenter_m = [0.0, 0.0]\nsize_m = 0.05\n",
            "[marker]\nimage = \"floor.png\"\nwidth_m = 0.3\n",
        );
        assert!(!picture_only.contains("marker.tags"), "{picture_only}");
        let (_d, p) = write(&picture_only);
        let shot = Shot::load(&p).expect("a picture marker alone");
        assert!(shot.marker.tags.is_empty());
        assert_eq!(shot.marker.image.as_deref(), Some(Path::new("floor.png")));
        assert_eq!(shot.marker.width_m, Some(0.3));
        // Round trip: the written shot reads back the same.
        let again = Shot::parse(&shot.to_toml().expect("toml"), &p).expect("reads back");
        assert_eq!(again, shot);

        let both = SHOT.replace(
            "[marker]\n",
            "[marker]\nimage = \"floor.png\"\nwidth_m = 0.3\n",
        );
        let (_d, p) = write(&both);
        let shot = Shot::load(&p).expect("picture and tags");
        assert_eq!(shot.marker.tags.len(), 1);
        assert!(shot.marker.image.is_some());

        let no_marker = SHOT.replace(
            "[[marker.tags]]\nid = 0\ncenter_m = [0.0, 0.0]\nsize_m = 0.05\n",
            "",
        );
        for (text, needle) in [
            (no_marker, "at least one tag"),
            (
                picture_only.replace("width_m = 0.3\n", ""),
                "image needs width_m",
            ),
            (
                SHOT.replace("[marker]\n", "[marker]\nwidth_m = 0.3\n"),
                "give image too",
            ),
            (picture_only.replace("0.3", "-1.0"), "width_m must be"),
            (picture_only.replace("0.3", "nan"), "width_m must be"),
        ] {
            let (_d, p) = write(&text);
            let e = Shot::load(&p).expect_err(needle).to_string();
            assert!(
                e.contains(needle) && e.contains("shot.toml"),
                "{needle}: {e}"
            );
        }
    }
}
