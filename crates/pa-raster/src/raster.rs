//! Triangle rasterisation into a visibility buffer (nearest surface per pixel: its triangle
//! and its inverse depth), the core of the CPU path.
//!
//! # Conventions
//!
//! | space | axes | notes |
//! |---|---|---|
//! | camera | OpenCV: +X right, +Y down, +Z forward, metres | triangles arrive here |
//! | pixel | +x right, +y down | pixel `(x, y)` is covered when its *centre*, the point `(x, y)` (integer coordinates, OpenCV), is inside the projected triangle |
//!
//! This is the sample point the GPU path uses too: `Intrinsics::clip_from_camera` maps the
//! OpenCV pixel centre `u` to the framebuffer's sample point `u + 0.5`.
//!
//! # Math
//!
//! For a triangle `(a, b, c)` in camera space with `e1 = b - a`, `e2 = c - a`, the ray through
//! pixel `(x, y)` has direction `d = ((x - cx) / fx, (y - cy) / fy, 1)`. Its intersection with
//! the triangle's plane (Moller-Trumbore with the ray's origin at the camera) is
//!
//! `D = d . (e2 x e1)`, `U = d . (a x e2)`, `V = d . (e1 x a)`, `T = a . (e2 x e1)`,
//! barycentrics `(1 - U/D - V/D, U/D, V/D)` and depth `z = T / D`.
//!
//! `D`, `U`, `V` are affine in `(x, y)`: three planes per triangle, evaluated per pixel with two
//! multiply-adds each. The barycentrics are exactly the perspective-correct ones (the GPU's
//! default interpolation), and `1 / z = D / T` is affine too, so the depth test compares
//! `D / T` (larger is nearer). All forms are multiplied by `sign(T)` so that `D > 0` wherever
//! the ray meets the plane in front of the camera; a pixel is covered when `D > 0`, `U >= 0`,
//! `V >= 0`, `D - U - V >= 0` and `near <= z <= far`. No back-face culling (as the GPU path).
//!
//! Triangles that cross the near plane are handled without splitting: their screen bounds come
//! from the part in front of the plane (the triangle clipped to `z >= near`), and the per-pixel
//! depth bound removes the rest.

use glam::{DVec3, Vec3};
use rayon::prelude::*;

/// A pinhole camera for rasterisation: OpenCV intrinsics of the target image, and the clip
/// range.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RasterCamera {
    pub fx: f64,
    pub fy: f64,
    pub cx: f64,
    pub cy: f64,
    pub width: u32,
    pub height: u32,
    pub near_m: f32,
    pub far_m: f32,
}

impl RasterCamera {
    /// A camera from intrinsics (taken at their own `width` x `height`).
    pub fn new(k: &pa_camera::Intrinsics, near_m: f32, far_m: f32) -> Self {
        Self {
            fx: k.fx,
            fy: k.fy,
            cx: k.cx,
            cy: k.cy,
            width: k.width,
            height: k.height,
            near_m,
            far_m,
        }
    }

    /// Pixel position of a camera-space point for triangle set-up ([`TriSetup::new_projected`]),
    /// `None` in front of the near plane (or not finite).
    #[inline]
    pub fn project_for_setup(&self, p: Vec3) -> Option<[f64; 2]> {
        let p = p.as_dvec3();
        let in_range = p.z >= self.near_m as f64 && p.is_finite();
        if !in_range {
            return None;
        }
        let iz = 1.0 / p.z;
        Some([self.fx * p.x * iz + self.cx, self.fy * p.y * iz + self.cy])
    }

    /// Pinhole projection of a camera-space point (no distortion); `None` behind the camera.
    pub fn pixel_from_camera(&self, p: DVec3) -> Option<(f64, f64)> {
        (p.z > 0.0).then(|| (self.fx * p.x / p.z + self.cx, self.fy * p.y / p.z + self.cy))
    }
}

/// An inclusive pixel rectangle.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PixelRect {
    pub x0: u32,
    pub y0: u32,
    pub x1: u32,
    pub y1: u32,
}

impl PixelRect {
    /// The smallest rectangle holding both.
    pub fn union(self, o: PixelRect) -> PixelRect {
        PixelRect {
            x0: self.x0.min(o.x0),
            y0: self.y0.min(o.y0),
            x1: self.x1.max(o.x1),
            y1: self.y1.max(o.y1),
        }
    }

    /// `a` or `b` or their union.
    pub fn union_opt(a: Option<PixelRect>, b: Option<PixelRect>) -> Option<PixelRect> {
        match (a, b) {
            (Some(a), Some(b)) => Some(a.union(b)),
            (a, None) => a,
            (None, b) => b,
        }
    }

    pub fn width(&self) -> u32 {
        self.x1 - self.x0 + 1
    }

    pub fn height(&self) -> u32 {
        self.y1 - self.y0 + 1
    }
}

/// An affine form `a x + b y + c` over pixel coordinates.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Plane {
    pub a: f32,
    pub b: f32,
    pub c: f32,
}

impl Plane {
    /// The form `d(x, y) . v` for the camera's ray direction `d`.
    fn of_ray_dot(cam: &RasterCamera, v: DVec3, inv_fx: f64, inv_fy: f64) -> Self {
        let a = v.x * inv_fx;
        let b = v.y * inv_fy;
        Plane {
            a: a as f32,
            b: b as f32,
            c: (v.z - a * cam.cx - b * cam.cy) as f32,
        }
    }

    #[inline(always)]
    pub fn at(&self, x: f32, y: f32) -> f32 {
        // Plain multiply-adds: `mul_add` is a library call on CPUs built without FMA.
        self.a * x + self.b * y + self.c
    }
}

/// Per-triangle set-up (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TriSetup {
    pub d: Plane,
    pub u: Plane,
    pub v: Plane,
    /// `1 / T` after the sign normalisation: `1 / z = D * inv_t`.
    pub inv_t: f32,
    /// `D - U - V`, and the reciprocal x-slopes of `U`, `V`, `D - U - V`, `D` (0 where the
    /// slope is 0), for [`TriSetup::row_span`] without divisions.
    pub e: Plane,
    pub inv_a: [f32; 4],
    /// Screen bounds, clipped to the image.
    pub rect: PixelRect,
    /// The triangle's vertices wind counter-clockwise on screen (the GPU's `front_facing` with
    /// `FrontFace::Ccw`, for the normal flip of double-sided shading).
    pub ccw_on_screen: bool,
}

/// Barycentrics and inverse depth of a pixel inside a triangle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hit {
    pub b: [f32; 3],
    pub inv_z: f32,
}

impl TriSetup {
    /// Sets up the camera-space triangle `(a, b, c)`; `None` when it covers no pixel centre
    /// for certain (behind the near plane, edge-on, degenerate, or outside the image).
    pub fn new(cam: &RasterCamera, a: Vec3, b: Vec3, c: Vec3) -> Option<Self> {
        Self::new_culled(cam, a, b, c, None)
    }

    /// [`TriSetup::new`], also `None` when `keep_ccw` is given and the triangle's winding on
    /// screen is not that one (back-face culling; see [`crate::mesh`] for when it is exact).
    pub fn new_culled(
        cam: &RasterCamera,
        a: Vec3,
        b: Vec3,
        c: Vec3,
        keep_ccw: Option<bool>,
    ) -> Option<Self> {
        let proj = [
            cam.project_for_setup(a),
            cam.project_for_setup(b),
            cam.project_for_setup(c),
        ];
        Self::new_projected(cam, [a, b, c], proj, keep_ccw)
    }

    /// [`TriSetup::new_culled`] with the vertices' pixel positions already known
    /// ([`RasterCamera::project_for_setup`] of each; a vertex is shared by about six
    /// triangles, so projecting each once saves most of the set-up's divisions).
    pub fn new_projected(
        cam: &RasterCamera,
        [a, b, c]: [Vec3; 3],
        proj: [Option<[f64; 2]>; 3],
        keep_ccw: Option<bool>,
    ) -> Option<Self> {
        let (a, b, c) = (a.as_dvec3(), b.as_dvec3(), c.as_dvec3());
        if !(a.is_finite() && b.is_finite() && c.is_finite()) {
            return None;
        }
        let near = cam.near_m as f64;
        if a.z < near && b.z < near && c.z < near {
            return None;
        }
        if a.z > cam.far_m as f64 && b.z > cam.far_m as f64 && c.z > cam.far_m as f64 {
            return None;
        }
        let (e1, e2) = (b - a, c - a);
        let n = e2.cross(e1);
        let t = a.dot(n);
        if t == 0.0 || !t.is_finite() {
            return None;
        }
        if keep_ccw.is_some_and(|ccw| ccw != (t > 0.0)) {
            return None;
        }
        let rect = match proj {
            [Some(p), Some(q), Some(r)] => rect_of_points(cam, &[p, q, r])?,
            _ => screen_rect(cam, [a, b, c], near)?,
        };
        let s = t.signum();
        let (inv_fx, inv_fy) = (1.0 / cam.fx, 1.0 / cam.fy);
        let d = Plane::of_ray_dot(cam, n * s, inv_fx, inv_fy);
        let u = Plane::of_ray_dot(cam, a.cross(e2) * s, inv_fx, inv_fy);
        let v = Plane::of_ray_dot(cam, e1.cross(a) * s, inv_fx, inv_fy);
        let e = Plane {
            a: d.a - u.a - v.a,
            b: d.b - u.b - v.b,
            c: d.c - u.c - v.c,
        };
        let inv = |a: f32| if a != 0.0 { 1.0 / a } else { 0.0 };
        Some(Self {
            d,
            u,
            v,
            inv_t: (1.0 / (t * s)) as f32,
            e,
            inv_a: [inv(u.a), inv(v.a), inv(e.a), inv(d.a)],
            rect,
            ccw_on_screen: t > 0.0,
        })
    }

    /// The pixels of row `y` (inside the set-up's rectangle) where the triangle may cover a
    /// pixel centre: the interval where `U`, `V`, `D - U - V` and `D` are all >= 0, widened
    /// by one pixel each side against rounding (the per-pixel test decides). `None` when
    /// empty.
    #[inline]
    pub fn row_span(&self, y: f32) -> Option<(u32, u32)> {
        let (mut lo, mut hi) = (self.rect.x0 as f32, self.rect.x1 as f32);
        for (f, inv_a) in [&self.u, &self.v, &self.e, &self.d]
            .into_iter()
            .zip(self.inv_a)
        {
            // f(x) = f0 + a x >= 0 at row y.
            let f0 = f.b * y + f.c;
            if f.a > 0.0 {
                lo = lo.max(-f0 * inv_a - 1.0);
            } else if f.a < 0.0 {
                hi = hi.min(-f0 * inv_a + 1.0);
            } else if f0 < 0.0 {
                return None;
            }
        }
        let nonempty = lo <= hi;
        if !nonempty {
            return None;
        }
        // lo, hi are within the rectangle: ceil and floor by truncation of non-negatives.
        let x0 = (lo as u32 + u32::from((lo as u32 as f32) < lo)).max(self.rect.x0);
        let x1 = (hi as u32).min(self.rect.x1);
        (x0 <= x1).then_some((x0, x1))
    }

    /// The hit at pixel centre `(x, y)`, without the coverage test.
    #[inline(always)]
    pub fn hit(&self, x: f32, y: f32) -> Hit {
        let d = self.d.at(x, y);
        let u = self.u.at(x, y);
        let v = self.v.at(x, y);
        let r = 1.0 / d;
        Hit {
            b: [1.0 - (u + v) * r, u * r, v * r],
            inv_z: d * self.inv_t,
        }
    }
}

/// Screen bounds of the part of a camera-space triangle in front of the near plane.
fn screen_rect(cam: &RasterCamera, v: [DVec3; 3], near: f64) -> Option<PixelRect> {
    let mut pts = [[0.0; 2]; 6];
    let mut n = 0;
    for i in 0..3 {
        let (p, q) = (v[i], v[(i + 1) % 3]);
        if p.z >= near {
            let (x, y) = cam.pixel_from_camera(p)?;
            pts[n] = [x, y];
            n += 1;
        }
        if (p.z >= near) != (q.z >= near) {
            let t = (near - p.z) / (q.z - p.z);
            let m = p + (q - p) * t;
            let (x, y) = cam.pixel_from_camera(DVec3::new(m.x, m.y, near))?;
            pts[n] = [x, y];
            n += 1;
        }
    }
    rect_of_points(cam, &pts[..n])
}

/// The pixel centres' rectangle spanned by points in pixels, clipped to the image.
fn rect_of_points(cam: &RasterCamera, pts: &[[f64; 2]]) -> Option<PixelRect> {
    let (mut lx, mut ly, mut hx, mut hy) = (f64::MAX, f64::MAX, f64::MIN, f64::MIN);
    for &[x, y] in pts {
        lx = lx.min(x);
        ly = ly.min(y);
        hx = hx.max(x);
        hy = hy.max(y);
    }
    if !(lx.is_finite() && ly.is_finite() && hx.is_finite() && hy.is_finite()) {
        return None;
    }
    let (w, h) = (cam.width as i64, cam.height as i64);
    // Pixel centres at integers: x0 = ceil(lx), x1 = floor(hx), clipped to the image (the
    // clamp first, so that far-away vertices cannot overflow the conversion).
    let lim = 1e9;
    let floor = |v: f64| {
        let v = v.clamp(-lim, lim);
        let t = v as i64;
        t - i64::from((t as f64) > v)
    };
    let x0 = (-floor(-lx)).max(0);
    let y0 = (-floor(-ly)).max(0);
    let x1 = floor(hx).min(w - 1);
    let y1 = floor(hy).min(h - 1);
    if x0 > x1 || y0 > y1 {
        return None;
    }
    Some(PixelRect {
        x0: x0 as u32,
        y0: y0 as u32,
        x1: x1 as u32,
        y1: y1 as u32,
    })
}

/// A slot of a set-up list: a set-up, or an empty slot (a triangle that covers nothing),
/// so that lists can be filled in parallel by index.
pub trait SetupSlot: Sync {
    fn setup(&self) -> Option<&TriSetup>;
}

impl SetupSlot for TriSetup {
    fn setup(&self) -> Option<&TriSetup> {
        Some(self)
    }
}

impl SetupSlot for Option<TriSetup> {
    fn setup(&self) -> Option<&TriSetup> {
        self.as_ref()
    }
}

/// Id of an empty pixel in a [`VisBuffer`].
pub const NO_TRIANGLE: u32 = u32::MAX;

/// Nearest surface per pixel: inverse camera-space depth (0 where empty) and the index of
/// the triangle set-up that put it there. Long-lived: only the rectangle written last time is
/// cleared before the next frame.
#[derive(Debug, Clone, Default)]
pub struct VisBuffer {
    pub width: u32,
    pub height: u32,
    pub inv_z: Vec<f32>,
    pub id: Vec<u32>,
    /// The rectangle that may hold surfaces (union of the triangles' bounds).
    pub dirty: Option<PixelRect>,
}

impl VisBuffer {
    /// An empty buffer.
    pub fn new(width: u32, height: u32) -> Self {
        let n = width as usize * height as usize;
        Self {
            width,
            height,
            inv_z: vec![0.0; n],
            id: vec![NO_TRIANGLE; n],
            dirty: None,
        }
    }

    /// Makes the buffer `width` x `height` and empty (clears only the dirty rectangle when
    /// the size is unchanged).
    pub fn reset(&mut self, width: u32, height: u32) {
        if (self.width, self.height) != (width, height) {
            *self = Self::new(width, height);
            return;
        }
        if let Some(r) = self.dirty.take() {
            let w = self.width as usize;
            for y in r.y0..=r.y1 {
                let row = y as usize * w;
                let (a, b) = (row + r.x0 as usize, row + r.x1 as usize + 1);
                self.inv_z[a..b].fill(0.0);
                self.id[a..b].fill(NO_TRIANGLE);
            }
        }
    }

    /// Camera-space depth at `(x, y)` in metres (+inf where empty or outside).
    pub fn depth_m(&self, x: u32, y: u32) -> f32 {
        if x >= self.width || y >= self.height {
            return f32::INFINITY;
        }
        let iz = self.inv_z[y as usize * self.width as usize + x as usize];
        if iz > 0.0 {
            1.0 / iz
        } else {
            f32::INFINITY
        }
    }

    /// Rasterises `setups` (ids are their indices plus `id_base`) with a depth test against
    /// what the buffer holds, in parallel over bands of [`BAND_ROWS`] rows. Each band draws
    /// only the triangles binned to it, in index order (so ties in the depth test keep the
    /// first triangle, as on the GPU), and binning reads each set-up twice whatever the
    /// number of bands.
    pub fn draw<S: SetupSlot>(&mut self, cam: &RasterCamera, setups: &[S], id_base: u32) {
        let bins = Bins::of(setups, self.height as usize);
        let Some(rect) = bins.iter().filter_map(|b| b.rect).reduce(PixelRect::union) else {
            return;
        };
        self.dirty = PixelRect::union_opt(self.dirty, Some(rect));
        let w = self.width as usize;
        let inv_near = 1.0 / cam.near_m;
        let inv_far = 1.0 / cam.far_m;
        let (first_band, last_band) = (rect.y0 as usize / BAND_ROWS, rect.y1 as usize / BAND_ROWS);
        let start = first_band * BAND_ROWS * w;
        let end = ((last_band + 1) * BAND_ROWS).min(self.height as usize) * w;
        let inv_z = &mut self.inv_z[start..end];
        let ids = &mut self.id[start..end];
        inv_z
            .par_chunks_mut(BAND_ROWS * w)
            .zip(ids.par_chunks_mut(BAND_ROWS * w))
            .enumerate()
            .for_each(|(k, (zs, is))| {
                let band = first_band + k;
                let y_begin = (band * BAND_ROWS) as u32;
                let y_end = y_begin + (zs.len() / w) as u32 - 1;
                let binned = bins.iter().flat_map(|b| b.band(band));
                for i in binned {
                    let Some(s) = setups[i as usize].setup() else {
                        continue;
                    };
                    let r = s.rect;
                    let id = id_base + i;
                    for y in r.y0.max(y_begin)..r.y1.min(y_end) + 1 {
                        let yf = y as f32;
                        // The row's span where every form is >= 0 (each is affine in x), one
                        // pixel wider on each side against rounding; the exact test below
                        // decides each pixel.
                        let Some((x0, x1)) = s.row_span(yf) else {
                            continue;
                        };
                        let xf = x0 as f32;
                        let (d0, u0, v0) = (s.d.at(xf, yf), s.u.at(xf, yf), s.v.at(xf, yf));
                        let row = (y - y_begin) as usize * w;
                        let zrow = &mut zs[row + x0 as usize..=row + x1 as usize];
                        let irow = &mut is[row + x0 as usize..=row + x1 as usize];
                        // Branch-free over the span (the forms at pixel k are the row start
                        // plus k steps, so the loop vectorises).
                        for (k, (z, i)) in zrow.iter_mut().zip(irow.iter_mut()).enumerate() {
                            let kf = k as f32;
                            let d = d0 + kf * s.d.a;
                            let u = u0 + kf * s.u.a;
                            let v = v0 + kf * s.v.a;
                            let e = d - u - v;
                            let iz = d * s.inv_t;
                            // Inside when d > 0 and u, v, d - u - v >= 0 (no sign bit set).
                            let inside = (d > 0.0)
                                & ((u.to_bits() | v.to_bits() | e.to_bits()) >> 31 == 0)
                                & (iz <= inv_near)
                                & (iz >= inv_far)
                                & (iz > *z);
                            *z = if inside { iz } else { *z };
                            *i = if inside { id } else { *i };
                        }
                    }
                }
            });
    }
}

/// Rows of a band of [`VisBuffer::draw`] (bands start at multiples of it).
pub const BAND_ROWS: usize = 16;

/// The set-ups of one run of consecutive indices sorted into the bands their rows touch
/// (counting sort): a triangle spanning several bands is in each.
struct Bins {
    /// Bounds of the run's set-ups.
    rect: Option<PixelRect>,
    /// `order[starts[b]..starts[b + 1]]`: the indices (into all set-ups) in band `b`,
    /// increasing.
    starts: Vec<u32>,
    order: Vec<u32>,
}

impl Bins {
    /// Set-ups per run: enough runs for the thread pool, few enough that each band's lists
    /// stay long.
    const MIN_RUN: usize = 2048;

    /// The bins of `setups` over an image `height` rows tall, runs in parallel.
    fn of<S: SetupSlot>(setups: &[S], height: usize) -> Vec<Bins> {
        let bands = height.div_ceil(BAND_ROWS);
        let run = setups
            .len()
            .div_ceil(2 * rayon::current_num_threads())
            .max(Self::MIN_RUN);
        setups
            .par_chunks(run)
            .enumerate()
            .map(|(c, chunk)| {
                let base = (c * run) as u32;
                let bands_of = |r: PixelRect| {
                    (r.y0 as usize / BAND_ROWS)..=(r.y1 as usize / BAND_ROWS).min(bands - 1)
                };
                let mut starts = vec![0u32; bands + 1];
                let mut rect = None;
                for s in chunk.iter().filter_map(SetupSlot::setup) {
                    rect = PixelRect::union_opt(rect, Some(s.rect));
                    for b in bands_of(s.rect) {
                        starts[b + 1] += 1;
                    }
                }
                for b in 0..bands {
                    starts[b + 1] += starts[b];
                }
                let mut next = starts.clone();
                let mut order = vec![0u32; starts[bands] as usize];
                for (i, s) in chunk.iter().enumerate() {
                    let Some(s) = s.setup() else {
                        continue;
                    };
                    for b in bands_of(s.rect) {
                        order[next[b] as usize] = base + i as u32;
                        next[b] += 1;
                    }
                }
                Bins {
                    rect,
                    starts,
                    order,
                }
            })
            .collect()
    }

    /// The indices in `band`, increasing.
    fn band(&self, band: usize) -> impl Iterator<Item = u32> + '_ {
        let (a, b) = match (self.starts.get(band), self.starts.get(band + 1)) {
            (Some(&a), Some(&b)) => (a as usize, b as usize),
            _ => (0, 0),
        };
        self.order[a..b].iter().copied()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cam(w: u32, h: u32) -> RasterCamera {
        RasterCamera {
            fx: 100.0,
            fy: 100.0,
            cx: (w as f64 - 1.0) / 2.0,
            cy: (h as f64 - 1.0) / 2.0,
            width: w,
            height: h,
            near_m: 0.01,
            far_m: 100.0,
        }
    }

    /// Exact coverage of pixel centres by a projected triangle (2D point-in-triangle).
    fn inside_2d(p: [(f64, f64); 3], x: f64, y: f64) -> Option<bool> {
        let e = |a: (f64, f64), b: (f64, f64)| (b.0 - a.0) * (y - a.1) - (b.1 - a.1) * (x - a.0);
        let (e0, e1, e2) = (e(p[0], p[1]), e(p[1], p[2]), e(p[2], p[0]));
        let eps = 1e-6;
        if [e0, e1, e2].iter().any(|v| v.abs() < eps) {
            return None; // on an edge: either answer is right
        }
        Some((e0 > 0.0 && e1 > 0.0 && e2 > 0.0) || (e0 < 0.0 && e1 < 0.0 && e2 < 0.0))
    }

    #[test]
    fn coverage_and_depth_match_analytic_projection() {
        let c = cam(64, 48);
        let tris = [
            [
                Vec3::new(-0.2, -0.1, 1.0),
                Vec3::new(0.25, -0.05, 1.3),
                Vec3::new(0.0, 0.2, 0.8),
            ],
            // Clockwise on screen.
            [
                Vec3::new(0.0, 0.2, 0.8),
                Vec3::new(0.25, -0.05, 1.3),
                Vec3::new(-0.2, -0.1, 1.0),
            ],
        ];
        for t in tris {
            let s = TriSetup::new(&c, t[0], t[1], t[2]).unwrap();
            let mut vb = VisBuffer::new(64, 48);
            vb.draw(&c, &[s], 0);
            let proj = t.map(|p| c.pixel_from_camera(p.as_dvec3()).unwrap());
            let mut covered = 0;
            for y in 0..48 {
                for x in 0..64 {
                    let want = inside_2d(proj, x as f64, y as f64);
                    let got = vb.id[y * 64 + x] == 0;
                    if let Some(want) = want {
                        assert_eq!(got, want, "pixel ({x}, {y})");
                    }
                    if got {
                        covered += 1;
                        // Depth: the ray through the pixel meets the plane at this z.
                        let h = s.hit(x as f32, y as f32);
                        let p: Vec3 = t[0] * h.b[0] + t[1] * h.b[1] + t[2] * h.b[2];
                        let z = vb.depth_m(x as u32, y as u32);
                        assert!((p.z - z).abs() < 1e-5, "{} vs {z}", p.z);
                        // The point projects back onto the pixel centre.
                        let (u, v) = c.pixel_from_camera(p.as_dvec3()).unwrap();
                        assert!((u - x as f64).abs() < 1e-3 && (v - y as f64).abs() < 1e-3);
                    }
                }
            }
            assert!(covered > 100, "{covered}");
        }
    }

    #[test]
    fn nearer_surface_wins_and_near_plane_clips() {
        let c = cam(32, 32);
        let quad = |z: f32| {
            [
                Vec3::new(-z, -z, z),
                Vec3::new(z, -z, z),
                Vec3::new(0.0, z, z),
            ]
        };
        let far = quad(2.0);
        let near = quad(1.0);
        let setups: Vec<TriSetup> = [far, near]
            .iter()
            .map(|t| TriSetup::new(&c, t[0], t[1], t[2]).unwrap())
            .collect();
        let mut vb = VisBuffer::new(32, 32);
        vb.draw(&c, &setups, 10);
        assert_eq!(vb.id[16 * 32 + 16], 11);
        assert!((vb.depth_m(16, 16) - 1.0).abs() < 1e-6);
        // A triangle crossing the near plane: only its part beyond it is drawn.
        let crossing = [
            Vec3::new(-0.1, 0.0, -0.5),
            Vec3::new(0.1, 0.0, 2.0),
            Vec3::new(0.1, 0.1, 2.0),
        ];
        let s = TriSetup::new(&c, crossing[0], crossing[1], crossing[2]).unwrap();
        vb.reset(32, 32);
        assert!(vb.id.iter().all(|&i| i == NO_TRIANGLE));
        vb.draw(&c, &[s], 0);
        for y in 0..32 {
            for x in 0..32 {
                let z = vb.depth_m(x, y);
                assert!(!z.is_finite() || z >= c.near_m - 1e-6);
            }
        }
        // Entirely behind: nothing.
        assert!(TriSetup::new(&c, quad(-1.0)[0], quad(-1.0)[1], quad(-1.0)[2]).is_none());
    }

    /// Drawing thousands of triangles at once (binned into bands, several runs, many
    /// triangles over band borders and equal depths) gives, to the bit, what drawing them one
    /// by one in index order gives: the nearest surface, the first triangle on ties.
    #[test]
    fn binned_draw_equals_drawing_one_by_one() {
        let c = cam(200, 150);
        let mut seed = 7u32;
        let mut rnd = || {
            seed ^= seed << 13;
            seed ^= seed >> 17;
            seed ^= seed << 5;
            seed as f32 / u32::MAX as f32
        };
        let mut slots: Vec<Option<TriSetup>> = Vec::new();
        for k in 0..5000 {
            // Half the triangles come in pairs at the same depth (ties); a few are long.
            let z = if k % 2 == 1 { 1.0 } else { 0.8 + rnd() };
            let (x, y) = (rnd() * 2.0 - 1.0, rnd() * 1.6 - 0.8);
            let size = if k % 97 == 0 { 0.8 } else { 0.06 };
            let a = Vec3::new(x, y, 1.0) * z;
            let b = Vec3::new(x + size * rnd(), y + size * (rnd() - 0.5), 1.0) * z;
            let d = Vec3::new(x + size * (rnd() - 0.5), y + size * rnd(), 1.0) * z;
            slots.push(TriSetup::new(&c, a, b, d));
        }
        assert!(slots.len() > 2 * Bins::MIN_RUN);
        let mut all = VisBuffer::new(200, 150);
        all.draw(&c, &slots, 3);
        let mut one = VisBuffer::new(200, 150);
        for (i, s) in slots.iter().enumerate() {
            one.draw(&c, std::slice::from_ref(s), 3 + i as u32);
        }
        let drawn = all.id.iter().filter(|&&i| i != NO_TRIANGLE).count();
        assert!(drawn > 10_000, "{drawn}");
        assert_eq!(all.id, one.id);
        assert!(all
            .inv_z
            .iter()
            .zip(&one.inv_z)
            .all(|(a, b)| a.to_bits() == b.to_bits()));
        assert_eq!(all.dirty, one.dirty);
    }

    #[test]
    fn shared_edges_leave_no_gaps() {
        // A fan of triangles around a centre: every pixel centre inside the hull is covered.
        let c = cam(80, 80);
        let centre = Vec3::new(0.01, -0.02, 1.0);
        let n = 13;
        let ring: Vec<Vec3> = (0..n)
            .map(|i| {
                let a = i as f32 / n as f32 * std::f32::consts::TAU + 0.1;
                Vec3::new(0.35 * a.cos(), 0.35 * a.sin(), 1.0 + 0.1 * a.sin())
            })
            .collect();
        let setups: Vec<TriSetup> = (0..n)
            .filter_map(|i| TriSetup::new(&c, centre, ring[i], ring[(i + 1) % n]))
            .collect();
        let mut vb = VisBuffer::new(80, 80);
        vb.draw(&c, &setups, 0);
        // Inside a circle well within the polygon every pixel is covered.
        for y in 0..80 {
            for x in 0..80 {
                let (dx, dy) = (x as f64 - 39.5, y as f64 - 39.5);
                if (dx * dx + dy * dy).sqrt() < 25.0 {
                    assert_ne!(vb.id[y * 80 + x], NO_TRIANGLE, "gap at ({x}, {y})");
                }
            }
        }
    }
}
