//! The real cell: what a real iiwa cell has that an ideal twin lacks (issue 45;
//! docs/sources.md, section 6), as one switch. `profile = "ideal"` turns every imperfection off:
//! frictionless joints (the robot file's `<dynamics friction>` is ignored), one contact friction
//! coefficient, an exact wrench estimate but for its noise, exact load data and no latency.
//! `profile = "real"` draws, for each cell, the imperfections whose values are uncertain from
//! uniform ranges ([`RealCell`]): the joints' friction, the peg-hole friction, the wrench
//! estimate's bias and gain, and the error of the peg mass the controller believes; the control
//! latency is fixed.
//!
//! A cell draws from its own seed ([`RealCell::draw`]): every trial from its trial seed, every
//! sampling episode of a reference manifold from its episode seed, so a trial's draw is fixed by
//! its seed alone, is recorded in its record ([`CellDraw`]) and comes back with `rerun`.
//!
//! A built-in pair is printed once ([`RealCell::print`]): its walls' deviation and its edges are
//! drawn from the scenario's seed (a lone trial's: its own) and the pair's name and clearance, so
//! its reference manifold and every trial of it meet the same print (paper IV-B).

use crate::choice::{Choice, Named};
use crate::error::{Error, Result};
use crate::twin::geometry::{self, Builtin, MIN_CHAMFER_M, PartPair, Print};
use crate::twin::sensing::MAX_ENCODER_OFFSET_RAD;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

/// Which cell the twin simulates.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Profile {
    /// Every imperfection off: the twin the physics self-checks run.
    Ideal,
    /// The imperfections of a real cell, drawn per trial within their ranges.
    Real,
}

impl Choice for Profile {
    const WHAT: &'static str = "profile";
    const NAMED: &'static [Named<Self>] = &[
        Named {
            name: "ideal",
            value: Profile::Ideal,
            help: "every imperfection off: frictionless joints, exact load data, no latency",
        },
        Named {
            name: "real",
            value: Profile::Real,
            help: "a real cell's imperfections, drawn per trial within their ranges ([cell])",
        },
    ];
}

/// A uniform range, low and high (equal: a fixed value).
pub type Range = [f64; 2];

/// The `[cell]` section of a scenario: the profile and, for the real one, the range each
/// uncertain value is drawn from. Fields not given keep their defaults (docs/sources.md, 6).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RealCell {
    pub profile: Profile,
    /// Scale of every joint's friction: the robot file's `<dynamics friction>`, or
    /// `[physics] joint_friction` when the scenario gives it.
    pub joint_friction_scale: Range,
    /// Kinetic friction coefficient between peg and hole.
    pub contact_friction: Range,
    /// The static coefficient over the kinetic one (at least 1).
    pub static_over_kinetic: Range,
    /// Half-range of the wrench estimate's bias on each axis: force (N) and torque (N m).
    pub wrench_bias: [f64; 2],
    /// Gain of the wrench estimate.
    pub wrench_gain: Range,
    /// Relative error of the peg mass the controller and the estimator use (the load data).
    pub payload_error: Range,
    /// Time from a control cycle's measurements to its torques at the drives, s (a whole number
    /// of control periods).
    pub latency_s: f64,
    /// Half-range of each joint encoder's constant offset, rad: the kinematic calibration error
    /// the controller and every recorded pose carry. 0 by default: its scale is what `calibrate`
    /// fits to the paper's x, y error (docs/sources.md, 6.6).
    pub encoder_offset_rad: f64,
    /// How far a printed wall stands off its CAD, m per side: the peg's walls out (outsides print
    /// large) and the hole's in (holes print small), each drawn in this range once per pair.
    pub print_deviation_m: Range,
    /// The printed pair's tip and mouth edges, as 45-degree bevels of this size, m: each drawn
    /// once per pair (the CAD's 0.3 mm chamfer and the print's rounding together).
    pub edge_bevel_m: Range,
}

impl Default for RealCell {
    /// The real cell at the ranges of docs/sources.md, 6: what a scenario, `pegtwin trial`, the
    /// Python package and the Gymnasium environment run unless told `profile = "ideal"`.
    fn default() -> Self {
        RealCell {
            profile: Profile::Real,
            joint_friction_scale: [0.5, 2.0],
            contact_friction: [0.12, 0.76],
            static_over_kinetic: [1.0, 1.0],
            wrench_bias: [1.0, 0.1],
            wrench_gain: [0.9, 1.1],
            payload_error: [-0.1, 0.1],
            latency_s: 0.001,
            encoder_offset_rad: 0.0,
            print_deviation_m: [0.0, 12.5e-6],
            edge_bevel_m: [0.3e-3, 0.5e-3],
        }
    }
}

/// Largest joint friction scale accepted.
pub const MAX_JOINT_FRICTION_SCALE: f64 = 10.0;
/// Largest contact friction coefficient accepted (as `[physics] friction`).
pub const MAX_CONTACT_FRICTION: f64 = 2.0;
/// Largest relative payload error accepted.
pub const MAX_PAYLOAD_ERROR: f64 = 0.5;
/// Largest print deviation accepted, m per side (either way).
pub const MAX_PRINT_DEVIATION_M: f64 = 0.5e-3;
/// Largest edge bevel accepted, m.
pub const MAX_EDGE_BEVEL_M: f64 = 2e-3;

/// What one cell drew: the values its imperfections took (recorded in a trial's record).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CellDraw {
    pub joint_friction_scale: f64,
    /// Kinetic and static friction coefficients between peg and hole.
    pub contact_friction: f64,
    pub static_friction: f64,
    /// Bias of the wrench estimate, N and N m (base frame, torque about the TCP).
    pub wrench_bias: [f64; 6],
    pub wrench_gain: f64,
    /// The controller's peg mass over the true one, minus one.
    pub payload_error: f64,
    /// Each joint encoder's constant offset, rad (absent: none).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub encoder_offset_rad: Vec<f64>,
}

impl RealCell {
    /// The ideal cell: what [`crate::twin::workcell::WorkCellParams`] builds by default, and the
    /// physics self-checks run.
    pub fn ideal() -> Self {
        RealCell {
            profile: Profile::Ideal,
            ..RealCell::default()
        }
    }

    pub fn is_ideal(&self) -> bool {
        self.profile == Profile::Ideal
    }

    /// Whether its encoders read the joints off by drawn constant offsets.
    pub fn reads_off(&self) -> bool {
        !self.is_ideal() && self.encoder_offset_rad > 0.0
    }

    /// The draw of the cell of an arm of `joints` joints seeded `seed` (`None`: the ideal cell
    /// draws nothing). Each value has its place in one ChaCha8 stream, in the order of
    /// [`CellDraw`]'s fields; the encoder offsets come last, one per joint, and only when their
    /// range is not zero.
    pub fn draw(&self, seed: u64, joints: usize) -> Option<CellDraw> {
        if self.is_ideal() {
            return None;
        }
        let mut rng = ChaCha8Rng::seed_from_u64(seed ^ CELL_STREAM);
        let mut within = |r: Range| r[0] + (r[1] - r[0]) * rng.random::<f64>();
        let joint_friction_scale = within(self.joint_friction_scale);
        let contact_friction = within(self.contact_friction);
        let static_friction = contact_friction * within(self.static_over_kinetic);
        let [force, torque] = self.wrench_bias;
        let wrench_bias = [force, force, force, torque, torque, torque].map(|h| within([-h, h]));
        let wrench_gain = within(self.wrench_gain);
        let payload_error = within(self.payload_error);
        let h = self.encoder_offset_rad;
        let encoder_offset_rad = match h > 0.0 {
            true => (0..joints).map(|_| within([-h, h])).collect(),
            false => Vec::new(),
        };
        Some(CellDraw {
            joint_friction_scale,
            contact_friction,
            static_friction,
            wrench_bias,
            wrench_gain,
            payload_error,
            encoder_offset_rad,
        })
    }

    /// The print of the built-in `pair` (`None`: the ideal cell prints exactly). The peg's
    /// growth, the hole's shrink and the two edges are drawn in that order from one ChaCha8
    /// stream, seeded by `seed`, the pair's name and its clearance.
    pub fn print(&self, seed: u64, pair: &PartPair) -> Option<Print> {
        if self.is_ideal() {
            return None;
        }
        let name = pair.name.bytes().fold(0xcbf2_9ce4_8422_2325_u64, |h, b| {
            (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3)
        });
        let stream = seed ^ PRINT_STREAM ^ name ^ pair.clearance_m.to_bits().rotate_left(17);
        let mut rng = ChaCha8Rng::seed_from_u64(stream);
        let mut within = |r: Range| r[0] + (r[1] - r[0]) * rng.random::<f64>();
        let growth = within(self.print_deviation_m);
        let shrink = within(self.print_deviation_m);
        let edges = [within(self.edge_bevel_m), within(self.edge_bevel_m)];
        Some(Print::new(pair.clearance_m, growth, shrink, edges))
    }

    /// `pair` as the real cell prints it from `seed` ([`RealCell::print`]): a built-in rebuilt
    /// with its print; an assembly's or a mesh pair, whose files are the parts, as it is.
    pub fn printed(&self, seed: u64, pair: PartPair) -> Result<PartPair> {
        let builtin = Builtin::from_name(&pair.name)
            .filter(|_| pair.content_key.is_none() && pair.print.is_none());
        match (builtin, self.print(seed, &pair)) {
            (Some(b), Some(print)) => geometry::build_printed(b, pair.clearance_m, Some(print)),
            _ => Ok(pair),
        }
    }

    /// Refuses ranges outside what a cell can run with, naming the field.
    pub fn ensure_valid(&self) -> Result<()> {
        let ranges = [
            (
                "joint_friction_scale",
                self.joint_friction_scale,
                0.0,
                MAX_JOINT_FRICTION_SCALE,
            ),
            (
                "contact_friction",
                self.contact_friction,
                0.0,
                MAX_CONTACT_FRICTION,
            ),
            ("static_over_kinetic", self.static_over_kinetic, 1.0, 5.0),
            ("wrench_gain", self.wrench_gain, 0.5, 2.0),
            (
                "payload_error",
                self.payload_error,
                -MAX_PAYLOAD_ERROR,
                MAX_PAYLOAD_ERROR,
            ),
            (
                "print_deviation_m",
                self.print_deviation_m,
                -MAX_PRINT_DEVIATION_M,
                MAX_PRINT_DEVIATION_M,
            ),
            (
                "edge_bevel_m",
                self.edge_bevel_m,
                MIN_CHAMFER_M,
                MAX_EDGE_BEVEL_M,
            ),
        ];
        for (field, [lo, hi], least, most) in ranges {
            if !(least <= lo && lo <= hi && hi <= most) {
                return Err(Error::Input(format!(
                    "cell.{field} = [{lo:?}, {hi:?}]: expected a range [low, high] with \
                     {least} <= low <= high <= {most}"
                )));
            }
        }
        let [force, torque] = self.wrench_bias;
        let (most_f, most_t) = crate::twin::sensing::MAX_WRENCH_BIAS;
        if !((0.0..=most_f).contains(&force) && (0.0..=most_t).contains(&torque)) {
            return Err(Error::Input(format!(
                "cell.wrench_bias = [{force:?}, {torque:?}]: expected half-ranges of at most \
                 {most_f} N and {most_t} N m"
            )));
        }
        if !(0.0..=MAX_ENCODER_OFFSET_RAD).contains(&self.encoder_offset_rad) {
            return Err(Error::Input(format!(
                "cell.encoder_offset_rad = {:?}: expected a half-range of 0 to \
                 {MAX_ENCODER_OFFSET_RAD} rad",
                self.encoder_offset_rad
            )));
        }
        if !(0.0..=crate::twin::control::MAX_LATENCY_S).contains(&self.latency_s) {
            return Err(Error::Input(format!(
                "cell.latency_s = {:?}: expected 0 to {} s",
                self.latency_s,
                crate::twin::control::MAX_LATENCY_S
            )));
        }
        Ok(())
    }
}

/// Mixed into a cell's seed for its draw ("cell"), so that the draw's stream differs from the
/// sensors' (which the seed itself seeds).
const CELL_STREAM: u64 = 0x6365_6c6c;
/// Mixed into a pair's print seed ("print").
const PRINT_STREAM: u64 = 0x70_7269_6e74;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_ideal_cell_draws_nothing_and_the_real_one_draws_within_its_ranges() {
        assert_eq!(RealCell::ideal().draw(3, 7), None);
        let real = RealCell {
            static_over_kinetic: [1.0, 1.5],
            ..RealCell::default()
        };
        for seed in 0..200 {
            let d = real.draw(seed, 7).unwrap();
            assert_eq!(
                Some(&d),
                real.draw(seed, 7).as_ref(),
                "the same seed, the same draw"
            );
            assert!((0.5..=2.0).contains(&d.joint_friction_scale));
            assert!((0.12..=0.76).contains(&d.contact_friction));
            assert!(d.static_friction >= d.contact_friction);
            assert!(d.static_friction <= 1.5 * d.contact_friction);
            assert!(d.wrench_bias[..3].iter().all(|b| b.abs() <= 1.0));
            assert!(d.wrench_bias[3..].iter().all(|b| b.abs() <= 0.1));
            assert!((0.9..=1.1).contains(&d.wrench_gain));
            assert!((-0.1..=0.1).contains(&d.payload_error));
            assert!(d.encoder_offset_rad.is_empty(), "none by default");
        }
        assert_ne!(real.draw(1, 7), real.draw(2, 7));
        // Offsets come last: turning them on leaves every other value of the draw as it was.
        let offsets = RealCell {
            encoder_offset_rad: 1e-4,
            ..real.clone()
        };
        let (a, b) = (real.draw(5, 6).unwrap(), offsets.draw(5, 6).unwrap());
        assert_eq!(b.encoder_offset_rad.len(), 6);
        assert!(b.encoder_offset_rad.iter().all(|o| o.abs() <= 1e-4));
        assert_eq!(
            CellDraw {
                encoder_offset_rad: Vec::new(),
                ..b
            },
            a
        );
    }

    #[test]
    fn a_fixed_value_is_a_range_of_one_point() {
        let real = RealCell {
            contact_friction: [0.3, 0.3],
            payload_error: [0.0, 0.0],
            ..RealCell::default()
        };
        let d = real.draw(9, 7).unwrap();
        assert_eq!(d.contact_friction, 0.3);
        assert_eq!(d.payload_error, 0.0);
    }

    #[test]
    fn bad_ranges_are_named() {
        let bad = |cell: RealCell, field: &str| {
            let e = cell.ensure_valid().unwrap_err().to_string();
            assert!(e.contains(field), "{e}");
        };
        let base = RealCell::default();
        bad(
            RealCell {
                contact_friction: [0.5, 0.2],
                ..base.clone()
            },
            "cell.contact_friction",
        );
        bad(
            RealCell {
                static_over_kinetic: [0.8, 1.0],
                ..base.clone()
            },
            "cell.static_over_kinetic",
        );
        bad(
            RealCell {
                wrench_bias: [100.0, 0.1],
                ..base.clone()
            },
            "cell.wrench_bias",
        );
        bad(
            RealCell {
                latency_s: 1.0,
                ..base
            },
            "cell.latency_s",
        );
        bad(
            RealCell {
                edge_bevel_m: [0.0, 0.3e-3],
                ..RealCell::default()
            },
            "cell.edge_bevel_m",
        );
    }

    #[test]
    fn a_pair_is_printed_once_per_seed_and_measures_its_printed_clearance() {
        use crate::twin::assembly::measure::measure_fit;
        let exact = geometry::build_builtin(Builtin::Cross, 0.5e-3).unwrap();
        let ideal = RealCell::ideal().printed(4, exact.clone()).unwrap();
        assert_eq!(ideal.print, None);
        let vertices = |p: &PartPair| -> Vec<_> {
            (p.peg.pieces.iter().chain(&p.hole.pieces))
                .flat_map(|c| c.vertices.clone())
                .collect()
        };
        assert_eq!(
            vertices(&ideal),
            vertices(&exact),
            "the ideal cell prints the CAD"
        );
        let as_cad = Print::exact(0.5e-3);
        let cad = geometry::build_printed(Builtin::Cross, 0.5e-3, Some(as_cad)).unwrap();
        assert_eq!(
            vertices(&cad),
            vertices(&exact),
            "the exact print is the CAD"
        );
        let cell = RealCell {
            print_deviation_m: [20e-6, 40e-6],
            ..RealCell::default()
        };
        let a = cell.printed(4, exact.clone()).unwrap();
        let b = cell.printed(4, exact.clone()).unwrap();
        let print = a.print.expect("the real cell prints");
        assert_eq!(a.print, b.print, "the same seed, the same print");
        assert_eq!(a.content_key, Some(print.key()), "its manifold is its own");
        assert_ne!(cell.printed(5, exact.clone()).unwrap().print, a.print);
        assert!((20e-6..=40e-6).contains(&print.peg_growth_m));
        assert!((20e-6..=40e-6).contains(&print.hole_shrink_m));
        assert!((0.3e-3..=0.5e-3).contains(&print.peg_edge_m));
        let lost = 2.0 * (print.peg_growth_m + print.hole_shrink_m);
        assert!((print.clearance_m - (0.5e-3 - lost)).abs() < 1e-12);
        let fit = measure_fit(&a.peg, &a.hole, 1e-3, (5e-3, 45e-3)).unwrap();
        assert!(
            (2.0 * fit.gap_min_m - print.clearance_m).abs() < 2e-6,
            "measured {} m, printed {} m",
            2.0 * fit.gap_min_m,
            print.clearance_m
        );
        assert_eq!(
            a.clearance_m, 0.5e-3,
            "the nominal clearance names the pair"
        );
        assert_eq!(
            cell.printed(4, a.clone()).unwrap().print,
            a.print,
            "printed once: a printed pair is not printed again"
        );
    }

    #[test]
    fn a_print_that_closes_the_gap_is_refused_by_name() {
        let exact = geometry::build_builtin(Builtin::Cross, 0.1e-3).unwrap();
        let cell = RealCell {
            print_deviation_m: [40e-6, 40e-6],
            ..RealCell::default()
        };
        let e = cell.printed(1, exact).unwrap_err().to_string();
        assert!(e.contains("cell.print_deviation_m"), "{e}");
    }
}
