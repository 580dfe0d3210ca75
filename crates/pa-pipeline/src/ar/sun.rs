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

/// The sun's direction over the frames of a take, in the world (marker) frame, where the set's
/// light stands still: each frame's own estimate is noisy (on the Blender CesiumMan set 3-12
/// degrees off, 4.4 degrees median between consecutive stills), their running mean is not.
/// A mean of unit vectors over the first [`SunTrack::MEMORY`] frames, then an exponential
/// average with that memory, so that a light that moves is followed.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct SunTrack {
    sum: Vec3,
    frames: u32,
}

impl SunTrack {
    /// Frames the running mean remembers.
    const MEMORY: u32 = 16;

    /// Adds a frame's estimate (unit vector) and returns the direction to use.
    pub(super) fn add(&mut self, toward: Vec3) -> Vec3 {
        if !toward.is_finite() {
            return self.direction().unwrap_or(toward);
        }
        if self.frames >= Self::MEMORY {
            self.sum *= 1.0 - 1.0 / Self::MEMORY as f32;
        } else {
            self.frames += 1;
        }
        self.sum += toward;
        self.direction().unwrap_or(toward)
    }

    fn direction(&self) -> Option<Vec3> {
        (self.frames > 0)
            .then(|| self.sum.normalize_or_zero())
            .filter(|d| *d != Vec3::ZERO)
    }
}

/// The sun fitted on `samples` starting from the direction of `light` (or along `known`, a
/// direction measured otherwise: the shadows' light), and into `sun_lit` (one entry per
/// primitive, one `[key, animated]` per vertex) the fraction of it each vertex receives.
/// Without `known`, the frame's own direction goes into `track` and the fit takes the
/// track's. `None` (and `sun_lit` emptied) when the light has no sun.
pub(super) fn sun_on_primitives(
    light: &Irradiance,
    samples: &[IrradianceSample],
    known: Option<Vec3>,
    track: &mut SunTrack,
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
        None => track.add(crate::sun_fit::direction_on_key_pose(samples, start, &key)),
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
    // Primitives in parallel too: many small props are many short lists.
    prims
        .par_iter()
        .map(|p| {
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
        })
        .collect_into_vec(sun_lit);
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

#[cfg(test)]
mod tests {
    use super::*;

    /// Unit vectors `jitter_deg` off `truth`, each turned about `truth` by the golden angle.
    fn jittered(truth: Vec3, jitter_deg: f32, n: usize) -> Vec<Vec3> {
        let side = truth.any_orthonormal_vector();
        (0..n)
            .map(|i| {
                let about = glam::Quat::from_axis_angle(truth, i as f32 * 2.399_963);
                let off = glam::Quat::from_axis_angle(about * side, jitter_deg.to_radians());
                off * truth
            })
            .collect()
    }

    fn angle_deg(a: Vec3, b: Vec3) -> f32 {
        a.angle_between(b).to_degrees()
    }

    #[test]
    fn the_track_averages_the_frames_jitter_away_and_follows_a_moved_light() {
        let truth = Vec3::new(-0.5, 0.6, 1.0).normalize();
        let mut track = SunTrack::default();
        let frames = jittered(truth, 8.0, 12);
        let used: Vec<Vec3> = frames.iter().map(|&d| track.add(d)).collect();
        assert!(
            angle_deg(used[0], frames[0]) < 1e-3,
            "the first frame is its own"
        );
        // Each frame alone is 8 degrees off; the running mean gets closer frame by frame.
        let last = angle_deg(used[11], truth);
        assert!(last < 1.5, "after 12 frames {last} degrees off");
        // Frame to frame, the direction used moves far less than the frames' own estimates.
        let own_step = angle_deg(frames[10], frames[11]);
        let used_step = angle_deg(used[10], used[11]);
        assert!(used_step < 0.2 * own_step, "{used_step} vs {own_step}");
        // A light that moved 40 degrees is followed within a few memories.
        let moved = glam::Quat::from_rotation_y(40f32.to_radians()) * truth;
        let mut d = Vec3::ZERO;
        for _ in 0..4 * SunTrack::MEMORY {
            d = track.add(moved);
        }
        assert!(
            angle_deg(d, moved) < 2.0,
            "{} degrees behind",
            angle_deg(d, moved)
        );
        // Not finite: the track's direction, unchanged.
        let before = track.add(moved);
        assert_eq!(track.add(Vec3::NAN), before);
        assert!(SunTrack::default().add(Vec3::NAN).is_nan());
    }
}
