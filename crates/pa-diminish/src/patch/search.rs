//! PatchMatch over the pyramid: the nearest-neighbour field of every level's holes, coarse to
//! fine, with the PixMix cost (appearance + spatial + temporal).

use super::pyramid::{add, Level, HIDDEN, HOLE, KNOWN, UNSET};
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
}

/// Runs PatchMatch on every level, coarsest first; on return every hole of level 0 holds the
/// colour of its match. `nnf[l]` is level `l`'s field (one source index a pixel; holes only).
pub(super) fn solve(
    levels: &mut [Level],
    nnf: &mut Vec<Vec<u32>>,
    votes: &mut Vec<[f32; 3]>,
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
        let search_r = if coarsest { lv.w.max(lv.h) as i32 } else { 4 };
        for it in 0..sweeps {
            sweep(lv, field, &cost, it % 2 == 1, search_r, &mut rng);
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
    let (w, h) = (lv.w as i32, lv.h as i32);
    out.clear();
    for &p in &lv.holes {
        let p = p as usize;
        let (px, py) = ((p % lv.w) as i32, (p / lv.w) as i32);
        let mut sum = [0.0f32; 3];
        let mut n = 0.0f32;
        for dy in -r..=r {
            for dx in -r..=r {
                let (qx, qy) = (px + dx, py + dy);
                if qx < 0 || qy < 0 || qx >= w || qy >= h {
                    continue;
                }
                let q = (qy * w + qx) as usize;
                if lv.state[q] != HOLE {
                    continue;
                }
                let m = field[q] as i32;
                let (sx, sy) = (m % w - dx, m / w - dy);
                if sx < 0 || sy < 0 || sx >= w || sy >= h {
                    continue;
                }
                let s = (sy * w + sx) as usize;
                if lv.state[s] != KNOWN {
                    continue;
                }
                add(&mut sum, lv.color[s]);
                n += 1.0;
            }
        }
        out.push(if n > 0.0 {
            sum.map(|v| v / n)
        } else {
            lv.color[p]
        });
    }
    for (&p, c) in lv.holes.iter().zip(out.iter()) {
        lv.color[p as usize] = *c;
    }
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
        lv.state[p as usize] = UNSET;
    }
    let order = std::mem::take(&mut lv.order);
    for &p in &order {
        let p = p as usize;
        let (px, py) = ((p % lv.w) as i32, (p / lv.w) as i32);
        let mut best = lv.sources[rng.below(lv.sources.len())] as usize;
        let mut best_cost = total_cost(lv, field, cost, p, best, f32::INFINITY);
        let consider = |lv: &Level, s: usize, best: &mut usize, best_cost: &mut f32| {
            if s != *best && lv.state[s] == KNOWN {
                let c = total_cost(lv, field, cost, p, s, *best_cost);
                if c < *best_cost {
                    *best = s;
                    *best_cost = c;
                }
            }
        };
        for dy in -1..=1 {
            for dx in -1..=1 {
                let (nx, ny) = (px + dx, py + dy);
                if (dx, dy) == (0, 0) || nx < 0 || ny < 0 || nx >= w || ny >= h {
                    continue;
                }
                let n = (ny * w + nx) as usize;
                if lv.state[n] != HOLE {
                    continue;
                }
                let m = field[n] as i32;
                let (sx, sy) = (m % w - dx, m / w - dy);
                if sx >= 0 && sy >= 0 && sx < w && sy < h {
                    consider(lv, (sy * w + sx) as usize, &mut best, &mut best_cost);
                }
            }
        }
        for _ in 0..START_RANDOM {
            let s = lv.sources[rng.below(lv.sources.len())] as usize;
            consider(lv, s, &mut best, &mut best_cost);
        }
        let mut r = lv.w.max(lv.h) as i32 / 2;
        while r >= 1 {
            let (bx, by) = ((best % lv.w) as i32, (best / lv.w) as i32);
            let sx = (bx + rng.offset(r)).clamp(0, w - 1);
            let sy = (by + rng.offset(r)).clamp(0, h - 1);
            consider(lv, (sy * w + sx) as usize, &mut best, &mut best_cost);
            r /= 2;
        }
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
            None => lv.sources[rng.below(lv.sources.len())] as usize,
        };
        field[p] = s as u32;
        lv.color[p] = lv.color[s];
    }
}

/// One PatchMatch sweep over the holes (forward, or backward with `reverse`).
fn sweep(
    lv: &mut Level,
    field: &mut [u32],
    cost: &Cost,
    reverse: bool,
    search_r: i32,
    rng: &mut Rng,
) {
    let (w, h) = (lv.w as i32, lv.h as i32);
    let nh = lv.holes.len();
    let d: i32 = if reverse { 1 } else { -1 };
    for k in 0..nh {
        let p = lv.holes[if reverse { nh - 1 - k } else { k }] as usize;
        let (px, py) = ((p % lv.w) as i32, (p / lv.w) as i32);
        let mut best = field[p] as usize;
        let mut best_cost = total_cost(lv, field, cost, p, best, f32::INFINITY);
        // Propagation from the neighbours visited before p in this sweep.
        for (nx, ny) in [(px + d, py), (px, py + d)] {
            if nx < 0 || ny < 0 || nx >= w || ny >= h {
                continue;
            }
            let n = (ny * w + nx) as usize;
            if lv.state[n] != HOLE {
                continue;
            }
            let m = field[n] as i32;
            let (sx, sy) = (m % w - (nx - px), m / w - (ny - py));
            if sx < 0 || sy < 0 || sx >= w || sy >= h {
                continue;
            }
            let s = (sy * w + sx) as usize;
            if s == best || lv.state[s] != KNOWN {
                continue;
            }
            let c = total_cost(lv, field, cost, p, s, best_cost);
            if c < best_cost {
                best = s;
                best_cost = c;
            }
        }
        // Random search around the best match, halving the radius.
        let mut r = search_r;
        while r >= 1 {
            let (bx, by) = ((best % lv.w) as i32, (best / lv.w) as i32);
            let sx = (bx + rng.offset(r)).clamp(0, w - 1);
            let sy = (by + rng.offset(r)).clamp(0, h - 1);
            let s = (sy * w + sx) as usize;
            if s != best && lv.state[s] == KNOWN {
                let c = total_cost(lv, field, cost, p, s, best_cost);
                if c < best_cost {
                    best = s;
                    best_cost = c;
                }
            }
            r /= 2;
        }
        field[p] = best as u32;
        lv.color[p] = lv.color[best];
    }
}

/// The cost of matching hole `p` to source `s`; stops early (returning at least `bound`) once
/// the partial sum exceeds `bound`.
fn total_cost(lv: &Level, field: &[u32], cost: &Cost, p: usize, s: usize, bound: f32) -> f32 {
    let (w, h) = (lv.w as i32, lv.h as i32);
    let (px, py) = ((p % lv.w) as i32, (p / lv.w) as i32);
    let (sx, sy) = ((s % lv.w) as i32, (s / lv.w) as i32);
    // Spatial and temporal first (cheap).
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
        let (ex, ey) = ((sx + dx - m % w) as f32, (sy + dy - m / w) as f32);
        spatial += (ex * ex + ey * ey).min(cost.tau);
    }
    let mut total = cost.lambda * spatial;
    if !lv.prior_ok.is_empty() && lv.prior_ok[p] {
        let (a, b) = (lv.color[s], lv.prior[p]);
        let d = [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
        total += cost.mu * (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    }
    if total >= bound {
        return total;
    }
    // Appearance: the mean squared difference over the patch's usable offsets.
    let r = cost.r;
    let mut sum = 0.0f32;
    let mut n = 0u32;
    for dy in -r..=r {
        let ty = py + dy;
        if ty < 0 || ty >= h {
            continue;
        }
        let qy = (sy + dy).clamp(0, h - 1);
        let trow = (ty * w) as usize;
        let srow = (qy * w) as usize;
        for dx in -r..=r {
            let tx = px + dx;
            if tx < 0 || tx >= w {
                continue;
            }
            let t = trow + tx as usize;
            if t == p || lv.state[t] == HIDDEN || lv.state[t] == UNSET {
                continue;
            }
            let q = srow + (sx + dx).clamp(0, w - 1) as usize;
            let (a, b) = (lv.color[t], lv.color[q]);
            let d = [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
            sum += d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
            n += 1;
        }
    }
    if n == 0 {
        return total;
    }
    total + sum / n as f32
}
