//! The real cell (`[cell] profile = "real"`): each cell draws its imperfections from its seed and
//! they act as drawn. A trial records its draw and repeats bit for bit; the ideal cell ignores the
//! robot file's joint friction and the real one scales it; the wrench estimate reads the drawn
//! bias at rest; the controller's wrong load data moves the held TCP by what its stiffness
//! predicts.

use nalgebra::Vector6;
use pegtwin::method::config::Method;
use pegtwin::method::request::TrialRequest;
use pegtwin::twin::control::ImpedanceGains;
use pegtwin::twin::geometry::{PartPair, build_builtin, builtin_by_name};
use pegtwin::twin::real_cell::{Profile, RealCell};
use pegtwin::twin::robot::RobotModel;
use pegtwin::twin::robot::urdf::iiwa14;
use pegtwin::twin::workcell::{WorkCell, WorkCellParams, nominal_hole_pose, tcp_in_hole};

fn cross() -> PartPair {
    build_builtin(builtin_by_name("cross").unwrap(), 0.5e-3).unwrap()
}

/// The real cell with every imperfection fixed at the value given (the others ideal).
fn real(edit: impl FnOnce(&mut RealCell)) -> RealCell {
    let mut cell = RealCell {
        profile: Profile::Real,
        joint_friction_scale: [0.0, 0.0],
        contact_friction: [0.3, 0.3],
        static_over_kinetic: [1.0, 1.0],
        wrench_bias: [0.0, 0.0],
        wrench_gain: [1.0, 1.0],
        payload_error: [0.0, 0.0],
        latency_s: 0.0,
        encoder_offset_rad: 0.0,
        print_deviation_m: [0.0, 0.0],
        edge_bevel_m: [0.3e-3, 0.3e-3],
    };
    edit(&mut cell);
    cell
}

/// A cell in free air 0.1 m over the nominal hole under `gains`.
fn free_cell(robot: RobotModel, cell: RealCell, gains: ImpedanceGains, seed: u64) -> WorkCell {
    let pair = cross();
    let params = WorkCellParams {
        cell,
        ..WorkCellParams::default()
    };
    let start = tcp_in_hole(&nominal_hole_pose(&pair, &params), -0.1);
    WorkCell::new(&pair, robot, &params, None, &start, gains, seed).unwrap()
}

#[test]
fn a_real_trial_records_its_draw_and_repeats_bit_for_bit() {
    let request = |profile| TrialRequest {
        method: Method::Direct,
        seed: 3,
        t_obs_s: 2.0,
        profile,
        ..TrialRequest::new("cross", 0.5)
    };
    let json = |r: &TrialRequest| serde_json::to_string(&r.run(&()).unwrap()).unwrap();
    let first = json(&request(Profile::Real));
    assert_eq!(
        first,
        json(&request(Profile::Real)),
        "the same seed, the same record"
    );
    let record: serde_json::Value = serde_json::from_str(&first).unwrap();
    let drawn = RealCell::default().draw(3, 7).unwrap();
    assert_eq!(record["real_cell"], serde_json::to_value(&drawn).unwrap());
    let ideal: serde_json::Value = serde_json::from_str(&json(&request(Profile::Ideal))).unwrap();
    assert!(
        ideal.get("real_cell").is_none(),
        "an ideal record has no draw"
    );
}

/// How far the limp TCP moves in 0.5 s under a 2 N push along base x, m.
fn travel_under_push(robot: RobotModel, cell: RealCell) -> f64 {
    let limp = ImpedanceGains {
        stiffness: [0.0; 6],
        null_stiffness: 0.0,
        ..ImpedanceGains::default()
    };
    let mut c = free_cell(robot, cell, limp, 1);
    c.run(0.1);
    let before = c.truth().tcp_pose().translation.vector;
    c.set_disturbance(Some(Vector6::new(2.0, 0.0, 0.0, 0.0, 0.0, 0.0)));
    c.run(0.5);
    assert!(c.fault().is_none(), "{:?}", c.fault());
    (c.truth().tcp_pose().translation.vector - before).norm()
}

#[test]
fn the_ideal_cell_ignores_the_files_joint_friction_and_the_real_one_scales_it() {
    let mut sticky = iiwa14().unwrap();
    for j in &mut sticky.joints {
        j.friction = 1.0;
    }
    let ideal = travel_under_push(sticky.clone(), RealCell::ideal());
    let none = travel_under_push(sticky.clone(), real(|_| {}));
    let held = travel_under_push(sticky, real(|c| c.joint_friction_scale = [2.0, 2.0]));
    assert!(ideal > 1e-3, "the ideal arm moved {ideal} m");
    assert!(
        none > 1e-3,
        "the real arm at friction scale 0 moved {none} m"
    );
    assert!(
        held < 20e-6,
        "2 N m of friction per joint let it move {held} m"
    );
}

#[test]
fn the_wrench_estimate_reads_the_drawn_bias_at_rest() {
    let cell = real(|c| c.wrench_bias = [3.0, 0.5]);
    let mut c = free_cell(iiwa14().unwrap(), cell, ImpedanceGains::default(), 5);
    c.run(1.0);
    let bias = Vector6::from(c.draw().unwrap().wrench_bias);
    let error = c.measurements().wrench - bias;
    assert!(bias.norm() > 0.5, "{bias}");
    assert!(
        error.fixed_rows::<3>(0).norm() < 0.5,
        "{error} against {bias}"
    );
}

#[test]
fn wrong_load_data_moves_the_held_tcp_by_what_its_stiffness_predicts() {
    let gains = ImpedanceGains::default();
    let k_z = gains.stiffness[2];
    let height = |payload_error: f64| {
        let cell = real(|c| c.payload_error = [payload_error, payload_error]);
        let mut c = free_cell(iiwa14().unwrap(), cell, gains.clone(), 1);
        c.run(1.5);
        c.truth().tcp_pose().translation.z
    };
    let (exact, heavy) = (height(0.0), height(0.5));
    // The controller compensates gravity for 1.5 x the peg's mass: the surplus lifts the TCP
    // against the z stiffness.
    let predicted = 0.5 * pegtwin::twin::workcell::BUILTIN_PEG_MASS_KG * 9.81 / k_z;
    let rise = heavy - exact;
    assert!(
        (rise - predicted).abs() < 0.2 * predicted,
        "rose {rise} m, predicted {predicted} m"
    );
}

#[test]
fn encoder_offsets_move_the_measured_tcp_as_the_kinematics_of_the_offset_joints_say() {
    let cell = real(|c| c.encoder_offset_rad = 1e-3);
    let mut c = free_cell(iiwa14().unwrap(), cell, ImpedanceGains::default(), 7);
    c.run(0.2);
    let offsets = c.draw().unwrap().encoder_offset_rad.clone();
    assert_eq!(offsets.len(), 7);
    let q = c.truth().q();
    let seen: Vec<f64> = q.iter().zip(&offsets).map(|(q, o)| q + o).collect();
    let params = WorkCellParams::default();
    let model = pegtwin::twin::workcell::with_peg(iiwa14().unwrap(), &cross(), &params).unwrap();
    let expected = model.tcp_pose(&seen).translation.vector;
    let truth = c.truth().tcp_pose().translation.vector;
    let measured = c.measurements().tcp.translation.vector;
    assert!((measured - truth).norm() > 0.1e-3, "the offsets moved it");
    // Within the encoders' 20-bit quantisation over the arm's reach.
    assert!(
        (measured - expected).norm() < 20e-6,
        "{measured} vs {expected}"
    );
}
