//! `pegtwin tune` as one call, for the command line and Python alike: the search
//! ([`crate::campaign::tune`]) with its journal in the output folder, then its table and plot.

use crate::campaign::report;
use crate::campaign::run::{RunOptions, ensure_new_or_empty};
use crate::campaign::scenario::Scenario;
use crate::campaign::tune::{Evaluation, TuneJournal, TuneOptions, evaluations_csv, tune};
use crate::error::{Error, Result};
use std::path::Path;

/// Runs the search `options` on `scenario` into the folder `out` (new or empty; with `resume`,
/// one a killed search left), keeping each evaluation in its journal as it finishes, then writes
/// `tune.csv` and `figures/tune.png`. `on_resume` is told how many evaluations the journal held,
/// `on_rung` each rung's size. Returns every evaluation, rung by rung, best first in a rung.
pub fn tune_into(
    scenario: &Scenario,
    options: &TuneOptions,
    run: &RunOptions,
    out: &Path,
    resume: bool,
    on_resume: &dyn Fn(usize),
    on_rung: &dyn Fn(usize, usize, usize),
) -> Result<Vec<Evaluation>> {
    if !resume {
        ensure_new_or_empty(out, "tune writes into new folders only, unless --resume")?;
    }
    std::fs::create_dir_all(out).map_err(|e| Error::file(out, format!("cannot create: {e}")))?;
    let journal = TuneJournal::open(out, scenario, options, resume)?;
    if !journal.is_empty() {
        on_resume(journal.len());
    }
    let evals = tune(scenario, options, run, on_rung, Some(&journal))?;
    report::write_tune(out, &evals)?;
    crate::files::write_atomically(&out.join("tune.csv"), &evaluations_csv(&evals))?;
    Ok(evals)
}

/// The winner: the best evaluation of the last rung.
pub fn best(evals: &[Evaluation]) -> &Evaluation {
    let last_rung = evals.last().map_or(0, |e| e.rung);
    (evals.iter())
        .find(|e| e.rung == last_rung)
        .expect("a search evaluates at least one candidate")
}
