//! URDF rigs: forward kinematics against poses worked out by hand, the
//! forms real files come in (Y up, a scale, CRLF, no inertials), and
//! errors that name the file, the link or joint and the field.

use cloth_collide::ShapeSpec;
use cloth_rapier::rig::RigGeometry;
use cloth_rapier::{JointValue, Rig, RigError, RigOptions, UpAxis};
use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use std::f64::consts::FRAC_PI_2;
use std::path::{Path, PathBuf};

fn fixture(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/rigs").join(name)
}

/// A chain: `base` -> revolute about Z at (1, 0, 0) -> `arm` -> prismatic
/// along the arm's X at (0.5, 0, 0) with the joint frame turned 90 degrees
/// about X -> `slider` -> spherical at (0, 0, 0.2) -> `tip`.
const CHAIN: &str = r#"<?xml version="1.0"?>
<robot name="chain">
  <link name="base"/>
  <link name="arm">
    <collision><origin xyz="0.25 0 0"/><geometry><cylinder radius="0.05" length="0.5"/></geometry></collision>
  </link>
  <link name="slider"/>
  <link name="tip"><collision><geometry><sphere radius="0.1"/></geometry></collision></link>
  <joint name="turn" type="revolute">
    <parent link="base"/><child link="arm"/>
    <origin xyz="1 0 0"/><axis xyz="0 0 2"/>
    <limit lower="-3" upper="3" effort="0" velocity="1"/>
  </joint>
  <joint name="slide" type="prismatic">
    <parent link="arm"/><child link="slider"/>
    <origin xyz="0.5 0 0" rpy="1.5707963267948966 0 0"/><axis xyz="1 0 0"/>
    <limit lower="0" upper="1" effort="0" velocity="1"/>
  </joint>
  <joint name="ball" type="spherical">
    <parent link="slider"/><child link="tip"/>
    <origin xyz="0 0 0.2"/>
  </joint>
</robot>
"#;

fn close(a: Point3<f64>, b: Point3<f64>) -> bool {
    (a - b).norm() < 1e-14
}

#[test]
fn forward_kinematics_places_each_link_where_the_joints_put_it() {
    let rig = Rig::parse(CHAIN, Path::new("chain.urdf"), RigOptions::default()).unwrap();
    let mut pose = rig.rest_pose();
    pose.joints[rig.joint("turn").unwrap()] = JointValue::Angle(FRAC_PI_2);
    pose.joints[rig.joint("slide").unwrap()] = JointValue::Offset(0.3);
    let spin = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), FRAC_PI_2);
    pose.joints[rig.joint("ball").unwrap()] = JointValue::Rotation(spin);
    pose.root = Isometry3::from_parts(Translation3::new(0.0, 0.0, 2.0), UnitQuaternion::identity());
    let mut at = Vec::new();
    rig.link_poses(&pose, &mut at).unwrap();
    let origin = |link: &str| at[rig.link(link).unwrap()] * Point3::origin();
    // The arm turns a quarter about Z at (1, 0, 2): its X is the world's Y.
    assert!(close(origin("arm"), Point3::new(1.0, 0.0, 2.0)));
    assert!(close(at[rig.link("arm").unwrap()] * Point3::new(1.0, 0.0, 0.0), Point3::new(1.0, 1.0, 2.0)));
    // The slider: 0.5 along the arm's X, then 0.3 along the joint frame's X
    // (the frame is only turned about X, so that is the arm's X too).
    assert!(close(origin("slider"), Point3::new(1.0, 0.8, 2.0)));
    // The tip: 0.2 along the slider's Z, which the joint frame's quarter
    // turn about X made the arm's -Y, the world's +X.
    assert!(close(origin("tip"), Point3::new(1.2, 0.8, 2.0)));
    // The ball joint turns the tip a further quarter about the slider's X
    // (the world's Y): the tip's Z points along the world's Z... worked:
    // world <- arm (Rz 90) <- frame (Rx 90) <- ball (Rx 90): Rz90 Rx180,
    // whose Z is -Z.
    let tip_z = at[rig.link("tip").unwrap()].rotation * Vector3::z();
    assert!((tip_z - Vector3::new(0.0, 0.0, -1.0)).norm() < 1e-14, "tip z {tip_z}");
    // The arm's cylinder lies along its link frame's Z, 0.25 out along X.
    let arm = &rig.links[rig.link("arm").unwrap()];
    assert_eq!(arm.shapes.len(), 1);
    assert_eq!(arm.shapes[0].geometry, RigGeometry::Solid(ShapeSpec::Cylinder { half_length_m: 0.25, radius_m: 0.05 }));
}

#[test]
fn a_value_of_the_wrong_kind_or_count_is_refused() {
    let rig = Rig::parse(CHAIN, Path::new("chain.urdf"), RigOptions::default()).unwrap();
    let mut at = Vec::new();
    let mut pose = rig.rest_pose();
    pose.joints[rig.joint("turn").unwrap()] = JointValue::Offset(0.1);
    let e = rig.link_poses(&pose, &mut at).unwrap_err().to_string();
    assert!(e.contains("\"turn\""), "{e}");
    pose = rig.rest_pose();
    pose.joints[rig.joint("slide").unwrap()] = JointValue::Offset(f64::NAN);
    let e = rig.link_poses(&pose, &mut at).unwrap_err().to_string();
    assert!(e.contains("\"slide\"") && e.contains("not finite"), "{e}");
    pose.joints.pop();
    assert!(matches!(rig.link_poses(&pose, &mut at), Err(RigError::Pose { .. })));
}

/// The mannequin fixture stands 1.76 m tall with its soles on the ground
/// when its pelvis is at 0.92 m; left and right mirror; bending a knee a
/// quarter turn carries the foot back by the shin's length.
#[test]
fn the_mannequin_has_human_proportions() {
    let rig = Rig::load(&fixture("mannequin.urdf"), RigOptions::default()).unwrap();
    assert_eq!(rig.links.len(), 15);
    let mut pose = rig.rest_pose();
    pose.root = Isometry3::translation(0.0, 0.0, 0.92);
    let mut at = Vec::new();
    rig.link_poses(&pose, &mut at).unwrap();
    // Lowest and highest points of the collision shapes (boxes by their
    // corners, round shapes by their radius along Z).
    let (mut low, mut high) = (f64::MAX, f64::MIN);
    for (link, frame) in rig.links.iter().zip(&at) {
        for s in &link.shapes {
            let f = frame * s.origin;
            let reach = |axis_half: f64, r: f64| {
                let z = (f.rotation * Vector3::z()).z.abs() * axis_half + r;
                (f.translation.z - z, f.translation.z + z)
            };
            let (lo, hi) = match &s.geometry {
                RigGeometry::Solid(ShapeSpec::Cuboid { half_extents_m }) => {
                    let half = Vector3::from(*half_extents_m);
                    let z = (f.rotation.to_rotation_matrix().matrix().abs() * half).z;
                    (f.translation.z - z, f.translation.z + z)
                }
                RigGeometry::Solid(
                    ShapeSpec::Capsule { half_length_m, radius_m } | ShapeSpec::Cylinder { half_length_m, radius_m },
                ) => reach(*half_length_m, *radius_m),
                RigGeometry::Solid(ShapeSpec::Ball { radius_m }) => reach(0.0, *radius_m),
                other => unreachable!("the mannequin has no {other:?}"),
            };
            low = low.min(lo);
            high = high.max(hi);
        }
    }
    assert!(low.abs() < 1e-12 && (high - 1.76).abs() < 1e-12, "soles at {low} m, head top at {high} m");
    let origin = |name: &str| at[rig.link(name).unwrap()].translation.vector;
    for (l, r) in [("hand_l", "hand_r"), ("foot_l", "foot_r"), ("upper_arm_l", "upper_arm_r")] {
        let (a, b) = (origin(l), origin(r));
        assert!((a.x - b.x).abs() + (a.y + b.y).abs() + (a.z - b.z).abs() < 1e-15, "{l} {a} vs {r} {b}");
    }
    let knee = rig.joint("knee_l").unwrap();
    pose.joints[knee] = JointValue::Angle(FRAC_PI_2);
    let before = origin("foot_l");
    rig.link_poses(&pose, &mut at).unwrap();
    let after = at[rig.link("foot_l").unwrap()].translation.vector;
    assert!((after - before - Vector3::new(-0.43, 0.0, 0.43)).norm() < 1e-14, "foot moved by {}", after - before);
}

#[test]
fn y_up_centimetre_crlf_files_read_as_the_z_up_metre_one() {
    // The chain in centimetres, Y up, CRLF line ends: every length x100,
    // and every frame as the file's axes see it (the world's Z is the
    // file's Y, the world's Y the file's -Z): offsets and axes turned by
    // -90 degrees about X, joint frames conjugated by it (a turn about X
    // is unchanged), shape frames turned by it.
    let y_up = CHAIN
        .replace(r#"<origin xyz="0.25 0 0"/>"#, r#"<origin xyz="25 0 0" rpy="-1.5707963267948966 0 0"/>"#)
        .replace(r#"radius="0.05" length="0.5""#, r#"radius="5" length="50""#)
        .replace(r#"radius="0.1""#, r#"radius="10""#)
        .replace(r#"<origin xyz="1 0 0"/><axis xyz="0 0 2"/>"#, r#"<origin xyz="100 0 0"/><axis xyz="0 2 0"/>"#)
        .replace(
            r#"<origin xyz="0.5 0 0" rpy="1.5707963267948966 0 0"/>"#,
            r#"<origin xyz="50 0 0" rpy="1.5707963267948966 0 0"/>"#,
        )
        .replace(r#"<origin xyz="0 0 0.2"/>"#, r#"<origin xyz="0 20 0"/>"#)
        .replace(
            "<link name=\"tip\"><collision>",
            "<link name=\"tip\"><collision><origin rpy=\"-1.5707963267948966 0 0\"/>",
        )
        .replace(r#"lower="0" upper="1""#, r#"lower="0" upper="100""#)
        .replace('\n', "\r\n");
    let z = Rig::parse(CHAIN, Path::new("chain.urdf"), RigOptions::default()).unwrap();
    let y = Rig::parse(&y_up, Path::new("chain-y.urdf"), RigOptions { up_axis: UpAxis::Y, scale: 0.01 }).unwrap();
    let mut pose = z.rest_pose();
    pose.joints[z.joint("turn").unwrap()] = JointValue::Angle(0.7);
    pose.joints[z.joint("slide").unwrap()] = JointValue::Offset(0.3);
    let (mut a, mut b) = (Vec::new(), Vec::new());
    z.link_poses(&pose, &mut a).unwrap();
    // Joint values are SI whatever the file's unit.
    y.link_poses(&pose, &mut b).unwrap();
    for (k, link) in z.links.iter().enumerate() {
        let (pa, pb) = (a[k] * Point3::origin(), b[k] * Point3::origin());
        assert!((pa - pb).norm() < 1e-14, "{}: {pa} (Z up, m) vs {pb} (Y up, cm)", link.name);
        for (sa, sb) in link.shapes.iter().zip(&y.links[k].shapes) {
            let (fa, fb) = (a[k] * sa.origin, b[k] * sb.origin);
            assert!((fa.translation.vector - fb.translation.vector).norm() < 1e-14, "{} shape", link.name);
            assert!((fa.rotation * Vector3::z() - fb.rotation * Vector3::z()).norm() < 1e-14, "{} axis", link.name);
        }
    }
    assert_eq!(y.links[1].shapes[0].geometry, z.links[1].shapes[0].geometry);
    assert_eq!(y.links[3].shapes[0].geometry, z.links[3].shapes[0].geometry);
}

/// Each error names the file, the element and the field.
#[test]
fn bad_rigs_are_refused_naming_file_element_and_field() {
    let file = Path::new("rigs/bad.urdf");
    let check = |text: String, options: RigOptions, wanted: &[&str]| {
        let e = Rig::parse(&text, file, options).unwrap_err().to_string();
        for w in wanted {
            assert!(e.contains(w), "{e:?} should mention {w:?}");
        }
        assert!(e.starts_with("rigs/bad.urdf"), "{e}");
    };
    let o = RigOptions::default();
    check(
        CHAIN.replace(r#"<parent link="arm"/>"#, r#"<parent link="elbow"/>"#),
        o,
        &["\"slide\"", "parent.link", "elbow"],
    );
    check(CHAIN.replace(r#"radius="0.1""#, r#"radius="-0.1""#), o, &["\"tip\"", "collision[0].geometry.sphere.radius"]);
    check(CHAIN.replace(r#"<axis xyz="0 0 2"/>"#, r#"<axis xyz="0 0 0"/>"#), o, &["\"turn\"", "axis.xyz"]);
    check(CHAIN.replace(r#"lower="-3" upper="3""#, r#"lower="3" upper="-3""#), o, &["\"turn\"", "limit"]);
    check(CHAIN.replace(r#"type="spherical""#, r#"type="planar""#), o, &["\"ball\"", "type", "planar"]);
    check(
        CHAIN.replace(r#"<child link="tip"/>"#, r#"<child link="arm"/>"#),
        o,
        &["\"ball\"", "child.link", "\"turn\""],
    );
    check(
        CHAIN.replace(r#"<link name="slider"/>"#, r#"<link name="slider"/><link name="stray"/>"#),
        o,
        &["stray", "one tree"],
    );
    check(CHAIN.replace("<link name=\"tip\">", "<link name=\"arm\">"), o, &["\"arm\"", "two links"]);
    check(
        CHAIN.replace(r#"<sphere radius="0.1"/>"#, r#"<mesh filename="package://robot/tip.obj"/>"#),
        o,
        &["\"tip\"", "mesh.filename", "package://"],
    );
    check(
        CHAIN.replace(r#"<sphere radius="0.1"/>"#, r#"<mesh filename="tip.obj"/>"#),
        o,
        &["\"tip\"", "tip.obj", "does not exist"],
    );
    check(CHAIN.replace("</robot>", ""), o, &["not valid URDF"]);
    check(CHAIN.to_string(), RigOptions { scale: -1.0, ..o }, &["scale"]);
    let missing = Rig::load(Path::new("rigs/none.urdf"), o).unwrap_err().to_string();
    assert!(missing.starts_with("rigs/none.urdf"), "{missing}");
}

/// URDF's `rpy` is roll, pitch, yaw about the fixed X, Y, Z axes:
/// `R = Rz(yaw) Ry(pitch) Rx(roll)`.
#[test]
fn rpy_is_fixed_axis_roll_pitch_yaw() {
    let text = r#"<robot name="r"><link name="a"/><link name="b"/>
      <joint name="j" type="fixed"><parent link="a"/><child link="b"/>
      <origin xyz="0 0 0" rpy="0.3 0.5 0.7"/></joint></robot>"#;
    let rig = Rig::parse(text, Path::new("r.urdf"), RigOptions::default()).unwrap();
    let about = |axis, angle| UnitQuaternion::from_axis_angle(&axis, angle);
    let expected = about(Vector3::z_axis(), 0.7) * about(Vector3::y_axis(), 0.5) * about(Vector3::x_axis(), 0.3);
    let got = rig.joints[0].origin.rotation;
    assert!(got.angle_to(&expected) < 1e-15, "rpy gave {got:?}, expected {expected:?}");
}
