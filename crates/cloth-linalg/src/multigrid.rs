//! An aggregation multigrid V-cycle, used as a PCG preconditioner.
//!
//! Block-Jacobi needs more iterations the stiffer the cloth and the finer
//! the grid (its condition number grows like `h^2 k / m`). A V-cycle damps
//! the smooth error that Jacobi cannot: each level groups nodes into
//! aggregates (piecewise-constant prolongation `P`, restriction `P^T`),
//! the coarse operator is the Galerkin product `P^T A P` (a block sum, so
//! its pattern is built once and each refill costs about one SpMV), the
//! smoother is damped block-Jacobi before and after the coarse correction,
//! and the coarsest level is solved by dense Cholesky. The cycle is
//! symmetric, so PCG stays conjugate-gradient.

use crate::{BlockPattern, BlockSparseMatrix, Mat3, Vec3, par::ROW_CHUNK};
use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;

/// One level's grouping of nodes: `coarse_of[i]` is node `i`'s aggregate.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Aggregation {
    /// Aggregate of each fine node, in `0..n_coarse`.
    pub coarse_of: Vec<u32>,
    /// Number of aggregates.
    pub n_coarse: usize,
}

/// Why a hierarchy could not be built.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum MultigridError {
    /// An aggregation does not fit the level it is applied to.
    #[error("aggregation {level} maps {got} nodes but its level has {expected}")]
    SizeMismatch {
        /// Level index.
        level: usize,
        /// Nodes on that level.
        expected: usize,
        /// Nodes in the aggregation.
        got: usize,
    },
    /// An aggregate index is out of range or an aggregate is empty.
    #[error("aggregation {level} has an out-of-range or empty aggregate")]
    BadAggregate {
        /// Level index.
        level: usize,
    },
}

/// Gathers, for each target index, the list of source indices mapping to it
/// (CSR), so sums can run in parallel over targets in a fixed order.
#[derive(Debug, Clone)]
struct Gather {
    ptr: Vec<usize>,
    src: Vec<u32>,
}

impl Gather {
    fn new(target_of: impl Iterator<Item = usize> + Clone, n_targets: usize) -> Self {
        let mut ptr = vec![0usize; n_targets + 1];
        for t in target_of.clone() {
            ptr[t + 1] += 1;
        }
        for k in 0..n_targets {
            ptr[k + 1] += ptr[k];
        }
        let mut fill = ptr.clone();
        let mut src = vec![0u32; ptr[n_targets]];
        for (s, t) in target_of.enumerate() {
            src[fill[t]] = s as u32;
            fill[t] += 1;
        }
        Self { ptr, src }
    }

    fn sources(&self, t: usize) -> &[u32] {
        &self.src[self.ptr[t]..self.ptr[t + 1]]
    }
}

#[derive(Debug, Clone)]
struct Level {
    /// Fine node -> aggregate.
    coarse_of: Vec<u32>,
    /// Aggregate -> fine nodes (restriction).
    members: Gather,
    /// Coarse slot -> fine slots (Galerkin product).
    slots: Gather,
    /// The coarse operator `P^T A P`.
    coarse: BlockSparseMatrix,
    /// Damped inverse diagonal blocks of this level's (fine) operator (for
    /// a paired node, its diagonal block of the pair's inverse).
    inv_diag: Vec<Mat3>,
    /// Nodes smoothed as pairs (the finest level only): each node's
    /// partner (itself when unpaired) and the pair's inverse's
    /// off-diagonal block `(A_pair^-1)_ij`, damped.
    pairs: Option<(Vec<u32>, Vec<Mat3>)>,
    b: Vec<Vec3>,
    x: Vec<Vec3>,
    r: Vec<Vec3>,
}

/// An aggregation multigrid hierarchy; rebuild the operators with
/// [`Multigrid::update`] whenever the fine matrix changes (same pattern).
#[derive(Debug, Clone)]
pub struct Multigrid {
    levels: Vec<Level>,
    /// Dense coarsest operator, factorised in place (lower Cholesky factor).
    coarsest: DMatrix<f64>,
    /// Whether the factorisation succeeded (else: block-Jacobi on the coarsest level).
    coarsest_ok: bool,
    coarsest_rhs: DVector<f64>,
    coarsest_inv_diag: Vec<Mat3>,
    coarsest_b: Vec<Vec3>,
    coarsest_x: Vec<Vec3>,
    omega: f64,
}

/// Smoother damping for matrices of two-node elements (links). The
/// symmetric cycle is positive definite when `2 D / omega - A` is. A sum
/// of PSD element matrices over `k` nodes each (plus a diagonal) satisfies
/// `A <= k D` (Cauchy-Schwarz on each element's PSD blocks,
/// `|x_a^T K_ab x_b| <= sqrt(x_a^T K_aa x_a x_b^T K_bb x_b)`), on every
/// level too (an aggregated element still touches at most `k` nodes); so
/// `omega < 2 / k` is safe: `omega < 1` for links. 0.7 took the fewest
/// iterations among 0.45-0.8 on the 75 x 75 hanging cloth; elements of `k`
/// nodes get `0.7 * 2 / k` ([`Multigrid::for_element_size`]).
const OMEGA: f64 = 0.7;

impl Multigrid {
    /// Builds the hierarchy for matrices with pattern `fine`; `aggregations[l]`
    /// coarsens level `l`.
    pub fn new(fine: &BlockPattern, aggregations: &[Aggregation]) -> Result<Self, MultigridError> {
        let mut levels = Vec::new();
        let mut pattern = fine.clone();
        for (l, agg) in aggregations.iter().enumerate() {
            let n = pattern.n();
            if agg.coarse_of.len() != n {
                return Err(MultigridError::SizeMismatch { level: l, expected: n, got: agg.coarse_of.len() });
            }
            if agg.coarse_of.iter().any(|&c| c as usize >= agg.n_coarse) {
                return Err(MultigridError::BadAggregate { level: l });
            }
            let members = Gather::new(agg.coarse_of.iter().map(|&c| c as usize), agg.n_coarse);
            if (0..agg.n_coarse).any(|c| members.sources(c).is_empty()) {
                return Err(MultigridError::BadAggregate { level: l });
            }
            let pairs: Vec<(usize, usize)> = (0..n)
                .flat_map(|i| pattern.row_cols(i).iter().map(move |&j| (i, j as usize)))
                .map(|(i, j)| (agg.coarse_of[i] as usize, agg.coarse_of[j] as usize))
                .collect();
            let coarse_pattern = BlockPattern::from_pairs(agg.n_coarse, pairs).expect("aggregates are in range");
            let slot_target: Vec<usize> = (0..n)
                .flat_map(|i| {
                    let (ci, cols) = (agg.coarse_of[i] as usize, pattern.row_cols(i));
                    let cp = &coarse_pattern;
                    cols.iter().map(move |&j| cp.slot(ci, agg.coarse_of[j as usize] as usize).expect("in pattern"))
                })
                .collect();
            let slots = Gather::new(slot_target.iter().copied(), coarse_pattern.nnz_blocks());
            levels.push(Level {
                coarse_of: agg.coarse_of.clone(),
                members,
                slots,
                coarse: BlockSparseMatrix::new(coarse_pattern.clone()),
                inv_diag: vec![Mat3::identity(); n],
                pairs: None,
                b: vec![Vec3::zeros(); n],
                x: vec![Vec3::zeros(); n],
                r: vec![Vec3::zeros(); n],
            });
            pattern = coarse_pattern;
        }
        let nc = pattern.n();
        Ok(Self {
            levels,
            coarsest: DMatrix::zeros(3 * nc, 3 * nc),
            coarsest_ok: false,
            coarsest_rhs: DVector::zeros(3 * nc),
            coarsest_inv_diag: vec![Mat3::identity(); nc],
            coarsest_b: vec![Vec3::zeros(); nc],
            coarsest_x: vec![Vec3::zeros(); nc],
            omega: OMEGA,
        })
    }

    /// Sets the smoother's damping for a matrix assembled from PSD element
    /// matrices of at most `nodes` nodes each (2 for links, 3 for
    /// triangles, 6 for Volino's bending triangles): `omega = 0.7 * 2 / nodes`, which keeps
    /// the cycle positive definite (see [`OMEGA`]); the default is links.
    pub fn for_element_size(mut self, nodes: usize) -> Self {
        self.omega = OMEGA * 2.0 / nodes.max(2) as f64;
        self
    }

    /// Smooths the finest level's nodes `(i, j)` of `pairs` together: a
    /// 6 x 6 block of the smoother instead of two 3 x 3 ones. For nodes
    /// tied by a coupling much stiffer than their others (a seam's
    /// stitch), point-block Jacobi divides each node's residual by a
    /// diagonal the stiff coupling inflates, so the pair barely follows its
    /// neighbours; the pair's block does not. Pairs that repeat a node (or
    /// are out of range) are skipped. The cycle stays symmetric positive
    /// definite: it is block-Jacobi on a coarser partition, and an element
    /// touches no more blocks than before.
    pub fn with_pairs(mut self, pairs: &[(usize, usize)]) -> Self {
        let Some(first) = self.levels.first_mut() else { return self };
        let n = first.inv_diag.len();
        let mut partner: Vec<u32> = (0..n as u32).collect();
        let mut any = false;
        for &(i, j) in pairs {
            if i < n && j < n && i != j && partner[i] as usize == i && partner[j] as usize == j {
                (partner[i], partner[j]) = (j as u32, i as u32);
                any = true;
            }
        }
        if any {
            first.pairs = Some((partner, vec![Mat3::zeros(); n]));
        }
        self
    }

    /// Number of levels including the finest.
    pub fn depth(&self) -> usize {
        self.levels.len() + 1
    }

    /// Rebuilds every level's operator from the fine matrix `a`.
    pub fn update(&mut self, a: &BlockSparseMatrix) {
        let omega = self.omega;
        for l in 0..self.levels.len() {
            let (done, rest) = self.levels.split_at_mut(l);
            let fine = if l == 0 { a } else { &done[l - 1].coarse };
            let level = &mut rest[0];
            inverse_diagonal(fine, omega, &mut level.inv_diag);
            if let Some((partner, inv_off)) = &mut level.pairs {
                invert_pairs(fine, omega, partner, &mut level.inv_diag, inv_off);
            }
            let slots = &level.slots;
            let src = fine.values();
            level.coarse.values_mut().par_chunks_mut(ROW_CHUNK).enumerate().for_each(|(c, chunk)| {
                for (k, v) in chunk.iter_mut().enumerate() {
                    *v = slots.sources(c * ROW_CHUNK + k).iter().map(|&s| src[s as usize]).sum();
                }
            });
        }
        let last = self.levels.last().map_or(a, |l| &l.coarse);
        inverse_diagonal(last, 1.0, &mut self.coarsest_inv_diag);
        self.coarsest.fill(0.0);
        for (i, j, b) in last.blocks() {
            self.coarsest.fixed_view_mut::<3, 3>(3 * i, 3 * j).copy_from(b);
        }
        self.coarsest_ok = cholesky_in_place(&mut self.coarsest);
    }

    /// `z = V-cycle(r)`, a symmetric positive definite approximation of `A^-1 r`.
    pub fn apply(&mut self, a: &BlockSparseMatrix, r: &[Vec3], z: &mut [Vec3]) {
        if self.levels.is_empty() {
            self.coarsest_b.copy_from_slice(r);
            self.solve_coarsest();
            z.copy_from_slice(&self.coarsest_x);
            return;
        }
        self.levels[0].b.copy_from_slice(r);
        // Down: pre-smooth from zero, restrict the residual.
        for l in 0..self.levels.len() {
            let (before, after) = self.levels.split_at_mut(l);
            let (level, rest) = after.split_first_mut().expect("level l exists");
            let op = if l == 0 { a } else { &before[l - 1].coarse };
            jacobi_from_zero(&level.inv_diag, level.pairs.as_ref(), &level.b, &mut level.x);
            op.residual(&level.b, &level.x, &mut level.r);
            let target = if let Some(next) = rest.first_mut() { &mut next.b } else { &mut self.coarsest_b };
            restrict(&level.members, &level.r, target);
        }
        self.solve_coarsest();
        // Up: prolong the correction, post-smooth.
        for l in (0..self.levels.len()).rev() {
            let (before, after) = self.levels.split_at_mut(l);
            let (level, rest) = after.split_first_mut().expect("level l exists");
            let op = if l == 0 { a } else { &before[l - 1].coarse };
            let correction = rest.first().map_or(&self.coarsest_x, |next| &next.x);
            level.x.par_iter_mut().zip(level.coarse_of.par_iter()).with_min_len(ROW_CHUNK).for_each(|(xi, &c)| {
                *xi += correction[c as usize];
            });
            op.residual(&level.b, &level.x, &mut level.r);
            let (r, inv_diag, pairs) = (&level.r, &level.inv_diag, level.pairs.as_ref());
            level.x.par_iter_mut().enumerate().with_min_len(ROW_CHUNK).for_each(|(i, xi)| {
                *xi += smoothed(inv_diag, pairs, r, i);
            });
        }
        z.copy_from_slice(&self.levels[0].x);
    }

    /// `coarsest_x = A_c^-1 coarsest_b` by the stored Cholesky factor.
    fn solve_coarsest(&mut self) {
        if !self.coarsest_ok {
            let (b, d) = (&self.coarsest_b, &self.coarsest_inv_diag);
            self.coarsest_x.iter_mut().zip(b).zip(d).for_each(|((xi, bi), di)| *xi = di * bi);
            return;
        }
        for (i, bi) in self.coarsest_b.iter().enumerate() {
            self.coarsest_rhs.fixed_rows_mut::<3>(3 * i).copy_from(bi);
        }
        cholesky_solve_in_place(&self.coarsest, &mut self.coarsest_rhs);
        for (i, xi) in self.coarsest_x.iter_mut().enumerate() {
            *xi = self.coarsest_rhs.fixed_rows::<3>(3 * i).into_owned();
        }
    }
}

/// Overwrites the lower triangle of the SPD matrix `a` with its Cholesky
/// factor `L` (`a = L L^T`), without allocating. Returns false if `a` is not
/// positive definite.
fn cholesky_in_place(a: &mut DMatrix<f64>) -> bool {
    let n = a.nrows();
    for j in 0..n {
        let mut d = a[(j, j)];
        for k in 0..j {
            d -= a[(j, k)] * a[(j, k)];
        }
        if !(d > 0.0 && d.is_finite()) {
            return false;
        }
        let d = d.sqrt();
        a[(j, j)] = d;
        for i in j + 1..n {
            let mut s = a[(i, j)];
            for k in 0..j {
                s -= a[(i, k)] * a[(j, k)];
            }
            a[(i, j)] = s / d;
        }
    }
    true
}

/// Solves `L L^T x = b` in place with the factor from [`cholesky_in_place`].
fn cholesky_solve_in_place(l: &DMatrix<f64>, b: &mut DVector<f64>) {
    let n = l.nrows();
    for i in 0..n {
        let mut s = b[i];
        for k in 0..i {
            s -= l[(i, k)] * b[k];
        }
        b[i] = s / l[(i, i)];
    }
    for i in (0..n).rev() {
        let mut s = b[i];
        for k in i + 1..n {
            s -= l[(k, i)] * b[k];
        }
        b[i] = s / l[(i, i)];
    }
}

/// `inv[i] = omega * A_ii^-1` (identity where a block is not positive definite).
fn inverse_diagonal(a: &BlockSparseMatrix, omega: f64, inv: &mut [Mat3]) {
    inv.par_iter_mut().enumerate().with_min_len(ROW_CHUNK).for_each(|(i, p)| {
        *p = a.diag(i).cholesky().map_or_else(Mat3::identity, |c| c.inverse()) * omega;
    });
}

/// The pairs' damped inverse blocks: `omega [A_ii A_ij; A_ji A_jj]^-1`
/// into the diagonal and off-diagonal slots (a pair whose block is not
/// positive definite keeps its two point blocks).
fn invert_pairs(a: &BlockSparseMatrix, omega: f64, partner: &[u32], inv_diag: &mut [Mat3], inv_off: &mut [Mat3]) {
    for i in 0..partner.len() {
        let j = partner[i] as usize;
        if j <= i {
            continue;
        }
        let Some(slot) = a.pattern().slot(i, j) else { continue };
        let mut m = nalgebra::Matrix6::<f64>::zeros();
        let (aij, aji) = (a.values()[slot], a.values()[slot].transpose());
        m.fixed_view_mut::<3, 3>(0, 0).copy_from(a.diag(i));
        m.fixed_view_mut::<3, 3>(0, 3).copy_from(&aij);
        m.fixed_view_mut::<3, 3>(3, 0).copy_from(&aji);
        m.fixed_view_mut::<3, 3>(3, 3).copy_from(a.diag(j));
        let Some(c) = m.cholesky() else { continue };
        let inv = c.inverse() * omega;
        inv_diag[i] = inv.fixed_view::<3, 3>(0, 0).into_owned();
        inv_off[i] = inv.fixed_view::<3, 3>(0, 3).into_owned();
        inv_off[j] = inv.fixed_view::<3, 3>(3, 0).into_owned();
        inv_diag[j] = inv.fixed_view::<3, 3>(3, 3).into_owned();
    }
}

/// The smoother's correction at node `i` for residual `r`.
#[inline]
fn smoothed(inv_diag: &[Mat3], pairs: Option<&(Vec<u32>, Vec<Mat3>)>, r: &[Vec3], i: usize) -> Vec3 {
    let own = inv_diag[i] * r[i];
    match pairs {
        Some((partner, inv_off)) if partner[i] as usize != i => own + inv_off[i] * r[partner[i] as usize],
        _ => own,
    }
}

fn jacobi_from_zero(inv_diag: &[Mat3], pairs: Option<&(Vec<u32>, Vec<Mat3>)>, b: &[Vec3], x: &mut [Vec3]) {
    x.par_iter_mut().enumerate().with_min_len(ROW_CHUNK).for_each(|(i, xi)| *xi = smoothed(inv_diag, pairs, b, i));
}

/// `target[c] = sum of src over aggregate c`, in member order.
fn restrict(members: &Gather, src: &[Vec3], target: &mut [Vec3]) {
    target.par_iter_mut().enumerate().with_min_len(ROW_CHUNK / 4).for_each(|(c, t)| {
        *t = members.sources(c).iter().map(|&i| src[i as usize]).sum();
    });
}
