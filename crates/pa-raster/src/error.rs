//! Errors of the CPU path.

/// What the CPU renderer refuses.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum RasterError {
    #[error("texture size {width}x{height} is out of range (1..={max} a side)", max = crate::texture::MAX_TEXTURE_SIDE)]
    TextureSize { width: u32, height: u32 },
    #[error("{what}: expected {expected} bytes, got {got}")]
    DataLength {
        what: &'static str,
        expected: usize,
        got: usize,
    },
}
