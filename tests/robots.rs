//! Your own robot: an assembly file's `[robot]` (a built-in other than the iiwa 14, or a URDF with
//! its flange link and tool offset) holds the peg in every trial; bad robots are refused by field.

mod common;

use common::{pegtwin, stderr};
use pegtwin::method::config::Method;
use pegtwin::method::request::TrialRequest;
use pegtwin::twin::assembly::{PairSource, load};
use pegtwin::twin::real_cell::Profile;
use std::path::{Path, PathBuf};

/// An assembly of the built-in cross at 0.5 mm with `robot` as its `[robot]` section.
fn cross_with(dir: &Path, file: &str, robot: &str) -> PathBuf {
    let path = dir.join(file);
    let text = format!(
        "name = \"cross-arm\"\nclearance_mm = 0.5\n[peg]\nbuiltin = \"cross\"\n[hole]\n\
         builtin = \"cross\"\n{robot}"
    );
    std::fs::write(&path, text).unwrap();
    path
}

/// A serial arm of `n` revolute joints about z, each link `length_m` up from the last, its tip
/// link `tip`, and optionally a second branch at the base.
fn arm_urdf(n: usize, length_m: f64, branch: bool) -> String {
    let link = |name: &str| {
        format!(
            "<link name=\"{name}\"><inertial><origin xyz=\"0 0 0.05\"/><mass value=\"1\"/>\
             <inertia ixx=\"0.01\" ixy=\"0\" ixz=\"0\" iyy=\"0.01\" iyz=\"0\" izz=\"0.01\"/>\
             </inertial></link>\n"
        )
    };
    let mut text = String::from("<robot name=\"small\">\n");
    text += &link("l0");
    for i in 1..=n {
        text += &link(&format!("l{i}"));
        let axis = if i % 2 == 0 { "0 1 0" } else { "0 0 1" };
        text += &format!(
            "<joint name=\"j{i}\" type=\"revolute\"><parent link=\"l{}\"/><child link=\"l{i}\"/>\
             <origin xyz=\"0 0 {length_m}\"/><axis xyz=\"{axis}\"/>\
             <limit lower=\"-3\" upper=\"3\" effort=\"100\" velocity=\"2\"/></joint>\n",
            i - 1
        );
    }
    if branch {
        text += &link("side");
        text += "<joint name=\"js\" type=\"revolute\"><parent link=\"l0\"/><child link=\"side\"/>\
                 <axis xyz=\"0 0 1\"/><limit lower=\"-1\" upper=\"1\" effort=\"10\" velocity=\"1\"/>\
                 </joint>\n";
    }
    text + "</robot>\n"
}

/// A short direct trial of the assembly at `file` runs without a fault and pushes the peg from
/// its 3 mm start further in. On the ideal cell: this checks that the robot holds and drives
/// the peg where its section puts the hole, not the real cell's odds (on the real cell, seed 3
/// draws a contact friction of 0.54, and the UR5e's observation walks the peg up and out of the
/// mouth against it, without a fault).
fn assert_direct_trial_goes_in(file: PathBuf) {
    let request = TrialRequest {
        pair: PairSource::Assembly(file),
        method: Method::Direct,
        t_obs_s: 2.0,
        seed: 3,
        profile: Profile::Ideal,
        ..TrialRequest::new("cross", 0.5)
    };
    let r = request.run(&()).unwrap();
    assert!(r.fault.is_none(), "{:?}", r.fault);
    let depth_mm = r.final_depth_mm.unwrap();
    assert!(depth_mm > 5.0, "{depth_mm} mm");
}

#[test]
fn a_flange_link_and_tool_offset_put_the_peg_where_the_default_flange_does() {
    let dir = tempfile::tempdir().unwrap();
    let default = load(&cross_with(dir.path(), "a.toml", "")).unwrap();
    // The iiwa 14's flange is 45 mm beyond link 7: name link 7 and offset the tool by 45 mm.
    let moved = load(&cross_with(
        dir.path(),
        "b.toml",
        "[robot]\nbuiltin = \"iiwa14\"\nflange_link = \"iiwa_link_7\"\ntool_xyz_mm = [0, 0, 45]\n",
    ))
    .unwrap();
    assert_eq!(moved.report.robot.flange, "iiwa_link_7");
    for (a, b) in default
        .report
        .robot
        .start_q_deg
        .iter()
        .zip(&moved.report.robot.start_q_deg)
    {
        assert!((a - b).abs() < 1e-6, "{:?}", moved.report.robot.start_q_deg);
    }
    // Another robot (even the same arm said differently) is another manifold in the cache.
    assert_ne!(default.pair.content_key, moved.pair.content_key);
}

#[test]
fn a_urdf_that_ends_short_of_its_flange_takes_a_tool_offset() {
    let dir = tempfile::tempdir().unwrap();
    // The UR5e as a user's file without its tool0 frame: it ends at wrist 3, 99.6 mm short.
    let text = pegtwin::twin::robot::urdf::builtin_text("ur5e").unwrap();
    let cut = text.find("<joint name=\"flange_joint\"").unwrap();
    let short = text[..cut].replace("<link name=\"tool0\"/>", "") + "</robot>\n";
    std::fs::create_dir_all(dir.path().join("robots")).unwrap();
    std::fs::write(dir.path().join("robots/arm.urdf"), short).unwrap();
    let builtin = load(&cross_with(
        dir.path(),
        "a.toml",
        "[robot]\nbuiltin = \"ur5e\"\n",
    ))
    .unwrap();
    let user = load(&cross_with(
        dir.path(),
        "b.toml",
        "[robot]\nurdf = \"robots/arm.urdf\"\npackage_paths = [\"robots\"]\n\
         flange_link = \"wrist_3_link\"\ntool_xyz_mm = [0, 0, 99.6]\n",
    ))
    .unwrap();
    assert_eq!(user.report.robot.flange, "wrist_3_link");
    assert!(user.report.robot.source.ends_with("arm.urdf"));
    let (a, b) = (
        &builtin.report.robot.start_q_deg,
        &user.report.robot.start_q_deg,
    );
    assert!(
        a.iter().zip(b).all(|(a, b)| (a - b).abs() < 1e-6),
        "{a:?} vs {b:?}"
    );
}

#[test]
fn the_hole_stands_where_the_robot_section_says() {
    let dir = tempfile::tempdir().unwrap();
    let far = cross_with(
        dir.path(),
        "far.toml",
        "[robot]\nbuiltin = \"ur5e\"\nhole_xy_mm = [1200, 0]\n",
    );
    let err = load(&far).unwrap_err().to_string();
    assert!(
        err.contains("cannot reach") && err.contains("hole_xy_mm"),
        "{err}"
    );
    let near = cross_with(
        dir.path(),
        "near.toml",
        "[robot]\nbuiltin = \"ur5e\"\nhole_xy_mm = [350, 200]\n",
    );
    let default = cross_with(dir.path(), "default.toml", "[robot]\nbuiltin = \"ur5e\"\n");
    let (a, b) = (load(&near).unwrap(), load(&default).unwrap());
    assert_ne!(a.report.robot.start_q_deg, b.report.robot.start_q_deg);
    // Another place is another manifold (and another campaign fingerprint).
    assert_ne!(a.pair.content_key, b.pair.content_key);
    assert_direct_trial_goes_in(near);
}

#[test]
fn the_six_joint_ur5e_holds_the_peg_through_a_trial() {
    let dir = tempfile::tempdir().unwrap();
    let file = cross_with(dir.path(), "ur.toml", "[robot]\nbuiltin = \"ur5e\"\n");
    let assembly = load(&file).unwrap();
    assert_eq!(assembly.report.robot.joints, 6);
    assert_direct_trial_goes_in(file);
}

#[test]
fn the_six_joint_ur5e_and_the_iiwa7_show_the_commanded_cartesian_stiffness() {
    for robot in ["ur5e", "iiwa7"] {
        let out = pegtwin(&["robot", "stiffness", "--builtin", robot]);
        let text = String::from_utf8_lossy(&out.stdout);
        // Exit 0: every axis within 5 % of the commanded stiffness (no null space for the UR5e).
        assert!(out.status.success(), "{robot}: {text}{}", stderr(&out));
        assert!(text.contains("PASS"), "{text}");
    }
}

#[test]
fn bad_robots_are_refused_naming_the_file_and_field() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("branch.urdf"), arm_urdf(6, 0.2, true)).unwrap();
    std::fs::write(dir.path().join("short.urdf"), arm_urdf(6, 0.05, false)).unwrap();
    let cases = [
        (
            "builtin = \"ur10\"\n",
            "expected one of the built-in robots iiwa14, iiwa7, ur5e",
        ),
        ("urdf = \"branch.urdf\"\n", "only serial chains"),
        ("urdf = \"missing.urdf\"\n", "cannot read"),
        ("urdf = \"short.urdf\"\n", "cannot reach the start pose"),
        (
            "builtin = \"ur5e\"\nflange_link = \"tool9\"\n",
            "flange link 'tool9' is not a link",
        ),
        (
            "builtin = \"ur5e\"\nflange_link = \"forearm_link\"\n",
            "is not at the chain's tip",
        ),
        (
            "builtin = \"ur5e\"\npackage_paths = [\".\"]\n",
            "package_paths: only with urdf",
        ),
        ("builtin = \"ur5e\"\nstart_q_deg = [0, 0]\n", "start_q_deg"),
        (
            "builtin = \"ur5e\"\ntool_xyz_mm = [0, 0, 5000]\n",
            "tool_xyz_mm",
        ),
        ("builtin = \"ur5e\"\ngripper = 1\n", "gripper"),
        ("builtin = \"ur5e\"\nhole_xy_mm = [9000, 0]\n", "hole_xy_mm"),
    ];
    for (k, (robot, expected)) in cases.iter().enumerate() {
        let file = cross_with(
            dir.path(),
            &format!("bad{k}.toml"),
            &format!("[robot]\n{robot}"),
        );
        let out = pegtwin(&["assembly", "check", file.to_str().unwrap()]);
        let err = stderr(&out);
        assert_eq!(out.status.code(), Some(2), "{robot}: {err}");
        assert!(err.contains(expected), "{robot}: {err}");
        let named = err.contains(&format!("bad{k}.toml")) || err.contains(".urdf");
        assert!(named, "{robot}: the file is not named: {err}");
    }
}
