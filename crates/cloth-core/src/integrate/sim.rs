//! A simulation: an immutable model, the explicit state, an integrator and
//! its scratch space.

use crate::contacts::{max_penetration, particles_inside};
use crate::control::{Control, ControlError, SolidImpulse, SolidMotion};
use crate::{ClothModel, ClothState, Integrator, IntegratorKind, SolverParams, StepError, StepReport, Vec3, Workspace};
use std::sync::Arc;

/// Owns a model and its state and advances them in time.
#[derive(Debug)]
pub struct Simulation {
    model: Arc<ClothModel>,
    state: ClothState,
    integrator: Box<dyn Integrator>,
    solver: SolverParams,
    workspace: Workspace,
    control: Control,
    /// The state at the start of the current step.
    start: ClothState,
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
            let state = ClothState::jittered(sim.model(), self.initial_jitter_m);
            sim.restore(&state).expect("a state built for this model");
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
            start: ClothState::at_rest(&model),
            workspace: Workspace::new(&model, &solver),
            control: Control::for_model(&model),
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

    /// Advances by `h` seconds, then applies the model's deformation
    /// constraints if it has them and closes the stitches whose gaps have
    /// closed. On error the state is unchanged.
    pub fn step(&mut self, h: f64) -> Result<StepReport, StepError> {
        let (model, control) = (&self.model, &self.control);
        if !control.bodies().is_empty() && !self.integrator.takes_bodies() {
            return Err(StepError::BodiesNeedMatrix { integrator: self.integrator.name() });
        }
        // The step's start, to go back to if the step blows up (into a
        // buffer kept from step to step: no allocation).
        self.start.clone_from(&self.state);
        let mut report = self.integrator.step(model, &mut self.state, control, h, &mut self.workspace, &self.solver)?;
        let limit = self.solver.blow_up_stretch;
        if let Some((stretch, i, j)) = model.most_stretched(&self.state.x).filter(|s| s.0 > limit) {
            std::mem::swap(&mut self.state, &mut self.start);
            let (step, time_s) = (self.state.steps + 1, self.state.time_s);
            return Err(StepError::BlewUp { step, time_s, i, j, stretch, limit });
        }
        let integrator = self.integrator.as_ref();
        super::finish::finish_step(model, control, integrator, &mut self.state, &mut self.workspace, &mut report, h);
        Ok(report)
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

    /// The cloth-solid contacts of the last step (point, normal, solid
    /// velocity and the normal force each exerted), sorted by particle.
    pub fn contacts(&self) -> &[crate::contacts::SolidContact] {
        &self.workspace.contacts.solid
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
    /// comes on top, see [`crate::bodies`]). `None` when no such body took
    /// part in the last step.
    pub fn body_velocity_change(&self, k: usize) -> Option<(Vec3, Vec3)> {
        self.workspace.bodies.velocity_change.get(k).copied()
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
        self.workspace = Workspace::new(&model, &self.solver);
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
        for c in self.contacts().iter().filter(|c| c.collider as usize == index && c.impulse_n_s != Vec3::zeros()) {
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
        self.workspace.pin_forces.get(index).map_or(Vec3::zeros(), |f| -f)
    }

    /// The mean force the cloth exerted on held particle `particle` over
    /// the last step, N (what the hand feels); `None` when it is not held.
    pub fn hold_reaction(&self, particle: usize) -> Option<Vec3> {
        let j = self.control.hold_index(particle)?;
        let f = self.workspace.pin_forces.get(self.model.pins().len() + j).copied().unwrap_or_default();
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

    /// A copy of the complete state (history included), for rollback.
    pub fn snapshot(&self) -> ClothState {
        self.state.clone()
    }

    /// Returns to a snapshot taken from a simulation of the same model.
    /// Stepping from it reproduces the original run bit for bit. A state of
    /// the wrong size or with a non-finite position or velocity is refused
    /// ([`StepError::StateMismatch`], [`StepError::NonFinite`] naming the
    /// particle).
    pub fn restore(&mut self, snapshot: &ClothState) -> Result<(), StepError> {
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
        self.state.clone_from(snapshot);
        if let Some(explicit) = self.workspace.explicit.as_mut() {
            explicit.end_energy_window();
        }
        Ok(())
    }
}
