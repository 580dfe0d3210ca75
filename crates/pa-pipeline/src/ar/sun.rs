//! The set's sun on the twins, for either render path: fitted on the key pose's irradiance
//! samples ([`crate::sun_fit`]), then the fraction of it every vertex of both poses receives
//! from a shadow map of all the twins in that pose ([`pa_raster::sun::ShadowMap`]).

use glam::Vec3;
use pa_raster::sun::{CoarseMesh, ShadowMap, SunLight};
use rayon::prelude::*;

use crate::shading::{Irradiance, IrradianceSample};

/// One primitive of a twin in both poses, world (marker) frame: vertex `i` of the key pose is
/// vertex `i` of the animated one.
pub(super) struct SunPrimitive<'a> {
    pub key_positions: &'a [Vec3],
    pub key_normals: &'a [Vec3],
    pub anim_positions: &'a [Vec3],
    pub anim_normals: &'a [Vec3],
    /// The coarse mesh the shadow maps draw.
    pub shadow: &'a CoarseMesh,
}

/// The sun fitted on `samples` starting from the direction of `light` (or along `known`, a
/// direction measured otherwise: the shadows' light), and into `sun_lit` (one entry per
/// primitive, one `[key, animated]` per vertex) the fraction of it each vertex receives.
/// `None` (and `sun_lit` emptied) when the light has no sun.
pub(super) fn sun_on_primitives(
    light: &Irradiance,
    samples: &[IrradianceSample],
    known: Option<Vec3>,
    prims: &[SunPrimitive<'_>],
    sun_lit: &mut Vec<Vec<[f32; 2]>>,
) -> Option<SunLight> {
    sun_lit.clear();
    let start = match known {
        Some(l) => l.normalize(),
        None => crate::sun_fit::sun_direction(light)?,
    };
    // The coarse meshes' vertices in both poses.
    let key_vertices = coarse_vertices(prims, |p| p.key_positions);
    let anim_vertices = coarse_vertices(prims, |p| p.anim_positions);
    let (key, anim) = (
        coarse_meshes(&key_vertices, prims),
        coarse_meshes(&anim_vertices, prims),
    );
    let toward = match known {
        Some(_) => start,
        None => crate::sun_fit::direction_on_key_pose(samples, start, &key),
    };
    let (key_map, anim_map) = rayon::join(
        || ShadowMap::new(toward, &key),
        || ShadowMap::new(toward, &anim),
    );
    let lit: Vec<f32> = samples
        .iter()
        .map(|s| key_map.lit(s.position_world, s.normal_world))
        .collect();
    let sun = crate::sun_fit::fit_sun(samples, toward, &lit)?;
    log::debug!("sun: {sun:?}");
    sun_lit.extend(prims.iter().map(|p| {
        let mut out = Vec::new();
        (0..p.key_positions.len())
            .into_par_iter()
            .with_min_len(1024)
            .map(|i| {
                let kp = p.key_positions[i];
                let kn = p.key_normals.get(i).copied().unwrap_or_default();
                let ap = p.anim_positions.get(i).copied().unwrap_or(kp);
                let an = p.anim_normals.get(i).copied().unwrap_or_default();
                [key_map.lit_vertex(kp, kn), anim_map.lit_vertex(ap, an)]
            })
            .collect_into_vec(&mut out);
        out
    }));
    Some(sun)
}

/// Each primitive's coarse-mesh vertices gathered from its positions in one pose.
fn coarse_vertices<'a>(
    prims: &[SunPrimitive<'a>],
    positions: impl Fn(&SunPrimitive<'a>) -> &'a [Vec3],
) -> Vec<Vec<Vec3>> {
    prims
        .iter()
        .map(|p| {
            let mut v = Vec::new();
            p.shadow.gather(positions(p), &mut v);
            v
        })
        .collect()
}

/// The coarse meshes of one pose as the shadow map takes them: `(vertices, triangles)`.
fn coarse_meshes<'a>(
    vertices: &'a [Vec<Vec3>],
    prims: &'a [SunPrimitive<'_>],
) -> Vec<(&'a [Vec3], &'a [u32])> {
    vertices
        .iter()
        .zip(prims)
        .map(|(v, p)| (v.as_slice(), p.shadow.triangles.as_slice()))
        .collect()
}
