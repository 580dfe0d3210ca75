//! Export of the tracked camera of a take as an animated glTF 2.0 camera (`camera.gltf`), so
//! artists can finish the shot in their own tools (Blender: File > Import > glTF 2.0).
//!
//! The file is self-contained: one `.gltf` (JSON) with its single buffer embedded as a
//! `data:application/octet-stream;base64,...` URI (animations need accessors, so a `.gltf`
//! without buffers is not an option).
//!
//! Contents:
//! - node 0, `marker`: the scene root, the marker (tag centre) at the world origin. Its
//!   rotation turns our marker frame into glTF's Y-up world, so the marker lies on the XZ
//!   plane, the table's up side facing +Y.
//! - node 1, `tracked_camera`, child of `marker`: a perspective camera, animated with
//!   `translation` and `rotation` channels (LINEAR, one key per still that has a pose, at time
//!   `index / fps`: key `i` falls on frame `i` of `frames/NNNNNN.png` played at the shot's
//!   fps). Stills without a pose (not tracked, skipped) have no key; between keys the camera
//!   is interpolated. Its rest transform is the first key.
//!
//! Conventions:
//!
//! | space | axes | notes |
//! |---|---|---|
//! | marker (ours, `pa-track`) | +X right, +Y down the printed page, +Z into the table | metres, origin at the tag centre |
//! | camera (ours, OpenCV) | +X right, +Y down, +Z forward | `camera_from_marker * p_marker` |
//! | glTF world | right-handed, +Y up | marker +X = +X, marker +Y = +Z, marker +Z = -Y |
//! | glTF camera | looks down its local -Z, +Y up, +X right | |
//!
//! So `world_from_marker` is a rotation of +90 degrees about X (it takes marker -Z, out of the
//! table, to world +Y), and the camera node's transform is
//! `world_from_marker * marker_from_camera * diag(1, -1, -1)`: the root node carries the first
//! factor, the animated child the other two (`diag(1, -1, -1)` turns the glTF camera's axes
//! into OpenCV's; it is a rotation, so the child's transform stays rigid).
//!
//! Intrinsics: `yfov = 2 atan(height / (2 fy))`, `aspectRatio = width / height`,
//! `znear = 0.01` m, no `zfar` (infinite). A glTF camera has square pixels and a centred
//! principal point; the exact `fx, fy, cx, cy, width, height` are kept in the camera's
//! `extras` for tools that can use them.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use glam::{Mat3, Mat4, Quat, Vec3, Vec4};
use pa_camera::Intrinsics;
use serde_json::json;

use crate::log::{write_durable_if_changed, Entry};
use crate::TakeError;

/// Near plane of the exported camera, metres.
pub const ZNEAR_M: f32 = 0.01;

/// An exported camera document.
#[derive(Debug, Clone)]
pub struct CameraGltf {
    /// The `.gltf` JSON text.
    pub json: String,
    /// Number of animation keys (stills with a pose).
    pub keys: usize,
}

/// Rotation from our marker frame to glTF's Y-up world: +90 degrees about X.
pub fn world_from_marker() -> Quat {
    Quat::from_rotation_x(std::f32::consts::FRAC_PI_2)
}

/// The glTF camera's axes expressed in OpenCV camera axes: `diag(1, -1, -1)`.
fn cv_from_gl() -> Mat4 {
    Mat4::from_diagonal(Vec4::new(1.0, -1.0, -1.0, 1.0))
}

/// The `tracked_camera` node's local transform (relative to the `marker` root) for one pose:
/// `marker_from_camera * diag(1, -1, -1)`, as (translation, unit rotation).
fn local_trs(camera_from_marker: &Mat4) -> (Vec3, Quat) {
    let m = camera_from_marker.inverse() * cv_from_gl();
    let t = m.w_axis.truncate();
    let q = Quat::from_mat3(&Mat3::from_mat4(m)).normalize();
    (t, q)
}

/// Checks that a pose is finite and rigid (orthonormal rotation, no scale or shear).
fn check_pose(index: usize, p: &Mat4) -> Result<(), TakeError> {
    if !p.is_finite() {
        return Err(TakeError::PoseNotFinite { index });
    }
    let r = Mat3::from_mat4(*p);
    let err = (r.transpose() * r - Mat3::IDENTITY).to_cols_array();
    let bottom = p.row(3) - Vec4::W;
    if err.iter().any(|e| e.abs() > 1e-3)
        || (r.determinant() - 1.0).abs() > 1e-3
        || bottom.abs().max_element() > 1e-6
    {
        return Err(TakeError::PoseNotRigid { index });
    }
    Ok(())
}

/// Builds the glTF document of a take's tracked camera.
///
/// `poses`: (still index, `camera_from_marker` or `None`), in any order; stills without a pose
/// are left out. `fps`: stills per second of the finished film (key `i` at `i / fps`).
/// Errors when no still has a pose, when an index repeats, or on a non-rigid pose, rather
/// than writing an invalid or empty file.
pub fn camera_gltf(
    poses: &[(usize, Option<Mat4>)],
    k: &Intrinsics,
    fps: f32,
) -> Result<CameraGltf, TakeError> {
    if !(fps.is_finite() && fps > 0.0) {
        return Err(TakeError::ExportFps { fps });
    }
    if !(k.fy.is_finite() && k.fy > 0.0 && k.width > 0 && k.height > 0) {
        return Err(TakeError::ExportIntrinsics {
            fy: k.fy,
            width: k.width,
            height: k.height,
        });
    }
    let mut keyed: Vec<(usize, Mat4)> = poses
        .iter()
        .filter_map(|(i, p)| p.map(|p| (*i, p)))
        .collect();
    if keyed.is_empty() {
        return Err(TakeError::ExportNoPose {
            stills: poses.len(),
        });
    }
    keyed.sort_by_key(|(i, _)| *i);
    for w in keyed.windows(2) {
        if w[0].0 == w[1].0 {
            return Err(TakeError::ExportTwoPoses { index: w[0].0 });
        }
    }
    let n = keyed.len();
    let mut times = Vec::with_capacity(n);
    let mut translations = Vec::with_capacity(n);
    let mut rotations: Vec<Quat> = Vec::with_capacity(n);
    for (i, p) in &keyed {
        check_pose(*i, p)?;
        let (t, mut q) = local_trs(p);
        // Same hemisphere as the previous key, so interpolation takes the short way.
        if let Some(prev) = rotations.last() {
            if prev.dot(q) < 0.0 {
                q = -q;
            }
        }
        times.push(*i as f32 / fps);
        translations.push(t);
        rotations.push(q);
    }

    let mut bin = Vec::with_capacity(n * 4 * (1 + 3 + 4));
    for t in &times {
        bin.extend_from_slice(&t.to_le_bytes());
    }
    for t in &translations {
        for c in t.to_array() {
            bin.extend_from_slice(&c.to_le_bytes());
        }
    }
    for q in &rotations {
        for c in q.to_array() {
            bin.extend_from_slice(&c.to_le_bytes());
        }
    }
    let (t_len, tr_len, r_len) = (n * 4, n * 12, n * 16);

    let yfov = 2.0 * (k.height as f64 / (2.0 * k.fy)).atan();
    let aspect = k.width as f64 / k.height as f64;
    let root = world_from_marker();
    let doc = json!({
        "asset": {
            "version": "2.0",
            "generator": "Props Alive (propsalive run): tracked camera",
        },
        "scene": 0,
        "scenes": [{ "name": "take", "nodes": [0] }],
        "nodes": [
            {
                "name": "marker",
                "rotation": root.to_array(),
                "children": [1],
            },
            {
                "name": "tracked_camera",
                "camera": 0,
                "translation": translations[0].to_array(),
                "rotation": rotations[0].to_array(),
                "extras": { "stills": keyed.iter().map(|(i, _)| *i).collect::<Vec<_>>() },
            },
        ],
        "cameras": [{
            "name": "tracked_camera",
            "type": "perspective",
            "perspective": {
                "yfov": yfov as f32,
                "aspectRatio": aspect as f32,
                "znear": ZNEAR_M,
            },
            "extras": {
                "fx": k.fx,
                "fy": k.fy,
                "cx": k.cx,
                "cy": k.cy,
                "width": k.width,
                "height": k.height,
            },
        }],
        "buffers": [{
            "byteLength": bin.len(),
            "uri": format!("data:application/octet-stream;base64,{}", base64_encode(&bin)),
        }],
        "bufferViews": [
            { "buffer": 0, "byteOffset": 0, "byteLength": t_len },
            { "buffer": 0, "byteOffset": t_len, "byteLength": tr_len },
            { "buffer": 0, "byteOffset": t_len + tr_len, "byteLength": r_len },
        ],
        "accessors": [
            {
                "bufferView": 0,
                "componentType": 5126,
                "count": n,
                "type": "SCALAR",
                "min": [times[0]],
                "max": [times[n - 1]],
            },
            { "bufferView": 1, "componentType": 5126, "count": n, "type": "VEC3" },
            { "bufferView": 2, "componentType": 5126, "count": n, "type": "VEC4" },
        ],
        "animations": [{
            "name": "tracked_camera",
            "samplers": [
                { "input": 0, "output": 1, "interpolation": "LINEAR" },
                { "input": 0, "output": 2, "interpolation": "LINEAR" },
            ],
            "channels": [
                { "sampler": 0, "target": { "node": 1, "path": "translation" } },
                { "sampler": 1, "target": { "node": 1, "path": "rotation" } },
            ],
        }],
    });
    Ok(CameraGltf {
        json: serde_json::to_string_pretty(&doc)?,
        keys: n,
    })
}

/// What [`export_camera`] did.
#[derive(Debug, Clone, PartialEq)]
pub enum Exported {
    /// No still of the take was tracked: nothing written.
    NoPose,
    /// `camera.gltf` written at `path` (or already holding exactly this document).
    Written {
        path: PathBuf,
        /// Animation keys: stills with a pose.
        keys: usize,
        fps: f32,
    },
}

impl std::fmt::Display for Exported {
    /// The line `propsalive run` prints.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Exported::NoPose => write!(
                f,
                "note: no still of the take was tracked: no camera.gltf written"
            ),
            Exported::Written { path, keys, fps } => write!(
                f,
                "camera: {keys} tracked still(s) exported to {} (glTF 2.0, Y-up, {fps} fps)",
                path.display()
            ),
        }
    }
}

/// Writes `camera.gltf` in the take folder `out` from the log's poses of stills `0..n` (a
/// resumed run exports the whole take), unless it already holds exactly this document. No
/// pose at all is not an error: the frames are there ([`Exported::NoPose`]).
pub fn export_camera(
    out: &Path,
    entries: &BTreeMap<usize, Entry>,
    n: usize,
    intrinsics: &Intrinsics,
    fps: f32,
) -> Result<Exported, TakeError> {
    let poses: Vec<(usize, Option<Mat4>)> = entries
        .values()
        .filter(|e| e.index < n)
        .map(|e| {
            let pose = e
                .camera_from_marker
                .as_deref()
                .filter(|m| m.len() == 16)
                .map(Mat4::from_cols_slice);
            (e.index, pose)
        })
        .collect();
    if !poses.iter().any(|(_, p)| p.is_some()) {
        return Ok(Exported::NoPose);
    }
    let doc = camera_gltf(&poses, intrinsics, fps)?;
    let path = out.join("camera.gltf");
    write_durable_if_changed(&path, doc.json.as_bytes())?;
    Ok(Exported::Written {
        path,
        keys: doc.keys,
        fps,
    })
}

/// Standard base64 (RFC 4648, with padding).
fn base64_encode(bytes: &[u8]) -> String {
    const ABC: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut s = String::with_capacity(bytes.len().div_ceil(3) * 4);
    for chunk in bytes.chunks(3) {
        let b = [
            chunk[0],
            chunk.get(1).copied().unwrap_or(0),
            chunk.get(2).copied().unwrap_or(0),
        ];
        let v = (b[0] as u32) << 16 | (b[1] as u32) << 8 | b[2] as u32;
        for j in 0..4 {
            if j <= chunk.len() {
                s.push(ABC[(v >> (18 - 6 * j) & 63) as usize] as char);
            } else {
                s.push('=');
            }
        }
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    fn intrinsics() -> Intrinsics {
        Intrinsics {
            fx: 800.0,
            fy: 810.0,
            cx: 320.0,
            cy: 240.0,
            width: 640,
            height: 480,
        }
    }

    fn b64_decode(s: &str) -> Vec<u8> {
        let val = |c: u8| -> u32 {
            match c {
                b'A'..=b'Z' => (c - b'A') as u32,
                b'a'..=b'z' => (c - b'a' + 26) as u32,
                b'0'..=b'9' => (c - b'0' + 52) as u32,
                b'+' => 62,
                b'/' => 63,
                _ => panic!("bad base64 {c}"),
            }
        };
        let mut out = Vec::new();
        for chunk in s.as_bytes().chunks(4) {
            let pad = chunk.iter().filter(|&&c| c == b'=').count();
            let mut v = 0u32;
            for &c in chunk {
                v = v << 6 | if c == b'=' { 0 } else { val(c) };
            }
            let b = [(v >> 16) as u8, (v >> 8) as u8, v as u8];
            out.extend_from_slice(&b[..3 - pad]);
        }
        out
    }

    /// The parsed document, and each accessor's floats.
    fn decode(json: &str) -> (serde_json::Value, Vec<Vec<f32>>) {
        let doc: serde_json::Value = serde_json::from_str(json).expect("json");
        let uri = doc["buffers"][0]["uri"].as_str().expect("uri");
        let data = b64_decode(
            uri.strip_prefix("data:application/octet-stream;base64,")
                .expect("data uri"),
        );
        assert_eq!(
            data.len() as u64,
            doc["buffers"][0]["byteLength"].as_u64().unwrap()
        );
        let mut out = Vec::new();
        for a in doc["accessors"].as_array().unwrap() {
            let view = &doc["bufferViews"][a["bufferView"].as_u64().unwrap() as usize];
            let off = view["byteOffset"].as_u64().unwrap() as usize;
            let len = view["byteLength"].as_u64().unwrap() as usize;
            let comps = match a["type"].as_str().unwrap() {
                "SCALAR" => 1,
                "VEC3" => 3,
                "VEC4" => 4,
                t => panic!("type {t}"),
            };
            assert_eq!(a["componentType"], 5126);
            assert_eq!(len, a["count"].as_u64().unwrap() as usize * comps * 4);
            out.push(
                data[off..off + len]
                    .chunks_exact(4)
                    .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
                    .collect(),
            );
        }
        (doc, out)
    }

    /// World transform of the camera node at key `j`.
    fn world_of_key(doc: &serde_json::Value, acc: &[Vec<f32>], j: usize) -> Mat4 {
        let r: Vec<f32> = doc["nodes"][0]["rotation"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_f64().unwrap() as f32)
            .collect();
        let root = Mat4::from_quat(Quat::from_slice(&r));
        let t = Vec3::from_slice(&acc[1][3 * j..3 * j + 3]);
        let q = Quat::from_slice(&acc[2][4 * j..4 * j + 4]);
        root * Mat4::from_rotation_translation(q, t)
    }

    fn close(a: Vec3, b: Vec3) -> bool {
        (a - b).abs().max_element() < 1e-5
    }

    #[test]
    fn camera_above_marker_looks_down() {
        // 1 m above the tag centre looking straight down, marker +Y toward the image bottom:
        // the camera and marker axes coincide, the marker 1 m ahead.
        let cfm = Mat4::from_translation(Vec3::new(0.0, 0.0, 1.0));
        let out = camera_gltf(&[(0, Some(cfm))], &intrinsics(), 24.0).unwrap();
        assert_eq!(out.keys, 1);
        let (doc, acc) = decode(&out.json);
        assert_eq!(doc["nodes"][1]["name"], "tracked_camera");
        assert_eq!(doc["nodes"][1]["camera"], 0);
        let w = world_of_key(&doc, &acc, 0);
        assert!(close(w.w_axis.truncate(), Vec3::Y), "{:?}", w.w_axis);
        let forward = w.transform_vector3(-Vec3::Z);
        assert!(close(forward, -Vec3::Y), "{forward:?}");
        // The image top (camera up) is marker -Y, "up the page": world -Z.
        assert!(close(w.transform_vector3(Vec3::Y), -Vec3::Z));
        // The marker lies on the XZ plane: its +Z (into the table) is world -Y.
        let root = Mat4::from_quat(world_from_marker());
        assert!(close(root.transform_vector3(Vec3::Z), -Vec3::Y));
        assert!(close(root.transform_vector3(Vec3::X), Vec3::X));
    }

    #[test]
    fn accessors_decode_to_the_poses_and_yfov_matches() {
        let poses: Vec<(usize, Option<Mat4>)> = (0..5)
            .map(|i| {
                let f = i as f32;
                let cfm = Mat4::from_rotation_translation(
                    Quat::from_euler(glam::EulerRot::XYZ, 0.3 + 0.1 * f, -0.2 * f, 0.05 * f),
                    Vec3::new(0.02 * f, -0.01, 0.5 + 0.03 * f),
                );
                (i * 2, if i == 2 { None } else { Some(cfm) })
            })
            .collect();
        let k = intrinsics();
        let out = camera_gltf(&poses, &k, 12.0).unwrap();
        assert_eq!(out.keys, 4);
        let (doc, acc) = decode(&out.json);
        // Times: stills 0, 2, 6, 8 (still 4 has no pose) at index / fps, with min/max.
        assert_eq!(acc[0], vec![0.0, 2.0 / 12.0, 6.0 / 12.0, 8.0 / 12.0]);
        assert_eq!(doc["accessors"][0]["min"][0].as_f64().unwrap() as f32, 0.0);
        assert_eq!(
            doc["accessors"][0]["max"][0].as_f64().unwrap() as f32,
            8.0 / 12.0
        );
        assert_eq!(doc["accessors"][1]["count"], 4);
        assert_eq!(doc["nodes"][1]["extras"]["stills"], json!([0, 2, 6, 8]));
        let kept: Vec<Mat4> = poses.iter().filter_map(|(_, p)| *p).collect();
        for (j, cfm) in kept.iter().enumerate() {
            let w = world_of_key(&doc, &acc, j);
            // The expected transform, built independently.
            let want = Mat4::from_quat(world_from_marker())
                * cfm.inverse()
                * Mat4::from_diagonal(Vec4::new(1.0, -1.0, -1.0, 1.0));
            let d = (w - want).to_cols_array();
            assert!(
                d.iter().all(|x| x.abs() < 1e-5),
                "key {j}: {w:?} vs {want:?}"
            );
            // A marker point seen through the glTF camera lands where OpenCV's camera sees it.
            let p_m = Vec3::new(0.03, -0.04, 0.0);
            let p_world = Mat4::from_quat(world_from_marker()).transform_point3(p_m);
            let p_gl = w.inverse().transform_point3(p_world);
            let p_cv = Vec3::new(p_gl.x, -p_gl.y, -p_gl.z);
            assert!(close(p_cv, cfm.transform_point3(p_m)));
            let q = Quat::from_slice(&acc[2][4 * j..4 * j + 4]);
            assert!((q.length() - 1.0).abs() < 1e-5);
        }
        let cam = &doc["cameras"][0];
        assert_eq!(cam["type"], "perspective");
        let yfov = cam["perspective"]["yfov"].as_f64().unwrap();
        assert!((yfov - 2.0 * (480.0f64 / (2.0 * 810.0)).atan()).abs() < 1e-6);
        let aspect = cam["perspective"]["aspectRatio"].as_f64().unwrap();
        assert!((aspect - 640.0 / 480.0).abs() < 1e-6);
        assert!((cam["perspective"]["znear"].as_f64().unwrap() - 0.01).abs() < 1e-7);
        assert_eq!(
            doc["animations"][0]["samplers"][0]["interpolation"],
            "LINEAR"
        );
    }

    #[test]
    fn no_pose_is_an_error_and_bad_input_is_refused() {
        let k = intrinsics();
        let e = camera_gltf(&[(0, None), (1, None)], &k, 24.0).unwrap_err();
        assert!(e.to_string().contains("none of the 2 still(s)"), "{e}");
        assert!(camera_gltf(&[], &k, 24.0).is_err());
        let id = Some(Mat4::from_translation(Vec3::Z));
        assert!(camera_gltf(&[(0, id)], &k, 0.0).is_err());
        assert!(camera_gltf(&[(3, id), (3, id)], &k, 24.0).is_err());
        let scaled = Some(Mat4::from_scale(Vec3::splat(2.0)));
        assert!(camera_gltf(&[(0, scaled)], &k, 24.0).is_err());
    }

    #[test]
    fn base64_matches_rfc4648() {
        assert_eq!(base64_encode(b""), "");
        assert_eq!(base64_encode(b"f"), "Zg==");
        assert_eq!(base64_encode(b"fo"), "Zm8=");
        assert_eq!(base64_encode(b"foo"), "Zm9v");
        assert_eq!(base64_encode(b"foobar"), "Zm9vYmFy");
        let bytes: Vec<u8> = (0..=255).collect();
        assert_eq!(b64_decode(&base64_encode(&bytes)), bytes);
    }

    #[test]
    fn our_loader_reads_the_file() {
        let cfm = Mat4::from_translation(Vec3::new(0.0, 0.0, 1.0));
        let out = camera_gltf(&[(0, Some(cfm)), (1, Some(cfm))], &intrinsics(), 24.0).unwrap();
        let res = pa_model::Model::from_slice(
            out.json.as_bytes(),
            "camera.gltf",
            None,
            &pa_model::LoadOptions::default(),
        );
        match res {
            Ok(m) => assert_eq!(m.animations.len(), 1),
            Err(e) => panic!("our loader rejects the camera file: {e}"),
        }
    }
}
