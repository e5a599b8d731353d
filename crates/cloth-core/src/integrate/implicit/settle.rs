//! Settling a step's solid-contact set over repeated solves (Baraff &
//! Witkin's active set, with Coulomb friction decided in the solve).
//!
//! Each pass reads the constraint forces off the last solve and changes
//! the set: contacts that pull are released, free particles that ended
//! inside a solid are added, stuck contacts beyond their Coulomb bound
//! slide. Then the system is solved again, until a pass changes nothing.
//!
//! Solves are *rough* (capped at `solver.contacts.settling_iterations` CG iterations)
//! while the set changes: they only decide which contacts hold, stick or
//! slide. The [`Settling`] state machine says which solve comes next.

use super::scheme::Linearised;
use super::solve::{add_solve, solve};
use super::workspace::{StepInputs, Workspace};
use crate::contacts::{
    CoupledRows, FrictionMode, MAX_REVIVALS, SolidContact, add_penetrating, constrain_contacts, read_contact_forces,
    release_pulling, stick_frictional_contacts, stick_or_slide,
};
use crate::integrate::timer::{Stage, StageTimer};
use crate::{ClothModel, SolverParams, StepError, StepReport};

/// How a step treats its solid contacts, from the solver settings and the
/// model.
#[derive(Debug, Clone, Copy)]
pub(crate) struct ContactRules {
    /// Coulomb friction decided in the solve (stick or slide), not smoothed
    /// into Newton's potential (which happens when Newton runs on every
    /// step): see `contacts::FrictionMode`.
    pub(crate) friction_in_solve: bool,
    /// Rough solves while the set settles (`settling_iterations > 0`, the
    /// model has solids, friction in the solve).
    pub(crate) rough_solves: bool,
}

impl ContactRules {
    /// The rules for `solver`'s settings; `carried`: Newton corrections
    /// that carry bodies follow (`body_newton`), which keep the linearised
    /// step's contact constraints and so its friction in the solve.
    pub(crate) fn new(model: &ClothModel, solver: &SolverParams, carried: bool) -> Self {
        let friction_in_solve = carried || solver.newton.iterations <= 1 || solver.newton.trigger > 0.0;
        let rough_solves =
            solver.contacts.settling_iterations > 0 && !model.colliders().is_empty() && friction_in_solve;
        Self { friction_in_solve, rough_solves }
    }
}

/// Which solve comes next while the contact set settles.
///
/// The unknown is *exact* when it solves the current set to `rel_tol`,
/// else *rough*. After a pass:
/// - exact, and the set settled (or the passes ran out): done; but when
///   a sliding contact's friction `mu N` came from a rough solve's `N`,
///   one more exact solve takes `N` from an exact one;
/// - rough, and the set settled (or the passes ran out): an exact solve,
///   then one more pass to check the set;
/// - the set changed: a rough solve (exact without rough solves).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Settling {
    rough: SolverParams,
    full: SolverParams,
    rough_solves: bool,
    exact: bool,
    friction_from_rough: bool,
}

/// What [`Settling::after_pass`] decides.
pub(crate) enum NextSolve {
    /// The set is settled and solved.
    Done,
    /// One more exact solve (sliding friction read from an exact solve),
    /// then done.
    Last(SolverParams),
    /// Solve with these settings (`exact`: to `rel_tol`), then another pass.
    Solve { params: SolverParams, exact: bool },
}

impl Settling {
    pub(crate) fn new(solver: &SolverParams, rules: ContactRules) -> Self {
        let rough = SolverParams {
            max_iter: solver.contacts.settling_iterations.min(solver.max_iter),
            accept_unconverged: true,
            ..*solver
        };
        Self { rough, full: *solver, rough_solves: rules.rough_solves, exact: true, friction_from_rough: false }
    }

    /// Settings of the step's first solve: rough when it starts with
    /// contacts to settle.
    pub(crate) fn first(&self, contacts_at_start: bool) -> (SolverParams, bool) {
        let rough = self.rough_solves && contacts_at_start;
        (if rough { self.rough } else { self.full }, !rough)
    }

    /// Records a solve: it is exact when asked to be, or when a rough one
    /// converged anyway.
    pub(crate) fn solved(&mut self, asked_exact: bool, converged: bool) {
        self.exact = asked_exact || converged;
    }

    /// Whether the last solve was exact.
    pub(crate) fn exact(&self) -> bool {
        self.exact
    }

    /// After a pass that `settled` (changed nothing) or was the `last`:
    /// the next solve, or done. `sliding` says whether any contact slides.
    pub(crate) fn after_pass(&mut self, settled: bool, last: bool, sliding: impl FnOnce() -> bool) -> NextSolve {
        if self.exact && (settled || last) {
            return if settled && self.friction_from_rough && sliding() {
                NextSolve::Last(self.full)
            } else {
                NextSolve::Done
            };
        }
        self.friction_from_rough = !self.exact;
        let full = settled || last || !self.rough_solves;
        NextSolve::Solve { params: if full { self.full } else { self.rough }, exact: full }
    }
}

/// What the contact passes leave for the rest of the step.
pub(crate) struct Settled {
    /// Solves, CG iterations and whether the set's final solve converged.
    pub(crate) report: StepReport,
    /// Contacts were still being added when the passes ran out.
    pub(crate) unresolved: bool,
}

/// Sticks the frictional contacts that have none yet
/// ([`crate::contacts`]' `stick_frictional_contacts`) and returns how many.
/// Contacts with solids whose motion is a guess (a co-simulation master's)
/// keep their friction after the solve; prescribed motions (kinematic
/// bodies, rig links) are exact, as the scene's own solids.
pub(crate) fn stick_frictional<S>(step: StepInputs<'_, S>, contacts: &mut [SolidContact]) -> usize {
    let StepInputs { model, control, h, .. } = step;
    let prescribed = |i: usize| model.is_pinned(i) || control.is_held(i);
    let driven = |k: usize| {
        model.colliders()[k].is_external() && !control.is_solid_prescribed(k) && !control.is_solid_in_solve(k)
    };
    stick_frictional_contacts(contacts, h, prescribed, driven)
}

/// Solves the step with the contacts of its start, then settles the set
/// pass by pass (at most `solver.contacts.max_passes` re-solves); the
/// passes' counters go to `ws.contacts`' stats, the solves' time to
/// `timer`'s solve stage.
pub(crate) fn settle_contacts<S: Linearised>(
    step: StepInputs<'_, S>,
    ws: &mut Workspace<'_>,
    rules: ContactRules,
    force_coefficient: f64,
    timer: &mut StageTimer,
) -> Result<Settled, StepError> {
    let StepInputs { scheme, model, state, control: _, h, solver } = step;
    let value = |target, i| scheme.pinned(state, h, target, i);
    let mut settling = Settling::new(solver, rules);
    let (first, exact) = settling.first(!ws.contacts.solid.is_empty());
    let (mut report, mut solve_s) = solve(ws, state, &first)?;
    settling.solved(exact, report.converged);
    // A rough first solve does not count as unconverged.
    report.converged |= !exact;
    let mut unresolved = false;
    let last = solver.contacts.max_passes;
    let passes = if model.colliders().is_empty() { 0 } else { last + 1 };
    for pass in 0..passes {
        let matrix = &CoupledRows { matrix: &ws.s.system.matrix, coupled: &ws.s.coupled };
        let rhs = &ws.s.system.rhs;
        let (contacts, unknown) = (&mut ws.contacts.solid, &ws.s.unknown);
        let masses = model.masses();
        let bodies = &ws.out.bodies;
        let kept = |c: &SolidContact| c.revivals >= MAX_REVIVALS && bodies.outweighs(c, masses[c.particle as usize]);
        let (filter, laws) = (&mut ws.s.filter, (value, kept));
        let released = release_pulling(contacts, matrix, rhs, unknown, force_coefficient, &state.x, filter, laws);
        for i in 0..state.len() {
            ws.out.x[i] = scheme.advance(state, &ws.s.aux, h, i, ws.s.unknown[i]).0;
        }
        let (contacts, rhs, solved) =
            (&mut ws.contacts.solid, &mut ws.s.system.rhs, (&ws.s.unknown[..], force_coefficient));
        let matrix = &CoupledRows { matrix: &ws.s.system.matrix, coupled: &ws.s.coupled };
        let filter = &mut ws.s.filter;
        let slid = stick_or_slide(contacts, matrix, rhs, solved, &state.x, &ws.out.x, filter, value);
        let bodies = &ws.out.bodies;
        let movable = |c: &SolidContact| bodies.holds(c);
        let (contacts, filter) = (&mut ws.contacts, &mut ws.s.filter);
        let added = add_penetrating(model, &state.x, &ws.out.x, (state.time_s, h), contacts, filter, (value, movable));
        if rules.friction_in_solve && added > 0 && stick_frictional(step, &mut ws.contacts.solid) > 0 {
            constrain_contacts(&ws.contacts.solid, &state.x, &mut ws.s.filter, value);
        }
        let stats = &mut ws.contacts.stats;
        (stats.released, stats.added) = (stats.released + released, stats.added + added);
        unresolved = added > 0 && pass == last;
        let settled = released + added + slid == 0;
        let sliding = || ws.contacts.solid.iter().any(|c| c.friction_mode == FrictionMode::Slide);
        match settling.after_pass(settled, pass == last, sliding) {
            // Bodies in the solve take the forces of the last solve: it
            // must be of the set that stands.
            NextSolve::Done if !settled && ws.out.bodies.active() => {
                let (r, s) = solve(ws, state, solver)?;
                add_solve(&mut report, &mut solve_s, &r, s, true);
                break;
            }
            NextSolve::Done => break,
            NextSolve::Last(params) => {
                let (r, s) = solve(ws, state, &params)?;
                add_solve(&mut report, &mut solve_s, &r, s, true);
                break;
            }
            NextSolve::Solve { params, exact } => {
                let (r, s) = solve(ws, state, &params)?;
                settling.solved(exact, r.converged);
                add_solve(&mut report, &mut solve_s, &r, s, settling.exact());
            }
        }
    }
    if ws.out.bodies.active() {
        let (matrix, rhs, solved) = (&ws.s.system.matrix, &ws.s.system.rhs, (&ws.s.unknown[..], force_coefficient));
        let bodies = &ws.out.bodies;
        read_contact_forces(&mut ws.contacts.solid, matrix, rhs, solved, |c| bodies.holds(c));
    }
    timer.add(Stage::Solve, solve_s);
    Ok(Settled { report, unresolved })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn settling(rough_solves: bool) -> Settling {
        let contacts = crate::ContactSetParams { settling_iterations: 4, ..Default::default() };
        let solver = SolverParams { contacts, max_iter: 100, ..SolverParams::default() };
        Settling::new(&solver, ContactRules { friction_in_solve: true, rough_solves })
    }

    /// The next solve's iteration cap and whether it is exact (`Last`
    /// shows its cap plus 1000), or None when done.
    fn solve_of(next: NextSolve) -> Option<(usize, bool)> {
        match next {
            NextSolve::Done => None,
            NextSolve::Last(params) => Some((params.max_iter + 1000, true)),
            NextSolve::Solve { params, exact } => Some((params.max_iter, exact)),
        }
    }

    #[test]
    fn a_changing_set_is_solved_roughly_then_exactly_then_checked() {
        let mut s = settling(true);
        let (first, exact) = s.first(true);
        assert_eq!((first.max_iter, exact), (4, false));
        s.solved(exact, false);
        // The set changed: another rough solve.
        assert_eq!(solve_of(s.after_pass(false, false, || false)), Some((4, false)));
        s.solved(false, false);
        // It settled on a rough solve: an exact one, then a check.
        assert_eq!(solve_of(s.after_pass(true, false, || false)), Some((100, true)));
        s.solved(true, true);
        // Settled and exact: done (nothing slides).
        assert_eq!(solve_of(s.after_pass(true, false, || false)), None);
    }

    #[test]
    fn sliding_friction_read_from_a_rough_solve_gets_one_exact_solve() {
        let mut s = settling(true);
        let (_, exact) = s.first(true);
        s.solved(exact, false);
        assert_eq!(solve_of(s.after_pass(true, false, || true)), Some((100, true)));
        s.solved(true, true);
        // Exact and settled, but the sliding contacts' N came from the
        // rough solve: one last exact solve.
        assert_eq!(solve_of(s.after_pass(true, false, || true)), Some((1100, true)));
        // Without sliding contacts, done.
        let mut s = settling(true);
        let (_, exact) = s.first(true);
        s.solved(exact, false);
        assert_eq!(solve_of(s.after_pass(true, false, || false)), Some((100, true)));
        s.solved(true, true);
        assert_eq!(solve_of(s.after_pass(true, false, || false)), None);
    }

    #[test]
    fn without_rough_solves_every_solve_is_exact_and_the_last_pass_ends_it() {
        let mut s = settling(false);
        let (first, exact) = s.first(true);
        assert_eq!((first.max_iter, exact), (100, true));
        s.solved(exact, true);
        assert_eq!(solve_of(s.after_pass(false, false, || false)), Some((100, true)));
        s.solved(true, true);
        assert_eq!(solve_of(s.after_pass(false, true, || false)), None);
    }

    #[test]
    fn a_rough_solve_that_converges_counts_as_exact() {
        let mut s = settling(true);
        let (_, exact) = s.first(true);
        s.solved(exact, true);
        assert!(s.exact());
        assert_eq!(solve_of(s.after_pass(true, false, || false)), None);
    }
}
