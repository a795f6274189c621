//! The least-squares solver on Algorithm 1's residuals (Section IV-D).
//!
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

use super::algorithm1::{RunState, aligned};
use super::correspondence::{Correspondence, SearchState, dot};
use super::{RegistrationConfig, median};
use crate::method::manifold::{Manifold, Resolution};
use crate::pose::{Iso, rpy_rate_to_angular_velocity, se3_exp, se3_log};
use nalgebra::{Matrix3, Matrix6, Vector3, Vector6};

/// The transposed Jacobian of `delta_i` with respect to the hole-frame update `exp(xi)`,
/// applied to the scaled-coordinate vector `n`: `Jᵀ n`, the gradient direction of the residual
/// `n · delta_i` (scaled coordinates per SI twist).
///
/// `delta(xi) = coords(o⁻¹ exp(xi) q) = coords(exp(Ad(o⁻¹) xi) D)`, so `J = S Jc Ad(o⁻¹)` with
/// `S` the scale factors, `Jc = [[I, -[t_D]x], [0, E⁻¹]]` (a left perturbation of `D` moves its
/// translation by `rho + phi x t_D` and its angles by `E⁻¹ phi`, `E` the roll-pitch-yaw rate map)
/// and `Ad(T) = [[R, [t]x R], [0, R]]`. `Jᵀ n` is computed as three matrix-vector products.
pub(super) struct MisalignmentJacobian {
    factors: [f64; 6],
    t_d: Vector3<f64>,
    e_inv_t: Matrix3<f64>,
    r_t: Matrix3<f64>,
    p: Vector3<f64>,
}

impl MisalignmentJacobian {
    pub(super) fn new(c: &Correspondence, factors: &[f64; 6]) -> Self {
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
    pub(super) fn transpose_times(&self, n: &[f64; 6]) -> Vector6<f64> {
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
pub(super) const LM_DAMPING: [f64; 3] = [1e-4, 1e-8, 1e4];
/// The least-squares solver stops after this many rejected steps in a row (no step it can take
/// lowers the cost).
pub(super) const MAX_REJECTIONS: usize = 3;
/// The least-squares solver stops when an accepted step lowers the cost by less than this
/// fraction (progress along weakly observable directions has stalled).
pub(super) const COST_TOLERANCE: f64 = 1e-4;
/// A stage that thins the observations keeps them all when thinning would leave this few.
pub(super) const MIN_COARSE_OBSERVATIONS: usize = 100;

/// The residuals `r_q = n_q · delta` and `r_p = n_p · delta` of every correspondence.
pub(super) fn residuals(cs: &[Correspondence]) -> Vec<[f64; 2]> {
    cs.iter()
        .map(|c| [dot(&c.delta, &c.n_q), dot(&c.delta, &c.n_p)])
        .collect()
}

/// Huber threshold: `huber_k` robust standard deviations (1.4826 x median |r|).
pub(super) fn huber_threshold(res: &[[f64; 2]], huber_k: f64) -> f64 {
    let abs: Vec<f64> = res.iter().flatten().map(|r| r.abs()).collect();
    (huber_k * 1.4826 * median(&abs)).max(1e-9)
}

/// Huber cost of the residuals.
pub(super) fn robust_cost(res: &[[f64; 2]], threshold: f64) -> f64 {
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
pub(super) fn normal_equations(
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
pub(super) fn damped_step(h: &Matrix6<f64>, g: &Vector6<f64>, damping: f64) -> Iso {
    let lhs = h + Matrix6::identity() * (damping * h.trace() / 6.0).max(1e-300);
    let xi = lhs
        .cholesky()
        .map(|ch| -ch.solve(g))
        .unwrap_or_else(Vector6::zeros);
    se3_exp(&xi)
}

/// The least-squares solver's stages, coarse to fine: (every how-many-th observation, manifold
/// resolution, the step size below which the stage hands over, mm-eq). Far from the manifold a
/// nearest-neighbour search visits much of the tree and every observation costs the same; a
/// quarter of the observations against a sixty-fourth of the manifold brings the estimate close
/// cheaply, all observations against the coarse manifold settle the weakly observable directions,
/// and the full manifold finishes.
pub(super) const STAGES: [(usize, Resolution, Option<f64>); 3] = [
    (4, Resolution::Coarse, Some(0.1)),
    (1, Resolution::Coarse, Some(0.05)),
    (1, Resolution::Full, None),
];

/// Levenberg-Marquardt on the symmetric point-to-plane residuals through [`STAGES`]; each stage
/// but the last may use at most a third of the iterations. Every proposed step counts as an
/// iteration.
pub(super) fn run_least_squares(
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
pub(super) fn levenberg_marquardt(
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pose::{Pose6, PoseMetric, se3_exp};

    #[test]
    fn jacobian_matches_finite_differences() {
        let metric = PoseMetric::default();
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
