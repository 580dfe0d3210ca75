//! PatchMatch over the pyramid: the nearest-neighbour field of every level's holes, coarse to
//! fine, with the PixMix cost (appearance + spatial + temporal).

use super::pyramid::{add, Level, HIDDEN, HOLE, KNOWN, PRIOR, UNSET};
use rayon::prelude::*;

use super::PatchParams;

/// A small deterministic generator (SplitMix64).
pub(super) struct Rng(u64);

impl Rng {
    pub(super) fn new(seed: u64) -> Self {
        Self(seed)
    }

    pub(super) fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in `0..n` (`n > 0`).
    pub(super) fn below(&mut self, n: usize) -> usize {
        ((self.next_u64() >> 32) as usize * n) >> 32
    }

    /// Uniform in `-r..=r`.
    fn offset(&mut self, r: i32) -> i32 {
        self.below(2 * r as usize + 1) as i32 - r
    }
}

/// The cost terms' settings on one level.
struct Cost {
    r: i32,
    lambda: f32,
    tau: f32,
    mu: f32,
    kappa: f32,
}

/// Runs PatchMatch on every level, coarsest first; on return every hole of level 0 holds the
/// colour of its match. `nnf[l]` is level `l`'s field (one source index a pixel; holes only).
pub(super) fn solve(
    levels: &mut [Level],
    nnf: &mut Vec<Vec<u32>>,
    votes: &mut Vec<[f32; 3]>,
    next: &mut Vec<u32>,
    params: &PatchParams,
) {
    let n = levels.len();
    nnf.resize_with(n, Vec::new);
    let mut rng = Rng::new(params.seed);
    for l in (0..n).rev() {
        let (fine, coarse) = levels.split_at_mut(l + 1);
        let lv = &mut fine[l];
        let (field, coarse_field) = {
            let (a, b) = nnf.split_at_mut(l + 1);
            (&mut a[l], b.first())
        };
        field.clear();
        field.resize(lv.w * lv.h, 0);
        match (coarse.first(), coarse_field) {
            (Some(c), Some(cf)) => upsample(lv, c, cf, field, &mut rng),
            _ => greedy_start(lv, field, &cost_of(params, l), &mut rng),
        }
        let coarsest = l + 1 == n;
        let sweeps = if coarsest {
            params.sweeps[0]
        } else if l == 0 {
            params.sweeps[2]
        } else {
            params.sweeps[1]
        };
        let cost = cost_of(params, l);
        // The random search's first radius: the whole level on the coarsest, a few pixels on
        // the finer ones (their start is already good to a pixel or two).
        let search_r = if coarsest {
            lv.w.max(lv.h) as i32
        } else if l == 0 {
            params.fine_search_px as i32
        } else {
            4
        };
        for it in 0..sweeps {
            if !coarsest && lv.holes.len() >= PARALLEL_MIN_HOLES {
                let seed = rng.next_u64();
                sweep_parallel(lv, field, &cost, search_r, seed, next);
            } else {
                sweep(lv, field, &cost, it % 2 == 1, search_r, &mut rng);
            }
        }
    }
    if let (Some(lv), Some(field)) = (levels.first_mut(), nnf.first()) {
        vote(lv, field, params.vote_radius as i32, votes);
    }
}

/// The final colours of the finest level: each hole the mean of what the matches of the holes
/// around it (within `r`, Chebyshev) say it should be, `I(f(p + v) - v)` (the overlapping
/// patches' vote): smooths the seams between copied pieces and the sensor noise they carry.
fn vote(lv: &mut Level, field: &[u32], r: i32, out: &mut Vec<[f32; 3]>) {
    if r == 0 {
        return;
    }
    out.clear();
    out.resize(lv.holes.len(), [0.0; 3]);
    {
        let lv: &Level = lv;
        out.par_chunks_mut(CHUNK)
            .zip(lv.holes.par_chunks(CHUNK))
            .for_each(|(out, holes)| {
                for (o, &p) in out.iter_mut().zip(holes) {
                    *o = vote_one(lv, field, r, p as usize);
                }
            });
    }
    for (&p, c) in lv.holes.iter().zip(out.iter()) {
        lv.color[p as usize] = *c;
    }
}

fn vote_one(lv: &Level, field: &[u32], r: i32, p: usize) -> [f32; 3] {
    let (w, h) = (lv.w as i32, lv.h as i32);
    let (px, py) = xy(lv, p);
    // `p`'s own match: a neighbour whose match continues it (most of them, in a coherent
    // field) implies exactly that source, found without dividing.
    let f = field[p] as usize;
    let (fx, _) = xy(lv, f);
    let own = lv.state[f] == KNOWN;
    let mut sum = [0.0f32; 3];
    let mut count = 0.0f32;
    for dy in -r..=r {
        let ny = py + dy;
        if ny < 0 || ny >= h {
            continue;
        }
        for dx in -r..=r {
            let nx = px + dx;
            if nx < 0 || nx >= w {
                continue;
            }
            let n = (ny * w + nx) as usize;
            if lv.state[n] != HOLE {
                continue;
            }
            let m = field[n] as i32;
            let s = if own && m == f as i32 + dy * w + dx && fx + dx >= 0 && fx + dx < w {
                f
            } else {
                match implied_source(lv, field, (px, py), (dx, dy)) {
                    Some((s, _, _)) => s,
                    None => continue,
                }
            };
            add(&mut sum, lv.color[s]);
            count += 1.0;
        }
    }
    if count > 0.0 {
        sum.map(|v| v / count)
    } else {
        lv.color[p]
    }
}

/// Column and row of pixel `i` of `lv`.
fn xy(lv: &Level, i: usize) -> (i32, i32) {
    ((i % lv.w) as i32, (i / lv.w) as i32)
}

/// The source that the hole pixel at `(px + dx, py + dy)` implies for `(px, py)`: its match
/// shifted back by `(dx, dy)`, when the neighbour lies inside the level and is a hole pixel,
/// and that source lies inside the level and is known (PatchMatch's propagation, the vote).
/// Returns the source's index, column and row.
fn implied_source(
    lv: &Level,
    field: &[u32],
    (px, py): (i32, i32),
    (dx, dy): (i32, i32),
) -> Option<(usize, i32, i32)> {
    let (w, h) = (lv.w as i32, lv.h as i32);
    let (nx, ny) = (px + dx, py + dy);
    if nx < 0 || ny < 0 || nx >= w || ny >= h {
        return None;
    }
    let n = (ny * w + nx) as usize;
    if lv.state[n] != HOLE {
        return None;
    }
    let m = field[n] as i32;
    let (sx, sy) = (m % w - dx, m / w - dy);
    if sx < 0 || sy < 0 || sx >= w || sy >= h {
        return None;
    }
    let s = (sy * w + sx) as usize;
    (lv.state[s] == KNOWN).then_some((s, sx, sy))
}

fn cost_of(params: &PatchParams, level: usize) -> Cost {
    Cost {
        r: if level == 0 {
            params.fine_patch_radius
        } else {
            params.patch_radius
        } as i32,
        lambda: params.spatial_weight / 4.0,
        tau: params.spatial_cap,
        mu: params.temporal_weight,
        kappa: params.surface_weight,
    }
}

/// Random candidates a hole of the coarsest level tries in the first pass.
const START_RANDOM: usize = 24;

/// The coarsest level's first field: the holes in onion order (from the known pixels
/// inwards), each matched against the known pixels and the holes matched before it only, from
/// its matched 8-neighbours' continuations, random sources and a random search around the
/// best. Structure entering the hole from its border is carried inwards this way.
fn greedy_start(lv: &mut Level, field: &mut [u32], cost: &Cost, rng: &mut Rng) {
    let (w, h) = (lv.w as i32, lv.h as i32);
    for &p in &lv.holes {
        let p = p as usize;
        // With a prior, its colours stand for the holes not matched yet: the start then
        // reproduces the previous frame's fill where the view has not changed.
        lv.state[p] = if !lv.prior_ok.is_empty() && lv.prior_ok[p] {
            PRIOR
        } else {
            UNSET
        };
    }
    let order = std::mem::take(&mut lv.order);
    for &p in &order {
        let p = p as usize;
        let (px, py) = xy(lv, p);
        let target = (p, px, py);
        let first = lv.sources[rng.below(lv.sources.len())] as usize;
        let (fx, fy) = xy(lv, first);
        let mut best = (first, fx, fy);
        let mut best_cost = total_cost(lv, field, cost, target, best, f32::INFINITY);
        let consider = |lv: &Level,
                        s: (usize, i32, i32),
                        best: &mut (usize, i32, i32),
                        best_cost: &mut f32| {
            if s.0 != best.0 && lv.state[s.0] == KNOWN {
                let c = total_cost(lv, field, cost, target, s, *best_cost);
                if c < *best_cost {
                    *best = s;
                    *best_cost = c;
                }
            }
        };
        for dy in -1..=1 {
            for dx in -1..=1 {
                if (dx, dy) == (0, 0) {
                    continue;
                }
                if let Some(s) = implied_source(lv, field, (px, py), (dx, dy)) {
                    consider(lv, s, &mut best, &mut best_cost);
                }
            }
        }
        for _ in 0..START_RANDOM {
            let s = lv.sources[rng.below(lv.sources.len())] as usize;
            let (sx, sy) = xy(lv, s);
            consider(lv, (s, sx, sy), &mut best, &mut best_cost);
        }
        let mut r = lv.w.max(lv.h) as i32 / 2;
        while r >= 1 {
            let sx = (best.1 + rng.offset(r)).clamp(0, w - 1);
            let sy = (best.2 + rng.offset(r)).clamp(0, h - 1);
            consider(
                lv,
                ((sy * w + sx) as usize, sx, sy),
                &mut best,
                &mut best_cost,
            );
            r /= 2;
        }
        let best = best.0;
        field[p] = best as u32;
        lv.color[p] = lv.color[best];
        lv.state[p] = HOLE;
    }
    lv.order = order;
}

/// Level `lv`'s field from the coarser level's: the child of the parent's match at the same
/// 2x2 position, or a random source when that is not a known pixel; colours follow.
fn upsample(
    lv: &mut Level,
    coarse: &Level,
    coarse_field: &[u32],
    field: &mut [u32],
    rng: &mut Rng,
) {
    let (w, h) = (lv.w, lv.h);
    for &p in &lv.holes {
        let p = p as usize;
        let (x, y) = (p % w, p / w);
        let parent = (y / 2) * coarse.w + x / 2;
        let mut s = None;
        if coarse.state[parent] == HOLE {
            let m = coarse_field[parent] as usize;
            let (mx, my) = (m % coarse.w, m / coarse.w);
            for (ox, oy) in [(x % 2, y % 2), (0, 0), (1, 0), (0, 1), (1, 1)] {
                let (sx, sy) = (2 * mx + ox, 2 * my + oy);
                if sx < w && sy < h && lv.state[sy * w + sx] == KNOWN {
                    s = Some(sy * w + sx);
                    break;
                }
            }
        }
        let s = match s {
            Some(s) => s,
            None => random_known(lv, rng),
        };
        field[p] = s as u32;
        lv.color[p] = lv.color[s];
    }
}

/// A random known pixel of `lv` (which has some): random positions until one is known, then,
/// after 64 misses, the first known pixel from a random start.
fn random_known(lv: &Level, rng: &mut Rng) -> usize {
    let n = lv.state.len();
    for _ in 0..64 {
        let i = rng.below(n);
        if lv.state[i] == KNOWN {
            return i;
        }
    }
    let start = rng.below(n);
    (0..n)
        .map(|k| (start + k) % n)
        .find(|&i| lv.state[i] == KNOWN)
        .unwrap_or(start)
}

/// One PatchMatch sweep over the holes (forward, or backward with `reverse`), in place: each
/// hole sees the matches its predecessors in the scan just found.
fn sweep(
    lv: &mut Level,
    field: &mut [u32],
    cost: &Cost,
    reverse: bool,
    search_r: i32,
    rng: &mut Rng,
) {
    let nh = lv.holes.len();
    let d: i32 = if reverse { 1 } else { -1 };
    for k in 0..nh {
        let p = lv.holes[if reverse { nh - 1 - k } else { k }] as usize;
        let best = improve(lv, field, cost, p, &[(d, 0), (0, d)], search_r, rng);
        field[p] = best as u32;
        lv.color[p] = lv.color[best];
    }
}

/// Levels with at least this many holes (not the coarsest) are swept in parallel.
const PARALLEL_MIN_HOLES: usize = 8192;

/// Holes a parallel sweep hands to one task (each task has its own generator, seeded by its
/// chunk's index, so the result does not depend on the number of threads).
pub(super) const CHUNK: usize = 2048;

/// One PatchMatch sweep with every hole improved from the field and colours as they were
/// before the sweep (Jacobi order: propagation from all four neighbours), in parallel over
/// chunks of holes; `next` is scratch. Used on the finest level, where the start from the
/// coarser level is already good and the holes are many.
fn sweep_parallel(
    lv: &mut Level,
    field: &mut [u32],
    cost: &Cost,
    search_r: i32,
    seed: u64,
    next: &mut Vec<u32>,
) {
    next.clear();
    next.resize(lv.holes.len(), 0);
    {
        let (lv, field): (&Level, &[u32]) = (lv, field);
        next.par_chunks_mut(CHUNK)
            .zip(lv.holes.par_chunks(CHUNK))
            .enumerate()
            .for_each(|(ci, (out, holes))| {
                let mut rng = Rng::new(seed ^ (ci as u64).wrapping_mul(0xA24B_AED4_963E_E407));
                for (o, &p) in out.iter_mut().zip(holes) {
                    let dirs = [(-1, 0), (1, 0), (0, -1), (0, 1)];
                    *o = improve(lv, field, cost, p as usize, &dirs, search_r, &mut rng) as u32;
                }
            });
    }
    for (&p, &s) in lv.holes.iter().zip(next.iter()) {
        field[p as usize] = s;
        lv.color[p as usize] = lv.color[s as usize];
    }
}

/// The best of hole `p`'s current match, the continuations of its neighbours' matches at the
/// offsets `dirs`, and a random search around the best with radii `search_r`, `search_r / 2`,
/// ..., 1.
fn improve(
    lv: &Level,
    field: &[u32],
    cost: &Cost,
    p: usize,
    dirs: &[(i32, i32)],
    search_r: i32,
    rng: &mut Rng,
) -> usize {
    let (w, h) = (lv.w as i32, lv.h as i32);
    let (px, py) = xy(lv, p);
    let target = (p, px, py);
    let f = field[p] as usize;
    let (fx, fy) = xy(lv, f);
    let mut best = (f, fx, fy);
    let mut best_cost = total_cost(lv, field, cost, target, best, f32::INFINITY);
    for &(dx, dy) in dirs {
        let Some(s) = implied_source(lv, field, (px, py), (dx, dy)) else {
            continue;
        };
        if s.0 == best.0 {
            continue;
        }
        let c = total_cost(lv, field, cost, target, s, best_cost);
        if c < best_cost {
            best = s;
            best_cost = c;
        }
    }
    let mut r = search_r;
    while r >= 1 {
        let sx = (best.1 + rng.offset(r)).clamp(0, w - 1);
        let sy = (best.2 + rng.offset(r)).clamp(0, h - 1);
        let s = (sy * w + sx) as usize;
        if s != best.0 && lv.state[s] == KNOWN {
            let c = total_cost(lv, field, cost, target, (s, sx, sy), best_cost);
            if c < best_cost {
                best = (s, sx, sy);
                best_cost = c;
            }
        }
        r /= 2;
    }
    best.0
}

/// The cost of matching hole `p` (index, column, row) to source `s` (the same); stops early
/// (returning at least `bound`) once the partial sum exceeds `bound`.
fn total_cost(
    lv: &Level,
    field: &[u32],
    cost: &Cost,
    (p, px, py): (usize, i32, i32),
    (s, sx, sy): (usize, i32, i32),
    bound: f32,
) -> f32 {
    let (w, h) = (lv.w as i32, lv.h as i32);
    // Spatial and temporal first (cheap). A neighbour's match differs from the continuation
    // `s + (n - p)` by whole pixels: 0 when it continues it (found without dividing), else at
    // least 1, which the cap `tau` (when at most 1) saturates.
    let mut spatial = 0.0f32;
    for (dx, dy) in [(-1, 0), (1, 0), (0, -1), (0, 1)] {
        let (nx, ny) = (px + dx, py + dy);
        if nx < 0 || ny < 0 || nx >= w || ny >= h {
            continue;
        }
        let n = (ny * w + nx) as usize;
        if lv.state[n] != HOLE {
            continue;
        }
        let m = field[n] as i32;
        let (cx, cy) = (sx + dx, sy + dy);
        let continues = cx >= 0 && cx < w && cy >= 0 && cy < h && m == cy * w + cx;
        if !continues {
            spatial += if cost.tau <= 1.0 {
                cost.tau
            } else {
                let (ex, ey) = ((cx - m % w) as f32, (cy - m / w) as f32);
                (ex * ex + ey * ey).min(cost.tau)
            };
        }
    }
    let mut total = cost.lambda * spatial;
    if !lv.prior_ok.is_empty() && lv.prior_ok[p] {
        let (a, b) = (lv.color[s], lv.prior[p]);
        let d = [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
        total += cost.mu * (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    }
    let labels = !lv.label.is_empty();
    if labels && lv.label[p] != lv.label[s] {
        total += cost.kappa;
    }
    if total >= bound {
        return total;
    }
    // Appearance: the mean squared difference over the patch's usable offsets. The mean is at
    // least the partial sum over the largest possible count: stop once that exceeds the bound.
    let r = cost.r;
    let mut sum = 0.0f32;
    let mut n = 0u32;
    let inv_max = 1.0 / ((2 * r + 1) * (2 * r + 1) - 1).max(1) as f32;
    // The patch's columns inside the level, and the source's columns they pair with (shift
    // `sx - px`); when those lie inside the level too (nearly always), a row is a run of
    // pairs without clamping or bounds checks, summed in the same order as the general case.
    let (tx0, tx1) = ((px - r).max(0), (px + r).min(w - 1));
    let shift = sx - px;
    let unclamped = tx0 + shift >= 0 && tx1 + shift < w;
    for dy in -r..=r {
        if total + sum * inv_max >= bound {
            return bound;
        }
        let ty = py + dy;
        if ty < 0 || ty >= h {
            continue;
        }
        let qy = (sy + dy).clamp(0, h - 1);
        let trow = (ty * w) as usize;
        let srow = (qy * w) as usize;
        if unclamped {
            let (t0, t1) = (trow + tx0 as usize, trow + tx1 as usize + 1);
            let s0 = (srow as i32 + tx0 + shift) as usize;
            let s1 = s0 + (t1 - t0);
            // The centre (`p` itself) is left out: its column in the run, on row 0 only.
            let centre = if dy == 0 {
                (px - tx0) as usize
            } else {
                usize::MAX
            };
            let pairs = lv.color[t0..t1]
                .iter()
                .zip(&lv.state[t0..t1])
                .zip(&lv.color[s0..s1])
                .enumerate();
            if labels {
                let tl = &lv.label[t0..t1];
                let sl = &lv.label[s0..s1];
                for (i, ((a, &st), b)) in pairs {
                    if i == centre || st == HIDDEN || st == UNSET {
                        continue;
                    }
                    let d = [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
                    sum += d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
                    if tl[i] != sl[i] {
                        sum += cost.kappa;
                    }
                    n += 1;
                }
            } else {
                for (i, ((a, &st), b)) in pairs {
                    if i == centre || st == HIDDEN || st == UNSET {
                        continue;
                    }
                    let d = [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
                    sum += d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
                    n += 1;
                }
            }
            continue;
        }
        for tx in tx0..=tx1 {
            let t = trow + tx as usize;
            if t == p || lv.state[t] == HIDDEN || lv.state[t] == UNSET {
                continue;
            }
            let q = srow + (tx + shift).clamp(0, w - 1) as usize;
            let (a, b) = (lv.color[t], lv.color[q]);
            let d = [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
            sum += d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
            if labels && lv.label[t] != lv.label[q] {
                sum += cost.kappa;
            }
            n += 1;
        }
    }
    if n == 0 {
        return total;
    }
    total + sum / n as f32
}
