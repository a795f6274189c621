//! Observation that stops itself (issue "know when you know"; docs/method.md, "Observation that
//! stops itself"): the limits on the estimate's standard deviations under which the insertion can
//! start. The loop that observes, registers and asks is `method::trial`'s
//! ([`crate::method::trial::ObservingTrial::observe_adaptively`]).
//!
//! The insertion aligns the peg to the estimate and inserts compliantly (IV-E). It tolerates:
//! - a lateral error up to the lead-in: half the gap plus the two 45-degree chamfers, which guide
//!   a tip that lands on them into the hole;
//! - a yaw error that moves the peg's outermost corner (at `r` from its axis) by no more than the
//!   lead-in: `lead-in / r`;
//! - a tilt below the paper's critical orientation error, 2.5 deg (Fig. 5: beyond it, success
//!   falls; here 49 % against 84 % below it over 375 trials at 0.5 mm, docs/method.md).
//!
//! Each limit is half its tolerance: with calibrated standard deviations
//! ([`crate::method::register::uncertainty`]), the error then lies within the tolerance in about
//! 95 % of trials. z is not limited: the insertion overshoots the believed floor and stops on a
//! seat force (IV-E, V-B).
//!
//! A limit may also be out of reach: the standard deviations shrink about as 1/sqrt(t) from a
//! start the real cell makes wide, down to the calibration's floor, and on four in five of the
//! paper scenario's trials at 0.5 mm the tilt's does not meet its limit within the longest
//! budget. The observation then stops when the trend of an axis still above its limit says it
//! would not meet it by then ([`StopRule::out_of_reach`]), a futility stop as in a sequential
//! trial. At 0.1 mm that stop costs success (docs/method.md): the tilt the insertion tolerates
//! shrinks with the clearance, and the tilt limit does not.

use crate::choice::{Choice, Named};
use crate::method::config::AdaptiveConfig;
use crate::method::primitives::Probe;
use crate::method::register::uncertainty;
use crate::twin::geometry::{HOLE_ENTRY_CHAMFER_M, PEG_TIP_CHAMFER_M, PartPair};
use serde::{Deserialize, Serialize};

/// Why an adaptive observation stopped, in its record (`observation_stop`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ObservationStop {
    /// Every standard deviation within its limit ([`StopRule::met`]).
    Certain,
    /// A limit out of reach by the longest budget ([`StopRule::out_of_reach`]).
    OutOfReach,
    /// The longest budget ran out.
    Budget,
    /// The trial could not go on observing: a physics fault.
    Fault,
}

/// How many checks of an active observation widened each motion group ([`StopRule::weakest`]),
/// in its record (`widened`): which uncertainty active probing chased.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Widened {
    /// The spiral (x, y).
    pub lateral: u32,
    /// The roll and pitch oscillations.
    pub tilt: u32,
    /// The yaw oscillation.
    pub yaw: u32,
}

impl Widened {
    /// Counts one check that widened `probe`.
    pub fn add(&mut self, probe: Probe) {
        match probe {
            Probe::Lateral => self.lateral += 1,
            Probe::Tilt => self.tilt += 1,
            Probe::Yaw => self.yaw += 1,
        }
    }
}

impl Choice for ObservationStop {
    const WHAT: &'static str = "observation stop";
    const NAMED: &'static [Named<Self>] = &[
        Named {
            name: "certain",
            value: ObservationStop::Certain,
            help: "every standard deviation of the estimate within its limit",
        },
        Named {
            name: "out_of_reach",
            value: ObservationStop::OutOfReach,
            help: "a standard deviation that, by its trend, would not meet its limit in time",
        },
        Named {
            name: "budget",
            value: ObservationStop::Budget,
            help: "the longest observation ran out",
        },
        Named {
            name: "fault",
            value: ObservationStop::Fault,
            help: "a physics fault stopped the trial",
        },
    ];
}

/// The paper's critical orientation error (Fig. 5), rad.
pub const CRITICAL_TILT_RAD: f64 = 2.5 * std::f64::consts::PI / 180.0;

/// How many standard deviations of the estimate must fit in each tolerance.
pub const SIGMAS: f64 = 2.0;

/// The largest standard deviation of each axis of the estimate (x, y, z m; roll, pitch, yaw rad)
/// at which the observation stops, and the floor no observation takes it below.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StopRule {
    pub max_std: [f64; 6],
    /// The calibration's floor at the reference manifold's clearance ([`uncertainty::axis_floor`],
    /// as registration adds it): the part of each standard deviation that does not shrink with
    /// more observations.
    pub floor: [f64; 6],
}

impl StopRule {
    /// The limits for `pair`: `cfg`'s where it sets them, else half the insertion's tolerances;
    /// the floor of a reference manifold of clearance `manifold_clearance_m` (its file's).
    pub fn for_pair(
        pair: &PartPair,
        cfg: &AdaptiveConfig,
        manifold_clearance_m: Option<f64>,
    ) -> Self {
        let lead_in = lead_in_m(pair);
        let xy = cfg.max_std_xy_m.unwrap_or(lead_in / SIGMAS);
        let tilt = cfg.max_std_tilt_rad.unwrap_or(CRITICAL_TILT_RAD / SIGMAS);
        let yaw = cfg
            .max_std_yaw_rad
            .unwrap_or(lead_in / peg_radius_m(pair) / SIGMAS);
        StopRule {
            max_std: [xy, xy, f64::INFINITY, tilt, tilt, yaw],
            floor: uncertainty::axis_floor(manifold_clearance_m),
        }
    }

    /// Whether an estimate with standard deviations `std` is certain enough to insert.
    pub fn met(&self, std: &[f64; 6]) -> bool {
        std.iter().zip(&self.max_std).all(|(s, max)| s <= max)
    }

    /// Whether an axis still above its limit at `now` (time s, standard deviations) would not
    /// meet it by `t_max_s`, by the trend since the check `before`. The part above the floor,
    /// `r = sqrt(std² - floor²)`, follows a power of time through both checks, `r(t) = r(now)
    /// (t / t_now)^-p` (p = 1/2 for independent observations), or keeps its present value where
    /// it did not shrink; the floor stays. A limit under the floor is out of reach at once.
    pub fn out_of_reach(
        &self,
        before: (f64, &[f64; 6]),
        now: (f64, &[f64; 6]),
        t_max_s: f64,
    ) -> bool {
        let ((t0, s0), (t1, s1)) = (before, now);
        (0..6).any(|i| {
            let f = self.floor[i];
            let (r0, r1) = (above_floor(s0[i], f), above_floor(s1[i], f));
            let r_max = if r1 < r0 && t1 > t0 {
                let p = (r0 / r1).ln() / (t1 / t0).ln();
                r1 * (t1 / t_max_s).powf(p)
            } else {
                r1
            };
            s1[i] > self.max_std[i] && r_max.hypot(f) > self.max_std[i]
        })
    }

    /// The motion group whose axes stand furthest above their limits, as a share of the limit
    /// (x, y: the spiral; roll, pitch: the tilt oscillations; yaw), for active probing to widen.
    /// Ties go to the earlier group.
    pub fn weakest(&self, std: &[f64; 6]) -> Probe {
        let share = |axes: &[usize]| {
            axes.iter()
                .map(|&i| std[i] / self.max_std[i])
                .fold(0.0, f64::max)
        };
        let groups = [
            (Probe::Lateral, share(&[0, 1])),
            (Probe::Tilt, share(&[3, 4])),
            (Probe::Yaw, share(&[5])),
        ];
        groups
            .iter()
            .fold(groups[0], |best, g| if g.1 > best.1 { *g } else { best })
            .0
    }
}

/// The part of a standard deviation `std` above its floor `f`: `sqrt(std² - f²)`, 0 under it.
fn above_floor(std: f64, f: f64) -> f64 {
    (std * std - f * f).max(0.0).sqrt()
}

/// The lateral error the insertion tolerates, m: half the (printed) diametral clearance plus
/// the peg tip's and the hole mouth's 45-degree chamfers (a built-in's, as printed; an assembly's
/// chamfers are not known and count as none).
pub fn lead_in_m(pair: &PartPair) -> f64 {
    let chamfers = match (&pair.print, &pair.content_key) {
        (Some(print), _) => print.peg_edge_m + print.hole_edge_m,
        (None, None) => PEG_TIP_CHAMFER_M + HOLE_ENTRY_CHAMFER_M,
        (None, Some(_)) => 0.0,
    };
    let clearance = pair.print.map_or(pair.clearance_m, |p| p.clearance_m);
    clearance / 2.0 + chamfers
}

/// The distance of the peg's outermost point from its axis over the part that enters the hole
/// (from the tip up to the cavity's depth), m.
pub fn peg_radius_m(pair: &PartPair) -> f64 {
    pair.peg
        .pieces
        .iter()
        .flat_map(|p| &p.vertices)
        .filter(|v| v.z <= pair.cavity_depth_m)
        .map(|v| v.x.hypot(v.y))
        .fold(0.0, f64::max)
        .max(f64::MIN_POSITIVE)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::twin::geometry::{build_builtin, builtin_by_name};

    #[test]
    fn the_limits_follow_the_gap_the_chamfers_and_the_pegs_size() {
        let cross = build_builtin(builtin_by_name("cross").unwrap(), 0.5e-3).unwrap();
        let rule = StopRule::for_pair(&cross, &AdaptiveConfig::default(), Some(0.5e-3));
        // Half of (0.25 mm + 0.3 mm + 0.3 mm).
        assert!(
            (rule.max_std[0] - 0.425e-3).abs() < 1e-12,
            "{:?}",
            rule.max_std
        );
        assert_eq!(rule.max_std[0], rule.max_std[1]);
        assert!(rule.max_std[2].is_infinite());
        assert!((rule.max_std[3].to_degrees() - 1.25).abs() < 1e-12);
        let r = peg_radius_m(&cross);
        assert!(r > 5e-3 && r < 0.05, "{r}");
        assert!((rule.max_std[5] - 0.85e-3 / r / 2.0).abs() < 1e-12);
        // A tighter fit stops later: its limits are smaller.
        let tight = build_builtin(builtin_by_name("cross").unwrap(), 0.1e-3).unwrap();
        let tight = StopRule::for_pair(&tight, &AdaptiveConfig::default(), Some(0.1e-3));
        assert!(tight.max_std[0] < rule.max_std[0]);
        // A limit set by hand wins.
        let set = AdaptiveConfig {
            max_std_xy_m: Some(1e-4),
            ..AdaptiveConfig::default()
        };
        assert_eq!(StopRule::for_pair(&cross, &set, None).max_std[0], 1e-4);
        assert!(rule.met(&[1e-4, 1e-4, 1.0, 0.01, 0.01, 0.001]));
        assert!(!rule.met(&[1e-3, 1e-4, 1.0, 0.01, 0.01, 0.001]));
    }

    #[test]
    fn a_limit_is_out_of_reach_when_its_trend_misses_it_by_the_longest_budget() {
        let rule = StopRule {
            max_std: [1e-4, 1e-4, f64::INFINITY, 0.01, 0.01, 0.002],
            floor: [0.0; 6],
        };
        let ok = [1e-4, 1e-4, 1.0, 0.01, 0.01, 0.002];
        let with = |i: usize, v: f64| {
            let mut s = ok;
            s[i] = v;
            s
        };
        // Roll at 2x its limit at 4 s: shrinking as 1/sqrt(t) it reaches 0.02 * sqrt(4/10) =
        // 1.26x by 10 s (out of reach); as 1/t, 0.8x (within reach).
        let sqrt = with(3, 0.02);
        let before = with(3, 0.02 * (4.0f64 / 3.0).sqrt());
        assert!(rule.out_of_reach((3.0, &before), (4.0, &sqrt), 10.0));
        let fast = with(3, 0.02 * 4.0 / 3.0);
        assert!(!rule.out_of_reach((3.0, &fast), (4.0, &sqrt), 10.0));
        // Not shrinking: out of reach; an axis within its limit, or z, never is.
        assert!(rule.out_of_reach((3.0, &sqrt), (4.0, &sqrt), 10.0));
        assert!(!rule.out_of_reach((3.0, &ok), (4.0, &ok), 10.0));
        let z = with(2, 5.0);
        assert!(!rule.out_of_reach((3.0, &z), (4.0, &z), 10.0));
        // At the longest budget the trend is the present value.
        assert!(rule.out_of_reach((9.0, &fast), (10.0, &with(3, 0.011)), 10.0));
        assert!(!rule.out_of_reach((9.0, &fast), (10.0, &with(3, 0.009)), 10.0));
    }

    #[test]
    fn only_the_part_above_the_floor_shrinks_and_a_floor_over_the_limit_is_out_of_reach() {
        let inf = f64::INFINITY;
        let mut rule = StopRule {
            max_std: [inf, inf, inf, 0.01, 0.01, inf],
            floor: [0.0, 0.0, 0.0, 0.008, 0.008, 0.0],
        };
        // Roll's part above a 0.008 floor shrinking as 1/t from 0.016 at 4 s: 0.0064 by 10 s,
        // 0.0102 with the floor (out of reach). The totals alone, extrapolated as a power of
        // time, would have promised 0.0083 (within reach).
        let total = |r: f64| [0.0, 0.0, 0.0, r.hypot(0.008), 0.0, 0.0];
        let (before, now) = (total(0.016 * 4.0 / 3.0), total(0.016));
        assert!(rule.out_of_reach((3.0, &before), (4.0, &now), 10.0));
        let no_floor = StopRule {
            floor: [0.0; 6],
            ..rule
        };
        assert!(!no_floor.out_of_reach((3.0, &before), (4.0, &now), 10.0));
        // From 0.012 at 4 s: 0.0048 by 10 s, 0.0093 with the floor (within reach).
        let (before, now) = (total(0.012 * 4.0 / 3.0), total(0.012));
        assert!(!rule.out_of_reach((3.0, &before), (4.0, &now), 10.0));
        // A floor over the limit: out of reach however fast the rest shrinks.
        rule.floor[3] = 0.012;
        let at = |r: f64| [0.0, 0.0, 0.0, r.hypot(0.012), 0.0, 0.0];
        assert!(rule.out_of_reach((3.0, &at(1.0)), (4.0, &at(0.001)), 10.0));
    }

    #[test]
    fn active_probing_widens_the_group_furthest_above_its_limit() {
        let rule = StopRule {
            max_std: [1e-4, 1e-4, f64::INFINITY, 0.01, 0.01, 0.002],
            floor: [0.0; 6],
        };
        // y at 3x its limit, pitch at 2x, yaw at 1.5x; z is never chosen.
        assert_eq!(
            rule.weakest(&[1e-4, 3e-4, 1.0, 0.01, 0.02, 0.003]),
            Probe::Lateral
        );
        assert_eq!(
            rule.weakest(&[1e-4, 1e-4, 1.0, 0.04, 0.02, 0.003]),
            Probe::Tilt
        );
        assert_eq!(rule.weakest(&[0.0, 0.0, 1.0, 0.0, 0.0, 0.003]), Probe::Yaw);
    }
}
