//! Curved and slanted parts (fillets, drafts, a rounded pin) cut into convex parts by CoACD
//! (Wei et al., "Approximate convex decomposition for 3D meshes with collision-aware concavity
//! and tree search", SIGGRAPH 2022), the field's collision-aware convex decomposition, run
//! through its Python package (`pip install coacd`; the interpreter is `$PEGTWIN_PYTHON`, else
//! `python3`). Its concavity threshold is chosen from the clearance: the parts may stand at
//! most a quarter of it off the surface (the limit `assembly check` refuses above); CoACD
//! measures concavity on the part scaled into a unit box, so the first threshold is a multiple
//! of that deviation over the part's half size, halved while the parts, measured as
//! `assembly check` measures them, stand further off. The result is cached by the mesh file's
//! checksum, its units and the clearance.

use crate::error::{Error, Result};
use crate::twin::geometry::mesh::{MeshUnits, approximation_deviation, read_mesh};
use crate::twin::geometry::solid::{ConvexPiece, P3, TriangleSoup};
use serde::{Deserialize, Serialize};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

/// The interpreter that runs CoACD: `$PEGTWIN_PYTHON`, else `python3`.
pub const PYTHON_VAR: &str = "PEGTWIN_PYTHON";
/// The script handed to it.
const SCRIPT: &str = include_str!("coacd.py");
/// CoACD's seed: its tree search is random.
const SEED: u64 = 0;
/// The first threshold, as a multiple of the deviation allowed over the part's half size:
/// CoACD's parts stood about 4.5 times closer to the surface than its threshold times the half
/// size (a filleted cross pin, 40 mm long: threshold 0.02, 0.09 mm), so this first try is
/// usually the coarsest that passes (fewest parts, fastest).
const START_OF_BOUND: f64 = 4.0;
/// CoACD's own default, never exceeded.
const COARSEST_THRESHOLD: f64 = 0.05;
/// Runs at most, halving the threshold after each whose parts stand too far off.
const RUNS: usize = 4;

/// A part cut into convex parts.
#[derive(Clone, Debug)]
pub struct Decomposition {
    pub pieces: Vec<ConvexPiece>,
    /// How far the pieces stand off the part's surface, m.
    pub deviation_m: f64,
    /// CoACD's concavity threshold (on the part scaled into a unit box).
    pub threshold: f64,
    /// Whether it came from the cache.
    pub cached: bool,
}

/// What the cache keeps beside the parts.
#[derive(Serialize, Deserialize)]
struct Meta {
    threshold: f64,
    deviation_m: f64,
    parts: usize,
}

/// Cuts the part in `file` (in `units`) into convex parts standing at most `max_deviation_m`
/// off its surface, or refuses; cached in `cache_dir`/coacd.
pub fn decompose(
    file: &Path,
    units: MeshUnits,
    max_deviation_m: f64,
    cache_dir: &Path,
) -> Result<Decomposition> {
    let soup = read_mesh(file, units)?;
    let bytes = std::fs::read(file).map_err(|e| Error::file(file, format!("cannot read: {e}")))?;
    let key = format!(
        "{}-{:08x}-{}-{:.1}um",
        file.file_stem().unwrap_or_default().to_string_lossy(),
        crc32fast::hash(&bytes),
        units.in_words().replace(' ', "_"),
        max_deviation_m * 1e6
    );
    let folder = cache_dir.join("coacd").join(key);
    if let Some(cached) = load_cached(&folder)? {
        return Ok(cached);
    }
    let (lo, hi) = bounds(&soup.vertices);
    let half_size = (hi - lo).amax() / 2.0;
    let mut threshold = (START_OF_BOUND * max_deviation_m / half_size).min(COARSEST_THRESHOLD);
    let mut made = cut(&soup, file, threshold)?;
    for _ in 1..RUNS {
        if made.deviation_m <= max_deviation_m {
            break;
        }
        threshold /= 2.0;
        made = cut(&soup, file, threshold)?;
    }
    if made.deviation_m > max_deviation_m {
        return Err(Error::file(
            file,
            format!(
                "CoACD's {} parts stand {:.4} mm off the surface at threshold {threshold:.5}, \
                 more than {:.4} mm (a quarter of the clearance): split the part by hand where \
                 it is curved, or give a larger clearance",
                made.pieces.len(),
                made.deviation_m * 1e3,
                max_deviation_m * 1e3
            ),
        ));
    }
    store(&folder, &made)?;
    // The parts as stored (single-precision STL), so that a first run and a cached one agree.
    let stored = load_cached(&folder)?.expect("just stored");
    Ok(Decomposition {
        cached: false,
        ..stored
    })
}

/// One CoACD run at `threshold`, its parts measured.
fn cut(soup: &TriangleSoup, file: &Path, threshold: f64) -> Result<Decomposition> {
    let parts = run_coacd(soup, file, threshold)?;
    let pieces = parts
        .iter()
        .filter_map(|points| ConvexPiece::from_points(points))
        .filter(|p| p.collider_shape().is_some())
        .collect::<Vec<_>>();
    if pieces.is_empty() {
        return Err(Error::file(
            file,
            "CoACD returned no convex part with volume",
        ));
    }
    let deviation_m = approximation_deviation(&pieces, soup, file)?;
    Ok(Decomposition {
        pieces,
        deviation_m,
        threshold,
        cached: false,
    })
}

#[derive(Deserialize)]
struct CoacdOut {
    parts: Vec<Vec<[f64; 3]>>,
}

/// Runs the script on the mesh; the parts' vertices, metres.
fn run_coacd(soup: &TriangleSoup, file: &Path, threshold: f64) -> Result<Vec<Vec<P3>>> {
    let python = std::env::var(PYTHON_VAR).unwrap_or_else(|_| "python3".into());
    let job = serde_json::json!({
        "vertices": soup.vertices.iter().map(|v| [v.x, v.y, v.z]).collect::<Vec<_>>(),
        "triangles": soup.triangles,
        "threshold": threshold,
        "seed": SEED,
    });
    let mut child = Command::new(&python)
        .args(["-c", SCRIPT])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .map_err(|e| {
            Error::file(
                file,
                format!("cannot run {python} for CoACD ({e}): install Python 3 and `pip install coacd`, or set {PYTHON_VAR}"),
            )
        })?;
    let mut stdin = child.stdin.take().expect("piped");
    let text = job.to_string();
    let writer = std::thread::spawn(move || stdin.write_all(text.as_bytes()));
    let out = child
        .wait_with_output()
        .map_err(|e| Error::file(file, format!("CoACD ({python}) failed: {e}")))?;
    let _ = writer.join();
    let said = String::from_utf8_lossy(&out.stderr);
    match out.status.code() {
        Some(0) => {}
        Some(3) => {
            return Err(Error::file(
                file,
                format!(
                    "CoACD is not installed for {python} ({}): `pip install coacd`, or set \
                     {PYTHON_VAR} to a Python that has it",
                    said.trim()
                ),
            ));
        }
        _ => {
            return Err(Error::file(
                file,
                format!("CoACD ({python}) failed: {}", said.trim()),
            ));
        }
    }
    let parsed: CoacdOut = serde_json::from_slice(&out.stdout).map_err(|e| {
        Error::file(
            file,
            format!("CoACD's output is not what was expected: {e}"),
        )
    })?;
    Ok(parsed
        .parts
        .into_iter()
        .map(|p| p.into_iter().map(|[x, y, z]| P3::new(x, y, z)).collect())
        .collect())
}

fn bounds(points: &[P3]) -> (nalgebra::Vector3<f64>, nalgebra::Vector3<f64>) {
    points.iter().fold(
        (
            nalgebra::Vector3::repeat(f64::MAX),
            nalgebra::Vector3::repeat(f64::MIN),
        ),
        |(lo, hi), p| (lo.inf(&p.coords), hi.sup(&p.coords)),
    )
}

/// The parts as binary STL in millimetres, `part_000.stl` on, in `dir` (made if missing).
pub fn write_parts(pieces: &[ConvexPiece], dir: &Path) -> Result<Vec<PathBuf>> {
    std::fs::create_dir_all(dir)
        .map_err(|e| Error::file(dir, format!("cannot create the folder: {e}")))?;
    pieces
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let path = dir.join(format!("part_{i:03}.stl"));
            p.to_mesh().write_stl_mm(&path)?;
            Ok(path)
        })
        .collect()
}

/// The cached decomposition: parts written first, `meta.json` last (its presence says whole).
fn load_cached(folder: &Path) -> Result<Option<Decomposition>> {
    let meta_path = folder.join("meta.json");
    if !meta_path.is_file() {
        return Ok(None);
    }
    let meta: Meta = serde_json::from_str(&crate::files::read_text(&meta_path)?)
        .map_err(|e| Error::file(&meta_path, format!("not a decomposition record: {e}")))?;
    let mut pieces = Vec::new();
    for i in 0..meta.parts {
        let path = folder.join(format!("part_{i:03}.stl"));
        let soup = read_mesh(&path, MeshUnits::Mm)?;
        let piece = ConvexPiece::from_points(&soup.vertices)
            .ok_or_else(|| Error::file(&path, "a cached part has no volume: delete the folder"))?;
        pieces.push(piece);
    }
    Ok(Some(Decomposition {
        pieces,
        deviation_m: meta.deviation_m,
        threshold: meta.threshold,
        cached: true,
    }))
}

fn store(folder: &Path, made: &Decomposition) -> Result<()> {
    write_parts(&made.pieces, folder)?;
    let meta = Meta {
        threshold: made.threshold,
        deviation_m: made.deviation_m,
        parts: made.pieces.len(),
    };
    let text = serde_json::to_string_pretty(&meta).expect("meta serialises");
    crate::files::write_atomically(&folder.join("meta.json"), text.as_bytes())
}
