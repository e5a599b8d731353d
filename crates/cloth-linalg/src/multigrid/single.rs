//! `f32` copies of large level operators for the cycle's residuals: half
//! the memory traffic, accumulated in `f64`.

use super::*;
use crate::par::ROW_CHUNK;
use crate::{BlockPattern, BlockSparseMatrix, Mat3, Vec3};

/// A block matrix with `f32` blocks (column-major, like [`Mat3`]) on a
/// given pattern: a level's operator for the cycle's residuals.
#[derive(Debug, Clone)]
pub(super) struct SinglePrecision {
    pub(super) blocks: Vec<[f32; 9]>,
}

impl SinglePrecision {
    pub(super) fn new(pattern: &BlockPattern) -> Self {
        Self { blocks: vec![[0.0; 9]; pattern.nnz_blocks()] }
    }

    /// Rounds the symmetric part of `a` (same pattern), `(A_ij + A_ji^T) / 2`,
    /// into this copy. Rounding `A` itself would not do: an assembly's
    /// `A_ij` and `A_ji^T` may differ in their last bit, which rounding to
    /// `f32` can turn into a relative `6e-8`, and the cycle would no longer
    /// be symmetric to roundoff. The two sums are the same IEEE sums, so
    /// the copy is symmetric bit for bit.
    pub(super) fn copy_from(&mut self, a: &BlockSparseMatrix) {
        self.blocks.par_chunks_mut(ROW_CHUNK).enumerate().for_each(|(chunk, to)| {
            for (k, t) in to.iter_mut().enumerate() {
                *t = rounded_symmetric(a, chunk * ROW_CHUNK + k);
            }
        });
    }

    /// As [`SinglePrecision::copy_from`] for one slot.
    pub(super) fn copy_slot(&mut self, a: &BlockSparseMatrix, slot: usize) {
        self.blocks[slot] = rounded_symmetric(a, slot);
    }

    /// `r = b - A x` on `pattern` (this copy's), accumulated in `f64`,
    /// parallel over rows.
    pub(super) fn residual(&self, pattern: &BlockPattern, b: &[Vec3], x: &[Vec3], r: &mut [Vec3]) {
        let rows = r.par_chunks_mut(ROW_CHUNK).zip(b.par_chunks(ROW_CHUNK));
        rows.enumerate().for_each(|(chunk, (rs, bs))| {
            for (k, (ri, bi)) in rs.iter_mut().zip(bs).enumerate() {
                let i = chunk * ROW_CHUNK + k;
                let mut a = [0.0f64; 3];
                for (m, &c) in self.blocks[pattern.row_range(i)].iter().zip(pattern.row_cols(i)) {
                    let xc = &x[c as usize];
                    // Column by column: converting all nine entries first
                    // made this 17% slower than the f64 product in cache.
                    for k in 0..3 {
                        let column = [f64::from(m[3 * k]), f64::from(m[3 * k + 1]), f64::from(m[3 * k + 2])];
                        a[0] += column[0] * xc[k];
                        a[1] += column[1] * xc[k];
                        a[2] += column[2] * xc[k];
                    }
                }
                *ri = bi - Vec3::from(a);
            }
        });
    }
}

/// `(A_ij + A_ji^T) / 2` at `slot` (of `(i, j)`), rounded to `f32`.
pub(super) fn rounded_symmetric(a: &BlockSparseMatrix, slot: usize) -> [f32; 9] {
    let values = a.values();
    let sym = (values[slot] + values[a.pattern().mirror_slot(slot)].transpose()) * 0.5;
    std::array::from_fn(|k| sym.as_slice()[k] as f32)
}

/// Blocks from which a level's operator gets an `f32` copy for the
/// cycle's residuals: 36 MB of `f64` blocks, beyond this machine's 32 MB
/// L3 (measured, hanging cloth: neutral at 129 x 129, 278k blocks; the
/// solve 20% faster at 257 x 257, 1.1M blocks).
pub(super) const SINGLE_MIN_BLOCKS: usize = 500_000;

/// An `f32` block as a [`Mat3`].
pub(super) fn widen(block: &[f32; 9]) -> Mat3 {
    Mat3::from_iterator(block.iter().map(|&v| f64::from(v)))
}
