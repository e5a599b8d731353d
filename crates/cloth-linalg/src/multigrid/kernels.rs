//! The cycle's kernels: damped block-Jacobi (single blocks or pairs),
//! the Galerkin block sum, restriction.

use super::*;
use crate::par::ROW_CHUNK;
use crate::{BlockSparseMatrix, Mat3, Vec3};

/// `inv[i] = omega * A_ii^-1` (identity where a block is not positive definite).
pub(super) fn inverse_diagonal(a: &BlockSparseMatrix, omega: f64, inv: &mut [Mat3]) {
    inv.par_iter_mut().enumerate().with_min_len(ROW_CHUNK).for_each(|(i, p)| {
        *p = inverse_diagonal_block(a, omega, i);
    });
}

/// `omega * A_ii^-1` (the identity where the block is not positive definite).
pub(super) fn inverse_diagonal_block(a: &BlockSparseMatrix, omega: f64, i: usize) -> Mat3 {
    inverse_block(a.diag(i), omega)
}

/// `omega * d^-1` (the identity where `d` is not positive definite).
pub(super) fn inverse_block(d: &Mat3, omega: f64) -> Mat3 {
    d.cholesky().map_or_else(Mat3::identity, |c| c.inverse()) * omega
}

/// The pairs' damped inverse blocks (see [`invert_pair`]), over `inv_diag`'s
/// point blocks.
pub(super) fn invert_pairs(
    a: &BlockSparseMatrix,
    omega: f64,
    partner: &[u32],
    inv_diag: &mut [Mat3],
    inv_off: &mut [Mat3],
) {
    for (i, &j) in partner.iter().enumerate() {
        if j as usize > i {
            invert_pair(a, omega, (i, j as usize), no_extra(), inv_diag, inv_off);
        }
    }
}

/// No addition to a pair's diagonal blocks (see [`invert_pair`]).
pub(super) fn no_extra() -> (Mat3, Mat3) {
    (Mat3::zeros(), Mat3::zeros())
}

/// The pair `i < j`'s damped inverse `omega [A_ii + e_i, A_ij; A_ji, A_jj +
/// e_j]^-1` into the diagonal and off-diagonal slots, `(e_i, e_j) =
/// extra` (zero but where couplings stiffen the smoother). A pair whose
/// block is not positive definite (or not stored) keeps its two point
/// blocks in `inv_diag` and no coupling.
pub(super) fn invert_pair(
    a: &BlockSparseMatrix,
    omega: f64,
    (i, j): (usize, usize),
    extra: (Mat3, Mat3),
    inv_diag: &mut [Mat3],
    inv_off: &mut [Mat3],
) {
    (inv_off[i], inv_off[j]) = (Mat3::zeros(), Mat3::zeros());
    let Some(slot) = a.pattern().slot(i, j) else { return };
    let mut m = nalgebra::Matrix6::<f64>::zeros();
    let (aij, aji) = (a.values()[slot], a.values()[slot].transpose());
    m.fixed_view_mut::<3, 3>(0, 0).copy_from(&(a.diag(i) + extra.0));
    m.fixed_view_mut::<3, 3>(0, 3).copy_from(&aij);
    m.fixed_view_mut::<3, 3>(3, 0).copy_from(&aji);
    m.fixed_view_mut::<3, 3>(3, 3).copy_from(&(a.diag(j) + extra.1));
    let Some(c) = m.cholesky() else { return };
    let inv = c.inverse() * omega;
    inv_diag[i] = inv.fixed_view::<3, 3>(0, 0).into_owned();
    inv_off[i] = inv.fixed_view::<3, 3>(0, 3).into_owned();
    inv_off[j] = inv.fixed_view::<3, 3>(3, 0).into_owned();
    inv_diag[j] = inv.fixed_view::<3, 3>(3, 3).into_owned();
}

/// `coarse`'s blocks as the sums of the fine blocks `block(s)` over each
/// coarse slot's fine slots `s`, in `slots`' order, parallel over slots.
pub(super) fn galerkin(slots: &Gather, coarse: &mut BlockSparseMatrix, block: impl Fn(usize) -> Mat3 + Sync) {
    coarse.values_mut().par_chunks_mut(ROW_CHUNK).enumerate().for_each(|(c, chunk)| {
        for (k, v) in chunk.iter_mut().enumerate() {
            *v = slots.sources(c * ROW_CHUNK + k).iter().map(|&s| block(s as usize)).sum();
        }
    });
}

/// The smoother's correction at node `i` for residual `r`.
#[inline]
pub(super) fn smoothed(inv_diag: &[Mat3], pairs: Option<&(Vec<u32>, Vec<Mat3>)>, r: &[Vec3], i: usize) -> Vec3 {
    let own = inv_diag[i] * r[i];
    match pairs {
        Some((partner, inv_off)) if partner[i] as usize != i => own + inv_off[i] * r[partner[i] as usize],
        _ => own,
    }
}

pub(super) fn jacobi_from_zero(inv_diag: &[Mat3], pairs: Option<&(Vec<u32>, Vec<Mat3>)>, b: &[Vec3], x: &mut [Vec3]) {
    x.par_iter_mut().enumerate().with_min_len(ROW_CHUNK).for_each(|(i, xi)| *xi = smoothed(inv_diag, pairs, b, i));
}

/// `target[c] = sum of src over aggregate c`, in member order.
pub(super) fn restrict(members: &Gather, src: &[Vec3], target: &mut [Vec3]) {
    target.par_iter_mut().enumerate().with_min_len(ROW_CHUNK / 4).for_each(|(c, t)| {
        *t = members.sources(c).iter().map(|&i| src[i as usize]).sum();
    });
}
