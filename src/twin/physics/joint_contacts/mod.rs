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

mod newton;
mod rows;

use newton::{NewtonBuffers, minimise};
use rows::{JointRows, Rows};

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
/// Friction bounds refreshed from the normal impulses this many times (staggered projections).
const FRICTION_ROUNDS: usize = 3;
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
    /// What the joints' friction did, when they have any.
    pub joint_friction: Option<JointFrictionSolve>,
}

/// The joints' friction over one step.
#[derive(Clone, Debug)]
pub struct JointFrictionSolve {
    /// Its torque on each joint, N m (motor side: the torque sensors do not read it).
    pub torque_nm: DVector<f64>,
    /// Its work at the velocities it left, J.
    pub work_j: f64,
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
        joint_friction: joints.map(|j| {
            let impulse = DVector::from_fn(v.len(), |i, _| j.impulse(i, v[i]));
            JointFrictionSolve {
                work_j: impulse.dot(&v),
                torque_nm: impulse / dt,
            }
        }),
    };
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

#[cfg(test)]
mod tests {
    use super::newton::add_outer;
    use super::rows::dot;
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
