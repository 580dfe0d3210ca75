//! The crate's single error type.

use crate::types::Rect;

/// Everything that can go wrong in `pa-diminish`. Fields are structured so that callers can
/// react to them; the messages name the offending sizes.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DiminishError {
    /// An image or mask has a zero width or height.
    #[error("{what} has zero size {width}x{height}")]
    ZeroSize {
        what: &'static str,
        width: u32,
        height: u32,
    },
    /// A buffer's length does not match `width * height * channels`.
    #[error("{what} buffer has {actual} bytes, expected {width}x{height}x{channels} = {expected}")]
    BufferLength {
        what: &'static str,
        width: u32,
        height: u32,
        channels: u32,
        expected: usize,
        actual: usize,
    },
    /// Two images (or an image and a mask) that must have the same size do not.
    #[error(
        "size mismatch: {what} is {actual_width}x{actual_height}, expected {expected_width}x{expected_height}"
    )]
    SizeMismatch {
        what: &'static str,
        expected_width: u32,
        expected_height: u32,
        actual_width: u32,
        actual_height: u32,
    },
    /// An operation that needs at least one set mask pixel got an empty mask.
    #[error("{what}: the mask is empty")]
    EmptyMask { what: &'static str },
    /// No in-image boundary pixel is available to fill from (the region covers the whole
    /// image, or every ray leaves the image before reaching a known pixel).
    #[error("no in-image boundary pixels around {region} in the {width}x{height} image")]
    NoBoundary {
        region: Rect,
        width: u32,
        height: u32,
    },
    /// The homography has non-finite entries or is (numerically) singular.
    #[error("homography is not invertible or not finite (det = {det})")]
    SingularHomography { det: f64 },
    /// A parameter is out of its valid range.
    #[error("invalid parameter {name} = {value}: {reason}")]
    InvalidParameter {
        name: &'static str,
        value: f64,
        reason: &'static str,
    },
}
