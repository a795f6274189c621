//! What pegtwin measures of a peg/hole fit from the solids alone, with the peg lined up on the
//! hole's axis (peg frame on the hole frame, moved down z): how far the peg goes in before it
//! stops and on what (its tip on the floor, or its flange on the block), the cavity's depth under
//! the tip, and the gap between peg and hole walls over the engagement (per side, minimum and
//! median over 0.5 mm slices). The exact penetration test (`twin::physics::penetration`) decides
//! contact; the gaps are distances from points on the peg's surface to the hole's surface.

pub use crate::twin::geometry::Seat;
use crate::twin::geometry::solid::{P3, Solid};
use crate::twin::physics::penetration::PenetrationProbe;
use nalgebra::Isometry3;
use parry3d::math::Vector as V3f;
use parry3d::query::{PointQuery, Ray, RayCast};
use parry3d::shape::TriMesh;

/// Step of the scan down the hole's axis, m (the first contact is then found by bisection).
const SCAN_STEP_M: f64 = 0.25e-3;
/// Bisection tolerance on the seat depth, m.
const SEAT_TOLERANCE_M: f64 = 1e-7;
/// Penetration that counts as contact, m (touching faces overlap by 0).
const CONTACT_M: f64 = 1e-9;
/// A seat whose stopping peg piece reaches within this of the tip is the tip on the floor, m.
const TIP_BAND_M: f64 = 1e-3;
/// Height of the slices the gap is reported over, m.
const GAP_SLICE_M: f64 = 0.5e-3;

/// The fit as measured, SI units.
#[derive(Clone, Debug)]
pub struct Fit {
    /// How deep the tip is below the mouth when the peg stops, m (`None`: it passes through).
    pub seat_depth_m: Option<f64>,
    pub seat: Seat,
    /// Depth of the floor under the peg's tip below the mouth, m (`None`: no floor, a through
    /// hole).
    pub cavity_depth_m: Option<f64>,
    /// Smallest gap between peg and hole walls on one side, m (half the diametral clearance).
    pub gap_min_m: f64,
    /// Median over the 0.5 mm slices of the engagement of each slice's smallest gap, m.
    pub gap_median_m: f64,
    /// The band of depths below the mouth over which the gap was measured, m (top, bottom).
    pub gap_band_m: (f64, f64),
}

/// Why a fit could not be measured.
#[derive(Clone, Debug, PartialEq)]
pub enum FitError {
    /// The peg, tip `depth_m` below the mouth, already intersects the hole.
    IntersectsAt { depth_m: f64 },
    /// The peg stops `depth_m` below the mouth, short of the depth asked for.
    StopsAt { depth_m: f64 },
    /// No slice of the peg's side faces the hole's walls inside the hole.
    NoEngagement,
}

/// The peg `peg` (peg frame) pushed into the hole `hole` (hole frame) along the hole's axis,
/// from its tip `above_m` above the mouth down to `max_depth_m`; it must go at least
/// `min_depth_m` in.
pub fn measure_fit(
    peg: &Solid,
    hole: &Solid,
    above_m: f64,
    (min_depth_m, max_depth_m): (f64, f64),
) -> Result<Fit, FitError> {
    let probe = PenetrationProbe::new(hole, &Isometry3::identity());
    let contact = first_contact(&probe, peg, -above_m, max_depth_m);
    match contact {
        Some(d) if d == -above_m => return Err(FitError::IntersectsAt { depth_m: d }),
        Some(d) if d < min_depth_m => return Err(FitError::StopsAt { depth_m: d }),
        _ => {}
    }
    let seat = match contact {
        None => Seat::Through,
        Some(d) => seat_kind(&probe, peg, d),
    };
    let surface = union_surface(hole);
    let cavity_depth_m = floor_under_tip(peg, &surface, max_depth_m);
    let engaged = contact.unwrap_or(max_depth_m.min(peg.bounds().1.z));
    let (gap_min_m, gap_median_m, gap_band_m) =
        gaps(peg, &surface, engaged).ok_or(FitError::NoEngagement)?;
    Ok(Fit {
        seat_depth_m: contact,
        seat,
        cavity_depth_m,
        gap_min_m,
        gap_median_m,
        gap_band_m,
    })
}

/// The peg frame with its tip `depth_m` below the mouth, in the hole frame.
fn at_depth(depth_m: f64) -> Isometry3<f64> {
    Isometry3::translation(0.0, 0.0, -depth_m)
}

/// The first depth in [from_m, to_m] at which the peg touches the hole (to 0.1 um), if any.
fn first_contact(probe: &PenetrationProbe, peg: &Solid, from_m: f64, to_m: f64) -> Option<f64> {
    let touches = |d: f64| probe.max_penetration(peg, &at_depth(d)) > CONTACT_M;
    if touches(from_m) {
        return Some(from_m);
    }
    let mut free = from_m;
    while free < to_m {
        let next = (free + SCAN_STEP_M).min(to_m);
        if touches(next) {
            let mut hit = next;
            while hit - free > SEAT_TOLERANCE_M {
                let mid = 0.5 * (free + hit);
                if touches(mid) {
                    hit = mid;
                } else {
                    free = mid;
                }
            }
            return Some(free);
        }
        free = next;
    }
    None
}

/// What stops the peg at `depth_m`: the lowest peg piece that touches just below it decides.
fn seat_kind(probe: &PenetrationProbe, peg: &Solid, depth_m: f64) -> Seat {
    let below = at_depth(depth_m + 10.0 * SEAT_TOLERANCE_M);
    let lowest = peg
        .pieces
        .iter()
        .filter(|p| probe.piece_penetration(p, &below) > CONTACT_M)
        .map(|p| p.bounds().0.z)
        .fold(f64::INFINITY, f64::min);
    if lowest - peg.bounds().0.z <= TIP_BAND_M {
        Seat::TipOnFloor
    } else {
        Seat::FlangeOnBlock
    }
}

/// All pieces' faces as one triangle mesh (f32): the nearest face of the union is the nearest
/// point of the solid from any point outside it.
fn union_surface(solid: &Solid) -> TriMesh {
    let mut vertices = Vec::new();
    let mut triangles = Vec::new();
    for piece in &solid.pieces {
        let base = vertices.len() as u32;
        vertices.extend(piece.vertices.iter().map(f32_point));
        triangles.extend(piece.triangles().iter().map(|t| t.map(|i| i + base)));
    }
    TriMesh::new(vertices, triangles).expect("convex pieces have faces")
}

fn f32_point(p: &P3) -> V3f {
    V3f::new(p.x as f32, p.y as f32, p.z as f32)
}

/// The median depth of the floor under the peg's tip: rays down the hole's axis through the
/// vertices of the peg's tip face, from 1 mm above the mouth. `None` when most find no floor.
fn floor_under_tip(peg: &Solid, surface: &TriMesh, max_depth_m: f64) -> Option<f64> {
    const START_M: f64 = 1e-3;
    let tip_z = peg.bounds().0.z;
    let tip_points: Vec<&P3> = peg
        .pieces
        .iter()
        .flat_map(|p| p.vertices.iter())
        .filter(|v| v.z - tip_z < 1e-6)
        .collect();
    let mut depths: Vec<f64> = tip_points
        .iter()
        .filter_map(|v| {
            let from = V3f::new(v.x as f32, v.y as f32, START_M as f32);
            let ray = Ray::new(from, V3f::new(0.0, 0.0, -1.0));
            let toi = surface.cast_local_ray(&ray, (max_depth_m + START_M) as f32, true)?;
            Some(toi as f64 - START_M)
        })
        .collect();
    if depths.len() * 2 <= tip_points.len() {
        return None;
    }
    depths.sort_by(f64::total_cmp);
    Some(depths[depths.len() / 2])
}

/// The smallest and the median per-slice gap (per side) between the peg's side and the hole,
/// with the peg's tip `engaged_m` below the mouth, over the band that leaves out 1 mm (or a
/// quarter of the engagement) at the mouth and at the tip, where the chamfers are.
fn gaps(peg: &Solid, surface: &TriMesh, engaged_m: f64) -> Option<(f64, f64, (f64, f64))> {
    let margin = 1e-3f64.min(engaged_m / 4.0);
    let (top, bottom) = (-margin, -engaged_m + margin);
    if top <= bottom {
        return None;
    }
    let place = at_depth(engaged_m);
    let slices = ((top - bottom) / GAP_SLICE_M).ceil().max(1.0) as usize;
    let mut slice_min = vec![f64::INFINITY; slices];
    for piece in &peg.pieces {
        for p in piece.surface_samples() {
            let q = place * p;
            if q.z > top || q.z < bottom {
                continue;
            }
            let gap = surface.distance_to_local_point(f32_point(&q), false) as f64;
            let k = (((top - q.z) / GAP_SLICE_M) as usize).min(slices - 1);
            slice_min[k] = slice_min[k].min(gap);
        }
    }
    let mut measured: Vec<f64> = slice_min.into_iter().filter(|g| g.is_finite()).collect();
    if measured.is_empty() {
        return None;
    }
    measured.sort_by(f64::total_cmp);
    Some((measured[0], measured[measured.len() / 2], (-top, -bottom)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::twin::geometry::{Builtin, build_builtin};

    #[test]
    fn the_cross_seats_its_tip_on_the_floor_with_the_gap_it_was_made_with() {
        let pair = build_builtin(Builtin::Cross, 0.5e-3).unwrap();
        let fit = measure_fit(&pair.peg, &pair.hole, 1e-3, (5e-3, 45e-3)).unwrap();
        assert_eq!(fit.seat, Seat::TipOnFloor);
        let seat = fit.seat_depth_m.unwrap();
        assert!((seat - pair.cavity_depth_m).abs() < 1e-6, "{seat}");
        let floor = fit.cavity_depth_m.unwrap();
        assert!((floor - pair.cavity_depth_m).abs() < 1e-6, "{floor}");
        assert!((fit.gap_min_m - 0.25e-3).abs() < 1e-6, "{}", fit.gap_min_m);
        assert!(
            (fit.gap_median_m - 0.25e-3).abs() < 1e-6,
            "{}",
            fit.gap_median_m
        );
    }

    #[test]
    fn a_peg_placed_inside_the_block_is_refused() {
        let pair = build_builtin(Builtin::Cross, 0.5e-3).unwrap();
        let sunk = Solid {
            pieces: pair
                .peg
                .pieces
                .iter()
                .map(|p| p.transformed(&Isometry3::translation(0.02, 0.0, -0.005)))
                .collect(),
            boundary: None,
        };
        let err = measure_fit(&sunk, &pair.hole, 1e-3, (5e-3, 45e-3)).unwrap_err();
        assert_eq!(err, FitError::IntersectsAt { depth_m: -1e-3 });
    }
}
