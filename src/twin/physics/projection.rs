//! Position projection of the arm's peg (post-stabilisation: M. B. Cline and D. K. Pai,
//! "Post-stabilization for rigid body simulation with contact and constraints", ICRA 2003; the
//! position passes of Box2D's and PhysX's solvers do the same job). After rapier's
//! velocity-level step, what the peg's exact convex pieces still overlap of the hole's is moved
//! out by the joint displacement that moves the peg least, subject to every nearby piece pair's
//! gap ending at least `-PROJECTION_TOLERANCE_M`. Velocities are left alone, so the step's
//! momentum and its contact impulses (the measured wrench) are what the solver computed; what is
//! removed is the penetration that rapier's soft contact keeps under a sustained wedge (a spring
//! of the row's projected mass times omega^2: 12-95 um under a few hundred newtons in the
//! motion cases of `validate --arm`, docs/journal/2026-11-23.md "The arm at 0.1 mm"), which at a 0.1 mm fit
//! is a fifth of the gap. The arm cell runs it when `PhysicsParams::position_projection` is set.
//! Experimental: it makes the campaigns' estimates worse and their insertions jam (measured in
//! docs/physics.md), and the twisted gear's rows can admit no displacement at all.
//!
//! - The rows come from the exact pieces in f64 (`penetration::PenetrationProbe::gap_rows`): per
//!   piece pair, the axis of least overlap, the direction that opens it and the peg's deepest
//!   vertex along it. rapier's own solver contacts were tried first and do not serve: they are
//!   the step's start, and a peg that slid along a wall in the step carries contact points past
//!   the faces they were made on (measured: a projection on them left the exact depth at 5-25 um
//!   where the rows said 0.6 um).
//! - The metric is the peg's displacement, `J^T diag(1, 1, 1, r^2, r^2, r^2) J` at the TCP with
//!   `r` the peg's reach, plus a trace of the inertia for the arm's self-motion. The inertia
//!   metric alone (Cline and Pai's) turns the wrist, the cheapest joint, and swings the peg into
//!   walls no row saw (measured: the probing case went from 15 to 53 um).
//! - The problem, `min |dq|_W` subject to `A dq >= b`, is a least-distance program in
//!   `y = L^T dq`; it is solved exactly by Lawson and Hanson's reduction to non-negative least
//!   squares. A projected Gauss-Seidel on its dual needed thousands of sweeps on a wedged peg.
//! - A linearisation: the cell runs up to three rounds, each on rows measured afresh.

use super::penetration::GapRow;
use crate::twin::robot::{Iso, Kinematics, RobotModel};
use nalgebra::{DMatrix, DVector};

/// A pair may stay this far inside (metres) after the projection.
pub const PROJECTION_TOLERANCE_M: f64 = 0.5e-6;
/// The projection runs only when some pair is deeper than this (metres).
pub const PROJECTION_TRIGGER_M: f64 = 1.0e-6;
/// The exact pieces are consulted only when one of the solver's contacts is deeper than this
/// (metres): on a peg at rest or sliding freely, the projection costs one pass over the
/// solver's contacts.
pub const SOLVER_TRIGGER_M: f64 = 0.5e-6;
/// The pairs a projection looks at are those within this (metres) plus three times the depth it
/// removes: a least displacement moves the peg about as far as the depth, and whatever a round
/// pushes into beyond that is found by the next round.
const REACH_FLOOR_M: f64 = 5e-6;
/// Weight of the arm's inertia (1/kg) in the metric, against the peg's displacement (m^2).
const SELF_MOTION_WEIGHT: f64 = 1e-6;
/// Steps of the active-set solver at most, and its tolerance on the gradient.
const MAX_ACTIVE_SET_STEPS: usize = 64;
const NNLS_TOLERANCE: f64 = 1e-12;

/// How far apart (metres) the piece pairs of a projection that removes `depth_m` may be.
pub fn reach_m(depth_m: f64) -> f64 {
    REACH_FLOOR_M + 3.0 * depth_m
}

/// The joint displacement (rad, or m on prismatic joints) that takes every row of `rows` to a gap
/// of at least `-PROJECTION_TOLERANCE_M` and moves the peg least (its points within
/// `peg_reach_m` of the TCP) for `model` at `q` (`world_t_base` places the arm; the rows are
/// carried by its last link). `None` when no row is deeper than `PROJECTION_TRIGGER_M`, or when
/// the rows admit no displacement (the penetration then stays, for the cell's checks to see).
pub fn projection(
    model: &RobotModel,
    q: &[f64],
    world_t_base: &Iso,
    rows: &[GapRow],
    peg_reach_m: f64,
) -> Option<DVector<f64>> {
    if !rows.iter().any(|r| r.gap_m < -PROJECTION_TRIGGER_M) {
        return None;
    }
    let k = model.kinematics(q);
    let last = model.dof() - 1;
    let base_t_world = world_t_base.inverse();
    // A: one row per contact, the opening speed of its point per joint speed.
    let mut a = DMatrix::zeros(rows.len(), model.dof());
    for (i, r) in rows.iter().enumerate() {
        let jac = model.point_jacobian(&k, &(base_t_world * r.point), last);
        let n = base_t_world.rotation * r.opening;
        a.row_mut(i)
            .copy_from(&(n.transpose() * jac.fixed_rows::<3>(0)));
    }
    // In y = L^T dq (M = L L^T) the cost is |y|^2 / 2 and the rows become G = A L^-T: a
    // least-distance problem, solved in micrometres.
    let l = displacement_metric(model, &k, peg_reach_m).cholesky()?.l();
    let g_t = l.solve_lower_triangular(&a.transpose())?;
    let h: Vec<f64> = rows
        .iter()
        .map(|r| (-PROJECTION_TOLERANCE_M - r.gap_m) * 1e6)
        .collect();
    let y = least_distance(&g_t, &h)? * 1e-6;
    l.transpose().solve_upper_triangular(&y)
}

/// The metric of the projection, `J^T diag(1, 1, 1, r^2, r^2, r^2) J + eps M` at the TCP: the
/// squared displacement of the peg's points within `reach_m` of the TCP, and a little of the
/// arm's inertia so that the arm's self-motion costs something.
fn displacement_metric(model: &RobotModel, k: &Kinematics, reach_m: f64) -> DMatrix<f64> {
    let jac = model.tcp_jacobian(k);
    let mut weighted = jac.clone();
    for r in 3..6 {
        weighted.row_mut(r).scale_mut(reach_m * reach_m);
    }
    jac.tr_mul(&weighted) + model.mass_matrix(k) * SELF_MOTION_WEIGHT
}

/// The shortest `y` with `G y >= h` (`g_t` is `G^T`, n x m), by Lawson and Hanson's reduction of
/// least-distance programming to non-negative least squares (Solving Least Squares Problems,
/// 1974, ch. 23): with `E = [G^T; h^T]` and `f = (0, .., 0, 1)`, the NNLS residual
/// `r = E u - f` gives `y = -r[..n] / r[n]`. `None` when the rows admit no solution.
fn least_distance(g_t: &DMatrix<f64>, h: &[f64]) -> Option<DVector<f64>> {
    let n = g_t.nrows();
    let mut e = g_t.clone().insert_row(n, 0.0);
    e.row_mut(n).copy_from_slice(h);
    let mut f = DVector::zeros(n + 1);
    f[n] = 1.0;
    let u = nnls(&e, &f);
    let r = &e * u - f;
    if r[n].abs() < 1e-12 {
        return None;
    }
    Some(r.rows(0, n) * (-1.0 / r[n]))
}

/// Non-negative least squares, `min |E u - f|, u >= 0`, by Lawson and Hanson's active-set
/// algorithm (ibid., ch. 23); the passive set never holds more columns than `E` has rows.
fn nnls(e: &DMatrix<f64>, f: &DVector<f64>) -> DVector<f64> {
    let m = e.ncols();
    let mut u = DVector::zeros(m);
    let mut passive = vec![false; m];
    for _ in 0..MAX_ACTIVE_SET_STEPS {
        let w = e.tr_mul(&(f - e * &u));
        let Some(t) = (0..m)
            .filter(|&j| !passive[j] && w[j] > NNLS_TOLERANCE)
            .max_by(|&a, &b| w[a].total_cmp(&w[b]))
        else {
            break;
        };
        passive[t] = true;
        loop {
            let z = passive_least_squares(e, f, &passive);
            let blocking = (0..m)
                .filter(|&j| passive[j] && z[j] <= 0.0)
                .map(|j| u[j] / (u[j] - z[j]))
                .min_by(|a, b| a.total_cmp(b));
            let Some(alpha) = blocking else {
                u = z;
                break;
            };
            u += (z - &u) * alpha;
            for j in 0..m {
                if passive[j] && u[j] <= NNLS_TOLERANCE {
                    passive[j] = false;
                    u[j] = 0.0;
                }
            }
        }
    }
    u
}

/// The unconstrained least-squares solution on the passive columns, zero elsewhere.
fn passive_least_squares(e: &DMatrix<f64>, f: &DVector<f64>, passive: &[bool]) -> DVector<f64> {
    let cols: Vec<usize> = (0..passive.len()).filter(|&j| passive[j]).collect();
    let sub = e.select_columns(&cols);
    let z_p = sub
        .svd(true, true)
        .solve(f, 1e-12)
        .expect("the SVD was computed with both factors");
    let mut z = DVector::zeros(passive.len());
    for (k, &j) in cols.iter().enumerate() {
        z[j] = z_p[k];
    }
    z
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::twin::robot::urdf::iiwa14;
    use nalgebra::{Point3, Vector3};

    #[test]
    fn least_distance_finds_the_shortest_point_of_a_polyhedron() {
        // y0 >= 1 and y0 + y1 >= 3: the nearest point is (1.5, 1.5), the first row inactive.
        let g_t = DMatrix::from_row_slice(2, 2, &[1.0, 1.0, 0.0, 1.0]);
        let y = least_distance(&g_t, &[1.0, 3.0]).unwrap();
        assert!(
            (y[0] - 1.5).abs() < 1e-12 && (y[1] - 1.5).abs() < 1e-12,
            "{y}"
        );
        // y0 >= 2 and -y0 >= -1 admit nothing.
        let g_t = DMatrix::from_row_slice(1, 2, &[1.0, -1.0]);
        assert!(least_distance(&g_t, &[2.0, -1.0]).is_none());
    }

    #[test]
    fn a_peg_tip_5_um_inside_a_wall_is_moved_out_by_5_um_and_no_further() {
        let model = iiwa14().unwrap();
        let q = [0.1, 0.6, -0.1, -1.2, 0.05, 0.9, 0.2];
        let tcp = model.tcp_pose(&q);
        let tip = Point3::from(tcp.translation.vector);
        // Pressed 5 um into a wall whose normal is +x, and 20 um from a wall on the other side.
        let rows = [
            GapRow {
                point: tip,
                opening: Vector3::x(),
                gap_m: -5e-6,
            },
            GapRow {
                point: tip,
                opening: -Vector3::x(),
                gap_m: 20e-6,
            },
        ];
        let dq = projection(&model, &q, &Iso::identity(), &rows, 0.05).unwrap();
        let moved: Vec<f64> = q.iter().zip(dq.iter()).map(|(a, b)| a + b).collect();
        let shift = model.tcp_pose(&moved).translation.vector - tcp.translation.vector;
        let out = 5e-6 - PROJECTION_TOLERANCE_M;
        assert!((shift.x - out).abs() < 0.05e-6, "{shift}");
        assert!(
            shift.y.abs() < 0.05e-6 && shift.z.abs() < 0.05e-6,
            "{shift}"
        );
        let none = [GapRow {
            gap_m: -0.5e-6,
            ..rows[0]
        }];
        assert!(projection(&model, &q, &Iso::identity(), &none, 0.05).is_none());
    }
}
