//! Placing the key prop in the preview (`P`, the nudge keys, `G`, `W`): the frames kept for
//! registration, the key pose's outline at the current placement, registering on the kept
//! frames and writing the placement into the shot file. The state (the placement, placement
//! mode, whether it was edited) is `pa_overlay::state`'s; this is the work behind its effects.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use glam::{DVec3, Mat4};
use pa_camera::CameraModel;
use pa_model::{anim::Pose, Model};
use pa_pipeline::register::{
    register, write, PlacementParams, RegisterSettings, RegisterView, Registration, TwinOutline,
};
use pa_pipeline::shot::Placement;

use super::state::PlacementValues;

/// Frames kept for `G`.
pub const MAX_VIEWS: usize = 10;
/// A frame is kept when its view direction differs from every kept one by this much.
const MIN_VIEW_CHANGE_DEG: f64 = 4.0;

/// The placement work of the preview.
pub struct Placer {
    /// The shot file (`W` writes into it); `None` for the built-in scene.
    shot: Option<PathBuf>,
    upright: bool,
    scale: f64,
    /// The outline of the key pose at animation frame `.1`.
    outline: Option<(TwinOutline, u32)>,
    /// Frames with their tracked pose, oldest first, from different directions.
    views: Vec<RegisterView>,
}

impl Placer {
    /// For the shot at `shot` (or the built-in scene) standing at `placement`; returns the
    /// state's starting values too.
    pub fn new(shot: Option<PathBuf>, placement: &Placement) -> (Self, PlacementValues) {
        let scale = shot
            .as_deref()
            .and_then(|p| pa_io::read_to_string_regular(p, 4 << 20, "a shot file").ok())
            .and_then(|t| write::placement_scale(&t))
            .unwrap_or(1.0);
        let values = PlacementValues {
            translation_m: placement.translation_m.map(f64::from),
            yaw_deg: placement.yaw_deg as f64,
        };
        (
            Self {
                shot,
                upright: placement.upright,
                scale,
                outline: None,
                views: Vec::new(),
            },
            values,
        )
    }

    /// The registration parameters of the state's values.
    pub fn params(&self, v: &PlacementValues) -> PlacementParams {
        PlacementParams {
            translation_m: v.translation_m,
            yaw_deg: v.yaw_deg,
            scale: self.scale,
            upright: self.upright,
        }
    }

    /// Frames kept for registration.
    pub fn view_count(&self) -> usize {
        self.views.len()
    }

    /// Keeps a tracked frame when it looks from a new direction (the oldest goes beyond
    /// [`MAX_VIEWS`]).
    pub fn remember(
        &mut self,
        name: &str,
        rgba8: &[u8],
        (width, height): (u32, u32),
        camera: CameraModel,
        camera_from_marker: Mat4,
    ) {
        let dir = |m: &Mat4| {
            m.as_dmat4()
                .inverse()
                .transform_point3(DVec3::ZERO)
                .normalize_or_zero()
        };
        let d = dir(&camera_from_marker);
        let new = self.views.iter().all(|v| {
            v.width != width
                || v.height != height
                || dir(&v.camera_from_marker)
                    .dot(d)
                    .clamp(-1.0, 1.0)
                    .acos()
                    .to_degrees()
                    >= MIN_VIEW_CHANGE_DEG
        });
        if !new {
            return;
        }
        self.views
            .retain(|v| v.width == width && v.height == height);
        if self.views.len() == MAX_VIEWS {
            self.views.remove(0);
        }
        self.views.push(RegisterView {
            name: name.to_string(),
            width,
            height,
            rgba8: rgba8.to_vec(),
            camera,
            camera_from_marker,
        });
    }

    /// The outline pixels of the key pose (animation frame `key_frame`) at `placement`.
    #[allow(clippy::too_many_arguments)]
    pub fn outline(
        &mut self,
        model: &Model,
        key_pose: impl FnOnce() -> Pose,
        key_frame: u32,
        camera: &CameraModel,
        camera_from_marker: Mat4,
        placement: &PlacementValues,
        (width, height): (u32, u32),
    ) -> Vec<(u32, u32)> {
        if self.outline.as_ref().is_none_or(|(_, f)| *f != key_frame) {
            self.outline = TwinOutline::new(model, &key_pose()).map(|o| (o, key_frame));
        }
        match &self.outline {
            Some((o, _)) => o.pixels(
                camera,
                camera_from_marker,
                &self.params(placement),
                width,
                height,
            ),
            None => Vec::new(),
        }
    }

    /// Registers the placement on the kept frames.
    pub fn register(
        &self,
        model: &Model,
        key_pose: &Pose,
        start: &PlacementValues,
    ) -> Result<Registration> {
        let r = register(
            model,
            key_pose,
            self.params(start),
            &self.views,
            &RegisterSettings::default(),
        )
        .with_context(|| format!("registering on the last {} frame(s) seen", self.views.len()))?;
        Ok(r)
    }

    /// Writes the placement into the shot file; returns the shot and the backup.
    pub fn write(&self, placement: &PlacementValues) -> Result<(&Path, PathBuf)> {
        let shot = self.shot.as_deref().context(
            "the built-in scene has no shot file to write into (run `propsalive preview SHOT.toml --input ...`)",
        )?;
        let backup = write::write_placement(shot, &self.params(placement), false)?;
        Ok((shot, backup))
    }
}

impl super::Preview {
    /// The pipeline draws the twin at the state's placement.
    pub(super) fn place_pipeline(&mut self) {
        if let Some(v) = self.state.placement {
            let m = self.placer.params(&v).marker_from_prop_f32();
            self.pipeline.set_first_marker_from_prop(m);
        }
    }

    /// `G`: registers the placement on the kept frames (the window waits meanwhile).
    pub(super) fn register(&mut self) {
        let Some(start) = self.state.placement else {
            return;
        };
        let kept = self.placer.view_count();
        if kept < 2 {
            self.toast_error(format!(
                "G registers on frames from different directions: {kept} kept so far; move the camera around the prop (tracked frames 4 degrees apart are kept)"
            ));
            return;
        }
        let prop = self.pipeline.first_prop();
        let key_s = self.state.key_pose().frame as f32 / self.fps;
        let key = pa_model::anim::sample(&prop.model, prop.animation, key_s);
        match self.placer.register(&prop.model, &key, &start) {
            Ok(r) => {
                let d = r.placement.change_from(&r.start);
                self.state.set_placement(values_of(&r));
                self.place_pipeline();
                self.toast(format!(
                    "registered on {} frames: {:+.1} {:+.1} {:+.1} mm, {:+.1} deg; residual {:.2} px (W writes it)",
                    r.views.len(), d[0], d[1], d[2], d[3], r.residual_px
                ));
            }
            Err(e) => self.toast_error(format!("{e:#}")),
        }
    }

    /// `W`: writes the placement into the shot file (backup first).
    pub(super) fn write_placement(&mut self) {
        let Some(p) = self.state.placement else {
            return;
        };
        match self.placer.write(&p) {
            Ok((shot, backup)) => {
                self.state.placement_written();
                let msg = format!("wrote {} (backup {})", shot.display(), backup.display());
                self.toast(msg);
            }
            Err(e) => self.toast_error(format!("writing the placement: {e:#}")),
        }
    }
}

/// The state's values of a registration's answer.
pub fn values_of(r: &Registration) -> PlacementValues {
    PlacementValues {
        translation_m: r.placement.translation_m,
        yaw_deg: r.placement.yaw_deg,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use pa_camera::Intrinsics;

    fn view_from(az_deg: f32) -> Mat4 {
        let az = az_deg.to_radians();
        let eye = glam::Vec3::new(0.5 * az.sin(), 0.5 * az.cos(), -0.3);
        pa_camera::camera_from_world_look_at(eye, glam::Vec3::ZERO, glam::Vec3::NEG_Z)
            .expect("view")
    }

    #[test]
    fn keeps_frames_from_new_directions_only() {
        let (mut p, v) = Placer::new(None, &Placement::default());
        assert_eq!(v.translation_m, [0.0; 3]);
        assert_eq!(p.scale, 1.0);
        let camera = CameraModel::pinhole(Intrinsics::from_fov_y(0.8, 32, 24).expect("k"));
        let px = vec![0u8; 32 * 24 * 4];
        p.remember("a", &px, (32, 24), camera, view_from(0.0));
        p.remember("b", &px, (32, 24), camera, view_from(1.0));
        assert_eq!(p.view_count(), 1, "1 degree away is the same view");
        p.remember("c", &px, (32, 24), camera, view_from(10.0));
        assert_eq!(p.view_count(), 2);
        for k in 0..20 {
            p.remember("d", &px, (32, 24), camera, view_from(20.0 + 5.0 * k as f32));
        }
        assert_eq!(p.view_count(), MAX_VIEWS);
        // The oldest went first.
        assert!(p.views.iter().all(|v| v.name == "d"));
        // Another frame size replaces the kept ones.
        let px2 = vec![0u8; 16 * 12 * 4];
        p.remember("e", &px2, (16, 12), camera, view_from(0.0));
        assert_eq!(p.view_count(), 1);
        // No shot file: W says why.
        let e = p.write(&v).expect_err("no shot").to_string();
        assert!(e.contains("built-in scene has no shot file"), "{e}");
    }
}
