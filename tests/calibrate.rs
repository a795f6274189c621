//! `pegtwin calibrate` checked on targets the twin made itself (issue 46): a run at a known
//! peg-hole friction gives the "measured" figures; the calibration, on other trial seeds,
//! recovers the friction inside its posterior 90 % range, narrower than the prior, and predicts
//! the held-out force; a target no friction in the prior reaches is flagged (exit 1); a
//! calibration cut short resumes to the same posterior; a bad targets file is refused naming the
//! field.

mod common;
use common::{pegtwin, stderr};
use std::path::Path;

/// The baseline alone (no manifold to build), short observations.
const SCENARIO: &str = "name = \"cal\"\nseed = 11\ntrials = 20\ngeometries = [\"cross\"]\n\
                        clearances_mm = [0.5]\nt_obs_s = [2.0]\nmethods = [\"direct\"]\n\
                        direct_t_obs_s = 2.0\n";

/// The true kinetic friction coefficient of the "real" cell.
const TRUE_FRICTION: f64 = 0.5;

fn write(dir: &Path, name: &str, text: &str) -> String {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p.to_str().unwrap().to_owned()
}

/// The "real" cell's figures: the scenario on other seeds, at the true friction, more trials.
fn measured(dir: &Path, cache: &str) -> serde_json::Value {
    let real = SCENARIO
        .replace("seed = 11", "seed = 99")
        .replace("trials = 20", "trials = 60")
        + &format!("[cell]\ncontact_friction = [{TRUE_FRICTION}, {TRUE_FRICTION}]\n");
    let scenario = write(dir, "real.toml", &real);
    let out = dir.join("real");
    let o = pegtwin(&[
        "campaign",
        &scenario,
        "--out",
        out.to_str().unwrap(),
        "--cache-dir",
        cache,
        "--replays",
        "none",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    summary["cells"][0].clone()
}

/// Fit the success count and, when given, a failure force; hold out the measured failure force.
fn targets(cell: &serde_json::Value, fit_force: Option<f64>, samples: usize) -> String {
    let force = &cell["peak_fz_failure_n"];
    let mut text = format!(
        "free = [\"contact_friction\"]\nsamples = {samples}\nseed = 3\n[prior]\n\
         contact_friction = [0.1, 1.0]\n\
         [[target]]\nname = \"success & <fit>\"\nrole = \"fit\"\nfigure = \"success\"\nmethod = \"direct\"\n\
         successes = {}\ntrials = {}\n\
         [[target]]\nrole = \"hold_out\"\nfigure = \"peak_fz_failure_n\"\nmethod = \"direct\"\n\
         mean = {}\nstd = {}\nn = {}\n",
        cell["successes"], cell["trials"], force["mean"], force["std"], force["n"]
    );
    if let Some(f) = fit_force {
        text += &format!(
            "[[target]]\nrole = \"fit\"\nfigure = \"peak_fz_failure_n\"\nmethod = \"direct\"\n\
             mean = {f}\nstd = 5.0\nn = 20\n"
        );
    }
    text
}

fn calibrate(
    scenario: &str,
    targets: &str,
    out: &Path,
    cache: &str,
    extra: &[&str],
) -> std::process::Output {
    let mut args = vec![
        "calibrate",
        scenario,
        "--targets",
        targets,
        "--out",
        out.to_str().unwrap(),
        "--cache-dir",
        cache,
    ];
    args.extend_from_slice(extra);
    pegtwin(&args)
}

fn posterior(out: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(out.join("posterior.json")).unwrap()).unwrap()
}

#[test]
fn calibrate_recovers_a_known_friction_flags_the_unreachable_and_resumes() {
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    let cache = t.join("cache");
    let cache = cache.to_str().unwrap();
    let cell = measured(t, cache);
    let scenario = write(t, "cal.toml", SCENARIO);
    let file = write(t, "targets.toml", &targets(&cell, None, 10));

    let out = t.join("cal");
    let o = calibrate(&scenario, &file, &out, cache, &[]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    // Without a terminal, each draw says so in a line, with the time it took and what is left.
    assert!(
        stderr(&o).contains("draw 10 of 10 done (") && stderr(&o).contains(" left)"),
        "{}",
        stderr(&o)
    );
    let p = posterior(&out);
    let q = &p["quantiles_5_50_95"][0];
    let (lo, hi) = (q[0].as_f64().unwrap(), q[2].as_f64().unwrap());
    assert!(
        lo <= TRUE_FRICTION && TRUE_FRICTION <= hi,
        "90 % range {lo}-{hi}: {p}"
    );
    assert!(
        hi - lo < 0.7 * 0.9,
        "the posterior is narrower than the prior: {lo}-{hi}"
    );
    assert_eq!(
        p["targets"][1]["predictive"]["inside"], true,
        "held-out force: {p}"
    );
    for f in [
        "report.html",
        "posterior.csv",
        "cell.toml",
        "evaluations.jsonl",
    ] {
        assert!(out.join(f).is_file(), "{f}");
    }
    let report = std::fs::read_to_string(out.join("report.html")).unwrap();
    assert!(
        report.contains("success &amp; &lt;fit&gt;"),
        "labels escaped: {report}"
    );
    let cell_toml = std::fs::read_to_string(out.join("cell.toml")).unwrap();
    assert!(
        cell_toml.contains("[cell]") && cell_toml.contains("contact_friction"),
        "{cell_toml}"
    );

    // Cut short after three draws and part of a fourth line: resumed, the same posterior.
    let cut = t.join("cut");
    std::fs::create_dir(&cut).unwrap();
    std::fs::copy(out.join("calibration.json"), cut.join("calibration.json")).unwrap();
    let lines = std::fs::read_to_string(out.join("evaluations.jsonl")).unwrap();
    let kept: Vec<&str> = lines.lines().take(4).collect();
    let partial = format!(
        "{}\n{}",
        kept[..3].join("\n"),
        &kept[3][..kept[3].len() / 2]
    );
    std::fs::write(cut.join("evaluations.jsonl"), partial).unwrap();
    let o = calibrate(&scenario, &file, &cut, cache, &["--resume"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    for f in [
        "evaluations.jsonl",
        "posterior.csv",
        "posterior.json",
        "cell.toml",
    ] {
        assert_eq!(
            std::fs::read(cut.join(f)).unwrap(),
            std::fs::read(out.join(f)).unwrap(),
            "{f} after a resume"
        );
    }
    let o = calibrate(&scenario, &file, &cut, cache, &[]);
    assert_eq!(o.status.code(), Some(2), "a used folder without --resume");

    // A draw read back with more successes than trials is refused, naming its line.
    let forged = t.join("forged");
    std::fs::create_dir(&forged).unwrap();
    std::fs::copy(
        out.join("calibration.json"),
        forged.join("calibration.json"),
    )
    .unwrap();
    let mut first: serde_json::Value = serde_json::from_str(kept[0]).unwrap();
    let count = (first["figures"].as_array_mut().unwrap().iter_mut())
        .find_map(|f| f.get_mut("count"))
        .expect("a success count");
    count["s"] = serde_json::json!(count["m"].as_u64().unwrap() + 1);
    std::fs::write(forged.join("evaluations.jsonl"), format!("{first}\n")).unwrap();
    let o = calibrate(&scenario, &file, &forged, cache, &["--resume"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("line 1"), "{}", stderr(&o));

    // A failure force no friction in the prior reaches.
    let file = write(t, "far.toml", &targets(&cell, Some(400.0), 4));
    let o = calibrate(&scenario, &file, &t.join("far"), cache, &[]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("no value in the prior reaches"),
        "{}",
        stderr(&o)
    );
    let report = std::fs::read_to_string(t.join("far/report.html")).unwrap();
    assert!(report.contains("No value in the prior reaches"), "{report}");
}

#[test]
fn bad_targets_are_refused_naming_the_field() {
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    let scenario = write(t, "cal.toml", SCENARIO);
    let fit = "[[target]]\nrole = \"fit\"\nfigure = \"success\"\nmethod = \"direct\"\nsuccesses = 3\ntrials = 10\n";
    let cases = [
        ("free = []\n".to_string() + fit, "free"),
        ("free = [\"gravity\"]\n".to_string() + fit, "free"),
        (
            "free = [\"wrench_gain\", \"wrench_gain\"]\n".to_string() + fit,
            "twice",
        ),
        (
            "free = [\"wrench_gain\"]\n[prior]\nwrench_gain = [2, 1]\n".to_string() + fit,
            "prior.wrench_gain",
        ),
        (
            "free = [\"wrench_gain\"]\n[prior]\nwrench_gain = [0.1, 1]\n".to_string() + fit,
            "prior.wrench_gain",
        ),
        (
            "free = [\"wrench_gain\"]\n[prior]\ncontact_friction = [0.1, 1]\n".to_string() + fit,
            "prior.contact_friction",
        ),
        (
            "free = [\"wrench_gain\"]\nsamples = 3\n".to_string() + fit,
            "samples",
        ),
        (
            "free = [\"wrench_gain\"]\nsamples = 0\n".to_string() + fit,
            "samples",
        ),
        (
            "free = [\"wrench_gain\"]\n".to_string()
                + &fit.replace("successes = 3", "successes = 11"),
            "target[0]",
        ),
        (
            "free = [\"wrench_gain\"]\n".to_string() + &fit.replace("\"direct\"", "\"manifold\""),
            "target[0]",
        ),
        (
            "free = [\"wrench_gain\"]\n".to_string() + &fit.replace("\"fit\"", "\"hold_out\""),
            "fit",
        ),
        (
            "free = [\"wrench_gain\"]\n".to_string()
                + &fit.replace("successes = 3", "mean = 3.0\nn = 4"),
            "target[0]",
        ),
        (
            "free = [\"wrench_gain\"]\nextra = 1\n".to_string() + fit,
            "extra",
        ),
    ];
    for (k, (text, field)) in cases.iter().enumerate() {
        let file = write(t, &format!("bad{k}.toml"), text);
        let out = t.join(format!("out{k}"));
        let o = calibrate(&scenario, &file, &out, "/nonexistent", &[]);
        assert_eq!(o.status.code(), Some(2), "case {k}: {}", stderr(&o));
        assert!(stderr(&o).contains(field), "case {k}: {}", stderr(&o));
        assert!(!out.exists(), "case {k}: nothing written");
    }
}

/// The paper's targets file is read against the scenario it was calibrated on: every figure names
/// a row, every value a range (the budget refusal comes after those checks, before any trial
/// runs).
#[test]
fn the_paper_targets_are_read_against_the_paper_calibration_scenario() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    let o = pegtwin(&[
        "calibrate",
        "scenarios/paper-calibration.toml",
        "--targets",
        "scenarios/paper-cell.targets.toml",
        "--out",
        out.to_str().unwrap(),
        "--max-trials",
        "1",
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("10 draws x 250 trials"),
        "{}",
        stderr(&o)
    );
    assert!(!out.exists());
}
