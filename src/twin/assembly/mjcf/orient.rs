//! Where MJCF places an element: `pos` and one orientation of `quat` (w x y z), `axisangle`,
//! `xyaxes`, `zaxis` or `euler` (in the `<compiler>`'s `angle` unit and `eulerseq`), as MuJoCo's
//! compiler turns each into a rotation; and a geom's `fromto`.

use super::defaults::{Attrs, ORIENTATIONS};
use nalgebra::{Isometry3, Matrix3, Quaternion, Rotation3, Translation3, UnitQuaternion, Vector3};

/// Below this length a direction is refused as none (MuJoCo's mjEPS).
const MIN_AXIS: f64 = 1e-14;

/// How the model writes angles (`<compiler angle eulerseq>`).
#[derive(Clone, Debug)]
pub struct Angles {
    pub degrees: bool,
    /// `eulerseq`: three of x, y, z (about the moving axes) or X, Y, Z (about the fixed ones).
    pub sequence: String,
}

impl Angles {
    /// MuJoCo's defaults: degrees, `xyz`.
    pub fn read(compiler: &Attrs) -> Result<Angles, String> {
        let degrees = match compiler.get("angle").unwrap_or("degree") {
            "degree" => true,
            "radian" => false,
            _ => return Err(compiler.fail("angle", "expected degree or radian")),
        };
        let sequence = compiler.get("eulerseq").unwrap_or("xyz").to_string();
        let valid = sequence.len() == 3
            && (sequence.chars().all(|c| "xyz".contains(c))
                || sequence.chars().all(|c| "XYZ".contains(c)));
        if !valid {
            return Err(compiler.fail("eulerseq", "expected three of xyz or XYZ"));
        }
        Ok(Angles { degrees, sequence })
    }

    fn radians(&self, angle: f64) -> f64 {
        if self.degrees {
            angle.to_radians()
        } else {
            angle
        }
    }
}

/// The numbers of attribute `name`, if given.
pub fn numbers(attrs: &Attrs, name: &str) -> Result<Option<Vec<f64>>, String> {
    let Some(text) = attrs.get(name) else {
        return Ok(None);
    };
    text.split_whitespace()
        .map(|t| {
            t.parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| attrs.fail(name, format!("'{t}' is not a number")))
        })
        .collect::<Result<Vec<_>, _>>()
        .map(Some)
}

/// Attribute `name` as exactly `N` numbers, if given.
pub fn fixed<const N: usize>(attrs: &Attrs, name: &str) -> Result<Option<[f64; N]>, String> {
    match numbers(attrs, name)? {
        None => Ok(None),
        Some(v) => v
            .try_into()
            .map(Some)
            .map_err(|_| attrs.fail(name, format!("expected {N} numbers"))),
    }
}

/// The element's pose: `pos` and its orientation.
pub fn pose(attrs: &Attrs, angles: &Angles) -> Result<Isometry3<f64>, String> {
    let pos = fixed::<3>(attrs, "pos")?.unwrap_or([0.0; 3]);
    Ok(Isometry3::from_parts(
        Translation3::new(pos[0], pos[1], pos[2]),
        orientation(attrs, angles)?,
    ))
}

/// The rotation of the element's one orientation attribute (identity when it has none).
pub fn orientation(attrs: &Attrs, angles: &Angles) -> Result<UnitQuaternion<f64>, String> {
    let given: Vec<&str> = ORIENTATIONS
        .into_iter()
        .filter(|k| attrs.get(k).is_some())
        .collect();
    let Some(&which) = given.first() else {
        return Ok(UnitQuaternion::identity());
    };
    if given.len() > 1 {
        return Err(format!(
            "{}: {} given together: give one orientation",
            attrs.what,
            given.join(" and ")
        ));
    }
    let fail = |msg: &str| attrs.fail(which, msg);
    match which {
        "quat" => {
            let [w, x, y, z] = fixed::<4>(attrs, which)?.expect("given");
            let q = Quaternion::new(w, x, y, z);
            if q.norm() < MIN_AXIS {
                return Err(fail("expected four numbers w x y z, not all 0"));
            }
            Ok(UnitQuaternion::new_normalize(q))
        }
        "axisangle" => {
            let [x, y, z, a] = fixed::<4>(attrs, which)?.expect("given");
            let axis = unit(Vector3::new(x, y, z)).ok_or_else(|| fail("the axis is 0"))?;
            Ok(UnitQuaternion::from_axis_angle(&axis, angles.radians(a)))
        }
        "xyaxes" => {
            let v = fixed::<6>(attrs, which)?.expect("given");
            xy_axes(
                Vector3::new(v[0], v[1], v[2]),
                Vector3::new(v[3], v[4], v[5]),
            )
            .ok_or_else(|| fail("the axes are 0 or parallel"))
        }
        "zaxis" => {
            let [x, y, z] = fixed::<3>(attrs, which)?.expect("given");
            z_to(&Vector3::new(x, y, z)).ok_or_else(|| fail("the axis is 0"))
        }
        _ => {
            let e = fixed::<3>(attrs, which)?.expect("given");
            Ok(euler(e, angles))
        }
    }
}

fn unit(v: Vector3<f64>) -> Option<nalgebra::Unit<Vector3<f64>>> {
    nalgebra::Unit::try_new(v, MIN_AXIS)
}

/// `xyaxes`: x as given, y made orthogonal to it, z = x cross y.
fn xy_axes(x: Vector3<f64>, y: Vector3<f64>) -> Option<UnitQuaternion<f64>> {
    let x = unit(x)?.into_inner();
    let y = unit(y - x * x.dot(&y))?.into_inner();
    let z = x.cross(&y).normalize();
    let m = Matrix3::from_columns(&[x, y, z]);
    Some(UnitQuaternion::from_rotation_matrix(
        &Rotation3::from_matrix_unchecked(m),
    ))
}

/// The shortest rotation that turns z onto `v` (MuJoCo's `mju_quatZ2Vec`: a half turn about x
/// for -z).
pub fn z_to(v: &Vector3<f64>) -> Option<UnitQuaternion<f64>> {
    let v = unit(*v)?.into_inner();
    let z = Vector3::z();
    let axis = z.cross(&v);
    let sin = axis.norm();
    if sin < 1e-15 {
        return Some(if v.z < 0.0 {
            UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI)
        } else {
            UnitQuaternion::identity()
        });
    }
    let angle = sin.atan2(v.dot(&z));
    Some(UnitQuaternion::from_axis_angle(
        &nalgebra::Unit::new_unchecked(axis / sin),
        angle,
    ))
}

/// MuJoCo's Euler angles: three rotations about the axes of `eulerseq`, lower case about the
/// moving axes, upper case about the fixed ones.
fn euler(e: [f64; 3], angles: &Angles) -> UnitQuaternion<f64> {
    let mut q = UnitQuaternion::identity();
    for (k, axis) in angles.sequence.chars().enumerate() {
        let unit = match axis.to_ascii_lowercase() {
            'x' => Vector3::x_axis(),
            'y' => Vector3::y_axis(),
            _ => Vector3::z_axis(),
        };
        let r = UnitQuaternion::from_axis_angle(&unit, angles.radians(e[k]));
        q = if axis.is_ascii_lowercase() {
            q * r
        } else {
            r * q
        };
    }
    q
}

/// A geom's `fromto` (x1 y1 z1 x2 y2 z2): its pose (centred between the points, z along the
/// segment from the second point to the first, as MuJoCo's compiler sets it) and its half
/// length.
pub fn from_to(attrs: &Attrs) -> Result<Option<(Isometry3<f64>, f64)>, String> {
    let Some(v) = fixed::<6>(attrs, "fromto")? else {
        return Ok(None);
    };
    let from = Vector3::new(v[0], v[1], v[2]);
    let to = Vector3::new(v[3], v[4], v[5]);
    let rotation =
        z_to(&(from - to)).ok_or_else(|| attrs.fail("fromto", "the two points are the same"))?;
    let centre = (from + to) / 2.0;
    Ok(Some((
        Isometry3::from_parts(Translation3::from(centre), rotation),
        (to - from).norm() / 2.0,
    )))
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
        let q = euler([90.0, 0.0, 90.0], &intrinsic);
        // R = Rx(90) Rz(90): x turns to y, then y to z.
        let x = q * Vector3::x();
        assert!((x - Vector3::new(0.0, 0.0, 1.0)).norm() < 1e-12, "{x}");
        let extrinsic = Angles {
            degrees: false,
            sequence: "XYZ".into(),
        };
        let q = euler([std::f64::consts::FRAC_PI_2, 0.0, 0.0], &extrinsic);
        assert!((q * Vector3::y() - Vector3::z()).norm() < 1e-12);
    }

    #[test]
    fn z_axes_turn_z_onto_them() {
        for v in [
            Vector3::new(1.0, 2.0, 3.0),
            Vector3::new(0.0, 0.0, -2.0),
            Vector3::new(0.0, 0.0, 5.0),
            Vector3::new(-1.0, 0.0, 0.0),
        ] {
            let q = z_to(&v).unwrap();
            assert!((q * Vector3::z() - v.normalize()).norm() < 1e-12, "{v}");
        }
        assert!(z_to(&Vector3::zeros()).is_none());
        let q = xy_axes(Vector3::new(0.0, 2.0, 0.0), Vector3::new(-1.0, 1.0, 0.0)).unwrap();
        assert!((q * Vector3::x() - Vector3::y()).norm() < 1e-12);
        assert!((q * Vector3::y() + Vector3::x()).norm() < 1e-12);
    }
}
