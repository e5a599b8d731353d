//! What one step takes and gives back: the integrator's kind, the
//! solver's parameters, the step's report and error, and the workspace
//! the integrators reuse from step to step.

use super::integrator::{BackwardEuler, Bdf2, Integrator};
use crate::contacts::{ContactBuffers, ContactStats};
use crate::energy::EnergyReport;
use crate::explicit::ExplicitBuffers;
use crate::{ClothModel, Vec3, forces::SystemBuffers};
use cloth_linalg::{ConstraintFilter, Pcg, PcgError, PcgParams, PreconditionerKind};
use serde::{Deserialize, Serialize};

/// Default of [`SolverParams::max_contact_passes`]: a safety bound, not a
/// budget. The active set must settle: a stuck contact holds the load off
/// the stuck ones behind it, so a cloth pulled across a table is released
/// one row a pass; a low cap leaves rows stuck beyond their Coulomb bound
/// and the pins pump that into the links (`docs/contacts.md`).
pub(crate) const MAX_CONTACT_PASSES: usize = 30;

/// Default of [`SolverParams::settling_iterations`].
pub(crate) const SETTLING_ITERATIONS: usize = 4;

/// Which integrator a simulation uses (scene name in brackets).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum IntegratorKind {
    /// Forward Euler (`forward-euler`): order 1, one force evaluation.
    ForwardEuler,
    /// Symplectic (semi-implicit) Euler (`symplectic-euler`): order 1.
    SymplecticEuler,
    /// Explicit midpoint (`midpoint`): order 2, two force evaluations.
    Midpoint,
    /// Classic Runge-Kutta (`rk4`): order 4, four force evaluations.
    Rk4,
    /// Dormand-Prince 5(4) with adaptive substeps (`dopri5`): order 5,
    /// error controlled by [`AdaptiveParams::error_tolerance`].
    Dopri5,
    /// Backward Euler, Baraff & Witkin (1998) (`backward-euler`): first
    /// order, strongly damping; PCG to a tolerance.
    BackwardEuler,
    /// Backward Euler with a fixed number of matrix-free, mass-scaled CG
    /// iterations (`backward-euler-fixed-cg`), Volino & Magnenat-Thalmann
    /// (2001); the count is [`SolverParams::fixed_cg_iterations`].
    BackwardEulerFixedCg,
    /// Bdf2 (`bdf2`): second-order BDF, Choi & Ko (2002) Eq. 20; starts with
    /// one backward-Euler step.
    Bdf2,
    /// Vertex Block Descent (`vbd`), Chen, Macklin et al. (2024): backward
    /// Euler's incremental potential minimised by coloured Gauss-Seidel
    /// sweeps of per-particle Newton steps ([`crate::vbd`]); the sweeps
    /// are [`SolverParams::vbd`]'s.
    Vbd,
}

impl IntegratorKind {
    /// Every kind, in the order above.
    pub const ALL: [IntegratorKind; 9] = [
        IntegratorKind::ForwardEuler,
        IntegratorKind::SymplecticEuler,
        IntegratorKind::Midpoint,
        IntegratorKind::Rk4,
        IntegratorKind::Dopri5,
        IntegratorKind::BackwardEuler,
        IntegratorKind::BackwardEulerFixedCg,
        IntegratorKind::Bdf2,
        IntegratorKind::Vbd,
    ];

    /// The integrator.
    pub fn build(self) -> Box<dyn Integrator> {
        match self {
            IntegratorKind::BackwardEuler => Box::new(BackwardEuler),
            IntegratorKind::Bdf2 => Box::new(Bdf2),
            IntegratorKind::BackwardEulerFixedCg => Box::new(crate::matrix_free::BackwardEulerFixedCg),
            IntegratorKind::Vbd => Box::new(crate::vbd::Vbd),
            explicit => Box::new(crate::explicit::Explicit(explicit)),
        }
    }

    /// Name as written in scene files.
    pub fn name(self) -> &'static str {
        match self {
            IntegratorKind::ForwardEuler => "forward-euler",
            IntegratorKind::SymplecticEuler => "symplectic-euler",
            IntegratorKind::Midpoint => "midpoint",
            IntegratorKind::Rk4 => "rk4",
            IntegratorKind::Dopri5 => "dopri5",
            IntegratorKind::BackwardEuler => "backward-euler",
            IntegratorKind::BackwardEulerFixedCg => "backward-euler-fixed-cg",
            IntegratorKind::Bdf2 => "bdf2",
            IntegratorKind::Vbd => "vbd",
        }
    }

    /// Whether the integrator solves a linear system each step.
    pub fn is_implicit(self) -> bool {
        matches!(self, IntegratorKind::BackwardEuler | IntegratorKind::BackwardEulerFixedCg | IntegratorKind::Bdf2)
    }

    /// Whether the integrator handles self-collision (inside its solve:
    /// the assembled implicit steps and the vertex solver).
    pub fn handles_self_collision(self) -> bool {
        matches!(self, IntegratorKind::BackwardEuler | IntegratorKind::Bdf2 | IntegratorKind::Vbd)
    }
}

/// Every solver setting of a simulation, in one place: the scene's
/// `[solver]` table deserialises into it (every key optional, unknown keys
/// refused). The PCG settings are shared by every assembled implicit step;
/// each algorithm's own settings are a table of their own
/// (`[solver.newton]`, `[solver.contacts]`, `[solver.adaptive]`,
/// `[solver.vbd]`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SolverParams {
    /// PCG relative tolerance (dimensionless, in (0, 1)). Default 1e-4.
    pub rel_tol: f64,
    /// PCG iteration cap. Default 1000.
    pub max_iter: usize,
    /// PCG preconditioner. Default the multigrid, built from the model's
    /// grids.
    pub preconditioner: PreconditionerKind,
    /// Accept the last PCG iterate when `max_iter` is reached (the step is
    /// then reported as unconverged) instead of failing the step.
    pub accept_unconverged: bool,
    /// CG iterations per step of `backward-euler-fixed-cg`. Default 4.
    pub fixed_cg_iterations: usize,
    /// `bdf2` retakes a step as backward Euler when the energy monitor
    /// flags it ([`EnergyReport::flagged`]), and `backward-euler` retakes
    /// a flagged single linearised step with Newton iterations
    /// ([`StepReport::retaken_with_newton`]). Default true.
    pub energy_guard: bool,
    /// A step that would leave any link longer than this many times its
    /// rest length fails ([`StepError::BlewUp`]): no cloth stretches so
    /// far, and a blown-up run would otherwise go on to the end. Default
    /// 100 (dimensionless, > 1): a large step can stretch a link tenfold
    /// for a step or two and recover (BDF2 at h = 0.2 s on the hanging
    /// cloth: 10.1, then below 1.2).
    pub blow_up_stretch: f64,
    /// Newton iterations of `backward-euler` and `bdf2` (`[solver.newton]`).
    pub newton: NewtonParams,
    /// How the implicit steps settle their solid contacts (`[solver.contacts]`).
    pub contacts: ContactSetParams,
    /// The adaptive explicit integrator's error control (`[solver.adaptive]`).
    pub adaptive: AdaptiveParams,
    /// The vertex solver's settings (`[solver.vbd]`; `vbd` only).
    pub vbd: crate::VbdParams,
}

impl SolverParams {
    /// The settings of one PCG solve.
    pub fn pcg(&self) -> PcgParams {
        PcgParams { rel_tol: self.rel_tol, max_iter: self.max_iter, preconditioner: self.preconditioner }
    }

    /// Checks every setting; the error names the first bad key under
    /// `[solver]` (such as `newton.iterations`) and what is wrong.
    pub fn validate(&self) -> Result<(), (String, String)> {
        if !(self.rel_tol.is_finite() && self.rel_tol > 0.0 && self.rel_tol < 1.0) {
            return Err(("rel_tol".into(), format!("must be in (0, 1), got {}", self.rel_tol)));
        }
        if self.max_iter == 0 {
            return Err(("max_iter".into(), "must be >= 1".into()));
        }
        if self.blow_up_stretch.is_nan() || self.blow_up_stretch <= 1.0 {
            return Err(("blow_up_stretch".into(), format!("must be > 1, got {}", self.blow_up_stretch)));
        }
        let within =
            |table: &str, r: Result<(), (&'static str, String)>| r.map_err(|(k, m)| (format!("{table}.{k}"), m));
        within("newton", self.newton.validate())?;
        within("adaptive", self.adaptive.validate())?;
        within("vbd", self.vbd.validate())
    }
}

impl Default for SolverParams {
    /// Relative tolerance 1e-4, at most 1000 iterations, the multigrid
    /// preconditioner (built from the model's grids), unconverged solves
    /// accepted and counted; each algorithm's table at its defaults.
    fn default() -> Self {
        Self {
            rel_tol: PcgParams::default().rel_tol,
            max_iter: PcgParams::default().max_iter,
            preconditioner: PreconditionerKind::Multigrid,
            accept_unconverged: true,
            fixed_cg_iterations: 4,
            energy_guard: true,
            blow_up_stretch: 100.0,
            newton: NewtonParams::default(),
            contacts: ContactSetParams::default(),
            adaptive: AdaptiveParams::default(),
            vbd: crate::VbdParams::default(),
        }
    }
}

/// The `k h^2 / m` (the stiffest link's or membrane corner's natural
/// frequency times the step, squared; [`crate::ClothModel::stiffest_per_mass`])
/// above which a step may be large for the material and
/// [`NewtonParams::auto_trigger`] checks it: the fixtures at their steps
/// reach 1.2e4 (the stiff trampoline at 1/90 s; Volino's 5 mm cantilever
/// at 5 ms, 4.4e5, is checked and never misjudged), the large steps that
/// overstretch with the single linearised step 1.3e5 (a drape at 0.2 s)
/// to 6e7 (a stiff cloth at 0.2 s).
pub const AUTO_NEWTON_MIN_K_H2_M: f64 = 3e4;

/// Newton iterations of `backward-euler` and `bdf2` (`[solver.newton]`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct NewtonParams {
    /// Most linear solves per step: 1 (default) is Choi & Ko's and Baraff
    /// & Witkin's single linearised step; more adds Newton corrections
    /// with a line search on the incremental potential, solids then acting
    /// as penalties and their friction as a dissipation potential (see
    /// [`NewtonReport`]).
    pub iterations: usize,
    /// Newton stops once the step equation's residual, as a distance
    /// (`|r_i| dx/du / m_i`, the distance a particle would still move under
    /// its unbalanced force alone), is below this everywhere, m. Default 1e-6.
    pub tolerance_m: f64,
    /// With `iterations > 1`, the Newton iterations run only on steps whose
    /// single linearised step misjudged some link's tension by more than
    /// this share of `k_s L` (its stiffness times its rest length: 0.25 is
    /// a quarter of the link's length in strain; see
    /// `newton::tension_linearisation_error`); the other steps are the
    /// single linearised step, bit for bit. 0 (default): Newton on every
    /// step. The fixtures' worst steps at 1/90 s: `docs/solvers.md`.
    pub trigger: f64,
    /// With `iterations = 1`: a step large for the material by its
    /// `k_s h^2 / m` ([`AUTO_NEWTON_MIN_K_H2_M`]) whose single linearised
    /// step misjudged some link's tension by more than this share of
    /// `k_s L` (measured at 1/90 s the fixtures' worst step is 0.45; a
    /// hanging cloth at h = 1 s reaches 86) engages Newton: from it on the
    /// run takes Newton iterations ([`NewtonParams::auto_iterations`] of
    /// them) on every step ([`crate::ClothState::newton_engaged`]). 0: never.
    /// Default 0.5.
    pub auto_trigger: f64,
    /// The Newton iterations a run takes once [`NewtonParams::auto_trigger`]
    /// engaged them. Default 10.
    pub auto_iterations: usize,
}

impl Default for NewtonParams {
    fn default() -> Self {
        Self { iterations: 1, tolerance_m: 1e-6, trigger: 0.0, auto_trigger: 0.5, auto_iterations: 10 }
    }
}

impl NewtonParams {
    /// Checks the settings; names the first bad field.
    pub fn validate(&self) -> Result<(), (&'static str, String)> {
        if self.iterations == 0 {
            return Err(("iterations", "must be >= 1".into()));
        }
        if !(self.tolerance_m.is_finite() && self.tolerance_m > 0.0) {
            return Err(("tolerance_m", format!("must be finite and > 0, got {}", self.tolerance_m)));
        }
        if !(self.trigger.is_finite() && self.trigger >= 0.0) {
            return Err(("trigger", format!("must be finite and >= 0, got {}", self.trigger)));
        }
        if !(self.auto_trigger.is_finite() && self.auto_trigger >= 0.0) {
            return Err(("auto_trigger", format!("must be finite and >= 0, got {}", self.auto_trigger)));
        }
        if self.auto_iterations < 2 {
            return Err(("auto_iterations", format!("must be >= 2, got {}", self.auto_iterations)));
        }
        Ok(())
    }

    /// Whether Newton iterations may run at all (`iterations > 1`).
    pub fn enabled(&self) -> bool {
        self.iterations > 1
    }
}

/// How the implicit steps settle their solid contacts' active set
/// (`[solver.contacts]`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ContactSetParams {
    /// Most re-solves of one step's contact active set (contacts released,
    /// added, switched between sticking and sliding). The default, 30, is a
    /// bound, not a budget: the set settles, Coulomb's bound holds. Fewer
    /// trade friction for time: where the passes run out, contacts stay
    /// stuck beyond their bound (`cloth study stability`, "pulled across a
    /// table").
    pub max_passes: usize,
    /// CG iterations of each solve while a step's contact set is still
    /// settling: the first solve of a step that starts with solid contacts
    /// and every re-solve after a pass changed the set. The set settles on
    /// these rough solves (they only decide which contacts hold, stick or
    /// slide); then one solve to `rel_tol` and a last check of the set end
    /// the step. 0: every solve to `rel_tol`. Default 4, which halves the
    /// CG iterations of the contact fixtures (`docs/contacts.md`).
    pub settling_iterations: usize,
}

impl Default for ContactSetParams {
    fn default() -> Self {
        Self { max_passes: MAX_CONTACT_PASSES, settling_iterations: SETTLING_ITERATIONS }
    }
}

/// The adaptive explicit integrator's error control (`[solver.adaptive]`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct AdaptiveParams {
    /// Local error tolerance (relative, and absolute in m and m/s).
    /// Default 1e-4.
    pub error_tolerance: f64,
    /// Most substeps (accepted plus rejected) within one step before
    /// giving up. Default 100000.
    pub max_substeps: usize,
}

impl Default for AdaptiveParams {
    fn default() -> Self {
        Self { error_tolerance: 1e-4, max_substeps: 100_000 }
    }
}

impl AdaptiveParams {
    /// Checks the settings; names the first bad field.
    pub fn validate(&self) -> Result<(), (&'static str, String)> {
        if !(self.error_tolerance.is_finite() && self.error_tolerance > 0.0) {
            return Err(("error_tolerance", format!("must be finite and > 0, got {}", self.error_tolerance)));
        }
        if self.max_substeps == 0 {
            return Err(("max_substeps", "must be >= 1".into()));
        }
        Ok(())
    }
}

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
    /// ([`EnergyReport::flagged`]) and was retaken as a backward-Euler
    /// step, which also restarts BDF2's history.
    pub retaken_as_backward_euler: bool,
    /// Backward Euler (not BDF2's first and retaken steps): the single
    /// linearised step was flagged ([`EnergyReport::flagged`]) and the
    /// step was retaken with [`NewtonParams::auto_iterations`] Newton
    /// iterations (reported in `newton`).
    pub retaken_with_newton: bool,
    /// Sweeps of the vertex solver (`vbd`; 0 for the others).
    pub descent_iterations: usize,
}

/// What the Newton iterations of an implicit step did (see
/// [`NewtonParams::iterations`]).
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
    /// Whether the residual met [`NewtonParams::tolerance_m`].
    pub converged: bool,
    /// Whether the iterations ran because the run's steps are large for
    /// its material ([`NewtonParams::auto_trigger`]), not because asked.
    pub automatic: bool,
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
    /// ([`SolverParams::blow_up_stretch`] times its rest length): the run
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
    /// `bdf2` (assembled) and `vbd` (in its sweeps) handle.
    #[error("integrator {integrator} does not handle self-collisions: use backward-euler, bdf2 or vbd")]
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
    /// stitches make unstable ([`ClothModel::explicit_stitch_step_limit`]).
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
}

/// Scratch space of the integrators, sized once per model.
#[derive(Debug, Clone)]
pub struct Workspace {
    pub(crate) system: SystemBuffers,
    pub(crate) pcg: Pcg,
    pub(crate) filter: ConstraintFilter,
    pub(crate) unknown: Vec<Vec3>,
    pub(crate) aux: Vec<Vec3>,
    pub(crate) aux2: Vec<Vec3>,
    pub(crate) new_x: Vec<Vec3>,
    pub(crate) new_v: Vec<Vec3>,
    /// Newton iterations' buffers (allocated on first use).
    pub(crate) newton: Option<crate::newton::NewtonBuffers>,
    /// External (wind) forces at the start of the step, and their scratch.
    pub(crate) external: Vec<Vec3>,
    pub(crate) external_scratch: crate::forces::ForceBuffers,
    /// Stage storage of the explicit integrators (allocated on first use).
    pub(crate) explicit: Option<ExplicitBuffers>,
    /// Buffers of the vertex solver (allocated on first use).
    pub(crate) vbd: Option<crate::vbd::VbdBuffers>,
    /// Buffers of the matrix-free solver (allocated on first use).
    pub(crate) matrix_free: Option<crate::matrix_free::MatrixFreeBuffers>,
    /// Contacts and collision scratch space.
    pub(crate) contacts: ContactBuffers,
    /// Force each pin exerted on its particle in the last step, N.
    pub(crate) pin_forces: Vec<Vec3>,
    /// Scratch of the energy monitor.
    pub(crate) energy: crate::forces::EnergyBuffers,
    /// Rigid bodies in the solve.
    pub(crate) bodies: crate::bodies::BodyBuffers,
}

impl Workspace {
    /// Buffers for `model`, and the multigrid hierarchy when `solver` asks for it.
    pub fn new(model: &ClothModel, solver: &SolverParams) -> Self {
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
            aux: vec![Vec3::zeros(); n],
            aux2: vec![Vec3::zeros(); n],
            new_x: vec![Vec3::zeros(); n],
            new_v: vec![Vec3::zeros(); n],
            newton: None,
            external: vec![Vec3::zeros(); n],
            external_scratch: crate::forces::ForceBuffers::external(model),
            explicit: None,
            matrix_free: None,
            vbd: None,
            contacts: ContactBuffers::default(),
            pin_forces: vec![Vec3::zeros(); model.pins().len()],
            energy: crate::forces::EnergyBuffers::new(model),
            bodies: Default::default(),
        }
    }
}
