//! The pipeline's settings: how the twin is textured, how the real prop is removed, which
//! renderer runs the texture stage.

use pa_render::Renderer;

/// How the twin is textured.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Texturing {
    /// Sampled from the live frame at the key-pose projection. With `visibility`, key-pose
    /// points hidden from the camera (occluded, facing away, or seen so obliquely that the
    /// in-between would stretch their few pixels) take the model's texture, shaded by the
    /// set's light as measured on the visible key prop ([`crate::shading`]); without, they
    /// sample whatever the frame shows there (the paper; back-facing and outside points take
    /// the model's texture times one colour gain).
    Live { visibility: bool },
    /// The model's own base-colour texture (no live sampling).
    ModelTexture,
}

/// How the real prop is removed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Fill {
    /// The paper's screen-space rectangle with boundary averages.
    PaperRectangle,
    /// Inverse-distance ray fill over the dilated key-pose silhouette.
    Rays,
    /// The clean plate warped by the table-plane homography (ray fill where it has no data).
    CleanPlate,
    /// The patch fill ([`pa_diminish::patch`], PixMix class): continues the surroundings'
    /// structure and texture into the hole, seeded by the previous frame's result warped by
    /// the table-plane homography (kept by the pipeline, forgotten by
    /// [`crate::ar::ArPipeline::reset_tracker`]). With `plate`, the clean plate (when the
    /// pipeline has one) is used where it has data and the patch fill covers the rest.
    Patch { plate: bool },
    /// No diminishing (the real prop stays visible).
    None,
}

/// Which renderer runs the texture stage (the key-pose depth, the visibility map and the
/// live-textured twin). Both compute the same image (`tests/cpu_gpu_parity.rs` bounds the
/// difference); `propsalive bench --render-path` compares their speed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RenderPath {
    /// wgpu ([`pa_render::Renderer`]): the GPU, or Mesa's software drivers without one.
    Gpu,
    /// Our own rasteriser ([`pa_raster`]): work proportional to the prop, not the frame.
    Cpu,
}

impl RenderPath {
    /// The faster path for this renderer: the CPU path when wgpu runs on a software
    /// rasteriser (measured: see the README's speed section), the GPU otherwise.
    /// `PROPSALIVE_RENDER_PATH=cpu|gpu` overrides.
    pub fn auto(renderer: &Renderer) -> Self {
        match std::env::var("PROPSALIVE_RENDER_PATH").ok().as_deref() {
            Some("cpu") => Self::Cpu,
            Some("gpu") => Self::Gpu,
            _ if renderer.is_software() => Self::Cpu,
            _ => Self::Gpu,
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            Self::Gpu => "gpu",
            Self::Cpu => "cpu",
        }
    }
}

/// A render path name other than `gpu` or `cpu` ([`RenderPath`]'s `FromStr`).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("render path {given:?}: expected gpu or cpu")]
pub struct ParseRenderPathError {
    /// The name given.
    pub given: String,
}

impl std::str::FromStr for RenderPath {
    type Err = ParseRenderPathError;
    fn from_str(s: &str) -> Result<Self, ParseRenderPathError> {
        match s {
            "gpu" => Ok(Self::Gpu),
            "cpu" => Ok(Self::Cpu),
            _ => Err(ParseRenderPathError { given: s.into() }),
        }
    }
}

/// Settings of the frame pipeline.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ArSettings {
    pub texturing: Texturing,
    pub fill: Fill,
    /// Dilation of the key-pose silhouette, pixels.
    pub dilate_px: u32,
    /// Anti-aliased twin edges ([`crate::composite`]).
    pub anti_alias: bool,
    /// How a live sample becomes the twin's colour (with visibility only: the light is
    /// measured then).
    pub look: LiveLook,
    /// Align the clean plate to the frame on the pixels around the mask before it fills
    /// (`pa_diminish::plate_align`: the homography from two tracked poses is off by their
    /// errors); clean-plate fills, the marker's hiding by a plate, and the patch fill's
    /// previous-frame prior.
    pub align_plate: bool,
}

/// How a live sample becomes the twin's colour (`pa_raster::look`; both render paths).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct LiveLook {
    /// Shade live samples at the in-between's normal with the set's light measured on the key
    /// prop ([`crate::shading`]): times `E(n_anim) / E(n_key)`.
    pub relight: bool,
    /// Blend live and fallback colour with a weight that goes smoothly to 0 towards each
    /// fallback condition, instead of hard seams.
    pub feather: bool,
    /// With `relight`: model the set's light as a sun plus ambient with the twin's own cast
    /// shadows ([`crate::sun_fit`], [`pa_raster::sun`]) where the key prop's shading fits one,
    /// instead of the first-order light alone: a part that turns away from the sun, or into
    /// the shadow of another part, darkens to the ambient.
    pub sun: bool,
    /// With `relight` and the sun: add the light a glossy prop reflects where the in-between
    /// turns a surface edge-on to the camera, and take the key view's out
    /// ([`crate::grazing`], `pa_raster::look`); measured on the key frame against the sun's
    /// light, zero for a matte prop (and without the sun, which the measure needs).
    pub grazing: bool,
}

impl LiveLook {
    /// Hard seams, no relighting (the look before issue 13).
    pub const PLAIN: Self = Self {
        relight: false,
        feather: false,
        sun: false,
        grazing: false,
    };
    /// Relighting and feathered seams (our default, [`ArSettings::ours`]).
    pub const RELIT_FEATHERED: Self = Self {
        relight: true,
        feather: true,
        sun: true,
        grazing: true,
    };
}

impl ArSettings {
    /// Our method: live texturing with visibility, relit with feathered seams, ray fill, 4 px
    /// dilation, anti-aliased edges.
    pub fn ours() -> Self {
        Self {
            texturing: Texturing::Live { visibility: true },
            fill: Fill::Rays,
            dilate_px: 4,
            anti_alias: true,
            look: LiveLook::RELIT_FEATHERED,
            align_plate: true,
        }
    }

    /// The paper's method: live texturing without visibility, rectangle fill.
    pub fn paper() -> Self {
        Self {
            texturing: Texturing::Live { visibility: false },
            fill: Fill::PaperRectangle,
            dilate_px: 0,
            anti_alias: false,
            look: LiveLook::PLAIN,
            align_plate: false,
        }
    }
}
