//! The set's sun on the twin: a directional light with ambient, and the twin's own cast
//! shadows (an arm's shadow on the chest), for relighting a live sample and shading the
//! fallback.
//!
//! First-order spherical harmonics ([`crate::look::irradiance`]) are linear in the normal:
//! they cannot say that a surface turned away from a sun gets only the ambient light, nor that
//! a surface behind another part of the prop is in its shadow. On a set lit by one hard light
//! (measured on the Blender Cycles CesiumMan set) those are most of the error of the twin's
//! interior: the twin was brighter than the truth by more than 20 levels on pixels carrying
//! 56 % of the squared error. Here the irradiance of a surface point with unit normal `n` is
//!
//! `E(n, s) = ambient + s * direct * max(n . l, 0)` (per linear RGB channel)
//!
//! with `l` the unit direction towards the light in the world (the marker frame) and `s` in
//! [0, 1] the fraction of the light the point receives, read from a [`ShadowMap`] of the
//! posed twin along `l`. A live sample taken at the key pose (`n_k`, `s_k`) shows at the
//! in-between (`n_i`, `s_i`) times `E(n_i, s_i) / E(n_k, s_k)`, clamped to
//! [[`SUN_RELIGHT_MIN`], [`SUN_RELIGHT_MAX`]].
//!
//! Conventions: positions and normals in the world frame the light is fitted in; the map's
//! depth is `p . l` (larger is nearer the light); cells square, `cell_m` metres.

use std::ops::Range;

use glam::Vec3;
use rayon::prelude::*;

use crate::look::MIN_IRRADIANCE;

/// Smallest ratio `E(n_i, s_i) / E(n_k, s_k)`: a point that goes from full light into shadow
/// keeps about the ambient's share (about 0.3 on the Blender sets' table).
pub const SUN_RELIGHT_MIN: f32 = 0.25;
/// Largest ratio: brightening a sample taken in shadow amplifies its noise.
pub const SUN_RELIGHT_MAX: f32 = 2.5;
/// Shadow-map cells along the longer side of the twin as the light sees it (measured on the
/// Blender sets: 64, 96, 128 and 192 cells gave 23.56, 23.62, 23.63 and 23.64 dB on CesiumMan
/// and 28.63, 28.61, 28.62 and 28.61 dB on the bust; the cost grows with the cells).
pub const SHADOW_MAP_CELLS: usize = 64;

/// A directional light with ambient, per linear RGB channel.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SunLight {
    /// Unit direction towards the light, world frame.
    pub toward_light: Vec3,
    pub ambient_rgb: [f32; 3],
    pub direct_rgb: [f32; 3],
}

impl SunLight {
    /// Irradiance at unit normal `n` (zero: the ambient plus half the direct light) receiving
    /// the fraction `lit` of the light, floored at [`MIN_IRRADIANCE`].
    #[inline]
    pub fn irradiance(&self, n: Vec3, lit: f32) -> [f32; 3] {
        let cos = if n == Vec3::ZERO {
            0.5
        } else {
            n.dot(self.toward_light).max(0.0)
        };
        let d = lit.clamp(0.0, 1.0) * cos;
        std::array::from_fn(|c| (self.ambient_rgb[c] + self.direct_rgb[c] * d).max(MIN_IRRADIANCE))
    }

    /// `E(n_anim, lit_anim) / E(n_key, lit_key)` per channel, clamped to
    /// [[`SUN_RELIGHT_MIN`], [`SUN_RELIGHT_MAX`]].
    #[inline]
    pub fn relight_factor(
        &self,
        n_key: Vec3,
        lit_key: f32,
        n_anim: Vec3,
        lit_anim: f32,
    ) -> [f32; 3] {
        let (ek, ea) = (
            self.irradiance(n_key, lit_key),
            self.irradiance(n_anim, lit_anim),
        );
        std::array::from_fn(|c| (ea[c] / ek[c]).clamp(SUN_RELIGHT_MIN, SUN_RELIGHT_MAX))
    }
}

/// Depth of the posed twin as the light sees it: an orthographic map along the light, the
/// largest `p . l` per cell (the surface nearest the light).
#[derive(Debug, Clone, Default)]
pub struct ShadowMap {
    toward_light: Vec3,
    u: Vec3,
    v: Vec3,
    u0: f32,
    v0: f32,
    cell_m: f32,
    width: usize,
    height: usize,
    depth: Vec<f32>,
}

impl ShadowMap {
    /// The map of `meshes` (`(positions, triangle indices)`, world frame) along
    /// `toward_light` (unit), [`SHADOW_MAP_CELLS`] cells along the longer side. Indices out of
    /// range and non-finite positions are skipped; an empty twin gives a map that lights
    /// everything.
    pub fn new(toward_light: Vec3, meshes: &[(&[Vec3], &[u32])]) -> Self {
        let l = toward_light.normalize_or_zero();
        if l == Vec3::ZERO {
            return Self::default();
        }
        let u = l.any_orthonormal_vector();
        let v = l.cross(u);
        // Every vertex projected once: (u, v, depth), NaN where not finite.
        let mut projected: Vec<Vec<[f32; 3]>> = Vec::with_capacity(meshes.len());
        let (mut umin, mut umax, mut vmin, mut vmax) = (f32::MAX, f32::MIN, f32::MAX, f32::MIN);
        for (positions, _) in meshes {
            projected.push(
                positions
                    .iter()
                    .map(|p| {
                        if !p.is_finite() {
                            return [f32::NAN; 3];
                        }
                        let (pu, pv) = (p.dot(u), p.dot(v));
                        umin = umin.min(pu);
                        umax = umax.max(pu);
                        vmin = vmin.min(pv);
                        vmax = vmax.max(pv);
                        [pu, pv, p.dot(l)]
                    })
                    .collect(),
            );
        }
        let extent = (umax - umin).max(vmax - vmin);
        if !(extent.is_finite() && extent > 0.0) {
            return Self::default();
        }
        let cell_m = extent / SHADOW_MAP_CELLS as f32;
        // One cell of margin on every side, so the filter reads empty cells there.
        let (u0, v0) = (umin - cell_m, vmin - cell_m);
        let width = ((umax - u0) / cell_m) as usize + 2;
        let height = ((vmax - v0) / cell_m) as usize + 2;
        let inv_cell = 1.0 / cell_m;
        for q in projected.iter_mut() {
            for p in q.iter_mut() {
                p[0] = (p[0] - u0) * inv_cell - 0.5;
                p[1] = (p[1] - v0) * inv_cell - 0.5;
            }
        }
        // Each mesh's vertices, then runs of its triangles, drawn in parallel into partial
        // maps merged by the maximum: the same map as drawing them one after the other.
        const TRIANGLES_PER_TASK: usize = 1024;
        let mut tasks = Vec::new();
        for (m, (_, indices)) in meshes.iter().enumerate() {
            tasks.push((m, None));
            let count = indices.len() / 3;
            tasks.extend(
                (0..count)
                    .step_by(TRIANGLES_PER_TASK)
                    .map(|t| (m, Some(t..(t + TRIANGLES_PER_TASK).min(count)))),
            );
        }
        let empty = || vec![f32::NEG_INFINITY; width * height];
        let draw = |mut depth: Vec<f32>, (m, triangles): &(usize, Option<Range<usize>>)| {
            let q = &projected[*m];
            match triangles {
                // Each vertex marks its own cell too, so triangles smaller than a cell leave
                // no holes.
                None => {
                    for p in q.iter() {
                        if p.iter().all(|v| v.is_finite()) {
                            let (x, y) = ((p[0] + 0.5) as usize, (p[1] + 0.5) as usize);
                            if x < width && y < height {
                                let cell = &mut depth[y * width + x];
                                *cell = cell.max(p[2]);
                            }
                        }
                    }
                }
                Some(range) => {
                    let indices = &meshes[*m].1[range.start * 3..range.end * 3];
                    for t in indices.chunks_exact(3) {
                        if let (Some(a), Some(b), Some(c)) = (
                            q.get(t[0] as usize),
                            q.get(t[1] as usize),
                            q.get(t[2] as usize),
                        ) {
                            draw_triangle(&mut depth, width, height, [*a, *b, *c]);
                        }
                    }
                }
            }
            depth
        };
        let depth = tasks
            .par_iter()
            .fold(empty, draw)
            .reduce_with(|mut a, b| {
                for (x, y) in a.iter_mut().zip(&b) {
                    *x = x.max(*y);
                }
                a
            })
            .unwrap_or_else(empty);
        Self {
            toward_light: l,
            u,
            v,
            u0,
            v0,
            cell_m,
            width,
            height,
            depth,
        }
    }

    /// Cell coordinates (continuous, cell centres at integers) and depth of a world point.
    #[inline]
    fn project(&self, p: Vec3) -> (f32, f32, f32) {
        (
            (p.dot(self.u) - self.u0) / self.cell_m - 0.5,
            (p.dot(self.v) - self.v0) / self.cell_m - 0.5,
            p.dot(self.toward_light),
        )
    }

    /// The fraction in [0, 1] of the light that reaches the surface point `p` with normal `n`
    /// (zero: no normal offset): the 2 x 2 cells around it, each lit when nothing in it lies
    /// more than the bias nearer the light, weighted bilinearly (percentage-closer
    /// filtering). The point is first moved 1.5 cells along its normal and the bias is 2
    /// cells, so a surface does not shadow itself.
    pub fn lit(&self, p: Vec3, n: Vec3) -> f32 {
        if self.depth.is_empty() || !p.is_finite() {
            return 1.0;
        }
        let q = p + n.normalize_or_zero() * (1.5 * self.cell_m);
        let (x, y, d) = self.project(q);
        if !(x.is_finite() && y.is_finite()) {
            return 1.0;
        }
        let limit = d + 2.0 * self.cell_m;
        // Cells outside the map are empty: lit. (x, y >= -1 keeps the floor an integer cast.)
        let (x, y) = (x.max(-1.0), y.max(-1.0));
        let (x0, y0) = ((x + 1.0) as isize - 1, (y + 1.0) as isize - 1);
        let (fx, fy) = (x - x0 as f32, y - y0 as f32);
        let lit_at = |xx: isize, yy: isize| -> f32 {
            let blocked = xx >= 0
                && yy >= 0
                && (xx as usize) < self.width
                && (yy as usize) < self.height
                && self.depth[yy as usize * self.width + xx as usize] > limit;
            if blocked {
                0.0
            } else {
                1.0
            }
        };
        let top = lit_at(x0, y0) * (1.0 - fx) + lit_at(x0 + 1, y0) * fx;
        let bottom = lit_at(x0, y0 + 1) * (1.0 - fx) + lit_at(x0 + 1, y0 + 1) * fx;
        top * (1.0 - fy) + bottom * fy
    }

    /// [`ShadowMap::lit`] for a vertex; 1 without a look-up when its normal (non-zero) faces
    /// away from the light: it gets no direct light whatever the map says (the clamped cosine
    /// is 0 there), and 1 keeps the interpolation into a neighbouring lit triangle from
    /// darkening it (measured on the CesiumMan set: 0 there cost 0.06 dB).
    #[inline]
    pub fn lit_vertex(&self, p: Vec3, n: Vec3) -> f32 {
        if n != Vec3::ZERO && n.dot(self.toward_light) <= 0.0 {
            1.0
        } else {
            self.lit(p, n)
        }
    }
}

/// Draws a triangle into the `depth` of a `width` x `height` map, given in cell coordinates
/// and depth (`[x, y, depth]`; NaN: skipped).
fn draw_triangle(depth: &mut [f32], width: usize, height: usize, q: [[f32; 3]; 3]) {
    if q.iter().flatten().any(|v| !v.is_finite()) {
        return;
    }
    let [a, b, c] = q;
    let area = (b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1]);
    if area.abs() < 1e-12 {
        return;
    }
    // Integer floor and ceiling without the library calls (no rounding instruction in
    // the baseline x86-64 target); the coordinates are finite here.
    let floor = |x: f32| {
        let t = x as i32;
        t - i32::from((t as f32) > x)
    };
    let ceil = |x: f32| {
        let t = x as i32;
        t + i32::from((t as f32) < x)
    };
    let x0 = ceil(a[0].min(b[0]).min(c[0])).max(0);
    let y0 = ceil(a[1].min(b[1]).min(c[1])).max(0);
    let x1 = floor(a[0].max(b[0]).max(c[0])).min(width as i32 - 1);
    let y1 = floor(a[1].max(b[1]).max(c[1])).min(height as i32 - 1);
    if x1 < x0 || y1 < y0 {
        return;
    }
    let (x0, y0, x1, y1) = (x0 as usize, y0 as usize, x1 as usize, y1 as usize);
    // Barycentric weights of b and c, and the depth, as planes in (x, y).
    let inv = 1.0 / area;
    let (wb_x, wb_y) = ((c[1] - a[1]) * inv, -(c[0] - a[0]) * inv);
    let (wc_x, wc_y) = (-(b[1] - a[1]) * inv, (b[0] - a[0]) * inv);
    let (db, dc) = (b[2] - a[2], c[2] - a[2]);
    let (d_x, d_y) = (wb_x * db + wc_x * dc, wb_y * db + wc_y * dc);
    const EPS: f32 = -1e-4;
    for y in y0..=y1 {
        let (ry, rx) = (y as f32 - a[1], x0 as f32 - a[0]);
        let mut wb = wb_x * rx + wb_y * ry;
        let mut wc = wc_x * rx + wc_y * ry;
        let mut d = a[2] + d_x * rx + d_y * ry;
        let row = &mut depth[y * width..];
        for cell in &mut row[x0..=x1] {
            if wb >= EPS && wc >= EPS && wb + wc <= 1.0 - EPS && d > *cell {
                *cell = d;
            }
            wb += wb_x;
            wc += wc_x;
            d += d_x;
        }
    }
}

/// Cells along the longest side of a primitive's bounding box for [`coarse_mesh`].
pub const COARSE_CELLS: usize = 32;

/// A coarser mesh of the same surface for the shadow map, from vertex clustering
/// ([`coarse_mesh`]): a subset of a primitive's vertices and triangles over them.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct CoarseMesh {
    /// Indices into the primitive's vertices.
    pub vertices: Vec<u32>,
    /// Triangles, indexing [`CoarseMesh::vertices`].
    pub triangles: Vec<u32>,
}

impl CoarseMesh {
    /// The coarse vertices' positions gathered from the primitive's `positions` in any pose
    /// (missing: NaN, which the map skips), into `out` (cleared first).
    pub fn gather(&self, positions: &[Vec3], out: &mut Vec<Vec3>) {
        out.clear();
        out.extend(
            self.vertices
                .iter()
                .map(|&i| positions.get(i as usize).copied().unwrap_or(Vec3::NAN)),
        );
    }
}

/// A coarser mesh of the same surface for the shadow map, by vertex clustering: vertices in
/// one cell of a grid over `positions` ([`COARSE_CELLS`] along the longest side) are
/// represented by the first of them, and the triangles whose three corners land in three
/// different cells are kept, on the representatives. It indexes the primitive's own vertices,
/// so it serves every pose of a skinned mesh; computed once, from the rest pose. Out-of-range
/// indices and non-finite positions are left out.
pub fn coarse_mesh(positions: &[Vec3], indices: &[u32]) -> CoarseMesh {
    let finite = || positions.iter().filter(|p| p.is_finite());
    let lo = finite().fold(Vec3::splat(f32::MAX), |a, &p| a.min(p));
    let hi = finite().fold(Vec3::splat(f32::MIN), |a, &p| a.max(p));
    let extent = (hi - lo).max_element();
    if !(extent.is_finite() && extent > 0.0) {
        return CoarseMesh::default();
    }
    let inv_cell = COARSE_CELLS as f32 / extent;
    // Cell -> the coarse vertex (index into `vertices`) that represents it.
    let mut cell_vertex: std::collections::HashMap<(u32, u32, u32), u32> =
        std::collections::HashMap::new();
    let mut vertices = Vec::new();
    let representative: Vec<Option<u32>> = positions
        .iter()
        .enumerate()
        .map(|(i, p)| {
            if !p.is_finite() {
                return None;
            }
            let c = ((*p - lo) * inv_cell).min(Vec3::splat(COARSE_CELLS as f32));
            let key = (c.x as u32, c.y as u32, c.z as u32);
            Some(*cell_vertex.entry(key).or_insert_with(|| {
                vertices.push(i as u32);
                vertices.len() as u32 - 1
            }))
        })
        .collect();
    let mut triangles = Vec::new();
    for t in indices.chunks_exact(3) {
        let r = [t[0], t[1], t[2]].map(|i| representative.get(i as usize).copied().flatten());
        if let [Some(a), Some(b), Some(c)] = r {
            if a != b && b != c && a != c {
                triangles.extend([a, b, c]);
            }
        }
    }
    CoarseMesh {
        vertices,
        triangles,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two horizontal squares, the upper one half over the lower; light straight down.
    fn two_squares() -> (Vec<Vec3>, Vec<u32>) {
        let sq = |x0: f32, z: f32| {
            [
                Vec3::new(x0, 0.0, z),
                Vec3::new(x0 + 1.0, 0.0, z),
                Vec3::new(x0 + 1.0, 1.0, z),
                Vec3::new(x0, 1.0, z),
            ]
        };
        let mut p = sq(0.0, 0.0).to_vec();
        p.extend(sq(0.5, 0.5));
        (p, vec![0, 1, 2, 0, 2, 3, 4, 5, 6, 4, 6, 7])
    }

    #[test]
    fn a_square_shadows_the_one_below_it_and_not_itself() {
        let (p, i) = two_squares();
        let map = ShadowMap::new(Vec3::Z, &[(&p, &i)]);
        // Under the upper square: dark; beside it: lit; on the upper square: lit.
        assert_eq!(map.lit(Vec3::new(0.8, 0.5, 0.0), Vec3::Z), 0.0);
        assert_eq!(map.lit(Vec3::new(0.2, 0.5, 0.0), Vec3::Z), 1.0);
        assert_eq!(map.lit(Vec3::new(1.0, 0.5, 0.5), Vec3::Z), 1.0);
        // A vertex facing away from the light gets no direct light: no look-up, 1.
        assert_eq!(map.lit_vertex(Vec3::new(0.8, 0.5, 0.0), -Vec3::Z), 1.0);
        assert_eq!(map.lit_vertex(Vec3::new(0.8, 0.5, 0.0), Vec3::Z), 0.0);
        // At the shadow's edge: partly lit.
        let edge = map.lit(Vec3::new(0.5, 0.5, 0.0), Vec3::Z);
        assert!(edge > 0.0 && edge < 1.0, "{edge}");
        // Light from below: the upper square is in the lower one's shadow where they overlap.
        let below = ShadowMap::new(-Vec3::Z, &[(&p, &i)]);
        assert_eq!(below.lit(Vec3::new(0.8, 0.5, 0.5), -Vec3::Z), 0.0);
        assert_eq!(below.lit(Vec3::new(1.3, 0.5, 0.5), -Vec3::Z), 1.0);
    }

    #[test]
    fn hostile_input_lights_everything() {
        let (p, _) = two_squares();
        let bad = [0u32, 1, 99];
        let map = ShadowMap::new(Vec3::Z, &[(&p, &bad)]);
        assert_eq!(map.lit(Vec3::new(0.8, 0.5, 0.0), Vec3::Z), 1.0);
        let empty = ShadowMap::new(Vec3::ZERO, &[(&p, &bad)]);
        assert_eq!(empty.lit(Vec3::ZERO, Vec3::Z), 1.0);
        let nan = [Vec3::NAN; 3];
        let map = ShadowMap::new(Vec3::Z, &[(&nan, &[0, 1, 2])]);
        assert_eq!(map.lit(Vec3::ZERO, Vec3::Z), 1.0);
        assert_eq!(map.lit(Vec3::NAN, Vec3::Z), 1.0);
    }

    /// The map drawn in parallel runs (merged by the maximum) is the map drawn one vertex
    /// and one triangle after the other, to the bit: two meshes of several runs each.
    #[test]
    fn parallel_map_equals_the_sequential_drawing() {
        let grid = |n: usize, offset: Vec3| {
            let mut positions = Vec::new();
            for i in 0..=n {
                for j in 0..=n {
                    let (x, y) = (i as f32 / n as f32 - 0.5, j as f32 / n as f32 - 0.5);
                    let z = 0.2 * (7.0 * x).sin() * (5.0 * y).cos();
                    positions.push(Vec3::new(x, y, z) * 0.3 + offset);
                }
            }
            let mut indices = Vec::new();
            for i in 0..n as u32 {
                for j in 0..n as u32 {
                    let a = i * (n as u32 + 1) + j;
                    let b = a + n as u32 + 1;
                    indices.extend_from_slice(&[a, b, a + 1, a + 1, b, b + 1]);
                }
            }
            (positions, indices)
        };
        let (p1, i1) = grid(40, Vec3::ZERO);
        let (p2, i2) = grid(30, Vec3::new(0.1, 0.05, 0.08));
        let meshes = [
            (p1.as_slice(), i1.as_slice()),
            (p2.as_slice(), i2.as_slice()),
        ];
        assert!(i1.len() / 3 > 3 * 1024, "several runs per mesh");
        let map = ShadowMap::new(Vec3::new(0.3, -0.2, 0.9).normalize(), &meshes);
        let (w, h) = (map.width, map.height);
        let mut depth = vec![f32::NEG_INFINITY; w * h];
        let inv_cell = 1.0 / map.cell_m;
        for (positions, indices) in meshes {
            let q: Vec<[f32; 3]> = positions
                .iter()
                .map(|p| {
                    let (pu, pv) = (p.dot(map.u), p.dot(map.v));
                    [
                        (pu - map.u0) * inv_cell - 0.5,
                        (pv - map.v0) * inv_cell - 0.5,
                        p.dot(map.toward_light),
                    ]
                })
                .collect();
            for p in &q {
                let (x, y) = ((p[0] + 0.5) as usize, (p[1] + 0.5) as usize);
                if x < w && y < h {
                    depth[y * w + x] = depth[y * w + x].max(p[2]);
                }
            }
            for t in indices.chunks_exact(3) {
                let [a, b, c] = [0, 1, 2].map(|k| q[t[k] as usize]);
                draw_triangle(&mut depth, w, h, [a, b, c]);
            }
        }
        let drawn = depth.iter().filter(|d| d.is_finite()).count();
        assert!(drawn > w * h / 4, "{drawn} of {} cells drawn", w * h);
        let same = depth
            .iter()
            .zip(&map.depth)
            .all(|(a, b)| a.to_bits() == b.to_bits());
        assert!(same, "parallel map differs from the sequential drawing");
    }

    #[test]
    fn relight_factor_follows_the_sun_and_the_shadow() {
        let sun = SunLight {
            toward_light: Vec3::Z,
            ambient_rgb: [0.3; 3],
            direct_rgb: [0.7; 3],
        };
        // Lit and facing -> in shadow: ambient share (0.3), floored at SUN_RELIGHT_MIN.
        let f = sun.relight_factor(Vec3::Z, 1.0, Vec3::Z, 0.0);
        assert!((f[0] - 0.3).abs() < 1e-6, "{f:?}");
        // Turned away from the sun: the same.
        assert!((sun.relight_factor(Vec3::Z, 1.0, -Vec3::Z, 1.0)[0] - 0.3).abs() < 1e-6);
        // Nothing changes: 1.
        assert_eq!(sun.relight_factor(Vec3::X, 0.4, Vec3::X, 0.4), [1.0; 3]);
        // Shadow to light: clamped at the top.
        assert_eq!(
            sun.relight_factor(Vec3::Z, 0.0, Vec3::Z, 1.0),
            [SUN_RELIGHT_MAX; 3]
        );
    }
}
