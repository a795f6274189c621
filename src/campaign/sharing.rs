//! Trials that share their observation (issue 17). A campaign compares its methods on the same
//! draws: every cell of a pair runs trial `i` from the same seed. The direct baseline observes
//! for `direct_t_obs_s` (the paper's 10 s) exactly as the manifold method does at the same
//! `t_obs`, so the two trials are one simulation until the observation ends; they differ only in
//! what follows (registration, insertion). A campaign runs that observation once and each trial
//! goes on from a fork of the cell (`method::trial::Observed::fork`), and each record is the one
//! its trial gives alone, bit for bit.

use crate::campaign::records::TrialSpec;
use crate::campaign::scenario::Scenario;
use std::collections::HashMap;

/// `trials`, in their order, gathered into the pieces of work a campaign runs: each piece is
/// one trial, or the trials that observe alike. Trials observe alike when they have the same
/// seed, pair and cell parameters, and trial settings that differ only after the observation
/// (`TrialConfig::observes_like`). A trial whose settings are invalid runs alone (its error
/// is its own).
pub fn share_observations(scenario: &Scenario, trials: &[TrialSpec]) -> Vec<Vec<TrialSpec>> {
    let cells = scenario.cells();
    let configs: Vec<_> = cells.iter().map(|c| scenario.trial_config(c)).collect();
    let params: Vec<_> = cells.iter().map(|c| scenario.cell_params_for(c)).collect();
    let alike = |a: &TrialSpec, b: &TrialSpec| {
        let (ca, cb) = (&cells[a.cell], &cells[b.cell]);
        a.seed == b.seed
            && ca.geometry == cb.geometry
            && ca.clearance_mm == cb.clearance_mm
            && params[a.cell] == params[b.cell]
            && configs[a.cell].observes_like(&configs[b.cell])
    };
    let mut pieces: Vec<Vec<TrialSpec>> = Vec::with_capacity(trials.len());
    let mut by_seed: HashMap<u64, Vec<usize>> = HashMap::new();
    for spec in trials {
        if configs[spec.cell].ensure_valid().is_ok() {
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
    use crate::method::seeds;

    /// Every trial of `s`, cell-major, seeded as a campaign seeds them.
    fn all_trials(s: &Scenario) -> Vec<TrialSpec> {
        let cells = s.cells();
        let specs = cells.iter().enumerate().flat_map(|(c, cell)| {
            (0..s.trials).map(move |t| TrialSpec {
                cell: c,
                trial: t,
                seed: seeds::trial(s.seed, &cell.geometry, cell.clearance_mm, t),
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
        share_observations(s, &all_trials(s))
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
    fn the_direct_baseline_shares_the_observation_of_the_manifold_method_at_its_t_obs() {
        let s = scenario("");
        let pieces = share_observations(&s, &all_trials(&s));
        assert_eq!(pieces.iter().map(Vec::len).sum::<usize>(), 12);
        assert_eq!(
            shared(&s),
            [
                ["cross 0.5 mm manifold 10 s 0", "cross 0.5 mm direct 10 s 0"],
                ["cross 0.5 mm manifold 10 s 1", "cross 0.5 mm direct 10 s 1"],
                ["key 0.5 mm manifold 10 s 0", "key 0.5 mm direct 10 s 0"],
                ["key 0.5 mm manifold 10 s 1", "key 0.5 mm direct 10 s 1"],
            ]
        );
        // Different insertion settings still share; different observation settings do not.
        let insertion =
            scenario("[direct.gains.insert]\nstiffness = [655, 655, 4791, 13.7, 13.7, 13.7]\n");
        assert_eq!(shared(&insertion).len(), 4);
        let observation =
            scenario("[direct.gains.observe]\nstiffness = [900, 900, 1500, 5, 5, 5]\n");
        assert!(shared(&observation).is_empty());
    }
}
