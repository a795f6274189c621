//! The command line's spelling of the library's choices (clap value enums), so that the library
//! itself does not depend on clap.

use clap::ValueEnum;
use pegtwin::campaign::replays::Replays;
use pegtwin::campaign::tune::TuneTarget;
use pegtwin::method::config::{Method, Start};
use pegtwin::method::register::Solver;
use pegtwin::twin::geometry::mesh::MeshUnits;

/// How the trial inserts.
#[derive(Clone, Copy, ValueEnum)]
pub enum MethodArg {
    /// Estimate the hole pose from the contact manifold, then insert along the estimate.
    Manifold,
    /// The paper's baseline: observe, then insert along the peg's z with no estimate.
    Direct,
}

impl From<MethodArg> for Method {
    fn from(m: MethodArg) -> Self {
        match m {
            MethodArg::Manifold => Method::Manifold,
            MethodArg::Direct => Method::Direct,
        }
    }
}

/// What `tune` searches.
#[derive(Clone, Copy, ValueEnum)]
pub enum TuneTargetChoice {
    /// The observation and insertion gains of every method.
    Gains,
    /// The direct baseline's insertion: stiffness, damping and seat force (the paper tuned it).
    Direct,
}

impl From<TuneTargetChoice> for TuneTarget {
    fn from(t: TuneTargetChoice) -> Self {
        match t {
            TuneTargetChoice::Gains => TuneTarget::Gains,
            TuneTargetChoice::Direct => TuneTarget::Direct,
        }
    }
}

/// How a trial starts.
#[derive(Clone, Copy, ValueEnum)]
pub enum StartArg {
    /// Partially inserted in the true hole (the paper's set-up).
    Partial,
    /// Above the nominal hole: approach, then a spiral search until the peg drops in.
    Above,
}

impl From<StartArg> for Start {
    fn from(s: StartArg) -> Self {
        match s {
            StartArg::Partial => Start::Partial,
            StartArg::Above => Start::Above,
        }
    }
}

/// Which update rule each registration iteration uses.
#[derive(Clone, Copy, ValueEnum)]
pub enum SolverArg {
    /// Algorithm 1's update: SE(3) mean of the symmetric point-to-plane misalignments.
    Paper,
    /// Gauss-Newton on the same residuals with a Huber loss.
    LeastSquares,
}

impl From<SolverArg> for Solver {
    fn from(s: SolverArg) -> Self {
        match s {
            SolverArg::Paper => Solver::Paper,
            SolverArg::LeastSquares => Solver::LeastSquares,
        }
    }
}

/// Length unit of a mesh file.
#[derive(Clone, Copy, ValueEnum)]
pub enum UnitsArg {
    Mm,
    M,
}

impl From<UnitsArg> for MeshUnits {
    fn from(u: UnitsArg) -> Self {
        match u {
            UnitsArg::Mm => MeshUnits::Mm,
            UnitsArg::M => MeshUnits::M,
        }
    }
}

/// Which trials of a campaign get a 3-D replay.
#[derive(Clone, Copy, ValueEnum)]
pub enum ReplaysArg {
    /// Every failed or faulted trial among the first 50 of each cell, and the first two trials of
    /// every cell.
    Failures,
    /// Every trial.
    All,
    /// None.
    None,
}

impl From<ReplaysArg> for Replays {
    fn from(r: ReplaysArg) -> Self {
        match r {
            ReplaysArg::Failures => Replays::Failures,
            ReplaysArg::All => Replays::All,
            ReplaysArg::None => Replays::None,
        }
    }
}
