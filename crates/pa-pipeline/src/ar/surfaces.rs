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
}

impl TagPrint {
    /// Whether the print is white at marker point `p` (the white ring and beyond: white).
    fn white_at(&self, p: DVec2) -> bool {
        let d = p - self.center;
        let (c, s) = self.rot;
        // Into the tag's own axes (rotate by -rotation).
        let (u, v) = (c * d.x + s * d.y, -s * d.x + c * d.y);
        let off = 0.5 * f64::from(self.total);
        let (cu, cv) = (
            (u / self.cell_m + off).floor(),
            (v / self.cell_m + off).floor(),
        );
        if cu < 0.0 || cv < 0.0 || cu >= f64::from(self.total) || cv >= f64::from(self.total) {
            return true;
        }
        self.cells[cv as usize * self.total as usize + cu as usize] != 0
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
                    Some(TagPrint {
                        center: t.center_m,
                        rot: (t.rotation_rad.cos(), t.rotation_rad.sin()),
                        cell_m: t.size_m / f64::from(layout.border_cells.max(1)),
                        total: cells.width,
                        cells: cells.data,
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

    /// Paints the board's known print into the pixels of `fill` (set, not hidden) that show a
    /// tag (`labels` == [`TAG`]) in `rect`, and clears them in `fill`: a covered tag is
    /// redrawn from its pattern, not invented. Each pixel is the mean of 2x2 samples of the
    /// pattern (back-projected onto the marker plane), mapped to this frame's black and white
    /// as measured on the known pixels of the tags in `rect` (mean colour of the known tag
    /// pixels the pattern says are black, and of those it says are white, each at least
    /// [`MIN_LEVEL_SAMPLES`]). Returns the pixels painted (0 when the levels are unknown).
    pub fn paint_tags(
        &self,
        camera: &CameraModel,
        camera_from_marker: Mat4,
        rect: Rect,
        labels: &Mask,
        image: &mut [u8],
        fill: &mut Mask,
    ) -> usize {
        if self.prints.is_empty() {
            return 0;
        }
        let marker_from_camera = camera_from_marker.as_dmat4().inverse();
        let origin = marker_from_camera.transform_point3(DVec3::ZERO);
        // The marker point seen at pixel (x, y) (None: the ray misses the plane).
        let on_plane = |x: f64, y: f64| -> Option<DVec2> {
            let dir = marker_from_camera.transform_vector3(camera.ray_from_pixel(DVec2::new(x, y)));
            if dir.z.abs() < 1e-12 {
                return None;
            }
            let t = -origin.z / dir.z;
            (t > 0.0).then(|| {
                let p = origin + t * dir;
                DVec2::new(p.x, p.y)
            })
        };
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
        let w = fill.width() as usize;
        let lab = labels.as_slice();
        // Levels from the known tag pixels (pure black or pure white samples only).
        let (mut black, mut white) = (([0.0f64; 3], 0usize), ([0.0f64; 3], 0usize));
        for y in rect.y as usize..(rect.y + rect.height) as usize {
            for x in rect.x as usize..(rect.x + rect.width) as usize {
                let i = y * w + x;
                if lab[i] != TAG || fill.as_slice()[i] != 0 {
                    continue;
                }
                let Some(k) = whiteness(x, y) else { continue };
                let acc = if k == 0.0 {
                    &mut black
                } else if k == 1.0 {
                    &mut white
                } else {
                    continue;
                };
                for c in 0..3 {
                    acc.0[c] += f64::from(image[i * 4 + c]);
                }
                acc.1 += 1;
            }
        }
        if black.1 < MIN_LEVEL_SAMPLES || white.1 < MIN_LEVEL_SAMPLES {
            return 0;
        }
        let lo = black.0.map(|v| v / black.1 as f64);
        let hi = white.0.map(|v| v / white.1 as f64);
        let mut painted = 0;
        let data = fill.as_mut_slice();
        for y in rect.y as usize..(rect.y + rect.height) as usize {
            for x in rect.x as usize..(rect.x + rect.width) as usize {
                let i = y * w + x;
                if lab[i] != TAG || data[i] != Mask::SET {
                    continue;
                }
                let Some(k) = whiteness(x, y) else { continue };
                for c in 0..3 {
                    let v = lo[c] + f64::from(k) * (hi[c] - lo[c]);
                    image[i * 4 + c] = v.round().clamp(0.0, 255.0) as u8;
                }
                data[i] = 0;
                painted += 1;
            }
        }
        painted
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

/// Sets to `label` the pixels of `rect` whose centre lies inside the convex quad `q` grown
/// by `grow` pixels (its edges moved outwards).
fn paint_quad(data: &mut [u8], w: usize, rect: Rect, q: &[DVec2; 4], grow: f64, label: u8) {
    // Orientation: the signed area's sign makes every edge's inside positive.
    let area: f64 = (0..4).map(|i| q[i].perp_dot(q[(i + 1) % 4])).sum();
    if area.abs() < 1e-9 {
        return;
    }
    let s = area.signum();
    let edges: Vec<(DVec2, DVec2)> = (0..4)
        .filter_map(|i| {
            let (a, b) = (q[i], q[(i + 1) % 4]);
            let d = b - a;
            let len = d.length();
            // Unit normal pointing inside; the edge line through `a`.
            (len > 1e-12).then(|| (a, s * d.perp() / len))
        })
        .collect();
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
    for y in lo_y..=hi_y {
        for x in lo_x..=hi_x {
            let c = DVec2::new(x as f64, y as f64);
            if edges.iter().all(|(a, n)| (c - *a).dot(*n) >= -grow) {
                data[y as usize * w + x as usize] = label;
            }
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
        // The right half of the tag is hidden (painted magenta) and to fill.
        let mut fill = Mask::zeros(200, 200).expect("mask");
        for y in 60..140 {
            for x in 100..140 {
                fill.as_mut_slice()[y * 200 + x] = Mask::SET;
                image[(y * 200 + x) * 4..(y * 200 + x) * 4 + 3].copy_from_slice(&[250, 0, 200]);
            }
        }
        let s = BoardSurfaces::new(&board, Some(0.1));
        let rect = Rect::from_inclusive(40, 40, 159, 159);
        let mut labels = Mask::zeros(200, 200).expect("labels");
        s.label(&cam, pose, rect, &mut labels);
        let before = fill.clone();
        let n = s.paint_tags(&cam, pose, rect, &labels, &mut image, &mut fill);
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
