//! A ball dropped into a hammock comes to rest on it; the posts carry cloth
//! plus ball; no particle enters the ball or the posts; the monolithic
//! master solves the cloth once a step.

use cloth_core::Vec3;
use cloth_rapier::CoupledScene;
use std::path::PathBuf;

fn fixture(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/scenes").join(name)
}

#[test]
#[ignore = "slow tier: cargo test --release -- --ignored"]
fn the_hammock_holds_the_ball_and_the_posts_carry_both() {
    let scene = CoupledScene::load(&fixture("hammock.toml"), &[]).unwrap();
    let mut run = scene.build().unwrap();
    let ball = run.bodies.iter().find(|b| b.name == "ball").unwrap().handle;
    let mut passes = 0;
    let window = 45usize; // the last half second
    let (mut carried, mut z) = (Vec3::zeros(), Vec::new());
    for step in 0..run.config.steps {
        let report = run.step().unwrap();
        passes += report.iterations;
        let rb = &run.world.bodies[ball];
        z.push(rb.center_of_mass().z);
        if step % 30 == 0 {
            println!(
                "step {step}: ball z {:.6} passes {} residual {:.2e}",
                rb.center_of_mass().z,
                report.iterations,
                report.residual
            );
        }
        if step + window as u64 >= run.config.steps {
            let cloth = run.cloths[run.cloth].simulation();
            carried -= (0..cloth.model().pins().len()).map(|k| cloth.pin_reaction(k)).sum::<Vec3>() / window as f64;
        }
    }
    let cloth = run.cloths[run.cloth].simulation();
    let model = cloth.model();
    let g = 9.81;
    let cloth_weight = model.masses().iter().sum::<f64>() * g;
    let ball_weight = run.world.bodies[ball].mass() * g;
    let h = run.config.dt_s;
    let last = &z[z.len() - window..];
    let (lo, hi) = last.iter().fold((f64::MAX, f64::MIN), |(a, b), &v| (a.min(v), b.max(v)));
    let amplitude = (hi - lo) / 2.0;
    let drift = (last[window - 1] - last[0]) / (window as f64 * h);
    let weight = cloth_weight + ball_weight;
    println!(
        "after {:.2} s: ball at z {:.4} m, bobbing {amplitude:.2e} m, drift {drift:.1e} m/s over the last {window} steps; \
         pins carry {:.5} N (mean over them) of {weight:.5} N (cloth {cloth_weight:.5} + ball {ball_weight:.5}); \
         {:.2} passes/step; penetration {:.2e} m",
        cloth.time(),
        z.last().unwrap(),
        carried.z,
        passes as f64 / run.config.steps as f64,
        cloth.max_penetration()
    );
    let speed = run.world.bodies[ball].linvel().length();
    println!("ball speed at the end {speed:.2e} m/s");
    assert!(speed < 7e-4, "the ball still moves at {speed} m/s");
    assert!(amplitude < 4e-5, "the ball still bobs by {amplitude} m");
    assert!(*z.last().unwrap() < 1.0, "the ball rests below the posts' height");
    let rel = (carried.z - weight).abs() / weight;
    assert!(rel < 5e-5, "pins carry {} N, cloth + ball weigh {weight} N", carried.z);
    assert_eq!(passes, run.config.steps as usize, "one solve a step");
    assert!(cloth.max_penetration() < model.contact_thickness());
}
