//! The Python binding of pegtwin: conversions between Python and the Rust library, nothing else.
//! Records cross as the same JSON the command line prints (`trial --json`), arrays as numpy
//! arrays; every error of the library is raised as `ValueError` with the message the command
//! line prints, a stopped campaign as `KeyboardInterrupt`. The GIL is released while the library
//! works. The Python-side API, its documentation and the Gymnasium environment are in
//! `python/pegtwin/`.

use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray1, PyArray2, PyReadonlyArray1, PyReadonlyArray2};
use pegtwin::campaign::replays::Replays;
use pegtwin::campaign::report;
use pegtwin::campaign::run::{self, CampaignOptions, CampaignProgress, RunOptions, Shard};
use pegtwin::campaign::scenario::Scenario;
use pegtwin::choice::Choice;
use pegtwin::error::Error;
use pegtwin::method::config::{Method, Start};
use pegtwin::method::env::{EnvConfig, PegEnv, Step, StepInfo};
use pegtwin::method::manifold::cache::{self, BuildProgress, Sampler};
use pegtwin::method::manifold::{Manifold, file};
use pegtwin::method::register::{RegistrationConfig, Solver, register as register_hole};
use pegtwin::method::request::TrialRequest;
use pegtwin::pose::Pose6;
use pegtwin::twin::assembly::PairSource;
use pegtwin::twin::real_cell::Profile;
use pyo3::exceptions::{PyKeyboardInterrupt, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::path::PathBuf;
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::time::Duration;

mod campaigns;

/// The library's error as Python's: `ValueError` with the command line's message.
fn py_err(e: Error) -> PyErr {
    match e {
        Error::Stopped(msg) => PyKeyboardInterrupt::new_err(msg),
        other => PyValueError::new_err(other.to_string()),
    }
}

/// The pair a Python call names: a built-in with its clearance, or an assembly file.
fn pair_source(
    geometry: Option<String>,
    clearance_mm: Option<f64>,
    assembly: Option<PathBuf>,
) -> PyResult<PairSource> {
    match (geometry, clearance_mm, assembly) {
        (Some(name), Some(clearance_mm), None) => Ok(PairSource::Builtin { name, clearance_mm }),
        (None, None, Some(path)) => Ok(PairSource::Assembly(path)),
        _ => Err(PyValueError::new_err(
            "give geometry and clearance_mm (a built-in), or assembly (an assembly file), not both",
        )),
    }
}

/// One trial (`pegtwin trial --json`): the record as JSON text. Values left out take the
/// command line's defaults.
#[pyfunction]
#[pyo3(signature = (geometry, clearance_mm, seed, method, start, t_obs_s=None, offset_mm=None, offset_deg=None, manifold=None, cache_dir=None, assembly=None, profile="real", sampler="robot"))]
#[allow(clippy::too_many_arguments)]
fn trial_json(
    py: Python<'_>,
    geometry: Option<String>,
    clearance_mm: Option<f64>,
    seed: u64,
    method: &str,
    start: &str,
    t_obs_s: Option<f64>,
    offset_mm: Option<f64>,
    offset_deg: Option<f64>,
    manifold: Option<PathBuf>,
    cache_dir: Option<PathBuf>,
    assembly: Option<PathBuf>,
    profile: &str,
    sampler: &str,
) -> PyResult<String> {
    let defaults = TrialRequest {
        pair: pair_source(geometry, clearance_mm, assembly)?,
        ..TrialRequest::new("cross", 0.5)
    };
    let request = TrialRequest {
        t_obs_s: t_obs_s.unwrap_or(defaults.t_obs_s),
        method: Method::by_name(method).map_err(py_err)?,
        start: Start::by_name(start).map_err(py_err)?,
        seed,
        offset_mm: offset_mm.unwrap_or(defaults.offset_mm),
        offset_deg: offset_deg.unwrap_or(defaults.offset_deg),
        manifold,
        sampler: Sampler::by_name(sampler).map_err(py_err)?,
        cache_dir,
        profile: Profile::by_name(profile).map_err(py_err)?,
        ..defaults
    };
    let result = py.detach(|| request.run(&())).map_err(py_err)?;
    Ok(serde_json::to_string_pretty(&result).expect("result serialises"))
}

/// A campaign's progress handed to a Python callable `(done, total)`, and Ctrl-C as a stop.
struct Progress {
    callback: Option<Py<PyAny>>,
    total: AtomicUsize,
    done: AtomicUsize,
    stop: AtomicBool,
    /// The first exception the callback raised (the campaign stops on it).
    raised: Mutex<Option<PyErr>>,
}

impl Progress {
    fn report(&self) {
        let Some(callback) = &self.callback else {
            return;
        };
        let (done, total) = (
            self.done.load(Ordering::SeqCst),
            self.total.load(Ordering::SeqCst),
        );
        Python::attach(|py| {
            if let Err(e) = callback.call1(py, (done, total)) {
                self.stop.store(true, Ordering::SeqCst);
                self.raised
                    .lock()
                    .expect("no panic holding it")
                    .get_or_insert(e);
            }
        });
    }
}

impl BuildProgress for Progress {}

impl CampaignProgress for Progress {
    fn trials_started(&self, total: usize, done: usize) {
        self.total.store(total, Ordering::SeqCst);
        self.done.store(done, Ordering::SeqCst);
        self.report();
    }

    fn trial_done(&self) {
        self.done.fetch_add(1, Ordering::SeqCst);
        self.report();
    }

    fn should_stop(&self) -> bool {
        self.stop.load(Ordering::SeqCst)
    }
}

/// Runs a campaign into `out` and writes its report (`pegtwin campaign`); returns `out`.
#[pyfunction]
#[pyo3(signature = (scenario, out, threads=None, shard=None, resume=false, cache_dir=None, replays="failures", progress=None))]
#[allow(clippy::too_many_arguments)]
fn campaign(
    py: Python<'_>,
    scenario: PathBuf,
    out: PathBuf,
    threads: Option<usize>,
    shard: Option<&str>,
    resume: bool,
    cache_dir: Option<PathBuf>,
    replays: &str,
    progress: Option<Py<PyAny>>,
) -> PyResult<String> {
    let replays = Replays::by_name(replays).map_err(py_err)?;
    let scenario = Scenario::load(&scenario).map_err(py_err)?;
    let shard = shard.map(Shard::parse).transpose().map_err(py_err)?;
    let pool = run::worker_pool(threads).map_err(py_err)?;
    let cache_dir = cache::folder(cache_dir.as_deref()).map_err(py_err)?;
    let progress = Progress {
        callback: progress,
        total: AtomicUsize::new(0),
        done: AtomicUsize::new(0),
        stop: AtomicBool::new(false),
        raised: Mutex::new(None),
    };
    let options = CampaignOptions {
        shard: shard.unwrap_or(Shard::WHOLE),
        resume,
        replays,
    };
    let run = RunOptions {
        cache_dir,
        progress: &progress,
    };
    let outcome = py.detach(|| {
        std::thread::scope(|scope| {
            let worker = scope.spawn(|| {
                let ran = pool.install(|| run::campaign(&scenario, &out, options, &run))?;
                report::write_campaign_report(&out, &scenario, &ran.trials, &run.cache_dir)
            });
            while !worker.is_finished() {
                std::thread::sleep(Duration::from_millis(50));
                if Python::attach(|py| py.check_signals()).is_err() {
                    progress.stop.store(true, Ordering::SeqCst);
                }
            }
            worker.join().expect("the campaign thread does not panic")
        })
    });
    if let Some(e) = progress.raised.lock().expect("no panic holding it").take() {
        return Err(e);
    }
    outcome.map_err(py_err)?;
    Ok(out.display().to_string())
}

/// A reference contact manifold (paper IV-B): contact poses `hole_T_peg` and their normals.
#[pyclass(module = "pegtwin._pegtwin", frozen)]
struct ManifoldFile {
    inner: Manifold,
}

#[pymethods]
impl ManifoldFile {
    /// Loads a manifold file (`pegtwin manifold build|import|synth` write them).
    #[staticmethod]
    fn load(py: Python<'_>, path: PathBuf) -> PyResult<Self> {
        let inner = py.detach(|| file::load(&path)).map_err(py_err)?;
        Ok(ManifoldFile { inner })
    }

    /// The contact poses, an (N, 6) array: x, y, z (m), roll, pitch, yaw (rad).
    #[getter]
    fn points<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        rows(py, self.inner.points.iter().map(|p| p.0))
    }

    /// The unit normals in the manifold's scaled 6-D metric, an (N, 6) array.
    #[getter]
    fn normals<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        rows(py, self.inner.normals.iter().copied())
    }

    /// Where the manifold came from (geometry, clearance, metric, ...) as JSON text.
    fn meta_json(&self) -> String {
        serde_json::to_string(&self.inner.meta).expect("metadata serialises")
    }

    fn __len__(&self) -> usize {
        self.inner.points.len()
    }
}

/// Rows of six as an (N, 6) array.
fn rows<'py>(py: Python<'py>, rows: impl Iterator<Item = [f64; 6]>) -> Bound<'py, PyArray2<f64>> {
    let flat: Vec<f64> = rows.flatten().collect();
    let n = flat.len() / 6;
    Array2::from_shape_vec((n, 6), flat)
        .expect("rows of six")
        .into_pyarray(py)
}

/// Algorithm 1 with restarts (`pegtwin register`): the registration as JSON text.
#[pyfunction]
#[pyo3(signature = (manifold, observations, init, solver=None, iterations=None, restarts=None, seed=None, normal_k=None))]
#[allow(clippy::too_many_arguments)]
fn register_json(
    py: Python<'_>,
    manifold: &ManifoldFile,
    observations: PyReadonlyArray2<'_, f64>,
    init: PyReadonlyArray1<'_, f64>,
    solver: Option<&str>,
    iterations: Option<usize>,
    restarts: Option<usize>,
    seed: Option<u64>,
    normal_k: Option<usize>,
) -> PyResult<String> {
    let obs = observations.as_array();
    if obs.ncols() != 6 {
        return Err(PyValueError::new_err(format!(
            "observations of shape ({}, {}): expected (N, 6) rows of x, y, z (m), roll, pitch, yaw (rad)",
            obs.nrows(),
            obs.ncols()
        )));
    }
    let init = init.as_array();
    if init.len() != 6 {
        return Err(PyValueError::new_err(format!(
            "init of length {}: expected 6 values x, y, z (m), roll, pitch, yaw (rad)",
            init.len()
        )));
    }
    let observations: Vec<Pose6> = obs
        .rows()
        .into_iter()
        .map(|r| Pose6(std::array::from_fn(|i| r[i])))
        .collect();
    let init = Pose6(std::array::from_fn(|i| init[i]));
    let defaults = RegistrationConfig::default();
    let solver = solver
        .map_or(Ok(defaults.solver), Solver::by_name)
        .map_err(py_err)?;
    let config = RegistrationConfig {
        solver,
        iterations: iterations.unwrap_or(defaults.iterations),
        restarts: restarts.unwrap_or(defaults.restarts),
        seed: seed.unwrap_or(defaults.seed),
        normal_k: normal_k.unwrap_or(defaults.normal_k),
        ..defaults
    };
    let reg = py
        .detach(|| register_hole(&manifold.inner, &observations, &init, &config))
        .map_err(py_err)?;
    Ok(serde_json::to_string(&reg).expect("registration serialises"))
}

/// The cell as a step-by-step environment (`pegtwin::method::env`).
#[pyclass(module = "pegtwin._pegtwin")]
struct Env {
    inner: PegEnv,
}

#[pymethods]
impl Env {
    #[new]
    #[pyo3(signature = (geometry, clearance_mm, start="partial", control_hz=None, episode_s=None, offset_mm=None, offset_deg=None, max_step_mm=None, max_step_deg=None, variable_stiffness=false, assembly=None, profile="real"))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        geometry: Option<String>,
        clearance_mm: Option<f64>,
        start: &str,
        control_hz: Option<f64>,
        episode_s: Option<f64>,
        offset_mm: Option<f64>,
        offset_deg: Option<f64>,
        max_step_mm: Option<f64>,
        max_step_deg: Option<f64>,
        variable_stiffness: bool,
        assembly: Option<PathBuf>,
        profile: &str,
    ) -> PyResult<Self> {
        let profile = Profile::by_name(profile).map_err(py_err)?;
        let pair = pair_source(geometry, clearance_mm, assembly)?;
        let d = EnvConfig::default();
        let m = offset_mm.map_or(d.offset_range[0], |v| v * 1e-3);
        let a = offset_deg.map_or(d.offset_range[3], f64::to_radians);
        let config = EnvConfig {
            control_hz: control_hz.unwrap_or(d.control_hz),
            episode_s: episode_s.unwrap_or(d.episode_s),
            start: Start::by_name(start).map_err(py_err)?,
            offset_range: [m, m, m, a, a, a],
            max_step_m: max_step_mm.map_or(d.max_step_m, |v| v * 1e-3),
            max_step_rad: max_step_deg.map_or(d.max_step_rad, f64::to_radians),
            variable_stiffness,
            ..d
        };
        let request = TrialRequest {
            pair,
            ..TrialRequest::new("cross", 0.5)
        };
        let inner = py
            .detach(|| {
                let (pair, _) = request.check()?;
                let spec = request.pair.robot()?;
                let (robot, _) = spec.load()?;
                let mut params =
                    pegtwin::twin::workcell::WorkCellParams::default().placed_for(&spec);
                params.cell.profile = profile;
                PegEnv::new(pair, robot, params, config)
            })
            .map_err(py_err)?;
        Ok(Env { inner })
    }

    /// Length of an action (6, or 8 with variable stiffness).
    #[getter]
    fn action_len(&self) -> usize {
        self.inner.config().action_len()
    }

    /// Rate of `step` calls, Hz.
    #[getter]
    fn control_hz(&self) -> f64 {
        self.inner.config().control_hz
    }

    /// Simulated time after which an episode is truncated, s.
    #[getter]
    fn episode_s(&self) -> f64 {
        self.inner.config().episode_s
    }

    /// Starts an episode from trial `seed`'s set-up: `(observation, info)`.
    fn reset<'py>(
        &mut self,
        py: Python<'py>,
        seed: u64,
    ) -> PyResult<(Bound<'py, PyArray1<f64>>, Bound<'py, PyDict>)> {
        let (obs, info) = py.detach(|| self.inner.reset(seed)).map_err(py_err)?;
        Ok((obs.to_vec().into_pyarray(py), info_dict(py, &info)?))
    }

    /// One control period: `(observation, reward, terminated, truncated, info)`.
    #[allow(clippy::type_complexity)]
    fn step<'py>(
        &mut self,
        py: Python<'py>,
        action: PyReadonlyArray1<'_, f64>,
    ) -> PyResult<(
        Bound<'py, PyArray1<f64>>,
        f64,
        bool,
        bool,
        Bound<'py, PyDict>,
    )> {
        let action = action.as_array().to_vec();
        let Step {
            observation,
            reward,
            terminated,
            truncated,
            info,
        } = py.detach(|| self.inner.step(&action)).map_err(py_err)?;
        let obs = observation.to_vec().into_pyarray(py);
        Ok((obs, reward, terminated, truncated, info_dict(py, &info)?))
    }
}

/// A step's info as a dict (SI units, as the library's).
fn info_dict<'py>(py: Python<'py>, info: &StepInfo) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("time_s", info.time_s)?;
    d.set_item("depth_m", info.depth_m)?;
    d.set_item("true_wrench", info.true_wrench.to_vec())?;
    d.set_item("penetration_m", info.penetration_m)?;
    d.set_item("contact", info.contact)?;
    d.set_item("success", info.success)?;
    d.set_item("hole_offset", info.hole_offset.0.to_vec())?;
    match &info.sim_fault {
        Some(f) => d.set_item("sim_fault", f.reason.clone())?,
        None => d.set_item("sim_fault", py.None())?,
    }
    Ok(d)
}

#[pymodule]
fn _pegtwin(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(trial_json, m)?)?;
    m.add_function(wrap_pyfunction!(campaign, m)?)?;
    m.add_function(wrap_pyfunction!(register_json, m)?)?;
    m.add_function(wrap_pyfunction!(campaigns::merge, m)?)?;
    m.add_function(wrap_pyfunction!(campaigns::check_json, m)?)?;
    m.add_function(wrap_pyfunction!(campaigns::rerun_json, m)?)?;
    m.add_function(wrap_pyfunction!(campaigns::tune_json, m)?)?;
    m.add_function(wrap_pyfunction!(campaigns::evaluate_json, m)?)?;
    m.add_class::<ManifoldFile>()?;
    m.add_class::<Env>()?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
