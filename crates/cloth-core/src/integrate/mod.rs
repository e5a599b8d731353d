//! How the cloth moves: the explicit [`crate::ClothState`], the per-step
//! [`control`] inputs from outside (where a co-simulation unit or a rigid
//! body engine plugs in), the step's stages (`pipeline.rs`: loads,
//! collision, assemble, solve, respond, balance, commit, finish), the
//! integrators behind the [`crate::Integrator`] trait (implicit with
//! filtered PCG, explicit, matrix-free, the vertex solver [`vbd`], the
//! quasi-Newton minimisation [`quasi_newton`]) found by
//! name in a registry, and [`crate::Simulation`], which owns model, state,
//! control, the integrator and what each stage hands on.

pub(crate) mod bodies;
pub(crate) mod body_solve;
pub(crate) mod control;
pub(crate) mod energy;
pub(crate) mod explicit;
pub(crate) mod implicit;
pub(crate) mod loads;
pub(crate) mod matrix_free;
pub(crate) mod params;
pub(crate) mod pipeline;
pub(crate) mod quasi_newton;
pub(crate) mod registry;
pub(crate) mod report;
pub(crate) mod sim;
pub(crate) mod snapshot_bytes;
pub(crate) mod state;
pub(crate) mod step;
pub(crate) mod timer;
pub(crate) mod vbd;
