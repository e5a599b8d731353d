//! Preconditioned conjugate gradients with Baraff & Witkin's constraint
//! filter ("modified PCG", Baraff & Witkin 1998 §5.3; used by Choi & Ko 2002).
//!
//! Solves `A x = b` for symmetric positive definite `A` on the subspace left
//! free by the filter, with the constrained components of `x` prescribed:
//!
//! ```text
//! x   <- S x + (I - S) z                       (start: caller's guess, filtered)
//! r   <- S (b - A x);   c <- S P^-1 r
//! loop: q <- S A c;  alpha <- (r.P^-1 r)/(c.q);  x += alpha c;  r -= alpha q
//!       s <- P^-1 r;  beta <- (r.s)_new/(r.s)_old;  c <- S (s + beta c)
//! ```
//!
//! Convergence is `|r| <= rel_tol * |S (b - A z)|`, i.e. relative to the
//! residual of the guess "free components zero": a warm start then counts
//! as the head start it is, not as a harder problem.

use crate::{
    BlockSparseMatrix, ConstraintFilter, Couplings, Mat3, Preconditioner, PreconditionerKind, Vec3,
    par::{ROW_CHUNK, chunk_count, dot_with},
};
use rayon::prelude::*;

/// Settings of one PCG solve.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PcgParams {
    /// Stop when the filtered residual norm falls below `rel_tol` times its
    /// reference (dimensionless). Default `1e-4`.
    pub rel_tol: f64,
    /// Give up after this many iterations. Default 1000.
    pub max_iter: usize,
    /// Preconditioner. Default block-Jacobi.
    pub preconditioner: PreconditionerKind,
}

impl Default for PcgParams {
    fn default() -> Self {
        Self { rel_tol: 1e-4, max_iter: 1000, preconditioner: PreconditionerKind::BlockJacobi }
    }
}

impl PcgParams {
    /// The squared residual norm a solve stops at, `rel_tol^2 |r_ref|^2`,
    /// from the reference's squared norm `ref_sq`.
    pub(crate) fn stop_sq(&self, ref_sq: f64) -> f64 {
        self.rel_tol * self.rel_tol * ref_sq
    }
}

/// What a solve did.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PcgInfo {
    /// Iterations (matrix-vector products) performed.
    pub iterations: usize,
    /// Final `|S r| / |S (b - A z)|` (0 when the reference is 0).
    pub rel_residual: f64,
    /// Whether the multigrid hierarchy was refilled only where the filter
    /// changed since the last solve of the same matrix (see
    /// [`Pcg::solve_in_place`]).
    pub partial_refill: bool,
}

/// Why a solve failed.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum PcgError {
    /// `c . A c <= 0` for a search direction `c`: the filtered matrix is not
    /// positive definite.
    #[error("matrix not positive definite: curvature {curvature:e} at iteration {iteration}")]
    NotPositiveDefinite {
        /// Iteration at which it was detected.
        iteration: usize,
        /// The offending `c . A c`.
        curvature: f64,
    },
    /// `max_iter` was reached before `rel_tol`. The unknown holds the last
    /// iterate, which callers may choose to accept.
    #[error("PCG did not converge: {} iterations, relative residual {:e}", info.iterations, info.rel_residual)]
    NotConverged {
        /// State at the last iteration.
        info: PcgInfo,
    },
    /// `rel_tol` is negative or not finite.
    #[error("PCG relative tolerance must be finite and >= 0, got {rel_tol}")]
    InvalidTolerance {
        /// The offending tolerance.
        rel_tol: f64,
    },
    /// [`PreconditionerKind::Multigrid`] was asked for but no hierarchy was
    /// set with [`Pcg::set_multigrid`].
    #[error("multigrid preconditioner requested but no hierarchy was set")]
    NoMultigridHierarchy,
    /// `r . P^-1 r <= 0`: the preconditioner is not positive definite.
    #[error("preconditioner not positive definite at iteration {iteration}")]
    PreconditionerNotPositive {
        /// Iteration at which it was detected.
        iteration: usize,
    },
    /// The right-hand side, the matrix or an iterate is not finite.
    #[error("non-finite value in PCG at iteration {iteration}")]
    NonFinite {
        /// Iteration at which it was detected (0: in the input).
        iteration: usize,
    },
}

/// A PCG solver owning its scratch vectors, so repeated solves of the same
/// size do not allocate.
#[derive(Debug, Clone, Default)]
pub struct Pcg {
    r: Vec<Vec3>,
    s: Vec<Vec3>,
    c: Vec<Vec3>,
    q: Vec<Vec3>,
    partials: Vec<f64>,
    partials2: Vec<f64>,
    precond: Preconditioner,
    /// `S A S + (I - S) d`, the operator the multigrid hierarchy is built
    /// from when particles are constrained (allocated on first use; see
    /// `filter_in_place`).
    filtered: Option<BlockSparseMatrix>,
    /// Original blocks changed by `filter_in_place`, for restoring: one
    /// list per chunk of [`ROW_CHUNK`] rows.
    saved_blocks: Vec<Vec<(usize, Mat3)>>,
    /// What [`Pcg::solve_in_place`] last built the multigrid hierarchy from.
    hierarchy: HierarchySource,
    /// Couplings the operator adds to the matrix (none by default).
    couplings: Couplings,
}

/// What a multigrid hierarchy was last built from: the unfiltered
/// matrix's [`BlockSparseMatrix::revision`] and the filter's projectors
/// by particle. A solve with the same matrix under another filter (a
/// contact pass) then refills only what the particles whose projector
/// changed reach.
#[derive(Debug, Clone, Default)]
pub(crate) struct HierarchySource {
    from: Option<(u64, Vec<(usize, Mat3)>)>,
    /// Scratch: the current filter's projectors, and the particles whose
    /// projector changed since the hierarchy was built.
    projectors: Vec<(usize, Mat3)>,
    changed: Vec<usize>,
}

impl HierarchySource {
    /// Collects `filter`'s projectors (by particle) and, when the
    /// hierarchy was last built from this very `a` (its revision as the
    /// last solve left it), the particles whose projector differs from
    /// then: the rows and columns in which the filtered operator differs.
    /// Returns them, or `None` when the hierarchy must be rebuilt whole.
    pub(crate) fn changes(&mut self, a: &BlockSparseMatrix, filter: &ConstraintFilter) -> Option<&[usize]> {
        self.projectors.clear();
        self.projectors.extend(filter.iter().map(|(i, s, _)| (i, *s)));
        self.projectors.sort_unstable_by_key(|&(i, _)| i);
        self.changed.clear();
        let (revision, old) = self.from.as_ref()?;
        if *revision != a.revision() {
            return None;
        }
        // Released or turned (a free particle's projector is the identity,
        // which no constraint's is), then added.
        let same = |p: &Mat3, q: &Mat3| p.iter().zip(q.iter()).all(|(a, b)| a.to_bits() == b.to_bits());
        let kept = |i: usize| old.binary_search_by_key(&i, |&(j, _)| j).is_ok();
        self.changed.extend(old.iter().filter(|(i, s)| !same(&filter.projector(*i), s)).map(|&(i, _)| i));
        self.changed.extend(self.projectors.iter().map(|&(i, _)| i).filter(|&i| !kept(i)));
        Some(&self.changed)
    }

    /// Records that the hierarchy was built (`built`) from `a` under the
    /// filter last given to [`HierarchySource::changes`], or forgets it.
    pub(crate) fn built(&mut self, a: &BlockSparseMatrix, built: bool) {
        let projectors = std::mem::take(&mut self.projectors);
        let old = std::mem::replace(&mut self.from, built.then(|| (a.revision(), projectors)));
        self.projectors = old.map(|(_, p)| p).unwrap_or_default();
    }

    /// Forgets the hierarchy's source: the next solve rebuilds it whole.
    pub(crate) fn forget(&mut self) {
        self.from = None;
    }
}

impl Pcg {
    /// A solver with scratch space for `n` block rows (grows on demand).
    pub fn new(n: usize) -> Self {
        let mut p = Self::default();
        p.resize(n);
        p
    }

    /// The couplings every solve adds to its matrix's off-diagonal blocks
    /// until changed ([`Couplings`]): fill them before a solve, clear them
    /// for a plain one.
    pub fn couplings_mut(&mut self) -> &mut Couplings {
        &mut self.couplings
    }

    fn resize(&mut self, n: usize) {
        for v in [&mut self.r, &mut self.s, &mut self.c, &mut self.q] {
            v.resize(n, Vec3::zeros());
        }
        self.partials.resize(chunk_count(n), 0.0);
        self.partials2.resize(chunk_count(n), 0.0);
    }

    /// Solves `A x = b` under `filter`. On entry `x` is the initial guess (its
    /// constrained components are overwritten by the prescribed values); on
    /// return it is the solution, or the last iterate on error.
    ///
    /// With the multigrid preconditioner and constrained particles, the
    /// hierarchy is built from a filtered copy of `A` (see
    /// [`Pcg::solve_in_place`], which avoids the copy).
    pub fn solve(
        &mut self,
        a: &BlockSparseMatrix,
        b: &[Vec3],
        filter: &ConstraintFilter,
        params: &PcgParams,
        x: &mut [Vec3],
    ) -> Result<PcgInfo, PcgError> {
        self.hierarchy.forget();
        let Some(start) = self.begin(a, b, filter, params, x)? else { return Ok(PcgInfo::default()) };
        if let Some(info) = converged_at_start(params, start) {
            return Ok(info);
        }
        if !needs_filtered_hierarchy(params, filter) {
            return self.iterate(a, filter, params, x, start, None);
        }
        let f = filtered_copy(self.filtered.take(), a, filter, &mut self.saved_blocks);
        // S A S c = S (S A S + (I - S) d) c for c = S c: iterating on the
        // filtered copy gives the same iterates.
        let result = self.iterate(&f, filter, params, x, start, None);
        self.filtered = Some(f);
        result
    }

    /// As [`Pcg::solve`], but with the multigrid preconditioner and
    /// constrained particles `A` is turned into `S A S + (I - S) d` in place
    /// for the iterations and restored bit for bit before returning (only
    /// the constrained rows and columns change): no copy of the matrix.
    ///
    /// Solving again with the same matrix (the same
    /// [`BlockSparseMatrix::revision`] as this solve left it) under another
    /// filter, as a contact pass does, the multigrid refills only what the
    /// particles whose constraint changed reach: the same hierarchy bit for
    /// bit, at a fraction of the cost.
    pub fn solve_in_place(
        &mut self,
        a: &mut BlockSparseMatrix,
        b: &[Vec3],
        filter: &ConstraintFilter,
        params: &PcgParams,
        x: &mut [Vec3],
    ) -> Result<PcgInfo, PcgError> {
        let Some(start) = self.begin(a, b, filter, params, x)? else { return Ok(PcgInfo::default()) };
        // Before the hierarchy is touched: it stays the one `hierarchy`
        // describes.
        if let Some(info) = converged_at_start(params, start) {
            return Ok(info);
        }
        if params.preconditioner != PreconditionerKind::Multigrid {
            return self.iterate(a, filter, params, x, start, None);
        }
        let mut hierarchy = std::mem::take(&mut self.hierarchy);
        let changed_rows = hierarchy.changes(a, filter);
        let result = if needs_filtered_hierarchy(params, filter) {
            let mut saved = std::mem::take(&mut self.saved_blocks);
            filter_in_place(a, filter, &mut saved);
            let result = self.iterate(a, filter, params, x, start, changed_rows);
            restore_filtered(a, &mut saved);
            self.saved_blocks = saved;
            result
        } else {
            self.iterate(a, filter, params, x, start, changed_rows)
        };
        hierarchy.built(a, !matches!(result, Err(PcgError::NoMultigridHierarchy)));
        self.hierarchy = hierarchy;
        result
    }

    /// Checks the inputs and computes the starting residual. Returns `None`
    /// when the prescribed values alone solve the system (`x` then holds
    /// them), else `(reference r.r, r.r)`.
    fn begin(
        &mut self,
        a: &BlockSparseMatrix,
        b: &[Vec3],
        filter: &ConstraintFilter,
        params: &PcgParams,
        x: &mut [Vec3],
    ) -> Result<Option<(f64, f64)>, PcgError> {
        let n = a.n();
        assert!(
            b.len() == n && x.len() == n && filter.n() == n,
            "Pcg::solve: dimension mismatch (matrix {n}, rhs {}, unknown {}, filter {})",
            b.len(),
            x.len(),
            filter.n()
        );
        if !(params.rel_tol.is_finite() && params.rel_tol >= 0.0) {
            return Err(PcgError::InvalidTolerance { rel_tol: params.rel_tol });
        }
        self.resize(n);
        // Reference residual S (b - A z), z = the prescribed part alone
        // (kept in c), and the residual of the caller's guess, in one pass
        // over the matrix.
        let z_only = &mut self.c;
        z_only.par_chunks_mut(ROW_CHUNK).for_each(|ch| ch.fill(Vec3::zeros()));
        filter.impose(z_only);
        filter.impose(x);
        a.residual_pair(b, (&self.c, x), (&mut self.s, &mut self.r));
        if !self.couplings.is_empty() {
            self.couplings.add_off_diagonal(&self.c, -1.0, &mut self.s);
            self.couplings.add_off_diagonal(x, -1.0, &mut self.r);
        }
        filter.project(&mut self.s);
        let ref_sq = dot_with(&self.s, &self.s, &mut self.partials);
        if !ref_sq.is_finite() {
            return Err(PcgError::NonFinite { iteration: 0 });
        }
        if ref_sq == 0.0 {
            x.copy_from_slice(&self.c);
            return Ok(None);
        }
        // A guess worse than none is dropped.
        filter.project(&mut self.r);
        let mut r_sq = dot_with(&self.r, &self.r, &mut self.partials);
        if r_sq.is_nan() || r_sq > ref_sq {
            x.copy_from_slice(&self.c);
            self.r.copy_from_slice(&self.s);
            r_sq = ref_sq;
        }
        Ok(Some((ref_sq, r_sq)))
    }

    /// The preconditioned iterations from the residual [`Pcg::begin`] left
    /// in `r`, with the operator `a` (also the preconditioner's matrix).
    fn iterate(
        &mut self,
        a: &BlockSparseMatrix,
        filter: &ConstraintFilter,
        params: &PcgParams,
        x: &mut [Vec3],
        (ref_sq, mut r_sq): (f64, f64),
        changed_rows: Option<&[usize]>,
    ) -> Result<PcgInfo, PcgError> {
        if params.preconditioner == PreconditionerKind::Multigrid {
            match changed_rows {
                // The same matrix, so the same couplings (the refill's premise).
                Some(changed) => self.precond.set_couplings_rows(&self.couplings, filter, changed),
                None => self.precond.set_couplings(&self.couplings, filter),
            }
        }
        let (built, partial_refill) = match changed_rows {
            Some(changed) => self.precond.update_rows(params.preconditioner, a, changed),
            None => (self.precond.update(params.preconditioner, a), false),
        };
        if !built {
            return Err(PcgError::NoMultigridHierarchy);
        }
        let ref_norm = ref_sq.sqrt();
        let tol_sq = params.stop_sq(ref_sq);
        self.precond.apply(a, &self.r, &mut self.s);
        self.c.copy_from_slice(&self.s);
        filter.project(&mut self.c);
        let mut rho = dot_with(&self.r, &self.c, &mut self.partials);

        let flexible = self.precond.is_nonlinear();
        let mut iterations = 0;
        while r_sq > tol_sq {
            if iterations == params.max_iter {
                let info = PcgInfo { iterations, rel_residual: r_sq.sqrt() / ref_norm, partial_refill };
                return Err(PcgError::NotConverged { info });
            }
            iterations += 1;
            // c = S c, so c.(S A c) = c.(A c): the dot fuses with the product.
            let mut curvature = a.mul_vec_dot(&self.c, &mut self.q, &mut self.partials);
            if !self.couplings.is_empty() {
                curvature += self.couplings.add_off_diagonal(&self.c, 1.0, &mut self.q);
            }
            filter.project(&mut self.q);
            if !curvature.is_finite() {
                return Err(PcgError::NonFinite { iteration: iterations });
            }
            if curvature <= 0.0 {
                return Err(PcgError::NotPositiveDefinite { iteration: iterations, curvature });
            }
            let alpha = rho / curvature;
            let rho_old = rho;
            if self.precond.is_pointwise() {
                (r_sq, rho) = self.step_fused(alpha, x);
            } else {
                r_sq = self.advance(alpha, x);
                // The loop's exits (at its top) come before the
                // preconditioner: its result would only serve a next
                // direction (one cycle of five in a four-iteration solve).
                if r_sq.is_finite() && (r_sq <= tol_sq || iterations == params.max_iter) {
                    continue;
                }
                rho = self.precondition(a);
            }
            if !r_sq.is_finite() || !rho.is_finite() {
                return Err(PcgError::NonFinite { iteration: iterations });
            }
            if rho <= 0.0 && r_sq > 0.0 {
                return Err(PcgError::PreconditionerNotPositive { iteration: iterations });
            }
            // Flexible (Polak-Ribiere) for a nonlinear preconditioner:
            // beta = s_new.(r_new - r_old) / rho_old, r_new - r_old = -alpha q.
            let beta = if flexible {
                -alpha * dot_with(&self.q, &self.s, &mut self.partials) / rho_old
            } else {
                rho / rho_old
            };
            self.c
                .par_chunks_mut(ROW_CHUNK)
                .zip(self.s.par_chunks(ROW_CHUNK))
                .for_each(|(cc, cs)| cc.iter_mut().zip(cs).for_each(|(ci, si)| *ci = si + beta * *ci));
            filter.project(&mut self.c);
        }
        Ok(PcgInfo { iterations, rel_residual: r_sq.sqrt() / ref_norm, partial_refill })
    }

    /// Sets the hierarchy for [`PreconditionerKind::Multigrid`].
    pub fn set_multigrid(&mut self, mg: crate::Multigrid) {
        self.hierarchy.forget();
        self.precond.set_multigrid(mg);
    }

    /// `x += alpha c; r -= alpha q`, returning `r.r` (summed in chunk
    /// order), for a preconditioner that is not row-local.
    fn advance(&mut self, alpha: f64, x: &mut [Vec3]) -> f64 {
        x.par_chunks_mut(ROW_CHUNK)
            .zip(self.r.par_chunks_mut(ROW_CHUNK))
            .zip(self.c.par_chunks(ROW_CHUNK).zip(self.q.par_chunks(ROW_CHUNK)))
            .for_each(|((cx, cr), (cc, cq))| {
                for k in 0..cx.len() {
                    cx[k] += alpha * cc[k];
                    cr[k] -= alpha * cq[k];
                }
            });
        dot_with(&self.r, &self.r, &mut self.partials)
    }

    /// `s = P^-1 r` after [`Pcg::advance`], returning `r.s`.
    fn precondition(&mut self, a: &BlockSparseMatrix) -> f64 {
        self.precond.apply(a, &self.r, &mut self.s);
        dot_with(&self.r, &self.s, &mut self.partials)
    }

    /// `x += alpha c; r -= alpha q; s = P^-1 r`, returning `(r.r, r.s)` summed
    /// in chunk order: one pass over memory instead of four.
    fn step_fused(&mut self, alpha: f64, x: &mut [Vec3]) -> (f64, f64) {
        let precond = &self.precond;
        x.par_chunks_mut(ROW_CHUNK)
            .zip(self.r.par_chunks_mut(ROW_CHUNK))
            .zip(self.s.par_chunks_mut(ROW_CHUNK))
            .zip(self.c.par_chunks(ROW_CHUNK).zip(self.q.par_chunks(ROW_CHUNK)))
            .zip(self.partials.par_iter_mut().zip(self.partials2.par_iter_mut()))
            .enumerate()
            .for_each(|(chunk, ((((cx, cr), cs), (cc, cq)), (p_rr, p_rs)))| {
                let (mut rr, mut rs) = (0.0, 0.0);
                for k in 0..cx.len() {
                    cx[k] += alpha * cc[k];
                    cr[k] -= alpha * cq[k];
                    cs[k] = precond.apply_one(chunk * ROW_CHUNK + k, &cr[k]);
                    rr += cr[k].dot(&cr[k]);
                    rs += cr[k].dot(&cs[k]);
                }
                *p_rr = rr;
                *p_rs = rs;
            });
        (self.partials.iter().sum(), self.partials2.iter().sum())
    }
}

/// The result of a solve whose start `(reference r.r, r.r)` already meets
/// `rel_tol` (as [`Pcg::iterate`] would report it after zero iterations),
/// so that neither the filter nor the preconditioner is set up for it: a
/// contact step's last check of its settled set is often such a solve
/// (about a third of an iteration's time went to the set-up).
fn converged_at_start(params: &PcgParams, (ref_sq, r_sq): (f64, f64)) -> Option<PcgInfo> {
    let converged = r_sq <= params.stop_sq(ref_sq);
    converged.then(|| PcgInfo { iterations: 0, rel_residual: r_sq.sqrt() / ref_sq.sqrt(), partial_refill: false })
}

/// Whether the multigrid hierarchy must be built from the filtered operator.
fn needs_filtered_hierarchy(params: &PcgParams, filter: &ConstraintFilter) -> bool {
    params.preconditioner == PreconditionerKind::Multigrid && filter.constrained_count() > 0
}

/// `A <- S A S + (I - S) d` blockwise, `S` the filter's projectors and
/// `d_i = tr(A_ii) / 3` the constrained particle's own diagonal scale
/// (N/m or kg, as the matrix): the constrained rows and columns are
/// projected and the constrained directions of the diagonal get `d_i`.
/// PCG never sees that term (its directions are filtered), only the
/// multigrid hierarchy does. With the identity there instead (a unit
/// whose size has nothing to do with the matrix's: `1` against `d ~ 1e-2`
/// on a fine cloth at 1/90 s), a contact made its aggregate's coarse
/// block far stiffer along the contact normal than the cloth around it,
/// and the coarse levels stopped correcting it (the drape at 101 x 101,
/// E = 20 N/m, V-cycle: 62 -> 53 CG a step with `d`). The original of
/// every block changed goes to `saved` first (each once, one list per
/// chunk of [`ROW_CHUNK`] rows), so [`restore_filtered`] can put `A` back
/// exactly. Each block is computed from its original alone (`S_i A_ij`,
/// then `S_j` on the right), so the result does not depend on the
/// filter's entry order nor on the threads.
/// `S A S + (I - S) d` as a copy of `a`, in `previous` when it has `a`'s
/// pattern (no allocation from solve to solve).
pub(crate) fn filtered_copy(
    previous: Option<BlockSparseMatrix>,
    a: &BlockSparseMatrix,
    filter: &ConstraintFilter,
    saved: &mut Vec<Vec<(usize, Mat3)>>,
) -> BlockSparseMatrix {
    let mut f = match previous {
        Some(f) if f.pattern() == a.pattern() => f,
        _ => BlockSparseMatrix::new(a.pattern().clone()),
    };
    f.values_mut().par_chunks_mut(ROW_CHUNK).zip(a.values().par_chunks(ROW_CHUNK)).for_each(|(fv, av)| {
        fv.copy_from_slice(av);
    });
    filter_in_place(&mut f, filter, saved);
    f
}

/// `f`, a [`filtered_copy`] of a matrix (originals of its filtered blocks
/// in `saved`), filtered again under `filter`: only the blocks either
/// filter touches are rewritten, no copy of the matrix.
pub(crate) fn refilter(f: &mut BlockSparseMatrix, filter: &ConstraintFilter, saved: &mut Vec<Vec<(usize, Mat3)>>) {
    restore_filtered(f, saved);
    filter_in_place(f, filter, saved);
}

fn filter_in_place(a: &mut BlockSparseMatrix, filter: &ConstraintFilter, saved: &mut Vec<Vec<(usize, Mat3)>>) {
    saved.resize_with(a.n().div_ceil(ROW_CHUNK), Vec::new);
    // Each changed block belongs to one row: its own when the row is
    // constrained (`S_i A_ij S_j`), else its column's (`A_ij S_j`). So the
    // chunks of rows are independent, and each keeps its own originals.
    a.edit_row_chunks(saved, |pattern, rows, first_slot, blocks, saved| {
        saved.clear();
        for i in rows {
            let slots = pattern.row_range(i).zip(pattern.row_cols(i)).map(|(slot, &j)| (slot, j as usize));
            if filter.is_free(i) {
                for (slot, j) in slots.filter(|&(_, j)| !filter.is_free(j)) {
                    let block = &mut blocks[slot - first_slot];
                    saved.push((slot, *block));
                    *block *= filter.projector(j);
                }
                continue;
            }
            let (s, diag) = (filter.projector(i), pattern.diag_slot(i));
            for (slot, j) in slots {
                let block = &mut blocks[slot - first_slot];
                let b = *block;
                saved.push((slot, b));
                *block = if slot == diag {
                    s * b * s + (Mat3::identity() - s) * own_scale(&b)
                } else if filter.is_free(j) {
                    s * b
                } else {
                    s * b * filter.projector(j)
                };
            }
        }
    });
}

/// Puts back the blocks [`filter_in_place`] saved, bit for bit.
fn restore_filtered(a: &mut BlockSparseMatrix, saved: &mut [Vec<(usize, Mat3)>]) {
    a.edit_row_chunks(saved, |_, _, first_slot, blocks, saved| {
        for &(slot, block) in saved.iter() {
            blocks[slot - first_slot] = block;
        }
    });
}

/// `tr(A_ii) / 3`, or 1 when that is not a positive number.
fn own_scale(diag: &Mat3) -> f64 {
    let d = diag.trace() / 3.0;
    if d > 0.0 && d.is_finite() { d } else { 1.0 }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{BlockPattern, Constraint};

    /// `filter_in_place` equals `S A S + (I - S) tr(A_ii) / 3` computed
    /// block by block, and `restore_filtered` gives back `A`: on five
    /// particles (one chunk of rows), and on 600 in three chunks with
    /// couplings across the chunks' borders (each chunk's task then
    /// changes blocks whose mirrors another task changes).
    #[test]
    fn filtered_operator_is_s_a_s_plus_the_constrained_directions_own_scale() {
        let five = [(0, 1), (1, 2), (2, 3), (3, 4), (0, 4), (1, 3)];
        let kinds = [
            (1, Constraint::OneDirection { normal: Vec3::new(1.0, 2.0, 2.0) }),
            (3, Constraint::Fixed),
            (4, Constraint::TwoDirections { n: Vec3::x(), m: Vec3::new(0.0, 1.0, 1.0) }),
        ];
        check_filter(5, &five, &kinds);
        let n = 600;
        assert!(n > 2 * ROW_CHUNK);
        let mut pairs: Vec<(usize, usize)> = (0..n - 7).flat_map(|i| [(i, i + 1), (i, i + 7)]).collect();
        pairs.extend([(0, n - 1), (100, 400), (ROW_CHUNK - 1, ROW_CHUNK), (5, 2 * ROW_CHUNK + 5)]);
        let kinds: Vec<_> = (0..n)
            .filter_map(|i| match i % 7 {
                0 => Some((i, Constraint::Fixed)),
                2 | 5 => Some((i, Constraint::OneDirection { normal: Vec3::new(1.0, i as f64, 2.0) })),
                3 => Some((i, Constraint::TwoDirections { n: Vec3::z(), m: Vec3::new(1.0, 1.0, 0.5) })),
                _ => None,
            })
            .collect();
        check_filter(n, &pairs, &kinds);
    }

    fn check_filter(n: usize, pairs: &[(usize, usize)], constraints: &[(usize, Constraint)]) {
        let pattern = BlockPattern::from_pairs(n, pairs.iter().copied()).unwrap();
        let mut a = BlockSparseMatrix::new(pattern.clone());
        let cols: Vec<Vec<u32>> = (0..n).map(|i| pattern.row_cols(i).to_vec()).collect();
        // A symmetric matrix with distinct entries: A_ij = M(i + j) + M(i + j)^T.
        let block = |i: usize, j: usize| {
            let m = Mat3::from_fn(|r, c| ((i + j) * 9 + r * 3 + c) as f64 * 0.1 + 1.0);
            m + m.transpose()
        };
        a.fill_rows(|i, row| {
            for (slot, &j) in row.iter_mut().zip(&cols[i]) {
                *slot = block(i, j as usize);
            }
        });
        let mut filter = ConstraintFilter::new(n);
        for &(i, c) in constraints {
            filter.set(i, c, Vec3::zeros()).unwrap();
        }
        let mut f = a.clone();
        let mut saved = Vec::new();
        filter_in_place(&mut f, &filter, &mut saved);
        for (i, j, got) in f.blocks() {
            let mut expected = filter.projector(i) * block(i, j) * filter.projector(j);
            if i == j {
                expected += (Mat3::identity() - filter.projector(i)) * block(i, i).trace() / 3.0;
            }
            assert!((got - expected).norm() <= 1e-15 * block(i, j).norm(), "block ({i}, {j}) of {n}");
        }
        // Restoring the saved blocks gives back A exactly.
        let mut slots: Vec<usize> = saved.iter().flatten().map(|s| s.0).collect();
        slots.sort_unstable();
        assert!(slots.windows(2).all(|w| w[0] != w[1]), "a block saved twice");
        restore_filtered(&mut f, &mut saved);
        assert_eq!(f.values(), a.values());
    }
}
