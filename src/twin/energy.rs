//! Where the arm's mechanical energy comes from: the ledger that tells a blow-up of the physics
//! from one that the drives power (issue 14; docs/physics.md, "Whose energy: the physics' faults
//! told from the drives'").
//!
//! Each physics step the cell books the arm's mechanical energy (the links' kinetic energy, the
//! rotors' through the armature, and the potential energy in gravity, J) and the work done on
//! the arm in that step by three things: the joint torques the controller commands (and a
//! diagnostic push, where one is applied), the contact impulses on the arm's bodies, and the
//! joints' viscous damping. What the three do not explain is the integrator's own error.
//! Contacts without restitution only take energy out of the arm, the damping only takes, and a
//! sound integrator keeps its error small; so when a joint runs away, the account of its last
//! [`WINDOW_S`] says who paid for it: the drives (the commanded motion, the gains, the
//! controller; what the real robot would do too), or the contact solve or the integrator (the
//! physics').
//!
//! How exact it is. The energy is exact, and so is the drives' work: a joint torque is constant
//! over a step, so its work is the torque times the joint's travel. The physics' share, energy
//! gained less the drives' and the damping's work, is therefore as exact as the damping's work
//! (booked at the speed after the step, as rapier applies it): the split between the drives and
//! the physics is sound. The contacts' share is booked at the velocities after the step: the
//! impulse times the velocity it left, which a converged contact without restitution holds at
//! zero or below (no velocity into the surface, friction against the sliding), so a positive
//! share is the contact solve putting energy in. The energy an impact legitimately takes out
//! (the impulse times the approach velocity it stopped) is then not in the contacts' share but
//! in the integrator's, as a loss; the split of the physics' share between the two is an
//! indication, not a measurement.

use serde::{Deserialize, Serialize};
use std::collections::VecDeque;

/// The span of time before a fault that its account covers, s.
pub const WINDOW_S: f64 = 0.1;

/// What put energy into the arm.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum EnergySource {
    /// The joint torques: the controller answering its target and gains.
    Drives,
    /// The contact impulses: an unconverged or over-stiff contact solve.
    Contacts,
    /// Neither: the integrator's error.
    Integration,
}

impl EnergySource {
    /// Whether the physics, not the commanded motion, supplied the energy.
    pub fn is_physics(self) -> bool {
        !matches!(self, EnergySource::Drives)
    }

    fn describe(self) -> &'static str {
        match self {
            EnergySource::Drives => "the drives",
            EnergySource::Contacts => "the contacts",
            EnergySource::Integration => "the integrator",
        }
    }
}

/// The arm's energy account over a span of time, J.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct EnergyFlows {
    /// The span the account covers, s (shorter when the run is).
    pub window_s: f64,
    /// Gain of kinetic plus gravitational potential energy.
    pub mechanical_gain_j: f64,
    /// Work of the joint torques (and of a diagnostic push).
    pub drives_j: f64,
    /// Work of the contact impulses on the arm's bodies.
    pub contacts_j: f64,
    /// Work of the joints' viscous damping (never positive).
    pub joint_damping_j: f64,
    /// The gain the work does not explain: the integrator's error.
    pub integration_j: f64,
    /// Who put more in: the drives, or the physics (then the contacts or the integrator,
    /// whichever put in more of it).
    pub source: EnergySource,
}

impl EnergyFlows {
    /// One line for a fault's reason: who paid, and the three inputs.
    pub fn describe(&self) -> String {
        format!(
            "the energy came from {} (last {:.0} ms: drives {:+.2} J, contacts {:+.2} J, integration {:+.2} J)",
            self.source.describe(),
            self.window_s * 1e3,
            self.drives_j,
            self.contacts_j,
            self.integration_j
        )
    }
}

/// Running totals since the start, J.
#[derive(Clone, Copy, Debug, Default)]
struct Totals {
    time_s: f64,
    mechanical_j: f64,
    drives_j: f64,
    contacts_j: f64,
    damping_j: f64,
}

/// What one physics step booked, J.
#[derive(Clone, Copy, Debug)]
pub struct StepEnergy {
    /// The arm's mechanical energy after the step.
    pub mechanical_j: f64,
    /// Work over the step of the joint torques, the contact impulses and the joint damping.
    pub drives_j: f64,
    pub contacts_j: f64,
    pub damping_j: f64,
}

/// The last [`WINDOW_S`] of the account, one entry per step.
#[derive(Clone)]
pub struct EnergyLedger {
    /// Never empty: it opens with the start.
    entries: VecDeque<Totals>,
    capacity: usize,
}

impl EnergyLedger {
    /// A ledger for steps of `dt_s` seconds, opened with the arm's energy at the start.
    pub fn new(dt_s: f64, mechanical_j: f64) -> Self {
        let capacity = (WINDOW_S / dt_s).round() as usize + 1;
        let start = Totals {
            mechanical_j,
            ..Totals::default()
        };
        let mut entries = VecDeque::with_capacity(capacity);
        entries.push_back(start);
        EnergyLedger { entries, capacity }
    }

    fn last(&self) -> Totals {
        *self
            .entries
            .back()
            .expect("the ledger opens with the start")
    }

    /// Books one step ending at `time_s`.
    pub fn book(&mut self, time_s: f64, step: StepEnergy) {
        let last = self.last();
        let t = Totals {
            time_s,
            mechanical_j: step.mechanical_j,
            drives_j: last.drives_j + step.drives_j,
            contacts_j: last.contacts_j + step.contacts_j,
            damping_j: last.damping_j + step.damping_j,
        };
        if self.entries.len() == self.capacity {
            self.entries.pop_front();
        }
        self.entries.push_back(t);
    }

    /// The account of the last [`WINDOW_S`] (or of the whole run, when shorter).
    pub fn flows(&self) -> EnergyFlows {
        let (first, last) = (self.entries[0], self.last());
        let mechanical_gain_j = last.mechanical_j - first.mechanical_j;
        let drives_j = last.drives_j - first.drives_j;
        let contacts_j = last.contacts_j - first.contacts_j;
        let joint_damping_j = last.damping_j - first.damping_j;
        let integration_j = mechanical_gain_j - drives_j - contacts_j - joint_damping_j;
        let source = if drives_j >= contacts_j + integration_j {
            EnergySource::Drives
        } else if contacts_j >= integration_j {
            EnergySource::Contacts
        } else {
            EnergySource::Integration
        };
        EnergyFlows {
            window_s: last.time_s - first.time_s,
            mechanical_gain_j,
            drives_j,
            contacts_j,
            joint_damping_j,
            integration_j,
            source,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn step(mechanical_j: f64, drives_j: f64, contacts_j: f64) -> StepEnergy {
        StepEnergy {
            mechanical_j,
            drives_j,
            contacts_j,
            damping_j: -0.001,
        }
    }

    #[test]
    fn the_account_covers_the_last_window_and_names_who_paid() {
        let mut ledger = EnergyLedger::new(1e-3, 10.0);
        // 200 steps where the drives put 0.01 J per step in, and the arm gains it less the damping.
        let mut e = 10.0;
        for k in 1..=200 {
            e += 0.01 - 0.001;
            ledger.book(k as f64 * 1e-3, step(e, 0.01, 0.0));
        }
        let f = ledger.flows();
        assert!((f.window_s - WINDOW_S).abs() < 1e-9, "{f:?}");
        assert!((f.drives_j - 1.0).abs() < 1e-9, "{f:?}");
        assert!((f.joint_damping_j + 0.1).abs() < 1e-9, "{f:?}");
        assert!(f.integration_j.abs() < 1e-9, "{f:?}");
        assert_eq!(f.source, EnergySource::Drives);
        assert!(!f.source.is_physics());
        // Then the contacts pay while the drives take energy out.
        for k in 201..=300 {
            e += 0.02 - 0.005 - 0.001;
            ledger.book(k as f64 * 1e-3, step(e, -0.005, 0.02));
        }
        let f = ledger.flows();
        assert_eq!(f.source, EnergySource::Contacts);
        assert!(f.source.is_physics());
        assert!((f.contacts_j - 2.0).abs() < 1e-9, "{f:?}");
        // A gain nobody's work explains is the integrator's.
        for k in 301..=400 {
            e += 0.03;
            ledger.book(k as f64 * 1e-3, step(e, 0.0, 0.0));
        }
        let f = ledger.flows();
        assert_eq!(f.source, EnergySource::Integration);
        assert!((f.integration_j - 3.1).abs() < 1e-9, "{f:?}");
        assert!(
            f.describe()
                .starts_with("the energy came from the integrator (last 100 ms")
        );
    }

    #[test]
    fn a_short_run_is_accounted_from_its_start() {
        let mut ledger = EnergyLedger::new(1e-3, 1.0);
        ledger.book(1e-3, step(1.5, 0.5, 0.0));
        let f = ledger.flows();
        assert!((f.window_s - 1e-3).abs() < 1e-12);
        assert!((f.mechanical_gain_j - 0.5).abs() < 1e-12);
        assert_eq!(f.source, EnergySource::Drives);
    }
}
