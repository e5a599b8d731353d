//! The quasi-Newton step against backward Euler solved to convergence,
//! its dampers' forms against the terms' forces, its initial Hessian,
//! free fall, momentum and bits across thread counts.

use super::*;
use crate::integrate::vbd::tests::{converged_backward_euler, free_sheet_falls_at_g, hanging, largest_difference};
use crate::terms::{At, acting};
use crate::{Edge, IntegratorKind, ModelKind, QuasiNewtonParams, Simulation, SolverParams};

fn solver(iterations: usize, tolerance_m: f64) -> SolverParams {
    SolverParams {
        quasi_newton: QuasiNewtonParams { iterations, tolerance_m, ..QuasiNewtonParams::default() },
        ..SolverParams::default()
    }
}

/// Ten steps minimised to a tight gradient land where backward Euler's
/// Newton iterations do: the same potential, the same minimum. The line
/// search on the potential stops near a residual of 3e-10 m, where the
/// potential's changes reach its rounding (Volino's membranes), so the
/// steps are not all reported converged at 1e-10 m.
#[test]
fn a_converged_quasi_newton_step_is_the_backward_euler_step() {
    for kind in [ModelKind::ChoiKo, ModelKind::Provot, ModelKind::Volino] {
        let model = hanging(kind, 6);
        let h = 1.0 / 90.0;
        let reference = converged_backward_euler(&model, h, 10);
        let mut sim = Simulation::new(model.clone(), IntegratorKind::QuasiNewton, solver(5000, 1e-10));
        let mut iterations = 0;
        for _ in 0..10 {
            iterations += sim.step(h).unwrap().descent_iterations;
        }
        let error = largest_difference(&sim.state().x, &reference);
        let moved = largest_difference(&sim.state().x, model.rest_positions());
        println!("{kind:?}: {error:.3e} m off backward Euler, moved {moved:.3e} m, {iterations} iterations");
        assert!(error < 1e-9, "{kind:?}: {error:.3e} m");
    }
}

/// The dampers' forms are the terms' damping: `p^T C p` is the power the
/// terms dissipate at velocity `p`, and `v^T C p` is minus the damping
/// force's work along `p` (forces at `v` less forces at rest).
#[test]
fn damping_forms_are_the_terms_damping() {
    for kind in [ModelKind::ChoiKo, ModelKind::Provot, ModelKind::Volino] {
        let model = ClothModel::builder()
            .grid([5, 5], [0.3, 0.3])
            .kind(kind)
            .bending()
            .damping()
            .drag()
            .gravity([0.0, 0.0, -9.81])
            .build()
            .unwrap();
        let n = model.particle_count();
        let wave = |i: usize, a: f64| Vec3::new((a * i as f64).sin(), (1.3 * a * i as f64).cos(), 0.3 * a);
        let x: Vec<Vec3> = model.rest_positions().iter().enumerate().map(|(i, r)| r + wave(i, 0.7) * 0.01).collect();
        let v: Vec<Vec3> = (0..n).map(|i| wave(i, 1.1)).collect();
        let p: Vec<Vec3> = (0..n).map(|i| wave(i, 0.4) * 0.1).collect();
        let still = vec![Vec3::zeros(); n];
        let (vcp, pcp) = damping_forms(&model, &x, &v, &p, &[]);
        let power: f64 = acting(&model).map(|t| t.dissipation(&At::new(&model, &x, &p, &[]))).sum();
        let (moving, resting) =
            (crate::forces::total_forces(&model, &x, &v, &[]), crate::forces::total_forces(&model, &x, &still, &[]));
        let work: f64 = (0..n).map(|i| -(moving[i] - resting[i]).dot(&p[i])).sum();
        println!("{kind:?}: p^T C p {pcp:.6e} against {power:.6e}; v^T C p {vcp:.6e} against {work:.6e}");
        assert!((pcp - power).abs() <= 1e-12 * power.abs(), "{kind:?}: {pcp} against {power}");
        assert!((vcp - work).abs() <= 1e-12 * work.abs().max(pcp), "{kind:?}: {vcp} against {work}");
    }
}

/// The initial Hessian: mass over `h^2` plus the links' stiffness on the
/// diagonal, minus it between linked particles, and a pinned particle's
/// row the identity while its links stay on its neighbours' diagonals.
#[test]
fn the_initial_hessian_is_mass_plus_the_links_laplacian() {
    let model = ClothModel::builder()
        .grid([3, 3], [0.2, 0.2])
        .kind(ModelKind::Provot)
        .gravity([0.0, 0.0, -9.81])
        .pin_edge(0, Edge::JMax)
        .build()
        .unwrap();
    let n = model.particle_count();
    let mut weights = vec![vec![0.0; n]; n];
    for l in model.stretch_links() {
        let (i, j) = (l.i as usize, l.j as usize);
        weights[i][j] += l.k_s;
        weights[j][i] += l.k_s;
    }
    let h = 0.01;
    let mut hessian = InitialHessian::new(&model, &[]).unwrap();
    let fixed: Vec<bool> = (0..n).map(|i| model.pins().iter().any(|p| p.particle == i)).collect();
    assert!(fixed.iter().any(|&f| f) && !fixed.iter().all(|&f| f));
    hessian.prepare(&model, h, &fixed, &vec![0.0; n]).unwrap();
    for i in 0..n {
        for j in 0..n {
            let expected = if fixed[i] || fixed[j] {
                if i == j { 1.0 } else { 0.0 }
            } else if i == j {
                model.masses()[i] / (h * h) + weights[i].iter().sum::<f64>()
            } else {
                -weights[i][j]
            };
            let got = hessian.entry(i, j);
            // The weights are read at the rest shape stretched by PROBE_STRETCH.
            assert!((got - expected).abs() <= 1e-9 * expected.abs().max(1.0), "({i}, {j}): {got} against {expected}");
        }
    }
}

/// A free sheet under gravity falls as backward Euler's discrete free
/// fall at any step size (the first guess is the step's solution).
#[test]
fn a_free_sheet_falls_at_g_at_any_step() {
    free_sheet_falls_at_g(IntegratorKind::QuasiNewton);
}

/// A tumbling free sheet without gravity keeps its linear momentum: the
/// internal forces sum to zero, so a converged step changes the momentum
/// only by its gradient's remainder.
#[test]
fn a_free_sheet_keeps_its_momentum() {
    let model = ClothModel::builder().grid([7, 7], [0.4, 0.4]).bending().damping().build().unwrap();
    let n = model.particle_count();
    let mut sim = Simulation::new(model.clone(), IntegratorKind::QuasiNewton, solver(500, 1e-12));
    let mut state = sim.state().clone();
    for (i, v) in state.v.iter_mut().enumerate() {
        *v = Vec3::new(0.5 + 0.3 * (i as f64).sin(), -0.2 * (i % 4) as f64, 0.4 * (0.7 * i as f64).cos());
    }
    sim.set_state(&state).unwrap();
    let momentum = |s: &crate::ClothState| -> Vec3 { (0..n).map(|i| s.v[i] * model.masses()[i]).sum() };
    let before = momentum(sim.state());
    for _ in 0..20 {
        sim.step(1.0 / 90.0).unwrap();
    }
    let drift = (momentum(sim.state()) - before).norm() / before.norm();
    println!("momentum drift {drift:.2e} over 20 steps");
    assert!(drift < 1e-9, "momentum drifted by {drift:e}");
}

/// One and two threads: the same bits.
#[test]
fn one_and_two_threads_give_the_same_bits() {
    let model = hanging(ModelKind::ChoiKo, 12);
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| {
            let mut sim = Simulation::new(model.clone(), IntegratorKind::QuasiNewton, SolverParams::default());
            for _ in 0..10 {
                sim.step(1.0 / 90.0).unwrap();
            }
            sim.state().clone()
        })
    };
    let (one, two) = (run(1), run(2));
    let same = |a: &[Vec3], b: &[Vec3]| {
        a.iter().zip(b).all(|(p, q)| p.iter().zip(q.iter()).all(|(u, w)| u.to_bits() == w.to_bits()))
    };
    assert!(same(&one.x, &two.x) && same(&one.v, &two.v));
}

/// The history's two-loop recursion meets the newest pair's secant
/// equation `H y = s`, and a refused pair (`s . y <= 0`) written over the
/// oldest of a full history drops that pair: what is left acts as a
/// history of the kept pairs alone.
#[test]
fn the_history_keeps_the_secant_pairs_and_drops_a_refused_one() {
    let model = ClothModel::builder().grid([3, 3], [0.2, 0.2]).kind(ModelKind::Provot).build().unwrap();
    let n = model.particle_count();
    let mut hessian = InitialHessian::new(&model, &[]).unwrap();
    hessian.prepare(&model, 0.01, &vec![false; n], &vec![0.0; n]).unwrap();
    let field = |a: f64| -> Vec<Vec3> {
        (0..n).map(|i| Vec3::new((a * i as f64).sin(), (a + 0.3 * i as f64).cos(), 0.1 * a * i as f64)).collect()
    };
    let zeros = vec![Vec3::zeros(); n];
    // y = B s with B diagonal and positive: s . y > 0.
    let pair = |a: f64| {
        let s = field(a);
        let y: Vec<Vec3> = s.iter().enumerate().map(|(i, v)| v * (1.0 + i as f64)).collect();
        (s, y)
    };
    let mut history = History::new(2, n);
    for a in [0.7, 1.3, 2.1] {
        let (s, y) = pair(a);
        assert!(history.push(&s, &zeros, &y, &zeros));
    }
    let (s3, y3) = pair(2.1);
    let mut r = zeros.clone();
    history.apply(&y3, &mut r, &mut hessian);
    let secant = largest_difference(&r, &s3) / s3.iter().map(|v| v.norm()).fold(0.0, f64::max);
    assert!(secant < 1e-12, "H y = s off by {secant:e}");
    // A refused pair: y = -s.
    let s4 = field(3.3);
    let y4: Vec<Vec3> = s4.iter().map(|v| -v).collect();
    assert!(!history.push(&s4, &zeros, &y4, &zeros));
    assert_eq!(history.len, 1);
    let mut only = History::new(2, n);
    only.push(&s3, &zeros, &y3, &zeros);
    let g = field(0.4);
    let (mut a, mut b) = (zeros.clone(), zeros.clone());
    history.apply(&g, &mut a, &mut hessian);
    only.apply(&g, &mut b, &mut hessian);
    assert_eq!(largest_difference(&a, &b), 0.0);
}
