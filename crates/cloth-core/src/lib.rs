//! Cloth simulation core: quad-grid topology, Choi & Ko's (2002) interaction
//! models, implicit integrators (backward Euler, BDF2) solved by filtered
//! PCG, and TOML scene files.
//!
//! Data flow of one step ([`Simulation::step`], its stages in
//! `docs/step.md`): [`ClothModel`] (immutable) + [`ClothState`] (explicit)
//! -> force terms ([`terms`], each applying its [`laws`]) and the contacts
//! ([`Contacts`], geometry from `cloth-collide`) -> system matrix with a
//! pattern built once -> PCG with pins and contacts as Baraff-Witkin
//! constraints -> friction -> new state. Units are SI throughout.
//!
//! The surface, each item by one path: the model and its builder
//! ([`ClothModel`], [`ModelBuilder`], [`ModelSpec`]), the state
//! ([`ClothState`], [`Snapshot`]), the simulation ([`Simulation`], the
//! [`Integrator`] trait and [`IntegratorKind`]), the per-step inputs from
//! outside ([`Control`]: external solids, pin targets and forces in,
//! contact impulses and pin reactions out), the scene files ([`scene`]),
//! the laws ([`laws`], [`element_laws`], [`contact_laws`], [`aero_laws`])
//! and the force-term interface ([`terms`]).

mod contact;
mod field_error;
#[cfg(test)]
mod finite_differences;
mod integrate;
mod model;
pub mod scene;
#[cfg(feature = "testing")]
pub mod testing;

// The public surface: each item by one path. The laws and the force-term
// interface are modules of their own; everything else sits at the root.
pub use contact::contact_laws;
pub use model::{aero_laws, element_laws, laws, terms};

// Short paths inside the crate (`crate::contacts`, `crate::forces`).
pub(crate) use contact::{colliders, contacts};
pub(crate) use integrate::{bodies, control, energy, params, registry, report, sim, state, step, vbd};
pub(crate) use model::{
    cloth_mesh, colouring, constraints, elements, forces, keyframes, material, pins, seams, system, topology, wind,
};

pub use cloth_collide::{BodyPose, ShapeSpec, VoxelHash};
pub use cloth_linalg::{PcgParams, PreconditionerKind};
pub use cloth_mesh::{MeshEdge, MeshHinge, MeshTopology};
pub use colliders::{
    Collider, ColliderSpec, CollisionSpec, DEFAULT_THICKNESS_M, SelfCollision, SelfCollisionSpec, rotation_from_degrees,
};
pub use constraints::{OVER_LIMIT_TOLERANCE, OverStretch, over_stretched};
pub use contacts::{
    ContactStats, Contacts, Crossing, CrossingCheck, FrictionMode, Inside, LASTING_STEPS, MEETING_FRACTION,
    MIN_SELF_GAP, SelfContact, SolidContact, TangleCounts, TangleEvent, TangleWatch, self_intersections,
};
pub use control::{Control, ControlError, SolidImpulse, SolidMotion};
pub use elements::{BendHinge, BendTriple, CurvatureElement, ElementSet, MembraneElement};
pub use energy::{BODY_GAIN_TOLERANCE, EnergyReport, GAIN_TOLERANCE};
pub use field_error::FieldError;
pub use forces::{EnergyBuffers, elastic_energy, forces_into, potential_energy, total_forces};
pub use integrate::bodies::{BodyError, BodyInSolve};
pub use integrate::explicit::ENERGY_WINDOW;
pub use integrate::implicit::{BackwardEuler, Bdf2};
pub use integrate::loads::Loads;
pub use integrate::matrix_free::BackwardEulerFixedCg;
pub use integrate::quasi_newton::QuasiNewton;
pub use integrate::snapshot_bytes::{SNAPSHOT_FORMAT_VERSION, SnapshotBytesError};
pub use integrate::timer::{Lap, Stage, StageTimer};
pub use material::{BendConstants, Compressive, Lattice, Material, Membrane};
pub use model::{
    BendLaw, BendLink, BendingLaw, ClothMesh, ClothModel, Compression, ConeWrap, Effect, EffectValues, Effects,
    Incidence, MeshPanel, MeshRange, ModelBuilder, ModelError, ModelKind, ModelSpec, PanelRange, PatternMesh,
    PatternPiece, PinSpec, StrainLimit, StretchLink,
};
pub use params::{
    AUTO_NEWTON_MIN_K_H2_M, AdaptiveParams, ContactSetParams, NewtonParams, QuasiNewtonParams, SolverParams, VbdParams,
};
pub use pins::{Pin, PinMotion};
pub use registry::IntegratorKind;
pub use report::{NewtonReport, StageTimes, StepError, StepReport};
pub use seams::{SeamSide, SeamSpec, Stitch};
pub use sim::{Simulation, SimulationBuilder};
pub use state::{ClothState, IntegratorMemory, Snapshot};
pub use step::{Attempt, Capabilities, ContactHandling, Integrator, Step, StepOutput};
pub use topology::{Diagonals, Edge, GridLink, GridPanel, LinkType, PanelMesh};
pub use vbd::Vbd;
pub use wind::{Wind, WindProfile};

// The README's Rust example, compiled and run as a doctest.
#[cfg(doctest)]
#[doc = include_str!("../../../README.md")]
pub struct ReadmeDoctests;

/// A 3-vector of `f64`.
pub type Vec3 = nalgebra::Vector3<f64>;
/// A 3x3 matrix of `f64`.
pub type Mat3 = nalgebra::Matrix3<f64>;
