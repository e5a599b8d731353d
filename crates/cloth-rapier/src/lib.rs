//! Cloth coupled both ways with rapier rigid bodies (rapier3d-f64 0.36).
//!
//! - [`ClothSet`] holds cloths next to a rapier [`PhysicsWorld`]'s
//!   `RigidBodySet`; [`ClothBuilder`] makes one from a
//!   [`cloth_core::ClothModel`], attaching pins to bodies.
//! - [`ClothSet::step`] steps cloths and bodies together with a
//!   [`Master`]: staggered (one pass) or iterated to agreement (see
//!   [`coupling`]). Cloth particles collide with the world's colliders
//!   (any parry shape rapier accepts, meshes included) of fixed, kinematic
//!   and dynamic bodies; contact impulses (friction included) and the pull
//!   on attached pins go back to the bodies.
//! - [`Rig`] is a character rig read from URDF and posed by forward
//!   kinematics ([`rig`]); [`motion`] plays BVH ([`bvh`]) or keyframe
//!   clips on it (retargeted, interpolated, looped, blended in from rest);
//!   [`character::RigBodies`] puts its links in a world as kinematic
//!   bodies; a scene's `[rig]` section ([`rig_scene`]) does all three.
//! - [`RapierUnit`] is a rapier world as a co-simulation unit for
//!   `cloth-cosim`'s masters.
//!
//! rapier's math is glam (through its `math` re-exports); the cloth's is
//! nalgebra. [`convert`] converts at the boundary. Units are SI.

pub mod bvh;
pub mod character;
pub mod cloth_set;
pub mod convert;
pub mod coupling;
mod events;
mod monolithic;
pub mod motion;
mod names;
pub mod rig;
pub mod rig_scene;
pub mod run_control;
pub mod scene;
pub mod unit;
pub mod world;

pub use cloth_set::{Attachment, ClothBuilder, ClothHandle, ClothSet, CoupledCloth, CoupledSnapshot, CouplingError};
pub use coupling::{CouplingReport, IteratedCoupling, Master, MonolithicCoupling};
pub use monolithic::gravity_share;
pub use rapier3d_f64;
pub use rapier3d_f64::prelude::PhysicsWorld;
pub use rig::{JointKind, JointValue, Rig, RigError, RigOptions, RigPose, UpAxis};
pub use run_control::{ClothLoad, RunControlError};
pub use scene::{CoupledRun, CoupledScene};
pub use unit::RapierUnit;
pub use world::{CollideWith, Momentum, WorldSnapshot, WorldSolid, bodies_momentum, import_colliders};
