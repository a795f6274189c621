//! Motion primitives as moving impedance targets (paper IV-B and IV-C): an Archimedean spiral in
//! the hole's x, y; oscillations in roll, pitch and yaw at distinct frequencies; a slow descent in
//! z; random perturbations (Ornstein-Uhlenbeck, seeded) against sampling bias; and amplitude
//! schedules by depth and clearance.
//!
//! A primitive gives the target of the TCP relative to the hole frame the robot believes in:
//! `hole_T_target = Trans(x, y, -depth) * Rz(yaw) Ry(pitch) Rx(roll)` (the TCP is the peg tip, z up
//! the peg, so an aligned, inserted peg has `hole_T_tcp = Trans(0, 0, -depth)`). The targets move
//! beyond the free play on purpose: under a compliant impedance the excess becomes a contact force
//! (stiffness x overtravel), which is what the contact detector feels.

use crate::method::session::Session;
use crate::pose::{Iso, Pose6};
use crate::twin::workcell::Measurements;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use serde::{Deserialize, Serialize};
use std::f64::consts::TAU;
use std::ops::ControlFlow;

/// Archimedean spiral `r = pitch * theta / 2 pi`, travelled at constant speed out to the maximum
/// radius and back to the centre, over and over.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Spiral {
    /// Largest radius, m.
    pub max_radius_m: f64,
    /// Radial growth per turn, m.
    pub pitch_m: f64,
    /// Speed along the curve, m/s.
    pub speed_m_per_s: f64,
}

impl Spiral {
    /// `b` of `r = b theta`.
    fn b(&self) -> f64 {
        self.pitch_m / TAU
    }

    /// Arc length from the centre to angle `theta`.
    fn arc_length(&self, theta: f64) -> f64 {
        0.5 * self.b() * (theta * (1.0 + theta * theta).sqrt() + theta.asinh())
    }

    /// The angle at arc length `s` (Newton's method; the arc length is convex in theta).
    fn angle_at(&self, s: f64) -> f64 {
        let b = self.b();
        let mut theta = (2.0 * s / b).sqrt();
        for _ in 0..8 {
            let f = self.arc_length(theta) - s;
            let df = b * (1.0 + theta * theta).sqrt();
            theta -= f / df;
        }
        theta.max(0.0)
    }

    /// Offset in x, y at time `t_s`, m.
    pub fn offset(&self, t_s: f64) -> [f64; 2] {
        if self.max_radius_m <= 0.0 || self.pitch_m <= 0.0 || self.speed_m_per_s <= 0.0 {
            return [0.0, 0.0];
        }
        let theta_max = self.max_radius_m / self.b();
        let s_max = self.arc_length(theta_max);
        // Out and back: a triangle wave of the arc length.
        let travelled = (self.speed_m_per_s * t_s).rem_euclid(2.0 * s_max);
        let s = if travelled <= s_max {
            travelled
        } else {
            2.0 * s_max - travelled
        };
        let theta = self.angle_at(s);
        let r = self.b() * theta;
        [r * theta.cos(), r * theta.sin()]
    }
}

/// Sinusoids on roll, pitch and yaw with distinct frequencies (a Lissajous figure that fills the
/// angular box instead of retracing one curve).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Oscillation {
    /// Amplitudes of roll, pitch, yaw, rad.
    pub amplitude_rad: [f64; 3],
    /// Frequencies of roll, pitch, yaw, Hz.
    pub frequency_hz: [f64; 3],
}

impl Oscillation {
    /// Roll, pitch, yaw at time `t_s`, rad.
    pub fn angles(&self, t_s: f64) -> [f64; 3] {
        std::array::from_fn(|i| {
            // Quarter-period phase steps so that the three axes do not start together.
            let phase = i as f64 * TAU / 4.0;
            self.amplitude_rad[i] * (TAU * self.frequency_hz[i] * t_s + phase).sin()
        })
    }
}

/// Descent in z: from `start_depth_m` to `end_depth_m` at `speed_m_per_s`, then holding.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Descent {
    pub start_depth_m: f64,
    pub end_depth_m: f64,
    pub speed_m_per_s: f64,
}

impl Descent {
    /// Target depth of the tip below the mouth at time `t_s`, m.
    pub fn depth(&self, t_s: f64) -> f64 {
        let span = self.end_depth_m - self.start_depth_m;
        let moved = (self.speed_m_per_s * t_s.max(0.0)).min(span.abs());
        self.start_depth_m + moved * span.signum()
    }

    /// Time to reach the end depth, s.
    pub fn duration_s(&self) -> f64 {
        if self.speed_m_per_s > 0.0 {
            (self.end_depth_m - self.start_depth_m).abs() / self.speed_m_per_s
        } else {
            f64::INFINITY
        }
    }
}

/// Random perturbation of the target: an Ornstein-Uhlenbeck process per axis, stationary
/// standard deviations `sigma_m` (x, y, z) and `sigma_rad` (roll, pitch, yaw), correlation time
/// `correlation_time_s`; deterministic for a seed.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Perturbation {
    pub sigma_m: f64,
    pub sigma_rad: f64,
    pub correlation_time_s: f64,
}

/// The state of a [`Perturbation`].
pub struct PerturbationState {
    params: Perturbation,
    rng: ChaCha8Rng,
    value: [f64; 6],
}

impl PerturbationState {
    pub fn new(params: Perturbation, seed: u64) -> Self {
        PerturbationState {
            params,
            rng: ChaCha8Rng::seed_from_u64(seed),
            value: [0.0; 6],
        }
    }

    /// Advances by `dt_s` (exact discretisation of the process) and returns the offsets
    /// `[x, y, z, roll, pitch, yaw]` (m, rad).
    pub fn step(&mut self, dt_s: f64) -> [f64; 6] {
        let tau = self.params.correlation_time_s.max(1e-6);
        let a = (-dt_s / tau).exp();
        let spread = (1.0 - a * a).sqrt();
        for i in 0..6 {
            let sigma = if i < 3 {
                self.params.sigma_m
            } else {
                self.params.sigma_rad
            };
            let n: f64 = StandardNormal.sample(&mut self.rng);
            self.value[i] = a * self.value[i] + sigma * spread * n;
        }
        self.value
    }
}

/// Amplitudes as a function of depth and clearance. The free play of a peg at depth `d` in a hole
/// of diametral clearance `c` is `c / 2` sideways and about `c / d` in tilt (the tip and the mouth
/// edge each take up half the gap over the engaged length); the motion adds an overtravel beyond
/// that play, which the compliant controller turns into a contact force.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AmplitudeSchedule {
    /// Lateral overtravel beyond the gap, m.
    pub lateral_overtravel_m: f64,
    /// Angular overtravel beyond the free tilt, rad.
    pub angular_overtravel_rad: f64,
    /// Largest free tilt used (the c/d estimate grows without bound near the mouth), rad.
    pub max_free_tilt_rad: f64,
    /// Yaw amplitude as a fraction of the tilt amplitude.
    pub yaw_fraction: f64,
}

impl AmplitudeSchedule {
    /// Largest spiral radius at this clearance, m.
    pub fn lateral_radius(&self, clearance_m: f64) -> f64 {
        clearance_m / 2.0 + self.lateral_overtravel_m
    }

    /// Roll, pitch and yaw amplitudes at this depth and clearance, rad.
    pub fn angular_amplitudes(&self, depth_m: f64, clearance_m: f64) -> [f64; 3] {
        let free = (clearance_m / depth_m.max(1e-4)).min(self.max_free_tilt_rad);
        let tilt = free + self.angular_overtravel_rad;
        [tilt, tilt, tilt * self.yaw_fraction]
    }
}

/// The combined sampling motion: spiral + oscillation + descent + perturbation, with amplitudes
/// from a schedule. `scale` shrinks or widens the amplitudes (phase 1 / phase 2 of observation).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SamplingMotion {
    /// Spiral pitch, m per turn, and speed along it, m/s (the radius comes from the schedule).
    pub spiral_pitch_m: f64,
    pub spiral_speed_m_per_s: f64,
    /// Oscillation frequencies of roll, pitch, yaw, Hz.
    pub frequency_hz: [f64; 3],
    pub descent: Descent,
    pub perturbation: Perturbation,
    pub schedule: AmplitudeSchedule,
    /// Multiplies every amplitude where one scale serves the whole drive (the sampler's
    /// [`ScaleSchedule::constant`]; the geometric sampler's ranges).
    pub scale: f64,
    /// Time offset of the spiral and the oscillation, s (episodes start at different phases).
    pub phase_s: f64,
}

impl SamplingMotion {
    /// Target `hole_T_tcp` at time `t_s`, with the perturbation's current `noise` (from
    /// [`PerturbationState::step`]), the amplitudes of the spiral, the roll and pitch, and the
    /// yaw scaled by `scales` (in [`Probe`]'s order; a drive's [`ScaleSchedule::scales_at`]).
    pub fn target(&self, t_s: f64, clearance_m: f64, noise: &[f64; 6], scales: [f64; 3]) -> Pose6 {
        let depth = self.descent.depth(t_s);
        let spiral = Spiral {
            max_radius_m: scales[0] * self.schedule.lateral_radius(clearance_m),
            pitch_m: self.spiral_pitch_m,
            speed_m_per_s: self.spiral_speed_m_per_s,
        };
        let [roll, pitch, yaw] = self.schedule.angular_amplitudes(depth, clearance_m);
        let amplitudes = [roll * scales[1], pitch * scales[1], yaw * scales[2]];
        let oscillation = Oscillation {
            amplitude_rad: amplitudes,
            frequency_hz: self.frequency_hz,
        };
        let [x, y] = spiral.offset(t_s + self.phase_s);
        let [roll, pitch, yaw] = oscillation.angles(t_s + self.phase_s);
        Pose6([
            x + noise[0],
            y + noise[1],
            -depth + noise[2],
            roll + noise[3],
            pitch + noise[4],
            yaw + noise[5],
        ])
    }
}

/// The groups of the motion's amplitudes: the spiral (x, y), the roll and pitch oscillations
/// (tilt), the yaw oscillation. Active probing (issue "know when you know", docs/method.md)
/// widens one of them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Probe {
    Lateral = 0,
    Tilt = 1,
    Yaw = 2,
}

/// The amplitude scale of a drive: `before` until `switch_s`, then `after` (the two phases of
/// the observation, paper IV-C; one constant scale for the manifold sampler); after the switch,
/// a `widened` group keeps the wide scale `before` (active probing).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ScaleSchedule {
    pub before: f64,
    pub after: f64,
    /// Time of the switch from the start of the drive, s.
    pub switch_s: f64,
    pub widened: Option<Probe>,
}

impl ScaleSchedule {
    /// One scale throughout.
    pub fn constant(scale: f64) -> Self {
        ScaleSchedule {
            before: scale,
            after: scale,
            switch_s: f64::INFINITY,
            widened: None,
        }
    }

    /// The scales of the spiral, the tilt and the yaw at `t_s` from the start of the drive.
    pub fn scales_at(&self, t_s: f64) -> [f64; 3] {
        if t_s < self.switch_s {
            return [self.before; 3];
        }
        let mut scales = [self.after; 3];
        if let Some(probe) = self.widened {
            scales[probe as usize] = self.before;
        }
        scales
    }
}

/// One run of the sampling motion (paper IV-B, IV-C) for `duration_s` in the hole frame the robot
/// believes in, `base_t_hole`: at every physics step the target is `base_t_hole *
/// motion.target(t)` with the perturbation's next value. Both the offline sampler of the reference
/// manifold and the online observation drive their primitives through [`Drive::run`].
pub struct Drive<'a> {
    pub base_t_hole: Iso,
    pub motion: &'a SamplingMotion,
    pub schedule: ScaleSchedule,
    /// Diametral clearance the amplitudes are scheduled for, m.
    pub clearance_m: f64,
    pub duration_s: f64,
}

impl Drive<'_> {
    /// Runs the motion on `session` with the perturbation `noise`; `on_step` sees the
    /// measurements after every step. Stops when the physics faults or `on_step` breaks.
    pub fn run(
        &self,
        session: &mut Session,
        noise: &mut PerturbationState,
        on_step: impl FnMut(&Measurements) -> ControlFlow<()>,
    ) {
        let steps = Drive::steps_until(self.duration_s, session.dt_s());
        self.run_steps(session, noise, 0..steps, on_step);
    }

    /// The number of physics steps of `dt` in the first `t_s` of the drive.
    pub fn steps_until(t_s: f64, dt: f64) -> usize {
        (t_s / dt).round() as usize
    }

    /// Runs steps `steps` of the drive (step `k` at `k dt` from its start), `noise` having run
    /// the steps before; false if it stopped early. A drive run in consecutive pieces, each
    /// after one that ran to its end, is the same simulation as one run whole (the observation
    /// stops at each budget of a `t_obs` sweep this way).
    pub fn run_steps(
        &self,
        session: &mut Session,
        noise: &mut PerturbationState,
        steps: std::ops::Range<usize>,
        mut on_step: impl FnMut(&Measurements) -> ControlFlow<()>,
    ) -> bool {
        let dt = session.dt_s();
        for k in steps {
            let t = k as f64 * dt;
            let scales = self.schedule.scales_at(t);
            let n = noise.step(dt);
            let target = self.motion.target(t, self.clearance_m, &n, scales);
            session.command_pose(self.base_t_hole * target.to_iso());
            if !session.step() || on_step(&session.measurements()).is_break() {
                return false;
            }
        }
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spiral_reaches_its_radius_at_constant_speed_and_comes_back() {
        let s = Spiral {
            max_radius_m: 2e-3,
            pitch_m: 0.2e-3,
            speed_m_per_s: 10e-3,
        };
        let dt = 1e-4;
        let theta_max = 2e-3 / s.b();
        let back = 2.0 * s.arc_length(theta_max) / 10e-3;
        let mut max_r: f64 = 0.0;
        let mut prev = s.offset(0.0);
        for k in 1..(back / dt) as usize {
            let p = s.offset(k as f64 * dt);
            let r = (p[0] * p[0] + p[1] * p[1]).sqrt();
            max_r = max_r.max(r);
            let step = ((p[0] - prev[0]).powi(2) + (p[1] - prev[1]).powi(2)).sqrt();
            // Chord per step never exceeds the arc per step.
            assert!(step <= 10e-3 * dt * 1.0001 + 1e-12, "step {step} at {k}");
            prev = p;
        }
        assert!((max_r - 2e-3).abs() < 1e-5, "max radius {max_r}");
        let centre = s.offset(back);
        assert!(
            centre[0].hypot(centre[1]) < 1e-6,
            "back at the centre after {back} s"
        );
    }

    #[test]
    fn oscillation_stays_in_its_box_and_descent_holds_at_the_end() {
        let o = Oscillation {
            amplitude_rad: [0.01, 0.02, 0.005],
            frequency_hz: [0.7, 1.1, 0.5],
        };
        for k in 0..1000 {
            let a = o.angles(k as f64 * 0.01);
            for (v, amp) in a.iter().zip(o.amplitude_rad) {
                assert!(v.abs() <= amp + 1e-15);
            }
        }
        let d = Descent {
            start_depth_m: 0.002,
            end_depth_m: 0.012,
            speed_m_per_s: 0.002,
        };
        assert!((d.depth(2.5) - 0.007).abs() < 1e-12);
        assert_eq!(d.depth(100.0), 0.012);
        assert!((d.duration_s() - 5.0).abs() < 1e-12);
    }

    #[test]
    fn a_widened_group_keeps_the_wide_scale_after_the_switch() {
        let mut s = ScaleSchedule {
            before: 1.0,
            after: 0.8,
            switch_s: 3.6,
            widened: None,
        };
        assert_eq!(s.scales_at(1.0), [1.0; 3]);
        assert_eq!(s.scales_at(4.0), [0.8; 3]);
        s.widened = Some(Probe::Tilt);
        assert_eq!(s.scales_at(1.0), [1.0; 3]);
        assert_eq!(s.scales_at(4.0), [0.8, 1.0, 0.8]);
        let motion = crate::method::manifold::build::SamplerConfig::default().motion;
        let noise = [0.0; 6];
        let wide = motion.target(2.0, 5e-4, &noise, [0.8, 1.0, 0.8]).0;
        let narrow = motion.target(2.0, 5e-4, &noise, [0.8; 3]).0;
        assert_eq!(wide[..3], narrow[..3]);
        assert!(wide[3].abs() > narrow[3].abs() && wide[5] == narrow[5]);
    }

    #[test]
    fn perturbation_is_seeded_and_has_its_stationary_spread() {
        let p = Perturbation {
            sigma_m: 1e-4,
            sigma_rad: 1e-3,
            correlation_time_s: 0.05,
        };
        let mut a = PerturbationState::new(p.clone(), 3);
        let mut b = PerturbationState::new(p, 3);
        let mut sum_sq = 0.0;
        let n = 200_000;
        for _ in 0..n {
            let va = a.step(1e-3);
            assert_eq!(va, b.step(1e-3));
            sum_sq += va[0] * va[0];
        }
        let sd = (sum_sq / n as f64).sqrt();
        assert!((sd / 1e-4 - 1.0).abs() < 0.1, "stationary sd {sd}");
    }

    #[test]
    fn amplitudes_shrink_with_depth_and_grow_with_clearance() {
        let s = AmplitudeSchedule {
            lateral_overtravel_m: 2e-3,
            angular_overtravel_rad: 0.01,
            max_free_tilt_rad: 0.05,
            yaw_fraction: 0.5,
        };
        let shallow = s.angular_amplitudes(0.003, 0.5e-3);
        let deep = s.angular_amplitudes(0.02, 0.5e-3);
        assert!(shallow[0] > deep[0] && deep[0] > 0.01);
        assert!(s.angular_amplitudes(0.02, 1e-3)[0] > deep[0]);
        assert!((s.lateral_radius(0.5e-3) - 2.25e-3).abs() < 1e-12);
        assert!((deep[2] - deep[0] * 0.5).abs() < 1e-15);
    }
}
