//! Criterion benchmarks of one step of a 64 x 64 hanging cloth for every
//! integrator and model (2 threads). Explicit methods step 1e-4 s (one
//! stable step of full work, DOPRI5 included), implicit ones 1/90 s.
//!
//! Run: `cargo bench -p cloth-benches --bench methods`

use cloth_benches::{THREADS, hanging_cloth_with};
use cloth_core::IntegratorKind;
use criterion::{Criterion, criterion_group, criterion_main};
use std::time::{Duration, Instant};

fn methods(c: &mut Criterion) {
    let pool = rayon::ThreadPoolBuilder::new().num_threads(THREADS).build().expect("thread pool");
    for model in ["choi-ko", "provot", "volino"] {
        let mut group = c.benchmark_group(format!("step_64x64_{model}"));
        for kind in IntegratorKind::ALL {
            let h = if kind.is_implicit() { 1.0 / 90.0 } else { 1e-4 };
            let extra = [
                format!("simulation.model={model}"),
                format!("simulation.integrator={}", kind.name()),
                format!("simulation.dt_s={h}"),
            ];
            let (mut sim, _, state) = hanging_cloth_with(64, 10, &extra);
            group.bench_function(kind.name(), |b| {
                b.iter_custom(|iters| {
                    pool.install(|| {
                        let mut total = Duration::ZERO;
                        for _ in 0..iters {
                            sim.restore(&state).expect("same model");
                            let t = Instant::now();
                            sim.step(h).expect("one step");
                            total += t.elapsed();
                        }
                        total
                    })
                })
            });
        }
        group.finish();
    }
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(10).measurement_time(Duration::from_secs(2)).warm_up_time(Duration::from_millis(500));
    targets = methods
}
criterion_main!(benches);
