//! The robot model against the facts sheet (docs/sources.md, 1 and 2): forward kinematics
//! test vectors (section 1.4) and the DH table (1.3), the Jacobian against finite differences,
//! gravity torques and effective masses (5.3), and the loader's rules and errors.

use nalgebra::{Isometry3, Matrix3, Translation3, UnitQuaternion, Vector3};
use pegtwin::twin::robot::urdf::{IIWA7_URDF, IIWA14_URDF, UR5E_URDF, load};
use pegtwin::twin::robot::{GRAVITY_UPRIGHT, RobotModel};
use std::f64::consts::{FRAC_PI_2, FRAC_PI_4, PI};
use std::path::Path;

fn iiwa14() -> RobotModel {
    load(Path::new(IIWA14_URDF), &[]).unwrap().model
}

fn iiwa7() -> RobotModel {
    load(Path::new(IIWA7_URDF), &[]).unwrap().model
}

/// Standard DH (facts sheet 1.3): a = 0, alpha as listed, theta = q, d per robot.
fn dh_flange(d: [f64; 7], q: &[f64]) -> Isometry3<f64> {
    let alpha = [
        -FRAC_PI_2, FRAC_PI_2, FRAC_PI_2, -FRAC_PI_2, -FRAC_PI_2, FRAC_PI_2, 0.0,
    ];
    let mut t = Isometry3::identity();
    for i in 0..7 {
        t =
            t * Isometry3::from_parts(
                Translation3::new(0.0, 0.0, d[i]),
                UnitQuaternion::from_axis_angle(&Vector3::z_axis(), q[i]),
            ) * Isometry3::from_parts(
                Translation3::identity(),
                UnitQuaternion::from_axis_angle(&Vector3::x_axis(), alpha[i]),
            );
    }
    t
}

const D14: [f64; 7] = [0.36, 0.0, 0.42, 0.0, 0.40, 0.0, 0.126];
const D7: [f64; 7] = [0.34, 0.0, 0.40, 0.0, 0.40, 0.0, 0.126];

fn random_qs(n: usize) -> Vec<Vec<f64>> {
    (0..n)
        .map(|k| {
            (0..7)
                .map(|i| 1.9 * ((k * 7 + i) as f64 * 0.618_034 * 2.0 * PI).sin())
                .collect()
        })
        .collect()
}

/// q, flange position (m), flange rotation (rows), as printed in the facts sheet.
type FkVector = ([f64; 7], [f64; 3], [[f64; 3]; 3]);

#[test]
#[allow(clippy::approx_constant)] // the sheet's printed five-decimal values, kept as printed
fn fk_matches_the_facts_sheet_test_vectors() {
    let robot = iiwa14();
    let cases: [FkVector; 4] = [
        (
            [0.0; 7],
            [0.0, 0.0, 1.306],
            [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
        ),
        (
            [0.0, FRAC_PI_4, 0.0, -FRAC_PI_2, 0.0, 0.0, 0.0],
            [0.66892, 0.0, 0.28505],
            [
                [-0.70711, 0.0, 0.70711],
                [0.0, 1.0, 0.0],
                [-0.70711, 0.0, -0.70711],
            ],
        ),
        (
            [0.0, FRAC_PI_4, 0.0, -FRAC_PI_2, 0.0, FRAC_PI_4, 0.0],
            [0.57983, 0.0, 0.24814],
            [[-1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, -1.0]],
        ),
        (
            [0.5, 0.5, 0.5, -1.0, 0.5, 0.5, 0.5],
            [0.45553, 0.52818, 0.74537],
            [
                [-0.92802, -0.22123, 0.29973],
                [0.22123, 0.32007, 0.9212],
                [-0.29973, 0.9212, -0.24809],
            ],
        ),
    ];
    for (q, p, r) in cases {
        let f = robot.flange_pose(&q);
        // The sheet prints 5 decimals: agreement to its rounding, and to 1e-9 with the DH table.
        let err = (f.translation.vector - Vector3::from(p)).amax();
        assert!(err <= 5e-6, "q {q:?}: p {:?}", f.translation);
        let m = f.rotation.to_rotation_matrix();
        for (i, row) in r.iter().enumerate() {
            for (j, v) in row.iter().enumerate() {
                assert!((m[(i, j)] - v).abs() <= 5e-5, "q {q:?}: R {m}");
            }
        }
        let dh = dh_flange(D14, &q);
        assert!((f.translation.vector - dh.translation.vector).norm() < 1e-9);
        assert!(f.rotation.angle_to(&dh.rotation) < 1e-9);
    }
}

#[test]
fn fk_of_both_arms_matches_the_dh_table_at_random_configurations() {
    for (robot, d) in [(iiwa14(), D14), (iiwa7(), D7)] {
        for q in random_qs(50) {
            let f = robot.flange_pose(&q);
            let dh = dh_flange(d, &q);
            assert!(
                (f.translation.vector - dh.translation.vector).norm() < 1e-6,
                "{} q {q:?}",
                robot.name
            );
            assert!(
                f.rotation.angle_to(&dh.rotation) < 1e-6,
                "{} q {q:?}",
                robot.name
            );
        }
    }
}

/// The UR5e's DH frames 1 to 6 by the maker's standard DH table (a, d, alpha; theta = q).
fn ur5e_dh_frames(q: &[f64]) -> Vec<Isometry3<f64>> {
    let a = [0.0, -0.425, -0.3922, 0.0, 0.0, 0.0];
    let d = [0.1625, 0.0, 0.0, 0.1333, 0.0997, 0.0996];
    let alpha = [FRAC_PI_2, 0.0, 0.0, FRAC_PI_2, -FRAC_PI_2, 0.0];
    let mut t = Isometry3::identity();
    (0..6)
        .map(|i| {
            t =
                t * Isometry3::from_parts(
                    Translation3::new(0.0, 0.0, d[i]),
                    UnitQuaternion::from_axis_angle(&Vector3::z_axis(), q[i]),
                ) * Isometry3::from_parts(
                    Translation3::new(a[i], 0.0, 0.0),
                    UnitQuaternion::from_axis_angle(&Vector3::x_axis(), alpha[i]),
                );
            t
        })
        .collect()
}

#[test]
fn the_ur5e_file_is_its_dh_table() {
    let robot = load(Path::new(UR5E_URDF), &[]).unwrap().model;
    assert_eq!((robot.dof(), robot.flange_name.as_str()), (6, "tool0"));
    let mass: f64 = robot.links.iter().map(|l| l.inertial.mass_kg).sum();
    assert!((mass - 17.7).abs() < 0.01, "{mass} kg");
    // The published centres of mass, in DH frame i.
    let coms = [
        [0.0, -0.02561, 0.00193],
        [0.2125, 0.0, 0.11336],
        [0.15, 0.0, 0.0265],
        [0.0, -0.0018, 0.01634],
        [0.0, 0.0018, 0.01634],
        [0.0, 0.0, -0.001159],
    ];
    for q in random_qs(50) {
        let q = &q[..6];
        let dh = ur5e_dh_frames(q);
        let f = robot.flange_pose(q);
        assert!(
            (f.translation.vector - dh[5].translation.vector).norm() < 1e-9,
            "q {q:?}"
        );
        assert!(f.rotation.angle_to(&dh[5].rotation) < 1e-9, "q {q:?}");
        let k = robot.kinematics(q);
        for (i, c) in coms.iter().enumerate() {
            let com = k.frames[i] * robot.links[i].inertial.com;
            let published = dh[i] * nalgebra::Point3::from(*c);
            assert!((com - published).norm() < 1e-9, "link {} q {q:?}", i + 1);
        }
    }
}

#[test]
fn jacobian_matches_finite_differences() {
    let robot = iiwa14();
    for q in random_qs(20) {
        let k = robot.kinematics(&q);
        let jac = robot.tcp_jacobian(&k);
        let f0 = robot.flange_pose(&q);
        let h = 1e-6;
        for i in 0..7 {
            let mut qp = q.clone();
            qp[i] += h;
            let f1 = robot.flange_pose(&qp);
            let v = (f1.translation.vector - f0.translation.vector) / h;
            let w = (f1.rotation * f0.rotation.inverse()).scaled_axis() / h;
            for r in 0..3 {
                assert!(
                    (jac[(r, i)] - v[r]).abs() < 1e-5,
                    "v col {i}: {} vs {}",
                    jac[(r, i)],
                    v[r]
                );
                assert!((jac[(r + 3, i)] - w[r]).abs() < 1e-5, "w col {i}");
            }
        }
    }
}

#[test]
fn inertial_set_is_the_cad_set() {
    let robot = iiwa14();
    assert!(
        (robot.total_mass_kg() - 29.9).abs() < 1e-5,
        "{}",
        robot.total_mass_kg()
    );
    assert_eq!(robot.dof(), 7);
    let limits: Vec<f64> = robot.joints.iter().map(|j| j.effort_limit).collect();
    assert_eq!(limits, [320.0, 320.0, 176.0, 176.0, 110.0, 40.0, 40.0]);
    assert_eq!(robot.flange_name, "iiwa_link_ee_kuka");
}

#[test]
fn gravity_torques_match_the_facts_sheet() {
    // Section 5.3, CAD set, q = home: 0, -49.3, -0.3, 13.4, -0.3, -0.3, 0 N m (printed to 0.1).
    let robot = iiwa14();
    let q = [0.0, FRAC_PI_4, 0.0, -FRAC_PI_2, 0.0, 0.0, 0.0];
    let g = robot.gravity_torques(&robot.kinematics(&q), &GRAVITY_UPRIGHT);
    let expected = [0.0, -49.3, -0.3, 13.4, -0.3, -0.3, 0.0];
    for i in 0..7 {
        assert!(
            (g[i] - expected[i]).abs() <= 0.051,
            "A{}: {} vs {}",
            i + 1,
            g[i],
            expected[i]
        );
    }
}

#[test]
fn gravity_torques_are_the_gradient_of_potential_energy() {
    let robot = iiwa14();
    let potential = |q: &[f64]| -> f64 {
        let k = robot.kinematics(q);
        robot
            .links
            .iter()
            .zip(&k.frames)
            .map(|(l, f)| l.inertial.mass_kg * 9.81 * (f * l.inertial.com).z)
            .sum()
    };
    for q in random_qs(10) {
        let g = robot.gravity_torques(&robot.kinematics(&q), &GRAVITY_UPRIGHT);
        for i in 0..7 {
            let mut qp = q.clone();
            let mut qm = q.clone();
            qp[i] += 1e-6;
            qm[i] -= 1e-6;
            let fd = (potential(&qp) - potential(&qm)) / 2e-6;
            assert!((g[i] - fd).abs() < 1e-4, "A{}: {} vs {fd}", i + 1, g[i]);
        }
    }
}

#[test]
fn effective_masses_match_the_facts_sheet() {
    // Section 5.3, CAD set, no rotor inertia: m_eff x/y/z at home 6.02/2.31/6.02 kg, the inverse
    // of the translational block of J M^-1 J^T at the flange.
    let mut robot = iiwa14();
    robot.armature = vec![0.0; 7];
    let q = [0.0, FRAC_PI_4, 0.0, -FRAC_PI_2, 0.0, 0.0, 0.0];
    let k = robot.kinematics(&q);
    let jac = robot.tcp_jacobian(&k);
    let minv = robot.mass_matrix(&k).try_inverse().unwrap();
    let inv = (&jac * minv * jac.transpose())
        .fixed_view::<3, 3>(0, 0)
        .into_owned();
    let lambda: Matrix3<f64> = inv.try_inverse().unwrap();
    for (i, m) in [6.02, 2.31, 6.02].iter().enumerate() {
        assert!(
            (lambda[(i, i)] - m).abs() <= 0.006,
            "axis {i}: {}",
            lambda[(i, i)]
        );
    }
}

#[test]
fn mass_matrix_is_symmetric_positive_definite_and_includes_rotor_inertia() {
    let robot = iiwa14();
    for q in random_qs(5) {
        let k = robot.kinematics(&q);
        let m = robot.mass_matrix(&k);
        assert!((&m - m.transpose()).amax() < 1e-12);
        assert!(m.clone().cholesky().is_some());
        let mut bare = robot.clone();
        bare.armature = vec![0.0; 7];
        let diff = m - bare.mass_matrix(&k);
        for i in 0..7 {
            assert!((diff[(i, i)] - robot.armature[i]).abs() < 1e-12);
        }
    }
}

#[test]
fn q_is_checked_for_length_and_limits() {
    let robot = iiwa14();
    let e = robot.check_q(&[0.0; 6]).unwrap_err().to_string();
    assert!(e.contains("6 values") && e.contains("7 joints"), "{e}");
    let e = robot
        .check_q(&[0.0, 2.2, 0.0, 0.0, 0.0, 0.0, 0.0])
        .unwrap_err()
        .to_string();
    assert!(e.contains("iiwa_joint_2") && e.contains("2.2"), "{e}");
    robot.check_q(&[0.0; 7]).unwrap();
}

const TWO_LINK: &str = r#"<?xml version="1.0"?>
<robot name="two">
  <link name="base"/>
  <link name="a"><inertial><mass value="1"/><inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial>COLLISION</link>
  <link name="tip"/>
  <joint name="j1" type="revolute"><parent link="base"/><child link="a"/><axis xyz="0 0 1"/>
    <limit lower="-1" upper="1" effort="10" velocity="1"/></joint>
  <joint name="fix" type="fixed"><parent link="a"/><child link="tip"/><origin xyz="0 0 0.5"/></joint>
  EXTRA
</robot>"#;

fn write_urdf(dir: &Path, collision: &str, extra: &str) -> std::path::PathBuf {
    let path = dir.join("robot.urdf");
    std::fs::write(
        &path,
        TWO_LINK
            .replace("COLLISION", collision)
            .replace("EXTRA", extra),
    )
    .unwrap();
    path
}

const TETRA_STL: &str = "solid t
facet normal 0 0 -1
outer loop
vertex 0 0 0
vertex 0 1 0
vertex 1 0 0
endloop
endfacet
facet normal 0 -1 0
outer loop
vertex 0 0 0
vertex 1 0 0
vertex 0 0 1
endloop
endfacet
facet normal -1 0 0
outer loop
vertex 0 0 0
vertex 0 0 1
vertex 0 1 0
endloop
endfacet
facet normal 1 1 1
outer loop
vertex 1 0 0
vertex 0 1 0
vertex 0 0 1
endloop
endfacet
endsolid t
";

#[test]
fn any_serial_chain_loads_with_package_meshes_as_convex_hulls() {
    let dir = tempfile::tempdir().unwrap();
    let pkg = dir.path().join("share").join("my_robot").join("meshes");
    std::fs::create_dir_all(&pkg).unwrap();
    std::fs::write(pkg.join("a.stl"), TETRA_STL).unwrap();
    let collision = r#"<collision><geometry><mesh filename="package://my_robot/meshes/a.stl" scale="0.1 0.1 0.1"/></geometry></collision>
        <visual><geometry><mesh filename="package://my_robot/meshes/missing.dae"/></geometry></visual>"#;
    let path = write_urdf(dir.path(), collision, "");
    let loaded = load(&path, &[dir.path().join("share")]).unwrap();
    let m = &loaded.model;
    assert_eq!(m.dof(), 1);
    assert_eq!(m.flange_name, "tip");
    assert!((m.flange_pose(&[0.3]).translation.vector.z - 0.5).abs() < 1e-12);
    match &m.links[0].collision[0].shape {
        pegtwin::twin::robot::Shape::ConvexHull { points } => {
            assert!(points.iter().all(|p| p.coords.amax() <= 0.1 + 1e-12));
        }
        other => panic!("expected a convex hull, got {other:?}"),
    }
    assert_eq!(loaded.warnings.len(), 1, "{:?}", loaded.warnings);
    assert!(loaded.warnings[0].contains("missing.dae"));
}

#[test]
fn loader_errors_name_the_file_element_and_reason() {
    let dir = tempfile::tempdir().unwrap();
    let cases: [(&str, &str, &[&str]); 5] = [
        (
            r#"<collision><geometry><mesh filename="package://nowhere/a.stl"/></geometry></collision>"#,
            "",
            &[
                "<link name=\"a\">",
                "collision mesh 'package://nowhere/a.stl' not found",
            ],
        ),
        (
            "",
            r#"<link name="b"/><joint name="j2" type="revolute"><parent link="a"/><child link="b"/><axis xyz="1 0 0"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint>"#,
            &["link 'a' has 2 child joints", "fix", "j2", "serial chains"],
        ),
        (
            "",
            r#"<joint name="bad" type="fixed"><parent link="tip"/><child link="ghost"/></joint>"#,
            &["<joint name=\"bad\">", "child link 'ghost'"],
        ),
        (
            "",
            r#"<link name="c"/><joint name="f" type="floating"><parent link="tip"/><child link="c"/></joint>"#,
            &["<joint name=\"f\">", "Floating", "not supported"],
        ),
        ("", "<link name=\"a\"/>", &["same name"]),
    ];
    for (collision, extra, needles) in cases {
        let path = write_urdf(dir.path(), collision, extra);
        let e = load(&path, &[]).err().expect("must fail").to_string();
        assert!(e.contains("robot.urdf"), "{e}");
        for n in needles {
            assert!(e.contains(n), "{e} should contain {n}");
        }
    }
    let path = dir.path().join("fixed_only.urdf");
    std::fs::write(&path, r#"<robot name="r"><link name="a"/><link name="b"/><joint name="f" type="fixed"><parent link="a"/><child link="b"/></joint></robot>"#).unwrap();
    let e = load(&path, &[]).err().unwrap().to_string();
    assert!(e.contains("no movable joint"), "{e}");
    std::fs::write(&path, "<robot name=\"r\"><link name=\"a\"></robot>").unwrap();
    let e = load(&path, &[]).err().unwrap().to_string();
    assert!(
        e.contains("fixed_only.urdf") && e.contains("not a valid URDF") && e.contains("1:"),
        "{e}"
    );
    let bad_limit = TWO_LINK
        .replace("COLLISION", "")
        .replace("EXTRA", "")
        .replace("lower=\"-1\"", "lower=\"x\"");
    std::fs::write(&path, bad_limit).unwrap();
    let e = load(&path, &[]).err().unwrap().to_string();
    assert!(
        e.contains("line 7")
            && e.contains("<limit lower=\"x\">")
            && e.contains("expected 1 number in"),
        "{e}"
    );
}

#[test]
fn the_embedded_iiwa14_is_the_shipped_file() {
    // `urdf::iiwa14()` reads the URDF compiled into the binary (a copied binary or the Python
    // package has no source tree); it must be the same robot as the file.
    let embedded = pegtwin::twin::robot::urdf::iiwa14().unwrap();
    let file = iiwa14();
    assert_eq!(embedded.dof(), file.dof());
    assert_eq!(embedded.total_mass_kg(), file.total_mass_kg());
    let q = [0.3, -0.5, 0.2, 1.1, -0.4, 0.7, 0.1];
    assert_eq!(embedded.tcp_pose(&q), file.tcp_pose(&q));
    assert_eq!(
        format!("{:?}", embedded.links),
        format!("{:?}", file.links),
        "links, inertials and limits"
    );
}
