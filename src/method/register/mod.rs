//! Contact manifold registration: Algorithm 1 of the paper (Section IV-D), and a least-squares
//! solver on the same residuals.
//!
//! Notation follows the paper. `A` is the robot base, `h,t` the hole frame as estimated at iteration
//! `t`, `H` the true hole frame of the reference manifold. Observations are peg poses `A_T_p`; the
//! result is the hole pose `A_T_h`.
//!
//! - [`algorithm1`]: Algorithm 1, line by line, with the paper's update ([`Solver::Paper`]);
//! - [`correspondence`]: its lines 6-9, the correspondences both solvers use;
//! - [`least_squares`]: the same residuals solved by Levenberg-Marquardt ([`Solver::LeastSquares`],
//!   the default);
//! - here: the settings, the checks of the input, the restarts and their combination.
//!
//! # Restarts
//!
//! `restarts` runs start from `A_T_h,0 ⊗ exp(xi)`, `xi` Gaussian with `sigma_m` on each translation
//! axis and `sigma_rad` on each rotation axis of the hole frame, each from its own random stream
//! (seed, restart index): results do not depend on the thread count. The restarts run in parallel.
//! Outlying restarts are rejected by the median absolute deviation: each result is written as a
//! scaled twist from the mean of all results; a restart is rejected when any axis lies more than
//! `mad_threshold` x 1.4826 x MAD from that axis's median (MAD floored at [`MAD_FLOOR_MM`] so that
//! restarts that agree to micrometres are all kept). The estimate is the SE(3) mean of the rest
//! (of all, all kept, where the test would reject every one).

pub mod algorithm1;
pub mod correspondence;
pub mod least_squares;
pub mod uncertainty;

use crate::choice::{Choice, Named};
use crate::error::{Error, Result};
use crate::method::manifold::{Manifold, Resolution};
use crate::pose::{Iso, Pose6, PoseMetric, se3_exp, se3_log, se3_mean};
use algorithm1::{aligned, run_paper};
use correspondence::rms_residual;
use least_squares::run_least_squares;
use nalgebra::{Matrix6, Vector3, Vector6};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::time::Instant;

/// Floor of the MAD used to reject restarts, mm-equivalents.
pub const MAD_FLOOR_MM: f64 = 0.01;

/// Which update rule each iteration uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Solver {
    /// Algorithm 1's update: SE(3) mean of the symmetric point-to-plane misalignments.
    Paper,
    /// Gauss-Newton on the same residuals with a Huber loss.
    LeastSquares,
}

impl Choice for Solver {
    const WHAT: &'static str = "solver";
    const NAMED: &'static [Named<Self>] = &[
        Named {
            name: "paper",
            value: Solver::Paper,
            help: "Algorithm 1's update: SE(3) mean of the symmetric point-to-plane misalignments",
        },
        Named {
            name: "least-squares",
            value: Solver::LeastSquares,
            help: "Gauss-Newton on the same residuals with a Huber loss",
        },
    ];
}

/// How the paper's update is applied (see the module documentation).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum PaperUpdate {
    /// `h,t_T_h,t+1 = (mean Delta)⁻¹`: moves the estimate towards the manifold.
    Consistent,
    /// `h,t_T_h,t+1 = mean Delta` as printed in Algorithm 1: moves it away.
    AsPrinted,
}

/// Restarts per registration. Eight agree with sixteen on the paper's experiment (same successes,
/// MAE within 0.01 mm and 0.08 deg on 100 trials) with half the restart work (13 % less time for
/// the whole campaign).
pub const DEFAULT_RESTARTS: usize = 8;
/// Spread of the restarts' initial rotation, deg per axis: about the standard deviation of the
/// paper's orientation prior U(-5, 5) deg (2.9 deg). Restarts drawn with 1 deg could not leave
/// the basin of a roll/pitch bias of the nominal pose (docs/journal/2026-11-25.md).
pub const DEFAULT_SIGMA_DEG: f64 = 3.0;

/// Parameters of a registration (in files, fields not given keep their defaults).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RegistrationConfig {
    pub solver: Solver,
    /// Maximum iterations per restart (N).
    pub iterations: usize,
    /// Stop a restart when its update is smaller than this, mm-equivalents.
    pub tolerance_mm: f64,
    /// Number of restarts (R).
    pub restarts: usize,
    /// Standard deviation of the restarts' initial translation, per axis, m.
    pub sigma_m: f64,
    /// Standard deviation of the restarts' initial rotation, per axis, rad.
    pub sigma_rad: f64,
    /// Observations per observation normal (k).
    pub normal_k: usize,
    /// Seed of the restarts' initial poses (in a trial, mixed with the trial's registration
    /// stream: `method::seeds::TrialSeeds::registration`).
    pub seed: u64,
    /// Form of the paper's update.
    pub paper_update: PaperUpdate,
    /// Huber threshold of the least-squares solver, in robust standard deviations.
    pub huber_k: f64,
    /// Restart rejection threshold, in robust standard deviations (1.4826 MAD).
    pub mad_threshold: f64,
}

impl Default for RegistrationConfig {
    fn default() -> Self {
        RegistrationConfig {
            solver: Solver::LeastSquares,
            iterations: 50,
            tolerance_mm: 1e-3,
            restarts: DEFAULT_RESTARTS,
            sigma_m: 1e-3,
            sigma_rad: DEFAULT_SIGMA_DEG.to_radians(),
            normal_k: crate::method::manifold::DEFAULT_NORMAL_K,
            seed: 0,
            paper_update: PaperUpdate::Consistent,
            huber_k: 1.345,
            mad_threshold: 3.0,
        }
    }
}

impl RegistrationConfig {
    /// Reject values that cannot work, naming the field.
    pub fn ensure_valid(&self) -> Result<()> {
        let bad = |field: &str, expected: &str| {
            Err(Error::Input(format!(
                "registration {field}: expected {expected}"
            )))
        };
        if !(1..=MAX_ITERATIONS).contains(&self.iterations) {
            return bad("iterations", &format!("1 to {MAX_ITERATIONS}"));
        }
        if !(1..=MAX_RESTARTS).contains(&self.restarts) {
            return bad("restarts", &format!("1 to {MAX_RESTARTS}"));
        }
        if !(self.tolerance_mm >= 0.0 && self.tolerance_mm.is_finite()) {
            return bad("tolerance", "a finite number >= 0");
        }
        if !(self.sigma_m >= 0.0 && self.sigma_m <= MAX_SIGMA_M) {
            return bad("sigma (position)", "0 to 1000 mm");
        }
        if !(self.sigma_rad >= 0.0 && self.sigma_rad <= std::f64::consts::PI) {
            return bad("sigma (orientation)", "0 to 180 deg");
        }
        if !(7..=MAX_NORMAL_K).contains(&self.normal_k) {
            return bad(
                "k",
                &format!("7 to {MAX_NORMAL_K} (a normal in 6-D needs 7 points)"),
            );
        }
        if !(self.huber_k > 0.0 && self.mad_threshold > 0.0) {
            return bad("huber_k / mad_threshold", "positive numbers");
        }
        Ok(())
    }
}

/// Largest spread of the restarts' initial positions, m.
const MAX_SIGMA_M: f64 = 1.0;
/// Bounds on the work one registration may be asked for: iterations per restart, restarts,
/// neighbours per normal.
pub const MAX_ITERATIONS: usize = 10_000;
pub const MAX_RESTARTS: usize = 1_000;
pub const MAX_NORMAL_K: usize = 1_000;

/// The result of one restart.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct RestartResult {
    /// Initial hole pose `A_T_h,0` of this restart.
    pub initial: Pose6,
    /// Final hole pose `A_T_h`.
    pub estimate: Pose6,
    /// Iterations run.
    pub iterations: usize,
    /// Size of each iteration's update, mm-equivalents.
    pub step_mm: Vec<f64>,
    /// RMS of the symmetric point-to-plane residuals at the last correspondences, mm-equivalents.
    pub residual_mm: f64,
    /// Whether the MAD test rejected it.
    pub rejected: bool,
    /// The covariance of its optimum, m and rad ([`uncertainty::run_covariance`]); not written
    /// out.
    #[serde(skip)]
    pub covariance: [[f64; 6]; 6],
}

/// Wall time per stage, seconds.
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub struct StageTimes {
    pub restarts_s: f64,
    pub combine_s: f64,
    pub total_s: f64,
}

/// The estimate and how it was reached.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Registration {
    /// Estimated hole pose in the robot base frame, `A_T_h` (m, rad).
    pub estimate: Pose6,
    pub solver: Solver,
    pub restarts: Vec<RestartResult>,
    /// Restarts kept by the MAD test.
    pub kept: usize,
    /// The covariance of the estimate's error in the estimated hole frame (x, y, z m; roll,
    /// pitch, yaw rad), row by row: the covariance and spread of the restarts it was combined
    /// from, scaled by the measured [`uncertainty::AXIS_SCALE`] with the floor of the manifold's
    /// clearance ([`uncertainty::axis_floor`]) added (docs/registration.md, "Uncertainty").
    #[serde(default)]
    pub covariance: [[f64; 6]; 6],
    /// The standard deviation of each axis of `covariance` (m, rad).
    #[serde(default)]
    pub estimate_std: [f64; 6],
    pub time: StageTimes,
}

/// Estimate `A_T_h` from observations `A_T_p` against `manifold`, starting from `init` (Algorithm 1
/// with restarts).
pub fn register(
    manifold: &Manifold,
    observations: &[Pose6],
    init: &Pose6,
    cfg: &RegistrationConfig,
) -> Result<Registration> {
    cfg.ensure_valid()?;
    check_observations(observations, cfg.normal_k, &manifold.meta.metric)?;
    init.ensure_plausible("initial estimate")?;
    check_near_manifold(manifold, observations, init)?;
    let t0 = Instant::now();
    let obs: Vec<Iso> = observations.iter().map(Pose6::to_iso).collect();
    let init = init.to_iso();
    let mut restarts: Vec<RestartResult> = (0..cfg.restarts)
        .into_par_iter()
        .with_min_len(min_chunk())
        .map(|r| run_from(manifold, &obs, restart_start(&init, r, cfg), cfg))
        .collect();
    let t1 = Instant::now();
    let estimate = combine_restarts(&mut restarts, &manifold.meta.metric, cfg.mad_threshold);
    let floor = uncertainty::axis_floor(manifold.meta.clearance_m);
    let covariance = uncertainty::estimate_covariance(&estimate, &restarts, &floor);
    let t2 = Instant::now();
    Ok(Registration {
        estimate: Pose6::from_iso(&estimate),
        solver: cfg.solver,
        kept: restarts.iter().filter(|r| !r.rejected).count(),
        covariance,
        estimate_std: uncertainty::axis_std(&covariance),
        restarts,
        time: StageTimes {
            restarts_s: (t1 - t0).as_secs_f64(),
            combine_s: (t2 - t1).as_secs_f64(),
            total_s: (t2 - t0).as_secs_f64(),
        },
    })
}

/// Refuses observations that cannot pin a 6-D pose: fewer than the `k` an observation normal
/// needs, implausible values, fewer than `k` distinct poses (repeated rows), or a cloud that
/// spreads along one line only (in the metric's scaled coordinates).
fn check_observations(observations: &[Pose6], k: usize, metric: &PoseMetric) -> Result<()> {
    if observations.len() < k {
        return Err(Error::Input(format!(
            "{} observations, fewer than the k = {k} neighbours an observation normal needs",
            observations.len()
        )));
    }
    for (i, p) in observations.iter().enumerate() {
        p.ensure_plausible(&format!("observation {i}"))?;
    }
    let distinct = distinct_poses(observations);
    if distinct < k {
        return Err(Error::Input(format!(
            "only {distinct} distinct observations among {} (repeated rows?): the observation \
             normals need k = {k}",
            observations.len()
        )));
    }
    let scaled: Vec<[f64; 6]> = observations.iter().map(|p| metric.scaled(p)).collect();
    let spread = principal_spreads(&scaled);
    if spread[1] <= 1e-6 * spread[0] {
        return Err(Error::Input(format!(
            "the {} observations lie on one line in pose space ({:.3} mm-equivalents along it, \
             {:.3e} across): they cannot fix a 6-D pose",
            observations.len(),
            spread[0],
            spread[1]
        )));
    }
    Ok(())
}

/// How many distinct poses `observations` holds (a zero and a negative zero are one).
pub fn distinct_poses(observations: &[Pose6]) -> usize {
    let bits = |p: &Pose6| p.0.map(|v| (v + 0.0).to_bits());
    (observations.iter().map(bits))
        .collect::<std::collections::BTreeSet<_>>()
        .len()
}

/// Standard deviations of a scaled point cloud along its principal axes, largest first.
fn principal_spreads(points: &[[f64; 6]]) -> [f64; 6] {
    let n = points.len() as f64;
    let mean = points
        .iter()
        .fold(Vector6::zeros(), |m, p| m + Vector6::from(*p))
        / n;
    let cov = points.iter().fold(Matrix6::zeros(), |c, p| {
        let d = Vector6::from(*p) - mean;
        c + d * d.transpose()
    }) / n;
    let mut sd: Vec<f64> = cov
        .symmetric_eigenvalues()
        .iter()
        .map(|e| e.max(0.0).sqrt())
        .collect();
    sd.sort_by(|a, b| b.total_cmp(a));
    std::array::from_fn(|i| sd[i])
}

/// The most the observations' centre may lie outside the manifold's extent, seen from the
/// initial estimate, m: more than the largest hole offset a trial draws (50 mm) and far less than
/// a unit error of a thousand.
pub const MAX_OBSERVATION_GAP_M: f64 = 0.1;

/// Refuses observations whose centre, seen from the initial estimate of the hole, lies far outside
/// the manifold's extent: observations in millimetres, or an estimate far from the hole.
fn check_near_manifold(manifold: &Manifold, observations: &[Pose6], init: &Pose6) -> Result<()> {
    let hole_t_base = init.to_iso().inverse();
    let centre = observations.iter().fold(Vector3::zeros(), |c, p| {
        c + (hole_t_base * p.to_iso()).translation.vector
    }) / observations.len() as f64;
    let ranges = manifold.ranges();
    let gap = Vector3::from_fn(|i, _| {
        let [lo, hi] = ranges[i];
        (lo - centre[i]).max(centre[i] - hi).max(0.0)
    })
    .norm();
    if gap > MAX_OBSERVATION_GAP_M {
        return Err(Error::Input(format!(
            "the observations' centre lies {gap:.3} m outside the manifold's extent, seen from the \
             initial estimate: observations hold metres and radians (were these millimetres?), and \
             the initial estimate must be near the hole"
        )));
    }
    Ok(())
}

/// The smallest share a parallel loop of the registration is split into: one item, or the whole
/// loop when the caller is itself a parallel task (a campaign's trial). There, a split would make
/// the worker wait on a join, and a waiting worker steals another trial: several trials then live
/// on one thread at once and memory creeps up over a long campaign, while the trials already fill
/// the cores. The results are the same either way.
fn min_chunk() -> usize {
    if rayon::current_thread_index().is_some() {
        usize::MAX
    } else {
        1
    }
}

/// The initial pose of restart `r`: `init ⊗ exp(xi)`, `xi` from the restart's own random stream.
pub fn restart_start(init: &Iso, r: usize, cfg: &RegistrationConfig) -> Iso {
    let mut rng = ChaCha8Rng::seed_from_u64(cfg.seed);
    rng.set_stream(r as u64);
    let mut xi = Vector6::zeros();
    for k in 0..6 {
        let z: f64 = StandardNormal.sample(&mut rng);
        xi[k] = z * if k < 3 { cfg.sigma_m } else { cfg.sigma_rad };
    }
    init * se3_exp(&xi)
}

/// One run of Algorithm 1 from `start` (`A_T_h,0`), observations `A_T_p`.
pub fn run_from(
    manifold: &Manifold,
    observations: &[Iso],
    start: Iso,
    cfg: &RegistrationConfig,
) -> RestartResult {
    let (state, step_mm) = match cfg.solver {
        Solver::Paper => {
            let (state, mut search) = aligned(
                manifold,
                observations,
                start,
                Resolution::Full,
                cfg.normal_k,
            );
            run_paper(manifold, state, &mut search, cfg)
        }
        Solver::LeastSquares => run_least_squares(manifold, observations, start, cfg),
    };
    let factors = manifold.meta.metric.factors();
    RestartResult {
        initial: Pose6::from_iso(&start),
        estimate: Pose6::from_iso(&state.estimate),
        iterations: step_mm.len(),
        residual_mm: rms_residual(&state.cs),
        step_mm,
        rejected: false,
        covariance: uncertainty::run_covariance(&state.cs, &factors, cfg.huber_k),
    }
}

/// Reject outlying restarts (MAD) and return the SE(3) mean of the others (of all, kept, where
/// the test would reject every one).
fn combine_restarts(results: &mut [RestartResult], metric: &PoseMetric, threshold: f64) -> Iso {
    let all: Vec<Iso> = results.iter().map(|r| r.estimate.to_iso()).collect();
    let centre = se3_mean(&all, metric);
    let centre_inv = centre.inverse();
    let f = metric.factors();
    let coords: Vec<[f64; 6]> = all
        .iter()
        .map(|t| {
            let xi = se3_log(&(centre_inv * t));
            std::array::from_fn(|k| xi[k] * f[k])
        })
        .collect();
    for axis in 0..6 {
        let values: Vec<f64> = coords.iter().map(|c| c[axis]).collect();
        let med = median(&values);
        let deviations: Vec<f64> = values.iter().map(|v| (v - med).abs()).collect();
        let mad = median(&deviations).max(MAD_FLOOR_MM);
        for (r, d) in results.iter_mut().zip(&deviations) {
            if *d > threshold * 1.4826 * mad || !d.is_finite() {
                r.rejected = true;
            }
        }
    }
    if results.iter().all(|r| r.rejected) {
        // Axis by axis the test can reject every restart: with no consensus to keep, all are
        // kept, and the estimate is their mean.
        results.iter_mut().for_each(|r| r.rejected = false);
        return centre;
    }
    let kept: Vec<Iso> = results
        .iter()
        .zip(&all)
        .filter(|(r, _)| !r.rejected)
        .map(|(_, t)| *t)
        .collect();
    se3_mean(&kept, metric)
}

fn median(values: &[f64]) -> f64 {
    let mut v = values.to_vec();
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn repeated_readings_count_once_and_a_signed_zero_with_its_twin() {
        let p = |x: f64| Pose6([x, 0.0, 0.0, 0.0, 0.0, 0.0]);
        let readings: Vec<Pose6> = (0..1000).map(|i| p((i % 9) as f64 * 1e-4)).collect();
        assert_eq!(distinct_poses(&readings), 9);
        assert_eq!(distinct_poses(&[p(0.0), p(-0.0)]), 1);
    }

    /// A restart that ended at `p` (m, rad), not rejected, with no covariance of its own.
    fn result(p: [f64; 6]) -> RestartResult {
        RestartResult {
            initial: Pose6::IDENTITY,
            estimate: Pose6(p),
            iterations: 1,
            step_mm: vec![],
            residual_mm: 0.0,
            rejected: false,
            covariance: [[0.0; 6]; 6],
        }
    }

    #[test]
    fn mad_rejects_the_outlying_restart() {
        let metric = PoseMetric::default();
        let mut rs: Vec<RestartResult> = (0..7)
            .map(|i| {
                let d = 1e-5 * i as f64;
                result([0.6 + d, 0.05 - d, 0.2, 0.0, d, 0.3])
            })
            .collect();
        rs.push(result([0.6, 0.05, 0.21, 0.0, 0.0, 0.3]));
        let mean = combine_restarts(&mut rs, &metric, 3.0);
        assert!(rs[7].rejected && rs[..7].iter().all(|r| !r.rejected));
        assert!((mean.translation.vector.z - 0.2).abs() < 1e-9);
    }

    /// Seen on a plug3 trial: the MAD test, axis by axis, rejected every restart, and the
    /// estimate (the mean of all) came with a zero covariance, which an adaptive observation read
    /// as certain. Now every restart is kept, and the estimate is as uncertain as all of them.
    #[test]
    fn when_the_mad_test_would_reject_every_restart_all_are_kept() {
        let metric = PoseMetric::default();
        // Each restart lies out on an axis of its own.
        let mut rs: Vec<RestartResult> = (0..4)
            .map(|axis| {
                let mut p = [0.0; 6];
                p[axis] = 1e-2;
                result(p)
            })
            .collect();
        let all: Vec<Iso> = rs.iter().map(|r| r.estimate.to_iso()).collect();
        let mean = combine_restarts(&mut rs, &metric, 3.0);
        assert!(rs.iter().all(|r| !r.rejected));
        assert_eq!(mean, se3_mean(&all, &metric));
        let floor = uncertainty::axis_floor(None);
        let cov = uncertainty::estimate_covariance(&mean, &rs, &floor);
        assert!((0..4).all(|i| cov[i][i] > floor[i] * floor[i]), "{cov:?}");
    }
}
