//! Physics of the Choi-Ko model at the level of a whole cloth: forces against
//! energies, Jacobians against forces, momentum, free fall, resolution
//! independence, stability at large steps, determinism and rollback.

use cloth_core::terms::SystemTerms;
use cloth_core::testing::eval_link;
use cloth_core::testing::{SystemBuffers, assemble};
use cloth_core::{
    BendingLaw, ClothModel, Compression, Effects, GridPanel, IntegratorKind, LinkType, Mat3, Material, ModelKind,
    ModelSpec, PreconditionerKind, Simulation, SolverParams, Vec3,
};
use cloth_core::{EnergyBuffers, elastic_energy, potential_energy, total_forces};
use cloth_tests::{Rng, same_bits, simulation};

fn small_model(bending: bool, damping: bool, gravity: bool) -> ClothModel {
    small_model_of(ModelKind::ChoiKo, bending, damping, gravity)
}

fn small_model_of(kind: ModelKind, bending: bool, damping: bool, gravity: bool) -> ClothModel {
    small_model_with(
        kind,
        Effects {
            gravity: gravity.then(|| Vec3::new(0.0, 0.0, -9.81)),
            damping,
            bending,
            drag: false,
            ..Effects::default()
        },
    )
}

fn small_model_with(kind: ModelKind, effects: Effects) -> ClothModel {
    small_model_spec(ModelSpec { kind, effects, ..ModelSpec::default() })
}

/// Choi & Ko's model with the paper's pair law (`arc-chord`).
fn small_pair_law_model(bending: bool) -> ClothModel {
    let effects = Effects { gravity: Some(Vec3::new(0.0, 0.0, -9.81)), bending, ..Effects::default() };
    small_model_spec(ModelSpec { bending_law: Some(BendingLaw::ArcChord), effects, ..ModelSpec::default() })
}

/// The 6 x 5 test panel and material under `spec`'s model, law and effects.
fn small_model_spec(spec: ModelSpec) -> ClothModel {
    ClothModel::build(&ModelSpec {
        panels: vec![GridPanel {
            particles: [6, 5],
            size_m: [0.1, 0.08],
            origin_m: [0.0, 0.0, 0.5],
            u_axis: [1.0, 0.0, 0.0],
            v_axis: [0.0, 1.0, 0.0],
            wrap_u: false,
        }],
        material: Material { damping_n_s_m: 0.5, drag_n_s_m3: 0.3, ..Material::default() },
        pins: vec![],
        ..spec
    })
    .unwrap()
}

/// Positions with some links stretched and some compressed enough to
/// buckle (beyond the ramp), so every law branch is exercised.
fn perturbed(model: &ClothModel, rng: &mut Rng, amplitude: f64) -> Vec<Vec3> {
    let mut x: Vec<Vec3> = model.rest_positions().to_vec();
    // Crumple along u (compresses type-2 links into the arc branch) and jitter.
    for p in x.iter_mut() {
        p.x *= 0.8;
        p.z += 0.01 * (p.x * 60.0).sin();
        *p += rng.vec3() * amplitude;
    }
    x
}

/// The assembled matrix as a dense (3n x 3n) row-major array.
fn dense(bufs: &SystemBuffers, n: usize) -> Vec<f64> {
    let mut a = vec![0.0; 9 * n * n];
    for (i, j, b) in bufs.matrix.blocks() {
        for r in 0..3 {
            for c in 0..3 {
                a[(3 * i + r) * 3 * n + 3 * j + c] += b[(r, c)];
            }
        }
    }
    a
}

/// Asserts `f = -grad E` at `x` (zero velocity) by central differences,
/// to `1e-5` of the largest force.
fn assert_forces_are_energy_gradient(model: &ClothModel, x: &[Vec3]) {
    let zero = vec![Vec3::zeros(); x.len()];
    let f = total_forces(model, x, &zero, &[]);
    let scale = f.iter().map(|v| v.norm()).fold(0.0, f64::max);
    assert!(scale > 0.0);
    let h = 1e-7;
    for i in 0..x.len() {
        for c in 0..3 {
            let (mut xp, mut xm) = (x.to_vec(), x.to_vec());
            xp[i][c] += h;
            xm[i][c] -= h;
            let grad = (potential_energy(model, &xp, &[]) - potential_energy(model, &xm, &[])) / (2.0 * h);
            assert!(
                (f[i][c] + grad).abs() <= 1e-5 * scale,
                "particle {i} component {c}: f = {}, -dE/dx = {}",
                f[i][c],
                -grad
            );
        }
    }
}

#[test]
fn forces_are_minus_the_energy_gradient() {
    let mut rng = Rng(1);
    // The paper's pair law: both branches of the type-2 law and both states
    // of the tension-only type-1 links occur.
    let model = small_pair_law_model(true);
    let x = perturbed(&model, &mut rng, 2e-3);
    let kinds: Vec<(bool, bool)> = (0..model.link_count())
        .map(|k| {
            let (i, j, t) = model.link_ends(k);
            let d = (x[j] - x[i]).norm();
            let rest = (model.rest_positions()[j] - model.rest_positions()[i]).norm();
            (t == LinkType::Interlaced, d < rest)
        })
        .collect();
    assert!(kinds.contains(&(true, true)) && kinds.contains(&(false, false)) && kinds.contains(&(false, true)));
    assert_forces_are_energy_gradient(&model, &x);
    // The default arc-path law: type-1 links in tension and in compression,
    // every type-2 triple bent.
    let model = small_model(true, false, true);
    let x = perturbed(&model, &mut rng, 2e-3);
    let compressed = compressed_links(&model, &x);
    assert!(compressed > 0 && compressed < model.link_count(), "{compressed} compressed links");
    let triples = &model.elements().triples;
    let straight = |t: &cloth_core::BendTriple| {
        let [i, m, j] = t.nodes.map(|n| x[n as usize]);
        (x_dist(i, j) - x_dist(i, m) - x_dist(m, j)).abs() < 1e-12
    };
    assert!(!triples.is_empty() && !triples.iter().any(straight));
    assert_forces_are_energy_gradient(&model, &x);
}

/// The energy monitor's buffers hold no element Hessians
/// (`ElementBuffers::forces_only`): its elastic energy is still the
/// assembly's, bit for bit, for the arc-path triples and Volino's
/// membranes and bending triangles; and its buffers refuse an assembly.
#[test]
fn energy_only_buffers_give_the_assemblys_elastic_energy_bit_for_bit() {
    let mut rng = Rng(3);
    let models = [small_model(true, false, true), small_model_of(ModelKind::Volino, true, false, true)];
    for model in &models {
        assert!(!model.elements().is_empty());
        let x = perturbed(model, &mut rng, 2e-3);
        let mut system = SystemBuffers::new(model);
        assemble(model, &x, &SystemTerms::new(-1.0, 0.0, 0.0, &[]), &mut system);
        let monitor = elastic_energy(model, &x, &[], &mut EnergyBuffers::new(model));
        assert!(monitor > 0.0);
        assert_eq!(monitor.to_bits(), system.elastic_energy().to_bits());
    }
    let set = models[0].elements();
    let mut forces_only = cloth_core::testing::ElementBuffers::forces_only(set);
    let x = models[0].rest_positions();
    let refused = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        cloth_core::testing::evaluate(set, x, 1.0, 1.0, None, &mut forces_only)
    }));
    assert!(refused.is_err(), "an assembly into forces-only buffers must not pass silently");
}

fn x_dist(a: Vec3, b: Vec3) -> f64 {
    (b - a).norm()
}

/// How many type-1 links are shorter than at rest in `x`.
fn compressed_links(model: &ClothModel, x: &[Vec3]) -> usize {
    (0..model.link_count())
        .filter(|&k| {
            let (i, j, _) = model.link_ends(k);
            (x[j] - x[i]).norm() < (model.rest_positions()[j] - model.rest_positions()[i]).norm()
        })
        .count()
}

/// Finite-difference Jacobian of the total force with respect to x (or v),
/// compared with the assembled matrix `A = M - c_v D - c_x K` at c = -1.
fn jacobian_error(model: &ClothModel, x: &[Vec3], v: &[Vec3], wrt_velocity: bool, dropped: &Mat3Sum) -> f64 {
    let n = x.len();
    let mut bufs = SystemBuffers::new(model);
    let terms =
        SystemTerms::new(if wrt_velocity { 0.0 } else { -1.0 }, if wrt_velocity { -1.0 } else { 0.0 }, 0.0, &[]);
    assemble(model, x, &terms, &mut bufs);
    let mut a = dense(&bufs, n);
    for i in 0..n {
        for c in 0..3 {
            a[(3 * i + c) * 3 * n + 3 * i + c] -= model.masses()[i];
        }
    }
    // Add back the orthogonal type-2 terms the system matrix drops.
    for (i, j, b) in dropped {
        for r in 0..3 {
            for c in 0..3 {
                a[(3 * i + r) * 3 * n + 3 * j + c] += b[(r, c)];
            }
        }
    }
    let h = 1e-7;
    let mut worst: f64 = 0.0;
    let scale = a.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
    for j in 0..n {
        for c in 0..3 {
            let (mut xp, mut xm, mut vp, mut vm) = (x.to_vec(), x.to_vec(), v.to_vec(), v.to_vec());
            if wrt_velocity {
                vp[j][c] += h;
                vm[j][c] -= h;
            } else {
                xp[j][c] += h;
                xm[j][c] -= h;
            }
            let fp = total_forces(model, &xp, &vp, &[]);
            let fm = total_forces(model, &xm, &vm, &[]);
            for i in 0..n {
                for r in 0..3 {
                    let fd = (fp[i][r] - fm[i][r]) / (2.0 * h);
                    worst = worst.max((fd - a[(3 * i + r) * 3 * n + 3 * j + c]).abs() / scale);
                }
            }
        }
    }
    worst
}

type Mat3Sum = Vec<(usize, usize, Mat3)>;

/// The orthogonal term `(phi/d)(I - P)` of every compressed link (every
/// type-2 link of the paper's law, type-1 links under the arc-path law, and
/// Provot's compressed springs), as blocks of df/dx: the system matrix drops
/// it to stay positive definite.
fn dropped_compression_terms(model: &ClothModel, x: &[Vec3]) -> Mat3Sum {
    let mut out = Vec::new();
    for k in 0..model.link_count() {
        let (i, j, _) = model.link_ends(k);
        let xij = x[j] - x[i];
        let d = xij.norm();
        let u = xij / d;
        let phi = eval_link(model, k, x, &[]).force.dot(&u);
        if phi >= 0.0 {
            continue;
        }
        let ortho = (Mat3::identity() - u * u.transpose()) * (phi / d);
        out.extend([(i, j, ortho), (j, i, ortho), (i, i, -ortho), (j, j, -ortho)]);
    }
    out
}

#[test]
fn stiffness_matrix_matches_finite_differences_of_forces() {
    let mut rng = Rng(2);
    let v = vec![Vec3::zeros(); 30];
    // Type-1 only under the paper's law (tension-only links): the assembled
    // K is the exact Jacobian.
    let model = small_pair_law_model(false);
    let mut x = perturbed(&model, &mut rng, 2e-3);
    for p in x.iter_mut() {
        p.x *= 1.3; // stretch most type-1 links
    }
    let err = jacobian_error(&model, &x, &v, false, &vec![]);
    assert!(err < 1e-6, "type-1 Jacobian error {err:e}");
    // Under the arc-path law the type-1 links also resist compression: exact
    // once the orthogonal term of the compressed ones is added back.
    let model = small_model(false, false, true);
    let dropped = dropped_compression_terms(&model, &x);
    assert!(!dropped.is_empty(), "some type-1 links are compressed");
    let err = jacobian_error(&model, &x, &v, false, &dropped);
    assert!(err < 1e-6, "type-1 Jacobian error with compression {err:e}");
    // With the paper's type-2 links: exact once their dropped orthogonal term
    // is added back.
    let model = small_pair_law_model(true);
    let x = perturbed(&model, &mut rng, 2e-3);
    let dropped = dropped_compression_terms(&model, &x);
    let err = jacobian_error(&model, &x, &v, false, &dropped);
    assert!(err < 1e-6, "type-1 + type-2 Jacobian error {err:e}");
    // And without adding it back, the difference is visible (the test can fail).
    assert!(jacobian_error(&model, &x, &v, false, &vec![]) > 1e-4);
}

#[test]
fn damping_matrix_matches_finite_differences_of_forces() {
    // Link damping and particle drag together.
    let model = small_model_with(
        ModelKind::ChoiKo,
        Effects { gravity: None, damping: true, bending: true, drag: true, ..Effects::default() },
    );
    let mut rng = Rng(3);
    let x = perturbed(&model, &mut rng, 2e-3);
    let v: Vec<Vec3> = (0..x.len()).map(|_| rng.vec3()).collect();
    let err = jacobian_error(&model, &x, &v, true, &vec![]);
    assert!(err < 1e-7, "damping Jacobian error {err:e}");
}

#[test]
fn internal_forces_conserve_linear_and_angular_momentum() {
    let model = small_model(true, true, false);
    let mut rng = Rng(4);
    let x = perturbed(&model, &mut rng, 3e-3);
    let v: Vec<Vec3> = (0..x.len()).map(|_| rng.vec3()).collect();
    let f = total_forces(&model, &x, &v, &[]);
    let scale: f64 = f.iter().map(|v| v.norm()).sum();
    let net: Vec3 = f.iter().sum();
    let torque: Vec3 = x.iter().zip(&f).map(|(p, q)| p.cross(q)).sum();
    assert!(scale > 1e-3);
    assert!(net.norm() < 1e-14 * scale, "net force {net:?}");
    assert!(torque.norm() < 1e-14 * scale, "net torque {torque:?}");
}

fn tight_solver() -> SolverParams {
    SolverParams {
        rel_tol: 1e-12,
        max_iter: 5000,
        preconditioner: PreconditionerKind::BlockJacobi,
        accept_unconverged: false,
        ..SolverParams::default()
    }
}

#[test]
fn implicit_steps_conserve_linear_momentum() {
    for kind in [IntegratorKind::BackwardEuler, IntegratorKind::Bdf2] {
        let model = small_model(true, true, false);
        let mass = model.masses().to_vec();
        let mut sim = Simulation::new(model, kind, tight_solver());
        let mut rng = Rng(5);
        let mut s = sim.state().clone();
        for v in s.v.iter_mut() {
            *v = rng.vec3() * 0.5;
        }
        sim.set_state(&s).unwrap();
        let momentum = |sim: &Simulation| -> Vec3 { sim.state().v.iter().zip(&mass).map(|(v, m)| v * *m).sum() };
        let p0 = momentum(&sim);
        let scale: f64 = sim.state().v.iter().zip(&mass).map(|(v, m)| v.norm() * m).sum();
        for _ in 0..20 {
            sim.step(0.01).unwrap();
        }
        let p1 = momentum(&sim);
        assert!((p1 - p0).norm() < 1e-10 * scale, "{kind:?}: momentum drift {:?}", p1 - p0);
    }
}

/// With no pins every link stays at rest length in free fall, so each
/// integrator must reproduce its own discrete free-fall recurrence.
#[test]
fn free_fall_matches_the_exact_discrete_trajectories() {
    let g = -10.0;
    let h = 0.01;
    for kind in ["backward-euler", "bdf2"] {
        let set = format!("simulation.integrator={kind}");
        // The recurrence holds to the linear solve's tolerance: the default
        // law has bending stiffness at rest, so the multigrid no longer
        // solves a uniform fall in one iteration, and at the scene's 1e-10
        // (relative to a right-hand side that carries the whole velocity)
        // BDF2 drifts 7.5e-9 m in 50 steps. At 1e-14 the worst error is
        // 1.6e-15 m (backward Euler) and 5.4e-13 m (BDF2).
        let (mut sim, cfg) = simulation("freefall.toml", &[&set, "solver.rel_tol=1e-14"]);
        assert_eq!(cfg.dt_s, h);
        let z0 = sim.state().x.clone();
        // Reference recurrences on (z, v) relative to the start.
        let (mut z, mut v, mut z_prev, mut v_prev) = (0.0, 0.0, 0.0, 0.0);
        for n in 0..cfg.steps {
            sim.step(h).unwrap();
            let (z_new, v_new) = if kind == "bdf2" && n > 0 {
                let v_new = (4.0 * v - v_prev) / 3.0 + 2.0 * h / 3.0 * g;
                ((4.0 * z - z_prev) / 3.0 + 2.0 * h / 3.0 * v_new, v_new)
            } else {
                (z + h * (v + h * g), v + h * g)
            };
            (z_prev, v_prev, z, v) = (z, v, z_new, v_new);
            for (p, p0) in sim.state().x.iter().zip(&z0) {
                assert!((p.z - p0.z - z).abs() < 1e-12, "{kind} step {n}: z error {}", p.z - p0.z - z);
                assert!((p.x - p0.x).abs() < 1e-12 && (p.y - p0.y).abs() < 1e-12);
            }
        }
        // Both approach the analytic fall g t^2 / 2 (first order for BE).
        let t = sim.time();
        let exact = 0.5 * g * t * t;
        let tol = if kind == "bdf2" { 0.02 } else { 0.05 };
        assert!((z - exact).abs() < tol * exact.abs(), "{kind}: {z} vs {exact}");
    }
}

/// Choi & Ko claim stability at steps of 0.2 s and longer.
#[test]
fn hanging_cloth_is_stable_at_a_fifth_of_a_second() {
    let (mut sim, _) = simulation("hang.toml", &["simulation.dt_s=0.2"]);
    for _ in 0..100 {
        sim.step(0.2).unwrap();
    }
    assert!(sim.state().first_non_finite().is_none());
    let stretch = sim.model().max_stretch_ratio(&sim.state().x);
    assert!(stretch < 1.2, "max stretch {stretch}");
    // It hangs: the lowest point is well below the pins (z = 1).
    let min_z = sim.state().x.iter().map(|p| p.z).fold(f64::INFINITY, f64::min);
    assert!(min_z < 0.2, "min z {min_z}");
}

#[test]
fn restore_then_step_reproduces_the_same_bits() {
    let (mut sim, cfg) = simulation("hang.toml", &["panels.0.particles=[15, 15]", "pins.0.nodes=[[0, 14], [14, 14]]"]);
    for _ in 0..5 {
        sim.step(cfg.dt_s).unwrap();
    }
    let snap = sim.snapshot();
    for _ in 0..7 {
        sim.step(cfg.dt_s).unwrap();
    }
    let first = sim.snapshot();
    // Scribble over the state, then roll back.
    sim.step(cfg.dt_s * 3.0).unwrap();
    sim.restore(&snap).unwrap();
    for _ in 0..7 {
        sim.step(cfg.dt_s).unwrap();
    }
    assert!(same_bits(&first.state.x, &sim.state().x) && same_bits(&first.state.v, &sim.state().v));
    assert_eq!(first, sim.snapshot());
}

#[test]
fn results_are_bit_identical_with_one_and_two_threads() {
    // Large enough for several parallel chunks; the fold has solid
    // contacts (released and added), friction and self-collision; the
    // round tablecloth is a pattern's irregular mesh (hinges, graph
    // aggregates) on a ball.
    let scenes: [(&str, &[&str], usize); 3] = [
        ("hang.toml", &["panels.0.particles=[33, 33]", "pins.0.nodes=[[0, 32], [32, 32]]"], 10),
        ("fold.toml", &[], 120),
        ("round-tablecloth.toml", &["meshes.0.pattern.edge_length_m=0.04"], 40),
    ];
    for (scene, overrides, steps) in scenes {
        let run = |threads: usize| {
            rayon_pool(threads).install(|| {
                let (mut sim, cfg) = simulation(scene, overrides);
                for _ in 0..steps {
                    sim.step(cfg.dt_s).unwrap();
                }
                sim.snapshot()
            })
        };
        let (one, two) = (run(1), run(2));
        assert!(same_bits(&one.state.x, &two.state.x) && same_bits(&one.state.v, &two.state.v), "{scene}");
    }
}

fn rayon_pool(threads: usize) -> rayon::ThreadPool {
    rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap()
}

/// A pin on a path is a hard constraint: it follows its path exactly and
/// carries the path's velocity, with both integrators.
#[test]
fn pins_follow_their_prescribed_paths_exactly() {
    let velocity = [0.3, -0.1, 0.2];
    for kind in ["backward-euler", "bdf2"] {
        let set_kind = format!("simulation.integrator={kind}");
        let motion = format!("pins.0.motion={{ kind = \"linear\", velocity_m_s = {velocity:?} }}");
        let (mut sim, cfg) = simulation(
            "hang.toml",
            &["panels.0.particles=[9, 9]", "pins.0.nodes=[[0, 8], [8, 8]]", &set_kind, &motion],
        );
        let pins = sim.model().pins().to_vec();
        for _ in 0..30 {
            sim.step(cfg.dt_s).unwrap();
        }
        let t = sim.time();
        for pin in &pins {
            let expect = pin.anchor + Vec3::from(velocity) * t;
            let got = sim.state().x[pin.particle];
            assert!((got - expect).norm() < 1e-12, "{kind}: pin {} at {got:?}, path at {expect:?}", pin.particle);
            let v = sim.state().v[pin.particle];
            assert!((v - Vec3::from(velocity)).norm() < 1e-9, "{kind}: pin velocity {v:?}");
        }
        // The free cloth is dragged along and stays finite.
        assert!(sim.state().first_non_finite().is_none());
    }
}

/// The preconditioner changes the cost of a step, not its answer: the
/// hanging cloth after 0.5 s agrees across preconditioners at a tight tolerance.
#[test]
fn preconditioners_agree_on_the_trajectory() {
    let run = |pc: &str| {
        let set = format!("solver.preconditioner={pc}");
        let (mut sim, cfg) = simulation(
            "hang.toml",
            &["panels.0.particles=[21, 21]", "pins.0.nodes=[[0, 20], [20, 20]]", "solver.rel_tol=1e-10", &set],
        );
        let mut iterations = 0;
        for _ in 0..45 {
            iterations += sim.step(cfg.dt_s).unwrap().cg_iterations;
        }
        (sim.state().x.clone(), iterations)
    };
    let (mg, mg_iters) = run("multigrid");
    for pc in ["block-jacobi", "diagonal"] {
        let (other, iters) = run(pc);
        let diff = mg.iter().zip(&other).map(|(a, b)| (a - b).norm()).fold(0.0, f64::max);
        assert!(diff < 1e-7, "{pc}: max position difference {diff} m");
        assert!(mg_iters < iters, "multigrid {mg_iters} iterations vs {pc} {iters}");
    }
}

/// Volino's matrix-free backward Euler runs exactly the iterations it is
/// given, and with enough of them reproduces PCG-solved backward Euler.
#[test]
fn fixed_cg_backward_euler_converges_to_backward_euler() {
    // The paper's pair law: a flat cloth has no out-of-plane stiffness at
    // rest, which the first step's check below relies on.
    let set = [
        "panels.0.particles=[13, 13]",
        "pins.0.nodes=[[0, 12], [12, 12]]",
        "solver.rel_tol=1e-12",
        "simulation.bending_law=\"arc-chord\"",
    ];
    let run = |kind: &str, iterations: usize| {
        let integrator = format!("simulation.integrator={kind}");
        let count = format!("solver.fixed_cg_iterations={iterations}");
        let (mut sim, cfg) = simulation("hang.toml", &[set[0], set[1], set[2], set[3], &integrator, &count]);
        let mut reports = Vec::new();
        for _ in 0..20 {
            reports.push(sim.step(cfg.dt_s).unwrap());
        }
        (sim.state().x.clone(), reports)
    };
    let (reference, _) = run("backward-euler", 0);
    let mut last = f64::INFINITY;
    for iterations in [2, 8, 32, 400] {
        let (x, reports) = run("backward-euler-fixed-cg", iterations);
        assert!(reports.iter().all(|r| r.cg_iterations <= iterations && r.force_evaluations == 1));
        if iterations < 100 {
            // The first step from rest is exact after one iteration: with
            // mass scaling and no out-of-plane stiffness, uniform gravity is
            // an eigenvector of the operator.
            assert_eq!(reports[0].cg_iterations, 1);
            assert!(reports[1..].iter().all(|r| r.cg_iterations == iterations), "{iterations}: stopped early");
        }
        let diff = x.iter().zip(&reference).map(|(a, b)| (a - b).norm()).fold(0.0, f64::max);
        assert!(diff < last, "{iterations} iterations: {diff} m from backward Euler (was {last})");
        last = diff;
    }
    assert!(last < 1e-8, "400 iterations still {last} m from backward Euler");
}

/// Provot's linear springs pass the same energy and Jacobian checks
/// (compressed springs lose only their orthogonal term in the matrix).
#[test]
fn provot_forces_and_jacobians_match_finite_differences() {
    let model = small_model_of(ModelKind::Provot, true, false, true);
    assert!(model.stretch_links().iter().all(|l| l.compression == Compression::Linear(l.k_s)));
    let mut rng = Rng(21);
    let x = perturbed(&model, &mut rng, 2e-3);
    let zero = vec![Vec3::zeros(); x.len()];
    assert_forces_are_energy_gradient(&model, &x);
    let dropped = dropped_compression_terms(&model, &x);
    assert!(!dropped.is_empty(), "some Provot springs are compressed");
    let err = jacobian_error(&model, &x, &zero, false, &dropped);
    assert!(err < 1e-6, "Provot Jacobian error {err:e}");
}

/// Provot's deformation constraints: with them no structural or shear link
/// ends a step longer than (1 + tau_c) L, pins never move, and without them
/// the soft cloth does overstretch at its pinned corners.
#[test]
fn deformation_constraints_bound_the_stretch() {
    let base = ["simulation.model=provot", "material.tensile_stiffness_n_m=5.0", "panels.0.particles=[15, 15]"];
    let pins = "pins.0.nodes=[[0, 14], [14, 14]]";
    let run = |extra: &[&str]| {
        let mut o: Vec<&str> = base.to_vec();
        o.push(pins);
        o.extend_from_slice(extra);
        let (mut sim, cfg) = simulation("hang.toml", &o);
        let mut worst: f64 = 0.0;
        for _ in 0..60 {
            sim.step(cfg.dt_s).unwrap();
            worst = worst.max(sim.model().max_stretch_ratio(&sim.state().x));
            for pin in sim.model().pins() {
                assert_eq!(sim.state().x[pin.particle], pin.anchor);
            }
        }
        worst
    };
    let free = run(&[]);
    assert!(free > 1.2, "without constraints the soft cloth should overstretch, got {free}");
    let limited = run(&[
        "simulation.effects=[\"gravity\", \"bending\", \"damping\", \"strain-limit\"]",
        "constraints.max_strain=0.1",
        "constraints.passes=5000",
    ]);
    assert!(limited <= 1.1 * (1.0 + 1e-9), "max stretch {limited} with tau_c = 0.1");
}

/// Newton iterations solve the nonlinear backward-Euler equation
/// `M dv = h f(x + h (v + dv), v + dv)`: its residual after the step falls
/// fast with the number of iterations (one iteration is Baraff & Witkin's
/// and Choi & Ko's linearised step).
#[test]
fn newton_iterations_converge_the_nonlinear_step() {
    let residual = |newton: usize| {
        let count = format!("solver.newton.iterations={newton}");
        let (mut sim, _) = simulation(
            "hang.toml",
            &[
                "panels.0.particles=[15, 15]",
                "pins.0.nodes=[[0, 14], [14, 14]]",
                "simulation.integrator=backward-euler",
                "solver.rel_tol=1e-12",
                "solver.preconditioner=block-jacobi",
                "solver.newton.tolerance_m=1e-15",
                &count,
            ],
        );
        let h = 0.02;
        for _ in 0..5 {
            sim.step(h).unwrap();
        }
        let before = sim.snapshot();
        sim.step(h).unwrap();
        let after = sim.state();
        let model = sim.model();
        let f = total_forces(model, &after.x, &after.v, &after.stitches_closed);
        let sum: f64 = f
            .iter()
            .enumerate()
            .filter(|(i, _)| !model.is_pinned(*i))
            .map(|(i, fi)| ((after.v[i] - before.state.v[i]) * model.masses()[i] - fi * h).norm_squared())
            .sum();
        sum.sqrt()
    };
    let (one, two, four, eight) = (residual(1), residual(2), residual(4), residual(8));
    // Measured: 3.2e-3, 1.7e-3, 7.5e-5, 5.4e-11: slow while the iterates
    // cross the kinks of the compressed type-1 links' buckling law (ramp to
    // arc), then superlinear (not quadratic: the matrix leaves out their
    // orthogonal term and takes the Gauss-Newton part of the triples'
    // Hessian). The paper's pair law: 5.1e-3, 4.5e-4, 1.4e-7, 7e-14.
    assert!(two < 0.6 * one, "residual {one:e} -> {two:e} after 2 iterations");
    assert!(four < 3e-2 * one, "residual {one:e} -> {four:e} after 4 iterations");
    assert!(eight < 2e-8 * one, "residual {one:e} -> {eight:e} after 8 iterations");
}

/// Volino's accurate model (membrane and bending triangles): forces
/// are minus the energy gradient, and in tension without bending the
/// assembled stiffness is the exact Jacobian.
#[test]
fn volino_forces_and_jacobians_match_finite_differences() {
    let model = small_model_of(ModelKind::Volino, true, false, true);
    assert!(!model.elements().membranes.is_empty() && !model.elements().curvatures.is_empty());
    assert!(model.bend_links().is_empty() && model.stretch_links().iter().all(|l| l.k_s == 0.0));
    let mut rng = Rng(31);
    let x = perturbed(&model, &mut rng, 2e-3);
    let zero = vec![Vec3::zeros(); x.len()];
    assert_forces_are_energy_gradient(&model, &x);
    // Membrane only, uniformly stretched by 20% plus jitter: tensile stress everywhere.
    let model = small_model_of(ModelKind::Volino, false, false, true);
    let mut x: Vec<Vec3> = model.rest_positions().iter().map(|p| p * 1.2).collect();
    for p in x.iter_mut() {
        *p += rng.vec3() * 1e-4;
    }
    let err = jacobian_error(&model, &x, &zero, false, &vec![]);
    assert!(err < 1e-6, "Volino membrane Jacobian error {err:e}");
}

/// One scene runs with any model: the hanging cloth stays finite, hangs,
/// and the three models agree on where it is after 1 s of its swing (one
/// material, the same cloth: centres of mass within 1.19 cm, the bending
/// models differing in B; with each link's constant `(2/3) E a / L^2`
/// instead of each model's own mapping, 5.8 cm).
#[test]
fn every_model_runs_the_hanging_cloth() {
    let centre = |sim: &Simulation| {
        let m = sim.model().masses();
        m.iter().zip(&sim.state().x).fold(Vec3::zeros(), |a, (mi, x)| a + x * *mi) / m.iter().sum::<f64>()
    };
    let mut centres = Vec::new();
    for model in ["choi-ko", "provot", "volino"] {
        let set = format!("simulation.model={model}");
        let (mut sim, cfg) =
            simulation("hang.toml", &["panels.0.particles=[15, 15]", "pins.0.nodes=[[0, 14], [14, 14]]", &set]);
        let (mut min_z, mut stretch) = (f64::INFINITY, 0.0_f64);
        for _ in 0..90 {
            sim.step(cfg.dt_s).unwrap_or_else(|e| panic!("{model}: {e}"));
            min_z = sim.state().x.iter().map(|p| p.z).fold(min_z, f64::min);
            stretch = stretch.max(sim.model().max_stretch_ratio(&sim.state().x));
        }
        // It swings down through the vertical (the far edge is 1 m long) without tearing.
        assert!(min_z < 0.2 && stretch < 1.5, "{model}: lowest z {min_z}, max stretch {stretch}");
        centres.push(centre(&sim));
    }
    for a in &centres {
        for b in &centres {
            assert!((a - b).norm() < 0.013, "the models part: centres {centres:?}");
        }
    }
}

/// Volino's bending triangles store the plate energy `B |kappa|^2 A / 2`
/// of every quadratic deflection `w = eps (a x^2 + 2 b x y + c y^2) / 2`
/// (bend about either axis, twist, saddle, a mix) on every triangle with
/// three neighbours, to the small-deflection expansion's order (measured
/// worst relative error 4.9e-9 at curvatures of 1e-3 /m). A hinge per edge
/// (the diagonal of `M` alone) fails it: it
/// stores 3.0x the twist energy. The whole sheet, whose free edges carry
/// no moment, stores less.
#[test]
fn volino_bending_triangles_store_the_plate_energy_of_every_quadratic() {
    use cloth_core::element_laws::curvature_bending_with;
    let b = 1e-4;
    let model = ClothModel::build(&ModelSpec {
        kind: ModelKind::Volino,
        panels: vec![GridPanel {
            particles: [9, 9],
            size_m: [0.08, 0.08],
            origin_m: [-0.04, -0.04, 0.0],
            u_axis: [1.0, 0.0, 0.0],
            v_axis: [0.0, 1.0, 0.0],
            wrap_u: false,
        }],
        material: Material { flexural_rigidity_n_m: b, ..Material::default() },
        effects: Effects { gravity: None, damping: false, bending: true, drag: false, ..Effects::default() },
        ..ModelSpec::default()
    })
    .unwrap();
    let elements = &model.elements().curvatures;
    let interior: Vec<_> = elements.iter().filter(|e| (0..3).all(|k| e.stiffness[(k, k)] > 0.0)).collect();
    // 8 x 8 cells, two triangles each; 30 have an edge on the border (in the
    // two corner cells off the diagonals' line one triangle has two).
    assert_eq!((elements.len(), interior.len()), (128, 128 - 30));
    let eps = 1e-3;
    let mut worst = 0.0_f64;
    for (name, [a, bxy, c]) in [
        ("bend x", [1.0, 0.0, 0.0]),
        ("bend y", [0.0, 0.0, 1.0]),
        ("twist", [0.0, 1.0, 0.0]),
        ("saddle", [1.0, 0.0, -1.0]),
        ("mixed", [0.7, -0.4, 0.3]),
    ] {
        let (a, bxy, c) = (a * eps, bxy * eps, c * eps);
        let x: Vec<Vec3> = model
            .rest_positions()
            .iter()
            .map(|p| Vec3::new(p.x, p.y, 0.5 * (a * p.x * p.x + 2.0 * bxy * p.x * p.y + c * p.y * p.y)))
            .collect();
        let plate = 0.5 * b * (a * a + 2.0 * bxy * bxy + c * c);
        let bending = |e: &cloth_core::CurvatureElement| {
            curvature_bending_with(e.nodes.map(|q| x[q as usize]), e.rest_angles, &e.stiffness, false).energy
        };
        for e in &interior {
            let energy = bending(e);
            let [p0, p1, p2] = [0, 1, 2].map(|k| model.rest_positions()[e.nodes[k] as usize]);
            let area = 0.5 * (p1 - p0).cross(&(p2 - p0)).norm();
            let error = energy / (plate * area) - 1.0;
            worst = worst.max(error.abs());
            assert!(
                error.abs() < 1e-8,
                "{name}: triangle {:?} stores {energy:e} J, plate {:e} J",
                e.nodes,
                plate * area
            );
        }
        let sheet = elements.iter().map(bending).sum::<f64>() / (plate * 0.08 * 0.08);
        assert!(sheet > 0.7 && sheet < 1.0 + 1e-8, "{name}: the sheet stores {sheet} of the plate energy");
    }
    println!("worst relative error {worst:e}");
}

/// Drag alone on a cloth moving rigidly: every integrator reproduces its
/// own discrete exponential decay (`lambda = drag / rho`), and internal
/// forces stay zero.
#[test]
fn drag_decays_velocity_like_the_discrete_exponential() {
    let (rho, drag) = (0.1, 0.5);
    let lambda = drag / rho;
    let h = 0.01;
    // (Explicit methods are unstable for this stiff cloth at h = 0.01 s:
    // rounding noise in the links grows. Their drag is covered by the
    // convergence tests.)
    for kind in [IntegratorKind::BackwardEuler, IntegratorKind::Bdf2, IntegratorKind::BackwardEulerFixedCg] {
        let model = ClothModel::build(&ModelSpec {
            panels: vec![GridPanel {
                particles: [6, 6],
                size_m: [0.1, 0.1],
                origin_m: [0.0; 3],
                u_axis: [1.0, 0.0, 0.0],
                v_axis: [0.0, 1.0, 0.0],
                wrap_u: false,
            }],
            material: Material { areal_density_kg_m2: rho, drag_n_s_m3: drag, ..Material::default() },
            effects: Effects { gravity: None, damping: true, bending: true, drag: true, ..Effects::default() },
            ..ModelSpec::default()
        })
        .unwrap();
        let mut sim = Simulation::new(model, kind, SolverParams { fixed_cg_iterations: 200, ..tight_solver() });
        let mut s = sim.state().clone();
        let v0 = Vec3::new(0.3, -0.2, 1.0);
        s.v.iter_mut().for_each(|v| *v = v0);
        sim.set_state(&s).unwrap();
        let (mut v, mut v_prev) = (1.0_f64, 1.0_f64);
        for n in 0..30 {
            sim.step(h).unwrap();
            let next = match kind {
                IntegratorKind::Bdf2 if n > 0 => (4.0 * v - v_prev) / (3.0 * (1.0 + 2.0 * h * lambda / 3.0)),
                _ => v / (1.0 + h * lambda),
            };
            (v_prev, v) = (v, next);
            for p in &sim.state().v {
                assert!((p - v0 * v).norm() < 1e-9, "{kind:?} step {n}: {p:?} vs {:?}", v0 * v);
            }
        }
    }
}
