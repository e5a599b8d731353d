//! The vertex solver against backward Euler solved to convergence, its
//! potential at every sweep, its colours, its bits across thread counts,
//! and its contacts.

use super::*;
use crate::{Edge, IntegratorKind, ModelKind, NewtonParams, Simulation, SolverParams, VbdParams};

/// A hanging `n x n` sheet, 0.5 m square, pinned along one edge, with
/// bending and damping.
pub(crate) fn hanging(kind: ModelKind, n: usize) -> ClothModel {
    ClothModel::builder()
        .grid([n, n], [0.5, 0.5])
        .kind(kind)
        .bending()
        .damping()
        .gravity([0.0, 0.0, -9.81])
        .pin_edge(0, Edge::JMax)
        .build()
        .unwrap()
}

fn solver(iterations: usize, rho: f64) -> SolverParams {
    SolverParams {
        vbd: VbdParams { iterations, chebyshev_rho: rho, ..VbdParams::default() },
        ..SolverParams::default()
    }
}

/// Backward Euler's step with Newton iterations to a tight residual.
pub(crate) fn converged_backward_euler(model: &ClothModel, h: f64, steps: usize) -> Vec<Vec3> {
    let tight = SolverParams {
        rel_tol: 1e-12,
        max_iter: 10_000,
        newton: NewtonParams { iterations: 50, tolerance_m: 1e-13, ..Default::default() },
        ..SolverParams::default()
    };
    let mut sim = Simulation::new(model.clone(), IntegratorKind::BackwardEuler, tight);
    for _ in 0..steps {
        sim.step(h).unwrap();
    }
    sim.state().x.clone()
}

pub(crate) fn largest_difference(a: &[Vec3], b: &[Vec3]) -> f64 {
    a.iter().zip(b).map(|(p, q)| (p - q).norm()).fold(0.0, f64::max)
}

/// Ten steps with 2000 sweeps each (no acceleration) land where backward
/// Euler's Newton iterations do: the same potential, the same minimum.
#[test]
fn many_sweeps_reach_the_backward_euler_step() {
    for kind in [ModelKind::ChoiKo, ModelKind::Provot, ModelKind::Volino] {
        let model = hanging(kind, 6);
        let h = 1.0 / 90.0;
        let reference = converged_backward_euler(&model, h, 10);
        let mut sim = Simulation::new(model.clone(), IntegratorKind::Vbd, solver(2000, 0.0));
        for _ in 0..10 {
            sim.step(h).unwrap();
        }
        let error = largest_difference(&sim.state().x, &reference);
        let moved = largest_difference(&sim.state().x, model.rest_positions());
        println!("{kind:?}: {error:.3e} m off backward Euler, moved {moved:.3e} m");
        // Measured 1.3e-13 m (Choi & Ko, Provot), 1.4e-14 m (Volino).
        assert!(error < 1e-12, "{kind:?}: {error:.3e} m");
    }
}

/// Backward Euler's incremental potential of a step from `x0`, `v0` at
/// `x`, J: inertia plus every term's energy (no damping, no contacts).
fn incremental_potential(model: &ClothModel, x0: &[Vec3], v0: &[Vec3], h: f64, x: &[Vec3]) -> f64 {
    let at = At::new(model, x, &[], &[]);
    let elastic: f64 = crate::terms::acting(model).map(|t| t.energy(&at)).sum();
    let inertia: f64 =
        (0..x.len()).map(|i| model.masses()[i] / (2.0 * h * h) * (x[i] - x0[i] - v0[i] * h).norm_squared()).sum();
    inertia + elastic
}

/// Each sweep of coloured local Newton steps lowers the incremental
/// potential (a block coordinate descent; no acceleration, no damping).
/// With the local line search ([`VbdParams::line_search`]); without it
/// Choi & Ko's sheet rose in sweeps 2, 4 and 6 (to three times the first
/// sweep's potential).
/// Checked from a disturbed, moving sheet of every model over 30 sweeps,
/// each count from the same start (the first k sweeps of a step are the
/// same for any count).
#[test]
fn the_incremental_potential_falls_at_every_sweep() {
    for kind in [ModelKind::ChoiKo, ModelKind::Provot, ModelKind::Volino] {
        let model = ClothModel::builder()
            .grid([8, 8], [0.4, 0.4])
            .kind(kind)
            .bending()
            .gravity([0.0, 0.0, -9.81])
            .pin_edge(0, Edge::JMax)
            .build()
            .unwrap();
        let n = model.particle_count();
        let x0: Vec<Vec3> = model
            .rest_positions()
            .iter()
            .enumerate()
            .map(|(i, p)| p + Vec3::new(0.0, 0.0, 2e-3 * ((i * 7 % 5) as f64 - 2.0)))
            .collect();
        let v0: Vec<Vec3> = (0..n).map(|i| Vec3::new(0.1 * (i % 3) as f64, 0.0, -0.2)).collect();
        let h = 1.0 / 60.0;
        let mut last = f64::INFINITY;
        for sweeps in 1..=30 {
            let searching =
                SolverParams { vbd: VbdParams { line_search: true, ..solver(sweeps, 0.0).vbd }, ..solver(sweeps, 0.0) };
            let mut sim = Simulation::new(model.clone(), IntegratorKind::Vbd, searching);
            let mut state = sim.state().clone();
            state.x.clone_from(&x0);
            state.v.clone_from(&v0);
            sim.set_state(&state).unwrap();
            sim.step(h).unwrap();
            let g = incremental_potential(&model, &x0, &v0, h, &sim.state().x);
            assert!(g < last, "{kind:?}: sweep {sweeps} raised the potential from {last} to {g} J");
            last = g;
        }
    }
}

/// Chebyshev's weights: 1, `2 / (2 - rho^2)`, then towards the fixed
/// point `2 (1 - sqrt(1 - rho^2)) / rho^2`.
#[test]
fn chebyshev_weights_follow_the_recurrence() {
    let rho: f64 = 0.9;
    let mut omega = 1.0;
    let mut all = Vec::new();
    for k in 1..=60 {
        omega = chebyshev_omega(k, rho, omega);
        all.push(omega);
    }
    assert_eq!(all[0], 1.0);
    assert!((all[1] - 2.0 / (2.0 - 0.81)).abs() < 1e-15);
    assert!((all[2] - 4.0 / (4.0 - 0.81 * all[1])).abs() < 1e-15);
    let limit = 2.0 * (1.0 - (1.0 - rho * rho).sqrt()) / (rho * rho);
    assert!((all[59] - limit).abs() < 1e-12, "{} against {limit}", all[59]);
}

/// The middle of a sheet pinned along one edge falls at g over its first
/// 40 steps of 1e-9 and 1e-6 s (the pins' pull has not reached it): its
/// velocity is `-g t` to 1e-13 (measured 6.9e-16; at 1e-3 s the implicit
/// step lets the pins reach it, 1e-9). The unknown is the displacement over the step, not
/// the position: at h = 1e-9 s a particle moves 1e-17 m a step, below a
/// position's last bit, and a velocity read from positions was 0 (off g
/// by 1, `cloth study stability` with `vbd`).
#[test]
fn the_middle_of_a_pinned_sheet_falls_at_g_at_any_step() {
    // A metre up, as a scene's cloth is: positions of order 1 m.
    let model = ClothModel::builder()
        .panel(crate::GridPanel::flat([21, 21], [0.5, 0.5]).origin([-0.25, -0.25, 1.0]))
        .bending()
        .damping()
        .gravity([0.0, 0.0, -9.81])
        .pin_edge(0, Edge::JMax)
        .build()
        .unwrap();
    let middle = 10 * 21 + 10;
    for h in [1e-9, 1e-6] {
        let mut sim = Simulation::new(model.clone(), IntegratorKind::Vbd, SolverParams::default());
        let mut worst = 0.0_f64;
        for _ in 0..40 {
            sim.step(h).unwrap();
            let t = sim.time();
            worst = worst.max((sim.state().v[middle].z + 9.81 * t).abs() / (9.81 * t));
        }
        println!("h = {h:e}: off g by {worst:.1e}");
        assert!(worst < 1e-13, "h = {h}: the middle is off g by {worst}");
    }
}

/// A free sheet under gravity falls as backward Euler's discrete free fall,
/// `-g h^2 N (N + 1) / 2` after N steps, at any step size.
#[test]
fn a_free_sheet_falls_at_g_at_any_step() {
    free_sheet_falls_at_g(IntegratorKind::Vbd);
}

/// `kind`'s free sheet against backward Euler's discrete free fall, to
/// 1e-9 of the distance fallen after 40 steps of 1e-9 s to 1/90 s.
pub(crate) fn free_sheet_falls_at_g(kind: IntegratorKind) {
    let model = ClothModel::builder().grid([6, 6], [0.5, 0.5]).bending().gravity([0.0, 0.0, -9.81]).build().unwrap();
    for h in [1e-9, 1e-6, 1e-3, 1.0 / 90.0] {
        let mut sim = Simulation::new(model.clone(), kind, SolverParams::default());
        let n = 40;
        for _ in 0..n {
            sim.step(h).unwrap();
        }
        let mean_z = sim.state().x.iter().map(|p| p.z).sum::<f64>() / 36.0;
        let exact = -9.81 * h * h * (n * (n + 1)) as f64 / 2.0;
        let error = (mean_z / exact - 1.0).abs();
        println!("{kind:?}, h = {h:e}: fell {mean_z:e} m, backward Euler {exact:e} m ({error:.1e})");
        assert!(error < 1e-9, "{kind:?}, h = {h}: fell {mean_z} m against {exact} m");
    }
}
