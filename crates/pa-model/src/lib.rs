//! glTF 2.0 prop models for Props Alive: hardened loading, animation sampling, CPU skinning
//! and export of posed meshes.
//!
//! The stage this crate serves is **animate** (frame -> track -> place -> *animate* -> texture
//! -> diminish -> composite -> output). It is pure CPU code with no renderer dependency:
//!
//! - [`Model::load`] reads `.glb` / `.gltf` (external `.bin` and images, data URIs) into our own
//!   plain types, checking every byte range, index and count on the way (hostile files give a
//!   [`ModelError`] naming the file and the problem, never a panic or an unbounded allocation).
//!   A primitive without `NORMAL` gets flat normals there, once, for every renderer
//!   ([`Primitive::drawn`]); its own vertices stay the file's.
//! - [`anim`] samples an animation at any time into a [`anim::Pose`] (LINEAR, STEP,
//!   CUBICSPLINE; translation, rotation, scale, morph weights).
//! - [`skin`] is the CPU reference of linear blend skinning `v' = sum_i w_i M_i v` plus morph
//!   targets, in glTF world space (right-handed, +Y up, metres).
//! - [`export`] writes a posed mesh as OBJ, STL or GLB.
//! - [`describe`] is the bounded text summary of a model that `propsalive inspect` prints.
//!
//! # Hostile files
//!
//! Loading never panics on a file's contents and never blocks or allocates without bound:
//!
//! - Only regular files are opened ([`pa_io`]): a FIFO, a device (`/dev/zero`), a socket or a
//!   folder, as the model file or behind a buffer or image URI, is refused at once.
//! - The GLB container is parsed by our own checked code, and every index in the JSON
//!   (accessors, buffer views, buffers, meshes, materials, textures, images, samplers, skins,
//!   nodes, scenes, animation samplers and channels) and every enumerated value the `gltf`
//!   crate would otherwise unwrap is checked before that crate sees the document. A bad
//!   reference gives [`ErrorKind::Reference`] naming where it is and what it names.
//! - The node hierarchy is checked in linear time and walked without recursion, so a
//!   100,000-node chain loads (and poses) quickly and cannot overflow the stack.
//!
//! # Budgets
//!
//! Before any accessor is decoded, the loader adds up what the document asks for and refuses
//! it ([`ErrorKind::OverBudget`], naming the file, the budget and where it ran out) when a
//! total exceeds its budget in [`Limits`]. The defaults:
//!
//! | Budget ([`Limits`] field)   | Default    | Counts                                                     |
//! |-----------------------------|------------|------------------------------------------------------------|
//! | `max_file_bytes`            | 2 GiB      | one file read from disk (model, `.bin`, image)             |
//! | `max_input_bytes`           | 2 GiB      | all buffer data and encoded images together (files and data URIs; the GLB binary chunk is not copied) |
//! | `max_vertex_bytes`          | 1 GiB      | decoded vertex attributes, triangle indices and inverse bind matrices, plus the flat normals and flat-shaded copies of primitives without normals ([`Primitive::flat_shaded`]), in bytes of [`Model`]'s types |
//! | `max_morph_bytes`           | 1 GiB      | decoded morph target deltas (the flat-shaded copies' included) plus every node's morph weights |
//! | `max_animation_bytes`       | 512 MiB    | decoded key times and values of every channel, plus a fixed cost per channel |
//! | `max_nodes`                 | 1,048,576  | nodes                                                      |
//! | `max_instanced_vertices`    | 33,554,432 | vertices drawn: each mesh node counts its mesh's vertices and those of their flat-shaded copies (bounds posing and export) |
//! | `max_image_side`            | 16,384 px  | width or height of one decoded image                       |
//! | `max_image_bytes`           | 1 GiB      | all decoded RGBA8 images together                          |
//!
//! The decoded totals are exact sizes of what [`Model`] will hold, computed with overflow-checked
//! (saturating) arithmetic from the declared counts, so an 800-byte file declaring 2^24 sparse
//! vertices with 16 morph targets, or a file repeating a large animation thousands of times, is
//! refused before anything is allocated. While an accessor is decoded, memory briefly reaches
//! about twice that accessor's decoded size. An accessor without a buffer view may have at most
//! [`accessor::MAX_VIEWLESS_ELEMENTS`] elements.

pub mod accessor;
pub mod anim;
mod budget;
pub mod describe;
pub mod export;
mod flat;
mod load;
pub mod skin;
mod validate;

use std::path::PathBuf;

use glam::{Mat4, Quat, Vec3};

pub use load::{Limits, LoadOptions};

/// An error while loading or using a model. Its message names the file and the problem.
#[derive(Debug, thiserror::Error)]
#[error("{}: {kind}", path.display())]
pub struct ModelError {
    /// The model file (or output file, for export errors).
    pub path: PathBuf,
    /// What went wrong.
    pub kind: ErrorKind,
}

/// What went wrong with a model.
#[derive(Debug, thiserror::Error)]
pub enum ErrorKind {
    #[error("cannot read file: {0}")]
    Io(#[from] std::io::Error),
    /// The model file is a FIFO, a device, a socket or a folder (see [`pa_io::read_regular`]).
    #[error("is {kind}, not a regular file (only regular files are read)")]
    NotRegularFile { kind: &'static str },
    #[error("not a valid glTF 2.0 file: {0}")]
    Parse(String),
    #[error("{what} is {size} bytes, over the limit of {limit} bytes")]
    TooLarge { what: String, size: u64, limit: u64 },
    #[error("URI {uri:?} escapes the model's folder (absolute paths and '..' are refused)")]
    UriEscapes { uri: String },
    #[error("URI {uri:?} is not supported: {reason}")]
    UnsupportedUri { uri: String, reason: String },
    #[error("buffer {index}: {message}")]
    Buffer { index: usize, message: String },
    #[error("accessor {index}: {message}")]
    Accessor { index: usize, message: String },
    #[error(
        "mesh {mesh} primitive {primitive}: joint index {joint} at vertex {vertex} is past the \
         skin's {joint_count} joints (node {node})"
    )]
    JointOutOfRange {
        node: usize,
        mesh: usize,
        primitive: usize,
        vertex: usize,
        joint: u32,
        joint_count: usize,
    },
    #[error(
        "mesh {mesh} primitive {primitive}: invalid skin weights at vertex {vertex}: {message}"
    )]
    InvalidWeights {
        mesh: usize,
        primitive: usize,
        vertex: usize,
        message: String,
    },
    #[error("mesh {mesh} primitive {primitive}: {message}")]
    Primitive {
        mesh: usize,
        primitive: usize,
        message: String,
    },
    #[error("image {index}: {message}")]
    Image { index: usize, message: String },
    #[error("skin {index}: {message}")]
    Skin { index: usize, message: String },
    #[error("animation {index}: {message}")]
    Animation { index: usize, message: String },
    #[error("node hierarchy: {0}")]
    Hierarchy(String),
    /// An index in the JSON names an object that does not exist.
    #[error("{at}: {field} names {kind} {index}, which does not exist ({})", counted(*count, kind))]
    Reference {
        /// Where the reference is ("mesh 0 primitive 1").
        at: String,
        /// The JSON property holding it ("attributes.POSITION").
        field: String,
        /// What it names ("accessor").
        kind: &'static str,
        index: usize,
        /// How many of `kind` the file has.
        count: usize,
    },
    /// A value in the JSON that is not allowed there (an unknown enumerated value, a missing
    /// property the loader needs).
    #[error("{at}: {message}")]
    Invalid { at: String, message: String },
    /// The document asks for more than a budget of [`Limits`] allows.
    #[error(
        "{what} needs {needed} {unit}, over the budget of {limit} {unit} (Limits::{budget}); \
         the budget ran out at {at}"
    )]
    OverBudget {
        /// What is counted ("decoded vertex data").
        what: &'static str,
        /// The [`Limits`] field.
        budget: &'static str,
        /// "bytes", "nodes", "vertices".
        unit: &'static str,
        /// The running total when the budget ran out.
        needed: u64,
        limit: u64,
        /// The object that made it run out ("mesh 0 primitive 0 morph target 5").
        at: String,
    },
    #[error("no animation named {0:?} (see `propsalive inspect`)")]
    NoSuchAnimation(String),
    #[error("cannot export: {0}")]
    Export(String),
    /// A GLB of a posed model without triangles ([`export::glb_bytes`]).
    #[error("the posed model has no triangles")]
    NoTriangles,
    /// A GLB container larger than its 32-bit length field can say
    /// ([`export::glb_container`]).
    #[error("GLB of {bytes} bytes is over 4 GiB")]
    GlbTooLarge { bytes: usize },
    /// Serialising a GLB's JSON chunk ([`export::glb_container`]).
    #[error("{0}")]
    GlbJson(serde_json::Error),
}

/// "there is 1 node", "there are 3 nodes".
fn counted(count: usize, kind: &str) -> String {
    if count == 1 {
        format!("there is 1 {kind}")
    } else {
        format!("there are {count} {kind}s")
    }
}

impl ModelError {
    pub(crate) fn new(path: impl Into<PathBuf>, kind: ErrorKind) -> Self {
        Self {
            path: path.into(),
            kind,
        }
    }
}

/// A node's local transform.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum LocalTransform {
    /// A matrix (cannot be animated, per the spec).
    Matrix(Mat4),
    /// Translation, rotation (unit quaternion), scale.
    Trs(Trs),
}

/// Translation, rotation, scale.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Trs {
    pub translation: Vec3,
    pub rotation: Quat,
    pub scale: Vec3,
}

impl Default for Trs {
    fn default() -> Self {
        Self {
            translation: Vec3::ZERO,
            rotation: Quat::IDENTITY,
            scale: Vec3::ONE,
        }
    }
}

impl Trs {
    /// `parent_from_node` as a matrix.
    pub fn matrix(&self) -> Mat4 {
        Mat4::from_scale_rotation_translation(self.scale, self.rotation, self.translation)
    }
}

impl LocalTransform {
    /// `parent_from_node` as a matrix.
    pub fn matrix(&self) -> Mat4 {
        match self {
            Self::Matrix(m) => *m,
            Self::Trs(t) => t.matrix(),
        }
    }
}

/// A node of the scene graph.
#[derive(Debug, Clone)]
pub struct Node {
    pub name: Option<String>,
    pub parent: Option<usize>,
    pub children: Vec<usize>,
    /// Rest (non-animated) local transform.
    pub local: LocalTransform,
    pub mesh: Option<usize>,
    pub skin: Option<usize>,
    /// Morph weights of this node's mesh (node weights, else the mesh's, else zeros).
    pub morph_weights: Vec<f32>,
}

/// A morph target: per-vertex deltas.
#[derive(Debug, Clone, Default)]
pub struct MorphTarget {
    pub position_deltas: Vec<Vec3>,
    /// Empty when the target has no normal deltas.
    pub normal_deltas: Vec<Vec3>,
}

/// One drawable primitive of a mesh (always a triangle list after loading).
///
/// Its vertices are the file's, in the file's order (posing, export and the conformance
/// references compare them by index). Draw it through [`Primitive::drawn`]: a primitive whose
/// file has no `NORMAL` is drawn with flat normals (glTF 2.0 requires them), computed once
/// at load (see [`Primitive::flat_shaded`]).
#[derive(Debug, Clone, Default)]
pub struct Primitive {
    pub positions: Vec<Vec3>,
    /// The file's NORMAL. When the file has none: the flat normals for a non-indexed
    /// triangle list (each vertex belongs to one triangle, so they fit in place), otherwise
    /// empty, and [`Primitive::flat_shaded`] holds the flat-shaded copy that is drawn.
    pub normals: Vec<Vec3>,
    /// TEXCOORD_0; empty when absent.
    pub uvs: Vec<[f32; 2]>,
    /// Up to 8 joint influences (JOINTS_0, JOINTS_1); empty for rigid primitives.
    pub joints: Vec<[u16; 8]>,
    /// Weights matching `joints`, normalised to sum to 1.
    pub weights: Vec<[f32; 8]>,
    /// Triangle list indices (every primitive mode is converted to a triangle list; points and
    /// lines produce none).
    pub indices: Vec<u32>,
    pub material: Option<usize>,
    pub morph_targets: Vec<MorphTarget>,
    /// For a primitive with triangles whose file has no NORMAL and whose triangles share
    /// vertices (indexed lists, strips, fans): the same triangles un-welded, three vertices
    /// of their own each (triangle `t` is vertices `3t..3t + 3`), every per-vertex attribute
    /// copied and the triangle's unit normal on each corner; its morph targets move positions
    /// only (no normal deltas), and it has no `flat_shaded` of its own. Both render paths
    /// draw it instead of this primitive ([`Primitive::drawn`]); `None` otherwise. The
    /// approximations (morphs and skinning carry the rest-pose flat normals) are described in
    /// the loader's `flat` module.
    pub flat_shaded: Option<Box<Primitive>>,
}

impl Primitive {
    /// Number of triangles.
    pub fn triangle_count(&self) -> usize {
        self.indices.len() / 3
    }

    /// The primitive as the renderers draw it: [`Primitive::flat_shaded`] when there is one,
    /// else this primitive. Same triangles, same material; every triangle has normals.
    pub fn drawn(&self) -> &Primitive {
        self.flat_shaded.as_deref().unwrap_or(self)
    }
}

/// A mesh: a list of primitives.
#[derive(Debug, Clone, Default)]
pub struct Mesh {
    pub name: Option<String>,
    pub primitives: Vec<Primitive>,
}

/// A skin: joints and their inverse bind matrices.
#[derive(Debug, Clone)]
pub struct Skin {
    pub name: Option<String>,
    /// Node indices of the joints.
    pub joints: Vec<usize>,
    /// `joint_from_bind` per joint (identity when the file has none).
    pub inverse_bind_matrices: Vec<Mat4>,
}

/// A decoded RGBA8 image (sRGB encoded, as in the file).
#[derive(Debug, Clone)]
pub struct Image {
    pub name: Option<String>,
    pub width: u32,
    pub height: u32,
    pub rgba8: Vec<u8>,
}

/// The parts of a glTF material Props Alive uses.
#[derive(Debug, Clone)]
pub struct Material {
    pub name: Option<String>,
    pub base_color_factor: [f32; 4],
    /// Index into [`Model::images`].
    pub base_color_image: Option<usize>,
    pub double_sided: bool,
}

/// The animated property of a channel.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Property {
    Translation,
    Rotation,
    Scale,
    MorphWeights,
}

/// Keyframe interpolation.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Interpolation {
    Linear,
    Step,
    CubicSpline,
}

/// A sampler with its keyframes, validated at load time.
#[derive(Debug, Clone)]
pub struct Sampler {
    pub interpolation: Interpolation,
    /// Strictly increasing key times in seconds.
    pub times_s: Vec<f32>,
    /// Flat output values: per key, `components` values (three groups for CUBICSPLINE:
    /// in-tangent, value, out-tangent). Rotation keys are normalised.
    pub values: Vec<f32>,
    /// Values per element (3, 4, or the number of morph targets).
    pub components: usize,
}

/// One animated property of one node.
#[derive(Debug, Clone)]
pub struct Channel {
    pub node: usize,
    pub property: Property,
    pub sampler: Sampler,
}

/// An animation clip.
#[derive(Debug, Clone)]
pub struct Animation {
    pub name: Option<String>,
    pub channels: Vec<Channel>,
    /// The last key time of any channel.
    pub duration_s: f32,
}

/// A loaded glTF model.
#[derive(Debug, Clone)]
pub struct Model {
    /// Where it was loaded from (used in error messages).
    pub path: PathBuf,
    pub nodes: Vec<Node>,
    /// Root nodes of the default scene (or of every root when the file names no scene).
    pub roots: Vec<usize>,
    pub meshes: Vec<Mesh>,
    pub skins: Vec<Skin>,
    pub materials: Vec<Material>,
    pub images: Vec<Image>,
    pub animations: Vec<Animation>,
    /// Warnings raised while loading (for example weights that were renormalised).
    pub warnings: Vec<String>,
}

impl Model {
    /// Loads a `.glb` or `.gltf` file with the default limits.
    pub fn load(path: impl Into<PathBuf>) -> Result<Self, ModelError> {
        load::load(path.into(), &LoadOptions::default())
    }

    /// Loads a `.glb` or `.gltf` file with explicit limits.
    pub fn load_with(path: impl Into<PathBuf>, options: &LoadOptions) -> Result<Self, ModelError> {
        load::load(path.into(), options)
    }

    /// Parses a glTF from memory. `base_dir` resolves relative URIs (none when `None`).
    pub fn from_slice(
        bytes: &[u8],
        name: impl Into<PathBuf>,
        base_dir: Option<&std::path::Path>,
        options: &LoadOptions,
    ) -> Result<Self, ModelError> {
        load::from_slice(bytes, name.into(), base_dir, options)
    }

    /// Finds an animation by name, or by index when `name_or_index` is a number.
    pub fn find_animation(&self, name_or_index: &str) -> Result<usize, ModelError> {
        if let Some(i) = self
            .animations
            .iter()
            .position(|a| a.name.as_deref() == Some(name_or_index))
        {
            return Ok(i);
        }
        match name_or_index.parse::<usize>() {
            Ok(i) if i < self.animations.len() => Ok(i),
            _ => Err(ModelError::new(
                &self.path,
                ErrorKind::NoSuchAnimation(name_or_index.to_string()),
            )),
        }
    }

    /// Total vertex count over all meshes (each mesh counted once).
    pub fn vertex_count(&self) -> usize {
        self.meshes
            .iter()
            .flat_map(|m| &m.primitives)
            .map(|p| p.positions.len())
            .sum()
    }

    /// Total triangle count over all meshes (each mesh counted once).
    pub fn triangle_count(&self) -> usize {
        self.meshes
            .iter()
            .flat_map(|m| &m.primitives)
            .map(|p| p.triangle_count())
            .sum()
    }

    /// Nodes that carry a mesh, in index order.
    pub fn mesh_nodes(&self) -> impl Iterator<Item = (usize, &Node)> {
        self.nodes
            .iter()
            .enumerate()
            .filter(|(_, n)| n.mesh.is_some())
    }
}
