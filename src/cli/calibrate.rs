//! `pegtwin calibrate`: the real cell's `[cell]` values fitted to measured figures (issue 46).

use super::campaign::run_options;
use super::progress::Bars;
use clap::Args;
use indicatif::ProgressBar;
use pegtwin::campaign::calibrate::targets::Targets;
use pegtwin::campaign::calibrate::{CalibrateOptions, calibrate};
use pegtwin::campaign::run as campaign;
use pegtwin::campaign::scenario::Scenario;
use pegtwin::error::Result;
use std::io::IsTerminal;
use std::path::PathBuf;
use std::sync::Mutex;
use std::time::Instant;

#[derive(Args)]
pub struct CalibrateArgs {
    /// Scenario file (TOML) whose [cell] is calibrated; its cells and seeds run at each draw.
    pub scenario: PathBuf,
    /// Targets file (TOML): the measured figures, fitted or held out, and the free [cell] values.
    #[arg(long)]
    pub targets: PathBuf,
    /// Output folder (new or empty unless --resume).
    #[arg(long)]
    pub out: PathBuf,
    /// Complete a calibration that was interrupted in --out (the same posterior).
    #[arg(long)]
    pub resume: bool,
    /// The most trials the calibration may run in all (draws x trials per draw).
    #[arg(long, default_value_t = 100_000)]
    pub max_trials: usize,
    /// Worker threads (default: all cores). Results do not depend on it.
    #[arg(long)]
    pub threads: Option<usize>,
    /// Folder of cached manifolds (default: $XDG_CACHE_HOME/pegtwin or ~/.cache/pegtwin).
    #[arg(long)]
    pub cache_dir: Option<PathBuf>,
}

/// Exit 0, or 1 when a fitted figure is one no value in the prior reaches.
pub fn calibrate_command(args: CalibrateArgs) -> Result<i32> {
    let scenario = Scenario::load(&args.scenario)?;
    let targets = Targets::load(&args.targets, &scenario)?;
    let bars = Bars::on_terminal();
    let run = run_options(&args.cache_dir, &bars)?;
    let options = CalibrateOptions {
        resume: args.resume,
        max_trials: args.max_trials,
    };
    let shown = std::io::stderr().is_terminal();
    let bar = ProgressBar::new(targets.file.samples as u64);
    let clock = DrawClock::default();
    let on_draw = |done: usize, all: usize| match shown {
        true => bar.set_position(done as u64),
        false => eprintln!("{}", clock.line(done, all)),
    };
    let posterior = campaign::worker_pool(args.threads)?
        .install(|| calibrate(&scenario, &targets, &args.out, options, &run, &on_draw))?;
    bar.finish_and_clear();
    for ((name, q), prior) in posterior
        .free
        .iter()
        .zip(&posterior.quantiles)
        .zip(&posterior.prior)
    {
        println!(
            "{name}: {:.4} (90 %: {:.4} - {:.4}; prior {:.4} - {:.4})",
            q[1], q[0], q[2], prior[0], prior[1]
        );
    }
    for (t, p) in targets.targets.iter().zip(&posterior.predictive) {
        let verdict = p.map_or("no such figure from the twin", |p| match p.inside {
            true => "inside",
            false => "outside",
        });
        println!("{}: {verdict} its 90 % prediction", t.label);
    }
    println!(
        "{} draws; the posterior weighs {} points of the prior, {:.0} effectively; results in {}",
        posterior.evaluations.len(),
        posterior.points.len(),
        posterior.effective_points,
        args.out.join("report.html").display()
    );
    if !posterior.unreachable.is_empty() {
        eprintln!(
            "no value in the prior reaches {} fitted figure(s): see the report",
            posterior.unreachable.len()
        );
        return Ok(1);
    }
    Ok(0)
}

/// Times the draws this run finishes, for the line each prints where no bar is shown (a batch
/// job's log): a draw is a whole campaign, minutes apart.
struct DrawClock {
    start: Instant,
    /// The first draw this run finished (a resumed run starts past the finished ones).
    first: Mutex<Option<usize>>,
}

impl Default for DrawClock {
    fn default() -> Self {
        DrawClock {
            start: Instant::now(),
            first: Mutex::new(None),
        }
    }
}

impl DrawClock {
    /// "draw 7 of 24 done (13 minutes in this run, about 2 hours left)".
    fn line(&self, done: usize, all: usize) -> String {
        let first = *self
            .first
            .lock()
            .expect("no clock user panicked")
            .get_or_insert(done);
        let elapsed = self.start.elapsed();
        let per_draw = elapsed.div_f64((done + 1 - first) as f64);
        let left = per_draw.mul_f64(all.saturating_sub(done) as f64);
        format!(
            "draw {done} of {all} done ({} in this run, about {} left)",
            indicatif::HumanDuration(elapsed),
            indicatif::HumanDuration(left)
        )
    }
}
