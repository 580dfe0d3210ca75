//! Axis ticks and their labels.

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
