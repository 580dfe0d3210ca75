//! `propsalive marker --family tag36h11 --id 0 --size-mm 80 [--dpi 300] --out STEM_OR_DIR`:
//! a printable marker (or, with `--board ROWSxCOLS --gap-mm G --first-id N`, a board of
//! tags laid out exactly as [`pa_track::Board::grid`] expects).
//!
//! Two files are written, atomically and never over existing ones without `--force`:
//! - `STEM.svg` at true physical size (`width`/`height` in `mm`, `viewBox` in mm), with the
//!   family, ids, tag size and a "print at 100 %" note as `<text>` in the bottom margin;
//! - `STEM.png` rasterised at `--dpi`, with the DPI stored in its `pHYs` chunk (so image
//!   viewers and print dialogs know the physical size). The PNG carries **no visible text**
//!   (no font is built in); the same label is stored in its `tEXt` metadata (`Title`,
//!   `Description`) and in the file name.
//!
//! With `--shot SHOT.toml`, the sheet is the shot's board (its `[[marker.tags]]`, each at its
//! centre and size) with the footprint of each key prop: where its key pose, placed by the
//! shot's `[placement]`, touches the table (the convex hull of the vertices within 2 mm of the
//! lowest, `pa_pipeline::footprint`), labelled with the key's name, and an arrow to the prop's
//! front, so that the print and the prop on it stand where the shot says.
//!
//! The size given is the side of the tag's black border square, the quantity the tracker's
//! `--tag-size-m` means. Board tags are centred at `(c - (cols-1)/2, r - (rows-1)/2) *
//! (size + gap)` from the board centre, ids row-major from the top-left as printed.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use pa_overlay::sheet::{encode_png, raster, svg, Footprint, Sheet, SheetScale, TagAt};
use pa_pipeline::footprint;
use pa_pipeline::shot::Shot;
use pa_track::TagFamily;

#[derive(clap::Args)]
pub struct Args {
    /// Tag family (tag36h11, tag25h9, tag16h5, tagStandard41h12, ...).
    #[arg(long, default_value = "tag36h11")]
    pub family: String,
    /// Tag id (single marker).
    #[arg(long, default_value_t = 0, conflicts_with = "board")]
    pub id: u32,
    /// Side of the tag's black border square in millimetres (what the tracker calls the
    /// tag size).
    #[arg(long, required_unless_present_any = ["shot", "image", "check"])]
    pub size_mm: Option<f64>,
    /// Check whether PICTURE can be tracked as an image target (keypoints, spread,
    /// repetition) and write nothing: see `marker_check`.
    #[arg(long, conflicts_with_all = ["shot", "board", "size_mm", "out"])]
    pub check: Option<PathBuf>,
    /// Print a shot's board (its `[[marker.tags]]`) with the footprint of each key prop (the
    /// outline of where its key pose touches the table, its name and a front arrow) instead
    /// of --family/--id/--board/--size-mm.
    #[arg(long, conflicts_with_all = ["board", "size_mm", "id", "family"])]
    pub shot: Option<PathBuf>,
    /// Print a picture at true size (with a scale bar) instead of a tag:
    /// `--image PICTURE --width-mm W` (`cmd/marker_image.rs`).
    #[arg(long, requires = "width_mm", conflicts_with_all = ["board", "size_mm", "shot"])]
    pub image: Option<PathBuf>,
    /// The picture's printed width in millimetres (its height follows its aspect).
    #[arg(long, requires = "image")]
    pub width_mm: Option<f64>,
    /// Resolution of the PNG in dots per inch.
    #[arg(long, default_value_t = 300.0)]
    pub dpi: f64,
    /// A board of ROWSxCOLS tags instead of one tag.
    #[arg(long)]
    pub board: Option<String>,
    /// Gap between the black squares of neighbouring board tags, millimetres
    /// (default: two cells of the tag).
    #[arg(long, requires = "board")]
    pub gap_mm: Option<f64>,
    /// Id of the board's top-left tag; ids run row-major.
    #[arg(long, default_value_t = 0, requires = "board")]
    pub first_id: u32,
    /// White margin around the tag(s) in millimetres (the label goes in the bottom margin).
    #[arg(long, default_value_t = 10.0)]
    pub margin_mm: f64,
    /// Output: a file stem (`out/tag0` gives out/tag0.png and out/tag0.svg; a .png or .svg
    /// extension is dropped) or an existing folder (or a path ending in `/`), in which a name
    /// is made from the family, ids and size.
    #[arg(long, short, required_unless_present = "check")]
    pub out: Option<PathBuf>,
    /// Replace output files that exist.
    #[arg(long)]
    pub force: bool,
}

/// A sheet and the two files it goes to.
pub struct Output {
    pub sheet: Sheet,
    pub png: PathBuf,
    pub svg: PathBuf,
}

/// The sheet of a shot: its board and the footprints of its key poses.
fn shot_sheet(args: &Args, shot_path: &Path) -> Result<Sheet> {
    let shot = Shot::load(shot_path)?;
    if shot.marker.tags.is_empty() {
        bail!(
            "{}: the marker is a picture without tags: print the picture itself with `propsalive marker --image PICTURE --width-mm W --out STEM`",
            shot_path.display()
        );
    }
    let model_path = Shot::resolve(shot_path, &shot.model);
    let model = pa_model::Model::load(&model_path)?;
    let anim = shot.check_model(shot_path, &model)?;
    let family: TagFamily = shot.marker.family.parse()?;
    let tags: Vec<TagAt> = shot
        .marker
        .tags
        .iter()
        .map(|t| TagAt {
            id: t.id,
            center_mm: (t.center_m[0] * 1000.0, t.center_m[1] * 1000.0),
            size_mm: t.size_m * 1000.0,
        })
        .collect();
    let smallest = tags.iter().map(|t| t.size_mm).fold(f64::INFINITY, f64::min);
    let scale = SheetScale::new(family, smallest, args.dpi, args.margin_mm)?;
    let marker_from_prop = shot.placement.marker_from_prop();
    let mut footprints = Vec::new();
    for (line, k) in shot.key_poses.iter().enumerate() {
        let points = footprint::posed_points(
            &model,
            Some(anim),
            k.frame as f32 / shot.fps,
            marker_from_prop,
        );
        let fp = footprint::footprint(&points, marker_from_prop, footprint::CONTACT_BAND_M)
            .with_context(|| format!("{}: the model has no vertices", model_path.display()))?;
        if fp.lowest_z_m.abs() > 0.001 {
            errln!(
                "note: key pose {:?} {} the sheet by {:.1} mm (its lowest point; [placement] translation_m[2])",
                k.name,
                if fp.lowest_z_m < 0.0 { "floats above" } else { "sinks into" },
                fp.lowest_z_m.abs() * 1000.0
            );
        }
        footprints.push(Footprint {
            name: k.name.clone(),
            outline_mm: fp
                .outline_m
                .iter()
                .map(|p| (p.x * 1000.0, p.y * 1000.0))
                .collect(),
            centre_mm: (fp.centre_m.x * 1000.0, fp.centre_m.y * 1000.0),
            front: (fp.front.x, fp.front.y),
            label_line: line as u32,
        });
    }
    let name = shot_path.file_name().map_or_else(
        || shot_path.display().to_string(),
        |n| n.to_string_lossy().into_owned(),
    );
    let mut sheet = scale.layout_tags(
        &tags,
        footprints,
        &format!("shot {name}: board and key prop footprints"),
    )?;
    sheet.file_stem = format!(
        "{}_board",
        shot_path
            .file_stem()
            .map_or_else(|| "shot".into(), |s| s.to_string_lossy().into_owned())
    );
    Ok(sheet)
}

/// Resolves and checks the flags (nothing is written).
pub fn resolve(args: &Args) -> Result<Output> {
    let sheet = match (&args.shot, args.size_mm) {
        (Some(shot), _) => shot_sheet(args, shot)?,
        (None, Some(size_mm)) => {
            let family: TagFamily = args.family.parse()?;
            let scale = SheetScale::new(family, size_mm, args.dpi, args.margin_mm)?;
            let board = match &args.board {
                Some(b) => Some(super::parse_grid(b)?),
                None => None,
            };
            let first_id = if args.board.is_some() {
                args.first_id
            } else {
                args.id
            };
            scale.layout(board, first_id, args.gap_mm)?
        }
        (None, None) => bail!("--size-mm or --shot is needed"),
    };
    let out = args.out.as_deref().context("--out is needed")?;
    let (png, svg) = output_pair(out, &sheet.file_stem, args.force)?;
    sheet.check_png_size()?;
    Ok(Output { sheet, png, svg })
}

/// The `.png` and `.svg` files of `--out`: a stem, a `.png`/`.svg` path (extension dropped)
/// or a folder (`default_stem` inside it); refused where one exists, unless `force`.
pub(crate) fn output_pair(
    out: &Path,
    default_stem: &str,
    force: bool,
) -> Result<(PathBuf, PathBuf)> {
    let out_str = out.to_string_lossy();
    let stem = if out.is_dir() || out_str.ends_with('/') || out_str.ends_with('\\') {
        out.join(default_stem)
    } else {
        match out.extension().and_then(|e| e.to_str()) {
            Some(e) if e.eq_ignore_ascii_case("png") || e.eq_ignore_ascii_case("svg") => {
                out.with_extension("")
            }
            _ => out.to_path_buf(),
        }
    };
    let with_ext = |ext: &str| {
        let mut s = stem.clone().into_os_string();
        s.push(".");
        s.push(ext);
        PathBuf::from(s)
    };
    let (png, svg) = (with_ext("png"), with_ext("svg"));
    for p in [&png, &svg] {
        if p.exists() && !force {
            bail!("{} exists; pass --force to replace it", p.display());
        }
    }
    Ok((png, svg))
}

fn write_sheet(out: &Output) -> Result<()> {
    let sheet = &out.sheet;
    for p in [&out.png, &out.svg] {
        if let Some(dir) = p.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir)
                .with_context(|| format!("creating folder {}", dir.display()))?;
        }
    }
    let img = raster(sheet);
    let label = sheet.label.join("; ");
    let png = encode_png(
        &img,
        sheet.dpi,
        &[
            ("Title", sheet.label[0].as_str()),
            ("Description", label.as_str()),
            ("Software", "propsalive marker"),
        ],
    )?;
    pa_model::export::write_atomic(&out.png, &png)
        .with_context(|| format!("writing {}", out.png.display()))?;
    pa_model::export::write_atomic(&out.svg, svg(sheet).as_bytes())
        .with_context(|| format!("writing {}", out.svg.display()))?;
    Ok(())
}

fn describe(sheet: &Sheet, path: &Path) -> String {
    path.display().to_string() + &format!(" ({:.1} x {:.1} mm)", sheet.page_w_mm, sheet.page_h_mm)
}

pub fn run(args: Args) -> Result<()> {
    if let Some(picture) = &args.check {
        return super::marker_check::run(picture);
    }
    if let (Some(picture), Some(w)) = (&args.image, args.width_mm) {
        return super::marker_image::run(
            picture,
            w,
            args.dpi,
            args.margin_mm,
            args.out
                .as_deref()
                .context("--out is required with --image")?,
            args.force,
        );
    }
    let out = resolve(&args)?;
    write_sheet(&out)?;
    let sheet = &out.sheet;
    let img_w = (sheet.page_w_mm * sheet.dpi / 25.4).round();
    let img_h = (sheet.page_h_mm * sheet.dpi / 25.4).round();
    outln!("{}", sheet.label.join("\n"));
    outln!(
        "marker origin (centre of the {}) at ({:.3}, {:.3}) mm from the page's top-left; +X right, +Y down the page",
        if sheet.ids.len() > 1 { "board" } else { "tag" },
        sheet.origin_mm.0,
        sheet.origin_mm.1
    );
    outln!(
        "wrote {} and {} at {} dpi ({img_w}x{img_h} px)",
        describe(sheet, &out.svg),
        out.png.display(),
        sheet.dpi
    );
    if let Some(shot) = &args.shot {
        for fp in &sheet.footprints {
            outln!(
                "key prop {}: footprint outline centred at ({:.1}, {:.1}) mm from the marker origin; stand it on its outline, its front along the arrow",
                fp.name,
                (fp.centre_mm.0 * 10.0).round() / 10.0 + 0.0,
                (fp.centre_mm.1 * 10.0).round() / 10.0 + 0.0
            );
        }
        outln!(
            "next: propsalive preview {} (then register and run)",
            shot.display()
        );
    } else if sheet.ids.len() > 1 {
        outln!(
            "track it with: propsalive track INPUT --tag-size-m {} --family {} --board {}x{} --gap-m {} --first-id {}",
            sheet.size_mm / 1000.0,
            sheet.family,
            sheet.rows,
            sheet.cols,
            sheet.gap_mm / 1000.0,
            sheet.ids[0]
        );
    } else {
        outln!(
            "track it with: propsalive track INPUT --tag-size-m {} --family {} --id {}",
            sheet.size_mm / 1000.0,
            sheet.family,
            sheet.ids[0]
        );
    }
    Ok(())
}
