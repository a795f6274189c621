//! The physics world: one place that builds rapier with integration parameters validated for
//! sub-millimetre clearance, puts solids in it, and reads the contact wrench on a body.
//!
//! Parameters (measured and explained in docs/physics.md; re-measured by `pegtwin validate`):
//! contact recycling off (stale contacts let a peg tunnel or jam falsely in a tight hole),
//! contact clustering off (clustered impulses over-report the force), `length_unit` 0.01 m, contact
//! softness 240 Hz (the default 30/60 Hz lets a peg sink into a rim it cannot enter), 1 ms step,
//! 4 solver iterations, Coulomb friction per contact point, predictive contacts 30 um ahead (the
//! arm cell: 10 um, as it also looks ahead at its torques) or further at speed
//! (`set_prediction_for_speed`), and rapier's swept CCD off (it treats a body with 0.3 mm
//! chamfer pieces as "fast" at any speed and sweeps every piece: 54 % of the time of a `gear` step).

pub mod arm;
pub mod compound;
pub mod dispatcher;
pub mod joint_contacts;
pub mod penetration;
pub mod projection;
pub mod sat;
pub mod signed_gap;

use crate::twin::geometry::solid::Solid;
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use rapier3d::prelude::*;

/// Contacts are predicted at least this far (metres) in every step.
pub const MIN_PREDICTION_M: f64 = 30e-6;

/// Integration and contact parameters.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct PhysicsParams {
    /// Physics step, seconds.
    pub dt_s: f64,
    /// Solver iterations (substeps) per step.
    pub solver_iterations: usize,
    /// Projected Gauss-Seidel passes over the constraints in each substep (rapier's
    /// `num_internal_pgs_iterations`). On rapier's contacts (`arm_contacts = "rapier"`) one pass
    /// leaves the contacts of a peg pinched between opposite walls unconverged: the gear at
    /// 0.1 mm on the arm then gains energy about its axis until joint 7 runs away; four passes
    /// converge it in trials at a third of the cost of four substeps, but 13 of the 48 episodes
    /// of its manifold build still fault there, and eight passes leave none (docs/physics.md,
    /// "The arm at 0.1 mm"). The joint-space contacts do not use them. The arm cell uses four
    /// (`twin::workcell::ARM_PGS_ITERATIONS`); the free peg of `validate`, with four substeps, one.
    pub pgs_iterations: usize,
    /// rapier's length unit, metres.
    pub length_unit_m: f64,
    /// Contact constraint natural frequency, Hz (dynamic and static contacts).
    pub contact_frequency_hz: f64,
    /// Coulomb friction coefficient between peg and hole while they slide (kinetic).
    pub friction: f64,
    /// The static coefficient (at least `friction`) of a contact point at rest; absent: the
    /// kinetic one (no stiction peak). The arm's joint-space contacts use it ([`ContactFriction`]);
    /// rapier's contacts (the free peg's, the arm's with `arm_contacts = "rapier"`) take the
    /// kinetic one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub static_friction: Option<f64>,
    /// Position projection of the arm's peg after every step (`projection`): what its exact
    /// pieces still overlap after the velocity-level solve is moved out. Experimental and off by
    /// default: it takes `validate --arm`'s motion cases at 0.1 mm from 12-43 um to under 2 um
    /// on four built-ins, but it lowers the smoke campaign's manifold success at 0.5 mm from 6/8
    /// to 1/8 (docs/journal/2026-11-25.md, "Position projection"); the arm cell only.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub position_projection: bool,
    /// Who solves the arm's peg contacts: an exact Newton solve in joint space
    /// (`joint_contacts`, the default), or rapier's multibody contact rows (the default until
    /// 2026-11-26); the arm cell only. Not written when it is rapier's, so that the cache keys
    /// of manifolds built with rapier's contacts before the switch still find them.
    #[serde(skip_serializing_if = "ArmContacts::is_rapier")]
    pub arm_contacts: ArmContacts,
    /// The arm's joint friction (`joint_friction`); none unless given here or in the robot's
    /// file. Not written when it is the default, so that earlier cache keys still hold.
    #[serde(default, skip_serializing_if = "JointFriction::is_default")]
    pub joint_friction: JointFriction,
}

/// Coulomb friction with stiction in each of the arm's joints, on the motor side of its torque
/// sensor, as in the iiwa's gear units (their sensors sit at the gear output): the torque
/// sensors and the wrench estimate do not read it as contact. It is solved with the peg's
/// contacts in joint space (`joint_contacts`), so a stuck joint holds without chatter and breaks
/// away where its torque exceeds the static value; the joints' viscous friction is their
/// `<dynamics damping>`.
///
/// A joint sliding at speed `v` resists with `F_c + (F_s - F_c) exp(-(v / v_s)^2)` (the Stribeck
/// curve, its speed taken at the start of the step), a joint at rest with up to `F_s`.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct JointFriction {
    /// Coulomb (sliding) friction per joint, N m; absent: the robot file's `<dynamics friction>`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub coulomb_nm: Option<Vec<f64>>,
    /// Static (breakaway) friction per joint, N m, each at least its Coulomb value; absent: the
    /// Coulomb values (no stiction peak).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub static_nm: Option<Vec<f64>>,
    /// The Stribeck speed, rad/s: how fast the friction falls from static to Coulomb as a
    /// joint speeds up; absent: [`STRIBECK_SPEED_RAD_PER_S`].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stribeck_rad_per_s: Option<f64>,
}

/// The joint friction of one arm, resolved ([`JointFriction::resolve`]).
#[derive(Clone, Debug, PartialEq)]
pub struct FrictionLaw {
    pub coulomb_nm: Vec<f64>,
    pub static_nm: Vec<f64>,
    pub stribeck_rad_per_s: f64,
}

impl FrictionLaw {
    /// Joint `i`'s friction torque at speed `v` (rad/s), N m: the Stribeck curve.
    pub fn torque_nm(&self, i: usize, v: f64) -> f64 {
        let (c, s) = (self.coulomb_nm[i], self.static_nm[i]);
        c + (s - c) * (-(v / self.stribeck_rad_per_s).powi(2)).exp()
    }

    /// Each joint's friction bound over a step of `dt` s that starts at speeds `qd`, N m s.
    pub fn bounds(&self, qd: &[f64], dt: f64) -> Vec<f64> {
        qd.iter()
            .enumerate()
            .map(|(i, &v)| self.torque_nm(i, v) * dt)
            .collect()
    }
}

/// The default Stribeck speed, rad/s (real-cell.md, section 2: about 0.01 rad/s).
pub const STRIBECK_SPEED_RAD_PER_S: f64 = 0.01;
/// Largest joint friction accepted, N m: beyond the iiwa's smallest drive torque (40 N m).
pub const MAX_JOINT_FRICTION_NM: f64 = 40.0;
/// Accepted Stribeck speeds, rad/s.
pub const STRIBECK_RANGE_RAD_PER_S: (f64, f64) = (1e-4, 10.0);

impl JointFriction {
    fn is_default(&self) -> bool {
        *self == JointFriction::default()
    }

    /// The law of a robot whose file gives `file_coulomb_nm` per joint; `None` when every joint
    /// is frictionless. Errors name the field and what was expected.
    pub fn resolve(&self, file_coulomb_nm: &[f64]) -> crate::error::Result<Option<FrictionLaw>> {
        self.ensure_valid()?;
        let n = file_coulomb_nm.len();
        let per_joint = |field: &str, v: &Option<Vec<f64>>, default: &[f64]| match v {
            Some(v) if v.len() != n => Err(crate::error::Error::Input(format!(
                "physics.joint_friction.{field}: {} values for a robot of {n} joints",
                v.len()
            ))),
            Some(v) => Ok(v.clone()),
            None => Ok(default.to_vec()),
        };
        let coulomb = per_joint("coulomb_nm", &self.coulomb_nm, file_coulomb_nm)?;
        let stiction = per_joint("static_nm", &self.static_nm, &coulomb)?;
        if let Some(i) = (0..n).find(|&i| stiction[i] < coulomb[i]) {
            return Err(crate::error::Error::Input(format!(
                "physics.joint_friction.static_nm[{i}] = {}: expected at least the joint's \
                 Coulomb friction {} N m",
                stiction[i], coulomb[i]
            )));
        }
        let stribeck_rad_per_s = self.stribeck_rad_per_s.unwrap_or(STRIBECK_SPEED_RAD_PER_S);
        Ok(stiction.iter().any(|&s| s > 0.0).then_some(FrictionLaw {
            coulomb_nm: coulomb,
            static_nm: stiction,
            stribeck_rad_per_s,
        }))
    }

    /// Refuses values outside their ranges, naming the field.
    fn ensure_valid(&self) -> crate::error::Result<()> {
        for (field, values) in [
            ("coulomb_nm", &self.coulomb_nm),
            ("static_nm", &self.static_nm),
        ] {
            for (i, v) in values.iter().flatten().enumerate() {
                if !(0.0..=MAX_JOINT_FRICTION_NM).contains(v) {
                    return Err(crate::error::Error::Input(format!(
                        "physics.joint_friction.{field}[{i}] = {v:?}: expected a torque in \
                         [0, {MAX_JOINT_FRICTION_NM}] N m"
                    )));
                }
            }
        }
        if let Some(v) = self.stribeck_rad_per_s {
            let (lo, hi) = STRIBECK_RANGE_RAD_PER_S;
            if !(lo..=hi).contains(&v) {
                return Err(crate::error::Error::Input(format!(
                    "physics.joint_friction.stribeck_rad_per_s = {v:?}: expected a speed in \
                     [{lo}, {hi}] rad/s"
                )));
            }
        }
        Ok(())
    }
}

/// The solver of the arm's peg contacts.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ArmContacts {
    /// rapier's projected Gauss-Seidel over multibody contact rows, soft at 240 Hz.
    Rapier,
    /// Newton's method on the joint-space contact problem (`joint_contacts`).
    JointSpace,
}

impl ArmContacts {
    fn is_rapier(&self) -> bool {
        *self == ArmContacts::Rapier
    }
}

impl Default for PhysicsParams {
    fn default() -> Self {
        PhysicsParams {
            dt_s: 1e-3,
            solver_iterations: 4,
            pgs_iterations: 1,
            length_unit_m: 0.01,
            contact_frequency_hz: 240.0,
            friction: 0.3,
            static_friction: None,
            position_projection: false,
            arm_contacts: ArmContacts::JointSpace,
            joint_friction: JointFriction::default(),
        }
    }
}

/// Accepted physics settings: step (s), substeps and PGS passes, contact natural frequency (Hz),
/// friction coefficient. Outside them a run either does not resolve a 0.1 mm gap or does unbounded
/// work per simulated second.
pub const DT_RANGE_S: (f64, f64) = (1e-5, 1e-3);
pub const ITERATIONS_RANGE: (usize, usize) = (1, 50);
pub const CONTACT_FREQUENCY_RANGE_HZ: (f64, f64) = (1.0, 10_000.0);
pub const FRICTION_RANGE: (f64, f64) = (0.0, 2.0);

/// A contact point slower than about this at the start of a step is at rest, m/s: the friction
/// falls from static to kinetic over it ([`ContactFriction::at`]).
pub const CONTACT_STRIBECK_M_PER_S: f64 = 1e-3;

/// Coulomb friction between the peg and what it touches, with stiction: a point sliding at `v`
/// (m/s, at the start of the step) has the coefficient
/// `mu_k + (mu_s - mu_k) exp(-(v / v_s)^2)`, `v_s` = [`CONTACT_STRIBECK_M_PER_S`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ContactFriction {
    pub kinetic: f64,
    pub static_: f64,
}

impl ContactFriction {
    /// The coefficient of a point sliding at `slip_m_per_s`.
    pub fn at(&self, slip_m_per_s: f64) -> f64 {
        if self.static_ > self.kinetic {
            let fall = (-(slip_m_per_s / CONTACT_STRIBECK_M_PER_S).powi(2)).exp();
            self.kinetic + (self.static_ - self.kinetic) * fall
        } else {
            self.kinetic
        }
    }
}

impl PhysicsParams {
    /// The peg's contact friction.
    pub fn contact_friction(&self) -> ContactFriction {
        ContactFriction {
            kinetic: self.friction,
            static_: self.static_friction.unwrap_or(self.friction),
        }
    }

    /// Refuses settings outside the accepted ranges, naming the field (as in a scenario's
    /// `[physics]` section) and the range.
    pub fn ensure_valid(&self) -> crate::error::Result<()> {
        let bad = |field: &str, v: String, range: String| {
            Err(crate::error::Error::Input(format!(
                "physics.{field} = {v}: expected {range}"
            )))
        };
        let within = |v: f64, (lo, hi): (f64, f64)| v >= lo && v <= hi;
        if !within(self.dt_s, DT_RANGE_S) {
            let (lo, hi) = DT_RANGE_S;
            return bad(
                "dt_s",
                format!("{:?}", self.dt_s),
                format!("a step in [{lo}, {hi}] s"),
            );
        }
        for (field, n) in [
            ("solver_iterations", self.solver_iterations),
            ("pgs_iterations", self.pgs_iterations),
        ] {
            let (lo, hi) = ITERATIONS_RANGE;
            if !(lo..=hi).contains(&n) {
                return bad(field, n.to_string(), format!("{lo} to {hi}"));
            }
        }
        if !within(self.contact_frequency_hz, CONTACT_FREQUENCY_RANGE_HZ) {
            let (lo, hi) = CONTACT_FREQUENCY_RANGE_HZ;
            let range = format!("a frequency in [{lo}, {hi}] Hz");
            return bad(
                "contact_frequency_hz",
                format!("{:?}", self.contact_frequency_hz),
                range,
            );
        }
        if !within(self.friction, FRICTION_RANGE) {
            let (lo, hi) = FRICTION_RANGE;
            let range = format!("a coefficient in [{lo}, {hi}]");
            return bad("friction", format!("{:?}", self.friction), range);
        }
        if let Some(s) = self.static_friction
            && !(within(s, FRICTION_RANGE) && s >= self.friction)
        {
            let hi = FRICTION_RANGE.1;
            let range = format!("a coefficient in [friction = {}, {hi}]", self.friction);
            return bad("static_friction", format!("{s:?}"), range);
        }
        self.joint_friction.ensure_valid()
    }

    /// rapier's integration parameters for these settings.
    pub fn integration_parameters(&self) -> IntegrationParameters {
        let mut p = IntegrationParameters {
            dt: self.dt_s as f32,
            num_solver_iterations: self.solver_iterations,
            num_internal_pgs_iterations: self.pgs_iterations,
            length_unit: self.length_unit_m as f32,
            contact_recycling: false,
            contact_clustering: false,
            friction_model: FrictionModel::Coulomb,
            normalized_prediction_distance: (MIN_PREDICTION_M / self.length_unit_m) as f32,
            max_ccd_substeps: 0,
            ..Default::default()
        };
        p.contact_softness.natural_frequency = self.contact_frequency_hz as f32;
        p.static_contact_softness.natural_frequency = self.contact_frequency_hz as f32;
        p
    }

    /// An empty world with gravity -9.81 m/s^2 along z.
    pub fn new_world(&self) -> PhysicsWorld {
        let mut world = PhysicsWorld::new();
        world.narrow_phase = NarrowPhase::with_query_dispatcher(dispatcher::ExactConvexDispatcher);
        world.gravity = Vector::new(0.0, 0.0, -9.81);
        world.integration_parameters = self.integration_parameters();
        world
    }
}

/// A copy of `world` that steps on exactly as `world` would: every body, collider, joint and
/// contact (with its warm-start impulses) is cloned, and the copy gets a new pipeline. rapier's
/// `PhysicsPipeline` holds only workspaces that each step refills, and cannot be cloned
/// (`WorkCell::fork` forks a cell through this, for the trials of a campaign that share their
/// observation; the test `a_forked_cell_steps_on_as_the_original` checks it bit for bit).
pub fn fork_world(world: &PhysicsWorld) -> PhysicsWorld {
    PhysicsWorld {
        gravity: world.gravity,
        integration_parameters: world.integration_parameters,
        physics_pipeline: PhysicsPipeline::new(),
        collision_pipeline: CollisionPipeline::new(),
        islands: world.islands.clone(),
        broad_phase: world.broad_phase.clone(),
        narrow_phase: world.narrow_phase.clone(),
        bodies: world.bodies.clone(),
        colliders: world.colliders.clone(),
        impulse_joints: world.impulse_joints.clone(),
        multibody_joints: world.multibody_joints.clone(),
        soft_bodies: world.soft_bodies.clone(),
        ccd_solver: world.ccd_solver.clone(),
    }
}

/// Sets the world's contact prediction distance for the coming step: at least `floor_m`
/// (metres; [`MIN_PREDICTION_M`] for the free peg), and 1.5 times the distance a point moving at
/// `max_point_speed` (m/s) covers in one step, so that a fast peg still meets a rim it drops
/// onto. rapier's per-body soft CCD does the same but drops every contact of a body resting a
/// micrometre above a face (its pre-check uses bounding boxes without margin), so pegtwin adapts
/// the world's distance instead.
pub fn set_prediction_for_speed(world: &mut PhysicsWorld, max_point_speed: f64, floor_m: f64) {
    let p = &mut world.integration_parameters;
    let distance = floor_m.max(1.5 * max_point_speed * p.dt as f64);
    p.normalized_prediction_distance = (distance / p.length_unit as f64) as f32;
}

/// The largest speed (m/s) of any point of a body within `radius` metres of its centre of mass.
pub fn max_point_speed(world: &PhysicsWorld, body: RigidBodyHandle, radius: f64) -> f64 {
    let rb = &world.bodies[body];
    v64(rb.linvel()).norm() + v64(rb.angvel()).norm() * radius
}

/// A force and a torque, N and N m, in the world frame.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Wrench {
    pub force: Vector3<f64>,
    pub torque: Vector3<f64>,
}

/// glam vector to nalgebra f64.
pub fn v64(v: Vector) -> Vector3<f64> {
    Vector3::new(v.x as f64, v.y as f64, v.z as f64)
}

/// nalgebra f64 vector to glam.
pub fn v32(v: &Vector3<f64>) -> Vector {
    Vector::new(v.x as f32, v.y as f32, v.z as f32)
}

/// A rapier pose as an f64 isometry.
pub fn pose64(p: &Pose) -> Isometry3<f64> {
    let iso: Isometry3<f32> = (*p).into();
    iso.cast::<f64>()
}

/// An f64 isometry as a rapier pose.
pub fn pose32(p: &Isometry3<f64>) -> Pose {
    let t = Translation3::from(p.translation.vector.cast::<f32>());
    let r: UnitQuaternion<f32> = p.rotation.cast::<f32>();
    Isometry3::from_parts(t, r).into()
}

/// One compound collider made of a solid's convex pieces, every one of them: the loaders refuse
/// a piece the engine cannot take (`ConvexPiece::collider_shape`), so none is dropped here.
pub fn compound_collider(solid: &Solid, friction: f64) -> ColliderBuilder {
    let shapes: Vec<(Pose, SharedShape)> = solid
        .pieces
        .iter()
        .map(|p| {
            let shape = p
                .collider_shape()
                .expect("every piece of a solid was checked by its loader");
            (Pose::from_translation(v32(&p.centroid().coords)), shape)
        })
        .collect();
    ColliderBuilder::compound(shapes).friction(friction as f32)
}

/// Adds a fixed solid at `pose`; returns its collider.
pub fn add_fixed(
    world: &mut PhysicsWorld,
    solid: &Solid,
    pose: &Isometry3<f64>,
    friction: f64,
) -> ColliderHandle {
    let body = world.insert_body(RigidBodyBuilder::fixed().pose(pose32(pose)));
    world.insert_collider(compound_collider(solid, friction), Some(body))
}

/// Adds a dynamic solid of `mass_kg` (uniform density) at `pose`; returns body and collider.
pub fn add_dynamic(
    world: &mut PhysicsWorld,
    solid: &Solid,
    pose: &Isometry3<f64>,
    mass_kg: f64,
    friction: f64,
) -> (RigidBodyHandle, ColliderHandle) {
    let body = world.insert_body(
        RigidBodyBuilder::dynamic()
            .pose(pose32(pose))
            .can_sleep(false),
    );
    let collider = world.insert_collider(
        compound_collider(solid, friction).mass(mass_kg as f32),
        Some(body),
    );
    (body, collider)
}

/// How many contact points the solver handled on `collider` in the last step (each is one or more
/// constraint rows: the cost of a multibody contact grows with them).
pub fn solver_contact_count(world: &PhysicsWorld, collider: ColliderHandle) -> usize {
    world
        .narrow_phase
        .contact_pairs_with(collider)
        .filter_map(|pair| pair.rigid())
        .flat_map(|rigid| rigid.solver_manifolds())
        .map(|m| m.data.solver_contacts.len())
        .sum()
}

/// The smallest gap (metres; negative: overlapping) among the solver's contact points on
/// `collider` at the bodies' current poses: each solver contact keeps its two surface points on
/// their bodies, and their separation along the manifold normal is the gap the solver would see.
pub fn min_solver_gap(world: &PhysicsWorld, collider: ColliderHandle) -> f64 {
    let mut gap = f64::INFINITY;
    for rigid in world
        .narrow_phase
        .contact_pairs_with(collider)
        .filter_map(|pair| pair.rigid())
    {
        for manifold in rigid.solver_manifolds() {
            let normal = manifold.data.normal;
            for contact in &manifold.data.solver_contacts {
                let (p1, p2) = manifold
                    .data
                    .solver_contact_world_points(contact, &world.bodies);
                gap = gap.min((p2 - p1).dot(normal) as f64);
            }
        }
    }
    gap
}

/// The contact wrench that all other colliders exert on `collider` during the last step, from the
/// solver's normal and friction impulses divided by the step; the torque is about `about` (world).
pub fn contact_wrench(
    world: &PhysicsWorld,
    collider: ColliderHandle,
    about: Vector3<f64>,
) -> Wrench {
    let dt = world.integration_parameters.dt as f64;
    let mut w = Wrench::default();
    for pair in world.narrow_phase.contact_pairs_with(collider) {
        // Impulses are stored as applied to collider1's body.
        let sign = if pair.collider1 == collider {
            1.0
        } else {
            -1.0
        };
        let Some(rigid) = pair.rigid() else {
            continue;
        };
        for manifold in rigid.solver_manifolds() {
            let dir1 = -manifold.data.normal;
            let t1 = rapier3d::utils::OrthonormalBasis::orthonormal_vector(dir1);
            let t2 = dir1.cross(t1);
            for contact in &manifold.data.solver_contacts {
                let point = &manifold.points[contact.contact_id[0] as usize & 0x7fff_ffff];
                let data = &point.data;
                let impulse =
                    dir1 * data.impulse + t1 * data.tangent_impulse.x + t2 * data.tangent_impulse.y;
                let f = v64(impulse) * (sign / dt);
                let (p1, p2) = manifold
                    .data
                    .solver_contact_world_points(contact, &world.bodies);
                let at = v64((p1 + p2) * 0.5);
                w.force += f;
                w.torque += (at - about).cross(&f);
            }
        }
    }
    w
}
