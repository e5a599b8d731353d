//! The collision stage and the contacts' response: the two places of a
//! step where [`Contacts`] are made. Detection at the step's start finds
//! what the integrator takes into its solve (by its
//! [`ContactHandling`]); the response after the solve completes the step
//! (friction, no bounce off holding solids, self-collision separation,
//! the continuous self-collision test, the projection out of solids), or
//! for the integrators without contacts in their solve, handles the
//! solids at the step's end.

use super::contacts::*;
use super::detect::reach_surface;
use super::surroundings::{plane_force, surroundings};
use crate::colliders::SelfCollision;
use crate::integrate::step::{ContactHandling, Step, StepOutput};
use crate::integrate::timer::{Stage, StageTimer};
use crate::model::fast_projection::SolidBound;
use crate::{ClothModel, StepError, Vec3};
use cloth_linalg::ROW_CHUNK;
use rayon::prelude::*;

/// Solids within this many contact thicknesses of a particle in a step's
/// finish bound its moves in the deformation constraints' fast
/// projections: those it may reach while they move it.
const SOLID_BOUND_REACH: f64 = 2.0;

/// Rounds of impact zones and projection out of the solids after a step
/// whose projection pushed cloth (see [`Contacts::respond_to_solve`]).
const PROJECTION_ROUNDS: usize = 4;

impl Contacts {
    /// The collision stage: the contacts of the step's start that an
    /// integrator with `handling` takes into its solve, and their counters.
    pub(crate) fn detect(
        &mut self,
        step: &Step<'_>,
        handling: ContactHandling,
        timer: &mut StageTimer,
    ) -> Result<(), StepError> {
        self.stats = ContactStats::default();
        match handling {
            ContactHandling::Constraints => self.detect_constraints(step, timer),
            ContactHandling::Penalties => self.detect_surroundings(step, timer),
            ContactHandling::AfterStep => Ok(()),
        }
    }

    /// The response after the solve: completes the step in `out`.
    pub(crate) fn respond(
        &mut self,
        step: &Step<'_>,
        handling: ContactHandling,
        out: &mut StepOutput,
        timer: &mut StageTimer,
    ) {
        match handling {
            ContactHandling::Constraints => {
                let lap = timer.start();
                self.respond_to_solve(step, out, timer);
                timer.stop(lap, Stage::Update);
            }
            ContactHandling::Penalties => self.respond_to_penalties(step, out, timer),
            ContactHandling::AfterStep => {
                if !step.model.colliders().is_empty() {
                    timer.time(Stage::Collision, || self.collide_after_step(step, out));
                }
            }
        }
    }

    /// Self-collision forces of the step's start into `self_force` (and
    /// their stiffness into `self_stiffness`), and the cloth-solid
    /// contacts of the step from the particles' predicted positions.
    fn detect_constraints(&mut self, step: &Step<'_>, timer: &mut StageTimer) -> Result<(), StepError> {
        let Step { model, state, control, h, .. } = *step;
        if let Some(sc) = model.self_collision() {
            let found = timer.time(Stage::SelfCollision, || {
                detect_self_contacts(model, sc, &state.x, &state.v, h, self).map_err(|particle| StepError::NonFinite {
                    step: state.steps + 1,
                    time_s: state.time_s,
                    particle,
                    quantity: "position",
                })
            })?;
            self.stats += found;
        }
        self.solid.clear();
        if !model.colliders().is_empty() {
            let found = timer.time(Stage::Collision, || {
                self.set_external(control);
                detect_solid_contacts(model, state, h, self)
            });
            self.stats += found;
        }
        Ok(())
    }

    /// The self-collision pairs of the step's start, and each particle's
    /// surroundings: the solids within its reach (twice the thickness plus
    /// twice what it covers in a step at its speed), found where each
    /// solid is at the step's start and carried to its end.
    fn detect_surroundings(&mut self, step: &Step<'_>, timer: &mut StageTimer) -> Result<(), StepError> {
        let Step { model, state, control, h, .. } = *step;
        let (xn, vn) = (&state.x[..], &state.v[..]);
        if let Some(sc) = model.self_collision() {
            let found = timer.time(Stage::SelfCollision, || {
                detect_self_contacts(model, sc, xn, vn, h, self).map_err(|particle| StepError::NonFinite {
                    step: state.steps + 1,
                    time_s: state.time_s,
                    particle,
                    quantity: "position",
                })
            })?;
            self.stats.hash_builds += found.hash_builds;
            self.stats.self_contacts = self.self_pairs.iter().filter(|c| c.repels).count();
        }
        let lap = timer.start();
        let n = state.len();
        self.around.resize(n, Surroundings::free(Vec3::zeros()));
        self.around_queries.resize(n, 0);
        let thickness = model.contact_thickness();
        let reach = |i: usize| 2.0 * thickness + 2.0 * h * vn[i].norm();
        let (solids, solids_now) = if model.colliders().is_empty() {
            (&[][..], &[][..])
        } else {
            self.set_external(control);
            let Contacts { now, next, external: motions, .. } = self;
            (next.at(model, motions, state.time_s + h), now.at(model, motions, state.time_s))
        };
        let paths = crate::control::PinPaths::new(model, control, xn, state.time_s, h);
        self.around_fixed.clear();
        self.around_fixed.resize(n, false);
        for i in paths.particles() {
            self.around_fixed[i] = true;
        }
        let fixed = &self.around_fixed;
        self.around.par_iter_mut().zip(self.around_queries.par_iter_mut()).enumerate().for_each(|(i, (a, q))| {
            (*a, *q) = if fixed[i] || solids.is_empty() {
                (Surroundings::free(xn[i]), 0)
            } else {
                surroundings(model, (solids_now, solids), xn[i], reach(i), thickness)
            };
        });
        for (i, (a, q)) in self.around.iter().zip(&self.around_queries).enumerate() {
            self.stats.narrow_phase_queries += *q as usize;
            // How deep the step starts inside a solid where the solid is
            // now (as the other integrators report it), for the particles
            // near one.
            for p in a.planes.iter().flatten() {
                let k = p.collider as usize;
                let now = model.colliders()[k].shape.closest(solids_now[k].pose(), xn[i]);
                self.stats.max_penetration_m = self.stats.max_penetration_m.max(-now.distance_m);
            }
        }
        timer.stop(lap, Stage::Collision);
        Ok(())
    }

    /// The particles a local step's bound stopped (`cut`) look around
    /// again from where they are (`x`), against the solids at the step's
    /// end, with the reach of [`Contacts::detect`]; `cut` is cleared.
    pub(crate) fn look_around_again(&mut self, step: &Step<'_>, x: &[Vec3], cut: &mut [bool]) {
        let Step { model, state, h, .. } = *step;
        if model.colliders().is_empty() {
            return;
        }
        let thickness = model.contact_thickness();
        let vn = &state.v;
        let reach = |i: usize| 2.0 * thickness + 2.0 * h * vn[i].norm();
        let solids = self.next.at(model, &self.external, state.time_s + h);
        self.around.par_iter_mut().zip(cut.par_iter_mut()).enumerate().for_each(|(i, (a, c))| {
            if *c {
                *a = surroundings(model, (solids, solids), x[i], reach(i), thickness).0;
                *c = false;
            }
        });
    }

    /// The response of the assembled implicit steps after their solve
    /// (positions and velocities in `out`, how the solve went in
    /// `out.response`): friction (in the solve for squeezed particles and
    /// in Newton iterations), no bounce off holding solids, self-collision
    /// separation, the continuous self-collision test and the last
    /// projection out of solids (solids last: cloth never ends a step
    /// inside one).
    fn respond_to_solve(&mut self, step: &Step<'_>, out: &mut StepOutput, timer: &mut StageTimer) {
        let Step { model, state, h, .. } = *step;
        let response = out.response;
        let (tau, newton) = (response.time_s, response.newton);
        let masses = model.masses();
        let stats = &mut self.stats;
        let solid = &mut self.solid;
        if response.squeeze_friction || newton {
            squeeze_friction_forces(solid, &out.v);
        }
        stats.sticking = apply_friction(solid, masses, (tau, h), newton, &mut out.x, &mut out.v);
        if !newton {
            // Held particles do not bounce off their solid.
            out.bodies.stop_separation(solid, masses, &mut out.v);
            let bodies = &out.bodies;
            stop_separation(solid, masses, &mut out.v, |c| bodies.holds(c));
        }
        if let Some(sc) = model.self_collision() {
            let pairs = &self.self_pairs;
            self.stats.self_separations = separate_self_contacts(model, sc, pairs, tau, &mut out.x, &mut out.v);
            if sc.continuous {
                self.crossings.start_step(out.x.len());
                self.untangle_counted(model, sc, &state.x, tau, (&mut out.x, &mut out.v), timer);
            }
        }
        if !model.colliders().is_empty() {
            // After Newton iterations (penalties, not constraints), an active
            // set that ran out of passes or self-collision separations (which
            // can push a hem into a swinging shin): check every particle.
            let stats = self.stats;
            let all = response.unresolved || newton || stats.self_separations > 0 || stats.self_crossings > 0;
            let times = (state.time_s, h);
            let continuous = model.self_collision().filter(|sc| sc.continuous);
            if continuous.is_some() {
                self.crossings.before_projection(&out.x);
            }
            self.stats.projected = project_out(model, &state.x, times, self, all, &mut out.x, &mut out.v);
            // A solid pushing cloth out can push it through another layer
            // (a hem pinched between the knees): the pushed particles are held
            // and carry what they would cross with them, then the solids
            // project again, a few rounds.
            if let Some(sc) = continuous.filter(|_| self.stats.projected > 0) {
                self.untangle_holding_projected(
                    model,
                    sc,
                    (&state.x, &state.x),
                    times,
                    tau,
                    (&mut out.x, &mut out.v),
                    timer,
                );
            }
        }
        self.stats.contacts = self.solid.iter().filter(|c| c.active).count();
    }

    /// The continuous test and impact zones along the motion from `from` to
    /// `x` (`untangle_step`), timed as self-collision: the meetings found
    /// add to the step's count, those left replace it. Returns the
    /// meetings found.
    fn untangle_counted(
        &mut self,
        model: &ClothModel,
        sc: &SelfCollision,
        from: &[Vec3],
        tau: f64,
        (x, v): (&mut [Vec3], &mut [Vec3]),
        timer: &mut StageTimer,
    ) -> usize {
        let lap = timer.start();
        let (met, left) = untangle_step(model, sc, from, tau, x, v, self);
        timer.stop(lap, Stage::SelfCollision);
        (self.stats.self_crossings, self.stats.crossings_left) = (self.stats.self_crossings + met, left);
        met
    }

    /// Impact zones along the motion from `from` to `x`, the particles a
    /// projection pushed held, then the projection out of the solids
    /// (`start`: the step's start), in rounds until nothing meets or
    /// nothing is pushed; then, if meetings are left, zones free of the
    /// solids. Returns the meetings found.
    #[allow(clippy::too_many_arguments)]
    fn untangle_holding_projected(
        &mut self,
        model: &ClothModel,
        sc: &SelfCollision,
        (from, start): (&[Vec3], &[Vec3]),
        times: (f64, f64),
        tau: f64,
        (x, v): (&mut [Vec3], &mut [Vec3]),
        timer: &mut StageTimer,
    ) -> usize {
        let mut found = 0;
        for _ in 0..PROJECTION_ROUNDS {
            self.crossings.hold_projected(x);
            let met = self.untangle_counted(model, sc, from, tau, (&mut *x, &mut *v), timer);
            found += met;
            if met == 0 || model.colliders().is_empty() {
                break;
            }
            self.crossings.before_projection(x);
            let again = project_out(model, start, times, self, true, x, v);
            self.stats.projected += again;
            if again == 0 {
                break;
            }
        }
        // Held particles on both sides of a meeting (two layers pinched
        // between solids) can leave it crossing: then zones move free of
        // the solids. A particle left inside a solid's layer is pushed out
        // by the next step's contacts; a crossing is undone by nothing.
        if self.stats.crossings_left > 0 {
            self.crossings.start_step(x.len());
            found += self.untangle_counted(model, sc, from, tau, (x, v), timer);
        }
        found
    }

    /// Before the deformation constraints correct the step's end `x`: with
    /// continuous self-collision, remembers it, none held.
    pub(crate) fn before_corrections(&mut self, model: &ClothModel, x: &[Vec3]) {
        if model.self_collision().is_some_and(|sc| sc.continuous) {
            self.crossings.start_step(x.len());
            self.crossings.uncorrected.clear();
            self.crossings.uncorrected.extend_from_slice(x);
        }
    }

    /// The solids within [`SOLID_BOUND_REACH`] thicknesses of each
    /// particle at positions `x` (the end of a step of `h` from `t`,
    /// started at `start`), as the bounds the deformation constraints'
    /// fast projection keeps the particles in: the tangent plane at the
    /// closest point, on the side the particle came from (as the
    /// projection out of the solids takes it), moved out by the thickness.
    /// In particle order, then the model's order of solids.
    pub(crate) fn find_solid_bounds(&mut self, model: &ClothModel, start: &[Vec3], (t, h): (f64, f64), x: &[Vec3]) {
        let thickness = model.contact_thickness();
        let limit = (SOLID_BOUND_REACH * thickness, false);
        let solids = self.next.at(model, &self.external, t + h);
        let held = &self.held;
        self.bound_chunks.resize_with(x.len().div_ceil(ROW_CHUNK), Vec::new);
        self.bound_chunks.par_iter_mut().enumerate().for_each(|(k, bounds)| {
            bounds.clear();
            for i in k * ROW_CHUNK..((k + 1) * ROW_CHUNK).min(x.len()) {
                if prescribed(model, held, i) {
                    continue;
                }
                for (c, next) in model.colliders().iter().zip(solids) {
                    if let Some((_, s)) = reach_surface(c, (next, h), start[i], x[i], limit, &mut 0).within() {
                        let (particle, normal) = (i as u32, s.normal);
                        bounds.push(SolidBound { particle, normal, offset_m: normal.dot(&s.point) + thickness });
                    }
                }
            }
        });
        self.solid_bounds.clear();
        self.solid_bounds.extend(self.bound_chunks.iter().flatten());
    }

    /// The projection out of the solids between the constraints' passes
    /// (`start`: the step's start, `times`: its time and length, s); the
    /// particles it moves are held by the impact zones that follow, and
    /// counted. Returns how many it moved.
    pub(crate) fn project_corrected(
        &mut self,
        model: &ClothModel,
        start: &[Vec3],
        times: (f64, f64),
        x: &mut [Vec3],
        v: &mut [Vec3],
    ) -> usize {
        self.crossings.before_projection(x);
        let moved = project_out(model, start, times, self, true, x, v);
        self.crossings.hold_projected(x);
        self.stats.projected += moved;
        moved
    }

    /// After the deformation constraints: nothing passes through the cloth
    /// along the motion they gave it (from `before_corrections`' positions
    /// to `x`), as after the solve. A link shortened through another layer
    /// leaves a crossing that the next step's continuous test cannot see,
    /// since that step starts with it. Returns the meetings found.
    pub(crate) fn untangle_corrections(
        &mut self,
        model: &ClothModel,
        (start, times): (&[Vec3], (f64, f64)),
        (x, v): (&mut [Vec3], &mut [Vec3]),
        timer: &mut StageTimer,
    ) -> usize {
        let Some(sc) = model.self_collision().filter(|sc| sc.continuous) else { return 0 };
        let from = std::mem::take(&mut self.crossings.uncorrected);
        let found = self.untangle_holding_projected(model, sc, (&from, start), times, times.1, (x, v), timer);
        self.crossings.uncorrected = from;
        found
    }

    /// The response of the integrators whose contacts are penalties: the
    /// contacts whose penalty acts at the end of the step (with the
    /// impulse the penalty and friction gave over it), then the continuous
    /// self-collision test (nothing passes through the cloth in the step;
    /// velocities are the displacement over `h` there).
    fn respond_to_penalties(&mut self, step: &Step<'_>, out: &mut StepOutput, timer: &mut StageTimer) {
        let Step { model, state, h, .. } = *step;
        let thickness = model.contact_thickness();
        let lap = timer.start();
        self.solid.clear();
        for (i, a) in self.around.iter().enumerate() {
            let k = contact_penalty_stiffness(model.masses()[i], h);
            for p in a.planes.iter().flatten() {
                let gap = p.gap(&out.x[i]);
                let push = contact_penalty(gap, thickness, k).1;
                if push > 0.0 {
                    let (force, _) = plane_force(p, &out.x[i], &out.v[i], k, thickness, h, FRICTION_SMOOTHING_M_S);
                    self.solid.push(penalty_contact(i, p, push, force * h, gap));
                }
            }
        }
        self.stats.contacts = self.solid.len();
        timer.stop(lap, Stage::Update);
        if let Some(sc) = model.self_collision().filter(|sc| sc.continuous) {
            self.crossings.start_step(out.x.len());
            let met = self.untangle_counted(model, sc, &state.x, h, (&mut out.x, &mut out.v), timer);
            // Impact zones move particles rigidly, blind to the solids: a
            // zone in a heap on the floor carried particles 12 mm into it
            // (the quasi-Newton step at 100 iterations). Project them out.
            if met > 0 && !model.colliders().is_empty() {
                let lap = timer.start();
                let times = (state.time_s, h);
                self.stats.projected = project_out(model, &state.x, times, self, true, &mut out.x, &mut out.v);
                timer.stop(lap, Stage::Collision);
            }
        }
    }

    /// The solids at the step's end, for the integrators without contacts
    /// in their solve (see [`collide_after_step`]).
    fn collide_after_step(&mut self, step: &Step<'_>, out: &mut StepOutput) {
        let Step { model, state, control, h, .. } = *step;
        self.set_external(control);
        let times = (state.time_s, h);
        self.stats = collide_after_step(model, &state.x, times, self, &mut out.x, &mut out.v);
    }
}

/// What a penalty step reports of a solid's contact with particle `i`:
/// the plane `p`, its push (N), the impulse over the step (N s) and the
/// gap (m).
fn penalty_contact(i: usize, p: &Plane, push: f64, impulse: Vec3, gap: f64) -> SolidContact {
    SolidContact {
        distance_m: gap,
        normal_force_n: push,
        impulse_n_s: impulse,
        ..SolidContact::new(i, p.collider as usize, p.point, p.normal, p.solid_velocity, p.friction)
    }
}
