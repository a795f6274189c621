//! The work cell (the robot's, not a campaign's cell): the robot base on a table at the world
//! origin, the hole fixture standing on the table in front of it, the peg rigidly on the flange,
//! the controller and the sensors, stepped together. One control cycle (default 1 kHz) reads the sensors, runs the estimator and the
//! controller; the torques are held over the physics steps of the cycle.
//!
//! Frames: `world` = `base` (the base stands upright at the origin, z up), `hole` (mouth centre,
//! z out of the hole), `tcp` = the peg frame (tip centre, z up the peg, so pointing at the flange
//! when the peg hangs from it).

mod build;
mod step;

use crate::error::{Error, Result};
use crate::twin::control::{Controller, ControllerParams, ImpedanceGains, Mode};
use crate::twin::energy::{EnergyFlows, EnergyLedger};
use crate::twin::geometry::PartPair;
use crate::twin::physics::arm::Arm;
use crate::twin::physics::joint_contacts::ContactSolve;
use crate::twin::physics::penetration::PenetrationProbe;
use crate::twin::physics::{ContactFriction, FrictionLaw, PhysicsParams, contact_wrench};
use crate::twin::real_cell::{CellDraw, RealCell};
use crate::twin::robot::spec::RobotSpec;
use crate::twin::robot::{Iso, RobotModel};
use crate::twin::sensing::{SensorParams, Sensors, Wrench6};
use build::steps_per_control_cycle;
pub use build::with_peg;
use nalgebra::{DVector, Translation3, UnitQuaternion, Vector6};
use rapier3d::prelude::{ColliderHandle, PhysicsWorld};
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
/// torques of the last control cycle add in one step ([`WorkCell::accel_ahead`]): the floor covers
/// only what neither foresees (contact impulses, the velocity-squared terms). The free peg of
/// `validate` keeps 30 um ([`crate::twin::physics::MIN_PREDICTION_M`]). A piece pair within the
/// distance is tested at every step, and 10 um instead of 30 halves the gear's step at 0.1 mm
/// (docs/performance.md).
pub const ARM_MIN_PREDICTION_M: f64 = 10e-6;

/// The arm cell's contact prediction in words, for the manifold cache's key: a manifold built
/// under an earlier rule is rebuilt, not reused.
pub const ARM_PREDICTION_RULE: &str = "1.5 x (speed + torque lookahead) x dt, 10 um floor";

/// The work cell's layout and the parameters of everything in it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WorkCellParams {
    #[serde(skip)]
    pub physics: PhysicsParams,
    pub controller: ControllerParams,
    pub sensors: SensorParams,
    /// Nominal hole mouth position in the base frame, x and y, m.
    pub hole_xy_m: [f64; 2],
    /// Mass of the peg with its holder, kg.
    pub peg_mass_kg: f64,
    /// The real cell's imperfections, drawn by each cell from its seed (`[cell]`); the ideal
    /// cell by default (absent in files: ideal), which a scenario or a trial request replaces.
    #[serde(
        default = "RealCell::ideal",
        skip_serializing_if = "RealCell::is_ideal"
    )]
    pub cell: RealCell,
}

impl Default for WorkCellParams {
    fn default() -> Self {
        WorkCellParams {
            physics: PhysicsParams {
                solver_iterations: ARM_SOLVER_ITERATIONS,
                pgs_iterations: ARM_PGS_ITERATIONS,
                ..PhysicsParams::default()
            },
            controller: ControllerParams::default(),
            sensors: SensorParams::default(),
            hole_xy_m: [0.55, 0.0],
            peg_mass_kg: BUILTIN_PEG_MASS_KG,
            cell: RealCell::ideal(),
        }
    }
}

impl WorkCellParams {
    /// Everything a cell checks when it is built, checked up front (so a campaign refuses a
    /// setting before it writes anything): physics ranges, a control period that is a whole
    /// number of physics steps, the sensors, the peg mass.
    pub fn ensure_valid(&self) -> Result<()> {
        self.physics.ensure_valid()?;
        steps_per_control_cycle(self)?;
        self.controller.latency_cycles()?;
        self.cell.ensure_valid()?;
        if !self.cell.is_ideal() {
            ControllerParams {
                latency_s: self.cell.latency_s,
                ..self.controller.clone()
            }
            .latency_cycles()
            .map_err(|e| Error::Input(format!("cell.latency_s: {e}")))?;
        }
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

impl WorkCellParams {
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
pub fn nominal_hole_pose(pair: &PartPair, params: &WorkCellParams) -> Iso {
    let height = -pair.hole.bounds().0.z;
    Iso::translation(params.hole_xy_m[0], params.hole_xy_m[1], height)
}

/// The TCP pose (base frame) of a peg aligned with a hole at `base_t_hole`, its tip `depth_m`
/// below the mouth (negative: above).
pub fn tcp_in_hole(base_t_hole: &Iso, depth_m: f64) -> Iso {
    base_t_hole * Iso::translation(0.0, 0.0, -depth_m)
}

/// The simulated cell, seen through its ports as the real cell is (as Drake's systems are):
/// commands in ([`WorkCell::command_pose`], [`WorkCell::switch_gains`], [`WorkCell::set_mode`]),
/// [`Measurements`] out. The ground truth (true pose, true contact wrench, joint state) is behind
/// [`WorkCell::truth`], for scoring, validation and traces only; the method never holds a `WorkCell` (it
/// drives a `method::session::Session`, which lends it the ports alone).
pub struct WorkCell {
    world: PhysicsWorld,
    arm: Arm,
    /// The robot model with the peg as its tool.
    model: RobotModel,
    /// The model the controller and the estimator use: `model` with the peg mass they believe.
    believed: RobotModel,
    /// What the cell drew of the real cell's imperfections (`None`: the ideal cell).
    draw: Option<CellDraw>,
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
    /// Torques computed and not yet at the drives, oldest first (`ControllerParams::latency_s`:
    /// one per cycle of latency).
    in_flight: std::collections::VecDeque<DVector<f64>>,
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
    /// Coulomb friction between the peg and what it touches: the kinetic coefficient (rapier's
    /// colliders carry it), and with the static one for the joint-space contacts.
    friction: f64,
    contact_friction: ContactFriction,
    /// The joints' friction, when they have any (`PhysicsParams::joint_friction`).
    joint_friction: Option<FrictionLaw>,
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
    cell: &'a WorkCell,
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

/// Steps between exact penetration checks.
const PENETRATION_CHECK_STEPS: u64 = 250;
/// A joint faster than this multiple of its speed limit is a runaway.
const RUNAWAY_FACTOR: f64 = 3.0;
/// How long before a fault a torque at its limit counts as the fault's cause, s.
pub const SATURATION_WINDOW_S: f64 = 0.1;

impl WorkCell {
    /// Physics step, s.
    pub fn dt_s(&self) -> f64 {
        self.dt_s
    }

    /// What the cell drew of the real cell's imperfections (`None`: the ideal cell).
    pub fn draw(&self) -> Option<&CellDraw> {
        self.draw.as_ref()
    }

    /// Simulated time, s.
    pub fn time_s(&self) -> f64 {
        self.steps as f64 * self.dt_s
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

    /// The hole pose as this robot reads it where it stands, base frame: the true hole carried by
    /// `read_T_true`, the TCP pose its encoders' constant offsets give (without their noise)
    /// relative to the true one. What a robot taught the hole by touching it holds as the hole's
    /// pose; the true one exactly where the encoders have no offsets. `None`: no fixture.
    pub fn hole_as_read(&self) -> Option<Iso> {
        let hole = self.base_t_hole?;
        let offsets = &self.sensors.params.encoder_offset_rad;
        if offsets.is_empty() {
            return Some(hole);
        }
        let q = self.arm.q(&self.world);
        let read: Vec<f64> = q.iter().zip(offsets).map(|(q, o)| q + o).collect();
        Some(self.believed.tcp_pose(&read) * self.model.tcp_pose(&q).inverse() * hole)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pose::Pose6;
    use crate::twin::geometry::{build_builtin, builtin_by_name};
    use crate::twin::physics::max_point_speed;
    use crate::twin::robot::urdf::iiwa14;
    use nalgebra::Vector3;

    /// The stiffest, least damped corner of the Sunrise box (5 000 N/m, 300 N m/rad, damping
    /// 0.1) thrown 5 mm and 3 deg off its target: the peg's fastest point never gets farther in a
    /// step than the contacts were predicted, though its speed at the start of a step alone
    /// (1.5 x, and the floor) would have fallen short.
    #[test]
    fn the_prediction_covers_every_step_of_a_stiff_arm_thrown_off_its_target() {
        let pair = build_builtin(builtin_by_name("cross").expect("cross"), 0.5e-3).expect("pair");
        let params = WorkCellParams::default();
        let start = tcp_in_hole(&nominal_hole_pose(&pair, &params), -0.05);
        let gains = ImpedanceGains::uniform(5000.0, 300.0, 0.1);
        let mut cell = WorkCell::new(
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
        let params = WorkCellParams::default();
        let nominal = nominal_hole_pose(&pair, &params);
        let truth = nominal * Iso::translation(1e-3, -0.5e-3, 0.0);
        let start = tcp_in_hole(&truth, 3e-3);
        let gains = ImpedanceGains::uniform(1000.0, 20.0, 0.7);
        let new_cell = || {
            WorkCell::new(
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
        let push = |cell: &mut WorkCell, k: usize| {
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
            let bits = |c: &WorkCell| {
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
