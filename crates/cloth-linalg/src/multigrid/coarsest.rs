//! The coarsest level, solved exactly by a dense Cholesky factorisation.

use super::*;
use crate::{BlockSparseMatrix, Mat3, Vec3};

/// The coarsest level, solved directly.
#[derive(Debug, Clone)]
pub(super) struct Coarsest {
    /// Dense operator, row-major, factorised in place: its lower triangle
    /// becomes the Cholesky factor `L`. Row-major so that the inner loops
    /// of [`cholesky_in_place`] run along rows (refactorised at every
    /// solve, the 108 x 108 factor of the 41 x 41 drape was 3.9% of its
    /// single-thread profile as a column-major `DMatrix`, 2.5% now).
    pub(super) factor: Vec<f64>,
    /// `L^T`, row-major: the rows the solves run along.
    pub(super) factor_t: Vec<f64>,
    /// Whether the factorisation succeeded (else: block-Jacobi).
    pub(super) ok: bool,
    /// The solves' right-hand side and solution, and the factorisation's
    /// scratch column (3 per node: the dense operator's dimension).
    pub(super) rhs: Vec<f64>,
    pub(super) inv_diag: Vec<Mat3>,
    pub(super) b: Vec<Vec3>,
    pub(super) x: Vec<Vec3>,
    /// The solve's couplings on the coarsest nodes, factored with the
    /// operator.
    pub(super) couplings: LevelCouplings,
}

impl Coarsest {
    pub(super) fn new(n: usize) -> Self {
        let dim = 3 * n;
        Self {
            factor: vec![0.0; dim * dim],
            factor_t: vec![0.0; dim * dim],
            ok: false,
            rhs: vec![0.0; dim],
            inv_diag: vec![Mat3::identity(); n],
            b: vec![Vec3::zeros(); n],
            x: vec![Vec3::zeros(); n],
            couplings: LevelCouplings::default(),
        }
    }

    /// Factorises `a` (block-Jacobi if it is not positive definite).
    pub(super) fn update(&mut self, a: &BlockSparseMatrix) {
        inverse_diagonal(a, 1.0, &mut self.inv_diag);
        let dim = self.rhs.len();
        self.factor.fill(0.0);
        for (i, j, b) in a.blocks() {
            for r in 0..3 {
                for c in 0..3 {
                    self.factor[(3 * i + r) * dim + 3 * j + c] = b[(r, c)];
                }
            }
        }
        self.couplings.add_to_dense(&mut self.factor, dim);
        self.ok = cholesky_in_place(&mut self.factor, dim, &mut self.rhs);
        if self.ok {
            transpose_lower(&self.factor, dim, &mut self.factor_t);
        }
    }

    /// `x = A^-1 b` by the stored factor.
    pub(super) fn solve(&mut self) {
        if !self.ok {
            self.x.iter_mut().zip(&self.b).zip(&self.inv_diag).for_each(|((xi, bi), di)| *xi = di * bi);
            return;
        }
        for (i, bi) in self.b.iter().enumerate() {
            self.rhs[3 * i..3 * i + 3].copy_from_slice(bi.as_slice());
        }
        cholesky_solve_in_place(&self.factor_t, &mut self.rhs);
        for (i, xi) in self.x.iter_mut().enumerate() {
            *xi = Vec3::from_column_slice(&self.rhs[3 * i..3 * i + 3]);
        }
    }
}

/// Overwrites the lower triangle of the SPD `n x n` row-major matrix `a`
/// with its Cholesky factor `L` (`a = L L^T`), without allocating (`column`
/// holds `n` scratch entries). Returns false if `a` is not positive
/// definite.
///
/// Right-looking: step `j` finishes column `j` and subtracts `L_ij L_kj`
/// from every entry `(i, k)` below and right of it, a loop along rows
/// without a dependency between its entries (the left-looking dot product
/// `a_ik - sum_j L_ij L_kj` waited on each subtraction). Each entry still
/// receives the same subtractions in the same order (`j` ascending), then
/// the same division: the same factor bit for bit.
pub(super) fn cholesky_in_place(a: &mut [f64], n: usize, column: &mut [f64]) -> bool {
    for j in 0..n {
        let (head, tail) = a.split_at_mut((j + 1) * n);
        let d = head[j * n + j];
        if !(d > 0.0 && d.is_finite()) {
            return false;
        }
        let d = d.sqrt();
        head[j * n + j] = d;
        for (row_k, l_kj) in tail.chunks_exact_mut(n).zip(column.iter_mut()) {
            row_k[j] /= d;
            *l_kj = row_k[j];
        }
        for (m, row_i) in tail.chunks_exact_mut(n).enumerate() {
            let l_ij = row_i[j];
            for (a_ik, &l_kj) in row_i[j + 1..=j + 1 + m].iter_mut().zip(&column[..=m]) {
                *a_ik -= l_ij * l_kj;
            }
        }
    }
    true
}

/// `l_t = L^T` for the lower triangle `L` of the `n x n` row-major `l`
/// (only `l_t`'s upper triangle is written).
pub(super) fn transpose_lower(l: &[f64], n: usize, l_t: &mut [f64]) {
    for i in 0..n {
        for k in 0..=i {
            l_t[k * n + i] = l[i * n + k];
        }
    }
}

/// Solves `L L^T x = b` in place given `l_t`, the transpose of the factor
/// from [`cholesky_in_place`] (row-major). The forward
/// substitution runs by columns (`b_i -= L_ik b_k` for all `i > k` once
/// `b_k` is final: each `b_i` gets the subtractions in the order of the
/// dot product `b_i - sum_k L_ik b_k`, so the same bits, with no chain of
/// dependent subtractions); the backward one keeps the dot product (by
/// columns it would subtract in the opposite order).
pub(super) fn cholesky_solve_in_place(l_t: &[f64], b: &mut [f64]) {
    let n = b.len();
    for k in 0..n {
        let (done, rest) = b.split_at_mut(k + 1);
        let row = &l_t[k * n..(k + 1) * n];
        done[k] /= row[k];
        let b_k = done[k];
        for (b_i, &l_ik) in rest.iter_mut().zip(&row[k + 1..]) {
            *b_i -= l_ik * b_k;
        }
    }
    for i in (0..n).rev() {
        let row = &l_t[i * n..(i + 1) * n];
        let mut s = b[i];
        for (&l_ki, &b_k) in row[i + 1..].iter().zip(&b[i + 1..]) {
            s -= l_ki * b_k;
        }
        b[i] = s / row[i];
    }
}
