//! The patch fill's image pyramid over the work region: colours, the state of every pixel
//! (known source, hole to fill, hidden), the prior colours, and the coarsest level's
//! onion-peel start.

use rayon::prelude::*;

use crate::plate::Homography;
use crate::types::{ImageRgba8, Mask, Rect};

use super::PatchPrior;

/// A known pixel: a source, never written.
pub(super) const KNOWN: u8 = 0;
/// A pixel to fill.
pub(super) const HOLE: u8 = 1;
/// A pixel neither read nor written (the twin will cover it).
pub(super) const HIDDEN: u8 = 2;
/// A hole not matched yet (during the coarsest level's first pass): not read either.
pub(super) const UNSET: u8 = 3;
/// A hole not matched yet but with a prior colour (during the coarsest level's first pass):
/// its colour (the prior) is read by the appearance term, its match is not.
pub(super) const PRIOR: u8 = 4;

/// One level of the pyramid (row-major, `w x h`).
#[derive(Debug, Default, Clone)]
pub(super) struct Level {
    pub w: usize,
    pub h: usize,
    /// RGB in [0, 255]; holes hold the current fill.
    pub color: Vec<[f32; 3]>,
    pub state: Vec<u8>,
    /// The prior colour of each pixel (valid where `prior_ok`; both empty without a prior).
    pub prior: Vec<[f32; 3]>,
    pub prior_ok: Vec<bool>,
    /// The surface label of each pixel (empty without a surface map).
    pub label: Vec<u8>,
    /// Number of known pixels.
    pub known: usize,
    /// Indices of the known pixels (the coarsest level only; empty on the others).
    pub sources: Vec<u32>,
    /// Indices of the holes, in raster order.
    pub holes: Vec<u32>,
    /// Indices of the holes ring by ring from the known pixels inwards ([`onion_peel`]).
    pub order: Vec<u32>,
}

impl Level {
    /// Sizes the level to `w` x `h`: every pixel known and black, no holes, no labels; a prior
    /// of nothing when `with_prior`.
    fn reset(&mut self, w: usize, h: usize, with_prior: bool) {
        self.color.clear();
        self.state.clear();
        self.resize_for_overwrite(w, h, with_prior);
    }

    /// As [`Level::reset`], but the colours and states of the pixels the level already had
    /// are left as they were: for a caller that writes them all.
    fn resize_for_overwrite(&mut self, w: usize, h: usize, with_prior: bool) {
        self.w = w;
        self.h = h;
        self.color.resize(w * h, [0.0; 3]);
        self.state.resize(w * h, KNOWN);
        self.prior.clear();
        self.prior_ok.clear();
        if with_prior {
            self.prior.resize(w * h, [0.0; 3]);
            self.prior_ok.resize(w * h, false);
        }
        self.label.clear();
        self.sources.clear();
        self.holes.clear();
    }

    fn index(&mut self) {
        self.sources.clear();
        self.holes.clear();
        self.known = 0;
        for (i, &s) in self.state.iter().enumerate() {
            match s {
                KNOWN => self.known += 1,
                HOLE => self.holes.push(i as u32),
                _ => {}
            }
        }
    }

    /// Fills `sources` (used by the coarsest level's random start).
    fn collect_sources(&mut self) {
        self.sources.clear();
        self.sources.extend(
            self.state
                .iter()
                .enumerate()
                .filter(|(_, &s)| s == KNOWN)
                .map(|(i, _)| i as u32),
        );
    }

    /// The larger side of the holes' bounding box (0 without holes).
    fn hole_extent(&self) -> usize {
        let (mut x0, mut y0, mut x1, mut y1) = (usize::MAX, usize::MAX, 0, 0);
        for &p in &self.holes {
            let (x, y) = (p as usize % self.w, p as usize / self.w);
            x0 = x0.min(x);
            x1 = x1.max(x);
            y0 = y0.min(y);
            y1 = y1.max(y);
        }
        if self.holes.is_empty() {
            0
        } else {
            (x1 - x0 + 1).max(y1 - y0 + 1)
        }
    }
}

/// Builds the pyramid of `region` of `frame` into `levels` (level 0 the finest): the state of a
/// local pixel comes from `state`; a coarse pixel is a hole if any of its 2x2 children is,
/// else hidden if any child is, else known (its colour the children's mean). Levels are added
/// while the holes' box is larger than `coarsest_px` and the level larger than 8 x 8. The
/// prior is sampled on level `prior_level` (or the coarsest, if there are fewer levels) and
/// averaged down from there. The surface labels (from `surfaces`, if given) go down as the
/// most frequent of the 2x2 children's.
#[allow(clippy::too_many_arguments)]
pub(super) fn build(
    levels: &mut Vec<Level>,
    frame: &ImageRgba8,
    region: Rect,
    state: impl Fn(usize, usize) -> u8 + Sync,
    prior: Option<(&PatchPrior<'_>, &Homography)>,
    surfaces: Option<&Mask>,
    prior_level: usize,
    coarsest_px: u32,
) {
    let (w, h) = (region.width as usize, region.height as usize);
    if levels.is_empty() {
        levels.push(Level::default());
    }
    let l0 = &mut levels[0];
    // Every state and colour is written below.
    l0.resize_for_overwrite(w, h, false);
    let stride = frame.width() as usize * 4;
    let data = frame.as_slice();
    let (x0, y0) = (region.x as usize, region.y as usize);
    // Rows in parallel: the states and the known colours, then the holes' prior colours.
    l0.state
        .par_chunks_mut(w)
        .zip(l0.color.par_chunks_mut(w))
        .enumerate()
        .for_each(|(ly, (states, colors))| {
            let row = &data[(y0 + ly) * stride + x0 * 4..(y0 + ly) * stride + (x0 + w) * 4];
            for (lx, ((st, c), px)) in states
                .iter_mut()
                .zip(colors.iter_mut())
                .zip(row.chunks_exact(4))
                .enumerate()
            {
                *st = state(lx, ly);
                *c = if *st == KNOWN {
                    [f32::from(px[0]), f32::from(px[1]), f32::from(px[2])]
                } else {
                    [0.0; 3]
                };
            }
        });
    l0.index();
    if let Some(m) = surfaces {
        let mw = m.width() as usize;
        let md = m.as_slice();
        for ly in 0..h {
            let row = (y0 + ly) * mw + x0;
            l0.label.extend_from_slice(&md[row..row + w]);
        }
    }
    if prior_level == 0 {
        if let Some((p, hom)) = prior {
            sample_level_prior(&mut levels[0], 0, region, p, hom);
        }
    }
    let mut n = 1;
    while {
        let last = &levels[n - 1];
        last.hole_extent() > coarsest_px as usize && last.w > 8 && last.h > 8
    } {
        if levels.len() <= n {
            levels.push(Level::default());
        }
        let (fine, coarse) = levels.split_at_mut(n);
        downsample(&fine[n - 1], &mut coarse[0]);
        if coarse[0].known == 0 {
            // Every coarse pixel touches the hole: stop at the finer level.
            break;
        }
        if n == prior_level {
            if let Some((p, hom)) = prior {
                sample_level_prior(&mut coarse[0], n, region, p, hom);
            }
        }
        n += 1;
    }
    levels.truncate(n);
    if let Some(last) = levels.last_mut() {
        last.collect_sources();
    }
    // The pyramid stopped below the prior's level: the prior goes on the coarsest level.
    if prior_level >= n {
        if let (Some((p, hom)), Some(last)) = (prior, levels.last_mut()) {
            sample_level_prior(last, n - 1, region, p, hom);
        }
    }
}

/// Samples the prior for the holes of `lv`, level `level` of the pyramid over `region` (each
/// pixel at the centre of the full-resolution pixels it covers); rows in parallel.
pub(super) fn sample_level_prior(
    lv: &mut Level,
    level: usize,
    region: Rect,
    p: &PatchPrior<'_>,
    hom: &Homography,
) {
    let w = lv.w;
    lv.prior.clear();
    lv.prior.resize(w * lv.h, [0.0; 3]);
    lv.prior_ok.clear();
    lv.prior_ok.resize(w * lv.h, false);
    let scale = (1usize << level) as f64;
    let (x0, y0) = (f64::from(region.x), f64::from(region.y));
    let centre = |i: usize, o: f64| o + scale * (i as f64 + 0.5) - 0.5;
    lv.prior
        .par_chunks_mut(w)
        .zip(lv.prior_ok.par_chunks_mut(w))
        .zip(lv.state.par_chunks(w))
        .enumerate()
        .for_each(|(ly, ((prior, ok), states))| {
            for (lx, st) in states.iter().enumerate() {
                if *st == HOLE {
                    if let Some(c) = sample_prior(p, hom, centre(lx, x0), centre(ly, y0)) {
                        prior[lx] = c;
                        ok[lx] = true;
                    }
                }
            }
        });
}

fn downsample(fine: &Level, coarse: &mut Level) {
    let (w, h) = (fine.w.div_ceil(2), fine.h.div_ceil(2));
    let with_prior = !fine.prior.is_empty();
    coarse.reset(w, h, with_prior);
    // The 2x2 children of coarse pixel (x, y) inside the fine level, row by row.
    let children = |x: usize, y: usize| {
        let (fw, i) = (fine.w, 2 * y * fine.w + 2 * x);
        let (right, below) = (2 * x + 1 < fw, 2 * y + 1 < fine.h);
        let mut c = [i, i + 1, i + fw, i + fw + 1];
        let n = match (right, below) {
            (true, true) => 4,
            (true, false) => 2,
            (false, true) => {
                c[1] = i + fw;
                2
            }
            (false, false) => 1,
        };
        ChildList { c, n, k: 0 }
    };
    // Rows in parallel.
    coarse
        .state
        .par_chunks_mut(w)
        .zip(coarse.color.par_chunks_mut(w))
        .enumerate()
        .for_each(|(y, (states, colors))| {
            for (x, (st, col)) in states.iter_mut().zip(colors.iter_mut()).enumerate() {
                let (mut any_hole, mut any_hidden) = (false, false);
                let mut sum = [0.0f32; 3];
                let mut n = 0.0f32;
                for c in children(x, y) {
                    match fine.state[c] {
                        HOLE => any_hole = true,
                        HIDDEN => any_hidden = true,
                        _ => {
                            add(&mut sum, fine.color[c]);
                            n += 1.0;
                        }
                    }
                }
                *st = if any_hole {
                    HOLE
                } else if any_hidden {
                    HIDDEN
                } else {
                    KNOWN
                };
                if *st == KNOWN && n > 0.0 {
                    *col = sum.map(|v| v / n);
                }
            }
        });
    if !fine.label.is_empty() {
        coarse.label.resize(w * h, 0);
        coarse
            .label
            .par_chunks_mut(w)
            .enumerate()
            .for_each(|(y, labels)| {
                for (x, out) in labels.iter_mut().enumerate() {
                    let mut ls = [0u8; 4];
                    let mut n = 0;
                    for c in children(x, y) {
                        ls[n] = fine.label[c];
                        n += 1;
                    }
                    *out = most_frequent(&ls[..n]);
                }
            });
    }
    if with_prior {
        coarse
            .prior
            .par_chunks_mut(w)
            .zip(coarse.prior_ok.par_chunks_mut(w))
            .zip(coarse.state.par_chunks(w))
            .enumerate()
            .for_each(|(y, ((prior, ok), states))| {
                for (x, st) in states.iter().enumerate() {
                    if *st != HOLE {
                        continue;
                    }
                    let mut psum = [0.0f32; 3];
                    let mut pn = 0.0f32;
                    for c in children(x, y) {
                        if fine.prior_ok[c] {
                            add(&mut psum, fine.prior[c]);
                            pn += 1.0;
                        }
                    }
                    if pn > 0.0 {
                        prior[x] = psum.map(|v| v / pn);
                        ok[x] = true;
                    }
                }
            });
    }
    coarse.index();
}

/// Up to 4 pixel indices (a coarse pixel's children), iterated in order.
struct ChildList {
    c: [usize; 4],
    n: usize,
    k: usize,
}

impl Iterator for ChildList {
    type Item = usize;
    #[inline]
    fn next(&mut self) -> Option<usize> {
        (self.k < self.n).then(|| {
            self.k += 1;
            self.c[self.k - 1]
        })
    }
}

/// The most frequent of 1 to 4 labels (ties: the first's).
fn most_frequent(ls: &[u8]) -> u8 {
    // Nearly always: one surface.
    if ls.iter().all(|&b| b == ls[0]) {
        return ls[0];
    }
    let mut best = ls[0];
    let mut best_n = 0;
    for &a in ls {
        let k = ls.iter().filter(|&&b| b == a).count();
        if k > best_n {
            best = a;
            best_n = k;
        }
    }
    best
}

/// The prior's colour at current-frame pixel `(x, y)`: the previous image bilinearly sampled at
/// the warped position, when all four samples lie inside it and none was hidden there.
pub(super) fn sample_prior(
    p: &PatchPrior<'_>,
    prior_from_current: &Homography,
    x: f64,
    y: f64,
) -> Option<[f32; 3]> {
    let [qx, qy] = prior_from_current.apply([x, y])?;
    let (w, h) = p.image.size();
    if !(qx >= 0.0 && qy >= 0.0 && qx <= f64::from(w - 1) && qy <= f64::from(h - 1)) {
        return None;
    }
    let (x0, y0) = (qx.floor() as usize, qy.floor() as usize);
    let (x1, y1) = ((x0 + 1).min(w as usize - 1), (y0 + 1).min(h as usize - 1));
    let (fx, fy) = ((qx - x0 as f64) as f32, (qy - y0 as f64) as f32);
    let m = p.mask.as_slice();
    let wu = w as usize;
    if [(x0, y0), (x1, y0), (x0, y1), (x1, y1)]
        .iter()
        .any(|&(a, b)| m[b * wu + a] == Mask::HIDDEN)
    {
        return None;
    }
    let d = p.image.as_slice();
    let px = |a: usize, b: usize, c: usize| f32::from(d[(b * wu + a) * 4 + c]);
    let mut out = [0.0f32; 3];
    for (c, o) in out.iter_mut().enumerate() {
        let top = px(x0, y0, c) * (1.0 - fx) + px(x1, y0, c) * fx;
        let bot = px(x0, y1, c) * (1.0 - fx) + px(x1, y1, c) * fx;
        *o = top * (1.0 - fy) + bot * fy;
    }
    Some(out)
}

/// Orders the holes of `lv` ring by ring from the known pixels inwards (8-connected) into
/// `lv.order`, and gives each a first colour: its prior where it has one, else the mean of its
/// 8-neighbours coloured in earlier rings. Returns false when some holes cannot be reached (cut
/// off by hidden pixels or without known pixels).
pub(super) fn onion_peel(lv: &mut Level) -> bool {
    let (w, h) = (lv.w, lv.h);
    let mut done: Vec<bool> = lv.state.iter().map(|&s| s == KNOWN).collect();
    let mut left: Vec<u32> = lv.holes.clone();
    lv.order.clear();
    let mut ring: Vec<(u32, [f32; 3])> = Vec::new();
    while !left.is_empty() {
        ring.clear();
        left.retain(|&p| {
            let p = p as usize;
            let (x, y) = (p % w, p / w);
            let mut sum = [0.0f32; 3];
            let mut n = 0.0f32;
            for ny in y.saturating_sub(1)..(y + 2).min(h) {
                for nx in x.saturating_sub(1)..(x + 2).min(w) {
                    let q = ny * w + nx;
                    if done[q] {
                        add(&mut sum, lv.color[q]);
                        n += 1.0;
                    }
                }
            }
            if n > 0.0 {
                ring.push((p as u32, sum.map(|v| v / n)));
                false
            } else {
                true
            }
        });
        if ring.is_empty() {
            return false;
        }
        for &(p, c) in &ring {
            let p = p as usize;
            lv.color[p] = if !lv.prior_ok.is_empty() && lv.prior_ok[p] {
                lv.prior[p]
            } else {
                c
            };
            done[p] = true;
            lv.order.push(p as u32);
        }
    }
    true
}

/// `acc += c`, per channel.
pub(super) fn add(acc: &mut [f32; 3], c: [f32; 3]) {
    for (a, v) in acc.iter_mut().zip(c) {
        *a += v;
    }
}
