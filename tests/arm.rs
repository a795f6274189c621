//! The arm as a rapier multibody: torque-driven, held by gravity compensation, consistent with
//! the model's kinematics.

use pegtwin::twin::physics::PhysicsParams;
use pegtwin::twin::physics::arm::Arm;
use pegtwin::twin::robot::urdf::{IIWA7_URDF, IIWA14_URDF, UR5E_URDF, load};
use pegtwin::twin::robot::{GRAVITY_UPRIGHT, Iso, RobotModel};
use std::f64::consts::{FRAC_PI_2, FRAC_PI_4};
use std::path::Path;

/// Tool pointing down over the table (docs/sources.md, 1: the third test vector).
const TOOL_DOWN: [f64; 7] = [0.0, FRAC_PI_4, 0.0, -FRAC_PI_2, 0.0, FRAC_PI_4, 0.0];

fn model(path: &str) -> RobotModel {
    load(Path::new(path), &[]).unwrap().model
}

/// Largest flange displacement (m) over `seconds` with tau = g(q) from the model.
fn gravity_hold_drift(robot: &RobotModel, q0: &[f64], seconds: f64) -> f64 {
    let params = PhysicsParams::default();
    let mut world = params.new_world();
    let arm = Arm::insert(&mut world, robot, Iso::identity(), q0, vec![]);
    let start = robot.flange_pose(q0).translation.vector;
    let mut worst: f64 = 0.0;
    for _ in 0..(seconds / params.dt_s).round() as usize {
        let q = arm.q(&world);
        let g = robot.gravity_torques(&robot.kinematics(&q), &GRAVITY_UPRIGHT);
        arm.apply_torques(&mut world, g.as_slice());
        world.step();
        arm.clear_torques(&mut world);
        let now = robot.flange_pose(&arm.q(&world)).translation.vector;
        worst = worst.max((now - start).norm());
    }
    worst
}

#[test]
fn multibody_starts_where_the_model_says() {
    let robot = model(IIWA14_URDF);
    let mut world = PhysicsParams::default().new_world();
    let arm = Arm::insert(&mut world, &robot, Iso::identity(), &TOOL_DOWN, vec![]);
    let q = arm.q(&world);
    for (a, b) in q.iter().zip(TOOL_DOWN) {
        assert!((a - b).abs() < 1e-6, "{q:?}");
    }
    let link7 = arm.last_link_pose(&world);
    let flange = link7 * robot.last_t_flange;
    let expected = robot.flange_pose(&TOOL_DOWN);
    assert!((flange.translation.vector - expected.translation.vector).norm() < 1e-6);
    assert!(flange.rotation.angle_to(&expected.rotation) < 1e-5);
}

#[test]
fn gravity_compensation_holds_both_arms_within_10_micrometres_for_5_s() {
    for path in [IIWA14_URDF, IIWA7_URDF] {
        let robot = model(path);
        let drift = gravity_hold_drift(&robot, &TOOL_DOWN, 5.0);
        println!("{}: drift {:.2e} m", robot.name, drift);
        assert!(drift < 1e-5, "{}: drift {drift} m", robot.name);
    }
}

#[test]
fn gravity_compensation_holds_the_six_joint_ur5e_within_10_micrometres_for_5_s() {
    let robot = model(UR5E_URDF);
    // Elbow up, tool pointing down.
    let q = [0.0, -FRAC_PI_2, FRAC_PI_2, -FRAC_PI_2, -FRAC_PI_2, 0.0];
    let drift = gravity_hold_drift(&robot, &q, 5.0);
    assert!(drift < 1e-5, "drift {drift} m");
}

#[test]
fn without_gravity_compensation_the_arm_falls() {
    let robot = model(IIWA14_URDF);
    let params = PhysicsParams::default();
    let mut world = params.new_world();
    let arm = Arm::insert(&mut world, &robot, Iso::identity(), &TOOL_DOWN, vec![]);
    for _ in 0..200 {
        world.step();
    }
    let q = arm.q(&world);
    let fell = (robot.flange_pose(&q).translation.vector
        - robot.flange_pose(&TOOL_DOWN).translation.vector)
        .norm();
    assert!(fell > 0.01, "fell {fell} m");
}
