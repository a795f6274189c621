//! `pegtwin validate --arm`: the physics checked where the trials use it, with the peg on the
//! iiwa 14's flange, driven through the Cartesian impedance controller at the gains of the trial
//! phases (observation, alignment, insertion) and of the manifold sampler (paper IV-B, IV-C, V-A).
//!
//! The free-peg `validate` ([`super::free_peg`]) holds a peg of 0.3 kg with 10 N m/rad and checks
//! the contact solver in isolation; the arm adds the articulated inertia of seven links, the
//! controller and the trials' stiffer rotations. Besides the shared [`Verdict`] (its penetration
//! checked every [`PENETRATION_CHECK_STEPS`] steps), each case reports the peak true contact force
//! and torque and any `sim_fault` with its reason. A case passes when its outcome is as expected,
//! no fault stopped it and the penetration stays within its bar.

use super::free_peg::lift_until_free;
use super::{CaseReport, Judgement, Report, Verdict, penetration_limit_m};
use crate::error::Result;
use crate::method::config::TrialConfig;
use crate::method::manifold::build::SamplerConfig;
use crate::method::observe::observation_motion;
use crate::method::primitives::{Drive, PerturbationState, SamplingMotion, ScaleSchedule};
use crate::method::session::{Phase, Recorder, Session};
use crate::pose::Iso;
use crate::twin::control::{ControllerParams, ImpedanceGains};
use crate::twin::geometry::{PartPair, Seat};
use crate::twin::physics::penetration::PenetrationProbe;
use crate::twin::robot::RobotModel;
use crate::twin::workcell::{SimFault, WorkCell, WorkCellParams, nominal_hole_pose};
use nalgebra::{Translation3, UnitQuaternion, Vector3};
use serde::Serialize;
use std::ops::ControlFlow;
use std::time::Instant;

/// Steps between exact penetration checks (the check costs about as much as a step of the gear).
pub const PENETRATION_CHECK_STEPS: u64 = 4;
/// Descent speed of the insertion cases, m/s.
const DESCENT_M_PER_S: f64 = 20e-3;
/// How far the insertion and floor cases press the target below the floor, m.
const PRESS_M: f64 = 1e-3;
/// Time over which the orientation target of a tilted start turns upright, s.
const UPRIGHT_S: f64 = 0.3;
/// Time at the end of a case over which the contact force is averaged, s.
const SETTLE_S: f64 = 0.2;
/// Agreement of the floor's force with the impedance spring (the arm at rest on the floor).
const SPRING_AGREEMENT: f64 = 0.05;
/// Yaw of the believed hole against the true one in the probing case, rad: the oscillation then
/// twists the peg into the walls.
const PROBE_TWIST_RAD: f64 = 0.05;

/// The result of one arm case (its speed: the cell with its controller and sensors).
#[derive(Clone, Debug, Serialize)]
pub struct ArmCase {
    #[serde(flatten)]
    pub verdict: Verdict,
    /// Which gains drove the peg.
    pub gains: String,
    /// The physics fault that stopped the case, if one did.
    pub fault: Option<SimFault>,
    /// Largest true contact force on the peg, N.
    pub peak_force_n: f64,
    /// Largest true contact torque on the peg about its tip, N m.
    pub peak_torque_nm: f64,
}

impl CaseReport for ArmCase {
    fn verdict(&self) -> &Verdict {
        &self.verdict
    }
}

/// What the arm rig holds fixed: the robot and its controller.
#[derive(Clone, Debug, Serialize)]
pub struct ArmSetup {
    /// The robot's name (its URDF's `<robot name>`).
    pub robot: String,
    pub controller: ControllerParams,
}

/// The whole arm validation of a pair.
pub type ArmValidationReport = Report<ArmSetup, ArmCase>;

/// The settled state a case is judged on, all in the hole frame.
struct Settled {
    /// Final `hole_T_tcp` (the true tip pose).
    tip: Iso,
    /// Lowest tip z seen, m.
    min_z_m: f64,
    /// True contact force on the peg averaged over the last [`SETTLE_S`], N.
    force_n: Vector3<f64>,
    /// The target at the end, `hole_T_tcp`.
    target: Iso,
}

/// Judges a case from its settled state: whether the outcome is as expected, and what was seen.
type Judge = Box<dyn Fn(&Settled) -> Judgement>;

/// How a case moves the impedance target.
enum Motion {
    /// `hole_T_tcp` target as a function of time, s; the gains switch to `then` at `switch_s`.
    Path {
        target: Box<dyn Fn(f64) -> Iso>,
        switch: Option<(f64, ImpedanceGains)>,
    },
    /// The sampling primitives in a hole frame yawed by `twist_rad` from the true one.
    Primitives {
        motion: SamplingMotion,
        twist_rad: f64,
    },
}

struct Case {
    name: &'static str,
    gains_name: &'static str,
    gains: ImpedanceGains,
    expected: String,
    /// Start `hole_T_tcp`.
    start: Iso,
    motion: Motion,
    duration_s: f64,
    judge: Judge,
}

/// Looks at the truth after every step: exact penetration, peak wrench, lowest tip, the force
/// over the settling window.
struct Monitor<'a> {
    probe: &'a PenetrationProbe,
    peg: &'a crate::twin::geometry::solid::Solid,
    base_t_hole: Iso,
    settle_from_s: f64,
    steps: u64,
    max_penetration_m: f64,
    peak_force_n: f64,
    peak_torque_nm: f64,
    min_z_m: f64,
    settle_sum: Vector3<f64>,
    settle_n: usize,
    /// Wall time spent in the monitor itself, s (left out of the speed).
    own_s: f64,
}

impl Recorder for Monitor<'_> {
    fn record(&mut self, cell: &WorkCell, _: Phase) {
        let started = Instant::now();
        let truth = cell.truth();
        let tcp = truth.tcp_pose();
        let hole_t_tcp = self.base_t_hole.inverse() * tcp;
        self.min_z_m = self.min_z_m.min(hole_t_tcp.translation.vector.z);
        let w = truth.contact_wrench();
        let force = w.fixed_rows::<3>(0).into_owned();
        self.peak_force_n = self.peak_force_n.max(force.norm());
        self.peak_torque_nm = self.peak_torque_nm.max(w.fixed_rows::<3>(3).norm());
        if cell.time_s() >= self.settle_from_s {
            self.settle_sum += self.base_t_hole.rotation.inverse() * force;
            self.settle_n += 1;
        }
        if self.steps.is_multiple_of(PENETRATION_CHECK_STEPS) {
            let depth = self.probe.max_penetration(self.peg, &tcp);
            self.max_penetration_m = self.max_penetration_m.max(depth);
        }
        self.steps += 1;
        self.own_s += started.elapsed().as_secs_f64();
    }
}

/// Runs the case matrix on `pair` with the trial `config`'s gains and the manifold `sampler`.
pub fn validate_arm(
    pair: &PartPair,
    robot: &RobotModel,
    params: &WorkCellParams,
    config: &TrialConfig,
    sampler: &SamplerConfig,
) -> Result<ArmValidationReport> {
    let base_t_hole = nominal_hole_pose(pair, params);
    let probe = PenetrationProbe::new(&pair.hole, &base_t_hole);
    let limit_m = penetration_limit_m(pair.clearance_m);
    let mut reports = Vec::new();
    for case in cases(pair, &probe, &base_t_hole, config, sampler) {
        reports.push(run_case(&case, pair, robot, params, &probe, limit_m)?);
    }
    let setup = ArmSetup {
        robot: robot.name.clone(),
        controller: params.controller.clone(),
    };
    Ok(Report::new(pair, params.physics.clone(), setup, reports))
}

fn run_case(
    case: &Case,
    pair: &PartPair,
    robot: &RobotModel,
    params: &WorkCellParams,
    probe: &PenetrationProbe,
    limit_m: f64,
) -> Result<ArmCase> {
    let base_t_hole = nominal_hole_pose(pair, params);
    let start = base_t_hole * case.start;
    let mut cell = WorkCell::new(
        pair,
        robot.clone(),
        params,
        Some(base_t_hole),
        &start,
        case.gains.clone(),
        1,
    )?;
    let mut monitor = Monitor {
        probe,
        peg: &pair.peg,
        base_t_hole,
        settle_from_s: case.duration_s - SETTLE_S,
        steps: 0,
        max_penetration_m: 0.0,
        peak_force_n: 0.0,
        peak_torque_nm: 0.0,
        min_z_m: f64::INFINITY,
        settle_sum: Vector3::zeros(),
        settle_n: 0,
        own_s: 0.0,
    };
    let started = Instant::now();
    let (fault, target) = {
        let mut session = Session::new(&mut cell, Some(&mut monitor), Phase::Insert);
        let target = drive(case, &mut session, &base_t_hole, pair.clearance_m)?;
        (session.fault().cloned(), target)
    };
    let physics_s = started.elapsed().as_secs_f64() - monitor.own_s;
    let settled = Settled {
        tip: base_t_hole.inverse() * cell.truth().tcp_pose(),
        min_z_m: monitor.min_z_m,
        force_n: monitor.settle_sum / monitor.settle_n.max(1) as f64,
        target,
    };
    let (outcome_ok, observed) = (case.judge)(&settled);
    let judgement = (outcome_ok && fault.is_none(), observed);
    let penetration = (monitor.max_penetration_m, limit_m);
    let speed = monitor.steps as f64 / physics_s.max(1e-9);
    let verdict = Verdict::new(
        case.name,
        &case.expected,
        judgement,
        penetration,
        speed,
        true,
    );
    Ok(ArmCase {
        verdict: match params.cell.is_ideal() {
            true => verdict,
            false => verdict.soundness_only(fault.is_none()),
        },
        gains: case.gains_name.into(),
        fault,
        peak_force_n: monitor.peak_force_n,
        peak_torque_nm: monitor.peak_torque_nm,
    })
}

/// Drives the case's motion for its duration (or until a fault); returns the last target,
/// `hole_T_tcp`.
fn drive(case: &Case, session: &mut Session, base_t_hole: &Iso, clearance_m: f64) -> Result<Iso> {
    let dt = session.dt_s();
    let steps = (case.duration_s / dt).round() as usize;
    match &case.motion {
        Motion::Path { target, switch } => {
            let mut pending = switch.clone();
            for k in 0..steps {
                let t = k as f64 * dt;
                if let Some((_, gains)) = pending.take_if(|(at, _)| t >= *at) {
                    session.switch_gains(gains)?;
                }
                session.command_pose(base_t_hole * target(t));
                if !session.step() {
                    break;
                }
            }
            Ok(target(steps as f64 * dt))
        }
        Motion::Primitives { motion, twist_rad } => {
            let believed = base_t_hole * yaw(*twist_rad);
            let drive = Drive {
                base_t_hole: believed,
                motion,
                schedule: ScaleSchedule::constant(1.0),
                clearance_m,
                duration_s: case.duration_s,
            };
            let mut noise = PerturbationState::new(motion.perturbation.clone(), 1);
            drive.run(session, &mut noise, |_| ControlFlow::Continue(()));
            Ok(base_t_hole.inverse() * session.measurements().tcp)
        }
    }
}

fn yaw(rad: f64) -> Iso {
    Iso::from_parts(
        Translation3::identity(),
        UnitQuaternion::from_euler_angles(0.0, 0.0, rad),
    )
}

/// `hole_T_tcp` upright at `(x, y, z)`.
fn at(x: f64, y: f64, z: f64) -> Iso {
    Iso::translation(x, y, z)
}

/// The tip at the floor: the judge of the insertion cases.
fn full_depth(depth_m: f64, stop: &'static str) -> Judge {
    Box::new(move |s: &Settled| {
        let z = s.tip.translation.vector.z;
        (
            z <= -depth_m + 0.1e-3,
            format!(
                "tip at z = {:.3} mm (full insertion at {:.3} mm, {})",
                z * 1e3,
                -depth_m * 1e3,
                stop
            ),
        )
    })
}

/// Descends from `z0` at [`DESCENT_M_PER_S`] to [`PRESS_M`] below the floor, turning from
/// `start` to upright over [`UPRIGHT_S`].
fn descend(start: Iso, depth_m: f64) -> Box<dyn Fn(f64) -> Iso> {
    Box::new(move |t: f64| {
        let z0 = start.translation.vector.z;
        let z = (z0 - DESCENT_M_PER_S * t).max(-depth_m - PRESS_M);
        let turn = (t / UPRIGHT_S).min(1.0);
        let rotation = start.rotation.slerp(&UnitQuaternion::identity(), turn);
        Iso::from_parts(Translation3::new(0.0, 0.0, z), rotation)
    })
}

fn cases(
    pair: &PartPair,
    probe: &PenetrationProbe,
    base_t_hole: &Iso,
    config: &TrialConfig,
    sampler: &SamplerConfig,
) -> Vec<Case> {
    let depth = pair.cavity_depth_m;
    let insertion_s = (depth + PRESS_M) / DESCENT_M_PER_S + 1.0;
    let tilted = |deg: f64| {
        let tilt = at(0.0, 0.0, -2e-3)
            * Iso::from_parts(
                Translation3::identity(),
                UnitQuaternion::from_euler_angles(deg.to_radians(), 0.0, 0.0),
            );
        lift_until_free(probe, pair, base_t_hole, tilt)
    };
    let tilted_case = |name: &'static str, deg: f64| {
        let start = tilted(deg);
        Case {
            name,
            gains_name: "align, then insert",
            gains: config.align_gains.clone(),
            expected: format!(
                "starts tilted {deg} deg, turns upright under the alignment gains, reaches full depth under the insertion gains"
            ),
            start,
            motion: Motion::Path {
                target: descend_after(start, depth, UPRIGHT_S),
                switch: Some((UPRIGHT_S, config.insert_gains.clone())),
            },
            duration_s: insertion_s + UPRIGHT_S,
            judge: full_depth(depth, pair.seat.describe()),
        }
    };
    let mut all = vec![
        aligned_insertion((depth, pair.seat.describe()), insertion_s, config),
        lateral_press(pair, config),
        tilted_case("tilted_1deg", 1.0),
        tilted_case("tilted_3deg", 3.0),
        rim_jam(pair, probe, base_t_hole, config),
    ];
    // A through hole has no floor to press.
    if pair.seat != Seat::Through {
        all.push(floor_press(depth, config));
    }
    all.push(probing(config));
    all.push(sampling(sampler));
    all
}

/// Holds `start` for `hold_s` (turning upright), then descends as [`descend`].
fn descend_after(start: Iso, depth_m: f64, hold_s: f64) -> Box<dyn Fn(f64) -> Iso> {
    let down = descend(
        Iso::from_parts(start.translation, UnitQuaternion::identity()),
        depth_m,
    );
    Box::new(move |t: f64| {
        if t < hold_s {
            let turn = (t / UPRIGHT_S).min(1.0);
            let rotation = start.rotation.slerp(&UnitQuaternion::identity(), turn);
            Iso::from_parts(start.translation, rotation)
        } else {
            down(t - hold_s)
        }
    })
}

fn aligned_insertion(
    (depth, stop): (f64, &'static str),
    insertion_s: f64,
    config: &TrialConfig,
) -> Case {
    let start = at(0.0, 0.0, -2e-3);
    Case {
        name: "aligned_insertion",
        gains_name: "insert",
        gains: config.insert_gains.clone(),
        expected: "reaches full depth from 2 mm partial insertion".into(),
        start,
        motion: Motion::Path {
            target: descend(start, depth),
            switch: None,
        },
        duration_s: insertion_s,
        judge: full_depth(depth, stop),
    }
}

fn lateral_press(pair: &PartPair, config: &TrialConfig) -> Case {
    let half_gap = pair.clearance_m / 2.0;
    let offset = 1e-3;
    let k = config.align_gains.stiffness[0];
    Case {
        name: "lateral_press",
        gains_name: "align",
        gains: config.align_gains.clone(),
        expected: format!(
            "pressed 1 mm sideways at 10 mm depth, stays in the hole: tip within c/2 = {:.3} mm of the axis, the wall carrying the spring",
            half_gap * 1e3
        ),
        start: at(0.0, 0.0, -10e-3),
        motion: Motion::Path {
            target: Box::new(move |_| at(offset, 0.0, -10e-3)),
            switch: None,
        },
        duration_s: 0.6,
        judge: Box::new(move |s| {
            let x = s.tip.translation.vector.x;
            (
                x <= half_gap + 0.01e-3 && -s.force_n.x > 0.5 * k * (offset - half_gap),
                format!(
                    "tip x = {:.4} mm, wall force {:.2} N",
                    x * 1e3,
                    -s.force_n.x
                ),
            )
        }),
    }
}

fn rim_jam(
    pair: &PartPair,
    probe: &PenetrationProbe,
    base_t_hole: &Iso,
    config: &TrialConfig,
) -> Case {
    let rim = (1.5e-3f64).max(3.0 * pair.clearance_m);
    Case {
        name: "rim_jam",
        gains_name: "insert",
        gains: config.insert_gains.clone(),
        expected: format!(
            "resting on the rim {:.1} mm off the axis, pushed down to 5 mm below it at 20 mm/s: jams, no entry (tip stays above -0.05 mm)",
            rim * 1e3
        ),
        start: lift_until_free(probe, pair, base_t_hole, at(rim, 0.0, 0.0)),
        motion: Motion::Path {
            target: Box::new(move |t| at(rim, 0.0, (-DESCENT_M_PER_S * t).max(-5e-3))),
            switch: None,
        },
        duration_s: 1.0,
        judge: Box::new(|s| {
            (
                s.min_z_m >= -0.05e-3,
                format!(
                    "lowest tip z = {:.4} mm, final {:.4} mm",
                    s.min_z_m * 1e3,
                    s.tip.translation.vector.z * 1e3
                ),
            )
        }),
    }
}

fn floor_press(depth: f64, config: &TrialConfig) -> Case {
    let gains = config.insert_gains.clone();
    let k = gains.stiffness[2];
    Case {
        name: "floor_press",
        gains_name: "insert",
        expected: format!(
            "pressed 1 mm into the floor: the floor carries the spring, stiffness x offset ({:.2} N), within {} %",
            k * PRESS_M,
            SPRING_AGREEMENT * 100.0
        ),
        gains,
        start: at(0.0, 0.0, -depth + 10e-6),
        motion: Motion::Path {
            target: Box::new(move |_| at(0.0, 0.0, -depth - PRESS_M)),
            switch: None,
        },
        duration_s: 0.8,
        judge: Box::new(move |s| {
            let offset = s.tip.translation.vector.z - s.target.translation.vector.z;
            let expected = k * offset;
            (
                (s.force_n.z - expected).abs() <= SPRING_AGREEMENT * expected,
                format!(
                    "floor force {:.3} N vs stiffness x offset {:.3} N",
                    s.force_n.z, expected
                ),
            )
        }),
    }
}

/// The observation's primitives at full amplitude for 10 s, the believed hole yawed
/// [`PROBE_TWIST_RAD`] so that the oscillation twists the peg into the walls.
fn probing(config: &TrialConfig) -> Case {
    let motion = observation_motion(config);
    Case {
        name: "probing",
        gains_name: "observe",
        gains: config.observe_gains.clone(),
        expected: format!(
            "10 s of the observation's spiral and oscillation at full amplitude, twisted {:.1} deg into the walls: no fault",
            PROBE_TWIST_RAD.to_degrees()
        ),
        start: at(0.0, 0.0, -config.start_depth_m),
        motion: Motion::Primitives {
            motion,
            twist_rad: PROBE_TWIST_RAD,
        },
        duration_s: 10.0,
        judge: completed(),
    }
}

/// One episode of the manifold sampler (its low-stiffness gains and its motion).
fn sampling(sampler: &SamplerConfig) -> Case {
    Case {
        name: "sampling_episode",
        gains_name: "sampler",
        gains: sampler.gains.clone(),
        expected: format!(
            "one {} s episode of the manifold sampler: no fault",
            sampler.episode_s
        ),
        start: at(0.0, 0.0, -sampler.motion.descent.start_depth_m),
        motion: Motion::Primitives {
            motion: sampler.motion.clone(),
            twist_rad: 0.0,
        },
        duration_s: sampler.episode_s,
        judge: completed(),
    }
}

/// The judge of the motion cases: the fault check does the judging; report where it ended.
fn completed() -> Judge {
    Box::new(|s| {
        let p = s.tip.translation.vector;
        (
            true,
            format!(
                "ran to the end; tip at ({:.3}, {:.3}, {:.3}) mm, lowest z {:.3} mm",
                p.x * 1e3,
                p.y * 1e3,
                p.z * 1e3,
                s.min_z_m * 1e3
            ),
        )
    })
}
