//! [`BarChart`] as SVG.

use std::fmt::Write as _;

use super::{
    escape, format_tick, n, nice_ticks, note_line, svg_open, text_width, BarChart, BarGroup,
};
use super::{FONT, GRID, INK, PALETTE, SMALL};

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
