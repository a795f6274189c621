//! The contact points once the axis is known: a face contact clips the incident face against the
//! reference face (Sutherland-Hodgman) and keeps up to four points; an edge contact takes the
//! closest points of the two edges.

use rapier3d::parry::math::{Pose, Real, Vector};
use rapier3d::parry::query::{ContactManifold, TrackedContact};
use rapier3d::parry::shape::{ConvexPolyhedron, PackedFeatureId};
use smallvec::SmallVec;

/// A face polygon, or what clipping leaves of one: held inline up to 16 vertices (a strip's faces
/// have four or five), so that a contact allocates nothing.
pub(super) type Polygon = SmallVec<[Vector; 16]>;

pub(super) fn face_polygon(p: &ConvexPolyhedron, face: usize) -> Polygon {
    let f = &p.faces()[face];
    let first = f.first_vertex_or_edge as usize;
    p.vertices_adj_to_face()[first..first + f.num_vertices_or_edges as usize]
        .iter()
        .map(|&i| p.points()[i as usize])
        .collect()
}

/// Contacts on reference face `face` of `r` (frame of `r`; `pos_ri` places the incident shape
/// `i` in it). `flipped` when `r` is the manifold's second shape.
pub(super) fn face_contacts<M, C: Default + Copy>(
    pos_ri: &Pose,
    r: &ConvexPolyhedron,
    face: usize,
    inc: &ConvexPolyhedron,
    prediction: Real,
    flipped: bool,
    manifold: &mut ContactManifold<M, C>,
) {
    let n = r.faces()[face].normal;
    let reference = face_polygon(r, face);
    // The incident face: the one most anti-parallel to n.
    let n_i = pos_ri.rotation.inverse() * n;
    let (inc_face, _) = inc
        .faces()
        .iter()
        .enumerate()
        .map(|(k, f)| (k, f.normal.dot(n_i)))
        .fold((0, Real::MAX), |acc, x| if x.1 < acc.1 { x } else { acc });
    let mut poly: Polygon = face_polygon(inc, inc_face)
        .iter()
        .map(|&p| *pos_ri * p)
        .collect();
    let mut clipped = Polygon::new();
    let centre = reference.iter().copied().sum::<Vector>() / reference.len() as Real;
    for k in 0..reference.len() {
        let (v0, v1) = (reference[k], reference[(k + 1) % reference.len()]);
        let mut side = (v1 - v0).cross(n);
        if side.dot(centre - v0) > 0.0 {
            side = -side;
        }
        clip(&poly, side, side.dot(v0), &mut clipped);
        std::mem::swap(&mut poly, &mut clipped);
        if poly.is_empty() {
            return;
        }
    }
    let plane = n.dot(reference[0]);
    let mut points: Depths = poly
        .into_iter()
        .map(|p| (p, n.dot(p) - plane))
        .filter(|(_, d)| *d <= prediction)
        .collect();
    reduce_to_four(&mut points);
    let pos_ir = pos_ri.inverse();
    for (k, (p_inc, depth)) in points.into_iter().enumerate() {
        let p_ref = p_inc - n * depth;
        let fid_r = PackedFeatureId::face(face as u32);
        let fid_i = PackedFeatureId::vertex((inc_face * 64 + k) as u32);
        let contact = if flipped {
            TrackedContact::new(pos_ir * p_inc, p_ref, fid_i, fid_r, depth)
        } else {
            TrackedContact::new(p_ref, pos_ir * p_inc, fid_r, fid_i, depth)
        };
        manifold.points.push(contact);
    }
}

/// Sutherland-Hodgman: the part of a polygon with `side . p <= offset`, into `out`.
pub(super) fn clip(poly: &[Vector], side: Vector, offset: Real, out: &mut Polygon) {
    out.clear();
    for k in 0..poly.len() {
        let (p, q) = (poly[k], poly[(k + 1) % poly.len()]);
        let (dp, dq) = (side.dot(p) - offset, side.dot(q) - offset);
        if dp <= 0.0 {
            out.push(p);
        }
        if (dp < 0.0) != (dq < 0.0) && dp != dq {
            out.push(p + (q - p) * (dp / (dp - dq)));
        }
    }
}

/// Contact points on the incident face and their depths along the reference normal (metres).
pub(super) type Depths = SmallVec<[(Vector, Real); 16]>;

/// Keeps at most four points spanning the largest area: the deepest, the farthest from it, the
/// farthest from their line, and the farthest on the other side.
pub(super) fn reduce_to_four(points: &mut Depths) {
    if points.len() <= 4 {
        return;
    }
    let deepest = (0..points.len())
        .min_by(|&i, &j| points[i].1.total_cmp(&points[j].1))
        .unwrap_or(0);
    let p0 = points[deepest].0;
    let far = (0..points.len())
        .max_by(|&i, &j| {
            (points[i].0 - p0)
                .length_squared()
                .total_cmp(&(points[j].0 - p0).length_squared())
        })
        .unwrap_or(0);
    let p1 = points[far].0;
    let line = p1 - p0;
    let area = |i: usize| (points[i].0 - p0).cross(line);
    let third = (0..points.len())
        .max_by(|&i, &j| {
            area(i)
                .length_squared()
                .total_cmp(&area(j).length_squared())
        })
        .unwrap_or(0);
    let normal = area(third);
    let fourth = (0..points.len())
        .min_by(|&i, &j| area(i).dot(normal).total_cmp(&area(j).dot(normal)))
        .unwrap_or(0);
    let mut keep: SmallVec<[usize; 4]> = SmallVec::from_buf([deepest, far, third, fourth]);
    keep.sort_unstable();
    keep.dedup();
    *points = keep.into_iter().map(|i| points[i]).collect();
}

#[allow(clippy::too_many_arguments)]
pub(super) fn edge_contact<M, C: Default + Copy>(
    pos12: &Pose,
    a: &ConvexPolyhedron,
    ia: usize,
    b: &ConvexPolyhedron,
    ib: usize,
    n1: Vector,
    prediction: Real,
    manifold: &mut ContactManifold<M, C>,
) {
    let ea = &a.edges()[ia];
    let eb = &b.edges()[ib];
    let (a0, a1) = (
        a.points()[ea.vertices[0] as usize],
        a.points()[ea.vertices[1] as usize],
    );
    let (b0, b1) = (
        *pos12 * b.points()[eb.vertices[0] as usize],
        *pos12 * b.points()[eb.vertices[1] as usize],
    );
    let (pa, pb) = closest_points_segments(a0, a1, b0, b1);
    let dist = (pb - pa).dot(n1);
    if dist <= prediction {
        manifold.points.push(TrackedContact::new(
            pa,
            pos12.inverse() * pb,
            PackedFeatureId::edge(ia as u32),
            PackedFeatureId::edge(ib as u32),
            dist,
        ));
    }
}

/// Closest points between segments [p0, p1] and [q0, q1].
pub(super) fn closest_points_segments(
    p0: Vector,
    p1: Vector,
    q0: Vector,
    q1: Vector,
) -> (Vector, Vector) {
    let (d1, d2, r) = (p1 - p0, q1 - q0, p0 - q0);
    let (a, e, f) = (d1.dot(d1), d2.dot(d2), d2.dot(r));
    let c = d1.dot(r);
    let b = d1.dot(d2);
    let denom = a * e - b * b;
    let mut s = if denom > 1e-12 {
        ((b * f - c * e) / denom).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let mut t = (b * s + f) / e.max(1e-12);
    if t < 0.0 {
        t = 0.0;
        s = (-c / a.max(1e-12)).clamp(0.0, 1.0);
    } else if t > 1.0 {
        t = 1.0;
        s = ((b - c) / a.max(1e-12)).clamp(0.0, 1.0);
    }
    (p0 + d1 * s, q0 + d2 * t)
}
