//! Observation (paper IV-C, Fig. 3 "observe"): around the hole pose the robot believes in, the
//! sampling primitives of the reference manifold (spiral, oscillations, descent, perturbation)
//! run under a compliant impedance for `t_obs` seconds, in two phases: wide amplitudes while
//! descending to the observation depth (phase 1), smaller ones there (phase 2). Every step whose
//! estimated wrench says contact records the measured TCP pose; the recording is then thinned by
//! temporal downsampling to the observations registration uses.

use crate::method::config::TrialConfig;
use crate::method::manifold::build::SamplerConfig;
use crate::method::primitives::{
    Descent, Drive, PerturbationState, Probe, SamplingMotion, ScaleSchedule,
};
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
/// descending from the start depth to the observation depth in `phase1_s` (phase 1). The motion
/// does not depend on `t_obs`: the budget only says when it stops, so a longer observation is a
/// shorter one gone on (as a robot given more time would), and the observations of a `t_obs`
/// sweep differ in their budget alone.
pub fn observation_motion(config: &TrialConfig) -> SamplingMotion {
    let mut motion = SamplerConfig::default().motion;
    let r = &config.offset_range;
    motion.schedule.lateral_overtravel_m += r[0].max(r[1]);
    motion.schedule.angular_overtravel_rad += r[3].max(r[4]);
    motion.descent = Descent {
        start_depth_m: config.start_depth_m,
        end_depth_m: config.observe_depth_m,
        speed_m_per_s: (config.observe_depth_m - config.start_depth_m).max(0.0) / config.phase1_s,
    };
    motion
}

/// The observation (IV-C) around `believed` (`base_T_hole`), its perturbation seeded by
/// `perturbation_seed`. It can stop at several budgets: run to the shortest, read what it holds,
/// go on to the next. What it holds at each is what an observation of that budget alone records,
/// bit for bit (the motion does not depend on the budget, [`observation_motion`]). It stops
/// early only if the physics faults (the session keeps the fault).
pub struct ObservationPhase {
    believed: Iso,
    motion: SamplingMotion,
    schedule: ScaleSchedule,
    clearance_m: f64,
    noise: PerturbationState,
    contacts: Vec<Pose6>,
    start_s: f64,
    /// Steps of the motion run so far.
    steps: usize,
    /// Whether the physics faulted: the motion stops for good.
    stopped: bool,
}

impl ObservationPhase {
    /// Starts observing now, in the session's observation phase.
    pub fn start(
        session: &mut Session,
        believed: &Iso,
        config: &TrialConfig,
        clearance_m: f64,
        perturbation_seed: u64,
    ) -> ObservationPhase {
        session.set_phase(Phase::Observe);
        let motion = observation_motion(config);
        let noise = PerturbationState::new(motion.perturbation.clone(), perturbation_seed);
        ObservationPhase {
            believed: *believed,
            schedule: ScaleSchedule {
                before: config.phase1_scale,
                after: config.phase2_scale,
                switch_s: motion.descent.duration_s(),
                widened: None,
            },
            motion,
            clearance_m,
            noise,
            contacts: Vec::new(),
            start_s: session.time_s(),
            steps: 0,
            stopped: false,
        }
    }

    /// Observes until `t_obs_s` after the start (nothing if it is there already), recording the
    /// measured TCP pose at every step whose estimated wrench says contact.
    pub fn run_to(&mut self, session: &mut Session, t_obs_s: f64) {
        let end = Drive::steps_until(t_obs_s, session.dt_s());
        if self.stopped || end <= self.steps {
            return;
        }
        let drive = Drive {
            base_t_hole: self.believed,
            motion: &self.motion,
            schedule: self.schedule,
            clearance_m: self.clearance_m,
            duration_s: t_obs_s,
        };
        let contacts = &mut self.contacts;
        let completed = drive.run_steps(session, &mut self.noise, self.steps..end, |m| {
            if m.contact {
                contacts.push(Pose6::from_iso(&m.tcp));
            }
            ControlFlow::Continue(())
        });
        self.steps = end;
        self.stopped = !completed;
    }

    /// From now on (after phase 1), `probe`'s amplitudes keep phase 1's wide scale, the others
    /// phase 2's (active probing: the widest the fixed primitives move, so within their force and
    /// travel limits).
    pub fn widen(&mut self, probe: Probe) {
        self.schedule.widened = Some(probe);
    }

    /// What has been observed so far, at simulated time `now_s`.
    pub fn observation(&self, now_s: f64) -> Observation {
        Observation {
            contacts: self.contacts.clone(),
            duration_s: now_s - self.start_s,
        }
    }
}
