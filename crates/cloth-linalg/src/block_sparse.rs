//! Symmetric sparse matrices of 3x3 blocks with a fixed sparsity pattern.
//!
//! The pattern (block compressed rows, both triangles stored) is built once
//! from the interaction stencils; each time step refills the values in place.
//! Storing both triangles costs memory but lets every row of a product be
//! computed independently, so the parallel product needs no reduction.

use crate::par::{ROW_CHUNK, residual_rows, rows_with_dot};
use crate::{Mat3, Vec3};
use rayon::prelude::*;
use std::ops::Range;
use std::sync::atomic::{AtomicU64, Ordering};

/// Why a sparsity pattern could not be built.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum PatternError {
    /// A pair names a row or column outside `0..n`.
    #[error("block pair ({i}, {j}) is out of range for {n} block rows")]
    OutOfRange {
        /// Row of the offending pair.
        i: usize,
        /// Column of the offending pair.
        j: usize,
        /// Number of block rows.
        n: usize,
    },
}

/// The block sparsity pattern of a symmetric `n x n` block matrix: every
/// diagonal block plus the blocks `(i, j)` and `(j, i)` of each coupled pair.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BlockPattern {
    row_ptr: Vec<usize>,
    cols: Vec<u32>,
    diag: Vec<usize>,
    /// `mirror[slot(i, j)] = slot(j, i)`.
    mirror: Vec<u32>,
}

impl BlockPattern {
    /// Builds the pattern for `n` block rows from coupled pairs (duplicates and
    /// self-pairs are allowed and merged). Columns are sorted within a row.
    pub fn from_pairs(n: usize, pairs: impl IntoIterator<Item = (usize, usize)>) -> Result<Self, PatternError> {
        let mut rows: Vec<Vec<u32>> = (0..n).map(|i| vec![i as u32]).collect();
        for (i, j) in pairs {
            if i >= n || j >= n {
                return Err(PatternError::OutOfRange { i, j, n });
            }
            rows[i].push(j as u32);
            rows[j].push(i as u32);
        }
        let mut row_ptr = Vec::with_capacity(n + 1);
        let mut cols = Vec::new();
        let mut diag = Vec::with_capacity(n);
        row_ptr.push(0);
        for (i, mut r) in rows.into_iter().enumerate() {
            r.sort_unstable();
            r.dedup();
            let d = r.binary_search(&(i as u32)).expect("diagonal is always present");
            diag.push(cols.len() + d);
            cols.extend_from_slice(&r);
            row_ptr.push(cols.len());
        }
        let mut pattern = Self { row_ptr, cols, diag, mirror: Vec::new() };
        pattern.mirror = (0..n)
            .flat_map(|i| pattern.row_cols(i).iter().map(move |&j| (i, j as usize)))
            .map(|(i, j)| pattern.slot(j, i).expect("both (i, j) and (j, i) were pushed") as u32)
            .collect();
        Ok(pattern)
    }

    /// Number of block rows.
    pub fn n(&self) -> usize {
        self.diag.len()
    }

    /// Number of stored blocks (both triangles and the diagonal).
    pub fn nnz_blocks(&self) -> usize {
        self.cols.len()
    }

    /// Storage slot of block `(i, j)`, if it is in the pattern.
    pub fn slot(&self, i: usize, j: usize) -> Option<usize> {
        let r = self.row_range(i);
        let found = self.cols[r.clone()].binary_search(&(j as u32)).ok()?;
        Some(r.start + found)
    }

    /// Storage slot of block `(j, i)`, given the slot of `(i, j)` (the
    /// pattern is structurally symmetric; a table built with it).
    pub fn mirror_slot(&self, slot: usize) -> usize {
        self.mirror[slot] as usize
    }

    /// Storage slot of the diagonal block `(i, i)`.
    pub fn diag_slot(&self, i: usize) -> usize {
        self.diag[i]
    }

    /// Storage slots of row `i`.
    pub fn row_range(&self, i: usize) -> Range<usize> {
        self.row_ptr[i]..self.row_ptr[i + 1]
    }

    /// Column indices of row `i`, sorted.
    pub fn row_cols(&self, i: usize) -> &[u32] {
        &self.cols[self.row_range(i)]
    }
}

/// A symmetric block matrix with a fixed [`BlockPattern`].
#[derive(Debug, Clone)]
pub struct BlockSparseMatrix {
    pattern: BlockPattern,
    values: Vec<Mat3>,
    /// See [`BlockSparseMatrix::revision`].
    revision: u64,
}

/// The next [`BlockSparseMatrix::revision`], shared by all matrices.
static NEXT_REVISION: AtomicU64 = AtomicU64::new(0);

fn next_revision() -> u64 {
    NEXT_REVISION.fetch_add(1, Ordering::Relaxed)
}

impl BlockSparseMatrix {
    /// A zero matrix with the given pattern.
    pub fn new(pattern: BlockPattern) -> Self {
        let values = vec![Mat3::zeros(); pattern.nnz_blocks()];
        Self { pattern, values, revision: next_revision() }
    }

    /// A number that changes whenever the values may have changed (every
    /// mutable access draws a new one, unique across all matrices): two
    /// reads of the same number saw the same values. A clone keeps it (and
    /// the values).
    pub fn revision(&self) -> u64 {
        self.revision
    }

    /// The sparsity pattern.
    pub fn pattern(&self) -> &BlockPattern {
        &self.pattern
    }

    /// Number of block rows.
    pub fn n(&self) -> usize {
        self.pattern.n()
    }

    /// All stored blocks, in slot order.
    pub fn values(&self) -> &[Mat3] {
        &self.values
    }

    /// All stored blocks, mutable (the pattern stays fixed).
    pub fn values_mut(&mut self) -> &mut [Mat3] {
        self.revision = next_revision();
        &mut self.values
    }

    /// The pattern and the mutable values at once (to edit blocks found
    /// through the pattern).
    pub fn pattern_and_values_mut(&mut self) -> (&BlockPattern, &mut [Mat3]) {
        self.revision = next_revision();
        (&self.pattern, &mut self.values)
    }

    /// Makes the matrix symmetric bit for bit from its upper triangle:
    /// each block below the diagonal becomes the transpose of its mirror,
    /// `A_ji = A_ij^T` for `i < j`, and each diagonal block its symmetric
    /// part `(A_ii + A_ii^T) / 2`. For a symmetric matrix of which only
    /// the upper triangle was computed.
    pub fn symmetric_from_upper(&mut self) {
        self.revision = next_revision();
        let pattern = &self.pattern;
        for i in 0..pattern.n() {
            let diag = pattern.diag_slot(i);
            for slot in pattern.row_range(i).start..diag {
                self.values[slot] = self.values[pattern.mirror_slot(slot)].transpose();
            }
            let d = self.values[diag];
            self.values[diag] = (d + d.transpose()) * 0.5;
        }
    }

    /// The diagonal block of row `i`.
    pub fn diag(&self, i: usize) -> &Mat3 {
        &self.values[self.pattern.diag[i]]
    }

    /// Refills the matrix row by row in parallel: `fill(i, row_blocks)` gets
    /// the blocks of row `i` (in the column order of [`BlockPattern::row_cols`])
    /// and must overwrite all of them. Rows are disjoint, so no reduction and
    /// no allocation is involved.
    pub fn fill_rows<F>(&mut self, fill: F)
    where
        F: Fn(usize, &mut [Mat3]) + Sync,
    {
        // `()` per task: a Vec of them does not allocate.
        let mut tasks = vec![(); self.n().div_ceil(FILL_ROWS_PER_TASK)];
        self.revision = next_revision();
        let fill_chunk =
            |pattern: &BlockPattern, rows: Range<usize>, first_slot: usize, blocks: &mut [Mat3], _: &mut ()| {
                for i in rows {
                    let range = pattern.row_range(i);
                    fill(i, &mut blocks[range.start - first_slot..range.end - first_slot]);
                }
            };
        edit_chunks(&self.pattern, FILL_ROWS_PER_TASK, 0..tasks.len(), &mut self.values, 0, &mut tasks, &fill_chunk);
    }

    /// Edits the matrix in parallel, one task per chunk of [`ROW_CHUNK`]
    /// rows: `edit(pattern, rows, first_slot, blocks, own)` gets chunk
    /// `k`'s rows, the slot of their first block, their blocks (`blocks[0]`
    /// is slot `first_slot`) and `own = &mut per_chunk[k]` (the chunk's
    /// scratch or output). `per_chunk` has one entry per chunk, `n.div_ceil(ROW_CHUNK)`.
    pub fn edit_row_chunks<T, F>(&mut self, per_chunk: &mut [T], edit: F)
    where
        T: Send,
        F: Fn(&BlockPattern, Range<usize>, usize, &mut [Mat3], &mut T) + Sync,
    {
        let chunks = self.n().div_ceil(ROW_CHUNK);
        assert_eq!(per_chunk.len(), chunks, "edit_row_chunks: one entry per chunk of {ROW_CHUNK} rows");
        self.revision = next_revision();
        edit_chunks(&self.pattern, ROW_CHUNK, 0..chunks, &mut self.values, 0, per_chunk, &edit);
    }

    /// Row `i` of `A x`.
    #[inline]
    pub fn row_times(&self, i: usize, x: &[Vec3]) -> Vec3 {
        let range = self.pattern.row_range(i);
        let mut a = [0.0; 3];
        for (b, &c) in self.values[range.clone()].iter().zip(&self.pattern.cols[range]) {
            let t = block_times(b, &x[c as usize]);
            (a[0], a[1], a[2]) = (a[0] + t[0], a[1] + t[1], a[2] + t[2]);
        }
        Vec3::from(a)
    }

    /// `y = A x`, parallel over rows.
    pub fn mul_vec(&self, x: &[Vec3], y: &mut [Vec3]) {
        let n = self.n();
        assert!(x.len() == n && y.len() == n, "mul_vec: dimension mismatch");
        y.par_chunks_mut(ROW_CHUNK).enumerate().for_each(|(chunk, ys)| {
            for (k, yi) in ys.iter_mut().enumerate() {
                *yi = self.row_times(chunk * ROW_CHUNK + k, x);
            }
        });
    }

    /// `r = b - A x`, parallel over rows.
    pub fn residual(&self, b: &[Vec3], x: &[Vec3], r: &mut [Vec3]) {
        let n = self.n();
        assert!(x.len() == n && b.len() == n && r.len() == n, "residual: dimension mismatch");
        residual_rows(b, r, |i| self.row_times(i, x));
    }

    /// `r1 = b - A x1` and `r2 = b - A x2` in one pass over the matrix (a
    /// solve's two starting residuals), each row summed as
    /// [`BlockSparseMatrix::residual`] sums it: the same bits as two calls.
    pub fn residual_pair(&self, b: &[Vec3], (x1, x2): (&[Vec3], &[Vec3]), (r1, r2): (&mut [Vec3], &mut [Vec3])) {
        let n = self.n();
        let lengths = [b.len(), x1.len(), x2.len(), r1.len(), r2.len()];
        assert!(lengths.iter().all(|&l| l == n), "residual_pair: dimension mismatch");
        let rows = r1.par_chunks_mut(ROW_CHUNK).zip(r2.par_chunks_mut(ROW_CHUNK)).zip(b.par_chunks(ROW_CHUNK));
        rows.enumerate().for_each(|(chunk, ((r1s, r2s), bs))| {
            for (k, ((r1i, r2i), bi)) in r1s.iter_mut().zip(r2s).zip(bs).enumerate() {
                let (y1, y2) = self.row_times_pair(chunk * ROW_CHUNK + k, x1, x2);
                (*r1i, *r2i) = (bi - y1, bi - y2);
            }
        });
    }

    /// Row `i` of `A x1` and of `A x2`, each summed as [`BlockSparseMatrix::row_times`].
    #[inline]
    fn row_times_pair(&self, i: usize, x1: &[Vec3], x2: &[Vec3]) -> (Vec3, Vec3) {
        let range = self.pattern.row_range(i);
        let (mut a, mut b) = ([0.0; 3], [0.0; 3]);
        for (blk, &c) in self.values[range.clone()].iter().zip(&self.pattern.cols[range]) {
            let (t, u) = (block_times(blk, &x1[c as usize]), block_times(blk, &x2[c as usize]));
            (a[0], a[1], a[2]) = (a[0] + t[0], a[1] + t[1], a[2] + t[2]);
            (b[0], b[1], b[2]) = (b[0] + u[0], b[1] + u[1], b[2] + u[2]);
        }
        (Vec3::from(a), Vec3::from(b))
    }

    /// `y = A x` and returns `x . y` (the curvature CG needs) in the same
    /// pass, summed in chunk order. `partials` needs one slot per
    /// [`ROW_CHUNK`] rows.
    pub fn mul_vec_dot(&self, x: &[Vec3], y: &mut [Vec3], partials: &mut [f64]) -> f64 {
        let n = self.n();
        assert!(x.len() == n && y.len() == n, "mul_vec_dot: dimension mismatch");
        assert_eq!(partials.len(), n.div_ceil(ROW_CHUNK).max(1), "mul_vec_dot: partials length");
        rows_with_dot(x, y, partials, |i| self.row_times(i, x))
    }

    /// Iterates over the stored blocks as `(row, col, block)`.
    pub fn blocks(&self) -> impl Iterator<Item = (usize, usize, &Mat3)> + '_ {
        (0..self.n()).flat_map(move |i| {
            self.pattern.row_range(i).map(move |s| (i, self.pattern.cols[s] as usize, &self.values[s]))
        })
    }
}

/// A column-major 3x3 block times a 3-vector, written out (every product
/// of the matrix sums these in column order, so two products agree bit
/// for bit).
#[inline]
fn block_times(b: &Mat3, x: &Vec3) -> [f64; 3] {
    let m = b.as_slice();
    [m[0] * x.x + m[3] * x.y + m[6] * x.z, m[1] * x.x + m[4] * x.y + m[7] * x.z, m[2] * x.x + m[5] * x.y + m[8] * x.z]
}

/// Rows per leaf task of [`BlockSparseMatrix::fill_rows`].
const FILL_ROWS_PER_TASK: usize = 128;

/// Runs `edit` on chunks `chunks` of `chunk_rows` rows each (the last one
/// may be short), splitting them in halves over rayon's threads; their
/// blocks are `vals` (starting at slot `base`), their own entries `own`.
/// [`BlockSparseMatrix::edit_row_chunks`] and [`BlockSparseMatrix::fill_rows`].
fn edit_chunks<T, F>(
    pattern: &BlockPattern,
    chunk_rows: usize,
    chunks: Range<usize>,
    vals: &mut [Mat3],
    base: usize,
    own: &mut [T],
    edit: &F,
) where
    T: Send,
    F: Fn(&BlockPattern, Range<usize>, usize, &mut [Mat3], &mut T) + Sync,
{
    let first_row = |chunk: usize| (chunk * chunk_rows).min(pattern.n());
    if chunks.len() <= 1 {
        if let Some(own) = own.first_mut() {
            edit(pattern, first_row(chunks.start)..first_row(chunks.end), base, vals, own);
        }
        return;
    }
    let mid = chunks.start + chunks.len() / 2;
    let split = pattern.row_ptr[first_row(mid)];
    let (lo, hi) = vals.split_at_mut(split - base);
    let (own_lo, own_hi) = own.split_at_mut(mid - chunks.start);
    rayon::join(
        || edit_chunks(pattern, chunk_rows, chunks.start..mid, lo, base, own_lo, edit),
        || edit_chunks(pattern, chunk_rows, mid..chunks.end, hi, split, own_hi, edit),
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pattern_merges_duplicates_and_sorts() {
        let p = BlockPattern::from_pairs(4, [(0, 2), (2, 0), (1, 1), (3, 0)]).unwrap();
        assert_eq!(p.row_cols(0), &[0, 2, 3]);
        assert_eq!(p.row_cols(1), &[1]);
        assert_eq!(p.row_cols(2), &[0, 2]);
        assert_eq!(p.slot(0, 3), Some(2));
        assert_eq!(p.slot(1, 3), None);
        assert_eq!(p.diag_slot(2), p.slot(2, 2).unwrap());
        for i in 0..p.n() {
            for (slot, &j) in p.row_range(i).zip(p.row_cols(i)) {
                assert_eq!(p.mirror_slot(slot), p.slot(j as usize, i).unwrap());
            }
        }
    }

    /// Each chunk's task gets its own rows (all of them, once), the slot
    /// of their first block, exactly their blocks, and its own entry of
    /// `per_chunk`; the last chunk is a short one.
    #[test]
    fn edit_row_chunks_hands_each_task_its_rows_blocks_and_entry() {
        let n = 2 * ROW_CHUNK + 37;
        let pairs: Vec<_> = (0..n - 5).flat_map(|i| [(i, i + 1), (i, i + 5)]).collect();
        let mut a = BlockSparseMatrix::new(BlockPattern::from_pairs(n, pairs).unwrap());
        let mut seen = vec![(0..0, usize::MAX); n.div_ceil(ROW_CHUNK)];
        a.edit_row_chunks(&mut seen, |pattern, rows, first_slot, blocks, seen| {
            assert_eq!(blocks.len(), pattern.row_range(rows.end - 1).end - first_slot);
            for i in rows.clone() {
                for slot in pattern.row_range(i) {
                    blocks[slot - first_slot] = Mat3::from_element(i as f64);
                }
            }
            *seen = (rows, first_slot);
        });
        for (k, (rows, first_slot)) in seen.iter().enumerate() {
            assert_eq!(*rows, k * ROW_CHUNK..((k + 1) * ROW_CHUNK).min(n));
            assert_eq!(*first_slot, a.pattern().row_range(rows.start).start);
        }
        for (i, _, b) in a.blocks() {
            assert_eq!(*b, Mat3::from_element(i as f64), "row {i}");
        }
        // No rows: no chunk, no task.
        let mut empty = BlockSparseMatrix::new(BlockPattern::from_pairs(0, []).unwrap());
        empty.edit_row_chunks(&mut [] as &mut [()], |_, _, _, _, _| panic!("a task without rows"));
        empty.fill_rows(|_, _| panic!("a row of none"));
    }

    #[test]
    fn pattern_rejects_out_of_range() {
        assert_eq!(BlockPattern::from_pairs(2, [(0, 2)]), Err(PatternError::OutOfRange { i: 0, j: 2, n: 2 }));
    }

    /// `y = A x` against a dense product built from the fill function
    /// alone (not from the matrix's own blocks), on a matrix that is not
    /// symmetric, blockwise or as a whole, and with blocks that are not
    /// symmetric themselves: a product with the transposed blocks
    /// (`m[1] * x0` read as `m[3] * x0`, ...) or with the transposed matrix
    /// (`y_j += A_ij x_i`) fails it.
    #[test]
    fn mul_vec_matches_dense_product() {
        let n = 600; // more than two chunks
        let pairs: Vec<_> = (0..n - 3).flat_map(|i| [(i, i + 1), (i, i + 3)]).collect();
        let mut a = BlockSparseMatrix::new(BlockPattern::from_pairs(n, pairs).unwrap());
        let cols: Vec<Vec<u32>> = (0..n).map(|i| a.pattern().row_cols(i).to_vec()).collect();
        let entry = |i: usize, j: usize, r: usize, c: usize| {
            1.0 + i as f64 * 0.01 - j as f64 * 0.003 + (3 * r + c) as f64 * 0.7 - (r * c) as f64 * 0.2
        };
        a.fill_rows(|i, row| {
            for (b, &j) in row.iter_mut().zip(&cols[i]) {
                *b = Mat3::from_fn(|r, c| entry(i, j as usize, r, c));
            }
        });
        let x: Vec<Vec3> = (0..n).map(|i| Vec3::new(i as f64, 1.0, -0.5 * i as f64)).collect();
        let mut y = vec![Vec3::zeros(); n];
        a.mul_vec(&x, &mut y);
        let mut partials = vec![0.0; n.div_ceil(ROW_CHUNK)];
        let mut y2 = vec![Vec3::zeros(); n];
        let xay = a.mul_vec_dot(&x, &mut y2, &mut partials);
        assert_eq!(y, y2);
        // Two residuals in one pass: the same bits as two passes.
        let (b, x2): (Vec<Vec3>, Vec<Vec3>) = (0..n).map(|i| (Vec3::new(0.5, -(i as f64), 2.0), x[n - 1 - i])).unzip();
        let (mut r1, mut r2, mut one, mut two) = (y.clone(), y.clone(), y.clone(), y.clone());
        a.residual_pair(&b, (&x, &x2), (&mut r1, &mut r2));
        a.residual(&b, &x, &mut one);
        a.residual(&b, &x2, &mut two);
        assert!(r1 == one && r2 == two, "residual_pair differs from residual");
        let direct: f64 = x.iter().zip(&y).map(|(p, q)| p.dot(q)).sum();
        assert!((xay - direct).abs() <= 1e-12 * direct.abs());
        // The dense reference: the pattern's column lists and the fill alone.
        let mut worst = 0.0_f64;
        for i in 0..n {
            let mut expect = Vec3::zeros();
            for &j in &cols[i] {
                for (r, e) in expect.iter_mut().enumerate() {
                    for (c, xc) in x[j as usize].iter().enumerate() {
                        *e += entry(i, j as usize, r, c) * xc;
                    }
                }
            }
            worst = worst.max((y[i] - expect).norm() / expect.norm().max(1.0));
        }
        eprintln!("SpMV against the dense product: {worst:.1e}");
        // Measured 4.1e-16 (summation order); a transposed block gives 1.3.
        assert!(worst <= 1e-15, "SpMV off the dense product by {worst:e}");
    }
}
