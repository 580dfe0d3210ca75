//! Loading glTF 2.0 files into [`Model`], with every reference checked.

use std::path::{Component, Path, PathBuf};

use base64::Engine as _;
use glam::{Mat4, Quat, Vec3};
use gltf::accessor::{DataType, Dimensions};
use gltf::mesh::{Mode, Semantic};

use crate::accessor::{expect_dims, read_f64, read_u32, read_vec3};
use crate::{
    Animation, Channel, ErrorKind, Image, Interpolation, LocalTransform, Material, Mesh, Model,
    ModelError, MorphTarget, Node, Primitive, Property, Sampler, Skin, Trs,
};

/// Resource limits for loading (bounded allocation against absurd or hostile files).
#[derive(Debug, Clone, Copy)]
pub struct Limits {
    /// Largest model file, external buffer or external image read from disk.
    pub max_file_bytes: u64,
    /// Largest width or height of a decoded image.
    pub max_image_side: u32,
    /// Largest total allocation for decoded images.
    pub max_image_bytes: u64,
}

impl Default for Limits {
    fn default() -> Self {
        Self {
            max_file_bytes: 2 << 30,
            max_image_side: 16_384,
            max_image_bytes: 1 << 30,
        }
    }
}

/// Options for [`Model::load_with`].
#[derive(Debug, Clone, Copy, Default)]
pub struct LoadOptions {
    pub limits: Limits,
    /// Skip decoding images (faster `inspect` and skinning-only use).
    pub skip_images: bool,
}

/// Weight sums further than this from 1 are reported (they are always renormalised).
const WEIGHT_SUM_WARN: f32 = 1e-3;

pub(crate) fn load(path: PathBuf, options: &LoadOptions) -> Result<Model, ModelError> {
    let bytes = read_bounded(&path, options.limits.max_file_bytes)
        .map_err(|kind| ModelError::new(&path, kind))?;
    let base_dir = path
        .parent()
        .map(Path::to_path_buf)
        .unwrap_or_else(|| PathBuf::from("."));
    from_slice(&bytes, path, Some(&base_dir), options)
}

fn read_bounded(path: &Path, limit: u64) -> Result<Vec<u8>, ErrorKind> {
    let meta = std::fs::metadata(path)?;
    if meta.len() > limit {
        return Err(ErrorKind::TooLarge {
            what: format!("file {}", path.display()),
            size: meta.len(),
            limit,
        });
    }
    Ok(std::fs::read(path)?)
}

pub(crate) fn from_slice(
    bytes: &[u8],
    path: PathBuf,
    base_dir: Option<&Path>,
    options: &LoadOptions,
) -> Result<Model, ModelError> {
    let gltf = gltf::Gltf::from_slice(bytes)
        .map_err(|e| ModelError::new(&path, ErrorKind::Parse(e.to_string())))?;
    let mut loader = Loader {
        doc: &gltf.document,
        options,
        base_dir,
        buffers: Vec::new(),
        warnings: Vec::new(),
    };
    let result = loader.run(gltf.blob.as_deref());
    let (nodes, roots, meshes, skins, materials, images, animations) =
        result.map_err(|kind| ModelError::new(&path, kind))?;
    Ok(Model {
        path,
        nodes,
        roots,
        meshes,
        skins,
        materials,
        images,
        animations,
        warnings: loader.warnings,
    })
}

type Parts = (
    Vec<Node>,
    Vec<usize>,
    Vec<Mesh>,
    Vec<Skin>,
    Vec<Material>,
    Vec<Image>,
    Vec<Animation>,
);

struct Loader<'a> {
    doc: &'a gltf::Document,
    options: &'a LoadOptions,
    base_dir: Option<&'a Path>,
    buffers: Vec<Vec<u8>>,
    warnings: Vec<String>,
}

impl Loader<'_> {
    fn run(&mut self, blob: Option<&[u8]>) -> Result<Parts, ErrorKind> {
        if let Some(ext) = self.doc.extensions_required().next() {
            return Err(ErrorKind::Parse(format!(
                "requires extension {ext:?}, which Props Alive does not support"
            )));
        }
        self.load_buffers(blob)?;
        let images = self.load_images()?;
        let materials = self.load_materials(&images);
        let meshes = self.load_meshes()?;
        let skins = self.load_skins()?;
        let mut nodes = self.load_nodes()?;
        check_skinned_nodes(&nodes, &meshes, &skins)?;
        let animations = self.load_animations(&mut nodes, &meshes)?;
        let roots = self.roots(&nodes);
        Ok((nodes, roots, meshes, skins, materials, images, animations))
    }

    fn warn(&mut self, message: String) {
        log::warn!("{message}");
        self.warnings.push(message);
    }

    fn load_buffers(&mut self, blob: Option<&[u8]>) -> Result<(), ErrorKind> {
        for buffer in self.doc.buffers() {
            let index = buffer.index();
            let declared = buffer.length();
            let data = match buffer.source() {
                gltf::buffer::Source::Bin => blob
                    .ok_or_else(|| ErrorKind::Buffer {
                        index,
                        message: "refers to the GLB binary chunk, which is missing".into(),
                    })?
                    .to_vec(),
                gltf::buffer::Source::Uri(uri) => self
                    .read_uri(uri)
                    .map_err(|message| ErrorKind::Buffer { index, message })?,
            };
            if data.len() < declared {
                return Err(ErrorKind::Buffer {
                    index,
                    message: format!(
                        "declares {declared} bytes but only {} are present: truncated or \
                         corrupt buffer",
                        data.len()
                    ),
                });
            }
            let mut data = data;
            data.truncate(declared);
            self.buffers.push(data);
        }
        Ok(())
    }

    /// Reads a data URI or a file relative to the model's folder. Errors are messages that
    /// name the URI.
    fn read_uri(&self, uri: &str) -> Result<Vec<u8>, String> {
        if let Some(rest) = uri.strip_prefix("data:") {
            let (header, payload) = rest
                .split_once(',')
                .ok_or_else(|| format!("data URI {:?} has no ',' separator", short(uri)))?;
            if !header.ends_with(";base64") {
                return Err(format!("data URI {:?} is not base64-encoded", short(uri)));
            }
            let limit = self.options.limits.max_file_bytes;
            if payload.len() as u64 / 4 * 3 > limit {
                return Err(format!("data URI decodes to more than {limit} bytes"));
            }
            return base64::engine::general_purpose::STANDARD
                .decode(payload.trim())
                .map_err(|e| format!("data URI {:?} is not valid base64: {e}", short(uri)));
        }
        let path = self.resolve_relative(uri)?;
        read_bounded(&path, self.options.limits.max_file_bytes)
            .map_err(|e| format!("cannot read {uri:?} ({}): {e}", path.display()))
    }

    /// Resolves a relative URI inside the model's folder, refusing anything that escapes it.
    fn resolve_relative(&self, uri: &str) -> Result<PathBuf, String> {
        let escapes = || ErrorKind::UriEscapes { uri: uri.into() }.to_string();
        if uri.contains("://") || uri.starts_with("file:") {
            return Err(ErrorKind::UnsupportedUri {
                uri: uri.into(),
                reason: "only relative paths and data: URIs are read".into(),
            }
            .to_string());
        }
        let decoded = percent_decode(uri).ok_or_else(|| {
            ErrorKind::UnsupportedUri {
                uri: uri.into(),
                reason: "bad percent-encoding".into(),
            }
            .to_string()
        })?;
        if decoded.contains('\0') {
            return Err(escapes());
        }
        let normalised = decoded.replace('\\', "/");
        let rel = Path::new(&normalised);
        let looks_windows_absolute = normalised.len() >= 2 && normalised.as_bytes()[1] == b':';
        if rel.is_absolute() || looks_windows_absolute {
            return Err(escapes());
        }
        for c in rel.components() {
            match c {
                Component::Normal(_) | Component::CurDir => {}
                _ => return Err(escapes()),
            }
        }
        let base = self.base_dir.ok_or_else(|| {
            ErrorKind::UnsupportedUri {
                uri: uri.into(),
                reason: "a model loaded from memory cannot refer to external files".into(),
            }
            .to_string()
        })?;
        let joined = base.join(rel);
        // Symbolic links must not lead out of the folder either.
        if let (Ok(base_c), Ok(file_c)) = (base.canonicalize(), joined.canonicalize()) {
            if !file_c.starts_with(&base_c) {
                return Err(escapes());
            }
        }
        Ok(joined)
    }

    fn load_images(&mut self) -> Result<Vec<Image>, ErrorKind> {
        let mut images = Vec::new();
        let mut total: u64 = 0;
        for image in self.doc.images() {
            let index = image.index();
            let name = image.name().map(str::to_string);
            if self.options.skip_images {
                images.push(Image {
                    name,
                    width: 0,
                    height: 0,
                    rgba8: Vec::new(),
                });
                continue;
            }
            let image_err = |message: String| ErrorKind::Image { index, message };
            let encoded: Vec<u8> = match image.source() {
                gltf::image::Source::View { view, .. } => {
                    let buffer = self
                        .buffers
                        .get(view.buffer().index())
                        .ok_or_else(|| image_err("buffer view names a missing buffer".into()))?;
                    let start = view.offset();
                    let end = start.saturating_add(view.length());
                    buffer
                        .get(start..end)
                        .ok_or_else(|| {
                            image_err(format!(
                                "buffer view {} is outside its buffer: truncated or corrupt",
                                view.index()
                            ))
                        })?
                        .to_vec()
                }
                gltf::image::Source::Uri { uri, .. } => self.read_uri(uri).map_err(image_err)?,
            };
            let lim = &self.options.limits;
            let reader = image::ImageReader::new(std::io::Cursor::new(&encoded))
                .with_guessed_format()
                .map_err(|e| image_err(format!("cannot read: {e}")))?;
            let (w, h) = reader
                .into_dimensions()
                .map_err(|e| image_err(format!("cannot decode: {e}")))?;
            if w > lim.max_image_side || h > lim.max_image_side {
                return Err(image_err(format!(
                    "{w}x{h} is larger than the limit of {} px a side",
                    lim.max_image_side
                )));
            }
            total += w as u64 * h as u64 * 4;
            if total > lim.max_image_bytes {
                return Err(ErrorKind::TooLarge {
                    what: "decoded images".into(),
                    size: total,
                    limit: lim.max_image_bytes,
                });
            }
            let mut reader = image::ImageReader::new(std::io::Cursor::new(&encoded))
                .with_guessed_format()
                .map_err(|e| image_err(format!("cannot read: {e}")))?;
            let mut limits = image::Limits::default();
            limits.max_image_width = Some(lim.max_image_side);
            limits.max_image_height = Some(lim.max_image_side);
            limits.max_alloc = Some(lim.max_image_bytes);
            reader.limits(limits);
            let decoded = reader
                .decode()
                .map_err(|e| image_err(format!("cannot decode: {e}")))?
                .to_rgba8();
            images.push(Image {
                name,
                width: decoded.width(),
                height: decoded.height(),
                rgba8: decoded.into_raw(),
            });
        }
        Ok(images)
    }

    fn load_materials(&self, images: &[Image]) -> Vec<Material> {
        self.doc
            .materials()
            .map(|m| {
                let pbr = m.pbr_metallic_roughness();
                let base_color_image = pbr
                    .base_color_texture()
                    .map(|info| info.texture().source().index())
                    .filter(|&i| i < images.len());
                Material {
                    name: m.name().map(str::to_string),
                    base_color_factor: pbr.base_color_factor(),
                    base_color_image,
                    double_sided: m.double_sided(),
                }
            })
            .collect()
    }

    fn load_meshes(&mut self) -> Result<Vec<Mesh>, ErrorKind> {
        let mut meshes = Vec::new();
        for mesh in self.doc.meshes() {
            let mut primitives = Vec::new();
            for prim in mesh.primitives() {
                primitives.push(self.load_primitive(mesh.index(), &prim)?);
            }
            meshes.push(Mesh {
                name: mesh.name().map(str::to_string),
                primitives,
            });
        }
        Ok(meshes)
    }

    fn load_primitive(
        &mut self,
        mesh: usize,
        prim: &gltf::Primitive<'_>,
    ) -> Result<Primitive, ErrorKind> {
        let primitive = prim.index();
        let perr = |message: String| ErrorKind::Primitive {
            mesh,
            primitive,
            message,
        };
        let pos_acc = prim
            .get(&Semantic::Positions)
            .ok_or_else(|| perr("has no POSITION attribute".into()))?;
        let positions = read_vec3(&pos_acc, &self.buffers, "POSITION")?;
        let n = positions.len();
        let check_count = |acc: &gltf::Accessor<'_>, what: &str| -> Result<(), ErrorKind> {
            if acc.count() != n {
                Err(ErrorKind::Primitive {
                    mesh,
                    primitive,
                    message: format!("{what} has {} elements but POSITION has {n}", acc.count()),
                })
            } else {
                Ok(())
            }
        };

        let normals = match prim.get(&Semantic::Normals) {
            Some(acc) => {
                check_count(&acc, "NORMAL")?;
                read_vec3(&acc, &self.buffers, "NORMAL")?
            }
            None => Vec::new(),
        };
        let uvs = match prim.get(&Semantic::TexCoords(0)) {
            Some(acc) => {
                check_count(&acc, "TEXCOORD_0")?;
                expect_dims(&acc, &[Dimensions::Vec2], "TEXCOORD_0")?;
                read_f64(&acc, &self.buffers)?
                    .chunks_exact(2)
                    .map(|c| [c[0] as f32, c[1] as f32])
                    .collect()
            }
            None => Vec::new(),
        };

        let (joints, weights) = self.load_influences(mesh, primitive, prim, n)?;

        let mut indices = match prim.indices() {
            Some(acc) => {
                expect_dims(&acc, &[Dimensions::Scalar], "indices")?;
                read_u32(&acc, &self.buffers)?
            }
            None => (0..n as u32).collect(),
        };
        if let Some((k, &bad)) = indices.iter().enumerate().find(|(_, &i)| i as usize >= n) {
            return Err(perr(format!("index {k} is {bad}, past the {n} vertices")));
        }
        indices = match prim.mode() {
            Mode::Triangles => {
                let whole = indices.len() / 3 * 3;
                indices.truncate(whole);
                indices
            }
            Mode::TriangleStrip => (2..indices.len())
                .flat_map(|i| {
                    if i % 2 == 0 {
                        [indices[i - 2], indices[i - 1], indices[i]]
                    } else {
                        [indices[i - 1], indices[i - 2], indices[i]]
                    }
                })
                .collect(),
            Mode::TriangleFan => (2..indices.len())
                .flat_map(|i| [indices[0], indices[i - 1], indices[i]])
                .collect(),
            other => {
                self.warn(format!(
                    "mesh {mesh} primitive {primitive}: mode {other:?} has no triangles; it is \
                     kept for skinning but not drawn"
                ));
                Vec::new()
            }
        };

        let mut morph_targets = Vec::new();
        for target in prim.morph_targets() {
            let position_deltas = match target.positions() {
                Some(acc) => {
                    check_count(&acc, "morph target POSITION")?;
                    read_vec3(&acc, &self.buffers, "morph target POSITION")?
                }
                None => vec![Vec3::ZERO; n],
            };
            let normal_deltas = match target.normals() {
                Some(acc) => {
                    check_count(&acc, "morph target NORMAL")?;
                    read_vec3(&acc, &self.buffers, "morph target NORMAL")?
                }
                None => Vec::new(),
            };
            morph_targets.push(MorphTarget {
                position_deltas,
                normal_deltas,
            });
        }

        Ok(Primitive {
            positions,
            normals,
            uvs,
            joints,
            weights,
            indices,
            material: prim.material().index(),
            morph_targets,
        })
    }

    /// JOINTS_0/1 and WEIGHTS_0/1: up to 8 influences, validated and normalised.
    #[allow(clippy::type_complexity)]
    fn load_influences(
        &mut self,
        mesh: usize,
        primitive: usize,
        prim: &gltf::Primitive<'_>,
        n: usize,
    ) -> Result<(Vec<[u16; 8]>, Vec<[f32; 8]>), ErrorKind> {
        let mut joints = Vec::new();
        let mut weights = Vec::new();
        for set in 0..2u32 {
            let (j, w) = (
                prim.get(&Semantic::Joints(set)),
                prim.get(&Semantic::Weights(set)),
            );
            let (j, w) = match (j, w) {
                (None, None) => break,
                (Some(j), Some(w)) => (j, w),
                _ => {
                    return Err(ErrorKind::Primitive {
                        mesh,
                        primitive,
                        message: format!("JOINTS_{set} and WEIGHTS_{set} must come together"),
                    })
                }
            };
            for (acc, what) in [(&j, "JOINTS"), (&w, "WEIGHTS")] {
                expect_dims(acc, &[Dimensions::Vec4], what)?;
                if acc.count() != n {
                    return Err(ErrorKind::Primitive {
                        mesh,
                        primitive,
                        message: format!(
                            "{what}_{set} has {} elements but POSITION has {n}",
                            acc.count()
                        ),
                    });
                }
            }
            if !matches!(j.data_type(), DataType::U8 | DataType::U16) {
                return Err(ErrorKind::Accessor {
                    index: j.index(),
                    message: format!(
                        "JOINTS_{set} must be unsigned byte or short, found {:?}",
                        j.data_type()
                    ),
                });
            }
            let jv = read_u32(&j, &self.buffers)?;
            let wv = read_f64(&w, &self.buffers)?;
            if set == 0 {
                joints = vec![[0u16; 8]; n];
                weights = vec![[0f32; 8]; n];
            }
            let base = set as usize * 4;
            for v in 0..n {
                for k in 0..4 {
                    joints[v][base + k] = jv[v * 4 + k] as u16;
                    weights[v][base + k] = wv[v * 4 + k] as f32;
                }
            }
        }
        let mut renormalised = 0usize;
        for (v, w) in weights.iter_mut().enumerate() {
            let bad = |message: String| ErrorKind::InvalidWeights {
                mesh,
                primitive,
                vertex: v,
                message,
            };
            if let Some(x) = w.iter().find(|x| !x.is_finite()) {
                return Err(bad(format!("weight {x} is not a finite number")));
            }
            if let Some(x) = w.iter().find(|&&x| x < 0.0) {
                return Err(bad(format!("weight {x} is negative")));
            }
            let sum: f32 = w.iter().sum();
            if sum <= 1e-12 {
                return Err(bad("all weights are zero".into()));
            }
            if (sum - 1.0).abs() > WEIGHT_SUM_WARN {
                renormalised += 1;
            }
            if sum != 1.0 {
                for x in w.iter_mut() {
                    *x /= sum;
                }
            }
        }
        // Unused influence slots must not point anywhere odd: zero-weight joints are reset.
        for (j, w) in joints.iter_mut().zip(&weights) {
            for k in 0..8 {
                if w[k] == 0.0 {
                    j[k] = 0;
                }
            }
        }
        if renormalised > 0 {
            self.warn(format!(
                "mesh {mesh} primitive {primitive}: skin weights of {renormalised} vertices do \
                 not sum to 1; they were normalised"
            ));
        }
        Ok((joints, weights))
    }

    fn load_skins(&mut self) -> Result<Vec<Skin>, ErrorKind> {
        let mut skins = Vec::new();
        for skin in self.doc.skins() {
            let index = skin.index();
            let joints: Vec<usize> = skin.joints().map(|j| j.index()).collect();
            if joints.is_empty() {
                return Err(ErrorKind::Skin {
                    index,
                    message: "has no joints".into(),
                });
            }
            let inverse_bind_matrices = match skin.inverse_bind_matrices() {
                Some(acc) => {
                    expect_dims(&acc, &[Dimensions::Mat4], "inverseBindMatrices")?;
                    let v = read_f64(&acc, &self.buffers)?;
                    if acc.count() < joints.len() {
                        return Err(ErrorKind::Skin {
                            index,
                            message: format!(
                                "has {} joints but only {} inverse bind matrices",
                                joints.len(),
                                acc.count()
                            ),
                        });
                    }
                    let mats: Vec<Mat4> = v
                        .chunks_exact(16)
                        .take(joints.len())
                        .map(|c| {
                            let mut a = [0f32; 16];
                            for (d, s) in a.iter_mut().zip(c) {
                                *d = *s as f32;
                            }
                            Mat4::from_cols_array(&a)
                        })
                        .collect();
                    if mats.iter().any(|m| !m.is_finite()) {
                        return Err(ErrorKind::Skin {
                            index,
                            message: "an inverse bind matrix is not finite".into(),
                        });
                    }
                    mats
                }
                None => vec![Mat4::IDENTITY; joints.len()],
            };
            skins.push(Skin {
                name: skin.name().map(str::to_string),
                joints,
                inverse_bind_matrices,
            });
        }
        Ok(skins)
    }

    fn load_nodes(&mut self) -> Result<Vec<Node>, ErrorKind> {
        let count = self.doc.nodes().count();
        let mut nodes = Vec::with_capacity(count);
        for node in self.doc.nodes() {
            let local = match node.transform() {
                gltf::scene::Transform::Matrix { matrix } => {
                    let m = Mat4::from_cols_array_2d(&matrix);
                    if !m.is_finite() {
                        return Err(ErrorKind::Hierarchy(format!(
                            "node {} has a non-finite matrix",
                            node.index()
                        )));
                    }
                    LocalTransform::Matrix(m)
                }
                gltf::scene::Transform::Decomposed {
                    translation,
                    rotation,
                    scale,
                } => {
                    let t = Trs {
                        translation: Vec3::from(translation),
                        rotation: normalise_quat(Quat::from_array(rotation)),
                        scale: Vec3::from(scale),
                    };
                    if !(t.translation.is_finite() && t.scale.is_finite()) {
                        return Err(ErrorKind::Hierarchy(format!(
                            "node {} has a non-finite transform",
                            node.index()
                        )));
                    }
                    LocalTransform::Trs(t)
                }
            };
            let target_count = node
                .mesh()
                .and_then(|m| m.primitives().map(|p| p.morph_targets().count()).max())
                .unwrap_or(0);
            let mut morph_weights = node
                .weights()
                .or_else(|| node.mesh().and_then(|m| m.weights()))
                .map(<[f32]>::to_vec)
                .unwrap_or_default();
            morph_weights.resize(target_count, 0.0);
            nodes.push(Node {
                name: node.name().map(str::to_string),
                parent: None,
                children: node.children().map(|c| c.index()).collect(),
                local,
                mesh: node.mesh().map(|m| m.index()),
                skin: node.skin().map(|s| s.index()),
                morph_weights,
            });
        }
        for i in 0..count {
            for c in nodes[i].children.clone() {
                if c == i {
                    return Err(ErrorKind::Hierarchy(format!("node {i} is its own child")));
                }
                if let Some(p) = nodes[c].parent {
                    return Err(ErrorKind::Hierarchy(format!(
                        "node {c} has two parents ({p} and {i})"
                    )));
                }
                nodes[c].parent = Some(i);
            }
        }
        // With at most one parent each, a cycle shows as a walk longer than the node count.
        for start in 0..count {
            let mut at = start;
            let mut steps = 0;
            while let Some(p) = nodes[at].parent {
                at = p;
                steps += 1;
                if steps > count {
                    return Err(ErrorKind::Hierarchy(format!(
                        "node {start} is part of a cycle"
                    )));
                }
            }
        }
        Ok(nodes)
    }

    fn load_animations(
        &mut self,
        nodes: &mut [Node],
        meshes: &[Mesh],
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
                let times_s: Vec<f32> = read_f64(&input, &self.buffers)?
                    .into_iter()
                    .map(|t| t as f32)
                    .collect();
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
                let values: Vec<f32> = read_f64(&output, &self.buffers)?
                    .into_iter()
                    .map(|v| v as f32)
                    .collect();
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
                            .and_then(|m| meshes.get(m))
                            .and_then(|m| m.primitives.iter().map(|p| p.morph_targets.len()).max())
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
                let expected = keys * groups * components;
                if values.len() != expected {
                    return Err(aerr(format!(
                        "channel {ci} has {} output values, expected {expected} ({keys} keys x \
                         {groups} x {components})",
                        values.len()
                    )));
                }
                let mut sampler = Sampler {
                    interpolation,
                    times_s,
                    values,
                    components,
                };
                if property == Property::Rotation {
                    reject_zero_rotation_keys(&mut sampler)
                        .map_err(|m| aerr(format!("channel {ci}: {m}")))?;
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

    fn roots(&self, nodes: &[Node]) -> Vec<usize> {
        let scene = self
            .doc
            .default_scene()
            .or_else(|| self.doc.scenes().next());
        match scene {
            Some(s) => s.nodes().map(|n| n.index()).collect(),
            None => (0..nodes.len())
                .filter(|&i| nodes[i].parent.is_none())
                .collect(),
        }
    }
}

/// Checks every skinned node's primitives against its skin.
fn check_skinned_nodes(nodes: &[Node], meshes: &[Mesh], skins: &[Skin]) -> Result<(), ErrorKind> {
    for (ni, node) in nodes.iter().enumerate() {
        let (Some(mi), Some(si)) = (node.mesh, node.skin) else {
            continue;
        };
        let joint_count = skins[si].joints.len();
        for (pi, prim) in meshes[mi].primitives.iter().enumerate() {
            for (v, (j, w)) in prim.joints.iter().zip(&prim.weights).enumerate() {
                for k in 0..8 {
                    if w[k] > 0.0 && j[k] as usize >= joint_count {
                        return Err(ErrorKind::JointOutOfRange {
                            node: ni,
                            mesh: mi,
                            primitive: pi,
                            vertex: v,
                            joint: j[k] as u32,
                            joint_count,
                        });
                    }
                }
            }
        }
    }
    Ok(())
}

fn normalise_quat(q: Quat) -> Quat {
    let len = q.length();
    if len.is_finite() && len > 1e-12 {
        q / len
    } else {
        Quat::IDENTITY
    }
}

/// Checks rotation keyframe values (not CUBICSPLINE tangents): a zero quaternion has no
/// rotation. Non-unit keys are kept as they are: interpolation runs on the stored values and
/// the result is normalised (the conformance reference and three.js agree on that order).
fn reject_zero_rotation_keys(s: &mut Sampler) -> Result<(), String> {
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
    for key in s.values.chunks_exact_mut(stride) {
        let v = &key[offset..offset + 4];
        if Quat::from_xyzw(v[0], v[1], v[2], v[3]).length() < 1e-6 {
            return Err("a rotation key is the zero quaternion".into());
        }
    }
    Ok(())
}

fn short(s: &str) -> String {
    if s.len() > 48 {
        let cut = s.char_indices().nth(48).map(|(i, _)| i).unwrap_or(s.len());
        format!("{}...", &s[..cut])
    } else {
        s.to_string()
    }
}

fn percent_decode(s: &str) -> Option<String> {
    let bytes = s.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'%' {
            let hex = s.get(i + 1..i + 3)?;
            out.push(u8::from_str_radix(hex, 16).ok()?);
            i += 3;
        } else {
            out.push(bytes[i]);
            i += 1;
        }
    }
    String::from_utf8(out).ok()
}
