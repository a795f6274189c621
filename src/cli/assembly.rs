//! `pegtwin assembly check`: an assembly file loaded and measured, printed; `pegtwin assembly
//! mjcf`: the collision geoms pegtwin reads from a MuJoCo model's body.

use clap::Subcommand;
use pegtwin::error::{Error, Result};
use pegtwin::twin::assembly::decompose;
use pegtwin::twin::assembly::measure::Seat;
use pegtwin::twin::assembly::{AssemblyReport, PartReport, load};
use pegtwin::twin::geometry::check_clearance;
use pegtwin::twin::geometry::mesh::MeshUnits;
use std::path::{Path, PathBuf};

#[derive(Subcommand)]
pub enum AssemblyAction {
    /// Load an assembly file, measure its fit (clearance, insertion depth, what stops the peg,
    /// blind or through) and check its frames; exit 2 with the field to change if something is
    /// wrong.
    Check {
        /// The assembly file (TOML).
        file: PathBuf,
        /// Print the report as JSON.
        #[arg(long)]
        json: bool,
    },
    /// Print, as JSON lines, the collision geoms pegtwin reads from one body of a MuJoCo model
    /// (MJCF): each geom's type, MuJoCo size, pose in the body's frame (pos, quat w x y z, model
    /// units) and collision bits, and a mesh geom's vertices in the body's frame.
    /// Cut one part that is neither convex nor a stack of extrusions (fillets, drafts, slanted
    /// faces) into convex parts with CoACD (`pip install coacd`; `$PEGTWIN_PYTHON` names the
    /// interpreter), its threshold chosen so that the parts stand at most a quarter of the
    /// clearance off the surface (measured, refused above); written as STL in mm for
    /// `mesh = "DIR"`, `units = "mm"`.
    Decompose {
        /// The part: one STL or OBJ file.
        part: PathBuf,
        /// The part's length unit: mm or m.
        #[arg(long, value_parser = parse_units)]
        units: MeshUnits,
        /// The pair's clearance, mm (diametral).
        #[arg(long = "clearance-mm")]
        clearance_mm: f64,
        /// The folder the convex parts are written to (part_000.stl, ...).
        #[arg(long)]
        out: PathBuf,
        /// Where decompositions are cached (default: $XDG_CACHE_HOME/pegtwin, else
        /// ~/.cache/pegtwin).
        #[arg(long = "cache-dir")]
        cache_dir: Option<PathBuf>,
    },
    Mjcf {
        /// The MJCF file.
        file: PathBuf,
        /// The body whose geoms (and its child bodies') make the part.
        #[arg(long)]
        body: String,
    },
}

pub fn assembly_command(action: AssemblyAction) -> Result<i32> {
    match action {
        AssemblyAction::Check { file, json } => {
            let report = load(&file)?.report;
            if json {
                let text = serde_json::to_string_pretty(&report).expect("report serialises");
                println!("{text}");
            } else {
                print_report(&report);
            }
            Ok(0)
        }
        AssemblyAction::Decompose {
            part,
            units,
            clearance_mm,
            out,
            cache_dir,
        } => decompose(&part, units, clearance_mm, &out, cache_dir.as_deref()),
        AssemblyAction::Mjcf { file, body } => {
            for geom in pegtwin::twin::assembly::mjcf::report(&file, &body)? {
                println!(
                    "{}",
                    serde_json::to_string(&geom).expect("report serialises")
                );
            }
            Ok(0)
        }
    }
}

fn parse_units(text: &str) -> std::result::Result<MeshUnits, String> {
    match text {
        "mm" => Ok(MeshUnits::Mm),
        "m" => Ok(MeshUnits::M),
        other => Err(format!("'{other}': expected mm or m")),
    }
}

fn decompose(
    part: &Path,
    units: MeshUnits,
    clearance_mm: f64,
    out: &Path,
    cache_dir: Option<&Path>,
) -> Result<i32> {
    let clearance_m = clearance_mm * 1e-3;
    check_clearance(clearance_m).map_err(|e| Error::Input(format!("--clearance-mm: {e}")))?;
    if out.exists() && std::fs::read_dir(out).map_or(true, |mut d| d.next().is_some()) {
        return Err(Error::file(out, "--out: expected a new or empty folder"));
    }
    let cache = pegtwin::files::cache_folder(cache_dir)?;
    let max_deviation_m = clearance_m * pegtwin::twin::assembly::MAX_DEVIATION_OF_CLEARANCE;
    let cut = decompose::decompose(part, units, max_deviation_m, &cache)?;
    let written = decompose::write_parts(&cut.pieces, out)?;
    println!(
        "{}: {} convex parts (CoACD threshold {:.5}{}), {:.4} mm off its surface (at most {:.4} mm, a quarter of {clearance_mm} mm)",
        part.display(),
        written.len(),
        cut.threshold,
        if cut.cached { ", cached" } else { "" },
        cut.deviation_m * 1e3,
        max_deviation_m * 1e3
    );
    println!(
        "written to {} in mm: in an assembly file, mesh = \"{}\" with units = \"mm\"",
        out.display(),
        out.display()
    );
    Ok(0)
}

fn print_part(role: &str, p: &PartReport) {
    println!(
        "{role:<5} {}: {} convex pieces, {:.1} x {:.1} x {:.1} mm, {:.0} mm^3, deviation from its surface {:.4} mm",
        p.source,
        p.pieces,
        p.size_mm[0],
        p.size_mm[1],
        p.size_mm[2],
        p.volume_mm3,
        p.max_deviation_mm
    );
}

fn print_report(r: &AssemblyReport) {
    println!("assembly {} ({})", r.name, r.file.display());
    print_part("peg", &r.peg);
    print_part("hole", &r.hole);
    println!(
        "clearance (diametral): {:.4} mm minimum, {:.4} mm median over the engagement (gap per side {:.4} / {:.4} mm, measured {:.1} to {:.1} mm below the mouth)",
        r.clearance_min_mm,
        r.clearance_median_mm,
        r.gap_per_side_min_mm,
        r.gap_per_side_median_mm,
        r.gap_band_mm[0],
        r.gap_band_mm[1]
    );
    println!(
        "axes: the peg's {:.4} mm off the hole's, leaning {:.3} deg to it (as the wall gaps measure them)",
        r.axis_offset_mm, r.axis_tilt_deg
    );
    let seat = match (r.seat, r.seat_depth_mm) {
        (Seat::TipOnFloor, Some(d)) => format!("stops {d:.3} mm in, its tip on the floor"),
        (Seat::FlangeOnBlock, Some(d)) => format!("stops {d:.3} mm in, its flange on the block"),
        _ => "passes through: nothing stops it".into(),
    };
    println!("the peg, pushed straight in, {seat}");
    match r.cavity_depth_mm {
        Some(d) => {
            println!("blind hole: the floor under the peg's tip is {d:.3} mm below the mouth")
        }
        None => println!("through hole: no floor under the peg's tip"),
    }
    println!(
        "full insertion: tip {:.3} mm below the mouth (success within the scenario's success_mm of it)",
        r.insertion_depth_mm
    );
    println!(
        "peg mass {:.4} kg; the peg starts clear of the hole (checked from 1 mm above the mouth to 5 mm in)",
        r.peg_mass_kg
    );
    let q: Vec<String> = r
        .robot
        .start_q_deg
        .iter()
        .map(|v| format!("{v:.1}"))
        .collect();
    println!(
        "robot {}: {} joints, flange {}; reaches the start over the hole at q = [{}] deg",
        r.robot.source,
        r.robot.joints,
        r.robot.flange,
        q.join(", ")
    );
    for w in &r.warnings {
        println!("warning: {w}");
    }
}
