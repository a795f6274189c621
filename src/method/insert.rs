//! Insertion (paper IV-E, Fig. 3 "insert"): a small retract along the peg's own axis, an in-plane
//! alignment to the estimated hole at constant depth under high stiffness, then a compliant
//! insertion along the estimated hole axis toward a target past the believed floor (the paper
//! V-B: "the error in Z ... is easily compensated for by overshooting"). The paper's baseline
//! (`direct`) skips the alignment and inserts along the axis of the hole it believes in.
//!
//! The insertion ends as a KUKA Sunrise motion with break conditions would: on a jam force
//! anywhere (`insert_stop_force_n`), or, once the tip is deep enough for the floor to be near
//! (within `insert_seat_window_m` of the believed floor: the belief's z uncertainty), on the seat
//! force
//! (`insert_seat_force_n`, a few newtons): the target stops where it is, so the peg rests on the
//! floor with about that force instead of the overshoot's spring force.

use crate::error::Result;
use crate::method::config::TrialConfig;
use crate::method::session::{Phase, Session};
use crate::pose::{Iso, Pose6};
use crate::twin::workcell::tcp_in_hole;
use serde::{Deserialize, Serialize};

/// Time the insertion target rests at its end before the trial is scored, s.
const INSERT_SETTLE_S: f64 = 0.5;
/// Duration of the retract move, s.
const RETRACT_S: f64 = 0.3;
/// Hold at the aligned pose before inserting, s.
const ALIGN_HOLD_S: f64 = 0.3;

/// Why the compliant insertion's target stopped advancing.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum InsertEnd {
    /// The seat force condition, near the believed floor: the peg is down.
    Seat,
    /// The jam force condition, anywhere.
    Jam,
    /// The target travelled its whole way (past the believed floor by the overshoot).
    Travel,
    /// The insertion's time limit, or the physics faulted.
    #[default]
    Limit,
}

/// What the insertion did.
#[derive(Clone, Debug, Default)]
pub struct Insertion {
    /// |Fz| along the peg axis (estimated) at every physics step of the compliant insertion, N.
    pub fz_n: Vec<f64>,
    /// Why the target stopped.
    pub end: InsertEnd,
    /// Simulated time of each phase, s.
    pub retract_s: f64,
    pub align_s: f64,
    pub insert_s: f64,
}

/// Retracts, aligns to `estimate` when there is one (else stays on the axis of `believed`), and
/// inserts down to the floor of a cavity `cavity_depth_m` deep.
pub fn insert(
    session: &mut Session,
    believed: &Iso,
    estimate: Option<&Pose6>,
    config: &TrialConfig,
    cavity_depth_m: f64,
) -> Result<Insertion> {
    let retract_s = retract(session, config.retract_m);
    let (axis_frame, depth, align_s) = match estimate {
        Some(e) => align(session, &e.to_iso(), config)?,
        None => {
            let (frame, depth) = on_axis(session, believed);
            (frame, depth, 0.0)
        }
    };
    // Down to the floor of the hole the robot believes in, and `insert_overshoot_m` past it (the
    // estimate's z is its weakest axis, paper V-B); without an estimate, past it also by the z
    // uncertainty of the nominal hole.
    let uncertainty = if estimate.is_some() {
        0.0
    } else {
        config.offset_range[2]
    };
    let to_floor = cavity_depth_m - depth;
    let travel = (to_floor + config.insert_overshoot_m + uncertainty).max(0.0);
    let seat = SeatCondition::new(to_floor, config);
    let (fz_n, end, insert_s) = compliant_insertion(session, &axis_frame, travel, seat, config)?;
    Ok(Insertion {
        fz_n,
        end,
        retract_s,
        align_s,
        insert_s,
    })
}

/// The seat break condition: armed once the measured tip has advanced `armed_after_m` along the
/// insertion axis, it stops the target when the tip has stalled and the estimated |Fz| exceeds
/// `force_n`. It arms within the window above the believed floor, and never before the tip has
/// come down half the retract: the floor is at least the retract away when the insertion
/// starts, and a peg held at its start by stiction (pressed to a wall by the alignment or the
/// observation; 10-13 N break it free) has arrived nowhere.
#[derive(Clone, Copy, Debug)]
struct SeatCondition {
    armed_after_m: f64,
    force_n: f64,
}

impl SeatCondition {
    /// For an insertion that starts `to_floor_m` above the believed floor.
    fn new(to_floor_m: f64, config: &TrialConfig) -> Self {
        SeatCondition {
            armed_after_m: (to_floor_m - config.insert_seat_window_m).max(0.5 * config.retract_m),
            force_n: config.insert_seat_force_n,
        }
    }
}

/// A small retract along the peg's own axis; returns its duration, s.
fn retract(session: &mut Session, retract_m: f64) -> f64 {
    let here = session.measurements().tcp;
    let t0 = session.time_s();
    session.set_phase(Phase::Retract);
    session.move_linear(
        &here,
        &(here * Iso::translation(0.0, 0.0, retract_m)),
        RETRACT_S,
    );
    session.time_s() - t0
}

/// In-plane alignment to the estimated hole `hole_est` at the present depth under high
/// stiffness. Returns the aligned frame the insertion runs along, the depth, and the duration.
fn align(session: &mut Session, hole_est: &Iso, config: &TrialConfig) -> Result<(Iso, f64, f64)> {
    let now = session.measurements().tcp;
    let depth = -(hole_est.inverse() * now).translation.z;
    let aligned = tcp_in_hole(hole_est, depth);
    session.set_phase(Phase::Align);
    session.switch_gains(config.align_gains.clone())?;
    let t0 = session.time_s();
    session.move_linear(&now, &aligned, config.align_s);
    session.hold(&aligned, ALIGN_HOLD_S);
    Ok((aligned, depth, session.time_s() - t0))
}

/// Without an estimate: the commanded peg axis (the believed hole's z) at the present depth.
fn on_axis(session: &Session, believed: &Iso) -> (Iso, f64) {
    let now = session.measurements().tcp;
    let depth = -(believed.inverse() * now).translation.z;
    (tcp_in_hole(believed, depth), depth)
}

/// Compliant insertion along `axis_frame`'s z by `travel_m`, within the time limit: the target
/// advances at the insertion speed until it has travelled its way, the estimated |Fz| says the
/// peg jammed, or the seat condition says it is down (force break conditions, as Sunrise's
/// `ForceCondition`); then it rests where it stopped for half a second. Returns the per-step
/// |Fz|, why the target stopped, and the duration, s.
fn compliant_insertion(
    session: &mut Session,
    axis_frame: &Iso,
    travel_m: f64,
    seat: SeatCondition,
    config: &TrialConfig,
) -> Result<(Vec<f64>, InsertEnd, f64)> {
    session.set_phase(Phase::Insert);
    session.switch_gains(config.insert_gains.clone())?;
    let t0 = session.time_s();
    let dt = session.dt_s();
    let limit = (config.insert_limit_s / dt).round() as usize;
    let settle = (INSERT_SETTLE_S / dt).round() as usize;
    let from_axis = axis_frame.inverse();
    let mut fz = Vec::new();
    let mut advanced = Vec::new();
    let mut s = 0.0;
    let mut stopped: Option<(usize, InsertEnd)> = None;
    for k in 0..limit {
        if stopped.is_none() {
            s = (k as f64 * dt * config.insert_speed_m_per_s).min(travel_m);
        }
        session.command_pose(axis_frame * Iso::translation(0.0, 0.0, -s));
        if !session.step() {
            break;
        }
        let m = session.measurements();
        let z = m.tcp.rotation * nalgebra::Vector3::z();
        let f = (m.wrench[0] * z.x + m.wrench[1] * z.y + m.wrench[2] * z.z).abs();
        fz.push(f);
        advanced.push(-(from_axis * m.tcp).translation.z);
        if stopped.is_none() {
            let tip = TipProgress::of(&advanced, dt, config.insert_speed_m_per_s);
            stopped = break_condition(f, tip, s >= travel_m, seat, config).map(|e| (k, e));
        }
        if stopped.is_some_and(|(h, _)| k >= h + settle) {
            break;
        }
    }
    let end = stopped.map_or(InsertEnd::Limit, |(_, e)| e);
    Ok((fz, end, session.time_s() - t0))
}

/// Span over which the seat condition judges whether the tip still advances, s.
const STALL_SPAN_S: f64 = 0.05;
/// The tip has stalled when it advanced less than this share of the target's speed over
/// `STALL_SPAN_S`.
const STALL_SPEED_SHARE: f64 = 0.25;

/// Where the measured tip is along the insertion axis, and whether it has stopped advancing.
#[derive(Clone, Copy, Debug)]
struct TipProgress {
    /// Measured advance along the axis since the insertion began, m.
    advanced_m: f64,
    /// Advanced less than `STALL_SPEED_SHARE` of the target's speed over the last
    /// `STALL_SPAN_S` (false before that much time has passed).
    stalled: bool,
}

impl TipProgress {
    /// From the per-step measured advances so far (`dt_s` apart) and the target's speed, m/s.
    fn of(advances_m: &[f64], dt_s: f64, speed_m_per_s: f64) -> Self {
        let span = (STALL_SPAN_S / dt_s).round() as usize;
        let advanced_m = advances_m.last().copied().unwrap_or(0.0);
        let stalled = advances_m.len() > span
            && advanced_m - advances_m[advances_m.len() - 1 - span]
                < STALL_SPEED_SHARE * speed_m_per_s * span as f64 * dt_s;
        TipProgress {
            advanced_m,
            stalled,
        }
    }
}

/// Which break condition, if any, stops the insertion's target at a step: |Fz| `f_n`, the
/// measured tip's progress, whether the target has travelled its way. The seat condition wants
/// the tip stopped as well as pressing: a peg that slides down under wall friction of a few
/// newtons is not yet down.
fn break_condition(
    f_n: f64,
    tip: TipProgress,
    travelled: bool,
    seat: SeatCondition,
    config: &TrialConfig,
) -> Option<InsertEnd> {
    if f_n > config.insert_stop_force_n {
        Some(InsertEnd::Jam)
    } else if tip.advanced_m >= seat.armed_after_m && tip.stalled && f_n > seat.force_n {
        Some(InsertEnd::Seat)
    } else if travelled {
        Some(InsertEnd::Travel)
    } else {
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const DT: f64 = 1e-3;
    const SPEED: f64 = 15e-3;

    /// Advances of a tip moving at `speed` m/s for `steps` steps after `rest` steps at rest.
    fn advances(rest: usize, steps: usize, speed: f64) -> Vec<f64> {
        (0..rest)
            .map(|_| 0.0)
            .chain((1..=steps).map(|k| k as f64 * DT * speed))
            .collect()
    }

    #[test]
    fn a_tip_that_follows_its_target_has_not_stalled_and_one_at_rest_has() {
        assert!(!TipProgress::of(&advances(0, 200, SPEED), DT, SPEED).stalled);
        assert!(!TipProgress::of(&advances(0, 200, 0.5 * SPEED), DT, SPEED).stalled);
        assert!(TipProgress::of(&advances(200, 0, SPEED), DT, SPEED).stalled);
        assert!(TipProgress::of(&advances(0, 200, 0.1 * SPEED), DT, SPEED).stalled);
        // Not judged before the span has passed.
        assert!(!TipProgress::of(&advances(30, 0, SPEED), DT, SPEED).stalled);
    }

    #[test]
    fn the_seat_condition_arms_in_the_window_once_the_tip_came_down_half_the_retract() {
        let config = TrialConfig::default();
        let far = SeatCondition::new(12e-3, &config);
        assert!((far.armed_after_m - (12e-3 - config.insert_seat_window_m)).abs() < 1e-12);
        let near = SeatCondition::new(3e-3, &config);
        assert_eq!(near.armed_after_m, 0.5 * config.retract_m);
    }

    #[test]
    fn the_seat_condition_wants_the_window_the_stall_and_the_force() {
        let config = TrialConfig::default();
        let seat = SeatCondition {
            armed_after_m: 5e-3,
            force_n: config.insert_seat_force_n,
        };
        let at = |advanced_m, stalled| TipProgress {
            advanced_m,
            stalled,
        };
        let press = config.insert_seat_force_n + 1.0;
        assert_eq!(
            break_condition(press, at(6e-3, true), false, seat, &config),
            Some(InsertEnd::Seat)
        );
        // Above the window (a jam near the mouth), or sliding under wall friction: not down.
        assert_eq!(
            break_condition(press, at(4e-3, true), false, seat, &config),
            None
        );
        assert_eq!(
            break_condition(press, at(6e-3, false), false, seat, &config),
            None
        );
        assert_eq!(
            break_condition(press, at(6e-3, false), true, seat, &config),
            Some(InsertEnd::Travel)
        );
        let jam = config.insert_stop_force_n + 1.0;
        assert_eq!(
            break_condition(jam, at(0.0, false), false, seat, &config),
            Some(InsertEnd::Jam)
        );
    }
}
