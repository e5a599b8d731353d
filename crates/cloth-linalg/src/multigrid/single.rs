//! `f32` copies of large level operators for the cycle's residuals and
//! the K-cycle's Krylov products: half the memory traffic, accumulated in
//! `f64`.

use super::*;
use crate::par::{ROW_CHUNK, residual_rows, rows_with_dot};
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
        residual_rows(b, r, |i| self.row_times(pattern, i, x));
    }

    /// `y = A x` on `pattern` (this copy's), accumulated in `f64`, and
    /// `x.y` summed in chunk order (`partials`: one per chunk of
    /// [`ROW_CHUNK`] rows), as [`BlockSparseMatrix::mul_vec_dot`].
    pub(super) fn mul_vec_dot(&self, pattern: &BlockPattern, x: &[Vec3], y: &mut [Vec3], partials: &mut [f64]) -> f64 {
        rows_with_dot(x, y, partials, |i| self.row_times(pattern, i, x))
    }

    /// Row `i` of `A x`, each block widened column by column and summed in
    /// `f64`.
    #[inline(always)]
    fn row_times(&self, pattern: &BlockPattern, i: usize, x: &[Vec3]) -> Vec3 {
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
        Vec3::from(a)
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

#[cfg(test)]
mod tests {
    use super::*;

    /// A symmetric pattern of `n` nodes, each linked to the next three,
    /// with pseudo-random blocks (not symmetric in value).
    fn random_matrix(n: usize) -> BlockSparseMatrix {
        let pairs = (0..n).flat_map(|i| (i + 1..(i + 4).min(n)).map(move |j| (i, j)));
        let mut a = BlockSparseMatrix::new(BlockPattern::from_pairs(n, pairs).unwrap());
        let mut seed = 0x2545_f491_4f6c_dd1d_u64;
        for v in a.values_mut() {
            *v = Mat3::from_fn(|_, _| {
                seed = seed.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1_442_695_040_888_963_407);
                (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
            });
        }
        a
    }

    #[test]
    fn product_is_the_rounded_operators_product_and_its_dot() {
        let n = 300;
        let a = random_matrix(n);
        let mut single = SinglePrecision::new(a.pattern());
        single.copy_from(&a);
        // The rounded operator in `f64`, and the symmetric part it rounds.
        let (mut widened, mut symmetric) = (a.clone(), a.clone());
        for s in 0..a.pattern().nnz_blocks() {
            widened.values_mut()[s] = widen(&single.blocks[s]);
            symmetric.values_mut()[s] = (a.values()[s] + a.values()[a.pattern().mirror_slot(s)].transpose()) * 0.5;
        }
        let x: Vec<Vec3> = (0..n).map(|i| Vec3::new((i as f64).sin(), (i as f64 * 0.7).cos(), 1.0)).collect();
        let mut partials = vec![0.0; chunk_count(n)];
        let (mut y, mut y_widened, mut y_symmetric) = (vec![Vec3::zeros(); n], x.clone(), x.clone());
        let dot = single.mul_vec_dot(a.pattern(), &x, &mut y, &mut partials);
        widened.mul_vec(&x, &mut y_widened);
        symmetric.mul_vec(&x, &mut y_symmetric);
        let scale = y_symmetric.iter().map(|v| v.amax()).fold(0.0, f64::max);
        let off = |p: &[Vec3], q: &[Vec3]| p.iter().zip(q).map(|(u, v)| (u - v).amax()).fold(0.0, f64::max) / scale;
        // The widened operator's product up to the order of its sums:
        // measured 2.6e-16.
        assert!(off(&y, &y_widened) <= 1e-15, "against the widened copy: {:e}", off(&y, &y_widened));
        // Within f32 rounding of the operator: measured 3.0e-8.
        assert!(off(&y, &y_symmetric) < 1e-7, "against the f64 operator: {:e}", off(&y, &y_symmetric));
        let expected: f64 = x.iter().zip(&y).map(|(u, v)| u.dot(v)).sum();
        assert!((dot - expected).abs() <= 1e-13 * expected.abs(), "dot {dot} against {expected}");
        // The residual reads the same rows.
        let b: Vec<Vec3> = (0..n).map(|i| Vec3::repeat(i as f64 * 1e-3)).collect();
        let mut r = vec![Vec3::zeros(); n];
        single.residual(a.pattern(), &b, &x, &mut r);
        assert!(r.iter().zip(&b).zip(&y).all(|((r, b), y)| *r == b - y));
    }
}
