//! Descriptor matching: brute-force Hamming distance with a ratio test, kept spread over a
//! grid of the frame so that a few busy regions do not dominate the homography.

use rayon::prelude::*;

use super::features::{hamming, Descriptor, Keypoint};

/// A match of frame keypoint `frame` to picture keypoint `picture`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Match {
    pub frame: usize,
    pub picture: usize,
    pub distance: u32,
}

/// Matching settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MatchConfig {
    /// Largest accepted Hamming distance (of 256 bits).
    pub max_distance: u32,
    /// Best distance must be below this fraction of the second best.
    pub ratio: f32,
    /// Grid cell side in frame pixels and matches kept per cell.
    pub cell_px: f32,
    pub per_cell: usize,
}

impl Default for MatchConfig {
    fn default() -> Self {
        Self {
            max_distance: 80,
            ratio: 0.85,
            cell_px: 40.0,
            per_cell: 6,
        }
    }
}

/// Best and second-best distances of `d` among `set`: `(index, best, second)`.
pub fn nearest_two(d: &Descriptor, set: &[Descriptor]) -> (usize, u32, u32) {
    let (mut bi, mut b1, mut b2) = (0usize, u32::MAX, u32::MAX);
    for (i, s) in set.iter().enumerate() {
        let h = hamming(d, s);
        if h < b1 {
            b2 = b1;
            b1 = h;
            bi = i;
        } else if h < b2 {
            b2 = h;
        }
    }
    (bi, b1, b2)
}

/// Matches frame descriptors to the picture's.
pub fn match_descriptors(
    frame_kps: &[Keypoint],
    frame_desc: &[Descriptor],
    picture_desc: &[Descriptor],
    cfg: &MatchConfig,
) -> Vec<Match> {
    let mut m: Vec<Match> = frame_desc
        .par_iter()
        .enumerate()
        .filter_map(|(i, d)| {
            let (j, b1, b2) = nearest_two(d, picture_desc);
            (b1 <= cfg.max_distance && (b1 as f32) < cfg.ratio * b2 as f32).then_some(Match {
                frame: i,
                picture: j,
                distance: b1,
            })
        })
        .collect();
    // One frame keypoint per picture keypoint (the closest).
    m.sort_by_key(|x| (x.picture, x.distance));
    m.dedup_by_key(|x| x.picture);
    // Spread: at most `per_cell` per frame cell, best first.
    m.sort_by_key(|x| x.distance);
    let mut count = std::collections::HashMap::new();
    m.retain(|x| {
        let k = &frame_kps[x.frame];
        let key = ((k.x / cfg.cell_px) as i32, (k.y / cfg.cell_px) as i32);
        let c = count.entry(key).or_insert(0usize);
        *c += 1;
        *c <= cfg.per_cell
    });
    m
}
