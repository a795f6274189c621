//! `pegtwin trial`: one online trial, the manifold method or the direct baseline.

use super::choices::{MethodArg, StartArg};
use super::progress::Bars;
use clap::Args;
use pegtwin::error::{Error, Result};
use pegtwin::method::config::{MAX_OFFSET, TrialConfig};
use pegtwin::method::manifold::Manifold;
use pegtwin::method::manifold::cache::{self, ManifoldSpec};
use pegtwin::method::manifold::file;
use pegtwin::method::session::{Recorder, trace_csv};
use pegtwin::method::trial::{TrialResult, run_trial};
use pegtwin::replay::Replay;
use pegtwin::twin::cell::CellParams;
use pegtwin::twin::geometry::{self, PartPair};
use std::path::PathBuf;

/// The library's default offset half-ranges, mm and deg (the paper's U(-5, 5)).
fn default_offsets() -> (f64, f64) {
    let r = TrialConfig::default().offset_range;
    (r[0] * 1e3, r[3].to_degrees())
}

#[derive(Args)]
pub struct TrialArgs {
    /// Built-in geometry name (see `geometry list`).
    #[arg(long)]
    pub geometry: String,
    /// Diametral clearance, mm.
    #[arg(long, allow_negative_numbers = true)]
    pub clearance_mm: f64,
    /// Observation time, s.
    #[arg(long, default_value_t = TrialConfig::default().t_obs_s, allow_negative_numbers = true)]
    pub t_obs: f64,
    #[arg(long, value_enum, default_value = "manifold")]
    pub method: MethodArg,
    /// Start partially inserted (the paper's set-up) or above the hole with a spiral search.
    #[arg(long, value_enum, default_value = "partial")]
    pub start: StartArg,
    /// Trial seed: draws the hole offset and seeds every noise source.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Half-range of the hole's position offset, mm (U(-r, r) on x, y, z).
    #[arg(long, default_value_t = default_offsets().0, allow_negative_numbers = true)]
    pub offset_mm: f64,
    /// Half-range of the hole's orientation offset, deg (U(-r, r) on roll, pitch, yaw).
    #[arg(long, default_value_t = default_offsets().1, allow_negative_numbers = true)]
    pub offset_deg: f64,
    /// Reference manifold file (default: the cache, built on demand).
    #[arg(long)]
    pub manifold: Option<PathBuf>,
    /// Folder of cached manifolds (default: $XDG_CACHE_HOME/pegtwin or ~/.cache/pegtwin).
    #[arg(long)]
    pub cache_dir: Option<PathBuf>,
    /// Print the result as JSON.
    #[arg(long)]
    pub json: bool,
    /// Write the time series (time, phase, TCP pose, estimated and true wrench, contact) as CSV.
    #[arg(long)]
    pub trace: Option<PathBuf>,
    /// Write a 3-D replay of the trial: one self-contained HTML page (open it in a browser).
    #[arg(long)]
    pub replay: Option<PathBuf>,
}

pub fn trial_command(args: TrialArgs) -> Result<i32> {
    let clearance_m = args.clearance_mm * 1e-3;
    geometry::check_clearance(clearance_m)?;
    let pair = geometry::build_builtin(geometry::builtin_by_name(&args.geometry)?, clearance_m)?;
    let (max_m, max_rad) = MAX_OFFSET;
    for (flag, v, max) in [
        ("--offset-mm", args.offset_mm, max_m * 1e3),
        ("--offset-deg", args.offset_deg, max_rad.to_degrees()),
    ] {
        if !(v >= 0.0 && v <= max) {
            return Err(Error::Input(format!(
                "{flag} {v}: expected a half-range from 0 to {max:.0}"
            )));
        }
    }
    let (m, a) = (args.offset_mm * 1e-3, args.offset_deg.to_radians());
    let config = TrialConfig {
        method: args.method.into(),
        start: args.start.into(),
        t_obs_s: args.t_obs,
        offset_range: [m, m, m, a, a, a],
        ..Default::default()
    };
    config.ensure_valid()?;
    for path in args.trace.iter().chain(&args.replay) {
        pegtwin::files::ensure_writable(path)?;
    }
    let robot = pegtwin::twin::robot::urdf::iiwa14()?;
    let params = CellParams::default();
    let manifold = match args.method {
        MethodArg::Manifold => Some(reference_manifold(&args, &pair, &robot, &params)?),
        MethodArg::Direct => None,
    };
    let mut recorders = (Vec::new(), Replay::new(&pair, &robot));
    let recording = args.trace.is_some() || args.replay.is_some();
    let result = run_trial(
        &pair,
        &robot,
        &params,
        &config,
        manifold.as_ref(),
        args.seed,
        recording.then_some(&mut recorders as &mut dyn Recorder),
    )?;
    let (rows, replay) = recorders;
    if let Some(path) = &args.trace {
        pegtwin::files::write_atomically(path, &trace_csv(&rows))?;
    }
    if let Some(path) = &args.replay {
        replay.write_html(path, &result, manifold.as_ref())?;
    }
    if args.json {
        println!(
            "{}",
            serde_json::to_string_pretty(&result).expect("result serialises")
        );
    } else {
        print_result(&result);
    }
    Ok(0)
}

/// The manifold given, or the cached one for this pair, built (and cached) when missing.
fn reference_manifold(
    args: &TrialArgs,
    pair: &PartPair,
    robot: &pegtwin::twin::robot::RobotModel,
    params: &CellParams,
) -> Result<Manifold> {
    if let Some(path) = &args.manifold {
        if !file::is_binary(path) && path.extension().is_some_and(|e| e == "csv") {
            return Err(pegtwin::error::Error::file(
                path,
                format!(
                    "a trial needs a manifold file that records its geometry and clearance; make \
                     one from this CSV with `pegtwin manifold import {} --geometry {} \
                     --clearance-mm {} --out FILE`",
                    path.display(),
                    pair.name,
                    pair.clearance_m * 1e3
                ),
            ));
        }
        let m = file::load(path)?;
        m.check_made_for(pair, path)?;
        return Ok(m);
    }
    let spec = ManifoldSpec::default();
    let dir = args.cache_dir.as_deref();
    cache::resolve(pair, robot, &spec, params, dir, &Bars::new(true))
}

fn print_result(r: &TrialResult) {
    let o = r.offset;
    println!(
        "{} at {} mm, method {:?}, seed {}, t_obs {} s",
        r.geometry, r.clearance_mm, r.method, r.seed, r.t_obs_s
    );
    println!(
        "hole offset: x {:.2} y {:.2} z {:.2} mm, roll {:.2} pitch {:.2} yaw {:.2} deg",
        o[0], o[1], o[2], o[3], o[4], o[5]
    );
    if let Some(e) = &r.errors {
        println!(
            "estimate error: x {:.3} y {:.3} z {:.3} mm, roll {:.3} pitch {:.3} yaw {:.3} deg",
            e.x_mm, e.y_mm, e.z_mm, e.roll_deg, e.pitch_deg, e.yaw_deg
        );
    }
    println!(
        "outcome: {} ({}); {} contact observations, {} used; Fz peak {:.1} N, mean {:.1} N",
        r.outcome,
        match r.final_depth_mm {
            Some(d) => format!("tip {d:.2} mm below the mouth"),
            None => "not inserted".into(),
        },
        r.contact_observations,
        r.observations_used,
        r.peak_fz_n,
        r.mean_fz_n
    );
    if let Some(why) = &r.stopped {
        println!("stopped before inserting: {why}");
    }
    if let Some(f) = &r.fault {
        println!("sim_fault at {:.3} s: {}", f.time_s, f.reason);
    }
    let t = &r.times;
    println!(
        "time: search {:.1} s, observe {:.1} s, register {:.2} s wall, retract {:.2} s, align {:.2} s, insert {:.2} s; {:.1} s wall in all",
        t.search_s, t.observe_s, t.register_wall_s, t.retract_s, t.align_s, t.insert_s, r.wall_s
    );
}
