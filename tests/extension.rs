//! Extending the library from outside its crates: an integrator and a
//! force term written here, plugged in through the builders.

use cloth_core::forces::{self, ForceBuffers};
use cloth_core::terms::{At, ForceTerm, VertexBlock};
use cloth_core::{
    Capabilities, ClothModel, Contacts, GridPanel, Integrator, IntegratorKind, Mat3, Simulation, SolverParams,
    StageTimer, Step, StepError, StepOutput, StepReport, Vec3,
};
use std::sync::Arc;

/// Symplectic Euler (`v' = v + h f / m`, `x' = x + h v'`) with fixed pins,
/// written with the public force loop only; its scratch (the forces and
/// the force loop's buffers) is its own, allocated on its first step.
#[derive(Debug, Default)]
struct OutsideSymplecticEuler {
    scratch: Option<(ForceBuffers, Vec<Vec3>)>,
}

impl Integrator for OutsideSymplecticEuler {
    fn name(&self) -> &'static str {
        "outside-symplectic-euler"
    }

    fn capabilities(&self) -> Capabilities {
        Capabilities::default()
    }

    fn solve(
        &mut self,
        step: &Step<'_>,
        _: &mut Contacts,
        out: &mut StepOutput,
        _: &mut StageTimer,
    ) -> Result<StepReport, StepError> {
        let (model, state, h) = (step.model, step.state, step.h);
        let (buffers, f) =
            self.scratch.get_or_insert_with(|| (ForceBuffers::new(model), vec![Vec3::zeros(); model.particle_count()]));
        forces::forces_into(model, &state.x, &state.v, &state.stitches_closed, buffers, f);
        let (x, v) = out.state_mut();
        for i in 0..state.len() {
            if model.is_pinned(i) {
                (x[i], v[i]) = (state.x[i], Vec3::zeros());
                continue;
            }
            v[i] = state.v[i] + f[i] * (h / model.masses()[i]);
            x[i] = state.x[i] + v[i] * h;
        }
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
    let mut outside =
        Simulation::builder(hanging_cloth()).custom_integrator(Box::<OutsideSymplecticEuler>::default()).build();
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

/// A harmonic well of the caller's own: every particle pulled towards its
/// anchor with `f_i = -m_i w^2 (x_i - a_i)`, energy `m_i w^2 |x_i - a_i|^2 / 2`.
#[derive(Debug)]
struct Well {
    anchors: Vec<Vec3>,
    omega_rad_s: f64,
}

impl ForceTerm for Well {
    fn name(&self) -> &'static str {
        "well"
    }

    fn acts_on(&self, _: &ClothModel) -> bool {
        true
    }

    fn energy(&self, at: &At<'_>) -> f64 {
        let k = self.omega_rad_s * self.omega_rad_s;
        at.x.iter()
            .zip(&self.anchors)
            .zip(at.model.masses())
            .map(|((x, a), m)| 0.5 * m * k * (x - a).norm_squared())
            .sum()
    }

    fn add_forces(&self, at: &At<'_>, _: &mut ForceBuffers, out: &mut [Vec3]) {
        for (i, f) in out.iter_mut().enumerate() {
            *f += self.vertex(at, i).force;
        }
    }

    fn vertex(&self, at: &At<'_>, i: usize) -> VertexBlock {
        let k = at.model.masses()[i] * self.omega_rad_s * self.omega_rad_s;
        VertexBlock { force: (self.anchors[i] - at.x[i]) * k, stiffness: Mat3::identity() * k, ..VertexBlock::zero() }
    }
}

/// The free cloth in the well, 1 cm above its anchors: it moves as one,
/// `z(t) = a + d cos(w t)`, its links never stretched.
fn in_a_well(omega_rad_s: f64, d: f64) -> ClothModel {
    let free =
        ClothModel::builder().panel(GridPanel::flat([9, 9], [0.4, 0.4]).origin([0.0, 0.0, 1.0])).bending().damping();
    let anchors = free.build().unwrap().rest_positions().iter().map(|p| p - Vec3::new(0.0, 0.0, d)).collect();
    free.force_term(Arc::new(Well { anchors, omega_rad_s })).build().unwrap()
}

fn mean_height(sim: &Simulation) -> f64 {
    sim.state().x.iter().map(|p| p.z).sum::<f64>() / sim.state().len() as f64
}

/// A force term from outside the crate acts in the explicit and in the
/// implicit steps: the cloth swings in the well at `w`.
#[test]
fn a_force_term_from_outside_the_crate_swings_the_cloth_at_its_frequency() {
    let (omega, d) = (2.0 * std::f64::consts::PI, 0.01);
    let anchor_z = 1.0 - d;
    // Symplectic Euler, 1e-4 s: after a whole period, back where it began.
    let mut explicit = Simulation::builder(in_a_well(omega, d)).integrator(IntegratorKind::SymplecticEuler).build();
    for _ in 0..10_000 {
        explicit.step(1e-4).unwrap();
    }
    let explicit_error = (mean_height(&explicit) - (anchor_z + d)).abs();
    // BDF2 and backward Euler, 1 ms: after half a period, on the far
    // side, less their numerical damping.
    let half_period = |integrator| {
        let solver = SolverParams { rel_tol: 1e-10, ..SolverParams::default() };
        let mut sim = Simulation::builder(in_a_well(omega, d)).integrator(integrator).solver(solver).build();
        for _ in 0..500 {
            sim.step(1e-3).unwrap();
        }
        (mean_height(&sim) - (anchor_z - d), sim.model().max_stretch_ratio(&sim.state().x))
    };
    let (implicit_error, stretch) = half_period(IntegratorKind::Bdf2);
    let implicit_error = implicit_error.abs();
    let (euler_gap, _) = half_period(IntegratorKind::BackwardEuler);
    // Backward Euler's amplitude decays by (1 + w^2 h^2)^(-1/2) a step.
    let euler_expected = d * (1.0 - (1.0 + (omega * 1e-3_f64).powi(2)).powf(-250.0));
    let euler_error = (euler_gap - euler_expected).abs();
    println!(
        "explicit {explicit_error:.3e} m, BDF2 {implicit_error:.3e} m off; backward Euler {euler_gap:.4e} m short against {euler_expected:.4e} ({euler_error:.2e} m); stretch {stretch}"
    );
    // Measured 3.3e-13 m, 3.0e-7 m (BDF2's damping over 500 steps) and
    // 8.5e-12 m from backward Euler's exact damping.
    assert!(explicit_error < 1e-12, "symplectic Euler {explicit_error} m off");
    assert!(implicit_error < 5e-7, "BDF2 {implicit_error} m off");
    assert!(euler_error < 1e-10, "backward Euler {euler_gap} m short, expected {euler_expected}");
    assert!((stretch - 1.0).abs() < 1e-9, "the links stretched to {stretch}");
}
