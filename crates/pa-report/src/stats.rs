//! Summary statistics of the reports: means and medians that skip missing and non-finite
//! values (quality figures), and the median and 95th percentile of timings ([`Stat`]).

/// Mean of the finite values (`None` if there are none).
pub fn mean(values: impl IntoIterator<Item = Option<f64>>) -> Option<f64> {
    let v: Vec<f64> = values
        .into_iter()
        .flatten()
        .filter(|x| x.is_finite())
        .collect();
    (!v.is_empty()).then(|| v.iter().sum::<f64>() / v.len() as f64)
}

/// Median of the finite values (the upper one of an even count; `None` if there are none).
pub fn median(values: impl IntoIterator<Item = Option<f64>>) -> Option<f64> {
    let mut v: Vec<f64> = values
        .into_iter()
        .flatten()
        .filter(|x| x.is_finite())
        .collect();
    if v.is_empty() {
        return None;
    }
    v.sort_by(f64::total_cmp);
    Some(v[v.len() / 2])
}

/// Median and 95th percentile (nearest rank) of `v`.
#[derive(Debug, Clone, Copy)]
pub struct Stat {
    pub median: f64,
    pub p95: f64,
}

/// The [`Stat`] of `v` (both NaN for no values).
pub fn stat(mut v: Vec<f64>) -> Stat {
    if v.is_empty() {
        return Stat {
            median: f64::NAN,
            p95: f64::NAN,
        };
    }
    v.sort_by(f64::total_cmp);
    let n = v.len();
    let median = if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    };
    let rank = ((0.95 * n as f64).ceil() as usize).clamp(1, n);
    Stat {
        median,
        p95: v[rank - 1],
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn percentiles() {
        let s = stat((1..=20).map(f64::from).collect());
        assert_eq!(s.median, 10.5);
        assert_eq!(s.p95, 19.0);
        let s = stat(vec![3.0]);
        assert_eq!((s.median, s.p95), (3.0, 3.0));
        assert!(stat(Vec::new()).median.is_nan());
    }

    #[test]
    fn means_and_medians_skip_missing_and_non_finite_values() {
        let v = [
            Some(1.0),
            None,
            Some(f64::NAN),
            Some(4.0),
            Some(f64::INFINITY),
        ];
        assert_eq!(mean(v), Some(2.5));
        assert_eq!(median(v), Some(4.0));
        assert_eq!(median([Some(3.0), Some(1.0), Some(2.0)]), Some(2.0));
        assert_eq!(mean([None, Some(f64::NAN)]), None);
        assert_eq!(median(Vec::new()), None);
    }
}
