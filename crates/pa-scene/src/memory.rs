//! Texture memory on the generated scene (`eval`'s memory rows): the pipeline with its
//! texture memory on ([`pa_pipeline::ar::ArPipeline::set_texture_memory`]), alone or primed by
//! a scan pass, a camera that circles the key prop once ([`scan_orbit`]) before the take.
//! The scan's frames are tracked like any input (each as a still) and fed to the memory only.

use glam::{Mat4, Vec3};
use pa_pipeline::ar::{ArPipeline, ArSettings};
use pa_render::Renderer;
use pa_track::{DetectorConfig, Tracker, TrackerConfig};

use pa_pipeline::ar::ArFrame;

use crate::error::SceneError;
use crate::eval::FrameMetrics;
pub use crate::eval::TwinTexture;
use crate::scene::{Scene, SceneFrame, SceneSpec};

/// Views of the scan orbit in `eval` (15 degrees apart).
pub const SCAN_VIEWS: u32 = 24;

/// How a memory row primes the memory.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MemoryMode {
    /// Memory on, filled by the take's own frames.
    On,
    /// Memory on, primed by a scan orbit of [`SCAN_VIEWS`] views first.
    Scan,
}

/// One memory row of `eval`.
pub struct MemoryMethod {
    pub name: &'static str,
    pub settings: ArSettings,
    /// None: the memory off.
    pub mode: Option<MemoryMode>,
    /// The twin's model against the printed prop.
    pub twin: TwinTexture,
}

/// The memory rows, after the methods of [`crate::methods::methods`]; compare with
/// "ours: live + visibility, ray fill" (the same pipeline with the memory off). The last
/// three give the twin a model whose textures are their mean colour
/// ([`TwinTexture::FlatColour`]): what the memory is for, a prop whose paint the model does
/// not know.
pub fn memory_methods() -> Vec<MemoryMethod> {
    let row = |name, mode, twin| MemoryMethod {
        name,
        settings: ArSettings::ours(),
        mode,
        twin,
    };
    let (printed, flat) = (TwinTexture::AsPrinted, TwinTexture::FlatColour);
    vec![
        row("ours: + texture memory", Some(MemoryMode::On), printed),
        row(
            "ours: + texture memory + scan",
            Some(MemoryMode::Scan),
            printed,
        ),
        row("model painted flat: ours", None, flat),
        row(
            "model painted flat: + texture memory",
            Some(MemoryMode::On),
            flat,
        ),
        row(
            "model painted flat: + texture memory + scan",
            Some(MemoryMode::Scan),
            flat,
        ),
    ]
}

/// `views` cameras evenly around the key prop, starting at frame 0's view: the same distance
/// from the prop's centre (its key pose at `key_time_s`) and the same height above the table,
/// each looking at the centre (OpenCV axes, the table's normal up in the image).
pub fn scan_orbit(scene: &Scene, key_time_s: f32, views: u32) -> Vec<Mat4> {
    let tris = scene.prop_triangles(key_time_s);
    let n = (tris.len() * 3).max(1) as f32;
    let centre = tris.iter().flatten().fold(Vec3::ZERO, |a, &p| a + p) / n;
    let eye0 = scene
        .camera_from_marker(0)
        .inverse()
        .transform_point3(Vec3::ZERO);
    let d = eye0 - centre;
    let radius = (d.x * d.x + d.y * d.y).sqrt();
    let start = d.y.atan2(d.x);
    // The table's normal, pointing to the camera's side.
    let up = if d.z >= 0.0 { Vec3::Z } else { Vec3::NEG_Z };
    (0..views)
        .map(|k| {
            let a = start + std::f32::consts::TAU * k as f32 / views.max(1) as f32;
            let eye = centre + Vec3::new(radius * a.cos(), radius * a.sin(), d.z);
            look_at(eye, centre, up)
        })
        .collect()
}

/// `camera_from_marker` of a camera at `eye` looking at `target` (OpenCV: +x right, +y down,
/// +z forward), `up` up in the image.
pub fn look_at(eye: Vec3, target: Vec3, up: Vec3) -> Mat4 {
    let forward = (target - eye).normalize();
    let right = forward.cross(up).normalize();
    let down = forward.cross(right);
    let rotation = Mat4::from_cols(
        right.extend(0.0),
        down.extend(0.0),
        forward.extend(0.0),
        glam::Vec4::W,
    )
    .transpose();
    rotation * Mat4::from_translation(-eye)
}

/// The scan pass on the generated scene: renders the orbit's views with the key prop in its
/// key pose, tracks each as a still (a tracker of its own, as `run` tracks stills: one
/// sighting, no filter, no search region) and feeds it to the memory with that pose.
/// Returns the views used (tracked). The pipeline's own tracker is reset after the scan.
pub fn prime_with_scan(
    scene: &Scene,
    renderer: &mut Renderer,
    pipeline: &mut ArPipeline,
    key_time_s: f32,
    views: u32,
) -> Result<usize, SceneError> {
    let mut tracker = Tracker::new(
        pa_camera::CameraModel::pinhole(scene.intrinsics),
        scene.track_target()?,
        DetectorConfig::default(),
        TrackerConfig::per_still(),
    )?;
    let mut used = 0;
    for camera_from_marker in scan_orbit(scene, key_time_s, views) {
        let f = scene.render_view(renderer, camera_from_marker, Some(key_time_s))?;
        tracker.reset();
        let gray = pa_pipeline::ar::gray_from_rgba(&f.rgba8, f.width, f.height)?;
        let Some(pose) = tracker.update(&gray, 0.0)?.pose else {
            continue;
        };
        if pipeline.remember_with_pose(&f.rgba8, f.width, f.height, key_time_s, pose.to_mat4())? {
            used += 1;
        }
    }
    pipeline.reset_tracker();
    Ok(used)
}

/// [`crate::eval::run_scene`] with the texture memory as `memory` says (None: off) and the
/// twin's model as `twin` says.
pub fn run_scene_memory<E: From<SceneError>>(
    renderer: &mut Renderer,
    spec: SceneSpec,
    settings: ArSettings,
    (memory, twin): (Option<MemoryMode>, TwinTexture),
    frames: impl IntoIterator<Item = u32>,
    mut each: impl FnMut(&SceneFrame, &ArFrame, &FrameMetrics) -> Result<(), E>,
) -> Result<Vec<FrameMetrics>, E> {
    let key_time_s = spec.key_frames.first().copied().unwrap_or(0) as f32 / spec.fps;
    let prepare = |scene: &Scene, renderer: &mut Renderer, p: &mut ArPipeline| {
        if let Some(mode) = memory {
            p.set_texture_memory(true);
            if mode == MemoryMode::Scan {
                prime_with_scan(scene, renderer, p, key_time_s, SCAN_VIEWS)?;
            }
        }
        Ok(())
    };
    crate::eval::run_scene_twin(
        renderer,
        spec,
        settings,
        twin,
        frames,
        false,
        prepare,
        |f, out, m, _| each(f, out, m),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn look_at_puts_the_target_on_the_optical_axis_upright() {
        let eye = Vec3::new(0.3, -0.2, 0.25);
        let target = Vec3::new(0.0, 0.0, 0.05);
        let m = look_at(eye, target, Vec3::Z);
        let t = m.transform_point3(target);
        assert!(t.x.abs() < 1e-5 && t.y.abs() < 1e-5, "{t}");
        assert!((t.z - (target - eye).length()).abs() < 1e-5);
        // A point above the target is higher in the image (smaller y).
        let above = m.transform_point3(target + Vec3::Z * 0.05);
        assert!(above.y < -1e-3, "{above}");
        // A rigid transform.
        let r = glam::Mat3::from_mat4(m);
        assert!((r.determinant() - 1.0).abs() < 1e-5);
    }
}
