//! Linear algebra for implicit cloth: a symmetric 3x3-block sparse matrix
//! whose sparsity pattern is built once and refilled in place, and a
//! preconditioned conjugate gradient solver with Baraff & Witkin's (1998)
//! constraint filter, as used by Choi & Ko (2002, §4).
//!
//! Every parallel loop here splits work into fixed-size chunks and combines
//! partial results in chunk order, so results are bit-identical whatever the
//! number of threads.

mod block_sparse;
mod buckets;
mod cg;
mod coupled;
mod couplings;
mod envelope_cholesky;
mod filter;
mod graph_aggregation;
mod multigrid;
mod par;
mod pcg;
mod precond;
mod scalar_cholesky;

pub use block_sparse::{BlockPattern, BlockSparseMatrix, PatternError};
pub use buckets::Buckets;
pub use cg::{CgScratch, cg_fixed_iterations};
pub use coupled::{CoupledPcg, RigidCoupling, RigidLink};
pub use couplings::{Coupling, Couplings};
pub use envelope_cholesky::EnvelopeCholesky;
pub use filter::{Constraint, ConstraintFilter, FilterError};
pub use graph_aggregation::{GraphAggregation, graph_aggregation};
pub use multigrid::{Aggregation, Cycle, K_CYCLE_MIN_NODES, Multigrid, MultigridError, SMOOTHED_MIN_NODES};
pub use par::{ROW_CHUNK, dot};
pub use pcg::{Pcg, PcgError, PcgInfo, PcgParams};
pub use precond::{Preconditioner, PreconditionerKind};
pub use scalar_cholesky::{CholeskyError, ScalarCholesky};

/// A 3-vector of `f64` (one particle's position, velocity or force).
pub type Vec3 = nalgebra::Vector3<f64>;
/// A 3x3 block of `f64` (one particle-particle coupling).
pub type Mat3 = nalgebra::Matrix3<f64>;
