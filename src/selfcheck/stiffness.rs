//! Robot diagnostics a robotics user expects before trusting the twin: the static stiffness the
//! arm really shows under its Cartesian impedance, measured in simulation by pushing the TCP.

use crate::error::{Error, Result};
use crate::twin::control::{ImpedanceGains, tcp_error};
use crate::twin::geometry::PartPair;
use crate::twin::robot::RobotModel;
use crate::twin::workcell::{WorkCell, WorkCellParams, nominal_hole_pose, tcp_in_hole};
use nalgebra::Vector6;
use rayon::prelude::*;
use serde::Serialize;

/// Axis names in the TCP frame.
pub const AXIS_NAMES: [&str; 6] = ["x", "y", "z", "rx", "ry", "rz"];

/// How hard and how long the stiffness test pushes.
#[derive(Clone, Copy, Debug)]
pub struct PushTest {
    /// Force on the translational axes, N.
    pub force_n: f64,
    /// Torque on the rotational axes, N m.
    pub torque_nm: f64,
    /// Time to settle before and after the push, s.
    pub settle_s: f64,
}

/// Pushes a diagnostic accepts: the TCP wrench bound of the controller's inputs.
pub const MAX_PUSH: (f64, f64) = crate::twin::control::MAX_TCP_WRENCH;

impl PushTest {
    /// Refuses pushes that are not positive or beyond [`MAX_PUSH`], naming the value.
    pub fn ensure_valid(&self) -> Result<()> {
        let (max_n, max_nm) = MAX_PUSH;
        if !(self.force_n > 0.0 && self.force_n <= max_n) {
            return Err(Error::Input(format!(
                "push force {} N: expected more than 0 and at most {max_n} N",
                self.force_n
            )));
        }
        if !(self.torque_nm > 0.0 && self.torque_nm <= max_nm) {
            return Err(Error::Input(format!(
                "push torque {} N m: expected more than 0 and at most {max_nm} N m",
                self.torque_nm
            )));
        }
        Ok(())
    }
}

impl Default for PushTest {
    fn default() -> Self {
        PushTest {
            force_n: 10.0,
            torque_nm: 1.0,
            settle_s: 1.5,
        }
    }
}

/// Commanded against measured static stiffness on one TCP axis.
#[derive(Clone, Debug, Serialize)]
pub struct AxisStiffness {
    pub axis: &'static str,
    /// N/m or N m/rad.
    pub commanded: f64,
    pub measured: f64,
    /// (measured - commanded) / commanded, percent.
    pub error_percent: f64,
    /// Push applied, N or N m.
    pub push: f64,
    /// Static deflection, m or rad.
    pub deflection: f64,
}

/// Pushes the TCP of an arm held under `gains` (peg in free air 0.1 m above the nominal hole) with
/// a known force or torque along each TCP axis in turn, waits for it to settle, and reports the
/// stiffness it shows. The six axes run in parallel (independent simulations).
pub fn measure_stiffness(
    pair: &PartPair,
    robot: &RobotModel,
    params: &WorkCellParams,
    gains: &ImpedanceGains,
    test: PushTest,
) -> Result<Vec<AxisStiffness>> {
    gains.ensure_valid()?;
    test.ensure_valid()?;
    let start = tcp_in_hole(&nominal_hole_pose(pair, params), -0.1);
    (0..6)
        .into_par_iter()
        .map(|axis| {
            let mut cell = WorkCell::new(pair, robot.clone(), params, None, &start, gains.clone(), 1)?;
            cell.run(test.settle_s);
            let before = cell.truth().tcp_pose();
            let magnitude = if axis < 3 {
                test.force_n
            } else {
                test.torque_nm
            };
            let mut w_tcp = Vector6::zeros();
            w_tcp[axis] = magnitude;
            let r = before.rotation;
            let f = r * w_tcp.fixed_rows::<3>(0).into_owned();
            let t = r * w_tcp.fixed_rows::<3>(3).into_owned();
            cell.set_disturbance(Some(Vector6::new(f.x, f.y, f.z, t.x, t.y, t.z)));
            cell.run(test.settle_s);
            if let Some(f) = cell.fault() {
                return Err(Error::Input(format!(
                    "a push of {magnitude} on the {} axis does not settle under these gains ({} at {:.3} s): use a smaller push or stiffer gains",
                    AXIS_NAMES[axis], f.reason, f.time_s
                )));
            }
            let deflection = tcp_error(&cell.truth().tcp_pose(), &before)[axis];
            let measured = magnitude / deflection;
            let commanded = gains.stiffness[axis];
            Ok(AxisStiffness {
                axis: AXIS_NAMES[axis],
                commanded,
                measured,
                error_percent: 100.0 * (measured - commanded) / commanded,
                push: magnitude,
                deflection,
            })
        })
        .collect()
}
