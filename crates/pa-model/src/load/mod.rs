//! Loading glTF 2.0 files into [`Model`], with every reference checked.
//!
//! The order matters for hostile files: the GLB container is split by our own checked code,
//! the JSON is parsed without the `gltf` crate's validation, every index is checked
//! ([`crate::validate`]), then the crate's own validation runs, then the budgets are added up
//! ([`crate::budget`]), and only then are files read and accessors decoded.

use std::borrow::Cow;
use std::path::{Path, PathBuf};

use crate::{Animation, ErrorKind, Image, Material, Mesh, Model, ModelError, Node, Skin};

mod animation;
mod container;
mod mesh;
mod nodes;
mod resources;

use container::split_container;
use nodes::check_skinned_nodes;

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
    let (json, blob) = split_container(bytes).map_err(fail)?;
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
}
