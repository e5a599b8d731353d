//! What an integrator sees of a step and what it hands on: the
//! [`Integrator`] trait, the step's read-only inputs ([`Step`]), where its
//! solve writes ([`StepOutput`]), what it can do ([`Capabilities`]).
//!
//! The pipeline (`pipeline.rs`) calls the trait's stages in order; an
//! integrator fills in the ones it has. One written outside this crate
//! implements [`Integrator::name`], [`Integrator::capabilities`] and
//! [`Integrator::solve`], keeps its scratch in itself, and is handed to
//! [`crate::SimulationBuilder::custom_integrator`].

use super::body_solve::BodyBuffers;
use super::loads::Loads;
use super::state::IntegratorMemory;
use super::timer::StageTimer;
use crate::contacts::Contacts;
use crate::control::Control;
use crate::energy::EnergyReport;
use crate::{ClothModel, ClothState, SolverParams, StepError, StepReport, Vec3};

/// How an integrator treats contacts, and so what the collision stage
/// finds for it ([`Contacts`]) and how it responds after the solve.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ContactHandling {
    /// Constraints in an assembled solve (`backward-euler`, `bdf2`): solid
    /// contacts found at the step's start from predicted positions and
    /// settled as an active set, self-collision repulsion in the system,
    /// friction and the projection out of solids after the solve; the
    /// particles contacts hold restart the scheme's history.
    Constraints,
    /// Energies in a minimisation (`vbd`): each particle's surroundings
    /// (nearby solid surfaces and a ball free of any other) and the
    /// self-collision pairs, as penalties.
    Penalties,
    /// Solids after the step, at its end positions (the explicit
    /// integrators, `backward-euler-fixed-cg`, and by default one written
    /// outside the crate); no self-collision.
    AfterStep,
}

impl ContactHandling {
    /// Whether self-collision can act (in the solve or the minimisation).
    pub fn handles_self_collision(self) -> bool {
        self != ContactHandling::AfterStep
    }
}

/// What an integrator can do: the pipeline reads it to choose its stages
/// and to refuse what the integrator cannot take.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Capabilities {
    /// How it treats contacts.
    pub contacts: ContactHandling,
    /// Whether rigid bodies can join its solve ([`Control::set_bodies`]).
    pub bodies: bool,
    /// Whether it takes the loads from outside the cloth (the wind's and
    /// the control's forces) once, at the step's start ([`Step::loads`]);
    /// the explicit integrators take them at every stage instead.
    pub loads_at_start: bool,
    /// Whether it solves a linear system each step (and so takes steps
    /// far above the explicit integrators' stability limit).
    pub linear_solve: bool,
}

impl Default for Capabilities {
    /// Contacts after the step, no bodies, no loads at the start, no
    /// linear solve: what an explicit integrator from outside needs.
    fn default() -> Self {
        Self { contacts: ContactHandling::AfterStep, bodies: false, loads_at_start: false, linear_solve: false }
    }
}

/// Which attempt at a step this is: the first, or a retake asked for by
/// [`Integrator::retake`] after the first was refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Attempt {
    /// The step as the integrator takes it.
    #[default]
    First,
    /// Retaken as a backward-Euler step (BDF2's energy guard).
    AsBackwardEuler,
    /// Retaken with Newton iterations (backward Euler's energy guard).
    WithNewton,
}

/// What one step reads and never changes.
#[derive(Debug, Clone, Copy)]
pub struct Step<'a> {
    /// The model.
    pub model: &'a ClothModel,
    /// The state at the step's start.
    pub state: &'a ClothState,
    /// The per-step inputs from outside.
    pub control: &'a Control,
    /// The step, s.
    pub h: f64,
    /// Every solver setting.
    pub solver: &'a SolverParams,
    /// The loads from outside the cloth at the step's start (gathered
    /// when the integrator takes them, [`Capabilities::loads_at_start`]).
    pub loads: &'a Loads,
    /// Which attempt at the step this is.
    pub attempt: Attempt,
}

/// How the contacts' response after an assembled solve treats it
/// ([`ContactHandling::Constraints`]).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub(crate) struct Response {
    /// The time over which a force acting during the step changes the new
    /// velocity, s (`h` for backward Euler, `2h/3` for BDF2).
    pub time_s: f64,
    /// Newton corrections ran: solids were penalties, not constraints.
    pub newton: bool,
    /// The contact passes ran out while still adding contacts.
    pub unresolved: bool,
    /// Squeezed particles' friction was in the solve.
    pub squeeze_friction: bool,
}

/// Where a step's solve writes: the state at the step's end, the force
/// each pin (and each held particle) exerted on its particle over the
/// step, and the bodies in the solve. Sized for the model by the
/// simulation; the pipeline commits it.
#[derive(Debug, Clone)]
pub struct StepOutput {
    pub(crate) x: Vec<Vec3>,
    pub(crate) v: Vec<Vec3>,
    pub(crate) pin_forces: Vec<Vec3>,
    pub(crate) bodies: BodyBuffers,
    pub(crate) response: Response,
}

impl StepOutput {
    /// Buffers for a model of `particles` particles and `pins` pins.
    pub(crate) fn new(particles: usize, pins: usize) -> Self {
        Self {
            x: vec![Vec3::zeros(); particles],
            v: vec![Vec3::zeros(); particles],
            pin_forces: vec![Vec3::zeros(); pins],
            bodies: BodyBuffers::default(),
            response: Response::default(),
        }
    }

    /// Positions at the step's end, m.
    pub fn positions(&self) -> &[Vec3] {
        &self.x
    }

    /// Velocities at the step's end, m/s.
    pub fn velocities(&self) -> &[Vec3] {
        &self.v
    }

    /// Positions (m) and velocities (m/s) at the step's end, to write.
    pub fn state_mut(&mut self) -> (&mut [Vec3], &mut [Vec3]) {
        (&mut self.x, &mut self.v)
    }

    /// The mean force each pin, then each held particle, exerted on its
    /// particle over the step, N ([`crate::Simulation::pin_reaction`]):
    /// resized to `count` entries, to write.
    pub fn pin_forces_mut(&mut self, count: usize) -> &mut [Vec3] {
        self.pin_forces.resize(count, Vec3::zeros());
        &mut self.pin_forces
    }
}

/// A time integrator: the stages of a step that are its own. The
/// pipeline runs, for each attempt at a step: the loads (when
/// [`Capabilities::loads_at_start`]), the collision stage, then
/// [`Integrator::assemble`], [`Integrator::solve`], the contacts'
/// response and [`Integrator::balance`]; asks [`Integrator::retake`]
/// whether to try again; and commits [`StepOutput`] unless the step blew
/// up. Scratch lives in the integrator; what influences the next step's
/// result lives in the state or in [`Integrator::memory`].
pub trait Integrator: Send + Sync + std::fmt::Debug {
    /// The integrator's name, as reports and errors show it (a scene's
    /// `simulation.integrator` for the built-in ones).
    fn name(&self) -> &'static str;

    /// What it can do.
    fn capabilities(&self) -> Capabilities;

    /// Builds the step's system from the state, the loads and the
    /// contacts found (the implicit integrators; nothing by default).
    fn assemble(
        &mut self,
        _step: &Step<'_>,
        _contacts: &mut Contacts,
        _timer: &mut StageTimer,
    ) -> Result<(), StepError> {
        Ok(())
    }

    /// Solves the step: the state at its end and the pins' forces into
    /// `out`. On error the pipeline leaves the state as it was.
    fn solve(
        &mut self,
        step: &Step<'_>,
        contacts: &mut Contacts,
        out: &mut StepOutput,
        timer: &mut StageTimer,
    ) -> Result<StepReport, StepError>;

    /// The step's energy balance, after the contacts' response (`None` by
    /// default: not measured).
    fn balance(&mut self, _step: &Step<'_>, _contacts: &Contacts, _out: &StepOutput) -> Option<EnergyReport> {
        None
    }

    /// Whether to take the step again, and how, after an attempt that
    /// `report`s what it did (never by default).
    fn retake(
        &self,
        _step: &Step<'_>,
        _report: &StepReport,
        _contacts: &Contacts,
        _out: &StepOutput,
    ) -> Option<Attempt> {
        None
    }

    /// The step the last attempt solved was committed.
    fn committed(&mut self, _report: &StepReport) {}

    /// What it carries to the next step (nothing by default).
    fn memory(&self) -> IntegratorMemory {
        IntegratorMemory::default()
    }

    /// Takes up a memory from [`Integrator::memory`] (a restored
    /// snapshot); an error when its names are not this integrator's.
    fn restore_memory(&mut self, memory: &IntegratorMemory) -> Result<(), StepError> {
        self.memory().same_names(memory)
    }

    /// Drops scratch sized for the model (its solids changed).
    fn reset(&mut self) {}
}
