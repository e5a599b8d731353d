//! The cloth as a co-simulation unit: variables, rollback and serialised
//! state reproduce a run bit for bit.

use cloth_core::scene::Scene;
use cloth_cosim::{ClothUnit, StepOutcome, Unit, UnitError};
use std::path::PathBuf;

fn sweep_unit() -> ClothUnit {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/scenes/sweep.toml");
    let overrides = vec![
        r#"colliders.0.motion={ kind = "external" }"#.to_string(),
        r#"pins.0.motion={ kind = "external" }"#.to_string(),
        "panels.0.particles=[11,11]".to_string(),
    ];
    let scene = Scene::parse_file(&path, &overrides).unwrap();
    let (model, cfg) = scene.build().unwrap();
    ClothUnit::new("cloth", cfg.simulation(model))
}

fn outputs(unit: &ClothUnit) -> Vec<u64> {
    (0..unit.variables().len()).map(|vr| unit.get(vr).unwrap().to_bits()).collect()
}

/// Drives the ball through the curtain: `solid0.velocity.y` = 0.6 m/s
/// (the position input is where the ball is at the end of the step).
fn run(unit: &mut ClothUnit, from_step: usize, steps: usize) {
    let (h, vy) = (1.0 / 90.0, 0.6);
    let (py, vel) = (unit.find("solid0.position.y").unwrap(), unit.find("solid0.velocity.y").unwrap());
    for k in from_step..from_step + steps {
        let t = k as f64 * h;
        unit.set(py, -0.4 + vy * (t + h)).unwrap();
        unit.set(vel, vy).unwrap();
        assert_eq!(unit.do_step(t, h).unwrap(), StepOutcome::Completed);
    }
}

#[test]
fn the_cloth_unit_names_its_inputs_and_outputs() {
    let mut unit = sweep_unit();
    let names: Vec<&str> = unit.variables().iter().map(|v| v.name.as_str()).collect();
    for name in
        ["pin0.target.x", "solid0.position.y", "solid0.rotation.z", "solid0.force.y", "pin10.reaction.z", "lowest_z"]
    {
        assert!(names.contains(&name), "{name} missing from {names:?}");
    }
    let force = unit.find("solid0.force.y").unwrap();
    assert!(matches!(unit.set(force, 1.0), Err(UnitError::Causality { .. })));
    let target = unit.find("pin0.target.x").unwrap();
    assert!(matches!(unit.set(target, f64::NAN), Err(UnitError::InvalidValue { .. })));
}

#[test]
fn the_ball_pushes_the_curtain_and_feels_it() {
    let mut unit = sweep_unit();
    run(&mut unit, 0, 80);
    let fy = unit.get(unit.find("solid0.force.y").unwrap()).unwrap();
    println!("force of the curtain on the ball after 80 steps: {fy} N");
    // The ball moves in +y into the curtain: the cloth pushes it back.
    assert!(fy < -1e-3, "{fy}");
}

#[test]
fn rollback_and_serialised_state_replay_bit_for_bit() {
    let mut unit = sweep_unit();
    run(&mut unit, 0, 40);
    let saved = unit.get_state();
    let bytes = unit.serialize_state(&saved).unwrap();
    run(&mut unit, 40, 30);
    let first = outputs(&unit);
    let first_x = unit.simulation().state().x.clone();
    unit.set_state(&saved).unwrap();
    run(&mut unit, 40, 30);
    assert_eq!(outputs(&unit), first);
    let restored = unit.deserialize_state(&bytes).unwrap();
    unit.set_state(&restored).unwrap();
    run(&mut unit, 40, 30);
    assert_eq!(outputs(&unit), first);
    assert!(same_bits(&unit.simulation().state().x, &first_x));
    assert!(matches!(unit.deserialize_state(&bytes[..bytes.len() - 8]), Err(UnitError::BadState { .. })));
    assert!(matches!(unit.do_step(0.0, 0.01), Err(UnitError::StepFailed { .. })), "wrong start time");
}

fn same_bits(a: &[cloth_core::Vec3], b: &[cloth_core::Vec3]) -> bool {
    a.iter().zip(b).all(|(p, q)| p.iter().zip(q.iter()).all(|(x, y)| x.to_bits() == y.to_bits()))
}
