//! Assembly files: a user's own meshes, in their own frames and units, reach every command as the
//! built-ins do; the fit is measured from the meshes; bad files are refused by field.

mod common;

use common::{pegtwin, stderr};
use nalgebra::{Isometry3, Translation3, UnitQuaternion};
use pegtwin::method::request::TrialRequest;
use pegtwin::pose::rotation_rpy;
use pegtwin::twin::assembly::measure::Seat;
use pegtwin::twin::assembly::{PairSource, load};
use pegtwin::twin::geometry::mesh::{MeshUnits, read_mesh};
use pegtwin::twin::geometry::planar::rect;
use pegtwin::twin::geometry::solid::{BoundaryMesh, ConvexPiece, P3, ZPlane};
use pegtwin::twin::geometry::{Builtin, build_builtin};
use std::path::Path;

/// A pose from mm and deg, R = Rz(yaw) Ry(pitch) Rx(roll).
fn pose(xyz_mm: [f64; 3], rpy_deg: [f64; 3]) -> Isometry3<f64> {
    let [r, p, y] = rpy_deg.map(f64::to_radians);
    Isometry3::from_parts(
        Translation3::new(xyz_mm[0] * 1e-3, xyz_mm[1] * 1e-3, xyz_mm[2] * 1e-3),
        UnitQuaternion::from_rotation_matrix(&rotation_rpy(r, p, y)),
    )
}

/// Every STL in `from` moved by `iso` into `to` (millimetres).
fn move_parts(from: &Path, to: &Path, iso: &Isometry3<f64>) {
    std::fs::create_dir_all(to).unwrap();
    for entry in std::fs::read_dir(from).unwrap() {
        let path = entry.unwrap().path();
        let soup = read_mesh(&path, MeshUnits::Mm).unwrap();
        let moved = BoundaryMesh {
            vertices: soup.vertices.iter().map(|v| iso * v).collect(),
            triangles: soup.triangles,
        };
        moved
            .write_stl_mm(&to.join(path.file_name().unwrap()))
            .unwrap();
    }
}

fn frame_lines(iso_xyz: [f64; 3], rpy: [f64; 3]) -> String {
    format!("frame_xyz_mm = {iso_xyz:?}\nframe_rpy_deg = {rpy:?}\n")
}

/// A built-in's convex parts, exported, moved into other frames, and described by an assembly
/// file whose frames undo the move (the peg upside down 25 mm up, the hole turned and shifted).
fn moved_export(dir: &Path, name: &str, clearance_mm: f64) -> std::path::PathBuf {
    let out = pegtwin(&[
        "geometry",
        "export",
        name,
        "--clearance-mm",
        &clearance_mm.to_string(),
        "--out",
        dir.join("export").to_str().unwrap(),
        "--convex-parts",
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let (peg_xyz, peg_rpy) = ([10.0, -5.0, 25.0], [180.0, 0.0, 30.0]);
    let (hole_xyz, hole_rpy) = ([100.0, 50.0, -20.0], [0.0, 0.0, 90.0]);
    move_parts(
        &dir.join("export/peg_parts"),
        &dir.join("parts/peg"),
        &pose(peg_xyz, peg_rpy),
    );
    move_parts(
        &dir.join("export/hole_parts"),
        &dir.join("parts/hole"),
        &pose(hole_xyz, hole_rpy),
    );
    let file = dir.join(format!("{name}.toml"));
    let text = format!(
        "name = \"my-{name}\"\n[peg]\nmesh = \"parts/peg\"\nunits = \"mm\"\nmass_kg = 0.3\n{}[hole]\nmesh = \"parts/hole/\"\nunits = \"mm\"\n{}",
        frame_lines(peg_xyz, peg_rpy),
        frame_lines(hole_xyz, hole_rpy)
    );
    std::fs::write(&file, text).unwrap();
    file
}

#[test]
fn exported_parts_in_other_frames_load_as_the_builtin_with_its_measured_clearance() {
    for (builtin, clearance_mm) in [(Builtin::Cross, 0.5), (Builtin::Plug3, 0.5)] {
        let dir = tempfile::tempdir().unwrap();
        let file = moved_export(dir.path(), builtin.name(), clearance_mm);
        let assembly = load(&file).unwrap();
        let reference = build_builtin(builtin, clearance_mm * 1e-3).unwrap();
        let r = &assembly.report;
        // Within the built-in's chord error per side, both sides: the diametral clearance.
        let tolerance_mm = 2.0 * reference.chord_error_m * 1e3 + 1e-5;
        assert!(
            (r.clearance_min_mm - clearance_mm).abs() <= tolerance_mm,
            "{}: {} mm",
            builtin.name(),
            r.clearance_min_mm
        );
        assert_eq!(r.seat, Seat::TipOnFloor);
        assert!(r.blind);
        assert!((r.insertion_depth_mm - reference.cavity_depth_m * 1e3).abs() < 1e-3);
        assert_eq!(r.peg.pieces, reference.peg.pieces.len());
        assert_eq!(r.hole.pieces, reference.hole.pieces.len());
        for (a, b) in [
            (assembly.pair.peg.bounds(), reference.peg.bounds()),
            (assembly.pair.hole.bounds(), reference.hole.bounds()),
        ] {
            assert!((a.0 - b.0).norm() < 1e-6 && (a.1 - b.1).norm() < 1e-6);
        }
    }
}

#[test]
fn a_trial_on_the_exported_cross_goes_as_on_the_builtin() {
    let dir = tempfile::tempdir().unwrap();
    let file = moved_export(dir.path(), "cross", 0.5);
    let run = |pair: PairSource| {
        let mut request = TrialRequest::new("cross", 0.5);
        request.pair = pair;
        request.method = pegtwin::method::config::Method::Direct;
        request.seed = 3;
        // The ideal cell: the real one prints the built-in (its walls and edges off the CAD),
        // while an assembly's files are its parts as they are.
        request.profile = pegtwin::twin::real_cell::Profile::Ideal;
        request.run(&()).unwrap()
    };
    let mine = run(PairSource::Assembly(file));
    let builtin = run(PairSource::Builtin {
        name: "cross".into(),
        clearance_mm: 0.5,
    });
    assert_eq!(mine.geometry, "my-cross");
    assert_eq!(mine.outcome, builtin.outcome);
    let (a, b) = (
        mine.final_depth_mm.unwrap(),
        builtin.final_depth_mm.unwrap(),
    );
    assert!((a - b).abs() < 0.5, "{a} vs {b} mm");
}

/// Writes each box (x0, y0, z0, x1, y1, z1 in mm) as one convex part in `dir`.
fn write_boxes(dir: &Path, boxes: &[[f64; 6]]) {
    std::fs::create_dir_all(dir).unwrap();
    for (k, b) in boxes.iter().enumerate() {
        let m = b.map(|v| v * 1e-3);
        let piece = ConvexPiece::slab(
            &rect(m[0], m[1], m[3], m[4]),
            ZPlane::flat(m[2]),
            ZPlane::flat(m[5]),
        );
        piece
            .to_mesh()
            .write_stl_mm(&dir.join(format!("{k}.stl")))
            .unwrap();
    }
}

/// A square 10 mm pin (`pin_mm` long) under a 30 mm flange (or none), and a square cavity
/// `clearance_mm` wider, 25 mm deep in a 40 mm block, with or without its floor.
fn square_pair(
    dir: &Path,
    (pin_mm, clearance_mm): (f64, f64),
    flange: bool,
    floor: bool,
    extra: &str,
) -> std::path::PathBuf {
    let mut peg = vec![[-5.0, -5.0, 0.0, 5.0, 5.0, pin_mm]];
    if flange {
        peg.push([-15.0, -15.0, pin_mm, 15.0, 15.0, pin_mm + 5.0]);
    }
    write_boxes(&dir.join("peg"), &peg);
    let (h, w) = (5.0 + clearance_mm / 2.0, 20.0);
    let mut hole = vec![
        [-w, -w, -25.0, -h, w, 0.0],
        [h, -w, -25.0, w, w, 0.0],
        [-h, -w, -25.0, h, -h, 0.0],
        [-h, h, -25.0, h, w, 0.0],
    ];
    if floor {
        hole.push([-w, -w, -35.0, w, w, -25.0]);
    }
    write_boxes(&dir.join("hole"), &hole);
    let file = dir.join("square.toml");
    let text = format!(
        "name = \"square\"\n[peg]\nmesh = \"peg\"\nunits = \"mm\"\n[hole]\nmesh = \"hole\"\nunits = \"mm\"\n{extra}"
    );
    std::fs::write(&file, text).unwrap();
    file
}

#[test]
fn where_the_peg_seats_is_measured_flange_floor_or_through() {
    let dir = tempfile::tempdir().unwrap();
    let seated = load(&square_pair(dir.path(), (20.0, 0.4), true, true, "")).unwrap();
    let r = &seated.report;
    assert_eq!(r.seat, Seat::FlangeOnBlock);
    assert!((r.insertion_depth_mm - 20.0).abs() < 1e-3, "{r:?}");
    assert!((r.cavity_depth_mm.unwrap() - 25.0).abs() < 1e-3);
    assert!(
        (r.clearance_min_mm - 0.4).abs() < 1e-4,
        "{}",
        r.clearance_min_mm
    );
    assert!((seated.pair.peg_mass_kg.unwrap() - 2700.0 * 6.5e-6).abs() < 1e-6);

    let dir = tempfile::tempdir().unwrap();
    let through = load(&square_pair(dir.path(), (40.0, 0.4), false, false, "")).unwrap_err();
    assert!(
        through
            .to_string()
            .contains("hole.success_depth_mm: missing"),
        "{through}"
    );
    let file = square_pair(
        dir.path(),
        (40.0, 0.4),
        false,
        false,
        "success_depth_mm = 22\n",
    );
    let through = load(&file).unwrap();
    assert_eq!(through.report.seat, Seat::Through);
    assert!(!through.report.blind);
    assert!((through.pair.cavity_depth_m - 22e-3).abs() < 1e-12);
    // validate leaves the floor press out: a through hole has no floor.
    let out = pegtwin(&["validate", "--assembly", file.to_str().unwrap()]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(!text.contains("floor_press"), "{text}");
    assert!(text.contains("a through hole's success depth"), "{text}");
}

/// `pegtwin validate --assembly FILE`, which must pass: its report.
fn validate_passes(file: &Path) -> String {
    let out = pegtwin(&["validate", "--assembly", file.to_str().unwrap()]);
    let text = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(out.status.success(), "{text}{}", stderr(&out));
    text
}

/// At 1 mm: at 0.4 mm this sharp-edged square pin's lateral press reads 21 um of exact
/// penetration against the 20 um bar (the seat, the subject here, passes there too).
#[test]
fn validate_passes_a_pair_whose_flange_seats_before_the_tip_reaches_the_floor() {
    let dir = tempfile::tempdir().unwrap();
    let file = square_pair(dir.path(), (20.0, 1.0), true, true, "");
    let text = validate_passes(&file);
    assert!(
        text.contains("(full insertion at -20.000 mm, flange on the block)"),
        "{text}"
    );
}

/// A bare 10 mm square pin (no holder) held by the free-peg rig at 0.3 kg turns fast about its
/// axis (2000 rad/s of impedance damping against a 1 ms step): the rig halves its step, and the
/// tilted cases, which went 3.9 mm into the walls at 1 ms, pass.
#[test]
fn validate_steps_a_bare_slender_pin_finer_and_passes_it() {
    let dir = tempfile::tempdir().unwrap();
    let file = square_pair(dir.path(), (20.0, 1.0), false, true, "");
    let text = validate_passes(&file);
    assert!(text.contains("step 0.5 ms"), "{text}");
}

/// The flanged square pin of `square_pair` (20 mm) in a square cavity `clearance_mm` wider, 25 mm
/// deep, whose mouth carries a `chamfer_mm` x 45 deg chamfer on each side (square corners: the
/// four chamfered walls stand between four corner blocks).
fn chamfered_square_pair(dir: &Path, clearance_mm: f64, chamfer_mm: f64) -> std::path::PathBuf {
    let file = square_pair(dir, (20.0, clearance_mm), true, true, "");
    let hole = dir.join("hole");
    std::fs::remove_dir_all(&hole).unwrap();
    let (h, w, d) = (5.0 + clearance_mm / 2.0, 20.0, 25.0);
    let mut boxes = vec![[-w, -w, -d - 10.0, w, w, -d]];
    for (sx, sy) in [(1.0, 1.0), (1.0, -1.0), (-1.0, 1.0), (-1.0, -1.0)] {
        let (x, y) = (sx * h, sy * h);
        let (xw, yw) = (sx * w, sy * w);
        boxes.push([x.min(xw), y.min(yw), -d, x.max(xw), y.max(yw), 0.0]);
    }
    write_boxes(&hole, &boxes);
    // A wall's section across it (from the cavity outwards, depth), turned to each side.
    let section = [
        (h, -d),
        (w, -d),
        (w, 0.0),
        (h + chamfer_mm, 0.0),
        (h, -chamfer_mm),
    ];
    let turns = [(1.0, 0.0), (-1.0, 0.0), (0.0, 1.0), (0.0, -1.0)];
    for (k, (cx, cy)) in turns.into_iter().enumerate() {
        let points: Vec<P3> = section
            .iter()
            .flat_map(|&(u, z)| {
                [-h, h].map(|v| P3::new(cx * u - cy * v, cy * u + cx * v, z) * 1e-3)
            })
            .collect();
        ConvexPiece::from_points(&points)
            .unwrap()
            .to_mesh()
            .write_stl_mm(&hole.join(format!("wall{k}.stl")))
            .unwrap();
    }
    file
}

/// The rim jam sets the peg down past a chamfer that would guide it in (at 2.5 mm the peg's
/// edge at the usual 3 mm offset lands on the chamfer and slides 1.8 mm in), and the rest of the
/// matrix runs as without a chamfer.
#[test]
fn validate_passes_a_pair_with_an_entry_chamfer() {
    let dir = tempfile::tempdir().unwrap();
    let file = chamfered_square_pair(dir.path(), 1.0, 2.5);
    let text = validate_passes(&file);
    assert!(
        text.contains("resting on the rim 3.5 mm off the axis (past the mouth's chamfer"),
        "{text}"
    );
}

/// The pin and the flange of `square_pair` as one part (an L in section: its hull stands 8 mm
/// off its surface), turned by `turn` in the file.
fn write_pin_and_flange(dir: &Path, turn: &Isometry3<f64>) {
    let pin = ConvexPiece::slab(
        &rect(-5e-3, -5e-3, 5e-3, 5e-3),
        ZPlane::flat(0.0),
        ZPlane::flat(20e-3),
    );
    let flange = ConvexPiece::slab(
        &rect(-15e-3, -15e-3, 15e-3, 15e-3),
        ZPlane::flat(20e-3),
        ZPlane::flat(25e-3),
    );
    let (a, b) = (pin.to_mesh(), flange.to_mesh());
    let n = a.vertices.len() as u32;
    let both = BoundaryMesh {
        vertices: a
            .vertices
            .iter()
            .chain(&b.vertices)
            .map(|p| turn * p)
            .collect(),
        triangles: a
            .triangles
            .iter()
            .copied()
            .chain(b.triangles.iter().map(|t| t.map(|i| i + n)))
            .collect(),
    };
    std::fs::remove_dir_all(dir.join("peg")).unwrap();
    std::fs::create_dir(dir.join("peg")).unwrap();
    both.write_stl_mm(&dir.join("peg/pin_and_flange.stl"))
        .unwrap();
}

/// A part that is not convex is never hulled: as a stack of extrusions along an axis of its
/// file it is cut into exact prisms (the L: two, 0 mm off its surface; turned 20 deg about x it
/// is still a stack, along x); turned about two axes, it is refused by name.
#[test]
fn a_part_that_is_not_convex_is_decomposed_exactly_or_refused_by_name() {
    let dir = tempfile::tempdir().unwrap();
    let file = square_pair(dir.path(), (20.0, 0.4), true, true, "");
    write_pin_and_flange(dir.path(), &Isometry3::identity());
    let loaded = load(&file).unwrap();
    assert_eq!(loaded.pair.peg.pieces.len(), 2);
    let dev = loaded.report.peg.max_deviation_mm;
    assert!(dev < 1e-6, "{dev} mm");
    assert!(
        loaded
            .report
            .warnings
            .iter()
            .any(|w| w.contains("decomposed exactly into 2 prisms")),
        "{:?}",
        loaded.report.warnings
    );
    assert!((loaded.report.clearance_min_mm - 0.4).abs() < 1e-4);

    // Asked to decompose with CoACD, a stack keeps its exact cut: its two prisms.
    let plain = std::fs::read_to_string(&file).unwrap();
    let asked = plain
        .replacen(
            "mesh = \"peg\"\nunits = \"mm\"\n",
            "mesh = \"peg/pin_and_flange.stl\"\nunits = \"mm\"\ndecompose = \"coacd\"\n",
            1,
        )
        .replacen("[peg]", "clearance_mm = 0.4\n[peg]", 1);
    std::fs::write(&file, &asked).unwrap();
    let kept = pegtwin(&["assembly", "check", file.to_str().unwrap(), "--json"]);
    assert!(kept.status.success(), "{asked}\n{}", stderr(&kept));
    let report: serde_json::Value = serde_json::from_slice(&kept.stdout).unwrap();
    assert_eq!(report["peg"]["pieces"], 2, "{report}");
    std::fs::write(&file, &plain).unwrap();

    let turned = |rpy: [f64; 3]| {
        write_pin_and_flange(dir.path(), &pose([0.0; 3], rpy));
        let frame = format!("units = \"mm\"\nframe_rpy_deg = {rpy:?}\n");
        std::fs::write(&file, plain.replacen("units = \"mm\"\n", &frame, 1)).unwrap();
        load(&file)
    };
    let along_x = turned([20.0, 0.0, 0.0]).unwrap();
    assert!(along_x.report.peg.max_deviation_mm < 1e-6);
    assert!((along_x.report.clearance_min_mm - 0.4).abs() < 1e-4);
    let err = turned([20.0, 30.0, 0.0]).unwrap_err().to_string();
    assert!(
        err.contains("pin_and_flange.stl") && err.contains("it is not convex"),
        "{err}"
    );
}

/// A convex peg in one file (a square pin with a 1 mm chamfer at its tip) is taken as it is, one
/// exact piece, where V-HACD's pieces had it refused as "not convex" (issue 47, class 6).
#[test]
fn a_convex_peg_in_one_file_is_taken_as_it_is() {
    let dir = tempfile::tempdir().unwrap();
    let file = square_pair(dir.path(), (20.0, 0.4), false, true, "");
    let square = |half: f64, z: f64| {
        [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)]
            .map(|(x, y)| P3::new(x * half, y * half, z) * 1e-3)
    };
    let points: Vec<P3> = [square(4.0, 0.0), square(5.0, 1.0), square(5.0, 20.0)].concat();
    (ConvexPiece::from_points(&points).unwrap().to_mesh())
        .write_stl_mm(&dir.path().join("pin.stl"))
        .unwrap();
    let text = std::fs::read_to_string(&file).unwrap();
    std::fs::write(
        &file,
        text.replacen("mesh = \"peg\"", "mesh = \"pin.stl\"", 1),
    )
    .unwrap();
    let loaded = load(&file).unwrap();
    assert_eq!(loaded.pair.peg.pieces.len(), 1);
    assert!(loaded.report.peg.max_deviation_mm < 1e-6);
    assert!((loaded.report.clearance_min_mm - 0.4).abs() < 1e-4);
}

#[test]
fn bad_assembly_files_are_refused_by_field_with_exit_2() {
    let dir = tempfile::tempdir().unwrap();
    let good = square_pair(dir.path(), (20.0, 0.4), true, true, "");
    let text = std::fs::read_to_string(&good).unwrap();
    let cases = [
        (
            text.replace("mesh = \"peg\"", "mesh = \"nowhere\""),
            "nowhere",
        ),
        (
            text.replace("units = \"mm\"\n[hole]", "units = \"m\"\n[hole]"),
            "read as metres",
        ),
        (
            text.replace("[hole]\n", "frame_xyz_mm = [0, 0, -10]\n[hole]\n"),
            "peg.frame_xyz_mm: the peg's lowest point lies 10.000 mm above",
        ),
        (
            text.replace("[hole]\n", "frame_xyz_mm = [3, 0, 0]\n[hole]\n"),
            "the peg stops 0.000 mm below the mouth",
        ),
        (
            text.replace("[hole]\n", "frame_xyz_mm = [3, 0, 0]\n[hole]\n")
                + "frame_xyz_mm = [0, 0, -10]\n",
            "the peg already intersects the hole",
        ),
        (
            format!("{text}frame_rpy_deg = [180, 0, 0]\n"),
            "hole.frame_rpy_deg",
        ),
        (
            text.replace("name = \"square\"", "name = \"a/b\""),
            "name = \"a/b\"",
        ),
        (
            format!("{text}colour = 1\n"),
            "line 8: unknown field `colour`",
        ),
        (
            text.replace("units = \"mm\"\n[hole]", "[hole]"),
            "peg.units: missing",
        ),
        (
            text.replace("[hole]\n", "frame_xyz_mm = [0, 0, 0, 1e308]\n[hole]\n"),
            "peg.frame_xyz_mm: 4 values given, expected 3",
        ),
        (
            text.replace("mesh = \"peg\"", "mesh = \"flat\""),
            "peg.mesh: convex piece 0 of the peg has no volume",
        ),
        (
            text.replace("mesh = \"peg\"", "mesh = \"sheet\""),
            "the peg is 0.0500 mm thick at its thinnest",
        ),
    ];
    write_boxes(
        &dir.path().join("flat"),
        &[[-5.0, -5.0, 0.0, 5.0, 5.0, 0.0]],
    );
    write_boxes(
        &dir.path().join("sheet"),
        &[[-5.0, -0.025, 0.0, 5.0, 0.025, 20.0]],
    );
    for (k, (body, expected)) in cases.iter().enumerate() {
        let file = dir.path().join(format!("bad{k}.toml"));
        std::fs::write(&file, body).unwrap();
        let out = pegtwin(&["assembly", "check", file.to_str().unwrap()]);
        let err = stderr(&out);
        assert_eq!(out.status.code(), Some(2), "case {k}: {err}");
        assert!(err.contains(expected), "case {k}: {err}");
    }
}

#[test]
fn a_scenario_runs_assemblies_beside_builtins_and_keys_on_their_meshes() {
    let dir = tempfile::tempdir().unwrap();
    moved_export(dir.path(), "cross", 0.5);
    let scenario = dir.path().join("mine.toml");
    std::fs::write(
        &scenario,
        "name = \"mine\"\ntrials = 2\ngeometries = [\"cross\"]\nclearances_mm = [1.0]\n\
         assemblies = [\"cross.toml\"]\nt_obs_s = [10.0]\nmethods = [\"direct\"]\n",
    )
    .unwrap();
    let s = pegtwin::campaign::scenario::Scenario::load(&scenario).unwrap();
    let labels: Vec<String> = s.cells().iter().map(|c| c.label()).collect();
    assert_eq!(
        labels,
        ["cross 1 mm direct 10 s", "my-cross 0.5 mm direct 10 s"]
    );
    // Named as a user in its folder names it: a bare file name.
    let out = dir.path().join("results");
    let run = std::process::Command::new(env!("CARGO_BIN_EXE_pegtwin"))
        .args(["campaign", "mine.toml", "--out", "results"])
        .current_dir(dir.path())
        .output()
        .unwrap();
    assert!(run.status.success(), "{}", stderr(&run));
    // `check` reads the scenario back from campaign.json, its assemblies with it.
    let baseline = dir.path().join("baseline.json");
    let check = pegtwin(&[
        "check",
        out.to_str().unwrap(),
        "--write-baseline",
        baseline.to_str().unwrap(),
    ]);
    assert!(check.status.success(), "{}", stderr(&check));
    assert!(
        std::fs::read_to_string(&baseline)
            .unwrap()
            .contains("my-cross")
    );

    // Editing a mesh is another campaign; a name taken by a built-in is refused.
    let part = dir.path().join("parts/hole/0000.stl");
    let mut soup = read_mesh(&part, MeshUnits::Mm).unwrap();
    soup.vertices[0].x -= 1e-4;
    BoundaryMesh {
        vertices: soup.vertices,
        triangles: soup.triangles,
    }
    .write_stl_mm(&part)
    .unwrap();
    let edited = pegtwin::campaign::scenario::Scenario::load(&scenario).unwrap();
    assert_ne!(edited.fingerprint(), s.fingerprint());
    let file = dir.path().join("cross.toml");
    let text = std::fs::read_to_string(&file).unwrap();
    std::fs::write(&file, text.replace("my-cross", "cross")).unwrap();
    let err = pegtwin::campaign::scenario::Scenario::load(&scenario).unwrap_err();
    assert!(err.to_string().contains("is already taken"), "{err}");
}

#[test]
fn mjcf_bodies_of_mesh_and_box_geoms_are_parts() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let out = pegtwin(&[
        "geometry",
        "export",
        "cross",
        "--clearance-mm",
        "0.5",
        "--out",
        d.join("export").to_str().unwrap(),
        "--convex-parts",
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    // The hole's parts turned 90 deg about z, which its geom's euler turns back.
    move_parts(
        &d.join("export/hole_parts"),
        &d.join("meshes/hole"),
        &pose([0.0; 3], [0.0, 0.0, 90.0]),
    );
    let mut assets = String::new();
    let mut peg_geoms = String::new();
    let mut hole_geoms = String::new();
    for (kind, folder, geoms, extra) in [
        ("peg", d.join("export/peg_parts"), &mut peg_geoms, ""),
        (
            "hole",
            d.join("meshes/hole"),
            &mut hole_geoms,
            " euler=\"0 0 -90\"",
        ),
    ] {
        let mut files: Vec<_> = std::fs::read_dir(&folder)
            .unwrap()
            .map(|e| e.unwrap().path())
            .collect();
        files.sort();
        for (k, f) in files.iter().enumerate() {
            assets.push_str(&format!(
                "<mesh name=\"{kind}{k}\" file=\"{}\" scale=\"0.001 0.001 0.001\"/>\n",
                f.display()
            ));
            geoms.push_str(&format!(
                "<geom type=\"mesh\" mesh=\"{kind}{k}\"{extra}/>\n"
            ));
        }
    }
    let model = format!(
        "<mujoco>\n<compiler angle=\"degree\"/>\n<asset>\n{assets}</asset>\n<worldbody>\n\
         <body name=\"peg\" pos=\"0.5 0 0.3\">\n{peg_geoms}</body>\n\
         <body name=\"block\" pos=\"0.5 0 0\"><body name=\"hole\" quat=\"1 0 0 0\">\n{hole_geoms}</body></body>\n\
         <body name=\"square\"><geom type=\"box\" size=\"0.005 0.005 0.01\" pos=\"0 0 0.01\"/></body>\n\
         <body name=\"square_hole\">\n\
         <geom type=\"box\" size=\"0.02 0.0148 0.0125\" pos=\"0 0.0202 -0.0125\"/>\n\
         <geom type=\"box\" size=\"0.02 0.0148 0.0125\" pos=\"0 -0.0202 -0.0125\"/>\n\
         <geom type=\"box\" size=\"0.0148 0.0054 0.0125\" pos=\"0.0202 0 -0.0125\"/>\n\
         <geom type=\"box\" size=\"0.0148 0.0054 0.0125\" pos=\"-0.0202 0 -0.0125\"/>\n\
         <geom type=\"box\" size=\"0.02 0.02 0.005\" pos=\"0 0 -0.03\"/>\n\
         </body>\n</worldbody>\n</mujoco>\n"
    );
    std::fs::write(d.join("env.xml"), model).unwrap();
    let assembly = |peg: &str, hole: &str| {
        let file = d.join(format!("{peg}.toml"));
        let text = format!(
            "name = \"{peg}\"\n[peg]\nmjcf = \"env.xml\"\nbody = \"{peg}\"\n[hole]\nmjcf = \"env.xml\"\nbody = \"{hole}\"\n"
        );
        std::fs::write(&file, text).unwrap();
        file
    };
    let cross = load(&assembly("peg", "hole")).unwrap();
    assert!(
        (cross.report.clearance_min_mm - 0.5).abs() < 1e-4,
        "{:?}",
        cross.report
    );
    assert_eq!(cross.report.seat, Seat::TipOnFloor);
    assert!((cross.report.insertion_depth_mm - 30.0).abs() < 1e-3);
    let square = load(&assembly("square", "square_hole")).unwrap();
    assert!(
        (square.report.clearance_min_mm - 0.8).abs() < 1e-4,
        "{:?}",
        square.report
    );
    assert!((square.report.insertion_depth_mm - 25.0).abs() < 1e-3);

    let missing = assembly("square", "no_such_body");
    let out = pegtwin(&["assembly", "check", missing.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2));
    let err = stderr(&out);
    assert!(
        err.contains("env.xml") && err.contains("no <body name=\"no_such_body\">"),
        "{err}"
    );
}

fn within_one_percent(measured_mm: f64, true_mm: f64, what: &str) {
    assert!(
        (measured_mm - true_mm).abs() <= 0.01 * true_mm,
        "{what}: measured {measured_mm} mm, made {true_mm} mm"
    );
}

/// `assembly check` measures fits of 0.1-10 mm within 1 %: exported built-ins with flat walls
/// (moved into other frames) and square pins, blind and through (issue 47, class 4: the floor
/// once read as a wall, so that any clearance above about 2 mm read as about 2 mm).
#[test]
fn fits_of_a_tenth_to_ten_millimetres_are_measured_within_one_percent() {
    for clearance_mm in [0.1, 0.5, 1.0, 2.0, 5.0] {
        for builtin in [Builtin::Cross, Builtin::Extrusion] {
            let dir = tempfile::tempdir().unwrap();
            let file = moved_export(dir.path(), builtin.name(), clearance_mm);
            let r = load(&file).unwrap().report;
            let what = format!("{} at {clearance_mm} mm", builtin.name());
            within_one_percent(r.clearance_min_mm, clearance_mm, &what);
            within_one_percent(r.clearance_median_mm, clearance_mm, &what);
            let lined_up = r.axis_offset_mm < 0.01 * clearance_mm && r.axis_tilt_deg < 0.01;
            assert!(lined_up, "{what}: {r:?}");
        }
    }
    for clearance_mm in [0.1, 0.5, 1.0, 2.0, 5.0, 10.0] {
        for blind in [true, false] {
            let dir = tempfile::tempdir().unwrap();
            let extra = if blind { "" } else { "success_depth_mm = 22\n" };
            let file = square_pair(dir.path(), (40.0, clearance_mm), false, blind, extra);
            let r = load(&file).unwrap().report;
            let what = format!("square pin at {clearance_mm} mm, blind {blind}");
            within_one_percent(r.clearance_min_mm, clearance_mm, &what);
            within_one_percent(r.clearance_median_mm, clearance_mm, &what);
            assert_eq!(r.blind, blind, "{what}");
        }
    }
}

/// The millimetres or degrees an error message gives after `before`.
fn figure_after(text: &str, before: &str) -> f64 {
    let at = text
        .find(before)
        .unwrap_or_else(|| panic!("{before:?} not in {text}"))
        + before.len();
    let figure: String = text[at..]
        .chars()
        .take_while(|c| c.is_ascii_digit() || *c == '.')
        .collect();
    figure.parse().unwrap()
}

/// A hole frame off the hole's axis (0.1-0.4 of the clearance, any direction) or tilted
/// (0.2-0.5 deg about any horizontal axis), drawn from a seeded stream over clearances of
/// 0.1-5 mm, is refused with the size of the misalignment, not measured as a tighter fit
/// (issue 47, class 4); the same pairs lined up load.
#[test]
fn frames_off_the_axis_or_tilted_are_refused_with_the_size_of_it() {
    use rand::{Rng, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(47);
    let mut cases: Vec<(f64, [f64; 3], [f64; 3])> = vec![(0.5, [0.05, 0.0, 0.0], [0.0; 3])];
    for _ in 0..4 {
        let clearance_mm = 10f64.powf(rng.random_range(-1.0..0.7));
        let (size, turn) = (rng.random_range(0.1..0.4), rng.random_range(0.0..360f64));
        let (dx, dy) = (turn.to_radians().cos(), turn.to_radians().sin());
        let offset = [dx * size * clearance_mm, dy * size * clearance_mm, 0.0];
        cases.push((clearance_mm, offset, [0.0; 3]));
        let clearance_mm = rng.random_range(0.5..5.0);
        let (tilt, turn) = (rng.random_range(0.2..0.5), rng.random_range(0.0..360f64));
        let rpy = [
            tilt * turn.to_radians().cos(),
            tilt * turn.to_radians().sin(),
            0.0,
        ];
        cases.push((clearance_mm, [0.0; 3], rpy));
    }
    for (clearance_mm, xyz, rpy) in cases {
        let dir = tempfile::tempdir().unwrap();
        let lined_up = square_pair(dir.path(), (40.0, clearance_mm), false, true, "");
        within_one_percent(
            load(&lined_up).unwrap().report.clearance_min_mm,
            clearance_mm,
            "lined up",
        );
        let file = square_pair(
            dir.path(),
            (40.0, clearance_mm),
            false,
            true,
            &frame_lines(xyz, rpy),
        );
        let err = load(&file).unwrap_err().to_string();
        let what = format!("{clearance_mm} mm, frame {xyz:?} {rpy:?}: {err}");
        if rpy == [0.0; 3] {
            let off = figure_after(&err, "stands ");
            let truth = xyz[0].hypot(xyz[1]);
            assert!((off - truth).abs() <= 0.25 * truth, "{what}");
        } else {
            let tilt = figure_after(&err, "leans ");
            let truth = rpy[0].hypot(rpy[1]);
            assert!((tilt - truth).abs() <= 0.25 * truth, "{what}");
        }
    }
}

/// A round peg from MuJoCo primitives (a cylinder by `fromto`; a display sphere and a geom
/// whose bits meet no hole geom left out) in a square hole of boxes placed through default
/// classes: the clearance is the square's side less the diameter, as the polygonised cylinder
/// has a vertex on each axis.
#[test]
fn mjcf_primitives_through_default_classes_make_a_pair() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(
        d.join("walls.xml"),
        "<mujoco>\n<default><default class=\"wall\"><geom type=\"box\" size=\"0.02 0.0148 0.0125\"/>\
         </default></default>\n</mujoco>\n",
    )
    .unwrap();
    let model = "<mujoco>\n<include file=\"walls.xml\"/>\n<worldbody>\n\
         <body name=\"peg\" pos=\"0 0 0.3\">\n\
         <geom type=\"cylinder\" fromto=\"0 0 0.03 0 0 0\" size=\"0.0046\"/>\n\
         <geom name=\"look\" type=\"sphere\" size=\"0.03\" contype=\"0\" conaffinity=\"0\"/>\n\
         <geom name=\"bits\" type=\"box\" size=\"0.03 0.03 0.001\" pos=\"0 0 0.02\" contype=\"2\" conaffinity=\"2\"/>\n\
         </body>\n\
         <body name=\"hole\" childclass=\"wall\">\n\
         <geom pos=\"0 0.0202 -0.0125\"/>\n<geom pos=\"0 -0.0202 -0.0125\"/>\n\
         <geom pos=\"0.0202 0 -0.0125\" zaxis=\"0 0 1\" size=\"0.0148 0.0054\"/>\n\
         <geom pos=\"-0.0202 0 -0.0125\" size=\"0.0148 0.0054\"/>\n\
         <geom type=\"box\" size=\"0.02 0.02 0.005\" pos=\"0 0 -0.03\"/>\n\
         </body>\n</worldbody>\n</mujoco>\n";
    std::fs::write(d.join("env.xml"), model).unwrap();
    let file = d.join("round.toml");
    std::fs::write(
        &file,
        "name = \"round\"\n[peg]\nmjcf = \"env.xml\"\nbody = \"peg\"\n[hole]\nmjcf = \"env.xml\"\nbody = \"hole\"\n",
    )
    .unwrap();
    let round = load(&file).unwrap();
    // Square 2 x 5.4 mm, diameter 9.2 mm: 10.8 - 9.2 = 1.6 mm.
    assert!(
        (round.report.clearance_min_mm - 1.6).abs() < 1e-4,
        "{:?}",
        round.report
    );
    assert!(
        round.report.peg.max_deviation_mm <= 0.0025,
        "{:?}",
        round.report.peg
    );
    assert!(
        round.report.peg.max_deviation_mm > 0.0,
        "{:?}",
        round.report.peg
    );
    assert!((round.report.insertion_depth_mm - 25.0).abs() < 1e-3);
    let warned = round.report.warnings.join("\n");
    assert!(
        warned.contains("<geom name=\"bits\"> (line 7)") && warned.contains("left out"),
        "{warned}"
    );
    assert!(!warned.contains("look"), "{warned}");
}

/// What pegtwin does not read is refused by element, attribute and line, with exit 2.
#[test]
fn mjcf_refusals_name_the_element_attribute_and_line() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    for (body, expected) in [
        (
            "<geom type=\"plane\" size=\"1 1 1\"/>",
            &["<geom> (line 3)", "type=\"plane\"", "not a part"][..],
        ),
        (
            "<geom name=\"g\" type=\"box\" size=\"1 1 1\" quat=\"1 0 0 0\" zaxis=\"0 0 1\"/>",
            &["<geom name=\"g\"> (line 3)", "quat and zaxis"][..],
        ),
        (
            "<geom class=\"nope\" type=\"box\" size=\"1 1 1\"/>",
            &["(line 3)", "class=\"nope\""][..],
        ),
        (
            "<geom type=\"sphere\" fromto=\"0 0 0 0 0 1\" size=\"1\"/>",
            &["(line 3)", "fromto=", "not a sphere"][..],
        ),
        (
            "<geom type=\"box\" mesh=\"m\" size=\"1 1 1\"/>",
            &["(line 3)", "mesh=\"m\"", "fitted to a mesh"][..],
        ),
        (
            "<geom type=\"box\" size=\"1 1 x\"/>",
            &["(line 3)", "size=\"1 1 x\"", "'x' is not a number"][..],
        ),
        (
            "<geom type=\"capsule\" xyaxes=\"1 0 0 2 0 0\" size=\"1 2\"/>",
            &["(line 3)", "xyaxes=", "parallel"][..],
        ),
        (
            "<replicate count=\"2\"><geom type=\"box\" size=\"1 1 1\"/></replicate>",
            &["<replicate> (line 3)", "not supported"][..],
        ),
    ] {
        let model = format!(
            "<mujoco>\n<worldbody><body name=\"peg\">\n{body}\n</body></worldbody>\n</mujoco>\n"
        );
        std::fs::write(d.join("env.xml"), model).unwrap();
        let out = pegtwin(&[
            "assembly",
            "mjcf",
            d.join("env.xml").to_str().unwrap(),
            "--body",
            "peg",
        ]);
        assert_eq!(out.status.code(), Some(2), "{body}");
        let err = stderr(&out);
        for e in expected {
            assert!(
                err.contains(e) && err.contains("env.xml"),
                "{body}: {e}: {err}"
            );
        }
    }
}

/// `decompose = "coacd"` comes with one mesh file and the pair's design clearance.
#[test]
fn decompose_entries_are_checked_by_field() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    for (text, expected) in [
        (
            "name = \"p\"\n[peg]\nmesh = \"pin.stl\"\nunits = \"mm\"\ndecompose = \"coacd\"\n[hole]\nmesh = \"h.stl\"\nunits = \"mm\"\n",
            "clearance_mm: decompose = \"coacd\" needs",
        ),
        (
            "name = \"p\"\nclearance_mm = 0.5\n[peg]\nmesh = \"parts/\"\nunits = \"mm\"\ndecompose = \"coacd\"\n[hole]\nmesh = \"h.stl\"\nunits = \"mm\"\n",
            "peg.decompose: only for mesh = \"ONE FILE",
        ),
        (
            "name = \"p\"\nclearance_mm = 0.5\n[peg]\nmesh = \"pin.stl\"\nunits = \"mm\"\n[hole]\nmesh = \"h.stl\"\nunits = \"mm\"\n",
            "clearance_mm = 0.5: only for built-in parts and decompose",
        ),
        (
            "name = \"p\"\nclearance_mm = 0.5\n[peg]\nmesh = \"pin.stl\"\nunits = \"mm\"\ndecompose = \"vhacd\"\n[hole]\nmesh = \"h.stl\"\nunits = \"mm\"\n",
            "line 6: unknown variant `vhacd`, expected `coacd`",
        ),
    ] {
        let file = d.join("a.toml");
        std::fs::write(&file, text).unwrap();
        let out = pegtwin(&["assembly", "check", file.to_str().unwrap()]);
        assert_eq!(out.status.code(), Some(2), "{text}");
        let err = stderr(&out);
        assert!(
            err.contains(expected) && err.contains("a.toml"),
            "{expected}: {err}"
        );
    }
}
