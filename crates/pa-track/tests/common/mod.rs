//! Test helpers: a CPU renderer of tags seen by a camera (inverse mapping of every pixel onto
//! the marker plane with supersampling), noise, blur and a tiny deterministic PRNG.
#![allow(dead_code)]

use glam::{DQuat, DVec2, DVec3};
use pa_camera::{CameraModel, Intrinsics};
use pa_track::board::BoardTag;
use pa_track::{family_layout, marker_cells, GrayImage, Pose, TagFamily};

/// SplitMix64.
pub struct Rng(pub u64);

impl Rng {
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    pub fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
    pub fn gauss(&mut self) -> f64 {
        let u1 = self.uniform().max(1e-300);
        let u2 = self.uniform();
        (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
    }
}

/// [`camera_720p`] as the picture renderer of `image_target::synth` takes it.
pub fn pinhole_720p() -> pa_track::image_target::synth::Pinhole {
    let c = camera_720p().intrinsics;
    pa_track::image_target::synth::Pinhole {
        fx: c.fx,
        fy: c.fy,
        cx: c.cx,
        cy: c.cy,
        width: c.width,
        height: c.height,
    }
}

pub fn camera_720p() -> CameraModel {
    CameraModel::pinhole(Intrinsics {
        fx: 1000.0,
        fy: 1000.0,
        cx: 639.5,
        cy: 359.5,
        width: 1280,
        height: 720,
    })
}

/// `camera_from_marker` for a camera looking at the marker origin from `distance_m`, the
/// marker tilted by `tilt_deg` about its X axis and turned by `yaw_deg` in its plane, the
/// origin at `offset_px`-ish from the image centre (given as a camera-space offset).
pub fn view_pose(tilt_deg: f64, yaw_deg: f64, distance_m: f64, offset: DVec3) -> Pose {
    Pose {
        rotation: DQuat::from_rotation_x(tilt_deg.to_radians())
            * DQuat::from_rotation_z(yaw_deg.to_radians()),
        translation: DVec3::new(0.0, 0.0, distance_m) + offset,
    }
}

pub struct Scene {
    pub family: TagFamily,
    pub tags: Vec<BoardTag>,
    /// Grey of the table outside the tags' white quiet zones.
    pub background: u8,
}

/// Renders the scene; `ss` x `ss` samples per pixel.
pub fn render(cam: &CameraModel, scene: &Scene, camera_from_marker: &Pose, ss: u32) -> GrayImage {
    let k = &cam.intrinsics;
    let (w, h) = (k.width, k.height);
    let mut img = GrayImage::filled(w, h, scene.background);
    let layout = family_layout(scene.family).expect("family");
    let total = layout.total_cells as f64;
    let border = layout.border_cells as f64;
    let cells: Vec<GrayImage> = scene
        .tags
        .iter()
        .map(|t| marker_cells(scene.family, t.id).expect("id"))
        .collect();
    let marker_from_camera = camera_from_marker.inverse();
    let origin = marker_from_camera.translation;
    // Bounding box of the projected quiet zones.
    let (mut lo, mut hi) = (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY));
    for t in &scene.tags {
        let big = BoardTag {
            size_m: t.size_m * total / border,
            ..*t
        };
        for p in big.object_points() {
            if let Some(px) = cam.pixel_from_camera(camera_from_marker.transform_point(p)) {
                lo = lo.min(px);
                hi = hi.max(px);
            }
        }
    }
    let x0 = (lo.x.floor() - 2.0).max(0.0) as u32;
    let y0 = (lo.y.floor() - 2.0).max(0.0) as u32;
    let x1 = ((hi.x.ceil() + 3.0).max(0.0) as u32).min(w);
    let y1 = ((hi.y.ceil() + 3.0).max(0.0) as u32).min(h);
    for y in y0..y1 {
        for x in x0..x1 {
            let mut acc = 0.0;
            for sy in 0..ss {
                for sx in 0..ss {
                    let p = DVec2::new(
                        x as f64 + (sx as f64 + 0.5) / ss as f64 - 0.5,
                        y as f64 + (sy as f64 + 0.5) / ss as f64 - 0.5,
                    );
                    let d = marker_from_camera.rotation * cam.ray_from_pixel(p);
                    let mut v = scene.background as f64;
                    if d.z.abs() > 1e-12 {
                        let s = -origin.z / d.z;
                        if s > 0.0 {
                            let q = (origin + d * s).truncate();
                            for (t, c) in scene.tags.iter().zip(&cells) {
                                let (sn, cs) = t.rotation_rad.sin_cos();
                                let r = q - t.center_m;
                                let local = DVec2::new(cs * r.x + sn * r.y, -sn * r.x + cs * r.y);
                                let cu = local.x / t.size_m * border + total * 0.5;
                                let cv = local.y / t.size_m * border + total * 0.5;
                                if cu >= 0.0 && cv >= 0.0 && cu < total && cv < total {
                                    v = c.data[cv as usize * c.width as usize + cu as usize] as f64;
                                    break;
                                }
                            }
                        }
                    }
                    acc += v;
                }
            }
            img.data[(y * w + x) as usize] = (acc / (ss * ss) as f64).round() as u8;
        }
    }
    img
}

/// Separable Gaussian blur.
pub fn blur(img: &GrayImage, sigma: f64) -> GrayImage {
    if sigma <= 0.0 {
        return img.clone();
    }
    let r = (3.0 * sigma).ceil() as i64;
    let kernel: Vec<f64> = (-r..=r)
        .map(|i| (-(i * i) as f64 / (2.0 * sigma * sigma)).exp())
        .collect();
    let sum: f64 = kernel.iter().sum();
    let (w, h) = (img.width as i64, img.height as i64);
    let pass = |src: &[f64], horizontal: bool| -> Vec<f64> {
        let mut out = vec![0.0; src.len()];
        for y in 0..h {
            for x in 0..w {
                let mut a = 0.0;
                for (i, kv) in kernel.iter().enumerate() {
                    let o = i as i64 - r;
                    let (xx, yy) = if horizontal {
                        ((x + o).clamp(0, w - 1), y)
                    } else {
                        (x, (y + o).clamp(0, h - 1))
                    };
                    a += kv * src[(yy * w + xx) as usize];
                }
                out[(y * w + x) as usize] = a / sum;
            }
        }
        out
    };
    let f: Vec<f64> = img.data.iter().map(|v| *v as f64).collect();
    let f = pass(&pass(&f, true), false);
    GrayImage {
        width: img.width,
        height: img.height,
        data: f
            .iter()
            .map(|v| v.round().clamp(0.0, 255.0) as u8)
            .collect(),
    }
}

/// Adds Gaussian noise of `sigma` grey levels.
pub fn add_noise(img: &mut GrayImage, sigma: f64, rng: &mut Rng) {
    for v in &mut img.data {
        *v = (*v as f64 + sigma * rng.gauss()).round().clamp(0.0, 255.0) as u8;
    }
}

/// Exact projected corners of a board tag (for state-machine tests without images).
pub fn project_tag(cam: &CameraModel, pose: &Pose, tag: &BoardTag) -> [DVec2; 4] {
    tag.object_points().map(|p| {
        cam.pixel_from_camera(pose.transform_point(p))
            .expect("in front")
    })
}
