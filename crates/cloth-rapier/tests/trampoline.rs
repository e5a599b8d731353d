//! A box 1x, 10x and 100x the cloth's mass dropped on a cloth held at its
//! four corners (`fixtures/scenes/trampoline.toml`) comes to rest: the
//! monolithic master solves the cloth once a step, the box ends still,
//! no particle enters it, and the corners carry cloth plus box.

use cloth_core::Vec3;
use cloth_rapier::CoupledScene;
use std::path::PathBuf;

fn fixture(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/scenes").join(name)
}

#[test]
#[ignore = "slow tier: cargo test --release -- --ignored"]
fn a_box_of_any_weight_comes_to_rest_on_the_trampoline() {
    for mass in [0.2, 2.0, 20.0] {
        let scene = CoupledScene::load(&fixture("trampoline.toml"), &[format!("bodies.0.mass_kg={mass}")]).unwrap();
        let mut run = scene.build().unwrap();
        let body = run.bodies.iter().find(|b| b.name == "box").unwrap().handle;
        let window = 45u64; // the last half second
        let (mut solves, mut carried) = (0, Vec3::zeros());
        for step in 0..run.config.steps {
            solves += run.step().unwrap().iterations;
            if step + window >= run.config.steps {
                let cloth = run.cloths[run.cloth].simulation();
                carried -= (0..cloth.model().pins().len()).map(|k| cloth.pin_reaction(k)).sum::<Vec3>() / window as f64;
            }
        }
        let cloth = run.cloths[run.cloth].simulation();
        let g = 9.81;
        let weight = (cloth.model().masses().iter().sum::<f64>() + run.world.bodies[body].mass()) * g;
        let speed = run.world.bodies[body].linvel().length();
        let rel = (carried.z - weight) / weight;
        let penetration = cloth.max_penetration();
        println!(
            "box {mass} kg: speed {speed:.2e} m/s after {:.1} s; corners carry {:.5} N of {weight:.5} N ({rel:+.2e}); \
             {solves} solves in {} steps; deepest in a solid {penetration:.2e} m",
            cloth.time(),
            carried.z,
            run.config.steps
        );
        assert!(speed < 5e-4, "box {mass} kg still moves at {speed} m/s");
        assert!(rel.abs() < 2e-4, "box {mass} kg: the corners carry {} N of {weight} N", carried.z);
        assert_eq!(solves, run.config.steps as usize, "one solve a step");
        assert!(penetration <= cloth.model().contact_thickness());
    }
}
