//! Which terms act on a model, in the order every particle adds them:
//! the registry's built-in terms it has, then those added from outside.

use super::{At, EXTERNAL_TERMS, ForceBuffers, ForceTerm, INTERNAL_TERMS};
use crate::{ClothModel, Vec3};

/// The internal terms that act on `model`: those of [`super::INTERNAL_TERMS`] it
/// has, then those added from outside ([`ClothModel::with_force_term`]).
pub fn acting(model: &ClothModel) -> impl Iterator<Item = &dyn ForceTerm> + '_ {
    let extra = model.extra_terms().iter().map(|t| t.as_ref() as &dyn ForceTerm);
    INTERNAL_TERMS.iter().map(|t| *t as &dyn ForceTerm).chain(extra).filter(move |t| t.acts_on(model) && !t.external())
}

/// The external terms that act on `model`: those of [`super::EXTERNAL_TERMS`] it
/// has, then those added from outside.
pub fn external(model: &ClothModel) -> impl Iterator<Item = &dyn ForceTerm> + '_ {
    let extra = model.extra_terms().iter().map(|t| t.as_ref() as &dyn ForceTerm);
    EXTERNAL_TERMS.iter().map(|t| *t as &dyn ForceTerm).chain(extra).filter(move |t| t.acts_on(model) && t.external())
}

/// Adds every external term's forces at `at` to `out`, N.
pub fn add_external_forces(at: &At<'_>, scratch: &mut ForceBuffers, out: &mut [Vec3]) {
    for term in external(at.model) {
        term.add_forces(at, scratch, out);
    }
}

/// The acting terms the implicit steps assemble from their Jacobian (no
/// [`ForceTerm::assembly`] of their own).
pub fn from_jacobian(model: &ClothModel) -> impl Iterator<Item = &dyn ForceTerm> + '_ {
    acting(model).filter(|t| t.assembly().is_none())
}
