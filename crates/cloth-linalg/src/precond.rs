//! Preconditioners for [`crate::Pcg`].

use crate::{BlockSparseMatrix, Mat3, Multigrid, Vec3, par::ROW_CHUNK};
use rayon::prelude::*;

/// Which preconditioner PCG uses (scene name in brackets).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum PreconditionerKind {
    /// Plain conjugate gradients (`none`).
    None,
    /// Inverse of the scalar diagonal of the matrix, Jacobi (`diagonal`).
    Diagonal,
    /// Inverse of each 3x3 diagonal block, block-Jacobi (`block-jacobi`). Choi & Ko (2002,
    /// §4) report it about 20% faster than the scalar diagonal.
    #[default]
    BlockJacobi,
    /// One aggregation multigrid cycle, [`Multigrid`] (`multigrid`); the hierarchy must
    /// be given with [`crate::Pcg::set_multigrid`].
    Multigrid,
}

/// A preconditioner `P^-1` built from a matrix, stored as one 3x3 block per
/// row (diagonal for [`PreconditionerKind::Diagonal`]).
#[derive(Debug, Clone, Default)]
pub struct Preconditioner {
    kind: PreconditionerKind,
    inv: Vec<Mat3>,
    multigrid: Option<Multigrid>,
}

impl Preconditioner {
    /// Hands the solve's couplings to the multigrid hierarchy, if any (see
    /// [`Multigrid::set_couplings`]); the other kinds see only the matrix.
    pub fn set_couplings(&mut self, couplings: &crate::Couplings, filter: &crate::ConstraintFilter) {
        if let Some(mg) = &mut self.multigrid {
            mg.set_couplings(couplings, filter);
        }
    }

    /// As [`Preconditioner::set_couplings`], for the couplings of the last
    /// call under a filter changed only at `changed` (see
    /// [`Multigrid::set_couplings_rows`]).
    pub fn set_couplings_rows(
        &mut self,
        couplings: &crate::Couplings,
        filter: &crate::ConstraintFilter,
        changed: &[usize],
    ) {
        if let Some(mg) = &mut self.multigrid {
            mg.set_couplings_rows(couplings, filter, changed);
        }
    }

    /// Rebuilds `P^-1` from the diagonal blocks of `a`, reusing storage.
    /// A block that cannot be inverted (not positive) falls back to the
    /// identity for that row, which keeps `P^-1` symmetric positive definite.
    /// Returns false when `kind` is [`PreconditionerKind::Multigrid`] and no
    /// hierarchy was set.
    pub fn update(&mut self, kind: PreconditionerKind, a: &BlockSparseMatrix) -> bool {
        self.kind = kind;
        match kind {
            PreconditionerKind::None => return true,
            PreconditionerKind::Multigrid => {
                return match &mut self.multigrid {
                    Some(mg) => {
                        mg.update(a);
                        true
                    }
                    None => false,
                };
            }
            PreconditionerKind::Diagonal | PreconditionerKind::BlockJacobi => {}
        }
        self.inv.resize(a.n(), Mat3::identity());
        self.inv.par_chunks_mut(ROW_CHUNK).enumerate().for_each(|(c, chunk)| {
            for (k, p) in chunk.iter_mut().enumerate() {
                let d = a.diag(c * ROW_CHUNK + k);
                *p = match kind {
                    PreconditionerKind::Diagonal => {
                        let inv = |x: f64| {
                            if x > 0.0 && x.is_finite() { 1.0 / x } else { 1.0 }
                        };
                        Mat3::from_diagonal(&Vec3::new(inv(d[(0, 0)]), inv(d[(1, 1)]), inv(d[(2, 2)])))
                    }
                    _ => d.cholesky().map(|ch| ch.inverse()).unwrap_or_else(Mat3::identity),
                };
            }
        });
        true
    }

    /// As [`Preconditioner::update`], for an `a` that differs from the
    /// matrix of the last update only in the rows and columns of the nodes
    /// `changed`: the multigrid refills only what they reach
    /// ([`Multigrid::update_rows`]), the other kinds rebuild. Returns
    /// whether it was built (as `update`) and whether only in part.
    pub fn update_rows(&mut self, kind: PreconditionerKind, a: &BlockSparseMatrix, changed: &[usize]) -> (bool, bool) {
        match (kind, &mut self.multigrid) {
            (PreconditionerKind::Multigrid, Some(mg)) => {
                self.kind = kind;
                (true, mg.update_rows(a, changed))
            }
            _ => (self.update(kind, a), false),
        }
    }

    /// Sets the multigrid hierarchy used by [`PreconditionerKind::Multigrid`].
    pub fn set_multigrid(&mut self, mg: Multigrid) {
        self.multigrid = Some(mg);
    }

    /// Whether `P^-1` acts row by row (so PCG can fuse it into its update).
    pub fn is_pointwise(&self) -> bool {
        self.kind != PreconditionerKind::Multigrid
    }

    /// Whether `P^-1 r` is a nonlinear function of `r` (the multigrid's
    /// K-cycle): PCG then needs the flexible update.
    pub fn is_nonlinear(&self) -> bool {
        self.kind == PreconditionerKind::Multigrid && self.multigrid.as_ref().is_some_and(Multigrid::is_nonlinear)
    }

    /// The kind last built.
    pub fn kind(&self) -> PreconditionerKind {
        self.kind
    }

    /// `P^-1 r` for row `i` alone.
    #[inline]
    /// Only for pointwise kinds (see [`Preconditioner::is_pointwise`]).
    pub fn apply_one(&self, i: usize, r: &Vec3) -> Vec3 {
        match self.kind {
            PreconditionerKind::None => *r,
            _ => self.inv[i] * r,
        }
    }

    /// `s = P^-1 r` for the matrix `a` last passed to [`Preconditioner::update`].
    pub fn apply(&mut self, a: &BlockSparseMatrix, r: &[Vec3], s: &mut [Vec3]) {
        if self.kind == PreconditionerKind::None {
            s.copy_from_slice(r);
            return;
        }
        if self.kind == PreconditionerKind::Multigrid {
            self.multigrid.as_mut().expect("update() checked the hierarchy").apply(a, r, s);
            return;
        }
        s.par_chunks_mut(ROW_CHUNK).zip(r.par_chunks(ROW_CHUNK)).zip(self.inv.par_chunks(ROW_CHUNK)).for_each(
            |((cs, cr), cp)| {
                for ((si, ri), pi) in cs.iter_mut().zip(cr).zip(cp) {
                    *si = pi * ri;
                }
            },
        );
    }
}
