//! `fig8_time`: what observing longer buys. Each cell of the methods that register (the manifold
//! method at each fixed t_obs, the adaptive method) is a point at its mean observation time and
//! its success rate, with its 95 % Wilson interval; per pair in its colour, pooled in black.

use super::charts::draw_legend;
use crate::campaign::summary::{CellSummary, Summary};
use crate::figures::{DrawResult, err};
use crate::method::config::Method;
use plotters::coord::Shift;
use plotters::prelude::*;

/// Whether the figure has something to show: a cell of the adaptive or the active method.
pub(super) fn wanted(summary: &Summary) -> bool {
    summary.cells.iter().any(|c| c.cell.method.stops_itself())
}

/// (mean observation time s, success %, Wilson low %, high %) of a cell.
fn point(c: &CellSummary) -> (f64, f64, f64, f64) {
    (
        c.mean_phase_s[1],
        c.success_rate * 100.0,
        c.success_ci95[0] * 100.0,
        c.success_ci95[1] * 100.0,
    )
}

pub(super) fn draw_time<DB: DrawingBackend>(
    root: DrawingArea<DB, Shift>,
    summary: &Summary,
) -> DrawResult {
    root.fill(&WHITE).map_err(err)?;
    let registering = |c: &&CellSummary| c.cell.method.registers() && c.trials > 0;
    let all: Vec<&CellSummary> = (summary.cells.iter().chain(&summary.pooled))
        .filter(registering)
        .collect();
    let t_max = all.iter().map(|c| c.cell.t_obs_s).fold(1.0, f64::max);
    let mut chart = ChartBuilder::on(&root)
        .caption(
            "Success against mean observation time (circles: fixed t_obs; triangles: adaptive; crosses: active)",
            ("sans-serif", 20),
        )
        .margin(10)
        .x_label_area_size(45)
        .y_label_area_size(55)
        .build_cartesian_2d(0.0..t_max * 1.1, 0.0..135.0)
        .map_err(err)?;
    chart
        .configure_mesh()
        .x_desc("mean observation time (s)")
        .y_desc("success rate (%)")
        .label_style(("sans-serif", 14))
        .draw()
        .map_err(err)?;
    let mut groups: Vec<String> = Vec::new();
    for c in &all {
        if !groups.contains(&c.cell.geometry) {
            groups.push(c.cell.geometry.clone());
        }
    }
    for (g, name) in groups.iter().enumerate() {
        let colour = if name == "all" {
            BLACK.to_rgba()
        } else {
            Palette99::pick(g).to_rgba()
        };
        let cells: Vec<&&CellSummary> = all.iter().filter(|c| &c.cell.geometry == name).collect();
        chart
            .draw_series(cells.iter().map(|c| {
                let (t, _, lo, hi) = point(c);
                PathElement::new(vec![(t, lo), (t, hi)], colour.stroke_width(1))
            }))
            .map_err(err)?;
        chart
            .draw_series(cells.iter().map(|c| {
                let (t, rate, _, _) = point(c);
                let style = colour.filled();
                let shape: DynElement<DB, (f64, f64)> = match c.cell.method {
                    Method::Adaptive => TriangleMarker::new((t, rate), 7, style).into_dyn(),
                    Method::Active => Cross::new((t, rate), 6, colour.stroke_width(2)).into_dyn(),
                    _ => Circle::new((t, rate), 5, style).into_dyn(),
                };
                shape
            }))
            .map_err(err)?
            .label(name.clone())
            .legend(move |(x, y)| Circle::new((x + 7, y), 5, colour.filled()));
    }
    draw_legend(&mut chart, SeriesLabelPosition::UpperLeft)?;
    root.present().map_err(err)
}
