//! The couplings a solve adds to its matrix ([`crate::Couplings`]), on
//! every level of the hierarchy: without them the cycle preconditions `A`
//! where PCG solves `A + E`, and where layers of cloth press on each other
//! (a heap, a garment's folds) it treats the layers as held in place by
//! their contacts instead of moving together.
//!
//! A coupling is the stiffness `k w w^T` over up to four nodes, `w_i = g_i
//! S_i u` its node weight times its direction, projected by the node's
//! filter (the hierarchy's operator is `S A S + (I - S) d`, so `S E S` is
//! the coupling's part of it). `A` holds each node's own block `k w_i
//! w_i^T`; the rest is applied here. On a coarse level the Galerkin product
//! `P^T E P` of a plain aggregation is again such a term: the weights of
//! the nodes in one aggregate add up, `W_a = sum w_i`, and the own blocks
//! the level's matrix already holds are `O_a = sum w_i w_i^T`, so
//!
//! `(E x)_a = k (W_a (sum_b W_b . x_b) - O_a x_a)`,
//!
//! the exact Galerkin level of `A + E`, which stays symmetric positive
//! definite with it.
//!
//! The damped block-Jacobi smoother keeps the cycle positive definite when
//! `2 D / omega` bounds the level's operator; the damping was chosen for
//! `A`'s elements of at most `n_e` nodes, `omega = 2 OMEGA / n_e`, so that
//! `A <= n_e D` (see `OMEGA`). A term over `m` nodes is bounded by its
//! nodes' blocks (Cauchy-Schwarz): `k W W^T <= m F`, `F = blockdiag(k W_a
//! W_a^T)`. Each coupled node's smoother block gains `c F_a`:
//! - on a coarse level, `c = omega m / 2`, so that `2 c F / omega`
//!   bounds the whole term;
//! - on the finest, where `F` is the own blocks `D` already holds (`D >=
//!   F`), the slack `(2 / omega - n_e) D` covers part of `E <= (m - 1) F`,
//!   and `c = omega max(0, m - 1 - 2 / omega + n_e) / 2`.
//!
//! Without it, a particle pressed by a triangle (4 nodes) on a cloth of
//! links (damped for 2) made the cycle indefinite. The sharper bound on
//! the finest level saves iterations (`docs/results/self-contact-couplings.md`).

use super::kernels::{inverse_block, invert_pair};
use crate::{BlockSparseMatrix, ConstraintFilter, Couplings, Mat3, Vec3};

/// One coupling on one level: its nodes (distinct; `len` of them used).
#[derive(Debug, Clone, Copy)]
struct Term {
    nodes: [u32; 4],
    len: usize,
    /// `W_a`, per node.
    w: [Vec3; 4],
    /// `O_a`, per node: the own blocks the level's matrix holds.
    own: [Mat3; 4],
    /// Stiffness `k` (the matrix's units).
    k: f64,
}

/// The couplings on one level's nodes.
#[derive(Debug, Clone, Default)]
pub(super) struct LevelCouplings {
    terms: Vec<Term>,
    /// Per node of the level: what the smoother's diagonal gains (zero
    /// between calls of [`LevelCouplings::stiffen_smoother`]).
    extra: Vec<Mat3>,
    /// The nodes some term reaches, each once, and their marks.
    touched: Vec<u32>,
    listed: Vec<bool>,
}

impl LevelCouplings {
    /// Whether there is no term.
    pub(super) fn is_empty(&self) -> bool {
        self.terms.is_empty()
    }

    /// The finest level's terms from the solve's couplings, each node's
    /// weight projected by its filter.
    pub(super) fn set_fine(&mut self, couplings: &Couplings, filter: &ConstraintFilter) {
        self.terms.clear();
        self.terms.extend(couplings.terms().iter().map(|c| Term::fine(c, filter)));
    }

    /// As [`LevelCouplings::set_fine`], for the couplings of the last call
    /// (as many terms) under a filter that changed only at the nodes
    /// `marked`: only the terms reaching them are made again, and their
    /// places listed in `redone`.
    pub(super) fn update_fine(
        &mut self,
        couplings: &Couplings,
        filter: &ConstraintFilter,
        marked: &[bool],
        redone: &mut Vec<u32>,
    ) {
        redone.clear();
        for (k, (c, t)) in couplings.terms().iter().zip(&mut self.terms).enumerate() {
            if c.nodes.iter().zip(&c.weights).any(|(&node, &g)| g != 0.0 && marked[node as usize]) {
                *t = Term::fine(c, filter);
                redone.push(k as u32);
            }
        }
    }

    /// The number of terms.
    pub(super) fn len(&self) -> usize {
        self.terms.len()
    }

    /// The next level's terms: each node taken to its aggregate
    /// (`coarse_of`), nodes in one aggregate merged.
    pub(super) fn aggregate_into(&self, coarse_of: &[u32], next: &mut LevelCouplings) {
        next.terms.clear();
        next.terms.extend(self.terms.iter().map(|t| t.aggregated(coarse_of)));
    }

    /// As [`LevelCouplings::aggregate_into`] for the terms `redone` alone
    /// (the others are as the last call left them).
    pub(super) fn aggregate_redone(&self, coarse_of: &[u32], next: &mut LevelCouplings, redone: &[u32]) {
        for &k in redone {
            next.terms[k as usize] = self.terms[k as usize].aggregated(coarse_of);
        }
    }

    /// `out += factor E x`; returns `x . (factor E x)`. Serial, in the
    /// terms' order: the same bits on any thread count.
    pub(super) fn add_product(&self, x: &[Vec3], factor: f64, out: &mut [Vec3]) -> f64 {
        let mut dot = 0.0;
        for t in &self.terms {
            let k = factor * t.k;
            let gap: f64 = (0..t.len).map(|a| t.w[a].dot(&x[t.nodes[a] as usize])).sum();
            for a in 0..t.len {
                let i = t.nodes[a] as usize;
                let y = (t.w[a] * gap - t.own[a] * x[i]) * k;
                dot += x[i].dot(&y);
                out[i] += y;
            }
        }
        dot
    }

    /// Adds the terms to a dense row-major operator of `3 n` rows.
    pub(super) fn add_to_dense(&self, dense: &mut [f64], dim: usize) {
        for t in &self.terms {
            for a in 0..t.len {
                for b in 0..t.len {
                    let mut block = t.w[a] * t.w[b].transpose() * t.k;
                    if a == b {
                        block -= t.own[a] * t.k;
                    }
                    let (i, j) = (3 * t.nodes[a] as usize, 3 * t.nodes[b] as usize);
                    for r in 0..3 {
                        for c in 0..3 {
                            dense[(i + r) * dim + j + c] += block[(r, c)];
                        }
                    }
                }
            }
        }
    }
}

impl LevelCouplings {
    /// Recomputes the smoother's damped inverse blocks `inv_diag` (and the
    /// pairs', `pairs`) of the nodes the terms touch, from `a`'s diagonal
    /// plus each node's bound of the terms (see the module docs).
    ///
    /// `refilled`: `None` after a full refill (every inverse is plain:
    /// each touched node's is recomputed), or after a partial refill
    /// ([`super::Multigrid::update_rows`]) the nodes whose diagonal inverse
    /// it recomputed. Only they and their pair partners are recomputed: the
    /// other nodes' diagonal blocks and filters, so their bounds and their
    /// inverses, are those of the last call.
    pub(super) fn stiffen_smoother(
        &mut self,
        a: &BlockSparseMatrix,
        (omega, finest): (f64, bool),
        inv_diag: &mut [Mat3],
        pairs: Option<&mut (Vec<u32>, Vec<Mat3>)>,
        refilled: Option<&[bool]>,
    ) {
        if self.terms.is_empty() {
            return;
        }
        self.extra.resize(inv_diag.len(), Mat3::zeros());
        self.listed.resize(inv_diag.len(), false);
        let element_nodes = 2.0 * super::OMEGA / omega;
        for t in &self.terms {
            let m = t.len as f64;
            let share = if finest { (m - 1.0 - 2.0 / omega + element_nodes).max(0.0) } else { m };
            let scale = 0.5 * omega * share * t.k;
            for a in 0..t.len {
                let i = t.nodes[a] as usize;
                if !self.listed[i] {
                    self.listed[i] = true;
                    self.touched.push(i as u32);
                }
                self.extra[i] += t.w[a] * t.w[a].transpose() * scale;
            }
        }
        let partner = |i: usize| pairs.as_ref().map_or(i, |(partner, _)| partner[i] as usize);
        let stale = |i: usize, p: usize| refilled.is_none_or(|marks| marks[i] || marks[p]);
        let extra = &self.extra;
        for &i in &self.touched {
            let i = i as usize;
            if stale(i, partner(i)) {
                inv_diag[i] = inverse_block(&(a.diag(i) + extra[i]), omega);
            }
        }
        if let Some((partner, inv_off)) = pairs {
            for &i in &self.touched {
                let (i, p) = (i as usize, partner[i as usize] as usize);
                if p != i && stale(i, p) {
                    inv_diag[p] = inverse_block(&(a.diag(p) + extra[p]), omega);
                    let (lo, hi) = (i.min(p), i.max(p));
                    invert_pair(a, omega, (lo, hi), (extra[lo], extra[hi]), inv_diag, inv_off);
                }
            }
        }
        for &i in &self.touched {
            (self.extra[i as usize], self.listed[i as usize]) = (Mat3::zeros(), false);
        }
        self.touched.clear();
    }
}

impl Term {
    /// The finest level's term of coupling `c`: each node's weight times
    /// the direction, projected by its filter.
    fn fine(c: &crate::Coupling, filter: &ConstraintFilter) -> Self {
        let mut t = Term { nodes: [0; 4], len: 0, w: [Vec3::zeros(); 4], own: [Mat3::zeros(); 4], k: c.stiffness };
        for (&node, &g) in c.nodes.iter().zip(&c.weights) {
            if g != 0.0 {
                let w = filter.projector(node as usize) * c.direction * g;
                t.add(node, w, w * w.transpose());
            }
        }
        t
    }

    /// This term on the next level: each node taken to its aggregate,
    /// nodes in one aggregate merged.
    fn aggregated(&self, coarse_of: &[u32]) -> Self {
        let mut c = Term { len: 0, ..*self };
        for a in 0..self.len {
            c.add(coarse_of[self.nodes[a] as usize], self.w[a], self.own[a]);
        }
        c
    }

    /// Adds `w` and `own` to `node`'s entry, making one if it has none.
    fn add(&mut self, node: u32, w: Vec3, own: Mat3) {
        let a = (0..self.len).find(|&a| self.nodes[a] == node).unwrap_or_else(|| {
            self.nodes[self.len] = node;
            self.w[self.len] = Vec3::zeros();
            self.own[self.len] = Mat3::zeros();
            self.len += 1;
            self.len - 1
        });
        self.w[a] += w;
        self.own[a] += own;
    }
}
