//! `pegtwin validate [--arm]`: the physics self-check of a pair, printed.

use super::ValidateArgs;
use pegtwin::error::Result;
use pegtwin::method::config::TrialConfig;
use pegtwin::method::manifold::build::SamplerConfig;
use pegtwin::selfcheck::Verdict;
use pegtwin::selfcheck::arm::{ArmValidationReport, validate_arm};
use pegtwin::selfcheck::free_peg::{FreePegGains, ValidationReport, validate};
use pegtwin::twin::physics::{ArmContacts, PhysicsParams};
use serde::Serialize;

/// Runs the free-peg or the arm validation; exit 0 only when every case is as expected.
pub fn validate_command(args: ValidateArgs) -> Result<i32> {
    let pair = args.pair.build()?;
    let passed = if args.arm {
        let (robot, mut params) = args.pair.robot()?;
        params.physics.position_projection = args.position_projection;
        params.cell.profile = args.profile;
        if args.rapier_contacts {
            params.physics.arm_contacts = ArmContacts::Rapier;
        }
        let report = validate_arm(
            &pair,
            &robot,
            &params,
            &TrialConfig::default(),
            &SamplerConfig::default(),
        )?;
        show(&report, args.json, print_arm_validation);
        report.passed
    } else {
        let report = validate(&pair, &PhysicsParams::default(), FreePegGains::default());
        show(&report, args.json, print_validation);
        report.passed
    };
    Ok(if passed { 0 } else { 1 })
}

fn show<R: Serialize>(report: &R, json: bool, print: fn(&R)) {
    if json {
        println!(
            "{}",
            serde_json::to_string_pretty(report).expect("report serialises")
        );
    } else {
        print(report);
    }
}

fn verdict(passed: bool) -> &'static str {
    if passed {
        "all cases as expected"
    } else {
        "SOME CASES FAILED"
    }
}

fn print_arm_validation(r: &ArmValidationReport) {
    println!(
        "validate --arm {} at {} mm clearance (penetration limit {:.4} mm; {}, {} substeps, {} Gauss-Seidel passes, {})",
        r.geometry,
        r.clearance_mm,
        r.penetration_limit_mm,
        r.rig.robot,
        r.physics.solver_iterations,
        r.physics.pgs_iterations,
        match (r.physics.position_projection, r.physics.arm_contacts) {
            (false, ArmContacts::JointSpace) => "joint-space contacts",
            (true, ArmContacts::JointSpace) => "joint-space contacts, position projection",
            (false, ArmContacts::Rapier) => "rapier's contacts",
            (true, ArmContacts::Rapier) => "rapier's contacts, position projection",
        }
    );
    for c in &r.cases {
        let v = &c.verdict;
        println!(
            "{} {:<18} pen {:.4} mm  peak |F| {:.1} N  |T| {:.2} N m  {:.0} steps/s  ({} gains)",
            if v.passed { "PASS" } else { "FAIL" },
            v.name,
            v.max_penetration_mm,
            c.peak_force_n,
            c.peak_torque_nm,
            v.steps_per_s,
            c.gains
        );
        print_expected_and_observed(v);
        if let Some(f) = &c.fault {
            println!("     sim_fault at {:.3} s: {}", f.time_s, f.reason);
        }
    }
    if r.cases.iter().all(|c| c.verdict.outcome_required) {
        println!("{}", verdict(r.passed));
    } else if r.passed {
        println!("every case sound: no sim_fault, penetration within the limit");
    } else {
        println!("SOME CASES FAULTED OR PENETRATED PAST THE LIMIT");
    }
}
/// A case's expected and observed outcomes, the expected one marked when it is only reported
/// (an ideal arm's, on the real cell).
fn print_expected_and_observed(v: &Verdict) {
    let reported_only = match v.outcome_required {
        true => "",
        false => " (an ideal arm's; on the real cell, reported only)",
    };
    println!(
        "     expected{reported_only}: {}\n     observed: {}",
        v.expected, v.observed
    );
}

fn print_validation(r: &ValidationReport) {
    println!(
        "validate {} at {} mm clearance (penetration limit {:.4} mm; step {} ms)",
        r.geometry,
        r.clearance_mm,
        r.penetration_limit_mm,
        r.physics.dt_s * 1e3
    );
    for c in &r.cases {
        let v = &c.verdict;
        println!(
            "{} {:<18} pen {:.4} mm  F_solver ({:+.3}, {:+.3}, {:+.3}) N  momentum err {:.2} %  {:.0} steps/s",
            if v.passed { "PASS" } else { "FAIL" },
            v.name,
            v.max_penetration_mm,
            c.force_readout_n[0],
            c.force_readout_n[1],
            c.force_readout_n[2],
            c.force_error_pct,
            v.steps_per_s
        );
        print_expected_and_observed(v);
    }
    println!("{}", verdict(r.passed));
}
