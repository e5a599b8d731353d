//! Collision detection for cloth. This crate holds the broad phase: a
//! voxel grid stored as a spatial hash (Zhang & Yuen 2000, as used by Choi
//! & Ko 2002 §5). Points and triangles are registered in the cubic voxels
//! they touch; candidate pairs come only from shared voxels, so the cost is
//! near-linear in the number of particles for cloth-like distributions.
//!
//! Results are sorted, so they do not depend on hashing or scheduling.

mod voxel_hash;

pub use voxel_hash::{BroadPhaseError, VoxelHash};

/// A 3-vector of `f64`.
pub type Vec3 = nalgebra::Vector3<f64>;
