//! One physics step of the cell ([`WorkCell::step`]), as rapier's pipeline steps its world: a
//! control cycle when one is due, the torques applied, the world stepped, the peg's contacts
//! solved, the energy accounted.

use super::{ARM_MIN_PREDICTION_M, WorkCell};
use crate::twin::energy::StepEnergy;
use crate::twin::physics::joint_contacts;
use crate::twin::physics::projection;
use crate::twin::physics::{max_point_speed, set_prediction_for_speed, v64};
use crate::twin::robot::{Dynamics, RobotModel};
use crate::twin::sensing::Wrench6;
use nalgebra::{DVector, Point3, Vector3};

/// Bound on the acceleration (m/s^2) of any point of the tool within `reach_m` of the TCP, free
/// of contact, under the torques `tau` at the joint speeds `qd` (rad/s) and the viscous damping
/// of `model`'s joints: `qdd = M^-1 (tau - g - D qd)`, at the TCP `J qdd = [a; alpha]`, and
/// `|a| + |alpha| reach_m`. The velocity-squared terms are left out (small at the arm's speeds
/// beside what a change of torque brings). A mass matrix that does not factor (a joint state no
/// longer finite, which the cell reports as a `sim_fault`) gives 0.
pub(super) fn free_acceleration_bound(
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

/// Rounds of position projection per step at most.
pub(super) const PROJECTION_ROUNDS: usize = 3;

impl WorkCell {
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
        let joint_bounds = (self.joint_friction.as_ref()).map(|f| f.bounds(&self.qd, dt));
        if self.joint_space_contacts || joint_bounds.is_some() {
            self.solve_peg_contacts(&q_before, joint_bounds.as_deref());
        }
        // Torques do not change velocities until the step, so the last step's velocities are
        // the ones before this one.
        let qd = self.arm.qd(&self.world);
        for (i, (v, v_before)) in qd.iter().zip(&self.qd).enumerate() {
            let qdd = (v - v_before) / dt;
            self.tau_link[i] =
                self.tau[i] - self.model.armature[i] * qdd - self.model.joints[i].damping * v;
        }
        // The joints' friction acts between motor and sensor: the link gets what it leaves.
        if let Some(friction) = self
            .peg_contacts
            .as_ref()
            .and_then(|c| c.joint_friction.as_ref())
        {
            self.tau_link += &friction.torque_nm;
        }
        self.steps += 1;
        let booked = self.step_energy(&q_before, &qd, dt);
        self.energy.book(self.time_s(), booked);
        self.qd = qd;
        if self.position_projection {
            self.project_out_penetration();
        }
    }

    /// Solves the peg's contacts found at the start of the step (at `q_before`; rapier's own
    /// when it solves them) and the joints' friction within `joint_bounds` (N m s per joint)
    /// against the velocity rapier's step left, and applies the result as semi-implicit Euler
    /// does: the velocity change, and the joints moved by the step times it ([`joint_contacts`]).
    pub(super) fn solve_peg_contacts(&mut self, q_before: &[f64], joint_bounds: Option<&[f64]>) {
        self.peg_contacts = None;
        let contacts = match self.joint_space_contacts {
            true => joint_contacts::peg_contacts(&self.world, self.peg),
            false => Vec::new(),
        };
        if contacts.is_empty() && joint_bounds.is_none() {
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
            (&self.qd, &v_free),
            &contacts,
            (&self.contact_friction, joint_bounds),
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
    pub(super) fn project_out_penetration(&mut self) {
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
    pub(super) fn step_energy(&self, q_before: &[f64], qd: &[f64], dt: f64) -> StepEnergy {
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
            damping_j: match self
                .peg_contacts
                .as_ref()
                .and_then(|c| c.joint_friction.as_ref())
            {
                Some(friction) => damping_work + friction.work_j,
                None => damping_work,
            },
        }
    }

    /// Power of the diagnostic push on the TCP, W (zero without one).
    pub(super) fn disturbance_power(&self) -> f64 {
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

    pub(super) fn control_cycle(&mut self) {
        let period = 1.0 / self.controller.params.rate_hz;
        let q = self.arm.q(&self.world);
        let q_meas = self.sensors.read_q(&q);
        let tau_meas = self.sensors.read_torques(&self.tau_link, period);
        let gravity = Vector3::from(self.controller.params.gravity);
        let d = self.believed.dynamics(&q_meas, &gravity);
        self.tcp_measured = d.tcp;
        self.sensors.estimate(&d, &self.qd, &tau_meas, period);
        let command = self.controller.update(&d, &q_meas, &self.qd);
        self.tau = match self.in_flight.pop_front() {
            // Latency: this cycle's torques wait their turn behind the ones still in flight.
            Some(due) => {
                self.in_flight.push_back(command);
                due
            }
            None => command,
        };
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

    pub(super) fn apply_disturbance(&mut self, w: &Wrench6) {
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
}
