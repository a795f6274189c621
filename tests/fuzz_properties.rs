//! The fuzz targets' properties (fuzz/harness.rs) on stable, in CI: every committed crash input
//! (fuzz/regressions/TARGET/) and every seed (fuzz/seeds/TARGET/) holds them, and so do
//! deterministic mutations of the seeds (bit flips, interesting bytes, cut, repeated and deleted
//! spans, numbers swapped for extreme ones). `cargo fuzz` explores further on nightly
//! (fuzz/README.md); set PEGTWIN_FUZZ_ITERATIONS to run more mutations here (per target) and
//! PEGTWIN_FUZZ_SEED for another sequence of them.

#[path = "../fuzz/harness.rs"]
mod harness;

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::path::{Path, PathBuf};

const DEFAULT_ITERATIONS: u64 = 400;

/// Numbers a hostile or careless file holds.
const EXTREME_NUMBERS: &[&str] = &[
    "1e308",
    "-1e308",
    "NaN",
    "nan",
    "inf",
    "-inf",
    "0",
    "-0",
    "1e-320",
    "4294967296",
    "18446744073709551616",
    "-1",
    "0.000001",
    "1000000",
    "99999999999999999999",
    "",
];

fn files(dir: &Path) -> Vec<(PathBuf, Vec<u8>)> {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return Vec::new();
    };
    let mut out: Vec<(PathBuf, Vec<u8>)> = entries
        .map(|e| e.expect("listable").path())
        .filter(|p| p.is_file())
        .map(|p| {
            let bytes = std::fs::read(&p).expect("readable");
            (p, bytes)
        })
        .collect();
    out.sort();
    out
}

fn fuzz_dir(kind: &str, target: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("fuzz")
        .join(kind)
        .join(target)
}

/// Runs a property on one input; a panic names the target and where the input was saved.
fn hold(target: &str, f: harness::Property, input: &[u8], label: &str) {
    if std::panic::catch_unwind(|| f(input)).is_err() {
        let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("fuzz-failures");
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join(format!("{target}-{label}"));
        std::fs::write(&path, input).unwrap();
        panic!(
            "{target}: input {label} breaks the property; saved to {}",
            path.display()
        );
    }
}

#[test]
fn every_seed_and_regression_input_holds_the_properties() {
    for (target, f) in harness::TARGETS {
        let seeds = files(&fuzz_dir("seeds", target));
        assert!(!seeds.is_empty(), "{target} has seeds");
        for kind in ["seeds", "regressions"] {
            for (path, bytes) in files(&fuzz_dir(kind, target)) {
                let name = path.file_name().unwrap().to_string_lossy().into_owned();
                hold(target, *f, &bytes, &name);
            }
        }
    }
}

/// One random edit of `data`.
fn mutate(rng: &mut ChaCha8Rng, data: &mut Vec<u8>) {
    let len = data.len();
    let at = |rng: &mut ChaCha8Rng| {
        if len == 0 {
            0
        } else {
            rng.random_range(0..len)
        }
    };
    match rng.random_range(0..7) {
        0 if len > 0 => {
            let i = at(rng);
            data[i] ^= 1 << rng.random_range(0..8);
        }
        1 if len > 0 => {
            let i = at(rng);
            data[i] = *b"\0\xff0-.e9\n,=[]\"<>/"
                .get(rng.random_range(0..16))
                .unwrap();
        }
        2 => {
            let i = at(rng);
            data.truncate(i);
        }
        3 if len > 0 => {
            let (a, n) = (at(rng), rng.random_range(1..64));
            let span: Vec<u8> = data[a..(a + n).min(len)].to_vec();
            let b = at(rng);
            data.splice(b..b, span);
        }
        4 if len > 0 => {
            let (a, n) = (at(rng), rng.random_range(1..64));
            data.drain(a..(a + n).min(len));
        }
        _ => swap_number(rng, data),
    }
}

/// Replaces one run of digits (with its sign, point and exponent) by an extreme number.
fn swap_number(rng: &mut ChaCha8Rng, data: &mut Vec<u8>) {
    let starts: Vec<usize> = (0..data.len())
        .filter(|&i| data[i].is_ascii_digit() && (i == 0 || !data[i - 1].is_ascii_digit()))
        .collect();
    if starts.is_empty() {
        return;
    }
    let a = starts[rng.random_range(0..starts.len())];
    let is_number = |c: &u8| c.is_ascii_digit() || b".eE+-".contains(c);
    let b = a + data[a..].iter().take_while(|c| is_number(c)).count();
    let with = EXTREME_NUMBERS[rng.random_range(0..EXTREME_NUMBERS.len())];
    data.splice(a..b, with.bytes());
}

#[test]
fn mutated_seeds_hold_the_properties() {
    let setting = |name: &str, default: u64| {
        std::env::var(name)
            .ok()
            .and_then(|v| v.parse().ok())
            .unwrap_or(default)
    };
    let iterations = setting("PEGTWIN_FUZZ_ITERATIONS", DEFAULT_ITERATIONS);
    let seed = setting("PEGTWIN_FUZZ_SEED", 18);
    for (k, (target, f)) in harness::TARGETS.iter().enumerate() {
        let seeds = files(&fuzz_dir("seeds", target));
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        rng.set_stream(k as u64);
        for i in 0..iterations {
            let mut data = seeds[rng.random_range(0..seeds.len())].1.clone();
            for _ in 0..rng.random_range(1..5) {
                mutate(&mut rng, &mut data);
            }
            hold(target, *f, &data, &format!("mutation-{i}"));
        }
    }
}
