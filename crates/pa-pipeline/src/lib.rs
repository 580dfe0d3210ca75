//! The wiring between the stages' pure math and the renderer.
//!
//! [`twin`] uploads a [`pa_model::Model`] to a [`pa_render::Renderer`] once and turns each
//! frame's animation pose into draw data (joint matrices, morph weights), so that skinning runs
//! in the renderer's vertex stage.

pub mod ar;
pub mod composite;
pub mod cpu_twin;
pub mod footprint;
pub mod framing;
pub mod grazing;
pub mod metrics;
pub mod register;
pub mod shading;
pub mod shadow;
pub mod shot;
pub mod shot_config;
pub mod shot_diminish;
pub mod shot_hide;
pub mod shot_scan;
pub mod shot_texture;
pub mod sun_fit;
pub mod twin;

pub use twin::{GpuTwin, TwinFrame};
