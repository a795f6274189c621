//! Is the estimate's uncertainty calibrated? The coverage table (the share of trials whose true
//! error lies within two of the estimate's standard deviations, per axis) and `fig7_coverage`,
//! the histogram of error / std per axis beside the standard normal density it should follow.

use super::page::escape;
use crate::campaign::records::TrialRecord;
use crate::campaign::summary::{COVERAGE_AXES, Summary, standardised_errors};
use crate::figures::{DrawResult, err};
use plotters::coord::Shift;
use plotters::prelude::*;

/// Width of a histogram bin, standard deviations.
const BIN_STD: f64 = 0.5;
/// The histogram spans ± this many standard deviations; the trials beyond are counted apart.
const SPAN_STD: f64 = 5.0;
const BINS: usize = (2.0 * SPAN_STD / BIN_STD) as usize;

/// The histogram of every trial's error / std, per axis, pooled over the campaign.
#[derive(Clone, Debug, Default)]
pub(super) struct CoverageTally {
    trials: usize,
    counts: [[usize; BINS]; 6],
    beyond: [usize; 6],
}

impl CoverageTally {
    pub(super) fn add(&mut self, r: &TrialRecord) {
        let Some(z) = standardised_errors(r) else {
            return;
        };
        self.trials += 1;
        for (a, z) in z.iter().enumerate() {
            let bin = ((z + SPAN_STD) / BIN_STD).floor();
            if bin >= 0.0 && bin < BINS as f64 {
                self.counts[a][bin as usize] += 1;
            } else {
                self.beyond[a] += 1;
            }
        }
    }

    /// Whether any trial had an estimate with its standard deviations.
    pub(super) fn is_empty(&self) -> bool {
        self.trials == 0
    }
}

/// One panel per axis: the share of trials per bin as a density, and the standard normal.
pub(super) fn draw_coverage<DB: DrawingBackend>(
    root: DrawingArea<DB, Shift>,
    tally: &CoverageTally,
) -> DrawResult {
    root.fill(&WHITE).map_err(err)?;
    let (title, body) = root.split_vertically(40);
    title
        .titled(
            &format!(
                "Error / estimated std per axis, {} trials (curve: the standard normal)",
                tally.trials
            ),
            ("sans-serif", 20),
        )
        .map_err(err)?;
    let n = tally.trials.max(1) as f64;
    let density = |k: usize| k as f64 / n / BIN_STD;
    let tallest = tally
        .counts
        .iter()
        .flatten()
        .map(|&k| density(k))
        .fold(0.0, f64::max);
    let y_max = (1.1 * tallest).max(0.5);
    for (a, panel) in body.split_evenly((2, 3)).iter().enumerate() {
        let caption = format!(
            "{}: {} beyond ±{SPAN_STD}",
            COVERAGE_AXES[a], tally.beyond[a]
        );
        let mut chart = ChartBuilder::on(panel)
            .caption(caption, ("sans-serif", 15))
            .margin(6)
            .x_label_area_size(25)
            .y_label_area_size(40)
            .build_cartesian_2d(-SPAN_STD..SPAN_STD, 0.0..y_max)
            .map_err(err)?;
        chart
            .configure_mesh()
            .disable_x_mesh()
            .label_style(("sans-serif", 12))
            .draw()
            .map_err(err)?;
        chart
            .draw_series(tally.counts[a].iter().enumerate().map(|(b, &k)| {
                let lo = -SPAN_STD + b as f64 * BIN_STD;
                Rectangle::new(
                    [(lo, 0.0), (lo + BIN_STD, density(k))],
                    BLUE.mix(0.5).filled(),
                )
            }))
            .map_err(err)?;
        let normal = (0..=200).map(|i| {
            let z = -SPAN_STD + i as f64 * 2.0 * SPAN_STD / 200.0;
            (
                z,
                (-0.5 * z * z).exp() / (2.0 * std::f64::consts::PI).sqrt(),
            )
        });
        chart
            .draw_series(LineSeries::new(normal, BLACK.stroke_width(2)))
            .map_err(err)?;
    }
    root.present().map_err(err)
}

/// The coverage table of `summary`'s cells and pooled rows that have estimates with their
/// standard deviations; empty when none has.
pub(super) fn coverage_html(summary: &Summary) -> String {
    let rows: String = summary
        .cells
        .iter()
        .chain(&summary.pooled)
        .filter_map(|c| {
            let cov = c.coverage_2sigma?;
            let cells: String = cov
                .iter()
                .map(|v| format!("<td>{:.0} %</td>", v * 100.0))
                .collect();
            Some(format!(
                "<tr><td>{}</td><td>{}</td><td>{}</td>{cells}</tr>\n",
                escape(&c.cell.geometry),
                c.cell.clearance_mm,
                c.cell.t_obs_s
            ))
        })
        .collect();
    if rows.is_empty() {
        return String::new();
    }
    let axes: String = COVERAGE_AXES
        .iter()
        .map(|a| format!("<th>{a}</th>"))
        .collect();
    format!(
        "<h2>Is the estimate's uncertainty calibrated?</h2>\n<p>The share of the manifold \
         method's trials whose true error lies within two of the estimate's standard deviations \
         (<code>estimate_std</code>), per axis: about 95 % when they are calibrated \
         (docs/registration.md, \"Uncertainty\").</p>\n<table><tr><th>geometry</th>\
         <th>clearance mm</th><th>t_obs s</th>{axes}</tr>\n{rows}</table>\n"
    )
}
