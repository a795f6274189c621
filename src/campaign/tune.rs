//! Gain tuning: which impedance gains of the observation and insertion phases give the highest
//! success rate and the lowest peak force, for a scenario.
//!
//! Search: a Latin hypercube over the gains (space-filling, seeded), then successive halving
//! (Jamieson and Talwalkar 2016, as Hyperband's inner loop and Optuna's pruner): every candidate
//! runs a few trials per cell, the best `1/ETA` go on with `ETA` times as many, until one rung
//! is left or the trial budget per candidate reaches the scenario's `trials`. Rungs reuse the
//! campaign's trials (same seeds, so every candidate meets the same hole offsets: common random
//! numbers make the comparison sharper than independent draws would).
//!
//! Score: success rate first, then the mean peak |Fz| of the successes (lower is better).
//!
//! Ranges (within KUKA Sunrise's: 0-5000 N/m, 0-300 N m/rad, damping 0.1-1.0): observation
//! translational stiffness 300-3000 N/m (x, y; z 1.5 x), rotational 2-50 N m/rad, damping 0.3-1.0;
//! insertion translational 300-5000 N/m (x, y; z 2000 N/m kept), rotational 10-300 N m/rad,
//! damping 0.3-1.0. Stiffnesses are drawn log-uniformly.

use crate::campaign::records::TrialRecord;
use crate::campaign::run::{Prepared, RunOptions, all_trials, prepare, run_trials};
use crate::campaign::scenario::Scenario;
use crate::error::{Error, Result};
use rand::SeedableRng;
use rand::seq::SliceRandom;
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use serde::Serialize;

/// Survivors of a rung: one in `ETA`.
const ETA: usize = 3;

/// One point of the search space.
#[derive(Clone, Debug, Serialize)]
pub struct Candidate {
    pub id: usize,
    /// Observation: translational stiffness x, y (N/m; z is 1.5 x), rotational (N m/rad), damping.
    pub observe_n_per_m: f64,
    pub observe_nm_per_rad: f64,
    pub observe_damping: f64,
    /// Insertion: translational stiffness x, y (N/m), rotational (N m/rad), damping.
    pub insert_n_per_m: f64,
    pub insert_nm_per_rad: f64,
    pub insert_damping: f64,
}

/// One evaluation of a candidate at a rung.
#[derive(Clone, Debug, Serialize)]
pub struct Evaluation {
    pub rung: usize,
    pub trials_per_cell: usize,
    #[serde(flatten)]
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
}

impl Default for TuneOptions {
    fn default() -> Self {
        TuneOptions {
            candidates: 27,
            first_trials: 2,
            seed: 1,
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
fn latin_hypercube(n: usize, d: usize, seed: u64) -> Vec<Vec<f64>> {
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
pub fn candidates(n: usize, seed: u64) -> Vec<Candidate> {
    latin_hypercube(n, 6, seed)
        .into_iter()
        .enumerate()
        .map(|(id, u)| Candidate {
            id,
            observe_n_per_m: log_lerp(300.0, 3000.0, u[0]),
            observe_nm_per_rad: log_lerp(2.0, 50.0, u[1]),
            observe_damping: lerp(0.3, 1.0, u[2]),
            insert_n_per_m: log_lerp(300.0, 5000.0, u[3]),
            insert_nm_per_rad: log_lerp(10.0, 300.0, u[4]),
            insert_damping: lerp(0.3, 1.0, u[5]),
        })
        .collect()
}

impl Candidate {
    /// The scenario with this candidate's gains (other overrides of the scenario kept).
    pub fn apply(&self, scenario: &Scenario) -> Scenario {
        let mut s = scenario.clone();
        let (o, i) = (self.observe_n_per_m, self.insert_n_per_m);
        s.gains.observe.stiffness = Some([
            o,
            o,
            1.5 * o,
            self.observe_nm_per_rad,
            self.observe_nm_per_rad,
            self.observe_nm_per_rad,
        ]);
        s.gains.observe.damping_ratio = Some([self.observe_damping; 6]);
        s.gains.insert.stiffness = Some([
            i,
            i,
            2000.0,
            self.insert_nm_per_rad,
            self.insert_nm_per_rad,
            self.insert_nm_per_rad,
        ]);
        s.gains.insert.damping_ratio = Some([self.insert_damping; 6]);
        s
    }

    /// The gains as a scenario snippet.
    pub fn snippet(&self) -> String {
        let section = |name: &str, t: f64, tz: f64, r: f64, d: f64| {
            format!(
                "[gains.{name}]\nstiffness = [{t:.0}, {t:.0}, {tz:.0}, {r:.1}, {r:.1}, {r:.1}]\ndamping_ratio = [{d:.2}, {d:.2}, {d:.2}, {d:.2}, {d:.2}, {d:.2}]\n"
            )
        };
        let o = self.observe_n_per_m;
        format!(
            "{}\n{}",
            section(
                "observe",
                o,
                1.5 * o,
                self.observe_nm_per_rad,
                self.observe_damping
            ),
            section(
                "insert",
                self.insert_n_per_m,
                2000.0,
                self.insert_nm_per_rad,
                self.insert_damping
            )
        )
    }
}

/// Orders evaluations best first: success rate, then lower peak force, then id.
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
            .then(a.candidate.id.cmp(&b.candidate.id))
    });
}

fn evaluate(
    scenario: &Scenario,
    prepared: &Prepared,
    candidate: &Candidate,
    rung: usize,
    trials_per_cell: usize,
) -> Result<Evaluation> {
    let mut s = candidate.apply(scenario);
    s.trials = trials_per_cell;
    s.ensure_valid()?;
    let specs = all_trials(&s);
    let records: Vec<TrialRecord> = run_trials(&s, prepared, &specs);
    let successes = records.iter().filter(|r| r.result.success).count();
    let peaks: Vec<f64> = records
        .iter()
        .filter(|r| r.result.success)
        .map(|r| r.result.peak_fz_n)
        .collect();
    Ok(Evaluation {
        rung,
        trials_per_cell,
        candidate: candidate.clone(),
        trials: records.len(),
        successes,
        success_rate: successes as f64 / records.len().max(1) as f64,
        peak_fz_n: crate::campaign::summary::MeanStd::of(&peaks).map_or(f64::NAN, |m| m.mean),
    })
}

/// Runs the search; returns every evaluation, rung by rung, best first within a rung.
/// `on_rung` is told each rung's size before it runs.
pub fn tune(
    scenario: &Scenario,
    options: &TuneOptions,
    run: &RunOptions,
    on_rung: &dyn Fn(usize, usize, usize),
) -> Result<Vec<Evaluation>> {
    if options.candidates == 0 || options.first_trials == 0 {
        return Err(Error::Input(
            "tune: expected at least 1 candidate and 1 trial per cell".into(),
        ));
    }
    let prepared = prepare(scenario, &all_trials(scenario), run)?;
    let mut alive = candidates(options.candidates, options.seed);
    let mut trials = options.first_trials.min(scenario.trials);
    let mut out = Vec::new();
    for rung in 0.. {
        on_rung(rung, alive.len(), trials);
        let mut evals = alive
            .par_iter()
            .map(|c| evaluate(scenario, &prepared, c, rung, trials))
            .collect::<Result<Vec<_>>>()?;
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

/// The evaluations as CSV, one row per candidate and rung.
pub fn evaluations_csv(evals: &[Evaluation]) -> Vec<u8> {
    let mut w = csv::Writer::from_writer(Vec::new());
    w.write_record([
        "rung",
        "trials_per_cell",
        "candidate",
        "observe_n_per_m",
        "observe_nm_per_rad",
        "observe_damping",
        "insert_n_per_m",
        "insert_nm_per_rad",
        "insert_damping",
        "trials",
        "successes",
        "success_rate",
        "peak_fz_n",
    ])
    .expect("in-memory csv");
    for e in evals {
        let c = &e.candidate;
        w.write_record([
            e.rung.to_string(),
            e.trials_per_cell.to_string(),
            c.id.to_string(),
            format!("{:.1}", c.observe_n_per_m),
            format!("{:.2}", c.observe_nm_per_rad),
            format!("{:.3}", c.observe_damping),
            format!("{:.1}", c.insert_n_per_m),
            format!("{:.2}", c.insert_nm_per_rad),
            format!("{:.3}", c.insert_damping),
            e.trials.to_string(),
            e.successes.to_string(),
            format!("{:.4}", e.success_rate),
            if e.peak_fz_n.is_nan() {
                String::new()
            } else {
                format!("{:.2}", e.peak_fz_n)
            },
        ])
        .expect("in-memory csv");
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
        for c in candidates(20, 1) {
            let base = "name = \"t\"\ntrials = 1\ngeometries = [\"cross\"]\nclearances_mm = [0.5]\nt_obs_s = [6.0]\nmethods = [\"manifold\"]\n";
            let s = c.apply(&Scenario::parse(base).unwrap());
            s.ensure_valid().unwrap();
            let snippet = Scenario::parse(&format!("{base}{}", c.snippet())).unwrap();
            assert_eq!(snippet.gains.insert.stiffness.unwrap()[2], 2000.0);
        }
    }
}
