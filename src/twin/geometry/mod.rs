//! Peg and hole geometry: the five built-in pairs (exact convex decompositions with chamfers),
//! meshes in and out, and the clearance convention.
//!
//! Frames: the peg frame has its origin at the centre of the peg tip, z up along the peg; the hole
//! frame has its origin at the centre of the hole mouth, z out of the hole. Clearance follows ISO
//! fits: hole size minus peg size (diametral), so the cavity is the peg profile offset by c/2.

pub mod mesh;
pub mod planar;
pub mod print;
pub mod profile;
pub mod round;
pub mod solid;
pub mod stack;

use crate::error::{Error, Result};
use planar::{P2, Region, difference, offset_left, rect, simplify_ring, union};
pub use print::Print;
pub use profile::Builtin;
use solid::{BoundaryMesh, ConvexPiece, Solid, ZPlane, prisms};

/// Length of the peg's engagement part (tip to body), metres.
pub const PIN_LENGTH_M: f64 = 32e-3;
/// Depth of the blind cavity, mouth to floor, metres.
pub const CAVITY_DEPTH_M: f64 = 30e-3;
/// Side of the square hole block, metres.
pub const BLOCK_SIZE_M: f64 = 70e-3;
/// Thickness of the block under the cavity floor, metres.
pub const FLOOR_THICKNESS_M: f64 = 10e-3;
/// Height of the peg body (the flange that mounts on the robot), metres.
pub const BODY_HEIGHT_M: f64 = 10e-3;
/// Side of the square peg body, metres.
pub const BODY_SIZE_M: f64 = 36e-3;
/// 45-degree chamfer on the peg tip, metres (smaller where a profile's features are thinner than
/// it allows: `fitting_chamfer`).
pub const PEG_TIP_CHAMFER_M: f64 = 0.3e-3;
/// 45-degree chamfer on the hole mouth, metres (smaller where needed, as the peg's).
pub const HOLE_ENTRY_CHAMFER_M: f64 = 0.3e-3;
/// Smallest and largest clearance the built-ins are made for, metres (both included).
pub const CLEARANCE_RANGE_M: (f64, f64) = (0.01e-3, 5e-3);

/// Where the peg stops when pushed straight in.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Seat {
    /// The peg's tip reaches the cavity floor.
    TipOnFloor,
    /// A part of the peg above its tip (its flange, a shoulder) lands on the block.
    FlangeOnBlock,
    /// Nothing stops it within the hole: a through hole.
    Through,
}

impl Seat {
    /// What stops the peg at full insertion, in words.
    pub fn describe(self) -> &'static str {
        match self {
            Seat::TipOnFloor => "tip on the floor",
            Seat::FlangeOnBlock => "flange on the block",
            Seat::Through => "a through hole's success depth",
        }
    }
}

/// A peg and its hole, ready for simulation.
#[derive(Clone, Debug)]
pub struct PartPair {
    pub name: String,
    /// Diametral clearance (hole size minus peg size), metres. For meshes, the value the user
    /// states; the meshes themselves decide the real gap.
    pub clearance_m: f64,
    /// Largest distance between a polygonised round edge and the true curve, metres.
    pub chord_error_m: f64,
    /// The peg in the peg frame.
    pub peg: Solid,
    /// The hole block in the hole frame.
    pub hole: Solid,
    /// Depth of the cavity floor below the mouth, metres (tip z at full insertion is minus this).
    /// For an assembly file's pair, the depth at which the peg is fully inserted: where it seats
    /// (tip on the floor or shoulder on the block), or the depth its file gives for a through hole.
    pub cavity_depth_m: f64,
    /// What stops the peg at `cavity_depth_m` (the built-ins: its tip on the floor).
    pub seat: Seat,
    /// The peg's mass, kg (an assembly's, from its volume or its file); `None`: the cell's
    /// `peg_mass_kg` (0.3 kg, the built-ins').
    pub peg_mass_kg: Option<f64>,
    /// A checksum of what the pair was made from beyond its name and clearance (an assembly's
    /// mesh contents, frames and mass); `None` for built-ins, which those two decide. Cached
    /// manifolds are keyed on it, and on a printed built-in's print.
    pub content_key: Option<String>,
    /// How a built-in came out of the printer on the real cell (`None`: as its CAD says).
    pub print: Option<Print>,
}

impl PartPair {
    /// A rough relative cost of simulating this pair, for the order in which a campaign runs its
    /// work only ([`crate::schedule`]): the square root of its convex pieces (peg and hole). The
    /// narrow phase grows with the piece pairs in contact, which grow slower than the pieces: at
    /// 0.5 mm the gear has 645 pieces and the cross 39, and a manifold trial of the gear takes
    /// about three times a cross's (`docs/performance.md`), against 4.1 here.
    pub fn relative_step_cost(&self) -> f64 {
        ((self.peg.pieces.len() + self.hole.pieces.len()) as f64).sqrt()
    }

    /// The diametral clearance in mm to 0.1 um, as records, labels and file names show it (an
    /// assembly's is measured: 0.498 mm, not 0.49799999999999994).
    pub fn clearance_mm(&self) -> f64 {
        (self.clearance_m * 1e7).round() / 1e4
    }
}

/// Checks a clearance value (metres) against the supported range.
pub fn check_clearance(clearance_m: f64) -> Result<()> {
    let (lo, hi) = CLEARANCE_RANGE_M;
    if !(clearance_m >= lo && clearance_m <= hi) {
        // The value as typed in mm: 9 mm reads back as 9.000000000000002 after m and back.
        let shown_mm = (clearance_m * 1e12).round() / 1e9;
        return Err(Error::Input(format!(
            "clearance {} mm is out of range: expected {} to {} mm",
            if shown_mm.is_finite() {
                shown_mm
            } else {
                clearance_m * 1e3
            },
            lo * 1e3,
            hi * 1e3
        )));
    }
    Ok(())
}

/// Looks a built-in up by name, with an error that lists the known names.
pub fn builtin_by_name(name: &str) -> Result<Builtin> {
    Builtin::from_name(name).ok_or_else(|| {
        let known: Vec<&str> = Builtin::ALL.iter().map(|b| b.name()).collect();
        Error::Input(format!(
            "unknown geometry '{name}': expected one of {}",
            known.join(", ")
        ))
    })
}

/// The chord tolerance for a clearance: 1/20 of the gap on each side.
pub fn chord_tolerance(clearance_m: f64) -> f64 {
    clearance_m / 2.0 / 20.0
}

/// Builds a built-in pair at a clearance (metres), as its CAD says.
pub fn build_builtin(builtin: Builtin, clearance_m: f64) -> Result<PartPair> {
    build_printed(builtin, clearance_m, None)
}

/// Builds a built-in pair at a nominal clearance (metres) as `print` came out (`None`: exact).
/// The chord tolerance follows the printed clearance; a print that closes the gap below the
/// least clearance pegtwin builds is refused.
pub fn build_printed(builtin: Builtin, clearance_m: f64, print: Option<Print>) -> Result<PartPair> {
    check_clearance(clearance_m)?;
    let made = print.unwrap_or(Print::exact(clearance_m));
    if made.clearance_m.is_nan() || made.clearance_m < CLEARANCE_RANGE_M.0 {
        return Err(Error::Input(format!(
            "{} at {} mm: the print (walls {:.4} mm out on the peg, {:.4} mm in on the hole) leaves              a clearance of {:.4} mm, less than the {} mm pegtwin builds: expected              cell.print_deviation_m to leave a gap",
            builtin.name(),
            clearance_m * 1e3,
            made.peg_growth_m * 1e3,
            made.hole_shrink_m * 1e3,
            made.clearance_m * 1e3,
            CLEARANCE_RANGE_M.0 * 1e3
        )));
    }
    let tol = chord_tolerance(made.clearance_m);
    let half_gap = clearance_m / 2.0;
    let d_max = half_gap + made.hole_edge_m;
    let simplified = |regions: Vec<Region>| -> Vec<Region> {
        regions
            .into_iter()
            .map(|r| Region {
                outer: simplify_ring(&r.outer, tol),
                holes: r.holes.iter().map(|h| simplify_ring(h, tol)).collect(),
            })
            .collect()
    };
    let peg_profile = simplified(union(&builtin.pieces(made.peg_growth_m, tol, d_max)));
    let cavity = simplified(union(&builtin.pieces(
        half_gap - made.hole_shrink_m,
        tol,
        d_max,
    )));
    let named = |e: String| Error::Input(format!("{}: {e}", builtin.name()));
    let peg = build_peg(&peg_profile, made.peg_edge_m).map_err(named)?;
    let hole = build_hole(&cavity, made.hole_edge_m).map_err(named)?;
    Ok(PartPair {
        name: builtin.name().to_string(),
        clearance_m,
        chord_error_m: tol,
        peg,
        hole,
        cavity_depth_m: CAVITY_DEPTH_M,
        seat: Seat::TipOnFloor,
        peg_mass_kg: None,
        content_key: print.map(|p| p.key()),
        print,
    })
}

/// Widths of the wall strips that carry the chamfers, as multiples of the chamfer, widest first:
/// each ring takes the widest that no edge of it collapses at.
const STRIP_WIDTH_FACTORS: [f64; 4] = [2.0, 1.5, 1.2, 1.0];

/// The chamfered edges of a region. Along each chamfered ring, a wall strip (see
/// `STRIP_WIDTH_FACTORS`) runs from each edge to its mitred offset into the material,
/// bounded by the corner bisectors (the straight skeleton, so neighbouring strips meet exactly);
/// each strip is one convex piece with the 45-degree bevel cut on its edge. The rest of the
/// region (the core) is decomposed into plain prisms. Chunky strips instead of separate bevel
/// slivers keep the engine's convex-convex contacts sound.
struct Skirt {
    /// Per edge: (edge start, edge end, chamfer-offset start, end, strip-offset start, end).
    strips: Vec<[P2; 6]>,
    /// Each chamfered ring offset by the chamfer, vertex for vertex (for the boundary mesh).
    chamfer_rings: Vec<Vec<P2>>,
    core: Vec<Region>,
    /// The chamfer the strips carry, metres (see [`fitting_chamfer`]).
    chamfer: f64,
}

fn skirt(
    material: &[Region],
    rings: &[Vec<P2>],
    nominal_chamfer: f64,
) -> std::result::Result<Skirt, String> {
    let chamfer = fitting_chamfer(rings, nominal_chamfer)?;
    let mut strips = Vec::new();
    let mut chamfer_rings = Vec::new();
    for ring in rings {
        let c = offset_left(ring, chamfer).expect("the chamfer fits every ring");
        let w = STRIP_WIDTH_FACTORS
            .iter()
            .find_map(|f| offset_left(ring, f * chamfer))
            .unwrap_or_else(|| c.clone());
        let n = ring.len();
        for i in 0..n {
            let j = (i + 1) % n;
            strips.push([ring[i], ring[j], c[i], c[j], w[i], w[j]]);
        }
        chamfer_rings.push(c);
    }
    let quads: Vec<Vec<P2>> = strips
        .iter()
        .map(|s| vec![s[0], s[1], s[5], s[4]])
        .collect();
    Ok(Skirt {
        core: difference(material, &quads),
        strips,
        chamfer_rings,
        chamfer,
    })
}

/// The chamfer a profile carries: the nominal one, or where a feature of the profile is thinner
/// than it allows (a 0.5 mm tooth flat at a large clearance, a short edge of a finely polygonised
/// curve at a small one), the largest whole micrometre below 80 % of the distance at which the
/// first edge collapses. Below [`MIN_CHAMFER_M`] the profile is refused.
fn fitting_chamfer(rings: &[Vec<P2>], nominal: f64) -> std::result::Result<f64, String> {
    let collapse = rings
        .iter()
        .map(|r| planar::collapse_distance(r))
        .fold(f64::INFINITY, f64::min);
    if collapse > nominal {
        return Ok(nominal);
    }
    let reduced = (0.8 * collapse * 1e6).floor() * 1e-6;
    if reduced < MIN_CHAMFER_M {
        return Err(format!(
            "a feature of the profile collapses under a {:.3} mm chamfer (the least pegtwin \
             builds is {} mm): the profile is too thin at this clearance",
            collapse * 1e3,
            MIN_CHAMFER_M * 1e3
        ));
    }
    Ok(reduced)
}

/// The smallest chamfer a built-in carries, metres.
pub const MIN_CHAMFER_M: f64 = 0.02e-3;

/// A strip piece: the ring edge at height `z_edge`, the chamfer line and the strip's inner line
/// at `z_face` (the tip or the mouth), the bevel between them, and the edge and inner line again at
/// `z_far` (the other end), with its exact faces.
fn strip_piece(s: &[P2; 6], z_edge: f64, z_face: f64, z_far: f64) -> ConvexPiece {
    let [vi, vj, ci, cj, wi, wj] = *s;
    let at = |p: P2, z: f64| solid::P3::new(p.x, p.y, z);
    // 0 vi, 1 vj at the edge; 2 ci, 3 cj, 4 wi, 5 wj at the face; 6 vi, 7 vj, 8 wi, 9 wj far.
    let vertices = vec![
        at(vi, z_edge),
        at(vj, z_edge),
        at(ci, z_face),
        at(cj, z_face),
        at(wi, z_face),
        at(wj, z_face),
        at(vi, z_far),
        at(vj, z_far),
        at(wi, z_far),
        at(wj, z_far),
    ];
    let faces = vec![
        vec![0, 1, 3, 2],    // bevel
        vec![2, 3, 5, 4],    // flat end face
        vec![6, 7, 9, 8],    // far end
        vec![0, 1, 7, 6],    // the ring edge's wall
        vec![4, 5, 9, 8],    // the inner wall
        vec![1, 3, 5, 9, 7], // side along the bisector at j
        vec![0, 2, 4, 8, 6], // side along the bisector at i
    ];
    ConvexPiece::from_faces(vertices, faces)
}

/// The peg: pin(s) with a tip chamfered by `edge_m`, and the body block on top.
fn build_peg(profile: &[Region], edge_m: f64) -> std::result::Result<Solid, String> {
    let rings: Vec<Vec<P2>> = profile.iter().flat_map(|r| r.rings().cloned()).collect();
    let sk = skirt(profile, &rings, edge_m)?;
    let ch = sk.chamfer;
    let mut pieces = prisms(&sk.core, ZPlane::flat(0.0), ZPlane::flat(PIN_LENGTH_M));
    pieces.extend(
        sk.strips
            .iter()
            .map(|s| strip_piece(s, ch, 0.0, PIN_LENGTH_M)),
    );
    let half = BODY_SIZE_M / 2.0;
    let body = rect(-half, -half, half, half);
    let top = PIN_LENGTH_M + BODY_HEIGHT_M;
    pieces.push(ConvexPiece::slab(
        &body,
        ZPlane::flat(PIN_LENGTH_M),
        ZPlane::flat(top),
    ));

    let mut m = mesh::MeshBuilder::default();
    for (ring, off) in rings.iter().zip(&sk.chamfer_rings) {
        m.side_band(off, 0.0, ring, ch);
        m.side_band(ring, ch, ring, PIN_LENGTH_M);
    }
    let mut k = 0;
    for region in profile {
        let n_rings = 1 + region.holes.len();
        let tip = Region {
            outer: sk.chamfer_rings[k].clone(),
            holes: sk.chamfer_rings[k + 1..k + n_rings].to_vec(),
        };
        m.cap(&tip, 0.0, false);
        k += n_rings;
    }
    let body_bottom = Region {
        outer: body.clone(),
        holes: profile
            .iter()
            .map(|r| r.outer.iter().rev().cloned().collect())
            .collect(),
    };
    m.cap(&body_bottom, PIN_LENGTH_M, false);
    m.side_band(&body, PIN_LENGTH_M, &body, top);
    m.cap(
        &Region {
            outer: body,
            holes: vec![],
        },
        top,
        true,
    );
    Ok(Solid {
        pieces,
        boundary: Some(m.finish()),
    })
}

/// The hole block: walls around the cavity with a mouth chamfered by `edge_m`, and the floor
/// slab.
fn build_hole(cavity: &[Region], edge_m: f64) -> std::result::Result<Solid, String> {
    let half = BLOCK_SIZE_M / 2.0;
    let square = rect(-half, -half, half, half);
    let block = Region {
        outer: square.clone(),
        holes: vec![],
    };
    let cavity_rings: Vec<Vec<P2>> = cavity.iter().map(|r| r.outer.clone()).collect();
    let material = difference(std::slice::from_ref(&block), &cavity_rings);
    if material.len() != 1 {
        return Err("the cavity splits the block".into());
    }
    let rings: Vec<Vec<P2>> = material[0].holes.clone();
    let sk = skirt(&material, &rings, edge_m)?;
    let ch = sk.chamfer;
    let floor = -CAVITY_DEPTH_M;
    let bottom = floor - FLOOR_THICKNESS_M;
    let mut pieces = prisms(&sk.core, ZPlane::flat(floor), ZPlane::flat(0.0));
    pieces.extend(sk.strips.iter().map(|s| strip_piece(s, -ch, 0.0, floor)));
    pieces.push(ConvexPiece::slab(
        &square,
        ZPlane::flat(bottom),
        ZPlane::flat(floor),
    ));

    let mut m = mesh::MeshBuilder::default();
    m.cap(
        &Region {
            outer: square.clone(),
            holes: sk.chamfer_rings.clone(),
        },
        0.0,
        true,
    );
    for (ring, off) in rings.iter().zip(&sk.chamfer_rings) {
        m.side_band(ring, -ch, off, 0.0);
        m.side_band(ring, floor, ring, -ch);
        let floor_region = Region {
            outer: ring.iter().rev().cloned().collect(),
            holes: vec![],
        };
        m.cap(&floor_region, floor, true);
    }
    m.side_band(&square, bottom, &square, 0.0);
    m.cap(
        &Region {
            outer: square,
            holes: vec![],
        },
        bottom,
        false,
    );
    Ok(Solid {
        pieces,
        boundary: Some(m.finish()),
    })
}

/// Writes `peg.stl` and `hole.stl` (millimetres, watertight) into `dir`, creating it, and with
/// `convex_parts` also `peg_parts/` and `hole_parts/`: one STL per convex collision piece, the
/// layout MuJoCo users keep from CoACD or V-HACD. Each file is written whole or not at all
/// ([`crate::files::write_atomically_with`]), so a failure leaves no half-written STL.
pub fn export_stl(pair: &PartPair, dir: &std::path::Path, convex_parts: bool) -> Result<()> {
    let write = |mesh: &BoundaryMesh, dest: std::path::PathBuf| mesh.write_stl_mm(&dest);
    let mkdir = |d: &std::path::Path| {
        std::fs::create_dir_all(d).map_err(|e| Error::file(d, format!("cannot create: {e}")))
    };
    mkdir(dir)?;
    for (name, solid) in [("peg", &pair.peg), ("hole", &pair.hole)] {
        let mesh = solid.boundary.as_ref().ok_or_else(|| {
            Error::Input(format!(
                "{}: only built-in geometries can be exported",
                pair.name
            ))
        })?;
        write(mesh, dir.join(format!("{name}.stl")))?;
        if convex_parts {
            let parts = dir.join(format!("{name}_parts"));
            mkdir(&parts)?;
            for (k, piece) in solid.pieces.iter().enumerate() {
                write(&piece.to_mesh(), parts.join(format!("{k:04}.stl")))?;
            }
        }
    }
    Ok(())
}
