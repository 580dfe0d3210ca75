//! The charts: well-formed SVG on ordinary and degenerate input; ticks and labels.

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
