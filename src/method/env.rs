//! The cell as a reinforcement-learning environment, in Gymnasium's terms (`reset`, `step`;
//! wrapped in Python as `pegtwin.gym.PegInHoleEnv`). A reset sets a trial's experiment up (paper
//! V-A): the hole's offset from nominal drawn from the seed exactly as a trial with that seed
//! draws it, the peg partially inserted in the true hole, or above the nominal mouth. A step
//! moves the Cartesian impedance target by a bounded increment (and optionally sets the
//! stiffness), then runs the physics underneath for one control period at its own 1 ms step.
//!
//! The policy sees what the method sees (IV-C): the measured TCP pose in the nominal hole frame
//! and the wrench estimated from the joint torque sensors, noise and all. The truth (the true
//! contact wrench, the exact penetration, the depth, a `sim_fault`) is reported beside it for the
//! user and for the reward, never as an observation.

use crate::error::{Error, Result};
use crate::method::config::{Start, TrialConfig};
use crate::method::seeds::TrialSeeds;
use crate::method::trial::Setup;
use crate::pose::{Iso, Pose6};
use crate::twin::control::{
    ImpedanceGains, ROTATIONAL_STIFFNESS_RANGE, TRANSLATIONAL_STIFFNESS_RANGE,
};
use crate::twin::geometry::PartPair;
use crate::twin::physics::penetration::PenetrationProbe;
use crate::twin::robot::RobotModel;
use crate::twin::workcell::{SimFault, WorkCell, WorkCellParams};
use nalgebra::{Translation3, UnitQuaternion};

/// Length of an observation: TCP pose `[x, y, z, roll, pitch, yaw]` in the nominal hole frame
/// (m, rad), then the estimated wrench `[fx, fy, fz, tx, ty, tz]` (base frame, N and N m).
pub const OBSERVATION_LEN: usize = 12;

/// How the environment runs and rewards.
#[derive(Clone, Debug)]
pub struct EnvConfig {
    /// Rate of `step` calls, Hz (the physics runs at its own 1 kHz underneath; 1-100 Hz, and a
    /// whole number of control cycles per step).
    pub control_hz: f64,
    /// Simulated time after which an episode is truncated, s.
    pub episode_s: f64,
    pub start: Start,
    /// Half-ranges of the hole's offset from nominal, `[x, y, z, roll, pitch, yaw]`, m and rad.
    pub offset_range: [f64; 6],
    /// The largest target move per step for an action component of 1: m along the hole
    /// frame's axes, rad about the TCP's axes.
    pub max_step_m: f64,
    pub max_step_rad: f64,
    /// Impedance gains at reset (the method's insertion gains by default).
    pub gains: ImpedanceGains,
    /// Two more action components set the translational and rotational stiffness (all axes)
    /// within Sunrise's ranges (`twin::control`), -1 the lowest and 1 the highest.
    pub variable_stiffness: bool,
    /// Reward per mm of depth gained in the true hole.
    pub reward_per_mm: f64,
    /// Penalty per N of estimated force beyond `force_free_n`, per step.
    pub force_penalty_per_n: f64,
    pub force_free_n: f64,
    /// Reward on success (the tip within the trial's 2 mm of the floor, paper V-A).
    pub success_reward: f64,
}

impl Default for EnvConfig {
    /// 20 Hz, 10 s episodes from a partial insertion, the paper's offsets (5 mm, 5 deg), at most
    /// 1 mm and 0.5 deg per step, the insertion's gains; +1 per mm, -0.01 per N beyond 10 N, +10
    /// on success.
    fn default() -> Self {
        let trial = TrialConfig::default();
        EnvConfig {
            control_hz: 20.0,
            episode_s: 10.0,
            start: Start::Partial,
            offset_range: trial.offset_range,
            max_step_m: 1e-3,
            max_step_rad: 0.5f64.to_radians(),
            gains: trial.insert_gains,
            variable_stiffness: false,
            reward_per_mm: 1.0,
            force_penalty_per_n: 0.01,
            force_free_n: 10.0,
            success_reward: 10.0,
        }
    }
}

impl EnvConfig {
    /// Length of an action: 6, or 8 with variable stiffness.
    pub fn action_len(&self) -> usize {
        if self.variable_stiffness { 8 } else { 6 }
    }

    /// Checks every value, naming the one at fault.
    pub fn ensure_valid(&self, params: &WorkCellParams) -> Result<()> {
        let checks = [
            ("control_hz", self.control_hz, 1.0, 100.0),
            ("episode_s", self.episode_s, 0.01, 600.0),
            ("max_step_m", self.max_step_m, 0.0, 0.01),
            ("max_step_rad", self.max_step_rad, 0.0, 0.1),
            ("reward_per_mm", self.reward_per_mm, -1e6, 1e6),
            ("force_penalty_per_n", self.force_penalty_per_n, 0.0, 1e6),
            ("force_free_n", self.force_free_n, 0.0, 1e4),
            ("success_reward", self.success_reward, -1e6, 1e6),
        ];
        for (field, v, lo, hi) in checks {
            if !(v >= lo && v <= hi) {
                return Err(Error::Input(format!("{field} {v}: expected {lo} to {hi}")));
            }
        }
        let cycles = params.controller.rate_hz / self.control_hz;
        if (cycles - cycles.round()).abs() > 1e-9 {
            return Err(Error::Input(format!(
                "control_hz {}: expected a whole number of {} Hz control cycles per step",
                self.control_hz, params.controller.rate_hz
            )));
        }
        TrialConfig {
            offset_range: self.offset_range,
            ..TrialConfig::default()
        }
        .ensure_valid()?;
        self.gains.ensure_valid()
    }
}

/// What a step reports beside the observation.
#[derive(Clone, Debug)]
pub struct StepInfo {
    /// Simulated time since reset, s.
    pub time_s: f64,
    /// Tip depth below the true mouth, m.
    pub depth_m: f64,
    /// True contact wrench from the physics (base frame, N and N m).
    pub true_wrench: [f64; 6],
    /// Largest exact penetration of the peg into the hole now, m.
    pub penetration_m: f64,
    /// The estimator's contact flag.
    pub contact: bool,
    pub success: bool,
    /// The physics fault that ended the episode, if one did.
    pub sim_fault: Option<SimFault>,
    /// The true hole offset from nominal, `[x, y, z, roll, pitch, yaw]`, m and rad.
    pub hole_offset: Pose6,
}

/// One step's result, Gymnasium's five values.
#[derive(Clone, Debug)]
pub struct Step {
    pub observation: [f64; OBSERVATION_LEN],
    pub reward: f64,
    /// Success, or a physics fault.
    pub terminated: bool,
    /// The episode's time is up.
    pub truncated: bool,
    pub info: StepInfo,
}

/// An episode under way.
struct Episode {
    cell: WorkCell,
    nominal: Iso,
    truth: Iso,
    offset: Pose6,
    target: Iso,
    depth_m: f64,
    fault: Option<SimFault>,
    /// Exact penetration of the peg into the hole at its true pose.
    probe: PenetrationProbe,
    /// The stiffness the controller runs at, N/m and N m/rad.
    stiffness: [f64; 6],
}

/// The seed an environment's pair is printed from on the real cell: an environment is one cell
/// with one printed pair, whatever its episodes' seeds ([`crate::twin::real_cell::RealCell::print`]).
pub const ENV_PRINT_SEED: u64 = 1;

/// The environment over one part pair.
pub struct PegEnv {
    pair: PartPair,
    robot: RobotModel,
    params: WorkCellParams,
    config: EnvConfig,
    trial: TrialConfig,
    episode: Option<Episode>,
}

impl PegEnv {
    /// An environment of `pair` held by `robot` in the cell `params`.
    pub fn new(
        pair: PartPair,
        robot: RobotModel,
        params: WorkCellParams,
        config: EnvConfig,
    ) -> Result<Self> {
        config.ensure_valid(&params)?;
        let pair = params.cell.printed(ENV_PRINT_SEED, pair)?;
        let trial = TrialConfig {
            start: config.start,
            offset_range: config.offset_range,
            ..TrialConfig::default()
        };
        Ok(PegEnv {
            pair,
            robot,
            params,
            config,
            trial,
            episode: None,
        })
    }

    pub fn config(&self) -> &EnvConfig {
        &self.config
    }

    /// Starts an episode: the hole offset as trial `seed` draws it, the sensors seeded as its
    /// sensors are, the peg at the trial's start and the target where the robot believes that
    /// start to be (the nominal hole's, for a partial insertion). Returns the first observation.
    pub fn reset(&mut self, seed: u64) -> Result<([f64; OBSERVATION_LEN], StepInfo)> {
        let setup = Setup::draw(
            &self.pair,
            self.robot.joints.len(),
            &self.params,
            &self.trial,
            TrialSeeds { trial: seed },
        );
        // The trial's set-up under the environment's gains from the first step.
        let under_env_gains = TrialConfig {
            observe_gains: self.config.gains.clone(),
            ..self.trial.clone()
        };
        let mut cell = setup.cell(&self.pair, &self.robot, &self.params, &under_env_gains)?;
        let target = setup.believed_start(&self.trial);
        cell.command_pose(target);
        let (nominal, truth) = (setup.nominal, setup.truth);
        let mut episode = Episode {
            cell,
            nominal,
            truth,
            offset: setup.offset,
            target,
            depth_m: 0.0,
            fault: None,
            probe: PenetrationProbe::new(&self.pair.hole, &truth),
            stiffness: self.config.gains.stiffness,
        };
        episode.depth_m = episode.depth();
        let info = self.info(&episode, false);
        let observation = episode.observation();
        self.episode = Some(episode);
        Ok((observation, info))
    }

    /// One control period under `action` (each component clipped to [-1, 1]).
    pub fn step(&mut self, action: &[f64]) -> Result<Step> {
        let want = self.config.action_len();
        if action.len() != want {
            return Err(Error::Input(format!(
                "action of length {}: expected {want} values",
                action.len()
            )));
        }
        if let Some(bad) = action.iter().find(|a| !a.is_finite()) {
            return Err(Error::Input(format!(
                "action value {bad}: expected a number"
            )));
        }
        let a: Vec<f64> = action.iter().map(|v| v.clamp(-1.0, 1.0)).collect();
        let mut episode = self.episode.take().ok_or_else(|| {
            Error::Input("step before reset: call reset() to start an episode".into())
        })?;
        if episode.fault.is_some() {
            self.episode = Some(episode);
            return Err(Error::Input(
                "step after the episode ended in a sim_fault: call reset()".into(),
            ));
        }
        self.apply(&mut episode, &a)?;
        let steps = (1.0 / (self.config.control_hz * episode.cell.dt_s())).round() as usize;
        for _ in 0..steps {
            episode.cell.step();
            if let Some(f) = episode.cell.fault() {
                episode.fault = Some(f);
                break;
            }
        }
        let step = self.score(&mut episode);
        self.episode = Some(episode);
        Ok(step)
    }

    /// Moves the target by the action's increment and sets the stiffness it asks for.
    fn apply(&self, episode: &mut Episode, a: &[f64]) -> Result<()> {
        let (m, r) = (self.config.max_step_m, self.config.max_step_rad);
        let in_hole = episode.nominal.inverse() * episode.target;
        let shift = Translation3::new(a[0] * m, a[1] * m, a[2] * m);
        let turn = UnitQuaternion::from_euler_angles(a[3] * r, a[4] * r, a[5] * r);
        let moved = Iso::from_parts(shift * in_hole.translation, in_hole.rotation * turn);
        episode.target = episode.nominal * moved;
        episode.cell.command_pose(episode.target);
        if self.config.variable_stiffness {
            let gains = stiffness_gains(&self.config.gains, a[6], a[7]);
            if gains.stiffness != episode.stiffness {
                episode.stiffness = gains.stiffness;
                episode.cell.switch_gains(gains)?;
            }
        }
        Ok(())
    }

    /// The step's reward, ends and info, after the physics ran.
    fn score(&self, episode: &mut Episode) -> Step {
        let depth = episode.depth();
        let gained_mm = (depth - episode.depth_m) * 1e3;
        episode.depth_m = depth;
        let success = episode.fault.is_none()
            && (depth - self.pair.cavity_depth_m).abs() <= self.trial.success_eps_m;
        let force = episode.cell.measurements().wrench.fixed_rows::<3>(0).norm();
        let c = &self.config;
        let mut reward =
            c.reward_per_mm * gained_mm - c.force_penalty_per_n * (force - c.force_free_n).max(0.0);
        if success {
            reward += c.success_reward;
        }
        let info = self.info(episode, success);
        Step {
            observation: episode.observation(),
            reward,
            terminated: success || episode.fault.is_some(),
            truncated: info.time_s >= c.episode_s - 1e-9,
            info,
        }
    }

    fn info(&self, episode: &Episode, success: bool) -> StepInfo {
        let tcp = episode.cell.truth().tcp_pose();
        StepInfo {
            time_s: episode.cell.time_s(),
            depth_m: episode.depth_m,
            true_wrench: episode.cell.truth().contact_wrench().into(),
            penetration_m: episode.probe.max_penetration(&self.pair.peg, &tcp),
            contact: episode.cell.measurements().contact,
            success,
            sim_fault: episode.fault.clone(),
            hole_offset: episode.offset,
        }
    }
}

impl Episode {
    /// Tip depth below the true mouth, m.
    fn depth(&self) -> f64 {
        -(self.truth.inverse() * self.cell.truth().tcp_pose())
            .translation
            .z
    }

    /// What the robot measures: its TCP pose in the nominal hole frame, the estimated wrench.
    fn observation(&self) -> [f64; OBSERVATION_LEN] {
        let m = self.cell.measurements();
        let pose = Pose6::from_iso(&(self.nominal.inverse() * m.tcp));
        let mut out = [0.0; OBSERVATION_LEN];
        out[..6].copy_from_slice(&pose.0);
        out[6..].copy_from_slice(m.wrench.as_slice());
        out
    }
}

/// `base` with the stiffness a variable-stiffness action asks for: `t` and `r` in [-1, 1] map
/// linearly onto the translational and rotational ranges.
fn stiffness_gains(base: &ImpedanceGains, t: f64, r: f64) -> ImpedanceGains {
    let map = |(lo, hi): (f64, f64), v: f64| lo + (v + 1.0) / 2.0 * (hi - lo);
    let kt = map(TRANSLATIONAL_STIFFNESS_RANGE, t);
    let kr = map(ROTATIONAL_STIFFNESS_RANGE, r);
    ImpedanceGains {
        stiffness: [kt, kt, kt, kr, kr, kr],
        ..base.clone()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::twin::geometry::{build_builtin, builtin_by_name};
    use crate::twin::robot::urdf::iiwa14;

    fn env(config: EnvConfig) -> Result<PegEnv> {
        let pair = build_builtin(builtin_by_name("cross").unwrap(), 0.5e-3).unwrap();
        PegEnv::new(pair, iiwa14().unwrap(), WorkCellParams::default(), config)
    }

    #[test]
    fn settings_that_cannot_run_are_refused_by_name() {
        for (config, expected) in [
            (
                EnvConfig {
                    control_hz: 7.0,
                    ..EnvConfig::default()
                },
                "control_hz 7: expected a whole number",
            ),
            (
                EnvConfig {
                    max_step_m: 1.0,
                    ..EnvConfig::default()
                },
                "max_step_m 1: expected 0 to 0.01",
            ),
        ] {
            let e = env(config).err().expect("refused").to_string();
            assert!(e.contains(expected), "{e}");
        }
        let mut ok = env(EnvConfig::default()).unwrap();
        assert!(ok.step(&[0.0; 6]).is_err(), "a step before reset");
        ok.reset(1).unwrap();
        assert!(ok.step(&[0.0; 5]).is_err());
        assert!(ok.step(&[f64::NAN; 6]).is_err());
    }

    #[test]
    fn pushing_straight_down_into_an_aligned_hole_succeeds_and_is_reproducible() {
        let aligned = EnvConfig {
            offset_range: [0.0; 6],
            ..EnvConfig::default()
        };
        let run = || {
            let mut e = env(aligned.clone()).unwrap();
            let (first, info) = e.reset(5).unwrap();
            assert!((info.depth_m - 3e-3).abs() < 1e-5, "{}", info.depth_m);
            let mut steps = vec![];
            for _ in 0..60 {
                let s = e.step(&[0.0, 0.0, -1.0, 0.0, 0.0, 0.0]).unwrap();
                let end = s.terminated || s.truncated;
                steps.push(s);
                if end {
                    break;
                }
            }
            (first, steps)
        };
        let (first, steps) = run();
        let last = steps.last().unwrap();
        assert!(last.terminated && last.info.success, "{:?}", last.info);
        assert!(last.info.sim_fault.is_none() && last.info.penetration_m < 0.05e-3);
        let total: f64 = steps.iter().map(|s| s.reward).sum();
        assert!(total > 20.0, "{total}");
        let (again, replayed) = run();
        assert_eq!(first, again);
        assert_eq!(
            steps.iter().map(|s| s.observation).collect::<Vec<_>>(),
            replayed.iter().map(|s| s.observation).collect::<Vec<_>>()
        );
    }
}
