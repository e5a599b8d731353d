//! A sparse Cholesky factor `A = L L^T` of a symmetric positive definite
//! scalar matrix (faer's supernodal or simplicial factor, chosen by its
//! flop count): the symbolic analysis (fill-reducing ordering, elimination
//! tree) once per sparsity pattern, the numeric factor whenever the values
//! change, and solves with one column per task.
//!
//! A cloth's `M/h^2 + L` (mass plus a weighted graph Laplacian) is the
//! same matrix for each of the three coordinates, so one `n x n` factor
//! serves `x`, `y` and `z` ([`ScalarCholesky::solve_vec3`]). Everything
//! runs with faer's sequential kernels, so results are the same bits for
//! any number of threads; the three coordinates run in parallel.

use crate::Vec3;
use faer::Par;
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::sparse::linalg::cholesky::{CholeskySymbolicParams, LltRef, SymbolicCholesky, factorize_symbolic_cholesky};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Conj, MatMut, Side};
use rayon::prelude::*;

/// Why a factor could not be made.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CholeskyError {
    /// A pair names a row outside the matrix.
    #[error("entry ({row}, {col}) is outside a {n} x {n} matrix")]
    OutOfRange {
        /// The entry's row.
        row: usize,
        /// Its column.
        col: usize,
        /// The matrix's order.
        n: usize,
    },
    /// An off-diagonal pair names one row twice.
    #[error("pair ({row}, {row}) is on the diagonal, not off it")]
    OnDiagonal {
        /// The row.
        row: usize,
    },
    /// The matrix is not numerically positive definite.
    #[error("the matrix is not positive definite (pivot {pivot} of the ordered matrix)")]
    NotPositiveDefinite {
        /// The failed pivot's index in faer's fill-reducing order.
        pivot: usize,
    },
    /// faer could not allocate or analyse the pattern.
    #[error("sparse Cholesky: {0}")]
    Faer(String),
}

/// One coordinate's right-hand side and its solve's scratch.
struct Column {
    values: Vec<f64>,
    scratch: MemBuffer,
}

/// A sparse Cholesky factor of a symmetric positive definite `n x n`
/// matrix whose lower triangle's pattern is fixed at construction.
pub struct ScalarCholesky {
    n: usize,
    /// Lower triangle in compressed columns: column starts, sorted rows
    /// (the diagonal first), values.
    col_ptr: Vec<usize>,
    row_idx: Vec<usize>,
    values: Vec<f64>,
    symbolic: SymbolicCholesky<usize>,
    factor: Vec<f64>,
    factor_scratch: MemBuffer,
    factored: bool,
    columns: Vec<Column>,
}

impl std::fmt::Debug for ScalarCholesky {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ScalarCholesky")
            .field("n", &self.n)
            .field("stored", &self.row_idx.len())
            .field("factor_values", &self.factor.len())
            .field("factored", &self.factored)
            .finish()
    }
}

impl ScalarCholesky {
    /// The symbolic factor of an `n x n` matrix with a diagonal and the
    /// off-diagonal entries `pairs` (each unordered pair once or more; the
    /// symmetric entry is implied). Values start at zero.
    pub fn new(n: usize, pairs: impl IntoIterator<Item = (usize, usize)>) -> Result<Self, CholeskyError> {
        let mut lower: Vec<(usize, usize)> = (0..n).map(|i| (i, i)).collect();
        for (i, j) in pairs {
            if i >= n || j >= n {
                return Err(CholeskyError::OutOfRange { row: i, col: j, n });
            }
            lower.push((i.max(j), i.min(j)));
        }
        // By column, then row: the diagonal leads each column.
        lower.sort_unstable_by_key(|&(row, col)| (col, row));
        lower.dedup();
        let mut col_ptr = vec![0usize; n + 1];
        for &(_, col) in &lower {
            col_ptr[col + 1] += 1;
        }
        for j in 0..n {
            col_ptr[j + 1] += col_ptr[j];
        }
        let row_idx: Vec<usize> = lower.iter().map(|&(row, _)| row).collect();
        let pattern = SymbolicSparseColMatRef::new_checked(n, n, &col_ptr, None, &row_idx);
        let symbolic =
            factorize_symbolic_cholesky(pattern, Side::Lower, Default::default(), CholeskySymbolicParams::default())
                .map_err(|e| CholeskyError::Faer(format!("{e:?}")))?;
        let factor_req = symbolic.factorize_numeric_llt_scratch::<f64>(Par::Seq, Default::default());
        let solve_req = symbolic.solve_in_place_scratch::<f64>(1, Par::Seq);
        let columns = (0..3).map(|_| Column { values: vec![0.0; n], scratch: MemBuffer::new(solve_req) }).collect();
        Ok(Self {
            n,
            values: vec![0.0; row_idx.len()],
            col_ptr,
            row_idx,
            factor: vec![0.0; symbolic.len_val()],
            symbolic,
            factor_scratch: MemBuffer::new(factor_req),
            factored: false,
            columns,
        })
    }

    /// The matrix's order.
    pub fn order(&self) -> usize {
        self.n
    }

    /// Where entry `(i, j)` (either order) is stored in
    /// [`ScalarCholesky::values_mut`], if the pattern has it.
    pub fn slot(&self, i: usize, j: usize) -> Option<usize> {
        let (row, col) = (i.max(j), i.min(j));
        if col >= self.n {
            return None;
        }
        let (start, end) = (self.col_ptr[col], self.col_ptr[col + 1]);
        self.row_idx[start..end].binary_search(&row).ok().map(|k| start + k)
    }

    /// The stored values of the lower triangle, by [`ScalarCholesky::slot`].
    pub fn values(&self) -> &[f64] {
        &self.values
    }

    /// The stored values of the lower triangle, to fill by
    /// [`ScalarCholesky::slot`]; the factor is stale until
    /// [`ScalarCholesky::factor`].
    pub fn values_mut(&mut self) -> &mut [f64] {
        self.factored = false;
        &mut self.values
    }

    /// The numeric factor of the stored values (no allocation).
    pub fn factor(&mut self) -> Result<(), CholeskyError> {
        self.factored = false;
        let pattern = SymbolicSparseColMatRef::new_checked(self.n, self.n, &self.col_ptr, None, &self.row_idx);
        let matrix = SparseColMatRef::new(pattern, &self.values);
        let result = self.symbolic.factorize_numeric_llt::<f64>(
            &mut self.factor,
            matrix,
            Side::Lower,
            Default::default(),
            Par::Seq,
            MemStack::new(&mut self.factor_scratch),
            Default::default(),
        );
        match result {
            Ok(_) => {
                self.factored = true;
                Ok(())
            }
            Err(faer::linalg::solvers::LltError::NonPositivePivot { index }) => {
                Err(CholeskyError::NotPositiveDefinite { pivot: index })
            }
        }
    }

    /// Whether the values have been factored since they last changed.
    pub fn is_factored(&self) -> bool {
        self.factored
    }

    /// Solves `A x = b` for each coordinate of `b` (one `Vec3` per row),
    /// in place, the coordinates in parallel. Panics if the factor is
    /// stale or `b` is not of the matrix's order (a caller's bug).
    pub fn solve_vec3(&mut self, b: &mut [Vec3]) {
        assert!(self.factored, "ScalarCholesky::solve_vec3 before factor");
        assert_eq!(b.len(), self.n, "right-hand side of the wrong length");
        for (k, column) in self.columns.iter_mut().enumerate() {
            for (c, v) in column.values.iter_mut().zip(b.iter()) {
                *c = v[k];
            }
        }
        let factor = LltRef::new(&self.symbolic, &self.factor);
        self.columns.par_iter_mut().for_each(|column| {
            let rhs = MatMut::from_column_major_slice_mut(&mut column.values, self.n, 1);
            factor.solve_in_place_with_conj(Conj::No, rhs, Par::Seq, MemStack::new(&mut column.scratch));
        });
        for (k, column) in self.columns.iter().enumerate() {
            for (c, v) in column.values.iter().zip(b.iter_mut()) {
                v[k] = *c;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The path graph's Laplacian plus a diagonal, factored and solved:
    /// the solution satisfies the system to rounding, each coordinate the
    /// same as the others for the same data, and a refactor with new
    /// values gives the new system's solution.
    #[test]
    fn a_laplacian_plus_mass_is_solved_to_rounding() {
        let n = 50;
        let pairs: Vec<(usize, usize)> = (0..n - 1).map(|i| (i + 1, i)).chain([(0, n - 1)]).collect();
        let mut chol = ScalarCholesky::new(n, pairs.iter().copied()).unwrap();
        for mass in [1.0, 1e-3] {
            let dense = {
                let mut a = nalgebra::DMatrix::<f64>::zeros(n, n);
                for &(i, j) in &pairs {
                    let w = 1.0 + 0.01 * (i + j) as f64;
                    a[(i, j)] -= w;
                    a[(j, i)] -= w;
                    a[(i, i)] += w;
                    a[(j, j)] += w;
                }
                for i in 0..n {
                    a[(i, i)] += mass * (1.0 + i as f64 / n as f64);
                }
                a
            };
            let values = chol.values_mut();
            values.iter_mut().for_each(|v| *v = 0.0);
            for j in 0..n {
                for i in j..n {
                    if dense[(i, j)] != 0.0 {
                        let s = chol.slot(i, j).unwrap();
                        chol.values_mut()[s] = dense[(i, j)];
                    }
                }
            }
            chol.factor().unwrap();
            let b: Vec<Vec3> = (0..n).map(|i| Vec3::new(i as f64, 1.0, (i as f64).sin())).collect();
            let mut x = b.clone();
            chol.solve_vec3(&mut x);
            for k in 0..3 {
                let xk = nalgebra::DVector::from_iterator(n, x.iter().map(|v| v[k]));
                let bk = nalgebra::DVector::from_iterator(n, b.iter().map(|v| v[k]));
                let residual = (&dense * &xk - &bk).norm() / bk.norm();
                assert!(residual < 1e-12, "mass {mass}, coordinate {k}: relative residual {residual:e}");
            }
        }
        assert_eq!(chol.slot(3, 7), None);
        assert_eq!(chol.slot(7, 6), chol.slot(6, 7));
    }

    /// An indefinite matrix is refused with an error, not a factor.
    #[test]
    fn an_indefinite_matrix_is_refused() {
        let mut chol = ScalarCholesky::new(2, [(0, 1)]).unwrap();
        let (d0, d1, off) = (chol.slot(0, 0).unwrap(), chol.slot(1, 1).unwrap(), chol.slot(1, 0).unwrap());
        let v = chol.values_mut();
        (v[d0], v[d1], v[off]) = (1.0, 1.0, 2.0);
        assert!(matches!(chol.factor(), Err(CholeskyError::NotPositiveDefinite { .. })));
        assert!(!chol.is_factored());
        assert!(matches!(ScalarCholesky::new(2, [(0, 2)]), Err(CholeskyError::OutOfRange { .. })));
    }
}
