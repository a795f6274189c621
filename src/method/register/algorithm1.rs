//! Algorithm 1 of the paper (Section IV-D), line by line: the loop of one restart with the
//! paper's update. The correspondences of lines 6-9 are [`super::correspondence`]'s; the
//! least-squares solver ([`super::least_squares`]) shares lines 3, 6-9 and 13-14.
//!
//! # Line by line ([`run_paper`], from [`super::run_from`])
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

use super::correspondence::{Correspondence, SearchState, correspondences, dot};
use super::{PaperUpdate, RegistrationConfig};
use crate::method::manifold::{Manifold, Resolution};
use crate::pose::{Iso, PoseMetric, se3_log, se3_mean};

/// Line 10: the symmetric point-to-plane misalignment, scaled coordinates.
pub(super) fn symmetric_misalignment(c: &Correspondence) -> [f64; 6] {
    let (a, b) = (dot(&c.delta, &c.n_q), dot(&c.delta, &c.n_p));
    std::array::from_fn(|i| 0.5 * (a * c.n_q[i] + b * c.n_p[i]))
}

/// Line 12 of Algorithm 1: the hole-frame update from the SE(3) mean of the `Delta_i`.
pub(super) fn paper_update(cs: &[Correspondence], metric: &PoseMetric, form: PaperUpdate) -> Iso {
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

/// Where a run stands: estimate, observations in its hole frame, their correspondences.
pub(super) struct RunState {
    pub(super) estimate: Iso,
    pub(super) obs_h: Vec<Iso>,
    pub(super) cs: Vec<Correspondence>,
}

impl RunState {
    /// Lines 13-14: apply a hole-frame update to the estimate and the observations, and find the
    /// new correspondences.
    pub(super) fn updated(
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
pub(super) fn aligned(
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

/// Algorithm 1's loop (lines 4-15) with the paper's update.
pub(super) fn run_paper(
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
