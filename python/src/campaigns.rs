//! The campaign commands besides `campaign` itself, for Python: `merge`, `check`, `rerun`,
//! `tune`, and the trials of a range under overridden settings (an outer search's evaluation).
//! Conversions only: each calls the library as the command line does and returns JSON text.

use crate::py_err;
use pegtwin::campaign::check::{Baseline, compare};
use pegtwin::campaign::records::TrialRecord;
use pegtwin::campaign::report;
use pegtwin::campaign::run::{self, RunOptions};
use pegtwin::campaign::scenario::Scenario;
use pegtwin::campaign::summary;
use pegtwin::campaign::tune::{TuneOptions, TuneTarget};
use pegtwin::campaign::tuning::{best, tune_into};
use pegtwin::choice::Choice;
use pegtwin::method::manifold::cache;
use pyo3::prelude::*;
use std::path::PathBuf;

/// The run options of a call without a progress display.
fn quiet_run(cache_dir: Option<PathBuf>) -> PyResult<RunOptions<'static>> {
    Ok(RunOptions {
        cache_dir: cache::folder(cache_dir.as_deref()).map_err(py_err)?,
        progress: &(),
    })
}

/// Joins shard folders into `out` with the report (`pegtwin merge`); returns `out`.
#[pyfunction]
#[pyo3(signature = (dirs, out, resume=false, cache_dir=None))]
pub fn merge(
    py: Python<'_>,
    dirs: Vec<PathBuf>,
    out: PathBuf,
    resume: bool,
    cache_dir: Option<PathBuf>,
) -> PyResult<String> {
    let cache_dir = cache::folder(cache_dir.as_deref()).map_err(py_err)?;
    py.detach(|| {
        let (scenario, trials, _) = run::merge(&dirs, &out, resume)?;
        report::write_campaign_report(&out, &scenario, &trials, &cache_dir)
    })
    .map_err(py_err)?;
    Ok(out.display().to_string())
}

/// The regression gate (`pegtwin check`) as JSON: `{"passed", "findings"}`, or with
/// `write_baseline` the baseline written, `{"written", "cells"}`.
#[pyfunction]
#[pyo3(signature = (dir, baseline=None, write_baseline=None))]
pub fn check_json(
    py: Python<'_>,
    dir: PathBuf,
    baseline: Option<PathBuf>,
    write_baseline: Option<PathBuf>,
) -> PyResult<String> {
    py.detach(|| {
        let (c, trials) = run::read_finished(&dir)?;
        let summary = summary::summarise(&c.scenario, &trials)?;
        if let Some(path) = &write_baseline {
            let json = serde_json::to_vec_pretty(&Baseline::from_summary(&summary))
                .expect("baseline serialises");
            pegtwin::files::write_atomically(path, &json)?;
            let cells = summary.cells.len();
            return Ok(serde_json::json!({"written": path, "cells": cells}).to_string());
        }
        let Some(path) = &baseline else {
            return Err(pegtwin::error::Error::Input(
                "check: give baseline (to hold the run to) or write_baseline".into(),
            ));
        };
        let findings = compare(&summary, &Baseline::load(path)?);
        let passed = !findings.iter().any(|f| f.failed);
        Ok(serde_json::json!({"passed": passed, "findings": findings}).to_string())
    })
    .map_err(py_err)
}

/// One trial of a campaign again (`pegtwin rerun --json`), from a scenario file or a results
/// folder: its record as JSON text.
#[pyfunction]
#[pyo3(signature = (campaign, cell, trial, cache_dir=None))]
pub fn rerun_json(
    py: Python<'_>,
    campaign: PathBuf,
    cell: usize,
    trial: usize,
    cache_dir: Option<PathBuf>,
) -> PyResult<String> {
    let options = quiet_run(cache_dir)?;
    py.detach(|| {
        let scenario = if campaign.is_dir() {
            run::read_campaign(&campaign)?.scenario
        } else {
            Scenario::load(&campaign)?
        };
        let (spec, prepared) = run::single_trial(&scenario, cell, trial, &options)?;
        let plan = run::Plan::new(&scenario, &prepared);
        let result = run::run_one_recorded(&plan, &spec, None)?;
        let record = TrialRecord {
            cell: spec.cell,
            trial: spec.trial,
            result,
        };
        Ok(serde_json::to_string(&record).expect("record serialises"))
    })
    .map_err(py_err)
}

/// Gain tuning (`pegtwin tune`) into `out`: JSON with the folder's `tune.csv` path and the
/// winner's scenario snippet.
#[pyfunction]
#[pyo3(signature = (scenario, out, candidates=None, first_trials=None, seed=None, target="gains", threads=None, cache_dir=None, resume=false))]
#[allow(clippy::too_many_arguments)]
pub fn tune_json(
    py: Python<'_>,
    scenario: PathBuf,
    out: PathBuf,
    candidates: Option<usize>,
    first_trials: Option<usize>,
    seed: Option<u64>,
    target: &str,
    threads: Option<usize>,
    cache_dir: Option<PathBuf>,
    resume: bool,
) -> PyResult<String> {
    let defaults = TuneOptions::default();
    let options = TuneOptions {
        candidates: candidates.unwrap_or(defaults.candidates),
        first_trials: first_trials.unwrap_or(defaults.first_trials),
        seed: seed.unwrap_or(defaults.seed),
        target: TuneTarget::by_name(target).map_err(py_err)?,
    };
    let scenario = Scenario::load(&scenario).map_err(py_err)?;
    let pool = run::worker_pool(threads).map_err(py_err)?;
    let run = quiet_run(cache_dir)?;
    py.detach(|| {
        let evals = pool.install(|| {
            tune_into(
                &scenario,
                &options,
                &run,
                &out,
                resume,
                &|_| {},
                &|_, _, _| {},
            )
        })?;
        let snippet = best(&evals).candidate.snippet(&scenario);
        let csv = out.join("tune.csv");
        Ok(serde_json::json!({"csv": csv, "snippet": snippet}).to_string())
    })
    .map_err(py_err)
}

/// The trials `start..stop` of every cell of the scenario with the TOML `overrides` laid over
/// it ([`Scenario::load_with`]): the records as JSON lines, cell-major. Every call meets the same
/// seeds, so candidates of an outer search (Optuna's) are compared on the same hole offsets.
#[pyfunction]
#[pyo3(signature = (scenario, overrides, start, stop, threads=None, cache_dir=None))]
pub fn evaluate_json(
    py: Python<'_>,
    scenario: PathBuf,
    overrides: &str,
    start: usize,
    stop: usize,
    threads: Option<usize>,
    cache_dir: Option<PathBuf>,
) -> PyResult<String> {
    let scenario = Scenario::load_with(&scenario, overrides).map_err(py_err)?;
    let pool = run::worker_pool(threads).map_err(py_err)?;
    let run = quiet_run(cache_dir)?;
    let records = py
        .detach(|| pool.install(|| run::run_trial_range(&scenario, start..stop, &run)))
        .map_err(py_err)?;
    let lines: Vec<String> = (records.iter())
        .map(|r| serde_json::to_string(r).expect("record serialises"))
        .collect();
    Ok(lines.join("\n"))
}
