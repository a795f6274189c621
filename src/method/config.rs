//! What a trial does: the method, how it starts, and the settings of every stage (paper IV-C
//! observation, IV-D registration, IV-E insertion, V-A the experiment's offsets), with the values
//! the paper's experiment runs at as defaults.

use crate::choice::{Choice, Named};
use crate::error::{Error, Result};
use crate::method::register::RegistrationConfig;
use crate::twin::control::{ImpedanceGains, is_positive};
use serde::{Deserialize, Serialize};

/// How the trial inserts.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Method {
    /// Estimate the hole pose from the contact manifold, then insert along the estimate.
    Manifold,
    /// The paper's baseline: observe, then insert along the peg's z with no estimate.
    Direct,
    /// The manifold method whose observation stops itself: it registers as observations come in
    /// and stops once the estimate's insertion-critical uncertainties are small enough
    /// ([`AdaptiveConfig`], `method::adaptive`), or at `t_obs_s`.
    Adaptive,
    /// The adaptive method probing actively: after each registration, the motion widens the
    /// amplitudes of the axes whose uncertainty stands furthest above its limit.
    Active,
}

impl Method {
    /// Whether the method registers its observations against a reference manifold.
    pub fn registers(self) -> bool {
        matches!(self, Method::Manifold | Method::Adaptive | Method::Active)
    }

    /// Whether the method decides while observing when to stop (adaptive, active).
    pub fn stops_itself(self) -> bool {
        matches!(self, Method::Adaptive | Method::Active)
    }
}

/// How a trial starts.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Start {
    /// Partially inserted in the true hole (the paper's set-up).
    Partial,
    /// Above the nominal hole: approach, then a spiral search pressing on the surface until the
    /// peg drops in, then down to the partial insertion.
    Above,
}

impl Choice for Method {
    const WHAT: &'static str = "method";
    const NAMED: &'static [Named<Self>] = &[
        Named {
            name: "manifold",
            value: Method::Manifold,
            help: "estimate the hole pose from the contact manifold, then insert along the estimate",
        },
        Named {
            name: "direct",
            value: Method::Direct,
            help: "the paper's baseline: observe, then insert along the peg's z with no estimate",
        },
        Named {
            name: "adaptive",
            value: Method::Adaptive,
            help: "the manifold method, observing until the estimate is certain enough to insert \
                   (at most t_obs)",
        },
        Named {
            name: "active",
            value: Method::Active,
            help: "the adaptive method, widening the motion on the axes it knows least after each \
                   registration",
        },
    ];
}

impl Choice for Start {
    const WHAT: &'static str = "start";
    const NAMED: &'static [Named<Self>] = &[
        Named {
            name: "partial",
            value: Start::Partial,
            help: "partially inserted in the true hole (the paper's set-up)",
        },
        Named {
            name: "above",
            value: Start::Above,
            help: "above the nominal hole: approach, then a spiral search until the peg drops in",
        },
    ];
}

/// Shortest and longest observation a trial accepts, s (the paper: 6-10 s; 0.1 s is a hundred
/// control cycles).
pub const MIN_T_OBS_S: f64 = 0.1;
pub const MAX_T_OBS_S: f64 = 600.0;
/// Largest success threshold on the final depth, m (the paper: 2 mm).
pub const MAX_SUCCESS_EPS_M: f64 = 0.03;
/// Largest half-range of the hole's offset a trial accepts: 50 mm and 45 deg (beyond, the peg
/// does not start in the hole's reach).
pub const MAX_OFFSET: (f64, f64) = (0.05, std::f64::consts::FRAC_PI_4);

/// Everything a trial does.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TrialConfig {
    pub method: Method,
    pub start: Start,
    /// The spiral search from above (`start = above`).
    pub search: SearchConfig,
    /// Observation time, s.
    pub t_obs_s: f64,
    /// Half-ranges of the uniform hole offset: x, y, z (m), roll, pitch, yaw (rad).
    pub offset_range: [f64; 6],
    /// Depth of the initial partial insertion, m.
    pub start_depth_m: f64,
    /// Observation: phase 1 amplitude scale until `observe_depth_m`, then phase 2 scale.
    pub phase1_scale: f64,
    pub phase2_scale: f64,
    pub observe_depth_m: f64,
    /// Time spent descending from `start_depth_m` to `observe_depth_m` (phase 1), s: the same
    /// for every `t_obs` (an observation shorter than this ends in phase 1). The default, 3.6 s,
    /// leaves the paper's shortest budget (6 s) two fifths in phase 2.
    pub phase1_s: f64,
    /// Gains of the observation motions: compliant, and softest in rotation, so that the
    /// orientation error of the nominal pose presses the peg only lightly against the walls.
    pub observe_gains: ImpedanceGains,
    /// Observations kept after temporal downsampling.
    pub observations: usize,
    /// Small retract before alignment, m.
    pub retract_m: f64,
    /// High-stiffness gains of the in-plane alignment.
    pub align_gains: ImpedanceGains,
    /// Duration of the alignment move, s.
    pub align_s: f64,
    /// Compliant gains of the insertion.
    pub insert_gains: ImpedanceGains,
    /// Insertion speed of the target, m/s.
    pub insert_speed_m_per_s: f64,
    /// Time limit of the insertion, s.
    pub insert_limit_s: f64,
    /// The insertion target goes this far past the believed floor, m (the compliance turns it into
    /// the seating force; it also absorbs the estimate's error in z).
    pub insert_overshoot_m: f64,
    /// The insertion target stops advancing once the estimated |Fz| exceeds this, N (a force
    /// break condition, as Sunrise's `ForceCondition`): the peg has jammed.
    pub insert_stop_force_n: f64,
    /// Once the tip is within `insert_seat_window_m` of the believed floor, the insertion target
    /// stops when the estimated |Fz| exceeds this, N (a seat condition: the peg rests on the
    /// floor with about this force). At or above `insert_stop_force_n` it never acts.
    pub insert_seat_force_n: f64,
    /// How far above the believed floor the seat condition arms, m: the belief's z uncertainty.
    /// The registration does not observe z (its z error follows the hole's z offset, about
    /// 1.3 mm deeper: docs/method.md, "Why the seat condition looks for a stall"), so the default spans the paper's
    /// 5 mm offset range and that bias with margin.
    pub insert_seat_window_m: f64,
    /// Success when the final tip depth is within this of the floor, m (paper: 2 mm).
    pub success_eps_m: f64,
    pub registration: RegistrationConfig,
    /// When the adaptive method registers and when it stops (`t_obs_s` is its longest
    /// observation).
    #[serde(default)]
    pub adaptive: AdaptiveConfig,
}

/// The adaptive method's observation (issue "know when you know"; docs/method.md, "Observation
/// that stops itself"): it registers the observations so far every `check_every_s` from
/// `check_from_s` on, each registration starting from the previous estimate, and stops when every
/// standard deviation of the estimate is within its limit, or when one would not be by `t_obs_s`.
/// The limits default to what the insertion tolerates (`method::adaptive::StopRule`); each can be
/// set here instead.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct AdaptiveConfig {
    /// The first registration, s after the observation starts.
    pub check_from_s: f64,
    /// Time between registrations, s.
    pub check_every_s: f64,
    /// Largest standard deviation of x and y to stop at, m (default: from the clearance and the
    /// chamfers).
    pub max_std_xy_m: Option<f64>,
    /// Largest standard deviation of roll and pitch to stop at, rad (default: from the paper's
    /// critical orientation error).
    pub max_std_tilt_rad: Option<f64>,
    /// Largest standard deviation of yaw to stop at, rad (default: from the clearance, the
    /// chamfers and the peg's size).
    pub max_std_yaw_rad: Option<f64>,
    /// Whether it also stops when the trend of its standard deviations says a limit would still
    /// not be met at `t_obs_s` (`StopRule::out_of_reach`): observing on would not make it
    /// certain enough.
    pub stop_out_of_reach: bool,
}

impl Default for AdaptiveConfig {
    fn default() -> Self {
        AdaptiveConfig {
            check_from_s: 4.0,
            check_every_s: 0.5,
            max_std_xy_m: None,
            max_std_tilt_rad: None,
            max_std_yaw_rad: None,
            stop_out_of_reach: true,
        }
    }
}

impl AdaptiveConfig {
    /// Rejects values the adaptive observation cannot run with, naming the field.
    pub fn ensure_valid(&self, t_obs_max_s: f64) -> Result<()> {
        if !(is_positive(self.check_from_s) && self.check_from_s <= t_obs_max_s) {
            return Err(Error::Input(format!(
                "adaptive check_from_s {} s: expected more than 0 and at most the longest \
                 observation, {t_obs_max_s} s",
                self.check_from_s
            )));
        }
        if !(is_positive(self.check_every_s) && self.check_every_s <= MAX_T_OBS_S) {
            return Err(Error::Input(format!(
                "adaptive check_every_s {} s: expected more than 0 and at most {MAX_T_OBS_S} s",
                self.check_every_s
            )));
        }
        for (field, v) in [
            ("max_std_xy_m", self.max_std_xy_m),
            ("max_std_tilt_rad", self.max_std_tilt_rad),
            ("max_std_yaw_rad", self.max_std_yaw_rad),
        ] {
            if let Some(v) = v
                && !is_positive(v)
            {
                return Err(Error::Input(format!(
                    "adaptive {field} {v}: expected a positive limit"
                )));
            }
        }
        Ok(())
    }
}

impl Default for TrialConfig {
    fn default() -> Self {
        let d = 5e-3;
        let a = 5f64.to_radians();
        TrialConfig {
            method: Method::Manifold,
            start: Start::Partial,
            search: SearchConfig::default(),
            t_obs_s: 10.0,
            offset_range: [d, d, d, a, a, a],
            start_depth_m: 3e-3,
            phase1_scale: 1.0,
            phase2_scale: 0.8,
            observe_depth_m: 18e-3,
            phase1_s: 3.6,
            observe_gains: ImpedanceGains {
                stiffness: [2424.0, 2424.0, 3636.0, 14.3, 14.3, 14.3],
                damping_ratio: [0.73; 6],
                additional_force: [0.0, 0.0, -5.0, 0.0, 0.0, 0.0],
                ..Default::default()
            },
            observations: 1000,
            retract_m: 1e-3,
            align_gains: ImpedanceGains::uniform(4000.0, 250.0, 0.7),
            align_s: 1.0,
            insert_gains: ImpedanceGains {
                stiffness: [3955.0, 3955.0, 3631.0, 5.6, 5.6, 5.6],
                damping_ratio: [0.82; 6],
                ..Default::default()
            },
            insert_speed_m_per_s: 15e-3,
            insert_limit_s: 6.0,
            insert_overshoot_m: 11.8e-3,
            insert_stop_force_n: 80.0,
            insert_seat_force_n: 20.9,
            insert_seat_window_m: 3.8e-3,
            success_eps_m: 2e-3,
            registration: RegistrationConfig::default(),
            adaptive: AdaptiveConfig::default(),
        }
    }
}

impl TrialConfig {
    /// The defaults of a trial of `method`: the direct baseline inserts with its own gains and
    /// seat force, tuned for success as the paper tuned its baseline (V-B:
    /// `pegtwin tune scenarios/tune-direct.toml --target direct`, on the real cell with the
    /// default observation gains; docs/scenarios.md, "Tuning"), and the overshoot, jam break and
    /// seat window it was tuned under (5 mm, 40 N, 8 mm).
    pub fn for_method(method: Method) -> Self {
        let base = TrialConfig {
            method,
            ..TrialConfig::default()
        };
        match method {
            Method::Manifold | Method::Adaptive | Method::Active => base,
            Method::Direct => TrialConfig {
                insert_gains: ImpedanceGains {
                    stiffness: [3955.0, 3955.0, 3631.0, 11.0, 11.0, 11.0],
                    damping_ratio: [0.82; 6],
                    ..Default::default()
                },
                insert_seat_force_n: 20.9,
                insert_overshoot_m: 5e-3,
                insert_stop_force_n: 40.0,
                insert_seat_window_m: 8e-3,
                ..base
            },
        }
    }

    /// Whether a trial under `other` runs the same simulation as one under `self` (same seed, pair
    /// and cell) until its observation ends: the two differ at most in what the later stages read
    /// (the method, the observations kept, registration, retract, alignment, insertion, the
    /// success threshold). A field added to `TrialConfig` counts as part of the observation
    /// until it is listed here. Such trials share one observation in a campaign
    /// (`campaign::sharing`, `method::trial::ObservingTrial`).
    pub fn observes_like(&self, other: &TrialConfig) -> bool {
        let later = TrialConfig {
            method: self.method,
            observations: self.observations,
            retract_m: self.retract_m,
            align_gains: self.align_gains.clone(),
            align_s: self.align_s,
            insert_gains: self.insert_gains.clone(),
            insert_speed_m_per_s: self.insert_speed_m_per_s,
            insert_limit_s: self.insert_limit_s,
            insert_overshoot_m: self.insert_overshoot_m,
            insert_stop_force_n: self.insert_stop_force_n,
            insert_seat_force_n: self.insert_seat_force_n,
            insert_seat_window_m: self.insert_seat_window_m,
            success_eps_m: self.success_eps_m,
            registration: self.registration.clone(),
            adaptive: self.adaptive.clone(),
            ..other.clone()
        };
        later == *self
    }

    /// Whether trials under `self` and `other` run the same simulation (same seed, pair and
    /// cell) until the shorter of their two observations ends: they observe alike but for
    /// `t_obs`, which only says when the observation's motion stops
    /// ([`crate::method::observe::observation_motion`]). A campaign runs the longer
    /// observation once and the shorter trial goes on from its budget
    /// (`method::trial::ObservingTrial`).
    pub fn observes_like_but_for_budget(&self, other: &TrialConfig) -> bool {
        let same_budget = TrialConfig {
            t_obs_s: other.t_obs_s,
            ..self.clone()
        };
        same_budget.observes_like(other)
    }

    /// Rejects values a trial cannot run with, naming the field.
    pub fn ensure_valid(&self) -> Result<()> {
        if !(self.t_obs_s >= MIN_T_OBS_S && self.t_obs_s <= MAX_T_OBS_S) {
            return Err(Error::Input(format!(
                "t_obs {} s: expected {MIN_T_OBS_S} to {MAX_T_OBS_S} s",
                self.t_obs_s
            )));
        }
        if !(self.success_eps_m > 0.0 && self.success_eps_m <= MAX_SUCCESS_EPS_M) {
            return Err(Error::Input(format!(
                "success threshold {} mm: expected more than 0 and at most {} mm",
                self.success_eps_m * 1e3,
                MAX_SUCCESS_EPS_M * 1e3
            )));
        }
        let (max_m, max_rad) = MAX_OFFSET;
        for (i, v) in self.offset_range.iter().enumerate() {
            let (limit, shown, unit) = if i < 3 {
                (max_m, v * 1e3, "mm")
            } else {
                (max_rad, v.to_degrees(), "deg")
            };
            if !(*v >= 0.0 && *v <= limit) {
                let most = if i < 3 {
                    limit * 1e3
                } else {
                    limit.to_degrees()
                };
                return Err(Error::Input(format!(
                    "offset half-range {shown} {unit}: expected 0 to {most:.0} {unit}"
                )));
            }
        }
        self.ensure_valid_insertion()?;
        if !(self.phase1_s > 0.0 && self.phase1_s <= MAX_T_OBS_S) {
            return Err(Error::Input(format!(
                "phase1_s {} s: expected more than 0 and at most {MAX_T_OBS_S} s",
                self.phase1_s
            )));
        }
        self.search.ensure_valid()?;
        self.observe_gains.ensure_valid()?;
        self.align_gains.ensure_valid()?;
        self.insert_gains.ensure_valid()?;
        if self.method.stops_itself() {
            self.adaptive.ensure_valid(self.t_obs_s)?;
        }
        self.registration.ensure_valid()
    }

    /// Rejects insertion settings a trial cannot run with, naming the field.
    fn ensure_valid_insertion(&self) -> Result<()> {
        if !(self.insert_overshoot_m >= 0.0 && self.insert_overshoot_m <= 0.05) {
            return Err(Error::Input(format!(
                "insert_overshoot_m {} m: expected 0 to 0.05 m",
                self.insert_overshoot_m
            )));
        }
        if !is_positive(self.insert_stop_force_n) {
            return Err(Error::Input(format!(
                "insert_stop_force_n {} N: expected a positive force",
                self.insert_stop_force_n
            )));
        }
        if !(is_positive(self.insert_speed_m_per_s) && self.insert_speed_m_per_s <= 0.1) {
            return Err(Error::Input(format!(
                "insert_speed_m_per_s {} m/s: expected more than 0 and at most 0.1 m/s",
                self.insert_speed_m_per_s
            )));
        }
        if !(is_positive(self.insert_limit_s) && self.insert_limit_s <= MAX_T_OBS_S) {
            return Err(Error::Input(format!(
                "insert_limit_s {} s: expected more than 0 and at most {MAX_T_OBS_S} s",
                self.insert_limit_s
            )));
        }
        if !is_positive(self.insert_seat_force_n) {
            return Err(Error::Input(format!(
                "insert_seat_force_n {} N: expected a positive force",
                self.insert_seat_force_n
            )));
        }
        if !(self.insert_seat_window_m >= 0.0 && self.insert_seat_window_m <= 0.05) {
            return Err(Error::Input(format!(
                "insert_seat_window_m {} m: expected 0 to 0.05 m",
                self.insert_seat_window_m
            )));
        }
        Ok(())
    }
}

/// The spiral search from above (the classic peg-in-hole search, before the paper's partial
/// insertion): approach, press on the fixture's top, spiral until the peg drops in.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SearchConfig {
    /// Time limit of the whole search, s.
    pub limit_s: f64,
    /// Start height of the tip above the highest mouth the offsets allow, m.
    pub start_clearance_m: f64,
    /// Approach speed along the nominal hole axis until contact, m/s.
    pub approach_speed_m_per_s: f64,
    /// Target depth below the height of first contact while spiralling (the press), m.
    pub press_depth_m: f64,
    /// The hole is found when the tip is this far below the height of first contact, m.
    pub drop_m: f64,
    /// Radial growth of the spiral per turn, m.
    pub spiral_pitch_m: f64,
    /// Speed along the spiral, m/s.
    pub spiral_speed_m_per_s: f64,
    /// Spiral radius beyond the position uncertainty and the clearance, m.
    pub spiral_margin_m: f64,
    /// Duration of the move down to the partial insertion once the peg dropped, s.
    pub descend_s: f64,
}

impl Default for SearchConfig {
    fn default() -> Self {
        SearchConfig {
            limit_s: 30.0,
            start_clearance_m: 5e-3,
            approach_speed_m_per_s: 10e-3,
            press_depth_m: 3e-3,
            drop_m: 1e-3,
            spiral_pitch_m: 0.5e-3,
            spiral_speed_m_per_s: 10e-3,
            spiral_margin_m: 1e-3,
            descend_s: 0.5,
        }
    }
}

impl SearchConfig {
    /// Rejects values a search cannot run with, naming the field.
    pub fn ensure_valid(&self) -> Result<()> {
        for (field, v) in [
            ("limit_s", self.limit_s),
            ("approach_speed_m_per_s", self.approach_speed_m_per_s),
            ("drop_m", self.drop_m),
            ("spiral_pitch_m", self.spiral_pitch_m),
            ("spiral_speed_m_per_s", self.spiral_speed_m_per_s),
            ("descend_s", self.descend_s),
        ] {
            if !is_positive(v) {
                return Err(Error::Input(format!(
                    "search {field} {v}: expected a positive value"
                )));
            }
        }
        for (field, v) in [
            ("start_clearance_m", self.start_clearance_m),
            ("press_depth_m", self.press_depth_m),
            ("spiral_margin_m", self.spiral_margin_m),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(Error::Input(format!(
                    "search {field} {v}: expected a finite value >= 0"
                )));
            }
        }
        Ok(())
    }
}
