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
//! Files: [`file`] (versioned binary with a checksum, and CSV). Test data: [`synthetic`].

pub mod file;
pub mod synthetic;

use crate::error::{Error, Result};
use crate::pose::{Pose6, PoseMetric};
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
    tree: ImmutableKdTree<f64, u32, 6, 32>,
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

    /// Indices of the `k` nearest points to `q` (nearest first).
    pub fn nearest_k(&self, q: &[f64; 6], k: NonZero<usize>) -> Vec<usize> {
        self.tree
            .nearest_n::<SquaredEuclidean>(&rotate(&self.rotation, q), k)
            .into_iter()
            .map(|n| n.item as usize)
            .collect()
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

/// Normals of every point of a cloud from its `k` nearest neighbours in `index` (which indexes
/// `points`), computed in parallel; the result does not depend on the thread count.
pub fn cloud_normals(points: &[[f64; 6]], index: &ScaledIndex, k: usize) -> Vec<[f64; 6]> {
    let k = NonZero::new(k.max(1)).expect("k >= 1");
    points
        .par_iter()
        .map(|p| {
            let idx = index.nearest_k(p, k);
            neighbourhood_normal(idx.iter().map(|&i| &points[i]))
        })
        .collect()
}

/// A reference contact manifold: poses, normals, index, metadata.
pub struct Manifold {
    pub meta: ManifoldMeta,
    /// Contact poses `hole_T_peg`, m and rad.
    pub points: Vec<Pose6>,
    /// Unit normals in scaled coordinates, one per point.
    pub normals: Vec<[f64; 6]>,
    scaled: Vec<[f64; 6]>,
    index: ScaledIndex,
}

impl Manifold {
    /// A manifold from poses; normals are computed with `meta.normal_k` neighbours.
    pub fn from_points(points: Vec<Pose6>, meta: ManifoldMeta) -> Result<Self> {
        check_points(&points, meta.normal_k)?;
        let scaled: Vec<[f64; 6]> = points.iter().map(|p| meta.metric.scaled(p)).collect();
        let index = ScaledIndex::new(&scaled);
        let normals = cloud_normals(&scaled, &index, meta.normal_k);
        Ok(Manifold {
            meta,
            points,
            normals,
            scaled,
            index,
        })
    }

    /// A manifold from poses and their precomputed normals (read from a file).
    pub fn with_normals(
        points: Vec<Pose6>,
        normals: Vec<[f64; 6]>,
        meta: ManifoldMeta,
    ) -> Result<Self> {
        check_points(&points, meta.normal_k)?;
        if normals.len() != points.len() {
            return Err(Error::Input(format!(
                "manifold has {} points but {} normals",
                points.len(),
                normals.len()
            )));
        }
        let scaled: Vec<[f64; 6]> = points.iter().map(|p| meta.metric.scaled(p)).collect();
        let index = ScaledIndex::new(&scaled);
        Ok(Manifold {
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

    /// Scaled coordinates of point `i`.
    pub fn scaled(&self, i: usize) -> &[f64; 6] {
        &self.scaled[i]
    }

    /// Index and squared scaled distance of the manifold point nearest to `q` (scaled coordinates).
    pub fn nearest(&self, q: &[f64; 6]) -> (usize, f64) {
        self.index.nearest(q)
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
    if points.len() > u32::MAX as usize {
        return Err(Error::Input(format!(
            "manifold has {} points; at most {} are supported",
            points.len(),
            u32::MAX
        )));
    }
    if let Some(i) = points.iter().position(|p| !p.is_finite()) {
        return Err(Error::Input(format!(
            "manifold point {i} is not finite: {:?}",
            points[i].0
        )));
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

    #[test]
    fn rotated_index_finds_the_same_neighbours() {
        let pts: Vec<[f64; 6]> = (0..2000)
            .map(|i| {
                let t = i as f64;
                [
                    0.2 * (t * 0.731).sin(),
                    0.2 * (t * 0.377).cos(),
                    10.0 * (t * 0.0113).sin(),
                    2.0 * (t * 0.517).sin(),
                    2.0 * (t * 0.291).cos(),
                    1.0 * (t * 0.173).sin(),
                ]
            })
            .collect();
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
