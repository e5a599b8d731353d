//! The assembled implicit integrators, backward Euler and BDF2: each step
//! is one linearised (single Newton iteration) step of its scheme
//! ([`scheme`]), assembled with the pattern built once, solved by the
//! filtered PCG while the solid contacts' active set settles ([`settle`]),
//! with Newton iterations ([`newton`]) when asked or when the steps are
//! large for the material.
//!
//! Their stages in the pipeline: [`Integrator::assemble`] (the scheme's
//! vectors, the loads the system carries, the matrix and right-hand side),
//! [`Integrator::solve`] (pins and contacts constrained, the contact set
//! settled, Newton when needed, the pins' reactions and the new state),
//! [`Integrator::balance`] (the step's energy), [`Integrator::retake`]
//! (the energy guards).

mod body_newton;
mod newton;
mod scheme;
mod settle;
mod solve;
mod workspace;

pub(crate) use scheme::{EulerScheme, Linearised};
pub(crate) use solve::constrain_pins;

use super::state::IntegratorMemory;
use super::step::{Attempt, Capabilities, ContactHandling, Integrator, Response, Step, StepOutput};
use super::timer::{Stage, StageTimer};
use crate::contacts::{
    Contacts, CoupledRows, FrictionMode, SystemRows, constrain_contacts, linearise_squeeze_friction,
};
use crate::control::PinPaths;
use crate::energy::{self, EnergyReport};
use crate::system::assemble;
use crate::{Mat3, NewtonParams, NewtonReport, SolverParams, StepError, StepReport, Vec3};
use cloth_linalg::PreconditionerKind;
use scheme::Bdf2Scheme;
use settle::{ContactRules, settle_contacts, stick_frictional};
use solve::{couple_self_contacts, with_loads};
use workspace::{Scratch, StepInputs, SystemLoads, Workspace};

/// Backward Euler (Baraff & Witkin 1998, Eq. 16):
/// `[M - h D - h^2 K] dv = h (f + h K v)`, `x' = x + h (v + dv)`. A single
/// linearised step that creates energy is retaken with Newton iterations
/// ([`Attempt::WithNewton`]).
#[derive(Debug, Default)]
pub struct BackwardEuler(Implicit);

/// Second-order BDF (Choi & Ko 2002, Eq. 20, multiplied by `M` to keep
/// the matrix symmetric), with `dx = x' - x`, `delta = x - x_prev`:
/// `[M - (2h/3) D - (4h^2/9) K] dx = M (delta/3 + h (8 v - 2 v_prev)/9)
///   + (4h^2/9)(f - D v) - (2h/9) D delta`,  `v' = (3 dx - delta) / (2h)`.
/// It needs one previous step of the same size, so it starts (and
/// restarts) with a backward-Euler step; a BDF2 step that creates energy
/// is retaken as backward Euler ([`Attempt::AsBackwardEuler`]).
#[derive(Debug, Default)]
pub struct Bdf2(Implicit);

impl BackwardEuler {
    /// Its name in scene files.
    pub(crate) const NAME: &'static str = "backward-euler";
}

impl Bdf2 {
    /// Its name in scene files.
    pub(crate) const NAME: &'static str = "bdf2";
}

/// The stages and memory both implicit integrators share, delegated to
/// [`Implicit`]; each writes its own `assemble` (which scheme),
/// `retake` and `committed`.
macro_rules! implicit_stages {
    () => {
        fn name(&self) -> &'static str {
            Self::NAME
        }

        fn capabilities(&self) -> Capabilities {
            IMPLICIT
        }

        fn solve(
            &mut self,
            step: &Step<'_>,
            contacts: &mut Contacts,
            out: &mut StepOutput,
            timer: &mut StageTimer,
        ) -> Result<StepReport, StepError> {
            self.0.solve(step, contacts, out, timer)
        }

        fn balance(&mut self, step: &Step<'_>, contacts: &Contacts, out: &StepOutput) -> Option<EnergyReport> {
            Some(self.0.balance(step, contacts, out))
        }

        fn memory(&self) -> IntegratorMemory {
            self.0.memory()
        }

        fn restore_memory(&mut self, memory: &IntegratorMemory) -> Result<(), StepError> {
            self.0.restore_memory(memory)
        }

        fn reset(&mut self) {
            self.0.scratch = None;
        }
    };
}

impl Integrator for BackwardEuler {
    implicit_stages!();

    fn assemble(&mut self, step: &Step<'_>, contacts: &mut Contacts, timer: &mut StageTimer) -> Result<(), StepError> {
        self.0.scheme = SchemeKind::Euler;
        self.0.assemble(step, contacts, timer);
        Ok(())
    }

    /// A single linearised step that the energy monitor flags is retaken
    /// with Newton iterations ([`NewtonParams::auto_iterations`] of them),
    /// which follow the tension-only links across their kink (after a
    /// body tore through a cloth, the cloth alone recoiling gained 1 J in
    /// one step); the next step is again the single linearised one. With
    /// bodies in the solve, the corrections carry them (`body_newton`).
    /// Not when the step touched a solid moved by a guess from outside (a
    /// partitioned master's body): Newton's penalties on solids give a
    /// body no impulse.
    fn retake(&self, step: &Step<'_>, report: &StepReport, contacts: &Contacts, out: &StepOutput) -> Option<Attempt> {
        let flagged = flagged(report, contacts, out);
        let guarded = step.solver.energy_guard && flagged && report.newton.is_none();
        (step.attempt == Attempt::First && guarded && !touches_a_guessed_solid(step, contacts, out))
            .then_some(Attempt::WithNewton)
    }

    fn committed(&mut self, report: &StepReport) {
        self.0.newton_engaged |= report.newton.is_some_and(|n| n.automatic);
    }
}

impl Integrator for Bdf2 {
    implicit_stages!();

    /// BDF2 with a previous step of the same size; backward Euler
    /// otherwise and when retaken.
    fn assemble(&mut self, step: &Step<'_>, contacts: &mut Contacts, timer: &mut StageTimer) -> Result<(), StepError> {
        let state = step.state;
        let bdf2 = state.has_history && same_step(state.last_dt_s, step.h) && step.attempt == Attempt::First;
        self.0.scheme = if bdf2 { SchemeKind::Bdf2 } else { SchemeKind::Euler };
        self.0.assemble(step, contacts, timer);
        Ok(())
    }

    /// A BDF2 step that creates energy (its linearisation across the kink
    /// of tension-only links pumps energy into a violently moved cloth) is
    /// retaken as backward Euler, which also restarts BDF2's history; with
    /// a body in the solve touching the cloth, as backward Euler with
    /// Newton corrections that carry the body (a body striking cloth at
    /// rest: the linear step's links have no stiffness across them, which
    /// backward Euler alone does not change).
    fn retake(&self, step: &Step<'_>, report: &StepReport, contacts: &Contacts, out: &StepOutput) -> Option<Attempt> {
        if !(self.0.scheme == SchemeKind::Bdf2 && step.solver.energy_guard && flagged(report, contacts, out)) {
            return None;
        }
        Some(if touches_a_body_in_the_solve(contacts, out) && !touches_a_guessed_solid(step, contacts, out) {
            Attempt::WithNewton
        } else {
            Attempt::AsBackwardEuler
        })
    }

    /// Only the backward-Euler steps (the first, a restart, a retake)
    /// engage Newton for the run.
    fn committed(&mut self, report: &StepReport) {
        if self.0.scheme == SchemeKind::Euler {
            self.0.newton_engaged |= report.newton.is_some_and(|n| n.automatic);
        }
    }
}

/// What both implicit integrators can do.
const IMPLICIT: Capabilities =
    Capabilities { contacts: ContactHandling::Constraints, bodies: true, loads_at_start: true, linear_solve: true };

/// The memory's one entry: 1 once a step of the run was large for its
/// material ([`NewtonParams::auto_trigger`]), so that every step takes
/// Newton iterations from then on; else 0.
const NEWTON_ENGAGED: &str = "newton_engaged";

/// Whether two step sizes are the same for BDF2's constant-step formula:
/// equal to 1e-12 relative. A host that steps to communication points
/// `t0 + n h` hands steps that differ from `h` in the last bits (FMPy's
/// `simulate_fmu` does); taken as new sizes, each would restart BDF2 as
/// backward Euler, silently another integrator. The formula's error from
/// such a difference is of the same relative size.
pub(crate) fn same_step(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-12 * a.abs().max(b.abs())
}

/// Whether the energy monitor flags the step just solved: its growth
/// over [`crate::GAIN_TOLERANCE`] of the energy in play, or over
/// [`crate::BODY_GAIN_TOLERANCE`] when bodies are in the solve and the
/// cloth touches nothing else. (Pulled across a fixed table under a box,
/// a tablecloth's balance is off by 1e-2 to 1e-1 on most steps, friction
/// on the table after the solve; Newton corrections did not change it,
/// and retaking every step cost 1.85 times the run.)
fn flagged(report: &StepReport, contacts: &Contacts, out: &StepOutput) -> bool {
    let only_bodies = || out.bodies.active() && contacts.solid.iter().all(|c| out.bodies.holds(c));
    report.energy.is_some_and(|e| e.flagged || (e.growth_share > crate::BODY_GAIN_TOLERANCE && only_bodies()))
}

/// Whether a contact of the step just solved is with a body in the solve.
fn touches_a_body_in_the_solve(contacts: &Contacts, out: &StepOutput) -> bool {
    contacts.solid.iter().any(|c| out.bodies.holds(c))
}

/// Whether a contact of the step just solved is with an external solid
/// whose motion is a guess and whose body is not in the solve (a
/// partitioned master's body, [`crate::Control::set_solid_motion`]).
fn touches_a_guessed_solid(step: &Step<'_>, contacts: &Contacts, out: &StepOutput) -> bool {
    let (model, control) = (step.model, step.control);
    let guessed = |k: usize| model.colliders()[k].is_external() && !control.is_solid_prescribed(k);
    contacts.solid.iter().any(|c| !out.bodies.holds(c) && guessed(c.collider as usize))
}

/// Which scheme the current attempt takes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
enum SchemeKind {
    #[default]
    Euler,
    Bdf2,
}

/// The engine both implicit integrators share: scratch, memory, and the
/// current attempt's scheme.
#[derive(Debug, Default)]
pub(crate) struct Implicit {
    scratch: Option<Box<Scratch>>,
    newton_engaged: bool,
    scheme: SchemeKind,
}

impl Implicit {
    fn memory(&self) -> IntegratorMemory {
        IntegratorMemory::new(vec![(NEWTON_ENGAGED, f64::from(u8::from(self.newton_engaged)))])
    }

    fn restore_memory(&mut self, memory: &IntegratorMemory) -> Result<(), StepError> {
        self.memory().same_names(memory)?;
        self.newton_engaged = memory.get(NEWTON_ENGAGED).is_some_and(|v| v != 0.0);
        Ok(())
    }

    /// The stage "assemble" of the current scheme.
    fn assemble(&mut self, step: &Step<'_>, contacts: &mut Contacts, timer: &mut StageTimer) {
        match self.scheme {
            SchemeKind::Euler => self.assemble_with(&EulerScheme, step, contacts, timer),
            SchemeKind::Bdf2 => self.assemble_with(&Bdf2Scheme, step, contacts, timer),
        }
    }

    fn solve(
        &mut self,
        step: &Step<'_>,
        contacts: &mut Contacts,
        out: &mut StepOutput,
        timer: &mut StageTimer,
    ) -> Result<StepReport, StepError> {
        match self.scheme {
            SchemeKind::Euler => self.solve_with(&EulerScheme, step, contacts, out, timer),
            SchemeKind::Bdf2 => self.solve_with(&Bdf2Scheme, step, contacts, out, timer),
        }
    }

    /// The scheme's vectors, the loads the system carries (the loads of
    /// the step's start, self-collision repulsion, squeezed particles'
    /// friction), the matrix and right-hand side, and the energy at the
    /// step's start.
    fn assemble_with<S: Linearised>(
        &mut self,
        scheme: &S,
        step: &Step<'_>,
        contacts: &mut Contacts,
        timer: &mut StageTimer,
    ) {
        let Step { model, state, h, solver, loads, .. } = *step;
        let s = self.scratch.get_or_insert_with(|| Box::new(Scratch::new(model, solver)));
        scheme.prepare(state, h, &mut s.aux, &mut s.aux2);
        let mut system_loads = SystemLoads { external: loads.forces().is_some(), ..SystemLoads::default() };
        if let Some(f) = loads.forces() {
            s.external.copy_from_slice(f);
        }
        if model.self_collision().is_some() {
            if !system_loads.external {
                s.external.iter_mut().for_each(|f| *f = Vec3::zeros());
            }
            for (f, c) in s.external.iter_mut().zip(&contacts.self_force) {
                *f += c;
            }
            (system_loads.external, system_loads.self_collision) = (true, true);
        }
        squeeze_friction_in_solve(&state.v, s, contacts, &mut system_loads);
        s.loads = system_loads;
        let terms = with_loads(scheme.terms(state, &s.aux, &s.aux2, h), &s.external, contacts, &system_loads);
        s.force_coefficient = terms.force;
        let timing = assemble(model, &state.x, &terms, &mut s.system);
        couple_self_contacts(&terms, contacts, system_loads.self_collision, s.pcg.couplings_mut(), &mut s.system.rhs);
        timer.add(Stage::Forces, timing.links_s);
        timer.add(Stage::Assembly, timing.gather_s);
        s.energy_before = energy::mechanical_with(model, &state.x, &state.v, s.system.elastic_energy());
    }

    /// Pins and the starting contacts in the filter, the contact set
    /// settled over filtered PCG solves, Newton corrections when needed,
    /// then the pins' reactions and the new state into `out`.
    fn solve_with<S: Linearised>(
        &mut self,
        scheme: &S,
        step: &Step<'_>,
        contacts: &mut Contacts,
        out: &mut StepOutput,
        timer: &mut StageTimer,
    ) -> Result<StepReport, StepError> {
        let Step { model, h, .. } = *step;
        let solver = &attempt_solver(step);
        let s = self.scratch.as_mut().expect("assembled before solved");
        let (force_coefficient, loads) = (s.force_coefficient, s.loads);
        let mut ws = Workspace { s, contacts, out };
        let inputs = StepInputs::of(scheme, step, solver);
        // A retake with Newton carries the bodies in its corrections.
        let carried = step.attempt == Attempt::WithNewton && !step.control.bodies().is_empty();
        let rules = ContactRules::new(model, solver, carried);
        timer.time(Stage::Assembly, || constrain_start(inputs, &mut ws, rules));
        // The passes over the contact set are collision work; their
        // solves are timed inside as the solve.
        let lap = timer.start();
        let settled = settle_contacts(inputs, &mut ws, rules, force_coefficient, timer);
        timer.stop(lap, if model.colliders().is_empty() { Stage::Solve } else { Stage::Collision });
        let settled = settled?;
        let mut report = settled.report;
        (report.force_evaluations, report.substeps) = (1, 1);
        if carried {
            let lap = timer.start();
            let outcome = body_newton::iterate_with_bodies(inputs, &mut ws, &loads, timer);
            timer.stop(lap, Stage::Solve);
            add_newton(&mut report, &outcome?, (false, false));
        }
        if ws.out.bodies.active() {
            ws.out.bodies.follow(ws.contacts, h);
        }
        let plan = if carried {
            NewtonPlan { escalate: false, automatic: false, struck: false }
        } else {
            newton_plan(inputs, &mut ws, self.newton_engaged)
        };
        // Engaged automatically: the run's Newton settings.
        let newton = &solver.newton;
        let auto_solver =
            SolverParams { newton: NewtonParams { iterations: newton.auto_iterations, ..*newton }, ..*solver };
        let inputs = if plan.automatic || plan.struck { StepInputs { solver: &auto_solver, ..inputs } } else { inputs };
        if plan.escalate {
            if rules.friction_in_solve {
                // Newton smooths friction into its potential from scratch.
                for c in ws.contacts.solid.iter_mut().filter(|c| !c.pressed) {
                    (c.friction_mode, c.solve_constant_n) = (FrictionMode::AfterSolve, Vec3::zeros());
                }
            }
            let lap = timer.start();
            let outcome = newton::iterate(inputs, &mut ws, &loads, timer);
            timer.stop(lap, Stage::Solve);
            add_newton(&mut report, &outcome?, (plan.automatic, plan.struck));
        }
        timer.time(Stage::Update, || new_state(inputs, &mut ws, force_coefficient, plan.escalate || carried));
        ws.out.response = Response {
            time_s: scheme.response_time(h),
            newton: plan.escalate,
            unresolved: settled.unresolved,
            squeeze_friction: loads.squeeze_friction,
        };
        Ok(report)
    }

    /// The step's energy balance (after the contacts' response).
    fn balance(&mut self, step: &Step<'_>, contacts: &Contacts, out: &StepOutput) -> EnergyReport {
        let Step { model, state, control, h, .. } = *step;
        let s = self.scratch.as_mut().expect("assembled before balanced");
        let balance = energy::StepEnergy {
            before: s.energy_before,
            x: &state.x,
            new_x: &out.x,
            new_v: &out.v,
            pins: PinPaths::new(model, control, &state.x, state.time_s, h),
            pin_forces: &out.pin_forces,
            external: s.loads.external.then_some(&s.external[..]),
            contacts: &contacts.solid,
            stitches_closed: &state.stitches_closed,
        };
        let after = energy::mechanical(model, &out.x, &out.v, &state.stitches_closed, &mut s.energy);
        balance.report(model, after)
    }
}

/// Adds Newton iterations' outcome to the step's report, with why they
/// ran when not asked for: `(automatic, struck)`.
fn add_newton(report: &mut StepReport, out: &newton::NewtonOutcome, (automatic, struck): (bool, bool)) {
    report.force_evaluations += out.evaluations;
    report.cg_iterations += out.cg_iterations;
    report.converged &= out.cg_converged;
    report.newton = Some(NewtonReport {
        corrections: out.corrections,
        backtracks: out.backtracks,
        energy_evaluations: out.energy_evaluations,
        residual_m: out.residual_m,
        converged: out.converged,
        automatic,
        struck,
    });
}

/// The solver settings of the current attempt: a retake with Newton
/// takes [`NewtonParams::auto_iterations`] of them on this step only.
fn attempt_solver(step: &Step<'_>) -> SolverParams {
    let solver = step.solver;
    match step.attempt {
        Attempt::WithNewton => {
            let newton = NewtonParams { iterations: solver.newton.auto_iterations, trigger: 0.0, ..solver.newton };
            SolverParams { newton, ..*solver }
        }
        Attempt::First | Attempt::AsBackwardEuler => *solver,
    }
}

/// Puts the friction of squeezed particles that slide into the solve (see
/// `linearise_squeeze_friction`): damping blocks into
/// `contacts.friction_damping`, their constant part into `s.external`.
fn squeeze_friction_in_solve(v: &[Vec3], s: &mut Scratch, contacts: &mut Contacts, loads: &mut SystemLoads) {
    if !contacts.solid.iter().any(|c| c.pressed && c.friction > 0.0) {
        return;
    }
    if !loads.external {
        s.external.iter_mut().for_each(|f| *f = Vec3::zeros());
        loads.external = true;
    }
    contacts.friction_damping.resize(v.len(), Mat3::zeros());
    contacts.friction_damping.iter_mut().for_each(|c| *c = Mat3::zeros());
    loads.squeeze_friction =
        linearise_squeeze_friction(&mut contacts.solid, v, &mut contacts.friction_damping, &mut s.external);
}

/// The pins' prescribed unknowns and the starting contacts (stuck when
/// friction is decided in the solve) in the filter, the scheme's first
/// guess of the unknown, and the bodies in the solve.
fn constrain_start<S: Linearised>(step: StepInputs<'_, S>, ws: &mut Workspace<'_>, rules: ContactRules) {
    let StepInputs { scheme, model, state, control, h, .. } = step;
    let value = |target, i| scheme.pinned(state, h, target, i);
    constrain_pins(model, state, control, h, &mut ws.s.filter, value);
    if rules.friction_in_solve {
        stick_frictional(step, &mut ws.contacts.solid);
    }
    constrain_contacts(&ws.contacts.solid, &state.x, &mut ws.s.filter, value);
    for i in 0..state.len() {
        ws.s.unknown[i] = scheme.guess(state, &ws.s.aux, i);
    }
    let paths = PinPaths::new(model, control, &state.x, state.time_s, h);
    let factors = (h, scheme.force_coefficient(h), scheme.position_per_unknown(h));
    let multigrid = step.solver.preconditioner == PreconditionerKind::Multigrid;
    ws.out.bodies.prepare(model, multigrid, control.bodies(), |p| paths.position(p, state.time_s + h), factors);
}

/// Whether Newton iterations follow the single linearised step, and why
/// when not asked for: the run's steps are large for the material, or
/// this step alone misjudged a tension.
#[derive(Debug, Clone, Copy)]
struct NewtonPlan {
    escalate: bool,
    automatic: bool,
    struck: bool,
}

/// The Newton decision after the single linearised step. Asked for
/// (`iterations > 1`): on every step, or with a `trigger` only on steps
/// whose linearisation misjudged some link's tension by more. Not asked
/// for: for the rest of the run once a step large for the material by
/// `k h^2 / m` misjudged one by more than `auto_trigger`; on any other
/// step alone if a link with an end on a solid was misjudged by more (a
/// solid struck the cloth) and no bodies are in the solve. The measures
/// are a parallel pass over the links, and for a strike a pass over the
/// contacts' links.
fn newton_plan<S: Linearised>(step: StepInputs<'_, S>, ws: &mut Workspace<'_>, engaged: bool) -> NewtonPlan {
    let StepInputs { scheme, model, state, control, h, solver, .. } = step;
    let newton = &solver.newton;
    let mut misjudged = || newton::worst_tension_error(scheme, model, state, h, ws);
    let plan = |escalate, automatic, struck| NewtonPlan { escalate, automatic, struck };
    if newton.iterations > 1 {
        return plan(newton.trigger <= 0.0 || misjudged() > newton.trigger, false, false);
    }
    if engaged {
        return plan(true, true, false);
    }
    if newton.auto_trigger <= 0.0 {
        return plan(false, false, false);
    }
    if h * h * model.stiffest_per_mass() > crate::AUTO_NEWTON_MIN_K_H2_M {
        let engage = misjudged() > newton.auto_trigger;
        return plan(engage, engage, false);
    }
    let struck = control.bodies().is_empty()
        && newton::worst_struck_tension_error(scheme, (model, state), h, ws) > newton.auto_trigger;
    plan(struck, false, struck)
}

/// The pins' reactions (their rows of the unfiltered residual; after
/// Newton the system is assembled at the final iterate, `rhs = -r`) and
/// the new positions and velocities, into `ws.out`.
fn new_state<S: Linearised>(step: StepInputs<'_, S>, ws: &mut Workspace<'_>, force_coefficient: f64, newton: bool) {
    let StepInputs { scheme, model, state, control, h, .. } = step;
    let pins = PinPaths::new(model, control, &state.x, state.time_s, h);
    let s = &*ws.s;
    let rows = CoupledRows { matrix: &s.system.matrix, coupled: &s.coupled };
    let forces = ws.out.pin_forces_mut(pins.count());
    for (i, f) in pins.particles().zip(forces) {
        let residual = if newton { -s.system.rhs[i] } else { rows.row_times(i, &s.unknown) - s.system.rhs[i] };
        *f = residual / force_coefficient;
    }
    for i in 0..state.len() {
        (ws.out.x[i], ws.out.v[i]) = scheme.advance(state, &s.aux, h, i, s.unknown[i]);
    }
}
