//! Binarisation, connected components and boundary clusters for the quad search (the first
//! stages of the AprilTag detector, Olson 2011 / Wang & Olson 2016), run-length based, in bands
//! of rows on the pool's threads with the same result as one scan.
//!
//! - [`threshold`]: each pixel is compared with the midpoint of the min and max grey level of
//!   the 3x3 block of 4x4-pixel tiles around it; blocks with less contrast than
//!   `min_white_black_diff` are left undecided ([`SKIP`]). The partial tiles along the right
//!   and bottom edges use the nearest full tile and are always decided (as in the reference).
//! - [`Segmenter::segment`]: runs of equal value per row, joined by union-find: black
//!   4-connected, white 8-connected. Components under 25 pixels are ignored.
//!   Each band finds its runs and joins them alone; the seams between bands are joined after.
//! - The boundary points between every pair of adjacent black and white components (at half
//!   pixel positions, `2x + dx`), grouped per pair: the clusters the quads are fitted to. Each
//!   band collects its own, and the bands' clusters are merged in row order.

use std::ops::Range;

use rayon::prelude::*;

use crate::quad::Pt;

/// Undecided pixel (low-contrast neighbourhood).
pub(crate) const SKIP: u8 = 127;

const TILE: usize = 4;

/// Binarises `gray` (`w x h`) into `out`: 0 (black), 255 (white) or [`SKIP`].
pub(crate) fn threshold(
    gray: &[u8],
    w: usize,
    h: usize,
    min_white_black_diff: u8,
    split: f32,
    out: &mut Vec<u8>,
    scratch: &mut Vec<u8>,
) {
    let (tw, th) = (w / TILE, h / TILE);
    if tw == 0 || th == 0 {
        out.clear();
        out.resize(w * h, SKIP);
        return;
    }
    // Every pixel is written below.
    out.resize(w * h, 0);
    // Tile min/max.
    scratch.clear();
    scratch.resize(4 * tw * th, 0);
    let (tmin, rest) = scratch.split_at_mut(tw * th);
    let (tmax, rest) = rest.split_at_mut(tw * th);
    let (bmin, bmax) = rest.split_at_mut(tw * th);
    let n = tw * TILE;
    let mut colmin = vec![0u8; n];
    let mut colmax = vec![0u8; n];
    for ty in 0..th {
        let base = ty * TILE * w;
        let r0 = &gray[base..base + n];
        let r1 = &gray[base + w..base + w + n];
        let r2 = &gray[base + 2 * w..base + 2 * w + n];
        let r3 = &gray[base + 3 * w..base + 3 * w + n];
        for i in 0..n {
            let (a, b, c, d) = (r0[i], r1[i], r2[i], r3[i]);
            colmin[i] = a.min(b).min(c.min(d));
            colmax[i] = a.max(b).max(c.max(d));
        }
        let row = ty * tw..(ty + 1) * tw;
        for (t, c) in tmin[row.clone()].iter_mut().zip(colmin.chunks_exact(TILE)) {
            *t = c[0].min(c[1]).min(c[2].min(c[3]));
        }
        for (t, c) in tmax[row].iter_mut().zip(colmax.chunks_exact(TILE)) {
            *t = c[0].max(c[1]).max(c[2].max(c[3]));
        }
    }
    // 3x3 erosion / dilation over the tile grid (separable).
    let mut hmin = vec![0u8; tw * th];
    let mut hmax = vec![0u8; tw * th];
    for ty in 0..th {
        let row = ty * tw;
        for tx in 0..tw {
            let (a, b) = (tx.saturating_sub(1), (tx + 1).min(tw - 1));
            let mut mn = tmin[row + a].min(tmin[row + tx]);
            let mut mx = tmax[row + a].max(tmax[row + tx]);
            mn = mn.min(tmin[row + b]);
            mx = mx.max(tmax[row + b]);
            hmin[row + tx] = mn;
            hmax[row + tx] = mx;
        }
    }
    for ty in 0..th {
        let (a, b) = (ty.saturating_sub(1), (ty + 1).min(th - 1));
        for tx in 0..tw {
            bmin[ty * tw + tx] = hmin[a * tw + tx]
                .min(hmin[ty * tw + tx])
                .min(hmin[b * tw + tx]);
            bmax[ty * tw + tx] = hmax[a * tw + tx]
                .max(hmax[ty * tw + tx])
                .max(hmax[b * tw + tx]);
        }
    }
    // Per tile: threshold and undecided mask, expanded to a per-pixel row shared by the
    // tile row; then a branch-free compare per pixel.
    let wt = w.div_ceil(TILE) * TILE;
    let mut thr = vec![0u8; wt];
    let mut mask = vec![0u8; wt];
    let half = split == 0.5;
    for ty in 0..h.div_ceil(TILE) {
        let full_row = ty < th;
        let cty = ty.min(th - 1);
        let tiles = thr.chunks_exact_mut(TILE).zip(mask.chunks_exact_mut(TILE));
        for (tx, (tc, mc)) in tiles.enumerate() {
            let i = cty * tw + tx.min(tw - 1);
            let (mn, mx) = (bmin[i], bmax[i]);
            // Partial tiles are always decided, as in the reference implementation.
            let undecided = full_row && tx < tw && mx - mn < min_white_black_diff;
            let t = if half {
                mn + (mx - mn) / 2
            } else {
                mn + ((mx - mn) as f32 * split) as u8
            };
            tc.copy_from_slice(&[t; TILE]);
            mc.copy_from_slice(&[if undecided { 0xFF } else { 0 }; TILE]);
        }
        let (thr, mask) = (&thr[..w], &mask[..w]);
        for y in ty * TILE..((ty + 1) * TILE).min(h) {
            let src = &gray[y * w..(y + 1) * w];
            let dst = &mut out[y * w..(y + 1) * w];
            for x in 0..w {
                let white = ((src[x] > thr[x]) as u8).wrapping_neg();
                let m = mask[x];
                dst[x] = (white & !m) | (SKIP & m);
            }
        }
    }
}

#[derive(Debug, Clone, Copy)]
struct Run {
    x0: u16,
    x1: u16,
    v: u8,
}

/// Rows per band under which the segmentation does not split the image further.
const MIN_BAND_ROWS: usize = 32;

/// The runs of one band of rows and their union-find, indices local to the band.
#[derive(Default)]
struct BandRuns {
    runs: Vec<Run>,
    /// First run of each of the band's rows.
    row_start: Vec<u32>,
    parent: Vec<u32>,
    size: Vec<u32>,
}

impl BandRuns {
    /// Runs of `rows` of `bin` (`w` wide), each row's runs joined to the row above's.
    fn extract(&mut self, bin: &[u8], w: usize, rows: Range<usize>) {
        self.runs.clear();
        self.row_start.clear();
        self.parent.clear();
        self.size.clear();
        for y in rows.clone() {
            let row = &bin[y * w..(y + 1) * w];
            let start = self.runs.len();
            self.row_start.push(start as u32);
            let mut x = 0;
            while x < w {
                let v = row[x];
                let x0 = x;
                x += 1;
                // Skip quickly over long runs, 8 bytes at a time.
                let pat = u64::from_ne_bytes([v; 8]);
                while x + 8 <= w {
                    let chunk = u64::from_ne_bytes(row[x..x + 8].try_into().unwrap_or([0; 8]));
                    if chunk != pat {
                        break;
                    }
                    x += 8;
                }
                while x < w && row[x] == v {
                    x += 1;
                }
                if v != SKIP {
                    self.parent.push(self.runs.len() as u32);
                    self.runs.push(Run {
                        x0: x0 as u16,
                        x1: x as u16,
                        v,
                    });
                    self.size.push((x - x0) as u32);
                }
            }
            if y > rows.start {
                let above = self.row_start[y - rows.start - 1] as usize..start;
                let below = start..self.runs.len();
                join_rows(&self.runs, &mut self.parent, &mut self.size, above, below);
            }
        }
    }
}

/// Joins the runs of one row (`below`) to those of the row above (`above`) that touch them
/// with the same value: white diagonally too (8-connectivity), black not.
fn join_rows(
    runs: &[Run],
    parent: &mut [u32],
    size: &mut [u32],
    above: Range<usize>,
    below: Range<usize>,
) {
    let mut j = above.start;
    for i in below {
        let r = runs[i];
        let ext = (r.v == 255) as u16;
        let (a, b) = (r.x0.saturating_sub(ext), r.x1 + ext);
        while j < above.end && runs[j].x1 <= a {
            j += 1;
        }
        let mut k = j;
        while k < above.end && runs[k].x0 < b {
            if runs[k].v == r.v {
                union(parent, size, i as u32, k as u32);
            }
            k += 1;
        }
    }
}

/// Boundary points grouped per component pair, the groups in order of first appearance.
#[derive(Default)]
struct ClusterSink {
    cluster_of: std::collections::HashMap<u64, u32, BuildIdHasher>,
    keys: Vec<u64>,
    /// Boundary points per cluster (reused allocations; those from `n` on are empty).
    clusters: Vec<Vec<Pt>>,
    n: usize,
    last_key: u64,
    last_idx: usize,
}

impl ClusterSink {
    fn reset(&mut self) {
        self.cluster_of.clear();
        self.keys.clear();
        for c in &mut self.clusters[..self.n] {
            c.clear();
        }
        self.n = 0;
        self.last_key = u64::MAX;
        self.last_idx = 0;
    }

    /// The index of a new cluster for `key`.
    fn open(&mut self, key: u64) -> usize {
        let n = self.n;
        self.cluster_of.insert(key, n as u32);
        self.keys.push(key);
        if self.clusters.len() == n {
            self.clusters.push(Vec::new());
        }
        self.n += 1;
        n
    }

    /// The cluster of the component pair `(l0, l1)` (either order), opened when new.
    #[inline]
    fn cluster(&mut self, l0: u32, l1: u32) -> &mut Vec<Pt> {
        let key = if l0 < l1 {
            ((l1 as u64) << 32) | l0 as u64
        } else {
            ((l0 as u64) << 32) | l1 as u64
        };
        if key != self.last_key {
            self.last_idx = match self.cluster_of.get(&key) {
                Some(&i) => i as usize,
                None => self.open(key),
            };
            self.last_key = key;
        }
        &mut self.clusters[self.last_idx]
    }

    /// Appends the clusters of `later` (found in rows below this sink's): the points of a
    /// pair both have go after this sink's, new pairs after this sink's pairs, as one scan
    /// over all the rows would have ordered them.
    fn absorb(&mut self, later: &mut ClusterSink) {
        for i in 0..later.n {
            let key = later.keys[i];
            match self.cluster_of.get(&key) {
                Some(&j) => self.clusters[j as usize].extend_from_slice(&later.clusters[i]),
                None => {
                    let j = self.open(key);
                    std::mem::swap(&mut self.clusters[j], &mut later.clusters[i]);
                }
            }
        }
        self.last_key = u64::MAX;
    }
}

/// Reusable buffers for the connected components and clusters.
#[derive(Default)]
pub(crate) struct Segmenter {
    runs: Vec<Run>,
    row_start: Vec<u32>,
    parent: Vec<u32>,
    size: Vec<u32>,
    /// Per run: the component root, or `u32::MAX` for components under 25 pixels.
    label: Vec<u32>,
    bands: Vec<BandRuns>,
    /// The clusters (the first band's, then every band's merged into it).
    clusters: ClusterSink,
    /// The other bands' clusters before they are merged.
    band_clusters: Vec<ClusterSink>,
}

/// Multiplicative hashing for the `u64` pair keys.
#[derive(Default, Clone, Copy)]
pub(crate) struct BuildIdHasher;

pub(crate) struct IdHasher(u64);

impl std::hash::BuildHasher for BuildIdHasher {
    type Hasher = IdHasher;
    fn build_hasher(&self) -> IdHasher {
        IdHasher(0)
    }
}

impl std::hash::Hasher for IdHasher {
    fn finish(&self) -> u64 {
        self.0
    }
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 = (self.0.rotate_left(8) ^ b as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15);
        }
    }
    fn write_u64(&mut self, v: u64) {
        self.0 = (v ^ (v >> 29)).wrapping_mul(0x9E37_79B9_7F4A_7C15);
    }
}

fn find(parent: &mut [u32], mut i: u32) -> u32 {
    while parent[i as usize] != i {
        let p = parent[parent[i as usize] as usize];
        parent[i as usize] = p;
        i = p;
    }
    i
}

/// The root of `i` without path compression (for readers sharing `parent`).
fn root(parent: &[u32], mut i: u32) -> u32 {
    while parent[i as usize] != i {
        i = parent[i as usize];
    }
    i
}

fn union(parent: &mut [u32], size: &mut [u32], a: u32, b: u32) {
    let (ra, rb) = (find(parent, a), find(parent, b));
    if ra == rb {
        return;
    }
    let (big, small) = if size[ra as usize] >= size[rb as usize] {
        (ra, rb)
    } else {
        (rb, ra)
    };
    parent[small as usize] = big;
    size[big as usize] += size[small as usize];
}

/// Row `k` of `n` equal bands of `h` rows starts at.
fn band_start(h: usize, n: usize, k: usize) -> usize {
    h * k / n
}

impl Segmenter {
    /// The boundary clusters found by the last [`Segmenter::segment`].
    pub fn clusters_mut(&mut self) -> &mut [Vec<Pt>] {
        &mut self.clusters.clusters[..self.clusters.n]
    }

    /// Components of the binarised image `bin` (`w x h`) and the boundary clusters between
    /// them ([`Segmenter::clusters_mut`]), in bands of rows on the pool's threads.
    pub fn segment(&mut self, bin: &[u8], w: usize, h: usize) {
        let bands = rayon::current_num_threads().min(h / MIN_BAND_ROWS).max(1);
        self.segment_in_bands(bin, w, h, bands);
    }

    /// [`Segmenter::segment`] in `bands` bands of rows. The clusters, their order and the
    /// order of their points do not depend on `bands`: each band's runs and boundary points
    /// are found on their own, then joined across the seams in row order.
    fn segment_in_bands(&mut self, bin: &[u8], w: usize, h: usize, bands: usize) {
        let bands = bands.clamp(1, h.max(1));
        if self.bands.len() < bands {
            self.bands.resize_with(bands, BandRuns::default);
        }
        // Runs and union-find per band.
        if bands == 1 {
            self.bands[0].extract(bin, w, 0..h);
        } else {
            self.bands[..bands]
                .par_iter_mut()
                .enumerate()
                .for_each(|(k, b)| {
                    b.extract(bin, w, band_start(h, bands, k)..band_start(h, bands, k + 1))
                });
        }
        // All bands' runs in one list (the first band's by a swap), then the seams.
        let first = &mut self.bands[0];
        std::mem::swap(&mut self.runs, &mut first.runs);
        std::mem::swap(&mut self.row_start, &mut first.row_start);
        std::mem::swap(&mut self.parent, &mut first.parent);
        std::mem::swap(&mut self.size, &mut first.size);
        for b in &self.bands[1..bands] {
            let off = self.runs.len() as u32;
            self.row_start.extend(b.row_start.iter().map(|s| s + off));
            self.runs.extend_from_slice(&b.runs);
            self.parent.extend(b.parent.iter().map(|p| p + off));
            self.size.extend_from_slice(&b.size);
        }
        self.row_start.push(self.runs.len() as u32);
        for k in 1..bands {
            let y = band_start(h, bands, k);
            let rs = &self.row_start;
            let above = rs[y - 1] as usize..rs[y] as usize;
            let below = rs[y] as usize..rs[y + 1] as usize;
            join_rows(&self.runs, &mut self.parent, &mut self.size, above, below);
        }
        // Labels: component root, or none for small components.
        let (parent, size) = (&self.parent, &self.size);
        self.label.clear();
        self.label.resize(self.runs.len(), 0);
        let per_job = self.label.len().div_ceil(bands).max(1);
        self.label
            .par_chunks_mut(per_job)
            .enumerate()
            .for_each(|(c, out)| {
                for (i, l) in out.iter_mut().enumerate() {
                    let r = root(parent, (c * per_job + i) as u32);
                    *l = if size[r as usize] >= 25 { r } else { u32::MAX };
                }
            });
        // Boundary points per band, merged in row order.
        self.clusters.reset();
        if w < 3 || h < 3 {
            return;
        }
        if self.band_clusters.len() + 1 < bands {
            self.band_clusters
                .resize_with(bands - 1, ClusterSink::default);
        }
        let (runs, row_start, label) = (&self.runs, &self.row_start, &self.label);
        let source_rows =
            |k: usize| band_start(h, bands, k).max(1)..band_start(h, bands, k + 1).min(h - 1);
        if bands == 1 {
            boundary_points(
                runs,
                row_start,
                label,
                w,
                source_rows(0),
                &mut self.clusters,
            );
        } else {
            let mut sinks: Vec<&mut ClusterSink> = std::iter::once(&mut self.clusters)
                .chain(self.band_clusters.iter_mut())
                .take(bands)
                .collect();
            sinks.par_iter_mut().enumerate().for_each(|(k, sink)| {
                if k > 0 {
                    sink.reset();
                }
                boundary_points(runs, row_start, label, w, source_rows(k), sink);
            });
            for later in &mut self.band_clusters[..bands - 1] {
                self.clusters.absorb(later);
            }
        }
    }
}

/// The boundary points of the runs of `rows` (source rows, each with the row below) between
/// components of 25 pixels or more, into `sink`.
fn boundary_points(
    runs: &[Run],
    row_start: &[u32],
    label: &[u32],
    w: usize,
    rows: Range<usize>,
    sink: &mut ClusterSink,
) {
    let xmax = (w - 1) as u16; // pixels x in [1, w - 1) are sources
    for y in rows {
        let (r0, r1) = (row_start[y] as usize, row_start[y + 1] as usize);
        let (s0, s1) = (r1, row_start[y + 2] as usize);
        let mut j = s0;
        for i in r0..r1 {
            let r = runs[i];
            let l0 = label[i];
            if l0 == u32::MAX {
                continue;
            }
            let d = 255 - 2 * r.v as i16; // v1 - v0 for the opposite colour
                                          // Horizontal: the run's last pixel and the next run's first.
            if i + 1 < r1 {
                let n = runs[i + 1];
                let x = r.x1 - 1;
                if n.x0 == r.x1 && n.v != r.v && x >= 1 && x < xmax {
                    let l1 = label[i + 1];
                    if l1 != u32::MAX {
                        let p = Pt {
                            x: 2 * x + 1,
                            y: 2 * y as u16,
                            gx: d,
                            gy: 0,
                            slope: 0.0,
                        };
                        sink.cluster(l0, l1).push(p);
                    }
                }
            }
            // Row below: straight down and both diagonals.
            let (a, b) = (r.x0.max(1), r.x1.min(xmax));
            if a >= b {
                continue;
            }
            while j < s1 && runs[j].x1 < a {
                j += 1;
            }
            let mut k = j;
            while k < s1 && runs[k].x0 < b + 1 {
                let s = runs[k];
                k += 1;
                if s.v == r.v {
                    continue;
                }
                let l1 = label[k - 1];
                if l1 == u32::MAX {
                    continue;
                }
                // Source pixels x in [a, b) with x + dx in [s.x0, s.x1), each direction
                // in turn.
                let row_y = 2 * y as u16 + 1;
                let c = sink.cluster(l0, l1);
                for x in a.max(s.x0)..b.min(s.x1) {
                    c.push(Pt {
                        x: 2 * x,
                        y: row_y,
                        gx: 0,
                        gy: d,
                        slope: 0.0,
                    });
                }
                for x in a.max(s.x0 + 1)..b.min(s.x1 + 1) {
                    c.push(Pt {
                        x: 2 * x - 1,
                        y: row_y,
                        gx: -d,
                        gy: d,
                        slope: 0.0,
                    });
                }
                for x in a.max(s.x0.saturating_sub(1))..b.min(s.x1.saturating_sub(1)) {
                    c.push(Pt {
                        x: 2 * x + 1,
                        y: row_y,
                        gx: d,
                        gy: d,
                        slope: 0.0,
                    });
                }
            }
        }
    }
}

#[cfg(test)]
#[allow(clippy::needless_range_loop)]
mod tests {
    use super::*;

    /// A boundary point `(x, y, gx, gy)`, and the points of every cluster.
    type Point = (u16, u16, i16, i16);
    type PointLists = Vec<Vec<Point>>;
    use crate::{Detector, DetectorConfig, GrayImage};

    struct Rng(u64);
    impl Rng {
        fn next(&mut self) -> u8 {
            self.0 = self
                .0
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (self.0 >> 56) as u8
        }
    }

    /// The reference binarisation, pixel by pixel.
    fn threshold_naive(gray: &[u8], w: usize, h: usize, diff: u8) -> Vec<u8> {
        let (tw, th) = (w / TILE, h / TILE);
        let tile = |tx: usize, ty: usize| {
            let (mut mn, mut mx) = (255u8, 0u8);
            for y in ty * TILE..ty * TILE + TILE {
                for x in tx * TILE..tx * TILE + TILE {
                    mn = mn.min(gray[y * w + x]);
                    mx = mx.max(gray[y * w + x]);
                }
            }
            (mn, mx)
        };
        let blurred = |tx: usize, ty: usize| {
            let (mut mn, mut mx) = (255u8, 0u8);
            for y in ty.saturating_sub(1)..(ty + 2).min(th) {
                for x in tx.saturating_sub(1)..(tx + 2).min(tw) {
                    let (a, b) = tile(x, y);
                    mn = mn.min(a);
                    mx = mx.max(b);
                }
            }
            (mn, mx)
        };
        let mut out = vec![0u8; w * h];
        for y in 0..h {
            for x in 0..w {
                let full = x < tw * TILE && y < th * TILE;
                let (mn, mx) = blurred((x / TILE).min(tw - 1), (y / TILE).min(th - 1));
                out[y * w + x] = if full && mx - mn < diff {
                    SKIP
                } else if gray[y * w + x] > mn + (mx - mn) / 2 {
                    255
                } else {
                    0
                };
            }
        }
        out
    }

    #[test]
    fn threshold_matches_the_reference_definition() {
        let mut rng = Rng(3);
        for (w, h) in [(4, 4), (9, 7), (33, 18), (64, 65)] {
            let gray: Vec<u8> = (0..w * h).map(|_| rng.next() / 2 + 60).collect();
            for diff in [5, 40, 90] {
                let (mut out, mut scratch) = (Vec::new(), Vec::new());
                threshold(&gray, w, h, diff, 0.5, &mut out, &mut scratch);
                assert_eq!(
                    out,
                    threshold_naive(&gray, w, h, diff),
                    "{w}x{h}, diff {diff}"
                );
            }
        }
    }

    /// The reference clusters, pixel by pixel: union-find over pixels (black 4-connected,
    /// white 8-connected), components of 25+ pixels, boundary points from each pixel to its
    /// right, lower, lower-left and lower-right neighbours. Returned as sorted point lists.
    fn clusters_naive(bin: &[u8], w: usize, h: usize) -> PointLists {
        let mut parent: Vec<usize> = (0..w * h).collect();
        fn root(p: &mut [usize], mut i: usize) -> usize {
            while p[i] != i {
                p[i] = p[p[i]];
                i = p[i];
            }
            i
        }
        for y in 0..h {
            for x in 0..w {
                let v = bin[y * w + x];
                if v == SKIP {
                    continue;
                }
                let mut nb = vec![(x.wrapping_sub(1), y), (x, y.wrapping_sub(1))];
                if v == 255 {
                    nb.push((x.wrapping_sub(1), y.wrapping_sub(1)));
                    nb.push((x + 1, y.wrapping_sub(1)));
                }
                for (nx, ny) in nb {
                    if nx < w && ny < h && bin[ny * w + nx] == v {
                        let (a, b) = (root(&mut parent, y * w + x), root(&mut parent, ny * w + nx));
                        parent[a] = b;
                    }
                }
            }
        }
        let mut size = vec![0usize; w * h];
        for i in 0..w * h {
            if bin[i] != SKIP {
                let r = root(&mut parent, i);
                size[r] += 1;
            }
        }
        let mut map: std::collections::BTreeMap<(usize, usize), Vec<Point>> = Default::default();
        for y in 1..h - 1 {
            for x in 1..w - 1 {
                let v0 = bin[y * w + x];
                if v0 == SKIP {
                    continue;
                }
                let r0 = root(&mut parent, y * w + x);
                if size[r0] < 25 {
                    continue;
                }
                for (dx, dy) in [(1i64, 0i64), (0, 1), (-1, 1), (1, 1)] {
                    let (nx, ny) = ((x as i64 + dx) as usize, (y as i64 + dy) as usize);
                    let v1 = bin[ny * w + nx];
                    if v0 as u16 + v1 as u16 != 255 {
                        continue;
                    }
                    let r1 = root(&mut parent, ny * w + nx);
                    if size[r1] < 25 {
                        continue;
                    }
                    let d = v1 as i16 - v0 as i16;
                    map.entry((r0.min(r1), r0.max(r1))).or_default().push((
                        (2 * x as i64 + dx) as u16,
                        (2 * y as i64 + dy) as u16,
                        dx as i16 * d,
                        dy as i16 * d,
                    ));
                }
            }
        }
        let mut out: Vec<_> = map
            .into_values()
            .map(|mut v| {
                v.sort();
                v
            })
            .collect();
        out.sort();
        out
    }

    /// A binarised `w x h` image of random blocks of `cell` px, some undecided.
    fn random_blocks(rng: &mut Rng, w: usize, h: usize, cell: usize) -> Vec<u8> {
        let (bw, bh) = (w.div_ceil(cell), h.div_ceil(cell));
        let blocks: Vec<u8> = (0..bw * bh)
            .map(|_| match rng.next() % 7 {
                0 => SKIP,
                1..=3 => 0,
                _ => 255,
            })
            .collect();
        (0..w * h)
            .map(|i| blocks[(i / w / cell) * bw + (i % w) / cell])
            .collect()
    }

    #[test]
    fn clusters_match_the_reference_definition() {
        let mut rng = Rng(11);
        let mut seg = Segmenter::default();
        for (w, h) in [(40usize, 30usize), (64, 64), (97, 53)] {
            for cell in [1usize, 2, 3, 5] {
                let bin = random_blocks(&mut rng, w, h, cell);
                seg.segment_in_bands(&bin, w, h, 3);
                let mut ours: PointLists = seg
                    .clusters_mut()
                    .iter()
                    .map(|c| {
                        let mut v: Vec<_> = c.iter().map(|p| (p.x, p.y, p.gx, p.gy)).collect();
                        v.sort();
                        v
                    })
                    .collect();
                ours.sort();
                assert_eq!(ours, clusters_naive(&bin, w, h), "{w}x{h}, cell {cell}");
            }
        }
    }

    /// Every cluster's points, in the segmenter's order (clusters and points unsorted).
    fn clusters_in_order(seg: &mut Segmenter) -> PointLists {
        seg.clusters_mut()
            .iter()
            .map(|c| c.iter().map(|p| (p.x, p.y, p.gx, p.gy)).collect())
            .collect()
    }

    #[test]
    fn bands_give_the_clusters_of_one_scan_in_the_same_order() {
        let mut rng = Rng(23);
        let (mut one, mut banded) = (Segmenter::default(), Segmenter::default());
        for (w, h) in [(64usize, 48usize), (97, 131), (200, 37)] {
            for cell in [1usize, 2, 4] {
                // With a black ring across every seam, so that components span bands.
                let mut bin = random_blocks(&mut rng, w, h, cell);
                for (i, v) in bin.iter_mut().enumerate() {
                    let (x, y) = (i % w, i / w);
                    if x == 3 || x == w - 4 || y == 3 || y == h - 4 {
                        *v = 0;
                    }
                }
                one.segment_in_bands(&bin, w, h, 1);
                let reference = clusters_in_order(&mut one);
                assert!(
                    reference.len() > 3,
                    "{w}x{h}, cell {cell}: too few clusters"
                );
                for bands in [2, 3, 5, h] {
                    banded.segment_in_bands(&bin, w, h, bands);
                    let ours = clusters_in_order(&mut banded);
                    assert_eq!(ours, reference, "{w}x{h}, cell {cell}, {bands} bands");
                }
            }
        }
    }

    #[test]
    fn odd_sizes_and_noise_do_not_panic() {
        let mut rng = Rng(7);
        let mut det = Detector::new(DetectorConfig::c_reference().thorough()).expect("detector");
        for (w, h) in [(8, 8), (9, 1000), (1000, 9), (31, 17), (64, 48), (257, 129)] {
            let noise: Vec<u8> = (0..w * h).map(|_| rng.next()).collect();
            let blocks: Vec<u8> = (0..w * h)
                .map(|i| {
                    if (i % w / 3 + i / w / 3) % 2 == 0 {
                        0
                    } else {
                        255
                    }
                })
                .collect();
            for data in [noise, blocks, vec![0; w * h], vec![255; w * h]] {
                let img = GrayImage::new(w as u32, h as u32, data).expect("image");
                det.detect(&img).expect("detect");
            }
        }
    }
}
