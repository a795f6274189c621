//! The robot model: a serial chain read from a URDF (see [`urdf`]), with the kinematics and rigid-body
//! dynamics the controller and the wrench estimator need, in f64 and in the robot's `base` frame:
//! link and flange poses, the TCP (the tip of a tool carried on the flange), the 6 x n geometric
//! Jacobian (rows `[v; w]`), gravity torques g(q), the joint-space inertia M(q) (links, tool and
//! rotor inertia) and the Cartesian inertia at the TCP.
//!
//! The simulator's multibody ([`crate::twin::physics::arm`]) is built from the same model, so the controller's
//! model and the simulated plant agree except where a test perturbs them on purpose.

pub mod spec;
pub mod urdf;

use crate::error::{Error, Result};
use nalgebra::{
    DMatrix, DVector, Isometry3, Matrix3, Matrix6, Point3, Translation3, UnitQuaternion, Vector3,
};
use serde::Serialize;

pub type Iso = Isometry3<f64>;

/// Gravity in the robot base frame when the base stands upright, m/s^2.
pub const GRAVITY_UPRIGHT: Vector3<f64> = Vector3::new(0.0, 0.0, -9.81);

/// How a joint moves.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum JointKind {
    /// Rotation about the axis, radians; `continuous` joints have infinite limits.
    Revolute,
    /// Translation along the axis, metres.
    Prismatic,
}

/// One movable joint of the chain.
#[derive(Clone, Debug, Serialize)]
pub struct Joint {
    pub name: String,
    pub kind: JointKind,
    /// Parent link frame to joint frame at q = 0 (URDF `<origin>`, with any fixed joints between
    /// the previous movable joint and this one folded in).
    #[serde(skip)]
    pub origin: Iso,
    /// Unit axis in the joint (= child link) frame.
    #[serde(skip)]
    pub axis: Vector3<f64>,
    /// Position limits, rad or m.
    pub lower: f64,
    pub upper: f64,
    /// Speed limit, rad/s or m/s.
    pub velocity_limit: f64,
    /// Torque or force limit, N m or N.
    pub effort_limit: f64,
    /// Viscous damping, N m s/rad (URDF `<dynamics damping>`).
    pub damping: f64,
    /// Coulomb friction, N m (URDF `<dynamics friction>`).
    pub friction: f64,
}

/// Mass properties of a rigid body in its own frame.
#[derive(Clone, Copy, Debug)]
pub struct Inertial {
    pub mass_kg: f64,
    /// Centre of mass, m.
    pub com: Point3<f64>,
    /// Inertia about the centre of mass, axes of the body frame, kg m^2.
    pub inertia: Matrix3<f64>,
}

impl Inertial {
    pub const ZERO: Inertial = Inertial {
        mass_kg: 0.0,
        com: Point3::new(0.0, 0.0, 0.0),
        inertia: Matrix3::new(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0),
    };

    /// The same body seen from a frame in which this body's frame sits at `pose`.
    pub fn transformed(&self, pose: &Iso) -> Inertial {
        let r = pose.rotation.to_rotation_matrix();
        Inertial {
            mass_kg: self.mass_kg,
            com: pose * self.com,
            inertia: r.matrix() * self.inertia * r.matrix().transpose(),
        }
    }

    /// Two bodies rigidly joined (same frame): parallel-axis theorem about the joint centre of mass.
    pub fn combined(&self, other: &Inertial) -> Inertial {
        let m = self.mass_kg + other.mass_kg;
        if m <= 0.0 {
            return Inertial::ZERO;
        }
        let com =
            Point3::from((self.com.coords * self.mass_kg + other.com.coords * other.mass_kg) / m);
        let shifted = |b: &Inertial| {
            let d = b.com - com;
            b.inertia + b.mass_kg * (Matrix3::identity() * d.norm_squared() - d * d.transpose())
        };
        Inertial {
            mass_kg: m,
            com,
            inertia: shifted(self) + shifted(other),
        }
    }
}

/// A collision shape of a link, in the link frame.
#[derive(Clone, Debug)]
pub enum Shape {
    /// Half extents, m.
    Box {
        half_extents: Vector3<f64>,
    },
    /// Along z of its frame, centred.
    Cylinder {
        radius: f64,
        length: f64,
    },
    /// Along z of its frame, centred; `length` between the cap centres.
    Capsule {
        radius: f64,
        length: f64,
    },
    Sphere {
        radius: f64,
    },
    /// The convex hull of a mesh's vertices (already scaled), m.
    ConvexHull {
        points: Vec<Point3<f64>>,
    },
}

/// A collision shape placed in its link's frame.
#[derive(Clone, Debug)]
pub struct CollisionShape {
    pub origin: Iso,
    pub shape: Shape,
}

/// A link: everything rigidly attached to the child side of a movable joint (or to the base).
#[derive(Clone, Debug)]
pub struct Link {
    pub name: String,
    pub inertial: Inertial,
    pub collision: Vec<CollisionShape>,
}

/// A tool carried rigidly on the flange (the peg with its holder).
#[derive(Clone, Debug)]
pub struct Tool {
    /// Mass properties in the flange frame.
    pub inertial: Inertial,
    /// `flange_T_tcp`: the tool centre point, the peg tip for pegtwin.
    pub flange_t_tcp: Iso,
}

/// A serial-chain robot: base link, n movable joints with their child links, the flange.
#[derive(Clone, Debug)]
pub struct RobotModel {
    pub name: String,
    pub base: Link,
    pub joints: Vec<Joint>,
    /// `links[i]` is the child of `joints[i]`.
    pub links: Vec<Link>,
    /// Name of the flange frame (the chain's tip link).
    pub flange_name: String,
    /// `last_link_T_flange`.
    pub last_t_flange: Iso,
    /// Reflected rotor inertia per joint, kg m^2 (not in URDF; see [`default_armature`]).
    pub armature: Vec<f64>,
    pub tool: Option<Tool>,
    /// A joint configuration near the cell's start pose (tool pointing down in front of the
    /// robot), where [`RobotModel::start_configuration`] starts its inverse kinematics; `None`:
    /// searched for.
    pub ik_seed: Option<Vec<f64>>,
    /// Checksum of what the robot is made from (URDF text, flange, tool offset, seed), for cache
    /// file names; `None` for the default robot, the built-in iiwa 14.
    pub content_key: Option<String>,
}

/// Default reflected rotor inertia, kg m^2 per joint. KUKA publishes none (docs/sources.md, 2);
/// 0.1 on the four large joints and 0.05 on the wrist are the order of a 1e-5 to 4e-5 kg m^2
/// rotor behind a 100:1 to 160:1 harmonic drive. Below about 0.01 the 1 ms multibody step of
/// the light last link diverges (measured: docs/robot.md).
pub fn default_armature(n: usize) -> Vec<f64> {
    (0..n).map(|i| if i < 4 { 0.1 } else { 0.05 }).collect()
}

/// Poses of every joint frame of a configuration, base frame.
pub struct Kinematics {
    /// `base_T_link_i` for each movable joint's child link.
    pub frames: Vec<Iso>,
    /// Joint axes, base frame.
    pub axes: Vec<Vector3<f64>>,
}

impl RobotModel {
    /// Number of movable joints.
    pub fn dof(&self) -> usize {
        self.joints.len()
    }

    /// Total mass of base and links (without the tool), kg.
    pub fn total_mass_kg(&self) -> f64 {
        self.base.inertial.mass_kg + self.links.iter().map(|l| l.inertial.mass_kg).sum::<f64>()
    }

    /// Attaches a tool (replacing any previous one).
    pub fn with_tool(mut self, tool: Tool) -> Self {
        self.tool = Some(tool);
        self
    }

    /// Checks a joint configuration: its length and each value against the joint's limits.
    pub fn check_q(&self, q: &[f64]) -> Result<()> {
        if q.len() != self.dof() {
            return Err(Error::Input(format!(
                "q has {} values but robot '{}' has {} joints",
                q.len(),
                self.name,
                self.dof()
            )));
        }
        for (j, &v) in self.joints.iter().zip(q) {
            if !v.is_finite() || v < j.lower || v > j.upper {
                return Err(Error::Input(format!(
                    "q for joint '{}' is {v}, outside its limits [{}, {}]",
                    j.name, j.lower, j.upper
                )));
            }
        }
        Ok(())
    }

    /// Joint frames and axes at `q` (no checks; `q.len()` must equal `dof()`).
    pub fn kinematics(&self, q: &[f64]) -> Kinematics {
        let mut frames = Vec::with_capacity(self.dof());
        let mut axes = Vec::with_capacity(self.dof());
        let mut t = Iso::identity();
        for (j, &qi) in self.joints.iter().zip(q) {
            let motion = match j.kind {
                JointKind::Revolute => Iso::from_parts(
                    Translation3::identity(),
                    UnitQuaternion::from_scaled_axis(j.axis * qi),
                ),
                JointKind::Prismatic => {
                    Iso::from_parts(Translation3::from(j.axis * qi), UnitQuaternion::identity())
                }
            };
            t = t * j.origin * motion;
            axes.push(t.rotation * j.axis);
            frames.push(t);
        }
        Kinematics { frames, axes }
    }

    /// `base_T_flange` at `q`.
    pub fn flange_pose(&self, q: &[f64]) -> Iso {
        self.flange_from(&self.kinematics(q))
    }

    fn flange_from(&self, k: &Kinematics) -> Iso {
        k.frames.last().copied().unwrap_or_else(Iso::identity) * self.last_t_flange
    }

    /// `flange_T_tcp` (identity without a tool).
    pub fn flange_t_tcp(&self) -> Iso {
        self.tool
            .as_ref()
            .map_or_else(Iso::identity, |t| t.flange_t_tcp)
    }

    /// `base_T_tcp` from computed kinematics.
    pub fn tcp_from(&self, k: &Kinematics) -> Iso {
        self.flange_from(k) * self.flange_t_tcp()
    }

    /// `base_T_tcp` at `q`.
    pub fn tcp_pose(&self, q: &[f64]) -> Iso {
        self.tcp_from(&self.kinematics(q))
    }

    /// Geometric Jacobian (6 x n, rows `[v; w]`, base frame) of the point `p` (base frame) carried
    /// by the child link of joint `last` and every joint before it.
    pub fn point_jacobian(&self, k: &Kinematics, p: &Point3<f64>, last: usize) -> DMatrix<f64> {
        let mut jac = DMatrix::zeros(6, self.dof());
        for i in 0..=last {
            let z = k.axes[i];
            let (v, w) = match self.joints[i].kind {
                JointKind::Revolute => (
                    z.cross(&(p - Point3::from(k.frames[i].translation.vector))),
                    z,
                ),
                JointKind::Prismatic => (z, Vector3::zeros()),
            };
            jac.fixed_view_mut::<3, 1>(0, i).copy_from(&v);
            jac.fixed_view_mut::<3, 1>(3, i).copy_from(&w);
        }
        jac
    }

    /// Geometric Jacobian of the TCP (the flange without a tool).
    pub fn tcp_jacobian(&self, k: &Kinematics) -> DMatrix<f64> {
        let p = Point3::from(self.tcp_from(k).translation.vector);
        self.point_jacobian(k, &p, self.dof() - 1)
    }

    /// Mass properties of the child link of each joint, the tool included in the last one.
    fn link_inertials(&self) -> Vec<Inertial> {
        let mut out: Vec<Inertial> = self.links.iter().map(|l| l.inertial).collect();
        if let (Some(tool), Some(last)) = (&self.tool, out.last_mut()) {
            *last = last.combined(&tool.inertial.transformed(&self.last_t_flange));
        }
        out
    }

    /// Gravity torques g(q), N m: the joint torques that hold the arm still against `gravity`
    /// (m/s^2, base frame), `sum_i J_com,i^T (-m_i gravity)`.
    pub fn gravity_torques(&self, k: &Kinematics, gravity: &Vector3<f64>) -> DVector<f64> {
        self.link_terms(k, gravity).1
    }

    /// Joint-space inertia M(q), kg m^2: links and tool, plus the rotor inertia on the diagonal.
    pub fn mass_matrix(&self, k: &Kinematics) -> DMatrix<f64> {
        self.link_terms(k, &Vector3::zeros()).0 + self.armature_matrix()
    }

    fn armature_matrix(&self) -> DMatrix<f64> {
        DMatrix::from_diagonal(&DVector::from_row_slice(&self.armature))
    }

    /// The joint-space inertia of links and tool (no rotor inertia) and the gravity torques, from
    /// one pass over the links' centre-of-mass Jacobians.
    fn link_terms(&self, k: &Kinematics, gravity: &Vector3<f64>) -> (DMatrix<f64>, DVector<f64>) {
        let n = self.dof();
        let mut m = DMatrix::zeros(n, n);
        let mut g = DVector::zeros(n);
        for (i, link) in self.link_inertials().iter().enumerate() {
            let com = k.frames[i] * link.com;
            let jac = self.point_jacobian(k, &com, i);
            let jv = jac.fixed_rows::<3>(0);
            let jw = jac.fixed_rows::<3>(3);
            let r = k.frames[i].rotation.to_rotation_matrix();
            let inertia = r.matrix() * link.inertia * r.matrix().transpose();
            // In place: M += m Jv^T Jv + Jw^T I Jw, g += Jv^T (-m gravity).
            m.gemm_tr(link.mass_kg, &jv, &jv, 1.0);
            m.gemm_tr(1.0, &jw, &(inertia * jw), 1.0);
            g.gemv_tr(-link.mass_kg, &jv, gravity, 1.0);
        }
        (m, g)
    }

    /// Everything a control cycle needs at `q`, computed once.
    pub fn dynamics(&self, q: &[f64], gravity: &Vector3<f64>) -> Dynamics {
        let kinematics = self.kinematics(q);
        let (link_mass, gravity_torques) = self.link_terms(&kinematics, gravity);
        Dynamics {
            tcp: self.tcp_from(&kinematics),
            jacobian: self.tcp_jacobian(&kinematics),
            mass: &link_mass + self.armature_matrix(),
            link_mass,
            gravity: gravity_torques,
            kinematics,
        }
    }
}

/// The model evaluated at one configuration (base frame).
pub struct Dynamics {
    pub kinematics: Kinematics,
    /// `base_T_tcp`.
    pub tcp: Iso,
    /// TCP Jacobian, 6 x n, rows `[v; w]`.
    pub jacobian: DMatrix<f64>,
    /// Joint-space inertia of links and tool (what the joint torque sensors carry), kg m^2.
    pub link_mass: DMatrix<f64>,
    /// `link_mass` plus the rotor inertia: the inertia the motors drive.
    pub mass: DMatrix<f64>,
    /// g(q), N m.
    pub gravity: DVector<f64>,
}

impl Dynamics {
    /// `M^-1` (Cholesky; M is positive definite by construction for a finite `q`). A joint state
    /// that is no longer finite gives a NaN matrix, which the cell reports as a `sim_fault`.
    pub fn mass_inverse(&self) -> DMatrix<f64> {
        let n = self.mass.nrows();
        self.mass
            .clone()
            .cholesky()
            .map_or_else(|| DMatrix::from_element(n, n, f64::NAN), |c| c.inverse())
    }

    /// Cartesian inertia at the TCP, `(J M^-1 J^T)^-1` (6 x 6, base frame), from `M^-1`, inverted
    /// with a small damping so that it stays finite near singular configurations.
    pub fn cartesian_inertia(&self, mass_inverse: &DMatrix<f64>) -> Matrix6<f64> {
        let jac = &self.jacobian;
        let inv: Matrix6<f64> = (jac * mass_inverse * jac.transpose())
            .fixed_view::<6, 6>(0, 0)
            .into_owned();
        (inv + Matrix6::identity() * 1e-9)
            .try_inverse()
            .unwrap_or_else(Matrix6::zeros)
    }
}

impl RobotModel {
    /// Joint positions that put the TCP at `target` (`base_T_tcp`), by damped least squares from
    /// `seed`, within 1e-9 m and 1e-9 rad; an error if the pose is out of reach or the solution
    /// leaves the joint limits.
    pub fn inverse_kinematics(&self, target: &Iso, seed: &[f64]) -> Result<Vec<f64>> {
        let mut q = seed.to_vec();
        for _ in 0..200 {
            let k = self.kinematics(&q);
            let tcp = self.tcp_from(&k);
            let dp = target.translation.vector - tcp.translation.vector;
            let dr = (target.rotation * tcp.rotation.inverse()).scaled_axis();
            if dp.norm() < 1e-9 && dr.norm() < 1e-9 {
                self.check_q(&q)?;
                return Ok(q);
            }
            let err = DVector::from_row_slice(&[dp.x, dp.y, dp.z, dr.x, dr.y, dr.z]);
            let jac = self.tcp_jacobian(&k);
            let jjt = &jac * jac.transpose() + DMatrix::identity(6, 6) * 1e-6;
            let step = jac.transpose()
                * jjt
                    .cholesky()
                    .ok_or_else(|| unreachable_pose(target))?
                    .solve(&err);
            for (qi, s) in q.iter_mut().zip(step.iter()) {
                *qi += s.clamp(-0.2, 0.2);
            }
        }
        Err(unreachable_pose(target))
    }
}

/// Seeds the start search draws (after the zero configuration) when a robot has no IK seed.
const START_SEARCH_SEEDS: usize = 64;
/// How high above the table (z = 0 of the base) every joint but the first must stand at the
/// start, m.
const MIN_JOINT_HEIGHT_M: f64 = 0.02;

impl RobotModel {
    /// Joint positions that put the TCP at `target` (`base_T_tcp`) to start a trial: inverse
    /// kinematics from the robot's [`RobotModel::ik_seed`]; without one, from the zero
    /// configuration and [`START_SEARCH_SEEDS`] seeds drawn within the joint limits (clipped to
    /// +-pi) by a fixed-seed generator, keeping the solution with every joint but the first above
    /// the table and the largest manipulability `sqrt(det(J J^T))` (furthest from a singularity).
    /// Deterministic: the same robot and target give the same configuration.
    pub fn start_configuration(&self, target: &Iso) -> Result<Vec<f64>> {
        if let Some(seed) = &self.ik_seed {
            return self.inverse_kinematics(target, seed);
        }
        let mut best: Option<(f64, Vec<f64>)> = None;
        for seed in self.search_seeds() {
            let Ok(q) = self.inverse_kinematics(target, &seed) else {
                continue;
            };
            let k = self.kinematics(&q);
            if k.frames[1..]
                .iter()
                .any(|f| f.translation.z < MIN_JOINT_HEIGHT_M)
            {
                continue;
            }
            let score = self.start_score(&q, &k);
            if best.as_ref().is_none_or(|(b, _)| score > *b) {
                best = Some((score, q));
            }
        }
        best.map(|(_, q)| q).ok_or_else(|| {
            let p = target.translation.vector;
            Error::Input(format!(
                "robot '{}' cannot reach the start pose at ({:.4}, {:.4}, {:.4}) m (base frame) \
                 with the peg pointing down and every joint above the table, from {} seeds \
                 ([robot] hole_xy_mm says where the hole stands; 550, 0 mm by default); \
                 check the robot's tool offset, or give a start_q_deg near a pose that reaches it",
                self.name,
                p.x,
                p.y,
                p.z,
                START_SEARCH_SEEDS + 1
            ))
        })
    }

    /// How good a start `q` is: its manipulability `sqrt(det(J J^T))` (furthest from a
    /// singularity), scaled down as any joint comes within a quarter of its half-range of a limit.
    fn start_score(&self, q: &[f64], k: &Kinematics) -> f64 {
        let jac = self.tcp_jacobian(k);
        let manipulability = (&jac * jac.transpose()).determinant().max(0.0).sqrt();
        let margin = self
            .joints
            .iter()
            .zip(q)
            .map(|(j, &v)| {
                let half = 0.5 * (j.upper - j.lower).min(2.0 * std::f64::consts::TAU);
                ((v - j.lower).min(j.upper - v) / half).min(0.25) / 0.25
            })
            .fold(1.0, f64::min);
        manipulability * margin
    }

    /// The zero configuration (clamped into the limits), then seeds drawn uniformly within the
    /// limits clipped to +-pi.
    fn search_seeds(&self) -> Vec<Vec<f64>> {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(0);
        let range = |j: &Joint| {
            let lim = std::f64::consts::PI;
            (j.lower.max(-lim), j.upper.min(lim))
        };
        let zero = self
            .joints
            .iter()
            .map(|j| 0.0f64.clamp(j.lower, j.upper))
            .collect();
        let drawn = (0..START_SEARCH_SEEDS).map(|_| {
            self.joints
                .iter()
                .map(|j| {
                    let (lo, hi) = range(j);
                    lo + (hi - lo) * rng.random::<f64>()
                })
                .collect()
        });
        let mut seeds = vec![zero];
        seeds.extend(drawn);
        seeds
    }
}

fn unreachable_pose(target: &Iso) -> Error {
    let p = target.translation.vector;
    Error::Input(format!(
        "TCP pose at ({:.4}, {:.4}, {:.4}) m is out of the robot's reach from the seed configuration",
        p.x, p.y, p.z
    ))
}

/// An isometry from URDF-style `xyz` and `rpy` (R = Rz(yaw) Ry(pitch) Rx(roll)).
pub fn iso_xyz_rpy(xyz: [f64; 3], rpy: [f64; 3]) -> Iso {
    Iso::from_parts(
        Translation3::new(xyz[0], xyz[1], xyz[2]),
        UnitQuaternion::from_euler_angles(rpy[0], rpy[1], rpy[2]),
    )
}
