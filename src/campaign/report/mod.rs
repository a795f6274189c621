//! The report's figures (plotters, PNG and SVG) and `report.html`:
//! - `fig4_success`: success rate per geometry, the manifold method at each t_obs beside the
//!   direct baseline, with 95 % Wilson intervals (paper Fig. 4);
//! - `fig5_errors`: success rate against the estimate's position error (max |x|, |y|) and
//!   orientation error (max |roll|, |pitch|, |yaw|), with the number of trials per bin; bins past
//!   2.5 deg are drawn red as in the paper (Fig. 5);
//! - `fig6_fz`: |Fz| during insertion, mean +- 1 std, for successes and failures of each method
//!   (Fig. 6);
//! - `fig7_coverage`: the estimate's error over its estimated standard deviation, per axis,
//!   beside the standard normal (issue "know when you know"), with the coverage table;
//! - `fig8_time`, when the adaptive method ran: success against mean observation time, each cell
//!   of the methods that register, per pair and pooled;
//! - with several clearances, `fig5_errors-{c}mm` and `fig6_fz-{c}mm` for each clearance beside
//!   the pooled ones (the paper pools its 0.1-1.0 mm parts).

mod charts;
mod coverage;
mod page;
mod timing;

use charts::{FigureTally, draw_errors, draw_fz, draw_success, draw_tune, render, success_series};
use coverage::{CoverageTally, draw_coverage};
pub(crate) use page::escape;
use page::html;

use super::summary::{Summary, SummaryTally, two_passes};
use crate::campaign::records::RecordSource;
use crate::campaign::replays;
use crate::campaign::scenario::Scenario;
use crate::campaign::tune::Evaluation;
use crate::error::Result;

use crate::method::manifold::{cache, plot};

use std::path::Path;

/// Draws the gain search (`figures/tune.png` and `.svg`).
pub fn write_tune(dir: &Path, evals: &[Evaluation]) -> Result<()> {
    render(
        dir,
        "tune",
        |a| draw_tune(a, evals),
        |a| draw_tune(a, evals),
    )
}

/// A finished campaign's whole report in `dir`: each pair's manifold figure (from the cache in
/// `cache_dir`, never built), then the summary, the figures and report.html ([`write_all`]).
pub fn write_campaign_report(
    dir: &Path,
    scenario: &Scenario,
    source: &dyn RecordSource,
    cache_dir: &Path,
) -> Result<Summary> {
    write_manifolds(dir, scenario, cache_dir)?;
    write_all(dir, scenario, source)
}

/// Writes `summary.json`, `summary.csv` and the report (`report.html`, `figures/`) into `dir`,
/// from two streaming passes over `source`.
pub fn write_all(dir: &Path, scenario: &Scenario, source: &dyn RecordSource) -> Result<Summary> {
    let mut cells = SummaryTally::new(scenario);
    let mut figures = FigureTally::per_clearance(scenario);
    let mut coverage = CoverageTally::default();
    two_passes(source, &mut |r, pass| {
        cells.add(r, pass);
        figures.iter_mut().for_each(|f| f.add(r, pass));
        if pass == super::summary::Pass::Mean {
            coverage.add(r);
        }
    })?;
    let summary = cells.finish(scenario);
    let write = crate::files::write_atomically;
    write(
        &dir.join("summary.json"),
        &serde_json::to_vec_pretty(&summary).expect("summary serialises"),
    )?;
    write(
        &dir.join("summary.csv"),
        &super::summary::summary_csv(&summary),
    )?;
    write_report(dir, scenario, &summary, &figures, &coverage)?;
    Ok(summary)
}

/// Draws the figures into `dir/figures` and writes `dir/report.html`.
fn write_report(
    dir: &Path,
    scenario: &Scenario,
    summary: &Summary,
    figures: &[FigureTally],
    coverage: &CoverageTally,
) -> Result<()> {
    let mut geometries: Vec<String> = Vec::new();
    for c in &summary.cells {
        if !geometries.contains(&c.cell.geometry) {
            geometries.push(c.cell.geometry.clone());
        }
    }
    let series = success_series(summary, &geometries);
    render(
        dir,
        "fig4_success",
        |a| draw_success(a, &geometries, &series),
        |a| draw_success(a, &geometries, &series),
    )?;
    for tally in figures {
        let (name, _) = tally.suffixes();
        render(
            dir,
            &format!("fig5_errors{name}"),
            |a| draw_errors(a, tally),
            |a| draw_errors(a, tally),
        )?;
        render(
            dir,
            &format!("fig6_fz{name}"),
            |a| draw_fz(a, tally),
            |a| draw_fz(a, tally),
        )?;
    }
    if !coverage.is_empty() {
        render(
            dir,
            "fig7_coverage",
            |a| draw_coverage(a, coverage),
            |a| draw_coverage(a, coverage),
        )?;
    }
    let time_figure = timing::wanted(summary);
    if time_figure {
        render(
            dir,
            "fig8_time",
            |a| timing::draw_time(a, summary),
            |a| timing::draw_time(a, summary),
        )?;
    }
    let replays = replays::list(dir)?;
    let manifolds = manifold_figures(dir)?;
    let clearances: Vec<f64> = figures.iter().filter_map(|f| f.clearance_mm).collect();
    let extra = page::Extras {
        coverage_table: coverage::coverage_html(summary),
        coverage: !coverage.is_empty(),
        time: time_figure,
    };
    let page = html(scenario, summary, &replays, &manifolds, &clearances, extra);
    crate::files::write_atomically(&dir.join("report.html"), page.as_bytes())
}

/// The prefix of the figures of the reference manifolds.
const MANIFOLD_FIGURE: &str = "manifold-";

/// Draws the reference manifold of every pair the manifold method ran on, as `manifold plot`
/// does, into `dir/figures/manifold-{geometry}-{clearance}mm.png` and `.svg`, from the cache
/// folder `cache_dir` (a manifold that is not there is not drawn; nothing is built).
pub fn write_manifolds(dir: &Path, scenario: &Scenario, cache_dir: &Path) -> Result<()> {
    let mut drawn = Vec::new();
    for cell in scenario.cells() {
        let key = (cell.geometry.clone(), cell.clearance_mm.to_bits());
        if !cell.method.registers() || drawn.contains(&key) {
            continue;
        }
        drawn.push(key);
        let pair = scenario.pair(&cell)?;
        if let Some(m) = cache::cached(
            &pair,
            &scenario.manifold,
            &scenario.work_cell_params_for(&cell),
            cache_dir,
        )? {
            let name = format!("{MANIFOLD_FIGURE}{}-{}mm", cell.geometry, cell.clearance_mm);
            plot::plot(
                &m.points,
                &plot::label(&m.meta),
                &dir.join("figures"),
                &name,
            )?;
        }
    }
    Ok(())
}

/// The manifold figures in `dir/figures` (names without extension, sorted).
fn manifold_figures(dir: &Path) -> Result<Vec<String>> {
    let folder = dir.join("figures");
    let Ok(entries) = std::fs::read_dir(&folder) else {
        return Ok(Vec::new());
    };
    let mut names: Vec<String> = entries
        .filter_map(|e| e.ok())
        .filter_map(|e| {
            let name = e.file_name().to_string_lossy().into_owned();
            let stem = name.strip_suffix(".png")?;
            stem.starts_with(MANIFOLD_FIGURE).then(|| stem.to_string())
        })
        .collect();
    names.sort();
    Ok(names)
}
