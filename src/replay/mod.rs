//! See what happened: a trial recorded and played back in 3-D, in one self-contained HTML page
//! (`pegtwin trial --replay`, and the failed trials of a campaign, `campaign --replays`).
//!
//! A [`Replay`] is a [`Recorder`]: it looks at the cell while the trial runs, as `--trace` does,
//! and keeps a frame every [`FRAME_DT_S`] — the true pose of every link and of the peg, the
//! estimated and the true contact wrench, the phase — and the registration's input and output
//! (paper IV-D). [`Replay::write_html`] puts them, with the meshes of the arm, the peg and the
//! hole ([`scene`]), into the viewer's page (`viewer/` at the top of the repository, embedded
//! in the binary; [`page`]). Recording reads the cell and commands nothing: a trial with a
//! replay gives the same result as one without.

pub mod page;
pub mod registration;
pub mod scene;

use crate::error::Result;
use crate::method::manifold::Manifold;
use crate::method::session::{Phase, Recorder};
use crate::method::trial::TrialResult;
use crate::pose::{Iso, Pose6};
use crate::twin::geometry::PartPair;
use crate::twin::robot::RobotModel;
use crate::twin::workcell::WorkCell;
use std::path::Path;

/// Time between recorded frames, s (50 Hz: a 20 s trial is 1 000 frames, about 0.4 MB).
pub const FRAME_DT_S: f64 = 0.02;

/// The phases in the order a replay numbers them.
pub const PHASES: [Phase; 6] = [
    Phase::Sample,
    Phase::Search,
    Phase::Observe,
    Phase::Retract,
    Phase::Align,
    Phase::Insert,
];

/// One recorded instant (base frame, m, rad, N, N m).
#[derive(Clone, Debug)]
pub struct Frame {
    pub time_s: f64,
    pub phase: Phase,
    /// `base_T_link` of the base link and of each moving link.
    pub links: Vec<Iso>,
    /// `base_T_tcp`, the true pose of the peg (its frame is the TCP's).
    pub peg: Iso,
    /// The wrench the robot estimates from its joint torques, at the TCP.
    pub est_wrench: [f64; 6],
    /// The wrench the physics applies to the peg, at the TCP.
    pub true_wrench: [f64; 6],
    /// The estimator's contact flag.
    pub contact: bool,
}

/// The registration as the trial ran it (paper IV-D).
#[derive(Clone, Debug)]
pub struct RegistrationRecord {
    /// The contact poses registered, `base_T_tcp`.
    pub observations: Vec<Pose6>,
    /// The hole frame believed before registering, `base_T_hole`.
    pub believed: Iso,
    /// The estimate, `base_T_hole` (none for the direct baseline).
    pub estimate: Option<Iso>,
}

/// A trial being recorded for replay.
#[derive(Clone)]
pub struct Replay {
    scene: scene::Scene,
    frames: Vec<Frame>,
    next_frame_s: f64,
    true_hole: Option<Iso>,
    registration: Option<RegistrationRecord>,
}

impl Replay {
    /// An empty recording of a trial of `pair` on `robot`.
    pub fn new(pair: &PartPair, robot: &RobotModel) -> Self {
        Replay {
            scene: scene::Scene::new(pair, robot),
            frames: Vec::new(),
            next_frame_s: 0.0,
            true_hole: None,
            registration: None,
        }
    }

    /// Writes the replay of the trial that gave `result` to `path` (one HTML file); `manifold`,
    /// the reference manifold it registered against, adds the registration panel.
    pub fn write_html(
        &self,
        path: &Path,
        result: &TrialResult,
        manifold: Option<&Manifold>,
    ) -> Result<()> {
        let panel = match (&self.registration, manifold) {
            (Some(reg), Some(m)) => Some(registration::png(m, reg)?),
            _ => None,
        };
        let html = page::html(self, result, panel.as_deref());
        crate::files::write_atomically(path, html.as_bytes())
    }
}

impl Recorder for Replay {
    fn record(&mut self, cell: &WorkCell, phase: Phase) {
        let time_s = cell.time_s();
        if time_s + 1e-9 < self.next_frame_s {
            return;
        }
        self.next_frame_s = time_s + FRAME_DT_S;
        let truth = cell.truth();
        if self.true_hole.is_none() {
            self.true_hole = truth.base_t_hole();
        }
        self.frames.push(Frame {
            time_s,
            phase,
            links: truth.link_poses(),
            peg: truth.tcp_pose(),
            est_wrench: cell.measurements().wrench.into(),
            true_wrench: truth.contact_wrench().into(),
            contact: cell.measurements().contact,
        });
    }

    fn registration(&mut self, observations: &[Pose6], believed: &Iso, estimate: Option<&Pose6>) {
        self.registration = Some(RegistrationRecord {
            observations: observations.to_vec(),
            believed: *believed,
            estimate: estimate.map(Pose6::to_iso),
        });
    }
}
