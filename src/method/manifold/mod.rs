//! The reference contact manifold (paper Sections IV-B and IV-D): contact poses `hole_T_peg` with
//! their local normals, a k-d tree over them, and where they came from.
//!
//! The manifold lives in the 6-D coordinate space of [`crate::pose::PoseMetric`] (positions in mm,
//! angles in degrees times `mm_per_deg`). A contact manifold is a hypersurface of that space (the
//! boundary of the peg's free configurations), so each point has one normal: the singular vector of
//! the smallest singular value of the covariance of its `k` nearest neighbours (paper IV-D). Normals
//! are unit vectors in scaled coordinates; their sign is fixed so that the largest-magnitude
//! component is positive (registration only uses `(d . n) n`, which does not depend on it).
//!
//! Files: [`self::file`] (versioned binary with a checksum, and CSV). Test data: [`synthetic`].

pub mod build;
pub mod cache;
pub mod file;
pub mod geometric;
pub mod plot;
pub mod synthetic;

use crate::error::{Error, Result};
use crate::pose::{Iso, Pose6, PoseMetric};
use crate::twin::geometry::PartPair;
use kiddo::SquaredEuclidean;
use kiddo::immutable::float::kdtree::ImmutableKdTree;
use nalgebra::{Matrix6, SymmetricEigen, Vector6};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::num::NonZero;

/// Default number of neighbours for normals (paper IV-D leaves it open; 12 is twice the dimension).
pub const DEFAULT_NORMAL_K: usize = 12;

/// Where a manifold came from and in which units it is written.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ManifoldMeta {
    /// Geometry name (`cross`, `gear`, a mesh file, `synthetic-square`, ...).
    pub geometry: String,
    /// Diametral clearance it was made with, m (absent when unknown, e.g. imported).
    pub clearance_m: Option<f64>,
    /// Units of the stored poses: always `"m, rad"`.
    pub units: String,
    /// The 6-D metric the normals were computed in.
    pub metric: PoseMetric,
    /// Neighbours used for each normal.
    pub normal_k: usize,
    /// How it was made (generator and its parameters, or the imported file).
    pub source: String,
    /// Seed of the generator, if it had one.
    pub seed: Option<u64>,
}

/// The most poses a manifold may hold (built, synthesised or imported): 100 times the paper's.
pub const MAX_POINTS: usize = 5_000_000;

/// Units written into every manifold.
pub const UNITS: &str = "m, rad";

/// A nearest-neighbour index over points in scaled coordinates.
///
/// kiddo's immutable tree splits its dimensions in turn, whatever their spread. Contact poses are
/// far from isotropic in the scaled space (x, y over tenths of a millimetre, z over many
/// millimetres, angles over degrees), so a plain tree cuts thin axes as often as wide ones and
/// queries visit many more leaves. The index therefore stores the points in a rotated frame, found
/// once from their covariance, in which every axis has the same variance. A rotation preserves
/// Euclidean distances, so neighbours and distances are exactly those of the scaled space.
pub struct ScaledIndex {
    rotation: Matrix6<f64>,
    tree: ImmutableKdTree<f64, u32, 6, 64>,
}

impl ScaledIndex {
    /// Index `points` (scaled coordinates).
    pub fn new(points: &[[f64; 6]]) -> Self {
        let rotation = spread_equalising_rotation(&covariance(points.iter()));
        Self::with_rotation(points, rotation)
    }

    /// Index `points` with a plain kiddo tree over the scaled coordinates (for comparison).
    pub fn unrotated(points: &[[f64; 6]]) -> Self {
        Self::with_rotation(points, Matrix6::identity())
    }

    fn with_rotation(points: &[[f64; 6]], rotation: Matrix6<f64>) -> Self {
        let rotated: Vec<[f64; 6]> = points.iter().map(|p| rotate(&rotation, p)).collect();
        ScaledIndex {
            rotation,
            tree: ImmutableKdTree::new_from_slice(&rotated),
        }
    }

    /// Index and squared distance of the nearest point to `q`.
    pub fn nearest(&self, q: &[f64; 6]) -> (usize, f64) {
        let n = self
            .tree
            .nearest_one::<SquaredEuclidean>(&rotate(&self.rotation, q));
        (n.item as usize, n.distance)
    }

    /// A cache of the `m` nearest points to `q`; `ids` maps this index's items to the indices
    /// the cache should hold (identity when `None`). `within`, when known, bounds the distance of
    /// the `m`-th nearest point from above (scaled units): the search then skips the subtrees
    /// beyond it from the start, and finds the same points (it searches again unbounded if the
    /// bound proves short, so a wrong bound costs time, never an answer).
    pub fn cache(
        &self,
        q: &[f64; 6],
        m: NonZero<usize>,
        ids: Option<&[usize]>,
        within: Option<f64>,
    ) -> NeighbourCache {
        let rotated = rotate(&self.rotation, q);
        let found = within
            .map(|r| {
                // Wide of the rounding of the rotated coordinates (relative 1e-15).
                let reach = r * (1.0 + 1e-9) + 1e-12;
                self.tree
                    .nearest_n_within::<SquaredEuclidean>(&rotated, reach * reach, m, true)
            })
            .filter(|found| found.len() == m.get())
            .unwrap_or_else(|| self.tree.nearest_n::<SquaredEuclidean>(&rotated, m));
        let radius = found.last().map_or(0.0, |n| n.distance.sqrt());
        // A cache that holds every point is exact whatever the motion.
        let radius = if found.len() < m.get() {
            f64::INFINITY
        } else {
            radius
        };
        NeighbourCache {
            query: *q,
            candidates: found
                .iter()
                .map(|n| ids.map_or(n.item as usize, |ids| ids[n.item as usize]))
                .collect(),
            radius,
        }
    }

    /// Indices of the `k` nearest points to `q` (nearest first).
    pub fn nearest_k(&self, q: &[f64; 6], k: NonZero<usize>) -> Vec<usize> {
        self.tree
            .nearest_n::<SquaredEuclidean>(&rotate(&self.rotation, q), k)
            .into_iter()
            .map(|n| n.item as usize)
            .collect()
    }
}

/// The `m` nearest neighbours of a query, kept so that later queries near it can be answered
/// without a tree search (warm-started correspondences).
///
/// Every point not in `candidates` was at least `radius` from `query`. If the distance between
/// the query and any such point has since shrunk by at most `slack`, it is now at least
/// `radius - slack` away; so when the k-th nearest candidate is closer than that, the k nearest
/// candidates are exactly the k nearest points. For fixed points, `slack` is how far the query
/// moved ([`NeighbourCache::moved`]); for points that move too, it also bounds their motion
/// relative to the query's.
#[derive(Clone, Debug)]
pub struct NeighbourCache {
    query: [f64; 6],
    candidates: Vec<usize>,
    radius: f64,
}

impl NeighbourCache {
    /// How far `q` is from the query the cache was made for.
    pub fn moved(&self, q: &[f64; 6]) -> f64 {
        squared_distance(q, &self.query).sqrt()
    }

    /// The distance from `q` of the farthest cached point (indices into `points`).
    pub fn farthest(&self, points: &[[f64; 6]], q: &[f64; 6]) -> f64 {
        self.candidates
            .iter()
            .map(|&i| squared_distance(q, &points[i]))
            .fold(0.0, f64::max)
            .sqrt()
    }

    /// The cached points, nearest to the cached query first.
    pub fn candidates(&self) -> &[usize] {
        &self.candidates
    }

    /// The `k` nearest points to `q` (indices into `points`, nearest first) if the cache
    /// guarantees them, `None` otherwise.
    pub fn k_nearest(
        &self,
        points: &[[f64; 6]],
        q: &[f64; 6],
        k: usize,
        slack: f64,
    ) -> Option<Vec<usize>> {
        if self.candidates.len() <= k {
            return None;
        }
        let mut d: Vec<(f64, usize)> = self
            .candidates
            .iter()
            .map(|&i| (squared_distance(q, &points[i]), i))
            .collect();
        d.select_nth_unstable_by(k - 1, |a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        let kth = d[k - 1].0.sqrt();
        if kth * (1.0 + 1e-12) >= self.radius - slack {
            return None;
        }
        let mut best = d[..k].to_vec();
        best.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        Some(best.into_iter().map(|(_, i)| i).collect())
    }
}

fn rotate(r: &Matrix6<f64>, p: &[f64; 6]) -> [f64; 6] {
    let v = r * Vector6::from_column_slice(p);
    v.into()
}

/// Covariance (mean-centred) of 6-D points.
fn covariance<'a>(points: impl Iterator<Item = &'a [f64; 6]> + Clone) -> Matrix6<f64> {
    let mut n = 0.0;
    let mut mean = Vector6::zeros();
    for p in points.clone() {
        mean += Vector6::from_column_slice(p);
        n += 1.0;
    }
    if n == 0.0 {
        return Matrix6::zeros();
    }
    mean /= n;
    let mut cov = Matrix6::zeros();
    for p in points {
        let d = Vector6::from_column_slice(p) - mean;
        cov += d * d.transpose();
    }
    cov / n
}

/// An orthogonal matrix `Q` such that `Q C Qᵀ` has equal diagonal entries: principal axes first,
/// then plane rotations that move variance from the widest axis to the narrowest, setting one
/// axis to the mean variance at each step (n - 1 steps).
fn spread_equalising_rotation(cov: &Matrix6<f64>) -> Matrix6<f64> {
    let eig = SymmetricEigen::new(*cov);
    let mut q = eig.eigenvectors.transpose();
    let mut c = q * cov * q.transpose();
    let target = c.trace() / 6.0;
    let mut done = [false; 6];
    for _ in 0..5 {
        let open: Vec<usize> = (0..6).filter(|&i| !done[i]).collect();
        let (Some(&i), Some(&j)) = (
            open.iter()
                .max_by(|a, b| c[(**a, **a)].total_cmp(&c[(**b, **b)])),
            open.iter()
                .min_by(|a, b| c[(**a, **a)].total_cmp(&c[(**b, **b)])),
        ) else {
            break;
        };
        let (a, b, e) = (c[(i, i)], c[(j, j)], c[(i, j)]);
        if a - b <= 1e-12 * target.abs().max(f64::MIN_POSITIVE) {
            break;
        }
        // a cos²t + b sin²t + e sin2t = target  <=>  R cos(2t - phi) = target - (a + b)/2.
        let half = 0.5 * (a - b);
        let r = half.hypot(e);
        let phi = e.atan2(half);
        let t = 0.5 * (phi + ((target - 0.5 * (a + b)) / r).clamp(-1.0, 1.0).acos());
        let mut g = Matrix6::identity();
        g[(i, i)] = t.cos();
        g[(i, j)] = t.sin();
        g[(j, i)] = -t.sin();
        g[(j, j)] = t.cos();
        q = g * q;
        c = g * c * g.transpose();
        done[i] = true;
    }
    q
}

/// The unit normal of a neighbourhood: the eigenvector of the smallest eigenvalue of its
/// covariance (equal to the singular vector of the smallest singular value, paper IV-D), with the
/// largest-magnitude component made positive.
pub fn neighbourhood_normal<'a>(
    neighbours: impl Iterator<Item = &'a [f64; 6]> + Clone,
) -> [f64; 6] {
    let eig = SymmetricEigen::new(covariance(neighbours));
    let (imin, _) = eig
        .eigenvalues
        .iter()
        .enumerate()
        .min_by(|a, b| a.1.total_cmp(b.1))
        .expect("six eigenvalues");
    let mut n: Vector6<f64> = eig.eigenvectors.column(imin).into_owned();
    let big = n.iamax();
    if n[big] < 0.0 {
        n = -n;
    }
    n.into()
}

/// Normals of every point of a cloud from its `k` nearest neighbours, computed in parallel; the
/// result does not depend on the thread count. The neighbours come from a transient f32 tree with
/// 128-point leaves over the index's rotated frame (1.5 x faster for these all-points searches than
/// the f64 query tree); f32 rounding can only swap neighbours tied to a few nanometres, which
/// does not change a normal.
pub fn cloud_normals(points: &[[f64; 6]], index: &ScaledIndex, k: usize) -> Vec<[f64; 6]> {
    let k = NonZero::new(k.max(1)).expect("k >= 1");
    let rotated: Vec<[f32; 6]> = points
        .iter()
        .map(|p| {
            let r = rotate(&index.rotation, p);
            std::array::from_fn(|i| r[i] as f32)
        })
        .collect();
    let tree: ImmutableKdTree<f32, u32, 6, 128> = ImmutableKdTree::new_from_slice(&rotated);
    rotated
        .par_iter()
        .map(|q| {
            let nb = tree.nearest_n_within::<SquaredEuclidean>(q, f32::INFINITY, k, false);
            let mut idx: Vec<usize> = nb.iter().map(|n| n.item as usize).collect();
            idx.sort_unstable();
            neighbourhood_normal(idx.iter().map(|&i| &points[i]))
        })
        .collect()
}

/// Manifold points kept in a correspondence cache: at full resolution, where steps are small and
/// a larger cache is reused for many iterations; at the coarse level, where steps are large and
/// caches are soon renewed.
const REFERENCE_CACHE_SIZE: NonZero<usize> = NonZero::new(16).unwrap();
const COARSE_CACHE_SIZE: NonZero<usize> = NonZero::new(4).unwrap();
/// The coarse level holds every `COARSE_STRIDE`-th point ...
const COARSE_STRIDE: usize = 64;
/// ... when the manifold has at least this many points.
const COARSE_MIN_POINTS: usize = 32_000;

/// Which points a nearest-neighbour search considers.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Resolution {
    /// Every 64th point (all points for small manifolds): cheap far from the
    /// manifold, for the first iterations of a coarse-to-fine solver.
    Coarse,
    /// Every point.
    Full,
}

/// A subset of the manifold with its own index (`ids` are indices into the manifold).
struct Subset {
    ids: Vec<usize>,
    index: ScaledIndex,
}

/// A reference contact manifold: poses, normals, index, metadata.
pub struct Manifold {
    pub meta: ManifoldMeta,
    /// Contact poses `hole_T_peg`, m and rad.
    pub points: Vec<Pose6>,
    /// Unit normals in scaled coordinates, one per point.
    pub normals: Vec<[f64; 6]>,
    scaled: Vec<[f64; 6]>,
    transforms: Vec<Iso>,
    index: ScaledIndex,
    coarse: Option<Subset>,
}

/// The coarse level of a manifold of `scaled` points, if it is large enough to need one.
fn coarse_subset(scaled: &[[f64; 6]]) -> Option<Subset> {
    (scaled.len() >= COARSE_MIN_POINTS).then(|| {
        let ids: Vec<usize> = (0..scaled.len()).step_by(COARSE_STRIDE).collect();
        let pts: Vec<[f64; 6]> = ids.iter().map(|&i| scaled[i]).collect();
        Subset {
            ids,
            index: ScaledIndex::new(&pts),
        }
    })
}

impl Manifold {
    /// Checks that this reference manifold was made for `pair` (same geometry, same clearance);
    /// `source` names the file in the error.
    pub fn check_made_for(&self, pair: &PartPair, source: &std::path::Path) -> Result<()> {
        let same_clearance = self
            .meta
            .clearance_m
            .is_some_and(|c| (c - pair.clearance_m).abs() < 1e-9);
        if self.meta.geometry == pair.name && same_clearance {
            return Ok(());
        }
        let made_at = self
            .meta
            .clearance_m
            .map_or("unknown".into(), |c| format!("{}", c * 1e3));
        Err(Error::file(
            source,
            format!(
                "this manifold was made for geometry '{}' at {made_at} mm clearance; the trial asks for '{}' at {} mm",
                self.meta.geometry,
                pair.name,
                pair.clearance_mm()
            ),
        ))
    }

    /// A manifold from poses; normals are computed with `meta.normal_k` neighbours.
    pub fn from_points(points: Vec<Pose6>, meta: ManifoldMeta) -> Result<Self> {
        Self::build(points, None, meta)
    }

    /// A manifold from poses and their precomputed normals (read from a file).
    pub fn with_normals(
        points: Vec<Pose6>,
        normals: Vec<[f64; 6]>,
        meta: ManifoldMeta,
    ) -> Result<Self> {
        Self::build(points, Some(normals), meta)
    }

    fn build(
        points: Vec<Pose6>,
        normals: Option<Vec<[f64; 6]>>,
        meta: ManifoldMeta,
    ) -> Result<Self> {
        meta.metric.ensure_valid()?;
        check_points(&points, meta.normal_k)?;
        if let Some(n) = normals.as_ref().filter(|n| n.len() != points.len()) {
            return Err(Error::Input(format!(
                "manifold has {} points but {} normals",
                points.len(),
                n.len()
            )));
        }
        if let Some(n) = &normals {
            check_normals(n)?;
        }
        let scaled: Vec<[f64; 6]> = points.iter().map(|p| meta.metric.scaled(p)).collect();
        let index = ScaledIndex::new(&scaled);
        let normals = normals.unwrap_or_else(|| cloud_normals(&scaled, &index, meta.normal_k));
        Ok(Manifold {
            coarse: coarse_subset(&scaled),
            transforms: points.iter().map(Pose6::to_iso).collect(),
            meta,
            points,
            normals,
            scaled,
            index,
        })
    }

    /// Number of contact poses.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// Whether the manifold is empty (never true for a constructed manifold).
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// Point `i` as a rigid transform `hole_T_peg`.
    pub fn transform(&self, i: usize) -> &Iso {
        &self.transforms[i]
    }

    /// Index of the manifold point nearest to `q` (scaled coordinates) at a resolution, answered
    /// from `cache` when it guarantees the answer, else by a tree search that refreshes the cache.
    pub fn nearest_cached(
        &self,
        resolution: Resolution,
        q: &[f64; 6],
        cache: &mut Option<NeighbourCache>,
    ) -> usize {
        if let Some(hit) = cache
            .as_ref()
            .and_then(|c| c.k_nearest(&self.scaled, q, 1, c.moved(q)))
        {
            return hit[0];
        }
        // The old cache's points are still there: the farthest of them from `q` bounds the new
        // search (where the old cache was as large as the new one will be).
        let farthest = |m: NonZero<usize>| {
            cache
                .as_ref()
                .filter(|c| c.candidates.len() >= m.get())
                .map(|c| c.farthest(&self.scaled, q))
        };
        let fresh = match (resolution, &self.coarse) {
            (Resolution::Coarse, Some(c)) => c.index.cache(
                q,
                COARSE_CACHE_SIZE,
                Some(&c.ids),
                farthest(COARSE_CACHE_SIZE),
            ),
            _ => self.index.cache(
                q,
                REFERENCE_CACHE_SIZE,
                None,
                farthest(REFERENCE_CACHE_SIZE),
            ),
        };
        let nearest = fresh.candidates[0];
        *cache = Some(fresh);
        nearest
    }

    /// Per-axis minimum and maximum of the poses (m, rad), for coverage reports.
    pub fn ranges(&self) -> [[f64; 2]; 6] {
        let mut r = [[f64::INFINITY, f64::NEG_INFINITY]; 6];
        for p in &self.points {
            for (a, v) in r.iter_mut().zip(p.0) {
                a[0] = a[0].min(v);
                a[1] = a[1].max(v);
            }
        }
        r
    }
}

/// Squared Euclidean distance of two points in scaled coordinates.
pub fn squared_distance(a: &[f64; 6], b: &[f64; 6]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum()
}

fn check_points(points: &[Pose6], k: usize) -> Result<()> {
    if k < 7 {
        return Err(Error::Input(format!(
            "normal_k = {k}: a normal in 6-D needs at least 7 neighbours"
        )));
    }
    if points.len() < k {
        return Err(Error::Input(format!(
            "manifold has {} points, fewer than the {k} neighbours each normal needs",
            points.len()
        )));
    }
    if points.len() > MAX_POINTS {
        return Err(Error::Input(format!(
            "manifold has {} points; at most {MAX_POINTS} are supported",
            points.len()
        )));
    }
    for (i, p) in points.iter().enumerate() {
        p.ensure_plausible(&format!("manifold point {i}"))?;
    }
    let distinct: std::collections::BTreeSet<[u64; 6]> = points
        .iter()
        .map(|p| p.0.map(|v| (v + 0.0).to_bits()))
        .collect();
    if distinct.len() < k {
        return Err(Error::Input(format!(
            "manifold has {} points but only {} distinct ones (repeated rows?), fewer than the \
             {k} neighbours each normal needs",
            points.len(),
            distinct.len()
        )));
    }
    Ok(())
}

/// How far from 1 the length of a normal read from a file may be (CSV rounding).
pub const NORMAL_LENGTH_TOLERANCE: f64 = 1e-3;

/// Normals read from a file must be unit vectors (NaN or zero normals give confident nonsense).
fn check_normals(normals: &[[f64; 6]]) -> Result<()> {
    for (i, n) in normals.iter().enumerate() {
        let norm = n.iter().map(|v| v * v).sum::<f64>().sqrt();
        if norm.is_nan() || (norm - 1.0).abs() > NORMAL_LENGTH_TOLERANCE {
            return Err(Error::Input(format!(
                "manifold normal {i} has length {norm}: expected a unit vector (recompute the normals: import the poses without them)"
            )));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn equalising_rotation_is_orthogonal_and_flattens_variances() {
        let mut c = Matrix6::from_diagonal(&Vector6::new(100.0, 0.01, 4.0, 0.2, 9.0, 1.0));
        c[(0, 2)] = 3.0;
        c[(2, 0)] = 3.0;
        let q = spread_equalising_rotation(&c);
        assert!((q * q.transpose() - Matrix6::identity()).norm() < 1e-10);
        let r = q * c * q.transpose();
        let mean = c.trace() / 6.0;
        for i in 0..6 {
            assert!((r[(i, i)] - mean).abs() < 1e-9 * mean, "{r}");
        }
    }

    #[test]
    fn normal_of_a_hyperplane_is_its_normal() {
        // Points on the hyperplane x0 + x1 = 0 (any other coordinates).
        let pts: Vec<[f64; 6]> = (0..40)
            .map(|i| {
                let t = i as f64;
                let a = (t * 0.37).sin();
                [
                    a,
                    -a,
                    (t * 0.11).cos(),
                    (t * 0.23).sin(),
                    t * 0.01,
                    (t * 0.7).cos(),
                ]
            })
            .collect();
        let n = neighbourhood_normal(pts.iter());
        let s = std::f64::consts::FRAC_1_SQRT_2;
        assert!((n[0] - s).abs() < 1e-9 && (n[1] - s).abs() < 1e-9, "{n:?}");
    }

    /// `n` points spread like contact poses in scaled coordinates: tenths along x and y, tens
    /// along z, units along the angles.
    fn anisotropic_cloud(n: usize) -> Vec<[f64; 6]> {
        (0..n)
            .map(|i| {
                let t = i as f64;
                [
                    0.2 * (t * 0.731).sin(),
                    0.2 * (t * 0.377).cos(),
                    10.0 * (t * 0.0113).sin(),
                    2.0 * (t * 0.517).sin(),
                    2.0 * (t * 0.291).cos(),
                    (t * 0.173).sin(),
                ]
            })
            .collect()
    }

    #[test]
    fn a_bounded_cache_search_finds_what_the_unbounded_one_finds() {
        let pts = anisotropic_cloud(3000);
        let index = ScaledIndex::new(&pts);
        let m = NonZero::new(16).expect("16");
        for q in pts.iter().step_by(97) {
            let moved = [
                q[0] + 0.02,
                q[1] - 0.01,
                q[2] + 0.3,
                q[3],
                q[4] - 0.05,
                q[5],
            ];
            let old = index.cache(q, m, None, None);
            let plain = index.cache(&moved, m, None, None);
            // The old cache's farthest point bounds the new search; a bound too short to hold
            // `m` points falls back to the unbounded search.
            for within in [old.farthest(&pts, &moved), 0.5 * plain.radius] {
                let bounded = index.cache(&moved, m, None, Some(within));
                assert_eq!(bounded.candidates(), plain.candidates());
                assert_eq!(bounded.radius.to_bits(), plain.radius.to_bits());
            }
        }
    }

    #[test]
    fn rotated_index_finds_the_same_neighbours() {
        let pts = anisotropic_cloud(2000);
        let a = ScaledIndex::new(&pts);
        let b = ScaledIndex::unrotated(&pts);
        for q in pts.iter().step_by(37) {
            let q = [q[0] + 0.01, q[1], q[2] - 0.3, q[3], q[4] + 0.1, q[5]];
            let (ia, da) = a.nearest(&q);
            let (ib, db) = b.nearest(&q);
            assert!((da - db).abs() < 1e-9 && (ia == ib || (da - db).abs() < 1e-12));
        }
    }
}
