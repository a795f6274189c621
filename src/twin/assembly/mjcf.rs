//! MuJoCo users' files: the collision geoms of one body of an MJCF model, as the convex parts of
//! a peg or a hole (`[peg] mjcf = "env.xml"`, `body = "peg"`). MuJoCo collides a mesh geom as
//! the convex hull of its mesh, so each mesh geom is one convex part here too; `box` geoms are
//! taken as boxes. Read: `<compiler meshdir|assetdir angle eulerseq>`, `<asset><mesh name file
//! scale>`, and under the body (and its child bodies) every geom's `type`, `mesh`, `size`, `pos`,
//! `quat` (w x y z) and `euler`, and child bodies' `pos`, `quat`, `euler`. The parts come out in
//! the body's own frame; anything else that would place a geom (`axisangle`, `xyaxes`, `zaxis`,
//! `fromto`, default classes, `<include>`) is refused by name rather than misread.

use crate::error::{Error, Result};
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use roxmltree::{Document, Node};
use std::path::{Path, PathBuf};

/// What a geom is made of.
#[derive(Clone, Debug, PartialEq)]
pub enum GeomShape {
    /// A mesh file, its vertices multiplied by `scale` (model units).
    Mesh { file: PathBuf, scale: Vector3<f64> },
    /// A box of these half-extents (model units).
    Box { half_extents: Vector3<f64> },
}

/// One collision geom of the body, placed in the body's frame (model units).
#[derive(Clone, Debug)]
pub struct Geom {
    pub shape: GeomShape,
    pub body_t_geom: Isometry3<f64>,
}

/// How the model writes angles.
struct Angles {
    degrees: bool,
    /// `eulerseq`: three of x, y, z (intrinsic, lower case) or X, Y, Z (extrinsic).
    sequence: String,
}

/// The geoms of `body` in the MJCF file `path`.
pub fn body_geoms(path: &Path, body: &str) -> Result<Vec<Geom>> {
    let text = crate::files::read_text(path)?;
    let doc =
        Document::parse(&text).map_err(|e| Error::file(path, format!("not valid XML: {e}")))?;
    let fail = |msg: String| Error::file(path, msg);
    let root = doc.root_element();
    if root.tag_name().name() != "mujoco" {
        return Err(fail(
            "not an MJCF model: expected a <mujoco> root element".into(),
        ));
    }
    if root.descendants().any(|n| n.has_tag_name("include")) {
        return Err(fail(
            "<include> is not supported: put the included file's elements in".into(),
        ));
    }
    let dir = path.parent().unwrap_or(Path::new("."));
    let (angles, mesh_dir) = compiler(root, dir).map_err(fail)?;
    let target = root
        .descendants()
        .find(|n| n.has_tag_name("body") && n.attribute("name") == Some(body))
        .ok_or_else(|| fail(format!("no <body name=\"{body}\"> in the model")))?;
    let mut geoms = Vec::new();
    collect(target, &Isometry3::identity(), &angles, &mut geoms).map_err(fail)?;
    let geoms = geoms
        .into_iter()
        .map(|(node, place)| geom(root, node, place, &angles, &mesh_dir))
        .collect::<std::result::Result<Vec<_>, String>>()
        .map_err(fail)?;
    if geoms.is_empty() {
        return Err(fail(format!("<body name=\"{body}\"> holds no geom")));
    }
    Ok(geoms)
}

/// The compiler's angle convention and the folder mesh files are relative to.
fn compiler(root: Node, dir: &Path) -> std::result::Result<(Angles, PathBuf), String> {
    let c = root.children().find(|n| n.has_tag_name("compiler"));
    let get = |name: &str| c.and_then(|c| c.attribute(name));
    let degrees = match get("angle").unwrap_or("degree") {
        "degree" => true,
        "radian" => false,
        other => {
            return Err(format!(
                "compiler angle=\"{other}\": expected degree or radian"
            ));
        }
    };
    let sequence = get("eulerseq").unwrap_or("xyz").to_string();
    let valid = sequence.len() == 3
        && (sequence.chars().all(|c| "xyz".contains(c))
            || sequence.chars().all(|c| "XYZ".contains(c)));
    if !valid {
        return Err(format!(
            "compiler eulerseq=\"{sequence}\": expected three of xyz or XYZ"
        ));
    }
    let mesh_dir = dir.join(get("meshdir").or(get("assetdir")).unwrap_or(""));
    Ok((Angles { degrees, sequence }, mesh_dir))
}

/// Every geom under `body` with the pose of its body in the target body's frame.
fn collect<'a>(
    body: Node<'a, 'a>,
    place: &Isometry3<f64>,
    angles: &Angles,
    out: &mut Vec<(Node<'a, 'a>, Isometry3<f64>)>,
) -> std::result::Result<(), String> {
    for child in body.children().filter(Node::is_element) {
        match child.tag_name().name() {
            "geom" => out.push((child, *place)),
            "body" => {
                let inner = place * pose(child, angles)?;
                collect(child, &inner, angles, out)?;
            }
            _ => {}
        }
    }
    Ok(())
}

/// The pose an element's `pos`, `quat` and `euler` give.
fn pose(node: Node, angles: &Angles) -> std::result::Result<Isometry3<f64>, String> {
    let what = describe(node);
    for refused in ["axisangle", "xyaxes", "zaxis", "fromto"] {
        if node.attribute(refused).is_some() {
            return Err(format!(
                "{what}: {refused}= is not supported: give pos, quat or euler"
            ));
        }
    }
    let pos = match node.attribute("pos") {
        Some(v) => vector(v, &what, "pos")?,
        None => Vector3::zeros(),
    };
    let rotation = match (node.attribute("quat"), node.attribute("euler")) {
        (Some(_), Some(_)) => return Err(format!("{what}: give quat or euler, not both")),
        (Some(q), None) => quaternion(q, &what)?,
        (None, Some(e)) => euler(vector(e, &what, "euler")?, angles),
        (None, None) => UnitQuaternion::identity(),
    };
    Ok(Isometry3::from_parts(Translation3::from(pos), rotation))
}

/// `<geom name="...">` or `<body>` for messages.
fn describe(node: Node) -> String {
    match node.attribute("name") {
        Some(n) => format!("<{} name=\"{n}\">", node.tag_name().name()),
        None => format!("<{}> (line {})", node.tag_name().name(), line_of(node)),
    }
}

fn line_of(node: Node) -> u32 {
    node.document().text_pos_at(node.range().start).row
}

fn numbers(text: &str, what: &str, field: &str) -> std::result::Result<Vec<f64>, String> {
    text.split_whitespace()
        .map(|t| {
            t.parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| format!("{what}: {field}=\"{text}\": '{t}' is not a number"))
        })
        .collect()
}

fn vector(text: &str, what: &str, field: &str) -> std::result::Result<Vector3<f64>, String> {
    match numbers(text, what, field)?.as_slice() {
        [x, y, z] => Ok(Vector3::new(*x, *y, *z)),
        _ => Err(format!(
            "{what}: {field}=\"{text}\": expected three numbers"
        )),
    }
}

fn quaternion(text: &str, what: &str) -> std::result::Result<UnitQuaternion<f64>, String> {
    match numbers(text, what, "quat")?.as_slice() {
        [w, x, y, z] if (w * w + x * x + y * y + z * z) > 1e-12 => Ok(
            UnitQuaternion::new_normalize(nalgebra::Quaternion::new(*w, *x, *y, *z)),
        ),
        _ => Err(format!(
            "{what}: quat=\"{text}\": expected four numbers w x y z, not all 0"
        )),
    }
}

/// MuJoCo's Euler angles: three rotations about the axes of `eulerseq`, lower case about the
/// moving (intrinsic) axes, upper case about the fixed (extrinsic) ones.
fn euler(angles_in: Vector3<f64>, angles: &Angles) -> UnitQuaternion<f64> {
    let scale = if angles.degrees {
        std::f64::consts::PI / 180.0
    } else {
        1.0
    };
    let mut q = UnitQuaternion::identity();
    for (k, axis) in angles.sequence.chars().enumerate() {
        let unit = match axis.to_ascii_lowercase() {
            'x' => Vector3::x_axis(),
            'y' => Vector3::y_axis(),
            _ => Vector3::z_axis(),
        };
        let r = UnitQuaternion::from_axis_angle(&unit, angles_in[k] * scale);
        q = if axis.is_ascii_lowercase() {
            q * r
        } else {
            r * q
        };
    }
    q
}

/// One geom: its shape (a mesh asset or a box) and its pose in the body's frame.
fn geom(
    root: Node,
    node: Node,
    place: Isometry3<f64>,
    angles: &Angles,
    mesh_dir: &Path,
) -> std::result::Result<Geom, String> {
    let what = describe(node);
    let kind = match (node.attribute("type"), node.attribute("mesh")) {
        (Some(t), _) => t,
        (None, Some(_)) => "mesh",
        (None, None) if node.attribute("class").is_some() => {
            return Err(format!(
                "{what}: its type comes from a default class, which is not read: give type="
            ));
        }
        (None, None) => "sphere",
    };
    let shape = match kind {
        "mesh" => mesh_asset(root, node, &what, mesh_dir)?,
        "box" => {
            let size = node
                .attribute("size")
                .ok_or_else(|| format!("{what}: a box needs size=\"hx hy hz\""))?;
            GeomShape::Box {
                half_extents: vector(size, &what, "size")?,
            }
        }
        other => {
            return Err(format!(
                "{what}: type=\"{other}\" is not supported: give mesh or box geoms (export \
                 round shapes as meshes)"
            ));
        }
    };
    Ok(Geom {
        shape,
        body_t_geom: place * pose(node, angles)?,
    })
}

/// The `<mesh>` asset a geom names: its file (relative to meshdir) and scale.
fn mesh_asset(
    root: Node,
    geom: Node,
    what: &str,
    mesh_dir: &Path,
) -> std::result::Result<GeomShape, String> {
    let name = geom
        .attribute("mesh")
        .ok_or_else(|| format!("{what}: a mesh geom needs mesh=\"NAME\""))?;
    let asset = root
        .descendants()
        .filter(|n| n.has_tag_name("mesh") && n.parent().is_some_and(|p| p.has_tag_name("asset")))
        .find(|n| {
            let file_stem = n
                .attribute("file")
                .and_then(|f| Path::new(f).file_stem())
                .and_then(|s| s.to_str());
            n.attribute("name").or(file_stem) == Some(name)
        })
        .ok_or_else(|| format!("{what}: no <mesh name=\"{name}\"> in <asset>"))?;
    let file = asset
        .attribute("file")
        .ok_or_else(|| format!("<mesh name=\"{name}\">: no file= (only mesh files are read)"))?;
    let scale = match asset.attribute("scale") {
        Some(s) => vector(s, &format!("<mesh name=\"{name}\">"), "scale")?,
        None => Vector3::repeat(1.0),
    };
    Ok(GeomShape::Mesh {
        file: mesh_dir.join(file),
        scale,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn euler_sequences_follow_mujoco() {
        let intrinsic = Angles {
            degrees: true,
            sequence: "xyz".into(),
        };
        let q = euler(Vector3::new(90.0, 0.0, 90.0), &intrinsic);
        // R = Rx(90) Rz(90): x turns to y, then y to z.
        let x = q * Vector3::x();
        assert!((x - Vector3::new(0.0, 0.0, 1.0)).norm() < 1e-12, "{x}");
        let extrinsic = Angles {
            degrees: false,
            sequence: "XYZ".into(),
        };
        let q = euler(
            Vector3::new(std::f64::consts::FRAC_PI_2, 0.0, 0.0),
            &extrinsic,
        );
        assert!((q * Vector3::y() - Vector3::z()).norm() < 1e-12);
    }
}
