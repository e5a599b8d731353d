//! What the workspace's tests and benchmarks reach inside the crate
//! (feature `testing`): the implicit system's assembly, the element and
//! link evaluations, the strain limiter, and analytic references to
//! compare runs with. Not a stable surface: a user of the library needs
//! none of it.

pub mod reference;

pub use crate::constraints::{StrainLimitReport, apply_strain_limit};
pub use crate::elements::{ElementBuffers, evaluate};
pub use crate::system::{SystemBuffers, assemble};
pub use crate::terms::acting::add_external_forces;
pub use crate::terms::links::{LinkEval, eval_link, link_force};
