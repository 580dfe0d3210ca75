//! Animation sampling (glTF 2.0 section 3.11 and appendix C).
//!
//! Times before the first key clamp to the first key; after the last, to the last key.
//! LINEAR rotations use shortest-path slerp; CUBICSPLINE uses the cubic Hermite spline with
//! tangents scaled by the key interval; rotations are normalised after interpolation.

use glam::{Mat4, Quat, Vec3};

use crate::{Interpolation, LocalTransform, Model, Property, Sampler, Trs};

/// The animated state of every node: local transforms and morph weights.
#[derive(Debug, Clone)]
pub struct Pose {
    pub local: Vec<LocalTransform>,
    pub morph_weights: Vec<Vec<f32>>,
}

impl Pose {
    /// The rest pose (no animation applied).
    pub fn rest(model: &Model) -> Self {
        Self {
            local: model.nodes.iter().map(|n| n.local).collect(),
            morph_weights: model
                .nodes
                .iter()
                .map(|n| n.morph_weights.clone())
                .collect(),
        }
    }

    /// `world_from_node` for every node.
    pub fn world_from_node(&self, model: &Model) -> Vec<Mat4> {
        let mut world: Vec<Option<Mat4>> = vec![None; model.nodes.len()];
        for i in 0..model.nodes.len() {
            resolve_world(i, model, &self.local, &mut world);
        }
        world
            .into_iter()
            .map(|m| m.unwrap_or(Mat4::IDENTITY))
            .collect()
    }
}

/// Iterative (no recursion: deep hierarchies must not overflow the stack).
fn resolve_world(node: usize, model: &Model, local: &[LocalTransform], world: &mut [Option<Mat4>]) {
    if world[node].is_some() {
        return;
    }
    let mut chain = vec![node];
    let mut at = node;
    while let Some(p) = model.nodes[at].parent {
        if world[p].is_some() {
            break;
        }
        chain.push(p);
        at = p;
    }
    for &n in chain.iter().rev() {
        let parent = model.nodes[n]
            .parent
            .and_then(|p| world[p])
            .unwrap_or(Mat4::IDENTITY);
        world[n] = Some(parent * local[n].matrix());
    }
}

/// Samples animation `animation` at `time_s` into a pose (nodes it does not animate keep their
/// rest transform).
pub fn sample(model: &Model, animation: usize, time_s: f32) -> Pose {
    let mut pose = Pose::rest(model);
    let Some(anim) = model.animations.get(animation) else {
        return pose;
    };
    for ch in &anim.channels {
        let v = sample_sampler(&ch.sampler, ch.property, time_s);
        match ch.property {
            Property::MorphWeights => {
                let w = &mut pose.morph_weights[ch.node];
                w.clear();
                w.extend_from_slice(&v);
            }
            p => {
                let mut trs = match pose.local[ch.node] {
                    LocalTransform::Trs(t) => t,
                    LocalTransform::Matrix(m) => {
                        let (scale, rotation, translation) = m.to_scale_rotation_translation();
                        Trs {
                            translation,
                            rotation,
                            scale,
                        }
                    }
                };
                match p {
                    Property::Translation => trs.translation = Vec3::new(v[0], v[1], v[2]),
                    Property::Scale => trs.scale = Vec3::new(v[0], v[1], v[2]),
                    Property::Rotation => {
                        trs.rotation = Quat::from_xyzw(v[0], v[1], v[2], v[3]).normalize()
                    }
                    Property::MorphWeights => {}
                }
                pose.local[ch.node] = LocalTransform::Trs(trs);
            }
        }
    }
    pose
}

/// Samples one sampler at `t` (seconds), returning `components` values.
pub fn sample_sampler(s: &Sampler, property: Property, t: f32) -> Vec<f32> {
    let n = s.components;
    let keys = s.times_s.len();
    let cubic = s.interpolation == Interpolation::CubicSpline;
    // Value of key k (the middle group for CUBICSPLINE).
    let value = |k: usize| -> &[f32] {
        if cubic {
            &s.values[(3 * k + 1) * n..(3 * k + 2) * n]
        } else {
            &s.values[k * n..(k + 1) * n]
        }
    };
    if keys == 1 || t <= s.times_s[0] {
        return value(0).to_vec();
    }
    if t >= s.times_s[keys - 1] {
        return value(keys - 1).to_vec();
    }
    // The interval [k, k+1] containing t.
    let k = s.times_s.partition_point(|&x| x <= t).saturating_sub(1);
    let k = k.min(keys - 2);
    let (t0, t1) = (s.times_s[k], s.times_s[k + 1]);
    let dt = t1 - t0;
    let u = if dt > 0.0 { (t - t0) / dt } else { 0.0 };
    match s.interpolation {
        Interpolation::Step => value(k).to_vec(),
        Interpolation::Linear => {
            let (a, b) = (value(k), value(k + 1));
            if property == Property::Rotation {
                let qa = Quat::from_slice(a);
                let qb = Quat::from_slice(b);
                slerp(qa, qb, u).to_array().to_vec()
            } else {
                a.iter().zip(b).map(|(x, y)| x + (y - x) * u).collect()
            }
        }
        Interpolation::CubicSpline => {
            let v0 = value(k);
            let b0 = &s.values[(3 * k + 2) * n..(3 * k + 3) * n]; // out-tangent of k
            let a1 = &s.values[(3 * (k + 1)) * n..(3 * (k + 1) + 1) * n]; // in-tangent of k+1
            let v1 = value(k + 1);
            let (u2, u3) = (u * u, u * u * u);
            let h00 = 2.0 * u3 - 3.0 * u2 + 1.0;
            let h10 = u3 - 2.0 * u2 + u;
            let h01 = -2.0 * u3 + 3.0 * u2;
            let h11 = u3 - u2;
            let out: Vec<f32> = (0..n)
                .map(|i| h00 * v0[i] + h10 * dt * b0[i] + h01 * v1[i] + h11 * dt * a1[i])
                .collect();
            if property == Property::Rotation {
                Quat::from_slice(&out).normalize().to_array().to_vec()
            } else {
                out
            }
        }
    }
}

/// Shortest-path spherical linear interpolation of unit quaternions.
fn slerp(a: Quat, b: Quat, u: f32) -> Quat {
    let mut d = a.dot(b);
    let b = if d < 0.0 {
        d = -d;
        -b
    } else {
        b
    };
    if d > 0.9995 {
        return (a + (b - a) * u).normalize();
    }
    let theta = d.clamp(-1.0, 1.0).acos();
    let s = theta.sin();
    let wa = ((1.0 - u) * theta).sin() / s;
    let wb = (u * theta).sin() / s;
    (a * wa + b * wb).normalize()
}
