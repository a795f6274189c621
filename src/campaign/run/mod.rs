//! Campaigns: every trial of a scenario, in parallel, into a results folder that survives kills,
//! splits into shards and merges back.
//!
//! Reproducibility. A trial's seed derives from (scenario seed, geometry, clearance, trial index)
//! only — not from the method or t_obs, so every cell of a pair sees the same hole offsets
//! (common random numbers: the methods are compared on the same draws) — and not from the
//! thread, the shard or the order of completion. A trial is a pure function of its seed and the
//! scenario, so `trials.jsonl` is the same for any `--threads`, any sharding, and after
//! `--resume`.
//!
//! The folder. `campaign.json` holds the scenario, its fingerprint and the shard; `trials.jsonl`
//! one JSON record per trial, appended and flushed as each trial finishes, then rewritten in
//! (cell, trial) order once the run is complete. A kill can only cut the last line short;
//! `--resume` drops that line, keeps the finished trials and runs the rest.

mod folder;
mod trials;

pub use folder::{
    CAMPAIGN_FILE, CampaignFile, Shard, TRIALS_FILE, ensure_new_or_empty, merge, read_campaign,
    read_finished,
};
use folder::{check_folder, create_folder};
pub use trials::{CampaignTrials, trial_seed};

use crate::campaign::records::{
    TrialRecord, TrialSet, TrialSpec, TrialsFile, check_complete, check_entries_belong,
    index_records, write_sorted,
};
use crate::campaign::replays::{ReplayWriter, Replays};
use crate::campaign::scenario::{Condition, PlannedCell, Scenario};
use crate::campaign::sharing::share_observations;
use crate::error::{Error, Result};
use crate::method::config::{Start, TrialConfig};
use crate::method::manifold::Manifold;
use crate::method::manifold::cache::{self, BuildProgress, Wanted};
use crate::method::session::Recorder;
use crate::method::trial::{ObservingTrial, TrialResult, errored_trial, finish_trial, run_trial};
use crate::replay::Replay;
use crate::schedule;
use crate::twin::geometry::PartPair;
use crate::twin::robot::RobotModel;
use std::collections::{BTreeMap, BTreeSet};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

/// What a campaign reports while it runs, for a progress display (the library prints nothing).
pub trait CampaignProgress: BuildProgress {
    /// `total` trials are wanted, `done` of them were already there.
    fn trials_started(&self, _total: usize, _done: usize) {}
    /// One more trial finished.
    fn trial_done(&self) {}
    /// The trials finished (or the run failed).
    fn trials_finished(&self) {}
    /// True once the user wants the run stopped: no trial starts after it, the trials running
    /// finish and are kept, and the campaign ends with [`Error::Stopped`] (`--resume` completes it).
    fn should_stop(&self) -> bool {
        false
    }
}

/// No progress display.
impl CampaignProgress for () {}

/// Where a campaign's manifolds are cached and whom to tell how it goes.
pub struct RunOptions<'a> {
    pub cache_dir: PathBuf,
    pub progress: &'a dyn CampaignProgress,
}

/// The most worker threads a run starts (a few hundred cores is the largest node in use).
pub const MAX_THREADS: usize = 512;

/// The pool a run's trials go to: `threads` workers (`None`: one per core), 1 to [`MAX_THREADS`].
pub fn worker_pool(threads: Option<usize>) -> Result<rayon::ThreadPool> {
    if let Some(n) = threads
        && !(1..=MAX_THREADS).contains(&n)
    {
        return Err(Error::Input(format!(
            "--threads {n}: expected 1 to {MAX_THREADS}"
        )));
    }
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads.unwrap_or(0))
        .build()
        .map_err(|e| Error::Input(format!("cannot start the worker threads: {e}")))
}

/// The pairs, their robots and the reference manifolds the given trials need.
pub struct Prepared {
    pairs: BTreeMap<(String, u64), PartPair>,
    robots: BTreeMap<(String, u64), RobotModel>,
    manifolds: BTreeMap<(String, u64), Manifold>,
}

fn pair_key(cell: &Condition) -> (String, u64) {
    (cell.geometry.clone(), cell.clearance_mm.to_bits())
}

/// What a campaign's trials run from, resolved once: the scenario's cells with their settings
/// and parameters ([`Scenario::plan`]), and the pairs, robots and manifolds [`prepare`]d for them.
/// Tuning runs several plans (one per candidate's gains) on one preparation.
pub struct Plan<'a> {
    cells: Vec<PlannedCell>,
    prepared: &'a Prepared,
}

impl<'a> Plan<'a> {
    /// The plan of `scenario` on `prepared` (prepared for this scenario's pairs).
    pub fn new(scenario: &Scenario, prepared: &'a Prepared) -> Self {
        Plan {
            cells: scenario.plan(),
            prepared,
        }
    }

    /// A plan of `cells` (from one scenario or several) on `prepared` (prepared for their pairs).
    pub fn of_cells(cells: Vec<PlannedCell>, prepared: &'a Prepared) -> Self {
        Plan { cells, prepared }
    }

    /// Campaign cell `cell`.
    pub fn cell(&self, cell: usize) -> &PlannedCell {
        &self.cells[cell]
    }

    /// The pair of cell `cell`, its robot and its reference manifold (when its method registers).
    pub fn inputs(&self, cell: usize) -> (&'a PartPair, &'a RobotModel, Option<&'a Manifold>) {
        self.prepared.inputs(&self.cells[cell].condition)
    }
}

impl Prepared {
    /// The pair of `cell`, its robot and its reference manifold (when its method registers).
    fn inputs(&self, cell: &Condition) -> (&PartPair, &RobotModel, Option<&Manifold>) {
        let key = pair_key(cell);
        (
            &self.pairs[&key],
            &self.robots[&key],
            self.manifolds.get(&key),
        )
    }
}

/// Builds the pairs and loads (or builds and caches) the manifolds of the cells numbered
/// `cells` (in the scenario's cell order). The missing
/// manifolds are built side by side ([`cache::resolve_all`]: every episode of every build goes to
/// the one pool, the costliest pair's first, so the cores do not idle at the end of each build
/// while its last episodes run; issue 17). Each file is the same as when built alone; when builds
/// fail, the first failing pair's error (in the scenario's order) is returned, after the others
/// were built and cached.
pub fn prepare(scenario: &Scenario, cells: &[usize], options: &RunOptions) -> Result<Prepared> {
    let conditions = scenario.cells();
    let mut pairs = BTreeMap::new();
    let mut robots = BTreeMap::new();
    let mut registering = Vec::new();
    for &c in cells {
        let cell = &conditions[c];
        let key = pair_key(cell);
        if !pairs.contains_key(&key) {
            pairs.insert(key.clone(), scenario.pair(cell)?);
            robots.insert(key.clone(), scenario.robot(cell).load()?.0);
        }
        if cell.method.registers() && !registering.iter().any(|(k, _)| *k == key) {
            registering.push((key, scenario.work_cell_params_for(cell)));
        }
    }
    let wanted: Vec<Wanted> = (registering.iter())
        .map(|(key, params)| Wanted {
            pair: &pairs[key],
            robot: &robots[key],
            params: params.clone(),
        })
        .collect();
    let built = cache::resolve_all(
        &wanted,
        &scenario.manifold,
        &options.cache_dir,
        options.progress,
    );
    let mut manifolds = BTreeMap::new();
    for ((key, _), manifold) in registering.into_iter().zip(built) {
        manifolds.insert(key, manifold?);
    }
    Ok(Prepared {
        pairs,
        robots,
        manifolds,
    })
}

/// Every reference manifold the cells of `scenario` need, loaded from the cache folder or built
/// into it, as [`prepare`] does for the whole campaign: a job array's shards then find them
/// ready instead of each building the same files. Returns how many there are.
pub fn build_manifolds(scenario: &Scenario, options: &RunOptions) -> Result<usize> {
    let cells: Vec<usize> = (0..scenario.cells().len()).collect();
    Ok(prepare(scenario, &cells, options)?.manifolds.len())
}

/// The trials numbered `trials` (from 0, as in `trials.jsonl`) of every cell of `scenario`, run
/// on the current rayon pool: each the campaign's record of that trial, bit for bit (a trial is
/// a pure function of its seed and the scenario), so that candidates of an outer search (gains
/// overridden, [`Scenario::load_with`]) meet the same seeds. In cell-major order.
pub fn run_trial_range(
    scenario: &Scenario,
    trials: std::ops::Range<usize>,
    options: &RunOptions,
) -> Result<Vec<TrialRecord>> {
    if trials.is_empty() || trials.end > scenario.trials {
        return Err(Error::Input(format!(
            "trials {}..{}: expected a non-empty range within the scenario's {} trials per cell",
            trials.start, trials.end, scenario.trials
        )));
    }
    let all = CampaignTrials::of(scenario, Shard::WHOLE);
    let specs: Vec<TrialSpec> = (0..all.cells())
        .flat_map(|cell| trials.clone().map(move |t| (cell, t)))
        .filter_map(|(cell, t)| all.spec(cell, t))
        .collect();
    let cells: Vec<usize> = (0..all.cells()).collect();
    let prepared = prepare(scenario, &cells, options)?;
    Ok(run_trials(&Plan::new(scenario, &prepared), &specs))
}

/// One trial of a scenario, ready to run on its own as its campaign runs it: cell `cell` and trial
/// `trial`, numbered from 0 as in `trials.jsonl`. Only that trial's pair is prepared (its
/// manifold loaded from the cache, or built into it). Its record is the campaign's, bit for bit:
/// a trial is a pure function of its seed and the scenario (module docs).
pub fn single_trial(
    scenario: &Scenario,
    cell: usize,
    trial: usize,
    options: &RunOptions,
) -> Result<(TrialSpec, Prepared)> {
    let trials = CampaignTrials::of(scenario, Shard::WHOLE);
    if cell >= trials.cells() {
        return Err(Error::Input(format!(
            "--cell {cell}: the scenario has {} cells, numbered from 0 as in trials.jsonl",
            trials.cells()
        )));
    }
    let Some(spec) = trials.spec(cell, trial) else {
        return Err(Error::Input(format!(
            "--trial {trial}: the scenario runs {} trials per cell, numbered from 0 as in trials.jsonl",
            scenario.trials
        )));
    };
    let prepared = prepare(scenario, &[cell], options)?;
    Ok((spec, prepared))
}

/// Runs one trial of a campaign (the real one is [`run_one`]; a test may inject another).
pub(crate) type RunOne<'a> = dyn Fn(&Plan, &TrialSpec) -> Result<TrialResult> + Sync + 'a;

/// Runs `trials` in parallel on the current rayon pool and returns their records in the order of
/// `trials` (for `tune`, `calibrate` and `evaluate`, which keep them; a campaign streams them
/// instead, see [`stream_trials_with`]). Trials that observe alike share their observation, as
/// in a campaign, with no replays: each record is the one its trial gives alone, bit for bit. A
/// trial that raises an error or panics is recorded with outcome `error` and its message, and
/// the others go on.
pub fn run_trials(plan: &Plan, trials: &[TrialSpec]) -> Vec<TrialRecord> {
    let no_replays = ReplayWriter::new(Path::new(""), Replays::None);
    let runner = Runner {
        one: &run_one,
        sharing: Some(&no_replays),
    };
    let done = Mutex::new(Vec::with_capacity(trials.len()));
    let keep = |r: &TrialRecord| {
        done.lock().expect("no collector panicked").push(r.clone());
        Ok(())
    };
    stream_trials_with(plan, trials, &runner, &(), &keep)
        .expect("trials are not stopped and their errors are recorded");
    let order: BTreeMap<(usize, usize), usize> = (trials.iter().enumerate())
        .map(|(i, t)| ((t.cell, t.trial), i))
        .collect();
    let mut records = done.into_inner().expect("no collector panicked");
    records.sort_by_key(|r| order[&(r.cell, r.trial)]);
    records
}

/// How a campaign runs its trials.
pub(crate) struct Runner<'a> {
    /// Runs one trial by itself.
    pub one: &'a RunOne<'a>,
    /// With `Some`, the trials of a seed that observe alike share their observation
    /// ([`crate::campaign::sharing`]) and record their replays here; with `None` (a test that
    /// injects its own `one`), every trial runs alone.
    pub sharing: Option<&'a ReplayWriter>,
}

/// Runs `trials` in parallel and hands each record to `on_done` as it finishes (from any thread),
/// keeping none: memory stays flat however many trials a campaign runs. Trials that observe
/// alike run their observation once ([`run_shared`]), as one piece of work; the pieces start in
/// the trials' order, round by round, the longest of each round first ([`piece_cost`],
/// [`crate::schedule`]). A stop asked for through `progress` is seen before each trial.
fn stream_trials_with(
    plan: &Plan,
    trials: &[TrialSpec],
    runner: &Runner<'_>,
    progress: &dyn CampaignProgress,
    on_done: &(dyn Fn(&TrialRecord) -> Result<()> + Sync),
) -> Result<()> {
    let pieces = match runner.sharing {
        Some(_) => share_observations(&plan.cells, trials),
        None => trials.iter().map(|t| vec![*t]).collect(),
    };
    // Trial-major as before (a stopped run holds a like share of each cell), and longest first
    // within each round of trials: a long piece is not the last of its round to start.
    let mut costed: Vec<(f64, Vec<TrialSpec>)> = (pieces.into_iter())
        .map(|p| (piece_cost(plan, &p), p))
        .collect();
    costed.sort_by(|a, b| (a.1[0].trial.cmp(&b.1[0].trial)).then(b.0.total_cmp(&a.0)));
    let pieces: Vec<Vec<TrialSpec>> = costed.into_iter().map(|(_, p)| p).collect();
    schedule::try_in_order(&pieces, |piece| {
        let ran = match runner.sharing {
            Some(replays) if piece.len() > 1 => run_shared(plan, piece, replays, progress, on_done),
            _ => piece.iter().try_for_each(|spec| {
                go_on(progress)?;
                on_done(&guarded_trial(plan, spec, runner.one))
            }),
        };
        release_freed_memory();
        ran
    })
}

/// A rough relative cost of a piece of work (trials that share their observation, or one
/// trial), for the order in which a campaign runs them only (longest first,
/// [`crate::schedule`]): the simulated seconds it may run at most (the search's limit when it
/// starts above the hole, the longest observation, each trial's alignment and insertion limit)
/// times its pair's [`PartPair::relative_step_cost`].
fn piece_cost(plan: &Plan, piece: &[TrialSpec]) -> f64 {
    let configs: Vec<&TrialConfig> = (piece.iter()).map(|t| &plan.cell(t.cell).config).collect();
    let search = |c: &TrialConfig| match c.start {
        Start::Above => c.search.limit_s,
        Start::Partial => 0.0,
    };
    let observing = (configs.iter())
        .map(|c| search(c) + c.t_obs_s)
        .fold(0.0, f64::max);
    let after: f64 = configs.iter().map(|c| c.align_s + c.insert_limit_s).sum();
    let (pair, _, _) = plan.inputs(piece[0].cell);
    (observing + after) * pair.relative_step_cost()
}

/// `Err(Stopped)` once a stop has been asked for: the trials that finished are kept.
fn go_on(progress: &dyn CampaignProgress) -> Result<()> {
    if progress.should_stop() {
        return Err(Error::Stopped(
            "the campaign was stopped; the trials that finished are kept (resume it to complete \
             it)"
            .into(),
        ));
    }
    Ok(())
}

/// Trials that observe alike but for their budget ([`share_observations`]), each record handed
/// to `on_done` as it finishes: the longest observation runs once, and at each budget the trials
/// that end their observation there go on from a fork of it (and of its replay's recording), so
/// that each record and replay is the one its trial gives alone, bit for bit. An error or a panic
/// in the observation is that of every trial still observing, as it would be alone; one after it
/// is its own trial's. A stop is seen before each trial; a trial not run then runs alone when the
/// campaign is resumed.
fn run_shared(
    plan: &Plan,
    trials: &[TrialSpec],
    replays: &ReplayWriter,
    progress: &dyn CampaignProgress,
    on_done: &(dyn Fn(&TrialRecord) -> Result<()> + Sync),
) -> Result<()> {
    go_on(progress)?;
    let budget = |t: &TrialSpec| plan.cell(t.cell).config.t_obs_s;
    let mut trials = trials.to_vec();
    trials.sort_by(|a, b| budget(a).total_cmp(&budget(b)));
    let longest = &trials[trials.len() - 1];
    let (pair, robot, _) = plan.inputs(longest.cell);
    let PlannedCell { params, config, .. } = plan.cell(longest.cell);
    let mut watched = trials
        .iter()
        .any(|t| replays.may_want(t))
        .then(|| Replay::new(pair, robot));
    let mut observing = guarded(|| {
        let recorder = watched.as_mut().map(|r| r as &mut dyn Recorder);
        ObservingTrial::start(pair, robot, params, config, longest.seed, recorder)
    });
    for (i, spec) in trials.iter().enumerate() {
        if i > 0 {
            go_on(progress)?;
        }
        let at_budget = observing.as_mut().map_err(|m| m.clone()).and_then(|o| {
            guarded(|| {
                o.observe_until(
                    budget(spec),
                    watched.as_mut().map(|r| r as &mut dyn Recorder),
                );
                Ok(o.observed())
            })
        });
        if let Err(message) = &at_budget {
            observing = Err(message.clone());
        }
        let (_, _, manifold) = plan.inputs(spec.cell);
        let config = &plan.cell(spec.cell).config;
        let mut replay = watched.clone().filter(|_| replays.may_want(spec));
        let result = at_budget.and_then(|observed| {
            guarded(|| {
                let recorder = replay.as_mut().map(|r| r as &mut dyn Recorder);
                finish_trial(observed, pair, config, manifold, recorder)
            })
        });
        if let Ok(result) = &result {
            replays.keep(spec, replay.as_ref(), result, manifold);
        }
        let result = result.unwrap_or_else(|m| errored(plan, spec, m));
        on_done(&record(spec, result))?;
    }
    Ok(())
}

/// The record of trial `spec`.
fn record(spec: &TrialSpec, result: TrialResult) -> TrialRecord {
    TrialRecord {
        cell: spec.cell,
        trial: spec.trial,
        result,
    }
}

/// What `work` returns, or the message of its error or its panic.
fn guarded<T>(work: impl FnOnce() -> Result<T>) -> std::result::Result<T, String> {
    match std::panic::catch_unwind(std::panic::AssertUnwindSafe(work)) {
        Ok(Ok(value)) => Ok(value),
        Ok(Err(e)) => Err(e.to_string()),
        Err(panic) => Err(format!("panicked: {}", panic_message(panic.as_ref()))),
    }
}

/// Hands the pages the allocator holds free back to the system, after each trial. glibc keeps
/// what a trial freed inside its per-thread arenas (about 3 MB each with two workers, while the
/// live heap between trials is under 1 MB), and fragmentation makes that pile creep up over
/// thousands of trials; `malloc_trim` returns the free pages (docs/journal/2026-11-26.md, "Soak").
fn release_freed_memory() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: malloc_trim only gives free pages back to the kernel; no live allocation moves.
    unsafe {
        libc::malloc_trim(0);
    }
}

/// One trial's record, whatever happens in it: an error or a panic becomes outcome `error` with
/// its message, so one bad trial does not take a 10 000-trial campaign down.
fn guarded_trial(plan: &Plan, spec: &TrialSpec, run: &RunOne<'_>) -> TrialRecord {
    let result = guarded(|| run(plan, spec)).unwrap_or_else(|message| errored(plan, spec, message));
    record(spec, result)
}

/// The trial `spec` of the campaign.
pub fn run_one(plan: &Plan, spec: &TrialSpec) -> Result<TrialResult> {
    run_one_recorded(plan, spec, None)
}

/// The trial `spec` of the campaign, seen by `recorder` (a replay).
pub fn run_one_recorded(
    plan: &Plan,
    spec: &TrialSpec,
    recorder: Option<&mut dyn Recorder>,
) -> Result<TrialResult> {
    let (pair, robot, manifold) = plan.inputs(spec.cell);
    let PlannedCell { params, config, .. } = plan.cell(spec.cell);
    run_trial(pair, robot, params, config, manifold, spec.seed, recorder)
}

/// The record of trial `spec` that could not run: `message` says why.
fn errored(plan: &Plan, spec: &TrialSpec, message: String) -> TrialResult {
    let (pair, robot, _) = plan.inputs(spec.cell);
    let PlannedCell { params, config, .. } = plan.cell(spec.cell);
    let arm = (pair, robot.joints.len());
    errored_trial(arm, params, config, spec.seed, message)
}

/// The message of a panic's payload (a `&str` or a `String`, as `panic!` makes them).
fn panic_message(payload: &(dyn std::any::Any + Send)) -> String {
    payload
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| payload.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "(no message)".into())
}

/// How a campaign folder is opened.
#[derive(Clone, Copy, Debug)]
pub struct CampaignOptions {
    pub shard: Shard,
    pub resume: bool,
    /// Which trials get a 3-D replay in `replays/` (they do not change the records).
    pub replays: Replays,
}

/// The outcome of `campaign`.
pub struct CampaignRun {
    /// The folder's `trials.jsonl`, complete and in (cell, trial) order.
    pub trials: TrialsFile,
    /// How many trials it holds.
    pub count: usize,
    /// Trials run now (the rest were already there).
    pub ran: usize,
    /// Finished trials run again to draw the replays their folder lacked (`--resume`).
    pub redrawn: usize,
}

/// Runs (or completes, with `resume`) a campaign into `out`.
pub fn campaign(
    scenario: &Scenario,
    out: &Path,
    options: CampaignOptions,
    run: &RunOptions,
) -> Result<CampaignRun> {
    let replays = ReplayWriter::new(out, options.replays);
    let one = |p: &Plan, spec: &TrialSpec| {
        let (pair, robot, manifold) = p.inputs(spec.cell);
        replays.record(spec, (pair, robot, manifold), |recorder| {
            run_one_recorded(p, spec, recorder)
        })
    };
    let runner = Runner {
        one: &one,
        sharing: Some(&replays),
    };
    let outcome = campaign_with(scenario, out, options, run, &runner);
    replays.finish(outcome)
}

pub(crate) fn campaign_with(
    scenario: &Scenario,
    out: &Path,
    options: CampaignOptions,
    run: &RunOptions,
    runner: &Runner<'_>,
) -> Result<CampaignRun> {
    let described = CampaignFile::new(scenario, options.shard);
    let is_new = check_folder(out, &described, options.resume)?;
    let trials_path = out.join(TRIALS_FILE);
    let wanted = CampaignTrials::of(scenario, options.shard);
    let done = index_records(&trials_path, true)?;
    check_entries_belong(&done, &wanted, &trials_path)?;
    let finished: BTreeSet<(usize, usize)> = done.iter().map(|e| (e.cell, e.trial)).collect();
    drop(done);
    let resumed = finished.len();
    let redraw = match runner.sharing {
        Some(replays) if resumed > 0 => {
            let records = TrialsFile {
                path: trials_path.clone(),
            };
            replays.missing(&records, &wanted)?
        }
        _ => Vec::new(),
    };
    let mut cells = unfinished_cells(&wanted, &finished);
    cells.extend(redraw.iter().map(|(spec, _)| spec.cell));
    cells.sort_unstable();
    cells.dedup();
    let prepared = prepare(scenario, &cells, run)?;
    if is_new {
        create_folder(out, &described)?;
    }
    let file = std::fs::OpenOptions::new()
        .create(true)
        .append(true)
        .open(&trials_path)
        .map_err(|e| Error::file(&trials_path, format!("cannot open for appending: {e}")))?;
    let writer = Mutex::new(file);
    run.progress.trials_started(wanted.count(), resumed);
    let append = |record: &TrialRecord| -> Result<()> {
        let mut line = serde_json::to_string(record).expect("record serialises");
        line.push('\n');
        let mut f = writer.lock().expect("no writer panicked");
        f.write_all(line.as_bytes())
            .and_then(|_| f.flush())
            .map_err(|e| Error::file(&trials_path, format!("cannot append: {e}")))?;
        run.progress.trial_done();
        Ok(())
    };
    let plan = Plan::new(scenario, &prepared);
    let ran = stream_rounds(&plan, &wanted, &finished, runner, run.progress, &append);
    run.progress.trials_finished();
    ran?;
    redraw_replays(&plan, &redraw, runner.one)?;
    let entries = index_records(&trials_path, false)?;
    check_complete(&entries, &wanted, &trials_path)?;
    let trials = entries.len();
    write_sorted(&trials_path, &[(trials_path.clone(), entries)])?;
    Ok(CampaignRun {
        trials: TrialsFile { path: trials_path },
        count: trials,
        ran: trials - resumed,
        redrawn: redraw.len(),
    })
}

/// Runs again, each alone, the finished trials whose replay is missing ([`ReplayWriter::missing`]),
/// for their replays only: their records stay as they are (a trial is a function of its seed; one
/// that comes out otherwise than its record is an error naming it, and gets no page).
fn redraw_replays(plan: &Plan, redraw: &[(TrialSpec, String)], one: &RunOne<'_>) -> Result<()> {
    schedule::try_in_order(redraw, |(spec, outcome)| {
        let again = guarded(|| one(plan, spec)).map_err(|m| {
            Error::Input(format!(
                "trial {} of cell {}, run again to draw its replay: {m}",
                spec.trial, spec.cell
            ))
        })?;
        if again.outcome != *outcome {
            return Err(Error::Input(format!(
                "trial {} of cell {} came out {} where its record says {outcome}: its replay is \
                 not drawn (was the campaign run by another build of pegtwin?)",
                spec.trial, spec.cell, again.outcome
            )));
        }
        Ok(())
    })
}

/// The cells that hold a trial of `wanted` not yet `finished`, in the scenario's cell order.
fn unfinished_cells(wanted: &CampaignTrials, finished: &BTreeSet<(usize, usize)>) -> Vec<usize> {
    let mut done_in = vec![0usize; wanted.cells()];
    for &(cell, _) in finished {
        done_in[cell] += 1;
    }
    (0..wanted.cells())
        .filter(|&c| done_in[c] < wanted.held_in_cell(c))
        .collect()
}

/// Runs the trials of `wanted` not yet `finished` ([`stream_trials_with`]), in rounds of trial
/// numbers, each listed when it starts ([`CampaignTrials::round_len`]): a campaign's plan stays in
/// memory proportional to its cells however many trials it asks for. A round's pieces all run
/// before the next round is listed; a campaign of a few thousand trials is one round.
fn stream_rounds(
    plan: &Plan,
    wanted: &CampaignTrials,
    finished: &BTreeSet<(usize, usize)>,
    runner: &Runner<'_>,
    progress: &dyn CampaignProgress,
    on_done: &(dyn Fn(&TrialRecord) -> Result<()> + Sync),
) -> Result<()> {
    let per_round = wanted.round_len();
    for start in (0..wanted.per_cell()).step_by(per_round) {
        let pending: Vec<TrialSpec> = (wanted.round(start..start.saturating_add(per_round)))
            .filter(|t| !finished.contains(&(t.cell, t.trial)))
            .collect();
        if !pending.is_empty() {
            stream_trials_with(plan, &pending, runner, progress, on_done)?;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shard_parsing_names_the_flag() {
        assert_eq!(Shard::parse("1/4").unwrap(), Shard { index: 1, count: 4 });
        for bad in ["4/4", "1", "a/2", "0/0"] {
            let e = Shard::parse(bad).unwrap_err().to_string();
            assert!(e.contains("--shard"), "{e}");
        }
    }

    /// `--shard auto` reads the shard from a Slurm job array or a Kubernetes Indexed Job.
    #[test]
    fn the_scheduler_gives_the_shard() {
        let env = |pairs: &'static [(&'static str, &'static str)]| {
            move |name: &str| {
                (pairs.iter())
                    .find(|(k, _)| *k == name)
                    .map(|(_, v)| v.to_string())
            }
        };
        let slurm = env(&[
            ("SLURM_ARRAY_TASK_ID", "6"),
            ("SLURM_ARRAY_TASK_MIN", "5"),
            ("SLURM_ARRAY_TASK_MAX", "8"),
            ("SLURM_ARRAY_TASK_COUNT", "4"),
            ("SLURM_ARRAY_TASK_STEP", "1"),
        ]);
        assert_eq!(
            Shard::from_scheduler(&slurm).unwrap(),
            Shard { index: 1, count: 4 }
        );
        let k8s = env(&[("JOB_COMPLETION_INDEX", "2"), ("PEGTWIN_SHARD_COUNT", "3")]);
        assert_eq!(
            Shard::from_scheduler(&k8s).unwrap(),
            Shard { index: 2, count: 3 }
        );
        let refused = |pairs, wanted: &str| {
            let e = Shard::from_scheduler(&env(pairs)).unwrap_err().to_string();
            assert!(e.contains("--shard auto") && e.contains(wanted), "{e}");
        };
        refused(&[], "SLURM_ARRAY_TASK_ID");
        refused(&[("JOB_COMPLETION_INDEX", "0")], "PEGTWIN_SHARD_COUNT");
        refused(
            &[("JOB_COMPLETION_INDEX", "3"), ("PEGTWIN_SHARD_COUNT", "3")],
            "0 <= index < count",
        );
        refused(&[("SLURM_ARRAY_TASK_ID", "1")], "SLURM_ARRAY_TASK_MIN");
        refused(
            &[
                ("SLURM_ARRAY_TASK_ID", "2"),
                ("SLURM_ARRAY_TASK_MIN", "0"),
                ("SLURM_ARRAY_TASK_COUNT", "2"),
                ("SLURM_ARRAY_TASK_STEP", "2"),
            ],
            "consecutive",
        );
        refused(
            &[
                ("SLURM_ARRAY_TASK_ID", "x"),
                ("SLURM_ARRAY_TASK_MIN", "0"),
                ("SLURM_ARRAY_TASK_COUNT", "2"),
            ],
            "SLURM_ARRAY_TASK_ID=x",
        );
    }
}
