//! The shot: what an AR take needs to know, written as a TOML file.
//!
//! ```toml
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
//! [[marker.tags]]               # board layout, marker frame (metres); one entry = one tag
//! id = 0
//! center_m = [0.0, 0.0]
//! size_m = 0.05
//!
//! [placement]                   # marker_from_prop
//! translation_m = [0.0, 0.0, 0.0]
//! upright = true                # prop +Y up (marker -Z), prop front +Z toward marker +Y
//! yaw_deg = 0.0                 # then a turn about the prop's up axis
//!
//! [diminish]                    # optional: see crate::shot_diminish
//! fill = "rays"
//! ```
//!
//! Hostile input: the file is read through [`pa_io`] (a regular file of at most
//! [`MAX_SHOT_BYTES`]; a FIFO or a device is refused at once), every number must be finite,
//! fixed-size vectors must have exactly their length, tag ids must be codes of the family and
//! appear once, and a parse error gives the line, the column and what was expected, never the
//! file's text.

use std::collections::HashSet;
use std::path::{Path, PathBuf};

use glam::{Mat3, Mat4, Vec3};
use pa_camera::diag::{fmt_position, toml_error};
use serde::{Deserialize, Deserializer, Serialize};

pub use crate::shot_diminish::ShotDiminish;

/// The largest shot file read (4 MiB): a shot is a few hundred bytes, a board of every
/// tag36h11 code about 40 KiB.
pub const MAX_SHOT_BYTES: u64 = 4 << 20;

/// The field names of the shot, which parse errors may repeat.
const FIELDS: &[&str] = &[
    "model",
    "animation",
    "fps",
    "key_poses",
    "name",
    "frame",
    "marker_id",
    "present_key",
    "camera",
    "calibration",
    "fov_y_deg",
    "marker",
    "family",
    "tags",
    "id",
    "center_m",
    "size_m",
    "placement",
    "translation_m",
    "upright",
    "yaw_deg",
    // [diminish] (crate::shot_diminish::FIELDS)
    "diminish",
    "fill",
    "clean_plate",
    "plate_frames",
    "dilation_px",
    "shadows",
];

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

/// The marker board.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ShotMarker {
    #[serde(default = "default_family")]
    pub family: String,
    pub tags: Vec<ShotTag>,
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
}

fn yes() -> bool {
    true
}

impl Default for Placement {
    fn default() -> Self {
        Self {
            translation_m: [0.0; 3],
            upright: true,
            yaw_deg: 0.0,
        }
    }
}

impl Placement {
    /// `marker_from_prop`.
    pub fn marker_from_prop(&self) -> Mat4 {
        let upright = if self.upright {
            Mat3::from_cols(Vec3::X, Vec3::NEG_Z, Vec3::Y)
        } else {
            Mat3::IDENTITY
        };
        Mat4::from_translation(Vec3::from(self.translation_m))
            * Mat4::from_mat3(upright)
            * Mat4::from_rotation_y(self.yaw_deg.to_radians())
    }
}

/// A shot file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Shot {
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
        let shot: Shot = toml::from_str(text).map_err(|e| {
            let e = toml_error(text, &e, FIELDS);
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
        if self.marker.tags.is_empty() {
            return Err(bad("the marker needs at least one tag".into()));
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
        crate::shot_diminish::check(&self.diminish, path)
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
}
