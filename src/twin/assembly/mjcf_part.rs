//! An MJCF body as a part: its collision geoms ([`super::mjcf`]) chosen as MuJoCo would collide
//! them with the other part, and made into convex pieces in metres.

use super::mjcf::{self, Geom, GeomShape};
use crate::error::{Error, Result};
use crate::twin::geometry::chord_tolerance;
use crate::twin::geometry::mesh::{MeshUnits, check_in_range, mesh_part};
use crate::twin::geometry::planar::rect;
use crate::twin::geometry::solid::{ConvexPiece, Solid, ZPlane};
use nalgebra::{Isometry3, Translation3, Vector3};
use std::path::{Path, PathBuf};

/// The clearance whose chord tolerance polygonises round geoms, m: the smallest clearance
/// pegtwin is made for, so that a round geom stands off its surface by at most the built-ins'
/// chord error there (2.5 um; `assembly check` reports each geom's as its deviation).
const ROUND_CHORD_CLEARANCE_M: f64 = 0.1e-3;

/// Each part's kept geoms (`None` for a part that is not an MJCF body) and the warnings.
type Paired = (Option<Vec<Geom>>, Option<Vec<Geom>>, Vec<String>);

/// Where a part's geoms come from: an MJCF file and body.
pub struct Source<'a> {
    pub file: PathBuf,
    pub body: &'a str,
}

/// An MJCF body's pieces, in its frame, and each geom's deviation from its surface (m).
pub struct MjcfSolid {
    pub solid: Solid,
    pub deviations: Vec<(PathBuf, f64)>,
}

/// The geoms each MJCF part keeps, and what was left out: a geom that collides with no geom
/// of the other part (MuJoCo's `contype`/`conaffinity` rule; a mesh or built-in part collides
/// as MuJoCo's default, 1 and 1) is left out with a warning; two kept geoms that would not
/// collide are refused by name, since every peg piece meets every hole piece here.
pub fn paired_geoms(peg: Option<&Source>, hole: Option<&Source>) -> Result<Paired> {
    let read = |s: Option<&Source>| -> Result<Option<Vec<Geom>>> {
        s.map(|s| mjcf::body_geoms(&s.file, s.body)).transpose()
    };
    let (peg_geoms, hole_geoms) = (read(peg)?, read(hole)?);
    let bits_of = |gs: &Option<Vec<Geom>>| match gs {
        Some(gs) => gs.iter().map(Geom::bits).collect::<Vec<_>>(),
        None => vec![(1u32, 1u32)],
    };
    let (peg_bits, hole_bits) = (bits_of(&peg_geoms), bits_of(&hole_geoms));
    let mut warnings = Vec::new();
    let mut keep = |section: &str, geoms: Option<Vec<Geom>>, other: &[(u32, u32)]| {
        geoms.map(|gs| {
            gs.into_iter()
                .filter(|g| {
                    let hit = other.iter().any(|o| mjcf::bits_collide(g.bits(), *o));
                    if !hit {
                        warnings.push(format!(
                            "[{section}] {}: collides with no geom of the other part \
                             (contype/conaffinity): left out",
                            g.what
                        ));
                    }
                    hit
                })
                .collect::<Vec<_>>()
        })
    };
    let peg_kept = keep("peg", peg_geoms, &hole_bits);
    let hole_kept = keep("hole", hole_geoms, &peg_bits);
    for (section, kept) in [("peg", &peg_kept), ("hole", &hole_kept)] {
        if kept.as_ref().is_some_and(Vec::is_empty) {
            let file = if section == "peg" { peg } else { hole }.map(|s| s.file.clone());
            return Err(Error::file(
                file.unwrap_or_default(),
                format!("[{section}]: no geom collides with the other part (contype/conaffinity)"),
            ));
        }
    }
    check_all_meet(&peg_kept, &hole_kept, peg.or(hole))?;
    Ok((peg_kept, hole_kept, warnings))
}

/// Every kept peg geom must collide with every kept hole geom.
fn check_all_meet(
    peg: &Option<Vec<Geom>>,
    hole: &Option<Vec<Geom>>,
    at: Option<&Source>,
) -> Result<()> {
    let (Some(peg), Some(hole)) = (peg, hole) else {
        return Ok(());
    };
    for p in peg {
        if let Some(h) = hole.iter().find(|h| !mjcf::collide(p, h)) {
            return Err(Error::file(
                at.map(|s| s.file.clone()).unwrap_or_default(),
                format!(
                    "peg {} and hole {} do not collide (contype/conaffinity) while other geoms \
                     of theirs do: pegtwin collides every peg geom with every hole geom; give \
                     them bits that collide, or bits that leave one out",
                    p.what, h.what
                ),
            ));
        }
    }
    Ok(())
}

/// The geoms as convex pieces in the body's frame, metres (`units`: the model's length unit,
/// metres when not given, as MuJoCo models are).
pub fn solid(file: &Path, geoms: Vec<Geom>, units: Option<MeshUnits>) -> Result<MjcfSolid> {
    let s = units.unwrap_or(MeshUnits::M).scale();
    let mut pieces = Vec::new();
    let mut deviations = Vec::new();
    let chord_m = chord_tolerance(ROUND_CHORD_CLEARANCE_M);
    for g in geoms {
        let place = Isometry3::from_parts(
            Translation3::from(g.body_t_geom.translation.vector * s),
            g.body_t_geom.rotation,
        );
        match &g.shape {
            GeomShape::Mesh {
                file: mesh, scale, ..
            } => {
                let mut soup = g.mesh_soup()?.expect("a mesh geom");
                for v in &mut soup.vertices {
                    *v *= s;
                }
                let words = format!(
                    "{} x scale {scale:?}",
                    units.unwrap_or(MeshUnits::M).in_words()
                );
                check_in_range(&soup, mesh, &words)?;
                let part = mesh_part(&soup, mesh)?;
                pieces.extend(part.pieces);
                deviations.push((mesh.clone(), part.deviation_m));
            }
            GeomShape::Box { half_extents } => {
                pieces.push(box_piece(&(half_extents * s), &place, file, &g.what)?);
            }
            GeomShape::Round(round) => {
                let shaped = round.scaled(s).polygonise(chord_m).ok_or_else(|| {
                    Error::file(file, format!("{}: its size must be above 0", g.what))
                })?;
                pieces.push(shaped.piece.transformed(&place));
                let label = PathBuf::from(format!("{} {}", file.display(), g.what));
                deviations.push((label, shaped.deviation_m));
            }
        }
    }
    let solid = Solid {
        pieces,
        boundary: None,
    };
    Ok(MjcfSolid { solid, deviations })
}

/// A box of half-extents `h` (m) placed at `place`: the slab over its rectangle, moved.
fn box_piece(
    h: &Vector3<f64>,
    place: &Isometry3<f64>,
    file: &Path,
    what: &str,
) -> Result<ConvexPiece> {
    if !h.iter().all(|v| *v > 0.0) {
        let msg = format!("{what}: a box of half-extents {h:?}: expected all above 0");
        return Err(Error::file(file, msg));
    }
    let slab = ConvexPiece::slab(
        &rect(-h.x, -h.y, h.x, h.y),
        ZPlane::flat(-h.z),
        ZPlane::flat(h.z),
    );
    Ok(slab.transformed(place))
}
