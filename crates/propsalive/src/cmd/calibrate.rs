//! `propsalive calibrate IMAGES... (--chessboard ROWSxCOLS --square-mm S | --board ROWSxCOLS
//! --size-mm S --gap-mm G [--first-id N] [--family F]) --out camera.yaml [--force]`: camera
//! intrinsics and lens distortion from images of a planar target (`pa_calib`), written as
//! OpenCV calibration YAML that `track --calib`, `run` and OpenCV itself read.
//!
//! Decisions:
//! - IMAGES are files or folders (a folder's images in natural order); an image that cannot
//!   be read or shows no (complete) board is listed as skipped with the reason, not an error.
//!   Images of different sizes are an error naming both files. Fewer than two views is an
//!   error; the library's warnings (few or alike views, poorly constrained parameters, low
//!   coverage, an outlier view) are printed on stderr and do not stop the output.
//! - `--chessboard` counts **inner** corners (OpenCV's `patternSize`); `--board` is the
//!   AprilTag board of `propsalive marker --board` with the same `--size-mm`, `--gap-mm` and
//!   `--first-id`.
//! - k3 is fixed at 0 unless `--k3` (wide-angle lenses); `--zero-tangent` fixes p1 = p2 = 0.
//! - The output must be `.yaml` or `.yml`; it is written atomically (`pa_io`) and an existing
//!   file is kept unless `--force`. That is checked before any image is read. A FIFO, device
//!   or link in its place is never replaced, even with `--force`.
//! - `--board`: every id from `--first-id` to `--first-id + ROWS * COLS - 1` must be a code of
//!   `--family` (tag36h11 has 587), checked before the board is built.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use pa_calib::{CalibOptions, Calibrator, ChessboardSize, ImageOutcome, Target};
use pa_track::{Board, TagFamily};

#[derive(clap::Args)]
pub struct Args {
    /// Images (.png, .jpg, .tif) or folders of them, at least two views of the target.
    #[arg(required = true)]
    pub images: Vec<PathBuf>,
    /// A chessboard with ROWSxCOLS inner corners (where four squares meet), e.g. 6x9.
    #[arg(long, required_unless_present = "board", conflicts_with = "board")]
    pub chessboard: Option<String>,
    /// Side of a chessboard square in millimetres.
    #[arg(long, requires = "chessboard")]
    pub square_mm: Option<f64>,
    /// An AprilTag board of ROWSxCOLS tags, as `propsalive marker --board` prints it.
    #[arg(long)]
    pub board: Option<String>,
    /// Side of a board tag's black border square in millimetres (`marker --size-mm`).
    #[arg(long, requires = "board")]
    pub size_mm: Option<f64>,
    /// Gap between the black squares of neighbouring board tags in millimetres
    /// (`marker --gap-mm`; the marker's label prints it).
    #[arg(long, requires = "board")]
    pub gap_mm: Option<f64>,
    /// Id of the board's top-left tag; ids run row-major.
    #[arg(long, default_value_t = 0)]
    pub first_id: u32,
    /// Tag family of the board.
    #[arg(long, default_value = "tag36h11")]
    pub family: String,
    /// Board images with fewer of its tags than this are skipped.
    #[arg(long, default_value_t = 2)]
    pub min_tags: usize,
    /// Estimate the sixth-order radial term k3 too (wide-angle lenses; views must reach the
    /// image corners). By default k3 = 0.
    #[arg(long)]
    pub k3: bool,
    /// Assume no tangential distortion (p1 = p2 = 0).
    #[arg(long)]
    pub zero_tangent: bool,
    /// Output: OpenCV calibration YAML (.yaml or .yml).
    #[arg(long, short)]
    pub out: PathBuf,
    /// Replace the output file if it exists.
    #[arg(long)]
    pub force: bool,
}

fn parse_grid(flag: &str, s: &str) -> Result<(u32, u32)> {
    let Some((r, c)) = s.split_once(['x', 'X']) else {
        bail!("{flag} {s:?} must look like ROWSxCOLS, e.g. 6x9");
    };
    let r: u32 = r
        .trim()
        .parse()
        .with_context(|| format!("{flag} {s:?}: rows"))?;
    let c: u32 = c
        .trim()
        .parse()
        .with_context(|| format!("{flag} {s:?}: columns"))?;
    if r == 0 || c == 0 || r > 1000 || c > 1000 {
        bail!("{flag} {s:?}: rows and columns must be in 1..=1000");
    }
    Ok((r, c))
}

fn positive_mm(flag: &str, v: Option<f64>) -> Result<f64> {
    match v {
        Some(v) if v.is_finite() && v > 0.0 && v <= 10_000.0 => Ok(v),
        Some(v) => bail!("{flag} must be a length in (0, 10000] mm, got {v}"),
        None => bail!("{flag} is required"),
    }
}

/// The resolved, checked configuration.
pub struct Config {
    pub images: Vec<PathBuf>,
    pub target: Target,
    pub description: String,
    pub options: CalibOptions,
    pub out: PathBuf,
}

/// Checks the flags and lists the images (nothing is read or written).
pub fn resolve(args: &Args) -> Result<Config> {
    let ext = args
        .out
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    if !matches!(ext.as_deref(), Some("yaml" | "yml")) {
        bail!(
            "--out {}: the calibration is written as OpenCV YAML; name it .yaml or .yml",
            args.out.display()
        );
    }
    if args.out.exists() && !args.force {
        bail!("{} exists; pass --force to replace it", args.out.display());
    }
    let (target, description) = match (&args.chessboard, &args.board) {
        (Some(cb), None) => {
            let (rows, cols) = parse_grid("--chessboard", cb)?;
            if rows < 2 || cols < 2 {
                bail!("--chessboard {cb:?}: a chessboard needs at least 2x2 inner corners");
            }
            let square_mm = positive_mm("--square-mm", args.square_mm)?;
            (
                Target::Chessboard {
                    size: ChessboardSize { rows, cols },
                    square_m: square_mm / 1000.0,
                },
                format!("chessboard of {rows}x{cols} inner corners, {square_mm} mm squares"),
            )
        }
        (None, Some(b)) => {
            let (rows, cols) = parse_grid("--board", b)?;
            let size_mm = positive_mm("--size-mm", args.size_mm)?;
            let gap_mm = match args.gap_mm {
                Some(g) if g.is_finite() && (0.0..=10_000.0).contains(&g) => g,
                Some(g) => bail!("--gap-mm must be in [0, 10000] mm, got {g}"),
                None => bail!("--gap-mm is required with --board (the marker's label prints it)"),
            };
            let family: TagFamily = args.family.parse()?;
            // The ids first_id.. first_id + rows * cols - 1 must all be codes of the family
            // (checked arithmetic: a huge --first-id must not wrap around).
            let codes = pa_track::family_layout(family)?.id_count;
            let end = rows
                .checked_mul(cols)
                .and_then(|n| args.first_id.checked_add(n));
            if end.is_none_or(|end| end > codes) {
                bail!(
                    "--board {b:?} --first-id {}: the board needs ids {}..={} but {family} has \
                     {codes} codes (ids 0..={})",
                    args.first_id,
                    args.first_id,
                    args.first_id as u64 + rows as u64 * cols as u64 - 1,
                    codes.saturating_sub(1)
                );
            }
            let board = Board::grid(
                family,
                rows,
                cols,
                size_mm / 1000.0,
                gap_mm / 1000.0,
                args.first_id,
            )?;
            let last = board.tags.last().map_or(args.first_id, |t| t.id);
            (
                Target::TagBoard {
                    board,
                    min_tags: args.min_tags.max(1),
                },
                format!(
                    "{family} board of {rows}x{cols} tags (ids {}..={last}), {size_mm} mm tags, {gap_mm} mm gaps",
                    args.first_id
                ),
            )
        }
        _ => bail!("give either --chessboard ROWSxCOLS --square-mm S or --board ROWSxCOLS --size-mm S --gap-mm G"),
    };
    let mut images = Vec::new();
    for input in &args.images {
        let (frames, _) = super::track::list_frames(input)?;
        images.extend(frames);
    }
    Ok(Config {
        images,
        target,
        description,
        options: CalibOptions {
            fix_k3: !args.k3,
            fix_tangential: args.zero_tangent,
            ..CalibOptions::default()
        },
        out: args.out.clone(),
    })
}

fn name(p: &Path) -> String {
    p.display().to_string()
}

pub fn run(args: Args) -> Result<()> {
    let cfg = resolve(&args)?;
    outln!(
        "calibrating from {} image(s): {}",
        cfg.images.len(),
        cfg.description
    );
    let mut cal = Calibrator::new(cfg.target.clone())?;
    for path in &cfg.images {
        match cal.add_file(path)? {
            ImageOutcome::View { points } => outln!("  {}: {points} corners", name(path)),
            ImageOutcome::Skipped(reason) => {
                outln!("  {}: skipped ({reason})", name(path));
            }
        }
    }
    let views = cal.views().len();
    outln!(
        "{views} view(s) of {} image(s); {} skipped",
        cfg.images.len(),
        cal.skipped().len()
    );
    let result = cal.calibrate(&cfg.options)?;

    out!("{}", pa_calib::report::summary(&result, &cfg.options));
    for w in &result.warnings {
        errln!("warning: {w}");
    }
    let text = pa_calib::yaml::to_opencv_yaml(&result, Some(&cfg.target));
    if let Some(dir) = cfg.out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir)
            .with_context(|| format!("creating folder {}", dir.display()))?;
    }
    // Atomic either way (pa_io): without --force the name is taken only if still free (another
    // process may have made it meanwhile); with it, a file that is not a regular file (a FIFO,
    // a device, a link) is still never replaced.
    if args.force {
        pa_model::export::write_atomic(&cfg.out, text.as_bytes())
            .with_context(|| format!("writing {}", cfg.out.display()))?;
    } else if !pa_model::export::write_new_atomic(&cfg.out, text.as_bytes())
        .with_context(|| format!("writing {}", cfg.out.display()))?
    {
        bail!("{} exists; pass --force to replace it", cfg.out.display());
    }
    outln!("wrote {}", cfg.out.display());
    Ok(())
}
