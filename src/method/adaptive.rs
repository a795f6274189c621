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

use crate::method::config::AdaptiveConfig;
use crate::method::primitives::Probe;
use crate::twin::geometry::{HOLE_ENTRY_CHAMFER_M, PEG_TIP_CHAMFER_M, PartPair};

/// The paper's critical orientation error (Fig. 5), rad.
pub const CRITICAL_TILT_RAD: f64 = 2.5 * std::f64::consts::PI / 180.0;

/// How many standard deviations of the estimate must fit in each tolerance.
pub const SIGMAS: f64 = 2.0;

/// The largest standard deviation of each axis of the estimate (x, y, z m; roll, pitch, yaw rad)
/// at which the observation stops.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StopRule {
    pub max_std: [f64; 6],
}

impl StopRule {
    /// The limits for `pair`: `cfg`'s where it sets them, else half the insertion's tolerances.
    pub fn for_pair(pair: &PartPair, cfg: &AdaptiveConfig) -> Self {
        let lead_in = lead_in_m(pair);
        let xy = cfg.max_std_xy_m.unwrap_or(lead_in / SIGMAS);
        let tilt = cfg.max_std_tilt_rad.unwrap_or(CRITICAL_TILT_RAD / SIGMAS);
        let yaw = cfg
            .max_std_yaw_rad
            .unwrap_or(lead_in / peg_radius_m(pair) / SIGMAS);
        StopRule {
            max_std: [xy, xy, f64::INFINITY, tilt, tilt, yaw],
        }
    }

    /// Whether an estimate with standard deviations `std` is certain enough to insert.
    pub fn met(&self, std: &[f64; 6]) -> bool {
        std.iter().zip(&self.max_std).all(|(s, max)| s <= max)
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
        let rule = StopRule::for_pair(&cross, &AdaptiveConfig::default());
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
        let tight = StopRule::for_pair(&tight, &AdaptiveConfig::default());
        assert!(tight.max_std[0] < rule.max_std[0]);
        // A limit set by hand wins.
        let set = AdaptiveConfig {
            max_std_xy_m: Some(1e-4),
            ..AdaptiveConfig::default()
        };
        assert_eq!(StopRule::for_pair(&cross, &set).max_std[0], 1e-4);
        assert!(rule.met(&[1e-4, 1e-4, 1.0, 0.01, 0.01, 0.001]));
        assert!(!rule.met(&[1e-3, 1e-4, 1.0, 0.01, 0.01, 0.001]));
    }

    #[test]
    fn active_probing_widens_the_group_furthest_above_its_limit() {
        let rule = StopRule {
            max_std: [1e-4, 1e-4, f64::INFINITY, 0.01, 0.01, 0.002],
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
