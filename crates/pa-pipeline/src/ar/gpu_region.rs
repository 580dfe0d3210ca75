//! Screen regions for the wgpu path: which pixels the key props, their live samples and the
//! twins can reach this frame, from the poses posed on the CPU. The wgpu path reads back and
//! uploads those regions only instead of whole frames: on a discrete GPU the full-frame
//! transfers were most of the texture stage (1920x1080 on an H200: 26 ms of read-back a
//! frame, measured with `propsalive bench --render-path gpu`).
//!
//! | region | from | projection | used for |
//! |---|---|---|---|
//! | key | key-pose vertices | pinhole (as rendered) | reading back the visibility map |
//! | sample | the key region | + the lens distortion's largest shift | the frame upload |
//! | twin | in-between vertices | pinhole (as rendered) | reading back the live twin |
//!
//! A triangle's projection lies in the hull of its vertices' projections (pinhole), so the
//! vertices bound what the rasteriser covers; [`REGION_MARGIN_PX`] covers rounding, the
//! coverage rule and the bilinear taps of a sample. Anything at or behind the near plane, or
//! not finite, makes the region the whole frame.

use glam::{DVec2, Mat4, Vec3};
use pa_camera::CameraModel;
use pa_render::{LiveRegionFrame, PixelRegion};

use super::texture::{mask_rows, Bbox};

/// Pixels of margin around a projected bound.
const REGION_MARGIN_PX: f64 = 4.0;

/// The pinhole region of `points` (world frame) seen from `camera_from_world` with `camera`'s
/// intrinsics at `width` x `height` (see the module docs); at least one pixel.
pub(super) fn screen_region<'a>(
    points: impl IntoIterator<Item = &'a Vec3>,
    camera: &CameraModel,
    camera_from_world: Mat4,
    near_m: f32,
    width: u32,
    height: u32,
) -> PixelRegion {
    let full = PixelRegion::full(width, height);
    let k = &camera.intrinsics;
    let k = if (k.width, k.height) == (width, height) {
        *k
    } else {
        k.scaled_to(width, height)
    };
    let (fx, fy, cx, cy) = (k.fx as f32, k.fy as f32, k.cx as f32, k.cy as f32);
    let (mut u0, mut v0, mut u1, mut v1) = (f32::MAX, f32::MAX, f32::MIN, f32::MIN);
    for p in points {
        let c = camera_from_world.transform_point3(*p);
        if !(c.z > near_m && c.is_finite()) {
            return full;
        }
        let (u, v) = (fx * c.x / c.z + cx, fy * c.y / c.z + cy);
        (u0, u1) = (u0.min(u), u1.max(u));
        (v0, v1) = (v0.min(v), v1.max(v));
    }
    if u0 > u1 {
        // No points: nothing is drawn; one pixel keeps the read-back well-formed.
        return PixelRegion {
            x: 0,
            y: 0,
            width: 1,
            height: 1,
        };
    }
    clamp_region(
        f64::from(u0) - REGION_MARGIN_PX,
        f64::from(v0) - REGION_MARGIN_PX,
        f64::from(u1) + REGION_MARGIN_PX,
        f64::from(v1) + REGION_MARGIN_PX,
        width,
        height,
    )
}

/// The region the live samples of points projecting into the pinhole region `key` can reach
/// through `camera`'s lens distortion: `key` grown by the largest shift the distortion gives
/// on its corners, edge midpoints and centre (radial distortion shifts most at the point
/// farthest from the centre), times 1.5, plus the margin.
pub(super) fn sample_region(
    key: PixelRegion,
    camera: &CameraModel,
    width: u32,
    height: u32,
) -> PixelRegion {
    let k = &camera.intrinsics;
    if (k.width, k.height) != (width, height) {
        return PixelRegion::full(width, height);
    }
    let (x0, y0) = (f64::from(key.x), f64::from(key.y));
    let (x1, y1) = (x0 + f64::from(key.width), y0 + f64::from(key.height));
    let mut shift: f64 = 0.0;
    for &x in &[x0, 0.5 * (x0 + x1), x1] {
        for &y in &[y0, 0.5 * (y0 + y1), y1] {
            let n = DVec2::new((x - k.cx) / k.fx, (y - k.cy) / k.fy);
            let d = camera.distortion.distort(n);
            let s = DVec2::new((d.x - n.x) * k.fx, (d.y - n.y) * k.fy).length();
            if !s.is_finite() {
                return PixelRegion::full(width, height);
            }
            shift = shift.max(s);
        }
    }
    let grow = 1.5 * shift + REGION_MARGIN_PX;
    clamp_region(x0 - grow, y0 - grow, x1 + grow, y1 + grow, width, height)
}

/// The pixels whose centres lie in [u0, u1] x [v0, v1], clamped to the frame; at least one.
fn clamp_region(u0: f64, v0: f64, u1: f64, v1: f64, width: u32, height: u32) -> PixelRegion {
    let clamp = |a: f64, side: u32| a.clamp(0.0, f64::from(side - 1)) as u32;
    let (x0, y0) = (clamp(u0.floor(), width), clamp(v0.floor(), height));
    let (x1, y1) = (clamp(u1.ceil(), width), clamp(v1.ceil(), height));
    PixelRegion {
        x: x0,
        y: y0,
        width: x1.max(x0) - x0 + 1,
        height: y1.max(y0) - y0 + 1,
    }
}

/// A full-frame depth buffer (metres, +inf where empty) kept between frames and written one
/// region at a time: only the previous region is reset, so a frame costs its regions' pixels.
#[derive(Default)]
pub(super) struct RegionDepth {
    depth: Vec<f32>,
    width: u32,
    last: Option<PixelRegion>,
}

impl RegionDepth {
    /// Writes `values` (row-major over `region`) into a `width` x `height` frame, +inf
    /// elsewhere ([`RegionDepth::depth`]).
    pub(super) fn write(&mut self, width: u32, height: u32, region: PixelRegion, values: &[f32]) {
        let n = width as usize * height as usize;
        if self.depth.len() != n || self.width != width {
            self.depth = vec![f32::INFINITY; n];
            self.width = width;
            self.last = None;
        }
        let w = width as usize;
        if let Some(r) = self.last.take() {
            for row in rows(r, w) {
                self.depth[row].fill(f32::INFINITY);
            }
        }
        for (row, src) in rows(region, w).zip(values.chunks_exact(region.width as usize)) {
            self.depth[row].copy_from_slice(src);
        }
        self.last = Some(region);
    }

    /// The whole frame's depth as last written.
    pub(super) fn depth(&self) -> &[f32] {
        &self.depth
    }

    /// The full-frame mask of the finite depths and its bounding box (work in the last
    /// region only).
    pub(super) fn mask_and_bbox(&self) -> (Vec<bool>, Option<Bbox>) {
        let mut mask = vec![false; self.depth.len()];
        let Some(r) = self.last else {
            return (mask, None);
        };
        let bbox = mask_rows(
            located_rows(r, self.width as usize),
            &mut mask,
            |row| &self.depth[row],
            |d: &f32| d.is_finite(),
        );
        (mask, bbox)
    }
}

/// [`rows`] with each row's frame row and first column, as [`mask_rows`] takes them.
fn located_rows(
    region: PixelRegion,
    w: usize,
) -> impl Iterator<Item = (usize, usize, std::ops::Range<usize>)> {
    rows(region, w)
        .enumerate()
        .map(move |(k, row)| (region.y as usize + k, region.x as usize, row))
}

/// The row ranges of `region` in a frame `w` pixels wide.
fn rows(region: PixelRegion, w: usize) -> impl Iterator<Item = std::ops::Range<usize>> {
    let (x, rw) = (region.x as usize, region.width as usize);
    (region.y as usize..(region.y + region.height) as usize).map(move |y| y * w + x..y * w + x + rw)
}

/// The live twin of one region placed into full-frame buffers: colour (zero elsewhere), the
/// mask of drawn pixels and its bounding box, and the live codes (zero elsewhere).
pub(super) fn twin_from_region(r: &LiveRegionFrame) -> (Vec<u8>, Vec<bool>, Option<Bbox>, Vec<u8>) {
    let (width, height) = r.target_size;
    let (w, n) = (width as usize, width as usize * height as usize);
    let region = r.region;
    let rw = region.width as usize;
    let mut rgba = vec![0u8; n * 4];
    let mut codes = vec![0u8; n];
    let mut mask = vec![false; n];
    for (k, row) in rows(region, w).enumerate() {
        rgba[row.start * 4..row.end * 4].copy_from_slice(&r.rgba8[k * rw * 4..(k + 1) * rw * 4]);
        codes[row.clone()].copy_from_slice(&r.live_valid[k * rw..(k + 1) * rw]);
    }
    // The region's own depth rows, found from a frame row's span.
    let bbox = mask_rows(
        located_rows(region, w),
        &mut mask,
        |row| {
            let k = row.start / w - region.y as usize;
            &r.depth_m[k * rw..(k + 1) * rw]
        },
        |d: &f32| d.is_finite(),
    );
    (rgba, mask, bbox, codes)
}

#[cfg(test)]
mod tests {
    use super::*;
    use pa_camera::{Distortion, Intrinsics};

    fn camera(distortion: Distortion) -> CameraModel {
        let mut c = CameraModel::pinhole(Intrinsics {
            fx: 500.0,
            fy: 500.0,
            cx: 319.5,
            cy: 239.5,
            width: 640,
            height: 480,
        });
        c.distortion = distortion;
        c
    }

    #[test]
    fn pinhole_region_holds_every_projection_with_its_margin() {
        let cam = camera(Distortion::default());
        let points = [Vec3::new(-0.1, -0.05, 1.0), Vec3::new(0.1, 0.05, 2.0)];
        let r = screen_region(&points, &cam, Mat4::IDENTITY, 0.01, 640, 480);
        // u in [269.5, 344.5], v in [214.5, 252]: floor/ceil, then 4 px of margin.
        assert_eq!((r.x, r.y), (265, 210));
        assert_eq!((r.x + r.width - 1, r.y + r.height - 1), (349, 256));
        let behind = [Vec3::new(0.0, 0.0, -1.0)];
        let r = screen_region(&behind, &cam, Mat4::IDENTITY, 0.01, 640, 480);
        assert_eq!(r, PixelRegion::full(640, 480));
        let nan = [Vec3::new(f32::NAN, 0.0, 1.0)];
        let r = screen_region(&nan, &cam, Mat4::IDENTITY, 0.01, 640, 480);
        assert_eq!(r, PixelRegion::full(640, 480));
        let none: [Vec3; 0] = [];
        let r = screen_region(&none, &cam, Mat4::IDENTITY, 0.01, 640, 480);
        assert_eq!(r.area(), 1);
    }

    #[test]
    fn sample_region_grows_with_the_distortion_and_holds_the_distorted_points() {
        let key = PixelRegion {
            x: 400,
            y: 300,
            width: 150,
            height: 120,
        };
        let plain = sample_region(key, &camera(Distortion::default()), 640, 480);
        assert_eq!((plain.x, plain.y), (396, 296));
        let d = Distortion {
            k1: -0.3,
            k2: 0.1,
            p1: 0.001,
            p2: -0.002,
            k3: 0.0,
        };
        let cam = camera(d);
        let r = sample_region(key, &cam, 640, 480);
        assert!(r.x < plain.x && r.y < plain.y, "{r:?} vs {plain:?}");
        // Every point of the key region, distorted, lies in the sample region.
        let k = cam.intrinsics;
        for i in 0..=30 {
            for j in 0..=30 {
                let x = f64::from(key.x) + f64::from(key.width) * f64::from(i) / 30.0;
                let y = f64::from(key.y) + f64::from(key.height) * f64::from(j) / 30.0;
                let n = DVec2::new((x - k.cx) / k.fx, (y - k.cy) / k.fy);
                let p = cam.distortion.distort(n);
                let (u, v) = (p.x * k.fx + k.cx, p.y * k.fy + k.cy);
                let inside = |a: f64, start: u32, len: u32| {
                    a >= f64::from(start) && a <= f64::from(start + len - 1)
                };
                assert!(
                    inside(u.clamp(0.0, 639.0), r.x, r.width)
                        && inside(v.clamp(0.0, 479.0), r.y, r.height),
                    "({u}, {v}) outside {r:?}"
                );
            }
        }
    }

    #[test]
    fn region_depth_resets_only_the_last_region_and_masks_it() {
        let mut d = RegionDepth::default();
        let a = PixelRegion {
            x: 1,
            y: 1,
            width: 2,
            height: 2,
        };
        d.write(4, 3, a, &[1.0, f32::INFINITY, 2.0, 3.0]);
        let out = d.depth().to_vec();
        let inf = f32::INFINITY;
        assert_eq!(
            out,
            vec![inf, inf, inf, inf, inf, 1.0, inf, inf, inf, 2.0, 3.0, inf]
        );
        let (mask, bbox) = d.mask_and_bbox();
        assert_eq!(bbox, Some((1, 1, 2, 2)));
        assert_eq!(mask.iter().filter(|&&m| m).count(), 3);
        let b = PixelRegion {
            x: 0,
            y: 0,
            width: 1,
            height: 1,
        };
        d.write(4, 3, b, &[5.0]);
        let out = d.depth().to_vec();
        assert_eq!(out[0], 5.0);
        assert!(out[1..].iter().all(|z| z.is_infinite()));
        assert_eq!(d.mask_and_bbox().1, Some((0, 0, 0, 0)));
    }

    #[test]
    fn twin_from_region_places_the_region_and_matches_a_full_frame_scan() {
        let region = PixelRegion {
            x: 2,
            y: 1,
            width: 2,
            height: 2,
        };
        let inf = f32::INFINITY;
        let r = LiveRegionFrame {
            region,
            target_size: (5, 4),
            rgba8: (0..16).collect(),
            depth_m: vec![1.0, inf, inf, 2.0],
            live_valid: vec![255, 0, 0, 3],
        };
        let (rgba, mask, bbox, codes) = twin_from_region(&r);
        assert_eq!(&rgba[(5 + 2) * 4..(5 + 4) * 4], &[0, 1, 2, 3, 4, 5, 6, 7]);
        assert_eq!(
            &rgba[(10 + 2) * 4..(10 + 4) * 4],
            &[8, 9, 10, 11, 12, 13, 14, 15]
        );
        assert_eq!(
            rgba.iter().map(|&c| usize::from(c)).sum::<usize>(),
            (0..16).sum::<usize>()
        );
        assert_eq!(codes[5 + 2], 255);
        assert_eq!(codes[10 + 3], 3);
        let expected = crate::composite::bounding_box(&mask, 5, 4);
        assert_eq!(bbox, expected);
        assert_eq!(bbox, Some((2, 1, 3, 2)));
        assert_eq!(mask.iter().filter(|&&m| m).count(), 2);
    }
}
