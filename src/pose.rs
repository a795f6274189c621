//! Poses as 6-vectors, the 6-D metric between them, and the SE(3) tools registration needs.
//!
//! A [`Pose6`] is `[x, y, z, roll, pitch, yaw]` in metres and radians with
//! R = Rz(yaw) Ry(pitch) Rx(roll) (ROS REP-103, nalgebra's `from_euler_angles`). Arithmetic on poses
//! goes through [`Iso`] (rigid transforms); the 6-vector is the exchange format (CSV files, command
//! line) and the coordinate space in which the contact manifold lives (paper Section IV-D).
//!
//! Distances in that 6-D space need a common unit for metres and radians: [`PoseMetric`] maps a pose
//! to *scaled coordinates* in millimetre-equivalents, positions in mm and angles in degrees times
//! `mm_per_deg` (default 1: one millimetre counts like one degree, as the paper's authors did).

use crate::error::{Error, Result};
use nalgebra::{Isometry3, Matrix3, Rotation3, Translation3, UnitQuaternion, Vector3, Vector6};
use serde::{Deserialize, Serialize};

/// A rigid transform in double precision (the registration works in f64 throughout).
pub type Iso = Isometry3<f64>;

/// A pose `[x, y, z, roll, pitch, yaw]` in metres and radians.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Pose6(pub [f64; 6]);

impl Pose6 {
    /// The identity pose.
    pub const IDENTITY: Pose6 = Pose6([0.0; 6]);

    /// The rigid transform of this pose.
    pub fn to_iso(&self) -> Iso {
        let [x, y, z, roll, pitch, yaw] = self.0;
        Isometry3::from_parts(
            Translation3::new(x, y, z),
            UnitQuaternion::from_euler_angles(roll, pitch, yaw),
        )
    }

    /// The pose of a rigid transform (angles as nalgebra's `euler_angles`: roll and yaw in
    /// (-pi, pi], pitch in [-pi/2, pi/2]).
    pub fn from_iso(t: &Iso) -> Pose6 {
        let (roll, pitch, yaw) = t.rotation.euler_angles();
        let p = t.translation.vector;
        Pose6([p.x, p.y, p.z, roll, pitch, yaw])
    }

    /// `self ⊗ other`.
    pub fn compose(&self, other: &Pose6) -> Pose6 {
        Pose6::from_iso(&(self.to_iso() * other.to_iso()))
    }

    /// `self⁻¹`.
    pub fn inverse(&self) -> Pose6 {
        Pose6::from_iso(&self.to_iso().inverse())
    }

    /// The pose of `other` seen from `self`: `self⁻¹ ⊗ other`.
    pub fn relative(&self, other: &Pose6) -> Pose6 {
        Pose6::from_iso(&(self.to_iso().inverse() * other.to_iso()))
    }

    /// Whether all six numbers are finite.
    pub fn is_finite(&self) -> bool {
        self.0.iter().all(|v| v.is_finite())
    }

    /// Refuses a pose that no robot cell holds: a coordinate beyond [`MAX_COORDINATE_M`] or an
    /// angle beyond [`MAX_ANGLE_RAD`] (non-finite included) is a unit error or corrupt data,
    /// named with `what` and the axis.
    pub fn ensure_plausible(&self, what: &str) -> Result<()> {
        const AXES: [&str; 6] = ["x", "y", "z", "roll", "pitch", "yaw"];
        for (i, v) in self.0.iter().enumerate() {
            let (limit, unit) = if i < 3 {
                (MAX_COORDINATE_M, "m")
            } else {
                (MAX_ANGLE_RAD, "rad")
            };
            if !(v.is_finite() && v.abs() <= limit) {
                let shown = if v.abs() < 1e6 {
                    v.to_string()
                } else {
                    format!("{v:e}")
                };
                return Err(Error::Input(format!(
                    "{what}: {} = {shown} {unit}: expected a finite value within +-{limit:.4} {unit} (metres and radians)",
                    AXES[i]
                )));
            }
        }
        Ok(())
    }

    /// Position in millimetres and angles in degrees, for people to read.
    pub fn to_mm_deg(&self) -> [f64; 6] {
        let [x, y, z, r, p, w] = self.0;
        [
            x * 1e3,
            y * 1e3,
            z * 1e3,
            r.to_degrees(),
            p.to_degrees(),
            w.to_degrees(),
        ]
    }
}

/// Largest plausible coordinate of a pose in a robot cell, m: beyond it a value is a unit error
/// (millimetres read as metres) or corrupt data.
pub const MAX_COORDINATE_M: f64 = 10.0;
/// Largest plausible angle of a roll-pitch-yaw pose, rad (writers keep angles within +-pi).
pub const MAX_ANGLE_RAD: f64 = 2.0 * std::f64::consts::PI;
/// The range of [`PoseMetric::mm_per_deg`] that weighs rotation and translation sensibly.
pub const MM_PER_DEG_RANGE: (f64, f64) = (1e-3, 1e3);

/// The metric of the 6-D pose space: how many millimetres one degree counts for.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct PoseMetric {
    /// One degree of rotation counts like this many millimetres of translation.
    pub mm_per_deg: f64,
}

impl Default for PoseMetric {
    fn default() -> Self {
        PoseMetric { mm_per_deg: 1.0 }
    }
}

impl PoseMetric {
    /// Refuses a weight outside [`MM_PER_DEG_RANGE`] (zero or negative weights make every pose
    /// look alike; huge ones overflow the search).
    pub fn ensure_valid(&self) -> Result<()> {
        let (lo, hi) = MM_PER_DEG_RANGE;
        if !(self.mm_per_deg >= lo && self.mm_per_deg <= hi) {
            return Err(Error::Input(format!(
                "mm_per_deg {:?}: expected {lo} to {hi} (millimetres that one degree counts for)",
                self.mm_per_deg
            )));
        }
        Ok(())
    }

    /// Millimetre-equivalents per radian.
    fn mm_per_rad(&self) -> f64 {
        self.mm_per_deg * 180.0 / std::f64::consts::PI
    }

    /// Per-coordinate factors from SI (m, rad) to scaled coordinates (mm-equivalents).
    pub fn factors(&self) -> [f64; 6] {
        let a = self.mm_per_rad();
        [1e3, 1e3, 1e3, a, a, a]
    }

    /// Scaled coordinates (mm-equivalents) of a pose.
    pub fn scaled(&self, p: &Pose6) -> [f64; 6] {
        let f = self.factors();
        std::array::from_fn(|i| p.0[i] * f[i])
    }

    /// The pose of scaled coordinates.
    pub fn unscaled(&self, s: &[f64; 6]) -> Pose6 {
        let f = self.factors();
        Pose6(std::array::from_fn(|i| s[i] / f[i]))
    }

    /// The scaled length of a twist `(rho [m], phi [rad])`.
    pub fn twist_norm(&self, xi: &Vector6<f64>) -> f64 {
        let (l, a) = (1e3, self.mm_per_rad());
        ((l * xi.fixed_rows::<3>(0).norm()).powi(2) + (a * xi.fixed_rows::<3>(3).norm()).powi(2))
            .sqrt()
    }
}

fn skew(v: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::new(0.0, -v.z, v.y, v.z, 0.0, -v.x, -v.y, v.x, 0.0)
}

/// Exponential map of SE(3): twist `(rho, phi)` (m, rad) to a rigid transform.
pub fn se3_exp(xi: &Vector6<f64>) -> Iso {
    let rho = xi.fixed_rows::<3>(0).into_owned();
    let phi = xi.fixed_rows::<3>(3).into_owned();
    let theta = phi.norm();
    let w = skew(&phi);
    let (b, c) = if theta < 1e-6 {
        (
            0.5 - theta * theta / 24.0,
            1.0 / 6.0 - theta * theta / 120.0,
        )
    } else {
        let t2 = theta * theta;
        (
            (1.0 - theta.cos()) / t2,
            (theta - theta.sin()) / (t2 * theta),
        )
    };
    let v = Matrix3::identity() + w * b + w * w * c;
    Isometry3::from_parts(
        Translation3::from(v * rho),
        UnitQuaternion::from_scaled_axis(phi),
    )
}

/// Logarithm of SE(3): the twist `(rho, phi)` (m, rad) with `se3_exp(twist) == t`.
pub fn se3_log(t: &Iso) -> Vector6<f64> {
    let phi = t.rotation.scaled_axis();
    let theta = phi.norm();
    let w = skew(&phi);
    let d = if theta < 1e-6 {
        1.0 / 12.0 + theta * theta / 720.0
    } else {
        (1.0 - theta * theta.sin() / (2.0 * (1.0 - theta.cos()))) / (theta * theta)
    };
    let v_inv = Matrix3::identity() - w * 0.5 + w * w * d;
    let rho = v_inv * t.translation.vector;
    Vector6::new(rho.x, rho.y, rho.z, phi.x, phi.y, phi.z)
}

/// Iterations and tolerance (scaled twist norm, mm-equivalents: 1e-9 is a picometre) of
/// [`se3_mean`].
const MEAN_MAX_ITERATIONS: usize = 50;
const MEAN_TOLERANCE: f64 = 1e-9;

/// The SE(3) mean of rigid transforms, every transform weighted equally.
///
/// The iterative Lie-algebra (Karcher) mean: start at the first transform, average the twists
/// `log(mean⁻¹ ⊗ T_i)` arithmetically, move the mean by `exp` of that average, repeat until the
/// average twist vanishes. Twists are averaged in SI units; the stopping test uses `metric`.
/// Returns the identity for an empty slice.
pub fn se3_mean(transforms: &[Iso], metric: &PoseMetric) -> Iso {
    let Some(first) = transforms.first() else {
        return Iso::identity();
    };
    let mut mean = *first;
    for _ in 0..MEAN_MAX_ITERATIONS {
        let inv = mean.inverse();
        let sum: Vector6<f64> = transforms.iter().map(|t| se3_log(&(inv * t))).sum();
        let step = sum / transforms.len() as f64;
        mean *= se3_exp(&step);
        if metric.twist_norm(&step) < MEAN_TOLERANCE {
            break;
        }
    }
    mean
}

/// The matrix that maps roll-pitch-yaw rates to the angular velocity they cause, expressed in the
/// fixed (parent) frame: `omega = E(rpy) * d(rpy)/dt` for R = Rz(yaw) Ry(pitch) Rx(roll).
pub fn rpy_rate_to_angular_velocity(rpy: &Vector3<f64>) -> Matrix3<f64> {
    let (p, y) = (rpy.y, rpy.z);
    let (sp, cp, sy, cy) = (p.sin(), p.cos(), y.sin(), y.cos());
    Matrix3::new(cy * cp, -sy, 0.0, sy * cp, cy, 0.0, -sp, 0.0, 1.0)
}

/// The rotation of roll, pitch, yaw (R = Rz(yaw) Ry(pitch) Rx(roll)).
pub fn rotation_rpy(roll: f64, pitch: f64, yaw: f64) -> Rotation3<f64> {
    Rotation3::from_euler_angles(roll, pitch, yaw)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pose(v: [f64; 6]) -> Iso {
        Pose6(v).to_iso()
    }

    #[test]
    fn rpy_convention_is_rz_ry_rx() {
        let (r, p, y) = (0.3, -0.2, 1.1);
        let expected = Rotation3::from_axis_angle(&Vector3::z_axis(), y)
            * Rotation3::from_axis_angle(&Vector3::y_axis(), p)
            * Rotation3::from_axis_angle(&Vector3::x_axis(), r);
        let got = rotation_rpy(r, p, y);
        assert!((got.matrix() - expected.matrix()).norm() < 1e-12);
        let back = Pose6::from_iso(&pose([0.1, 0.2, 0.3, r, p, y]));
        for (a, b) in back.0.iter().zip([0.1, 0.2, 0.3, r, p, y]) {
            assert!((a - b).abs() < 1e-12);
        }
    }

    #[test]
    fn compose_inverse_relative() {
        let a = Pose6([0.01, -0.02, 0.3, 0.1, 0.2, -0.3]);
        let b = Pose6([-0.004, 0.05, -0.01, -0.05, 0.02, 0.4]);
        let ab = a.compose(&b);
        let back = a.relative(&ab);
        for (u, v) in back.0.iter().zip(b.0) {
            assert!((u - v).abs() < 1e-12);
        }
        let id = a.compose(&a.inverse());
        assert!(id.0.iter().all(|v| v.abs() < 1e-12));
    }

    #[test]
    fn exp_log_round_trip() {
        for xi in [
            Vector6::new(0.01, -0.02, 0.03, 0.4, -0.5, 0.6),
            Vector6::new(1e-4, 2e-4, -3e-4, 1e-8, -2e-8, 3e-9),
            Vector6::new(0.0, 0.0, 0.0, 0.0, 0.0, 0.0),
        ] {
            let back = se3_log(&se3_exp(&xi));
            assert!((back - xi).norm() < 1e-12, "{xi} -> {back}");
        }
    }

    #[test]
    fn mean_of_symmetric_set_is_its_centre() {
        let centre = pose([0.1, 0.2, -0.1, 0.05, -0.02, 0.3]);
        let offsets = [
            Vector6::new(0.002, 0.0, 0.0, 0.0, 0.03, 0.0),
            Vector6::new(-0.002, 0.0, 0.0, 0.0, -0.03, 0.0),
            Vector6::new(0.0, 0.001, 0.0, 0.02, 0.0, 0.0),
            Vector6::new(0.0, -0.001, 0.0, -0.02, 0.0, 0.0),
        ];
        let set: Vec<Iso> = offsets.iter().map(|o| centre * se3_exp(o)).collect();
        let mean = se3_mean(&set, &PoseMetric::default());
        assert!(se3_log(&(centre.inverse() * mean)).norm() < 1e-12);
    }

    #[test]
    fn rpy_rates_match_finite_differences() {
        let rpy = Vector3::new(0.2, -0.4, 0.7);
        let e = rpy_rate_to_angular_velocity(&rpy);
        let r0 = rotation_rpy(rpy.x, rpy.y, rpy.z);
        let h = 1e-7;
        for k in 0..3 {
            let mut q = rpy;
            q[k] += h;
            let r1 = rotation_rpy(q.x, q.y, q.z);
            // R1 R0ᵀ = exp([omega h]x): read omega from the skew part.
            let d = (r1 * r0.inverse()).into_inner();
            let omega = Vector3::new(
                d[(2, 1)] - d[(1, 2)],
                d[(0, 2)] - d[(2, 0)],
                d[(1, 0)] - d[(0, 1)],
            ) / (2.0 * h);
            assert!((omega - e.column(k)).norm() < 1e-6);
        }
    }
}
