//! Which robot holds the peg: a built-in (`iiwa14`, the default; `iiwa7`; `ur5e`) or a user's
//! URDF, with the link that is its flange, where the peg's holder sits on that flange and,
//! optionally, a joint configuration near the start pose. An assembly file's `[robot]` section
//! is read into one (`crate::twin::assembly`).

use super::urdf;
use super::{Iso, RobotModel, iso_xyz_rpy};
use crate::error::{Error, Result};
use std::path::PathBuf;

/// Where the URDF comes from.
#[derive(Clone, Debug, PartialEq)]
pub enum RobotSource {
    /// A built-in robot by name ([`BUILTIN_ROBOTS`]).
    Builtin(String),
    /// A URDF file, with the folders its `package://` meshes resolve against.
    Urdf {
        path: PathBuf,
        package_paths: Vec<PathBuf>,
    },
}

/// A robot as a user names it.
#[derive(Clone, Debug, PartialEq)]
pub struct RobotSpec {
    pub source: RobotSource,
    /// The link whose frame is the flange (`None`: the chain's last link).
    pub flange_link: Option<String>,
    /// `flange_T_mount`: where the peg's top face (its holder) sits on the flange, m and rad
    /// (URDFs often end short of the flange, as pybullet's iiwa 14 does by 45 mm).
    pub tool_offset: Iso,
    /// A joint configuration near the start pose for the inverse kinematics, rad (`None`: the
    /// built-in's, or searched for; see [`RobotModel::start_configuration`]).
    pub start_q_rad: Option<Vec<f64>>,
    /// Where the hole's fixture stands in the robot's base frame, x and y, m (`None`: the cell's
    /// default, 0.55 m in front of the base).
    pub hole_xy_m: Option<[f64; 2]>,
}

impl Default for RobotSpec {
    /// The built-in iiwa 14 with the peg on its flange.
    fn default() -> Self {
        RobotSpec::builtin("iiwa14")
    }
}

impl RobotSpec {
    /// A built-in robot with the peg on its flange.
    pub fn builtin(name: &str) -> Self {
        RobotSpec {
            source: RobotSource::Builtin(name.into()),
            flange_link: None,
            tool_offset: Iso::identity(),
            start_q_rad: None,
            hole_xy_m: None,
        }
    }

    /// Builds the tool offset from the assembly file's `tool_xyz_mm` and `tool_rpy_deg`.
    pub fn with_tool_mm_deg(mut self, xyz_mm: [f64; 3], rpy_deg: [f64; 3]) -> Self {
        self.tool_offset = iso_xyz_rpy(xyz_mm.map(|v| v * 1e-3), rpy_deg.map(f64::to_radians));
        self
    }

    /// Whether this is the default robot (the built-in iiwa 14 as shipped): its cached manifolds
    /// keep the names they had before robots could be chosen.
    pub fn is_default(&self) -> bool {
        *self == RobotSpec::default()
    }

    /// A short label for reports: the built-in's name or the URDF's file name.
    pub fn label(&self) -> String {
        match &self.source {
            RobotSource::Builtin(name) => name.clone(),
            RobotSource::Urdf { path, .. } => path.display().to_string(),
        }
    }

    /// Loads the model (the loader's warnings are returned beside it), with its flange moved by
    /// the tool offset, its IK seed and its content key set.
    pub fn load(&self) -> Result<(RobotModel, Vec<String>)> {
        let flange = self.flange_link.as_deref();
        let (text, loaded) = match &self.source {
            RobotSource::Builtin(name) => (
                urdf::builtin_text(name)?.to_string(),
                urdf::builtin(name, flange)?,
            ),
            RobotSource::Urdf {
                path,
                package_paths,
            } => {
                let text = crate::files::read_text(path)?;
                let loaded = urdf::load_text(&text, path, package_paths, flange)?;
                (text, loaded)
            }
        };
        let mut model = loaded.model;
        model.last_t_flange *= self.tool_offset;
        if let Some(q) = &self.start_q_rad {
            model
                .check_q(q)
                .map_err(|e| Error::Input(format!("start_q_deg: {e}")))?;
            model.ik_seed = Some(q.clone());
        }
        if !self.is_default() {
            model.content_key = Some(self.content_key(&text));
        }
        Ok((model, loaded.warnings))
    }

    /// Checksum of the URDF text, the flange link, the tool offset, the seed and the hole's place.
    fn content_key(&self, text: &str) -> String {
        let mut h = crc32fast::Hasher::new();
        h.update(text.as_bytes());
        h.update(self.flange_link.as_deref().unwrap_or("").as_bytes());
        let t = self.tool_offset.to_homogeneous();
        let hole = self.hole_xy_m.iter().flatten();
        for v in t
            .iter()
            .chain(self.start_q_rad.iter().flatten())
            .chain(hole)
        {
            h.update(&v.to_le_bytes());
        }
        format!("{}-{:08x}", self.short_name(), h.finalize())
    }

    /// The built-in's name or the URDF's file stem, for cache file names.
    fn short_name(&self) -> String {
        match &self.source {
            RobotSource::Builtin(name) => name.clone(),
            RobotSource::Urdf { path, .. } => path
                .file_stem()
                .map_or("robot".into(), |s| s.to_string_lossy().into_owned()),
        }
    }
}
