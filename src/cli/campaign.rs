//! `pegtwin campaign`, `merge`, `check` and `tune`.

use super::choices::choice;
use super::progress::Bars;
use clap::Args;
use pegtwin::campaign::check::{Baseline, compare, findings_table};
use pegtwin::campaign::replays::Replays;
use pegtwin::campaign::run::{self as campaign, CampaignOptions, RunOptions, Shard};
use pegtwin::campaign::scenario::Scenario;
use pegtwin::campaign::tune::{TuneOptions, TuneTarget};
use pegtwin::campaign::tuning::{best, tune_into};
use pegtwin::campaign::usage::Stopwatch;
use pegtwin::campaign::{report, summary};
use pegtwin::choice::Choice;
use pegtwin::error::Result;
use pegtwin::method::manifold::cache;
use std::path::{Path, PathBuf};

#[derive(Args)]
pub struct CampaignArgs {
    /// Scenario file (TOML).
    pub scenario: PathBuf,
    /// Results folder (created; must be new or empty unless --resume).
    #[arg(long)]
    pub out: PathBuf,
    /// Worker threads (default: all cores). Results do not depend on it.
    #[arg(long)]
    pub threads: Option<usize>,
    /// Run only shard I of N (0 <= I < N): trial number n belongs to shard n % N. `auto`: the
    /// shard a Slurm job array or a Kubernetes Indexed Job gives this task (deploy/README.md).
    #[arg(long)]
    pub shard: Option<String>,
    /// Complete a campaign that was interrupted in --out.
    #[arg(long)]
    pub resume: bool,
    /// Folder of cached manifolds (default: $XDG_CACHE_HOME/pegtwin or ~/.cache/pegtwin).
    #[arg(long)]
    pub cache_dir: Option<PathBuf>,
    /// Which trials get a 3-D replay page in OUT/replays, linked from report.html.
    #[arg(long, value_parser = choice::<Replays>(), default_value = Replays::Failures.name())]
    pub replays: Replays,
}

#[derive(Args)]
pub struct MergeArgs {
    /// Shard result folders.
    #[arg(required = true)]
    pub dirs: Vec<PathBuf>,
    /// Merged results folder (new or empty, or with --resume one a merge was cut short in).
    #[arg(long)]
    pub out: PathBuf,
    /// Complete a merge of these shards that was cut short in --out.
    #[arg(long)]
    pub resume: bool,
    /// Folder of cached manifolds, for the report's manifold figures (default: $XDG_CACHE_HOME/pegtwin or ~/.cache/pegtwin).
    #[arg(long)]
    pub cache_dir: Option<PathBuf>,
}

#[derive(Args)]
pub struct CheckArgs {
    /// Results folder of a finished campaign.
    pub dir: PathBuf,
    /// Baseline to hold the run to (exit 1 when a cell regressed).
    #[arg(long, required_unless_present = "write_baseline")]
    pub baseline: Option<PathBuf>,
    /// Write the run's summary as a baseline file instead.
    #[arg(long, conflicts_with = "baseline")]
    pub write_baseline: Option<PathBuf>,
}

#[derive(Args)]
pub struct ExportArgs {
    /// Results folder of a finished campaign (merged, when it ran in shards).
    pub dir: PathBuf,
    /// The Parquet file to write (its trials.jsonl stays the canonical record).
    #[arg(long)]
    pub parquet: PathBuf,
}

#[derive(Args)]
pub struct TuneArgs {
    /// Scenario file (TOML): its cells and offsets; `trials` caps the trials per cell of the
    /// last rung.
    pub scenario: PathBuf,
    /// Output folder for tune.csv and the plot (new or empty, unless --resume); it keeps
    /// the evaluations as they finish in tune-journal.jsonl.
    #[arg(long)]
    pub out: PathBuf,
    /// Go on with a search that was killed in --out (same scenario and options): the
    /// evaluations it finished are kept, and the result is the uninterrupted search's.
    #[arg(long)]
    pub resume: bool,
    /// Candidates of the first rung (Latin hypercube).
    #[arg(long, default_value_t = TuneOptions::default().candidates)]
    pub candidates: usize,
    /// Trials per cell at the first rung (times 3 per rung).
    #[arg(long, default_value_t = TuneOptions::default().first_trials)]
    pub first_trials: usize,
    /// Seed of the design.
    #[arg(long, default_value_t = TuneOptions::default().seed)]
    pub seed: u64,
    /// What to tune: the method's observation and insertion gains, or the direct baseline's
    /// insertion (stiffness, damping, seat force) on the scenario's direct cells.
    #[arg(long, value_parser = choice::<TuneTarget>(), default_value = TuneTarget::Gains.name())]
    pub target: TuneTarget,
    /// Worker threads (default: all cores).
    #[arg(long)]
    pub threads: Option<usize>,
    /// Folder of cached manifolds.
    #[arg(long)]
    pub cache_dir: Option<PathBuf>,
}

pub(super) fn run_options<'a>(
    cache_dir: &Option<PathBuf>,
    bars: &'a Bars,
) -> Result<RunOptions<'a>> {
    Ok(RunOptions {
        cache_dir: cache::folder(cache_dir.as_deref())?,
        progress: bars,
    })
}

pub fn campaign_command(args: CampaignArgs) -> Result<i32> {
    let scenario = Scenario::load(&args.scenario)?;
    let shard = match &args.shard {
        Some(s) => Shard::parse(s)?,
        None => Shard::WHOLE,
    };
    let bars = Bars::on_terminal();
    let run = run_options(&args.cache_dir, &bars)?;
    let options = CampaignOptions {
        shard,
        resume: args.resume,
        replays: args.replays,
    };
    let pool = campaign::worker_pool(args.threads)?;
    let watch = Stopwatch::start(pool.current_num_threads());
    let outcome = pool.install(|| campaign::campaign(&scenario, &args.out, options, &run))?;
    let usage = watch.usage();
    let summary =
        report::write_campaign_report(&args.out, &scenario, &outcome.trials, &run.cache_dir)?;
    print!("{}", summary::summary_table(&summary));
    let redrawn = match outcome.redrawn {
        0 => String::new(),
        n => format!(", {n} run again for the replays the folder lacked"),
    };
    println!(
        "{} trials ({} run now{redrawn}) in {}; results in {}",
        outcome.count,
        outcome.ran,
        usage.describe(),
        args.out.join("report.html").display()
    );
    Ok(0)
}

pub fn merge_command(args: MergeArgs) -> Result<i32> {
    let (scenario, trials, count) = campaign::merge(&args.dirs, &args.out, args.resume)?;
    let cache_dir = cache::folder(args.cache_dir.as_deref())?;
    let summary = report::write_campaign_report(&args.out, &scenario, &trials, &cache_dir)?;
    print!("{}", summary::summary_table(&summary));
    println!(
        "{} trials from {} shards; results in {}",
        count,
        args.dirs.len(),
        args.out.display()
    );
    Ok(0)
}

fn finished_summary(dir: &Path) -> Result<summary::Summary> {
    let (c, trials) = campaign::read_finished(dir)?;
    summary::summarise(&c.scenario, &trials)
}

pub fn check_command(args: CheckArgs) -> Result<i32> {
    let summary = finished_summary(&args.dir)?;
    if let Some(path) = &args.write_baseline {
        let json = serde_json::to_vec_pretty(&Baseline::from_summary(&summary))
            .expect("baseline serialises");
        pegtwin::files::write_atomically(path, &json)?;
        println!(
            "baseline of {} cells written to {}",
            summary.cells.len(),
            path.display()
        );
        return Ok(0);
    }
    let path = args
        .baseline
        .as_ref()
        .expect("clap requires one of the two");
    let baseline = Baseline::load(path)?;
    if baseline.fingerprint != summary.fingerprint {
        eprintln!(
            "warning: the baseline was made from another scenario (fingerprint {} vs {}); comparing cell by cell",
            baseline.fingerprint, summary.fingerprint
        );
    }
    let findings = compare(&summary, &baseline);
    print!("{}", findings_table(&findings));
    let failed = findings.iter().any(|f| f.failed);
    println!(
        "{}",
        if failed {
            "check FAILED"
        } else {
            "check passed"
        }
    );
    Ok(i32::from(failed))
}

pub fn export_command(args: ExportArgs) -> Result<i32> {
    let rows = pegtwin::campaign::export::write_parquet(&args.dir, &args.parquet)?;
    println!("{rows} trials written to {}", args.parquet.display());
    Ok(0)
}

pub fn tune_command(args: TuneArgs) -> Result<i32> {
    let scenario = Scenario::load(&args.scenario)?;
    let bars = Bars::on_terminal();
    let run = run_options(&args.cache_dir, &bars)?;
    let options = TuneOptions {
        candidates: args.candidates,
        first_trials: args.first_trials,
        seed: args.seed,
        target: args.target,
    };
    let only = args.target.only_method();
    let cells = scenario
        .cells()
        .iter()
        .filter(|c| only.is_none_or(|m| c.method == m))
        .count();
    let evals = campaign::worker_pool(args.threads)?.install(|| {
        tune_into(
            &scenario,
            &options,
            &run,
            &args.out,
            args.resume,
            &|n| eprintln!("resuming: {n} evaluations were finished"),
            &|rung, n, trials| {
                eprintln!("rung {rung}: {n} candidates x {} trials", trials * cells);
            },
        )
    })?;
    let best = best(&evals);
    println!(
        "best: candidate {} at rung {}: {}/{} successes, mean peak Fz {:.1} N\n\n{}",
        best.candidate.id,
        best.rung,
        best.successes,
        best.trials,
        best.peak_fz_n,
        best.candidate.snippet(&scenario)
    );
    Ok(0)
}
