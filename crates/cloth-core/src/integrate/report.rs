//! What one step gives back: its report, its stage times and its error.

use crate::contacts::ContactStats;
use crate::energy::EnergyReport;
use cloth_linalg::PcgError;

/// Wall time per stage of one step, s.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct StageTimes {
    /// Evaluating interaction laws on links (forces and Jacobian blocks).
    pub forces_s: f64,
    /// Gathering into the matrix and right-hand side; pin constraints.
    pub assembly_s: f64,
    /// PCG.
    pub solve_s: f64,
    /// State update and finiteness check.
    pub update_s: f64,
    /// Cloth-solid narrow phase (0 without colliders).
    pub collision_s: f64,
    /// Self-collision: spatial hash, pair tests and repulsion (0 when off).
    pub self_collision_s: f64,
}

impl std::ops::AddAssign for StageTimes {
    fn add_assign(&mut self, o: Self) {
        self.forces_s += o.forces_s;
        self.assembly_s += o.assembly_s;
        self.solve_s += o.solve_s;
        self.update_s += o.update_s;
        self.collision_s += o.collision_s;
        self.self_collision_s += o.self_collision_s;
    }
}

/// What one step did.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct StepReport {
    /// Force (and, for implicit methods, Jacobian) evaluations.
    pub force_evaluations: usize,
    /// Accepted substeps (1 except for the adaptive integrator).
    pub substeps: usize,
    /// Rejected substeps of the adaptive integrator.
    pub rejected_steps: usize,
    /// Links shortened by the deformation constraints after the step.
    pub strain_corrections: usize,
    /// PCG iterations.
    pub cg_iterations: usize,
    /// Final relative residual of PCG.
    pub rel_residual: f64,
    /// False when PCG hit `max_iter` and its last iterate was accepted.
    pub converged: bool,
    /// Time per stage.
    pub stages: StageTimes,
    /// Collision counters.
    pub contacts: ContactStats,
    /// The Newton iterations (`None` for the single linearised step).
    pub newton: Option<NewtonReport>,
    /// The step's energy balance: every step of the integrators with an
    /// assembled matrix; for the explicit ones the balance of the last
    /// [`crate::ENERGY_WINDOW`] steps, at each step whose count is a
    /// multiple of it (`None` at the others and for
    /// `backward-euler-fixed-cg`).
    pub energy: Option<EnergyReport>,
    /// BDF2 only: the step gained energy beyond what its loads explain
    /// ([`EnergyReport::flagged`](crate::EnergyReport::flagged)) and was retaken as a backward-Euler
    /// step, which also restarts BDF2's history.
    pub retaken_as_backward_euler: bool,
    /// Backward Euler (not BDF2's first and retaken steps): the single
    /// linearised step was flagged ([`EnergyReport::flagged`](crate::EnergyReport::flagged)) and the
    /// step was retaken with [`NewtonParams::auto_iterations`](crate::NewtonParams::auto_iterations) Newton
    /// iterations (reported in `newton`).
    pub retaken_with_newton: bool,
    /// Sweeps of the vertex solver (`vbd`), L-BFGS iterations of
    /// `quasi-newton`; 0 for the others.
    pub descent_iterations: usize,
}

/// What the Newton iterations of an implicit step did (see
/// [`NewtonParams::iterations`](crate::NewtonParams::iterations)).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct NewtonReport {
    /// Newton corrections after the first linearised solve.
    pub corrections: usize,
    /// Halvings of the correction by the line search, all corrections.
    pub backtracks: usize,
    /// Elastic energy evaluations of the line search.
    pub energy_evaluations: usize,
    /// Residual of the step equation at the final iterate as a distance,
    /// `max_i |r_i| a / m_i` (m; `a = dx/du`).
    pub residual_m: f64,
    /// Whether the residual met [`NewtonParams::tolerance_m`](crate::NewtonParams::tolerance_m).
    pub converged: bool,
    /// Whether the iterations ran because the run's steps are large for
    /// its material ([`NewtonParams::auto_trigger`](crate::NewtonParams::auto_trigger)), not because asked.
    pub automatic: bool,
    /// Whether the iterations ran on this step alone because its single
    /// linearised step misjudged a link's tension
    /// ([`NewtonParams::auto_trigger`](crate::NewtonParams::auto_trigger)), not because asked.
    pub struck: bool,
}

/// Why a step failed. The state is left as it was before the step.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum StepError {
    /// The step size is not a finite positive number.
    #[error("invalid time step {h} s: must be finite and > 0")]
    InvalidTimeStep {
        /// The offending step, s.
        h: f64,
    },
    /// The linear solve failed.
    #[error("step {step} (t = {time_s} s): linear solve failed: {source}")]
    Solver {
        /// Index of the failed step (1-based).
        step: u64,
        /// Time at the start of the step, s.
        time_s: f64,
        /// The solver's error.
        source: PcgError,
    },
    /// The quasi-Newton step's initial Hessian could not be factored (a
    /// free particle without mass or links).
    #[error("step {step} (t = {time_s} s): the quasi-Newton initial Hessian: {source}")]
    Factor {
        /// Index of the failed step (1-based).
        step: u64,
        /// Time at the start of the step, s.
        time_s: f64,
        /// The factor's error.
        source: cloth_linalg::CholeskyError,
    },
    /// The new state is not finite.
    #[error("step {step} (t = {time_s} s): particle {particle} has a non-finite {quantity}")]
    NonFinite {
        /// Index of the failed step (1-based).
        step: u64,
        /// Time at the start of the step, s.
        time_s: f64,
        /// First offending particle.
        particle: usize,
        /// "position" or "velocity".
        quantity: &'static str,
    },
    /// The step would leave a link far longer than any cloth stretches
    /// ([`SolverParams::blow_up_stretch`](crate::SolverParams::blow_up_stretch) times its rest length): the run
    /// has blown up, and the step is refused.
    #[error(
        "step {step} (t = {time_s} s): the link between particles {i} and {j} would be {stretch:.3e} times its rest \
         length: the cloth has blown up ([solver] blow_up_stretch = {limit})"
    )]
    BlewUp {
        /// Index of the failed step (1-based).
        step: u64,
        /// Time at the start of the step, s.
        time_s: f64,
        /// The most stretched link's particles.
        i: usize,
        /// See `i`.
        j: usize,
        /// Its length over its rest length.
        stretch: f64,
        /// The limit it passed.
        limit: f64,
    },
    /// The adaptive integrator's step size collapsed (the error could not
    /// be met), or it needed more substeps than allowed.
    #[error("step {step} (t = {time_s} s): adaptive step size fell to {h} s after {attempts} substeps")]
    StepSizeUnderflow {
        /// Index of the failed step (1-based).
        step: u64,
        /// Time reached, s.
        time_s: f64,
        /// Last step size tried, s.
        h: f64,
        /// Substeps attempted (accepted and rejected).
        attempts: usize,
    },
    /// The model asks for self-collision, which only `backward-euler`,
    /// `bdf2` (assembled), `vbd` and `quasi-newton` (in their minimisation) handle.
    #[error("integrator {integrator} does not handle self-collisions: use backward-euler, bdf2, vbd or quasi-newton")]
    SelfCollisionNeedsMatrix {
        /// The integrator's scene name.
        integrator: &'static str,
    },
    /// Bodies were set to join the solve ([`crate::Control::set_bodies`]),
    /// which only the assembled implicit steps have.
    #[error("integrator {integrator} has no linear solve for bodies to join: use backward-euler or bdf2")]
    BodiesNeedMatrix {
        /// The integrator's scene name.
        integrator: &'static str,
    },
    /// A fixed-step explicit integrator was asked for a step its seams'
    /// stitches make unstable ([`ClothModel::explicit_stitch_step_limit`](crate::ClothModel::explicit_stitch_step_limit)).
    #[error(
        "integrator {integrator} at h = {h_s} s: the seams' stitches need h < {limit_s:.3e} s with an explicit \
         integrator (stiff dashpots on light particles); use bdf2 or backward-euler"
    )]
    StitchesNeedSmallerStep {
        /// The integrator's scene name.
        integrator: &'static str,
        /// The step asked for, s.
        h_s: f64,
        /// The longest stable step, s.
        limit_s: f64,
    },
    /// A state does not fit the model.
    #[error("state has {got} particles but the model has {expected}")]
    StateMismatch {
        /// Particles in the model.
        expected: usize,
        /// Particles in the state.
        got: usize,
    },
    /// A state's stitch flags do not fit the model's seams.
    #[error("state has {got} stitch states but the model has {expected} stitches")]
    StitchStateMismatch {
        /// Stitches in the model.
        expected: usize,
        /// Flags in the state.
        got: usize,
    },
    /// A model put in place of the simulation's differs in more than its
    /// constants ([`crate::Simulation::replace_model`]).
    #[error("the new model differs in its {0}: only its constants may change between steps")]
    ModelMismatch(&'static str),
    /// A snapshot's integrator memory is not this integrator's (a
    /// snapshot of a simulation with another integrator).
    #[error("the snapshot's integrator memory holds [{got}] but this integrator's holds [{expected}]")]
    MemoryMismatch {
        /// The names this integrator's memory holds.
        expected: String,
        /// The names the snapshot's holds.
        got: String,
    },
}
