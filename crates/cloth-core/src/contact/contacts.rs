//! Collision detection and response (Choi & Ko 2002 §5 with Baraff &
//! Witkin's 1998 constraints):
//!
//! - Cloth-solid, implicit step: a particle whose predicted position
//!   `x + h (2v - v_prev)` comes within the thickness of a solid gets the
//!   normal component of its unknown prescribed (two components against
//!   two solids), so it ends the step on the offset surface, moving with
//!   the solid. After a solve, the constraint force is read from the
//!   unfiltered residual: contacts that pull are released, free particles
//!   that ended inside are added, and the system is solved again
//!   (`release_pulling`, `add_penetrating`); `project_out` is the
//!   last safety net. Friction then removes tangential velocity relative
//!   to the solid, at most `mu |f_n| tau / m` (Coulomb), all of it when
//!   that suffices (the static regime) (`apply_friction`).
//! - Cloth-solid in Newton iterations (`solver.newton.iterations > 1`):
//!   after the first solve the solids act as a stiff penalty energy
//!   ([`contact_penalty`], `penalty_contacts`) and their friction as a
//!   smoothed Coulomb dissipation potential ([`smoothed_friction`]), both
//!   inside the minimisation (see the `newton` module); `apply_friction`
//!   then only stops the smoothing's creep.
//! - Cloth-solid without an assembled matrix (explicit, fixed-CG):
//!   `collide_after_step`.
//! - Self-collision: particle-particle and particle-triangle repulsion
//!   ([`crate::laws::repulsion`]) found through the voxel hash at the start of the
//!   step, applied with its Jacobian along the repelling direction only,
//!   and `separate_self_contacts` after the step; then, with
//!   `continuous`, no particle or edge may pass through the cloth during
//!   the step (`untangle_step`: continuous detection, rigid impact zones).
//!
//! Everything is evaluated in a fixed particle order (or reduced exactly),
//! so results do not depend on the number of threads.
//!
//! One file a part, beside this one in `contact/`: `types` (contacts,
//! counters, buffers), `detect`, `active_set`, `contact_laws`, `penalty`
//! (the Newton path), `response` (after the solve), `projection` and
//! `self_collision`; this module gathers them.

// What a user of the library sees: the contacts a step reports, the
// counters, and the contact laws.
pub(crate) use super::contact_laws::*;
pub use super::crossings::{Crossing, CrossingCheck, self_intersections};
pub use super::impact_zones::MEETING_FRACTION;
pub use super::projection::Inside;
pub use super::self_collision::MIN_SELF_GAP;
pub use super::tangles::{LASTING_STEPS, TangleCounts, TangleEvent, TangleWatch};
pub use super::types::{ContactStats, Contacts, FrictionMode, SelfContact, SolidContact};

// The steps' drivers, for the integrators of this crate.
pub(crate) use super::active_set::*;
pub(crate) use super::detect::*;
pub(crate) use super::impact_zones::*;
pub(crate) use super::penalty::*;
pub(crate) use super::projection::*;
pub(crate) use super::response::*;
pub(crate) use super::scratch::*;
pub(crate) use super::self_collision::*;
pub(crate) use super::surroundings::*;

#[cfg(test)]
#[path = "contact_tests.rs"]
mod tests;
