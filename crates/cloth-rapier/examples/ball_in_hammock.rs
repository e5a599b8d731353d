//! A cloth hung between two rapier posts catches a rapier ball: the cloth
//! is built with `ClothModel::builder` (a scene file can describe the same
//! cloth), the bodies with rapier's own builders, and one call steps both.
//!
//! `cargo run --release -p cloth-rapier --example ball_in_hammock`

use cloth_core::{ClothModel, GridPanel, IntegratorKind, Material, PinMotion, PinSpec};
use cloth_rapier::rapier3d_f64::math::Vector;
use cloth_rapier::rapier3d_f64::prelude::{ColliderBuilder, RigidBodyBuilder};
use cloth_rapier::{ClothBuilder, ClothSet, CollideWith, Master, PhysicsWorld};

/// Step, s, and steps (3 s).
const DT_S: f64 = 1.0 / 90.0;
const STEPS: u64 = 270;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    // 1 x 0.6 m, 21 x 13 particles, its four corners held by the posts
    // (pins whose motion comes from outside: the bodies they attach to).
    let model = ClothModel::builder()
        .panel(GridPanel::flat([21, 13], [1.0, 0.6]).origin([-0.5, -0.3, 1.0]))
        .material(Material {
            areal_density_kg_m2: 0.2,
            tensile_stiffness_n_m: 2000.0,
            flexural_rigidity_n_m: 1e-5,
            buckling_stiffness_n_m: 2000.0,
            damping_n_s_m: 0.5,
            ..Material::default()
        })
        .gravity([0.0, 0.0, -9.81])
        .bending()
        .damping()
        .pin(PinSpec {
            nodes: vec![[0, 0], [0, 12], [20, 0], [20, 12]],
            motion: PinMotion::External,
            ..PinSpec::default()
        })
        .build()?;

    let mut world = PhysicsWorld::new();
    world.gravity = Vector::new(0.0, 0.0, -9.81); // the cloth's gravity: checked on insert
    world.integration_parameters.dt = DT_S;
    let mut posts = Vec::new();
    for x in [-0.55, 0.55] {
        let post = world.bodies.insert(RigidBodyBuilder::fixed().translation(Vector::new(x, 0.0, 1.0)));
        let collider =
            world.colliders.insert_with_parent(ColliderBuilder::capsule_y(0.5, 0.02), post, &mut world.bodies);
        posts.push((post, collider));
    }
    let ball = world.bodies.insert(RigidBodyBuilder::dynamic().translation(Vector::new(0.05, 0.02, 1.25)));
    world.colliders.insert_with_parent(ColliderBuilder::ball(0.1).mass(0.5).friction(0.4), ball, &mut world.bodies);

    // Pins 0 and 1 (x = -0.5) to the left post, 2 and 3 to the right one.
    let builder = ClothBuilder::new(model)
        .integrator(IntegratorKind::BackwardEuler)
        .attach(0, posts[0].0)
        .attach(1, posts[0].0)
        .attach(2, posts[1].0)
        .attach(3, posts[1].0)
        .collide_with(CollideWith::AllExcept(posts.iter().map(|p| p.1).collect()));
    let mut cloths = ClothSet::new();
    let hammock = cloths.insert(builder, &world)?;

    let master = Master::default(); // iterated to agreement
    let mut passes = 0;
    for step in 1..=STEPS {
        passes += cloths.step(&mut world, &master)?.iterations;
        if step % 45 == 0 {
            let z = world.bodies[ball].translation().z;
            let sim = cloths[hammock].simulation();
            let carried: f64 = (0..4).map(|k| -sim.pin_reaction(k).z).sum();
            println!("t = {:.2} s: ball at z = {z:.4} m; the posts carry {carried:.3} N", sim.time());
        }
    }
    println!("{:.1} coupling passes per step", passes as f64 / STEPS as f64);
    Ok(())
}
