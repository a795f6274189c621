//! Contact manifold registration: Algorithm 1 of the paper (Section IV-D), and a least-squares
//! solver on the same residuals.
//!
//! Notation follows the paper. `A` is the robot base, `h,t` the hole frame as estimated at iteration
//! `t`, `H` the true hole frame of the reference manifold. Observations are peg poses `A_T_p`; the
//! result is the hole pose `A_T_h`.
//!
//! # Algorithm 1, line by line ([`run_from`])
//!
//! - **Line 3, initial alignment**: `h,0_T_p = (A_T_h,0)⁻¹ ⊗ A_T_p` for every observation.
//! - **Line 6, correspondence**: the manifold point nearest to each observation in the scaled 6-D
//!   space (Euclidean k-d tree, [`crate::method::manifold::ScaledIndex`]) and its stored normal `n_q`.
//! - **Line 7, point-to-point misalignment**: `delta_i = (h,t_T_p,i)⁻¹ ⊗ H_T_p,i`, as a 6-vector
//!   `[x, y, z, roll, pitch, yaw]` in scaled coordinates.
//! - **Lines 8-9, observation normal**: the `k` nearest observations of each observation, in the
//!   current hole frame, recomputed every iteration (normals are not invariant to the update).
//! - **Line 10, symmetric point-to-plane misalignment**:
//!   `Delta_i = ½ [(delta_i · n_q) n_q + (delta_i · n_p) n_p]`, taken back to metres and radians.
//! - **Line 12, update**: the SE(3) mean of the `Delta_i` ([`crate::pose::se3_mean`], equal weights).
//!   *Choice, measured and tested*: `delta_i` as printed measures the observation-to-reference
//!   error from the observation's side, `delta_i ≈ E⁻¹` for a hole-frame error `E`, so applying its
//!   mean as `h,t_T_h,t+1` (as printed) doubles the error every iteration. The consistent update
//!   is the inverse of the mean, `h,t_T_h,t+1 = (mean Delta)⁻¹`; [`PaperUpdate::AsPrinted`] keeps the
//!   printed form for reproduction (test `printed_update_diverges`).
//! - **Line 13**: `A_T_h,t+1 = A_T_h,t ⊗ h,t_T_h,t+1`. **Line 14**: `h,t+1_T_p = (h,t_T_h,t+1)⁻¹ ⊗
//!   h,t_T_p`.
//! - **Stop** after `iterations` or when the update's scaled size is below `tolerance`.
//!
//! # Least squares ([`Solver::LeastSquares`])
//!
//! The same correspondences, normals and `delta_i`, but the update is the Gauss-Newton step on the
//! residuals `r_q,i = n_q · delta_i` and `r_p,i = n_p · delta_i`, linearised in the Lie algebra of the
//! hole-frame update (analytic Jacobian, tested against finite differences), with a Huber loss
//! (threshold `huber_k` robust standard deviations, the standard deviation estimated from the
//! median absolute residual) and Levenberg damping: a step is kept only if it lowers the cost at
//! the correspondences of the new pose, so weakly observable directions cannot run away. It runs
//! coarse to fine through the stages of `STAGES`. The paper's update moves each observation by a projection of
//! its error onto two normals and averages; along directions that few normals see, it takes a
//! small fraction of the step each iteration. Gauss-Newton takes the whole step at once.
//!
//! # Correspondences
//!
//! Both solvers search exactly (Lines 6 and 8 are true nearest neighbours), warm-started from the
//! previous iteration through [`NeighbourCache`]: the answer is read from the cache when the cache
//! proves it, found by a tree search otherwise.
//!
//! # Restarts
//!
//! `restarts` runs start from `A_T_h,0 ⊗ exp(xi)`, `xi` Gaussian with `sigma_m` on each translation
//! axis and `sigma_rad` on each rotation axis of the hole frame, each from its own random stream
//! (seed, restart index): results do not depend on the thread count. The restarts run in parallel.
//! Outlying restarts are rejected by the median absolute deviation: each result is written as a
//! scaled twist from the mean of all results; a restart is rejected when any axis lies more than
//! `mad_threshold` x 1.4826 x MAD from that axis's median (MAD floored at [`MAD_FLOOR_MM`] so that
//! restarts that agree to micrometres are all kept). The estimate is the SE(3) mean of the rest.

use crate::error::{Error, Result};
use crate::method::manifold::{
    Manifold, NeighbourCache, Resolution, ScaledIndex, neighbourhood_normal, squared_distance,
};
use crate::pose::{
    Iso, Pose6, PoseMetric, rpy_rate_to_angular_velocity, se3_exp, se3_log, se3_mean,
};
use nalgebra::{Matrix3, Matrix6, Vector3, Vector6};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::num::NonZero;
use std::sync::OnceLock;
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
    let t2 = Instant::now();
    Ok(Registration {
        estimate: Pose6::from_iso(&estimate),
        solver: cfg.solver,
        kept: restarts.iter().filter(|r| !r.rejected).count(),
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
    let scaled: Vec<[f64; 6]> = observations.iter().map(|p| metric.scaled(p)).collect();
    let distinct: std::collections::BTreeSet<[u64; 6]> = scaled
        .iter()
        .map(|s| s.map(|v| (v + 0.0).to_bits()))
        .collect();
    if distinct.len() < k {
        return Err(Error::Input(format!(
            "only {} distinct observations among {} (repeated rows?): the observation normals \
             need k = {k}",
            distinct.len(),
            observations.len()
        )));
    }
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

/// One correspondence of Algorithm 1 (lines 6-9), all vectors in scaled coordinates.
struct Correspondence {
    /// `delta_i`, the observation-to-reference misalignment as a 6-vector.
    delta: [f64; 6],
    /// `D_i = (h,t_T_p,i)⁻¹ ⊗ H_T_p,i` and the observation `h,t_T_p,i` (for the Jacobian).
    relative: Iso,
    observation: Iso,
    n_q: [f64; 6],
    n_p: [f64; 6],
}

fn dot(a: &[f64; 6], b: &[f64; 6]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// Spare candidates kept in each observation's neighbour cache.
const NEIGHBOUR_SPARE: usize = 16;

/// Search state carried from one iteration to the next: warm-started correspondences. The caches
/// only shorten the searches; every answer is the exact nearest neighbour (see
/// [`crate::method::manifold::NeighbourCache`]).
struct SearchState {
    resolution: Resolution,
    /// Per observation: its nearest manifold points at its last tree search.
    reference: Vec<Option<NeighbourCache>>,
    /// Per observation: its nearest observations when `epoch` was taken.
    neighbours: Vec<Option<NeighbourCache>>,
    /// Observation positions (scaled) when the neighbour caches were made.
    epoch: Vec<[f64; 6]>,
    /// Observations whose neighbour cache could not answer at the last pass.
    misses: usize,
}

impl SearchState {
    fn new(n: usize, resolution: Resolution) -> Self {
        SearchState {
            resolution,
            reference: vec![None; n],
            neighbours: vec![None; n],
            epoch: Vec::new(),
            misses: 0,
        }
    }
}

/// Lines 6-9 for every observation (in parallel; deterministic whatever the thread count).
fn correspondences(
    manifold: &Manifold,
    obs_h: &[Iso],
    k: usize,
    state: &mut SearchState,
) -> Vec<Correspondence> {
    let metric = manifold.meta.metric;
    let n = obs_h.len();
    let scaled: Vec<[f64; 6]> = obs_h
        .iter()
        .map(|o| metric.scaled(&Pose6::from_iso(o)))
        .collect();
    // Neighbour caches are renewed together when many missed (or at the start).
    let renew = state.epoch.len() != n || state.misses * 8 > n;
    let (spread, max_spread) = if renew {
        (Vec::new(), 0.0)
    } else {
        displacement_spread(&scaled, &state.epoch)
    };
    let obs_index: OnceLock<ScaledIndex> = OnceLock::new();
    let index = || obs_index.get_or_init(|| ScaledIndex::new(&scaled));
    let k_nz = NonZero::new(k).expect("k >= 7");
    let m = NonZero::new(k + NEIGHBOUR_SPARE).expect("m > 0");
    let resolution = state.resolution;
    let results: Vec<(Correspondence, Option<NeighbourCache>, bool)> = state
        .reference
        .par_iter_mut()
        .zip(state.neighbours.par_iter())
        .with_min_len(min_chunk())
        .enumerate()
        .map(|(i, (ref_cache, nb_cache))| {
            let (o, s) = (&obs_h[i], &scaled[i]);
            // Line 6: nearest reference point and its normal.
            let j = manifold.nearest_cached(resolution, s, ref_cache);
            // Line 7: point-to-point misalignment.
            let relative = o.inverse() * manifold.transform(j);
            let delta = metric.scaled(&Pose6::from_iso(&relative));
            // Line 8: the k nearest observations.
            let (mut neighbours, fresh, miss) = if renew {
                let c = index().cache(s, m, None, None);
                (c.candidates()[..k].to_vec(), Some(c), false)
            } else {
                match nb_cache
                    .as_ref()
                    .and_then(|c| c.k_nearest(&scaled, s, k, spread[i] + max_spread))
                {
                    Some(nb) => (nb, None, false),
                    None => (index().nearest_k(s, k_nz), None, true),
                }
            };
            // Line 9: their normal (summed in index order, so the bits do not depend on how
            // the neighbours were found).
            neighbours.sort_unstable();
            let n_p = neighbourhood_normal(neighbours.iter().map(|&b| &scaled[b]));
            let c = Correspondence {
                delta,
                relative,
                observation: *o,
                n_q: manifold.normals[j],
                n_p,
            };
            (c, fresh, miss)
        })
        .collect();
    state.misses = results.iter().filter(|r| r.2).count();
    let (cs, fresh): (Vec<Correspondence>, Vec<Option<NeighbourCache>>) =
        results.into_iter().map(|(c, fresh, _)| (c, fresh)).unzip();
    if renew {
        state.epoch = scaled;
        state.neighbours = fresh;
    }
    cs
}

/// How far each observation has moved since the neighbour caches' epoch, apart from the mean
/// move, and the largest of those (scaled coordinates). Between renewals the distance between
/// two observations can only have shrunk by the difference of their displacements: at most
/// |d_i - c| + max_j |d_j - c| for observation i, with c the mean displacement (small: the
/// update moves them nearly as one).
fn displacement_spread(scaled: &[[f64; 6]], epoch: &[[f64; 6]]) -> (Vec<f64>, f64) {
    let displacement: Vec<[f64; 6]> = scaled
        .iter()
        .zip(epoch)
        .map(|(a, b)| std::array::from_fn(|k| a[k] - b[k]))
        .collect();
    let mean: [f64; 6] = std::array::from_fn(|k| {
        displacement.iter().map(|d| d[k]).sum::<f64>() / displacement.len().max(1) as f64
    });
    let spread: Vec<f64> = displacement
        .iter()
        .map(|d| squared_distance(d, &mean).sqrt())
        .collect();
    let max_spread = spread.iter().copied().fold(0.0, f64::max);
    (spread, max_spread)
}

/// Line 10: the symmetric point-to-plane misalignment, scaled coordinates.
fn symmetric_misalignment(c: &Correspondence) -> [f64; 6] {
    let (a, b) = (dot(&c.delta, &c.n_q), dot(&c.delta, &c.n_p));
    std::array::from_fn(|i| 0.5 * (a * c.n_q[i] + b * c.n_p[i]))
}

/// RMS of the residuals `n_q · delta` and `n_p · delta`, mm-equivalents.
fn rms_residual(cs: &[Correspondence]) -> f64 {
    let sum: f64 = cs
        .iter()
        .map(|c| dot(&c.delta, &c.n_q).powi(2) + dot(&c.delta, &c.n_p).powi(2))
        .sum();
    (sum / (2 * cs.len()).max(1) as f64).sqrt()
}

/// Line 12 of Algorithm 1: the hole-frame update from the SE(3) mean of the `Delta_i`.
fn paper_update(cs: &[Correspondence], metric: &PoseMetric, form: PaperUpdate) -> Iso {
    let deltas: Vec<Iso> = cs
        .iter()
        .map(|c| metric.unscaled(&symmetric_misalignment(c)).to_iso())
        .collect();
    let mean = se3_mean(&deltas, metric);
    match form {
        PaperUpdate::Consistent => mean.inverse(),
        PaperUpdate::AsPrinted => mean,
    }
}

/// The transposed Jacobian of `delta_i` with respect to the hole-frame update `exp(xi)`,
/// applied to the scaled-coordinate vector `n`: `Jᵀ n`, the gradient direction of the residual
/// `n · delta_i` (scaled coordinates per SI twist).
///
/// `delta(xi) = coords(o⁻¹ exp(xi) q) = coords(exp(Ad(o⁻¹) xi) D)`, so `J = S Jc Ad(o⁻¹)` with
/// `S` the scale factors, `Jc = [[I, -[t_D]x], [0, E⁻¹]]` (a left perturbation of `D` moves its
/// translation by `rho + phi x t_D` and its angles by `E⁻¹ phi`, `E` the roll-pitch-yaw rate map)
/// and `Ad(T) = [[R, [t]x R], [0, R]]`. `Jᵀ n` is computed as three matrix-vector products.
struct MisalignmentJacobian {
    factors: [f64; 6],
    t_d: Vector3<f64>,
    e_inv_t: Matrix3<f64>,
    r_t: Matrix3<f64>,
    p: Vector3<f64>,
}

impl MisalignmentJacobian {
    fn new(c: &Correspondence, factors: &[f64; 6]) -> Self {
        let d = &c.relative;
        let (roll, pitch, yaw) = d.rotation.euler_angles();
        let e_inv = rpy_rate_to_angular_velocity(&Vector3::new(roll, pitch, yaw))
            .try_inverse()
            .unwrap_or_else(Matrix3::zeros);
        let inv = c.observation.inverse();
        MisalignmentJacobian {
            factors: *factors,
            t_d: d.translation.vector,
            e_inv_t: e_inv.transpose(),
            r_t: inv.rotation.to_rotation_matrix().into_inner().transpose(),
            p: inv.translation.vector,
        }
    }

    /// `Jᵀ n`.
    fn transpose_times(&self, n: &[f64; 6]) -> Vector6<f64> {
        let f = &self.factors;
        let v1 = Vector3::new(f[0] * n[0], f[1] * n[1], f[2] * n[2]);
        let v2 = Vector3::new(f[3] * n[3], f[4] * n[4], f[5] * n[5]);
        // Jcᵀ v = (v1, [t_D]x v1 + E⁻ᵀ v2).
        let w1 = v1;
        let w2 = self.t_d.cross(&v1) + self.e_inv_t * v2;
        // Adᵀ w = (Rᵀ w1, Rᵀ (w2 - p x w1)).
        let a1 = self.r_t * w1;
        let a2 = self.r_t * (w2 - self.p.cross(&w1));
        Vector6::new(a1.x, a1.y, a1.z, a2.x, a2.y, a2.z)
    }
}

/// Levenberg damping, relative to the mean diagonal of the normal equations: start, smallest,
/// largest (beyond it no step lowers the cost: converged).
const LM_DAMPING: [f64; 3] = [1e-4, 1e-8, 1e4];
/// The least-squares solver stops after this many rejected steps in a row (no step it can take
/// lowers the cost).
const MAX_REJECTIONS: usize = 3;
/// The least-squares solver stops when an accepted step lowers the cost by less than this
/// fraction (progress along weakly observable directions has stalled).
const COST_TOLERANCE: f64 = 1e-4;
/// A stage that thins the observations keeps them all when thinning would leave this few.
const MIN_COARSE_OBSERVATIONS: usize = 100;

/// The residuals `r_q = n_q · delta` and `r_p = n_p · delta` of every correspondence.
fn residuals(cs: &[Correspondence]) -> Vec<[f64; 2]> {
    cs.iter()
        .map(|c| [dot(&c.delta, &c.n_q), dot(&c.delta, &c.n_p)])
        .collect()
}

/// Huber threshold: `huber_k` robust standard deviations (1.4826 x median |r|).
fn huber_threshold(res: &[[f64; 2]], huber_k: f64) -> f64 {
    let abs: Vec<f64> = res.iter().flatten().map(|r| r.abs()).collect();
    (huber_k * 1.4826 * median(&abs)).max(1e-9)
}

/// Huber cost of the residuals.
fn robust_cost(res: &[[f64; 2]], threshold: f64) -> f64 {
    res.iter()
        .flatten()
        .map(|r| {
            let a = r.abs();
            if a <= threshold {
                0.5 * a * a
            } else {
                threshold * (a - 0.5 * threshold)
            }
        })
        .sum()
}

/// Gauss-Newton normal equations `(H, g)` of the Huber-weighted residuals (IRLS weights).
fn normal_equations(
    cs: &[Correspondence],
    res: &[[f64; 2]],
    factors: &[f64; 6],
    threshold: f64,
) -> (Matrix6<f64>, Vector6<f64>) {
    let mut h = Matrix6::zeros();
    let mut g = Vector6::zeros();
    for (c, r) in cs.iter().zip(res) {
        let jac = MisalignmentJacobian::new(c, factors);
        for (n, r) in [(&c.n_q, r[0]), (&c.n_p, r[1])] {
            let a = jac.transpose_times(n);
            let w = if r.abs() <= threshold {
                1.0
            } else {
                threshold / r.abs()
            };
            h += w * a * a.transpose();
            g += w * r * a;
        }
    }
    (h, g)
}

/// The damped Gauss-Newton step for `(H, g)` as a hole-frame update.
fn damped_step(h: &Matrix6<f64>, g: &Vector6<f64>, damping: f64) -> Iso {
    let lhs = h + Matrix6::identity() * (damping * h.trace() / 6.0).max(1e-300);
    let xi = lhs
        .cholesky()
        .map(|ch| -ch.solve(g))
        .unwrap_or_else(Vector6::zeros);
    se3_exp(&xi)
}

/// Where a run stands: estimate, observations in its hole frame, their correspondences.
struct RunState {
    estimate: Iso,
    obs_h: Vec<Iso>,
    cs: Vec<Correspondence>,
}

impl RunState {
    /// Lines 13-14: apply a hole-frame update to the estimate and the observations, and find the
    /// new correspondences.
    fn updated(
        &self,
        update: &Iso,
        manifold: &Manifold,
        k: usize,
        search: &mut SearchState,
    ) -> RunState {
        let back = update.inverse();
        let obs_h: Vec<Iso> = self.obs_h.iter().map(|o| back * o).collect();
        let cs = correspondences(manifold, &obs_h, k, search);
        RunState {
            estimate: self.estimate * update,
            obs_h,
            cs,
        }
    }
}

/// Where a run starts: line 3's initial alignment of `observations` by `estimate`, and the
/// correspondences found there at `resolution`.
fn aligned(
    manifold: &Manifold,
    observations: &[Iso],
    estimate: Iso,
    resolution: Resolution,
    k: usize,
) -> (RunState, SearchState) {
    // Line 3: initial alignment.
    let inv = estimate.inverse();
    let obs_h: Vec<Iso> = observations.iter().map(|o| inv * o).collect();
    let mut search = SearchState::new(obs_h.len(), resolution);
    let cs = correspondences(manifold, &obs_h, k, &mut search);
    let state = RunState {
        estimate,
        obs_h,
        cs,
    };
    (state, search)
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
    RestartResult {
        initial: Pose6::from_iso(&start),
        estimate: Pose6::from_iso(&state.estimate),
        iterations: step_mm.len(),
        residual_mm: rms_residual(&state.cs),
        step_mm,
        rejected: false,
    }
}

/// Algorithm 1's loop (lines 4-15) with the paper's update.
fn run_paper(
    manifold: &Manifold,
    mut state: RunState,
    search: &mut SearchState,
    cfg: &RegistrationConfig,
) -> (RunState, Vec<f64>) {
    let metric = manifold.meta.metric;
    let mut steps = Vec::with_capacity(cfg.iterations);
    for _ in 0..cfg.iterations {
        // Lines 10-12.
        let update = paper_update(&state.cs, &metric, cfg.paper_update);
        let step = metric.twist_norm(&se3_log(&update));
        steps.push(step);
        if !step.is_finite() {
            break;
        }
        // Lines 13-14, then lines 6-9 of the next iteration.
        state = state.updated(&update, manifold, cfg.normal_k, search);
        if step < cfg.tolerance_mm {
            break;
        }
    }
    (state, steps)
}

/// The least-squares solver's stages, coarse to fine: (every how-many-th observation, manifold
/// resolution, the step size below which the stage hands over, mm-eq). Far from the manifold a
/// nearest-neighbour search visits much of the tree and every observation costs the same; a
/// quarter of the observations against a sixty-fourth of the manifold brings the estimate close
/// cheaply, all observations against the coarse manifold settle the weakly observable directions,
/// and the full manifold finishes.
const STAGES: [(usize, Resolution, Option<f64>); 3] = [
    (4, Resolution::Coarse, Some(0.1)),
    (1, Resolution::Coarse, Some(0.05)),
    (1, Resolution::Full, None),
];

/// Levenberg-Marquardt on the symmetric point-to-plane residuals through [`STAGES`]; each stage
/// but the last may use at most a third of the iterations. Every proposed step counts as an
/// iteration.
fn run_least_squares(
    manifold: &Manifold,
    observations: &[Iso],
    start: Iso,
    cfg: &RegistrationConfig,
) -> (RunState, Vec<f64>) {
    let mut steps = Vec::with_capacity(cfg.iterations);
    let mut estimate = start;
    let mut last = None;
    for (stride, resolution, hand_over) in STAGES {
        let subset: Vec<Iso> = observations.iter().step_by(stride).copied().collect();
        let obs = if subset.len() > cfg.normal_k.max(MIN_COARSE_OBSERVATIONS) {
            subset
        } else {
            observations.to_vec()
        };
        let (state, mut search) = aligned(manifold, &obs, estimate, resolution, cfg.normal_k);
        let budget = match hand_over {
            Some(_) => cfg.iterations.div_ceil(3).min(cfg.iterations - steps.len()),
            None => cfg.iterations - steps.len(),
        };
        let tolerance = hand_over.unwrap_or(cfg.tolerance_mm);
        let (state, stage_steps) =
            levenberg_marquardt(manifold, state, &mut search, cfg, budget, tolerance);
        steps.extend(stage_steps);
        estimate = state.estimate;
        last = Some(state);
    }
    (last.expect("at least one stage"), steps)
}

/// Levenberg-Marquardt iterations from `state`: a step is kept only if it lowers the Huber cost
/// with the correspondences found at the new pose; otherwise the damping grows and the step
/// shrinks. Stops after `budget` steps, when a step is below `tolerance_mm`, when a kept step
/// lowers the cost by less than [`COST_TOLERANCE`], or after [`MAX_REJECTIONS`] refusals in a row.
fn levenberg_marquardt(
    manifold: &Manifold,
    mut state: RunState,
    search: &mut SearchState,
    cfg: &RegistrationConfig,
    budget: usize,
    tolerance_mm: f64,
) -> (RunState, Vec<f64>) {
    let metric = manifold.meta.metric;
    let factors = metric.factors();
    let mut steps = Vec::with_capacity(budget);
    let mut damping = LM_DAMPING[0];
    let mut rejections = 0;
    let linearise = |state: &RunState| {
        let res = residuals(&state.cs);
        let threshold = huber_threshold(&res, cfg.huber_k);
        let (h, g) = normal_equations(&state.cs, &res, &factors, threshold);
        (res, threshold, h, g)
    };
    let (mut res, mut threshold, mut h, mut g) = linearise(&state);
    while steps.len() < budget {
        let update = damped_step(&h, &g, damping);
        let step = metric.twist_norm(&se3_log(&update));
        steps.push(step);
        let trial = state.updated(&update, manifold, cfg.normal_k, search);
        let (old_cost, new_cost) = (
            robust_cost(&res, threshold),
            robust_cost(&residuals(&trial.cs), threshold),
        );
        let accepted = new_cost <= old_cost;
        let done = if accepted {
            state = trial;
            rejections = 0;
            damping = (damping * 0.1).max(LM_DAMPING[1]);
            step < tolerance_mm || old_cost - new_cost < COST_TOLERANCE * old_cost
        } else {
            rejections += 1;
            damping *= 10.0;
            damping > LM_DAMPING[2] || rejections >= MAX_REJECTIONS || step < tolerance_mm
        };
        if done || !step.is_finite() {
            break;
        }
        if accepted {
            (res, threshold, h, g) = linearise(&state);
        }
    }
    (state, steps)
}

/// Reject outlying restarts (MAD) and return the SE(3) mean of the others.
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
    let kept: Vec<Iso> = results
        .iter()
        .zip(&all)
        .filter(|(r, _)| !r.rejected)
        .map(|(_, t)| *t)
        .collect();
    if kept.is_empty() {
        centre
    } else {
        se3_mean(&kept, metric)
    }
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
    use crate::method::manifold::synthetic::SyntheticPair;
    use crate::method::manifold::{ManifoldMeta, UNITS};

    fn small_manifold() -> Manifold {
        let pair = SyntheticPair::square(0.02, 0.5e-3);
        let pts = pair.sample_contacts(3000, [0.002, 0.010], 1);
        Manifold::from_points(
            pts,
            ManifoldMeta {
                geometry: pair.name.clone(),
                clearance_m: Some(pair.clearance_m),
                units: UNITS.into(),
                metric: PoseMetric::default(),
                normal_k: 12,
                source: "test".into(),
                seed: Some(1),
            },
        )
        .unwrap()
    }

    #[test]
    fn mad_rejects_the_outlying_restart() {
        let metric = PoseMetric::default();
        let result = |p: [f64; 6]| RestartResult {
            initial: Pose6::IDENTITY,
            estimate: Pose6(p),
            iterations: 1,
            step_mm: vec![],
            residual_mm: 0.0,
            rejected: false,
        };
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

    #[test]
    fn jacobian_matches_finite_differences() {
        let m = small_manifold();
        let metric = m.meta.metric;
        let o = Pose6([0.3, -0.1, 0.5, 3.0, 0.02, -0.4]).to_iso();
        let q = Pose6([1e-4, -2e-4, -0.004, 0.003, -0.002, 0.004]).to_iso();
        let c = Correspondence {
            delta: [0.0; 6],
            relative: o.inverse() * q,
            observation: o,
            n_q: [0.0; 6],
            n_p: [0.0; 6],
        };
        let jac = MisalignmentJacobian::new(&c, &metric.factors());
        let coords = |xi: &Vector6<f64>| {
            let p = metric.scaled(&Pose6::from_iso(&(o.inverse() * se3_exp(xi) * q)));
            Vector6::from_column_slice(&p)
        };
        let h = 1e-7;
        for k in 0..6 {
            let mut e = Vector6::zeros();
            e[k] = h;
            let fd = (coords(&e) - coords(&-e)) / (2.0 * h);
            // Column k of J is (Jᵀ e_i)_k over the rows i.
            let col = Vector6::from_fn(|i, _| {
                let mut unit = [0.0; 6];
                unit[i] = 1.0;
                jac.transpose_times(&unit)[k]
            });
            let err = (fd - col).norm() / fd.norm().max(1.0);
            assert!(err < 1e-5, "column {k}: {fd} vs {col}");
        }
    }
}
