//! The named random streams, in one place. A campaign's scenario seed gives each trial its seed
//! ([`trial`]); a trial's seed gives each source of randomness its own stream ([`TrialSeeds`]);
//! a manifold build's seed gives each sampling episode its seed ([`episode`]). Every stream is a
//! ChaCha8 generator (rand_chacha) seeded from these values, so a result depends on its seed
//! alone, whatever the thread count, shard or machine.

/// SplitMix64's finaliser (Steele, Lea and Flood 2014): a bijection of u64 that mixes every input
/// bit into every output bit.
fn mix(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// SplitMix64's increment (the golden ratio in 64 bits).
const GOLDEN: u64 = 0x9E37_79B9_7F4A_7C15;

/// The seed of trial `index` of a pair (geometry name and clearance in mm) in a campaign whose
/// scenario seed is `scenario_seed`: the same for every method and observation time, so that the
/// methods meet the same hole offsets.
pub fn trial(scenario_seed: u64, geometry: &str, clearance_mm: f64, index: usize) -> u64 {
    let pair = crc32fast::hash(format!("{geometry}/{clearance_mm}").as_bytes());
    let mut z = scenario_seed ^ (u64::from(pair) << 32) ^ (index as u64).wrapping_mul(GOLDEN);
    for _ in 0..2 {
        z = mix(z.wrapping_add(GOLDEN));
    }
    z
}

/// The seed of sampling episode `episode` of a manifold build seeded `build_seed` (paper IV-B):
/// independent streams whatever the thread that runs the episode.
pub fn episode(build_seed: u64, episode: usize) -> u64 {
    mix(build_seed.wrapping_add((episode as u64 + 1).wrapping_mul(GOLDEN)))
}

/// The streams of one trial, derived from its seed. The offset, perturbation and sensor streams
/// keep the derivations the first campaigns were run with (so their records stay reproducible);
/// one consequence: trial seed n's perturbation stream is trial seed n + 1's sensor stream.
/// Campaign trial seeds come from [`trial`], a SplitMix64 output, and are never adjacent; the
/// registration stream is mixed.
#[derive(Clone, Copy, Debug)]
pub struct TrialSeeds {
    pub trial: u64,
}

impl TrialSeeds {
    /// The true hole offset from the nominal pose (paper V-A: U(-5, 5) mm and deg).
    pub fn offset(&self) -> u64 {
        self.trial ^ 0x6f66_6673_6574
    }

    /// The random perturbation of the observation motion (paper IV-C).
    pub fn perturbation(&self) -> u64 {
        self.trial.wrapping_add(1)
    }

    /// The sensors: encoder and joint-torque noise, torque sensor bias.
    pub fn sensors(&self) -> u64 {
        self.trial
    }

    /// The registration's restarts (their initial poses, paper IV-D), mixed with the seed of the
    /// registration settings so that a scenario can still vary it.
    pub fn registration(&self, config_seed: u64) -> u64 {
        mix(self.trial ^ 0x7265_6769_7374_6572) ^ config_seed
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn episode_seeds_differ_and_are_stable() {
        let a: Vec<u64> = (0..100).map(|e| episode(5, e)).collect();
        let mut sorted = a.clone();
        sorted.sort_unstable();
        sorted.dedup();
        assert_eq!(sorted.len(), 100);
        assert_eq!(a[3], episode(5, 3));
        assert_ne!(episode(5, 3), episode(6, 3));
    }

    #[test]
    fn trial_seeds_depend_on_the_pair_and_the_index_only() {
        assert_eq!(trial(1, "cross", 0.5, 3), trial(1, "cross", 0.5, 3));
        assert_ne!(trial(1, "cross", 0.5, 3), trial(1, "cross", 0.5, 4));
        assert_ne!(trial(1, "cross", 0.5, 3), trial(1, "gear", 0.5, 3));
        assert_ne!(trial(1, "cross", 0.5, 3), trial(1, "cross", 1.0, 3));
        assert_ne!(trial(1, "cross", 0.5, 3), trial(2, "cross", 0.5, 3));
    }

    #[test]
    fn every_stream_of_a_trial_differs_and_follows_the_trial_seed() {
        for seed in [0, 7, trial(1, "gear", 0.1, 3)] {
            let s = TrialSeeds { trial: seed };
            let mut all = vec![s.offset(), s.perturbation(), s.sensors(), s.registration(0)];
            all.sort_unstable();
            all.dedup();
            assert_eq!(all.len(), 4, "trial seed {seed}");
            assert_ne!(s.registration(0), s.registration(1));
            assert_ne!(
                s.registration(0),
                TrialSeeds { trial: seed + 1 }.registration(0)
            );
        }
    }
}
