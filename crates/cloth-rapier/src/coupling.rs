//! One step of cloth and rigid bodies together.
//!
//! The interface is each coupled dynamic body's mean velocity over the
//! step: the displacement of its centre of mass over `h` and its rotation
//! increment (as a rotation vector) over `h`. A guess fixes the body's end
//! pose; the cloth sees the body as an external solid moving on the
//! straight line (and shortest turn) there. (The end velocity would not
//! do: rapier substeps, so a body falling under gravity does not end at
//! `x_0 + h v_1`, and the cloth would see it off by about `g h^2 / 3` every
//! step; in the hammock that mismatch kept the ball bouncing.) A pass:
//! 1. every cloth steps with each body moving along the path of the guess
//!    (attached pins following the body's points to the end pose);
//! 2. what the cloth took from the bodies comes back to them: the contact
//!    impulses (normal force over the step plus friction, read from the
//!    cloth's solve) and `h` times the pull on the attached pins, as linear
//!    and angular impulses about the centre of mass at the start;
//! 3. rapier steps (its own contacts, joints and gravity), giving each
//!    body's end pose, hence its mean velocity.
//!
//! Whatever the guess, the impulse a body receives is exactly what the
//! cloth lost to it, so cloth plus bodies conserve linear momentum in every
//! pass (to the solver's round-off; see the tests).
//!
//! [`Master::Staggered`] makes one pass with the guess "start velocity plus
//! gravity" (a one-way-per-step, explicit coupling, as cheap as it gets).
//! [`Master::Iterated`] repeats the pass from the saved start until the mean
//! velocities agree with the guess, moving the guess by fixed relaxation or
//! interface quasi-Newton (IQN-ILS); this is what keeps light bodies on
//! heavy cloth (and heavy on light) stable (Shinar, Schroeder & Fedkiw 2008
//! show the staggered scheme's limit).

use crate::cloth_set::{ClothSet, CouplingError};
use crate::convert::{pose_to_rapier, rotation_from_rapier, vec_from_rapier, vec_to_rapier};
use crate::world::{BodyStart, Drive, WorldSnapshot};
use cloth_core::{Snapshot, StepReport, Vec3};
use cloth_cosim::{GuessUpdate, Relaxation};
use rapier3d_f64::prelude::{EventHandler, PhysicsHooks, PhysicsWorld, RigidBodyHandle};

/// Parameters of the iterated coupling.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IteratedCoupling {
    /// Most passes per step before giving up (see `accept_unconverged`). Default 20.
    pub max_iterations: usize,
    /// Converged when every mean velocity component changes by less than
    /// `abs_tol_m_s + rel_tol |value|` (m/s, rad/s). Defaults 1e-6 and 1e-6.
    pub abs_tol_m_s: f64,
    /// See `abs_tol_m_s`.
    pub rel_tol: f64,
    /// Guess update. Default quasi-Newton after a first step of 0.5.
    pub relaxation: Relaxation,
    /// When `max_iterations` is reached, repeat the pass with the smallest
    /// residual and go on (reported as not converged) instead of failing the
    /// step. Default true: a cloth contact that switches on or off with the
    /// guess makes the bodies' end velocities jump, so a step can have no
    /// exact fixed point (seen in the hammock: two contact sets alternating
    /// 3e-3 m/s apart); the best pass is then as close as the contacts allow,
    /// and a body lighter than the cloths ends as that pass's guess moved
    /// it (the side the cloth resolved its contacts with).
    pub accept_unconverged: bool,
}

impl Default for IteratedCoupling {
    fn default() -> Self {
        Self {
            max_iterations: 20,
            abs_tol_m_s: 1e-6,
            rel_tol: 1e-6,
            relaxation: Relaxation::QuasiNewton { initial: 0.5 },
            accept_unconverged: true,
        }
    }
}

/// Parameters of the monolithic coupling.
///
/// The cloth's solve knows a body's inertia, gravity and the cloth, not
/// rapier's contacts and joints on it, which act in rapier's step after
/// it. When they end a body elsewhere than the solve assumed where a
/// cloth meets it (a ball landing on a plate through the cloth), the
/// cloths are solved once more with rapier's extra motion in the body's
/// guess, and the body is moved to where that solve leaves it; rapier
/// steps once either way. A body that meets only cloth agrees at once.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MonolithicCoupling {
    /// The cloths' solves per step, 1 or 2: with 1, what rapier's
    /// contacts do within the step is left to the next step, where the
    /// cloth meets the body where rapier put it. Default 2.
    pub max_solves: usize,
    /// Agreement where a cloth meets a body, m: rapier's step and the
    /// cloths' solve put each pinned point, and each contact point along
    /// its normal, within `tol_m` of each other at the end of the step.
    /// Default (`None`): a fifth of the thinnest cloth's contact layer
    /// (1 mm for the default 5 mm layer). A body that ends closer to the
    /// cloth than the solve assumed by less than that leaves its particles
    /// within the layer, which the next step's contacts take up.
    pub tol_m: Option<f64>,
}

/// The share of the contact layer that is [`MonolithicCoupling::tol_m`]'s default.
pub(crate) const TOL_LAYER_SHARE: f64 = 0.2;

impl Default for MonolithicCoupling {
    fn default() -> Self {
        Self { max_solves: 2, tol_m: None }
    }
}

/// How cloth and bodies are stepped together.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Master {
    /// One pass: the cloth sees each body at its start velocity plus
    /// gravity, then the bodies receive the cloth's impulses and step.
    Staggered,
    /// Passes repeated until the bodies' mean velocities agree with the guess.
    Iterated(IteratedCoupling),
    /// The bodies inside the cloth's solve: every dynamic body a cloth
    /// touches or holds joins its implicit step as six unknowns
    /// ([`cloth_core::BodyInSolve`]), so the cloth and the body answer each
    /// other within the step; rapier then steps once with the cloth's
    /// impulses (a second solve of the cloths when rapier's own contacts
    /// or joints moved a body where a cloth meets it: see
    /// [`MonolithicCoupling`]). Needs an assembled implicit integrator
    /// (`bdf2`, `backward-euler`). A body several cloths share meets them
    /// one after the other, each seeing what the ones before did to it.
    Monolithic(MonolithicCoupling),
}

impl Default for Master {
    /// Monolithic: what a scene with an assembled implicit integrator uses.
    fn default() -> Self {
        Master::Monolithic(MonolithicCoupling::default())
    }
}

/// What a coupled step did.
#[derive(Debug, Clone, PartialEq)]
pub struct CouplingReport {
    /// Passes made: 1 for the staggered master; the iterated master's
    /// passes (`max_iterations + 1` when not converged: the best pass is
    /// repeated); the monolithic master's solves of the cloths (1 or 2).
    pub iterations: usize,
    /// Whether `residual <= 1` (always for staggered).
    pub converged: bool,
    /// Iterated: the largest change of a mean velocity in the accepted
    /// pass over its tolerance. Monolithic: how far the motion rapier's
    /// contacts saw differs, where the cloths meet the bodies, from the
    /// one the cloths' last solve gave them, over the tolerance
    /// ([`MonolithicCoupling`]). 0 for staggered.
    pub residual: f64,
    /// Cloth-body contacts in the accepted pass.
    pub contacts: usize,
    /// Dynamic bodies coupled to some cloth.
    pub coupled_bodies: usize,
    /// Each cloth's step report in the accepted pass, in set order.
    pub cloths: Vec<StepReport>,
}

/// The impulse the cloths gave one body in a pass.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct BodyImpulse {
    pub(crate) linear: Vec3,
    /// About the body's centre of mass at the start of the step.
    pub(crate) angular: Vec3,
}

/// A point where a cloth holds or presses a body, at the end of the
/// cloths' solves.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Hold {
    /// From the body's centre of mass (where the solve moved it), m.
    pub(crate) lever: Vec3,
    /// A contact's outward normal (the cloth resists only along it);
    /// `None` for a pin, which holds in every direction.
    pub(crate) normal: Option<Vec3>,
}

/// What the cloths' solves of one pass produced.
pub(crate) struct Solved {
    /// The impulse each coupled body took.
    pub(crate) impulses: Vec<BodyImpulse>,
    /// With the bodies in the solve: the mean velocities the cloths'
    /// solves left them (6 per body), which rapier's step reproduces
    /// unless its own contacts or joints act on them; else the guess.
    pub(crate) assumed: Vec<f64>,
    /// Where each coupled body is held or pressed (with the bodies in the
    /// solves; the monolithic master measures its disagreement there).
    pub(crate) holds: Vec<Vec<Hold>>,
    /// Cloth-body contacts.
    pub(crate) contacts: usize,
    /// Each cloth's step report.
    pub(crate) reports: Vec<StepReport>,
    /// Whether the bodies were in the solves.
    pub(crate) in_solve: bool,
}

/// What one pass produced.
pub(crate) struct Pass {
    /// Mean velocities of the coupled dynamic bodies after rapier's step (6 per body).
    pub(crate) end: Vec<f64>,
    /// The cloths' half.
    pub(crate) solved: Solved,
    /// What rapier reported in this pass's step.
    pub(crate) events: crate::events::RecordedEvents,
}

/// A body some cloth touches or holds, and how it starts the step.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Coupled {
    pub(crate) handle: RigidBodyHandle,
    pub(crate) start: BodyStart,
    /// Index of its 6 guess values, for dynamic bodies.
    pub(crate) slot: Option<usize>,
}

impl ClothSet {
    /// Steps every cloth and the rapier world together by the world's
    /// `integration_parameters.dt` with `master`. Errors: see
    /// [`ClothSet::step_with_events`].
    pub fn step(&mut self, world: &mut PhysicsWorld, master: &Master) -> Result<CouplingReport, CouplingError> {
        self.step_with_events(world, master, &(), &())
    }

    /// As [`ClothSet::step`], with rapier's physics hooks (filters and
    /// contact modifications of body-body pairs, in every rapier step)
    /// and event handler. The iterated master steps rapier once a pass:
    /// `events` hears only the accepted pass, after it, with the contact
    /// pairs as it left them. The others step it once.
    ///
    /// On error every cloth is back where it was, and so is the world,
    /// unless rapier's own step made a body non-finite
    /// ([`CouplingError::NonFiniteBody`]): the world is then as that step
    /// left it (only the iterated master keeps a copy of the world).
    pub fn step_with_events(
        &mut self,
        world: &mut PhysicsWorld,
        master: &Master,
        hooks: &dyn PhysicsHooks,
        events: &dyn EventHandler,
    ) -> Result<CouplingReport, CouplingError> {
        let h = world.integration_parameters.dt;
        if !(h.is_finite() && h > 0.0) {
            return Err(CouplingError::Params { field: "dt", message: format!("must be finite and > 0, got {h}") });
        }
        match master {
            Master::Iterated(p) => check_iterated(p)?,
            Master::Monolithic(p) => crate::monolithic::check(p)?,
            Master::Staggered => {}
        }
        for cloth in self.cloths_mut() {
            cloth.sync_colliders(world)?;
        }
        let coupled = self.coupled_bodies(world);
        let slots = coupled.iter().filter(|c| c.slot.is_some()).count();
        let gravity = vec_from_rapier(world.gravity);
        // First guess: each dynamic body's velocity after gravity alone.
        // (The staggered master's only guess: the cloth sees the body
        // move as if the cloth were not there.) The monolithic master's is
        // the body's velocity now: a body resting on cloth is then found
        // where it rests, not where gravity alone would take it (contacts
        // at its rim came and went every step, and a 0.2 kg box rocked at
        // 2 cm/s); the solve adds gravity and the cloth's answer.
        let mut guess = vec![0.0; 6 * slots];
        for c in &coupled {
            if let Some(s) = c.slot {
                let rb = &world.bodies[c.handle];
                let share = if matches!(master, Master::Monolithic(_)) { 0.0 } else { 1.0 };
                let v = vec_from_rapier(rb.linvel()) + gravity * (rb.gravity_scale() * h * share);
                let w = vec_from_rapier(rb.angvel());
                guess[6 * s..6 * s + 6].copy_from_slice(&[v.x, v.y, v.z, w.x, w.y, w.z]);
            }
        }
        let time_s = self.cloths_mut().next().map_or(0.0, |c| c.sim.time());
        // Only the iterated master repeats rapier's step; the others step it
        // once and need only the cloths' start.
        let saved_world = matches!(master, Master::Iterated(_)).then(|| WorldSnapshot::take(world));
        let saved_cloths: Vec<Snapshot> = self.cloths_mut().map(|c| c.sim.snapshot()).collect();
        let rollback = |set: &mut ClothSet, world: &mut PhysicsWorld| -> Result<(), CouplingError> {
            if let Some(saved) = &saved_world {
                saved.restore(world);
            }
            set.restore_cloths(&saved_cloths, time_s)
        };
        let (rollback, hooks) = (&rollback, (master, hooks));
        let result = match master {
            Master::Staggered => self.pass(world, &coupled, &guess, h, hooks).map(|pass| (1, 0.0, pass)),
            Master::Monolithic(p) => self.monolithic(world, &coupled, &mut guess, (h, p, hooks.1), &saved_cloths),
            Master::Iterated(p) => self.iterate(world, &coupled, &mut guess, (h, p, hooks.1), time_s, rollback),
        };
        match result {
            Ok((iterations, residual, pass)) => {
                pass.events.deliver(world, events);
                Ok(CouplingReport {
                    iterations,
                    converged: residual <= 1.0,
                    residual,
                    contacts: pass.solved.contacts,
                    coupled_bodies: coupled.len(),
                    cloths: pass.solved.reports,
                })
            }
            Err(e) => {
                rollback(self, world)?;
                Err(e)
            }
        }
    }

    /// Puts every cloth back to `saved` (taken at `time_s`).
    pub(crate) fn restore_cloths(&mut self, saved: &[Snapshot], time_s: f64) -> Result<(), CouplingError> {
        for (index, (c, s)) in self.cloths_mut().zip(saved).enumerate() {
            c.sim.restore(s).map_err(|e| CouplingError::Cloth { cloth: index, time_s, message: e.to_string() })?;
        }
        Ok(())
    }

    /// Passes until the end velocities agree with the guess.
    fn iterate(
        &mut self,
        world: &mut PhysicsWorld,
        coupled: &[Coupled],
        guess: &mut [f64],
        (h, p, hooks): (f64, &IteratedCoupling, &dyn PhysicsHooks),
        time_s: f64,
        rollback: &dyn Fn(&mut ClothSet, &mut PhysicsWorld) -> Result<(), CouplingError>,
    ) -> Result<(usize, f64, Pass), CouplingError> {
        let mut update = GuessUpdate::new(p.relaxation);
        let mut best = (f64::INFINITY, guess.to_vec());
        for iteration in 1..=p.max_iterations {
            if iteration > 1 {
                rollback(self, world)?;
            }
            let pass = self.pass(world, coupled, guess, h, (&Master::Iterated(*p), hooks))?;
            let end = &pass.end;
            let weight: Vec<f64> = end.iter().map(|y| 1.0 / (p.abs_tol_m_s + p.rel_tol * y.abs())).collect();
            let scaled =
                end.iter().zip(guess.iter()).zip(&weight).map(|((y, u), w)| (y - u).abs() * w).fold(0.0, f64::max);
            if scaled <= 1.0 {
                return Ok((iteration, scaled, pass));
            }
            if scaled < best.0 {
                best = (scaled, guess.to_vec());
            }
            update.next(guess, end, &weight);
        }
        if !p.accept_unconverged {
            return Err(CouplingError::NotConverged { time_s, iterations: p.max_iterations, residual: best.0 });
        }
        // Contacts that switch on and off with the guess make the interface
        // map jump, and there may be no fixed point: keep the best pass.
        rollback(self, world)?;
        guess.copy_from_slice(&best.1);
        let pass = self.pass(world, coupled, guess, h, (&Master::Iterated(*p), hooks))?;
        // That pass gave the bodies impulses that disagree with the motion
        // the cloth saw (the guess): for a body lighter than the cloth,
        // energy from nothing (a 36 mg ball on a 36 g cloth was thrown up
        // at 10 m/s). Keep the heavier side: a light body ends where the
        // guess moved it, as the cloth saw it, its end velocity rapier's
        // shifted by what the guess's mean velocity differs from rapier's
        // (its momentum off by its mass times the residual); a heavy one
        // keeps rapier's answer to the impulses (the cloth off instead).
        // (The guess is a mean velocity: set as the end velocity, a ball
        // rising at 1 m/s off the cloth kept the `g h / 2` it should have
        // lost, 25 mm/s and 7e-4 J in one 5 ms step.)
        let cloth_mass: f64 = self.cloths_mut().map(|c| c.sim.model().masses().iter().sum::<f64>()).sum();
        for c in coupled {
            if let Some(s) = c.slot
                && world.bodies[c.handle].mass() < cloth_mass
            {
                let ((v, w), (v_rapier, w_rapier)) = (mean_twist(guess, s), mean_twist(&pass.end, s));
                let rb = &mut world.bodies[c.handle];
                let v_end = vec_from_rapier(rb.linvel()) + v - v_rapier;
                let w_end = vec_from_rapier(rb.angvel()) + w - w_rapier;
                rb.set_position(pose_to_rapier(&c.start.end_pose(h, v, w)), true);
                rb.set_linvel(vec_to_rapier(v_end), true);
                rb.set_angvel(vec_to_rapier(w_end), true);
            }
        }
        Ok((p.max_iterations + 1, best.0, pass))
    }

    /// The bodies any cloth touches through a solid or holds by a pin, in a
    /// fixed order (first seen), with their starting motion.
    fn coupled_bodies(&mut self, world: &PhysicsWorld) -> Vec<Coupled> {
        let mut out: Vec<Coupled> = Vec::new();
        let mut slots = 0;
        for cloth in self.cloths_mut() {
            let bodies = cloth.solids.iter().filter_map(|s| s.body).chain(cloth.attachments.iter().map(|a| a.body));
            for handle in bodies {
                let Some(rb) = world.bodies.get(handle) else { continue };
                if out.iter().any(|c| c.handle == handle) {
                    continue;
                }
                let start = BodyStart::of(rb);
                let slot = (start.kind == Drive::Dynamic).then(|| {
                    slots += 1;
                    slots - 1
                });
                out.push(Coupled { handle, start, slot });
            }
        }
        out
    }

    /// One pass with end velocities `guess`: cloths step, bodies receive
    /// the impulses, rapier steps. Returns the end velocities and the
    /// number of cloth-body contacts. With the monolithic master the
    /// dynamic bodies join each cloth's solve, and each cloth sees the
    /// bodies as the cloths before it left them.
    pub(crate) fn pass(
        &mut self,
        world: &mut PhysicsWorld,
        coupled: &[Coupled],
        guess: &[f64],
        h: f64,
        (master, hooks): (&Master, &dyn PhysicsHooks),
    ) -> Result<Pass, CouplingError> {
        let in_solve = matches!(master, Master::Monolithic(_));
        let solved = self.solve_cloths(world, coupled, guess, h, in_solve)?;
        self.step_bodies(world, coupled, solved, h, hooks)
    }

    /// The cloths' half of a pass: every cloth steps with the bodies on
    /// `guess` (in its solve when `in_solve`), and the impulses each body
    /// took are summed.
    pub(crate) fn solve_cloths(
        &mut self,
        world: &PhysicsWorld,
        coupled: &[Coupled],
        guess: &[f64],
        h: f64,
        in_solve: bool,
    ) -> Result<Solved, CouplingError> {
        let mut seen = guess.to_vec();
        let find = |handle: RigidBodyHandle| coupled.iter().position(|c| c.handle == handle);
        let mut impulses = vec![BodyImpulse::default(); coupled.len()];
        let mut holds = vec![Vec::new(); coupled.len()];
        let mut contacts = 0;
        let mut reports = Vec::new();
        for (index, cloth) in self.cloths_mut().enumerate() {
            let twist = |c: &Coupled| c.slot.map_or((Vec3::zeros(), Vec3::zeros()), |s| mean_twist(&seen, s));
            let t = cloth.sim.time();
            let fail = |message: String| CouplingError::Cloth { cloth: index, time_s: t, message };
            for s in &cloth.solids {
                let Some(c) = s.body.and_then(find).map(|k| &coupled[k]) else { continue };
                let (v, w) = twist(c);
                let motion = c.start.motion(t, h, v, w);
                // A kinematic body's motion is known (its next pose), and
                // so is a still one's (fixed, sleeping: it does not move
                // within the step); a dynamic body's is the master's guess.
                let set = if c.start.kind != Drive::Dynamic {
                    cloth.sim.set_solid_motion_prescribed(s.solid, motion)
                } else {
                    cloth.sim.set_solid_motion(s.solid, motion)
                };
                set.map_err(|e| fail(e.to_string()))?;
            }
            let mut targets = Vec::with_capacity(cloth.attachments.len());
            for a in &cloth.attachments {
                let Some(k) = find(a.body) else { continue };
                let (v, w) = twist(&coupled[k]);
                let end = coupled[k].start.end_pose(h, v, w);
                let target = end.position + end.rotation * a.local_point;
                cloth.sim.set_pin_target(a.pin, target).map_err(|e| fail(e.to_string()))?;
                targets.push((k, a.pin, target));
            }
            // Levers of the impulses: about the centre of mass at the start,
            // or, for bodies in the solve, where the solve moved it about.
            let about: Vec<Vec3> = coupled
                .iter()
                .map(|c| match c.slot {
                    Some(s) if in_solve => c.start.com + mean_twist(&seen, s).0 * h,
                    _ => c.start.com,
                })
                .collect();
            let joined =
                if in_solve { crate::monolithic::bodies_in_solve(cloth, world, coupled, &about, h) } else { vec![] };
            cloth.sim.set_bodies(joined).map_err(|e| fail(e.to_string()))?;
            let stepped = cloth.sim.step(h);
            // Bodies join one step at a time: the next master may not be this one.
            cloth.sim.set_bodies(Vec::new()).map_err(|e| fail(e.to_string()))?;
            reports.push(stepped.map_err(|e| fail(e.to_string()))?);
            let mut got_here = vec![BodyImpulse::default(); coupled.len()];
            for s in &cloth.solids {
                let Some(k) = s.body.and_then(find) else { continue };
                let got = cloth.sim.solid_impulse(s.solid, about[k]);
                got_here[k].linear += got.linear;
                got_here[k].angular += got.angular;
                contacts += got.contacts;
                if in_solve {
                    let touching = cloth.sim.contacts().solid().iter().filter(|c| c.collider as usize == s.solid);
                    holds[k].extend(
                        touching
                            .filter(|c| c.impulse_n_s != Vec3::zeros())
                            .map(|c| Hold { lever: c.point - about[k], normal: Some(c.normal) }),
                    );
                }
            }
            for (k, pin, at) in targets {
                let j = cloth.sim.pin_reaction(pin) * h;
                got_here[k].linear += j;
                got_here[k].angular += (at - about[k]).cross(&j);
                if in_solve {
                    holds[k].push(Hold { lever: at - about[k], normal: None });
                }
            }
            for (k, j) in got_here.iter().enumerate() {
                impulses[k].linear += j.linear;
                impulses[k].angular += j.angular;
                if in_solve && let Some(s) = coupled[k].slot {
                    crate::monolithic::add_impulse(
                        world,
                        &world.bodies[coupled[k].handle],
                        j,
                        &mut seen[6 * s..6 * s + 6],
                    );
                }
            }
        }
        let mut assumed = seen;
        if in_solve {
            for c in coupled {
                if let Some(s) = c.slot {
                    let fall = crate::monolithic::free_fall(world, &world.bodies[c.handle], h);
                    (0..3).for_each(|k| assumed[6 * s + k] += fall[k]);
                }
            }
        }
        Ok(Solved { impulses, assumed, holds, contacts, reports, in_solve })
    }

    /// Rapier's half of a pass: the bodies receive the cloths' impulses
    /// and rapier steps.
    pub(crate) fn step_bodies(
        &mut self,
        world: &mut PhysicsWorld,
        coupled: &[Coupled],
        solved: Solved,
        h: f64,
        hooks: &dyn PhysicsHooks,
    ) -> Result<Pass, CouplingError> {
        let mut held = Vec::new();
        for (c, j) in coupled.iter().zip(&solved.impulses) {
            if c.slot.is_some() {
                let rb = &mut world.bodies[c.handle];
                if solved.in_solve {
                    // As the solve took it: a force over rapier's substeps.
                    held.push((c.handle, crate::monolithic::apply_as_force(rb, j, h)));
                } else {
                    rb.apply_impulse(vec_to_rapier(j.linear), true);
                    rb.apply_torque_impulse(vec_to_rapier(j.angular), true);
                }
            }
        }
        let events = crate::events::RecordedEvents::default();
        world.step_with_events(hooks, &events);
        for (handle, forces) in held {
            crate::monolithic::restore_forces(&mut world.bodies[handle], forces);
        }
        let mut end = vec![0.0; solved.assumed.len()];
        for c in coupled {
            if let Some(s) = c.slot {
                let rb = &world.bodies[c.handle];
                let v = (vec_from_rapier(rb.center_of_mass()) - c.start.com) / h;
                let turn = rotation_from_rapier(*rb.rotation()) * c.start.pose.rotation.inverse();
                let w = turn.scaled_axis() / h;
                end[6 * s..6 * s + 6].copy_from_slice(&[v.x, v.y, v.z, w.x, w.y, w.z]);
                if end[6 * s..6 * s + 6].iter().any(|x| !x.is_finite()) {
                    let time_s = self.cloths_mut().next().map_or(0.0, |c| c.sim.time() - h);
                    return Err(CouplingError::NonFiniteBody { body: c.handle, time_s });
                }
            }
        }
        Ok(Pass { end, solved, events })
    }
}

/// Body `slot`'s mean linear (m/s) and angular (rad/s) velocity over the
/// step in a guess or a pass's result (6 values per body).
pub(crate) fn mean_twist(values: &[f64], slot: usize) -> (Vec3, Vec3) {
    let at = |k: usize| Vec3::from_column_slice(&values[6 * slot + k..6 * slot + k + 3]);
    (at(0), at(3))
}

/// Checks a master's pass count (named `field`) and its agreement tolerances.
pub(crate) fn check_passes(
    field: &'static str,
    passes: usize,
    abs_tol: f64,
    rel_tol: f64,
) -> Result<(), CouplingError> {
    let bad = |field, message: String| Err(CouplingError::Params { field, message });
    if passes == 0 {
        return bad(field, "must be >= 1".into());
    }
    if !(abs_tol.is_finite() && abs_tol >= 0.0 && rel_tol.is_finite() && rel_tol >= 0.0) || abs_tol + rel_tol == 0.0 {
        return bad("abs_tol_m_s", format!("tolerances must be finite, >= 0 and not both 0: {abs_tol} and {rel_tol}"));
    }
    Ok(())
}

fn check_iterated(p: &IteratedCoupling) -> Result<(), CouplingError> {
    let bad = |field, message: String| Err(CouplingError::Params { field, message });
    check_passes("max_iterations", p.max_iterations, p.abs_tol_m_s, p.rel_tol)?;
    match p.relaxation {
        Relaxation::Fixed(w) | Relaxation::QuasiNewton { initial: w } if !(w > 0.0 && w <= 1.0) => {
            bad("relaxation", format!("omega must be in (0, 1], got {w}"))
        }
        _ => Ok(()),
    }
}
