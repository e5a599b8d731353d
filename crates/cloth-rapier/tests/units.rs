//! The rapier world and the cloth as co-simulation units reach the same
//! coupled motion as `ClothSet::step`: both iterate to the same fixed point.

use cloth_cosim::{
    ClothUnit, CoSimulation, Connection, InputOverStep, IteratedParams, Master as CosimMaster, Port, Unit, UnitError,
};
use cloth_rapier::{CoupledRun, CoupledScene, IteratedCoupling, Master, RapierUnit};

const SCENE: &str = r#"
[simulation]
integrator = "backward-euler"
dt_s = 0.005
duration_s = 0.2
effects = ["gravity", "bending", "damping"]

[solver]
rel_tol = 1e-12
max_iter = 2000

[material]
areal_density_kg_m2 = 0.1
tensile_stiffness_n_m = 500.0
flexural_rigidity_n_m = 1e-5
buckling_stiffness_n_m = 500.0
damping_n_s_m = 0.05

[[panels]]
particles = [11, 11]
size_m = [0.5, 0.5]
origin_m = [-0.25, -0.25, 0.0]

[[pins]]
nodes = [[0, 0], [10, 0], [0, 10], [10, 10]]

[[bodies]]
name = "ball"
kind = "dynamic"
shape = { kind = "ball", radius_m = 0.06 }
position_m = [0.01, 0.0, 0.07]
velocity_m_s = [0.0, 0.0, -1.0]
mass_kg = 0.02
friction = 0.3
"#;

fn build() -> CoupledRun {
    CoupledScene::parse(SCENE, &[]).unwrap().build().unwrap()
}

#[test]
fn units_under_the_iterated_master_agree_with_the_cloth_set() {
    let tight = IteratedCoupling { abs_tol_m_s: 1e-10, rel_tol: 1e-10, max_iterations: 40, ..Default::default() };
    let mut direct = build();
    for _ in 0..direct.config.steps {
        direct.step_with(&Master::Iterated(tight)).unwrap();
    }
    let ball_direct = direct.world.bodies[direct.bodies[0].handle].translation();

    let mut run = build();
    let (h, steps) = (run.config.dt_s, run.config.steps);
    let ball = run.bodies[0].handle;
    let solid = run.cloths[run.cloth].world_solids().iter().find(|s| s.body == Some(ball)).unwrap().solid;
    let sim = run.cloths.remove(run.cloth).unwrap();
    // Rapier steps first and hands on its bodies' end poses.
    let cloth = ClothUnit::new("cloth", sim).with_solids_at_step_end();
    let rapier = RapierUnit::new("rapier", run.world, vec![ball]).unwrap();
    let mut connections = Vec::new();
    let port = |unit: usize, u: &dyn Unit, name: &str| Port { unit, var: u.find(name).unwrap() };
    for axis in ["x", "y", "z"] {
        for field in ["position", "rotation", "velocity", "angular_velocity"] {
            let from = port(0, &rapier, &format!("body0.{field}.{axis}"));
            connections.push(Connection { from, to: port(1, &cloth, &format!("solid{solid}.{field}.{axis}")) });
        }
        for field in ["force", "torque"] {
            let from = port(1, &cloth, &format!("solid{solid}.{field}.{axis}"));
            connections.push(Connection { from, to: port(0, &rapier, &format!("body0.{field}.{axis}")) });
        }
    }
    let params = IteratedParams {
        inputs: InputOverStep::EndValue,
        abs_tol: 1e-10,
        rel_tol: 1e-10,
        accept_unconverged: true,
        ..Default::default()
    };
    let mut cosim =
        CoSimulation::new(vec![Box::new(rapier), Box::new(cloth)], connections, CosimMaster::Iterated(params)).unwrap();
    let mut iterations = 0;
    for _ in 0..steps {
        iterations += cosim.step(h).unwrap().iterations;
    }
    let z = |name: &str| cosim.get(Port { unit: 0, var: cosim.unit(0).find(name).unwrap() }).unwrap();
    let gap =
        ((z("body0.position.x") - ball_direct.x).powi(2) + (z("body0.position.z") - ball_direct.z).powi(2)).sqrt();
    println!(
        "after {steps} steps: ball z {:.6} m (ClothSet) and {:.6} m (units, {:.1} iterations/step); gap {gap:.2e} m",
        ball_direct.z,
        z("body0.position.z"),
        iterations as f64 / steps as f64
    );
    assert!(ball_direct.z > -0.2 && z("body0.velocity.z").abs() < 1.0, "the cloth catches the ball");
    assert!(gap < 1e-11, "the two routes differ by {gap} m");
}

#[test]
fn the_rapier_unit_refuses_what_it_cannot_do() {
    let run = build();
    let ball = run.bodies[0].handle;
    let mut unit = RapierUnit::new("rapier", run.world, vec![ball]).unwrap();
    let out = unit.find("body0.position.z").unwrap();
    assert!(matches!(unit.set(out, 1.0), Err(UnitError::Causality { .. })));
    let force = unit.find("body0.force.z").unwrap();
    assert!(matches!(unit.set(force, f64::NAN), Err(UnitError::InvalidValue { .. })));
    assert!(matches!(unit.do_step(1.0, 0.01), Err(UnitError::StepFailed { .. })));
    let state = unit.get_state();
    assert!(matches!(unit.serialize_state(&state), Err(UnitError::Unsupported { .. })));
}
