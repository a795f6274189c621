//! `pegtwin bench`: the speed of the pieces a campaign is made of, measured on the user's own
//! machine in one run, with the ratio to real time where the piece simulates time.
//!
//! - the arm cell (the iiwa 14 under 1 kHz Cartesian impedance, the peg 5 mm in its hole at
//!   0.1 mm, probing the walls as the observation does) with the cross and with the gear, on the
//!   joint-space contacts (the default) and on rapier's: physics steps per second on one core,
//!   the scenes of `cargo bench --bench arm`;
//! - one 20 s sampling episode of the manifold build (cross at 0.5 mm), one core;
//! - one trial of the direct baseline (cross at 0.5 mm, 10 s observation), one core;
//! - 1 000 steps of the Gymnasium environment's core (`method::env`, cross at 0.5 mm, 20 Hz
//!   control over the 1 kHz physics) under a uniformly random policy, one core;
//! - one registration (paper IV-D) of 1 000 observations against a 100 000-pose analytic cross
//!   manifold, 16 restarts, on the current thread pool (as in a campaign).
//!
//! With a scenario (`pegtwin bench --campaign FILE`), the campaign's own figures too, each in
//! a scratch folder that is removed afterwards: every reference manifold it registers against,
//! built alone on all cores into an empty cache, by the robot sampler and by the geometric one
//! (the scenario's own sampler's file is the one the cached campaign uses); the whole campaign with those manifolds cached;
//! and the whole campaign again from an empty cache (its manifolds built side by side, then its
//! trials), each with its CPU time, how busy it kept the cores, and simulated over wall time.
//!
//! Wall-clock figures: run it on an idle machine. Instruction counts, which do not depend on the
//! load, are in `docs/performance.md`.

use crate::campaign::records::RecordSource;
use crate::campaign::replays::Replays;
use crate::campaign::run::{CampaignOptions, RunOptions, Shard, campaign, prepare};
use crate::campaign::scenario::Scenario;
use crate::campaign::usage::Stopwatch;
use crate::choice::Choice;
use crate::error::{Error, Result};
use crate::method::config::{Method, TrialConfig};
use crate::method::env::{EnvConfig, PegEnv};
use crate::method::manifold::build::{SamplerConfig, run_episode};
use crate::method::manifold::cache::Sampler;
use crate::method::manifold::geometric::DRAWS_PER_POINT;
use crate::method::manifold::synthetic::SyntheticPair;
use crate::method::manifold::{DEFAULT_NORMAL_K, Manifold, ManifoldMeta, UNITS};
use crate::method::register::{RegistrationConfig, register};
use crate::method::seeds;
use crate::method::trial::run_trial;
use crate::pose::{Iso, Pose6, PoseMetric};
use crate::twin::control::ImpedanceGains;
use crate::twin::geometry::{PartPair, build_builtin, builtin_by_name};
use crate::twin::physics::ArmContacts;
use crate::twin::robot::urdf::iiwa14;
use crate::twin::workcell::{WorkCell, WorkCellParams, nominal_hole_pose, tcp_in_hole};
use serde::Serialize;
use std::path::Path;
use std::time::Instant;

/// How much of each piece to run.
#[derive(Clone, Copy, Debug)]
pub struct BenchOptions {
    /// Physics steps measured on the cross's arm scene (the gear's runs a tenth of them).
    pub arm_steps: usize,
    /// Steps of the environment under a random policy.
    pub env_steps: usize,
}

impl Default for BenchOptions {
    /// 2 000 arm steps; 1 000 environment steps (the Python package's issue measures 1 000).
    fn default() -> Self {
        BenchOptions {
            arm_steps: 2000,
            env_steps: 1000,
        }
    }
}

/// One measured figure.
#[derive(Clone, Debug, Serialize)]
pub struct BenchRow {
    pub name: String,
    pub what: String,
    /// The figure, in `unit`.
    pub value: f64,
    pub unit: String,
    /// Simulated time over wall time (above 1: faster than the real robot), where time is
    /// simulated.
    pub real_time_factor: Option<f64>,
}

/// Steps the arm scenes settle before they are measured.
const SETTLE_STEPS: usize = 200;

/// The probing target of the arm scenes at time `t_s`: a 0.3 mm circle in x, y, 1 mm below the
/// start, rocking 0.5 deg in roll and pitch (as the observation phase probes).
pub fn probing_target(start: &Iso, t_s: f64) -> Iso {
    let w = std::f64::consts::TAU;
    start
        * Iso::translation(0.3e-3 * (w * t_s).cos(), 0.3e-3 * (w * t_s).sin(), -1e-3)
        * Iso::rotation(nalgebra::Vector3::new(
            0.5f64.to_radians() * (w * 1.3 * t_s).sin(),
            0.5f64.to_radians() * (w * 0.7 * t_s).sin(),
            0.0,
        ))
}

/// The arm scene of `geometry` at 0.1 mm: the cell with the peg 5 mm in its hole under 500 N/m,
/// settled for [`SETTLE_STEPS`] steps of probing, and the start pose the probing is about.
pub fn arm_scene(geometry: &str, contacts: ArmContacts) -> Result<(WorkCell, Iso)> {
    arm_scene_of(
        &build_builtin(builtin_by_name(geometry)?, 0.1e-3)?,
        contacts,
    )
}

fn arm_scene_of(pair: &PartPair, contacts: ArmContacts) -> Result<(WorkCell, Iso)> {
    let mut params = WorkCellParams::default();
    params.physics.arm_contacts = contacts;
    let hole = nominal_hole_pose(pair, &params);
    let start = tcp_in_hole(&hole, 0.005);
    let gains = ImpedanceGains::uniform(500.0, 20.0, 0.7);
    let mut cell = WorkCell::new(pair, iiwa14()?, &params, Some(hole), &start, gains, 1)?;
    probe(&mut cell, &start, SETTLE_STEPS);
    Ok((cell, start))
}

/// `steps` physics steps of probing.
pub fn probe(cell: &mut WorkCell, start: &Iso, steps: usize) {
    for _ in 0..steps {
        let t = cell.time_s();
        cell.command_pose(probing_target(start, t));
        cell.step();
    }
}

/// The mean number of contact points the solver handles per step over `steps` more steps of
/// probing (counted apart from the timed steps).
fn contacts_per_step(cell: &mut WorkCell, start: &Iso, steps: usize) -> f64 {
    let mut contacts = 0;
    for _ in 0..steps {
        probe(cell, start, 1);
        contacts += cell.truth().solver_contacts();
    }
    contacts as f64 / steps as f64
}

/// Runs every piece and returns the table.
pub fn run(options: &BenchOptions) -> Result<Vec<BenchRow>> {
    let gear_steps = (options.arm_steps / 10).max(1);
    Ok(vec![
        arm_row("cross", options.arm_steps, ArmContacts::JointSpace)?,
        arm_row("gear", gear_steps, ArmContacts::JointSpace)?,
        arm_row("cross", options.arm_steps, ArmContacts::Rapier)?,
        arm_row("gear", gear_steps, ArmContacts::Rapier)?,
        episode_row()?,
        trial_row()?,
        env_row(options.env_steps)?,
        registration_row()?,
    ])
}

fn arm_row(geometry: &str, steps: usize, solver: ArmContacts) -> Result<BenchRow> {
    let pair = build_builtin(builtin_by_name(geometry)?, 0.1e-3)?;
    let (mut cell, start) = arm_scene_of(&pair, solver)?;
    let dt = cell.dt_s();
    let t0 = Instant::now();
    probe(&mut cell, &start, steps);
    let rate = steps as f64 / t0.elapsed().as_secs_f64();
    let contacts = contacts_per_step(&mut cell, &start, steps.min(100));
    Ok(BenchRow {
        name: match solver {
            ArmContacts::JointSpace => format!("arm_{geometry}"),
            ArmContacts::Rapier => format!("arm_{geometry}_rapier"),
        },
        what: format!(
            "arm cell, iiwa 14 + {geometry} at 0.1 mm ({} + {} convex pieces, {contacts:.0} contact points{}), probing, {steps} steps, one core",
            pair.peg.pieces.len(),
            pair.hole.pieces.len(),
            match solver {
                ArmContacts::JointSpace => "",
                ArmContacts::Rapier => ", rapier's contacts",
            },
        ),
        value: rate,
        unit: "steps/s".into(),
        real_time_factor: Some(rate * dt),
    })
}

fn episode_row() -> Result<BenchRow> {
    let pair = build_builtin(builtin_by_name("cross")?, 0.5e-3)?;
    let sampler = SamplerConfig::default();
    let t0 = Instant::now();
    run_episode(
        &pair,
        &iiwa14()?,
        &WorkCellParams::default(),
        &sampler,
        seeds::episode(1, 0),
    )?;
    let wall = t0.elapsed().as_secs_f64();
    Ok(BenchRow {
        name: "sampling_episode".into(),
        what: format!(
            "one manifold sampling episode, cross at 0.5 mm, {} s simulated, one core",
            sampler.episode_s
        ),
        value: wall,
        unit: "s".into(),
        real_time_factor: Some(sampler.episode_s / wall),
    })
}

fn trial_row() -> Result<BenchRow> {
    let pair = build_builtin(builtin_by_name("cross")?, 0.5e-3)?;
    let config = TrialConfig {
        method: Method::Direct,
        ..TrialConfig::default()
    };
    let t0 = Instant::now();
    let r = run_trial(
        &pair,
        &iiwa14()?,
        &WorkCellParams::default(),
        &config,
        None,
        3,
        None,
    )?;
    let wall = t0.elapsed().as_secs_f64();
    let simulated = r.times.simulated_s();
    Ok(BenchRow {
        name: "trial_direct".into(),
        what: format!(
            "one trial, direct baseline, cross at 0.5 mm, {} s observation ({simulated:.1} s simulated), one core",
            config.t_obs_s
        ),
        value: wall,
        unit: "s".into(),
        real_time_factor: Some(simulated / wall),
    })
}

/// `steps` environment steps under a uniformly random policy (seeded), resetting when an
/// episode ends: steps per second and the ratio to real time at the control rate.
fn env_row(steps: usize) -> Result<BenchRow> {
    use rand::{Rng, SeedableRng};
    let pair = build_builtin(builtin_by_name("cross")?, 0.5e-3)?;
    let config = EnvConfig::default();
    let control_hz = config.control_hz;
    let mut env = PegEnv::new(pair, iiwa14()?, WorkCellParams::default(), config)?;
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
    let t0 = Instant::now();
    env.reset(0)?;
    for _ in 0..steps {
        let action: Vec<f64> = (0..env.config().action_len())
            .map(|_| rng.random_range(-1.0..=1.0))
            .collect();
        let step = env.step(&action)?;
        if step.terminated || step.truncated {
            env.reset(rng.random())?;
        }
    }
    let rate = steps as f64 / t0.elapsed().as_secs_f64();
    Ok(BenchRow {
        name: "env_random_policy".into(),
        what: format!(
            "{steps} environment steps, random policy, cross at 0.5 mm, {control_hz} Hz control over 1 kHz physics, one core"
        ),
        value: rate,
        unit: "steps/s".into(),
        real_time_factor: Some(rate / control_hz),
    })
}

fn registration_row() -> Result<BenchRow> {
    let pair = SyntheticPair::cross(0.03, 0.01, 0.5e-3);
    let points = pair.sample_contacts(100_000, [0.001, 0.015], 1);
    let truth = Pose6([0.6, 0.05, 0.2, 0.0, 0.0, 0.3]);
    let noise = (5e-6, 0.005f64.to_radians());
    let observations = pair.observe(&truth, 1000, [0.002, 0.008], noise, 2);
    let init = truth.compose(&Pose6([0.004, -0.003, 0.005, 0.07, -0.05, 0.08]));
    let meta = ManifoldMeta {
        geometry: pair.name.clone(),
        clearance_m: Some(pair.clearance_m),
        units: UNITS.into(),
        metric: PoseMetric::default(),
        normal_k: DEFAULT_NORMAL_K,
        source: "pegtwin bench".into(),
        seed: Some(1),
    };
    let manifold = Manifold::from_points(points, meta)?;
    let config = RegistrationConfig::default();
    let t0 = Instant::now();
    register(&manifold, &observations, &init, &config)?;
    Ok(BenchRow {
        name: "registration".into(),
        what: format!(
            "registration, 1000 observations, 100 000-pose manifold, {} restarts (the trials' default), {} threads",
            config.restarts,
            rayon::current_num_threads()
        ),
        value: t0.elapsed().as_secs_f64(),
        unit: "s".into(),
        real_time_factor: None,
    })
}

/// The rows of a campaign of `scenario` (module docs): its manifolds built one by one, the
/// campaign with them cached, the campaign from an empty cache. Runs on the current thread
/// pool, in a scratch folder removed afterwards.
pub fn campaign_rows(scenario: &Scenario) -> Result<Vec<BenchRow>> {
    let scratch = tempfile::tempdir().map_err(|e| {
        Error::file(
            std::env::temp_dir(),
            format!("cannot make the bench's scratch folder: {e}"),
        )
    })?;
    let cache = scratch.path().join("cache");
    let mut rows = Vec::new();
    for c in one_manifold_cell_per_pair(scenario) {
        let robot = manifold_row(scenario, c, Sampler::Robot, &cache, scratch.path())?;
        let mut geometric = manifold_row(scenario, c, Sampler::Geometric, &cache, scratch.path())?;
        geometric.what += &format!(
            ", {:.1} x faster than the robot's",
            robot.value / geometric.value
        );
        rows.extend([robot, geometric]);
    }
    let cold_cache = scratch.path().join("empty-cache");
    for (name, cache, how) in [
        ("campaign_cached", &cache, "its manifolds cached"),
        ("campaign_cold", &cold_cache, "from an empty cache"),
    ] {
        let out = scratch.path().join(name);
        rows.push(campaign_row(scenario, name, &out, cache, how)?);
    }
    Ok(rows)
}

/// The reference manifold of cell `c` built alone by `sampler` on all cores: into `cache` when
/// it is the scenario's own sampler (the cached campaign then uses it), else into a folder of
/// `scratch` of its own.
fn manifold_row(
    scenario: &Scenario,
    c: usize,
    sampler: Sampler,
    cache: &Path,
    scratch: &Path,
) -> Result<BenchRow> {
    let own = scenario.manifold.sampler == sampler;
    let mut scenario = scenario.clone();
    scenario.manifold.sampler = sampler;
    let cell = &scenario.cells()[c];
    let watch = Stopwatch::start(rayon::current_num_threads());
    let options = RunOptions {
        cache_dir: if own {
            cache.to_path_buf()
        } else {
            scratch.join(format!("{}-cache", sampler.name()))
        },
        progress: &(),
    };
    prepare(&scenario, &[c], &options)?;
    let usage = watch.usage();
    let spec = &scenario.manifold;
    let how = match sampler {
        Sampler::Robot => format!("{} episodes of {} s", spec.episodes, spec.episode_s),
        Sampler::Geometric => format!("{} contact poses drawn", DRAWS_PER_POINT * spec.points),
    };
    Ok(BenchRow {
        name: format!(
            "manifold_{}_{}_{}mm",
            sampler.name(),
            cell.geometry,
            cell.clearance_mm
        ),
        what: format!(
            "reference manifold by the {} sampler, {} at {} mm, {how}, built alone: {}",
            sampler.name(),
            cell.geometry,
            cell.clearance_mm,
            usage.describe()
        ),
        value: usage.wall_s,
        unit: "s".into(),
        real_time_factor: sampler
            .is_robot()
            .then(|| spec.episodes as f64 * spec.episode_s / usage.wall_s),
    })
}

/// The first manifold-method cell of each pair the scenario registers against.
fn one_manifold_cell_per_pair(scenario: &Scenario) -> Vec<usize> {
    let cells = scenario.cells();
    let mut seen = Vec::new();
    (0..cells.len())
        .filter(|&c| {
            let cell = &cells[c];
            let pair = (cell.geometry.clone(), cell.clearance_mm.to_bits());
            let first = cell.method.registers() && !seen.contains(&pair);
            if first {
                seen.push(pair);
            }
            first
        })
        .collect()
}

/// The whole campaign into `out` with manifolds cached in `cache`: wall time, CPU time and
/// simulated time of its trials.
fn campaign_row(
    scenario: &Scenario,
    name: &str,
    out: &Path,
    cache: &Path,
    how: &str,
) -> Result<BenchRow> {
    let watch = Stopwatch::start(rayon::current_num_threads());
    let options = CampaignOptions {
        shard: Shard::WHOLE,
        resume: false,
        replays: Replays::None,
    };
    let run = RunOptions {
        cache_dir: cache.to_path_buf(),
        progress: &(),
    };
    let finished = campaign(scenario, out, options, &run)?;
    let usage = watch.usage();
    let mut simulated = 0.0;
    finished
        .trials
        .for_each(&mut |r| simulated += r.result.times.simulated_s())?;
    Ok(BenchRow {
        name: name.into(),
        what: format!(
            "campaign '{}' ({} trials), {how}: {}",
            scenario.name,
            finished.count,
            usage.describe()
        ),
        value: usage.wall_s,
        unit: "s".into(),
        real_time_factor: Some(simulated / usage.wall_s),
    })
}

/// The table as text.
pub fn table(rows: &[BenchRow]) -> String {
    let mut out = format!(
        "{:<24} {:>16} {:>10}  what\n",
        "piece", "figure", "x realtime"
    );
    for r in rows {
        let factor = r
            .real_time_factor
            .map_or("-".to_string(), |f| format!("{f:.2}"));
        out += &format!(
            "{:<24} {:>16} {:>10}  {}\n",
            r.name,
            format!("{:.2} {}", r.value, r.unit),
            factor,
            r.what
        );
    }
    out
}
