//! The report's figures, drawn with plotters: success per geometry (Fig. 4), success against the
//! estimate's errors (Fig. 5), |Fz| during insertion (Fig. 6), and the tuner's evaluations.

use crate::campaign::records::TrialRecord;

use crate::campaign::scenario::Scenario;
use crate::campaign::summary::{Moments, Pass, Summary, abs_errors, wilson_interval};
use crate::campaign::tune::Evaluation;
use crate::error::Result;
use crate::figures::{self, DrawResult, err};
use crate::method::config::Method;

use crate::method::trial::FZ_PROFILE_DT_S;
use plotters::coord::Shift;
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;
use std::path::Path;

pub(super) const SIZE: (u32, u32) = (960, 540);

/// Position error bins, mm (upper edges; the last is open).
pub(super) const POSITION_BINS_MM: [f64; 6] = [0.1, 0.2, 0.3, 0.5, 1.0, f64::INFINITY];
/// Orientation error bins, deg.
pub(super) const ORIENTATION_BINS_DEG: [f64; 7] = [0.5, 1.0, 1.5, 2.0, 2.5, 5.0, f64::INFINITY];
/// The paper's critical orientation error, deg.
pub(super) const CRITICAL_DEG: f64 = 2.5;

/// Renders one figure of the report to `dir/figures/{name}.png` and `.svg`.
pub(super) fn render(
    dir: &Path,
    name: &str,
    draw_png: impl Fn(DrawingArea<BitMapBackend, Shift>) -> DrawResult,
    draw_svg: impl Fn(DrawingArea<SVGBackend, Shift>) -> DrawResult,
) -> Result<()> {
    figures::render(&dir.join("figures"), name, SIZE, draw_png, draw_svg)
}

pub(super) type Chart<'a, DB> = ChartContext<'a, DB, Cartesian2d<RangedCoordf64, RangedCoordf64>>;

/// A chart with one category per integer x (labelled by `labels`) and a percentage y axis.
pub(super) fn category_chart<'a, DB: DrawingBackend>(
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
pub(super) fn draw_legend<'a, DB: DrawingBackend + 'a>(
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
pub(super) struct BarSeries {
    label: String,
    values: Vec<Option<[f64; 3]>>,
}

pub(super) fn success_series(summary: &Summary, geometries: &[String]) -> Vec<BarSeries> {
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
                Method::Adaptive => format!("adaptive, t_obs <= {t} s"),
                Method::Active => format!("active, t_obs <= {t} s"),
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

pub(super) fn draw_success<DB: DrawingBackend>(
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
pub(super) struct Bins {
    edges: &'static [f64],
    counts: Vec<(usize, usize)>,
}

impl Bins {
    pub(super) fn new(edges: &'static [f64]) -> Self {
        Bins {
            edges,
            counts: vec![(0, 0); edges.len()],
        }
    }

    pub(super) fn add(&mut self, value: f64, success: bool) {
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
pub(super) struct ProfileTally {
    trials: usize,
    samples: Vec<Moments>,
}

impl ProfileTally {
    pub(super) fn add(&mut self, profile_n: &[f64], pass: Pass) {
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
    pub(super) fn band(&self) -> Vec<(f64, f64, f64)> {
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
pub(super) const FZ_GROUPS: [(Method, bool, &str, RGBColor); 4] = [
    (Method::Manifold, true, "manifold, success", GREEN),
    (Method::Manifold, false, "manifold, failure", BLUE),
    (Method::Direct, true, "direct, success", MAGENTA),
    (Method::Direct, false, "direct, failure", RED),
];

/// What the figures of one group of trials need from the records, gathered over
/// [`two_passes`] (no record is kept).
#[derive(Clone, Debug)]
pub(super) struct FigureTally {
    /// Which trials: every one (none), or those at one clearance, mm.
    pub(super) clearance_mm: Option<f64>,
    position: Bins,
    orientation: Bins,
    fz: [ProfileTally; 4],
}

impl FigureTally {
    pub(super) fn new(clearance_mm: Option<f64>) -> Self {
        FigureTally {
            clearance_mm,
            position: Bins::new(&POSITION_BINS_MM),
            orientation: Bins::new(&ORIENTATION_BINS_DEG),
            fz: Default::default(),
        }
    }

    /// The figures' file name suffix and title suffix: none pooled, else the clearance.
    pub(super) fn suffixes(&self) -> (String, String) {
        self.clearance_mm
            .map_or((String::new(), String::new()), |c| {
                (format!("-{c}mm"), format!(" at {c} mm"))
            })
    }

    /// The pooled figures, then one set per clearance when the scenario has several.
    pub(super) fn per_clearance(scenario: &Scenario) -> Vec<FigureTally> {
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

    pub(super) fn add(&mut self, r: &TrialRecord, pass: Pass) {
        let res = &r.result;
        if self.clearance_mm.is_some_and(|c| c != res.clearance_mm) {
            return;
        }
        if let (Pass::Mean, Some(e)) = (pass, abs_errors(r))
            && res.method.registers()
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

pub(super) fn bin_labels(edges: &[f64]) -> Vec<String> {
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

pub(super) fn draw_binned<DB: DrawingBackend>(
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

pub(super) fn draw_errors<DB: DrawingBackend>(
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
pub(super) type ProfileGroup = (String, RGBAColor, Vec<(f64, f64, f64)>);

pub(super) fn draw_fz<DB: DrawingBackend>(
    root: DrawingArea<DB, Shift>,
    tally: &FigureTally,
) -> DrawResult {
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

pub(super) fn draw_tune<DB: DrawingBackend>(
    root: DrawingArea<DB, Shift>,
    evals: &[Evaluation],
) -> DrawResult {
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
    // The incumbent (the scenario's own settings) ringed at every rung it reached.
    chart
        .draw_series(
            (evals.iter())
                .filter(|e| e.candidate.incumbent && e.peak_fz_n.is_finite())
                .map(|e| {
                    Circle::new(
                        (e.peak_fz_n, e.success_rate * 100.0),
                        9,
                        BLACK.stroke_width(2),
                    )
                }),
        )
        .map_err(err)?
        .label("the scenario's own settings")
        .legend(|(x, y)| Circle::new((x + 6, y), 7, BLACK.stroke_width(2)));
    draw_legend(&mut chart, SeriesLabelPosition::LowerRight)?;
    root.present().map_err(err)
}
