//! `pegtwin trial`: one online trial, the manifold method or the direct baseline; `pegtwin rerun`:
//! one trial of a campaign again, on its own, to trace or replay it.

use super::PairChoice;
use super::choices::choice;
use super::progress::Bars;
use clap::Args;
use pegtwin::campaign::records::TrialRecord;
use pegtwin::campaign::run as campaign;
use pegtwin::campaign::scenario::Scenario;
use pegtwin::choice::Choice;
use pegtwin::error::Result;
use pegtwin::method::config::{Method, Start, TrialConfig};
use pegtwin::method::manifold::Manifold;
use pegtwin::method::manifold::cache::Sampler;
use pegtwin::method::request::{TrialRequest, default_offsets_mm_deg};
use pegtwin::method::session::{Recorder, trace_csv};
use pegtwin::method::trace_mcap::trace_mcap;
use pegtwin::method::trial::TrialResult;
use pegtwin::replay::Replay;
use pegtwin::twin::geometry::PartPair;
use pegtwin::twin::real_cell::{Profile, RealCell};
use pegtwin::twin::robot::RobotModel;
use std::path::PathBuf;

/// Where a trial's recordings go.
#[derive(Args)]
pub struct RecordingArgs {
    /// Write the 1 kHz time series (time, phase, TCP pose, estimated and true wrench, contact):
    /// CSV, or MCAP for Foxglove and PlotJuggler when the file name ends in `.mcap`.
    #[arg(long)]
    pub trace: Option<PathBuf>,
    /// Write a 3-D replay of the trial: one self-contained HTML page (open it in a browser).
    #[arg(long)]
    pub replay: Option<PathBuf>,
}

impl RecordingArgs {
    /// Refuses, before anything runs, a trace or replay path that cannot be written.
    fn ensure_writable(&self) -> Result<()> {
        for path in self.trace.iter().chain(&self.replay) {
            pegtwin::files::ensure_writable(path)?;
        }
        Ok(())
    }

    /// Runs a trial through `run`, recording it when a trace or a replay is asked for, and
    /// writes them once it has finished.
    fn run(
        &self,
        (pair, robot, manifold): (&PartPair, &RobotModel, Option<&Manifold>),
        run: impl FnOnce(Option<&mut dyn Recorder>) -> Result<TrialResult>,
    ) -> Result<TrialResult> {
        let mut recorders = (Vec::new(), Replay::new(pair, robot));
        let recording = self.trace.is_some() || self.replay.is_some();
        let result = run(recording.then_some(&mut recorders as &mut dyn Recorder))?;
        let (rows, page) = recorders;
        if let Some(path) = &self.trace {
            let is_mcap = path
                .extension()
                .is_some_and(|e| e.eq_ignore_ascii_case("mcap"));
            let bytes = if is_mcap {
                trace_mcap(&rows)?
            } else {
                trace_csv(&rows)
            };
            pegtwin::files::write_atomically(path, &bytes)?;
        }
        if let Some(path) = &self.replay {
            page.write_html(path, &result, manifold)?;
        }
        Ok(result)
    }
}

/// The library's default offset half-ranges, mm and deg (the paper's U(-5, 5)).
#[derive(Args)]
#[command(group(clap::ArgGroup::new("pair").required(true).args(["geometry", "assembly"])))]
pub struct TrialArgs {
    #[command(flatten)]
    pub pair: PairChoice,
    /// Observation time, s.
    #[arg(long, default_value_t = TrialConfig::default().t_obs_s, allow_negative_numbers = true)]
    pub t_obs: f64,
    #[arg(long, value_parser = choice::<Method>(), default_value = Method::Manifold.name())]
    pub method: Method,
    /// Start partially inserted (the paper's set-up) or above the hole with a spiral search.
    #[arg(long, value_parser = choice::<Start>(), default_value = Start::Partial.name())]
    pub start: Start,
    /// Trial seed: draws the hole offset and seeds every noise source.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// The ideal cell or the real one (its imperfections drawn from the seed, docs/physics.md).
    #[arg(long, value_parser = choice::<Profile>(), default_value = RealCell::default().profile.name())]
    pub profile: Profile,
    /// Half-range of the hole's position offset, mm (U(-r, r) on x, y, z).
    #[arg(long, default_value_t = default_offsets_mm_deg().0, allow_negative_numbers = true)]
    pub offset_mm: f64,
    /// Half-range of the hole's orientation offset, deg (U(-r, r) on roll, pitch, yaw).
    #[arg(long, default_value_t = default_offsets_mm_deg().1, allow_negative_numbers = true)]
    pub offset_deg: f64,
    /// Reference manifold file (default: the cache, built on demand).
    #[arg(long)]
    pub manifold: Option<PathBuf>,
    /// How the cached reference manifold is made, when no --manifold is given.
    #[arg(long, value_parser = choice::<Sampler>(), default_value = Sampler::Robot.name(), conflicts_with = "manifold")]
    pub sampler: Sampler,
    /// Folder of cached manifolds (default: $XDG_CACHE_HOME/pegtwin or ~/.cache/pegtwin).
    #[arg(long)]
    pub cache_dir: Option<PathBuf>,
    /// Print the result as JSON.
    #[arg(long)]
    pub json: bool,
    #[command(flatten)]
    pub recording: RecordingArgs,
}

impl TrialArgs {
    /// The library's request for these arguments.
    fn request(&self) -> TrialRequest {
        TrialRequest {
            pair: self.pair.source(),
            t_obs_s: self.t_obs,
            method: self.method,
            start: self.start,
            seed: self.seed,
            offset_mm: self.offset_mm,
            offset_deg: self.offset_deg,
            manifold: self.manifold.clone(),
            sampler: self.sampler,
            cache_dir: self.cache_dir.clone(),
            profile: self.profile,
        }
    }
}

pub fn trial_command(args: TrialArgs) -> Result<i32> {
    let request = args.request();
    let checked = request.check()?;
    args.recording.ensure_writable()?;
    let trial = request.prepare(checked, &Bars::new(true))?;
    let result = args.recording.run(
        (&trial.pair, &trial.robot, trial.manifold.as_ref()),
        |recorder| trial.run(recorder),
    )?;
    if args.json {
        println!(
            "{}",
            serde_json::to_string_pretty(&result).expect("result serialises")
        );
    } else {
        print_result(&result);
    }
    Ok(0)
}

/// One trial of a campaign again, on its own (a scenario file or a campaign's results folder).
#[derive(Args)]
pub struct RerunArgs {
    /// A scenario file (TOML), or the results folder of a campaign (its campaign.json).
    pub campaign: PathBuf,
    /// The trial's cell, numbered from 0 as in trials.jsonl (`cell`).
    #[arg(long)]
    pub cell: usize,
    /// The trial within its cell, numbered from 0 as in trials.jsonl (`trial`).
    #[arg(long)]
    pub trial: usize,
    /// Folder of cached manifolds (default: $XDG_CACHE_HOME/pegtwin or ~/.cache/pegtwin).
    #[arg(long)]
    pub cache_dir: Option<PathBuf>,
    /// Print the record as one JSON line, the same as the trial's line of trials.jsonl.
    #[arg(long)]
    pub json: bool,
    #[command(flatten)]
    pub recording: RecordingArgs,
}

pub fn rerun_command(args: RerunArgs) -> Result<i32> {
    let scenario = if args.campaign.is_dir() {
        campaign::read_campaign(&args.campaign)?.scenario
    } else {
        Scenario::load(&args.campaign)?
    };
    args.recording.ensure_writable()?;
    let bars = Bars::new(true);
    let options = super::campaign::run_options(&args.cache_dir, &bars)?;
    let (spec, prepared) = campaign::single_trial(&scenario, args.cell, args.trial, &options)?;
    let plan = campaign::Plan::new(&scenario, &prepared);
    let result = args.recording.run(plan.inputs(spec.cell), |recorder| {
        campaign::run_one_recorded(&plan, &spec, recorder)
    })?;
    if args.json {
        let record = TrialRecord {
            cell: spec.cell,
            trial: spec.trial,
            result,
        };
        println!(
            "{}",
            serde_json::to_string(&record).expect("record serialises")
        );
    } else {
        print_result(&result);
    }
    Ok(0)
}

fn print_result(r: &TrialResult) {
    let o = r.offset;
    println!(
        "{} at {} mm, method {:?}, seed {}, t_obs {} s",
        r.geometry, r.clearance_mm, r.method, r.seed, r.t_obs_s
    );
    println!(
        "hole offset: x {:.2} y {:.2} z {:.2} mm, roll {:.2} pitch {:.2} yaw {:.2} deg",
        o[0], o[1], o[2], o[3], o[4], o[5]
    );
    if let Some(e) = &r.errors {
        println!(
            "estimate error: x {:.3} y {:.3} z {:.3} mm, roll {:.3} pitch {:.3} yaw {:.3} deg",
            e.x_mm, e.y_mm, e.z_mm, e.roll_deg, e.pitch_deg, e.yaw_deg
        );
    }
    if let Some(t) = r.observation_s {
        let why = (r.observation_stop).map_or(String::new(), |s| format!(" ({})", s.name()));
        println!("observed {t} s of at most {} s{why}", r.t_obs_s);
    }
    if let Some(w) = r.widened {
        println!(
            "widened after its checks: lateral {}, tilt {}, yaw {}",
            w.lateral, w.tilt, w.yaw
        );
    }
    if let Some(std) = r.estimate_std {
        let s = pegtwin::pose::Pose6(std).to_mm_deg();
        println!(
            "estimate std:   x {:.3} y {:.3} z {:.3} mm, roll {:.3} pitch {:.3} yaw {:.3} deg",
            s[0], s[1], s[2], s[3], s[4], s[5]
        );
    }
    println!(
        "outcome: {} ({}); {} contact observations, {} used; Fz peak {:.1} N, mean {:.1} N",
        r.outcome,
        match r.final_depth_mm {
            Some(d) => format!("tip {d:.2} mm below the mouth"),
            None => "not inserted".into(),
        },
        r.contact_observations,
        r.observations_used,
        r.peak_fz_n,
        r.mean_fz_n
    );
    if let Some(why) = &r.stopped {
        println!("stopped before inserting: {why}");
    }
    if let Some(f) = &r.fault {
        println!("sim_fault at {:.3} s: {}", f.time_s, f.reason);
    }
    let t = &r.times;
    println!(
        "time: search {:.1} s, observe {:.1} s, register {:.2} s wall, retract {:.2} s, align {:.2} s, insert {:.2} s; {:.1} s wall in all",
        t.search_s, t.observe_s, t.register_wall_s, t.retract_s, t.align_s, t.insert_s, r.wall_s
    );
}
