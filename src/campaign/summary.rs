//! What a campaign measured: per-cell statistics (`summary.json`, `summary.csv`, the printed
//! table) and the HTML report with the paper's figures (`plots`).
//!
//! Statistics per cell (geometry x clearance x method x t_obs):
//! - success rate with its 95 % Wilson score interval (good at small n and at 0 % / 100 %,
//!   where the normal approximation collapses);
//! - per axis, the mean absolute error of the estimate and the standard deviation of the
//!   absolute error (the paper's "MAE" and "standard deviation in error"), over the trials that
//!   produced an estimate (manifold method);
//! - peak |Fz| during insertion, mean and standard deviation, for successes and failures apart;
//! - mean simulated time per phase.

use crate::campaign::records::{RecordSource, TrialRecord};
use crate::campaign::scenario::{Condition, Scenario};
use crate::choice::Choice;
use crate::error::Result;

use serde::{Deserialize, Serialize};

/// z of the two-sided 95 % normal quantile.
const Z95: f64 = 1.959_963_984_540_054;

/// The 95 % Wilson score interval of `k` successes in `n` trials.
pub fn wilson_interval(k: usize, n: usize) -> [f64; 2] {
    if n == 0 {
        return [0.0, 1.0];
    }
    let (n, p) = (n as f64, k as f64 / n as f64);
    let z2 = Z95 * Z95;
    let centre = (p + z2 / (2.0 * n)) / (1.0 + z2 / n);
    let half = Z95 / (1.0 + z2 / n) * (p * (1.0 - p) / n + z2 / (4.0 * n * n)).sqrt();
    [(centre - half).max(0.0), (centre + half).min(1.0)]
}

/// Mean and (population) standard deviation of a sample; `None` when it is empty.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct MeanStd {
    pub mean: f64,
    pub std: f64,
    pub n: usize,
}

impl MeanStd {
    pub fn of(values: &[f64]) -> Option<Self> {
        let mut m = Moments::default();
        for pass in [Pass::Mean, Pass::Spread] {
            values.iter().for_each(|&v| m.add(pass, v));
        }
        m.finish()
    }
}

/// Which of the two passes over the records a summary is in: means first, then the spread about
/// them (the textbook two-pass variance, stable for the small spreads of errors in mm).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Pass {
    Mean,
    Spread,
}

/// Mean and standard deviation of a stream, kept in O(1) memory over [`two_passes`].
#[derive(Clone, Copy, Debug, Default)]
pub struct Moments {
    n: usize,
    sum: f64,
    squares: f64,
}

impl Moments {
    pub fn add(&mut self, pass: Pass, v: f64) {
        match pass {
            Pass::Mean => {
                self.n += 1;
                self.sum += v;
            }
            Pass::Spread => self.squares += (v - self.mean()).powi(2),
        }
    }

    fn mean(&self) -> f64 {
        self.sum / self.n as f64
    }

    /// The (population) statistics once both passes are done; `None` for an empty stream.
    pub fn finish(&self) -> Option<MeanStd> {
        (self.n > 0).then(|| MeanStd {
            mean: self.mean(),
            std: (self.squares / self.n as f64).sqrt(),
            n: self.n,
        })
    }
}

/// Hands every record of `source` to `each` twice: once with [`Pass::Mean`], then once with
/// [`Pass::Spread`].
pub fn two_passes(
    source: &dyn RecordSource,
    each: &mut dyn FnMut(&TrialRecord, Pass),
) -> Result<()> {
    source.for_each(&mut |r| each(r, Pass::Mean))?;
    source.for_each(&mut |r| each(r, Pass::Spread))
}

/// Axis names of the error columns.
pub const AXES: [&str; 6] = ["x_mm", "y_mm", "z_mm", "roll_deg", "pitch_deg", "yaw_deg"];

/// Axis names of the coverage columns (a share has no unit).
pub const COVERAGE_AXES: [&str; 6] = ["x", "y", "z", "roll", "pitch", "yaw"];

/// The statistics of one cell.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct CellSummary {
    #[serde(flatten)]
    pub cell: Condition,
    pub trials: usize,
    pub successes: usize,
    pub sim_faults: usize,
    /// Trials that raised an error or panicked (outcome `error`; counted as not successful).
    #[serde(default)]
    pub error_trials: usize,
    pub success_rate: f64,
    /// 95 % Wilson interval of the success rate.
    pub success_ci95: [f64; 2],
    /// Mean absolute error per axis (x, y, z mm; roll, pitch, yaw deg); manifold method only.
    pub mae: Option<[f64; 6]>,
    /// Standard deviation of the absolute error per axis.
    pub abs_error_std: Option<[f64; 6]>,
    /// The share of the trials with an estimate whose true error on each axis lies within two of
    /// the estimate's standard deviations (`estimate_std`): 0.954 when they are calibrated.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub coverage_2sigma: Option<[f64; 6]>,
    pub peak_fz_success_n: Option<MeanStd>,
    pub peak_fz_failure_n: Option<MeanStd>,
    /// Mean simulated time per phase, s: search, observe, retract, align, insert.
    pub mean_phase_s: [f64; 5],
    /// Simulated time from the partial insertion to the full one of the successes, s: observe,
    /// retract, align and insert (the paper: 7-11 s; the registration's wall time comes on top
    /// on a real cell).
    #[serde(default)]
    pub partial_to_full_s: Option<MeanStd>,
    /// How the failures that inserted failed ([`FailureModes`]).
    #[serde(default)]
    pub failure_modes: FailureModes,
}

/// How the failed trials of a cell that inserted without a physics fault failed, by why their
/// insertion's target stopped and where the peg was (records' `insert_end`, `final_depth_mm`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct FailureModes {
    /// The jam break fired: the force along the peg passed `jam_force_n`.
    pub jam: usize,
    /// The seat break fired above the floor: the peg stalled short of it, pressing past
    /// `seat_force_n` (friction or a wall held it, not the floor).
    pub stall: usize,
    /// The target ran its whole way (or out of time) and the peg stayed short of the floor with
    /// less than the jam force: held by two-point contact and friction, wedged.
    pub wedge: usize,
}

impl FailureModes {
    /// Counts `result` if it failed after inserting without a fault.
    fn add(&mut self, result: &crate::method::trial::TrialResult) {
        use crate::method::insert::InsertEnd;
        if result.success || result.fault.is_some() {
            return;
        }
        match result.insert_end {
            Some(InsertEnd::Jam) => self.jam += 1,
            Some(InsertEnd::Seat) => self.stall += 1,
            Some(InsertEnd::Travel | InsertEnd::Limit) => self.wedge += 1,
            None => {}
        }
    }
}

/// The whole summary (`summary.json`).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Summary {
    pub scenario: String,
    pub fingerprint: String,
    pub cells: Vec<CellSummary>,
    /// Per method and t_obs, every geometry pooled (the paper's averages), geometry `all`: with
    /// several clearances, first one group per clearance, then every clearance pooled
    /// (clearance 0); with one, its groups at that clearance.
    pub pooled: Vec<CellSummary>,
}

/// A record's error on each axis in units of its estimate's standard deviation (signed), when it
/// has both: against the hole as the robot reads it where the encoders carry offsets (the
/// registration's own error, which its standard deviation describes), else the true hole.
pub fn standardised_errors(r: &TrialRecord) -> Option<[f64; 6]> {
    let e = (r.result.read_errors.as_ref()).or(r.result.errors.as_ref())?;
    let std = r.result.estimate_std?;
    let si = [
        e.x_mm * 1e-3,
        e.y_mm * 1e-3,
        e.z_mm * 1e-3,
        e.roll_deg.to_radians(),
        e.pitch_deg.to_radians(),
        e.yaw_deg.to_radians(),
    ];
    Some(std::array::from_fn(|a| si[a] / std[a]))
}

/// Absolute errors of a record, x y z mm, roll pitch yaw deg.
pub fn abs_errors(r: &TrialRecord) -> Option<[f64; 6]> {
    r.result
        .errors
        .as_ref()
        .map(|e| [e.x_mm, e.y_mm, e.z_mm, e.roll_deg, e.pitch_deg, e.yaw_deg].map(f64::abs))
}

/// Summarises records cell by cell, in the scenario's cell order (two passes over `source`).
pub fn summarise(scenario: &Scenario, source: &dyn RecordSource) -> Result<Summary> {
    let mut tally = SummaryTally::new(scenario);
    two_passes(source, &mut |r, pass| tally.add(r, pass))?;
    Ok(tally.finish(scenario))
}

/// The running statistics of every cell and pooled group, filled record by record.
pub struct SummaryTally {
    cells: Vec<CellTally>,
    pooled: Vec<(Condition, CellTally)>,
    /// The pooled groups of each cell (none when nothing is pooled).
    group_of: Vec<Vec<usize>>,
}

impl SummaryTally {
    pub fn new(scenario: &Scenario) -> Self {
        let cells = scenario.cells();
        let (pooled, group_of) = pooled_groups(&cells);
        SummaryTally {
            cells: vec![CellTally::default(); cells.len()],
            pooled: pooled
                .into_iter()
                .map(|c| (c, CellTally::default()))
                .collect(),
            group_of,
        }
    }

    /// Counts `r` in its cell and its pooled group (a record of no cell of the scenario is left
    /// out).
    pub fn add(&mut self, r: &TrialRecord, pass: Pass) {
        if let Some(tally) = self.cells.get_mut(r.cell) {
            tally.add(r, pass);
        }
        for &g in self.group_of.get(r.cell).into_iter().flatten() {
            self.pooled[g].1.add(r, pass);
        }
    }

    pub fn finish(&self, scenario: &Scenario) -> Summary {
        Summary {
            scenario: scenario.name.clone(),
            fingerprint: scenario.fingerprint(),
            cells: scenario
                .cells()
                .into_iter()
                .zip(&self.cells)
                .map(|(cell, t)| t.summary(cell))
                .collect(),
            pooled: self
                .pooled
                .iter()
                .map(|(c, t)| t.summary(c.clone()))
                .collect(),
        }
    }
}

/// The pooled groups (geometry `all`) when there are several pairs: per (method, t_obs) at each
/// clearance when there are several clearances, then per (method, t_obs) over every clearance
/// (clearance 0; with one clearance, that clearance); and the groups of each cell.
fn pooled_groups(cells: &[Condition]) -> (Vec<Condition>, Vec<Vec<usize>>) {
    let mut pairs: Vec<(&str, f64)> = Vec::new();
    let mut clearances: Vec<f64> = Vec::new();
    for c in cells {
        if !pairs.contains(&(c.geometry.as_str(), c.clearance_mm)) {
            pairs.push((c.geometry.as_str(), c.clearance_mm));
        }
        if !clearances.contains(&c.clearance_mm) {
            clearances.push(c.clearance_mm);
        }
    }
    if pairs.len() < 2 {
        return (Vec::new(), vec![Vec::new(); cells.len()]);
    }
    let mut groups: Vec<Condition> = Vec::new();
    let mut group = |c: &Condition, clearance_mm: f64| {
        let same = |g: &Condition| {
            g.method == c.method && g.t_obs_s == c.t_obs_s && g.clearance_mm == clearance_mm
        };
        groups.iter().position(same).unwrap_or_else(|| {
            groups.push(Condition {
                geometry: "all".into(),
                clearance_mm,
                method: c.method,
                t_obs_s: c.t_obs_s,
            });
            groups.len() - 1
        })
    };
    let several = clearances.len() > 1;
    let mut group_of: Vec<Vec<usize>> = cells
        .iter()
        .map(|c| {
            if several {
                vec![group(c, c.clearance_mm)]
            } else {
                Vec::new()
            }
        })
        .collect();
    let overall = if several { 0.0 } else { clearances[0] };
    for (c, of) in cells.iter().zip(&mut group_of) {
        of.push(group(c, overall));
    }
    (groups, group_of)
}

/// The running statistics of one cell (or pooled group).
#[derive(Clone, Debug, Default)]
struct CellTally {
    trials: usize,
    successes: usize,
    sim_faults: usize,
    error_trials: usize,
    abs_errors: [Moments; 6],
    peak_fz_success: Moments,
    peak_fz_failure: Moments,
    phase_sums_s: [f64; 5],
    partial_to_full_s: Moments,
    failure_modes: FailureModes,
    /// Trials with an estimate and its standard deviations, and of them those whose error lies
    /// within two standard deviations, per axis.
    with_std: usize,
    within_2sigma: [usize; 6],
}

impl CellTally {
    fn add(&mut self, r: &TrialRecord, pass: Pass) {
        let res = &r.result;
        if let Some(e) = abs_errors(r) {
            (0..6).for_each(|a| self.abs_errors[a].add(pass, e[a]));
        }
        if res.fault.is_none() {
            let peaks = if res.success {
                &mut self.peak_fz_success
            } else {
                &mut self.peak_fz_failure
            };
            peaks.add(pass, res.peak_fz_n);
        }
        if res.success {
            let t = &res.times;
            let s = t.observe_s + t.retract_s + t.align_s + t.insert_s;
            self.partial_to_full_s.add(pass, s);
        }
        if pass == Pass::Mean {
            self.trials += 1;
            self.successes += usize::from(res.success);
            self.sim_faults += usize::from(res.fault.is_some());
            self.error_trials += usize::from(res.error_message.is_some());
            self.failure_modes.add(res);
            if let Some(z) = standardised_errors(r) {
                self.with_std += 1;
                (0..6).for_each(|a| self.within_2sigma[a] += usize::from(z[a].abs() <= 2.0));
            }
            let t = &res.times;
            let phases = [t.search_s, t.observe_s, t.retract_s, t.align_s, t.insert_s];
            (0..5).for_each(|p| self.phase_sums_s[p] += phases[p]);
        }
    }

    fn summary(&self, cell: Condition) -> CellSummary {
        let n = self.trials;
        let per_axis = |f: fn(&MeanStd) -> f64| -> Option<[f64; 6]> {
            let cols: Vec<MeanStd> = self.abs_errors.iter().filter_map(Moments::finish).collect();
            (cols.len() == 6).then(|| std::array::from_fn(|a| f(&cols[a])))
        };
        let per_trial = |v: f64| if n == 0 { 0.0 } else { v / n as f64 };
        CellSummary {
            trials: n,
            successes: self.successes,
            sim_faults: self.sim_faults,
            error_trials: self.error_trials,
            success_rate: per_trial(self.successes as f64),
            success_ci95: wilson_interval(self.successes, n),
            mae: per_axis(|m| m.mean),
            abs_error_std: per_axis(|m| m.std),
            coverage_2sigma: (self.with_std > 0)
                .then(|| self.within_2sigma.map(|k| k as f64 / self.with_std as f64)),
            peak_fz_success_n: self.peak_fz_success.finish(),
            peak_fz_failure_n: self.peak_fz_failure.finish(),
            mean_phase_s: self.phase_sums_s.map(per_trial),
            partial_to_full_s: self.partial_to_full_s.finish(),
            failure_modes: self.failure_modes,
            cell,
        }
    }
}

fn opt(v: Option<f64>, digits: usize) -> String {
    v.map_or(String::new(), |v| format!("{v:.digits$}"))
}

/// `summary.csv`: one row per cell.
pub fn summary_csv(summary: &Summary) -> Vec<u8> {
    let mut w = csv::Writer::from_writer(Vec::new());
    let mut header: Vec<String> = [
        "geometry",
        "clearance_mm",
        "method",
        "t_obs_s",
        "trials",
        "successes",
        "sim_faults",
        "error_trials",
        "success_rate",
        "ci95_low",
        "ci95_high",
    ]
    .map(String::from)
    .to_vec();
    header.extend(AXES.iter().map(|a| format!("mae_{a}")));
    header.extend(AXES.iter().map(|a| format!("abs_error_std_{a}")));
    header.extend(
        [
            "peak_fz_success_mean_n",
            "peak_fz_success_std_n",
            "peak_fz_failure_mean_n",
            "peak_fz_failure_std_n",
            "search_s",
            "observe_s",
            "retract_s",
            "align_s",
            "insert_s",
            "partial_to_full_success_s",
            "failures_jam",
            "failures_stall",
            "failures_wedge",
        ]
        .map(String::from),
    );
    header.extend(COVERAGE_AXES.iter().map(|a| format!("coverage_2sigma_{a}")));
    w.write_record(&header).expect("in-memory csv");
    for c in summary.cells.iter().chain(&summary.pooled) {
        let mut row = vec![
            c.cell.geometry.clone(),
            c.cell.clearance_mm.to_string(),
            c.cell.method.name().into(),
            c.cell.t_obs_s.to_string(),
            c.trials.to_string(),
            c.successes.to_string(),
            c.sim_faults.to_string(),
            c.error_trials.to_string(),
            format!("{:.4}", c.success_rate),
            format!("{:.4}", c.success_ci95[0]),
            format!("{:.4}", c.success_ci95[1]),
        ];
        for v in [c.mae, c.abs_error_std] {
            row.extend((0..6).map(|a| opt(v.map(|v| v[a]), 4)));
        }
        for m in [c.peak_fz_success_n, c.peak_fz_failure_n] {
            row.push(opt(m.map(|m| m.mean), 3));
            row.push(opt(m.map(|m| m.std), 3));
        }
        row.extend(c.mean_phase_s.iter().map(|t| format!("{t:.3}")));
        row.push(opt(c.partial_to_full_s.map(|m| m.mean), 3));
        let f = c.failure_modes;
        row.extend([f.jam, f.stall, f.wedge].map(|n| n.to_string()));
        row.extend((0..6).map(|a| opt(c.coverage_2sigma.map(|v| v[a]), 4)));
        w.write_record(&row).expect("in-memory csv");
    }
    w.into_inner().expect("in-memory csv")
}

/// The summary as a text table (what `campaign` prints).
pub fn summary_table(summary: &Summary) -> String {
    let mut out = format!(
        "{:<10} {:>6} {:<8} {:>5} {:>9} {:>13} {:>5} {:>5} {:>5} {:>5} {:>5} {:>5} {:>11} {:>11} {:>9} {:>12}\n",
        "geometry",
        "c mm",
        "method",
        "t_obs",
        "success",
        "95% CI",
        "x mm",
        "y mm",
        "z mm",
        "r deg",
        "p deg",
        "yw deg",
        "Fz ok N",
        "Fz fail N",
        "to full s",
        "jam/stl/wdg"
    );
    for c in summary.cells.iter().chain(&summary.pooled) {
        let mae = |a: usize| opt(c.mae.map(|m| m[a]), 2);
        let fz =
            |m: Option<MeanStd>| m.map_or("-".into(), |m| format!("{:.1}±{:.1}", m.mean, m.std));
        out += &format!(
            "{:<10} {:>6} {:<8} {:>5} {:>4}/{:<4} {:>5.0}-{:<5.0}% {:>5} {:>5} {:>5} {:>5} {:>5} {:>5} {:>11} {:>11} {:>9} {:>12}\n",
            c.cell.geometry,
            c.cell.clearance_mm,
            c.cell.method.name(),
            c.cell.t_obs_s,
            c.successes,
            c.trials,
            c.success_ci95[0] * 100.0,
            c.success_ci95[1] * 100.0,
            mae(0),
            mae(1),
            mae(2),
            mae(3),
            mae(4),
            mae(5),
            fz(c.peak_fz_success_n),
            fz(c.peak_fz_failure_n),
            opt(c.partial_to_full_s.map(|m| m.mean), 1),
            format!(
                "{}/{}/{}",
                c.failure_modes.jam, c.failure_modes.stall, c.failure_modes.wedge
            ),
        );
    }
    let errors: usize = summary.cells.iter().map(|c| c.error_trials).sum();
    if errors > 0 {
        out += &format!(
            "{errors} trial(s) ended in error (a bug or an input the checks missed): outcome \"error\" and error_message in trials.jsonl\n"
        );
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::method::config::Method;

    fn cell(geometry: &str, clearance_mm: f64, method: Method, t_obs_s: f64) -> Condition {
        Condition {
            geometry: geometry.into(),
            clearance_mm,
            method,
            t_obs_s,
        }
    }

    #[test]
    fn several_clearances_pool_per_clearance_and_over_all() {
        let cells = [
            cell("cross", 0.1, Method::Manifold, 6.0),
            cell("cross", 0.1, Method::Direct, 10.0),
            cell("cross", 0.5, Method::Manifold, 6.0),
            cell("cross", 0.5, Method::Direct, 10.0),
            cell("gear", 0.1, Method::Manifold, 6.0),
            cell("gear", 0.1, Method::Direct, 10.0),
        ];
        let (groups, of) = pooled_groups(&cells);
        let names: Vec<(f64, Method)> = groups.iter().map(|g| (g.clearance_mm, g.method)).collect();
        assert_eq!(
            names,
            [
                (0.1, Method::Manifold),
                (0.1, Method::Direct),
                (0.5, Method::Manifold),
                (0.5, Method::Direct),
                (0.0, Method::Manifold),
                (0.0, Method::Direct),
            ]
        );
        assert!(groups.iter().all(|g| g.geometry == "all"));
        // gear 0.1 manifold: its clearance's group and the overall one.
        assert_eq!(of[4], vec![0, 4]);
        // One clearance: one group per (method, t_obs) at it, as before.
        let (groups, of) = pooled_groups(&[cells[0].clone(), cells[4].clone()]);
        assert_eq!(groups.len(), 1);
        assert_eq!(groups[0].clearance_mm, 0.1);
        assert_eq!(of, vec![vec![0], vec![0]]);
    }

    /// A manifold trial's record with `errors` (mm, deg) and `estimate_std` (m, rad).
    fn estimated(errors: [f64; 6], std: [f64; 6]) -> TrialRecord {
        let [x_mm, y_mm, z_mm, roll_deg, pitch_deg, yaw_deg] = errors;
        serde_json::from_value(serde_json::json!({
            "cell": 0, "trial": 0, "seed": 1, "geometry": "cross", "clearance_mm": 0.5,
            "method": "manifold", "start": "partial", "t_obs_s": 10.0, "offset": [0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
            "outcome": "success", "stopped": null, "success": true, "fault": null,
            "estimate": [0.6, 0.0, 0.2, 0.0, 0.0, 0.0], "estimate_std": std,
            "errors": { "x_mm": x_mm, "y_mm": y_mm, "z_mm": z_mm, "roll_deg": roll_deg,
                        "pitch_deg": pitch_deg, "yaw_deg": yaw_deg },
            "final_depth_mm": 30.0, "contact_observations": 1000, "observations_used": 1000,
            "peak_fz_n": 1.0, "mean_fz_n": 1.0, "insert_fz_n": [],
            "times": { "search_s": 0.0, "observe_s": 10.0, "retract_s": 0.0, "align_s": 0.0,
                       "insert_s": 1.0 }
        }))
        .expect("a record")
    }

    #[test]
    fn coverage_counts_the_errors_within_two_standard_deviations_per_axis() {
        // std 0.1 mm and 1 deg (in m and rad): 0.15 mm / 1.5 deg lie within 2 sigma, 0.25 mm /
        // 2.5 deg beyond.
        let std = [
            1e-4,
            1e-4,
            1e-4,
            1f64.to_radians(),
            1f64.to_radians(),
            1f64.to_radians(),
        ];
        let inside = estimated([0.15, -0.15, 0.15, 1.5, -1.5, 1.5], std);
        let outside_x = estimated([0.25, 0.0, 0.0, 0.0, 0.0, -2.5], std);
        let z = standardised_errors(&outside_x).unwrap();
        assert!(
            (z[0] - 2.5).abs() < 1e-9 && (z[5] + 2.5).abs() < 1e-9,
            "{z:?}"
        );
        let mut tally = CellTally::default();
        for r in [&inside, &outside_x] {
            tally.add(r, Pass::Mean);
            tally.add(r, Pass::Spread);
        }
        let summary = tally.summary(cell("cross", 0.5, Method::Manifold, 10.0));
        assert_eq!(
            summary.coverage_2sigma,
            Some([0.5, 1.0, 1.0, 1.0, 1.0, 0.5])
        );
        // A trial with no estimate (the direct baseline) is left out of the coverage.
        let mut direct = CellTally::default();
        direct.add(&inside.clone().without_estimate(), Pass::Mean);
        assert_eq!(
            direct
                .summary(cell("cross", 0.5, Method::Direct, 10.0))
                .coverage_2sigma,
            None
        );
    }

    #[test]
    fn coverage_reads_the_error_against_the_hole_as_read_where_the_encoders_are_off() {
        // x 0.5 mm off the true hole (a kinematic calibration error), 0.05 mm off the hole as
        // the robot reads it: the registration's std of 0.1 mm covers the latter; the MAE keeps
        // the former.
        let std = [1e-4, 1e-4, 1e-4, 0.02, 0.02, 0.02];
        let mut r = estimated([0.5, 0.0, 0.0, 0.0, 0.0, 0.0], std);
        assert!((standardised_errors(&r).unwrap()[0] - 5.0).abs() < 1e-9);
        let mut read = r.result.errors.clone().unwrap();
        read.x_mm = 0.05;
        r.result.read_errors = Some(read);
        assert!((standardised_errors(&r).unwrap()[0] - 0.5).abs() < 1e-9);
        assert_eq!(abs_errors(&r).unwrap()[0], 0.5);
    }

    impl TrialRecord {
        fn without_estimate(mut self) -> Self {
            self.result.estimate = None;
            self.result.estimate_std = None;
            self.result.errors = None;
            self
        }
    }

    #[test]
    fn wilson_matches_reference_values() {
        // Reference: 8/10 -> [0.490, 0.943]; 0/10 -> [0, 0.278]; 10/10 -> [0.722, 1].
        let close =
            |a: [f64; 2], b: [f64; 2]| (a[0] - b[0]).abs() < 1e-3 && (a[1] - b[1]).abs() < 1e-3;
        assert!(
            close(wilson_interval(8, 10), [0.4902, 0.9433]),
            "{:?}",
            wilson_interval(8, 10)
        );
        assert!(close(wilson_interval(0, 10), [0.0, 0.2775]));
        assert!(close(wilson_interval(10, 10), [0.7225, 1.0]));
    }

    #[test]
    fn mean_std_of_a_sample() {
        let m = MeanStd::of(&[1.0, 3.0]).unwrap();
        assert_eq!((m.mean, m.std, m.n), (2.0, 1.0, 2));
        assert!(MeanStd::of(&[]).is_none());
    }
}
