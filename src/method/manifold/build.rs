//! The offline reference manifold (paper IV-B): the hole at a known pose, the robot under low
//! stiffness runs the sampling primitives from partial insertion down the engagement depth, over
//! many independent episodes (rayon, one seeded simulation each), and records `hole_T_peg`
//! whenever its estimated wrench says contact. The raw cloud is then downsampled to a fixed count
//! by a voxel grid so that density does not bias registration, and given normals.
//!
//! **Why a voxel grid.** Time spent in a region, not its geometric content, sets the raw density:
//! the spiral dwells where the peg rests against a wall, so flat faces of the manifold collect
//! most samples while corners, the discriminative features, get few (paper IV-B). A grid in the
//! scaled 6-D space keeps one pose per occupied cell, so every region counts by the volume it
//! occupies, not by how long the robot stayed there. The cell size is found by bisection to give
//! at least N occupied cells; if more, a seeded uniform subset of cells is kept. Each cell keeps
//! the pose nearest its cell's mean (a real sample, not an average of poses).

use super::{DEFAULT_NORMAL_K, MAX_POINTS, Manifold, ManifoldMeta, UNITS};
use crate::error::{Error, Result};
use crate::method::primitives::{
    AmplitudeSchedule, Descent, Drive, Perturbation, PerturbationState, SamplingMotion,
    ScaleSchedule,
};
use crate::method::seeds;
use crate::method::session::{Phase, Session};
use crate::pose::{Pose6, PoseMetric};
use crate::twin::control::ImpedanceGains;
use crate::twin::geometry::PartPair;
use crate::twin::robot::RobotModel;
use crate::twin::workcell::{SimFault, WorkCell, WorkCellParams, nominal_hole_pose, tcp_in_hole};
use rand::SeedableRng;
use rand::seq::SliceRandom;
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::ops::ControlFlow;
use std::sync::Mutex;

/// Everything the generator does, stored in the manifold's metadata.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SamplerConfig {
    /// Independent simulations.
    pub episodes: usize,
    /// Simulated time per episode, s.
    pub episode_s: f64,
    /// Low-stiffness impedance of the sampling motions.
    pub gains: ImpedanceGains,
    /// The motion; its descent runs from partial insertion down the engagement depth.
    pub motion: SamplingMotion,
}

impl Default for SamplerConfig {
    fn default() -> Self {
        SamplerConfig {
            episodes: 48,
            episode_s: 20.0,
            gains: ImpedanceGains {
                stiffness: [1000.0, 1000.0, 1500.0, 30.0, 30.0, 30.0],
                // A constant push into the hole (TCP z points up the peg) keeps the peg seated
                // while the spiral and the tilts press it against the walls.
                additional_force: [0.0, 0.0, -5.0, 0.0, 0.0, 0.0],
                ..Default::default()
            },
            motion: SamplingMotion {
                spiral_pitch_m: 1e-3,
                spiral_speed_m_per_s: 15e-3,
                frequency_hz: [0.6, 0.9, 0.45],
                descent: Descent {
                    start_depth_m: 2e-3,
                    end_depth_m: 20e-3,
                    speed_m_per_s: 1e-3,
                },
                perturbation: Perturbation {
                    sigma_m: 0.5e-3,
                    sigma_rad: 0.005,
                    correlation_time_s: 0.2,
                },
                schedule: AmplitudeSchedule {
                    lateral_overtravel_m: 8e-3,
                    angular_overtravel_rad: 0.06,
                    max_free_tilt_rad: 0.035,
                    yaw_fraction: 1.0,
                },
                scale: 1.0,
                phase_s: 0.0,
            },
        }
    }
}

impl SamplerConfig {
    /// Rejects values that cannot make a manifold, naming the field.
    pub fn ensure_valid(&self) -> Result<()> {
        if !(1..=MAX_EPISODES).contains(&self.episodes) {
            return Err(Error::Input(format!(
                "episodes is {}: expected 1 to {MAX_EPISODES}",
                self.episodes
            )));
        }
        if !(self.episode_s > 0.0 && self.episode_s <= MAX_EPISODE_S) {
            return Err(Error::Input(format!(
                "episode_s is {:?}: expected more than 0 and at most {MAX_EPISODE_S} s",
                self.episode_s
            )));
        }
        self.gains.ensure_valid()
    }
}

/// Bounds on a reference manifold's sampling: episodes, simulated seconds per episode.
pub const MAX_EPISODES: usize = 10_000;
pub const MAX_EPISODE_S: f64 = 600.0;

/// Tip height above the mouth at which an episode counts the peg as out of the hole, m.
const LEFT_HOLE_M: f64 = 1e-3;

/// What one episode produced.
pub struct Episode {
    /// Contact poses `hole_T_peg` (m, rad).
    pub poses: Vec<Pose6>,
    /// Set when the physics blew up; the episode's poses are then dropped.
    pub fault: Option<SimFault>,
}

/// Runs one sampling episode: the hole at its nominal pose, the peg aligned at the start depth,
/// the motion with this episode's seed (perturbation and phase). The robot knows the hole as it
/// reads it there ([`WorkCell::hole_as_read`]), as a cell that taught the hole by touching it
/// does: it moves and records the poses `hole_T_peg` in its own frame, so that its encoders'
/// offsets shift the manifold as they shift the poses it later observes, and cancel.
pub fn run_episode(
    pair: &PartPair,
    robot: &RobotModel,
    params: &WorkCellParams,
    config: &SamplerConfig,
    seed: u64,
) -> Result<Episode> {
    let hole = nominal_hole_pose(pair, params);
    let start = tcp_in_hole(&hole, config.motion.descent.start_depth_m);
    let mut cell = WorkCell::new(
        pair,
        robot.clone(),
        params,
        Some(hole),
        &start,
        config.gains.clone(),
        seed,
    )?;
    let known = cell.hole_as_read().expect("the cell has the hole");
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut motion = config.motion.clone();
    motion.phase_s = rand::Rng::random_range(&mut rng, 0.0..1000.0);
    let mut noise =
        PerturbationState::new(motion.perturbation.clone(), rand::Rng::random(&mut rng));
    let drive = Drive {
        base_t_hole: known,
        motion: &motion,
        schedule: ScaleSchedule::constant(motion.scale),
        clearance_m: pair.clearance_m,
        duration_s: config.episode_s,
    };
    let hole_inv = known.inverse();
    let mut poses = Vec::new();
    let mut session = Session::new(&mut cell, None, Phase::Sample);
    drive.run(&mut session, &mut noise, |m| {
        if !m.contact {
            return ControlFlow::Continue(());
        }
        let pose = Pose6::from_iso(&(hole_inv * m.tcp));
        // The engagement only: the tip below the mouth. A peg levered out of the hole does not
        // find its way back; the episode ends there.
        if pose.0[2] < 0.0 {
            poses.push(pose);
        } else if pose.0[2] > LEFT_HOLE_M {
            return ControlFlow::Break(());
        }
        ControlFlow::Continue(())
    });
    Ok(match session.fault() {
        Some(fault) => Episode {
            poses: Vec::new(),
            fault: Some(fault.clone()),
        },
        None => Episode { poses, fault: None },
    })
}

/// Voxel-grid downsampling to `n` poses in the scaled space of `metric` (see the module doc).
/// The cell size is found by bisection, each step counting the occupied cells of ~10^6 poses:
/// the counting and the sorts run on the thread pool (the same result on any number of threads:
/// every sorted key is distinct, so the order is the one a serial sort gives).
pub fn downsample(points: &[Pose6], metric: &PoseMetric, n: usize, seed: u64) -> Vec<Pose6> {
    if points.len() <= n {
        return points.to_vec();
    }
    let scaled: Vec<[f64; 6]> = points.par_iter().map(|p| metric.scaled(p)).collect();
    let cell_of = |p: &[f64; 6], size: f64| p.map(|v| (v / size).floor() as i64);
    let count_at = |size: f64| {
        let mut cells: Vec<[i64; 6]> = scaled.par_iter().map(|p| cell_of(p, size)).collect();
        cells.par_sort_unstable();
        1 + cells.windows(2).filter(|w| w[0] != w[1]).count()
    };
    // Bisection on the log of the cell size: the largest size that still gives n cells.
    let spread = scaled
        .iter()
        .fold(0.0f64, |m, p| p.iter().fold(m, |m, v| m.max(v.abs())));
    let (mut small, mut large) = (1e-9f64.max(spread * 1e-9), (2.0 * spread).max(1e-6));
    for _ in 0..40 {
        let mid = (small * large).sqrt();
        if count_at(mid) >= n {
            small = mid;
        } else {
            large = mid;
        }
    }
    // Every pose with its cell, sorted by cell (then pose): a cell is a run.
    let mut keyed: Vec<([i64; 6], u32)> = scaled
        .par_iter()
        .enumerate()
        .map(|(i, p)| (cell_of(p, small), i as u32))
        .collect();
    keyed.par_sort_unstable();
    let mut chosen: Vec<usize> = keyed
        .chunk_by(|a, b| a.0 == b.0)
        .map(|cell| representative(&cell.iter().map(|m| m.1).collect::<Vec<_>>(), &scaled))
        .collect();
    if chosen.len() > n {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        chosen.shuffle(&mut rng);
        chosen.truncate(n);
        chosen.sort_unstable();
    }
    chosen.into_iter().map(|i| points[i]).collect()
}

/// The member of a cell nearest the cell's mean.
fn representative(members: &[u32], scaled: &[[f64; 6]]) -> usize {
    let mut mean = [0.0; 6];
    for &i in members {
        for (m, v) in mean.iter_mut().zip(scaled[i as usize]) {
            *m += v / members.len() as f64;
        }
    }
    let d = |i: u32| -> f64 {
        scaled[i as usize]
            .iter()
            .zip(mean)
            .map(|(a, b)| (a - b) * (a - b))
            .sum()
    };
    members
        .iter()
        .copied()
        .min_by(|a, b| d(*a).total_cmp(&d(*b)).then(a.cmp(b)))
        .expect("a cell has members") as usize
}

/// Largest share of sampling episodes whose physics may fault before a build is refused: the
/// dropped episodes would leave holes in the manifold where the faults happened.
pub const MAX_FAULTED_SHARE: f64 = 0.05;

/// Refuses a build in which more than [`MAX_FAULTED_SHARE`] of the episodes faulted, naming the
/// first faults.
fn check_faults(faults: &[(usize, SimFault)], episodes: usize, pair: &PartPair) -> Result<()> {
    if (faults.len() as f64) <= MAX_FAULTED_SHARE * episodes as f64 {
        return Ok(());
    }
    let examples: Vec<String> = faults
        .iter()
        .take(3)
        .map(|(e, f)| format!("episode {e} at {:.3} s: {}", f.time_s, f.reason))
        .collect();
    Err(Error::Input(format!(
        "the physics faulted in {} of {} sampling episodes of {} at {} mm (at most {} % may): {}; \
         nothing was cached{}",
        faults.len(),
        episodes,
        pair.name,
        pair.clearance_mm(),
        MAX_FAULTED_SHARE * 100.0,
        examples.join("; "),
        fault_hint(faults)
    )))
}

/// What a refused build's faults point to, by who put in the energy that ended each episode
/// (`twin::energy`): the contacts or the integrator, a contact solve that did not converge
/// (docs/physics.md: the gear at 0.1 mm faults at 4 Gauss-Seidel passes and builds at 8); the
/// drives, the commanded motion. A fault without an energy account counts as the physics' when
/// no drive was at its torque limit.
fn fault_hint(faults: &[(usize, SimFault)]) -> String {
    let physics = faults
        .iter()
        .filter(|(_, f)| f.is_physics().unwrap_or(f.saturated_joints.is_empty()))
        .count();
    let driven = faults.len() - physics;
    let drives = format!("{driven} powered by the drives: the commanded motion's");
    if physics == 0 {
        return format!(" ({drives})");
    }
    let mut hint = format!(
        " ({physics} powered by the contacts or the integrator: the contact solve did not \
         converge; more Gauss-Seidel passes, a scenario's `[physics] pgs_iterations`, may \
         converge it"
    );
    if driven > 0 {
        hint += &format!("; {drives}");
    }
    hint + ")"
}

/// The result of a build.
pub struct BuildReport {
    pub manifold: Manifold,
    /// Contact poses recorded before downsampling.
    pub raw_count: usize,
    /// Episodes whose physics blew up (their poses were dropped), with the reasons.
    pub faults: Vec<(usize, SimFault)>,
}

/// A reference manifold to build: the pair with its robot and cell, and how to sample it.
#[derive(Clone, Copy)]
pub struct BuildJob<'a> {
    pub pair: &'a PartPair,
    pub robot: &'a RobotModel,
    pub params: &'a WorkCellParams,
    pub config: &'a SamplerConfig,
    /// Poses kept after downsampling.
    pub points: usize,
    pub seed: u64,
}

impl BuildJob<'_> {
    /// Refuses a sampler or a point count out of range, before anything runs.
    fn check(&self) -> Result<()> {
        self.config.ensure_valid()?;
        if !(DEFAULT_NORMAL_K + 1..=MAX_POINTS).contains(&self.points) {
            return Err(Error::Input(format!(
                "--points {}: expected {} (the normal neighbourhood) to {MAX_POINTS}",
                self.points,
                DEFAULT_NORMAL_K + 1
            )));
        }
        Ok(())
    }

    /// A rough relative cost of one of its episodes, for the order in which they run only.
    fn episode_cost(&self) -> f64 {
        self.config.episode_s * self.pair.relative_step_cost()
    }
}

/// Builds the reference manifold of `pair`: `config.episodes` episodes in parallel, downsampled to
/// `points`, normals from the `DEFAULT_NORMAL_K` nearest neighbours. `on_episode` is called as
/// each episode finishes (for a progress bar).
pub fn build(
    pair: &PartPair,
    robot: &RobotModel,
    params: &WorkCellParams,
    config: &SamplerConfig,
    points: usize,
    seed: u64,
    on_episode: &(dyn Fn() + Sync),
) -> Result<BuildReport> {
    let job = BuildJob {
        pair,
        robot,
        params,
        config,
        points,
        seed,
    };
    let mut reports = build_all(&[job], on_episode, |_, report| report);
    reports.pop().expect("one report per job")
}

/// Builds several reference manifolds side by side, each as [`build`] does alone, to the byte,
/// and hands each to `finished` (with its job's index) as soon as its last episode is done; their
/// results in the order of `jobs`. The episodes of every build go to the pool together, the
/// costliest pair's first ([`crate::schedule`]), so that no core idles at the end of one build
/// while another's episodes wait, and a build's downsampling overlaps the others' episodes
/// (issue 17). A job refused or failed does not stop the others.
pub fn build_all<R: Send>(
    jobs: &[BuildJob],
    on_episode: &(dyn Fn() + Sync),
    finished: impl Fn(usize, Result<BuildReport>) -> R + Sync,
) -> Vec<R> {
    let results: Vec<Mutex<Option<R>>> = jobs.iter().map(|_| Mutex::new(None)).collect();
    let finish = |j: usize, report: Result<BuildReport>| {
        let r = finished(j, report);
        *results[j].lock().expect("no result writer panicked") = Some(r);
    };
    let mut episodes = Vec::new();
    for (j, job) in jobs.iter().enumerate() {
        match job.check() {
            Ok(()) => episodes.extend((0..job.config.episodes).map(|e| (j, e))),
            Err(e) => finish(j, Err(e)),
        }
    }
    // Longest first; the sort is stable, so a job's episodes keep their order.
    episodes.sort_by(|a, b| {
        jobs[b.0]
            .episode_cost()
            .total_cmp(&jobs[a.0].episode_cost())
    });
    let slots: Vec<EpisodeSlots> = jobs.iter().map(EpisodeSlots::new).collect();
    crate::schedule::map_in_order(&episodes, |&(j, e)| {
        let job = &jobs[j];
        let out = run_episode(
            job.pair,
            job.robot,
            job.params,
            job.config,
            seeds::episode(job.seed, e),
        );
        on_episode();
        if let Some(all) = slots[j].put(e, out) {
            finish(j, all.and_then(|episodes| assemble(job, episodes)));
        }
    });
    results
        .into_iter()
        .map(|r| {
            r.into_inner()
                .expect("no result writer panicked")
                .expect("every job finished")
        })
        .collect()
}

/// A build's episodes as they finish, in any order.
struct EpisodeSlots {
    done: Mutex<Vec<Option<Result<Episode>>>>,
}

impl EpisodeSlots {
    fn new(job: &BuildJob) -> Self {
        EpisodeSlots {
            done: Mutex::new((0..job.config.episodes).map(|_| None).collect()),
        }
    }

    /// Puts episode `e`'s result; once it was the last, all of them in episode order (the first
    /// error in that order, if any).
    fn put(&self, e: usize, out: Result<Episode>) -> Option<Result<Vec<Episode>>> {
        let mut done = self.done.lock().expect("no episode writer panicked");
        done[e] = Some(out);
        if done.iter().any(Option::is_none) {
            return None;
        }
        let all = std::mem::take(&mut *done);
        Some(
            all.into_iter()
                .map(|o| o.expect("every episode put"))
                .collect(),
        )
    }
}

/// The manifold of `job` from its episodes (in episode order): refused when too many faulted or
/// too few poses were recorded; otherwise downsampled, with normals and the recipe in its
/// metadata.
fn assemble(job: &BuildJob, episodes: Vec<Episode>) -> Result<BuildReport> {
    let (pair, config, points, seed) = (job.pair, job.config, job.points, job.seed);
    let faults: Vec<(usize, SimFault)> = episodes
        .iter()
        .enumerate()
        .filter_map(|(i, e)| e.fault.clone().map(|f| (i, f)))
        .collect();
    check_faults(&faults, config.episodes, pair)?;
    let raw: Vec<Pose6> = episodes.into_iter().flat_map(|e| e.poses).collect();
    if raw.len() < points {
        return Err(Error::Input(format!(
            "{} contact poses were recorded in {} episodes, fewer than the {points} requested: \
             ask for fewer --points or more --episodes / --episode-s (nothing was cached)",
            raw.len(),
            config.episodes
        )));
    }
    if raw.len() < DEFAULT_NORMAL_K + 1 {
        return Err(Error::Input(format!(
            "only {} contact poses were recorded: the sampling motion never pressed hard enough \
             (contact threshold {} N)",
            raw.len(),
            job.params.sensors.contact_on_n
        )));
    }
    let metric = PoseMetric::default();
    let kept = downsample(&raw, &metric, points, seed);
    let meta = ManifoldMeta {
        geometry: pair.name.clone(),
        clearance_m: Some(pair.clearance_m),
        units: UNITS.into(),
        metric,
        normal_k: DEFAULT_NORMAL_K,
        source: format!(
            "pegtwin manifold build: {} raw contact poses from {} episodes ({} faulted, dropped), \
             voxel-grid downsampled; sampler {}",
            raw.len(),
            config.episodes,
            faults.len(),
            serde_json::to_string(config).expect("config serialises")
        ),
        seed: Some(seed),
    };
    Ok(BuildReport {
        manifold: Manifold::from_points(kept, meta)?,
        raw_count: raw.len(),
        faults,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::twin::energy::{EnergyFlows, EnergySource};

    #[test]
    fn voxel_downsampling_removes_density_bias() {
        // Two regions of equal volume; the second holds ten times the samples.
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let mut points = Vec::new();
        let mut cube = |offset: f64, count: usize, points: &mut Vec<Pose6>| {
            for _ in 0..count {
                let p: [f64; 6] = std::array::from_fn(|i| {
                    let u: f64 = rand::Rng::random(&mut rng);
                    if i < 3 {
                        (offset + u) * 1e-3
                    } else {
                        u.to_radians()
                    }
                });
                points.push(Pose6(p));
            }
        };
        cube(0.0, 10_000, &mut points);
        cube(5.0, 100_000, &mut points);
        let kept = downsample(&points, &PoseMetric::default(), 1_000, 7);
        assert_eq!(kept.len(), 1_000);
        let dense = kept.iter().filter(|p| p.0[0] > 2.5e-3).count() as f64 / kept.len() as f64;
        // Raw, the dense region holds 91 % of the poses; by volume it is half. A 6-D grid of about
        // 500 cells per region is coarse (3 to 4 cells per axis), so where the grid happens to
        // cut each region moves the share by up to (4/3)^3: 0.5 to 0.7 is unbiased at this size.
        assert!(dense < 0.7, "share of the dense region {dense} (raw 0.91)");
        let one_thread = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .expect("a pool");
        assert_eq!(
            kept,
            one_thread.install(|| downsample(&points, &PoseMetric::default(), 1_000, 7)),
            "the same on one thread"
        );
        assert!(
            kept.iter().all(|k| points.contains(k)),
            "keeps real samples"
        );
    }

    #[test]
    fn a_build_with_more_than_5_percent_faulted_episodes_is_refused() {
        let pair = crate::twin::geometry::build_builtin(
            crate::twin::geometry::builtin_by_name("cross").unwrap(),
            0.5e-3,
        )
        .unwrap();
        let fault = |e: usize| {
            (
                e,
                SimFault {
                    time_s: 1.0,
                    reason: "runaway velocity".into(),
                    saturated_joints: Vec::new(),
                    energy: Some(flows(EnergySource::Contacts)),
                },
            )
        };
        let two: Vec<_> = (0..2).map(fault).collect();
        assert!(check_faults(&two, 48, &pair).is_ok(), "2 of 48 is 4 %");
        let three: Vec<_> = (0..3).map(fault).collect();
        let e = check_faults(&three, 48, &pair).unwrap_err().to_string();
        assert!(
            e.contains("3 of 48") && e.contains("runaway velocity") && e.contains("pgs_iterations"),
            "{e}"
        );
        let mut driven = three.clone();
        for (_, f) in &mut driven {
            f.energy = Some(flows(EnergySource::Drives));
        }
        let e = check_faults(&driven, 48, &pair).unwrap_err().to_string();
        assert!(
            e.contains("3 powered by the drives") && !e.contains("pgs_iterations"),
            "{e}"
        );
        driven[1].1.energy = None;
        let e = check_faults(&driven, 48, &pair).unwrap_err().to_string();
        assert!(
            e.contains("1 powered by the contacts") && e.contains("2 powered by the drives"),
            "{e}"
        );
    }

    #[test]
    fn builds_side_by_side_are_each_the_build_alone_and_a_refused_one_stops_none() {
        let pair = |name| {
            crate::twin::geometry::build_builtin(
                crate::twin::geometry::builtin_by_name(name).unwrap(),
                0.5e-3,
            )
            .unwrap()
        };
        let (cross, key) = (pair("cross"), pair("key"));
        let robot = crate::twin::robot::urdf::iiwa14().unwrap();
        let params = WorkCellParams::default();
        let config = SamplerConfig {
            episodes: 3,
            episode_s: 0.4,
            ..SamplerConfig::default()
        };
        let job = |pair, points| BuildJob {
            pair,
            robot: &robot,
            params: &params,
            config: &config,
            points,
            seed: 5,
        };
        let jobs = [job(&cross, 20), job(&cross, 0), job(&key, 20)];
        let together = build_all(&jobs, &|| {}, |j, report| (j, report));
        assert_eq!(
            together.iter().map(|(j, _)| *j).collect::<Vec<_>>(),
            [0, 1, 2]
        );
        let refused = together[1].1.as_ref().err().expect("0 points").to_string();
        assert!(refused.contains("--points 0"), "{refused}");
        // The episodes, each from its own seed, assembled in episode order.
        let by_hand: Vec<Episode> = (0..config.episodes)
            .map(|e| run_episode(&cross, &robot, &params, &config, seeds::episode(5, e)).unwrap())
            .collect();
        let by_hand = assemble(&jobs[0], by_hand).expect("builds by hand");
        let first = together[0].1.as_ref().expect("builds side by side");
        assert_eq!(first.manifold.points, by_hand.manifold.points);
        assert!(by_hand.raw_count > 20, "{}", by_hand.raw_count);
        for (job, (_, report)) in [(jobs[0], &together[0]), (jobs[2], &together[2])] {
            let alone = build(
                job.pair,
                &robot,
                &params,
                &config,
                job.points,
                job.seed,
                &|| {},
            )
            .expect("builds alone");
            let report = report.as_ref().expect("builds side by side");
            assert_eq!(report.raw_count, alone.raw_count);
            assert_eq!(report.manifold.points, alone.manifold.points);
            assert_eq!(report.manifold.normals, alone.manifold.normals);
            assert_eq!(report.manifold.meta, alone.manifold.meta);
        }
    }

    #[test]
    fn a_robot_whose_encoders_read_off_samples_the_hole_as_it_reads_it() {
        // The same episode (seed, every other draw) with the encoders off by up to 2 mrad and
        // with none: taught the hole as it reads it, the robot records its poses where the exact
        // one does, within a small fraction of how far the offsets move its TCP reading (a robot
        // that took the true hole for its reading would record them that far off).
        let pair = crate::twin::geometry::build_builtin(
            crate::twin::geometry::builtin_by_name("cross").unwrap(),
            0.5e-3,
        )
        .unwrap();
        let robot = crate::twin::robot::urdf::iiwa14().unwrap();
        let exact = WorkCellParams {
            cell: crate::twin::real_cell::RealCell::default(),
            ..WorkCellParams::default()
        };
        let mut off = exact.clone();
        off.cell.encoder_offset_rad = 2e-3;
        let config = SamplerConfig {
            episodes: 1,
            episode_s: 2.0,
            ..SamplerConfig::default()
        };
        let seed = seeds::episode(5, 0);
        let mean_xy = |params: &WorkCellParams| {
            let poses = run_episode(&pair, &robot, params, &config, seed)
                .unwrap()
                .poses;
            assert!(poses.len() > 100, "{} contact poses", poses.len());
            let n = poses.len() as f64;
            [0, 1].map(|i| poses.iter().map(|p| p.0[i]).sum::<f64>() / n)
        };
        let (a, b) = (mean_xy(&exact), mean_xy(&off));
        let hole = nominal_hole_pose(&pair, &off);
        let start = tcp_in_hole(&hole, config.motion.descent.start_depth_m);
        let cell = WorkCell::new(
            &pair,
            robot.clone(),
            &off,
            Some(hole),
            &start,
            config.gains,
            seed,
        )
        .unwrap();
        let read = cell.hole_as_read().unwrap();
        let shift_m = (read.translation.vector - hole.translation.vector).norm();
        assert!(shift_m > 1e-3, "the offsets move the reading {shift_m} m");
        let apart_m = (a[0] - b[0]).hypot(a[1] - b[1]);
        assert!(
            apart_m < 0.05 * shift_m,
            "{apart_m} m apart, reading shift {shift_m} m"
        );
    }

    fn flows(source: EnergySource) -> EnergyFlows {
        EnergyFlows {
            window_s: 0.1,
            mechanical_gain_j: 1.0,
            drives_j: 0.0,
            contacts_j: 0.0,
            joint_damping_j: 0.0,
            integration_j: 0.0,
            source,
        }
    }
}
