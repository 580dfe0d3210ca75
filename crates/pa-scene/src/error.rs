//! The crate's error type.

/// Everything that can go wrong building or measuring a scene.
///
/// A wrapped error is the variant's field and its message is the whole message (it is not
/// also returned by `source()`, so a chain-printing caller shows it once).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SceneError {
    /// [`crate::SceneSpec::key_frames`] is empty.
    #[error("a scene needs at least one key pose")]
    NoKeyPose,
    /// The camera of the spec (field of view, size) is invalid.
    #[error("{0}")]
    Camera(pa_camera::CameraError),
    /// Uploading or rendering the set.
    #[error("{0}")]
    Render(pa_render::RenderError),
    /// The board's tags, or the tracker built for the scene.
    #[error("{0}")]
    Track(pa_track::TrackError),
    /// Loading the built-in prop.
    #[error("{0}")]
    Model(pa_model::ModelError),
    /// Encoding the prop's texture.
    #[error("{0}")]
    Image(image::ImageError),
    /// Assembling the prop's GLB container (`pa_model::export::glb_container`).
    #[error("{0}")]
    Glb(pa_model::ErrorKind),
    /// Building or running the frame pipeline.
    #[error("{0}")]
    Pipeline(pa_pipeline::ar::ArError),
    /// The clean plate's image.
    #[error("{0}")]
    Diminish(pa_diminish::DiminishError),
    /// [`crate::SceneSpec::props`] is 0 or more than there are spots for.
    #[error("a scene holds 1 to {max} props, not {props}")]
    PropCount { props: u32, max: usize },
    /// A scene variant name that does not exist (`--scene`).
    #[error("unknown scene variant \"{name}\" (known: {known})")]
    UnknownVariant { name: String, known: String },
    /// A hiding of the board that does not exist (`demo --hide`).
    #[error("unknown hide \"{given}\" (known: cover, plate)")]
    UnknownHide { given: String },
    /// A file of an external set (manifest, image) or of its kit.
    #[error("{}: {problem}", file.display())]
    Set {
        file: std::path::PathBuf,
        problem: SetProblem,
    },
    /// A set's frames differ in a way the measurement cannot use (sizes, masks).
    #[error("set frame {frame}: {what}")]
    SetFrame { frame: u32, what: &'static str },
}

/// What is wrong with a file of an external set.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SetProblem {
    /// Opening, reading or writing it.
    #[error("{message}")]
    Io {
        kind: std::io::ErrorKind,
        message: String,
    },
    /// It is a folder, a device, a FIFO...
    #[error("not a regular file")]
    NotAFile,
    /// It is larger than the reader's budget.
    #[error("{bytes} bytes, more than the limit of {limit}")]
    TooLarge { bytes: u64, limit: u64 },
    /// It is not JSON.
    #[error("not JSON at line {line}, column {column}: {message}")]
    Json {
        line: usize,
        column: usize,
        message: String,
    },
    /// A field is missing or has a value the reader refuses.
    #[error("field `{field}` {reason}")]
    Field { field: String, reason: &'static str },
    /// An image that does not decode.
    #[error("not a readable image: {message}")]
    Image { message: String },
    /// An image of another size than the manifest's.
    #[error("image is {width}x{height}, the manifest says {expected_width}x{expected_height}")]
    ImageSize {
        width: u32,
        height: u32,
        expected_width: u32,
        expected_height: u32,
    },
}

macro_rules! from {
    ($($variant:ident($ty:ty)),* $(,)?) => {$(
        impl From<$ty> for SceneError {
            fn from(e: $ty) -> Self {
                SceneError::$variant(e)
            }
        }
    )*};
}

from!(
    Camera(pa_camera::CameraError),
    Render(pa_render::RenderError),
    Track(pa_track::TrackError),
    Model(pa_model::ModelError),
    Image(image::ImageError),
    Pipeline(pa_pipeline::ar::ArError),
    Diminish(pa_diminish::DiminishError),
);
