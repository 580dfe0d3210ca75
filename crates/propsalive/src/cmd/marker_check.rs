//! `propsalive marker --check PICTURE`: whether a picture can be tracked as an image target
//! (`track --image-target`), before it is printed: the keypoints found on it (over all
//! scales), how much of it they cover (an 8 x 8 grid) and how many look like another part of
//! the picture (self-matching of the descriptors: repetitive texture confuses matching),
//! each with its threshold ([`pa_track::image_target::quality`]), any warnings, and a
//! verdict line: `verdict: good`, `verdict: usable` (with warnings) or `verdict: unusable`
//! (the command then fails, exit status 1).

use std::path::Path;

use anyhow::{bail, Context, Result};
use pa_track::image_target::quality::{
    AMBIGUOUS_BITS, COVERAGE_GRID, GOOD_COVERAGE, GOOD_KEYPOINTS, MIN_COVERAGE, REPETITIVE_FRACTION,
};
use pa_track::image_target::MIN_KEYPOINTS;
use pa_track::{assess_picture, GrayImage, Verdict};

pub fn run(picture: &Path) -> Result<()> {
    let img = image::open(picture)
        .with_context(|| format!("{}: not a readable image", picture.display()))?
        .to_luma8();
    let gray = GrayImage::from(&img);
    let q = assess_picture(&gray)
        .with_context(|| format!("{}: cannot be used as an image target", picture.display()))?;
    outln!("{}: {}x{} px", picture.display(), q.width_px, q.height_px);
    outln!(
        "keypoints: {} (at least {MIN_KEYPOINTS} needed, {GOOD_KEYPOINTS} or more is good)",
        q.keypoints
    );
    outln!(
        "coverage: {:.0} % of an {COVERAGE_GRID}x{COVERAGE_GRID} grid holds keypoints (at least {:.0} % needed, {:.0} % or more is good)",
        100.0 * q.coverage,
        100.0 * MIN_COVERAGE,
        100.0 * GOOD_COVERAGE
    );
    outln!(
        "repetition: {:.1} % of keypoints have a descriptor within {AMBIGUOUS_BITS} bits of another part of the picture (warned above {:.0} %)",
        100.0 * q.ambiguous_fraction,
        100.0 * REPETITIVE_FRACTION
    );
    for w in &q.warnings {
        outln!("warning: {w}");
    }
    match q.verdict {
        Verdict::Good => outln!("verdict: good: this picture can be tracked"),
        Verdict::Usable => {
            outln!("verdict: usable: this picture can be tracked, see the warnings")
        }
        Verdict::Unusable => {
            outln!("verdict: unusable: this picture cannot be tracked");
            bail!("{} cannot be tracked as an image target", picture.display());
        }
    }
    Ok(())
}
