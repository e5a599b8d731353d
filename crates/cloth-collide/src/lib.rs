//! Collision detection for cloth.
//!
//! - Broad phase: a voxel grid stored as a spatial hash (Zhang & Yuen
//!   2000, as used by Choi & Ko 2002 §5). Points and triangles are
//!   registered in the cubic voxels they touch; candidate pairs come only
//!   from shared voxels, so the cost is near-linear in the number of
//!   particles for cloth-like distributions. Used for self-collision.
//! - Continuous detection between moving triangles ([`point_triangle_impact`],
//!   [`edge_edge_impact`]) over the swept boxes of a [`BoxGrid`].
//! - Narrow phase against solids: [`SolidShape`] (ball, cuboid, capsule,
//!   cylinder, convex hull, OBJ triangle mesh, half-space) gives the signed
//!   distance, closest point and outward normal through parry (f64).
//!
//! - Readers of the surfaces cloth and solids come from: OBJ and glTF.
//!
//! Results are sorted, so they do not depend on hashing or scheduling.

mod box_grid;
mod ccd;
mod cell;
mod collider;
mod gltf_mesh;
mod obj;
mod patch_tree;
mod triangle;
mod voxel_hash;

pub use box_grid::{Aabb, BoxGrid};
pub use ccd::{Path, edge_edge_impact, point_triangle_impact, segment_crosses_triangle, segment_distance};
pub use collider::{BodyPose, ShapeError, ShapeSpec, SolidShape, SurfacePoint};
pub use gltf_mesh::{GltfError, parse_gltf, read_gltf};
pub use obj::{ObjError, SurfaceMesh, parse_obj, parse_obj_points};
pub use patch_tree::{PatchTask, PatchTree, share_a_corner};
pub use triangle::closest_point_on_triangle;
pub use voxel_hash::{BroadPhaseError, TRIANGLE_GROUP, VoxelHash};

/// A 3-vector of `f64`.
pub type Vec3 = nalgebra::Vector3<f64>;

/// Runs `f`, turning a panic into its message: for third-party code that
/// panics on some inputs it should refuse (spade's refinement on a few
/// outlines, gltf-json's validation on a dangling accessor), so the
/// caller can refuse them as errors instead.
pub fn catch_panic<T>(f: impl FnOnce() -> T) -> Result<T, String> {
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(f)).map_err(|panic| {
        panic
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| panic.downcast_ref::<String>().cloned())
            .unwrap_or_default()
    })
}
