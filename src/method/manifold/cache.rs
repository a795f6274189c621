//! The on-disk cache of reference manifolds: built once per pair and generator settings, reused
//! by every trial and campaign (`$XDG_CACHE_HOME/pegtwin`, else `~/.cache/pegtwin`).
//!
//! A cached file is named `{geometry}-{clearance}mm-{key}.manifold`, where `key` is a checksum of
//! everything that decides its content (sampler, points, seed, cell and physics parameters), so a
//! change of any of them builds a new file instead of reusing a stale one. Files are written
//! atomically, so concurrent builders (shards on one machine) cannot leave a half-written file.

use super::Manifold;
use super::build::{SamplerConfig, build};
use super::file;
use crate::error::{Error, Result};
use crate::method::trial::check_manifold;
use crate::twin::cell::CellParams;
use crate::twin::geometry::PartPair;
use crate::twin::robot::RobotModel;
use std::path::{Path, PathBuf};

/// What a reference manifold is made from.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Recipe<'a> {
    pub sampler: &'a SamplerConfig,
    /// Points kept after downsampling.
    pub points: usize,
    pub seed: u64,
    pub params: &'a CellParams,
}

impl Recipe<'_> {
    /// The checksum that names the cached file.
    pub fn key(&self) -> String {
        let json = serde_json::to_string(&(self, &self.params.physics)).expect("recipe serialises");
        format!("{:08x}", crc32fast::hash(json.as_bytes()))
    }
}

/// The default cache folder.
pub fn default_dir() -> Result<PathBuf> {
    if let Some(x) = std::env::var_os("XDG_CACHE_HOME").filter(|v| !v.is_empty()) {
        return Ok(Path::new(&x).join("pegtwin"));
    }
    std::env::var_os("HOME")
        .map(|h| Path::new(&h).join(".cache").join("pegtwin"))
        .ok_or_else(|| {
            Error::Input("no cache folder: set --cache-dir, XDG_CACHE_HOME or HOME".into())
        })
}

/// Where the manifold of `pair` made by `recipe` is cached in `dir`.
pub fn path(dir: &Path, pair: &PartPair, recipe: &Recipe) -> PathBuf {
    dir.join(format!(
        "{}-{}mm-{}.manifold",
        pair.name,
        pair.clearance_m * 1e3,
        recipe.key()
    ))
}

/// The cached manifold of `pair`, built and cached first when missing. `progress` shows a bar.
pub fn load_or_build(
    pair: &PartPair,
    robot: &RobotModel,
    recipe: &Recipe,
    dir: &Path,
    progress: bool,
) -> Result<Manifold> {
    let path = path(dir, pair, recipe);
    if path.is_file() {
        let m = file::load(&path)?;
        check_manifold(&m, pair, &path)?;
        return Ok(m);
    }
    std::fs::create_dir_all(dir)
        .map_err(|e| Error::file(dir, format!("cannot create the cache folder: {e}")))?;
    if progress {
        eprintln!(
            "building the reference manifold of {} at {} mm into {} (once)",
            pair.name,
            pair.clearance_m * 1e3,
            path.display()
        );
    }
    let bar = if progress {
        indicatif::ProgressBar::new(recipe.sampler.episodes as u64)
    } else {
        indicatif::ProgressBar::hidden()
    };
    let report = build(
        pair,
        robot,
        recipe.params,
        recipe.sampler,
        recipe.points,
        recipe.seed,
        &|| bar.inc(1),
    )?;
    bar.finish_and_clear();
    file::save(&report.manifold, &path)?;
    Ok(report.manifold)
}
