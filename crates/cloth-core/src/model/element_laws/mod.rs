//! The element laws: pure functions from an element's corner positions
//! to its energy, forces and a positive semidefinite stiffness, one file
//! an element: Volino's membrane and bending element (his "accurate"
//! model, 2001), and Choi & Ko's arc-path triples and mesh hinges.

mod curvature;
mod dihedral;
mod hinge;
mod membrane;
mod triple;

pub use curvature::*;
pub use dihedral::*;
pub use hinge::*;
pub use membrane::*;
pub use triple::*;

use crate::{Mat3, Vec3};

/// What an element law returns for `K` corners without its matrix (for
/// explicit steps and energies: no Hessian built, none copied).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ElementForces<const K: usize> {
    /// Energy, J.
    pub energy: f64,
    /// Force on each corner, N.
    pub forces: [Vec3; K],
}

impl<const K: usize> From<ElementResponse<K>> for ElementForces<K> {
    fn from(r: ElementResponse<K>) -> Self {
        Self { energy: r.energy, forces: r.forces }
    }
}

/// What an element law returns for `K` corners.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ElementResponse<const K: usize> {
    /// Energy, J.
    pub energy: f64,
    /// Force on each corner, N.
    pub forces: [Vec3; K],
    /// `H_ab`, a positive semi-definite approximation of `d^2 E / dx_a dx_b`
    /// (so `df_a/dx_b ~ -H_ab`), N/m.
    pub hessian: [[Mat3; K]; K],
}

#[cfg(test)]
/// `x` with coordinate `c` of corner `k` moved by `d` (m): one side of a
/// central difference.
pub(crate) fn moved<const K: usize>(mut x: [Vec3; K], k: usize, c: usize, d: f64) -> [Vec3; K] {
    x[k][c] += d;
    x
}
