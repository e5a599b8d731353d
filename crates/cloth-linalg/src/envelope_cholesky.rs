//! A Cholesky factor `A = L L^T` of a small symmetric positive definite
//! matrix whose pattern changes from one solve to the next: rows ordered
//! by reverse Cuthill-McKee (George & Liu 1981, §4.3), then factored in
//! their envelope (each row from its first nonzero column to the
//! diagonal, where all of a row's fill lies).
//!
//! Made for systems of a few hundred rows assembled anew for every solve
//! (a fast projection's active constraints): a general sparse factor
//! spends most of such a solve in its symbolic analysis (fill-reducing
//! ordering, elimination tree, supernodes), while here the analysis is a
//! breadth-first search and the factor streams contiguous row segments.
//! The work grows with the envelope ([`EnvelopeCholesky::analyse`]
//! returns it), so a caller can keep an iterative solver for systems
//! whose envelope is wide. Every loop is serial in a fixed order, and
//! the buffers are reused: no allocation once they have grown.

use crate::{Buckets, CholeskyError};

/// The envelope factor and its ordering; see the module documentation.
#[derive(Debug, Clone, Default)]
pub struct EnvelopeCholesky {
    n: usize,
    /// `order[r]`: the original row at ordered position `r`.
    order: Vec<u32>,
    /// `position[i]`: the ordered position of original row `i`.
    position: Vec<u32>,
    /// Each row's neighbours (original numbering, sorted), each pair both ways.
    adj: Buckets<u32>,
    /// Ordered row `r`'s first stored column.
    first: Vec<u32>,
    /// Where ordered row `r`'s segment starts in `env`.
    start: Vec<usize>,
    /// The rows' segments: the matrix's lower envelope, then `L` in place.
    env: Vec<f64>,
    /// For each off-diagonal pair of the last analysis, its slot in `env`.
    slots: Vec<usize>,
    /// A row's neighbours being sorted, and the rows by degree (where
    /// each component's search starts).
    neighbours: Vec<u32>,
    by_degree: Vec<u32>,
    /// Right-hand side in the ordered numbering.
    y: Vec<f64>,
    factored: bool,
}

impl EnvelopeCholesky {
    /// Orders and lays out an `n x n` matrix with a diagonal and the
    /// off-diagonal entries `pairs` (each `(i, j)`, `i != j`, stands for
    /// both `(i, j)` and `(j, i)`; a pair may repeat). Returns the
    /// factor's work, `sum over rows of (segment length)^2`, about its
    /// multiply-adds.
    pub fn analyse(&mut self, n: usize, pairs: &[(u32, u32)]) -> Result<usize, CholeskyError> {
        self.factored = false;
        self.n = n;
        for &(i, j) in pairs {
            if i as usize >= n || j as usize >= n {
                return Err(CholeskyError::OutOfRange { row: i as usize, col: j as usize, n });
            }
            if i == j {
                return Err(CholeskyError::OnDiagonal { row: i as usize });
            }
        }
        self.adj.rebuild(n, || pairs.iter().flat_map(|&(i, j)| [(i as usize, j), (j as usize, i)]));
        self.adj.sort_each();
        self.order_reverse_cuthill_mckee(n);
        // Each ordered row's envelope: back to its earliest neighbour.
        self.first.clear();
        self.start.clear();
        let mut len = 0;
        for r in 0..n {
            let i = self.order[r] as usize;
            let neighbours = self.adj.of(i);
            let first = neighbours.iter().map(|&j| self.position[j as usize]).fold(r as u32, u32::min);
            self.first.push(first);
            self.start.push(len);
            len += r + 1 - first as usize;
        }
        self.start.push(len);
        self.env.clear();
        self.env.resize(len, 0.0);
        self.slots.clear();
        for &(i, j) in pairs {
            let (a, b) = (self.position[i as usize] as usize, self.position[j as usize] as usize);
            let (row, col) = (a.max(b), a.min(b));
            self.slots.push(self.start[row] + col - self.first[row] as usize);
        }
        Ok((0..n).map(|r| (self.start[r + 1] - self.start[r]).pow(2)).sum())
    }

    /// Factors the matrix laid out by the last [`EnvelopeCholesky::analyse`]
    /// with diagonal `diag` (one per row) and off-diagonal values `off`
    /// (one per pair given there, repeats summed). Panics when the lengths
    /// do not match the analysis (a caller's bug).
    pub fn factor(&mut self, diag: &[f64], off: &[f64]) -> Result<(), CholeskyError> {
        assert_eq!(diag.len(), self.n, "EnvelopeCholesky::factor: one diagonal value per row");
        assert_eq!(off.len(), self.slots.len(), "EnvelopeCholesky::factor: one value per analysed pair");
        self.factored = false;
        self.env.iter_mut().for_each(|v| *v = 0.0);
        for (r, &i) in self.order.iter().enumerate() {
            self.env[self.start[r + 1] - 1] = diag[i as usize];
        }
        for (&slot, &v) in self.slots.iter().zip(off) {
            self.env[slot] += v;
        }
        for r in 0..self.n {
            let fr = self.first[r] as usize;
            let (done, rest) = self.env.split_at_mut(self.start[r]);
            let row = &mut rest[..r + 1 - fr];
            for c in fr..r {
                let fc = self.first[c] as usize;
                let from = fr.max(fc);
                let col_row = &done[self.start[c]..self.start[c + 1]];
                let sum = dot(&row[from - fr..c - fr], &col_row[from - fc..c - fc]);
                row[c - fr] = (row[c - fr] - sum) / col_row[c - fc];
            }
            let d = row[r - fr] - dot(&row[..r - fr], &row[..r - fr]);
            if !(d > 0.0 && d.is_finite()) {
                return Err(CholeskyError::NotPositiveDefinite { pivot: r });
            }
            row[r - fr] = d.sqrt();
        }
        self.factored = true;
        Ok(())
    }

    /// Solves `A x = b` in place. Panics if the factor is stale or `b` is
    /// not of the matrix's order (a caller's bug).
    pub fn solve(&mut self, b: &mut [f64]) {
        assert!(self.factored, "EnvelopeCholesky::solve before factor");
        assert_eq!(b.len(), self.n, "EnvelopeCholesky::solve: right-hand side of the wrong length");
        self.y.clear();
        self.y.extend(self.order.iter().map(|&i| b[i as usize]));
        let y = &mut self.y;
        // L z = y, row by row.
        for r in 0..self.n {
            let fr = self.first[r] as usize;
            let row = &self.env[self.start[r]..self.start[r + 1]];
            y[r] = (y[r] - dot(&row[..r - fr], &y[fr..r])) / row[r - fr];
        }
        // L^T x = z, column by column from the last.
        for r in (0..self.n).rev() {
            let fr = self.first[r] as usize;
            let row = &self.env[self.start[r]..self.start[r + 1]];
            y[r] /= row[r - fr];
            let yr = y[r];
            for (yk, &l) in y[fr..r].iter_mut().zip(&row[..r - fr]) {
                *yk -= l * yr;
            }
        }
        for (&i, &v) in self.order.iter().zip(y.iter()) {
            b[i as usize] = v;
        }
    }

    /// The stored entries of the factor (its envelope) after the last analysis.
    pub fn stored(&self) -> usize {
        self.env.len()
    }

    /// Cuthill-McKee from a least-connected row of each component (lowest
    /// index among equals), neighbours by increasing degree, reversed.
    fn order_reverse_cuthill_mckee(&mut self, n: usize) {
        let degree = |adj: &Buckets<u32>, i: u32| adj.of(i as usize).len();
        self.position.clear();
        self.position.resize(n, u32::MAX);
        self.order.clear();
        let mut by_degree = std::mem::take(&mut self.by_degree);
        by_degree.clear();
        by_degree.extend(0..n as u32);
        by_degree.sort_unstable_by_key(|&i| (degree(&self.adj, i), i));
        for &root in &by_degree {
            if self.position[root as usize] != u32::MAX {
                continue;
            }
            self.position[root as usize] = self.order.len() as u32;
            self.order.push(root);
            let mut head = self.order.len() - 1;
            while head < self.order.len() {
                let i = self.order[head] as usize;
                head += 1;
                self.neighbours.clear();
                let list = self.adj.of(i);
                self.neighbours.extend(list.iter().copied().filter(|&j| self.position[j as usize] == u32::MAX));
                self.neighbours.dedup();
                self.neighbours.sort_unstable_by_key(|&j| (degree(&self.adj, j), j));
                for &j in &self.neighbours {
                    self.position[j as usize] = self.order.len() as u32;
                    self.order.push(j);
                }
            }
        }
        self.by_degree = by_degree;
        self.order.reverse();
        for (r, &i) in self.order.iter().enumerate() {
            self.position[i as usize] = r as u32;
        }
    }
}

/// `a . b`, summed in order.
fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A test system: its order, off-diagonal pairs, diagonal and pair values.
    struct System {
        n: usize,
        pairs: Vec<(u32, u32)>,
        diag: Vec<f64>,
        off: Vec<f64>,
    }

    /// A random sparse symmetric matrix made diagonally dominant: pairs of
    /// a 2D grid's neighbours (shuffled numbering) plus a repeated far one.
    fn system(n_side: usize, seed: u64) -> System {
        let mut s = seed;
        let mut next = move || {
            s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (s >> 11) as f64 / (1u64 << 53) as f64
        };
        let n = n_side * n_side;
        let mut label: Vec<u32> = (0..n as u32).collect();
        for i in (1..n).rev() {
            label.swap(i, (next() * (i + 1) as f64) as usize);
        }
        let mut pairs = Vec::new();
        for y in 0..n_side {
            for x in 0..n_side {
                let i = y * n_side + x;
                if x + 1 < n_side {
                    pairs.push((label[i], label[i + 1]));
                }
                if y + 1 < n_side {
                    pairs.push((label[i], label[i + n_side]));
                    if x + 1 < n_side {
                        pairs.push((label[i], label[i + n_side + 1]));
                    }
                }
            }
        }
        if n > 1 {
            pairs.push((label[0], label[n - 1]));
            pairs.push((label[0], label[n - 1]));
        }
        let off: Vec<f64> = pairs.iter().map(|_| next() * 2.0 - 1.0).collect();
        let mut diag = vec![0.0; n];
        for (&(i, j), v) in pairs.iter().zip(&off) {
            diag[i as usize] += v.abs();
            diag[j as usize] += v.abs();
        }
        diag.iter_mut().for_each(|d| *d += 1e-3 + next());
        System { n, pairs, diag, off }
    }

    fn dense(sys: &System) -> nalgebra::DMatrix<f64> {
        let mut a = nalgebra::DMatrix::<f64>::from_diagonal(&nalgebra::DVector::from_column_slice(&sys.diag));
        for (&(i, j), &v) in sys.pairs.iter().zip(&sys.off) {
            a[(i as usize, j as usize)] += v;
            a[(j as usize, i as usize)] += v;
        }
        a
    }

    /// Solutions satisfy the system to rounding, on grids numbered at
    /// random (the ordering must find the band) with a repeated far pair,
    /// and the buffers serve a second, different system.
    #[test]
    fn solves_sparse_systems_to_rounding() {
        let mut chol = EnvelopeCholesky::default();
        for (side, seed) in [(1, 1), (7, 2), (15, 3)] {
            let sys = system(side, seed);
            let n = sys.n;
            chol.analyse(n, &sys.pairs).unwrap();
            chol.factor(&sys.diag, &sys.off).unwrap();
            let b: Vec<f64> = (0..n).map(|i| (i as f64 * 0.37).sin() + 0.5).collect();
            let mut x = b.clone();
            chol.solve(&mut x);
            let a = dense(&sys);
            let r = &a * nalgebra::DVector::from_column_slice(&x) - nalgebra::DVector::from_column_slice(&b);
            let rel = r.norm() / b.iter().map(|v| v * v).sum::<f64>().sqrt();
            assert!(rel < 1e-15, "{side} x {side}: relative residual {rel:e}");
        }
    }

    /// Reverse Cuthill-McKee finds a grid's band: a 15 x 15 grid with one
    /// diagonal, numbered at random, keeps 11.4 entries a row (its band
    /// is 16; a random order's envelope is of the order of n/3 = 75).
    #[test]
    fn the_ordering_finds_a_narrow_envelope() {
        let sys = system(15, 4);
        let n = sys.n;
        let mut chol = EnvelopeCholesky::default();
        let work = chol.analyse(n, &sys.pairs[..sys.pairs.len() - 2]).unwrap();
        let per_row = chol.stored() as f64 / n as f64;
        assert!(per_row < 12.0, "{per_row} entries a row");
        assert!(work < 33_000, "work {work}");
    }

    /// An indefinite matrix is refused with the pivot that failed; pairs
    /// outside the matrix or on its diagonal are refused before that.
    #[test]
    fn refuses_indefinite_matrices_and_bad_pairs() {
        let mut chol = EnvelopeCholesky::default();
        chol.analyse(2, &[(0, 1)]).unwrap();
        let err = chol.factor(&[1.0, 1.0], &[2.0]).unwrap_err();
        assert!(matches!(err, CholeskyError::NotPositiveDefinite { .. }), "{err:?}");
        assert!(matches!(chol.analyse(2, &[(0, 2)]), Err(CholeskyError::OutOfRange { row: 0, col: 2, n: 2 })));
        assert!(matches!(chol.analyse(2, &[(1, 1)]), Err(CholeskyError::OnDiagonal { row: 1 })));
    }
}
