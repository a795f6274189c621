//! Meshes in: convex-part folders, single non-convex files, and bad files.

use pegtwin::twin::geometry::mesh::{MeshUnits, load_solid};
use pegtwin::twin::geometry::{Builtin, build_builtin, export_stl};
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
