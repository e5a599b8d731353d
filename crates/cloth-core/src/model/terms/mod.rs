//! Force terms: one effect each (gravity, drag, the links, the elements,
//! the wind's two force models), behind one trait that every solver reads
//! the same physics through.
//!
//! A term gives its potential energy, adds its forces to every particle
//! (the explicit integrators' force evaluation, [`crate::forces::forces_into`],
//! is the registry's terms in order), dissipates power, and gives the
//! per-particle block a vertex solver needs: the force on one particle
//! and `-df_i/dx_i`, `-df_i/dv_i` (Vertex Block Descent's local Newton
//! step). Sign convention as in [`crate::laws`]: forces, not gradients;
//! the stiffness block is the Hessian's diagonal block, positive
//! semidefinite where the laws make it so.
//!
//! Adding an effect is one file implementing [`ForceTerm`] and one line:
//! in [`INTERNAL_TERMS`] for a built-in effect, or
//! [`ClothModel::with_force_term`] (or the builder's `force_term`) from
//! outside the crate. The implicit steps assemble the built-in terms' laws
//! in one fused pass ([`crate::forces::assemble`]) and linearise any
//! other term on the diagonal ([`ForceTerm::fused`]).
//!
//! External terms ([`ForceTerm::external`]: the wind's) are forces from
//! outside the cloth: every step takes them at its start, as given over the
//! step, and the energy monitor counts their work as external work.
//! Self-collision repulsion is not a term: it acts on the pairs the
//! contact stage detects each step ([`crate::contacts`]), not on `(x, v)`
//! alone.

mod aerodynamics;
mod drag;
mod element_terms;
mod fluid;
mod gravity;
mod links;

pub use aerodynamics::Aerodynamics;
pub use drag::Drag;
pub use element_terms::Elements;
pub use fluid::Fluid;
pub use gravity::Gravity;
pub use links::Links;

use crate::forces::ForceBuffers;
use crate::{ClothModel, Mat3, Vec3};

/// Where the terms are evaluated: a model at positions `x` (m) and
/// velocities `v` (m/s), with its stitches' states and the air's velocity.
#[derive(Debug, Clone, Copy)]
pub struct At<'a> {
    /// The model.
    pub model: &'a ClothModel,
    /// Positions, m.
    pub x: &'a [Vec3],
    /// Velocities, m/s.
    pub v: &'a [Vec3],
    /// Of each stitch, whether it has closed ([`crate::ClothState::stitches_closed`]).
    pub stitches_closed: &'a [bool],
    /// The air's velocity, m/s: the wind's at this time
    /// ([`crate::WindProfile::velocity`]); `None` where no external term is
    /// evaluated.
    pub air_m_s: Option<Vec3>,
}

impl<'a> At<'a> {
    /// `model` at `(x, v)` with `stitches_closed`, in still air.
    pub fn new(model: &'a ClothModel, x: &'a [Vec3], v: &'a [Vec3], stitches_closed: &'a [bool]) -> Self {
        Self { model, x, v, stitches_closed, air_m_s: None }
    }

    /// The same point with the air at the model's wind velocity at time
    /// `t` (s), an external wind's from `set` (m/s), times `scale`.
    pub fn with_wind_at(self, t: f64, set: Option<Vec3>, scale: f64) -> Self {
        Self { air_m_s: self.model.wind().map(|w| w.profile.velocity(t, set) * scale), ..self }
    }
}

/// One particle's share of a term: what a vertex solver needs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VertexBlock {
    /// Force on the particle, N.
    pub force: Vec3,
    /// `-df_i/dx_i`, N/m (the energy's Hessian block where the term has an
    /// energy; its positive semidefinite part where the law's is not).
    pub stiffness: Mat3,
    /// `-df_i/dv_i`, N s/m.
    pub damping: Mat3,
    /// The part of `force` that dissipates (dampers, drag), N: the rest
    /// of a term with [`ForceTerm::vertex_energy`] is minus that energy's
    /// gradient.
    pub dissipative: Vec3,
}

impl VertexBlock {
    /// No force, no blocks.
    pub fn zero() -> Self {
        Self { force: Vec3::zeros(), stiffness: Mat3::zeros(), damping: Mat3::zeros(), dissipative: Vec3::zeros() }
    }
}

impl std::ops::AddAssign for VertexBlock {
    fn add_assign(&mut self, o: Self) {
        self.force += o.force;
        self.stiffness += o.stiffness;
        self.damping += o.damping;
        self.dissipative += o.dissipative;
    }
}

/// One effect's forces on the cloth.
pub trait ForceTerm: Send + Sync + std::fmt::Debug {
    /// The effect's name.
    fn name(&self) -> &'static str;

    /// Whether `model` has this effect: an effect the model was not built
    /// with costs nothing.
    fn acts_on(&self, model: &ClothModel) -> bool;

    /// Potential energy at `at.x`, J (0 for a force without one). Reads
    /// positions only: `at.v` may be empty.
    fn energy(&self, at: &At<'_>) -> f64;

    /// Power the term dissipates at `at.v`, W (>= 0; 0 for a conservative
    /// term).
    fn dissipation(&self, _at: &At<'_>) -> f64 {
        0.0
    }

    /// Adds the force on every particle to `out`, N, in a fixed order per
    /// particle (the same bits for any thread count), with `scratch` sized
    /// for the model.
    fn add_forces(&self, at: &At<'_>, scratch: &mut ForceBuffers, out: &mut [Vec3]);

    /// Particle `i`'s force and blocks.
    fn vertex(&self, at: &At<'_>, i: usize) -> VertexBlock;

    /// The energy of the term's parts that involve particle `i`, with `i`
    /// at `xi` and the others at `at.x`, J: what changes when `i` alone
    /// moves (a vertex solver's line search). `None` (the default) for a
    /// term without a potential: its force then counts as constant over
    /// a local step.
    fn vertex_energy(&self, _at: &At<'_>, _i: usize, _xi: Vec3) -> Option<f64> {
        None
    }

    /// [`ForceTerm::vertex`] and [`ForceTerm::vertex_energy`] at `at.x`
    /// together: a term that evaluates both from one law evaluation
    /// overrides it (a vertex solver's line search needs both every local
    /// step).
    fn vertex_with_energy(&self, at: &At<'_>, i: usize) -> (VertexBlock, Option<f64>) {
        (self.vertex(at, i), self.vertex_energy(at, i, at.x[i]))
    }

    /// Whether the implicit steps assemble this term's laws in their fused
    /// pass ([`crate::forces::assemble`]: the built-in terms). The others
    /// are linearised on the diagonal from [`ForceTerm::vertex`]: exact for
    /// a force on each particle alone.
    fn fused(&self) -> bool {
        false
    }

    /// Whether this is a force from outside the cloth (the wind's): every
    /// step takes it at the step's start, as given over the step, and
    /// the energy monitor counts its work as external work, not as
    /// potential or dissipation.
    fn external(&self) -> bool {
        false
    }
}

/// The forces the cloth exerts on itself and gravity, in the order every
/// particle adds them. One line an effect.
pub const INTERNAL_TERMS: &[&dyn ForceTerm] = &[&Gravity, &Drag, &Elements, &Links];

/// The forces from outside the cloth, in the order every particle adds
/// them. One line an effect.
pub const EXTERNAL_TERMS: &[&dyn ForceTerm] = &[&Aerodynamics, &Fluid];

/// The internal terms that act on `model`: those of [`INTERNAL_TERMS`] it
/// has, then those added from outside ([`ClothModel::with_force_term`]).
pub fn acting(model: &ClothModel) -> impl Iterator<Item = &dyn ForceTerm> + '_ {
    let extra = model.extra_terms().iter().map(|t| t.as_ref() as &dyn ForceTerm);
    INTERNAL_TERMS.iter().map(|t| *t as &dyn ForceTerm).chain(extra).filter(move |t| t.acts_on(model) && !t.external())
}

/// The external terms that act on `model`: those of [`EXTERNAL_TERMS`] it
/// has, then those added from outside.
pub fn external(model: &ClothModel) -> impl Iterator<Item = &dyn ForceTerm> + '_ {
    let extra = model.extra_terms().iter().map(|t| t.as_ref() as &dyn ForceTerm);
    EXTERNAL_TERMS.iter().map(|t| *t as &dyn ForceTerm).chain(extra).filter(move |t| t.acts_on(model) && t.external())
}

/// Adds every external term's forces at `at` to `out`, N.
pub fn add_external_forces(at: &At<'_>, scratch: &mut ForceBuffers, out: &mut [Vec3]) {
    for term in external(at.model) {
        term.add_forces(at, scratch, out);
    }
}

/// The acting terms the implicit steps linearise on the diagonal (not
/// [`ForceTerm::fused`]).
pub fn unfused(model: &ClothModel) -> impl Iterator<Item = &dyn ForceTerm> + '_ {
    acting(model).filter(|t| !t.fused())
}

/// The sum of every acting term's block at particle `i`.
pub fn vertex_block(at: &At<'_>, i: usize) -> VertexBlock {
    sum_of_blocks(acting(at.model), at, i)
}

/// The sum of `terms`' blocks at particle `i`, in their order.
pub fn sum_of_blocks<'t>(terms: impl Iterator<Item = &'t dyn ForceTerm>, at: &At<'_>, i: usize) -> VertexBlock {
    let mut total = VertexBlock::zero();
    for term in terms {
        total += term.vertex(at, i);
    }
    total
}

#[cfg(test)]
mod tests;
