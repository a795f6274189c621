//! The regression gate: a campaign's summary against a committed baseline.
//!
//! A cell fails when
//! - its success rate falls below the baseline's 95 % Wilson lower bound;
//! - an axis' mean absolute error exceeds `baseline x (1 + mae_rel) + mae_abs` (mm or deg);
//! - the mean peak |Fz| of its successes exceeds `baseline x (1 + fz_rel) + fz_abs_n`;
//! - any of its trials ended in error (raised an error or panicked);
//! - or it is missing from the run.
//!
//! The tolerances live in the baseline file, so a project can loosen or tighten them where it
//! keeps its baseline. Cells are matched by geometry, clearance, method and t_obs; a run of a
//! different scenario (another fingerprint) is still compared cell by cell, with a warning.

use crate::campaign::summary::{AXES, CellSummary, Summary};
use crate::error::{Error, Result};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// How far a run may move from its baseline before the gate fails.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Tolerances {
    pub mae_rel: f64,
    pub mae_abs_mm: f64,
    pub mae_abs_deg: f64,
    pub fz_rel: f64,
    pub fz_abs_n: f64,
}

impl Default for Tolerances {
    fn default() -> Self {
        Tolerances {
            mae_rel: 0.5,
            mae_abs_mm: 0.25,
            mae_abs_deg: 0.25,
            fz_rel: 0.25,
            fz_abs_n: 3.0,
        }
    }
}

/// A baseline file.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Baseline {
    pub scenario: String,
    pub fingerprint: String,
    pub tolerances: Tolerances,
    pub cells: Vec<CellSummary>,
}

impl Baseline {
    /// A baseline from a run's summary with the default tolerances.
    pub fn from_summary(summary: &Summary) -> Self {
        Baseline {
            scenario: summary.scenario.clone(),
            fingerprint: summary.fingerprint.clone(),
            tolerances: Tolerances::default(),
            cells: summary.cells.clone(),
        }
    }

    /// Reads a baseline file, checked as a user's input is: a baseline that holds no cell would
    /// pass any run ("0 quantities compared"), and a tolerance that is negative or not finite
    /// (a NaN limit) would pass any quantity.
    pub fn load(path: &Path) -> Result<Self> {
        let text = crate::files::read_text(path)?;
        let b: Baseline = serde_json::from_str(&text).map_err(|e| {
            Error::file(path, format!("line {}: not a baseline file: {e}", e.line()))
        })?;
        if b.cells.is_empty() {
            return Err(Error::file(
                path,
                "cells = []: expected the cells of a finished campaign \
                 (pegtwin check DIR --write-baseline FILE)",
            ));
        }
        let t = &b.tolerances;
        for (field, v) in [
            ("mae_rel", t.mae_rel),
            ("mae_abs_mm", t.mae_abs_mm),
            ("mae_abs_deg", t.mae_abs_deg),
            ("fz_rel", t.fz_rel),
            ("fz_abs_n", t.fz_abs_n),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(Error::file(
                    path,
                    format!("tolerances.{field} = {v}: expected a finite value of at least 0"),
                ));
            }
        }
        Ok(b)
    }
}

/// One compared quantity.
#[derive(Clone, Debug, Serialize)]
pub struct Finding {
    pub cell: String,
    pub quantity: String,
    pub baseline: Option<f64>,
    pub now: Option<f64>,
    /// The bound `now` is held to (a lower bound for success, else an upper bound).
    pub limit: Option<f64>,
    pub failed: bool,
}

/// Compares a run with its baseline; every quantity compared is returned.
pub fn compare(summary: &Summary, baseline: &Baseline) -> Vec<Finding> {
    let tol = &baseline.tolerances;
    let mut out = Vec::new();
    for base in &baseline.cells {
        let label = base.cell.label();
        let Some(now) = summary.cells.iter().find(|c| c.cell == base.cell) else {
            out.push(Finding {
                cell: label,
                quantity: "cell".into(),
                baseline: None,
                now: None,
                limit: None,
                failed: true,
            });
            continue;
        };
        out.push(Finding {
            cell: label.clone(),
            quantity: "error_trials".into(),
            baseline: Some(base.error_trials as f64),
            now: Some(now.error_trials as f64),
            limit: Some(0.0),
            failed: now.error_trials > 0,
        });
        out.push(Finding {
            cell: label.clone(),
            quantity: "success_rate".into(),
            baseline: Some(base.success_rate),
            now: Some(now.success_rate),
            limit: Some(base.success_ci95[0]),
            failed: now.success_rate < base.success_ci95[0],
        });
        if let (Some(b), Some(n)) = (base.mae, now.mae) {
            for a in 0..6 {
                let abs = if a < 3 {
                    tol.mae_abs_mm
                } else {
                    tol.mae_abs_deg
                };
                let limit = b[a] * (1.0 + tol.mae_rel) + abs;
                out.push(Finding {
                    cell: label.clone(),
                    quantity: format!("mae_{}", AXES[a]),
                    baseline: Some(b[a]),
                    now: Some(n[a]),
                    limit: Some(limit),
                    failed: n[a] > limit,
                });
            }
        }
        if let (Some(b), Some(n)) = (base.peak_fz_success_n, now.peak_fz_success_n) {
            let limit = b.mean * (1.0 + tol.fz_rel) + tol.fz_abs_n;
            out.push(Finding {
                cell: label.clone(),
                quantity: "peak_fz_success_n".into(),
                baseline: Some(b.mean),
                now: Some(n.mean),
                limit: Some(limit),
                failed: n.mean > limit,
            });
        }
    }
    out
}

/// The findings as a table: the failed ones, then those that moved, then a count of the rest.
pub fn findings_table(findings: &[Finding]) -> String {
    let f = |v: Option<f64>| v.map_or("-".into(), |v| format!("{v:.3}"));
    let mut out = format!(
        "{:<6} {:<32} {:<22} {:>10} {:>10} {:>10}\n",
        "status", "cell", "quantity", "baseline", "now", "limit"
    );
    let moved = |x: &Finding| x.baseline != x.now;
    let failed = findings.iter().filter(|x| x.failed);
    let moved_ok = findings.iter().filter(|x| !x.failed && moved(x));
    for x in failed.chain(moved_ok) {
        out += &format!(
            "{:<6} {:<32} {:<22} {:>10} {:>10} {:>10}\n",
            if x.failed { "FAIL" } else { "ok" },
            x.cell,
            x.quantity,
            f(x.baseline),
            f(x.now),
            f(x.limit)
        );
    }
    let unchanged = findings.iter().filter(|x| !x.failed && !moved(x)).count();
    let failed = findings.iter().filter(|x| x.failed).count();
    out += &format!(
        "{} quantities compared, {unchanged} unchanged, {failed} failed\n",
        findings.len()
    );
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::campaign::records::{TrialSpec, read_records};
    use crate::campaign::run::{
        CampaignOptions, Plan, RunOptions, Runner, Shard, campaign_with, run_one,
    };
    use crate::campaign::scenario::Condition;
    use crate::campaign::scenario::Scenario;
    use crate::campaign::summary::{MeanStd, summarise, wilson_interval};
    use crate::method::config::Method;

    fn cell(successes: usize, mae_x: f64, fz: f64) -> CellSummary {
        CellSummary {
            cell: Condition {
                geometry: "cross".into(),
                clearance_mm: 0.5,
                method: Method::Manifold,
                t_obs_s: 6.0,
            },
            trials: 10,
            successes,
            sim_faults: 0,
            error_trials: 0,
            success_rate: successes as f64 / 10.0,
            success_ci95: wilson_interval(successes, 10),
            mae: Some([mae_x, 0.1, 2.0, 0.5, 0.5, 0.1]),
            abs_error_std: Some([0.1; 6]),
            coverage_2sigma: None,
            peak_fz_success_n: Some(MeanStd {
                mean: fz,
                std: 1.0,
                n: successes,
            }),
            peak_fz_failure_n: None,
            mean_phase_s: [0.0; 5],
            partial_to_full_s: None,
            failure_modes: Default::default(),
        }
    }

    fn summary(c: CellSummary) -> Summary {
        Summary {
            scenario: "s".into(),
            fingerprint: "f".into(),
            cells: vec![c],
            pooled: Vec::new(),
        }
    }

    #[test]
    fn passes_on_the_same_run_and_fails_on_each_kind_of_regression() {
        let base = Baseline::from_summary(&summary(cell(10, 0.1, 20.0)));
        let failed = |c: CellSummary| -> Vec<String> {
            compare(&summary(c), &base)
                .into_iter()
                .filter(|f| f.failed)
                .map(|f| f.quantity)
                .collect()
        };
        assert!(failed(cell(10, 0.1, 20.0)).is_empty());
        // 10/10 -> lower bound 72 %: 8/10 passes, 7/10 fails.
        assert!(failed(cell(8, 0.1, 20.0)).is_empty());
        assert_eq!(failed(cell(7, 0.1, 20.0)), ["success_rate"]);
        // MAE limit 0.1 x 1.5 + 0.25 = 0.4 mm.
        assert!(failed(cell(10, 0.39, 20.0)).is_empty());
        assert_eq!(failed(cell(10, 0.41, 20.0)), ["mae_x_mm"]);
        // Fz limit 20 x 1.25 + 3 = 28 N.
        assert_eq!(failed(cell(10, 0.1, 28.5)), ["peak_fz_success_n"]);
        let mut other = cell(10, 0.1, 20.0);
        other.cell.t_obs_s = 8.0;
        assert_eq!(failed(other), ["cell"]);
    }

    #[test]
    fn a_campaign_records_a_trial_that_panics_or_errs_and_goes_on() {
        let s = Scenario::parse(
            "name = \"t\"\ntrials = 3\ngeometries = [\"cross\"]\nclearances_mm = [1.0]\nt_obs_s = [1.0]\nmethods = [\"direct\"]\ndirect_t_obs_s = 1.0\n",
        )
        .unwrap();
        let dir = std::env::temp_dir().join(format!("pegtwin-errtrial-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let inject = |p: &Plan, spec: &TrialSpec| match spec.trial {
            1 => panic!("injected"),
            2 => Err(Error::Input("injected error".into())),
            _ => run_one(p, spec),
        };
        let run = RunOptions {
            cache_dir: dir.join("cache"),
            progress: &(),
        };
        let whole = CampaignOptions {
            shard: Shard::WHOLE,
            resume: false,
            replays: crate::campaign::replays::Replays::None,
        };
        let injected = Runner {
            one: &inject,
            sharing: None,
        };
        let out = campaign_with(&s, &dir.join("out"), whole, &run, &injected).unwrap();
        let records = read_records(&out.trials.path, false).unwrap();
        let outcomes: Vec<&str> = records.iter().map(|r| r.result.outcome.as_str()).collect();
        assert_eq!(outcomes[1..], ["error", "error"]);
        assert_ne!(outcomes[0], "error");
        assert_eq!(
            records[1].result.error_message.as_deref(),
            Some("panicked: injected")
        );
        assert!(
            records[2]
                .result
                .error_message
                .as_deref()
                .unwrap()
                .contains("injected error")
        );
        let summary = summarise(&s, &out.trials).unwrap();
        assert_eq!(summary.cells[0].error_trials, 2);
        let mut baseline = Baseline::from_summary(&summary);
        baseline.cells[0].error_trials = 0;
        let findings = compare(&summary, &baseline);
        assert!(
            findings
                .iter()
                .any(|f| f.quantity == "error_trials" && f.failed)
        );
        // --resume counts them as done.
        let again = CampaignOptions {
            resume: true,
            ..whole
        };
        let real = Runner {
            one: &run_one,
            sharing: None,
        };
        let resumed = campaign_with(&s, &dir.join("out"), again, &run, &real).unwrap();
        assert_eq!(resumed.ran, 0);
        let _ = std::fs::remove_dir_all(&dir);
    }
}
