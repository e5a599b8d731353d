//! Implicit integrators behind one trait: each takes one linearised
//! (single Newton iteration) step solved by the filtered PCG.

use crate::contacts::{
    ContactBuffers, ContactStats, FrictionMode, apply_friction, constrain_contacts, detect_self_contacts,
    detect_solid_contacts, linearise_squeeze_friction, project_out, separate_self_contacts, squeeze_friction_forces,
    stop_separation, untangle_step,
};
use crate::control::{Control, PinPaths};
use crate::energy;
use crate::{
    ClothModel, ClothState, Mat3, Vec3,
    forces::{SystemTerms, assemble},
};
use cloth_linalg::{Constraint, ConstraintFilter, PcgError};
use std::time::Instant;

use super::settle::{ContactRules, settle_contacts, stick_frictional};
pub use super::step_types::*;

/// A time integrator: advances `state` by `h` seconds. Integrators hold only
/// parameters; everything that influences the result lives in the state,
/// so a restored snapshot steps to the same bits.
pub trait Integrator: Send + Sync + std::fmt::Debug {
    /// The integrator's name, as reports and errors show it (a scene's
    /// `simulation.integrator` for the built-in ones).
    fn name(&self) -> &'static str;

    /// One step of size `h` (s). On error the state is unchanged.
    fn step(
        &self,
        model: &ClothModel,
        state: &mut ClothState,
        control: &Control,
        h: f64,
        ws: &mut Workspace,
        solver: &SolverParams,
    ) -> Result<StepReport, StepError>;

    /// Whether the particles its contacts hold restart the scheme's history
    /// after the step ([`crate::contacts`]' `restart_history_at_contacts`):
    /// the linearised implicit steps, whose contacts are constraints.
    fn restarts_history_at_contacts(&self) -> bool {
        false
    }

    /// Whether rigid bodies can join its solve ([`crate::Control::set_bodies`]).
    fn takes_bodies(&self) -> bool {
        false
    }
}

/// Backward Euler (Baraff & Witkin 1998, Eq. 16):
/// `[M - h D - h^2 K] dv = h (f + h K v)`, `x' = x + h (v + dv)`.
#[derive(Debug, Clone, Copy, Default)]
pub struct BackwardEuler;

/// Second-order BDF (Choi & Ko 2002, Eq. 20, multiplied by `M` to keep
/// the matrix symmetric), with `dx = x' - x`, `delta = x - x_prev`:
/// `[M - (2h/3) D - (4h^2/9) K] dx = M (delta/3 + h (8 v - 2 v_prev)/9)
///   + (4h^2/9)(f - D v) - (2h/9) D delta`,  `v' = (3 dx - delta) / (2h)`.
/// `f - D v` is the undamped force, since damping is linear in `v`.
#[derive(Debug, Clone, Copy, Default)]
pub struct Bdf2;

impl Integrator for BackwardEuler {
    fn name(&self) -> &'static str {
        IntegratorKind::BackwardEuler.name()
    }

    fn takes_bodies(&self) -> bool {
        true
    }

    fn restarts_history_at_contacts(&self) -> bool {
        true
    }

    fn step(
        &self,
        model: &ClothModel,
        state: &mut ClothState,
        control: &Control,
        h: f64,
        ws: &mut Workspace,
        solver: &SolverParams,
    ) -> Result<StepReport, StepError> {
        check_step(model, state, h)?;
        guarded_backward_euler(model, state, control, h, ws, solver)
    }
}

impl Integrator for Bdf2 {
    fn name(&self) -> &'static str {
        IntegratorKind::Bdf2.name()
    }

    fn takes_bodies(&self) -> bool {
        true
    }

    fn restarts_history_at_contacts(&self) -> bool {
        true
    }

    fn step(
        &self,
        model: &ClothModel,
        state: &mut ClothState,
        control: &Control,
        h: f64,
        ws: &mut Workspace,
        solver: &SolverParams,
    ) -> Result<StepReport, StepError> {
        check_step(model, state, h)?;
        // BDF2 needs one previous step of the same size; otherwise start
        // (or restart) with backward Euler.
        if !state.has_history || !same_step(state.last_dt_s, h) {
            return linearised_step(&BackwardEuler, model, state, control, h, ws, solver);
        }
        // A BDF2 step that creates energy (its linearisation across the
        // kink of tension-only links pumps energy into a violently moved
        // cloth) is retaken as backward Euler.
        let report = uncommitted_step(self, model, state, control, h, ws, solver)?;
        if solver.energy_guard && report.energy.is_some_and(|e| e.flagged) {
            let mut report = linearised_step(&BackwardEuler, model, state, control, h, ws, solver)?;
            report.retaken_as_backward_euler = true;
            return Ok(report);
        }
        commit(state, ws, h)?;
        Ok(report)
    }
}

/// Whether two step sizes are the same for BDF2's constant-step formula:
/// equal to 1e-12 relative. A host that steps to communication points
/// `t0 + n h` hands steps that differ from `h` in the last bits (FMPy's
/// `simulate_fmu` does); taken as new sizes, each would restart BDF2 as
/// backward Euler, silently another integrator. The formula's error from
/// such a difference is of the same relative size.
pub(crate) fn same_step(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-12 * a.abs().max(b.abs())
}

/// What distinguishes one single-Newton-iteration implicit scheme from
/// another: its linear system, its unknown, and how the unknown updates
/// the state. [`linearised_step`] does the rest.
pub(crate) trait Linearised {
    /// Fills the scheme's auxiliary vectors from the state.
    fn prepare(&self, state: &ClothState, h: f64, aux: &mut [Vec3], aux2: &mut [Vec3]);
    /// The system's coefficients and right-hand-side terms.
    fn terms<'a>(&self, state: &'a ClothState, aux: &'a [Vec3], aux2: &'a [Vec3], h: f64) -> SystemTerms<'a>;
    /// The unknown of particle `i` when its position at `t + h` is `target`.
    fn pinned(&self, state: &ClothState, h: f64, target: Vec3, i: usize) -> Vec3;
    /// Initial PCG guess for particle `i` (from the state only, so a
    /// restored snapshot solves from the same guess).
    fn guess(&self, state: &ClothState, aux: &[Vec3], i: usize) -> Vec3;
    /// New `(x, v)` of particle `i` from the solved unknown.
    fn advance(&self, state: &ClothState, aux: &[Vec3], h: f64, i: usize, unknown: Vec3) -> (Vec3, Vec3);
    /// For a Newton correction at iterate `u`: the `y` of the `M y` term of
    /// the negative residual, particle `i`.
    fn newton_mass_term(&self, aux2: &[Vec3], i: usize, u: Vec3) -> Vec3;
    /// The time over which a force acting during the step changes the new
    /// velocity, s (`h` for backward Euler, `2h/3` for BDF2); also the
    /// position change per velocity change of the new state.
    fn response_time(&self, h: f64) -> f64;
    /// The coefficient `c_f` of the forces in the step equation
    /// `M (u - y0) = c_f f(x(u), v(u))` (`h` for backward Euler, `4h^2/9`
    /// for BDF2), s or s^2.
    fn force_coefficient(&self, h: f64) -> f64;
    /// `dx'/du`: how the new positions move with the unknown (`h`, `1`).
    fn position_per_unknown(&self, h: f64) -> f64;
    /// `dv'/du`: how the new velocities move with the unknown (`1`, `3/(2h)`).
    fn velocity_per_unknown(&self, h: f64) -> f64;
    /// The system of a Newton correction at an iterate with velocities `v_k`
    /// (positions are passed to the assembly): same matrix, right-hand side
    /// the negative residual `c_f f(x_k, v_k) + M y`.
    fn newton_terms<'a>(&self, h: f64, v_k: &'a [Vec3], y: &'a [Vec3], stitches_closed: &'a [bool]) -> SystemTerms<'a>;
}

impl Linearised for BackwardEuler {
    fn prepare(&self, _: &ClothState, _: f64, _: &mut [Vec3], _: &mut [Vec3]) {}

    fn terms<'a>(&self, state: &'a ClothState, _: &'a [Vec3], _: &'a [Vec3], h: f64) -> SystemTerms<'a> {
        let v = &state.v;
        let closed = &state.stitches_closed;
        SystemTerms { k_times: Some((h * h, v)), d_times: Some((h, v)), ..SystemTerms::new(h * h, h, h, closed) }
    }

    /// `dv = (p(t + h) - x) / h - v`.
    fn pinned(&self, state: &ClothState, h: f64, target: Vec3, i: usize) -> Vec3 {
        (target - state.x[i]) / h - state.v[i]
    }

    /// The previous change of velocity.
    fn guess(&self, state: &ClothState, _: &[Vec3], i: usize) -> Vec3 {
        if state.has_history { state.v[i] - state.v_prev[i] } else { Vec3::zeros() }
    }

    fn advance(&self, state: &ClothState, _: &[Vec3], h: f64, i: usize, dv: Vec3) -> (Vec3, Vec3) {
        let v = state.v[i] + dv;
        (state.x[i] + v * h, v)
    }

    fn response_time(&self, h: f64) -> f64 {
        h
    }

    fn force_coefficient(&self, h: f64) -> f64 {
        h
    }

    fn position_per_unknown(&self, h: f64) -> f64 {
        h
    }

    fn velocity_per_unknown(&self, _: f64) -> f64 {
        1.0
    }

    /// Residual `M dv - h f(x + h (v + dv), v + dv)`: `y = -dv`.
    fn newton_mass_term(&self, _: &[Vec3], _: usize, dv: Vec3) -> Vec3 {
        -dv
    }

    fn newton_terms<'a>(&self, h: f64, v_k: &'a [Vec3], y: &'a [Vec3], closed: &'a [bool]) -> SystemTerms<'a> {
        SystemTerms { d_times: Some((h, v_k)), mass_times: Some(y), ..SystemTerms::new(h * h, h, h, closed) }
    }
}

impl Linearised for Bdf2 {
    /// `aux = delta = x - x_prev`; `aux2 = delta/3 + h (8 v - 2 v_prev)/9`.
    fn prepare(&self, state: &ClothState, h: f64, aux: &mut [Vec3], aux2: &mut [Vec3]) {
        for i in 0..state.len() {
            let delta = state.x[i] - state.x_prev[i];
            aux[i] = delta;
            aux2[i] = delta / 3.0 + (state.v[i] * 8.0 - state.v_prev[i] * 2.0) * (h / 9.0);
        }
    }

    fn terms<'a>(&self, state: &'a ClothState, aux: &'a [Vec3], aux2: &'a [Vec3], h: f64) -> SystemTerms<'a> {
        SystemTerms {
            d_times: Some((-2.0 * h / 9.0, aux)),
            mass_times: Some(aux2),
            ..SystemTerms::new(4.0 * h * h / 9.0, 2.0 * h / 3.0, 4.0 * h * h / 9.0, &state.stitches_closed)
        }
    }

    /// `dx = p(t + h) - x`.
    fn pinned(&self, state: &ClothState, _: f64, target: Vec3, i: usize) -> Vec3 {
        target - state.x[i]
    }

    /// The previous displacement.
    fn guess(&self, _: &ClothState, aux: &[Vec3], i: usize) -> Vec3 {
        aux[i]
    }

    fn advance(&self, state: &ClothState, aux: &[Vec3], h: f64, i: usize, dx: Vec3) -> (Vec3, Vec3) {
        (state.x[i] + dx, (dx * 3.0 - aux[i]) / (2.0 * h))
    }

    /// `v' = (3 dx - delta) / (2h)` and `dx` moves by `(4h^2/9) f / m`.
    fn response_time(&self, h: f64) -> f64 {
        2.0 * h / 3.0
    }

    fn force_coefficient(&self, h: f64) -> f64 {
        4.0 * h * h / 9.0
    }

    fn position_per_unknown(&self, _: f64) -> f64 {
        1.0
    }

    fn velocity_per_unknown(&self, h: f64) -> f64 {
        1.5 / h
    }

    /// Residual `M (dx - y0) - (4h^2/9) f(x + dx, v'(dx))` with `y0 = aux2`: `y = y0 - dx`.
    fn newton_mass_term(&self, aux2: &[Vec3], i: usize, dx: Vec3) -> Vec3 {
        aux2[i] - dx
    }

    fn newton_terms<'a>(&self, h: f64, v_k: &'a [Vec3], y: &'a [Vec3], closed: &'a [bool]) -> SystemTerms<'a> {
        let c = 4.0 * h * h / 9.0;
        SystemTerms { d_times: Some((c, v_k)), mass_times: Some(y), ..SystemTerms::new(c, 2.0 * h / 3.0, c, closed) }
    }
}

/// One backward-Euler step, committed. A single linearised step that
/// creates energy (after a body tore through a cloth, the cloth alone
/// recoiling gained 1 J in one step) is retaken with Newton iterations
/// ([`NewtonParams::auto_iterations`] of them), which follow the
/// tension-only links across their kink; the next step is again the
/// single linearised one. Ordinary steps cost what they did. Not when
/// the step touched a body ([`touches_a_body`]): Newton's penalties on
/// solids give a body no impulse.
fn guarded_backward_euler(
    model: &ClothModel,
    state: &mut ClothState,
    control: &Control,
    h: f64,
    ws: &mut Workspace,
    solver: &SolverParams,
) -> Result<StepReport, StepError> {
    let report = uncommitted_step(&BackwardEuler, model, state, control, h, ws, solver)?;
    let flagged = report.energy.is_some_and(|e| e.flagged);
    if !(solver.energy_guard && flagged && report.newton.is_none()) || touches_a_body(model, control, ws) {
        return committed(report, state, ws, h);
    }
    let newton = NewtonParams { iterations: solver.newton.auto_iterations, trigger: 0.0, ..solver.newton };
    let retake = SolverParams { newton, ..*solver };
    let report = uncommitted_step(&BackwardEuler, model, state, control, h, ws, &retake)?;
    committed(StepReport { retaken_with_newton: true, ..report }, state, ws, h)
}

/// One step of a [`Linearised`] scheme, committed.
fn linearised_step<S: Linearised>(
    scheme: &S,
    model: &ClothModel,
    state: &mut ClothState,
    control: &Control,
    h: f64,
    ws: &mut Workspace,
    solver: &SolverParams,
) -> Result<StepReport, StepError> {
    let report = uncommitted_step(scheme, model, state, control, h, ws, solver)?;
    committed(report, state, ws, h)
}

/// Commits the step solved in `ws` whose report is `report`.
fn committed(report: StepReport, state: &mut ClothState, ws: &mut Workspace, h: f64) -> Result<StepReport, StepError> {
    commit(state, ws, h)?;
    state.newton_engaged |= report.newton.is_some_and(|n| n.automatic);
    Ok(report)
}

/// Whether a contact of the step just solved (in `ws`) is with a solid
/// whose reaction goes to a rigid body: a body in the solve, or an
/// external solid whose motion is a guess (a partitioned master's body,
/// [`Control::set_solid_motion`]).
fn touches_a_body(model: &ClothModel, control: &Control, ws: &Workspace) -> bool {
    let guessed = |k: usize| model.colliders()[k].is_external() && !control.is_solid_prescribed(k);
    ws.contacts.solid.iter().any(|c| ws.bodies.holds(c) || guessed(c.collider as usize))
}

/// One step of a [`Linearised`] scheme up to its commit, as named
/// phases (the state is not changed; the result is in `ws.new_x` and
/// `ws.new_v`):
///
/// 1. **gather loads**: wind and outside forces, self-collision, the solid
///    contacts of the step's start ([`step_loads`]);
/// 2. **assemble** `A` and `b` ([`assemble`]);
/// 3. **constrain** pins and the starting contacts in the filter;
/// 4. **settle the contact set** over filtered PCG solves
///    ([`settle::settle_contacts`]);
/// 5. **Newton** corrections with a line search, when asked;
/// 6. **respond**: pin reactions, the new positions and velocities,
///    friction, no bounce off holding solids, self-collision separation,
///    the last projection out of solids ([`respond`]);
/// 7. **balance** the step's energy and report its stages.
fn uncommitted_step<S: Linearised>(
    scheme: &S,
    model: &ClothModel,
    state: &ClothState,
    control: &Control,
    h: f64,
    ws: &mut Workspace,
    solver: &SolverParams,
) -> Result<StepReport, StepError> {
    // 1. Gather loads.
    scheme.prepare(state, h, &mut ws.aux, &mut ws.aux2);
    let mut loads = step_loads(model, state, control, h, ws)?;
    squeeze_friction_in_solve(state, ws, &mut loads);
    // 2. Assemble.
    let terms = with_loads(scheme.terms(state, &ws.aux, &ws.aux2, h), &ws.external, &ws.contacts, &loads);
    let force_coefficient = terms.force;
    let timing = assemble(model, &state.x, &terms, &mut ws.system);
    let energy_before = energy::mechanical_with(model, &state.x, &state.v, ws.system.elastic_energy());
    // 3. Constrain pins and the contacts of the step's start.
    let t_pins = Instant::now();
    let rules = ContactRules::new(model, solver);
    let step = StepInputs { scheme, model, state, control, h, solver };
    constrain_start(step, ws, rules);
    let pins_s = t_pins.elapsed().as_secs_f64();
    // 4. Settle the contact set.
    let mut stats = loads.stats;
    let settled = settle_contacts(step, ws, rules, force_coefficient, &mut stats)?;
    let (mut report, mut solve_s) = (settled.report, settled.solve_s);
    if ws.bodies.active() {
        ws.bodies.follow(&mut ws.contacts, h);
    }
    (report.force_evaluations, report.substeps) = (1, 1);
    let (mut forces_s, mut assembly_s) = (timing.links_s, timing.gather_s + pins_s);
    // 5. Newton iterations with a line search on the nonlinear step
    // equation (see `newton`): solids then act as penalties,
    // self-collision as at the start of the step.
    let newton = &solver.newton;
    let misjudged = |ws: &mut Workspace| crate::newton::worst_tension_error(scheme, model, state, h, ws);
    let (escalate, automatic) = if newton.iterations > 1 {
        (newton.trigger <= 0.0 || misjudged(ws) > newton.trigger, false)
    } else {
        // Checked only on steps large for the material by `k h^2 / m`: a
        // pass over the links on every step cost 5-10% of a light scene's.
        let large = h * h * model.stiffest_per_mass() > crate::AUTO_NEWTON_MIN_K_H2_M;
        let engaged =
            state.newton_engaged || (newton.auto_trigger > 0.0 && large && misjudged(ws) > newton.auto_trigger);
        (engaged, engaged)
    };
    // Engaged automatically: the run's Newton settings.
    let auto_solver =
        SolverParams { newton: NewtonParams { iterations: newton.auto_iterations, ..*newton }, ..*solver };
    let step = if automatic { StepInputs { solver: &auto_solver, ..step } } else { step };
    if escalate {
        if rules.friction_in_solve {
            // Newton smooths friction into its potential from scratch.
            for c in ws.contacts.solid.iter_mut().filter(|c| !c.pressed) {
                (c.friction_mode, c.solve_constant_n) = (FrictionMode::AfterSolve, Vec3::zeros());
            }
        }
        let out = crate::newton::iterate(step, ws, &loads)?;
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
        });
        forces_s += out.forces_s;
        assembly_s += out.assembly_s;
        solve_s += out.solve_s;
    }
    // 6. Respond.
    let t_update = Instant::now();
    let response = Response { force_coefficient, newton: escalate, unresolved: settled.unresolved };
    let (pins, crossings_s) = respond(step, ws, &loads, response, &mut stats);
    // 7. Balance the energy and report.
    let balance = energy::StepEnergy {
        before: energy_before,
        x: &state.x,
        new_x: &ws.new_x,
        new_v: &ws.new_v,
        pins,
        pin_forces: &ws.pin_forces,
        external: loads.external.then_some(&ws.external[..]),
        contacts: &ws.contacts.solid,
        stitches_closed: &state.stitches_closed,
    };
    let after = energy::mechanical(model, &ws.new_x, &ws.new_v, &state.stitches_closed, &mut ws.energy);
    report.energy = Some(balance.report(model, after));
    report.stages = StageTimes {
        forces_s,
        assembly_s,
        solve_s,
        update_s: t_update.elapsed().as_secs_f64() - crossings_s,
        collision_s: loads.collision_s,
        self_collision_s: loads.self_collision_s + crossings_s,
    };
    report.contacts = stats;
    Ok(report)
}

/// What one step of a [`Linearised`] scheme reads and never changes: the
/// scheme, the model, the state at the step's start, the control inputs,
/// the step size (s) and the solver settings.
pub(crate) struct StepInputs<'a, S> {
    pub(crate) scheme: &'a S,
    pub(crate) model: &'a ClothModel,
    pub(crate) state: &'a ClothState,
    pub(crate) control: &'a Control,
    pub(crate) h: f64,
    pub(crate) solver: &'a SolverParams,
}

impl<S> Clone for StepInputs<'_, S> {
    fn clone(&self) -> Self {
        *self
    }
}

impl<S> Copy for StepInputs<'_, S> {}

/// Phase 3: the pins' prescribed unknowns and the starting contacts
/// (stuck when friction is decided in the solve) in the filter, and the
/// scheme's first guess of the unknown.
fn constrain_start<S: Linearised>(step: StepInputs<'_, S>, ws: &mut Workspace, rules: ContactRules) {
    let StepInputs { scheme, model, state, control, h, .. } = step;
    let value = |target, i| scheme.pinned(state, h, target, i);
    constrain_pins(model, state, control, h, &mut ws.filter, value);
    if rules.friction_in_solve {
        stick_frictional(step, &mut ws.contacts.solid);
    }
    constrain_contacts(&ws.contacts.solid, &state.x, &mut ws.filter, value);
    for i in 0..state.len() {
        ws.unknown[i] = scheme.guess(state, &ws.aux, i);
    }
    let paths = PinPaths::new(model, control, &state.x, state.time_s, h);
    let factors = (h, scheme.force_coefficient(h), scheme.position_per_unknown(h));
    let multigrid = step.solver.preconditioner == cloth_linalg::PreconditionerKind::Multigrid;
    ws.bodies.prepare(model, multigrid, control.bodies(), |p| paths.position(p, state.time_s + h), factors);
}

/// Rounds of impact zones and projection out of the solids after a step
/// whose projection pushed cloth (see `respond`).
const PROJECTION_ROUNDS: usize = 4;

/// What the response needs to know of the solves.
#[derive(Debug, Clone, Copy)]
struct Response {
    /// The right-hand side's force coefficient (pin reactions from the residual).
    force_coefficient: f64,
    /// Newton corrections ran: solids were penalties, not constraints.
    newton: bool,
    /// The contact passes ran out while still adding contacts.
    unresolved: bool,
}

/// Phase 6: the pins' reactions (their rows of the unfiltered residual),
/// the new positions and velocities, friction, no bounce off holding
/// solids, self-collision separation, the continuous self-collision test
/// and the last projection out of solids (solids last: cloth never ends a
/// step inside one). Returns the pin paths for the energy balance, and the
/// time the continuous test took (s, counted as self-collision).
fn respond<'a, S: Linearised>(
    step: StepInputs<'a, S>,
    ws: &mut Workspace,
    loads: &StepLoads,
    response: Response,
    stats: &mut ContactStats,
) -> (PinPaths<'a>, f64) {
    let StepInputs { scheme, model, state, control, h, .. } = step;
    let newton = response.newton;
    // After Newton the system is assembled at the final iterate: `rhs = -r`.
    let pins = PinPaths::new(model, control, &state.x, state.time_s, h);
    ws.pin_forces.resize(pins.count(), Vec3::zeros());
    for (i, f) in pins.particles().zip(&mut ws.pin_forces) {
        let residual =
            if newton { -ws.system.rhs[i] } else { ws.system.matrix.row_times(i, &ws.unknown) - ws.system.rhs[i] };
        *f = residual / response.force_coefficient;
    }
    for i in 0..state.len() {
        (ws.new_x[i], ws.new_v[i]) = scheme.advance(state, &ws.aux, h, i, ws.unknown[i]);
    }
    let tau = scheme.response_time(h);
    let solid = &mut ws.contacts.solid;
    // Friction in the solve: squeezed particles', and the held ones' in Newton iterations.
    if loads.squeeze_friction || newton {
        squeeze_friction_forces(solid, &ws.new_v);
    }
    stats.sticking = apply_friction(solid, model.masses(), (tau, h), newton, &mut ws.new_x, &mut ws.new_v);
    if !newton {
        // Held particles do not bounce off their solid.
        ws.bodies.stop_separation(solid, model.masses(), &mut ws.new_v);
        let bodies = &ws.bodies;
        stop_separation(solid, model.masses(), &mut ws.new_v, |c| bodies.holds(c));
    }
    let mut crossings_s = 0.0;
    if let Some(sc) = model.self_collision() {
        let pairs = &ws.contacts.self_pairs;
        stats.self_separations = separate_self_contacts(model, sc, pairs, tau, &mut ws.new_x, &mut ws.new_v);
        if sc.continuous {
            let t = Instant::now();
            ws.contacts.crossings.start_step(ws.new_x.len());
            (stats.self_crossings, stats.crossings_left) =
                untangle_step(model, sc, &state.x, tau, &mut ws.new_x, &mut ws.new_v, &mut ws.contacts);
            crossings_s += t.elapsed().as_secs_f64();
        }
    }
    if !model.colliders().is_empty() {
        // After Newton iterations (penalties, not constraints), an active
        // set that ran out of passes or self-collision separations (which
        // can push a hem into a swinging shin): check every particle.
        let all = response.unresolved || newton || stats.self_separations > 0 || stats.self_crossings > 0;
        let times = (state.time_s, h);
        let continuous = model.self_collision().filter(|sc| sc.continuous);
        if continuous.is_some() {
            ws.contacts.crossings.before_projection(&ws.new_x);
        }
        stats.projected = project_out(model, &state.x, times, &mut ws.contacts, all, &mut ws.new_x, &mut ws.new_v);
        // A solid pushing cloth out can push it through another layer
        // (a hem pinched between the knees): the pushed particles are held
        // and carry what they would cross with them, then the solids
        // project again, a few rounds.
        if let Some(sc) = continuous.filter(|_| stats.projected > 0) {
            for _ in 0..PROJECTION_ROUNDS {
                let t = Instant::now();
                ws.contacts.crossings.hold_projected(&ws.new_x);
                let (met, left) =
                    untangle_step(model, sc, &state.x, tau, &mut ws.new_x, &mut ws.new_v, &mut ws.contacts);
                crossings_s += t.elapsed().as_secs_f64();
                (stats.self_crossings, stats.crossings_left) = (stats.self_crossings + met, left);
                if met == 0 {
                    break;
                }
                ws.contacts.crossings.before_projection(&ws.new_x);
                let again = project_out(model, &state.x, times, &mut ws.contacts, true, &mut ws.new_x, &mut ws.new_v);
                stats.projected += again;
                if again == 0 {
                    break;
                }
            }
        }
    }
    stats.contacts = ws.contacts.solid.iter().filter(|c| c.active).count();
    (pins, crossings_s)
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

/// A scheme's `terms` with the loads of the step that `loads` says are
/// present: external forces, self-collision stiffness, squeeze friction.
pub(crate) fn with_loads<'a>(
    mut terms: SystemTerms<'a>,
    external: &'a [Vec3],
    contacts: &'a ContactBuffers,
    loads: &StepLoads,
) -> SystemTerms<'a> {
    terms.external = loads.external.then_some(external);
    terms.diag_stiffness = loads.self_collision.then_some(&contacts.self_stiffness[..]);
    terms.diag_damping = loads.squeeze_friction.then_some(&contacts.friction_damping[..]);
    terms
}

/// Puts the friction of squeezed particles that slide into the solve (see
/// `linearise_squeeze_friction`): damping blocks into
/// `ws.contacts.friction_damping`, their constant part into `ws.external`.
fn squeeze_friction_in_solve(state: &ClothState, ws: &mut Workspace, loads: &mut StepLoads) {
    if !ws.contacts.solid.iter().any(|c| c.pressed && c.friction > 0.0) {
        return;
    }
    if !loads.external {
        ws.external.iter_mut().for_each(|f| *f = Vec3::zeros());
        loads.external = true;
    }
    let bufs = &mut ws.contacts;
    bufs.friction_damping.resize(state.len(), Mat3::zeros());
    bufs.friction_damping.iter_mut().for_each(|c| *c = Mat3::zeros());
    loads.squeeze_friction =
        linearise_squeeze_friction(&mut bufs.solid, &state.v, &mut bufs.friction_damping, &mut ws.external);
}

/// What acts on the cloth besides its own links in one step.
pub(crate) struct StepLoads {
    /// `ws.external` holds forces (wind, self-collision).
    pub(crate) external: bool,
    /// `ws.contacts.self_stiffness` holds self-collision stiffness.
    pub(crate) self_collision: bool,
    /// `ws.contacts.friction_damping` holds friction of squeezed particles.
    pub(crate) squeeze_friction: bool,
    stats: ContactStats,
    collision_s: f64,
    self_collision_s: f64,
}

/// Wind and self-collision forces at the start of the step into
/// `ws.external`, and the cloth-solid contacts of the step into
/// `ws.contacts.solid`. Only what the model has is computed.
fn step_loads(
    model: &ClothModel,
    state: &ClothState,
    control: &Control,
    h: f64,
    ws: &mut Workspace,
) -> Result<StepLoads, StepError> {
    let mut loads = StepLoads {
        external: external_forces(model, state, control, ws),
        self_collision: false,
        squeeze_friction: false,
        stats: ContactStats::default(),
        collision_s: 0.0,
        self_collision_s: 0.0,
    };
    if let Some(sc) = model.self_collision() {
        let t = Instant::now();
        let stats = detect_self_contacts(model, sc, &state.x, &state.v, h, &mut ws.contacts).map_err(|particle| {
            StepError::NonFinite { step: state.steps + 1, time_s: state.time_s, particle, quantity: "position" }
        })?;
        if !loads.external {
            ws.external.iter_mut().for_each(|f| *f = Vec3::zeros());
        }
        for (f, s) in ws.external.iter_mut().zip(&ws.contacts.self_force) {
            *f += s;
        }
        (loads.external, loads.self_collision) = (true, true);
        loads.stats += stats;
        loads.self_collision_s = t.elapsed().as_secs_f64();
    }
    ws.contacts.solid.clear();
    if !model.colliders().is_empty() {
        let t = Instant::now();
        ws.contacts.set_external(control);
        loads.stats += detect_solid_contacts(model, state, h, &mut ws.contacts);
        loads.collision_s = t.elapsed().as_secs_f64();
    }
    Ok(loads)
}

/// The after-step response to solids of the integrators without an
/// assembled matrix, on `ws.new_x`/`new_v` (nothing without solids); its
/// time goes to `stages.collision_s`.
pub(crate) fn collide_after_step(
    model: &ClothModel,
    state: &ClothState,
    control: &Control,
    h: f64,
    ws: &mut Workspace,
    stages: &mut StageTimes,
) -> ContactStats {
    if model.colliders().is_empty() {
        return ContactStats::default();
    }
    let t = Instant::now();
    ws.contacts.set_external(control);
    let times = (state.time_s, h);
    let stats =
        crate::contacts::collide_after_step(model, &state.x, times, &mut ws.contacts, &mut ws.new_x, &mut ws.new_v);
    stages.collision_s += t.elapsed().as_secs_f64();
    stats
}

/// Fails when the model asks for self-collision, which only the assembled
/// implicit integrators and the vertex solver handle (the explicit and
/// fixed-CG steps handle solids after the step, see
/// [`crate::contacts::collide_after_step`]).
pub(crate) fn reject_self_collision(model: &ClothModel, integrator: &'static str) -> Result<(), StepError> {
    if model.self_collision().is_some() {
        return Err(StepError::SelfCollisionNeedsMatrix { integrator });
    }
    Ok(())
}

/// Wind forces at the start of the step and the control's external
/// forces into `ws.external`; false (and nothing computed) when there are
/// neither.
pub(crate) fn external_forces(model: &ClothModel, state: &ClothState, control: &Control, ws: &mut Workspace) -> bool {
    if !has_external_forces(model, control) {
        return false;
    }
    ws.external.iter_mut().for_each(|f| *f = Vec3::zeros());
    let at = crate::terms::At::new(model, &state.x, &state.v, &state.stitches_closed).with_wind_at(
        state.time_s,
        control.wind(),
        control.wind_scale(),
    );
    crate::terms::add_external_forces(&at, &mut ws.external_scratch, &mut ws.external);
    control.add_forces_to(&mut ws.external);
    true
}

/// Whether any force from outside the cloth acts: an external term of the
/// model (the wind's) or the control's forces.
pub(crate) fn has_external_forces(model: &ClothModel, control: &Control) -> bool {
    crate::terms::external(model).next().is_some() || control.forces().is_some()
}

pub(crate) fn check_step(model: &ClothModel, state: &ClothState, h: f64) -> Result<(), StepError> {
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
    Ok(())
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

pub(crate) fn solve(
    ws: &mut Workspace,
    state: &ClothState,
    solver: &SolverParams,
) -> Result<(StepReport, f64), StepError> {
    let t0 = Instant::now();
    let result = if ws.bodies.active() {
        ws.bodies.link(&ws.filter, &ws.contacts.solid, state.len());
        ws.bodies.solve(&ws.system.matrix, &ws.system.rhs, &ws.filter, &solver.pcg(), &mut ws.unknown)
    } else {
        ws.pcg.solve_in_place(&mut ws.system.matrix, &ws.system.rhs, &ws.filter, &solver.pcg(), &mut ws.unknown)
    };
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
fn locate_non_finite(ws: &Workspace, state: &ClothState) -> StepError {
    let bad = |v: &Vec3| !v.iter().all(|c| c.is_finite());
    let matrix_row_bad = |i: usize| {
        ws.system.matrix.pattern().row_range(i).any(|s| !ws.system.matrix.values()[s].iter().all(|c| c.is_finite()))
    };
    let found = (0..state.len())
        .find_map(|i| bad(&ws.system.rhs[i]).then_some((i, "force")))
        .or_else(|| (0..state.len()).find_map(|i| matrix_row_bad(i).then_some((i, "stiffness"))))
        .or_else(|| (0..state.len()).find_map(|i| bad(&ws.unknown[i]).then_some((i, "solver iterate"))))
        .or_else(|| state.first_non_finite());
    // Every input finite yet PCG overflowed: blame the largest force.
    let (particle, quantity) = found.unwrap_or_else(|| {
        let largest = (0..state.len()).max_by(|&a, &b| ws.system.rhs[a].norm().total_cmp(&ws.system.rhs[b].norm()));
        (largest.unwrap_or(0), "value in the linear solve (overflow from its force)")
    });
    StepError::NonFinite { step: state.steps + 1, time_s: state.time_s, particle, quantity }
}

/// Checks the new state in `ws.new_x`/`new_v` and, if finite, makes it current.
pub(crate) fn commit(state: &mut ClothState, ws: &mut Workspace, h: f64) -> Result<(), StepError> {
    let bad = |v: &Vec3| !v.iter().all(|c| c.is_finite());
    for i in 0..state.len() {
        let quantity = if bad(&ws.new_x[i]) {
            "position"
        } else if bad(&ws.new_v[i]) {
            "velocity"
        } else {
            continue;
        };
        return Err(StepError::NonFinite { step: state.steps + 1, time_s: state.time_s, particle: i, quantity });
    }
    // Rotate buffers: current -> previous, new -> current (no allocation).
    std::mem::swap(&mut state.x_prev, &mut state.x);
    std::mem::swap(&mut state.v_prev, &mut state.v);
    std::mem::swap(&mut state.x, &mut ws.new_x);
    std::mem::swap(&mut state.v, &mut ws.new_v);
    state.has_history = true;
    state.last_dt_s = h;
    state.time_s += h;
    state.steps += 1;
    Ok(())
}
