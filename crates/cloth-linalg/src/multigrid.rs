//! An aggregation multigrid cycle, used as a PCG preconditioner.
//!
//! Block-Jacobi needs more iterations the stiffer the cloth and the finer
//! the grid (its condition number grows like `h^2 k / m`); a multigrid
//! cycle damps the smooth error that Jacobi cannot. Each level groups
//! nodes into aggregates (piecewise-constant prolongation `P`, restriction
//! `P^T`), the coarse operator is the Galerkin block sum `P^T A P` (its
//! pattern built once, each refill about one SpMV), damped block-Jacobi
//! smooths before and after the coarse correction, and the coarsest level
//! is solved by dense Cholesky.
//!
//! - **W below the first coarse level** ([`Cycle::W`]): every coarse
//!   problem below the first is solved by two cycles, which keeps the
//!   iterations from growing with the grid for about 10% more arithmetic.
//! - **K-cycle on large grids** ([`Cycle::K`]; Notay & Vassilevski 2008,
//!   from [`K_CYCLE_MIN_NODES`]): two steps of flexible CG on each coarse
//!   problem; PCG then takes the flexible update.
//! - **A smoothed first level** ([`Multigrid::smoothed`]; Vaněk, Mandel &
//!   Brezina 1996, from [`SMOOTHED_MIN_NODES`]) for matrices solved once a
//!   step: plain aggregates correct less well as `h^2 k / m` grows.
//! - **Couplings outside the matrix** ([`Multigrid::set_couplings`]: a
//!   self-collision contact's blocks between its particles) on every
//!   level: their Galerkin products over the aggregates, in the cycle's
//!   residuals, and in the coarsest factor.
//! - **`f32` operators** on levels of at least 500,000 blocks: the
//!   cycle's residuals and the K-cycle's coarse Krylov products read a
//!   rounded copy and accumulate in `f64`, so the W-cycle stays symmetric
//!   positive definite and PCG's own products keep full precision.
//!
//! Measurements behind each choice: `docs/results/solver-before-after.md`
//! and `docs/results/scaling.md`.

use crate::{
    BlockPattern, BlockSparseMatrix, Mat3, Vec3,
    par::{ROW_CHUNK, chunk_count, dot_with},
};
use rayon::prelude::*;

mod coarsest;
mod kernels;
mod level_couplings;
mod single;
mod smoothed;

use coarsest::*;
use kernels::*;
use level_couplings::LevelCouplings;
use single::*;

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
    /// Fine slot -> coarse slot (the inverse of `slots`).
    slot_target: Vec<u32>,
    /// Coarse slots a partial refill recomputes, each with its row and
    /// column, and whether it is marked in that list (see
    /// [`Multigrid::update_rows`]).
    dirty: Vec<Dirty>,
    marked: Vec<bool>,
    /// Per node, whether a partial refill recomputed its diagonal inverse
    /// (false between refills).
    refilled: Vec<bool>,
    /// The coarse operator `P^T A P`.
    coarse: BlockSparseMatrix,
    /// This level's own operator (the fine matrix, or the previous
    /// level's `coarse`) in single precision, for the residuals and the
    /// K-cycle's products with it, on levels of at least
    /// `SINGLE_MIN_BLOCKS` blocks (smaller ones read the `f64` operator).
    single: Option<SinglePrecision>,
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
    /// The first of two coarse corrections while the second is computed
    /// (empty on the finest).
    first: Vec<Vec3>,
    /// `A c1` in the K-cycle's coarse solve (empty on the finest).
    v: Vec<Vec3>,
    /// Chunk partials for this level's dot products.
    partials: Vec<f64>,
    /// The solve's couplings on this level's operator (see
    /// [`Multigrid::set_couplings`]).
    couplings: LevelCouplings,
}

/// An aggregation multigrid hierarchy; rebuild the operators with
/// [`Multigrid::update`] whenever the fine matrix changes (same pattern).
#[derive(Debug, Clone)]
pub struct Multigrid {
    levels: Vec<Level>,
    coarsest: Coarsest,
    omega: f64,
    cycle: Cycle,
    /// The finest operator's changed slots in a partial refill.
    fine_dirty: Vec<Dirty>,
    /// Per fine node, whether [`Multigrid::set_couplings_rows`] is to
    /// make its terms again (false between calls), and those terms.
    coupling_marks: Vec<bool>,
    redone_terms: Vec<u32>,
    /// A smoothed-aggregation finest level in place of `levels` and
    /// `coarsest` (see [`Multigrid::smoothed`]).
    smoothed: Option<Box<smoothed::SmoothedFirst>>,
}

/// A slot of a level's operator that a partial refill recomputes: `(slot,
/// row, column)`.
type Dirty = (u32, u32, u32);

/// Share of the finest operator's slots above which
/// [`Multigrid::update_rows`] refills everything (in parallel) instead.
const PARTIAL_REFILL_MAX_SHARE: f64 = 0.25;

/// How a cycle solves its coarse problems (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Cycle {
    /// One cycle on the first coarse problem, two stationary cycles on
    /// every problem below it (`e = B r`, `e += B (r - A e)`): a fixed
    /// symmetric positive definite operator.
    W,
    /// Notay & Vassilevski's K-cycle: every coarse problem is solved by two
    /// steps of flexible conjugate gradients preconditioned by the next
    /// level's cycle. The cycle is then a nonlinear function of its input
    /// ([`Multigrid::is_nonlinear`]), and PCG uses the flexible
    /// (Polak-Ribiere) update.
    K,
}

/// Fine-level nodes from which [`Multigrid::new`] takes the K-cycle (the W
/// below). Measured (BDF2 at 1/90 s, PCG to 1e-3, 2 threads; CG a step and
/// solve ms a step, W -> K): hanging cloth at 65 x 65 10.7 -> 8.8 CG but
/// 7.4 -> 10.6 ms; at 129 x 129 13.1 -> 8.7, 84 -> 73 ms; at 257 x 257
/// 17.4 -> 10.7, 372 -> 323 ms; the 101 x 101 drape on a sphere 56.8 ->
/// 50.8 CG, 217-235 -> 239-271 ms (its contact passes' re-solves take a
/// few iterations each, which a stronger cycle does not shorten); the
/// Table-1 one-piece 43.5 -> 40.4 CG, 25% more solve time.
pub const K_CYCLE_MIN_NODES: usize = 16_000;

/// Fine-level nodes from which a hierarchy solved once per update is worth
/// a smoothed first level ([`Multigrid::smoothed`]; `ClothModel::multigrid`
/// takes it for models without solids). Measured on the hanging cloth
/// (BDF2 at 1/90 s, PCG to 1e-3, 0.2 s, 2 threads; CG a step and ms a step,
/// plain K-cycle -> smoothed): 129 x 129 8.7 -> 6.3 CG, 74-75 -> 100-102
/// ms; 257 x 257 10.7 -> 6.7 CG, 442-454 -> 468-517 ms; 513 x 513 19.4 ->
/// 7.6 CG, 2,429 -> 1,714 ms. Each update costs about ten products with
/// the fine operator and each cycle reads a first coarse operator of 24.5
/// blocks a row: below some 100,000 nodes the saved iterations do not pay
/// for them.
pub const SMOOTHED_MIN_NODES: usize = 100_000;

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
        Self::with_single_precision_from(fine, aggregations, SINGLE_MIN_BLOCKS)
    }

    /// As [`Multigrid::new`], with `f32` copies of the operators of the
    /// levels of at least `blocks` blocks for the cycle's residuals and
    /// products (`new` takes `SINGLE_MIN_BLOCKS`; see the module docs).
    pub fn with_single_precision_from(
        fine: &BlockPattern,
        aggregations: &[Aggregation],
        blocks: usize,
    ) -> Result<Self, MultigridError> {
        check_aggregations(fine.n(), aggregations)?;
        let mut levels = Vec::new();
        let mut pattern = fine.clone();
        for (l, agg) in aggregations.iter().enumerate() {
            let n = pattern.n();
            let members = Gather::new(agg.coarse_of.iter().map(|&c| c as usize), agg.n_coarse);
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
                slot_target: slot_target.iter().map(|&t| t as u32).collect(),
                dirty: Vec::new(),
                marked: vec![false; coarse_pattern.nnz_blocks()],
                refilled: vec![false; n],
                coarse: BlockSparseMatrix::new(coarse_pattern.clone()),
                single: (pattern.nnz_blocks() >= blocks).then(|| SinglePrecision::new(&pattern)),
                inv_diag: vec![Mat3::identity(); n],
                pairs: None,
                b: vec![Vec3::zeros(); n],
                x: vec![Vec3::zeros(); n],
                r: vec![Vec3::zeros(); n],
                first: if l == 0 { Vec::new() } else { vec![Vec3::zeros(); n] },
                v: if l == 0 { Vec::new() } else { vec![Vec3::zeros(); n] },
                partials: vec![0.0; chunk_count(n)],
                couplings: LevelCouplings::default(),
            });
            pattern = coarse_pattern;
        }
        let cycle = if fine.n() >= K_CYCLE_MIN_NODES { Cycle::K } else { Cycle::W };
        let coarsest = Coarsest::new(pattern.n());
        Ok(Self {
            levels,
            coarsest,
            omega: OMEGA,
            cycle,
            fine_dirty: Vec::new(),
            coupling_marks: Vec::new(),
            redone_terms: Vec::new(),
            smoothed: None,
        })
    }

    /// A hierarchy whose finest level is smoothed aggregation (`P = (I -
    /// omega_p D^-1 A_f) P_0` over `aggregations[0]`, `A_c = P^T A P`)
    /// above the plain K-cycle hierarchy of `A_c` over the other
    /// aggregations (see the `smoothed` module). Its iterations stay nearly
    /// flat as the grid is refined where the plain hierarchy's grow; each
    /// [`Multigrid::update`] costs about ten products with `A`, and
    /// [`Multigrid::update_rows`] refills it whole, so it pays on large
    /// matrices solved once per update, not for contact passes. The first
    /// update fixes which couplings are strong. Without aggregations it is
    /// [`Multigrid::new`]'s direct solve. The first update panics if a row
    /// of `P`, `A P` or `P^T A P` would meet more than 255 aggregates (a
    /// cloth's meet 4, 16 and 25-50).
    pub fn smoothed(fine: &BlockPattern, aggregations: &[Aggregation]) -> Result<Self, MultigridError> {
        Self::smoothed_with_single_precision_from(fine, aggregations, SINGLE_MIN_BLOCKS)
    }

    /// As [`Multigrid::smoothed`], with `f32` copies of the operators of at
    /// least `blocks` blocks for the cycle's residuals.
    pub fn smoothed_with_single_precision_from(
        fine: &BlockPattern,
        aggregations: &[Aggregation],
        blocks: usize,
    ) -> Result<Self, MultigridError> {
        check_aggregations(fine.n(), aggregations)?;
        if aggregations.is_empty() {
            return Self::with_single_precision_from(fine, aggregations, blocks);
        }
        let first = smoothed::SmoothedFirst::new(aggregations, blocks);
        Ok(Self {
            levels: Vec::new(),
            coarsest: Coarsest::new(0),
            omega: OMEGA,
            cycle: Cycle::K,
            fine_dirty: Vec::new(),
            coupling_marks: Vec::new(),
            redone_terms: Vec::new(),
            smoothed: Some(Box::new(first)),
        })
    }

    /// The `f32` copy of the finest operator, when it is large enough to
    /// have one (see [`Level::single`]).
    fn finest_single(&self) -> Option<&SinglePrecision> {
        self.levels.first().and_then(|l| l.single.as_ref())
    }

    /// Sets the smoother's damping directly (the smoothed level hands its
    /// own to the hierarchy below it).
    fn set_omega(&mut self, omega: f64) {
        self.omega = omega;
    }

    /// Sets the smoother's damping for a matrix assembled from PSD element
    /// matrices of at most `nodes` nodes each (2 for links, 3 for
    /// triangles, 6 for Volino's bending triangles): `omega = 0.7 * 2 / nodes`, which keeps
    /// the cycle positive definite (see `OMEGA`); the default is links.
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
        if let Some(first) = &mut self.smoothed {
            if let Some(partner) = partners(first.fine_n(), pairs) {
                first.set_partner(partner);
            }
            return self;
        }
        let Some(first) = self.levels.first_mut() else { return self };
        let n = first.inv_diag.len();
        if let Some(partner) = partners(n, pairs) {
            first.pairs = Some((partner, vec![Mat3::zeros(); n]));
        }
        self
    }

    /// Solves the coarse problems as `cycle` says (`new` takes the K-cycle
    /// from [`K_CYCLE_MIN_NODES`] fine nodes, else the W-cycle). A
    /// [`Multigrid::smoothed`] hierarchy has no choice to make: its coarse
    /// problem is the K-cycle's two flexible CG steps, and the levels below
    /// take the K-cycle, so `with_cycle` changes nothing there.
    pub fn with_cycle(mut self, cycle: Cycle) -> Self {
        self.cycle = cycle;
        self
    }

    /// Whether [`Multigrid::apply`] is a nonlinear function of its input
    /// (the K-cycle): PCG must then use the flexible update.
    pub fn is_nonlinear(&self) -> bool {
        self.smoothed.is_some() || self.cycle == Cycle::K && self.levels.len() > 1
    }

    /// Whether the finest level is smoothed aggregation ([`Multigrid::smoothed`]).
    pub fn is_smoothed(&self) -> bool {
        self.smoothed.is_some()
    }

    /// Number of levels including the finest.
    pub fn depth(&self) -> usize {
        self.smoothed.as_ref().map_or(self.levels.len() + 1, |first| first.depth())
    }

    /// Takes the couplings a solve adds to its matrix ([`crate::Couplings`],
    /// each node's part projected by `filter`) into every level's operator
    /// from the next [`Multigrid::update`] or [`Multigrid::update_rows`]
    /// on: the coarse levels get their Galerkin products, the cycle's
    /// residuals their products, and the coarsest factor them. A
    /// [`Multigrid::smoothed`] hierarchy leaves them out.
    pub fn set_couplings(&mut self, couplings: &crate::Couplings, filter: &crate::ConstraintFilter) {
        if self.smoothed.is_some() {
            return;
        }
        let Some(first) = self.levels.first_mut() else {
            self.coarsest.couplings.set_fine(couplings, filter);
            return;
        };
        if couplings.is_empty() && first.couplings.is_empty() {
            return;
        }
        first.couplings.set_fine(couplings, filter);
        for l in 0..self.levels.len() {
            let (done, rest) = self.levels.split_at_mut(l + 1);
            let level = &done[l];
            let next = rest.first_mut().map_or(&mut self.coarsest.couplings, |next| &mut next.couplings);
            level.couplings.aggregate_into(&level.coarse_of, next);
        }
    }

    /// As [`Multigrid::set_couplings`], for the couplings of the last call
    /// under a filter that changed only at the nodes `changed` (the premise
    /// of [`Multigrid::update_rows`]): only the terms reaching those nodes
    /// are made again, on every level, each as `set_couplings` makes it.
    pub fn set_couplings_rows(
        &mut self,
        couplings: &crate::Couplings,
        filter: &crate::ConstraintFilter,
        changed: &[usize],
    ) {
        let Some(first) = self.levels.first_mut() else { return self.set_couplings(couplings, filter) };
        if self.smoothed.is_some() || first.couplings.len() != couplings.terms().len() {
            return self.set_couplings(couplings, filter);
        }
        let (marked, redone) = (&mut self.coupling_marks, &mut self.redone_terms);
        marked.resize(first.inv_diag.len(), false);
        changed.iter().for_each(|&i| marked[i] = true);
        first.couplings.update_fine(couplings, filter, marked, redone);
        changed.iter().for_each(|&i| marked[i] = false);
        for l in 0..self.levels.len() {
            let (done, rest) = self.levels.split_at_mut(l + 1);
            let level = &done[l];
            let next = rest.first_mut().map_or(&mut self.coarsest.couplings, |next| &mut next.couplings);
            level.couplings.aggregate_redone(&level.coarse_of, next, redone);
        }
    }

    /// Rebuilds every level's operator from the fine matrix `a`.
    pub fn update(&mut self, a: &BlockSparseMatrix) {
        let omega = self.omega;
        if let Some(first) = &mut self.smoothed {
            first.update(a, omega);
            return;
        }
        for l in 0..self.levels.len() {
            let (done, rest) = self.levels.split_at_mut(l);
            let fine = if l == 0 { a } else { &done[l - 1].coarse };
            let level = &mut rest[0];
            inverse_diagonal(fine, omega, &mut level.inv_diag);
            if let Some((partner, inv_off)) = &mut level.pairs {
                invert_pairs(fine, omega, partner, &mut level.inv_diag, inv_off);
            }
            level.couplings.stiffen_smoother(fine, (omega, l == 0), &mut level.inv_diag, level.pairs.as_mut(), None);
            // The Galerkin product of the rounded operator the residuals
            // use, so each coarse level is exactly the Galerkin level of
            // the operator above it (the sewn seam of `tests/seams.rs` at
            // rel_tol 1e-12: centre of mass 1.78e-11 m from `A`'s product,
            // 1.25e-11 from this).
            let (slots, coarse) = (&level.slots, &mut level.coarse);
            match &mut level.single {
                Some(single) => {
                    single.copy_from(fine);
                    galerkin(slots, coarse, |s| widen(&single.blocks[s]));
                }
                None => galerkin(slots, coarse, |s| fine.values()[s]),
            }
        }
        self.coarsest.update(self.levels.last().map_or(a, |l| &l.coarse));
    }

    /// As [`Multigrid::update`], for an `a` that differs from the matrix of
    /// the last update only in the rows and columns of the nodes `changed`
    /// (a solve's constraint filter changed there, the matrix and the
    /// couplings given to [`Multigrid::set_couplings`] did not):
    /// only what those blocks reach is recomputed, each block, inverse and
    /// Galerkin sum as `update` computes it, so the hierarchy is the same
    /// bit for bit. The caller vouches for the premise; a `changed` that
    /// touches more than a quarter of the blocks refills everything.
    /// Returns whether the refill was partial.
    pub fn update_rows(&mut self, a: &BlockSparseMatrix, changed: &[usize]) -> bool {
        if self.smoothed.is_some() {
            self.update(a);
            return false;
        }
        let pattern = a.pattern();
        let mut dirty = std::mem::take(&mut self.fine_dirty);
        dirty.clear();
        for &i in changed {
            for (slot, &j) in pattern.row_range(i).zip(pattern.row_cols(i)) {
                dirty.push((slot as u32, i as u32, j));
                if j as usize != i {
                    dirty.push((pattern.mirror_slot(slot) as u32, j, i as u32));
                }
            }
        }
        if dirty.len() as f64 > PARTIAL_REFILL_MAX_SHARE * pattern.nnz_blocks() as f64 {
            self.fine_dirty = dirty;
            self.update(a);
            return false;
        }
        let omega = self.omega;
        for l in 0..self.levels.len() {
            let (done, rest) = self.levels.split_at_mut(l);
            let (fine, fine_dirty) = match done.last() {
                None => (a, &dirty),
                Some(above) => (&above.coarse, &above.dirty),
            };
            let level = &mut rest[0];
            // Diagonal inverses (and the finest level's pairs) of the rows
            // whose diagonal block changed.
            for &(_, i, _) in fine_dirty.iter().filter(|&&(_, i, j)| i == j) {
                let i = i as usize;
                level.refilled[i] = true;
                level.inv_diag[i] = inverse_diagonal_block(fine, omega, i);
                if let Some((partner, inv_off)) = &mut level.pairs {
                    let p = partner[i] as usize;
                    if p != i {
                        level.inv_diag[p] = inverse_diagonal_block(fine, omega, p);
                        invert_pair(fine, omega, (i.min(p), i.max(p)), no_extra(), &mut level.inv_diag, inv_off);
                    }
                }
            }
            let refilled = Some(&level.refilled[..]);
            level.couplings.stiffen_smoother(
                fine,
                (omega, l == 0),
                &mut level.inv_diag,
                level.pairs.as_mut(),
                refilled,
            );
            for &(_, i, _) in fine_dirty.iter().filter(|&&(_, i, j)| i == j) {
                level.refilled[i as usize] = false;
            }
            if let Some(single) = &mut level.single {
                for &(slot, _, _) in fine_dirty {
                    single.copy_slot(fine, slot as usize);
                }
            }
            // The coarse slots the changed fine slots sum into.
            level.dirty.clear();
            for &(slot, i, j) in fine_dirty {
                let target = level.slot_target[slot as usize];
                if !level.marked[target as usize] {
                    level.marked[target as usize] = true;
                    let (ci, cj) = (level.coarse_of[i as usize], level.coarse_of[j as usize]);
                    level.dirty.push((target, ci, cj));
                }
            }
            let (slots, values, single) = (&level.slots, level.coarse.values_mut(), &level.single);
            for &(target, _, _) in &level.dirty {
                level.marked[target as usize] = false;
                let sources = slots.sources(target as usize).iter();
                values[target as usize] = match single {
                    Some(single) => sources.map(|&s| widen(&single.blocks[s as usize])).sum(),
                    None => sources.map(|&s| fine.values()[s as usize]).sum(),
                };
            }
        }
        self.coarsest.update(self.levels.last().map_or(a, |l| &l.coarse));
        self.fine_dirty = dirty;
        true
    }

    /// `z = B r`, one cycle: a symmetric positive definite approximation
    /// of `A^-1 r` for the matrix last passed to [`Multigrid::update`].
    pub fn apply(&mut self, a: &BlockSparseMatrix, r: &[Vec3], z: &mut [Vec3]) {
        if let Some(first) = &mut self.smoothed {
            first.apply(a, r, z);
            return;
        }
        let Some(first) = self.levels.first_mut() else {
            self.coarsest.b.copy_from_slice(r);
            self.coarsest.solve();
            z.copy_from_slice(&self.coarsest.x);
            return;
        };
        first.b.copy_from_slice(r);
        cycle(&mut self.levels, &mut self.coarsest, a, true, self.cycle);
        z.copy_from_slice(&self.levels[0].x);
    }
}

/// Checks that `aggregations[l]` maps the nodes of level `l` (`n` on the
/// finest, the previous aggregation's aggregates below) onto non-empty
/// aggregates in range.
fn check_aggregations(n: usize, aggregations: &[Aggregation]) -> Result<(), MultigridError> {
    let mut expected = n;
    for (level, agg) in aggregations.iter().enumerate() {
        if agg.coarse_of.len() != expected {
            return Err(MultigridError::SizeMismatch { level, expected, got: agg.coarse_of.len() });
        }
        let mut used = vec![false; agg.n_coarse];
        for &c in &agg.coarse_of {
            *used.get_mut(c as usize).ok_or(MultigridError::BadAggregate { level })? = true;
        }
        if used.contains(&false) {
            return Err(MultigridError::BadAggregate { level });
        }
        expected = agg.n_coarse;
    }
    Ok(())
}

/// Each of `n` nodes' partner in `pairs` (itself when unpaired; pairs that
/// repeat a node or are out of range are skipped), or `None` when no pair
/// is kept.
fn partners(n: usize, pairs: &[(usize, usize)]) -> Option<Vec<u32>> {
    let mut partner: Vec<u32> = (0..n as u32).collect();
    let mut any = false;
    for &(i, j) in pairs {
        if i < n && j < n && i != j && partner[i] as usize == i && partner[j] as usize == j {
            (partner[i], partner[j]) = (j as u32, i as u32);
            any = true;
        }
    }
    any.then_some(partner)
}

/// `levels[0].x = B levels[0].b`: pre-smooth from zero, correct from the
/// coarse problem, post-smooth. The coarse problem is solved by one cycle
/// below the finest level (`finest`) and by two below any other (see the
/// module docs): `e = B_c r_c`, then `e += B_c (r_c - A_c e)`, which is
/// symmetric because `B_c` is. Loops split at [`ROW_CHUNK`] rows as
/// elsewhere: running levels under 1024 nodes on one thread was tried
/// (1.05-1.40 ms a CG iteration on the Table-1 one-piece against
/// 1.23-1.42, within the machine's noise) and ran a 21 x 21 cloth's whole
/// cycle on one thread, doubling its Newton steps.
fn cycle(levels: &mut [Level], coarsest: &mut Coarsest, a: &BlockSparseMatrix, finest: bool, kind: Cycle) {
    let (level, rest) = levels.split_first_mut().expect("a cycle runs on a level");
    jacobi_from_zero(&level.inv_diag, level.pairs.as_ref(), &level.b, &mut level.x);
    residual(level.single.as_ref(), a, &level.b, &level.x, &mut level.r);
    level.couplings.add_product(&level.x, -1.0, &mut level.r);
    if rest.is_empty() {
        restrict(&level.members, &level.r, &mut coarsest.b);
        coarsest.solve();
    } else {
        restrict(&level.members, &level.r, &mut rest[0].b);
        let coarse = &level.coarse;
        cycle(rest, coarsest, coarse, false, kind);
        match kind {
            Cycle::K => krylov_second_step(rest, coarsest, coarse),
            Cycle::W if !finest => {
                let next = &mut rest[0];
                std::mem::swap(&mut next.first, &mut next.x);
                residual(next.single.as_ref(), coarse, &next.b, &next.first, &mut next.r);
                next.couplings.add_product(&next.first, -1.0, &mut next.r);
                // The coarse right-hand side becomes its residual; the old one
                // (now in `r`) is not needed again.
                std::mem::swap(&mut next.b, &mut next.r);
                cycle(rest, coarsest, coarse, false, kind);
                let next = &mut rest[0];
                next.x.par_iter_mut().zip(next.first.par_iter()).with_min_len(ROW_CHUNK).for_each(|(x, e)| *x += e);
            }
            Cycle::W => {}
        }
    }
    let correction = rest.first().map_or(&coarsest.x, |next| &next.x);
    level.x.par_iter_mut().zip(level.coarse_of.par_iter()).with_min_len(ROW_CHUNK).for_each(|(xi, &c)| {
        *xi += correction[c as usize];
    });
    residual(level.single.as_ref(), a, &level.b, &level.x, &mut level.r);
    level.couplings.add_product(&level.x, -1.0, &mut level.r);
    let (r, inv_diag, pairs) = (&level.r, &level.inv_diag, level.pairs.as_ref());
    level.x.par_iter_mut().enumerate().with_min_len(ROW_CHUNK).for_each(|(i, xi)| {
        *xi += smoothed(inv_diag, pairs, r, i);
    });
}

/// The K-cycle's coarse solve, given its first step `c1 = B b` in
/// `rest[0].x` (`b = rest[0].b`, `A` = `coarse`): two steps of flexible CG,
///
/// ```text
/// rho1 = c1.A c1,  t1 = (c1.b) / rho1,  r2 = b - t1 A c1,  c2 = B r2
/// gamma = c2.A c1, rho2 = c2.A c2 - gamma^2 / rho1,  alpha2 = c2.r2
/// x = (t1 - gamma alpha2 / (rho1 rho2)) c1 + (alpha2 / rho2) c2
/// ```
///
/// the combination of `c1` and `c2` of least `A`-norm error (Notay &
/// Vassilevski 2008, "Recursive Krylov-based multigrid cycles"). A step
/// without positive curvature (roundoff, `c2` parallel to `c1`) is dropped.
fn krylov_second_step(rest: &mut [Level], coarsest: &mut Coarsest, coarse: &BlockSparseMatrix) {
    let next = &mut rest[0];
    let rho1 = mul_vec_dot(next.single.as_ref(), coarse, &next.x, &mut next.v, &mut next.partials)
        + next.couplings.add_product(&next.x, 1.0, &mut next.v);
    let t1 = dot_with(&next.x, &next.b, &mut next.partials) / rho1;
    if !(rho1 > 0.0 && t1.is_finite()) {
        return;
    }
    let (b, v) = (&next.b, &next.v);
    next.r.par_iter_mut().enumerate().with_min_len(ROW_CHUNK).for_each(|(i, ri)| *ri = b[i] - v[i] * t1);
    // c1 to `first`, r2 becomes the right-hand side (the old one is not needed again).
    std::mem::swap(&mut next.first, &mut next.x);
    std::mem::swap(&mut next.b, &mut next.r);
    cycle(rest, coarsest, coarse, false, Cycle::K);
    let next = &mut rest[0];
    let c2_a_c2 = mul_vec_dot(next.single.as_ref(), coarse, &next.x, &mut next.r, &mut next.partials)
        + next.couplings.add_product(&next.x, 1.0, &mut next.r);
    let gamma = dot_with(&next.x, &next.v, &mut next.partials);
    let alpha2 = dot_with(&next.x, &next.b, &mut next.partials);
    let (w1, w2) = krylov_weights(rho1, t1, c2_a_c2, gamma, alpha2);
    let first = &next.first;
    next.x.par_iter_mut().enumerate().with_min_len(ROW_CHUNK).for_each(|(i, x)| *x = first[i] * w1 + *x * w2);
}

/// The weights `(w1, w2)` of `x = w1 c1 + w2 c2` in the K-cycle's coarse
/// solve ([`krylov_second_step`]) from `rho1 = c1.A c1`, `t1 = (c1.b) /
/// rho1`, `c2.A c2`, `gamma = c2.A c1` and `alpha2 = c2.r2`; a second
/// step without positive curvature is dropped.
fn krylov_weights(rho1: f64, t1: f64, c2_a_c2: f64, gamma: f64, alpha2: f64) -> (f64, f64) {
    let rho2 = c2_a_c2 - gamma * gamma / rho1;
    if rho2 > 0.0 && (alpha2 / rho2).is_finite() {
        (t1 - gamma * alpha2 / (rho1 * rho2), alpha2 / rho2)
    } else {
        (t1, 0.0)
    }
}

/// `r = b - A x` with the level's `f32` copy of `a` when it has one.
fn residual(single: Option<&SinglePrecision>, a: &BlockSparseMatrix, b: &[Vec3], x: &[Vec3], r: &mut [Vec3]) {
    match single {
        Some(single) => single.residual(a.pattern(), b, x, r),
        None => a.residual(b, x, r),
    }
}

/// `y = A x`, returning `x.y`, from the level's `f32` copy of `a` when it
/// has one: the K-cycle's coarse Krylov steps then read half the bytes,
/// and take the same rounded operator as the cycle's residuals and the
/// Galerkin products below.
fn mul_vec_dot(
    single: Option<&SinglePrecision>,
    a: &BlockSparseMatrix,
    x: &[Vec3],
    y: &mut [Vec3],
    partials: &mut [f64],
) -> f64 {
    match single {
        Some(single) => single.mul_vec_dot(a.pattern(), x, y, partials),
        None => a.mul_vec_dot(x, y, partials),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The textbook left-looking factorisation and substitutions (each
    /// entry a dot product, `k` ascending), on a row-major matrix.
    fn left_looking(a: &mut [f64], n: usize) -> bool {
        for j in 0..n {
            let mut d = a[j * n + j];
            for k in 0..j {
                d -= a[j * n + k] * a[j * n + k];
            }
            if !(d > 0.0 && d.is_finite()) {
                return false;
            }
            let d = d.sqrt();
            a[j * n + j] = d;
            for i in j + 1..n {
                let mut s = a[i * n + j];
                for k in 0..j {
                    s -= a[i * n + k] * a[j * n + k];
                }
                a[i * n + j] = s / d;
            }
        }
        true
    }

    fn substitute(l: &[f64], b: &mut [f64]) {
        let n = b.len();
        for i in 0..n {
            let mut s = b[i];
            for k in 0..i {
                s -= l[i * n + k] * b[k];
            }
            b[i] = s / l[i * n + i];
        }
        for i in (0..n).rev() {
            let mut s = b[i];
            for k in i + 1..n {
                s -= l[k * n + i] * b[k];
            }
            b[i] = s / l[i * n + i];
        }
    }

    /// A symmetric positive definite `n x n` matrix with entries of many
    /// magnitudes (so a change in the order of operations shows in the
    /// last bits), row-major.
    fn spd(n: usize) -> Vec<f64> {
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let g: Vec<f64> = (0..n * n).map(|_| next() * 10f64.powi((next() * 6.0) as i32)).collect();
        let mut a = vec![0.0; n * n];
        for i in 0..n {
            for j in 0..n {
                a[i * n + j] = (0..n).map(|k| g[i * n + k] * g[j * n + k]).sum::<f64>();
            }
            a[i * n + i] += 1e-3;
        }
        a
    }

    #[test]
    fn right_looking_cholesky_and_column_substitution_keep_the_bits_of_the_dot_product_forms() {
        for n in [1, 2, 7, 48, 90] {
            let a = spd(n);
            let (mut want, mut got) = (a.clone(), a.clone());
            assert!(left_looking(&mut want, n));
            assert!(cholesky_in_place(&mut got, n, &mut vec![0.0; n]));
            for i in 0..n {
                for k in 0..=i {
                    assert_eq!(got[i * n + k].to_bits(), want[i * n + k].to_bits(), "n = {n}: L[{i}][{k}]");
                }
            }
            let mut l_t = vec![0.0; n * n];
            transpose_lower(&got, n, &mut l_t);
            let b: Vec<f64> = (0..n).map(|i| (i as f64 * 0.37).sin() * 10f64.powi(i as i32 % 5)).collect();
            let (mut x_want, mut x_got) = (b.clone(), b);
            substitute(&want, &mut x_want);
            cholesky_solve_in_place(&l_t, &mut x_got);
            let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&x_got), bits(&x_want), "n = {n}");
        }
        // Not positive definite: refused, as before.
        let mut indefinite = vec![1.0, 2.0, 2.0, 1.0];
        assert!(!cholesky_in_place(&mut indefinite, 2, &mut [0.0; 2]));
    }
}
