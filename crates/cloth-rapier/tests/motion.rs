//! Motion for rigs: BVH read as the format defines it, retargeting that
//! puts every link where the BVH puts its joint, keyframes interpolated
//! (slerp for rotations), and playback (rest, blend, loops that carry the
//! root's displacement).

use cloth_rapier::bvh::{Bvh, BvhError};
use cloth_rapier::motion::{BvhMap, Clip, MotionError, Playback, RigMotion, twist_angle};
use cloth_rapier::{JointValue, Rig, RigOptions, UpAxis};
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

fn fixture(dir: &str, name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../fixtures").join(dir).join(name)
}

fn mannequin() -> Rig {
    Rig::load(&fixture("rigs", "mannequin.urdf"), RigOptions::default()).unwrap()
}

/// The name table of the fixtures' BVH files.
fn mannequin_map() -> BvhMap {
    let pairs = [
        ("waist", "Spine"),
        ("neck", "Neck"),
        ("shoulder_l", "LeftArm"),
        ("elbow_l", "LeftForeArm"),
        ("shoulder_r", "RightArm"),
        ("elbow_r", "RightForeArm"),
        ("hip_l", "LeftUpLeg"),
        ("knee_l", "LeftLeg"),
        ("hip_r", "RightUpLeg"),
        ("knee_r", "RightLeg"),
    ];
    BvhMap {
        root: "Hips".into(),
        joints: pairs.iter().map(|(r, b)| (r.to_string(), b.to_string())).collect::<BTreeMap<_, _>>(),
        up_axis: UpAxis::Y,
        scale: 0.01,
    }
}

const TWO_JOINTS: &str = "HIERARCHY
ROOT Base
{
  OFFSET 1 2 3
  CHANNELS 6 Yrotation Xposition Zrotation Yposition Zposition Xrotation
  JOINT Arm
  {
    OFFSET 0 0 5
    CHANNELS 3 Yrotation Xrotation Zrotation
    End Site
    {
      OFFSET 0 0 1
    }
  }
}
MOTION
Frames: 2
Frame Time: 0.04
0 0 0 0 0 0 0 0 0
30 0.5 -40 1.5 -2 10 20 -60 45
";

fn about(axis: Vector3<f64>, deg: f64) -> UnitQuaternion<f64> {
    UnitQuaternion::from_axis_angle(&nalgebra::Unit::new_normalize(axis), deg.to_radians())
}

#[test]
fn bvh_channels_compose_in_the_order_listed() {
    let bvh = Bvh::parse(TWO_JOINTS, Path::new("two.bvh")).unwrap();
    assert_eq!((bvh.frames(), bvh.frame_time_s, bvh.values_per_frame), (2, 0.04, 9));
    let (x, y, z) = (Vector3::x(), Vector3::y(), Vector3::z());
    // Root: Y, then Z, then X (positions interleaved do not turn it).
    let root = about(y, 30.0) * about(z, -40.0) * about(x, 10.0);
    assert!(bvh.local_rotation(1, 0).angle_to(&root) < 1e-14);
    let arm = about(y, 20.0) * about(x, -60.0) * about(z, 45.0);
    assert!(bvh.local_rotation(1, 1).angle_to(&arm) < 1e-14);
    // Position: offset plus channels, whatever their place among the rotations.
    assert!((bvh.root_position(1) - Vector3::new(1.5, 3.5, 1.0)).norm() < 1e-14);
    let mut at = Vec::new();
    bvh.global_positions(1, &mut at);
    assert!((at[1] - (Vector3::new(1.5, 3.5, 1.0) + root * Vector3::new(0.0, 0.0, 5.0))).norm() < 1e-14);
}

#[test]
fn bvh_errors_name_the_line_and_the_problem() {
    let cases: [(String, usize, &str); 9] = [
        // Counts the file cannot hold: refused, never allocated (they aborted the process).
        (TWO_JOINTS.replace("CHANNELS 3", "CHANNELS 99999999999"), 9, "at most 6"),
        (TWO_JOINTS.replace("Frames: 2", "Frames: 99999999999"), 20, "ends at frame 2"),
        (TWO_JOINTS.replace("30 0.5 -40 1.5 -2 10 20 -60 45", "30 0.5 -40 1.5 -2 10 20 -60"), 20, "has 8 values"),
        (TWO_JOINTS.replace("30 0.5 -40 1.5 -2 10 20 -60 45", "30 0.5 -40 1.5 -2 10 20 -60 45 7"), 20, "more than"),
        (TWO_JOINTS.replace("Frames: 2", "Frames: 3"), 20, "ends at frame 2"),
        (TWO_JOINTS.replace("Frames: 2", "Frames: 1"), 20, "after the 1 frames"),
        (TWO_JOINTS.replace("Xrotation Zrotation", "Wrotation Zrotation"), 9, "unknown channel"),
        (TWO_JOINTS.replace("Frame Time: 0.04", "Frame Time: -0.04"), 18, "frame time must be > 0"),
        (TWO_JOINTS.replace("1.5 -2 10", "1.5 nan 10"), 20, "not a finite number"),
    ];
    for (text, line, message) in cases {
        let err = Bvh::parse(&text, Path::new("bad.bvh")).unwrap_err();
        let BvhError { file, line: got, message: text } = &err;
        assert_eq!(file, Path::new("bad.bvh"));
        assert!(*got == line && text.contains(message), "{err}: expected line {line} and {message:?}");
    }
    let twice = TWO_JOINTS.replace("JOINT Arm", "JOINT Base");
    assert!(Bvh::parse(&twice, Path::new("b.bvh")).unwrap_err().message.contains("defined twice"));
}

#[test]
fn twist_is_the_rotation_about_the_axis_left_after_the_swing() {
    let (x, y) = (Vector3::x(), Vector3::y_axis());
    for (a, b) in [(40.0, 0.0), (-75.0, 30.0), (120.0, -50.0), (179.0, 80.0)] {
        let q = about(x, b) * about(*y, a);
        let got = twist_angle(&q, &y).to_degrees();
        assert!((got - a).abs() < 1e-10, "twist of swing {b} then {a}: {got}");
    }
}

/// Every joint of the rig where the BVH puts the joint mapped to it, at
/// every frame of both fixtures: up axis, scale, composition order and the
/// rig's rolled shoulder frames all enter. Exact but for the tilted
/// forearms and hands, whose offsets (and elbow channels: an elbow takes
/// only the twist about its axis) the file holds to 6 decimals of a cm
/// (5.1e-9 m measured). A wrong convention is off by centimetres.
#[test]
fn retargeted_motions_put_each_link_where_the_bvh_puts_its_joint() {
    let rig = mannequin();
    let map = mannequin_map();
    for name in ["walk.bvh", "turn.bvh"] {
        let path = fixture("motions", name);
        let bvh = Bvh::load(&path).unwrap();
        let clip = Clip::from_bvh(&bvh, &path, &rig, &map).unwrap();
        assert_eq!(clip.poses.len(), bvh.frames());
        let (mut links, mut joints) = (Vec::new(), Vec::new());
        let up = UpAxis::Y.turn();
        let (mut worst, mut worst_forearm): (f64, f64) = (0.0, 0.0);
        for (frame, pose) in clip.poses.iter().enumerate() {
            rig.link_poses(pose, &mut links).unwrap();
            bvh.global_positions(frame, &mut joints);
            let mut pairs: Vec<(usize, &str)> =
                map.joints.iter().map(|(r, b)| (rig.joints[rig.joint(r).unwrap()].child, b.as_str())).collect();
            pairs.push((rig.root, &map.root));
            // The hands (fixed wrists) where the BVH's hands are.
            pairs.extend([(rig.link("hand_l").unwrap(), "LeftHand"), (rig.link("hand_r").unwrap(), "RightHand")]);
            for (link, bvh_joint) in pairs {
                let expected = up * joints[bvh.joint(bvh_joint).unwrap()] * 0.01;
                let off = (links[link].translation.vector - expected).norm();
                if bvh_joint.ends_with("Hand") || bvh_joint.ends_with("ForeArm") {
                    worst_forearm = worst_forearm.max(off);
                } else {
                    worst = worst.max(off);
                }
            }
        }
        assert!(worst < 1e-12, "{name}: a joint is {worst} m from the BVH's");
        assert!(worst_forearm < 6e-9, "{name}: a forearm or hand is {worst_forearm} m from the BVH's");
    }
    // The walk moves the legs as a walk: the left foot ahead of the right at a quarter cycle.
    let path = fixture("motions", "walk.bvh");
    let clip = Clip::from_bvh(&Bvh::load(&path).unwrap(), &path, &rig, &map).unwrap();
    let mut links = Vec::new();
    rig.link_poses(&clip.sample(0.25), &mut links).unwrap();
    let foot = |n: &str| links[rig.link(n).unwrap()].translation.vector;
    assert!(foot("foot_l").x - foot("foot_r").x > 0.3, "{} vs {}", foot("foot_l"), foot("foot_r"));
}

#[test]
fn a_bad_name_table_names_the_entry() {
    let rig = mannequin();
    let path = fixture("motions", "walk.bvh");
    let bvh = Bvh::load(&path).unwrap();
    let mut map = mannequin_map();
    map.joints.insert("knee_l".into(), "LeftKnee".into());
    let err = Clip::from_bvh(&bvh, &path, &rig, &map).unwrap_err();
    assert!(matches!(&err, MotionError::Invalid { field, .. } if field == "joints.knee_l"), "{err}");
    let mut map = mannequin_map();
    map.joints.insert("ankle_l".into(), "LeftFoot".into());
    let err = Clip::from_bvh(&bvh, &path, &rig, &map).unwrap_err();
    assert!(err.to_string().contains("joints.ankle_l") && err.to_string().contains("Fixed"), "{err}");
    let mut map = mannequin_map();
    map.root = "Pelvis".into();
    assert!(Clip::from_bvh(&bvh, &path, &rig, &map).unwrap_err().to_string().contains("root"));
}

/// Every wrong name of a table is reported at once, each with the names it
/// resembles: a misspelt rig joint, a BVH joint that is not in the file,
/// and the root.
#[test]
fn every_wrong_name_is_reported_at_once_with_the_nearest_names() {
    let rig = mannequin();
    let path = fixture("motions", "walk.bvh");
    let bvh = Bvh::load(&path).unwrap();
    let mut map = mannequin_map();
    map.joints.remove("knee_l");
    map.joints.insert("kne_l".into(), "LeftLeg".into());
    map.joints.insert("hip_l".into(), "LeftUpperLeg".into());
    map.root = "Hip".into();
    let err = Clip::from_bvh(&bvh, &path, &rig, &map).unwrap_err();
    let text = err.to_string();
    println!("{text}");
    assert!(matches!(&err, MotionError::Invalid { field, .. } if field == "joints"), "{err}");
    assert!(text.starts_with(&path.display().to_string()), "names the file: {text}");
    for part in [
        "root: no BVH joint \"Hip\" (nearest: \"Hips\"",
        "joints.kne_l: no rig joint \"kne_l\" (nearest: \"knee_l\"",
        "joints.hip_l: no BVH joint \"LeftUpperLeg\" (nearest: \"LeftUpLeg\"",
    ] {
        assert!(text.contains(part), "{part} missing from {text}");
    }
    let keys = KEYS.replace("knee_l = 60", "kne_l = 60").replace("shoulder_l = [0.0, 0.0, 90.0]", "sholder_l = 4");
    let err = Clip::parse_keyframes(&keys, Path::new("keys.toml"), &rig).unwrap_err().to_string();
    println!("{err}");
    assert!(err.contains("keys[1].joints.kne_l: no rig joint \"kne_l\" (nearest: \"knee_l\""), "{err}");
    assert!(err.contains("keys[1].joints.sholder_l: no rig joint \"sholder_l\" (nearest: \"shoulder_l\""), "{err}");
}

const KEYS: &str = r#"
[[keys]]
time_s = 0.0
root_position_m = [0.0, 0.0, 0.92]
joints = { knee_l = 0.0, shoulder_l = [0.0, 0.0, 0.0] }

[[keys]]
time_s = 2.0
root_position_m = [1.0, 0.0, 0.92]
root_rotation_deg = [0.0, 0.0, 90.0]
joints = { knee_l = 60, shoulder_l = [0.0, 0.0, 90.0] }
"#;

#[test]
fn keyframes_interpolate_angles_linearly_and_rotations_by_slerp() {
    let rig = mannequin();
    let clip = Clip::parse_keyframes(KEYS, Path::new("keys.toml"), &rig).unwrap();
    let mid = clip.sample(1.0);
    let knee = rig.joint("knee_l").unwrap();
    assert_eq!(mid.joints[knee], JointValue::Angle(30f64.to_radians()));
    let JointValue::Rotation(q) = mid.joints[rig.joint("shoulder_l").unwrap()] else { panic!("spherical") };
    assert!(q.angle_to(&about(Vector3::z(), 45.0)) < 1e-12, "{q:?}");
    assert!((mid.root.translation.vector - Vector3::new(0.5, 0.0, 0.92)).norm() < 1e-15);
    assert!(mid.root.rotation.angle_to(&about(Vector3::z(), 45.0)) < 1e-12);
    // A joint a key does not list is at rest; after the end the last key holds.
    assert_eq!(clip.sample(5.0).joints[rig.joint("elbow_l").unwrap()], JointValue::Angle(0.0));
    assert_eq!(clip.sample(5.0).joints[knee], JointValue::Angle(60f64.to_radians()));

    let bad = [
        (KEYS.replace("knee_l = 60", "knee_x = 60"), "keys[1].joints.knee_x"),
        (KEYS.replace("knee_l = 60", "ankle_l = 60"), "keys[1].joints.ankle_l"),
        (KEYS.replace("knee_l = 60", "knee_l = [1.0, 2.0, 3.0]"), "keys[1].joints.knee_l"),
        (KEYS.replace("shoulder_l = [0.0, 0.0, 90.0]", "shoulder_l = 4"), "keys[1].joints.shoulder_l"),
        (KEYS.replace("time_s = 2.0", "time_s = 0.0"), "keys[1].time_s"),
        (KEYS.replace("root_rotation_deg", "root_turn_deg"), "root_turn_deg"),
    ];
    for (text, field) in bad {
        let err = Clip::parse_keyframes(&text, Path::new("keys.toml"), &rig).unwrap_err();
        assert!(err.to_string().starts_with("keys.toml") && err.to_string().contains(field), "{err}");
    }
}

#[test]
fn playback_rests_blends_and_loops_carrying_the_root() {
    let rig = mannequin();
    let map = mannequin_map();
    let path = fixture("motions", "walk.bvh");
    let clip = Clip::from_bvh(&Bvh::load(&path).unwrap(), &path, &rig, &map).unwrap();
    let first = clip.poses[0].clone();
    let placement = Isometry3::from_parts(Translation3::new(0.0, 2.0, 0.0), about(Vector3::z(), 90.0));
    let playback = Playback { settle_s: 0.5, blend_s: 0.25, looping: true, placement };
    let motion = RigMotion::new(clip.clone(), &rig, playback, &path).unwrap();
    // Settling: the rest pose where the clip starts.
    let rest = motion.pose_at(0.3);
    assert_eq!(rest.joints, rig.rest_pose().joints);
    assert!((rest.root.translation.vector - (placement * first.root).translation.vector).norm() < 1e-15);
    // Blended in while the clip plays from the end of the settling: half
    // way (smoothstep 1/2) half the clip's knee angle, then the clip.
    let clip_at = |tau: f64| {
        let mut pose = clip.sample(tau);
        pose.root = placement * pose.root;
        pose
    };
    assert_eq!(motion.pose_at(0.75), clip_at(0.25));
    assert_eq!(motion.pose_at(0.9), clip_at(0.4));
    let halfway = motion.pose_at(0.625);
    let knee = rig.joint("knee_r").unwrap();
    let (JointValue::Angle(k), JointValue::Angle(k_clip)) = (halfway.joints[knee], clip_at(0.125).joints[knee]) else {
        panic!("revolute")
    };
    assert!((k - k_clip / 2.0).abs() < 1e-12, "smoothstep is half at halfway: {k} vs {k_clip}");
    let root = halfway.root.translation.vector;
    let expected = (placement * first.root).translation.vector.lerp(&clip_at(0.125).root.translation.vector, 0.5);
    assert!((root - expected).norm() < 1e-14, "root {root} vs {expected}");
    // Loops: the same joints two cycles later, the root 1 m further
    // along the clip's forward (the placement turns it to +y).
    // (A cycle is 30 frames of the file's 0.03333333 s.)
    let period = motion.clip().duration_s();
    assert!((period - 1.0).abs() < 1e-6);
    for t in [0.9, 1.3, 1.61] {
        let (a, b) = (motion.pose_at(t), motion.pose_at(t + 2.0 * period));
        for (x, y) in a.joints.iter().zip(&b.joints) {
            match (x, y) {
                (JointValue::Angle(p), JointValue::Angle(q)) => assert!((p - q).abs() < 1e-12),
                (JointValue::Rotation(p), JointValue::Rotation(q)) => assert!((p.coords - q.coords).norm() < 1e-13),
                _ => assert_eq!(x, y),
            }
        }
        let step = b.root.translation.vector - a.root.translation.vector;
        assert!((step - Vector3::new(0.0, 2.0, 0.0)).norm() < 1e-12, "two cycles at t = {t}: {step}");
    }
    // The turn loops with its quarter turn carried: two cycles, half a turn.
    let path = fixture("motions", "turn.bvh");
    let clip = Clip::from_bvh(&Bvh::load(&path).unwrap(), &path, &rig, &map).unwrap();
    let motion = RigMotion::new(clip, &rig, Playback::default(), &path).unwrap();
    let period = motion.clip().duration_s();
    let turned = motion.pose_at(2.0 * period).root.rotation * motion.pose_at(0.0).root.rotation.inverse();
    assert!(turned.angle_to(&about(Vector3::z(), 180.0)) < 1e-9, "{:?}", turned.euler_angles());
}

/// A `[rig]` section's mistakes are errors naming the field, and the
/// file where the mistake is in another file.
#[test]
fn rig_scene_errors_name_the_field_and_the_file() {
    let scenes = fixture("scenes", "");
    let text = std::fs::read_to_string(fixture("scenes", "skirt-walk.toml")).unwrap();
    let build = |text: &str, overrides: &[&str]| {
        let overrides: Vec<String> = overrides.iter().map(|s| s.to_string()).collect();
        let mut scene = cloth_rapier::CoupledScene::parse(text, &overrides)?;
        scene.scene.base_dir = scenes.clone();
        scene.build().map(|_| ())
    };
    build(&text, &[]).unwrap();
    let cases: [(String, &[&str], &str); 8] = [
        (text.replace("friction = 0.3", "friction = 0.3\ncolour = 1"), &[], "colour"),
        (text.clone(), &["rig.urdf=\"../rigs/nobody.urdf\""], "rig.urdf"),
        (text.clone(), &["rig.settle_s=-1.0"], "rig.settle_s"),
        (text.clone(), &["rig.friction=nan"], "rig.friction"),
        (text.replace("knee_l = \"LeftLeg\"", "knee_l = \"LeftKnee\""), &[], "joints.knee_l"),
        (text.replace("walk.bvh", "missing.bvh"), &[], "missing.bvh"),
        (text.replace("body = \"pelvis\"", "body = \"pelvs\""), &[], "attachments[0].body: no body or rig link \"pelvs\" (nearest: \"pelvis\""),
        (
            text.replace("[[attachments]]", "[[bodies]]\nname = \"pelvis\"\nkind = \"fixed\"\nshape = { kind = \"ball\", radius_m = 0.1 }\n\n[[attachments]]"),
            &[],
            "also a link of the rig",
        ),
    ];
    for (text, overrides, expected) in cases {
        let err = build(&text, overrides).unwrap_err().to_string();
        assert!(err.contains(expected), "{err:?} should mention {expected:?}");
    }
    // Two wrong attachments: both at once.
    let twice = text.replace("body = \"pelvis\"", "body = \"pelvs\"\n\n[[attachments]]\npins = 0\nbody = \"torsoo\"");
    let err = build(&twice, &[]).unwrap_err().to_string();
    assert!(err.contains("attachments[0].body: no body or rig link \"pelvs\" (nearest: \"pelvis\""), "{err}");
    assert!(err.contains("attachments[1].body: no body or rig link \"torsoo\" (nearest: \"torso\""), "{err}");
}

/// A character at the wrong scale, or read with the wrong up axis, gets a
/// warning before the first step naming the file and the key to set; the
/// rig's summary says what was read; each solid is named by its link.
#[test]
fn a_wrong_scale_or_up_axis_is_warned_about_by_key() {
    let path = fixture("scenes", "skirt-walk.toml");
    let build = |overrides: &[&str]| {
        let overrides: Vec<String> = overrides.iter().map(|s| s.to_string()).collect();
        cloth_rapier::CoupledScene::load(&path, &overrides).unwrap().build().unwrap()
    };
    let run = build(&[]);
    assert!(run.warnings().is_empty(), "{:?}", run.warnings());
    let summary = run.rig.as_ref().unwrap().summary(&run.world);
    println!("{summary}");
    assert!((summary.height_m - 1.76).abs() < 0.01 && summary.links == 15, "{summary}");
    assert!(summary.driven.iter().any(|j| j == "knee_l") && !summary.driven.iter().any(|j| j == "ankle_l"));
    let names = run.solid_names();
    assert!(names.iter().any(|n| n == "pelvis") && names.iter().any(|n| n == "shin_l"), "{names:?}");
    // The skirt then starts inside the character too: allowed here, and
    // reported after the rig's warning.
    let allow = "collision.allow_start_inside=true";
    let tall = build(&["rig.scale=4.0", allow]).warnings();
    println!("{tall:?}");
    assert!(tall.len() == 2 && tall[0].contains("mannequin.urdf") && tall[0].contains("rig.scale"), "{tall:?}");
    assert!(tall[1].contains("starts inside") && tall[1].contains("in \"pelvis\""), "{tall:?}");
    let lying = build(&["rig.up_axis=\"y\"", allow]).warnings();
    println!("{lying:?}");
    assert!(lying[0].contains("lies on its side") && lying[0].contains("rig.up_axis"), "{lying:?}");
    assert!(build(&["rig.scale=0.1", allow]).warnings()[0].contains("0.18 m tall"));
}

/// The settle pose can be the motion's first frame or joint values over
/// the rest pose; the character holds it until the motion blends in, and
/// wrong joint names are reported with the nearest ones.
#[test]
fn a_settle_pose_is_held_before_the_motion() {
    let path = fixture("scenes", "skirt-walk.toml");
    let build = |overrides: &[&str]| {
        let overrides: Vec<String> = overrides.iter().map(|s| s.to_string()).collect();
        cloth_rapier::CoupledScene::load(&path, &overrides)
            .and_then(|s| s.build().map_err(|kind| cloth_core::scene::SceneError { file: path.clone(), kind }))
    };
    let run = build(&[]).unwrap();
    let rig = run.rig.as_ref().unwrap();
    let elbow = rig.rig.joint("elbow_l").unwrap();
    assert_eq!(rig.pose_at(0.2).joints, rig.rig.rest_pose().joints, "rest by default");
    let first = rig.motion.clip().poses[0].joints.clone();
    let run = build(&["rig.settle_pose=\"first-frame\""]).unwrap();
    assert_eq!(run.rig.as_ref().unwrap().pose_at(0.2).joints, first);
    for blend in ["1.0", "0.0"] {
        let run = build(&["rig.settle_pose={ joints = { elbow_l = 30.0 } }", &format!("rig.blend_s={blend}")]).unwrap();
        let rig = run.rig.as_ref().unwrap();
        assert_eq!(rig.pose_at(0.2).joints[elbow], JointValue::Angle(30f64.to_radians()), "blend {blend}");
        let knee = rig.rig.joint("knee_l").unwrap();
        assert_eq!(rig.pose_at(0.2).joints[knee], JointValue::Angle(0.0));
    }
    let err = build(&["rig.settle_pose={ joints = { elbw_l = 30.0, knee_l = [1.0, 2.0, 3.0] } }"]).unwrap_err();
    let text = err.to_string();
    println!("{text}");
    assert!(text.contains("skirt-walk.toml") && text.contains("rig.settle_pose.joints"), "{text}");
    assert!(text.contains("rig.settle_pose.joints.elbw_l: no rig joint \"elbw_l\" (nearest: \"elbow_l\""), "{text}");
    assert!(text.contains("rig.settle_pose.joints.knee_l"), "{text}");
}
