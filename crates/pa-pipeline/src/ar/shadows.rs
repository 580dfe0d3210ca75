//! Shadows in the frame pipeline (off unless [`ArPipeline::set_shadows`]): the key props'
//! cast shadow lifted out of the frame before the fill, and the in-between twins' shadow cast
//! onto the diminished background before the composite, with the same light, softness and
//! darkening. The geometry is [`crate::shadow`]'s, the image math `pa_diminish::shadow`'s.
//!
//! The light is estimated from the frame ([`crate::shadow::estimate_light`]) once, on the
//! first tracked frame that shows a measurable shadow (retried every
//! [`RETRY_FRAMES`] frames until then, the wait doubling after each failed try up to 16
//! times as long), and kept: the set's light does not move. The
//! darkening is measured again on every frame where the key shadow is in view (across its
//! outline, [`crate::shadow::measure_outline`], else by medians); a frame whose
//! predicted shadow region is not measurably darker than its surroundings
//! ([`crate::shadow::MAX_SHADOW_LUMINANCE`]) lifts nothing.

use glam::Vec3;
use pa_diminish::shadow::{cast_shadow, lift_shadow, measure_shadow, SameSurface};
use pa_diminish::{dilate_in_bbox, DilateShape, ImageRgba8, Rect};

use super::texture::Textured;
use super::{mask_from_bools, ArError, ArPipeline, FrameTimes, FrameView};
use crate::shadow::{
    estimate_light, measure_outline, posed_triangles, soft_matte, ShadowLight, ShadowView,
};

/// Frames between the first two tries at estimating the light while none is known; each
/// further failed try doubles the wait ([`retry_frames`]), so that a set without a measurable
/// shadow costs a try (0.3-0.9 s at 640x360) ever more rarely.
pub const RETRY_FRAMES: u32 = 12;

/// Doublings of [`RETRY_FRAMES`] at most: after five failed tries, one every 192 frames.
pub const MAX_RETRY_DOUBLINGS: u32 = 4;

/// Frames to wait after `failed` tries in a row found no light (`failed` at least 1).
pub fn retry_frames(failed: u32) -> u32 {
    RETRY_FRAMES << failed.saturating_sub(1).min(MAX_RETRY_DOUBLINGS)
}

/// Pixels around the key silhouette that are not table (its anti-aliased edge, the contact).
const EXCLUDE_GROW_PX: u32 = 3;

/// What the pipeline keeps for shadows.
#[derive(Debug, Clone, Default)]
pub(super) struct ShadowState {
    enabled: bool,
    light: Option<ShadowLight>,
    /// Given by the caller: never re-estimated.
    fixed: bool,
    /// Frames left before the next estimation try.
    retry_in: u32,
    /// Tries in a row that found no light.
    failed_tries: u32,
}

impl ShadowState {
    /// The light's direction when shadows are on and it is known (finite, non-zero).
    fn sun_direction(&self) -> Option<Vec3> {
        self.enabled
            .then_some(self.light)
            .flatten()
            .map(|l| l.toward_light)
            .filter(|l| l.is_finite() && l.length() > 0.5)
    }
}

/// The props posed at a frame's two times, as triangles in the marker frame.
pub(super) struct ShadowTriangles {
    key: Vec<[Vec3; 3]>,
    anim: Vec<[Vec3; 3]>,
}

impl ArPipeline {
    /// Turns shadows on or off: with them, the key props' cast shadow is lifted from the
    /// frame and the twins cast theirs (see the module docs). Off by default.
    pub fn set_shadows(&mut self, on: bool) {
        self.shadows.enabled = on;
    }

    /// Whether shadows are on.
    pub fn shadows(&self) -> bool {
        self.shadows.enabled
    }

    /// The light the shadows use, once estimated (or given).
    pub fn shadow_light(&self) -> Option<ShadowLight> {
        self.shadows.light
    }

    /// The direction toward the light for the sun's relighting ([`super::sun`]): the shadows'
    /// light when shadows are on and it is known (estimated from the key prop's cast shadow on
    /// an earlier frame, or given), which is better measured than the key prop's shading.
    pub(super) fn sun_direction_from_shadows(&self) -> Option<Vec3> {
        self.shadows.sun_direction()
    }

    /// Gives the light (never re-estimated), or `None` to estimate it from the next frames.
    pub fn set_shadow_light(&mut self, light: Option<ShadowLight>) {
        self.shadows.light = light;
        self.shadows.fixed = light.is_some();
        self.shadows.retry_in = 0;
        self.shadows.failed_tries = 0;
    }

    /// The props' triangles at the frame's key and in-between times, when shadows are on.
    pub(super) fn shadow_triangles(&self, times: FrameTimes) -> Option<ShadowTriangles> {
        if !self.shadows.enabled {
            return None;
        }
        let (mut key, mut anim) = (Vec::new(), Vec::new());
        for p in &self.props {
            let (anim_pose, key_pose) = p.poses(times);
            key.extend(posed_triangles(&p.model, &key_pose, p.marker_from_prop));
            anim.extend(posed_triangles(&p.model, &anim_pose, p.marker_from_prop));
        }
        Some(ShadowTriangles { key, anim })
    }

    /// The frame with the key props' shadow lifted, or `None` when there is nothing to lift
    /// (no light yet, the shadow out of view or not measurably darker).
    pub(super) fn lift_key_shadow(
        &mut self,
        view: &FrameView<'_>,
        textured: &Textured,
        tris: &ShadowTriangles,
    ) -> Result<Option<Vec<u8>>, ArError> {
        let FrameView {
            rgba8,
            width,
            height,
            camera_model,
            camera_from_marker,
            ..
        } = *view;
        let Some((x0, y0, x1, y1)) = textured.key_bbox else {
            return Ok(None);
        };
        let frame = ImageRgba8::new(width, height, rgba8.to_vec())?;
        let mut exclude = mask_from_bools(width, height, &textured.key_mask)?;
        let bbox = Rect::from_inclusive(x0 as u32, y0 as u32, x1 as u32, y1 as u32);
        dilate_in_bbox(&mut exclude, bbox, EXCLUDE_GROW_PX, DilateShape::Disc);
        let print = self
            .surfaces
            .as_ref()
            .map(|(s, _)| s.print_view(&camera_model, camera_from_marker));
        let same = |a: [u32; 2], b: [u32; 2]| print.as_ref().is_some_and(|p| p.same_print(a, b));
        let view = ShadowView {
            frame: &frame,
            camera: &camera_model,
            camera_from_marker,
            exclude: &exclude,
            same_surface: print.is_some().then_some(&same as SameSurface<'_>),
        };
        let state = &mut self.shadows;
        if state.light.is_none() && !state.fixed {
            if state.retry_in == 0 {
                state.light = estimate_light(&view, &tris.key)?;
                state.failed_tries = match state.light {
                    Some(_) => 0,
                    None => state.failed_tries.saturating_add(1),
                };
                state.retry_in = retry_frames(state.failed_tries.max(1));
            } else {
                state.retry_in -= 1;
            }
        }
        let Some(light) = state.light.as_mut() else {
            return Ok(None);
        };
        let Some(matte) = soft_matte(
            &tris.key,
            light,
            &camera_model,
            camera_from_marker,
            width,
            height,
        )?
        else {
            return Ok(None);
        };
        // This frame's darkening where it can be measured: across the outline, else by
        // medians. Nothing lifted where the predicted region is not darker than the table
        // around it.
        let measured = match measure_outline(&view, &tris.key, light)? {
            Some(r) => Some(r),
            None => measure_shadow(&frame, &matte, Some(&exclude))?,
        };
        let ratio = match measured {
            Some(r) if r.luminance() <= crate::shadow::MAX_SHADOW_LUMINANCE => {
                light.ratio_rgb = r.rgb;
                r.rgb
            }
            Some(_) => return Ok(None),
            None => light.ratio_rgb,
        };
        let mut frame = frame;
        lift_shadow(&mut frame, &matte, ratio)?;
        Ok(Some(frame.into_vec()))
    }

    /// Casts the in-between twins' shadow onto `background` with the light of the key
    /// shadow (nothing until a light is known).
    pub(super) fn cast_twin_shadow(
        &self,
        background: &mut ImageRgba8,
        view: &FrameView<'_>,
        tris: &ShadowTriangles,
    ) -> Result<(), ArError> {
        let Some(light) = self.shadows.light else {
            return Ok(());
        };
        let (width, height) = background.size();
        if let Some(matte) = soft_matte(
            &tris.anim,
            &light,
            &view.camera_model,
            view.camera_from_marker,
            width,
            height,
        )? {
            cast_shadow(background, &matte, light.ratio_rgb)?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_sun_takes_the_shadows_light_only_when_shadows_are_on_and_it_is_known() {
        let light = ShadowLight {
            toward_light: Vec3::new(-0.4, 0.48, -0.78),
            softness_px: 0.75,
            ratio_rgb: [0.3; 3],
        };
        let mut state = ShadowState::default();
        assert_eq!(state.sun_direction(), None);
        state.light = Some(light);
        assert_eq!(state.sun_direction(), None, "shadows off");
        state.enabled = true;
        assert_eq!(state.sun_direction(), Some(light.toward_light));
        state.light = Some(ShadowLight {
            toward_light: Vec3::NAN,
            ..light
        });
        assert_eq!(state.sun_direction(), None, "a NaN light");
    }

    #[test]
    fn failed_tries_at_the_light_come_ever_more_rarely() {
        let waits: Vec<u32> = (1..=7).map(retry_frames).collect();
        assert_eq!(waits, [12, 24, 48, 96, 192, 192, 192]);
        assert_eq!(retry_frames(0), RETRY_FRAMES);
        assert_eq!(retry_frames(u32::MAX), 192);
    }
}
