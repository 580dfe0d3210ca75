//! The shot's `[texture]` table: how live samples become the twin's colour
//! ([`crate::ar::LiveLook`]).
//!
//! ```toml
//! [texture]
//! relight = false   # do not shade the live texture at the in-between's normals
//! sun = false       # relight with the first-order light only (no sun, no cast shadows)
//! feather = false   # hard seams between live and fallback colour
//! grazing = false   # no grazing reflection (the glossy rim the key view did not show)
//! ```

use serde::{Deserialize, Serialize};

/// The shot's `[texture]`: relighting, the sun and feathered seams (`crate::ar::LiveLook`),
/// all on unless the shot switches them off (as [`crate::ar::ArSettings::ours`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ShotTexture {
    /// Shade live samples at the in-between's normal with the set's light.
    pub relight: bool,
    /// Blend live and fallback colour smoothly instead of hard seams.
    pub feather: bool,
    /// Relight with the set's sun and the twin's own cast shadows.
    pub sun: bool,
    /// With `relight`: the reflection a glossy prop shows at grazing angles
    /// ([`crate::grazing`]).
    pub grazing: bool,
}

impl Default for ShotTexture {
    fn default() -> Self {
        let look = crate::ar::ArSettings::ours().look;
        Self {
            relight: look.relight,
            feather: look.feather,
            sun: look.sun,
            grazing: look.grazing,
        }
    }
}

impl ShotTexture {
    /// The defaults (what the shot writer leaves out).
    pub fn is_empty(&self) -> bool {
        *self == Self::default()
    }

    /// The pipeline's look (the sun only relights: off without `relight`).
    pub fn look(&self) -> crate::ar::LiveLook {
        crate::ar::LiveLook {
            relight: self.relight,
            feather: self.feather,
            sun: self.relight && self.sun,
            grazing: self.relight && self.grazing,
        }
    }
}
