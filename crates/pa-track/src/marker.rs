//! Canonical tag images (the bit patterns of a family, as the AprilTag C library's
//! `apriltag_to_image` draws them), for printing markers.

use crate::{GrayImage, TagFamily, TrackError};

/// Geometry of a family's printed tag, in cells.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FamilyLayout {
    /// Cells across the whole canonical image, including the white quiet border
    /// (10 for tag36h11).
    pub total_cells: u32,
    /// Cells across the black border square whose outer corners are detected and whose side
    /// is the physical `tag_size_m` (8 for tag36h11).
    pub border_cells: u32,
    /// Number of valid ids (587 for tag36h11).
    pub id_count: u32,
}

/// The layout of a family.
pub fn family_layout(family: TagFamily) -> Result<FamilyLayout, TrackError> {
    let f = family.def();
    Ok(FamilyLayout {
        total_cells: f.total_width as u32,
        border_cells: f.width_at_border as u32,
        id_count: f.count as u32,
    })
}

/// The canonical tag image, one pixel per cell (`total_cells` square): black 0, white 255.
/// Pixel-identical to the apriltag-imgs PNGs.
pub fn marker_cells(family: TagFamily, id: u32) -> Result<GrayImage, TrackError> {
    let f = family.def();
    let code = *f.codes().get(id as usize).ok_or(TrackError::UnknownId {
        family,
        id,
        count: f.count as u32,
    })? as u64;
    let tw = f.total_width;
    let mut img = GrayImage::filled(tw as u32, tw as u32, 0);
    let set = |img: &mut GrayImage, x: usize, y: usize| {
        if x < tw && y < tw {
            img.data[y * tw + x] = 255;
        }
    };
    let wbw = f.width_at_border + if f.reversed_border { 0 } else { 2 };
    let wbs = (tw - wbw) / 2;
    for i in 0..wbw.saturating_sub(1) {
        set(&mut img, wbs + i, wbs);
        set(&mut img, tw - 1 - wbs, wbs + i);
        set(&mut img, wbs + i + 1, tw - wbs - 1);
        set(&mut img, wbs, wbs + 1 + i);
    }
    let bs = (tw as isize - f.width_at_border as isize) / 2;
    for i in 0..f.nbits {
        if code & (1u64 << (f.nbits - i - 1)) != 0 {
            let x = f.bit_x[i] as isize + bs;
            let y = f.bit_y[i] as isize + bs;
            if x >= 0 && y >= 0 {
                set(&mut img, x as usize, y as usize);
            }
        }
    }
    Ok(img)
}

/// The tag image scaled to `size_px` square (nearest neighbour), ready to print. The whole
/// image spans `total_cells`; the black border square is `border_cells / total_cells` of it.
/// For crisp cells choose `size_px` a multiple of `total_cells`.
pub fn marker_image(family: TagFamily, id: u32, size_px: u32) -> Result<GrayImage, TrackError> {
    let cells = marker_cells(family, id)?;
    if size_px < cells.width {
        return Err(TrackError::Config(format!(
            "marker size {size_px} px is smaller than the {} cells of {family}",
            cells.width
        )));
    }
    let n = cells.width as u64;
    let s = size_px as u64;
    let mut out = GrayImage::filled(size_px, size_px, 255);
    for y in 0..s {
        let cy = (y * n / s) as usize;
        for x in 0..s {
            let cx = (x * n / s) as usize;
            out.data[(y * s + x) as usize] = cells.data[cy * n as usize + cx];
        }
    }
    Ok(out)
}
