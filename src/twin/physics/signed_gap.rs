//! The signed gap between a moving solid and a probe's fixed one, for finding the first contact
//! along a path of poses (the geometric manifold sampler): the separating-axis test of
//! [`super::penetration`], made cheap for many calls on nearby poses. Each call remembers, per
//! piece pair, the axis that separated it and a lower bound of its distance ([`GapHints`]), so
//! that the next call tries that axis first and skips the pairs that cannot be the closest; the
//! buffers are kept between calls, and the face normals' own extents are not projected again.

use super::penetration::{PenetrationProbe, Posed, bounds_of, project, within};
use crate::twin::geometry::solid::P3;
use crate::twin::geometry::solid::{ConvexPiece, Solid};
use nalgebra::{Isometry3, Vector3};

/// How far a moving piece's bounds may move before the fixed pieces near it are looked up
/// again, as a share of the margin (the lookup then takes the margin and this much more).
const LIST_SLACK: f64 = 4.0;

/// What [`PenetrationProbe::signed_gap`] remembers of a piece pair.
#[derive(Clone, Copy, Debug)]
struct Hint {
    /// Index of the axis that gave the pair's gap ([`posed_gap`]'s numbering).
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
    /// The piece at the present call's pose; its normals, edges and extents only where a pair
    /// was tested ([`Self::oriented_at`]).
    posed: Posed,
    /// The call whose pose the normals, edges and extents are at.
    oriented_at: u64,
    /// Its largest distance of a vertex from the moving solid's origin, m.
    radius_m: f64,
    /// Its own extents along its face normals, in its own frame.
    local_extents: Vec<(f64, f64)>,
    /// The fixed pieces within the margin and [`LIST_SLACK`] of the piece's bounds as they
    /// were when listed (and those bounds): while its bounds stay within the slack of those,
    /// the pieces near it are among these.
    listed: Vec<usize>,
    listed_bounds: Option<(P3, P3)>,
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
            listed: Vec::new(),
            listed_bounds: None,
        }
    }

    /// Whether its bounds lie within `slack_m` of those it was listed at.
    fn still_listed(&self, slack_m: f64) -> bool {
        let (lo, hi) = self.posed.bounds;
        self.listed_bounds.is_some_and(|(l0, h0)| {
            (0..3).all(|i| lo[i] >= l0[i] - slack_m && hi[i] <= h0[i] + slack_m)
        })
    }

    /// Places the vertices at `pose` (the normals, edges and extents wait for [`Self::orient`]).
    fn place(&mut self, piece: &ConvexPiece, pose: &Isometry3<f64>) {
        let vertices = &mut self.posed.vertices;
        vertices.clear();
        vertices.extend(piece.vertices.iter().map(|v| pose * v));
        self.posed.bounds = bounds_of(vertices.iter().copied());
    }

    /// Turns the normals and edges to `pose`, and shifts the extents with it, once per call.
    fn orient(&mut self, piece: &ConvexPiece, pose: &Isometry3<f64>, call: u64) -> &Posed {
        if self.oriented_at != call {
            let posed = &mut self.posed;
            posed.face_normals.clear();
            posed
                .face_normals
                .extend(piece.face_normals.iter().map(|n| pose * n));
            posed.edge_dirs.clear();
            posed
                .edge_dirs
                .extend(piece.edge_dirs.iter().map(|e| pose * e));
            let shift = pose.translation.vector;
            posed.face_extents.clear();
            posed.face_extents.extend(
                (posed.face_normals.iter().zip(&self.local_extents))
                    .map(|(n, (lo, hi))| (lo + n.dot(&shift), hi + n.dot(&shift))),
            );
            self.oriented_at = call;
        }
        &self.posed
    }
}

/// Each piece pair's last gap (or a lower bound of it) and axis, for
/// [`PenetrationProbe::signed_gap`] (one per search), and the buffers its calls reuse.
#[derive(Clone, Default)]
pub struct GapHints {
    /// Sorted by the pair (moving piece, fixed piece).
    pairs: Vec<((usize, usize), Hint)>,
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

impl GapHints {
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
    }

    /// How far any point of moving piece `p` may have moved since the last call, m.
    fn moved_m(&self, p: usize) -> f64 {
        self.moved.map_or(f64::INFINITY, |(t, turn)| {
            (t + turn * self.pieces[p].radius_m) * (1.0 + 1e-9) + 1e-12
        })
    }
}

/// The separating-axis candidate `k` of two pieces: the face normals of `a`, then those of
/// `b`, then the cross products of their edge directions (row by row); `None` for a cross
/// product of parallel edges.
fn axis(a: &Posed, b: &Posed, k: usize) -> Option<Vector3<f64>> {
    let (na, nb) = (a.face_normals.len(), b.face_normals.len());
    if k < na {
        return Some(a.face_normals[k]);
    }
    if k < na + nb {
        return Some(b.face_normals[k - na]);
    }
    let e = k - na - nb;
    let c = a.edge_dirs[e / b.edge_dirs.len()].cross(&b.edge_dirs[e % b.edge_dirs.len()]);
    let len = c.norm();
    (len > 1e-9).then(|| c / len)
}

/// The extents of `a` and `b` along candidate `k` ([`axis`]); a face normal's own piece gives
/// its kept [`Posed::face_extents`].
fn extents(a: &Posed, b: &Posed, k: usize) -> Option<((f64, f64), (f64, f64))> {
    let na = a.face_normals.len();
    let axis = axis(a, b, k)?;
    Some(match k {
        k if k < na => (a.face_extents[k], project(&b.vertices, &axis)),
        k if k < na + b.face_normals.len() => (project(&a.vertices, &axis), b.face_extents[k - na]),
        _ => (project(&a.vertices, &axis), project(&b.vertices, &axis)),
    })
}

/// The largest separation (metres; negative: minus the overlap depth) of two convex pieces
/// along the separating-axis candidates ([`axis`]), and the candidate that gives it: minus the
/// penetration depth when they overlap. `first` is tried first (the last call's axis). Stops
/// as soon as it reaches `enough` (the caller's smallest gap so far, which this pair can then
/// not lower) and returns the separation found by then.
fn posed_gap(a: &Posed, b: &Posed, enough: f64, first: Option<usize>) -> (f64, usize) {
    let mut best = (f64::NEG_INFINITY, 0);
    let count = a.face_normals.len() + b.face_normals.len() + a.edge_dirs.len() * b.edge_dirs.len();
    for k in first.into_iter().chain(0..count) {
        let Some(((a0, a1), (b0, b1))) = extents(a, b, k) else {
            continue;
        };
        let sep = (b0 - a1).max(a0 - b1);
        if sep > best.0 {
            best = (sep, k);
        }
        if best.0 >= enough {
            break;
        }
    }
    best
}

impl PenetrationProbe {
    /// The signed gap (metres) between `moving` placed at `pose` and the fixed solid: over the
    /// piece pairs whose bounds come within `margin_m`, the least of each pair's largest
    /// separation along the separating-axis candidates ([`posed_gap`]); `margin_m` when no pair
    /// comes that close. Negative: minus the penetration depth ([`Self::max_penetration`]) of
    /// the deepest pair; zero exactly when touching; positive: a lower bound of the distance.
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
        self.near_pairs(moving, pose, margin_m, hints);
        let least = self.least_gap(moving, pose, margin_m, hints);
        hints.moved = None;
        least
    }

    /// Places every moving piece at `pose` and lists the pairs whose bounds come within
    /// `margin_m` into `hints.near`, each with its hint from the last call.
    fn near_pairs(
        &self,
        moving: &Solid,
        pose: &Isometry3<f64>,
        margin_m: f64,
        hints: &mut GapHints,
    ) {
        hints.near.clear();
        let mut known = hints.pairs.iter().peekable();
        for (p, piece) in moving.pieces.iter().enumerate() {
            let placed = &mut hints.pieces[p];
            placed.place(piece, pose);
            let slack_m = LIST_SLACK * margin_m;
            if !placed.still_listed(slack_m) {
                let bounds = placed.posed.bounds;
                self.near_into(&bounds, margin_m + slack_m, &mut placed.listed);
                placed.listed_bounds = Some(bounds);
            }
            hints.fixed_near.clear();
            hints.fixed_near.extend(
                (placed.listed.iter().copied())
                    .filter(|&f| within(&placed.posed.bounds, &self.fixed[f].bounds, margin_m)),
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
        pose: &Isometry3<f64>,
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
            let placed = hints.pieces[p].orient(&moving.pieces[p], pose, hints.call);
            let (gap, axis) = posed_gap(placed, &self.fixed[f], least, hint.map(|h| h.axis));
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
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::twin::geometry::planar::rect;
    use crate::twin::geometry::solid::ZPlane;

    fn cube(x: f64, y: f64, z: f64) -> ConvexPiece {
        ConvexPiece::slab(
            &rect(x, y, x + 1.0, y + 1.0),
            ZPlane::flat(z),
            ZPlane::flat(z + 1.0),
        )
    }

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
        let probe = PenetrationProbe::new(&fixed, &Isometry3::identity());
        let moving = solid(vec![cube(0.0, 0.0, 0.0)]);
        let (mut overlapping, mut apart) = (0, 0);
        for pose in path() {
            let depth = probe.max_penetration(&moving, &pose);
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
        let probe = PenetrationProbe::new(&fixed, &Isometry3::identity());
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
                assert!(hinted > 0.0 && hinted >= fresh, "{k}: {hinted} {fresh}");
            }
        }
    }
}
