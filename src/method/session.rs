//! The method's handle on the cell: the real robot's ports and nothing else. A session commands
//! impedance targets and gains, reads [`Measurements`] (encoder pose, estimated wrench, contact
//! flag), and steps the physics, stopping at the first physics fault and keeping it. After every
//! step it hands the cell to an optional [`Recorder`] (the `--trace` time series, the checks of
//! `validate --arm`): the one place where the truth is read, for the user, never for the method.
//!
//! Every stage of the method (search, observe, insert, and the manifold sampler) drives a
//! `Session`; none of them can reach the cell's ground truth, which is the point.

use crate::error::Result;
use crate::pose::{Iso, Pose6};
use crate::twin::control::ImpedanceGains;
use crate::twin::workcell::{Measurements, SimFault, WorkCell};
use serde::Serialize;

/// The phases of a trial (and the manifold sampler's), as the trace names them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Phase {
    Sample,
    Search,
    Observe,
    Retract,
    Align,
    Insert,
}

impl Phase {
    /// The name in traces.
    pub fn name(self) -> &'static str {
        match self {
            Phase::Sample => "sample",
            Phase::Search => "search",
            Phase::Observe => "observe",
            Phase::Retract => "retract",
            Phase::Align => "align",
            Phase::Insert => "insert",
        }
    }
}

/// One sample of the time series (`--trace`).
#[derive(Clone, Debug, Serialize)]
pub struct TraceRow {
    pub time_s: f64,
    pub phase: &'static str,
    /// Measured TCP pose, base frame, m and rad.
    pub tcp: [f64; 6],
    pub est_wrench: [f64; 6],
    pub true_wrench: [f64; 6],
    pub contact: bool,
}

/// The trace as CSV (m, rad, N, N m; base frame), header first.
pub fn trace_csv(rows: &[TraceRow]) -> Vec<u8> {
    let mut w = csv::Writer::from_writer(Vec::new());
    let mut header = vec!["time_s".to_string(), "phase".into()];
    header.extend(["x", "y", "z", "roll", "pitch", "yaw"].map(String::from));
    for prefix in ["est", "true"] {
        header.extend(["fx", "fy", "fz", "tx", "ty", "tz"].map(|c| format!("{prefix}_{c}")));
    }
    header.push("contact".into());
    w.write_record(&header).expect("in-memory CSV");
    for r in rows {
        let mut rec = vec![format!("{:.3}", r.time_s), r.phase.to_string()];
        rec.extend(
            r.tcp
                .iter()
                .chain(&r.est_wrench)
                .chain(&r.true_wrench)
                .map(|v| format!("{v:e}")),
        );
        rec.push(u8::from(r.contact).to_string());
        w.write_record(&rec).expect("in-memory CSV");
    }
    w.into_inner().expect("in-memory CSV")
}

/// What looks at the cell after every step of a session: it may read the truth, and it cannot
/// command anything.
pub trait Recorder {
    fn record(&mut self, cell: &WorkCell, phase: Phase);

    /// The registration's input and output (IV-D), for a recorder that draws them: the contact
    /// poses used (`base_T_tcp`), the hole frame believed before registering, and the estimated
    /// one (none for the direct baseline or a registration that did not run).
    fn registration(
        &mut self,
        _observations: &[Pose6],
        _believed: &Iso,
        _estimate: Option<&Pose6>,
    ) {
    }
}

/// Two recorders fed together (a `--trace` and a `--replay` of the same trial).
impl<A: Recorder, B: Recorder> Recorder for (A, B) {
    fn record(&mut self, cell: &WorkCell, phase: Phase) {
        self.0.record(cell, phase);
        self.1.record(cell, phase);
    }

    fn registration(&mut self, observations: &[Pose6], believed: &Iso, estimate: Option<&Pose6>) {
        self.0.registration(observations, believed, estimate);
        self.1.registration(observations, believed, estimate);
    }
}

/// The `--trace` time series: one row per step.
impl Recorder for Vec<TraceRow> {
    fn record(&mut self, cell: &WorkCell, phase: Phase) {
        let m = cell.measurements();
        self.push(TraceRow {
            time_s: m.time_s,
            phase: phase.name(),
            tcp: Pose6::from_iso(&m.tcp).0,
            est_wrench: m.wrench.into(),
            true_wrench: cell.truth().contact_wrench().into(),
            contact: m.contact,
        });
    }
}

/// The method's stepping of a cell: faults stop it, the recorder sees each step.
pub struct Session<'a> {
    cell: &'a mut WorkCell,
    recorder: Option<&'a mut dyn Recorder>,
    fault: Option<SimFault>,
    phase: Phase,
}

impl<'a> Session<'a> {
    pub fn new(
        cell: &'a mut WorkCell,
        recorder: Option<&'a mut dyn Recorder>,
        phase: Phase,
    ) -> Self {
        Session::resume(cell, recorder, None, phase)
    }

    /// A session that goes on from where an earlier one over the same cell stopped: its fault
    /// (if the physics faulted) and its phase.
    pub fn resume(
        cell: &'a mut WorkCell,
        recorder: Option<&'a mut dyn Recorder>,
        fault: Option<SimFault>,
        phase: Phase,
    ) -> Self {
        Session {
            cell,
            recorder,
            fault,
            phase,
        }
    }

    /// The phase the following steps belong to.
    pub fn set_phase(&mut self, phase: Phase) {
        self.phase = phase;
    }

    /// The physics fault that stopped the session, if one did.
    pub fn fault(&self) -> Option<&SimFault> {
        self.fault.as_ref()
    }

    /// Physics step, s.
    pub fn dt_s(&self) -> f64 {
        self.cell.dt_s()
    }

    /// Simulated time, s.
    pub fn time_s(&self) -> f64 {
        self.cell.time_s()
    }

    /// What the robot reports now.
    pub fn measurements(&self) -> Measurements {
        self.cell.measurements()
    }

    /// Commands the impedance target `base_T_tcp`.
    pub fn command_pose(&mut self, target: Iso) {
        self.cell.command_pose(target);
    }

    /// New impedance gains, keeping the current target (Sunrise mode switch).
    pub fn switch_gains(&mut self, gains: ImpedanceGains) -> Result<()> {
        self.cell.switch_gains(gains)
    }

    /// One physics step; false once the physics has faulted.
    pub fn step(&mut self) -> bool {
        if self.fault.is_some() {
            return false;
        }
        self.cell.step();
        if let Some(f) = self.cell.fault() {
            self.fault = Some(f);
            return false;
        }
        if let Some(recorder) = self.recorder.as_deref_mut() {
            recorder.record(self.cell, self.phase);
        }
        true
    }

    /// Hands the registration's input and output to the recorder (see [`Recorder::registration`]).
    pub fn record_registration(
        &mut self,
        observations: &[Pose6],
        believed: &Iso,
        estimate: Option<&Pose6>,
    ) {
        if let Some(recorder) = self.recorder.as_deref_mut() {
            recorder.registration(observations, believed, estimate);
        }
    }

    /// Moves the target from `from` to `to` (linear in position, slerp in rotation) over `seconds`.
    pub fn move_linear(&mut self, from: &Iso, to: &Iso, seconds: f64) {
        let steps = (seconds / self.dt_s()).round().max(1.0) as usize;
        for k in 1..=steps {
            let s = k as f64 / steps as f64;
            self.command_pose(from.lerp_slerp(to, s));
            if !self.step() {
                return;
            }
        }
    }

    /// Holds the target at `at` for `seconds`.
    pub fn hold(&mut self, at: &Iso, seconds: f64) {
        self.move_linear(at, at, seconds);
    }
}
