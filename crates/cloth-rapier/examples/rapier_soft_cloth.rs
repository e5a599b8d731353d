//! rapier's own cloth (`SoftBodyBuilder::cloth`) beside this library's, on
//! three scenes at h = 1/90 s:
//!
//! - **hang**: 1 m square, 41 x 41 particles, 0.1 kg, hung from two
//!   corners for 2 s;
//! - **drape**: the same square dropped from 0.1 m onto a fixed ball of
//!   radius 0.3 m (friction 0.3) for 2 s, as `fixtures/scenes/drape-sphere.toml`;
//! - **hammock**: 1.0 x 0.6 m, 21 x 13 particles, 0.12 kg, held at its four
//!   corners, catching a 0.5 kg dynamic ball of radius 0.1 m for 4 s, as
//!   `fixtures/scenes/hammock.toml`.
//!
//! Each row gives the wall time a step (median of the steps), the worst
//! structural-edge stretch at the end and over the run, and what the scene
//! asks of contact and coupling: how deep the cloth sank into the ball,
//! how fast anything still moves at the end, where the ball came to rest.
//!
//!     cargo run --release -p cloth-rapier --example rapier_soft_cloth
//!
//! rapier's cloth takes its stiffness as a natural frequency and damping
//! ratio per constraint family (its default: edges at 30 Hz), not as a
//! fabric's tensile stiffness in N/m; its rows are its default and a
//! stiffer 200 Hz. This library's rows are Choi & Ko's cloth with the
//! fixtures' materials: BDF2 for hang and drape, backward Euler with the
//! ball inside the cloth's solve (the monolithic master) for the hammock.

use cloth_core::Simulation;
use cloth_core::scene::Scene;
use cloth_rapier::CoupledScene;
use rapier3d_f64::prelude::{
    ColliderBuilder, PhysicsWorld, RigidBodyBuilder, RigidBodyHandle, SoftBodyBuilder, SoftBodyHandle,
    SoftBodyMaterial, SpringCoefficients, Vector,
};
use std::path::{Path, PathBuf};
use std::time::Instant;

const H: f64 = 1.0 / 90.0;

/// A grid cloth: particles along x and y, size (m), mass (kg), where its
/// first particle sits (m), and how long it runs (steps).
#[derive(Clone, Copy)]
struct Grid {
    n: [usize; 2],
    size: [f64; 2],
    mass: f64,
    origin: [f64; 3],
    steps: usize,
}

const HANG: Grid = Grid { n: [41, 41], size: [1.0, 1.0], mass: 0.1, origin: [0.0, 0.0, 1.0], steps: 180 };
const DRAPE: Grid = Grid { n: [41, 41], size: [1.0, 1.0], mass: 0.1, origin: [-0.5, -0.5, 0.4], steps: 180 };
const HAMMOCK: Grid = Grid { n: [21, 13], size: [1.0, 0.6], mass: 0.12, origin: [-0.5, -0.3, 1.0], steps: 360 };

/// The drape's fixed ball (radius, m, at the origin) and the hammock's
/// dynamic one (radius m, mass kg, start m, friction, damping 1/s).
const DRAPE_BALL_R: f64 = 0.3;
const BALL_R: f64 = 0.1;
const BALL_KG: f64 = 0.5;
const BALL_START: [f64; 3] = [0.05, 0.02, 1.25];

impl Grid {
    fn spacing(&self) -> [f64; 2] {
        [self.size[0] / (self.n[0] - 1) as f64, self.size[1] / (self.n[1] - 1) as f64]
    }

    /// Worst structural-edge stretch, `at(i, j)` the position of particle
    /// (i along x, j along y).
    fn stretch(&self, at: impl Fn(usize, usize) -> [f64; 3]) -> f64 {
        let [dx, dy] = self.spacing();
        let length =
            |a: [f64; 3], b: [f64; 3]| ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt();
        let mut worst: f64 = 0.0;
        for i in 0..self.n[0] {
            for j in 0..self.n[1] {
                if i + 1 < self.n[0] {
                    worst = worst.max(length(at(i, j), at(i + 1, j)) / dx);
                }
                if j + 1 < self.n[1] {
                    worst = worst.max(length(at(i, j), at(i, j + 1)) / dy);
                }
            }
        }
        worst
    }
}

/// What a run measured.
#[derive(Default)]
struct Row {
    cloth: String,
    ms_per_step: f64,
    end_stretch: f64,
    peak_stretch: f64,
    /// Lowest cloth point at the end, m.
    lowest_z: f64,
    /// Deepest any particle went inside the ball over the run, m
    /// (0 when none did).
    ball_depth: f64,
    /// Fastest particle at the end, m/s.
    cloth_speed: f64,
    /// The hammock's ball at the end: height (m) and speed (m/s).
    ball: Option<(f64, f64)>,
    /// When the hammock's ball fell below the whole cloth, s.
    ball_out_s: Option<f64>,
    /// Whether every position stayed finite.
    finite: bool,
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn norm(v: [f64; 3]) -> f64 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}

/// How deep `p` is inside a ball of radius `r` at `c`, m (0 outside).
fn depth_in_ball(p: [f64; 3], c: [f64; 3], r: f64) -> f64 {
    (r - norm([p[0] - c[0], p[1] - c[1], p[2] - c[2]])).max(0.0)
}

/// A ball the cloth meets after a step: centre and radius, m; `moves`
/// for the hammock's, whose fall below the whole cloth is watched.
struct Ball {
    centre: [f64; 3],
    radius: f64,
    moves: bool,
}

impl Row {
    /// Takes in the state after step `k` (from 1): the cloth's positions
    /// `x`, particle (i along x, j along y) at `x[index(i, j)]`, and the
    /// ball, if the scene has one. Both libraries are measured by this.
    fn observe(
        &mut self,
        g: &Grid,
        k: usize,
        x: &[[f64; 3]],
        index: impl Fn(usize, usize) -> usize,
        ball: Option<Ball>,
    ) {
        self.peak_stretch = self.peak_stretch.max(g.stretch(|i, j| x[index(i, j)]));
        if let Some(b) = ball {
            self.ball_depth = x.iter().fold(self.ball_depth, |d, &p| d.max(depth_in_ball(p, b.centre, b.radius)));
            let lowest = x.iter().map(|p| p[2]).fold(f64::INFINITY, f64::min);
            if b.moves && self.ball_out_s.is_none() && b.centre[2] < lowest {
                self.ball_out_s = Some(k as f64 * H);
            }
        }
    }

    /// Takes in the end of the run: the steps' wall times (s), the
    /// positions as for [`Row::observe`] and the fastest particle (m/s).
    fn finish(
        &mut self,
        g: &Grid,
        times: Vec<f64>,
        x: &[[f64; 3]],
        index: impl Fn(usize, usize) -> usize,
        fastest: f64,
    ) {
        self.ms_per_step = 1e3 * median(times);
        self.end_stretch = g.stretch(|i, j| x[index(i, j)]);
        self.lowest_z = x.iter().map(|p| p[2]).fold(f64::INFINITY, f64::min);
        self.cloth_speed = fastest;
        self.finite = x.iter().flatten().all(|c| c.is_finite());
    }
}

#[derive(Clone, Copy, PartialEq)]
enum Case {
    Hang,
    Drape,
    Hammock,
}

impl Case {
    fn grid(self) -> Grid {
        match self {
            Case::Hang => HANG,
            Case::Drape => DRAPE,
            Case::Hammock => HAMMOCK,
        }
    }
}

/// One scene with rapier's cloth, its edges at `edge_hz`.
fn rapier_cloth(case: Case, edge_hz: f64) -> Row {
    let g = case.grid();
    let mut world = PhysicsWorld::new();
    world.gravity = Vector::new(0.0, 0.0, -9.81);
    world.integration_parameters.dt = H;
    let [dx, dy] = g.spacing();
    let [nx, ny] = g.n;
    let index = |i: usize, j: usize| (i * ny + j) as u32;
    let pins: Vec<u32> = match case {
        Case::Hang => vec![index(0, ny - 1), index(nx - 1, ny - 1)],
        Case::Drape => vec![],
        Case::Hammock => vec![index(0, 0), index(0, ny - 1), index(nx - 1, 0), index(nx - 1, ny - 1)],
    };
    let friction = if case == Case::Hammock { 0.4 } else { 0.3 };
    let material =
        SoftBodyMaterial { edge_softness: SpringCoefficients::new(edge_hz, 1.0), ..SoftBodyMaterial::default() };
    let cloth =
        SoftBodyBuilder::cloth(Vector::from(g.origin), Vector::new(dx, 0.0, 0.0), Vector::new(0.0, dy, 0.0), nx, ny)
            .mass(g.mass)
            .material(material)
            .surface_collider(ColliderBuilder::ball(0.05).density(0.0).friction(friction))
            .pinned_particles(pins);
    let ball: Option<RigidBodyHandle> = match case {
        Case::Hang => None,
        Case::Drape => {
            world.colliders.insert(ColliderBuilder::ball(DRAPE_BALL_R).friction(0.3));
            None
        }
        Case::Hammock => {
            let b = world.bodies.insert(
                RigidBodyBuilder::dynamic()
                    .translation(Vector::from(BALL_START))
                    .linear_damping(2.0)
                    .angular_damping(2.0),
            );
            world.colliders.insert_with_parent(
                ColliderBuilder::ball(BALL_R).mass(BALL_KG).friction(0.4),
                b,
                &mut world.bodies,
            );
            Some(b)
        }
    };
    let PhysicsWorld { soft_bodies, bodies, colliders, .. } = &mut world;
    let handle = soft_bodies.insert(cloth, bodies, colliders);
    let positions = |world: &PhysicsWorld, handle: SoftBodyHandle| -> Vec<[f64; 3]> {
        world.soft_bodies.get(handle).expect("inserted").particle_positions().map(|p| [p.x, p.y, p.z]).collect()
    };
    let mut row = Row { cloth: format!("rapier `SoftBodyBuilder::cloth`, edges at {edge_hz} Hz"), ..Row::default() };
    // rapier numbers particle (i, j) as i ny + j.
    let at = |i: usize, j: usize| i * ny + j;
    let the_ball = |world: &PhysicsWorld| match (case, ball) {
        (Case::Drape, _) => Some(Ball { centre: [0.0; 3], radius: DRAPE_BALL_R, moves: false }),
        (_, Some(b)) => Some(Ball { centre: world.bodies[b].translation().into(), radius: BALL_R, moves: true }),
        _ => None,
    };
    let mut times = Vec::with_capacity(g.steps);
    for k in 1..=g.steps {
        let t = Instant::now();
        world.step();
        times.push(t.elapsed().as_secs_f64());
        row.observe(&g, k, &positions(&world, handle), at, the_ball(&world));
    }
    let soft = world.soft_bodies.get(handle).expect("inserted");
    let fastest = soft.particle_velocities().map(|v| v.length()).fold(0.0, f64::max);
    row.finish(&g, times, &positions(&world, handle), at, fastest);
    row.ball = ball.map(|b| (world.bodies[b].translation().z, world.bodies[b].linvel().length()));
    row
}

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/scenes").join(name)
}

/// This library's positions, and where its grid panel keeps particle (i
/// along x, j along y).
fn ours(sim: &Simulation) -> Vec<[f64; 3]> {
    sim.state().x.iter().map(|p| (*p).into()).collect()
}

/// Hang or drape with this library, from the fixture.
fn this_library_cloth(case: Case) -> Row {
    let g = case.grid();
    let [nx, ny] = g.n;
    let (file, extra) = match case {
        Case::Hang => (
            "hang.toml",
            vec![
                format!("panels.0.particles=[{nx}, {ny}]"),
                format!("panels.0.size_m=[{}, {}]", g.size[0], g.size[1]),
                format!("pins.0.nodes=[[0, {}], [{}, {}]]", ny - 1, nx - 1, ny - 1),
                format!("material.areal_density_kg_m2={}", g.mass / (g.size[0] * g.size[1])),
                "simulation.integrator=\"bdf2\"".to_string(),
            ],
        ),
        _ => ("drape-sphere.toml", vec![]),
    };
    let scene = Scene::parse_file(&fixture(file), &extra).expect("the fixture");
    let (model, cfg) = scene.build().expect("builds");
    let mut sim = cfg.simulation(model);
    let at = |i: usize, j: usize| j * nx + i;
    let ball = || (case == Case::Drape).then_some(Ball { centre: [0.0; 3], radius: DRAPE_BALL_R, moves: false });
    let mut row = Row { cloth: "this library, Choi & Ko, BDF2".to_string(), ..Row::default() };
    let mut times = Vec::with_capacity(g.steps);
    for k in 1..=g.steps {
        let t = Instant::now();
        sim.step(H).expect("steps");
        times.push(t.elapsed().as_secs_f64());
        row.observe(&g, k, &ours(&sim), at, ball());
    }
    row.finish(&g, times, &ours(&sim), at, fastest(&sim));
    row
}

/// The hammock with this library, its ball inside the cloth's solve.
fn this_library_hammock() -> Row {
    let g = HAMMOCK;
    let mut run = CoupledScene::load(&fixture("hammock.toml"), &[]).expect("the fixture").build().expect("builds");
    let ball = run.bodies.iter().find(|b| b.name == "ball").expect("the fixture's ball").handle;
    let at = |i: usize, j: usize| j * g.n[0] + i;
    let mut row =
        Row { cloth: "this library, Choi & Ko, backward Euler, ball in the solve".to_string(), ..Row::default() };
    let mut times = Vec::with_capacity(g.steps);
    for k in 1..=g.steps {
        let t = Instant::now();
        run.step().expect("steps");
        times.push(t.elapsed().as_secs_f64());
        let centre = run.world.bodies[ball].translation().into();
        let x = ours(run.cloths[run.cloth].simulation());
        row.observe(&g, k, &x, at, Some(Ball { centre, radius: BALL_R, moves: true }));
    }
    let sim = run.cloths[run.cloth].simulation();
    row.finish(&g, times, &ours(sim), at, fastest(sim));
    let b = &run.world.bodies[ball];
    row.ball = Some((b.translation().z, b.linvel().length()));
    row
}

/// This library's fastest particle, m/s.
fn fastest(sim: &Simulation) -> f64 {
    sim.state().v.iter().map(|v| v.norm()).fold(0.0, f64::max)
}

fn main() {
    for (title, case) in [("hang", Case::Hang), ("drape on a ball", Case::Drape), ("ball on a hammock", Case::Hammock)]
    {
        let ours = if case == Case::Hammock { this_library_hammock() } else { this_library_cloth(case) };
        let rows = [rapier_cloth(case, 30.0), rapier_cloth(case, 200.0), ours];
        println!("\n{title} ({} s)\n", case.grid().steps as f64 * H);
        println!(
            "| cloth | ms / step | edge stretch at the end | worst over the run | lowest point (m) | deepest in the ball (mm) | fastest particle at the end (m/s) | ball z (m), speed (m/s) at the end |"
        );
        println!("|---|---|---|---|---|---|---|---|");
        for r in rows {
            let ball = match (r.ball, r.ball_out_s) {
                (_, Some(t)) => format!("fell out at {t:.2} s"),
                (Some((z, v)), None) => format!("{z:.3}, {v:.4}"),
                (None, None) => "-".to_string(),
            };
            let depth = if case == Case::Hang { "-".to_string() } else { format!("{:.1}", 1e3 * r.ball_depth) };
            let blew = if r.finite { "" } else { " (not finite)" };
            println!(
                "| {}{blew} | {:.2} | {:.3} | {:.3} | {:.3} | {depth} | {:.3} | {ball} |",
                r.cloth, r.ms_per_step, r.end_stretch, r.peak_stretch, r.lowest_z, r.cloth_speed
            );
        }
    }
}
