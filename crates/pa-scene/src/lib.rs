//! The scene generator: Props Alive's demo and its measuring instrument.
//!
//! [`prop`] builds the built-in prop (a rigged, textured bust of about 8,000 vertices with a
//! neck turn, a nod and a jaw) as a GLB that goes through the same loader as users' models.
//! [`scene`] puts it on an AprilTag board on a textured table under a light, and renders what a
//! moving camera sees: the physical key prop (the input), the in-between poses as if printed
//! (the ground truth), and a clean plate. [`variant`] is what real sets have beyond the default
//! set (soft cast and contact shadows, the prop across the sheet's edge or on a tag, woven
//! cloth, a fill light) and the named variants of `--scene`; [`shadow`] computes the prop's
//! shadows on the table plane. [`methods`] lists the pipeline configurations `propsalive
//! eval` compares. [`set`] reads takes of the same set rendered by another renderer
//! (Blender) and measures them the same way; [`flicker`] is the temporal metric of the fill.

mod error;
pub mod eval;
pub mod flicker;
pub mod hide;
pub mod memory;
pub mod methods;
pub mod prop;
pub mod scene;
pub mod set;
pub mod shadow;
pub mod tracking;
pub mod variant;

pub use error::{SceneError, SetProblem};
pub use hide::{HideKind, TruthSheet};
pub use prop::{prop_glb, prop_model, PropSpec};
pub use scene::{CoverSheet, Scene, SceneFrame, SceneSpec, SheetLook};
pub use variant::{parse_variant, Placement, SceneVariant, SetOptions};

#[cfg(test)]
mod tests {
    use super::prop::*;
    use pa_model::{anim, skin};

    #[test]
    fn builtin_prop_loads_with_rig_and_clip() {
        let spec = PropSpec::default();
        let model = prop_model(&spec).expect("prop loads");
        assert_eq!(model.vertex_count() as u32, spec.vertex_count());
        assert!(
            (7_500..8_500).contains(&model.vertex_count()),
            "{}",
            model.vertex_count()
        );
        assert_eq!(model.skins[0].joints.len(), 4);
        assert_eq!(model.animations[0].name.as_deref(), Some("Animate"));
        assert!((model.animations[0].duration_s - CLIP_DURATION_S).abs() < 1e-6);
        assert!(model.warnings.is_empty(), "{:?}", model.warnings);
        assert_eq!(model.images[0].width, spec.texture_px);
        // Every weight row sums to 1.
        let prim = &model.meshes[0].primitives[0];
        for w in &prim.weights {
            assert!((w.iter().sum::<f32>() - 1.0).abs() < 1e-5);
        }
    }

    #[test]
    fn the_clip_turns_the_head_by_the_stated_angle() {
        let model = prop_model(&PropSpec::default()).expect("prop loads");
        let prim = &model.meshes[0].primitives[0];
        // The nose tip: the front-most vertex (largest z).
        let (nose, rest) = prim
            .positions
            .iter()
            .enumerate()
            .max_by(|a, b| a.1.z.total_cmp(&b.1.z))
            .expect("vertices");
        let (turn, nod, _) = clip_angles_deg(1.0);
        assert!(nod.abs() < 1e-3 && (turn - 40.0).abs() < 1e-3);
        let posed = skin::pose_meshes(&model, &anim::sample(&model, 0, 1.0));
        let p = posed[0].positions[nose];
        // A rotation about +Y through the neck axis (x = z = 0).
        let expected = glam::Quat::from_rotation_y(turn.to_radians()) * *rest;
        assert!((p - expected).length() < 1e-4, "{p} vs {expected}");
        // At t = 0 the prop is at rest.
        let posed0 = skin::pose_meshes(&model, &anim::sample(&model, 0, 0.0));
        let max_d = posed0[0]
            .positions
            .iter()
            .zip(&prim.positions)
            .map(|(a, b)| (*a - *b).length())
            .fold(0.0, f32::max);
        assert!(max_d < 1e-5, "{max_d}");
    }

    #[test]
    fn vertex_count_presets() {
        for n in [2_000u32, 8_000, 32_000, 128_000] {
            let s = PropSpec::with_vertex_count(n);
            let got = s.vertex_count() as f32;
            assert!((got / n as f32 - 1.0).abs() < 0.1, "{n}: {got}");
        }
    }
}
