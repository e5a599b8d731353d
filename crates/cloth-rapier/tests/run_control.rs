//! Inputs to a built scene from outside: a force and a torque move a free
//! body by Newton's law for one step each, a kinematic target is reached,
//! joint values are held, and refused inputs change nothing.

use cloth_core::{BodyPose, Vec3};
use cloth_rapier::{CoupledScene, JointValue, RunControlError};
use nalgebra::UnitQuaternion;
use std::path::PathBuf;

fn fixture(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/scenes").join(name)
}

fn hammock(extra: &[&str]) -> cloth_rapier::CoupledRun {
    let mut sets = vec!["bodies.2.linear_damping_1_s=0.0".to_string(), "bodies.2.angular_damping_1_s=0.0".to_string()];
    sets.extend(extra.iter().map(|s| s.to_string()));
    CoupledScene::load(&fixture("hammock.toml"), &sets).unwrap().build().unwrap()
}

#[test]
fn a_force_and_a_torque_accelerate_a_free_body_for_one_step() {
    // The ball, above the cloth: three times its weight up for ten steps,
    // 2 g t up; a torque about z, tau t / I (I = 2/5 m r^2); then g again.
    let mut run = hammock(&[]);
    let (h, g) = (run.config.dt_s, 9.81);
    let m = run.world.bodies[run.bodies[2].handle].mass();
    let inertia = 0.4 * m * 0.1 * 0.1;
    for _ in 0..10 {
        run.apply_force(2, Vec3::new(0.0, 0.0, 3.0 * m * g), Vec3::new(0.0, 0.0, 1e-3)).unwrap();
        run.step().unwrap();
    }
    let (_, v, w) = run.body_state(2).unwrap();
    // Measured: exact to the last bits (2.2e-16 relative).
    assert!((v.z - 2.0 * g * 10.0 * h).abs() < 1e-12, "{v:?}");
    assert!((w.z - 1e-3 / inertia * 10.0 * h).abs() < 1e-12, "{w:?}");
    run.step().unwrap();
    let (_, v2, _) = run.body_state(2).unwrap();
    assert!((v2.z - v.z + g * h).abs() < 1e-12);
    assert_eq!(run.cloth_load(2).unwrap().contacts, 0);
}

#[test]
fn a_kinematic_target_is_reached_and_held() {
    let mut run = hammock(&["bodies.2.kind=\"kinematic\""]);
    let target =
        BodyPose { position: Vec3::new(0.1, 0.2, 1.4), rotation: UnitQuaternion::from_euler_angles(0.0, 0.0, 0.3) };
    run.set_kinematic_target(2, target).unwrap();
    for _ in 0..2 {
        run.step().unwrap();
        let (pose, _, _) = run.body_state(2).unwrap();
        assert!((pose.position - target.position).norm() < 1e-14 && pose.rotation.angle_to(&target.rotation) < 1e-12);
    }
}

#[test]
fn refused_inputs_name_the_body_or_joint_and_change_nothing() {
    let mut run = hammock(&[]);
    assert_eq!(
        run.apply_force(7, Vec3::zeros(), Vec3::zeros()),
        Err(RunControlError::NoSuchBody { index: 7, count: 3 })
    );
    assert!(matches!(
        run.apply_force(0, Vec3::z(), Vec3::zeros()),
        Err(RunControlError::WrongBodyKind { kind: "fixed", .. })
    ));
    assert!(matches!(
        run.apply_force(2, Vec3::new(f64::NAN, 0.0, 0.0), Vec3::zeros()),
        Err(RunControlError::NonFinite { .. })
    ));
    assert_eq!(run.set_joint_positions(&[("L_Knee".into(), JointValue::Angle(0.1))]), Err(RunControlError::NoRig));
    let mut rig = CoupledScene::load(&fixture("humanoid-skirt.toml"), &[]).unwrap().build().unwrap();
    let before = rig.joint_positions().unwrap();
    let refused =
        rig.set_joint_positions(&[("L_Knee".into(), JointValue::Angle(0.4)), ("L_Hip".into(), JointValue::Angle(0.2))]);
    assert!(matches!(refused, Err(RunControlError::WrongJointValue { kind: "spherical", .. })), "{refused:?}");
    assert_eq!(rig.joint_positions().unwrap(), before);
    rig.set_joint_positions(&[("L_Knee".into(), JointValue::Angle(0.4))]).unwrap();
    rig.step().unwrap();
    let knee = rig.joint_positions().unwrap().into_iter().find(|(n, _)| n == "L_Knee").map(|(_, v)| v);
    assert_eq!(knee, Some(JointValue::Angle(0.4)));
}
