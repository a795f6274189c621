//! Issue 18's hostile inputs as regression tests: each is refused with exit code 2 and a message
//! naming the value and what was expected, before anything is written.

use std::path::Path;

mod common;
use common::{pegtwin, stderr};

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

fn refused(args: &[&str], expected: &str) {
    let o = pegtwin(args);
    assert_eq!(o.status.code(), Some(2), "{args:?}: {}", stderr(&o));
    assert!(
        stderr(&o).contains(expected),
        "{args:?}: expected '{expected}' in: {}",
        stderr(&o)
    );
}

const IIWA14: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/assets/iiwa14/iiwa14.urdf");

#[test]
fn broken_urdfs_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(IIWA14).unwrap();
    let deep = format!(
        "<robot name=\"r\">{}{}</robot>",
        "<a>".repeat(50_000),
        "</a>".repeat(50_000)
    );
    let cases = [
        (
            "self_parent",
            text.replacen(
                "<parent link=\"iiwa_link_2\"/>",
                "<parent link=\"iiwa_link_3\"/>",
                1,
            ),
            "parent and child are the same link",
        ),
        (
            "duplicate_joint",
            text.replacen("\"iiwa_joint_3\"", "\"iiwa_joint_2\"", 1),
            "joint names must be unique",
        ),
        (
            "zero_mass",
            text.replace("<mass value=\"", "<mass value=\"0\" was=\""),
            "needs a mass > 0 kg",
        ),
        (
            "huge_inertia",
            text.replacen("ixx=\"", "ixx=\"1e308\" was=\"", 1),
            "expected 1 number in [-10000, 10000]",
        ),
        ("deep", deep, "nest deeper than 32 levels"),
    ];
    for (name, urdf, expected) in cases {
        let path = dir.path().join(format!("{name}.urdf"));
        std::fs::write(&path, urdf).unwrap();
        refused(&["robot", "info", "--urdf", s(&path)], expected);
    }
}

const SCENARIO: &str = r#"
name = "t"
trials = 1
geometries = ["cross"]
clearances_mm = [1.0]
t_obs_s = [0.5]
methods = ["manifold", "direct"]
direct_t_obs_s = 0.5
"#;

#[test]
fn implausible_scenarios_are_refused_before_anything_is_written() {
    let dir = tempfile::tempdir().unwrap();
    let cases = [
        (
            format!("{SCENARIO}[gains.insert]\nadditional_force = [1e308, 0, 0, 0, 0, 0]\n"),
            "additional force x 1e308 N is outside the accepted range [-500, 500]",
        ),
        (format!("success_mm = 0\n{SCENARIO}"), "success_mm = 0.0"),
        (SCENARIO.replace("[0.5]", "[1e-9]"), "t_obs_s = 1e-9"),
        (
            SCENARIO.replace("[\"cross\"]", "[\"cross\", \"cross\"]"),
            "\"cross\" is listed twice",
        ),
        (
            format!("{SCENARIO}[physics]\ndt_s = 0.002\n"),
            "physics.dt_s = 0.002",
        ),
        (
            format!("{SCENARIO}[physics]\ndt_s = 0.0007\n"),
            "must be a whole number of physics steps",
        ),
        (
            format!("{SCENARIO}[physics]\ncontact_frequency_hz = 1e-6\n"),
            "physics.contact_frequency_hz = 1e-6",
        ),
        (
            format!("{SCENARIO}[sensors]\ntorque_noise_nm = 1e308\n"),
            "sensor torque_noise_nm is 1e308",
        ),
    ];
    for (i, (text, expected)) in cases.iter().enumerate() {
        let path = dir.path().join(format!("s{i}.toml"));
        std::fs::write(&path, text).unwrap();
        let out = dir.path().join(format!("out{i}"));
        refused(&["campaign", s(&path), "--out", s(&out)], expected);
        assert!(!out.exists(), "case {i} wrote {}", out.display());
    }
}

#[test]
fn a_bad_cache_folder_or_thread_count_leaves_no_output() {
    let dir = tempfile::tempdir().unwrap();
    let scenario = dir.path().join("s.toml");
    std::fs::write(&scenario, SCENARIO).unwrap();
    let file = dir.path().join("a_file");
    std::fs::write(&file, "").unwrap();
    let out = dir.path().join("out");
    let args = ["campaign", s(&scenario), "--out", s(&out)];
    refused(
        &[&args[..], &["--cache-dir", s(&file)]].concat(),
        "cannot create the cache folder",
    );
    refused(
        &[&args[..], &["--threads", "100000"]].concat(),
        "--threads 100000: expected 1 to 512",
    );
    assert!(!out.exists());
}

#[test]
fn trial_paths_are_checked_before_the_run() {
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("poses.csv");
    std::fs::write(&csv, "x,y,z,roll,pitch,yaw\n").unwrap();
    let trial = ["trial", "--geometry", "cross", "--clearance-mm", "0.5"];
    refused(
        &[&trial[..], &["--manifold", s(&csv)]].concat(),
        "pegtwin manifold import",
    );
    // A 600 s observation would take minutes: the missing folder is found first.
    let t0 = std::time::Instant::now();
    let trace = dir.path().join("missing").join("t.csv");
    refused(
        &[
            &trial[..],
            &["--method", "direct", "--t-obs", "600", "--trace", s(&trace)],
        ]
        .concat(),
        "cannot write",
    );
    assert!(t0.elapsed().as_secs() < 30);
}

#[test]
fn every_builtin_builds_across_the_documented_clearance_range() {
    let dir = tempfile::tempdir().unwrap();
    for g in ["cross", "extrusion", "plug3", "key", "gear"] {
        for c in ["0.01", "0.02", "2", "3", "5"] {
            let o = pegtwin(&[
                "geometry",
                "export",
                g,
                "--clearance-mm",
                c,
                "--out",
                s(dir.path()),
            ]);
            assert!(o.status.success(), "{g} at {c} mm: {}", stderr(&o));
        }
        refused(
            &[
                "geometry",
                "export",
                g,
                "--clearance-mm",
                "0.009",
                "--out",
                s(dir.path()),
            ],
            "expected 0.01 to 5 mm",
        );
    }
}

#[test]
fn degenerate_observations_are_refused_not_registered() {
    let dir = tempfile::tempdir().unwrap();
    let m = dir.path().join("cross.manifold");
    let obs = dir.path().join("obs.csv");
    let o = pegtwin(&[
        "manifold",
        "synth",
        "--shape",
        "cross",
        "--clearance-mm",
        "0.5",
        "--points",
        "5000",
        "--out",
        s(&m),
        "--observations",
        s(&obs),
        "--observation-count",
        "100",
        "--true-pose",
        "0.55,0,0.1,0,0,0",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = std::fs::read_to_string(&obs).unwrap();
    let mut lines = text.lines();
    let header = lines.next().unwrap();
    let rows: Vec<Vec<f64>> = lines
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect();
    let write = |name: &str, rows: &[Vec<f64>]| {
        let path = dir.path().join(name);
        let body: Vec<String> = rows
            .iter()
            .map(|r| r.iter().map(f64::to_string).collect::<Vec<_>>().join(","))
            .collect();
        std::fs::write(&path, format!("{header}\n{}\n", body.join("\n"))).unwrap();
        path
    };
    let repeated = write("repeated.csv", &vec![rows[0].clone(); 100]);
    let line: Vec<Vec<f64>> = (0..100)
        .map(|i| {
            let mut r = rows[0].clone();
            r[0] += i as f64 * 1e-4;
            r
        })
        .collect();
    let line = write("line.csv", &line);
    // Millimetres about the nominal hole, read as metres.
    let mm: Vec<Vec<f64>> = rows
        .iter()
        .map(|r| {
            let mut r = r.clone();
            r[0] = (r[0] - 0.55) * 1e3;
            r[2] = (r[2] - 0.1) * 1e3;
            r
        })
        .collect();
    let mm = write("mm.csv", &mm);
    for (path, expected) in [
        (repeated, "only 1 distinct observations"),
        (line, "lie on one line in pose space"),
        (mm, "were these millimetres?"),
    ] {
        refused(
            &[
                "register",
                "--manifold",
                s(&m),
                "--observations",
                s(&path),
                "--init",
                "0.55,0,0.1,0,0,0",
            ],
            expected,
        );
    }
}

#[test]
fn degenerate_manifold_csvs_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let seed =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("fuzz/seeds/pose_csv/square60_normals.csv");
    let text = std::fs::read_to_string(&seed).unwrap();
    let mut lines = text.lines();
    let header = lines.next().unwrap();
    let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    let write = |name: &str, header: &str, rows: Vec<String>| {
        let path = dir.path().join(name);
        std::fs::write(&path, format!("{header}\n{}\n", rows.join("\n"))).unwrap();
        path
    };
    let with_normal = |n: &str| -> Vec<String> {
        rows.iter()
            .map(|r| format!("{},{}", r[..6].join(","), [n; 6].join(",")))
            .collect()
    };
    let poses_header = &header[..header.find(",nx").unwrap()];
    let cases = [
        (
            write("nan.csv", header, with_normal("nan")),
            "expected a finite number",
        ),
        (
            write("zero.csv", header, with_normal("0")),
            "expected a unit vector",
        ),
        (
            write("same.csv", poses_header, vec!["0,0,0,0,0,0".into(); 60]),
            "only 1 distinct ones",
        ),
        (
            write(
                "huge.csv",
                poses_header,
                rows.iter()
                    .map(|r| format!("1e300,{}", r[1..6].join(",")))
                    .collect(),
            ),
            "x = 1e300 m",
        ),
    ];
    for (path, expected) in cases {
        let out = dir.path().join("out.manifold");
        refused(
            &["manifold", "import", s(&path), "--out", s(&out)],
            expected,
        );
        assert!(!out.exists());
    }
    let poses = write(
        "poses.csv",
        poses_header,
        rows.iter().map(|r| r[..6].join(",")).collect(),
    );
    for (weight, expected) in [
        ("--mm-per-deg=1e308", "mm_per_deg 1e308"),
        ("--mm-per-deg=-1", "expected a positive number"),
    ] {
        let out = dir.path().join("out.manifold");
        let args = ["manifold", "import", s(&poses), "--out", s(&out), weight];
        let o = pegtwin(&args);
        assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
        assert!(stderr(&o).contains(expected), "{}", stderr(&o));
    }
}

#[test]
fn a_mesh_cavity_deeper_than_the_hole_mesh_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let o = pegtwin(&[
        "geometry",
        "export",
        "cross",
        "--clearance-mm",
        "1",
        "--out",
        s(dir.path()),
        "--convex-parts",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let (peg, hole) = (dir.path().join("peg_parts"), dir.path().join("hole_parts"));
    refused(
        &[
            "validate",
            "--peg-mesh",
            s(&peg),
            "--hole-mesh",
            s(&hole),
            "--mesh-units",
            "mm",
            "--clearance-mm",
            "1",
            "--depth-mm",
            "1000",
        ],
        "cavity depth 1000 mm: expected more than 0 and at most the 40.000 mm",
    );
}
