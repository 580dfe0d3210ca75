//! Registration of the key prop: where does the physical prop stand on the marker?
//!
//! From several frames of the key prop standing on the marker, each with its tracked
//! `camera_from_marker`, [`register`] refines the shot's placement (`marker_from_prop`: the
//! translation on the table x/y, the lift z, the yaw; optionally a uniform scale) by aligning
//! the outline of the key-pose twin with the frames' edges over all views at once.
//!
//! Method:
//! - **Image side** ([`edges`]): around the prop's projection at the start placement (a
//!   margin wide enough for the search), each frame becomes a grey pyramid (full, 1/2, 1/4);
//!   at each level, Sobel gradients, non-maximum suppression, and edges binned by orientation
//!   (6 bins over 180 degrees, each edge also in its nearer neighbouring bin); each bin gets an
//!   exact Euclidean distance transform.
//! - **Model side** ([`silhouette`]): the key-pose twin (`cpu_twin`'s skinning, welded by
//!   position) is projected through the frame's camera (with its distortion) and rasterised
//!   into a silhouette mask; its outline points are samples of the mesh's contour edges (a
//!   front face next to a back face) that lie on the mask's outer boundary, each with the
//!   orientation of the outline's normal.
//! - **Cost**: the mean over all views' outline points of Tukey's biweight of the distance to
//!   the nearest image edge of the same orientation (bilinear in the distance map), so that the
//!   hand, the tags and the table's grain near the prop cost at most a constant.
//! - **Search** ([`solve`]): at 1/4 resolution a grid over x/y (+-`search_mm`, 9 steps), yaw
//!   (+-`search_deg`, 9 steps) and lift (3 steps); the best few start Levenberg-Marquardt
//!   (iteratively reweighted); then 1/2 and full resolution, re-extracting the outline
//!   between rounds.
//! - **Verdict**: per view, the fraction of outline points within 1.5 px of an edge of the
//!   same orientation ([`ViewAgreement`]); over all views, the conditioning of the normal
//!   equations ([`Conditioning`]): how many pixels the outline moves (RMS) per millimetre
//!   along the weakest and the strongest direction of the translation (and scale), the yaw
//!   marginalised out, and per degree of yaw, the translation marginalised out. Views all from
//!   one direction leave the distance along it weak: their ratio is small. Too few views, a
//!   prop outside the views, a prop not found in the images and weakly constrained answers
//!   are typed errors ([`RegisterError`]).

mod edges;
mod silhouette;
mod solve;
#[cfg(test)]
mod tests;
pub mod track;
pub mod write;

use glam::{DMat3, DMat4, DVec3, Mat4};
use pa_camera::CameraModel;
use pa_model::{anim::Pose, Model};
use rayon::prelude::*;

use crate::shot::Placement;
use edges::{edge_level, grey_roi, half, Roi};
use silhouette::{outline_pixels_of, project, TwinShape};
use solve::ViewData;

/// Errors of registration. Each says what to do about it.
#[derive(Debug, thiserror::Error)]
pub enum RegisterError {
    /// Fewer usable views than the problem needs.
    #[error("registration needs at least {needed} views of the key prop from different directions; {got} given: one view cannot fix the prop's distance along its line of sight")]
    TooFewViews { got: usize, needed: usize },
    /// The marker was tracked in too few of the frames.
    #[error("the marker was tracked in {tracked} of {frames} frames; registration needs at least {needed} tracked frames (show the whole board, in focus)")]
    NotTracked {
        tracked: usize,
        frames: usize,
        needed: usize,
    },
    /// The twin at the start placement is outside (or almost outside) the views.
    #[error("the key prop at the shot's placement is inside only {visible} of {views} views (at least {needed} needed): check the placement and that the prop is in the frames")]
    PropNotVisible {
        visible: usize,
        views: usize,
        needed: usize,
    },
    /// A frame's pixels do not match its size.
    #[error("view {index}: {width}x{height} RGBA8 needs {expected} bytes, got {got}")]
    BadFrame {
        index: usize,
        width: u32,
        height: u32,
        expected: usize,
        got: usize,
    },
    /// The model has no triangles to align.
    #[error("the model has no triangles in its key pose")]
    NoGeometry,
    /// The outline does not match the images: the prop is not in the frames, or far from
    /// the start.
    #[error("the key prop's outline matches the images' edges on only {agreement_pct:.0}% of its length (median of {views} views, at least {needed_pct:.0}% needed): is the key prop standing on the marker in these frames, within {search_mm} mm and {search_deg} degrees of the shot's placement?")]
    NoMatch {
        agreement_pct: f64,
        views: usize,
        needed_pct: f64,
        search_mm: f64,
        search_deg: f64,
    },
    /// The views do not constrain the answer (all from one direction, or too little outline).
    #[error("the views do not constrain the placement: {what} (the views span {spread_deg:.0} degrees): add views from other directions (around the prop, and from higher or lower)")]
    Unconstrained {
        /// What is weak, with the numbers.
        what: String,
        conditioning: Conditioning,
        spread_deg: f64,
    },
    /// The tracker failed (`track` helpers).
    #[error(transparent)]
    Track(#[from] pa_track::TrackError),
}

/// A placement as registration refines it: `marker_from_prop = T(translation) * upright *
/// Ry(yaw) * S(scale)`, as [`Placement::marker_from_prop`] with a uniform scale.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlacementParams {
    pub translation_m: [f64; 3],
    pub yaw_deg: f64,
    pub scale: f64,
    pub upright: bool,
}

impl PlacementParams {
    /// The shot's placement, its `scale` included.
    pub fn from_placement(p: &Placement) -> Self {
        Self {
            translation_m: p.translation_m.map(f64::from),
            yaw_deg: p.yaw_deg as f64,
            scale: p.scale as f64,
            upright: p.upright,
        }
    }

    /// Back to the shot's placement.
    pub fn to_placement(&self) -> Placement {
        Placement {
            translation_m: self.translation_m.map(|v| v as f32),
            upright: self.upright,
            yaw_deg: self.yaw_deg as f32,
            scale: self.scale as f32,
        }
    }

    /// `marker_from_prop`.
    pub fn marker_from_prop(&self) -> DMat4 {
        let upright = if self.upright {
            DMat3::from_cols(DVec3::X, DVec3::NEG_Z, DVec3::Y)
        } else {
            DMat3::IDENTITY
        };
        DMat4::from_translation(DVec3::from(self.translation_m))
            * DMat4::from_mat3(upright)
            * DMat4::from_rotation_y(self.yaw_deg.to_radians())
            * DMat4::from_scale(DVec3::splat(self.scale))
    }

    /// `marker_from_prop` in f32, for the renderer.
    pub fn marker_from_prop_f32(&self) -> Mat4 {
        self.marker_from_prop().as_mat4()
    }

    /// Moved by `d` = [x mm, y mm, z mm, yaw degrees, scale percent].
    pub fn with_delta(&self, d: &[f64; 5]) -> Self {
        Self {
            translation_m: [
                self.translation_m[0] + d[0] * 1e-3,
                self.translation_m[1] + d[1] * 1e-3,
                self.translation_m[2] + d[2] * 1e-3,
            ],
            yaw_deg: self.yaw_deg + d[3],
            scale: self.scale * (1.0 + d[4] * 1e-2),
            upright: self.upright,
        }
    }

    /// The change from `other`: translation (mm), yaw (degrees), scale (percent).
    pub fn change_from(&self, other: &Self) -> [f64; 5] {
        [
            (self.translation_m[0] - other.translation_m[0]) * 1e3,
            (self.translation_m[1] - other.translation_m[1]) * 1e3,
            (self.translation_m[2] - other.translation_m[2]) * 1e3,
            self.yaw_deg - other.yaw_deg,
            (self.scale / other.scale - 1.0) * 1e2,
        ]
    }
}

/// One frame to register from.
#[derive(Debug, Clone)]
pub struct RegisterView {
    /// A name for messages (the still's file name, `video.mp4#12`).
    pub name: String,
    pub width: u32,
    pub height: u32,
    /// sRGB RGBA8, row-major.
    pub rgba8: Vec<u8>,
    pub camera: CameraModel,
    /// The tracked pose of the marker.
    pub camera_from_marker: Mat4,
}

/// What to refine and how far to search.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RegisterSettings {
    /// Also refine a uniform scale.
    pub refine_scale: bool,
    /// The grid's half-width on the table (millimetres).
    pub search_mm: f64,
    /// The grid's half-width in yaw (degrees).
    pub search_deg: f64,
    /// The fewest views accepted.
    pub min_views: usize,
    /// The lowest median edge agreement accepted (0..1).
    pub min_agreement: f64,
    /// The least ratio of the weakest to the strongest translation direction
    /// ([`Conditioning::translation_ratio`]).
    pub min_translation_ratio: f64,
    /// The least ratio of the yaw's pixels per degree to the strongest translation's pixels
    /// per millimetre ([`Conditioning::yaw_ratio`]).
    pub min_yaw_ratio: f64,
}

impl Default for RegisterSettings {
    fn default() -> Self {
        Self {
            refine_scale: false,
            search_mm: 12.0,
            search_deg: 12.0,
            min_views: 2,
            min_agreement: 0.35,
            min_translation_ratio: 0.3,
            min_yaw_ratio: 0.02,
        }
    }
}

/// How well the refined outline agrees with one view.
#[derive(Debug, Clone, PartialEq)]
pub struct ViewAgreement {
    pub name: String,
    /// Outline points compared.
    pub points: usize,
    /// Fraction of them within 1.5 px of an image edge of the same orientation.
    pub edge_agreement: f64,
    /// RMS distance (full-resolution pixels) of those within 3 px.
    pub rms_px: f64,
    /// The same fraction at the start placement.
    pub start_agreement: f64,
}

/// The answer.
#[derive(Debug, Clone, PartialEq)]
pub struct Registration {
    pub start: PlacementParams,
    pub placement: PlacementParams,
    /// RMS outline-to-edge distance over all views' agreeing points (full-resolution px).
    pub residual_px: f64,
    pub views: Vec<ViewAgreement>,
    /// Views skipped because the prop is not inside them at the start placement.
    pub skipped: Vec<String>,
    /// The widest angle between two views' directions to the prop (degrees).
    pub spread_deg: f64,
    pub conditioning: Conditioning,
}

/// How well the views pin the placement down: outline pixels moved (RMS over all views'
/// agreeing points, full resolution) per unit along a direction of the parameters.
#[derive(Debug, Clone, PartialEq)]
pub struct Conditioning {
    /// Px per mm along the weakest direction of the translation, the yaw (and scale)
    /// marginalised out.
    pub translation_weakest: f64,
    /// That direction in words (`y 84%, lift 16%`).
    pub weakest_direction: String,
    /// Px per mm along the strongest direction of the translation.
    pub translation_strongest: f64,
    /// Px per degree of yaw, the translation marginalised out.
    pub yaw_px_per_deg: f64,
    /// Px per percent of scale, the others marginalised out (when the scale is refined).
    pub scale_px_per_pct: Option<f64>,
}

impl Conditioning {
    /// Weakest over strongest translation direction (1 = as well constrained in depth as
    /// across).
    pub fn translation_ratio(&self) -> f64 {
        self.translation_weakest / self.translation_strongest.max(1e-12)
    }

    /// Px per degree of yaw over px per mm of the strongest translation.
    pub fn yaw_ratio(&self) -> f64 {
        self.yaw_px_per_deg / self.translation_strongest.max(1e-12)
    }
}

const NAMES: [&str; 5] = ["x", "y", "lift", "yaw", "scale"];

/// The outline of the key-pose twin, prepared once, for drawing on frames (the preview).
pub struct TwinOutline {
    shape: TwinShape,
}

impl TwinOutline {
    /// The model at its key pose; `None` when it has no triangles.
    pub fn new(model: &Model, key: &Pose) -> Option<Self> {
        TwinShape::new(model, key).map(|shape| Self { shape })
    }

    /// The outline's pixels in a `width` x `height` frame seen through `camera` at
    /// `camera_from_marker`, with the prop placed by `placement`.
    pub fn pixels(
        &self,
        camera: &CameraModel,
        camera_from_marker: Mat4,
        placement: &PlacementParams,
        width: u32,
        height: u32,
    ) -> Vec<(u32, u32)> {
        let m = camera_from_marker.as_dmat4() * placement.marker_from_prop();
        outline_pixels_of(&self.shape, camera, m, width, height)
    }
}

/// Refines `start` from `views` (see the module docs).
pub fn register(
    model: &Model,
    key: &Pose,
    start: PlacementParams,
    views: &[RegisterView],
    settings: &RegisterSettings,
) -> Result<Registration, RegisterError> {
    let needed = settings.min_views.max(2);
    if views.len() < needed {
        return Err(RegisterError::TooFewViews {
            got: views.len(),
            needed,
        });
    }
    for (index, v) in views.iter().enumerate() {
        let expected = v.width as usize * v.height as usize * 4;
        if v.rgba8.len() != expected || v.width < 16 || v.height < 16 {
            return Err(RegisterError::BadFrame {
                index,
                width: v.width,
                height: v.height,
                expected,
                got: v.rgba8.len(),
            });
        }
    }
    let shape = TwinShape::new(model, key).ok_or(RegisterError::NoGeometry)?;
    let n_params = if settings.refine_scale { 5 } else { 4 };

    // The views where the prop is (mostly) inside the frame, each with its region.
    let start_m = start.marker_from_prop();
    let mut kept = Vec::new();
    let mut skipped = Vec::new();
    for v in views {
        match roi_for(&shape, v, start_m, settings) {
            Some(roi) => kept.push((v, roi)),
            None => skipped.push(v.name.clone()),
        }
    }
    if kept.len() < needed {
        return Err(RegisterError::PropNotVisible {
            visible: kept.len(),
            views: views.len(),
            needed,
        });
    }
    let data: Vec<ViewData> = kept
        .par_iter()
        .map(|(v, roi)| {
            let mut img = grey_roi(&v.rgba8, v.width, *roi);
            let (mut w, mut h) = (roi.width as usize, roi.height as usize);
            let origin = (roi.x0 as f64, roi.y0 as f64);
            let mut levels = vec![edge_level(&img, w, h, 1.0, origin)];
            for l in 1..LEVELS {
                let (next, nw, nh) = half(&img, w, h);
                (img, w, h) = (next, nw, nh);
                levels.push(edge_level(&img, w, h, 0.5f64.powi(l as i32), origin));
            }
            ViewData {
                camera: v.camera,
                camera_from_marker: v.camera_from_marker.as_dmat4(),
                levels,
            }
        })
        .collect();

    // Coarse: a grid, then LM from the best few.
    let coarse = LEVELS - 1;
    let tau = |level: usize| TAU_FULL_PX[level] * 0.5f64.powi(level as i32);
    let points = solve::outlines(&shape, &data, coarse, &start);
    let candidates = solve::grid(
        &data,
        &points,
        coarse,
        &start,
        settings.search_mm,
        settings.search_deg,
        4,
        tau(coarse),
        4,
    );
    let mut best = (start, f64::INFINITY);
    for (c, _) in candidates {
        let mut theta = c;
        let mut cost = f64::INFINITY;
        for _ in 0..2 {
            let pts = solve::outlines(&shape, &data, coarse, &theta);
            (theta, cost) = solve::refine(&data, &pts, coarse, theta, n_params, tau(coarse), 12);
        }
        if cost < best.1 {
            best = (theta, cost);
        }
    }
    let mut theta = best.0;
    // Finer levels.
    for level in (0..coarse).rev() {
        for _ in 0..3 {
            let pts = solve::outlines(&shape, &data, level, &theta);
            (theta, _) = solve::refine(&data, &pts, level, theta, n_params, tau(level), 10);
        }
    }

    // Agreement, residual, conditioning.
    let final_points = solve::outlines(&shape, &data, 0, &theta);
    let start_points = solve::outlines(&shape, &data, 0, &start);
    let mut agreements = Vec::new();
    let (mut sq, mut nsq) = (0.0, 0usize);
    for (i, ((v, _), vd)) in kept.iter().zip(&data).enumerate() {
        let (agree, rms_sum, rms_n) = agreement(vd, &final_points[i], &theta);
        let (start_agree, _, _) = agreement(vd, &start_points[i], &start);
        sq += rms_sum;
        nsq += rms_n;
        agreements.push(ViewAgreement {
            name: v.name.clone(),
            points: final_points[i].len(),
            edge_agreement: agree,
            rms_px: if rms_n > 0 {
                (rms_sum / rms_n as f64).sqrt()
            } else {
                f64::NAN
            },
            start_agreement: start_agree,
        });
    }
    let residual_px = if nsq > 0 {
        (sq / nsq as f64).sqrt()
    } else {
        f64::NAN
    };
    let spread_deg = view_spread_deg(&data, &theta);
    let mut sorted: Vec<f64> = agreements.iter().map(|a| a.edge_agreement).collect();
    sorted.sort_by(f64::total_cmp);
    let median = sorted[sorted.len() / 2];
    if median.is_nan() || median < settings.min_agreement {
        return Err(RegisterError::NoMatch {
            agreement_pct: median * 1e2,
            views: agreements.len(),
            needed_pct: settings.min_agreement * 1e2,
            search_mm: settings.search_mm,
            search_deg: settings.search_deg,
        });
    }
    let (h, _, n) =
        solve::normal_equations(&data, &final_points, 0, &theta, n_params, TAU_FULL_PX[0]);
    let conditioning = conditioning(&h, n_params, n);
    let weak = if below(
        conditioning.translation_ratio(),
        settings.min_translation_ratio,
    ) {
        Some(format!(
            "moving the prop 1 mm along {} moves its outline by {:.2} px RMS, {:.0}% of the strongest direction's {:.2} px (at least {:.0}% needed)",
            conditioning.weakest_direction,
            conditioning.translation_weakest,
            conditioning.translation_ratio() * 1e2,
            conditioning.translation_strongest,
            settings.min_translation_ratio * 1e2
        ))
    } else if below(conditioning.yaw_ratio(), settings.min_yaw_ratio) {
        Some(format!(
            "turning the prop 1 degree moves its outline by {:.3} px RMS, {:.1}% of 1 mm's {:.2} px (at least {:.1}% needed: is the prop nearly round?)",
            conditioning.yaw_px_per_deg,
            conditioning.yaw_ratio() * 1e2,
            conditioning.translation_strongest,
            settings.min_yaw_ratio * 1e2
        ))
    } else {
        None
    };
    if let Some(what) = weak {
        return Err(RegisterError::Unconstrained {
            what,
            conditioning,
            spread_deg,
        });
    }
    Ok(Registration {
        start,
        placement: theta,
        residual_px,
        views: agreements,
        skipped,
        spread_deg,
        conditioning,
    })
}

/// Pyramid levels (full, 1/2, 1/4).
const LEVELS: usize = 3;
/// The biweight's cut-off at each level, in full-resolution pixels.
const TAU_FULL_PX: [f64; LEVELS] = [6.0, 10.0, 24.0];

/// The region of a view to compare: the twin's projected box at the start, widened for the
/// search; `None` when less than 60% of the box is inside the frame or it is tiny.
fn roi_for(
    shape: &TwinShape,
    v: &RegisterView,
    marker_from_prop: DMat4,
    settings: &RegisterSettings,
) -> Option<Roi> {
    let p = project(
        shape,
        &v.camera,
        v.camera_from_marker.as_dmat4() * marker_from_prop,
    );
    let mut lo = (f64::INFINITY, f64::INFINITY);
    let mut hi = (f64::NEG_INFINITY, f64::NEG_INFINITY);
    for q in p.pixels.iter().flatten() {
        lo = (lo.0.min(q.x), lo.1.min(q.y));
        hi = (hi.0.max(q.x), hi.1.max(q.y));
    }
    if p.pixels.iter().any(Option::is_none) || !(hi.0 > lo.0 && hi.1 > lo.1) {
        return None;
    }
    let (bw, bh) = (hi.0 - lo.0, hi.1 - lo.1);
    let (w, h) = (v.width as f64, v.height as f64);
    let inside = (hi.0.min(w) - lo.0.max(0.0)).max(0.0) * (hi.1.min(h) - lo.1.max(0.0)).max(0.0);
    if bw < 8.0 || bh < 8.0 || inside < 0.6 * bw * bh {
        return None;
    }
    // The search moves the outline by about the prop's size times the angle, plus the
    // translation seen at the prop's distance.
    let (lo_p, hi_p) = shape.bounds();
    let size_m = (hi_p - lo_p).length().max(1e-6);
    let px_per_m = bw.max(bh) / size_m;
    let margin = px_per_m
        * (settings.search_mm * 1.5e-3 + size_m * 0.5 * settings.search_deg.to_radians())
        + 24.0;
    let x0 = (lo.0 - margin).floor().max(0.0);
    let y0 = (lo.1 - margin).floor().max(0.0);
    let x1 = (hi.0 + margin).ceil().min(w);
    let y1 = (hi.1 + margin).ceil().min(h);
    let roi = Roi {
        x0: x0 as u32,
        y0: y0 as u32,
        width: (x1 - x0) as u32,
        height: (y1 - y0) as u32,
    };
    (roi.width >= 16 && roi.height >= 16).then_some(roi)
}

/// Edge agreement of outline points at level 0: the fraction within 1.5 px, and the sum of
/// squared distances and count of those within 3 px.
fn agreement(
    v: &ViewData,
    points: &[silhouette::OutlinePoint],
    theta: &PlacementParams,
) -> (f64, f64, usize) {
    if points.is_empty() {
        return (0.0, 0.0, 0);
    }
    let lv = &v.levels[0];
    let m = v.camera_from_marker * theta.marker_from_prop();
    let (mut near, mut sq, mut n) = (0usize, 0.0, 0usize);
    for p in points {
        let c = m.transform_point3(p.prop);
        let Some(px) = v.camera.pixel_from_camera(c) else {
            continue;
        };
        let (x, y) = lv.to_level((px.x, px.y));
        let Some((d, _, _)) = lv.sample(p.bin, x, y) else {
            continue;
        };
        if d <= 1.5 {
            near += 1;
        }
        if d <= 3.0 {
            sq += d * d;
            n += 1;
        }
    }
    (near as f64 / points.len() as f64, sq, n)
}

/// The widest angle between the directions from the prop to two cameras (degrees).
fn view_spread_deg(views: &[ViewData], theta: &PlacementParams) -> f64 {
    let prop = theta.marker_from_prop().transform_point3(DVec3::ZERO);
    let dirs: Vec<DVec3> = views
        .iter()
        .map(|v| {
            let eye = v.camera_from_marker.inverse().transform_point3(DVec3::ZERO);
            (eye - prop).normalize_or_zero()
        })
        .collect();
    let mut widest: f64 = 0.0;
    for (i, a) in dirs.iter().enumerate() {
        for b in &dirs[i + 1..] {
            widest = widest.max(a.dot(*b).clamp(-1.0, 1.0).acos().to_degrees());
        }
    }
    widest
}

/// The information of `h` (n x n, units mm, degrees, percent) about the parameters `keep`
/// with the others marginalised out (the Schur complement), as a `keep.len()` block.
fn marginal(h: &[[f64; 5]; 5], n: usize, keep: &[usize]) -> [[f64; 5]; 5] {
    let other: Vec<usize> = (0..n).filter(|i| !keep.contains(i)).collect();
    let mut hoo = [[0.0; 5]; 5];
    for (a, &i) in other.iter().enumerate() {
        for (b, &j) in other.iter().enumerate() {
            hoo[a][b] = h[i][j];
        }
    }
    let mut out = [[0.0; 5]; 5];
    for (a, &i) in keep.iter().enumerate() {
        for (b, &j) in keep.iter().enumerate() {
            out[a][b] = h[i][j];
        }
    }
    if other.is_empty() {
        return out;
    }
    // out -= H_ko H_oo^-1 H_ok, one column of H_ok at a time.
    for (b, &j) in keep.iter().enumerate() {
        let mut col = [0.0; 5];
        for (a, &i) in other.iter().enumerate() {
            col[a] = h[i][j];
        }
        let Some(x) = solve::solve_spd(&hoo, &col, other.len()) else {
            continue;
        };
        for (a, &i) in keep.iter().enumerate() {
            let s: f64 = other.iter().enumerate().map(|(c, &o)| h[i][o] * x[c]).sum();
            out[a][b] -= s;
        }
    }
    out
}

/// The [`Conditioning`] of `h` over `count` agreeing points.
fn conditioning(h: &[[f64; 5]; 5], n: usize, count: usize) -> Conditioning {
    let count = count.max(1) as f64;
    let keep = [0usize, 1, 2];
    let t = marginal(h, n, &keep);
    let (values, vectors) = jacobi_eigen(&t, keep.len());
    let m = keep.len();
    let (kmin, &lmin) = values[..m]
        .iter()
        .enumerate()
        .min_by(|a, b| a.1.total_cmp(b.1))
        .unwrap_or((0, &0.0));
    let lmax = values[..m].iter().copied().fold(0.0, f64::max);
    let v = vectors[kmin];
    let mut parts: Vec<(f64, usize)> = (0..m).map(|a| (v[a].abs(), keep[a])).collect();
    parts.sort_by(|a, b| b.0.total_cmp(&a.0));
    let words: Vec<String> = parts
        .iter()
        .filter(|(a, _)| *a > 0.3)
        .map(|(a, i)| format!("{} {:.0}%", NAMES[*i], a * a * 100.0))
        .collect();
    let yaw = marginal(h, n, &[3])[0][0];
    let scale = (n > 4).then(|| (marginal(h, n, &[4])[0][0].max(0.0) / count).sqrt());
    Conditioning {
        translation_weakest: (lmin.max(0.0) / count).sqrt(),
        weakest_direction: words.join(", "),
        translation_strongest: (lmax.max(0.0) / count).sqrt(),
        yaw_px_per_deg: (yaw.max(0.0) / count).sqrt(),
        scale_px_per_pct: scale,
    }
}

/// True when `v` is below `min` or not a number.
fn below(v: f64, min: f64) -> bool {
    v.is_nan() || v < min
}

/// Eigen-decomposition of the symmetric `n x n` leading block of `a` (cyclic Jacobi):
/// eigenvalues and unit eigenvectors (`vectors[k]` belongs to `values[k]`).
#[allow(clippy::needless_range_loop)]
fn jacobi_eigen(a: &[[f64; 5]; 5], n: usize) -> ([f64; 5], [[f64; 5]; 5]) {
    let mut m = *a;
    let mut v = [[0.0; 5]; 5];
    for (i, row) in v.iter_mut().enumerate() {
        row[i] = 1.0;
    }
    for _ in 0..64 {
        let off: f64 = (0..n)
            .flat_map(|i| (0..n).filter(move |&j| j != i).map(move |j| (i, j)))
            .map(|(i, j)| m[i][j] * m[i][j])
            .sum();
        if off < 1e-20 {
            break;
        }
        for p in 0..n {
            for q in p + 1..n {
                if m[p][q].abs() < 1e-300 {
                    continue;
                }
                let theta = (m[q][q] - m[p][p]) / (2.0 * m[p][q]);
                let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
                let t = if theta == 0.0 { 1.0 } else { t };
                let c = 1.0 / (t * t + 1.0).sqrt();
                let s = t * c;
                for k in 0..n {
                    let (mkp, mkq) = (m[k][p], m[k][q]);
                    m[k][p] = c * mkp - s * mkq;
                    m[k][q] = s * mkp + c * mkq;
                }
                for k in 0..n {
                    let (mpk, mqk) = (m[p][k], m[q][k]);
                    m[p][k] = c * mpk - s * mqk;
                    m[q][k] = s * mpk + c * mqk;
                }
                for row in v.iter_mut().take(n) {
                    let (vp, vq) = (row[p], row[q]);
                    row[p] = c * vp - s * vq;
                    row[q] = s * vp + c * vq;
                }
            }
        }
    }
    let mut values = [0.0; 5];
    let mut vectors = [[0.0; 5]; 5];
    for k in 0..n {
        values[k] = m[k][k];
        for i in 0..n {
            vectors[k][i] = v[i][k];
        }
    }
    (values, vectors)
}
