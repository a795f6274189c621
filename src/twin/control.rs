//! Torque-level controllers with KUKA Sunrise semantics (docs/sources.md, 4.1 and 5).
//!
//! **Cartesian impedance** (`CartesianImpedanceControlMode`): per-axis stiffness (0-5000 N/m,
//! 0-300 N m/rad) and damping ratio (0.1-1.0), both in the TCP frame, as Sunrise parametrises
//! `CartDOF.X..C`. The damping ratio becomes a damping matrix through the Cartesian inertia
//! Lambda(q) by the factorisation design of Albu-Schaeffer et al. (ICRA 2003; docs/sources.md, 5.2):
//! `D = Lambda^1/2 Xi K^1/2 + K^1/2 Xi Lambda^1/2`, so that 0.7 means 0.7 of critical damping of
//! the real arm, not of a unit mass. The spring-damper wrench is clamped per axis to the max
//! control force; an additional (feed-forward) wrench is added after the clamp. A null-space
//! stiffness and damping ratio pull the elbow to a reference posture through the dynamically
//! consistent projector `I - J^T Lambda J M^-1`, which leaves the TCP's stiffness untouched.
//!
//! **Joint position** (`PositionControlMode`): a stiff joint-space PD (default 2000 N m/rad, as
//! MuJoCo Menagerie's iiwa servos), damping ratio 1 on the joint-space inertia diagonal.
//!
//! Both produce the torque on top of gravity; like the real controller (which adds gravity
//! internally), [`Controller`] adds g(q) and clamps each joint to its torque limit. Switching mode
//! is bumpless: the difference between the last torque of the old mode and the first of the new
//! one is added as an offset that fades linearly to zero over [`ControllerParams::switch_blend_s`].
//! The offset depends on time only, never on the state, so it cannot destabilise the loop. (An
//! earlier version slewed the task torque by 1 N m per cycle in every cycle, as franka_ros does;
//! inside the feedback loop that lag pumped energy into the wrist at the stiff, lightly damped
//! corners of the Sunrise ranges: docs/journal/2026-11-23.md, "The Sunrise gain corners".)

use crate::error::{Error, Result};
use crate::twin::robot::{Dynamics, GRAVITY_UPRIGHT, Iso, RobotModel};
use nalgebra::{DMatrix, DVector, Matrix3, Matrix6, SymmetricEigen, Vector6};
use serde::{Deserialize, Serialize};

/// Sunrise ranges (docs/sources.md, 4.1).
pub const TRANSLATIONAL_STIFFNESS_RANGE: (f64, f64) = (0.0, 5000.0);
pub const ROTATIONAL_STIFFNESS_RANGE: (f64, f64) = (0.0, 300.0);
pub const DAMPING_RATIO_RANGE: (f64, f64) = (0.1, 1.0);
pub const NULL_SPACE_DAMPING_RANGE: (f64, f64) = (0.3, 1.0);
/// The largest force (N) and torque (N m) pegtwin accepts at the TCP, from a user's additional
/// control force or a diagnostic push: twice the iiwa 14's rated payload and more than its wrist
/// transmits. Sunrise takes any value; a larger one is a unit error.
pub const MAX_TCP_WRENCH: (f64, f64) = (500.0, 100.0);
/// Plausible upper bounds: null-space stiffness, N m/rad (Sunrise: >= 0), and max control force,
/// N or N m (libiiwa sends 1e6 for "unlimited").
pub const MAX_NULL_STIFFNESS: f64 = 1e4;
pub const MAX_CONTROL_FORCE_LIMIT: f64 = 1e6;

const AXES: [&str; 6] = ["x", "y", "z", "a (about z)", "b (about y)", "c (about x)"];

/// Cartesian impedance parameters, Sunrise semantics. Stiffness and damping act in the TCP frame:
/// index 0-2 translation x, y, z (N/m), 3-5 rotation about x, y, z (N m/rad).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ImpedanceGains {
    pub stiffness: [f64; 6],
    pub damping_ratio: [f64; 6],
    /// Null-space stiffness, N m/rad (>= 0).
    pub null_stiffness: f64,
    /// Null-space damping ratio (0.3-1.0).
    pub null_damping_ratio: f64,
    /// Largest spring-damper force and torque per axis (TCP frame), N and N m; `None`: unlimited.
    pub max_control_force: Option<[f64; 6]>,
    /// Feed-forward wrench added at the TCP (TCP frame), N and N m.
    pub additional_force: [f64; 6],
}

impl Default for ImpedanceGains {
    /// The Sunrise defaults: 2000 N/m, 200 N m/rad, damping 0.7, null space 100 N m/rad and 0.7.
    fn default() -> Self {
        ImpedanceGains {
            stiffness: [2000.0, 2000.0, 2000.0, 200.0, 200.0, 200.0],
            damping_ratio: [0.7; 6],
            null_stiffness: 100.0,
            null_damping_ratio: 0.7,
            max_control_force: None,
            additional_force: [0.0; 6],
        }
    }
}

impl ImpedanceGains {
    /// Same translational / rotational stiffness and one damping ratio on all axes.
    pub fn uniform(translational: f64, rotational: f64, damping_ratio: f64) -> Self {
        ImpedanceGains {
            stiffness: [
                translational,
                translational,
                translational,
                rotational,
                rotational,
                rotational,
            ],
            damping_ratio: [damping_ratio; 6],
            ..Default::default()
        }
    }

    /// Rejects values outside the Sunrise ranges (and pegtwin's plausible bounds where Sunrise
    /// sets none), naming the parameter, axis and range.
    pub fn ensure_valid(&self) -> Result<()> {
        for (i, &k) in self.stiffness.iter().enumerate() {
            let (lo, hi) = if i < 3 {
                TRANSLATIONAL_STIFFNESS_RANGE
            } else {
                ROTATIONAL_STIFFNESS_RANGE
            };
            let unit = if i < 3 { "N/m" } else { "N m/rad" };
            check_range(&format!("stiffness {}", AXES[i]), k, (lo, hi), unit)?;
        }
        for (i, &d) in self.damping_ratio.iter().enumerate() {
            check_range(
                &format!("damping ratio {}", AXES[i]),
                d,
                DAMPING_RATIO_RANGE,
                "",
            )?;
        }
        check_range(
            "null-space stiffness",
            self.null_stiffness,
            (0.0, MAX_NULL_STIFFNESS),
            "N m/rad",
        )?;
        check_range(
            "null-space damping ratio",
            self.null_damping_ratio,
            NULL_SPACE_DAMPING_RANGE,
            "",
        )?;
        for i in 0..6 {
            let unit = if i < 3 { "N" } else { "N m" };
            if let Some(max) = self.max_control_force {
                check_range(
                    &format!("max control force {}", AXES[i]),
                    max[i],
                    (f64::MIN_POSITIVE, MAX_CONTROL_FORCE_LIMIT),
                    unit,
                )?;
            }
            let limit = if i < 3 {
                MAX_TCP_WRENCH.0
            } else {
                MAX_TCP_WRENCH.1
            };
            check_range(
                &format!("additional force {}", AXES[i]),
                self.additional_force[i],
                (-limit, limit),
                unit,
            )?;
        }
        Ok(())
    }
}

/// Positive and finite (false for NaN).
pub fn is_positive(v: f64) -> bool {
    v > 0.0 && v.is_finite()
}

fn check_range(what: &str, v: f64, (lo, hi): (f64, f64), unit: &str) -> Result<()> {
    if !(v >= lo && v <= hi) {
        return Err(Error::Input(format!(
            "{what} {v:?} {unit} is outside the accepted range [{lo}, {hi}] {unit} (KUKA \
             Sunrise's, or pegtwin's plausible one where Sunrise sets none)"
        )));
    }
    Ok(())
}

/// Joint-position mode gains.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct JointPositionGains {
    /// N m/rad, every joint.
    pub stiffness: f64,
    /// Damping ratio on the diagonal of M(q).
    pub damping_ratio: f64,
}

impl Default for JointPositionGains {
    fn default() -> Self {
        JointPositionGains {
            stiffness: 2000.0,
            damping_ratio: 1.0,
        }
    }
}

/// What the controller does.
#[derive(Clone, Debug, PartialEq)]
#[allow(clippy::large_enum_variant)] // one mode per controller, never stored in bulk
pub enum Mode {
    /// Hold the TCP at `target` (`base_T_tcp`) under Cartesian impedance.
    CartesianImpedance { gains: ImpedanceGains, target: Iso },
    /// Hold the joints at `target` (rad).
    JointPosition {
        gains: JointPositionGains,
        target: Vec<f64>,
    },
}

/// Controller settings that do not change with the mode.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ControllerParams {
    /// Control rate, Hz (the physics step must divide the control period).
    pub rate_hz: f64,
    /// Time over which a mode switch fades from the old mode's torque to the new one's, s
    /// (0: switch at once).
    pub switch_blend_s: f64,
    /// Gravity in the robot base frame, m/s^2.
    pub gravity: [f64; 3],
    /// Time from a control cycle's measurements to its torques reaching the drives, s: a whole
    /// number of control periods (0: none, the default).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub latency_s: f64,
}

fn is_zero(v: &f64) -> bool {
    *v == 0.0
}

/// The longest control latency accepted, s.
pub const MAX_LATENCY_S: f64 = 0.05;

impl ControllerParams {
    /// The latency in control cycles; an error naming `latency_s` unless it is a whole number
    /// of control periods in [0, `MAX_LATENCY_S`].
    pub fn latency_cycles(&self) -> Result<usize> {
        let cycles = self.latency_s * self.rate_hz;
        let whole = cycles.round();
        if !(0.0..=MAX_LATENCY_S).contains(&self.latency_s) || (cycles - whole).abs() > 1e-6 {
            return Err(Error::Input(format!(
                "controller latency_s = {:?}: expected a whole number of control periods \
                 ({} s) in [0, {MAX_LATENCY_S}] s",
                self.latency_s,
                1.0 / self.rate_hz
            )));
        }
        Ok(whole as usize)
    }
}

impl Default for ControllerParams {
    /// 1 kHz, a 50 ms switch blend (our choice: Sunrise does not document how it smooths a mode
    /// switch), upright base.
    fn default() -> Self {
        ControllerParams {
            rate_hz: 1000.0,
            switch_blend_s: 0.05,
            gravity: GRAVITY_UPRIGHT.into(),
            latency_s: 0.0,
        }
    }
}

/// The controller of one arm: a mode, its target, the null-space reference, the last torque.
#[derive(Clone)]
pub struct Controller {
    pub params: ControllerParams,
    mode: Mode,
    /// Null-space reference posture, rad.
    pub q_null: Vec<f64>,
    /// Last commanded torque without gravity, N m.
    tau_task: DVector<f64>,
    /// The fading offset of a mode switch in progress.
    blend: Blend,
    /// Joint torque limits, N m.
    effort_limits: Vec<f64>,
    /// Per joint: whether the last cycle's torque was clamped to its limit.
    saturated: Vec<bool>,
}

impl Controller {
    /// A controller of `model` starting in `mode`, with the null-space reference at `q0`.
    pub fn new(
        params: ControllerParams,
        model: &RobotModel,
        mode: Mode,
        q0: &[f64],
    ) -> Result<Self> {
        if !(params.rate_hz > 0.0 && params.rate_hz <= 10_000.0) {
            return Err(Error::Input(format!(
                "control rate {} Hz: expected more than 0 and at most 10000 Hz",
                params.rate_hz
            )));
        }
        if !(params.switch_blend_s >= 0.0 && params.switch_blend_s <= 1.0) {
            return Err(Error::Input(format!(
                "switch blend {} s: expected 0 to 1 s",
                params.switch_blend_s
            )));
        }
        check_mode(&mode)?;
        Ok(Controller {
            params,
            mode,
            q_null: q0.to_vec(),
            tau_task: DVector::zeros(q0.len()),
            blend: Blend::Idle,
            effort_limits: model.joints.iter().map(|j| j.effort_limit).collect(),
            saturated: vec![false; q0.len()],
        })
    }

    pub fn mode(&self) -> &Mode {
        &self.mode
    }

    /// Switches to `mode` (validated); the next cycles blend the old torque into the new.
    pub fn set_mode(&mut self, mode: Mode) -> Result<()> {
        check_mode(&mode)?;
        self.mode = mode;
        let cycles = (self.params.switch_blend_s * self.params.rate_hz).round() as u32;
        self.blend = if cycles > 0 {
            Blend::Pending { cycles }
        } else {
            Blend::Idle
        };
        Ok(())
    }

    /// Moves the Cartesian impedance target (ignored in joint-position mode, which has its own).
    pub fn set_cartesian_target(&mut self, target: Iso) {
        if let Mode::CartesianImpedance { target: t, .. } = &mut self.mode {
            *t = target;
        }
    }

    /// One cycle: the joint torques to apply (N m; gravity included, blended across a mode
    /// switch, clamped to the torque limits), from the model evaluated at the measured joint
    /// positions `q` and the joint velocities `qd` (rad, rad/s).
    pub fn update(&mut self, d: &Dynamics, q: &[f64], qd: &[f64]) -> DVector<f64> {
        let qd_v = DVector::from_row_slice(qd);
        let wanted = match &self.mode {
            Mode::CartesianImpedance { gains, target } => {
                impedance_torque(d, gains, target, &qd_v, q, &self.q_null)
            }
            Mode::JointPosition { gains, target } => {
                joint_position_torque(&d.mass, gains, target, q, &qd_v)
            }
        };
        self.tau_task = self.blend.apply(wanted, &self.tau_task);
        let mut tau = &self.tau_task + &d.gravity;
        for ((t, limit), sat) in tau
            .iter_mut()
            .zip(&self.effort_limits)
            .zip(&mut self.saturated)
        {
            *sat = t.abs() > *limit;
            *t = t.clamp(-limit, *limit);
        }
        tau
    }

    /// Per joint: whether the last cycle asked for more torque than the joint's limit (and was
    /// clamped to it).
    pub fn saturated(&self) -> &[bool] {
        &self.saturated
    }
}

/// Bumpless transfer across a mode switch: the old mode's last task torque minus the new mode's
/// first, faded linearly to zero.
#[derive(Clone)]
enum Blend {
    /// No switch in progress.
    Idle,
    /// A switch happened; its offset is taken at the next cycle, over `cycles` cycles.
    Pending { cycles: u32 },
    /// Fading `offset` (N m): `left` of `cycles` cycles to go.
    Fading {
        offset: DVector<f64>,
        left: u32,
        cycles: u32,
    },
}

impl Blend {
    /// The task torque to command this cycle when the mode wants `wanted` and the last cycle
    /// commanded `last` (both N m, without gravity).
    fn apply(&mut self, wanted: DVector<f64>, last: &DVector<f64>) -> DVector<f64> {
        if let Blend::Pending { cycles } = *self {
            *self = Blend::Fading {
                offset: last - &wanted,
                left: cycles,
                cycles,
            };
        }
        match self {
            Blend::Idle | Blend::Pending { .. } => wanted,
            Blend::Fading {
                offset,
                left,
                cycles,
            } => {
                let share = f64::from(*left) / f64::from(*cycles);
                let tau = wanted + &*offset * share;
                *left -= 1;
                if *left == 0 {
                    *self = Blend::Idle;
                }
                tau
            }
        }
    }
}

fn check_mode(mode: &Mode) -> Result<()> {
    match mode {
        Mode::CartesianImpedance { gains, .. } => gains.ensure_valid(),
        Mode::JointPosition { gains, .. } => {
            if !(gains.stiffness > 0.0 && gains.damping_ratio > 0.0) {
                return Err(Error::Input(format!(
                    "joint position gains {} N m/rad, damping ratio {}: expected positive values",
                    gains.stiffness, gains.damping_ratio
                )));
            }
            Ok(())
        }
    }
}

/// Pose error of the TCP against its target, TCP frame: `[position (m); rotation vector (rad)]`,
/// the rotation that takes the target orientation to the current one.
pub fn tcp_error(tcp: &Iso, target: &Iso) -> Vector6<f64> {
    let r = tcp.rotation.inverse();
    let dp = r * (tcp.translation.vector - target.translation.vector);
    let dr = r * (tcp.rotation * target.rotation.inverse()).scaled_axis();
    Vector6::new(dp.x, dp.y, dp.z, dr.x, dr.y, dr.z)
}

/// `blockdiag(R, R)`: a 6-vector from the TCP frame to the base frame.
fn twist_rotation(tcp: &Iso) -> Matrix6<f64> {
    let r: Matrix3<f64> = *tcp.rotation.to_rotation_matrix().matrix();
    let mut out = Matrix6::zeros();
    out.fixed_view_mut::<3, 3>(0, 0).copy_from(&r);
    out.fixed_view_mut::<3, 3>(3, 3).copy_from(&r);
    out
}

/// Symmetric positive semi-definite square root.
fn sqrt_psd(a: &Matrix6<f64>) -> Matrix6<f64> {
    let eig = SymmetricEigen::new(*a);
    let s = eig.eigenvalues.map(|v| v.max(0.0).sqrt());
    eig.eigenvectors * Matrix6::from_diagonal(&s) * eig.eigenvectors.transpose()
}

/// Damping matrix (TCP frame) by the factorisation design: `L^1/2 Xi K^1/2 + K^1/2 Xi L^1/2`.
pub fn factorisation_damping(lambda_tcp: &Matrix6<f64>, gains: &ImpedanceGains) -> Matrix6<f64> {
    let l_half = sqrt_psd(lambda_tcp);
    let k_half = Matrix6::from_diagonal(&Vector6::from(gains.stiffness).map(f64::sqrt));
    let xi = Matrix6::from_diagonal(&Vector6::from(gains.damping_ratio));
    l_half * xi * k_half + k_half * xi * l_half
}

fn impedance_torque(
    d: &Dynamics,
    gains: &ImpedanceGains,
    target: &Iso,
    qd: &DVector<f64>,
    q: &[f64],
    q_null: &[f64],
) -> DVector<f64> {
    let (tcp, jac, m) = (d.tcp, &d.jacobian, &d.mass);
    let minv = d.mass_inverse();
    let lambda = d.cartesian_inertia(&minv);
    let to_base = twist_rotation(&tcp);
    let lambda_tcp = to_base.transpose() * lambda * to_base;
    let damping = factorisation_damping(&lambda_tcp, gains);
    let v_tcp = to_base.transpose() * Vector6::from_iterator((jac * qd).iter().copied());
    let e = tcp_error(&tcp, target);
    let mut f_tcp =
        -(Matrix6::from_diagonal(&Vector6::from(gains.stiffness)) * e) - damping * v_tcp;
    if let Some(max) = gains.max_control_force {
        for i in 0..6 {
            f_tcp[i] = f_tcp[i].clamp(-max[i], max[i]);
        }
    }
    f_tcp += Vector6::from(gains.additional_force);
    let f_base = to_base * f_tcp;
    let f = DVector::from_column_slice(f_base.as_slice());
    let tau_task = jac.transpose() * &f;
    // Null space: joint-space spring-damper projected with I - J^T Lambda J M^-1. A 6-joint arm
    // has none (the projector is zero up to rounding), so it gets the task torque alone.
    let n = q.len();
    if n <= 6 {
        return tau_task;
    }
    let mut tau0 = DVector::zeros(n);
    for i in 0..n {
        let d = 2.0 * gains.null_damping_ratio * (gains.null_stiffness * m[(i, i)]).sqrt();
        tau0[i] = gains.null_stiffness * (q_null[i] - q[i]) - d * qd[i];
    }
    let lambda_d = DMatrix::from_column_slice(6, 6, lambda.as_slice());
    let jbar_t = &lambda_d * jac * &minv; // J^{T#}, 6 x n
    let projector = DMatrix::identity(n, n) - jac.transpose() * jbar_t;
    tau_task + projector * tau0
}

fn joint_position_torque(
    m: &DMatrix<f64>,
    gains: &JointPositionGains,
    target: &[f64],
    q: &[f64],
    qd: &DVector<f64>,
) -> DVector<f64> {
    DVector::from_fn(q.len(), |i, _| {
        let d = 2.0 * gains.damping_ratio * (gains.stiffness * m[(i, i)]).sqrt();
        gains.stiffness * (target[i] - q[i]) - d * qd[i]
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gains_outside_the_sunrise_ranges_are_rejected_by_name() {
        let mut g = ImpedanceGains::default();
        g.stiffness[2] = 6000.0;
        let e = g.ensure_valid().unwrap_err().to_string();
        assert!(
            e.contains("stiffness z") && e.contains("6000") && e.contains("[0, 5000]"),
            "{e}"
        );
        let mut g = ImpedanceGains::default();
        g.stiffness[4] = 350.0;
        assert!(
            g.ensure_valid()
                .unwrap_err()
                .to_string()
                .contains("[0, 300]")
        );
        let mut g = ImpedanceGains::default();
        g.damping_ratio[0] = 0.05;
        assert!(
            g.ensure_valid()
                .unwrap_err()
                .to_string()
                .contains("damping ratio x")
        );
        let g = ImpedanceGains {
            null_damping_ratio: 0.2,
            ..Default::default()
        };
        assert!(
            g.ensure_valid()
                .unwrap_err()
                .to_string()
                .contains("null-space damping")
        );
        let g = ImpedanceGains {
            max_control_force: Some([10.0, 10.0, 0.0, 1.0, 1.0, 1.0]),
            ..Default::default()
        };
        assert!(
            g.ensure_valid()
                .unwrap_err()
                .to_string()
                .contains("max control force z")
        );
        ImpedanceGains::default().ensure_valid().unwrap();
        ImpedanceGains::uniform(5000.0, 300.0, 1.0)
            .ensure_valid()
            .unwrap();
    }

    #[test]
    fn a_mode_switch_starts_at_the_old_torque_and_fades_to_the_new_one() {
        let mut blend = Blend::Pending { cycles: 4 };
        let last = DVector::from_element(2, 10.0);
        let wanted = DVector::from_element(2, 2.0);
        let taus: Vec<f64> = (0..6)
            .map(|_| blend.apply(wanted.clone(), &last)[0])
            .collect();
        assert_eq!(taus, [10.0, 8.0, 6.0, 4.0, 2.0, 2.0]);
        assert!(matches!(blend, Blend::Idle));
        let mut idle = Blend::Idle;
        assert_eq!(idle.apply(wanted.clone(), &last), wanted);
    }

    #[test]
    fn factorisation_damping_is_critical_for_a_diagonal_inertia() {
        let lambda = Matrix6::from_diagonal(&Vector6::new(4.0, 4.0, 4.0, 0.09, 0.09, 0.09));
        let g = ImpedanceGains::uniform(2500.0, 100.0, 1.0);
        let d = factorisation_damping(&lambda, &g);
        assert!((d[(0, 0)] - 2.0 * (2500.0f64 * 4.0).sqrt()).abs() < 1e-9);
        assert!((d[(3, 3)] - 2.0 * (100.0f64 * 0.09).sqrt()).abs() < 1e-9);
        assert!(d[(0, 1)].abs() < 1e-12);
    }

    #[test]
    fn tcp_error_is_zero_on_target_and_signed_in_the_tcp_frame() {
        let target = Iso::from_parts(
            nalgebra::Translation3::new(0.5, 0.0, 0.3),
            nalgebra::UnitQuaternion::from_euler_angles(std::f64::consts::PI, 0.0, 0.0),
        );
        assert!(tcp_error(&target, &target).norm() < 1e-12);
        let moved = Iso::from_parts(
            nalgebra::Translation3::new(0.501, 0.0, 0.3),
            target.rotation,
        );
        let e = tcp_error(&moved, &target);
        // TCP x is base x under a roll of pi.
        assert!((e[0] - 0.001).abs() < 1e-12 && e[1].abs() < 1e-12, "{e}");
        let up = Iso::from_parts(
            nalgebra::Translation3::new(0.5, 0.0, 0.301),
            target.rotation,
        );
        assert!(
            (tcp_error(&up, &target)[2] + 0.001).abs() < 1e-12,
            "TCP z points down"
        );
    }
}
