//! The model side of registration: the key-pose twin as one welded triangle mesh in prop space,
//! its silhouette mask seen from a camera (rasterised at a pyramid level), and the points of
//! its outline: samples of the mesh's contour edges (where a front face meets a back face)
//! whose projection lies on the silhouette's outer boundary, each with its outline normal.

use std::collections::HashMap;

use glam::{DMat4, DVec2, DVec3, Mat4};
use pa_camera::CameraModel;
use pa_model::{anim::Pose, Model};

use super::edges::{bin_of, EdgeLevel};
use crate::cpu_twin::CpuTwin;

/// The key-pose twin: welded positions (prop space, metres), triangles, and each edge with its
/// two faces (`u32::MAX` for a border edge).
pub(crate) struct TwinShape {
    pub positions: Vec<DVec3>,
    pub triangles: Vec<[u32; 3]>,
    pub edges: Vec<([u32; 2], [u32; 2])>,
}

/// One point of the twin's outline, fixed on the model.
#[derive(Debug, Clone, Copy)]
pub(crate) struct OutlinePoint {
    /// Prop space (unscaled), metres.
    pub prop: DVec3,
    /// Orientation bin of the outline's normal in the image.
    pub bin: usize,
}

impl TwinShape {
    /// The model posed at `key` (prop space), welded by position so that texture seams do
    /// not read as outline.
    pub fn new(model: &Model, key: &Pose) -> Option<Self> {
        let mut twin = CpuTwin::new(model).ok()?;
        twin.pose(model, key, key, Mat4::IDENTITY);
        let mut positions = Vec::new();
        let mut triangles = Vec::new();
        let mut weld: HashMap<[i64; 3], u32> = HashMap::new();
        for (p, posed) in twin.primitives.iter().zip(&twin.key) {
            let prim = model.meshes[p.mesh].primitives[p.primitive].drawn();
            let map: Vec<u32> = posed
                .positions_world
                .iter()
                .map(|v| {
                    let key = [
                        (v.x as f64 * 1e6).round() as i64,
                        (v.y as f64 * 1e6).round() as i64,
                        (v.z as f64 * 1e6).round() as i64,
                    ];
                    *weld.entry(key).or_insert_with(|| {
                        positions.push(v.as_dvec3());
                        (positions.len() - 1) as u32
                    })
                })
                .collect();
            for t in prim.indices.chunks_exact(3) {
                let tri = [
                    *map.get(t[0] as usize)?,
                    *map.get(t[1] as usize)?,
                    *map.get(t[2] as usize)?,
                ];
                if tri[0] != tri[1] && tri[1] != tri[2] && tri[0] != tri[2] {
                    triangles.push(tri);
                }
            }
        }
        if triangles.is_empty() {
            return None;
        }
        let mut faces_of: HashMap<[u32; 2], [u32; 2]> = HashMap::new();
        for (f, t) in triangles.iter().enumerate() {
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                let e = [a.min(b), a.max(b)];
                let slot = faces_of.entry(e).or_insert([u32::MAX; 2]);
                if slot[0] == u32::MAX {
                    slot[0] = f as u32;
                } else if slot[1] == u32::MAX {
                    slot[1] = f as u32;
                }
            }
        }
        let mut edges: Vec<([u32; 2], [u32; 2])> = faces_of.into_iter().collect();
        edges.sort_unstable();
        Some(Self {
            positions,
            triangles,
            edges,
        })
    }

    /// The lowest and highest points and the centre of the bounding box (prop space).
    pub fn bounds(&self) -> (DVec3, DVec3) {
        let mut lo = DVec3::splat(f64::INFINITY);
        let mut hi = DVec3::splat(f64::NEG_INFINITY);
        for p in &self.positions {
            lo = lo.min(*p);
            hi = hi.max(*p);
        }
        (lo, hi)
    }
}

/// The twin seen from one camera at one placement: pixel positions (full resolution) and
/// which faces face the camera.
pub(crate) struct Projected {
    pub pixels: Vec<Option<DVec2>>,
    pub front: Vec<bool>,
}

/// Projects the twin through `camera_from_prop`.
pub(crate) fn project(
    shape: &TwinShape,
    camera: &CameraModel,
    camera_from_prop: DMat4,
) -> Projected {
    let cam: Vec<DVec3> = shape
        .positions
        .iter()
        .map(|p| camera_from_prop.transform_point3(*p))
        .collect();
    let pixels = cam.iter().map(|c| camera.pixel_from_camera(*c)).collect();
    let front = shape
        .triangles
        .iter()
        .map(|t| {
            let (a, b, c) = (cam[t[0] as usize], cam[t[1] as usize], cam[t[2] as usize]);
            (b - a).cross(c - a).dot(a) < 0.0
        })
        .collect();
    Projected { pixels, front }
}

/// The silhouette mask of `projected` over an edge level's region (level pixels, pixel
/// centres covered).
pub(crate) fn silhouette(shape: &TwinShape, projected: &Projected, level: &EdgeLevel) -> Vec<bool> {
    let (w, h) = (level.width, level.height);
    let mut mask = vec![false; w * h];
    for t in &shape.triangles {
        let (Some(a), Some(b), Some(c)) = (
            projected.pixels[t[0] as usize],
            projected.pixels[t[1] as usize],
            projected.pixels[t[2] as usize],
        ) else {
            continue;
        };
        let p = [a, b, c].map(|v| {
            let l = level.to_level((v.x, v.y));
            DVec2::new(l.0, l.1)
        });
        fill_triangle(&mut mask, w, h, p);
    }
    mask
}

fn fill_triangle(mask: &mut [bool], w: usize, h: usize, p: [DVec2; 3]) {
    let area = (p[1] - p[0]).perp_dot(p[2] - p[0]);
    if area.abs() < 1e-12 {
        return;
    }
    let lo = p[0].min(p[1]).min(p[2]);
    let hi = p[0].max(p[1]).max(p[2]);
    let x0 = lo.x.ceil().max(0.0) as usize;
    let y0 = lo.y.ceil().max(0.0) as usize;
    let x1 = (hi.x.floor().min(w as f64 - 1.0)).max(-1.0);
    let y1 = (hi.y.floor().min(h as f64 - 1.0)).max(-1.0);
    if x1 < 0.0 || y1 < 0.0 {
        return;
    }
    let (x1, y1) = (x1 as usize, y1 as usize);
    let s = area.signum();
    for y in y0..=y1 {
        for x in x0..=x1 {
            let q = DVec2::new(x as f64, y as f64);
            let e0 = (p[1] - p[0]).perp_dot(q - p[0]) * s;
            let e1 = (p[2] - p[1]).perp_dot(q - p[1]) * s;
            let e2 = (p[0] - p[2]).perp_dot(q - p[2]) * s;
            if e0 >= 0.0 && e1 >= 0.0 && e2 >= 0.0 {
                mask[y * w + x] = true;
            }
        }
    }
}

/// The outline points of the twin at this view and placement: contour edges sampled about
/// every level pixel, kept where one side of the sample is inside the silhouette and the other
/// outside (the outer boundary, not a contour hidden behind the twin).
pub(crate) fn outline(
    shape: &TwinShape,
    projected: &Projected,
    level: &EdgeLevel,
    mask: &[bool],
) -> Vec<OutlinePoint> {
    let (w, h) = (level.width, level.height);
    let inside = |q: DVec2| -> Option<bool> {
        let (x, y) = (q.x.round(), q.y.round());
        if x < 0.0 || y < 0.0 || x >= w as f64 || y >= h as f64 {
            return None;
        }
        Some(mask[y as usize * w + x as usize])
    };
    let mut out = Vec::new();
    for (e, faces) in &shape.edges {
        let contour = match (faces[0], faces[1]) {
            (f, u32::MAX) => f != u32::MAX,
            (f, g) => projected.front[f as usize] != projected.front[g as usize],
        };
        if !contour {
            continue;
        }
        let (Some(a), Some(b)) = (
            projected.pixels[e[0] as usize],
            projected.pixels[e[1] as usize],
        ) else {
            continue;
        };
        let la = level.to_level((a.x, a.y));
        let lb = level.to_level((b.x, b.y));
        let (la, lb) = (DVec2::new(la.0, la.1), DVec2::new(lb.0, lb.1));
        let len = (lb - la).length();
        if len < 1e-9 {
            continue;
        }
        let dir = (lb - la) / len;
        let normal = DVec2::new(-dir.y, dir.x);
        let n = (len.ceil() as usize).clamp(1, 64);
        for k in 0..n {
            let t = (k as f64 + 0.5) / n as f64;
            let q = la + (lb - la) * t;
            let (Some(i1), Some(i2)) = (inside(q + normal * 1.5), inside(q - normal * 1.5)) else {
                continue;
            };
            if i1 == i2 {
                continue;
            }
            let p0 = shape.positions[e[0] as usize];
            let p1 = shape.positions[e[1] as usize];
            out.push(OutlinePoint {
                prop: p0 + (p1 - p0) * t,
                bin: bin_of(normal.y.atan2(normal.x)),
            });
        }
    }
    out
}

/// The pixels (full resolution) of the twin's outline seen through `camera_from_prop`: the
/// silhouette's boundary pixels over the frame.
pub(crate) fn outline_pixels_of(
    shape: &TwinShape,
    camera: &CameraModel,
    camera_from_prop: DMat4,
    width: u32,
    height: u32,
) -> Vec<(u32, u32)> {
    let projected = project(shape, camera, camera_from_prop);
    let level = EdgeLevel {
        scale: 1.0,
        origin: (0.0, 0.0),
        width: width as usize,
        height: height as usize,
        dist: Default::default(),
    };
    let mask = silhouette(shape, &projected, &level);
    let (w, h) = (width as usize, height as usize);
    let mut out = Vec::new();
    for y in 0..h {
        for x in 0..w {
            if !mask[y * w + x] {
                continue;
            }
            let edge = x == 0
                || y == 0
                || x + 1 == w
                || y + 1 == h
                || !mask[y * w + x - 1]
                || !mask[y * w + x + 1]
                || !mask[(y - 1) * w + x]
                || !mask[(y + 1) * w + x];
            if edge {
                out.push((x as u32, y as u32));
            }
        }
    }
    out
}
