//! What a real set has that the default set does not: the options of
//! [`crate::SceneSpec::set`] and the named scene variants of `propsalive eval --scene` and
//! `propsalive demo --scene`.
//!
//! - `shadows`: the key light (and the fill light, when there is one) casts a soft shadow of
//!   the prop onto the table and the sheet, and the prop darkens the table where it meets it
//!   (contact shadow); in the inputs (the key prop's shadow), in the ground truth (the
//!   in-between's shadow: the truth of an AR frame is the set as if the animated prop stood
//!   there), not in the clean plate (no prop).
//! - `edge`: the prop stands across the sheet's back edge (away from the camera), half its
//!   pedestal on the table, and on half of the back middle tag (id 1, which then never
//!   decodes): the key prop's outline crosses paper, tag and wood.
//! - `covered-tag`: the prop's pedestal reaches 3 mm into the printed square of the front
//!   middle tag (id 6: its white quiet zone, 5.6 mm wide, up to the black border), and the
//!   tag still decodes (measured: in every frame where it does on the default set; 1.5 mm
//!   farther, touching the black border, it no longer does).
//! - `cloth`: the table is a woven cloth (plain weave with coloured bands) instead of wood.
//! - `fill-light`: a second, cooler light from the camera's right.
//! - `high-camera`: the camera looks down 24 deg more steeply (52-58 deg instead of 28-34):
//!   the background behind the head in the image, where the in-betweens reveal it, is then
//!   the sheet and its back edge about 0.1 m behind the prop, and the prop's cast shadow,
//!   instead of the table far behind.
//! - `picture`: the marker is a printed picture (`crate::scene::marker_picture`, the sheet's
//!   size) instead of the board of tags, tracked by its natural features
//!   (`pa_track::TrackTarget::Image`); not part of `hard`.
//! - `hard`: all of them (`edge` takes precedence over `covered-tag` for the placement; the
//!   edge placement covers a tag too).
//!
//! The default (`default`, or no `--scene`) is the set as it always was.

use glam::{Mat4, Vec2, Vec3};
use pa_camera::Intrinsics;
use pa_render::{DirectionalLight, RenderedFrame};

use crate::scene::{Background, BOARD_SHEET_M};
use crate::shadow::{AreaLight, ContactShadow, PlaneShadows};
use crate::SceneError;

/// Where the prop stands on the board.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Placement {
    /// At the board's centre, inside the ring of tags (the default).
    #[default]
    Centre,
    /// Across the sheet's back edge (-Y, away from the camera): half the pedestal on the
    /// table.
    SheetEdge,
    /// On the quiet zone of the front middle tag (id 6), which still decodes.
    CoveredTag,
}

impl Placement {
    /// The prop's position on the marker plane, metres.
    pub fn offset_m(self) -> Vec2 {
        match self {
            Placement::Centre => Vec2::ZERO,
            Placement::SheetEdge => Vec2::new(0.0, -BOARD_SHEET_M * 0.5),
            Placement::CoveredTag => Vec2::new(0.0, 0.012),
        }
    }
}

/// The set's options beyond the default set (all off by default).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct SetOptions {
    /// Soft cast shadows of every light and the contact shadow.
    pub shadows: bool,
    pub placement: Placement,
    /// The second light ([`fill_light`]).
    pub fill_light: bool,
    /// The camera looks down more steeply ([`crate::scene::HIGH_CAMERA_RAISE_DEG`]).
    pub high_camera: bool,
    /// The marker is a printed picture, not tags ([`crate::scene::marker_picture`]).
    pub picture_marker: bool,
}

impl SetOptions {
    /// Side of the printed sheet on the table, metres: the board's, or the picture's.
    pub fn sheet_side_m(&self) -> f32 {
        if self.picture_marker {
            crate::scene::MARKER_PICTURE_M
        } else {
            BOARD_SHEET_M
        }
    }

    /// True for the default set (nothing added).
    pub fn is_default(&self) -> bool {
        *self == Self::default()
    }
}

/// The fill light: cooler and dimmer than the key light, from the camera's right and front
/// (the key light comes from the left and behind).
pub fn fill_light() -> DirectionalLight {
    DirectionalLight {
        toward_light_world: Vec3::new(0.9, 0.5, -0.6),
        radiance_rgb: [0.1, 0.13, 0.2],
    }
}

/// Angular radius of the key light's disc (a softbox about 0.2 m across at 1.5 m).
pub const KEY_LIGHT_RADIUS_DEG: f32 = 4.0;
/// Angular radius of the fill light's disc (a larger, softer source).
pub const FILL_LIGHT_RADIUS_DEG: f32 = 10.0;
/// Directions sampled over a light's disc.
pub const LIGHT_SAMPLES: u32 = 24;
/// The contact shadow's ambient occlusion.
pub const CONTACT: ContactShadow = ContactShadow {
    radius_m: 0.03,
    samples: 32,
};

/// The shadow-casting lights of a set: the key light, then the fill light when present.
pub fn shadow_lights(key: &DirectionalLight, fill: Option<&DirectionalLight>) -> Vec<AreaLight> {
    let mut lights = vec![AreaLight {
        toward_light: key.toward_light_world,
        angular_radius_rad: KEY_LIGHT_RADIUS_DEG.to_radians(),
        samples: LIGHT_SAMPLES,
    }];
    if let Some(f) = fill {
        lights.push(AreaLight {
            toward_light: f.toward_light_world,
            angular_radius_rad: FILL_LIGHT_RADIUS_DEG.to_radians(),
            samples: LIGHT_SAMPLES,
        });
    }
    lights
}

/// A named scene variant: the set's options and the table, if the variant names one.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct SceneVariant {
    pub set: SetOptions,
    pub background: Option<Background>,
}

/// The feature names [`parse_variant`] accepts, in the order of its help.
pub const VARIANT_NAMES: [&str; 9] = [
    "default",
    "shadows",
    "edge",
    "covered-tag",
    "cloth",
    "fill-light",
    "high-camera",
    "picture",
    "hard",
];

/// Parses a comma-separated list of variant names (`hard`, or e.g. `shadows,edge,cloth`).
pub fn parse_variant(list: &str) -> Result<SceneVariant, SceneError> {
    let mut v = SceneVariant::default();
    let (mut edge, mut covered) = (false, false);
    for name in list.split(',').map(str::trim) {
        match name {
            "default" => {}
            "shadows" => v.set.shadows = true,
            "edge" => edge = true,
            "covered-tag" => covered = true,
            "cloth" => v.background = Some(Background::Cloth),
            "fill-light" => v.set.fill_light = true,
            "high-camera" => v.set.high_camera = true,
            "picture" => v.set.picture_marker = true,
            "hard" => {
                v.set.shadows = true;
                v.set.fill_light = true;
                v.set.high_camera = true;
                v.background = Some(Background::Cloth);
                edge = true;
                covered = true;
            }
            other => {
                return Err(SceneError::UnknownVariant {
                    name: other.to_string(),
                    known: VARIANT_NAMES.join(", "),
                })
            }
        }
    }
    v.set.placement = if edge {
        Placement::SheetEdge
    } else if covered {
        Placement::CoveredTag
    } else {
        Placement::Centre
    };
    Ok(v)
}

/// The plane's lighting terms for the shadow pass: the ambient and, per light, its radiance
/// times the cosine on the plane (normal -Z), linear RGB.
#[derive(Debug, Clone)]
pub(crate) struct PlaneLighting {
    pub ambient: [f32; 3],
    pub direct: Vec<[f32; 3]>,
}

impl PlaneLighting {
    pub fn new(ambient: [f32; 3], lights: &[&DirectionalLight]) -> Self {
        let direct = lights
            .iter()
            .map(|l| {
                let c = (-l.toward_light_world.normalize_or_zero().z).max(0.0);
                l.radiance_rgb.map(|r| r * c)
            })
            .collect();
        Self { ambient, direct }
    }
}

/// Plane pixels: within this distance of the marker plane (the table lies 0.5 mm under the
/// sheet).
const PLANE_TOLERANCE_M: f32 = 0.0015;

/// sRGB decoding of the 256 codes.
pub(crate) fn srgb_lut() -> [f32; 256] {
    std::array::from_fn(|v| {
        let c = v as f32 / 255.0;
        if c <= 0.04045 {
            c / 12.92
        } else {
            ((c + 0.055) / 1.055).powf(2.4)
        }
    })
}

pub(crate) fn srgb_encode(l: f32) -> u8 {
    let l = l.clamp(0.0, 1.0);
    let c = if l <= 0.003_130_8 {
        12.92 * l
    } else {
        1.055 * l.powf(1.0 / 2.4) - 0.055
    };
    (c * 255.0 + 0.5) as u8
}

/// Adds the fill light's pass (`fill`, lit by the fill light alone) to `base` (ambient + key
/// light) in linear light, and darkens the plane pixels by the shadows: a plane pixel's colour
/// is albedo * (ambient * sky_visibility + sum_k light_visibility_k * direct_k), which is
/// `base * (ambient * sky + v_0 * direct_0) / (ambient + direct_0) + fill * v_1`. A pixel is on
/// the plane when the point its depth gives lies within 1.5 mm of it (`intrinsics` and
/// `camera_from_marker` are the render's).
pub(crate) fn relight(
    base: &mut RenderedFrame,
    fill: Option<&RenderedFrame>,
    plane: &PlaneLighting,
    shadows: Option<&PlaneShadows>,
    intrinsics: &Intrinsics,
    camera_from_marker: Mat4,
) {
    let lut = srgb_lut();
    let marker_from_camera = camera_from_marker.inverse();
    let (fx, fy) = (intrinsics.fx as f32, intrinsics.fy as f32);
    let (cx, cy) = (intrinsics.cx as f32, intrinsics.cy as f32);
    let w = base.width as usize;
    for (i, &z) in base.depth_m.iter().enumerate() {
        if !z.is_finite() {
            continue;
        }
        let mut key_factor = [1f32; 3];
        let mut fill_factor = 1f32;
        if let Some(sh) = shadows {
            let (x, y) = ((i % w) as f32, (i / w) as f32);
            let camera = Vec3::new((x - cx) / fx * z, (y - cy) / fy * z, z);
            let p = marker_from_camera.transform_point3(camera);
            if p.z.abs() <= PLANE_TOLERANCE_M {
                let q = p.truncate();
                let (sky, key) = (sh.ambient_visibility(q), sh.light_visibility(0, q));
                if let Some(d) = plane.direct.first() {
                    for c in 0..3 {
                        let lit = plane.ambient[c] + d[c];
                        if lit > 0.0 {
                            key_factor[c] = (plane.ambient[c] * sky + key * d[c]) / lit;
                        }
                    }
                }
                fill_factor = sh.light_visibility(1, q);
            }
        }
        let unchanged = fill.is_none() && key_factor == [1.0; 3];
        if unchanged {
            continue;
        }
        for c in 0..3 {
            let mut l = lut[base.rgba8[i * 4 + c] as usize] * key_factor[c];
            if let Some(f) = fill {
                l += lut[f.rgba8[i * 4 + c] as usize] * fill_factor;
            }
            base.rgba8[i * 4 + c] = srgb_encode(l);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn variant_names_parse_and_unknown_names_are_refused() {
        assert_eq!(parse_variant("default").ok(), Some(SceneVariant::default()));
        assert!(parse_variant("default").is_ok_and(|v| v.set.is_default()));
        let v = parse_variant("shadows, edge,cloth").expect("parses");
        assert!(v.set.shadows && !v.set.fill_light);
        assert_eq!(v.set.placement, Placement::SheetEdge);
        assert_eq!(v.background, Some(Background::Cloth));
        let v = parse_variant("covered-tag").expect("parses");
        assert_eq!(v.set.placement, Placement::CoveredTag);
        assert_eq!(v.background, None);
        let hard = parse_variant("hard").expect("parses");
        assert_eq!(
            hard,
            parse_variant("shadows,edge,covered-tag,cloth,fill-light,high-camera").expect("parses")
        );
        let e = parse_variant("shadows,sun")
            .expect_err("unknown")
            .to_string();
        assert!(e.contains("\"sun\"") && e.contains("covered-tag"), "{e}");
        for n in VARIANT_NAMES {
            assert!(parse_variant(n).is_ok(), "{n}");
        }
    }

    #[test]
    fn the_edge_placement_straddles_the_sheet_edge_and_covered_tag_reaches_into_a_tag() {
        // The pedestal's radius is 0.24 of the prop's height.
        let r = 0.24 * crate::PropSpec::default().height_m;
        let edge = Placement::SheetEdge.offset_m();
        assert!(edge.y - r < -BOARD_SHEET_M * 0.5 && edge.y + r > -BOARD_SHEET_M * 0.5);
        assert_eq!(edge.x, 0.0);
        let board = crate::scene::set_board();
        let tag = |id: u32| board.tags.iter().find(|t| t.id == id).expect("tag");
        // Tag 1 (back middle): the edge placement stands on half of its printed square.
        let t1 = tag(1);
        assert_eq!(t1.center_m, glam::DVec2::new(0.0, -0.085));
        let printed_half = t1.size_m * 10.0 / 8.0 * 0.5;
        let covered = (edge.y as f64 + r as f64) - (t1.center_m.y - printed_half);
        assert!(
            (0.45..0.65).contains(&(covered / (2.0 * printed_half))),
            "{covered}"
        );
        // Tag 6 (front middle): the covered-tag placement reaches into its printed square
        // (10 cells), not onto its black border (8 cells).
        let t6 = tag(6);
        assert_eq!(t6.center_m, glam::DVec2::new(0.0, 0.085));
        let reach = (Placement::CoveredTag.offset_m().y + r) as f64;
        let printed = t6.center_m.y - t6.size_m * 10.0 / 8.0 * 0.5;
        let border = t6.center_m.y - t6.size_m * 0.5;
        assert!(reach > printed + 0.002 && reach < border - 0.001, "{reach}");
    }
}
