//! What the cloth is: the immutable [`ClothModel`] (particles, links,
//! elements, pins, the effects a scene asked for, the sparsity pattern),
//! its topology and material, and the interaction laws with the loops that
//! evaluate them. Nothing here changes during a run.

mod assembly;
mod build;
mod build_mesh;
mod build_parts;
mod builder;
pub mod cloth_mesh;
mod cloth_model;
pub mod colouring;
pub(crate) mod constraints;
mod effects;
pub mod element_laws;
pub mod elements;
pub mod forces;
pub(crate) mod keyframes;
pub mod laws;
mod layout;
mod links;
pub(crate) mod material;
pub mod pattern;
pub(crate) mod pins;
mod queries;
pub mod seams;
mod sparsity;
mod spec;
pub mod system;
pub mod terms;
pub(crate) mod topology;
pub mod wind;

pub use builder::ModelBuilder;
pub use cloth_mesh::{ClothMesh, MeshPanel};
pub use cloth_model::ClothModel;
pub use effects::{Effect, EffectValues};
pub use layout::{MeshRange, PanelRange};
pub use links::{BendLaw, BendLink, Compression, Incidence, StretchLink};
pub use pattern::{ConeWrap, PatternMesh, PatternPiece};
pub use spec::*;
