//! Vertex Block Descent (Chen, Macklin et al., SIGGRAPH 2024): backward
//! Euler's incremental potential
//! `G(x) = sum_i m_i / (2 h^2) |x_i - y_i|^2 + E(x) + contacts`,
//! `y = x_n + h v_n`, minimised by Gauss-Seidel sweeps of per-particle
//! 3x3 Newton steps `dx_i = H_i^-1 f_i`, colour by colour
//! ([`crate::colouring::Colouring`]: the particles of one colour share no
//! link or element, so their steps run in parallel and give the same bits
//! with any number of threads), with Chebyshev's semi-iterative
//! acceleration over the sweeps.
//!
//! The forces and blocks are the [`crate::terms`]' (the same laws as the
//! implicit steps, so a material means the same cloth); damping enters
//! through the velocity `v = (x - x_n) / h` the iterate implies (its
//! block over `h` in `H_i`). Wind and the control's forces are taken at the
//! step's start, as the implicit steps take them. Solids and
//! self-collision pairs are energies of the particles they touch, with
//! lagged, smoothed Coulomb friction (IPC), and per-particle bounds on each
//! local step keep particles out of solids (its `contact` module).

pub(crate) mod self_pairs;
#[cfg(test)]
pub(crate) mod tests;

use super::step::{Capabilities, ContactHandling, Integrator, Step, StepOutput};
use super::timer::{Stage, StageTimer};
use crate::colouring::Colouring;
use crate::contacts::{
    Contacts, FRICTION_SMOOTHING_M_S, Surroundings, contact_penalty, contact_penalty_stiffness, lag_normal_forces,
    plane_force, share_to_bound,
};
use crate::control::PinPaths;
use crate::terms::{At, acting};
use crate::{ClothModel, Mat3, StepError, StepReport, Vec3};
use rayon::prelude::*;
use self_pairs::{PairIndex, SelfPair};

/// Chebyshev's weight `omega_k` of sweep `k` (1-based) from the previous
/// one (Wang 2015, as VBD uses it): 1, then `2 / (2 - rho^2)`, then
/// `4 / (4 - rho^2 omega_{k-1})`.
pub(crate) fn chebyshev_omega(k: usize, rho: f64, previous: f64) -> f64 {
    match k {
        0 | 1 => 1.0,
        2 => 2.0 / (2.0 - rho * rho),
        _ => 4.0 / (4.0 - rho * rho * previous),
    }
}

/// Vertex Block Descent (`vbd`).
#[derive(Debug, Default)]
pub struct Vbd {
    buffers: Option<Box<VbdBuffers>>,
}

/// Buffers of the vertex solver, allocated on first use.
#[derive(Debug, Clone)]
pub(crate) struct VbdBuffers {
    colouring: Colouring,
    /// The displacement inertia alone would make, `h v_n`, m.
    inertial: Vec<Vec3>,
    /// The iterate's displacement over the step, m: the unknown. Kept
    /// apart from the positions so that the velocity `d / h` keeps its
    /// digits when the step is far below a position's rounding (h = 1e-9
    /// s moves a particle 1e-17 m, below the last bit of a position of 1 m).
    d: Vec<Vec3>,
    /// The iterate's positions `x_n + d`, m, and velocities `d / h`, m/s.
    x: Vec<Vec3>,
    v: Vec<Vec3>,
    /// The displacements one and two sweeps back (Chebyshev).
    previous: Vec<Vec3>,
    before_previous: Vec<Vec3>,
    /// Prescribed this step (pins, held particles).
    fixed: Vec<bool>,
    /// One colour's local steps: displacement, and whether its bound cut it.
    moves: Vec<(Vec3, bool)>,
    /// Particles whose bound cut their step in this sweep.
    cut: Vec<bool>,
    pairs: Vec<SelfPair>,
    index: PairIndex,
}

impl VbdBuffers {
    fn new(model: &ClothModel) -> Self {
        let n = model.particle_count();
        let zeros = vec![Vec3::zeros(); n];
        Self {
            colouring: Colouring::of(model),
            inertial: zeros.clone(),
            d: zeros.clone(),
            x: zeros.clone(),
            v: zeros.clone(),
            previous: zeros.clone(),
            before_previous: zeros,
            fixed: vec![false; n],
            moves: Vec::with_capacity(n),
            cut: vec![false; n],
            pairs: Vec::new(),
            index: PairIndex::default(),
        }
    }
}

/// What every local step of one step reads besides the iterate.
#[derive(Clone, Copy)]
struct Common<'a> {
    model: &'a ClothModel,
    stitches_closed: &'a [bool],
    external: Option<&'a [Vec3]>,
    h: f64,
    thickness: f64,
    self_thickness: f64,
}

/// Particle `i`'s loads at the iterate, besides inertia.
struct Loads {
    /// Force, N.
    force: Vec3,
    /// `-df/dx` with the dampers' `-df/dv / h`, N/m.
    stiffness: Mat3,
    /// The part of `force` a local step counts constant: dissipative
    /// forces, loads without a potential, friction (lagged), N.
    constant: Vec3,
    /// The energy of the terms and contacts with a potential, J.
    energy: f64,
}

/// Halvings of a local step before it is dropped for the sweep.
const MAX_HALVINGS: usize = 8;

/// Everything a local step reads: the iterate and the step's fixed data.
struct Local<'a> {
    common: Common<'a>,
    x: &'a [Vec3],
    v: &'a [Vec3],
    d: &'a [Vec3],
    inertial: &'a [Vec3],
    around: &'a [Surroundings],
    pairs: &'a [SelfPair],
    index: &'a PairIndex,
}

impl<'a> Local<'a> {
    /// The local steps at the buffers' iterate, with the solids `around`
    /// each particle.
    fn at(common: Common<'a>, b: &'a VbdBuffers, around: &'a [Surroundings]) -> Self {
        let (x, v, d, inertial) = (&b.x[..], &b.v[..], &b.d[..], &b.inertial[..]);
        Self { common, x, v, d, inertial, around, pairs: &b.pairs, index: &b.index }
    }

    /// Particle `i`'s loads from everything but inertia at the iterate
    /// (the energies only `with_energy`).
    fn loads(&self, i: usize, with_energy: bool) -> Loads {
        let Common { model, stitches_closed, external, h, thickness, self_thickness } = self.common;
        let at = At::new(model, self.x, self.v, stitches_closed);
        let mut l = Loads { force: Vec3::zeros(), stiffness: Mat3::zeros(), constant: Vec3::zeros(), energy: 0.0 };
        for term in acting(model) {
            let (b, energy) = if with_energy { term.vertex_with_energy(&at, i) } else { (term.vertex(&at, i), None) };
            l.force += b.force;
            l.stiffness += b.stiffness + b.damping / h;
            if with_energy {
                match energy {
                    Some(e) => l.energy += e,
                    None => l.constant += b.force - b.dissipative,
                }
            }
            l.constant += b.dissipative;
        }
        if let Some(e) = external {
            l.force += e[i];
            l.constant += e[i];
        }
        let penalty = contact_penalty_stiffness(model.masses()[i], h);
        for plane in self.around[i].planes.iter().flatten() {
            let (pf, pk) = plane_force(plane, &self.x[i], &self.v[i], penalty, thickness, h, FRICTION_SMOOTHING_M_S);
            let (energy, push) = contact_penalty(plane.gap(&self.x[i]), thickness, penalty);
            l.force += pf;
            l.stiffness += pk;
            l.energy += energy;
            // Friction counts as constant over a local step (lagged).
            l.constant += pf - plane.normal * push;
        }
        for &(pair, slot) in self.index.of(i) {
            let p = &self.pairs[pair as usize];
            let (pf, pk) = p.force_on(slot as usize, self.x, self_thickness);
            l.force += pf;
            l.stiffness += pk;
            l.energy += contact_penalty(p.gap(self.x), self_thickness, p.stiffness_n_m).0;
        }
        l
    }

    /// The local potential of particle `i` moved by `dx` from the iterate
    /// (J, up to a constant): inertia, the energies of the terms with one
    /// and of the contacts, and the work of the loads counted constant
    /// (`constant`, N).
    fn merit(&self, i: usize, dx: Vec3, constant: &Vec3) -> f64 {
        let Common { model, stitches_closed, h, thickness, self_thickness, .. } = self.common;
        let at = At::new(model, self.x, self.v, stitches_closed);
        let xi = self.x[i] + dx;
        let inertia = model.masses()[i] / (2.0 * h * h) * (self.d[i] + dx - self.inertial[i]).norm_squared();
        let terms: f64 = acting(model).filter_map(|t| t.vertex_energy(&at, i, xi)).sum();
        let penalty = contact_penalty_stiffness(model.masses()[i], h);
        let planes: f64 =
            self.around[i].planes.iter().flatten().map(|p| contact_penalty(p.gap(&xi), thickness, penalty).0).sum();
        let pairs: f64 = self
            .index
            .of(i)
            .iter()
            .map(|&(pair, slot)| {
                let p = &self.pairs[pair as usize];
                let gap = p.gap(self.x) + p.coefficients[slot as usize] * p.direction.dot(&(xi - self.x[i]));
                contact_penalty(gap, self_thickness, p.stiffness_n_m).0
            })
            .sum();
        inertia + terms + planes + pairs - constant.dot(&xi)
    }

    /// The local Newton step of particle `i` (m), cut to its bounds and,
    /// with `line_search`, halved until the local potential falls (a
    /// Hessian made positive semidefinite, or a law concave in
    /// compression, can overshoot); whether the ball cut it.
    fn step(&self, i: usize, line_search: bool) -> (Vec3, bool) {
        let h = self.common.h;
        let inertia = self.common.model.masses()[i] / (h * h);
        let l = self.loads(i, line_search);
        let force = l.force - (self.d[i] - self.inertial[i]) * inertia;
        let hessian = l.stiffness + Mat3::identity() * inertia;
        let dx = match hessian.cholesky() {
            Some(c) => c.solve(&force),
            // Indefinite: a gradient step, short enough for the stiffest axis.
            None => force / (inertia + l.stiffness.diagonal().abs().max()),
        };
        let (mut dx, cut) = self.bounded(i, dx);
        if line_search {
            let work = l.constant.dot(&self.x[i]);
            let start = inertia / 2.0 * (self.d[i] - self.inertial[i]).norm_squared() + l.energy - work;
            // Changes below the rounding of the potential's parts count as
            // none, and a step whose predicted decrease (`f . dx / 2`) is
            // below it is taken unchecked: the check would compare noise
            // (at h = 1e-9 s it stopped a falling particle).
            let rounding = 1e-13 * (start.abs() + l.energy.abs() + work.abs());
            if 0.5 * force.dot(&dx) <= rounding {
                return (dx, cut);
            }
            let mut halvings = 0;
            while self.merit(i, dx, &l.constant) > start + rounding {
                if halvings == MAX_HALVINGS {
                    return (Vec3::zeros(), false);
                }
                dx *= 0.5;
                halvings += 1;
            }
        }
        (dx, cut)
    }

    /// `dx` from particle `i`'s iterate, shortened so that it comes no
    /// closer to a solid's plane than [`SOLID_FLOOR`] of the thickness (nor
    /// deeper, if it is already closer) and no self pair closes more than
    /// half its gap,
    /// then cut to the particle's ball; whether the ball cut it.
    fn bounded(&self, i: usize, mut dx: Vec3) -> (Vec3, bool) {
        let from = self.x[i];
        let mut share = 1.0_f64;
        let mut keep = |gap: f64, change: f64, floor: f64| share = share.min(share_to_bound(gap, change, floor));
        let floor = SOLID_FLOOR * self.common.thickness;
        for plane in self.around[i].planes.iter().flatten() {
            let gap = plane.gap(&from);
            keep(gap, plane.normal.dot(&dx), gap.min(floor));
        }
        for &(pair, slot) in self.index.of(i) {
            let p = &self.pairs[pair as usize];
            let gap = p.gap(self.x);
            keep(gap, p.coefficients[slot as usize] * p.direction.dot(&dx), (0.5 * gap).min(gap));
        }
        dx *= share;
        let ball = &self.around[i];
        let to = from + dx - ball.centre;
        if to.norm() > ball.radius_m {
            return (ball.centre + to * (ball.radius_m / to.norm()) - from, true);
        }
        (dx, false)
    }
}

impl Vbd {
    /// Its name in scene files.
    pub(crate) const NAME: &'static str = "vbd";
}

impl Integrator for Vbd {
    fn name(&self) -> &'static str {
        Self::NAME
    }

    fn capabilities(&self) -> Capabilities {
        Capabilities { contacts: ContactHandling::Penalties, loads_at_start: true, ..Capabilities::default() }
    }

    fn solve(
        &mut self,
        step: &Step<'_>,
        contacts: &mut Contacts,
        out: &mut StepOutput,
        timer: &mut StageTimer,
    ) -> Result<StepReport, StepError> {
        let Step { model, state, h, solver, loads, .. } = *step;
        let params = solver.vbd;
        let b = self.buffers.get_or_insert_with(|| Box::new(VbdBuffers::new(model)));
        let n = state.len();
        let (xn, vn) = (&state.x[..], &state.v[..]);
        let gravity = model.effects().gravity.unwrap_or_else(Vec3::zeros);
        let lap = timer.start();
        let (paths, self_thickness) =
            start_step(step, contacts, (&mut b.inertial, &mut b.fixed), (&mut b.pairs, &mut b.index));
        timer.stop(lap, Stage::Update);
        let thickness = model.contact_thickness();
        let common = Common {
            model,
            stitches_closed: &state.stitches_closed,
            external: loads.forces(),
            h,
            thickness,
            self_thickness,
        };

        // The first guess, within the bounds from the step's start: the
        // paper's adaptive one, gravity as far as each particle's last
        // acceleration followed it.
        let lap = timer.start();
        let mut moves = std::mem::take(&mut b.moves);
        moves.clear();
        moves.resize(n, (Vec3::zeros(), false));
        {
            let start = Local { x: xn, v: vn, ..Local::at(common, b, &contacts.around) };
            let history = state.has_history && state.last_dt_s > 0.0;
            moves.par_chunks_mut(MOVE_CHUNK).enumerate().for_each(|(chunk, ms)| {
                for (k, m) in ms.iter_mut().enumerate() {
                    let i = chunk * MOVE_CHUNK + k;
                    let last = history.then(|| (state.v[i] - state.v_prev[i]) / state.last_dt_s);
                    let accel = adaptive_acceleration(gravity, last);
                    *m = start.bounded(i, vn[i] * h + accel * (h * h));
                }
            });
        }
        for (d, m) in b.d.iter_mut().zip(&moves) {
            *d = m.0;
        }
        for k in 0..paths.count() {
            let i = paths.particle(k);
            b.d[i] = paths.position(k, state.time_s + h) - xn[i];
        }
        for (((x, v), d), x0) in b.x.iter_mut().zip(b.v.iter_mut()).zip(&b.d).zip(xn) {
            (*x, *v) = (x0 + d, d / h);
        }
        let accelerate = params.chebyshev_rho > 0.0;
        if accelerate {
            b.previous.copy_from_slice(&b.d);
            b.before_previous.copy_from_slice(&b.d);
        }

        let mut omega = 1.0;
        let mut sweeps = 0;
        let mut converged = params.tolerance_m <= 0.0;
        for sweep in 1..=params.iterations {
            sweeps = sweep;
            // The friction's normal forces, lagged from the sweep's start.
            lag_normal_forces(model, &mut contacts.around, &b.x, h, thickness);
            let mut largest = 0.0_f64;
            for c in 0..b.colouring.len() {
                let group = &b.colouring.groups()[c];
                moves.clear();
                moves.resize(group.len(), (Vec3::zeros(), false));
                let local = Local::at(common, b, &contacts.around);
                let fixed = &b.fixed;
                moves.par_chunks_mut(MOVE_CHUNK).zip(group.par_chunks(MOVE_CHUNK)).for_each(|(ms, ids)| {
                    for (m, &i) in ms.iter_mut().zip(ids) {
                        let i = i as usize;
                        *m = if fixed[i] { (Vec3::zeros(), false) } else { local.step(i, params.line_search) };
                    }
                });
                let group = &b.colouring.groups()[c];
                for (&(dx, cut), &i) in moves.iter().zip(group) {
                    let i = i as usize;
                    b.d[i] += dx;
                    (b.x[i], b.v[i]) = (xn[i] + b.d[i], b.d[i] / h);
                    b.cut[i] |= cut;
                    largest = largest.max(dx.norm());
                }
            }
            // Chebyshev over the sweeps, kept where it stays in bounds.
            omega = chebyshev_omega(sweep, params.chebyshev_rho, omega);
            if accelerate && sweep > 1 {
                let floor = SOLID_FLOOR * thickness;
                let particles = b.d.iter_mut().zip(b.x.iter_mut().zip(b.v.iter_mut())).zip(&b.before_previous);
                for (i, ((d, (x, v)), older)) in particles.enumerate() {
                    if b.fixed[i] {
                        continue;
                    }
                    let accelerated = older + (*d - older) * omega;
                    let (to, a) = (xn[i] + accelerated, &contacts.around[i]);
                    let in_planes = a.planes.iter().flatten().all(|p| p.gap(&to) >= p.gap(x).min(floor));
                    if in_planes && (to - a.centre).norm() <= a.radius_m {
                        (*d, *x, *v) = (accelerated, to, accelerated / h);
                    }
                }
            }
            if accelerate {
                std::mem::swap(&mut b.before_previous, &mut b.previous);
                b.previous.copy_from_slice(&b.d);
            }
            // Particles their ball stopped look around again from where they are.
            contacts.look_around_again(step, &b.x, &mut b.cut);
            if params.tolerance_m > 0.0 && largest < params.tolerance_m {
                converged = true;
                break;
            }
        }
        b.moves = moves;
        timer.stop(lap, Stage::Solve);

        // Outputs: pin reactions and the new state.
        let lap = timer.start();
        let local = Local::at(common, b, &contacts.around);
        let forces = out.pin_forces_mut(paths.count());
        for (k, f) in forces.iter_mut().enumerate() {
            let i = paths.particle(k);
            let inertia = model.masses()[i] / (h * h);
            *f = (b.d[i] - b.inertial[i]) * inertia - local.loads(i, false).force;
        }
        // The iterate becomes the new state; the next step sets every
        // entry of `b.x` and `b.v` before it reads them.
        std::mem::swap(&mut out.x, &mut b.x);
        std::mem::swap(&mut out.v, &mut b.v);
        timer.stop(lap, Stage::Update);
        Ok(StepReport {
            force_evaluations: sweeps,
            substeps: 1,
            converged,
            descent_iterations: sweeps,
            ..StepReport::default()
        })
    }

    fn reset(&mut self) {
        self.buffers = None;
    }
}

/// What both minimisers (`vbd`, `quasi-newton`) set up at a step's start:
/// each particle's displacement under inertia alone, `h v_n` (m), which
/// particles are prescribed, and the self pairs the collision stage found
/// as penalties, indexed by particle. Returns the prescribed paths and the
/// self-collision thickness, m.
pub(crate) fn start_step<'a>(
    step: &Step<'a>,
    contacts: &Contacts,
    (inertial, fixed): (&mut [Vec3], &mut [bool]),
    (pairs, index): (&mut Vec<SelfPair>, &mut PairIndex),
) -> (PinPaths<'a>, f64) {
    let Step { model, state, control, h, .. } = *step;
    for (inertial, v) in inertial.iter_mut().zip(&state.v) {
        *inertial = v * h;
    }
    fixed.iter_mut().for_each(|f| *f = false);
    let paths = PinPaths::new(model, control, &state.x, state.time_s, h);
    for k in 0..paths.count() {
        fixed[paths.particle(k)] = true;
    }
    pairs.clear();
    let self_thickness = model.self_collision().map_or(0.0, |sc| sc.thickness_m);
    if let Some(sc) = model.self_collision() {
        let repelling = contacts.self_pairs.iter().filter(|c| c.repels);
        pairs.extend(repelling.map(|c| SelfPair::of(c, sc.stiffness_n_m)));
    }
    index.rebuild(state.len(), pairs);
    (paths, self_thickness)
}

/// The share of the contact thickness no local step may carry a particle
/// below. Not 0: a particle left exactly on a surface has no direction to
/// it, and the next step's closest point then gave a wrong normal (the
/// table fixture's rim let particles 2 cm into the top).
pub(crate) const SOLID_FLOOR: f64 = 0.5;

/// Particles a task of one colour's sweep takes at a time.
const MOVE_CHUNK: usize = 32;

/// The paper's adaptive first guess's acceleration, m/s^2: gravity `g`
/// scaled by how much of it the particle's last acceleration `last`
/// followed, clamped to `[0, 1]` (a particle at rest on a solid starts
/// where it was); all of `g` without a last step.
fn adaptive_acceleration(g: Vec3, last: Option<Vec3>) -> Vec3 {
    let g2 = g.norm_squared();
    match last {
        Some(a) if g2 > 0.0 => g * (a.dot(&g) / g2).clamp(0.0, 1.0),
        _ => g,
    }
}
