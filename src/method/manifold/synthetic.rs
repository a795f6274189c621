//! Analytic contact manifolds of prismatic pegs, for testing and benchmarking registration with a
//! known ground truth, independent of the physics.
//!
//! A prismatic peg (outline extruded along its z, tip at z = 0) sits in a prismatic cavity (the
//! outline grown by half the clearance, mouth at z = 0, z out of the hole). The peg is free when
//! its part below the mouth lies inside the cavity. Contacts between two prisms are vertex-to-face:
//! a vertical edge of the peg against a cavity wall, or a vertical edge of the cavity against a peg
//! face; both distances vary linearly along the edges, so they are checked at the two ends of the
//! engaged part, the tip outline and the peg's section in the mouth plane. [`SyntheticPair::margin`]
//! is the smallest of those signed distances (m): positive when free, zero in contact, negative in
//! penetration. Contact poses are found by bisection on the margin along random directions from the
//! centred pose, at depths drawn uniformly from a range.

use crate::pose::{Pose6, rotation_rpy};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use rayon::prelude::*;

/// A peg outline and its cavity, both counter-clockwise, in metres.
#[derive(Clone, Debug)]
pub struct SyntheticPair {
    /// Name for metadata (`synthetic-square`, `synthetic-cross`).
    pub name: String,
    /// Diametral clearance, m.
    pub clearance_m: f64,
    peg: Vec<[f64; 2]>,
    cavity: Vec<[f64; 2]>,
    /// Cavity vertices that point into the cavity (where hole material can touch a peg face).
    cavity_reflex: Vec<[f64; 2]>,
    /// Half the smallest outline width, m (sets the scale of the yaw search).
    half_width_m: f64,
}

/// Root-finding stops when the margin is below this, m.
const MARGIN_TOLERANCE_M: f64 = 1e-12;
/// Root-finding gives up after this many evaluations (the bracket is then 2⁻⁶⁰ of its start).
const MAX_EVALUATIONS: usize = 60;

/// The smallest `s > 0` where `margin(s)` crosses zero, with `margin(0) > 0`: the bracket is
/// doubled until the margin is negative, then narrowed by regula falsi with the Illinois
/// modification (superlinear on piecewise-smooth margins). `None` if no contact is found.
fn contact_along(margin: impl Fn(f64) -> f64) -> Option<f64> {
    let (mut lo, mut f_lo) = (0.0, margin(0.0));
    let (mut hi, mut f_hi) = (1.0, margin(1.0));
    while f_hi > 0.0 {
        (lo, f_lo) = (hi, f_hi);
        hi *= 2.0;
        if hi > 1e6 {
            return None;
        }
        f_hi = margin(hi);
    }
    let mut side = 0i8;
    for _ in 0..MAX_EVALUATIONS {
        let s = (lo * f_hi - hi * f_lo) / (f_hi - f_lo);
        let f = margin(s);
        if f.abs() < MARGIN_TOLERANCE_M {
            return Some(s);
        }
        if f > 0.0 {
            (lo, f_lo) = (s, f);
            if side == 1 {
                f_hi *= 0.5;
            }
            side = 1;
        } else {
            (hi, f_hi) = (s, f);
            if side == -1 {
                f_lo *= 0.5;
            }
            side = -1;
        }
    }
    Some(0.5 * (lo + hi))
}

impl SyntheticPair {
    /// A square peg of side `side_m` in a square hole of side `side_m + clearance_m`.
    pub fn square(side_m: f64, clearance_m: f64) -> Self {
        let rect = |h: f64| vec![[-h, -h], [h, -h], [h, h], [-h, h]];
        Self::new(
            "synthetic-square",
            clearance_m,
            rect(side_m / 2.0),
            rect((side_m + clearance_m) / 2.0),
            side_m / 2.0,
        )
    }

    /// A plus-shaped peg, `span_m` end to end and `arm_m` wide, in a cavity grown by half the
    /// clearance on every side.
    pub fn cross(span_m: f64, arm_m: f64, clearance_m: f64) -> Self {
        let plus = |s: f64, a: f64| {
            vec![
                [a, -s],
                [a, -a],
                [s, -a],
                [s, a],
                [a, a],
                [a, s],
                [-a, s],
                [-a, a],
                [-s, a],
                [-s, -a],
                [-a, -a],
                [-a, -s],
            ]
        };
        let g = clearance_m / 2.0;
        Self::new(
            "synthetic-cross",
            clearance_m,
            plus(span_m / 2.0, arm_m / 2.0),
            plus(span_m / 2.0 + g, arm_m / 2.0 + g),
            arm_m / 2.0,
        )
    }

    fn new(
        name: &str,
        clearance_m: f64,
        peg: Vec<[f64; 2]>,
        cavity: Vec<[f64; 2]>,
        half_width_m: f64,
    ) -> Self {
        let cavity_reflex = reflex_vertices(&cavity);
        SyntheticPair {
            name: name.to_string(),
            clearance_m,
            peg,
            cavity,
            cavity_reflex,
            half_width_m,
        }
    }

    /// Signed distance (m) from contact for the peg at `hole_T_peg`: > 0 free, 0 contact, < 0
    /// penetrating. Only meaningful with the tip below the mouth.
    pub fn margin(&self, hole_t_peg: &Pose6) -> f64 {
        let [x, y, z, roll, pitch, yaw] = hole_t_peg.0;
        let r = rotation_rpy(roll, pitch, yaw);
        let m = r.matrix();
        let section = |mouth: bool| -> Vec<[f64; 2]> {
            self.peg
                .iter()
                .map(|u| {
                    // Point at height h along the peg's vertical edge through u.
                    let h = if mouth {
                        (-(z + m[(2, 0)] * u[0] + m[(2, 1)] * u[1]) / m[(2, 2)]).max(0.0)
                    } else {
                        0.0
                    };
                    [
                        x + m[(0, 0)] * u[0] + m[(0, 1)] * u[1] + m[(0, 2)] * h,
                        y + m[(1, 0)] * u[0] + m[(1, 1)] * u[1] + m[(1, 2)] * h,
                    ]
                })
                .collect()
        };
        [section(false), section(true)]
            .iter()
            .map(|s| self.section_margin(s))
            .fold(f64::INFINITY, f64::min)
    }

    /// Containment margin of one peg section in the cavity: peg vertices inside the cavity, cavity
    /// reflex vertices outside the peg.
    fn section_margin(&self, section: &[[f64; 2]]) -> f64 {
        let inside = section
            .iter()
            .map(|v| signed_distance(v, &self.cavity))
            .fold(f64::INFINITY, f64::min);
        let outside = self
            .cavity_reflex
            .iter()
            .map(|w| -signed_distance(w, section))
            .fold(f64::INFINITY, f64::min);
        inside.min(outside)
    }

    /// `n` contact poses `hole_T_peg` with the tip at depths uniform in `depth_m` (below the
    /// mouth, positive numbers), deterministic in `seed` whatever the thread count.
    pub fn sample_contacts(&self, n: usize, depth_m: [f64; 2], seed: u64) -> Vec<Pose6> {
        (0..n)
            .into_par_iter()
            .map(|i| {
                let mut rng = ChaCha8Rng::seed_from_u64(seed);
                rng.set_stream(i as u64);
                self.sample_one(&mut rng, depth_m)
            })
            .collect()
    }

    /// `n` observations `A_T_p = A_T_h ⊗ hole_T_peg` of contact poses at depths in `depth_m`,
    /// each coordinate disturbed by uniform noise of half-width `noise_m` (positions) and
    /// `noise_rad` (angles): what a robot at hole pose `base_t_hole` would record.
    pub fn observe(
        &self,
        base_t_hole: &Pose6,
        n: usize,
        depth_m: [f64; 2],
        noise: (f64, f64),
        seed: u64,
    ) -> Vec<Pose6> {
        let (noise_m, noise_rad) = noise;
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        rng.set_stream(u64::MAX);
        self.sample_contacts(n, depth_m, seed)
            .into_iter()
            .map(|mut p| {
                for (k, v) in p.0.iter_mut().enumerate() {
                    let half = if k < 3 { noise_m } else { noise_rad };
                    if half > 0.0 {
                        *v += rng.random_range(-half..half);
                    }
                }
                base_t_hole.compose(&p)
            })
            .collect()
    }

    fn sample_one(&self, rng: &mut ChaCha8Rng, depth_m: [f64; 2]) -> Pose6 {
        let depth = rng.random_range(depth_m[0]..=depth_m[1]);
        let g = self.clearance_m / 2.0;
        // Directions in (x, y, roll, pitch, yaw), scaled so each axis reaches contact at s ~ 1.
        let extent = [g, g, g / depth, g / depth, g / self.half_width_m];
        let dir: [f64; 5] = std::array::from_fn(|k| {
            let z: f64 = StandardNormal.sample(&mut *rng);
            extent[k] * z
        });
        let pose = |s: f64| {
            Pose6([
                s * dir[0],
                s * dir[1],
                -depth,
                s * dir[2],
                s * dir[3],
                s * dir[4],
            ])
        };
        pose(
            contact_along(|s| self.margin(&pose(s)))
                .expect("turning or shifting a peg far enough always meets a cavity wall"),
        )
    }
}

/// Vertices of a counter-clockwise polygon where it turns clockwise (interior angle > 180 deg).
fn reflex_vertices(poly: &[[f64; 2]]) -> Vec<[f64; 2]> {
    let n = poly.len();
    (0..n)
        .filter(|&i| {
            let (a, b, c) = (poly[(i + n - 1) % n], poly[i], poly[(i + 1) % n]);
            (b[0] - a[0]) * (c[1] - b[1]) - (b[1] - a[1]) * (c[0] - b[0]) < 0.0
        })
        .map(|i| poly[i])
        .collect()
}

/// Signed distance from `p` to a simple polygon's boundary: positive inside, negative outside.
fn signed_distance(p: &[f64; 2], poly: &[[f64; 2]]) -> f64 {
    let n = poly.len();
    let mut d2 = f64::INFINITY;
    let mut inside = false;
    for i in 0..n {
        let (a, b) = (poly[i], poly[(i + 1) % n]);
        let (ex, ey) = (b[0] - a[0], b[1] - a[1]);
        let (px, py) = (p[0] - a[0], p[1] - a[1]);
        let t = ((px * ex + py * ey) / (ex * ex + ey * ey)).clamp(0.0, 1.0);
        let (dx, dy) = (px - t * ex, py - t * ey);
        d2 = d2.min(dx * dx + dy * dy);
        if (a[1] > p[1]) != (b[1] > p[1]) && p[0] < a[0] + (p[1] - a[1]) * ex / ey {
            inside = !inside;
        }
    }
    if inside { d2.sqrt() } else { -d2.sqrt() }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn centred_peg_has_half_the_clearance() {
        for pair in [
            SyntheticPair::square(0.02, 0.5e-3),
            SyntheticPair::cross(0.03, 0.01, 0.5e-3),
        ] {
            let m = pair.margin(&Pose6([0.0, 0.0, -0.005, 0.0, 0.0, 0.0]));
            assert!((m - 0.25e-3).abs() < 1e-12, "{}: {m}", pair.name);
            let shifted = pair.margin(&Pose6([0.1e-3, 0.0, -0.005, 0.0, 0.0, 0.0]));
            assert!(
                (shifted - 0.15e-3).abs() < 1e-12,
                "{}: {shifted}",
                pair.name
            );
        }
    }

    #[test]
    fn sampled_poses_are_in_contact() {
        let pair = SyntheticPair::cross(0.03, 0.01, 0.5e-3);
        let pts = pair.sample_contacts(200, [0.002, 0.008], 3);
        for p in &pts {
            assert!(pair.margin(p).abs() < 1e-11, "{p:?}");
            assert!((-0.008..=-0.002).contains(&p.0[2]));
        }
        assert_eq!(pts, pair.sample_contacts(200, [0.002, 0.008], 3));
    }

    #[test]
    fn yaw_is_limited_by_the_arm_tips() {
        // An arm tip corner (15, 5) mm turned by 10 mrad rises 0.15 mm: free (gap 0.25 mm);
        // by 20 mrad it rises 0.30 mm: into the wall.
        let cross = SyntheticPair::cross(0.03, 0.01, 0.5e-3);
        let small = cross.margin(&Pose6([0.0, 0.0, -0.005, 0.0, 0.0, 0.01]));
        let large = cross.margin(&Pose6([0.0, 0.0, -0.005, 0.0, 0.0, 0.02]));
        assert!(small > 0.0 && large < 0.0, "{small} {large}");
    }
}
