//! The scenario's overrides of the trial's defaults: per-phase gains (`[gains.*]`), the insertion
//! (`[insertion]`), the direct baseline's own (`[direct]`), the physics (`[physics]`) and each
//! pair's (`[[pair_physics]]`).

use super::Condition;
use crate::error::{Error, Result};
use crate::method::config::TrialConfig;
use crate::twin::control::ImpedanceGains;
use crate::twin::workcell::WorkCellParams;
use serde::{Deserialize, Serialize};

/// Gain overrides of the three online phases.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PhaseGains {
    #[serde(default)]
    pub observe: GainsOverride,
    #[serde(default)]
    pub align: GainsOverride,
    #[serde(default)]
    pub insert: GainsOverride,
}

/// Fields of `ImpedanceGains` to replace; the rest keep the phase's default.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GainsOverride {
    /// N/m on x, y, z; N m/rad on roll, pitch, yaw (TCP frame).
    pub stiffness: Option<[f64; 6]>,
    pub damping_ratio: Option<[f64; 6]>,
    /// N m/rad.
    pub null_stiffness: Option<f64>,
    pub null_damping_ratio: Option<f64>,
    /// N and N m per axis.
    pub max_control_force: Option<[f64; 6]>,
    /// Feed-forward wrench at the TCP, N and N m.
    pub additional_force: Option<[f64; 6]>,
}

impl GainsOverride {
    /// `base` with these fields replaced.
    pub fn apply(&self, base: &ImpedanceGains) -> ImpedanceGains {
        let mut g = base.clone();
        if let Some(v) = self.stiffness {
            g.stiffness = v;
        }
        if let Some(v) = self.damping_ratio {
            g.damping_ratio = v;
        }
        if let Some(v) = self.null_stiffness {
            g.null_stiffness = v;
        }
        if let Some(v) = self.null_damping_ratio {
            g.null_damping_ratio = v;
        }
        if let Some(v) = self.max_control_force {
            g.max_control_force = Some(v);
        }
        if let Some(v) = self.additional_force {
            g.additional_force = v;
        }
        g
    }
}

/// Settings of the insertion (paper IV-E) to replace; units in the names.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InsertionOverride {
    /// Speed of the insertion target, mm/s.
    pub speed_mm_per_s: Option<f64>,
    /// How far past the believed floor the target goes, mm.
    pub overshoot_mm: Option<f64>,
    /// The jam break condition: |Fz| above this anywhere stops the target, N.
    pub jam_force_n: Option<f64>,
    /// The seat break condition: near the floor, a stalled tip pressing harder than this, N.
    pub seat_force_n: Option<f64>,
    /// How far above the believed floor the seat condition arms, mm.
    pub seat_window_mm: Option<f64>,
    /// Time limit of the insertion, s.
    pub limit_s: Option<f64>,
}

impl InsertionOverride {
    pub(super) fn is_default(&self) -> bool {
        *self == Self::default()
    }

    /// `config` with these fields replaced.
    pub(super) fn apply(&self, config: &mut TrialConfig) {
        let mm = |v: Option<f64>| v.map(|v| v * 1e-3);
        let c = config;
        c.insert_speed_m_per_s = mm(self.speed_mm_per_s).unwrap_or(c.insert_speed_m_per_s);
        c.insert_overshoot_m = mm(self.overshoot_mm).unwrap_or(c.insert_overshoot_m);
        c.insert_stop_force_n = self.jam_force_n.unwrap_or(c.insert_stop_force_n);
        c.insert_seat_force_n = self.seat_force_n.unwrap_or(c.insert_seat_force_n);
        c.insert_seat_window_m = mm(self.seat_window_mm).unwrap_or(c.insert_seat_window_m);
        c.insert_limit_s = self.limit_s.unwrap_or(c.insert_limit_s);
    }

    /// Range checks, naming the field under `section`.
    pub(super) fn ensure_valid(&self, section: &str) -> Result<()> {
        // (field, value, lowest, highest, whether the lowest itself is refused)
        let checks = [
            ("speed_mm_per_s", self.speed_mm_per_s, 0.0, 100.0, true),
            ("overshoot_mm", self.overshoot_mm, 0.0, 50.0, false),
            ("jam_force_n", self.jam_force_n, 0.0, 500.0, true),
            ("seat_force_n", self.seat_force_n, 0.0, 500.0, true),
            ("seat_window_mm", self.seat_window_mm, 0.0, 50.0, false),
            ("limit_s", self.limit_s, 0.0, 600.0, true),
        ];
        for (field, v, lo, hi, lo_open) in checks {
            let Some(v) = v else { continue };
            let above = if lo_open { v > lo } else { v >= lo };
            if !(above && v <= hi) {
                let bracket = if lo_open { "(" } else { "[" };
                return Err(Error::Input(format!(
                    "{section}.{field} = {v:?}: expected a value in {bracket}{lo}, {hi}]"
                )));
            }
        }
        Ok(())
    }
}

/// The direct baseline's own settings, applied to its cells over the scenario's.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DirectOverride {
    #[serde(default)]
    pub gains: PhaseGains,
    #[serde(default)]
    pub insertion: InsertionOverride,
}

impl DirectOverride {
    pub(super) fn is_default(&self) -> bool {
        *self == Self::default()
    }
}

/// Physics parameters to replace.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PhysicsOverride {
    /// Physics step, s.
    pub dt_s: Option<f64>,
    /// Solver iterations (substeps) per step.
    pub solver_iterations: Option<usize>,
    /// Gauss-Seidel passes over the constraints per substep.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pgs_iterations: Option<usize>,
    /// Contact constraint natural frequency, Hz.
    pub contact_frequency_hz: Option<f64>,
    /// Coulomb friction between peg and hole (kinetic).
    pub friction: Option<f64>,
    /// The static coefficient of a contact at rest.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub static_friction: Option<f64>,
    /// Position projection of the arm's peg after every step.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub position_projection: Option<bool>,
    /// Who solves the arm's peg contacts: `"joint_space"` (default) or `"rapier"`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub arm_contacts: Option<crate::twin::physics::ArmContacts>,
    /// The arm's joint friction: `{ coulomb_nm = [..], static_nm = [..], stribeck_rad_per_s }`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub joint_friction: Option<crate::twin::physics::JointFriction>,
}

/// `[[pair_physics]]`: physics parameters for one geometry (or assembly), at one clearance or
/// at all of them, applied over the scenario's `[physics]`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PairPhysics {
    /// A built-in geometry of `geometries` or an assembly's name.
    pub geometry: String,
    /// One of `clearances_mm`; every clearance when absent.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub clearance_mm: Option<f64>,
    /// The parameters to replace, e.g. `{ pgs_iterations = 8 }`.
    pub physics: PhysicsOverride,
}

impl PairPhysics {
    pub(super) fn matches(&self, cell: &Condition) -> bool {
        self.geometry == cell.geometry && self.clearance_mm.is_none_or(|c| c == cell.clearance_mm)
    }
}

impl PhysicsOverride {
    /// `params` with the fields given here replaced.
    pub(super) fn apply(&self, params: &mut WorkCellParams) {
        let ph = &mut params.physics;
        ph.dt_s = self.dt_s.unwrap_or(ph.dt_s);
        ph.solver_iterations = self.solver_iterations.unwrap_or(ph.solver_iterations);
        ph.pgs_iterations = self.pgs_iterations.unwrap_or(ph.pgs_iterations);
        ph.contact_frequency_hz = self.contact_frequency_hz.unwrap_or(ph.contact_frequency_hz);
        ph.friction = self.friction.unwrap_or(ph.friction);
        ph.static_friction = self.static_friction.or(ph.static_friction);
        ph.position_projection = self.position_projection.unwrap_or(ph.position_projection);
        ph.arm_contacts = self.arm_contacts.unwrap_or(ph.arm_contacts);
        if let Some(f) = &self.joint_friction {
            ph.joint_friction = f.clone();
        }
    }
}

/// The adaptive method's observation (`methods = ["adaptive"]`, `[adaptive]`); units in the
/// names. Left out, a limit follows from the pair (`method::adaptive::StopRule`).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AdaptiveOverride {
    /// The longest it observes, s (default [`DEFAULT_T_OBS_MAX_S`]).
    pub t_obs_max_s: Option<f64>,
    /// Its first registration, s after the observation starts.
    pub check_from_s: Option<f64>,
    /// Time between its registrations, s.
    pub check_every_s: Option<f64>,
    /// It stops once the estimate's standard deviation in x and y is at most this, mm...
    pub max_std_xy_mm: Option<f64>,
    /// ... in roll and pitch at most this, deg ...
    pub max_std_tilt_deg: Option<f64>,
    /// ... and in yaw at most this, deg.
    pub max_std_yaw_deg: Option<f64>,
    /// Whether it also stops when a limit is out of reach by `t_obs_max_s` (default true).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stop_out_of_reach: Option<bool>,
}

/// The adaptive method's longest observation unless set, s: the paper's longest t_obs.
pub const DEFAULT_T_OBS_MAX_S: f64 = 10.0;

impl AdaptiveOverride {
    pub(super) fn is_default(&self) -> bool {
        *self == Self::default()
    }

    /// The longest the adaptive method observes, s.
    pub fn t_obs_max_s(&self) -> f64 {
        self.t_obs_max_s.unwrap_or(DEFAULT_T_OBS_MAX_S)
    }

    /// `config` with these fields replaced.
    pub(super) fn apply(&self, config: &mut TrialConfig) {
        let a = &mut config.adaptive;
        a.check_from_s = self.check_from_s.unwrap_or(a.check_from_s);
        a.check_every_s = self.check_every_s.unwrap_or(a.check_every_s);
        a.max_std_xy_m = self.max_std_xy_mm.map(|v| v * 1e-3).or(a.max_std_xy_m);
        a.max_std_tilt_rad = (self.max_std_tilt_deg.map(f64::to_radians)).or(a.max_std_tilt_rad);
        a.max_std_yaw_rad = (self.max_std_yaw_deg.map(f64::to_radians)).or(a.max_std_yaw_rad);
        a.stop_out_of_reach = self.stop_out_of_reach.unwrap_or(a.stop_out_of_reach);
    }

    /// Refuses a value out of range, naming the field.
    pub(super) fn ensure_valid(&self) -> Result<()> {
        let max = crate::method::config::MAX_T_OBS_S;
        let min = crate::method::config::MIN_T_OBS_S;
        let t_max = self.t_obs_max_s();
        let checks = [
            ("t_obs_max_s", self.t_obs_max_s, min, max),
            ("check_from_s", self.check_from_s, 0.0, t_max),
            ("check_every_s", self.check_every_s, 0.0, max),
            ("max_std_xy_mm", self.max_std_xy_mm, 0.0, 1000.0),
            ("max_std_tilt_deg", self.max_std_tilt_deg, 0.0, 180.0),
            ("max_std_yaw_deg", self.max_std_yaw_deg, 0.0, 180.0),
        ];
        for (field, v, lo, hi) in checks {
            let Some(v) = v else { continue };
            if !(v > 0.0 && v >= lo && v <= hi) {
                return Err(Error::Input(format!(
                    "adaptive.{field} = {v:?}: expected a value in ({}, {hi}]",
                    lo.max(0.0)
                )));
            }
        }
        Ok(())
    }
}
