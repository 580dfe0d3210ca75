//! The kit: what an external renderer needs to build our set (`propsalive eval --write-kit`).
//!
//! `kit.json` (format `propsalive-kit/1`) lists the image size and OpenCV intrinsics, the
//! model (the built-in bust as `prop.glb`, or a glTF file's path) with its placement
//! `marker_from_prop` (row-major), the board (its tags and `board.png`, the printed sheet at
//! true size), the key pose's animation time and, per frame, the in-between's animation time
//! and the true `camera_from_marker` of a handheld path around the set. The files are returned
//! as bytes; the caller writes them.

use std::path::PathBuf;

use glam::{Mat4, Vec3};
use pa_camera::{camera_from_world_look_at, Intrinsics};
use pa_model::{anim, skin, Model};

use super::manifest::{board_json, matrix_json};
use crate::error::SetProblem;
use crate::prop::{prop_glb, prop_model, PropSpec};
use crate::scene::{board_texture, marker_from_prop, set_board, Rng, BOARD_SHEET_M};
use crate::SceneError;

/// The model of a kit.
#[derive(Debug, Clone, PartialEq)]
pub enum KitModel {
    /// The built-in bust (written as `prop.glb`).
    BuiltinBust,
    /// A glTF file, scaled to `height_m` tall, its footprint centred on the board, turned by
    /// `yaw_deg` about the up axis.
    Gltf {
        path: PathBuf,
        height_m: f32,
        yaw_deg: f32,
    },
}

/// What to build.
#[derive(Debug, Clone, PartialEq)]
pub struct KitSpec {
    pub width: u32,
    pub height: u32,
    pub fov_y_deg: f64,
    pub frames: u32,
    pub seed: u64,
    pub model: KitModel,
}

impl Default for KitSpec {
    fn default() -> Self {
        Self {
            width: 640,
            height: 360,
            fov_y_deg: 45.0,
            frames: 16,
            seed: 1,
            model: KitModel::BuiltinBust,
        }
    }
}

/// A kit's files: name (relative to the kit folder) and bytes.
pub struct Kit {
    pub files: Vec<(&'static str, Vec<u8>)>,
}

/// The model's placement on the board: `marker_from_prop` for a glTF model scaled to
/// `height_m` (its rest pose at time 0 measured), footprint centred, turned by `yaw_deg`.
pub fn placement(model: &Model, height_m: f32, yaw_deg: f32) -> Option<Mat4> {
    let pose = anim::sample(model, 0, 0.0);
    let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
    for p in skin::pose_meshes(model, &pose) {
        for v in &p.positions {
            lo = lo.min(*v);
            hi = hi.max(*v);
        }
    }
    let size = hi - lo;
    if !(size.y.is_finite() && size.y > 1e-9 && height_m > 0.0) {
        return None;
    }
    let s = height_m / size.y;
    let base = Vec3::new(0.5 * (lo.x + hi.x), lo.y, 0.5 * (lo.z + hi.z));
    Some(
        marker_from_prop()
            * Mat4::from_rotation_y(yaw_deg.to_radians())
            * Mat4::from_scale(Vec3::splat(s))
            * Mat4::from_translation(-base),
    )
}

/// The handheld path: an arc of 60 degrees around the front of the prop, rising a little,
/// with smooth jitter; `target_m` is the point looked at (marker frame).
pub fn handheld_path(frames: u32, seed: u64, target_m: Vec3) -> Vec<Mat4> {
    let mut rng = Rng::new(seed);
    let waves: Vec<(f32, f32, f32)> = (0..9)
        .map(|_| {
            (
                0.2 + rng.f32() * 0.6,
                rng.f32() * std::f32::consts::TAU,
                0.5 + rng.f32(),
            )
        })
        .collect();
    (0..frames.max(1))
        .map(|i| {
            let u = if frames > 1 {
                i as f32 / (frames - 1) as f32
            } else {
                0.0
            };
            let j = |k: usize| {
                let (f, p, a) = waves[k];
                a * (f * std::f32::consts::TAU * i as f32 + p).sin()
            };
            let az = (-30.0 + 60.0 * u + 2.0 * j(0)).to_radians();
            let el = (30.0 + 8.0 * u + 1.5 * j(1)).to_radians();
            let d = 0.6 + 0.015 * j(2);
            let eye = Vec3::new(
                d * el.cos() * az.sin(),
                d * el.cos() * az.cos(),
                -d * el.sin(),
            );
            let look = target_m + 0.006 * Vec3::new(j(3), j(4), j(5));
            let up = Vec3::new(0.04 * j(6), 0.0, -1.0).normalize();
            camera_from_world_look_at(eye, look, up).unwrap_or(Mat4::IDENTITY)
        })
        .collect()
}

/// Builds the kit.
pub fn kit(spec: &KitSpec) -> Result<Kit, SceneError> {
    let intrinsics = Intrinsics::from_fov_y(spec.fov_y_deg.to_radians(), spec.width, spec.height)?;
    let board = set_board();
    let mut files: Vec<(&'static str, Vec<u8>)> = Vec::new();
    let (model, model_json, place, height_m) = match &spec.model {
        KitModel::BuiltinBust => {
            let ps = PropSpec::default();
            files.push(("prop.glb", prop_glb(&ps)?));
            (
                prop_model(&ps)?,
                serde_json::json!({"builtin": "bust", "glb": "prop.glb"}),
                marker_from_prop(),
                ps.height_m,
            )
        }
        KitModel::Gltf {
            path,
            height_m,
            yaw_deg,
        } => {
            let model = Model::load(path.clone())?;
            let place = placement(&model, *height_m, *yaw_deg).ok_or_else(|| SceneError::Set {
                file: path.clone(),
                problem: SetProblem::Field {
                    field: "meshes".into(),
                    reason: "have no extent to scale",
                },
            })?;
            let abs = std::fs::canonicalize(path).unwrap_or_else(|_| path.clone());
            (
                model,
                serde_json::json!({"path": abs.to_string_lossy()}),
                place,
                *height_m,
            )
        }
    };
    let duration = model
        .animations
        .first()
        .map(|a| a.duration_s)
        .filter(|d| *d > 0.0)
        .ok_or_else(|| SceneError::Set {
            file: spec_model_path(spec),
            problem: SetProblem::Field {
                field: "animations".into(),
                reason: "has no animation to take in-betweens from",
            },
        })?;
    let n = spec.frames.max(1);
    let path = handheld_path(n, spec.seed, Vec3::new(0.0, 0.0, -0.4 * height_m));
    let frames: Vec<serde_json::Value> = path
        .iter()
        .enumerate()
        .map(|(i, &m)| {
            serde_json::json!({
                "index": i, "time_s": duration * i as f32 / n as f32, "key_time_s": 0.0,
                "camera_from_marker": matrix_json(m),
            })
        })
        .collect();
    let sheet_px = 2080;
    let tex = board_texture(&board, sheet_px)?;
    let img = image::RgbaImage::from_raw(tex.width, tex.height, tex.rgba8).ok_or(
        SceneError::SetFrame {
            frame: 0,
            what: "board texture has the wrong size",
        },
    )?;
    let mut png = Vec::new();
    img.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)?;
    files.push(("board.png", png));
    let json = serde_json::json!({
        "format": "propsalive-kit/1",
        "width": spec.width, "height": spec.height,
        "intrinsics": {"fx": intrinsics.fx, "fy": intrinsics.fy, "cx": intrinsics.cx,
                       "cy": intrinsics.cy},
        "model": model_json, "animation": 0, "animation_duration_s": duration,
        "marker_from_prop": matrix_json(place),
        "board": board_json(&board), "board_png": "board.png", "board_sheet_m": BOARD_SHEET_M,
        "fps": 24, "frames": frames,
    });
    let text = serde_json::to_string_pretty(&json).map_err(|e| SceneError::Set {
        file: "kit.json".into(),
        problem: SetProblem::Json {
            line: e.line(),
            column: e.column(),
            message: e.to_string(),
        },
    })?;
    files.push(("kit.json", text.into_bytes()));
    Ok(Kit { files })
}

fn spec_model_path(spec: &KitSpec) -> PathBuf {
    match &spec.model {
        KitModel::BuiltinBust => "prop.glb".into(),
        KitModel::Gltf { path, .. } => path.clone(),
    }
}
