//! An assembly file's `[robot]` section: the robot that holds the peg.
//!
//! ```toml
//! [robot]                      # optional: the built-in iiwa 14 when absent
//! urdf = "robots/my_arm.urdf"  # or: builtin = "iiwa14" | "iiwa7" | "ur5e"
//! package_paths = ["robots/"]  # where package:// meshes resolve (URDF only)
//! flange_link = "tool0"        # the link whose frame is the flange (default: the chain's tip)
//! tool_xyz_mm = [0, 0, 0]      # where the peg's top face sits on the flange link
//! tool_rpy_deg = [0, 0, 0]
//! start_q_deg = [0, -90, 90, -90, -90, 0]  # optional: near the start pose (an IK seed)
//! hole_xy_mm = [400, 0]        # optional: where the hole stands in the base frame (550, 0)
//! ```
//!
//! The robot is loaded and asked to reach the cell's start pose when the assembly loads, so a
//! non-serial URDF or a hole out of reach fails there, naming the file and the field.

use crate::error::{Error, Result};
use crate::twin::geometry::PartPair;
use crate::twin::robot::Iso;
use crate::twin::robot::spec::{RobotSource, RobotSpec};
use crate::twin::robot::urdf;
use crate::twin::workcell::{WorkCellParams, nominal_hole_pose, tcp_in_hole, with_peg};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// `[robot]` as written.
#[derive(Debug, Default, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RobotEntry {
    builtin: Option<String>,
    urdf: Option<PathBuf>,
    #[serde(default)]
    package_paths: Vec<PathBuf>,
    flange_link: Option<String>,
    #[serde(default)]
    tool_xyz_mm: [f64; 3],
    #[serde(default)]
    tool_rpy_deg: [f64; 3],
    start_q_deg: Option<Vec<f64>>,
    /// Where the hole's fixture stands in the robot's base frame, x and y, mm.
    hole_xy_mm: Option<[f64; 2]>,
}

/// The largest tool offset accepted, mm.
const MAX_TOOL_OFFSET_MM: f64 = 1000.0;
/// The farthest a hole may stand from the robot's base, per axis, mm.
const MAX_HOLE_XY_MM: f64 = 3000.0;
/// How far above the mouth the reach check puts the peg's tip, m (the trials' highest start).
const REACH_CHECK_HEIGHT_M: f64 = 0.02;

/// The robot of an assembly file at `file` (paths relative to `dir`): the built-in iiwa 14 when
/// the file has no `[robot]`.
pub(super) fn spec(entry: Option<&RobotEntry>, dir: &Path, file: &Path) -> Result<RobotSpec> {
    let Some(e) = entry else {
        return Ok(RobotSpec::default());
    };
    let bad = |msg: String| Error::file(file, msg);
    let source = match (&e.builtin, &e.urdf) {
        (Some(name), None) => {
            urdf::builtin_text(name).map_err(|e| bad(format!("[robot] builtin: {e}")))?;
            if !e.package_paths.is_empty() {
                return Err(bad(
                    "[robot] package_paths: only with urdf = \"FILE\"".into()
                ));
            }
            RobotSource::Builtin(name.clone())
        }
        (None, Some(urdf)) => RobotSource::Urdf {
            path: dir.join(urdf),
            package_paths: e.package_paths.iter().map(|p| dir.join(p)).collect(),
        },
        _ => {
            return Err(bad(
                "[robot]: give one of urdf = \"FILE\" or builtin = \"iiwa14\" | \"iiwa7\" | \"ur5e\""
                    .into(),
            ));
        }
    };
    for (field, v, max) in [
        ("tool_xyz_mm", &e.tool_xyz_mm[..], MAX_TOOL_OFFSET_MM),
        ("tool_rpy_deg", &e.tool_rpy_deg[..], 360.0),
        (
            "hole_xy_mm",
            e.hole_xy_mm.as_ref().map_or(&[][..], |v| &v[..]),
            MAX_HOLE_XY_MM,
        ),
    ] {
        if !v.iter().all(|x| x.abs() <= max) {
            return Err(bad(format!(
                "[robot] {field} = {v:?}: expected values within +-{max}"
            )));
        }
    }
    let start_q_rad = match &e.start_q_deg {
        Some(q) if !q.iter().all(|v| v.abs() <= 720.0) => {
            return Err(bad(format!(
                "[robot] start_q_deg = {q:?}: expected joint angles in degrees within +-720"
            )));
        }
        q => q
            .as_ref()
            .map(|q| q.iter().map(|v| v.to_radians()).collect()),
    };
    Ok(RobotSpec {
        source,
        flange_link: e.flange_link.clone(),
        tool_offset: Iso::identity(),
        start_q_rad,
        hole_xy_m: e.hole_xy_mm.map(|v| v.map(|x| x * 1e-3)),
    }
    .with_tool_mm_deg(e.tool_xyz_mm, e.tool_rpy_deg))
}

/// What `assembly check` reports of the robot.
#[derive(Clone, Debug, Serialize)]
pub struct RobotReport {
    /// A built-in's name or the URDF's path.
    pub source: String,
    pub joints: usize,
    /// The flange link.
    pub flange: String,
    /// The joint configuration with the peg's tip 20 mm over the nominal hole, deg.
    pub start_q_deg: Vec<f64>,
}

/// The robot as loaded and checked.
pub(super) struct RobotCheck {
    pub report: RobotReport,
    pub warnings: Vec<String>,
    /// The robot's content key (`None`: the default iiwa 14).
    pub key: Option<String>,
}

/// Loads the robot and checks that it reaches the cell's start pose over the nominal hole with
/// the peg of `pair` (the default cell).
pub(super) fn check_reach(spec: &RobotSpec, pair: &PartPair, file: &Path) -> Result<RobotCheck> {
    let in_file = |e: Error| match e {
        Error::Input(msg) => Error::file(file, format!("[robot]: {msg}")),
        other => other,
    };
    let (model, warnings) = spec.load().map_err(in_file)?;
    let params = WorkCellParams::default().placed_for(spec);
    let model = with_peg(model, pair, &params).map_err(in_file)?;
    let start = tcp_in_hole(&nominal_hole_pose(pair, &params), -REACH_CHECK_HEIGHT_M);
    let q = model.start_configuration(&start).map_err(in_file)?;
    Ok(RobotCheck {
        report: RobotReport {
            source: spec.label(),
            joints: model.dof(),
            flange: model.flange_name.clone(),
            start_q_deg: q.iter().map(|v| v.to_degrees()).collect(),
        },
        warnings,
        key: model.content_key,
    })
}
