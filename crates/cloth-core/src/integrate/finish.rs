//! The end of every step, whatever the integrator: Provot's deformation
//! constraints (and the projection out of solids they may need), the
//! restart of the history at held contacts, and the stitches that close.

use crate::contacts::{project_out, restart_history_at_contacts};
use crate::control::Control;
use crate::{ClothModel, ClothState, Integrator, StepReport, Workspace, apply_strain_limit};

/// Finishes a committed step of size `h` on `state`, adding what it did to
/// `report`.
pub(crate) fn finish_step(
    model: &ClothModel,
    control: &Control,
    integrator: &dyn Integrator,
    state: &mut ClothState,
    ws: &mut Workspace,
    report: &mut StepReport,
    h: f64,
) {
    if let Some(limit) = model.strain_limit() {
        let t = std::time::Instant::now();
        let ClothState { x, v, x_prev, time_s, stitches_closed, .. } = state;
        let held = |i| control.is_held(i);
        report.strain_corrections = apply_strain_limit(model, &limit, held, stitches_closed, (x, v), h).corrections;
        // The corrections may move particles into solids: move them out.
        if !model.colliders().is_empty() {
            report.contacts.projected += project_out(model, x_prev, (*time_s - h, h), &mut ws.contacts, true, x, v);
        }
        report.stages.update_s += t.elapsed().as_secs_f64();
    }
    // After every correction of the step (the projection above sweeps from
    // `x_prev`, the start of the step); not after Newton iterations, whose
    // solids are penalties.
    if integrator.restarts_history_at_contacts() && report.newton.is_none() {
        let ClothState { x, v, x_prev, v_prev, .. } = state;
        restart_history_at_contacts(&ws.contacts.solid, h, (x, v), (x_prev, v_prev));
    }
    model.close_stitches(&state.x, &mut state.stitches_closed);
}
