//! The reference manifold from the parts alone (no dynamics): the set of peg poses `hole_T_peg`
//! where the peg touches the hole without overlapping it, found with the exact separating-axis
//! test ([`PenetrationProbe`]), over the region of poses the robot sampler's motion reaches
//! ([`Region`]). The contact manifold is a property of the two parts (paper IV-A); the robot
//! sampler (paper IV-B, [`super::build`]) finds it through the physics and a contact detector,
//! this one finds it directly, in seconds instead of minutes, and independently of the physics
//! and the cell (so one file serves every physics draw of a calibration).
//!
//! **Draws.** Each draw is a tip depth, uniform over the region's depths, and a direction in
//! (x, y, roll, pitch, yaw) from the centred pose at that depth, each axis a normal variate scaled
//! by the free play of that axis (half the clearance sideways, `c / d` in tilt, half the
//! clearance over the peg's radius in yaw). The peg moves along the direction until it first
//! overlaps the hole (doubling from the step at which the direction has used up the free play,
//! then regula falsi with the Anderson-Bjorck weights until no point of the peg that can reach
//! the hole, below its top, moves more than [`TOUCH_TOLERANCE_M`] across the bracket); the free
//! end of the bracket is the contact pose. A draw whose centred pose overlaps (below the depth
//! where the centred peg first touches, [`Centred`]), or whose ray leaves the region before
//! touching, is dropped (the robot's motion does not go there). The draws are then downsampled
//! by the same voxel grid as the robot's ([`downsample`]), so that every region of the manifold
//! counts by the volume it occupies, and given normals the same way.
//!
//! The gap is the exact separating-axis test made cheap for the many nearby poses of a ray
//! ([`GapProbe::signed_gap`]); a build of the gear at 0.1 mm (100 000 draws) takes about a
//! minute on 2 cores (`pegtwin bench`).
//!
//! Every draw has its own random stream (the seed, stream = the draw's index), and draws are
//! gathered in index order: the manifold is the same on any number of threads.

use super::build::{BuildReport, SamplerConfig, downsample};
use super::{DEFAULT_NORMAL_K, MAX_POINTS, Manifold, ManifoldMeta, UNITS};
use crate::error::{Error, Result};
use crate::method::primitives::SamplingMotion;
use crate::pose::{Pose6, PoseMetric};
use crate::twin::geometry::PartPair;
use crate::twin::physics::signed_gap::{GapHints, GapProbe, NearLists};
use nalgebra::Isometry3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use rayon::prelude::*;
use serde::Serialize;

/// Contact poses drawn per pose kept: the voxel grid then evens out where the rays bunch.
pub const DRAWS_PER_POINT: usize = 2;
/// The bisection stops when no point of the peg moves more than this between the free and the
/// overlapping end of its bracket, m: each kept pose is within this of touching.
pub const TOUCH_TOLERANCE_M: f64 = 0.5e-6;
/// How far the robot's targets spread beyond its commanded motion, in standard deviations of the
/// motion's random perturbation (2: 95 % of a normal variate).
pub const PERTURBATION_REACH_SIGMAS: f64 = 2.0;
/// What decides a geometric manifold beyond its motion, points and seed: part of its cache key
/// (a change of the method here builds new files instead of reusing stale ones).
pub const RULE: &str = "geometric v3: 2 draws per point, 0.5 um, 2 sigma, first step 1/|variates|, centred gap table, \
     Minkowski edge axes, Anderson-Bjorck, engaged reach";
/// The signed gap's margin, as a share of the clearance: pairs farther apart count as this far.
/// A narrower margin tests fewer piece pairs per pose but flattens the gap away from contact, so
/// the root finder needs more poses; a quarter was the fastest of 1/16, 1/4 and 1 on the cross
/// at 0.5 mm (6.7 s against 8.0 s and 11.4 s).
const GAP_MARGIN: f64 = 0.25;
/// Draws tried at most, per contact pose wanted, before the build is refused.
const MAX_DRAWS_PER_CONTACT: usize = 50;
/// Draws handed to the thread pool at a time, at most.
const BATCH: usize = 8192;

/// The poses the robot sampler's motion ([`SamplingMotion`]) reaches at a clearance: the tip's
/// depth over the descent, widened by the perturbation; roll and pitch within the oscillation's
/// amplitude at that depth (free tilt plus overtravel, [`crate::method::primitives::
/// AmplitudeSchedule`]), yaw within its fraction of it, each widened by the perturbation; x and
/// y within the spiral's radius, widened likewise. All in the hole frame, m and rad.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Region {
    /// Tip depths below the mouth, shallowest first, m.
    pub depth_m: [f64; 2],
    /// Largest |x| and |y| of the tip, m.
    pub lateral_m: f64,
    /// Diametral clearance, m.
    clearance_m: f64,
    /// The motion whose amplitudes bound the angles.
    motion: SamplingMotion,
}

impl Region {
    /// The region the robot sampler's `motion` reaches in `pair`; the deepest tip stops at the
    /// pair's full insertion.
    pub fn of(pair: &PartPair, motion: &SamplingMotion) -> Result<Region> {
        let d = &motion.descent;
        let spread_m = PERTURBATION_REACH_SIGMAS * motion.perturbation.sigma_m;
        let shallow = (d.start_depth_m.min(d.end_depth_m) - spread_m).max(0.0);
        let deep = d.start_depth_m.max(d.end_depth_m).min(pair.cavity_depth_m);
        if deep <= shallow {
            return Err(Error::Input(format!(
                "the sampling motion's descent ({} to {} mm) does not reach into the hole of {} \
                 ({} mm deep)",
                d.start_depth_m * 1e3,
                d.end_depth_m * 1e3,
                pair.name,
                pair.cavity_depth_m * 1e3
            )));
        }
        Ok(Region {
            depth_m: [shallow, deep],
            lateral_m: motion.scale * motion.schedule.lateral_radius(pair.clearance_m) + spread_m,
            clearance_m: pair.clearance_m,
            motion: motion.clone(),
        })
    }

    /// Largest |roll|, |pitch|, |yaw| at a tip depth, rad.
    pub fn angle_limits(&self, depth_m: f64) -> [f64; 3] {
        let spread = PERTURBATION_REACH_SIGMAS * self.motion.perturbation.sigma_rad;
        (self.motion.schedule)
            .angular_amplitudes(depth_m, self.clearance_m)
            .map(|a| self.motion.scale * a + spread)
    }

    /// The largest step `s` along `dir` (x, y, roll, pitch, yaw) from the centred pose at
    /// `depth_m` that stays in the region.
    fn reach(&self, depth_m: f64, dir: &[f64; 5]) -> f64 {
        let [roll, pitch, yaw] = self.angle_limits(depth_m);
        let limits = [self.lateral_m, self.lateral_m, roll, pitch, yaw];
        limits
            .iter()
            .zip(dir)
            .filter(|(_, d)| **d != 0.0)
            .map(|(l, d)| l / d.abs())
            .fold(f64::INFINITY, f64::min)
    }
}

/// The centred peg (x, y and the angles zero) over the region's depths: its gap at evenly
/// spaced depths, and the depth down to which it is free. A draw starts from the centred pose at
/// its depth; below that depth it is [`Draw::Blocked`], above it the gap there (interpolated)
/// weighs its first secant step ([`first_touch`]).
struct Centred {
    /// Gaps at `depth_m[0] + k * step_m`, m.
    gaps: Vec<f64>,
    shallow_m: f64,
    step_m: f64,
    /// The centred peg is free from the shallowest depth down to this one, m.
    free_to_m: f64,
    /// The fixed pieces near each piece of the centred peg at the same depths, listed wide
    /// enough for the poses of most draws from there ([`LIST_REACH`]).
    lists: Vec<NearLists>,
}

/// Depths at which the centred peg's gap is sampled: a blocked stretch shorter than the region's
/// depth over this goes unseen.
const CENTRED_SAMPLES: usize = 256;
/// How far, in clearances, a piece's bounds may move from the centred peg's before its near
/// fixed pieces are looked up in the hole's tree rather than in the centred peg's lists.
const LIST_REACH: f64 = 8.0;

impl Centred {
    fn of(rays: &Rays) -> Centred {
        let [shallow_m, deep] = rays.region.depth_m;
        let step_m = (deep - shallow_m) / (CENTRED_SAMPLES - 1) as f64;
        let gap_at = |depth: f64| {
            let pose = Pose6([0.0, 0.0, -depth, 0.0, 0.0, 0.0]);
            rays.gap(&pose, &mut GapHints::default())
        };
        let gaps: Vec<f64> = (0..CENTRED_SAMPLES)
            .into_par_iter()
            .map(|k| gap_at(shallow_m + k as f64 * step_m))
            .collect();
        // Down to the first sample that overlaps, and then to its root.
        let free_to_m = match gaps.iter().position(|g| *g <= 0.0) {
            None => deep,
            Some(0) => f64::NEG_INFINITY,
            Some(k) => {
                let above = shallow_m + (k - 1) as f64 * step_m;
                let down = |s: f64| gap_at(above + s);
                match first_touch(down, gaps[k - 1], step_m, step_m, TOUCH_TOLERANCE_M) {
                    Touch::At(s) => above + s,
                    Touch::Blocked => above,
                    // Free only by the rounding of the sample's depth: its gap was not.
                    Touch::Free => above + step_m,
                }
            }
        };
        let reach_m = LIST_REACH * rays.region.clearance_m;
        let margin_m = GAP_MARGIN * rays.region.clearance_m;
        let lists = (0..CENTRED_SAMPLES)
            .into_par_iter()
            .map(|k| {
                let pose = Pose6([0.0, 0.0, -(shallow_m + k as f64 * step_m), 0.0, 0.0, 0.0]);
                (rays.probe).near_lists(&rays.pair.peg, &pose.to_iso(), margin_m, reach_m)
            })
            .collect();
        Centred {
            gaps,
            shallow_m,
            step_m,
            free_to_m,
            lists,
        }
    }

    /// The near lists of the sampled depth nearest `depth_m`.
    fn lists_at(&self, depth_m: f64) -> &NearLists {
        let k = ((depth_m - self.shallow_m) / self.step_m).round().max(0.0) as usize;
        &self.lists[k.min(self.lists.len() - 1)]
    }

    /// The centred peg's gap at `depth_m`, interpolated (positive), or `None` where it is
    /// blocked.
    fn gap_at(&self, depth_m: f64) -> Option<f64> {
        if depth_m > self.free_to_m {
            return None;
        }
        let at = ((depth_m - self.shallow_m) / self.step_m).max(0.0);
        let k = (at as usize).min(self.gaps.len() - 2);
        let t = (at - k as f64).min(1.0);
        let gap = (1.0 - t) * self.gaps[k] + t * self.gaps[k + 1];
        Some(gap.max(f64::MIN_POSITIVE))
    }
}

/// What one draw gave.
enum Draw {
    /// A contact pose.
    Contact(Pose6),
    /// The centred pose at the drawn depth already overlaps the hole.
    Blocked,
    /// The ray leaves the region before it touches.
    Outside,
}

/// A geometric build in progress: the pair, its probe, the region and the ray scales.
struct Rays<'a> {
    pair: &'a PartPair,
    probe: GapProbe,
    region: Region,
    /// The peg's vertices by their height above the tip (m), each with the largest distance
    /// from the tip of the vertices up to that height (m): turns an angle into a motion of the
    /// points that can reach the hole ([`Rays::engaged_reach`]).
    reach_by_height: Vec<(f64, f64)>,
    /// Largest distance of a peg vertex from the peg's axis, m.
    lateral_m: f64,
    /// The highest point of the hole, m (no point of the peg above it can touch the hole).
    hole_top_m: f64,
    /// Largest distance of an engaged peg vertex from the peg's axis, m (sets the yaw scale).
    radius_m: f64,
    seed: u64,
}

impl<'a> Rays<'a> {
    fn new(pair: &'a PartPair, region: Region, seed: u64) -> Self {
        let vertices = || pair.peg.pieces.iter().flat_map(|p| p.vertices.iter());
        let mut reach_by_height: Vec<(f64, f64)> =
            vertices().map(|v| (v.z, v.coords.norm())).collect();
        reach_by_height.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut most = 0.0f64;
        for (_, reach) in &mut reach_by_height {
            most = most.max(*reach);
            *reach = most;
        }
        let hole_vertices = pair.hole.pieces.iter().flat_map(|p| p.vertices.iter());
        let deepest = region.depth_m[1];
        let radius_m = vertices()
            .filter(|v| v.z <= deepest)
            .map(|v| v.x.hypot(v.y))
            .fold(0.0, f64::max);
        Rays {
            probe: GapProbe::new(&pair.hole, &Isometry3::identity()),
            pair,
            region,
            reach_by_height,
            lateral_m: vertices().map(|v| v.x.hypot(v.y)).fold(0.0, f64::max),
            hole_top_m: hole_vertices.map(|v| v.z).fold(f64::NEG_INFINITY, f64::max),
            radius_m: radius_m.max(pair.clearance_m),
            seed,
        }
    }

    /// The signed gap between the parts at `pose` (m; negative: overlapping), exact at zero
    /// ([`PenetrationProbe::signed_gap`]); pairs farther apart than [`GAP_MARGIN`] times the
    /// clearance count as that.
    fn gap(&self, pose: &Pose6, hints: &mut GapHints) -> f64 {
        let margin_m = GAP_MARGIN * self.region.clearance_m;
        (self.probe).signed_gap(&self.pair.peg, &pose.to_iso(), margin_m, hints)
    }

    /// The largest distance from the tip of a point of the peg that can touch the hole, with
    /// the tip at `depth_m` and the peg tilted within the region: the points below the hole's
    /// top, which lie at most `(top + depth + lateral sin(tilt)) / cos(tilt)` above the tip.
    fn engaged_reach(&self, depth_m: f64) -> f64 {
        let [roll, pitch, _] = self.region.angle_limits(depth_m);
        let tilt = roll.hypot(pitch);
        let all = self.reach_by_height.last().map_or(0.0, |r| r.1);
        if tilt >= std::f64::consts::FRAC_PI_2 {
            return all;
        }
        let height = (self.hole_top_m + depth_m + self.lateral_m * tilt.sin()) / tilt.cos();
        let below = self.reach_by_height.partition_point(|(z, _)| *z <= height);
        below
            .checked_sub(1)
            .map_or(0.0, |k| self.reach_by_height[k].1)
    }

    /// Draw `i`'s depth and direction (x, y, roll, pitch, yaw per unit step), each from its own
    /// stream, and the step at which the direction has used up the free play (the variates'
    /// length in units of it): where contact is likely, the first step tried.
    fn direction(&self, i: u64) -> (f64, [f64; 5], f64) {
        let mut rng = ChaCha8Rng::seed_from_u64(self.seed);
        rng.set_stream(i);
        let [shallow, deep] = self.region.depth_m;
        let depth = rng.random_range(shallow..=deep);
        let gap = self.region.clearance_m / 2.0;
        let [roll, pitch, yaw] = self.region.angle_limits(depth);
        let tilt = self.region.clearance_m / depth.max(1e-4);
        let scales = [
            gap,
            gap,
            tilt.min(roll),
            tilt.min(pitch),
            (gap / self.radius_m).min(yaw),
        ];
        let variates: [f64; 5] = std::array::from_fn(|_| StandardNormal.sample(&mut rng));
        let dir: [f64; 5] = std::array::from_fn(|k| scales[k] * variates[k]);
        let first = 1.0 / variates.iter().map(|v| v * v).sum::<f64>().sqrt();
        (depth, dir, first)
    }

    /// Draw `i`: its depth and direction ([`Self::direction`]), then the first contact along it
    /// from the centred pose (`hints`: a worker's buffers, started afresh with the centred
    /// peg's near lists at the nearest depth).
    fn draw<'c>(&self, i: u64, centred: &'c Centred, hints: &mut GapHints<'c>) -> Draw {
        let (depth, dir, first) = self.direction(i);
        hints.start(centred.lists_at(depth));
        let Some(gap0) = centred.gap_at(depth) else {
            return Draw::Blocked;
        };
        let pose = |s: f64| {
            let [x, y, r, p, w] = dir.map(|d| s * d);
            Pose6([x, y, -depth, r, p, w])
        };
        // How far the tip moves and the peg turns per unit step (the turn: every angle's share,
        // summed, an upper bound), and a point of the peg at most (at the farthest vertex).
        let translation = dir[0].hypot(dir[1]);
        let turn: f64 = dir[2..].iter().map(|a| a.abs()).sum();
        let speed = translation + self.engaged_reach(depth) * turn;
        // The gaps of the last step, and the step, so that the next one skips the pairs its
        // motion cannot bring closest ([`GapHints::moved`]).
        let last = std::cell::RefCell::new((hints, None::<f64>));
        let along = |s: f64| {
            let (hints, step) = &mut *last.borrow_mut();
            if let Some(previous) = step.replace(s) {
                let ds = (s - previous).abs();
                hints.moved(translation * ds, turn * ds);
            }
            self.gap(&pose(s), hints)
        };
        let limit = self.region.reach(depth, &dir);
        match first_touch(along, gap0, first, limit, TOUCH_TOLERANCE_M / speed) {
            Touch::At(s) => Draw::Contact(pose(s)),
            Touch::Blocked => Draw::Blocked,
            Touch::Free => Draw::Outside,
        }
    }
}

/// Where a ray first touches.
#[derive(Debug, PartialEq)]
enum Touch {
    /// Free at this step, overlapping within the tolerance beyond it.
    At(f64),
    /// Touching or overlapping at the start.
    Blocked,
    /// Free all the way to the limit.
    Free,
}

/// The first root of `gap(s)` for `s` in `[0, limit]`, bracketed to `tolerance` (the free end
/// returned), where `gap` is a signed gap, continuous and exact at zero, and `gap0` is positive,
/// the gap at zero or an estimate of it (it weighs the first secant only; zero is tested only
/// if it ends up the free end). The bracket is found by doubling from the step `first`, then
/// narrowed by regula falsi with the Anderson-Bjorck modification (superlinear on
/// piecewise-smooth gaps), each step kept half a tolerance inside the bracket so that the last
/// two close it.
fn first_touch(
    gap: impl Fn(f64) -> f64,
    gap0: f64,
    first: f64,
    limit: f64,
    tolerance: f64,
) -> Touch {
    let (mut lo, mut f_lo, mut lo_tested) = (0.0, gap0, false);
    let mut hi = first.min(limit);
    let mut f_hi = gap(hi);
    while f_hi > 0.0 {
        if hi >= limit {
            return Touch::Free;
        }
        (lo, f_lo, lo_tested) = (hi, f_hi, true);
        hi = (2.0 * hi).min(limit);
        f_hi = gap(hi);
    }
    let mut side = 0i8;
    while hi - lo > tolerance {
        let secant = (lo * f_hi - hi * f_lo) / (f_hi - f_lo);
        let s = if secant.is_finite() {
            // Half a tolerance inside either end at least: a step that close to the root
            // closes the bracket with the next one.
            secant.clamp(lo + 0.5 * tolerance, hi - 0.5 * tolerance)
        } else {
            0.5 * (lo + hi)
        };
        let f = gap(s);
        // Anderson-Bjorck: an end kept twice is weighed down by how much the other end's gap
        // fell (by half where it did not fall).
        let weight = |replaced: f64| match 1.0 - f / replaced {
            m if m > 0.0 => m,
            _ => 0.5,
        };
        if f > 0.0 {
            if side == 1 {
                f_hi *= weight(f_lo);
            }
            (lo, f_lo, lo_tested, side) = (s, f, true, 1);
        } else {
            if side == -1 {
                f_lo *= weight(f_hi);
            }
            (hi, f_hi, side) = (s, f, -1);
        }
    }
    if !lo_tested && gap(lo) <= 0.0 {
        return Touch::Blocked;
    }
    Touch::At(lo)
}

/// What a geometric build drew.
struct Drawn {
    contacts: Vec<Pose6>,
    draws: usize,
    blocked: usize,
    outside: usize,
}

/// Draws until `wanted` contact poses are found (in draw order), refusing after
/// [`MAX_DRAWS_PER_CONTACT`] draws per pose wanted, or after a first batch with none.
fn draw_contacts(rays: &Rays, wanted: usize) -> Result<Drawn> {
    let mut drawn = Drawn {
        contacts: Vec::with_capacity(wanted),
        draws: 0,
        blocked: 0,
        outside: 0,
    };
    let most = wanted.saturating_mul(MAX_DRAWS_PER_CONTACT);
    let centred = Centred::of(rays);
    while drawn.contacts.len() < wanted {
        // Refused at the budget, or at once when a whole batch touched nowhere.
        if drawn.draws >= most || (drawn.draws > 0 && drawn.contacts.is_empty()) {
            return Err(Error::Input(format!(
                "{} of {} geometric draws of {} at {} mm touched inside the region the robot's \
                 motion reaches ({} started overlapping, {} left the region): the peg does not \
                 fit its hole centred, or the region misses the walls",
                drawn.contacts.len(),
                drawn.draws,
                rays.pair.name,
                rays.pair.clearance_mm(),
                drawn.blocked,
                drawn.outside
            )));
        }
        // No more draws than poses still wanted: those beyond would not be kept.
        let size = (wanted - drawn.contacts.len()).min(BATCH);
        let start = drawn.draws as u64;
        let batch: Vec<Draw> = (start..start + size as u64)
            .into_par_iter()
            .map_init(GapHints::default, |hints, i| rays.draw(i, &centred, hints))
            .collect();
        drawn.draws += size;
        for d in batch {
            match d {
                Draw::Contact(p) if drawn.contacts.len() < wanted => drawn.contacts.push(p),
                Draw::Contact(_) => {}
                Draw::Blocked => drawn.blocked += 1,
                Draw::Outside => drawn.outside += 1,
            }
        }
    }
    Ok(drawn)
}

/// Builds the reference manifold of `pair` from its geometry: [`DRAWS_PER_POINT`] x `points`
/// contact poses over the region `config`'s motion reaches, downsampled to `points` by the voxel
/// grid, normals from the `DEFAULT_NORMAL_K` nearest neighbours.
pub fn build(
    pair: &PartPair,
    config: &SamplerConfig,
    points: usize,
    seed: u64,
) -> Result<BuildReport> {
    if !(DEFAULT_NORMAL_K + 1..=MAX_POINTS).contains(&points) {
        return Err(Error::Input(format!(
            "--points {points}: expected {} (the normal neighbourhood) to {MAX_POINTS}",
            DEFAULT_NORMAL_K + 1
        )));
    }
    let region = Region::of(pair, &config.motion)?;
    let rays = Rays::new(pair, region.clone(), seed);
    let drawn = draw_contacts(&rays, DRAWS_PER_POINT * points)?;
    let metric = PoseMetric::default();
    let kept = downsample(&drawn.contacts, &metric, points, seed);
    let meta = ManifoldMeta {
        geometry: pair.name.clone(),
        clearance_m: Some(pair.clearance_m),
        units: UNITS.into(),
        metric,
        normal_k: DEFAULT_NORMAL_K,
        source: format!(
            "pegtwin manifold build --sampler geometric: {} contact poses from {} draws ({} \
             started overlapping, {} left the region, dropped), each within {} um of touching, \
             voxel-grid downsampled; region {}",
            drawn.contacts.len(),
            drawn.draws,
            drawn.blocked,
            drawn.outside,
            TOUCH_TOLERANCE_M * 1e6,
            serde_json::to_string(&region).expect("region serialises")
        ),
        seed: Some(seed),
    };
    Ok(BuildReport {
        manifold: Manifold::from_points(kept, meta)?,
        raw_count: drawn.contacts.len(),
        faults: Vec::new(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::twin::geometry::{build_builtin, builtin_by_name};
    use crate::twin::physics::penetration::PenetrationProbe;

    #[test]
    fn the_first_touch_is_bracketed_to_the_tolerance_from_the_free_side() {
        // A kinked gap with its root at 0.7.
        let gap = |s: f64| {
            if s < 0.5 {
                1.0 - s
            } else {
                0.5 - (s - 0.5) * 2.5
            }
        };
        // The gap at zero, exact or only estimated, weighs the first step only.
        for gap0 in [1.0, 1e-3, 1e3] {
            let Touch::At(s) = first_touch(gap, gap0, 1.0, 10.0, 1e-9) else {
                panic!("a root in range");
            };
            assert!(s <= 0.7 && 0.7 - s <= 1e-9, "{gap0}: {s}");
        }
        assert_eq!(first_touch(gap, 1.0, 1.0, 0.6, 1e-9), Touch::Free);
        // Zero is tested when the bracket closes on it: overlapping or touching there.
        assert_eq!(
            first_touch(|s| s - 1.0, 1.0, 1.0, 10.0, 1e-9),
            Touch::Blocked
        );
        assert_eq!(
            first_touch(|_| 0.0, 1.0, 1.0, 10.0, 1e-9),
            Touch::Blocked,
            "touching at the start"
        );
        // A root far beyond the first step: found by doubling.
        let Touch::At(s) = first_touch(|s| 37.0 - s, 37.0, 1.0, 100.0, 1e-9) else {
            panic!("a root in range");
        };
        assert!((37.0 - s) <= 1e-9 && s <= 37.0, "{s}");
    }

    #[test]
    fn the_centred_peg_is_blocked_only_below_the_floor() {
        let pair = build_builtin(builtin_by_name("cross").unwrap(), 0.5e-3).unwrap();
        let mut motion = SamplerConfig::default().motion;
        let rays = Rays::new(&pair, Region::of(&pair, &motion).unwrap(), 1);
        let centred = Centred::of(&rays);
        // Free over the whole descent, the clearance's half a side at every depth.
        assert_eq!(centred.free_to_m, rays.region.depth_m[1]);
        for depth in [1e-3, 7.3e-3, 20e-3] {
            let g = centred.gap_at(depth).unwrap();
            assert!(g > 0.0 && g <= GAP_MARGIN * 0.5e-3, "{depth}: {g}");
        }
        // A descent to the hole's floor: blocked within the tolerance above it.
        motion.descent.end_depth_m = 1.0;
        let rays = Rays::new(&pair, Region::of(&pair, &motion).unwrap(), 1);
        let floor = pair.cavity_depth_m;
        let centred = Centred::of(&rays);
        assert!(
            centred.free_to_m <= floor && floor - centred.free_to_m <= TOUCH_TOLERANCE_M,
            "{} against {floor}",
            centred.free_to_m
        );
        assert_eq!(centred.gap_at(floor), None);
        assert!(centred.gap_at(floor - 1e-3).is_some());
    }

    #[test]
    fn the_region_is_the_one_the_robot_sampler_reaches() {
        let pair = build_builtin(builtin_by_name("cross").unwrap(), 0.5e-3).unwrap();
        let motion = SamplerConfig::default().motion;
        let region = Region::of(&pair, &motion).unwrap();
        // The descent from 2 to 20 mm, the shallow end widened by two sigmas of 0.5 mm.
        assert!(
            (region.depth_m[0] - 1e-3).abs() < 1e-12,
            "{:?}",
            region.depth_m
        );
        assert!(
            (region.depth_m[1] - 20e-3).abs() < 1e-12,
            "{:?}",
            region.depth_m
        );
        // At 2 mm the free tilt c/d = 0.25 rad is capped at 0.035; then 0.06 of overtravel and
        // two sigmas of 5 mrad. At 20 mm, c/d = 0.025.
        for (depth, tilt) in [(2e-3, 0.105), (20e-3, 0.095)] {
            let limits = region.angle_limits(depth);
            for l in limits {
                assert!((l - tilt).abs() < 1e-12, "{depth}: {limits:?}");
            }
        }
        let mut shallow = motion.clone();
        shallow.descent.end_depth_m = -3e-3;
        shallow.descent.start_depth_m = -1e-3;
        let e = Region::of(&pair, &shallow).unwrap_err().to_string();
        assert!(e.contains("does not reach into the hole"), "{e}");
        // A motion that never leaves the free play touches nowhere: refused after one batch.
        let mut timid = SamplerConfig::default();
        let m = &mut timid.motion;
        (m.scale, m.schedule.lateral_overtravel_m) = (0.5, 0.0);
        (
            m.schedule.angular_overtravel_rad,
            m.schedule.max_free_tilt_rad,
        ) = (0.0, 0.0);
        (m.perturbation.sigma_m, m.perturbation.sigma_rad) = (0.0, 0.0);
        let e = build(&pair, &timid, 1000, 1)
            .err()
            .expect("refused")
            .to_string();
        // One batch of as many draws as poses wanted (two per point).
        assert!(e.contains("0 of 2000 geometric draws"), "{e}");
        assert!(e.contains("2000 left the region"), "{e}");
    }

    #[test]
    fn every_pose_touches_within_the_tolerance_the_same_on_one_thread() {
        let pair = build_builtin(builtin_by_name("key").unwrap(), 0.3e-3).unwrap();
        let config = SamplerConfig::default();
        let report = build(&pair, &config, 2000, 3).unwrap();
        let m = &report.manifold;
        assert_eq!(m.len(), 2000);
        assert_eq!(report.raw_count, 4000);
        let probe = GapProbe::new(&pair.hole, &Isometry3::identity());
        let exact = PenetrationProbe::new(&pair.hole, &Isometry3::identity());
        for p in &m.points {
            let mut hints = GapHints::default();
            let gap = probe.signed_gap(&pair.peg, &p.to_iso(), 1e-3, &mut hints);
            // Free, and within the tolerance of touching (the gap bounds the distance below).
            assert!((0.0..=TOUCH_TOLERANCE_M).contains(&gap), "{p:?}: {gap}");
            assert_eq!(exact.max_penetration(&pair.peg, &p.to_iso()), 0.0);
            assert!((-20e-3..=-1e-3).contains(&p.0[2]), "{p:?}");
        }
        let one = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap();
        let alone = one.install(|| build(&pair, &config, 2000, 3)).unwrap();
        assert_eq!(alone.manifold.points, m.points);
        assert_eq!(alone.manifold.normals, m.normals);
        assert_ne!(
            build(&pair, &config, 2000, 4).unwrap().manifold.points,
            m.points
        );
        assert!(
            build(&pair, &config, 5, 3).is_err(),
            "too few points for a normal"
        );
    }
}
