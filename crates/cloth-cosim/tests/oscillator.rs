//! The masters on the two-mass oscillator benchmark against its exact
//! solution: measured order in the macro step and energy drift. The units
//! integrate with 20 RK4 substeps per macro step, so their own error
//! (below 1e-9 m here) is far under the coupling error measured.

use cloth_cosim::oscillator::{BenchmarkRun, benchmark, order};
use cloth_cosim::{Extrapolation, GaussSeidelParams, InputOverStep, IteratedParams, JacobiParams, Master, Relaxation};

const STEPS: [f64; 4] = [1.0 / 200.0, 1.0 / 400.0, 1.0 / 800.0, 1.0 / 1600.0];

fn measured(name: &str, master: Master) -> (f64, Vec<BenchmarkRun>) {
    let runs: Vec<_> = STEPS.iter().map(|&h| benchmark(master.clone(), h, 1.0, 20).unwrap()).collect();
    let p = order(&runs);
    for r in &runs {
        println!(
            "{name}: H = {:.6} error {:.3e} drift {:+.3e} unit steps {}",
            r.macro_step_s, r.max_error_m, r.energy_drift, r.unit_steps
        );
    }
    println!("{name}: order {p:.3}");
    (p, runs)
}

fn iterated(inputs: InputOverStep) -> Master {
    Master::Iterated(IteratedParams { inputs, ..IteratedParams::default() })
}

#[test]
fn zero_order_hold_masters_are_first_order_and_gain_energy() {
    let jacobi = Master::Jacobi(JacobiParams::default());
    let gauss_seidel = Master::GaussSeidel(GaussSeidelParams::default());
    for (name, master) in [("jacobi", jacobi), ("gauss-seidel", gauss_seidel)] {
        let (p, runs) = measured(name, master);
        assert!((p - 1.0).abs() < 0.1, "{name}: order {p}");
        assert!(runs.iter().all(|r| r.energy_drift > 0.0), "{name} should gain energy");
    }
}

#[test]
fn first_order_hold_makes_the_explicit_masters_second_order() {
    let jacobi = Master::Jacobi(JacobiParams { extrapolation: Extrapolation::FirstOrderHold });
    let gauss_seidel =
        Master::GaussSeidel(GaussSeidelParams { order: vec![1, 0], extrapolation: Extrapolation::FirstOrderHold });
    for (name, master) in [("jacobi-foh", jacobi), ("gauss-seidel-foh", gauss_seidel)] {
        let (p, _) = measured(name, master);
        assert!((p - 2.0).abs() < 0.1, "{name}: order {p}");
    }
}

#[test]
fn iterated_coupling_is_second_order_with_interpolated_inputs() {
    let (p, runs) = measured("iterated-linear", iterated(InputOverStep::Linear));
    assert!((p - 2.0).abs() < 0.05, "order {p}");
    // Iterated to convergence it conserves energy to the step's own accuracy.
    assert!(runs.iter().all(|r| r.energy_drift.abs() < 1e-8), "{runs:?}");
    let (p, _) = measured("iterated-end-value", iterated(InputOverStep::EndValue));
    assert!((p - 1.0).abs() < 0.08, "order {p}");
}

#[test]
fn relaxation_schemes_reach_the_same_answer() {
    let base = IteratedParams::default();
    let h = 1.0 / 400.0;
    let reference = benchmark(Master::Iterated(base), h, 1.0, 20).unwrap();
    for relaxation in [Relaxation::Fixed(1.0), Relaxation::Fixed(0.5)] {
        let r = benchmark(Master::Iterated(IteratedParams { relaxation, ..base }), h, 1.0, 20).unwrap();
        println!("{relaxation:?}: {} unit steps vs {}", r.unit_steps, reference.unit_steps);
        assert!((r.max_error_m - reference.max_error_m).abs() < 1e-7, "{relaxation:?}: {r:?} vs {reference:?}");
    }
}
