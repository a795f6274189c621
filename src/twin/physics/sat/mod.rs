//! Contact manifolds between convex pieces by the separating-axis test, replacing the engine's
//! GJK/EPA path for convex polyhedra.
//!
//! GJK/EPA in f32 reports bogus contacts between long, thin convex pieces (measured here: 4 of
//! 113 separated piece pairs of the `cross` pair at 0.1 mm clearance came back as penetrating by
//! 0.19 to 0.94 mm, which jammed a peg that fits). The separating-axis test is exact for convex
//! polytopes: the axis of least penetration among the face normals of both pieces and the
//! cross products of edge pairs that form a face of the Minkowski difference (the Gauss-map test
//! of D. Gregorius, GDC 2013) is the contact normal. Face contacts clip the incident face against
//! the reference face (Sutherland-Hodgman) and keep up to four points; edge contacts take the
//! closest points of the two edges. The last axis is cached in the manifold so that a separated
//! pair costs two support scans.

mod contacts;
mod turned;

use contacts::{edge_contact, face_contacts};
pub(crate) use turned::TurnedPieces;
use turned::{GaussArcs, SCRATCH, Scratch, Turned, is_real};

use rapier3d::parry::math::{Pose, Real, Vector};
use rapier3d::parry::query::{ContactManifold, TrackedContact};
use rapier3d::parry::shape::ConvexPolyhedron;
use smallvec::SmallVec;

/// Smallest and largest projection of a polyhedron's vertices on `dir` (its own frame).
fn extent(p: &ConvexPolyhedron, dir: Vector) -> (Real, Real) {
    p.points()
        .iter()
        .fold((Real::MAX, Real::MIN), |(lo, hi), v| {
            let d = v.dot(dir);
            (lo.min(d), hi.max(d))
        })
}

/// Separation of B from A along `n` (A's frame, pointing from A to B): min of B minus max of A.
fn separation(a: &ConvexPolyhedron, b: &ConvexPolyhedron, pos12: &Pose, n: Vector) -> Real {
    let (_, a_hi) = extent(a, n);
    let n_b = pos12.rotation.inverse() * n;
    let (b_lo, _) = extent(b, n_b);
    b_lo + n.dot(pos12.translation) - a_hi
}

/// The axis that decides the contact.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Axis {
    FaceA(usize),
    FaceB(usize),
    Edges(usize, usize),
}

/// Cosine of the largest normal rotation (0.1 deg) for which contact points are kept.
const COHERENCE_COS: Real = 0.999_998_5;
/// Square of the largest sliding (1 micrometre) for which contact points are kept, m^2.
const COHERENCE_DIST_SQ: Real = 1e-12;

/// Faces win over edges unless the edge axis separates more by this much (metres): keeps the
/// manifold from flickering between a face and an edge of a resting face contact.
const EDGE_TOLERANCE: Real = 1e-7;

/// The SAT manifold of two pieces (`pos12` places `b` in `a`'s frame; `sa`, `sb` are their
/// [`SatPiece`]s; `b_id` names `b` among the pieces whose turned copies `turned` keeps, one id
/// per piece). Returns `Some(gap)` when the pieces are apart by more than `prediction`: `gap`
/// (metres) is a lower bound on their distance, the separation along the axis that proved it (the
/// manifold is then empty).
pub(crate) fn sat_manifold<M, C: Default + Copy>(
    pos12: &Pose,
    (a, sa): (&ConvexPolyhedron, &SatPiece),
    (b, sb, b_id): (&ConvexPolyhedron, &SatPiece, u32),
    prediction: Real,
    manifold: &mut ContactManifold<M, C>,
    turned: &mut TurnedPieces,
) -> Option<Real> {
    // A pair at rest keeps its contact points: only their separations are refreshed, while no
    // point has slid by more than a micrometre and the normal has turned by less than 0.1 deg.
    if manifold.try_update_contacts_eps(pos12, COHERENCE_COS, COHERENCE_DIST_SQ) {
        return None;
    }
    // The cached axis first: a pair that stays apart costs two support scans.
    let cached = manifold.local_n1;
    if cached.length_squared() > 0.5 {
        let gap = separation(a, b, pos12, cached);
        if gap > prediction {
            manifold.clear();
            return Some(gap);
        }
    }
    let b_turned = turned.find_or_turn(b, sb, b_id, &pos12.rotation);
    let best = SCRATCH.with_borrow_mut(|scratch| {
        best_axis(pos12, (a, sa), sb, b_turned, prediction, scratch, true)
    });
    let (_, axis, n1) = match best {
        Ok(best) => best,
        Err((separating, gap)) => {
            manifold.clear();
            manifold.local_n1 = separating;
            return Some(gap);
        }
    };
    // The old points are kept only to carry their ids and impulses over to the new ones (a face
    // contact keeps at most four: copied aside, so that the manifold keeps its storage).
    let old_points: SmallVec<[TrackedContact<C>; 4]> = manifold.points.drain(..).collect();
    manifold.local_n1 = n1;
    manifold.local_n2 = pos12.rotation.inverse() * -n1;
    match axis {
        Axis::FaceA(f) => face_contacts(pos12, a, f, b, prediction, false, manifold),
        Axis::FaceB(f) => face_contacts(&pos12.inverse(), b, f, a, prediction, true, manifold),
        Axis::Edges(ia, ib) => edge_contact(pos12, a, ia, b, ib, n1, prediction, manifold),
    }
    manifold.match_contacts(&old_points);
    None
}

/// The separating-axis test proper: the axis of largest separation among the face normals of
/// both pieces and the edge pairs that make a face of the Minkowski difference, or
/// `Err((axis, gap))` as soon as one separates them by more than `prediction`. `prune` lets the
/// edge stage pass over the edges of A that [`edge_surely_below`] settles (the same result; the
/// tests compare both).
fn best_axis(
    pos12: &Pose,
    (a, sa): (&ConvexPolyhedron, &SatPiece),
    sb: &SatPiece,
    b_turned: &Turned,
    prediction: Real,
    scratch: &mut Scratch,
    prune: bool,
) -> Result<(Real, Axis, Vector), (Vector, Real)> {
    // B in A's frame: turned (maybe by an earlier pair), then moved, as `pos12 * p` does.
    let Scratch { pb, crosses, above } = scratch;
    pb.clear();
    pb.extend(b_turned.points.iter().map(|&p| p + pos12.translation));
    let nb = &b_turned.normals;
    let pa = a.points();

    // Face normals of A: separation = min over B along n minus A's face plane (the minimum of
    // B's heights above the plane: rounding is monotonic, so the same value).
    let mut best = (Real::MIN, Axis::FaceA(0), Vector::ZERO);
    above.clear();
    for (i, (f, &plane)) in a.faces().iter().zip(&sa.planes).enumerate() {
        let n = f.normal;
        let start = above.len();
        above.extend(pb.iter().map(|p| n.dot(*p) - plane));
        let s = above[start..].iter().fold(Real::MAX, |m, &h| m.min(h));
        if s > prediction {
            return Err((n, s));
        }
        if s > best.0 {
            best = (s, Axis::FaceA(i), n);
        }
    }
    // Face normals of B (axis -m from A to B): separation = min over A along m minus B's plane.
    for (i, (m, &v)) in nb.iter().zip(&sb.face_vertex).enumerate() {
        let plane = m.dot(pb[v as usize]);
        let s = pa.iter().fold(Real::MAX, |acc, p| acc.min(m.dot(*p))) - plane;
        if s > prediction {
            return Err((-*m, s));
        }
        // Prefer A's faces when both are as good.
        if s > best.0 + EDGE_TOLERANCE * 0.1 {
            best = (s, Axis::FaceB(i), -*m);
        }
    }
    // Edge pairs that make a face of the Minkowski difference.
    let arcs = &b_turned.arcs;
    let heights = Heights {
        above,
        per_face: pb.len(),
        limit: if prune {
            prune_limit(best.0, (sa, sb), pos12)
        } else {
            Real::MIN
        },
    };
    edge_stage((a, sa), sb, (pb, arcs), prediction, best, crosses, &heights)
}

/// The heights of B's vertices above A's face planes (metres, face by face, `per_face` each),
/// and the height below which an edge of A is passed over ([`edge_surely_below`]).
struct Heights<'a> {
    above: &'a [Real],
    per_face: usize,
    limit: Real,
}

/// Absolute slack of the edge pruning, relative to the pieces' reach: far above the f32 rounding
/// of the heights and of the edge stage's separations, far below the margins that prune.
const PRUNE_SLACK: Real = 1e-5;

/// The height below which an edge of A is passed over, when the best face axis separates the
/// pieces by `face_best` (metres): below zero and below it by the slack.
fn prune_limit(face_best: Real, (sa, sb): (&SatPiece, &SatPiece), pos12: &Pose) -> Real {
    let t = pos12.translation;
    let scale = sa.reach + sb.reach + t.x.abs() + t.y.abs() + t.z.abs();
    face_best.min(0.0) - PRUNE_SLACK * scale
}

/// Whether every edge pair of `ea` (an edge of A) that the edge stage could take separates the
/// pieces by less than `heights.limit` (which is negative and below the best face axis): the edge
/// can then neither beat the best axis nor end the test, and passing over it (its crossing test
/// and all) leaves the result as it was.
///
/// Why: an edge pair's axis `n` lies on `ea`'s Gauss arc, `n = (α n1 + β n2) / L` with `α, β >= 0`
/// (`n1`, `n2` the normals of `ea`'s faces, `L = |α n1 + β n2| <= α + β`), and its separation is
/// `n . (q - p)` with `p` on `ea` and `q` B's lowest point along `n`, so no higher than any
/// vertex `c` of B: `s <= (α h1(c) + β h2(c)) / L`, where `h1`, `h2` are `c`'s heights above the
/// two face planes (both through `p`). When both are at most `D < 0`, that is at most `D`. So one
/// vertex of B below both planes by more than the limit bounds every pair of the edge. The slack
/// ([`PRUNE_SLACK`]) covers the f32 rounding of the heights and of `s`, and a crossing that the
/// f32 Gauss-map test finds just off an arc's end, up to 1e-5 rad off (an axis farther off is not
/// a face of the Minkowski difference: the edge stage would take a wrong axis there).
fn edge_surely_below(ea: &RealEdge, heights: &Heights) -> bool {
    let n = heights.per_face;
    let [f1, f2] = ea.faces.map(|f| f as usize * n);
    let (h1, h2) = (&heights.above[f1..f1 + n], &heights.above[f2..f2 + n]);
    h1.iter().zip(h2).any(|(&x, &y)| x.max(y) <= heights.limit)
}

/// The best axis after the face axes `best`, among edge pairs of A and B that make a face of the
/// Minkowski difference; `Err((axis, gap))` as soon as one separates the pieces by more than
/// `prediction`. `pb` and `arcs` are B's points and Gauss arcs in A's frame.
fn edge_stage(
    (a, sa): (&ConvexPolyhedron, &SatPiece),
    sb: &SatPiece,
    (pb, arcs): (&[Vector], &GaussArcs),
    prediction: Real,
    mut best: (Real, Axis, Vector),
    crosses: &mut Vec<bool>,
    heights: &Heights,
) -> Result<(Real, Axis, Vector), (Vector, Real)> {
    let pa = a.points();
    let face_limit = best.0;
    crosses.clear();
    crosses.resize(arcs.len(), false);
    for ea in sa.edges.iter().filter(|ea| !edge_surely_below(ea, heights)) {
        let dir_a = a.edges()[ea.index as usize].dir;
        let p_a = pa[ea.v0 as usize];
        let outward = p_a - sa.centroid;
        arcs.crossing(ea, crosses);
        for j in (0..crosses.len()).filter(|&j| crosses[j]) {
            let eb = &sb.edges[j];
            let start_b = pb[eb.v0 as usize];
            let axis = dir_a.cross(arcs.dir[j]);
            // Only an axis that could beat the best so far (or end the test) is normalised.
            let threshold = best.0.max(face_limit + EDGE_TOLERANCE);
            if surely_below(axis, start_b - p_a, outward, threshold.min(prediction)) {
                continue;
            }
            let len = axis.length();
            if len < 1e-5 {
                continue;
            }
            let mut axis = axis / len;
            if axis.dot(outward) < 0.0 {
                axis = -axis;
            }
            let s = axis.dot(start_b - p_a);
            if s > prediction {
                return Err((axis, s));
            }
            if s > threshold {
                best = (s, Axis::Edges(ea.index as usize, eb.index as usize), axis);
            }
        }
    }
    Ok(best)
}

/// Relative slack of [`surely_below`], far above the f32 rounding of the few operations it bounds
/// (a few units of 6e-8).
const SLACK: Real = 1e-5;

/// Whether the separation along the edge axis `raw / |raw|` (turned to point along `outward`,
/// away from A), as the edge stage computes it in f32 from `raw` and `diff` (from A's edge to B's),
/// is surely below `limit`, without the square root and the division: the pair could then
/// neither beat the best axis nor end the test, and skipping it leaves the result as it was, to
/// the bit. Unsure (an axis nearly across `outward`, a separation near the limit): `false`.
fn surely_below(raw: Vector, diff: Vector, outward: Vector, limit: Real) -> bool {
    let l1 = |v: Vector| v.x.abs() + v.y.abs() + v.z.abs();
    let r1 = l1(raw);
    let along = raw.dot(outward);
    if along.abs() <= SLACK * r1 * l1(outward) {
        return false;
    }
    let s = if along < 0.0 {
        -raw.dot(diff)
    } else {
        raw.dot(diff)
    };
    // `upper / |raw|` bounds the separation the edge stage would compute.
    let upper = s + SLACK * r1 * l1(diff);
    if limit >= 0.0 {
        upper < 0.0
    } else {
        upper < 0.0 && upper * upper > limit * limit * raw.length_squared() * (1.0 + SLACK)
    }
}

/// What the separating-axis test needs of a piece besides its polyhedron, computed once per piece
/// (its own frame), with the same operations the test used to repeat at every call.
#[derive(Clone, Debug)]
pub(crate) struct SatPiece {
    /// Per face, the offset of its plane along its normal, metres.
    planes: Vec<Real>,
    /// Per face, the index of its first vertex.
    face_vertex: Vec<u32>,
    /// The real edges, in the polyhedron's order (see [`is_real`]).
    edges: Vec<RealEdge>,
    /// The mean of the vertices.
    centroid: Vector,
    /// The largest `|x| + |y| + |z|` of a vertex, metres: the scale of the test's rounding.
    reach: Real,
}

/// A real edge of a piece and its arc on the Gauss map.
#[derive(Clone, Debug)]
struct RealEdge {
    /// Its index among the polyhedron's edges, its first vertex and its two faces.
    index: u32,
    v0: u32,
    faces: [u32; 2],
    /// The normals of its two faces, and their cross product `n2 x n1`.
    n1: Vector,
    n2: Vector,
    w: Vector,
}

impl SatPiece {
    pub(crate) fn new(p: &ConvexPolyhedron) -> Self {
        let points = p.points();
        let face_vertex: Vec<u32> = p
            .faces()
            .iter()
            .map(|f| p.vertices_adj_to_face()[f.first_vertex_or_edge as usize])
            .collect();
        let planes = p
            .faces()
            .iter()
            .zip(&face_vertex)
            .map(|(f, &v)| f.normal.dot(points[v as usize]))
            .collect();
        let edges = p
            .edges()
            .iter()
            .enumerate()
            .filter(|(_, e)| is_real(e.faces))
            .map(|(i, e)| {
                let n1 = p.faces()[e.faces[0] as usize].normal;
                let n2 = p.faces()[e.faces[1] as usize].normal;
                RealEdge {
                    index: i as u32,
                    v0: e.vertices[0],
                    faces: e.faces,
                    n1,
                    n2,
                    w: n2.cross(n1),
                }
            })
            .collect();
        let centroid = points.iter().copied().sum::<Vector>() / points.len() as Real;
        let reach = points
            .iter()
            .map(|p| p.x.abs() + p.y.abs() + p.z.abs())
            .fold(0.0, Real::max);
        SatPiece {
            planes,
            face_vertex,
            edges,
            centroid,
            reach,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;
    use rapier3d::parry::math::Rotation;

    /// A chamfered wall strip like the ones the pegs' outlines become: a 4 x 1 x 20 mm prism
    /// with a 45 deg bevel along one long edge.
    fn strip() -> ConvexPolyhedron {
        let mut points = Vec::new();
        for z in [0.0, 20e-3] {
            for (x, y) in [
                (0.0, 0.0),
                (4e-3, 0.0),
                (4e-3, 0.5e-3),
                (3.5e-3, 1e-3),
                (0.0, 1e-3),
            ] {
                points.push(Vector::new(x, y, z));
            }
        }
        ConvexPolyhedron::from_convex_hull(&points).expect("a strip")
    }

    /// For overlapping pieces the separating-axis value is the largest separation over every
    /// direction, so no face normal and no cross product of any two edges (whether or not they
    /// make a face of the Minkowski difference) may separate them more than the axis found; and
    /// the axis found separates them by the value reported. Run over random overlaps of two
    /// strips, with edge axes among the winners (the path the edge stage's shortcut takes).
    #[test]
    fn the_axis_found_separates_overlapping_pieces_most() {
        let (a, b) = (strip(), strip());
        let (sa, sb) = (SatPiece::new(&a), SatPiece::new(&b));
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let mut scratch = Scratch::default();
        let mut turned = TurnedPieces::default();
        let (mut overlapping, mut by_edges) = (0, 0);
        for _ in 0..4000 {
            let angles = Vector::new(rng.random(), rng.random(), rng.random()) * 2.0 - Vector::ONE;
            let rotation = Rotation::from_scaled_axis(angles * rng.random_range(0.0..3.2));
            let offset = Vector::new(
                rng.random_range(-5e-3..5e-3),
                rng.random_range(-3e-3..3e-3),
                rng.random_range(-20e-3..20e-3),
            );
            let pos12 = Pose::from_parts(offset, rotation);
            let b_turned = turned.find_or_turn(&b, &sb, 0, &pos12.rotation);
            let Ok((s, axis, n)) =
                best_axis(&pos12, (&a, &sa), &sb, b_turned, 30e-6, &mut scratch, true)
            else {
                continue;
            };
            if s >= 0.0 {
                continue;
            }
            overlapping += 1;
            by_edges += usize::from(matches!(axis, Axis::Edges(..)));
            let mut candidates: Vec<Vector> = a.faces().iter().map(|f| f.normal).collect();
            candidates.extend(b.faces().iter().map(|f| pos12.rotation * -f.normal));
            for ea in a.edges() {
                for eb in b.edges() {
                    let x = ea.dir.cross(pos12.rotation * eb.dir);
                    if x.length() > 1e-3 {
                        candidates.extend([x.normalize(), -x.normalize()]);
                    }
                }
            }
            let most = candidates
                .iter()
                .map(|&u| separation(&a, &b, &pos12, u))
                .fold(Real::MIN, Real::max);
            let tolerance = 1e-6;
            assert!(
                most <= s + EDGE_TOLERANCE + tolerance,
                "{most} beyond {s} ({pos12:?})"
            );
            let along = separation(&a, &b, &pos12, n);
            assert!(
                (along - s).abs() < tolerance,
                "{along} against {s} ({pos12:?})"
            );
        }
        assert!(overlapping > 1000, "{overlapping} overlaps");
        assert!(by_edges > 50, "{by_edges} edge axes among {overlapping}");
    }

    /// Passing over the edges of A that [`edge_surely_below`] settles gives the test's result to the
    /// bit: the axis, its separation and its normal, or the separating axis and gap. Run over
    /// strips lying along each other (pressed together by up to 20 um, turned by up to 0.6 deg, as
    /// a peg's wall strips meet the bore's) and over random overlaps, with edge axes among the
    /// winners; in the first, more than half of A's edges are passed over.
    #[test]
    fn edges_passed_over_change_no_axis() {
        let (a, b) = (strip(), strip());
        let (sa, sb) = (SatPiece::new(&a), SatPiece::new(&b));
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let (mut scratch, mut turned) = (Scratch::default(), TurnedPieces::default());
        let (mut by_edges, mut edges, mut passed_over) = (0, 0, 0);
        for k in 0..6000 {
            let along = k % 2 == 0;
            let angles = Vector::new(rng.random(), rng.random(), rng.random()) * 2.0 - Vector::ONE;
            let (turn, offset) = if along {
                let y = 1e-3 - rng.random_range(0.0..20e-6);
                let (x, z) = (
                    rng.random_range(-3e-3..3e-3),
                    rng.random_range(-10e-3..10e-3),
                );
                (0.01, Vector::new(x, y, z))
            } else {
                let x = rng.random_range(-5e-3..5e-3);
                let (y, z) = (
                    rng.random_range(-3e-3..3e-3),
                    rng.random_range(-20e-3..20e-3),
                );
                (3.2, Vector::new(x, y, z))
            };
            let rotation = Rotation::from_scaled_axis(angles * rng.random_range(0.0..turn));
            let pos12 = Pose::from_parts(offset, rotation);
            let b_turned = turned.find_or_turn(&b, &sb, 0, &pos12.rotation);
            let mut test = |prune| {
                best_axis(&pos12, (&a, &sa), &sb, b_turned, 30e-6, &mut scratch, prune)
                    .map(|(s, axis, n)| (s.to_bits(), axis, n.to_array()))
                    .map_err(|(n, gap)| (n.to_array(), gap.to_bits()))
            };
            let (pruned, full) = (test(true), test(false));
            assert_eq!(pruned, full, "{pos12:?}");
            let Ok((s, axis, _)) = full else { continue };
            let by_edge = matches!(axis, Axis::Edges(..));
            by_edges += usize::from(by_edge);
            if along && !by_edge {
                // The best axis is a face's: its separation is the limit's face value.
                let heights = Heights {
                    above: &scratch.above,
                    per_face: b.points().len(),
                    limit: prune_limit(f32::from_bits(s), (&sa, &sb), &pos12),
                };
                edges += sa.edges.len();
                passed_over += sa
                    .edges
                    .iter()
                    .filter(|e| edge_surely_below(e, &heights))
                    .count();
            }
        }
        assert!(by_edges > 100, "{by_edges} edge axes");
        assert!(
            2 * passed_over > edges,
            "{passed_over} of {edges} edges passed over"
        );
    }

    /// A box, for a second kind of piece.
    fn block() -> ConvexPolyhedron {
        let mut points = Vec::new();
        for z in [0.0, 6e-3] {
            for (x, y) in [(0.0, 0.0), (2e-3, 0.0), (2e-3, 3e-3), (0.0, 3e-3)] {
                points.push(Vector::new(x, y, z));
            }
        }
        ConvexPolyhedron::from_convex_hull(&points).expect("a block")
    }

    /// Pieces kept turned give every pair the manifold it gets from pieces turned anew: two
    /// pieces of B met in turn against A, several pairs at each rotation (as a compound's pairs
    /// share theirs), more pieces and rotations than the kept ones.
    #[test]
    fn pieces_kept_turned_give_the_manifolds_of_pieces_turned_anew() {
        let a = strip();
        let bs = [strip(), block()];
        let sa = SatPiece::new(&a);
        let sbs = bs.each_ref().map(SatPiece::new);
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let mut kept = TurnedPieces::default();
        let mut with_contact = 0;
        for _ in 0..400 {
            let angles = Vector::new(rng.random(), rng.random(), rng.random()) * 2.0 - Vector::ONE;
            let rotation = Rotation::from_scaled_axis(angles * rng.random_range(0.0..0.1));
            for _ in 0..6 {
                let which = rng.random_range(0..2);
                let id = 40 + which as u32 + 2 * rng.random_range(0..10);
                let offset = Vector::new(
                    rng.random_range(-2e-3..4e-3),
                    rng.random_range(-3e-3..2e-3),
                    rng.random_range(-5e-3..15e-3),
                );
                let pos12 = Pose::from_parts(offset, rotation);
                let (b, sb) = (&bs[which], &sbs[which]);
                // A piece id names one piece: ids of the same parity are the same piece here.
                let test = |turned: &mut TurnedPieces| {
                    let mut m = ContactManifold::<(), ()>::new();
                    let gap = sat_manifold(&pos12, (&a, &sa), (b, sb, id), 30e-6, &mut m, turned);
                    (gap, m)
                };
                let (gap_kept, m_kept) = test(&mut kept);
                let (gap_anew, m_anew) = test(&mut TurnedPieces::default());
                assert_eq!(gap_kept.map(f32::to_bits), gap_anew.map(f32::to_bits));
                assert_eq!(m_kept.local_n1.to_array(), m_anew.local_n1.to_array());
                assert_eq!(m_kept.points.len(), m_anew.points.len());
                for (p, q) in m_kept.points.iter().zip(&m_anew.points) {
                    assert_eq!(p.local_p1.to_array(), q.local_p1.to_array());
                    assert_eq!(p.local_p2.to_array(), q.local_p2.to_array());
                    assert_eq!(p.dist.to_bits(), q.dist.to_bits());
                }
                with_contact += usize::from(!m_kept.points.is_empty());
            }
        }
        assert!(with_contact > 200, "{with_contact} pairs in contact");
    }
}
