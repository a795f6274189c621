//! Manifold files (binary and CSV) and `pegtwin manifold` / `pegtwin register` from the command
//! line: round trips, the estimate, and clear errors on bad input.

use std::path::Path;

mod common;
use common::{pegtwin, stderr};

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// A small synthetic cross manifold and 300 observations through a known hole pose.
fn synth(dir: &Path) -> (std::path::PathBuf, std::path::PathBuf) {
    let m = dir.join("cross.manifold");
    let obs = dir.join("obs.csv");
    let o = pegtwin(&[
        "manifold",
        "synth",
        "--shape",
        "cross",
        "--clearance-mm",
        "0.5",
        "--points",
        "20000",
        "--out",
        s(&m),
        "--observations",
        s(&obs),
        "--observation-count",
        "300",
        "--true-pose",
        "0.6,0.05,0.2,0,0,0.3",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    (m, obs)
}

#[test]
fn register_recovers_the_synthetic_hole_pose() {
    let dir = tempfile::tempdir().unwrap();
    let (m, obs) = synth(dir.path());
    let o = pegtwin(&[
        "register",
        "--manifold",
        s(&m),
        "--observations",
        s(&obs),
        "--init",
        "0.603,0.048,0.203,0.05,-0.04,0.35",
        "--restarts",
        "4",
        "--json",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let est: Vec<f64> = v["estimate_base_T_hole"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect();
    assert!(
        (est[0] - 0.6).abs() < 1e-4 && (est[1] - 0.05).abs() < 1e-4,
        "{est:?}"
    );
    assert!((est[5] - 0.3).abs() < 0.1f64.to_radians(), "{est:?}");
    let restarts = v["result"]["restarts"].as_array().unwrap();
    assert_eq!(restarts.len(), 4);
    assert!(restarts[0]["iterations"].as_u64().unwrap() >= 1);
    assert!(v["result"]["time"]["total_s"].as_f64().unwrap() > 0.0);
}

#[test]
fn csv_round_trip_keeps_poses_and_normals_bit_for_bit() {
    let dir = tempfile::tempdir().unwrap();
    let (m, _) = synth(dir.path());
    let csv = dir.path().join("m.csv");
    let back = dir.path().join("back.manifold");
    assert!(
        pegtwin(&["manifold", "export", s(&m), "--csv", s(&csv)])
            .status
            .success()
    );
    let o = pegtwin(&["manifold", "import", s(&csv), "--out", s(&back)]);
    assert!(o.status.success(), "{}", stderr(&o));
    let a = pegtwin::method::manifold::file::load(&m).unwrap();
    let b = pegtwin::method::manifold::file::load(&back).unwrap();
    assert_eq!(a.points, b.points);
    assert_eq!(a.normals, b.normals);
    // A CSV without normals gets them computed: the same as the generator's.
    let text = std::fs::read_to_string(&csv).unwrap();
    let poses_only: String = text
        .lines()
        .map(|l| l.split(',').take(6).collect::<Vec<_>>().join(","))
        .collect::<Vec<_>>()
        .join("\n");
    let csv6 = dir.path().join("poses.csv");
    std::fs::write(&csv6, poses_only).unwrap();
    let back6 = dir.path().join("back6.manifold");
    let o = pegtwin(&["manifold", "import", s(&csv6), "--out", s(&back6)]);
    assert!(o.status.success(), "{}", stderr(&o));
    let c = pegtwin::method::manifold::file::load(&back6).unwrap();
    assert_eq!(a.normals, c.normals);
}

#[test]
fn corrupt_or_foreign_manifold_files_are_named_errors() {
    let dir = tempfile::tempdir().unwrap();
    let (m, obs) = synth(dir.path());
    let bytes = std::fs::read(&m).unwrap();
    let flipped = dir.path().join("flipped.manifold");
    let mut b = bytes.clone();
    let mid = b.len() / 2;
    b[mid] ^= 0x40;
    std::fs::write(&flipped, &b).unwrap();
    let newer = dir.path().join("newer.manifold");
    let mut b = bytes.clone();
    b[16] = 9;
    std::fs::write(&newer, &b).unwrap();
    let cut = dir.path().join("cut.manifold");
    std::fs::write(&cut, &bytes[..bytes.len() / 3]).unwrap();
    for (file, expected) in [
        (&flipped, "checksum mismatch"),
        (&newer, "format version 9"),
        (&cut, "checksum"),
        (&obs, "not a pegtwin manifold"),
    ] {
        let o = pegtwin(&["manifold", "info", s(file)]);
        assert_eq!(o.status.code(), Some(2), "{}", file.display());
        let e = stderr(&o);
        assert!(e.contains(expected) && e.contains(s(file)), "{e}");
    }
}

#[test]
fn bad_csv_and_flags_are_clear_errors_with_exit_2() {
    let dir = tempfile::tempdir().unwrap();
    let (m, _) = synth(dir.path());
    let write = |name: &str, text: &str| {
        let p = dir.path().join(name);
        std::fs::write(&p, text).unwrap();
        p
    };
    let header = write("header.csv", "x,y,z,rx,ry,rz\n0,0,0,0,0,0\n");
    let nan = write(
        "nan.csv",
        "x,y,z,roll,pitch,yaw\n0,0,0,0,0,0\n0,0,NaN,0,0,0\n",
    );
    let text = write("text.csv", "x,y,z,roll,pitch,yaw\n0,0,0,0,zero,0\n");
    let few = write(
        "few.csv",
        "x,y,z,roll,pitch,yaw\n0,0,0,0,0,0\n0,0,0,0,0,0\n",
    );
    let short = write("short.csv", "x,y,z,roll,pitch,yaw\n0,0,0,0,0\n");
    let cases: [(&Path, &str); 5] = [
        (&header, "line 1: header is `x,y,z,rx,ry,rz`"),
        (&nan, "line 3: z = NaN"),
        (&text, "line 2: pitch = `zero` is not a number"),
        (&few, "fewer than the k = 12"),
        (&short, "line 2"),
    ];
    for (obs, expected) in cases {
        let o = pegtwin(&[
            "register",
            "--manifold",
            s(&m),
            "--observations",
            s(obs),
            "--init",
            "0.6,0.05,0.2,0,0,0.3",
        ]);
        assert_eq!(o.status.code(), Some(2), "{}", obs.display());
        let e = stderr(&o);
        assert!(e.contains(expected) && e.contains(s(obs)), "{e}");
    }
    // A manifold CSV with too few rows for its normals.
    let o = pegtwin(&[
        "manifold",
        "import",
        s(&few),
        "--out",
        s(&dir.path().join("x")),
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("fewer than the 12 neighbours"),
        "{}",
        stderr(&o)
    );
    assert!(!dir.path().join("x").exists(), "no half-written output");
    for (flag, value, expected) in [
        ("--init", "0.6,0.05,0.2,0,0", "six comma-separated numbers"),
        ("--init", "0.6,0.05,0.2,0,0,yaw", "yaw = `yaw`"),
        ("--restarts", "0", "restarts"),
        ("--k", "3", "7 to 1000"),
    ] {
        let mut args = vec!["register", "--manifold", s(&m), "--observations", s(&few)];
        if flag != "--init" {
            args.extend(["--init", "0.6,0.05,0.2,0,0,0.3"]);
        }
        args.extend([flag, value]);
        let o = pegtwin(&args);
        assert_eq!(o.status.code(), Some(2), "{flag} {value}");
        assert!(stderr(&o).contains(expected), "{}", stderr(&o));
    }
}

#[test]
fn manifold_build_samples_contacts_inside_the_hole_deterministically() {
    let dir = tempfile::tempdir().unwrap();
    let build = |name: &str, threads: &str| {
        let out = dir.path().join(name);
        let o = std::process::Command::new(env!("CARGO_BIN_EXE_pegtwin"))
            .args([
                "manifold",
                "build",
                "--geometry",
                "cross",
                "--clearance-mm",
                "0.5",
                "--episodes",
                "2",
            ])
            .args([
                "--episode-s",
                "3",
                "--points",
                "400",
                "--seed",
                "4",
                "--quiet",
                "--out",
            ])
            .arg(&out)
            .env("RAYON_NUM_THREADS", threads)
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        out
    };
    let one = build("one.manifold", "1");
    let two = build("two.manifold", "2");
    assert_eq!(
        std::fs::read(&one).unwrap(),
        std::fs::read(&two).unwrap(),
        "1 vs 2 threads"
    );
    let info = pegtwin(&["manifold", "info", one.to_str().unwrap(), "--json"]);
    let v: serde_json::Value = serde_json::from_slice(&info.stdout).unwrap();
    assert_eq!(v["points"], 400);
    assert_eq!(v["meta"]["geometry"], "cross");
    assert!((v["meta"]["clearance_m"].as_f64().unwrap() - 0.5e-3).abs() < 1e-12);
    let source = v["meta"]["source"].as_str().unwrap();
    assert!(
        source.contains("from 2 episodes (0 faulted, dropped)"),
        "the build's faults are kept in its metadata: {source}"
    );
    let r = &v["ranges_m_rad"];
    for axis in 0..2 {
        for end in 0..2 {
            assert!(
                r[axis][end].as_f64().unwrap().abs() < 0.5e-3,
                "x, y within the hole's play: {r}"
            );
        }
    }
    assert!(r[2][1].as_f64().unwrap() < 0.0, "tip below the mouth: {r}");
}

#[test]
fn manifold_build_rejects_bad_input() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("m.manifold");
    let out = out.to_str().unwrap();
    for (args, needle) in [
        (
            vec!["--geometry", "banana", "--clearance-mm", "0.5"],
            "banana",
        ),
        (
            vec!["--geometry", "cross", "--clearance-mm", "-1"],
            "clearance",
        ),
        (
            vec![
                "--geometry",
                "cross",
                "--clearance-mm",
                "0.5",
                "--points",
                "5",
            ],
            "--points 5",
        ),
        (
            vec![
                "--geometry",
                "cross",
                "--clearance-mm",
                "0.5",
                "--episodes",
                "0",
            ],
            "episodes",
        ),
        (
            vec![
                "--geometry",
                "cross",
                "--clearance-mm",
                "0.5",
                "--sampler",
                "geometric",
                "--episode-s",
                "4",
            ],
            "the geometric sampler has none: leave them out, or use --sampler robot",
        ),
        (
            vec![
                "--geometry",
                "cross",
                "--clearance-mm",
                "0.5",
                "--episodes",
                "1",
                "--episode-s",
                "0.5",
                "--points",
                "50000",
            ],
            "fewer than the 50000 requested",
        ),
    ] {
        let mut all = vec!["manifold", "build", "--quiet", "--out", out];
        all.extend(args);
        let o = pegtwin(&all);
        assert_eq!(o.status.code(), Some(2), "{all:?}");
        assert!(stderr(&o).contains(needle), "{all:?}: {}", stderr(&o));
        assert!(!std::path::Path::new(out).exists(), "no output on error");
    }
}

/// Values near the end of f64 used to panic in the nearest-neighbour search (issue 18); they are
/// refused up front, naming what is implausible.
#[test]
fn implausible_values_are_refused_not_panicked_on() {
    let dir = tempfile::tempdir().unwrap();
    let (m, obs) = synth(dir.path());
    let far = dir.path().join("far.csv");
    let mut text = std::fs::read_to_string(&obs).unwrap();
    text.push_str("0.6,0.05,1e308,0,0,0.3\n");
    std::fs::write(&far, text).unwrap();
    let good_init = "0.603,0.048,0.203,0.05,-0.04,0.35";
    let register = |obs: &Path, init: &str, extra: &[&str]| {
        let mut args = vec![
            "register",
            "--manifold",
            s(&m),
            "--observations",
            s(obs),
            "--init",
            init,
        ];
        args.extend_from_slice(extra);
        pegtwin(&args)
    };
    let cases = [
        (
            register(&obs, "1e308,0,0,0,0,0", &[]),
            "initial estimate: x = ",
        ),
        (register(&obs, good_init, &["--sigma-mm", "1e308"]), "sigma"),
        (register(&far, good_init, &[]), "z = 1e308 m"),
        (
            pegtwin(&["robot", "stiffness", "--force-n", "1e308"]),
            "push force",
        ),
        (
            pegtwin(&[
                "trial",
                "--geometry",
                "cross",
                "--clearance-mm",
                "0.5",
                "--t-obs",
                "1e308",
            ]),
            "t_obs",
        ),
    ];
    for (o, expected) in cases {
        assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
        assert!(stderr(&o).contains(expected), "{}", stderr(&o));
    }
}

#[test]
fn plot_draws_a_manifold_file_and_a_csv_and_refuses_a_bad_one() {
    let dir = tempfile::tempdir().unwrap();
    let (m, _) = synth(dir.path());
    let csv = dir.path().join("poses.csv");
    let o = pegtwin(&["manifold", "export", s(&m), "--csv", s(&csv)]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = dir.path().join("figures");
    for (input, name) in [(&m, "cross"), (&csv, "poses")] {
        let o = pegtwin(&["manifold", "plot", s(input), "--out", s(&out)]);
        assert!(o.status.success(), "{}", stderr(&o));
        let png = std::fs::read(out.join(format!("{name}.png"))).unwrap();
        assert_eq!(&png[1..4], b"PNG");
        let svg = std::fs::read_to_string(out.join(format!("{name}.svg"))).unwrap();
        // 20 000 poses through a stride of 4: 5 000, less the few beyond the 0.1-99.9 % span of
        // x, y or z, in each of the six panels.
        let title = svg.split("Contact manifold").nth(1).expect("title");
        let count = |after: &str| -> usize {
            let head = title.split(after).next().unwrap();
            head.rsplit([' ', '(']).next().unwrap().parse().unwrap()
        };
        let (shown, left_out) = (
            count(" of 20000 poses shown"),
            count(" beyond the 0.1-99.9 %"),
        );
        assert_eq!(shown + left_out, 5000, "{title}");
        assert!(left_out < 100, "{title}");
        assert_eq!(svg.matches("<circle").count(), 6 * shown);
    }
    let bad = dir.path().join("bad.manifold");
    std::fs::write(&bad, b"not a manifold").unwrap();
    let o = pegtwin(&["manifold", "plot", s(&bad), "--out", s(&out)]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("bad.manifold"), "{}", stderr(&o));
    assert!(!out.join("bad.png").exists());
}

/// `--sampler geometric`: the poses where the parts touch, from their shapes alone; the same
/// file on any number of threads; a trial builds it into the cache under a key of its own.
#[test]
fn the_geometric_sampler_builds_from_the_parts_and_serves_a_trial() {
    let dir = tempfile::tempdir().unwrap();
    let build = |name: &str, threads: &str| {
        let out = dir.path().join(name);
        let o = std::process::Command::new(env!("CARGO_BIN_EXE_pegtwin"))
            .args(["manifold", "build", "--geometry", "cross", "--clearance-mm"])
            .args(["0.5", "--sampler", "geometric", "--points", "1000", "--out"])
            .arg(&out)
            .env("RAYON_NUM_THREADS", threads)
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        out
    };
    let one = build("one.manifold", "1");
    let two = build("two.manifold", "2");
    assert_eq!(std::fs::read(&one).unwrap(), std::fs::read(&two).unwrap());
    let info = pegtwin(&["manifold", "info", s(&one), "--json"]);
    let v: serde_json::Value = serde_json::from_slice(&info.stdout).unwrap();
    assert_eq!(v["points"], 1000);
    let source = v["meta"]["source"].as_str().unwrap();
    assert!(source.contains("--sampler geometric"), "{source}");
    let r = &v["ranges_m_rad"];
    for axis in 0..2 {
        for end in 0..2 {
            // Half the clearance, and what a tilt near the mouth adds to the tip.
            assert!(r[axis][end].as_f64().unwrap().abs() < 0.5e-3, "{r}");
        }
    }
    assert!(r[2][0].as_f64().unwrap() >= -20e-3 && r[2][1].as_f64().unwrap() <= -1e-3);
    let bad = pegtwin(
        &[
            "manifold",
            "build",
            "--geometry",
            "cross",
            "--clearance-mm",
            "0.5",
        ]
        .into_iter()
        .chain([
            "--sampler",
            "geometrical",
            "--out",
            s(&dir.path().join("bad")),
        ])
        .collect::<Vec<_>>(),
    );
    assert_eq!(bad.status.code(), Some(2));
    assert!(stderr(&bad).contains("geometric"), "{}", stderr(&bad));
    let cache = dir.path().join("cache");
    let trial = pegtwin(&[
        "trial",
        "--geometry",
        "cross",
        "--clearance-mm",
        "0.5",
        "--sampler",
        "geometric",
        "--profile",
        "ideal",
        "--cache-dir",
        s(&cache),
        "--json",
    ]);
    assert!(trial.status.success(), "{}", stderr(&trial));
    let files: Vec<String> = std::fs::read_dir(&cache)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert_eq!(files.len(), 1, "{files:?}");
    assert!(files[0].starts_with("cross-0.5mm-geo"), "{files:?}");
}
