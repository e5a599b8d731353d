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
//! A term also gives its force's Jacobian, the blocks between particles
//! included ([`ForceTerm::jacobian`], over the pairs it couples,
//! [`ForceTerm::coupled_pairs`]), and the implicit steps' assembly loops
//! over the terms (the `system` module): a term assembles itself
//! ([`ForceTerm::assembly`]: the built-in ones, link by link and element
//! by element) or is assembled from its Jacobian.
//!
//! Adding an effect is one file implementing [`ForceTerm`] and one line:
//! in [`INTERNAL_TERMS`] for a built-in effect, or
//! [`crate::ClothModel::with_force_term`] (or the builder's `force_term`) from
//! outside the crate.
//!
//! External terms ([`ForceTerm::external`]: the wind's) are forces from
//! outside the cloth: every step takes them at its start, as given over the
//! step, and the energy monitor counts their work as external work.
//! Self-collision repulsion is not a term: it acts on the pairs the
//! contact stage detects each step ([`crate::Contacts`]), not on `(x, v)`
//! alone.

pub(crate) mod acting;
mod aerodynamics;
mod drag;
mod element_terms;
mod fluid;
mod gravity;
pub(crate) mod links;

pub(crate) use acting::{acting, add_external_forces, external, from_jacobian};
pub use aerodynamics::Aerodynamics;
pub use drag::Drag;
pub use element_terms::Elements;
pub use fluid::Fluid;
pub use gravity::Gravity;
pub use links::Links;
pub(crate) use links::link_energy;

pub use super::assembly::{Row, SystemTerms};
pub use super::cloth_model::{
    At, ForceBuffers, ForceTerm, Jacobian, JacobianBlocks, TermAssembly, TermScratch, VertexBlock,
};

/// The forces the cloth exerts on itself and gravity, in the order every
/// particle adds them. One line an effect.
pub const INTERNAL_TERMS: &[&dyn ForceTerm] = &[&Gravity, &Drag, &Elements, &Links];

/// The forces from outside the cloth, in the order every particle adds
/// them. One line an effect.
pub const EXTERNAL_TERMS: &[&dyn ForceTerm] = &[&Aerodynamics, &Fluid];

#[cfg(test)]
mod tests;
