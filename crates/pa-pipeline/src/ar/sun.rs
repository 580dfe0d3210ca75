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
///
/// It also keeps the key pose's shadow map ([`KeyShadow`]) from frame to frame: the key pose
/// stands still in the world, and so does the light.
#[derive(Debug, Clone, Default)]
pub(super) struct SunTrack {
    sum: Vec3,
    frames: u32,
    key: Option<KeyShadow>,
}

/// The key pose's shadow map along the light as it was when drawn, and each key vertex's
/// fraction of the sun read from it: the same on every frame while the key pose and the light
/// stay, so they are drawn again only when either moves (measured at 1280x720 with the
/// texture memory on: the texture stage 8.74-9.30 -> 8.35-8.70 ms).
#[derive(Debug, Clone)]
struct KeyShadow {
    /// The coarse meshes' key-pose vertices the map was drawn from, one list per primitive.
    vertices: Vec<Vec<Vec3>>,
    /// The direction towards the light the map was drawn along.
    toward: Vec3,
    map: ShadowMap,
    /// One per primitive (in the caller's order), filled on first use.
    lit: Vec<KeyLit>,
}

/// One primitive's key-pose vertices and the fraction of the sun each receives in
/// [`KeyShadow::map`].
#[derive(Debug, Clone, Default)]
struct KeyLit {
    positions: Vec<Vec3>,
    normals: Vec<Vec3>,
    lit: Vec<f32>,
}

impl KeyLit {
    /// The fractions of `p`'s key vertices in `map`: kept when `p`'s key pose is the one
    /// they were read for, read again otherwise.
    fn update(&mut self, p: &SunPrimitive<'_>, map: &ShadowMap) -> &[f32] {
        if self.positions != p.key_positions || self.normals != p.key_normals {
            self.positions.clear();
            self.positions.extend_from_slice(p.key_positions);
            self.normals.clear();
            self.normals.extend_from_slice(p.key_normals);
            (0..p.key_positions.len())
                .into_par_iter()
                .with_min_len(1024)
                .map(|i| {
                    let n = p.key_normals.get(i).copied().unwrap_or_default();
                    map.lit_vertex(p.key_positions[i], n)
                })
                .collect_into_vec(&mut self.lit);
        }
        &self.lit
    }
}

/// The largest angle (radians) the light may turn before the key pose's shadow map is drawn
/// along it again: a shadow edge moves by `tan(angle)` of its occluder's distance, here a
/// sixty-fourth, one cell of the map ([`pa_raster::sun::SHADOW_MAP_CELLS`] along the twin)
/// for an occluder the twin's whole size away.
const KEY_MAP_MAX_TURN: f32 = 0.9 * std::f32::consts::PI / 180.0;

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
/// track's. The key pose's shadow map stays in `track` from frame to frame: drawn again when
/// the key pose moves or the direction turns by more than [`KEY_MAP_MAX_TURN`] from the
/// map's, which the frame takes otherwise. `None` (and `sun_lit` emptied) when the light has
/// no sun.
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
    // The key pose's map of an earlier frame, while the key pose is the same.
    let kept = track.key.take().filter(|k| k.vertices == key_vertices);
    let toward = match known {
        Some(_) => start,
        None => track.add(match &kept {
            Some(k) => crate::sun_fit::direction_in_key_shadow(samples, start, &k.map),
            None => crate::sun_fit::direction_on_key_pose(samples, start, &key),
        }),
    };
    // While the light stays within KEY_MAP_MAX_TURN of that map's, the frame takes the map's
    // direction for both poses and the fit.
    let kept = kept.filter(|k| k.toward.angle_between(toward) <= KEY_MAP_MAX_TURN);
    let (mut key_shadow, anim_map, toward) = match kept {
        Some(k) => {
            let anim_map = ShadowMap::new(k.toward, &anim);
            let toward = k.toward;
            (k, anim_map, toward)
        }
        None => {
            let (map, anim_map) = rayon::join(
                || ShadowMap::new(toward, &key),
                || ShadowMap::new(toward, &anim),
            );
            let vertices = key_vertices;
            let lit = Vec::new();
            let key_shadow = KeyShadow {
                vertices,
                toward,
                map,
                lit,
            };
            (key_shadow, anim_map, toward)
        }
    };
    let key_map = &key_shadow.map;
    let lit: Vec<f32> = samples
        .iter()
        .map(|s| key_map.lit(s.position_world, s.normal_world))
        .collect();
    let sun = crate::sun_fit::fit_sun(samples, toward, &lit);
    log::debug!("sun: {sun:?}");
    if sun.is_some() {
        key_shadow.lit.resize_with(prims.len(), KeyLit::default);
        let KeyShadow { map, lit, .. } = &mut key_shadow;
        // Primitives in parallel too: many small props are many short lists.
        prims
            .par_iter()
            .zip(lit.par_iter_mut())
            .map(|(p, key_lit)| {
                let key_lit = key_lit.update(p, map);
                let mut out = Vec::new();
                (0..p.key_positions.len())
                    .into_par_iter()
                    .with_min_len(1024)
                    .map(|i| {
                        let ap = p
                            .anim_positions
                            .get(i)
                            .copied()
                            .unwrap_or(p.key_positions[i]);
                        let an = p.anim_normals.get(i).copied().unwrap_or_default();
                        [key_lit[i], anim_map.lit_vertex(ap, an)]
                    })
                    .collect_into_vec(&mut out);
                out
            })
            .collect_into_vec(sun_lit);
    }
    track.key = Some(key_shadow);
    sun
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

    /// Vertices along a side of [`post_on_floor`]'s floor.
    const FLOOR_SIDE: u32 = 41;

    /// A floor 1 m square (`FLOOR_SIDE` squared vertices, z = 0, normals up and bumpy, listed
    /// first) with a post 0.2 m square and 0.6 m tall
    /// at its centre, faces with their own vertices and outward normals: `(positions,
    /// normals, triangle indices)`.
    fn post_on_floor() -> (Vec<Vec3>, Vec<Vec3>, Vec<u32>) {
        let (mut p, mut n, mut t) = (Vec::new(), Vec::new(), Vec::new());
        let (side, last) = (FLOOR_SIDE, (FLOOR_SIDE - 1) as f32);
        for j in 0..side {
            for i in 0..side {
                p.push(Vec3::new(i as f32 / last - 0.5, j as f32 / last - 0.5, 0.0));
                // Bumpy: a fit over normals of only a few directions is ill-posed.
                let (a, b) = (i as f32, j as f32);
                let tilt = Vec3::new((0.7 * a + 1.3 * b).sin(), (1.1 * a - 0.5 * b).cos(), 0.0);
                n.push((Vec3::Z + 0.5 * tilt).normalize());
                if i + 1 < side && j + 1 < side {
                    let a = j * side + i;
                    t.extend([a, a + 1, a + side + 1, a, a + side + 1, a + side]);
                }
            }
        }
        let (h, w) = (0.6, 0.1);
        let corner = |x: f32, y: f32, z: f32| Vec3::new(x * w, y * w, z * h);
        let faces = [
            ([(-1., -1.), (1., -1.)], Vec3::NEG_Y),
            ([(1., -1.), (1., 1.)], Vec3::X),
            ([(1., 1.), (-1., 1.)], Vec3::Y),
            ([(-1., 1.), (-1., -1.)], Vec3::NEG_X),
        ];
        for ([(x0, y0), (x1, y1)], normal) in faces {
            let a = p.len() as u32;
            p.extend([
                corner(x0, y0, 0.0),
                corner(x1, y1, 0.0),
                corner(x1, y1, 1.0),
                corner(x0, y0, 1.0),
            ]);
            n.extend([normal; 4]);
            t.extend([a, a + 1, a + 2, a, a + 2, a + 3]);
        }
        let a = p.len() as u32;
        p.extend([(-1., -1.), (1., -1.), (1., 1.), (-1., 1.)].map(|(x, y)| corner(x, y, 1.0)));
        n.extend([Vec3::Z; 4]);
        t.extend([a, a + 1, a + 2, a, a + 2, a + 3]);
        (p, n, t)
    }

    /// The sun's fractions of one primitive, the same in both poses, with the coarse mesh
    /// `shadow` (made once, from the model as loaded), lit by a sun along `truth` and taken
    /// to be along `known`, from `track`.
    fn sun_lit_of(
        (positions, normals, indices): (&[Vec3], &[Vec3], &[u32]),
        shadow: &CoarseMesh,
        truth: Vec3,
        known: Vec3,
        track: &mut SunTrack,
    ) -> (SunLight, Vec<Vec<[f32; 2]>>) {
        let prims = [SunPrimitive {
            key_positions: positions,
            key_normals: normals,
            anim_positions: positions,
            anim_normals: normals,
            shadow,
        }];
        // Every vertex a sample under an ambient of 0.3 and a sun of 0.7, shadows included,
        // with a little noise (the fit drops its largest residuals: no ties).
        let map = ShadowMap::new(truth, &[(positions, indices)]);
        let samples: Vec<_> = positions
            .iter()
            .zip(normals)
            .enumerate()
            .map(|(i, (&p, &n))| {
                let noise = 0.01 * (i as f32 * 12.9898).sin();
                let e = 0.3 + 0.7 * map.lit_vertex(p, n) * n.dot(truth).max(0.0) + noise;
                IrradianceSample {
                    normal_world: n,
                    position_world: p,
                    ratio_rgb: [e; 3],
                }
            })
            .collect();
        let light = Irradiance::constant([1.0; 3]);
        let mut sun_lit = Vec::new();
        let sun = sun_on_primitives(&light, &samples, Some(known), track, &prims, &mut sun_lit);
        (
            sun.unwrap_or_else(|| panic!("no sun along {known}")),
            sun_lit,
        )
    }

    /// The key pose's shadow map (and its vertices' fractions of the sun) is kept from frame
    /// to frame while the light turns by less than `KEY_MAP_MAX_TURN` (the frame then takes
    /// the map's direction), and drawn again, as on a take's first frame, when the light
    /// turns further or the key pose moves.
    #[test]
    fn the_key_pose_shadow_map_is_kept_until_the_light_turns_or_the_key_pose_moves() {
        let (positions, normals, indices) = post_on_floor();
        let post = (positions.as_slice(), normals.as_slice(), indices.as_slice());
        let shadow = pa_raster::sun::coarse_mesh(&positions, &indices);
        let l0 = Vec3::new(1.0, 0.3, 0.7).normalize();
        let turned = |deg: f32| glam::Quat::from_rotation_z(deg.to_radians()) * l0;
        let fresh = |mesh, l| sun_lit_of(mesh, &shadow, l, l, &mut SunTrack::default());
        let mut track = SunTrack::default();
        let (sun0, lit0) = sun_lit_of(post, &shadow, l0, l0, &mut track);
        assert!(angle_deg(sun0.toward_light, l0) < 1e-3);
        let shadowed = lit0.iter().flatten().filter(|l| l[0] < 0.5).count();
        assert!(shadowed > 5, "the post casts a shadow: {shadowed} vertices");
        // Taken half a degree off: the map along l0 is kept, and so is everything drawn
        // along it.
        let (sun, lit) = sun_lit_of(post, &shadow, l0, turned(0.5), &mut track);
        assert_eq!((sun, &lit), (sun0, &lit0));
        // The light moved five degrees: drawn again along it, as a fresh take draws it.
        let l5 = turned(5.0);
        let (sun, lit) = sun_lit_of(post, &shadow, l5, l5, &mut track);
        assert_eq!((sun, lit.clone()), fresh(post, l5));
        assert_ne!(lit, lit0, "the shadow moved with the light");
        // A key vertex the coarse mesh does not carry moved into the shadow: the map is
        // kept (its vertices did not move), the vertex's fraction is read again.
        let coarse = &shadow.vertices;
        let lit_at = |i: usize| lit[0][i][0];
        let floor = (FLOOR_SIDE * FLOOR_SIDE) as usize;
        let dark = (0..floor)
            .find(|&j| lit_at(j) == 0.0)
            .expect("a shadowed floor vertex");
        let bright = (0..floor)
            .find(|&i| lit_at(i) == 1.0 && !coarse.contains(&(i as u32)))
            .expect("a lit floor vertex not in the coarse mesh");
        let mut one_moved = positions.clone();
        one_moved[bright] = positions[dark];
        let one_moved = (one_moved.as_slice(), normals.as_slice(), indices.as_slice());
        let (sun, lit) = sun_lit_of(one_moved, &shadow, l5, l5, &mut track);
        assert_eq!(lit[0][bright][0], 0.0);
        assert_eq!((sun, lit), fresh(one_moved, l5));
        // The key pose moved 5 cm (the same light): drawn again.
        let moved: Vec<Vec3> = positions.iter().map(|p| *p + Vec3::X * 0.05).collect();
        let moved = (moved.as_slice(), normals.as_slice(), indices.as_slice());
        let (sun, lit) = sun_lit_of(moved, &shadow, l5, l5, &mut track);
        assert_eq!((sun, lit), fresh(moved, l5));
    }
}
