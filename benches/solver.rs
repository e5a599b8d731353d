//! Criterion benchmarks: block SpMV, PCG per preconditioner, and one full
//! BDF2 step, on the 75 x 75 hanging cloth with 2 threads.
//!
//! Run: `cargo bench -p cloth-benches`
//!
//! Each measurement runs inside a 2-thread rayon pool (`iter_custom`), as a
//! simulation step does, so no per-call cross-thread dispatch is timed.

use cloth_benches::{hanging_cloth, pool};
use cloth_core::terms::SystemTerms;
use cloth_core::testing::{SystemBuffers, assemble};
use cloth_core::{PcgParams, PreconditionerKind, Vec3};
use cloth_linalg::{Constraint, ConstraintFilter, Multigrid, Pcg};
use criterion::{Criterion, criterion_group, criterion_main};
use std::hint::black_box;
use std::time::{Duration, Instant};

const N: usize = 75;

/// Times `iters` calls of `f` inside `pool`.
fn timed_in_pool(pool: &rayon::ThreadPool, iters: u64, mut f: impl FnMut() + Send) -> Duration {
    pool.install(|| {
        let t = Instant::now();
        for _ in 0..iters {
            f();
        }
        t.elapsed()
    })
}

/// The BDF2 matrix and right-hand side at the benchmark state.
fn system() -> (SystemBuffers, ConstraintFilter, Multigrid) {
    let (sim, cfg, snapshot) = hanging_cloth(N, 45, "multigrid");
    let state = &snapshot.state;
    let model = sim.model();
    let h = cfg.dt_s;
    let delta: Vec<Vec3> = state.x.iter().zip(&state.x_prev).map(|(a, b)| a - b).collect();
    let mut bufs = SystemBuffers::new(model);
    let terms = SystemTerms {
        d_times: Some((-2.0 * h / 9.0, &delta)),
        mass_times: Some(&delta),
        ..SystemTerms::new(4.0 * h * h / 9.0, 2.0 * h / 3.0, 4.0 * h * h / 9.0, &state.stitches_closed)
    };
    assemble(model, &state.x, &terms, &mut bufs);
    let mut filter = ConstraintFilter::new(model.particle_count());
    for pin in model.pins() {
        filter.set(pin.particle, Constraint::Fixed, Vec3::zeros()).expect("valid pin");
    }
    (bufs, filter, model.multigrid())
}

fn spmv(c: &mut Criterion) {
    let pool = pool();
    let (bufs, _, _) = system();
    let x: Vec<Vec3> = (0..bufs.rhs.len()).map(|i| Vec3::new(1.0, i as f64 * 1e-3, -0.5)).collect();
    let mut y = vec![Vec3::zeros(); x.len()];
    c.bench_function("spmv_75x75", |b| {
        b.iter_custom(|iters| timed_in_pool(&pool, iters, || bufs.matrix.mul_vec(black_box(&x), &mut y)))
    });
}

fn pcg(c: &mut Criterion) {
    let pool = pool();
    let (bufs, filter, multigrid) = system();
    let mut group = c.benchmark_group("pcg_75x75_rel_tol_1e-3");
    for (name, kind) in [
        ("multigrid", PreconditionerKind::Multigrid),
        ("block_jacobi", PreconditionerKind::BlockJacobi),
        ("diagonal", PreconditionerKind::Diagonal),
        ("none", PreconditionerKind::None),
    ] {
        let params = PcgParams { rel_tol: 1e-3, max_iter: 5000, preconditioner: kind };
        let mut solver = Pcg::new(bufs.rhs.len());
        solver.set_multigrid(multigrid.clone());
        let mut x = vec![Vec3::zeros(); bufs.rhs.len()];
        group.bench_function(name, |b| {
            b.iter_custom(|iters| {
                timed_in_pool(&pool, iters, || {
                    x.iter_mut().for_each(|v| *v = Vec3::zeros());
                    solver.solve(&bufs.matrix, &bufs.rhs, &filter, &params, &mut x).expect("converges");
                })
            })
        });
    }
    group.finish();
}

fn bdf2_step(c: &mut Criterion) {
    let pool = pool();
    let mut group = c.benchmark_group("bdf2_step_75x75");
    for name in ["multigrid", "block-jacobi"] {
        let (mut sim, cfg, state) = hanging_cloth(N, 45, name);
        group.bench_function(name, |b| {
            b.iter_custom(|iters| {
                timed_in_pool(&pool, iters, || {
                    sim.restore(&state).expect("same model");
                    sim.step(cfg.dt_s).expect("step");
                })
            })
        });
    }
    group.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(20);
    targets = spmv, pcg, bdf2_step
}
criterion_main!(benches);
