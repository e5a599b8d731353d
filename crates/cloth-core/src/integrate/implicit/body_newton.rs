//! Newton corrections of a step with rigid bodies in the solve.
//!
//! The coupled single linearised step sees the links at the step's start.
//! A body that strikes cloth at rest drags the particles it meets by
//! `v h` in one step, across links that have no stiffness sideways in the
//! linear model: the solve lets the body through unslowed, and the links
//! then hold energy that nothing put in (a 2 kg box landing at 1.85 m/s
//! on a trampoline: 2.4 J, 0.37 of the energy in play).
//!
//! Newton's method on the coupled step equation follows them. The active
//! set of the settled linearised step stays: each correction `(du, dy)`
//! solves the coupled system assembled at the iterate under the same
//! constraints with zero prescribed values (`BodyBuffers::correct`), so
//! the held particles move with their body, and the body's row holds at
//! `y + dy` with the reactions of the iterate. Solids are constraints
//! here, not the penalties of the cloth-only Newton iterations
//! ([`super::newton`]): a penalty gives a body no impulse in the solve.
//! No line search: the corrections stop at
//! [`crate::NewtonParams::tolerance_m`] or after the step's Newton
//! iterations.

use super::newton::{
    NewtonOutcome, advance_iterate, assemble_iterate, copy_loads, residual_distance, solve_direction, with_buffers,
};
use super::scheme::Linearised;
use super::solve::solve_correction;
use super::workspace::{NewtonBuffers, StepInputs, SystemLoads, Workspace};
use crate::contacts::read_contact_forces;
use crate::integrate::timer::StageTimer;
use crate::{StepError, Vec3};

/// Newton corrections from the settled coupled solve in `ws.s.unknown`
/// (see the module). On return `ws.s.unknown` holds the last iterate,
/// `ws.s.system` the assembly there (its right-hand side is `-r`), the
/// bodies their total change, and the contacts with bodies the normal
/// forces of that iterate.
pub(crate) fn iterate_with_bodies<S: Linearised>(
    step: StepInputs<'_, S>,
    ws: &mut Workspace<'_>,
    loads: &SystemLoads,
    timer: &mut StageTimer,
) -> Result<NewtonOutcome, StepError> {
    with_buffers(step.model, ws, |ws, nb| corrections(step, ws, loads, nb, timer))
}

fn corrections<S: Linearised>(
    step: StepInputs<'_, S>,
    ws: &mut Workspace<'_>,
    loads: &SystemLoads,
    nb: &mut NewtonBuffers,
    timer: &mut StageTimer,
) -> Result<NewtonOutcome, StepError> {
    let StepInputs { scheme, state, h, solver, .. } = step;
    let (c_f, a) = (scheme.force_coefficient(h), scheme.position_per_unknown(h));
    let mut out = NewtonOutcome { cg_converged: true, ..Default::default() };
    ws.s.filter.zero_prescribed();
    nb.u.copy_from_slice(&ws.s.unknown);
    for solves in 1.. {
        advance_iterate(scheme, state, ws, h, nb);
        copy_loads(ws, nb, loads, loads.squeeze_friction, &state.x);
        assemble_iterate(step, ws, nb, timer);
        out.evaluations += 1;
        out.residual_m = residual_distance(ws, a);
        out.converged = out.residual_m <= solver.newton.tolerance_m;
        if out.converged || solves >= solver.newton.iterations {
            break;
        }
        solve_direction(ws, state, solver, &mut out, timer, solve_correction)?;
        for (u, p) in nb.u.iter_mut().zip(&ws.s.unknown) {
            *u += p;
        }
    }
    ws.s.unknown.copy_from_slice(&nb.u);
    // The contacts' forces at the last iterate, `r_i / c_f`: the
    // assembly's `-rhs`, read as `A 0 - rhs`.
    nb.trial.iter_mut().for_each(|p| *p = Vec3::zeros());
    let (matrix, rhs, bodies) = (&ws.s.system.matrix, &ws.s.system.rhs, &ws.out.bodies);
    read_contact_forces(&mut ws.contacts.solid, matrix, rhs, (&nb.trial, c_f), |c| bodies.holds(c));
    Ok(out)
}
