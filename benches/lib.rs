//! Shared set-up for the benchmarks: the hanging-cloth fixture at Choi & Ko's
//! Table-1 scale (75 x 75 = 5625 particles), mid-swing.

use cloth_core::scene::{RunConfig, Scene};
use cloth_core::{ClothState, Simulation};
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
pub fn hanging_cloth(n: usize, steps: usize, preconditioner: &str) -> (Simulation, RunConfig, ClothState) {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../fixtures/scenes/hang.toml");
    let overrides = vec![
        format!("panels.0.particles=[{n}, {n}]"),
        format!("pins.0.nodes=[[0, {last}], [{last}, {last}]]", last = n - 1),
        format!("solver.preconditioner={preconditioner}"),
    ];
    let scene = Scene::parse_file(&path, &overrides).expect("fixture parses");
    let (model, cfg) = scene.build().expect("fixture builds");
    let mut sim = Simulation::new(model, cfg.integrator, cfg.solver);
    for _ in 0..steps {
        sim.step(cfg.dt_s).expect("fixture steps");
    }
    let state = sim.snapshot();
    (sim, cfg, state)
}
