//! Sub-pixel refinement of a detected tag's corners in linear light.
//!
//! The quad search finds a tag's edges on the binarised image, where the grey level crosses
//! halfway between the local black and white, and the AprilTag C library does the same.
//! Frames are gamma-encoded (sRGB-like), but a lens and a sensor blur an edge in linear
//! light: the halfway grey of the encoded frame is only about a fifth of the way up in
//! linear light, so the edge found lies inside the black border. Every tag then looks a
//! little smaller than it is, and the board a little further away: on Cycles' frames of
//! the bust (`crates/pa-scene/tests/data/blender_bust`) the pose was 0.7-1.3 mm too far
//! along the line of sight (0.15-0.2 % of the distance, with 0.1 mm across it), and the
//! twin's silhouette 0.2-0.3 px inside the truth's.
//!
//! Here each edge is found again on the frame decoded to linear light: at points along it
//! (the middle 70 %, away from the corners), the centroid of the profile's derivative
//! across the edge, which for any symmetric blur lies on the edge itself; a line through
//! those points (first those within [`OUTLIER_PX`] of the median offset, then those within
//! it of that line: a prop over part of an edge); corners at the lines' intersections. The
//! profile is read within half a bit cell of the edge, so that the next edge inside the tag
//! does not pull it, and twice, the second time centred on the first's lines.
//!
//! Coordinates: OpenCV's pixel-centre convention (pixel `(x, y)`'s centre is at `(x, y)`),
//! as [`Detection::corners_px`].

use std::sync::OnceLock;

use glam::DVec2;
use rayon::prelude::*;

use crate::detect::{Detection, GrayImage};
use crate::tracker::CornerRefinement;

/// Passes, each centring the window on the last one's edge: a window off-centre by the
/// search's bias cuts one tail of a wide blur more than the other, which pulls the centroid
/// back toward where it started.
const PASSES: usize = 2;
/// Step between profile samples across an edge, pixels.
const STEP_PX: f64 = 0.25;
/// The widest half-window across an edge, pixels.
const MAX_RANGE_PX: f64 = 2.0;
/// The narrowest: below it the tag is too small to refine (its corners are kept).
const MIN_RANGE_PX: f64 = 0.75;
/// Fewest points along an edge.
const MIN_POINTS: usize = 6;
/// A point further than this from its edge's first line is dropped before the second fit.
const OUTLIER_PX: f64 = 0.35;
/// Least linear-light step across an edge (of 1) for a point to count.
const MIN_CONTRAST: f64 = 0.05;
/// An edge that would move further than this (pixels, at either end) keeps the tag's
/// corners as found: the refinement corrects a sub-pixel bias, and a larger move means it
/// read something else.
const MAX_SHIFT_PX: f64 = 1.0;
/// The same for a corner, which moves further than its edges where they meet at an acute
/// angle (a tag seen 70 degrees off its normal).
const MAX_MOVE_PX: f64 = 4.0;
/// Bit cells across tag36h11's black border square (the family's `width_at_border`; the
/// other families' are similar or wider, which only makes the window more cautious).
const CELLS_ACROSS: f64 = 8.0;

/// sRGB-encoded 8-bit value -> linear light in [0, 1] (built once: every tracked frame
/// reads it).
fn decode_lut() -> &'static [f32; 256] {
    static LUT: OnceLock<[f32; 256]> = OnceLock::new();
    LUT.get_or_init(|| {
        std::array::from_fn(|i| {
            let c = i as f64 / 255.0;
            (if c <= 0.04045 {
                c / 12.92
            } else {
                ((c + 0.055) / 1.055).powf(2.4)
            }) as f32
        })
    })
}

/// Linear 8-bit value -> [0, 1].
fn identity_lut() -> &'static [f32; 256] {
    static LUT: OnceLock<[f32; 256]> = OnceLock::new();
    LUT.get_or_init(|| std::array::from_fn(|i| i as f32 / 255.0))
}

/// Refines the corners of every detection in `gray` in place, as `how` says (what
/// [`crate::Tracker`] does with [`crate::TrackerConfig::refine_corners`]; for callers of
/// [`crate::Detector`] directly). A detection whose edges cannot be found again (a tag
/// under about 12 px a side, one cut by the frame's border, too little contrast, or an edge
/// that would move more than a pixel) keeps its corners.
pub fn refine_tag_corners(gray: &GrayImage, how: CornerRefinement, detections: &mut [Detection]) {
    if detections.is_empty() || gray.data.len() != gray.width as usize * gray.height as usize {
        return;
    }
    let lut = match how {
        CornerRefinement::Off => return,
        CornerRefinement::Srgb => decode_lut(),
        CornerRefinement::Linear => identity_lut(),
    };
    // One tag per task on the pool (each reads about 10k samples).
    detections.par_iter_mut().for_each(|d| {
        if let Some(c) = refine_corners(gray, lut, &d.corners_px) {
            d.corners_px = c;
        }
    });
}

/// The corners of the quad `corners` (in order around it) refined in light as `lut` reads
/// it, or `None` when an edge has too few usable points, the tag is too small, or an edge would
/// move more than [`MAX_SHIFT_PX`] (a corner more than [`MAX_MOVE_PX`]).
fn refine_corners(gray: &GrayImage, lut: &[f32; 256], corners: &[DVec2; 4]) -> Option<[DVec2; 4]> {
    let min_side = (0..4)
        .map(|i| (corners[(i + 1) % 4] - corners[i]).length())
        .fold(f64::INFINITY, f64::min);
    let range = (0.5 * min_side / CELLS_ACROSS).min(MAX_RANGE_PX);
    if !min_side.is_finite() || range < MIN_RANGE_PX {
        return None;
    }
    let mut out = *corners;
    for _ in 0..PASSES {
        let mut lines = [(DVec2::ZERO, DVec2::ZERO); 4];
        for (i, line) in lines.iter_mut().enumerate() {
            let (p, d) = refine_edge(gray, lut, out[i], out[(i + 1) % 4], range)?;
            // How far the edge moved from where the detector put it, at both its ends.
            let (a, b) = (corners[i], corners[(i + 1) % 4]);
            if (a - p).perp_dot(d).abs().max((b - p).perp_dot(d).abs()) > MAX_SHIFT_PX {
                return None;
            }
            *line = (p, d);
        }
        for (i, corner) in out.iter_mut().enumerate() {
            // Corner i joins edge i - 1 (into it) and edge i (out of it).
            let (p, d) = lines[(i + 3) % 4];
            let (q, e) = lines[i];
            let den = d.perp_dot(e);
            if den.abs() < 1e-9 {
                return None;
            }
            let c = p + d * ((q - p).perp_dot(e) / den);
            if !c.is_finite() || (c - corners[i]).length() > MAX_MOVE_PX {
                return None;
            }
            *corner = c;
        }
    }
    Some(out)
}

/// One edge from `a` to `b` found again: a point on it and its unit direction.
fn refine_edge(
    gray: &GrayImage,
    lut: &[f32; 256],
    a: DVec2,
    b: DVec2,
    range: f64,
) -> Option<(DVec2, DVec2)> {
    let along = b - a;
    let len = along.length();
    let dir = along / len;
    let normal = DVec2::new(dir.y, -dir.x);
    let count = ((len / 2.0) as usize).clamp(MIN_POINTS, 48);
    let steps = (2.0 * range / STEP_PX).round() as usize;
    let mut points = Vec::with_capacity(count);
    let mut profile = vec![0.0f64; steps + 1];
    for k in 0..count {
        let u = 0.15 + 0.7 * (k as f64 + 0.5) / count as f64;
        let p0 = a + along * u;
        let mut inside = true;
        for (j, v) in profile.iter_mut().enumerate() {
            let t = -range + STEP_PX * j as f64;
            match sample(gray, lut, p0 + normal * t) {
                Some(s) => *v = s,
                None => {
                    inside = false;
                    break;
                }
            }
        }
        if !inside {
            continue;
        }
        // Which way the edge rises (black border inside, white outside, or the reverse).
        let rise = profile[steps] - profile[0];
        if rise.abs() < MIN_CONTRAST {
            continue;
        }
        let sign = rise.signum();
        let (mut sum_w, mut sum_wt) = (0.0, 0.0);
        for j in 0..steps {
            let w = (sign * (profile[j + 1] - profile[j])).max(0.0);
            let t = -range + STEP_PX * (j as f64 + 0.5);
            sum_w += w;
            sum_wt += w * t;
        }
        if sum_w < MIN_CONTRAST {
            continue;
        }
        points.push((p0, sum_wt / sum_w));
    }
    if points.len() < MIN_POINTS {
        return None;
    }
    // The start is within a pixel of the edge and nearly parallel to it: the points that
    // agree with the median offset first (an occluder's edge pulls a few points far off,
    // and would tilt a line fitted to all), then those near the line through them.
    let mut offsets: Vec<f64> = points.iter().map(|&(_, e)| e).collect();
    offsets.sort_by(f64::total_cmp);
    let median = offsets[offsets.len() / 2];
    let near_median: Vec<DVec2> = points
        .iter()
        .filter(|&&(_, e)| (e - median).abs() <= OUTLIER_PX)
        .map(|&(p, e)| p + normal * e)
        .collect();
    let (c, d) = fit_line(&near_median)?;
    let kept: Vec<DVec2> = points
        .iter()
        .map(|&(p, e)| p + normal * e)
        .filter(|&p| (p - c).perp_dot(d).abs() <= OUTLIER_PX)
        .collect();
    let (c, d) = fit_line(&kept)?;
    // Keep the edge's direction (the corner order relies on it).
    Some((c, if d.dot(dir) < 0.0 { -d } else { d }))
}

/// The total-least-squares line through `points` (centroid, unit direction); `None` for
/// fewer than [`MIN_POINTS`].
fn fit_line(points: &[DVec2]) -> Option<(DVec2, DVec2)> {
    if points.len() < MIN_POINTS {
        return None;
    }
    let n = points.len() as f64;
    let c = points.iter().copied().sum::<DVec2>() / n;
    let (mut sxx, mut sxy, mut syy) = (0.0, 0.0, 0.0);
    for p in points {
        let q = *p - c;
        sxx += q.x * q.x;
        sxy += q.x * q.y;
        syy += q.y * q.y;
    }
    let theta = 0.5 * (2.0 * sxy).atan2(sxx - syy);
    let d = DVec2::new(theta.cos(), theta.sin());
    d.is_finite().then_some((c, d))
}

/// Bilinear linear-light value at `p` (pixel centres at integers); `None` outside the
/// pixel centres' hull.
fn sample(gray: &GrayImage, lut: &[f32; 256], p: DVec2) -> Option<f64> {
    let (w, h) = (gray.width as usize, gray.height as usize);
    if !(p.x >= 0.0 && p.y >= 0.0) {
        return None;
    }
    let (x0, y0) = (p.x.floor() as usize, p.y.floor() as usize);
    if x0 + 1 >= w || y0 + 1 >= h {
        return None;
    }
    let (fx, fy) = (p.x - x0 as f64, p.y - y0 as f64);
    let at = |x: usize, y: usize| f64::from(lut[usize::from(gray.data[y * w + x])]);
    let top = at(x0, y0) * (1.0 - fx) + at(x0 + 1, y0) * fx;
    let bottom = at(x0, y0 + 1) * (1.0 - fx) + at(x0 + 1, y0 + 1) * fx;
    Some(top * (1.0 - fy) + bottom * fy)
}

#[cfg(test)]
#[path = "edges_tests.rs"]
mod tests;
