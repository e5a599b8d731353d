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
    BlockSparseMatrix, ConstraintFilter, Preconditioner, PreconditionerKind, Vec3,
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

/// What a solve did.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PcgInfo {
    /// Iterations (matrix-vector products) performed.
    pub iterations: usize,
    /// Final `|S r| / |S (b - A z)|` (0 when the reference is 0).
    pub rel_residual: f64,
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
}

impl Pcg {
    /// A solver with scratch space for `n` block rows (grows on demand).
    pub fn new(n: usize) -> Self {
        let mut p = Self::default();
        p.resize(n);
        p
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
    pub fn solve(
        &mut self,
        a: &BlockSparseMatrix,
        b: &[Vec3],
        filter: &ConstraintFilter,
        params: &PcgParams,
        x: &mut [Vec3],
    ) -> Result<PcgInfo, PcgError> {
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
        if !self.precond.update(params.preconditioner, a) {
            return Err(PcgError::NoMultigridHierarchy);
        }

        // Reference residual S (b - A z), z = the prescribed part alone (kept in s).
        let z_only = &mut self.c;
        z_only.par_chunks_mut(ROW_CHUNK).for_each(|ch| ch.fill(Vec3::zeros()));
        filter.impose(z_only);
        a.mul_vec(&self.c, &mut self.q);
        sub_into(b, &self.q, &mut self.s);
        filter.project(&mut self.s);
        let ref_sq = dot_with(&self.s, &self.s, &mut self.partials);
        if !ref_sq.is_finite() {
            return Err(PcgError::NonFinite { iteration: 0 });
        }
        if ref_sq == 0.0 {
            // The prescribed values alone solve the system.
            x.copy_from_slice(&self.c);
            return Ok(PcgInfo::default());
        }
        let ref_norm = ref_sq.sqrt();
        let tol_sq = params.rel_tol * params.rel_tol * ref_sq;

        // Residual of the caller's guess; a guess worse than none is dropped.
        filter.impose(x);
        a.mul_vec(x, &mut self.q);
        sub_into(b, &self.q, &mut self.r);
        filter.project(&mut self.r);
        let mut r_sq = dot_with(&self.r, &self.r, &mut self.partials);
        if r_sq.is_nan() || r_sq > ref_sq {
            x.copy_from_slice(&self.c);
            self.r.copy_from_slice(&self.s);
            r_sq = ref_sq;
        }
        self.precond.apply(a, &self.r, &mut self.s);
        self.c.copy_from_slice(&self.s);
        filter.project(&mut self.c);
        let mut rho = dot_with(&self.r, &self.c, &mut self.partials);

        let mut iterations = 0;
        while r_sq > tol_sq {
            if iterations == params.max_iter {
                let info = PcgInfo { iterations, rel_residual: r_sq.sqrt() / ref_norm };
                return Err(PcgError::NotConverged { info });
            }
            iterations += 1;
            // c = S c, so c.(S A c) = c.(A c): the dot fuses with the product.
            let curvature = a.mul_vec_dot(&self.c, &mut self.q, &mut self.partials);
            filter.project(&mut self.q);
            if !curvature.is_finite() {
                return Err(PcgError::NonFinite { iteration: iterations });
            }
            if curvature <= 0.0 {
                return Err(PcgError::NotPositiveDefinite { iteration: iterations, curvature });
            }
            let alpha = rho / curvature;
            let rho_old = rho;
            (r_sq, rho) =
                if self.precond.is_pointwise() { self.step_fused(alpha, x) } else { self.step_unfused(alpha, a, x) };
            if !r_sq.is_finite() || !rho.is_finite() {
                return Err(PcgError::NonFinite { iteration: iterations });
            }
            if rho <= 0.0 && r_sq > 0.0 {
                return Err(PcgError::PreconditionerNotPositive { iteration: iterations });
            }
            let beta = rho / rho_old;
            self.c
                .par_chunks_mut(ROW_CHUNK)
                .zip(self.s.par_chunks(ROW_CHUNK))
                .for_each(|(cc, cs)| cc.iter_mut().zip(cs).for_each(|(ci, si)| *ci = si + beta * *ci));
            filter.project(&mut self.c);
        }
        Ok(PcgInfo { iterations, rel_residual: r_sq.sqrt() / ref_norm })
    }

    /// Sets the hierarchy for [`PreconditionerKind::Multigrid`].
    pub fn set_multigrid(&mut self, mg: crate::Multigrid) {
        self.precond.set_multigrid(mg);
    }

    /// As [`Pcg::step_fused`] for a preconditioner that is not row-local.
    fn step_unfused(&mut self, alpha: f64, a: &BlockSparseMatrix, x: &mut [Vec3]) -> (f64, f64) {
        x.par_chunks_mut(ROW_CHUNK)
            .zip(self.r.par_chunks_mut(ROW_CHUNK))
            .zip(self.c.par_chunks(ROW_CHUNK).zip(self.q.par_chunks(ROW_CHUNK)))
            .for_each(|((cx, cr), (cc, cq))| {
                for k in 0..cx.len() {
                    cx[k] += alpha * cc[k];
                    cr[k] -= alpha * cq[k];
                }
            });
        self.precond.apply(a, &self.r, &mut self.s);
        let r_sq = dot_with(&self.r, &self.r, &mut self.partials);
        let rho = dot_with(&self.r, &self.s, &mut self.partials);
        (r_sq, rho)
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

fn sub_into(a: &[Vec3], b: &[Vec3], out: &mut [Vec3]) {
    out.par_chunks_mut(ROW_CHUNK).zip(a.par_chunks(ROW_CHUNK).zip(b.par_chunks(ROW_CHUNK))).for_each(
        |(o, (ca, cb))| {
            for ((oi, ai), bi) in o.iter_mut().zip(ca).zip(cb) {
                *oi = ai - bi;
            }
        },
    );
}
