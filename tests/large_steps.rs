//! Large steps solved as what they are: the nonlinear implicit equation,
//! by Newton's method with a line search on the incremental potential
//! (`solver.newton.iterations > 1`), against the single linearised step.

use cloth_tests::simulation;

/// The hanging cloth (21 x 21, with drag so that it comes to rest) run for
/// 20 s at step `h`: the largest stretch at any step, the final positions
/// and the Newton counters.
fn hang(h: f64, newton: usize) -> (f64, Vec<cloth_core::Vec3>, usize, usize) {
    let overrides = [
        "panels.0.particles=[21, 21]".to_string(),
        "pins.0.nodes=[[0, 20], [20, 20]]".into(),
        "simulation.effects=[\"gravity\", \"bending\", \"damping\", \"drag\"]".into(),
        "material.drag_n_s_m3=0.5".into(),
        "solver.rel_tol=1e-6".into(),
        format!("solver.newton.iterations={newton}"),
        "solver.newton.tolerance_m=1e-5".into(),
        // One iteration is the single linearised step, not engaged on its own.
        "solver.newton.auto_trigger=0".into(),
    ];
    let o: Vec<&str> = overrides.iter().map(String::as_str).collect();
    let (mut sim, _) = simulation("hang.toml", &o);
    let (mut peak, mut corrections, mut unconverged) = (1.0f64, 0, 0);
    for _ in 0..(20.0 / h).round() as usize {
        let report = sim.step(h).unwrap();
        peak = peak.max(sim.model().max_stretch_ratio(&sim.state().x));
        if let Some(n) = report.newton {
            corrections += n.corrections;
            unconverged += usize::from(!n.converged);
        }
    }
    (peak, sim.state().x.clone(), corrections, unconverged)
}

fn largest_distance(a: &[cloth_core::Vec3], b: &[cloth_core::Vec3]) -> f64 {
    a.iter().zip(b).map(|(p, q)| (p - q).norm()).fold(0.0, f64::max)
}

/// Choi & Ko's and Baraff & Witkin's single linearised step at h = 0.2 s
/// lets the flat cloth fall `h^2 g` in its first step, whatever its links
/// say: links stretch many times their length. Newton with a line search
/// keeps the stretch at what small steps give and ends at the same rest
/// shape.
#[test]
#[ignore = "slow tier: cargo test --release -- --ignored"]
fn newton_keeps_a_large_step_as_stretched_as_small_steps() {
    let (small_peak, small_rest, ..) = hang(1.0 / 90.0, 1);
    let (single_peak, single_rest, ..) = hang(0.2, 1);
    let (newton_peak, newton_rest, corrections, unconverged) = hang(0.2, 10);
    let (single_gap, newton_gap) =
        (largest_distance(&single_rest, &small_rest), largest_distance(&newton_rest, &small_rest));
    eprintln!(
        "peak stretch: h = 1/90 s {small_peak:.4}, h = 0.2 s single step {single_peak:.3}, Newton {newton_peak:.4} \
         ({corrections} corrections in 100 steps, {unconverged} steps above tolerance); rest shape off the \
         h = 1/90 s one by {single_gap:.4} m (single step), {newton_gap:.4} m (Newton)"
    );
    // Measured 3.83 (the type-2 triples give a flat cloth bending stiffness
    // in the linearised step; the paper's pair law, none: 18.7).
    assert!(single_peak > 2.0, "the single step no longer overstretches ({single_peak}): update this test");
    assert!(newton_peak <= small_peak * 1.001, "Newton peak stretch {newton_peak} vs {small_peak} at h = 1/90 s");
    // Measured 1.03 cm at one particle of the bottom rows: the
    // buckled type-1 links' post-buckling plateau lets the wrinkles near
    // the bottom corners settle in a different pattern (20 s and 40 s at
    // h = 1/90 s agree to 2e-8 m; the pair law's gap: 0.01 cm).
    let rms = (newton_rest.iter().zip(&small_rest).map(|(p, q)| (p - q).norm_squared()).sum::<f64>()
        / small_rest.len() as f64)
        .sqrt();
    assert!(
        newton_gap < 0.011 && rms < 0.002,
        "Newton rest shape {newton_gap} m (RMS {rms} m) from the small-step one"
    );
    // The stopping rule ends most steps after a correction or two (measured
    // 149 corrections in 100 steps; the cap is 9 per step).
    assert!(corrections < 155, "{corrections} Newton corrections in 100 steps");
}

/// The sphere drape (41 x 41, 1 m, on a ball of radius 0.3 m) for 2 s at
/// step `h`: the largest stretch at any step, the final stretch, the
/// smallest distance of any particle from the ball's surface at any step
/// (from the ball's own geometry, m; negative inside), and the final
/// height of the cloth's centre particle.
fn drape(h: f64, newton: usize) -> (f64, f64, f64, f64) {
    let overrides = [
        format!("simulation.dt_s={h}"),
        format!("solver.newton.iterations={newton}"),
        "solver.newton.tolerance_m=1e-5".into(),
        "solver.rel_tol=1e-6".into(),
        "solver.newton.auto_trigger=0".into(),
    ];
    let o: Vec<&str> = overrides.iter().map(String::as_str).collect();
    let (mut sim, cfg) = simulation("drape-sphere.toml", &o);
    let (mut peak, mut clearance) = (1.0f64, f64::INFINITY);
    for _ in 0..cfg.steps {
        if sim.step(h).is_err() {
            return (f64::INFINITY, f64::INFINITY, f64::INFINITY, f64::NAN);
        }
        let x = &sim.state().x;
        peak = peak.max(sim.model().max_stretch_ratio(x));
        clearance = clearance.min(x.iter().map(|p| p.norm() - 0.3).fold(f64::INFINITY, f64::min));
    }
    let x = &sim.state().x;
    (peak, sim.model().max_stretch_ratio(x), clearance, x[x.len() / 2].z)
}

/// At h = 0.2 s the cloth meets the ball in the middle of its first step.
/// The single linearised step overstretches it (links 4.5 times their
/// length at the worst step, 1.53 at the end; 33 and tangled while
/// friction was decided after the solve); Newton iterations with the ball
/// as a penalty energy and
/// friction as a dissipation potential settle it on the ball untangled,
/// nowhere inside it, its top where small steps put it.
#[test]
#[ignore = "slow tier: cargo test --release -- --ignored"]
fn newton_drapes_a_sphere_at_large_steps() {
    let (single_peak, single_final, ..) = drape(0.2, 1);
    let (peak, final_stretch, clearance, top) = drape(0.2, 10);
    eprintln!(
        "h = 0.2 s: single step peak {single_peak:.2}, final {single_final:.2}; Newton peak {peak:.4}, final \
         {final_stretch:.4}, closest to the ball {clearance:.2e} m, top at {top:.5} m"
    );
    assert!(single_peak > 2.0, "the single step no longer overstretches ({single_peak}): update this test");
    // Measured 1.112 (the cloth wrapping the ball), 1.027 at rest (before
    // continuous collision detection held the particles whose 20 cm steps
    // cross the ball on its near side: 1.083 and 1.029).
    assert!(peak < 1.12 && final_stretch < 1.03, "stretch {peak} (peak), {final_stretch} (final)");
    // Measured 2.50 mm: nothing nearer than half the 5 mm thickness.
    assert!(clearance > 2.4e-3, "a particle {clearance} m from the ball");
    // On the offset surface (0.3 m + 5 mm), sunk g h^2 / 1000 = 0.4 mm into it.
    assert!((top - 0.305).abs() < 5e-4, "the centre rests at {top} m");
}

/// A violent event: the 21 x 21 hanging cloth's two pins jump 5 m
/// sideways in 0.1 s and stop; 6 s at h = 1/90 s.
struct PinJump {
    /// The fastest particle at the end, m/s.
    speed: f64,
    /// The largest stretch at the end.
    stretch: f64,
    /// Kinetic energy at the end, as a fraction of the kinetic and elastic
    /// energy the cloth holds when the pins stop.
    kinetic_left: f64,
    /// Steps the energy monitor flagged, those retaken as backward Euler,
    /// and those retaken with Newton iterations.
    flagged: usize,
    retaken: usize,
    retaken_with_newton: usize,
}

fn pin_jump(integrator: &str, energy_guard: bool) -> PinJump {
    let guard = format!("solver.energy_guard={energy_guard}");
    let integrator = format!("simulation.integrator=\"{integrator}\"");
    let (mut sim, cfg) = simulation(
        "hang.toml",
        &[
            "panels.0.particles=[21, 21]",
            "pins.0.nodes=[[0, 20], [20, 20]]",
            "pins.0.motion={ kind = \"keyframes\", times_s = [0.0, 0.1], offsets_m = [[0.0, 0.0, 0.0], [5.0, 0.0, 0.0]] }",
            "simulation.duration_s=6",
            &guard,
            &integrator,
            // Without the guard the cloth blows up (a link 128x its rest
            // length at 3.8 s): that is what this run shows.
            "solver.blow_up_stretch=inf",
            // The single linearised step and its guard. With the automatic
            // Newton step on, the misjudged steps of the jump take Newton
            // iterations instead, and guarded BDF2 settles more slowly
            // (2.9e-4 of E(0.1 s) left as kinetic energy after 6 s).
            "solver.newton.auto_trigger=0",
        ],
    );
    let (mut flagged, mut retaken, mut retaken_with_newton) = (0, 0, 0);
    let (mut at_stop, mut kinetic) = (f64::NAN, 0.0);
    for _ in 0..cfg.steps {
        let r = sim.step(cfg.dt_s).unwrap();
        flagged += usize::from(r.energy.is_some_and(|e| e.flagged));
        retaken += usize::from(r.retaken_as_backward_euler);
        retaken_with_newton += usize::from(r.retaken_with_newton);
        let e = r.energy.expect("implicit steps report their energy");
        kinetic = e.kinetic_j;
        if sim.time() > 0.1 + 1e-9 && at_stop.is_nan() {
            at_stop = e.kinetic_j + e.elastic_j;
        }
    }
    let speed = sim.state().v.iter().map(|v| v.norm()).fold(0.0, f64::max);
    PinJump {
        speed,
        stretch: sim.model().max_stretch_ratio(&sim.state().x),
        kinetic_left: kinetic / at_stop,
        flagged,
        retaken,
        retaken_with_newton,
    }
}

/// BDF2's single linearised step across the kink of tension-only links
/// (a link that goes slack within the step still gets the linear model's
/// compressive force) pumps energy into the violently moved cloth: without
/// the guard it ends at hundreds of m/s with links tens of times their
/// length, and the energy monitor flags those steps. (Newton's iterations
/// or Provot's two-sided springs also settle it; backward Euler's damping
/// hides it.) With the guard the flagged steps are retaken as backward
/// Euler and the cloth swings down: measured 1.6e-5 of its energy at the
/// stop left as kinetic energy after 6 s, stretch 1.071, its fastest
/// particle at 1.45 m/s, 27 steps retaken; unguarded 752 m/s, stretch 86,
/// 174 steps flagged.
#[test]
#[ignore = "slow tier: cargo test --release -- --ignored"]
fn bdf2_settles_after_a_violent_pin_jump() {
    let j = pin_jump("bdf2", true);
    eprintln!(
        "guarded: {:.3} m/s, stretch {:.4}, kinetic left {:.2e} of E(0.1 s), {} steps retaken as backward Euler",
        j.speed, j.stretch, j.kinetic_left, j.retaken
    );
    assert!(j.stretch < 1.1, "guarded BDF2: stretch {}", j.stretch);
    assert!(j.kinetic_left < 1.5e-4, "guarded BDF2 still holds {} of E(0.1 s) as kinetic energy", j.kinetic_left);
    // Backward Euler's own steps during the jump may stay flagged: the pin
    // work is estimated with the end-of-step force, poor while the pins
    // move at 50 m/s.
    assert!(j.retaken > 0, "no step retaken ({} flagged)", j.flagged);
    let j = pin_jump("bdf2", false);
    eprintln!("unguarded: {:.1} m/s, stretch {:.1}, {} steps flagged", j.speed, j.stretch, j.flagged);
    assert!(j.speed > 100.0 && j.stretch > 10.0, "unguarded BDF2 no longer blows up: {} m/s, {}", j.speed, j.stretch);
    assert!(j.flagged > 100, "the monitor flagged only {} steps of the blow-up", j.flagged);
}

/// The same pin jump under backward Euler: the monitor flags 16 of its
/// single linearised steps. Each is retaken with Newton iterations, which
/// follow the links across their kink, and none is flagged then (29
/// retaken: the retakes change the steps after them). Measured: stretch
/// 1.074 (unguarded 1.072), 3.6e-5 of the energy at the stop left as
/// kinetic energy after 6 s against 2.4e-6 unguarded, nearer the 1.7e-4
/// that backward Euler leaves at h / 10 (about): the linearised step damps
/// more.
#[test]
#[ignore = "slow tier: cargo test --release -- --ignored"]
fn backward_euler_retakes_a_flagged_step_with_newton() {
    let guarded = pin_jump("backward-euler", true);
    let unguarded = pin_jump("backward-euler", false);
    for (name, j) in [("guarded", &guarded), ("unguarded", &unguarded)] {
        eprintln!(
            "{name}: {:.3} m/s, stretch {:.4}, kinetic left {:.2e} of E(0.1 s), {} flagged, {} retaken with Newton",
            j.speed, j.stretch, j.kinetic_left, j.flagged, j.retaken_with_newton
        );
    }
    assert!(unguarded.flagged > 0 && unguarded.retaken_with_newton == 0, "unguarded: {} flagged", unguarded.flagged);
    assert!(guarded.retaken_with_newton > 0 && guarded.retaken == 0, "{} retaken", guarded.retaken_with_newton);
    assert_eq!(guarded.flagged, 0, "a retaken step still creates energy");
    assert!(guarded.stretch < 1.08, "guarded: stretch {}", guarded.stretch);
}

/// A ball (r = 8 cm) driven down into a cloth pinned at its corners at
/// 2 m/s, then held (backward Euler, h = 5 ms, the mass-ratio case of
/// `cloth study stability` with the ball prescribed): Newton converges
/// at every step. Its line search once saw only the iterate's contacts:
/// from an iterate just off the ball a full correction stepped particles
/// deep into it, the next pushed them out past the thickness, and Newton
/// alternated between the two (measured before: 4 of 100 steps
/// unconverged after 29 corrections, residual up to 3.9 mm, 10.6
/// corrections a step; now none, 7.1 a step).
#[test]
fn newton_converges_while_a_solid_presses_into_the_cloth() {
    const SCENE: &str = r#"
[simulation]
integrator = "backward-euler"
dt_s = 0.005
duration_s = 0.5
effects = ["gravity", "bending", "damping"]

[solver]
rel_tol = 1e-8
max_iter = 2000

[solver.newton]
iterations = 30

[material]
areal_density_kg_m2 = 0.1
tensile_stiffness_n_m = 500.0
flexural_rigidity_n_m = 1e-5
buckling_stiffness_n_m = 500.0
damping_n_s_m = 0.05

[[panels]]
particles = [13, 13]
size_m = [0.6, 0.6]
origin_m = [-0.3, -0.3, 0.0]

[[pins]]
nodes = [[0, 0], [12, 0], [0, 12], [12, 12]]

[[colliders]]
shape = { kind = "ball", radius_m = 0.08 }
position_m = [0.03, -0.02, 0.2]
friction = 0.3
motion = { kind = "keyframes", times_s = [0.0, 0.1, 0.3], offsets_m = [[0.0, 0.0, 0.0], [0.0, 0.0, -0.2], [0.0, 0.0, -0.21]] }
"#;
    let (model, cfg) = cloth_core::scene::Scene::parse(SCENE, &[]).unwrap().build().unwrap();
    let mut sim = cfg.simulation(model);
    let (mut unconverged, mut corrections, mut worst) = (0, 0, 0.0f64);
    for _ in 0..cfg.steps {
        let n = sim.step(cfg.dt_s).unwrap().newton.unwrap();
        unconverged += usize::from(!n.converged);
        corrections += n.corrections;
        worst = worst.max(n.residual_m);
    }
    let mean = corrections as f64 / cfg.steps as f64;
    eprintln!("{unconverged} steps unconverged, {mean:.2} corrections a step, worst residual {worst:.2e} m");
    assert_eq!(unconverged, 0, "worst residual {worst} m");
    assert!(sim.max_penetration() < 1e-4, "a particle {} m inside the ball", sim.max_penetration());
}

/// `solver.newton.trigger`: Newton only on steps whose linearised tension
/// is off by more than the trigger. Where no step is, the run is the
/// single linearised step's to the bit (the sphere drape, contacts and
/// friction in the solve included); a ball hitting a curtain at 3 m/s
/// at 1/90 s is (`cloth study stability`, the known-defect rows of the
/// single step against these).
#[test]
fn newton_trigger_leaves_steps_it_does_not_trigger_alone() {
    for scene in ["hang.toml", "drape-sphere.toml"] {
        let run = |overrides: &[&str]| {
            let (mut sim, cfg) = simulation(scene, overrides);
            for _ in 0..30 {
                let report = sim.step(cfg.dt_s).unwrap();
                assert!(report.newton.is_none() || overrides.is_empty(), "{scene}: a step triggered Newton");
            }
            sim.state().x.clone()
        };
        let single = run(&[]);
        let untriggered = run(&["solver.newton.iterations=10", "solver.newton.trigger=0.5"]);
        assert!(cloth_tests::same_bits(&single, &untriggered), "{scene}: not the single step's bits");
    }
}

/// A ball striking a fine curtain (1 cm links) at 2 m/s, 1/90 s a step:
/// the single linearised step has no sideways stiffness in a link at
/// rest, so the particles the ball hits move alone and their links
/// stretch by about `sqrt(1 + (v h / L)^2)`. By default
/// (`solver.newton.auto_trigger` = 0.5) the hit's first step takes Newton
/// iterations, that step alone; at 0.25 three steps do. Newton on every
/// step gives what 1 ms steps give (1.138 against 1.132). Nothing is
/// left inside the ball.
#[test]
fn a_struck_fine_cloth_takes_newton_iterations_where_it_is_struck() {
    const SCENE: &str = r#"
[simulation]
integrator = "bdf2"
dt_s = 0.011111111111111112
duration_s = 0.1
effects = ["gravity", "bending", "damping"]

[solver]
rel_tol = 1e-3

[material]
areal_density_kg_m2 = 0.15
tensile_stiffness_n_m = 200.0
flexural_rigidity_n_m = 1e-5
buckling_stiffness_n_m = 200.0
damping_n_s_m = 0.02

[[panels]]
particles = [31, 31]
size_m = [0.3, 0.3]
origin_m = [-0.15, 0.0, 0.0]
u_axis = [1.0, 0.0, 0.0]
v_axis = [0.0, 0.0, 1.0]

[[pins]]
nodes = [[0, 30], [10, 30], [20, 30], [30, 30]]

[collision]
thickness_m = 0.005

[[colliders]]
shape = { kind = "ball", radius_m = 0.05 }
position_m = [0.0, -0.08, 0.12]
friction = 0.3
motion = { kind = "linear", velocity_m_s = [0.0, 2.0, 0.0] }
"#;
    let run = |overrides: &[String]| {
        let (model, cfg) = cloth_core::scene::Scene::parse(SCENE, overrides).unwrap().build().unwrap();
        let mut sim = cfg.simulation(model);
        let (mut peak, mut struck, mut newton) = (1.0f64, 0u64, 0u64);
        let mut penetration = 0.0f64;
        for _ in 0..cfg.steps {
            let report = sim.step(cfg.dt_s).unwrap();
            peak = peak.max(sim.model().max_stretch_ratio(&sim.state().x));
            penetration = penetration.max(sim.max_penetration());
            if let Some(n) = report.newton {
                newton += 1;
                struck += u64::from(n.struck);
                assert!(!n.automatic, "engaged for the run");
            }
        }
        (peak, struck, newton, penetration, cfg.steps)
    };
    let (single, _, single_newton, _, _) = run(&["solver.newton.auto_trigger=0".into()]);
    let (peak, struck, newton, penetration, steps) = run(&[]);
    let (finer, finer_struck, ..) = run(&["solver.newton.auto_trigger=0.25".into()]);
    let (small, ..) = run(&["simulation.dt_s=1e-3".into(), "solver.newton.auto_trigger=0".into()]);
    eprintln!(
        "peak stretch: single step {single:.3}, default {peak:.3} ({struck} of {steps} steps struck), \
         trigger 0.25 {finer:.3} ({finer_struck} struck), h = 1 ms {small:.3}; penetration {penetration:.2e} m"
    );
    assert_eq!(single_newton, 0);
    assert_eq!(newton, struck);
    // Measured 1.572, 1.339 (the hit's first step), 1.245 (3 steps), 1.132.
    assert!(single > 1.5, "the single step no longer overstretches ({single}): update this test");
    assert!((1..=2).contains(&struck) && peak < 1.36, "{peak}, {struck} steps struck");
    assert!(finer_struck > struck && finer < 1.26, "{finer}, {finer_struck} steps struck");
    assert!(small < 1.14, "{small}");
    assert!(penetration < 1e-3, "{penetration}");
}

/// What the energy monitor saw of an explicit run: windows flagged, the
/// stretch at the end of the first flagged one (`NAN`: none) and the steps
/// from it to the run's end, the largest stretch, whether the run stopped
/// on a non-finite state, and reports at steps that are not a multiple of
/// `ENERGY_WINDOW` (none expected).
#[derive(Debug)]
struct Watched {
    flagged: usize,
    first: f64,
    steps_after_first: u64,
    worst: f64,
    non_finite: bool,
    misplaced: usize,
}

/// Runs `hang.toml` (21 x 21, Provot's springs, symplectic Euler) at step
/// `h` for 1 s or until a step fails.
fn explicit_hang(h: f64) -> Watched {
    let (mut sim, _) = simulation(
        "hang.toml",
        &[
            "panels.0.particles=[21, 21]",
            "pins.0.nodes=[[0, 20], [20, 20]]",
            "simulation.model=\"provot\"",
            "simulation.integrator=\"symplectic-euler\"",
            // The blow-up itself is what the monitor is watched on.
            "solver.blow_up_stretch=inf",
        ],
    );
    let mut w =
        Watched { flagged: 0, first: f64::NAN, steps_after_first: 0, worst: 0.0, non_finite: false, misplaced: 0 };
    for _ in 0..(1.0 / h).round() as u64 {
        w.steps_after_first += u64::from(w.flagged > 0);
        let r = match sim.step(h) {
            Ok(r) => r,
            Err(e) => {
                w.non_finite = matches!(e, cloth_core::StepError::NonFinite { .. });
                break;
            }
        };
        let stretch = sim.model().max_stretch_ratio(&sim.state().x);
        w.worst = w.worst.max(stretch);
        if let Some(e) = r.energy {
            w.misplaced += usize::from(!sim.state().steps.is_multiple_of(cloth_core::ENERGY_WINDOW));
            if e.flagged && w.flagged == 0 {
                w.first = stretch;
            }
            w.flagged += usize::from(e.flagged);
        }
    }
    w
}

/// An explicit step beyond its stability limit multiplies the cloth's
/// energy every step, and a run may stay finite all along (the 101 x 101
/// drape at 0.4 ms with Provot's springs reached a stretch of 1.9e93 and
/// exited 0). The explicit integrators' energy windows flag every run
/// that blows up, well before it overflows, and none at the steps that do
/// not. Measured on this cloth: stable to 1.1 ms (stretch 1.283 at every
/// step size), blown up from 1.2 ms; the first flagged window came 79-289
/// steps before the state overflowed.
#[test]
fn explicit_steps_beyond_their_stability_limit_are_flagged() {
    for h in [2e-4, 5e-4, 1e-3, 1.1e-3] {
        let w = explicit_hang(h);
        eprintln!("h = {h:e} s: {w:?}");
        assert_eq!(w.misplaced, 0);
        assert!(w.flagged == 0 && w.worst < 1.3 && !w.non_finite, "stable step {h} s: {w:?}");
    }
    for h in [1.2e-3, 1.4e-3, 1.8e-3, 2e-3, 4e-3] {
        let w = explicit_hang(h);
        eprintln!("h = {h:e} s: {w:?}");
        assert_eq!(w.misplaced, 0);
        assert!(w.worst > 100.0 || w.non_finite, "step {h} s was meant to blow up: {w:?}");
        assert!(w.flagged > 0, "step {h} s blew up unflagged: {w:?}");
        assert!(w.steps_after_first >= 4 * cloth_core::ENERGY_WINDOW, "step {h} s flagged late: {w:?}");
    }
}

/// Steps `sim` `steps` times at `h` (calling `before_step` first each
/// time) and hands each explicit energy window's report to `window` with
/// the energy in play over it: the kinetic and elastic energies at both
/// ends and the works' magnitudes (the first window, which has no report
/// before it, is only checked for a flag).
fn energy_windows(
    sim: &mut cloth_core::Simulation,
    (h, steps): (f64, u64),
    mut before_step: impl FnMut(&mut cloth_core::Simulation),
    mut window: impl FnMut(&cloth_core::EnergyReport, f64),
) {
    let mut before = None;
    for _ in 0..steps {
        before_step(sim);
        let r = sim.step(h).unwrap();
        let Some(e) = r.energy else { continue };
        assert!(!e.flagged, "t = {}: {e:?}", sim.time());
        if let Some((k0, e0)) = before {
            let works = e.pin_work_j.abs() + e.external_work_j.abs() + e.contact_work_j.abs();
            window(&e, k0 + e0 + e.kinetic_j + e.elastic_j + works);
        }
        before = Some((e.kinetic_j, e.elastic_j));
    }
}

/// The explicit integrators' energy windows balance the work done on the
/// cloth: a flag (16 x 11) in a gusty wind with its pinned edge shaken up
/// and down at 5 Hz, classic RK4 at 0.2 ms (far inside its stability
/// limit), no dampers, so the energy changes by the wind's and the pins'
/// work alone. Each window's gain stays within `TOL` of the energy in play
/// while the wind's and the pins' works are each far larger: leaving
/// either out of the balance fails.
#[test]
fn explicit_energy_windows_balance_the_work_of_wind_and_pins() {
    const TOL: f64 = 1.5e-4;
    let (mut sim, cfg) = simulation(
        "flag.toml",
        &[
            "panels.0.particles=[16, 11]",
            "simulation.integrator=\"rk4\"",
            "simulation.dt_s=2e-4",
            "simulation.duration_s=0.5",
            "simulation.effects=[\"gravity\", \"wind\", \"aerodynamics\"]",
            "pins.0.motion={ kind = \"oscillate\", amplitude_m = [0.0, 0.0, 0.02], frequency_hz = 5.0 }",
        ],
    );
    // Per window, of the energy in play: |gain|, |wind's work|, |pins' work|.
    let (mut gains, mut wind, mut pins) = (Vec::new(), Vec::new(), Vec::new());
    energy_windows(
        &mut sim,
        (cfg.dt_s, cfg.steps),
        |_| {},
        |e, in_play| {
            gains.push(e.gain_j.abs() / in_play);
            wind.push(e.external_work_j.abs() / in_play);
            pins.push(e.pin_work_j.abs() / in_play);
        },
    );
    let median = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let worst = gains.iter().copied().fold(0.0, f64::max);
    let (gain, wind, pins) = (median(&mut gains), median(&mut wind), median(&mut pins));
    eprintln!(
        "of the energy in play, median window: gain {gain:.2e} (worst {worst:.2e}), wind's work {wind:.2e}, pins' {pins:.2e}"
    );
    assert!(worst < TOL, "a window's gain is {worst} of the energy in play");
    assert!(wind > 10.0 * gain && pins > 10.0 * gain, "works too small to test the balance: wind {wind}, pins {pins}");
}

/// The same balance with the control's forces, the one load that comes and
/// goes: the hanging cloth (11 x 11, Provot's springs, no dampers) pushed
/// sideways for 0.1 s, then let go, under RK4 at 0.2 ms. Every window
/// balances to `TOL` of the energy in play (measured 4.1e-10), the push's
/// windows (its work up to 3.3e-2 of it) and those after it: with the
/// push still counted once it stopped, 5.2e-4.
#[test]
fn explicit_energy_windows_balance_a_push_that_stops() {
    const TOL: f64 = 5e-10;
    let (mut sim, cfg) = simulation(
        "hang.toml",
        &[
            "panels.0.particles=[11, 11]",
            "pins.0.nodes=[[0, 10], [10, 10]]",
            "simulation.model=\"provot\"",
            "simulation.integrator=\"rk4\"",
            "simulation.dt_s=2e-4",
            "simulation.duration_s=0.3",
            "simulation.effects=[\"gravity\"]",
        ],
    );
    let push = vec![cloth_core::Vec3::new(2e-3, 0.0, 0.0); sim.model().particle_count()];
    sim.set_external_forces(&push).unwrap();
    let (mut worst, mut pushed_work) = (0.0f64, 0.0f64);
    let stop = |sim: &mut cloth_core::Simulation| {
        if sim.time() >= 0.1 {
            sim.clear_external_forces();
        }
    };
    energy_windows(&mut sim, (cfg.dt_s, cfg.steps), stop, |e, in_play| {
        worst = worst.max(e.gain_j.abs() / in_play);
        pushed_work = pushed_work.max(e.external_work_j.abs() / in_play);
    });
    eprintln!("of the energy in play: gain up to {worst:.2e}; the push's work up to {pushed_work:.2e} of a window's");
    assert!(worst < TOL, "a window's gain is {worst} of the energy in play");
}

/// A restored snapshot starts a new energy window: a simulation pushed
/// for ten steps, then put back to another's state at the same step
/// count, balances its next window from that state (its gain as small as
/// the unpushed run's) and reports the same energies, bit for bit.
#[test]
fn a_restored_snapshot_starts_a_new_energy_window() {
    let overrides = [
        "panels.0.particles=[11, 11]",
        "pins.0.nodes=[[0, 10], [10, 10]]",
        "simulation.model=\"provot\"",
        "simulation.integrator=\"rk4\"",
        "simulation.effects=[\"gravity\"]",
    ];
    let h = 2e-4;
    let window = cloth_core::ENERGY_WINDOW as usize;
    let (mut plain, _) = simulation("hang.toml", &overrides);
    for _ in 0..10 {
        plain.step(h).unwrap();
    }
    let snapshot = plain.snapshot();
    let finish = |sim: &mut cloth_core::Simulation| {
        (10..window - 1).for_each(|_| assert!(sim.step(h).unwrap().energy.is_none()));
        sim.step(h).unwrap().energy.expect("a report at the window's end")
    };
    let expected = finish(&mut plain);
    let (mut pushed, _) = simulation("hang.toml", &overrides);
    let push = vec![cloth_core::Vec3::new(0.0, 2e-3, 0.0); pushed.model().particle_count()];
    pushed.set_external_forces(&push).unwrap();
    for _ in 0..10 {
        pushed.step(h).unwrap();
    }
    pushed.clear_external_forces();
    pushed.restore(&snapshot).unwrap();
    let got = finish(&mut pushed);
    let in_play = got.kinetic_j + got.elastic_j;
    eprintln!(
        "window's gain: {:.2e} of the energy at its end (unpushed run {:.2e})",
        got.gain_j / in_play,
        expected.gain_j / in_play
    );
    assert_eq!(
        (got.kinetic_j.to_bits(), got.elastic_j.to_bits(), got.gravitational_j.to_bits()),
        (expected.kinetic_j.to_bits(), expected.elastic_j.to_bits(), expected.gravitational_j.to_bits())
    );
    // Measured 6.8e-12; without the new window 2.6e-2.
    assert!(got.gain_j.abs() < 1e-11 * in_play && !got.flagged, "{got:?}");
}

/// With the scene's defaults, the three large steps that the single
/// linearised step overstretched hold: the run sees its steps are large
/// for the material (`k h^2 / m` above `AUTO_NEWTON_MIN_K_H2_M`, and the
/// first step's tension misjudged by more than `auto_trigger`) and takes
/// Newton iterations from then on; each ends where small steps do
/// (measured: 1.1189, 1.0002, 1.0275 against 1.1191, 1.0003, 1.0186; the
/// drape was 1.0282 before continuous collision detection). At
/// h = 1/90 s the fixtures never check (`k h^2 / m` 395). Volino's
/// membrane triangles count in `k h^2 / m` and his links (without
/// stiffness) measure the misjudged stretch: 1.1070, 1.0003, 1.0332
/// against 1.0989, 1.0003, 1.0189 (before, Newton never engaged for his
/// model: peaks 75, 25 and 4.8 at the first steps; ends 1.1115, 1.0042,
/// 1.0340).
#[test]
#[ignore = "slow tier: cargo test --release -- --ignored"]
fn defaults_hold_at_large_steps() {
    const VOLINO: &str = "simulation.model=\"volino\"";
    /// Scene, overrides, step (s), duration (s), final stretch at h = 1/90 s, tolerance.
    type Case<'a> = (&'a str, &'a [&'a str], f64, f64, f64, f64);
    let cases: [Case; 6] = [
        ("hang.toml", &[], 1.0, 20.0, 1.1191, 0.011),
        ("hang.toml", &["material.tensile_stiffness_n_m=1e5"], 0.2, 4.0, 1.0003, 0.011),
        ("drape-sphere.toml", &[], 0.2, 4.0, 1.0186, 0.011),
        ("hang.toml", &[VOLINO], 1.0, 20.0, 1.0989, 0.011),
        ("hang.toml", &["material.tensile_stiffness_n_m=1e5", VOLINO], 0.2, 4.0, 1.0003, 0.011),
        ("drape-sphere.toml", &[VOLINO], 0.2, 4.0, 1.0189, 0.015),
    ];
    for (scene, extra, h, duration, small_step, tolerance) in cases {
        let mut overrides: Vec<String> = extra.iter().map(|s| s.to_string()).collect();
        overrides.push(format!("simulation.dt_s={h}"));
        let o: Vec<&str> = overrides.iter().map(String::as_str).collect();
        let (mut sim, _) = simulation(scene, &o);
        let mut automatic = 0;
        for _ in 0..(duration / h).round() as usize {
            automatic += usize::from(sim.step(h).unwrap().newton.is_some_and(|n| n.automatic));
        }
        let stretch = sim.model().max_stretch_ratio(&sim.state().x);
        println!(
            "{scene} {extra:?} at h = {h} s: final stretch {stretch:.4} (h = 1/90 s: {small_step}), {automatic} steps with Newton"
        );
        let engaged = sim.integrator_memory().get("newton_engaged") == Some(1.0);
        assert!(engaged && automatic > 0, "{scene}: Newton not engaged");
        assert!(stretch < small_step + tolerance, "{scene}: stretch {stretch} against {small_step} at small steps");
        if extra.is_empty() || extra == [VOLINO] {
            // The fixture's own material at its own step is not even checked.
            let at_small = cloth_core::AUTO_NEWTON_MIN_K_H2_M / sim.model().stiffest_per_mass();
            assert!((1.0f64 / 90.0).powi(2) < at_small, "{scene}: 1/90 s would be checked");
        }
    }
}
