//! Solids as exact unions of convex pieces, with the watertight boundary mesh when we built them.

use super::planar::{P2, Region, convex_decomposition};
use nalgebra::{Isometry3, Point3, Vector3};
use parry3d::shape::{ConvexPolyhedron, SharedShape};

/// A point in space, metres.
pub type P3 = Point3<f64>;

/// The plane `z = a x + b y + c` (metres).
#[derive(Clone, Copy, Debug)]
pub struct ZPlane {
    pub a: f64,
    pub b: f64,
    pub c: f64,
}

impl ZPlane {
    pub fn flat(z: f64) -> Self {
        ZPlane {
            a: 0.0,
            b: 0.0,
            c: z,
        }
    }

    pub fn z(&self, p: P2) -> f64 {
        self.a * p.x + self.b * p.y + self.c
    }
}

/// Spacing of [`ConvexPiece::surface_samples`] along edges, m.
const SAMPLE_SPACING_M: f64 = 0.5e-3;
/// Most subdivisions of a face triangle for the samples inside it.
const INTERIOR_SUBDIVISIONS: usize = 8;

/// A triangle mesh as read from a file or made to be written, metres: the input of the exact
/// stack cut (`stack`) and of a mesh part (`mesh`).
pub struct TriangleSoup {
    pub vertices: Vec<P3>,
    pub triangles: Vec<[u32; 3]>,
}

/// One convex piece in f64: vertices, and faces as outward counter-clockwise polygons, with the
/// data an exact separating-axis test needs (outward unit face normals, unit edge directions).
/// Pieces pegtwin builds carry their exact topology; the engine's collider is made from it as is
/// (`SharedShape::convex_mesh`) rather than re-derived by a convex hull, whose tolerances drop
/// vertices of long thin pieces.
#[derive(Clone, Debug)]
pub struct ConvexPiece {
    pub vertices: Vec<P3>,
    pub faces: Vec<Vec<u32>>,
    pub face_normals: Vec<Vector3<f64>>,
    pub edge_dirs: Vec<Vector3<f64>>,
}

impl ConvexPiece {
    /// A piece from its vertices and face polygons (any orientation: each face is turned to face
    /// away from the centroid).
    pub fn from_faces(vertices: Vec<P3>, faces: Vec<Vec<u32>>) -> Self {
        let centre = centroid(&vertices);
        let mut faces = faces;
        let mut face_normals = Vec::with_capacity(faces.len());
        let mut edge_dirs = Vec::new();
        for face in &mut faces {
            let pts: Vec<P3> = face.iter().map(|&i| vertices[i as usize]).collect();
            let mut n = newell_normal(&pts);
            let fc = centroid(&pts);
            if n.dot(&(fc - centre)) < 0.0 {
                face.reverse();
                n = -n;
            }
            face_normals.push(n);
            for k in 0..pts.len() {
                let d = pts[(k + 1) % pts.len()] - pts[k];
                if d.norm() > 0.0 {
                    edge_dirs.push(d.normalize());
                }
            }
        }
        let edge_dirs = distinct_up_to_sign(edge_dirs);
        ConvexPiece {
            vertices,
            faces,
            face_normals,
            edge_dirs,
        }
    }

    /// The vertical prism over a convex counter-clockwise `footprint` between two planes
    /// (`lower` strictly below `upper` on the footprint).
    pub fn slab(footprint: &[P2], lower: ZPlane, upper: ZPlane) -> Self {
        let n = footprint.len() as u32;
        let mut vertices: Vec<P3> = footprint
            .iter()
            .map(|&p| P3::new(p.x, p.y, lower.z(p)))
            .collect();
        vertices.extend(footprint.iter().map(|&p| P3::new(p.x, p.y, upper.z(p))));
        let mut faces = vec![(0..n).collect::<Vec<u32>>(), (n..2 * n).collect()];
        faces.extend((0..n).map(|i| vec![i, (i + 1) % n, n + (i + 1) % n, n + i]));
        Self::from_faces(vertices, faces)
    }

    /// A convex piece from its points (the convex hull is taken, as for mesh files). `None` if
    /// they span no volume (or parry's hull fails on them).
    pub fn from_points(points: &[P3]) -> Option<Self> {
        let centre = centroid(points);
        let local = local_f32(points, &centre);
        let hull = catch_quietly(|| ConvexPolyhedron::from_convex_hull(&local)).flatten()?;
        let vertices: Vec<P3> = hull
            .points()
            .iter()
            .map(|p| P3::new(p.x as f64, p.y as f64, p.z as f64) + centre.coords)
            .collect();
        let faces = hull
            .faces()
            .iter()
            .map(|f| {
                let first = f.first_vertex_or_edge as usize;
                hull.vertices_adj_to_face()[first..first + f.num_vertices_or_edges as usize]
                    .to_vec()
            })
            .collect();
        Some(Self::from_faces(vertices, faces))
    }

    /// Points on the piece's faces, for measuring how far it stands from a surface: along every
    /// edge of its face triangles every 0.5 mm (at most 128 per edge), and a grid of at most
    /// 8 x 8 inside each triangle (so that a face spanning a hole of the surface is seen).
    pub fn surface_samples(&self) -> Vec<P3> {
        let mut out = Vec::new();
        for t in self.triangles() {
            let [a, b, c] = t.map(|i| self.vertices[i as usize]);
            for (p, q) in [(a, b), (b, c), (c, a)] {
                let n = ((q - p).norm() / SAMPLE_SPACING_M).ceil().clamp(1.0, 128.0) as usize;
                out.extend((0..n).map(|k| p + (q - p) * (k as f64 / n as f64)));
            }
            let longest = [(b - a).norm(), (c - b).norm(), (a - c).norm()]
                .into_iter()
                .fold(0.0, f64::max);
            let n = ((longest / SAMPLE_SPACING_M).ceil() as usize).clamp(1, INTERIOR_SUBDIVISIONS);
            for i in 1..n {
                for j in 1..n - i {
                    let (u, v) = (i as f64 / n as f64, j as f64 / n as f64);
                    out.push(a + (b - a) * u + (c - a) * v);
                }
            }
        }
        out
    }

    /// The faces as triangles (fans), outward.
    pub fn triangles(&self) -> Vec<[u32; 3]> {
        self.faces
            .iter()
            .flat_map(|f| (1..f.len() - 1).map(move |k| [f[0], f[k], f[k + 1]]))
            .collect()
    }

    /// The piece as a closed triangle mesh.
    pub fn to_mesh(&self) -> BoundaryMesh {
        BoundaryMesh {
            vertices: self.vertices.clone(),
            triangles: self.triangles(),
        }
    }

    /// The piece moved by `iso` (vertices, normals and edges; the faces keep their order).
    pub fn transformed(&self, iso: &Isometry3<f64>) -> ConvexPiece {
        ConvexPiece {
            vertices: self.vertices.iter().map(|p| iso * p).collect(),
            faces: self.faces.clone(),
            face_normals: self.face_normals.iter().map(|n| iso * n).collect(),
            edge_dirs: self.edge_dirs.iter().map(|e| iso * e).collect(),
        }
    }

    /// The engine's shape of the piece, about its centroid (`None` when parry refuses it: a
    /// piece that is flat, degenerate or whose faces do not close). Loaders check every piece
    /// with it, so that no part is dropped on its way into the physics.
    ///
    /// The piece's own faces go in as they are; where parry cannot rebuild a topology from them
    /// (its face merging trips an assertion on slivers read back from f32 STL files, a rounding
    /// problem parry's source notes), the hull of the vertices is taken instead.
    pub fn collider_shape(&self) -> Option<SharedShape> {
        let points = self.points_f32_about(&self.centroid());
        let triangles = self.triangles();
        catch_quietly(|| SharedShape::convex_mesh(points.clone(), &triangles))
            .flatten()
            .or_else(|| catch_quietly(|| SharedShape::convex_hull(&points)).flatten())
    }

    /// Enclosed volume, m^3.
    pub fn volume(&self) -> f64 {
        self.to_mesh().volume()
    }

    /// The centroid of the vertices.
    pub fn centroid(&self) -> P3 {
        centroid(&self.vertices)
    }

    /// The vertices relative to `centre`, as f32 points for a collider placed at `centre` (f32
    /// keeps its precision about the piece's own centroid).
    pub fn points_f32_about(&self, centre: &P3) -> Vec<parry3d::math::Vector> {
        local_f32(&self.vertices, centre)
    }

    /// Axis-aligned bounds (min, max).
    pub fn bounds(&self) -> (P3, P3) {
        let mut lo = P3::new(f64::MAX, f64::MAX, f64::MAX);
        let mut hi = P3::new(f64::MIN, f64::MIN, f64::MIN);
        for p in &self.vertices {
            lo = lo.inf(p);
            hi = hi.sup(p);
        }
        (lo, hi)
    }
}

/// Unit normal of a planar polygon by Newell's method (counter-clockwise gives the outward side).
/// The directions in `dirs` that are not bit for bit another earlier one or its negation, in
/// their order. Every edge of a polyhedron is walked once by each of its two faces, in opposite
/// directions, and a prism's side edges are all parallel: the separating-axis test of
/// `twin::physics::penetration` takes one axis per distinct direction, so the repeats only cost
/// (they gave the same overlap: the negated axis projects to the same interval, reversed).
fn distinct_up_to_sign(dirs: Vec<Vector3<f64>>) -> Vec<Vector3<f64>> {
    // The key turns -0.0 into 0.0 (adding 0.0) and the direction so that its first non-zero
    // component is positive: `d` and `-d` share it.
    let key = |d: &Vector3<f64>| {
        let first = d.iter().copied().find(|c| *c != 0.0).unwrap_or(0.0);
        let s = if first < 0.0 { -1.0 } else { 1.0 };
        [d.x, d.y, d.z].map(|c| (s * c + 0.0).to_bits())
    };
    let mut seen = std::collections::HashSet::new();
    dirs.into_iter().filter(|d| seen.insert(key(d))).collect()
}

fn newell_normal(pts: &[P3]) -> Vector3<f64> {
    let mut n = Vector3::zeros();
    for k in 0..pts.len() {
        let (a, b) = (pts[k], pts[(k + 1) % pts.len()]);
        n += Vector3::new(
            (a.y - b.y) * (a.z + b.z),
            (a.z - b.z) * (a.x + b.x),
            (a.x - b.x) * (a.y + b.y),
        );
    }
    n.normalize()
}

thread_local! {
    /// Set while [`catch_quietly`] runs: its panics are caught, not reported.
    static QUIET: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}

/// Runs `f`, turning a panic inside it into `None` without printing it: for parry's
/// constructors, which assert on some rounding-damaged inputs instead of refusing them. The
/// panic hook in place before the first call keeps reporting every other panic.
fn catch_quietly<T>(f: impl FnOnce() -> T) -> Option<T> {
    static HOOK: std::sync::Once = std::sync::Once::new();
    HOOK.call_once(|| {
        let previous = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            if !QUIET.with(std::cell::Cell::get) {
                previous(info);
            }
        }));
    });
    QUIET.with(|q| q.set(true));
    let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(f));
    QUIET.with(|q| q.set(false));
    result.ok()
}

fn centroid(points: &[P3]) -> P3 {
    P3::from(points.iter().map(|p| p.coords).sum::<Vector3<f64>>() / points.len().max(1) as f64)
}

fn local_f32(points: &[P3], centre: &P3) -> Vec<parry3d::math::Vector> {
    points
        .iter()
        .map(|p| {
            let q = p - centre;
            parry3d::math::Vector::new(q.x as f32, q.y as f32, q.z as f32)
        })
        .collect()
}

/// A watertight triangle mesh: outward-facing, counter-clockwise triangles, metres.
#[derive(Clone, Debug, Default)]
pub struct BoundaryMesh {
    pub vertices: Vec<P3>,
    pub triangles: Vec<[u32; 3]>,
}

/// A solid body: the convex pieces that make its collision shape and, for built-ins, its exact
/// boundary.
#[derive(Clone, Debug)]
pub struct Solid {
    pub pieces: Vec<ConvexPiece>,
    pub boundary: Option<BoundaryMesh>,
}

impl Solid {
    /// The summed volume of the pieces, m^3 (where pieces overlap, the overlap counts twice).
    pub fn pieces_volume_m3(&self) -> f64 {
        self.pieces.iter().map(ConvexPiece::volume).sum()
    }

    /// Bounds over all pieces (min, max).
    pub fn bounds(&self) -> (P3, P3) {
        self.pieces.iter().map(|p| p.bounds()).fold(
            (
                P3::new(f64::MAX, f64::MAX, f64::MAX),
                P3::new(f64::MIN, f64::MIN, f64::MIN),
            ),
            |(lo, hi), (l, h)| (lo.inf(&l), hi.sup(&h)),
        )
    }
}

/// Prisms over the exact convex decomposition of `regions`, between two planes.
pub fn prisms(regions: &[Region], lower: ZPlane, upper: ZPlane) -> Vec<ConvexPiece> {
    regions
        .iter()
        .flat_map(convex_decomposition)
        .map(|f| ConvexPiece::slab(&f, lower, upper))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::twin::geometry::planar::rect;

    #[test]
    fn a_box_keeps_one_edge_direction_per_axis() {
        // 6 faces of 4 edges walk 24 edge directions: each of the 12 edges twice, 4 per axis.
        let cube = ConvexPiece::slab(
            &rect(0.0, 0.0, 1.0, 2.0),
            ZPlane::flat(0.0),
            ZPlane::flat(3.0),
        );
        assert_eq!(cube.edge_dirs.len(), 3);
        for axis in [Vector3::x(), Vector3::y(), Vector3::z()] {
            assert!(cube.edge_dirs.iter().any(|d| d.cross(&axis).norm() == 0.0));
        }
    }

    #[test]
    fn directions_equal_up_to_sign_are_kept_once_and_near_ones_stay() {
        let d = Vector3::new(0.6, -0.8, 0.0);
        let near = Vector3::new(0.6, -0.8 + 1e-15, 0.0);
        let kept = distinct_up_to_sign(vec![
            d,
            -d,
            Vector3::new(-0.0, 0.0, 1.0),
            Vector3::z(),
            near,
        ]);
        assert_eq!(kept, vec![d, Vector3::new(-0.0, 0.0, 1.0), near]);
    }
}
