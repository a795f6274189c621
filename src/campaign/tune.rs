//! Gain tuning: which impedance gains of the observation and insertion phases give the highest
//! success rate and the lowest peak force, for a scenario; or ([`TuneTarget::Direct`]) which
//! insertion of the direct baseline does, as the paper tuned its baseline (V-B).
//!
//! Search: a Latin hypercube over the gains (space-filling, seeded), then successive halving
//! (Jamieson and Talwalkar 2016, as Hyperband's inner loop and Optuna's pruner): every candidate
//! runs a few trials per cell, the best `1/ETA` go on with `ETA` times as many, until one rung
//! is left or the trial budget per candidate reaches the scenario's `trials`. Rungs reuse the
//! campaign's trials (same seeds, so every candidate meets the same hole offsets: common random
//! numbers make the comparison sharper than independent draws would). Where the candidates differ
//! only after the observation (the direct and insertion targets), a rung's trials of a seed share
//! one observation ([`crate::campaign::sharing`]), as a campaign's cells do: each record is the
//! one its trial gives alone, and the rung costs one observation per seed instead of one per
//! candidate.
//!
//! Score: success rate first, then the mean peak |Fz| of the successes (lower is better).
//!
//! The scenario's own settings run beside the hypercube as one more candidate, the incumbent
//! (the last id), as Optuna's `enqueue_trial` seeds a study with the known point: a search
//! returns them, not a worse point, when none of the drawn candidates beats them, and a tie goes
//! to them.
//!
//! Ranges (within KUKA Sunrise's: 0-5000 N/m, 0-300 N m/rad, damping 0.1-1.0): observation
//! translational stiffness 300-3000 N/m (x, y; z 1.5 x), rotational 2-50 N m/rad, damping 0.3-1.0;
//! insertion translational 300-5000 N/m (x, y; z 2000 N/m kept), rotational 10-300 N m/rad,
//! damping 0.3-1.0. The direct target's are in `DIRECT_AXES`, the method's insertion target's in
//! `INSERTION_AXES`. Stiffnesses and forces are drawn log-uniformly.

use crate::campaign::journal::Journal;
use crate::campaign::records::{TrialRecord, TrialSpec};
use crate::campaign::run::{
    CampaignTrials, Plan, Prepared, RunOptions, Shard, prepare, run_trials,
};
use crate::campaign::scenario::{GainsOverride, Scenario};
use crate::choice::{Choice, Named};
use crate::error::{Error, Result};
use crate::method::config::{Method, TrialConfig};
use crate::twin::control::ImpedanceGains;
use rand::SeedableRng;
use rand::seq::SliceRandom;
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use std::path::Path;

/// Survivors of a rung: one in `ETA`.
const ETA: usize = 3;

/// What the search tunes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum TuneTarget {
    /// The observation and insertion gains of every method (`[gains.observe]`,
    /// `[gains.insert]`).
    #[default]
    Gains,
    /// The direct baseline's insertion, as the paper tuned it ("impedance parameters optimized
    /// for higher success", V-B): its insertion stiffness and damping and its seat force
    /// (`[direct.gains.insert]`, `[direct.insertion]`); only the scenario's direct cells run.
    Direct,
    /// The manifold method's insertion alone (paper IV-E: "optimized compliance parameters"), with
    /// the observation's gains kept: its stiffness (z included), damping, overshoot past the
    /// believed floor and seat force (`[gains.insert]`, `[insertion]`); only the scenario's
    /// manifold cells run.
    Insertion,
}

impl Choice for TuneTarget {
    const WHAT: &'static str = "target";
    const NAMED: &'static [Named<Self>] = &[
        Named {
            name: "gains",
            value: TuneTarget::Gains,
            help: "the observation and insertion gains of every method",
        },
        Named {
            name: "direct",
            value: TuneTarget::Direct,
            help: "the direct baseline's insertion: stiffness, damping and seat force (the paper tuned it)",
        },
        Named {
            name: "insertion",
            value: TuneTarget::Insertion,
            help: "the manifold method's insertion: stiffness (z too), damping, overshoot and seat force",
        },
    ];
}

/// One tuned parameter: its name (a column of tune.csv), its range, and whether it is drawn
/// log-uniformly.
#[derive(Clone, Copy, Debug)]
struct Axis {
    name: &'static str,
    lo: f64,
    hi: f64,
    log: bool,
}

const fn axis(name: &'static str, lo: f64, hi: f64, log: bool) -> Axis {
    Axis { name, lo, hi, log }
}

/// [`TuneTarget::Gains`]: observation x, y stiffness (N/m; z is 1.5 x), rotational (N m/rad),
/// damping; insertion x, y (N/m; z 2000 N/m kept), rotational, damping.
const GAINS_AXES: [Axis; 6] = [
    axis("observe_n_per_m", 300.0, 3000.0, true),
    axis("observe_nm_per_rad", 2.0, 50.0, true),
    axis("observe_damping", 0.3, 1.0, false),
    axis("insert_n_per_m", 300.0, 5000.0, true),
    axis("insert_nm_per_rad", 10.0, 300.0, true),
    axis("insert_damping", 0.3, 1.0, false),
];

/// [`TuneTarget::Direct`]: insertion x, y and z stiffness (N/m), rotational (N m/rad), damping,
/// and the seat force (N; at the jam force's 40 N the seat condition never acts: the baseline
/// may push as hard as it likes).
const DIRECT_AXES: [Axis; 5] = [
    axis("insert_n_per_m", 300.0, 5000.0, true),
    axis("insert_z_n_per_m", 500.0, 5000.0, true),
    axis("insert_nm_per_rad", 10.0, 300.0, true),
    axis("insert_damping", 0.3, 1.0, false),
    axis("seat_force_n", 3.0, 40.0, true),
];

/// [`TuneTarget::Insertion`]: insertion x, y and z stiffness (N/m), rotational (N m/rad),
/// damping, how far the target goes past the believed floor (mm: the compliance turns it into
/// the push that carries the peg past friction; the registration's z error is about 2 mm), the
/// seat force (N) and how far above the believed floor the seat break arms (mm: a window wider
/// than the z error also stops a peg that a wall holds short of the floor).
const INSERTION_AXES: [Axis; 7] = [
    axis("insert_n_per_m", 300.0, 5000.0, true),
    axis("insert_z_n_per_m", 500.0, 5000.0, true),
    axis("insert_nm_per_rad", 5.0, 300.0, true),
    axis("insert_damping", 0.3, 1.0, false),
    axis("overshoot_mm", 2.0, 15.0, false),
    axis("seat_force_n", 3.0, 40.0, true),
    axis("seat_window_mm", 1.0, 10.0, false),
];

impl TuneTarget {
    fn axes(self) -> &'static [Axis] {
        match self {
            TuneTarget::Gains => &GAINS_AXES,
            TuneTarget::Direct => &DIRECT_AXES,
            TuneTarget::Insertion => &INSERTION_AXES,
        }
    }

    /// Whether the target's candidates differ only after the observation, so that their trials
    /// of a seed can share it.
    fn after_observation(self) -> bool {
        match self {
            TuneTarget::Gains => false,
            TuneTarget::Direct | TuneTarget::Insertion => true,
        }
    }

    /// The one method whose cells the target runs, if it runs one only.
    pub fn only_method(self) -> Option<Method> {
        match self {
            TuneTarget::Gains => None,
            TuneTarget::Direct => Some(Method::Direct),
            TuneTarget::Insertion => Some(Method::Manifold),
        }
    }
}

/// One point of the search space.
#[derive(Clone, Debug)]
pub struct Candidate {
    pub id: usize,
    pub target: TuneTarget,
    /// The value of each of the target's axes, in their order.
    pub values: Vec<f64>,
    /// The scenario's own settings ([`incumbent`]): they run as the scenario has them (their
    /// `values` only read them), whatever form its gains take.
    pub incumbent: bool,
}

/// One evaluation of a candidate at a rung.
#[derive(Clone, Debug)]
pub struct Evaluation {
    pub rung: usize,
    pub trials_per_cell: usize,
    pub candidate: Candidate,
    pub trials: usize,
    pub successes: usize,
    pub success_rate: f64,
    /// Mean peak |Fz| of the successes, N (`NaN` without any).
    pub peak_fz_n: f64,
}

/// What the search was asked to do.
#[derive(Clone, Debug)]
pub struct TuneOptions {
    /// Candidates of the first rung.
    pub candidates: usize,
    /// Trials per cell at the first rung.
    pub first_trials: usize,
    pub seed: u64,
    pub target: TuneTarget,
}

impl Default for TuneOptions {
    fn default() -> Self {
        TuneOptions {
            candidates: 27,
            first_trials: 2,
            seed: 1,
            target: TuneTarget::Gains,
        }
    }
}

/// `[lo, hi]` at `u` in [0, 1], log-uniform.
fn log_lerp(lo: f64, hi: f64, u: f64) -> f64 {
    (lo.ln() + u * (hi.ln() - lo.ln())).exp()
}

fn lerp(lo: f64, hi: f64, u: f64) -> f64 {
    lo + u * (hi - lo)
}

/// A Latin hypercube of `n` points in [0, 1]^d: each axis cut in `n` strata, one point per
/// stratum, strata paired at random; the point at each stratum's centre (reproducible).
pub(crate) fn latin_hypercube(n: usize, d: usize, seed: u64) -> Vec<Vec<f64>> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let columns: Vec<Vec<usize>> = (0..d)
        .map(|_| {
            let mut p: Vec<usize> = (0..n).collect();
            p.shuffle(&mut rng);
            p
        })
        .collect();
    (0..n)
        .map(|i| {
            columns
                .iter()
                .map(|c| (c[i] as f64 + 0.5) / n as f64)
                .collect()
        })
        .collect()
}

/// The candidates of the first rung.
pub fn candidates(n: usize, seed: u64, target: TuneTarget) -> Vec<Candidate> {
    let axes = target.axes();
    latin_hypercube(n, axes.len(), seed)
        .into_iter()
        .enumerate()
        .map(|(id, u)| Candidate {
            id,
            target,
            values: axes
                .iter()
                .zip(u)
                .map(|(a, u)| {
                    if a.log {
                        log_lerp(a.lo, a.hi, u)
                    } else {
                        lerp(a.lo, a.hi, u)
                    }
                })
                .collect(),
            incumbent: false,
        })
        .collect()
}

/// The configuration of the cells a target tunes, as `scenario` sets them: its first cell of the
/// target's method (for [`TuneTarget::Gains`], its first that registers, or else its first).
fn tuned_config(scenario: &Scenario, target: TuneTarget) -> TrialConfig {
    let cells = scenario.cells();
    let wanted = |m: Method| target.only_method().map_or(m != Method::Direct, |t| t == m);
    let cell = (cells.iter())
        .find(|c| wanted(c.method))
        .or(cells.first())
        .expect("a valid scenario has cells");
    scenario.trial_config(cell)
}

/// The value of the axis `name` in a trial configuration.
fn setting(c: &TrialConfig, name: &str) -> f64 {
    let (obs, ins) = (&c.observe_gains, &c.insert_gains);
    match name {
        "observe_n_per_m" => obs.stiffness[0],
        "observe_nm_per_rad" => obs.stiffness[3],
        "observe_damping" => obs.damping_ratio[0],
        "insert_n_per_m" => ins.stiffness[0],
        "insert_z_n_per_m" => ins.stiffness[2],
        "insert_nm_per_rad" => ins.stiffness[3],
        "insert_damping" => ins.damping_ratio[0],
        "overshoot_mm" => c.insert_overshoot_m * 1e3,
        "seat_force_n" => c.insert_seat_force_n,
        "seat_window_mm" => c.insert_seat_window_m * 1e3,
        _ => unreachable!("every axis has a setting: {name}"),
    }
}

/// The incumbent: the scenario's own settings, as candidate `id` (its `values` are read from
/// the cells the target tunes; x's stiffness and damping stand for a phase's).
pub fn incumbent(scenario: &Scenario, target: TuneTarget, id: usize) -> Candidate {
    let config = tuned_config(scenario, target);
    Candidate {
        id,
        target,
        values: (target.axes().iter())
            .map(|a| setting(&config, a.name))
            .collect(),
        incumbent: true,
    }
}

/// Sets the diagonal stiffness (x, y translational, z, rotational) and one damping ratio of a
/// phase's override, keeping its other fields.
fn set_gains(g: &mut GainsOverride, t: f64, tz: f64, r: f64, d: f64) {
    g.stiffness = Some([t, t, tz, r, r, r]);
    g.damping_ratio = Some([d; 6]);
}

/// A `[section]` of gains as TOML.
fn gains_toml(section: &str, g: &ImpedanceGains) -> String {
    let [x, y, z, a, b, c] = g.stiffness;
    let d = g.damping_ratio.map(|d| format!("{d:.2}")).join(", ");
    format!(
        "[{section}]\nstiffness = [{x:.0}, {y:.0}, {z:.0}, {a:.1}, {b:.1}, {c:.1}]\n\
         damping_ratio = [{d}]\n"
    )
}

impl Candidate {
    /// The value of the axis named `name`.
    fn get(&self, name: &str) -> f64 {
        let k = self.target.axes().iter().position(|a| a.name == name);
        self.values[k.expect("an axis of the target")]
    }

    /// The scenario with this candidate's settings (other overrides of the scenario kept); for
    /// the direct and insertion targets, only the cells they tune.
    pub fn apply(&self, scenario: &Scenario) -> Scenario {
        let mut s = scenario.clone();
        if let Some(method) = self.target.only_method() {
            s.methods = vec![method];
        }
        if self.incumbent {
            return s;
        }
        let v = |name| self.get(name);
        match self.target {
            TuneTarget::Gains => {
                let o = v("observe_n_per_m");
                let (r, d) = (v("observe_nm_per_rad"), v("observe_damping"));
                set_gains(&mut s.gains.observe, o, 1.5 * o, r, d);
                let (i, r, d) = (
                    v("insert_n_per_m"),
                    v("insert_nm_per_rad"),
                    v("insert_damping"),
                );
                set_gains(&mut s.gains.insert, i, 2000.0, r, d);
            }
            TuneTarget::Direct => {
                set_gains(
                    &mut s.direct.gains.insert,
                    v("insert_n_per_m"),
                    v("insert_z_n_per_m"),
                    v("insert_nm_per_rad"),
                    v("insert_damping"),
                );
                s.direct.insertion.seat_force_n = Some(v("seat_force_n"));
            }
            TuneTarget::Insertion => {
                set_gains(
                    &mut s.gains.insert,
                    v("insert_n_per_m"),
                    v("insert_z_n_per_m"),
                    v("insert_nm_per_rad"),
                    v("insert_damping"),
                );
                s.insertion.overshoot_mm = Some(v("overshoot_mm"));
                s.insertion.seat_force_n = Some(v("seat_force_n"));
                s.insertion.seat_window_mm = Some(v("seat_window_mm"));
            }
        }
        s
    }

    /// The candidate's settings as a scenario snippet: the gains and settings the tuned cells
    /// run with under it (the incumbent's: the scenario's own, written out).
    pub fn snippet(&self, scenario: &Scenario) -> String {
        let c = tuned_config(&self.apply(scenario), self.target);
        let v = |name| setting(&c, name);
        match self.target {
            TuneTarget::Gains => format!(
                "{}\n{}",
                gains_toml("gains.observe", &c.observe_gains),
                gains_toml("gains.insert", &c.insert_gains)
            ),
            TuneTarget::Direct => format!(
                "{}\n[direct.insertion]\nseat_force_n = {:.1}\n",
                gains_toml("direct.gains.insert", &c.insert_gains),
                v("seat_force_n")
            ),
            TuneTarget::Insertion => format!(
                "{}\n[insertion]\novershoot_mm = {:.1}\nseat_force_n = {:.1}\nseat_window_mm = {:.1}\n",
                gains_toml("gains.insert", &c.insert_gains),
                v("overshoot_mm"),
                v("seat_force_n"),
                v("seat_window_mm")
            ),
        }
    }
}

/// Orders evaluations best first: success rate, then lower peak force, then the incumbent, then
/// id.
fn rank(evals: &mut [Evaluation]) {
    let fz = |e: &Evaluation| {
        if e.peak_fz_n.is_nan() {
            f64::INFINITY
        } else {
            e.peak_fz_n
        }
    };
    evals.sort_by(|a, b| {
        b.success_rate
            .total_cmp(&a.success_rate)
            .then(fz(a).total_cmp(&fz(b)))
            .then(b.candidate.incumbent.cmp(&a.candidate.incumbent))
            .then(a.candidate.id.cmp(&b.candidate.id))
    });
}

/// The evaluations of `batch` at `rung`, `trials_per_cell` trials per cell each, in its order:
/// every candidate's trials run as one plan (the candidates' cells side by side), so that trials
/// of a seed that observe alike share their observation.
pub fn evaluate_candidates(
    scenario: &Scenario,
    prepared: &Prepared,
    batch: &[Candidate],
    rung: usize,
    trials_per_cell: usize,
) -> Result<Vec<Evaluation>> {
    let (mut cells, mut specs, mut spans) = (Vec::new(), Vec::new(), Vec::new());
    for candidate in batch {
        let mut s = candidate.apply(scenario);
        s.trials = trials_per_cell;
        s.ensure_valid()?;
        let first = specs.len();
        let offset = cells.len();
        let own = CampaignTrials::of(&s, Shard::WHOLE);
        specs.extend(own.iter().map(|t| TrialSpec {
            cell: t.cell + offset,
            ..t
        }));
        spans.push(first..specs.len());
        cells.extend(s.plan());
    }
    let records = run_trials(&Plan::of_cells(cells, prepared), &specs);
    Ok((batch.iter().zip(spans))
        .map(|(c, span)| evaluation(c, rung, trials_per_cell, &records[span]))
        .collect())
}

/// A candidate's evaluation from its trials' records.
fn evaluation(
    candidate: &Candidate,
    rung: usize,
    trials_per_cell: usize,
    records: &[TrialRecord],
) -> Evaluation {
    let successes = records.iter().filter(|r| r.result.success).count();
    let peaks: Vec<f64> = records
        .iter()
        .filter(|r| r.result.success)
        .map(|r| r.result.peak_fz_n)
        .collect();
    Evaluation {
        rung,
        trials_per_cell,
        candidate: candidate.clone(),
        trials: records.len(),
        successes,
        success_rate: successes as f64 / records.len().max(1) as f64,
        peak_fz_n: crate::campaign::summary::MeanStd::of(&peaks).map_or(f64::NAN, |m| m.mean),
    }
}

/// What a search has finished, kept in a [`Journal`] as it goes, so that a killed search
/// resumes (`tune --resume`) to the result an uninterrupted one gives: each evaluation is a pure
/// function of the scenario, the options, the candidate, its rung and its trials.
pub struct TuneJournal {
    journal: Journal,
    known: Vec<Evaluation>,
}

/// The journal's file in a tune's output folder.
pub const TUNE_JOURNAL: &str = "tune-journal.jsonl";

impl TuneJournal {
    /// The journal of the search `options` on `scenario` in the folder `dir`: new, or with
    /// `resume` the one a search with the same scenario and options left there.
    pub fn open(
        dir: &Path,
        scenario: &Scenario,
        options: &TuneOptions,
        resume: bool,
    ) -> Result<Self> {
        let header = serde_json::json!({
            "tune": 1,
            "scenario": scenario.fingerprint(),
            "candidates": options.candidates,
            "first_trials": options.first_trials,
            "seed": options.seed,
            "target": options.target.name(),
            "incumbent": true,
        });
        let (journal, entries) = Journal::open(&dir.join(TUNE_JOURNAL), &header, resume)?;
        let known = (entries.iter())
            .map(|e| evaluation_from_json(e, options.target))
            .collect::<Option<Vec<_>>>()
            .ok_or_else(|| {
                Error::file(
                    dir.join(TUNE_JOURNAL),
                    "holds an entry that is not an evaluation: choose another --out",
                )
            })?;
        Ok(TuneJournal { journal, known })
    }

    /// How many evaluations it holds.
    pub fn len(&self) -> usize {
        self.known.len()
    }

    /// Whether it holds none.
    pub fn is_empty(&self) -> bool {
        self.known.is_empty()
    }

    /// The evaluation of `candidate` at `rung` with `trials` per cell, if it was finished.
    fn known(&self, candidate: &Candidate, rung: usize, trials: usize) -> Option<Evaluation> {
        (self.known.iter())
            .find(|e| {
                e.rung == rung && e.trials_per_cell == trials && e.candidate.id == candidate.id
            })
            .cloned()
    }

    /// Keeps a finished evaluation.
    fn record(&self, e: &Evaluation) -> Result<()> {
        self.journal.append(&serde_json::json!({
            "rung": e.rung,
            "trials_per_cell": e.trials_per_cell,
            "id": e.candidate.id,
            "values": e.candidate.values,
            "incumbent": e.candidate.incumbent,
            "trials": e.trials,
            "successes": e.successes,
            "peak_fz_n": (!e.peak_fz_n.is_nan()).then_some(e.peak_fz_n),
        }))
    }
}

/// An evaluation [`TuneJournal::record`] wrote, if `v` is one (with a value for each of the
/// target's axes: a journal of a search over fewer axes is not one).
fn evaluation_from_json(v: &serde_json::Value, target: TuneTarget) -> Option<Evaluation> {
    let count = |key: &str| v.get(key)?.as_u64().map(|n| n as usize);
    let values = (v.get("values")?.as_array()?.iter())
        .map(|x| x.as_f64())
        .collect::<Option<Vec<f64>>>()
        .filter(|v| v.len() == target.axes().len())?;
    let (trials, successes) = (count("trials")?, count("successes")?);
    let peak = v.get("peak_fz_n")?;
    Some(Evaluation {
        rung: count("rung")?,
        trials_per_cell: count("trials_per_cell")?,
        candidate: Candidate {
            id: count("id")?,
            target,
            values,
            incumbent: v.get("incumbent")?.as_bool()?,
        },
        trials,
        successes,
        success_rate: successes as f64 / trials.max(1) as f64,
        peak_fz_n: if peak.is_null() {
            f64::NAN
        } else {
            peak.as_f64()?
        },
    })
}

/// Runs the search; returns every evaluation, rung by rung, best first within a rung.
/// `on_rung` is told each rung's size before it runs. With a `journal`, each evaluation it holds
/// is taken from it and each new one is written to it as soon as it is finished.
pub fn tune(
    scenario: &Scenario,
    options: &TuneOptions,
    run: &RunOptions,
    on_rung: &dyn Fn(usize, usize, usize),
    journal: Option<&TuneJournal>,
) -> Result<Vec<Evaluation>> {
    if options.candidates == 0 || options.first_trials == 0 {
        return Err(Error::Input(
            "tune: expected at least 1 candidate and 1 trial per cell".into(),
        ));
    }
    if let Some(method) = options.target.only_method()
        && !scenario.methods.contains(&method)
    {
        return Err(Error::Input(format!(
            "tune --target {}: the scenario has no {} cells (methods)",
            options.target.name(),
            method.name()
        )));
    }
    let probe = candidates(1, options.seed, options.target)[0].apply(scenario);
    let every_cell: Vec<usize> = (0..probe.cells().len()).collect();
    let prepared = prepare(&probe, &every_cell, run)?;
    let mut alive = candidates(options.candidates, options.seed, options.target);
    alive.push(incumbent(scenario, options.target, options.candidates));
    let mut trials = options.first_trials.min(scenario.trials);
    let mut out = Vec::new();
    for rung in 0.. {
        on_rung(rung, alive.len(), trials);
        let mut evals = run_rung(scenario, options, &prepared, &alive, rung, trials, journal)?;
        rank(&mut evals);
        let last = alive.len() <= 1 || trials >= scenario.trials;
        alive = evals
            .iter()
            .take(alive.len().div_ceil(ETA))
            .map(|e| e.candidate.clone())
            .collect();
        out.extend(evals);
        if last {
            break;
        }
        trials = (trials * ETA).min(scenario.trials);
    }
    Ok(out)
}

/// The evaluations of the candidates `alive` at a rung, in their order: those `journal` holds
/// from it, the others run and kept in it. Candidates that differ after the observation only run
/// together, sharing each seed's observation (kept as the rung ends); others run side by side,
/// each kept as soon as it finishes.
fn run_rung(
    scenario: &Scenario,
    options: &TuneOptions,
    prepared: &Prepared,
    alive: &[Candidate],
    rung: usize,
    trials: usize,
    journal: Option<&TuneJournal>,
) -> Result<Vec<Evaluation>> {
    let known = |c: &Candidate| journal.and_then(|j| j.known(c, rung, trials));
    let keep = |e: &Evaluation| journal.map_or(Ok(()), |j| j.record(e));
    if !options.target.after_observation() {
        return (alive.par_iter())
            .map(|c| {
                if let Some(e) = known(c) {
                    return Ok(e);
                }
                let e =
                    evaluate_candidates(scenario, prepared, std::slice::from_ref(c), rung, trials)?;
                let e = e.into_iter().next().expect("one evaluation per candidate");
                keep(&e)?;
                Ok(e)
            })
            .collect();
    }
    let known: Vec<Option<Evaluation>> = alive.iter().map(known).collect();
    let unknown: Vec<Candidate> = (alive.iter().zip(&known))
        .filter(|(_, k)| k.is_none())
        .map(|(c, _)| c.clone())
        .collect();
    let fresh = if unknown.is_empty() {
        Vec::new()
    } else {
        evaluate_candidates(scenario, prepared, &unknown, rung, trials)?
    };
    let mut fresh = fresh.into_iter();
    (known.into_iter())
        .map(|k| match k {
            Some(e) => Ok(e),
            None => {
                let e = fresh.next().expect("an evaluation per unknown candidate");
                keep(&e)?;
                Ok(e)
            }
        })
        .collect()
}

/// The evaluations as CSV, one row per candidate and rung; a column per tuned axis.
pub fn evaluations_csv(evals: &[Evaluation]) -> Vec<u8> {
    let mut w = csv::Writer::from_writer(Vec::new());
    let axes = evals.first().map_or(&[][..], |e| e.candidate.target.axes());
    let head = ["rung", "trials_per_cell", "candidate", "incumbent"].into_iter();
    let tail = ["trials", "successes", "success_rate", "peak_fz_n"].into_iter();
    w.write_record(head.chain(axes.iter().map(|a| a.name)).chain(tail))
        .expect("in-memory csv");
    for e in evals {
        let c = &e.candidate;
        let values = c.values.iter().map(|v| format!("{v:.3}"));
        let peak = if e.peak_fz_n.is_nan() {
            String::new()
        } else {
            format!("{:.2}", e.peak_fz_n)
        };
        let row = [e.rung, e.trials_per_cell, c.id]
            .map(|n| n.to_string())
            .into_iter()
            .chain([c.incumbent.to_string()])
            .chain(values)
            .chain([
                e.trials.to_string(),
                e.successes.to_string(),
                format!("{:.4}", e.success_rate),
                peak,
            ]);
        w.write_record(row).expect("in-memory csv");
    }
    w.into_inner().expect("in-memory csv")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn latin_hypercube_has_one_point_per_stratum() {
        let pts = latin_hypercube(7, 6, 3);
        for d in 0..6 {
            let mut strata: Vec<usize> = pts.iter().map(|p| (p[d] * 7.0) as usize).collect();
            strata.sort();
            assert_eq!(strata, (0..7).collect::<Vec<_>>());
        }
    }

    #[test]
    fn candidates_stay_in_the_sunrise_ranges() {
        let base = "name = \"t\"\ntrials = 1\ngeometries = [\"cross\"]\nclearances_mm = [0.5]\nt_obs_s = [6.0]\nmethods = [\"manifold\", \"direct\"]\n";
        let scenario = Scenario::parse(base).unwrap();
        for c in candidates(20, 1, TuneTarget::Gains) {
            c.apply(&scenario).ensure_valid().unwrap();
            let snippet = Scenario::parse(&format!("{base}{}", c.snippet(&scenario))).unwrap();
            assert_eq!(snippet.gains.insert.stiffness.unwrap()[2], 2000.0);
            assert_eq!(snippet.gains.observe.additional_force, None);
        }
        for c in candidates(20, 1, TuneTarget::Direct) {
            let tuned = c.apply(&scenario);
            tuned.ensure_valid().unwrap();
            assert_eq!(tuned.methods, vec![Method::Direct]);
            let snippet = Scenario::parse(&format!("{base}{}", c.snippet(&scenario))).unwrap();
            let seat = snippet.direct.insertion.seat_force_n.unwrap();
            assert!((seat - c.get("seat_force_n")).abs() < 0.051, "{seat}");
            assert_eq!(snippet.gains, scenario.gains, "the method's gains stay");
        }
        for c in candidates(20, 1, TuneTarget::Insertion) {
            let tuned = c.apply(&scenario);
            tuned.ensure_valid().unwrap();
            assert_eq!(tuned.methods, vec![Method::Manifold]);
            let snippet = Scenario::parse(&format!("{base}{}", c.snippet(&scenario))).unwrap();
            let over = snippet.insertion.overshoot_mm.unwrap();
            assert!((over - c.get("overshoot_mm")).abs() < 0.051, "{over}");
            let window = snippet.insertion.seat_window_mm.unwrap();
            assert!((window - c.get("seat_window_mm")).abs() < 0.051, "{window}");
            let z = snippet.gains.insert.stiffness.unwrap()[2];
            assert!((z - c.get("insert_z_n_per_m")).abs() < 0.51, "{z}");
            assert_eq!(snippet.gains.observe, scenario.gains.observe);
        }
    }

    /// The incumbent runs the scenario as it is, reads its settings, and its snippet writes them
    /// out: pasted into the scenario, the tuned cells run as before.
    #[test]
    fn the_incumbent_is_the_scenario_as_it_is() {
        let head = "name = \"t\"\ntrials = 1\ngeometries = [\"cross\"]\nclearances_mm = [0.5]\nt_obs_s = [6.0]\nmethods = [\"manifold\", \"direct\"]\n";
        let own_gains = "[gains.insert]\nstiffness = [1000, 1200, 2000, 30, 40, 50]\n";
        let scenario = Scenario::parse(&format!("{head}{own_gains}")).unwrap();
        for target in [TuneTarget::Gains, TuneTarget::Direct, TuneTarget::Insertion] {
            let own = incumbent(&scenario, target, 9);
            assert!(own.incumbent && own.id == 9);
            let applied = own.apply(&scenario);
            let pasted = Scenario::parse(&format!("{head}{}", own.snippet(&scenario))).unwrap();
            for cell in applied.cells() {
                let before = scenario.trial_config(&cell);
                let (as_is, from_snippet) =
                    (applied.trial_config(&cell), pasted.trial_config(&cell));
                assert_eq!(as_is.insert_gains, before.insert_gains, "{target:?}");
                assert_eq!(as_is.observe_gains, before.observe_gains, "{target:?}");
                let close = |a: &[f64; 6], b: &[f64; 6]| {
                    a.iter()
                        .zip(b)
                        .all(|(a, b)| (a - b).abs() <= 0.05 + 0.005 * b.abs())
                };
                let (p, b) = (&from_snippet.insert_gains, &before.insert_gains);
                assert!(close(&p.stiffness, &b.stiffness), "{target:?}: {p:?}");
                assert!(close(&p.damping_ratio, &b.damping_ratio), "{target:?}");
            }
        }
        let own = incumbent(&scenario, TuneTarget::Gains, 0);
        assert_eq!(own.get("insert_n_per_m"), 1000.0, "x stands for the phase");
        assert_eq!(own.get("insert_nm_per_rad"), 30.0);
    }

    /// A candidate must beat the scenario's own settings to replace them.
    #[test]
    fn a_tie_goes_to_the_incumbent() {
        let scenario = Scenario::parse("name = \"t\"\ntrials = 1\ngeometries = [\"cross\"]\nclearances_mm = [0.5]\nt_obs_s = [6.0]\nmethods = [\"manifold\"]\n").unwrap();
        let at = |candidate: Candidate, peak_fz_n| Evaluation {
            rung: 0,
            trials_per_cell: 1,
            candidate,
            trials: 2,
            successes: 1,
            success_rate: 0.5,
            peak_fz_n,
        };
        let drawn = candidates(2, 1, TuneTarget::Gains);
        let own = incumbent(&scenario, TuneTarget::Gains, 2);
        let mut evals = vec![
            at(drawn[0].clone(), 5.0),
            at(own.clone(), 5.0),
            at(drawn[1].clone(), 4.0),
        ];
        rank(&mut evals);
        let order: Vec<usize> = evals.iter().map(|e| e.candidate.id).collect();
        assert_eq!(order, [1, 2, 0]);
    }
}
