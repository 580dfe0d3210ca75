//! Synthetic calibration views with known truth: a planar pattern (chessboard or AprilTag
//! board) rendered through a [`CameraModel`] with lens distortion, for tests, demos and
//! measuring the calibration.
//!
//! Rendering is analytic: every pixel's footprint (its four corners, pixel centres at integer
//! coordinates so the footprint of pixel (x, y) is `[x - 0.5, x + 0.5] x [y - 0.5, y + 0.5]`)
//! is undistorted to rays ([`CameraModel::ray_from_pixel`]) and intersected with the board
//! plane. A pixel whose four corners fall in one cell of the pattern takes that cell's
//! value; other pixels are supersampled (`n` x `n` samples, board coordinates interpolated
//! across the footprint), as a sensor integrates over its pixels. Optional Gaussian blur
//! (optics) and Gaussian noise (sensor) follow, then quantisation to 8 bits.

use glam::{DMat3, DVec2, DVec3};
use pa_camera::CameraModel;
use pa_track::{marker_image, Board, GrayImage, Pose, TagFamily};

use crate::CalibrateError;

/// A plane pattern of uniformly coloured square cells on a lattice, in the board frame
/// (metres; +X right, +Y down, +Z into the board; z = 0 is the board's face).
#[derive(Debug, Clone, PartialEq)]
pub struct PlanarPattern {
    /// Cells across (along +X).
    pub cells_x: u32,
    /// Cells down (along +Y).
    pub cells_y: u32,
    /// Side of one cell, metres.
    pub cell_m: f64,
    /// Board coordinates of the top-left corner of cell (0, 0), metres.
    pub origin_m: DVec2,
    /// Cell values, row-major (0 black, 255 white).
    pub values: Vec<u8>,
    /// Value outside the pattern.
    pub background: u8,
}

impl PlanarPattern {
    /// A chessboard with `rows` x `cols` inner corners of pitch `square_m`, with inner corner
    /// `(r, c)` at board coordinates `(c * square_m, r * square_m)` (the order of
    /// [`crate::find_chessboard`]), surrounded by `margin_squares` squares of white. The
    /// square whose bottom-right corner is inner corner (0, 0) is black.
    pub fn chessboard(rows: u32, cols: u32, square_m: f64, margin_squares: u32) -> Self {
        let (sx, sy) = (cols + 1, rows + 1);
        let (cx, cy) = (sx + 2 * margin_squares, sy + 2 * margin_squares);
        let mut values = vec![255u8; (cx * cy) as usize];
        for y in 0..sy {
            for x in 0..sx {
                if (x + y) % 2 == 0 {
                    values[((y + margin_squares) * cx + x + margin_squares) as usize] = 0;
                }
            }
        }
        let m = (margin_squares + 1) as f64 * square_m;
        Self {
            cells_x: cx,
            cells_y: cy,
            cell_m: square_m,
            origin_m: DVec2::new(-m, -m),
            values,
            background: 255,
        }
    }

    /// The AprilTag board [`Board::grid`] describes (as `propsalive marker --board` prints
    /// it), one lattice cell per tag cell. The gap must be a whole number of tag cells
    /// (`tag_size_m / border_cells`), so that the lattice is shared by all tags.
    pub fn tag_board(
        family: TagFamily,
        rows: u32,
        cols: u32,
        tag_size_m: f64,
        gap_m: f64,
        first_id: u32,
    ) -> Result<(Self, Board), CalibrateError> {
        let board = Board::grid(family, rows, cols, tag_size_m, gap_m, first_id)?;
        let layout = pa_track::family_layout(family)?;
        let cell = tag_size_m / layout.border_cells as f64;
        let gap_cells = gap_m / cell;
        if (gap_cells - gap_cells.round()).abs() > 1e-6 {
            return Err(CalibrateError::InvalidTarget {
                reason: format!(
                    "synthetic tag board: gap {gap_m} m is not a whole number of {cell} m cells"
                ),
            });
        }
        let total = layout.total_cells;
        let pitch = layout.border_cells + gap_cells.round() as u32;
        let margin = 2u32;
        let cx = (cols - 1) * pitch + total + 2 * margin;
        let cy = (rows - 1) * pitch + total + 2 * margin;
        let mut values = vec![255u8; (cx * cy) as usize];
        for (k, tag) in board.tags.iter().enumerate() {
            let (r, c) = (k as u32 / cols, k as u32 % cols);
            let img = marker_image(family, tag.id, total)?;
            for y in 0..total {
                for x in 0..total {
                    let v = img.data[(y * total + x) as usize];
                    let i = ((r * pitch + y + margin) * cx + c * pitch + x + margin) as usize;
                    values[i] = values[i].min(v);
                }
            }
        }
        // Tag (0, 0)'s canonical image starts half an image left/up of its centre.
        let c0 = board.tags[0].center_m;
        let origin_m = c0 - DVec2::splat((total as f64 * 0.5 + margin as f64) * cell);
        Ok((
            Self {
                cells_x: cx,
                cells_y: cy,
                cell_m: cell,
                origin_m,
                values,
                background: 255,
            },
            board,
        ))
    }

    /// The lattice cell at board coordinates `p_m` (`None` outside the pattern).
    fn cell(&self, p_m: DVec2) -> Option<usize> {
        let q = (p_m - self.origin_m) / self.cell_m;
        if !(q.x >= 0.0 && q.y >= 0.0) {
            return None;
        }
        let (x, y) = (q.x as u32, q.y as u32);
        (x < self.cells_x && y < self.cells_y).then(|| (y * self.cells_x + x) as usize)
    }

    /// The pattern's value at board coordinates `p_m`.
    pub fn value_at(&self, p_m: DVec2) -> u8 {
        self.cell(p_m).map_or(self.background, |i| self.values[i])
    }

    /// Board coordinates of the pattern's four outer corners.
    pub fn outline_m(&self) -> [DVec2; 4] {
        let (w, h) = (
            self.cells_x as f64 * self.cell_m,
            self.cells_y as f64 * self.cell_m,
        );
        let o = self.origin_m;
        [
            o,
            o + DVec2::new(w, 0.0),
            o + DVec2::new(w, h),
            o + DVec2::new(0.0, h),
        ]
    }
}

/// How a synthetic view is degraded.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RenderSettings {
    /// Samples per pixel side where a pixel straddles cells. 16 by default: at 4 the
    /// quantised coverage of edges nearly aligned with the pixel grid moves corners by up to
    /// 0.2 px (a rendering artefact, not a detector error).
    pub supersample: u32,
    /// Grey level of black cells.
    pub dark: u8,
    /// Grey level of white cells and the background.
    pub bright: u8,
    /// Gaussian blur (optics), pixels; 0 for none.
    pub blur_sigma_px: f64,
    /// Gaussian noise, grey levels; 0 for none.
    pub noise_sigma: f64,
    /// Seed of the noise.
    pub seed: u64,
}

impl Default for RenderSettings {
    fn default() -> Self {
        Self {
            supersample: 16,
            dark: 40,
            bright: 215,
            blur_sigma_px: 0.7,
            noise_sigma: 2.0,
            seed: 1,
        }
    }
}

/// Rays through the pixel corners of a camera, computed once and reused for every view.
pub struct RayMap {
    camera: CameraModel,
    /// `(width + 1) * (height + 1)` rays (z = 1) through `(x - 0.5, y - 0.5)`.
    rays: Vec<DVec3>,
}

impl RayMap {
    /// The rays of `camera` (its intrinsics' width and height).
    pub fn new(camera: CameraModel) -> Self {
        let (w, h) = (camera.intrinsics.width, camera.intrinsics.height);
        let mut rays = Vec::with_capacity((w as usize + 1) * (h as usize + 1));
        for y in 0..=h {
            for x in 0..=w {
                rays.push(camera.ray_from_pixel(DVec2::new(x as f64 - 0.5, y as f64 - 0.5)));
            }
        }
        Self { camera, rays }
    }

    /// The camera.
    pub fn camera(&self) -> &CameraModel {
        &self.camera
    }

    /// Renders `pattern` seen with the pose `camera_from_board`.
    pub fn render(
        &self,
        pattern: &PlanarPattern,
        camera_from_board: &Pose,
        settings: &RenderSettings,
    ) -> GrayImage {
        let (w, h) = (
            self.camera.intrinsics.width as usize,
            self.camera.intrinsics.height as usize,
        );
        let r = DMat3::from_quat(camera_from_board.rotation);
        let t = camera_from_board.translation;
        let n = r.z_axis; // board normal in the camera frame
        let nt = n.dot(t);
        let rt = r.transpose();
        let board: Vec<Option<DVec2>> = self
            .rays
            .iter()
            .map(|d| {
                let den = n.dot(*d);
                let s = nt / den;
                if !(den.abs() > 1e-12 && s > 0.0 && s.is_finite()) {
                    return None;
                }
                Some((rt * (*d * s - t)).truncate())
            })
            .collect();
        let ss = settings.supersample.max(1) as usize;
        let (lo, hi) = (settings.dark as f64, settings.bright as f64);
        let level = |v: u8| lo + (hi - lo) * v as f64 / 255.0;
        let mut img = vec![0f64; w * h];
        for y in 0..h {
            for x in 0..w {
                let c = [
                    board[y * (w + 1) + x],
                    board[y * (w + 1) + x + 1],
                    board[(y + 1) * (w + 1) + x],
                    board[(y + 1) * (w + 1) + x + 1],
                ];
                let [Some(c00), Some(c10), Some(c01), Some(c11)] = c else {
                    img[y * w + x] = level(pattern.background);
                    continue;
                };
                let k = pattern.cell(c00);
                if k == pattern.cell(c10) && k == pattern.cell(c01) && k == pattern.cell(c11) {
                    img[y * w + x] = level(pattern.value_at(c00));
                    continue;
                }
                let mut acc = 0.0;
                for sy in 0..ss {
                    let fy = (sy as f64 + 0.5) / ss as f64;
                    let left = c00.lerp(c01, fy);
                    let right = c10.lerp(c11, fy);
                    for sx in 0..ss {
                        let fx = (sx as f64 + 0.5) / ss as f64;
                        acc += level(pattern.value_at(left.lerp(right, fx)));
                    }
                }
                img[y * w + x] = acc / (ss * ss) as f64;
            }
        }
        if settings.blur_sigma_px > 0.0 {
            img = gaussian_blur(&img, w, h, settings.blur_sigma_px);
        }
        let mut rng = SplitMix(settings.seed);
        let data = img
            .iter()
            .map(|v| {
                let noisy = if settings.noise_sigma > 0.0 {
                    v + settings.noise_sigma * rng.gaussian()
                } else {
                    *v
                };
                noisy.round().clamp(0.0, 255.0) as u8
            })
            .collect();
        GrayImage {
            width: w as u32,
            height: h as u32,
            data,
        }
    }
}

fn gaussian_blur(img: &[f64], w: usize, h: usize, sigma: f64) -> Vec<f64> {
    let r = (3.0 * sigma).ceil() as isize;
    let k: Vec<f64> = (-r..=r)
        .map(|i| (-(i * i) as f64 / (2.0 * sigma * sigma)).exp())
        .collect();
    let s: f64 = k.iter().sum();
    let k: Vec<f64> = k.iter().map(|v| v / s).collect();
    let (wi, hi) = (w as isize, h as isize);
    let mut tmp = vec![0.0; w * h];
    for y in 0..hi {
        for x in 0..wi {
            tmp[(y * wi + x) as usize] = k
                .iter()
                .enumerate()
                .map(|(i, kv)| kv * img[(y * wi + (x + i as isize - r).clamp(0, wi - 1)) as usize])
                .sum();
        }
    }
    let mut out = vec![0.0; w * h];
    for y in 0..hi {
        for x in 0..wi {
            out[(y * wi + x) as usize] = k
                .iter()
                .enumerate()
                .map(|(i, kv)| kv * tmp[((y + i as isize - r).clamp(0, hi - 1) * wi + x) as usize])
                .sum();
        }
    }
    out
}

/// A small deterministic generator (SplitMix64).
#[derive(Debug, Clone)]
pub struct SplitMix(pub u64);

impl SplitMix {
    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    /// Uniform in [0, 1).
    pub fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Uniform in [a, b).
    pub fn range(&mut self, a: f64, b: f64) -> f64 {
        a + (b - a) * self.uniform()
    }

    /// Standard normal (Box-Muller).
    pub fn gaussian(&mut self) -> f64 {
        let u1 = self.uniform().max(1e-300);
        let u2 = self.uniform();
        (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
    }
}

/// `count` varied poses `camera_from_board` from which the whole `region_m` (a rectangle of
/// board coordinates, e.g. the pattern's outline) is seen inside the image with a margin of
/// `margin_px`: tilts between 5 degrees and `max_tilt_deg` about random axes in the board
/// plane, in-plane turns up to 30 degrees, the board's centre anywhere in the middle 70 % of
/// the image (so that the views reach its edges and corners), its size 35-75 % of the image
/// height. Deterministic for a `seed`; fewer than `count` poses
/// only when the camera cannot see the region at all.
pub fn varied_poses(
    camera: &CameraModel,
    region_m: [DVec2; 4],
    count: usize,
    max_tilt_deg: f64,
    margin_px: f64,
    seed: u64,
) -> Vec<Pose> {
    let k = camera.intrinsics;
    let (w, h) = (k.width as f64, k.height as f64);
    let centre = region_m.iter().copied().sum::<DVec2>() / 4.0;
    let extent = region_m
        .iter()
        .map(|p| p.distance(centre))
        .fold(0.0, f64::max)
        * 2.0;
    let mut rng = SplitMix(seed);
    let mut out = Vec::with_capacity(count);
    for _ in 0..count * 2000 {
        if out.len() == count {
            break;
        }
        let tilt = rng.range(5.0, max_tilt_deg.max(5.0)).to_radians();
        let axis_angle = rng.range(0.0, std::f64::consts::TAU);
        let spin = rng.range(-30.0, 30.0).to_radians();
        let axis = DVec3::new(axis_angle.cos(), axis_angle.sin(), 0.0);
        let rot = glam::DQuat::from_axis_angle(axis, tilt) * glam::DQuat::from_rotation_z(spin);
        let u = rng.range(0.15, 0.85) * w;
        let v = rng.range(0.15, 0.85) * h;
        let frac = rng.range(0.35, 0.75);
        let dist = k.fy * extent / (frac * h);
        let ray = camera.ray_from_pixel(DVec2::new(u, v)).normalize();
        let t = ray * dist - rot * centre.extend(0.0);
        let pose = Pose {
            rotation: rot,
            translation: t,
        };
        let visible = region_m.iter().all(|p| {
            camera
                .pixel_from_camera(pose.transform_point(p.extend(0.0)))
                .is_some_and(|px| {
                    px.x >= margin_px
                        && px.y >= margin_px
                        && px.x <= w - 1.0 - margin_px
                        && px.y <= h - 1.0 - margin_px
                })
        });
        // Also the region's edges (distortion bends them outwards between the corners).
        let edges_visible = (0..4).all(|e| {
            let (a, b) = (region_m[e], region_m[(e + 1) % 4]);
            (1..8).all(|s| {
                let p = a.lerp(b, s as f64 / 8.0).extend(0.0);
                camera
                    .pixel_from_camera(pose.transform_point(p))
                    .is_some_and(|px| {
                        px.x >= margin_px
                            && px.y >= margin_px
                            && px.x <= w - 1.0 - margin_px
                            && px.y <= h - 1.0 - margin_px
                    })
            })
        });
        if visible && edges_visible {
            out.push(pose);
        }
    }
    out
}
