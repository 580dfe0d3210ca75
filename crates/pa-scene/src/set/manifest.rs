//! The set manifest (`manifest.json`): what an external renderer wrote for a take, read with
//! every field checked. Format `propsalive-set/1` (documented in `scripts/blender/README.md`):
//!
//! ```json
//! { "format": "propsalive-set/1", "renderer": "Blender 3.4.1 Cycles ...",
//!   "width": 640, "height": 360,
//!   "intrinsics": { "fx": 434.6, "fy": 434.6, "cx": 319.5, "cy": 179.5 },
//!   "model": { "builtin": "bust" } | { "path": "/abs/or/relative/to/set/model.gltf" },
//!   "animation": 0,
//!   "marker_from_prop": [[1,0,0,0],[0,0,1,0],[0,-1,0,0],[0,0,0,1]],
//!   "board": { "family": "tag36h11", "tags": [ { "id": 0, "center_m": [-0.085, -0.085],
//!              "size_m": 0.045, "rotation_rad": 0.0 } ] },
//!   "plate": { "image": "plate/0000.png", "camera_from_marker": [[...4 rows...]] },
//!   "table_m": 1.6,
//!   "frames": [ { "index": 0, "time_s": 0.0, "key_time_s": 0.0,
//!                 "camera_from_marker": [[r00,r01,r02,tx],[...],[...],[0,0,0,1]],
//!                 "input": "input/0000.png", "truth": "truth/0000.png",
//!                 "key_mask": "mask_key/0000.png", "truth_mask": "mask_truth/0000.png",
//!                 "plate": "plate/0000.png" } ] }
//! ```
//!
//! Matrices are row-major 4x4 (rows of four numbers), `camera_from_marker` in OpenCV camera
//! axes and the marker frame of `pa-track` (metres). Image paths are relative to the set
//! folder and may not leave it. Every problem is a [`SceneError::Set`] naming the file and
//! the field.

use std::io::Read as _;
use std::path::{Component, Path, PathBuf};

use glam::{DVec2, Mat4, Vec4};
use pa_camera::Intrinsics;
use pa_track::board::BoardTag;
use pa_track::{Board, TagFamily};
use serde_json::Value;

use crate::error::SetProblem;
use crate::SceneError;

/// The format string of the manifests this reader understands.
pub const FORMAT: &str = "propsalive-set/1";
/// The largest manifest read, bytes.
pub const MAX_MANIFEST_BYTES: u64 = 16 << 20;
/// The largest image of a set read, bytes.
pub const MAX_IMAGE_BYTES: u64 = 64 << 20;
/// The most frames a manifest may list.
pub const MAX_FRAMES: usize = 10_000;
/// The largest image side a set may have, pixels.
pub const MAX_SIDE: u32 = 8192;

/// The model of a set.
#[derive(Debug, Clone, PartialEq)]
pub enum SetModel {
    /// The built-in bust of [`crate::prop`] with its default spec.
    BuiltinBust,
    /// A glTF file (absolute, or relative to the set folder).
    Path(PathBuf),
}

/// One frame of a set.
#[derive(Debug, Clone, PartialEq)]
pub struct SetFrame {
    pub index: u32,
    /// Animation time of the in-between (the ground truth), seconds.
    pub time_s: f32,
    /// Animation time of the key prop present in the input, seconds.
    pub key_time_s: f32,
    /// The true camera pose, OpenCV axes, marker frame.
    pub camera_from_marker: Mat4,
    /// Image files, relative to the set folder.
    pub input: PathBuf,
    pub truth: PathBuf,
    pub key_mask: PathBuf,
    pub truth_mask: PathBuf,
    pub plate: Option<PathBuf>,
}

/// A parsed manifest.
#[derive(Debug, Clone, PartialEq)]
pub struct SetManifest {
    /// The folder the manifest was read from.
    pub dir: PathBuf,
    pub renderer: String,
    pub width: u32,
    pub height: u32,
    pub intrinsics: Intrinsics,
    pub model: SetModel,
    pub animation: usize,
    pub marker_from_prop: Mat4,
    pub board: Board,
    /// The clean plate for the plate fill: image (relative path) and its camera.
    pub plate: Option<(PathBuf, Mat4)>,
    /// Side of the square table the board lies on (centred on the marker), metres: where
    /// the background is the table plane (the flicker metric counts only those pixels).
    pub table_m: Option<f32>,
    pub frames: Vec<SetFrame>,
}

fn problem(file: &Path, problem: SetProblem) -> SceneError {
    SceneError::Set {
        file: file.to_path_buf(),
        problem,
    }
}

/// Reads a regular file of at most `limit` bytes.
pub fn read_bounded(path: &Path, limit: u64) -> Result<Vec<u8>, SceneError> {
    let io = |e: std::io::Error| {
        problem(
            path,
            SetProblem::Io {
                kind: e.kind(),
                message: e.to_string(),
            },
        )
    };
    let file = std::fs::File::open(path).map_err(io)?;
    let meta = file.metadata().map_err(io)?;
    if !meta.is_file() {
        return Err(problem(path, SetProblem::NotAFile));
    }
    if meta.len() > limit {
        return Err(problem(
            path,
            SetProblem::TooLarge {
                bytes: meta.len(),
                limit,
            },
        ));
    }
    let mut bytes = Vec::new();
    file.take(limit + 1).read_to_end(&mut bytes).map_err(io)?;
    if bytes.len() as u64 > limit {
        return Err(problem(
            path,
            SetProblem::TooLarge {
                bytes: bytes.len() as u64,
                limit,
            },
        ));
    }
    Ok(bytes)
}

/// An RGBA8 image of a set, `width x height`.
pub fn read_rgba8(path: &Path, width: u32, height: u32) -> Result<Vec<u8>, SceneError> {
    let bytes = read_bounded(path, MAX_IMAGE_BYTES)?;
    let mut reader = image::ImageReader::new(std::io::Cursor::new(bytes));
    let mut limits = image::Limits::default();
    limits.max_image_width = Some(MAX_SIDE);
    limits.max_image_height = Some(MAX_SIDE);
    reader.limits(limits);
    let reader = reader.with_guessed_format().map_err(|e| {
        problem(
            path,
            SetProblem::Image {
                message: e.to_string(),
            },
        )
    })?;
    let img = reader.decode().map_err(|e| {
        problem(
            path,
            SetProblem::Image {
                message: e.to_string(),
            },
        )
    })?;
    if (img.width(), img.height()) != (width, height) {
        return Err(problem(
            path,
            SetProblem::ImageSize {
                width: img.width(),
                height: img.height(),
                expected_width: width,
                expected_height: height,
            },
        ));
    }
    Ok(img.to_rgba8().into_raw())
}

/// A mask image of a set: set where the red channel is at least 128.
pub fn read_mask(path: &Path, width: u32, height: u32) -> Result<Vec<bool>, SceneError> {
    Ok(read_rgba8(path, width, height)?
        .chunks_exact(4)
        .map(|p| p[0] >= 128)
        .collect())
}

/// The reader's cursor: the file and the field being read, for errors.
struct Ctx<'a> {
    file: &'a Path,
}

impl Ctx<'_> {
    fn err(&self, field: &str, reason: &'static str) -> SceneError {
        problem(
            self.file,
            SetProblem::Field {
                field: field.to_string(),
                reason,
            },
        )
    }
    fn get<'v>(&self, v: &'v Value, key: &str, field: &str) -> Result<&'v Value, SceneError> {
        v.get(key).ok_or_else(|| self.err(field, "missing"))
    }
    fn num(&self, v: &Value, field: &str) -> Result<f64, SceneError> {
        v.as_f64()
            .filter(|x| x.is_finite())
            .ok_or_else(|| self.err(field, "must be a finite number"))
    }
    fn uint(&self, v: &Value, field: &str, max: u64) -> Result<u64, SceneError> {
        let n = v
            .as_u64()
            .ok_or_else(|| self.err(field, "must be a non-negative integer"))?;
        if n > max {
            return Err(self.err(field, "is too large"));
        }
        Ok(n)
    }
    fn str<'v>(&self, v: &'v Value, field: &str) -> Result<&'v str, SceneError> {
        v.as_str()
            .ok_or_else(|| self.err(field, "must be a string"))
    }
    fn arr<'v>(&self, v: &'v Value, field: &str) -> Result<&'v Vec<Value>, SceneError> {
        v.as_array()
            .ok_or_else(|| self.err(field, "must be an array"))
    }
    /// A path inside the set folder: relative, no `..`, no root.
    fn rel_path(&self, v: &Value, field: &str) -> Result<PathBuf, SceneError> {
        let s = self.str(v, field)?;
        let p = PathBuf::from(s);
        if s.is_empty()
            || p.components()
                .any(|c| !matches!(c, Component::Normal(_) | Component::CurDir))
        {
            return Err(self.err(field, "must be a relative path inside the set folder"));
        }
        Ok(p)
    }
    /// A row-major 4x4 affine matrix (last row 0 0 0 1); `rigid`: its rotation orthonormal
    /// and proper.
    fn matrix(&self, v: &Value, field: &str, rigid: bool) -> Result<Mat4, SceneError> {
        let rows = self.arr(v, field)?;
        if rows.len() != 4 {
            return Err(self.err(field, "must have 4 rows"));
        }
        let mut m = [[0f64; 4]; 4];
        for (r, row) in rows.iter().enumerate() {
            let row = self.arr(row, field)?;
            if row.len() != 4 {
                return Err(self.err(field, "each row must have 4 numbers"));
            }
            for (c, x) in row.iter().enumerate() {
                m[r][c] = self.num(x, field)?;
                if m[r][c].abs() > 1e6 {
                    return Err(self.err(field, "has an entry beyond 1e6"));
                }
            }
        }
        // f32 writers leave a last row like (-0, 0, -0, 0.99999994).
        if m[3]
            .iter()
            .zip([0.0, 0.0, 0.0, 1.0])
            .any(|(a, b)| (a - b).abs() > 1e-5)
        {
            return Err(self.err(field, "last row must be 0 0 0 1"));
        }
        m[3] = [0.0, 0.0, 0.0, 1.0];
        let col = |c: usize| {
            Vec4::new(
                m[0][c] as f32,
                m[1][c] as f32,
                m[2][c] as f32,
                m[3][c] as f32,
            )
        };
        let mat = Mat4::from_cols(col(0), col(1), col(2), col(3));
        let det = mat.determinant();
        if !(det.is_finite() && det.abs() > 1e-12) {
            return Err(self.err(field, "is singular"));
        }
        if rigid {
            for i in 0..3 {
                for j in 0..3 {
                    let dot: f64 = (0..3).map(|k| m[k][i] * m[k][j]).sum();
                    let want = if i == j { 1.0 } else { 0.0 };
                    if (dot - want).abs() > 1e-3 {
                        return Err(self.err(field, "rotation is not orthonormal"));
                    }
                }
            }
            if det < 0.0 {
                return Err(self.err(field, "rotation is a reflection"));
            }
        }
        Ok(mat)
    }
}

impl SetManifest {
    /// Reads `dir/manifest.json`.
    pub fn read(dir: &Path) -> Result<Self, SceneError> {
        let file = dir.join("manifest.json");
        let bytes = read_bounded(&file, MAX_MANIFEST_BYTES)?;
        Self::parse(&bytes, dir, &file)
    }

    /// Parses manifest bytes; `file` names them in errors, `dir` is the set folder.
    pub fn parse(bytes: &[u8], dir: &Path, file: &Path) -> Result<Self, SceneError> {
        let v: Value = serde_json::from_slice(bytes).map_err(|e| {
            problem(
                file,
                SetProblem::Json {
                    line: e.line(),
                    column: e.column(),
                    message: e.to_string(),
                },
            )
        })?;
        let cx = Ctx { file };
        let format = cx.str(cx.get(&v, "format", "format")?, "format")?;
        if format != FORMAT {
            return Err(cx.err("format", "is not propsalive-set/1"));
        }
        let renderer = match v.get("renderer") {
            Some(r) => cx.str(r, "renderer")?.chars().take(200).collect(),
            None => String::new(),
        };
        let width = cx.uint(cx.get(&v, "width", "width")?, "width", MAX_SIDE as u64)? as u32;
        let height = cx.uint(cx.get(&v, "height", "height")?, "height", MAX_SIDE as u64)? as u32;
        if width == 0 || height == 0 {
            return Err(cx.err("width", "width and height must be positive"));
        }
        let k = cx.get(&v, "intrinsics", "intrinsics")?;
        let kn = |name: &str| -> Result<f64, SceneError> {
            let field = format!("intrinsics.{name}");
            cx.num(cx.get(k, name, &field)?, &field)
        };
        let intrinsics = Intrinsics {
            fx: kn("fx")?,
            fy: kn("fy")?,
            cx: kn("cx")?,
            cy: kn("cy")?,
            width,
            height,
        };
        intrinsics
            .validate()
            .map_err(|_| cx.err("intrinsics", "are not a usable pinhole camera"))?;
        let m = cx.get(&v, "model", "model")?;
        let model = match (m.get("builtin"), m.get("path")) {
            (Some(b), None) => {
                if cx.str(b, "model.builtin")? != "bust" {
                    return Err(cx.err("model.builtin", "must be \"bust\""));
                }
                SetModel::BuiltinBust
            }
            (None, Some(p)) => {
                let s = cx.str(p, "model.path")?;
                if s.is_empty() {
                    return Err(cx.err("model.path", "is empty"));
                }
                SetModel::Path(PathBuf::from(s))
            }
            _ => return Err(cx.err("model", "needs exactly one of \"builtin\" and \"path\"")),
        };
        let animation = match v.get("animation") {
            Some(a) => cx.uint(a, "animation", 1 << 16)? as usize,
            None => 0,
        };
        let marker_from_prop = cx.matrix(
            cx.get(&v, "marker_from_prop", "marker_from_prop")?,
            "marker_from_prop",
            false,
        )?;
        let board = parse_board(&cx, cx.get(&v, "board", "board")?)?;
        let plate = match v.get("plate") {
            Some(p) if !p.is_null() => Some((
                cx.rel_path(cx.get(p, "image", "plate.image")?, "plate.image")?,
                cx.matrix(
                    cx.get(p, "camera_from_marker", "plate.camera_from_marker")?,
                    "plate.camera_from_marker",
                    true,
                )?,
            )),
            _ => None,
        };
        let table_m = match v.get("table_m") {
            Some(t) if !t.is_null() => {
                let t = cx.num(t, "table_m")?;
                if !(t > 0.0 && t <= 1000.0) {
                    return Err(cx.err("table_m", "must be in (0, 1000] metres"));
                }
                Some(t as f32)
            }
            _ => None,
        };
        let list = cx.arr(cx.get(&v, "frames", "frames")?, "frames")?;
        if list.is_empty() {
            return Err(cx.err("frames", "is empty"));
        }
        if list.len() > MAX_FRAMES {
            return Err(cx.err("frames", "has more than 10000 frames"));
        }
        let mut frames = Vec::with_capacity(list.len());
        for (i, f) in list.iter().enumerate() {
            let field = |name: &str| format!("frames[{i}].{name}");
            let time = |name: &str| -> Result<f32, SceneError> {
                let t = cx.num(cx.get(f, name, &field(name))?, &field(name))?;
                if !(0.0..=1e5).contains(&t) {
                    return Err(cx.err(&field(name), "must be in 0..=100000 seconds"));
                }
                Ok(t as f32)
            };
            let path = |name: &str| cx.rel_path(cx.get(f, name, &field(name))?, &field(name));
            frames.push(SetFrame {
                index: cx.uint(
                    cx.get(f, "index", &field("index"))?,
                    &field("index"),
                    u32::MAX as u64,
                )? as u32,
                time_s: time("time_s")?,
                key_time_s: time("key_time_s")?,
                camera_from_marker: cx.matrix(
                    cx.get(f, "camera_from_marker", &field("camera_from_marker"))?,
                    &field("camera_from_marker"),
                    true,
                )?,
                input: path("input")?,
                truth: path("truth")?,
                key_mask: path("key_mask")?,
                truth_mask: path("truth_mask")?,
                plate: match f.get("plate") {
                    Some(p) if !p.is_null() => Some(cx.rel_path(p, &field("plate"))?),
                    _ => None,
                },
            });
        }
        Ok(Self {
            dir: dir.to_path_buf(),
            renderer,
            width,
            height,
            intrinsics,
            model,
            animation,
            marker_from_prop,
            board,
            plate,
            table_m,
            frames,
        })
    }

    /// The model's path, resolved against the set folder.
    pub fn model_path(&self) -> Option<PathBuf> {
        match &self.model {
            SetModel::Path(p) => Some(self.dir.join(p)),
            SetModel::BuiltinBust => None,
        }
    }
}

fn parse_board(cx: &Ctx<'_>, b: &Value) -> Result<Board, SceneError> {
    let family: TagFamily = cx
        .str(cx.get(b, "family", "board.family")?, "board.family")?
        .parse()
        .map_err(|_| cx.err("board.family", "is not a tag family"))?;
    let list = cx.arr(cx.get(b, "tags", "board.tags")?, "board.tags")?;
    if list.is_empty() || list.len() > 1024 {
        return Err(cx.err("board.tags", "must list 1 to 1024 tags"));
    }
    let mut tags = Vec::new();
    for (i, t) in list.iter().enumerate() {
        let field = |name: &str| format!("board.tags[{i}].{name}");
        let c = cx.arr(
            cx.get(t, "center_m", &field("center_m"))?,
            &field("center_m"),
        )?;
        if c.len() != 2 {
            return Err(cx.err(&field("center_m"), "must be [x, y]"));
        }
        let size_m = cx.num(cx.get(t, "size_m", &field("size_m"))?, &field("size_m"))?;
        if !(size_m > 1e-4 && size_m < 10.0) {
            return Err(cx.err(&field("size_m"), "must be in (0.0001, 10) metres"));
        }
        let center = DVec2::new(
            cx.num(&c[0], &field("center_m"))?,
            cx.num(&c[1], &field("center_m"))?,
        );
        if center.abs().max_element() > 100.0 {
            return Err(cx.err(&field("center_m"), "is more than 100 m from the origin"));
        }
        tags.push(BoardTag {
            id: cx.uint(cx.get(t, "id", &field("id"))?, &field("id"), 1 << 20)? as u32,
            center_m: center,
            size_m,
            rotation_rad: match t.get("rotation_rad") {
                Some(r) => cx.num(r, &field("rotation_rad"))?,
                None => 0.0,
            },
        });
    }
    Ok(Board { family, tags })
}

/// The manifest JSON of a matrix (row-major rows).
pub fn matrix_json(m: Mat4) -> Value {
    let r = |i: usize| {
        let row = m.row(i);
        serde_json::json!([row.x, row.y, row.z, row.w])
    };
    serde_json::json!([r(0), r(1), r(2), r(3)])
}

/// The manifest JSON of a board.
pub fn board_json(board: &Board) -> Value {
    serde_json::json!({
        "family": board.family.to_string(),
        "tags": board.tags.iter().map(|t| serde_json::json!({
            "id": t.id, "center_m": [t.center_m.x, t.center_m.y], "size_m": t.size_m,
            "rotation_rad": t.rotation_rad,
        })).collect::<Vec<_>>(),
    })
}
