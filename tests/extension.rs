//! Extending the library from outside its crates: an integrator written
//! here, plugged into a `Simulation` through `SimulationBuilder`.

use cloth_core::{
    ClothModel, ClothState, Control, GridPanel, Integrator, IntegratorKind, Simulation, SolverParams, StepError,
    StepReport, Workspace, forces,
};

/// Symplectic Euler (`v' = v + h f / m`, `x' = x + h v'`) with fixed pins,
/// written with the public force loop only.
#[derive(Debug)]
struct OutsideSymplecticEuler;

impl Integrator for OutsideSymplecticEuler {
    fn name(&self) -> &'static str {
        "outside-symplectic-euler"
    }

    fn step(
        &self,
        model: &ClothModel,
        state: &mut ClothState,
        _control: &Control,
        h: f64,
        _ws: &mut Workspace,
        _solver: &SolverParams,
    ) -> Result<StepReport, StepError> {
        let f = forces::total_forces(model, &state.x, &state.v, &state.stitches_closed);
        let (x_prev, v_prev) = (state.x.clone(), state.v.clone());
        for (i, ((x, v), f)) in state.x.iter_mut().zip(&mut state.v).zip(&f).enumerate() {
            if model.is_pinned(i) {
                *v = cloth_core::Vec3::zeros();
                continue;
            }
            *v += f * (h / model.masses()[i]);
            *x += *v * h;
        }
        (state.x_prev, state.v_prev) = (x_prev, v_prev);
        (state.time_s, state.steps, state.last_dt_s, state.has_history) = (state.time_s + h, state.steps + 1, h, true);
        Ok(StepReport { force_evaluations: 1, substeps: 1, converged: true, ..Default::default() })
    }
}

fn hanging_cloth() -> ClothModel {
    ClothModel::builder()
        .panel(GridPanel::flat([11, 11], [0.5, 0.5]).origin([0.0, 0.0, 1.0]))
        .gravity([0.0, 0.0, -9.81])
        .damping()
        .pin_nodes(0, [[0, 10], [10, 10]])
        .build()
        .unwrap()
}

/// The outside integrator swings the cloth as the built-in symplectic
/// Euler does, bit for bit, and the simulation reports its name.
#[test]
fn an_integrator_from_outside_the_crate_steps_a_simulation() {
    let h = 2e-4;
    let mut outside = Simulation::builder(hanging_cloth()).custom_integrator(Box::new(OutsideSymplecticEuler)).build();
    let mut built_in = Simulation::builder(hanging_cloth()).integrator(IntegratorKind::SymplecticEuler).build();
    assert_eq!(outside.integrator_name(), "outside-symplectic-euler");
    assert_eq!(built_in.integrator_name(), "symplectic-euler");
    for _ in 0..500 {
        outside.step(h).unwrap();
        built_in.step(h).unwrap();
    }
    let gap = outside.state().x.iter().zip(&built_in.state().x).map(|(a, b)| (a - b).norm()).fold(0.0, f64::max);
    let fall = 1.0 - outside.state().x.iter().map(|p| p.z).fold(f64::INFINITY, f64::min);
    println!("after 0.1 s: {gap:e} m apart, lowest point {fall:.4} m down");
    assert!(fall > 0.04, "the cloth fell only {fall} m");
    assert_eq!(gap, 0.0, "the same arithmetic in the same order");
}
