//! `pegtwin robot ...`: what a robotics user checks before trusting the arm model.

use clap::{Args, Subcommand};
use pegtwin::error::{Error, Result};
use pegtwin::selfcheck::stiffness::{AxisStiffness, PushTest, measure_stiffness};
use pegtwin::twin::control::ImpedanceGains;
use pegtwin::twin::geometry::{self, build_builtin, builtin_by_name};
use pegtwin::twin::robot::spec::RobotSpec;
use pegtwin::twin::robot::urdf::{iiwa14, load};
use pegtwin::twin::robot::{GRAVITY_UPRIGHT, RobotModel};
use pegtwin::twin::workcell::WorkCellParams;
use serde_json::json;
use std::path::PathBuf;

/// Largest stiffness error `robot stiffness` accepts, percent.
pub const STIFFNESS_TOLERANCE_PERCENT: f64 = 5.0;

#[derive(Subcommand)]
pub enum RobotAction {
    /// Joints, limits, link masses and total mass.
    Info {
        #[command(flatten)]
        robot: RobotArgs,
        #[arg(long)]
        json: bool,
    },
    /// Flange pose (base frame) at a joint configuration: xyz in m, rpy in rad, the 3x3 rotation.
    Fk {
        #[command(flatten)]
        robot: RobotArgs,
        #[command(flatten)]
        q: JointArgs,
        #[arg(long)]
        json: bool,
    },
    /// Gravity torques g(q), N m: what holds the arm still at a configuration.
    Gravity {
        #[command(flatten)]
        robot: RobotArgs,
        #[command(flatten)]
        q: JointArgs,
        #[arg(long)]
        json: bool,
    },
    /// Pushes the TCP with known forces and torques along each TCP axis in simulation under
    /// Cartesian impedance and reports the static stiffness measured against commanded (exit 1
    /// if an axis is off by more than 5 %).
    Stiffness(StiffnessArgs),
}

/// Which robot.
#[derive(Args)]
pub struct RobotArgs {
    /// URDF of a serial-chain robot (default: the shipped iiwa 14).
    #[arg(long, conflicts_with = "builtin")]
    pub urdf: Option<PathBuf>,
    /// A built-in robot: iiwa14, iiwa7 or ur5e.
    #[arg(long)]
    pub builtin: Option<String>,
    /// Folders searched for `package://` meshes (repeatable).
    #[arg(long)]
    pub package_path: Vec<PathBuf>,
}

impl RobotArgs {
    /// Loads the robot, printing the loader's warnings to stderr.
    pub fn load(&self) -> Result<RobotModel> {
        if let Some(name) = &self.builtin {
            return Ok(RobotSpec::builtin(name).load()?.0);
        }
        let Some(path) = &self.urdf else {
            return iiwa14();
        };
        let loaded = load(path, &self.package_path)?;
        for w in &loaded.warnings {
            eprintln!("warning: {w}");
        }
        Ok(loaded.model)
    }
}

/// A joint configuration.
#[derive(Args)]
#[group(required = true, multiple = false)]
pub struct JointArgs {
    /// Joint positions q1,...,qn in rad (m for prismatic joints).
    #[arg(long, allow_hyphen_values = true)]
    pub q: Option<String>,
    /// Joint positions q1,...,qn in degrees (revolute joints).
    #[arg(long, allow_hyphen_values = true)]
    pub q_deg: Option<String>,
}

impl JointArgs {
    /// Parses and checks the configuration against the robot (length and limits), in rad.
    pub fn resolve(&self, robot: &RobotModel) -> Result<Vec<f64>> {
        let (flag, text, scale) = match (&self.q, &self.q_deg) {
            (Some(t), _) => ("--q", t, 1.0),
            (None, Some(t)) => ("--q-deg", t, 1f64.to_radians()),
            (None, None) => return Err(Error::Input("give --q or --q-deg".into())),
        };
        let q = text
            .split(',')
            .enumerate()
            .map(|(i, v)| {
                v.trim()
                    .parse::<f64>()
                    .ok()
                    .filter(|x| x.is_finite())
                    .map(|x| x * scale)
                    .ok_or_else(|| {
                        Error::Input(format!(
                            "{flag}: value {} `{}` is not a finite number",
                            i + 1,
                            v.trim()
                        ))
                    })
            })
            .collect::<Result<Vec<f64>>>()?;
        robot
            .check_q(&q)
            .map_err(|e| Error::Input(format!("{flag}: {e}")))?;
        Ok(q)
    }
}

#[derive(Args)]
pub struct StiffnessArgs {
    #[command(flatten)]
    pub robot: RobotArgs,
    /// Translational stiffness on every axis, N/m (Sunrise: 0-5000).
    #[arg(long, default_value_t = ImpedanceGains::default().stiffness[0])]
    pub stiffness_n_per_m: f64,
    /// Rotational stiffness on every axis, N m/rad (Sunrise: 0-300).
    #[arg(long, default_value_t = ImpedanceGains::default().stiffness[3])]
    pub rot_stiffness_nm_per_rad: f64,
    /// Damping ratio on every axis (Sunrise: 0.1-1.0).
    #[arg(long, default_value_t = ImpedanceGains::default().damping_ratio[0])]
    pub damping_ratio: f64,
    /// Push on the translational axes, N.
    #[arg(long, default_value_t = PushTest::default().force_n)]
    pub force_n: f64,
    /// Push on the rotational axes, N m.
    #[arg(long, default_value_t = PushTest::default().torque_nm)]
    pub torque_nm: f64,
    /// Peg carried on the flange (built-in name).
    #[arg(long, default_value = "cross")]
    pub geometry: String,
    #[arg(long)]
    pub json: bool,
}

pub fn robot_command(action: RobotAction) -> Result<i32> {
    match action {
        RobotAction::Info { robot, json } => {
            let model = robot.load()?;
            print_info(&model, json);
            Ok(0)
        }
        RobotAction::Fk { robot, q, json } => {
            let model = robot.load()?;
            let q = q.resolve(&model)?;
            print_fk(&model, &q, json);
            Ok(0)
        }
        RobotAction::Gravity { robot, q, json } => {
            let model = robot.load()?;
            let q = q.resolve(&model)?;
            let g = model.gravity_torques(&model.kinematics(&q), &GRAVITY_UPRIGHT);
            if json {
                println!(
                    "{}",
                    json!({ "q_rad": q, "gravity_torques_nm": g.as_slice() })
                );
            } else {
                for (j, t) in model.joints.iter().zip(g.iter()) {
                    println!("{:<20} {t:>10.4} N m", j.name);
                }
            }
            Ok(0)
        }
        RobotAction::Stiffness(args) => stiffness_command(&args),
    }
}

fn print_info(model: &RobotModel, json: bool) {
    if json {
        let links: Vec<_> = std::iter::once(&model.base)
            .chain(&model.links)
            .map(|l| json!({ "name": l.name, "mass_kg": l.inertial.mass_kg }))
            .collect();
        let value = json!({
            "name": model.name,
            "dof": model.dof(),
            "joints": model.joints,
            "armature_kg_m2": model.armature,
            "links": links,
            "flange": model.flange_name,
            "total_mass_kg": model.total_mass_kg(),
        });
        println!(
            "{}",
            serde_json::to_string_pretty(&value).expect("info serialises")
        );
        return;
    }
    println!(
        "robot {} ({} joints), flange frame {}",
        model.name,
        model.dof(),
        model.flange_name
    );
    println!(
        "{:<16} {:>10} {:>10} {:>10} {:>10} {:>10} {:>10}",
        "joint", "lower rad", "upper rad", "vel rad/s", "effort Nm", "damping", "armature"
    );
    for (j, a) in model.joints.iter().zip(&model.armature) {
        println!(
            "{:<16} {:>10.5} {:>10.5} {:>10.5} {:>10.1} {:>10.3} {:>10.3}",
            j.name, j.lower, j.upper, j.velocity_limit, j.effort_limit, j.damping, a
        );
    }
    println!("{:<16} {:>10}", "link", "mass kg");
    for l in std::iter::once(&model.base).chain(&model.links) {
        println!("{:<16} {:>10.4}", l.name, l.inertial.mass_kg);
    }
    println!("total mass {:.4} kg", model.total_mass_kg());
}

fn print_fk(model: &RobotModel, q: &[f64], json: bool) {
    let f = model.flange_pose(q);
    let p = f.translation.vector;
    let (roll, pitch, yaw) = f.rotation.euler_angles();
    let r = f.rotation.to_rotation_matrix();
    let rows: Vec<[f64; 3]> = (0..3).map(|i| [r[(i, 0)], r[(i, 1)], r[(i, 2)]]).collect();
    if json {
        let value = json!({
            "q_rad": q,
            "frame": model.flange_name,
            "xyz_m": [p.x, p.y, p.z],
            "rpy_rad": [roll, pitch, yaw],
            "rotation": rows,
        });
        println!(
            "{}",
            serde_json::to_string_pretty(&value).expect("fk serialises")
        );
        return;
    }
    println!("{} in the base frame", model.flange_name);
    println!("xyz m   {:>12.6} {:>12.6} {:>12.6}", p.x, p.y, p.z);
    println!("rpy rad {:>12.6} {:>12.6} {:>12.6}", roll, pitch, yaw);
    for (i, row) in rows.iter().enumerate() {
        let label = if i == 0 { "R" } else { "" };
        println!(
            "{label:<7} {:>12.6} {:>12.6} {:>12.6}",
            row[0], row[1], row[2]
        );
    }
}

fn stiffness_command(args: &StiffnessArgs) -> Result<i32> {
    let model = args.robot.load()?;
    let gains = ImpedanceGains::uniform(
        args.stiffness_n_per_m,
        args.rot_stiffness_nm_per_rad,
        args.damping_ratio,
    );
    gains.ensure_valid()?;
    let pair = build_builtin(builtin_by_name(&args.geometry)?, 0.5e-3)?;
    geometry::check_clearance(pair.clearance_m)?;
    let test = PushTest {
        force_n: args.force_n,
        torque_nm: args.torque_nm,
        ..Default::default()
    };
    let axes = measure_stiffness(&pair, &model, &WorkCellParams::default(), &gains, test)?;
    let passed = axes
        .iter()
        .all(|a| a.error_percent.abs() <= STIFFNESS_TOLERANCE_PERCENT);
    if args.json {
        let value = json!({ "gains": gains, "axes": axes, "tolerance_percent": STIFFNESS_TOLERANCE_PERCENT, "passed": passed });
        println!(
            "{}",
            serde_json::to_string_pretty(&value).expect("stiffness serialises")
        );
    } else {
        print_stiffness(&axes);
        println!(
            "{}",
            if passed {
                "PASS"
            } else {
                "FAIL: an axis is off by more than 5 %"
            }
        );
    }
    Ok(if passed { 0 } else { 1 })
}

fn print_stiffness(axes: &[AxisStiffness]) {
    println!(
        "{:<5} {:>12} {:>12} {:>9} {:>8} {:>12}",
        "axis", "commanded", "measured", "error %", "push", "deflection"
    );
    for a in axes {
        let (k_unit, push_unit, d_unit, d_scale) = if a.axis.starts_with('r') {
            ("N m/rad", "N m", "mrad", 1e3)
        } else {
            ("N/m", "N", "mm", 1e3)
        };
        println!(
            "{:<5} {:>12} {:>12.1} {:>9.2} {:>8} {:>12}",
            a.axis,
            format!("{:.0} {k_unit}", a.commanded),
            a.measured,
            a.error_percent,
            format!("{} {push_unit}", a.push),
            format!("{:.4} {d_unit}", a.deflection * d_scale)
        );
    }
}
