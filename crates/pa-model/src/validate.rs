//! Checks on the raw glTF JSON before the `gltf` crate sees it.
//!
//! The `gltf` crate's wrappers (`Primitive::get`, `Channel::target`, `Image::source`, ...)
//! index and unwrap whatever the JSON says, trusting its own validation, which misses some
//! cases (a POSITION accessor index out of range panics inside that validation itself; the
//! channels of an animation are not validated at all; an image with a buffer view but no MIME
//! type, or with neither a URI nor a buffer view, is not caught). So every index and every
//! enumerated value is checked here first, with one error naming where it is and what it
//! names. Work is linear in the size of the JSON.

use gltf::json::validation::Checked;
use gltf::json::{self, Root};

use crate::accessor::MAX_VIEWLESS_ELEMENTS;
use crate::ErrorKind;

/// Checks every index (and every enumerated value the `gltf` crate unwraps) in `root`.
pub(crate) fn check_document(root: &Root) -> Result<(), ErrorKind> {
    let c = Counts::of(root);
    if let Some(scene) = root.scene {
        c.check(
            || "the document".into(),
            "scene",
            "scene",
            scene.value(),
            c.scenes,
        )?;
    }
    for (i, view) in root.buffer_views.iter().enumerate() {
        let at = || format!("buffer view {i}");
        c.check(at, "buffer", "buffer", view.buffer.value(), c.buffers)?;
        if let Some(Checked::Invalid) = view.target {
            return Err(invalid(at(), "target is not 34962 or 34963"));
        }
    }
    for (i, acc) in root.accessors.iter().enumerate() {
        let at = || format!("accessor {i}");
        if let Some(v) = acc.buffer_view {
            c.check(at, "bufferView", "buffer view", v.value(), c.views)?;
        }
        if matches!(acc.component_type, Checked::Invalid) {
            return Err(invalid(at(), "componentType is not a glTF component type"));
        }
        if matches!(acc.type_, Checked::Invalid) {
            return Err(invalid(
                at(),
                "type is not SCALAR, VEC2, VEC3, VEC4, MAT2, MAT3 or MAT4",
            ));
        }
        if let Some(sparse) = &acc.sparse {
            let v = sparse.indices.buffer_view.value();
            c.check(at, "sparse.indices.bufferView", "buffer view", v, c.views)?;
            let v = sparse.values.buffer_view.value();
            c.check(at, "sparse.values.bufferView", "buffer view", v, c.views)?;
            match sparse.indices.component_type {
                Checked::Valid(json::accessor::IndexComponentType(
                    json::accessor::ComponentType::U8
                    | json::accessor::ComponentType::U16
                    | json::accessor::ComponentType::U32,
                )) => {}
                _ => {
                    return Err(invalid(
                        at(),
                        "sparse.indices.componentType must be unsigned byte, short or int",
                    ))
                }
            }
        } else if acc.buffer_view.is_none() {
            return Err(invalid(at(), "has neither a bufferView nor sparse values"));
        }
        let count = acc.count.0;
        if acc.buffer_view.is_none() && count > MAX_VIEWLESS_ELEMENTS as u64 {
            return Err(ErrorKind::Accessor {
                index: i,
                message: format!(
                    "count {count} without a buffer view is absurd (limit \
                     {MAX_VIEWLESS_ELEMENTS})"
                ),
            });
        }
    }
    for (i, image) in root.images.iter().enumerate() {
        let at = || format!("image {i}");
        match (&image.buffer_view, &image.uri) {
            (Some(v), _) => {
                c.check(at, "bufferView", "buffer view", v.value(), c.views)?;
                if image.mime_type.is_none() {
                    return Err(invalid(at(), "has a bufferView but no mimeType"));
                }
            }
            (None, Some(_)) => {}
            (None, None) => return Err(invalid(at(), "has neither a uri nor a bufferView")),
        }
    }
    for (i, sampler) in root.samplers.iter().enumerate() {
        let at = || format!("sampler {i}");
        let bad_filter = matches!(sampler.mag_filter, Some(Checked::Invalid))
            || matches!(sampler.min_filter, Some(Checked::Invalid));
        if bad_filter
            || matches!(sampler.wrap_s, Checked::Invalid)
            || matches!(sampler.wrap_t, Checked::Invalid)
        {
            return Err(invalid(at(), "has an unknown filter or wrapping mode"));
        }
    }
    for (i, texture) in root.textures.iter().enumerate() {
        let at = || format!("texture {i}");
        c.check(at, "source", "image", texture.source.value(), c.images)?;
        if let Some(s) = texture.sampler {
            c.check(at, "sampler", "sampler", s.value(), c.samplers)?;
        }
    }
    for (i, m) in root.materials.iter().enumerate() {
        let at = || format!("material {i}");
        let pbr = &m.pbr_metallic_roughness;
        let infos = [
            (
                "pbrMetallicRoughness.baseColorTexture.index",
                pbr.base_color_texture.as_ref().map(|t| t.index.value()),
            ),
            (
                "pbrMetallicRoughness.metallicRoughnessTexture.index",
                pbr.metallic_roughness_texture
                    .as_ref()
                    .map(|t| t.index.value()),
            ),
            (
                "normalTexture.index",
                m.normal_texture.as_ref().map(|t| t.index.value()),
            ),
            (
                "occlusionTexture.index",
                m.occlusion_texture.as_ref().map(|t| t.index.value()),
            ),
            (
                "emissiveTexture.index",
                m.emissive_texture.as_ref().map(|t| t.index.value()),
            ),
        ];
        for (field, index) in infos {
            if let Some(t) = index {
                c.check(at, field, "texture", t, c.textures)?;
            }
        }
        if matches!(m.alpha_mode, Checked::Invalid) {
            return Err(invalid(at(), "alphaMode is not OPAQUE, MASK or BLEND"));
        }
    }
    for (mi, mesh) in root.meshes.iter().enumerate() {
        for (pi, prim) in mesh.primitives.iter().enumerate() {
            let at = || format!("mesh {mi} primitive {pi}");
            for (semantic, acc) in &prim.attributes {
                let field = match semantic {
                    Checked::Valid(s) => format!("attributes.{}", s.to_string()),
                    Checked::Invalid => {
                        return Err(invalid(at(), "has an attribute with an unknown name"))
                    }
                };
                c.check(at, &field, "accessor", acc.value(), c.accessors)?;
            }
            if let Some(acc) = prim.indices {
                c.check(at, "indices", "accessor", acc.value(), c.accessors)?;
            }
            if let Some(m) = prim.material {
                c.check(at, "material", "material", m.value(), c.materials)?;
            }
            if matches!(prim.mode, Checked::Invalid) {
                return Err(invalid(at(), "mode is not a glTF primitive mode (0 to 6)"));
            }
            for (ti, target) in prim.targets.iter().flatten().enumerate() {
                let fields = [
                    ("POSITION", target.positions),
                    ("NORMAL", target.normals),
                    ("TANGENT", target.tangents),
                ];
                for (name, acc) in fields {
                    if let Some(acc) = acc {
                        let field = format!("targets[{ti}].{name}");
                        c.check(at, &field, "accessor", acc.value(), c.accessors)?;
                    }
                }
            }
        }
    }
    for (i, skin) in root.skins.iter().enumerate() {
        let at = || format!("skin {i}");
        if let Some(acc) = skin.inverse_bind_matrices {
            c.check(
                at,
                "inverseBindMatrices",
                "accessor",
                acc.value(),
                c.accessors,
            )?;
        }
        for (k, j) in skin.joints.iter().enumerate() {
            c.check(at, &format!("joints[{k}]"), "node", j.value(), c.nodes)?;
        }
        if let Some(s) = skin.skeleton {
            c.check(at, "skeleton", "node", s.value(), c.nodes)?;
        }
    }
    for (i, node) in root.nodes.iter().enumerate() {
        let at = || format!("node {i}");
        if let Some(m) = node.mesh {
            c.check(at, "mesh", "mesh", m.value(), c.meshes)?;
        }
        if let Some(s) = node.skin {
            c.check(at, "skin", "skin", s.value(), c.skins)?;
        }
        if let Some(cam) = node.camera {
            c.check(at, "camera", "camera", cam.value(), c.cameras)?;
        }
        for (k, child) in node.children.iter().flatten().enumerate() {
            c.check(
                at,
                &format!("children[{k}]"),
                "node",
                child.value(),
                c.nodes,
            )?;
        }
    }
    for (i, scene) in root.scenes.iter().enumerate() {
        let at = || format!("scene {i}");
        for (k, n) in scene.nodes.iter().enumerate() {
            c.check(at, &format!("nodes[{k}]"), "node", n.value(), c.nodes)?;
        }
    }
    for (i, anim) in root.animations.iter().enumerate() {
        for (si, sampler) in anim.samplers.iter().enumerate() {
            let at = || format!("animation {i} sampler {si}");
            c.check(at, "input", "accessor", sampler.input.value(), c.accessors)?;
            c.check(
                at,
                "output",
                "accessor",
                sampler.output.value(),
                c.accessors,
            )?;
            if matches!(sampler.interpolation, Checked::Invalid) {
                return Err(invalid(
                    at(),
                    "interpolation is not LINEAR, STEP or CUBICSPLINE",
                ));
            }
        }
        for (ci, channel) in anim.channels.iter().enumerate() {
            let at = || format!("animation {i} channel {ci}");
            let samplers = anim.samplers.len();
            c.check(
                at,
                "sampler",
                "animation sampler",
                channel.sampler.value(),
                samplers,
            )?;
            c.check(
                at,
                "target.node",
                "node",
                channel.target.node.value(),
                c.nodes,
            )?;
            if matches!(channel.target.path, Checked::Invalid) {
                return Err(invalid(
                    at(),
                    "target.path is not translation, rotation, scale or weights",
                ));
            }
        }
    }
    Ok(())
}

fn invalid(at: String, message: &str) -> ErrorKind {
    ErrorKind::Invalid {
        at,
        message: message.into(),
    }
}

/// How many objects of each kind the document has.
struct Counts {
    accessors: usize,
    buffers: usize,
    views: usize,
    cameras: usize,
    images: usize,
    materials: usize,
    meshes: usize,
    nodes: usize,
    samplers: usize,
    scenes: usize,
    skins: usize,
    textures: usize,
}

impl Counts {
    fn of(root: &Root) -> Self {
        Self {
            accessors: root.accessors.len(),
            buffers: root.buffers.len(),
            views: root.buffer_views.len(),
            cameras: root.cameras.len(),
            images: root.images.len(),
            materials: root.materials.len(),
            meshes: root.meshes.len(),
            nodes: root.nodes.len(),
            samplers: root.samplers.len(),
            scenes: root.scenes.len(),
            skins: root.skins.len(),
            textures: root.textures.len(),
        }
    }

    /// Fails when `index` is not below `count`.
    fn check(
        &self,
        at: impl Fn() -> String,
        field: &str,
        kind: &'static str,
        index: usize,
        count: usize,
    ) -> Result<(), ErrorKind> {
        if index < count {
            Ok(())
        } else {
            Err(ErrorKind::Reference {
                at: at(),
                field: field.into(),
                kind,
                index,
                count,
            })
        }
    }
}
