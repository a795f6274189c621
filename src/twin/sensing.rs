//! Sensing like the real robot (docs/sources.md, 4.4): encoders, joint torque sensors, and the external
//! wrench at the TCP estimated from joint torques minus model torques.
//!
//! - **Joint positions**: the true angle quantised to the encoder resolution, plus Gaussian noise.
//! - **Measured joint torques**: what a torque sensor between gearbox and link sees, the motor
//!   torque minus the rotor's inertia and the joint's viscous friction,
//!   `tau_J = tau_motor - armature * qdd - damping * qd`, plus white noise and a bias that drifts
//!   as a random walk.
//! - **External joint torques** from a generalised-momentum observer (De Luca and Mattone, 2003):
//!   `r = K_O (p - p0 - integral(tau_J - g(q) + r) dt)` with `p = M_link(q) qd`, a first-order
//!   filter of `tau_ext` with bandwidth `K_O` that needs no joint acceleration. Coriolis and
//!   centrifugal torques (`C^T qd`, quadratic in joint speed: below 0.01 N m at the speeds of
//!   probing and insertion) are left out of the model: an assumption, stated here.
//! - **External wrench** at the TCP, base frame (force, and torque about the TCP): the damped
//!   least-squares solution of `J^T F = tau_ext`, `F = (J J^T + l^2 I)^-1 J tau_ext`, then a
//!   first-order low-pass filter.
//! - **Calibration error** of that estimate (the load data, the model): a constant bias and a
//!   gain, `F_reported = gain F + bias`, which the contact flag and every break condition read
//!   (none by default).
//! - **Contact**: `|F| > on` switches contact on, `|F| < off` switches it off (hysteresis;
//!   `on` is the paper's epsilon_f).
//!
//! KUKA publishes no accuracy for its estimate; the noise defaults are assumptions, documented on
//! [`SensorParams`], and every one of them is configurable.

use crate::error::{Error, Result};
use crate::twin::robot::Dynamics;
use nalgebra::{DMatrix, DVector, Matrix6, Vector6};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use serde::{Deserialize, Serialize};

/// Sensor and estimator parameters.
/// In files, fields not given keep their defaults.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SensorParams {
    /// Encoder resolution, rad (default 2 pi / 2^20, a 20-bit absolute encoder; assumption).
    pub encoder_resolution_rad: f64,
    /// Encoder noise (standard deviation), rad.
    pub encoder_noise_rad: f64,
    /// Joint torque sensor white noise (standard deviation), N m (default 0.05; assumption).
    pub torque_noise_nm: f64,
    /// Random-walk rate of the torque sensors' bias, N m per square-root second
    /// (default 0.01; assumption: the estimate is known to drift, docs/sources.md, 4.4).
    pub torque_bias_walk_nm: f64,
    /// Momentum-observer gain (bandwidth), 1/s.
    pub observer_gain_per_s: f64,
    /// Cut-off of the low-pass filter on the estimated wrench, Hz (10 Hz as lbr_fri_ros2_stack).
    pub wrench_filter_hz: f64,
    /// Damping of the least-squares inverse of J^T (m-equivalent).
    pub pinv_damping: f64,
    /// Contact switches on above this force, N (the paper's epsilon_f).
    pub contact_on_n: f64,
    /// Contact switches off below this force, N.
    pub contact_off_n: f64,
    /// Bias of the reported wrench, N and N m (base frame, torque about the TCP); zero by default.
    #[serde(skip_serializing_if = "is_zero")]
    pub wrench_bias: [f64; 6],
    /// Gain of the reported wrench (1: none).
    #[serde(skip_serializing_if = "is_one")]
    pub wrench_gain: f64,
    /// Each encoder's constant offset, rad (a kinematic calibration error: the controller and
    /// every recorded pose see the joint this much off); empty: none, else one per joint.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub encoder_offset_rad: Vec<f64>,
}

fn is_zero(v: &[f64; 6]) -> bool {
    *v == [0.0; 6]
}

fn is_one(v: &f64) -> bool {
    *v == 1.0
}

/// Largest bias of the reported wrench accepted: force (N) and torque (N m).
pub const MAX_WRENCH_BIAS: (f64, f64) = (50.0, 10.0);
/// Largest encoder offset accepted, rad (0.57 deg: a unit error beyond).
pub const MAX_ENCODER_OFFSET_RAD: f64 = 0.01;
/// Accepted gains of the reported wrench.
pub const WRENCH_GAIN_RANGE: (f64, f64) = (0.5, 2.0);

impl Default for SensorParams {
    fn default() -> Self {
        SensorParams {
            encoder_resolution_rad: std::f64::consts::TAU / (1u64 << 20) as f64,
            encoder_noise_rad: 0.0,
            torque_noise_nm: 0.05,
            torque_bias_walk_nm: 0.01,
            observer_gain_per_s: 100.0,
            wrench_filter_hz: 10.0,
            pinv_damping: 0.01,
            contact_on_n: 5.0,
            contact_off_n: 3.0,
            wrench_bias: [0.0; 6],
            wrench_gain: 1.0,
            encoder_offset_rad: Vec::new(),
        }
    }
}

impl SensorParams {
    /// Noise-free sensors (for tests that isolate the estimator's model error).
    pub fn ideal() -> Self {
        SensorParams {
            encoder_resolution_rad: 0.0,
            torque_noise_nm: 0.0,
            torque_bias_walk_nm: 0.0,
            ..Default::default()
        }
    }

    /// Rejects non-physical values, naming the field.
    pub fn ensure_valid(&self) -> Result<()> {
        // (name, value, least, most): a value outside is a unit error, or noise that buries
        // the contact force the method needs.
        let ranges = [
            (
                "encoder_resolution_rad",
                self.encoder_resolution_rad,
                0.0,
                0.01,
            ),
            ("encoder_noise_rad", self.encoder_noise_rad, 0.0, 0.01),
            ("torque_noise_nm", self.torque_noise_nm, 0.0, 10.0),
            ("torque_bias_walk_nm", self.torque_bias_walk_nm, 0.0, 10.0),
            ("pinv_damping", self.pinv_damping, 0.0, 1.0),
            ("observer_gain_per_s", self.observer_gain_per_s, 1e-3, 1e4),
            ("wrench_filter_hz", self.wrench_filter_hz, 1e-3, 500.0),
            ("contact_on_n", self.contact_on_n, 1e-3, 500.0),
            (
                "wrench_gain",
                self.wrench_gain,
                WRENCH_GAIN_RANGE.0,
                WRENCH_GAIN_RANGE.1,
            ),
        ];
        for (name, v, least, most) in ranges {
            if !(v >= least && v <= most) {
                return Err(Error::Input(format!(
                    "sensor {name} is {v:?}: expected a value in [{least}, {most}]"
                )));
            }
        }
        for (i, &b) in self.wrench_bias.iter().enumerate() {
            let most = if i < 3 {
                MAX_WRENCH_BIAS.0
            } else {
                MAX_WRENCH_BIAS.1
            };
            if b.is_nan() || b.abs() > most {
                return Err(Error::Input(format!(
                    "sensor wrench_bias[{i}] is {b:?}: expected a value in [-{most}, {most}]"
                )));
            }
        }
        if let Some((i, o)) = (self.encoder_offset_rad.iter().enumerate())
            .find(|(_, o)| o.is_nan() || o.abs() > MAX_ENCODER_OFFSET_RAD)
        {
            return Err(Error::Input(format!(
                "sensor encoder_offset_rad[{i}] is {o:?}: expected at most {} rad either way",
                MAX_ENCODER_OFFSET_RAD
            )));
        }
        if !(self.contact_off_n >= 0.0 && self.contact_off_n <= self.contact_on_n) {
            return Err(Error::Input(format!(
                "sensor contact_off_n is {}: expected a value between 0 and contact_on_n ({})",
                self.contact_off_n, self.contact_on_n
            )));
        }
        Ok(())
    }
}

/// A wrench: force (N) and torque (N m), base frame, torque about the TCP.
pub type Wrench6 = Vector6<f64>;

/// The robot's sensors and estimator state.
#[derive(Clone)]
pub struct Sensors {
    pub params: SensorParams,
    rng: ChaCha8Rng,
    bias: DVector<f64>,
    /// Momentum at the observer's start and the running integral.
    p0: Option<DVector<f64>>,
    integral: DVector<f64>,
    /// Observer output, estimated external joint torques, N m.
    pub tau_ext: DVector<f64>,
    /// Filtered external wrench at the TCP.
    filtered: Wrench6,
    /// The wrench reported: the filtered one through the calibration error.
    pub wrench: Wrench6,
    /// Contact flag with hysteresis.
    pub contact: bool,
}

impl Sensors {
    pub fn new(params: SensorParams, dof: usize, seed: u64) -> Result<Self> {
        params.ensure_valid()?;
        let offsets = params.encoder_offset_rad.len();
        if offsets != 0 && offsets != dof {
            return Err(Error::Input(format!(
                "sensor encoder_offset_rad: {offsets} values for an arm of {dof} joints"
            )));
        }
        Ok(Sensors {
            params,
            rng: ChaCha8Rng::seed_from_u64(seed),
            bias: DVector::zeros(dof),
            p0: None,
            integral: DVector::zeros(dof),
            tau_ext: DVector::zeros(dof),
            filtered: Wrench6::zeros(),
            wrench: Wrench6::zeros(),
            contact: false,
        })
    }

    fn gaussian(&mut self, sigma: f64) -> f64 {
        gaussian(&mut self.rng, sigma)
    }

    /// Encoder reading of true joint positions `q`, rad: off by the encoder's offset,
    /// quantised, with noise.
    pub fn read_q(&mut self, q: &[f64]) -> Vec<f64> {
        let res = self.params.encoder_resolution_rad;
        let sigma = self.params.encoder_noise_rad;
        let (offsets, rng) = (&self.params.encoder_offset_rad, &mut self.rng);
        q.iter()
            .enumerate()
            .map(|(i, &v)| {
                let v = offsets.get(i).map_or(v, |o| v + o);
                let quantised = if res > 0.0 {
                    (v / res).round() * res
                } else {
                    v
                };
                quantised + gaussian(rng, sigma)
            })
            .collect()
    }

    /// Torque-sensor reading from the link-side joint torques `tau_link` over a period `dt_s`:
    /// white noise plus a drifting bias.
    pub fn read_torques(&mut self, tau_link: &DVector<f64>, dt_s: f64) -> DVector<f64> {
        let walk = self.params.torque_bias_walk_nm * dt_s.sqrt();
        let noise = self.params.torque_noise_nm;
        let mut out = tau_link.clone();
        for i in 0..out.len() {
            self.bias[i] += self.gaussian(walk);
            out[i] += self.bias[i] + self.gaussian(noise);
        }
        out
    }

    /// One estimator cycle of `dt_s` seconds from the model at the measured joint positions,
    /// the joint velocities and the measured torques: updates `tau_ext`, `wrench` and `contact`.
    pub fn estimate(&mut self, d: &Dynamics, qd: &[f64], tau_measured: &DVector<f64>, dt_s: f64) {
        let p = &d.link_mass * DVector::from_row_slice(qd);
        let p0 = self.p0.get_or_insert_with(|| p.clone());
        self.tau_ext = (&p - &*p0 - &self.integral) * self.params.observer_gain_per_s;
        self.integral += (tau_measured - &d.gravity + &self.tau_ext) * dt_s;
        let jac = &d.jacobian;
        let f = wrench_from_joint_torques(jac, &self.tau_ext, self.params.pinv_damping);
        let alpha = 1.0 - (-std::f64::consts::TAU * self.params.wrench_filter_hz * dt_s).exp();
        self.filtered += (f - self.filtered) * alpha;
        let (gain, bias) = (self.params.wrench_gain, self.params.wrench_bias);
        self.wrench = if gain == 1.0 && is_zero(&bias) {
            self.filtered
        } else {
            self.filtered * gain + Wrench6::from(bias)
        };
        let force = self.wrench.fixed_rows::<3>(0).norm();
        if self.contact && force < self.params.contact_off_n {
            self.contact = false;
        } else if !self.contact && force > self.params.contact_on_n {
            self.contact = true;
        }
    }
}

/// A sample of zero-mean Gaussian noise of standard deviation `sigma` (none at 0).
fn gaussian(rng: &mut ChaCha8Rng, sigma: f64) -> f64 {
    if sigma > 0.0 {
        Normal::new(0.0, sigma).expect("sigma > 0").sample(rng)
    } else {
        0.0
    }
}

/// The TCP wrench whose `J^T F` best explains `tau_ext`: `(J J^T + l^2 I)^-1 J tau_ext`.
pub fn wrench_from_joint_torques(
    jac: &DMatrix<f64>,
    tau_ext: &DVector<f64>,
    damping: f64,
) -> Wrench6 {
    let jjt: Matrix6<f64> = (jac * jac.transpose())
        .fixed_view::<6, 6>(0, 0)
        .into_owned();
    let rhs: Vector6<f64> = Vector6::from_iterator((jac * tau_ext).iter().copied());
    let a = jjt + Matrix6::identity() * damping * damping;
    a.cholesky().map_or_else(Vector6::zeros, |c| c.solve(&rhs))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wrench_inversion_recovers_a_wrench_at_a_regular_configuration() {
        let robot = crate::twin::robot::urdf::iiwa14().unwrap();
        let q = [0.1, 0.7, -0.2, -1.4, 0.3, 0.9, 0.2];
        let k = robot.kinematics(&q);
        let jac = robot.tcp_jacobian(&k);
        let f = Vector6::new(3.0, -2.0, 10.0, 0.5, -0.3, 0.2);
        let tau = jac.transpose() * DVector::from_column_slice(f.as_slice());
        let back = wrench_from_joint_torques(&jac, &tau, 1e-4);
        assert!((back - f).norm() < 1e-3, "{back}");
    }

    #[test]
    fn bad_sensor_parameters_are_named() {
        let p = SensorParams {
            contact_off_n: 7.0,
            ..Default::default()
        };
        assert!(
            p.ensure_valid()
                .unwrap_err()
                .to_string()
                .contains("contact_off_n")
        );
        let p = SensorParams {
            torque_noise_nm: -1.0,
            ..Default::default()
        };
        assert!(
            p.ensure_valid()
                .unwrap_err()
                .to_string()
                .contains("torque_noise_nm")
        );
    }

    #[test]
    fn encoder_quantises() {
        let mut s = Sensors::new(SensorParams::default(), 1, 1).unwrap();
        let res = s.params.encoder_resolution_rad;
        let q = s.read_q(&[0.123_456_789]);
        assert!((q[0] / res - (q[0] / res).round()).abs() < 1e-6);
        assert!((q[0] - 0.123_456_789).abs() <= res / 2.0 + 1e-15);
    }
}
