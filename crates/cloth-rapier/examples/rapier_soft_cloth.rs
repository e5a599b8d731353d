//! rapier's own cloth (`SoftBodyBuilder::cloth`) beside this library's, on
//! the same hanging cloth: 1 m square, 41 x 41 particles, 0.1 kg, hung
//! from two corners for 2 s at 1/90 s. Prints, for each, the wall time a
//! step (median of the steps), the worst stretch of a structural edge at
//! the end and over the run, and how far the cloth sagged.
//!
//!     cargo run --release -p cloth-rapier --example rapier_soft_cloth
//!
//! rapier's cloth takes its stiffness as a natural frequency and damping
//! ratio per constraint family (its default: edges at 30 Hz), not as a
//! fabric's tensile stiffness in N/m; its rows here are its default and a
//! stiffer 200 Hz. This library's row is Choi & Ko's cloth at the hang
//! fixture's E = 200 N/m with BDF2 (the accurate reference).

use cloth_core::scene::Scene;
use rapier3d_f64::prelude::{PhysicsWorld, SoftBodyBuilder, SoftBodyMaterial, SpringCoefficients, Vector};
use std::path::Path;
use std::time::Instant;

const N: usize = 41;
const SIZE: f64 = 1.0;
const MASS: f64 = 0.1;
const H: f64 = 1.0 / 90.0;
const STEPS: usize = 180;

/// Worst structural-edge stretch of a grid of `N x N` positions, `at(i, j)`.
fn grid_stretch(at: impl Fn(usize, usize) -> [f64; 3]) -> f64 {
    let rest = SIZE / (N - 1) as f64;
    let length =
        |a: [f64; 3], b: [f64; 3]| ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt();
    let mut worst: f64 = 0.0;
    for i in 0..N {
        for j in 0..N {
            if i + 1 < N {
                worst = worst.max(length(at(i, j), at(i + 1, j)) / rest);
            }
            if j + 1 < N {
                worst = worst.max(length(at(i, j), at(i, j + 1)) / rest);
            }
        }
    }
    worst
}

struct Row {
    name: String,
    ms_per_step: f64,
    end_stretch: f64,
    peak_stretch: f64,
    lowest_z: f64,
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn rapier_cloth(edge_hz: f64) -> Row {
    let mut world = PhysicsWorld::new();
    world.gravity = Vector::new(0.0, 0.0, -9.81);
    world.integration_parameters.dt = H;
    let spacing = SIZE / (N - 1) as f64;
    // Particle (i, j) at origin + i du + j dv, index i N + j; pinned at (0, N-1) and (N-1, N-1).
    let corners = [(N - 1) as u32, ((N - 1) * N + N - 1) as u32];
    let material =
        SoftBodyMaterial { edge_softness: SpringCoefficients::new(edge_hz, 1.0), ..SoftBodyMaterial::default() };
    let cloth = SoftBodyBuilder::cloth(
        Vector::new(0.0, 0.0, 1.0),
        Vector::new(spacing, 0.0, 0.0),
        Vector::new(0.0, spacing, 0.0),
        N,
        N,
    )
    .mass(MASS)
    .material(material)
    .pinned_particles(corners);
    let PhysicsWorld { soft_bodies, bodies, colliders, .. } = &mut world;
    let handle = soft_bodies.insert(cloth, bodies, colliders);
    let mut times = Vec::with_capacity(STEPS);
    let mut peak: f64 = 0.0;
    let stretch = |world: &PhysicsWorld| {
        let x: Vec<Vector> = world.soft_bodies.get(handle).expect("inserted").particle_positions().collect();
        grid_stretch(|i, j| {
            let p = x[i * N + j];
            [p.x, p.y, p.z]
        })
    };
    for _ in 0..STEPS {
        let t = Instant::now();
        world.step();
        times.push(t.elapsed().as_secs_f64());
        peak = peak.max(stretch(&world));
    }
    let lowest = world
        .soft_bodies
        .get(handle)
        .expect("inserted")
        .particle_positions()
        .map(|p| p.z)
        .fold(f64::INFINITY, f64::min);
    Row {
        name: format!("rapier SoftBodyBuilder::cloth, edges at {edge_hz} Hz"),
        ms_per_step: 1e3 * median(times),
        end_stretch: stretch(&world),
        peak_stretch: peak,
        lowest_z: lowest,
    }
}

fn this_library(integrator: &str) -> Row {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/scenes/hang.toml");
    let overrides = vec![
        format!("panels.0.particles=[{N}, {N}]"),
        format!("panels.0.size_m=[{SIZE}, {SIZE}]"),
        format!("pins.0.nodes=[[0, {}], [{}, {}]]", N - 1, N - 1, N - 1),
        format!("simulation.integrator=\"{integrator}\""),
        format!("material.areal_density_kg_m2={}", MASS / (SIZE * SIZE)),
    ];
    let scene = Scene::parse_file(&path, &overrides).expect("the hang fixture");
    let (model, cfg) = scene.build().expect("builds");
    let mut sim = cfg.simulation(model);
    let stretch = |sim: &cloth_core::Simulation| {
        let x = &sim.state().x;
        grid_stretch(|i, j| {
            let p = x[j * N + i];
            [p.x, p.y, p.z]
        })
    };
    let (mut times, mut peak) = (Vec::with_capacity(STEPS), 0.0f64);
    for _ in 0..STEPS {
        let t = Instant::now();
        sim.step(H).expect("steps");
        times.push(t.elapsed().as_secs_f64());
        peak = peak.max(stretch(&sim));
    }
    Row {
        name: format!("this library, Choi & Ko at E = 200 N/m, {integrator}"),
        ms_per_step: 1e3 * median(times),
        end_stretch: stretch(&sim),
        peak_stretch: peak,
        lowest_z: sim.state().x.iter().map(|p| p.z).fold(f64::INFINITY, f64::min),
    }
}

fn main() {
    let rows = [rapier_cloth(30.0), rapier_cloth(200.0), this_library("bdf2")];
    println!("| cloth | ms / step | edge stretch at 2 s | worst edge stretch | lowest point (m) |");
    println!("|---|---|---|---|---|");
    for r in rows {
        println!(
            "| {} | {:.2} | {:.4} | {:.4} | {:.3} |",
            r.name, r.ms_per_step, r.end_stretch, r.peak_stretch, r.lowest_z
        );
    }
}
