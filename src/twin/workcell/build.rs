//! Building the cell ([`WorkCell::new`]) and forking it ([`WorkCell::fork`]).

use super::{WorkCell, WorkCellParams, flange_t_tcp};
use crate::error::{Error, Result};
use crate::twin::control::{Controller, ImpedanceGains, Mode};
use crate::twin::energy::EnergyLedger;
use crate::twin::geometry::PartPair;
use crate::twin::physics::arm::Arm;
use crate::twin::physics::penetration::PenetrationProbe;
use crate::twin::physics::{
    ArmContacts, FrictionLaw, add_fixed, compound_collider, fork_world, v64,
};
use crate::twin::real_cell::CellDraw;
use crate::twin::robot::{Inertial, Iso, RobotModel, Tool};
use crate::twin::sensing::Sensors;
use nalgebra::{DVector, Point3, Vector3};
use rapier3d::prelude::{ColliderBuilder, ColliderHandle, InteractionGroups, PhysicsWorld};

impl WorkCell {
    /// An independent copy of the cell that steps on bit for bit as this one would
    /// ([`fork_world`]): two trials whose first stages are the same simulation run them once and
    /// branch here.
    pub fn fork(&self) -> WorkCell {
        WorkCell {
            world: fork_world(&self.world),
            arm: self.arm.clone(),
            model: self.model.clone(),
            believed: self.believed.clone(),
            draw: self.draw.clone(),
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
            in_flight: self.in_flight.clone(),
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
            contact_friction: self.contact_friction,
            joint_friction: self.joint_friction.clone(),
        }
    }

    /// Builds the cell with the arm at rest at `start_tcp` (base frame) under Cartesian impedance
    /// with `gains`; `base_t_hole: None` leaves the fixture out. `seed` seeds the sensors and,
    /// in the real profile, the cell's draw of its imperfections ([`RealCell::draw`]).
    pub fn new(
        pair: &PartPair,
        robot: RobotModel,
        params: &WorkCellParams,
        base_t_hole: Option<Iso>,
        start_tcp: &Iso,
        gains: ImpedanceGains,
        seed: u64,
    ) -> Result<WorkCell> {
        params.ensure_valid()?;
        let Realised {
            params,
            draw,
            joint_friction,
            believed,
        } = realise(pair, &robot, params, seed)?;
        let params = &params;
        let steps_per_cycle = steps_per_control_cycle(params)?;
        let dt = params.physics.dt_s;
        let friction = params.physics.friction;
        let tcp_on_flange = flange_t_tcp(pair);
        let model = with_peg(robot, pair, params)?;
        let q0 = model.start_configuration(start_tcp)?;

        let joint_space_contacts = params.physics.arm_contacts == ArmContacts::JointSpace;
        let (world, arm, peg) = build_world(pair, &model, params, base_t_hole.as_ref(), &q0);
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
        let mut cell = WorkCell {
            world,
            arm,
            model,
            believed,
            draw,
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
            in_flight: std::collections::VecDeque::new(),
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
            contact_friction: params.physics.contact_friction(),
            joint_friction,
        };
        cell.hold(&q0, params)?;
        Ok(cell)
    }

    /// Starts holding the arm at `q0`: the task torque is zero at the target and gravity is
    /// compensated (as the controller believes it), those torques also in flight through the
    /// latency.
    fn hold(&mut self, q0: &[f64], params: &WorkCellParams) -> Result<()> {
        let k = self.believed.kinematics(q0);
        let gravity = Vector3::from(params.controller.gravity);
        self.tau = self.believed.gravity_torques(&k, &gravity);
        self.tau_link = self.tau.clone();
        let latency = params.controller.latency_cycles()?;
        self.in_flight = std::iter::repeat_n(self.tau.clone(), latency).collect();
        Ok(())
    }
}

/// What a cell's draw makes of its parameters ([`realise`]).
struct Realised {
    /// The parameters the cell runs under.
    params: WorkCellParams,
    draw: Option<CellDraw>,
    /// The joints' friction (`None`: frictionless).
    joint_friction: Option<FrictionLaw>,
    /// The model the controller and the estimator use.
    believed: RobotModel,
}

/// The cell of `robot` carrying the peg of `pair` under `params` (valid), as its draw from
/// `seed` makes it: on the real cell the drawn parameters, the robot file's joint friction scaled, and the peg
/// mass the controller believes; on the ideal one `params` as they are, frictionless joints
/// whatever the robot file says, and the true peg mass.
fn realise(
    pair: &PartPair,
    robot: &RobotModel,
    params: &WorkCellParams,
    seed: u64,
) -> Result<Realised> {
    let file_friction: Vec<f64> = robot.joints.iter().map(|j| j.friction).collect();
    let draw = params.cell.draw(seed, robot.joints.len());
    let (params, file_friction, payload_error) = match &draw {
        Some(d) => {
            let drawn = drawn_params(params, d, &file_friction);
            drawn.ensure_valid()?;
            (drawn, file_friction, d.payload_error)
        }
        None => (params.clone(), vec![0.0; file_friction.len()], 0.0),
    };
    let joint_friction = params.physics.joint_friction.resolve(&file_friction)?;
    let believed_mass_kg = peg_mass_kg(pair, &params) * (1.0 + payload_error);
    let believed = with_peg_of_mass(robot.clone(), pair, believed_mass_kg, &params);
    Ok(Realised {
        params,
        draw,
        joint_friction,
        believed,
    })
}

/// The cell's rapier world: the table, the hole's fixture at `base_t_hole` (none: free space),
/// and the arm at `q0` carrying the peg on its flange; with the arm and the peg's collider. In
/// joint-space contacts the narrow phase still finds the peg's contacts and rapier's solver
/// leaves them alone.
fn build_world(
    pair: &PartPair,
    model: &RobotModel,
    params: &WorkCellParams,
    base_t_hole: Option<&Iso>,
    q0: &[f64],
) -> (PhysicsWorld, Arm, ColliderHandle) {
    let friction = params.physics.friction;
    let mut world = params.physics.new_world();
    add_table(&mut world);
    if let Some(hole) = base_t_hole {
        add_fixed(&mut world, &pair.hole, hole, friction);
    }
    let mut peg_collider = compound_collider(&pair.peg, friction).density(0.0);
    if params.physics.arm_contacts == ArmContacts::JointSpace {
        peg_collider = peg_collider.solver_groups(InteractionGroups::none());
    }
    let tcp_on_flange = flange_t_tcp(pair);
    let arm = Arm::insert(
        &mut world,
        model,
        Iso::identity(),
        q0,
        vec![(tcp_on_flange, peg_collider)],
    );
    let peg = *world.bodies[arm.last_body()]
        .colliders()
        .last()
        .expect("the peg collider");
    (world, arm, peg)
}

/// Physics steps per control cycle: the control period must be a whole number of steps.
pub(super) fn steps_per_control_cycle(params: &WorkCellParams) -> Result<usize> {
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

/// The robot with the peg of `pair` on its flange as its tool (mass from the pair or `params`).
pub fn with_peg(robot: RobotModel, pair: &PartPair, params: &WorkCellParams) -> Result<RobotModel> {
    Ok(with_peg_of_mass(
        robot,
        pair,
        peg_mass_kg(pair, params),
        params,
    ))
}

/// The mass of the peg with its holder, kg: the pair's own, else the one of `params`.
fn peg_mass_kg(pair: &PartPair, params: &WorkCellParams) -> f64 {
    pair.peg_mass_kg.unwrap_or(params.peg_mass_kg)
}

/// The robot with the peg of `pair`, of `mass_kg`, on its flange as its tool: the mass
/// properties of its convex pieces at that mass, at `flange_t_tcp`.
fn with_peg_of_mass(
    robot: RobotModel,
    pair: &PartPair,
    mass_kg: f64,
    params: &WorkCellParams,
) -> RobotModel {
    let tcp_on_flange = flange_t_tcp(pair);
    let peg_props = compound_collider(&pair.peg, params.physics.friction)
        .mass(mass_kg as f32)
        .build()
        .mass_properties();
    let tool_inertial = Inertial {
        mass_kg: peg_props.mass() as f64,
        com: Point3::from(v64(peg_props.local_com)),
        inertia: nalgebra::Matrix3::from(peg_props.reconstruct_inertia_matrix()).cast::<f64>(),
    }
    .transformed(&tcp_on_flange);
    robot.with_tool(Tool {
        inertial: tool_inertial,
        flange_t_tcp: tcp_on_flange,
    })
}

/// `params` with the imperfections `draw` took: the contact and joint friction, the wrench
/// estimate's calibration error and the latency (the payload error is the believed model's).
/// The joints' nominal friction is `[physics] joint_friction` if given, else the robot file's
/// (`file_coulomb_nm`).
fn drawn_params(
    params: &WorkCellParams,
    draw: &CellDraw,
    file_coulomb_nm: &[f64],
) -> WorkCellParams {
    let mut p = params.clone();
    p.physics.friction = draw.contact_friction;
    p.physics.static_friction = Some(draw.static_friction);
    let jf = &mut p.physics.joint_friction;
    let scaled =
        |v: &[f64]| -> Vec<f64> { v.iter().map(|f| f * draw.joint_friction_scale).collect() };
    let coulomb = jf.coulomb_nm.as_deref().unwrap_or(file_coulomb_nm);
    jf.static_nm = jf.static_nm.as_deref().map(scaled);
    jf.coulomb_nm = Some(scaled(coulomb));
    let s = &mut p.sensors;
    for (b, d) in s.wrench_bias.iter_mut().zip(draw.wrench_bias) {
        *b += d;
    }
    s.wrench_gain *= draw.wrench_gain;
    if !draw.encoder_offset_rad.is_empty() {
        s.encoder_offset_rad = draw.encoder_offset_rad.clone();
    }
    p.controller.latency_s = params.cell.latency_s;
    p
}

/// The table: a fixed slab with its top at z = 0 (the base stands on it).
pub(super) fn add_table(world: &mut PhysicsWorld) {
    let table = ColliderBuilder::cuboid(0.8, 0.8, 0.025)
        .translation(crate::twin::physics::v32(&Vector3::new(0.4, 0.0, -0.025)));
    world.insert_collider(table, None);
}
