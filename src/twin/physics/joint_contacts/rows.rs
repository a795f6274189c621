//! The solve's rows: each contact point's normal and two tangent rows with their weights and
//! friction bound ([`Rows`]), and each joint's friction row ([`JointRows`]).

use super::{IMPEDANCE, Points};
use nalgebra::{DMatrix, DVector, Point3, Vector3};
use rapier3d::prelude::*;

/// The joints' friction rows: per joint its stick weight (kg m^2) and its friction bound in the
/// step (N m s, zero: frictionless).
pub struct JointRows {
    pub(super) weight: Vec<f64>,
    pub(super) bound: Vec<f64>,
}

impl JointRows {
    /// Rows of the bounds `bound` (N m s per joint) for the inertia whose inverse is
    /// `mass_inverse`.
    pub(super) fn new(bound: &[f64], mass_inverse: &DMatrix<f64>) -> Self {
        let ratio = IMPEDANCE / (1.0 - IMPEDANCE);
        JointRows {
            weight: (0..bound.len())
                .map(|i| ratio / mass_inverse[(i, i)].max(f64::MIN_POSITIVE))
                .collect(),
            bound: bound.to_vec(),
        }
    }

    /// Joint `i`'s friction impulse (N m s) at its velocity `v` (rad/s): `-W v` while it sticks,
    /// `-b sign(v)` while it slides.
    pub(super) fn impulse(&self, i: usize, v: f64) -> f64 {
        let (w, b) = (self.weight[i], self.bound[i]);
        if w * v.abs() <= b {
            -w * v
        } else {
            -b * v.signum()
        }
    }

    /// The curvature of joint `i`'s friction cost at velocity `v`: `W` while it sticks, 0 while it
    /// slides or without friction.
    pub(super) fn curvature(&self, i: usize, v: f64) -> f64 {
        let (w, b) = (self.weight[i], self.bound[i]);
        if b > 0.0 && w * v.abs() <= b { w } else { 0.0 }
    }
}

/// Per contact point: its normal row and two tangent rows (`n` columns each, stored flat), the
/// normal row's target speed (m/s) and weight (kg), the friction's weight (kg) and bound (N s).
pub(super) struct Rows {
    pub(super) n: usize,
    pub(super) jac: Vec<f64>,
    pub(super) target: Vec<f64>,
    pub(super) normal_weight: Vec<f64>,
    pub(super) friction_weight: Vec<f64>,
    pub(super) bound: Vec<f64>,
    /// The friction coefficient of each point.
    pub(super) mu: Vec<f64>,
    /// Normal and tangents (base frame) and the point on the peg, per point.
    pub(super) frame: Vec<[Vector3<f64>; 3]>,
    pub(super) point: Vec<Point3<f64>>,
    /// Which of the step's contact points each is.
    pub(super) taken: Vec<usize>,
}

impl Rows {
    pub(super) fn len(&self) -> usize {
        self.target.len()
    }

    pub(super) fn row(&self, r: usize) -> &[f64] {
        &self.jac[r * self.n..(r + 1) * self.n]
    }

    /// The speeds of every point's three rows at joint velocity `v`.
    pub(super) fn speeds(&self, v: &DVector<f64>) -> Vec<[f64; 3]> {
        let mut out = Vec::with_capacity(self.len());
        self.speeds_into(v, &mut out);
        out
    }

    /// [`Rows::speeds`] into `out`.
    pub(super) fn speeds_into(&self, v: &DVector<f64>, out: &mut Vec<[f64; 3]>) {
        out.clear();
        out.extend(
            (0..self.len())
                .map(|c| std::array::from_fn(|k| dot(self.row(3 * c + k), v.as_slice()))),
        );
    }

    /// The impulses (normal, tangent 1, tangent 2; N s) of point `c` at row speeds `s`.
    pub(super) fn impulses(&self, c: usize, s: &[f64; 3]) -> [f64; 3] {
        self.impulses_at(c, s, slip(s))
    }

    /// The normal impulse (N s) of point `c` at normal row speed `speed` (m/s).
    pub(super) fn normal_impulse(&self, c: usize, speed: f64) -> f64 {
        self.normal_weight[c] * (self.target[c] - speed).max(0.0)
    }

    /// [`Rows::impulses`] with the slip speed `slip` of `s` ([`slip`]) given.
    pub(super) fn impulses_at(&self, c: usize, s: &[f64; 3], slip: f64) -> [f64; 3] {
        let normal = self.normal_impulse(c, s[0]);
        let (w, b) = (self.friction_weight[c], self.bound[c]);
        let scale = if w * slip <= b { -w } else { -b / slip };
        [normal, scale * s[1], scale * s[2]]
    }

    /// The friction term's curvature in point `c`'s tangent plane at row speeds `s` (slip speed
    /// `slip`), as `[h11, h12, h22]` (kg): `D_f I` while it sticks, `(b / |x|) (I - x x^T /
    /// |x|^2)` while it slides (the Huber function's Hessian); `None` without friction (bound 0).
    pub(super) fn friction_curvature(&self, c: usize, s: &[f64; 3], slip: f64) -> Option<[f64; 3]> {
        let (w, b) = (self.friction_weight[c], self.bound[c]);
        if b <= 0.0 {
            return None;
        }
        if w * slip <= b {
            return Some([w, 0.0, w]);
        }
        let (u1, u2, k) = (s[1] / slip, s[2] / slip, b / slip);
        Some([k * (1.0 - u1 * u1), -k * u1 * u2, k * (1.0 - u2 * u2)])
    }
}

/// The slip speed of row speeds `s` (normal, tangent 1, tangent 2): the tangential speed's norm.
pub(super) fn slip(s: &[f64; 3]) -> f64 {
    (s[1] * s[1] + s[2] * s[2]).sqrt()
}

impl Rows {
    pub(super) fn new(n: usize) -> Self {
        Rows {
            n,
            jac: Vec::new(),
            target: Vec::new(),
            normal_weight: Vec::new(),
            friction_weight: Vec::new(),
            bound: Vec::new(),
            mu: Vec::new(),
            frame: Vec::new(),
            point: Vec::new(),
            taken: Vec::new(),
        }
    }

    /// Adds the normal and two tangent rows of each of the points `which`.
    pub(super) fn take(&mut self, points: &Points, which: &[usize], mass_inverse: &DMatrix<f64>) {
        let (jv, jw) = (points.jac.fixed_rows::<3>(0), points.jac.fixed_rows::<3>(3));
        let ratio = IMPEDANCE / (1.0 - IMPEDANCE);
        // A row, its rotational part, and the inverse inertia times the row.
        let [mut r, mut r_w, mut m_r] = [(); 3].map(|_| DVector::zeros(self.n));
        for &c in which {
            let normal = points.normal[c];
            let t1 = normal.cross(&least_aligned_axis(&normal)).normalize();
            let t2 = normal.cross(&t1);
            let mut inverse_mass = [0.0; 3];
            for (slot, d) in inverse_mass.iter_mut().zip([normal, t1, t2]) {
                jv.tr_mul_to(&d, &mut r);
                jw.tr_mul_to(&points.lever[c].cross(&d), &mut r_w);
                r += &r_w;
                mass_inverse.mul_to(&r, &mut m_r);
                *slot = r.dot(&m_r).max(f64::MIN_POSITIVE);
                self.jac.extend(r.iter());
            }
            self.target.push(points.target[c]);
            self.normal_weight.push(ratio / inverse_mass[0]);
            self.friction_weight
                .push(ratio / (0.5 * (inverse_mass[1] + inverse_mass[2])));
            self.bound.push(0.0);
            self.mu.push(points.mu[c]);
            self.frame.push([normal, t1, t2]);
            self.point.push(points.point[c]);
            self.taken.push(c);
        }
    }
}

/// The coordinate axis least aligned with `n` (a tangent seed).
pub(super) fn least_aligned_axis(n: &Vector3<f64>) -> Vector3<f64> {
    let a = n.abs();
    if a.x <= a.y && a.x <= a.z {
        Vector3::x()
    } else if a.y <= a.z {
        Vector3::y()
    } else {
        Vector3::z()
    }
}

/// The dot product of a row and a joint velocity, summed in joint order; unrolled for the
/// iiwa's seven joints.
pub(super) fn dot(row: &[f64], v: &[f64]) -> f64 {
    match (<&[f64; 7]>::try_from(row), <&[f64; 7]>::try_from(v)) {
        (Ok(row), Ok(v)) => row.iter().zip(v).map(|(a, b)| a * b).sum(),
        _ => row.iter().zip(v).map(|(a, b)| a * b).sum(),
    }
}
