//! Cast shadows on the table plane: the geometry (a posed mesh projected along the light onto
//! the marker plane z = 0, then into the frame) and the light, estimated from the frame.
//!
//! The marker frame has +Z into the table (`pa_track`), so the table is z = 0, up is -Z and a
//! light above the table has a direction *toward the light* with z < 0. A point `p` casts its
//! shadow at `p - l p.z / l.z` (the ray from `p` away from the light meets z = 0 there).
//!
//! The light ([`estimate_light`]): the key prop's geometry is known, so each candidate
//! direction predicts a shadow region on the table; the candidate whose region is the most
//! darkened (median colour inside over the lit ring around it, [`pa_diminish::shadow`]) in
//! the sense that its darkening explains the most of the observed luminance, wins,
//! on a coarse grid of directions then a finer one around the best. The winner is then
//! polished to where its outline is sharpest (pairs of pixels across it, each pair on one
//! surface: [`edge_contrast`]), and the softness and darkening are fitted on those pairs at
//! several distances from the outline ([`pa_diminish::shadow::fit_outline`]); the light is
//! kept only when the darkening is measurable ([`MAX_SHADOW_LUMINANCE`]). When that fit
//! finds no darkening (dark print or wood beside the prop posing as a shadow), the next
//! distinct peak of the coarse scores is tried, and after four of them the direction whose
//! outline is sharpest among those whose region is darker. Where the board's print is known
//! ([`ShadowView::same_surface`]), pairs across a tag's black and white are left out: the
//! medians inside and around a region take print for shadow, the pairs do not. Where too
//! little of the outline is in view, the softness and darkening come from those medians.
//! Pixel image math stays in `pa-diminish`; this module knows meshes and cameras.

use glam::{Mat4, Vec3};
use pa_camera::CameraModel;
use pa_diminish::shadow::{
    explained_darkening, fit_outline, fit_softness, lit_luminance, measure_shadow,
    outline_darkenings, SameSurface, ShadowMatte, ShadowRatio,
};
use pa_diminish::{DiminishError, ImageRgba8, Mask};
use pa_model::{anim::Pose, Model};
use rayon::prelude::*;

/// The set's key light as the shadows see it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ShadowLight {
    /// Unit direction toward the light, marker frame (z < 0: above the table).
    pub toward_light: Vec3,
    /// Gaussian standard deviation of the penumbra, pixels.
    pub softness_px: f32,
    /// Shadowed over lit, linear RGB.
    pub ratio_rgb: [f32; 3],
}

/// A frame as the shadow estimate reads it.
#[derive(Clone, Copy)]
pub struct ShadowView<'a> {
    pub frame: &'a ImageRgba8,
    pub camera: &'a CameraModel,
    pub camera_from_marker: Mat4,
    /// The pixels that are not table (the key prop, dilated).
    pub exclude: &'a Mask,
    /// Which pixel pairs show the same surface, when the set's print is known (the board):
    /// the outline compares only those.
    pub same_surface: Option<SameSurface<'a>>,
}

impl ShadowView<'_> {
    /// [`hard_matte`] of `triangles` along `dir` in this view.
    fn hard_matte(
        &self,
        triangles: &[[Vec3; 3]],
        dir: Vec3,
        margin_px: u32,
    ) -> Option<ShadowMatte> {
        let (w, h) = self.frame.size();
        hard_matte(
            triangles,
            dir,
            self.camera,
            self.camera_from_marker,
            margin_px,
            w,
            h,
        )
    }
}

/// A shadow whose luminance ratio is above this is not measurably darker than its
/// surroundings: no light is estimated from it.
pub const MAX_SHADOW_LUMINANCE: f32 = 0.7;

/// Extra pixels around a predicted shadow where the lit ring is measured.
pub const RING_PX: u32 = 12;

/// The margin of a hard matte whose outline is read at several distances: past the farthest
/// pair of [`pa_diminish::shadow::OUTLINE_FIT_STEPS_PX`].
const OUTLINE_MARGIN_PX: u32 = 20;

/// Softness candidates (Gaussian deviation, pixels) for [`estimate_light`].
pub const SOFTNESS_CANDIDATES_PX: [f32; 7] = [0.75, 1.5, 2.5, 4.0, 6.0, 9.0, 13.0];

/// The unit direction toward a light at `azimuth_deg` (about the table's normal, from the
/// marker's +X toward +Y) and `elevation_deg` above the table.
pub fn toward_light(azimuth_deg: f32, elevation_deg: f32) -> Vec3 {
    let (a, e) = (azimuth_deg.to_radians(), elevation_deg.to_radians());
    Vec3::new(e.cos() * a.cos(), e.cos() * a.sin(), -e.sin()).normalize()
}

/// Where `p` (marker frame) casts its shadow on the table along `toward_light`; `p` itself
/// when the light is parallel to the table (no shadow can be cast).
pub fn onto_table(p: Vec3, toward_light: Vec3) -> Vec3 {
    if toward_light.z.abs() < 1e-6 {
        return p;
    }
    p - toward_light * (p.z / toward_light.z)
}

/// The triangles of a model posed at `pose`, placed by `marker_from_prop` (marker frame),
/// each primitive as drawn.
pub fn posed_triangles(model: &Model, pose: &Pose, marker_from_prop: Mat4) -> Vec<[Vec3; 3]> {
    let mut out = Vec::new();
    for p in pa_model::skin::pose_drawn_meshes(model, pose) {
        let Some(prim) = model
            .meshes
            .get(p.mesh)
            .and_then(|m| m.primitives.get(p.primitive))
            .map(pa_model::Primitive::drawn)
        else {
            continue;
        };
        let at = |i: u32| {
            p.positions
                .get(i as usize)
                .map(|v| marker_from_prop.transform_point3(*v))
        };
        for t in prim.indices.chunks_exact(3) {
            if let (Some(a), Some(b), Some(c)) = (at(t[0]), at(t[1]), at(t[2])) {
                out.push([a, b, c]);
            }
        }
    }
    out
}

/// The shadow of `triangles` (marker frame) on the table along `toward_light`, as
/// pixel-space triangles of the frame seen by `camera` at `camera_from_marker` (distortion
/// included). A triangle with a corner behind the camera is dropped.
pub fn shadow_pixel_triangles(
    triangles: &[[Vec3; 3]],
    toward_light: Vec3,
    camera: &CameraModel,
    camera_from_marker: Mat4,
) -> Vec<[[f32; 2]; 3]> {
    let m = camera_from_marker.as_dmat4();
    let px = |p: Vec3| {
        let q = m.transform_point3(onto_table(p, toward_light).as_dvec3());
        camera
            .pixel_from_camera(q)
            .map(|v| [v.x as f32, v.y as f32])
    };
    triangles
        .iter()
        .filter_map(|t| Some([px(t[0])?, px(t[1])?, px(t[2])?]))
        .collect()
}

/// The hard matte of the shadow of `triangles` in a `width x height` frame, with a margin of
/// `margin_px` for softening and the lit ring; `None` when it misses the frame.
pub fn hard_matte(
    triangles: &[[Vec3; 3]],
    toward_light: Vec3,
    camera: &CameraModel,
    camera_from_marker: Mat4,
    margin_px: u32,
    width: u32,
    height: u32,
) -> Option<ShadowMatte> {
    let px = shadow_pixel_triangles(triangles, toward_light, camera, camera_from_marker);
    ShadowMatte::from_triangles(&px, margin_px, width, height)
}

/// The soft matte of the shadow of `triangles` under `light` (the hard matte blurred by its
/// softness).
pub fn soft_matte(
    triangles: &[[Vec3; 3]],
    light: &ShadowLight,
    camera: &CameraModel,
    camera_from_marker: Mat4,
    width: u32,
    height: u32,
) -> Result<Option<ShadowMatte>, DiminishError> {
    match hard_matte(
        triangles,
        light.toward_light,
        camera,
        camera_from_marker,
        RING_PX,
        width,
        height,
    ) {
        Some(m) => Ok(Some(m.soften(light.softness_px)?)),
        None => Ok(None),
    }
}

/// Scores a direction: the darkening its predicted shadow explains
/// ([`explained_darkening`]: higher = better; a region that is only part of the real shadow
/// explains less of it, one that spills onto lit table is penalised there), with the ratio;
/// `None` when too little of it is visible to measure.
fn score(
    view: &ShadowView<'_>,
    key_triangles: &[[Vec3; 3]],
    dir: Vec3,
) -> Result<Option<(f32, ShadowRatio)>, DiminishError> {
    let (frame, exclude) = (view.frame, view.exclude);
    let Some(m) = view.hard_matte(key_triangles, dir, RING_PX) else {
        return Ok(None);
    };
    // A shadow mostly hidden by the prop says nothing: at least a quarter of it in view.
    let Some(r) = measure_shadow(frame, &m, Some(exclude))? else {
        return Ok(None);
    };
    if (r.shadow_samples as f64) < 0.25 * m.area() {
        return Ok(None);
    }
    let Some(lit) = lit_luminance(frame, &m, Some(exclude))? else {
        return Ok(None);
    };
    let e = explained_darkening(frame, &m, &r, lit, Some(exclude))?;
    Ok(Some((e as f32, r)))
}

/// The darkening of the shadow of `triangles` under `light` in the view, measured across its
/// outline: the pairs (of one print, where the print is known) at every distance of
/// [`pa_diminish::shadow::OUTLINE_FIT_STEPS_PX`], fitted with the light's softness, the
/// darkening from those past the penumbra ([`fit_outline`]); `None` when too little of the
/// outline is in view ([`pa_diminish::shadow::MIN_OUTLINE_FIT_PAIRS`]). Pairs straddle one
/// surface, so a shadow across a sheet's edge measures as well as one on a single surface.
pub fn measure_outline(
    view: &ShadowView<'_>,
    triangles: &[[Vec3; 3]],
    light: &ShadowLight,
) -> Result<Option<ShadowRatio>, DiminishError> {
    let Some(m) = view.hard_matte(triangles, light.toward_light, OUTLINE_MARGIN_PX) else {
        return Ok(None);
    };
    Ok(fit_outline(
        view.frame,
        &m,
        &[light.softness_px],
        Some(view.exclude),
        view.same_surface,
    )?
    .map(|f| f.ratio))
}

/// Estimates the key light from the darkening on the table around the key prop: see the
/// module docs. `key_triangles` is the key pose in the marker frame. `Ok(None)` when no
/// direction predicts a measurably darker region.
pub fn estimate_light(
    view: &ShadowView<'_>,
    key_triangles: &[[Vec3; 3]],
) -> Result<Option<ShadowLight>, DiminishError> {
    let score_of = |az: f32, el: f32| -> Result<Option<f32>, DiminishError> {
        Ok(score(view, key_triangles, toward_light(az, el))?
            .filter(|s| s.1.luminance() <= MAX_SHADOW_LUMINANCE)
            .map(|s| s.0))
    };
    let edge_of = |az: f32, el: f32| edge_contrast(view, key_triangles, toward_light(az, el));
    search_light(score_of, edge_of, |az, el| {
        // The direction where its outline is sharpest first; the refined one when the
        // polished gives no light.
        let (paz, pel) = polish(&edge_of, az, el)?;
        match light_along(view, key_triangles, paz, pel)? {
            Some(l) => Ok(Some(l)),
            None if (paz, pel) != (az, el) => light_along(view, key_triangles, az, el),
            None => Ok(None),
        }
    })
}

/// Distances past the outline at which [`edge_contrast`] compares pairs.
const EDGE_STEPS_PX: [f32; 3] = [1.0, 2.0, 3.0];

/// Fewest pairs at a distance of [`EDGE_STEPS_PX`] for [`edge_contrast`] to count it.
const MIN_EDGE_PAIRS: usize = 8;

/// How sharply the frame darkens across the outline of the shadow along `dir`: the mean over
/// [`EDGE_STEPS_PX`] of the pairs' mean log-ratio (outside over inside, pairs of one
/// surface; a mean, so that every misplaced stretch of the outline counts). Highest where the
/// predicted outline lies on the real edge: a displaced outline compares pairs on one side of
/// the edge (both lit or both shadowed). `None` when fewer than two distances have
/// [`MIN_EDGE_PAIRS`] pairs.
fn edge_contrast(
    view: &ShadowView<'_>,
    triangles: &[[Vec3; 3]],
    dir: Vec3,
) -> Result<Option<f32>, DiminishError> {
    let Some(m) = view.hard_matte(triangles, dir, OUTLINE_MARGIN_PX) else {
        return Ok(None);
    };
    let logs: Vec<f32> = outline_darkenings(
        view.frame,
        &m,
        &EDGE_STEPS_PX,
        Some(view.exclude),
        view.same_surface,
    )?
    .into_iter()
    .flatten()
    .filter(|o| o.ratio.shadow_samples >= MIN_EDGE_PAIRS)
    .map(|o| o.mean_log as f32)
    .collect();
    Ok((logs.len() >= 2).then(|| logs.iter().sum::<f32>() / logs.len() as f32))
}

/// The direction `(az, el)` (degrees) moved to where its shadow's outline is sharpest
/// (`edge_of`, [`edge_contrast`] of a direction): a 5x5 grid of 2.5 degrees of azimuth and
/// elevation around it, then one of 0.8 degrees around the best; `(az, el)` itself when its
/// outline is not in view. The search's score weighs the darkening inside the region against
/// its ring, which print and grain there pull; pairs across the outline compare one surface
/// with itself.
fn polish(
    edge_of: &(dyn Fn(f32, f32) -> Result<Option<f32>, DiminishError> + Sync),
    az: f32,
    el: f32,
) -> Result<(f32, f32), DiminishError> {
    let Some(c0) = edge_of(az, el)? else {
        return Ok((az, el));
    };
    let (_, az, el) = climb((c0, az, el), &[(2.5, 2.5), (2.5 / 3.0, 2.5 / 3.0)], edge_of)?;
    Ok((az, el))
}

/// Scores each direction `(azimuth, elevation)` of `dirs` by `by` on the pool's threads; the
/// scored ones as `(score, azimuth, elevation)`, in the order of `dirs`.
fn score_all<E: Send>(
    dirs: &[(f32, f32)],
    by: &(dyn Fn(f32, f32) -> Result<Option<f32>, E> + Sync),
) -> Result<Vec<(f32, f32, f32)>, E> {
    let scores: Vec<Result<Option<f32>, E>> = dirs.par_iter().map(|&(az, el)| by(az, el)).collect();
    let mut out = Vec::with_capacity(dirs.len());
    for (&(az, el), s) in dirs.iter().zip(scores) {
        if let Some(s) = s? {
            out.push((s, az, el));
        }
    }
    Ok(out)
}

/// Climbs `score_of` from `best` (score, azimuth, elevation in degrees): for each spacing
/// `(azimuth, elevation)` of `steps`, the 5x5 grid of that spacing around the best so far
/// (elevations kept within 5..89 degrees) is scored ([`score_all`]), and a direction takes
/// the best's place only by scoring higher. The grid's centre, the best itself, is not
/// scored again.
fn climb<E: Send>(
    mut best: (f32, f32, f32),
    steps: &[(f32, f32)],
    score_of: &(dyn Fn(f32, f32) -> Result<Option<f32>, E> + Sync),
) -> Result<(f32, f32, f32), E> {
    for &(da, de) in steps {
        let (_, a0, e0) = best;
        let grid: Vec<(f32, f32)> = (-2..=2)
            .flat_map(|i| (-2..=2).map(move |j| (i, j)))
            .map(|(i, j)| (a0 + i as f32 * da, (e0 + j as f32 * de).clamp(5.0, 89.0)))
            .filter(|&d| d != (a0, e0))
            .collect();
        for (s, az, el) in score_all(&grid, score_of)? {
            if s > best.0 {
                best = (s, az, el);
            }
        }
    }
    Ok(best)
}

/// [`estimate_light`]'s search, given how a direction `(azimuth, elevation)` scores (the
/// darkening its region explains, `score_of`, `None` where the region is not measurably
/// darker; how sharp its outline is, `edge_of`) and whether a direction gives a light: both
/// scores over the coarse grid (every 15 degrees of azimuth, 20..80 degrees of elevation);
/// candidates are the distinct peaks of the two rankings, four of the region score's first
/// ([`REGION_TURNS`]), then the outline's among the directions whose region is measurably
/// darker (a sharp outline alone can be grain or print). Around a region-score peak a finer
/// grid, twice, at a third of the step each time, by that score (an outline peak goes to
/// `light_at` as it is: the light's polish refines it by its outline). When a candidate
/// gives no light (its outline shows no shadow: dark print or wood posing as one), the next
/// is tried, [`MAX_LIGHT_CANDIDATES`] at most.
fn search_light<E: Send>(
    score_of: impl Fn(f32, f32) -> Result<Option<f32>, E> + Sync,
    edge_of: impl Fn(f32, f32) -> Result<Option<f32>, E> + Sync,
    light_at: impl Fn(f32, f32) -> Result<Option<ShadowLight>, E>,
) -> Result<Option<ShadowLight>, E> {
    let grid: Vec<(f32, f32)> = (0..7)
        .flat_map(|ei| (0..24).map(move |ai| (ai as f32 * 15.0, 20.0 + ei as f32 * 10.0)))
        .collect();
    let mut by_region = score_all(&grid, &score_of)?;
    let darker: Vec<(f32, f32)> = by_region.iter().map(|&(_, a, e)| (a, e)).collect();
    let mut by_edge = score_all(&darker, &edge_of)?;
    // Stable sorts: equal scores keep the grid's order.
    by_region.sort_by(|a, b| b.0.total_cmp(&a.0));
    by_edge.sort_by(|a, b| b.0.total_cmp(&a.0));
    let mut cursors = [0usize; 2];
    // The candidates tried, and by which ranking.
    let mut tried: Vec<(f32, f32, usize)> = Vec::new();
    for turn in 0.. {
        if tried.len() >= MAX_LIGHT_CANDIDATES {
            break;
        }
        let which = usize::from(!REGION_TURNS.get(turn).copied().unwrap_or(turn % 2 == 0));
        let list = if which == 0 { &by_region } else { &by_edge };
        let cursor = &mut cursors[which];
        // The list's next peak: not a neighbour of a candidate of its own ranking (that is
        // the same peak), nor a cell the other ranking tried (a neighbour is refined from
        // another start, by another score).
        let next = loop {
            let Some(&c) = list.get(*cursor) else {
                break None;
            };
            *cursor += 1;
            let taken = tried.iter().any(|&(a, e, w)| {
                if w == which {
                    coarse_neighbours((a, e), (c.1, c.2))
                } else {
                    (a, e) == (c.1, c.2)
                }
            });
            if !taken {
                break Some(c);
            }
        };
        let Some((s0, a0, e0)) = next else {
            if cursors[0] >= by_region.len() && cursors[1] >= by_edge.len() {
                break;
            }
            continue;
        };
        tried.push((a0, e0, which));
        let best = if which == 0 {
            climb(
                (s0, a0, e0),
                &[(5.0, 10.0 / 3.0), (5.0 / 3.0, 10.0 / 9.0)],
                &score_of,
            )?
        } else {
            (s0, a0, e0)
        };
        let light = light_at(best.1, best.2)?;
        if light.is_some() {
            return Ok(light);
        }
    }
    Ok(None)
}

/// Whether each of the first turns of [`search_light`] takes the region score's next peak
/// (else the outline's): four region peaks (the light found from a region peak is the
/// better placed: on CesiumMan's first still the fourth gives it 0.4 degrees off, where the
/// outline's peak gives 1.4), then the outline's.
const REGION_TURNS: [bool; 5] = [true, true, true, true, false];

/// Coarse directions [`estimate_light`] tries at most, each a distinct peak of the coarse
/// scores, before it gives up on the frame.
pub const MAX_LIGHT_CANDIDATES: usize = 5;

/// Whether two directions `(azimuth, elevation)` of [`estimate_light`]'s coarse grid are the
/// same cell or neighbours (one step of 15 degrees of azimuth, 10 of elevation): a
/// neighbour of a tried candidate belongs to its peak.
fn coarse_neighbours((a0, e0): (f32, f32), (a1, e1): (f32, f32)) -> bool {
    let da = (a0 - a1).rem_euclid(360.0);
    da.min(360.0 - da) <= 15.5 && (e0 - e1).abs() <= 10.5
}

/// The light toward `(az, el)` (degrees): its softness and ratio fitted on the frame, or
/// `None` when the shadow it predicts is not measurably darker (across its outline where
/// enough of it is in view, else over its softened region).
fn light_along(
    view: &ShadowView<'_>,
    key_triangles: &[[Vec3; 3]],
    az: f32,
    el: f32,
) -> Result<Option<ShadowLight>, DiminishError> {
    let (frame, exclude) = (view.frame, view.exclude);
    let dir = toward_light(az, el);
    let margin = RING_PX + (3.0 * SOFTNESS_CANDIDATES_PX[6]).ceil() as u32;
    let Some(hard) = view.hard_matte(key_triangles, dir, margin) else {
        return Ok(None);
    };
    // The softness and darkening from the pairs across the outline where enough of it is in
    // view: each pair compares one surface with itself a few pixels away, so print and wood
    // beside the region do not pose as a shadow (an outline without an edge fits no
    // darkening). Else (too little of the outline in view) the medians of the softened
    // region against its ring.
    let fitted = match fit_outline(
        frame,
        &hard,
        &SOFTNESS_CANDIDATES_PX,
        Some(exclude),
        view.same_surface,
    )? {
        Some(fit) => Some((fit.softness_px, fit.ratio)),
        None => fit_softness(frame, &hard, &SOFTNESS_CANDIDATES_PX, Some(exclude))?,
    };
    let Some((softness_px, ratio)) = fitted else {
        return Ok(None);
    };
    let light = ShadowLight {
        toward_light: dir,
        softness_px,
        ratio_rgb: ratio.rgb,
    };
    Ok((ratio.luminance() <= MAX_SHADOW_LUMINANCE).then_some(light))
}

#[cfg(test)]
#[path = "shadow_tests.rs"]
mod tests;
