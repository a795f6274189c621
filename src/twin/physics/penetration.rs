//! An exact penetration measure, independent of the physics engine: the separating-axis test in
//! f64 between every pair of convex pieces whose bounds overlap. For two convex polytopes the
//! minimum over all face normals and edge-edge cross products of the projected overlap is the
//! penetration depth (the shortest translation that separates them).

use crate::twin::geometry::solid::{ConvexPiece, P3, Solid};
use nalgebra::{Isometry3, Vector3};
use rapier3d::parry::bounding_volume::Aabb;
use rapier3d::parry::math::Vector;
use rapier3d::parry::partitioning::{Bvh, BvhBuildStrategy};

/// A convex piece's vertices, face normals and edge directions placed in the world.
#[derive(Clone, Default)]
pub(super) struct Posed {
    pub(super) vertices: Vec<P3>,
    pub(super) face_normals: Vec<Vector3<f64>>,
    pub(super) edge_dirs: Vec<Vector3<f64>>,
    pub(super) bounds: (P3, P3),
}

impl Posed {
    fn new(piece: &ConvexPiece, iso: &Isometry3<f64>) -> Self {
        Posed::with_vertices(piece, iso, piece.vertices.iter().map(|p| iso * p).collect())
    }

    /// The piece at `iso`, given its `vertices` placed there.
    fn with_vertices(piece: &ConvexPiece, iso: &Isometry3<f64>, vertices: Vec<P3>) -> Self {
        let bounds = bounds_of(vertices.iter().copied());
        Posed {
            vertices,
            face_normals: piece.face_normals.iter().map(|n| iso * n).collect(),
            edge_dirs: piece.edge_dirs.iter().map(|e| iso * e).collect(),
            bounds,
        }
    }
}

/// Depth (metres) by which two convex pieces, given in one frame, overlap; 0 when they do not.
pub fn piece_penetration(a: &ConvexPiece, b: &ConvexPiece) -> f64 {
    let id = Isometry3::identity();
    posed_penetration(&Posed::new(a, &id), &Posed::new(b, &id))
}

fn posed_penetration(a: &Posed, b: &Posed) -> f64 {
    let mut depth = f64::INFINITY;
    let mut test = |axis: &Vector3<f64>| -> bool {
        let (a0, a1) = project(&a.vertices, axis);
        let (b0, b1) = project(&b.vertices, axis);
        let overlap = (a1 - b0).min(b1 - a0);
        depth = depth.min(overlap);
        overlap > 0.0
    };
    for n in a.face_normals.iter().chain(&b.face_normals) {
        if !test(n) {
            return 0.0;
        }
    }
    for ea in &a.edge_dirs {
        for eb in &b.edge_dirs {
            let c = ea.cross(eb);
            let len = c.norm();
            if len > 1e-9 && !test(&(c / len)) {
                return 0.0;
            }
        }
    }
    depth.max(0.0)
}

/// The least overlap (metres; negative: the separation) of `moving` with `fixed` and the unit
/// direction that opens it by moving `moving`; `None` as soon as an axis separates them by more
/// than `margin` (metres). The face normals of both come first; only a pair they leave
/// overlapping is tried on the edge-pair axes, which give the exact depth as in
/// [`posed_penetration`]. A pair the face normals separate keeps the largest separation among
/// them: a lower bound on its distance, which is what a projection must not close.
fn least_overlap(moving: &Posed, fixed: &Posed, margin: f64) -> Option<(f64, Vector3<f64>)> {
    let mut best = (f64::INFINITY, Vector3::z());
    let mut test = |axis: Vector3<f64>| {
        let (m0, m1) = project(&moving.vertices, &axis);
        let (f0, f1) = project(&fixed.vertices, &axis);
        // Move `moving` along -axis by m1 - f0, or along +axis by f1 - m0.
        for (overlap, opening) in [(m1 - f0, -axis), (f1 - m0, axis)] {
            if overlap < best.0 {
                best = (overlap, opening);
            }
        }
        best.0
    };
    let mut least = f64::INFINITY;
    for n in moving.face_normals.iter().chain(&fixed.face_normals) {
        least = test(*n);
        if least < -margin {
            return None;
        }
    }
    if least <= 0.0 {
        return Some(best);
    }
    'edges: for ea in &moving.edge_dirs {
        for eb in &fixed.edge_dirs {
            let c = ea.cross(eb);
            let len = c.norm();
            if len > 1e-9 && test(c / len) <= 0.0 {
                break 'edges;
            }
        }
    }
    Some(best)
}

/// The least and largest projection of `points` on `axis` (plain comparisons: the coordinates
/// are finite, and they let the compiler keep the loop tight).
pub(super) fn project(points: &[P3], axis: &Vector3<f64>) -> (f64, f64) {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for p in points {
        let d = p.x * axis.x + p.y * axis.y + p.z * axis.z;
        if d < lo {
            lo = d;
        }
        if d > hi {
            hi = d;
        }
    }
    (lo, hi)
}

/// Whether two bounding boxes come within `margin` (metres) of each other on every axis.
pub(super) fn within(a: &(P3, P3), b: &(P3, P3), margin: f64) -> bool {
    (0..3).all(|i| a.0[i] <= b.1[i] + margin && b.0[i] <= a.1[i] + margin)
}

/// One piece pair of a moving solid against the fixed one, for a position projection: the
/// moving piece's deepest point along the pair's least-overlap axis and the direction that opens
/// the pair (world frame), and the gap along that axis (metres; negative: overlapping).
#[derive(Clone, Copy, Debug)]
pub struct GapRow {
    pub point: P3,
    pub opening: Vector3<f64>,
    pub gap_m: f64,
}

/// Precomputed pieces and bounds of a fixed solid, for repeated penetration queries.
#[derive(Clone)]
pub struct PenetrationProbe {
    pub(super) fixed: Vec<Posed>,
    /// The fixed pieces' bounds (f32, loosened by `TREE_SLACK_M`), to find the pieces near a
    /// moving one without testing every pair; the exact f64 test follows.
    tree: Bvh,
}

/// How much the tree's f32 boxes are loosened, metres: far above the f32 rounding of
/// coordinates within a few metres of the origin (under 0.5 um).
const TREE_SLACK_M: f64 = 10e-6;

/// The bounds of points, smallest and largest corner.
pub(super) fn bounds_of(points: impl Iterator<Item = P3>) -> (P3, P3) {
    points.fold(
        (
            P3::new(f64::MAX, f64::MAX, f64::MAX),
            P3::new(f64::MIN, f64::MIN, f64::MIN),
        ),
        |(lo, hi), p| (lo.inf(&p), hi.sup(&p)),
    )
}

/// A box of the tree: `bounds` loosened by `margin` and `TREE_SLACK_M`.
fn tree_box((lo, hi): &(P3, P3), margin: f64) -> Aabb {
    let m = margin + TREE_SLACK_M;
    let corner = |p: &P3, s: f64| Vector::new((p.x + s) as f32, (p.y + s) as f32, (p.z + s) as f32);
    Aabb::new(corner(lo, -m), corner(hi, m))
}

impl PenetrationProbe {
    /// Prepares the fixed solid placed at `pose` in the world.
    pub fn new(fixed: &Solid, pose: &Isometry3<f64>) -> Self {
        let fixed: Vec<Posed> = (fixed.pieces.iter()).map(|p| Posed::new(p, pose)).collect();
        let boxes: Vec<Aabb> = fixed.iter().map(|f| tree_box(&f.bounds, 0.0)).collect();
        PenetrationProbe {
            tree: Bvh::from_leaves(BvhBuildStrategy::Binned, &boxes),
            fixed,
        }
    }

    /// The fixed pieces whose bounds come within `margin` (metres) of those of `piece` at
    /// `pose`, in index order; `None` when there are none (the piece is not placed then).
    fn near(
        &self,
        piece: &ConvexPiece,
        pose: &Isometry3<f64>,
        margin: f64,
    ) -> Option<(Posed, Vec<usize>)> {
        let bounds = bounds_of(piece.vertices.iter().map(|p| pose * p));
        let near = self.near_bounds(&bounds, margin);
        if near.is_empty() {
            return None;
        }
        Some((Posed::new(piece, pose), near))
    }

    /// The largest penetration depth (metres) between `moving` placed at `pose` and the fixed
    /// solid, over all pairs of pieces.
    pub fn max_penetration(&self, moving: &Solid, pose: &Isometry3<f64>) -> f64 {
        moving
            .pieces
            .iter()
            .map(|piece| self.piece_penetration(piece, pose))
            .fold(0.0, f64::max)
    }

    /// The fixed pieces whose bounds come within `margin` (metres) of `bounds`, in index order.
    fn near_bounds(&self, bounds: &(P3, P3), margin: f64) -> Vec<usize> {
        let mut near = Vec::new();
        self.near_into(bounds, margin, &mut near);
        near
    }

    /// [`Self::near_bounds`] into `near` (cleared first).
    pub(super) fn near_into(&self, bounds: &(P3, P3), margin: f64, near: &mut Vec<usize>) {
        near.clear();
        near.extend(
            (self.tree)
                .intersect_aabb(&tree_box(bounds, margin))
                .map(|i| i as usize)
                .filter(|&i| within(bounds, &self.fixed[i].bounds, margin)),
        );
        near.sort_unstable();
    }

    /// Every pair of a piece of `moving` at `pose` and a piece of the fixed solid whose bounds
    /// come within `margin_m`, as a [`GapRow`].
    pub fn gap_rows(&self, moving: &Solid, pose: &Isometry3<f64>, margin_m: f64) -> Vec<GapRow> {
        let mut rows = Vec::new();
        for piece in &moving.pieces {
            let Some((posed, near)) = self.near(piece, pose, margin_m) else {
                continue;
            };
            for fixed in near.iter().map(|&i| &self.fixed[i]) {
                let Some((overlap, opening)) = least_overlap(&posed, fixed, margin_m) else {
                    continue;
                };
                let point = posed
                    .vertices
                    .iter()
                    .min_by(|a, b| a.coords.dot(&opening).total_cmp(&b.coords.dot(&opening)))
                    .copied()
                    .expect("a convex piece has vertices");
                rows.push(GapRow {
                    point,
                    opening,
                    gap_m: -overlap,
                });
            }
        }
        rows
    }

    /// The largest penetration depth (metres) between one convex `piece` placed at `pose` and
    /// the fixed solid.
    pub fn piece_penetration(&self, piece: &ConvexPiece, pose: &Isometry3<f64>) -> f64 {
        let Some((posed, near)) = self.near(piece, pose, 0.0) else {
            return 0.0;
        };
        near.iter()
            .map(|&i| posed_penetration(&posed, &self.fixed[i]))
            .fold(0.0, f64::max)
    }
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;
    use crate::twin::geometry::planar::rect;
    use crate::twin::geometry::solid::{Solid, ZPlane};

    /// A unit cube with its least corner at (x, y, z).
    pub(in crate::twin::physics) fn cube(x: f64, y: f64, z: f64) -> ConvexPiece {
        ConvexPiece::slab(
            &rect(x, y, x + 1.0, y + 1.0),
            ZPlane::flat(z),
            ZPlane::flat(z + 1.0),
        )
    }

    #[test]
    fn overlapping_cubes_report_the_smallest_overlap() {
        assert!(
            (piece_penetration(&cube(0.0, 0.0, 0.0), &cube(0.9, 0.5, 0.2)) - 0.1).abs() < 1e-12
        );
        assert_eq!(
            piece_penetration(&cube(0.0, 0.0, 0.0), &cube(1.001, 0.0, 0.0)),
            0.0
        );
        // Tiny overlaps are measured, not inflated (the engine reported 9.9 mm for 1.6 um).
        let d = piece_penetration(&cube(0.0, 0.0, 0.0), &cube(1.0 - 1.6e-6, 0.3, 0.3));
        assert!((d - 1.6e-6).abs() < 1e-12, "{d}");
    }

    #[test]
    fn gap_rows_open_an_overlap_the_short_way_and_keep_near_pairs() {
        let solid = |pieces| Solid {
            pieces,
            boundary: None,
        };
        let fixed = solid(vec![cube(0.0, 0.0, 0.0), cube(3.0, 0.0, 0.0)]);
        let probe = PenetrationProbe::new(&fixed, &Isometry3::identity());
        // A unit cube 2 um into the first along x, 30 um short of the second.
        let moving = solid(vec![
            cube(1.0 - 2e-6, 0.2, 0.1),
            cube(2.0 - 30e-6, 0.2, 0.1),
        ]);
        let pose = Isometry3::identity();
        let rows = probe.gap_rows(&moving, &pose, 50e-6);
        assert_eq!(rows.len(), 2, "{rows:?}");
        assert!(
            (rows[0].gap_m + 2e-6).abs() < 1e-12 && rows[0].opening.x > 0.999,
            "{rows:?}"
        );
        assert!((rows[0].point.x - (1.0 - 2e-6)).abs() < 1e-12, "{rows:?}");
        assert!(
            (rows[1].gap_m - 30e-6).abs() < 1e-12 && rows[1].opening.x < -0.999,
            "{rows:?}"
        );
        // Beyond the margin, the second pair is left out.
        assert_eq!(probe.gap_rows(&moving, &pose, 10e-6).len(), 1);
    }

    #[test]
    fn edge_edge_axes_separate_crossed_wedges() {
        // A cube rotated 45 deg about z and x, just not touching the corner of another.
        let a = cube(0.0, 0.0, 0.0);
        let rot = Isometry3::new(
            Vector3::new(1.0 + 0.8, 0.5, 0.5),
            Vector3::new(0.0, 0.0, std::f64::consts::FRAC_PI_4),
        );
        let a = Posed::new(&a, &Isometry3::identity());
        let centred = Posed::new(&cube(-0.5, -0.5, -0.5), &rot);
        // The rotated cube reaches 0.5 * sqrt(2) = 0.707 < 0.8 from its centre: no contact.
        assert_eq!(posed_penetration(&a, &centred), 0.0);
        let closer = Isometry3::new(
            Vector3::new(1.0 + 0.6, 0.5, 0.5),
            Vector3::new(0.0, 0.0, std::f64::consts::FRAC_PI_4),
        );
        let d = posed_penetration(&a, &Posed::new(&cube(-0.5, -0.5, -0.5), &closer));
        assert!((d - (0.5f64.sqrt() - 0.6)).abs() < 1e-9, "{d}");
    }
}
