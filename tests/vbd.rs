//! The vertex solver (`vbd`) in fixture scenes: no particle inside a
//! solid, Coulomb's friction angle on the incline, the same bits with one
//! and two threads, and a hanging strip's static sag against the
//! continuum.

use cloth_core::contacts::FRICTION_SMOOTHING_M_S;
use cloth_core::{Simulation, Vec3};
use cloth_tests::{same_bits, simulation};

const VBD: &str = "simulation.integrator=\"vbd\"";

/// Overrides that tilt the incline fixture's plane (and the cloth lying 5
/// mm above it) to `deg` degrees, with friction `mu`, under `vbd`.
fn incline(deg: f64, mu: f64) -> Vec<String> {
    let (s, c) = deg.to_radians().sin_cos();
    let th = 0.005;
    vec![
        VBD.into(),
        // A coarse cloth and sweeps enough for the step to converge: what
        // is checked is the friction law, not the sweeps' convergence
        // (docs/results/vbd.md).
        "panels.0.particles=[3, 3]".into(),
        "solver.vbd.iterations=50".into(),
        format!("colliders.0.rotation_deg=[{deg}, 0.0, 0.0]"),
        format!("colliders.0.friction={mu}"),
        format!("panels.0.v_axis=[0.0, {c}, {s}]"),
        format!("panels.0.origin_m=[-0.25, {}, {}]", -s * th, c * th),
    ]
}

/// Mean displacement of the cloth down the slope after `duration` s, m,
/// and the deepest any particle went into the plane.
fn slide(deg: f64, mu: f64, duration: f64) -> (f64, f64) {
    let o = incline(deg, mu);
    let o: Vec<&str> = o.iter().map(String::as_str).collect();
    let (mut sim, cfg) = simulation("incline.toml", &o);
    let start = mean(&sim.state().x);
    let steps = (duration / cfg.dt_s).round() as usize;
    let mut deepest = 0.0_f64;
    for _ in 0..steps {
        sim.step(cfg.dt_s).unwrap();
        deepest = deepest.max(sim.max_penetration());
    }
    let (s, c) = deg.to_radians().sin_cos();
    let downhill = Vec3::new(0.0, -c, -s);
    ((mean(&sim.state().x) - start).dot(&downhill), deepest)
}

fn mean(x: &[Vec3]) -> Vec3 {
    x.iter().sum::<Vec3>() / x.len() as f64
}

/// Coulomb on the incline: the cloth holds where `tan theta < mu` but
/// for the smoothed friction's creep (below 1 mm/s), and slides at `g (sin theta - mu cos theta)` where
/// `tan theta > mu`, from the distance slid in 1 s against backward
/// Euler's discrete `a h^2 N (N + 1) / 2`. Measured: the creep to
/// 7e-4 of the smoothing's, the accelerations to 3.4e-4 of Coulomb's.
#[test]
fn incline_holds_below_the_friction_angle_and_slides_at_coulombs_rate_above() {
    let g = 9.81;
    for (deg, mu) in [(20.0, 0.5), (25.0, 0.5), (10.0, 0.2)] {
        let (s, deepest) = slide(deg, mu, 1.0);
        // The smoothing's creep: `mu N f1(v) = m g sin theta`, `f1(v) =
        // 2 v / eps - v^2 / eps^2`, so `v = eps (1 - sqrt(1 - tan theta / mu))`.
        let creep = FRICTION_SMOOTHING_M_S * (1.0 - (1.0 - f64::to_radians(deg).tan() / mu).sqrt());
        eprintln!("vbd: incline {deg} deg, mu {mu}: slid {s:.4e} m in 1 s, the smoothing's creep {creep:.4e} m/s");
        assert!((s / creep - 1.0).abs() < 1e-3, "tan {deg} < {mu}: the cloth should creep {creep} m/s, slid {s} m");
        assert!(deepest <= 1e-12, "a particle went {deepest} m into the plane");
    }
    for (deg, mu) in [(35.0, 0.5), (30.0, 0.3), (45.0, 0.8), (20.0, 0.0)] {
        let (sn, cs) = f64::to_radians(deg).sin_cos();
        let expected = g * (sn - mu * cs);
        let steps = 90.0;
        let (s, deepest) = slide(deg, mu, 1.0);
        let a = 2.0 * s / (1.0 + 1.0 / steps);
        let error = a / expected - 1.0;
        eprintln!("vbd: incline {deg} deg, mu {mu}: a = {a:.5} m/s^2, Coulomb {expected:.5} ({error:+.1e})");
        assert!(error.abs() <= 5e-4, "{deg} deg, mu {mu}: a = {a}, {expected}");
        assert!(deepest <= 1e-12, "a particle went {deepest} m into the plane");
    }
}

/// Drapes on a ball, a box, a table and a mesh, and a ball swept through
/// a curtain: no particle is ever inside a solid, and the cloth rests on it.
#[test]
fn drapes_stay_outside_their_solids() {
    for (scene, particles, fewest) in [
        ("drape-sphere.toml", "panels.0.particles=[21, 21]", 100),
        ("drape-cube.toml", "panels.0.particles=[21, 21]", 80),
        ("table.toml", "panels.0.particles=[21, 21]", 80),
        ("drape-mesh.toml", "panels.0.particles=[21, 21]", 100),
        ("sweep.toml", "panels.0.particles=[17, 17]", 5),
    ] {
        let (mut sim, cfg) = simulation(scene, &[VBD, particles, "simulation.duration_s=1.5"]);
        let (mut deepest, mut contacts) = (0.0_f64, 0);
        for _ in 0..cfg.steps {
            let r = sim.step(cfg.dt_s).unwrap();
            deepest = deepest.max(sim.max_penetration());
            contacts = contacts.max(r.contacts.contacts);
        }
        eprintln!("vbd {scene}: deepest {deepest:.2e} m, up to {contacts} contacts");
        assert!(deepest <= 1e-12, "{scene}: a particle was {deepest} m inside a solid");
        assert!(contacts >= fewest, "{scene}: only {contacts} contacts, expected at least {fewest}");
    }
}

/// A drape with self-collision and friction, run on pools of one and two
/// threads: the same bits.
#[test]
fn one_and_two_threads_give_the_same_bits() {
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| {
            let (mut sim, cfg): (Simulation, _) =
                simulation("fold.toml", &[VBD, "panels.0.particles=[21, 21]", "simulation.duration_s=0.5"]);
            for _ in 0..cfg.steps {
                sim.step(cfg.dt_s).unwrap();
            }
            sim.state().clone()
        })
    };
    let (one, two) = (run(1), run(2));
    assert!(same_bits(&one.x, &two.x) && same_bits(&one.v, &two.v));
}
