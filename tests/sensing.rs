//! What the real cell senses and commands imperfectly. The wrench estimate's calibration error
//! (`[sensors] wrench_bias`, `wrench_gain`): a known push on the TCP is reported as
//! `gain x push + bias`, and the contact flag reads the reported value. The control latency
//! (`ControllerParams::latency_s`): the drives get each cycle's torques that much later.

use nalgebra::Vector6;
use pegtwin::twin::control::{ControllerParams, ImpedanceGains};
use pegtwin::twin::geometry::{build_builtin, builtin_by_name};
use pegtwin::twin::robot::Iso;
use pegtwin::twin::robot::urdf::iiwa14;
use pegtwin::twin::sensing::SensorParams;
use pegtwin::twin::workcell::{WorkCell, WorkCellParams, nominal_hole_pose, tcp_in_hole};

/// The cross's arm held at the Sunrise defaults in free air 0.1 m over the nominal hole, after
/// 0.2 s at rest, under `params`; and its start pose.
fn held_arm(params: &WorkCellParams) -> (WorkCell, Iso) {
    let pair = build_builtin(builtin_by_name("cross").unwrap(), 0.5e-3).unwrap();
    let start = tcp_in_hole(&nominal_hole_pose(&pair, params), -0.1);
    let gains = ImpedanceGains::default();
    let mut cell = WorkCell::new(&pair, iiwa14().unwrap(), params, None, &start, gains, 1).unwrap();
    cell.run(0.2);
    (cell, start)
}

/// The reported wrench after 1 s of a 10 N push along base x on the arm held at the Sunrise
/// defaults in free air, with noise-free sensors and the calibration error `gain`, `bias`.
fn reported(gain: f64, bias: [f64; 6]) -> (Vector6<f64>, bool) {
    let params = WorkCellParams {
        sensors: SensorParams {
            wrench_gain: gain,
            wrench_bias: bias,
            ..SensorParams::ideal()
        },
        ..WorkCellParams::default()
    };
    let (mut cell, _) = held_arm(&params);
    let idle_contact = cell.measurements().contact;
    cell.set_disturbance(Some(Vector6::new(10.0, 0.0, 0.0, 0.0, 0.0, 0.0)));
    cell.run(1.0);
    (cell.measurements().wrench, idle_contact)
}

#[test]
fn the_reported_wrench_is_the_estimate_through_its_calibration_error() {
    let (exact, _) = reported(1.0, [0.0; 6]);
    assert!(
        (exact[0] - 10.0).abs() < 0.3 && exact[1].abs() < 0.3,
        "{exact}"
    );
    let bias = [0.0, 2.0, 0.0, 0.0, 0.0, 0.5];
    let (off, _) = reported(1.2, bias);
    let expected = exact * 1.2 + Vector6::from(bias);
    assert!((off - expected).norm() < 1e-9, "{off} against {expected}");
}

#[test]
fn a_bias_above_the_contact_threshold_reads_contact_in_free_air() {
    let (_, contact) = reported(1.0, [6.0, 0.0, 0.0, 0.0, 0.0, 0.0]);
    assert!(
        contact,
        "a 6 N bias against the 5 N threshold read no contact"
    );
}

#[test]
fn a_calibration_error_out_of_range_is_refused_naming_the_field() {
    let p = SensorParams {
        wrench_gain: 3.0,
        ..SensorParams::default()
    };
    assert!(
        p.ensure_valid()
            .unwrap_err()
            .to_string()
            .contains("wrench_gain")
    );
    let p = SensorParams {
        wrench_bias: [0.0, 0.0, 0.0, 20.0, 0.0, 0.0],
        ..SensorParams::default()
    };
    let e = p.ensure_valid().unwrap_err().to_string();
    assert!(e.contains("wrench_bias[3]"), "{e}");
}

/// The step (from a new target commanded at a control cycle) at which the drives' torques first
/// move by more than 1 N m, with the control latency `latency_s`.
fn first_torque_change(latency_s: f64) -> usize {
    let params = WorkCellParams {
        controller: ControllerParams {
            latency_s,
            ..ControllerParams::default()
        },
        sensors: SensorParams::ideal(),
        ..WorkCellParams::default()
    };
    let (mut cell, start) = held_arm(&params);
    let hold = cell.torques().clone();
    cell.command_pose(Iso::translation(0.01, 0.0, 0.0) * start);
    (0..100)
        .find(|_| {
            cell.step();
            (cell.torques() - &hold).amax() > 1.0
        })
        .expect("the torques change")
}

#[test]
fn the_drives_get_the_torques_a_latency_later() {
    let now = first_torque_change(0.0);
    assert_eq!(first_torque_change(0.005), now + 5);
    let e = WorkCellParams {
        controller: ControllerParams {
            latency_s: 0.0015,
            ..ControllerParams::default()
        },
        ..WorkCellParams::default()
    }
    .ensure_valid()
    .unwrap_err()
    .to_string();
    assert!(e.contains("latency_s = 0.0015"), "{e}");
}
