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
    /// A scene variant name that does not exist (`--scene`).
    #[error("unknown scene variant \"{name}\" (known: {known})")]
    UnknownVariant { name: String, known: String },
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
