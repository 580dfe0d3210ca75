//! Pose filtering for video. [`PoseFilter`] is a constant-velocity Kalman filter, one per
//! axis of rotation (a camera-frame scaled axis) and translation, whose measurement noise is
//! the one each frame's pose fit measured ([`crate::pose::PoseNoise`]: this frame's geometry,
//! which grows when tags are hidden, times the running mean of the fits' residual
//! variance). A frame that pins the pose well is followed closely; a poorly pinned one leans
//! on the prediction. The process noise (how much the camera may accelerate) adapts to the
//! innovations: it grows when they are larger than predicted or correlated from frame to
//! frame (the filter lags a move or a shifting bias), and shrinks back when they are small
//! or alternate, never below the configured one (`motion_scale_min` = 1: letting it shrink
//! smoothed a still camera more but lagged the clean moving one by 15-20 % of its error at
//! 960x540). An innovation beyond `gate_sigma` inflates the uncertainty by that ratio,
//! so a sudden move is followed at once. Rotation is filtered in the tangent space at the
//! prediction (`q <- exp(k y) q_pred`, `y = log(q_meas q_pred^-1)`), so there is no sign or
//! normalisation problem. [`OneEuro`] (Casiez et al., CHI 2012) remains as a scalar filter.
//!
//! Measured (`propsalive eval`'s tracking rows; `tests/tracking_filter.rs` in pa-scene):
//! on clean generated frames the filtered rotation error is no worse than per still, on
//! frames with sensor noise and blur it is lower.

use glam::{DQuat, DVec3};

use crate::pose::PoseNoise;
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
    /// Standard deviation of the camera's angular acceleration the motion model allows
    /// (rad/s^2; a handheld camera: a few).
    pub rotation_accel_rad_s2: f64,
    /// Standard deviation of the translational acceleration (m/s^2).
    pub translation_accel_m_s2: f64,
    /// Measurement noise assumed when a pose comes without its own (1 sigma per axis).
    pub default_rotation_sigma_rad: f64,
    pub default_translation_sigma_m: f64,
    /// Weight of a new frame in the running mean of the fits' residual variance (0..=1;
    /// 1 = this frame's alone). The geometry of the noise is always this frame's.
    pub noise_smoothing: f64,
    /// Innovations beyond this many predicted sigmas (rms over the axes) make the filter
    /// follow the measurement.
    pub gate_sigma: f64,
    /// Weight of a new frame in the running means of the innovations' autocorrelation that
    /// adapts the process noise to the motion (0: no adaptation).
    pub motion_smoothing: f64,
    /// Exponent of the adaptation per unit of lag-1 autocorrelation (the total per frame
    /// is at most one `motion_step`).
    pub motion_gain: f64,
    /// Largest change of the process-noise factor per frame (a factor > 1).
    pub motion_step: f64,
    /// Bounds of that adaptation, as factors on the accelerations' variance.
    pub motion_scale_min: f64,
    pub motion_scale_max: f64,
    /// Prior sigma of the velocity when tracking starts: rad/s and m/s.
    pub initial_angular_speed_rad_s: f64,
    pub initial_speed_m_s: f64,
}

impl Default for PoseFilterConfig {
    fn default() -> Self {
        Self {
            enabled: true,
            rotation_accel_rad_s2: 4.0,
            translation_accel_m_s2: 3.0,
            default_rotation_sigma_rad: 0.1f64.to_radians(),
            default_translation_sigma_m: 0.0005,
            noise_smoothing: 0.2,
            gate_sigma: 3.0,
            motion_smoothing: 0.1,
            motion_gain: 3.0,
            motion_step: 1.25,
            motion_scale_min: 1.0,
            motion_scale_max: 16.0,
            initial_angular_speed_rad_s: 1.0,
            initial_speed_m_s: 0.5,
        }
    }
}

/// One axis of the constant-velocity model: velocity, the covariance of (position,
/// velocity), and the adaptation of its process noise.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Axis {
    velocity: f64,
    /// Covariance `[[pp, pv], [pv, vv]]`.
    pp: f64,
    pv: f64,
    vv: f64,
    /// Running means of the normalised innovation's square and of its product with the
    /// previous one (lag-1 autocorrelation), and that previous one.
    c0: f64,
    c1: f64,
    last: f64,
    /// The motion the innovations show, as a factor on the configured process noise.
    q_scale: f64,
}

impl Axis {
    fn new(r: f64, speed_sigma: f64) -> Self {
        Self {
            velocity: 0.0,
            pp: r,
            pv: 0.0,
            vv: speed_sigma * speed_sigma,
            c0: 1.0,
            c1: 0.0,
            last: 0.0,
            q_scale: 1.0,
        }
    }

    /// Predicts over `dt` (white-noise acceleration of sigma `accel`), then updates with
    /// innovation `y` (measurement minus prediction) of measured variance `r`. Returns the
    /// correction to add to the predicted position.
    fn step(&mut self, y: f64, r: f64, dt: f64, accel: f64, cfg: &PoseFilterConfig) -> f64 {
        let q = accel * accel * self.q_scale;
        let (dt2, dt3, dt4) = (dt * dt, dt * dt * dt, dt * dt * dt * dt);
        let mut pp = self.pp + 2.0 * dt * self.pv + dt2 * self.vv + q * dt4 / 4.0;
        let mut pv = self.pv + dt * self.vv + q * dt3 / 2.0;
        let mut vv = self.vv + q * dt2;
        let s = pp + r;
        if s <= 0.0 || !s.is_finite() {
            // No uncertainty at all: take the measurement.
            self.pp = 0.0;
            self.pv = 0.0;
            return y;
        }
        // Whiteness: the innovations of a well-tuned filter are uncorrelated in time. When
        // consecutive ones agree (positive lag-1 autocorrelation: the filter lags motion or a
        // shifting bias) the process noise grows; when they alternate (it follows jitter) it
        // shrinks; by at most `motion_step` a frame, within the configured bounds.
        let y2 = y * y;
        let yn = y / s.sqrt();
        let b = cfg.motion_smoothing.clamp(0.0, 1.0);
        if b > 0.0 {
            self.c0 += b * (yn * yn - self.c0);
            self.c1 += b * (yn * self.last - self.c1);
            let rho = (self.c1 / self.c0.max(1e-12)).clamp(-1.0, 1.0);
            let step = cfg.motion_step.max(1.0 + 1e-6);
            let size = self.c0.max(1e-12).ln() / step.ln();
            let e = (size + cfg.motion_gain * rho).clamp(-1.0, 1.0);
            self.q_scale =
                (self.q_scale * step.powf(e)).clamp(cfg.motion_scale_min, cfg.motion_scale_max);
        }
        self.last = yn;
        // Normalised innovation: beyond the gate, inflate the prediction's uncertainty
        // so that the measurement is followed.
        let nis = y2 / s;
        let gate = cfg.gate_sigma.max(1.0);
        if nis > gate * gate {
            let lambda = nis / (gate * gate);
            pp *= lambda;
            pv *= lambda;
            vv *= lambda;
        }
        let s = pp + r;
        let kp = pp / s;
        let kv = pv / s;
        self.velocity += y * kv;
        self.pp = pp * (1.0 - kp);
        self.pv = pv * (1.0 - kp);
        self.vv = vv - kv * pv;
        y * kp
    }
}

/// Three axes (rotation or translation).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Group([Axis; 3]);

impl Group {
    fn new(r: DVec3, speed_sigma: f64) -> Self {
        Self([
            Axis::new(r.x, speed_sigma),
            Axis::new(r.y, speed_sigma),
            Axis::new(r.z, speed_sigma),
        ])
    }

    fn velocity(&self) -> DVec3 {
        DVec3::new(self.0[0].velocity, self.0[1].velocity, self.0[2].velocity)
    }

    fn step(&mut self, y: DVec3, r: DVec3, dt: f64, accel: f64, cfg: &PoseFilterConfig) -> DVec3 {
        DVec3::new(
            self.0[0].step(y.x, r.x, dt, accel, cfg),
            self.0[1].step(y.y, r.y, dt, accel, cfg),
            self.0[2].step(y.z, r.z, dt, accel, cfg),
        )
    }
}

/// The pose filter (see the module docs).
#[derive(Debug, Clone, PartialEq)]
pub struct PoseFilter {
    pub config: PoseFilterConfig,
    state: Option<FilterState>,
}

#[derive(Debug, Clone, Copy, PartialEq)]
struct FilterState {
    pose: Pose,
    rotation: Group,
    translation: Group,
    /// Running mean of the fits' residual variance, px^2.
    residual_var_px2: f64,
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

    /// The pose the motion model expects at `t_s` (`None` before the first sample or when
    /// disabled).
    pub fn predict(&self, t_s: f64) -> Option<Pose> {
        let s = self.state.filter(|_| self.config.enabled)?;
        let dt = (t_s - s.t).max(0.0);
        Some(Pose {
            rotation: (DQuat::from_scaled_axis(s.rotation.velocity() * dt) * s.pose.rotation)
                .normalize(),
            translation: s.pose.translation + s.translation.velocity() * dt,
        })
    }

    /// Filters a pose measured at `t_s` seconds with the configured default noise.
    pub fn filter(&mut self, pose: Pose, t_s: f64) -> Pose {
        self.filter_measured(pose, None, t_s)
    }

    /// Filters a pose measured at `t_s` seconds whose fit measured `noise` (see
    /// [`crate::pose::pose_noise`]; `None`: the configured default).
    pub fn filter_measured(&mut self, pose: Pose, noise: Option<PoseNoise>, t_s: f64) -> Pose {
        let c = self.config;
        let noise = noise.filter(PoseNoise::is_valid).unwrap_or_else(|| {
            PoseNoise::isotropic(c.default_rotation_sigma_rad, c.default_translation_sigma_m)
        });
        let Some(mut s) = self.state.filter(|_| c.enabled) else {
            let s2 = noise.residual_var_px2;
            self.state = Some(FilterState {
                pose,
                rotation: Group::new(noise.rotation_var * s2, c.initial_angular_speed_rad_s),
                translation: Group::new(noise.translation_var * s2, c.initial_speed_m_s),
                residual_var_px2: s2,
                t: t_s,
            });
            return pose;
        };
        // This frame's geometry, the running mean of the residual variance.
        let a = c.noise_smoothing.clamp(0.0, 1.0);
        s.residual_var_px2 += a * (noise.residual_var_px2 - s.residual_var_px2);
        let r_rot = noise.rotation_var * s.residual_var_px2;
        let r_tr = noise.translation_var * s.residual_var_px2;
        let dt = if t_s > s.t { t_s - s.t } else { 1.0 / 60.0 };
        // Prediction.
        let q_pred =
            (DQuat::from_scaled_axis(s.rotation.velocity() * dt) * s.pose.rotation).normalize();
        let t_pred = s.pose.translation + s.translation.velocity() * dt;
        // Innovations.
        let mut q = pose.rotation;
        if q.dot(q_pred) < 0.0 {
            q = -q;
        }
        let y_rot = (q * q_pred.conjugate()).normalize().to_scaled_axis();
        let y_tr = pose.translation - t_pred;
        let k_rot = s
            .rotation
            .step(y_rot, r_rot, dt, c.rotation_accel_rad_s2, &c);
        let k_tr = s
            .translation
            .step(y_tr, r_tr, dt, c.translation_accel_m_s2, &c);
        let out = Pose {
            rotation: (DQuat::from_scaled_axis(k_rot) * q_pred).normalize(),
            translation: t_pred + k_tr,
        };
        s.pose = out;
        s.t = t_s;
        self.state = Some(s);
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Deterministic normal samples (xorshift64*, Box-Muller).
    struct Normal(u64);
    impl Normal {
        fn uniform(&mut self) -> f64 {
            self.0 ^= self.0 >> 12;
            self.0 ^= self.0 << 25;
            self.0 ^= self.0 >> 27;
            ((self.0.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11) as f64 + 0.5) / (1u64 << 53) as f64
        }
        fn sample(&mut self) -> f64 {
            let (u, v) = (self.uniform(), self.uniform());
            (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
        }
        fn vec3(&mut self) -> DVec3 {
            DVec3::new(self.sample(), self.sample(), self.sample())
        }
    }

    /// A handheld camera as pa-scene moves it: a slow arc (18 deg/s) plus sinusoidal
    /// shake (0.3-2 Hz, up to 1.5 deg and 15 mm).
    fn trajectory(t: f64) -> Pose {
        let shake = |f: f64, p: f64, a: f64| a * (std::f64::consts::TAU * f * t + p).sin();
        let yaw = (-18.0 + 18.0 * t + shake(1.7, 0.3, 1.5)).to_radians();
        let pitch = (30.0 + 3.0 * t + shake(0.9, 2.0, 1.0)).to_radians();
        let roll = shake(1.3, 4.0, 0.8).to_radians();
        Pose {
            rotation: DQuat::from_rotation_x(pitch)
                * DQuat::from_rotation_y(yaw)
                * DQuat::from_rotation_z(roll),
            translation: DVec3::new(
                0.02 * t + shake(0.6, 1.0, 0.01),
                -0.01 + shake(1.9, 0.5, 0.01),
                0.55 - 0.05 * t + shake(0.4, 3.0, 0.01),
            ),
        }
    }

    /// Mean rotation (deg) and translation (mm) error over frames 12.. of a 24 fps clip of
    /// `frames` frames, raw and filtered, with measurement noise of `sigma_deg` and
    /// `sigma_mm` per axis (the filter is told that noise).
    fn run(sigma_deg: f64, sigma_mm: f64, frames: usize, seed: u64) -> [f64; 4] {
        run_with(
            PoseFilterConfig::default(),
            sigma_deg,
            sigma_mm,
            frames,
            seed,
        )
    }

    fn run_with(
        cfg: PoseFilterConfig,
        sigma_deg: f64,
        sigma_mm: f64,
        frames: usize,
        seed: u64,
    ) -> [f64; 4] {
        let mut f = PoseFilter::new(cfg);
        let mut rng = Normal(seed);
        let noise = PoseNoise::isotropic(sigma_deg.to_radians(), sigma_mm * 1e-3);
        let mut sums = [0.0; 4];
        let mut n = 0.0;
        for i in 0..frames {
            let t = i as f64 / 24.0;
            let truth = trajectory(t);
            let meas = Pose {
                rotation: DQuat::from_scaled_axis(rng.vec3() * sigma_deg.to_radians())
                    * truth.rotation,
                translation: truth.translation + rng.vec3() * sigma_mm * 1e-3,
            };
            let out = f.filter_measured(meas, Some(noise), t);
            if i >= 12 {
                sums[0] += meas.rotation_angle_to(&truth).to_degrees();
                sums[1] += out.rotation_angle_to(&truth).to_degrees();
                sums[2] += (meas.translation - truth.translation).length() * 1e3;
                sums[3] += (out.translation - truth.translation).length() * 1e3;
                n += 1.0;
            }
        }
        sums.map(|v| v / n)
    }

    #[test]
    fn clean_moving_camera_is_not_lagged() {
        // Exact measurements (noise 0.001 deg, 0.01 mm): the filter must follow them.
        for seed in [1, 2, 3] {
            let [raw_r, filt_r, raw_t, filt_t] = run(0.001, 0.01, 120, seed);
            eprintln!("exact seed {seed}: rot {raw_r:.5} -> {filt_r:.5} deg, trans {raw_t:.4} -> {filt_t:.4} mm");
            // Raw error ~0.0016 deg; the filter may add at most 0.001 deg and 0.01 mm.
            assert!(
                filt_r <= raw_r + 0.001,
                "rotation: filtered {filt_r} deg vs raw {raw_r}"
            );
            assert!(
                filt_t <= raw_t + 0.01,
                "translation: filtered {filt_t} mm vs raw {raw_t}"
            );
        }
        // As a clean per-still pose at the eval's level (0.02 deg): no worse than raw.
        let [raw_r, filt_r, raw_t, filt_t] = run(0.02, 0.1, 120, 4);
        eprintln!("clean: rot {raw_r:.4} -> {filt_r:.4} deg, trans {raw_t:.4} -> {filt_t:.4} mm");
        assert!(
            filt_r <= raw_r,
            "rotation: filtered {filt_r} vs raw {raw_r}"
        );
        assert!(
            filt_t <= raw_t,
            "translation: filtered {filt_t} vs raw {raw_t}"
        );
    }

    #[test]
    fn noisy_handheld_camera_is_smoothed() {
        // Jitter of 0.15 deg and 1 mm per axis on the same moving camera.
        for seed in [1, 2, 3] {
            let [raw_r, filt_r, raw_t, filt_t] = run(0.15, 1.0, 120, seed);
            eprintln!("noisy seed {seed}: rot {raw_r:.4} -> {filt_r:.4} deg, trans {raw_t:.3} -> {filt_t:.3} mm");
            // Measured: rotation 0.91-0.93x, translation 0.95-0.97x (the shake itself is
            // motion a causal filter cannot average, and the process noise never drops below
            // the configured one, so that a clean moving camera is never lagged).
            assert!(
                filt_r < 0.95 * raw_r,
                "rotation: filtered {filt_r} deg vs raw {raw_r}"
            );
            assert!(
                filt_t < 0.98 * raw_t,
                "translation: filtered {filt_t} mm vs raw {raw_t}"
            );
        }
    }

    #[test]
    fn still_camera_jitter_is_removed_and_a_jump_is_followed() {
        let mut f = PoseFilter::new(PoseFilterConfig::default());
        let mut rng = Normal(9);
        let noise = PoseNoise::isotropic(0.2f64.to_radians(), 1e-3);
        let truth = Pose {
            rotation: DQuat::from_rotation_x(0.5),
            translation: DVec3::new(0.0, 0.0, 0.6),
        };
        let (mut raw, mut filt) = (0.0, 0.0);
        for i in 0..96 {
            let t = i as f64 / 24.0;
            let meas = Pose {
                rotation: DQuat::from_scaled_axis(rng.vec3() * 0.2f64.to_radians())
                    * truth.rotation,
                translation: truth.translation + rng.vec3() * 1e-3,
            };
            let out = f.filter_measured(meas, Some(noise), t);
            if i >= 24 {
                raw += meas.rotation_angle_to(&truth);
                filt += out.rotation_angle_to(&truth);
            }
        }
        eprintln!("still: rot {raw:.4} -> {filt:.4}");
        // A still camera: measured 0.88x (the process noise stays at the configured one).
        assert!(filt < 0.92 * raw, "filtered {filt} vs raw {raw}");
        // A sudden 10 degree, 50 mm move (the camera picked up): followed at once.
        let moved = Pose {
            rotation: DQuat::from_rotation_y(10f64.to_radians()) * truth.rotation,
            translation: truth.translation + DVec3::new(0.05, 0.0, 0.0),
        };
        let out = f.filter_measured(moved, Some(noise), 4.0);
        assert!(out.rotation_angle_to(&moved).to_degrees() < 1.0);
        let out = f.filter_measured(moved, Some(noise), 4.0 + 1.0 / 24.0);
        assert!(out.rotation_angle_to(&moved).to_degrees() < 0.5);
        assert!((out.translation - moved.translation).length() < 0.003);
        // The prediction extrapolates; reset forgets.
        assert!(f.predict(5.0).is_some());
        f.reset();
        assert!(f.predict(5.0).is_none());
        assert_eq!(f.filter(truth, 6.0), truth);
    }

    #[test]
    fn disabled_filter_passes_through() {
        let mut f = PoseFilter::new(PoseFilterConfig {
            enabled: false,
            ..Default::default()
        });
        for i in 0..10 {
            let p = trajectory(i as f64 * 0.3);
            assert_eq!(f.filter(p, i as f64 * 0.3), p);
        }
        // Scalar One Euro filter: a constant passes through.
        let mut s = OneEuro::new(1.0, 0.0, 1.0);
        for i in 0..10 {
            assert_eq!(s.filter(2.5, i as f64 * 0.1), 2.5);
        }
    }
}
