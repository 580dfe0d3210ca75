//! Flicker: how much the filled (revealed) region changes from one frame to the next once the
//! camera's motion is taken out.
//!
//! The revealed background lies on the table plane (the marker plane, z = 0), so the plane's
//! homography between two views maps a pixel of the current frame to where the same point of
//! the table was in the previous frame. For every pixel revealed in both frames (the current
//! pixel in the current region, its warped position's nearest pixel in the previous region),
//! the change is the mean over R, G and B of `|current - previous(warped, bilinear)|` in 8-bit
//! levels. Only revealed pixels at least [`EDGE_MARGIN_PX`] from the in-between's silhouette
//! count ([`flicker_region`]), and, where the set's table size is known, only pixels that see
//! the table ([`Flicker::with_plane_extent`]). A static, exactly filled table gives 0 (up to
//! interpolation); the ground truth's own
//! figure is the floor a fill can reach (cast shadows and lighting move with the prop, and the
//! sensor's noise, where there is one, is new in every frame).

use glam::{DMat3, DVec3, Mat4};
use pa_camera::{CameraModel, Intrinsics};
use pa_pipeline::ar::plane_homography;

/// The bilinear sample of channel `c` of an RGBA8 image at `(x, y)` (pixel centres at integer
/// coordinates); None when a neighbour is outside.
fn bilinear(img: &[u8], w: usize, h: usize, x: f64, y: f64, c: usize) -> Option<f64> {
    if !(x >= 0.0 && y >= 0.0 && x <= (w - 1) as f64 && y <= (h - 1) as f64) {
        return None;
    }
    let (x0, y0) = (x.floor() as usize, y.floor() as usize);
    let (x1, y1) = ((x0 + 1).min(w - 1), (y0 + 1).min(h - 1));
    let (fx, fy) = (x - x0 as f64, y - y0 as f64);
    let p = |xx: usize, yy: usize| f64::from(img[(yy * w + xx) * 4 + c]);
    Some(
        (1.0 - fy) * ((1.0 - fx) * p(x0, y0) + fx * p(x1, y0))
            + fy * ((1.0 - fx) * p(x0, y1) + fx * p(x1, y1)),
    )
}

/// Mean absolute change (8-bit levels, mean of R, G, B) between `cur` and `prev` warped by
/// `prev_from_cur` (current pixel -> previous pixel), over the pixels set in `region_cur`
/// whose warped position is inside `prev` and lands on a pixel set in `region_prev`; with the
/// number of pixels. None when no pixel qualifies or the sizes disagree.
pub fn plane_change(
    prev: &[u8],
    cur: &[u8],
    width: usize,
    height: usize,
    prev_from_cur: DMat3,
    region_prev: &[bool],
    region_cur: &[bool],
) -> Option<(f64, usize)> {
    let n = width * height;
    if width == 0
        || height == 0
        || prev.len() != n * 4
        || cur.len() != n * 4
        || region_prev.len() != n
        || region_cur.len() != n
    {
        return None;
    }
    let (mut sum, mut count) = (0f64, 0usize);
    for (i, _) in region_cur.iter().enumerate().filter(|(_, &r)| r) {
        let (x, y) = ((i % width) as f64, (i / width) as f64);
        let q = prev_from_cur * DVec3::new(x, y, 1.0);
        if q.z <= 1e-12 {
            continue;
        }
        let (qx, qy) = (q.x / q.z, q.y / q.z);
        let (rx, ry) = (qx.round(), qy.round());
        if !(rx >= 0.0 && ry >= 0.0 && rx < width as f64 && ry < height as f64) {
            continue;
        }
        if !region_prev[ry as usize * width + rx as usize] {
            continue;
        }
        let mut d = 0.0;
        let mut ok = true;
        for c in 0..3 {
            match bilinear(prev, width, height, qx, qy, c) {
                Some(p) => d += (f64::from(cur[i * 4 + c]) - p).abs(),
                None => ok = false,
            }
        }
        if ok {
            sum += d / 3.0;
            count += 1;
        }
    }
    (count > 0).then(|| (sum / count as f64, count))
}

/// How far from the in-between's silhouette (Chebyshev, pixels) a revealed pixel must be to
/// count for flicker: nearer pixels mix the prop's edge into the background in both the output
/// and the truth, and that edge moves with the animation.
pub const EDGE_MARGIN_PX: usize = 2;

/// The region the flicker metric follows: revealed pixels (in `key`, not in `truth`) at
/// least `margin` pixels (Chebyshev) from every pixel of `truth`.
pub fn flicker_region(key: &[bool], truth: &[bool], width: usize, margin: usize) -> Vec<bool> {
    let height = truth.len().checked_div(width).unwrap_or(0);
    // Horizontal then vertical running maximum of `truth` over +-margin.
    let mut near = vec![false; truth.len()];
    for y in 0..height {
        for x in 0..width {
            let (a, b) = (x.saturating_sub(margin), (x + margin).min(width - 1));
            near[y * width + x] = truth[y * width + a..=y * width + b].iter().any(|&t| t);
        }
    }
    let mut out = vec![false; truth.len()];
    for y in 0..height {
        let (a, b) = (y.saturating_sub(margin), (y + margin).min(height - 1));
        for x in 0..width {
            let i = y * width + x;
            out[i] =
                key.get(i).copied().unwrap_or(false) && !(a..=b).any(|yy| near[yy * width + x]);
        }
    }
    out
}

/// One frame as the flicker metric remembers it.
struct Kept {
    ours: Vec<u8>,
    truth: Vec<u8>,
    region: Vec<bool>,
    camera_from_marker: Mat4,
}

/// The flicker of a sequence, frame by frame: ours (the pipeline's output) and the ground
/// truth's over the same pixels, camera motion compensated with the true cameras.
pub struct Flicker {
    camera: CameraModel,
    width: usize,
    height: usize,
    /// Only pixels whose ray meets the table plane in front of the camera within this
    /// half-side (metres, marker frame) count: beyond the table the background is not on the
    /// plane and no homography compensates it.
    plane_half_m: f64,
    prev: Option<Kept>,
}

impl Flicker {
    /// The metric for a camera; every pixel on the plane counts.
    pub fn new(intrinsics: Intrinsics) -> Self {
        Self {
            camera: CameraModel::pinhole(intrinsics),
            width: intrinsics.width as usize,
            height: intrinsics.height as usize,
            plane_half_m: f64::INFINITY,
            prev: None,
        }
    }

    /// Counts only pixels that see the plane within `half_m` of the marker origin (in x and
    /// y): the set's table.
    pub fn with_plane_extent(mut self, half_m: f64) -> Self {
        self.plane_half_m = half_m;
        self
    }

    /// `region` less the pixels whose ray misses the table (behind the camera, or beyond
    /// the extent).
    fn on_table(&self, region: &[bool], camera_from_marker: Mat4) -> Vec<bool> {
        let m = camera_from_marker.as_dmat4();
        let plane = DMat3::from_cols(
            m.x_axis.truncate(),
            m.y_axis.truncate(),
            DVec3::new(m.w_axis.x, m.w_axis.y, m.w_axis.z),
        );
        let marker_from_pixel = plane.inverse() * self.camera.intrinsics.matrix().inverse();
        let w = self.width;
        region
            .iter()
            .enumerate()
            .map(|(i, &r)| {
                if !r {
                    return false;
                }
                let q = marker_from_pixel * DVec3::new((i % w) as f64, (i / w) as f64, 1.0);
                // The plane point is q / q.z; it is in front of the camera when the pixel's
                // ray (depth 1 / q.z) is positive.
                q.z > 1e-12
                    && (q.x / q.z).abs() <= self.plane_half_m
                    && (q.y / q.z).abs() <= self.plane_half_m
            })
            .collect()
    }

    /// Forgets the previous frame (a new sequence starts).
    pub fn reset(&mut self) {
        self.prev = None;
    }

    /// Adds a frame: its output, ground truth, revealed region and true camera. Returns the
    /// change from the previous frame, (ours, truth), in 8-bit levels; None for the first
    /// frame or when the two regions do not overlap.
    pub fn step(
        &mut self,
        ours: &[u8],
        truth: &[u8],
        region: &[bool],
        camera_from_marker: Mat4,
    ) -> Option<(f64, f64)> {
        let on_table;
        let region = if self.plane_half_m.is_finite() {
            on_table = self.on_table(region, camera_from_marker);
            &on_table[..]
        } else {
            region
        };
        let result = self.prev.as_ref().and_then(|p| {
            // plane_homography(current, plate) maps plate pixels to current pixels: here the
            // "plate" is this frame and the "current" the previous one.
            let prev_from_cur =
                plane_homography(&self.camera, p.camera_from_marker, camera_from_marker);
            let (w, h) = (self.width, self.height);
            let (o, _) = plane_change(&p.ours, ours, w, h, prev_from_cur, &p.region, region)?;
            let (t, _) = plane_change(&p.truth, truth, w, h, prev_from_cur, &p.region, region)?;
            Some((o, t))
        });
        self.prev = Some(Kept {
            ours: ours.to_vec(),
            truth: truth.to_vec(),
            region: region.to_vec(),
            camera_from_marker,
        });
        result
    }
}

#[cfg(test)]
#[path = "flicker/tests.rs"]
mod tests;
