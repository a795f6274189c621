//! The command line: parses, calls the library, prints. Flags that people type take millimetres
//! and degrees and say so in their names.

use choices::choice;
use clap::{Args, Parser, Subcommand};
use pegtwin::choice::Choice;
use pegtwin::error::{Error, Result};
use pegtwin::twin::assembly::PairSource;
use pegtwin::twin::geometry::mesh::{MeshUnits, load_pair};
use pegtwin::twin::geometry::{self, Builtin, PartPair};
use pegtwin::twin::real_cell::Profile;
use pegtwin::twin::robot::RobotModel;
use pegtwin::twin::robot::spec::RobotSpec;
use pegtwin::twin::workcell::WorkCellParams;
use std::path::PathBuf;

mod assembly;
mod bench;
mod calibrate;
mod campaign;
mod choices;
mod progress;
mod registration;
mod robot;
mod trial;
mod validate;
pub use assembly::AssemblyAction;
pub use bench::BenchArgs;
pub use campaign::{CampaignArgs, CheckArgs, ExportArgs, MergeArgs, TuneArgs};
pub use registration::{ManifoldAction, RegisterArgs};
pub use robot::RobotAction;
pub use trial::{RerunArgs, TrialArgs};

#[derive(Parser)]
#[command(
    name = "pegtwin",
    version,
    about = "Digital twin for peg-in-hole assembly by contact-manifold pose estimation"
)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Subcommand)]
pub enum Command {
    /// Built-in peg/hole geometries: list them, export them as STL.
    Geometry {
        #[command(subcommand)]
        action: GeometryAction,
    },
    /// Your own peg and hole: check an assembly file and show what was measured of its fit.
    Assembly {
        #[command(subcommand)]
        action: AssemblyAction,
    },
    /// Self-check the contact physics on a pair before trusting a campaign (exit 0 only if every
    /// case behaves as expected).
    Validate(ValidateArgs),
    /// Reference contact manifolds: inspect, export to CSV, import from CSV, synthesise.
    Manifold {
        #[command(subcommand)]
        action: ManifoldAction,
    },
    /// Estimate the hole pose from observed contact poses (paper Algorithm 1).
    Register(RegisterArgs),
    /// The robot model: joints and masses, forward kinematics, gravity torques, and the static
    /// stiffness it shows in simulation under Cartesian impedance.
    Robot {
        #[command(subcommand)]
        action: RobotAction,
    },
    /// One online trial: a randomly offset hole, contact observation, registration, insertion
    /// (or the direct-insertion baseline).
    Trial(TrialArgs),
    /// One trial of a campaign again, on its own: its record bit for bit, with a trace or a 3-D
    /// replay (from a scenario file or a campaign's results folder).
    Rerun(RerunArgs),
    /// Every trial of a scenario in parallel: trials.jsonl, summary.json/csv, report.html.
    Campaign(CampaignArgs),
    /// Join the result folders of a campaign's shards into one.
    Merge(MergeArgs),
    /// The regression gate: hold a finished campaign to a baseline (exit 1 on a regression).
    Check(CheckArgs),
    /// A finished campaign's trials as a Parquet table (one row per trial, flat columns with
    /// units in their names), for pandas, polars, DuckDB and Arrow.
    Export(ExportArgs),
    /// Search the observation and insertion gains for the best success rate and lowest force.
    Tune(TuneArgs),
    /// Fit the real cell's [cell] values to figures measured on it, and predict the figures
    /// held out (posterior, calibrated [cell] section, report).
    Calibrate(calibrate::CalibrateArgs),
    /// Measure the speed of a campaign's pieces on this machine (arm physics, a sampling episode,
    /// a trial, a registration), with the ratio to real time.
    Bench(BenchArgs),
}

#[derive(Subcommand)]
pub enum GeometryAction {
    /// Show the built-ins and their dimensions.
    List {
        #[arg(long)]
        json: bool,
    },
    /// Write peg.stl and hole.stl (millimetres, watertight, hole frame at the mouth centre).
    Export {
        /// Built-in name (see `geometry list`).
        name: String,
        /// Diametral clearance, mm (hole size minus peg size).
        #[arg(long)]
        clearance_mm: f64,
        /// Output folder.
        #[arg(long)]
        out: PathBuf,
        /// Also write each convex collision piece as its own STL (peg_parts/, hole_parts/).
        #[arg(long)]
        convex_parts: bool,
    },
}

/// Which pair a trial or a manifold build runs: a built-in at a clearance, or an assembly file.
/// The command that flattens it requires one of `geometry` and `assembly` (an `ArgGroup`).
#[derive(Args)]
pub struct PairChoice {
    /// Built-in geometry name (see `geometry list`).
    #[arg(long, requires = "clearance_mm")]
    pub geometry: Option<String>,
    /// Diametral clearance of the built-in, mm.
    #[arg(long, allow_negative_numbers = true, requires = "geometry")]
    pub clearance_mm: Option<f64>,
    /// An assembly file: your own peg and hole (README, "Your own parts and robot").
    #[arg(long, conflicts_with_all = ["geometry", "clearance_mm"])]
    pub assembly: Option<PathBuf>,
}

impl PairChoice {
    /// The library's name for the chosen pair.
    pub fn source(&self) -> PairSource {
        match (&self.assembly, &self.geometry, self.clearance_mm) {
            (Some(path), _, _) => PairSource::Assembly(path.clone()),
            (None, Some(name), Some(clearance_mm)) => PairSource::Builtin {
                name: name.clone(),
                clearance_mm,
            },
            _ => unreachable!("clap requires --assembly, or --geometry with --clearance-mm"),
        }
    }
}

/// Which pair to validate: a built-in, an assembly file, or meshes.
#[derive(Args)]
pub struct PairArgs {
    /// Built-in geometry name (see `geometry list`).
    #[arg(long, required_unless_present_any = ["peg_mesh", "assembly"])]
    pub geometry: Option<String>,
    /// Diametral clearance, mm. For meshes: the clearance they were made with.
    #[arg(long, required_unless_present = "assembly")]
    pub clearance_mm: Option<f64>,
    /// An assembly file: your own peg and hole in their frames (README, "Your own parts and
    /// robot"); the clearance and depth are measured.
    #[arg(long, conflicts_with_all = ["geometry", "clearance_mm", "peg_mesh"])]
    pub assembly: Option<PathBuf>,
    /// Peg mesh, peg frame (tip centre at the origin, z up the peg): a folder of convex STL/OBJ
    /// parts or one STL/OBJ file to decompose.
    #[arg(long, requires = "hole_mesh", conflicts_with = "geometry")]
    pub peg_mesh: Option<PathBuf>,
    /// Hole mesh, hole frame (mouth centre at the origin, z out of the hole); as --peg-mesh.
    #[arg(long, requires_all = ["peg_mesh", "depth_mm"])]
    pub hole_mesh: Option<PathBuf>,
    /// Length unit of the mesh files.
    #[arg(long, value_parser = choice::<MeshUnits>(), default_value = MeshUnits::M.name())]
    pub mesh_units: MeshUnits,
    /// Cavity depth of a mesh hole, mouth to floor, mm.
    #[arg(long)]
    pub depth_mm: Option<f64>,
}

#[derive(Args)]
pub struct ValidateArgs {
    #[command(flatten)]
    pub pair: PairArgs,
    /// Drive the peg on the robot's flange (the iiwa 14, or the assembly's `[robot]`) through the
    /// controller at the trials' gains (and the manifold sampler's), instead of the free peg.
    #[arg(long)]
    pub arm: bool,
    /// With --arm: end every physics step with a position projection of the peg out of what it
    /// still overlaps (a scenario's `[physics] position_projection = true`).
    #[arg(long, requires = "arm")]
    pub position_projection: bool,
    /// With --arm: leave the peg's contacts to rapier's multibody contact rows (soft, the
    /// default until 2026-11-26) instead of the exact joint-space solve; a scenario's
    /// `[physics] arm_contacts = "rapier"`.
    #[arg(long, requires = "arm")]
    pub rapier_contacts: bool,
    /// With --arm: the ideal cell (the physics check) or the real one, each case's cell
    /// drawing the real cell's imperfections from its seed (docs/physics.md, "The real cell");
    /// there a case passes on soundness alone (no fault, penetration within the bar) and its
    /// ideal outcome is reported.
    #[arg(long, requires = "arm", value_parser = choice::<Profile>(), default_value = Profile::Ideal.name())]
    pub profile: Profile,
    /// Print the report as JSON.
    #[arg(long)]
    pub json: bool,
}

impl PairArgs {
    /// The robot that holds the peg (the assembly's, else the built-in iiwa 14) and the cell
    /// it stands in.
    pub fn robot(&self) -> Result<(RobotModel, WorkCellParams)> {
        let spec = match &self.assembly {
            Some(path) => PairSource::Assembly(path.clone()).robot()?,
            None => RobotSpec::default(),
        };
        Ok((spec.load()?.0, WorkCellParams::default().placed_for(&spec)))
    }

    /// Builds the pair, printing mesh warnings to stderr.
    pub fn build(&self) -> Result<PartPair> {
        if let Some(path) = &self.assembly {
            let (pair, warnings) = PairSource::Assembly(path.clone()).load()?;
            for w in warnings {
                eprintln!("warning: {w}");
            }
            return Ok(pair);
        }
        let clearance_m = self
            .clearance_mm
            .expect("clap requires it without --assembly")
            * 1e-3;
        geometry::check_clearance(clearance_m)?;
        match (&self.geometry, &self.peg_mesh, &self.hole_mesh) {
            (Some(name), _, _) => {
                geometry::build_builtin(geometry::builtin_by_name(name)?, clearance_m)
            }
            (None, Some(peg_path), Some(hole_path)) => {
                let depth_mm = self.depth_mm.unwrap_or(f64::NAN);
                if depth_mm.is_nan() || depth_mm <= 0.0 {
                    return Err(Error::Input(format!(
                        "--depth-mm {depth_mm}: expected the cavity depth of the mesh hole, more than 0 mm"
                    )));
                }
                let units = self.mesh_units;
                let (pair, warnings) =
                    load_pair(peg_path, hole_path, units, clearance_m, depth_mm * 1e-3)?;
                for w in warnings {
                    eprintln!("warning: {w}");
                }
                Ok(pair)
            }
            _ => Err(Error::Input(
                "give --geometry NAME, or both --peg-mesh and --hole-mesh".into(),
            )),
        }
    }
}

/// Runs a parsed command; returns the process exit code.
pub fn run(cli: Cli) -> Result<i32> {
    match cli.command {
        Command::Geometry { action } => geometry_command(action),
        Command::Assembly { action } => assembly::assembly_command(action),
        Command::Validate(args) => validate::validate_command(args),
        Command::Manifold { action } => registration::manifold_command(action),
        Command::Register(args) => registration::register_command(args),
        Command::Robot { action } => robot::robot_command(action),
        Command::Trial(args) => trial::trial_command(args),
        Command::Rerun(args) => trial::rerun_command(args),
        Command::Campaign(args) => campaign::campaign_command(args),
        Command::Merge(args) => campaign::merge_command(args),
        Command::Check(args) => campaign::check_command(args),
        Command::Export(args) => campaign::export_command(args),
        Command::Tune(args) => campaign::tune_command(args),
        Command::Calibrate(args) => calibrate::calibrate_command(args),
        Command::Bench(args) => bench::bench_command(args),
    }
}

fn geometry_command(action: GeometryAction) -> Result<i32> {
    match action {
        GeometryAction::List { json } => {
            let list: Vec<serde_json::Value> = Builtin::ALL
                .iter()
                .map(|b| {
                    serde_json::json!({
                        "name": b.name(),
                        "description": b.description(),
                        "dimensions_mm": b.dimensions(),
                    })
                })
                .collect();
            if json {
                println!(
                    "{}",
                    serde_json::to_string_pretty(&list).expect("list serialises")
                );
            } else {
                for b in Builtin::ALL {
                    println!("{:<10} {}", b.name(), b.description());
                    let dims: Vec<String> = b
                        .dimensions()
                        .iter()
                        .map(|d| format!("{} {} mm", d.name, d.value_mm))
                        .collect();
                    println!("{:<10} {}", "", dims.join(", "));
                }
                println!(
                    "\nall: engagement pin {} mm, blind cavity {} mm deep in a {} x {} mm block, chamfers {} mm (peg tip) and {} mm (hole mouth)",
                    geometry::PIN_LENGTH_M * 1e3,
                    geometry::CAVITY_DEPTH_M * 1e3,
                    geometry::BLOCK_SIZE_M * 1e3,
                    geometry::BLOCK_SIZE_M * 1e3,
                    geometry::PEG_TIP_CHAMFER_M * 1e3,
                    geometry::HOLE_ENTRY_CHAMFER_M * 1e3
                );
            }
            Ok(0)
        }
        GeometryAction::Export {
            name,
            clearance_mm,
            out,
            convex_parts,
        } => {
            let pair =
                geometry::build_builtin(geometry::builtin_by_name(&name)?, clearance_mm * 1e-3)?;
            geometry::export_stl(&pair, &out, convex_parts)?;
            println!(
                "wrote {} and {} (mm; clearance {} mm, chord error at most {:.4} mm)",
                out.join("peg.stl").display(),
                out.join("hole.stl").display(),
                clearance_mm,
                pair.chord_error_m * 1e3
            );
            Ok(0)
        }
    }
}
