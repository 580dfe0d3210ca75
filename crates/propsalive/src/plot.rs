//! Small, dependency-free SVG charts for the reports: a line/scatter chart and a horizontal
//! grouped bar chart.
//!
//! Both write standalone SVG 1.1 text (no scripts, no external resources, system sans-serif
//! font). Non-finite values are skipped, an empty chart or one whose values are all equal
//! still gets sane axes, and every number written to the SVG is finite. Colours are the
//! Okabe-Ito palette (distinguishable with the common colour-vision deficiencies); line
//! series also differ in marker shape, so they stay apart in grey-scale print.

use std::fmt::Write as _;

/// Okabe-Ito colours, in the order series get them (yellow last: weak on white).
pub const PALETTE: [&str; 8] = [
    "#0072B2", // blue
    "#D55E00", // vermillion
    "#009E73", // bluish green
    "#CC79A7", // reddish purple
    "#E69F00", // orange
    "#56B4E9", // sky blue
    "#000000", // black
    "#F0E442", // yellow
];

const FONT: f64 = 12.0;
const SMALL: f64 = 10.5;
const GRID: &str = "#dddddd";
const INK: &str = "#222222";

/// One series of a [`LineChart`].
#[derive(Debug, Clone, Default)]
pub struct Series {
    /// Legend name.
    pub name: String,
    /// Points joined by a line, each with a marker (in the given order; a non-finite point
    /// breaks the line).
    pub points: Vec<(f64, f64)>,
    /// Extra points drawn as small translucent markers of the series' colour and shape,
    /// not joined (for example the raw samples behind the line's bin means).
    pub scatter: Vec<(f64, f64)>,
}

/// A line chart with optional scatter points per series.
#[derive(Debug, Clone, Default)]
pub struct LineChart {
    pub title: String,
    pub x_label: String,
    pub y_label: String,
    pub series: Vec<Series>,
    /// Extend the x axis to include 0.
    pub x_from_zero: bool,
    /// A line of small text under the legend (empty: none).
    pub note: String,
}

/// One group of bars of a [`BarChart`]: one value per category.
#[derive(Debug, Clone, Default)]
pub struct BarGroup {
    /// Legend name.
    pub name: String,
    /// Value per category (`None` or non-finite: no bar, marked "n/a").
    pub values: Vec<Option<f64>>,
}

/// A horizontal grouped bar chart: categories top to bottom, each with one bar per group.
#[derive(Debug, Clone, Default)]
pub struct BarChart {
    pub title: String,
    /// Label of the value axis.
    pub value_label: String,
    pub categories: Vec<String>,
    pub groups: Vec<BarGroup>,
    /// A reference category (the baseline): its label is bold, and a dashed line in each
    /// group's colour marks its value across the chart.
    pub baseline: Option<usize>,
    /// A line of small text under the legend (empty: none).
    pub note: String,
}

/// Axis ticks: a 1-2-5 step and the tick values spanning `[lo, hi]`.
#[derive(Debug, Clone, PartialEq)]
pub struct Ticks {
    /// The axis range (the first and last tick).
    pub lo: f64,
    pub hi: f64,
    pub step: f64,
    pub values: Vec<f64>,
}

/// "Nice" ticks (steps of 1, 2 or 5 times a power of ten) covering `[lo, hi]` with about
/// `target` intervals (the step nearest `(hi - lo) / target`). Non-finite bounds are ignored (both non-finite: 0..1); an empty range
/// (`lo == hi`) is widened around the value, so the result always has `lo < hi` and at
/// least two ticks.
pub fn nice_ticks(lo: f64, hi: f64, target: usize) -> Ticks {
    const LIMIT: f64 = 1e300;
    let target = target.clamp(1, 50) as f64;
    let (lo, hi) = match (lo.is_finite(), hi.is_finite()) {
        (true, true) => (lo.min(hi), lo.max(hi)),
        (true, false) => (lo, lo),
        (false, true) => (hi, hi),
        (false, false) => (0.0, 1.0),
    };
    let (mut lo, mut hi) = (lo.clamp(-LIMIT, LIMIT), hi.clamp(-LIMIT, LIMIT));
    let magnitude = lo.abs().max(hi.abs());
    if hi - lo <= magnitude * 1e-12 || hi - lo < 1e-200 {
        let pad = if magnitude < 1e-200 {
            1.0
        } else {
            magnitude * 0.1
        };
        lo -= pad;
        hi += pad;
    }
    let raw = (hi - lo) / target;
    let power = 10f64.powf(raw.log10().floor());
    let norm = raw / power;
    // The nearest of 1, 2, 5, 10 on a log scale (boundaries at the geometric means).
    let nice = if norm < std::f64::consts::SQRT_2 {
        1.0
    } else if norm < 10f64.sqrt() {
        2.0
    } else if norm < 50f64.sqrt() {
        5.0
    } else {
        10.0
    };
    let step = nice * power;
    // Snap the quotients first so that 1.0 / 0.2 = 4.999... does not add a tick.
    let snap = |q: f64| {
        let r = q.round();
        if (q - r).abs() < 1e-9 {
            r
        } else {
            q
        }
    };
    let first = snap(lo / step).floor() as i64;
    let last = snap(hi / step).ceil() as i64;
    let values: Vec<f64> = (first..=last)
        .map(|k| {
            let v = k as f64 * step;
            if v.abs() < step * 1e-9 {
                0.0
            } else {
                v
            }
        })
        .collect();
    Ticks {
        lo: values[0],
        hi: values[values.len() - 1],
        step,
        values,
    }
}

/// A tick label: as many decimals as the step needs (any step, not only 1-2-5), scientific notation for very large or
/// very small steps, never "-0".
pub fn format_tick(v: f64, step: f64) -> String {
    if !v.is_finite() {
        return String::new();
    }
    if v == 0.0 {
        return "0".into();
    }
    let step = step.abs();
    if !(1e-5..1e6).contains(&step) {
        return format!("{v:.2e}");
    }
    // The fewest decimals that show the step exactly (0.2: 1, 0.025: 3).
    let decimals = (0..=6)
        .find(|&d| {
            let scaled = step * 10f64.powi(d);
            (scaled - scaled.round()).abs() <= scaled * 1e-6
        })
        .unwrap_or(6) as usize;
    let s = format!("{v:.decimals$}");
    if s.trim_start_matches('-')
        .chars()
        .all(|c| c == '0' || c == '.')
    {
        "0".into()
    } else {
        s
    }
}

/// Escapes text for XML content and attribute values; drops control characters XML does
/// not allow.
pub fn escape(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&apos;"),
            '\t' | '\n' | '\r' => out.push(c),
            c if (c as u32) < 0x20 || c == '\u{FFFE}' || c == '\u{FFFF}' => {}
            c => out.push(c),
        }
    }
    out
}

/// Approximate rendered width of `s` in a sans-serif font of `size` px.
fn text_width(s: &str, size: f64) -> f64 {
    s.chars().count() as f64 * size * 0.56
}

/// A coordinate for the SVG: finite by construction, written with one decimal.
fn n(v: f64) -> String {
    let v = if v.is_finite() { v } else { 0.0 };
    let s = format!("{v:.1}");
    if s == "-0.0" {
        "0.0".into()
    } else {
        s
    }
}

fn finite(p: &(f64, f64)) -> bool {
    p.0.is_finite() && p.1.is_finite()
}

fn svg_open(out: &mut String, width: f64, height: f64, title: &str) {
    let _ = writeln!(
        out,
        "<svg xmlns=\"http://www.w3.org/2000/svg\" version=\"1.1\" width=\"{w}\" height=\"{h}\" \
         viewBox=\"0 0 {w} {h}\" font-family=\"DejaVu Sans, Helvetica, Arial, sans-serif\" \
         font-size=\"{FONT}\" fill=\"{INK}\">",
        w = n(width),
        h = n(height)
    );
    let _ = writeln!(out, "<title>{}</title>", escape(title));
    let _ = writeln!(
        out,
        "<rect x=\"0\" y=\"0\" width=\"{}\" height=\"{}\" fill=\"#ffffff\"/>",
        n(width),
        n(height)
    );
    let _ = writeln!(
        out,
        "<text x=\"{}\" y=\"22\" text-anchor=\"middle\" font-size=\"15\" font-weight=\"bold\">{}</text>",
        n(width / 2.0),
        escape(title)
    );
}

/// A marker of shape `shape % 4` (circle, square, triangle, diamond) centred at (x, y).
fn marker(out: &mut String, shape: usize, x: f64, y: f64, r: f64, colour: &str, opacity: f64) {
    let style = if opacity < 1.0 {
        format!("fill=\"{colour}\" fill-opacity=\"{opacity}\" stroke=\"none\"")
    } else {
        format!("fill=\"{colour}\" stroke=\"#ffffff\" stroke-width=\"0.8\"")
    };
    match shape % 4 {
        0 => {
            let _ = writeln!(
                out,
                "<circle cx=\"{}\" cy=\"{}\" r=\"{}\" {style}/>",
                n(x),
                n(y),
                n(r)
            );
        }
        1 => {
            let s = r * 0.9;
            let _ = writeln!(
                out,
                "<rect x=\"{}\" y=\"{}\" width=\"{}\" height=\"{}\" {style}/>",
                n(x - s),
                n(y - s),
                n(2.0 * s),
                n(2.0 * s)
            );
        }
        2 => {
            let s = r * 1.2;
            let _ = writeln!(
                out,
                "<path d=\"M{} {} L{} {} L{} {} Z\" {style}/>",
                n(x),
                n(y - s),
                n(x + s * 0.87),
                n(y + s * 0.5),
                n(x - s * 0.87),
                n(y + s * 0.5)
            );
        }
        _ => {
            let s = r * 1.2;
            let _ = writeln!(
                out,
                "<path d=\"M{} {} L{} {} L{} {} L{} {} Z\" {style}/>",
                n(x),
                n(y - s),
                n(x + s),
                n(y),
                n(x),
                n(y + s),
                n(x - s),
                n(y)
            );
        }
    }
}

/// Writes `note` (if any) at `y` and returns the y below it.
fn note_line(out: &mut String, note: &str, x: f64, y: f64) -> f64 {
    if note.is_empty() {
        return y;
    }
    let _ = writeln!(
        out,
        "<text x=\"{}\" y=\"{}\" font-size=\"{SMALL}\" fill=\"#555555\">{}</text>",
        n(x),
        n(y + 12.0),
        escape(note)
    );
    y + 18.0
}

impl LineChart {
    /// The chart as a standalone SVG document.
    pub fn to_svg(&self) -> String {
        let (width, plot_h) = (760.0, 320.0);
        let (left, right, top) = (70.0, 24.0, 40.0);
        let plot_w = width - left - right;
        let all = || {
            self.series
                .iter()
                .flat_map(|s| s.points.iter().chain(&s.scatter))
                .filter(|p| finite(p))
        };
        let range = |f: fn(&(f64, f64)) -> f64| {
            all()
                .map(f)
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
                    (a.min(v), b.max(v))
                })
        };
        let (mut x0, mut x1) = range(|p| p.0);
        let (y0, y1) = range(|p| p.1);
        if self.x_from_zero {
            (x0, x1) = (x0.min(0.0), x1.max(0.0));
        }
        let xt = nice_ticks(x0, x1, 8);
        let yt = nice_ticks(y0, y1, 6);
        let sx = |x: f64| left + (x - xt.lo) / (xt.hi - xt.lo) * plot_w;
        let sy = |y: f64| top + plot_h - (y - yt.lo) / (yt.hi - yt.lo) * plot_h;

        let legend_top = top + plot_h + 52.0;
        let row_h = 18.0;
        let mut height = legend_top + row_h * self.series.len() as f64 + 8.0;
        if !self.note.is_empty() {
            height += 18.0;
        }
        let mut out = String::new();
        svg_open(&mut out, width, height, &self.title);

        // Grid, ticks and tick labels.
        for &v in &yt.values {
            let y = sy(v);
            let _ = writeln!(
                out,
                "<line x1=\"{}\" y1=\"{y}\" x2=\"{}\" y2=\"{y}\" stroke=\"{GRID}\"/>\n\
                 <text x=\"{}\" y=\"{}\" text-anchor=\"end\" font-size=\"{SMALL}\">{}</text>",
                n(left - 5.0),
                n(left + plot_w),
                n(left - 8.0),
                n(y + 4.0),
                escape(&format_tick(v, yt.step)),
                y = n(y)
            );
        }
        for &v in &xt.values {
            let x = sx(v);
            let _ = writeln!(
                out,
                "<line x1=\"{x}\" y1=\"{}\" x2=\"{x}\" y2=\"{}\" stroke=\"{GRID}\"/>\n\
                 <text x=\"{x}\" y=\"{}\" text-anchor=\"middle\" font-size=\"{SMALL}\">{}</text>",
                n(top),
                n(top + plot_h + 5.0),
                n(top + plot_h + 18.0),
                escape(&format_tick(v, xt.step)),
                x = n(x)
            );
        }
        // Axes.
        let _ = writeln!(
            out,
            "<path d=\"M{l} {t} L{l} {b} L{r} {b}\" fill=\"none\" stroke=\"{INK}\"/>",
            l = n(left),
            t = n(top),
            b = n(top + plot_h),
            r = n(left + plot_w)
        );
        let _ = writeln!(
            out,
            "<text x=\"{}\" y=\"{}\" text-anchor=\"middle\">{}</text>",
            n(left + plot_w / 2.0),
            n(top + plot_h + 38.0),
            escape(&self.x_label)
        );
        let (lx, ly) = (18.0, top + plot_h / 2.0);
        let _ = writeln!(
            out,
            "<text x=\"{}\" y=\"{}\" text-anchor=\"middle\" transform=\"rotate(-90 {} {})\">{}</text>",
            n(lx),
            n(ly),
            n(lx),
            n(ly),
            escape(&self.y_label)
        );

        // Series: translucent scatter first, then lines and their markers on top.
        for (i, s) in self.series.iter().enumerate() {
            let colour = PALETTE[i % PALETTE.len()];
            for p in s.scatter.iter().filter(|p| finite(p)) {
                marker(&mut out, i, sx(p.0), sy(p.1), 3.2, colour, 0.4);
            }
        }
        for (i, s) in self.series.iter().enumerate() {
            let colour = PALETTE[i % PALETTE.len()];
            for run in s.points.split(|p| !finite(p)).filter(|r| !r.is_empty()) {
                let pts: Vec<String> = run
                    .iter()
                    .map(|p| format!("{},{}", n(sx(p.0)), n(sy(p.1))))
                    .collect();
                let _ = writeln!(
                    out,
                    "<polyline fill=\"none\" stroke=\"{colour}\" stroke-width=\"2\" \
                     stroke-linejoin=\"round\" points=\"{}\"/>",
                    pts.join(" ")
                );
            }
            for p in s.points.iter().filter(|p| finite(p)) {
                marker(&mut out, i, sx(p.0), sy(p.1), 4.5, colour, 1.0);
            }
        }

        // Legend, one series a row.
        for (i, s) in self.series.iter().enumerate() {
            let colour = PALETTE[i % PALETTE.len()];
            let y = legend_top + row_h * i as f64;
            let x = left;
            if s.points.iter().any(finite) {
                let _ = writeln!(
                    out,
                    "<line x1=\"{}\" y1=\"{}\" x2=\"{}\" y2=\"{}\" stroke=\"{colour}\" stroke-width=\"2\"/>",
                    n(x),
                    n(y),
                    n(x + 28.0),
                    n(y)
                );
            }
            marker(&mut out, i, x + 14.0, y, 4.5, colour, 1.0);
            let has_data = s.points.iter().chain(&s.scatter).any(finite);
            let name = if has_data {
                s.name.clone()
            } else {
                format!("{} (no data)", s.name)
            };
            let _ = writeln!(
                out,
                "<text x=\"{}\" y=\"{}\">{}</text>",
                n(x + 36.0),
                n(y + 4.0),
                escape(&name)
            );
        }
        note_line(
            &mut out,
            &self.note,
            left,
            legend_top + row_h * self.series.len() as f64 - 8.0,
        );
        out.push_str("</svg>\n");
        out
    }
}

impl BarChart {
    /// The chart as a standalone SVG document.
    pub fn to_svg(&self) -> String {
        let value =
            |g: &BarGroup, c: usize| g.values.get(c).copied().flatten().filter(|v| v.is_finite());
        let n_groups = self.groups.len().max(1) as f64;
        let bar_h = 11.0;
        let gap = 12.0;
        let band = n_groups * bar_h + gap;
        let label_w = self
            .categories
            .iter()
            .map(|c| text_width(c, FONT))
            .fold(60.0, f64::max)
            .min(420.0);
        let (left, right, top) = (label_w + 16.0, 50.0, 40.0);
        let width = (left + 420.0 + right).max(640.0);
        let plot_w = width - left - right;
        let plot_h = band * self.categories.len().max(1) as f64;

        let (mut v0, mut v1) = (0.0f64, 0.0f64);
        for g in &self.groups {
            for c in 0..self.categories.len() {
                if let Some(v) = value(g, c) {
                    (v0, v1) = (v0.min(v), v1.max(v));
                }
            }
        }
        let vt = nice_ticks(v0, v1, 7);
        let sx = |v: f64| left + (v - vt.lo) / (vt.hi - vt.lo) * plot_w;

        // Legend entries flow left to right, wrapping.
        let mut legend = Vec::new();
        let (mut lx, mut ly) = (left, top + plot_h + 52.0);
        for (i, g) in self.groups.iter().enumerate() {
            let w = 22.0 + text_width(&g.name, FONT) + 18.0;
            if lx + w > width - 10.0 && lx > left {
                lx = left;
                ly += 18.0;
            }
            legend.push((i, lx, ly));
            lx += w;
        }
        let mut height = ly + 18.0;
        if !self.note.is_empty() {
            height += 18.0;
        }
        let mut out = String::new();
        svg_open(&mut out, width, height, &self.title);

        // Baseline band, grid and value ticks.
        if let Some(b) = self.baseline.filter(|&b| b < self.categories.len()) {
            let _ = writeln!(
                out,
                "<rect x=\"{}\" y=\"{}\" width=\"{}\" height=\"{}\" fill=\"#f2f2f2\"/>",
                n(4.0),
                n(top + band * b as f64),
                n(left + plot_w - 4.0),
                n(band)
            );
        }
        for &v in &vt.values {
            let x = sx(v);
            let _ = writeln!(
                out,
                "<line x1=\"{x}\" y1=\"{}\" x2=\"{x}\" y2=\"{}\" stroke=\"{GRID}\"/>\n\
                 <text x=\"{x}\" y=\"{}\" text-anchor=\"middle\" font-size=\"{SMALL}\">{}</text>",
                n(top),
                n(top + plot_h + 5.0),
                n(top + plot_h + 18.0),
                escape(&format_tick(v, vt.step)),
                x = n(x)
            );
        }
        let _ = writeln!(
            out,
            "<text x=\"{}\" y=\"{}\" text-anchor=\"middle\">{}</text>",
            n(left + plot_w / 2.0),
            n(top + plot_h + 38.0),
            escape(&self.value_label)
        );

        // Bars.
        let zero = sx(0.0f64.clamp(vt.lo, vt.hi));
        for (c, name) in self.categories.iter().enumerate() {
            let y = top + band * c as f64 + gap / 2.0;
            let bold = if self.baseline == Some(c) {
                " font-weight=\"bold\""
            } else {
                ""
            };
            let _ = writeln!(
                out,
                "<text x=\"{}\" y=\"{}\" text-anchor=\"end\"{bold}>{}</text>",
                n(left - 8.0),
                n(y + n_groups * bar_h / 2.0 + 4.0),
                escape(name)
            );
            for (i, g) in self.groups.iter().enumerate() {
                let colour = PALETTE[i % PALETTE.len()];
                let by = y + bar_h * i as f64;
                match value(g, c) {
                    Some(v) => {
                        let (a, b) = (zero.min(sx(v)), zero.max(sx(v)));
                        let _ = writeln!(
                            out,
                            "<rect x=\"{}\" y=\"{}\" width=\"{}\" height=\"{}\" fill=\"{colour}\"><title>{}: {}</title></rect>",
                            n(a),
                            n(by),
                            n((b - a).max(0.5)),
                            n(bar_h - 1.0),
                            escape(&format!("{name}, {}", g.name)),
                            escape(&format!("{v:.2}"))
                        );
                        let (tx, anchor) = if v >= 0.0 {
                            (b + 3.0, "start")
                        } else {
                            (a - 3.0, "end")
                        };
                        let _ = writeln!(
                            out,
                            "<text x=\"{}\" y=\"{}\" text-anchor=\"{anchor}\" font-size=\"9\">{}</text>",
                            n(tx),
                            n(by + bar_h - 2.5),
                            escape(&format!("{v:.1}"))
                        );
                    }
                    None => {
                        let _ = writeln!(
                            out,
                            "<text x=\"{}\" y=\"{}\" font-size=\"9\" fill=\"#777777\">n/a</text>",
                            n(zero + 3.0),
                            n(by + bar_h - 2.5)
                        );
                    }
                }
            }
        }
        // The baseline's values as dashed lines across all categories.
        if let Some(b) = self.baseline.filter(|&b| b < self.categories.len()) {
            for (i, g) in self.groups.iter().enumerate() {
                if let Some(v) = value(g, b) {
                    let _ = writeln!(
                        out,
                        "<line x1=\"{x}\" y1=\"{}\" x2=\"{x}\" y2=\"{}\" stroke=\"{}\" \
                         stroke-width=\"1.2\" stroke-dasharray=\"4 3\"/>",
                        n(top),
                        n(top + plot_h),
                        PALETTE[i % PALETTE.len()],
                        x = n(sx(v))
                    );
                }
            }
        }
        let _ = writeln!(
            out,
            "<path d=\"M{l} {t} L{l} {b} L{r} {b}\" fill=\"none\" stroke=\"{INK}\"/>",
            l = n(zero),
            t = n(top),
            b = n(top + plot_h),
            r = n(left + plot_w)
        );
        if zero > left + 0.5 {
            let _ = writeln!(
                out,
                "<path d=\"M{l} {b} L{z} {b}\" fill=\"none\" stroke=\"{INK}\"/>",
                l = n(left),
                z = n(zero),
                b = n(top + plot_h)
            );
        }

        for (i, x, y) in legend {
            let g = &self.groups[i];
            let _ = writeln!(
                out,
                "<rect x=\"{}\" y=\"{}\" width=\"16\" height=\"10\" fill=\"{}\"/>\n\
                 <text x=\"{}\" y=\"{}\">{}</text>",
                n(x),
                n(y - 5.0),
                PALETTE[i % PALETTE.len()],
                n(x + 22.0),
                n(y + 4.0),
                escape(&g.name)
            );
        }
        note_line(&mut out, &self.note, left, ly + 6.0);
        out.push_str("</svg>\n");
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Checks that tags balance (a tiny XML well-formedness check: no comments, CDATA or
    /// processing instructions are written) and that no raw `&`, `<` or `>` is left in text
    /// or attribute values.
    fn assert_well_formed(svg: &str) {
        assert!(svg.starts_with("<svg "), "{svg}");
        let mut stack: Vec<String> = Vec::new();
        let mut rest = svg;
        while let Some(open) = rest.find('<') {
            let text = &rest[..open];
            assert!(!text.contains('>'), "raw '>' in text {text:?}");
            check_entities(text);
            let close = rest[open..].find('>').expect("unclosed tag") + open;
            let tag = &rest[open + 1..close];
            assert!(!tag.contains('<'), "raw '<' inside tag {tag:?}");
            check_entities(tag);
            if let Some(name) = tag.strip_prefix('/') {
                assert_eq!(
                    stack.pop().as_deref(),
                    Some(name.trim()),
                    "mismatched </{name}>"
                );
            } else if !tag.ends_with('/') {
                let name = tag.split_whitespace().next().expect("tag name");
                stack.push(name.to_string());
            }
            // Attribute values are quoted and contain no quote.
            assert_eq!(
                tag.matches('"').count() % 2,
                0,
                "unbalanced quotes in {tag:?}"
            );
            rest = &rest[close + 1..];
        }
        assert!(rest.trim().is_empty(), "text after the root: {rest:?}");
        assert!(stack.is_empty(), "unclosed: {stack:?}");
        for bad in ["NaN", "inf"] {
            assert!(!svg.contains(bad), "{bad} in {svg}");
        }
    }

    fn check_entities(s: &str) {
        for (i, _) in s.match_indices('&') {
            let ent = &s[i..];
            assert!(
                ["&amp;", "&lt;", "&gt;", "&quot;", "&apos;"]
                    .iter()
                    .any(|e| ent.starts_with(e)),
                "raw '&' in {s:?}"
            );
        }
    }

    fn ticks(lo: f64, hi: f64, target: usize) -> Vec<f64> {
        nice_ticks(lo, hi, target).values
    }

    fn close(a: &[f64], b: &[f64]) -> bool {
        a.len() == b.len() && a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-9)
    }

    #[test]
    fn ticks_for_several_ranges() {
        let t = ticks(0.0, 1.0, 5);
        assert!(close(&t, &[0.0, 0.2, 0.4, 0.6, 0.8, 1.0]), "{t:?}");
        let t = ticks(17.3, 31.9, 6);
        assert!(
            close(&t, &[16.0, 18.0, 20.0, 22.0, 24.0, 26.0, 28.0, 30.0, 32.0]),
            "{t:?}"
        );
        let t = ticks(17.3, 31.9, 3);
        assert!(close(&t, &[15.0, 20.0, 25.0, 30.0, 35.0]), "{t:?}");
        let t = ticks(-37.0, -2.0, 5);
        assert!(
            close(
                &t,
                &[-40.0, -35.0, -30.0, -25.0, -20.0, -15.0, -10.0, -5.0, 0.0]
            ),
            "{t:?}"
        );
        let t = ticks(-37.0, -2.0, 3);
        assert!(close(&t, &[-40.0, -30.0, -20.0, -10.0, 0.0]), "{t:?}");
        let t = ticks(-0.3, 0.7, 5);
        assert!(close(&t, &[-0.4, -0.2, 0.0, 0.2, 0.4, 0.6, 0.8]), "{t:?}");
        let t = ticks(0.0, 1234.0, 5);
        let want: Vec<f64> = (0..=7).map(|k| k as f64 * 200.0).collect();
        assert!(close(&t, &want), "{t:?}");
        let t = ticks(0.0, 0.043, 5);
        assert!(close(&t, &[0.0, 0.01, 0.02, 0.03, 0.04, 0.05]), "{t:?}");
        // Reversed bounds are the same range.
        assert_eq!(ticks(1.0, 0.0, 5), ticks(0.0, 1.0, 5));
        for (lo, hi) in [
            (0.0, 1.0),
            (17.3, 31.9),
            (-5.0, 5.0),
            (1e-7, 3e-7),
            (2e8, 9e8),
        ] {
            let t = nice_ticks(lo, hi, 6);
            assert!(t.lo <= lo.min(hi) && t.hi >= lo.max(hi), "{t:?}");
            assert!(t.values.len() >= 2 && t.values.len() <= 16, "{t:?}");
            let m = t.step / 10f64.powf(t.step.log10().floor());
            assert!(
                [1.0, 2.0, 5.0].iter().any(|k| (m - k).abs() < 1e-9),
                "step {}",
                t.step
            );
        }
    }

    #[test]
    fn ticks_for_degenerate_ranges() {
        for v in [0.0, 25.0, -3.5, 1e-9, 1e12] {
            let t = nice_ticks(v, v, 5);
            assert!(t.lo < v && t.hi > v, "{v}: {t:?}");
            assert!(t.values.len() >= 2 && t.values.iter().all(|x| x.is_finite()));
        }
        let t = ticks(0.0, 0.0, 5);
        assert!(t.contains(&0.0), "{t:?}");
        for (lo, hi) in [
            (f64::NAN, f64::NAN),
            (f64::INFINITY, f64::NEG_INFINITY),
            (f64::NAN, 3.0),
            (-f64::MAX, f64::MAX),
        ] {
            let t = nice_ticks(lo, hi, 5);
            assert!(t.lo < t.hi && t.step > 0.0, "{lo}..{hi}: {t:?}");
            assert!(t.values.iter().all(|x| x.is_finite()), "{t:?}");
        }
    }

    #[test]
    fn tick_labels() {
        assert_eq!(format_tick(0.6000000000000001, 0.2), "0.6");
        assert_eq!(format_tick(20.0, 5.0), "20");
        assert_eq!(format_tick(0.05, 0.01), "0.05");
        assert_eq!(format_tick(0.075, 0.025), "0.075");
        assert_eq!(format_tick(0.05, 0.025), "0.050");
        assert_eq!(format_tick(1.5, 0.5), "1.5");
        assert_eq!(format_tick(250.0, 50.0), "250");
        assert_eq!(format_tick(-0.0, 0.1), "0");
        assert_eq!(format_tick(-1e-12, 0.1), "0");
        assert_eq!(format_tick(3e8, 1e8), "3.00e8");
    }

    #[test]
    fn escaping() {
        assert_eq!(
            escape(r#"a & b < c > d "e" 'f'"#),
            "a &amp; b &lt; c &gt; d &quot;e&quot; &apos;f&apos;"
        );
        assert_eq!(escape("bell\u{7}tab\t"), "belltab\t");
        let chart = LineChart {
            title: "<script>&\"'".into(),
            x_label: "x < y".into(),
            y_label: "a & b".into(),
            series: vec![Series {
                name: "\"quoted\" <name>".into(),
                points: vec![(0.0, 1.0), (1.0, 2.0)],
                scatter: vec![],
            }],
            x_from_zero: false,
            note: "R&D > 0".into(),
        };
        let svg = chart.to_svg();
        assert_well_formed(&svg);
        assert!(svg.contains("&lt;script&gt;&amp;&quot;&apos;"));
        assert!(svg.contains("&quot;quoted&quot; &lt;name&gt;"));
        assert!(!svg.contains("<script"));
    }

    #[test]
    fn line_chart_is_well_formed_with_a_line_per_series() {
        let chart = LineChart {
            title: "Prop PSNR".into(),
            x_label: "rotation, deg".into(),
            y_label: "PSNR, dB".into(),
            series: vec![
                Series {
                    name: "paper".into(),
                    points: vec![(2.0, 30.0), (10.0, 27.0), (30.0, 21.5)],
                    scatter: vec![(1.0, 31.0), (3.0, 29.0), (29.0, f64::NAN), (31.0, 22.0)],
                },
                Series {
                    name: "ours".into(),
                    points: vec![(2.0, 30.1), (f64::NAN, 1.0), (10.0, 27.7), (30.0, 23.2)],
                    scatter: vec![],
                },
                Series {
                    name: "empty".into(),
                    points: vec![],
                    scatter: vec![],
                },
            ],
            x_from_zero: true,
            note: "lines: bin means".into(),
        };
        let svg = chart.to_svg();
        assert_well_formed(&svg);
        // The NaN point splits "ours" into two runs; the empty series draws no line.
        assert_eq!(svg.matches("<polyline").count(), 3, "{svg}");
        for name in ["paper", "ours", "empty (no data)", "lines: bin means"] {
            assert!(svg.contains(name), "{name}");
        }
        for c in &PALETTE[..2] {
            assert!(svg.contains(c));
        }
    }

    #[test]
    fn line_chart_degenerate_inputs() {
        let cases = vec![
            vec![],
            vec![Series::default()],
            vec![Series {
                name: "same x".into(),
                points: vec![(5.0, 1.0), (5.0, 2.0), (5.0, 3.0)],
                scatter: vec![],
            }],
            vec![Series {
                name: "one point".into(),
                points: vec![(3.0, 3.0)],
                scatter: vec![],
            }],
            vec![Series {
                name: "non-finite only".into(),
                points: vec![(f64::NAN, 1.0), (1.0, f64::INFINITY)],
                scatter: vec![(f64::NEG_INFINITY, 0.0)],
            }],
            vec![Series {
                name: "huge".into(),
                points: vec![(-f64::MAX, f64::MAX), (f64::MAX, -f64::MAX)],
                scatter: vec![],
            }],
        ];
        for series in cases {
            for x_from_zero in [false, true] {
                let svg = LineChart {
                    title: "t".into(),
                    x_label: "x".into(),
                    y_label: "y".into(),
                    series: series.clone(),
                    x_from_zero,
                    note: String::new(),
                }
                .to_svg();
                assert_well_formed(&svg);
            }
        }
    }

    #[test]
    fn bar_chart_is_well_formed() {
        let chart = BarChart {
            title: "Methods".into(),
            value_label: "PSNR, dB".into(),
            categories: vec!["paper".into(), "ours & co".into(), "missing".into()],
            groups: vec![
                BarGroup {
                    name: "prop, Wood".into(),
                    values: vec![Some(24.3), Some(23.4), None],
                },
                BarGroup {
                    name: "revealed, Wood".into(),
                    values: vec![Some(15.2), Some(f64::NAN)],
                },
            ],
            baseline: Some(0),
            note: "dashed: the paper".into(),
        };
        let svg = chart.to_svg();
        assert_well_formed(&svg);
        // Three finite bars; a missing or non-finite value is marked n/a.
        assert_eq!(svg.matches("<rect").count() - 2 - 2, 3, "{svg}");
        assert_eq!(svg.matches(">n/a<").count(), 3);
        assert!(svg.contains("ours &amp; co") && svg.contains("prop, Wood"));
        assert_eq!(svg.matches("stroke-dasharray").count(), 2);

        // Negative values, no groups, no categories, out-of-range baseline.
        for chart in [
            BarChart {
                categories: vec!["a".into(), "b".into()],
                groups: vec![BarGroup {
                    name: "g".into(),
                    values: vec![Some(-3.0), Some(2.0)],
                }],
                ..BarChart::default()
            },
            BarChart::default(),
            BarChart {
                categories: vec!["a".into()],
                groups: vec![BarGroup {
                    name: "all equal".into(),
                    values: vec![Some(0.0)],
                }],
                baseline: Some(7),
                ..BarChart::default()
            },
        ] {
            assert_well_formed(&chart.to_svg());
        }
    }
}
