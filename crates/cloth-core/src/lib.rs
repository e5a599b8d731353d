//! Cloth simulation core: quad-grid topology, Choi & Ko's (2002) interaction
//! models, implicit integrators (backward Euler, BDF2) solved by filtered
//! PCG, and TOML scene files.
//!
//! Data flow of one step: [`ClothModel`] (immutable) + [`ClothState`]
//! (explicit) -> link laws ([`laws`], looped by [`forces`]) and collision
//! detection ([`contacts`], geometry from `cloth-collide`) -> system matrix
//! with a pattern built once -> PCG with pins and contacts as Baraff-Witkin
//! constraints -> friction -> new state. Units are SI throughout.
//!
//! Layout: [`model`] (what the cloth is: model, topology, material, laws),
//! [`integrate`] (how it moves: state, integrators, the simulation, and
//! [`control`], where an outside unit plugs in: external solids, pin
//! targets and forces in, contact impulses and pin reactions out),
//! [`contact`] (what it touches), [`scene`] (TOML files).

pub mod contact;
mod field_error;
pub mod integrate;
pub mod model;
pub mod reference;
pub mod scene;

// Every module also under its own name at the root, so paths stay short
// (`cloth_core::laws`, `cloth_core::contacts`) and inside the crate too.
pub use contact::{colliders, contacts};
pub use integrate::energy::{EnergyReport, GAIN_TOLERANCE};
pub use integrate::explicit::ENERGY_WINDOW;
pub use integrate::vbd::{self, Vbd};
pub use integrate::{bodies, control};
use integrate::{energy, params, registry, report, sim, state, step};
pub use model::seams::{self, SeamSide, SeamSpec, Stitch};
pub use model::{cloth_mesh, colouring, element_laws, elements, forces, laws, system, terms, wind};
use model::{constraints, keyframes, material, pins, topology};

pub use cloth_collide::{BodyPose, ShapeSpec, VoxelHash};
pub use cloth_linalg::{PcgParams, PreconditionerKind};
pub use colliders::{Collider, ColliderSpec, CollisionSpec, SelfCollision, SelfCollisionSpec};
pub use constraints::{StrainLimitReport, apply_strain_limit};
pub use contacts::{ContactStats, Contacts};
pub use control::{Control, ControlError, SolidImpulse, SolidMotion};
pub use field_error::FieldError;
pub use integrate::bodies::{BodyError, BodyInSolve};
pub use integrate::implicit::{BackwardEuler, Bdf2};
pub use integrate::loads::Loads;
pub use integrate::matrix_free::BackwardEulerFixedCg;
pub use integrate::timer::{Lap, Stage, StageTimer};
pub use material::{BendConstants, Compressive, Lattice, Material, Membrane};
pub use model::{
    BendLaw, BendLink, BendingLaw, ClothMesh, ClothModel, Compression, ConeWrap, Effect, EffectValues, Effects,
    Incidence, MeshPanel, MeshRange, ModelBuilder, ModelError, ModelKind, ModelSpec, PanelRange, PatternPiece, PinSpec,
    StrainLimit, StretchLink,
};
pub use params::{AUTO_NEWTON_MIN_K_H2_M, AdaptiveParams, ContactSetParams, NewtonParams, SolverParams, VbdParams};
pub use pins::{Pin, PinMotion};
pub use registry::IntegratorKind;
pub use report::{NewtonReport, StageTimes, StepError, StepReport};
pub use sim::{Simulation, SimulationBuilder};
pub use state::{ClothState, IntegratorMemory, Snapshot};
pub use step::{Attempt, Capabilities, ContactHandling, Integrator, Step, StepOutput};
pub use topology::{Diagonals, Edge, GridPanel, LinkType, PanelMesh};
pub use wind::{Wind, WindProfile};

// The README's Rust example, compiled and run as a doctest.
#[cfg(doctest)]
#[doc = include_str!("../../../README.md")]
pub struct ReadmeDoctests;

/// A 3-vector of `f64`.
pub type Vec3 = nalgebra::Vector3<f64>;
/// A 3x3 matrix of `f64`.
pub type Mat3 = nalgebra::Matrix3<f64>;
