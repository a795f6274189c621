//! Meshes in and out: the watertight boundary of built-in solids, STL export in millimetres,
//! and STL/OBJ import (a folder of convex parts, or one non-convex mesh decomposed by V-HACD).

use super::PartPair;
use super::planar::{P2, Region, triangulate};
use super::solid::{BoundaryMesh, ConvexPiece, P3, Solid, TriangleSoup};
use crate::choice::{Choice, Named};
use crate::error::{Error, Result};
use parry3d::math::Vector as V3f;
use parry3d::query::PointQuery;
use parry3d::shape::{TriMesh, TriMeshFlags};
use parry3d::transformation::vhacd::{VHACD, VHACDParameters};
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// Builds a watertight mesh from side bands and planar caps that share their ring vertices.
#[derive(Default)]
pub struct MeshBuilder {
    index: HashMap<[u64; 3], u32>,
    mesh: BoundaryMesh,
}

impl MeshBuilder {
    fn vertex(&mut self, p: P2, z: f64) -> u32 {
        let key = [p.x.to_bits(), p.y.to_bits(), z.to_bits()];
        let mesh = &mut self.mesh;
        *self.index.entry(key).or_insert_with(|| {
            mesh.vertices.push(P3::new(p.x, p.y, z));
            (mesh.vertices.len() - 1) as u32
        })
    }

    /// The ruled band between `low` (at `z_low`) and `high` (at `z_high`), two rings with the same
    /// number of vertices and the material on the left of their edges; faces point away from it.
    pub fn side_band(&mut self, low: &[P2], z_low: f64, high: &[P2], z_high: f64) {
        let n = low.len();
        for i in 0..n {
            let j = (i + 1) % n;
            let (a0, b0) = (self.vertex(low[i], z_low), self.vertex(low[j], z_low));
            let (a1, b1) = (self.vertex(high[i], z_high), self.vertex(high[j], z_high));
            self.mesh.triangles.push([a0, b0, b1]);
            self.mesh.triangles.push([a0, b1, a1]);
        }
    }

    /// A planar cap over a region at height `z`, facing up (+z) or down.
    pub fn cap(&mut self, region: &Region, z: f64, up: bool) {
        for [a, b, c] in triangulate(region) {
            let (ia, ib, ic) = (self.vertex(a, z), self.vertex(b, z), self.vertex(c, z));
            self.mesh
                .triangles
                .push(if up { [ia, ib, ic] } else { [ia, ic, ib] });
        }
    }

    pub fn finish(self) -> BoundaryMesh {
        self.mesh
    }
}

impl BoundaryMesh {
    /// True when every edge is shared by exactly two triangles with opposite directions.
    pub fn is_watertight(&self) -> bool {
        let mut count: HashMap<(u32, u32), i32> = HashMap::new();
        for t in &self.triangles {
            for k in 0..3 {
                *count.entry((t[k], t[(k + 1) % 3])).or_default() += 1;
            }
        }
        count
            .iter()
            .all(|(&(a, b), &c)| c == 1 && count.get(&(b, a)) == Some(&1))
    }

    /// Enclosed volume (divergence theorem), m^3; positive for outward-facing triangles.
    pub fn volume(&self) -> f64 {
        self.triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| self.vertices[i as usize].coords);
                a.dot(&b.cross(&c)) / 6.0
            })
            .sum()
    }

    /// Writes a binary STL in millimetres, whole or not at all.
    pub fn write_stl_mm(&self, path: &Path) -> Result<()> {
        let tris: Vec<stl_io::Triangle> = self
            .triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| self.vertices[i as usize].coords * 1e3);
                let n = (b - a).cross(&(c - a)).normalize();
                let v = |p: nalgebra::Vector3<f64>| {
                    stl_io::Vertex::new([p.x as f32, p.y as f32, p.z as f32])
                };
                stl_io::Triangle {
                    normal: stl_io::Normal::new([n.x as f32, n.y as f32, n.z as f32]),
                    vertices: [v(a), v(b), v(c)],
                }
            })
            .collect();
        crate::files::write_atomically_with(path, |mut w| stl_io::write_stl(&mut w, tris.iter()))
    }
}

/// Length unit of a mesh file (`"mm"` or `"m"` in an assembly file).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum MeshUnits {
    Mm,
    M,
}

impl Choice for MeshUnits {
    const WHAT: &'static str = "units";
    const NAMED: &'static [Named<Self>] = &[
        Named {
            name: "mm",
            value: MeshUnits::Mm,
            help: "millimetres",
        },
        Named {
            name: "m",
            value: MeshUnits::M,
            help: "metres",
        },
    ];
}

impl MeshUnits {
    /// Metres per unit.
    pub fn scale(self) -> f64 {
        match self {
            MeshUnits::Mm => 1e-3,
            MeshUnits::M => 1.0,
        }
    }

    /// The unit's name in words.
    pub fn in_words(self) -> &'static str {
        match self {
            MeshUnits::Mm => "millimetres",
            MeshUnits::M => "metres",
        }
    }
}

/// Reads an STL or OBJ file (by extension) into metres.
pub fn read_mesh(path: &Path, units: MeshUnits) -> Result<TriangleSoup> {
    let s = units.scale();
    read_mesh_scaled(path, &nalgebra::Vector3::repeat(s), units.in_words())
}

/// Reads an STL or OBJ file into metres, each coordinate times `metres_per_unit` (per axis, as an
/// MJCF mesh's `scale` times the model's unit); `unit_words` says how it was read, for errors.
pub fn read_mesh_scaled(
    path: &Path,
    metres_per_unit: &nalgebra::Vector3<f64>,
    unit_words: &str,
) -> Result<TriangleSoup> {
    let mut soup = read_mesh_as_written(path)?;
    let s = metres_per_unit;
    for v in &mut soup.vertices {
        *v = P3::new(v.x * s.x, v.y * s.y, v.z * s.z);
    }
    check_in_range(&soup, path, unit_words)?;
    Ok(soup)
}

/// Reads an STL or OBJ file in the file's own units (checked for finite vertices and valid
/// triangles; [`check_in_range`] once it is in metres).
pub fn read_mesh_as_written(path: &Path) -> Result<TriangleSoup> {
    let (raw, triangles) = read_raw_mesh(path)?;
    if triangles.is_empty() {
        return Err(Error::file(path, "the mesh has no triangles"));
    }
    if let Some(bad) = raw.iter().find(|v| v.iter().any(|c| !c.is_finite())) {
        return Err(Error::file(path, format!("vertex {bad:?} is not finite")));
    }
    if triangles.iter().flatten().any(|&i| i as usize >= raw.len()) {
        return Err(Error::file(path, "a triangle refers to a missing vertex"));
    }
    let vertices: Vec<P3> = raw
        .iter()
        .map(|v| P3::new(v[0] as f64, v[1] as f64, v[2] as f64))
        .collect();
    Ok(TriangleSoup {
        vertices,
        triangles,
    })
}

/// A mesh in metres must lie within the coordinate limit, or its units are wrong
/// (`unit_words`: how it was read).
pub fn check_in_range(soup: &TriangleSoup, path: &Path, unit_words: &str) -> Result<()> {
    let limit = crate::pose::MAX_COORDINATE_M;
    match soup.vertices.iter().find(|v| v.coords.amax() > limit) {
        Some(far) => Err(Error::file(
            path,
            format!(
                "vertex ({:.4}, {:.4}, {:.4}) m lies beyond +-{limit} m: are the units right \
                 (read as {})?",
                far.x, far.y, far.z, unit_words
            ),
        )),
        None => Ok(()),
    }
}

/// A mesh file's vertices, in the file's units, and its triangles (vertex indices).
type RawMesh = (Vec<[f32; 3]>, Vec<[u32; 3]>);

/// A mesh file's vertices and triangles as the STL or OBJ reader gives them (OBJ faces
/// triangulated, every object of the file in one list).
fn read_raw_mesh(path: &Path) -> Result<RawMesh> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase());
    match ext.as_deref() {
        Some("stl") => {
            let bytes = crate::files::read_input(path, crate::files::DATA_LIMIT_BYTES)?;
            let mesh = stl_io::read_stl(&mut std::io::Cursor::new(bytes))
                .map_err(|e| Error::file(path, format!("not a valid STL file: {e}")))?;
            Ok((
                mesh.vertices.iter().map(|v| v.0).collect(),
                mesh.faces
                    .iter()
                    .map(|f| f.vertices.map(|i| i as u32))
                    .collect(),
            ))
        }
        Some("obj") => {
            let options = tobj::LoadOptions {
                triangulate: true,
                single_index: true,
                ..Default::default()
            };
            let bytes = crate::files::read_input(path, crate::files::DATA_LIMIT_BYTES)?;
            let mut reader = std::io::Cursor::new(bytes);
            // Materials are not read: a part's geometry is all pegtwin takes from it.
            let no_materials = |_: &Path| Err(tobj::LoadError::OpenFileFailed);
            let (models, _) = tobj::load_obj_buf(&mut reader, &options, no_materials)
                .map_err(|e| Error::file(path, format!("not a valid OBJ file: {e}")))?;
            let mut raw = Vec::new();
            let mut tris = Vec::new();
            for m in models {
                let base = raw.len() as u32;
                raw.extend(m.mesh.positions.chunks_exact(3).map(|c| [c[0], c[1], c[2]]));
                tris.extend(
                    m.mesh
                        .indices
                        .chunks_exact(3)
                        .map(|c| [base + c[0], base + c[1], base + c[2]]),
                );
            }
            Ok((raw, tris))
        }
        _ => Err(Error::file(
            path,
            "unknown mesh format: expected a .stl or .obj file",
        )),
    }
}

fn trimesh(soup: &TriangleSoup, path: &Path) -> Result<TriMesh> {
    let v: Vec<V3f> = soup
        .vertices
        .iter()
        .map(|p| V3f::new(p.x as f32, p.y as f32, p.z as f32))
        .collect();
    TriMesh::new(v, soup.triangles.clone())
        .map_err(|e| Error::file(path, format!("not a usable triangle mesh: {e}")))
}

/// How far convex `pieces` that approximate the closed part in `soup` (read from `file`; pieces
/// that may overlap and need not share their faces, as an approximate decomposition's) stand
/// off its surface, metres: the farthest of the pieces' surface samples that lie outside the
/// part (inside, a sample is on a face between pieces, which nothing touches), and the farthest
/// of the part's vertices outside every piece.
pub fn approximation_deviation(
    pieces: &[ConvexPiece],
    soup: &TriangleSoup,
    file: &Path,
) -> Result<f64> {
    let v: Vec<V3f> = soup
        .vertices
        .iter()
        .map(|p| V3f::new(p.x as f32, p.y as f32, p.z as f32))
        .collect();
    let flags = TriMeshFlags::ORIENTED | TriMeshFlags::MERGE_DUPLICATE_VERTICES;
    let solid = TriMesh::with_flags(v, soup.triangles.clone(), flags)
        .map_err(|e| Error::file(file, format!("not a usable closed triangle mesh: {e}")))?;
    let outward = pieces
        .iter()
        .flat_map(ConvexPiece::surface_samples)
        .map(|p| {
            let at = V3f::new(p.x as f32, p.y as f32, p.z as f32);
            let proj = solid.project_local_point(at, false);
            if proj.is_inside {
                0.0
            } else {
                (proj.point - at).length() as f64
            }
        })
        .fold(0.0, f64::max);
    let planes: Vec<FacePlanes> = pieces.iter().map(FacePlanes::of).collect();
    Ok(outward.max(uncovered(&planes, soup)))
}

/// Largest distance from any of `points` to the surface of `surface`, metres.
fn max_distance_to_surface(points: impl Iterator<Item = P3>, surface: &TriMesh) -> f64 {
    points
        .map(|p| {
            surface.distance_to_local_point(V3f::new(p.x as f32, p.y as f32, p.z as f32), false)
                as f64
        })
        .fold(0.0, f64::max)
}

/// A solid loaded from meshes, with what was measured on the way.
pub struct LoadedSolid {
    pub solid: Solid,
    /// Largest deviation between the collision pieces and the input surface, metres.
    pub max_deviation_m: f64,
    /// Each input file with the largest deviation of its collision pieces from its surface,
    /// metres (one entry per part of a folder; one for a decomposed file).
    pub part_deviations: Vec<(PathBuf, f64)>,
    pub warnings: Vec<String>,
}

/// A peg/hole pair from mesh files (see [`load_solid`]): the peg in the peg frame (tip centre
/// at the origin, z up the peg), the hole in the hole frame (mouth centre at the origin, z out of
/// the hole), made with diametral clearance `clearance_m`, the cavity `cavity_depth_m` deep.
/// Returns the pair and the loaders' warnings.
pub fn load_pair(
    peg_path: &Path,
    hole_path: &Path,
    units: MeshUnits,
    clearance_m: f64,
    cavity_depth_m: f64,
) -> Result<(PartPair, Vec<String>)> {
    let half_gap = clearance_m / 2.0;
    let peg = load_solid(peg_path, units, half_gap)?;
    let hole = load_solid(hole_path, units, half_gap)?;
    let hole_bottom_m = -hole.solid.bounds().0.z;
    if !(cavity_depth_m > 0.0 && cavity_depth_m <= hole_bottom_m) {
        return Err(Error::file(
            hole_path,
            format!(
                "cavity depth {} mm: expected more than 0 and at most the {:.3} mm the hole mesh \
                 reaches below its mouth (z = 0)",
                cavity_depth_m * 1e3,
                hole_bottom_m * 1e3
            ),
        ));
    }
    let warnings = peg.warnings.into_iter().chain(hole.warnings).collect();
    let pair = PartPair {
        name: format!("{} in {}", peg_path.display(), hole_path.display()),
        clearance_m,
        chord_error_m: 0.0,
        peg: peg.solid,
        hole: hole.solid,
        cavity_depth_m,
        seat: super::Seat::TipOnFloor,
        peg_mass_kg: None,
        content_key: None,
        print: None,
    };
    Ok((pair, warnings))
}

/// Loads a solid from a folder of convex parts (one STL/OBJ file each, the usual CoACD or V-HACD
/// output) or from one non-convex STL/OBJ file, which is decomposed with V-HACD. `half_gap_m` is
/// half the stated clearance: a deviation above it draws a warning.
pub fn load_solid(path: &Path, units: MeshUnits, half_gap_m: f64) -> Result<LoadedSolid> {
    let meta =
        std::fs::metadata(path).map_err(|e| Error::file(path, format!("cannot read: {e}")))?;
    if meta.is_dir() {
        load_convex_parts(path, units, half_gap_m)
    } else {
        load_and_decompose(path, units, half_gap_m)
    }
}

fn mesh_files(dir: &Path) -> Result<Vec<PathBuf>> {
    let entries =
        std::fs::read_dir(dir).map_err(|e| Error::file(dir, format!("cannot list: {e}")))?;
    let mut files: Vec<PathBuf> = entries
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.extension()
                .and_then(|e| e.to_str())
                .is_some_and(|e| e.eq_ignore_ascii_case("stl") || e.eq_ignore_ascii_case("obj"))
        })
        .collect();
    files.sort();
    if files.is_empty() {
        return Err(Error::file(dir, "the folder holds no .stl or .obj file"));
    }
    Ok(files)
}

/// One part of a folder of convex parts (or an MJCF mesh geom), read from `file`: its convex
/// hull when that stands on the part's own surface; when the hull stands off it (the part is not
/// convex) and the part is a stack of extrusions along an axis, its exact pieces
/// (`stack::stack_decomposition`) instead. A part the physics cannot take is an error naming the
/// file.
pub struct MeshPart {
    pub pieces: Vec<ConvexPiece>,
    /// How far the pieces stand off the part's surface (or leave it uncovered), metres.
    pub deviation_m: f64,
    /// How far the part's convex hull stood off its surface, metres (0 for a convex part).
    pub hull_deviation_m: f64,
}

/// A hull standing further than this off its part's surface makes the loader try the exact
/// stack decomposition, metres (1 um: rounding in the files is far below it).
const HULL_TOLERANCE_M: f64 = 1e-6;

/// Reads one part (see [`MeshPart`]).
pub fn mesh_part(soup: &TriangleSoup, file: &Path) -> Result<MeshPart> {
    let hull = ConvexPiece::from_points(&soup.vertices)
        .filter(|p| p.collider_shape().is_some())
        .ok_or_else(|| {
            Error::file(
                file,
                "the part is flat or degenerate: it has no volume the physics can take",
            )
        })?;
    let surface = trimesh(soup, file)?;
    let hull_dev = max_distance_to_surface(hull.surface_samples().into_iter(), &surface);
    let stacked = (hull_dev > HULL_TOLERANCE_M)
        .then(|| super::stack::stack_decomposition(soup))
        .flatten()
        .filter(|pieces| pieces.iter().all(|p| p.collider_shape().is_some()))
        .map(|pieces| (surface_deviation(&pieces, soup, &surface), pieces))
        .filter(|(dev, _)| *dev < hull_dev);
    Ok(match stacked {
        Some((deviation_m, pieces)) => MeshPart {
            pieces,
            deviation_m,
            hull_deviation_m: hull_dev,
        },
        None => MeshPart {
            pieces: vec![hull],
            deviation_m: hull_dev,
            hull_deviation_m: hull_dev,
        },
    })
}

/// How far `pieces` deviate from the surface they stand for, metres: the farthest of their
/// surface samples from it (leaving out the samples on another piece: faces two pieces share
/// inside the solid are not its surface), and the farthest of its vertices outside every piece.
fn surface_deviation(pieces: &[ConvexPiece], soup: &TriangleSoup, surface: &TriMesh) -> f64 {
    let planes: Vec<FacePlanes> = pieces.iter().map(FacePlanes::of).collect();
    let on_another = |i: usize, p: &P3| {
        planes
            .iter()
            .enumerate()
            .any(|(j, pl)| j != i && pl.outside(p) <= SHARED_FACE_M)
    };
    let outward = max_distance_to_surface(
        pieces.iter().enumerate().flat_map(|(i, piece)| {
            let on_another = &on_another;
            piece
                .surface_samples()
                .into_iter()
                .filter(move |p| !on_another(i, p))
        }),
        surface,
    );
    outward.max(uncovered(&planes, soup))
}

/// The farthest of the part's vertices outside every piece, metres.
fn uncovered(planes: &[FacePlanes], soup: &TriangleSoup) -> f64 {
    soup.vertices
        .iter()
        .map(|p| {
            planes
                .iter()
                .map(|pl| pl.outside(p).max(0.0))
                .fold(f64::INFINITY, f64::min)
        })
        .fold(0.0, f64::max)
}

/// A sample this close to another piece (or inside it) lies on a face the two share, metres.
const SHARED_FACE_M: f64 = 1e-9;

/// A convex piece's face planes (outward unit normal, offset), for point tests.
struct FacePlanes(Vec<(nalgebra::Vector3<f64>, f64)>);

impl FacePlanes {
    fn of(piece: &ConvexPiece) -> Self {
        FacePlanes(
            piece
                .face_normals
                .iter()
                .map(|n| {
                    let support = piece
                        .vertices
                        .iter()
                        .map(|v| v.coords.dot(n))
                        .fold(f64::MIN, f64::max);
                    (*n, support)
                })
                .collect(),
        )
    }

    /// Distance of `p` outside the piece by its face planes (negative inside; a lower bound
    /// that is exact in the face regions), metres.
    fn outside(&self, p: &P3) -> f64 {
        self.0
            .iter()
            .map(|(n, d)| p.coords.dot(n) - d)
            .fold(f64::MIN, f64::max)
    }
}

fn load_convex_parts(dir: &Path, units: MeshUnits, half_gap_m: f64) -> Result<LoadedSolid> {
    let mut pieces = Vec::new();
    let mut warnings = Vec::new();
    let mut max_dev: f64 = 0.0;
    let mut part_deviations = Vec::new();
    for file in mesh_files(dir)? {
        let part = mesh_part(&read_mesh(&file, units)?, &file)?;
        let dev = part.deviation_m;
        if part.pieces.len() > 1 {
            warnings.push(format!(
                "{}: the part is not convex (its hull stands {:.3} mm off its surface): \
                 decomposed exactly into {} prisms, {:.4} mm off it",
                file.display(),
                part.hull_deviation_m * 1e3,
                part.pieces.len(),
                dev * 1e3
            ));
        } else if dev > half_gap_m.min(1e-4) {
            warnings.push(format!(
                "{}: the part is not convex: its convex hull stands up to {:.3} mm off its surface{}",
                file.display(),
                dev * 1e3,
                if dev > half_gap_m { ", more than half the clearance" } else { "" }
            ));
        }
        max_dev = max_dev.max(dev);
        part_deviations.push((file, dev));
        pieces.extend(part.pieces);
    }
    Ok(LoadedSolid {
        solid: Solid {
            pieces,
            boundary: None,
        },
        max_deviation_m: max_dev,
        part_deviations,
        warnings,
    })
}

/// One part in one file: its convex hull when the part is convex (a cone, a ball, a chamfered
/// pin), its exact pieces when it is a stack of extrusions ([`mesh_part`]), or else parry's
/// V-HACD pieces, when they stand closer to the surface than the hull does.
fn load_and_decompose(path: &Path, units: MeshUnits, half_gap_m: f64) -> Result<LoadedSolid> {
    let soup = read_mesh(path, units)?;
    let part = mesh_part(&soup, path)?;
    let (pieces, dev) = if part.pieces.len() > 1 || part.deviation_m <= HULL_TOLERANCE_M {
        (part.pieces, part.deviation_m)
    } else {
        let surface = trimesh(&soup, path)?;
        let pieces = vhacd_pieces(&surface, path)?;
        match surface_deviation(&pieces, &soup, &surface) {
            dev if dev < part.deviation_m => (pieces, dev),
            _ => (part.pieces, part.deviation_m),
        }
    };
    let mut warnings = Vec::new();
    if dev > half_gap_m {
        warnings.push(format!(
            "{}: the convex decomposition deviates up to {:.3} mm from the surface, more than half the clearance ({:.3} mm); supply convex parts from CoACD or V-HACD instead",
            path.display(),
            dev * 1e3,
            half_gap_m * 1e3
        ));
    }
    Ok(LoadedSolid {
        solid: Solid {
            pieces,
            boundary: None,
        },
        max_deviation_m: dev,
        part_deviations: vec![(path.to_path_buf(), dev)],
        warnings,
    })
}

/// The pieces of a part that is no stack of extrusions, by parry's V-HACD (voxel resolution 64:
/// a bounded cost, under a second for a part of a few thousand triangles).
fn vhacd_pieces(surface: &TriMesh, path: &Path) -> Result<Vec<ConvexPiece>> {
    let v: Vec<V3f> = surface.vertices().to_vec();
    let params = VHACDParameters {
        resolution: 64,
        concavity: 0.005,
        ..Default::default()
    };
    let decomposition = VHACD::decompose(&params, &v, surface.indices(), true);
    let pieces: Vec<ConvexPiece> = decomposition
        .compute_exact_convex_hulls(&v, surface.indices())
        .into_iter()
        .filter_map(|(pts, _)| {
            let p: Vec<P3> = pts
                .iter()
                .map(|q| P3::new(q.x as f64, q.y as f64, q.z as f64))
                .collect();
            ConvexPiece::from_points(&p)
        })
        .collect();
    if pieces.iter().any(|p| p.collider_shape().is_none()) {
        return Err(Error::file(
            path,
            "the convex decomposition produced a part the physics cannot take (flat or degenerate)",
        ));
    }
    if pieces.is_empty() {
        return Err(Error::file(
            path,
            "the convex decomposition produced no part",
        ));
    }
    Ok(pieces)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::twin::geometry::planar::rect;
    use crate::twin::geometry::solid::ZPlane;

    /// A 30 x 30 x 2 mm plate with a 10 x 10 mm square hole off its centre, as one part: the
    /// surfaces of the four boxes around the hole, written as one mesh.
    fn plate_with_a_hole() -> TriangleSoup {
        let mm = |x: f64| x * 1e-3;
        let boxes = [
            (-15.0, -15.0, 15.0, -2.0),
            (-15.0, 8.0, 15.0, 15.0),
            (-15.0, -2.0, -2.0, 8.0),
            (8.0, -2.0, 15.0, 8.0),
        ];
        let mut soup = TriangleSoup {
            vertices: Vec::new(),
            triangles: Vec::new(),
        };
        for (x0, y0, x1, y1) in boxes {
            let mesh = ConvexPiece::slab(
                &rect(mm(x0), mm(y0), mm(x1), mm(y1)),
                ZPlane::flat(0.0),
                ZPlane::flat(mm(2.0)),
            )
            .to_mesh();
            let n = soup.vertices.len() as u32;
            soup.vertices.extend(mesh.vertices);
            soup.triangles
                .extend(mesh.triangles.iter().map(|t| t.map(|i| i + n)));
        }
        soup
    }

    #[test]
    fn a_hull_over_a_hole_in_a_face_is_seen_and_the_plate_is_cut_exactly() {
        let part = mesh_part(&plate_with_a_hole(), Path::new("plate.stl")).unwrap();
        // The hull's faces span the hole: the middle of the hole is 5 mm from its walls.
        assert!(
            (part.hull_deviation_m - 5e-3).abs() < 0.1e-3,
            "{}",
            part.hull_deviation_m
        );
        assert!(part.pieces.len() >= 4, "{}", part.pieces.len());
        assert!(part.deviation_m < 1e-9, "{}", part.deviation_m);
        let volume: f64 = part.pieces.iter().map(|p| p.volume()).sum();
        assert!((volume / (30.0 * 30.0 * 2.0e-9 - 100.0 * 2.0e-9) - 1.0).abs() < 1e-6);
    }
}
