//! The replays of a campaign (`campaign --replays failures|all|none`): the 3-D replay page of
//! every failed and faulted trial among the first [`FAILURES_UP_TO_TRIAL`] of each cell (all of
//! them in a campaign of the paper's size) and of the first [`SAMPLED_TRIALS`] trials of every
//! cell, in `replays/` of the results folder, linked from `report.html`. A page is 0.3-0.9 MB
//! (the meshes travel in every page, so that each opens alone): the bound keeps a 10 000-trial
//! campaign whose trials mostly fail from writing gigabytes (`--replays all` writes every one).
//!
//! A replay is recorded while its trial runs and written when the trial ends, if the policy wants
//! it; recording reads the cell and commands nothing, so the records are the same with any
//! policy. A page is named `c{cell}-t{trial}-{outcome}.html` (cell and trial indices as in
//! `trials.jsonl`), so the report lists them without reading a record.

use crate::campaign::records::{RecordSource, TrialSet, TrialSpec};
use crate::campaign::scenario::Condition;
use crate::choice::{Choice, Named};
use crate::error::{Error, Result};
use crate::method::manifold::Manifold;
use crate::method::session::Recorder;
use crate::method::trial::TrialResult;
use crate::replay::Replay;
use crate::twin::geometry::PartPair;
use crate::twin::robot::RobotModel;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::sync::Mutex;

/// The folder of a results folder that holds the replays.
pub const REPLAYS_DIR: &str = "replays";
/// Trials of every cell replayed whatever their outcome (the samples of success), from trial 0.
pub const SAMPLED_TRIALS: usize = 2;
/// `--replays failures` replays the failures among the trials of a cell numbered below this.
pub const FAILURES_UP_TO_TRIAL: usize = 50;

/// Which trials of a campaign get a replay.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Replays {
    /// Every failed or faulted trial among the first [`FAILURES_UP_TO_TRIAL`] of each cell, and
    /// the first [`SAMPLED_TRIALS`] of each cell.
    #[default]
    Failures,
    /// Every trial.
    All,
    /// None.
    None,
}

impl Choice for Replays {
    const WHAT: &'static str = "replays";
    const NAMED: &'static [Named<Self>] = &[
        Named {
            name: "failures",
            value: Replays::Failures,
            help: "every failed or faulted trial among the first 50 of each cell, and the first two trials of every cell",
        },
        Named {
            name: "all",
            value: Replays::All,
            help: "every trial",
        },
        Named {
            name: "none",
            value: Replays::None,
            help: "none",
        },
    ];
}

impl Replays {
    /// Whether trial number `trial` of a cell may get a replay (it is recorded only then).
    pub fn may_want(self, trial: usize) -> bool {
        match self {
            Replays::None => false,
            Replays::All => true,
            Replays::Failures => trial < FAILURES_UP_TO_TRIAL.max(SAMPLED_TRIALS),
        }
    }

    /// Whether trial number `trial` of a cell, which ended as `result`, gets a replay. A trial that
    /// raised an error has none (it has no end to show).
    pub fn wants(self, trial: usize, result: &TrialResult) -> bool {
        match self {
            Replays::None => false,
            Replays::All => true,
            Replays::Failures => {
                trial < SAMPLED_TRIALS || !result.success && trial < FAILURES_UP_TO_TRIAL
            }
        }
    }
}

/// The file name of a trial's replay.
pub fn file_name(spec: &TrialSpec, outcome: &str) -> String {
    format!("c{:03}-t{:04}-{outcome}.html", spec.cell, spec.trial)
}

/// A replay in a results folder.
#[derive(Clone, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub struct ReplayLink {
    pub cell: usize,
    pub trial: usize,
    pub outcome: String,
    /// Relative to the results folder.
    pub href: String,
}

/// The replays in results folder `dir`, by cell and trial.
pub fn list(dir: &Path) -> Result<Vec<ReplayLink>> {
    let folder = dir.join(REPLAYS_DIR);
    if !folder.is_dir() {
        return Ok(Vec::new());
    }
    let entries = std::fs::read_dir(&folder)
        .map_err(|e| Error::file(&folder, format!("cannot list: {e}")))?;
    let mut links: Vec<ReplayLink> = entries
        .filter_map(|e| e.ok())
        .filter_map(|e| parse_name(&e.file_name().to_string_lossy()))
        .collect();
    links.sort();
    Ok(links)
}

/// `c{cell}-t{trial}-{outcome}.html`, or None for another file.
fn parse_name(name: &str) -> Option<ReplayLink> {
    let stem = name.strip_suffix(".html")?;
    let mut parts = stem.splitn(3, '-');
    let cell = parts.next()?.strip_prefix('c')?.parse().ok()?;
    let trial = parts.next()?.strip_prefix('t')?.parse().ok()?;
    let outcome = parts.next()?.to_string();
    Some(ReplayLink {
        cell,
        trial,
        outcome,
        href: format!("{REPLAYS_DIR}/{name}"),
    })
}

/// The report's cell-table entry for cell `cell`: how many replays it has, linked to its list.
pub fn cell_link(links: &[ReplayLink], cell: usize) -> String {
    match links.iter().filter(|l| l.cell == cell).count() {
        0 => "-".into(),
        n => format!("<a href=\"#replays-c{cell}\">{n}</a>"),
    }
}

/// The report's list of replays, one line per cell that has any.
pub fn section(links: &[ReplayLink], cells: &[Condition]) -> String {
    if links.is_empty() {
        return String::new();
    }
    let mut html = String::from(
        "<h2>Replays</h2>\n<p>3-D replays (open in a browser): every failed and faulted trial, and the first trials of each cell.</p>\n<ul>\n",
    );
    for (i, cell) in cells.iter().enumerate() {
        let mine: Vec<String> = links
            .iter()
            .filter(|l| l.cell == i)
            .map(|l| {
                format!(
                    "<a href=\"{}\">trial {} ({})</a>",
                    l.href, l.trial, l.outcome
                )
            })
            .collect();
        if !mine.is_empty() {
            html += &format!(
                "<li id=\"replays-c{i}\">{}: {}</li>\n",
                cell.label(),
                mine.join(", ")
            );
        }
    }
    html + "</ul>\n"
}

/// Runs a campaign's trials with their replays recorded, and writes the ones `policy` wants into
/// `out/replays`. A replay that cannot be written does not change its trial's record: the first
/// such error is kept and returned by [`ReplayWriter::finish`] once the trials are done.
pub struct ReplayWriter {
    folder: PathBuf,
    policy: Replays,
    failed: Mutex<Option<Error>>,
}

impl ReplayWriter {
    pub fn new(out: &Path, policy: Replays) -> Self {
        ReplayWriter {
            folder: out.join(REPLAYS_DIR),
            policy,
            failed: Mutex::new(None),
        }
    }

    /// Trial `spec` of a campaign on `pair` and `robot` (with `manifold` for the manifold
    /// method), run by `run` with a recorder when the policy may want its replay (a trial past
    /// the ones it replays runs unrecorded).
    pub fn record(
        &self,
        spec: &TrialSpec,
        (pair, robot, manifold): (&PartPair, &RobotModel, Option<&Manifold>),
        run: impl FnOnce(Option<&mut dyn Recorder>) -> Result<TrialResult>,
    ) -> Result<TrialResult> {
        let mut replay = self.may_want(spec).then(|| Replay::new(pair, robot));
        let result = run(replay.as_mut().map(|r| r as &mut dyn Recorder))?;
        self.keep(spec, replay.as_ref(), &result, manifold);
        Ok(result)
    }

    /// Whether the policy may want the replay of trial `spec` (it is recorded only then).
    pub fn may_want(&self, spec: &TrialSpec) -> bool {
        self.policy.may_want(spec.trial)
    }

    /// Writes `replay`, the recording of trial `spec` that ended as `result`, when the policy
    /// wants it (a failure to write is kept for [`ReplayWriter::finish`]).
    pub fn keep(
        &self,
        spec: &TrialSpec,
        replay: Option<&Replay>,
        result: &TrialResult,
        manifold: Option<&Manifold>,
    ) {
        let Some(replay) = replay.filter(|_| self.policy.wants(spec.trial, result)) else {
            return;
        };
        let path = self.folder.join(file_name(spec, &result.outcome));
        let written = std::fs::create_dir_all(&self.folder)
            .map_err(|e| Error::file(&self.folder, format!("cannot create: {e}")))
            .and_then(|_| replay.write_html(&path, result, manifold));
        if let Err(e) = written {
            self.failed
                .lock()
                .expect("no writer panicked")
                .get_or_insert(e);
        }
    }

    /// The finished trials of `records` (of the campaign whose trials are `specs`) whose replay
    /// the policy wants but the folder lacks, each with the outcome its record names: a run that
    /// could not write them (a full disk), or was killed between a record and its page.
    pub fn missing(
        &self,
        records: &dyn RecordSource,
        specs: &dyn TrialSet,
    ) -> Result<Vec<(TrialSpec, String)>> {
        let mut missing = Vec::new();
        if self.policy == Replays::None {
            return Ok(missing);
        }
        records.for_each(&mut |r| {
            let drawn = r.result.error_message.is_none() && self.policy.wants(r.trial, &r.result);
            let outcome = &r.result.outcome;
            if let Some(spec) = specs
                .spec(r.cell, r.trial)
                .filter(|spec| drawn && !self.folder.join(file_name(spec, outcome)).is_file())
            {
                missing.push((spec, outcome.clone()));
            }
        })?;
        Ok(missing)
    }

    /// The campaign's outcome, or the first replay that could not be written.
    pub fn finish<T>(self, outcome: Result<T>) -> Result<T> {
        let value = outcome?;
        match self.failed.into_inner().expect("no writer panicked") {
            Some(e) => Err(e),
            None => Ok(value),
        }
    }
}

/// Copies the replays of the shard folders `dirs` into the merged folder `out`.
pub fn merge(dirs: &[PathBuf], out: &Path) -> Result<()> {
    for dir in dirs {
        for link in list(dir)? {
            let (from, to) = (dir.join(&link.href), out.join(&link.href));
            let page = std::fs::read(&from)
                .map_err(|e| Error::file(&from, format!("cannot read: {e}")))?;
            let folder = out.join(REPLAYS_DIR);
            std::fs::create_dir_all(&folder)
                .map_err(|e| Error::file(&folder, format!("cannot create: {e}")))?;
            crate::files::write_atomically(&to, &page)?;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::method::config::TrialConfig;
    use crate::method::trial::errored_trial;
    use crate::twin::geometry::{build_builtin, builtin_by_name};
    use crate::twin::workcell::WorkCellParams;

    #[test]
    fn failures_replays_the_first_trials_and_the_early_failures() {
        let pair = build_builtin(builtin_by_name("cross").unwrap(), 1e-3).unwrap();
        let record = |success: bool| {
            let mut r = errored_trial(
                (&pair, 7),
                &WorkCellParams::default(),
                &TrialConfig::default(),
                1,
                String::new(),
            );
            r.success = success;
            r
        };
        let (ok, failed) = (record(true), record(false));
        let p = Replays::Failures;
        assert!(p.wants(0, &ok) && p.wants(1, &ok) && !p.wants(2, &ok));
        assert!(p.wants(2, &failed) && p.wants(49, &failed) && !p.wants(50, &failed));
        assert!(Replays::All.wants(5000, &ok) && !Replays::None.wants(0, &failed));
        assert!(p.may_want(49) && !p.may_want(50) && !Replays::None.may_want(0));
    }

    #[test]
    fn a_replay_name_reads_back() {
        let spec = TrialSpec {
            cell: 3,
            trial: 17,
            seed: 9,
            condition: 0,
        };
        let name = file_name(&spec, "sim_fault");
        assert_eq!(name, "c003-t0017-sim_fault.html");
        let link = parse_name(&name).unwrap();
        assert_eq!(
            (link.cell, link.trial, link.outcome.as_str()),
            (3, 17, "sim_fault")
        );
        assert_eq!(link.href, "replays/c003-t0017-sim_fault.html");
        assert!(parse_name("notes.txt").is_none());
        assert!(parse_name("c1-x2-failure.html").is_none());
    }
}
