//! A [`RobotModel`] as a rapier multibody: the base fixed at a world pose, one dynamic body per
//! link with the URDF's mass properties, revolute (or prismatic) multibody joints with the
//! URDF's viscous damping and the model's rotor inertia (rapier's `armature`), and the tool's
//! colliders on the last link. Joints are driven by torques only: rapier has no joint-torque
//! setter, so a joint torque `tau` is applied as `+tau * axis` on the child link and
//! `-tau * axis` on the parent (rapier maps link wrenches to generalised forces through J^T,
//! which turns that pair into exactly `tau` on the joint and nothing elsewhere).
//!
//! No joint position limits are enforced by the physics, and links do not collide with each other
//! (self-contacts off): the controller keeps the arm inside its limits and away from itself.

use super::{pose32, pose64, v32};
use crate::twin::robot::{Iso, JointKind, RobotModel, Shape};
use nalgebra::{Point3, UnitQuaternion, Vector3};
use rapier3d::prelude::*;

/// The arm inside a [`PhysicsWorld`].
#[derive(Clone)]
pub struct Arm {
    /// `world_T_base`.
    pub world_t_base: Iso,
    /// Base body (fixed) then one body per movable joint's child link.
    bodies: Vec<RigidBodyHandle>,
    /// The multibody joint of each movable joint.
    joints: Vec<MultibodyJointHandle>,
    kinds: Vec<JointKind>,
    /// Joint axes in the child link frames.
    axes: Vec<Vector3<f64>>,
}

impl Arm {
    /// Inserts `model` with its base at `world_t_base` and its joints at `q0`. The tool's
    /// colliders (if any) are passed in `tool_colliders`, placed in the flange frame.
    pub fn insert(
        world: &mut PhysicsWorld,
        model: &RobotModel,
        world_t_base: Iso,
        q0: &[f64],
        tool_colliders: Vec<(Iso, ColliderBuilder)>,
    ) -> Arm {
        let k = model.kinematics(q0);
        let base = world.insert_body(RigidBodyBuilder::fixed().pose(pose32(&world_t_base)));
        add_link_colliders(world, base, &model.base.collision);
        let mut bodies = vec![base];
        let mut joints = Vec::with_capacity(model.dof());
        for (i, (joint, link)) in model.joints.iter().zip(&model.links).enumerate() {
            let mut inertial = link.inertial;
            if i + 1 == model.dof()
                && let Some(tool) = &model.tool
            {
                inertial = inertial.combined(&tool.inertial.transformed(&model.last_t_flange));
            }
            let props = MassProperties::with_inertia_matrix(
                v32(&inertial.com.coords),
                inertial.mass_kg as f32,
                inertial.inertia.cast::<f32>().into(),
            );
            let body = world.insert_body(
                RigidBodyBuilder::dynamic()
                    .pose(pose32(&(world_t_base * k.frames[i])))
                    .additional_mass_properties(props)
                    .can_sleep(false),
            );
            add_link_colliders(world, body, &link.collision);
            let frame = UnitQuaternion::rotation_between(&Vector3::x(), &joint.axis)
                .unwrap_or_else(|| {
                    UnitQuaternion::from_axis_angle(&Vector3::z_axis(), std::f64::consts::PI)
                });
            let locked = match joint.kind {
                JointKind::Revolute => JointAxesMask::LOCKED_REVOLUTE_AXES,
                JointKind::Prismatic => JointAxesMask::LOCKED_PRISMATIC_AXES,
            };
            let data = GenericJointBuilder::new(locked)
                .contacts_enabled(false)
                .local_frame1(pose32(
                    &(joint.origin * Iso::from_parts(Default::default(), frame)),
                ))
                .local_frame2(pose32(&Iso::from_parts(Default::default(), frame)))
                .build();
            let handle = world
                .multibody_joints
                .insert(bodies[i], body, data, true)
                .expect("a serial chain never closes a loop");
            joints.push(handle);
            bodies.push(body);
        }
        let last = *bodies.last().expect("at least one link");
        for (pose, collider) in tool_colliders {
            let on_link = model.last_t_flange * pose;
            world.insert_collider(collider.position(pose32(&on_link)), Some(last));
        }
        let arm = Arm {
            world_t_base,
            bodies,
            joints,
            kinds: model.joints.iter().map(|j| j.kind).collect(),
            axes: model.joints.iter().map(|j| j.axis).collect(),
        };
        arm.set_up_multibody(world, model, q0);
        arm
    }

    /// Resolves the fixed root, sets damping and rotor inertia, puts the joints at `q0`. The
    /// links' mass properties are computed here rather than at the first step, as rapier would:
    /// until then its bodies weigh nothing, and the arm's energy at the start (the energy
    /// account's opening entry) read 0 J instead of the links' 74 J of potential energy.
    fn set_up_multibody(&self, world: &mut PhysicsWorld, model: &RobotModel, q0: &[f64]) {
        for &b in &self.bodies {
            world.bodies[b].recompute_mass_properties_from_colliders(&world.colliders);
        }
        let (mb, _) = world
            .multibody_joints
            .get_mut(self.joints[0])
            .expect("arm joints exist");
        mb.forward_kinematics(&world.bodies, true);
        mb.set_self_contacts_enabled(false);
        for (i, joint) in model.joints.iter().enumerate() {
            mb.damping_mut()[i] = joint.damping as f32;
            mb.armature_mut()[i] = model.armature[i] as f32;
        }
        let q: Vec<f32> = q0.iter().map(|&v| v as f32).collect();
        let current = self.q_of(mb);
        let disp: Vec<f32> = q.iter().zip(&current).map(|(a, b)| a - *b as f32).collect();
        mb.apply_displacements(&disp);
        mb.forward_kinematics(&world.bodies, false);
        mb.update_rigid_bodies(&mut world.bodies, true);
    }

    fn q_of(&self, mb: &Multibody) -> Vec<f64> {
        (0..self.joints.len())
            .map(|i| {
                let coords = mb.link(i + 1).expect("arm link").joint().coords();
                match self.kinds[i] {
                    JointKind::Revolute => coords[3] as f64,
                    JointKind::Prismatic => coords[0] as f64,
                }
            })
            .collect()
    }

    fn multibody<'w>(&self, world: &'w PhysicsWorld) -> &'w Multibody {
        world
            .multibody_joints
            .get(self.joints[0])
            .expect("arm joints exist")
            .0
    }

    /// Joint positions, rad or m.
    pub fn q(&self, world: &PhysicsWorld) -> Vec<f64> {
        self.q_of(self.multibody(world))
    }

    /// Joint velocities, rad/s or m/s.
    pub fn qd(&self, world: &PhysicsWorld) -> Vec<f64> {
        let mb = self.multibody(world);
        mb.generalized_velocity()
            .iter()
            .take(self.joints.len())
            .map(|&v| v as f64)
            .collect()
    }

    /// Applies joint torques (N m, or N on prismatic joints) for the coming step; call
    /// [`Arm::clear_torques`] after the step.
    pub fn apply_torques(&self, world: &mut PhysicsWorld, tau: &[f64]) {
        for (i, &t) in tau.iter().enumerate() {
            let child = self.bodies[i + 1];
            let axis_world = pose64(world.bodies[child].position()).rotation * self.axes[i];
            let w = v32(&(axis_world * t));
            match self.kinds[i] {
                JointKind::Revolute => {
                    world.bodies[child].add_torque(w, true);
                    world.bodies[self.bodies[i]].add_torque(-w, true);
                }
                JointKind::Prismatic => {
                    world.bodies[child].add_force(w, true);
                    world.bodies[self.bodies[i]].add_force(-w, true);
                }
            }
        }
    }

    /// Removes the torques applied for the last step.
    pub fn clear_torques(&self, world: &mut PhysicsWorld) {
        for &b in &self.bodies[1..] {
            world.bodies[b].reset_torques(false);
            world.bodies[b].reset_forces(false);
        }
    }

    /// Moves the joints by `dq` (rad, or m on prismatic joints) without touching their speeds,
    /// and the links' bodies and colliders with them. The bodies are moved through
    /// `RigidBody::set_position`, which flags the change: rapier's `update_rigid_bodies` writes
    /// the poses without the flag, and the colliders then stay where the step left them until
    /// the end of the next step, so the next narrow phase measures the contacts at the pose
    /// before the displacement.
    pub fn displace(&self, world: &mut PhysicsWorld, dq: &[f64]) {
        let (mb, _) = world
            .multibody_joints
            .get_mut(self.joints[0])
            .expect("arm joints exist");
        let disp: Vec<f32> = dq.iter().map(|&v| v as f32).collect();
        mb.apply_displacements(&disp);
        mb.forward_kinematics(&world.bodies, false);
        for link in mb.links().skip(1) {
            world.bodies[link.rigid_body_handle()].set_position(*link.local_to_world(), false);
        }
    }

    /// Sets the joint velocities (rad/s, or m/s on prismatic joints), and the links' bodies'
    /// velocities with them (through rapier's body Jacobians, at the links' current poses).
    pub fn set_qd(&self, world: &mut PhysicsWorld, qd: &[f64]) {
        let (mb, _) = world
            .multibody_joints
            .get_mut(self.joints[0])
            .expect("arm joints exist");
        let mut v = mb.generalized_velocity_mut();
        for (slot, &x) in v.iter_mut().zip(qd) {
            *slot = x as f32;
        }
        let v = mb.generalized_velocity().clone_owned();
        for link in mb.links().skip(1) {
            let twist = mb.body_jacobian(link.link_id()) * &v;
            let rb = &mut world.bodies[link.rigid_body_handle()];
            rb.set_linvel(Vector::new(twist[0], twist[1], twist[2]), false);
            rb.set_angvel(Vector::new(twist[3], twist[4], twist[5]), false);
        }
    }

    /// Body of the last link (the one carrying the flange and the tool).
    pub fn last_body(&self) -> RigidBodyHandle {
        *self.bodies.last().expect("at least one link")
    }

    /// The arm's mechanical energy, J: the links' kinetic energy, the rotors' (`armature`, kg m^2,
    /// at joint speeds `qd`) and the links' potential energy in the world's gravity.
    pub fn mechanical_energy(&self, world: &PhysicsWorld, armature: &[f64], qd: &[f64]) -> f64 {
        let g = super::v64(world.gravity);
        let links: f64 = self.bodies[1..]
            .iter()
            .map(|&b| {
                let rb = &world.bodies[b];
                rb.kinetic_energy() as f64
                    - rb.mass() as f64 * g.dot(&super::v64(rb.center_of_mass()))
            })
            .sum();
        let rotors: f64 = armature.iter().zip(qd).map(|(a, v)| 0.5 * a * v * v).sum();
        links + rotors
    }

    /// Power of the last step's contact impulses on the arm's links at their velocities after
    /// the step, W: the solver's own measure of what it did. A converged contact without
    /// restitution leaves no normal velocity into the surface and friction only opposes sliding,
    /// so this is zero or negative; positive, the contact solve put energy into the arm (an
    /// unconverged solve, or the position correction pushing out faster than it should).
    pub fn contact_power(&self, world: &PhysicsWorld) -> f64 {
        self.bodies[1..]
            .iter()
            .map(|&b| {
                let rb = &world.bodies[b];
                let com = super::v64(rb.center_of_mass());
                let (v, w) = (super::v64(rb.linvel()), super::v64(rb.angvel()));
                rb.colliders()
                    .iter()
                    .map(|&c| {
                        let wrench = super::contact_wrench(world, c, com);
                        wrench.force.dot(&v) + wrench.torque.dot(&w)
                    })
                    .sum::<f64>()
            })
            .sum()
    }

    /// `world_T_link` of the last link, from the physics.
    pub fn last_link_pose(&self, world: &PhysicsWorld) -> Iso {
        pose64(world.bodies[self.last_body()].position())
    }
}

fn add_link_colliders(
    world: &mut PhysicsWorld,
    body: RigidBodyHandle,
    shapes: &[crate::twin::robot::CollisionShape],
) {
    for c in shapes {
        let mut origin = c.origin;
        let shape = match &c.shape {
            Shape::Box { half_extents } => SharedShape::cuboid(
                half_extents.x as f32,
                half_extents.y as f32,
                half_extents.z as f32,
            ),
            Shape::Cylinder { radius, length } => {
                // parry's cylinder runs along y, URDF's along z.
                origin *= Iso::rotation(Vector3::x() * std::f64::consts::FRAC_PI_2);
                SharedShape::cylinder(*length as f32 / 2.0, *radius as f32)
            }
            Shape::Capsule { radius, length } => {
                SharedShape::capsule_z(*length as f32 / 2.0, *radius as f32)
            }
            Shape::Sphere { radius } => SharedShape::ball(*radius as f32),
            Shape::ConvexHull { points } => {
                let pts: Vec<Vector> = points
                    .iter()
                    .map(|p: &Point3<f64>| v32(&p.coords))
                    .collect();
                match SharedShape::convex_hull(&pts) {
                    Some(s) => s,
                    None => continue,
                }
            }
        };
        world.insert_collider(
            ColliderBuilder::new(shape)
                .density(0.0)
                .position(pose32(&origin)),
            Some(body),
        );
    }
}
