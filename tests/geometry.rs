//! Built-in geometry: exact decomposition, watertight exports, clearance as requested.

use nalgebra::Vector3;
use pegtwin::twin::geometry::planar::{P2, distance_to_segment};
use pegtwin::twin::geometry::solid::{ConvexPiece, Solid};
use pegtwin::twin::geometry::{Builtin, build_builtin};
use std::collections::HashMap;

const CLEARANCES_MM: [f64; 4] = [0.1, 0.2, 0.5, 1.0];

/// Volume of a convex piece in f64 from its outward faces (tetrahedra from the centroid).
fn piece_volume(piece: &ConvexPiece) -> f64 {
    let c = piece.centroid().coords;
    piece
        .faces
        .iter()
        .map(|f| {
            let p: Vec<Vector3<f64>> = f
                .iter()
                .map(|&i| piece.vertices[i as usize].coords - c)
                .collect();
            (1..p.len() - 1)
                .map(|k| p[0].dot(&p[k].cross(&p[k + 1])) / 6.0)
                .sum::<f64>()
        })
        .sum()
}

fn pieces_volume(solid: &Solid) -> f64 {
    solid.pieces.iter().map(piece_volume).sum()
}

#[test]
fn convex_pieces_fill_exactly_the_watertight_boundary() {
    for b in Builtin::ALL {
        for c in CLEARANCES_MM {
            let pair = build_builtin(b, c * 1e-3).unwrap();
            for (what, solid) in [("peg", &pair.peg), ("hole", &pair.hole)] {
                let mesh = solid.boundary.as_ref().unwrap();
                assert!(
                    mesh.is_watertight(),
                    "{} {what} at {c} mm is not watertight",
                    b.name()
                );
                let (vm, vp) = (mesh.volume(), pieces_volume(solid));
                // Exact up to the boolean library's picometre snapping.
                assert!(
                    (vm - vp).abs() < 1e-8 * vm,
                    "{} {what} at {c} mm: boundary {vm} m^3 vs pieces {vp} m^3",
                    b.name()
                );
            }
        }
    }
}

/// Segments of a mesh whose two ends lie at height z (millimetre STL, read back).
fn ring_segments_at(mesh: &stl_io::IndexedMesh, z: f32, wall_below: bool) -> Vec<(P2, P2)> {
    let mut segs = HashMap::new();
    let at = |i: usize| (mesh.vertices[i][2] - z).abs() < 1e-4;
    // Only faces of the walls on one side of the ring (not caps), so that cap diagonals and the
    // peg body do not count.
    for f in mesh.faces.iter().filter(|f| {
        !f.vertices.iter().all(|&i| at(i))
            && f.vertices
                .iter()
                .any(|&i| (mesh.vertices[i][2] < z - 1e-4) == wall_below && !at(i))
    }) {
        for k in 0..3 {
            let (a, b) = (f.vertices[k], f.vertices[(k + 1) % 3]);
            let (va, vb) = (mesh.vertices[a], mesh.vertices[b]);
            if at(a) && at(b) {
                let key = (a.min(b), a.max(b));
                segs.insert(
                    key,
                    (
                        P2::new(va[0] as f64, va[1] as f64),
                        P2::new(vb[0] as f64, vb[1] as f64),
                    ),
                );
            }
        }
    }
    segs.into_values().collect()
}

fn read_stl(path: &std::path::Path) -> stl_io::IndexedMesh {
    let mut f = std::fs::File::open(path).unwrap();
    stl_io::read_stl(&mut f).unwrap()
}

fn watertight(mesh: &stl_io::IndexedMesh) -> bool {
    let mut count: HashMap<(usize, usize), i32> = HashMap::new();
    for f in &mesh.faces {
        for k in 0..3 {
            *count
                .entry((f.vertices[k], f.vertices[(k + 1) % 3]))
                .or_default() += 1;
        }
    }
    count
        .iter()
        .all(|(&(a, b), &n)| n == 1 && count.get(&(b, a)) == Some(&1))
}

#[test]
fn exported_stls_are_watertight_and_keep_the_clearance() {
    let dir = tempfile::tempdir().unwrap();
    for b in Builtin::ALL {
        for c in CLEARANCES_MM {
            let pair = build_builtin(b, c * 1e-3).unwrap();
            let out = dir.path().join(format!("{}-{c}", b.name()));
            pegtwin::twin::geometry::export_stl(&pair, &out, false).unwrap();
            let peg = read_stl(&out.join("peg.stl"));
            let hole = read_stl(&out.join("hole.stl"));
            assert!(
                watertight(&peg) && watertight(&hole),
                "{} at {c} mm",
                b.name()
            );
            // Peg walls at the pin's top ring (z = 32 mm, peg frame) against the cavity walls at
            // the floor ring (z = -30 mm, hole frame): both are straight extrusions.
            let peg_ring = ring_segments_at(&peg, 32.0, true);
            let hole_ring = ring_segments_at(&hole, -30.0, false);
            assert!(!peg_ring.is_empty() && !hole_ring.is_empty());
            let one_way = |from: &[(P2, P2)], to: &[(P2, P2)]| {
                from.iter()
                    .flat_map(|s| [s.0, s.1])
                    .map(|p| {
                        to.iter()
                            .map(|t| distance_to_segment(p, t.0, t.1))
                            .fold(f64::INFINITY, f64::min)
                    })
                    .fold(f64::INFINITY, f64::min)
            };
            let gap_mm = one_way(&peg_ring, &hole_ring).min(one_way(&hole_ring, &peg_ring));
            let chord_mm = pair.chord_error_m * 1e3;
            assert!(
                (2.0 * gap_mm - c).abs() <= 2.0 * chord_mm + 2e-5,
                "{} at {c} mm: measured diametral clearance {} mm",
                b.name(),
                2.0 * gap_mm
            );
        }
    }
}

#[test]
fn engine_colliders_keep_every_vertex_and_face() {
    for b in Builtin::ALL {
        for c in CLEARANCES_MM {
            let pair = build_builtin(b, c * 1e-3).unwrap();
            for piece in pair.peg.pieces.iter().chain(&pair.hole.pieces) {
                let centre = piece.centroid();
                let shape = parry3d::shape::ConvexPolyhedron::from_convex_mesh(
                    piece.points_f32_about(&centre),
                    &piece.triangles(),
                )
                .expect("collider builds");
                assert_eq!(
                    shape.points().len(),
                    piece.vertices.len(),
                    "{} at {c} mm",
                    b.name()
                );
                assert_eq!(
                    shape.faces().len(),
                    piece.faces.len(),
                    "{} at {c} mm",
                    b.name()
                );
            }
        }
    }
}

#[test]
fn bad_clearances_and_names_are_rejected() {
    assert!(build_builtin(Builtin::Cross, 0.0).is_err());
    assert!(build_builtin(Builtin::Cross, -1e-4).is_err());
    assert!(build_builtin(Builtin::Cross, 5.1e-3).is_err());
    let err = pegtwin::twin::geometry::builtin_by_name("hexagon")
        .unwrap_err()
        .to_string();
    assert!(err.contains("hexagon") && err.contains("cross"), "{err}");
}
