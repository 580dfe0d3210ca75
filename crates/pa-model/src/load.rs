//! Loading glTF 2.0 files into [`Model`], with every reference checked.
//!
//! The order matters for hostile files: the GLB container is split by our own checked code,
//! the JSON is parsed without the `gltf` crate's validation, every index is checked
//! ([`crate::validate`]), then the crate's own validation runs, then the budgets are added up
//! ([`crate::budget`]), and only then are files read and accessors decoded.

use std::borrow::Cow;
use std::io::Read as _;
use std::path::{Component, Path, PathBuf};

use base64::Engine as _;
use glam::{Mat4, Quat, Vec3};
use gltf::accessor::{DataType, Dimensions};
use gltf::mesh::{Mode, Semantic};

use crate::accessor::{expect_dims, read_f32, read_f32_prefix, read_u32, read_vec3};
use crate::{
    Animation, Channel, ErrorKind, Image, Interpolation, LocalTransform, Material, Mesh, Model,
    ModelError, MorphTarget, Node, Primitive, Property, Sampler, Skin, Trs,
};

/// Resource limits for loading (bounded allocation against absurd or hostile files). The
/// crate documentation explains each budget; every one is checked before the memory it
/// bounds is allocated.
#[derive(Debug, Clone, Copy)]
pub struct Limits {
    /// Largest model file, external buffer or external image read from disk.
    pub max_file_bytes: u64,
    /// Largest total of buffer data and encoded images held or read (external files and
    /// decoded data URIs; the GLB binary chunk is used in place and not counted).
    pub max_input_bytes: u64,
    /// Largest total of decoded vertex data: positions, normals, UVs, joints and weights,
    /// triangle indices and inverse bind matrices, in bytes of [`Model`]'s types.
    pub max_vertex_bytes: u64,
    /// Largest total of decoded morph target deltas and node morph weights, in bytes.
    pub max_morph_bytes: u64,
    /// Largest total of decoded animation key times and values (plus a fixed cost per
    /// channel), in bytes.
    pub max_animation_bytes: u64,
    /// Most nodes.
    pub max_nodes: u64,
    /// Most vertices drawn: each node with a mesh counts its mesh's vertices (this bounds
    /// posing, export and rendering, which work per mesh node).
    pub max_instanced_vertices: u64,
    /// Largest width or height of a decoded image.
    pub max_image_side: u32,
    /// Largest total allocation for decoded images.
    pub max_image_bytes: u64,
}

impl Default for Limits {
    fn default() -> Self {
        Self {
            max_file_bytes: 2 << 30,
            max_input_bytes: 2 << 30,
            max_vertex_bytes: 1 << 30,
            max_morph_bytes: 1 << 30,
            max_animation_bytes: 512 << 20,
            max_nodes: 1 << 20,
            max_instanced_vertices: 1 << 25,
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

/// Validation errors listed in a message before "and N more".
const MAX_LISTED_ERRORS: usize = 8;

pub(crate) fn load(path: PathBuf, options: &LoadOptions) -> Result<Model, ModelError> {
    let bytes = pa_io::read_regular(&path, options.limits.max_file_bytes, "a glTF file")
        .map_err(|e| ModelError::new(&path, model_file_error(&path, e)))?;
    let base_dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    from_slice(&bytes, path, Some(&base_dir), options)
}

/// The error for the model file itself (its path is already in [`ModelError`]).
fn model_file_error(path: &Path, e: pa_io::IoError) -> ErrorKind {
    match e {
        pa_io::IoError::NotRegular { kind, .. } => ErrorKind::NotRegularFile { kind },
        pa_io::IoError::TooLarge { size, limit, .. } => ErrorKind::TooLarge {
            what: format!("file {}", path.display()),
            size,
            limit,
        },
        pa_io::IoError::Io { source, .. } => ErrorKind::Io(source),
        other => ErrorKind::Io(other.into()),
    }
}

pub(crate) fn from_slice(
    bytes: &[u8],
    path: PathBuf,
    base_dir: Option<&Path>,
    options: &LoadOptions,
) -> Result<Model, ModelError> {
    let fail = |kind: ErrorKind| ModelError::new(&path, kind);
    let (json, blob) = split_container(bytes).map_err(|m| fail(ErrorKind::Parse(m)))?;
    let root: gltf::json::Root = gltf::json::deserialize::from_slice(json)
        .map_err(|e| fail(ErrorKind::Parse(e.to_string())))?;
    crate::validate::check_document(&root).map_err(fail)?;
    let doc = gltf::Document::from_json(root)
        .map_err(|e| fail(ErrorKind::Parse(gltf_error_message(&e))))?;
    crate::budget::check(&doc, &options.limits).map_err(fail)?;
    let mut loader = Loader {
        doc: &doc,
        options,
        base_dir,
        buffers: Vec::new(),
        input_bytes: 0,
        warnings: Vec::new(),
    };
    let result = loader.run(blob);
    let (nodes, roots, meshes, skins, materials, images, animations) = result.map_err(fail)?;
    let warnings = loader.warnings;
    Ok(Model {
        path,
        nodes,
        roots,
        meshes,
        skins,
        materials,
        images,
        animations,
        warnings,
    })
}

/// The `gltf` crate's error, with a long list of validation errors cut short.
fn gltf_error_message(e: &gltf::Error) -> String {
    match e {
        gltf::Error::Validation(errors) => {
            let mut s = String::from("invalid glTF:");
            for (path, error) in errors.iter().take(MAX_LISTED_ERRORS) {
                s.push_str(&format!(" {path}: {error};"));
            }
            if errors.len() > MAX_LISTED_ERRORS {
                s.push_str(&format!(" and {} more", errors.len() - MAX_LISTED_ERRORS));
            }
            s
        }
        other => other.to_string(),
    }
}

const GLB_JSON: u32 = 0x4E4F_534A;
const GLB_BIN: u32 = 0x004E_4942;

fn le_u32(bytes: &[u8], at: usize) -> Option<u32> {
    let b = bytes.get(at..at.checked_add(4)?)?;
    Some(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
}

/// Splits a GLB container into its JSON and binary chunks (a `.gltf` is all JSON). Every
/// length is checked against the bytes present; chunks of unknown types are skipped, as the
/// spec asks.
fn split_container(bytes: &[u8]) -> Result<(&[u8], Option<&[u8]>), String> {
    if !bytes.starts_with(b"glTF") {
        return Ok((bytes, None));
    }
    let header = |at| le_u32(bytes, at).ok_or("GLB header is truncated (12 bytes needed)");
    let version = header(4)?;
    if version != 2 {
        return Err(format!("GLB version {version} is not 2"));
    }
    let length = header(8)? as usize;
    if length < 12 || length > bytes.len() {
        return Err(format!(
            "GLB header declares {length} bytes but the file has {} (at least 12 needed)",
            bytes.len()
        ));
    }
    let body = &bytes[12..length];
    let mut at = 0usize;
    let mut json = None;
    let mut bin = None;
    let mut chunk = 0usize;
    while body.len() - at >= 8 {
        let (Some(len), Some(ty)) = (le_u32(body, at), le_u32(body, at + 4)) else {
            break;
        };
        let len = len as usize;
        let start = at + 8;
        let Some(data) = start.checked_add(len).and_then(|end| body.get(start..end)) else {
            return Err(format!(
                "GLB chunk {chunk} declares {len} bytes but only {} remain: truncated or \
                 corrupt file",
                body.len() - start
            ));
        };
        match (chunk, ty) {
            (0, GLB_JSON) => json = Some(data),
            (0, _) => return Err(format!("GLB chunk 0 has type {ty:#010x}, not JSON")),
            (_, GLB_BIN) if bin.is_none() => bin = Some(data),
            _ => {}
        }
        at = start + len;
        chunk += 1;
    }
    let json = json.ok_or("GLB file has no JSON chunk")?;
    Ok((json, bin))
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
    /// Buffer data: the GLB binary chunk in place, or read from a file or data URI.
    buffers: Vec<Cow<'a, [u8]>>,
    /// Bytes read into memory for buffers and images so far ([`Limits::max_input_bytes`]).
    input_bytes: u64,
    warnings: Vec<String>,
}

/// How much of a URI's data to read.
#[derive(Clone, Copy)]
enum Want {
    /// At most this many bytes (a buffer: its declared length; the rest of a file is unread).
    Prefix(u64),
    /// All of it (an image), refusing more than the file limit.
    Whole,
}

impl<'a> Loader<'a> {
    fn run(&mut self, blob: Option<&'a [u8]>) -> Result<Parts, ErrorKind> {
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
        let mesh_targets: Vec<usize> = meshes
            .iter()
            .map(|m| {
                m.primitives
                    .iter()
                    .map(|p| p.morph_targets.len())
                    .max()
                    .unwrap_or(0)
            })
            .collect();
        let mut nodes = self.load_nodes(&mesh_targets)?;
        check_skinned_nodes(&nodes, &meshes, &skins)?;
        let animations = self.load_animations(&mut nodes, &mesh_targets)?;
        let roots = self.roots(&nodes);
        Ok((nodes, roots, meshes, skins, materials, images, animations))
    }

    fn warn(&mut self, message: String) {
        log::warn!("{message}");
        self.warnings.push(message);
    }

    /// Counts `bytes` more against [`Limits::max_input_bytes`].
    fn charge_input(&mut self, bytes: u64, at: impl FnOnce() -> String) -> Result<(), ErrorKind> {
        self.input_bytes = self.input_bytes.saturating_add(bytes);
        let limit = self.options.limits.max_input_bytes;
        if self.input_bytes > limit {
            return Err(ErrorKind::OverBudget {
                what: "buffer and image data read",
                budget: "max_input_bytes",
                unit: "bytes",
                needed: self.input_bytes,
                limit,
                at: at(),
            });
        }
        Ok(())
    }

    fn load_buffers(&mut self, blob: Option<&'a [u8]>) -> Result<(), ErrorKind> {
        for buffer in self.doc.buffers() {
            let index = buffer.index();
            let declared = buffer.length();
            let truncated = |present: usize| ErrorKind::Buffer {
                index,
                message: format!(
                    "declares {declared} bytes but only {present} are present: truncated or \
                     corrupt buffer"
                ),
            };
            let data: Cow<'a, [u8]> = match buffer.source() {
                gltf::buffer::Source::Bin => {
                    let blob = blob.ok_or_else(|| ErrorKind::Buffer {
                        index,
                        message: "refers to the GLB binary chunk, which is missing".into(),
                    })?;
                    Cow::Borrowed(blob.get(..declared).ok_or_else(|| truncated(blob.len()))?)
                }
                gltf::buffer::Source::Uri(uri) => {
                    let mut data = self.read_uri(uri, Want::Prefix(declared as u64), &|m| {
                        ErrorKind::Buffer { index, message: m }
                    })?;
                    if data.len() < declared {
                        return Err(truncated(data.len()));
                    }
                    data.truncate(declared);
                    Cow::Owned(data)
                }
            };
            self.buffers.push(data);
        }
        Ok(())
    }

    /// Reads a data URI or a regular file relative to the model's folder. `wrap` turns a
    /// message naming the URI into the error for the object that refers to it.
    fn read_uri(
        &mut self,
        uri: &str,
        want: Want,
        wrap: &dyn Fn(String) -> ErrorKind,
    ) -> Result<Vec<u8>, ErrorKind> {
        let limit = self.options.limits.max_file_bytes;
        if let Some(rest) = uri.strip_prefix("data:") {
            let (header, payload) = rest
                .split_once(',')
                .ok_or_else(|| wrap(format!("data URI {:?} has no ',' separator", short(uri))))?;
            if !header.ends_with(";base64") {
                return Err(wrap(format!(
                    "data URI {:?} is not base64-encoded",
                    short(uri)
                )));
            }
            let decoded_size = payload.len() as u64 / 4 * 3;
            if decoded_size > limit {
                return Err(wrap(format!("data URI decodes to more than {limit} bytes")));
            }
            self.charge_input(decoded_size, || format!("data URI {:?}", short(uri)))?;
            return base64::engine::general_purpose::STANDARD
                .decode(payload.trim())
                .map_err(|e| {
                    wrap(format!(
                        "data URI {:?} is not valid base64: {e}",
                        short(uri)
                    ))
                });
        }
        let path = self.resolve_relative(uri).map_err(wrap)?;
        let cannot = |e: pa_io::IoError| wrap(format!("cannot read {uri:?}: {e}"));
        let file = pa_io::open_regular(&path).map_err(cannot)?;
        let size = file
            .metadata()
            .map_err(|e| wrap(format!("cannot read {uri:?} ({}): {e}", path.display())))?
            .len();
        if size > limit {
            return Err(cannot(pa_io::IoError::TooLarge {
                path,
                size,
                limit,
                what: "a file a glTF model refers to",
            }));
        }
        let to_read = match want {
            Want::Prefix(n) => size.min(n),
            Want::Whole => size,
        };
        self.charge_input(to_read, || format!("file {uri:?}"))?;
        let mut bytes = Vec::with_capacity(to_read as usize);
        file.take(to_read)
            .read_to_end(&mut bytes)
            .map_err(|e| wrap(format!("cannot read {uri:?} ({}): {e}", path.display())))?;
        Ok(bytes)
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
            let encoded: Cow<'_, [u8]> = match image.source() {
                gltf::image::Source::View { view, .. } => {
                    let buffer = self
                        .buffers
                        .get(view.buffer().index())
                        .ok_or_else(|| image_err("buffer view names a missing buffer".into()))?;
                    let start = view.offset();
                    let end = start.saturating_add(view.length());
                    Cow::Borrowed(buffer.get(start..end).ok_or_else(|| {
                        image_err(format!(
                            "buffer view {} is outside its buffer: truncated or corrupt",
                            view.index()
                        ))
                    })?)
                }
                gltf::image::Source::Uri { uri, .. } => {
                    Cow::Owned(self.read_uri(uri, Want::Whole, &image_err)?)
                }
            };
            let lim = &self.options.limits;
            let reader = image::ImageReader::new(std::io::Cursor::new(&*encoded))
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
            let mut reader = image::ImageReader::new(std::io::Cursor::new(&*encoded))
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
                read_f32(&acc, &self.buffers)?
                    .chunks_exact(2)
                    .map(|c| [c[0], c[1]])
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

        let has_normals = !normals.is_empty();
        let mut out = Primitive {
            positions,
            normals,
            uvs,
            joints,
            weights,
            indices,
            material: prim.material().index(),
            morph_targets,
            flat_shaded: None,
        };
        // glTF: without NORMAL, flat normals (see `crate::flat`). The choice between in place
        // and a copy depends on the file's structure only, as the budget counted it.
        if !has_normals && !out.indices.is_empty() {
            if prim.indices().is_none() && prim.mode() == Mode::Triangles {
                crate::flat::fill_in_place(&mut out);
            } else {
                let copy = crate::flat::unwelded(&out).ok_or_else(|| {
                    perr(format!(
                        "has no NORMAL, and its {} triangles have too many corners (over \
                         2^32) for the flat-shaded copy",
                        out.triangle_count()
                    ))
                })?;
                out.flat_shaded = Some(Box::new(copy));
            }
        }
        Ok(out)
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
            let wv = read_f32(&w, &self.buffers)?;
            if set == 0 {
                joints = vec![[0u16; 8]; n];
                weights = vec![[0f32; 8]; n];
            }
            let base = set as usize * 4;
            for v in 0..n {
                for k in 0..4 {
                    joints[v][base + k] = jv[v * 4 + k] as u16;
                    weights[v][base + k] = wv[v * 4 + k];
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
                    // Only the matrices of the joints are decoded (a budget counts them).
                    let v = read_f32_prefix(&acc, &self.buffers, joints.len())?;
                    let mats: Vec<Mat4> = v.chunks_exact(16).map(Mat4::from_cols_slice).collect();
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

    /// Nodes with their parents, checked to form a forest. `mesh_targets` is the number of
    /// morph targets of each mesh. Linear in the number of nodes and children.
    fn load_nodes(&mut self, mesh_targets: &[usize]) -> Result<Vec<Node>, ErrorKind> {
        let count = self.doc.nodes().len();
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
                .and_then(|m| mesh_targets.get(m.index()))
                .copied()
                .unwrap_or(0);
            // Only the weights that are used are copied (the budget counts those).
            let mut morph_weights: Vec<f32> = node
                .weights()
                .or_else(|| node.mesh().and_then(|m| m.weights()))
                .map(|w| w.iter().take(target_count).copied().collect())
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
            for k in 0..nodes[i].children.len() {
                let c = nodes[i].children[k];
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
        let parents: Vec<Option<usize>> = nodes.iter().map(|n| n.parent).collect();
        if let Some(n) = find_cycle(&parents, &mut 0) {
            return Err(ErrorKind::Hierarchy(format!("node {n} is part of a cycle")));
        }
        Ok(nodes)
    }

    fn load_animations(
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

    /// The root nodes of the default scene (the first scene when none is named; every
    /// parentless node when there is no scene). A scene's entries that are not roots (the
    /// spec requires roots) or that repeat one are dropped with one warning, so that nothing
    /// walking from the roots visits a node twice.
    fn roots(&mut self, nodes: &[Node]) -> Vec<usize> {
        let scene = self
            .doc
            .default_scene()
            .or_else(|| self.doc.scenes().next());
        let Some(scene) = scene else {
            return (0..nodes.len())
                .filter(|&i| nodes[i].parent.is_none())
                .collect();
        };
        let mut listed = vec![false; nodes.len()];
        let mut roots = Vec::new();
        let mut dropped = 0usize;
        for n in scene.nodes().map(|n| n.index()) {
            match listed.get_mut(n) {
                Some(seen) if !*seen && nodes[n].parent.is_none() => {
                    *seen = true;
                    roots.push(n);
                }
                _ => dropped += 1,
            }
        }
        if dropped > 0 {
            self.warn(format!(
                "scene {}: {dropped} entries of its node list are repeated or not root nodes; \
                 they were ignored",
                scene.index()
            ));
        }
        roots
    }
}

/// Finds a node on a cycle of the parent links (each node has at most one parent), or
/// `None`. Linear: every node is entered once and finished once (`steps` counts the loop
/// iterations, for tests).
fn find_cycle(parents: &[Option<usize>], steps: &mut usize) -> Option<usize> {
    const NEW: u8 = 0;
    const ON_WALK: u8 = 1;
    const DONE: u8 = 2;
    let mut state = vec![NEW; parents.len()];
    for start in 0..parents.len() {
        if state[start] != NEW {
            continue;
        }
        // Walk up until a root or a node already known to reach one.
        let mut at = start;
        loop {
            *steps += 1;
            match state[at] {
                ON_WALK => return Some(at),
                DONE => break,
                _ => {}
            }
            state[at] = ON_WALK;
            match parents[at] {
                Some(p) => at = p,
                None => break,
            }
        }
        // Everything on this walk reaches a root.
        let mut at = start;
        while state[at] == ON_WALK {
            *steps += 1;
            state[at] = DONE;
            match parents[at] {
                Some(p) => at = p,
                None => break,
            }
        }
    }
    None
}

/// Checks every skinned node's primitives against its skin. Linear: the largest joint each
/// primitive uses is found once, and a node's primitives are scanned vertex by vertex only to
/// report the first bad vertex.
fn check_skinned_nodes(nodes: &[Node], meshes: &[Mesh], skins: &[Skin]) -> Result<(), ErrorKind> {
    // Per mesh, per primitive: the largest joint index with a non-zero weight.
    let max_joint: Vec<Vec<Option<u16>>> = meshes
        .iter()
        .map(|m| {
            m.primitives
                .iter()
                .map(|p| {
                    p.joints
                        .iter()
                        .zip(&p.weights)
                        .flat_map(|(j, w)| (0..8).filter(|&k| w[k] > 0.0).map(move |k| j[k]))
                        .max()
                })
                .collect()
        })
        .collect();
    for (ni, node) in nodes.iter().enumerate() {
        let (Some(mi), Some(si)) = (node.mesh, node.skin) else {
            continue;
        };
        let (Some(mesh), Some(skin)) = (meshes.get(mi), skins.get(si)) else {
            continue;
        };
        let joint_count = skin.joints.len();
        for (pi, prim) in mesh.primitives.iter().enumerate() {
            let fits = match max_joint[mi][pi] {
                Some(j) => (j as usize) < joint_count,
                None => true,
            };
            if fits {
                continue;
            }
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_cycle_check_is_linear_on_a_deep_chain() {
        // Node i's parent is i - 1: visiting from every node used to walk to the root each
        // time (n^2 / 2 steps); now each node is entered and finished once.
        let n: usize = 100_000;
        let parents: Vec<Option<usize>> = (0..n).map(|i| i.checked_sub(1)).collect();
        let mut steps = 0;
        assert_eq!(find_cycle(&parents, &mut steps), None);
        assert!(steps <= 3 * n, "{steps} steps for {n} nodes");
        // Children listed before their parents (the chain reversed) too.
        let parents: Vec<Option<usize>> = (0..n).map(|i| (i + 1 < n).then_some(i + 1)).collect();
        let mut steps = 0;
        assert_eq!(find_cycle(&parents, &mut steps), None);
        assert!(steps <= 3 * n, "{steps} steps for {n} nodes");
    }

    #[test]
    fn the_cycle_check_finds_cycles_anywhere() {
        // 0 <- 1 <- 2 <- 0 (a cycle), 3 a root, 4 <- 3.
        let parents = [Some(2), Some(0), Some(1), None, Some(3)];
        let found = find_cycle(&parents, &mut 0).expect("a cycle");
        assert!(found < 3, "{found}");
        // A tail leading into a cycle: 5 -> 6 -> 7 -> 6.
        let parents = [None, Some(0), None, None, None, Some(6), Some(7), Some(6)];
        let found = find_cycle(&parents, &mut 0).expect("a cycle");
        assert!(found == 6 || found == 7, "{found}");
        assert_eq!(find_cycle(&[None, Some(0), Some(0), Some(2)], &mut 0), None);
    }

    #[test]
    fn glb_container_lengths_are_checked() {
        assert!(split_container(b"glTF").is_err());
        let mut glb = b"glTF".to_vec();
        glb.extend(2u32.to_le_bytes());
        glb.extend(20u32.to_le_bytes());
        glb.extend(0u32.to_le_bytes()); // empty JSON chunk
        glb.extend(GLB_JSON.to_le_bytes());
        let (json, bin) = split_container(&glb).expect("valid container");
        assert!(json.is_empty() && bin.is_none());
        // A chunk length that wraps around past the end.
        glb[12..16].copy_from_slice(&u32::MAX.to_le_bytes());
        let e = split_container(&glb).expect_err("chunk past the end");
        assert!(e.contains("chunk 0"), "{e}");
        // Version and header length.
        glb[4..8].copy_from_slice(&1u32.to_le_bytes());
        assert!(split_container(&glb).expect_err("v1").contains("version 1"));
    }
}
