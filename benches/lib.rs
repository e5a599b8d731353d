//! Shared set-up for the benchmarks: the hanging-cloth fixture at Choi & Ko's
//! Table-1 scale (75 x 75 = 5625 particles), mid-swing.

use cloth_core::scene::{RunConfig, Scene};
use cloth_core::{Simulation, Snapshot};
use std::path::PathBuf;

/// Threads used by every benchmark: the target machine's two cores.
pub const THREADS: usize = 2;

/// A rayon pool of [`THREADS`] threads.
pub fn pool() -> rayon::ThreadPool {
    rayon::ThreadPoolBuilder::new().num_threads(THREADS).build().expect("thread pool")
}

/// `hang.toml` with an `n x n` grid and the named preconditioner, advanced
/// by `steps` steps so the cloth is moving and its links are stretched and
/// buckled.
pub fn hanging_cloth(n: usize, steps: usize, preconditioner: &str) -> (Simulation, RunConfig, Snapshot) {
    hanging_cloth_with(n, steps, &[format!("solver.preconditioner={preconditioner}")])
}

/// As [`hanging_cloth`], with any scene overrides.
pub fn hanging_cloth_with(n: usize, steps: usize, extra: &[String]) -> (Simulation, RunConfig, Snapshot) {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../fixtures/scenes/hang.toml");
    let mut overrides = vec![
        format!("panels.0.particles=[{n}, {n}]"),
        format!("pins.0.nodes=[[0, {last}], [{last}, {last}]]", last = n - 1),
    ];
    overrides.extend_from_slice(extra);
    let scene = Scene::parse_file(&path, &overrides).expect("fixture parses");
    let (model, cfg) = scene.build().expect("fixture builds");
    let mut sim = cfg.simulation(model);
    for _ in 0..steps {
        sim.step(cfg.dt_s).expect("fixture steps");
    }
    let state = sim.snapshot();
    (sim, cfg, state)
}
