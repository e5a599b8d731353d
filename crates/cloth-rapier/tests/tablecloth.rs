//! The tablecloth trick against Coulomb's law.

use cloth_rapier::{CoupledRun, CoupledScene};
use std::path::PathBuf;

/// One sample of the box per step.
struct Sample {
    /// Time at the end of the step, s.
    t: f64,
    /// The box's x, m, and x velocity, m/s.
    x: f64,
    v: f64,
    /// Whether the cloth touched the box during the step.
    on_cloth: bool,
    /// The x impulse the box took from cloth pressed on its sides (contact
    /// normals within 64 degrees of horizontal) during the step, N s.
    side_impulse: f64,
    /// The normal force of the cloth under the box (the other contacts), N.
    normal_force: f64,
}

fn run(velocity: f64, duration: f64) -> (CoupledRun, Vec<Sample>) {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/scenes/tablecloth.toml");
    let overrides =
        vec![format!("pins.0.motion.velocity_m_s=[{velocity}, 0.0, 0.0]"), format!("simulation.duration_s={duration}")];
    let mut run = CoupledScene::load(&path, &overrides).unwrap().build().unwrap();
    let boxed = run.bodies.iter().find(|b| b.name == "box").unwrap().handle;
    let solid = run.cloths[run.cloth].world_solids().iter().find(|s| s.body == Some(boxed)).unwrap().solid;
    let mut track = Vec::new();
    for _ in 0..run.config.steps {
        run.step().unwrap();
        let b = &run.world.bodies[boxed];
        let sim = run.cloths[run.cloth].simulation();
        let on_box = || sim.contacts().iter().filter(|c| c.collider as usize == solid);
        let on_cloth = on_box().any(|c| c.normal_force_n > 0.0);
        // The particle's impulse; the box takes the opposite.
        let side_impulse = -on_box().filter(|c| c.normal.z.abs() < 0.9).map(|c| c.impulse_n_s.x).sum::<f64>();
        let normal_force = on_box().filter(|c| c.normal.z.abs() >= 0.9).map(|c| c.normal_force_n).sum();
        let (t, x, v) = (sim.time(), b.translation().x, b.linvel().x);
        track.push(Sample { t, x, v, on_cloth, side_impulse, normal_force });
    }
    (run, track)
}

#[test]
#[ignore = "slow tier: cargo test --release -- --ignored"]
fn a_slow_pull_carries_the_box() {
    // Slow: 0.1 m/s for 1 s, far below what friction can follow (mu g = 3.9 m/s^2).
    let (_, slow) = run(0.1, 1.0);
    let last = slow.last().unwrap();
    println!("slow pull: the edge moved 0.100 m, the box {:.4} m, ends at {:.4} m/s", last.x, last.v);
    assert!((last.x - 0.1).abs() < 0.01, "the box should travel with the cloth: {}", last.x);
}

/// Yanked at 4 m/s, the cloth slides out from under the box. While it
/// does, the box slips on it: Coulomb's sliding friction `mu_b N_k` of the
/// cloth under it each step `k` of length `h` (about its weight; it
/// bounces on the squeezed cloth as it settles), plus the impulses `J_k`
/// of the cloth that rises against its rear face, so by the time `t_l`
/// the cloth leaves it, it has moved
/// `sum_k (mu_b N_k h + J_k)(t_l - t_k) / m` (`mu_b g t_l^2 / 2` for a
/// box resting with its weight only). It then drops the cloth's
/// thickness onto the table, whose friction (the average of the box's
/// 0.4 and the table's 0.2, rapier's default rule) stops it at `mu_t g`.
#[test]
#[ignore = "slow tier: cargo test --release -- --ignored"]
fn a_yank_leaves_the_box_slipping_at_coulomb_s_rate() {
    let (mu_box, mu_table, g) = (0.4, 0.5 * (0.4 + 0.2), 9.81);
    let (run, fast) = run(4.0, 0.35);
    let left = fast.iter().rposition(|s| s.on_cloth).unwrap();
    let (t_l, x_l) = (fast[left].t, fast[left].x);
    let boxed = run.bodies.iter().find(|b| b.name == "box").unwrap().handle;
    let (mass, h) = (run.world.bodies[boxed].mass(), run.config.dt_s);
    let pushed: f64 = fast[..=left].iter().map(|s| s.side_impulse * (t_l - s.t) / mass).sum();
    let coulomb = fast[..=left].iter().map(|s| mu_box * s.normal_force * h * (t_l - s.t) / mass).sum::<f64>() + pushed;
    let resting = 0.5 * mu_box * g * t_l * t_l;
    // Deceleration on the table: slope of the velocity once it has landed.
    let on_table: Vec<_> = fast[left..].iter().filter(|s| s.v > 0.02 && s.v < 0.15).collect();
    let (first, last) = (on_table[0], on_table[on_table.len() - 1]);
    let decel = (first.v - last.v) / (last.t - first.t);
    let end = fast.last().unwrap();
    let cloth_left = run.cloths[run.cloth].simulation().state().x.iter().map(|p| p.x).fold(f64::INFINITY, f64::min);
    println!(
        "yank: the cloth leaves the box at t = {t_l:.3} s after it moved {x_l:.4} m (Coulomb: {coulomb:.4} m, \
         of which {pushed:.4} m from the rear face; resting with its weight: {resting:.4} m); \
         on the table it slows at {decel:.3} m/s^2 (mu_t g = {:.3}) and stops after {:.4} m, at {:.4} m/s; \
         the cloth's near edge is at x = {cloth_left:.3} m",
        mu_table * g,
        end.x,
        end.v
    );
    // Measured: 0.0169 m against 0.0163 (3.6%; the cloth leaves the box at
    // 0.094 s). With every contact pass solved to rel_tol
    // (`solver.contacts.settling_iterations = 0`, or 8 and more) the active set
    // takes another path and the cloth leaves one step earlier: 0.0156
    // against 0.0151 (2.8%). With the table's friction on the cloth
    // decided after the solve instead: 0.0196 against 0.0193. With the box
    // inside the cloth's solve (the monolithic master, the default):
    // 0.0173 against 0.0181 (4.6%); the particles under the box are
    // squeezed against the table, so their friction on the box is the
    // squeezed particles' (after the solve, within mu N), not the solve's.
    assert!((x_l - coulomb).abs() < 0.05 * coulomb, "moved {x_l} m on the sliding cloth, Coulomb {coulomb}");
    assert!((decel - mu_table * g).abs() < 0.01 * mu_table * g, "table deceleration {decel}");
    assert!(cloth_left > 0.04 + end.x, "the cloth left the box");
    assert!(end.v.abs() < 1e-3, "the table's friction stops the box: {} m/s", end.v);
    assert!(end.x < 0.05 * (cloth_left + 0.3), "the box stays nearly in place: {} m", end.x);
}
