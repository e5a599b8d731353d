//! The linear solve of an implicit step and what sets it up: the filtered
//! PCG (with the bodies in the solve when there are any), the pins in the
//! constraint filter, and the loads the system carries besides the links.

use super::workspace::{SystemLoads, Workspace};
use crate::contacts::Contacts;
use crate::control::{Control, PinPaths};
use crate::system::SystemTerms;
use crate::{ClothModel, ClothState, SolverParams, StepError, StepReport, Vec3};
use cloth_linalg::{Constraint, ConstraintFilter, Coupling, Couplings, PcgError};
use std::time::Instant;

/// One filtered PCG solve of the assembled system into `ws.s.unknown`,
/// with the bodies in the solve when there are any. Returns what it did
/// and its wall time, s.
pub(crate) fn solve(
    ws: &mut Workspace<'_>,
    state: &ClothState,
    solver: &SolverParams,
) -> Result<(StepReport, f64), StepError> {
    solve_as(ws, state, solver, false)
}

/// [`solve`] for a Newton correction of the step with bodies in the
/// solve (see `BodyBuffers::correct`): the filter prescribes zero, and the
/// bodies' unknowns grow by theirs.
pub(crate) fn solve_correction(
    ws: &mut Workspace<'_>,
    state: &ClothState,
    solver: &SolverParams,
) -> Result<(StepReport, f64), StepError> {
    solve_as(ws, state, solver, true)
}

fn solve_as(
    ws: &mut Workspace<'_>,
    state: &ClothState,
    solver: &SolverParams,
    correction: bool,
) -> Result<(StepReport, f64), StepError> {
    let t0 = Instant::now();
    let s = &mut *ws.s;
    let result = if ws.out.bodies.active() {
        let bodies = &mut ws.out.bodies;
        bodies.link(&s.filter, &ws.contacts.solid, state.len());
        let (a, b, filter, params) = (&s.system.matrix, &s.system.rhs, &s.filter, &solver.pcg());
        if correction {
            bodies.correct(a, b, filter, params, &mut s.unknown)
        } else {
            bodies.solve(a, b, filter, params, &mut s.unknown)
        }
    } else {
        s.pcg.solve_in_place(&mut s.system.matrix, &s.system.rhs, &s.filter, &solver.pcg(), &mut s.unknown)
    };
    // The bodies' solve takes the matrix alone.
    s.coupled.iter_mut().for_each(|y| *y = Vec3::zeros());
    if !ws.out.bodies.active() {
        s.pcg.couplings_mut().add_off_diagonal(&s.unknown, 1.0, &mut s.coupled);
    }
    let elapsed = t0.elapsed().as_secs_f64();
    let fail = |source| StepError::Solver { step: state.steps + 1, time_s: state.time_s, source };
    let report = match result {
        Ok(info) => StepReport {
            cg_iterations: info.iterations,
            rel_residual: info.rel_residual,
            converged: true,
            ..Default::default()
        },
        Err(PcgError::NotConverged { info }) if solver.accept_unconverged => StepReport {
            cg_iterations: info.iterations,
            rel_residual: info.rel_residual,
            converged: false,
            ..Default::default()
        },
        Err(PcgError::NonFinite { .. }) => return Err(locate_non_finite(ws, state)),
        Err(e) => return Err(fail(e)),
    };
    Ok((report, elapsed))
}

/// Names the first particle whose force (right-hand side), matrix block or
/// solver iterate is not finite, so a blown-up run says where it broke.
fn locate_non_finite(ws: &Workspace<'_>, state: &ClothState) -> StepError {
    let s = &*ws.s;
    let bad = |v: &Vec3| !v.iter().all(|c| c.is_finite());
    let matrix_row_bad = |i: usize| {
        s.system.matrix.pattern().row_range(i).any(|k| !s.system.matrix.values()[k].iter().all(|c| c.is_finite()))
    };
    let found = (0..state.len())
        .find_map(|i| bad(&s.system.rhs[i]).then_some((i, "force")))
        .or_else(|| (0..state.len()).find_map(|i| matrix_row_bad(i).then_some((i, "stiffness"))))
        .or_else(|| (0..state.len()).find_map(|i| bad(&s.unknown[i]).then_some((i, "solver iterate"))))
        .or_else(|| state.first_non_finite());
    // Every input finite yet PCG overflowed: blame the largest force.
    let (particle, quantity) = found.unwrap_or_else(|| {
        let largest = (0..state.len()).max_by(|&a, &b| s.system.rhs[a].norm().total_cmp(&s.system.rhs[b].norm()));
        (largest.unwrap_or(0), "value in the linear solve (overflow from its force)")
    });
    StepError::NonFinite { step: state.steps + 1, time_s: state.time_s, particle, quantity }
}

/// Adds a contact pass's solve `r` (taking `s` seconds) to the step's
/// report; its residual and convergence count only when it solved the
/// set to `rel_tol` (`exact`), not for a rough settling solve.
pub(crate) fn add_solve(report: &mut StepReport, solve_s: &mut f64, r: &StepReport, s: f64, exact: bool) {
    report.cg_iterations += r.cg_iterations;
    *solve_s += s;
    if exact {
        (report.rel_residual, report.converged) = (r.rel_residual, report.converged & r.converged);
    }
}

/// Fully constrains every pinned particle; `value(target, i)` maps the pin's
/// position at `t + h` to the integrator's unknown.
pub(crate) fn constrain_pins(
    model: &ClothModel,
    state: &ClothState,
    control: &Control,
    h: f64,
    filter: &mut ConstraintFilter,
    value: impl Fn(Vec3, usize) -> Vec3,
) {
    filter.clear();
    let t_next = state.time_s + h;
    let paths = PinPaths::new(model, control, &state.x, state.time_s, h);
    for k in 0..paths.count() {
        let i = paths.particle(k);
        let z = value(paths.position(k, t_next), i);
        // A non-finite prescribed value is caught as a non-finite state below.
        let _ = filter.set(i, Constraint::Fixed, z);
    }
}

/// A scheme's `terms` with the loads of the step that `loads` says are
/// present: external forces, self-collision stiffness, squeeze friction.
pub(crate) fn with_loads<'a>(
    mut terms: SystemTerms<'a>,
    external: &'a [Vec3],
    contacts: &'a Contacts,
    loads: &SystemLoads,
) -> SystemTerms<'a> {
    terms.external = loads.external.then_some(external);
    terms.diag_stiffness = loads.self_collision.then_some(&contacts.self_stiffness[..]);
    terms.diag_damping = loads.squeeze_friction.then_some(&contacts.friction_damping[..]);
    terms
}

/// The self-collision contacts' stiffness between their particles, which
/// the assembled matrix (a fixed pattern, the contacts' diagonal blocks
/// alone) cannot hold: added to the solver's operator, scaled as the
/// matrix's stiffness (`c_x`), and, where the scheme's right-hand side
/// carries `a_k K w_k`, to it. Without it each particle of a contact saw
/// the contact as a spring to a fixed point: a contact of four free
/// particles moved its gap by up to four times its overlap in one step,
/// and layers pressed together rang (a sheet resting on another on the
/// floor was thrown off).
pub(crate) fn couple_self_contacts(
    terms: &SystemTerms<'_>,
    contacts: &Contacts,
    on: bool,
    couplings: &mut Couplings,
    rhs: &mut [Vec3],
) {
    couplings.clear();
    if !on {
        return;
    }
    for c in contacts.self_couplings.terms() {
        couplings.push(Coupling { stiffness: c.stiffness * terms.c_x, ..*c });
    }
    if let Some((a, w)) = terms.k_times {
        contacts.self_couplings.add_off_diagonal(w, -a, rhs);
    }
}
