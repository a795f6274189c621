//! Observation (paper IV-C, Fig. 3 "observe"): around the hole pose the robot believes in, the
//! sampling primitives of the reference manifold (spiral, oscillations, descent, perturbation)
//! run under a compliant impedance for `t_obs` seconds, in two phases: wide amplitudes while
//! descending to the observation depth (phase 1), smaller ones there (phase 2). Every step whose
//! estimated wrench says contact records the measured TCP pose; the recording is then thinned by
//! temporal downsampling to the observations registration uses.

use crate::method::config::TrialConfig;
use crate::method::manifold::build::SamplerConfig;
use crate::method::primitives::{Descent, Drive, PerturbationState, SamplingMotion, ScaleSchedule};
use crate::method::session::{Phase, Session};
use crate::pose::{Iso, Pose6};
use std::ops::ControlFlow;

/// What the observation recorded.
#[derive(Clone, Debug, Default)]
pub struct Observation {
    /// Measured contact poses `base_T_tcp` (m, rad), in recording order.
    pub contacts: Vec<Pose6>,
    /// Simulated time spent observing, s.
    pub duration_s: f64,
}

impl Observation {
    /// Temporal downsampling (IV-C): `n` observations evenly spaced in recording order.
    pub fn downsampled(&self, n: usize) -> Vec<Pose6> {
        temporal_downsample(&self.contacts, n)
    }
}

/// Temporal downsampling (IV-C): `n` observations evenly spaced in recording order.
pub fn temporal_downsample(poses: &[Pose6], n: usize) -> Vec<Pose6> {
    if poses.len() <= n {
        return poses.to_vec();
    }
    (0..n).map(|i| poses[i * poses.len() / n]).collect()
}

/// The observation's motion: the reference sampler's primitives, with amplitudes widened by the
/// uncertainty of the nominal pose (the sweep must reach past the hole wherever it really is),
/// descending from the start depth to the observation depth in phase 1.
pub fn observation_motion(config: &TrialConfig) -> SamplingMotion {
    let mut motion = SamplerConfig::default().motion;
    let r = &config.offset_range;
    motion.schedule.lateral_overtravel_m += r[0].max(r[1]);
    motion.schedule.angular_overtravel_rad += r[3].max(r[4]);
    motion.descent = Descent {
        start_depth_m: config.start_depth_m,
        end_depth_m: config.observe_depth_m,
        speed_m_per_s: (config.observe_depth_m - config.start_depth_m).max(0.0)
            / (config.phase1_fraction * config.t_obs_s),
    };
    motion
}

/// Observes for `config.t_obs_s` around `believed` (`base_T_hole`), the perturbation seeded with
/// `perturbation_seed`. Stops early only if the physics faults (the session keeps the fault).
pub fn observe(
    session: &mut Session,
    believed: &Iso,
    config: &TrialConfig,
    clearance_m: f64,
    perturbation_seed: u64,
) -> Observation {
    session.set_phase(Phase::Observe);
    let start_s = session.time_s();
    let motion = observation_motion(config);
    let drive = Drive {
        base_t_hole: *believed,
        motion: &motion,
        schedule: ScaleSchedule {
            before: config.phase1_scale,
            after: config.phase2_scale,
            switch_s: motion.descent.duration_s(),
        },
        clearance_m,
        duration_s: config.t_obs_s,
    };
    let mut noise = PerturbationState::new(motion.perturbation.clone(), perturbation_seed);
    let mut contacts = Vec::new();
    drive.run(session, &mut noise, |m| {
        if m.contact {
            contacts.push(Pose6::from_iso(&m.tcp));
        }
        ControlFlow::Continue(())
    });
    Observation {
        contacts,
        duration_s: session.time_s() - start_s,
    }
}
