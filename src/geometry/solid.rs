//! Solids as exact unions of convex pieces, with the watertight boundary mesh when we built them.

use super::planar::{P2, Region, convex_decomposition};
use nalgebra::{Point3, Vector3};
use parry3d::shape::ConvexPolyhedron;

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
        ZPlane { a: 0.0, b: 0.0, c: z }
    }

    pub fn z(&self, p: P2) -> f64 {
        self.a * p.x + self.b * p.y + self.c
    }
}

/// One convex piece in f64, with the data an exact separating-axis test needs: vertices, outward
/// face normals and edge directions (all unit vectors).
#[derive(Clone, Debug)]
pub struct ConvexPiece {
    pub vertices: Vec<P3>,
    pub face_normals: Vec<Vector3<f64>>,
    pub edge_dirs: Vec<Vector3<f64>>,
}

impl ConvexPiece {
    /// The part of the vertical prism over a convex counter-clockwise `footprint` between two
    /// planes (`lower` below `upper` everywhere on the footprint, possibly touching along an edge).
    pub fn slab(footprint: &[P2], lower: ZPlane, upper: ZPlane) -> Self {
        let mut vertices = Vec::with_capacity(footprint.len() * 2);
        for &p in footprint {
            let (zl, zu) = (lower.z(p), upper.z(p));
            vertices.push(P3::new(p.x, p.y, zl));
            if zu - zl > 1e-12 {
                vertices.push(P3::new(p.x, p.y, zu));
            }
        }
        let mut face_normals = vec![
            Vector3::new(lower.a, lower.b, -1.0).normalize(),
            Vector3::new(-upper.a, -upper.b, 1.0).normalize(),
        ];
        let mut edge_dirs = vec![Vector3::z()];
        let n = footprint.len();
        for i in 0..n {
            let d = footprint[(i + 1) % n] - footprint[i];
            face_normals.push(Vector3::new(d.y, -d.x, 0.0).normalize());
            for plane in [lower, upper] {
                edge_dirs.push(Vector3::new(d.x, d.y, plane.a * d.x + plane.b * d.y).normalize());
            }
        }
        ConvexPiece {
            vertices,
            face_normals,
            edge_dirs,
        }
    }

    /// A convex piece from its points (the convex hull is taken). `None` if they span no volume.
    pub fn from_points(points: &[P3]) -> Option<Self> {
        let pts: Vec<parry3d::math::Vector> = points
            .iter()
            .map(|p| parry3d::math::Vector::new(p.x as f32, p.y as f32, p.z as f32))
            .collect();
        let hull = ConvexPolyhedron::from_convex_hull(&pts)?;
        let v3 = |v: parry3d::math::Vector| Vector3::new(v.x as f64, v.y as f64, v.z as f64);
        Some(ConvexPiece {
            vertices: hull.points().iter().map(|&p| P3::from(v3(p))).collect(),
            face_normals: hull.faces().iter().map(|f| v3(f.normal).normalize()).collect(),
            edge_dirs: hull.edges().iter().map(|e| v3(e.dir).normalize()).collect(),
        })
    }

    /// The vertices as f32 points for a rapier collider.
    pub fn points_f32(&self) -> Vec<parry3d::math::Vector> {
        self.vertices
            .iter()
            .map(|p| parry3d::math::Vector::new(p.x as f32, p.y as f32, p.z as f32))
            .collect()
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
