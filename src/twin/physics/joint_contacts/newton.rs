//! Newton's method on the solve's convex cost: the gradient and Hessian of the rows' terms, the
//! safeguarded line search, and the small kernels unrolled for the iiwa's seven joints.

use super::rows::{JointRows, Rows, slip};
use nalgebra::{DMatrix, DVector};
use rapier3d::prelude::*;

/// Newton iterations at most per solve, and the joint-speed change (rad/s) below which a step
/// ends the solve.
pub(super) const MAX_NEWTON_STEPS: usize = 30;
pub(super) const NEWTON_TOLERANCE: f64 = 1e-10;
/// Iterations at most of the line search, and the slope (relative to the slope at its start) at
/// which it stops.
pub(super) const MAX_LINE_STEPS: usize = 30;
pub(super) const LINE_TOLERANCE: f64 = 1e-3;

/// The buffers of Newton's method, kept from one step to the next (the solve allocates per
/// step only the rows it takes).
pub(super) struct NewtonBuffers {
    /// `v - v_free`, rad/s.
    pub(super) dv: DVector<f64>,
    /// The cost's gradient (N m s) and the Newton step (rad/s).
    pub(super) grad: DVector<f64>,
    pub(super) delta: DVector<f64>,
    /// `M delta`, N m s.
    pub(super) m_delta: DVector<f64>,
    /// The cost's Hessian (kg m^2), then its Cholesky factor.
    pub(super) hess: DMatrix<f64>,
    /// A row times its Hessian weight.
    pub(super) weighted: Vec<f64>,
    /// The rows' speeds along the Newton step.
    pub(super) sigma: Vec<[f64; 3]>,
}

impl NewtonBuffers {
    pub(super) fn new(n: usize) -> Self {
        NewtonBuffers {
            dv: DVector::zeros(n),
            grad: DVector::zeros(n),
            delta: DVector::zeros(n),
            m_delta: DVector::zeros(n),
            hess: DMatrix::zeros(n, n),
            weighted: vec![0.0; n],
            sigma: Vec::new(),
        }
    }
}

/// Newton's method on the convex cost of the module doc, from `v` whose rows' speeds are
/// `speeds` (both kept up to date); returns the steps taken.
pub(super) fn minimise(
    mass: &DMatrix<f64>,
    v_free: &DVector<f64>,
    (rows, joints): (&Rows, Option<&JointRows>),
    v: &mut DVector<f64>,
    speeds: &mut [[f64; 3]],
    buf: &mut NewtonBuffers,
) -> usize {
    for step in 1..=MAX_NEWTON_STEPS {
        newton_system(mass, v_free, rows, v, speeds, buf);
        if let Some(j) = joints {
            add_joint_friction(j, v, buf);
        }
        let hess = std::mem::replace(&mut buf.hess, DMatrix::zeros(0, 0));
        let Some(h) = hess.cholesky() else {
            buf.hess = DMatrix::zeros(v.len(), v.len());
            return step;
        };
        buf.delta.copy_from(&buf.grad);
        h.solve_mut(&mut buf.delta);
        buf.delta.neg_mut();
        buf.hess = h.unpack_dirty();
        rows.speeds_into(&buf.delta, &mut buf.sigma);
        mass.mul_to(&buf.delta, &mut buf.m_delta);
        let alpha = line_search(
            (rows, joints),
            (&buf.dv, &buf.delta, &buf.m_delta),
            (v, speeds),
            &buf.sigma,
        );
        for (vi, di) in v.as_mut_slice().iter_mut().zip(buf.delta.as_slice()) {
            *vi += di * alpha;
        }
        for (s, d) in speeds.iter_mut().zip(&buf.sigma) {
            for k in 0..3 {
                s[k] += alpha * d[k];
            }
        }
        if buf.delta.amax() * alpha < NEWTON_TOLERANCE {
            return step;
        }
    }
    MAX_NEWTON_STEPS
}

/// The cost's gradient and Hessian at `v` (rows' speeds `speeds`), into `buf.grad` and
/// `buf.hess` (and `v - v_free` into `buf.dv`).
pub(super) fn newton_system(
    mass: &DMatrix<f64>,
    v_free: &DVector<f64>,
    rows: &Rows,
    v: &DVector<f64>,
    speeds: &[[f64; 3]],
    buf: &mut NewtonBuffers,
) {
    let dv = buf.dv.as_mut_slice();
    for ((d, a), b) in dv.iter_mut().zip(v.as_slice()).zip(v_free.as_slice()) {
        *d = a - b;
    }
    mass.mul_to(&buf.dv, &mut buf.grad);
    buf.hess.copy_from(mass);
    let grad = buf.grad.as_mut_slice();
    let (hess, weighted) = (buf.hess.as_mut_slice(), &mut buf.weighted);
    // Adds row `r`'s impulse `g` to the gradient and `w` times row `r` by row `r2` to the
    // Hessian (column-major), for each `(r2, w)` of `h`.
    let mut add = |r: usize, g: f64, h: &[(usize, f64)]| {
        let a = rows.row(r);
        for (gi, ai) in grad.iter_mut().zip(a) {
            *gi -= g * ai;
        }
        for &(r2, w) in h.iter().filter(|(_, w)| *w != 0.0) {
            for (wa, ai) in weighted.iter_mut().zip(a) {
                *wa = w * ai;
            }
            add_outer(hess, weighted, rows.row(r2));
        }
    };
    for (c, s) in speeds.iter().enumerate() {
        let normal = rows.normal_impulse(c, s[0]);
        if normal > 0.0 {
            add(3 * c, normal, &[(3 * c, rows.normal_weight[c])]);
        }
        if rows.bound[c] <= 0.0 {
            continue; // no friction yet (no curvature, zero impulses)
        }
        let slip = slip(s);
        let p = rows.impulses_at(c, s, slip);
        let (t1, t2) = (3 * c + 1, 3 * c + 2);
        if let Some([h11, h12, h22]) = rows.friction_curvature(c, s, slip) {
            add(t1, p[1], &[(t1, h11), (t2, h12)]);
            add(t2, p[2], &[(t2, h22), (t1, h12)]);
        }
    }
    symmetrise_lower(&mut buf.hess);
}

/// Adds the joints' friction at `v` to the gradient and the Hessian's diagonal in `buf`.
pub(super) fn add_joint_friction(joints: &JointRows, v: &DVector<f64>, buf: &mut NewtonBuffers) {
    let n = v.len();
    for i in 0..n {
        buf.grad[i] -= joints.impulse(i, v[i]);
        buf.hess[(i, i)] += joints.curvature(i, v[i]);
    }
    debug_assert_eq!(buf.hess.nrows(), n);
}

/// `hess += wa b^T` (column-major, `wa.len()` rows) over whole columns: the Hessian's upper
/// triangle gets sums of its own, which [`symmetrise_lower`] then overwrites with the lower's.
/// Unrolled for the iiwa's seven joints; any other count takes the loop.
pub(super) fn add_outer(hess: &mut [f64], wa: &[f64], b: &[f64]) {
    if let (Ok(wa), 49) = (<&[f64; 7]>::try_from(wa), hess.len()) {
        for (column, bj) in hess.as_chunks_mut::<7>().0.iter_mut().zip(b) {
            for (h_ij, wa_i) in column.iter_mut().zip(wa) {
                *h_ij += wa_i * bj;
            }
        }
    } else {
        for (column, bj) in hess.chunks_exact_mut(wa.len()).zip(b) {
            for (h_ij, wa_i) in column.iter_mut().zip(wa) {
                *h_ij += wa_i * bj;
            }
        }
    }
}

/// Copies the lower triangle (where the Hessian is summed) onto the upper.
pub(super) fn symmetrise_lower(m: &mut DMatrix<f64>) {
    for i in 0..m.nrows() {
        for j in 0..i {
            m[(j, i)] = m[(i, j)];
        }
    }
}

/// The minimiser along `v + alpha delta` (alpha >= 0): the cost's derivative there increases
/// with alpha; safeguarded Newton on it within a bracket. `dv` is `v - v_free`, `m_delta` is
/// `M delta`; `s0` and `sd` are the rows' speeds at `v` and along `delta`.
pub(super) fn line_search(
    (rows, joints): (&Rows, Option<&JointRows>),
    (dv, delta, m_delta): (&DVector<f64>, &DVector<f64>, &DVector<f64>),
    (v, s0): (&DVector<f64>, &[[f64; 3]]),
    sd: &[[f64; 3]],
) -> f64 {
    let (a0, a1) = (m_delta.dot(dv), m_delta.dot(delta));
    // phi'(alpha) and phi''(alpha).
    let slope = |alpha: f64| {
        let (mut d1, mut d2) = (a0 + a1 * alpha, a1);
        for (c, (s, sigma)) in s0.iter().zip(sd).enumerate() {
            let at: [f64; 3] = std::array::from_fn(|k| s[k] + alpha * sigma[k]);
            if rows.bound[c] <= 0.0 {
                // No friction yet: its impulses are signed zeros, which leave every non-zero
                // sum as it is (a zero `d1` may change its sign only, which no test below sees).
                let normal = rows.normal_impulse(c, at[0]);
                d1 -= normal * sigma[0];
                if normal > 0.0 {
                    d2 += rows.normal_weight[c] * sigma[0] * sigma[0];
                }
                continue;
            }
            let slip = slip(&at);
            let p = rows.impulses_at(c, &at, slip);
            d1 -= p[0] * sigma[0] + p[1] * sigma[1] + p[2] * sigma[2];
            if p[0] > 0.0 {
                d2 += rows.normal_weight[c] * sigma[0] * sigma[0];
            }
            if let Some([h11, h12, h22]) = rows.friction_curvature(c, &at, slip) {
                d2 += h11 * sigma[1] * sigma[1]
                    + 2.0 * h12 * sigma[1] * sigma[2]
                    + h22 * sigma[2] * sigma[2];
            }
        }
        if let Some(j) = joints {
            for (i, (vi, di)) in v.iter().zip(delta.iter()).enumerate() {
                let at = vi + alpha * di;
                d1 -= j.impulse(i, at) * di;
                d2 += j.curvature(i, at) * di * di;
            }
        }
        (d1, d2)
    };
    let (d0, _) = slope(0.0);
    if d0 >= 0.0 {
        return 0.0;
    }
    // Newton's step (alpha = 1) is the minimiser while no row changes state, so start there;
    // bisection keeps the iterate inside the bracket [lo, hi] where the slope changes sign.
    let (mut lo, mut hi) = (0.0, f64::INFINITY);
    let mut alpha = 1.0;
    for _ in 0..MAX_LINE_STEPS {
        let (d1, d2) = slope(alpha);
        if d1.abs() <= LINE_TOLERANCE * d0.abs() {
            break;
        }
        if d1 < 0.0 {
            lo = alpha;
        } else {
            hi = alpha;
        }
        let newton = alpha - d1 / d2;
        alpha = if d2 > 0.0 && newton > lo && newton < hi {
            newton
        } else if hi.is_finite() {
            0.5 * (lo + hi)
        } else {
            2.0 * alpha
        };
    }
    alpha
}
