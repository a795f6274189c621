//! One online trial (paper IV-C, IV-D, IV-E, V-A; Fig. 3 "observe", "register", "insert"), as
//! the paper ran it: a hole whose true pose is the nominal pose plus a random offset; the peg
//! starts partially inserted in it (or above it, with a spiral search); the robot observes
//! contacts for `t_obs` seconds around where it believes the hole is ([`observe`]), registers
//! them against the reference manifold (Algorithm 1, [`crate::method::register`]), then
//! retracts, aligns and inserts compliantly ([`insert`]). Or the paper's baseline, `direct`:
//! observe, then insert along the peg's own z with no estimate.
//!
//! The method sees only what the real cell sees: every stage drives a [`Session`], which lends it
//! the robot's commands and measurements. The true hole pose sets up the experiment (the fixture
//! and the initial partial insertion, as the experimenters placed them) and scores it here; it
//! never reaches a stage.

use crate::choice::Choice;
use crate::error::{Error, Result};
use crate::method::adaptive::{ObservationStop, StopRule, Widened};
use crate::method::config::{Method, Start, TrialConfig};
use crate::method::insert::{InsertEnd, Insertion, insert};
use crate::method::manifold::Manifold;
use crate::method::observe::{Observation, ObservationPhase};
use crate::method::register::{Registration, RegistrationConfig, distinct_poses, register};
use crate::method::search::{search, start_pose};
use crate::method::seeds::TrialSeeds;
use crate::method::session::{Phase, Recorder, Session};
use crate::pose::{Iso, Pose6};
use crate::twin::geometry::PartPair;
use crate::twin::geometry::Print;
use crate::twin::real_cell::CellDraw;
use crate::twin::robot::RobotModel;
use crate::twin::workcell::{SimFault, WorkCell, WorkCellParams, nominal_hole_pose, tcp_in_hole};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};
use std::time::Instant;

/// Sampling interval of the insertion force profile kept in a result, s.
pub const FZ_PROFILE_DT_S: f64 = 0.05;

/// Runs a trial. `manifold` is needed by the manifold method; `recorder` sees every step (the
/// `--trace` time series, a `--replay`).
pub fn run_trial(
    pair: &PartPair,
    robot: &RobotModel,
    params: &WorkCellParams,
    config: &TrialConfig,
    manifold: Option<&Manifold>,
    seed: u64,
    mut recorder: Option<&mut dyn Recorder>,
) -> Result<TrialResult> {
    if config.method.stops_itself() {
        return run_adaptive_trial(pair, robot, params, config, manifold, seed, recorder);
    }
    let looking = recorder.as_mut().map(|r| &mut **r as &mut dyn Recorder);
    let observed = observe_trial(pair, robot, params, config, seed, looking)?;
    finish_trial(observed, pair, config, manifold, recorder)
}

/// A trial of the adaptive method: it observes until its estimate is certain enough to insert
/// ([`ObservingTrial::observe_adaptively`]) or for `t_obs_s`, then inserts along the last
/// estimate. Its record holds the cell's `t_obs_s` and the time it observed, `observation_s`.
fn run_adaptive_trial(
    pair: &PartPair,
    robot: &RobotModel,
    params: &WorkCellParams,
    config: &TrialConfig,
    manifold: Option<&Manifold>,
    seed: u64,
    mut recorder: Option<&mut dyn Recorder>,
) -> Result<TrialResult> {
    let manifold = manifold.ok_or_else(|| {
        let method = config.method.name();
        Error::Input(format!("the {method} method needs a reference manifold"))
    })?;
    let looking = recorder.as_mut().map(|r| &mut **r as &mut dyn Recorder);
    let mut observing = ObservingTrial::start(pair, robot, params, config, seed, looking)?;
    let looking = recorder.as_mut().map(|r| &mut **r as &mut dyn Recorder);
    let adaptive = observing.observe_adaptively(pair, manifold, looking)?;
    let observed = observing.into_observed_at_budget();
    let at_stop = observed.config.clone();
    let estimator = Estimator::Given(adaptive.registration.map(Box::new));
    let mut result = finish(observed, pair, &at_stop, estimator, recorder)?;
    result.observation_s = Some(at_stop.t_obs_s);
    result.observation_stop = adaptive.stop;
    result.widened = adaptive.widened;
    result.check_s = Some(adaptive.checks.iter().map(|c| c.0).collect());
    result.check_std = Some(adaptive.checks.iter().map(|c| c.1).collect());
    result.t_obs_s = config.t_obs_s;
    Ok(result)
}

/// A trial up to the end of its observation (Fig. 3 "observe"): the cell as the observation
/// left it, and what registration and insertion start from. Trials that differ only in their
/// budget and after their observation ([`TrialConfig::observes_like_but_for_budget`]; same
/// seed, pair, robot and cell) run it once and each goes on from [`ObservingTrial::observed`] at its
/// budget: a campaign's direct baseline and its manifold trials at every `t_obs` share it.
pub struct ObservedTrial {
    config: TrialConfig,
    setup: Setup,
    cell: WorkCell,
    /// The physics fault that stopped the session, if one did.
    fault: Option<SimFault>,
    /// The hole frame the robot believes in; `None`: the search found no hole (or faulted), and
    /// the trial stopped.
    believed: Option<Iso>,
    search_s: f64,
    observation: Observation,
    /// Wall time so far, s.
    wall_s: f64,
}

/// The first stages of a trial: the set-up, the approach (or search), and the observation.
pub fn observe_trial(
    pair: &PartPair,
    robot: &RobotModel,
    params: &WorkCellParams,
    config: &TrialConfig,
    seed: u64,
    mut recorder: Option<&mut dyn Recorder>,
) -> Result<ObservedTrial> {
    let looking = recorder.as_mut().map(|r| &mut **r as &mut dyn Recorder);
    let mut observing = ObservingTrial::start(pair, robot, params, config, seed, looking)?;
    observing.observe_until(config.t_obs_s, recorder);
    Ok(observing.into_observed())
}

/// A registration and its wall time, s.
pub type TimedRegistration = (Registration, f64);

/// What an adaptive observation ended with ([`ObservingTrial::observe_adaptively`]).
pub struct AdaptiveObservation {
    /// The registration of the observation it stopped with (none when too few contacts were
    /// recorded to register, or when the trial stopped before observing), with its wall time.
    pub registration: Option<TimedRegistration>,
    /// Why it stopped (none when it never observed).
    pub stop: Option<ObservationStop>,
    /// For the active method, what its checks widened.
    pub widened: Option<Widened>,
    /// Each check that registered: its time, s, and the estimate's standard deviations then
    /// (m and rad).
    pub checks: Vec<(f64, [f64; 6])>,
}

/// A trial between its approach and the end of its observation, which can stop at several
/// budgets: the trials of a `t_obs` sweep that observe alike but for their budget
/// ([`TrialConfig::observes_like_but_for_budget`]) run the longest observation once, and each
/// goes on from its own budget ([`ObservingTrial::observed`]) as it would alone, bit for bit.
pub struct ObservingTrial {
    /// The trial so far, under the configuration it started under (the longest budget); its
    /// observation is read from `observation_phase` when it is handed on.
    trial: ObservedTrial,
    /// `None` when the trial stopped before observing.
    observation_phase: Option<ObservationPhase>,
    /// The budget observed to so far, s.
    budget_s: f64,
    started: Instant,
}

impl ObservingTrial {
    /// Sets the trial up (the hole offset, the cell) and approaches (or searches for) the hole;
    /// the observation starts then, under `config` (the longest budget of those asked for).
    pub fn start(
        pair: &PartPair,
        robot: &RobotModel,
        params: &WorkCellParams,
        config: &TrialConfig,
        seed: u64,
        recorder: Option<&mut dyn Recorder>,
    ) -> Result<ObservingTrial> {
        config.ensure_valid()?;
        let started = Instant::now();
        let seeds = TrialSeeds { trial: seed };
        let setup = Setup::draw(pair, robot.joints.len(), params, config, seeds);
        let mut cell = setup.cell(pair, robot, params, config)?;
        // A reborrow for the session's shorter life (the cell is younger than the recorder).
        let recorder = recorder.map(|r| &mut *r as &mut dyn Recorder);
        let mut session = Session::new(&mut cell, recorder, Phase::Search);
        let believed = setup.approach(&mut session, config, pair.clearance_m);
        let search_s = session.time_s();
        let observation_phase = believed.as_ref().map(|believed| {
            let perturbation = setup.seeds.perturbation();
            ObservationPhase::start(
                &mut session,
                believed,
                config,
                pair.clearance_m,
                perturbation,
            )
        });
        let fault = session.fault().cloned();
        let trial = ObservedTrial {
            config: config.clone(),
            setup,
            cell,
            fault,
            believed,
            search_s,
            observation: Observation::default(),
            wall_s: 0.0,
        };
        Ok(ObservingTrial {
            trial,
            observation_phase,
            budget_s: 0.0,
            started,
        })
    }

    /// Observes on until `t_obs_s` from the observation's start (at most the budget of the
    /// configuration it started under).
    pub fn observe_until(&mut self, t_obs_s: f64, recorder: Option<&mut dyn Recorder>) {
        let trial = &mut self.trial;
        self.budget_s = t_obs_s.min(trial.config.t_obs_s);
        let Some(observation_phase) = &mut self.observation_phase else {
            return;
        };
        let recorder = recorder.map(|r| &mut *r as &mut dyn Recorder);
        let fault = trial.fault.take();
        let mut session = Session::resume(&mut trial.cell, recorder, fault, Phase::Observe);
        observation_phase.run_to(&mut session, self.budget_s);
        trial.fault = session.fault().cloned();
    }

    /// The trial as it stands, for a trial whose budget ends here: a fork of the cell
    /// ([`WorkCell::fork`]) with the observation so far, under the configuration with this budget.
    pub fn observed(&self) -> ObservedTrial {
        let trial = &self.trial;
        ObservedTrial {
            config: TrialConfig {
                t_obs_s: self.budget_s,
                ..trial.config.clone()
            },
            setup: trial.setup.clone(),
            cell: trial.cell.fork(),
            fault: trial.fault.clone(),
            believed: trial.believed,
            search_s: trial.search_s,
            observation: self.observation(),
            wall_s: self.started.elapsed().as_secs_f64(),
        }
    }

    /// The observation of the adaptive method (docs/method.md, "Observation that stops itself"):
    /// from `check_from_s` on and every `check_every_s`, it registers the observations so far,
    /// starting from the last estimate (the believed hole at first), and stops as soon as the
    /// estimate's standard deviations meet [`StopRule`], as soon as one is out of reach by the
    /// longest budget ([`StopRule::out_of_reach`], unless turned off), or at that budget
    /// (`t_obs_s`). The active method also widens, after each check, the motion group its
    /// estimate knows least ([`StopRule::weakest`], [`ObservationPhase::widen`]).
    pub fn observe_adaptively(
        &mut self,
        pair: &PartPair,
        manifold: &Manifold,
        mut recorder: Option<&mut dyn Recorder>,
    ) -> Result<AdaptiveObservation> {
        let config = self.trial.config.clone();
        let rule = StopRule::for_pair(pair, &config.adaptive, manifold.meta.clearance_m);
        let mut t = config.adaptive.check_from_s.min(config.t_obs_s);
        let mut last: Option<TimedRegistration> = None;
        let mut before: Option<(f64, [f64; 6])> = None;
        let mut widened = (config.method == Method::Active).then(Widened::default);
        let mut checks = Vec::new();
        loop {
            self.observe_until(t, recorder.as_mut().map(|r| &mut **r as &mut dyn Recorder));
            let Some(believed) = self.trial.believed else {
                return Ok(AdaptiveObservation {
                    registration: None,
                    stop: None,
                    widened,
                    checks,
                });
            };
            let init = last.as_ref().map_or(believed, |(r, _)| r.estimate.to_iso());
            let observations = self.observation().downsampled(config.observations);
            let seeds = &self.trial.setup.seeds;
            last = match estimate_hole(Some(manifold), &observations, &init, &config, seeds)? {
                (Some(registration), wall_s) => Some((registration, wall_s)),
                (None, _) => None,
            };
            let std = last.as_ref().map(|(r, _)| r.estimate_std);
            checks.extend(std.map(|s| (t, s)));
            if let Some(stop) = self.stop_after_check(&rule, t, std, before) {
                return Ok(AdaptiveObservation {
                    registration: last,
                    stop: Some(stop),
                    widened,
                    checks,
                });
            }
            if let (Some(widened), Some(std), Some(phase)) =
                (&mut widened, std, &mut self.observation_phase)
            {
                let probe = rule.weakest(&std);
                phase.widen(probe);
                widened.add(probe);
            }
            before = std.map(|s| (t, s));
            t = (t + config.adaptive.check_every_s).min(config.t_obs_s);
        }
    }

    /// Whether the adaptive observation stops after its check at `t` (s), whose estimate has the
    /// standard deviations `std` (none: too few contacts to register), and why; `before` is the
    /// previous check's.
    fn stop_after_check(
        &self,
        rule: &StopRule,
        t: f64,
        std: Option<[f64; 6]>,
        before: Option<(f64, [f64; 6])>,
    ) -> Option<ObservationStop> {
        let config = &self.trial.config;
        let out_of_reach = |std: &[f64; 6]| {
            let before = before.filter(|_| config.adaptive.stop_out_of_reach);
            before.is_some_and(|(t0, s0)| rule.out_of_reach((t0, &s0), (t, std), config.t_obs_s))
        };
        if self.trial.fault.is_some() {
            Some(ObservationStop::Fault)
        } else if std.as_ref().is_some_and(|s| rule.met(s)) {
            Some(ObservationStop::Certain)
        } else if t >= config.t_obs_s {
            Some(ObservationStop::Budget)
        } else if std.as_ref().is_some_and(out_of_reach) {
            Some(ObservationStop::OutOfReach)
        } else {
            None
        }
    }

    /// The trial at the end of its observation, under its configuration with the budget it
    /// observed to (an adaptive trial's stop).
    pub fn into_observed_at_budget(self) -> ObservedTrial {
        let budget_s = self.budget_s;
        let mut observed = self.into_observed();
        observed.config.t_obs_s = budget_s;
        observed
    }

    /// The trial at the end of its observation.
    pub fn into_observed(self) -> ObservedTrial {
        let observation = self.observation();
        let wall_s = self.started.elapsed().as_secs_f64();
        ObservedTrial {
            observation,
            wall_s,
            ..self.trial
        }
    }

    fn observation(&self) -> Observation {
        let now_s = self.trial.cell.time_s();
        (self.observation_phase.as_ref())
            .map_or_else(Observation::default, |o| o.observation(now_s))
    }
}

/// The last stages of a trial under `config` (which must observe like the one `observed` ran
/// under): registration for the manifold method (Algorithm 1), insertion, and the score.
pub fn finish_trial(
    observed: ObservedTrial,
    pair: &PartPair,
    config: &TrialConfig,
    manifold: Option<&Manifold>,
    recorder: Option<&mut dyn Recorder>,
) -> Result<TrialResult> {
    finish(
        observed,
        pair,
        config,
        Estimator::Register(manifold),
        recorder,
    )
}

/// Where the estimate a trial inserts along comes from.
enum Estimator<'a> {
    /// The registration of its observation against this manifold (the manifold method; none:
    /// the direct baseline, which has no estimate).
    Register(Option<&'a Manifold>),
    /// A registration made while observing (the adaptive method), with its wall time, s.
    Given(Option<Box<TimedRegistration>>),
}

/// [`finish_trial`] with the estimate from `estimator`.
fn finish(
    observed: ObservedTrial,
    pair: &PartPair,
    config: &TrialConfig,
    estimator: Estimator<'_>,
    recorder: Option<&mut dyn Recorder>,
) -> Result<TrialResult> {
    config.ensure_valid()?;
    if !config.observes_like(&observed.config) {
        return Err(Error::Input(
            "a trial can only go on from an observation its own settings would have made".into(),
        ));
    }
    let started = Instant::now();
    let ObservedTrial {
        setup,
        mut cell,
        fault,
        believed,
        search_s,
        observation,
        wall_s,
        ..
    } = observed;
    let wall_s = || wall_s + started.elapsed().as_secs_f64();
    let Some(believed) = believed else {
        return Ok(setup.stopped(pair, config, fault, wall_s()));
    };
    let observations = observation.downsampled(config.observations);
    let recorder = recorder.map(|r| &mut *r as &mut dyn Recorder);
    let read_shift = setup.reads_off().then(|| read_t_true(&cell));
    let mut session = Session::resume(&mut cell, recorder, fault, Phase::Observe);
    let mut stages = Stages::new(search_s, observation, observations.len(), session.dt_s());
    stages.read_shift = read_shift;
    if session.fault().is_none() {
        (stages.estimate, stages.register_wall_s) = match estimator {
            Estimator::Register(manifold) => {
                estimate_hole(manifold, &observations, &believed, config, &setup.seeds)?
            }
            Estimator::Given(given) => given.map_or((None, 0.0), |g| (Some(g.0), g.1)),
        };
        let estimate = stages.estimate.as_ref().map(|r| &r.estimate);
        session.record_registration(&observations, &believed, estimate);
        stages.insertion = insert(
            &mut session,
            &believed,
            estimate,
            config,
            pair.cavity_depth_m,
        )?;
    }
    let fault = session.fault().cloned();
    let final_tcp = cell.truth().tcp_pose();
    Ok(setup.score(pair, config, stages, fault, &final_tcp, wall_s()))
}

/// `read_T_true`: the TCP pose the encoders give (forward kinematics of the joints as read)
/// relative to the true one, base frame. Near the pose it is taken at, it carries the true hole
/// to the hole as the robot reads it.
fn read_t_true(cell: &WorkCell) -> Iso {
    cell.measurements().tcp * cell.truth().tcp_pose().inverse()
}

/// Per-axis errors of the estimate, mm and deg (estimate against truth, in the true hole frame).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct AxisErrors {
    pub x_mm: f64,
    pub y_mm: f64,
    pub z_mm: f64,
    pub roll_deg: f64,
    pub pitch_deg: f64,
    pub yaw_deg: f64,
}

/// Simulated time per phase, s (rounded to the microsecond).
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub struct PhaseTimes {
    pub search_s: f64,
    pub observe_s: f64,
    /// Wall time of the registration (not part of the deterministic JSON result).
    #[serde(skip)]
    pub register_wall_s: f64,
    pub retract_s: f64,
    pub align_s: f64,
    pub insert_s: f64,
}

impl PhaseTimes {
    /// Simulated time of the whole trial, s.
    pub fn simulated_s(&self) -> f64 {
        self.search_s + self.observe_s + self.retract_s + self.align_s + self.insert_s
    }
}

/// The outcome of a trial.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct TrialResult {
    pub seed: u64,
    pub geometry: String,
    pub clearance_mm: f64,
    pub method: Method,
    pub start: Start,
    pub t_obs_s: f64,
    /// The true hole offset from nominal, mm and deg.
    pub offset: [f64; 6],
    /// What the trial's cell drew of the real cell's imperfections (absent: the ideal cell).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub real_cell: Option<CellDraw>,
    /// How the pair was printed, its measured clearance included (absent: as its CAD says).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub print: Option<Print>,
    /// `success`, `failure`, `sim_fault`, or `error` (the trial could not run to its end:
    /// `error_message` says why).
    pub outcome: String,
    /// Why the trial stopped before inserting, if it did.
    pub stopped: Option<String>,
    pub success: bool,
    pub fault: Option<SimFault>,
    /// Why the trial raised an error or panicked (outcome `error`): a bug or an input the
    /// checks missed, recorded so that a campaign goes on.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub error_message: Option<String>,
    /// How long the adaptive method observed before it stopped, s (`t_obs_s` is its longest);
    /// absent for the other methods, which observe for `t_obs_s`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub observation_s: Option<f64>,
    /// Why the adaptive method stopped observing: `certain`, `out_of_reach`, `budget` or
    /// `fault` (docs/method.md); absent for the other methods.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub observation_stop: Option<ObservationStop>,
    /// How many checks of the active method widened each motion group (`lateral`, `tilt`,
    /// `yaw`; docs/method.md, "Active probing"); absent for the other methods.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub widened: Option<Widened>,
    /// The times of the adaptive method's checks that registered, s (docs/method.md); absent for
    /// the other methods.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub check_s: Option<Vec<f64>>,
    /// The estimate's standard deviations at each of those checks (x, y, z m; roll, pitch, yaw
    /// rad, as `estimate_std`): how the uncertainty shrank as it observed; the last is the
    /// estimate's. Absent for the other methods.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub check_std: Option<Vec<[f64; 6]>>,
    /// Estimated `base_T_hole` (m, rad), manifold method only.
    pub estimate: Option<[f64; 6]>,
    /// The standard deviation of the estimate's error per axis, in the estimated hole frame
    /// (x, y, z m; roll, pitch, yaw rad): the registration's uncertainty (docs/registration.md).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub estimate_std: Option<[f64; 6]>,
    /// The covariance they come from (m and rad, row by row).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub estimate_covariance: Option<[[f64; 6]; 6]>,
    pub errors: Option<AxisErrors>,
    /// The estimate's errors against the hole as the robot reads it (the true hole moved by the
    /// shift between the TCP pose its encoders give and the true one where it observed), mm and
    /// deg: what registration can know and the insertion acts on, `errors` less the arm's
    /// kinematic calibration error (docs/registration.md). Present only when the cell's
    /// encoders carry offsets.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub read_errors: Option<AxisErrors>,
    /// Final tip depth below the true mouth, mm (none when the trial stopped before inserting).
    pub final_depth_mm: Option<f64>,
    pub contact_observations: usize,
    pub observations_used: usize,
    /// Force along the peg axis during insertion (estimated), N: peak and mean of |Fz|.
    pub peak_fz_n: f64,
    pub mean_fz_n: f64,
    /// |Fz| (estimated) during the insertion every `FZ_PROFILE_DT_S`, N (0.01 N resolution).
    pub insert_fz_n: Vec<f64>,
    /// Why the insertion's target stopped (none when the trial did not insert).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub insert_end: Option<InsertEnd>,
    pub times: PhaseTimes,
    /// Wall time of the whole trial, s (not part of the deterministic result).
    #[serde(skip)]
    pub wall_s: f64,
}

/// The experiment as the experimenters set it up (paper V-A): the nominal hole pose the robot is
/// told, the true pose (nominal plus a random offset drawn from the trial seed), and the seeds.
/// The Gymnasium environment (`method::env`) sets its episodes up through it too.
#[derive(Clone)]
pub(crate) struct Setup {
    pub(crate) nominal: Iso,
    pub(crate) offset: Pose6,
    pub(crate) truth: Iso,
    pub(crate) seeds: TrialSeeds,
    /// What the cell draws of the real cell's imperfections (from the sensors' seed, as
    /// [`WorkCell::new`] draws it).
    pub(crate) draw: Option<CellDraw>,
}

impl Setup {
    /// Whether the cell's encoders read the joints off by constant offsets (a kinematic
    /// calibration error).
    fn reads_off(&self) -> bool {
        self.draw
            .as_ref()
            .is_some_and(|d| !d.encoder_offset_rad.is_empty())
    }

    /// The set-up of trial `seeds` of `pair`, its arm of `joints` joints in the cell `params`.
    pub(crate) fn draw(
        pair: &PartPair,
        joints: usize,
        params: &WorkCellParams,
        config: &TrialConfig,
        seeds: TrialSeeds,
    ) -> Self {
        let nominal = nominal_hole_pose(pair, params);
        let offset = draw_offset(seeds.offset(), &config.offset_range);
        Setup {
            nominal,
            offset,
            truth: nominal * offset.to_iso(),
            seeds,
            draw: params.cell.draw(seeds.sensors(), joints),
        }
    }

    /// The cell with the fixture at the true pose and the peg at its start: partially inserted in
    /// the true hole (the paper's set-up), or above the nominal mouth for a search; under the
    /// observation gains of `config`.
    pub(crate) fn cell(
        &self,
        pair: &PartPair,
        robot: &RobotModel,
        params: &WorkCellParams,
        config: &TrialConfig,
    ) -> Result<WorkCell> {
        let start = match config.start {
            Start::Partial => tcp_in_hole(&self.truth, config.start_depth_m),
            Start::Above => start_pose(&self.nominal, config),
        };
        let gains = config.observe_gains.clone();
        let seed = self.seeds.sensors();
        WorkCell::new(
            pair,
            robot.clone(),
            params,
            Some(self.truth),
            &start,
            gains,
            seed,
        )
    }

    /// Brings the peg to the partial insertion the robot believes in and returns the hole frame
    /// it believes in: the nominal one (its compliance takes up the difference to the true
    /// hole), or where the search found the hole (`None`: it did not).
    fn approach(
        &self,
        session: &mut Session,
        config: &TrialConfig,
        clearance_m: f64,
    ) -> Option<Iso> {
        match config.start {
            Start::Partial => {
                session.command_pose(self.believed_start(config));
                Some(self.nominal)
            }
            Start::Above => search(session, &self.nominal, config, clearance_m),
        }
    }

    /// Where the robot believes the peg starts: partially inserted in the nominal hole, or above
    /// its mouth (where it also truly starts).
    pub(crate) fn believed_start(&self, config: &TrialConfig) -> Iso {
        match config.start {
            Start::Partial => tcp_in_hole(&self.nominal, config.start_depth_m),
            Start::Above => start_pose(&self.nominal, config),
        }
    }

    /// The result of a trial that stopped before observing: its search failed or faulted.
    fn stopped(
        &self,
        pair: &PartPair,
        config: &TrialConfig,
        fault: Option<SimFault>,
        wall_s: f64,
    ) -> TrialResult {
        let why = match fault {
            Some(_) => "the physics faulted during the search",
            None => "the search found no hole within its time limit",
        };
        TrialResult {
            stopped: Some(why.into()),
            ..self.common(pair, config, fault, wall_s)
        }
    }

    /// The part of every result that the setup decides.
    fn common(
        &self,
        pair: &PartPair,
        config: &TrialConfig,
        fault: Option<SimFault>,
        wall_s: f64,
    ) -> TrialResult {
        TrialResult {
            seed: self.seeds.trial,
            geometry: pair.name.clone(),
            clearance_mm: pair.clearance_mm(),
            method: config.method,
            start: config.start,
            t_obs_s: config.t_obs_s,
            offset: self.offset.to_mm_deg(),
            real_cell: self.draw.clone(),
            print: pair.print,
            outcome: outcome(fault.is_some(), false).into(),
            stopped: None,
            success: false,
            fault,
            error_message: None,
            observation_s: None,
            observation_stop: None,
            widened: None,
            check_s: None,
            check_std: None,
            estimate: None,
            estimate_std: None,
            estimate_covariance: None,
            errors: None,
            read_errors: None,
            final_depth_mm: None,
            contact_observations: 0,
            observations_used: 0,
            peak_fz_n: 0.0,
            mean_fz_n: 0.0,
            insert_fz_n: Vec::new(),
            insert_end: None,
            times: PhaseTimes::default(),
            wall_s,
        }
    }

    /// Scores a trial that observed: the final tip depth in the true hole against the floor
    /// (paper V-A: success within 2 mm), the estimate's errors, the insertion force.
    fn score(
        &self,
        pair: &PartPair,
        config: &TrialConfig,
        stages: Stages,
        fault: Option<SimFault>,
        final_tcp: &Iso,
        wall_s: f64,
    ) -> TrialResult {
        let final_depth = -(self.truth.inverse() * final_tcp).translation.z;
        let success =
            fault.is_none() && (final_depth - pair.cavity_depth_m).abs() <= config.success_eps_m;
        let fz = &stages.insertion.fz_n;
        TrialResult {
            outcome: outcome(fault.is_some(), success).into(),
            success,
            estimate: stages.estimate.as_ref().map(|r| r.estimate.0),
            estimate_std: stages.estimate.as_ref().map(|r| r.estimate_std),
            estimate_covariance: stages.estimate.as_ref().map(|r| r.covariance),
            errors: stages
                .estimate
                .as_ref()
                .map(|r| axis_errors(&self.truth, &r.estimate.to_iso())),
            read_errors: (stages.estimate.as_ref().zip(stages.read_shift))
                .map(|(r, shift)| axis_errors(&(shift * self.truth), &r.estimate.to_iso())),
            final_depth_mm: Some(final_depth * 1e3),
            contact_observations: stages.observation.contacts.len(),
            observations_used: stages.observations_used,
            peak_fz_n: fz.iter().copied().fold(0.0, f64::max),
            mean_fz_n: if fz.is_empty() {
                0.0
            } else {
                fz.iter().sum::<f64>() / fz.len() as f64
            },
            insert_fz_n: fz_profile(fz, stages.dt_s),
            insert_end: (!fz.is_empty()).then_some(stages.insertion.end),
            times: stages.times(),
            ..self.common(pair, config, fault, wall_s)
        }
    }
}

/// The record of a trial that raised an error or panicked with `message`: what its setup
/// decides (seed, pair, offset, the cell's draw for an arm of `joints` joints), outcome `error`.
pub fn errored_trial(
    (pair, joints): (&PartPair, usize),
    params: &WorkCellParams,
    config: &TrialConfig,
    seed: u64,
    message: String,
) -> TrialResult {
    let setup = Setup::draw(pair, joints, params, config, TrialSeeds { trial: seed });
    TrialResult {
        outcome: "error".into(),
        error_message: Some(message),
        ..setup.common(pair, config, None, 0.0)
    }
}

/// A trial's outcome as its record names it: `sim_fault` whenever the physics faulted.
fn outcome(faulted: bool, success: bool) -> &'static str {
    match (faulted, success) {
        (true, _) => "sim_fault",
        (false, true) => "success",
        (false, false) => "failure",
    }
}

/// The true hole offset of a trial from its offset stream: `[x, y, z, roll, pitch, yaw]` (m,
/// rad), uniform within `range` (paper V-A).
fn draw_offset(seed: u64, range: &[f64; 6]) -> Pose6 {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    Pose6(std::array::from_fn(|i| {
        if range[i] > 0.0 {
            rng.random_range(-range[i]..=range[i])
        } else {
            0.0
        }
    }))
}

/// What the stages of a trial that observed produced.
struct Stages {
    search_s: f64,
    observation: Observation,
    observations_used: usize,
    estimate: Option<Registration>,
    register_wall_s: f64,
    insertion: Insertion,
    dt_s: f64,
    /// `read_T_true`, base frame: how far the TCP pose the encoders give lies from the true one
    /// at the end of the observation, when the encoders carry offsets.
    read_shift: Option<Iso>,
}

impl Stages {
    fn new(search_s: f64, observation: Observation, observations_used: usize, dt_s: f64) -> Self {
        Stages {
            search_s,
            observation,
            observations_used,
            estimate: None,
            register_wall_s: 0.0,
            insertion: Insertion::default(),
            dt_s,
            read_shift: None,
        }
    }

    /// Simulated time per phase, rounded to the microsecond (the search's as it ran).
    fn times(&self) -> PhaseTimes {
        let us = |t: f64| (t * 1e6).round() / 1e6;
        let i = &self.insertion;
        PhaseTimes {
            search_s: self.search_s,
            observe_s: us(self.observation.duration_s),
            register_wall_s: self.register_wall_s,
            retract_s: us(i.retract_s),
            align_s: us(i.align_s),
            insert_s: us(i.insert_s),
        }
    }
}

/// Registration (IV-D, Fig. 3 "register") for the manifold method: the estimated `base_T_hole`
/// and its uncertainty, from the observations, starting from `init` (the believed hole), and
/// its wall time, s. None for the
/// direct baseline, or when too few observations were recorded for an observation normal. The
/// restarts draw from the trial's registration stream.
fn estimate_hole(
    manifold: Option<&Manifold>,
    observations: &[Pose6],
    init: &Iso,
    config: &TrialConfig,
    seeds: &TrialSeeds,
) -> Result<(Option<Registration>, f64)> {
    if !config.method.registers() {
        return Ok((None, 0.0));
    }
    let manifold = manifold
        .ok_or_else(|| Error::Input("the manifold method needs a reference manifold".into()))?;
    // An arm that barely moves repeats its readings: with no more distinct poses than an
    // observation normal needs neighbours, no estimate, as with too few observations
    // (registration refuses such a set as input).
    if distinct_poses(observations) <= config.registration.normal_k {
        return Ok((None, 0.0));
    }
    let t0 = Instant::now();
    let init = Pose6::from_iso(init);
    let registration = RegistrationConfig {
        seed: seeds.registration(config.registration.seed),
        ..config.registration.clone()
    };
    let reg = register(manifold, observations, &init, &registration)?;
    Ok((Some(reg), t0.elapsed().as_secs_f64()))
}

/// Every `FZ_PROFILE_DT_S` of a per-step |Fz| series, rounded to 0.01 N.
fn fz_profile(fz: &[f64], dt: f64) -> Vec<f64> {
    let stride = ((FZ_PROFILE_DT_S / dt).round() as usize).max(1);
    fz.iter()
        .step_by(stride)
        .map(|f| (f * 100.0).round() / 100.0)
        .collect()
}

/// Errors of an estimated hole pose: the estimate seen from the true hole frame, mm and deg.
pub fn axis_errors(truth: &Iso, estimate: &Iso) -> AxisErrors {
    let [x_mm, y_mm, z_mm, roll_deg, pitch_deg, yaw_deg] =
        Pose6::from_iso(&(truth.inverse() * estimate)).to_mm_deg();
    AxisErrors {
        x_mm,
        y_mm,
        z_mm,
        roll_deg,
        pitch_deg,
        yaw_deg,
    }
}
