//! The board's surfaces in the image, for the patch fill's surface term
//! ([`pa_diminish::PatchFill::surfaces`]): every pixel of the fill's work region is labelled
//! with what it shows, from the board pose: the table ([`TABLE`]), the printed sheet
//! ([`SHEET`]) or a tag ([`TAG`]: its projected quad grown by [`TAG_GROW_PX`], so that the
//! blurred rim of the black border counts as tag too). The patch fill then copies sheet into
//! sheet, table into table, and no tag fragment into the white paper.

use glam::{DVec2, DVec3, Mat4};
use pa_camera::CameraModel;
use pa_diminish::{Mask, Rect};
use pa_track::Board;
use rayon::prelude::*;

use super::ArPipeline;

impl ArPipeline {
    /// The board's surfaces for the patch fill's surface term (none: no surface term).
    pub fn set_board_surfaces(&mut self, surfaces: Option<BoardSurfaces>) {
        self.surfaces = surfaces.map(|s| (s, None));
    }
}

/// The label map of `surfaces` over `rect` in a view of the board from `camera_from_marker`,
/// in the buffer `buf` (made or remade at the frame's size); pixels outside `rect` hold
/// stale labels.
pub(super) fn surface_labels<'a>(
    surfaces: &BoardSurfaces,
    buf: &'a mut Option<Mask>,
    camera: &CameraModel,
    camera_from_marker: Mat4,
    (width, height): (u32, u32),
    rect: Rect,
) -> Option<&'a Mask> {
    if buf.as_ref().map(Mask::size) != Some((width, height)) {
        *buf = Some(Mask::zeros(width, height).ok()?);
    }
    let m = buf.as_mut()?;
    surfaces.label(camera, camera_from_marker, rect, m);
    Some(m)
}

/// The label of the table (everything off the sheet).
pub const TABLE: u8 = 0;
/// The label of the printed sheet around the tags.
pub const SHEET: u8 = 1;
/// The label of a tag (with its grown rim).
pub const TAG: u8 = 2;
/// Tags' quads are grown by this many pixels.
pub const TAG_GROW_PX: f64 = 1.5;
/// Known pixels of each kind (black, white) needed to measure a frame's tag levels.
pub const MIN_LEVEL_SAMPLES: usize = 12;
/// The tag levels are measured on every `LEVEL_STRIDE`-th pixel of every `LEVEL_STRIDE`-th
/// row of the work region, or on a coarser grid of about [`LEVEL_GRID_POINTS`] points when
/// the region is larger.
pub const LEVEL_STRIDE: usize = 2;
/// Grid points of the level measurement at most (about): a mean over hundreds of known tag
/// pixels is as good as one over thousands, and the back-projections are the painting's
/// main cost (the ray fill's tags at 1280x720: 1.2 ms with every other pixel).
pub const LEVEL_GRID_POINTS: usize = 4096;

/// The board's printed surfaces on the marker plane (z = 0, marker frame, metres).
#[derive(Debug, Clone, PartialEq)]
pub struct BoardSurfaces {
    /// The sheet's corners (a convex quad), if its outline is known.
    pub sheet: Option<[DVec3; 4]>,
    /// Every tag's corners.
    pub tags: Vec<[DVec3; 4]>,
    /// Every tag's printed pattern (tags of an unknown id are left out).
    prints: Vec<TagPrint>,
}

/// A tag's printed pattern on the marker plane.
#[derive(Debug, Clone, PartialEq)]
struct TagPrint {
    center: DVec2,
    /// (cos, sin) of its in-plane rotation.
    rot: (f64, f64),
    /// Metres a cell.
    cell_m: f64,
    /// Cells across the whole pattern (the white ring included).
    total: u32,
    /// One byte a cell, row-major: 0 black, 255 white.
    cells: Vec<u8>,
    /// Half the pattern's diagonal and a little more (metres): no point farther from the
    /// centre along x or y lies on the pattern.
    reach_m: f64,
}

impl TagPrint {
    /// Whether the print is white at marker point `p` (the white ring and beyond: white).
    fn white_at(&self, p: DVec2) -> bool {
        let d = p - self.center;
        // Beyond the pattern's circumscribed square: white (the cheap test first).
        if d.x.abs() > self.reach_m || d.y.abs() > self.reach_m {
            return true;
        }
        let (c, s) = self.rot;
        // Into the tag's own axes (rotate by -rotation).
        let (u, v) = (c * d.x + s * d.y, -s * d.x + c * d.y);
        let off = 0.5 * f64::from(self.total);
        let (cu, cv) = (u / self.cell_m + off, v / self.cell_m + off);
        let n = f64::from(self.total);
        // Outside [0, n): white. Inside, truncation is the floor (no libm call on baseline
        // x86-64).
        if !(cu >= 0.0 && cv >= 0.0 && cu < n && cv < n) {
            return true;
        }
        self.cells[cv as usize * self.total as usize + cu as usize] != 0
    }
}

/// Which tag pixels of a fill mask [`BoardSurfaces::paint_tags`] redraws.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PaintTags {
    /// The set pixels: those the fill would invent.
    Set,
    /// The hidden ones too (under the twin's opaque interior). The ray fill's rays then stop
    /// at the print there whether or not those pixels are hidden, so keeping the passes
    /// (which hides nothing) leaves the composite unchanged.
    SetAndHidden,
}

impl PaintTags {
    fn paints(self, f: u8) -> bool {
        f == Mask::SET || (self == PaintTags::SetAndHidden && f == Mask::HIDDEN)
    }
}

impl BoardSurfaces {
    /// The tags of `board`, and a square sheet of side `sheet_side_m` centred on the marker's
    /// origin (where the generated and the Blender sets print it), if given.
    pub fn new(board: &Board, sheet_side_m: Option<f64>) -> Self {
        let sheet = sheet_side_m.map(|s| {
            let h = 0.5 * s;
            [
                DVec3::new(-h, -h, 0.0),
                DVec3::new(h, -h, 0.0),
                DVec3::new(h, h, 0.0),
                DVec3::new(-h, h, 0.0),
            ]
        });
        let prints = match pa_track::family_layout(board.family) {
            Ok(layout) => board
                .tags
                .iter()
                .filter_map(|t| {
                    let cells = pa_track::marker_cells(board.family, t.id).ok()?;
                    let cell_m = t.size_m / f64::from(layout.border_cells.max(1));
                    Some(TagPrint {
                        center: t.center_m,
                        rot: (t.rotation_rad.cos(), t.rotation_rad.sin()),
                        cell_m,
                        total: cells.width,
                        cells: cells.data,
                        reach_m: 0.5
                            * std::f64::consts::SQRT_2
                            * cell_m
                            * f64::from(cells.width)
                            * 1.001,
                    })
                })
                .collect(),
            Err(_) => Vec::new(),
        };
        Self {
            sheet,
            tags: board.tags.iter().map(|t| t.object_points()).collect(),
            prints,
        }
    }

    /// Whether [`BoardSurfaces::paint_tags`] would paint anything: a pixel of `fill` in
    /// `rect` to paint ([`PaintTags`]) where `labels` shows a tag, on a board with tags.
    pub fn has_tags_to_paint(
        &self,
        rect: Rect,
        labels: &Mask,
        fill: &Mask,
        which: PaintTags,
    ) -> bool {
        let w = fill.width() as usize;
        let (x0, x1) = (rect.x as usize, (rect.x + rect.width) as usize);
        let (lab, f) = (labels.as_slice(), fill.as_slice());
        !self.prints.is_empty()
            && (rect.y as usize..(rect.y + rect.height) as usize)
                .any(|y| (y * w + x0..y * w + x1).any(|i| lab[i] == TAG && which.paints(f[i])))
    }

    /// Paints the board's known print into the pixels of `fill` that `which` names and that
    /// show a tag (`labels` == [`TAG`]) in `rect`, and clears them in `fill`: a covered tag is
    /// redrawn from its pattern, not invented. Each pixel is the mean of 2x2 samples of the
    /// pattern (back-projected onto the marker plane), mapped to this frame's black and white
    /// as measured on the known pixels of the tags in `rect` (mean colour of the known tag
    /// pixels the pattern says are black, and of those it says are white, each at least
    /// [`MIN_LEVEL_SAMPLES`], on a grid of step [`LEVEL_STRIDE`] or of about
    /// [`LEVEL_GRID_POINTS`] points). Returns the pixels painted
    /// (0 when the levels are unknown).
    pub fn paint_tags(
        &self,
        camera: &CameraModel,
        camera_from_marker: Mat4,
        rect: Rect,
        labels: &Mask,
        image: &mut [u8],
        fill: &mut Mask,
        which: PaintTags,
    ) -> usize {
        // Nothing to paint: no need to measure the levels.
        if !self.has_tags_to_paint(rect, labels, fill, which) {
            return 0;
        }
        self.paint_tags_found(camera, camera_from_marker, rect, labels, image, fill, which)
    }

    /// [`BoardSurfaces::paint_tags`] once [`BoardSurfaces::has_tags_to_paint`] said yes (the
    /// pipeline asks first, to copy the fill mask only when something will be painted).
    #[allow(clippy::too_many_arguments)]
    pub(super) fn paint_tags_found(
        &self,
        camera: &CameraModel,
        camera_from_marker: Mat4,
        rect: Rect,
        labels: &Mask,
        image: &mut [u8],
        fill: &mut Mask,
        which: PaintTags,
    ) -> usize {
        let w = fill.width() as usize;
        let (x0, x1) = (rect.x as usize, (rect.x + rect.width) as usize);
        let rows = rect.y as usize..(rect.y + rect.height) as usize;
        let lab = labels.as_slice();
        let to_paint = |i: usize, f: u8| lab[i] == TAG && which.paints(f);
        let plane = PlaneRays::new(camera, camera_from_marker);
        let on_plane = |x: f64, y: f64| plane.point(x, y);
        // The fraction of white at pixel (x, y): 2x2 samples.
        let whiteness = |x: usize, y: usize| -> Option<f32> {
            let mut n = 0u32;
            for (ox, oy) in [(-0.25, -0.25), (0.25, -0.25), (-0.25, 0.25), (0.25, 0.25)] {
                let p = on_plane(x as f64 + ox, y as f64 + oy)?;
                // White unless a tag prints black there.
                let white = self.prints.iter().all(|t| t.white_at(p));
                n += u32::from(white);
            }
            Some(n as f32 / 4.0)
        };
        // Levels from the known tag pixels (pure black or pure white samples only) on a grid
        // of every other pixel of every other row or coarser (LEVEL_GRID_POINTS), rows in
        // parallel. The sums are of bytes: exact in any order.
        type Levels = ([f64; 3], usize);
        let add = |a: Levels, b: Levels| {
            (
                [a.0[0] + b.0[0], a.0[1] + b.0[1], a.0[2] + b.0[2]],
                a.1 + b.1,
            )
        };
        let known = fill.as_slice();
        let img: &[u8] = image;
        let area = rect.width as f64 * rect.height as f64;
        let stride = LEVEL_STRIDE.max((area / LEVEL_GRID_POINTS as f64).sqrt().ceil() as usize);
        let (black, white) = rows
            .clone()
            .into_par_iter()
            .step_by(stride)
            .map(|y| {
                let (mut black, mut white): (Levels, Levels) = Default::default();
                for i in (y * w + x0..y * w + x1).step_by(stride) {
                    if lab[i] != TAG || known[i] != 0 {
                        continue;
                    }
                    let Some(k) = whiteness(i - y * w, y) else {
                        continue;
                    };
                    let acc = if k == 0.0 {
                        &mut black
                    } else if k == 1.0 {
                        &mut white
                    } else {
                        continue;
                    };
                    for c in 0..3 {
                        acc.0[c] += f64::from(img[i * 4 + c]);
                    }
                    acc.1 += 1;
                }
                (black, white)
            })
            .reduce(Default::default, |a, b| (add(a.0, b.0), add(a.1, b.1)));
        if black.1 < MIN_LEVEL_SAMPLES || white.1 < MIN_LEVEL_SAMPLES {
            return 0;
        }
        let lo = black.0.map(|v| v / black.1 as f64);
        let hi = white.0.map(|v| v / white.1 as f64);
        let first = rows.start;
        image[first * w * 4..rows.end * w * 4]
            .par_chunks_mut(w * 4)
            .zip(fill.as_mut_slice()[first * w..rows.end * w].par_chunks_mut(w))
            .enumerate()
            .map(|(r, (image_row, fill_row))| {
                let y = first + r;
                let mut painted = 0;
                for x in x0..x1 {
                    if !to_paint(y * w + x, fill_row[x]) {
                        continue;
                    }
                    let Some(k) = whiteness(x, y) else { continue };
                    for c in 0..3 {
                        let v = lo[c] + f64::from(k) * (hi[c] - lo[c]);
                        image_row[x * 4 + c] = v.round().clamp(0.0, 255.0) as u8;
                    }
                    fill_row[x] = 0;
                    painted += 1;
                }
                painted
            })
            .sum()
    }

    /// What the board prints at marker point `p`.
    fn print_at(&self, p: DVec2) -> Print {
        if self.prints.iter().any(|t| !t.white_at(p)) {
            return Print::Black;
        }
        let on = |q: &[DVec3; 4]| in_convex_quad(q, p);
        if self.sheet.as_ref().is_some_and(on) || self.tags.iter().any(on) {
            Print::White
        } else {
            Print::Table
        }
    }

    /// The print a pixel shows when the 3x3 pixels around it (their centres on the marker
    /// plane, through `plane`'s local affine map at the pixel) all show the same one; `None`
    /// near an edge of the print (a blurred mix).
    fn print_around(&self, plane: &PlaneRays<'_>, [x, y]: [u32; 2]) -> Option<Print> {
        let (x, y) = (f64::from(x), f64::from(y));
        let p0 = plane.point(x, y)?;
        let (px, py) = (plane.point(x + 1.0, y)? - p0, plane.point(x, y + 1.0)? - p0);
        let mut seen = None;
        for dy in [-1.0, 0.0, 1.0] {
            for dx in [-1.0, 0.0, 1.0] {
                let c = self.print_at(p0 + dx * px + dy * py);
                if seen.is_some_and(|s| s != c) {
                    return None;
                }
                seen = Some(c);
            }
        }
        seen
    }

    /// The board as seen from `camera_from_marker`, for [`PrintView::same_print`].
    pub fn print_view<'a>(
        &'a self,
        camera: &'a CameraModel,
        camera_from_marker: Mat4,
    ) -> PrintView<'a> {
        PrintView {
            surfaces: self,
            plane: PlaneRays::new(camera, camera_from_marker),
        }
    }

    /// Writes the label of every pixel of `rect` into `out` (pixels outside `rect` are not
    /// written). A quad with a corner behind the camera is left out.
    pub fn label(
        &self,
        camera: &CameraModel,
        camera_from_marker: Mat4,
        rect: Rect,
        out: &mut Mask,
    ) {
        let m = camera_from_marker.as_dmat4();
        let project = |q: &[DVec3; 4]| -> Option<[DVec2; 4]> {
            let mut o = [DVec2::ZERO; 4];
            for (o, p) in o.iter_mut().zip(q) {
                *o = camera.pixel_from_camera(m.transform_point3(*p))?;
            }
            Some(o)
        };
        let w = out.width() as usize;
        let data = out.as_mut_slice();
        for y in rect.y as usize..(rect.y + rect.height) as usize {
            data[y * w + rect.x as usize..y * w + (rect.x + rect.width) as usize].fill(TABLE);
        }
        if let Some(q) = self.sheet.as_ref().and_then(project) {
            paint_quad(data, w, rect, &q, 0.0, SHEET);
        }
        for q in self.tags.iter().filter_map(project) {
            paint_quad(data, w, rect, &q, TAG_GROW_PX, TAG);
        }
    }
}

/// What the board prints at a point of the marker plane.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Print {
    /// Off the sheet and the tags (wood, cloth: unknown albedo).
    Table,
    /// The sheet's paper, a tag's white ring or white cell.
    White,
    /// A tag's black cell.
    Black,
}

/// The board's print in one view ([`BoardSurfaces::print_view`]).
pub struct PrintView<'a> {
    surfaces: &'a BoardSurfaces,
    plane: PlaneRays<'a>,
}

impl PrintView<'_> {
    /// Whether pixels `a` and `b` show the same printed surface (the table, white paper, or a
    /// tag's black), away from any edge of the print: the pairs the shadow outline may
    /// compare ([`pa_diminish::shadow::SameSurface`]).
    pub fn same_print(&self, a: [u32; 2], b: [u32; 2]) -> bool {
        let s = self.surfaces;
        match (
            s.print_around(&self.plane, a),
            s.print_around(&self.plane, b),
        ) {
            (Some(pa), Some(pb)) => pa == pb,
            _ => false,
        }
    }
}

/// Pixels back-projected onto the marker plane (z = 0) of a view.
struct PlaneRays<'a> {
    camera: &'a CameraModel,
    marker_from_camera: glam::DMat4,
    /// The camera's centre, marker frame.
    origin: DVec3,
}

impl<'a> PlaneRays<'a> {
    fn new(camera: &'a CameraModel, camera_from_marker: Mat4) -> Self {
        let marker_from_camera = camera_from_marker.as_dmat4().inverse();
        Self {
            camera,
            marker_from_camera,
            origin: marker_from_camera.transform_point3(DVec3::ZERO),
        }
    }

    /// The marker point seen at pixel `(x, y)` (`None`: the ray misses the plane).
    fn point(&self, x: f64, y: f64) -> Option<DVec2> {
        let dir = self
            .marker_from_camera
            .transform_vector3(self.camera.ray_from_pixel(DVec2::new(x, y)));
        if dir.z.abs() < 1e-12 {
            return None;
        }
        let t = -self.origin.z / dir.z;
        (t > 0.0).then(|| {
            let p = self.origin + t * dir;
            DVec2::new(p.x, p.y)
        })
    }
}

/// Whether marker point `p` lies inside the convex quad `q` (marker plane, either winding).
fn in_convex_quad(q: &[DVec3; 4], p: DVec2) -> bool {
    let side = |i: usize| {
        let (a, b) = (q[i].truncate(), q[(i + 1) % 4].truncate());
        (b - a).perp_dot(p - a)
    };
    let s: [f64; 4] = [side(0), side(1), side(2), side(3)];
    s.iter().all(|&v| v >= 0.0) || s.iter().all(|&v| v <= 0.0)
}

/// The edges of quad `q` as (a point, the unit normal pointing inside), degenerate edges left
/// out; `None` for a quad of no area.
fn inner_edges(q: &[DVec2; 4]) -> Option<Vec<(DVec2, DVec2)>> {
    // Orientation: the signed area's sign makes every edge's inside positive.
    let area: f64 = (0..4).map(|i| q[i].perp_dot(q[(i + 1) % 4])).sum();
    if area.abs() < 1e-9 {
        return None;
    }
    let s = area.signum();
    Some(
        (0..4)
            .filter_map(|i| {
                let (a, b) = (q[i], q[(i + 1) % 4]);
                let d = b - a;
                let len = d.length();
                (len > 1e-12).then(|| (a, s * d.perp() / len))
            })
            .collect(),
    )
}

/// Sets to `label` the pixels of `rect` whose centre lies inside the convex quad `q` grown
/// by `grow` pixels (its edges moved outwards).
fn paint_quad(data: &mut [u8], w: usize, rect: Rect, q: &[DVec2; 4], grow: f64, label: u8) {
    let Some(edges) = inner_edges(q) else {
        return;
    };
    let (mut x0, mut y0, mut x1, mut y1) = (f64::MAX, f64::MAX, f64::MIN, f64::MIN);
    for p in q {
        x0 = x0.min(p.x);
        y0 = y0.min(p.y);
        x1 = x1.max(p.x);
        y1 = y1.max(p.y);
    }
    let lo_x = (x0 - grow).floor().max(f64::from(rect.x)) as i64;
    let lo_y = (y0 - grow).floor().max(f64::from(rect.y)) as i64;
    let hi_x = (x1 + grow).ceil().min(f64::from(rect.x + rect.width) - 1.0) as i64;
    let hi_y = (y1 + grow)
        .ceil()
        .min(f64::from(rect.y + rect.height) - 1.0) as i64;
    // The pixels inside every edge's half-plane (an intersection of half-planes is convex)
    // form one run in each row. Find the run's ends from the
    // edge lines, then settle them with the exact test (rounding may move an end by a pixel).
    let inside = |x: i64, y: i64| {
        let c = DVec2::new(x as f64, y as f64);
        edges.iter().all(|(a, n)| (c - *a).dot(*n) >= -grow)
    };
    for y in lo_y..=hi_y {
        let (mut l, mut r) = (lo_x as f64, hi_x as f64);
        for (a, n) in &edges {
            // n.x (x - a.x) + n.y (y - a.y) >= -grow
            let rhs = -grow - n.y * (y as f64 - a.y);
            if n.x > 1e-12 {
                l = l.max(a.x + rhs / n.x);
            } else if n.x < -1e-12 {
                r = r.min(a.x + rhs / n.x);
            } else if rhs > 1e-6 {
                // Parallel to the row and this row is outside it.
                r = l - 1.0;
            }
        }
        if l.is_nan() || r.is_nan() || l > r + 2.0 {
            continue;
        }
        let mut x0 = ((l.floor() as i64) - 1).max(lo_x);
        let mut x1 = ((r.ceil() as i64) + 1).min(hi_x);
        while x0 <= x1 && !inside(x0, y) {
            x0 += 1;
        }
        while x1 >= x0 && !inside(x1, y) {
            x1 -= 1;
        }
        if x0 <= x1 {
            let row = y as usize * w;
            data[row + x0 as usize..=row + x1 as usize].fill(label);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use pa_camera::Intrinsics;

    /// A camera looking straight down at the marker plane from 0.5 m: a marker point (x, y)
    /// lands on pixel (cx + f x / 0.5, cy + f y / 0.5).
    fn top_down() -> (CameraModel, Mat4) {
        let cam = CameraModel::pinhole(Intrinsics {
            fx: 500.0,
            fy: 500.0,
            cx: 99.5,
            cy: 99.5,
            width: 200,
            height: 200,
        });
        (cam, Mat4::from_translation(glam::Vec3::new(0.0, 0.0, 0.5)))
    }

    #[test]
    fn labels_follow_the_projected_sheet_and_tags() {
        let (cam, pose) = top_down();
        // Sheet 0.1 m: pixels 49.5..149.5; a tag of 0.02 m centred at (0.02, 0): pixels
        // 109.5..129.5 in x, 89.5..109.5 in y.
        let board = Board {
            family: pa_track::TagFamily::Tag36h11,
            tags: vec![pa_track::board::BoardTag {
                id: 0,
                center_m: glam::DVec2::new(0.02, 0.0),
                size_m: 0.02,
                rotation_rad: 0.0,
            }],
        };
        let s = BoardSurfaces::new(&board, Some(0.1));
        let mut out = Mask::new(200, 200, vec![9; 200 * 200]).expect("mask");
        let rect = Rect::from_inclusive(10, 10, 189, 189);
        s.label(&cam, pose, rect, &mut out);
        let at = |x: usize, y: usize| out.as_slice()[y * 200 + x];
        assert_eq!(at(5, 5), 9, "outside the rect: untouched");
        assert_eq!(at(20, 100), TABLE);
        assert_eq!(at(48, 100), TABLE);
        assert_eq!(at(51, 100), SHEET);
        assert_eq!(at(100, 100), SHEET);
        assert_eq!(at(148, 100), SHEET);
        assert_eq!(at(151, 100), TABLE);
        assert_eq!(at(120, 100), TAG);
        // Grown by 1.5 px: 0.5 px out is tag, 2.5 px out is sheet.
        assert_eq!(at(109, 100), TAG);
        assert_eq!(at(107, 100), SHEET);
        assert_eq!(at(130, 100), TAG);
        assert_eq!(at(132, 100), SHEET);
        assert_eq!(at(120, 89), TAG);
        assert_eq!(at(120, 87), SHEET);
        assert_eq!(at(120, 110), TAG);
        assert_eq!(at(120, 112), SHEET);
    }

    /// The scanline `paint_quad` labels exactly the pixels the per-pixel half-plane test
    /// does over the quad's grown box (the definition it replaced), on quads of every
    /// orientation and grow, convex or not, clipped by the rect, with degenerate edges.
    #[test]
    fn paint_quad_equals_the_per_pixel_test() {
        let brute = |data: &mut [u8], w: usize, rect: Rect, q: &[DVec2; 4], grow: f64| {
            let Some(edges) = inner_edges(q) else {
                return;
            };
            // The quad's box grown by `grow`, within the rect.
            let lo = |f: fn(&DVec2) -> f64, r0: u32| {
                let m = q.iter().map(f).fold(f64::MAX, f64::min);
                (m - grow).floor().max(f64::from(r0)) as i64
            };
            let hi = |f: fn(&DVec2) -> f64, r1: u32| {
                let m = q.iter().map(f).fold(f64::MIN, f64::max);
                (m + grow).ceil().min(f64::from(r1) - 1.0) as i64
            };
            let (x0, x1) = (lo(|p| p.x, rect.x), hi(|p| p.x, rect.x + rect.width));
            let (y0, y1) = (lo(|p| p.y, rect.y), hi(|p| p.y, rect.y + rect.height));
            for y in y0..=y1 {
                for x in x0..=x1 {
                    let c = DVec2::new(x as f64, y as f64);
                    if edges.iter().all(|(a, n)| (c - *a).dot(*n) >= -grow) {
                        data[y as usize * w + x as usize] = 7;
                    }
                }
            }
        };
        let mut seed = 12345u64;
        let mut rnd = |lo: f64, hi: f64| {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            lo + (hi - lo) * ((seed >> 11) as f64 / (1u64 << 53) as f64)
        };
        let (w, h) = (64usize, 48usize);
        let rect = Rect::from_inclusive(3, 2, 59, 44);
        let mut quads: Vec<[DVec2; 4]> = (0..400)
            .map(|_| {
                let c = DVec2::new(rnd(-10.0, 74.0), rnd(-10.0, 58.0));
                let mut q = [DVec2::ZERO; 4];
                for (k, p) in q.iter_mut().enumerate() {
                    let a = rnd(0.0, 1.5) + k as f64 * std::f64::consts::FRAC_PI_2;
                    *p = c + rnd(0.5, 30.0) * DVec2::new(a.cos(), a.sin());
                }
                q
            })
            .collect();
        // Axis-aligned edges on pixel centres, a repeated corner, and a line.
        quads.push([
            DVec2::new(10.0, 10.0),
            DVec2::new(30.0, 10.0),
            DVec2::new(30.0, 20.0),
            DVec2::new(10.0, 20.0),
        ]);
        quads.push([
            DVec2::new(10.0, 10.0),
            DVec2::new(10.0, 10.0),
            DVec2::new(30.0, 25.0),
            DVec2::new(5.0, 30.0),
        ]);
        quads.push([
            DVec2::new(1.0, 1.0),
            DVec2::new(5.0, 5.0),
            DVec2::new(9.0, 9.0),
            DVec2::new(3.0, 3.0),
        ]);
        for (i, q) in quads.iter().enumerate() {
            for grow in [0.0, 1.5] {
                let (mut a, mut b) = (vec![0u8; w * h], vec![0u8; w * h]);
                paint_quad(&mut a, w, rect, q, grow, 7);
                brute(&mut b, w, rect, q, grow);
                assert_eq!(a, b, "quad {i} {q:?}, grow {grow}");
            }
        }
    }

    /// A tag half hidden by the fill mask is redrawn from its print, in this frame's levels:
    /// the truth is the tag image rendered independently (marker_cells, 4x4 samples a pixel).
    #[test]
    fn a_covered_tag_is_redrawn_from_its_print() {
        let (cam, pose) = top_down();
        let board = Board {
            family: pa_track::TagFamily::Tag36h11,
            tags: vec![pa_track::board::BoardTag {
                id: 3,
                center_m: glam::DVec2::ZERO,
                size_m: 0.04,
                rotation_rad: 0.0,
            }],
        };
        let cells = pa_track::marker_cells(board.family, 3).expect("cells");
        // Pixel (x, y) sees marker point ((x - 99.5) / 1000, (y - 99.5) / 1000); a cell is
        // 5 mm, the pattern (10 cells with its white ring) spans +-25 mm.
        let (black, white) = (30.0f64, 220.0f64);
        let truth: Vec<f64> = (0..200 * 200)
            .map(|i| {
                let (x, y) = ((i % 200) as f64, (i / 200) as f64);
                let mut k = 0.0;
                for sy in 0..4 {
                    for sx in 0..4 {
                        let mx = (x - 0.375 + 0.25 * f64::from(sx) - 99.5) / 1000.0;
                        let my = (y - 0.375 + 0.25 * f64::from(sy) - 99.5) / 1000.0;
                        let (cu, cv) = ((mx / 0.005 + 5.0).floor(), (my / 0.005 + 5.0).floor());
                        let w = !(0.0..10.0).contains(&cu)
                            || !(0.0..10.0).contains(&cv)
                            || cells.data[cv as usize * 10 + cu as usize] != 0;
                        k += if w { 1.0 / 16.0 } else { 0.0 };
                    }
                }
                black + k * (white - black)
            })
            .collect();
        let mut image: Vec<u8> = truth
            .iter()
            .flat_map(|&v| {
                let v = v.round() as u8;
                [v, v, v, 255]
            })
            .collect();
        // The right half of the tag is hidden (painted magenta) and to fill; a strip of it is
        // under the twin's opaque interior (the fill mask's hidden pixels).
        let mut fill = Mask::zeros(200, 200).expect("mask");
        for y in 60..140 {
            for x in 100..140 {
                let hidden = (80..90).contains(&y);
                fill.as_mut_slice()[y * 200 + x] = if hidden { Mask::HIDDEN } else { Mask::SET };
                image[(y * 200 + x) * 4..(y * 200 + x) * 4 + 3].copy_from_slice(&[250, 0, 200]);
            }
        }
        let hidden_tag = |labels: &Mask, fill: &Mask| {
            (0..200 * 200)
                .filter(|&i| labels.as_slice()[i] == TAG && fill.as_slice()[i] == Mask::HIDDEN)
                .count()
        };
        let s = BoardSurfaces::new(&board, Some(0.1));
        let rect = Rect::from_inclusive(40, 40, 159, 159);
        let mut labels = Mask::zeros(200, 200).expect("labels");
        s.label(&cam, pose, rect, &mut labels);
        let before = fill.clone();
        // The fill's set pixels only: the hidden ones stay hidden and unpainted...
        let (mut only_set, mut img_set) = (fill.clone(), image.clone());
        let n_set = s.paint_tags(
            &cam,
            pose,
            rect,
            &labels,
            &mut img_set,
            &mut only_set,
            PaintTags::Set,
        );
        let under_twin = hidden_tag(&labels, &before);
        assert!(under_twin >= 200, "{under_twin} hidden tag pixels");
        assert_eq!(hidden_tag(&labels, &only_set), under_twin);
        // ... and with them, the tag under the twin is painted too.
        let n = s.paint_tags(
            &cam,
            pose,
            rect,
            &labels,
            &mut image,
            &mut fill,
            PaintTags::SetAndHidden,
        );
        assert_eq!(hidden_tag(&labels, &fill), 0);
        assert_eq!(n, n_set + under_twin);
        let (mut close, mut total, mut err) = (0usize, 0usize, 0.0f64);
        for i in 0..200 * 200 {
            if before.as_slice()[i] == 0 || fill.as_slice()[i] != 0 {
                continue;
            }
            total += 1;
            let e = (f64::from(image[i * 4]) - truth[i]).abs();
            err += e;
            close += usize::from(e <= 48.0);
            assert_eq!(labels.as_slice()[i], TAG, "only tag pixels are painted");
        }
        println!(
            "painted {n}: {close}/{total} within 48 levels, mean error {:.1}",
            err / total as f64
        );
        assert_eq!(n, total);
        // The pattern's black square plus the grown rim: 20 x 40 px and more.
        assert!(n >= 800, "{n} pixels painted");
        assert!(close * 100 >= total * 97, "{close} of {total} close");
        assert!(
            err / (total as f64) < 6.0,
            "mean error {}",
            err / total as f64
        );
    }
}
