//! The report's figures (plotters, PNG and SVG) and `report.html`:
//! - `fig4_success`: success rate per geometry, the manifold method at each t_obs beside the
//!   direct baseline, with 95 % Wilson intervals (paper Fig. 4);
//! - `fig5_errors`: success rate against the estimate's position error (max |x|, |y|) and
//!   orientation error (max |roll|, |pitch|, |yaw|), with the number of trials per bin; bins past
//!   2.5 deg are drawn red as in the paper (Fig. 5);
//! - `fig6_fz`: |Fz| during insertion, mean +- 1 std, for successes and failures of each method
//!   (Fig. 6);
//! - with several clearances, `fig5_errors-{c}mm` and `fig6_fz-{c}mm` for each clearance beside
//!   the pooled ones (the paper pools its 0.1-1.0 mm parts).

use super::summary::{
    AXES, MeanStd, Moments, Pass, Summary, SummaryTally, abs_errors, two_passes, wilson_interval,
};
use crate::campaign::records::{RecordSource, TrialRecord};
use crate::campaign::replays::{self, ReplayLink};
use crate::campaign::scenario::Scenario;
use crate::campaign::tune::Evaluation;
use crate::error::Result;
use crate::figures::{self, DrawResult, err};
use crate::method::config::Method;
use crate::method::manifold::{cache, plot};
use crate::method::trial::FZ_PROFILE_DT_S;
use plotters::coord::Shift;
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;
use std::path::Path;

const SIZE: (u32, u32) = (960, 540);

/// Position error bins, mm (upper edges; the last is open).
const POSITION_BINS_MM: [f64; 6] = [0.1, 0.2, 0.3, 0.5, 1.0, f64::INFINITY];
/// Orientation error bins, deg.
const ORIENTATION_BINS_DEG: [f64; 7] = [0.5, 1.0, 1.5, 2.0, 2.5, 5.0, f64::INFINITY];
/// The paper's critical orientation error, deg.
const CRITICAL_DEG: f64 = 2.5;

/// Renders one figure of the report to `dir/figures/{name}.png` and `.svg`.
fn render(
    dir: &Path,
    name: &str,
    draw_png: impl Fn(DrawingArea<BitMapBackend, Shift>) -> DrawResult,
    draw_svg: impl Fn(DrawingArea<SVGBackend, Shift>) -> DrawResult,
) -> Result<()> {
    figures::render(&dir.join("figures"), name, SIZE, draw_png, draw_svg)
}

type Chart<'a, DB> = ChartContext<'a, DB, Cartesian2d<RangedCoordf64, RangedCoordf64>>;

/// A chart with one category per integer x (labelled by `labels`) and a percentage y axis.
fn category_chart<'a, DB: DrawingBackend>(
    area: &'a DrawingArea<DB, Shift>,
    title: &str,
    title_size: u32,
    labels: Vec<String>,
    y_max: f64,
    x_desc: Option<&str>,
) -> std::result::Result<Chart<'a, DB>, String> {
    let n = labels.len() as f64;
    let mut chart = ChartBuilder::on(area)
        .caption(title, ("sans-serif", title_size))
        .margin(10)
        .x_label_area_size(45)
        .y_label_area_size(55)
        .build_cartesian_2d(-0.5..n - 0.5, 0.0..y_max)
        .map_err(err)?;
    let count = labels.len();
    let name = move |x: &f64| {
        let i = x.round();
        if (x - i).abs() < 1e-6 && i >= 0.0 && (i as usize) < labels.len() {
            labels[i as usize].clone()
        } else {
            String::new()
        }
    };
    let mut mesh = chart.configure_mesh();
    mesh.disable_x_mesh()
        .x_labels(count.max(2) * 2 + 1)
        .x_label_formatter(&name)
        .y_desc("success rate (%)")
        .label_style(("sans-serif", 14));
    if let Some(d) = x_desc {
        mesh.x_desc(d);
    }
    mesh.draw().map_err(err)?;
    Ok(chart)
}

/// The series legend, boxed, at `position`.
fn draw_legend<'a, DB: DrawingBackend + 'a>(
    chart: &mut Chart<'a, DB>,
    position: SeriesLabelPosition,
) -> DrawResult {
    chart
        .configure_series_labels()
        .position(position)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font(("sans-serif", 14))
        .draw()
        .map_err(err)
}

/// A bar series of fig. 4: a label and, per geometry, (rate, ci low, ci high).
struct BarSeries {
    label: String,
    values: Vec<Option<[f64; 3]>>,
}

fn success_series(summary: &Summary, geometries: &[String]) -> Vec<BarSeries> {
    let mut groups: Vec<(Method, f64)> = Vec::new();
    for c in &summary.cells {
        let g = (c.cell.method, c.cell.t_obs_s);
        if !groups.contains(&g) {
            groups.push(g);
        }
    }
    groups
        .into_iter()
        .map(|(method, t)| {
            let label = match method {
                Method::Manifold => format!("manifold, t_obs {t} s"),
                Method::Direct => format!("direct, t_obs {t} s"),
            };
            let values = geometries
                .iter()
                .map(|g| {
                    let cells: Vec<_> = summary
                        .cells
                        .iter()
                        .filter(|c| {
                            &c.cell.geometry == g && c.cell.method == method && c.cell.t_obs_s == t
                        })
                        .collect();
                    let (n, k) = cells
                        .iter()
                        .fold((0, 0), |(n, k), c| (n + c.trials, k + c.successes));
                    (n > 0).then(|| {
                        let ci = wilson_interval(k, n);
                        [k as f64 / n as f64 * 100.0, ci[0] * 100.0, ci[1] * 100.0]
                    })
                })
                .collect();
            BarSeries { label, values }
        })
        .collect()
}

fn draw_success<DB: DrawingBackend>(
    root: DrawingArea<DB, Shift>,
    geometries: &[String],
    series: &[BarSeries],
) -> DrawResult {
    root.fill(&WHITE).map_err(err)?;
    let mut chart = category_chart(
        &root,
        "Success rate per geometry (95 % Wilson intervals)",
        22,
        geometries.to_vec(),
        // Headroom above 100 % for the legend.
        135.0,
        None,
    )?;
    let width = 0.8 / series.len().max(1) as f64;
    for (s, bars) in series.iter().enumerate() {
        let colour = Palette99::pick(s).to_rgba();
        let offset = -0.4 + width * (s as f64 + 0.5);
        chart
            .draw_series(bars.values.iter().enumerate().filter_map(|(g, v)| {
                v.map(|[rate, _, _]| {
                    let x = g as f64 + offset;
                    Rectangle::new(
                        [(x - width * 0.45, 0.0), (x + width * 0.45, rate)],
                        colour.filled(),
                    )
                })
            }))
            .map_err(err)?
            .label(bars.label.clone())
            .legend(move |(x, y)| Rectangle::new([(x, y - 5), (x + 14, y + 5)], colour.filled()));
        chart
            .draw_series(bars.values.iter().enumerate().filter_map(|(g, v)| {
                v.map(|[_, lo, hi]| {
                    let x = g as f64 + offset;
                    PathElement::new(vec![(x, lo), (x, hi)], BLACK.stroke_width(2))
                })
            }))
            .map_err(err)?;
    }
    draw_legend(&mut chart, SeriesLabelPosition::UpperRight)?;
    root.present().map_err(err)
}

/// Trials and successes per bin of an error (the largest of some absolute errors).
#[derive(Clone, Debug)]
struct Bins {
    edges: &'static [f64],
    counts: Vec<(usize, usize)>,
}

impl Bins {
    fn new(edges: &'static [f64]) -> Self {
        Bins {
            edges,
            counts: vec![(0, 0); edges.len()],
        }
    }

    fn add(&mut self, value: f64, success: bool) {
        let b = self
            .edges
            .iter()
            .position(|&edge| value < edge)
            .unwrap_or(self.edges.len() - 1);
        self.counts[b].0 += 1;
        self.counts[b].1 += usize::from(success);
    }
}

/// |Fz| during insertion of one group of trials: mean and std per profile sample.
#[derive(Clone, Debug, Default)]
struct ProfileTally {
    trials: usize,
    samples: Vec<Moments>,
}

impl ProfileTally {
    fn add(&mut self, profile_n: &[f64], pass: Pass) {
        if pass == Pass::Mean {
            self.trials += 1;
        }
        if self.samples.len() < profile_n.len() {
            self.samples.resize(profile_n.len(), Moments::default());
        }
        for (m, &f) in self.samples.iter_mut().zip(profile_n) {
            m.add(pass, f);
        }
    }

    /// (time s, mean N, std N) per profile sample that at least one trial reached.
    fn band(&self) -> Vec<(f64, f64, f64)> {
        self.samples
            .iter()
            .enumerate()
            .filter_map(|(k, m)| {
                m.finish()
                    .map(|m| (k as f64 * FZ_PROFILE_DT_S, m.mean, m.std))
            })
            .collect()
    }
}

/// The groups of the |Fz| figure: method, success, label, colour.
const FZ_GROUPS: [(Method, bool, &str, RGBColor); 4] = [
    (Method::Manifold, true, "manifold, success", GREEN),
    (Method::Manifold, false, "manifold, failure", BLUE),
    (Method::Direct, true, "direct, success", MAGENTA),
    (Method::Direct, false, "direct, failure", RED),
];

/// What the figures of one group of trials need from the records, gathered over
/// [`two_passes`] (no record is kept).
#[derive(Clone, Debug)]
struct FigureTally {
    /// Which trials: every one (none), or those at one clearance, mm.
    clearance_mm: Option<f64>,
    position: Bins,
    orientation: Bins,
    fz: [ProfileTally; 4],
}

impl FigureTally {
    fn new(clearance_mm: Option<f64>) -> Self {
        FigureTally {
            clearance_mm,
            position: Bins::new(&POSITION_BINS_MM),
            orientation: Bins::new(&ORIENTATION_BINS_DEG),
            fz: Default::default(),
        }
    }

    /// The figures' file name suffix and title suffix: none pooled, else the clearance.
    fn suffixes(&self) -> (String, String) {
        self.clearance_mm
            .map_or((String::new(), String::new()), |c| {
                (format!("-{c}mm"), format!(" at {c} mm"))
            })
    }

    /// The pooled figures, then one set per clearance when the scenario has several.
    fn per_clearance(scenario: &Scenario) -> Vec<FigureTally> {
        let mut clearances: Vec<f64> = Vec::new();
        for c in scenario.cells() {
            if !clearances.contains(&c.clearance_mm) {
                clearances.push(c.clearance_mm);
            }
        }
        if clearances.len() < 2 {
            clearances.clear();
        }
        std::iter::once(None)
            .chain(clearances.into_iter().map(Some))
            .map(FigureTally::new)
            .collect()
    }

    fn add(&mut self, r: &TrialRecord, pass: Pass) {
        let res = &r.result;
        if self.clearance_mm.is_some_and(|c| c != res.clearance_mm) {
            return;
        }
        if let (Pass::Mean, Some(e)) = (pass, abs_errors(r))
            && res.method == Method::Manifold
        {
            self.position.add(e[0].max(e[1]), res.success);
            self.orientation.add(e[3].max(e[4]).max(e[5]), res.success);
        }
        let group = FZ_GROUPS
            .iter()
            .position(|g| g.0 == res.method && g.1 == res.success);
        if let Some(g) = group {
            self.fz[g].add(&res.insert_fz_n, pass);
        }
    }
}

fn bin_labels(edges: &[f64]) -> Vec<String> {
    let mut lo = 0.0;
    edges
        .iter()
        .map(|&hi| {
            let l = if hi.is_finite() {
                format!("{lo}-{hi}")
            } else {
                format!(">{lo}")
            };
            lo = hi;
            l
        })
        .collect()
}

fn draw_binned<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    title: &str,
    axis: &str,
    bins: &Bins,
    critical: Option<f64>,
) -> DrawResult {
    let mut chart = category_chart(area, title, 18, bin_labels(bins.edges), 115.0, Some(axis))?;
    let mut lo = 0.0;
    for (i, (&(total, ok), &hi)) in bins.counts.iter().zip(bins.edges).enumerate() {
        let past_critical = critical.is_some_and(|c| lo >= c);
        let colour = if past_critical {
            RED.mix(0.7)
        } else {
            BLUE.mix(0.6)
        };
        lo = hi;
        let x = i as f64;
        if past_critical {
            chart
                .draw_series([Rectangle::new(
                    [(x - 0.5, 0.0), (x + 0.5, 115.0)],
                    RED.mix(0.08).filled(),
                )])
                .map_err(err)?;
        }
        if total == 0 {
            continue;
        }
        let rate = ok as f64 / total as f64 * 100.0;
        chart
            .draw_series([Rectangle::new(
                [(x - 0.38, 0.0), (x + 0.38, rate)],
                colour.filled(),
            )])
            .map_err(err)?;
        chart
            .draw_series([Text::new(
                format!("n={total}"),
                (x - 0.25, rate + 6.0),
                ("sans-serif", 13),
            )])
            .map_err(err)?;
    }
    Ok(())
}

fn draw_errors<DB: DrawingBackend>(
    root: DrawingArea<DB, Shift>,
    tally: &FigureTally,
) -> DrawResult {
    root.fill(&WHITE).map_err(err)?;
    let (left, right) = root.split_horizontally(SIZE.0 / 2);
    let (_, at) = tally.suffixes();
    draw_binned(
        &left,
        &format!("Success vs position error{at}"),
        "max(|x|, |y|) error (mm)",
        &tally.position,
        None,
    )?;
    draw_binned(
        &right,
        &format!("Success vs orientation error{at}"),
        "max(|roll|, |pitch|, |yaw|) error (deg)",
        &tally.orientation,
        Some(CRITICAL_DEG),
    )?;
    root.present().map_err(err)
}

/// A labelled, coloured band of (time s, mean N, std N).
type ProfileGroup = (String, RGBAColor, Vec<(f64, f64, f64)>);

fn draw_fz<DB: DrawingBackend>(root: DrawingArea<DB, Shift>, tally: &FigureTally) -> DrawResult {
    root.fill(&WHITE).map_err(err)?;
    let groups: Vec<ProfileGroup> = FZ_GROUPS
        .iter()
        .zip(&tally.fz)
        .filter_map(|(&(_, _, label, colour), profile)| {
            let band = profile.band();
            (!band.is_empty()).then(|| {
                let label = format!("{label} (n={})", profile.trials);
                (label, colour.to_rgba(), band)
            })
        })
        .collect();
    let t_max = groups
        .iter()
        .flat_map(|g| g.2.last().map(|p| p.0))
        .fold(0.1, f64::max);
    let f_max = groups
        .iter()
        .flat_map(|g| g.2.iter().map(|p| p.1 + p.2))
        .fold(1.0, f64::max);
    let mut chart = ChartBuilder::on(&root)
        .caption(
            format!("|Fz| during insertion, mean ± 1 std{}", tally.suffixes().1),
            ("sans-serif", 22),
        )
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(55)
        .build_cartesian_2d(0.0..t_max, 0.0..f_max * 1.1)
        .map_err(err)?;
    chart
        .configure_mesh()
        .x_desc("time since the insertion started (s)")
        .y_desc("|Fz| (N)")
        .label_style(("sans-serif", 15))
        .draw()
        .map_err(err)?;
    for (label, colour, band) in &groups {
        let mut outline: Vec<(f64, f64)> = band.iter().map(|p| (p.0, p.1 + p.2)).collect();
        outline.extend(band.iter().rev().map(|p| (p.0, (p.1 - p.2).max(0.0))));
        chart
            .draw_series([Polygon::new(outline, colour.mix(0.15).filled())])
            .map_err(err)?;
        let c = *colour;
        chart
            .draw_series(LineSeries::new(
                band.iter().map(|p| (p.0, p.1)),
                c.stroke_width(2),
            ))
            .map_err(err)?
            .label(label.clone())
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 16, y)], c.stroke_width(2)));
    }
    draw_legend(&mut chart, SeriesLabelPosition::UpperRight)?;
    root.present().map_err(err)
}

fn draw_tune<DB: DrawingBackend>(root: DrawingArea<DB, Shift>, evals: &[Evaluation]) -> DrawResult {
    root.fill(&WHITE).map_err(err)?;
    let f_max = evals
        .iter()
        .map(|e| e.peak_fz_n)
        .filter(|f| f.is_finite())
        .fold(1.0, f64::max);
    let mut chart = ChartBuilder::on(&root)
        .caption(
            "Gain search: success rate and peak |Fz| per candidate",
            ("sans-serif", 22),
        )
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(55)
        .build_cartesian_2d(0.0..f_max * 1.1, 0.0..105.0)
        .map_err(err)?;
    chart
        .configure_mesh()
        .x_desc("mean peak |Fz| of the successes (N)")
        .y_desc("success rate (%)")
        .label_style(("sans-serif", 15))
        .draw()
        .map_err(err)?;
    let rungs = evals.iter().map(|e| e.rung).max().map_or(0, |r| r + 1);
    for rung in 0..rungs {
        let colour = Palette99::pick(rung).to_rgba();
        chart
            .draw_series(
                evals
                    .iter()
                    .filter(|e| e.rung == rung && e.peak_fz_n.is_finite())
                    .map(|e| {
                        Circle::new((e.peak_fz_n, e.success_rate * 100.0), 5, colour.filled())
                    }),
            )
            .map_err(err)?
            .label(format!("rung {rung}"))
            .legend(move |(x, y)| Circle::new((x + 6, y), 5, colour.filled()));
    }
    draw_legend(&mut chart, SeriesLabelPosition::LowerRight)?;
    root.present().map_err(err)
}

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
    two_passes(source, &mut |r, pass| {
        cells.add(r, pass);
        figures.iter_mut().for_each(|f| f.add(r, pass));
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
    write_report(dir, scenario, &summary, &figures)?;
    Ok(summary)
}

/// Draws the three figures into `dir/figures` and writes `dir/report.html`.
fn write_report(
    dir: &Path,
    scenario: &Scenario,
    summary: &Summary,
    figures: &[FigureTally],
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
    let replays = replays::list(dir)?;
    let manifolds = manifold_figures(dir)?;
    let clearances: Vec<f64> = figures.iter().filter_map(|f| f.clearance_mm).collect();
    let page = html(scenario, summary, &replays, &manifolds, &clearances);
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
        if cell.method != Method::Manifold || drawn.contains(&key) {
            continue;
        }
        drawn.push(key);
        let pair = scenario.pair(&cell)?;
        if let Some(m) = cache::cached(
            &pair,
            &scenario.manifold,
            &scenario.cell_params_for(&cell),
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

fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

fn html(
    scenario: &Scenario,
    summary: &Summary,
    replay_links: &[ReplayLink],
    manifolds: &[String],
    clearances_mm: &[f64],
) -> String {
    let rows = table_rows(summary, replay_links);
    let axes: String = AXES.iter().map(|a| format!("<th>MAE {a}</th>")).collect();
    format!(
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>pegtwin: {name}</title>\n<style>body{{font-family:sans-serif;margin:2em}}table{{border-collapse:collapse}}td,th{{border:1px solid #bbb;padding:3px 7px;text-align:right}}</style></head><body>\n<h1>pegtwin campaign: {name}</h1>\n<p>Scenario fingerprint {fp}; {n} trials per cell; hole offsets U(-{om}, {om}) mm and U(-{od}, {od}) deg; success when the final depth is within {sm} mm of the floor.</p>\n{pp}<table><tr><th>geometry</th><th>clearance mm</th><th>method</th><th>t_obs s</th><th>success</th><th>95 % CI</th>{axes}<th>peak Fz success N</th><th>peak Fz failure N</th><th>partial to full insertion s (successes)</th><th>replays</th></tr>\n{rows}</table>\n{figures}{rp}</body></html>\n",
        name = escape(&scenario.name),
        fp = summary.fingerprint,
        n = scenario.trials,
        om = scenario.offset_mm,
        od = scenario.offset_deg,
        sm = scenario.success_mm,
        pp = pair_physics_html(scenario),
        figures = figures_html(manifolds, clearances_mm),
        rp = replays::section(replay_links, &scenario.cells()),
    )
}

/// One table row per cell (with its replay links) and per pooled row.
fn table_rows(summary: &Summary, replay_links: &[ReplayLink]) -> String {
    let mut rows = String::new();
    let indexed = summary.cells.iter().enumerate().map(|(i, c)| (Some(i), c));
    for (index, c) in indexed.chain(summary.pooled.iter().map(|c| (None, c))) {
        let mae = |a: usize| c.mae.map_or(String::new(), |m| format!("{:.2}", m[a]));
        let fz =
            |m: Option<MeanStd>| m.map_or("-".into(), |m| format!("{:.1} ± {:.1}", m.mean, m.std));
        rows += &format!(
            "<tr><td>{}</td><td>{}</td><td>{:?}</td><td>{}</td><td>{}/{}</td><td>{:.0}-{:.0} %</td>{}<td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>\n",
            escape(&c.cell.geometry),
            c.cell.clearance_mm,
            c.cell.method,
            c.cell.t_obs_s,
            c.successes,
            c.trials,
            c.success_ci95[0] * 100.0,
            c.success_ci95[1] * 100.0,
            (0..6)
                .map(|a| format!("<td>{}</td>", mae(a)))
                .collect::<String>(),
            fz(c.peak_fz_success_n),
            fz(c.peak_fz_failure_n),
            c.partial_to_full_s
                .map_or("-".into(), |m| format!("{:.1} ± {:.1}", m.mean, m.std)),
            index.map_or(String::new(), |i| replays::cell_link(replay_links, i)),
        );
    }
    rows
}

/// The pairs that ran their own physics (`[[pair_physics]]`), so that a reader of the table
/// knows which rows were simulated differently; empty when none did.
fn pair_physics_html(scenario: &Scenario) -> String {
    let items: Vec<String> = scenario
        .pair_physics
        .iter()
        .map(|o| {
            let at = o
                .clearance_mm
                .map_or("every clearance".into(), |c| format!("{c} mm"));
            let set = toml::to_string(&o.physics).expect("physics overrides serialise");
            let set = set.trim().replace('\n', ", ");
            format!("{} at {at}: {}", escape(&o.geometry), escape(&set))
        })
        .collect();
    if items.is_empty() {
        return String::new();
    }
    format!(
        "<p>Physics of their own (<code>[[pair_physics]]</code>, over the scenario's): {}.</p>\n",
        items.join("; ")
    )
}

/// The paper's figures pooled, per clearance, and the reference manifolds'.
fn figures_html(manifolds: &[String], clearances_mm: &[f64]) -> String {
    let figure = |name: &str, caption: &str| {
        format!(
            "<figure><img src=\"figures/{name}.png\" alt=\"{caption}\" width=\"960\"><figcaption>{caption} (<a href=\"figures/{name}.svg\">SVG</a>)</figcaption></figure>\n"
        )
    };
    let mut out = figure(
        "fig4_success",
        "Success rate per geometry, method vs direct (paper Fig. 4)",
    );
    out += &figure(
        "fig5_errors",
        "Success rate against position and orientation error (paper Fig. 5)",
    );
    out += &figure(
        "fig6_fz",
        "|Fz| profiles during insertion, success and failure, method vs direct (paper Fig. 6)",
    );
    for c in clearances_mm {
        out += &figure(
            &format!("fig5_errors-{c}mm"),
            &format!("Success rate against the estimate's errors at {c} mm (Fig. 5)"),
        );
        out += &figure(
            &format!("fig6_fz-{c}mm"),
            &format!("|Fz| profiles during insertion at {c} mm (Fig. 6)"),
        );
    }
    for name in manifolds {
        out += &figure(
            name,
            &format!(
                "The reference contact manifold, {} (paper IV-B)",
                &name[MANIFOLD_FIGURE.len()..]
            ),
        );
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_report_names_the_pairs_with_physics_of_their_own() {
        let text = r#"
name = "t"
trials = 1
geometries = ["cross", "gear"]
clearances_mm = [0.1]
t_obs_s = [6.0]
methods = ["manifold"]
"#;
        let plain = Scenario::parse(text).unwrap();
        assert_eq!(pair_physics_html(&plain), "");
        let own = format!(
            "{text}\n[[pair_physics]]\ngeometry = \"gear\"\n\
             physics = {{ pgs_iterations = 8, friction = 0.2 }}\n"
        );
        let html = pair_physics_html(&Scenario::parse(&own).unwrap());
        assert!(
            html.contains("gear at every clearance: pgs_iterations = 8, friction = 0.2."),
            "{html}"
        );
    }
}
