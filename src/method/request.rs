//! One trial as a user asks for it, in the units people type: a built-in geometry by name and the
//! clearance in mm (or an assembly file), the offsets' half-ranges in mm and deg, a reference manifold file or the
//! cache. `pegtwin trial` and the Python package's `pegtwin.trial` both go through here, so they
//! check the same values in the same order, fail with the same messages and give the same record.

use crate::error::{Error, Result};
use crate::method::config::{MAX_OFFSET, Method, Start, TrialConfig};
use crate::method::manifold::Manifold;
use crate::method::manifold::cache::{self, BuildProgress, ManifoldSpec, Sampler};
use crate::method::manifold::file;
use crate::method::session::Recorder;
use crate::method::trial::{TrialResult, run_trial};
use crate::twin::assembly::PairSource;
use crate::twin::geometry::PartPair;
use crate::twin::real_cell::{Profile, RealCell};
use crate::twin::robot::RobotModel;
use crate::twin::workcell::WorkCellParams;
use std::path::PathBuf;

/// A trial's arguments as typed (mm, deg, names).
#[derive(Clone, Debug)]
pub struct TrialRequest {
    /// The pair: a built-in (`cross`, `extrusion`, `plug3`, `key`, `gear`) at a clearance in mm,
    /// or an assembly file.
    pub pair: PairSource,
    /// Observation time, s.
    pub t_obs_s: f64,
    pub method: Method,
    pub start: Start,
    /// Trial seed: draws the hole offset and seeds every noise source.
    pub seed: u64,
    /// Half-range of the hole's position offset, mm (U(-r, r) on x, y, z).
    pub offset_mm: f64,
    /// Half-range of the hole's orientation offset, deg (U(-r, r) on roll, pitch, yaw).
    pub offset_deg: f64,
    /// Reference manifold file (`None`: the cache, built on demand).
    pub manifold: Option<PathBuf>,
    /// How the cached reference manifold is made (when no file is given).
    pub sampler: Sampler,
    /// Folder of cached manifolds (`None`: `$XDG_CACHE_HOME/pegtwin` or `~/.cache/pegtwin`).
    pub cache_dir: Option<PathBuf>,
    /// The ideal cell or the real one, its imperfections drawn from the seed (`[cell]`'s
    /// default ranges).
    pub profile: Profile,
}

impl TrialRequest {
    /// The paper's trial of `geometry` at `clearance_mm`: the manifold method from a partial
    /// insertion, the library's default observation time and offsets (paper V-A), seed 1.
    pub fn new(geometry: &str, clearance_mm: f64) -> Self {
        let defaults = TrialConfig::default();
        let (offset_mm, offset_deg) = default_offsets_mm_deg();
        TrialRequest {
            pair: PairSource::Builtin {
                name: geometry.into(),
                clearance_mm,
            },
            t_obs_s: defaults.t_obs_s,
            method: Method::Manifold,
            start: Start::Partial,
            seed: 1,
            offset_mm,
            offset_deg,
            manifold: None,
            sampler: Sampler::Robot,
            cache_dir: None,
            profile: RealCell::default().profile,
        }
    }

    /// The pair and the trial's settings, every value checked (nothing is built from a value
    /// before it is checked; nothing is written).
    pub fn check(&self) -> Result<(PartPair, TrialConfig)> {
        let (pair, _warnings) = self.pair.load()?;
        let (max_m, max_rad) = MAX_OFFSET;
        for (flag, v, max) in [
            ("--offset-mm", self.offset_mm, max_m * 1e3),
            ("--offset-deg", self.offset_deg, max_rad.to_degrees()),
        ] {
            if !(v >= 0.0 && v <= max) {
                return Err(Error::Input(format!(
                    "{flag} {v}: expected a half-range from 0 to {max:.0}"
                )));
            }
        }
        let (m, a) = (self.offset_mm * 1e-3, self.offset_deg.to_radians());
        let config = TrialConfig {
            method: self.method,
            start: self.start,
            t_obs_s: self.t_obs_s,
            offset_range: [m, m, m, a, a, a],
            ..TrialConfig::for_method(self.method)
        };
        config.ensure_valid()?;
        Ok((pair, config))
    }

    /// Everything the trial needs, from what [`TrialRequest::check`] returned: the robot and,
    /// for the manifold method, the reference manifold (loaded, or built into the cache and
    /// reported to `progress`).
    pub fn prepare(
        &self,
        (pair, config): (PartPair, TrialConfig),
        progress: &dyn BuildProgress,
    ) -> Result<PreparedTrial> {
        let spec = self.pair.robot()?;
        let (robot, _warnings) = spec.load()?;
        let mut params = WorkCellParams::default().placed_for(&spec);
        params.cell.profile = self.profile;
        let pair = params.cell.printed(self.seed, pair)?;
        let manifold = match self.method.registers() {
            true => Some(self.reference_manifold(&pair, &robot, &params, progress)?),
            false => None,
        };
        Ok(PreparedTrial {
            pair,
            robot,
            params,
            config,
            manifold,
            seed: self.seed,
        })
    }

    /// Checks, prepares and runs the trial, unrecorded.
    pub fn run(&self, progress: &dyn BuildProgress) -> Result<TrialResult> {
        self.prepare(self.check()?, progress)?.run(None)
    }

    /// The manifold file given, or the cached one for this pair, built (and cached) when missing.
    fn reference_manifold(
        &self,
        pair: &PartPair,
        robot: &RobotModel,
        params: &WorkCellParams,
        progress: &dyn BuildProgress,
    ) -> Result<Manifold> {
        let Some(path) = &self.manifold else {
            let spec = ManifoldSpec {
                sampler: self.sampler,
                ..ManifoldSpec::default()
            };
            return cache::resolve(
                pair,
                robot,
                &spec,
                params,
                self.cache_dir.as_deref(),
                progress,
            );
        };
        if !file::is_binary(path) && path.extension().is_some_and(|e| e == "csv") {
            return Err(Error::file(
                path,
                format!(
                    "a trial needs a manifold file that records its geometry and clearance; make \
                     one from this CSV with `pegtwin manifold import {} --geometry {} \
                     --clearance-mm {} --out FILE`",
                    path.display(),
                    pair.name,
                    pair.clearance_mm()
                ),
            ));
        }
        let m = file::load(path)?;
        m.check_made_for(pair, path)?;
        Ok(m)
    }
}

/// A checked trial with its inputs at hand.
pub struct PreparedTrial {
    pub pair: PartPair,
    pub robot: RobotModel,
    pub params: WorkCellParams,
    pub config: TrialConfig,
    pub manifold: Option<Manifold>,
    pub seed: u64,
}

impl PreparedTrial {
    /// Runs the trial; `recorder` sees every step (a `--trace`, a `--replay`).
    pub fn run(&self, recorder: Option<&mut dyn Recorder>) -> Result<TrialResult> {
        run_trial(
            &self.pair,
            &self.robot,
            &self.params,
            &self.config,
            self.manifold.as_ref(),
            self.seed,
            recorder,
        )
    }
}

/// The default half-ranges of the hole's offset as people type them: mm, deg (paper V-A).
pub fn default_offsets_mm_deg() -> (f64, f64) {
    let r = TrialConfig::default().offset_range;
    (r[0] * 1e3, r[3].to_degrees())
}
