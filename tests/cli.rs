//! The command line: outputs, files, exit codes and error messages.

mod common;
use common::{pegtwin, stderr};

#[test]
fn geometry_list_names_the_five_built_ins() {
    let o = pegtwin(&["geometry", "list", "--json"]);
    assert!(o.status.success());
    let list: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let names: Vec<&str> = list
        .as_array()
        .unwrap()
        .iter()
        .map(|g| g["name"].as_str().unwrap())
        .collect();
    assert_eq!(names, ["cross", "extrusion", "plug3", "key", "gear"]);
}

#[test]
fn geometry_export_writes_both_stls() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("gear");
    let o = pegtwin(&[
        "geometry",
        "export",
        "gear",
        "--clearance-mm",
        "0.3",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(out.join("peg.stl").is_file() && out.join("hole.stl").is_file());
}

#[test]
fn bad_values_exit_2_and_say_what_was_expected() {
    let o = pegtwin(&["validate", "--geometry", "hexagon", "--clearance-mm", "0.1"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("hexagon") && stderr(&o).contains("cross"));
    for bad in ["0", "-0.2", "5.5"] {
        let o = pegtwin(&[
            "geometry",
            "export",
            "cross",
            "--clearance-mm",
            bad,
            "--out",
            "x",
        ]);
        assert_eq!(o.status.code(), Some(2), "{bad}");
        assert!(stderr(&o).contains("clearance"), "{}", stderr(&o));
    }
}

#[test]
fn a_garbage_mesh_exits_2_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let peg = dir.path().join("peg.stl");
    std::fs::write(&peg, b"garbage").unwrap();
    let o = pegtwin(&[
        "validate",
        "--peg-mesh",
        peg.to_str().unwrap(),
        "--hole-mesh",
        peg.to_str().unwrap(),
        "--depth-mm",
        "30",
        "--clearance-mm",
        "0.2",
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("peg.stl"), "{}", stderr(&o));
}

#[test]
fn bench_times_a_scenarios_manifolds_and_campaign_cached_and_cold() {
    let tmp = tempfile::tempdir().unwrap();
    let scenario = tmp.path().join("s.toml");
    std::fs::write(
        &scenario,
        "name = \"tiny\"\nseed = 7\ntrials = 2\ngeometries = [\"cross\"]\nclearances_mm = [0.5]\n\
         t_obs_s = [3.0]\nmethods = [\"manifold\", \"direct\"]\ndirect_t_obs_s = 3.0\n\
         [manifold]\npoints = 3000\nepisodes = 3\nepisode_s = 5.0\n",
    )
    .unwrap();
    let o = pegtwin(&[
        "bench",
        "--arm-steps",
        "10",
        "--env-steps",
        "10",
        "--json",
        "--campaign",
        scenario.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let rows: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let rows = rows.as_array().unwrap();
    let names: Vec<&str> = rows.iter().map(|r| r["name"].as_str().unwrap()).collect();
    // The campaign's rows follow the pieces' rows.
    let first = names.len() - 4;
    assert_eq!(
        names[first..],
        [
            "manifold_robot_cross_0.5mm",
            "manifold_geometric_cross_0.5mm",
            "campaign_cached",
            "campaign_cold"
        ]
    );
    assert!(
        (rows[first + 1]["what"].as_str().unwrap()).contains("x faster than the robot's"),
        "{}",
        rows[first + 1]
    );
    for r in &rows[first..] {
        assert!(r["value"].as_f64().unwrap() > 0.0, "{r}");
        let geometric = r["name"].as_str().unwrap().contains("geometric");
        assert_eq!(r["real_time_factor"].is_null(), geometric, "{r}");
    }
    assert!(
        rows[first + 2]["what"]
            .as_str()
            .unwrap()
            .contains("(4 trials)")
    );
    let o = pegtwin(&["bench", "--campaign", "missing.toml"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("missing.toml"), "{}", stderr(&o));
}

#[test]
fn bench_measures_every_piece_and_refuses_zero_steps() {
    let o = pegtwin(&["bench", "--arm-steps", "20", "--env-steps", "40", "--json"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let rows: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let names: Vec<&str> = rows
        .as_array()
        .unwrap()
        .iter()
        .map(|r| r["name"].as_str().unwrap())
        .collect();
    assert_eq!(
        names,
        [
            "arm_cross",
            "arm_gear",
            "arm_cross_rapier",
            "arm_gear_rapier",
            "sampling_episode",
            "trial_direct",
            "env_random_policy",
            "registration"
        ]
    );
    for r in rows.as_array().unwrap() {
        let v = r["value"].as_f64().unwrap();
        assert!(v.is_finite() && v > 0.0, "{r}");
    }
    assert!(rows[0]["real_time_factor"].as_f64().unwrap() > 0.0);
    let o = pegtwin(&["bench", "--arm-steps", "0"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("--arm-steps 0"), "{}", stderr(&o));
}
