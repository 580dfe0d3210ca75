//! [`LineChart`] as SVG.

use std::fmt::Write as _;

use super::{escape, finite, format_tick, marker, n, nice_ticks, note_line, svg_open, LineChart};
use super::{GRID, INK, PALETTE, SMALL};

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
