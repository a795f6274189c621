//! Loading a serial-chain URDF (parsed by urdf-rs) into a [`RobotModel`].
//!
//! Rules, as ROS tools apply them: the root is the one link that is no joint's child; the chain
//! must not branch; `revolute`, `continuous` and `prismatic` joints move, `fixed` joints fold
//! their child into the link before them (the tip's fixed joints give the flange frame);
//! `floating`, `planar` and `spherical` joints are refused. Mesh URIs (`package://pkg/path`,
//! `file://`, or relative to the URDF's folder) are resolved against a search path; a collision
//! mesh becomes the convex hull of its vertices and must exist, a missing visual mesh is only a
//! warning (pegtwin does not render).

use super::{
    CollisionShape, Inertial, Joint, JointKind, Link, RobotModel, Shape, default_armature,
    iso_xyz_rpy,
};
use crate::error::{Error, Result};
use crate::pose::{MAX_ANGLE_RAD, MAX_COORDINATE_M};
use crate::twin::geometry::mesh::{MeshUnits, read_mesh};
use nalgebra::{Matrix3, Point3, Vector3};
use std::collections::{HashMap, HashSet};
use std::path::{Path, PathBuf};

/// The iiwa 14 shipped with pegtwin: the file in the source tree (for tools that read files).
pub const IIWA14_URDF: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/assets/iiwa14/iiwa14.urdf");
/// The iiwa 7 variant shipped with pegtwin (placeholder inertials, see the file).
pub const IIWA7_URDF: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/assets/iiwa7/iiwa7.urdf");
/// The UR5e shipped with pegtwin (written from UR's published DH table, see the file).
pub const UR5E_URDF: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/assets/ur5e/ur5e.urdf");
/// The built-in robots' URDFs, embedded in the binary (they have no mesh files), so that a binary
/// copied or installed elsewhere, or the Python package, needs no source tree: name, text.
const BUILTIN_URDFS: [(&str, &str); 3] = [
    ("iiwa14", include_str!("../../../assets/iiwa14/iiwa14.urdf")),
    ("iiwa7", include_str!("../../../assets/iiwa7/iiwa7.urdf")),
    ("ur5e", include_str!("../../../assets/ur5e/ur5e.urdf")),
];
/// The built-in robots' names.
pub const BUILTIN_ROBOTS: [&str; 3] = ["iiwa14", "iiwa7", "ur5e"];

/// A loaded model and the warnings its loading raised.
pub struct Loaded {
    pub model: RobotModel,
    pub warnings: Vec<String>,
}

/// Loads `path`, resolving `package://` URIs against `search_path` (folders that hold packages, or
/// are packages themselves).
pub fn load(path: &Path, search_path: &[PathBuf]) -> Result<Loaded> {
    load_with_flange(path, search_path, None)
}

/// As [`load`], with the flange frame at link `flange` (the chain's last moving link or a link
/// fixed to it; `None`: the last link of the chain).
pub fn load_with_flange(
    path: &Path,
    search_path: &[PathBuf],
    flange: Option<&str>,
) -> Result<Loaded> {
    let text = crate::files::read_text(path)?;
    load_text(&text, path, search_path, flange)
}

/// Loads URDF `text` read from `path` (named in messages; meshes resolve from its folder).
pub fn load_text(
    text: &str,
    path: &Path,
    search_path: &[PathBuf],
    flange: Option<&str>,
) -> Result<Loaded> {
    check_xml(text).map_err(|msg| Error::file(path, format!("not a valid URDF: {msg}")))?;
    let robot = urdf_rs::read_from_string(text)
        .map_err(|e| Error::file(path, format!("not a valid URDF: {e}")))?;
    let dir = path.parent().unwrap_or(Path::new(".")).to_path_buf();
    let resolver = Resolver {
        urdf: path,
        dir,
        search_path,
    };
    build(&robot, &resolver, flange).map_err(|msg| Error::file(path, msg))
}

/// Loads the shipped iiwa 14 (embedded in the binary), with its tool-down IK seed.
pub fn iiwa14() -> Result<RobotModel> {
    Ok(builtin("iiwa14", None)?.model)
}

/// The iiwa 14's tool-down configuration in front of the robot (docs/sources.md, 1), rad: its
/// IK seed for the start pose.
pub const IIWA14_TOOL_DOWN_Q: [f64; 7] = [
    0.0,
    std::f64::consts::FRAC_PI_4,
    0.0,
    -std::f64::consts::FRAC_PI_2,
    0.0,
    std::f64::consts::FRAC_PI_4,
    0.0,
];

/// Loads a built-in robot ([`BUILTIN_ROBOTS`]) with its flange at link `flange` (`None`: the
/// file's). The iiwa 14 starts its inverse kinematics from [`IIWA14_TOOL_DOWN_Q`]; the others
/// search (`RobotModel::start_configuration`).
pub fn builtin(name: &str, flange: Option<&str>) -> Result<Loaded> {
    let shown = format!("{name}.urdf (built in)");
    let mut loaded = load_text(builtin_text(name)?, Path::new(&shown), &[], flange)?;
    if name == "iiwa14" {
        loaded.model.ik_seed = Some(IIWA14_TOOL_DOWN_Q.to_vec());
    }
    Ok(loaded)
}

/// The URDF text of a built-in robot ([`BUILTIN_ROBOTS`]).
pub fn builtin_text(name: &str) -> Result<&'static str> {
    BUILTIN_URDFS
        .iter()
        .find(|(n, _)| *n == name)
        .map(|(_, text)| *text)
        .ok_or_else(|| {
            Error::Input(format!(
                "robot '{name}': expected one of the built-in robots {}",
                BUILTIN_ROBOTS.join(", ")
            ))
        })
}

/// Numeric attributes of the URDF elements pegtwin reads: how many numbers each holds and the
/// plausible range of each number (SI: m, rad, kg, kg m^2, N or N m, m/s or rad/s). A value
/// outside it is a unit error or corrupt data, refused with the range in the message.
const NUMERIC_ATTRIBUTES: &[(&str, &str, usize, f64, f64)] = &[
    ("origin", "xyz", 3, -MAX_COORDINATE_M, MAX_COORDINATE_M),
    ("origin", "rpy", 3, -MAX_ANGLE_RAD, MAX_ANGLE_RAD),
    ("axis", "xyz", 3, -1e3, 1e3),
    ("mass", "value", 1, 0.0, MAX_LINK_MASS_KG),
    ("inertia", "ixx", 1, -MAX_INERTIA_KG_M2, MAX_INERTIA_KG_M2),
    ("inertia", "ixy", 1, -MAX_INERTIA_KG_M2, MAX_INERTIA_KG_M2),
    ("inertia", "ixz", 1, -MAX_INERTIA_KG_M2, MAX_INERTIA_KG_M2),
    ("inertia", "iyy", 1, -MAX_INERTIA_KG_M2, MAX_INERTIA_KG_M2),
    ("inertia", "iyz", 1, -MAX_INERTIA_KG_M2, MAX_INERTIA_KG_M2),
    ("inertia", "izz", 1, -MAX_INERTIA_KG_M2, MAX_INERTIA_KG_M2),
    ("limit", "lower", 1, -1e3, 1e3),
    ("limit", "upper", 1, -1e3, 1e3),
    ("limit", "effort", 1, 0.0, 1e6),
    ("limit", "velocity", 1, 0.0, 1e3),
    ("dynamics", "damping", 1, 0.0, 1e4),
    ("dynamics", "friction", 1, 0.0, 1e4),
    ("box", "size", 3, 0.0, MAX_COORDINATE_M),
    ("cylinder", "radius", 1, 0.0, MAX_COORDINATE_M),
    ("cylinder", "length", 1, 0.0, MAX_COORDINATE_M),
    ("sphere", "radius", 1, 0.0, MAX_COORDINATE_M),
    ("mesh", "scale", 3, -1e3, 1e3),
];

/// The heaviest link pegtwin accepts, kg (a large industrial arm's links weigh hundreds).
pub const MAX_LINK_MASS_KG: f64 = 1e4;
/// The largest inertia component pegtwin accepts, kg m^2.
pub const MAX_INERTIA_KG_M2: f64 = 1e4;
/// The deepest element nesting pegtwin reads (a URDF nests 5 deep; a deeper file is refused
/// before the XML deserialiser, which recurses, can overflow its stack on it).
pub const MAX_XML_DEPTH: usize = 32;

/// Checks the XML and the numeric attributes before urdf-rs reads the file, so that an error
/// names the line, the element and the attribute (urdf-rs reports only "invalid float literal").
fn check_xml(text: &str) -> std::result::Result<(), String> {
    let doc = roxmltree::Document::parse(text).map_err(|e| e.to_string())?;
    if doc.root_element().tag_name().name() != "robot" {
        return Err(format!(
            "the root element is <{}>, expected <robot>",
            doc.root_element().tag_name().name()
        ));
    }
    check_depth(&doc)?;
    for node in doc.descendants().filter(|n| n.is_element()) {
        let tag = node.tag_name().name();
        for (_, attr, count, min, max) in NUMERIC_ATTRIBUTES.iter().filter(|a| a.0 == tag) {
            let Some(value) = node.attribute(*attr) else {
                continue;
            };
            let numbers: Vec<Option<f64>> = value
                .split_whitespace()
                .map(|v| v.parse::<f64>().ok())
                .collect();
            let plausible = |n: &Option<f64>| n.is_some_and(|v| v >= *min && v <= *max);
            if numbers.len() != *count || !numbers.iter().all(plausible) {
                let line = doc.text_pos_at(node.range().start).row;
                return Err(format!(
                    "line {line}: <{tag} {attr}=\"{value}\">: expected {count} number{} in [{min}, {max}]",
                    if *count == 1 { "" } else { "s" }
                ));
            }
        }
    }
    Ok(())
}

/// Refuses element nesting deeper than [`MAX_XML_DEPTH`], without recursion: nodes come in
/// document order, so a parent's depth is known before its children's.
fn check_depth(doc: &roxmltree::Document) -> std::result::Result<(), String> {
    let mut depth = vec![0usize; doc.descendants().count()];
    for node in doc.descendants().filter(|n| n.is_element()) {
        let d = node.parent().map_or(0, |p| depth[p.id().get_usize()]) + 1;
        depth[node.id().get_usize()] = d;
        if d > MAX_XML_DEPTH {
            let line = doc.text_pos_at(node.range().start).row;
            return Err(format!(
                "line {line}: elements nest deeper than {MAX_XML_DEPTH} levels"
            ));
        }
    }
    Ok(())
}

struct Resolver<'a> {
    urdf: &'a Path,
    dir: PathBuf,
    search_path: &'a [PathBuf],
}

impl Resolver<'_> {
    /// Candidate files for a mesh URI, in search order.
    fn candidates(&self, uri: &str) -> Vec<PathBuf> {
        if let Some(rest) = uri.strip_prefix("package://") {
            let (pkg, rel) = rest.split_once('/').unwrap_or((rest, ""));
            let mut roots: Vec<PathBuf> = self.search_path.to_vec();
            roots.extend(self.dir.ancestors().map(Path::to_path_buf));
            roots
                .iter()
                .flat_map(|root| {
                    let inside = root.join(pkg).join(rel);
                    let is_pkg = root.file_name().is_some_and(|n| n == pkg);
                    std::iter::once(inside).chain(is_pkg.then(|| root.join(rel)))
                })
                .collect()
        } else if let Some(abs) = uri.strip_prefix("file://") {
            vec![PathBuf::from(abs)]
        } else {
            vec![self.dir.join(uri)]
        }
    }

    fn find(&self, uri: &str) -> Option<PathBuf> {
        self.candidates(uri).into_iter().find(|p| p.is_file())
    }
}

fn build(
    robot: &urdf_rs::Robot,
    res: &Resolver,
    flange: Option<&str>,
) -> std::result::Result<Loaded, String> {
    let links: HashMap<&str, &urdf_rs::Link> =
        robot.links.iter().map(|l| (l.name.as_str(), l)).collect();
    if links.len() != robot.links.len() {
        return Err("two <link> elements have the same name".into());
    }
    let children = check_joints(robot, &links)?;
    let root = find_root(robot)?;
    let mut warnings = Vec::new();
    let mut base = Link {
        name: root.into(),
        inertial: Inertial::ZERO,
        collision: vec![],
    };
    add_link_body(
        &mut base,
        links[root],
        &nalgebra::Isometry3::identity(),
        res,
        &mut warnings,
    )?;
    let mut chain = walk_chain(root, &children, &links, &mut base, res, &mut warnings)?;
    check_connected(robot, &chain.visited)?;
    if let Some(name) = flange {
        chain.move_flange_to(name)?;
    }
    check_moving_masses(&chain.links)?;
    let n = chain.joints.len();
    Ok(Loaded {
        model: RobotModel {
            name: robot.name.clone(),
            base,
            joints: chain.joints,
            links: chain.links,
            flange_name: chain.tip.into(),
            last_t_flange: chain.tip_offset,
            armature: default_armature(n),
            tool: None,
            ik_seed: None,
            content_key: None,
        },
        warnings,
    })
}

/// Child joints by parent link, after checking that joint names are unique, that both ends of
/// every joint exist and differ, and that no link is the child of two joints.
fn check_joints<'a>(
    robot: &'a urdf_rs::Robot,
    links: &HashMap<&str, &urdf_rs::Link>,
) -> std::result::Result<HashMap<&'a str, Vec<&'a urdf_rs::Joint>>, String> {
    let mut names = HashSet::new();
    let mut parent_of: HashMap<&str, &str> = HashMap::new();
    let mut children: HashMap<&str, Vec<&urdf_rs::Joint>> = HashMap::new();
    for j in &robot.joints {
        let at = |what: String| format!("<joint name=\"{}\">: {what}", j.name);
        if !names.insert(j.name.as_str()) {
            return Err(at(
                "a second joint has this name; joint names must be unique".into(),
            ));
        }
        for (role, name) in [("parent", &j.parent.link), ("child", &j.child.link)] {
            if !links.contains_key(name.as_str()) {
                return Err(at(format!("{role} link '{name}' is not defined")));
            }
        }
        if j.parent.link == j.child.link {
            return Err(at(format!(
                "parent and child are the same link '{}'",
                j.child.link
            )));
        }
        if let Some(other) = parent_of.insert(j.child.link.as_str(), j.name.as_str()) {
            return Err(at(format!(
                "link '{}' is already the child of joint '{other}'; a link has one parent",
                j.child.link
            )));
        }
        children.entry(j.parent.link.as_str()).or_default().push(j);
    }
    Ok(children)
}

/// The one link that is no joint's child.
fn find_root(robot: &urdf_rs::Robot) -> std::result::Result<&str, String> {
    let roots: Vec<&str> = robot
        .links
        .iter()
        .map(|l| l.name.as_str())
        .filter(|n| !robot.joints.iter().any(|j| j.child.link == *n))
        .collect();
    match roots.as_slice() {
        [r] => Ok(*r),
        [] => Err("no root link: every link is some joint's child (a loop)".into()),
        many => Err(format!("more than one root link: {}", many.join(", "))),
    }
}

/// The serial chain read from the root to the tip.
struct Chain<'a> {
    joints: Vec<Joint>,
    links: Vec<Link>,
    /// The last link reached (the flange frame).
    tip: &'a str,
    /// Pose of the tip's frame in the last moving link's frame.
    tip_offset: nalgebra::Isometry3<f64>,
    /// Every link reached, the root included.
    visited: HashSet<&'a str>,
    /// The last moving link and the links fixed to it, with their frames in its frame.
    tip_links: Vec<(&'a str, nalgebra::Isometry3<f64>)>,
}

impl Chain<'_> {
    /// Puts the flange frame at link `name`: the last moving link or one fixed to it.
    fn move_flange_to(&mut self, name: &str) -> std::result::Result<(), String> {
        if let Some((tip, offset)) = self.tip_links.iter().find(|(n, _)| *n == name) {
            self.tip = tip;
            self.tip_offset = *offset;
            return Ok(());
        }
        let tips: Vec<&str> = self.tip_links.iter().map(|(n, _)| *n).collect();
        let why = if self.visited.contains(name) {
            "is not at the chain's tip (moving joints follow it)"
        } else {
            "is not a link of this URDF"
        };
        Err(format!(
            "flange link '{name}' {why}; expected one of {}",
            tips.join(", ")
        ))
    }
}

/// Walks from the root along the one child joint of each link, folding fixed joints into the link
/// before them; refuses a branch.
fn walk_chain<'a>(
    root: &'a str,
    children: &HashMap<&'a str, Vec<&'a urdf_rs::Joint>>,
    links: &HashMap<&str, &urdf_rs::Link>,
    base: &mut Link,
    res: &Resolver,
    warnings: &mut Vec<String>,
) -> std::result::Result<Chain<'a>, String> {
    let mut chain = Chain {
        joints: Vec::new(),
        links: Vec::new(),
        tip: root,
        tip_offset: nalgebra::Isometry3::identity(),
        visited: HashSet::from([root]),
        tip_links: Vec::new(),
    };
    loop {
        let joint = match children.get(chain.tip).map(Vec::as_slice).unwrap_or(&[]) {
            [] => break,
            [j] => *j,
            many => {
                let names: Vec<&str> = many.iter().map(|j| j.name.as_str()).collect();
                return Err(format!(
                    "link '{}' has {} child joints ({}): only serial chains are supported",
                    chain.tip,
                    many.len(),
                    names.join(", ")
                ));
            }
        };
        let origin = chain.tip_offset * iso_xyz_rpy(joint.origin.xyz.0, joint.origin.rpy.0);
        let child = links[joint.child.link.as_str()];
        match &joint.joint_type {
            urdf_rs::JointType::Fixed => {
                chain.tip_offset = origin;
                chain.tip_links.push((joint.child.link.as_str(), origin));
                let target = chain.links.last_mut().unwrap_or(&mut *base);
                add_link_body(target, child, &origin, res, warnings)?;
            }
            urdf_rs::JointType::Revolute
            | urdf_rs::JointType::Continuous
            | urdf_rs::JointType::Prismatic => {
                chain.joints.push(movable_joint(joint, origin)?);
                chain.tip_offset = nalgebra::Isometry3::identity();
                chain.tip_links = vec![(joint.child.link.as_str(), chain.tip_offset)];
                let mut link = Link {
                    name: child.name.clone(),
                    inertial: Inertial::ZERO,
                    collision: vec![],
                };
                add_link_body(&mut link, child, &chain.tip_offset, res, warnings)?;
                chain.links.push(link);
            }
            other => {
                return Err(format!(
                    "<joint name=\"{}\">: type {other:?} is not supported (revolute, continuous, prismatic or fixed)",
                    joint.name
                ));
            }
        }
        chain.tip = joint.child.link.as_str();
        chain.visited.insert(chain.tip);
    }
    if chain.joints.is_empty() {
        return Err("the chain has no movable joint".into());
    }
    Ok(chain)
}

/// Refuses links the chain from the root never reaches (a detached part or a loop of joints).
fn check_connected(
    robot: &urdf_rs::Robot,
    visited: &HashSet<&str>,
) -> std::result::Result<(), String> {
    let unreached: Vec<&str> = robot
        .links
        .iter()
        .map(|l| l.name.as_str())
        .filter(|n| !visited.contains(n))
        .collect();
    if unreached.is_empty() {
        Ok(())
    } else {
        Err(format!(
            "links not connected to the chain from the root: {}",
            unreached.join(", ")
        ))
    }
}

/// A moving link (with the links fixed to it) needs a mass and an inertia the solver can invert.
fn check_moving_masses(links: &[Link]) -> std::result::Result<(), String> {
    for l in links {
        let eig = l.inertial.inertia.symmetric_eigenvalues();
        if l.inertial.mass_kg <= 0.0 || eig.iter().any(|&e| e <= 0.0) {
            return Err(format!(
                "<link name=\"{}\">: a moving link (with the links fixed to it) needs a mass > 0 kg \
                 and a positive-definite inertia; it has {} kg and principal inertias {:?} kg m^2",
                l.name,
                l.inertial.mass_kg,
                eig.as_slice()
            ));
        }
    }
    Ok(())
}

fn movable_joint(
    j: &urdf_rs::Joint,
    origin: nalgebra::Isometry3<f64>,
) -> std::result::Result<Joint, String> {
    let at = |what: &str| format!("<joint name=\"{}\">: {what}", j.name);
    let axis = Vector3::from(j.axis.xyz.0);
    if axis.norm() <= 1e-9 {
        return Err(at("<axis xyz> must be a non-zero vector"));
    }
    let continuous = j.joint_type == urdf_rs::JointType::Continuous;
    let (lower, upper) = if continuous {
        (f64::NEG_INFINITY, f64::INFINITY)
    } else {
        (j.limit.lower, j.limit.upper)
    };
    if !continuous && lower >= upper {
        return Err(at(&format!(
            "<limit lower=\"{lower}\" upper=\"{upper}\">: lower must be below upper"
        )));
    }
    if j.limit.effort <= 0.0 {
        return Err(at(&format!(
            "<limit effort=\"{}\">: expected a positive torque limit",
            j.limit.effort
        )));
    }
    if j.limit.velocity <= 0.0 {
        return Err(at(&format!(
            "<limit velocity=\"{}\">: expected a positive speed limit",
            j.limit.velocity
        )));
    }
    let dynamics = j.dynamics.clone().unwrap_or_default();
    if dynamics.damping < 0.0 || dynamics.friction < 0.0 {
        return Err(at("<dynamics> damping and friction must not be negative"));
    }
    Ok(Joint {
        name: j.name.clone(),
        kind: if j.joint_type == urdf_rs::JointType::Prismatic {
            JointKind::Prismatic
        } else {
            JointKind::Revolute
        },
        origin,
        axis: axis.normalize(),
        lower,
        upper,
        velocity_limit: j.limit.velocity,
        effort_limit: j.limit.effort,
        damping: dynamics.damping,
        friction: dynamics.friction,
    })
}

/// A rigid body's inertia: principal moments non-negative and obeying the triangle inequality
/// (each at most the sum of the other two), with a relative tolerance for rounded files.
fn physical_inertia(inertia: &Matrix3<f64>) -> bool {
    let e = inertia.symmetric_eigenvalues();
    let tol = 1e-6 * e.iter().map(|v| v.abs()).sum::<f64>() + 1e-12;
    e.iter().all(|&v| v >= -tol) && (0..3).all(|k| e[k] <= e[(k + 1) % 3] + e[(k + 2) % 3] + tol)
}

/// Adds a URDF link's inertial and collision shapes to `target`, the link sitting at `pose` in
/// `target`'s frame.
fn add_link_body(
    target: &mut Link,
    link: &urdf_rs::Link,
    pose: &nalgebra::Isometry3<f64>,
    res: &Resolver,
    warnings: &mut Vec<String>,
) -> std::result::Result<(), String> {
    let at = |what: String| format!("<link name=\"{}\">: {what}", link.name);
    let i = &link.inertial;
    if i.mass.value < 0.0 {
        return Err(at(format!(
            "<mass value=\"{}\">: expected a mass >= 0 kg",
            i.mass.value
        )));
    }
    let t = &i.inertia;
    let inertia = Matrix3::new(
        t.ixx, t.ixy, t.ixz, t.ixy, t.iyy, t.iyz, t.ixz, t.iyz, t.izz,
    );
    if i.mass.value > 0.0 && !physical_inertia(&inertia) {
        return Err(at(
            "<inertia> is not a physical inertia: its principal moments must be >= 0 and each \
             at most the sum of the other two"
                .into(),
        ));
    }
    let own = Inertial {
        mass_kg: i.mass.value,
        com: Point3::origin(),
        inertia,
    }
    .transformed(&iso_xyz_rpy(i.origin.xyz.0, i.origin.rpy.0));
    target.inertial = target.inertial.combined(&own.transformed(pose));
    for c in &link.collision {
        let shape = collision_shape(&c.geometry, res).map_err(at)?;
        target.collision.push(CollisionShape {
            origin: pose * iso_xyz_rpy(c.origin.xyz.0, c.origin.rpy.0),
            shape,
        });
    }
    for v in &link.visual {
        if let urdf_rs::Geometry::Mesh { filename, .. } = &v.geometry
            && res.find(filename).is_none()
        {
            warnings.push(format!(
                "{}: <link name=\"{}\"> visual mesh '{filename}' not found (ignored: pegtwin does not render)",
                res.urdf.display(),
                link.name
            ));
        }
    }
    Ok(())
}

fn collision_shape(g: &urdf_rs::Geometry, res: &Resolver) -> std::result::Result<Shape, String> {
    let positive = |name: &str, v: f64| {
        if v > 0.0 && v.is_finite() {
            Ok(v)
        } else {
            Err(format!(
                "collision {name} {v}: expected a positive length in m"
            ))
        }
    };
    Ok(match g {
        urdf_rs::Geometry::Box { size } => Shape::Box {
            half_extents: Vector3::new(
                positive("box size", size[0])?,
                positive("box size", size[1])?,
                positive("box size", size[2])?,
            ) / 2.0,
        },
        urdf_rs::Geometry::Cylinder { radius, length } => Shape::Cylinder {
            radius: positive("cylinder radius", *radius)?,
            length: positive("cylinder length", *length)?,
        },
        urdf_rs::Geometry::Capsule { radius, length } => Shape::Capsule {
            radius: positive("capsule radius", *radius)?,
            length: positive("capsule length", *length)?,
        },
        urdf_rs::Geometry::Sphere { radius } => Shape::Sphere {
            radius: positive("sphere radius", *radius)?,
        },
        urdf_rs::Geometry::Mesh { filename, scale } => {
            let Some(path) = res.find(filename) else {
                let tried: Vec<String> = res
                    .candidates(filename)
                    .iter()
                    .map(|p| p.display().to_string())
                    .collect();
                return Err(format!(
                    "collision mesh '{filename}' not found (looked for: {})",
                    tried.join(", ")
                ));
            };
            let soup = read_mesh(&path, MeshUnits::M).map_err(|e| e.to_string())?;
            let s = scale.map_or([1.0; 3], |s| s.0);
            Shape::ConvexHull {
                points: soup
                    .vertices
                    .iter()
                    .map(|p| Point3::new(p.x * s[0], p.y * s[1], p.z * s[2]))
                    .collect(),
            }
        }
    })
}
