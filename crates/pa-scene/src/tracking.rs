//! The tracker alone on a scene's camera frames: rotation and translation error per still
//! (the tracker reset before every frame and no filter, as `propsalive run` tracks stills)
//! and in video mode (one sequence, the pose filter on), on the clean frames and on the same
//! frames with sensor noise and blur ([`SensorNoise`]). `propsalive eval` reports the medians
//! as its "tracking" rows.

use glam::Mat4;
use pa_camera::CameraModel;
use pa_pipeline::ar::gray_from_rgba;
use pa_render::Renderer;
use pa_track::{DetectorConfig, Pose, Tracker, TrackerConfig};

use crate::scene::{Rng, Scene, SceneSpec};
use crate::SceneError;

/// Degradation of a camera frame: a blur, then Gaussian noise per channel.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SensorNoise {
    /// Standard deviation of the noise, 8-bit levels.
    pub sigma: f32,
    /// Passes of a 3x3 binomial blur (0: none; one pass is a Gaussian of sigma ~0.7 px).
    pub blur_passes: u32,
    /// Blur in linear light (decoded from sRGB, blurred, encoded again), as a lens blurs
    /// before the camera encodes; `false` blurs the encoded values (the eval's first noisy
    /// camera, kept for continuity of its figures: it keeps the encoded grey's halfway
    /// point where the sharp frame had it, which a lens does not).
    pub linear_light: bool,
}

impl SensorNoise {
    /// The eval's noisy camera: blur sigma ~1 px, noise of 15 levels (a small sensor in
    /// dim light; at 960x540 weaker noise does not raise the per-still pose error).
    pub const HANDHELD: SensorNoise = SensorNoise {
        sigma: 15.0,
        blur_passes: 2,
        linear_light: false,
    };

    /// [`SensorNoise::HANDHELD`] with its blur in linear light, as a lens blurs.
    pub const HANDHELD_LENS: SensorNoise = SensorNoise {
        linear_light: true,
        ..SensorNoise::HANDHELD
    };

    /// Applies the degradation to an RGBA8 frame (alpha untouched), deterministically from
    /// `seed`.
    pub fn apply(&self, rgba8: &mut [u8], width: u32, height: u32, seed: u64) {
        let (w, h) = (width as usize, height as usize);
        if rgba8.len() != w * h * 4 || w == 0 || h == 0 {
            return;
        }
        if self.linear_light && self.blur_passes > 0 {
            let lut = crate::variant::srgb_lut();
            let mut lin: Vec<f32> = rgba8.iter().map(|&v| lut[usize::from(v)]).collect();
            for _ in 0..self.blur_passes {
                for horizontal in [true, false] {
                    let src = lin.clone();
                    blur_pass(w, h, horizontal, |i, a, b, c| {
                        lin[i * 4 + c] =
                            0.25 * (src[a * 4 + c] + 2.0 * src[i * 4 + c] + src[b * 4 + c]);
                    });
                }
            }
            for (i, px) in rgba8.chunks_exact_mut(4).enumerate() {
                for c in 0..3 {
                    px[c] = crate::variant::srgb_encode(lin[i * 4 + c]);
                }
            }
        } else {
            for _ in 0..self.blur_passes {
                for horizontal in [true, false] {
                    let src = rgba8.to_vec();
                    blur_pass(w, h, horizontal, |i, a, b, c| {
                        let v = u32::from(src[a * 4 + c])
                            + 2 * u32::from(src[i * 4 + c])
                            + u32::from(src[b * 4 + c]);
                        rgba8[i * 4 + c] = ((v + 2) / 4) as u8;
                    });
                }
            }
        }
        let mut rng = Rng::new(seed);
        for px in rgba8.chunks_exact_mut(4) {
            for v in &mut px[..3] {
                // Box-Muller from two uniforms.
                let u1 = rng.f32().max(1e-7);
                let u2 = rng.f32();
                let g = (-2.0 * u1.ln()).sqrt() * (std::f32::consts::TAU * u2).cos();
                *v = (f32::from(*v) + self.sigma * g).round().clamp(0.0, 255.0) as u8;
            }
        }
    }
}

/// One pass of a [1 2 1] / 4 blur along rows (`horizontal`) or columns over a `w x h` frame
/// (the border repeated): `each(i, a, b, channel)` for every pixel `i`, its neighbours `a`
/// and `b` along the pass, and each colour channel.
fn blur_pass(
    w: usize,
    h: usize,
    horizontal: bool,
    mut each: impl FnMut(usize, usize, usize, usize),
) {
    for y in 0..h {
        for x in 0..w {
            let (a, b) = if horizontal {
                ((y * w + x.saturating_sub(1)), (y * w + (x + 1).min(w - 1)))
            } else {
                ((y.saturating_sub(1) * w + x), ((y + 1).min(h - 1) * w + x))
            };
            for c in 0..3 {
                each(y * w + x, a, b, c);
            }
        }
    }
}

/// Per-frame errors of the two tracking modes (`None`: no pose on that frame).
#[derive(Debug, Clone, Default)]
pub struct TrackingErrors {
    /// Rotation error, degrees, per still.
    pub per_still_rot_deg: Vec<Option<f64>>,
    /// Rotation error, degrees, with the video filter.
    pub video_rot_deg: Vec<Option<f64>>,
    /// Translation error, mm, per still.
    pub per_still_trans_mm: Vec<Option<f64>>,
    /// Translation error, mm, with the video filter.
    pub video_trans_mm: Vec<Option<f64>>,
}

/// Rotation (degrees) and translation (mm) error of `estimated` against a true
/// `camera_from_marker`, in f64 (an f32 quaternion cannot resolve hundredths of a degree).
pub fn pose_error_f64(estimated: &Pose, truth: Mat4) -> (f64, f64) {
    crate::eval::pose_error_of(estimated.rotation, estimated.translation, truth)
}

/// Tracks frames `frames` (consecutive, for the video mode) of the scene built from `spec`
/// both ways; with `noise`, each input frame is degraded first (the same for both modes).
pub fn tracking_errors(
    renderer: &mut Renderer,
    spec: SceneSpec,
    frames: impl IntoIterator<Item = u32>,
    noise: &[Option<SensorNoise>],
) -> Result<Vec<TrackingErrors>, SceneError> {
    let scene = Scene::new(spec, renderer)?;
    let camera = CameraModel::pinhole(scene.intrinsics);
    let target = scene.track_target()?;
    let per_still_cfg = TrackerConfig::per_still();
    let mut modes = Vec::new();
    for _ in noise {
        let still = Tracker::new(
            camera,
            target.clone(),
            DetectorConfig::default(),
            per_still_cfg,
        )?;
        let video = Tracker::new(
            camera,
            target.clone(),
            DetectorConfig::default(),
            TrackerConfig::default(),
        )?;
        modes.push((still, video, TrackingErrors::default()));
    }
    for i in frames {
        let key_time = scene.spec.key_frames[scene.key_for(i)] as f32 / scene.spec.fps;
        let truth = scene.camera_from_marker(i);
        let frame = scene.render_view(renderer, truth, Some(key_time))?;
        let t_s = f64::from(i) / f64::from(scene.spec.fps);
        for (n, (still, video, errs)) in noise.iter().zip(&mut modes) {
            let mut rgba = frame.rgba8.clone();
            if let Some(n) = n {
                n.apply(
                    &mut rgba,
                    frame.width,
                    frame.height,
                    scene.spec.seed ^ (u64::from(i) << 32),
                );
            }
            let gray = gray_from_rgba(&rgba, frame.width, frame.height)?;
            still.reset();
            let s = still
                .update(&gray, t_s)?
                .pose
                .map(|p| pose_error_f64(&p, truth));
            let v = video
                .update(&gray, t_s)?
                .pose
                .map(|p| pose_error_f64(&p, truth));
            errs.per_still_rot_deg.push(s.map(|e| e.0));
            errs.per_still_trans_mm.push(s.map(|e| e.1));
            errs.video_rot_deg.push(v.map(|e| e.0));
            errs.video_trans_mm.push(v.map(|e| e.1));
        }
    }
    Ok(modes.into_iter().map(|m| m.2).collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DQuat;

    #[test]
    fn noise_is_deterministic_and_of_the_stated_size() {
        let (w, h) = (64u32, 32u32);
        let flat = vec![128u8; (w * h * 4) as usize];
        let mut a = flat.clone();
        let mut b = flat.clone();
        let n = SensorNoise {
            sigma: 6.0,
            blur_passes: 1,
            linear_light: false,
        };
        n.apply(&mut a, w, h, 3);
        n.apply(&mut b, w, h, 3);
        assert_eq!(a, b);
        let dev: Vec<f64> = a
            .chunks_exact(4)
            .flat_map(|p| {
                p[..3]
                    .iter()
                    .map(|&v| f64::from(v) - 128.0)
                    .collect::<Vec<_>>()
            })
            .collect();
        let sd = (dev.iter().map(|d| d * d).sum::<f64>() / dev.len() as f64).sqrt();
        assert!((sd - 6.0).abs() < 0.3, "sd {sd}");
        assert!(a.chunks_exact(4).all(|p| p[3] == 128));
        // The blur alone keeps a flat image flat and softens a step; in linear light the
        // step is brighter beside the edge: 0 and 200 decode to 0 and 0.578, and a quarter
        // and three quarters of that encode to 106 and 176.
        for (linear_light, expected) in [(false, [0, 50, 150, 200]), (true, [0, 106, 176, 200])] {
            let mut step: Vec<u8> = (0..w * h)
                .flat_map(|i| {
                    let v = if i % w < w / 2 { 0 } else { 200 };
                    [v, v, v, 255]
                })
                .collect();
            SensorNoise {
                sigma: 0.0,
                blur_passes: 1,
                linear_light,
            }
            .apply(&mut step, w, h, 0);
            let row: Vec<u8> = (0..w as usize).map(|x| step[x * 4]).collect();
            assert_eq!(&row[w as usize / 2 - 2..w as usize / 2 + 2], &expected);
            assert!(step.chunks_exact(4).all(|p| p[3] == 255));
        }
    }

    #[test]
    fn pose_error_resolves_small_angles() {
        let truth = Pose {
            rotation: DQuat::from_rotation_x(0.6),
            translation: glam::DVec3::new(0.01, 0.02, 0.5),
        };
        let est = Pose {
            rotation: DQuat::from_rotation_y(0.01f64.to_radians()) * truth.rotation,
            translation: truth.translation + glam::DVec3::new(0.0, 0.0, 0.002),
        };
        let (r, t) = pose_error_f64(&est, truth.to_mat4());
        assert!((r - 0.01).abs() < 2e-4, "{r}");
        assert!((t - 2.0).abs() < 1e-3, "{t}");
    }
}
