//! Insertion (paper IV-E, Fig. 3 "insert"): a small retract along the peg's own axis, an in-plane
//! alignment to the estimated hole at constant depth under high stiffness, then a compliant
//! insertion along the estimated hole axis down past the believed floor. The paper's baseline
//! (`direct`) skips the alignment and inserts along the axis of the hole it believes in.

use crate::error::Result;
use crate::method::config::TrialConfig;
use crate::method::session::{Phase, Session};
use crate::pose::{Iso, Pose6};
use crate::twin::cell::tcp_in_hole;

/// Time the insertion target rests at its end before the trial is scored, s.
const INSERT_SETTLE_S: f64 = 0.5;
/// Duration of the retract move, s.
const RETRACT_S: f64 = 0.3;
/// Hold at the aligned pose before inserting, s.
const ALIGN_HOLD_S: f64 = 0.3;

/// What the insertion did.
#[derive(Clone, Debug, Default)]
pub struct Insertion {
    /// |Fz| along the peg axis (estimated) at every physics step of the compliant insertion, N.
    pub fz_n: Vec<f64>,
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
    let travel = (cavity_depth_m - depth + config.insert_overshoot_m + uncertainty).max(0.0);
    let (fz_n, insert_s) = compliant_insertion(session, &axis_frame, travel, config)?;
    Ok(Insertion {
        fz_n,
        retract_s,
        align_s,
        insert_s,
    })
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
/// advances at the insertion speed until it has travelled its way or the estimated |Fz| says the
/// peg jammed (a force break condition, as Sunrise's), then rests for half a second. Returns the
/// per-step |Fz| and the duration, s.
fn compliant_insertion(
    session: &mut Session,
    axis_frame: &Iso,
    travel_m: f64,
    config: &TrialConfig,
) -> Result<(Vec<f64>, f64)> {
    session.set_phase(Phase::Insert);
    session.switch_gains(config.insert_gains.clone())?;
    let t0 = session.time_s();
    let dt = session.dt_s();
    let limit = (config.insert_limit_s / dt).round() as usize;
    let settle = (INSERT_SETTLE_S / dt).round() as usize;
    let mut fz = Vec::new();
    let mut s = 0.0;
    let mut held_since = None;
    for k in 0..limit {
        if held_since.is_none() {
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
        if held_since.is_none() && (f > config.insert_stop_force_n || s >= travel_m) {
            held_since = Some(k);
        }
        if held_since.is_some_and(|h| k >= h + settle) {
            break;
        }
    }
    Ok((fz, session.time_s() - t0))
}
