//! Every solver setting, in one place: the scene's `[solver]` table and
//! each algorithm's own table beneath it.

use crate::FieldError;
use crate::PcgParams;
use cloth_linalg::PreconditionerKind;
use serde::{Deserialize, Serialize};

/// Default of [`SolverParams::max_contact_passes`]: a safety bound, not a
/// budget. The active set must settle: a stuck contact holds the load off
/// the stuck ones behind it, so a cloth pulled across a table is released
/// one row a pass; a low cap leaves rows stuck beyond their Coulomb bound
/// and the pins pump that into the links (`docs/contacts.md`).
pub(crate) const MAX_CONTACT_PASSES: usize = 30;

/// Default of [`SolverParams::settling_iterations`].
pub(crate) const SETTLING_ITERATIONS: usize = 4;

/// Every solver setting of a simulation, in one place: the scene's
/// `[solver]` table deserialises into it (every key optional, unknown keys
/// refused). The PCG settings are shared by every assembled implicit step;
/// each algorithm's own settings are a table of their own
/// (`[solver.newton]`, `[solver.contacts]`, `[solver.adaptive]`,
/// `[solver.vbd]`, `[solver.quasi_newton]`).
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
    /// flags it ([`EnergyReport::flagged`](crate::EnergyReport::flagged)), and `backward-euler` retakes
    /// a flagged single linearised step with Newton iterations
    /// ([`StepReport::retaken_with_newton`](crate::StepReport::retaken_with_newton)). Default true.
    pub energy_guard: bool,
    /// A step that would leave any link longer than this many times its
    /// rest length fails ([`StepError::BlewUp`](crate::StepError::BlewUp)): no cloth stretches so
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
    pub vbd: VbdParams,
    /// The quasi-Newton integrator's settings (`[solver.quasi_newton]`;
    /// `quasi-newton` only).
    pub quasi_newton: QuasiNewtonParams,
}

impl SolverParams {
    /// The settings of one PCG solve.
    pub fn pcg(&self) -> PcgParams {
        PcgParams { rel_tol: self.rel_tol, max_iter: self.max_iter, preconditioner: self.preconditioner }
    }

    /// Checks every setting; the error names the first bad key under
    /// `[solver]` (such as `newton.iterations`) and what is wrong.
    pub fn validate(&self) -> Result<(), FieldError> {
        if !(self.rel_tol.is_finite() && self.rel_tol > 0.0 && self.rel_tol < 1.0) {
            return Err(FieldError::new("rel_tol", format!("must be in (0, 1), got {}", self.rel_tol)));
        }
        if self.max_iter == 0 {
            return Err(FieldError::new("max_iter", "must be >= 1"));
        }
        if self.blow_up_stretch.is_nan() || self.blow_up_stretch <= 1.0 {
            return Err(FieldError::new("blow_up_stretch", format!("must be > 1, got {}", self.blow_up_stretch)));
        }
        let within = |table: &str, r: Result<(), FieldError>| r.map_err(|e| e.within(table));
        within("newton", self.newton.validate())?;
        within("adaptive", self.adaptive.validate())?;
        within("vbd", self.vbd.validate())?;
        within("quasi_newton", self.quasi_newton.validate())
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
            vbd: VbdParams::default(),
            quasi_newton: QuasiNewtonParams::default(),
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
    /// & Witkin's single linearised step (with Newton iterations where it
    /// misjudges: [`NewtonParams::auto_trigger`]); more adds Newton corrections
    /// with a line search on the incremental potential, solids then acting
    /// as penalties and their friction as a dissipation potential (see
    /// [`NewtonReport`](crate::NewtonReport)).
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
    /// With `iterations = 1`: a step whose single linearised step
    /// misjudged some link's tension by more than this share of `k_s L`
    /// takes Newton iterations ([`NewtonParams::auto_iterations`] of them).
    /// - A step large for the material by its `k_s h^2 / m`
    ///   ([`AUTO_NEWTON_MIN_K_H2_M`]; a hanging cloth at h = 1 s is off by
    ///   86) engages them for the rest of the run (`newton_engaged`
    ///   ([`crate::Simulation::integrator_memory`])).
    /// - Any other step takes them alone when the misjudged link has an
    ///   end in contact with a solid; the others stay the single step,
    ///   bit for bit. Such a step is a solid striking the cloth by a good
    ///   part of a link length in one step: a link at rest has no
    ///   sideways stiffness in the linear step, so the struck particles
    ///   move alone and stretch their links by `sqrt(1 + (v h / L)^2)`,
    ///   more on finer meshes (`docs/results/garments-primitives.md`).
    ///   Not on steps with bodies in the solve: Newton's solids are
    ///   penalties, which give a body no impulse.
    ///
    /// 0: never. Default 0.5.
    pub auto_trigger: f64,
    /// The Newton iterations of a step [`NewtonParams::auto_trigger`]
    /// picks. Default 10.
    pub auto_iterations: usize,
}

impl Default for NewtonParams {
    fn default() -> Self {
        Self { iterations: 1, tolerance_m: 1e-6, trigger: 0.0, auto_trigger: 0.5, auto_iterations: 10 }
    }
}

impl NewtonParams {
    /// Checks the settings; names the first bad field.
    pub fn validate(&self) -> Result<(), FieldError> {
        if self.iterations == 0 {
            return Err(FieldError::new("iterations", "must be >= 1"));
        }
        if !(self.tolerance_m.is_finite() && self.tolerance_m > 0.0) {
            return Err(FieldError::new("tolerance_m", format!("must be finite and > 0, got {}", self.tolerance_m)));
        }
        if !(self.trigger.is_finite() && self.trigger >= 0.0) {
            return Err(FieldError::new("trigger", format!("must be finite and >= 0, got {}", self.trigger)));
        }
        if !(self.auto_trigger.is_finite() && self.auto_trigger >= 0.0) {
            return Err(FieldError::new("auto_trigger", format!("must be finite and >= 0, got {}", self.auto_trigger)));
        }
        if self.auto_iterations < 2 {
            return Err(FieldError::new("auto_iterations", format!("must be >= 2, got {}", self.auto_iterations)));
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
    pub fn validate(&self) -> Result<(), FieldError> {
        if !(self.error_tolerance.is_finite() && self.error_tolerance > 0.0) {
            return Err(FieldError::new(
                "error_tolerance",
                format!("must be finite and > 0, got {}", self.error_tolerance),
            ));
        }
        if self.max_substeps == 0 {
            return Err(FieldError::new("max_substeps", "must be >= 1"));
        }
        Ok(())
    }
}

/// Settings of the vertex solver (`[solver.vbd]` in a scene).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct VbdParams {
    /// Sweeps over every colour per step. Default 10.
    pub iterations: usize,
    /// Stop before `iterations` once a sweep moves no particle farther
    /// than this, m. 0 (default): always `iterations` sweeps.
    pub tolerance_m: f64,
    /// Chebyshev acceleration's estimate of the sweeps' spectral radius,
    /// in `[0, 1)`; 0 (default) turns it off. Off by default: with solid
    /// contacts it fed energy into the incline's cloth (0.9 drove it
    /// uphill; `docs/results/vbd.md`).
    pub chebyshev_rho: f64,
    /// Halve a local step until the particle's local potential falls, so
    /// that every sweep lowers the step's potential (default true).
    /// Without it a sweep over Choi & Ko's links (concave in compression)
    /// can raise the potential, and the sweeps can cycle short of the
    /// solution: a hanging strip stalled at 20 times its static sag. It
    /// costs an energy evaluation at each trial position (2.0 times the
    /// hanging cloth's step; `docs/results/vbd.md`).
    pub line_search: bool,
}

impl Default for VbdParams {
    fn default() -> Self {
        Self { iterations: 10, tolerance_m: 0.0, chebyshev_rho: 0.0, line_search: true }
    }
}

impl VbdParams {
    /// Checks the settings; names the first bad field.
    pub fn validate(&self) -> Result<(), FieldError> {
        check_iterations_and_tolerance(self.iterations, self.tolerance_m)?;
        if !(0.0..1.0).contains(&self.chebyshev_rho) {
            return Err(FieldError::new("chebyshev_rho", format!("must be in [0, 1), got {}", self.chebyshev_rho)));
        }
        Ok(())
    }
}

/// Settings of the quasi-Newton integrator (`[solver.quasi_newton]` in a
/// scene).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct QuasiNewtonParams {
    /// Most L-BFGS iterations (line searches) per step. Default 50: at 20
    /// a cloth draped on a mesh kept particles jumping at 2.8 m/s
    /// (`docs/results/quasi-newton.md`).
    pub iterations: usize,
    /// `(s, y)` pairs the L-BFGS history keeps; it restarts each step.
    /// Default 5 (Liu, Bouaziz & Kavan 2017).
    pub history: usize,
    /// Stop once the gradient of the step's potential, as a distance
    /// (`max_i |g_i| h^2 / m_i`: how far particle `i` would still move
    /// under its unbalanced force alone), is below this, m. Default 1e-6.
    pub tolerance_m: f64,
}

impl Default for QuasiNewtonParams {
    fn default() -> Self {
        Self { iterations: 50, history: 5, tolerance_m: 1e-6 }
    }
}

impl QuasiNewtonParams {
    /// Checks the settings; names the first bad field.
    pub fn validate(&self) -> Result<(), FieldError> {
        check_iterations_and_tolerance(self.iterations, self.tolerance_m)
    }
}

/// A minimiser's `iterations` (>= 1) and `tolerance_m` (finite, >= 0).
fn check_iterations_and_tolerance(iterations: usize, tolerance_m: f64) -> Result<(), FieldError> {
    if iterations == 0 {
        return Err(FieldError::new("iterations", "must be >= 1"));
    }
    if !(tolerance_m.is_finite() && tolerance_m >= 0.0) {
        return Err(FieldError::new("tolerance_m", format!("must be finite and >= 0, got {tolerance_m}")));
    }
    Ok(())
}
