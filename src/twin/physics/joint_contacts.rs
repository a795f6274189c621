//! The arm's peg contacts solved in joint space, exactly, instead of by rapier's projected
//! Gauss-Seidel over multibody contact rows: the arm cell's default since 2026-11-26
//! (`PhysicsParams::arm_contacts`; docs/journal/2026-11-25.md, "Joint-space contacts").
//!
//! Why: the arm has a handful of degrees of freedom while its peg, wedged in a tight bore, has
//! hundreds of contact rows (about 1 300 contact points per step on the gear at 0.1 mm). rapier
//! relaxes those rows one by one through the arm's dense inertia; on a wedge that converges
//! slowly, so its contacts stay soft (a 240 Hz spring, 12-95 um of penetration under the motion
//! cases of `validate --arm`) and stiffer ones go unstable (docs/journal/2026-11-23.md, "The arm at 0.1 mm").
//! Here every row acts on the same few joint velocities, so the whole contact problem is a
//! convex program in `n` unknowns (`n` = the arm's joints), solved to its optimum by Newton's
//! method, as MuJoCo's primal solver does (E. Todorov, "Convex and analytically-invertible
//! dynamics with contacts and constraints", ICRA 2014):
//!
//! `min_v  1/2 (v - v_free)^T M (v - v_free) + sum_c 1/2 D_c min(0, J_c v - u_c)^2
//!          + sum_c H(D_f, b_c; T_c v)`
//!
//! - `v_free` is the joints' velocity after rapier's step without these contacts (torques,
//!   gravity, damping, gyroscopic terms: rapier's own integration), `M` the joint-space inertia
//!   with the rotor inertia, both at the start of the step, where the contacts were found.
//! - `J_c` is the normal row of contact point `c` (its normal times the point's Jacobian) and
//!   `u_c` the speed it must reach: a point `d > 0` away may approach by `d / dt` in the step
//!   (speculative contact, no tunnelling); a point `d` deep is pushed out by
//!   [`PUSH_OUT_FRACTION`] of `d` per step (Baumgarte).
//! - `D_c` makes the constraint soft by a fixed fraction of the row's own effective mass,
//!   `D = d / (1 - d) / (J M^-1 J^T)` with `d` = [`IMPEDANCE`]: every row is equally stiff
//!   relative to what it carries, whatever the wrist's small projected inertia.
//! - Friction is Coulomb's, isotropic: `T_c` holds the point's two tangent rows and `H` is the
//!   Huber function of the slip speed, `1/2 D_f |x|^2` up to `|x| = b / D_f` and linear beyond,
//!   so the friction impulse is `-D_f x` while it sticks and `-b x / |x|` while it slides. Its
//!   bound `b` is `mu` times the normal impulse (`mu` between the static and the kinetic
//!   coefficient by the point's slip speed at the start of the step, `ContactFriction::at`), refreshed from the solution
//!   [`FRICTION_ROUNDS`] times (staggered projections: D. M. Kaufman et al., "Staggered
//!   projections for frictional contact in multibody systems", SIGGRAPH Asia 2008). A friction
//!   pyramid as rows of their own (MuJoCo's pyramidal cone in this primal form) was tried first:
//!   it makes a sliding point dilate (`n . v >= mu |slip|`), which a peg between two walls
//!   0.05 mm apart cannot do, so it squeezed the peg with hundreds of newtons.
//! - The impulses are `p_c = D_c max(0, u_c - J_c v)` and the friction's; the arm's velocity
//!   changes by `M^-1 J^T p` and, as semi-implicit Euler integrates positions with the new
//!   velocity, its joints move by `dt` times that change.
//!
//! - The joints' own friction (`PhysicsParams::joint_friction`) adds one row per joint, its own
//!   velocity, with the same Huber cost: `H(W_i, b_i; v_i)`, `b_i` the joint's friction torque
//!   times the step, `W_i` as stiff relative to the joint's effective inertia as a contact row
//!   (MuJoCo's `frictionloss` in this primal form). A joint whose torque stays under its bound
//!   sticks (its impulse cancels the rest, without chatter); beyond it, it slides against the
//!   bound.
//!
//! The cost is convex and piecewise smooth: Newton's method with a safeguarded line search.

use super::ContactFriction;
use crate::twin::robot::{Iso, Kinematics, RobotModel};
use nalgebra::{DMatrix, DVector, Point3, Vector3};
use rapier3d::prelude::*;

/// Impedance of a contact row, MuJoCo's `d` in (0, 1): the constraint's weight is `d / (1 - d)`
/// times the row's effective mass. 0.9999 halves the motion cases' penetration and multiplies
/// their peak forces up to tenfold (2.5 kN on the cross's sampling episode).
pub const IMPEDANCE: f64 = 0.999;
/// Fraction of a penetration pushed out per step (Baumgarte's factor). Measured on `validate
/// --arm` at 0.1 mm: 0.2 left 4-14 um in the motion cases of the plug3 and the key, 0.4 keeps
/// every built-in under 5 um at every clearance, 0.05 fails the cross; 0.5 and 1.0 also pass
/// the cross (docs/physics.md).
pub const PUSH_OUT_FRACTION: f64 = 0.4;
/// Newton iterations at most per solve, and the joint-speed change (rad/s) below which a step
/// ends the solve.
const MAX_NEWTON_STEPS: usize = 30;
const NEWTON_TOLERANCE: f64 = 1e-10;
/// Friction bounds refreshed from the normal impulses this many times (staggered projections).
const FRICTION_ROUNDS: usize = 3;
/// Iterations at most of the line search, and the slope (relative to the slope at its start) at
/// which it stops.
const MAX_LINE_STEPS: usize = 30;
const LINE_TOLERANCE: f64 = 1e-3;

/// One contact point of the peg, world frame.
#[derive(Clone, Copy, Debug)]
pub struct PegContact {
    /// The contact point on the peg.
    pub point: Point3<f64>,
    /// Unit normal pushing the peg out of the other body.
    pub normal: Vector3<f64>,
    /// Signed distance along the normal, metres (negative: overlapping).
    pub dist_m: f64,
}

/// The contact points on `peg` that the narrow phase found at the start of the last step (every
/// manifold of every pair with the peg, the fixture's and the table's).
pub fn peg_contacts(world: &PhysicsWorld, peg: ColliderHandle) -> Vec<PegContact> {
    let mut out = Vec::new();
    for pair in world.narrow_phase.contact_pairs_with(peg) {
        let Some(rigid) = pair.rigid() else {
            continue;
        };
        let peg_is_1 = pair.collider1 == peg;
        let (c1, c2) = (
            &world.colliders[pair.collider1],
            &world.colliders[pair.collider2],
        );
        for m in &rigid.manifolds {
            let pos1 = *c1.position() * m.subshape_pos1().copied().unwrap_or(Pose::IDENTITY);
            let pos2 = *c2.position() * m.subshape_pos2().copied().unwrap_or(Pose::IDENTITY);
            let n1 = super::v64(pos1.rotation * m.local_n1);
            for p in &m.points {
                let (point, normal) = if peg_is_1 {
                    (pos1 * p.local_p1, -n1)
                } else {
                    (pos2 * p.local_p2, n1)
                };
                out.push(PegContact {
                    point: Point3::from(super::v64(point)),
                    normal,
                    dist_m: p.dist as f64,
                });
            }
        }
    }
    out
}

/// The joints' friction rows: per joint its stick weight (kg m^2) and its friction bound in the
/// step (N m s, zero: frictionless).
pub struct JointRows {
    weight: Vec<f64>,
    bound: Vec<f64>,
}

impl JointRows {
    /// Rows of the bounds `bound` (N m s per joint) for the inertia whose inverse is
    /// `mass_inverse`.
    fn new(bound: &[f64], mass_inverse: &DMatrix<f64>) -> Self {
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
    fn impulse(&self, i: usize, v: f64) -> f64 {
        let (w, b) = (self.weight[i], self.bound[i]);
        if w * v.abs() <= b {
            -w * v
        } else {
            -b * v.signum()
        }
    }

    /// The curvature of joint `i`'s friction cost at velocity `v`: `W` while it sticks, 0 while it
    /// slides or without friction.
    fn curvature(&self, i: usize, v: f64) -> f64 {
        let (w, b) = (self.weight[i], self.bound[i]);
        if b > 0.0 && w * v.abs() <= b { w } else { 0.0 }
    }
}

/// What the contact solve did in one step.
#[derive(Clone, Debug)]
pub struct ContactSolve {
    /// The joints' velocity change, rad/s (m/s on prismatic joints).
    pub dv: DVector<f64>,
    /// Mean contact force on the peg over the step, N, base frame.
    pub force: Vector3<f64>,
    /// Its torque about `about`, N m, base frame.
    pub torque: Vector3<f64>,
    /// Work of the contact impulses at the velocities they left, J.
    pub work_j: f64,
    /// Contact points taken.
    pub points: usize,
    /// The joints' friction torque over the step, N m (motor side: the torque sensors do not
    /// read it), and its work at the velocities it left, J; zero without joint friction.
    pub joint_friction_nm: DVector<f64>,
    pub joint_friction_work_j: f64,
}

/// Per contact point: its normal row and two tangent rows (`n` columns each, stored flat), the
/// normal row's target speed (m/s) and weight (kg), the friction's weight (kg) and bound (N s).
struct Rows {
    n: usize,
    jac: Vec<f64>,
    target: Vec<f64>,
    normal_weight: Vec<f64>,
    friction_weight: Vec<f64>,
    bound: Vec<f64>,
    /// The friction coefficient of each point.
    mu: Vec<f64>,
    /// Normal and tangents (base frame) and the point on the peg, per point.
    frame: Vec<[Vector3<f64>; 3]>,
    point: Vec<Point3<f64>>,
    /// Which of the step's contact points each is.
    taken: Vec<usize>,
}

impl Rows {
    fn len(&self) -> usize {
        self.target.len()
    }

    fn row(&self, r: usize) -> &[f64] {
        &self.jac[r * self.n..(r + 1) * self.n]
    }

    /// The speeds of every point's three rows at joint velocity `v`.
    fn speeds(&self, v: &DVector<f64>) -> Vec<[f64; 3]> {
        let mut out = Vec::with_capacity(self.len());
        self.speeds_into(v, &mut out);
        out
    }

    /// [`Rows::speeds`] into `out`.
    fn speeds_into(&self, v: &DVector<f64>, out: &mut Vec<[f64; 3]>) {
        out.clear();
        out.extend(
            (0..self.len())
                .map(|c| std::array::from_fn(|k| dot(self.row(3 * c + k), v.as_slice()))),
        );
    }

    /// The impulses (normal, tangent 1, tangent 2; N s) of point `c` at row speeds `s`.
    fn impulses(&self, c: usize, s: &[f64; 3]) -> [f64; 3] {
        self.impulses_at(c, s, slip(s))
    }

    /// The normal impulse (N s) of point `c` at normal row speed `speed` (m/s).
    fn normal_impulse(&self, c: usize, speed: f64) -> f64 {
        self.normal_weight[c] * (self.target[c] - speed).max(0.0)
    }

    /// [`Rows::impulses`] with the slip speed `slip` of `s` ([`slip`]) given.
    fn impulses_at(&self, c: usize, s: &[f64; 3], slip: f64) -> [f64; 3] {
        let normal = self.normal_impulse(c, s[0]);
        let (w, b) = (self.friction_weight[c], self.bound[c]);
        let scale = if w * slip <= b { -w } else { -b / slip };
        [normal, scale * s[1], scale * s[2]]
    }

    /// The friction term's curvature in point `c`'s tangent plane at row speeds `s` (slip speed
    /// `slip`), as `[h11, h12, h22]` (kg): `D_f I` while it sticks, `(b / |x|) (I - x x^T /
    /// |x|^2)` while it slides (the Huber function's Hessian); `None` without friction (bound 0).
    fn friction_curvature(&self, c: usize, s: &[f64; 3], slip: f64) -> Option<[f64; 3]> {
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
fn slip(s: &[f64; 3]) -> f64 {
    (s[1] * s[1] + s[2] * s[2]).sqrt()
}

/// Solves the contacts `contacts` (world frame) of the peg carried by `model`'s last link at the
/// configuration `k` (`world_t_base` places the arm), against the free velocity `v_free`, with
/// the joint-space inertia `mass`, Coulomb friction `friction`, over a step of `dt` seconds;
/// forces and torques are reported in the base frame, torques about `about` (base frame).
///
/// Most points a wedged peg's narrow phase reports stay apart (a gear at 0.1 mm: about 1 200
/// points, a tenth of them pressed), so the Newton iterations run over the points that press at
/// `v_free`, and each solution is checked against every point: one that the solution would push
/// into its wall joins, and the solve goes on from there. A point left out is inactive at the
/// solution, where the cost is then the full one, so the optimum is the full problem's.
/// `friction` is the contacts' (each point's coefficient from its slip speed at `v_start`, the
/// joints' velocity at the start of the step), `joint_bounds` the joints' friction bounds in the
/// step (N m s), when they have friction.
#[allow(clippy::too_many_arguments)]
pub fn solve(
    model: &RobotModel,
    k: &Kinematics,
    world_t_base: &Iso,
    mass: &DMatrix<f64>,
    (v_start, v_free): (&[f64], &DVector<f64>),
    contacts: &[PegContact],
    (friction, joint_bounds): (&ContactFriction, Option<&[f64]>),
    dt: f64,
    about: &Point3<f64>,
) -> Option<ContactSolve> {
    let mut points = Points::new(model, k, world_t_base, contacts, dt);
    points.friction_at(friction, v_start);
    let first = points.pressing(v_free, &[]);
    let (rows, joints, v, speeds) = solve_from(mass, v_free, &points, joint_bounds, &first)?;
    let mut out = ContactSolve {
        dv: &v - v_free,
        force: Vector3::zeros(),
        torque: Vector3::zeros(),
        work_j: 0.0,
        points: contacts.len(),
        joint_friction_nm: DVector::zeros(v.len()),
        joint_friction_work_j: 0.0,
    };
    if let Some(j) = &joints {
        for i in 0..v.len() {
            let p = j.impulse(i, v[i]);
            out.joint_friction_nm[i] = p / dt;
            out.joint_friction_work_j += p * v[i];
        }
    }
    for (c, s) in speeds.iter().enumerate() {
        let p = rows.impulses(c, s);
        let [n, t1, t2] = rows.frame[c];
        let f = (n * p[0] + t1 * p[1] + t2 * p[2]) / dt;
        out.force += f;
        out.torque += (rows.point[c] - about).cross(&f);
        out.work_j += p[0] * s[0] + p[1] * s[1] + p[2] * s[2];
    }
    Some(out)
}

/// The solve of [`solve`] with the rows of the points `first` to begin with: the rows it ended
/// with, the joint velocity and the rows' speeds there.
#[allow(clippy::type_complexity)]
fn solve_from(
    mass: &DMatrix<f64>,
    v_free: &DVector<f64>,
    points: &Points,
    joint_bounds: Option<&[f64]>,
    first: &[usize],
) -> Option<(Rows, Option<JointRows>, DVector<f64>, Vec<[f64; 3]>)> {
    let mass_inverse = mass.clone().cholesky()?.inverse();
    let joints = joint_bounds.map(|b| JointRows::new(b, &mass_inverse));
    let mut rows = Rows::new(v_free.len());
    rows.take(points, first, &mass_inverse);
    let mut v = v_free.clone();
    let mut speeds = rows.speeds(&v);
    let mut buffers = NewtonBuffers::new(v.len());
    for _ in 0..FRICTION_ROUNDS {
        loop {
            minimise(
                mass,
                v_free,
                (&rows, joints.as_ref()),
                &mut v,
                &mut speeds,
                &mut buffers,
            );
            let missed = points.pressing(&v, &rows.taken);
            if missed.is_empty() {
                break;
            }
            rows.take(points, &missed, &mass_inverse);
            speeds = rows.speeds(&v);
        }
        for (c, s) in speeds.iter().enumerate() {
            rows.bound[c] = rows.mu[c] * rows.normal_impulse(c, s[0]);
        }
    }
    Some((rows, joints, v, speeds))
}

/// Every contact point in the base frame, with its normal row's target speed, and the last
/// link's Jacobian at its origin `o`: a point `p` on the link moves at `v_o + w x (p - o)`, so
/// the row of direction `d` there is `d^T J_v + ((p - o) x d)^T J_w`.
struct Points {
    jac: DMatrix<f64>,
    point: Vec<Point3<f64>>,
    normal: Vec<Vector3<f64>>,
    lever: Vec<Vector3<f64>>,
    /// The normal speed (m/s) the point must reach: a point `d > 0` away may approach by
    /// `d / dt` in the step (speculative contact); one `d` deep is pushed out by
    /// [`PUSH_OUT_FRACTION`] of it.
    target: Vec<f64>,
    /// The point's friction coefficient ([`Points::friction_at`]).
    mu: Vec<f64>,
}

impl Points {
    fn new(
        model: &RobotModel,
        k: &Kinematics,
        world_t_base: &Iso,
        contacts: &[PegContact],
        dt: f64,
    ) -> Self {
        let last = model.dof() - 1;
        let base_t_world = world_t_base.inverse();
        let origin = Point3::from(k.frames[last].translation.vector);
        let point: Vec<Point3<f64>> = contacts.iter().map(|c| base_t_world * c.point).collect();
        Points {
            jac: model.point_jacobian(k, &origin, last),
            lever: point.iter().map(|p| p - origin).collect(),
            point,
            normal: contacts
                .iter()
                .map(|c| base_t_world.rotation * c.normal)
                .collect(),
            target: contacts
                .iter()
                .map(|c| {
                    if c.dist_m >= 0.0 {
                        -c.dist_m / dt
                    } else {
                        -PUSH_OUT_FRACTION * c.dist_m / dt
                    }
                })
                .collect(),
            mu: Vec::new(),
        }
    }

    /// Each point's friction coefficient under `friction` at the joint velocity `v` (the step's
    /// start): the kinetic one, or toward the static one as the point's slip speed falls.
    fn friction_at(&mut self, friction: &ContactFriction, v: &[f64]) {
        if friction.static_ <= friction.kinetic {
            self.mu = vec![friction.kinetic; self.point.len()];
            return;
        }
        let twist = &self.jac * DVector::from_column_slice(v);
        let (v_o, w) = (twist.fixed_rows::<3>(0), twist.fixed_rows::<3>(3));
        self.mu = (0..self.point.len())
            .map(|c| {
                let velocity = v_o + w.cross(&self.lever[c]);
                let n = self.normal[c];
                friction.at((velocity - n * n.dot(&velocity)).norm())
            })
            .collect();
    }

    /// The points not in `taken` whose normal row, at joint velocity `v`, moves into the wall
    /// faster than its target allows (the ones that would take an impulse).
    fn pressing(&self, v: &DVector<f64>, taken: &[usize]) -> Vec<usize> {
        let twist = &self.jac * v;
        let (v_o, w) = (twist.fixed_rows::<3>(0), twist.fixed_rows::<3>(3));
        let mut is_taken = vec![false; self.point.len()];
        for &c in taken {
            is_taken[c] = true;
        }
        (0..self.point.len())
            .filter(|&c| {
                !is_taken[c]
                    && self.normal[c].dot(&(v_o + w.cross(&self.lever[c]))) < self.target[c]
            })
            .collect()
    }
}

impl Rows {
    fn new(n: usize) -> Self {
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
    fn take(&mut self, points: &Points, which: &[usize], mass_inverse: &DMatrix<f64>) {
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
fn least_aligned_axis(n: &Vector3<f64>) -> Vector3<f64> {
    let a = n.abs();
    if a.x <= a.y && a.x <= a.z {
        Vector3::x()
    } else if a.y <= a.z {
        Vector3::y()
    } else {
        Vector3::z()
    }
}

/// The buffers of Newton's method, kept from one step to the next (the solve allocates per
/// step only the rows it takes).
struct NewtonBuffers {
    /// `v - v_free`, rad/s.
    dv: DVector<f64>,
    /// The cost's gradient (N m s) and the Newton step (rad/s).
    grad: DVector<f64>,
    delta: DVector<f64>,
    /// `M delta`, N m s.
    m_delta: DVector<f64>,
    /// The cost's Hessian (kg m^2), then its Cholesky factor.
    hess: DMatrix<f64>,
    /// A row times its Hessian weight.
    weighted: Vec<f64>,
    /// The rows' speeds along the Newton step.
    sigma: Vec<[f64; 3]>,
}

impl NewtonBuffers {
    fn new(n: usize) -> Self {
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
fn minimise(
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
fn newton_system(
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
fn add_joint_friction(joints: &JointRows, v: &DVector<f64>, buf: &mut NewtonBuffers) {
    let n = v.len();
    for i in 0..n {
        buf.grad[i] -= joints.impulse(i, v[i]);
        buf.hess[(i, i)] += joints.curvature(i, v[i]);
    }
    debug_assert_eq!(buf.hess.nrows(), n);
}

/// The dot product of a row and a joint velocity, summed in joint order; unrolled for the
/// iiwa's seven joints.
fn dot(row: &[f64], v: &[f64]) -> f64 {
    match (<&[f64; 7]>::try_from(row), <&[f64; 7]>::try_from(v)) {
        (Ok(row), Ok(v)) => row.iter().zip(v).map(|(a, b)| a * b).sum(),
        _ => row.iter().zip(v).map(|(a, b)| a * b).sum(),
    }
}

/// `hess += wa b^T` (column-major, `wa.len()` rows) over whole columns: the Hessian's upper
/// triangle gets sums of its own, which [`symmetrise_lower`] then overwrites with the lower's.
/// Unrolled for the iiwa's seven joints; any other count takes the loop.
fn add_outer(hess: &mut [f64], wa: &[f64], b: &[f64]) {
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
fn symmetrise_lower(m: &mut DMatrix<f64>) {
    for i in 0..m.nrows() {
        for j in 0..i {
            m[(j, i)] = m[(i, j)];
        }
    }
}

/// The minimiser along `v + alpha delta` (alpha >= 0): the cost's derivative there increases
/// with alpha; safeguarded Newton on it within a bracket. `dv` is `v - v_free`, `m_delta` is
/// `M delta`; `s0` and `sd` are the rows' speeds at `v` and along `delta`.
fn line_search(
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

#[cfg(test)]
mod tests {
    use super::*;

    /// Two unit-mass joints, one contact point whose normal row is joint 0 and whose tangents
    /// are joint 1 and nothing, with the given weights and friction bound.
    fn one_point(target: f64, weight: f64, friction_weight: f64, bound: f64) -> Rows {
        Rows {
            n: 2,
            jac: vec![1.0, 0.0, 0.0, 1.0, 0.0, 0.0],
            target: vec![target],
            normal_weight: vec![weight],
            friction_weight: vec![friction_weight],
            bound: vec![bound],
            mu: vec![0.0],
            frame: vec![[Vector3::x(), Vector3::y(), Vector3::z()]],
            point: vec![Point3::origin()],
            taken: vec![0],
        }
    }

    /// Newton's method from `v`, with fresh buffers.
    fn minimise_from(
        mass: &DMatrix<f64>,
        v_free: &DVector<f64>,
        rows: &Rows,
        v: &mut DVector<f64>,
    ) -> usize {
        let mut buffers = NewtonBuffers::new(v.len());
        minimise(
            mass,
            v_free,
            (rows, None),
            v,
            &mut rows.speeds(v),
            &mut buffers,
        )
    }

    #[test]
    fn a_normal_row_stops_the_approach_up_to_its_softness() {
        let mass = DMatrix::identity(2, 2);
        let v_free = DVector::from_vec(vec![-1.0, 0.5]);
        let rows = one_point(0.0, 999.0, 999.0, 0.0);
        let mut v = v_free.clone();
        minimise_from(&mass, &v_free, &rows, &mut v);
        // (v0 + 1) + 999 v0 = 0, and the frictionless tangent keeps its speed.
        assert!((v[0] + 1.0 / 1000.0).abs() < 1e-12, "{v}");
        assert!((v[1] - 0.5).abs() < 1e-12, "{v}");
    }

    #[test]
    fn friction_holds_a_slow_slip_and_is_bounded_on_a_fast_one() {
        let mass = DMatrix::identity(2, 2);
        let rows = one_point(0.0, 999.0, 999.0, 0.2);
        for (slip, expected) in [(0.1, 0.1 / 1000.0), (1.0, 0.8)] {
            let v_free = DVector::from_vec(vec![0.0, slip]);
            let mut v = v_free.clone();
            minimise_from(&mass, &v_free, &rows, &mut v);
            assert!((v[1] - expected).abs() < 1e-9, "slip {slip}: {v}");
            let p = rows.impulses(0, &rows.speeds(&v)[0]);
            assert!(p[1].abs() <= 0.2 + 1e-12, "slip {slip}: {p:?}");
        }
    }

    #[test]
    fn a_separating_point_takes_no_impulse() {
        let mass = DMatrix::identity(2, 2);
        let v_free = DVector::from_vec(vec![0.3, 0.0]);
        let rows = one_point(-0.01, 999.0, 999.0, 0.0);
        let mut v = v_free.clone();
        assert_eq!(minimise_from(&mass, &v_free, &rows, &mut v), 1);
        assert_eq!(v, v_free);
    }

    /// The unrolled seven-joint kernels sum what the plain loops over any joint count sum, term
    /// by term in the same order: the Hessian's lower triangle `h_ij += (w a_i) b_j` and the
    /// rows' speeds, to the bit.
    #[test]
    fn the_unrolled_kernels_sum_as_the_plain_loops_do() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        for n in [6, 7, 8] {
            let mut random = |len: usize| -> Vec<f64> {
                (0..len).map(|_| rng.random_range(-1e3..1e3)).collect()
            };
            let (mut hess, a, b, w) = (random(n * n), random(n), random(n), random(1)[0]);
            let mut plain = hess.clone();
            let wa: Vec<f64> = a.iter().map(|ai| w * ai).collect();
            add_outer(&mut hess, &wa, &b);
            for i in 0..n {
                for j in 0..=i {
                    plain[i + j * n] += w * a[i] * b[j];
                }
            }
            for i in 0..n {
                for j in 0..=i {
                    assert_eq!(hess[i + j * n].to_bits(), plain[i + j * n].to_bits());
                }
            }
            let sum = a.iter().zip(&b).fold(-0.0, |acc, (x, y)| acc + x * y);
            assert_eq!(dot(&a, &b).to_bits(), sum.to_bits(), "{n} joints");
        }
    }

    /// Forty points around the iiwa 14's tool tip, pressing, touching and apart, with normals in
    /// all directions, against a free motion of the arm into them: the solve that starts from
    /// the points pressing at the free velocity ends where the one over every point does.
    #[test]
    fn starting_from_the_pressing_points_reaches_the_solve_over_all_of_them() {
        use rand::{Rng, SeedableRng};
        let model = crate::twin::robot::urdf::iiwa14().unwrap();
        let q = [0.1, 0.5, -0.2, -1.4, 0.3, 1.1, 0.4];
        let k = model.kinematics(&q);
        let mass = model.mass_matrix(&k);
        let tcp = model.tcp_pose(&q);
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let contacts: Vec<PegContact> = (0..40)
            .map(|_| {
                let offset = Vector3::from_fn(|_, _| rng.random_range(-0.015..0.015));
                let normal = Vector3::from_fn(|_, _| rng.random_range(-1.0..1.0)).normalize();
                PegContact {
                    point: tcp * Point3::from(offset),
                    normal,
                    dist_m: rng.random_range(-5e-6..30e-6),
                }
            })
            .collect();
        let v_free = DVector::from_fn(7, |_, _| rng.random_range(-0.05..0.05));
        let mut points = Points::new(&model, &k, &Iso::identity(), &contacts, 1e-3);
        let mu = ContactFriction {
            kinetic: 0.3,
            static_: 0.3,
        };
        points.friction_at(&mu, v_free.as_slice());
        let first = points.pressing(&v_free, &[]);
        let all: Vec<usize> = (0..contacts.len()).collect();
        let (rows, _, v, _) = solve_from(&mass, &v_free, &points, None, &first).unwrap();
        let (_, _, v_all, _) = solve_from(&mass, &v_free, &points, None, &all).unwrap();
        assert!(first.len() < rows.taken.len(), "no point joined: {first:?}");
        assert!(rows.taken.len() < all.len(), "every point joined");
        assert!((&v - &v_all).amax() < 1e-8, "{v} against {v_all}");
        let mut only_first = Rows::new(7);
        only_first.take(&points, &first, &mass.clone().cholesky().unwrap().inverse());
        let mut v_first = v_free.clone();
        minimise_from(&mass, &v_free, &only_first, &mut v_first);
        assert!(
            (&v_first - &v_all).amax() > 1e-4,
            "the points that joined changed nothing"
        );
    }
}
