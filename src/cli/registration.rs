//! `pegtwin manifold ...` and `pegtwin register`: manifold files and Algorithm 1 from the command
//! line.

use super::choices::choice;
use clap::{Args, Subcommand, ValueEnum};
use pegtwin::choice::Choice;
use pegtwin::error::{Error, Result};
use pegtwin::method::manifold::cache::{ManifoldSpec, Sampler};
use pegtwin::method::manifold::file::{self, read_csv};
use pegtwin::method::manifold::plot;
use pegtwin::method::manifold::synthetic::SyntheticPair;
use pegtwin::method::manifold::{DEFAULT_NORMAL_K, MAX_POINTS, Manifold, ManifoldMeta, UNITS};
use pegtwin::method::register::{
    DEFAULT_RESTARTS, DEFAULT_SIGMA_DEG, Registration, RegistrationConfig, Solver, register,
};
use pegtwin::pose::{Pose6, PoseMetric};
use std::path::{Path, PathBuf};

#[derive(Subcommand)]
pub enum ManifoldAction {
    /// Show a manifold file's metadata, size and per-axis ranges.
    Info {
        file: PathBuf,
        #[arg(long)]
        json: bool,
    },
    /// Write a manifold file as CSV (x,y,z,roll,pitch,yaw,nx,...,nyaw; m and rad).
    Export {
        file: PathBuf,
        /// Output CSV.
        #[arg(long)]
        csv: PathBuf,
    },
    /// Draw a manifold (file or CSV of hole_T_peg poses) as the paper does: the x-y-z scatter
    /// coloured by roll, pitch and yaw, and the x-y, x-z, y-z projections. Writes
    /// DIR/NAME.png and DIR/NAME.svg (NAME: the file's stem).
    Plot {
        file: PathBuf,
        /// Output folder (created if needed).
        #[arg(long)]
        out: PathBuf,
    },
    /// Make a manifold file from a CSV of contact poses hole_T_peg (m, rad); normals are computed
    /// unless the CSV has the normal columns.
    Import {
        csv: PathBuf,
        /// Output manifold file.
        #[arg(long)]
        out: PathBuf,
        /// Geometry name for the metadata (default: the CSV's file name).
        #[arg(long)]
        geometry: Option<String>,
        /// Diametral clearance the poses were made with, mm, for the metadata.
        #[arg(long)]
        clearance_mm: Option<f64>,
        #[command(flatten)]
        metric: MetricArgs,
    },
    /// Sample an analytic contact manifold of a prismatic square or cross peg (test data with a
    /// known ground truth), and optionally observations of it through a hole pose.
    Synth(SynthArgs),
    /// Build the reference contact manifold of a pair in simulation (paper IV-B): the robot, under
    /// low stiffness, probes the hole at a known pose with the sampling primitives over many
    /// parallel episodes and records the poses where its estimated wrench says contact; the cloud
    /// is downsampled by a voxel grid and given normals. With --scenario: every manifold a
    /// scenario's campaign needs, into the cache (a job array's first step).
    Build(BuildArgs),
}

/// The 6-D metric and the neighbourhood size of normals.
#[derive(Args)]
pub struct MetricArgs {
    /// One degree counts like this many millimetres in the 6-D distance.
    #[arg(long, default_value_t = PoseMetric::default().mm_per_deg)]
    pub mm_per_deg: f64,
    /// Neighbours per normal.
    #[arg(long, default_value_t = DEFAULT_NORMAL_K)]
    pub k: usize,
}

impl MetricArgs {
    fn metric(&self) -> Result<PoseMetric> {
        if !(self.mm_per_deg > 0.0 && self.mm_per_deg.is_finite()) {
            return Err(Error::Input(format!(
                "--mm-per-deg {}: expected a positive number",
                self.mm_per_deg
            )));
        }
        Ok(PoseMetric {
            mm_per_deg: self.mm_per_deg,
        })
    }
}

#[derive(Clone, Copy, ValueEnum)]
pub enum SynthShape {
    /// 20 mm square peg.
    Square,
    /// Plus-shaped peg, 30 mm span, 10 mm arms.
    Cross,
}

#[derive(Args)]
pub struct SynthArgs {
    #[arg(long, value_enum)]
    pub shape: SynthShape,
    /// Diametral clearance, mm.
    #[arg(long, allow_negative_numbers = true)]
    pub clearance_mm: f64,
    /// Contact poses in the manifold.
    #[arg(long, default_value_t = 100_000)]
    pub points: usize,
    /// Output manifold file.
    #[arg(long)]
    pub out: PathBuf,
    /// Also write this many observations (peg poses in the base frame) to --observations.
    #[arg(long, default_value_t = 1000)]
    pub observation_count: usize,
    /// Observations CSV to write (needs --true-pose).
    #[arg(long, requires = "true_pose")]
    pub observations: Option<PathBuf>,
    /// True hole pose base_T_hole for the observations: x,y,z,roll,pitch,yaw in m and rad.
    #[arg(long, allow_hyphen_values = true)]
    pub true_pose: Option<String>,
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    #[command(flatten)]
    pub metric: MetricArgs,
}

#[derive(Args)]
pub struct RegisterArgs {
    /// Reference manifold: a pegtwin manifold file, or a CSV of hole_T_peg poses.
    #[arg(long)]
    pub manifold: PathBuf,
    /// Observed contact poses base_T_peg, CSV (x,y,z,roll,pitch,yaw; m and rad).
    #[arg(long)]
    pub observations: PathBuf,
    /// Initial estimate of the hole pose base_T_hole: x,y,z,roll,pitch,yaw in m and rad.
    #[arg(long, allow_hyphen_values = true)]
    pub init: String,
    /// Restarts (R), run in parallel.
    #[arg(long, default_value_t = DEFAULT_RESTARTS)]
    pub restarts: usize,
    /// Maximum iterations per restart (N).
    #[arg(long, default_value_t = RegistrationConfig::default().iterations)]
    pub iterations: usize,
    /// Seed of the restarts' initial poses.
    #[arg(long, default_value_t = RegistrationConfig::default().seed)]
    pub seed: u64,
    /// Update rule: the paper's (Algorithm 1) or least squares on the same residuals.
    #[arg(long, value_parser = choice::<Solver>(), default_value = Solver::LeastSquares.name())]
    pub solver: Solver,
    /// Standard deviation of the restarts' initial translation, mm per axis.
    #[arg(long, default_value_t = RegistrationConfig::default().sigma_m * 1e3)]
    pub sigma_mm: f64,
    /// Standard deviation of the restarts' initial rotation, deg per axis.
    #[arg(long, default_value_t = DEFAULT_SIGMA_DEG)]
    pub sigma_deg: f64,
    /// Stop a restart when its update is smaller than this, mm-equivalents.
    #[arg(long, default_value_t = RegistrationConfig::default().tolerance_mm)]
    pub tolerance_mm: f64,
    /// Observations per observation normal.
    #[arg(long, default_value_t = DEFAULT_NORMAL_K)]
    pub k: usize,
    /// For a CSV manifold: one degree counts like this many millimetres.
    #[arg(long, default_value_t = PoseMetric::default().mm_per_deg)]
    pub mm_per_deg: f64,
    /// Print the full result as JSON (per-restart results, iterations, residuals, times).
    #[arg(long)]
    pub json: bool,
}

/// Parse `x,y,z,roll,pitch,yaw` (m, rad) from a flag.
pub fn parse_pose(flag: &str, text: &str) -> Result<Pose6> {
    let values: Vec<&str> = text.split(',').map(str::trim).collect();
    if values.len() != 6 {
        return Err(Error::Input(format!(
            "{flag} `{text}`: expected six comma-separated numbers x,y,z,roll,pitch,yaw (m, rad)"
        )));
    }
    let mut pose = [0.0; 6];
    for (k, v) in values.iter().enumerate() {
        pose[k] = v
            .parse::<f64>()
            .ok()
            .filter(|x| x.is_finite())
            .ok_or_else(|| {
                Error::Input(format!(
                    "{flag}: {} = `{v}` is not a finite number",
                    pegtwin::method::manifold::file::POSE_COLUMNS[k]
                ))
            })?;
    }
    Ok(Pose6(pose))
}

fn csv_meta(path: &Path, metric: PoseMetric, k: usize) -> ManifoldMeta {
    ManifoldMeta {
        geometry: path
            .file_stem()
            .map_or("unknown".into(), |s| s.to_string_lossy().into_owned()),
        clearance_m: None,
        units: UNITS.into(),
        metric,
        normal_k: k,
        source: format!("CSV {}", path.display()),
        seed: None,
    }
}

/// `manifold plot`: a manifold file, or a CSV of poses, drawn into `out`.
fn plot_manifold(path: &Path, out: &Path) -> Result<()> {
    let is_csv = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("csv"));
    let (points, label) = if is_csv {
        let stem = path.file_stem().map(|s| s.to_string_lossy().into_owned());
        (read_csv(path)?.poses, stem.unwrap_or_default())
    } else {
        let m = file::load(path)?;
        let label = plot::label(&m.meta);
        (m.points, label)
    };
    let name = path
        .file_stem()
        .map_or("manifold".into(), |s| s.to_string_lossy().into_owned());
    plot::plot(&points, &label, out, &name)?;
    println!(
        "wrote {} and {}",
        out.join(format!("{name}.png")).display(),
        out.join(format!("{name}.svg")).display()
    );
    Ok(())
}

pub fn manifold_command(action: ManifoldAction) -> Result<i32> {
    match action {
        ManifoldAction::Info { file: path, json } => {
            let m = file::load(&path)?;
            print_info(&path, &m, json);
        }
        ManifoldAction::Export { file: path, csv } => {
            let m = file::load(&path)?;
            file::write_csv(&csv, &m.points, Some(&m.normals))?;
            println!("wrote {} ({} poses with normals)", csv.display(), m.len());
        }
        ManifoldAction::Import {
            csv,
            out,
            geometry,
            clearance_mm,
            metric,
        } => {
            let mut meta = csv_meta(&csv, metric.metric()?, metric.k);
            if let Some(g) = geometry {
                meta.geometry = g;
            }
            if let Some(c) = clearance_mm {
                pegtwin::twin::geometry::check_clearance(c * 1e-3)?;
                meta.clearance_m = Some(c * 1e-3);
            }
            let data = read_csv(&csv)?;
            let m = match data.normals {
                Some(n) => Manifold::with_normals(data.poses, n, meta),
                None => Manifold::from_points(data.poses, meta),
            }
            .map_err(|e| Error::file(&csv, e.to_string()))?;
            file::save(&m, &out)?;
            println!("wrote {} ({} poses)", out.display(), m.len());
        }
        ManifoldAction::Plot { file: path, out } => plot_manifold(&path, &out)?,
        ManifoldAction::Synth(args) => synth(args)?,
        ManifoldAction::Build(args) => build(args)?,
    }
    Ok(0)
}

#[derive(Args)]
#[command(group(clap::ArgGroup::new("pair").required(true).args(["geometry", "assembly", "scenario"])))]
pub struct BuildArgs {
    #[command(flatten)]
    pub pair: super::PairChoice,
    /// Instead of one pair: every reference manifold a scenario's campaign needs, built into (or
    /// found in) the cache folder, as the campaign would build them; so that the shards of a job
    /// array find them ready (deploy/README.md). The scenario's `[manifold]` says how.
    #[arg(long, conflicts_with_all = ["out", "points", "episodes", "episode_s", "seed", "sampler"])]
    pub scenario: Option<PathBuf>,
    /// With --scenario: the folder of cached manifolds (default: $XDG_CACHE_HOME/pegtwin or
    /// ~/.cache/pegtwin).
    #[arg(long, requires = "scenario")]
    pub cache_dir: Option<PathBuf>,
    /// With --scenario: worker threads (default: all cores). The files do not depend on it.
    #[arg(long, requires = "scenario")]
    pub threads: Option<usize>,
    /// Output manifold file.
    #[arg(long, required_unless_present = "scenario")]
    pub out: Option<PathBuf>,
    /// Poses kept after downsampling (the paper found 1e4-1e5 best).
    #[arg(long, default_value_t = ManifoldSpec::default().points)]
    pub points: usize,
    /// The robot sampler's independent sampling episodes (simulations run in parallel)
    /// [default: 48].
    #[arg(long)]
    pub episodes: Option<usize>,
    /// The robot sampler's simulated seconds per episode [default: 20].
    #[arg(long)]
    pub episode_s: Option<f64>,
    #[arg(long, default_value_t = ManifoldSpec::default().seed)]
    pub seed: u64,
    /// How contact poses are found: `robot` (the arm probes the hole in simulation, paper IV-B)
    /// or `geometric` (the poses where the parts touch, from their shapes alone, in seconds).
    #[arg(long, value_parser = choice::<Sampler>(), default_value = "robot")]
    pub sampler: Sampler,
    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,
}

fn build(args: BuildArgs) -> Result<()> {
    if let Some(scenario) = &args.scenario {
        return build_for_scenario(scenario, &args);
    }
    let out = args
        .out
        .as_deref()
        .expect("clap requires --out without --scenario");
    let source = args.pair.source();
    let (pair, warnings) = source.load()?;
    for w in warnings {
        eprintln!("warning: {w}");
    }
    if args.sampler == Sampler::Geometric {
        if args.episodes.is_some() || args.episode_s.is_some() {
            return Err(Error::Input(
                "--episodes and --episode-s set the robot sampler's simulations, and the \
                 geometric sampler has none: leave them out, or use --sampler robot"
                    .into(),
            ));
        }
        return build_geometric(&pair, &args, out);
    }
    let spec = source.robot()?;
    let (robot, _) = spec.load()?;
    let default = ManifoldSpec::default();
    let config = ManifoldSpec {
        episodes: args.episodes.unwrap_or(default.episodes),
        episode_s: args.episode_s.unwrap_or(default.episode_s),
        ..default
    }
    .sampler();
    let bar = indicatif::ProgressBar::new(config.episodes as u64);
    if args.quiet {
        bar.set_draw_target(indicatif::ProgressDrawTarget::hidden());
    } else {
        bar.set_style(
            indicatif::ProgressStyle::with_template(
                "{msg} [{bar:40}] {pos}/{len} episodes, {elapsed} elapsed, ETA {eta}",
            )
            .expect("template parses")
            .progress_chars("=> "),
        );
        bar.set_message(format!(
            "sampling {} at {} mm",
            pair.name,
            pair.clearance_m * 1e3
        ));
    }
    let started = std::time::Instant::now();
    let report = pegtwin::method::manifold::build::build(
        &pair,
        &robot,
        &pegtwin::twin::workcell::WorkCellParams::default().placed_for(&spec),
        &config,
        args.points,
        args.seed,
        &|| bar.inc(1),
    )?;
    bar.finish_and_clear();
    file::save(&report.manifold, out)?;
    for (episode, fault) in &report.faults {
        eprintln!(
            "warning: episode {episode} dropped: sim_fault at {:.3} s: {}",
            fault.time_s, fault.reason
        );
    }
    println!(
        "{} episodes x {} s in {:.1} s: {} contact poses recorded, {} kept (voxel grid)",
        config.episodes,
        config.episode_s,
        started.elapsed().as_secs_f64(),
        report.raw_count,
        report.manifold.len()
    );
    print_info(out, &report.manifold, false);
    Ok(())
}

/// `manifold build --scenario FILE`: every reference manifold the scenario's cells need, into
/// the cache folder (those already there are checked and kept).
fn build_for_scenario(path: &Path, args: &BuildArgs) -> Result<()> {
    let scenario = pegtwin::campaign::scenario::Scenario::load(path)?;
    let bars = super::progress::Bars::new(
        !args.quiet && std::io::IsTerminal::is_terminal(&std::io::stderr()),
    );
    let options = super::campaign::run_options(&args.cache_dir, &bars)?;
    let pool = pegtwin::campaign::run::worker_pool(args.threads)?;
    let started = std::time::Instant::now();
    let count = pool.install(|| pegtwin::campaign::run::build_manifolds(&scenario, &options))?;
    println!(
        "{count} reference manifold{} of {} ready in {} ({:.1} s)",
        if count == 1 { "" } else { "s" },
        path.display(),
        options.cache_dir.display(),
        started.elapsed().as_secs_f64()
    );
    Ok(())
}

/// `manifold build --sampler geometric`: the parts only (no robot, no episodes).
fn build_geometric(
    pair: &pegtwin::twin::geometry::PartPair,
    args: &BuildArgs,
    out: &Path,
) -> Result<()> {
    let started = std::time::Instant::now();
    let config = ManifoldSpec::default().sampler();
    let report =
        pegtwin::method::manifold::geometric::build(pair, &config, args.points, args.seed)?;
    file::save(&report.manifold, out)?;
    println!(
        "{} contact poses from the parts' geometry in {:.1} s, {} kept (voxel grid)",
        report.raw_count,
        started.elapsed().as_secs_f64(),
        report.manifold.len()
    );
    print_info(out, &report.manifold, false);
    Ok(())
}

fn synth(args: SynthArgs) -> Result<()> {
    let c = args.clearance_mm * 1e-3;
    pegtwin::twin::geometry::check_clearance(c)?;
    if args.points < args.metric.k.max(7) || args.points > MAX_POINTS {
        return Err(Error::Input(format!(
            "--points {}: expected --k = {} to {MAX_POINTS} points",
            args.points, args.metric.k
        )));
    }
    let pair = match args.shape {
        SynthShape::Square => SyntheticPair::square(0.02, c),
        SynthShape::Cross => SyntheticPair::cross(0.03, 0.01, c),
    };
    let truth = args
        .true_pose
        .as_deref()
        .map(|t| parse_pose("--true-pose", t))
        .transpose()?;
    let depth = SYNTH_MANIFOLD_DEPTH_M;
    let meta = ManifoldMeta {
        geometry: pair.name.clone(),
        clearance_m: Some(c),
        units: UNITS.into(),
        metric: args.metric.metric()?,
        normal_k: args.metric.k,
        source: format!(
            "analytic contact surface of a prismatic {} peg, tip {}-{} mm deep, {} points",
            pair.name,
            depth[0] * 1e3,
            depth[1] * 1e3,
            args.points
        ),
        seed: Some(args.seed),
    };
    let m = Manifold::from_points(pair.sample_contacts(args.points, depth, args.seed), meta)?;
    file::save(&m, &args.out)?;
    println!("wrote {} ({} poses)", args.out.display(), m.len());
    if let (Some(path), Some(truth)) = (args.observations, truth) {
        let obs = pair.observe(
            &truth,
            args.observation_count,
            SYNTH_OBSERVATION_DEPTH_M,
            SYNTH_NOISE,
            args.seed.wrapping_add(1),
        );
        file::write_csv(&path, &obs, None)?;
        println!("wrote {} ({} observations)", path.display(), obs.len());
    }
    Ok(())
}

/// Depth range of synthetic manifolds and observations (tip below the mouth), m.
pub const SYNTH_MANIFOLD_DEPTH_M: [f64; 2] = [0.001, 0.015];
pub const SYNTH_OBSERVATION_DEPTH_M: [f64; 2] = [0.002, 0.008];
/// Uniform noise half-widths of synthetic observations: 5 um, 0.005 deg.
pub const SYNTH_NOISE: (f64, f64) = (5e-6, 0.005 * std::f64::consts::PI / 180.0);

fn print_info(path: &Path, m: &Manifold, json: bool) {
    let ranges = m.ranges();
    if json {
        let v = serde_json::json!({
            "file": path.display().to_string(),
            "points": m.len(),
            "meta": m.meta,
            "ranges_m_rad": ranges,
        });
        println!("{}", serde_json::to_string_pretty(&v).expect("serialises"));
        return;
    }
    println!("{}: {} contact poses", path.display(), m.len());
    println!(
        "geometry {}, clearance {}, units {}, 1 deg = {} mm, normals from {} neighbours",
        m.meta.geometry,
        m.meta
            .clearance_m
            .map_or("unknown".into(), |c| format!("{} mm", c * 1e3)),
        m.meta.units,
        m.meta.metric.mm_per_deg,
        m.meta.normal_k
    );
    println!("source: {}", m.meta.source);
    for (name, r) in pegtwin::method::manifold::file::POSE_COLUMNS
        .iter()
        .zip(ranges)
    {
        let (scale, unit) = if ["x", "y", "z"].contains(name) {
            (1e3, "mm")
        } else {
            (180.0 / std::f64::consts::PI, "deg")
        };
        println!(
            "  {name:<5} {:>9.4} .. {:>9.4} {unit}",
            r[0] * scale,
            r[1] * scale
        );
    }
}

pub fn register_command(args: RegisterArgs) -> Result<i32> {
    let init = parse_pose("--init", &args.init)?;
    let cfg = RegistrationConfig {
        solver: args.solver,
        iterations: args.iterations,
        tolerance_mm: args.tolerance_mm,
        restarts: args.restarts,
        sigma_m: args.sigma_mm * 1e-3,
        sigma_rad: args.sigma_deg.to_radians(),
        normal_k: args.k,
        seed: args.seed,
        ..Default::default()
    };
    cfg.ensure_valid()?;
    let metric = MetricArgs {
        mm_per_deg: args.mm_per_deg,
        k: args.k,
    }
    .metric()?;
    let t0 = std::time::Instant::now();
    let manifold = file::load_any(&args.manifold, csv_meta(&args.manifold, metric, args.k))?;
    let load_s = t0.elapsed().as_secs_f64();
    let obs = read_csv(&args.observations)?.poses;
    let result = register(&manifold, &obs, &init, &cfg)
        .map_err(|e| Error::file(&args.observations, e.to_string()))?;
    if args.json {
        let v = serde_json::json!({
            "estimate_base_T_hole": result.estimate,
            "estimate_mm_deg": result.estimate.to_mm_deg(),
            "estimate_std": result.estimate_std,
            "manifold": { "file": args.manifold.display().to_string(), "points": manifold.len(), "meta": manifold.meta, "load_s": load_s },
            "observations": obs.len(),
            "config": cfg,
            "result": result,
        });
        println!("{}", serde_json::to_string_pretty(&v).expect("serialises"));
    } else {
        print_registration(&result, load_s);
    }
    Ok(0)
}

fn print_registration(r: &Registration, load_s: f64) {
    let p = r.estimate.0;
    let h = r.estimate.to_mm_deg();
    println!(
        "base_T_hole  x {:.6} m  y {:.6} m  z {:.6} m  roll {:.6} rad  pitch {:.6} rad  yaw {:.6} rad",
        p[0], p[1], p[2], p[3], p[4], p[5]
    );
    println!(
        "             ({:.3} mm, {:.3} mm, {:.3} mm, {:.3} deg, {:.3} deg, {:.3} deg)",
        h[0], h[1], h[2], h[3], h[4], h[5]
    );
    let s = Pose6(r.estimate_std).to_mm_deg();
    println!(
        "std (hole frame)  x {:.3} mm  y {:.3} mm  z {:.3} mm  roll {:.3} deg  pitch {:.3} deg  yaw {:.3} deg",
        s[0], s[1], s[2], s[3], s[4], s[5]
    );
    let iters: Vec<usize> = r.restarts.iter().map(|x| x.iterations).collect();
    let mean_iters = iters.iter().sum::<usize>() as f64 / iters.len().max(1) as f64;
    let kept: Vec<f64> = r
        .restarts
        .iter()
        .filter(|x| !x.rejected)
        .map(|x| x.residual_mm)
        .collect();
    let residual = kept.iter().sum::<f64>() / kept.len().max(1) as f64;
    println!(
        "solver {:?}: {} restarts, {} kept (MAD), {:.1} iterations on average, residual {:.4} mm-eq",
        r.solver,
        r.restarts.len(),
        r.kept,
        mean_iters,
        residual
    );
    println!(
        "time: load {:.3} s, restarts {:.3} s, combine {:.4} s",
        load_s, r.time.restarts_s, r.time.combine_s
    );
}

#[cfg(test)]
mod tests {
    use super::BuildArgs;
    use clap::{Args, Command};
    use pegtwin::method::manifold::build::SamplerConfig;

    /// The robot sampler's defaults are written into `manifold build --help` by hand (the flags
    /// are options, so that the geometric sampler can refuse them): they must be the sampler's.
    #[test]
    fn build_help_states_the_robot_samplers_defaults() {
        let help = BuildArgs::augment_args(Command::new("build"))
            .render_long_help()
            .to_string();
        let robot = SamplerConfig::default();
        for (flag, default) in [
            ("episodes", robot.episodes.to_string()),
            ("episode-s", robot.episode_s.to_string()),
        ] {
            let text = help
                .split(&format!("--{flag} <"))
                .nth(1)
                .and_then(|rest| rest.split("\n\n").next())
                .unwrap_or_else(|| panic!("--{flag} is not in the help"));
            assert!(
                text.contains(&format!("[default: {default}]")),
                "--{flag}'s help says {text:?}, the sampler's default is {default}"
            );
        }
    }
}
