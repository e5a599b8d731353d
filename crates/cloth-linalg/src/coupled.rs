//! Filtered PCG with rigid bodies among the unknowns: monolithic
//! cloth-body coupling.
//!
//! A body `b` adds six unknowns `y_b` (its end-of-step translation and
//! rotation vector, or their rates, in the units of the cloth's unknown)
//! to the filtered system `A x = b`. A particle `i` a body holds (a pin on
//! the body, a contact with it) has its constrained components follow the
//! body: `x_i = S_i w_i + (I - S_i)(z_i + J_i y_b)`, with the link map
//! `G_i = (I - S_i) J_i` (3x6) and `J_i = [I | -[r_i]x]` for the lever
//! `r_i` from the body's centre of mass. The body's own equation is
//! `K_b y_b = -sum_i G_i^T (A x - b)_i + l_b` (`l_b` a load no link
//! carries): its mass block (`K_b`, scaled by
//! the caller into the cloth's units) times its change equals the
//! constraint reactions of the particles it holds. Eliminating nothing,
//! the reduced unknown `(w, y)` solves
//!
//! ```text
//! [ S A S      S A G     ] [w]   [ S (b - A z)   ]
//! [ G^T A S    G^T A G + K ] [y] = [ G^T (b - A z) + l ]
//! ```
//!
//! which is `P^T diag(A, K) P` for the full-column-rank map
//! `P (w, y) = (S w + G y, y)`: symmetric positive definite whenever `A`
//! and every `K_b` are. The preconditioner is block diagonal: `S P^-1 S`
//! on particles (`P` the block-Jacobi of `A`, or, when asked for and set,
//! the multigrid of `S A S + (I - S) d` as in [`crate::Pcg`]) and
//! `(K_b + sum_i G_i^T A_ii G_i)^-1` on bodies, each block SPD, so the
//! preconditioner is positive definite on the reduced space.

use crate::{
    BlockSparseMatrix, ConstraintFilter, PcgError, PcgInfo, PcgParams, Preconditioner, PreconditionerKind, Vec3,
    par::{ROW_CHUNK, chunk_count, dot_with},
};
use nalgebra::{Matrix3x6, Matrix6, Vector6};
use rayon::prelude::*;

/// One particle a body holds: `x_i` gains `map * y_b`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RigidLink {
    /// The body (index into [`RigidCoupling::add_body`]'s order).
    pub body: usize,
    /// The particle.
    pub particle: usize,
    /// `G_i = (I - S_i) J_i`: how the particle's constrained components
    /// move with the body's six unknowns.
    pub map: Matrix3x6<f64>,
}

/// The bodies of one coupled solve and the particles they hold.
#[derive(Debug, Clone, Default)]
pub struct RigidCoupling {
    bodies: Vec<Matrix6<f64>>,
    links: Vec<RigidLink>,
    /// Each body's load outside the links, added to its row's right-hand side.
    loads: Vec<Vector6<f64>>,
}

impl RigidCoupling {
    /// No bodies (keeps the allocations).
    pub fn clear(&mut self) {
        self.bodies.clear();
        self.links.clear();
        self.loads.clear();
    }

    /// Unlinks every particle and zeroes the loads, keeping the bodies.
    pub fn clear_links(&mut self) {
        self.links.clear();
        self.loads.iter_mut().for_each(|l| *l = Vector6::zeros());
    }

    /// Adds `load` to body `body`'s right-hand side: a force on the body
    /// that no link carries (friction a particle takes from it at a fixed
    /// value, say), in the units of `G^T (b - A x)`.
    pub fn add_load(&mut self, body: usize, load: Vector6<f64>) {
        self.loads[body] += load;
    }

    /// Adds a body with mass block `k` (symmetric positive definite, in
    /// the cloth system's units); returns its index.
    pub fn add_body(&mut self, k: Matrix6<f64>) -> usize {
        self.bodies.push(k);
        self.loads.push(Vector6::zeros());
        self.bodies.len() - 1
    }

    /// Lets `body` carry `particle` through `map` (see [`RigidLink::map`]).
    pub fn link(&mut self, body: usize, particle: usize, map: Matrix3x6<f64>) {
        self.links.push(RigidLink { body, particle, map });
    }

    /// Number of bodies.
    pub fn body_count(&self) -> usize {
        self.bodies.len()
    }

    /// The links, in the order added.
    pub fn links(&self) -> &[RigidLink] {
        &self.links
    }

    /// Whether no particle is linked to a body (a coupled solve is then
    /// the plain filtered solve, with the bodies unmoved).
    pub fn is_empty(&self) -> bool {
        self.links.is_empty()
    }

    /// `u = w + sum_links G y` (`w` already filtered).
    fn expand(&self, w: &[Vec3], y: &[Vector6<f64>], u: &mut [Vec3]) {
        u.copy_from_slice(w);
        for l in &self.links {
            u[l.particle] += l.map * y[l.body];
        }
    }

    /// `out_b = K_b y_b + sum_links G^T t`, in link order.
    fn gather(&self, t: &[Vec3], y: &[Vector6<f64>], out: &mut [Vector6<f64>]) {
        for (o, (k, yb)) in out.iter_mut().zip(self.bodies.iter().zip(y)) {
            *o = k * yb;
        }
        for l in &self.links {
            out[l.body] += l.map.transpose() * t[l.particle];
        }
    }
}

/// A solver for [`RigidCoupling`] systems owning its scratch vectors.
#[derive(Debug, Clone, Default)]
pub struct CoupledPcg {
    w: Vec<Vec3>,
    r: Vec<Vec3>,
    s: Vec<Vec3>,
    c: Vec<Vec3>,
    q: Vec<Vec3>,
    u: Vec<Vec3>,
    t: Vec<Vec3>,
    z: Vec<Vec3>,
    ry: Vec<Vector6<f64>>,
    sy: Vec<Vector6<f64>>,
    cy: Vec<Vector6<f64>>,
    qy: Vec<Vector6<f64>>,
    body_inv: Vec<Matrix6<f64>>,
    partials: Vec<f64>,
    precond: Preconditioner,
    /// The multigrid's operator: a filtered copy of `A` (the coupled
    /// operator needs `A` itself, whose constrained rows carry the bodies).
    filtered: Option<BlockSparseMatrix>,
    saved_blocks: Vec<Vec<(usize, crate::Mat3)>>,
    has_multigrid: bool,
    /// What the multigrid was last built from.
    hierarchy: crate::pcg::HierarchySource,
}

/// Sum of `a_b . b_b` over bodies, in body order.
fn dot6(a: &[Vector6<f64>], b: &[Vector6<f64>]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x.dot(y)).sum()
}

impl CoupledPcg {
    /// Sets the hierarchy for [`PreconditionerKind::Multigrid`] (without
    /// one, a solve asking for it uses block-Jacobi).
    pub fn set_multigrid(&mut self, mg: crate::Multigrid) {
        self.precond.set_multigrid(mg);
        self.has_multigrid = true;
        self.hierarchy.forget();
    }

    fn resize(&mut self, n: usize, m: usize) {
        for v in
            [&mut self.w, &mut self.r, &mut self.s, &mut self.c, &mut self.q, &mut self.u, &mut self.t, &mut self.z]
        {
            v.resize(n, Vec3::zeros());
        }
        for v in [&mut self.ry, &mut self.sy, &mut self.cy, &mut self.qy] {
            v.resize(m, Vector6::zeros());
        }
        self.body_inv.resize(m, Matrix6::zeros());
        self.partials.resize(chunk_count(n), 0.0);
    }

    /// Solves the coupled system (see the module). On entry `x` is the
    /// guess of the full unknown (its free components are used) and `y`
    /// the bodies' guess; on return `x` is the full unknown, constrained
    /// components included (`S w + (I - S) z + G y`), and `y` the bodies'
    /// unknowns. Preconditioned by block-Jacobi, or by the multigrid when
    /// `params` asks for it and one was set.
    ///
    /// # Panics
    /// When the sizes of `a`, `b`, `x`, `filter` differ, `y` does not have
    /// one entry per body, or a link names a particle or body out of range
    /// (programming errors, not input errors).
    pub fn solve(
        &mut self,
        a: &BlockSparseMatrix,
        b: &[Vec3],
        filter: &ConstraintFilter,
        coupling: &RigidCoupling,
        params: &PcgParams,
        (x, y): (&mut [Vec3], &mut [Vector6<f64>]),
    ) -> Result<PcgInfo, PcgError> {
        let (n, m) = (a.n(), coupling.body_count());
        assert!(b.len() == n && x.len() == n && filter.n() == n && y.len() == m, "CoupledPcg: dimension mismatch");
        assert!(coupling.links.iter().all(|l| l.particle < n && l.body < m), "CoupledPcg: link out of range");
        if !(params.rel_tol.is_finite() && params.rel_tol >= 0.0) {
            return Err(PcgError::InvalidTolerance { rel_tol: params.rel_tol });
        }
        self.resize(n, m);
        // The prescribed part alone, and the reference residual of the
        // guess "free components and bodies zero": (S, G^T)(b - A z).
        self.z.par_chunks_mut(ROW_CHUNK).for_each(|ch| ch.fill(Vec3::zeros()));
        filter.impose(&mut self.z);
        a.residual(b, &self.z, &mut self.t);
        self.s.copy_from_slice(&self.t);
        filter.project(&mut self.s);
        self.cy.iter_mut().for_each(|v| *v = Vector6::zeros());
        coupling.gather(&self.t, &self.cy, &mut self.sy);
        for (s, load) in self.sy.iter_mut().zip(&coupling.loads) {
            *s += load;
        }
        let ref_sq = dot_with(&self.s, &self.s, &mut self.partials) + dot6(&self.sy, &self.sy);
        if !ref_sq.is_finite() {
            return Err(PcgError::NonFinite { iteration: 0 });
        }
        // The guess: x's free components, y as given.
        self.w.copy_from_slice(x);
        filter.project(&mut self.w);
        operator(a, filter, coupling, (&self.w, y), (&mut self.u, &mut self.t), (&mut self.q, &mut self.qy));
        // r = rhs - Op(guess): rhs rows are s/sy; Op(guess) is in q/qy.
        for i in 0..n {
            self.r[i] = self.s[i] - self.q[i];
        }
        for k in 0..m {
            self.ry[k] = self.sy[k] - self.qy[k];
        }
        let mut r_sq = dot_with(&self.r, &self.r, &mut self.partials) + dot6(&self.ry, &self.ry);
        if r_sq.is_nan() || r_sq > ref_sq {
            self.w.iter_mut().for_each(|v| *v = Vec3::zeros());
            y.iter_mut().for_each(|v| *v = Vector6::zeros());
            self.r.copy_from_slice(&self.s);
            self.ry.copy_from_slice(&self.sy);
            r_sq = ref_sq;
        }
        let info = if ref_sq == 0.0 {
            Ok(PcgInfo::default())
        } else {
            self.iterate(a, filter, coupling, params, y, (ref_sq, r_sq))
        };
        // The full unknown, even on error (the last iterate).
        coupling.expand(&self.w, y, x);
        for (xi, zi) in x.iter_mut().zip(&self.z) {
            *xi += zi;
        }
        info
    }

    fn iterate(
        &mut self,
        a: &BlockSparseMatrix,
        filter: &ConstraintFilter,
        coupling: &RigidCoupling,
        params: &PcgParams,
        y: &mut [Vector6<f64>],
        (ref_sq, mut r_sq): (f64, f64),
    ) -> Result<PcgInfo, PcgError> {
        let mut partial_refill = false;
        if params.preconditioner == PreconditionerKind::Multigrid && self.has_multigrid {
            // A contact pass solves the same matrix under another filter:
            // the copy is filtered again where the filters differ, and the
            // hierarchy refills only what the changed particles reach.
            let changed = self.hierarchy.changes(a, filter);
            let f = match (self.filtered.take(), changed.is_some()) {
                (Some(mut f), true) => {
                    crate::pcg::refilter(&mut f, filter, &mut self.saved_blocks);
                    f
                }
                (previous, _) => crate::pcg::filtered_copy(previous, a, filter, &mut self.saved_blocks),
            };
            match changed {
                Some(changed) => {
                    partial_refill = self.precond.update_rows(PreconditionerKind::Multigrid, &f, changed).1
                }
                None => _ = self.precond.update(PreconditionerKind::Multigrid, &f),
            }
            self.hierarchy.built(a, true);
            self.filtered = Some(f);
        } else {
            self.hierarchy.forget();
            self.precond.update(PreconditionerKind::BlockJacobi, a);
        }
        for (inv, k) in self.body_inv.iter_mut().zip(&coupling.bodies) {
            *inv = *k;
        }
        for l in &coupling.links {
            self.body_inv[l.body] += l.map.transpose() * a.diag(l.particle) * l.map;
        }
        for (k, inv) in self.body_inv.iter_mut().enumerate() {
            *inv = inv.cholesky().map(|c| c.inverse()).ok_or(PcgError::PreconditionerNotPositive { iteration: k })?;
        }
        let tol_sq = params.stop_sq(ref_sq);
        let mut rho = self.precondition(filter);
        self.c.copy_from_slice(&self.s);
        self.cy.copy_from_slice(&self.sy);
        let mut iterations = 0;
        while r_sq > tol_sq {
            if iterations == params.max_iter {
                let info = PcgInfo { iterations, rel_residual: (r_sq / ref_sq).sqrt(), partial_refill };
                return Err(PcgError::NotConverged { info });
            }
            iterations += 1;
            operator(a, filter, coupling, (&self.c, &self.cy), (&mut self.u, &mut self.t), (&mut self.q, &mut self.qy));
            let curvature = dot_with(&self.c, &self.q, &mut self.partials) + dot6(&self.cy, &self.qy);
            if !curvature.is_finite() {
                return Err(PcgError::NonFinite { iteration: iterations });
            }
            if curvature <= 0.0 {
                return Err(PcgError::NotPositiveDefinite { iteration: iterations, curvature });
            }
            let alpha = rho / curvature;
            self.w
                .par_chunks_mut(ROW_CHUNK)
                .zip(self.r.par_chunks_mut(ROW_CHUNK))
                .zip(self.c.par_chunks(ROW_CHUNK).zip(self.q.par_chunks(ROW_CHUNK)))
                .for_each(|((cw, cr), (cc, cq))| {
                    for k in 0..cw.len() {
                        cw[k] += alpha * cc[k];
                        cr[k] -= alpha * cq[k];
                    }
                });
            for ((yk, rk), (ck, qk)) in y.iter_mut().zip(&mut self.ry).zip(self.cy.iter().zip(&self.qy)) {
                *yk += alpha * ck;
                *rk -= alpha * qk;
            }
            r_sq = dot_with(&self.r, &self.r, &mut self.partials) + dot6(&self.ry, &self.ry);
            let rho_old = rho;
            rho = self.precondition(filter);
            if !r_sq.is_finite() || !rho.is_finite() {
                return Err(PcgError::NonFinite { iteration: iterations });
            }
            if rho <= 0.0 && r_sq > 0.0 {
                return Err(PcgError::PreconditionerNotPositive { iteration: iterations });
            }
            // Flexible (Polak-Ribiere) for a nonlinear preconditioner, as
            // in `Pcg`: beta = s_new.(r_new - r_old) / rho_old.
            let beta = if self.precond.is_nonlinear() {
                let sq = dot_with(&self.q, &self.s, &mut self.partials) + dot6(&self.qy, &self.sy);
                -alpha * sq / rho_old
            } else {
                rho / rho_old
            };
            self.c
                .par_chunks_mut(ROW_CHUNK)
                .zip(self.s.par_chunks(ROW_CHUNK))
                .for_each(|(cc, cs)| cc.iter_mut().zip(cs).for_each(|(ci, si)| *ci = si + beta * *ci));
            for (c, s) in self.cy.iter_mut().zip(&self.sy) {
                *c = s + beta * *c;
            }
        }
        Ok(PcgInfo { iterations, rel_residual: (r_sq / ref_sq).sqrt(), partial_refill })
    }

    /// `(s, sy) = P^-1 (r, ry)` (particles filtered), returning `r.s + ry.sy`.
    fn precondition(&mut self, filter: &ConstraintFilter) -> f64 {
        match &self.filtered {
            Some(f) if self.precond.kind() == PreconditionerKind::Multigrid => {
                self.precond.apply(f, &self.r, &mut self.s);
            }
            _ => {
                let precond = &self.precond;
                let rows = self.s.par_chunks_mut(ROW_CHUNK).zip(self.r.par_chunks(ROW_CHUNK));
                rows.enumerate().for_each(|(chunk, (cs, cr))| {
                    for (k, (si, ri)) in cs.iter_mut().zip(cr).enumerate() {
                        *si = precond.apply_one(chunk * ROW_CHUNK + k, ri);
                    }
                });
            }
        }
        filter.project(&mut self.s);
        for ((s, r), inv) in self.sy.iter_mut().zip(&self.ry).zip(&self.body_inv) {
            *s = inv * r;
        }
        dot_with(&self.r, &self.s, &mut self.partials) + dot6(&self.ry, &self.sy)
    }
}

/// `(q, qy) = Op(c, cy)`: `u = c + G cy`, `t = A u`, `q = S t`,
/// `qy = K cy + G^T t` (`u`, `t` scratch).
fn operator(
    a: &BlockSparseMatrix,
    filter: &ConstraintFilter,
    coupling: &RigidCoupling,
    (c, cy): (&[Vec3], &[Vector6<f64>]),
    (u, t): (&mut [Vec3], &mut [Vec3]),
    (q, qy): (&mut [Vec3], &mut [Vector6<f64>]),
) {
    coupling.expand(c, cy, u);
    a.mul_vec(u, t);
    q.copy_from_slice(t);
    filter.project(q);
    coupling.gather(t, cy, qy);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{BlockPattern, Constraint, Mat3};
    use nalgebra::{DMatrix, DVector};

    /// A chain of springs with masses on its diagonal: SPD, with distinct
    /// off-diagonal blocks.
    fn spring_chain(n: usize) -> BlockSparseMatrix {
        let pairs: Vec<(usize, usize)> = (0..n - 1).map(|i| (i, i + 1)).chain([(0, n - 1)]).collect();
        let pattern = BlockPattern::from_pairs(n, pairs).unwrap();
        let cols: Vec<Vec<u32>> = (0..n).map(|i| pattern.row_cols(i).to_vec()).collect();
        let spring = |i: usize, j: usize| {
            let d = Vec3::new(1.0 + (i + j) as f64 * 0.3, 0.5 - (i * j % 5) as f64 * 0.2, 0.7);
            d * d.transpose() * 40.0 + Mat3::identity() * 3.0
        };
        let mut a = BlockSparseMatrix::new(pattern);
        a.fill_rows(|i, row| {
            for (slot, &j) in row.iter_mut().zip(&cols[i]) {
                let j = j as usize;
                *slot = if i == j {
                    let neighbours = cols[i].iter().map(|&k| k as usize).filter(|&k| k != i);
                    Mat3::identity() * (1.0 + 0.1 * i as f64)
                        + neighbours.map(|k| spring(i.min(k), i.max(k))).sum::<Mat3>()
                } else {
                    -spring(i.min(j), i.max(j))
                };
            }
        });
        a
    }

    fn lever_map(r: Vec3, keep: Mat3) -> Matrix3x6<f64> {
        let mut j = Matrix3x6::zeros();
        j.fixed_view_mut::<3, 3>(0, 0).copy_from(&Mat3::identity());
        j.fixed_view_mut::<3, 3>(0, 3).copy_from(&-r.cross_matrix());
        keep * j
    }

    /// The coupled PCG against a dense solve of the saddle-point system
    /// with Lagrange multipliers for every constrained direction, built
    /// without the reduced form: `A x - b = C^T l`, `K y = -(C J)^T l`,
    /// `C x = C (z + J y)`.
    #[test]
    fn coupled_solve_matches_the_dense_saddle_point_system() {
        let n = 9;
        let a = spring_chain(n);
        let b: Vec<Vec3> = (0..n).map(|i| Vec3::new(i as f64 * 0.1, -1.0, 0.3 - i as f64 * 0.05)).collect();
        let mut filter = ConstraintFilter::new(n);
        // A free particle's pin (not on a body), two body contacts, two body pins.
        let n1 = Vec3::new(0.2, 1.0, -0.1).normalize();
        let n2 = Vec3::new(-0.3, 0.9, 0.2).normalize();
        filter.set(0, Constraint::Fixed, Vec3::new(0.01, 0.02, -0.03)).unwrap();
        filter.set(3, Constraint::OneDirection { normal: n1 }, n1 * 0.05).unwrap();
        filter.set(4, Constraint::OneDirection { normal: n2 }, n2 * -0.02).unwrap();
        filter.set(6, Constraint::Fixed, Vec3::new(0.0, 0.1, 0.0)).unwrap();
        filter.set(7, Constraint::Fixed, Vec3::new(0.05, 0.0, 0.02)).unwrap();
        let mut coupling = RigidCoupling::default();
        let body_mass = |m: f64, inertia: Mat3| {
            let mut k = Matrix6::zeros();
            k.fixed_view_mut::<3, 3>(0, 0).copy_from(&(Mat3::identity() * m));
            k.fixed_view_mut::<3, 3>(3, 3).copy_from(&inertia);
            k
        };
        let b0 = coupling.add_body(body_mass(2.0, Mat3::from_diagonal(&Vec3::new(0.3, 0.2, 0.25))));
        let b1 = coupling.add_body(body_mass(0.5, Mat3::new(0.1, 0.01, 0.0, 0.01, 0.12, 0.0, 0.0, 0.0, 0.08)));
        let levers = [
            (b0, 3, Vec3::new(0.1, -0.2, 0.0)),
            (b0, 4, Vec3::new(-0.1, -0.2, 0.05)),
            (b1, 6, Vec3::new(0.0, 0.3, 0.1)),
            (b1, 7, Vec3::new(0.2, 0.3, -0.1)),
        ];
        for &(body, i, r) in &levers {
            coupling.link(body, i, lever_map(r, Mat3::identity() - filter.projector(i)));
        }
        let params = PcgParams { rel_tol: 1e-13, max_iter: 500, ..Default::default() };
        let mut x = vec![Vec3::zeros(); n];
        let mut y = vec![Vector6::zeros(); 2];
        let info = CoupledPcg::default().solve(&a, &b, &filter, &coupling, &params, (&mut x, &mut y)).unwrap();
        assert!(info.iterations > 0);
        // Measured: particles 2.0e-15, bodies 2.8e-14 of the largest unknown.

        // The dense saddle point: unknowns x (3n), y (12), one multiplier per constrained direction.
        // (particle, constrained direction, its body and lever if any)
        type Row = (usize, Vec3, Option<(usize, Vec3)>);
        let mut rows: Vec<Row> = Vec::new();
        for (i, s, _) in filter.iter() {
            let p = Mat3::identity() - s;
            let eig = p.symmetric_eigen();
            for k in 0..3 {
                if eig.eigenvalues[k] > 0.5 {
                    let dir: Vec3 = eig.eigenvectors.column(k).into();
                    let body = levers.iter().find(|l| l.1 == i).map(|l| (l.0, l.2));
                    rows.push((i, dir, body));
                }
            }
        }
        let (nx, ny, nl) = (3 * n, 12, rows.len());
        let size = nx + ny + nl;
        let mut kkt = DMatrix::<f64>::zeros(size, size);
        let mut rhs = DVector::<f64>::zeros(size);
        for (i, j, blk) in a.blocks() {
            kkt.view_mut((3 * i, 3 * j), (3, 3)).copy_from(blk);
        }
        for (k, kb) in coupling.bodies.iter().enumerate() {
            kkt.view_mut((nx + 6 * k, nx + 6 * k), (6, 6)).copy_from(kb);
        }
        for (i, bi) in b.iter().enumerate() {
            rhs.rows_mut(3 * i, 3).copy_from(bi);
        }
        for (row, &(i, dir, body)) in rows.iter().enumerate() {
            let l = nx + ny + row;
            for d in 0..3 {
                kkt[(l, 3 * i + d)] = dir[d];
                kkt[(3 * i + d, l)] = -dir[d];
            }
            rhs[l] = dir.dot(&filter.prescribed(i));
            if let Some((bk, r)) = body {
                let cj = dir.transpose() * lever_map(r, Mat3::identity());
                for d in 0..6 {
                    kkt[(l, nx + 6 * bk + d)] = -cj[d];
                    kkt[(nx + 6 * bk + d, l)] = cj[d];
                }
            }
        }
        let dense = kkt.lu().solve(&rhs).unwrap();
        let scale = dense.rows(0, nx + ny).amax();
        for (i, xi) in x.iter().enumerate() {
            let err = (xi - Vec3::from(dense.fixed_rows::<3>(3 * i).into_owned())).amax();
            assert!(err <= 1e-14 * scale, "particle {i}: {err:e} of {scale:e}");
        }
        for (k, yk) in y.iter().enumerate() {
            let err = (yk - dense.fixed_rows::<6>(nx + 6 * k).into_owned()).amax();
            assert!(err <= 1e-13 * scale, "body {k}: {err:e} of {scale:e}");
        }
    }
}
