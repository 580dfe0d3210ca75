//! Mesh properties the rasteriser can use: whether a triangle mesh is closed and oriented
//! outwards, so that back faces can be culled without changing the image.
//!
//! For a closed surface whose triangles all wind counter-clockwise seen from outside, any ray
//! from a camera outside the volume meets a front face before any back face, so the nearest
//! surface of every pixel is a front face: culling the back faces leaves the depth and the
//! colour of every pixel unchanged (the GPU path, which never culls, draws the same image)
//! and halves the rasteriser's work.

use std::collections::HashMap;

use glam::Vec3;

/// True when the triangle list, with vertices welded by position (UV seams and poles
/// duplicate vertices; positions within 1e-6 of the bounding box's diagonal are one vertex),
/// is a closed 2-manifold (every edge used exactly twice, once in each direction) enclosing
/// a positive signed volume (counter-clockwise seen from outside). Triangles that weld to a
/// line or a point (a pole's fan) cover no area and are ignored. Conservative: vertices that
/// fall on either side of a welding cell, or anything unexpected, make it false.
pub fn closed_and_outward(positions: &[Vec3], indices: &[u32]) -> bool {
    if indices.is_empty() || !indices.len().is_multiple_of(3) || positions.is_empty() {
        return false;
    }
    let (lo, hi) = positions.iter().fold(
        (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN)),
        |(l, h), p| (l.min(*p), h.max(*p)),
    );
    let cell = f64::from((hi - lo).length()) * 1e-6;
    if !(cell.is_finite() && cell > 0.0) {
        return false;
    }
    // Weld by position, quantised to the cell.
    let mut ids: HashMap<[i64; 3], u32> = HashMap::with_capacity(positions.len());
    let welded: Vec<u32> = positions
        .iter()
        .map(|p| {
            let q = |v: f32| (f64::from(v) / cell).round() as i64;
            let key = [q(p.x), q(p.y), q(p.z)];
            let next = ids.len() as u32;
            *ids.entry(key).or_insert(next)
        })
        .collect();
    let mut edges: HashMap<(u32, u32), u32> = HashMap::with_capacity(indices.len());
    let mut volume6 = 0.0f64;
    for tri in indices.chunks_exact(3) {
        let Some(v) = tri
            .iter()
            .map(|&i| welded.get(i as usize).copied())
            .collect::<Option<Vec<u32>>>()
        else {
            return false;
        };
        if v[0] == v[1] || v[1] == v[2] || v[2] == v[0] {
            continue;
        }
        for k in 0..3 {
            *edges.entry((v[k], v[(k + 1) % 3])).or_insert(0) += 1;
        }
        let [a, b, c] = [tri[0], tri[1], tri[2]].map(|i| positions[i as usize].as_dvec3());
        volume6 += a.dot(b.cross(c));
    }
    let manifold = edges
        .iter()
        .all(|(&(i, j), &n)| n == 1 && edges.get(&(j, i)) == Some(&1));
    manifold && volume6 > 0.0
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A unit cube, counter-clockwise seen from outside, each face with its own 4 vertices
    /// (as a UV-mapped mesh has).
    fn cube() -> (Vec<Vec3>, Vec<u32>) {
        let faces: [[Vec3; 4]; 6] = [
            // +z, -z, +x, -x, +y, -y; corners counter-clockwise seen from outside.
            [
                Vec3::new(0., 0., 1.),
                Vec3::new(1., 0., 1.),
                Vec3::new(1., 1., 1.),
                Vec3::new(0., 1., 1.),
            ],
            [
                Vec3::new(0., 0., 0.),
                Vec3::new(0., 1., 0.),
                Vec3::new(1., 1., 0.),
                Vec3::new(1., 0., 0.),
            ],
            [
                Vec3::new(1., 0., 0.),
                Vec3::new(1., 1., 0.),
                Vec3::new(1., 1., 1.),
                Vec3::new(1., 0., 1.),
            ],
            [
                Vec3::new(0., 0., 0.),
                Vec3::new(0., 0., 1.),
                Vec3::new(0., 1., 1.),
                Vec3::new(0., 1., 0.),
            ],
            [
                Vec3::new(0., 1., 0.),
                Vec3::new(0., 1., 1.),
                Vec3::new(1., 1., 1.),
                Vec3::new(1., 1., 0.),
            ],
            [
                Vec3::new(0., 0., 0.),
                Vec3::new(1., 0., 0.),
                Vec3::new(1., 0., 1.),
                Vec3::new(0., 0., 1.),
            ],
        ];
        let mut p = Vec::new();
        let mut idx = Vec::new();
        for f in faces {
            let b = p.len() as u32;
            p.extend_from_slice(&f);
            idx.extend_from_slice(&[b, b + 1, b + 2, b, b + 2, b + 3]);
        }
        (p, idx)
    }

    /// A latitude-longitude sphere as generators build it: a grid whose seam column repeats
    /// the first (with sin/cos rounding) and whose pole rows collapse to points.
    fn uv_sphere(rows: usize, cols: usize) -> (Vec<Vec3>, Vec<u32>) {
        let mut p = Vec::new();
        for r in 0..=rows {
            let t = std::f32::consts::PI * r as f32 / rows as f32;
            for c in 0..=cols {
                let f = std::f32::consts::TAU * c as f32 / cols as f32;
                p.push(Vec3::new(t.sin() * f.sin(), t.cos(), t.sin() * f.cos()));
            }
        }
        let mut idx = Vec::new();
        let at = |r: usize, c: usize| (r * (cols + 1) + c) as u32;
        for r in 0..rows {
            for c in 0..cols {
                // Counter-clockwise seen from outside.
                idx.extend_from_slice(&[at(r, c), at(r + 1, c), at(r + 1, c + 1)]);
                idx.extend_from_slice(&[at(r, c), at(r + 1, c + 1), at(r, c + 1)]);
            }
        }
        (p, idx)
    }

    #[test]
    fn uv_sphere_with_seam_and_poles_is_closed() {
        let (p, idx) = uv_sphere(12, 24);
        assert!(closed_and_outward(&p, &idx));
    }

    #[test]
    fn cube_is_closed_and_outward_and_variants_are_not() {
        let (p, idx) = cube();
        assert!(closed_and_outward(&p, &idx));
        // Inside out.
        let flipped: Vec<u32> = idx.chunks(3).flat_map(|t| [t[0], t[2], t[1]]).collect();
        assert!(!closed_and_outward(&p, &flipped));
        // One face missing: open.
        assert!(!closed_and_outward(&p, &idx[..30]));
        // One triangle flipped: not consistently oriented.
        let mut one = idx.clone();
        one.swap(1, 2);
        assert!(!closed_and_outward(&p, &one));
        assert!(!closed_and_outward(&p, &[]));
        // Welding: every vertex duplicated (a seam everywhere) is still closed.
        let dup: Vec<Vec3> = p.iter().chain(p.iter()).copied().collect();
        let n = p.len() as u32;
        let mixed: Vec<u32> = idx
            .iter()
            .enumerate()
            .map(|(k, &i)| if k % 2 == 0 { i } else { i + n })
            .collect();
        assert!(closed_and_outward(&dup, &mixed));
        assert!(!closed_and_outward(&p, &[0, 1, 99]));
    }
}
