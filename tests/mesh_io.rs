//! Meshes in: convex-part folders, single non-convex files, and bad files.

use pegtwin::twin::geometry::mesh::{MeshUnits, load_solid};
use pegtwin::twin::geometry::solid::{ConvexPiece, P3};
use pegtwin::twin::geometry::{Builtin, build_builtin, export_stl};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::io::Write;

fn volume(solid: &pegtwin::twin::geometry::solid::Solid) -> f64 {
    solid.pieces.iter().map(|p| p.to_mesh().volume()).sum()
}

#[test]
fn a_folder_of_convex_parts_loads_back_as_the_same_solid() {
    let dir = tempfile::tempdir().unwrap();
    let pair = build_builtin(Builtin::Cross, 0.5e-3).unwrap();
    export_stl(&pair, dir.path(), true).unwrap();
    let loaded = load_solid(&dir.path().join("hole_parts"), MeshUnits::Mm, 0.25e-3).unwrap();
    assert_eq!(loaded.solid.pieces.len(), pair.hole.pieces.len());
    assert!(loaded.warnings.is_empty(), "{:?}", loaded.warnings);
    assert!(loaded.max_deviation_m < 1e-6, "{}", loaded.max_deviation_m);
    let (a, b) = (volume(&loaded.solid), volume(&pair.hole));
    assert!((a - b).abs() < 1e-6 * b, "{a} vs {b}");
}

#[test]
fn a_single_non_convex_mesh_is_decomposed_and_its_deviation_reported() {
    let dir = tempfile::tempdir().unwrap();
    let pair = build_builtin(Builtin::Cross, 1.0e-3).unwrap();
    export_stl(&pair, dir.path(), false).unwrap();
    let loaded = load_solid(&dir.path().join("peg.stl"), MeshUnits::Mm, 0.5e-3).unwrap();
    assert!(
        loaded.solid.pieces.len() >= 3,
        "{} parts",
        loaded.solid.pieces.len()
    );
    assert!(loaded.max_deviation_m > 0.0);
    // At a 0.01 mm gap any decomposition error of a voxel-based method is too large: warned.
    let strict = load_solid(&dir.path().join("peg.stl"), MeshUnits::Mm, 0.005e-3).unwrap();
    assert!(
        strict
            .warnings
            .iter()
            .any(|w| w.contains("peg.stl") && w.contains("deviates")),
        "{:?}",
        strict.warnings
    );
}

#[test]
fn a_non_convex_file_in_a_parts_folder_is_measured_and_named() {
    let dir = tempfile::tempdir().unwrap();
    let pair = build_builtin(Builtin::Cross, 0.5e-3).unwrap();
    export_stl(&pair, dir.path(), false).unwrap();
    let parts = dir.path().join("parts");
    std::fs::create_dir(&parts).unwrap();
    std::fs::copy(dir.path().join("peg.stl"), parts.join("whole_peg.stl")).unwrap();
    let loaded = load_solid(&parts, MeshUnits::Mm, 0.25e-3).unwrap();
    let w = loaded.warnings.join("\n");
    assert!(
        w.contains("whole_peg.stl") && w.contains("not convex"),
        "{w}"
    );
    assert!(loaded.max_deviation_m > 1e-3, "{}", loaded.max_deviation_m);
}

#[test]
fn obj_files_and_metre_units_load() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("cube.obj");
    let mut f = std::fs::File::create(&path).unwrap();
    writeln!(f, "v 0 0 0\nv 0.01 0 0\nv 0.01 0.01 0\nv 0 0.01 0\nv 0 0 0.01\nv 0.01 0 0.01\nv 0.01 0.01 0.01\nv 0 0.01 0.01").unwrap();
    writeln!(f, "f 1 3 2\nf 1 4 3\nf 5 6 7\nf 5 7 8\nf 1 2 6\nf 1 6 5\nf 2 3 7\nf 2 7 6\nf 3 4 8\nf 3 8 7\nf 4 1 5\nf 4 5 8").unwrap();
    drop(f);
    std::fs::create_dir(dir.path().join("parts")).unwrap();
    std::fs::copy(&path, dir.path().join("parts/cube.obj")).unwrap();
    let loaded = load_solid(&dir.path().join("parts"), MeshUnits::M, 1e-4).unwrap();
    assert!((volume(&loaded.solid) - 1e-6).abs() < 1e-12);
}

#[test]
fn bad_mesh_files_get_errors_that_name_them() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("nope.stl");
    let e = load_solid(&missing, MeshUnits::Mm, 1e-4)
        .err()
        .unwrap()
        .to_string();
    assert!(e.contains("nope.stl"), "{e}");

    let garbage = dir.path().join("garbage.stl");
    std::fs::write(
        &garbage,
        b"this is not an stl file at all, just some text\n",
    )
    .unwrap();
    let e = load_solid(&garbage, MeshUnits::Mm, 1e-4)
        .err()
        .unwrap()
        .to_string();
    assert!(e.contains("garbage.stl"), "{e}");

    let empty = dir.path().join("empty.stl");
    std::fs::write(&empty, b"solid empty\nendsolid empty\n").unwrap();
    let e = load_solid(&empty, MeshUnits::Mm, 1e-4)
        .err()
        .unwrap()
        .to_string();
    assert!(e.contains("empty.stl") && e.contains("no triangles"), "{e}");

    let text = dir.path().join("notes.txt");
    std::fs::write(&text, b"x").unwrap();
    let e = load_solid(&text, MeshUnits::Mm, 1e-4)
        .err()
        .unwrap()
        .to_string();
    assert!(e.contains("notes.txt") && e.contains(".stl or .obj"), "{e}");

    let empty_dir = dir.path().join("no_parts");
    std::fs::create_dir(&empty_dir).unwrap();
    let e = load_solid(&empty_dir, MeshUnits::Mm, 1e-4)
        .err()
        .unwrap()
        .to_string();
    assert!(
        e.contains("no_parts") && e.contains("no .stl or .obj"),
        "{e}"
    );
}

/// A convex solid of one of the shapes users bring as one file (issue 47, class 6), drawn from
/// `rng`: a cone or a frustum, a faceted ball, a chamfered round pin, or the hull of random
/// points. Its vertices, in mm.
fn random_convex_solid(rng: &mut ChaCha8Rng) -> (&'static str, Vec<[f64; 3]>) {
    let sides = rng.random_range(6..64);
    let ring = |r: f64, z: f64| {
        (0..sides).map(move |k| {
            let a = std::f64::consts::TAU * k as f64 / sides as f64;
            [r * a.cos(), r * a.sin(), z]
        })
    };
    let r = rng.random_range(2.0..20.0);
    let h = rng.random_range(3.0..40.0);
    match rng.random_range(0..4) {
        0 => {
            let top = rng.random_range(0.0..0.9) * r;
            let mut v: Vec<[f64; 3]> = ring(r, 0.0).collect();
            if top < 0.1 {
                v.push([0.0, 0.0, h]);
            } else {
                v.extend(ring(top, h));
            }
            ("cone", v)
        }
        1 => {
            let n = rng.random_range(50..300);
            let v = (0..n)
                .map(|_| {
                    let (u, w): (f64, f64) = (rng.random_range(-1.0..1.0), rng.random());
                    let (s, a) = ((1.0 - u * u).sqrt(), std::f64::consts::TAU * w);
                    [r * s * a.cos(), r * s * a.sin(), r * u]
                })
                .collect();
            ("ball", v)
        }
        2 => {
            let c = rng.random_range(0.1..0.4) * r;
            let v = ring(r - c, 0.0)
                .chain(ring(r, c))
                .chain(ring(r, h))
                .collect();
            ("chamfered pin", v)
        }
        _ => {
            let n = rng.random_range(4..40);
            let v = (0..n)
                .map(|_| [0, 1, 2].map(|_| rng.random_range(-r..r)))
                .collect();
            ("hull of points", v)
        }
    }
}

/// Convex parts in one file (a cone, a ball, a chamfered pin...) load as themselves, one exact
/// piece, with no warning: no longer decomposed by V-HACD and refused as "not convex".
#[test]
fn convex_parts_in_one_file_load_as_one_exact_piece() {
    let dir = tempfile::tempdir().unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(47);
    for k in 0..40 {
        let (shape, vertices) = random_convex_solid(&mut rng);
        let points: Vec<P3> = vertices.iter().map(|v| P3::from(*v) * 1e-3).collect();
        let Some(piece) =
            ConvexPiece::from_points(&points).filter(|p| p.collider_shape().is_some())
        else {
            continue; // the random points fell flat
        };
        let file = dir.path().join(format!("{k}.stl"));
        piece.to_mesh().write_stl_mm(&file).unwrap();
        let loaded = load_solid(&file, MeshUnits::Mm, 0.05e-3).unwrap_or_else(|e| {
            panic!("{shape} ({k}): {e}");
        });
        assert_eq!(loaded.solid.pieces.len(), 1, "{shape} ({k})");
        assert!(
            loaded.warnings.is_empty(),
            "{shape} ({k}): {:?}",
            loaded.warnings
        );
        assert!(
            loaded.max_deviation_m < 1e-6,
            "{shape} ({k}): {}",
            loaded.max_deviation_m
        );
        let (a, b) = (volume(&loaded.solid), piece.to_mesh().volume());
        assert!((a - b).abs() < 1e-6 * b, "{shape} ({k}): {a} vs {b}");
    }
}
