//! The signed gap between a moving solid and a probe's fixed one, for finding the first contact
//! along a path of poses (the geometric manifold sampler): the separating-axis test of
//! [`super::penetration`], made cheap for many calls on nearby poses. Each call remembers, per
//! piece pair, the axis that separated it and a lower bound of its distance ([`GapHints`]), so
//! that the next call tries that axis first and skips the pairs that cannot be the closest; the
//! buffers are kept between calls, and the face normals' own extents are not projected again.
//! Of the edge pairs, only those whose cross product is a face normal of the pieces' Minkowski
//! difference are tried (their Gauss-map arcs cross: Gregorius, "The separating axis test
//! between convex polyhedra", GDC 2013): the others never give the largest separation of
//! overlapping pieces, so the depth is the same, and the face normals and these suffice to
//! separate pieces that are apart.

use super::penetration::{PenetrationProbe, Posed, bounds_of, project, within};
use crate::twin::geometry::solid::P3;
use crate::twin::geometry::solid::{ConvexPiece, Solid};
use nalgebra::{Isometry3, Vector3};

/// How far a moving piece's bounds may move before the fixed pieces near it are looked up
/// again, as a share of the margin (the lookup then takes the margin and this much more).
const LIST_SLACK: f64 = 4.0;

/// A pose as a rotation matrix and a translation: placing a point takes fewer operations than
/// with the pose's quaternion, and a piece's vertices are placed at every call.
struct Placement {
    rotation: nalgebra::Matrix3<f64>,
    translation: Vector3<f64>,
}

impl Placement {
    fn of(pose: &Isometry3<f64>) -> Self {
        Placement {
            rotation: *pose.rotation.to_rotation_matrix().matrix(),
            translation: pose.translation.vector,
        }
    }

    fn point(&self, p: &P3) -> P3 {
        P3::from(self.rotation * p.coords + self.translation)
    }
}

/// An edge of a convex piece: its two vertices and the two faces it joins (indices into the
/// piece's vertices and faces).
#[derive(Clone, Copy, Debug)]
struct Edge {
    ends: [usize; 2],
    faces: [usize; 2],
}

/// The edges of `piece` between faces that are not parallel, in the order its faces walk them.
fn edges_of(piece: &ConvexPiece) -> Vec<Edge> {
    let mut open: std::collections::HashMap<(u32, u32), usize> = Default::default();
    let mut edges = Vec::new();
    for (f, face) in piece.faces.iter().enumerate() {
        for (k, &a) in face.iter().enumerate() {
            let b = face[(k + 1) % face.len()];
            let key = (a.min(b), a.max(b));
            if let Some(other) = open.remove(&key) {
                edges.push(Edge {
                    ends: [key.0 as usize, key.1 as usize],
                    faces: [other, f],
                });
            } else {
                open.insert(key, f);
            }
        }
    }
    let normal = |e: &Edge, i: usize| piece.face_normals[e.faces[i]];
    edges.retain(|e| normal(e, 0).cross(&normal(e, 1)).norm() > 1e-9);
    edges
}

/// An edge's arc on the Gauss map: the normals of its two faces, `a` and `b`, and `b x a`
/// (for a fixed piece, the negated normals: the arc of the Minkowski difference).
#[derive(Clone, Copy, Debug, Default)]
struct Arc {
    a: Vector3<f64>,
    b: Vector3<f64>,
    b_x_a: Vector3<f64>,
}

impl Arc {
    fn new(a: Vector3<f64>, b: Vector3<f64>) -> Self {
        Arc {
            a,
            b,
            b_x_a: b.cross(&a),
        }
    }

    /// Whether this arc (of a moving piece) and `other` (of a fixed piece, negated) cross:
    /// then the edges' cross product is a face normal of the Minkowski difference.
    fn crosses(&self, other: &Arc) -> bool {
        let cba = other.a.dot(&self.b_x_a);
        let dba = other.b.dot(&self.b_x_a);
        let adc = self.a.dot(&other.b_x_a);
        let bdc = self.b.dot(&other.b_x_a);
        cba * dba < 0.0 && adc * bdc < 0.0 && cba * bdc > 0.0
    }
}

/// What [`GapProbe::signed_gap`] keeps of a fixed piece beside its placement: its edges, their
/// (negated) arcs, and its own extents along its face normals.
#[derive(Clone)]
struct FixedPiece {
    edges: Vec<Edge>,
    arcs: Vec<Arc>,
    face_extents: Vec<(f64, f64)>,
}

/// A [`PenetrationProbe`] with what [`GapProbe::signed_gap`] needs of the fixed pieces.
#[derive(Clone)]
pub struct GapProbe {
    probe: PenetrationProbe,
    fixed_pieces: Vec<FixedPiece>,
}

impl GapProbe {
    /// Prepares the fixed solid placed at `pose` in the world.
    pub fn new(fixed: &Solid, pose: &Isometry3<f64>) -> Self {
        let probe = PenetrationProbe::new(fixed, pose);
        let fixed_pieces = (fixed.pieces.iter().zip(&probe.fixed))
            .map(|(piece, posed)| {
                let edges = edges_of(piece);
                let normal = |e: &Edge, i: usize| -posed.face_normals[e.faces[i]];
                let arcs = (edges.iter())
                    .map(|e| Arc::new(normal(e, 0), normal(e, 1)))
                    .collect();
                let face_extents = (posed.face_normals.iter())
                    .map(|n| project(&posed.vertices, n))
                    .collect();
                FixedPiece {
                    edges,
                    arcs,
                    face_extents,
                }
            })
            .collect();
        GapProbe {
            probe,
            fixed_pieces,
        }
    }
}

/// The fixed pieces near each piece of a moving solid at one pose, listed wide: a search
/// started with them ([`GapHints::start`]) takes a piece's near fixed pieces from here, and not
/// from the fixed solid's tree, while its bounds stay within `reach_m` of those listed here.
/// The pieces found are the same either way.
#[derive(Clone, Debug, Default)]
pub struct NearLists {
    /// The signed gap's margin they serve, m.
    margin_m: f64,
    /// How far a piece's bounds may lie beyond those listed here, m.
    reach_m: f64,
    /// Per moving piece: its bounds at the listed pose, and the fixed pieces within the
    /// margin, [`LIST_SLACK`] margins and `reach_m` of them (ascending).
    pieces: Vec<((P3, P3), Vec<u32>)>,
}

impl NearLists {
    /// The fixed pieces listed for moving piece `p`, if its `bounds` lie within the reach of
    /// those it was listed at, for `margin_m`.
    fn covering(&self, p: usize, bounds: &(P3, P3), margin_m: f64) -> Option<&[u32]> {
        let ((l0, h0), list) = self.pieces.get(p)?;
        let reach = self.reach_m;
        let inside = (0..3).all(|i| bounds.0[i] >= l0[i] - reach && bounds.1[i] <= h0[i] + reach);
        (margin_m == self.margin_m && inside).then_some(list.as_slice())
    }
}

/// What [`GapProbe::signed_gap`] remembers of a piece pair.
#[derive(Clone, Copy, Debug)]
struct Hint {
    /// Index of the candidate that gave the pair's gap ([`PiecePair::projected`]'s numbering).
    axis: usize,
    gap_m: f64,
}

/// A piece pair near at the present call, with what the last call remembered of it.
#[derive(Clone, Copy, Debug)]
struct Near {
    moving: usize,
    fixed: usize,
    hint: Option<Hint>,
}

/// What a moving piece keeps between calls: its placement (overwritten by each call) and what
/// does not depend on the pose.
#[derive(Clone, Default)]
struct MovingPiece {
    /// The piece at the present call's pose; its normals and edges only where a pair was
    /// tested ([`Self::oriented_at`]).
    posed: Posed,
    /// The call whose pose the normals, edges, [`Self::face_extents`] and centre are at.
    oriented_at: u64,
    /// Its largest distance of a vertex from the moving solid's origin, m.
    radius_m: f64,
    /// Its own extents along its face normals, in its own frame.
    local_extents: Vec<(f64, f64)>,
    /// The same at the pose the normals are at.
    face_extents: Vec<(f64, f64)>,
    edges: Vec<Edge>,
    /// The piece's centre (the mean of its vertices), at the pose the normals are at.
    centre: P3,
    local_centre: P3,
    /// The fixed pieces within the margin and [`LIST_SLACK`] of the piece's bounds as they
    /// were when listed (and those bounds, and the margin, m): while its bounds stay within the
    /// slack of those, the pieces near it with that margin are among these.
    listed: Vec<usize>,
    listed_at: Option<(P3, P3, f64)>,
}

impl MovingPiece {
    fn new(piece: &ConvexPiece) -> Self {
        MovingPiece {
            posed: Posed::default(),
            oriented_at: 0,
            radius_m: (piece.vertices.iter())
                .map(|v| v.coords.norm())
                .fold(0.0, f64::max),
            local_extents: (piece.face_normals.iter())
                .map(|n| project(&piece.vertices, n))
                .collect(),
            face_extents: Vec::new(),
            listed: Vec::new(),
            listed_at: None,
            edges: edges_of(piece),
            centre: P3::origin(),
            local_centre: P3::from(
                piece
                    .vertices
                    .iter()
                    .map(|v| v.coords)
                    .sum::<Vector3<f64>>()
                    / piece.vertices.len() as f64,
            ),
        }
    }

    /// Whether its bounds lie within `slack_m` of those it was listed at, with `margin_m`.
    fn still_listed(&self, margin_m: f64, slack_m: f64) -> bool {
        let (lo, hi) = self.posed.bounds;
        self.listed_at.is_some_and(|(l0, h0, margin)| {
            margin == margin_m
                && (0..3).all(|i| lo[i] >= l0[i] - slack_m && hi[i] <= h0[i] + slack_m)
        })
    }

    /// Places the vertices at `pose` (the normals, edges and extents wait for [`Self::orient`]).
    fn place(&mut self, piece: &ConvexPiece, pose: &Placement) {
        let vertices = &mut self.posed.vertices;
        vertices.clear();
        vertices.extend(piece.vertices.iter().map(|v| pose.point(v)));
        self.posed.bounds = bounds_of(vertices.iter().copied());
    }

    /// The separation from `fixed` along face normal `k` (of this piece, then of `fixed`, as
    /// [`PiecePair::projected`] numbers them) with only the vertices placed; `None` past them.
    fn face_gap(
        &self,
        piece: &ConvexPiece,
        (fixed, fixed_piece): (&Posed, &FixedPiece),
        pose: &Placement,
        k: usize,
    ) -> Option<f64> {
        let na = piece.face_normals.len();
        let ((a0, a1), (b0, b1)) = if k < na {
            let n = pose.rotation * piece.face_normals[k];
            let (lo, hi) = self.local_extents[k];
            let shift = n.dot(&pose.translation);
            ((lo + shift, hi + shift), project(&fixed.vertices, &n))
        } else {
            let n = fixed.face_normals.get(k - na)?;
            let extents = fixed_piece.face_extents[k - na];
            (project(&self.posed.vertices, n), extents)
        };
        Some((b0 - a1).max(a0 - b1))
    }

    /// Turns the normals to `pose`, and shifts the extents and the centre with it, once
    /// per call (the edges are the vertices').
    fn orient(&mut self, piece: &ConvexPiece, pose: &Placement, call: u64) -> &MovingPiece {
        if self.oriented_at != call {
            let posed = &mut self.posed;
            posed.face_normals.clear();
            (posed.face_normals).extend(piece.face_normals.iter().map(|n| pose.rotation * n));
            let shift = pose.translation;
            self.face_extents.clear();
            self.face_extents.extend(
                (posed.face_normals.iter().zip(&self.local_extents))
                    .map(|(n, (lo, hi))| (lo + n.dot(&shift), hi + n.dot(&shift))),
            );
            self.centre = pose.point(&self.local_centre);
            self.oriented_at = call;
        }
        self
    }
}

/// Each piece pair's last gap (or a lower bound of it) and axis, for
/// [`GapProbe::signed_gap`] (one per search), and the buffers its calls reuse: for one probe
/// and one moving solid.
#[derive(Clone, Default)]
pub struct GapHints<'a> {
    /// Sorted by the pair (moving piece, fixed piece).
    pairs: Vec<((usize, usize), Hint)>,
    /// The near fixed pieces listed near the search's poses ([`Self::start`]).
    lists: Option<&'a NearLists>,
    /// How far the moving solid may have moved since the last call: its origin, m, and its
    /// turn, rad; `None`: unknown.
    moved: Option<(f64, f64)>,
    /// The moving solid's pieces, in its order.
    pieces: Vec<MovingPiece>,
    /// Calls so far.
    call: u64,
    /// The present call's near pairs, in (moving, fixed) order, and what it found of each.
    near: Vec<Near>,
    found: Vec<Option<Hint>>,
    /// The fixed pieces near one moving piece.
    fixed_near: Vec<usize>,
}

impl<'a> GapHints<'a> {
    /// Tells the next call that the moving solid's origin has moved no more than
    /// `translation_m` since the last one, and the solid turned by no more than `turn_rad`: no
    /// point then moved farther than `translation_m + turn_rad` times its distance from the
    /// origin.
    pub fn moved(&mut self, translation_m: f64, turn_rad: f64) {
        self.moved = Some((translation_m, turn_rad));
    }

    /// Starts a new search (the pairs' hints and the motion are forgotten; the buffers, which
    /// do not change the results, are kept for the same moving solid).
    pub fn forget(&mut self) {
        self.pairs.clear();
        self.moved = None;
        self.lists = None;
    }

    /// Starts a new search ([`Self::forget`]) whose poses lie near those of `lists`
    /// ([`GapProbe::near_lists`]): a piece that moved beyond its listed fixed pieces takes them
    /// from there while it can (the results are the same; the fixed solid's tree is slower).
    pub fn start(&mut self, lists: &'a NearLists) {
        self.forget();
        self.lists = Some(lists);
    }

    /// How far any point of moving piece `p` may have moved since the last call, m.
    fn moved_m(&self, p: usize) -> f64 {
        self.moved.map_or(f64::INFINITY, |(t, turn)| {
            (t + turn * self.pieces[p].radius_m) * (1.0 + 1e-9) + 1e-12
        })
    }
}

/// Two pieces as [`PiecePair::gap`] sees them: the moving one (with its centre) and the fixed
/// one (with its negated arcs).
struct PiecePair<'a> {
    a: &'a MovingPiece,
    b: &'a Posed,
    b_piece: &'a FixedPiece,
}

impl PiecePair<'_> {
    /// Separation along candidate `k` by the projection of both pieces (any `k`; `None` for a
    /// cross product of parallel edges). The candidates: the face normals of `a`, then those of
    /// `b`, then one per pair of their edges (row by row).
    fn projected(&self, k: usize) -> Option<f64> {
        let (a, b) = (&self.a.posed, self.b);
        let (na, nb) = (a.face_normals.len(), b.face_normals.len());
        let ((a0, a1), (b0, b1)) = if k < na {
            (
                self.a.face_extents[k],
                project(&b.vertices, &a.face_normals[k]),
            )
        } else if k < na + nb {
            let n = &b.face_normals[k - na];
            (project(&a.vertices, n), self.b_piece.face_extents[k - na])
        } else {
            let (ea, eb) = self.edge_pair(k - na - nb);
            let n = self.edge_axis(ea, eb)?.0;
            (project(&a.vertices, &n), project(&b.vertices, &n))
        };
        Some((b0 - a1).max(a0 - b1))
    }

    /// The edges of candidate `k - na - nb`.
    fn edge_pair(&self, e: usize) -> (&Edge, &Edge) {
        let nb = self.b_piece.edges.len();
        (&self.a.edges[e / nb], &self.b_piece.edges[e % nb])
    }

    /// The unit cross product of two edges, turned away from `a`'s centre, and a point of
    /// each edge; `None` for parallel edges.
    fn edge_axis(&self, ea: &Edge, eb: &Edge) -> Option<(Vector3<f64>, P3, P3)> {
        let (va, vb) = (&self.a.posed.vertices, &self.b.vertices);
        let (pa, pb) = (va[ea.ends[0]], vb[eb.ends[0]]);
        let (da, db) = (va[ea.ends[1]] - pa, vb[eb.ends[1]] - pb);
        let n = da.cross(&db);
        let len = n.norm();
        if len <= 1e-9 * da.norm() * db.norm() {
            return None;
        }
        let n = n / len;
        let n = if n.dot(&(pa - self.a.centre)) < 0.0 {
            -n
        } else {
            n
        };
        Some((n, pa, pb))
    }

    /// The largest separation (metres; negative: minus the overlap depth) along the face
    /// normals and the edge pairs whose arcs cross, and the candidate that gives it: minus the
    /// penetration depth when they overlap. `first` is tried first (the last call's candidate,
    /// by projection). Stops as soon as it reaches `enough` (the caller's smallest gap so far,
    /// which this pair can then not lower) and returns the separation found by then.
    fn gap(&self, enough: f64, first: Option<usize>) -> (f64, usize) {
        let mut best = (f64::NEG_INFINITY, 0);
        let mut reached = |sep: f64, k: usize| {
            if sep > best.0 {
                best = (sep, k);
            }
            best.0 >= enough
        };
        let tried = first.and_then(|k| Some((self.projected(k)?, k)));
        if let Some((sep, k)) = tried
            && reached(sep, k)
        {
            return best;
        }
        let faces = self.a.posed.face_normals.len() + self.b.face_normals.len();
        for k in 0..faces {
            let sep = self.projected(k).expect("a face normal is an axis");
            if reached(sep, k) {
                return best;
            }
        }
        let nb = self.b_piece.edges.len();
        let normals = &self.a.posed.face_normals;
        for (i, ea) in self.a.edges.iter().enumerate() {
            let arc_a = Arc::new(normals[ea.faces[0]], normals[ea.faces[1]]);
            for (j, (eb, arc_b)) in self
                .b_piece
                .edges
                .iter()
                .zip(&self.b_piece.arcs)
                .enumerate()
            {
                if !arc_a.crosses(arc_b) {
                    continue;
                }
                let Some((n, pa, pb)) = self.edge_axis(ea, eb) else {
                    continue;
                };
                if reached(n.dot(&(pb - pa)), faces + i * nb + j) {
                    return best;
                }
            }
        }
        best
    }
}

impl GapProbe {
    /// The signed gap (metres) between `moving` placed at `pose` and the fixed solid: over the
    /// piece pairs whose bounds come within `margin_m`, the least of each pair's largest
    /// separation along the separating-axis candidates ([`PiecePair::gap`]); `margin_m` when no pair
    /// comes that close. Negative: minus the penetration depth of
    /// the deepest pair ([`PenetrationProbe::max_penetration`]); zero exactly when touching;
    /// positive: a lower bound of the distance.
    ///
    /// `hints` remembers, from the previous call, a lower bound of each pair's signed distance
    /// and the axis that gave it: the pair closest then is tried first and each pair on its last
    /// axis first. When the caller bounds how far the solid moved since ([`GapHints::moved`]), a
    /// pair's signed distance is at least its bound less how far its moving piece moved (the
    /// signed distance of two convex bodies changes no faster than their points move); a pair
    /// whose bound is still no smaller than the least gap found so far is not tested, nor turned.
    /// A positive value may then be larger than without the hints (never larger than the
    /// distance); its sign, and a negative value, do not depend on them.
    pub fn signed_gap(
        &self,
        moving: &Solid,
        pose: &Isometry3<f64>,
        margin_m: f64,
        hints: &mut GapHints,
    ) -> f64 {
        if hints.pieces.len() != moving.pieces.len() {
            hints.pieces = moving.pieces.iter().map(MovingPiece::new).collect();
        }
        hints.call += 1;
        let pose = Placement::of(pose);
        self.near_pairs(moving, &pose, margin_m, hints);
        let least = self.least_gap(moving, &pose, margin_m, hints);
        hints.moved = None;
        least
    }

    /// Places every moving piece at `pose` and lists the pairs whose bounds come within
    /// `margin_m` into `hints.near`, each with its hint from the last call.
    fn near_pairs(&self, moving: &Solid, pose: &Placement, margin_m: f64, hints: &mut GapHints) {
        hints.near.clear();
        let mut known = hints.pairs.iter().peekable();
        let lists = hints.lists;
        for (p, piece) in moving.pieces.iter().enumerate() {
            let placed = &mut hints.pieces[p];
            placed.place(piece, pose);
            let slack_m = LIST_SLACK * margin_m;
            if !placed.still_listed(margin_m, slack_m) {
                let bounds = placed.posed.bounds;
                let wide_m = margin_m + slack_m;
                match lists.and_then(|l| l.covering(p, &bounds, margin_m)) {
                    Some(listed) => {
                        placed.listed.clear();
                        placed.listed.extend(
                            (listed.iter().map(|&f| f as usize))
                                .filter(|&f| within(&bounds, &self.probe.fixed[f].bounds, wide_m)),
                        );
                    }
                    None => self.probe.near_into(&bounds, wide_m, &mut placed.listed),
                }
                placed.listed_at = Some((bounds.0, bounds.1, margin_m));
            }
            hints.fixed_near.clear();
            hints.fixed_near.extend(
                (placed.listed.iter().copied()).filter(|&f| {
                    within(&placed.posed.bounds, &self.probe.fixed[f].bounds, margin_m)
                }),
            );
            for &f in &hints.fixed_near {
                let hint = loop {
                    match known.peek() {
                        Some(&&(k, h)) if k == (p, f) => break Some(h),
                        Some(&&(k, _)) if k < (p, f) => _ = known.next(),
                        _ => break None,
                    }
                };
                hints.near.push(Near {
                    moving: p,
                    fixed: f,
                    hint,
                });
            }
        }
    }

    /// The least gap over `hints.near` (at most `margin_m`), the pair closest last time first;
    /// remembers each pair's gap or bound as the next call's hints.
    fn least_gap(
        &self,
        moving: &Solid,
        pose: &Placement,
        margin_m: f64,
        hints: &mut GapHints,
    ) -> f64 {
        let gap = |n: &Near| n.hint.map_or(f64::INFINITY, |h| h.gap_m);
        let closest = (0..hints.near.len())
            .min_by(|&a, &b| gap(&hints.near[a]).total_cmp(&gap(&hints.near[b])));
        let order = closest
            .into_iter()
            .chain((0..hints.near.len()).filter(|&i| Some(i) != closest));
        let mut least = margin_m;
        hints.found.clear();
        hints.found.resize(hints.near.len(), None);
        for i in order {
            let Near {
                moving: p,
                fixed: f,
                hint,
            } = hints.near[i];
            let bound = hint.map(|h| Hint {
                gap_m: h.gap_m - hints.moved_m(p),
                ..h
            });
            if let Some(b) = bound.filter(|b| b.gap_m >= least) {
                hints.found[i] = Some(b);
                continue;
            }
            // The last axis first, before turning the piece's normals where it is a face's.
            let fixed = (&self.probe.fixed[f], &self.fixed_pieces[f]);
            let piece = &moving.pieces[p];
            if let Some(h) = hint.and_then(|h| {
                let gap_m = hints.pieces[p].face_gap(piece, fixed, pose, h.axis)?;
                (gap_m >= least).then_some(Hint { gap_m, ..h })
            }) {
                hints.found[i] = Some(h);
                continue;
            }
            let pair = PiecePair {
                a: hints.pieces[p].orient(&moving.pieces[p], pose, hints.call),
                b: fixed.0,
                b_piece: fixed.1,
            };
            let (gap, axis) = pair.gap(least, hint.map(|h| h.axis));
            least = least.min(gap);
            hints.found[i] = Some(Hint { axis, gap_m: gap });
        }
        hints.pairs.clear();
        hints
            .pairs
            .extend((hints.near.iter().zip(&hints.found)).map(|(n, h)| {
                (
                    (n.moving, n.fixed),
                    h.expect("every pair is tested or bounded"),
                )
            }));
        least
    }

    /// The fixed pieces near each piece of `moving` at `pose` ([`NearLists`]), for searches
    /// with `margin_m` whose pieces' bounds stay within `reach_m` of these.
    pub fn near_lists(
        &self,
        moving: &Solid,
        pose: &Isometry3<f64>,
        margin_m: f64,
        reach_m: f64,
    ) -> NearLists {
        // A millionth wider: a piece within the reach then keeps every fixed piece it can list,
        // whatever the rounding.
        let wide_m = ((1.0 + LIST_SLACK) * margin_m + reach_m) * (1.0 + 1e-6);
        let mut listed = Vec::new();
        let pieces = (moving.pieces.iter())
            .map(|piece| {
                let bounds = bounds_of(piece.vertices.iter().map(|v| pose * v));
                self.probe.near_into(&bounds, wide_m, &mut listed);
                (bounds, listed.iter().map(|&f| f as u32).collect())
            })
            .collect();
        NearLists {
            margin_m,
            reach_m,
            pieces,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::twin::physics::penetration::tests::cube;

    fn solid(pieces: Vec<ConvexPiece>) -> Solid {
        Solid {
            pieces,
            boundary: None,
        }
    }

    /// Poses of a unit cube along a turning path past two fixed cubes: overlapping, touching
    /// and apart.
    fn path() -> Vec<Isometry3<f64>> {
        (0..400)
            .map(|k| {
                let s = k as f64 / 400.0;
                Isometry3::new(
                    Vector3::new(0.6 + 2.3 * s, 0.3 - 0.5 * s, 0.2 + 0.1 * s),
                    Vector3::new(0.3 * s, -0.2 * s, 0.7 * s),
                )
            })
            .collect()
    }

    #[test]
    fn the_gap_is_minus_the_depth_when_overlapping_and_positive_when_apart() {
        let fixed = solid(vec![cube(0.0, 0.0, 0.0), cube(3.5, 0.0, 0.0)]);
        let probe = GapProbe::new(&fixed, &Isometry3::identity());
        let moving = solid(vec![cube(0.0, 0.0, 0.0)]);
        let (mut overlapping, mut apart) = (0, 0);
        for pose in path() {
            let depth = probe.probe.max_penetration(&moving, &pose);
            let gap = probe.signed_gap(&moving, &pose, 0.5, &mut GapHints::default());
            if depth > 0.0 {
                overlapping += 1;
                assert!((gap + depth).abs() < 1e-12, "{pose}: {gap} against {depth}");
            } else {
                apart += 1;
                assert!((0.0..=0.5).contains(&gap), "{pose}: {gap}");
            }
        }
        assert!(overlapping > 50 && apart > 50, "{overlapping} {apart}");
    }

    #[test]
    fn hints_change_no_sign_and_no_depth_only_the_bound_of_a_distance() {
        let fixed = solid(vec![cube(0.0, 0.0, 0.0), cube(3.5, 0.0, 0.0)]);
        let probe = GapProbe::new(&fixed, &Isometry3::identity());
        let moving = solid(vec![cube(0.0, 0.0, 0.0), cube(0.0, 0.0, 1.0)]);
        let poses = path();
        let mut hints = GapHints::default();
        for (k, pose) in poses.iter().enumerate() {
            if k > 0 {
                // Per step: the origin moves under 6 mm and the cube turns under 3 mrad.
                hints.moved(6e-3, 3e-3);
            }
            let hinted = probe.signed_gap(&moving, pose, 0.5, &mut hints);
            let fresh = probe.signed_gap(&moving, pose, 0.5, &mut GapHints::default());
            if fresh <= 0.0 {
                assert_eq!(hinted, fresh, "{k}");
            } else {
                let apart = distance(&moving, pose, &fixed);
                assert!(hinted > 0.0 && hinted >= fresh, "{k}: {hinted} {fresh}");
                assert!(
                    hinted <= apart + 1e-5,
                    "{k}: {hinted} beyond the distance {apart}"
                );
            }
        }
    }

    #[test]
    fn near_lists_change_no_gap_and_serve_only_within_their_reach() {
        let fixed = solid(vec![cube(0.0, 0.0, 0.0), cube(3.5, 0.0, 0.0)]);
        let probe = GapProbe::new(&fixed, &Isometry3::identity());
        let moving = solid(vec![cube(0.0, 0.0, 0.0), cube(0.0, 0.0, 1.0)]);
        let poses = path();
        // Listed at the path's start, reaching a quarter of the way along it; a piece's list
        // is renewed when it moves 0.4 (four margins of 0.1), from the lists, then the tree.
        let lists = probe.near_lists(&moving, &poses[0], 0.1, 0.6);
        let bounds = |k: usize, p: usize| {
            let piece = moving.pieces[p].transformed(&poses[k]);
            bounds_of(piece.vertices.iter().copied())
        };
        assert!(lists.covering(0, &bounds(0, 0), 0.1).is_some());
        assert!(
            lists.covering(0, &bounds(0, 0), 0.2).is_none(),
            "another margin"
        );
        assert!(
            lists.covering(0, &bounds(399, 0), 0.1).is_none(),
            "beyond the reach"
        );
        let (mut listed, mut plain) = (GapHints::default(), GapHints::default());
        listed.start(&lists);
        for (k, pose) in poses.iter().enumerate() {
            if k > 0 {
                listed.moved(6e-3, 3e-3);
                plain.moved(6e-3, 3e-3);
            }
            let a = probe.signed_gap(&moving, pose, 0.1, &mut listed);
            let b = probe.signed_gap(&moving, pose, 0.1, &mut plain);
            assert_eq!(a.to_bits(), b.to_bits(), "{k}: {a} against {b}");
        }
    }

    /// The distance between `moving` at `pose` and `fixed` (parry's, in f32), m.
    fn distance(moving: &Solid, pose: &Isometry3<f64>, fixed: &Solid) -> f64 {
        use parry3d::math::{Pose, Vector};
        let placed = |p: &ConvexPiece| {
            let c = p.centroid();
            let at = Pose::from_translation(Vector::new(c.x as f32, c.y as f32, c.z as f32));
            (at, p.collider_shape().expect("a cube is a shape"))
        };
        let fixed: Vec<_> = fixed.pieces.iter().map(placed).collect();
        let mut least = f64::INFINITY;
        for a in moving.pieces.iter().map(|p| placed(&p.transformed(pose))) {
            for b in &fixed {
                let d = parry3d::query::distance(&a.0, &*a.1, &b.0, &*b.1).expect("convex shapes");
                least = least.min(d.distance as f64);
            }
        }
        least
    }
}
