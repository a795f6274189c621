//! `pegtwin calibrate` (issue 46; docs/calibration.md): the `[cell]` values of a real cell fitted
//! to figures measured on it, and the figures held out predicted, each with its interval.
//!
//! A Latin hypercube of draws over the free values' uniform prior ([`targets`]); at each draw, a
//! campaign of the cells the targets read, on the scenario's own trial seeds (every draw meets
//! the same hole offsets: common random numbers). Each figure's values over the draws are fitted
//! as a smooth function of the free values ([`surrogate`]), and a dense hypercube of the prior
//! weighted by the likelihood of the fitted figures there ([`inference`]) is the posterior; every
//! figure's posterior predictive says where a real run of the measured size would fall. The folder keeps each draw's figures as it finishes (`evaluations.jsonl`), so a
//! killed calibration resumes (`--resume`) to the same posterior.

pub mod inference;
mod report;
pub mod surrogate;
pub mod targets;

use crate::campaign::records::{TrialRecord, TrialSet, TrialSpec};
use crate::campaign::run::{CampaignTrials, Plan, RunOptions, Shard, prepare, run_trials};
use crate::campaign::scenario::{Condition, Scenario};
use crate::campaign::summary::{CellSummary, summarise};
use crate::campaign::tune::latin_hypercube;
use crate::error::{Error, Result};
use inference::Predictive;
use serde::{Deserialize, Serialize};
use std::io::{BufRead, Write};
use std::path::Path;
use surrogate::{Prediction, Simulated, Surrogate};
use targets::{Figure, Role, Targets, TargetsFile};

/// The calibration's description in its folder.
pub const CALIBRATION_FILE: &str = "calibration.json";
/// One line per finished draw.
pub const EVALUATIONS_FILE: &str = "evaluations.jsonl";
/// How many points of the prior the posterior weighs.
pub const POSTERIOR_POINTS: usize = 2048;
/// A fitted figure whose measured value lies further out than this two-sided tail of its
/// posterior predictive is one no value in the prior reaches.
pub const UNREACHABLE_TAIL: f64 = 0.002;

/// What `calibration.json` holds: the scenario's fingerprint, the targets as read, the draws.
#[derive(Debug, PartialEq, Serialize, Deserialize)]
struct CalibrationFile {
    fingerprint: String,
    targets: TargetsFile,
    /// The free values at each draw, in the order of `targets.free`.
    draws: Vec<Vec<f64>>,
}

/// One draw's figures (a line of `evaluations.jsonl`).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Evaluation {
    pub draw: usize,
    pub values: Vec<f64>,
    /// What the twin gave for each target, in the targets' order.
    pub figures: Vec<Simulated>,
}

/// A calibration's options.
#[derive(Clone, Copy, Debug)]
pub struct CalibrateOptions {
    pub resume: bool,
    /// The most trials the calibration may run in all (draws x trials per draw).
    pub max_trials: usize,
}

/// The posterior and the figures' predictions.
#[derive(Clone, Debug, Serialize)]
pub struct Posterior {
    pub free: Vec<&'static str>,
    pub prior: Vec<[f64; 2]>,
    /// Each free value's 5 %, 50 % and 95 % posterior quantiles.
    pub quantiles: Vec<[f64; 3]>,
    /// The effective number of points behind the weights (Kish).
    pub effective_points: f64,
    /// The draws the twin ran.
    pub evaluations: Vec<Evaluation>,
    /// The points of the prior the posterior weighs, and their weights.
    pub points: Vec<Vec<f64>>,
    pub weights: Vec<f64>,
    /// Each target's posterior predictive (`None`: the twin gave the figure at no draw).
    pub predictive: Vec<Option<Predictive>>,
    /// The fitted targets (indices) that no value in the prior reaches.
    pub unreachable: Vec<usize>,
    pub trials_per_draw: usize,
}

/// Calibrates `scenario`'s `[cell]` to `targets` in folder `out` (see the module doc), telling
/// `on_draw` each draw as it finishes (done, of all).
pub fn calibrate(
    scenario: &Scenario,
    targets: &Targets,
    out: &Path,
    options: CalibrateOptions,
    run: &RunOptions,
    on_draw: &(dyn Fn(usize, usize) + Sync),
) -> Result<Posterior> {
    let cells = cells_read(scenario, targets);
    let trials_per_draw = cells.len() * scenario.trials;
    let draws = draws(targets);
    let needed = draws.len().saturating_mul(trials_per_draw);
    if needed > options.max_trials {
        return Err(Error::Input(format!(
            "--max-trials {}: the calibration runs {} draws x {trials_per_draw} trials ({} cells x \
             {} trials) = {needed}; lower `samples` in the targets file or `trials` in the \
             scenario, or raise --max-trials",
            options.max_trials,
            draws.len(),
            cells.len(),
            scenario.trials
        )));
    }
    let described = CalibrationFile {
        fingerprint: scenario.fingerprint(),
        targets: targets.file.clone(),
        draws,
    };
    let mut done = open_folder(out, &described, options.resume)?;
    let path = out.join(EVALUATIONS_FILE);
    let mut file = std::fs::OpenOptions::new()
        .create(true)
        .append(true)
        .open(&path)
        .map_err(|e| Error::file(&path, format!("cannot open for appending: {e}")))?;
    for (i, values) in described.draws.iter().enumerate().skip(done.len()) {
        let evaluation = evaluate(scenario, targets, &cells, (i, values), run)?;
        let mut line = serde_json::to_string(&evaluation).expect("an evaluation serialises");
        line.push('\n');
        file.write_all(line.as_bytes())
            .and_then(|_| file.flush())
            .map_err(|e| Error::file(&path, format!("cannot append: {e}")))?;
        done.push(evaluation);
        on_draw(done.len(), described.draws.len());
    }
    let posterior = posterior(targets, done, trials_per_draw);
    report::write(out, scenario, targets, &posterior)?;
    Ok(posterior)
}

/// The draws: a Latin hypercube over the priors, seeded by the targets file.
fn draws(targets: &Targets) -> Vec<Vec<f64>> {
    hypercube(targets, targets.file.samples, targets.file.seed)
}

/// `n` points of a Latin hypercube over the priors.
fn hypercube(targets: &Targets, n: usize, seed: u64) -> Vec<Vec<f64>> {
    latin_hypercube(n, targets.free.len(), seed)
        .into_iter()
        .map(|u| {
            (targets.free.iter().zip(u))
                .map(|(f, u)| f.prior[0] + u * (f.prior[1] - f.prior[0]))
                .collect()
        })
        .collect()
}

/// `values` scaled to [0, 1] over their priors.
fn scaled(targets: &Targets, values: &[f64]) -> Vec<f64> {
    (targets.free.iter().zip(values))
        .map(|(f, v)| (v - f.prior[0]) / (f.prior[1] - f.prior[0]))
        .collect()
}

/// The cells of the scenario some target's row reads, in the scenario's order.
fn cells_read(scenario: &Scenario, targets: &Targets) -> Vec<usize> {
    let empty = crate::campaign::summary::SummaryTally::new(scenario).finish(scenario);
    let rows: Vec<&Condition> = (targets.targets.iter())
        .filter_map(|t| targets::row_of(&empty, &t.target).ok())
        .map(|r| &r.cell)
        .collect();
    let in_row = |c: &Condition, r: &Condition| {
        c.method == r.method
            && c.t_obs_s == r.t_obs_s
            && (r.geometry == "all" || r.geometry == c.geometry)
            && (r.clearance_mm == 0.0 || r.clearance_mm == c.clearance_mm)
    };
    (scenario.cells().iter().enumerate())
        .filter(|(_, c)| rows.iter().any(|r| in_row(c, r)))
        .map(|(i, _)| i)
        .collect()
}

/// Checks the folder: new or empty (then `calibration.json` is written), or, with `resume`, one
/// holding this calibration; returns the draws it finished (a last line cut by a kill dropped).
fn open_folder(out: &Path, described: &CalibrationFile, resume: bool) -> Result<Vec<Evaluation>> {
    let path = out.join(CALIBRATION_FILE);
    if !resume {
        crate::campaign::run::ensure_new_or_empty(
            out,
            "calibrate writes into new folders only (or --resume)",
        )?;
        std::fs::create_dir_all(out)
            .map_err(|e| Error::file(out, format!("cannot create: {e}")))?;
        let json = serde_json::to_vec_pretty(described).expect("a calibration serialises");
        crate::files::write_atomically(&path, &json)?;
        return Ok(Vec::new());
    }
    let text = crate::files::read_text(&path)?;
    let existing: CalibrationFile = serde_json::from_str(&text)
        .map_err(|e| Error::file(&path, format!("not a calibration file: {e}")))?;
    if existing != *described {
        return Err(Error::file(
            &path,
            "holds another calibration (its scenario, targets or draws differ): choose another --out",
        ));
    }
    read_evaluations(&out.join(EVALUATIONS_FILE), described)
}

/// The finished draws of `path`, in order, each checked against its draw; a last line cut short
/// by a kill is dropped (and the file cut to its whole lines).
fn read_evaluations(path: &Path, described: &CalibrationFile) -> Result<Vec<Evaluation>> {
    if !path.exists() {
        return Ok(Vec::new());
    }
    let (file, size) = crate::files::open_input(path, u64::MAX)?;
    let mut done: Vec<Evaluation> = Vec::new();
    let mut whole = 0u64;
    for (n, line) in std::io::BufReader::new(file).split(b'\n').enumerate() {
        let line = line.map_err(|e| Error::file(path, format!("cannot read: {e}")))?;
        if whole + line.len() as u64 >= size {
            break; // the last line, with no newline: cut short by a kill, dropped below
        }
        match serde_json::from_slice::<Evaluation>(&line) {
            Ok(e)
                if e.draw == done.len()
                    && described.draws.get(e.draw) == Some(&e.values)
                    && e.figures.len() == described.targets.targets.len()
                    && (e.figures.iter().zip(&described.targets.targets))
                        .all(|(f, t)| f.fits(t.figure)) =>
            {
                whole += line.len() as u64 + 1;
                done.push(e);
            }
            _ => {
                return Err(Error::file(
                    path,
                    format!(
                        "line {}: not draw {} of this calibration",
                        n + 1,
                        done.len()
                    ),
                ));
            }
        }
    }
    std::fs::OpenOptions::new()
        .write(true)
        .open(path)
        .and_then(|f| f.set_len(whole))
        .map_err(|e| Error::file(path, format!("cannot repair: {e}")))?;
    Ok(done)
}

/// The twin's figures at draw `values`: the scenario with the free values set, its `cells` run on
/// their trial seeds, summarised.
fn evaluate(
    scenario: &Scenario,
    targets: &Targets,
    cells: &[usize],
    (draw, values): (usize, &[f64]),
    run: &RunOptions,
) -> Result<Evaluation> {
    let mut s = scenario.clone();
    for (f, v) in targets.free.iter().zip(values) {
        f.value.set(&mut s.cell, *v);
    }
    s.ensure_valid()?;
    let prepared = prepare(&s, cells, run)?;
    let all = CampaignTrials::of(&s, Shard::WHOLE);
    let specs: Vec<TrialSpec> = (cells.iter())
        .flat_map(|&c| {
            (0..s.trials)
                .filter_map(|t| all.spec(c, t))
                .collect::<Vec<_>>()
        })
        .collect();
    let records: Vec<TrialRecord> = run_trials(&Plan::new(&s, &prepared), &specs);
    let summary = summarise(&s, &records)?;
    let figures = (targets.targets.iter())
        .map(|t| {
            targets::row_of(&summary, &t.target)
                .map(|row| simulated(row, t.target.figure))
                .unwrap_or(Simulated::Missing)
        })
        .collect();
    Ok(Evaluation {
        draw,
        values: values.to_vec(),
        figures,
    })
}

/// A row's figure as the twin gave it.
fn simulated(row: &CellSummary, figure: Figure) -> Simulated {
    let axis = |i: usize| match (row.mae, row.abs_error_std) {
        (Some(mae), Some(std)) => Simulated::Mean {
            mean: mae[i],
            std: std[i],
            m: row.trials - row.error_trials,
        },
        _ => Simulated::Missing,
    };
    let force = |f: Option<crate::campaign::summary::MeanStd>| {
        f.map_or(Simulated::Missing, |f| Simulated::Mean {
            mean: f.mean,
            std: f.std,
            m: f.n,
        })
    };
    match figure {
        Figure::Success => Simulated::Count {
            s: row.successes,
            m: row.trials,
        },
        Figure::MaeXMm => axis(0),
        Figure::MaeYMm => axis(1),
        Figure::MaeZMm => axis(2),
        Figure::MaeRollDeg => axis(3),
        Figure::MaePitchDeg => axis(4),
        Figure::MaeYawDeg => axis(5),
        Figure::PeakFzSuccessN => force(row.peak_fz_success_n),
        Figure::PeakFzFailureN => force(row.peak_fz_failure_n),
    }
}

/// The posterior from the finished draws: a surrogate of each figure over the draws, the dense
/// points of the prior weighted by the fitted figures' likelihood there ([`inference`]).
fn posterior(targets: &Targets, evaluations: Vec<Evaluation>, trials_per_draw: usize) -> Posterior {
    let u: Vec<Vec<f64>> = evaluations
        .iter()
        .map(|e| scaled(targets, &e.values))
        .collect();
    let surrogates: Vec<Option<Surrogate>> = (0..targets.targets.len())
        .map(|k| {
            let sims: Vec<Simulated> = evaluations.iter().map(|e| e.figures[k]).collect();
            Surrogate::fit(&u, &sims)
        })
        .collect();
    let points = hypercube(targets, POSTERIOR_POINTS, targets.file.seed ^ POINTS_STREAM);
    let predicted: Vec<Vec<Option<Prediction>>> = (points.iter())
        .map(|p| {
            let u = scaled(targets, p);
            surrogates
                .iter()
                .map(|s| s.as_ref().map(|s| s.at(&u)))
                .collect()
        })
        .collect();
    let ln_w: Vec<f64> = (predicted.iter())
        .map(|at| {
            (targets.targets.iter().zip(at))
                .filter(|(t, _)| t.target.role == Role::Fit)
                .map(|(t, p)| {
                    p.map_or(f64::NEG_INFINITY, |p| {
                        inference::ln_likelihood(&t.measured, &p)
                    })
                })
                .sum()
        })
        .collect();
    let weights = inference::normalise(&ln_w);
    let quantiles = (0..targets.free.len())
        .map(|j| {
            let v: Vec<f64> = points.iter().map(|p| p[j]).collect();
            [0.05, 0.5, 0.95].map(|q| inference::weighted_quantile(&v, &weights, q))
        })
        .collect();
    let predictive: Vec<Option<Predictive>> = (targets.targets.iter().enumerate())
        .map(|(k, t)| {
            let at: Option<Vec<Prediction>> = predicted.iter().map(|p| p[k]).collect();
            at.filter(|_| weights.iter().any(|w| *w > 0.0))
                .map(|at| inference::predictive(&t.measured, &at, &weights))
        })
        .collect();
    let unreachable = (targets.targets.iter().enumerate())
        .filter(|(k, t)| {
            t.target.role == Role::Fit && predictive[*k].is_none_or(|p| p.tail < UNREACHABLE_TAIL)
        })
        .map(|(k, _)| k)
        .collect();
    Posterior {
        free: targets.free.iter().map(|f| f.value.name()).collect(),
        prior: targets.free.iter().map(|f| f.prior).collect(),
        quantiles,
        effective_points: inference::effective_draws(&weights),
        evaluations,
        points,
        weights,
        predictive,
        unreachable,
        trials_per_draw,
    }
}

/// Seeds the posterior's points apart from the draws.
const POINTS_STREAM: u64 = 0x9e37_79b9_7f4a_7c15;

/// The scenario's `[cell]` with each free value's range set to its posterior 90 % range (the
/// encoder offsets' half-range, one number, to its posterior median), as a TOML section a
/// scenario can take.
pub fn calibrated_cell(scenario: &Scenario, targets: &Targets, posterior: &Posterior) -> String {
    let mut cell = scenario.cell.clone();
    for (f, q) in targets.free.iter().zip(&posterior.quantiles) {
        f.value.set_calibrated(&mut cell, *q);
    }
    #[derive(Serialize)]
    struct Section<'a> {
        cell: &'a crate::twin::real_cell::RealCell,
    }
    toml::to_string(&Section { cell: &cell }).expect("a cell serialises")
}
