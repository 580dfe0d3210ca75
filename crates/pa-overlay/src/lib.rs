//! CPU drawing for people, with no window and no GPU: what the live preview draws over and
//! under the composited frame, the preview's pure state, and printable marker sheets.
//!
//! - [`draw`]: an RGBA8 [`draw::Image`] with rectangles, blending, clipped lines, mask tints
//!   and outlines, and text in an embedded 8x8 bitmap font.
//! - [`hud`]: the status bar (timeline with key poses, fps, latency, tracking state, stage
//!   timings, overlay flags, recording), the tracked marker's axes and text panels.
//! - [`action`]: what the user can ask the preview for, and the key list.
//! - [`state`]: the preview's state machine (animation frame, play/pause, key pose, overlays);
//!   an [`action::Action`] in, the new state and an [`state::Effect`] for the window code out.
//! - [`layout`]: letterboxing and the window -> canvas -> animation frame mapping; the camera
//!   model at a frame size.
//! - [`detections`]: `propsalive track --draw`'s debug frames (detection outlines, marker
//!   axes) on an RGB copy of the grey frame.
//! - [`meter`]: the preview's smoothed fps and latency summary.
//! - [`sheet`]: marker sheets (one tag or a board) as SVG at physical size and PNG at a DPI.

pub mod action;
pub mod detections;
pub mod draw;
pub mod hud;
pub mod layout;
pub mod meter;
pub mod sheet;
pub mod sheet_image;
pub mod state;

use pa_track::TagFamily;

/// Errors of the overlays and marker sheets. The messages of the sheet checks name the
/// `propsalive marker` flags they come from.
#[derive(Debug, thiserror::Error)]
pub enum OverlayError {
    /// An overlay name that is not one of `axes`, `masks`, `onion`, `lineup`, `help`.
    #[error("unknown overlay {name:?} (axes, masks, onion, lineup, help)")]
    UnknownOverlay { name: String },
    /// The tag size is not in (0, 5000] mm.
    #[error("--size-mm must be in (0, 5000], got {size_mm}")]
    SizeOutOfRange { size_mm: f64 },
    /// The resolution is not in [10, 4800] dpi.
    #[error("--dpi must be in [10, 4800], got {dpi}")]
    DpiOutOfRange { dpi: f64 },
    /// The margin is not in [0, 1000] mm.
    #[error("--margin-mm must be in [0, 1000], got {margin_mm}")]
    MarginOutOfRange { margin_mm: f64 },
    /// A tag cell would be under 2 pixels in the PNG.
    #[error("a {size_mm} mm {family} tag has {cell_mm:.2} mm cells, under 2 pixels at {dpi} dpi; raise --dpi or --size-mm")]
    CellsTooSmall {
        family: TagFamily,
        size_mm: f64,
        cell_mm: f64,
        dpi: f64,
    },
    /// A board without tags, or with more than `u32::MAX`.
    #[error("a board of {rows}x{cols} tags is empty or too large")]
    EmptyBoard { rows: u32, cols: u32 },
    /// The ids `first_id..end` are not all ids of the family.
    #[error("{family} has ids 0..{id_count}; ids {first_id}..{end} do not fit")]
    IdsOutOfRange {
        family: TagFamily,
        id_count: u32,
        first_id: u32,
        end: u64,
    },
    /// Board tags closer than one white cell.
    #[error("--gap-mm {gap_mm} is too small: {family} tags of {size_mm} mm need at least {min_gap_mm:.2} mm between their black squares (one white cell)")]
    GapTooSmall {
        gap_mm: f64,
        family: TagFamily,
        size_mm: f64,
        min_gap_mm: f64,
    },
    /// A picture's printed width is not in [10, 5000] mm.
    #[error("--width-mm must be in [10, 5000], got {width_mm}")]
    WidthOutOfRange { width_mm: f64 },
    /// A picture too small to print (a side under 16 pixels) or too large to read (over
    /// 100 million pixels).
    #[error("the picture is {width}x{height} pixels: it needs at least 16 a side and at most 100 million")]
    PictureSize { width: u32, height: u32 },
    /// The PNG would have more than 400 million pixels.
    #[error("the PNG would be {width_px:.0}x{height_px:.0} pixels; lower --dpi")]
    PngTooLarge { width_px: f64, height_px: f64 },
    /// The PNG encoder's output did not start with the signature and `IHDR`.
    #[error("unexpected PNG layout from the encoder")]
    PngLayout,
    /// Encoding the PNG failed.
    #[error(transparent)]
    Image(#[from] image::ImageError),
    /// The tag family's tables (layout, tag images).
    #[error(transparent)]
    Track(#[from] pa_track::TrackError),
}
