//! The report of `propsalive eval`: the methods table, the degradation curves (quality against
//! the in-between's distance from its key pose) binned into tables, and the files.
//!
//! [`EvalReport::render`] makes `report.md`, `results.json` and three SVG plots linked from the
//! report: `methods.svg` (prop and revealed PSNR per method and background, the paper's method
//! as the baseline), `degradation_rotation.svg` and `degradation_translation.svg` (prop PSNR
//! against the head's rotation and displacement from the key pose present: every frame as a
//! point, bin means as a line); [`EvalFiles::write`] writes them atomically.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use crate::plot::{format_tick, BarChart, BarGroup, LineChart, Series};
use crate::stats::mean;
use crate::{write_file, ReportError};

/// Rotation bins of the degradation curve, degrees: `[from, to)`.
pub const ROTATION_BINS: [(f64, f64); 5] = [
    (0.0, 5.0),
    (5.0, 15.0),
    (15.0, 25.0),
    (25.0, 35.0),
    (35.0, 50.0),
];

/// About how many equal bins the displacement curve gets.
const DISPLACEMENT_BINS: f64 = 5.0;

/// Equal displacement bins from 0 past `max` whose width is 1, 2, 2.5 or 5 times a power of
/// ten, as close to [`DISPLACEMENT_BINS`] bins as that allows; and the width.
fn displacement_bins(max: f64) -> (Vec<(f64, f64)>, f64) {
    let max = if max.is_finite() && max > 0.0 {
        max
    } else {
        1.0
    };
    let power = 10f64.powf((max / DISPLACEMENT_BINS).log10().floor());
    let count = |step: f64| {
        let q = max / step;
        // 0.15 / 0.025 is 5.999...: snap before rounding up.
        (if (q - q.round()).abs() < 1e-9 {
            q.round()
        } else {
            q.ceil()
        })
        .max(1.0)
    };
    let step = [10.0, 5.0, 2.5, 2.0, 1.0]
        .into_iter()
        .map(|m| m * power)
        .min_by(|&a, &b| {
            (count(a) - DISPLACEMENT_BINS)
                .abs()
                .total_cmp(&(count(b) - DISPLACEMENT_BINS).abs())
        })
        .unwrap_or(power);
    let bins = (0..count(step) as usize)
        .map(|k| (k as f64 * step, (k + 1) as f64 * step))
        .collect();
    (bins, step)
}

/// One frame of a degradation curve.
#[derive(Debug, Clone)]
pub struct CurvePoint {
    pub seed: u64,
    pub frame: u32,
    /// Index of the key pose present.
    pub key: usize,
    /// Head rotation from the key pose present, degrees.
    pub rotation_deg: f64,
    /// Head displacement from the key pose present, prop heights
    /// (`pa_scene::eval::key_distance`).
    pub displacement_h: f64,
    pub psnr_prop: Option<f64>,
}

/// The frames of one method on the wood table.
#[derive(Debug, Clone)]
pub struct Curve {
    pub name: String,
    pub points: Vec<CurvePoint>,
}

/// One bin of a degradation curve.
struct Bin {
    from: f64,
    to: f64,
    /// Frames in the bin.
    frames: usize,
    /// Mean prop PSNR of the bin's frames that have one.
    psnr: Option<f64>,
    /// Mean distance of those same frames (where the curve's point is drawn).
    distance: Option<f64>,
}

/// Bins `frames` by `distance`: `[from, to)`, the last bin `[from, to]` when `close_last`.
fn bin_frames(
    frames: &[CurvePoint],
    bins: &[(f64, f64)],
    distance: fn(&CurvePoint) -> f64,
    close_last: bool,
) -> Vec<Bin> {
    bins.iter()
        .enumerate()
        .map(|(i, &(from, to))| {
            // Rounding may leave the largest distance a hair past the last bin's end.
            let last = close_last && i + 1 == bins.len();
            let inside = |d: f64| d >= from && (d < to || (last && d <= to + to.abs() * 1e-9));
            let sel: Vec<&CurvePoint> = frames.iter().filter(|f| inside(distance(f))).collect();
            let with_psnr: Vec<&&CurvePoint> = sel
                .iter()
                .filter(|f| f.psnr_prop.is_some_and(f64::is_finite))
                .collect();
            Bin {
                from,
                to,
                frames: sel.len(),
                psnr: mean(with_psnr.iter().map(|f| f.psnr_prop)),
                distance: mean(with_psnr.iter().map(|f| Some(distance(f)))),
            }
        })
        .collect()
}

/// The degradation table (Markdown), its JSON and its chart for one distance measure.
struct Degradation {
    table: String,
    json: Vec<serde_json::Value>,
    chart: LineChart,
}

fn degradation(
    curves: &[Curve],
    bins: &[(f64, f64)],
    step: f64,
    unit: &str,
    distance: fn(&CurvePoint) -> f64,
    close_last: bool,
    chart: LineChart,
) -> Degradation {
    let mut table = String::from("| method | ");
    for &(a, b) in bins {
        let _ = write!(
            table,
            "{}-{} {unit} | ",
            format_tick(a, step),
            format_tick(b, step)
        );
    }
    table.push_str("\n|---|");
    table.push_str(&"---|".repeat(bins.len()));
    table.push('\n');
    let mut json = Vec::new();
    let mut series = Vec::new();
    for c in curves {
        let binned = bin_frames(&c.points, bins, distance, close_last);
        let _ = write!(table, "| {} | ", c.name);
        let mut points = Vec::new();
        for b in &binned {
            let _ = write!(table, "{} (n={}) | ", fmt(b.psnr, 2), b.frames);
            points.push(serde_json::json!({
                "from": b.from, "to": b.to, "prop_psnr_db": b.psnr,
                "mean_distance": b.distance, "frames": b.frames,
            }));
        }
        table.push('\n');
        json.push(serde_json::json!({"method": c.name, "unit": unit, "bins": points}));
        series.push(Series {
            name: c.name.clone(),
            points: binned
                .iter()
                .filter_map(|b| Some((b.distance?, b.psnr?)))
                .collect(),
            scatter: c
                .points
                .iter()
                .filter_map(|f| Some((distance(f), f.psnr_prop?)))
                .collect(),
        });
    }
    Degradation {
        table,
        json,
        chart: LineChart { series, ..chart },
    }
}

fn fmt(v: Option<f64>, digits: usize) -> String {
    v.map(|x| format!("{x:.digits$}"))
        .unwrap_or_else(|| "-".into())
}

/// One row of the methods table: a method on one background, over every seed's frames.
#[derive(Debug, Clone)]
pub struct MethodRow {
    /// The background's name (`Wood`, `Plain`).
    pub background: String,
    pub method: String,
    /// Means over the frames.
    pub prop_psnr_db: Option<f64>,
    pub prop_ssim: Option<f64>,
    pub revealed_psnr_db: Option<f64>,
    pub revealed_ssim: Option<f64>,
    /// Revealed PSNR away from the twin's edge (`pa_scene::eval::FrameMetrics::
    /// psnr_revealed_off_edge`): the fill alone.
    pub revealed_off_edge_psnr_db: Option<f64>,
    /// Medians over the frames.
    pub rot_err_deg_median: Option<f64>,
    pub texture_diminish_ms_median: Option<f64>,
    /// Means over consecutive frame pairs: the frame-to-frame change of the revealed region
    /// after camera compensation, 8-bit levels, of the output and of the ground truth
    /// (`pa_scene::flicker`).
    pub flicker_ours: Option<f64>,
    pub flicker_truth: Option<f64>,
    /// Frames measured.
    pub frames: usize,
}

/// The methods table (Markdown): a header and a line per row.
pub fn methods_table(rows: &[MethodRow]) -> String {
    let mut table = String::new();
    let _ = writeln!(
        table,
        "| background | method | prop PSNR dB | prop SSIM | revealed PSNR dB | revealed SSIM | revealed off edge dB | rot. err. deg | texture+diminish ms | flicker ours / truth |\n|---|---|---|---|---|---|---|---|---|---|"
    );
    for r in rows {
        let _ = writeln!(
            table,
            "| {} | {} | {} | {} | {} | {} | {} | {} | {} | {} / {} |",
            r.background,
            r.method,
            fmt(r.prop_psnr_db, 2),
            fmt(r.prop_ssim, 3),
            fmt(r.revealed_psnr_db, 2),
            fmt(r.revealed_ssim, 3),
            fmt(r.revealed_off_edge_psnr_db, 2),
            fmt(r.rot_err_deg_median, 3),
            fmt(r.texture_diminish_ms_median, 1),
            fmt(r.flicker_ours, 2),
            fmt(r.flicker_truth, 2)
        );
    }
    table
}

impl MethodRow {
    /// The row in `results.json`.
    pub fn json(&self) -> serde_json::Value {
        serde_json::json!({
            "background": self.background, "method": self.method,
            "prop_psnr_db": self.prop_psnr_db, "prop_ssim": self.prop_ssim,
            "revealed_psnr_db": self.revealed_psnr_db,
            "revealed_ssim": self.revealed_ssim,
            "revealed_off_edge_psnr_db": self.revealed_off_edge_psnr_db,
            "rot_err_deg_median": self.rot_err_deg_median,
            "texture_diminish_ms_median": self.texture_diminish_ms_median,
            "flicker_ours": self.flicker_ours, "flicker_truth": self.flicker_truth,
            "frames": self.frames,
        })
    }
}

/// The bar chart of prop and revealed PSNR per method (categories: the methods in the order
/// of their first row) and background (in the order of their first row); the first method
/// whose name starts with "paper" is the baseline.
pub fn methods_chart(rows: &[MethodRow]) -> BarChart {
    let mut names: Vec<&str> = Vec::new();
    let mut backgrounds: Vec<&str> = Vec::new();
    // Rows without PSNR (the tracking rows) are not charted.
    for r in rows
        .iter()
        .filter(|r| r.prop_psnr_db.is_some() || r.revealed_psnr_db.is_some())
    {
        if !names.contains(&r.method.as_str()) {
            names.push(&r.method);
        }
        if !backgrounds.contains(&r.background.as_str()) {
            backgrounds.push(&r.background);
        }
    }
    let mut groups = Vec::new();
    for (what, pick) in [
        (
            "prop",
            (|r| r.0) as fn((Option<f64>, Option<f64>)) -> Option<f64>,
        ),
        ("revealed", |r| r.1),
    ] {
        for bg in &backgrounds {
            groups.push(BarGroup {
                name: format!("{what} PSNR, {bg}"),
                values: names
                    .iter()
                    .map(|name| {
                        rows.iter()
                            .find(|s| s.background == *bg && s.method == *name)
                            .and_then(|s| pick((s.prop_psnr_db, s.revealed_psnr_db)))
                    })
                    .collect(),
            });
        }
    }
    BarChart {
        title: "Mean PSNR per method: prop region and revealed background".into(),
        value_label: "PSNR, dB (higher is better)".into(),
        categories: names.iter().map(|s| s.to_string()).collect(),
        groups,
        baseline: names.iter().position(|n| n.starts_with("paper")),
        note: "shaded row and dashed lines: the paper's method (baseline)".into(),
    }
}

/// What `propsalive eval` measured, in plain numbers.
#[derive(Debug, Clone)]
pub struct EvalReport {
    /// Image size, pixels.
    pub width: u32,
    pub height: u32,
    /// Scene seeds.
    pub seeds: Vec<u64>,
    /// Frames measured per scene.
    pub frames: usize,
    /// The methods table's rows, background by background.
    pub methods: Vec<MethodRow>,
    /// The degradation curves.
    pub curves: Vec<Curve>,
}

/// The files of an evaluation, as text.
#[derive(Debug, Clone)]
pub struct EvalFiles {
    /// `report.md`.
    pub report: String,
    /// `results.json`.
    pub results: serde_json::Value,
    /// The plots: file name and SVG.
    pub plots: Vec<(&'static str, String)>,
}

impl EvalReport {
    /// The report, the JSON results and the plots.
    pub fn render(&self) -> EvalFiles {
        let (w, h) = (self.width, self.height);
        let curves = &self.curves;
        let table = methods_table(&self.methods);
        let json_rows: Vec<serde_json::Value> = self.methods.iter().map(MethodRow::json).collect();

        // Degradation curves: prop PSNR by distance of the in-between from its key pose.
        let points_note = "points: single frames (all seeds); lines: bin means (bins of the \
                       report's table), drawn at the mean distance of each bin's frames";
        let rotation = degradation(
            curves,
            &ROTATION_BINS,
            1.0,
            "deg",
            |f| f.rotation_deg,
            false,
            LineChart {
                title: "Prop PSNR against rotation from the key pose (wood table)".into(),
                x_label: "head rotation between the in-between and the key pose present, degrees"
                    .into(),
                y_label: "prop PSNR, dB".into(),
                x_from_zero: true,
                note: points_note.into(),
                ..LineChart::default()
            },
        );
        let max_displacement = curves
            .iter()
            .flat_map(|c| c.points.iter().map(|f| f.displacement_h))
            .filter(|d| d.is_finite())
            .fold(0.0, f64::max);
        let (bins, step) = displacement_bins(max_displacement);
        let translation = degradation(
            curves,
            &bins,
            step,
            "h",
            |f| f.displacement_h,
            true,
            LineChart {
                title: "Prop PSNR against displacement from the key pose (wood table)".into(),
                x_label: "mean displacement of the head's surface from the key pose present, \
                      prop heights"
                    .into(),
                y_label: "prop PSNR, dB".into(),
                x_from_zero: true,
                note: points_note.into(),
                ..LineChart::default()
            },
        );

        // Method comparison: prop and revealed PSNR per method and background.
        let methods_chart = methods_chart(&self.methods);

        let plots = [
            ("methods.svg", methods_chart.to_svg()),
            ("degradation_rotation.svg", rotation.chart.to_svg()),
            ("degradation_translation.svg", translation.chart.to_svg()),
        ];
        let caption = "*Points: single frames (all seeds); lines: the means of the table's bins, \
                   each drawn at the mean distance of its frames.*";
        let report = format!(
        "# Props Alive evaluation\n\nGenerated scenes at {w}x{h}, seeds {:?}, {} frames each, \
         real tracker, handheld camera unless a row says \"tripod\", ground truth = the in-between \
         rendered as if printed.\n\n## Methods\n\n{table}\n\
         ![Prop and revealed-background PSNR per method and background](methods.svg)\n\n\
         *Mean PSNR per method and background; the paper's method (shaded, dashed lines) is the \
         baseline.*\n\n\
         ## Degradation: prop PSNR against the head's rotation from the key pose (wood table)\n\n{}\n\
         ![Prop PSNR against the head's rotation from the key pose](degradation_rotation.svg)\n\n\
         {caption}\n\n\
         ## Degradation: prop PSNR against the head's displacement from the key pose (wood table)\n\n\
         Displacement: the mean distance the head's vertices (those weighted mostly to the \
         head or jaw joint) move between the key pose present and the in-between, in prop \
         heights (h).\n\n{}\n\
         ![Prop PSNR against the head's displacement from the key pose](degradation_translation.svg)\n\n\
         {caption}\n",
        self.seeds,
        self.frames,
        rotation.table,
        translation.table,
    );
        let json_frames: Vec<serde_json::Value> = curves
            .iter()
            .flat_map(|c| {
                c.points.iter().map(|f| {
                    serde_json::json!({
                        "method": c.name, "seed": f.seed, "frame": f.frame, "key": f.key,
                        "rotation_deg": f.rotation_deg,
                        "head_displacement_prop_heights": f.displacement_h,
                        "prop_psnr_db": f.psnr_prop,
                    })
                })
            })
            .collect();
        let json = serde_json::json!({
            "size": [w, h], "seeds": self.seeds, "methods": json_rows,
            "degradation": rotation.json,
            "degradation_translation": translation.json,
            "degradation_frames": json_frames,
            "plots": plots.iter().map(|p| p.0).collect::<Vec<_>>(),
        });
        EvalFiles {
            report,
            results: json,
            plots: plots.into_iter().collect(),
        }
    }
}

impl EvalFiles {
    /// Writes the plots, `report.md` and `results.json` into `dir` (which must exist), each
    /// atomically; returns the plots' paths.
    pub fn write(&self, dir: &Path) -> Result<Vec<PathBuf>, ReportError> {
        let mut plot_paths = Vec::new();
        for (name, svg) in &self.plots {
            plot_paths.push(write_plot(dir, name, svg)?);
        }
        pa_io::write_atomic(&dir.join("report.md"), self.report.as_bytes())?;
        pa_io::write_atomic(
            &dir.join("results.json"),
            serde_json::to_string_pretty(&self.results)?.as_bytes(),
        )?;
        Ok(plot_paths)
    }
}

/// Writes a plot next to the report, atomically (temporary file in the folder, rename).
fn write_plot(dir: &Path, name: &str, svg: &str) -> Result<PathBuf, ReportError> {
    let path = dir.join(name);
    write_file(&path, svg.as_bytes())?;
    Ok(path)
}

#[cfg(test)]
mod tests {
    use super::displacement_bins;

    #[test]
    fn displacement_bins_are_about_five_nice_steps_from_zero() {
        for (max, step, n) in [
            (0.15, 0.025, 6),
            (0.147, 0.025, 6),
            (0.16, 0.05, 4),
            (0.09, 0.02, 5),
            (1.0, 0.2, 5),
            (7.3, 2.0, 4),
            (0.0, 0.2, 5),
            (f64::NAN, 0.2, 5),
        ] {
            let (bins, s) = displacement_bins(max);
            assert!((s - step).abs() < 1e-12, "{max}: step {s}");
            assert_eq!(bins.len(), n, "{max}: {bins:?}");
            assert_eq!(bins[0].0, 0.0);
            if max.is_finite() {
                assert!(bins[n - 1].1 >= max - 1e-12, "{max}: {bins:?}");
            }
        }
    }
}
