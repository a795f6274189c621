//! What pegtwin measures of a peg/hole fit from the solids alone, with the peg lined up on the
//! hole's axis (peg frame on the hole frame, moved down z): how far the peg goes in before it
//! stops and on what (its tip on the floor, or its flange on the block), the cavity's depth under
//! the tip, and the gap between peg and hole walls over the engagement (per side, minimum and
//! median over 0.5 mm slices). The exact penetration test (`twin::physics::penetration`) decides
//! contact; the gaps are distances from points on the peg's side to the hole's walls (faces that
//! face sideways), each as it would be with the peg centred on the hole's axis: the offset and
//! the tilt of the peg's axis are fitted from the gaps themselves ([`Axis`]), so that a frame
//! off the axis reads as a misalignment, not as a tighter fit.

pub use crate::twin::geometry::Seat;
use crate::twin::geometry::solid::{P3, Solid};
use crate::twin::physics::penetration::PenetrationProbe;
use nalgebra::{DMatrix, DVector, Isometry3};
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
/// A hole face is a wall when its normal's z component is at most this (within 30 degrees of
/// horizontal): the floor, the mouth's face and 45-degree chamfers are not.
const WALL_MAX_NZ: f64 = 0.5;
/// A peg sample is behind the peg's surface when the way from its wall point meets the surface
/// more than this before it, m (f32 surfaces).
const FACING_TOLERANCE_M: f64 = 1e-6;
/// Direction sectors around the axis in which the facing gaps' lower envelope is taken.
const SECTORS: usize = 72;
/// Rounds of the axis fit that leave out the gaps it does not explain.
const TRIM_ROUNDS: usize = 10;
/// A gap within this of the fit is always kept, m.
const TRIM_FLOOR_M: f64 = 1e-6;
/// Singular values of the axis fit below this fraction of the largest are left out.
const AXIS_CONDITION: f64 = 1e-9;

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
    /// Where the peg's axis runs against the hole's, as the wall gaps show it.
    pub axis: Axis,
}

/// Where the peg's axis runs in the hole frame, measured from the wall gaps: how far it stands
/// off the hole's axis at the middle of the measured band, and how it leans.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Axis {
    /// Offset of the peg's axis from the hole's, x and y in the hole frame, m.
    pub offset_m: [f64; 2],
    /// Change of that offset per metre down the hole (x and y): the tilt, rad for small angles.
    pub tilt: [f64; 2],
    /// Depth (hole frame z) at which `offset_m` is taken, m.
    pub z_mid_m: f64,
}

impl Axis {
    /// How far off the hole's axis, m.
    pub fn offset_norm_m(&self) -> f64 {
        self.offset_m[0].hypot(self.offset_m[1])
    }

    /// The angle between the two axes, rad.
    pub fn tilt_rad(&self) -> f64 {
        self.tilt[0].hypot(self.tilt[1]).atan()
    }

    /// How much wider the gap `g` would be with the peg on the hole's axis, m.
    fn shift_along(&self, g: &WallGap) -> f64 {
        let dz = g.z_m - self.z_mid_m;
        let [ox, oy] = self.offset_m;
        g.toward[0] * (ox + dz * self.tilt[0]) + g.toward[1] * (oy + dz * self.tilt[1])
    }
}

/// The gaps over the engagement, per side, as with the peg on the hole's axis.
struct Gaps {
    min_m: f64,
    median_m: f64,
    band_m: (f64, f64),
    axis: Axis,
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
    let gaps = gaps(peg, hole, engaged).ok_or(FitError::NoEngagement)?;
    Ok(Fit {
        seat_depth_m: contact,
        seat,
        cavity_depth_m,
        gap_min_m: gaps.min_m,
        gap_median_m: gaps.median_m,
        gap_band_m: gaps.band_m,
        axis: gaps.axis,
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

/// A wall's gap as seen from one point of the peg's side: the distance to the nearest wall, the
/// horizontal part of the unit direction towards it and the point's depth (hole frame, z up).
#[derive(Clone, Copy, Debug)]
struct WallGap {
    gap_m: f64,
    toward: [f64; 2],
    z_m: f64,
}

/// The hole's walls: the faces of its pieces that face sideways (the floor, the mouth's face and
/// its chamfers left out, so that a wide gap reads as wide, not as the floor's distance).
fn wall_surface(solid: &Solid) -> Option<TriMesh> {
    let mut vertices = Vec::new();
    let mut triangles = Vec::new();
    for piece in &solid.pieces {
        for t in piece.triangles() {
            let [a, b, c] = t.map(|i| piece.vertices[i as usize]);
            let n = (b - a).cross(&(c - a));
            if n.norm() == 0.0 || n.z.abs() > WALL_MAX_NZ * n.norm() {
                continue;
            }
            let base = vertices.len() as u32;
            vertices.extend([a, b, c].iter().map(f32_point));
            triangles.push([base, base + 1, base + 2]);
        }
    }
    TriMesh::new(vertices, triangles).ok()
}

/// The wall gap of every sample of the peg's surface in the band (`top_m` to `bottom_m`, hole
/// frame z) that faces the wall across it, the peg placed at `place`: a sample behind the
/// peg's own surface (on a face between two of its pieces) is left out.
fn side_gaps(
    peg: &Solid,
    walls: &TriMesh,
    place: &Isometry3<f64>,
    (top_m, bottom_m): (f64, f64),
) -> Vec<WallGap> {
    let skin = union_surface(peg);
    let mut out = Vec::new();
    for piece in &peg.pieces {
        for p in piece.surface_samples() {
            let q = place * p;
            if q.z > top_m || q.z < bottom_m {
                continue;
            }
            let at = f32_point(&q);
            let wall = walls.project_local_point(at, false).point;
            let to_wall = wall - at;
            let gap = f64::from(to_wall.length());
            if gap > FACING_TOLERANCE_M && hidden(&skin, place, wall, at) {
                continue;
            }
            let (dx, dy) = (f64::from(to_wall.x), f64::from(to_wall.y));
            if dx.hypot(dy) > 0.0 {
                out.push(WallGap {
                    gap_m: gap,
                    toward: [dx / gap, dy / gap],
                    z_m: q.z,
                });
            }
        }
    }
    out
}

/// Whether the way from the wall point `wall` back to the peg's sample `at` (hole frame) meets
/// the peg's surface `skin` (peg frame, placed at `place`) before the sample.
fn hidden(skin: &TriMesh, place: &Isometry3<f64>, wall: V3f, at: V3f) -> bool {
    let back = place.inverse();
    let from = back * P3::new(f64::from(wall.x), f64::from(wall.y), f64::from(wall.z));
    let to = back * P3::new(f64::from(at.x), f64::from(at.y), f64::from(at.z));
    let length = (to - from).norm();
    let ray = Ray::new(f32_point(&from), f32_point(&P3::from((to - from) / length)));
    skin.cast_local_ray(&ray, length as f32, true)
        .is_some_and(|toi| (length - f64::from(toi)) > FACING_TOLERANCE_M)
}

/// The nearest wall gap per direction sector and per slice (one list per sector, in turn): the
/// lower
/// envelope of the gaps, a property of the two shapes that does not depend on how their faces
/// happen to be sampled.
fn facing_minima(gaps: &[WallGap], top_m: f64) -> Vec<Vec<WallGap>> {
    let mut best: std::collections::BTreeMap<(usize, usize), WallGap> = Default::default();
    for g in gaps {
        let slice = ((top_m - g.z_m) / GAP_SLICE_M) as usize;
        // Sectors centred on whole multiples of their width: a face along x or at 45 degrees
        // falls in one sector, not on a border where rounding picks a side.
        let turn = g.toward[1].atan2(g.toward[0]) / std::f64::consts::TAU;
        let sector = (turn * SECTORS as f64).round().rem_euclid(SECTORS as f64) as usize;
        let entry = best.entry((sector, slice)).or_insert(*g);
        if g.gap_m < entry.gap_m {
            *entry = *g;
        }
    }
    let mut sectors = vec![Vec::new(); SECTORS];
    for ((sector, _), g) in best {
        sectors[sector].push(g);
    }
    sectors
}

/// The peg's axis against the hole's, as the walls show it, from the facing gaps of each
/// direction sector (`gap = g_k - u . (offset + (z - z_mid) tilt)`, first order in the
/// misalignment: the distance's gradient is the direction to the wall):
/// - the tilt from how each sector's gap changes down the hole, whatever its level `g_k` (a
///   trimmed least-squares fit, rounds leaving out the gaps it does not explain);
/// - the offset from how opposite sectors' levels differ, assuming the design's gap is the same
///   on opposite sides (a polygonised arc on one side reads as a small offset: [`gaps`] and the
///   assembly's alignment check allow for it).
fn fit_axis(sectors: &[Vec<WallGap>], z_mid_m: f64) -> Axis {
    let mut kept: Vec<Vec<WallGap>> = sectors.to_vec();
    let mut tilt = [0.0; 2];
    for _ in 0..TRIM_ROUNDS {
        tilt = fit_tilt(&kept);
        let residuals: Vec<Vec<f64>> = kept.iter().map(|k| levelled(k, tilt, z_mid_m)).collect();
        let level: Vec<f64> = residuals.iter().map(|r| median(&mut r.clone())).collect();
        let mut spread: Vec<f64> = (residuals.iter().zip(&level))
            .flat_map(|(r, l)| r.iter().map(move |v| (v - l).abs()))
            .collect();
        let limit = (3.0 * median(&mut spread)).max(TRIM_FLOOR_M);
        for ((k, r), l) in kept.iter_mut().zip(&residuals).zip(&level) {
            let mut keep = r.iter().map(|v| (v - l).abs() <= limit);
            k.retain(|_| keep.next().unwrap_or(false));
        }
    }
    let offset_m = fit_offset(&kept, tilt, z_mid_m);
    Axis {
        offset_m,
        tilt,
        z_mid_m,
    }
}

/// Each gap of one sector as it would be at `z_mid_m` with the tilt undone.
fn levelled(sector: &[WallGap], tilt: [f64; 2], z_mid_m: f64) -> Vec<f64> {
    let axis = Axis {
        offset_m: [0.0; 2],
        tilt,
        z_mid_m,
    };
    sector
        .iter()
        .map(|g| g.gap_m + axis.shift_along(g))
        .collect()
}

/// The median of `values` (sorted in place; 0 for none).
fn median(values: &mut [f64]) -> f64 {
    values.sort_by(f64::total_cmp);
    values.get(values.len() / 2).copied().unwrap_or(0.0)
}

/// The tilt that best explains how each sector's gap changes down the hole: least squares on
/// the gaps and depths centred within each sector.
fn fit_tilt(sectors: &[Vec<WallGap>]) -> [f64; 2] {
    let (mut ata, mut atb) = (DMatrix::zeros(2, 2), DVector::zeros(2));
    for sector in sectors.iter().filter(|s| s.len() >= 2) {
        let n = sector.len() as f64;
        let mean_gap = sector.iter().map(|g| g.gap_m).sum::<f64>() / n;
        let mean_z = sector.iter().map(|g| g.z_m).sum::<f64>() / n;
        for g in sector {
            let dz = g.z_m - mean_z;
            let row = DVector::from_vec(vec![-g.toward[0] * dz, -g.toward[1] * dz]);
            ata += &row * row.transpose();
            atb += &row * (g.gap_m - mean_gap);
        }
    }
    solve_small(ata, atb).map_or([0.0; 2], |x| [x[0], x[1]])
}

/// The offset at `z_mid_m` that best explains how opposite sectors' levels differ: each pair
/// with gaps on both sides says `(level_opposite - level_k) / 2 = u_k . offset`; weighted least
/// squares over the pairs, each weighted by the slices the poorer side holds. A sector whose
/// opposite holds no gap says nothing (a design's corners need not face one another).
fn fit_offset(sectors: &[Vec<WallGap>], tilt: [f64; 2], z_mid_m: f64) -> [f64; 2] {
    let (mut ata, mut atb) = (DMatrix::zeros(2, 2), DVector::zeros(2));
    let half = sectors.len() / 2;
    for (one, other) in sectors[..half].iter().zip(&sectors[half..]) {
        if one.is_empty() || other.is_empty() {
            continue;
        }
        let n = one.len().min(other.len()) as f64;
        let level = |s: &[WallGap]| median(&mut levelled(s, tilt, z_mid_m));
        let along = 0.5 * (level(other) - level(one));
        let u = [0, 1].map(|i| {
            let mean = |s: &[WallGap]| s.iter().map(|g| g.toward[i]).sum::<f64>() / s.len() as f64;
            0.5 * (mean(one) - mean(other))
        });
        let row = DVector::from_vec(vec![u[0], u[1]]);
        ata += n * &row * row.transpose();
        atb += n * along * &row;
    }
    solve_small(ata, atb).map_or([0.0; 2], |x| [x[0], x[1]])
}

/// The solution of a small normal system, its unfixed directions left at zero.
fn solve_small(ata: DMatrix<f64>, atb: DVector<f64>) -> Option<DVector<f64>> {
    let svd = ata.svd(true, true);
    let eps = AXIS_CONDITION * svd.singular_values.max();
    svd.solve(&atb, eps)
        .ok()
        .filter(|x| x.iter().all(|v| v.is_finite()))
}

/// Each slice's smallest gap, each gap widened by `shift`, in increasing order.
fn slice_minima(
    gaps: &[WallGap],
    (top_m, bottom_m): (f64, f64),
    shift: impl Fn(&WallGap) -> f64,
) -> Vec<f64> {
    let slices = ((top_m - bottom_m) / GAP_SLICE_M).ceil().max(1.0) as usize;
    let mut slice_min = vec![f64::INFINITY; slices];
    for g in gaps {
        let k = (((top_m - g.z_m) / GAP_SLICE_M) as usize).min(slices - 1);
        slice_min[k] = slice_min[k].min(g.gap_m + shift(g));
    }
    let mut measured: Vec<f64> = slice_min.into_iter().filter(|g| g.is_finite()).collect();
    measured.sort_by(f64::total_cmp);
    measured
}

/// The smallest and the median per-slice gap (per side) between the peg's side and the hole's
/// walls, with the peg's tip `engaged_m` below the mouth, over the band that leaves out 1 mm (or
/// a quarter of the engagement) at the mouth and at the tip, where the chamfers are; with the
/// peg centred on the hole's axis (the measured misalignment undone) when that gives it more room.
fn gaps(peg: &Solid, hole: &Solid, engaged_m: f64) -> Option<Gaps> {
    let margin = 1e-3f64.min(engaged_m / 4.0);
    let (top, bottom) = (-margin, -engaged_m + margin);
    if top <= bottom {
        return None;
    }
    let walls = wall_surface(hole)?;
    let raw = side_gaps(peg, &walls, &at_depth(engaged_m), (top, bottom));
    let axis = fit_axis(&facing_minima(&raw, top), 0.5 * (top + bottom));
    // The peg where it stands or on the fitted axis, whichever leaves it more room: a design's
    // own uneven gaps (a polygonised arc on one side) can pull the fit off a true axis, and the
    // play of the peg is at least what it has in either place.
    let as_placed = slice_minima(&raw, (top, bottom), |_| 0.0);
    let centred = slice_minima(&raw, (top, bottom), |g| axis.shift_along(g));
    let measured = match (as_placed.first(), centred.first()) {
        (Some(a), Some(c)) if a >= c => as_placed,
        _ => centred,
    };
    if measured.is_empty() {
        return None;
    }
    Some(Gaps {
        min_m: measured[0],
        median_m: measured[measured.len() / 2],
        band_m: (-top, -bottom),
        axis,
    })
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
