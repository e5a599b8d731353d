//! One step of a simulation, as a list of stages in one place (as rapier's
//! `PhysicsPipeline::step`):
//!
//! ```text
//! attempt   loads -> collision -> assemble -> solve -> respond -> balance
//! retake    the integrator's guard may ask for another attempt
//! rollback  a step that blew up is refused: the state stays as it was
//! commit    the solved state becomes the current one
//! finish    deformation constraints, history at held contacts, stitches
//! ```
//!
//! Each stage is one call, timed by one [`StageTimer`]. What each stage
//! hands to the next (the loads, the [`Contacts`], the [`StepOutput`]) is
//! drawn in `docs/step.md`.

use super::loads::Loads;
use super::step::{Attempt, Capabilities, ContactHandling, Integrator, Step, StepOutput};
use super::timer::{Stage, StageTimer};
use crate::constraints::{apply_strain_limit_with, project_strain_limit};
use crate::contacts::{Contacts, restart_history_at_contacts};
use crate::control::Control;
use crate::{ClothModel, ClothState, SolverParams, StepError, StepReport, StrainLimit};

/// Everything a step reads and writes, borrowed from the simulation.
pub(crate) struct Parts<'a> {
    pub model: &'a ClothModel,
    pub state: &'a mut ClothState,
    pub control: &'a Control,
    pub solver: &'a SolverParams,
    pub integrator: &'a mut dyn Integrator,
    pub loads: &'a mut Loads,
    pub contacts: &'a mut Contacts,
    pub out: &'a mut StepOutput,
}

/// Advances `parts.state` by `h` seconds; on error the state is unchanged.
pub(crate) fn step(parts: Parts<'_>, h: f64) -> Result<StepReport, StepError> {
    let Parts { model, state, control, solver, integrator, loads, contacts, out } = parts;
    let caps = integrator.capabilities();
    refuse_what_it_cannot_take(model, state, control, h, caps, integrator.name())?;
    let mut timer = StageTimer::default();
    let mut attempt = Attempt::First;
    let mut report = loop {
        if caps.loads_at_start {
            timer.time(Stage::Forces, || loads.gather(model, state, control));
        } else {
            loads.clear();
        }
        let step = Step { model, state, control, h, solver, loads, attempt };
        contacts.detect(&step, caps.contacts, &mut timer)?;
        integrator.assemble(&step, contacts, &mut timer)?;
        let mut report = integrator.solve(&step, contacts, out, &mut timer)?;
        contacts.respond(&step, caps.contacts, out, &mut timer);
        report.contacts = contacts.stats();
        report.energy = timer.time(Stage::Update, || integrator.balance(&step, contacts, out));
        report.retaken_as_backward_euler = attempt == Attempt::AsBackwardEuler;
        report.retaken_with_newton = attempt == Attempt::WithNewton;
        match integrator.retake(&step, &report, contacts, out) {
            Some(next) => attempt = next,
            None => break report,
        }
    };
    refuse_non_finite(state, out)?;
    refuse_blow_up(model, state, out, solver)?;
    timer.time(Stage::Update, || commit(state, out, h));
    integrator.committed(&report);
    let lap = timer.start();
    finish(model, control, caps, state, contacts, &mut report, h, &mut timer);
    timer.stop(lap, Stage::Update);
    report.stages = timer.times();
    Ok(report)
}

/// Deformation-constraint passes between two projections out of solids
/// in a step's finish: at 5, a garment's 50 passes take up to ten turns.
const PASSES_PER_PROJECTION: usize = 5;

/// Checks for crossings of what the deformation constraints moved in a
/// step's finish, each after a turn of passes: impact zones that moved
/// cloth leave its links stretched, which the next turn's passes take up.
const CORRECTION_CHECKS: usize = 3;

/// Deformation-constraint passes after impact zones moved cloth in the
/// finish, at least (beyond `StrainLimit::passes` when those ran out): on
/// the T-shirt at 6,741 particles the zones left links at up to 1.75 with
/// no pass left, 1.28 with these.
const PASSES_AFTER_ZONES: usize = 2 * PASSES_PER_PROJECTION;

/// Fails on a step the simulation cannot take: a step size that is not a
/// positive number, a state that does not fit the model, bodies or
/// self-collision the integrator does not handle.
fn refuse_what_it_cannot_take(
    model: &ClothModel,
    state: &ClothState,
    control: &Control,
    h: f64,
    caps: Capabilities,
    integrator: &'static str,
) -> Result<(), StepError> {
    if !control.bodies().is_empty() && !caps.bodies {
        return Err(StepError::BodiesNeedMatrix { integrator });
    }
    if !(h.is_finite() && h > 0.0) {
        return Err(StepError::InvalidTimeStep { h });
    }
    if state.len() != model.particle_count() || state.v.len() != state.len() {
        return Err(StepError::StateMismatch { expected: model.particle_count(), got: state.len() });
    }
    if state.stitches_closed.len() != model.stitches().len() {
        let (expected, got) = (model.stitches().len(), state.stitches_closed.len());
        return Err(StepError::StitchStateMismatch { expected, got });
    }
    if model.self_collision().is_some() && !caps.contacts.handles_self_collision() {
        return Err(StepError::SelfCollisionNeedsMatrix { integrator });
    }
    Ok(())
}

/// Fails when the solved state has a position or velocity that is not
/// finite, naming the first particle.
fn refuse_non_finite(state: &ClothState, out: &StepOutput) -> Result<(), StepError> {
    let bad = |v: &crate::Vec3| !v.iter().all(|c| c.is_finite());
    for i in 0..state.len() {
        let quantity = if bad(&out.x[i]) {
            "position"
        } else if bad(&out.v[i]) {
            "velocity"
        } else {
            continue;
        };
        return Err(StepError::NonFinite { step: state.steps + 1, time_s: state.time_s, particle: i, quantity });
    }
    Ok(())
}

/// The rollback: a step that would leave a link longer than
/// [`SolverParams::blow_up_stretch`] times its rest length is refused.
fn refuse_blow_up(
    model: &ClothModel,
    state: &ClothState,
    out: &StepOutput,
    solver: &SolverParams,
) -> Result<(), StepError> {
    let limit = solver.blow_up_stretch;
    match model.most_stretched(&out.x).filter(|s| s.0 > limit) {
        Some((stretch, i, j)) => {
            Err(StepError::BlewUp { step: state.steps + 1, time_s: state.time_s, i, j, stretch, limit })
        }
        None => Ok(()),
    }
}

/// Makes the solved state current: the current one becomes the history
/// (buffers rotated, no allocation).
fn commit(state: &mut ClothState, out: &mut StepOutput, h: f64) {
    std::mem::swap(&mut state.x_prev, &mut state.x);
    std::mem::swap(&mut state.v_prev, &mut state.v);
    std::mem::swap(&mut state.x, &mut out.x);
    std::mem::swap(&mut state.v, &mut out.v);
    state.has_history = true;
    state.last_dt_s = h;
    state.time_s += h;
    state.steps += 1;
}

/// The end of every step, whatever the integrator: Provot's deformation
/// constraints (and the projection out of solids they may need), the
/// restart of the history at held contacts, and the stitches that close.
#[allow(clippy::too_many_arguments)]
fn finish(
    model: &ClothModel,
    control: &Control,
    caps: Capabilities,
    state: &mut ClothState,
    contacts: &mut Contacts,
    report: &mut StepReport,
    h: f64,
    timer: &mut StageTimer,
) {
    if let Some(limit) = model.strain_limit() {
        let ClothState { x, v, x_prev, time_s, stitches_closed, .. } = state;
        let held = |i| control.is_held(i);
        let times = (*time_s - h, h);
        // The corrections may move particles into solids, and moving them
        // out stretches their links again: a few passes, then the
        // projection, in turns, so that both hold where the cloth wraps a
        // solid's edge (docs/results/garments-primitives.md). Without
        // solids the turns are the passes in one run. What they moved is
        // then checked for crossings; where impact zones moved the cloth,
        // more passes follow (`PASSES_AFTER_ZONES` at least), a few checks
        // at most. Fast projections (`constraints.projections`) start each
        // round before the first check only: run after zones too, they
        // pulled the zones' rims back through the other layer, and on the
        // T-shirt at twice its Table-1 count zones and projections took
        // turns until the checks ran out, leaving links at 1.29 to 1.46.
        let solids = !model.colliders().is_empty();
        contacts.projection_memo.set_active(true);
        let mut passes_left = limit.passes;
        // The fast projections keep particles out of the solids near them
        // at the finish's start: one solve for both, where the projection
        // out of the solids after them would stretch what they shortened.
        contacts.solid_bounds.clear();
        if limit.projections > 0 && solids {
            contacts.find_solid_bounds(model, x_prev, times, x);
        }
        for check in 1..=CORRECTION_CHECKS {
            contacts.before_corrections(model, x);
            let mut corrected = false;
            while passes_left > 0 {
                let round = StrainLimit { passes: passes_left.min(PASSES_PER_PROJECTION), ..limit };
                if check == 1 {
                    let scratch = &mut contacts.strain_projection;
                    let bounds = &contacts.solid_bounds;
                    project_strain_limit(model, &limit, &held, (stitches_closed, bounds), (x, v), h, scratch);
                }
                let dirty = &mut contacts.strain_dirty;
                let done = apply_strain_limit_with(model, &round, held, stitches_closed, (x, v), h, dirty);
                passes_left -= done.passes;
                report.strain_corrections += done.corrections;
                let moved = if solids { contacts.project_corrected(model, x_prev, times, x, v) } else { 0 };
                corrected |= done.corrections > 0 || moved > 0;
                if done.settled && moved == 0 {
                    break;
                }
            }
            let zones_moved = corrected && contacts.untangle_corrections(model, (x_prev, times), (x, v), timer) > 0;
            if !zones_moved || check == CORRECTION_CHECKS {
                break;
            }
            // Zones move cloth as rigid pieces and stretch the links at their
            // rims; those passes are owed even when the budget ran out.
            passes_left = passes_left.max(PASSES_AFTER_ZONES);
        }
        contacts.projection_memo.set_active(false);
        report.contacts = contacts.stats();
    }
    // After every correction of the step (the projection above sweeps from
    // `x_prev`, the start of the step); not after Newton iterations, whose
    // solids are penalties.
    if caps.contacts == ContactHandling::Constraints && report.newton.is_none() {
        let ClothState { x, v, x_prev, v_prev, .. } = state;
        restart_history_at_contacts(contacts.solid(), h, (x, v), (x_prev, v_prev));
    }
    model.close_stitches(&state.x, &mut state.stitches_closed);
}
