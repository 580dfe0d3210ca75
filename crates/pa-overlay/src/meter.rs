//! The preview's frames-per-second and latency bookkeeping (what the status bar shows and the
//! summary printed at exit): an exponentially smoothed frame rate and every frame's
//! camera-to-screen latency.

use std::time::Instant;

/// Frames-per-second and latency bookkeeping.
#[derive(Debug, Default)]
pub struct Meter {
    last_present: Option<Instant>,
    /// The smoothed frame rate (none before the second frame).
    pub fps: Option<f64>,
    /// The last frame's latency, ms.
    pub latency_ms: Option<f64>,
    latencies: Vec<f64>,
}

impl Meter {
    /// A frame was presented at `now`, `latency_ms` after its camera frame was acquired.
    pub fn presented(&mut self, now: Instant, latency_ms: f64) {
        if let Some(prev) = self.last_present {
            let dt = now.duration_since(prev).as_secs_f64();
            if dt > 0.0 {
                let f = 1.0 / dt;
                self.fps = Some(self.fps.map_or(f, |old| 0.8 * old + 0.2 * f));
            }
        }
        self.last_present = Some(now);
        self.latency_ms = Some(latency_ms);
        self.latencies.push(latency_ms);
    }

    /// (median, 95th percentile) latency, ms.
    pub fn summary(&self) -> Option<(f64, f64)> {
        if self.latencies.is_empty() {
            return None;
        }
        let mut v = self.latencies.clone();
        v.sort_by(f64::total_cmp);
        let at = |q: f64| v[((v.len() - 1) as f64 * q).round() as usize];
        Some((at(0.5), at(0.95)))
    }
}

#[cfg(test)]
mod tests {
    use std::time::Duration;

    use super::*;

    #[test]
    fn meter_smooths_fps_and_summarises_latency() {
        let mut m = Meter::default();
        let t = Instant::now();
        m.presented(t, 50.0);
        assert_eq!(m.fps, None);
        m.presented(t + Duration::from_millis(100), 60.0);
        assert!((m.fps.unwrap() - 10.0).abs() < 1e-6);
        m.presented(t + Duration::from_millis(150), 70.0);
        // 0.8 * 10 + 0.2 * 20.
        assert!((m.fps.unwrap() - 12.0).abs() < 1e-6);
        assert_eq!(m.summary(), Some((60.0, 70.0)));
        assert_eq!(Meter::default().summary(), None);
    }
}
