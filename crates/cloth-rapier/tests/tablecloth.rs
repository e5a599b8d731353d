//! The tablecloth trick against Coulomb's law.

use cloth_rapier::{CoupledRun, CoupledScene};
use std::path::PathBuf;

fn run(velocity: f64, duration: f64) -> (CoupledRun, Vec<(f64, f64, f64)>) {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/scenes/tablecloth.toml");
    let overrides =
        vec![format!("pins.0.motion.velocity_m_s=[{velocity}, 0.0, 0.0]"), format!("simulation.duration_s={duration}")];
    let mut run = CoupledScene::load(&path, &overrides).unwrap().build().unwrap();
    let boxed = run.bodies.iter().find(|b| b.name == "box").unwrap().handle;
    let mut track = Vec::new();
    for _ in 0..run.config.steps {
        run.step().unwrap();
        let b = &run.world.bodies[boxed];
        track.push((run.cloths[run.cloth].simulation().time(), b.translation().x, b.linvel().x));
    }
    (run, track)
}

#[test]
fn a_slow_pull_carries_the_box() {
    // Slow: 0.1 m/s for 1 s, far below what friction can follow (mu g = 3.9 m/s^2).
    let (_, slow) = run(0.1, 1.0);
    let (_, x_slow, v_slow) = *slow.last().unwrap();
    println!("slow pull: the edge moved 0.100 m, the box {x_slow:.4} m, ends at {v_slow:.4} m/s");
    assert!((x_slow - 0.1).abs() < 0.01, "the box should travel with the cloth: {x_slow}");
}

/// Known failure (issue 9's closing note): the box slips at about 2 mu g,
/// and keeps speeding up after the cloth is gone. A particle pressed
/// between the table and the box keeps only its deepest contact (opposite
/// normals are not a crease), so the box's friction is measured against
/// the wrong normal force.
#[test]
#[ignore = "known: the box slides at 2 mu g; contacts squeezed between two opposite solids"]
fn a_yank_leaves_the_box_slipping_at_coulomb_s_rate() {
    let (mu, g) = (0.4, 9.81);
    // Fast: 4 m/s. While the cloth slides under it the box accelerates at mu g.
    let (run, fast) = run(4.0, 0.15);
    let sliding: Vec<_> = fast.iter().filter(|(t, _, _)| *t > 0.01 && *t < 0.05).collect();
    let (first, last) = (sliding[0], sliding[sliding.len() - 1]);
    let accel = (last.2 - first.2) / (last.0 - first.0);
    let (_, x_fast, v_fast) = *fast.last().unwrap();
    let cloth_left = run.cloths[run.cloth].simulation().state().x.iter().map(|p| p.x).fold(f64::INFINITY, f64::min);
    println!(
        "yank: box accelerates at {accel:.3} m/s^2 while sliding (mu g = {:.3}); after 0.15 s it moved {x_fast:.4} m at {v_fast:.3} m/s; the cloth's near edge is at x = {cloth_left:.3} m",
        mu * g
    );
    assert!((accel - mu * g).abs() < 0.1 * mu * g, "sliding acceleration {accel}, Coulomb {}", mu * g);
    assert!(cloth_left > 0.04, "the cloth left the box");
    assert!(x_fast < 0.03, "the box stays nearly in place: {x_fast}");
}
