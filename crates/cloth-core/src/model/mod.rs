//! What the cloth is: the immutable [`ClothModel`] (particles, links,
//! elements, pins, the effects a scene asked for, the sparsity pattern),
//! its topology and material, and the interaction laws with the loops that
//! evaluate them. Nothing here changes during a run.

pub mod aero_laws;
mod assembly;
mod build;
mod build_mesh;
mod build_parts;
mod builder;
pub(crate) mod cloth_mesh;
mod cloth_model;
pub(crate) mod colouring;
pub(crate) mod constraints;
mod effects;
pub mod element_laws;
pub(crate) mod elements;
pub(crate) mod fast_projection;
pub(crate) mod forces;
pub(crate) mod keyframes;
pub mod laws;
mod layout;
mod links;
pub(crate) mod material;
pub(crate) mod pattern;
pub(crate) mod pins;
mod queries;
pub(crate) mod seams;
mod sparsity;
mod spec;
pub(crate) mod system;
pub mod terms;
pub(crate) mod topology;
pub(crate) mod wind;

pub use builder::ModelBuilder;
pub use cloth_mesh::{ClothMesh, MeshPanel};
pub use cloth_model::ClothModel;
pub use effects::{Effect, EffectValues};
pub use layout::{MeshRange, PanelRange};
pub use links::{BendLaw, BendLink, Compression, Incidence, StretchLink};
pub use pattern::{ConeWrap, PatternMesh, PatternPiece};
pub use spec::*;
