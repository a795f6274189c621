//! The contact physics, through `validate`: every case behaves as expected, exact penetration
//! stays under 10 % of the gap, and the solver's contact force agrees with the momentum check.
//! The full matrix (five built-ins x four clearances) is `pegtwin validate`; here the tightest
//! clearance for every built-in and the loosest for the reference geometry.

use pegtwin::selfcheck::free_peg::{FORCE_AGREEMENT, FreePegGains, validate};
use pegtwin::twin::geometry::{Builtin, build_builtin};
use pegtwin::twin::physics::PhysicsParams;

fn check(builtin: Builtin, clearance_mm: f64) {
    let pair = build_builtin(builtin, clearance_mm * 1e-3).unwrap();
    let report = validate(&pair, &PhysicsParams::default(), FreePegGains::default());
    for case in &report.cases {
        assert!(
            case.verdict.passed,
            "{} at {clearance_mm} mm, {}: expected {}; observed {}; penetration {:.4} mm (limit {:.4}); force error {:.2} %",
            builtin.name(),
            case.verdict.name,
            case.verdict.expected,
            case.verdict.observed,
            case.verdict.max_penetration_mm,
            report.penetration_limit_mm,
            case.force_error_pct
        );
        assert!(case.force_error_pct <= FORCE_AGREEMENT * 100.0);
    }
    let floor = report
        .cases
        .iter()
        .find(|c| c.verdict.name == "floor_press")
        .unwrap();
    assert!(
        (floor.force_readout_n[2] - 2.0).abs() < 0.05,
        "{:?}",
        floor.force_readout_n
    );
}

#[test]
fn cross_at_the_tightest_and_loosest_clearance() {
    check(Builtin::Cross, 0.1);
    check(Builtin::Cross, 1.0);
}

#[test]
fn extrusion_at_0_1_mm() {
    check(Builtin::Extrusion, 0.1);
}

#[test]
fn plug3_at_0_1_mm() {
    check(Builtin::Plug3, 0.1);
}

#[test]
fn key_at_0_1_mm() {
    check(Builtin::Key, 0.1);
}

#[test]
fn gear_at_0_1_mm() {
    check(Builtin::Gear, 0.1);
}
