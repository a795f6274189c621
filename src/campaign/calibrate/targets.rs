//! The targets file of `pegtwin calibrate` (issue 46): what was measured on a real cell, which of
//! those figures the calibration fits and which it holds out, and which `[cell]` values are free
//! with their prior ranges. Checked against the scenario before any trial runs: every figure
//! must name one row of the scenario's summary (a cell, or the pooled row of its method), every
//! count fit its trials, every free value have a range the `[cell]` section accepts.

use crate::campaign::scenario::Scenario;
use crate::campaign::summary::{CellSummary, Summary, SummaryTally};
use crate::choice::Choice;
use crate::error::{Error, Result};
use crate::method::config::Method;
use crate::twin::real_cell::RealCell;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::Path;

/// The most parameter draws a calibration may ask for.
pub const MAX_SAMPLES: usize = 4096;

/// A targets file as written.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct TargetsFile {
    /// The `[cell]` values the calibration fits ([`FreeValue`] names).
    pub free: Vec<String>,
    /// Prior ranges, uniform, where other than the scenario's `[cell]` range of the value.
    #[serde(default)]
    pub prior: BTreeMap<String, [f64; 2]>,
    /// How many parameter draws (each one a campaign of the targets' cells).
    #[serde(default = "default_samples")]
    pub samples: usize,
    /// Seed of the draws (the trials keep the scenario's seeds).
    #[serde(default = "default_seed")]
    pub seed: u64,
    /// The measured figures.
    #[serde(rename = "target")]
    pub targets: Vec<Target>,
}

fn default_samples() -> usize {
    32
}

fn default_seed() -> u64 {
    1
}

/// Whether a figure is fitted or held out to judge the fit.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Role {
    Fit,
    HoldOut,
}

/// What was measured: a row of the campaign summary ([`crate::campaign::summary::CellSummary`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Figure {
    /// Successes out of trials.
    Success,
    /// Mean absolute error of the estimate on one axis (the manifold method), mm or deg.
    MaeXMm,
    MaeYMm,
    MaeZMm,
    MaeRollDeg,
    MaePitchDeg,
    MaeYawDeg,
    /// Mean peak |Fz| of the successes, or of the failures, N.
    PeakFzSuccessN,
    PeakFzFailureN,
}

/// One measured figure.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct Target {
    /// A label for the report (default: the figure and its row).
    #[serde(default)]
    pub name: Option<String>,
    pub role: Role,
    pub figure: Figure,
    pub method: Method,
    /// The observation time of the row, s (needed when the method runs several).
    #[serde(default)]
    pub t_obs_s: Option<f64>,
    /// The geometry of the row (default: every geometry pooled, or the only one).
    #[serde(default)]
    pub geometry: Option<String>,
    /// The clearance of the row, mm (default: every clearance pooled, or the only one).
    #[serde(default)]
    pub clearance_mm: Option<f64>,
    /// `success`: how many succeeded, out of `trials`.
    #[serde(default)]
    pub successes: Option<usize>,
    #[serde(default)]
    pub trials: Option<usize>,
    /// Other figures: the measured mean, the spread over the trials (standard deviation) and
    /// how many trials it is over.
    #[serde(default)]
    pub mean: Option<f64>,
    #[serde(default)]
    pub std: Option<f64>,
    #[serde(default)]
    pub n: Option<usize>,
}

/// A measured figure's value.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Measured {
    /// `k` successes of `n` trials.
    Count { k: usize, n: usize },
    /// A mean over `n` trials with their standard deviation.
    Mean { mean: f64, std: f64, n: usize },
}

/// A `[cell]` value the calibration may fit.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FreeValue {
    JointFrictionScale,
    ContactFriction,
    StaticOverKinetic,
    WrenchGain,
    PayloadError,
    EncoderOffsetRad,
    PrintDeviationM,
    EdgeBevelM,
}

const FREE_VALUES: [(&str, FreeValue); 8] = [
    ("joint_friction_scale", FreeValue::JointFrictionScale),
    ("contact_friction", FreeValue::ContactFriction),
    ("static_over_kinetic", FreeValue::StaticOverKinetic),
    ("wrench_gain", FreeValue::WrenchGain),
    ("payload_error", FreeValue::PayloadError),
    ("encoder_offset_rad", FreeValue::EncoderOffsetRad),
    ("print_deviation_m", FreeValue::PrintDeviationM),
    ("edge_bevel_m", FreeValue::EdgeBevelM),
];

impl FreeValue {
    fn named(name: &str) -> Option<Self> {
        FREE_VALUES
            .iter()
            .find(|(n, _)| *n == name)
            .map(|(_, v)| *v)
    }

    pub fn name(self) -> &'static str {
        FREE_VALUES
            .iter()
            .find(|(_, v)| *v == self)
            .expect("listed")
            .0
    }

    /// The scenario's range of the value (a half-range's is `[0, h]`).
    fn range_in(self, cell: &RealCell) -> [f64; 2] {
        match self {
            FreeValue::JointFrictionScale => cell.joint_friction_scale,
            FreeValue::ContactFriction => cell.contact_friction,
            FreeValue::StaticOverKinetic => cell.static_over_kinetic,
            FreeValue::WrenchGain => cell.wrench_gain,
            FreeValue::PayloadError => cell.payload_error,
            FreeValue::EncoderOffsetRad => [0.0, cell.encoder_offset_rad],
            FreeValue::PrintDeviationM => cell.print_deviation_m,
            FreeValue::EdgeBevelM => cell.edge_bevel_m,
        }
    }

    /// Sets the value in `cell` to `value` (a range to that one value; the encoder offsets'
    /// half-range to it).
    pub fn set(self, cell: &mut RealCell, value: f64) {
        self.set_range(cell, [value, value]);
    }

    /// Sets the value in `cell` from its posterior 5 / 50 / 95 % quantiles: a range to the 90 %
    /// range; the encoder offsets' half-range, which draws each trial's offsets and cannot hold
    /// a range itself, to the median (its 95 % point would widen every trial's offsets).
    pub fn set_calibrated(self, cell: &mut RealCell, q: [f64; 3]) {
        match self {
            FreeValue::EncoderOffsetRad => cell.encoder_offset_rad = q[1],
            _ => self.set_range(cell, [q[0], q[2]]),
        }
    }

    /// Sets the value's range in `cell` (the encoder offsets' half-range to its top).
    fn set_range(self, cell: &mut RealCell, range: [f64; 2]) {
        match self {
            FreeValue::JointFrictionScale => cell.joint_friction_scale = range,
            FreeValue::ContactFriction => cell.contact_friction = range,
            FreeValue::StaticOverKinetic => cell.static_over_kinetic = range,
            FreeValue::WrenchGain => cell.wrench_gain = range,
            FreeValue::PayloadError => cell.payload_error = range,
            FreeValue::EncoderOffsetRad => cell.encoder_offset_rad = range[1],
            FreeValue::PrintDeviationM => cell.print_deviation_m = range,
            FreeValue::EdgeBevelM => cell.edge_bevel_m = range,
        }
    }
}

/// A free value with its prior range.
#[derive(Clone, Copy, Debug)]
pub struct Free {
    pub value: FreeValue,
    pub prior: [f64; 2],
}

/// A target checked against the scenario: its measured value and which summary row it reads.
#[derive(Clone, Debug)]
pub struct Checked {
    pub target: Target,
    pub label: String,
    pub measured: Measured,
}

/// The targets file, checked.
#[derive(Clone, Debug)]
pub struct Targets {
    pub file: TargetsFile,
    pub free: Vec<Free>,
    pub targets: Vec<Checked>,
}

impl Targets {
    /// Reads `path` and checks it against `scenario` (exit 2 naming the field otherwise).
    pub fn load(path: &Path, scenario: &Scenario) -> Result<Self> {
        let text = crate::files::read_text(path)?;
        let file: TargetsFile =
            crate::toml_input::parse(&text).map_err(|e| Error::file(path, e))?;
        Self::check(file, scenario).map_err(|e| Error::file(path, e))
    }

    /// `file` checked against `scenario`, or what is wrong, naming the field.
    pub fn check(file: TargetsFile, scenario: &Scenario) -> std::result::Result<Self, String> {
        if scenario.cell.is_ideal() {
            return Err("the scenario's [cell] is ideal: calibrate a real cell".into());
        }
        let free = free_values(&file, scenario)?;
        let fewest = free.len() + 3;
        if !(fewest..=MAX_SAMPLES).contains(&file.samples) {
            return Err(format!(
                "samples = {}: expected {fewest} to {MAX_SAMPLES} (a line through the draws of \
                 {} free values, and two draws to judge it by)",
                file.samples,
                free.len()
            ));
        }
        let empty = SummaryTally::new(scenario).finish(scenario);
        let mut targets = Vec::new();
        for (i, t) in file.targets.iter().enumerate() {
            let at = format!("target[{i}]");
            let row = row_of(&empty, t).map_err(|e| format!("{at}: {e}"))?;
            let measured = measured(t).map_err(|e| format!("{at}.{e}"))?;
            let label = t.name.clone().unwrap_or_else(|| {
                let figure = serde_json::to_value(t.figure).expect("a figure serialises");
                format!(
                    "{} of {}",
                    figure.as_str().unwrap_or("figure"),
                    row.cell.label()
                )
            });
            targets.push(Checked {
                target: t.clone(),
                label,
                measured,
            });
        }
        if !targets.iter().any(|t| t.target.role == Role::Fit) {
            return Err("target: expected at least one with role = \"fit\"".into());
        }
        Ok(Targets {
            file,
            free,
            targets,
        })
    }
}

/// The free values and their priors: each named once, each prior a finite range, low below high.
fn free_values(file: &TargetsFile, scenario: &Scenario) -> std::result::Result<Vec<Free>, String> {
    if file.free.is_empty() {
        return Err("free: expected at least one [cell] value to fit".into());
    }
    let names: Vec<&str> = FREE_VALUES.iter().map(|(n, _)| *n).collect();
    let mut free: Vec<Free> = Vec::new();
    for name in &file.free {
        let value = FreeValue::named(name)
            .ok_or_else(|| format!("free: {name:?}: expected one of {}", names.join(", ")))?;
        if free.iter().any(|f| f.value == value) {
            return Err(format!("free: {name:?} named twice"));
        }
        let prior = file
            .prior
            .get(name.as_str())
            .copied()
            .unwrap_or_else(|| value.range_in(&scenario.cell));
        let [lo, hi] = prior;
        if !(lo.is_finite() && hi.is_finite() && lo < hi) {
            return Err(format!(
                "prior.{name} = [{lo}, {hi}]: expected a finite range, low below high (the \
                 scenario's [cell] range is a single value: give its prior)"
            ));
        }
        for end in prior {
            let mut cell = scenario.cell.clone();
            value.set(&mut cell, end);
            cell.ensure_valid()
                .map_err(|e| format!("prior.{name} = [{lo}, {hi}]: {e}"))?;
        }
        free.push(Free { value, prior });
    }
    if let Some(name) = file.prior.keys().find(|k| !file.free.contains(k)) {
        return Err(format!(
            "prior.{name}: not a free value (free = {:?})",
            file.free
        ));
    }
    Ok(free)
}

/// What was measured, checked: a count within its trials, or a finite mean and spread.
fn measured(t: &Target) -> std::result::Result<Measured, String> {
    match (t.figure, t.successes, t.trials, t.mean, t.std, t.n) {
        (Figure::Success, Some(k), Some(n), None, None, None) if n > 0 && k <= n => {
            Ok(Measured::Count { k, n })
        }
        (Figure::Success, Some(k), Some(n), None, None, None) => Err(format!(
            "successes = {k}, trials = {n}: expected 0 <= successes <= trials, trials > 0"
        )),
        (Figure::Success, ..) => {
            Err("successes: a success figure gives successes and trials only".into())
        }
        (_, None, None, Some(mean), std, Some(n)) => {
            let std = std.unwrap_or(0.0);
            if mean.is_finite() && mean >= 0.0 && std.is_finite() && std >= 0.0 && n > 0 {
                Ok(Measured::Mean { mean, std, n })
            } else {
                Err(format!(
                    "mean = {mean}, std = {std}, n = {n}: expected a finite mean and std, both \
                     at least 0, over n > 0 trials"
                ))
            }
        }
        _ => Err("mean: this figure gives mean, n and optionally std (not successes)".into()),
    }
}

/// The summary row a target reads: its method (and observation time), its geometry or every
/// geometry pooled, its clearance or every clearance pooled; when the scenario has one geometry
/// or one clearance, that one.
pub fn row_of<'a>(
    summary: &'a Summary,
    t: &Target,
) -> std::result::Result<&'a CellSummary, String> {
    let rows = summary.cells.iter().chain(&summary.pooled);
    let geometries: Vec<&str> = unique(summary.cells.iter().map(|c| c.cell.geometry.as_str()));
    let clearances: Vec<u64> = unique(summary.cells.iter().map(|c| c.cell.clearance_mm.to_bits()));
    let geometry = match (&t.geometry, geometries.as_slice()) {
        (Some(g), _) => g.as_str(),
        (None, [only]) => only,
        (None, _) => "all",
    };
    let clearance = match (t.clearance_mm, clearances.as_slice()) {
        (Some(c), _) => c,
        (None, [only]) => f64::from_bits(*only),
        (None, _) => 0.0,
    };
    let matching: Vec<&CellSummary> = rows
        .filter(|r| {
            r.cell.method == t.method
                && r.cell.geometry == geometry
                && r.cell.clearance_mm == clearance
                && t.t_obs_s.is_none_or(|s| r.cell.t_obs_s == s)
        })
        .collect();
    match matching.as_slice() {
        [row] => Ok(row),
        [] => Err(format!(
            "no row of the scenario's summary is {} {} at {} mm{}",
            t.method.name(),
            geometry,
            if clearance == 0.0 {
                "every".into()
            } else {
                clearance.to_string()
            },
            t.t_obs_s
                .map(|s| format!(", t_obs {s} s"))
                .unwrap_or_default()
        )),
        _ => Err("the method runs several observation times here: give t_obs_s".into()),
    }
}

fn unique<T: PartialEq>(items: impl Iterator<Item = T>) -> Vec<T> {
    let mut out = Vec::new();
    for item in items {
        if !out.contains(&item) {
            out.push(item);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_calibrated_range_is_the_90_percent_range_and_a_half_range_the_median() {
        let mut cell = RealCell::default();
        FreeValue::JointFrictionScale.set_calibrated(&mut cell, [3.0, 4.0, 5.0]);
        assert_eq!(cell.joint_friction_scale, [3.0, 5.0]);
        FreeValue::EncoderOffsetRad.set_calibrated(&mut cell, [1e-3, 1.3e-3, 1.6e-3]);
        assert_eq!(cell.encoder_offset_rad, 1.3e-3);
    }
}
