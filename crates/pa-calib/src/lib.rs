//! Camera calibration for Props Alive: intrinsics and lens distortion from several images of
//! a planar target, a chessboard or the project's own AprilTag board, written as OpenCV's
//! calibration YAML (which `pa_camera::load_calibration` and the tracker read).
//!
//! ```no_run
//! use pa_calib::{CalibOptions, Calibrator, ChessboardSize, Target};
//! # fn main() -> Result<(), pa_calib::CalibrateError> {
//! let mut cal = Calibrator::new(Target::Chessboard {
//!     size: ChessboardSize { rows: 6, cols: 9 },
//!     square_m: 0.025,
//! })?;
//! for path in ["a.png", "b.png", "c.png"] {
//!     let outcome = cal.add_file(std::path::Path::new(path))?; // a view, or why it was skipped
//!     println!("{path}: {outcome}");
//! }
//! let result = cal.calibrate(&CalibOptions::default())?;
//! println!("{:?}, RMS {:.3} px", result.camera, result.rms_px);
//! for w in &result.warnings {
//!     println!("warning: {w}");
//! }
//! # Ok(()) }
//! ```
//!
//! # Conventions
//!
//! - Pixels: OpenCV, the centre of pixel (0, 0) at (0, 0), +x right, +y down.
//! - Board frame: metres, right-handed, +X along a row of corners, +Y down the rows, +Z into
//!   the board (for the AprilTag board: `pa-track`'s marker frame, origin at the board's
//!   centre). Poses are `camera_from_board`, reported as OpenCV does (rotation vector and
//!   translation in metres).
//! - Chessboard sizes count **inner** corners (where four squares meet), `rows` x `cols`;
//!   corners come row-major (see [`find_chessboard`] for the first corner).
//! - Tag corners: `pa-track`'s order (printed top-left, top-right, bottom-right, bottom-left)
//!   and object points ([`pa_track::board::BoardTag::object_points`]).
//! - Errors: RMS reprojection error in pixels, `sqrt(sum |e|^2 / points)` (OpenCV's figure).
//!
//! # Modules
//!
//! [`chessboard`] finds chessboard corners; [`solve`] initialises (Zhang) and refines
//! (Levenberg-Marquardt) the camera; [`yaml`] writes the OpenCV file; [`report`] is the text
//! summary `propsalive calibrate` prints; [`synth`] renders synthetic views of a known camera,
//! for tests and measurements.

pub mod chessboard;
mod linalg;
pub mod report;
pub mod solve;
pub mod synth;
pub mod yaml;

use std::fmt;
use std::path::Path;

use glam::{DVec2, DVec3};
use pa_track::{Board, Detection, Detector, DetectorConfig, GrayImage, TrackError};

pub use chessboard::{find_chessboard, refine_corners, ChessboardSize};
pub use solve::{
    calibrate_views, CalibOptions, Calibration, IntrinsicsStdDev, ViewResult, MIN_VIEWS,
    RECOMMENDED_VIEWS,
};

/// Errors of calibration. Images without a board are not errors (see [`SkipReason`]).
#[derive(Debug, thiserror::Error)]
pub enum CalibrateError {
    /// An image whose size differs from the first image's.
    #[error(
        "{file}: {width}x{height} differs from {expected_width}x{expected_height} of \
         {first_file}; all images must come from one camera at one resolution"
    )]
    SizeMismatch {
        file: String,
        width: u32,
        height: u32,
        first_file: String,
        expected_width: u32,
        expected_height: u32,
    },
    /// No image showed the board.
    #[error("no image shows the board ({images} image(s) read, {skipped} skipped)")]
    NoBoardFound { images: usize, skipped: usize },
    /// Fewer views than the mathematics needs.
    #[error(
        "{found} view(s) of the board; calibration needs at least {needed} at different \
         angles (10-20 recommended)"
    )]
    TooFewViews { found: usize, needed: usize },
    /// A view's data cannot be used.
    #[error("view {view}: {reason}")]
    BadView { view: String, reason: String },
    /// The views do not determine a camera.
    #[error("degenerate geometry: {reason}")]
    Degenerate { reason: String },
    /// The target's description is invalid.
    #[error("invalid calibration target: {reason}")]
    InvalidTarget { reason: String },
    /// From the AprilTag detector or board.
    #[error(transparent)]
    Track(#[from] TrackError),
}

/// A doubt about a calibration; the result is usable but should be checked.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub enum CalibWarning {
    /// Fewer views than recommended.
    FewViews { views: usize, recommended: usize },
    /// All board normals lie within `max_angle_deg` of each other: focal length and
    /// principal point are weakly separated from the distance (Zhang's degenerate case).
    SimilarViews {
        max_angle_deg: f64,
        threshold_deg: f64,
    },
    /// A parameter's standard deviation (pixels), judged at `judged_noise_px` of corner noise
    /// per coordinate
    /// (this calibration's own RMS error, but no less than 0.1 px, so that clean but
    /// degenerate views are caught too), exceeds `limit_px`. `std_dev_px` is at this
    /// calibration's own noise.
    PoorlyConstrained {
        parameter: &'static str,
        std_dev_px: f64,
        judged_noise_px: f64,
        judged_std_dev_px: f64,
        limit_px: f64,
    },
    /// The corners of all views together reach only `fraction` of the image (8 x 8 cells):
    /// distortion toward the edges is extrapolated.
    LowCoverage { fraction: f64, recommended: f64 },
    /// A view whose error is far above the others' (a misdetection or motion blur?).
    OutlierView {
        view: String,
        rms_px: f64,
        median_rms_px: f64,
    },
}

impl fmt::Display for CalibWarning {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            CalibWarning::FewViews { views, recommended } => write!(
                f,
                "only {views} view(s); use at least {recommended} (10-20 is better), \
                 tilted differently"
            ),
            CalibWarning::SimilarViews {
                max_angle_deg,
                threshold_deg,
            } => write!(
                f,
                "the views are too alike: every board normal is within {max_angle_deg:.1} \
                 degrees of the others (want more than {threshold_deg}); tilt the board \
                 30-50 degrees in different directions"
            ),
            CalibWarning::PoorlyConstrained {
                parameter,
                std_dev_px,
                judged_noise_px,
                judged_std_dev_px,
                limit_px,
            } => write!(
                f,
                "{parameter} is poorly constrained: standard deviation {judged_std_dev_px:.2} px \
                 at {judged_noise_px:.2} px of corner noise (limit {limit_px:.2} px; \
                 {std_dev_px:.2} px at this calibration's noise); add views tilted in other \
                 directions"
            ),
            CalibWarning::LowCoverage {
                fraction,
                recommended,
            } => write!(
                f,
                "the corners cover only {:.0} % of the image (want {:.0} %): distortion \
                 toward the edges is extrapolated; add views with the board near the edges \
                 and corners",
                fraction * 100.0,
                recommended * 100.0
            ),
            CalibWarning::OutlierView {
                view,
                rms_px,
                median_rms_px,
            } => write!(
                f,
                "view {view} has an RMS error of {rms_px:.3} px against a median of \
                 {median_rms_px:.3} px: check it (misdetection, motion blur?) and drop it"
            ),
        }
    }
}

/// Correspondences of one image: board points and where they were seen.
#[derive(Debug, Clone, PartialEq)]
pub struct View {
    /// The image's name (its file), for messages.
    pub name: String,
    /// Board points (board frame, metres, z = 0).
    pub object_points_m: Vec<DVec3>,
    /// Their pixels (OpenCV pixel centres).
    pub image_points_px: Vec<DVec2>,
}

/// What the images show.
#[derive(Debug, Clone, PartialEq)]
pub enum Target {
    /// A chessboard with `size` inner corners and squares of `square_m` metres.
    Chessboard { size: ChessboardSize, square_m: f64 },
    /// An AprilTag board ([`Board::grid`], as `propsalive marker --board` prints it); every
    /// corner of every detected tag of the board is used. Images with fewer than
    /// `min_tags` of its tags are skipped.
    TagBoard { board: Board, min_tags: usize },
}

impl Target {
    /// The board points of a chessboard's corners in [`find_chessboard`]'s order:
    /// `(c * square_m, r * square_m, 0)` for corner `(r, c)`.
    pub fn chessboard_points(size: ChessboardSize, square_m: f64) -> Vec<DVec3> {
        (0..size.rows)
            .flat_map(|r| {
                (0..size.cols)
                    .map(move |c| DVec3::new(c as f64 * square_m, r as f64 * square_m, 0.0))
            })
            .collect()
    }
}

/// Correspondences from AprilTag detections of a board: the four corners of every detected
/// tag of `board` (the detection with the best decision margin where an id repeats), tags
/// in the board's order.
pub fn tag_board_correspondences(board: &Board, detections: &[Detection]) -> Vec<(DVec3, DVec2)> {
    let mut out = Vec::new();
    for tag in &board.tags {
        let best = detections
            .iter()
            .filter(|d| d.family == board.family && d.id == tag.id)
            .max_by(|a, b| a.decision_margin.total_cmp(&b.decision_margin));
        if let Some(d) = best {
            out.extend(tag.object_points().into_iter().zip(d.corners_px));
        }
    }
    out
}

/// Why an image gave no view.
#[derive(Debug, Clone, PartialEq)]
pub enum SkipReason {
    /// The file could not be read or decoded.
    Unreadable { error: String },
    /// No complete chessboard of the given size was found.
    NoChessboard { size: ChessboardSize },
    /// Too few tags of the board were found.
    TooFewTags { found: usize, needed: usize },
}

impl fmt::Display for SkipReason {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SkipReason::Unreadable { error } => write!(f, "cannot read the image: {error}"),
            SkipReason::NoChessboard { size } => write!(
                f,
                "no chessboard of {}x{} inner corners found (it must be fully visible)",
                size.rows, size.cols
            ),
            SkipReason::TooFewTags { found, needed } => write!(
                f,
                "{found} tag(s) of the board found, at least {needed} needed"
            ),
        }
    }
}

/// An image that gave no view.
#[derive(Debug, Clone, PartialEq)]
pub struct Skipped {
    /// The image's name (its file).
    pub name: String,
    pub reason: SkipReason,
}

/// What became of one image.
#[derive(Debug, Clone, PartialEq)]
pub enum ImageOutcome {
    /// A view with this many correspondences.
    View { points: usize },
    /// No view; why.
    Skipped(SkipReason),
}

impl fmt::Display for ImageOutcome {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ImageOutcome::View { points } => write!(f, "{points} corners"),
            ImageOutcome::Skipped(r) => write!(f, "skipped: {r}"),
        }
    }
}

/// Why [`read_image`] failed: the message of the error it wraps.
#[derive(Debug, thiserror::Error)]
enum ReadImageError {
    #[error("{0}")]
    Open(pa_io::IoError),
    #[error("{0}")]
    Sniff(std::io::Error),
    #[error("{0}")]
    Decode(image::ImageError),
}

/// Decodes an image file, opened only if it is a regular file ([`pa_io::open_regular`]).
/// The format comes from the extension, else from the content; the decoder's default
/// allocation limits apply.
fn read_image(path: &Path) -> Result<image::DynamicImage, ReadImageError> {
    let file = pa_io::open_regular(path).map_err(ReadImageError::Open)?;
    let mut reader = image::ImageReader::new(std::io::BufReader::new(file));
    match image::ImageFormat::from_path(path) {
        Ok(format) => reader.set_format(format),
        Err(_) => {
            reader = reader
                .with_guessed_format()
                .map_err(ReadImageError::Sniff)?
        }
    }
    reader.decode().map_err(ReadImageError::Decode)
}

/// Collects views from images, one at a time, then calibrates.
pub struct Calibrator {
    target: Target,
    detector: Option<Detector>,
    size: Option<(u32, u32, String)>,
    images: usize,
    views: Vec<View>,
    skipped: Vec<Skipped>,
}

impl Calibrator {
    /// A calibrator for `target`. Fails for a chessboard under 2x2 inner corners, a square
    /// size that is not a positive length, or a tag board without tags, with a tag whose id
    /// is past its family's codes, with an id twice, or with a tag whose size or place is not
    /// a finite number.
    pub fn new(target: Target) -> Result<Self, CalibrateError> {
        let invalid = |reason: String| Err(CalibrateError::InvalidTarget { reason });
        let detector = match &target {
            Target::Chessboard { size, square_m } => {
                if size.rows < 2 || size.cols < 2 {
                    return invalid(format!(
                        "a chessboard needs at least 2x2 inner corners, got {}x{}",
                        size.rows, size.cols
                    ));
                }
                if !(square_m.is_finite() && *square_m > 0.0) {
                    return invalid(format!("square size {square_m} m"));
                }
                None
            }
            Target::TagBoard { board, .. } => {
                if board.tags.is_empty() {
                    return invalid("the board has no tags".into());
                }
                let codes = pa_track::family_layout(board.family)?.id_count;
                let mut ids = std::collections::HashSet::new();
                for t in &board.tags {
                    if t.id >= codes {
                        return invalid(format!(
                            "tag id {} does not exist in {} (ids 0..={})",
                            t.id,
                            board.family,
                            codes.saturating_sub(1)
                        ));
                    }
                    if !ids.insert(t.id) {
                        return invalid(format!("tag id {} is on the board twice", t.id));
                    }
                    let finite = t.center_m.is_finite() && t.rotation_rad.is_finite();
                    if !(finite && t.size_m.is_finite() && t.size_m > 0.0) {
                        return invalid(format!(
                            "tag {}: size, centre and rotation must be finite, the size > 0",
                            t.id
                        ));
                    }
                }
                Some(Detector::new(DetectorConfig {
                    families: vec![board.family],
                    ..DetectorConfig::default()
                })?)
            }
        };
        Ok(Self {
            target,
            detector,
            size: None,
            images: 0,
            views: Vec::new(),
            skipped: Vec::new(),
        })
    }

    /// Reads an image file (PNG, JPEG, TIFF, ...; colour is converted to grey with Rec. 601
    /// weights) and adds it. An unreadable file is skipped, not an error; so is anything but a
    /// regular file (a FIFO or a device is refused at once, not waited on).
    pub fn add_file(&mut self, path: &Path) -> Result<ImageOutcome, CalibrateError> {
        let name = path.display().to_string();
        match read_image(path) {
            Ok(img) => self.add_image(&name, &GrayImage::from(&img)),
            Err(e) => {
                self.images += 1;
                let reason = SkipReason::Unreadable {
                    error: e.to_string(),
                };
                self.skipped.push(Skipped {
                    name,
                    reason: reason.clone(),
                });
                Ok(ImageOutcome::Skipped(reason))
            }
        }
    }

    /// Adds an image named `name`. Errors when its size differs from the first image's.
    pub fn add_image(
        &mut self,
        name: &str,
        image: &GrayImage,
    ) -> Result<ImageOutcome, CalibrateError> {
        if image.data.len() != image.width as usize * image.height as usize {
            return Err(TrackError::BadImage {
                width: image.width,
                height: image.height,
                len: image.data.len(),
            }
            .into());
        }
        match &self.size {
            Some((w, h, first)) if (*w, *h) != (image.width, image.height) => {
                return Err(CalibrateError::SizeMismatch {
                    file: name.to_string(),
                    width: image.width,
                    height: image.height,
                    first_file: first.clone(),
                    expected_width: *w,
                    expected_height: *h,
                });
            }
            Some(_) => {}
            None => self.size = Some((image.width, image.height, name.to_string())),
        }
        self.images += 1;
        let found: Result<Vec<(DVec3, DVec2)>, SkipReason> = match &self.target {
            Target::Chessboard { size, square_m } => match find_chessboard(image, *size) {
                Some(corners) => Ok(Target::chessboard_points(*size, *square_m)
                    .into_iter()
                    .zip(corners)
                    .collect()),
                None => Err(SkipReason::NoChessboard { size: *size }),
            },
            Target::TagBoard { board, min_tags } => {
                let detections = match self.detector.as_mut() {
                    Some(d) => d.detect(image)?,
                    None => Vec::new(),
                };
                let pairs = tag_board_correspondences(board, &detections);
                let tags = pairs.len() / 4;
                let needed = (*min_tags).max(1);
                if tags < needed {
                    Err(SkipReason::TooFewTags {
                        found: tags,
                        needed,
                    })
                } else {
                    Ok(pairs)
                }
            }
        };
        match found {
            Ok(pairs) => {
                let points = pairs.len();
                let (object_points_m, image_points_px) = pairs.into_iter().unzip();
                self.views.push(View {
                    name: name.to_string(),
                    object_points_m,
                    image_points_px,
                });
                Ok(ImageOutcome::View { points })
            }
            Err(reason) => {
                self.skipped.push(Skipped {
                    name: name.to_string(),
                    reason: reason.clone(),
                });
                Ok(ImageOutcome::Skipped(reason))
            }
        }
    }

    /// The views collected so far.
    pub fn views(&self) -> &[View] {
        &self.views
    }

    /// The images skipped so far, with the reason.
    pub fn skipped(&self) -> &[Skipped] {
        &self.skipped
    }

    /// The image size (of the first readable image).
    pub fn image_size(&self) -> Option<(u32, u32)> {
        self.size.as_ref().map(|(w, h, _)| (*w, *h))
    }

    /// The target.
    pub fn target(&self) -> &Target {
        &self.target
    }

    /// Calibrates from the views collected ([`calibrate_views`]).
    pub fn calibrate(&self, options: &CalibOptions) -> Result<Calibration, CalibrateError> {
        let Some((w, h)) = self.image_size().filter(|_| !self.views.is_empty()) else {
            return Err(CalibrateError::NoBoardFound {
                images: self.images,
                skipped: self.skipped.len(),
            });
        };
        calibrate_views(&self.views, w, h, options)
    }
}
