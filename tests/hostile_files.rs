//! Inputs that are not what they claim (issue 47, classes 2 and 3): every reader of a user's or a
//! results folder's file refuses folders, FIFOs, devices, dangling links and oversized files by
//! name, without opening what would block or read without end, and survives random bytes; every
//! writer refuses to replace what is not a regular file.

use pegtwin::error::Error;
use pegtwin::files::{self, DATA_LIMIT_BYTES, TEXT_LIMIT_BYTES};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::path::{Path, PathBuf};

mod common;
use common::{pegtwin, stderr};

type Reader = (&'static str, fn(&Path) -> Result<(), Error>);

/// Every reader of a file a user names or a results folder holds, as `Result<()>`.
fn readers() -> Vec<Reader> {
    use pegtwin::twin::geometry::mesh::{MeshUnits, read_mesh};
    vec![
        ("scenario", |p| {
            pegtwin::campaign::scenario::Scenario::load(p).map(drop)
        }),
        ("urdf", |p| {
            pegtwin::twin::robot::urdf::load(p, &[]).map(drop)
        }),
        ("assembly", |p| pegtwin::twin::assembly::load(p).map(drop)),
        ("mjcf", |p| {
            pegtwin::twin::assembly::mjcf::body_geoms(p, "peg").map(drop)
        }),
        ("baseline", |p| {
            pegtwin::campaign::check::Baseline::load(p).map(drop)
        }),
        ("manifold", |p| {
            pegtwin::method::manifold::file::load(p).map(drop)
        }),
        ("pose csv", |p| {
            pegtwin::method::manifold::file::read_csv(p).map(drop)
        }),
        ("stl", |p| read_mesh(p, MeshUnits::Mm).map(drop)),
        ("obj", |p| read_mesh(p, MeshUnits::Mm).map(drop)),
    ]
}

/// The file name a reader expects (a mesh reader goes by the extension).
fn name_for(reader: &str) -> &'static str {
    match reader {
        "stl" => "part.stl",
        "obj" => "part.obj",
        "pose csv" => "poses.csv",
        _ => "input.toml",
    }
}

fn mkfifo(path: &Path) {
    let ok = std::process::Command::new("mkfifo")
        .arg(path)
        .status()
        .is_ok_and(|s| s.success());
    assert!(ok, "mkfifo {}", path.display());
}

/// The hostile stand-ins for a file at `path`, made in turn; each is named in the refusal.
fn hostile(path: &Path, kind: &str, limit: u64) -> &'static str {
    let _ = std::fs::remove_file(path);
    let _ = std::fs::remove_dir_all(path);
    match kind {
        "folder" => {
            std::fs::create_dir(path).unwrap();
            "a folder"
        }
        "fifo" => {
            mkfifo(path);
            "a FIFO"
        }
        "device" => {
            std::os::unix::fs::symlink("/dev/zero", path).unwrap();
            "a device"
        }
        "dangling" => {
            std::os::unix::fs::symlink(path.with_extension("gone"), path).unwrap();
            "cannot read"
        }
        "oversized" => {
            let f = std::fs::File::create(path).unwrap();
            f.set_len(limit + 1).unwrap();
            "expected at most"
        }
        _ => unreachable!(),
    }
}

#[test]
fn readers_refuse_what_is_not_a_regular_file_of_bounded_size_by_name() {
    let dir = tempfile::tempdir().unwrap();
    for (reader, read) in readers() {
        let path = dir.path().join(name_for(reader));
        let limit = match reader {
            "manifold" | "pose csv" | "stl" | "obj" => DATA_LIMIT_BYTES,
            _ => TEXT_LIMIT_BYTES,
        };
        for kind in ["folder", "fifo", "device", "dangling", "oversized"] {
            let said = hostile(&path, kind, limit);
            let e = read(&path)
                .expect_err(&format!("{reader} took {kind}"))
                .to_string();
            assert!(
                e.contains(&*path.to_string_lossy()) && e.contains(said),
                "{reader}, {kind}: {e}"
            );
        }
    }
}

/// Random bytes, text-like and not, of random lengths: refused or read, never a panic.
#[test]
fn readers_survive_random_bytes() {
    let dir = tempfile::tempdir().unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(47);
    for (reader, read) in readers() {
        let path = dir.path().join(name_for(reader));
        for case in 0..40 {
            let len = rng.random_range(0..4096);
            let printable = case % 2 == 0;
            let bytes: Vec<u8> = (0..len)
                .map(|_| match printable {
                    true => b" =[]\"\n.,0123456789abcxyz<>/"[rng.random_range(0..27)],
                    false => rng.random(),
                })
                .collect();
            std::fs::write(&path, &bytes).unwrap();
            let outcome = std::panic::catch_unwind(|| read(&path));
            assert!(outcome.is_ok(), "{reader} panicked on case {case}");
        }
    }
}

fn made(dir: &Path, name: &str) -> PathBuf {
    dir.join(name)
}

#[test]
fn writers_replace_regular_files_only() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let target = made(d, "target.txt");
    std::fs::write(&target, b"kept").unwrap();

    let fifo = made(d, "fifo.json");
    mkfifo(&fifo);
    let link = made(d, "link.json");
    std::os::unix::fs::symlink(&target, &link).unwrap();
    let null = made(d, "null.json");
    std::os::unix::fs::symlink("/dev/null", &null).unwrap();
    let folder = made(d, "folder.json");
    std::fs::create_dir(&folder).unwrap();
    for (path, what) in [
        (&fifo, "a FIFO"),
        (&link, "a symbolic link"),
        (&null, "a symbolic link"),
        (&folder, "a folder"),
    ] {
        let e = files::write_atomically(path, b"new")
            .unwrap_err()
            .to_string();
        assert!(e.contains(what), "{e}");
        let e = files::ensure_writable(path).unwrap_err().to_string();
        assert!(e.contains(&*path.to_string_lossy()), "{e}");
    }
    use std::os::unix::fs::FileTypeExt;
    let kept = std::fs::symlink_metadata(&fifo).unwrap().file_type();
    assert!(kept.is_fifo(), "the FIFO is still a FIFO");
    assert!(
        std::fs::symlink_metadata(&link)
            .unwrap()
            .file_type()
            .is_symlink()
    );
    assert_eq!(
        std::fs::read(&target).unwrap(),
        b"kept",
        "the link's target is untouched"
    );
    let names: Vec<_> = std::fs::read_dir(d)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert!(
        names
            .iter()
            .all(|n| !n.to_string_lossy().ends_with(".partial")),
        "no half-written file left: {names:?}"
    );

    files::write_atomically(&target, b"replaced").unwrap();
    assert_eq!(std::fs::read(&target).unwrap(), b"replaced");
}

/// Every number of a JSON document, by a path of keys and indices.
fn numbers(v: &serde_json::Value, at: &mut Vec<String>, out: &mut Vec<Vec<String>>) {
    match v {
        serde_json::Value::Number(_) => out.push(at.clone()),
        serde_json::Value::Object(m) => m.iter().for_each(|(k, x)| {
            at.push(k.clone());
            numbers(x, at, out);
            at.pop();
        }),
        serde_json::Value::Array(a) => a.iter().enumerate().for_each(|(i, x)| {
            at.push(i.to_string());
            numbers(x, at, out);
            at.pop();
        }),
        _ => {}
    }
}

fn at_mut<'a>(v: &'a mut serde_json::Value, path: &[String]) -> &'a mut serde_json::Value {
    path.iter().fold(v, |v, k| match v {
        serde_json::Value::Array(a) => &mut a[k.parse::<usize>().unwrap()],
        other => &mut other[k.as_str()],
    })
}

/// A results folder's `campaign.json` is read back as a user's input is (issue 47, class 1):
/// any of its numbers set to zero, a negative, a huge or a fractional value, `check` and
/// `merge` either refuse with exit 2 naming the folder or its file, or take it when it is
/// unchanged in meaning; never a panic or an allocation the size of the number.
#[test]
fn an_edited_campaign_json_is_refused_by_name_never_trusted() {
    let dir = tempfile::tempdir().unwrap();
    let scenario = dir.path().join("s.toml");
    std::fs::write(
        &scenario,
        "name = \"s\"\ntrials = 1\ngeometries = [\"cross\"]\nclearances_mm = [1.0]\n\
         t_obs_s = [1.0]\nmethods = [\"direct\"]\ndirect_t_obs_s = 1.0\n",
    )
    .unwrap();
    let run = dir.path().join("run");
    let o = pegtwin(&[
        "campaign",
        scenario.to_str().unwrap(),
        "--out",
        run.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let file = run.join("campaign.json");
    let whole: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&file).unwrap()).unwrap();
    let mut paths = Vec::new();
    numbers(&whole, &mut Vec::new(), &mut paths);
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let values = [
        serde_json::json!(0),
        serde_json::json!(-1),
        serde_json::json!(u64::MAX),
        serde_json::json!(1e300),
        serde_json::json!(0.5),
    ];
    for case in 0..60 {
        let path = &paths[rng.random_range(0..paths.len())];
        let value = values[case % values.len()].clone();
        let mut edited = whole.clone();
        *at_mut(&mut edited, path) = value.clone();
        std::fs::write(&file, serde_json::to_vec(&edited).unwrap()).unwrap();
        let baseline = dir.path().join("b.json");
        let merged = dir.path().join(format!("m{case}"));
        for args in [
            vec![
                "check",
                run.to_str().unwrap(),
                "--write-baseline",
                baseline.to_str().unwrap(),
            ],
            vec![
                "merge",
                run.to_str().unwrap(),
                "--out",
                merged.to_str().unwrap(),
            ],
        ] {
            let o = pegtwin(&args);
            let code = o.status.code();
            assert!(
                code == Some(0) || (code == Some(2) && stderr(&o).contains(run.to_str().unwrap())),
                "{path:?} = {value}: {args:?} gave {code:?}: {}",
                stderr(&o)
            );
        }
    }
}

/// A baseline is read back as a user's input is (issue 47, class 5): one with no cells, or with a
/// tolerance that would make every limit NaN or negative, is refused naming the field, not
/// passed with "0 quantities compared".
#[test]
fn a_baseline_that_would_pass_anything_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("b.json");
    let good = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/scenarios/smoke.baseline.json"
    ))
    .unwrap();
    let whole: serde_json::Value = serde_json::from_str(&good).unwrap();
    let load = |v: &serde_json::Value| {
        std::fs::write(&path, serde_json::to_vec(v).unwrap()).unwrap();
        pegtwin::campaign::check::Baseline::load(&path).map(drop)
    };
    assert!(load(&whole).is_ok());
    let mut empty = whole.clone();
    empty["cells"] = serde_json::json!([]);
    let e = load(&empty).unwrap_err().to_string();
    assert!(e.contains("cells = []"), "{e}");
    for field in ["mae_rel", "mae_abs_mm", "mae_abs_deg", "fz_rel", "fz_abs_n"] {
        for bad in [serde_json::json!(-0.1), serde_json::json!(-1e300)] {
            let mut edited = whole.clone();
            edited["tolerances"][field] = bad;
            let e = load(&edited).unwrap_err().to_string();
            assert!(
                e.contains(&format!("tolerances.{field}")) || e.contains("not a baseline"),
                "{e}"
            );
        }
    }
}

/// A record moved into another cell of the same pair, whose trials share their seeds, is not
/// taken as that cell's by `check`, `merge` or `--resume` (issue 47, class 5): every record swaps
/// its cell with each record of the same trial number in another cell, and each edited file is
/// refused naming `trials.jsonl`.
#[test]
fn a_record_moved_into_another_cell_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let scenario = dir.path().join("s.toml");
    std::fs::write(
        &scenario,
        "name = \"s\"\ntrials = 2\ngeometries = [\"cross\"]\nclearances_mm = [1.0]\n\
         t_obs_s = [0.5]\nmethods = [\"manifold\", \"direct\"]\ndirect_t_obs_s = 0.5\n\
         [manifold]\nepisodes = 2\nepisode_s = 1.0\npoints = 1000\n",
    )
    .unwrap();
    let (run, cache) = (dir.path().join("run"), dir.path().join("cache"));
    let o = pegtwin(&[
        "campaign",
        scenario.to_str().unwrap(),
        "--out",
        run.to_str().unwrap(),
        "--cache-dir",
        cache.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let file = run.join("trials.jsonl");
    let whole = std::fs::read_to_string(&file).unwrap();
    let lines: Vec<serde_json::Value> = whole
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    let baseline = dir.path().join("b.json");
    let base = baseline.to_str().unwrap();
    let mut swaps = 0;
    for (i, a) in lines.iter().enumerate() {
        for (j, b) in lines.iter().enumerate() {
            if i >= j || a["trial"] != b["trial"] || a["cell"] == b["cell"] {
                continue;
            }
            let mut edited = lines.clone();
            edited[i]["cell"] = b["cell"].clone();
            edited[j]["cell"] = a["cell"].clone();
            let text: String = edited.iter().map(|v| format!("{v}\n")).collect();
            std::fs::write(&file, text).unwrap();
            let merged = dir.path().join(format!("m{i}-{j}"));
            for args in [
                vec!["check", run.to_str().unwrap(), "--write-baseline", base],
                vec![
                    "merge",
                    run.to_str().unwrap(),
                    "--out",
                    merged.to_str().unwrap(),
                ],
                vec![
                    "campaign",
                    scenario.to_str().unwrap(),
                    "--out",
                    run.to_str().unwrap(),
                    "--cache-dir",
                    cache.to_str().unwrap(),
                    "--resume",
                ],
            ] {
                let o = pegtwin(&args);
                assert_eq!(o.status.code(), Some(2), "{args:?}: {}", stderr(&o));
                assert!(
                    stderr(&o).contains("trials.jsonl") && stderr(&o).contains("moved"),
                    "{args:?}: {}",
                    stderr(&o)
                );
            }
            swaps += 1;
        }
    }
    assert_eq!(swaps, 2);
    std::fs::write(&file, whole).unwrap();
    let o = pegtwin(&["check", run.to_str().unwrap(), "--write-baseline", base]);
    assert!(o.status.success(), "{}", stderr(&o));
}
