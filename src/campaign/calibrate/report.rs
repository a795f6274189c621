//! What a calibration writes beside its draws: `posterior.csv` (every draw with its weight),
//! `posterior.json` (the quantiles, the predictions), `cell.toml` (the calibrated `[cell]`
//! section) and `report.html` (every figure beside its prediction, inside or outside).

use super::targets::{Measured, Role, Targets};
use super::{Posterior, calibrated_cell};
use crate::campaign::report::escape;
use crate::campaign::scenario::Scenario;
use crate::error::Result;
use std::fmt::Write;
use std::path::Path;

/// Writes the four files into `out`.
pub fn write(out: &Path, scenario: &Scenario, targets: &Targets, p: &Posterior) -> Result<()> {
    crate::files::write_atomically(&out.join("posterior.csv"), posterior_csv(p).as_bytes())?;
    let json = serde_json::to_vec_pretty(&serde_json::json!({
        "free": p.free,
        "prior": p.prior,
        "quantiles_5_50_95": p.quantiles,
        "effective_points": p.effective_points,
        "draws": p.evaluations.len(),
        "trials_per_draw": p.trials_per_draw,
        "targets": targets.targets.iter().zip(&p.predictive).map(|(t, pr)| serde_json::json!({
            "label": t.label,
            "role": t.target.role,
            "measured": t.measured,
            "predictive": pr,
        })).collect::<Vec<_>>(),
        "unreachable": p.unreachable,
    }))
    .expect("a posterior serialises");
    crate::files::write_atomically(&out.join("posterior.json"), &json)?;
    let cell = calibrated_cell(scenario, targets, p);
    let head = "# The calibrated real cell (pegtwin calibrate): each fitted value's range is its\n\
                # posterior 90 % range (the encoder offsets' half-range its median); the rest is the\n\
                # scenario's own.\n";
    crate::files::write_atomically(&out.join("cell.toml"), format!("{head}{cell}").as_bytes())?;
    crate::files::write_atomically(
        &out.join("report.html"),
        page(scenario, targets, p).as_bytes(),
    )
}

/// The posterior's points of the prior with their weights.
fn posterior_csv(p: &Posterior) -> String {
    let mut csv = format!("{},weight\n", p.free.join(","));
    for (point, w) in p.points.iter().zip(&p.weights) {
        let values: Vec<String> = point.iter().map(|v| format!("{v:e}")).collect();
        let _ = writeln!(csv, "{},{w:e}", values.join(","));
    }
    csv
}

/// A measured figure as the report shows it: a rate, or a mean ± its spread.
fn shown(m: &Measured) -> String {
    match m {
        Measured::Count { k, n } => format!("{:.1} % ({k} of {n})", 100.0 * *k as f64 / *n as f64),
        Measured::Mean { mean, std, n } => format!("{mean:.3} ± {std:.3} (n {n})"),
    }
}

fn page(scenario: &Scenario, targets: &Targets, p: &Posterior) -> String {
    let mut html = format!(
        "<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\"><title>calibration of {}</title>\
         <style>body{{font-family:sans-serif;max-width:1100px;margin:auto}}\
         td,th{{padding:2px 8px;text-align:right}} .out{{color:#b00;font-weight:bold}}</style>\
         </head><body>\n<h1>Calibration of {}</h1>\n<p>{} draws over the prior (Latin hypercube), \
         {} trials each; the posterior weighs {} points of the prior, {:.0} of them \
         effectively.</p>\n",
        escape(&scenario.name),
        escape(&scenario.name),
        p.evaluations.len(),
        p.trials_per_draw,
        p.points.len(),
        p.effective_points
    );
    html += "<h2>Free values</h2>\n<table><tr><th>value</th><th>prior</th><th>5 %</th>\
             <th>median</th><th>95 %</th></tr>\n";
    for ((name, prior), q) in p.free.iter().zip(&p.prior).zip(&p.quantiles) {
        let _ = writeln!(
            html,
            "<tr><td>{name}</td><td>{:.4}-{:.4}</td><td>{:.4}</td><td>{:.4}</td><td>{:.4}</td></tr>",
            prior[0], prior[1], q[0], q[1], q[2]
        );
    }
    html += "</table>\n<h2>Figures</h2>\n<p>Each measured figure beside the twin's 90 % \
             posterior predictive interval for a run of the measured size.</p>\n<table><tr>\
             <th>figure</th><th>role</th><th>measured</th><th>predicted (median)</th>\
             <th>90 % interval</th><th></th></tr>\n";
    for (t, pr) in targets.targets.iter().zip(&p.predictive) {
        let role = match t.target.role {
            Role::Fit => "fit",
            Role::HoldOut => "held out",
        };
        let scale = |v: f64| match t.measured {
            Measured::Count { .. } => format!("{:.1} %", 100.0 * v),
            Measured::Mean { .. } => format!("{v:.3}"),
        };
        let (median, interval, mark) = match pr {
            Some(pr) => (
                scale(pr.median),
                format!("{} - {}", scale(pr.interval[0]), scale(pr.interval[1])),
                if pr.inside {
                    "inside"
                } else {
                    "<span class=\"out\">outside</span>"
                },
            ),
            None => (
                "-".into(),
                "-".into(),
                "<span class=\"out\">the twin gave no such figure</span>",
            ),
        };
        let _ = writeln!(
            html,
            "<tr><td>{}</td><td>{role}</td><td>{}</td><td>{median}</td><td>{interval}</td><td>{mark}</td></tr>",
            escape(&t.label),
            shown(&t.measured)
        );
    }
    html += "</table>\n";
    if !p.unreachable.is_empty() {
        let names: Vec<String> = (p.unreachable.iter())
            .map(|&k| escape(&targets.targets[k].label))
            .collect();
        let _ = writeln!(
            html,
            "<p class=\"out\">No value in the prior reaches: {}.</p>",
            names.join("; ")
        );
    }
    html + "</body></html>\n"
}
