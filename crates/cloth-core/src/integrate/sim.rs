//! A simulation: an immutable model, the explicit state, the per-step
//! inputs, an integrator, and what each step hands on (the loads, the
//! contacts, the solved state); [`Simulation::step`] runs the pipeline.

use super::loads::Loads;
use super::pipeline::{self, Parts};
use super::state::{IntegratorMemory, Snapshot};
use super::step::{Integrator, StepOutput};
use crate::contacts::{Contacts, max_penetration, particles_inside};
use crate::control::{Control, ControlError, SolidImpulse, SolidMotion};
use crate::{ClothModel, ClothState, IntegratorKind, SolverParams, StepError, StepReport, Vec3};
use std::sync::Arc;

/// Owns a model and its state and advances them in time.
#[derive(Debug)]
pub struct Simulation {
    model: Arc<ClothModel>,
    state: ClothState,
    integrator: Box<dyn Integrator>,
    solver: SolverParams,
    control: Control,
    loads: Loads,
    contacts: Contacts,
    out: StepOutput,
}

/// Builds a [`Simulation`]: BDF2 with the default [`SolverParams`] unless
/// told otherwise, starting at rest (or jittered).
#[derive(Debug)]
pub struct SimulationBuilder {
    model: Arc<ClothModel>,
    integrator: Box<dyn Integrator>,
    solver: SolverParams,
    initial_jitter_m: f64,
}

impl SimulationBuilder {
    /// The integrator (default [`IntegratorKind::Bdf2`]).
    pub fn integrator(mut self, integrator: IntegratorKind) -> Self {
        self.integrator = integrator.build();
        self
    }

    /// An integrator of the caller's own, from outside this crate: anything
    /// that implements [`Integrator`].
    pub fn custom_integrator(mut self, integrator: Box<dyn Integrator>) -> Self {
        self.integrator = integrator;
        self
    }

    /// Every solver setting (default [`SolverParams::default`]).
    pub fn solver(mut self, solver: SolverParams) -> Self {
        self.solver = solver;
        self
    }

    /// Displaces each free particle by up to `jitter_m` (m) per component,
    /// deterministically: a perfectly symmetric cloth hides instabilities.
    pub fn initial_jitter(mut self, jitter_m: f64) -> Self {
        self.initial_jitter_m = jitter_m;
        self
    }

    /// The simulation at time 0.
    pub fn build(self) -> Simulation {
        let mut sim = Simulation::with_integrator(self.model, self.integrator, self.solver);
        if self.initial_jitter_m > 0.0 {
            sim.state = ClothState::jittered(sim.model(), self.initial_jitter_m);
        }
        sim
    }
}

impl Simulation {
    /// A builder for a simulation of `model`.
    pub fn builder(model: impl Into<Arc<ClothModel>>) -> SimulationBuilder {
        SimulationBuilder {
            model: model.into(),
            integrator: IntegratorKind::Bdf2.build(),
            solver: SolverParams::default(),
            initial_jitter_m: 0.0,
        }
    }

    /// A simulation starting from the model's rest shape at time 0.
    pub fn new(model: impl Into<Arc<ClothModel>>, integrator: IntegratorKind, solver: SolverParams) -> Self {
        Self::with_integrator(model, integrator.build(), solver)
    }

    /// A simulation with any [`Integrator`], starting from the model's rest
    /// shape at time 0.
    pub fn with_integrator(
        model: impl Into<Arc<ClothModel>>,
        integrator: Box<dyn Integrator>,
        solver: SolverParams,
    ) -> Self {
        let model = model.into();
        Self {
            state: ClothState::at_rest(&model),
            control: Control::for_model(&model),
            loads: Loads::new(&model),
            contacts: Contacts::default(),
            out: StepOutput::new(model.particle_count(), model.pins().len()),
            integrator,
            solver,
            model,
        }
    }

    /// Puts `model` in place of the simulation's between steps, keeping the
    /// state, the controls and the solver's workspace: for constants that
    /// change during a run (a material's damping, tuned from outside). A
    /// model of another structure is refused
    /// ([`ClothModel::structure_differs`]). Stepping on is then the run
    /// that restores this state into a simulation built with `model`.
    pub fn replace_model(&mut self, model: impl Into<Arc<ClothModel>>) -> Result<(), StepError> {
        let model = model.into();
        if let Some(what) = self.model.structure_differs(&model) {
            return Err(StepError::ModelMismatch(what));
        }
        self.model = model;
        Ok(())
    }

    /// Advances by `h` seconds through the step's stages (the pipeline:
    /// loads, collision, assemble, solve, respond, balance, then commit
    /// and finish: the model's deformation constraints if it has them, and
    /// the stitches whose gaps have closed). On error the state is
    /// unchanged.
    pub fn step(&mut self, h: f64) -> Result<StepReport, StepError> {
        let parts = Parts {
            model: &self.model,
            state: &mut self.state,
            control: &self.control,
            solver: &self.solver,
            integrator: self.integrator.as_mut(),
            loads: &mut self.loads,
            contacts: &mut self.contacts,
            out: &mut self.out,
        };
        pipeline::step(parts, h)
    }

    /// Simulated time, s.
    pub fn time(&self) -> f64 {
        self.state.time_s
    }

    /// The model.
    pub fn model(&self) -> &Arc<ClothModel> {
        &self.model
    }

    /// The current state.
    pub fn state(&self) -> &ClothState {
        &self.state
    }

    /// The integrator's name (a scene's `simulation.integrator` for the
    /// built-in ones).
    pub fn integrator_name(&self) -> &'static str {
        self.integrator.name()
    }

    /// The contacts of the last step: the collision stage's product, with
    /// the cloth-solid contacts ([`Contacts::solid`]) and the
    /// self-collision pairs.
    pub fn contacts(&self) -> &Contacts {
        &self.contacts
    }

    /// The per-step inputs set so far.
    pub fn control(&self) -> &Control {
        &self.control
    }

    /// Sets the motion of externally driven solid `index` for the next
    /// steps (see [`Control::set_solid_motion`]).
    pub fn set_solid_motion(&mut self, index: usize, motion: SolidMotion) -> Result<(), ControlError> {
        self.control.set_solid_motion(&self.model, index, motion)
    }

    /// Sets the prescribed motion of externally driven solid `index` (see
    /// [`Control::set_solid_motion_prescribed`]).
    pub fn set_solid_motion_prescribed(&mut self, index: usize, motion: SolidMotion) -> Result<(), ControlError> {
        self.control.set_solid_motion_prescribed(&self.model, index, motion)
    }

    /// Sets where externally driven pin `index` is at the end of the next
    /// step, m (see [`Control::set_pin_target`]).
    pub fn set_pin_target(&mut self, index: usize, position: Vec3) -> Result<(), ControlError> {
        self.control.set_pin_target(&self.model, index, position)
    }

    /// Holds free particle `particle` and moves it to `target` (m) by the
    /// end of the next step, then keeps it there until moved again or let
    /// go (see [`Control::hold`]): a hand grabbing the cloth.
    pub fn hold(&mut self, particle: usize, target: Vec3) -> Result<(), ControlError> {
        self.control.hold(&self.model, particle, target)
    }

    /// Lets a held particle go; whether it was held.
    pub fn let_go(&mut self, particle: usize) -> bool {
        self.control.let_go(particle)
    }

    /// Sets the air velocity of an external wind for the next steps, m/s
    /// (see [`Control::set_wind`]).
    pub fn set_wind(&mut self, velocity: Vec3) -> Result<(), ControlError> {
        self.control.set_wind(&self.model, velocity)
    }

    /// Scales the wind's air velocity from the next step on ([`Control::set_wind_scale`]).
    pub fn set_wind_scale(&mut self, scale: f64) -> Result<(), ControlError> {
        self.control.set_wind_scale(&self.model, scale)
    }

    /// Sets external forces on every particle, N, for the next steps.
    pub fn set_external_forces(&mut self, forces: &[Vec3]) -> Result<(), ControlError> {
        self.control.set_forces(&self.model, forces)
    }

    /// Lets rigid bodies join the next steps' solves (see
    /// [`Control::set_bodies`]).
    pub fn set_bodies(&mut self, bodies: Vec<crate::BodyInSolve>) -> Result<(), ControlError> {
        self.control.set_bodies(&self.model, bodies)
    }

    /// Body `k`'s change of mean linear (m/s) and angular (rad/s) velocity
    /// over the last step from the motion set for it, as the solve found
    /// it (`M dv` is the normal and pin impulse the cloth gave it; friction
    /// comes on top, see [`crate::BodyInSolve`]). `None` when no such body took
    /// part in the last step.
    pub fn body_velocity_change(&self, k: usize) -> Option<(Vec3, Vec3)> {
        self.out.bodies.velocity_change.get(k).copied()
    }

    /// Adds solids to the model mid-run (a collider added to a world the
    /// cloth shares), keeping the state, the integrator, the solver
    /// settings and every control input. The new solids come after the
    /// model's, at indices `colliders().len()..`.
    pub fn add_solids(&mut self, solids: Vec<crate::Collider>) -> Result<(), crate::ModelError> {
        if solids.is_empty() {
            return Ok(());
        }
        let model = Arc::new((*self.model).clone().with_solids(solids)?);
        self.contacts = Contacts::default();
        self.out = StepOutput::new(model.particle_count(), model.pins().len());
        self.integrator.reset();
        self.control.grow_solids(&model);
        self.model = model;
        Ok(())
    }

    /// Removes the external forces.
    pub fn clear_external_forces(&mut self) {
        self.control.clear_forces();
    }

    /// What the cloth did to solid `index` over the last step: the
    /// impulse (N s) and the angular impulse about `about` (m), N m s,
    /// summed over its contacts at their surface points. Zero before the
    /// first step and for solids not touched.
    pub fn solid_impulse(&self, index: usize, about: Vec3) -> SolidImpulse {
        let mut out = SolidImpulse::default();
        let touched =
            |c: &&crate::contacts::SolidContact| c.collider as usize == index && c.impulse_n_s != Vec3::zeros();
        for c in self.contacts.solid().iter().filter(touched) {
            let on_solid = -c.impulse_n_s;
            out.linear += on_solid;
            out.angular += (c.point - about).cross(&on_solid);
            out.contacts += 1;
        }
        out
    }

    /// The mean force the cloth exerted on pin `index` over the last step,
    /// N (the opposite of what holds the particle on its path: a hanging
    /// cloth pulls its pins down). Zero before the first step.
    pub fn pin_reaction(&self, index: usize) -> Vec3 {
        self.out.pin_forces.get(index).map_or(Vec3::zeros(), |f| -f)
    }

    /// The mean force the cloth exerted on held particle `particle` over
    /// the last step, N (what the hand feels); `None` when it is not held.
    pub fn hold_reaction(&self, particle: usize) -> Option<Vec3> {
        let j = self.control.hold_index(particle)?;
        let f = self.out.pin_forces.get(self.model.pins().len() + j).copied().unwrap_or_default();
        Some(-f)
    }

    /// Deepest any particle is inside a solid now, m (0 when none is), with
    /// external solids where the control put them.
    pub fn max_penetration(&self) -> f64 {
        max_penetration(&self.model, &self.control, &self.state.x, self.state.time_s)
    }

    /// Every particle inside a solid now, with the solid it is deepest in,
    /// in particle order (external solids where the control put them),
    /// but for the pairs `(particle, solid)` that `held` names (a pin
    /// inside the body that holds it).
    pub fn particles_inside(&self, held: impl Fn(usize, usize) -> bool) -> Vec<crate::contacts::Inside> {
        particles_inside(&self.model, &self.control, (&self.state.x, self.state.time_s), held)
    }

    /// Where solid `index` is now: on its scene path, or, driven from
    /// outside, where its last motion took it (its start pose before any).
    /// `None` for no such solid.
    pub fn solid_pose(&self, index: usize) -> Option<crate::BodyPose> {
        let collider = self.model.colliders().get(index)?;
        let t = self.state.time_s;
        Some(match self.control.solid_motions().get(index).copied().flatten() {
            Some(motion) if collider.is_external() => motion.pose_at(t),
            _ => collider.pose(t),
        })
    }

    /// Everything needed to go on from here: the state (history
    /// included) and the integrator's memory, for rollback.
    pub fn snapshot(&self) -> Snapshot {
        Snapshot { state: self.state.clone(), integrator: self.integrator.memory() }
    }

    /// What the integrator carries from step to step now (see
    /// [`Integrator::memory`]).
    pub fn integrator_memory(&self) -> IntegratorMemory {
        self.integrator.memory()
    }

    /// Returns to a snapshot taken from a simulation of the same model and
    /// integrator. Stepping from it reproduces the original run bit for
    /// bit. A state of the wrong size or with a non-finite position or
    /// velocity is refused ([`StepError::StateMismatch`],
    /// [`StepError::NonFinite`] naming the particle), and so is another
    /// integrator's memory ([`StepError::MemoryMismatch`]).
    pub fn restore(&mut self, snapshot: &Snapshot) -> Result<(), StepError> {
        self.check_snapshot(snapshot)?;
        self.integrator.restore_memory(&snapshot.integrator)?;
        self.state.clone_from(&snapshot.state);
        Ok(())
    }

    /// Whether [`Simulation::restore`] would take `snapshot`, changing
    /// nothing: the same refusals, so that a caller restoring several
    /// simulations together can check them all before it writes any.
    pub fn check_snapshot(&self, snapshot: &Snapshot) -> Result<(), StepError> {
        self.check_state(&snapshot.state)?;
        self.integrator.memory().same_names(&snapshot.integrator)
    }

    /// Puts `state` in place of the current one, the integrator's memory
    /// as it is (a state built or edited by the caller: a jittered start,
    /// particles moved by hand). Refused as [`Simulation::restore`]
    /// refuses a snapshot's state.
    pub fn set_state(&mut self, state: &ClothState) -> Result<(), StepError> {
        self.check_state(state)?;
        // Taken up again, so that what the integrator derived from the
        // old state (an energy window) starts anew.
        self.integrator.restore_memory(&self.integrator.memory())?;
        self.state.clone_from(state);
        Ok(())
    }

    fn check_state(&self, snapshot: &ClothState) -> Result<(), StepError> {
        let n = self.model.particle_count();
        let lens = [snapshot.x.len(), snapshot.v.len(), snapshot.x_prev.len(), snapshot.v_prev.len()];
        if let Some(&got) = lens.iter().find(|&&l| l != n) {
            return Err(StepError::StateMismatch { expected: n, got });
        }
        let stitches = self.model.stitches().len();
        if snapshot.stitches_closed.len() != stitches {
            return Err(StepError::StitchStateMismatch { expected: stitches, got: snapshot.stitches_closed.len() });
        }
        if let Some((particle, quantity)) = snapshot.first_non_finite() {
            return Err(StepError::NonFinite { step: snapshot.steps, time_s: snapshot.time_s, particle, quantity });
        }
        Ok(())
    }
}
