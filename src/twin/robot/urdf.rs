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
use crate::twin::geometry::mesh::{MeshUnits, read_mesh};
use nalgebra::{Matrix3, Point3, Vector3};
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// The iiwa 14 shipped with pegtwin.
pub const IIWA14_URDF: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/assets/iiwa14/iiwa14.urdf");
/// The iiwa 7 variant shipped with pegtwin (placeholder inertials, see the file).
pub const IIWA7_URDF: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/assets/iiwa7/iiwa7.urdf");

/// A loaded model and the warnings its loading raised.
pub struct Loaded {
    pub model: RobotModel,
    pub warnings: Vec<String>,
}

/// Loads `path`, resolving `package://` URIs against `search_path` (folders that hold packages, or
/// are packages themselves).
pub fn load(path: &Path, search_path: &[PathBuf]) -> Result<Loaded> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| Error::file(path, format!("cannot read: {e}")))?;
    check_xml(&text).map_err(|msg| Error::file(path, format!("not a valid URDF: {msg}")))?;
    let robot = urdf_rs::read_from_string(&text)
        .map_err(|e| Error::file(path, format!("not a valid URDF: {e}")))?;
    let dir = path.parent().unwrap_or(Path::new(".")).to_path_buf();
    let resolver = Resolver {
        urdf: path,
        dir,
        search_path,
    };
    build(&robot, &resolver).map_err(|msg| Error::file(path, msg))
}

/// Loads the shipped iiwa 14.
pub fn iiwa14() -> Result<RobotModel> {
    Ok(load(Path::new(IIWA14_URDF), &[])?.model)
}

/// Numeric attributes of the URDF elements pegtwin reads, and how many numbers each holds.
const NUMERIC_ATTRIBUTES: &[(&str, &str, usize)] = &[
    ("origin", "xyz", 3),
    ("origin", "rpy", 3),
    ("axis", "xyz", 3),
    ("mass", "value", 1),
    ("inertia", "ixx", 1),
    ("inertia", "ixy", 1),
    ("inertia", "ixz", 1),
    ("inertia", "iyy", 1),
    ("inertia", "iyz", 1),
    ("inertia", "izz", 1),
    ("limit", "lower", 1),
    ("limit", "upper", 1),
    ("limit", "effort", 1),
    ("limit", "velocity", 1),
    ("dynamics", "damping", 1),
    ("dynamics", "friction", 1),
    ("box", "size", 3),
    ("cylinder", "radius", 1),
    ("cylinder", "length", 1),
    ("sphere", "radius", 1),
    ("mesh", "scale", 3),
];

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
    for node in doc.descendants().filter(|n| n.is_element()) {
        let tag = node.tag_name().name();
        for (_, attr, count) in NUMERIC_ATTRIBUTES.iter().filter(|(t, _, _)| *t == tag) {
            let Some(value) = node.attribute(*attr) else {
                continue;
            };
            let numbers: Vec<Option<f64>> = value
                .split_whitespace()
                .map(|v| v.parse::<f64>().ok())
                .collect();
            if numbers.len() != *count || numbers.iter().any(|n| n.is_none_or(|v| !v.is_finite())) {
                let line = doc.text_pos_at(node.range().start).row;
                return Err(format!(
                    "line {line}: <{tag} {attr}=\"{value}\">: expected {count} finite number{}",
                    if *count == 1 { "" } else { "s" }
                ));
            }
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

fn build(robot: &urdf_rs::Robot, res: &Resolver) -> std::result::Result<Loaded, String> {
    let mut warnings = Vec::new();
    let links: HashMap<&str, &urdf_rs::Link> =
        robot.links.iter().map(|l| (l.name.as_str(), l)).collect();
    if links.len() != robot.links.len() {
        return Err("two <link> elements have the same name".into());
    }
    let mut children: HashMap<&str, Vec<&urdf_rs::Joint>> = HashMap::new();
    for j in &robot.joints {
        for (role, name) in [("parent", &j.parent.link), ("child", &j.child.link)] {
            if !links.contains_key(name.as_str()) {
                return Err(format!(
                    "<joint name=\"{}\">: {role} link '{name}' is not defined",
                    j.name
                ));
            }
        }
        children.entry(j.parent.link.as_str()).or_default().push(j);
    }
    let roots: Vec<&str> = robot
        .links
        .iter()
        .map(|l| l.name.as_str())
        .filter(|n| !robot.joints.iter().any(|j| j.child.link == *n))
        .collect();
    let root = match roots.as_slice() {
        [r] => *r,
        [] => return Err("no root link: every link is some joint's child (a loop)".into()),
        many => return Err(format!("more than one root link: {}", many.join(", "))),
    };

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
    let mut joints: Vec<Joint> = Vec::new();
    let mut model_links: Vec<Link> = Vec::new();
    // Pose of the current link's frame in the frame of the last movable joint's child (or base).
    let mut fixed_offset = nalgebra::Isometry3::identity();
    let mut current = root;
    loop {
        let next = children.get(current).map(Vec::as_slice).unwrap_or(&[]);
        let joint = match next {
            [] => break,
            [j] => *j,
            many => {
                let names: Vec<&str> = many.iter().map(|j| j.name.as_str()).collect();
                return Err(format!(
                    "link '{current}' has {} child joints ({}): only serial chains are supported",
                    many.len(),
                    names.join(", ")
                ));
            }
        };
        let origin = fixed_offset * iso_xyz_rpy(joint.origin.xyz.0, joint.origin.rpy.0);
        let child = links[joint.child.link.as_str()];
        match &joint.joint_type {
            urdf_rs::JointType::Fixed => {
                fixed_offset = origin;
                let target = model_links.last_mut().unwrap_or(&mut base);
                add_link_body(target, child, &fixed_offset, res, &mut warnings)?;
            }
            urdf_rs::JointType::Revolute
            | urdf_rs::JointType::Continuous
            | urdf_rs::JointType::Prismatic => {
                joints.push(movable_joint(joint, origin)?);
                fixed_offset = nalgebra::Isometry3::identity();
                let mut link = Link {
                    name: child.name.clone(),
                    inertial: Inertial::ZERO,
                    collision: vec![],
                };
                add_link_body(&mut link, child, &fixed_offset, res, &mut warnings)?;
                model_links.push(link);
            }
            other => {
                return Err(format!(
                    "<joint name=\"{}\">: type {other:?} is not supported (revolute, continuous, prismatic or fixed)",
                    joint.name
                ));
            }
        }
        current = joint.child.link.as_str();
    }
    if joints.is_empty() {
        return Err("the chain has no movable joint".into());
    }
    let n = joints.len();
    Ok(Loaded {
        model: RobotModel {
            name: robot.name.clone(),
            base,
            joints,
            links: model_links,
            flange_name: current.into(),
            last_t_flange: fixed_offset,
            armature: default_armature(n),
            tool: None,
        },
        warnings,
    })
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
    if i.mass.value > 0.0 && !inertia.symmetric_eigenvalues().iter().all(|&e| e >= -1e-12) {
        return Err(at("<inertia> is not positive semi-definite".into()));
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
