//! Shadows of the prop on the set's plane: the soft cast shadow of each light and the contact
//! shadow (ambient occlusion) where the prop meets the table.
//!
//! The receivers are the table and the board sheet, which lie in the marker plane (z = 0, +Z
//! into the table). A plane point `p` is in a light's shadow exactly when the ray from `p`
//! toward the light meets the prop, that is when `p` lies in the prop's projection along the
//! light onto the plane. So the shadow is computed without a shadow map: every triangle of the
//! posed prop is projected along a direction onto the plane and rasterised into a binary mask
//! over a grid around the prop (0.75 mm texels), once per direction:
//!
//! - **soft cast shadow**: a light is a disc of stated angular radius (a softbox); its
//!   directions are sampled on a golden-angle spiral over the disc and the masks averaged, so
//!   a plane point's value is the fraction of the light it sees (the penumbra grows with the
//!   occluder's height as a real area light's does);
//! - **contact shadow**: the ambient term is a uniform sky; its visibility is the cosine-
//!   weighted fraction of the hemisphere whose rays leave the point without meeting the prop
//!   within [`ContactShadow::radius_m`] (ambient occlusion with a distance limit: a triangle is
//!   clipped to the heights a ray of that direction reaches within the radius before it is
//!   projected).
//!
//! Everything is deterministic (fixed sample patterns, sequential sums). The prop's shadows on
//! itself are not modelled (the prop is shaded by the renderer's unshadowed Lambertian terms).

use glam::{Vec2, Vec3};

/// A light that casts a soft shadow: a disc seen under `angular_radius_rad` around the
/// direction toward it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AreaLight {
    /// From the surface toward the light's centre, marker frame (-Z is up); need not be unit.
    pub toward_light: Vec3,
    /// Angular radius of the light's disc (0: a hard shadow from a point at infinity).
    pub angular_radius_rad: f32,
    /// Directions sampled over the disc (1 for a hard shadow).
    pub samples: u32,
}

/// The contact shadow: ambient occlusion of the plane by the prop within a distance.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContactShadow {
    /// Occluders farther than this along a ray do not count.
    pub radius_m: f32,
    /// Cosine-weighted hemisphere directions.
    pub samples: u32,
}

/// Grid texel side, metres.
pub const TEXEL_M: f32 = 0.000_75;
/// Largest grid side in texels (the texel grows when the shadows are larger than this).
const MAX_SIDE: usize = 2048;

/// Visibility of the lights and of the ambient sky over a grid on the marker plane.
#[derive(Debug, Clone)]
pub struct PlaneShadows {
    origin: Vec2,
    texel_m: f32,
    w: usize,
    h: usize,
    /// Per light: the fraction of its disc seen, row-major.
    lights: Vec<Vec<f32>>,
    /// The fraction of the (cosine-weighted) sky seen; empty when no contact shadow.
    ambient: Vec<f32>,
}

/// One projection direction: `dir` toward the light (unit, `-dir.z > 0`), the weight of its
/// mask, and the largest occluder height that counts (`INFINITY`: all).
struct Pass {
    dir: Vec3,
    weight: f32,
    max_height: f32,
}

fn light_passes(light: &AreaLight) -> Vec<Pass> {
    let l = light.toward_light.normalize_or_zero();
    let n = light.samples.max(1);
    let (u, v) = l.any_orthonormal_pair();
    let r = light.angular_radius_rad.max(0.0).tan();
    let golden = std::f32::consts::PI * (3.0 - 5f32.sqrt());
    (0..n)
        .map(|k| {
            let dir = if n == 1 {
                l
            } else {
                let rho = r * ((k as f32 + 0.5) / n as f32).sqrt();
                let t = k as f32 * golden;
                (l + rho * (t.cos() * u + t.sin() * v)).normalize()
            };
            Pass {
                dir,
                weight: 1.0 / n as f32,
                max_height: f32::INFINITY,
            }
        })
        .collect()
}

fn contact_passes(c: &ContactShadow) -> Vec<Pass> {
    let n = c.samples.max(1);
    let golden = std::f32::consts::PI * (3.0 - 5f32.sqrt());
    (0..n)
        .map(|k| {
            // Cosine-weighted: uniform over the unit disc, lifted onto the hemisphere.
            let s = (k as f32 + 0.5) / n as f32;
            let (rho, up) = (s.sqrt(), (1.0 - s).sqrt());
            let t = k as f32 * golden;
            Pass {
                dir: Vec3::new(rho * t.cos(), rho * t.sin(), -up),
                weight: 1.0 / n as f32,
                // A ray leaving at `up` reaches height `t * up` after distance t.
                max_height: c.radius_m * up,
            }
        })
        .collect()
}

/// Projects a point of height `-q.z` along `dir` onto the plane z = 0.
fn project(q: Vec3, dir: Vec3) -> Vec2 {
    let t = q.z / dir.z; // both <= 0 for points above the plane: t >= 0
    Vec2::new(q.x - t * dir.x, q.y - t * dir.y)
}

/// The part of triangle `tri` with height `-z <= max_height` (Sutherland-Hodgman, one plane).
fn clip_below(tri: &[Vec3; 3], max_height: f32, out: &mut Vec<Vec3>) {
    out.clear();
    if max_height.is_infinite() {
        out.extend_from_slice(tri);
        return;
    }
    let inside = |p: Vec3| -p.z <= max_height;
    for i in 0..3 {
        let (a, b) = (tri[i], tri[(i + 1) % 3]);
        let (ia, ib) = (inside(a), inside(b));
        if ia {
            out.push(a);
        }
        if ia != ib {
            let t = (max_height + a.z) / (a.z - b.z);
            out.push(a + (b - a) * t);
        }
    }
}

impl PlaneShadows {
    /// Computes the visibility of each light in `lights` and of the sky (`contact`) over the
    /// plane, occluded by `triangles` (marker frame; points with z > 0, under the plane, are
    /// treated as on it).
    pub fn compute(
        triangles: &[[Vec3; 3]],
        lights: &[AreaLight],
        contact: Option<&ContactShadow>,
    ) -> Self {
        let light_passes: Vec<Vec<Pass>> = lights.iter().map(light_passes).collect();
        let contact_passes = contact.map(contact_passes).unwrap_or_default();
        // The grid: every projected vertex, plus the contact radius around the footprint.
        let (mut lo, mut hi) = (Vec2::splat(f32::INFINITY), Vec2::splat(f32::NEG_INFINITY));
        for tri in triangles {
            for &q in tri {
                let q = Vec3::new(q.x, q.y, q.z.min(0.0));
                for pass in light_passes.iter().flatten() {
                    let p = project(q, pass.dir);
                    lo = lo.min(p);
                    hi = hi.max(p);
                }
                if let Some(c) = contact {
                    let r = Vec2::splat(c.radius_m);
                    lo = lo.min(q.truncate() - r);
                    hi = hi.max(q.truncate() + r);
                }
            }
        }
        if !(lo.x.is_finite() && hi.x.is_finite() && lo.y.is_finite() && hi.y.is_finite()) {
            return Self {
                origin: Vec2::ZERO,
                texel_m: TEXEL_M,
                w: 0,
                h: 0,
                lights: vec![Vec::new(); lights.len()],
                ambient: Vec::new(),
            };
        }
        let extent = hi - lo;
        let texel_m = TEXEL_M.max(extent.max_element() / (MAX_SIDE - 4) as f32);
        let origin = lo - Vec2::splat(2.0 * texel_m);
        let w = (extent.x / texel_m).ceil() as usize + 4;
        let h = (extent.y / texel_m).ceil() as usize + 4;
        let mut grid = Self {
            origin,
            texel_m,
            w,
            h,
            lights: Vec::new(),
            ambient: Vec::new(),
        };
        let mut mask = vec![0u8; w * h];
        let mut clipped = Vec::with_capacity(4);
        let mut occlusion = |passes: &[Pass]| -> Vec<f32> {
            let mut acc = vec![0f32; w * h];
            for pass in passes {
                mask.fill(0);
                for tri in triangles {
                    let tri = tri.map(|q| Vec3::new(q.x, q.y, q.z.min(0.0)));
                    clip_below(&tri, pass.max_height, &mut clipped);
                    if clipped.len() < 3 {
                        continue;
                    }
                    let texel = |q: Vec3| (project(q, pass.dir) - origin) / texel_m - 0.5;
                    let a = texel(clipped[0]);
                    for k in 1..clipped.len() - 1 {
                        fill_triangle(
                            &mut mask,
                            w,
                            h,
                            [a, texel(clipped[k]), texel(clipped[k + 1])],
                        );
                    }
                }
                for (o, &m) in acc.iter_mut().zip(&mask) {
                    if m != 0 {
                        *o += pass.weight;
                    }
                }
            }
            acc.iter().map(|o| (1.0 - o).clamp(0.0, 1.0)).collect()
        };
        grid.lights = light_passes.iter().map(|p| occlusion(p)).collect();
        if contact.is_some() {
            grid.ambient = occlusion(&contact_passes);
        }
        grid
    }

    /// Bilinear look-up of `values` at plane point `p`; 1 (fully visible) off the grid.
    fn sample(&self, values: &[f32], p: Vec2) -> f32 {
        if values.is_empty() {
            return 1.0;
        }
        let t = (p - self.origin) / self.texel_m - 0.5;
        let (x0, y0) = (t.x.floor(), t.y.floor());
        let (fx, fy) = (t.x - x0, t.y - y0);
        let at = |x: f32, y: f32| -> f32 {
            if x < 0.0 || y < 0.0 || x >= self.w as f32 || y >= self.h as f32 {
                1.0
            } else {
                values[y as usize * self.w + x as usize]
            }
        };
        let top = at(x0, y0) * (1.0 - fx) + at(x0 + 1.0, y0) * fx;
        let bottom = at(x0, y0 + 1.0) * (1.0 - fx) + at(x0 + 1.0, y0 + 1.0) * fx;
        top * (1.0 - fy) + bottom * fy
    }

    /// The fraction of light `k`'s disc seen from plane point `p` (1 without that light).
    pub fn light_visibility(&self, k: usize, p: Vec2) -> f32 {
        self.lights.get(k).map_or(1.0, |v| self.sample(v, p))
    }

    /// The fraction of the sky seen from plane point `p` (1 without a contact shadow).
    pub fn ambient_visibility(&self, p: Vec2) -> f32 {
        self.sample(&self.ambient, p)
    }
}

/// Sets the texels whose centres lie in triangle `t` (texel coordinates: texel (i, j) has its
/// centre at (i, j)); edges inclusive, so triangles sharing an edge leave no gap.
fn fill_triangle(mask: &mut [u8], w: usize, h: usize, t: [Vec2; 3]) {
    let area = (t[1] - t[0]).perp_dot(t[2] - t[0]);
    if area.abs() < 1e-12 {
        return;
    }
    let s = area.signum();
    let lo = t[0].min(t[1]).min(t[2]).ceil().max(Vec2::ZERO);
    let hi = t[0].max(t[1]).max(t[2]).floor();
    let x1 = (hi.x as i64).min(w as i64 - 1);
    let y1 = (hi.y as i64).min(h as i64 - 1);
    let (x0, y0) = (lo.x as i64, lo.y as i64);
    for y in y0..=y1 {
        for x in x0..=x1 {
            let p = Vec2::new(x as f32, y as f32);
            let inside = (0..3).all(|i| {
                let (a, b) = (t[i], t[(i + 1) % 3]);
                s * (b - a).perp_dot(p - a) >= 0.0
            });
            if inside {
                mask[y as usize * w + x as usize] = 1;
            }
        }
    }
}

#[cfg(test)]
#[path = "shadow_tests.rs"]
mod tests;
