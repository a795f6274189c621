//! Assembly files: a user's own peg and hole, described in TOML and loaded into the [`PartPair`]
//! every command takes (`--assembly FILE`), with what pegtwin measured of the fit
//! (`pegtwin assembly check FILE`).
//!
//! ```toml
//! name = "my-plug"
//! [peg]
//! mesh = "peg_parts/"         # a folder of convex STL/OBJ parts, or one STL/OBJ to decompose
//! units = "mm"                # or "m"
//! frame_xyz_mm = [0, 0, -25]  # the peg frame (tip centre, z up the peg) in the mesh's coordinates
//! frame_rpy_deg = [0, 0, 0]
//! [hole]
//! mesh = "hole_parts/"
//! units = "mm"
//! frame_xyz_mm = [0, 0, 0]    # the hole frame (mouth centre, z out of the hole)
//! ```
//!
//! A part may instead be a built-in (`builtin = "cross"`, with `clearance_mm` at the top). Paths
//! are relative to the file; orientations are R = Rz(yaw) Ry(pitch) Rx(roll). Nothing is taken on
//! trust: the clearance, the depth at which the peg is fully inserted and what stops it there
//! are measured (`measure`), a frame that puts the peg in the block or a hole upside down is an
//! error naming the field to change, and a part whose collision shape stands more than a quarter
//! of the measured clearance off its surface (a non-convex part in a convex-part folder) is
//! refused by name rather than simulated as a fatter part.

pub mod decompose;
pub mod measure;
pub mod mjcf;
mod mjcf_part;
mod robot;
pub use robot::RobotReport;

use crate::error::{Error, Result};
use crate::pose::rotation_rpy;
use crate::twin::geometry::mesh::{MeshUnits, load_solid, mesh_part, read_mesh};
use crate::twin::geometry::solid::{ConvexPiece, Solid};
use crate::twin::geometry::{self, PartPair};
use crate::twin::robot::spec::RobotSpec;
use measure::{Fit, FitError, Seat, measure_fit};
use nalgebra::{Isometry3, Translation3, UnitQuaternion};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// Density of a mesh peg whose file gives neither its density nor its mass: aluminium, kg/m^3.
pub const DEFAULT_DENSITY_KG_PER_M3: f64 = 2700.0;
/// Mass of a built-in peg named in an assembly file, kg (the built-ins' peg with its holder).
pub const BUILTIN_PEG_MASS_KG: f64 = 0.3;
/// How far in the peg must go before it stops, m: trials start 3 mm in and succeed within 2 mm.
pub const MIN_INSERTION_M: f64 = 5e-3;
/// How far from its frame's origin the peg's tip may lie, m.
const TIP_TOLERANCE_M: f64 = 1e-5;
/// A part's size must lie in this range (m) for its units to be believed.
const PART_SIZE_RANGE_M: (f64, f64) = (1e-3, 1.0);
/// A part standing further off its surface than this fraction of the clearance is refused.
pub const MAX_DEVIATION_OF_CLEARANCE: f64 = 0.25;
/// A part whose hull or exact stack cut stands no further than this off its surface is taken
/// as it is, even with `decompose = "coacd"`, m (rounding in the files is far below it).
const EXACT_PART_M: f64 = 1e-6;
/// A part whose hull stands this far off its surface is not convex, whatever the clearance, m.
const NON_CONVEX_M: f64 = 0.05e-3;
/// The peg's axis may stand this fraction of the clearance off the hole's, as the wall gaps
/// measure it (a design's uneven gaps, a polygonised arc, read as a small offset)...
pub const MAX_AXIS_OFFSET_OF_CLEARANCE: f64 = 0.08;
/// ... or this far, whichever is more, m.
pub const MIN_AXIS_OFFSET_M: f64 = 0.01e-3;
/// The peg's axis may lean this much to the hole's, as the wall gaps measure it, rad (0.1 deg).
pub const MAX_AXIS_TILT_RAD: f64 = 0.1 * std::f64::consts::PI / 180.0;

/// An assembly file as written.
#[derive(Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
struct AssemblyFile {
    name: String,
    /// Clearance of built-in parts, mm (a mesh pair's is measured).
    clearance_mm: Option<f64>,
    peg: PartEntry,
    hole: PartEntry,
    robot: Option<robot::RobotEntry>,
}

/// `[peg]` or `[hole]` as written.
#[derive(Debug, Default, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
struct PartEntry {
    mesh: Option<PathBuf>,
    builtin: Option<String>,
    /// An MJCF model whose `body` holds the part's geoms.
    mjcf: Option<PathBuf>,
    body: Option<String>,
    units: Option<MeshUnits>,
    /// `"coacd"`: cut a single mesh into convex parts with CoACD ([`decompose`]).
    decompose: Option<Decomposer>,
    #[serde(default)]
    frame_xyz_mm: [f64; 3],
    #[serde(default)]
    frame_rpy_deg: [f64; 3],
    /// Peg only: kg/m^3.
    density_kg_per_m3: Option<f64>,
    /// Peg only: kg, with whatever holds it; overrides the density.
    mass_kg: Option<f64>,
    /// Hole only: where a through hole counts the peg as inserted, mm below the mouth.
    success_depth_mm: Option<f64>,
}

/// How a single mesh that is neither convex nor a stack of extrusions is cut.
#[derive(Clone, Copy, Debug, Deserialize, Serialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
enum Decomposer {
    Coacd,
}

/// One part as loaded, in its own frame.
struct LoadedPart {
    solid: Solid,
    report: PartReport,
    /// Each input file and its deviation, m.
    deviations: Vec<(PathBuf, f64)>,
    warnings: Vec<String>,
}

/// What was loaded and measured of one part, for `assembly check`.
#[derive(Clone, Debug, Serialize)]
pub struct PartReport {
    /// The mesh path or `builtin NAME`.
    pub source: String,
    pub pieces: usize,
    /// Largest distance between the collision pieces and the input surface, mm.
    pub max_deviation_mm: f64,
    /// Size of the part's bounds in its frame (x, y, z), mm.
    pub size_mm: [f64; 3],
    /// Volume of its pieces, mm^3.
    pub volume_mm3: f64,
}

/// What `pegtwin assembly check` reports (mm, kg).
#[derive(Clone, Debug, Serialize)]
pub struct AssemblyReport {
    pub name: String,
    pub file: PathBuf,
    pub peg: PartReport,
    pub hole: PartReport,
    /// Diametral clearance (twice the smallest gap per side), mm: the pair's clearance.
    pub clearance_min_mm: f64,
    /// Twice the median over the engagement of each 0.5 mm slice's smallest gap, mm.
    pub clearance_median_mm: f64,
    pub gap_per_side_min_mm: f64,
    pub gap_per_side_median_mm: f64,
    /// Depths below the mouth over which the gap was measured (top, bottom), mm.
    pub gap_band_mm: [f64; 2],
    /// How far the peg's axis stands off the hole's, as the wall gaps measure it, mm (the
    /// clearance is measured as with the peg on the hole's axis).
    pub axis_offset_mm: f64,
    /// The angle between the peg's axis and the hole's, as the wall gaps measure it, deg.
    pub axis_tilt_deg: f64,
    /// How far the peg goes in before it stops, mm (`None`: a through hole).
    pub seat_depth_mm: Option<f64>,
    pub seat: Seat,
    /// Depth of the floor under the peg's tip, mm (`None`: no floor).
    pub cavity_depth_mm: Option<f64>,
    pub blind: bool,
    /// The tip's depth at full insertion, mm: success is within `success_mm` of it.
    pub insertion_depth_mm: f64,
    pub peg_mass_kg: f64,
    /// The robot that holds the peg, and where it starts.
    pub robot: RobotReport,
    pub warnings: Vec<String>,
}

/// A loaded assembly: the pair every command runs, the robot that holds the peg and what was
/// measured of them.
#[derive(Clone, Debug)]
pub struct Assembly {
    pub pair: PartPair,
    pub robot: RobotSpec,
    pub report: AssemblyReport,
}

/// The robot of the assembly file at `path` (the built-in iiwa 14 when it has no `[robot]`),
/// read without loading the parts.
pub fn robot_of(path: &Path) -> Result<RobotSpec> {
    let text = crate::files::read_text(path)?;
    let file = parse(&text).map_err(|msg| Error::file(path, msg))?;
    robot::spec(
        file.robot.as_ref(),
        path.parent().unwrap_or(Path::new(".")),
        path,
    )
}

/// Reads an assembly file, loads its parts into their frames, measures the fit and checks it.
pub fn load(path: &Path) -> Result<Assembly> {
    let text = crate::files::read_text(path)?;
    let file = parse(&text).map_err(|msg| Error::file(path, msg))?;
    let dir = path.parent().unwrap_or(Path::new("."));
    check_entries(&file).map_err(|msg| Error::file(path, msg))?;
    let robot = robot::spec(file.robot.as_ref(), dir, path)?;
    let in_file = |e: Error| match e {
        Error::Input(msg) => Error::file(path, msg),
        other => other,
    };
    let sources = [&file.peg, &file.hole].map(|e| mjcf_source(e, dir));
    let (peg_geoms, hole_geoms, pair_warnings) =
        mjcf_part::paired_geoms(sources[0].as_ref(), sources[1].as_ref())?;
    let mut peg =
        load_part("peg", &file.peg, dir, file.clearance_mm, peg_geoms).map_err(in_file)?;
    let hole =
        load_part("hole", &file.hole, dir, file.clearance_mm, hole_geoms).map_err(in_file)?;
    peg.warnings.extend(pair_warnings);
    check_frames(&peg.solid, &hole.solid).map_err(|msg| Error::file(path, msg))?;
    let max_depth = -hole.solid.bounds().0.z + peg.solid.bounds().1.z;
    let fit =
        measure_fit(&peg.solid, &hole.solid, 1e-3, (MIN_INSERTION_M, max_depth)).map_err(|e| {
            // A hulled non-convex part is the likelier cause than the frames: say so first.
            let cause = not_convex(&peg, &hole, NON_CONVEX_M, "").unwrap_or_default();
            Error::file(path, format!("{cause}{}", fit_error(e)))
        })?;
    check_alignment(&fit).map_err(|msg| Error::file(path, msg))?;
    check_fit(&fit, &peg, &hole).map_err(|msg| Error::file(path, msg))?;
    let insertion_depth_m =
        insertion_depth(&fit, &file.hole, &peg.solid).map_err(|msg| Error::file(path, msg))?;
    let peg_mass_kg = peg_mass(&file.peg, &peg.solid);
    let clearance_m = round_to_tenth_um(2.0 * fit.gap_min_m);
    let mut pair = PartPair {
        name: file.name,
        clearance_m,
        chord_error_m: 0.0,
        content_key: Some(content_key(
            &peg.solid,
            &hole.solid,
            peg_mass_kg,
            insertion_depth_m,
        )),
        peg: peg.solid.clone(),
        hole: hole.solid.clone(),
        cavity_depth_m: insertion_depth_m,
        seat: fit.seat,
        peg_mass_kg: Some(peg_mass_kg),
        print: None,
    };
    let robot_check = robot::check_reach(&robot, &pair, path)?;
    if let (Some(key), Some(robot_key)) = (pair.content_key.as_mut(), &robot_check.key) {
        // The manifold is sampled by the robot: another robot is another cached file.
        *key = format!("{key}-{robot_key}");
    }
    let report = report(path, &fit, &pair, (peg, hole), robot_check);
    Ok(Assembly {
        pair,
        robot,
        report,
    })
}

/// What `assembly check` prints of a loaded `pair`, its parts, its fit and its robot.
fn report(
    path: &Path,
    fit: &Fit,
    pair: &PartPair,
    (peg, hole): (LoadedPart, LoadedPart),
    robot: robot::RobotCheck,
) -> AssemblyReport {
    let warnings = [peg.warnings, hole.warnings, robot.warnings].concat();
    AssemblyReport {
        name: pair.name.clone(),
        file: path.to_path_buf(),
        clearance_min_mm: pair.clearance_mm(),
        clearance_median_mm: 2.0 * fit.gap_median_m * 1e3,
        gap_per_side_min_mm: fit.gap_min_m * 1e3,
        gap_per_side_median_mm: fit.gap_median_m * 1e3,
        gap_band_mm: [fit.gap_band_m.0 * 1e3, fit.gap_band_m.1 * 1e3],
        axis_offset_mm: fit.axis.offset_norm_m() * 1e3,
        axis_tilt_deg: fit.axis.tilt_rad().to_degrees(),
        seat_depth_mm: fit.seat_depth_m.map(|d| d * 1e3),
        seat: fit.seat,
        cavity_depth_mm: fit.cavity_depth_m.map(|d| d * 1e3),
        blind: fit.cavity_depth_m.is_some(),
        insertion_depth_mm: pair.cavity_depth_m * 1e3,
        peg_mass_kg: pair.peg_mass_kg.unwrap_or_default(),
        robot: robot.report,
        warnings,
        peg: peg.report,
        hole: hole.report,
    }
}

/// The file's TOML, with the line of the first error.
fn parse(text: &str) -> std::result::Result<AssemblyFile, String> {
    crate::toml_input::parse(text)
}

/// Checks the fields that need no mesh: the name, which fields each part may have.
fn check_entries(file: &AssemblyFile) -> std::result::Result<(), String> {
    let name_ok = !file.name.is_empty()
        && file
            .name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || "-_.".contains(c));
    if !name_ok {
        return Err(format!(
            "name = {:?}: expected letters, digits, '-', '_' or '.' (it names cached files)",
            file.name
        ));
    }
    let builtin = file.peg.builtin.is_some() || file.hole.builtin.is_some();
    let decompose = file.peg.decompose.is_some() || file.hole.decompose.is_some();
    match file.clearance_mm {
        Some(c) if !builtin && !decompose => {
            return Err(format!(
                "clearance_mm = {c}: only for built-in parts and decompose = \"coacd\"; a mesh \
                 pair's clearance is measured"
            ));
        }
        Some(c) => geometry::check_clearance(c * 1e-3).map_err(|e| format!("clearance_mm: {e}"))?,
        None if builtin => {
            return Err("clearance_mm: a built-in part needs the clearance to build it at".into());
        }
        None if decompose => {
            return Err(
                "clearance_mm: decompose = \"coacd\" needs the pair's design clearance (its \
                 threshold follows it; the measured clearance then checks the parts)"
                    .into(),
            );
        }
        None => {}
    }
    for (section, e) in [("peg", &file.peg), ("hole", &file.hole)] {
        check_entry(section, e)?;
    }
    Ok(())
}

fn check_entry(section: &str, e: &PartEntry) -> std::result::Result<(), String> {
    let given = [e.mesh.is_some(), e.builtin.is_some(), e.mjcf.is_some()];
    if given.iter().filter(|g| **g).count() != 1 {
        return Err(format!(
            "[{section}]: give one of mesh = \"PATH\", builtin = \"NAME\" or mjcf = \"FILE\" \
             with body = \"NAME\""
        ));
    }
    if e.mesh.is_some() && e.units.is_none() {
        return Err(format!(
            "{section}.units: missing: say \"mm\" or \"m\" (mesh files carry no unit)"
        ));
    }
    let one_file = |m: &PathBuf| {
        m.extension().is_some_and(|x| {
            ["stl", "obj"].contains(&x.to_ascii_lowercase().to_str().unwrap_or(""))
        })
    };
    if e.decompose.is_some() && !e.mesh.as_ref().is_some_and(one_file) {
        return Err(format!(
            "{section}.decompose: only for mesh = \"ONE FILE.stl|obj\" (a folder's parts are \
             convex already)"
        ));
    }
    if e.mjcf.is_some() != e.body.is_some() {
        return Err(format!(
            "{section}.body: give it with mjcf = \"FILE\" (the body whose geoms make the part), \
             and only then"
        ));
    }
    let misplaced = match section {
        "peg" => e.success_depth_mm.map(|_| "success_depth_mm"),
        _ => e
            .density_kg_per_m3
            .map(|_| "density_kg_per_m3")
            .or(e.mass_kg.map(|_| "mass_kg")),
    };
    if let Some(field) = misplaced {
        return Err(format!("{section}.{field}: not a field of [{section}]"));
    }
    for (field, v, max) in [
        (
            "frame_xyz_mm",
            e.frame_xyz_mm,
            crate::pose::MAX_COORDINATE_M * 1e3,
        ),
        ("frame_rpy_deg", e.frame_rpy_deg, 360.0),
    ] {
        if !v.iter().all(|x| x.abs() <= max) {
            return Err(format!(
                "{section}.{field} = {v:?}: expected values within +-{max}"
            ));
        }
    }
    for (field, v, max) in [
        ("density_kg_per_m3", e.density_kg_per_m3, 30_000.0),
        ("mass_kg", e.mass_kg, crate::twin::workcell::MAX_PEG_MASS_KG),
        ("success_depth_mm", e.success_depth_mm, 1000.0),
    ] {
        if let Some(v) = v.filter(|v| !(*v > 0.0 && *v <= max)) {
            return Err(format!(
                "{section}.{field} = {v}: expected more than 0 and at most {max}"
            ));
        }
    }
    Ok(())
}

/// A part as read from its source, before it is moved into its frame.
struct ReadPart {
    solid: Solid,
    /// The mesh path, `builtin NAME` or the MJCF file and body.
    source: String,
    /// Each input file and its deviation, m.
    deviations: Vec<(PathBuf, f64)>,
    warnings: Vec<String>,
}

/// Where an entry's MJCF geoms come from, if it names a model.
fn mjcf_source<'a>(e: &'a PartEntry, dir: &Path) -> Option<mjcf_part::Source<'a>> {
    Some(mjcf_part::Source {
        file: dir.join(e.mjcf.as_ref()?),
        body: e.body.as_deref()?,
    })
}

/// Loads a part (mesh, built-in or the MJCF body's `geoms`) and moves it into its frame.
fn load_part(
    section: &str,
    e: &PartEntry,
    dir: &Path,
    clearance_mm: Option<f64>,
    geoms: Option<Vec<mjcf::Geom>>,
) -> Result<LoadedPart> {
    let read = read_part(section, e, dir, clearance_mm, geoms)?;
    let solid = Solid {
        pieces: move_into_frame(&read.solid.pieces, e),
        boundary: read
            .solid
            .boundary
            .filter(|_| e.builtin.is_some() && is_identity(e)),
    };
    let (lo, hi) = solid.bounds();
    let size = hi - lo;
    check_size(section, e, size.amax())?;
    check_solid(section, &solid, size.amin())?;
    let report = PartReport {
        source: read.source,
        pieces: solid.pieces.len(),
        max_deviation_mm: read.deviations.iter().map(|d| d.1).fold(0.0, f64::max) * 1e3,
        size_mm: [size.x * 1e3, size.y * 1e3, size.z * 1e3],
        volume_mm3: solid.pieces_volume_m3() * 1e9,
    };
    Ok(LoadedPart {
        solid,
        report,
        deviations: read.deviations,
        warnings: read.warnings,
    })
}

/// Reads a part from its mesh, built-in or MJCF body, in the source's own coordinates.
fn read_part(
    section: &str,
    e: &PartEntry,
    dir: &Path,
    clearance_mm: Option<f64>,
    geoms: Option<Vec<mjcf::Geom>>,
) -> Result<ReadPart> {
    let part = |solid, source, deviations, warnings| ReadPart {
        solid,
        source,
        deviations,
        warnings,
    };
    Ok(match (&e.mesh, &e.builtin) {
        (Some(mesh), _) if e.decompose.is_some() => {
            let units = e.units.expect("checked: a mesh has units");
            let c = clearance_mm.expect("checked: decompose comes with a clearance") * 1e-3;
            decomposed_mesh(&dir.join(mesh), units, c)?
        }
        (Some(mesh), _) => {
            let path = dir.join(mesh);
            let units = e.units.expect("checked: a mesh has units");
            let loaded = load_solid(&path, units, f64::INFINITY).map_err(|e| match e {
                Error::File { path, msg } => Error::file(path, format!("{msg} ([{section}])")),
                other => other,
            })?;
            let source = path.display().to_string();
            part(
                loaded.solid,
                source,
                loaded.part_deviations,
                loaded.warnings,
            )
        }
        (None, Some(name)) => {
            let builtin = geometry::builtin_by_name(name)
                .map_err(|err| Error::Input(format!("{section}.builtin: {err}")))?;
            let c = clearance_mm.expect("checked: built-ins come with a clearance") * 1e-3;
            let pair = geometry::build_builtin(builtin, c)?;
            let solid = if section == "peg" {
                pair.peg
            } else {
                pair.hole
            };
            part(solid, format!("builtin {name}"), Vec::new(), Vec::new())
        }
        (None, None) => {
            let file = dir.join(e.mjcf.as_ref().expect("checked: one source"));
            let body = e.body.as_deref().expect("checked: mjcf comes with body");
            let geoms = geoms.expect("an MJCF part's geoms are read with the other part's");
            let read = mjcf_part::solid(&file, geoms, e.units)?;
            let source = format!("{} body {body}", file.display());
            part(read.solid, source, read.deviations, Vec::new())
        }
    })
}

/// A mesh part whose `decompose` is set: its exact pieces when it is convex or a stack of
/// extrusions, else CoACD's cut to a deviation within the share of the clearance `clearance_m`
/// allows (with a warning saying so).
fn decomposed_mesh(path: &Path, units: MeshUnits, clearance_m: f64) -> Result<ReadPart> {
    let exact = mesh_part(&read_mesh(path, units)?, path)?;
    let source = path.display().to_string();
    if exact.deviation_m <= EXACT_PART_M {
        return Ok(ReadPart {
            solid: Solid {
                pieces: exact.pieces,
                boundary: None,
            },
            source,
            deviations: vec![(path.to_path_buf(), exact.deviation_m)],
            warnings: Vec::new(),
        });
    }
    let cache = crate::files::cache_folder(None)?;
    let threshold_m = clearance_m * MAX_DEVIATION_OF_CLEARANCE;
    let cut = decompose::decompose(path, units, threshold_m, &cache)?;
    let warning = format!(
        "{}: cut by CoACD into {} convex parts at threshold {:.5}, {:.4} mm off its surface{}",
        path.display(),
        cut.pieces.len(),
        cut.threshold,
        cut.deviation_m * 1e3,
        if cut.cached { " (cached)" } else { "" }
    );
    Ok(ReadPart {
        solid: Solid {
            pieces: cut.pieces,
            boundary: None,
        },
        source,
        deviations: vec![(path.to_path_buf(), cut.deviation_m)],
        warnings: vec![warning],
    })
}

fn is_identity(e: &PartEntry) -> bool {
    e.frame_xyz_mm == [0.0; 3] && e.frame_rpy_deg == [0.0; 3]
}

/// The pieces, given in the mesh's coordinates, in the part's frame (whose pose in those
/// coordinates the entry gives).
fn move_into_frame(pieces: &[ConvexPiece], e: &PartEntry) -> Vec<ConvexPiece> {
    let [x, y, z] = e.frame_xyz_mm.map(|v| v * 1e-3);
    let [r, p, yaw] = e.frame_rpy_deg.map(f64::to_radians);
    let mesh_t_frame = Isometry3::from_parts(
        Translation3::new(x, y, z),
        UnitQuaternion::from_rotation_matrix(&rotation_rpy(r, p, yaw)),
    );
    let frame_t_mesh = mesh_t_frame.inverse();
    pieces
        .iter()
        .map(|p| p.transformed(&frame_t_mesh))
        .collect()
}

/// A part thinner than this in any direction is not a part, m.
const MIN_PART_THICKNESS_M: f64 = 0.1e-3;
/// A convex piece with no more volume than this is flat, m^3 (a 0.01 mm cube).
const MIN_PIECE_VOLUME_M3: f64 = 1e-15;

/// A part smaller than 1 mm or larger than 1 m has its units wrong.
fn check_size(section: &str, e: &PartEntry, size_m: f64) -> Result<()> {
    let (lo, hi) = PART_SIZE_RANGE_M;
    if size_m >= lo && size_m <= hi {
        return Ok(());
    }
    let units = e.units.map_or("", MeshUnits::in_words);
    Err(Error::Input(format!(
        "{section}.units: the {section} measures {:.4} m across, read as {units}: expected a part \
         between {} mm and {} m (are the units right?)",
        size_m,
        lo * 1e3,
        hi
    )))
}

/// A part must be a solid: no piece without volume (a flat mesh, a lone triangle), and at least
/// [`MIN_PART_THICKNESS_M`] across in every direction.
fn check_solid(section: &str, solid: &Solid, thinnest_m: f64) -> Result<()> {
    let flat = solid
        .pieces
        .iter()
        .position(|p| p.volume().is_nan() || p.volume() <= MIN_PIECE_VOLUME_M3);
    if let Some(k) = flat {
        return Err(Error::Input(format!(
            "{section}.mesh: convex piece {k} of the {section} has no volume (a flat mesh or a \
             lone triangle): expected closed solids"
        )));
    }
    if thinnest_m.is_nan() || thinnest_m < MIN_PART_THICKNESS_M {
        return Err(Error::Input(format!(
            "{section}.mesh: the {section} is {:.4} mm thick at its thinnest: expected a solid at \
             least {} mm across in every direction",
            thinnest_m * 1e3,
            MIN_PART_THICKNESS_M * 1e3
        )));
    }
    Ok(())
}

/// The peg's tip at its frame's origin, the hole below its mouth.
fn check_frames(peg: &Solid, hole: &Solid) -> std::result::Result<(), String> {
    let (lo, _) = peg.bounds();
    if lo.z.abs() > TIP_TOLERANCE_M {
        let (dir, d) = if lo.z < 0.0 {
            ("below", -lo.z)
        } else {
            ("above", lo.z)
        };
        return Err(format!(
            "peg.frame_xyz_mm: the peg's lowest point lies {:.3} mm {dir} its frame's origin: the \
             peg frame sits at the centre of the peg's tip, z up the peg",
            d * 1e3
        ));
    }
    let (lo, hi) = hole.bounds();
    if hi.z > -lo.z {
        return Err(format!(
            "hole.frame_rpy_deg: the hole reaches {:.3} mm above its mouth and {:.3} mm below: \
             the hole frame's z points out of the hole (turn it over, e.g. roll 180)",
            hi.z * 1e3,
            -lo.z * 1e3
        ));
    }
    Ok(())
}

fn fit_error(e: FitError) -> String {
    match e {
        FitError::IntersectsAt { depth_m } => format!(
            "peg.frame_xyz_mm / hole.frame_xyz_mm: with its tip {:.1} mm above the mouth the peg \
             already intersects the hole: the two frames must line the peg up over the hole",
            -depth_m * 1e3
        ),
        FitError::StopsAt { depth_m } => format!(
            "peg.frame_xyz_mm / hole.frame_xyz_mm: the peg stops {:.3} mm below the mouth; \
             expected at least {} mm (are the frames lined up on the hole's axis?)",
            depth_m * 1e3,
            MIN_INSERTION_M * 1e3
        ),
        FitError::NoEngagement => {
            "the peg's side never faces the hole's walls: is the hole open at its frame's origin?"
                .into()
        }
    }
}

/// The frames must put the peg on the hole's axis: a peg off it or leaning to it would be
/// measured as a tighter fit than it is, seat short and count a wrong pose as the hole's.
fn check_alignment(fit: &Fit) -> std::result::Result<(), String> {
    let axis = &fit.axis;
    let band = format!(
        "measured from the wall gaps {:.1}-{:.1} mm below the mouth",
        fit.gap_band_m.0 * 1e3,
        fit.gap_band_m.1 * 1e3
    );
    if axis.tilt_rad() > MAX_AXIS_TILT_RAD {
        return Err(format!(
            "peg.frame_rpy_deg / hole.frame_rpy_deg: the peg's axis leans {:.2} deg to the \
             hole's (x {:+.5}, y {:+.5} per unit depth, {band}): the two frames' z axes must run \
             along the hole's axis within {:.1} deg",
            axis.tilt_rad().to_degrees(),
            axis.tilt[0],
            axis.tilt[1],
            MAX_AXIS_TILT_RAD.to_degrees()
        ));
    }
    let limit = MIN_AXIS_OFFSET_M.max(MAX_AXIS_OFFSET_OF_CLEARANCE * 2.0 * fit.gap_min_m);
    if axis.offset_norm_m() > limit {
        return Err(format!(
            "peg.frame_xyz_mm / hole.frame_xyz_mm: the peg's axis stands {:.3} mm off the \
             hole's (x {:+.3}, y {:+.3} mm in the hole frame, {band}): the two frames must \
             put the peg on the hole's axis within {:.3} mm ({} % of the clearance)",
            axis.offset_norm_m() * 1e3,
            axis.offset_m[0] * 1e3,
            axis.offset_m[1] * 1e3,
            limit * 1e3,
            MAX_AXIS_OFFSET_OF_CLEARANCE * 100.0,
        ));
    }
    Ok(())
}

/// Every part must be convex to a quarter of the clearance.
fn check_fit(fit: &Fit, peg: &LoadedPart, hole: &LoadedPart) -> std::result::Result<(), String> {
    let limit = MAX_DEVIATION_OF_CLEARANCE * 2.0 * fit.gap_min_m;
    let measured = format!(
        ", more than a quarter of the measured clearance ({:.3} mm)",
        2.0 * fit.gap_min_m * 1e3
    );
    match not_convex(peg, hole, limit, &measured) {
        Some(msg) => Err(msg.trim_end().to_string()),
        None => Ok(()),
    }
}

/// The first part whose collision shape stands more than `limit_m` off its surface, as a
/// message (`why` says what the limit is).
fn not_convex(peg: &LoadedPart, hole: &LoadedPart, limit_m: f64, why: &str) -> Option<String> {
    [("peg", peg), ("hole", hole)].iter().find_map(|(section, part)| {
        let (file, dev) = part.deviations.iter().find(|(_, d)| *d > limit_m)?;
        Some(format!(
            "{section}.mesh: {}: its collision shape stands {:.3} mm off its surface{why}: it is \
             not convex; split it into convex parts (CoACD, V-HACD). ",
            file.display(),
            dev * 1e3,
        ))
    })
}

/// The tip's depth at full insertion: where the peg seats, or the file's for a through hole.
fn insertion_depth(fit: &Fit, hole: &PartEntry, peg: &Solid) -> std::result::Result<f64, String> {
    match (fit.seat_depth_m, hole.success_depth_mm) {
        (Some(d), None) => Ok(d),
        (Some(d), Some(s)) => Err(format!(
            "hole.success_depth_mm = {s}: the peg seats {:.3} mm in ({}); the field is for \
             through holes",
            d * 1e3,
            match fit.seat {
                Seat::TipOnFloor => "tip on the floor",
                _ => "flange on the block",
            }
        )),
        (None, None) => Err(
            "hole.success_depth_mm: missing: nothing stops the peg in this \
                             through hole, so say how deep (mm below the mouth) counts as inserted"
                .into(),
        ),
        (None, Some(s)) => {
            let reach = peg.bounds().1.z * 1e3;
            if s >= MIN_INSERTION_M * 1e3 && s < reach {
                Ok(s * 1e-3)
            } else {
                Err(format!(
                    "hole.success_depth_mm = {s}: expected at least {} mm and less than the \
                     peg's length, {reach:.3} mm",
                    MIN_INSERTION_M * 1e3
                ))
            }
        }
    }
}

/// The peg's mass: the file's, else its volume times its density (a built-in peg: 0.3 kg).
fn peg_mass(e: &PartEntry, peg: &Solid) -> f64 {
    if let Some(m) = e.mass_kg {
        return m;
    }
    if e.builtin.is_some() && e.density_kg_per_m3.is_none() {
        return BUILTIN_PEG_MASS_KG;
    }
    peg.pieces_volume_m3() * e.density_kg_per_m3.unwrap_or(DEFAULT_DENSITY_KG_PER_M3)
}

fn round_to_tenth_um(v: f64) -> f64 {
    (v * 1e7).round() / 1e7
}

/// A checksum of the pieces as placed, the mass and the insertion depth.
fn content_key(peg: &Solid, hole: &Solid, mass_kg: f64, depth_m: f64) -> String {
    let mut h = crc32fast::Hasher::new();
    for piece in peg.pieces.iter().chain(&hole.pieces) {
        for v in &piece.vertices {
            for c in v.iter() {
                h.update(&c.to_bits().to_le_bytes());
            }
        }
        h.update(b"|");
    }
    h.update(&mass_kg.to_bits().to_le_bytes());
    h.update(&depth_m.to_bits().to_le_bytes());
    format!("{:08x}", h.finalize())
}

/// Which pair a command runs: a built-in at a clearance, or an assembly file.
#[derive(Clone, Debug, PartialEq)]
pub enum PairSource {
    /// A built-in by name at a diametral clearance in mm.
    Builtin { name: String, clearance_mm: f64 },
    /// An assembly file.
    Assembly(PathBuf),
}

impl PairSource {
    /// The pair, checked, with the loaders' warnings.
    pub fn load(&self) -> Result<(PartPair, Vec<String>)> {
        match self {
            PairSource::Builtin { name, clearance_mm } => {
                let clearance_m = clearance_mm * 1e-3;
                geometry::check_clearance(clearance_m)?;
                let pair = geometry::build_builtin(geometry::builtin_by_name(name)?, clearance_m)?;
                Ok((pair, Vec::new()))
            }
            PairSource::Assembly(path) => {
                let assembly = load(path)?;
                Ok((assembly.pair, assembly.report.warnings))
            }
        }
    }

    /// The robot that holds the peg: the assembly file's, else the built-in iiwa 14.
    pub fn robot(&self) -> Result<RobotSpec> {
        match self {
            PairSource::Builtin { .. } => Ok(RobotSpec::default()),
            PairSource::Assembly(path) => robot_of(path),
        }
    }
}
