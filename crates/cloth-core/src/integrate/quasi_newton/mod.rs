//! Quasi-Newton (Liu, Bouaziz & Kavan 2017, "Quasi-Newton methods for
//! real-time simulation of hyperelastic materials"): backward Euler's
//! incremental potential over the step's displacement `d = x - x_n`,
//!
//! `G(d) = sum_i m_i/(2h^2) |d_i - h v_n,i|^2 + U(x_n + d) - f_c.(x_n + d)
//!         + 1/(2h) d^T C d + contacts`,
//!
//! minimised by L-BFGS (two-loop recursion, [`QuasiNewtonParams::history`]
//! pairs, reset each step) whose initial Hessian is mass plus weighted graph
//! Laplacians ([`initial_hessian`]), one `n x n` matrix prefactored for all
//! three coordinates; each direction is searched with Armijo backtracking
//! on `G`. `U` is the terms' elastic energy (the same laws as the other
//! integrators), `f_c` gravity and the loads taken at the step's start,
//! `C` the dampers (drag, link dampers, stitch dashpots) with their
//! directions frozen at the iterate along each line.
//!
//! Contacts are energies in the same minimisation, as for the vertex
//! solver: each particle's nearby solid planes with penalty and lagged,
//! smoothed Coulomb friction (Li et al. 2020), the normal forces lagged
//! from the first guess and once more from the iterate the step converges
//! with, and the self-collision pairs the collision stage found.
//! Friction's sticking stiffness joins the initial Hessian's diagonal; the
//! penalties' act along their normals alone and are left to the history.
//! The search is projected: each particle moves at most as far as its
//! bounds let it (no closer to a plane than half the contact thickness,
//! no self pair closing by more than half its gap, inside the ball free
//! of other solids); a particle that reaches its ball looks around again
//! and the history restarts. Measurements: `docs/results/quasi-newton.md`.
//!
//! A pair `(s, y)` with `s . y <= 0` (a concave stretch of the energy:
//! compressed links buckling) is skipped, as Liu et al. advise.

mod initial_hessian;
#[cfg(test)]
mod tests;

use super::step::{Capabilities, ContactHandling, Integrator, Step, StepOutput};
use super::timer::{Stage, StageTimer};
use super::vbd::self_pairs::{PairIndex, SelfPair};
use super::vbd::{SOLID_FLOOR, start_step};
use crate::contacts::{FRICTION_SMOOTHING_M_S, contact_penalty, contact_penalty_stiffness, plane_force};
use crate::contacts::{Surroundings, friction_secant, lag_normal_forces, share_to_bound, smoothed_slip};
use crate::forces::{EnergyBuffers, damping_forms, elastic_energy, forces_into};
use crate::terms::ForceBuffers;
use crate::{ClothModel, StepError, StepReport, Vec3};
use cloth_linalg::{ROW_CHUNK, dot};
use initial_hessian::{InitialHessian, factor_error};
use rayon::prelude::*;

/// Armijo's sufficient-decrease constant.
const ARMIJO: f64 = 1e-4;
/// Most halvings of a step length before the line search gives up.
const MAX_BACKTRACKS: usize = 30;

/// The quasi-Newton integrator (`quasi-newton`).
#[derive(Debug, Default)]
pub struct QuasiNewton {
    buffers: Option<Box<Buffers>>,
}

impl QuasiNewton {
    /// Its name in scene files.
    pub(crate) const NAME: &'static str = "quasi-newton";
}

/// The L-BFGS history: the last `(s, y)` pairs, oldest first.
#[derive(Debug, Default)]
struct History {
    s: Vec<Vec<Vec3>>,
    y: Vec<Vec<Vec3>>,
    rho: Vec<f64>,
    /// Pairs in use (the first `len` of a ring starting at `head`).
    len: usize,
    head: usize,
    alpha: Vec<f64>,
}

impl History {
    fn new(pairs: usize, n: usize) -> Self {
        Self {
            s: vec![vec![Vec3::zeros(); n]; pairs],
            y: vec![vec![Vec3::zeros(); n]; pairs],
            rho: vec![0.0; pairs],
            len: 0,
            head: 0,
            alpha: vec![0.0; pairs],
        }
    }

    fn clear(&mut self) {
        (self.len, self.head) = (0, 0);
    }

    /// The ring slot of the `k`-th pair, oldest first.
    fn slot(&self, k: usize) -> usize {
        (self.head + k) % self.s.len()
    }

    /// Keeps `s = d - d_prev`, `y = g - g_prev` if `s . y > 0`, in place of
    /// the oldest pair when full; whether kept. A refused pair written over
    /// the oldest drops it.
    fn push(&mut self, d: &[Vec3], d_prev: &[Vec3], g: &[Vec3], g_prev: &[Vec3]) -> bool {
        let capacity = self.s.len();
        if capacity == 0 {
            return false;
        }
        let full = self.len == capacity;
        let k = if full { self.head } else { self.slot(self.len) };
        for (((s, y), (a, b)), (c, e)) in
            self.s[k].iter_mut().zip(self.y[k].iter_mut()).zip(d.iter().zip(d_prev)).zip(g.iter().zip(g_prev))
        {
            (*s, *y) = (a - b, c - e);
        }
        let sy = dot(&self.s[k], &self.y[k]);
        let kept = sy.is_finite() && sy > 1e-300;
        if kept {
            self.rho[k] = 1.0 / sy;
        }
        match (full, kept) {
            (false, true) => self.len += 1,
            (true, true) => self.head = (self.head + 1) % capacity,
            (true, false) => {
                self.head = (self.head + 1) % capacity;
                self.len -= 1;
            }
            (false, false) => {}
        }
        kept
    }

    /// `r = H g` by the two-loop recursion with `H0^-1` from `h0`.
    fn apply(&mut self, g: &[Vec3], r: &mut [Vec3], h0: &mut InitialHessian) {
        r.copy_from_slice(g);
        for k in (0..self.len).rev() {
            let slot = self.slot(k);
            let a = self.rho[slot] * dot(&self.s[slot], r);
            self.alpha[slot] = a;
            axpy(r, -a, &self.y[slot]);
        }
        h0.solve(r);
        for k in 0..self.len {
            let slot = self.slot(k);
            let b = self.rho[slot] * dot(&self.y[slot], r);
            axpy(r, self.alpha[slot] - b, &self.s[slot]);
        }
    }
}

/// `r += a x`.
fn axpy(r: &mut [Vec3], a: f64, x: &[Vec3]) {
    r.par_chunks_mut(ROW_CHUNK).zip(x.par_chunks(ROW_CHUNK)).for_each(|(r, x)| {
        for (r, x) in r.iter_mut().zip(x) {
            *r += x * a;
        }
    });
}

/// Sums `f(i)` over `0..n` in fixed chunks combined in order (the same
/// bits for any number of threads).
fn ordered_sum(n: usize, partials: &mut Vec<f64>, f: impl Fn(usize) -> f64 + Sync) -> f64 {
    partials.clear();
    partials.resize(n.div_ceil(ROW_CHUNK), 0.0);
    partials.par_iter_mut().enumerate().for_each(|(c, p)| {
        *p = (c * ROW_CHUNK..((c + 1) * ROW_CHUNK).min(n)).map(&f).sum();
    });
    partials.iter().sum()
}

/// Buffers of the quasi-Newton step, allocated on first use.
#[derive(Debug)]
struct Buffers {
    hessian: InitialHessian,
    history: History,
    fixed: Vec<bool>,
    inertial: Vec<Vec3>,
    d: Vec<Vec3>,
    d_prev: Vec<Vec3>,
    x: Vec<Vec3>,
    v: Vec<Vec3>,
    /// The gradient of G at the iterate, N (pins' rows included).
    g: Vec<Vec3>,
    /// Its free rows, and those of the last iterate.
    g_free: Vec<Vec3>,
    g_prev: Vec<Vec3>,
    p: Vec<Vec3>,
    trial: Vec<Vec3>,
    /// A trial's displacement from the iterate, m.
    delta: Vec<Vec3>,
    /// How far along the direction each particle may go (a share of it),
    /// and whether its ball set that.
    share: Vec<(f64, bool)>,
    forces: Vec<Vec3>,
    force_buffers: ForceBuffers,
    energy: EnergyBuffers,
    cut: Vec<bool>,
    /// Each particle's contact stiffness in the initial Hessian, N/m.
    contact_stiffness: Vec<f64>,
    partials: Vec<f64>,
    pairs: Vec<SelfPair>,
    index: PairIndex,
}

impl Buffers {
    fn new(model: &ClothModel, stitches_closed: &[bool], history: usize) -> Result<Self, cloth_linalg::CholeskyError> {
        let n = model.particle_count();
        let zeros = vec![Vec3::zeros(); n];
        Ok(Self {
            hessian: InitialHessian::new(model, stitches_closed)?,
            history: History::new(history, n),
            fixed: vec![false; n],
            inertial: zeros.clone(),
            d: zeros.clone(),
            d_prev: zeros.clone(),
            x: zeros.clone(),
            v: zeros.clone(),
            g: zeros.clone(),
            g_free: zeros.clone(),
            g_prev: zeros.clone(),
            p: zeros.clone(),
            trial: zeros.clone(),
            delta: zeros.clone(),
            share: vec![(1.0, false); n],
            forces: zeros,
            force_buffers: ForceBuffers::new(model),
            energy: EnergyBuffers::new(model),
            cut: vec![false; n],
            contact_stiffness: vec![0.0; n],
            partials: Vec::new(),
            pairs: Vec::new(),
            index: PairIndex::default(),
        })
    }
}

/// What every evaluation of one step reads besides the iterate.
#[derive(Clone, Copy)]
struct Common<'a> {
    model: &'a ClothModel,
    /// Loads taken at the step's start (wind, the control's forces), N.
    external: Option<&'a [Vec3]>,
    around: &'a [Surroundings],
    pairs: &'a [SelfPair],
    index: &'a PairIndex,
    h: f64,
    thickness: f64,
    self_thickness: f64,
}

impl Common<'_> {
    /// The contacts' force on particle `i` at `(x, v)`: its planes'
    /// penalty and friction and its self pairs' penalty, N.
    fn contact_force(&self, i: usize, x: &[Vec3], v: &[Vec3]) -> Vec3 {
        let k = contact_penalty_stiffness(self.model.masses()[i], self.h);
        let eps = FRICTION_SMOOTHING_M_S;
        let planes = self.around[i].planes.iter().flatten();
        let mut f: Vec3 = planes.map(|p| plane_force(p, &x[i], &v[i], k, self.thickness, self.h, eps).0).sum();
        for &(pair, slot) in self.index.of(i) {
            f += self.pairs[pair as usize].force_on(slot as usize, x, self.self_thickness).0;
        }
        f
    }

    /// The planes' energy change of particle `i` moved from `x` (velocity
    /// `v`) by `dx`: penalty (J) and friction's dissipation over the step
    /// `h D(slip)` (Li et al. 2020, §5), with the planes' lagged normals.
    fn plane_change(&self, i: usize, x: Vec3, v: Vec3, dx: Vec3) -> f64 {
        let k = contact_penalty_stiffness(self.model.masses()[i], self.h);
        let (h, eps) = (self.h, FRICTION_SMOOTHING_M_S);
        let to = x + dx;
        let mut change = 0.0;
        for plane in self.around[i].planes.iter().flatten() {
            change += contact_penalty(plane.gap(&to), self.thickness, k).0
                - contact_penalty(plane.gap(&x), self.thickness, k).0;
            let limit = plane.friction * plane.lagged_normal_n;
            if limit > 0.0 {
                let n = plane.normal;
                let tangential = |w: Vec3| w - n * n.dot(&w);
                let (s0, s1) = (tangential(v - plane.solid_velocity), tangential(v + dx / h - plane.solid_velocity));
                change += h * limit * (smoothed_slip(s1.norm(), eps) - smoothed_slip(s0.norm(), eps));
            }
        }
        change
    }
}

/// The stiffness particle `i` at `x` (mass `m`, kg) has from the friction
/// of the planes whose penalty it is in, N/m: friction's secant at rest,
/// `2 mu N / eps` over `h` (sticking), the same in every direction. The
/// penalty's own stiffness acts along the normal alone; in every
/// direction it held sliding particles back (the incline at 35 degrees
/// slid 2.4e-4 short of Coulomb's acceleration after 200 iterations a
/// step), so it is left to the history. The secant at the particle's
/// slip at the step's start instead let the same incline slide 4.7% past
/// Coulomb's acceleration.
fn contact_stiffness(around: &Surroundings, x: Vec3, m: f64, h: f64, thickness: f64) -> f64 {
    let k = contact_penalty_stiffness(m, h);
    let mut stiffness = 0.0;
    for plane in around.planes.iter().flatten() {
        let (_, push) = contact_penalty(plane.gap(&x), thickness, k);
        if push > 0.0 && plane.friction > 0.0 {
            stiffness += friction_secant(0.0, plane.friction * push, FRICTION_SMOOTHING_M_S) / h;
        }
    }
    stiffness
}

/// The largest share of `dx` (in `[0, 1]`) particle `i` at `x` may take:
/// no closer to a plane than [`SOLID_FLOOR`] of the thickness (nor deeper
/// if already closer), and inside its ball; whether the ball set it.
fn particle_limit(around: &Surroundings, x: Vec3, dx: Vec3, floor: f64) -> (f64, bool) {
    let mut share = 1.0_f64;
    for plane in around.planes.iter().flatten() {
        let gap = plane.gap(&x);
        share = share.min(share_to_bound(gap, plane.normal.dot(&dx), gap.min(floor)));
    }
    if around.radius_m.is_finite() {
        let (a, r) = (dx.norm_squared(), x - around.centre);
        let (b, c) = (2.0 * dx.dot(&r), r.norm_squared() - around.radius_m * around.radius_m);
        if a > 0.0 && (x + dx - around.centre).norm() > around.radius_m {
            let root = ((-b + (b * b - 4.0 * a * c).max(0.0).sqrt()) / (2.0 * a)).max(0.0);
            if root < share {
                return (root, true);
            }
        }
    }
    (share, false)
}

/// The largest share of `p` a self pair allows: its gap closes by at most half.
fn pair_limit(pair: &SelfPair, x: &[Vec3], p: &[Vec3]) -> f64 {
    let gap = pair.gap(x);
    share_to_bound(gap, pair.gap(p), (0.5 * gap).min(gap))
}

impl Integrator for QuasiNewton {
    fn name(&self) -> &'static str {
        Self::NAME
    }

    fn capabilities(&self) -> Capabilities {
        Capabilities { contacts: ContactHandling::Penalties, loads_at_start: true, linear_solve: true, bodies: false }
    }

    fn solve(
        &mut self,
        step: &Step<'_>,
        contacts: &mut crate::contacts::Contacts,
        out: &mut StepOutput,
        timer: &mut StageTimer,
    ) -> Result<StepReport, StepError> {
        let Step { model, state, h, solver, loads, .. } = *step;
        let params = solver.quasi_newton;
        let n = state.len();
        let (xn, vn) = (&state.x[..], &state.v[..]);
        let failed = |e| factor_error(state.steps + 1, state.time_s, e);
        let lap = timer.start();
        if self.buffers.as_ref().is_none_or(|b| b.history.s.len() != params.history) {
            let b = Buffers::new(model, &state.stitches_closed, params.history).map_err(failed)?;
            self.buffers = Some(Box::new(b));
        }
        let b = self.buffers.as_mut().expect("made above");
        b.history.clear();
        let (paths, self_thickness) =
            start_step(step, contacts, (&mut b.inertial, &mut b.fixed), (&mut b.pairs, &mut b.index));
        timer.stop(lap, Stage::Update);

        let lap = timer.start();
        let thickness = model.contact_thickness();
        let floor = SOLID_FLOOR * thickness;
        let masses = model.masses();
        let gravity = model.effects().gravity.unwrap_or_else(Vec3::zeros);
        // The first guess: inertia and gravity, within each particle's bounds.
        {
            let around = &contacts.around;
            let (d, fixed) = (&mut b.d, &b.fixed);
            d.par_iter_mut().enumerate().for_each(|(i, d)| {
                let guess = vn[i] * h + gravity * (h * h);
                *d = if fixed[i] { Vec3::zeros() } else { guess * particle_limit(&around[i], xn[i], guess, floor).0 };
            });
        }
        for k in 0..paths.count() {
            let i = paths.particle(k);
            b.d[i] = paths.position(k, state.time_s + h) - xn[i];
        }
        let set_iterate = |b: &mut Buffers| {
            for (((x, v), d), x0) in b.x.iter_mut().zip(b.v.iter_mut()).zip(&b.d).zip(xn) {
                (*x, *v) = (x0 + d, d / h);
            }
        };
        set_iterate(b);
        // The initial Hessian with the friction of the solids the first
        // guess is in.
        {
            let (x, around, fixed) = (&b.x, &contacts.around, &b.fixed);
            b.contact_stiffness.par_iter_mut().enumerate().for_each(|(i, c)| {
                *c = if fixed[i] { 0.0 } else { contact_stiffness(&around[i], x[i], masses[i], h, thickness) };
            });
        }
        b.hessian.prepare(model, h, &b.fixed, &b.contact_stiffness).map_err(failed)?;

        let mut evaluations = 0;
        let mut iterations = 0;
        let mut converged = false;
        let mut elastic = None;
        // Whether the last iterate's (d, g) make a history pair with this one's.
        let mut pushable = false;
        let (mut relag, mut relags_left) = (false, 1);
        let has_friction = contacts.around.iter().any(|a| a.planes.iter().flatten().any(|p| p.friction > 0.0));
        loop {
            // Friction's normal forces, lagged (Li et al. 2020): from the
            // first guess, and once more from the iterate the step
            // converges with (or reaches half its iterations with).
            if iterations == 0 || relag {
                lag_normal_forces(model, &mut contacts.around, &b.x, h, thickness);
                relag = false;
            }
            let common = Common {
                model,
                external: loads.forces(),
                around: &contacts.around,
                pairs: &b.pairs,
                index: &b.index,
                h,
                thickness,
                self_thickness,
            };
            // The gradient of G at the iterate (the pins' rows kept for their reactions).
            forces_into(model, &b.x, &b.v, &state.stitches_closed, &mut b.force_buffers, &mut b.forces);
            evaluations += 1;
            {
                let (x, v, d, inertial, forces) = (&b.x, &b.v, &b.d, &b.inertial, &b.forces);
                b.g.par_iter_mut().enumerate().for_each(|(i, g)| {
                    let external = common.external.map_or(Vec3::zeros(), |e| e[i]);
                    let load = forces[i] + external + common.contact_force(i, x, v);
                    *g = (d[i] - inertial[i]) * (masses[i] / (h * h)) - load;
                });
            }
            let residual =
                b.g.iter()
                    .zip(&b.fixed)
                    .enumerate()
                    .filter(|(_, (_, f))| !**f)
                    .map(|(i, (g, _))| g.norm() * h * h / masses[i])
                    .fold(0.0, f64::max);
            if !residual.is_finite() {
                let particle = b.g.iter().position(|g| !g.iter().all(|c| c.is_finite())).unwrap_or(0);
                return Err(StepError::NonFinite {
                    step: state.steps + 1,
                    time_s: state.time_s,
                    particle,
                    quantity: "position",
                });
            }
            let halfway = iterations == params.iterations / 2 && iterations > 0;
            if (residual <= params.tolerance_m || halfway) && relags_left > 0 && has_friction {
                // The energy changes: the history restarts.
                (relag, relags_left, pushable) = (true, relags_left - 1, false);
                b.history.clear();
                continue;
            }
            if residual <= params.tolerance_m {
                converged = true;
                break;
            }
            if iterations == params.iterations {
                break;
            }
            // The direction: -H g over the free rows.
            for (gf, (g, &f)) in b.g_free.iter_mut().zip(b.g.iter().zip(&b.fixed)) {
                *gf = if f { Vec3::zeros() } else { *g };
            }
            if pushable {
                b.history.push(&b.d, &b.d_prev, &b.g_free, &b.g_prev);
            }
            b.history.apply(&b.g_free, &mut b.p, &mut b.hessian);
            let mut slope = -dot(&b.g_free, &b.p);
            if slope.is_nan() || slope >= 0.0 {
                // Not a descent direction: restart from H0.
                b.history.clear();
                b.p.copy_from_slice(&b.g_free);
                b.hessian.solve(&mut b.p);
                slope = -dot(&b.g_free, &b.p);
            }
            std::mem::swap(&mut b.g_prev, &mut b.g_free);
            b.p.par_iter_mut().for_each(|p| *p = -*p);
            if slope.is_nan() || slope >= 0.0 {
                break;
            }
            // How far each particle may go along p: its planes and ball,
            // and the self pairs it is in.
            {
                let (x, p, around) = (&b.x, &b.p, &contacts.around);
                b.share
                    .par_iter_mut()
                    .enumerate()
                    .for_each(|(i, s)| *s = particle_limit(&around[i], x[i], p[i], floor));
                for pair in &b.pairs {
                    let limit = pair_limit(pair, x, p);
                    for (&node, &c) in pair.nodes.iter().zip(&pair.coefficients) {
                        let share = &mut b.share[node as usize];
                        if c != 0.0 && limit < share.0 {
                            *share = (limit, false);
                        }
                    }
                }
            }
            // Armijo backtracking on G along the path each particle's bound
            // cuts (a projected search): particle i moves p_i min(alpha, share_i).
            let u0 = match elastic {
                Some(u) => u,
                None => elastic_energy(model, &b.x, &state.stitches_closed, &mut b.energy),
            };
            let external = common.external;
            let mut alpha = 1.0_f64;
            let mut accepted = None;
            for _ in 0..=MAX_BACKTRACKS {
                let (p, share) = (&b.p, &b.share);
                b.delta.par_iter_mut().enumerate().for_each(|(i, dl)| *dl = p[i] * alpha.min(share[i].0));
                for ((t, x), dl) in b.trial.iter_mut().zip(&b.x).zip(&b.delta) {
                    *t = x + dl;
                }
                let u = elastic_energy(model, &b.trial, &state.stitches_closed, &mut b.energy);
                let (x, v, dl, d, inertial, gf) = (&b.x, &b.v, &b.delta, &b.d, &b.inertial, &b.g_prev);
                let inertia = ordered_sum(n, &mut b.partials, |i| {
                    masses[i] / (h * h) * ((d[i] - inertial[i]).dot(&dl[i]) + 0.5 * dl[i].norm_squared())
                });
                let load = ordered_sum(n, &mut b.partials, |i| {
                    (gravity * masses[i] + external.map_or(Vec3::zeros(), |e| e[i])).dot(&dl[i])
                });
                let predicted = ordered_sum(n, &mut b.partials, |i| gf[i].dot(&dl[i]));
                let planes = ordered_sum(n, &mut b.partials, |i| {
                    let free = common.around[i].planes.iter().all(Option::is_none);
                    if free { 0.0 } else { common.plane_change(i, x[i], v[i], dl[i]) }
                });
                let pairs: f64 = b
                    .pairs
                    .iter()
                    .map(|pair| {
                        let (g0, k) = (pair.gap(x), pair.stiffness_n_m);
                        contact_penalty(g0 + pair.gap(dl), self_thickness, k).0
                            - contact_penalty(g0, self_thickness, k).0
                    })
                    .sum();
                let (vcd, dcd) = damping_forms(model, x, v, dl, &state.stitches_closed);
                let change = inertia + (u - u0) - load + vcd + dcd / (2.0 * h) + planes + pairs;
                let noise = 1e-12 * (u0.abs() + load.abs() + inertia.abs());
                if predicted < 0.0 && change <= ARMIJO * predicted + noise {
                    accepted = Some(u);
                    break;
                }
                alpha *= 0.5;
            }
            let Some(u) = accepted else { break };
            elastic = Some(u);
            b.d_prev.copy_from_slice(&b.d);
            axpy(&mut b.d, 1.0, &b.delta);
            set_iterate(b);
            iterations += 1;
            pushable = true;
            // Particles their ball stopped look around again from where
            // they are: their energy changed, so the history restarts.
            let mut stopped = false;
            for (c, &(share, by_ball)) in b.cut.iter_mut().zip(&b.share) {
                *c = by_ball && share <= alpha;
                stopped |= *c;
            }
            if stopped {
                contacts.look_around_again(step, &b.x, &mut b.cut);
                b.history.clear();
                (elastic, pushable) = (None, false);
            }
        }
        timer.stop(lap, Stage::Solve);

        let lap = timer.start();
        let forces = out.pin_forces_mut(paths.count());
        for (k, f) in forces.iter_mut().enumerate() {
            *f = b.g[paths.particle(k)];
        }
        // The iterate becomes the new state; the next step sets every
        // entry of `b.x` and `b.v` before it reads them.
        std::mem::swap(&mut out.x, &mut b.x);
        std::mem::swap(&mut out.v, &mut b.v);
        timer.stop(lap, Stage::Update);
        Ok(StepReport {
            force_evaluations: evaluations,
            substeps: 1,
            converged,
            descent_iterations: iterations,
            ..StepReport::default()
        })
    }

    fn reset(&mut self) {
        self.buffers = None;
    }
}
