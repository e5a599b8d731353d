//! Newton's method with a line search for the implicit step.
//!
//! Backward Euler and BDF2 both ask for the unknown `u` (BE: the velocity
//! change `dv`; BDF2: the displacement `dx`) that zeroes the residual
//! `r(u) = M (u - y0) - c_f f(x(u), v(u))`, with `x(u) = x_u + a u`,
//! `v(u) = v_u + b u` (BE: `y0 = 0`, `c_f = h`, `a = h`, `b = 1`; BDF2:
//! `y0 = delta/3 + h (8 v - 2 v_prev)/9`, `c_f = 4h^2/9`, `a = 1`,
//! `b = 3/(2h)`). The residual is the gradient of the incremental
//! potential (Martin et al. 2011, Gast et al. 2015)
//!
//! `E(u) = 1/2 (u - y0)^T M (u - y0) + (c_f / a) [U(x(u)) - (M g + f_ext).x(u)]
//!        + (c_f / b) 1/2 v(u)^T C v(u)`,
//!
//! with `U` the elastic energy of links and elements and `C = -df/dv` the
//! damping (link dampers, drag, friction of squeezed particles) frozen at the
//! current iterate. Each Newton correction solves `A p = -r` with the
//! step's positive definite matrix (compressed links' negative orthogonal
//! stiffness dropped), so `p` is a descent direction of `E`; a backtracking
//! line search (Armijo) takes the largest `alpha` in `1, 1/2, 1/4, ...`
//! that lowers `E` by at least `1e-4 alpha |r.p|`. That is what keeps a
//! large step from overshooting: a full step that stretches links far more
//! than it gains in gravity and inertia is cut back.
//!
//! Solids are part of the step equation as a stiff penalty energy: a
//! particle closer than the contact thickness `e` to a solid at `t + h`
//! stores `k/2 (e - g)^2` (gap `g` to the solid's tangent plane at the
//! closest point of the iterate, or of the start of the step when the
//! iterate is inside; `k` from [`contact_penalty_stiffness`]). The
//! single linearised step holds particles with Baraff-Witkin constraints
//! and an active set; inside Newton iterations that active set chatters:
//! measured on the sphere drape at `h = 0.2 s`, a particle added when an
//! iterate put it inside and released when the next one pulled, 500-1500
//! changes per step and no step converging in 30 corrections, the cloth
//! held at 15x stretch by constraints from the first solve, or sliding
//! off the ball. An energy has no active set: the line search sees it.
//! The contacts (and their normal forces, `k (e - g)`) are those of the
//! last iterate.
//!
//! Friction of the particles on solids is in the step equation too:
//! Coulomb's law smoothed below a slip of
//! [`crate::contacts::FRICTION_SMOOTHING_M_S`] as a dissipation potential
//! `(c_f / b) mu N F0(|w|)` (Li et al. 2020, IPC §5), its normal force `N`
//! frozen (Li et al.'s lagging): first the constraint forces of the
//! linearised solve, then, once the iterations converge with those, the
//! penalty forces of that iterate, checked again. Applied after the
//! solve instead, as at small steps, static friction at `h = 0.2 s` moves
//! a held particle back by the whole distance its free neighbours have
//! slid past it: links 5x their rest length after one step.
//!
//! Stopping rule: the residual as a distance, `max_i |S_i r_i| a / m_i`
//! over the free directions `S_i` (m): the distance particle `i` would
//! still move if its unbalanced force acted on it alone over the step.
//! Since the matrix is at least `M`, it bounds the remaining Newton
//! correction in the mass norm. The iterations stop when it falls below
//! [`crate::NewtonParams::tolerance_m`] or after
//! [`crate::NewtonParams::iterations`] linear solves.

use super::scheme::Linearised;
use super::solve::{constrain_pins, solve};
use super::workspace::{NewtonBuffers, StepInputs, SystemLoads, Workspace};
use crate::contacts::{
    SolidContact, contact_friction_potential, contact_penalty_energy, contact_penalty_stiffness,
    linearise_contact_friction, penalty_contacts, penalty_watch,
};
use crate::forces::{EnergyBuffers, damping_forms, elastic_energy};
use crate::integrate::timer::{Stage, StageTimer};
use crate::system::SystemTerms;
use crate::system::{SystemBuffers, assemble};
use crate::{ClothModel, ClothState, Mat3, SolverParams, StepError, StepReport, Vec3};
use cloth_linalg::Couplings;

/// Armijo's sufficient-decrease constant.
const ARMIJO: f64 = 1e-4;
/// Most halvings of the step length before the line search gives up.
const MAX_BACKTRACKS: usize = 30;

/// An empty slot of [`NewtonBuffers::lagged`].
const NO_CONTACT: (u32, f64) = (u32::MAX, 0.0);

impl NewtonBuffers {
    pub(crate) fn new(model: &ClothModel) -> Self {
        let n = model.particle_count();
        let zeros = vec![Vec3::zeros(); n];
        Self {
            energy: EnergyBuffers::new(model),
            u: zeros.clone(),
            x: zeros.clone(),
            v: zeros.clone(),
            y: zeros.clone(),
            trial: zeros.clone(),
            external: zeros,
            damping: vec![Mat3::zeros(); n],
            stiffness: vec![Mat3::zeros(); n],
            lagged: vec![[NO_CONTACT; 2]; n],
        }
    }
}

/// What the Newton iterations of one step did.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(crate) struct NewtonOutcome {
    /// Newton corrections taken after the first linearised solve.
    pub corrections: usize,
    /// Halvings of the step length over all corrections.
    pub backtracks: usize,
    /// The residual as a distance at the final iterate, m.
    pub residual_m: f64,
    /// Whether `residual_m` met the tolerance.
    pub converged: bool,
    /// PCG iterations of the corrections.
    pub cg_iterations: usize,
    /// Whether every correction's PCG converged.
    pub cg_converged: bool,
    /// Force and Jacobian evaluations (one per iterate checked).
    pub evaluations: usize,
    /// Elastic energy evaluations of the line search.
    pub energy_evaluations: usize,
}

/// Newton iterations from the unknown in `ws.s.unknown` (the first
/// linearised solve). On return `ws.s.unknown` holds the last accepted
/// iterate and `ws.s.system` the assembly there (its right-hand side is
/// `-r`). Pins keep the values of the first solve; solids act through
/// penalties (the filter's contact constraints are removed). The
/// assemblies' and solves' times go to `timer`.
pub(crate) fn iterate<S: Linearised>(
    step: StepInputs<'_, S>,
    ws: &mut Workspace<'_>,
    loads: &SystemLoads,
    timer: &mut StageTimer,
) -> Result<NewtonOutcome, StepError> {
    with_buffers(step.model, ws, |ws, nb| iterate_with(step, ws, loads, nb, timer))
}

/// Runs `f` with the workspace's Newton buffers (made on first use).
pub(super) fn with_buffers<T>(
    model: &ClothModel,
    ws: &mut Workspace<'_>,
    f: impl FnOnce(&mut Workspace<'_>, &mut NewtonBuffers) -> T,
) -> T {
    let mut nb = ws.s.newton.take().unwrap_or_else(|| NewtonBuffers::new(model));
    let result = f(ws, &mut nb);
    ws.s.newton = Some(nb);
    result
}

/// A linear solve's signature: the filtered solve, or a correction that
/// carries bodies (`solve::solve_correction`).
pub(super) type Solve = fn(&mut Workspace<'_>, &ClothState, &SolverParams) -> Result<(StepReport, f64), StepError>;

/// One Newton direction into `ws.s.unknown`, from zero, by `solve`: its
/// CG iterations and convergence go to `out`, its time to `timer`.
pub(super) fn solve_direction(
    ws: &mut Workspace<'_>,
    state: &ClothState,
    solver: &SolverParams,
    out: &mut NewtonOutcome,
    timer: &mut StageTimer,
    solve: Solve,
) -> Result<(), StepError> {
    ws.s.unknown.iter_mut().for_each(|p| *p = Vec3::zeros());
    let (r, s) = solve(ws, state, solver)?;
    timer.add(Stage::Solve, s);
    (out.cg_iterations, out.cg_converged) = (out.cg_iterations + r.cg_iterations, out.cg_converged & r.converged);
    out.corrections += 1;
    Ok(())
}

/// The iterate's loads that the step carries besides the links: the
/// step's external forces, self-collision stiffness and (with
/// `squeeze_friction`) squeezed particles' friction damping.
/// Self-collision acts as the linear spring of the step's start,
/// `f(x) = f_0 - K (x - x_0)` (`K` its diagonal blocks and couplings), as
/// in the linearised solve: held at `f_0` over the corrections, a contact
/// pushed with its full start force through the step and threw a sheet
/// that landed on another off it.
pub(super) fn copy_loads(
    ws: &Workspace<'_>,
    nb: &mut NewtonBuffers,
    loads: &SystemLoads,
    squeeze_friction: bool,
    x0: &[Vec3],
) {
    copy_or_zero(loads.external.then_some(&ws.s.external), &mut nb.external);
    copy_or_zero(squeeze_friction.then_some(&ws.contacts.friction_damping), &mut nb.damping);
    copy_or_zero(loads.self_collision.then_some(&ws.contacts.self_stiffness), &mut nb.stiffness);
    if loads.self_collision {
        for (i, f) in nb.external.iter_mut().enumerate() {
            *f -= ws.contacts.self_stiffness[i] * (nb.x[i] - x0[i]);
        }
        let couplings = &ws.contacts.self_couplings;
        couplings.add_off_diagonal(&nb.x, -1.0, &mut nb.external);
        couplings.add_off_diagonal(x0, 1.0, &mut nb.external);
    }
}

/// Assembles the system at the iterate in `nb` (its right-hand side is
/// `-r`), with the loads in `nb`; the times go to `timer`.
pub(super) fn assemble_iterate<S: Linearised>(
    step: StepInputs<'_, S>,
    ws: &mut Workspace<'_>,
    nb: &NewtonBuffers,
    timer: &mut StageTimer,
) {
    let StepInputs { scheme, model, state, h, .. } = step;
    let terms = SystemTerms {
        external: Some(&nb.external),
        diag_stiffness: Some(&nb.stiffness),
        diag_damping: Some(&nb.damping),
        ..scheme.newton_terms(h, &nb.v, &nb.y, &state.stitches_closed)
    };
    let t = assemble(model, &nb.x, &terms, &mut ws.s.system);
    timer.add(Stage::Forces, t.links_s);
    timer.add(Stage::Assembly, t.gather_s);
}

fn iterate_with<S: Linearised>(
    step: StepInputs<'_, S>,
    ws: &mut Workspace<'_>,
    loads: &SystemLoads,
    nb: &mut NewtonBuffers,
    timer: &mut StageTimer,
) -> Result<NewtonOutcome, StepError> {
    let StepInputs { scheme, model, state, control, h, solver } = step;
    let (c_f, a, b) = (scheme.force_coefficient(h), scheme.position_per_unknown(h), scheme.velocity_per_unknown(h));
    let mut out = NewtonOutcome { cg_converged: true, ..Default::default() };
    let colliders = !model.colliders().is_empty();
    if colliders {
        // Solids act through the penalty from here on: their constraints go,
        // and so does the squeezed particles' friction linearised at the
        // start of the step (a particle between two solids has two penalties).
        ws.s.filter.clear();
        for c in ws.contacts.solid.iter().filter(|c| c.pressed) {
            ws.s.external[c.particle as usize] -= c.solve_constant_n;
        }
    }
    let squeeze_friction = loads.squeeze_friction && !colliders;
    // Friction's normal forces: first those of the linearised solve's
    // constraints, then those of a converged iterate.
    lag_normal_forces(&ws.contacts.solid, &mut nb.lagged);
    let (mut refresh, mut fresh) = (false, false);
    nb.u.copy_from_slice(&ws.s.unknown);
    for solves in 1.. {
        advance_iterate(scheme, state, ws, h, nb);
        copy_loads(ws, nb, loads, squeeze_friction, &state.x);
        if colliders {
            penalty_contacts(model, &state.x, &nb.x, (state.time_s, h), ws.contacts);
            if refresh {
                lag_normal_forces(&ws.contacts.solid, &mut nb.lagged);
            }
            (fresh, refresh) = (refresh, false);
            let lagged = &nb.lagged;
            let normal = |c: &SolidContact| {
                lagged[c.particle as usize].iter().find(|(k, _)| *k == c.collider).map_or(0.0, |(_, n)| *n)
            };
            let loads = (&mut nb.external[..], &mut nb.stiffness[..], &mut nb.damping[..]);
            add_contact_loads(model, h, &mut ws.contacts.solid, &nb.v, normal, loads);
        }
        assemble_iterate(step, ws, nb, timer);
        out.evaluations += 1;
        constrain_pins(model, state, control, h, &mut ws.s.filter, |_, _| Vec3::zeros());
        out.residual_m = residual_distance(ws, a);
        out.converged = out.residual_m <= solver.newton.tolerance_m;
        if out.converged && colliders && !fresh {
            // Converged with friction bounded by older normal forces: take
            // this iterate's and check again. Updating them at every
            // iterate instead (a moving potential) kept the sphere drape at
            // 1/90 s from converging in 9 corrections.
            refresh = true;
            continue;
        }
        if out.converged || solves >= solver.newton.iterations {
            break;
        }
        solve_direction(ws, state, solver, &mut out, timer, solve)?;
        if colliders {
            penalty_watch(model, &nb.x, &ws.s.unknown, a, state.time_s + h, ws.contacts);
        }
        let extra = Extra {
            external: loads.external.then_some(&ws.s.external[..]),
            friction: squeeze_friction.then_some(&ws.contacts.friction_damping[..]),
            contacts: colliders.then_some((&ws.contacts.solid[..], &ws.contacts.watch[..])),
            self_contacts: loads.self_collision.then_some((
                &ws.contacts.self_stiffness[..],
                &ws.contacts.self_couplings,
                &state.x[..],
            )),
            h,
            stitches_closed: &state.stitches_closed,
        };
        let Some((alpha, backtracks, evaluations)) = line_search(model, ws, nb, (c_f, a, b), extra) else {
            // Not a descent direction (an unconverged PCG): keep the iterate.
            break;
        };
        (out.backtracks, out.energy_evaluations) = (out.backtracks + backtracks, out.energy_evaluations + evaluations);
        if alpha == 0.0 {
            break;
        }
        for (u, p) in nb.u.iter_mut().zip(&ws.s.unknown) {
            *u += p * alpha;
        }
    }
    ws.s.unknown.copy_from_slice(&nb.u);
    Ok(out)
}

/// Links per parallel task of [`worst_tension_error`].
const LINK_CHUNK: usize = 1024;

/// The worst error of the single linearised step's tension over its
/// result `ws.s.unknown` (its end positions left in `ws.out.x`), as a share
/// of `k_s L`
/// ([`tension_linearisation_error`] of every stretch link). Used by
/// [`crate::NewtonParams::trigger`] and [`crate::NewtonParams::auto_trigger`].
pub(crate) fn worst_tension_error<S: Linearised>(
    scheme: &S,
    model: &ClothModel,
    state: &ClothState,
    h: f64,
    ws: &mut Workspace<'_>,
) -> f64 {
    use rayon::prelude::*;
    for i in 0..state.len() {
        ws.out.x[i] = scheme.advance(state, &ws.s.aux, h, i, ws.s.unknown[i]).0;
    }
    let (x, new_x) = (&state.x, &ws.out.x);
    // Checked on every step when the run may engage Newton on its own
    // (`NewtonParams::auto_trigger`): in parallel, and the maximum does not
    // depend on the order.
    model
        .stretch_links()
        .par_chunks(LINK_CHUNK)
        .map(|links| {
            links
                .iter()
                .map(|l| {
                    let (i, j) = (l.i as usize, l.j as usize);
                    tension_linearisation_error(l, (x[i], x[j]), (new_x[i], new_x[j]))
                })
                .fold(0.0, f64::max)
        })
        .reduce(|| 0.0, f64::max)
}

/// The worst [`tension_linearisation_error`] of the single linearised
/// step over the stretch links with an end in contact with a solid: a
/// solid striking the cloth ([`crate::NewtonParams::auto_trigger`]). Only
/// those links are visited, through each contact particle's incidence;
/// a link with both ends in contact counts twice, which a maximum ignores.
pub(crate) fn worst_struck_tension_error<S: Linearised>(
    scheme: &S,
    (model, state): (&ClothModel, &ClothState),
    h: f64,
    ws: &Workspace<'_>,
) -> f64 {
    let links = model.stretch_links();
    let end = |i: usize| scheme.advance(state, &ws.s.aux, h, i, ws.s.unknown[i]).0;
    let mut worst = 0.0f64;
    for c in &ws.contacts.solid {
        for inc in model.incidence(c.particle as usize) {
            let Some(l) = links.get(inc.link as usize) else { continue };
            let (i, j) = (l.i as usize, l.j as usize);
            worst = worst.max(tension_linearisation_error(l, (state.x[i], state.x[j]), (end(i), end(j))));
        }
    }
    worst
}

/// How wrong a linear step's tension of link `l` is after its ends moved
/// from `start` to `end` (m), as a share of `k_s L` (dimensionless):
/// `|f(end) - (f(start) + K (dx_j - dx_i))| / (k_s L)` with `f` the link's
/// tension alone (`k_s (d - L) u` when stretched, else none) and `K` its
/// Jacobian at `start` (axial `k_s u u^T` plus the geometric
/// `(|f| / d)(I - u u^T)`). A link at rest kicked sideways by a third of
/// its length (no transverse stiffness in the linear model) is off by
/// `sqrt(1 + 1/9) - 1 = 5.4%`; under small motions a linear step's error is
/// second order. Buckling (below the rest length) is left out: Choi &
/// Ko's law is linearised for stability, not accuracy. The share does not
/// depend on `k_s`, so it is computed for a unit stiffness: a link of a
/// membrane model (`k_s = 0`, the triangles carry the stretch) measures
/// how far the step's linearisation is off along its edge.
pub(crate) fn tension_linearisation_error(l: &crate::StretchLink, start: (Vec3, Vec3), end: (Vec3, Vec3)) -> f64 {
    let tension = |p: Vec3| -> (Vec3, Mat3) {
        let d = p.norm();
        if d <= l.rest {
            return (Vec3::zeros(), Mat3::zeros());
        }
        let (u, stretch) = (p / d, d - l.rest);
        let uu = u * u.transpose();
        (u * stretch, uu + (Mat3::identity() - uu) * (stretch / d))
    };
    let (f0, k0) = tension(start.1 - start.0);
    let predicted = f0 + k0 * ((end.1 - start.1) - (end.0 - start.0));
    (tension(end.1 - end.0).0 - predicted).norm() / l.rest
}

/// Adds the solids' penalties (force `k (e - g) n`, N; stiffness
/// `k n n^T`, N/m) and their smoothed Coulomb friction linearised at the
/// velocities `v` (with normal forces `normal(contact)`, N) to an
/// iterate's external forces, diagonal stiffness and diagonal damping.
fn add_contact_loads(
    model: &ClothModel,
    h: f64,
    contacts: &mut [SolidContact],
    v: &[Vec3],
    normal: impl Fn(&SolidContact) -> f64,
    (external, stiffness, damping): (&mut [Vec3], &mut [Mat3], &mut [Mat3]),
) {
    let masses = model.masses();
    for c in contacts.iter() {
        let i = c.particle as usize;
        external[i] += c.normal * c.normal_force_n;
        stiffness[i] += c.normal * c.normal.transpose() * contact_penalty_stiffness(masses[i], h);
    }
    linearise_contact_friction(contacts, v, normal, damping, external);
}

/// Each particle's contacts' normal forces (N, >= 0), by solid, into `lagged`.
fn lag_normal_forces(contacts: &[SolidContact], lagged: &mut [[(u32, f64); 2]]) {
    lagged.iter_mut().for_each(|l| *l = [NO_CONTACT; 2]);
    for c in contacts.iter().filter(|c| c.active) {
        if let Some(slot) = lagged[c.particle as usize].iter_mut().find(|(k, _)| *k == u32::MAX) {
            *slot = (c.collider, c.normal_force_n.max(0.0));
        }
    }
}

/// `to <- from`, or zeros.
fn copy_or_zero<T: Copy + Default>(from: Option<&Vec<T>>, to: &mut [T]) {
    match from {
        Some(f) => to.copy_from_slice(f),
        None => to.iter_mut().for_each(|t| *t = T::default()),
    }
}

/// Positions, velocities and the mass term of the iterate `nb.u`.
pub(super) fn advance_iterate<S: Linearised>(
    scheme: &S,
    state: &ClothState,
    ws: &Workspace<'_>,
    h: f64,
    nb: &mut NewtonBuffers,
) {
    for i in 0..state.len() {
        (nb.x[i], nb.v[i]) = scheme.advance(state, &ws.s.aux, h, i, nb.u[i]);
        nb.y[i] = scheme.newton_mass_term(&ws.s.aux2, i, nb.u[i]);
    }
}

/// `max_i |A_ii^-1 S_i r_i| a` with `r = -rhs` of the assembly at the
/// iterate and `A_ii` the matrix's diagonal block, m.
pub(super) fn residual_distance(ws: &Workspace<'_>, a: f64) -> f64 {
    (0..ws.s.system.rhs.len())
        .map(|i| {
            let r =
                if ws.s.filter.is_free(i) { ws.s.system.rhs[i] } else { ws.s.filter.projector(i) * ws.s.system.rhs[i] };
            let d = ws.s.system.matrix.diag(i).try_inverse().map_or(f64::INFINITY, |inv| (inv * r).norm());
            if r == Vec3::zeros() { 0.0 } else { d * a }
        })
        .fold(0.0, f64::max)
}

/// The step's coefficients `(c_f, a, b)`: forces, `dx/du`, `dv/du`.
type Coefficients = (f64, f64, f64);

/// The incremental potential along a correction `p` from an iterate:
/// `E(alpha) - E(0) = alpha q1 + alpha^2 q2 + s (U(x + alpha a p) - U(x)) +
/// s (P(x + alpha a p) - P(x)) + (c_f / b) (D(v + alpha b p) - D(v))` with
/// `s = c_f / a`. Every term but the elastic energy `U`, the solids'
/// penalty `P` (each on its tangent plane of the iterate) and the
/// friction dissipation `D` is a quadratic in `alpha`, so a trial costs
/// one elastic energy evaluation and a pass over the contacts.
#[derive(Debug, Clone, Copy)]
struct Line<'a> {
    /// `dE/dalpha` at 0, `r.p` with `r = -rhs` of the assembly at the iterate.
    slope: f64,
    q1: f64,
    q2: f64,
    /// `c_f / a`.
    scale: f64,
    /// Elastic energy at the iterate, J.
    u0: f64,
    a: f64,
    b: f64,
    /// Contacts with solids and the solids a correction would reach (see
    /// `penalty_watch`), with the friction dissipation (W) and penalty
    /// energy (J) at the iterate.
    contacts: Option<(&'a [SolidContact], &'a [SolidContact], f64, f64)>,
    /// The step, s.
    h: f64,
    /// The stitches' states (see [`crate::ClothState::stitches_closed`]).
    stitches_closed: &'a [bool],
}

/// What acts on the particles besides links and elements, as in the
/// assembly: external forces (N), squeezed particles' friction damping
/// blocks (N s/m), and the contacts with solids (penalty and smoothed
/// Coulomb friction) at the step `h` (s).
#[derive(Debug, Clone, Copy)]
struct Extra<'a> {
    external: Option<&'a [Vec3]>,
    friction: Option<&'a [Mat3]>,
    /// The iterate's contacts and the watched solids (`penalty_watch`).
    contacts: Option<(&'a [SolidContact], &'a [SolidContact])>,
    /// Self-collision's stiffness, diagonal blocks (N/m) and couplings,
    /// about the step's start positions (m): its energy
    /// `-f_0.d + d^T K d / 2`, `d = x - x_0` (`f_0` is in `external`).
    self_contacts: Option<(&'a [Mat3], &'a Couplings, &'a [Vec3])>,
    h: f64,
    stitches_closed: &'a [bool],
}

impl<'a> Line<'a> {
    /// The line through the iterate `(x, v, y)` (`y = y0 - u`) along `p`;
    /// `system` is the assembly there (its right-hand side and elastic
    /// energy).
    fn new(
        model: &ClothModel,
        (x, v, y): (&[Vec3], &[Vec3], &[Vec3]),
        system: &SystemBuffers,
        p: &[Vec3],
        (c_f, a, b): Coefficients,
        extra: Extra<'a>,
    ) -> Self {
        let rhs = &system.rhs;
        let masses = model.masses();
        // p is zero in the constrained directions, so constrained rows add nothing.
        let slope: f64 = -(0..p.len()).map(|i| rhs[i].dot(&p[i])).sum::<f64>();
        let gravity = model.effects().gravity.unwrap_or_else(Vec3::zeros);
        let (mut q1, mut q2) = (0.0, 0.0);
        for i in 0..p.len() {
            let m = masses[i];
            let load = gravity * m + extra.external.map_or(Vec3::zeros(), |f| f[i]);
            // (u - y0).p = -y.p
            q1 += -m * y[i].dot(&p[i]) - c_f * load.dot(&p[i]);
            q2 += 0.5 * m * p[i].norm_squared();
            // Squeezed-particle friction: (c_f/b) 1/2 v^T C v.
            let cp = extra.friction.map_or(Vec3::zeros(), |c| c[i] * p[i]);
            q1 += c_f * v[i].dot(&cp);
            q2 += 0.5 * c_f * b * p[i].dot(&cp);
        }
        if let Some((diag, couplings, x0)) = extra.self_contacts {
            // Positions move by `a alpha p`: c_f (K d).p and c_f a p^T K p / 2.
            for i in 0..p.len() {
                let kp = diag[i] * p[i];
                q1 += c_f * kp.dot(&(x[i] - x0[i]));
                q2 += 0.5 * c_f * a * kp.dot(&p[i]);
            }
            q1 += c_f * (couplings.bilinear(p, x) - couplings.bilinear(p, x0));
            q2 += 0.5 * c_f * a * couplings.bilinear(p, p);
        }
        // Drag, link dampers and stitch dashpots, directions frozen at the iterate.
        let (vcp, pcp) = damping_forms(model, x, v, p, extra.stitches_closed);
        q1 += c_f * vcp;
        q2 += 0.5 * c_f * b * pcp;
        let contacts = extra.contacts.map(|(c, watch)| {
            let penalty = contact_penalty_energy(c, model, extra.h, x, p, 0.0)
                + contact_penalty_energy(watch, model, extra.h, x, p, 0.0);
            (c, watch, contact_friction_potential(c, v, p, 0.0), penalty)
        });
        let (u0, h, stitches_closed) = (system.elastic_energy(), extra.h, extra.stitches_closed);
        Self { slope, q1, q2, scale: c_f / a, u0, a, b, contacts, h, stitches_closed }
    }

    /// `E(alpha) - E(0)`, J (trial positions written to `trial`).
    #[allow(clippy::too_many_arguments)]
    fn change(
        &self,
        model: &ClothModel,
        (x, v): (&[Vec3], &[Vec3]),
        p: &[Vec3],
        alpha: f64,
        trial: &mut [Vec3],
        energy: &mut EnergyBuffers,
    ) -> f64 {
        for ((t, x), p) in trial.iter_mut().zip(x).zip(p) {
            *t = x + p * (alpha * self.a);
        }
        let elastic = elastic_energy(model, trial, self.stitches_closed, energy) - self.u0;
        let contacts = self.contacts.map_or(0.0, |(contacts, watch, d0, p0)| {
            let beta = alpha * self.a;
            let penalty = contact_penalty_energy(contacts, model, self.h, x, p, beta)
                + contact_penalty_energy(watch, model, self.h, x, p, beta)
                - p0;
            let dissipation = contact_friction_potential(contacts, v, p, alpha * self.b) - d0;
            self.scale * penalty + self.scale * self.a / self.b * dissipation
        });
        alpha * self.q1 + alpha * alpha * self.q2 + self.scale * elastic + contacts
    }
}

/// Backtracking along the correction `p = ws.s.unknown` from the iterate in
/// `nb`: returns `(alpha, halvings, energy evaluations)`, `alpha = 0` when
/// no length down to `2^-30` lowers the incremental potential enough, and
/// `None` when `p` is not a descent direction.
fn line_search(
    model: &ClothModel,
    ws: &Workspace<'_>,
    nb: &mut NewtonBuffers,
    coefficients: Coefficients,
    extra: Extra<'_>,
) -> Option<(f64, usize, usize)> {
    let p = &ws.s.unknown;
    let iterate = (&nb.x[..], &nb.v[..], &nb.y[..]);
    let line = Line::new(model, iterate, &ws.s.system, p, coefficients, extra);
    if line.slope.is_nan() || line.slope >= 0.0 {
        return None;
    }
    // Rounding of a sum of many link energies: below this, changes are noise.
    let noise = 1e-13 * line.scale * line.u0.abs();
    let mut alpha = 1.0;
    for halvings in 0..=MAX_BACKTRACKS {
        let change = line.change(model, (&nb.x, &nb.v), p, alpha, &mut nb.trial, &mut nb.energy);
        if change <= ARMIJO * alpha * line.slope + noise {
            return Some((alpha, halvings, halvings + 1));
        }
        alpha *= 0.5;
    }
    Some((0.0, MAX_BACKTRACKS, MAX_BACKTRACKS + 1))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::contacts::contact_penalty;
    use crate::{Effects, GridPanel, Material, ModelKind, ModelSpec};

    /// Deterministic numbers in [-1, 1).
    fn noise(seed: &mut u64) -> f64 {
        *seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (*seed >> 11) as f64 / (1u64 << 52) as f64 - 1.0
    }

    fn model(kind: ModelKind) -> ClothModel {
        ClothModel::build(&ModelSpec {
            kind,
            panels: vec![GridPanel {
                particles: [6, 5],
                size_m: [0.1, 0.08],
                origin_m: [0.0, 0.0, 0.5],
                u_axis: [1.0, 0.0, 0.0],
                v_axis: [0.0, 1.0, 0.0],
                wrap_u: false,
            }],
            material: Material { damping_n_s_m: 0.5, drag_n_s_m3: 0.3, ..Material::default() },
            effects: Effects {
                gravity: Some(Vec3::new(0.0, 0.0, -9.81)),
                damping: true,
                bending: true,
                drag: true,
                ..Effects::default()
            },
            ..ModelSpec::default()
        })
        .unwrap()
    }

    /// Contacts with solids at every third particle of `x`: random
    /// normals, gaps inside the thickness `e`, sliding (slip ~0.3 m/s) or,
    /// every other one, slipping slower than the friction smoothing.
    fn contacts(model: &ClothModel, x: &[Vec3], v: &[Vec3], h: f64, seed: &mut u64) -> Vec<SolidContact> {
        let e = model.contact_thickness();
        (0..x.len())
            .step_by(3)
            .map(|i| {
                let normal = Vec3::new(noise(seed), noise(seed), 1.5).normalize();
                let gap = e * (0.5 + 0.4 * noise(seed));
                let slow = (i / 3) % 2 == 1;
                let slip = Vec3::new(noise(seed), noise(seed), noise(seed)) * if slow { 3e-4 } else { 0.3 };
                let held = SolidContact::new(i, 0, x[i] - normal * gap, normal, v[i] - slip, 0.4);
                let normal_force_n = contact_penalty(gap, e, contact_penalty_stiffness(model.masses()[i], h)).1;
                SolidContact { distance_m: gap, normal_force_n, ..held }
            })
            .collect()
    }

    /// The line search's potential is the one whose gradient is the
    /// Newton residual: its derivative along `p` (central differences of
    /// `Line::change`) equals `r.p` from the assembled right-hand side, for
    /// every model, with link dampers, drag, external forces, friction
    /// blocks, and solids' penalties and smoothed friction (sliding and
    /// below the smoothing speed). Leaving out the external forces and
    /// friction blocks, or the contacts, from the line (a wrong potential)
    /// is caught.
    #[test]
    fn line_search_potential_has_the_residual_as_gradient() {
        for kind in [ModelKind::ChoiKo, ModelKind::Provot, ModelKind::Volino] {
            let model = model(kind);
            let n = model.particle_count();
            let mut seed = 7;
            let mut random = |s: f64| Vec3::new(noise(&mut seed), noise(&mut seed), noise(&mut seed)) * s;
            // Stretched by 5 % and jittered: links in tension and compression.
            let x: Vec<Vec3> = model.rest_positions().iter().map(|p| p * 1.05 + random(2e-3)).collect();
            let v: Vec<Vec3> = (0..n).map(|_| random(0.3)).collect();
            let y: Vec<Vec3> = (0..n).map(|_| random(1e-3)).collect();
            let p: Vec<Vec3> = (0..n).map(|_| random(1e-3)).collect();
            let external: Vec<Vec3> = (0..n).map(|_| random(1e-2)).collect();
            let friction: Vec<Mat3> = (0..n)
                .map(|_| {
                    let w = random(1.0);
                    w * w.transpose() * 1e-2
                })
                .collect();
            // BDF2 at h = 10 ms.
            let h = 0.01;
            let (c_f, a, b) = (4.0 * h * h / 9.0, 1.0, 1.5 / h);
            let mut solids = contacts(&model, &x, &v, h, &mut seed);
            let (mut loads, mut stiffness, mut damping) = (external.clone(), vec![Mat3::zeros(); n], friction.clone());
            // Friction bounded by normal forces other than the penalties'
            // (lagged), as in the iterations.
            let lagged = |c: &SolidContact| 1.3 * c.normal_force_n;
            add_contact_loads(&model, h, &mut solids, &v, lagged, (&mut loads, &mut stiffness, &mut damping));
            let terms = SystemTerms {
                d_times: Some((c_f, &v[..])),
                mass_times: Some(&y[..]),
                external: Some(&loads[..]),
                diag_stiffness: Some(&stiffness[..]),
                diag_damping: Some(&damping[..]),
                ..SystemTerms::new(c_f, 2.0 * h / 3.0, c_f, &[])
            };
            let mut system = SystemBuffers::new(&model);
            assemble(&model, &x, &terms, &mut system);
            let mut energy = EnergyBuffers::new(&model);
            let mut trial = vec![Vec3::zeros(); n];
            let derivative_error = |extra: Extra<'_>, energy: &mut EnergyBuffers, trial: &mut [Vec3]| {
                let line = Line::new(&model, (&x, &v, &y), &system, &p, (c_f, a, b), extra);
                // Small: the smoothed friction below 1 mm/s curves on the
                // scale of the smoothing speed (error 4.8e-6 at 1e-4, 2e-9 here).
                let eps = 1e-6;
                let plus = line.change(&model, (&x, &v), &p, eps, trial, energy);
                let minus = line.change(&model, (&x, &v), &p, -eps, trial, energy);
                ((plus - minus) / (2.0 * eps) - line.slope).abs() / line.slope.abs()
            };
            let full = Extra {
                external: Some(&external),
                friction: Some(&friction),
                contacts: Some((&solids, &[])),
                self_contacts: None,
                h,
                stitches_closed: &[],
            };
            let err = derivative_error(full, &mut energy, &mut trial);
            let no_loads = derivative_error(Extra { external: None, friction: None, ..full }, &mut energy, &mut trial);
            let no_contacts = derivative_error(Extra { contacts: None, ..full }, &mut energy, &mut trial);
            eprintln!(
                "{kind:?}: relative derivative error {err:.2e}, without external and friction {no_loads:.2e}, \
                 without contacts {no_contacts:.2e}"
            );
            assert!(err < 6e-9, "{kind:?}: line derivative off the residual by {err:e}");
            assert!(no_loads > 1e-3, "{kind:?}: the check is blind to missing loads ({no_loads:e})");
            assert!(no_contacts > 1e-3, "{kind:?}: the check is blind to missing contacts ({no_contacts:e})");
        }
    }

    /// The trigger's measure: a link at rest kicked sideways by a third of
    /// its length is off by `sqrt(1 + 1/9) - 1`; a stretched link carried
    /// without turning is exact; turned by `theta`, off by `1 - cos theta`
    /// (second order: a tenth of the turn, a hundredth of the error).
    #[test]
    fn tension_linearisation_error_is_the_linear_links_miss() {
        let link = crate::StretchLink {
            i: 0,
            j: 1,
            rest: 0.05,
            k_s: 200.0,
            compression: crate::Compression::Linear(0.0),
            k_d: 0.0,
        };
        let (a, b) = (Vec3::zeros(), Vec3::new(0.05, 0.0, 0.0));
        let kicked = tension_linearisation_error(&link, (a, b), (a, b + Vec3::new(0.0, 0.05 / 3.0, 0.0)));
        assert!((kicked - ((1.0f64 + 1.0 / 9.0).sqrt() - 1.0)).abs() < 1e-14, "{kicked}");
        let stretched = Vec3::new(0.06, 0.0, 0.0);
        let shift = Vec3::new(0.3, -0.2, 0.1);
        assert!(tension_linearisation_error(&link, (a, stretched), (a + shift, stretched + shift)) < 1e-14);
        let turned = |theta: f64| {
            let end = Vec3::new(theta.cos(), theta.sin(), 0.0) * 0.06;
            tension_linearisation_error(&link, (a, stretched), (a, end))
        };
        // Its tension (2 N) turns exactly; the linear axial stiffness takes
        // the chord's shortening `d (1 - cos theta)` for a slackening:
        // off by `k_s d (1 - cos theta) - f (1 - cos theta)`, over `k_s L`:
        // `1 - cos theta`.
        let (coarse, fine) = (turned(0.1), turned(0.01));
        assert!((coarse - (1.0 - 0.1f64.cos())).abs() < 1e-14, "{coarse}");
        assert!((coarse / fine / 100.0 - 1.0).abs() < 1e-3, "{coarse} / {fine}");
    }
}
