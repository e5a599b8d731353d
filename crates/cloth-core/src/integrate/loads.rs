//! The loads stage: forces from outside the cloth at the step's start,
//! the model's external terms (the wind's) and the control's forces. The
//! integrators that take them once a step ([`crate::Capabilities::loads_at_start`])
//! hold them constant over the step.

use crate::control::Control;
use crate::terms::ForceBuffers;
use crate::{ClothModel, ClothState, Vec3};

/// The loads of a step: forces from outside the cloth at its start, N.
#[derive(Debug, Clone)]
pub struct Loads {
    forces: Vec<Vec3>,
    present: bool,
    scratch: ForceBuffers,
}

impl Loads {
    /// Buffers for `model`.
    pub(crate) fn new(model: &ClothModel) -> Self {
        Self {
            forces: vec![Vec3::zeros(); model.particle_count()],
            present: false,
            scratch: ForceBuffers::external(model),
        }
    }

    /// Forces on every particle at the step's start, N; `None` when there
    /// are none (or the integrator does not take loads at the start).
    pub fn forces(&self) -> Option<&[Vec3]> {
        self.present.then_some(&self.forces[..])
    }

    /// No loads for the coming step.
    pub(crate) fn clear(&mut self) {
        self.present = false;
    }

    /// The wind's forces at the state's `(x, v)` and time and the
    /// control's forces; nothing computed when there are neither.
    pub(crate) fn gather(&mut self, model: &ClothModel, state: &ClothState, control: &Control) {
        self.present = has_external_forces(model, control);
        if !self.present {
            return;
        }
        self.forces.iter_mut().for_each(|f| *f = Vec3::zeros());
        let at = crate::terms::At::new(model, &state.x, &state.v, &state.stitches_closed).with_wind_at(
            state.time_s,
            control.wind(),
            control.wind_scale(),
        );
        crate::terms::add_external_forces(&at, &mut self.scratch, &mut self.forces);
        control.add_forces_to(&mut self.forces);
    }
}

/// Whether any force from outside the cloth acts: an external term of the
/// model (the wind's) or the control's forces.
pub(crate) fn has_external_forces(model: &ClothModel, control: &Control) -> bool {
    crate::terms::external(model).next().is_some() || control.forces().is_some()
}
