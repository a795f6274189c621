//! What a replay draws, as triangle meshes in their bodies' frames (m): each link of the arm from
//! its URDF collision shapes (the shapes the physics uses; the built-in iiwa has no visual
//! meshes), the peg and the hole from their watertight boundaries (or, for a solid read from
//! convex parts, the union of its pieces' surfaces).

use crate::twin::geometry::PartPair;
use crate::twin::geometry::solid::Solid;
use crate::twin::robot::{Link, RobotModel, Shape};
use nalgebra::{Point3, UnitQuaternion, Vector3};
use parry3d::math::Vector3 as PVec;

/// Facets around a cylinder, capsule or sphere.
const ROUND_SUBDIVISIONS: u32 = 32;

/// A triangle mesh in its body's frame.
#[derive(Clone, Debug, Default)]
pub struct Mesh {
    /// x, y, z per vertex, m.
    pub positions: Vec<f32>,
    /// Three vertex indices per triangle, counter-clockwise seen from outside.
    pub indices: Vec<u32>,
}

impl Mesh {
    /// Appends triangles over `vertices` (in the mesh's frame).
    fn append(&mut self, vertices: &[Point3<f64>], triangles: &[[u32; 3]]) {
        let base = (self.positions.len() / 3) as u32;
        for v in vertices {
            self.positions.extend([v.x as f32, v.y as f32, v.z as f32]);
        }
        for t in triangles {
            self.indices.extend(t.iter().map(|i| base + i));
        }
    }
}

/// The static part of a replay: what each body looks like.
#[derive(Clone, Debug)]
pub struct Scene {
    /// The robot's name and its links (the base first), each with its mesh.
    pub robot_name: String,
    pub links: Vec<(String, Mesh)>,
    pub peg: Mesh,
    pub hole: Mesh,
    /// The geometry's name and clearance, m.
    pub geometry: String,
    pub clearance_m: f64,
}

impl Scene {
    pub fn new(pair: &PartPair, robot: &RobotModel) -> Self {
        let links = std::iter::once(&robot.base)
            .chain(&robot.links)
            .map(|l| (l.name.clone(), link_mesh(l)))
            .collect();
        Scene {
            robot_name: robot.name.clone(),
            links,
            peg: solid_mesh(&pair.peg),
            hole: solid_mesh(&pair.hole),
            geometry: pair.name.clone(),
            clearance_m: pair.clearance_m,
        }
    }
}

/// A solid's surface: its watertight boundary when it has one, else its pieces' surfaces.
pub fn solid_mesh(solid: &Solid) -> Mesh {
    let mut mesh = Mesh::default();
    match &solid.boundary {
        Some(b) => mesh.append(&b.vertices, &b.triangles),
        None => {
            for piece in &solid.pieces {
                mesh.append(&piece.vertices, &piece.triangles());
            }
        }
    }
    mesh
}

/// A link's collision shapes, each placed at its origin in the link frame.
pub fn link_mesh(link: &Link) -> Mesh {
    let mut mesh = Mesh::default();
    for c in &link.collision {
        let (vertices, triangles) = shape_triangles(&c.shape);
        let placed: Vec<Point3<f64>> = vertices
            .iter()
            .map(|v| c.origin * Point3::new(v.x as f64, v.y as f64, v.z as f64))
            .collect();
        mesh.append(&placed, &triangles);
    }
    mesh
}

/// A URDF shape as parry tessellates it, in the shape's frame (cylinders and capsules along z,
/// as URDF has them).
fn shape_triangles(shape: &Shape) -> (Vec<PVec>, Vec<[u32; 3]>) {
    use parry3d::shape::{Ball, Capsule, Cuboid, Cylinder};
    let n = ROUND_SUBDIVISIONS;
    match shape {
        Shape::Box { half_extents: h } => {
            Cuboid::new(PVec::new(h.x as f32, h.y as f32, h.z as f32)).to_trimesh()
        }
        Shape::Cylinder { radius, length } => {
            let (v, t) = Cylinder::new(*length as f32 / 2.0, *radius as f32).to_trimesh(n);
            (y_to_z(v), t)
        }
        Shape::Capsule { radius, length } => {
            Capsule::new_z(*length as f32 / 2.0, *radius as f32).to_trimesh(n, n / 2)
        }
        Shape::Sphere { radius } => Ball::new(*radius as f32).to_trimesh(n, n / 2),
        Shape::ConvexHull { points } => {
            let p: Vec<PVec> = points
                .iter()
                .map(|p| PVec::new(p.x as f32, p.y as f32, p.z as f32))
                .collect();
            parry3d::transformation::convex_hull(&p)
        }
    }
}

/// Turns parry's y-axis shapes to URDF's z axis (a quarter turn about x: y to z).
fn y_to_z(vertices: Vec<PVec>) -> Vec<PVec> {
    let r = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::FRAC_PI_2);
    vertices
        .into_iter()
        .map(|v| {
            let w = r * Vector3::new(v.x as f64, v.y as f64, v.z as f64);
            PVec::new(w.x as f32, w.y as f32, w.z as f32)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_urdf_cylinder_stands_along_z() {
        let (v, t) = shape_triangles(&Shape::Cylinder {
            radius: 0.05,
            length: 0.4,
        });
        assert!(!t.is_empty());
        let z_max = v.iter().map(|p| p.z).fold(f32::MIN, f32::max);
        let r_max = v
            .iter()
            .map(|p| (p.x * p.x + p.y * p.y).sqrt())
            .fold(f32::MIN, f32::max);
        assert!((z_max - 0.2).abs() < 1e-5, "z max {z_max}");
        assert!((r_max - 0.05).abs() < 1e-4, "radius {r_max}");
    }
}
