//! Cloth simulation core: quad-grid topology, Choi & Ko's (2002) interaction
//! models, implicit integrators (backward Euler, BDF2) solved by filtered
//! PCG, and TOML scene files.
//!
//! Data flow of one step: [`ClothModel`] (immutable) + [`ClothState`]
//! (explicit) -> link laws ([`laws`], looped by [`forces`]) and collision
//! detection ([`contacts`], geometry from `cloth-collide`) -> system matrix
//! with a pattern built once -> PCG with pins and contacts as Baraff-Witkin
//! constraints -> friction -> new state. Units are SI throughout.

pub mod colliders;
mod constraints;
pub mod contacts;
pub mod control;
pub mod element_laws;
pub mod elements;
mod explicit;
pub mod forces;
mod integrator;
mod keyframes;
pub mod laws;
mod material;
mod matrix_free;
mod model;
mod pins;
pub mod scene;
mod sim;
mod state;
mod topology;
pub mod wind;

pub use cloth_collide::{BodyPose, ShapeSpec, VoxelHash};
pub use cloth_linalg::{PcgParams, PreconditionerKind};
pub use colliders::{Collider, ColliderSpec, CollisionSpec, SelfCollision, SelfCollisionSpec};
pub use constraints::{StrainLimitReport, apply_strain_limit};
pub use contacts::ContactStats;
pub use control::{Control, ControlError, SolidImpulse, SolidMotion};
pub use integrator::{
    BackwardEuler, Bdf2, Integrator, IntegratorKind, SolverParams, StageTimes, StepError, StepReport, Workspace,
};
pub use material::{LinkConstants, Material};
pub use model::{
    BendLaw, BendLink, ClothModel, Edge, Effects, Incidence, ModelError, ModelKind, ModelSpec, PanelRange, PinSpec,
    StrainLimit, StretchLink,
};
pub use pins::{Pin, PinMotion};
pub use sim::Simulation;
pub use state::ClothState;
pub use topology::{GridPanel, LinkType, PanelError, PanelMesh};
pub use wind::{Wind, WindProfile};

/// A 3-vector of `f64`.
pub type Vec3 = nalgebra::Vector3<f64>;
/// A 3x3 matrix of `f64`.
pub type Mat3 = nalgebra::Matrix3<f64>;
