//! MuJoCo users' files: the collision geoms of one body of an MJCF model, as the convex parts of
//! a peg or a hole (`[peg] mjcf = "env.xml"`, `body = "peg"`), read as MuJoCo's compiler reads
//! them. The model's `<include>`s are spliced in ([`tree`]); each geom takes its default class
//! ([`defaults`]); its pose comes from `pos` and any one orientation, or from `fromto`
//! ([`orient`]), composed through the child bodies and `<frame>`s down from the named body. A
//! mesh geom is the convex hull of its mesh (as MuJoCo collides it), its vertices moved by the
//! asset's `refpos`/`refquat` and multiplied by its `scale`; `box` is a box, and `sphere`,
//! `capsule`, `cylinder` and `ellipsoid` are polygonised ([`crate::twin::geometry::round`]).
//! Geoms that collide with nothing (`contype` and `conaffinity` both 0) are left out; which of
//! the rest collide with the other part is the assembly's to check ([`collide`]). `group` does
//! not choose collisions in MuJoCo (it is for display), and is not read. The parts come out in
//! the body's own frame, in model units; anything that would change them and is not read is
//! refused by element, attribute and line.

pub mod defaults;
pub mod orient;
pub mod tree;

use crate::error::{Error, Result};
use crate::twin::geometry::mesh::read_mesh_as_written;
use crate::twin::geometry::round::Round;
use crate::twin::geometry::solid::TriangleSoup;
use defaults::{Attrs, Defaults};
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use orient::{Angles, fixed, from_to, pose};
use serde::Serialize;
use std::path::{Path, PathBuf};
use tree::Element;

/// What a geom is made of (model units).
#[derive(Clone, Debug, PartialEq)]
pub enum GeomShape {
    /// A mesh file whose vertex `v` becomes `scale * refquat^-1 (v - refpos)` (MuJoCo's order):
    /// `reference` is the asset's `refpos`/`refquat` pose.
    Mesh {
        file: PathBuf,
        scale: Vector3<f64>,
        reference: Isometry3<f64>,
    },
    /// A box of these half-extents.
    Box { half_extents: Vector3<f64> },
    /// A sphere, capsule, cylinder or ellipsoid.
    Round(Round),
}

/// One collision geom of the body, placed in the body's frame (model units).
#[derive(Clone, Debug)]
pub struct Geom {
    /// How messages name it: `<geom name="tip"> (line 12)`.
    pub what: String,
    pub name: Option<String>,
    pub shape: GeomShape,
    pub body_t_geom: Isometry3<f64>,
    /// MuJoCo's collision bits: two geoms collide when either's `contype` shares a bit with
    /// the other's `conaffinity`.
    pub contype: u32,
    pub conaffinity: u32,
}

/// Whether MuJoCo lets two geoms collide (its `contype`/`conaffinity` rule).
pub fn collide(a: &Geom, b: &Geom) -> bool {
    bits_collide(a.bits(), b.bits())
}

/// MuJoCo's rule on (`contype`, `conaffinity`) pairs: either's `contype` shares a bit with the
/// other's `conaffinity`.
pub fn bits_collide(a: (u32, u32), b: (u32, u32)) -> bool {
    a.0 & b.1 != 0 || b.0 & a.1 != 0
}

/// The model's settings a geom's reading needs.
struct Model {
    angles: Angles,
    defaults: Defaults,
    mesh_dir: PathBuf,
    assets: Vec<Element>,
}

/// The collision geoms of `body` (and its child bodies) in the MJCF file `path`.
pub fn body_geoms(path: &Path, body: &str) -> Result<Vec<Geom>> {
    let fail = |msg: String| Error::file(path, msg);
    let root = tree::read_model(path)?;
    let dir = path.parent().unwrap_or(Path::new("."));
    let model = read_settings(&root, dir).map_err(fail)?;
    let target = root
        .descendants()
        .into_iter()
        .find(|n| n.tag == "body" && n.attr("name") == Some(body))
        .ok_or_else(|| fail(format!("no <body name=\"{body}\"> in the model")))?;
    let childclass = enclosing_childclass(&root, target);
    let mut geoms = Vec::new();
    collect(
        target,
        &Isometry3::identity(),
        childclass,
        &model,
        &mut geoms,
    )
    .map_err(fail)?;
    if geoms.is_empty() {
        return Err(fail(format!("<body name=\"{body}\"> holds no geom")));
    }
    let colliding: Vec<Geom> = geoms
        .into_iter()
        .filter(|g| g.contype != 0 || g.conaffinity != 0)
        .collect();
    if colliding.is_empty() {
        return Err(fail(format!(
            "<body name=\"{body}\">: every geom has contype=\"0\" and conaffinity=\"0\": \
             none collides"
        )));
    }
    Ok(colliding)
}

/// The compiler's angles and mesh folder, the default classes and the mesh assets.
fn read_settings(root: &Element, dir: &Path) -> std::result::Result<Model, String> {
    // Several <compiler>s: each later attribute overrides, named at the first element.
    let mut compilers = root.children_named("compiler");
    let mut settings = compilers
        .next()
        .cloned()
        .unwrap_or_else(|| Element::synthetic("compiler"));
    for later in compilers {
        for (k, v) in later.attrs() {
            settings.set(k, v);
        }
    }
    let last = |name: &str| settings.attr(name).map(str::to_string);
    let angles = Angles::read(&Attrs::own(&settings))?;
    let mesh_dir = dir.join(last("meshdir").or(last("assetdir")).unwrap_or_default());
    let assets = root
        .children_named("asset")
        .flat_map(|a| a.children_named("mesh"))
        .cloned()
        .collect();
    Ok(Model {
        angles,
        defaults: Defaults::read(root)?,
        mesh_dir,
        assets,
    })
}

/// The `childclass` the target body inherits from the bodies and frames above it.
fn enclosing_childclass<'a>(root: &'a Element, target: &Element) -> Option<&'a str> {
    fn walk<'a>(
        at: &'a Element,
        target: &Element,
        inherited: Option<&'a str>,
    ) -> Option<Option<&'a str>> {
        for child in &at.children {
            if std::ptr::eq(child, target) {
                return Some(inherited);
            }
            let here = child.attr("childclass").or(inherited);
            if let Some(found) = walk(child, target, here) {
                return Some(found);
            }
        }
        None
    }
    walk(root, target, None).flatten()
}

/// Every geom under `body` (through child bodies and frames) with its pose in the target
/// body's frame.
fn collect(
    body: &Element,
    place: &Isometry3<f64>,
    inherited: Option<&str>,
    model: &Model,
    out: &mut Vec<Geom>,
) -> std::result::Result<(), String> {
    let childclass = body.attr("childclass").or(inherited);
    if let Some(c) = childclass.filter(|c| !model.defaults.has(c)) {
        return Err(format!(
            "{}: childclass=\"{c}\": no <default class=\"{c}\"> in the model",
            body.describe()
        ));
    }
    for child in &body.children {
        match child.tag.as_str() {
            "geom" => out.push(geom(child, place, childclass, model)?),
            "body" | "frame" => {
                let inner = place * pose(&Attrs::own(child), &model.angles)?;
                collect(child, &inner, childclass, model, out)?;
            }
            "replicate" | "attach" => {
                return Err(format!(
                    "{}: <{}> is not supported: write its bodies out",
                    child.describe(),
                    child.tag
                ));
            }
            _ => {}
        }
    }
    Ok(())
}

/// One geom: its resolved attributes, shape and pose in the target body's frame.
fn geom(
    node: &Element,
    place: &Isometry3<f64>,
    childclass: Option<&str>,
    model: &Model,
) -> std::result::Result<Geom, String> {
    let attrs = model.defaults.resolve(node, childclass)?;
    let kind = attrs.get("type").unwrap_or("sphere");
    if kind != "mesh" && attrs.get("mesh").is_some() {
        return Err(attrs.fail(
            "mesh",
            format!(
                "a {kind} fitted to a mesh is not read: give type=\"mesh\" or the {kind}'s size"
            ),
        ));
    }
    let fromto = from_to(&attrs)?;
    if fromto.is_some() && !["capsule", "cylinder", "box", "ellipsoid"].contains(&kind) {
        return Err(attrs.fail(
            "fromto",
            format!("MuJoCo takes fromto for a capsule, cylinder, box or ellipsoid, not a {kind}"),
        ));
    }
    let size = orient::numbers(&attrs, "size")?.unwrap_or_default();
    let shape = shape(kind, &size, fromto.map(|f| f.1), &attrs, model)?;
    let geom_pose = match fromto {
        Some((at, _)) => at,
        None => pose(&attrs, &model.angles)?,
    };
    Ok(Geom {
        what: attrs.what.clone(),
        name: node.attr("name").map(str::to_string),
        shape,
        body_t_geom: place * geom_pose,
        contype: bits(&attrs, "contype")?,
        conaffinity: bits(&attrs, "conaffinity")?,
    })
}

/// A geom's shape from its type and `size` (with `fromto`, its half length).
fn shape(
    kind: &str,
    size: &[f64],
    half_length: Option<f64>,
    attrs: &Attrs,
    model: &Model,
) -> std::result::Result<GeomShape, String> {
    let need = |n: usize| -> std::result::Result<Vec<f64>, String> {
        let n = if half_length.is_some() { 1 } else { n };
        if size.len() < n {
            return Err(attrs.fail(
                "size",
                format!(
                    "a {kind} needs {n} size number{}",
                    if n > 1 { "s" } else { "" }
                ),
            ));
        }
        let mut s = size[..n].to_vec();
        if let Some(h) = half_length {
            s.push(h);
        }
        Ok(s)
    };
    let round = |r: Round| Ok(GeomShape::Round(r));
    match kind {
        "mesh" => mesh_asset(attrs, model),
        "box" | "ellipsoid" => {
            let s = need(3)?;
            // With fromto, MuJoCo takes the first size for both x and y.
            let v = match half_length {
                Some(h) => Vector3::new(s[0], s[0], h),
                None => Vector3::new(s[0], s[1], s[2]),
            };
            if kind == "box" {
                Ok(GeomShape::Box { half_extents: v })
            } else {
                round(Round::Ellipsoid { radii: v })
            }
        }
        "sphere" => round(Round::Sphere {
            radius: need(1)?[0],
        }),
        "capsule" | "cylinder" => {
            let s = need(2)?;
            let (radius, half_length) = (s[0], s[1]);
            round(if kind == "capsule" {
                Round::Capsule {
                    radius,
                    half_length,
                }
            } else {
                Round::Cylinder {
                    radius,
                    half_length,
                }
            })
        }
        other => Err(attrs.fail(
            "type",
            format!(
                "a {other} is not a part: give mesh, box, sphere, capsule, cylinder or ellipsoid"
            ),
        )),
    }
}

/// `contype` or `conaffinity`: a bit mask, 1 when not given.
fn bits(attrs: &Attrs, name: &str) -> std::result::Result<u32, String> {
    match attrs.get(name) {
        None => Ok(1),
        Some(v) => v
            .trim()
            .parse::<i32>()
            .map(|b| b as u32)
            .map_err(|_| attrs.fail(name, "expected an integer bit mask")),
    }
}

/// The `<mesh>` asset a geom names: its file (relative to meshdir), scale and reference pose.
fn mesh_asset(geom: &Attrs, model: &Model) -> std::result::Result<GeomShape, String> {
    let name = geom
        .get("mesh")
        .ok_or_else(|| geom.fail("mesh", "a mesh geom needs mesh=\"NAME\""))?;
    let asset = model
        .assets
        .iter()
        .find(|n| {
            let file_stem = n
                .attr("file")
                .and_then(|f| Path::new(f).file_stem())
                .and_then(|s| s.to_str());
            n.attr("name").or(file_stem) == Some(name)
        })
        .ok_or_else(|| geom.fail("mesh", format!("no <mesh name=\"{name}\"> in <asset>")))?;
    let attrs = model.defaults.resolve(asset, None)?;
    let file = attrs.get("file").ok_or_else(|| {
        attrs.fail(
            "file",
            "only mesh files are read (not vertex= written in the model)",
        )
    })?;
    let scale = fixed::<3>(&attrs, "scale")?.unwrap_or([1.0; 3]);
    let refpos = fixed::<3>(&attrs, "refpos")?.unwrap_or([0.0; 3]);
    let refquat = match attrs.get("refquat") {
        None => UnitQuaternion::identity(),
        Some(_) => {
            let [w, x, y, z] = fixed::<4>(&attrs, "refquat")?.expect("given");
            let q = nalgebra::Quaternion::new(w, x, y, z);
            if q.norm() < 1e-14 {
                return Err(attrs.fail("refquat", "expected w x y z, not all 0"));
            }
            UnitQuaternion::new_normalize(q)
        }
    };
    Ok(GeomShape::Mesh {
        file: model.mesh_dir.join(file),
        scale: Vector3::from(scale),
        reference: Isometry3::from_parts(Translation3::from(Vector3::from(refpos)), refquat),
    })
}

impl Geom {
    /// A mesh geom's triangles in the body's frame, model units (`None` for a primitive; not
    /// yet checked to lie in range).
    pub fn mesh_soup(&self) -> Result<Option<TriangleSoup>> {
        let GeomShape::Mesh {
            file,
            scale,
            reference,
        } = &self.shape
        else {
            return Ok(None);
        };
        let mut soup = read_mesh_as_written(file)?;
        let to_reference = reference.inverse();
        for v in &mut soup.vertices {
            let local = (to_reference * *v).coords.component_mul(scale);
            *v = self.body_t_geom * nalgebra::Point3::from(local);
        }
        Ok(Some(soup))
    }

    /// Its (`contype`, `conaffinity`).
    pub fn bits(&self) -> (u32, u32) {
        (self.contype, self.conaffinity)
    }

    /// MuJoCo's `size` of the geom (zeros where its type has fewer numbers).
    pub fn mujoco_size(&self) -> [f64; 3] {
        match &self.shape {
            GeomShape::Mesh { .. } => [0.0; 3],
            GeomShape::Box { half_extents: h } => [h.x, h.y, h.z],
            GeomShape::Round(round) => {
                let mut size = [0.0; 3];
                for (to, from) in size.iter_mut().zip(round.sizes()) {
                    *to = from;
                }
                size
            }
        }
    }
}

/// What `pegtwin assembly mjcf` prints of a geom (model units; quaternion w x y z).
#[derive(Clone, Debug, Serialize)]
pub struct GeomReport {
    pub name: Option<String>,
    pub element: String,
    #[serde(rename = "type")]
    pub kind: &'static str,
    pub size: [f64; 3],
    pub pos: [f64; 3],
    pub quat: [f64; 4],
    pub contype: u32,
    pub conaffinity: u32,
    /// A mesh geom's vertices in the body's frame.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub vertices: Option<Vec<[f64; 3]>>,
}

/// The collision geoms of `body` as pegtwin reads them, for comparison with MuJoCo's compiler.
pub fn report(path: &Path, body: &str) -> Result<Vec<GeomReport>> {
    body_geoms(path, body)?
        .into_iter()
        .map(|g| {
            let q = g.body_t_geom.rotation;
            let t = g.body_t_geom.translation.vector;
            let vertices = g
                .mesh_soup()?
                .map(|s| s.vertices.iter().map(|v| [v.x, v.y, v.z]).collect());
            Ok(GeomReport {
                name: g.name.clone(),
                element: g.what.clone(),
                kind: match g.shape {
                    GeomShape::Mesh { .. } => "mesh",
                    GeomShape::Box { .. } => "box",
                    GeomShape::Round(round) => round.name(),
                },
                size: g.mujoco_size(),
                pos: [t.x, t.y, t.z],
                quat: [q.w, q.i, q.j, q.k],
                contype: g.contype,
                conaffinity: g.conaffinity,
                vertices,
            })
        })
        .collect()
}
