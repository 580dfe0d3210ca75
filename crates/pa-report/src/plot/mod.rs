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

mod bar;
mod line;
#[cfg(test)]
mod tests;
mod ticks;

pub use ticks::{format_tick, nice_ticks, Ticks};

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
