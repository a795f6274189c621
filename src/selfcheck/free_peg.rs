//! `pegtwin validate`: the contact solver checked in isolation. A free peg (the peg alone, as a
//! rigid body) is held by a 6-DoF Cartesian impedance at its tip and driven through a fixed
//! matrix of cases; besides the shared [`Verdict`], each case reports the contact force read
//! from the solver against a momentum check (m dv/dt minus the applied forces).

use super::{CaseReport, Judgement, Report, Verdict, penetration_limit_m};
use crate::twin::geometry::{PartPair, Seat};
use crate::twin::physics::penetration::PenetrationProbe;
use crate::twin::physics::{
    PhysicsParams, add_dynamic, add_fixed, contact_wrench, pose64, v32, v64,
};
use crate::twin::workcell::BUILTIN_PEG_MASS_KG;
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use rapier3d::prelude::{ColliderHandle, PhysicsWorld, RigidBodyHandle};
use serde::Serialize;
use std::time::Instant;

/// Mass of the free peg with its holder, kg: a built-in peg's, whatever the pair.
pub const FREE_PEG_MASS_KG: f64 = BUILTIN_PEG_MASS_KG;
/// Largest difference between the solver's contact force and the momentum check, fraction.
pub const FORCE_AGREEMENT: f64 = 0.02;
/// Time over which the orientation target turns upright, seconds.
const ORIENTATION_RAMP_S: f64 = 0.3;
/// Steps at the end of each case over which forces are averaged (the peg is at rest there).
const SETTLE_WINDOW_STEPS: usize = 200;

/// Gains of the free peg's impedance at its tip.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct FreePegGains {
    pub stiffness_n_per_m: f64,
    pub rot_stiffness_nm_per_rad: f64,
    pub damping_ratio: f64,
}

impl Default for FreePegGains {
    fn default() -> Self {
        FreePegGains {
            stiffness_n_per_m: 2000.0,
            rot_stiffness_nm_per_rad: 10.0,
            damping_ratio: 0.7,
        }
    }
}

/// A free peg over a fixed hole at the world origin, under impedance control at the peg tip.
pub struct FreePegRig {
    pub world: PhysicsWorld,
    body: RigidBodyHandle,
    collider: ColliderHandle,
    mass_kg: f64,
    /// Distance from the centre of mass to the farthest point of the peg, metres.
    reach_m: f64,
    /// Smallest principal moment of inertia, kg m^2.
    inertia_min: f64,
    damping_trans: f64,
    damping_rot: f64,
    gains: FreePegGains,
    /// Target pose of the peg frame (tip), world.
    pub target: Isometry3<f64>,
}

/// What one step measured.
pub struct StepSample {
    /// Contact force on the peg read from the solver, N.
    pub readout: Vector3<f64>,
    /// Contact force on the peg from the momentum balance, N.
    pub momentum: Vector3<f64>,
    /// Wall time of the physics step alone, seconds.
    pub step_s: f64,
}

impl FreePegRig {
    pub fn new(
        pair: &PartPair,
        params: &PhysicsParams,
        start: &Isometry3<f64>,
        gains: FreePegGains,
    ) -> Self {
        let mut world = params.new_world();
        add_fixed(
            &mut world,
            &pair.hole,
            &Isometry3::identity(),
            params.friction,
        );
        let (body, collider) = add_dynamic(
            &mut world,
            &pair.peg,
            start,
            FREE_PEG_MASS_KG,
            params.friction,
        );
        let mprops = world.colliders[collider].mass_properties();
        let mass_kg = mprops.mass() as f64;
        let inertia = mprops.principal_inertia();
        let inertia_min = inertia.x.min(inertia.y).min(inertia.z) as f64;
        let zeta = gains.damping_ratio;
        let (lo, hi) = pair.peg.bounds();
        let reach_m = (hi - lo).norm();
        FreePegRig {
            reach_m,
            inertia_min,
            damping_trans: 2.0 * zeta * (gains.stiffness_n_per_m * mass_kg).sqrt(),
            damping_rot: 2.0 * zeta * (gains.rot_stiffness_nm_per_rad * inertia_min).sqrt(),
            world,
            body,
            collider,
            mass_kg,
            gains,
            target: *start,
        }
    }

    /// The fastest mode of the rig's impedance, rad/s: the rotational spring about the peg's
    /// axis of least inertia, sqrt(k / I), or its damping rate c / I where that is faster.
    fn fastest_mode_rad_per_s(&self) -> f64 {
        let k = self.gains.rot_stiffness_nm_per_rad;
        (k / self.inertia_min)
            .sqrt()
            .max(self.damping_rot / self.inertia_min)
    }

    /// Pose of the peg frame (tip), world.
    pub fn tip_pose(&self) -> Isometry3<f64> {
        pose64(self.world.bodies[self.body].position())
    }

    /// Applies the impedance wrench, steps the physics once, and measures the contact force.
    pub fn step(&mut self) -> StepSample {
        let dt = self.world.integration_parameters.dt as f64;
        let rb = &self.world.bodies[self.body];
        let pose = pose64(rb.position());
        let com = v64(rb.center_of_mass());
        let v_com = v64(rb.linvel());
        let omega = v64(rb.angvel());
        let tip = pose.translation.vector;
        let v_tip = v_com + omega.cross(&(tip - com));
        let force = (self.target.translation.vector - tip) * self.gains.stiffness_n_per_m
            - v_tip * self.damping_trans;
        let rot_err = (self.target.rotation * pose.rotation.inverse()).scaled_axis();
        let torque = rot_err * self.gains.rot_stiffness_nm_per_rad - omega * self.damping_rot
            + (tip - com).cross(&force);
        let gravity_comp = Vector3::new(0.0, 0.0, 9.81 * self.mass_kg);
        let rb = &mut self.world.bodies[self.body];
        rb.reset_forces(true);
        rb.reset_torques(true);
        rb.add_force(v32(&(force + gravity_comp)), true);
        rb.add_torque(v32(&torque), true);
        let speed = crate::twin::physics::max_point_speed(&self.world, self.body, self.reach_m);
        let floor = crate::twin::physics::MIN_PREDICTION_M;
        crate::twin::physics::set_prediction_for_speed(&mut self.world, speed, floor);
        let started = Instant::now();
        self.world.step();
        let step_s = started.elapsed().as_secs_f64();
        let rb = &self.world.bodies[self.body];
        let v_after = v64(rb.linvel());
        let com_after = v64(rb.center_of_mass());
        StepSample {
            readout: contact_wrench(&self.world, self.collider, com_after).force,
            momentum: (v_after - v_com) * (self.mass_kg / dt) - force,
            step_s,
        }
    }
}

/// The result of one free-peg case.
#[derive(Clone, Debug, Serialize)]
pub struct FreePegCase {
    #[serde(flatten)]
    pub verdict: Verdict,
    /// Contact force from the solver, averaged over the final settled window, N.
    pub force_readout_n: [f64; 3],
    /// Contact force from the momentum balance over the same window, N.
    pub force_momentum_n: [f64; 3],
    /// |readout - momentum| / |momentum|, percent.
    pub force_error_pct: f64,
    pub force_ok: bool,
}

impl CaseReport for FreePegCase {
    fn verdict(&self) -> &Verdict {
        &self.verdict
    }
}

/// What the free-peg rig holds fixed: its impedance.
#[derive(Clone, Debug, Serialize)]
pub struct FreePegSetup {
    pub gains: FreePegGains,
}

/// The whole free-peg validation of a pair.
pub type ValidationReport = Report<FreePegSetup, FreePegCase>;

/// Judges a run from the final tip pose, the lowest tip z seen (m) and the settled contact force
/// (N): whether the outcome is as expected, and what was observed.
type Judge = Box<dyn Fn(&Isometry3<f64>, f64, &Vector3<f64>) -> Judgement>;

/// How a case drives the peg and judges it.
struct Case {
    name: &'static str,
    expected: String,
    start: Isometry3<f64>,
    /// Target tip position at time t (seconds). The orientation target turns from the start
    /// orientation to upright over `ORIENTATION_RAMP_S`, as a robot's filtered set-point would.
    target: Box<dyn Fn(f64) -> Vector3<f64>>,
    duration_s: f64,
    judge: Judge,
}

fn upright(x: f64, y: f64, z: f64) -> Isometry3<f64> {
    Isometry3::from_parts(Translation3::new(x, y, z), UnitQuaternion::identity())
}

/// Steps of [`lift_until_free`], metres, and how many it takes at most (0.1 m: a user's parts
/// decide whether the peg ever comes free, so the search is bounded).
const LIFT_STEP_M: f64 = 10e-6;
const LIFT_STEPS: usize = 10_000;

/// Raises a start pose `hole_T_peg` in 10 micrometre steps along the hole's axis until the peg
/// does not penetrate the hole posed at `base_t_hole` (the pose `probe` was made with), by at
/// most 0.1 m: a peg still in the hole there starts where it is, and its case fails on the
/// penetration it starts with.
pub fn lift_until_free(
    probe: &PenetrationProbe,
    pair: &PartPair,
    base_t_hole: &Isometry3<f64>,
    pose: Isometry3<f64>,
) -> Isometry3<f64> {
    let mut p = pose;
    for _ in 0..LIFT_STEPS {
        let inside = probe.max_penetration(&pair.peg, &(base_t_hole * p)) > 0.0;
        if !inside {
            break;
        }
        p.translation.vector.z += LIFT_STEP_M;
    }
    p
}

/// How far the peg's tip reaches over the block's flat top in the rim jam case, metres.
const RIM_LEDGE_M: f64 = 0.5e-3;
/// Steps of the rim jam's offset search, metres, and how far it looks.
const RIM_SEARCH_STEP_M: f64 = 0.1e-3;
const RIM_SEARCH_STEPS: usize = 200;

/// The rim jam's offset from the hole's axis along x, metres, and whether it had to move past an
/// entry chamfer: the least of max(1.5 mm, 3 c) and 0.1 mm steps beyond it at which the peg's tip,
/// a micrometre under the mouth plane, still meets the block `RIM_LEDGE_M` nearer the axis. A
/// peg set down on a chamfer slides in, as a chamfer is made to make it; the case asks whether
/// a peg on the flat rim stays out. The built-ins' 0.3 mm chamfers never move it.
fn rim_offset(probe: &PenetrationProbe, pair: &PartPair) -> (f64, bool) {
    let base = (1.5e-3f64).max(3.0 * pair.clearance_m);
    let rests = |x: f64| {
        let pose = upright(x - RIM_LEDGE_M, 0.0, -1e-6);
        probe.max_penetration(&pair.peg, &pose) > 0.0
    };
    (0..RIM_SEARCH_STEPS)
        .map(|k| base + k as f64 * RIM_SEARCH_STEP_M)
        .find(|&x| rests(x))
        .map_or((base, false), |x| (x, x > base))
}

/// The cases for `pair` (a through hole has no floor to press: its floor press is left out).
/// How far the insertion cases push below the floor, and the floor press presses into it, m.
const PRESS_M: f64 = 1e-3;
/// The descent speed of the insertion and rim cases, m/s.
const DESCENT_M_PER_S: f64 = 20e-3;
/// How far past the wall the lateral press targets the tip, m.
const WALL_OFFSET_M: f64 = 1e-3;

/// The free-peg cases in their report order (the floor press only where the peg seats on a
/// floor).
fn cases(pair: &PartPair, probe: &PenetrationProbe, gains: &FreePegGains) -> Vec<Case> {
    let k = gains.stiffness_n_per_m;
    let mut cases = vec![
        insertion_case(
            pair,
            "aligned_insertion",
            "reaches full depth from 2 mm partial insertion".into(),
            upright(0.0, 0.0, -2e-3),
        ),
        lateral_press_case(pair, k),
    ];
    for (name, deg) in [("tilted_1deg", 1.0f64), ("tilted_3deg", 3.0)] {
        let tilt = Isometry3::from_parts(
            Translation3::new(0.0, 0.0, -2e-3),
            UnitQuaternion::from_euler_angles(deg.to_radians(), 0.0, 0.0),
        );
        cases.push(insertion_case(
            pair,
            name,
            format!("starts tilted {deg} deg, aligns and reaches full depth"),
            lift_until_free(probe, pair, &Isometry3::identity(), tilt),
        ));
    }
    cases.push(rim_jam_case(pair, probe));
    if pair.seat != Seat::Through {
        cases.push(floor_press_case(pair, k));
    }
    cases
}

/// A descent at 20 mm/s from `start` to 1 mm below the floor, judged by the tip reaching full
/// depth.
fn insertion_case(
    pair: &PartPair,
    name: &'static str,
    expected: String,
    start: Isometry3<f64>,
) -> Case {
    let depth = pair.cavity_depth_m;
    let stop = pair.seat.describe();
    let z0 = -2e-3;
    Case {
        name,
        expected,
        start,
        target: Box::new(move |t: f64| {
            Vector3::new(0.0, 0.0, (z0 - DESCENT_M_PER_S * t).max(-depth - PRESS_M))
        }),
        duration_s: (depth + PRESS_M) / DESCENT_M_PER_S + 0.5,
        judge: Box::new(move |tip, _, _| {
            let z = tip.translation.vector.z;
            (
                z <= -depth + 0.1e-3,
                format!(
                    "tip at z = {:.3} mm (full insertion at {:.3} mm, {})",
                    z * 1e3,
                    -depth * 1e3,
                    stop
                ),
            )
        }),
    }
}

/// Pressed 1 mm sideways at 10 mm depth: the wall holds the tip within c/2 of the axis and
/// carries at least half the impedance's force.
fn lateral_press_case(pair: &PartPair, k: f64) -> Case {
    let half_gap = pair.clearance_m / 2.0;
    Case {
        name: "lateral_press",
        expected: format!(
            "pressed 1 mm sideways at 10 mm depth, stays in the hole: tip within c/2 = {:.3} mm of the axis",
            half_gap * 1e3
        ),
        start: upright(0.0, 0.0, -10e-3),
        target: Box::new(move |_| Vector3::new(WALL_OFFSET_M, 0.0, -10e-3)),
        duration_s: 0.6,
        judge: Box::new(move |tip, _, f| {
            let x = tip.translation.vector.x;
            (
                x <= half_gap + 0.01e-3 && f.x < -0.5 * k * (WALL_OFFSET_M - half_gap),
                format!("tip x = {:.4} mm, wall force {:.2} N", x * 1e3, -f.x),
            )
        }),
    }
}

/// Resting on the rim off the axis (past a wide chamfer), pushed down: it must jam, not enter.
fn rim_jam_case(pair: &PartPair, probe: &PenetrationProbe) -> Case {
    let (rim_offset, past_chamfer) = rim_offset(probe, pair);
    let rim_where = if past_chamfer {
        " (past the mouth's chamfer, so that it rests on the flat top)"
    } else {
        ""
    };
    Case {
        name: "rim_jam",
        expected: format!(
            "resting on the rim {:.1} mm off the axis{rim_where}, pushed down to 5 mm below it at 20 mm/s: jams, no entry (tip stays above -0.05 mm)",
            rim_offset * 1e3
        ),
        start: lift_until_free(
            probe,
            pair,
            &Isometry3::identity(),
            upright(rim_offset, 0.0, 0.0),
        ),
        target: Box::new(move |t| Vector3::new(rim_offset, 0.0, (-DESCENT_M_PER_S * t).max(-5e-3))),
        duration_s: 1.0,
        judge: Box::new(|tip, min_z, _| {
            (
                min_z >= -0.05e-3,
                format!(
                    "lowest tip z = {:.4} mm, final {:.4} mm",
                    min_z * 1e3,
                    tip.translation.vector.z * 1e3
                ),
            )
        }),
    }
}

/// Pressed 1 mm into the floor: the floor carries stiffness x offset within
/// [`FORCE_AGREEMENT`].
fn floor_press_case(pair: &PartPair, k: f64) -> Case {
    let depth = pair.cavity_depth_m;
    Case {
        name: "floor_press",
        expected: format!(
            "pressed 1 mm into the floor: force = stiffness x offset ({:.2} N)",
            k * PRESS_M
        ),
        start: upright(0.0, 0.0, -depth + 10e-6),
        target: Box::new(move |_| Vector3::new(0.0, 0.0, -depth - PRESS_M)),
        duration_s: 0.6,
        judge: Box::new(move |tip, _, f| {
            let offset = tip.translation.vector.z - (-depth - PRESS_M);
            let expected = k * offset;
            (
                (f.z - expected).abs() <= FORCE_AGREEMENT * expected,
                format!(
                    "floor force {:.4} N vs stiffness x offset {:.4} N",
                    f.z, expected
                ),
            )
        }),
    }
}

fn run_case(
    case: &Case,
    pair: &PartPair,
    params: &PhysicsParams,
    gains: FreePegGains,
    probe: &PenetrationProbe,
    limit_m: f64,
) -> FreePegCase {
    let mut rig = FreePegRig::new(pair, params, &case.start, gains);
    let steps = (case.duration_s / params.dt_s).round() as usize;
    let mut max_pen: f64 = 0.0;
    let mut min_z = f64::INFINITY;
    let mut step_time = 0.0;
    let (mut readout, mut momentum) = (Vector3::zeros(), Vector3::zeros());
    for i in 0..steps {
        let t = i as f64 * params.dt_s;
        let target = (case.target)(t);
        let ramp = (t / ORIENTATION_RAMP_S).min(1.0);
        let upright = UnitQuaternion::identity();
        let rotation = case.start.rotation.slerp(&upright, ramp);
        rig.target = Isometry3::from_parts(Translation3::from(target), rotation);
        let s = rig.step();
        step_time += s.step_s;
        let tip = rig.tip_pose();
        min_z = min_z.min(tip.translation.vector.z);
        max_pen = max_pen.max(probe.max_penetration(&pair.peg, &tip));
        if i + SETTLE_WINDOW_STEPS >= steps {
            readout += s.readout;
            momentum += s.momentum;
        }
    }
    let n = SETTLE_WINDOW_STEPS.min(steps) as f64;
    let (readout, momentum) = (readout / n, momentum / n);
    let tip = rig.tip_pose();
    let judgement = (case.judge)(&tip, min_z, &readout);
    let force_error = (readout - momentum).norm() / momentum.norm().max(1e-9);
    let force_ok = force_error <= FORCE_AGREEMENT;
    let speed = steps as f64 / step_time;
    FreePegCase {
        verdict: Verdict::new(
            case.name,
            &case.expected,
            judgement,
            (max_pen, limit_m),
            speed,
            force_ok,
        ),
        force_readout_n: readout.into(),
        force_momentum_n: momentum.into(),
        force_error_pct: force_error * 100.0,
        force_ok,
    }
}

/// The largest product of the rig's fastest mode and its step: the impedance is an explicit
/// force held over a step, and beyond about 1.4 (1 / damping ratio) its damping over-corrects
/// and the peg spins up. The built-ins' pegs stand at 0.57-0.68 at 1 ms.
const MAX_MODE_TIMES_STEP: f64 = 1.0;

/// The physics the rig runs at: `params`, with the step divided by the least whole number that
/// brings the rig's fastest mode within `MAX_MODE_TIMES_STEP` (a bare slender pin, whose yaw
/// inertia is small: a 10 mm square pin at 1 ms stands at 2.0).
fn rig_params(pair: &PartPair, params: &PhysicsParams, gains: FreePegGains) -> PhysicsParams {
    let rig = FreePegRig::new(pair, params, &Isometry3::identity(), gains);
    let split = (rig.fastest_mode_rad_per_s() * params.dt_s / MAX_MODE_TIMES_STEP).ceil();
    PhysicsParams {
        dt_s: params.dt_s / split.max(1.0),
        ..params.clone()
    }
}

/// Runs the whole matrix on a pair (at [`rig_params`]).
pub fn validate(pair: &PartPair, params: &PhysicsParams, gains: FreePegGains) -> ValidationReport {
    let probe = PenetrationProbe::new(&pair.hole, &Isometry3::identity());
    let limit_m = penetration_limit_m(pair.clearance_m);
    let params = &rig_params(pair, params, gains);
    let reports: Vec<FreePegCase> = cases(pair, &probe, &gains)
        .iter()
        .map(|c| run_case(c, pair, params, gains, &probe, limit_m))
        .collect();
    Report::new(pair, params.clone(), FreePegSetup { gains }, reports)
}
