//! Animations: channels and samplers, key times and values decoded and checked.

use glam::Quat;
use gltf::accessor::Dimensions;

use super::Loader;
use crate::accessor::{expect_dims, read_f32};
use crate::{
    Animation, Channel, ErrorKind, Interpolation, LocalTransform, Node, Property, Sampler, Trs,
};

impl<'a> Loader<'a> {
    pub(super) fn load_animations(
        &mut self,
        nodes: &mut [Node],
        mesh_targets: &[usize],
    ) -> Result<Vec<Animation>, ErrorKind> {
        let mut animations = Vec::new();
        for anim in self.doc.animations() {
            let index = anim.index();
            let aerr = |message: String| ErrorKind::Animation { index, message };
            let mut channels = Vec::new();
            let mut duration_s = 0f32;
            for (ci, channel) in anim.channels().enumerate() {
                let node = channel.target().node().index();
                let property = match channel.target().property() {
                    gltf::animation::Property::Translation => Property::Translation,
                    gltf::animation::Property::Rotation => Property::Rotation,
                    gltf::animation::Property::Scale => Property::Scale,
                    gltf::animation::Property::MorphTargetWeights => Property::MorphWeights,
                };
                let sampler = channel.sampler();
                let interpolation = match sampler.interpolation() {
                    gltf::animation::Interpolation::Linear => Interpolation::Linear,
                    gltf::animation::Interpolation::Step => Interpolation::Step,
                    gltf::animation::Interpolation::CubicSpline => Interpolation::CubicSpline,
                };
                let input = sampler.input();
                expect_dims(&input, &[Dimensions::Scalar], "animation input")?;
                let times_s: Vec<f32> = read_f32(&input, &self.buffers)?;
                if times_s.is_empty() {
                    return Err(aerr(format!("channel {ci} has no keyframes")));
                }
                if times_s.iter().any(|t| !t.is_finite()) {
                    return Err(aerr(format!("channel {ci} has a non-finite key time")));
                }
                if times_s.windows(2).any(|w| w[1] < w[0]) {
                    return Err(aerr(format!("channel {ci}: key times are not increasing")));
                }
                let output = sampler.output();
                let values: Vec<f32> = read_f32(&output, &self.buffers)?;
                if values.iter().any(|v| !v.is_finite()) {
                    return Err(aerr(format!("channel {ci} has a non-finite value")));
                }
                let groups = if interpolation == Interpolation::CubicSpline {
                    3
                } else {
                    1
                };
                let keys = times_s.len();
                let components = match property {
                    Property::Translation | Property::Scale => 3,
                    Property::Rotation => 4,
                    Property::MorphWeights => {
                        let targets = nodes[node]
                            .mesh
                            .and_then(|m| mesh_targets.get(m))
                            .copied()
                            .unwrap_or(0);
                        if targets == 0 {
                            return Err(aerr(format!(
                                "channel {ci} animates morph weights of node {node}, which has \
                                 no morph targets"
                            )));
                        }
                        targets
                    }
                };
                let expected = keys.saturating_mul(groups).saturating_mul(components);
                if values.len() != expected {
                    return Err(aerr(format!(
                        "channel {ci} has {} output values, expected {expected} ({keys} keys x \
                         {groups} x {components})",
                        values.len()
                    )));
                }
                let sampler = Sampler {
                    interpolation,
                    times_s,
                    values,
                    components,
                };
                if property == Property::Rotation && has_zero_rotation_key(&sampler) {
                    return Err(aerr(format!(
                        "channel {ci}: a rotation key is the zero quaternion"
                    )));
                }
                if let LocalTransform::Matrix(m) = nodes[node].local {
                    if property != Property::MorphWeights {
                        let (scale, rotation, translation) = m.to_scale_rotation_translation();
                        nodes[node].local = LocalTransform::Trs(Trs {
                            translation,
                            rotation,
                            scale,
                        });
                        self.warn(format!(
                            "animation {index} targets node {node}, which has a matrix \
                             transform; the matrix was decomposed into TRS"
                        ));
                    }
                }
                duration_s = duration_s.max(*sampler.times_s.last().unwrap_or(&0.0));
                channels.push(Channel {
                    node,
                    property,
                    sampler,
                });
            }
            animations.push(Animation {
                name: anim.name().map(str::to_string),
                channels,
                duration_s,
            });
        }
        Ok(animations)
    }
}

/// Whether a rotation keyframe value (not a CUBICSPLINE tangent) is the zero quaternion, which
/// has no rotation (the loader refuses it). Non-unit keys are kept as they are: interpolation runs on the stored values and
/// the result is normalised (the conformance reference and three.js agree on that order).
fn has_zero_rotation_key(s: &Sampler) -> bool {
    let stride = if s.interpolation == Interpolation::CubicSpline {
        12
    } else {
        4
    };
    let offset = if s.interpolation == Interpolation::CubicSpline {
        4
    } else {
        0
    };
    for key in s.values.chunks_exact(stride) {
        let v = &key[offset..offset + 4];
        if Quat::from_xyzw(v[0], v[1], v[2], v[3]).length() < 1e-6 {
            return true;
        }
    }
    false
}
