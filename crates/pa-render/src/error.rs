//! The error type of `pa-render`.

/// What to install when no adapter is found (also printed by the tests that skip).
pub const NO_ADAPTER_HINT: &str = "install Mesa's software drivers: apt-get install \
     mesa-vulkan-drivers libegl-mesa0, or set WGPU_BACKEND=gl";

/// Everything that can go wrong in `pa-render`. Invalid input is reported with a variant that
/// names the problem; the renderer never panics on user data.
#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    /// No graphics adapter at all (no GPU and no software rasteriser).
    #[error("no wgpu adapter found (backends {backends}): {NO_ADAPTER_HINT}")]
    NoAdapter {
        /// The backends that were searched (from `WGPU_BACKEND` or all).
        backends: String,
    },
    /// Adapters exist but none supports what the renderer needs.
    #[error(
        "no suitable wgpu adapter: {details}; prefer Vulkan (apt-get install mesa-vulkan-drivers, \
         WGPU_BACKEND=vulkan)"
    )]
    UnsupportedAdapter {
        /// One line per rejected adapter, naming what it lacks.
        details: String,
    },
    /// `WGPU_ADAPTER_NAME` is set but matches no adapter.
    #[error("WGPU_ADAPTER_NAME={wanted:?} matches no adapter; available: {available}")]
    AdapterNameNotFound { wanted: String, available: String },
    /// The adapter refused to create a device.
    #[error("could not create a wgpu device on {adapter}: {reason}")]
    RequestDevice { adapter: String, reason: String },

    /// A vertex attribute has the wrong number of elements.
    #[error("mesh attribute `{attribute}` has {actual} elements, expected {expected}")]
    AttributeLength {
        attribute: String,
        expected: usize,
        actual: usize,
    },
    /// The mesh has no vertices or no triangles.
    #[error("mesh is empty ({vertices} vertices, {indices} indices)")]
    EmptyMesh { vertices: usize, indices: usize },
    /// The index count is not a multiple of 3 (triangle lists only).
    #[error("mesh index count {count} is not a multiple of 3 (triangle list expected)")]
    IndexCountNotTriangles { count: usize },
    /// An index refers to a vertex that does not exist.
    #[error("mesh index #{position} = {index} is out of range (mesh has {vertex_count} vertices)")]
    IndexOutOfRange {
        position: usize,
        index: u32,
        vertex_count: usize,
    },
    /// A position, normal, uv, weight or morph delta is NaN or infinite.
    #[error("mesh attribute `{attribute}` of vertex {vertex} is not finite")]
    NonFinite { attribute: String, vertex: usize },
    /// Too many morph targets.
    #[error("mesh has {count} morph targets, at most {max} are supported")]
    TooManyMorphTargets { count: usize, max: usize },
    /// The mesh does not fit into one GPU buffer binding.
    #[error("mesh buffer `{buffer}` needs {bytes} bytes, the device allows {limit}")]
    MeshTooLarge {
        buffer: &'static str,
        bytes: u64,
        limit: u64,
    },

    /// The texture size is zero or above the device limit.
    #[error("texture size {width}x{height} is invalid (each side must be 1..={max})")]
    InvalidTextureSize { width: u32, height: u32, max: u32 },
    /// The texture data length does not match width * height * 4.
    #[error("texture data has {actual} bytes, {width}x{height} RGBA8 needs {expected}")]
    TextureDataLength {
        width: u32,
        height: u32,
        expected: usize,
        actual: usize,
    },
    /// [`crate::Renderer::update_texture`] was given data of another size than the texture.
    #[error("texture is {expected:?} (width, height), the new data is {actual:?}")]
    TextureSizeMismatch {
        expected: (u32, u32),
        actual: (u32, u32),
    },

    /// A draw's skin has too many joints.
    #[error("draw #{draw}: {count} joint matrices, at most {max} are supported")]
    TooManyJoints {
        draw: usize,
        count: usize,
        max: usize,
    },
    /// A skinned mesh references a joint that the draw does not provide.
    #[error(
        "draw #{draw}: vertex {vertex} uses joint {joint} with non-zero weight, but only \
         {joint_count} joint matrices were given"
    )]
    JointIndexOutOfRange {
        draw: usize,
        vertex: usize,
        joint: u16,
        joint_count: usize,
    },
    /// Joint matrices were given for a mesh without joints and weights.
    #[error("draw #{draw}: {count} joint matrices given, but the mesh has no joints/weights")]
    JointsForRigidMesh { draw: usize, count: usize },
    /// The number of morph weights does not match the mesh's morph targets.
    #[error("draw #{draw}: {actual} morph weights given, the mesh has {expected} morph targets (give 0 or {expected})")]
    MorphWeightCount {
        draw: usize,
        expected: usize,
        actual: usize,
    },
    /// A matrix, weight or colour of a draw is NaN or infinite.
    #[error("draw #{draw}: `{what}` is not finite")]
    NonFiniteDrawInput { draw: usize, what: &'static str },
    /// A mesh or texture from another `Renderer` (another device) was used.
    #[error("draw #{draw}: {what} was uploaded by a different Renderer")]
    ForeignResource { draw: usize, what: &'static str },

    /// The render size is zero or above the device's texture limit.
    #[error("render size {width}x{height} is invalid (each side must be 1..={max})")]
    InvalidRenderSize { width: u32, height: u32, max: u32 },
    /// The camera is unusable.
    #[error("region {region:?} is empty or outside the {width}x{height} target")]
    RegionOutsideTarget {
        region: crate::PixelRegion,
        width: u32,
        height: u32,
    },

    #[error("invalid camera: {0}")]
    InvalidCamera(String),
    /// The light is unusable.
    #[error("invalid lighting: {0}")]
    InvalidLighting(String),

    /// wgpu reported a validation or out-of-memory error (a bug in pa-render or a resource
    /// exhaustion).
    #[error("GPU error during {during}: {message}")]
    Gpu {
        during: &'static str,
        message: String,
    },
    /// Mapping a readback buffer failed.
    #[error("GPU readback failed: {0}")]
    Readback(String),
}
