//! The robot cell end to end: static stiffness under impedance, the estimated wrench against the
//! physics' contact force, insertion at 0.1 mm clearance, stalling when misaligned, mode switches.

use pegtwin::selfcheck::stiffness::{PushTest, measure_stiffness};
use pegtwin::twin::control::{ImpedanceGains, JointPositionGains, Mode};
use pegtwin::twin::energy::EnergySource;
use pegtwin::twin::geometry::{PartPair, build_builtin, builtin_by_name};
use pegtwin::twin::physics::ArmContacts;
use pegtwin::twin::physics::penetration::PenetrationProbe;
use pegtwin::twin::robot::Iso;
use pegtwin::twin::robot::urdf::iiwa14;
use pegtwin::twin::workcell::{WorkCell, WorkCellParams, nominal_hole_pose, tcp_in_hole};

/// The cell in free space (no fixture), the arm at rest at `start` under `gains`.
fn free_cell(
    pair: &PartPair,
    params: &WorkCellParams,
    start: &Iso,
    gains: ImpedanceGains,
) -> Result<WorkCell, pegtwin::error::Error> {
    WorkCell::new(pair, iiwa14().unwrap(), params, None, start, gains, 1)
}

fn cross(clearance_m: f64) -> PartPair {
    build_builtin(builtin_by_name("cross").unwrap(), clearance_m).unwrap()
}

#[test]
fn static_stiffness_is_within_5_percent_at_sunrise_defaults_and_maxima() {
    let pair = cross(0.5e-3);
    let robot = iiwa14().unwrap();
    for gains in [
        ImpedanceGains::default(),
        ImpedanceGains::uniform(5000.0, 300.0, 0.7),
    ] {
        let axes = measure_stiffness(
            &pair,
            &robot,
            &WorkCellParams::default(),
            &gains,
            PushTest::default(),
        )
        .unwrap();
        for a in axes {
            assert!(
                a.error_percent.abs() < 5.0,
                "{} commanded {} measured {}",
                a.axis,
                a.commanded,
                a.measured
            );
        }
    }
}

/// Lowers the peg from `start` by `travel_m` along the hole axis over 2 s, holds 2 s more;
/// returns the cell and the largest exact penetration seen (sampled every 5 ms).
fn press_down(
    pair: &PartPair,
    start: Iso,
    travel_m: f64,
    params: &WorkCellParams,
) -> (WorkCell, f64) {
    let hole = nominal_hole_pose(pair, params);
    let mut cell = WorkCell::new(
        pair,
        iiwa14().unwrap(),
        params,
        Some(hole),
        &start,
        ImpedanceGains::default(),
        7,
    )
    .unwrap();
    let probe = PenetrationProbe::new(&pair.hole, &hole);
    let mut worst: f64 = 0.0;
    for i in 0..4000 {
        let s = (i as f64 / 2000.0).min(1.0);
        cell.command_pose(start * Iso::translation(0.0, 0.0, -travel_m * s));
        cell.step();
        if i % 5 == 0 {
            worst = worst.max(probe.max_penetration(&pair.peg, &cell.truth().tcp_pose()));
        }
    }
    (cell, worst)
}

/// The cross at 0.1 mm lowered 1 mm off its axis, so that its arms land on the rim and are
/// pressed 10 mm further down (`press_down`).
fn press_on_rim(pair: &PartPair, params: &WorkCellParams) -> (WorkCell, f64) {
    let hole = nominal_hole_pose(pair, params);
    let start = tcp_in_hole(&hole, -0.001) * Iso::translation(0.001, 0.0, 0.0);
    press_down(pair, start, 0.01, params)
}

fn depth_m(cell: &WorkCell) -> f64 {
    -(cell.truth().base_t_hole().unwrap().inverse() * cell.truth().tcp_pose())
        .translation
        .z
}

#[test]
fn aligned_cross_goes_from_2_mm_to_full_depth_at_0_1_mm_and_the_press_is_estimated_within_1_n() {
    let pair = cross(0.1e-3);
    let params = WorkCellParams::default();
    let hole = nominal_hole_pose(&pair, &params);
    let start = tcp_in_hole(&hole, 0.002);
    let (cell, worst) = press_down(&pair, start, pair.cavity_depth_m + 0.003, &params);
    let depth = depth_m(&cell);
    assert!(
        (depth - pair.cavity_depth_m).abs() < 0.1e-3,
        "depth {depth} m"
    );
    assert!(worst <= 5e-6, "penetration {worst} m");
    // Static press on the floor: 2000 N/m x about 5 mm.
    let truth = cell.truth().contact_wrench();
    let est = cell.measurements().wrench;
    let f_true = truth.fixed_rows::<3>(0).into_owned();
    let f_est = est.fixed_rows::<3>(0).into_owned();
    assert!(f_true.z > 5.0, "pressing {f_true}");
    let noise = 3.0 * params.sensors.torque_noise_nm; // N m at about 1 m lever
    assert!(
        (f_est - f_true).norm() < 1.0 + noise,
        "estimated {f_est} true {f_true}"
    );
    assert!(cell.measurements().contact);
}

#[test]
fn misaligned_cross_stalls_on_the_mouth() {
    let pair = cross(0.1e-3);
    let params = WorkCellParams::default();
    let (cell, worst) = press_on_rim(&pair, &params);
    assert!(depth_m(&cell) < 0.1e-3, "depth {}", depth_m(&cell));
    assert!(worst <= 5e-6, "penetration {worst} m");
    let f = cell.truth().contact_wrench();
    assert!(f.z > 10.0, "the rim carries the press: {f}");
}

#[test]
fn contacts_take_energy_out_of_the_arm_and_the_account_closes_while_pressing_the_rim() {
    let pair = cross(0.1e-3);
    let params = WorkCellParams::default();
    let (cell, _) = press_on_rim(&pair, &params);
    let f = cell.energy_flows();
    assert!(cell.truth().contact_wrench().z > 10.0, "pressing the rim");
    assert!(f.contacts_j <= 1e-3, "contacts put energy in: {f:?}");
    assert!(
        f.integration_j.abs() <= 1e-3,
        "the account does not close: {f:?}"
    );
}

#[test]
fn a_commanded_twist_is_paid_for_by_the_drives_and_the_account_closes() {
    let pair = cross(0.5e-3);
    let params = WorkCellParams::default();
    let start = tcp_in_hole(&nominal_hole_pose(&pair, &params), -0.05);
    let gains = ImpedanceGains::uniform(2000.0, 300.0, 0.7);
    let mut cell = free_cell(&pair, &params, &start, gains).unwrap();
    cell.run(0.2);
    let twisted = start
        * Iso::from_parts(
            nalgebra::Translation3::identity(),
            nalgebra::UnitQuaternion::from_euler_angles(0.0, 0.0, 0.1),
        );
    cell.command_pose(twisted);
    cell.run(0.05);
    let f = cell.energy_flows();
    assert_eq!(f.source, EnergySource::Drives);
    assert!(f.drives_j > 0.05 && f.contacts_j == 0.0, "{f:?}");
    // rapier treats the damping and the gyroscopic terms implicitly: its integrator loses a
    // little of what the drives put in (15 % of it in this fast swing), and gains none.
    assert!(
        f.integration_j <= 0.0 && f.integration_j.abs() <= 0.2 * f.drives_j,
        "the account does not close: {f:?}"
    );
}

#[test]
fn switching_to_joint_position_mode_holds_the_pose_without_a_torque_jump() {
    let pair = cross(0.5e-3);
    let params = WorkCellParams::default();
    let hole = nominal_hole_pose(&pair, &params);
    let start = tcp_in_hole(&hole, -0.05);
    let mut cell = free_cell(&pair, &params, &start, ImpedanceGains::default()).unwrap();
    cell.run(0.5);
    let before = cell.truth().tcp_pose();
    let q = cell.truth().q();
    cell.set_mode(Mode::JointPosition {
        gains: JointPositionGains::default(),
        target: q,
    })
    .unwrap();
    let mut last = cell.torques().clone();
    for _ in 0..500 {
        cell.step();
        let jump = (cell.torques() - &last).amax();
        assert!(jump <= 1.5, "torque jump {jump} N m in one step");
        last = cell.torques().clone();
    }
    let moved = (cell.truth().tcp_pose().translation.vector - before.translation.vector).norm();
    assert!(moved < 0.1e-3, "moved {moved} m");
    let bad = ImpedanceGains {
        stiffness: [2000.0, 2000.0, 9000.0, 200.0, 200.0, 200.0],
        ..Default::default()
    };
    let e = cell
        .set_mode(Mode::CartesianImpedance {
            gains: bad,
            target: before,
        })
        .unwrap_err()
        .to_string();
    assert!(e.contains("stiffness z") && e.contains("9000"), "{e}");
}

#[test]
fn feed_forward_wrench_and_max_control_force_act_as_in_sunrise() {
    let pair = cross(0.5e-3);
    let params = WorkCellParams::default();
    let start = tcp_in_hole(&nominal_hole_pose(&pair, &params), -0.1);
    // 10 N feed-forward along TCP z against 2000 N/m: the TCP moves 5 mm along its z.
    let gains = ImpedanceGains {
        additional_force: [0.0, 0.0, 10.0, 0.0, 0.0, 0.0],
        ..Default::default()
    };
    let mut cell = free_cell(&pair, &params, &start, gains).unwrap();
    cell.run(2.0);
    let e = pegtwin::twin::control::tcp_error(&cell.truth().tcp_pose(), &start);
    assert!((e[2] - 0.005).abs() < 0.05e-3, "moved {e}");
    // A 6 N push along x with the spring force capped at 2 N: the TCP keeps yielding.
    let gains = ImpedanceGains {
        max_control_force: Some([2.0, 50.0, 50.0, 5.0, 5.0, 5.0]),
        ..Default::default()
    };
    let mut cell = free_cell(&pair, &params, &start, gains).unwrap();
    let x = start.rotation * nalgebra::Vector3::x();
    cell.set_disturbance(Some(nalgebra::Vector6::new(
        6.0 * x.x,
        6.0 * x.y,
        6.0 * x.z,
        0.0,
        0.0,
        0.0,
    )));
    cell.run(0.5);
    let early = pegtwin::twin::control::tcp_error(&cell.truth().tcp_pose(), &start)[0];
    cell.run(0.5);
    let late = pegtwin::twin::control::tcp_error(&cell.truth().tcp_pose(), &start)[0];
    assert!(
        early > 0.01 && late > early + 0.01,
        "capped spring must yield: {early} then {late} m"
    );
}

#[test]
fn control_rate_is_independent_of_the_physics_step() {
    let pair = cross(0.5e-3);
    let mut params = WorkCellParams::default();
    params.controller.rate_hz = 500.0;
    let start = tcp_in_hole(&nominal_hole_pose(&pair, &params), -0.1);
    let mut cell = free_cell(&pair, &params, &start, ImpedanceGains::default()).unwrap();
    cell.run(1.0);
    assert!(
        (cell.truth().tcp_pose().translation.vector - start.translation.vector).norm() < 0.05e-3
    );
    params.controller.rate_hz = 300.0;
    let e = free_cell(&pair, &params, &start, ImpedanceGains::default())
        .err()
        .unwrap()
        .to_string();
    assert!(e.contains("whole number of physics steps"), "{e}");
}

#[test]
fn a_drive_asked_for_more_than_its_torque_limit_is_named_until_100_ms_after() {
    let pair = cross(0.5e-3);
    let params = WorkCellParams::default();
    let start = tcp_in_hole(&nominal_hole_pose(&pair, &params), -0.05);
    let gains = ImpedanceGains::uniform(2000.0, 300.0, 0.7);
    let mut cell = free_cell(&pair, &params, &start, gains).unwrap();
    cell.run(0.05);
    assert!(cell.saturated_joints().is_empty(), "holding still");
    // Half a radian of yaw at 300 N m/rad asks joint 7 for 150 N m; it has 40.
    let twisted = start
        * Iso::from_parts(
            nalgebra::Translation3::identity(),
            nalgebra::UnitQuaternion::from_euler_angles(0.0, 0.0, 0.5),
        );
    cell.command_pose(twisted);
    cell.run(0.01);
    assert_eq!(cell.saturated_joints(), ["iiwa_joint_7"]);
    cell.command_pose(start);
    cell.run(1.0);
    assert!(cell.saturated_joints().is_empty(), "settled back");
}

#[test]
fn joint_space_contacts_carry_the_rim_press_with_an_estimate_within_1_n_and_a_closed_account() {
    let pair = cross(0.1e-3);
    let mut params = WorkCellParams::default();
    params.physics.arm_contacts = ArmContacts::JointSpace;
    let (cell, worst) = press_on_rim(&pair, &params);
    assert!(depth_m(&cell) < 0.1e-3, "depth {}", depth_m(&cell));
    assert!(worst <= 1e-6, "penetration {worst} m");
    let truth = cell.truth().contact_wrench();
    let f_true = truth.fixed_rows::<3>(0).into_owned();
    let f_est = cell.measurements().wrench.fixed_rows::<3>(0).into_owned();
    assert!(f_true.z > 10.0, "the rim carries the press: {f_true}");
    let noise = 3.0 * params.sensors.torque_noise_nm;
    assert!(
        (f_est - f_true).norm() < 1.0 + noise,
        "estimated {f_est} true {f_true}"
    );
    let f = cell.energy_flows();
    assert!(f.contacts_j <= 1e-3, "contacts put energy in: {f:?}");
    assert!(
        f.integration_j.abs() <= 1e-3,
        "the account does not close: {f:?}"
    );
}

#[test]
fn the_energy_account_opens_with_the_arms_energy_so_an_early_fault_is_not_booked_to_the_integrator()
{
    // The arm at rest in free space: its first 10 ms change its energy by next to nothing. The
    // account used to open at 0 J (rapier's bodies weigh nothing until its first step) and then
    // booked the links' 74 J of potential energy to the integrator for the first 100 ms.
    let pair = cross(0.5e-3);
    let params = WorkCellParams::default();
    let start = nominal_hole_pose(&pair, &params) * Iso::translation(0.0, 0.0, 0.05);
    let mut cell = free_cell(&pair, &params, &start, ImpedanceGains::default()).unwrap();
    cell.run(0.01);
    let f = cell.energy_flows();
    assert!(f.mechanical_gain_j.abs() < 0.01, "{f:?}");
    assert!(f.integration_j.abs() < 0.01, "{f:?}");
}
