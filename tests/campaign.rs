//! Campaigns through the command line: identical trials.jsonl for 1 and 2 threads, for two
//! merged shards and after a SIGKILL and --resume; the regression gate failing on a degraded
//! estimator and passing on a rerun; the report's files; clear errors on bad input.

mod common;
use common::{pegtwin, stderr};
use std::path::Path;
use std::process::Command;
use std::time::{Duration, Instant};

/// A tiny campaign: a small manifold, short observations (two budgets), both methods.
const SCENARIO: &str = r#"
name = "test"
seed = 7
trials = 3
geometries = ["cross"]
clearances_mm = [0.5]
t_obs_s = [2.0, 3.0]
methods = ["manifold", "direct"]
direct_t_obs_s = 3.0

[manifold]
points = 3000
episodes = 3
episode_s = 5.0
"#;

/// The same with a crippled estimator: one paper-update iteration from one restart.
const DEGRADED: &str = "\n[registration]\nsolver = \"paper\"\niterations = 1\nrestarts = 1\n";

fn write(dir: &Path, name: &str, text: &str) -> String {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p.to_str().unwrap().to_owned()
}

fn campaign(scenario: &str, out: &Path, cache: &Path, extra: &[&str]) -> std::process::Output {
    let mut args = vec![
        "campaign",
        scenario,
        "--out",
        out.to_str().unwrap(),
        "--cache-dir",
        cache.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    pegtwin(&args)
}

/// The replay pages of a results folder, sorted.
fn replays_of(dir: &Path) -> Vec<String> {
    let Ok(entries) = std::fs::read_dir(dir.join("replays")) else {
        return Vec::new();
    };
    let mut names: Vec<String> = entries
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

/// `--replays failures`: a page for every trial among the first 50 of a cell that did not succeed
/// and for trials 0 and 1 of every cell, none for the others, each named after its record's
/// outcome.
fn check_replays(trials_jsonl: &str, pages: &[String]) {
    for line in trials_jsonl.lines() {
        let r: serde_json::Value = serde_json::from_str(line).unwrap();
        let (cell, trial) = (r["cell"].as_u64().unwrap(), r["trial"].as_u64().unwrap());
        let outcome = r["outcome"].as_str().unwrap();
        let name = format!("c{cell:03}-t{trial:04}-{outcome}.html");
        let wanted = outcome != "error" && (trial < 2 || outcome != "success" && trial < 50);
        assert_eq!(pages.contains(&name), wanted, "{name} in {pages:?}");
    }
}

fn trials(dir: &Path) -> String {
    std::fs::read_to_string(dir.join("trials.jsonl")).unwrap()
}

#[test]
fn campaign_is_identical_across_threads_shards_and_a_kill() {
    let tmp = tempfile::tempdir().unwrap();
    let (t, cache) = (tmp.path(), tmp.path().join("cache"));
    let scenario = write(t, "s.toml", SCENARIO);

    let one = t.join("one");
    let o = campaign(&scenario, &one, &cache, &["--threads", "1"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let reference = trials(&one);
    assert_eq!(reference.lines().count(), 9);
    for f in [
        "summary.json",
        "summary.csv",
        "report.html",
        "figures/fig4_success.png",
        "figures/fig5_errors.svg",
        "figures/fig6_fz.png",
    ] {
        assert!(one.join(f).is_file(), "{f} written");
    }
    let table = String::from_utf8_lossy(&o.stdout);
    assert!(
        table.contains("manifold") && table.contains("direct"),
        "{table}"
    );
    let pages = replays_of(&one);
    check_replays(&reference, &pages);
    let report = std::fs::read_to_string(one.join("report.html")).unwrap();
    for page in &pages {
        assert!(report.contains(&format!("replays/{page}")), "{page} linked");
    }
    assert!(one.join("figures/manifold-cross-0.5mm.png").is_file());
    assert!(report.contains("figures/manifold-cross-0.5mm.png"));

    let two = t.join("two");
    let o = campaign(
        &scenario,
        &two,
        &cache,
        &["--threads", "2", "--replays", "none"],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(trials(&two), reference, "1 vs 2 threads, replays or none");
    assert!(replays_of(&two).is_empty(), "--replays none");

    let o = campaign(&scenario, &t.join("shard0"), &cache, &["--shard", "0/2"]);
    assert!(o.status.success(), "{}", stderr(&o));
    // Shard 1 as the second task of a Slurm job array numbered 5-6 gets it (`--shard auto`).
    let o = Command::new(env!("CARGO_BIN_EXE_pegtwin"))
        .args(["campaign", &scenario, "--shard", "auto", "--cache-dir"])
        .arg(&cache)
        .arg("--out")
        .arg(t.join("shard1"))
        .envs([
            ("SLURM_ARRAY_TASK_ID", "6"),
            ("SLURM_ARRAY_TASK_MIN", "5"),
            ("SLURM_ARRAY_TASK_MAX", "6"),
            ("SLURM_ARRAY_TASK_COUNT", "2"),
        ])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    let merged = t.join("merged");
    let o = pegtwin(&[
        "merge",
        t.join("shard1").to_str().unwrap(),
        t.join("shard0").to_str().unwrap(),
        "--out",
        merged.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    // A whole run's trials of a seed share one observation (campaign::sharing): the 2 s trial
    // goes on from its budget of the 3 s observation, the direct trial from its end. The shards
    // split them (trial numbers i, 3 + i and 6 + i): the 3 s manifold trial runs alone there,
    // and the other two share only with each other. The records and the replays are the same
    // (and `rerun`, which runs a trial alone, gives a 2 s trial's record below).
    assert_eq!(trials(&merged), reference, "merged shards");
    assert_eq!(replays_of(&merged), pages, "the shards' replays merged");
    let o = pegtwin(&[
        "merge",
        t.join("shard0").to_str().unwrap(),
        "--out",
        t.join("m2").to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("missing shards 1/2"), "{}", stderr(&o));

    // Kill a run once it has written a trial, cut its last line short, then resume.
    let killed = t.join("killed");
    let mut child = Command::new(env!("CARGO_BIN_EXE_pegtwin"))
        .args([
            "campaign",
            &scenario,
            "--out",
            killed.to_str().unwrap(),
            "--cache-dir",
            cache.to_str().unwrap(),
            "--threads",
            "1",
        ])
        .spawn()
        .unwrap();
    let start = Instant::now();
    while std::fs::read_to_string(killed.join("trials.jsonl")).map_or(0, |s| s.lines().count()) < 2
    {
        assert!(
            start.elapsed() < Duration::from_secs(120),
            "no trial written"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    // SAFETY: kill(2) on our own child's pid.
    unsafe { libc::kill(child.id() as i32, libc::SIGKILL) };
    child.wait().unwrap();
    let partial = trials(&killed);
    assert!(partial.lines().count() < 9, "killed before the end");
    std::fs::write(
        killed.join("trials.jsonl"),
        format!("{partial}{{\"cell\":1,\"tri"),
    )
    .unwrap();
    let o = campaign(&scenario, &killed, &cache, &[]);
    assert_eq!(o.status.code(), Some(2), "refused without --resume");
    assert!(stderr(&o).contains("--resume"), "{}", stderr(&o));
    let o = campaign(&scenario, &killed, &cache, &["--resume"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(trials(&killed), reference, "resumed after SIGKILL");

    // The regression gate.
    let baseline = t.join("baseline.json");
    let o = pegtwin(&[
        "check",
        one.to_str().unwrap(),
        "--write-baseline",
        baseline.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = pegtwin(&[
        "check",
        two.to_str().unwrap(),
        "--baseline",
        baseline.to_str().unwrap(),
    ]);
    assert_eq!(
        o.status.code(),
        Some(0),
        "rerun passes: {}",
        String::from_utf8_lossy(&o.stdout)
    );
    let degraded = write(t, "d.toml", &format!("{SCENARIO}{DEGRADED}"));
    let bad = t.join("degraded");
    let o = campaign(&degraded, &bad, &cache, &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = pegtwin(&[
        "check",
        bad.to_str().unwrap(),
        "--baseline",
        baseline.to_str().unwrap(),
    ]);
    let report = String::from_utf8_lossy(&o.stdout);
    assert_eq!(o.status.code(), Some(1), "degraded run fails: {report}");
    assert!(
        report.contains("FAIL") && report.contains("mae_"),
        "{report}"
    );

    // A folder holding another campaign is refused, even with --resume.
    let o = campaign(&degraded, &one, &cache, &["--resume"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("different campaign"), "{}", stderr(&o));
}

#[test]
fn rerun_gives_a_campaigns_record_bit_for_bit_and_traces_it() {
    let tmp = tempfile::tempdir().unwrap();
    let (t, cache) = (tmp.path(), tmp.path().join("cache"));
    let scenario = write(t, "s.toml", SCENARIO);
    let out = t.join("run");
    let o = campaign(&scenario, &out, &cache, &["--replays", "none"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let lines: Vec<String> = trials(&out).lines().map(str::to_owned).collect();
    let cache = cache.to_str().unwrap();
    for (from, cell, trial) in [(out.to_str().unwrap(), 0, 1), (&scenario, 1, 2)] {
        let trace = t.join(format!("trace{cell}.csv"));
        let (cell_s, trial_s) = (cell.to_string(), trial.to_string());
        let o = pegtwin(&[
            "rerun",
            from,
            "--cell",
            &cell_s,
            "--trial",
            &trial_s,
            "--cache-dir",
            cache,
            "--json",
            "--trace",
            trace.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{}", stderr(&o));
        let line = String::from_utf8(o.stdout).unwrap();
        assert_eq!(
            line.trim_end(),
            lines[cell * 3 + trial],
            "cell {cell} trial {trial}"
        );
        let csv = std::fs::read_to_string(&trace).unwrap();
        assert!(csv.starts_with("time_s,phase,") && csv.lines().count() > 1000);
    }
    for (flag, value, says) in [
        ("--cell", "3", "--cell 3: the scenario has 3 cells"),
        (
            "--trial",
            "3",
            "--trial 3: the scenario runs 3 trials per cell",
        ),
    ] {
        let mut args = vec!["rerun", &scenario, "--cell", "0", "--trial", "0"];
        let at = args.iter().position(|a| *a == flag).unwrap();
        args[at + 1] = value;
        args.extend(["--cache-dir", cache]);
        let o = pegtwin(&args);
        assert_eq!(o.status.code(), Some(2));
        assert!(stderr(&o).contains(says), "{}", stderr(&o));
    }
}

#[test]
fn bad_scenarios_and_folders_are_refused_with_exit_2() {
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    let cache = t.join("cache");
    let cases = [
        ("name = \"x\"\ntrials = [\n", "line"),
        (
            &format!("{SCENARIO}\nwhatever = 3\n"),
            "unknown field `whatever`",
        ),
        (&SCENARIO.replace("trials = 3", "trials = 0"), "trials"),
        (&SCENARIO.replace("[0.5]", "[0.5, 9]"), "clearances_mm"),
        (
            &SCENARIO.replace("[\"cross\"]", "[\"torus\"]"),
            "unknown geometry 'torus'",
        ),
        (
            &format!("{SCENARIO}\n[gains.insert]\nstiffness = [9000, 1, 1, 1, 1, 1]\n"),
            "gains.insert",
        ),
        (
            &format!("{SCENARIO}\n[sensors]\ntorque_noise_nm = -1\n"),
            "torque_noise_nm",
        ),
    ];
    for (i, (text, expected)) in cases.iter().enumerate() {
        let s = write(t, &format!("bad{i}.toml"), text);
        let o = campaign(&s, &t.join(format!("out{i}")), &cache, &[]);
        assert_eq!(o.status.code(), Some(2), "case {i}");
        let e = stderr(&o);
        assert!(
            e.contains(expected) && e.contains(&format!("bad{i}.toml")),
            "case {i}: {e}"
        );
        assert!(
            !t.join(format!("out{i}")).exists(),
            "case {i}: nothing written"
        );
    }
    let e = stderr(&campaign(
        &write(t, "bad0.toml", "name = \"x\"\ntrials = [\n"),
        &t.join("o"),
        &cache,
        &[],
    ));
    assert!(e.contains("line 2"), "{e}");

    let full = t.join("full");
    std::fs::create_dir_all(&full).unwrap();
    std::fs::write(full.join("notes.txt"), "mine").unwrap();
    let o = campaign(&write(t, "s.toml", SCENARIO), &full, &cache, &[]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("not empty"), "{}", stderr(&o));
    let o = campaign(
        &write(t, "s.toml", SCENARIO),
        &t.join("x"),
        &cache,
        &["--shard", "2/2"],
    );
    assert_eq!(o.status.code(), Some(2));
    let o = pegtwin(&["check", full.to_str().unwrap(), "--baseline", "nope.json"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("campaign.json"), "{}", stderr(&o));
}

/// `tune`, `calibrate` and Python's `evaluate` run trials through `run_trials`, which shares
/// each seed's observation between the cells that observe alike, as a campaign does: every record
/// is the campaign's, bit for bit.
#[test]
fn trials_run_for_a_search_are_the_campaigns_records() {
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    let scenario = write(t, "s.toml", SCENARIO);
    let cache = t.join("cache");
    let o = campaign(&scenario, &t.join("run"), &cache, &["--replays", "none"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let s = pegtwin::campaign::scenario::Scenario::load(Path::new(&scenario)).unwrap();
    let options = pegtwin::campaign::run::RunOptions {
        cache_dir: cache,
        progress: &(),
    };
    let records = pegtwin::campaign::run::run_trial_range(&s, 1..3, &options).unwrap();
    let lines: Vec<String> = (records.iter())
        .map(|r| serde_json::to_string(r).unwrap())
        .collect();
    let written = trials(&t.join("run"));
    let campaign: Vec<&str> = (written.lines())
        .filter(|l| !l.contains("\"trial\":0,"))
        .collect();
    assert_eq!(lines.len(), 6, "three cells, trials 1 and 2");
    assert_eq!(lines, campaign);
}

/// A search over the direct baseline's insertion runs a rung's candidates together, each seed's
/// observation once for all of them: each evaluation is the one its candidate gets alone.
#[test]
fn candidates_that_differ_after_the_observation_share_it_and_score_as_alone() {
    use pegtwin::campaign::tune::{TuneTarget, candidates, evaluate_candidates, incumbent};
    let tmp = tempfile::tempdir().unwrap();
    let s = pegtwin::campaign::scenario::Scenario::parse(SCENARIO).unwrap();
    let options = pegtwin::campaign::run::RunOptions {
        cache_dir: tmp.path().join("cache"),
        progress: &(),
    };
    let mut batch = candidates(2, 5, TuneTarget::Direct);
    batch.push(incumbent(&s, TuneTarget::Direct, 2));
    let direct = batch[0].apply(&s);
    let prepared = pegtwin::campaign::run::prepare(&direct, &[0], &options).unwrap();
    let together = evaluate_candidates(&s, &prepared, &batch, 0, 2).unwrap();
    for (c, e) in batch.iter().zip(&together) {
        let alone = evaluate_candidates(&s, &prepared, std::slice::from_ref(c), 0, 2).unwrap();
        let alone = &alone[0];
        assert_eq!(e.candidate.id, c.id);
        assert_eq!((e.trials, e.successes), (alone.trials, alone.successes));
        assert_eq!(e.peak_fz_n.to_bits(), alone.peak_fz_n.to_bits());
    }
    assert!(together.iter().all(|e| e.trials == 2));
}

#[test]
fn tune_writes_its_table_and_prints_a_usable_snippet() {
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    let scenario = write(t, "s.toml", &SCENARIO.replace("trials = 3", "trials = 2"));
    let out = t.join("tune");
    let o = pegtwin(&[
        "tune",
        &scenario,
        "--out",
        out.to_str().unwrap(),
        "--candidates",
        "3",
        "--first-trials",
        "1",
        "--cache-dir",
        t.join("cache").to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let table = std::fs::read_to_string(out.join("tune.csv")).unwrap();
    // Rung 0: 3 candidates and the scenario's own settings x 1 trial per cell; rung 1: the best
    // two x 2.
    assert_eq!(table.lines().count(), 1 + 4 + 2, "{table}");
    let own: Vec<&str> = table.lines().filter(|l| l.contains(",3,true,")).collect();
    assert!(own[0].starts_with("0,1,3,true,"), "{table}");
    assert!(out.join("figures/tune.png").is_file());
    let stdout = String::from_utf8_lossy(&o.stdout);
    let snippet = &stdout[stdout.find("[gains.observe]").expect("snippet printed")..];
    let s = write(t, "tuned.toml", &format!("{SCENARIO}\n{snippet}"));
    let o = pegtwin(&[
        "campaign",
        &s,
        "--out",
        t.join("x").to_str().unwrap(),
        "--shard",
        "5/2",
    ]);
    // The snippet parses (the only error left is the shard).
    assert!(stderr(&o).contains("--shard 5/2"), "{}", stderr(&o));

    // Killed once it has finished an evaluation (its last line cut short), then resumed: the
    // uninterrupted search's table. Without --resume the folder is refused.
    let killed = t.join("killed");
    let args = |out: &Path| {
        let mut a: Vec<String> = [
            "tune",
            &scenario,
            "--candidates",
            "3",
            "--first-trials",
            "1",
        ]
        .map(String::from)
        .to_vec();
        a.extend(["--threads", "1", "--cache-dir"].map(String::from));
        a.push(t.join("cache").to_str().unwrap().into());
        a.extend(["--out".to_string(), out.to_str().unwrap().into()]);
        a
    };
    let mut child = Command::new(env!("CARGO_BIN_EXE_pegtwin"))
        .args(args(&killed))
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let journal = killed.join("tune-journal.jsonl");
    let start = Instant::now();
    while std::fs::read_to_string(&journal).map_or(0, |s| s.lines().count()) < 2 {
        assert!(
            start.elapsed() < Duration::from_secs(120),
            "no evaluation kept"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    // SAFETY: kill(2) on our own child's pid.
    unsafe { libc::kill(child.id() as i32, libc::SIGKILL) };
    child.wait().unwrap();
    assert!(!killed.join("tune.csv").exists(), "killed before the end");
    let kept = std::fs::read_to_string(&journal).unwrap();
    std::fs::write(&journal, format!("{kept}{{\"rung\":0,\"tri")).unwrap();
    let o = pegtwin(&args(&killed).iter().map(String::as_str).collect::<Vec<_>>());
    assert_eq!(o.status.code(), Some(2), "refused without --resume");
    let mut resumed = args(&killed);
    resumed.push("--resume".into());
    let o = pegtwin(&resumed.iter().map(String::as_str).collect::<Vec<_>>());
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("resuming: "), "{}", stderr(&o));
    assert_eq!(
        std::fs::read_to_string(killed.join("tune.csv")).unwrap(),
        table
    );
}

/// With several clearances the summary pools per clearance and over all of them, and the report
/// draws Fig. 5 and 6 per clearance beside the pooled ones (issue 16, item 4).
#[test]
fn several_clearances_give_pooled_rows_and_figures_per_clearance() {
    let tmp = tempfile::tempdir().unwrap();
    let (t, cache) = (tmp.path(), tmp.path().join("cache"));
    let text = "name = \"c\"\ntrials = 1\ngeometries = [\"cross\", \"plug3\"]\n\
                clearances_mm = [0.5, 1.0]\nt_obs_s = [1.0]\nmethods = [\"direct\"]\n\
                direct_t_obs_s = 1.0\n";
    let scenario = write(t, "c.toml", text);
    let out = t.join("out");
    let o = campaign(&scenario, &out, &cache, &["--replays", "none"]);
    assert!(o.status.success(), "{}", stderr(&o));
    for f in ["fig5_errors", "fig6_fz"] {
        for suffix in ["", "-0.5mm", "-1mm"] {
            let png = out.join(format!("figures/{f}{suffix}.png"));
            assert!(png.is_file(), "{} written", png.display());
        }
    }
    let summary: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("summary.json")).unwrap()).unwrap();
    let pooled: Vec<(f64, u64)> = summary["pooled"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| {
            (
                p["clearance_mm"].as_f64().unwrap(),
                p["trials"].as_u64().unwrap(),
            )
        })
        .collect();
    assert_eq!(pooled, vec![(0.5, 2), (1.0, 2), (0.0, 4)]);
    let report = std::fs::read_to_string(out.join("report.html")).unwrap();
    assert!(report.contains("figures/fig6_fz-1mm.png"), "linked");
}

/// The manifolds a campaign builds side by side are the files each pair's build gives alone.
#[test]
fn manifolds_built_side_by_side_are_the_files_built_alone() {
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    let scenario = |clearances: &str| {
        format!(
            "name = \"m\"\ntrials = 1\ngeometries = [\"cross\"]\nclearances_mm = {clearances}\n\
             t_obs_s = [1.0]\nmethods = [\"manifold\"]\n[manifold]\npoints = 1000\n\
             episodes = 3\nepisode_s = 4.0\n"
        )
    };
    let together = t.join("together");
    let s = write(t, "both.toml", &scenario("[0.5, 1.0]"));
    let o = campaign(&s, &t.join("out"), &together, &["--replays", "none"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let alone = t.join("alone");
    for (i, c) in ["[0.5]", "[1.0]"].into_iter().enumerate() {
        let s = write(t, &format!("alone{i}.toml"), &scenario(c));
        let o = campaign(
            &s,
            &t.join(format!("out{i}")),
            &alone,
            &["--replays", "none"],
        );
        assert!(o.status.success(), "{}", stderr(&o));
    }
    let files = |dir: &Path| {
        let mut v: Vec<(String, Vec<u8>)> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| {
                let e = e.unwrap();
                let name = e.file_name().to_string_lossy().into_owned();
                (name, std::fs::read(e.path()).unwrap())
            })
            .collect();
        v.sort();
        v
    };
    let (a, b) = (files(&together), files(&alone));
    assert_eq!(a.len(), 2, "two manifolds built");
    assert!(a == b, "the same files, byte for byte");
    // `manifold build --scenario` builds what the campaign would (a job array's first step).
    let prebuilt = t.join("prebuilt");
    let build = [
        "manifold",
        "build",
        "--scenario",
        &s,
        "--quiet",
        "--cache-dir",
    ];
    let o = pegtwin(&[&build[..], &[prebuilt.to_str().unwrap()]].concat());
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        files(&prebuilt) == a,
        "manifold build --scenario: the campaign's files"
    );
    assert!(String::from_utf8_lossy(&o.stdout).contains("2 reference manifolds"));
    let o = pegtwin(&[&build[..], &[prebuilt.to_str().unwrap(), "--out", "x"]].concat());
    assert_eq!(o.status.code(), Some(2), "--scenario takes no --out");
}

/// Every scenario shipped in `scenarios/` (and under it) loads and passes its checks (assembly
/// files, cell files and calibration targets, `*.targets.toml`, beside them are read by their
/// own tests or the scenarios that take them).
#[test]
fn every_shipped_scenario_loads() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios");
    let mut found = 0;
    let mut dirs = vec![root];
    while let Some(dir) = dirs.pop() {
        for entry in std::fs::read_dir(&dir).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                dirs.push(path);
            } else if path.extension().is_some_and(|e| e == "toml")
                && !is_assembly(&path)
                && !is_cell_file(&path)
                && !path.to_string_lossy().ends_with(".targets.toml")
            {
                pegtwin::campaign::scenario::Scenario::load(&path)
                    .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
                found += 1;
            }
        }
    }
    assert!(found >= 5, "{found} scenarios");
}

/// Assembly files live beside scenarios; they have a `[peg]` section.
fn is_assembly(path: &Path) -> bool {
    std::fs::read_to_string(path).is_ok_and(|t| t.lines().any(|l| l.trim() == "[peg]"))
}

/// Cell files (`cell_file = "..."` in a scenario) hold a `[cell]` section and nothing else.
fn is_cell_file(path: &Path) -> bool {
    let text = std::fs::read_to_string(path).unwrap();
    let value: toml::Table = toml::from_str(&text).unwrap();
    value.keys().eq(["cell"])
}

/// The peak resident memory of a running child so far, bytes (Linux: VmHWM).
fn peak_memory(pid: u32) -> Option<u64> {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

/// A campaign is planned in memory proportional to its cells, not its trials (issue 47, class
/// 6): one shard of six cells of a million trials each runs its two trials in the memory of any
/// small campaign, 15 MB (listing the six million trials first took 200 MB, and those of 21
/// cells at a million each 2 GB before the first trial).
#[test]
fn a_campaign_of_millions_of_trials_is_planned_in_little_memory() {
    let dir = tempfile::tempdir().unwrap();
    let text = "name = \"huge\"\nseed = 3\ntrials = 1000000\ngeometries = [\"cross\", \"key\", \
                \"plug3\"]\nclearances_mm = [0.5, 1.0]\nt_obs_s = [3.0]\nmethods = [\"direct\"]\n\
                direct_t_obs_s = 3.0\n";
    let scenario = write(dir.path(), "huge.toml", text);
    let out = dir.path().join("out");
    let mut child = Command::new(env!("CARGO_BIN_EXE_pegtwin"))
        .args(["campaign", &scenario, "--out", out.to_str().unwrap()])
        .args(["--shard", "0/3000000", "--replays", "none"])
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let mut peak = 0;
    while child.try_wait().unwrap().is_none() {
        peak = peak.max(peak_memory(child.id()).unwrap_or(0));
        std::thread::sleep(Duration::from_millis(20));
    }
    let output = child.wait_with_output().unwrap();
    assert!(output.status.success(), "{}", stderr(&output));
    let records = trials(&out);
    assert_eq!(records.lines().count(), 2, "{records}");
    assert!(records.contains("\"cell\":3,\"trial\":0"), "{records}");
    assert!(peak < 64 << 20, "peak resident memory {} MB", peak >> 20);
}

/// A campaign of the direct baseline only (no manifold to build), four trials.
const DIRECT: &str = "name = \"direct\"\nseed = 5\ntrials = 4\ngeometries = [\"cross\"]\n\
                      clearances_mm = [0.5]\nt_obs_s = [2.0]\nmethods = [\"direct\"]\n\
                      direct_t_obs_s = 2.0\n";

/// The replay pages of a results folder, with their bytes.
fn pages(dir: &Path) -> Vec<(String, Vec<u8>)> {
    (replays_of(dir).into_iter())
        .map(|p| {
            let bytes = std::fs::read(dir.join("replays").join(&p)).unwrap();
            (p, bytes)
        })
        .collect()
}

/// Outputs cut short are completed (issue 47, class 3): the replays a run could not write (here
/// a file stands where their folder goes) or asked for only on resuming are drawn on `--resume`,
/// byte for byte those of an uncut run, the records untouched; a merge cut short is completed
/// by `merge --resume`, and without it the refusal says so.
#[test]
fn replays_a_run_lacks_are_drawn_on_resume_and_a_cut_merge_completes() {
    let tmp = tempfile::tempdir().unwrap();
    let (t, cache) = (tmp.path(), tmp.path().join("cache"));
    let scenario = write(t, "direct.toml", DIRECT);
    let all = ["--replays", "all"];
    let whole = t.join("whole");
    let o = campaign(&scenario, &whole, &cache, &all);
    assert!(o.status.success(), "{}", stderr(&o));
    let (reference, drawn) = (trials(&whole), pages(&whole));
    assert_eq!(drawn.len(), 4);

    let cut = t.join("cut");
    let o = campaign(&scenario, &cut, &cache, &["--replays", "none"]);
    assert!(o.status.success(), "{}", stderr(&o));
    std::fs::write(cut.join("replays"), "in the way").unwrap();
    let o = campaign(&scenario, &cut, &cache, &["--resume", "--replays", "all"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("replays"), "{}", stderr(&o));
    assert_eq!(trials(&cut), reference, "the records are untouched");
    std::fs::remove_file(cut.join("replays")).unwrap();
    let o = campaign(&scenario, &cut, &cache, &["--resume", "--replays", "all"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let said = String::from_utf8_lossy(&o.stdout);
    assert!(said.contains("4 run again for the replays"), "{said}");
    assert_eq!(trials(&cut), reference);
    assert!(
        pages(&cut) == drawn,
        "redrawn pages differ from the uncut run's"
    );
    let o = campaign(&scenario, &cut, &cache, &["--resume", "--replays", "all"]);
    assert!(o.status.success() && !String::from_utf8_lossy(&o.stdout).contains("run again"));

    let mut shards = Vec::new();
    for i in 0..2 {
        let dir = t.join(format!("shard{i}"));
        let shard = format!("{i}/2");
        let o = campaign(
            &scenario,
            &dir,
            &cache,
            &["--shard", &shard, "--replays", "all"],
        );
        assert!(o.status.success(), "{}", stderr(&o));
        shards.push(dir.to_str().unwrap().to_owned());
    }
    let merged = t.join("merged");
    let merge = |extra: &[&str]| {
        let mut args = vec![
            "merge",
            &shards[0],
            &shards[1],
            "--out",
            merged.to_str().unwrap(),
        ];
        args.extend_from_slice(extra);
        pegtwin(&args)
    };
    let o = merge(&["--cache-dir", cache.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    // Cut short after the records: some replays, the summary and the report missing.
    for p in replays_of(&merged).iter().step_by(2) {
        std::fs::remove_file(merged.join("replays").join(p)).unwrap();
    }
    for f in ["report.html", "summary.json", "summary.csv"] {
        std::fs::remove_file(merged.join(f)).unwrap();
    }
    let o = merge(&["--cache-dir", cache.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("--resume"), "{}", stderr(&o));
    let o = merge(&["--cache-dir", cache.to_str().unwrap(), "--resume"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(trials(&merged), reference);
    assert!(
        pages(&merged) == drawn,
        "merged pages differ from the whole run's"
    );
    assert!(merged.join("report.html").is_file() && merged.join("summary.json").is_file());
}
