//! The correspondences of Algorithm 1 (lines 6-9, Section IV-D), shared by both solvers.
//!
//!
//! Both solvers search exactly (Lines 6 and 8 are true nearest neighbours), warm-started from the
//! previous iteration through [`NeighbourCache`]: the answer is read from the cache when the cache
//! proves it, found by a tree search otherwise.
//!

use super::min_chunk;
use crate::method::manifold::{
    Manifold, NeighbourCache, Resolution, ScaledIndex, neighbourhood_normal, squared_distance,
};
use crate::pose::{Iso, Pose6};
use rayon::prelude::*;
use std::num::NonZero;
use std::sync::OnceLock;

/// One correspondence of Algorithm 1 (lines 6-9), all vectors in scaled coordinates.
pub(super) struct Correspondence {
    /// `delta_i`, the observation-to-reference misalignment as a 6-vector.
    pub(super) delta: [f64; 6],
    /// `D_i = (h,t_T_p,i)⁻¹ ⊗ H_T_p,i` and the observation `h,t_T_p,i` (for the Jacobian).
    pub(super) relative: Iso,
    pub(super) observation: Iso,
    pub(super) n_q: [f64; 6],
    pub(super) n_p: [f64; 6],
}

pub(super) fn dot(a: &[f64; 6], b: &[f64; 6]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// Spare candidates kept in each observation's neighbour cache.
pub(super) const NEIGHBOUR_SPARE: usize = 16;

/// Search state carried from one iteration to the next: warm-started correspondences. The caches
/// only shorten the searches; every answer is the exact nearest neighbour (see
/// [`crate::method::manifold::NeighbourCache`]).
pub(super) struct SearchState {
    pub(super) resolution: Resolution,
    /// Per observation: its nearest manifold points at its last tree search.
    pub(super) reference: Vec<Option<NeighbourCache>>,
    /// Per observation: its nearest observations when `epoch` was taken.
    pub(super) neighbours: Vec<Option<NeighbourCache>>,
    /// Observation positions (scaled) when the neighbour caches were made.
    pub(super) epoch: Vec<[f64; 6]>,
    /// Observations whose neighbour cache could not answer at the last pass.
    pub(super) misses: usize,
}

impl SearchState {
    pub(super) fn new(n: usize, resolution: Resolution) -> Self {
        SearchState {
            resolution,
            reference: vec![None; n],
            neighbours: vec![None; n],
            epoch: Vec::new(),
            misses: 0,
        }
    }
}

/// Lines 6-9 for every observation (in parallel; deterministic whatever the thread count).
pub(super) fn correspondences(
    manifold: &Manifold,
    obs_h: &[Iso],
    k: usize,
    state: &mut SearchState,
) -> Vec<Correspondence> {
    let metric = manifold.meta.metric;
    let n = obs_h.len();
    let scaled: Vec<[f64; 6]> = obs_h
        .iter()
        .map(|o| metric.scaled(&Pose6::from_iso(o)))
        .collect();
    // Neighbour caches are renewed together when many missed (or at the start).
    let renew = state.epoch.len() != n || state.misses * 8 > n;
    let (spread, max_spread) = if renew {
        (Vec::new(), 0.0)
    } else {
        displacement_spread(&scaled, &state.epoch)
    };
    let obs_index: OnceLock<ScaledIndex> = OnceLock::new();
    let index = || obs_index.get_or_init(|| ScaledIndex::new(&scaled));
    let k_nz = NonZero::new(k).expect("k >= 7");
    let m = NonZero::new(k + NEIGHBOUR_SPARE).expect("m > 0");
    let resolution = state.resolution;
    let results: Vec<(Correspondence, Option<NeighbourCache>, bool)> = state
        .reference
        .par_iter_mut()
        .zip(state.neighbours.par_iter())
        .with_min_len(min_chunk())
        .enumerate()
        .map(|(i, (ref_cache, nb_cache))| {
            let (o, s) = (&obs_h[i], &scaled[i]);
            // Line 6: nearest reference point and its normal.
            let j = manifold.nearest_cached(resolution, s, ref_cache);
            // Line 7: point-to-point misalignment.
            let relative = o.inverse() * manifold.transform(j);
            let delta = metric.scaled(&Pose6::from_iso(&relative));
            // Line 8: the k nearest observations.
            let (mut neighbours, fresh, miss) = if renew {
                let c = index().cache(s, m, None, None);
                (c.candidates()[..k].to_vec(), Some(c), false)
            } else {
                match nb_cache
                    .as_ref()
                    .and_then(|c| c.k_nearest(&scaled, s, k, spread[i] + max_spread))
                {
                    Some(nb) => (nb, None, false),
                    None => (index().nearest_k(s, k_nz), None, true),
                }
            };
            // Line 9: their normal (summed in index order, so the bits do not depend on how
            // the neighbours were found).
            neighbours.sort_unstable();
            let n_p = neighbourhood_normal(neighbours.iter().map(|&b| &scaled[b]));
            let c = Correspondence {
                delta,
                relative,
                observation: *o,
                n_q: manifold.normals[j],
                n_p,
            };
            (c, fresh, miss)
        })
        .collect();
    state.misses = results.iter().filter(|r| r.2).count();
    let (cs, fresh): (Vec<Correspondence>, Vec<Option<NeighbourCache>>) =
        results.into_iter().map(|(c, fresh, _)| (c, fresh)).unzip();
    if renew {
        state.epoch = scaled;
        state.neighbours = fresh;
    }
    cs
}

/// How far each observation has moved since the neighbour caches' epoch, apart from the mean
/// move, and the largest of those (scaled coordinates). Between renewals the distance between
/// two observations can only have shrunk by the difference of their displacements: at most
/// |d_i - c| + max_j |d_j - c| for observation i, with c the mean displacement (small: the
/// update moves them nearly as one).
pub(super) fn displacement_spread(scaled: &[[f64; 6]], epoch: &[[f64; 6]]) -> (Vec<f64>, f64) {
    let displacement: Vec<[f64; 6]> = scaled
        .iter()
        .zip(epoch)
        .map(|(a, b)| std::array::from_fn(|k| a[k] - b[k]))
        .collect();
    let mean: [f64; 6] = std::array::from_fn(|k| {
        displacement.iter().map(|d| d[k]).sum::<f64>() / displacement.len().max(1) as f64
    });
    let spread: Vec<f64> = displacement
        .iter()
        .map(|d| squared_distance(d, &mean).sqrt())
        .collect();
    let max_spread = spread.iter().copied().fold(0.0, f64::max);
    (spread, max_spread)
}

/// RMS of the residuals `n_q · delta` and `n_p · delta`, mm-equivalents.
pub(super) fn rms_residual(cs: &[Correspondence]) -> f64 {
    let sum: f64 = cs
        .iter()
        .map(|c| dot(&c.delta, &c.n_q).powi(2) + dot(&c.delta, &c.n_p).powi(2))
        .sum();
    (sum / (2 * cs.len()).max(1) as f64).sqrt()
}
