//! The on-disk cache of reference manifolds: built once per pair and generator settings, reused
//! by every trial and campaign (`$XDG_CACHE_HOME/pegtwin`, else `~/.cache/pegtwin`). This is the
//! one place that resolves a pair's reference manifold from a [`ManifoldSpec`].
//!
//! A cached file is named `{geometry}-{clearance}mm-{key}.manifold`, where `key` is a checksum of
//! everything that decides its content (sampler, points, seed, cell and physics parameters), so a
//! change of any of them builds a new file instead of reusing a stale one. Files are written
//! atomically, so concurrent builders (shards on one machine) cannot leave a half-written file.

use super::Manifold;
use super::build::{BuildJob, SamplerConfig, build_all};
use super::{file, geometric};
use crate::choice::{Choice, Named};
use crate::error::{Error, Result};
use crate::twin::geometry::PartPair;
use crate::twin::robot::RobotModel;
use crate::twin::workcell::{ARM_PREDICTION_RULE, WorkCellParams};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// How the reference manifolds are made (built once per geometry and clearance, then cached).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ManifoldSpec {
    /// Points kept after downsampling.
    pub points: usize,
    /// Sampling episodes.
    pub episodes: usize,
    /// Simulated time per episode, s.
    pub episode_s: f64,
    /// Seed of the sampling.
    pub seed: u64,
    /// How contact poses are found: the robot in simulation (paper IV-B) or the parts' geometry.
    /// Left out of a scenario's fingerprint when it is the robot (scenarios written before the
    /// choice keep theirs).
    #[serde(skip_serializing_if = "Sampler::is_robot")]
    pub sampler: Sampler,
}

/// Which sampler makes a reference manifold.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Sampler {
    /// The robot under low stiffness runs the sampling primitives in simulation and records the
    /// poses where its estimated wrench says contact ([`super::build`], paper IV-B).
    #[default]
    Robot,
    /// The poses where the parts touch without overlapping, found with the exact test over the
    /// region the robot's motion reaches ([`super::geometric`]).
    Geometric,
}

impl Choice for Sampler {
    const WHAT: &'static str = "sampler";
    const NAMED: &'static [Named<Self>] = &[
        Named {
            name: "robot",
            value: Sampler::Robot,
            help: "the arm probes the hole in simulation and records where it feels contact (paper IV-B)",
        },
        Named {
            name: "geometric",
            value: Sampler::Geometric,
            help: "the poses where the parts touch, from their shapes alone (seconds, independent of the physics)",
        },
    ];
}

impl Sampler {
    /// Whether this is the robot sampler.
    pub fn is_robot(&self) -> bool {
        *self == Sampler::Robot
    }
}

impl Default for ManifoldSpec {
    fn default() -> Self {
        let s = SamplerConfig::default();
        ManifoldSpec {
            points: 50_000,
            episodes: s.episodes,
            episode_s: s.episode_s,
            seed: 1,
            sampler: Sampler::Robot,
        }
    }
}

impl ManifoldSpec {
    /// Refuses robot-sampler settings (`episodes`, `episode_s`) other than the defaults on a
    /// geometric spec, where nothing would use them.
    pub fn ensure_episodes_used(&self) -> Result<()> {
        let default = ManifoldSpec::default();
        let set = self.episodes != default.episodes || self.episode_s != default.episode_s;
        if self.sampler == Sampler::Geometric && set {
            return Err(Error::Input(format!(
                "manifold.episodes = {}, manifold.episode_s = {}: they set the robot sampler's \
                 simulations, and the geometric sampler has none; leave them out, or set \
                 manifold.sampler = \"robot\"",
                self.episodes, self.episode_s
            )));
        }
        Ok(())
    }

    /// The sampler this spec asks for.
    pub fn sampler(&self) -> SamplerConfig {
        SamplerConfig {
            episodes: self.episodes,
            episode_s: self.episode_s,
            ..SamplerConfig::default()
        }
    }
}

/// What a reference manifold is made from.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Recipe<'a> {
    pub sampler: &'a SamplerConfig,
    /// Points kept after downsampling.
    pub points: usize,
    pub seed: u64,
    pub params: &'a WorkCellParams,
    /// Which sampler (left out for the robot's: its keys stay as they were).
    #[serde(skip_serializing_if = "Sampler::is_robot")]
    pub kind: Sampler,
}

/// How a robot whose encoders read off knows the hole it samples, for the cache's key: the
/// files of cells with offsets built before the robot was taught the hole are rebuilt.
const TAUGHT_HOLE_RULE: &str = "the hole as the robot reads it";

impl Recipe<'_> {
    /// The checksum that names the cached file. The robot's includes the physics parameters and
    /// the arm cell's contact prediction rule (and, for a cell whose encoders read off, how it
    /// knows the hole); the geometric one depends on the parts and the motion's region only
    /// (not the cell: one file serves every physics), and is marked `geo`.
    pub fn key(&self) -> String {
        let json = match self.kind {
            Sampler::Robot => {
                let physics = (&self.params.physics, ARM_PREDICTION_RULE);
                let reads_off = self.params.cell.reads_off()
                    || !self.params.sensors.encoder_offset_rad.is_empty();
                match reads_off {
                    true => serde_json::to_string(&(self, physics, TAUGHT_HOLE_RULE)),
                    false => serde_json::to_string(&(self, physics)),
                }
            }
            Sampler::Geometric => serde_json::to_string(&(
                &self.sampler.motion,
                self.points,
                self.seed,
                geometric::RULE,
            )),
        }
        .expect("recipe serialises");
        let prefix = if self.kind.is_robot() { "" } else { "geo" };
        format!("{prefix}{:08x}", crc32fast::hash(json.as_bytes()))
    }
}

/// What a build reports while it runs, for a progress display (the library prints nothing).
pub trait BuildProgress: Sync {
    /// The manifold of `pair` is about to be built into `path`, in `episodes` episodes (none for
    /// the geometric sampler).
    fn build_started(&self, _pair: &PartPair, _path: &Path, _episodes: usize) {}
    /// One sampling episode finished.
    fn episode_done(&self) {}
    /// The build finished (or failed).
    fn build_finished(&self) {}
}

/// No progress display.
impl BuildProgress for () {}

/// The cache folder every command and the Python package use (see
/// [`crate::files::cache_folder`]).
pub fn folder(given: Option<&Path>) -> Result<PathBuf> {
    crate::files::cache_folder(given)
}

/// Where the manifold of `pair` made by `recipe` is cached in `dir`: an assembly's pair adds the
/// checksum of its meshes, frames and mass, so that editing a mesh builds a new file.
pub fn path(dir: &Path, pair: &PartPair, recipe: &Recipe) -> PathBuf {
    let content = pair
        .content_key
        .as_ref()
        .map_or(String::new(), |k| format!("{k}-"));
    dir.join(format!(
        "{}-{}mm-{content}{}.manifold",
        pair.name,
        pair.clearance_mm(),
        recipe.key()
    ))
}

/// The reference manifold of `pair` made as `spec` says with the cell `params`, from the cache
/// folder `dir` (the default folder when `None`), built and cached first when missing.
pub fn resolve(
    pair: &PartPair,
    robot: &RobotModel,
    spec: &ManifoldSpec,
    params: &WorkCellParams,
    dir: Option<&Path>,
    progress: &dyn BuildProgress,
) -> Result<Manifold> {
    let dir = folder(dir)?;
    let wanted = Wanted {
        pair,
        robot,
        params: params.clone(),
    };
    let mut resolved = resolve_all(std::slice::from_ref(&wanted), spec, &dir, progress);
    resolved.pop().expect("one manifold per pair")
}

/// A pair whose reference manifold is wanted: its robot and the cell parameters of its sampling.
pub struct Wanted<'a> {
    pub pair: &'a PartPair,
    pub robot: &'a RobotModel,
    pub params: WorkCellParams,
}

/// The reference manifolds of `wanted` made as `spec` says, from the cache folder `dir`; the
/// missing ones are built side by side ([`build_all`]: every episode of every build to the one
/// pool) and each is cached as soon as it is built. Each file is the one its build gives alone.
/// One result per pair, in order: a failed build does not stop the others.
pub fn resolve_all(
    wanted: &[Wanted],
    spec: &ManifoldSpec,
    dir: &Path,
    progress: &dyn BuildProgress,
) -> Vec<Result<Manifold>> {
    let sampler = spec.sampler();
    let mut out: Vec<Option<Result<Manifold>>> = (wanted.iter())
        .map(|w| load_cached(w.pair, &recipe_of(spec, &sampler, &w.params), dir).transpose())
        .collect();
    let missing: Vec<usize> = (0..wanted.len()).filter(|&i| out[i].is_none()).collect();
    if missing.is_empty() {
        return out.into_iter().flatten().collect();
    }
    if let Err(e) = std::fs::create_dir_all(dir) {
        let error = || Error::file(dir, format!("cannot create the cache folder: {e}"));
        return (out.into_iter())
            .map(|o| o.unwrap_or_else(|| Err(error())))
            .collect();
    }
    let recipes: Vec<Recipe> = (missing.iter())
        .map(|&i| recipe_of(spec, &sampler, &wanted[i].params))
        .collect();
    let paths: Vec<PathBuf> = (missing.iter().zip(&recipes))
        .map(|(&i, r)| path(dir, wanted[i].pair, r))
        .collect();
    let built = match spec.sampler {
        Sampler::Robot => build_robot(wanted, &missing, &recipes, &paths, progress),
        Sampler::Geometric => build_geometric(wanted, &missing, &recipes, &paths, progress),
    };
    for (i, manifold) in missing.into_iter().zip(built) {
        out[i] = Some(manifold);
    }
    out.into_iter().flatten().collect()
}

/// Builds the robot-sampled manifolds of `wanted[missing]` side by side and caches each.
fn build_robot(
    wanted: &[Wanted],
    missing: &[usize],
    recipes: &[Recipe],
    paths: &[PathBuf],
    progress: &dyn BuildProgress,
) -> Vec<Result<Manifold>> {
    let jobs: Vec<BuildJob> = (missing.iter().zip(recipes))
        .map(|(&i, r)| BuildJob {
            pair: wanted[i].pair,
            robot: wanted[i].robot,
            params: r.params,
            config: r.sampler,
            points: r.points,
            seed: r.seed,
        })
        .collect();
    for (job, path) in jobs.iter().zip(paths) {
        progress.build_started(job.pair, path, job.config.episodes);
    }
    build_all(&jobs, &|| progress.episode_done(), |j, report| {
        progress.build_finished();
        let report = report?;
        file::save(&report.manifold, &paths[j])?;
        Ok(report.manifold)
    })
}

/// Builds the geometric manifolds of `wanted[missing]` one after the other (each on every
/// core) and caches each.
fn build_geometric(
    wanted: &[Wanted],
    missing: &[usize],
    recipes: &[Recipe],
    paths: &[PathBuf],
    progress: &dyn BuildProgress,
) -> Vec<Result<Manifold>> {
    (missing.iter().zip(recipes).zip(paths))
        .map(|((&i, r), path)| {
            progress.build_started(wanted[i].pair, path, 0);
            let report = geometric::build(wanted[i].pair, r.sampler, r.points, r.seed);
            progress.build_finished();
            let report = report?;
            file::save(&report.manifold, path)?;
            Ok(report.manifold)
        })
        .collect()
}

/// The recipe `spec` asks for (its sampler `sampler`) with the cell `params`.
fn recipe_of<'a>(
    spec: &ManifoldSpec,
    sampler: &'a SamplerConfig,
    params: &'a WorkCellParams,
) -> Recipe<'a> {
    Recipe {
        sampler,
        points: spec.points,
        seed: spec.seed,
        params,
        kind: spec.sampler,
    }
}

/// The reference manifold of `pair` made as `spec` says with the cell `params`, if the cache
/// folder `dir` holds it (nothing is built).
pub fn cached(
    pair: &PartPair,
    spec: &ManifoldSpec,
    params: &WorkCellParams,
    dir: &Path,
) -> Result<Option<Manifold>> {
    let sampler = spec.sampler();
    load_cached(pair, &recipe_of(spec, &sampler, params), dir)
}

/// The cached manifold of `pair` made by `recipe`, if there is one.
fn load_cached(pair: &PartPair, recipe: &Recipe, dir: &Path) -> Result<Option<Manifold>> {
    let path = path(dir, pair, recipe);
    if !path.is_file() {
        return Ok(None);
    }
    let m = file::load(&path)?;
    m.check_made_for(pair, &path)?;
    Ok(Some(m))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_samplers_keys_differ_and_the_geometric_one_ignores_the_cell() {
        let sampler = SamplerConfig::default();
        let params = WorkCellParams::default();
        let mut other = params.clone();
        other.physics.friction += 0.1;
        let recipe = |params, kind| Recipe {
            sampler: &sampler,
            points: 50_000,
            seed: 1,
            params,
            kind,
        };
        let robot = recipe(&params, Sampler::Robot);
        // The robot's recipe is written as it was before the choice (its cached files stay).
        assert!(!serde_json::to_string(&robot).unwrap().contains("kind"));
        assert_ne!(robot.key(), recipe(&other, Sampler::Robot).key());
        let geometric = recipe(&params, Sampler::Geometric).key();
        assert!(geometric.starts_with("geo"), "{geometric}");
        assert_eq!(geometric, recipe(&other, Sampler::Geometric).key());
        assert_ne!(geometric, robot.key());
    }
}
