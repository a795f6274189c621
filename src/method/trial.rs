//! One online trial (paper IV-C, IV-D, IV-E, V-A): a hole whose true pose is the nominal pose
//! plus a random offset; the peg starts partially inserted in it (as in the paper); the robot
//! observes contacts for `t_obs` seconds with the sampling primitives around where it stands,
//! registers them against the reference manifold (Algorithm 1), then retracts slightly, aligns
//! in-plane at constant depth under high stiffness and inserts compliantly. Or the paper's
//! baseline, `direct`: observe, then insert along the peg's own z with no estimate.
//!
//! The method sees only what the real cell sees: encoder readings and the estimated wrench. The
//! true hole pose sets up the experiment (the fixture and the initial partial insertion, as the
//! experimenters placed them) and scores it; it never reaches the method.

use crate::error::{Error, Result};
use crate::method::manifold::Manifold;
use crate::method::manifold::build::SamplerConfig;
use crate::method::primitives::{Descent, PerturbationState};
use crate::method::register::{RegistrationConfig, register};
use crate::pose::Pose6;
use crate::twin::cell::{Cell, CellParams, SimFault, nominal_hole_pose, tcp_in_hole};
use crate::twin::control::ImpedanceGains;
use crate::twin::geometry::PartPair;
use crate::twin::robot::{Iso, RobotModel};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};
use std::time::Instant;

/// Time the insertion target rests at its end before the trial is scored, s.
const INSERT_SETTLE_S: f64 = 0.5;
/// Sampling interval of the insertion force profile kept in a result, s.
pub const FZ_PROFILE_DT_S: f64 = 0.05;

/// How the trial inserts.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "snake_case")]
pub enum Method {
    /// Estimate the hole pose from the contact manifold, then insert along the estimate.
    Manifold,
    /// The paper's baseline: observe, then insert along the peg's z with no estimate.
    Direct,
}

/// How a trial starts.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "snake_case")]
pub enum Start {
    /// Partially inserted in the true hole (the paper's set-up).
    Partial,
    /// Above the nominal hole: approach, then a spiral search pressing on the surface until the
    /// peg drops in, then down to the partial insertion.
    Above,
}

/// Height above the highest possible mouth at which a search starts, m.
const SEARCH_CLEARANCE_M: f64 = 5e-3;

/// Everything a trial does.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TrialConfig {
    pub method: Method,
    pub start: Start,
    /// Spiral search from above: time limit, s.
    pub search_limit_s: f64,
    /// Observation time, s.
    pub t_obs_s: f64,
    /// Half-ranges of the uniform hole offset: x, y, z (m), roll, pitch, yaw (rad).
    pub offset_range: [f64; 6],
    /// Depth of the initial partial insertion, m.
    pub start_depth_m: f64,
    /// Observation: phase 1 amplitude scale until `observe_depth_m`, then phase 2 scale.
    pub phase1_scale: f64,
    pub phase2_scale: f64,
    pub observe_depth_m: f64,
    /// Share of `t_obs` spent descending to `observe_depth_m` (phase 1).
    pub phase1_fraction: f64,
    /// Gains of the observation motions: compliant, and softest in rotation, so that the
    /// orientation error of the nominal pose presses the peg only lightly against the walls.
    pub observe_gains: ImpedanceGains,
    /// Observations kept after temporal downsampling.
    pub observations: usize,
    /// Small retract before alignment, m.
    pub retract_m: f64,
    /// High-stiffness gains of the in-plane alignment.
    pub align_gains: ImpedanceGains,
    /// Duration of the alignment move, s.
    pub align_s: f64,
    /// Compliant gains of the insertion.
    pub insert_gains: ImpedanceGains,
    /// Insertion speed of the target, m/s.
    pub insert_speed_m_per_s: f64,
    /// Time limit of the insertion, s.
    pub insert_limit_s: f64,
    /// The insertion target goes this far past the believed floor, m (the compliance turns it into
    /// the seating force; it also absorbs the estimate's error in z).
    pub insert_overshoot_m: f64,
    /// The insertion target stops advancing once the estimated |Fz| exceeds this, N (a force
    /// break condition, as Sunrise's `ForceCondition`): the peg has jammed.
    pub insert_stop_force_n: f64,
    /// Success when the final tip depth is within this of the floor, m (paper: 2 mm).
    pub success_eps_m: f64,
    pub registration: RegistrationConfig,
}

impl Default for TrialConfig {
    fn default() -> Self {
        let d = 5e-3;
        let a = 5f64.to_radians();
        TrialConfig {
            method: Method::Manifold,
            start: Start::Partial,
            search_limit_s: 30.0,
            t_obs_s: 10.0,
            offset_range: [d, d, d, a, a, a],
            start_depth_m: 3e-3,
            phase1_scale: 1.0,
            phase2_scale: 0.8,
            observe_depth_m: 18e-3,
            phase1_fraction: 0.6,
            observe_gains: ImpedanceGains {
                stiffness: [1000.0, 1000.0, 1500.0, 5.0, 5.0, 5.0],
                additional_force: [0.0, 0.0, -5.0, 0.0, 0.0, 0.0],
                ..Default::default()
            },
            observations: 1000,
            retract_m: 1e-3,
            align_gains: ImpedanceGains::uniform(4000.0, 250.0, 0.7),
            align_s: 1.0,
            insert_gains: ImpedanceGains {
                stiffness: [1500.0, 1500.0, 2000.0, 50.0, 50.0, 50.0],
                ..Default::default()
            },
            insert_speed_m_per_s: 15e-3,
            insert_limit_s: 6.0,
            insert_overshoot_m: 5e-3,
            insert_stop_force_n: 40.0,
            success_eps_m: 2e-3,
            registration: RegistrationConfig::default(),
        }
    }
}

impl TrialConfig {
    /// Rejects values a trial cannot run with, naming the field.
    pub fn validate(&self) -> Result<()> {
        if !crate::twin::control::is_positive(self.t_obs_s) {
            return Err(Error::Input(format!(
                "t_obs {} s: expected a positive time",
                self.t_obs_s
            )));
        }
        if self
            .offset_range
            .iter()
            .any(|v| !(v.is_finite() && *v >= 0.0))
        {
            return Err(Error::Input(format!(
                "offset range {:?}: expected finite half-ranges >= 0",
                self.offset_range
            )));
        }
        if !(self.insert_overshoot_m >= 0.0 && self.insert_overshoot_m <= 0.05) {
            return Err(Error::Input(format!(
                "insert_overshoot_m {} m: expected 0 to 0.05 m",
                self.insert_overshoot_m
            )));
        }
        if !crate::twin::control::is_positive(self.insert_stop_force_n) {
            return Err(Error::Input(format!(
                "insert_stop_force_n {} N: expected a positive force",
                self.insert_stop_force_n
            )));
        }
        if !(self.phase1_fraction > 0.0 && self.phase1_fraction <= 1.0) {
            return Err(Error::Input(format!(
                "phase1_fraction {}: expected a share in (0, 1]",
                self.phase1_fraction
            )));
        }
        self.observe_gains.validate()?;
        self.align_gains.validate()?;
        self.insert_gains.validate()?;
        self.registration.check()
    }
}

/// Per-axis errors of the estimate, mm and deg (estimate against truth, in the true hole frame).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct AxisErrors {
    pub x_mm: f64,
    pub y_mm: f64,
    pub z_mm: f64,
    pub roll_deg: f64,
    pub pitch_deg: f64,
    pub yaw_deg: f64,
}

/// Simulated time per phase, s (rounded to the microsecond).
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub struct PhaseTimes {
    pub search_s: f64,
    pub observe_s: f64,
    /// Wall time of the registration (not part of the deterministic JSON result).
    #[serde(skip)]
    pub register_wall_s: f64,
    pub retract_s: f64,
    pub align_s: f64,
    pub insert_s: f64,
}

/// The outcome of a trial.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct TrialResult {
    pub seed: u64,
    pub geometry: String,
    pub clearance_mm: f64,
    pub method: Method,
    pub start: Start,
    pub t_obs_s: f64,
    /// The true hole offset from nominal, mm and deg.
    pub offset: [f64; 6],
    /// `success`, `failure` or `sim_fault`.
    pub outcome: String,
    /// Why the trial stopped before inserting, if it did.
    pub stopped: Option<String>,
    pub success: bool,
    pub fault: Option<SimFault>,
    /// Estimated `base_T_hole` (m, rad), manifold method only.
    pub estimate: Option<[f64; 6]>,
    pub errors: Option<AxisErrors>,
    /// Final tip depth below the true mouth, mm (none when the trial stopped before inserting).
    pub final_depth_mm: Option<f64>,
    pub contact_observations: usize,
    pub observations_used: usize,
    /// Force along the peg axis during insertion (estimated), N: peak and mean of |Fz|.
    pub peak_fz_n: f64,
    pub mean_fz_n: f64,
    /// |Fz| (estimated) during the insertion every `FZ_PROFILE_DT_S`, N (0.01 N resolution).
    pub insert_fz_n: Vec<f64>,
    pub times: PhaseTimes,
    /// Wall time of the whole trial, s (not part of the deterministic result).
    #[serde(skip)]
    pub wall_s: f64,
}

/// One sample of the time series (`--trace`).
#[derive(Clone, Debug, Serialize)]
pub struct TraceRow {
    pub time_s: f64,
    pub phase: &'static str,
    /// Measured TCP pose, base frame, m and rad.
    pub tcp: [f64; 6],
    pub est_wrench: [f64; 6],
    pub true_wrench: [f64; 6],
    pub contact: bool,
}

/// Checks that a reference manifold was made for this pair: same geometry, same clearance.
pub fn check_manifold(
    manifold: &Manifold,
    pair: &PartPair,
    source: &std::path::Path,
) -> Result<()> {
    let same_clearance = manifold
        .meta
        .clearance_m
        .is_some_and(|c| (c - pair.clearance_m).abs() < 1e-9);
    if manifold.meta.geometry != pair.name || !same_clearance {
        return Err(Error::file(
            source,
            format!(
                "this manifold was made for geometry '{}' at {} mm clearance; the trial asks for '{}' at {} mm",
                manifold.meta.geometry,
                manifold
                    .meta
                    .clearance_m
                    .map_or("unknown".into(), |c| format!("{}", c * 1e3)),
                pair.name,
                pair.clearance_m * 1e3
            ),
        ));
    }
    Ok(())
}

/// The trace as CSV (m, rad, N, N m; base frame), header first.
pub fn trace_csv(rows: &[TraceRow]) -> Vec<u8> {
    let mut w = csv::Writer::from_writer(Vec::new());
    let mut header = vec!["time_s".to_string(), "phase".into()];
    header.extend(["x", "y", "z", "roll", "pitch", "yaw"].map(String::from));
    for prefix in ["est", "true"] {
        header.extend(["fx", "fy", "fz", "tx", "ty", "tz"].map(|c| format!("{prefix}_{c}")));
    }
    header.push("contact".into());
    w.write_record(&header).expect("in-memory CSV");
    for r in rows {
        let mut rec = vec![format!("{:.3}", r.time_s), r.phase.to_string()];
        rec.extend(
            r.tcp
                .iter()
                .chain(&r.est_wrench)
                .chain(&r.true_wrench)
                .map(|v| format!("{v:e}")),
        );
        rec.push(u8::from(r.contact).to_string());
        w.write_record(&rec).expect("in-memory CSV");
    }
    w.into_inner().expect("in-memory CSV")
}

/// The true hole offset of a trial, drawn from its seed: `[x, y, z, roll, pitch, yaw]` (m, rad).
pub fn draw_offset(seed: u64, range: &[f64; 6]) -> Pose6 {
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x6f66_6673_6574);
    Pose6(std::array::from_fn(|i| {
        if range[i] > 0.0 {
            rng.random_range(-range[i]..=range[i])
        } else {
            0.0
        }
    }))
}

/// Runs a trial. `manifold` is needed by the manifold method (and checked against the pair).
pub fn run_trial(
    pair: &PartPair,
    robot: &RobotModel,
    params: &CellParams,
    config: &TrialConfig,
    manifold: Option<&Manifold>,
    seed: u64,
    trace: Option<&mut Vec<TraceRow>>,
) -> Result<TrialResult> {
    config.validate()?;
    let started = Instant::now();
    let nominal = nominal_hole_pose(pair, params);
    let offset = draw_offset(seed, &config.offset_range);
    let truth = nominal * offset.to_iso();
    let sampler = SamplerConfig::default();
    let start = match config.start {
        // The paper's set-up: the peg partially inserted in the true hole (the robot is then
        // commanded to the partial insertion it believes in, below).
        Start::Partial => tcp_in_hole(&truth, config.start_depth_m),
        // Above the nominal mouth, clear of the highest hole the offsets allow.
        Start::Above => tcp_in_hole(&nominal, -(config.offset_range[2] + SEARCH_CLEARANCE_M)),
    };
    let mut cell = Cell::new(
        pair,
        robot.clone(),
        params,
        Some(truth),
        &start,
        config.observe_gains.clone(),
        seed,
    )?;
    if config.start == Start::Partial {
        // Its compliance takes up the difference between the believed and the true hole.
        cell.controller
            .set_cartesian_target(tcp_in_hole(&nominal, config.start_depth_m));
    }
    let mut run = Run {
        cell: &mut cell,
        trace,
        fault: None,
        phase: "search",
    };
    let believed = match config.start {
        Start::Partial => Some(nominal),
        Start::Above => search(&mut run, &nominal, config, pair.clearance_m),
    };
    let Some(believed) = believed else {
        let why = match run.fault {
            Some(_) => "the physics faulted during the search",
            None => "the search found no hole within its time limit",
        };
        return Ok(stopped_result(
            pair,
            config,
            seed,
            &offset,
            run.fault.clone(),
            started,
            Some(why),
        ));
    };
    run.phase = "observe";
    let search_end_s = run.cell.time_s();

    // Observation (IV-C) in the hole frame the robot believes in: phase 1 wide amplitudes while
    // descending to the target depth, phase 2 smaller ones there.
    let mut motion = sampler.motion.clone();
    // The sweep must reach past the hole wherever it really is: widen the amplitudes by the
    // uncertainty of the nominal pose.
    let r = &config.offset_range;
    motion.schedule.lateral_overtravel_m += r[0].max(r[1]);
    motion.schedule.angular_overtravel_rad += r[3].max(r[4]);
    motion.descent = Descent {
        start_depth_m: config.start_depth_m,
        end_depth_m: config.observe_depth_m,
        speed_m_per_s: (config.observe_depth_m - config.start_depth_m).max(0.0)
            / (config.phase1_fraction * config.t_obs_s),
    };
    let mut noise = PerturbationState::new(motion.perturbation.clone(), seed.wrapping_add(1));
    let dt = params.physics.dt_s;
    let mut contacts: Vec<Pose6> = Vec::new();
    let obs_steps = (config.t_obs_s / dt).round() as usize;
    for k in 0..obs_steps {
        let t = k as f64 * dt;
        motion.scale = if t < motion.descent.duration_s() {
            config.phase1_scale
        } else {
            config.phase2_scale
        };
        let n = noise.step(dt);
        run.cell
            .controller
            .set_cartesian_target(believed * motion.target(t, pair.clearance_m, &n).to_iso());
        if !run.step() {
            break;
        }
        if run.cell.sensors.contact {
            contacts.push(Pose6::from_iso(&run.cell.measured_tcp_pose()));
        }
    }
    let mut times = PhaseTimes {
        search_s: search_end_s,
        observe_s: run.cell.time_s() - search_end_s,
        ..Default::default()
    };
    let contact_observations = contacts.len();
    let observations = temporal_downsample(&contacts, config.observations);

    // Registration (IV-D) or none (direct).
    let mut estimate = None;
    if run.fault.is_none() && config.method == Method::Manifold {
        let manifold = manifold
            .ok_or_else(|| Error::Input("the manifold method needs a reference manifold".into()))?;
        if observations.len() > config.registration.normal_k {
            let t0 = Instant::now();
            let reg = register(
                manifold,
                &observations,
                &Pose6::from_iso(&believed),
                &config.registration,
            )?;
            times.register_wall_s = t0.elapsed().as_secs_f64();
            estimate = Some(reg.estimate);
        }
    }

    // Insertion (IV-E).
    let mut fz = Vec::new();
    if run.fault.is_none() {
        let here = run.cell.measured_tcp_pose();
        let t0 = run.cell.time_s();
        // A small retract along the peg's own axis.
        run.phase = "retract";
        run.move_linear(
            &here,
            &(here * Iso::translation(0.0, 0.0, config.retract_m)),
            0.3,
        );
        times.retract_s = run.cell.time_s() - t0;
        // The frame the insertion runs along, at the present depth, and that depth.
        let (axis_frame, depth) = match &estimate {
            Some(e) => {
                // In-plane alignment at constant depth under high stiffness.
                let hole_est = e.to_iso();
                let now = run.cell.measured_tcp_pose();
                let depth = -(hole_est.inverse() * now).translation.z;
                let aligned = tcp_in_hole(&hole_est, depth);
                run.phase = "align";
                run.switch_gains(config.align_gains.clone());
                let t1 = run.cell.time_s();
                run.move_linear(&now, &aligned, config.align_s);
                run.hold(&aligned, 0.3);
                times.align_s = run.cell.time_s() - t1;
                (aligned, depth)
            }
            // Direct insertion, or no estimate: along the commanded peg axis (the believed hole's z)
            // from the present depth.
            None => {
                let now = run.cell.measured_tcp_pose();
                let depth = -(believed.inverse() * now).translation.z;
                (tcp_in_hole(&believed, depth), depth)
            }
        };
        // Compliant insertion along the frame's z down past the floor, within the time limit.
        run.phase = "insert";
        run.switch_gains(config.insert_gains.clone());
        // Down to the floor of the hole the robot believes in, and `insert_overshoot_m` past it
        // (the estimate's z is its weakest axis, paper V-B); without an estimate, past it also by
        // the z uncertainty of the nominal hole.
        let uncertainty = if estimate.is_some() {
            0.0
        } else {
            config.offset_range[2]
        };
        let travel =
            (pair.cavity_depth_m - depth + config.insert_overshoot_m + uncertainty).max(0.0);
        let t2 = run.cell.time_s();
        // Until the target has travelled its way or the force says stop, then settled for half
        // a second; or the time limit.
        let limit = (config.insert_limit_s / dt).round() as usize;
        let settle = (INSERT_SETTLE_S / dt).round() as usize;
        let mut s = 0.0;
        let mut held_since = None;
        for k in 0..limit {
            if held_since.is_none() {
                s = (k as f64 * dt * config.insert_speed_m_per_s).min(travel);
            }
            run.cell
                .controller
                .set_cartesian_target(axis_frame * Iso::translation(0.0, 0.0, -s));
            if !run.step() {
                break;
            }
            let w = run.cell.sensors.wrench;
            let z = run.cell.measured_tcp_pose().rotation * nalgebra::Vector3::z();
            let f = (w[0] * z.x + w[1] * z.y + w[2] * z.z).abs();
            fz.push(f);
            if held_since.is_none() && (f > config.insert_stop_force_n || s >= travel) {
                held_since = Some(k);
            }
            if held_since.is_some_and(|h| k >= h + settle) {
                break;
            }
        }
        times.insert_s = run.cell.time_s() - t2;
    }
    let fault = run.fault.clone();
    for t in [
        &mut times.observe_s,
        &mut times.retract_s,
        &mut times.align_s,
        &mut times.insert_s,
    ] {
        *t = (*t * 1e6).round() / 1e6;
    }
    let tip = truth.inverse() * cell.tcp_pose();
    let final_depth = -tip.translation.z;
    let success =
        fault.is_none() && (final_depth - pair.cavity_depth_m).abs() <= config.success_eps_m;
    let errors = estimate.map(|e| axis_errors(&truth, &e.to_iso()));
    let base = stopped_result(pair, config, seed, &offset, fault.clone(), started, None);
    Ok(TrialResult {
        outcome: if fault.is_some() {
            "sim_fault"
        } else if success {
            "success"
        } else {
            "failure"
        }
        .into(),
        success,
        estimate: estimate.map(|e| e.0),
        errors,
        final_depth_mm: Some(final_depth * 1e3),
        contact_observations,
        observations_used: observations.len(),
        peak_fz_n: fz.iter().copied().fold(0.0, f64::max),
        mean_fz_n: if fz.is_empty() {
            0.0
        } else {
            fz.iter().sum::<f64>() / fz.len() as f64
        },
        insert_fz_n: fz_profile(&fz, dt),
        times,
        wall_s: started.elapsed().as_secs_f64(),
        ..base
    })
}

/// Every `FZ_PROFILE_DT_S` of a per-step |Fz| series, rounded to 0.01 N.
fn fz_profile(fz: &[f64], dt: f64) -> Vec<f64> {
    let stride = ((FZ_PROFILE_DT_S / dt).round() as usize).max(1);
    fz.iter()
        .step_by(stride)
        .map(|f| (f * 100.0).round() / 100.0)
        .collect()
}

fn to_mm_deg(p: &Pose6) -> [f64; 6] {
    std::array::from_fn(|i| {
        if i < 3 {
            p.0[i] * 1e3
        } else {
            p.0[i].to_degrees()
        }
    })
}

/// Spiral search from above (the classic peg-in-hole search): descend along the nominal axis until
/// the estimated wrench says contact with the fixture's top, then press on it while an Archimedean
/// spiral sweeps x, y over the pose uncertainty, until the tip drops 1 mm below the height of first
/// contact; then down to the partial insertion. Returns the hole frame the robot now believes in
/// (the nominal orientation, centred where the peg dropped, its mouth at the contact height), or
/// `None` when the time limit passes first.
fn search(run: &mut Run, nominal: &Iso, config: &TrialConfig, clearance_m: f64) -> Option<Iso> {
    let dt = run.cell.dt_s();
    let start = run.cell.measured_tcp_pose();
    let height = (nominal.inverse() * start).translation.z;
    let limit = (config.search_limit_s / dt).round() as usize;
    let mut k = 0;
    // Approach at 10 mm/s.
    let mut contact_z = None;
    while k < limit {
        let z = height - 10e-3 * k as f64 * dt;
        run.cell
            .controller
            .set_cartesian_target(nominal * Iso::translation(0.0, 0.0, z));
        if !run.step() {
            return None;
        }
        k += 1;
        let tip = (nominal.inverse() * run.cell.measured_tcp_pose()).translation;
        if run.cell.sensors.contact {
            contact_z = Some(tip.z);
            break;
        }
    }
    let contact_z = contact_z?;
    // Press 3 mm below the surface and spiral.
    let r = &config.offset_range;
    let spiral = crate::method::primitives::Spiral {
        max_radius_m: r[0].max(r[1]) + clearance_m + 1e-3,
        pitch_m: 0.5e-3,
        speed_m_per_s: 10e-3,
    };
    let t0 = k;
    while k < limit {
        let [x, y] = spiral.offset((k - t0) as f64 * dt);
        run.cell
            .controller
            .set_cartesian_target(nominal * Iso::translation(x, y, contact_z - 3e-3));
        if !run.step() {
            return None;
        }
        k += 1;
        let tip = (nominal.inverse() * run.cell.measured_tcp_pose()).translation;
        if tip.z < contact_z - 1e-3 {
            let believed = nominal * Iso::translation(tip.x, tip.y, contact_z);
            run.phase = "search";
            let here = run.cell.measured_tcp_pose();
            run.move_linear(&here, &tcp_in_hole(&believed, config.start_depth_m), 0.5);
            return (run.fault.is_none()).then_some(believed);
        }
    }
    None
}

/// The result of a trial that stopped before inserting (a fault or a failed search, `why`), and
/// the common part of every result.
fn stopped_result(
    pair: &PartPair,
    config: &TrialConfig,
    seed: u64,
    offset: &Pose6,
    fault: Option<SimFault>,
    started: Instant,
    why: Option<&str>,
) -> TrialResult {
    TrialResult {
        seed,
        geometry: pair.name.clone(),
        clearance_mm: pair.clearance_m * 1e3,
        method: config.method,
        start: config.start,
        t_obs_s: config.t_obs_s,
        offset: to_mm_deg(offset),
        outcome: if fault.is_some() {
            "sim_fault"
        } else {
            "failure"
        }
        .into(),
        stopped: why.map(String::from),
        success: false,
        fault,
        estimate: None,
        errors: None,
        final_depth_mm: None,
        contact_observations: 0,
        observations_used: 0,
        peak_fz_n: 0.0,
        mean_fz_n: 0.0,
        insert_fz_n: Vec::new(),
        times: PhaseTimes::default(),
        wall_s: started.elapsed().as_secs_f64(),
    }
}

/// Errors of an estimated hole pose: the estimate seen from the true hole frame, mm and deg.
pub fn axis_errors(truth: &Iso, estimate: &Iso) -> AxisErrors {
    let e = to_mm_deg(&Pose6::from_iso(&(truth.inverse() * estimate)));
    AxisErrors {
        x_mm: e[0],
        y_mm: e[1],
        z_mm: e[2],
        roll_deg: e[3],
        pitch_deg: e[4],
        yaw_deg: e[5],
    }
}

/// Temporal downsampling (IV-C): `n` observations evenly spaced in recording order.
pub fn temporal_downsample(poses: &[Pose6], n: usize) -> Vec<Pose6> {
    if poses.len() <= n {
        return poses.to_vec();
    }
    (0..n).map(|i| poses[i * poses.len() / n]).collect()
}

/// A trial's stepping: faults stop it, the trace records each step.
struct Run<'a> {
    cell: &'a mut Cell,
    trace: Option<&'a mut Vec<TraceRow>>,
    fault: Option<SimFault>,
    phase: &'static str,
}

impl Run<'_> {
    /// One physics step; false once the physics has faulted.
    fn step(&mut self) -> bool {
        if self.fault.is_some() {
            return false;
        }
        self.cell.step();
        if let Some(f) = self.cell.fault() {
            self.fault = Some(f);
            return false;
        }
        if let Some(trace) = self.trace.as_deref_mut() {
            let tcp = Pose6::from_iso(&self.cell.measured_tcp_pose()).0;
            trace.push(TraceRow {
                time_s: self.cell.time_s(),
                phase: self.phase,
                tcp,
                est_wrench: self.cell.sensors.wrench.into(),
                true_wrench: self.cell.true_contact_wrench().into(),
                contact: self.cell.sensors.contact,
            });
        }
        true
    }

    /// Moves the target from `from` to `to` (linear in position, slerp in rotation) over `seconds`.
    fn move_linear(&mut self, from: &Iso, to: &Iso, seconds: f64) {
        let dt = self.cell.dt_s();
        let steps = (seconds / dt).round().max(1.0) as usize;
        for k in 1..=steps {
            let s = k as f64 / steps as f64;
            let target = from.lerp_slerp(to, s);
            self.cell.controller.set_cartesian_target(target);
            if !self.step() {
                return;
            }
        }
    }

    fn hold(&mut self, at: &Iso, seconds: f64) {
        self.move_linear(at, at, seconds);
    }

    /// New impedance gains, keeping the current target (Sunrise mode switch).
    fn switch_gains(&mut self, gains: ImpedanceGains) {
        let target = match self.cell.controller.mode() {
            crate::twin::control::Mode::CartesianImpedance { target, .. } => *target,
            crate::twin::control::Mode::JointPosition { .. } => self.cell.measured_tcp_pose(),
        };
        self.cell
            .controller
            .set_mode(crate::twin::control::Mode::CartesianImpedance { gains, target })
            .expect("gains checked by TrialConfig::validate");
    }
}
