//! One Euro filtering (Casiez et al., CHI 2012) of poses: little jitter when still, little
//! lag when moving fast. Translation is filtered as a vector; rotation in the tangent space
//! of the filtered quaternion (`q <- q * exp(alpha * log(q^-1 q_measured))`), so there is no
//! sign or normalisation problem.

use glam::{DQuat, DVec3};

use crate::Pose;

fn alpha(cutoff_hz: f64, dt: f64) -> f64 {
    let tau = 1.0 / (2.0 * std::f64::consts::PI * cutoff_hz.max(1e-6));
    1.0 / (1.0 + tau / dt)
}

/// A scalar One Euro filter.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OneEuro {
    /// Cutoff at rest, Hz (lower = smoother when still).
    pub min_cutoff_hz: f64,
    /// Cutoff increase per unit/s of speed (higher = less lag when moving).
    pub beta: f64,
    /// Cutoff of the speed estimate, Hz.
    pub d_cutoff_hz: f64,
    state: Option<(f64, f64, f64)>, // (x, dx, t)
}

impl OneEuro {
    pub fn new(min_cutoff_hz: f64, beta: f64, d_cutoff_hz: f64) -> Self {
        Self {
            min_cutoff_hz,
            beta,
            d_cutoff_hz,
            state: None,
        }
    }

    /// Filters a sample taken at `t_s` seconds.
    pub fn filter(&mut self, x: f64, t_s: f64) -> f64 {
        let Some((px, pdx, pt)) = self.state else {
            self.state = Some((x, 0.0, t_s));
            return x;
        };
        let dt = if t_s > pt { t_s - pt } else { 1.0 / 60.0 };
        let dx = (x - px) / dt;
        let edx = pdx + alpha(self.d_cutoff_hz, dt) * (dx - pdx);
        let cutoff = self.min_cutoff_hz + self.beta * edx.abs();
        let y = px + alpha(cutoff, dt) * (x - px);
        self.state = Some((y, edx, t_s));
        y
    }

    pub fn reset(&mut self) {
        self.state = None;
    }
}

/// Settings of the pose filter.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default)]
pub struct PoseFilterConfig {
    pub enabled: bool,
    pub translation_min_cutoff_hz: f64,
    /// Hz per m/s.
    pub translation_beta: f64,
    pub rotation_min_cutoff_hz: f64,
    /// Hz per rad/s.
    pub rotation_beta: f64,
    pub d_cutoff_hz: f64,
}

impl Default for PoseFilterConfig {
    fn default() -> Self {
        Self {
            enabled: true,
            translation_min_cutoff_hz: 1.5,
            translation_beta: 400.0,
            rotation_min_cutoff_hz: 1.5,
            rotation_beta: 80.0,
            d_cutoff_hz: 1.0,
        }
    }
}

/// One Euro filter on a pose.
#[derive(Debug, Clone, PartialEq)]
pub struct PoseFilter {
    pub config: PoseFilterConfig,
    state: Option<FilterState>,
}

#[derive(Debug, Clone, Copy, PartialEq)]
struct FilterState {
    pose: Pose,
    /// Low-passed velocity (m/s), a vector as in the One Euro paper: alternating jitter
    /// averages out of it, real motion does not.
    velocity_t: DVec3,
    /// Low-passed angular velocity (rad/s, scaled axis in the filtered pose's frame).
    velocity_r: DVec3,
    t: f64,
}

impl PoseFilter {
    pub fn new(config: PoseFilterConfig) -> Self {
        Self {
            config,
            state: None,
        }
    }

    /// Forgets the history (next sample passes through).
    pub fn reset(&mut self) {
        self.state = None;
    }

    /// Filters a pose measured at `t_s` seconds.
    pub fn filter(&mut self, pose: Pose, t_s: f64) -> Pose {
        let c = self.config;
        let Some(s) = self.state.filter(|_| c.enabled) else {
            self.state = Some(FilterState {
                pose,
                velocity_t: DVec3::ZERO,
                velocity_r: DVec3::ZERO,
                t: t_s,
            });
            return pose;
        };
        let dt = if t_s > s.t { t_s - s.t } else { 1.0 / 60.0 };
        // Translation.
        let dtr: DVec3 = pose.translation - s.pose.translation;
        let a_d = alpha(c.d_cutoff_hz, dt);
        let velocity_t = s.velocity_t + (dtr / dt - s.velocity_t) * a_d;
        let a_t = alpha(
            c.translation_min_cutoff_hz + c.translation_beta * velocity_t.length(),
            dt,
        );
        let translation = s.pose.translation + dtr * a_t;
        // Rotation in the tangent space.
        let mut q = pose.rotation;
        if q.dot(s.pose.rotation) < 0.0 {
            q = -q;
        }
        let delta = (s.pose.rotation.conjugate() * q).normalize();
        let w = delta.to_scaled_axis();
        let velocity_r = s.velocity_r + (w / dt - s.velocity_r) * a_d;
        let a_r = alpha(
            c.rotation_min_cutoff_hz + c.rotation_beta * velocity_r.length(),
            dt,
        );
        let rotation = (s.pose.rotation * DQuat::from_scaled_axis(w * a_r)).normalize();
        let out = Pose {
            rotation,
            translation,
        };
        self.state = Some(FilterState {
            pose: out,
            velocity_t,
            velocity_r,
            t: t_s,
        });
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn smooths_jitter_when_still_and_follows_fast_moves() {
        let mut f = PoseFilter::new(PoseFilterConfig::default());
        // Deterministic jitter: +-1 mm, +-0.2 deg.
        let mut raw_dev = 0.0;
        let mut filt_dev = 0.0;
        for i in 0..240 {
            let t = i as f64 / 60.0;
            let j = if i % 2 == 0 { 1.0 } else { -1.0 } * ((i * 7919 % 13) as f64 / 13.0);
            let truth = DVec3::new(0.0, 0.0, 1.0);
            let p = Pose {
                rotation: DQuat::from_rotation_y((0.2 * j).to_radians()),
                translation: truth + DVec3::splat(0.001 * j),
            };
            let out = f.filter(p, t);
            if i > 60 {
                raw_dev += (p.translation - truth).length();
                filt_dev += (out.translation - truth).length();
            }
        }
        assert!(
            filt_dev < 0.3 * raw_dev,
            "filtered {filt_dev} vs raw {raw_dev}"
        );

        // A fast move at 1 m/s and 180 deg/s: after 0.25 s the lag is small.
        let mut f = PoseFilter::new(PoseFilterConfig::default());
        let mut lag_t = 0.0;
        let mut lag_r = 0.0;
        for i in 0..30 {
            let t = i as f64 / 60.0;
            let p = Pose {
                rotation: DQuat::from_rotation_z(std::f64::consts::PI * t),
                translation: DVec3::new(t, 0.0, 1.0),
            };
            let out = f.filter(p, t);
            lag_t = (out.translation - p.translation).length();
            lag_r = out.rotation_angle_to(&p).to_degrees();
        }
        // 1 m/s: a 1 Hz low-pass would lag ~160 mm; One Euro keeps it to a few mm.
        assert!(lag_t < 0.012, "translation lag {lag_t} m");
        assert!(lag_r < 3.0, "rotation lag {lag_r} deg");

        // Scalar filter: constant passes through.
        let mut s = OneEuro::new(1.0, 0.0, 1.0);
        for i in 0..10 {
            assert_eq!(s.filter(2.5, i as f64 * 0.1), 2.5);
        }
    }
}
