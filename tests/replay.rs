//! `pegtwin trial --replay`: a self-contained page that holds the trial, does not change it, and
//! draws it in a real browser (headless Chromium, WebGL through SwiftShader).
//!
//! The browser test needs Debian's `chromium` (`.ci/run` installs it; `PEGTWIN_CHROMIUM` names
//! another binary). Without one it fails and says so; `PEGTWIN_SKIP_BROWSER_TESTS=1` skips it
//! on a machine that cannot have a browser.

use std::path::{Path, PathBuf};
use std::process::Command;

mod common;
use common::{pegtwin, stderr};

const TRIAL: [&str; 9] = [
    "trial",
    "--geometry",
    "cross",
    "--clearance-mm",
    "0.5",
    "--method",
    "direct",
    "--seed",
    "1",
];

/// Runs the test trial with `extra` flags and returns its JSON record.
fn trial_json(extra: &[&str]) -> serde_json::Value {
    let mut args = TRIAL.to_vec();
    args.push("--json");
    args.extend(extra);
    let o = pegtwin(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    serde_json::from_slice(&o.stdout).expect("trial --json prints JSON")
}

/// The recording inside a replay page.
fn page_data(html: &str) -> serde_json::Value {
    let open = "<script type=\"application/json\" id=\"replay-data\">";
    let start = html.find(open).expect("the page holds its data") + open.len();
    let end = start + html[start..].find("</script>").expect("the data ends");
    serde_json::from_str(&html[start..end]).expect("the data is JSON")
}

fn write_replay(dir: &Path) -> (PathBuf, serde_json::Value) {
    let page = dir.join("trial.html");
    let record = trial_json(&["--replay", page.to_str().unwrap()]);
    (page, record)
}

#[test]
fn a_replay_holds_the_trial_offline_and_recording_does_not_change_it() {
    let dir = tempfile::tempdir().unwrap();
    let (page, with_replay) = write_replay(dir.path());
    assert_eq!(
        with_replay,
        trial_json(&[]),
        "recording a replay changed the trial"
    );
    let html = std::fs::read_to_string(&page).unwrap();
    assert!(html.len() < 5_000_000, "page is {} bytes", html.len());
    for remote in ["src=\"http", "href=\"http", "import(", "fetch("] {
        assert!(!html.contains(remote), "the page reaches out: {remote}");
    }
    let data = page_data(&html);
    assert_eq!(data["trial"], with_replay);
    let frames = data["frames"]["count"].as_u64().unwrap() as f64;
    let t = &with_replay["times"];
    let duration: f64 = ["observe_s", "retract_s", "align_s", "insert_s"]
        .iter()
        .map(|k| t[k].as_f64().unwrap())
        .sum();
    assert!(
        (frames - duration / 0.02).abs() <= 3.0,
        "{frames} frames for {duration} s"
    );
    assert_eq!(
        data["links"].as_array().unwrap().len(),
        8,
        "base and 7 links"
    );
    assert!(data["true_hole"].is_array());
    assert!(data["estimated_hole"].is_null(), "direct has no estimate");
}

#[test]
fn a_replay_refuses_a_folder_as_its_path_before_running() {
    let dir = tempfile::tempdir().unwrap();
    let mut args = TRIAL.to_vec();
    args.extend(["--replay", dir.path().to_str().unwrap()]);
    let o = pegtwin(&args);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("is a folder"), "{}", stderr(&o));
}

/// The Chromium to drive, or None when the browser tests are skipped on purpose.
fn chromium() -> Option<PathBuf> {
    if std::env::var_os("PEGTWIN_SKIP_BROWSER_TESTS").is_some_and(|v| v == "1") {
        return None;
    }
    let named = std::env::var_os("PEGTWIN_CHROMIUM").map(PathBuf::from);
    let found = named
        .into_iter()
        .chain(["/usr/bin/chromium", "/usr/bin/chromium-browser"].map(PathBuf::from))
        .find(|p| p.is_file());
    assert!(
        found.is_some(),
        "no Chromium: install Debian's `chromium`, set PEGTWIN_CHROMIUM, or set \
         PEGTWIN_SKIP_BROWSER_TESTS=1 to skip the browser tests"
    );
    found
}

/// A screenshot of `url` (1280 x 800), decoded to RGB.
fn screenshot(browser: &Path, url: &str, out: &Path) -> (u32, u32, Vec<u8>) {
    let profile = tempfile::tempdir().unwrap();
    let o = Command::new(browser)
        .args([
            "--headless",
            "--no-sandbox",
            "--use-angle=swiftshader",
            "--enable-unsafe-swiftshader",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
            "--no-first-run",
            "--hide-scrollbars",
            "--window-size=1280,800",
            "--virtual-time-budget=5000",
        ])
        .arg(format!("--user-data-dir={}", profile.path().display()))
        .arg(format!("--screenshot={}", out.display()))
        .arg(url)
        .output()
        .expect("chromium starts");
    assert!(out.is_file(), "no screenshot: {}", stderr(&o));
    let decoder = png::Decoder::new(std::fs::File::open(out).unwrap());
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut buf).unwrap();
    let channels = info.color_type.samples();
    let rgb = buf[..info.buffer_size()]
        .chunks(channels)
        .flat_map(|p| [p[0], p[1], p[2]])
        .collect();
    (info.width, info.height, rgb)
}

/// What a screenshot shows in the 3-D view (the left 75 %): how many pixels of each part's
/// colour, and where the peg's lie.
#[derive(Debug)]
struct Seen {
    peg: usize,
    hole: usize,
    arm: usize,
    peg_centroid: (f64, f64),
}

fn look(width: u32, height: u32, rgb: &[u8]) -> Seen {
    let mut seen = Seen {
        peg: 0,
        hole: 0,
        arm: 0,
        peg_centroid: (0.0, 0.0),
    };
    let (mut sx, mut sy) = (0.0, 0.0);
    for y in 0..(height * 9 / 10) {
        for x in 0..(width * 3 / 4) {
            let i = 3 * (y * width + x) as usize;
            let (r, g, b) = (rgb[i] as i32, rgb[i + 1] as i32, rgb[i + 2] as i32);
            let background = (r - 233).abs() < 6 && (g - 236).abs() < 6 && (b - 240).abs() < 6;
            if background {
                continue;
            }
            if r > 90 && r - b > 70 && g < r - 30 {
                seen.peg += 1;
                sx += x as f64;
                sy += y as f64;
            } else if b > r + 12 && b > 60 {
                seen.hole += 1;
            } else if (r - g).abs() < 8 && (g - b).abs() < 10 && r > 60 && r < 225 {
                seen.arm += 1;
            }
        }
    }
    if seen.peg > 0 {
        seen.peg_centroid = (sx / seen.peg as f64, sy / seen.peg as f64);
    }
    seen
}

#[test]
fn a_replay_draws_the_parts_in_headless_chromium_and_the_peg_moves() {
    let Some(browser) = chromium() else {
        eprintln!("PEGTWIN_SKIP_BROWSER_TESTS=1: browser test skipped");
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let (page, record) = write_replay(dir.path());
    let url = |t: &str| format!("file://{}#t={t}", page.display());
    let start = screenshot(&browser, &url("0.2"), &dir.path().join("start.png"));
    let end = screenshot(&browser, &url("1000"), &dir.path().join("end.png"));
    let (a, b) = (look(start.0, start.1, &start.2), look(end.0, end.1, &end.2));
    eprintln!("seen at the start: {a:?}\nseen at the end: {b:?}");
    for seen in [&a, &b] {
        assert!(seen.peg > 2_000, "the peg is not drawn: {seen:?}");
        assert!(seen.hole > 10_000, "the hole is not drawn: {seen:?}");
        assert!(seen.arm > 10_000, "the arm is not drawn: {seen:?}");
    }
    // The tip went from about 3 mm into the hole to the final depth (27 mm for this seed): in the
    // close-up (about 4 pixels per mm) the peg's pixels move down the picture.
    let depth = record["final_depth_mm"].as_f64().unwrap();
    assert!(
        depth > 15.0,
        "the test trial changed: final depth {depth} mm"
    );
    let moved = b.peg_centroid.1 - a.peg_centroid.1;
    assert!(moved > 20.0, "the peg did not move down: {a:?} then {b:?}");
}
