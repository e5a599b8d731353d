//! What the implicit steps' stages share: their scratch (sized once per
//! model), the view of a step's buffers they work on, the step's fixed
//! inputs, and which loads the assembled system carries.

use crate::contacts::Contacts;
use crate::forces::EnergyBuffers;
use crate::integrate::step::{Step, StepOutput};
use crate::system::SystemBuffers;
use crate::{ClothModel, Mat3, SolverParams, Vec3};
use cloth_linalg::{ConstraintFilter, Pcg, PreconditionerKind};

/// The loads the assembled system carries besides the links: which of
/// `Scratch::external`, the contacts' self-collision stiffness and
/// squeezed particles' friction hold anything this step.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct SystemLoads {
    /// `Scratch::external` holds forces (wind, control, self-collision,
    /// squeezed particles' sliding friction).
    pub(crate) external: bool,
    /// `Contacts::self_stiffness` holds self-collision stiffness.
    pub(crate) self_collision: bool,
    /// `Contacts::friction_damping` holds friction of squeezed particles.
    pub(crate) squeeze_friction: bool,
}

/// Scratch of the implicit steps, sized once per model.
#[derive(Debug)]
pub(crate) struct Scratch {
    pub(crate) system: SystemBuffers,
    pub(crate) pcg: Pcg,
    pub(crate) filter: ConstraintFilter,
    pub(crate) unknown: Vec<Vec3>,
    /// The solver's couplings times `unknown` after the last solve
    /// (zero when it had none): the part of `(A + E) x` off the matrix.
    pub(crate) coupled: Vec<Vec3>,
    pub(crate) aux: Vec<Vec3>,
    pub(crate) aux2: Vec<Vec3>,
    /// Newton iterations' buffers (allocated on first use).
    pub(crate) newton: Option<NewtonBuffers>,
    /// The forces the system carries at the step's start, N (see
    /// [`SystemLoads::external`]).
    pub(crate) external: Vec<Vec3>,
    /// Scratch of the energy monitor.
    pub(crate) energy: EnergyBuffers,
    /// Which loads the current attempt's system carries.
    pub(crate) loads: SystemLoads,
    /// The scheme's force coefficient `c_f` of the current attempt.
    pub(crate) force_coefficient: f64,
    /// Kinetic, elastic and gravitational energy at the step's start, J.
    pub(crate) energy_before: (f64, f64, f64),
}

impl Scratch {
    /// Buffers for `model`, and the multigrid hierarchy when `solver` asks for it.
    pub(crate) fn new(model: &ClothModel, solver: &SolverParams) -> Self {
        let n = model.particle_count();
        let mut pcg = Pcg::new(n);
        if solver.preconditioner == PreconditionerKind::Multigrid {
            pcg.set_multigrid(model.multigrid());
        }
        Self {
            system: SystemBuffers::new(model),
            pcg,
            filter: ConstraintFilter::new(n),
            unknown: vec![Vec3::zeros(); n],
            coupled: vec![Vec3::zeros(); n],
            aux: vec![Vec3::zeros(); n],
            aux2: vec![Vec3::zeros(); n],
            newton: None,
            external: vec![Vec3::zeros(); n],
            energy: EnergyBuffers::new(model),
            loads: SystemLoads::default(),
            force_coefficient: 0.0,
            energy_before: (0.0, 0.0, 0.0),
        }
    }
}

/// The implicit steps' view of a step's buffers: their scratch, the
/// contacts and the output.
pub(crate) struct Workspace<'a> {
    pub(crate) s: &'a mut Scratch,
    pub(crate) contacts: &'a mut Contacts,
    pub(crate) out: &'a mut StepOutput,
}

/// What one attempt of a [`Linearised`] scheme reads and never changes:
/// the scheme, the model, the state at the step's start, the control
/// inputs, the step size (s) and the solver settings.
pub(crate) struct StepInputs<'a, S> {
    pub(crate) scheme: &'a S,
    pub(crate) model: &'a ClothModel,
    pub(crate) state: &'a crate::ClothState,
    pub(crate) control: &'a crate::Control,
    pub(crate) h: f64,
    pub(crate) solver: &'a SolverParams,
}

impl<S> Clone for StepInputs<'_, S> {
    fn clone(&self) -> Self {
        *self
    }
}

impl<S> Copy for StepInputs<'_, S> {}

impl<'a, S> StepInputs<'a, S> {
    pub(crate) fn of(scheme: &'a S, step: &Step<'a>, solver: &'a SolverParams) -> Self {
        let Step { model, state, control, h, .. } = *step;
        Self { scheme, model, state, control, h, solver }
    }
}

/// Scratch of the Newton iterations, sized once per model.
#[derive(Debug, Clone)]
pub(crate) struct NewtonBuffers {
    pub(super) energy: EnergyBuffers,
    /// The iterate's unknown, positions and velocities.
    pub(super) u: Vec<Vec3>,
    pub(super) x: Vec<Vec3>,
    pub(super) v: Vec<Vec3>,
    /// `y0 - u` at the iterate (the residual's mass term).
    pub(super) y: Vec<Vec3>,
    /// Positions of a line-search trial.
    pub(super) trial: Vec<Vec3>,
    /// External forces and diagonal damping of the iterate's assembly:
    /// the step's plus the held particles' linearised friction.
    pub(super) external: Vec<Vec3>,
    pub(super) damping: Vec<Mat3>,
    /// Diagonal stiffness of the iterate's assembly: self-collision's
    /// (of the start of the step) and the solids' penalties.
    pub(super) stiffness: Vec<Mat3>,
    /// Per particle, up to two `(solid, normal force in N)`: the normal
    /// forces friction uses, frozen between updates (`u32::MAX`: none).
    pub(super) lagged: Vec<[(u32, f64); 2]>,
}
