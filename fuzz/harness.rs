//! The properties fuzzed on every parser of user input (issue 18): whatever the bytes, the parser
//! returns an error or values that are finite and in range, and the first stage that uses them
//! does not panic. Shared by the libFuzzer targets in `fuzz_targets/` (nightly, `cargo fuzz`) and
//! the stable mutation test `tests/fuzz_properties.rs` (CI).
//!
//! The loaders read files, as the command line does, so each input goes through a scratch file
//! of this process and thread with the extension the loader dispatches on.

use pegtwin::campaign::records::read_records;
use pegtwin::campaign::scenario::Scenario;
use pegtwin::method::manifold::{Manifold, ManifoldMeta, NORMAL_LENGTH_TOLERANCE, UNITS, file};
use pegtwin::method::register::{RegistrationConfig, register};
use pegtwin::pose::{Pose6, PoseMetric};
use pegtwin::twin::geometry::mesh::{MeshUnits, read_mesh};
use pegtwin::twin::robot::urdf;
use std::path::PathBuf;

/// A fuzzed property: panics when the input breaks it.
pub type Property = fn(&[u8]);

/// The parsers under test, by target name.
pub const TARGETS: &[(&str, Property)] = &[
    ("scenario", scenario),
    ("manifold", manifold),
    ("pose_csv", pose_csv),
    ("stl", stl),
    ("obj", obj),
    ("urdf", urdf),
    ("records", records),
];

/// Writes `data` to this thread's scratch file with extension `ext` (in `$TMPDIR`; a memory
/// file system there, such as /dev/shm, makes the loop several times faster).
fn scratch(ext: &str, data: &[u8]) -> PathBuf {
    thread_local! {
        static DIR: PathBuf = {
            let thread = format!("{:?}", std::thread::current().id());
            let name: String = thread.chars().filter(char::is_ascii_alphanumeric).collect();
            let dir = std::env::temp_dir()
                .join(format!("pegtwin-fuzz-{}-{name}", std::process::id()));
            std::fs::create_dir_all(&dir).expect("scratch folder");
            dir
        };
    }
    let path = DIR.with(|dir| dir.join(format!("input.{ext}")));
    std::fs::write(&path, data).expect("scratch file");
    path
}

/// A scenario file: a parsed scenario is valid, has cells, and every cell's trial is valid.
pub fn scenario(data: &[u8]) {
    let Ok(s) = Scenario::load(&scratch("toml", data)) else {
        return;
    };
    s.ensure_valid().expect("a parsed scenario is valid");
    let cells = s.cells();
    assert!(!cells.is_empty(), "a parsed scenario has cells");
    for cell in &cells {
        s.trial_config(cell)
            .ensure_valid()
            .expect("cells are valid");
    }
    s.fingerprint();
}

/// A binary manifold file.
pub fn manifold(data: &[u8]) {
    if let Ok(m) = file::load(&scratch("pmf", data)) {
        check_manifold(&m);
    }
}

/// A CSV of contact poses (with or without normals), imported as a manifold.
pub fn pose_csv(data: &[u8]) {
    let meta = ManifoldMeta {
        geometry: "fuzz".into(),
        clearance_m: None,
        units: UNITS.into(),
        metric: PoseMetric::default(),
        normal_k: 12,
        source: "fuzz".into(),
        seed: None,
    };
    if let Ok(m) = file::load_any(&scratch("csv", data), meta) {
        check_manifold(&m);
    }
}

/// A loaded manifold holds plausible poses and unit normals, and registering a few of its own
/// poses against it returns an estimate or an error.
fn check_manifold(m: &Manifold) {
    m.meta
        .metric
        .ensure_valid()
        .expect("a loaded metric is valid");
    assert_eq!(m.points.len(), m.normals.len());
    for (p, n) in m.points.iter().zip(&m.normals) {
        p.ensure_plausible("pose")
            .expect("loaded poses are plausible");
        let norm = n.iter().map(|v| v * v).sum::<f64>().sqrt();
        assert!(
            (norm - 1.0).abs() <= NORMAL_LENGTH_TOLERANCE,
            "normal of length {norm}"
        );
    }
    let observations: Vec<Pose6> = m.points.iter().take(40).cloned().collect();
    let cfg = RegistrationConfig {
        restarts: 2,
        iterations: 3,
        ..RegistrationConfig::default()
    };
    if let Ok(r) = register(m, &observations, &Pose6([0.0; 6]), &cfg) {
        assert!(
            r.estimate.0.iter().all(|v| v.is_finite()),
            "finite estimate"
        );
    }
}

/// An STL mesh, read in both unit conventions.
pub fn stl(data: &[u8]) {
    check_mesh(&scratch("stl", data));
}

/// An OBJ mesh, read in both unit conventions.
pub fn obj(data: &[u8]) {
    check_mesh(&scratch("obj", data));
}

fn check_mesh(path: &std::path::Path) {
    for units in [MeshUnits::Mm, MeshUnits::M] {
        let Ok(soup) = read_mesh(path, units) else {
            continue;
        };
        assert!(!soup.triangles.is_empty());
        for v in &soup.vertices {
            assert!(
                v.coords
                    .iter()
                    .all(|c| c.abs() <= pegtwin::pose::MAX_COORDINATE_M)
            );
        }
        let n = soup.vertices.len();
        assert!(soup.triangles.iter().flatten().all(|&i| (i as usize) < n));
    }
}

/// A robot URDF: a loaded model has joints and finite forward kinematics at its zero
/// configuration (clamped into the joint limits).
pub fn urdf(data: &[u8]) {
    let Ok(loaded) = urdf::load(&scratch("urdf", data), &[]) else {
        return;
    };
    let model = loaded.model;
    assert!(!model.joints.is_empty());
    let q: Vec<f64> = model
        .joints
        .iter()
        .map(|j| 0.0f64.clamp(j.lower, j.upper))
        .collect();
    let pose = model.flange_pose(&q);
    assert!(pose.translation.vector.iter().all(|v| v.is_finite()));
}

/// A `trials.jsonl` of a results folder (as `merge`, `check` and `--resume` read it): every record
/// read serialises again.
pub fn records(data: &[u8]) {
    if let Ok(records) = read_records(&scratch("jsonl", data), false) {
        for r in &records {
            serde_json::to_string(r).expect("a record serialises");
        }
    }
}
