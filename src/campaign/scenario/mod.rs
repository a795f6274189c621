//! Scenario files: what a campaign runs, as TOML.
//!
//! A scenario names the cells of an experiment (geometry x clearance x method x t_obs), the
//! trials per cell, the offset ranges, and overrides of the controller gains per phase, the sensor
//! model, the physics and the registration. Every field not given keeps the value `pegtwin trial`
//! uses; unknown fields are errors (with their line), and values are range-checked with errors
//! that name the field. Units: fields typed by people carry them in their names (`clearances_mm`,
//! `offset_deg`); gains and sensor parameters are SI as in the code (stiffness N/m on x, y, z and
//! N m/rad on roll, pitch, yaw, in the TCP frame). The fields are listed in docs/scenarios.md.

mod overrides;

pub use overrides::{
    AdaptiveOverride, DirectOverride, GainsOverride, InsertionOverride, PairPhysics, PhaseGains,
    PhysicsOverride,
};

use crate::choice::Choice;
use crate::error::{Error, Result};
use crate::method::config::{
    MAX_SUCCESS_EPS_M, MAX_T_OBS_S, MIN_T_OBS_S, Method, Start, TrialConfig,
};
use crate::method::manifold::MAX_POINTS;
use crate::method::manifold::cache::ManifoldSpec;
use crate::method::register::RegistrationConfig;
use crate::twin::assembly;
use crate::twin::geometry::{self, PartPair};
use crate::twin::real_cell::RealCell;
use crate::twin::robot::spec::RobotSpec;
use crate::twin::sensing::SensorParams;
use crate::twin::workcell::WorkCellParams;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// The most trials a cell may ask for.
pub const MAX_TRIALS_PER_CELL: usize = 1_000_000;

/// A scenario as written in its file.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scenario {
    /// A name for reports.
    pub name: String,
    /// Campaign seed; every trial's seed derives from it (see `campaign::trial_seed`).
    #[serde(default = "default_seed")]
    pub seed: u64,
    /// Trials per cell.
    pub trials: usize,
    /// Built-in geometry names.
    #[serde(default)]
    pub geometries: Vec<String>,
    /// Diametral clearances of the built-ins, mm.
    #[serde(default)]
    pub clearances_mm: Vec<f64>,
    /// Assembly files (your own peg and hole), relative to the scenario file: each runs at the
    /// clearance measured from its meshes, under its `name`.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub assemblies: Vec<PathBuf>,
    /// The assemblies' pairs and robots, loaded with the scenario (in the order of `assemblies`).
    #[serde(skip)]
    pub loaded_assemblies: Vec<assembly::Assembly>,
    /// The folder the assembly paths are relative to (the scenario file's), absolute.
    #[serde(skip)]
    pub assembly_dir: PathBuf,
    /// Observation times of the manifold method, s.
    pub t_obs_s: Vec<f64>,
    /// Methods to run: "manifold", "direct", "adaptive" and/or "active".
    pub methods: Vec<Method>,
    /// Observation time of the direct baseline, s (the paper: 10 s).
    #[serde(default = "default_direct_t_obs")]
    pub direct_t_obs_s: f64,
    /// How trials start: "partial" (the paper) or "above" (spiral search).
    #[serde(default = "default_start")]
    pub start: Start,
    /// Half-range of the uniform hole position offset, mm (x, y, z).
    #[serde(default = "default_offset")]
    pub offset_mm: f64,
    /// Half-range of the uniform hole orientation offset, deg (roll, pitch, yaw).
    #[serde(default = "default_offset")]
    pub offset_deg: f64,
    /// Success threshold on the final depth, mm (the paper: 2 mm).
    #[serde(default = "default_success")]
    pub success_mm: f64,
    #[serde(default)]
    pub manifold: ManifoldSpec,
    #[serde(default)]
    pub gains: PhaseGains,
    #[serde(default)]
    pub sensors: Option<SensorParams>,
    #[serde(default)]
    pub physics: PhysicsOverride,
    /// The real cell's imperfections: the profile and the ranges of its draws (`[cell]`).
    #[serde(default, skip_serializing_if = "RealCell::is_ideal")]
    pub cell: RealCell,
    /// A file whose `[cell]` section is this scenario's (a calibration's `cell.toml`), relative
    /// to the scenario file; read with the scenario, which then holds the section itself.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cell_file: Option<PathBuf>,
    /// Physics for some pairs only, over `[physics]` (a pair whose contact solve needs more
    /// passes than the rest, so that the others keep their physics and their records).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub pair_physics: Vec<PairPhysics>,
    #[serde(default)]
    pub registration: Option<RegistrationConfig>,
    /// The insertion's motion and break conditions, for every method.
    #[serde(default, skip_serializing_if = "InsertionOverride::is_default")]
    pub insertion: InsertionOverride,
    /// The direct baseline's own gains and insertion, over the above (the paper tuned the
    /// baseline's impedance for success, V-B; `pegtwin tune --target direct` searches them).
    #[serde(default, skip_serializing_if = "DirectOverride::is_default")]
    pub direct: DirectOverride,
    /// The adaptive method's longest observation, when it registers and when it stops.
    #[serde(default, skip_serializing_if = "AdaptiveOverride::is_default")]
    pub adaptive: AdaptiveOverride,
}

fn default_seed() -> u64 {
    1
}
fn default_direct_t_obs() -> f64 {
    10.0
}
fn default_start() -> Start {
    Start::Partial
}
fn default_offset() -> f64 {
    5.0
}
fn default_success() -> f64 {
    2.0
}

/// One condition of the experiment, a cell of its table (named `Condition` so as not to be
/// confused with the robot cell): the trials that share geometry, clearance, method and t_obs.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Condition {
    pub geometry: String,
    pub clearance_mm: f64,
    pub method: Method,
    pub t_obs_s: f64,
}

/// A cell of a campaign with what its trials take from the scenario ([`Scenario::plan`]).
#[derive(Clone, Debug)]
pub struct PlannedCell {
    pub condition: Condition,
    /// The trial's settings: the scenario's gains, insertion and registration over the defaults.
    pub config: TrialConfig,
    /// The robot cell's: the scenario's physics (and its pair's own), sensors, fixture.
    pub params: WorkCellParams,
}

impl Condition {
    /// A short label, e.g. `cross 0.5 mm manifold 6 s`.
    pub fn label(&self) -> String {
        let m = self.method.name();
        format!(
            "{} {} mm {m} {} s",
            self.geometry, self.clearance_mm, self.t_obs_s
        )
    }
}

/// The folder of the scenario file `path`, which its relative paths start from (a bare file
/// name's parent is "": the working folder).
fn folder_of(path: &Path) -> &Path {
    path.parent()
        .filter(|d| !d.as_os_str().is_empty())
        .unwrap_or(Path::new("."))
}

/// A parse error's `line N: ...` of the merged scenario text said as the field it is on
/// (`[gains.insert] stiffness: ...`): the merged text's lines are neither the file's nor the
/// overrides'.
fn name_merged_line(merged: &str, msg: &str) -> String {
    let Some((n, rest)) = (msg.strip_prefix("line "))
        .and_then(|m| m.split_once(": "))
        .and_then(|(n, rest)| Some((n.parse::<usize>().ok()?, rest)))
    else {
        return msg.to_owned();
    };
    let lines: Vec<&str> = merged.lines().collect();
    let Some(line) = n.checked_sub(1).and_then(|i| lines.get(i)) else {
        return msg.to_owned();
    };
    let key = line.split('=').next().unwrap_or("").trim();
    let section = (lines[..n - 1].iter().rev())
        .map(|l| l.trim())
        .find(|l| l.starts_with('['))
        .map_or(String::new(), |s| format!("{s} "));
    format!("{section}{key}: {rest}")
}

/// Lays `over` over `base`: tables merged key by key, any other value replaced.
fn merge_tables(base: &mut toml::Table, over: toml::Table) {
    for (key, value) in over {
        match (base.get_mut(&key), value) {
            (Some(toml::Value::Table(b)), toml::Value::Table(o)) => merge_tables(b, o),
            (_, v) => {
                base.insert(key, v);
            }
        }
    }
}

impl Scenario {
    /// Reads and validates a scenario file, loading its assemblies (relative to its folder).
    pub fn load(path: &Path) -> Result<Self> {
        let text = crate::files::read_text(path)?;
        Self::parse_in(&text, folder_of(path)).map_err(|e| match e {
            Error::Input(msg) => Error::file(path, msg),
            other => other,
        })
    }

    /// Reads a scenario file with the TOML text `overrides` laid over it: tables are merged key
    /// by key and other values replaced, so `"[gains.insert]\nstiffness = [...]"` changes
    /// that one field whatever else the file's `[gains.insert]` holds. The result is checked as
    /// a scenario file is (a candidate's gains in an outer search, e.g. Optuna's).
    pub fn load_with(path: &Path, overrides: &str) -> Result<Self> {
        if overrides.trim().is_empty() {
            return Self::load(path);
        }
        let text = crate::files::read_text(path)?;
        let mut base: toml::Table =
            toml::from_str(&text).map_err(|e| Error::file(path, e.to_string()))?;
        let over: toml::Table =
            toml::from_str(overrides).map_err(|e| Error::Input(format!("overrides: {e}")))?;
        merge_tables(&mut base, over);
        let merged = toml::to_string(&base).expect("a TOML table serialises");
        Self::parse_in(&merged, folder_of(path)).map_err(|e| match e {
            Error::Input(msg) => Error::file(
                path,
                format!("with the overrides: {}", name_merged_line(&merged, &msg)),
            ),
            other => other,
        })
    }

    /// Parses and validates scenario text (assembly paths relative to the working folder).
    pub fn parse(text: &str) -> Result<Self> {
        Self::parse_in(text, Path::new("."))
    }

    /// Parses and validates scenario text, loading its assemblies from paths relative to `dir`.
    pub fn parse_in(text: &str, dir: &Path) -> Result<Self> {
        let mut scenario: Scenario = crate::toml_input::parse(text).map_err(Error::Input)?;
        scenario.read_cell_file(text, dir)?;
        scenario.load_assemblies(dir)?;
        scenario.ensure_valid()?;
        Ok(scenario)
    }

    /// Reads `cell_file` (relative to `dir`) into `cell`: the scenario then holds the section
    /// itself, as a campaign folder records it. A scenario giving both is refused.
    fn read_cell_file(&mut self, text: &str, dir: &Path) -> Result<()> {
        let Some(file) = self.cell_file.take() else {
            return Ok(());
        };
        let given: toml::Value = toml::from_str(text).map_err(|e| Error::Input(e.to_string()))?;
        if given.get("cell").is_some() {
            return Err(Error::Input(format!(
                "cell_file = {:?} and a [cell] section: give one of them",
                file.display().to_string()
            )));
        }
        #[derive(Deserialize, Serialize)]
        #[serde(deny_unknown_fields)]
        struct CellFile {
            cell: RealCell,
        }
        let path = dir.join(&file);
        let cell_text = crate::files::read_text(&path)?;
        let read: CellFile =
            crate::toml_input::parse(&cell_text).map_err(|e| Error::file(&path, e))?;
        read.cell
            .ensure_valid()
            .map_err(|e| Error::file(&path, format!("[cell]: {e}")))?;
        self.cell = read.cell;
        Ok(())
    }

    /// Loads the assembly files, their paths relative to `dir` (a campaign folder records it:
    /// `campaign.json` holds the scenario without its loaded pairs).
    pub fn load_assemblies(&mut self, dir: &Path) -> Result<()> {
        self.assembly_dir = std::path::absolute(dir)
            .map_err(|e| Error::file(dir, format!("cannot resolve the folder: {e}")))?;
        self.loaded_assemblies = self
            .assemblies
            .iter()
            .map(|a| assembly::load(&self.assembly_dir.join(a)))
            .collect::<Result<_>>()?;
        Ok(())
    }

    /// The pair a cell runs: a built-in at the cell's clearance (on the real cell, as printed
    /// once from the scenario's seed: [`crate::twin::real_cell::RealCell::print`]), or an
    /// assembly by its name.
    pub fn pair(&self, cell: &Condition) -> Result<PartPair> {
        if let Some(a) = self.assembly_of(cell) {
            return Ok(a.pair.clone());
        }
        let builtin = geometry::builtin_by_name(&cell.geometry)?;
        let exact = geometry::build_builtin(builtin, cell.clearance_mm * 1e-3)?;
        self.cell.printed(self.seed, exact)
    }

    /// The robot a cell runs on: its assembly's, else the built-in iiwa 14.
    pub fn robot(&self, cell: &Condition) -> RobotSpec {
        self.assembly_of(cell)
            .map_or_else(RobotSpec::default, |a| a.robot.clone())
    }

    /// The cell parameters of `cell`'s trials and manifold: [`Scenario::cell_params`] with its
    /// pair's `[[pair_physics]]` over them, and the hole where its robot's cell stands it.
    pub fn work_cell_params_for(&self, cell: &Condition) -> WorkCellParams {
        let mut p = self.work_cell_params();
        if let Some(o) = self.pair_physics.iter().find(|o| o.matches(cell)) {
            o.physics.apply(&mut p);
        }
        p.placed_for(&self.robot(cell))
    }

    fn assembly_of(&self, cell: &Condition) -> Option<&assembly::Assembly> {
        self.loaded_assemblies
            .iter()
            .find(|a| a.pair.name == cell.geometry)
    }

    /// Checks every field, naming the first that is wrong.
    pub fn ensure_valid(&self) -> Result<()> {
        let bad = |field: &str, v: String, expected: &str| {
            Err(Error::Input(format!("{field} = {v}: expected {expected}")))
        };
        if !(1..=MAX_TRIALS_PER_CELL).contains(&self.trials) {
            let expected = format!("1 to {MAX_TRIALS_PER_CELL}");
            return bad("trials", self.trials.to_string(), &expected);
        }
        if self.geometries.is_empty() && self.assemblies.is_empty() {
            return bad(
                "geometries",
                "[]".into(),
                "at least one geometry or assembly",
            );
        }
        for g in &self.geometries {
            geometry::builtin_by_name(g).map_err(|e| Error::Input(format!("geometries: {e}")))?;
        }
        self.ensure_assembly_names()?;
        if self.clearances_mm.is_empty() && !self.geometries.is_empty() {
            return bad("clearances_mm", "[]".into(), "at least one clearance");
        }
        for &c in &self.clearances_mm {
            geometry::check_clearance(c * 1e-3)
                .map_err(|e| Error::Input(format!("clearances_mm: {e}")))?;
        }
        if self.methods.is_empty() {
            return bad(
                "methods",
                "[]".into(),
                "\"manifold\", \"direct\" and/or \"adaptive\"",
            );
        }
        if self.methods.contains(&Method::Manifold) && self.t_obs_s.is_empty() {
            return bad("t_obs_s", "[]".into(), "at least one observation time");
        }
        for &t in self.t_obs_s.iter().chain([&self.direct_t_obs_s]) {
            if !(MIN_T_OBS_S..=MAX_T_OBS_S).contains(&t) {
                let expected = format!("times in [{MIN_T_OBS_S}, {MAX_T_OBS_S}] s");
                return bad("t_obs_s", format!("{t:?}"), &expected);
            }
        }
        for (field, v, max) in [
            ("offset_mm", self.offset_mm, 20.0),
            ("offset_deg", self.offset_deg, 20.0),
        ] {
            if !(v >= 0.0 && v <= max) {
                return bad(field, format!("{v:?}"), &format!("a value in [0, {max}]"));
            }
        }
        let max_success_mm = MAX_SUCCESS_EPS_M * 1e3;
        if !(self.success_mm > 0.0 && self.success_mm <= max_success_mm) {
            let expected = format!("a depth in (0, {max_success_mm}] mm");
            return bad("success_mm", format!("{:?}", self.success_mm), &expected);
        }
        self.ensure_no_repeats()?;
        let m = &self.manifold;
        if !(1000..=MAX_POINTS).contains(&m.points) {
            let expected = format!("1000 to {MAX_POINTS}");
            return bad("manifold.points", m.points.to_string(), &expected);
        }
        m.sampler()
            .ensure_valid()
            .map_err(|e| Error::Input(format!("manifold: {e}")))?;
        m.ensure_episodes_used()?;
        self.ensure_gains_valid()?;
        self.insertion.ensure_valid("insertion")?;
        self.direct.insertion.ensure_valid("direct.insertion")?;
        self.adaptive.ensure_valid()?;
        self.work_cell_params().ensure_valid()?;
        self.ensure_pair_physics_valid()?;
        for cell in self.cells() {
            self.trial_config(&cell)
                .ensure_valid()
                .map_err(|e| Error::Input(format!("{}: {e}", cell.label())))?;
        }
        Ok(())
    }

    /// An assembly's name labels its cells and seeds its trials: it may not be a built-in's or
    /// another assembly's.
    fn ensure_assembly_names(&self) -> Result<()> {
        let pairs: Vec<&PartPair> = self.loaded_assemblies.iter().map(|a| &a.pair).collect();
        for (k, pair) in pairs.iter().enumerate() {
            let taken = geometry::builtin_by_name(&pair.name).is_ok()
                || pairs[..k].iter().any(|p| p.name == pair.name);
            if taken {
                return Err(Error::Input(format!(
                    "assemblies: {}: its name \"{}\" is already taken (a built-in or another \
                     assembly); give each assembly its own name",
                    self.assemblies[k].display(),
                    pair.name
                )));
            }
        }
        Ok(())
    }

    /// The gains of every phase, the scenario's and the direct baseline's, each over the
    /// phase's defaults, within the Sunrise ranges.
    fn ensure_gains_valid(&self) -> Result<()> {
        for (section, gains, method) in [
            ("gains", &self.gains, Method::Manifold),
            ("direct.gains", &self.direct.gains, Method::Direct),
        ] {
            let d = TrialConfig::for_method(method);
            for (phase, o, base) in [
                ("observe", &gains.observe, &d.observe_gains),
                ("align", &gains.align, &d.align_gains),
                ("insert", &gains.insert, &d.insert_gains),
            ] {
                o.apply(base)
                    .ensure_valid()
                    .map_err(|e| Error::Input(format!("{section}.{phase}: {e}")))?;
            }
        }
        Ok(())
    }

    /// Every `[[pair_physics]]` names a pair of the scenario, once, and its parameters are in
    /// range.
    fn ensure_pair_physics_valid(&self) -> Result<()> {
        let cells = self.cells();
        for (k, o) in self.pair_physics.iter().enumerate() {
            let at = match o.clearance_mm {
                Some(c) => format!("geometry \"{}\" at clearance_mm = {c}", o.geometry),
                None => format!("geometry \"{}\"", o.geometry),
            };
            let field = format!("pair_physics[{k}]");
            let Some(cell) = cells.iter().find(|c| o.matches(c)) else {
                return Err(Error::Input(format!(
                    "{field}: {at} is not a pair of this scenario: expected a name of `geometries` \
                     or of an assembly, and a clearance of `clearances_mm` (or none for all)"
                )));
            };
            let overlaps = |p: &PairPhysics| {
                p.geometry == o.geometry
                    && (p.clearance_mm.is_none()
                        || o.clearance_mm.is_none()
                        || p.clearance_mm == o.clearance_mm)
            };
            if self.pair_physics[..k].iter().any(overlaps) {
                return Err(Error::Input(format!(
                    "{field}: {at} is given physics twice; give each pair one entry"
                )));
            }
            self.work_cell_params_for(cell)
                .ensure_valid()
                .map_err(|e| Error::Input(format!("{field}: {e}")))?;
        }
        Ok(())
    }

    /// Refuses a geometry, clearance, method or observation time listed twice: it would run the
    /// same cell twice under one label.
    fn ensure_no_repeats(&self) -> Result<()> {
        fn first_repeat<T: PartialEq>(items: &[T]) -> Option<&T> {
            items
                .iter()
                .enumerate()
                .find(|(i, v)| items[..*i].contains(v))
                .map(|(_, v)| v)
        }
        let repeat = first_repeat(&self.geometries)
            .map(|g| ("geometries", format!("\"{g}\"")))
            .or_else(|| first_repeat(&self.clearances_mm).map(|c| ("clearances_mm", c.to_string())))
            .or_else(|| first_repeat(&self.t_obs_s).map(|t| ("t_obs_s", t.to_string())))
            .or_else(|| first_repeat(&self.methods).map(|m| ("methods", format!("{m:?}"))));
        match repeat {
            Some((field, v)) => Err(Error::Input(format!(
                "{field}: {v} is listed twice; each value names a cell once"
            ))),
            None => Ok(()),
        }
    }

    /// The campaign's plan: its cells in their fixed order ([`Scenario::cells`]), each with the
    /// settings and parameters its trials run at, resolved once.
    pub fn plan(&self) -> Vec<PlannedCell> {
        (self.cells().into_iter())
            .map(|condition| PlannedCell {
                config: self.trial_config(&condition),
                params: self.work_cell_params_for(&condition),
                condition,
            })
            .collect()
    }

    /// The cells in their fixed order: geometry, clearance (each built-in at every clearance,
    /// then each assembly at its measured one), then the manifold method at each t_obs, then
    /// the direct baseline, then the adaptive method (at its longest observation).
    pub fn cells(&self) -> Vec<Condition> {
        let builtins = self
            .geometries
            .iter()
            .flat_map(|g| self.clearances_mm.iter().map(move |&c| (g.clone(), c)));
        let assemblies = self
            .loaded_assemblies
            .iter()
            .map(|a| (a.pair.name.clone(), a.pair.clearance_mm()));
        let mut cells = Vec::new();
        for (geometry, clearance_mm) in builtins.chain(assemblies) {
            for &method in &[
                Method::Manifold,
                Method::Direct,
                Method::Adaptive,
                Method::Active,
            ] {
                if !self.methods.contains(&method) {
                    continue;
                }
                let times = match method {
                    Method::Manifold => self.t_obs_s.clone(),
                    Method::Direct => vec![self.direct_t_obs_s],
                    Method::Adaptive | Method::Active => vec![self.adaptive.t_obs_max_s()],
                };
                for t in times {
                    cells.push(Condition {
                        geometry: geometry.clone(),
                        clearance_mm,
                        method,
                        t_obs_s: t,
                    });
                }
            }
        }
        cells
    }

    /// The trial configuration of a cell: the defaults, the scenario's overrides, and for the
    /// direct baseline its own (`[direct]`) over those.
    pub fn trial_config(&self, cell: &Condition) -> TrialConfig {
        let d = TrialConfig::for_method(cell.method);
        let (m, a) = (self.offset_mm * 1e-3, self.offset_deg.to_radians());
        let mut c = TrialConfig {
            method: cell.method,
            start: self.start,
            t_obs_s: cell.t_obs_s,
            offset_range: [m, m, m, a, a, a],
            observe_gains: self.gains.observe.apply(&d.observe_gains),
            align_gains: self.gains.align.apply(&d.align_gains),
            insert_gains: self.gains.insert.apply(&d.insert_gains),
            success_eps_m: self.success_mm * 1e-3,
            registration: self.registration.clone().unwrap_or(d.registration.clone()),
            ..d
        };
        self.insertion.apply(&mut c);
        if cell.method.stops_itself() {
            self.adaptive.apply(&mut c);
        }
        if cell.method == Method::Direct {
            let g = &self.direct.gains;
            c.observe_gains = g.observe.apply(&c.observe_gains);
            c.align_gains = g.align.apply(&c.align_gains);
            c.insert_gains = g.insert.apply(&c.insert_gains);
            self.direct.insertion.apply(&mut c);
        }
        c
    }

    /// The cell parameters (sensors, physics) of every trial and manifold.
    pub fn work_cell_params(&self) -> WorkCellParams {
        let mut p = WorkCellParams::default();
        if let Some(s) = &self.sensors {
            p.sensors = s.clone();
        }
        self.physics.apply(&mut p);
        p.cell = self.cell.clone();
        p
    }

    /// A fingerprint of everything that decides the trials' results (not the name): campaigns
    /// and shards with the same fingerprint can be resumed and merged.
    pub fn fingerprint(&self) -> String {
        let mut s = self.clone();
        s.name.clear();
        let mut json = serde_json::to_string(&s).expect("scenario serialises");
        // The assemblies' contents, not only their paths: editing a mesh or the robot's URDF
        // is a new campaign (an assembly's content key covers its robot).
        for a in &self.loaded_assemblies {
            json.push_str(a.pair.content_key.as_deref().unwrap_or_default());
        }
        format!("{:08x}", crc32fast::hash(json.as_bytes()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::twin::real_cell::Profile;

    const MINIMAL: &str = r#"
name = "t"
trials = 2
geometries = ["cross"]
clearances_mm = [0.5]
t_obs_s = [6.0, 10.0]
methods = ["manifold", "direct"]
"#;

    #[test]
    fn the_adaptive_method_runs_at_its_longest_observation_with_its_own_settings() {
        let text = MINIMAL.replace(
            r#"methods = ["manifold", "direct"]"#,
            r#"methods = ["manifold", "adaptive"]"#,
        );
        let s = Scenario::parse(&text).unwrap();
        let cells = s.cells();
        assert_eq!(cells.len(), 3);
        assert_eq!(
            (cells[2].method, cells[2].t_obs_s),
            (Method::Adaptive, 10.0)
        );
        let set = format!(
            "{text}\n[adaptive]\nt_obs_max_s = 8.0\ncheck_from_s = 3.0\nmax_std_xy_mm = 0.2\n\
             stop_out_of_reach = false\n"
        );
        let s = Scenario::parse(&set).unwrap();
        let cell = &s.cells()[2];
        assert_eq!(cell.t_obs_s, 8.0);
        let a = s.trial_config(cell).adaptive;
        assert_eq!((a.check_from_s, a.max_std_xy_m), (3.0, Some(2e-4)));
        assert_eq!((a.max_std_yaw_rad, a.stop_out_of_reach), (None, false));
        // The manifold method's cells keep their settings.
        let manifold = s.trial_config(&s.cells()[0]).adaptive;
        assert_eq!(
            (manifold.check_from_s, manifold.stop_out_of_reach),
            (4.0, true)
        );
        for (bad, field) in [
            ("max_std_xy_mm = 0.0", "adaptive.max_std_xy_mm"),
            ("check_from_s = 12.0", "adaptive.check_from_s"),
            ("t_obs_max_s = 700.0", "adaptive.t_obs_max_s"),
            ("check_every_s = -1.0", "adaptive.check_every_s"),
        ] {
            let err = Scenario::parse(&format!("{text}\n[adaptive]\n{bad}\n")).unwrap_err();
            assert!(err.to_string().contains(field), "{bad}: {err}");
        }
    }

    #[test]
    fn minimal_scenario_gives_manifold_then_direct_cells() {
        let s = Scenario::parse(MINIMAL).unwrap();
        let cells = s.cells();
        assert_eq!(cells.len(), 3);
        assert_eq!(cells[0].t_obs_s, 6.0);
        assert_eq!(cells[2].method, Method::Direct);
        assert_eq!(cells[2].t_obs_s, 10.0);
    }

    #[test]
    fn the_geometric_sampler_refuses_the_robots_episodes() {
        use crate::method::manifold::cache::Sampler;
        let geometric = format!("{MINIMAL}\n[manifold]\nsampler = \"geometric\"\n");
        let s = Scenario::parse(&geometric).unwrap();
        assert_eq!(s.manifold.sampler, Sampler::Geometric);
        let err = Scenario::parse(&format!("{geometric}episodes = 3\n"))
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("manifold.episodes = 3") && err.contains("manifold.sampler = \"robot\""),
            "{err}"
        );
        let robot = format!("{MINIMAL}\n[manifold]\nepisodes = 3\n");
        assert_eq!(Scenario::parse(&robot).unwrap().manifold.episodes, 3);
    }

    #[test]
    fn gain_overrides_keep_the_phase_defaults_elsewhere() {
        let text = format!("{MINIMAL}\n[gains.insert]\nstiffness = [800, 800, 2000, 40, 40, 40]\n");
        let s = Scenario::parse(&text).unwrap();
        let c = s.trial_config(&s.cells()[0]);
        assert_eq!(c.insert_gains.stiffness[0], 800.0);
        assert_eq!(c.observe_gains, TrialConfig::default().observe_gains);
    }

    #[test]
    fn the_direct_baseline_takes_its_own_gains_and_insertion_over_the_scenarios() {
        let text = format!(
            "{MINIMAL}\n[insertion]\nseat_force_n = 4\nspeed_mm_per_s = 10\n\
             [direct.gains.insert]\nstiffness = [800, 800, 3000, 40, 40, 40]\n\
             [direct.insertion]\nseat_force_n = 25\n"
        );
        let s = Scenario::parse(&text).unwrap();
        let cells = s.cells();
        let manifold = s.trial_config(&cells[0]);
        let direct = s.trial_config(cells.last().unwrap());
        assert_eq!(direct.method, Method::Direct);
        let d = TrialConfig::default();
        assert_eq!(manifold.insert_gains, d.insert_gains);
        assert_eq!(manifold.insert_seat_force_n, 4.0);
        assert_eq!(direct.insert_gains.stiffness[2], 3000.0);
        assert_eq!(direct.insert_seat_force_n, 25.0);
        for c in [&manifold, &direct] {
            assert!((c.insert_speed_m_per_s - 0.01).abs() < 1e-12);
        }
        // Absent, the sections leave the fingerprint of older scenarios as it was.
        let plain = Scenario::parse(MINIMAL).unwrap();
        assert!(!plain.fingerprint().is_empty());
        let json = serde_json::to_string(&plain).unwrap();
        assert!(
            !json.contains("insertion") && !json.contains("direct\":"),
            "{json}"
        );
    }

    #[test]
    fn errors_name_the_line_or_the_field() {
        let e = Scenario::parse(&format!("{MINIMAL}\nbogus = 1\n")).unwrap_err();
        assert!(
            e.to_string().contains("line 9") && e.to_string().contains("bogus"),
            "{e}"
        );
        let e = Scenario::parse(&MINIMAL.replace("trials = 2", "trials = \"two\"")).unwrap_err();
        assert!(e.to_string().contains("line 3"), "{e}");
        let e = Scenario::parse(&MINIMAL.replace("[0.5]", "[-1]")).unwrap_err();
        assert!(e.to_string().contains("clearances_mm"), "{e}");
        let text =
            format!("{MINIMAL}\n[gains.insert]\nstiffness = [9000, 800, 2000, 40, 40, 40]\n");
        let e = Scenario::parse(&text).unwrap_err();
        assert!(e.to_string().contains("gains.insert"), "{e}");
        let e =
            Scenario::parse(&format!("{MINIMAL}\n[physics]\npgs_iterations = 0\n")).unwrap_err();
        assert!(e.to_string().contains("physics.pgs_iterations"), "{e}");
        let e = Scenario::parse(&format!("{MINIMAL}\n[physics]\nfriction = -1\n")).unwrap_err();
        assert!(e.to_string().contains("physics.friction"), "{e}");
        let e = Scenario::parse(&format!(
            "{MINIMAL}\n[direct.insertion]\nseat_force_n = 0\n"
        ))
        .unwrap_err();
        assert!(
            e.to_string().contains("direct.insertion.seat_force_n"),
            "{e}"
        );
        let e = Scenario::parse(&format!("{MINIMAL}\n[insertion]\nspeed_mm_per_s = 1e9\n"))
            .unwrap_err();
        assert!(e.to_string().contains("insertion.speed_mm_per_s"), "{e}");
    }

    /// Overrides merge into the file's tables key by key; a bad value is named by its field.
    #[test]
    fn overrides_merge_into_the_file_and_name_a_bad_field() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("s.toml");
        std::fs::write(
            &path,
            "name = \"s\"\ntrials = 2\ngeometries = [\"cross\"]\nclearances_mm = [0.5]\n\
             t_obs_s = [2.0]\nmethods = [\"manifold\"]\n[gains.insert]\n\
             damping_ratio = [0.5, 0.5, 0.5, 0.5, 0.5, 0.5]\n",
        )
        .unwrap();
        let s =
            Scenario::load_with(&path, "[gains.insert]\nstiffness = [1, 2, 3, 4, 5, 6]").unwrap();
        assert_eq!(
            s.gains.insert.stiffness,
            Some([1.0, 2.0, 3.0, 4.0, 5.0, 6.0])
        );
        assert_eq!(
            s.gains.insert.damping_ratio,
            Some([0.5; 6]),
            "the file's field kept"
        );
        assert_eq!(Scenario::load_with(&path, " ").unwrap().trials, 2);
        let e = Scenario::load_with(&path, "[gains.insert]\nstiffness = 3").unwrap_err();
        assert!(e.to_string().contains("[gains.insert] stiffness: "), "{e}");
        let e = Scenario::load_with(&path, "[gains").unwrap_err();
        assert!(e.to_string().contains("overrides: "), "{e}");
    }

    #[test]
    fn fingerprint_ignores_the_name_only() {
        let a = Scenario::parse(MINIMAL).unwrap();
        let b = Scenario::parse(&MINIMAL.replace("\"t\"", "\"u\"")).unwrap();
        let c = Scenario::parse(&MINIMAL.replace("trials = 2", "trials = 3")).unwrap();
        assert_eq!(a.fingerprint(), b.fingerprint());
        assert_ne!(a.fingerprint(), c.fingerprint());
    }

    const TWO_PAIRS: &str = r#"
name = "t"
trials = 2
geometries = ["cross", "gear"]
clearances_mm = [0.1, 0.5]
t_obs_s = [6.0]
methods = ["manifold"]

[physics]
friction = 0.2
"#;

    fn cell(geometry: &str, clearance_mm: f64) -> Condition {
        Condition {
            geometry: geometry.into(),
            clearance_mm,
            method: Method::Manifold,
            t_obs_s: 6.0,
        }
    }

    #[test]
    fn position_projection_is_off_unless_physics_turns_it_on() {
        let plain = Scenario::parse(TWO_PAIRS).unwrap();
        assert!(!plain.work_cell_params().physics.position_projection);
        let text = TWO_PAIRS.replace("[physics]\n", "[physics]\nposition_projection = true\n");
        let on = Scenario::parse(&text).unwrap();
        assert!(
            on.work_cell_params_for(&cell("gear", 0.1))
                .physics
                .position_projection
        );
    }

    #[test]
    fn arm_contacts_are_the_joint_space_solve_unless_physics_names_rapiers() {
        use crate::twin::physics::ArmContacts;
        let plain = Scenario::parse(TWO_PAIRS).unwrap();
        assert_eq!(
            plain.work_cell_params().physics.arm_contacts,
            ArmContacts::JointSpace
        );
        let text = TWO_PAIRS.replace("[physics]\n", "[physics]\narm_contacts = \"rapier\"\n");
        let on = Scenario::parse(&text).unwrap();
        let physics = on.work_cell_params_for(&cell("gear", 0.1)).physics;
        assert_eq!(physics.arm_contacts, ArmContacts::Rapier);
        let bad = TWO_PAIRS.replace("[physics]\n", "[physics]\narm_contacts = \"newton\"\n");
        let err = Scenario::parse(&bad).unwrap_err().to_string();
        assert!(
            err.contains("arm_contacts") || err.contains("joint_space"),
            "{err}"
        );
    }

    #[test]
    fn pair_physics_replaces_the_named_pairs_physics_only() {
        let text = format!(
            "{TWO_PAIRS}\n[[pair_physics]]\ngeometry = \"gear\"\nclearance_mm = 0.1\n\
             physics = {{ pgs_iterations = 8 }}\n"
        );
        let s = Scenario::parse(&text).unwrap();
        let gear = s.work_cell_params_for(&cell("gear", 0.1)).physics;
        assert_eq!((gear.pgs_iterations, gear.friction), (8, 0.2));
        for (g, c) in [("gear", 0.5), ("cross", 0.1), ("cross", 0.5)] {
            let other = s.work_cell_params_for(&cell(g, c)).physics;
            assert_eq!(other, s.work_cell_params().physics, "{g} {c}");
        }
        // Without a clearance it holds at every clearance of the geometry.
        let every = text.replace("clearance_mm = 0.1\n", "");
        let s = Scenario::parse(&every).unwrap();
        assert_eq!(
            s.work_cell_params_for(&cell("gear", 0.5))
                .physics
                .pgs_iterations,
            8
        );
        // A scenario without it keeps its fingerprint (campaigns resume across this change).
        let plain = Scenario::parse(TWO_PAIRS).unwrap();
        assert!(
            !serde_json::to_string(&plain)
                .unwrap()
                .contains("pair_physics")
        );
    }

    #[test]
    fn joint_friction_is_read_from_physics_and_left_out_of_the_fingerprint_when_absent() {
        let text = TWO_PAIRS.replace(
            "[physics]\n",
            "[physics]\njoint_friction = { coulomb_nm = [1, 1, 0.6, 0.6, 0.4, 0.2, 0.2], \
             stribeck_rad_per_s = 0.02 }\n",
        );
        let s = Scenario::parse(&text).unwrap();
        let f = s
            .work_cell_params_for(&cell("gear", 0.1))
            .physics
            .joint_friction;
        assert_eq!(f.coulomb_nm.as_deref().map(<[f64]>::len), Some(7));
        assert_eq!((f.static_nm, f.stribeck_rad_per_s), (None, Some(0.02)));
        let plain = Scenario::parse(TWO_PAIRS).unwrap();
        assert!(
            !serde_json::to_string(&plain)
                .unwrap()
                .contains("\"joint_friction\"")
        );
        let bad = TWO_PAIRS.replace(
            "[physics]\n",
            "[physics]\njoint_friction = { coulomb_nm = [100, 1, 1, 1, 1, 1, 1] }\n",
        );
        let e = Scenario::parse(&bad).unwrap_err().to_string();
        assert!(e.contains("joint_friction.coulomb_nm[0]"), "{e}");
    }

    #[test]
    fn cell_errors_name_the_field() {
        for (line, field) in [
            ("profile = \"nope\"", "unknown variant `nope`"),
            ("contact_friction = [0.9, 0.1]", "cell.contact_friction"),
            ("latency_s = 0.0015", "cell.latency_s"),
            ("encoder_offset_rad = 1", "cell.encoder_offset_rad"),
        ] {
            let e = Scenario::parse(&format!("{MINIMAL}\n[cell]\n{line}\n")).unwrap_err();
            assert!(e.to_string().contains(field), "{line}: {e}");
        }
        assert!(Scenario::parse(MINIMAL).unwrap().cell.profile == Profile::Real);
    }

    #[test]
    fn pair_physics_errors_name_the_entry_and_what_was_expected() {
        let entry = |g: &str, c: &str, p: &str| {
            format!("\n[[pair_physics]]\ngeometry = \"{g}\"\n{c}physics = {{ {p} }}\n")
        };
        let cases = [
            (
                entry("key", "", "pgs_iterations = 8"),
                "pair_physics[0]: geometry \"key\"",
            ),
            (
                entry("gear", "clearance_mm = 0.2\n", "pgs_iterations = 8"),
                "not a pair of this scenario",
            ),
            (
                entry("gear", "", "pgs_iterations = 0"),
                "pair_physics[0]: physics.pgs_iterations",
            ),
            (
                entry("gear", "", "friction = 0.1") + &entry("gear", "clearance_mm = 0.1\n", ""),
                "pair_physics[1]: geometry \"gear\" at clearance_mm = 0.1 is given physics twice",
            ),
            (entry("gear", "", "passes = 8"), "unknown field `passes`"),
        ];
        for (extra, want) in cases {
            let e = Scenario::parse(&format!("{TWO_PAIRS}{extra}")).unwrap_err();
            assert!(e.to_string().contains(want), "{want}: {e}");
        }
    }

    #[test]
    fn a_cell_file_is_read_into_the_scenario_which_then_holds_it() {
        let dir = tempfile::tempdir().unwrap();
        let cell = "# calibrated\n[cell]\ncontact_friction = [0.4, 0.6]\n";
        std::fs::write(dir.path().join("cell.toml"), cell).unwrap();
        let text = format!("{MINIMAL}cell_file = \"cell.toml\"\n");
        let s = Scenario::parse_in(&text, dir.path()).unwrap();
        assert_eq!(s.cell.contact_friction, [0.4, 0.6]);
        assert!(s.cell_file.is_none());
        let inline = Scenario::parse(&format!("{MINIMAL}[cell]\ncontact_friction = [0.4, 0.6]\n"));
        assert_eq!(s.fingerprint(), inline.unwrap().fingerprint());
        let both = format!("{text}[cell]\nprofile = \"real\"\n");
        let e = Scenario::parse_in(&both, dir.path())
            .unwrap_err()
            .to_string();
        assert!(e.contains("give one of them"), "{e}");
        std::fs::write(
            dir.path().join("cell.toml"),
            "[cell]\ncontact_friction = [0.4, 9]\n",
        )
        .unwrap();
        let e = Scenario::parse_in(&text, dir.path())
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("cell.toml") && e.contains("contact_friction"),
            "{e}"
        );
        let e = Scenario::parse_in(&text.replace("cell.toml", "none.toml"), dir.path());
        assert!(e.unwrap_err().to_string().contains("none.toml"));
    }
}
