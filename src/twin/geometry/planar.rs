//! Planar (2-D) geometry in metres: rings, boolean operations, mitred offsets and the exact convex
//! decomposition of a polygon with holes (constrained Delaunay triangulation, then Hertel-Mehlhorn
//! merging). Every solid in pegtwin is an extrusion of these regions, so the 3-D pieces are exact.

use geo::{
    BooleanOps, Coord, LineString, MultiPolygon, Polygon, TriangulateDelaunay,
    triangulate_delaunay::DelaunayTriangulationConfig, unary_union,
};
use nalgebra::{Point2, Vector2};
use std::collections::HashMap;

/// A point in a plane, metres.
pub type P2 = Point2<f64>;

/// A closed polygon region: an outer ring (counter-clockwise) and holes (clockwise). Rings do not
/// repeat their first vertex. The material is on the left of every edge.
#[derive(Clone, Debug)]
pub struct Region {
    pub outer: Vec<P2>,
    pub holes: Vec<Vec<P2>>,
}

impl Region {
    /// All rings, outer first.
    pub fn rings(&self) -> impl Iterator<Item = &Vec<P2>> {
        std::iter::once(&self.outer).chain(self.holes.iter())
    }

    /// Area in m^2 (outer minus holes).
    pub fn area(&self) -> f64 {
        signed_area(&self.outer) + self.holes.iter().map(|h| signed_area(h)).sum::<f64>()
    }
}

/// Snap radius for the triangulation: far below any feature (0.1 nm).
const SNAP_RADIUS_M: f64 = 1e-10;

/// Smallest turn (radians) between consecutive edges of a ring or a convex piece. The engine's
/// convex hull merges faces less than about 1.5 deg apart and drops the vertex between them (a
/// 12-vertex prism of the `plug3` hole came back as a box), so pegtwin never makes such faces.
pub const MIN_TURN_RAD: f64 = 1.6 * std::f64::consts::PI / 180.0;

/// Pieces of a decomposition smaller than this are slivers of rounding, not material (1 um^2).
const DEGENERATE_AREA_M2: f64 = 1e-12;

/// Vertices of a boolean result closer than this are merged (1 nm).
const MERGE_DISTANCE_M: f64 = 1e-9;

/// Signed area of a ring (positive when counter-clockwise), m^2.
pub fn signed_area(ring: &[P2]) -> f64 {
    let n = ring.len();
    (0..n)
        .map(|i| {
            let (a, b) = (ring[i], ring[(i + 1) % n]);
            a.x * b.y - b.x * a.y
        })
        .sum::<f64>()
        * 0.5
}

/// 2-D cross product of two vectors.
pub fn cross(a: Vector2<f64>, b: Vector2<f64>) -> f64 {
    a.x * b.y - a.y * b.x
}

/// The convex hull of a point set, counter-clockwise, collinear points dropped (Andrew's chain).
pub fn convex_hull(points: &[P2]) -> Vec<P2> {
    let mut pts: Vec<P2> = points.to_vec();
    pts.sort_by(|a, b| a.x.total_cmp(&b.x).then(a.y.total_cmp(&b.y)));
    pts.dedup();
    if pts.len() < 3 {
        return pts;
    }
    let mut hull: Vec<P2> = Vec::with_capacity(pts.len() * 2);
    for pass in 0..2 {
        let start = hull.len();
        let iter: Box<dyn Iterator<Item = &P2>> = if pass == 0 {
            Box::new(pts.iter())
        } else {
            Box::new(pts.iter().rev())
        };
        for &p in iter {
            while hull.len() >= start + 2 {
                let (a, b) = (hull[hull.len() - 2], hull[hull.len() - 1]);
                if cross(b - a, p - b) <= 0.0 {
                    hull.pop();
                } else {
                    break;
                }
            }
            hull.push(p);
        }
        hull.pop();
    }
    hull
}

/// The number of sides of a regular polygon inscribed in a circle of `radius` whose chord error
/// (sagitta) is at most `tol`.
pub fn sides_for_circle(radius: f64, tol: f64) -> usize {
    let half_angle = (1.0 - (tol / radius).min(1.0)).acos();
    ((std::f64::consts::PI / half_angle).ceil() as usize).max(8)
}

/// A regular polygon of `sides` vertices on a circle, counter-clockwise, first vertex at `phase`.
pub fn circle(center: P2, radius: f64, sides: usize, phase: f64) -> Vec<P2> {
    (0..sides)
        .map(|i| {
            let a = phase + std::f64::consts::TAU * i as f64 / sides as f64;
            center + Vector2::new(a.cos(), a.sin()) * radius
        })
        .collect()
}

/// A polygon on a circle, counter-clockwise, with a vertex at each of `through` (angles in
/// radians) and uniform subdivisions between them so that the chord error is at most `tol`. Putting
/// vertices where other pieces cross the circle keeps the union free of tiny edges.
pub fn circle_through(center: P2, radius: f64, through: &[f64], tol: f64) -> Vec<P2> {
    let max_step = 2.0 * (1.0 - (tol / radius).min(1.0)).acos();
    let tau = std::f64::consts::TAU;
    let mut angles: Vec<f64> = through.iter().map(|a| a.rem_euclid(tau)).collect();
    angles.sort_by(f64::total_cmp);
    angles.dedup_by(|a, b| (*a - *b).abs() < 1e-12);
    if angles.is_empty() {
        angles.push(0.0);
    }
    let mut out = Vec::new();
    for (k, &a0) in angles.iter().enumerate() {
        let a1 = if k + 1 < angles.len() {
            angles[k + 1]
        } else {
            angles[0] + tau
        };
        let n = ((a1 - a0) / max_step).ceil().max(1.0) as usize;
        let n = if angles.len() == 1 { n.max(8) } else { n };
        for i in 0..n {
            let a = a0 + (a1 - a0) * i as f64 / n as f64;
            out.push(center + Vector2::new(a.cos(), a.sin()) * radius);
        }
    }
    out
}

/// An axis-aligned rectangle, counter-clockwise.
pub fn rect(x0: f64, y0: f64, x1: f64, y1: f64) -> Vec<P2> {
    vec![
        P2::new(x0, y0),
        P2::new(x1, y0),
        P2::new(x1, y1),
        P2::new(x0, y1),
    ]
}

/// Distance from a point to a segment.
pub fn distance_to_segment(p: P2, a: P2, b: P2) -> f64 {
    let ab = b - a;
    let len2 = ab.norm_squared();
    let t = if len2 > 0.0 {
        ((p - a).dot(&ab) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (p - (a + ab * t)).norm()
}

fn to_geo_ring(ring: &[P2]) -> LineString<f64> {
    LineString::new(ring.iter().map(|p| Coord { x: p.x, y: p.y }).collect())
}

fn to_geo(region: &Region) -> Polygon<f64> {
    Polygon::new(
        to_geo_ring(&region.outer),
        region.holes.iter().map(|h| to_geo_ring(h)).collect(),
    )
}

fn from_geo_ring(ls: &LineString<f64>, ccw: bool) -> Vec<P2> {
    let mut ring: Vec<P2> = ls.coords().map(|c| P2::new(c.x, c.y)).collect();
    if ring.len() > 1 && ring.first() == ring.last() {
        ring.pop();
    }
    // Boolean operations can leave two vertices a few picometres apart where an input vertex
    // sits on another polygon's edge: merge them so that no edge is shorter than a nanometre.
    let mut cleaned: Vec<P2> = Vec::with_capacity(ring.len());
    for p in ring {
        if cleaned
            .last()
            .is_none_or(|q: &P2| (p - q).norm() > MERGE_DISTANCE_M)
        {
            cleaned.push(p);
        }
    }
    while cleaned.len() > 1 && (cleaned[0] - cleaned[cleaned.len() - 1]).norm() <= MERGE_DISTANCE_M
    {
        cleaned.pop();
    }
    let mut ring = cleaned;
    if (signed_area(&ring) > 0.0) != ccw {
        ring.reverse();
    }
    ring
}

fn from_geo(mp: &MultiPolygon<f64>) -> Vec<Region> {
    mp.0.iter()
        .map(|p| Region {
            outer: from_geo_ring(p.exterior(), true),
            holes: p
                .interiors()
                .iter()
                .map(|h| from_geo_ring(h, false))
                .collect(),
        })
        .collect()
}

fn multi(regions: &[Region]) -> MultiPolygon<f64> {
    MultiPolygon(regions.iter().map(to_geo).collect())
}

fn union_multi(polygons: &[Vec<P2>]) -> MultiPolygon<f64> {
    let polys: Vec<Polygon<f64>> = polygons
        .iter()
        .map(|r| Polygon::new(to_geo_ring(r), vec![]))
        .collect();
    unary_union(&polys)
}

/// The union of counter-clockwise polygons, which may overlap (for example the convex pieces of
/// a profile).
pub fn union(polygons: &[Vec<P2>]) -> Vec<Region> {
    from_geo(&union_multi(polygons))
}

/// `regions` minus the union of `polygons` (which may overlap).
pub fn difference(regions: &[Region], polygons: &[Vec<P2>]) -> Vec<Region> {
    from_geo(&multi(regions).difference(&union_multi(polygons)))
}

/// Exact convex decomposition of a region: a constrained Delaunay triangulation of the region
/// (holes excluded), then Hertel-Mehlhorn merging (a diagonal is removed whenever both of its
/// ends stay convex). At most four times the optimal number of pieces; no point is moved.
pub fn convex_decomposition(region: &Region) -> Vec<Vec<P2>> {
    let triangles = triangulate(region);
    let mut index: HashMap<(u64, u64), usize> = HashMap::new();
    let mut vertices: Vec<P2> = Vec::new();
    let mut id = |c: Coord<f64>| -> usize {
        *index
            .entry((c.x.to_bits(), c.y.to_bits()))
            .or_insert_with(|| {
                vertices.push(P2::new(c.x, c.y));
                vertices.len() - 1
            })
    };
    let mut polys: Vec<Vec<usize>> = triangles
        .iter()
        .map(|t| t.iter().map(|p| id(Coord { x: p.x, y: p.y })).collect())
        .collect();
    hertel_mehlhorn(&vertices, &mut polys);
    polys
        .into_iter()
        .map(|p| p.into_iter().map(|i| vertices[i]).collect::<Vec<_>>())
        .filter(|p| signed_area(p) > DEGENERATE_AREA_M2)
        .collect()
}

/// A constrained Delaunay triangulation of a region (holes excluded), counter-clockwise
/// triangles whose corners are the region's own vertices, bit for bit.
pub fn triangulate(region: &Region) -> Vec<[P2; 3]> {
    let config = DelaunayTriangulationConfig {
        snap_radius: SNAP_RADIUS_M,
    };
    let triangles = to_geo(region)
        .constrained_triangulation(config)
        .unwrap_or_default();
    triangles
        .iter()
        .map(|t| {
            let p = |c: Coord<f64>| P2::new(c.x, c.y);
            let (a, b, c) = (p(t.v1()), p(t.v2()), p(t.v3()));
            if cross(b - a, c - a) < 0.0 {
                [a, c, b]
            } else {
                [a, b, c]
            }
        })
        .collect()
}

/// Merges counter-clockwise convex polygons that share an edge while the union stays convex.
fn hertel_mehlhorn(vertices: &[P2], polys: &mut Vec<Vec<usize>>) {
    loop {
        let mut edge_owner: HashMap<(usize, usize), usize> = HashMap::new();
        for (pi, p) in polys.iter().enumerate() {
            for k in 0..p.len() {
                edge_owner.insert((p[k], p[(k + 1) % p.len()]), pi);
            }
        }
        let mut merged_any = false;
        let mut alive = vec![true; polys.len()];
        for pi in 0..polys.len() {
            if !alive[pi] {
                continue;
            }
            let mut k = 0;
            while k < polys[pi].len() {
                let n = polys[pi].len();
                let (a, b) = (polys[pi][k], polys[pi][(k + 1) % n]);
                let Some(&qi) = edge_owner.get(&(b, a)) else {
                    k += 1;
                    continue;
                };
                if qi == pi || !alive[qi] {
                    k += 1;
                    continue;
                }
                if let Some(m) = merge_if_convex(vertices, &polys[pi], &polys[qi], a, b) {
                    alive[qi] = false;
                    polys[pi] = m;
                    for (e, p) in polys[pi].iter().enumerate() {
                        let next = polys[pi][(e + 1) % polys[pi].len()];
                        edge_owner.insert((*p, next), pi);
                    }
                    merged_any = true;
                    k = 0;
                } else {
                    k += 1;
                }
            }
        }
        let mut i = 0;
        polys.retain(|_| {
            i += 1;
            alive[i - 1]
        });
        if !merged_any {
            break;
        }
    }
}

/// Joins `p` (with edge a->b) and `q` (with edge b->a) if the result is convex.
fn merge_if_convex(
    vertices: &[P2],
    p: &[usize],
    q: &[usize],
    a: usize,
    b: usize,
) -> Option<Vec<usize>> {
    let pa = p.iter().position(|&v| v == a)?;
    let qb = q.iter().position(|&v| v == b)?;
    // Walk p from b around to a, then q from a (after b->a) around to b (exclusive ends).
    let mut out = Vec::with_capacity(p.len() + q.len() - 2);
    let np = p.len();
    for s in 0..np {
        out.push(p[(pa + 1 + s) % np]);
    }
    let nq = q.len();
    for s in 0..nq - 2 {
        out.push(q[(qb + 2 + s) % nq]);
    }
    let n = out.len();
    let convex = (0..n).all(|i| {
        let (u, v, w) = (
            vertices[out[(i + n - 1) % n]],
            vertices[out[i]],
            vertices[out[(i + 1) % n]],
        );
        turn(u, v, w) >= MIN_TURN_RAD
    });
    convex.then_some(out)
}

/// The signed turn (radians, positive to the left) at `v` walking u -> v -> w.
fn turn(u: P2, v: P2, w: P2) -> f64 {
    let (a, b) = (v - u, w - v);
    cross(a, b).atan2(a.dot(&b))
}

/// Drops the vertices of a ring where it turns by less than `MIN_TURN_RAD`, as long as the
/// simplified ring stays within `tol` of every dropped vertex.
pub fn simplify_ring(ring: &[P2], tol: f64) -> Vec<P2> {
    let mut out: Vec<P2> = ring.to_vec();
    loop {
        let n = out.len();
        if n <= 3 {
            return out;
        }
        let Some(i) = (0..n).find(|&i| {
            let (u, v, w) = (out[(i + n - 1) % n], out[i], out[(i + 1) % n]);
            turn(u, v, w).abs() < MIN_TURN_RAD && distance_to_segment(v, u, w) <= tol
        }) else {
            return out;
        };
        out.remove(i);
    }
}

/// Mitred offset of a ring by `distance` towards the left of its edges (into the material for
/// rings oriented with the material on their left). Returns one vertex per input vertex, or
/// `None` if an edge would collapse or reverse within that distance (a straight-skeleton edge
/// event, see [`collapse_distance`]), in which case the caller must use a smaller distance.
pub fn offset_left(ring: &[P2], distance: f64) -> Option<Vec<P2>> {
    let mitres = mitres(ring);
    (first_collapse(ring, &mitres) > distance).then(|| {
        ring.iter()
            .zip(&mitres)
            .map(|(p, m)| p + m * distance)
            .collect()
    })
}

/// The smallest left offset at which an edge of the ring collapses (its mitred end points meet),
/// infinite if none does: a feature of the profile thinner than twice a chamfer cannot carry it.
pub fn collapse_distance(ring: &[P2]) -> f64 {
    first_collapse(ring, &mitres(ring))
}

/// [`collapse_distance`] with the ring's mitres given.
fn first_collapse(ring: &[P2], mitres: &[Vector2<f64>]) -> f64 {
    let n = ring.len();
    (0..n)
        .map(|i| {
            let j = (i + 1) % n;
            let edge = ring[j] - ring[i];
            let closing = -(mitres[j] - mitres[i]).dot(&edge);
            if closing > 0.0 {
                edge.norm_squared() / closing
            } else {
                f64::INFINITY
            }
        })
        .fold(f64::INFINITY, f64::min)
}

/// Per vertex, how far it moves per unit of left offset (the mitre of its two edges' normals).
fn mitres(ring: &[P2]) -> Vec<Vector2<f64>> {
    let n = ring.len();
    let left = |a: P2, b: P2| {
        let d = (b - a).normalize();
        Vector2::new(-d.y, d.x)
    };
    (0..n)
        .map(|i| {
            let (prev, cur, next) = (ring[(i + n - 1) % n], ring[i], ring[(i + 1) % n]);
            let (na, nb) = (left(prev, cur), left(cur, next));
            (na + nb) / (1.0 + na.dot(&nb))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn decomposition_of_a_square_with_a_square_hole_covers_its_area() {
        let region = Region {
            outer: rect(-1.0, -1.0, 1.0, 1.0),
            holes: vec![{
                let mut h = rect(-0.5, -0.5, 0.5, 0.5);
                h.reverse();
                h
            }],
        };
        let pieces = convex_decomposition(&region);
        let area: f64 = pieces.iter().map(|p| signed_area(p)).sum();
        assert!((area - 3.0).abs() < 1e-12, "area {area}");
        assert!(
            pieces.len() >= 4 && pieces.len() <= 8,
            "{} pieces",
            pieces.len()
        );
        for p in &pieces {
            assert_eq!(
                convex_hull(p).len(),
                p.len(),
                "piece not strictly convex: {p:?}"
            );
        }
    }

    #[test]
    fn mitred_offset_of_a_square_moves_each_edge() {
        let sq = rect(0.0, 0.0, 1.0, 1.0);
        let inner = offset_left(&sq, 0.1).unwrap();
        assert!((signed_area(&inner) - 0.64).abs() < 1e-12);
        assert!(
            offset_left(&sq, 0.6).is_none(),
            "an edge event must be reported"
        );
    }

    #[test]
    fn circles_respect_the_chord_tolerance_and_pass_through_given_angles() {
        let (r, tol) = (0.008, 2.5e-6);
        let n = sides_for_circle(r, tol);
        let sagitta = r * (1.0 - (std::f64::consts::PI / n as f64).cos());
        assert!(sagitta <= tol);
        let ring = circle_through(P2::origin(), r, &[0.3, 2.0], tol);
        assert!(ring.iter().any(|p| (p.y.atan2(p.x) - 0.3).abs() < 1e-12));
        for k in 0..ring.len() {
            let mid = (ring[k].coords + ring[(k + 1) % ring.len()].coords) * 0.5;
            assert!(r - mid.norm() <= tol * 1.0001);
        }
    }
}
