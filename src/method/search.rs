//! Spiral search from above (the classic peg-in-hole search; the paper starts partially inserted
//! instead, `start = partial`): descend along the nominal hole axis until the estimated wrench
//! says contact with the fixture's top, then press on it while an Archimedean spiral sweeps x, y
//! over the pose uncertainty, until the tip drops below the height of first contact; then down to
//! the partial insertion.

use crate::method::config::TrialConfig;
use crate::method::primitives::Spiral;
use crate::method::session::{Phase, Session};
use crate::pose::Iso;
use crate::twin::workcell::tcp_in_hole;

/// Where a search starts: above the nominal mouth, clear of the highest hole the offsets allow.
pub fn start_pose(nominal: &Iso, config: &TrialConfig) -> Iso {
    tcp_in_hole(
        nominal,
        -(config.offset_range[2] + config.search.start_clearance_m),
    )
}

/// Runs the search from where the robot stands. Returns the hole frame the robot now believes in
/// (the nominal orientation, centred where the peg dropped, its mouth at the contact height), or
/// `None` when the time limit passes first or the physics faults.
pub fn search(
    session: &mut Session,
    nominal: &Iso,
    config: &TrialConfig,
    clearance_m: f64,
) -> Option<Iso> {
    session.set_phase(Phase::Search);
    let s = &config.search;
    let dt = session.dt_s();
    let height = (nominal.inverse() * session.measurements().tcp)
        .translation
        .z;
    let limit = (s.limit_s / dt).round() as usize;
    let mut k = 0;
    let mut contact_z = None;
    while k < limit {
        let z = height - s.approach_speed_m_per_s * k as f64 * dt;
        session.command_pose(nominal * Iso::translation(0.0, 0.0, z));
        if !session.step() {
            return None;
        }
        k += 1;
        let m = session.measurements();
        if m.contact {
            contact_z = Some((nominal.inverse() * m.tcp).translation.z);
            break;
        }
    }
    let contact_z = contact_z?;
    let r = &config.offset_range;
    let spiral = Spiral {
        max_radius_m: r[0].max(r[1]) + clearance_m + s.spiral_margin_m,
        pitch_m: s.spiral_pitch_m,
        speed_m_per_s: s.spiral_speed_m_per_s,
    };
    let t0 = k;
    while k < limit {
        let [x, y] = spiral.offset((k - t0) as f64 * dt);
        session.command_pose(nominal * Iso::translation(x, y, contact_z - s.press_depth_m));
        if !session.step() {
            return None;
        }
        k += 1;
        let tip = (nominal.inverse() * session.measurements().tcp).translation;
        if tip.z < contact_z - s.drop_m {
            let believed = nominal * Iso::translation(tip.x, tip.y, contact_z);
            let here = session.measurements().tcp;
            let partial = tcp_in_hole(&believed, config.start_depth_m);
            session.move_linear(&here, &partial, s.descend_s);
            return session.fault().is_none().then_some(believed);
        }
    }
    None
}
