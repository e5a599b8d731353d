//! Explicit integrators: forward Euler, symplectic Euler, explicit midpoint,
//! classic RK4 and the embedded Dormand-Prince 5(4) pair with adaptive step
//! size (Volino & Magnenat-Thalmann 2001 compare midpoint and an embedded
//! fifth-order Runge-Kutta against implicit Euler).
//!
//! The state `y = (x, v)` obeys `x' = v`, `v' = M^-1 f(x, v)`. Pinned
//! particles are prescribed: at every stage and at the end of a step their
//! position and velocity are set from their path, so pins stay exact.

use super::state::IntegratorMemory;
use super::step::{Capabilities, Integrator, Step, StepOutput};
use super::timer::{Stage, StageTimer};
use crate::contacts::Contacts;
use crate::control::{Control, PinPaths};
use crate::{
    ClothModel, ClothState, SolverParams, StepError, StepReport, Vec3,
    forces::{EnergyBuffers, forces_into},
    terms::At,
    terms::ForceBuffers,
};
use cloth_linalg::ROW_CHUNK;
use rayon::prelude::*;

/// A Butcher tableau `(c, A, b)` with optional embedded error weights
/// `e = b - b_hat` (the difference to a lower-order solution).
#[derive(Debug)]
pub(crate) struct Tableau {
    pub c: &'static [f64],
    pub a: &'static [&'static [f64]],
    pub b: &'static [f64],
    pub e: Option<&'static [f64]>,
}

/// Forward (explicit) Euler, order 1.
pub(crate) const FORWARD_EULER: Tableau = Tableau { c: &[0.0], a: &[&[]], b: &[1.0], e: None };

/// Explicit midpoint, order 2, two force evaluations (Volino's "midpoint").
pub(crate) const MIDPOINT: Tableau = Tableau { c: &[0.0, 0.5], a: &[&[], &[0.5]], b: &[0.0, 1.0], e: None };

/// Classic fourth-order Runge-Kutta.
pub(crate) const RK4: Tableau = Tableau {
    c: &[0.0, 0.5, 0.5, 1.0],
    a: &[&[], &[0.5], &[0.0, 0.5], &[0.0, 0.0, 1.0]],
    b: &[1.0 / 6.0, 1.0 / 3.0, 1.0 / 3.0, 1.0 / 6.0],
    e: None,
};

/// Dormand & Prince (1980) 5(4): fifth-order solution with a fourth-order
/// embedded estimate; seven stages, the last at the new point.
pub(crate) const DOPRI5: Tableau = Tableau {
    c: &[0.0, 1.0 / 5.0, 3.0 / 10.0, 4.0 / 5.0, 8.0 / 9.0, 1.0, 1.0],
    a: &[
        &[],
        &[1.0 / 5.0],
        &[3.0 / 40.0, 9.0 / 40.0],
        &[44.0 / 45.0, -56.0 / 15.0, 32.0 / 9.0],
        &[19372.0 / 6561.0, -25360.0 / 2187.0, 64448.0 / 6561.0, -212.0 / 729.0],
        &[9017.0 / 3168.0, -355.0 / 33.0, 46732.0 / 5247.0, 49.0 / 176.0, -5103.0 / 18656.0],
        &[35.0 / 384.0, 0.0, 500.0 / 1113.0, 125.0 / 192.0, -2187.0 / 6784.0, 11.0 / 84.0],
    ],
    b: &[35.0 / 384.0, 0.0, 500.0 / 1113.0, 125.0 / 192.0, -2187.0 / 6784.0, 11.0 / 84.0, 0.0],
    e: Some(&[
        35.0 / 384.0 - 5179.0 / 57600.0,
        0.0,
        500.0 / 1113.0 - 7571.0 / 16695.0,
        125.0 / 192.0 - 393.0 / 640.0,
        -2187.0 / 6784.0 + 92097.0 / 339200.0,
        11.0 / 84.0 - 187.0 / 2100.0,
        -1.0 / 40.0,
    ]),
};

/// Scratch space of the explicit integrators.
#[derive(Debug, Clone)]
pub(crate) struct ExplicitBuffers {
    kx: Vec<Vec<Vec3>>,
    kv: Vec<Vec<Vec3>>,
    xs: Vec<Vec3>,
    vs: Vec<Vec3>,
    force: Vec<Vec3>,
    forces: ForceBuffers,
    /// Result of the last attempted step.
    pub(crate) x_new: Vec<Vec3>,
    pub(crate) v_new: Vec<Vec3>,
    /// Per pin, minus the step's quadrature of the other forces on its
    /// particle, N s: in the last attempt, and summed over accepted substeps.
    pin_impulse: Vec<Vec3>,
    pin_total: Vec<Vec3>,
    /// The wind's and the control's forces at the step's first stage, N
    /// (empty when there are none): their work goes to the energy window.
    external: Vec<Vec3>,
    /// The energy balance since the last report (see [`EnergyWindow`]).
    window: Option<EnergyWindow>,
    /// Scratch of the energy monitor.
    energy: EnergyBuffers,
}

impl ExplicitBuffers {
    /// Buffers for up to `stages` stages.
    pub(crate) fn new(model: &ClothModel, stages: usize) -> Self {
        let n = model.particle_count();
        let zeros = || vec![Vec3::zeros(); n];
        Self {
            kx: (0..stages).map(|_| zeros()).collect(),
            kv: (0..stages).map(|_| zeros()).collect(),
            xs: zeros(),
            vs: zeros(),
            force: zeros(),
            forces: ForceBuffers::new(model),
            x_new: zeros(),
            v_new: zeros(),
            pin_impulse: vec![Vec3::zeros(); model.pins().len()],
            pin_total: vec![Vec3::zeros(); model.pins().len()],
            external: Vec::new(),
            window: None,
            energy: EnergyBuffers::new(model),
        }
    }
}

/// Steps over which an explicit integrator's energy is balanced: the
/// elastic energy takes a pass over every link and element, about as much
/// as a force evaluation, so it is measured at the end of every
/// `ENERGY_WINDOW`-th step (`state.steps` a multiple of it), not after
/// each (symplectic Euler's step is one force evaluation: the flag fixture
/// at 0.2 ms spends 6% of its time on the monitor, 11% with windows of
/// 8). An unstable step multiplies the energy every step: on the hanging
/// cloth the first flagged window came 79-289 steps before the state
/// overflowed (`tests/large_steps.rs`).
pub const ENERGY_WINDOW: u64 = 16;

/// The energy balance of the explicit steps since the window began: the
/// mechanical energy at its start and the work done on the cloth since,
/// J. It goes on only from the state the last step left (`state.steps ==
/// next_steps`, and no snapshot restored since); anything else starts a
/// new one.
#[derive(Debug, Clone, Copy)]
struct EnergyWindow {
    next_steps: u64,
    before: (f64, f64, f64),
    pin_work: f64,
    external_work: f64,
    contact_work: f64,
}

/// Adds the wind's and the control's forces at `(x, v)` and time `t` to
/// `force` (N). With `external`, also leaves them alone there (resized;
/// emptied when there are none), taken as the difference they made to
/// `force`, so `force` keeps its bits.
fn add_external_forces(
    model: &ClothModel,
    control: &Control,
    (x, v, stitches_closed): (&[Vec3], &[Vec3], &[bool]),
    t: f64,
    (scratch, force): (&mut ForceBuffers, &mut [Vec3]),
    mut external: Option<&mut Vec<Vec3>>,
) {
    let present = super::loads::has_external_forces(model, control);
    if let Some(e) = external.as_deref_mut() {
        // Without any, an empty list (not last step's forces).
        e.clear();
        if present {
            e.extend_from_slice(force);
        }
    }
    let external = external.filter(|_| present);
    let at = At::new(model, x, v, stitches_closed).with_wind_at(t, control.wind(), control.wind_scale());
    crate::terms::add_external_forces(&at, scratch, force);
    control.add_forces_to(force);
    if let Some(e) = external {
        e.iter_mut().zip(force.iter()).for_each(|(e, f)| *e = f - *e);
    }
}

/// Sets pinned and held particles to their path at time `t`.
fn impose_pins(paths: &PinPaths<'_>, t: f64, x: &mut [Vec3], v: &mut [Vec3]) {
    for k in 0..paths.count() {
        let i = paths.particle(k);
        (x[i], v[i]) = (paths.position(k, t), paths.velocity(k, t));
    }
}

/// `out = base + h sum_j coef_j k_j`, parallel per particle.
fn combine(base: &[Vec3], h: f64, coef: &[f64], k: &[Vec<Vec3>], out: &mut [Vec3]) {
    out.par_chunks_mut(ROW_CHUNK).enumerate().for_each(|(chunk, o)| {
        for (m, oi) in o.iter_mut().enumerate() {
            let i = chunk * ROW_CHUNK + m;
            let mut acc = Vec3::zeros();
            for (c, kj) in coef.iter().zip(k) {
                if *c != 0.0 {
                    acc += kj[i] * *c;
                }
            }
            *oi = base[i] + acc * h;
        }
    });
}

/// Where a step starts: positions, velocities, time.
#[derive(Clone, Copy)]
pub(crate) struct Start<'a> {
    pub x: &'a [Vec3],
    pub v: &'a [Vec3],
    pub t: f64,
    /// The stitches' states (see [`crate::ClothState::stitches_closed`]).
    pub stitches_closed: &'a [bool],
    /// Pin paths and external forces of the step.
    pub pins: PinPaths<'a>,
    pub control: &'a Control,
}

/// One Runge-Kutta step of size `h` from `start` into `bufs.x_new`,
/// `bufs.v_new`. Returns the force evaluations used and, for an embedded
/// pair, the scaled RMS error estimate (<= 1 is acceptable at `tolerance`).
pub(crate) fn rk_step(
    model: &ClothModel,
    tab: &Tableau,
    start: Start<'_>,
    h: f64,
    tolerance: f64,
    bufs: &mut ExplicitBuffers,
    timer: &mut StageTimer,
) -> (usize, f64) {
    let Start { x, v, t, stitches_closed, pins, control } = start;
    let masses = model.masses();
    bufs.pin_impulse.iter_mut().for_each(|p| *p = Vec3::zeros());
    for s in 0..tab.c.len() {
        let lap = timer.start();
        let (ts, coef) = (t + tab.c[s] * h, tab.a[s]);
        combine(x, h, coef, &bufs.kx, &mut bufs.xs);
        combine(v, h, coef, &bufs.kv, &mut bufs.vs);
        impose_pins(&pins, ts, &mut bufs.xs, &mut bufs.vs);
        timer.stop(lap, Stage::Update);
        let lap = timer.start();
        forces_into(model, &bufs.xs, &bufs.vs, stitches_closed, &mut bufs.forces, &mut bufs.force);
        let external = (s == 0).then_some(&mut bufs.external);
        let state = (&bufs.xs[..], &bufs.vs[..], stitches_closed);
        add_external_forces(model, control, state, ts, (&mut bufs.forces, &mut bufs.force), external);
        timer.stop(lap, Stage::Forces);
        let (kx, kv) = (&mut bufs.kx[s], &mut bufs.kv[s]);
        kx.copy_from_slice(&bufs.vs);
        kv.iter_mut().zip(&bufs.force).zip(masses).for_each(|((a, f), m)| *a = f / *m);
        // The force the pins must cancel, quadrature-weighted like the step.
        for (i, applied) in pins.particles().zip(&mut bufs.pin_impulse) {
            *applied -= bufs.force[i] * (h * tab.b[s]);
            kv[i] = Vec3::zeros();
        }
    }
    let lap = timer.start();
    combine(x, h, tab.b, &bufs.kx, &mut bufs.x_new);
    combine(v, h, tab.b, &bufs.kv, &mut bufs.v_new);
    impose_pins(&pins, t + h, &mut bufs.x_new, &mut bufs.v_new);
    let error = tab.e.map_or(0.0, |e| {
        // RMS over all components of e / (tol + tol |y|), Hairer-style; pins carry no error.
        let mut sum = 0.0;
        for i in 0..x.len() {
            if model.is_pinned(i) {
                continue;
            }
            let (mut ex, mut ev) = (Vec3::zeros(), Vec3::zeros());
            for (c, (kx, kv)) in e.iter().zip(bufs.kx.iter().zip(&bufs.kv)) {
                ex += kx[i] * (h * c);
                ev += kv[i] * (h * c);
            }
            for d in 0..3 {
                let sx = tolerance * (1.0 + x[i][d].abs().max(bufs.x_new[i][d].abs()));
                let sv = tolerance * (1.0 + v[i][d].abs().max(bufs.v_new[i][d].abs()));
                sum += (ex[d] / sx).powi(2) + (ev[d] / sv).powi(2);
            }
        }
        (sum / (6 * x.len()).max(1) as f64).sqrt()
    });
    timer.stop(lap, Stage::Update);
    (tab.c.len(), error)
}

/// Symplectic (semi-implicit) Euler: `v' = v + h M^-1 f(x, v)`, `x' = x + h v'`.
pub(crate) fn symplectic_euler_step(
    model: &ClothModel,
    start: Start<'_>,
    h: f64,
    bufs: &mut ExplicitBuffers,
    timer: &mut StageTimer,
) {
    let Start { x, v, t, stitches_closed, pins, control } = start;
    let lap = timer.start();
    forces_into(model, x, v, stitches_closed, &mut bufs.forces, &mut bufs.force);
    let external = Some(&mut bufs.external);
    add_external_forces(model, control, (x, v, stitches_closed), t, (&mut bufs.forces, &mut bufs.force), external);
    timer.stop(lap, Stage::Forces);
    let lap = timer.start();
    let masses = model.masses();
    for i in 0..x.len() {
        bufs.v_new[i] = v[i] + bufs.force[i] * (h / masses[i]);
        bufs.x_new[i] = x[i] + bufs.v_new[i] * h;
    }
    for (i, applied) in pins.particles().zip(&mut bufs.pin_impulse) {
        *applied = -bufs.force[i] * h;
    }
    impose_pins(&pins, t + h, &mut bufs.x_new, &mut bufs.v_new);
    timer.stop(lap, Stage::Update);
}

/// Advances `state` by `h_total` with adaptive Dormand-Prince substeps,
/// starting from `next_dt_s`, the step size the last step suggested (0:
/// none). The accepted result is left in `bufs.x_new`, `bufs.v_new` (the
/// substeps work in `x_work`, `v_work`); returns the report and the next
/// suggested step size.
#[allow(clippy::too_many_arguments)]
pub(crate) fn adaptive_dopri5(
    model: &ClothModel,
    state: &ClothState,
    control: &Control,
    (h_total, next_dt_s): (f64, f64),
    solver: &SolverParams,
    bufs: &mut ExplicitBuffers,
    (x_work, v_work): (&mut Vec<Vec3>, &mut Vec<Vec3>),
    timer: &mut StageTimer,
) -> Result<(StepReport, f64), StepError> {
    let (tolerance, max_substeps) = (solver.adaptive.error_tolerance, solver.adaptive.max_substeps);
    let mut report = StepReport { converged: true, ..Default::default() };
    let pins = PinPaths::new(model, control, &state.x, state.time_s, h_total);
    bufs.pin_total.iter_mut().for_each(|p| *p = Vec3::zeros());
    x_work.copy_from_slice(&state.x);
    v_work.copy_from_slice(&state.v);
    let mut done = 0.0;
    let mut h = if next_dt_s > 0.0 { next_dt_s.min(h_total) } else { h_total };
    let mut suggestion = h;
    while done < h_total {
        let remaining = h_total - done;
        let last = h >= remaining * (1.0 - 1e-12);
        let h_try = if last { remaining } else { h };
        let closed = &state.stitches_closed;
        let start = Start { x: x_work, v: v_work, t: state.time_s + done, stitches_closed: closed, pins, control };
        let (evals, err) = rk_step(model, &DOPRI5, start, h_try, tolerance, bufs, timer);
        report.force_evaluations += evals;
        // Step-size controller (order 5 error estimate of the order-4 solution).
        let factor = if err == 0.0 {
            5.0
        } else if err.is_finite() {
            (0.9 * err.powf(-0.2)).clamp(0.2, 5.0)
        } else {
            0.2
        };
        if err <= 1.0 {
            std::mem::swap(x_work, &mut bufs.x_new);
            std::mem::swap(v_work, &mut bufs.v_new);
            done = if last { h_total } else { done + h_try };
            report.substeps += 1;
            bufs.pin_total.iter_mut().zip(&bufs.pin_impulse).for_each(|(t, p)| *t += p);
            // A last step shortened to land on h_total says little about
            // the step size the dynamics allow: keep the larger proposal.
            suggestion = if last { (h_try * factor).max(h) } else { h_try * factor };
            h = suggestion;
        } else {
            report.rejected_steps += 1;
            h = h_try * factor;
        }
        if report.substeps + report.rejected_steps > max_substeps || h < 1e-14 * h_total {
            return Err(StepError::StepSizeUnderflow {
                step: state.steps + 1,
                time_s: state.time_s + done,
                h,
                attempts: report.substeps + report.rejected_steps,
            });
        }
    }
    std::mem::swap(x_work, &mut bufs.x_new);
    std::mem::swap(v_work, &mut bufs.v_new);
    Ok((report, suggestion))
}

/// An explicit method.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Method {
    ForwardEuler,
    SymplecticEuler,
    Midpoint,
    Rk4,
    Dopri5,
}

impl Method {
    /// Its name in scene files.
    pub(crate) const fn name(self) -> &'static str {
        match self {
            Method::ForwardEuler => "forward-euler",
            Method::SymplecticEuler => "symplectic-euler",
            Method::Midpoint => "midpoint",
            Method::Rk4 => "rk4",
            Method::Dopri5 => "dopri5",
        }
    }
}

/// The explicit integrators behind [`crate::Integrator`]: forward and
/// symplectic Euler, midpoint, RK4 and the adaptive DOPRI5, by method.
#[derive(Debug)]
pub(crate) struct Explicit {
    method: Method,
    buffers: Option<Box<ExplicitBuffers>>,
    /// The adaptive integrator's suggested substep, s (0: none yet): its
    /// memory.
    next_dt_s: f64,
    /// The suggestion of the step being taken, kept once it commits.
    proposed_dt_s: f64,
}

impl Explicit {
    /// The explicit integrator of `method`.
    pub(crate) fn new(method: Method) -> Self {
        Self { method, buffers: None, next_dt_s: 0.0, proposed_dt_s: 0.0 }
    }
}

/// The memory's one entry (DOPRI5's): the substep the last step suggested, s.
const NEXT_DT: &str = "next_dt_s";

impl Integrator for Explicit {
    fn name(&self) -> &'static str {
        self.method.name()
    }

    fn capabilities(&self) -> Capabilities {
        Capabilities::default()
    }

    fn solve(
        &mut self,
        step: &Step<'_>,
        _contacts: &mut Contacts,
        out: &mut StepOutput,
        timer: &mut StageTimer,
    ) -> Result<StepReport, StepError> {
        use Method as K;
        let Step { model, state, control, h, solver, .. } = *step;
        let limit_s = model.explicit_stitch_step_limit();
        if self.method != K::Dopri5 && h >= limit_s {
            return Err(StepError::StitchesNeedSmallerStep { integrator: self.method.name(), h_s: h, limit_s });
        }
        let mut report = StepReport { converged: true, substeps: 1, ..Default::default() };
        let mut next_dt = 0.0;
        let pins = PinPaths::new(model, control, &state.x, state.time_s, h);
        let bufs = self.buffers.get_or_insert_with(|| Box::new(ExplicitBuffers::new(model, DOPRI5.c.len())));
        bufs.pin_impulse.resize(pins.count(), Vec3::zeros());
        bufs.pin_total.resize(pins.count(), Vec3::zeros());
        let closed = &state.stitches_closed;
        let start = Start { x: &state.x, v: &state.v, t: state.time_s, stitches_closed: closed, pins, control };
        match self.method {
            K::SymplecticEuler => {
                symplectic_euler_step(model, start, h, bufs, timer);
                report.force_evaluations = 1;
            }
            K::ForwardEuler | K::Midpoint | K::Rk4 => {
                let tab = match self.method {
                    K::ForwardEuler => &FORWARD_EULER,
                    K::Midpoint => &MIDPOINT,
                    _ => &RK4,
                };
                let (evals, _) = rk_step(model, tab, start, h, 0.0, bufs, timer);
                report.force_evaluations = evals;
            }
            K::Dopri5 => {
                let work = (&mut out.x, &mut out.v);
                (report, next_dt) =
                    adaptive_dopri5(model, state, control, (h, self.next_dt_s), solver, bufs, work, timer)?
            }
        }
        self.proposed_dt_s = next_dt;
        if self.method != K::Dopri5 {
            std::mem::swap(&mut bufs.pin_total, &mut bufs.pin_impulse);
        }
        // What the pin gave its particle: its momentum change less the
        // other forces' impulse, as a mean force over the step.
        let masses = model.masses();
        let forces = out.pin_forces_mut(pins.count());
        for ((i, f), other) in pins.particles().zip(forces).zip(&bufs.pin_total) {
            *f = ((bufs.v_new[i] - state.v[i]) * masses[i] + other) / h;
        }
        std::mem::swap(&mut out.x, &mut bufs.x_new);
        std::mem::swap(&mut out.v, &mut bufs.v_new);
        Ok(report)
    }

    fn balance(&mut self, step: &Step<'_>, contacts: &Contacts, out: &StepOutput) -> Option<crate::EnergyReport> {
        let bufs = self.buffers.as_mut().expect("allocated by the step");
        balance_window(step, contacts, out, bufs)
    }

    fn committed(&mut self, _: &StepReport) {
        self.next_dt_s = self.proposed_dt_s;
    }

    fn memory(&self) -> IntegratorMemory {
        match self.method {
            Method::Dopri5 => IntegratorMemory::new(vec![(NEXT_DT, self.next_dt_s)]),
            _ => IntegratorMemory::default(),
        }
    }

    /// Also ends the energy window: the next step starts a new one from
    /// its own state (a restored snapshot may hold the step count the
    /// window expects and another state).
    fn restore_memory(&mut self, memory: &IntegratorMemory) -> Result<(), StepError> {
        self.memory().same_names(memory)?;
        self.next_dt_s = memory.get(NEXT_DT).unwrap_or(0.0);
        if let Some(bufs) = self.buffers.as_mut() {
            bufs.window = None;
        }
        Ok(())
    }

    fn reset(&mut self) {
        self.buffers = None;
    }
}

/// Adds the step from `step.state` to `out` to the energy window and, at the end of every [`ENERGY_WINDOW`]-th step, returns the
/// window's balance ([`crate::energy`]) and starts the next one. The works
/// are those the implicit steps report: the pins' mean forces, the
/// contacts' impulses against the solids' velocities, and the wind's and
/// the control's forces at the step's start (the first stage's, a
/// one-point quadrature) over its displacement. The dampers' dissipation
/// is not measured (`dissipated_j` 0): the gain is the growth. Each
/// report's elastic energy is one pass over the links and elements; a
/// window that starts anew takes one more.
fn balance_window(
    step: &Step<'_>,
    contacts: &Contacts,
    out: &StepOutput,
    bufs: &mut ExplicitBuffers,
) -> Option<crate::EnergyReport> {
    let Step { model, state, control, h, .. } = *step;
    let pins = PinPaths::new(model, control, &state.x, state.time_s, h);
    let (new_x, new_v, pin_forces) = (&out.x, &out.v, &out.pin_forces);
    let energy = &mut bufs.energy;
    let closed = &state.stitches_closed;
    let window = match bufs.window.filter(|w| w.next_steps == state.steps) {
        Some(w) => w,
        None => EnergyWindow {
            next_steps: state.steps,
            before: crate::energy::mechanical(model, &state.x, &state.v, closed, energy),
            pin_work: 0.0,
            external_work: 0.0,
            contact_work: 0.0,
        },
    };
    let external = (!bufs.external.is_empty()).then_some(&bufs.external[..]);
    let moved = (&state.x[..], &new_x[..]);
    let (pin_work, external_work, contact_work) =
        crate::energy::works(moved, (pins, &pin_forces[..]), external, &contacts.solid);
    let window = EnergyWindow {
        next_steps: state.steps + 1,
        pin_work: window.pin_work + pin_work,
        external_work: window.external_work + external_work,
        contact_work: window.contact_work + contact_work,
        ..window
    };
    if !(state.steps + 1).is_multiple_of(ENERGY_WINDOW) {
        bufs.window = Some(window);
        return None;
    }
    let after = crate::energy::mechanical(model, new_x, new_v, closed, energy);
    let works = (window.pin_work, window.external_work, window.contact_work);
    bufs.window = Some(EnergyWindow { before: after, pin_work: 0.0, external_work: 0.0, contact_work: 0.0, ..window });
    Some(crate::energy::balance(window.before, after, works, 0.0))
}
