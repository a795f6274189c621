//! The trials of a campaign, or of one shard of it, generated as they are wanted (issue 47): a
//! campaign is planned in memory proportional to its cells, not its trials (a scenario of 21
//! cells at a million trials each took 2 GB before its first trial when every trial was listed
//! up front).

use super::folder::Shard;
use crate::campaign::records::{TrialSet, TrialSpec, condition_key};
use crate::campaign::scenario::{Condition, Scenario};
use crate::method::seeds;
use std::ops::Range;

/// About how many trials a campaign lists at a time (a round, [`CampaignTrials::round_len`]).
pub const ROUND_TRIALS: usize = 4096;

/// The seed of trial `index` of a cell (see [`seeds::trial`]: the same for every method of a pair).
pub fn trial_seed(scenario_seed: u64, cell: &Condition, index: usize) -> u64 {
    seeds::trial(scenario_seed, &cell.geometry, cell.clearance_mm, index)
}

/// Trial `trial` of the cell numbered `index`, seeded from the scenario's seed.
fn trial_spec(scenario_seed: u64, (index, cell): (usize, &Condition), trial: usize) -> TrialSpec {
    TrialSpec {
        cell: index,
        trial,
        seed: trial_seed(scenario_seed, cell, trial),
        condition: condition_key(&cell.geometry, cell.clearance_mm, cell.method, cell.t_obs_s),
    }
}

/// The trials one shard of a scenario's campaign runs. Trials are numbered cell-major (trial
/// `t` of cell `c` is number `c * trials + t`) and number `n` belongs to shard `n % count`.
pub struct CampaignTrials {
    seed: u64,
    cells: Vec<Condition>,
    per_cell: usize,
    shard: Shard,
}

impl CampaignTrials {
    /// The trials of `shard` of `scenario`'s campaign.
    pub fn of(scenario: &Scenario, shard: Shard) -> Self {
        CampaignTrials {
            seed: scenario.seed,
            cells: scenario.cells(),
            per_cell: scenario.trials,
            shard,
        }
    }

    /// How many cells the scenario has.
    pub fn cells(&self) -> usize {
        self.cells.len()
    }

    /// How many trials each cell asks for (the shard runs some of them).
    pub fn per_cell(&self) -> usize {
        self.per_cell
    }

    /// How many of the trials numbered below `number` the shard holds.
    fn held_below(&self, number: usize) -> usize {
        let Shard { index, count } = self.shard;
        number / count + usize::from(index < number % count)
    }

    /// How many trial numbers a round of a campaign spans ([`Self::round`]): enough for about
    /// [`ROUND_TRIALS`] of the shard's trials, at least one.
    pub fn round_len(&self) -> usize {
        let numbers = ROUND_TRIALS.saturating_mul(self.shard.count) / self.cells.len().max(1);
        numbers.max(1)
    }

    /// How many trials of cell `cell` the shard holds.
    pub fn held_in_cell(&self, cell: usize) -> usize {
        self.held_below((cell + 1) * self.per_cell) - self.held_below(cell * self.per_cell)
    }

    /// The shard's trials numbered `trials` within every cell, trial-major (those numbered
    /// `trials.start` in every cell, then the next): every cell advances together, so a stopped
    /// run holds a like share of each cell.
    pub fn round(&self, trials: Range<usize>) -> impl Iterator<Item = TrialSpec> + '_ {
        let trials = trials.start..trials.end.min(self.per_cell);
        trials.flat_map(move |t| (0..self.cells.len()).filter_map(move |c| self.spec(c, t)))
    }

    /// Every trial of the shard, cell-major.
    pub fn iter(&self) -> impl Iterator<Item = TrialSpec> + '_ {
        (0..self.cells.len())
            .flat_map(move |c| (0..self.per_cell).filter_map(move |t| self.spec(c, t)))
    }
}

impl TrialSet for CampaignTrials {
    fn spec(&self, cell: usize, trial: usize) -> Option<TrialSpec> {
        let condition = self.cells.get(cell).filter(|_| trial < self.per_cell)?;
        self.shard
            .holds(cell * self.per_cell + trial)
            .then(|| trial_spec(self.seed, (cell, condition), trial))
    }

    fn count(&self) -> usize {
        self.held_below(self.cells.len() * self.per_cell)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::BTreeSet;

    fn scenario(trials: usize) -> Scenario {
        Scenario::parse(&format!(
            "name = \"t\"\ntrials = {trials}\ngeometries = [\"cross\", \"key\"]\nclearances_mm = [0.5]\nt_obs_s = [6.0, 8.0]\nmethods = [\"manifold\", \"direct\"]\n"
        ))
        .unwrap()
    }

    #[test]
    fn shards_split_the_trials_exactly_once_and_count_them_without_listing() {
        for per_cell in [1, 5, 7] {
            let s = scenario(per_cell);
            let whole = CampaignTrials::of(&s, Shard::WHOLE);
            assert_eq!(whole.count(), 2 * 3 * per_cell);
            for count in [1, 2, 4, 13, 100] {
                let mut seen = BTreeSet::new();
                for index in 0..count {
                    let part = CampaignTrials::of(&s, Shard { index, count });
                    let listed: Vec<TrialSpec> = part.iter().collect();
                    assert_eq!(listed.len(), part.count());
                    let mut by_round: Vec<TrialSpec> = part.round(0..per_cell).collect();
                    by_round.sort_by_key(|t| (t.cell, t.trial));
                    assert!(
                        listed.iter().zip(&by_round).all(|(a, b)| {
                            (a.cell, a.trial, a.seed) == (b.cell, b.trial, b.seed)
                        })
                    );
                    for c in 0..part.cells() {
                        let in_cell = listed.iter().filter(|t| t.cell == c).count();
                        assert_eq!(part.held_in_cell(c), in_cell);
                    }
                    for t in listed {
                        assert!(seen.insert((t.cell, t.trial)));
                    }
                }
                assert_eq!(seen.len(), whole.count());
            }
        }
    }

    #[test]
    fn a_million_trials_a_cell_are_planned_without_listing_them() {
        let s = scenario(crate::campaign::scenario::MAX_TRIALS_PER_CELL);
        let part = CampaignTrials::of(&s, Shard { index: 3, count: 7 });
        assert_eq!(part.count(), (6_000_000 - 3usize).div_ceil(7));
        let held = |c: usize, t: usize| (c * 1_000_000 + t) % 7 == 3;
        for (c, t) in [(5, 999_999), (5, 999_998), (0, 3), (0, 4), (2, 17)] {
            assert_eq!(part.spec(c, t).is_some(), held(c, t), "cell {c} trial {t}");
        }
        assert!(part.spec(6, 0).is_none() && part.spec(0, 1_000_000).is_none());
        let last_ten = (0..6).flat_map(|c| (999_990..1_000_000).map(move |t| (c, t)));
        let wanted = last_ten.filter(|&(c, t)| held(c, t)).count();
        assert_eq!(part.round(999_990..2_000_000).count(), wanted);
    }

    #[test]
    fn seeds_are_shared_across_methods_and_differ_across_pairs_and_trials() {
        let s = scenario(3);
        let cells = s.cells();
        let seed = |c: usize, t: usize| trial_seed(s.seed, &cells[c], t);
        assert_eq!(seed(0, 1), seed(2, 1)); // cross manifold 6 s vs cross direct
        assert_ne!(seed(0, 1), seed(0, 2));
        assert_ne!(seed(0, 1), seed(3, 1)); // key
    }
}
