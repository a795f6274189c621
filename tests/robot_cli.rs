//! `pegtwin robot ...` from the command line: output formats, the stiffness check, bad input.

mod common;
use common::{pegtwin, stderr};

fn json(args: &[&str]) -> serde_json::Value {
    let out = pegtwin(args);
    assert!(out.status.success(), "{}", stderr(&out));
    serde_json::from_slice(&out.stdout).unwrap()
}

#[test]
fn info_lists_joints_limits_and_the_total_mass() {
    let v = json(&["robot", "info", "--json"]);
    assert_eq!(v["dof"], 7);
    assert!((v["total_mass_kg"].as_f64().unwrap() - 29.9).abs() < 1e-6);
    assert_eq!(v["joints"][6]["effort_limit"], 40.0);
    assert_eq!(v["flange"], "iiwa_link_ee_kuka");
}

#[test]
fn fk_prints_the_flange_pose_in_m_and_rad() {
    let v = json(&["robot", "fk", "--q-deg", "0,45,0,-90,0,45,0", "--json"]);
    let xyz: Vec<f64> = v["xyz_m"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect();
    assert!(
        (xyz[0] - 0.57983).abs() < 5e-6 && xyz[1].abs() < 1e-9 && (xyz[2] - 0.24814).abs() < 5e-6,
        "{xyz:?}"
    );
    assert!(
        (v["rotation"][2][2].as_f64().unwrap() + 1.0).abs() < 1e-9,
        "tool points down"
    );
}

#[test]
fn gravity_prints_g_of_q_and_the_iiwa7_loads_too() {
    let v = json(&[
        "robot",
        "gravity",
        "--q",
        "0,0.7853981633974483,0,-1.5707963267948966,0,0,0",
        "--json",
    ]);
    assert!((v["gravity_torques_nm"][1].as_f64().unwrap() + 49.3).abs() < 0.05);
    let urdf = concat!(env!("CARGO_MANIFEST_DIR"), "/assets/iiwa7/iiwa7.urdf");
    let v = json(&["robot", "info", "--urdf", urdf, "--json"]);
    assert_eq!(v["name"], "iiwa7");
}

#[test]
fn stiffness_reports_every_axis_within_5_percent() {
    let v = json(&["robot", "stiffness", "--json"]);
    assert_eq!(v["passed"], true);
    assert_eq!(v["axes"].as_array().unwrap().len(), 6);
}

#[test]
fn bad_input_exits_2_naming_what_is_wrong() {
    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("bad.urdf");
    std::fs::write(&bad, "<robot name=\"r\">\n<link name=\"a\">\n</robot>\n").unwrap();
    let cases: Vec<(Vec<String>, &str)> = vec![
        (
            vec!["robot".into(), "fk".into(), "--q".into(), "0,0,0".into()],
            "3 values",
        ),
        (
            vec![
                "robot".into(),
                "fk".into(),
                "--q".into(),
                "0,2.5,0,0,0,0,0".into(),
            ],
            "iiwa_joint_2",
        ),
        (
            vec![
                "robot".into(),
                "gravity".into(),
                "--q-deg".into(),
                "0,x,0,0,0,0,0".into(),
            ],
            "`x`",
        ),
        (
            vec![
                "robot".into(),
                "stiffness".into(),
                "--stiffness-n-per-m".into(),
                "6000".into(),
            ],
            "[0, 5000]",
        ),
        (
            vec![
                "robot".into(),
                "stiffness".into(),
                "--damping-ratio".into(),
                "1.5".into(),
            ],
            "damping ratio",
        ),
        (
            vec![
                "robot".into(),
                "info".into(),
                "--urdf".into(),
                bad.display().to_string(),
            ],
            "bad.urdf",
        ),
        (
            vec![
                "robot".into(),
                "info".into(),
                "--urdf".into(),
                "/nonexistent/r.urdf".into(),
            ],
            "cannot read",
        ),
    ];
    for (args, needle) in cases {
        let refs: Vec<&str> = args.iter().map(String::as_str).collect();
        let out = pegtwin(&refs);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {}", stderr(&out));
        assert!(stderr(&out).contains(needle), "{args:?}: {}", stderr(&out));
        assert!(out.stdout.is_empty(), "{args:?} printed output");
    }
}
