//! An installed binary (`cargo install --path .`, or a copy) runs from any folder: the robot, the
//! font and the viewer are inside it, and it reads nothing from the source tree.

use std::path::Path;
use std::process::Command;

#[test]
fn the_binary_names_no_file_of_the_source_tree() {
    let bytes = std::fs::read(env!("CARGO_BIN_EXE_pegtwin")).unwrap();
    let assets = format!("{}/assets", env!("CARGO_MANIFEST_DIR"));
    let found = bytes.windows(assets.len()).any(|w| w == assets.as_bytes());
    assert!(!found, "the binary holds the path {assets}");
}

#[test]
fn a_copy_runs_from_another_folder() {
    let dir = tempfile::tempdir().unwrap();
    let bin = dir.path().join("pegtwin");
    std::fs::copy(env!("CARGO_BIN_EXE_pegtwin"), &bin).unwrap();
    let run = |args: &[&str]| {
        let out = Command::new(&bin)
            .args(args)
            .current_dir(dir.path())
            .env("HOME", dir.path())
            .env_remove("XDG_CACHE_HOME")
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{args:?}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        String::from_utf8_lossy(&out.stdout).into_owned()
    };
    assert!(run(&["robot", "info"]).contains("iiwa"));
    run(&[
        "geometry",
        "export",
        "cross",
        "--clearance-mm",
        "0.5",
        "--out",
        "cad",
        "--convex-parts",
    ]);
    std::fs::write(
        dir.path().join("mine.toml"),
        "name = \"mine\"\n[peg]\nmesh = \"cad/peg_parts\"\nunits = \"mm\"\n[hole]\nmesh = \"cad/hole_parts\"\nunits = \"mm\"\n",
    )
    .unwrap();
    assert!(run(&["assembly", "check", "mine.toml"]).contains("0.5000 mm minimum"));
    run(&[
        "trial",
        "--assembly",
        "mine.toml",
        "--method",
        "direct",
        "--seed",
        "3",
        "--replay",
        "trial.html",
    ]);
    assert!(Path::new(&dir.path().join("trial.html")).is_file());
}
