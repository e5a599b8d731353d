//! A simulation: an immutable model, the explicit state, an integrator and
//! its scratch space.

use crate::apply_strain_limit;
use crate::contacts::project_out;
use crate::{ClothModel, ClothState, Integrator, IntegratorKind, SolverParams, StepError, StepReport, Workspace};
use std::sync::Arc;

/// Owns a model and its state and advances them in time.
#[derive(Debug)]
pub struct Simulation {
    model: Arc<ClothModel>,
    state: ClothState,
    integrator: Box<dyn Integrator>,
    solver: SolverParams,
    workspace: Workspace,
}

impl Simulation {
    /// A simulation starting from the model's rest shape at time 0.
    pub fn new(model: impl Into<Arc<ClothModel>>, integrator: IntegratorKind, solver: SolverParams) -> Self {
        let model = model.into();
        Self {
            state: ClothState::at_rest(&model),
            workspace: Workspace::new(&model, &solver),
            integrator: integrator.build(),
            solver,
            model,
        }
    }

    /// Advances by `h` seconds, then applies the model's deformation
    /// constraints if it has them. On error the state is unchanged.
    pub fn step(&mut self, h: f64) -> Result<StepReport, StepError> {
        let mut report = self.integrator.step(&self.model, &mut self.state, h, &mut self.workspace, &self.solver)?;
        if let Some(limit) = self.model.strain_limit() {
            let t = std::time::Instant::now();
            let ClothState { x, v, x_prev, time_s, .. } = &mut self.state;
            report.strain_corrections = apply_strain_limit(&self.model, &limit, x, v, h).corrections;
            // The corrections may move particles into solids: move them out.
            if !self.model.colliders().is_empty() {
                let contacts = &mut self.workspace.contacts;
                report.contacts.projected += project_out(&self.model, x_prev, *time_s, contacts, true, x, v);
            }
            report.stages.update_s += t.elapsed().as_secs_f64();
        }
        Ok(report)
    }

    /// Simulated time, s.
    pub fn time(&self) -> f64 {
        self.state.time_s
    }

    /// The model.
    pub fn model(&self) -> &Arc<ClothModel> {
        &self.model
    }

    /// The current state.
    pub fn state(&self) -> &ClothState {
        &self.state
    }

    /// Which integrator is used.
    pub fn integrator(&self) -> IntegratorKind {
        self.integrator.kind()
    }

    /// The cloth-solid contacts of the last step (point, normal, solid
    /// velocity and the normal force each exerted), sorted by particle.
    pub fn contacts(&self) -> &[crate::contacts::SolidContact] {
        &self.workspace.contacts.solid
    }

    /// A copy of the complete state (history included), for rollback.
    pub fn snapshot(&self) -> ClothState {
        self.state.clone()
    }

    /// Returns to a snapshot taken from a simulation of the same model.
    /// Stepping from it reproduces the original run bit for bit.
    pub fn restore(&mut self, snapshot: &ClothState) -> Result<(), StepError> {
        let n = self.model.particle_count();
        let lens = [snapshot.x.len(), snapshot.v.len(), snapshot.x_prev.len(), snapshot.v_prev.len()];
        if let Some(&got) = lens.iter().find(|&&l| l != n) {
            return Err(StepError::StateMismatch { expected: n, got });
        }
        self.state.clone_from(snapshot);
        Ok(())
    }
}
