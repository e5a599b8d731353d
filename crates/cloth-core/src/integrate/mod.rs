//! How the cloth moves: the explicit [`crate::ClothState`], the per-step
//! [`control`] inputs from outside (where a co-simulation unit or a rigid
//! body engine plugs in), the integrators behind the [`crate::Integrator`]
//! trait (implicit with filtered PCG, explicit, matrix-free, the vertex
//! solver [`vbd`]), and
//! [`crate::Simulation`], which owns model, state, control and workspace.

pub mod bodies;
pub mod control;
pub(crate) mod energy;
pub(crate) mod explicit;
pub(crate) mod finish;
pub(crate) mod integrator;
pub(crate) mod matrix_free;
pub(crate) mod newton;
pub(crate) mod settle;
pub(crate) mod sim;
pub(crate) mod state;
pub(crate) mod step_types;
pub mod vbd;
