//! Deterministic data-parallel kernels on slices of [`Vec3`].
//!
//! Reductions are computed as one partial sum per fixed-size chunk, then
//! summed serially in chunk order: the result does not depend on how rayon
//! schedules the chunks, so it is the same with 1, 2 or 64 threads.

use crate::Vec3;
use rayon::prelude::*;

/// Rows (particles) per parallel task. Fixed, so that reductions have a fixed
/// summation order.
pub const ROW_CHUNK: usize = 256;

/// `sum_i a_i . b_i`, summed in a fixed order.
pub fn dot(a: &[Vec3], b: &[Vec3]) -> f64 {
    assert_eq!(a.len(), b.len(), "dot: length mismatch");
    dot_with(a, b, &mut vec![0.0; chunk_count(a.len())])
}

/// Like [`dot`], writing the chunk partials into a caller-owned buffer so the
/// hot loop does not allocate. `partials.len()` must be `a.len().div_ceil(ROW_CHUNK)`.
pub(crate) fn dot_with(a: &[Vec3], b: &[Vec3], partials: &mut [f64]) -> f64 {
    a.par_chunks(ROW_CHUNK)
        .zip(b.par_chunks(ROW_CHUNK))
        .zip(partials.par_iter_mut())
        .for_each(|((ca, cb), p)| *p = ca.iter().zip(cb).map(|(x, y)| x.dot(y)).sum());
    partials.iter().sum()
}

/// `r_i = b_i - row(i)` for every row, parallel over chunks of
/// [`ROW_CHUNK`] rows: a matrix's residual from its row product.
#[inline(always)]
pub(crate) fn residual_rows(b: &[Vec3], r: &mut [Vec3], row: impl Fn(usize) -> Vec3 + Sync) {
    r.par_chunks_mut(ROW_CHUNK).zip(b.par_chunks(ROW_CHUNK)).enumerate().for_each(|(chunk, (rs, bs))| {
        for (k, (ri, bi)) in rs.iter_mut().zip(bs).enumerate() {
            *ri = bi - row(chunk * ROW_CHUNK + k);
        }
    });
}

/// `y_i = row(i)` for every row, returning `x.y` summed in chunk order
/// (one partial per chunk of [`ROW_CHUNK`] rows in `partials`): a
/// matrix's product and CG's curvature in one pass.
#[inline(always)]
pub(crate) fn rows_with_dot(
    x: &[Vec3],
    y: &mut [Vec3],
    partials: &mut [f64],
    row: impl Fn(usize) -> Vec3 + Sync,
) -> f64 {
    y.par_chunks_mut(ROW_CHUNK).zip(partials.par_iter_mut()).enumerate().for_each(|(chunk, (ys, p))| {
        let mut acc = 0.0;
        for (k, yi) in ys.iter_mut().enumerate() {
            let i = chunk * ROW_CHUNK + k;
            *yi = row(i);
            acc += x[i].dot(yi);
        }
        *p = acc;
    });
    partials.iter().sum()
}

/// Number of chunk partials for a vector of `n` particles.
pub(crate) fn chunk_count(n: usize) -> usize {
    n.div_ceil(ROW_CHUNK).max(1)
}
