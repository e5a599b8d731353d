//! A body resting on cloth inside the cloth's solve.

use cloth_rapier::CoupledScene;

/// A 0.4 m cloth (9 x 9, 32 g) on a fixed table, a 0.5 kg box set on it:
/// once at rest, the table carries cloth plus box, as the cloth's contact
/// impulses on it say, and the box stays put on the cloth.
#[test]
fn the_table_under_a_clothed_box_carries_box_and_cloth() {
    let text = r#"
[simulation]
integrator = "bdf2"
dt_s = 0.01
duration_s = 1.5
effects = ["gravity", "bending", "damping"]
gravity_m_s2 = [0.0, 0.0, -9.81]

[solver]
rel_tol = 1e-9
max_iter = 1000

[material]
areal_density_kg_m2 = 0.2
tensile_stiffness_n_m = 2000.0
flexural_rigidity_n_m = 1e-5
buckling_stiffness_n_m = 2000.0
damping_n_s_m = 0.5

[[panels]]
particles = [9, 9]
size_m = [0.4, 0.4]
origin_m = [-0.2, -0.2, 0.0051]

[[bodies]]
name = "table"
kind = "fixed"
shape = { kind = "cuboid", half_extents_m = [0.5, 0.5, 0.05] }
position_m = [0.0, 0.0, -0.05]
friction = 0.3

[[bodies]]
name = "box"
kind = "dynamic"
shape = { kind = "cuboid", half_extents_m = [0.06, 0.06, 0.04] }
position_m = [0.0, 0.0, 0.052]
mass_kg = 0.5
friction = 0.4
"#;
    let mut run = CoupledScene::parse(text, &[]).unwrap().build().unwrap();
    let find = |name: &str| run.bodies.iter().find(|b| b.name == name).unwrap().handle;
    let (table, boxed) = (find("table"), find("box"));
    let solid = run.cloths[run.cloth].world_solids().iter().find(|s| s.body == Some(table)).unwrap().solid;
    let h = run.config.dt_s;
    let mut load = Vec::new();
    let mut passes = 0;
    for step in 0..run.config.steps {
        passes += run.step().unwrap().iterations;
        if step + 20 >= run.config.steps {
            let sim = run.cloths[run.cloth].simulation();
            load.push(-sim.solid_impulse(solid, nalgebra::Vector3::zeros()).linear.z / h);
        }
    }
    let sim = run.cloths[run.cloth].simulation();
    let cloth_mass: f64 = sim.model().masses().iter().sum();
    let b = &run.world.bodies[boxed];
    let weight = (cloth_mass + b.mass()) * 9.81;
    let carried = load.iter().sum::<f64>() / load.len() as f64;
    let speed = b.linvel().length();
    println!(
        "table carries {carried:.9} N of {weight:.9} N ({:.2e} relative); box at {:.5} m, {speed:.2e} m/s; \
         {:.2} passes a step; deepest particle {:.2e} m inside a solid",
        carried / weight - 1.0,
        b.translation().z,
        passes as f64 / run.config.steps as f64,
        sim.max_penetration()
    );
    // Measured: equal to the last bit printed (0 relative), at rest to 1.4e-15 m/s.
    assert!((carried / weight - 1.0).abs() < 1e-12, "the table carries {carried} N of {weight} N");
    assert!(speed < 1e-13, "the box rests: {speed} m/s");
}
