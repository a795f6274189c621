//! The cell: the robot base on a table at the world origin, the hole fixture standing on the
//! table in front of it, the peg rigidly on the flange, the controller and the sensors, stepped
//! together. One control cycle (default 1 kHz) reads the sensors, runs the estimator and the
//! controller; the torques are held over the physics steps of the cycle.
//!
//! Frames: `world` = `base` (the base stands upright at the origin, z up), `hole` (mouth centre,
//! z out of the hole), `tcp` = the peg frame (tip centre, z up the peg, so pointing at the flange
//! when the peg hangs from it).

use crate::error::{Error, Result};
use crate::twin::control::{Controller, ControllerParams, ImpedanceGains, Mode};
use crate::twin::energy::{EnergyFlows, EnergyLedger, StepEnergy};
use crate::twin::geometry::PartPair;
use crate::twin::physics::arm::Arm;
use crate::twin::physics::joint_contacts::{self, ContactSolve};
use crate::twin::physics::penetration::PenetrationProbe;
use crate::twin::physics::projection;
use crate::twin::physics::{
    ArmContacts, PhysicsParams, add_fixed, compound_collider, contact_wrench, fork_world,
    max_point_speed, set_prediction_for_speed, v64,
};
use crate::twin::robot::spec::RobotSpec;
use crate::twin::robot::{Dynamics, Inertial, Iso, RobotModel, Tool};
use crate::twin::sensing::{SensorParams, Sensors, Wrench6};
use nalgebra::{DVector, Point3, Translation3, UnitQuaternion, Vector3, Vector6};
use rapier3d::prelude::{ColliderBuilder, ColliderHandle, InteractionGroups, PhysicsWorld};
use serde::{Deserialize, Serialize};

/// Solver iterations (substeps) of the arm cell. rapier rebuilds the multibody's mass matrix in
/// every substep; two substeps instead of the free peg's four make the arm cell 1.35 x faster,
/// and the cell's tests hold with them (insertion at 0.1 mm with at most 5 um penetration, stall
/// when misaligned, the press estimate within 1 N), as measured for the arm (docs/robot.md).
pub const ARM_SOLVER_ITERATIONS: usize = 2;

/// Projected Gauss-Seidel passes per substep of the arm cell, for what rapier's solver still
/// holds (the peg's contacts only with `arm_contacts = "rapier"`). There, one pass leaves the
/// contacts of a peg pinched between opposite walls unconverged (the gear at 0.1 mm: 4 of 8
/// direct trials fault with one pass, none with four); four cost a third of the arm's speed
/// (docs/journal/2026-11-23.md, "The arm at 0.1 mm").
pub const ARM_PGS_ITERATIONS: usize = 4;

/// The arm cell's floor of the contact prediction distance, m. The distance is otherwise 1.5
/// times how far the peg's fastest point gets in the step, at its speed now plus what the
/// torques of the last control cycle add in one step ([`Cell::accel_ahead`]): the floor covers
/// only what neither foresees (contact impulses, the velocity-squared terms). The free peg of
/// `validate` keeps 30 um ([`crate::twin::physics::MIN_PREDICTION_M`]). A piece pair within the
/// distance is tested at every step, and 10 um instead of 30 halves the gear's step at 0.1 mm
/// (docs/performance.md).
pub const ARM_MIN_PREDICTION_M: f64 = 10e-6;

/// The arm cell's contact prediction in words, for the manifold cache's key: a manifold built
/// under an earlier rule is rebuilt, not reused.
pub const ARM_PREDICTION_RULE: &str = "1.5 x (speed + torque lookahead) x dt, 10 um floor";

/// Cell layout and the parameters of everything in it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CellParams {
    #[serde(skip)]
    pub physics: PhysicsParams,
    pub controller: ControllerParams,
    pub sensors: SensorParams,
    /// Nominal hole mouth position in the base frame, x and y, m.
    pub hole_xy_m: [f64; 2],
    /// Mass of the peg with its holder, kg.
    pub peg_mass_kg: f64,
}

impl Default for CellParams {
    fn default() -> Self {
        CellParams {
            physics: PhysicsParams {
                solver_iterations: ARM_SOLVER_ITERATIONS,
                pgs_iterations: ARM_PGS_ITERATIONS,
                ..PhysicsParams::default()
            },
            controller: ControllerParams::default(),
            sensors: SensorParams::default(),
            hole_xy_m: [0.55, 0.0],
            peg_mass_kg: BUILTIN_PEG_MASS_KG,
        }
    }
}

impl CellParams {
    /// Everything a cell checks when it is built, checked up front (so a campaign refuses a
    /// setting before it writes anything): physics ranges, a control period that is a whole
    /// number of physics steps, the sensors, the peg mass.
    pub fn ensure_valid(&self) -> Result<()> {
        self.physics.ensure_valid()?;
        steps_per_control_cycle(self)?;
        self.sensors
            .ensure_valid()
            .map_err(|e| Error::Input(format!("sensors: {e}")))?;
        if !(self.peg_mass_kg > 0.0 && self.peg_mass_kg <= MAX_PEG_MASS_KG) {
            return Err(Error::Input(format!(
                "peg mass {} kg: expected more than 0 and at most {MAX_PEG_MASS_KG} kg (the iiwa 14's payload)",
                self.peg_mass_kg
            )));
        }
        Ok(())
    }
}

impl CellParams {
    /// These parameters with the hole where `robot`'s cell stands it (its `hole_xy_m`, if any).
    pub fn placed_for(mut self, robot: &RobotSpec) -> Self {
        if let Some(xy) = robot.hole_xy_m {
            self.hole_xy_m = xy;
        }
        self
    }
}

/// Mass of a built-in peg with its holder, kg (the free-peg self-check holds every peg at it).
pub const BUILTIN_PEG_MASS_KG: f64 = 0.3;
/// The heaviest peg with its holder, kg: the iiwa 14's rated payload.
pub const MAX_PEG_MASS_KG: f64 = 14.0;

/// Length of a peg from its tip (z = 0) to its top face, m.
pub fn peg_length(pair: &PartPair) -> f64 {
    pair.peg.bounds().1.z
}

/// `flange_T_tcp` for a peg held by its top face, tip away from the flange.
pub fn flange_t_tcp(pair: &PartPair) -> Iso {
    Iso::from_parts(
        Translation3::new(0.0, 0.0, peg_length(pair)),
        UnitQuaternion::from_euler_angles(std::f64::consts::PI, 0.0, 0.0),
    )
}

/// The nominal hole pose, base frame: the fixture's bottom on the table (z = 0), hole z up.
pub fn nominal_hole_pose(pair: &PartPair, params: &CellParams) -> Iso {
    let height = -pair.hole.bounds().0.z;
    Iso::translation(params.hole_xy_m[0], params.hole_xy_m[1], height)
}

/// The TCP pose (base frame) of a peg aligned with a hole at `base_t_hole`, its tip `depth_m`
/// below the mouth (negative: above).
pub fn tcp_in_hole(base_t_hole: &Iso, depth_m: f64) -> Iso {
    base_t_hole * Iso::translation(0.0, 0.0, -depth_m)
}

/// The simulated cell, seen through its ports as the real cell is (as Drake's systems are):
/// commands in ([`Cell::command_pose`], [`Cell::switch_gains`], [`Cell::set_mode`]),
/// [`Measurements`] out. The ground truth (true pose, true contact wrench, joint state) is behind
/// [`Cell::truth`], for scoring, validation and traces only; the method never holds a `Cell` (it
/// drives a `method::session::Session`, which lends it the ports alone).
pub struct Cell {
    world: PhysicsWorld,
    arm: Arm,
    /// The robot model with the peg as its tool.
    model: RobotModel,
    controller: Controller,
    sensors: Sensors,
    /// True hole pose, base frame (`None`: no fixture, free space).
    base_t_hole: Option<Iso>,
    peg: ColliderHandle,
    peg_reach_m: f64,
    steps_per_cycle: usize,
    steps: u64,
    /// Physics step, s.
    dt_s: f64,
    /// Torques being applied, N m.
    tau: DVector<f64>,
    /// Link-side joint torques of the last physics step, N m.
    tau_link: DVector<f64>,
    /// Joint velocities after the last physics step, rad/s.
    qd: Vec<f64>,
    /// Bound on the acceleration of the peg's points under the torques of the last control
    /// cycle, free of contact (`free_acceleration_bound`), m/s^2.
    accel_ahead: f64,
    /// An external wrench pushed onto the TCP (base frame, torque about the TCP), for diagnostics.
    disturbance: Option<Wrench6>,
    /// TCP pose from the encoder readings of the last control cycle (base frame): the model's
    /// forward kinematics, evaluated once per cycle by the controller's model evaluation.
    tcp_measured: Iso,
    /// Exact penetration check of the peg against the fixture (fault detection).
    probe: Option<(PenetrationProbe, crate::twin::geometry::solid::Solid)>,
    /// Largest exact penetration before the physics counts as blown up, m.
    penetration_fault_m: f64,
    /// Per joint: the last time its commanded torque was clamped to its limit, s.
    saturated_at_s: Vec<f64>,
    /// The arm's energy account of the last 100 ms (who pays for a fault).
    energy: EnergyLedger,
    /// Whether each step ends with a position projection (`PhysicsParams::position_projection`).
    position_projection: bool,
    /// Whether the peg's contacts are solved in joint space (`PhysicsParams::arm_contacts`), and
    /// what that solve did in the last step (`None`: no contact, or rapier solves them).
    joint_space_contacts: bool,
    peg_contacts: Option<ContactSolve>,
    /// Coulomb friction between the peg and what it touches.
    friction: f64,
}

/// Bound on the acceleration (m/s^2) of any point of the tool within `reach_m` of the TCP, free
/// of contact, under the torques `tau` at the joint speeds `qd` (rad/s) and the viscous damping
/// of `model`'s joints: `qdd = M^-1 (tau - g - D qd)`, at the TCP `J qdd = [a; alpha]`, and
/// `|a| + |alpha| reach_m`. The velocity-squared terms are left out (small at the arm's speeds
/// beside what a change of torque brings). A mass matrix that does not factor (a joint state no
/// longer finite, which the cell reports as a `sim_fault`) gives 0.
fn free_acceleration_bound(
    model: &RobotModel,
    d: &Dynamics,
    tau: &DVector<f64>,
    qd: &[f64],
    reach_m: f64,
) -> f64 {
    let damping = |i: usize| model.joints[i].damping;
    let rhs = DVector::from_fn(tau.len(), |i, _| tau[i] - d.gravity[i] - damping(i) * qd[i]);
    let Some(chol) = d.mass.clone().cholesky() else {
        return 0.0;
    };
    let tcp = &d.jacobian * chol.solve(&rhs);
    tcp.fixed_rows::<3>(0).norm() + tcp.fixed_rows::<3>(3).norm() * reach_m
}

/// What the robot reports, as of its last control cycle: the only inputs of the method.
#[derive(Clone, Copy, Debug)]
pub struct Measurements {
    /// Simulated time, s.
    pub time_s: f64,
    /// TCP pose from the encoder readings (forward kinematics), base frame.
    pub tcp: Iso,
    /// Estimated external wrench at the TCP from the joint torque sensors (base frame, torque
    /// about the TCP), N and N m.
    pub wrench: Wrench6,
    /// The estimator's contact flag (with hysteresis).
    pub contact: bool,
}

/// The simulation's ground truth: for scoring, validating the physics and traces, never an input
/// of the method.
pub struct Truth<'a> {
    cell: &'a Cell,
}

impl Truth<'_> {
    /// True joint positions, rad.
    pub fn q(&self) -> Vec<f64> {
        self.cell.arm.q(&self.cell.world)
    }

    /// True poses of the base link (the identity) and of each moving link, base frame: the
    /// model's forward kinematics at the true joint positions.
    pub fn link_poses(&self) -> Vec<Iso> {
        let frames = self.cell.model.kinematics(&self.q()).frames;
        std::iter::once(Iso::identity()).chain(frames).collect()
    }

    /// Contact points the solver handled on the peg in the last step.
    pub fn solver_contacts(&self) -> usize {
        if self.cell.joint_space_contacts {
            return self.cell.peg_contacts.as_ref().map_or(0, |c| c.points);
        }
        crate::twin::physics::solver_contact_count(&self.cell.world, self.cell.peg)
    }

    /// True TCP pose, base frame.
    pub fn tcp_pose(&self) -> Iso {
        self.cell.true_tcp_pose()
    }

    /// True hole pose, base frame (`None`: no fixture).
    pub fn base_t_hole(&self) -> Option<Iso> {
        self.cell.base_t_hole
    }

    /// True contact wrench on the peg from the physics (base frame, torque about the TCP).
    pub fn contact_wrench(&self) -> Wrench6 {
        if self.cell.joint_space_contacts {
            // Already in the base frame, about the TCP at the start of the step.
            return self
                .cell
                .peg_contacts
                .as_ref()
                .map_or(Wrench6::zeros(), |c| {
                    let (f, t) = (c.force, c.torque);
                    Vector6::new(f.x, f.y, f.z, t.x, t.y, t.z)
                });
        }
        let tcp = self.tcp_pose().translation.vector;
        let w = contact_wrench(&self.cell.world, self.cell.peg, tcp);
        let r = self.cell.arm.world_t_base.rotation.inverse();
        let (f, t) = (r * w.force, r * w.torque);
        Vector6::new(f.x, f.y, f.z, t.x, t.y, t.z)
    }
}

/// Why a simulation stopped being trustworthy.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SimFault {
    /// Simulated time of detection, s.
    pub time_s: f64,
    pub reason: String,
    /// The joints whose commanded torque sat at its limit within the last 100 ms before the
    /// fault: the commanded motion asked more of the arm than its drives give (the real robot
    /// would stop on its torque monitoring too).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub saturated_joints: Vec<String>,
    /// The arm's energy account of the last 100 ms before the fault: who put the energy in
    /// (the drives: the commanded motion; the contacts or the integrator: the physics).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub energy: Option<EnergyFlows>,
}

impl SimFault {
    /// Whether the physics (the contact solve or the integrator), not the drives, put in the
    /// energy that ended the run; `None` when the record has no energy account (older records).
    pub fn is_physics(&self) -> Option<bool> {
        self.energy.as_ref().map(|e| e.source.is_physics())
    }
}

/// Rounds of position projection per step at most.
const PROJECTION_ROUNDS: usize = 3;
/// Steps between exact penetration checks.
const PENETRATION_CHECK_STEPS: u64 = 250;
/// A joint faster than this multiple of its speed limit is a runaway.
const RUNAWAY_FACTOR: f64 = 3.0;
/// How long before a fault a torque at its limit counts as the fault's cause, s.
pub const SATURATION_WINDOW_S: f64 = 0.1;

impl Cell {
    /// An independent copy of the cell that steps on bit for bit as this one would
    /// ([`fork_world`]): two trials whose first stages are the same simulation run them once and
    /// branch here.
    pub fn fork(&self) -> Cell {
        Cell {
            world: fork_world(&self.world),
            arm: self.arm.clone(),
            model: self.model.clone(),
            controller: self.controller.clone(),
            sensors: self.sensors.clone(),
            base_t_hole: self.base_t_hole,
            peg: self.peg,
            peg_reach_m: self.peg_reach_m,
            steps_per_cycle: self.steps_per_cycle,
            steps: self.steps,
            dt_s: self.dt_s,
            tau: self.tau.clone(),
            tau_link: self.tau_link.clone(),
            qd: self.qd.clone(),
            accel_ahead: self.accel_ahead,
            disturbance: self.disturbance,
            tcp_measured: self.tcp_measured,
            probe: self.probe.clone(),
            penetration_fault_m: self.penetration_fault_m,
            saturated_at_s: self.saturated_at_s.clone(),
            energy: self.energy.clone(),
            position_projection: self.position_projection,
            joint_space_contacts: self.joint_space_contacts,
            peg_contacts: self.peg_contacts.clone(),
            friction: self.friction,
        }
    }

    /// Builds the cell with the arm at rest at `start_tcp` (base frame) under Cartesian impedance
    /// with `gains`; `base_t_hole: None` leaves the fixture out.
    pub fn new(
        pair: &PartPair,
        robot: RobotModel,
        params: &CellParams,
        base_t_hole: Option<Iso>,
        start_tcp: &Iso,
        gains: ImpedanceGains,
        seed: u64,
    ) -> Result<Cell> {
        params.ensure_valid()?;
        let steps_per_cycle = steps_per_control_cycle(params)?;
        let dt = params.physics.dt_s;
        let friction = params.physics.friction;
        let tcp_on_flange = flange_t_tcp(pair);
        let model = with_peg(robot, pair, params)?;
        let q0 = model.start_configuration(start_tcp)?;

        let mut world = params.physics.new_world();
        add_table(&mut world);
        if let Some(hole) = &base_t_hole {
            add_fixed(&mut world, &pair.hole, hole, friction);
        }
        let joint_space_contacts = params.physics.arm_contacts == ArmContacts::JointSpace;
        let mut peg_collider = compound_collider(&pair.peg, friction).density(0.0);
        if joint_space_contacts {
            // The narrow phase still finds the peg's contacts; rapier's solver leaves them alone.
            peg_collider = peg_collider.solver_groups(InteractionGroups::none());
        }
        let arm = Arm::insert(
            &mut world,
            &model,
            Iso::identity(),
            &q0,
            vec![(tcp_on_flange, peg_collider)],
        );
        let peg = *world.bodies[arm.last_body()]
            .colliders()
            .last()
            .expect("the peg collider");
        let (lo, hi) = pair.peg.bounds();
        let peg_reach_m = (hi - lo).norm() + tcp_on_flange.translation.vector.norm();
        let controller = Controller::new(
            params.controller.clone(),
            &model,
            Mode::CartesianImpedance {
                gains,
                target: *start_tcp,
            },
            &q0,
        )?;
        let n = model.dof();
        let model_tcp = model.tcp_pose(&q0);
        let sensors = Sensors::new(params.sensors.clone(), n, seed)?;
        let energy = EnergyLedger::new(
            dt,
            arm.mechanical_energy(&world, &model.armature, &vec![0.0; n]),
        );
        let mut cell = Cell {
            world,
            arm,
            model,
            controller,
            sensors,
            base_t_hole,
            peg,
            peg_reach_m,
            steps_per_cycle,
            steps: 0,
            dt_s: dt,
            tau: DVector::zeros(n),
            tau_link: DVector::zeros(n),
            accel_ahead: 0.0,
            qd: vec![0.0; n],
            disturbance: None,
            tcp_measured: model_tcp,
            probe: base_t_hole.map(|h| (PenetrationProbe::new(&pair.hole, &h), pair.peg.clone())),
            penetration_fault_m: pair.clearance_m.max(0.1e-3),
            saturated_at_s: vec![f64::NEG_INFINITY; n],
            energy,
            position_projection: params.physics.position_projection,
            joint_space_contacts,
            peg_contacts: None,
            friction,
        };
        // Start holding the arm: the task torque is zero at the target, gravity is compensated.
        let k = cell.model.kinematics(&q0);
        cell.tau = cell
            .model
            .gravity_torques(&k, &Vector3::from(params.controller.gravity));
        cell.tau_link = cell.tau.clone();
        Ok(cell)
    }

    /// Physics step, s.
    pub fn dt_s(&self) -> f64 {
        self.dt_s
    }

    /// Simulated time, s.
    pub fn time_s(&self) -> f64 {
        self.steps as f64 * self.dt_s
    }

    /// Advances one physics step (running a control cycle first when one is due).
    pub fn step(&mut self) {
        if self.steps.is_multiple_of(self.steps_per_cycle as u64) {
            self.control_cycle();
        }
        let dt = self.dt_s;
        self.arm.apply_torques(&mut self.world, self.tau.as_slice());
        if let Some(w) = self.disturbance {
            self.apply_disturbance(&w);
        }
        let speed = max_point_speed(&self.world, self.arm.last_body(), self.peg_reach_m);
        let ahead = speed + self.accel_ahead * dt;
        set_prediction_for_speed(&mut self.world, ahead, ARM_MIN_PREDICTION_M);
        let q_before = self.arm.q(&self.world);
        self.world.step();
        self.arm.clear_torques(&mut self.world);
        if self.joint_space_contacts {
            self.solve_peg_contacts(&q_before);
        }
        // Torques do not change velocities until the step, so the last step's velocities are
        // the ones before this one.
        let qd = self.arm.qd(&self.world);
        for (i, (v, v_before)) in qd.iter().zip(&self.qd).enumerate() {
            let qdd = (v - v_before) / dt;
            self.tau_link[i] =
                self.tau[i] - self.model.armature[i] * qdd - self.model.joints[i].damping * v;
        }
        self.steps += 1;
        let booked = self.step_energy(&q_before, &qd, dt);
        self.energy.book(self.time_s(), booked);
        self.qd = qd;
        if self.position_projection {
            self.project_out_penetration();
        }
    }

    /// Solves the peg's contacts found at the start of the step (at `q_before`) against the
    /// velocity rapier's step left, and applies the result as semi-implicit Euler does: the
    /// velocity change, and the joints moved by the step times it ([`joint_contacts`]).
    fn solve_peg_contacts(&mut self, q_before: &[f64]) {
        self.peg_contacts = None;
        let contacts = joint_contacts::peg_contacts(&self.world, self.peg);
        if contacts.is_empty() {
            return;
        }
        let k = self.model.kinematics(q_before);
        let mass = self.model.mass_matrix(&k);
        let v_free = DVector::from_vec(self.arm.qd(&self.world));
        let about = Point3::from(self.model.tcp_from(&k).translation.vector);
        let Some(solve) = joint_contacts::solve(
            &self.model,
            &k,
            &self.arm.world_t_base,
            &mass,
            &v_free,
            &contacts,
            self.friction,
            self.dt_s,
            &about,
        ) else {
            return;
        };
        // Semi-implicit Euler, as the solve assumed: q = q_before + dt v_new. rapier's two
        // substeps put the free motion's end elsewhere by a dt^2 / 4 (measured: half a
        // micrometre at a wedged peg, which then never left the wall).
        let v_new = &v_free + &solve.dv;
        let q_now = self.arm.q(&self.world);
        let dq: Vec<f64> = (q_before.iter().zip(&q_now).zip(v_new.iter()))
            .map(|((q0, q), v)| q0 + self.dt_s * v - q)
            .collect();
        self.arm.displace(&mut self.world, &dq);
        self.arm.set_qd(&mut self.world, v_new.as_slice());
        self.peg_contacts = Some(solve);
    }

    /// Moves the arm out of what its peg still overlaps after the step
    /// ([`crate::twin::physics::projection`]), measured on the exact pieces; a few rounds, as
    /// a projection is a linearisation.
    fn project_out_penetration(&mut self) {
        let Some((probe, peg)) = &self.probe else {
            return;
        };
        let mut depth = -crate::twin::physics::min_solver_gap(&self.world, self.peg);
        if depth < projection::SOLVER_TRIGGER_M {
            return;
        }
        for _ in 0..PROJECTION_ROUNDS {
            let q = self.arm.q(&self.world);
            let tcp = self.model.tcp_pose(&q);
            let rows = probe.gap_rows(peg, &tcp, projection::reach_m(depth));
            let Some(dq) = projection::projection(
                &self.model,
                &q,
                &self.arm.world_t_base,
                &rows,
                self.peg_reach_m,
            ) else {
                return;
            };
            depth = -rows.iter().map(|r| r.gap_m).fold(0.0, f64::min);
            self.arm.displace(&mut self.world, dq.as_slice());
        }
    }

    /// The arm's energy after the step and the work done on it during the step, from the joint
    /// positions before it and the joint speeds `qd` after it (see [`crate::twin::energy`]). A
    /// joint torque is constant over the step, so its work is exact: torque times the joint's
    /// travel; the damping's is booked as rapier applies it, implicitly (at the speed after the
    /// step), and the contacts' at the velocities after the step.
    fn step_energy(&self, q_before: &[f64], qd: &[f64], dt: f64) -> StepEnergy {
        let q_after = self.arm.q(&self.world);
        let travel = q_after.iter().zip(q_before).map(|(q, q0)| q - q0);
        let (torque_work, damping_work) = (travel.zip(&self.tau).zip(qd))
            .zip(&self.model.joints)
            .fold((0.0, 0.0), |(t, d), (((dq, tau), v), j)| {
                (t + tau * dq, d - j.damping * v * dq)
            });
        StepEnergy {
            mechanical_j: self
                .arm
                .mechanical_energy(&self.world, &self.model.armature, qd),
            drives_j: torque_work + self.disturbance_power() * dt,
            contacts_j: self.arm.contact_power(&self.world) * dt
                + self.peg_contacts.as_ref().map_or(0.0, |c| c.work_j),
            damping_j: damping_work,
        }
    }

    /// Power of the diagnostic push on the TCP, W (zero without one).
    fn disturbance_power(&self) -> f64 {
        let Some(w) = &self.disturbance else {
            return 0.0;
        };
        let body = &self.world.bodies[self.arm.last_body()];
        let tcp = self.true_tcp_pose();
        let (v, omega) = (v64(body.linvel()), v64(body.angvel()));
        let v_tcp = v + omega.cross(&(tcp.translation.vector - v64(body.center_of_mass())));
        w.fixed_rows::<3>(0).dot(&v_tcp) + w.fixed_rows::<3>(3).dot(&omega)
    }

    /// Runs `seconds` of simulated time.
    pub fn run(&mut self, seconds: f64) {
        let n = (seconds / self.dt_s).round() as usize;
        for _ in 0..n {
            self.step();
        }
    }

    fn control_cycle(&mut self) {
        let period = 1.0 / self.controller.params.rate_hz;
        let q = self.arm.q(&self.world);
        let q_meas = self.sensors.read_q(&q);
        let tau_meas = self.sensors.read_torques(&self.tau_link, period);
        let gravity = Vector3::from(self.controller.params.gravity);
        let d = self.model.dynamics(&q_meas, &gravity);
        self.tcp_measured = d.tcp;
        self.sensors.estimate(&d, &self.qd, &tau_meas, period);
        self.tau = self.controller.update(&d, &q_meas, &self.qd);
        self.accel_ahead =
            free_acceleration_bound(&self.model, &d, &self.tau, &self.qd, self.peg_reach_m);
        let now = self.time_s();
        for (at, &sat) in self
            .saturated_at_s
            .iter_mut()
            .zip(self.controller.saturated())
        {
            if sat {
                *at = now;
            }
        }
    }

    /// The joints whose commanded torque was clamped to its limit within the last
    /// [`SATURATION_WINDOW_S`] (what a [`SimFault`] records as `saturated_joints`).
    pub fn saturated_joints(&self) -> Vec<String> {
        let now = self.time_s();
        self.model
            .joints
            .iter()
            .zip(&self.saturated_at_s)
            .filter(|(_, at)| now - **at <= SATURATION_WINDOW_S)
            .map(|(j, _)| j.name.clone())
            .collect()
    }

    fn apply_disturbance(&mut self, w: &Wrench6) {
        let tcp = self.true_tcp_pose();
        let body = &mut self.world.bodies[self.arm.last_body()];
        let at = crate::twin::physics::v32(&tcp.translation.vector);
        body.add_force_at_point(
            crate::twin::physics::v32(&w.fixed_rows::<3>(0).into_owned()),
            at,
            true,
        );
        body.add_torque(
            crate::twin::physics::v32(&w.fixed_rows::<3>(3).into_owned()),
            true,
        );
    }

    /// Joint torques being applied, N m.
    pub fn torques(&self) -> &DVector<f64> {
        &self.tau
    }

    /// What the robot reports now (see [`Measurements`]).
    pub fn measurements(&self) -> Measurements {
        Measurements {
            time_s: self.time_s(),
            tcp: self.tcp_measured,
            wrench: self.sensors.wrench,
            contact: self.sensors.contact,
        }
    }

    /// The arm's energy account of the last 100 ms: who put energy in (see
    /// [`crate::twin::energy`]).
    pub fn energy_flows(&self) -> EnergyFlows {
        self.energy.flows()
    }

    /// The ground truth (see [`Truth`]).
    pub fn truth(&self) -> Truth<'_> {
        Truth { cell: self }
    }

    /// Commands a new control mode (checked as the controller checks it).
    pub fn set_mode(&mut self, mode: Mode) -> Result<()> {
        self.controller.set_mode(mode)
    }

    /// Commands the Cartesian impedance target `base_T_tcp`.
    pub fn command_pose(&mut self, target: Iso) {
        self.controller.set_cartesian_target(target);
    }

    /// New impedance gains, keeping the current target (a Sunrise mode switch); from joint
    /// position mode, the target is where the robot measures itself.
    pub fn switch_gains(&mut self, gains: ImpedanceGains) -> Result<()> {
        let target = match self.controller.mode() {
            Mode::CartesianImpedance { target, .. } => *target,
            Mode::JointPosition { .. } => self.measurements().tcp,
        };
        self.controller
            .set_mode(Mode::CartesianImpedance { gains, target })
    }

    /// Pushes `wrench` onto the TCP from now on (base frame, torque about the TCP; `None`
    /// stops): an external disturbance for diagnostics and tests.
    pub fn set_disturbance(&mut self, wrench: Option<Wrench6>) {
        self.disturbance = wrench;
    }

    /// A reason to stop trusting the physics, if there is one: non-finite joint state, a joint
    /// running away (faster than three times its speed limit), or the peg inside the fixture by
    /// more than the clearance (checked exactly every 250 steps).
    pub fn fault(&self) -> Option<SimFault> {
        let fault = |reason: String| {
            let saturated_joints = self.saturated_joints();
            let energy = self.energy.flows();
            let mut reason = format!("{reason}; {}", energy.describe());
            if !saturated_joints.is_empty() {
                reason += &format!(
                    "; commanded torque at its limit within {} ms before: {}",
                    SATURATION_WINDOW_S * 1e3,
                    saturated_joints.join(", ")
                );
            }
            Some(SimFault {
                time_s: self.time_s(),
                reason,
                saturated_joints,
                energy: Some(energy),
            })
        };
        let q = self.arm.q(&self.world);
        let qd = &self.qd;
        if q.iter().chain(qd).any(|v| !v.is_finite()) {
            return fault("joint state is not finite (NaN or infinite)".into());
        }
        for (j, v) in self.model.joints.iter().zip(qd) {
            if v.abs() > RUNAWAY_FACTOR * j.velocity_limit {
                return fault(format!(
                    "runaway velocity: joint '{}' at {v:.3} rad/s, limit {} rad/s",
                    j.name, j.velocity_limit
                ));
            }
        }
        if let Some((probe, peg)) = &self.probe
            && self.steps.is_multiple_of(PENETRATION_CHECK_STEPS)
        {
            let depth = probe.max_penetration(peg, &self.true_tcp_pose());
            if depth > self.penetration_fault_m {
                return fault(format!(
                    "penetration {:.3} mm beyond the bound {:.3} mm",
                    depth * 1e3,
                    self.penetration_fault_m * 1e3
                ));
            }
        }
        None
    }

    fn true_tcp_pose(&self) -> Iso {
        self.model.tcp_pose(&self.arm.q(&self.world))
    }
}

/// Physics steps per control cycle: the control period must be a whole number of steps.
fn steps_per_control_cycle(params: &CellParams) -> Result<usize> {
    let dt = params.physics.dt_s;
    let period = 1.0 / params.controller.rate_hz;
    let steps = (period / dt).round() as usize;
    if steps == 0 || ((steps as f64) * dt - period).abs() > 1e-9 {
        return Err(Error::Input(format!(
            "physics.dt_s = {dt}: the control period {period} s must be a whole number of physics steps"
        )));
    }
    Ok(steps)
}

/// The robot model carrying the peg as its tool: the peg's mass properties (its convex pieces at
/// the pair's peg mass, else the peg mass of `params`) on the flange at `flange_t_tcp`.
/// The robot with the peg of `pair` on its flange as its tool (mass from the pair or `params`).
pub fn with_peg(robot: RobotModel, pair: &PartPair, params: &CellParams) -> Result<RobotModel> {
    let tcp_on_flange = flange_t_tcp(pair);
    let peg_props = compound_collider(&pair.peg, params.physics.friction)
        .mass(pair.peg_mass_kg.unwrap_or(params.peg_mass_kg) as f32)
        .build()
        .mass_properties();
    let tool_inertial = Inertial {
        mass_kg: peg_props.mass() as f64,
        com: Point3::from(v64(peg_props.local_com)),
        inertia: nalgebra::Matrix3::from(peg_props.reconstruct_inertia_matrix()).cast::<f64>(),
    }
    .transformed(&tcp_on_flange);
    Ok(robot.with_tool(Tool {
        inertial: tool_inertial,
        flange_t_tcp: tcp_on_flange,
    }))
}

/// The table: a fixed slab with its top at z = 0 (the base stands on it).
fn add_table(world: &mut PhysicsWorld) {
    let table = ColliderBuilder::cuboid(0.8, 0.8, 0.025)
        .translation(crate::twin::physics::v32(&Vector3::new(0.4, 0.0, -0.025)));
    world.insert_collider(table, None);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pose::Pose6;
    use crate::twin::geometry::{build_builtin, builtin_by_name};
    use crate::twin::robot::urdf::iiwa14;

    /// The stiffest, least damped corner of the Sunrise box (5 000 N/m, 300 N m/rad, damping
    /// 0.1) thrown 5 mm and 3 deg off its target: the peg's fastest point never gets farther in a
    /// step than the contacts were predicted, though its speed at the start of a step alone
    /// (1.5 x, and the floor) would have fallen short.
    #[test]
    fn the_prediction_covers_every_step_of_a_stiff_arm_thrown_off_its_target() {
        let pair = build_builtin(builtin_by_name("cross").expect("cross"), 0.5e-3).expect("pair");
        let params = CellParams::default();
        let start = tcp_in_hole(&nominal_hole_pose(&pair, &params), -0.05);
        let gains = ImpedanceGains::uniform(5000.0, 300.0, 0.1);
        let mut cell = Cell::new(
            &pair,
            iiwa14().expect("iiwa"),
            &params,
            None,
            &start,
            gains,
            1,
        )
        .expect("cell");
        let target = start
            * Iso::translation(5e-3, 0.0, 0.0)
            * Iso::rotation(Vector3::new(0.0, 3f64.to_radians(), 0.0));
        cell.command_pose(target);
        let (mut worst, mut speed_only_short) = (f64::MIN, 0);
        for _ in 0..300 {
            let reach = cell.peg_reach_m;
            let before = max_point_speed(&cell.world, cell.arm.last_body(), reach);
            cell.step();
            let predicted = cell.world.integration_parameters.prediction_distance() as f64;
            let after = max_point_speed(&cell.world, cell.arm.last_body(), reach);
            let moved = after * cell.dt_s;
            worst = worst.max(moved - predicted);
            let speed_only = ARM_MIN_PREDICTION_M.max(1.5 * before * cell.dt_s);
            speed_only_short += usize::from(moved > speed_only);
        }
        assert!(
            worst <= 0.0,
            "a step moved {:.2} um beyond its prediction",
            worst * 1e6
        );
        assert!(
            speed_only_short > 0,
            "the throw should outrun the speed alone"
        );
    }

    /// A cell forked while the peg presses into the walls of its hole steps on bit for bit as
    /// the original: the fork's new pipeline holds nothing the step needs, and the contacts'
    /// warm starts, the controller, the sensors' noise and the energy account travel with it.
    #[test]
    fn a_forked_cell_steps_on_as_the_original() {
        let pair = build_builtin(builtin_by_name("cross").expect("cross"), 0.5e-3).expect("pair");
        let params = CellParams::default();
        let nominal = nominal_hole_pose(&pair, &params);
        let truth = nominal * Iso::translation(1e-3, -0.5e-3, 0.0);
        let start = tcp_in_hole(&truth, 3e-3);
        let gains = ImpedanceGains::uniform(1000.0, 20.0, 0.7);
        let new_cell = || {
            Cell::new(
                &pair,
                iiwa14().expect("iiwa"),
                &params,
                Some(truth),
                &start,
                gains.clone(),
                7,
            )
            .expect("cell")
        };
        let mut original = new_cell();
        let push = |cell: &mut Cell, k: usize| {
            let wobble = Iso::rotation(Vector3::new(0.0, 0.02 * (k as f64 * 0.01).sin(), 0.0));
            cell.command_pose(tcp_in_hole(&nominal, 6e-3) * wobble);
        };
        for k in 0..400 {
            push(&mut original, k);
            original.step();
        }
        assert!(
            original.truth().solver_contacts() > 0,
            "the peg should touch the walls"
        );
        let mut fork = original.fork();
        let mut contact_steps = 0;
        for k in 400..800 {
            push(&mut original, k);
            push(&mut fork, k);
            original.step();
            fork.step();
            contact_steps += usize::from(original.truth().solver_contacts() > 0);
            let bits = |c: &Cell| {
                let m = c.measurements();
                (
                    c.truth().q(),
                    Pose6::from_iso(&m.tcp).0,
                    m.wrench,
                    c.torques().clone(),
                )
            };
            assert_eq!(bits(&original), bits(&fork), "step {k}");
        }
        assert!(contact_steps > 100, "{contact_steps} steps in contact");
        assert!(original.fault().is_none());
    }
}
