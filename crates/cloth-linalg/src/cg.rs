//! Plain conjugate gradients with a FIXED number of iterations on an
//! operator given as a closure (Volino & Magnenat-Thalmann 2001: implicit
//! Euler "with a fixed small number of CG iterations", the matrix-vector
//! product computed on the fly). The Baraff-Witkin filter keeps constrained
//! components at their prescribed values.

use crate::{ConstraintFilter, PcgError, PcgInfo, Vec3, par::chunk_count, par::dot_with};

/// Scratch vectors for [`cg_fixed_iterations`], sized once.
#[derive(Debug, Clone, Default)]
pub struct CgScratch {
    r: Vec<Vec3>,
    c: Vec<Vec3>,
    q: Vec<Vec3>,
    partials: Vec<f64>,
}

impl CgScratch {
    /// Scratch for `n` unknowns.
    pub fn new(n: usize) -> Self {
        Self {
            r: vec![Vec3::zeros(); n],
            c: vec![Vec3::zeros(); n],
            q: vec![Vec3::zeros(); n],
            partials: vec![0.0; chunk_count(n)],
        }
    }
}

/// Runs exactly `iterations` CG iterations on `A x = b` (fewer only if the
/// residual vanishes), starting from `x` with its constrained components
/// set by `filter`. `apply(w, y)` computes `y = A w` for the symmetric
/// positive definite `A`. `rel_residual` in the result is relative to the
/// starting residual.
pub fn cg_fixed_iterations(
    mut apply: impl FnMut(&[Vec3], &mut [Vec3]),
    b: &[Vec3],
    filter: &ConstraintFilter,
    iterations: usize,
    x: &mut [Vec3],
    scratch: &mut CgScratch,
) -> Result<PcgInfo, PcgError> {
    let n = b.len();
    assert!(x.len() == n && scratch.r.len() == n && filter.n() == n, "cg_fixed_iterations: dimension mismatch");
    let CgScratch { r, c, q, partials } = scratch;
    filter.impose(x);
    apply(x, q);
    r.iter_mut().zip(b).zip(q.iter()).for_each(|((ri, bi), qi)| *ri = bi - qi);
    filter.project(r);
    let mut rho = dot_with(r, r, partials);
    if !rho.is_finite() {
        return Err(PcgError::NonFinite { iteration: 0 });
    }
    let rho0 = rho;
    c.copy_from_slice(r);
    let mut done = 0;
    while done < iterations && rho > 0.0 {
        done += 1;
        apply(c, q);
        filter.project(q);
        let curvature = dot_with(c, q, partials);
        if !curvature.is_finite() {
            return Err(PcgError::NonFinite { iteration: done });
        }
        if curvature <= 0.0 {
            return Err(PcgError::NotPositiveDefinite { iteration: done, curvature });
        }
        let alpha = rho / curvature;
        x.iter_mut().zip(c.iter()).for_each(|(xi, ci)| *xi += ci * alpha);
        r.iter_mut().zip(q.iter()).for_each(|(ri, qi)| *ri -= qi * alpha);
        let rho_new = dot_with(r, r, partials);
        let beta = rho_new / rho;
        c.iter_mut().zip(r.iter()).for_each(|(ci, ri)| *ci = ri + *ci * beta);
        rho = rho_new;
    }
    Ok(PcgInfo {
        iterations: done,
        rel_residual: if rho0 > 0.0 { (rho / rho0).sqrt() } else { 0.0 },
        partial_refill: false,
    })
}
