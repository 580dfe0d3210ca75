//! Descriptor matching: brute-force Hamming distance with a ratio test, kept spread over a
//! grid of the frame so that a few busy regions do not dominate the homography.
//!
//! The picture's descriptors are held bit-sliced ([`DescriptorIndex`]): blocks of 128, each
//! as 256 bit planes (bit `j` of plane `b` is bit `b` of the block's descriptor `j`), so that
//! one query's distances to a whole block are counted at once by carry-save adders over
//! the planes; only the few descriptors that can still change the result (closer than the
//! second best so far) are looked at one by one.

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

/// Descriptors per block of a [`DescriptorIndex`].
const BLOCK: usize = 128;
/// One bit plane of a block (bit `j` of word `j / 64`: descriptor `j`'s bit).
type Lanes = [u64; 2];

/// Descriptors bit-sliced for matching (see the module's documentation).
#[derive(Debug, Clone, PartialEq)]
pub struct DescriptorIndex {
    blocks: Vec<[Lanes; 256]>,
    len: usize,
}

impl DescriptorIndex {
    pub fn new(set: &[Descriptor]) -> Self {
        let mut blocks = vec![[[0u64; 2]; 256]; set.len().div_ceil(BLOCK)];
        for (i, d) in set.iter().enumerate() {
            let (block, lane) = (&mut blocks[i / BLOCK], i % BLOCK);
            for (w, &word) in d.iter().enumerate() {
                let mut bits = word;
                while bits != 0 {
                    let b = bits.trailing_zeros() as usize;
                    bits &= bits - 1;
                    block[w * 64 + b][lane / 64] |= 1 << (lane % 64);
                }
            }
        }
        Self {
            blocks,
            len: set.len(),
        }
    }

    /// Number of descriptors.
    pub fn len(&self) -> usize {
        self.len
    }

    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// As [`nearest_two`], but distances of `cap` or more count as `cap`: `(index, best,
    /// second)` with `best` and `second` at most `cap` (index 0 when `best == cap`).
    pub fn nearest_two_below(&self, d: &Descriptor, cap: u32) -> (usize, u32, u32) {
        // The query's bits as all-ones / all-zeros masks, one per plane.
        let q: [Lanes; 256] = std::array::from_fn(|b| {
            let v = 0u64.wrapping_sub((d[b / 64] >> (b % 64)) & 1);
            [v, v]
        });
        let (mut bi, mut b1, mut b2) = (0usize, cap, cap);
        for (bn, block) in self.blocks.iter().enumerate() {
            let c = block_distances(block, &q);
            let mut below = less_than(&c, b2);
            // Lanes past the end of the set.
            let valid = (self.len - bn * BLOCK).min(BLOCK);
            if valid < BLOCK {
                below[1] &= low_bits(valid.saturating_sub(64));
                below[0] &= low_bits(valid.min(64));
            }
            for (k, &mask) in below.iter().enumerate() {
                let mut m = mask;
                while m != 0 {
                    let j = m.trailing_zeros() as usize;
                    m &= m - 1;
                    let h = c
                        .iter()
                        .enumerate()
                        .map(|(bit, plane)| (((plane[k] >> j) & 1) as u32) << bit)
                        .sum::<u32>();
                    if h < b1 {
                        b2 = b1;
                        b1 = h;
                        bi = bn * BLOCK + k * 64 + j;
                    } else if h < b2 {
                        b2 = h;
                    }
                }
            }
        }
        (bi, b1, b2)
    }
}

/// The `n` lowest bits set (`n <= 64`).
fn low_bits(n: usize) -> u64 {
    if n >= 64 {
        u64::MAX
    } else {
        (1u64 << n) - 1
    }
}

/// Carry-save adder: (carry, sum) of three bit-sliced inputs.
#[inline(always)]
fn csa(a: Lanes, b: Lanes, c: Lanes) -> (Lanes, Lanes) {
    let mut hi = [0u64; 2];
    let mut lo = [0u64; 2];
    for k in 0..2 {
        let u = a[k] ^ b[k];
        hi[k] = (a[k] & b[k]) | (u & c[k]);
        lo[k] = u ^ c[k];
    }
    (hi, lo)
}

/// The Hamming distances of the query (as masks `q`) to a block's 128 descriptors,
/// bit-sliced: 9 planes, least significant first (Harley-Seal carry-save counting, 16
/// planes at a time; written out so that it compiles to straight SSE2 code).
#[inline(never)]
fn block_distances(block: &[Lanes; 256], q: &[Lanes; 256]) -> [Lanes; 9] {
    let z = [0u64; 2];
    let (mut ones, mut twos, mut fours, mut eights) = (z, z, z, z);
    let mut sixteens = [z; 5];
    for (p, m) in block.chunks_exact(16).zip(q.chunks_exact(16)) {
        let x = |i: usize| [p[i][0] ^ m[i][0], p[i][1] ^ m[i][1]];
        let (ta, o) = csa(ones, x(0), x(1));
        let (tb, o) = csa(o, x(2), x(3));
        let (fa, t) = csa(twos, ta, tb);
        let (ta, o) = csa(o, x(4), x(5));
        let (tb, o) = csa(o, x(6), x(7));
        let (fb, t) = csa(t, ta, tb);
        let (ea, f) = csa(fours, fa, fb);
        let (ta, o) = csa(o, x(8), x(9));
        let (tb, o) = csa(o, x(10), x(11));
        let (fa, t) = csa(t, ta, tb);
        let (ta, o) = csa(o, x(12), x(13));
        let (tb, o) = csa(o, x(14), x(15));
        let (fb, t) = csa(t, ta, tb);
        let (eb, f) = csa(f, fa, fb);
        let (carry16, e) = csa(eights, ea, eb);
        (ones, twos, fours, eights) = (o, t, f, e);
        // Add to the (5-bit) count of sixteens.
        let mut carry = carry16;
        for c in sixteens.iter_mut() {
            for k in 0..2 {
                let t = c[k] & carry[k];
                c[k] ^= carry[k];
                carry[k] = t;
            }
        }
    }
    [
        ones,
        twos,
        fours,
        eights,
        sixteens[0],
        sixteens[1],
        sixteens[2],
        sixteens[3],
        sixteens[4],
    ]
}

/// Lanes whose bit-sliced count is below `t`.
fn less_than(c: &[Lanes; 9], t: u32) -> Lanes {
    if t >= 1 << 9 {
        return [u64::MAX; 2];
    }
    let mut lt = [0u64; 2];
    let mut eq = [u64::MAX; 2];
    for bit in (0..9).rev() {
        for k in 0..2 {
            if (t >> bit) & 1 == 1 {
                lt[k] |= eq[k] & !c[bit][k];
                eq[k] &= c[bit][k];
            } else {
                eq[k] &= !c[bit][k];
            }
        }
    }
    lt
}

/// Matches frame descriptors to the picture's.
pub fn match_descriptors(
    frame_kps: &[Keypoint],
    frame_desc: &[Descriptor],
    picture_desc: &[Descriptor],
    cfg: &MatchConfig,
) -> Vec<Match> {
    match_indexed(
        frame_kps,
        frame_desc,
        &DescriptorIndex::new(picture_desc),
        cfg,
    )
}

/// Distances from which on a second-best distance can no longer reject a match (those at
/// most `max_distance` pass the ratio test against it): larger ones need not be told apart.
fn distance_cap(cfg: &MatchConfig) -> u32 {
    let first = (0..=256u32)
        .find(|&c| (cfg.max_distance as f32) < cfg.ratio * c as f32)
        .unwrap_or(257);
    first.max(cfg.max_distance.saturating_add(1)).min(257)
}

/// [`match_descriptors`] against an indexed picture (same result).
pub fn match_indexed(
    frame_kps: &[Keypoint],
    frame_desc: &[Descriptor],
    picture: &DescriptorIndex,
    cfg: &MatchConfig,
) -> Vec<Match> {
    let cap = distance_cap(cfg);
    let mut m: Vec<Match> = frame_desc
        .par_iter()
        .with_min_len(16)
        .enumerate()
        .filter_map(|(i, d)| {
            let (j, b1, b2) = picture.nearest_two_below(d, cap);
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

#[cfg(test)]
mod tests {
    use super::*;

    /// A deterministic pseudo-random descriptor.
    fn descriptor(seed: u64) -> Descriptor {
        let mut s = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
        std::array::from_fn(|_| {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            s
        })
    }

    /// `d` with `n` bits flipped (spread over the words).
    fn flipped(d: &Descriptor, n: usize) -> Descriptor {
        let mut out = *d;
        for i in 0..n {
            let b = (i * 37) % 256;
            out[b / 64] ^= 1 << (b % 64);
        }
        out
    }

    #[test]
    fn indexed_nearest_two_agrees_with_brute_force_below_the_cap() {
        // 300 descriptors (a partial last block), some near copies of the queries.
        let queries: Vec<Descriptor> = (0..40).map(|i| descriptor(1000 + i)).collect();
        let mut set: Vec<Descriptor> = (0..300).map(descriptor).collect();
        for (i, q) in queries.iter().enumerate() {
            set[(i * 7 + 3) % 300] = flipped(q, 5 + i);
            if i % 3 == 0 {
                set[(i * 11 + 150) % 300] = flipped(q, 20 + i);
            }
        }
        let index = DescriptorIndex::new(&set);
        assert_eq!(index.len(), 300);
        for cap in [40, 95, 257] {
            for q in queries.iter().chain(&set[..20]) {
                let (i, b1, b2) = nearest_two(q, &set);
                let (j, c1, c2) = index.nearest_two_below(q, cap);
                assert_eq!(c1, b1.min(cap));
                assert_eq!(c2, b2.min(cap));
                if b1 < cap {
                    assert_eq!(i, j);
                }
            }
        }
    }

    #[test]
    fn indexed_matching_equals_plain_matching() {
        let set: Vec<Descriptor> = (0..500).map(descriptor).collect();
        let frame: Vec<Descriptor> = (0..200)
            .map(|i| {
                if i % 2 == 0 {
                    flipped(&set[(i * 3) % 500], i % 90)
                } else {
                    descriptor(5000 + i as u64)
                }
            })
            .collect();
        let kps: Vec<Keypoint> = (0..200)
            .map(|i| Keypoint {
                x: (i % 20) as f32 * 50.0,
                y: (i / 20) as f32 * 50.0,
                level: 0,
                angle: 0.0,
                score: 1.0,
            })
            .collect();
        let cfg = MatchConfig::default();
        // The brute-force reference.
        let mut want: Vec<Match> = frame
            .iter()
            .enumerate()
            .filter_map(|(i, d)| {
                let (j, b1, b2) = nearest_two(d, &set);
                (b1 <= cfg.max_distance && (b1 as f32) < cfg.ratio * b2 as f32).then_some(Match {
                    frame: i,
                    picture: j,
                    distance: b1,
                })
            })
            .collect();
        want.sort_by_key(|x| (x.picture, x.distance));
        want.dedup_by_key(|x| x.picture);
        want.sort_by_key(|x| x.distance);
        let got = match_descriptors(&kps, &frame, &set, &cfg);
        assert!(got.len() > 40, "{}", got.len());
        assert_eq!(got, want);
    }
}
