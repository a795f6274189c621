//! Trials that share their observation (issue 17). A campaign compares its methods on the same
//! draws: every cell of a pair runs trial `i` from the same seed. The direct baseline observes
//! for `direct_t_obs_s` (the paper's 10 s) exactly as the manifold method does at the same
//! `t_obs`, and the manifold method's shorter budgets (6 and 8 s) observe the same motion for
//! less time (`method::observe::observation_motion`): the trials of a seed are one simulation
//! until each one's observation ends, and differ only in when it ends and in what follows
//! (registration, insertion). A campaign runs the longest observation once; each trial goes on
//! from a fork of the cell taken at its own budget (`method::trial::ObservingTrial`), and each record
//! is the one its trial gives alone, bit for bit.

use crate::campaign::records::TrialSpec;
use crate::campaign::scenario::PlannedCell;
use std::collections::HashMap;

/// `trials`, in their order, gathered into the pieces of work a campaign runs: each piece is
/// one trial, or the trials that observe alike but for their budget. They do when they have the
/// same seed, pair and cell parameters, and trial settings that differ only in `t_obs` and after
/// the observation (`TrialConfig::observes_like_but_for_budget`). A trial whose settings are
/// invalid runs alone (its error is its own).
pub fn share_observations(plan: &[PlannedCell], trials: &[TrialSpec]) -> Vec<Vec<TrialSpec>> {
    let alike = |a: &TrialSpec, b: &TrialSpec| {
        let (ca, cb) = (&plan[a.cell], &plan[b.cell]);
        a.seed == b.seed
            && ca.condition.geometry == cb.condition.geometry
            && ca.condition.clearance_mm == cb.condition.clearance_mm
            && ca.params == cb.params
            && ca.config.observes_like_but_for_budget(&cb.config)
    };
    let mut pieces: Vec<Vec<TrialSpec>> = Vec::with_capacity(trials.len());
    let mut by_seed: HashMap<u64, Vec<usize>> = HashMap::new();
    for spec in trials {
        let config = &plan[spec.cell].config;
        // The adaptive and active methods decide while observing: they observe alone.
        if config.ensure_valid().is_ok() && !config.method.stops_itself() {
            let open = by_seed.entry(spec.seed).or_default();
            if let Some(&piece) = open.iter().find(|&&p| alike(&pieces[p][0], spec)) {
                pieces[piece].push(*spec);
                continue;
            }
            open.push(pieces.len());
        }
        pieces.push(vec![*spec]);
    }
    pieces
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::campaign::scenario::Scenario;
    use crate::method::seeds;

    /// Every trial of `s`, cell-major, seeded as a campaign seeds them.
    fn all_trials(s: &Scenario) -> Vec<TrialSpec> {
        let cells = s.cells();
        let specs = cells.iter().enumerate().flat_map(|(c, cell)| {
            (0..s.trials).map(move |t| TrialSpec {
                cell: c,
                trial: t,
                seed: seeds::trial(s.seed, &cell.geometry, cell.clearance_mm, t),
                condition: 0,
            })
        });
        specs.collect()
    }

    fn scenario(extra: &str) -> Scenario {
        Scenario::parse(&format!(
            "name = \"s\"\ntrials = 2\ngeometries = [\"cross\", \"key\"]\nclearances_mm = [0.5]\n\
             t_obs_s = [6.0, 10.0]\nmethods = [\"manifold\", \"direct\"]\ndirect_t_obs_s = 10.0\n{extra}"
        ))
        .expect("scenario")
    }

    /// Labels of the cells of each piece of work with more than one trial.
    fn shared(s: &Scenario) -> Vec<Vec<String>> {
        let cells = s.cells();
        share_observations(&s.plan(), &all_trials(s))
            .into_iter()
            .filter(|p| p.len() > 1)
            .map(|p| {
                p.iter()
                    .map(|t| format!("{} {}", cells[t.cell].label(), t.trial))
                    .collect()
            })
            .collect()
    }

    #[test]
    fn the_trials_of_a_seed_share_one_observation_whatever_their_budget() {
        let s = scenario("");
        let pieces = share_observations(&s.plan(), &all_trials(&s));
        assert_eq!(pieces.iter().map(Vec::len).sum::<usize>(), 12);
        let piece = |g: &str, t: usize| {
            [
                format!("{g} 0.5 mm manifold 6 s {t}"),
                format!("{g} 0.5 mm manifold 10 s {t}"),
                format!("{g} 0.5 mm direct 10 s {t}"),
            ]
        };
        assert_eq!(
            shared(&s),
            [
                piece("cross", 0),
                piece("cross", 1),
                piece("key", 0),
                piece("key", 1)
            ]
        );
        // Different insertion settings still share; different observation settings do not.
        let insertion =
            scenario("[direct.gains.insert]\nstiffness = [655, 655, 4791, 13.7, 13.7, 13.7]\n");
        assert_eq!(shared(&insertion).len(), 4);
        let observation =
            scenario("[direct.gains.observe]\nstiffness = [900, 900, 1500, 5, 5, 5]\n");
        let manifold_only = |g: &str, t: usize| {
            [
                format!("{g} 0.5 mm manifold 6 s {t}"),
                format!("{g} 0.5 mm manifold 10 s {t}"),
            ]
        };
        assert_eq!(
            shared(&observation),
            [
                manifold_only("cross", 0),
                manifold_only("cross", 1),
                manifold_only("key", 0),
                manifold_only("key", 1)
            ]
        );
    }
}
