//! Whether a picture can be tracked, before it is printed: enough keypoints, spread over the
//! picture, and distinct (a repeating texture makes keypoints match each other, which
//! confuses matching: measured by matching the picture's descriptors against themselves).

use super::features::hamming;
use super::{picture_features, working_copy, MIN_KEYPOINTS};
use crate::{GrayImage, TrackError};

/// Keypoints for a good picture.
pub const GOOD_KEYPOINTS: usize = 300;
/// Grid used for the coverage (cells per side).
pub const COVERAGE_GRID: usize = 8;
/// Coverage (fraction of grid cells holding a keypoint) of a good picture, and the least a
/// usable one needs.
pub const GOOD_COVERAGE: f64 = 0.6;
pub const MIN_COVERAGE: f64 = 0.25;
/// A keypoint is ambiguous when another one, elsewhere in the picture, has a descriptor this
/// close (Hamming bits of 256; exact repeats give 0, the procedural test picture's 5th
/// percentile is 20).
pub const AMBIGUOUS_BITS: u32 = 16;
/// Fraction of ambiguous keypoints above which the texture is called repetitive.
pub const REPETITIVE_FRACTION: f64 = 0.25;

/// The verdict.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Verdict {
    /// Enough distinct keypoints, spread over the picture.
    Good,
    /// Trackable, with warnings (few keypoints, parts without texture, repetition).
    Usable,
    /// Not trackable.
    Unusable,
}

/// Measurements of a picture.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct PictureQuality {
    pub width_px: u32,
    pub height_px: u32,
    /// Keypoints over all scales (working resolution).
    pub keypoints: usize,
    /// Fraction of the cells of an 8 x 8 grid holding a keypoint.
    pub coverage: f64,
    /// Fraction of keypoints with a near-identical descriptor elsewhere in the picture.
    pub ambiguous_fraction: f64,
    pub verdict: Verdict,
    /// Why the verdict is not `Good`, one line each.
    pub warnings: Vec<String>,
}

/// Measures `picture` (any size above [`super::MIN_SIDE_PX`]). A featureless picture is not
/// an error here: its verdict is `Unusable`.
pub fn assess_picture(picture: &GrayImage) -> Result<PictureQuality, TrackError> {
    let work = working_copy(picture)?;
    let (_, kps, desc, _) = picture_features(&work, false);
    let (w, h) = (work.width as f32, work.height as f32);
    let g = COVERAGE_GRID;
    let mut cells = vec![false; g * g];
    for k in &kps {
        let cx = ((k.x / w * g as f32) as usize).min(g - 1);
        let cy = ((k.y / h * g as f32) as usize).min(g - 1);
        cells[cy * g + cx] = true;
    }
    let coverage = cells.iter().filter(|c| **c).count() as f64 / (g * g) as f64;
    // Self-matching: the nearest descriptor of another keypoint at least 24 px (scaled by
    // the pair's level) away.
    let ambiguous = kps
        .iter()
        .zip(&desc)
        .enumerate()
        .filter(|(i, (k, d))| {
            kps.iter().zip(&desc).enumerate().any(|(j, (k2, d2))| {
                let far = 24.0 * 2f32.powf(0.5 * k.level.max(k2.level) as f32);
                j != *i
                    && (k.x - k2.x).powi(2) + (k.y - k2.y).powi(2) > far * far
                    && hamming(d, d2) < AMBIGUOUS_BITS
            })
        })
        .count();
    let ambiguous_fraction = if kps.is_empty() {
        0.0
    } else {
        ambiguous as f64 / kps.len() as f64
    };
    let mut warnings = Vec::new();
    let mut unusable = false;
    if kps.len() < MIN_KEYPOINTS {
        unusable = true;
        warnings.push(format!(
            "only {} keypoints (at least {MIN_KEYPOINTS} needed, {GOOD_KEYPOINTS} or more is good): the picture is too flat or smooth",
            kps.len()
        ));
    } else if kps.len() < GOOD_KEYPOINTS {
        warnings.push(format!(
            "{} keypoints ({GOOD_KEYPOINTS} or more is good): add detail or contrast",
            kps.len()
        ));
    }
    if coverage < MIN_COVERAGE {
        unusable = true;
        warnings.push(format!(
            "keypoints cover {:.0} % of the picture (at least {:.0} % needed): most of it has no texture",
            100.0 * coverage,
            100.0 * MIN_COVERAGE
        ));
    } else if coverage < GOOD_COVERAGE {
        warnings.push(format!(
            "keypoints cover {:.0} % of the picture ({:.0} % or more is good): parts without texture track poorly when the rest is hidden",
            100.0 * coverage,
            100.0 * GOOD_COVERAGE
        ));
    }
    if ambiguous_fraction > REPETITIVE_FRACTION {
        warnings.push(format!(
            "repetitive texture: {:.0} % of keypoints look like another part of the picture (more than {:.0} %): matches may be confused",
            100.0 * ambiguous_fraction,
            100.0 * REPETITIVE_FRACTION
        ));
    }
    let verdict = if unusable {
        Verdict::Unusable
    } else if warnings.is_empty() {
        Verdict::Good
    } else {
        Verdict::Usable
    };
    Ok(PictureQuality {
        width_px: picture.width,
        height_px: picture.height,
        keypoints: kps.len(),
        coverage,
        ambiguous_fraction,
        verdict,
        warnings,
    })
}
