//! Smoothed aggregation on the finest level (Vaněk, Mandel & Brezina
//! 1996, "Algebraic multigrid by smoothed aggregation for second and fourth
//! order elliptic problems").
//!
//! Piecewise-constant aggregates interpolate a smooth correction with jumps
//! between aggregates; the jumps carry energy that grows with the ratio of
//! stiffness to mass, `h^2 k / m`, which quadruples from one grid to the
//! next finer one. On the hanging cloth the K-cycle's iterations doubled
//! from 257 x 257 to 513 x 513 particles, and a 257 x 257 cloth made 4
//! times lighter took as many as the finer one
//! (`docs/results/solver-before-after.md`). Smoothing the prolongator with one
//! damped Jacobi step of the operator,
//!
//! ```text
//! P = (I - omega_p D^-1 A_f) P_0,    A_c = P^T A P,
//! ```
//!
//! (`P_0` the aggregates, `D` the diagonal blocks of `A`, `A_f` the
//! operator with its weak couplings lumped onto the diagonal) makes each
//! aggregate's basis function overlap its neighbours' and fall off
//! smoothly. Only the finest level is smoothed: the levels below keep the
//! plain aggregates of [`Multigrid`] (a smoothed prolongator on every level
//! saved a further 15% of the iterations at 513 x 513 for denser coarse
//! operators and a slower solve).
//!
//! The couplings that are strong, `|A_ij|_F > THETA sqrt(|A_ii|_F
//! |A_jj|_F)`, are read from the first matrix given to
//! [`SmoothedFirst::update`], which then fixes the prolongator's pattern,
//! the coarse operator's pattern and the hierarchy below for good. Later
//! matrices keep the pattern and refill the values: each update recomputes
//! `P` (one pass over `A`) and the triple product (about ten times the
//! work of a product with `A`), summing only the upper triangle of the
//! symmetric `A_c` and mirroring the lower one (the refill's triple
//! product 97-128 -> 64-77 ms at 513 x 513 particles, the mirror 13-16).

use super::{
    Cycle, Multigrid, SinglePrecision, inverse_diagonal_block, invert_pairs, jacobi_from_zero, krylov_weights,
    mul_vec_dot, residual, smoothed, widen,
};
use crate::par::{ROW_CHUNK, chunk_count, dot_with};
use crate::{Aggregation, BlockPattern, BlockSparseMatrix, Mat3, Vec3};
use rayon::prelude::*;

/// Strength threshold: an off-diagonal block is a strong coupling when its
/// Frobenius norm exceeds `THETA` times the geometric mean of the two
/// diagonal blocks' (the usual value for smoothed aggregation of
/// elasticity). On the hanging cloth it keeps the links to the eight
/// nearest particles and drops the interlaced buckling links: 4 prolongator
/// blocks a row, 24.5 blocks a row in the coarse operator.
const THETA: f64 = 0.08;

/// Damping of the prolongator's Jacobi step, `omega_p`: `4 / (3
/// lambda_max(D^-1 A))` with `lambda_max` about 2 for matrices of links.
const OMEGA_P: f64 = 2.0 / 3.0;

/// The finest level of a smoothed-aggregation hierarchy, with the plain
/// hierarchy of its coarse operator below it.
#[derive(Debug, Clone)]
pub(super) struct SmoothedFirst {
    /// Fine node -> aggregate (`P_0`).
    coarse_of: Vec<u32>,
    n_coarse: usize,
    /// The aggregations of the levels below.
    below: Vec<Aggregation>,
    /// Levels of at least this many blocks get `f32` copies for residuals.
    single_from: usize,
    /// Nodes smoothed as pairs: each node's partner (itself when unpaired).
    partner: Option<Vec<u32>>,
    /// Built from the first matrix (see the module docs).
    built: Option<Built>,
}

#[derive(Debug, Clone)]
struct Built {
    /// Blocks a row of `P`, stored `width` to a row: the row's own
    /// aggregate first, then its strong neighbours' in ascending order;
    /// the `p_len` real entries of a row are followed by unused padding.
    width: usize,
    p_col: Vec<u32>,
    p_val: Vec<Mat3>,
    p_len: Vec<u8>,
    /// For each slot of the fine pattern, the entry of its row's `P` that
    /// `-omega_p D_i^-1 A_ij` goes to: the neighbour's aggregate for a
    /// strong coupling, the own aggregate (lumped) for a weak one and for
    /// the diagonal.
    p_entry_of_slot: Vec<u8>,
    /// `P^T` as lists: aggregate `c`'s entries `i * width + k` are
    /// `t_src[t_ptr[c]..t_ptr[c + 1]]`, ascending.
    t_ptr: Vec<u32>,
    t_src: Vec<u32>,
    /// `P`'s blocks in `t_src`'s order, `t_val[m] = p_val[t_src[m]]`:
    /// the restriction and `P^T (A P)` read them in order instead of
    /// gathering them across `P`'s rows.
    t_val: Vec<Mat3>,
    /// `A P`, stored `ap_width` to a row (its aggregates ascending, then
    /// zero padding), `ap_len` real entries a row (their aggregates are
    /// needed only to place the products, in `ap_at` and `coarse_at`).
    ap_width: usize,
    ap_val: Vec<Mat3>,
    ap_len: Vec<u8>,
    /// Where `A_s P_jk` goes in its row of `A P`: `ap_at[s * width + k]`.
    ap_at: Vec<u8>,
    /// Where `P_e^T (A P)_iq` goes in coarse row `c`, for the `m`-th entry
    /// `e` of `t_src` (row `i`): `coarse_at[m * ap_width + q]`.
    coarse_at: Vec<u8>,
    /// The first `q` whose block lands on or right of coarse row `c`'s
    /// diagonal, for the `m`-th entry of `t_src` (a row of `A P` lists
    /// its aggregates ascending): `A_c` is symmetric, so only its upper
    /// triangle is summed, the lower one mirrored
    /// ([`BlockSparseMatrix::symmetric_from_upper`]).
    upper_from: Vec<u8>,
    /// `P^T A P`.
    coarse: BlockSparseMatrix,
    /// The plain aggregation hierarchy of `coarse`, K-cycle.
    inner: Multigrid,
    single: Option<SinglePrecision>,
    /// `D_i^-1` (undamped, for `P`) and `omega D_i^-1` (the smoother).
    inv_plain: Vec<Mat3>,
    inv_diag: Vec<Mat3>,
    pairs: Option<(Vec<u32>, Vec<Mat3>)>,
    x: Vec<Vec3>,
    r: Vec<Vec3>,
    /// Coarse vectors: right-hand side, the two cycles' results, `A_c c1`,
    /// the second right-hand side, `A_c c2`.
    b_c: Vec<Vec3>,
    c1: Vec<Vec3>,
    c2: Vec<Vec3>,
    v: Vec<Vec3>,
    r2: Vec<Vec3>,
    w: Vec<Vec3>,
    partials: Vec<f64>,
}

impl SmoothedFirst {
    /// The first level over `aggregations[0]`, the plain hierarchy over
    /// the rest (checked by the caller).
    pub(super) fn new(aggregations: &[Aggregation], single_from: usize) -> Self {
        Self {
            coarse_of: aggregations[0].coarse_of.clone(),
            n_coarse: aggregations[0].n_coarse,
            below: aggregations[1..].to_vec(),
            single_from,
            partner: None,
            built: None,
        }
    }

    /// Nodes of the finest level.
    pub(super) fn fine_n(&self) -> usize {
        self.coarse_of.len()
    }

    /// Smooths the finest level's nodes in pairs (see
    /// [`Multigrid::with_pairs`]).
    pub(super) fn set_partner(&mut self, partner: Vec<u32>) {
        self.partner = Some(partner);
        self.built = None;
    }

    /// Levels including the finest.
    pub(super) fn depth(&self) -> usize {
        2 + self.below.len()
    }

    /// Refills `P`, `A_c` and the hierarchy below from `a` (fixing the
    /// patterns from the first `a`), the smoother damped by `omega`.
    pub(super) fn update(&mut self, a: &BlockSparseMatrix, omega: f64) {
        if self.built.is_none() {
            self.built = Some(self.build(a.pattern(), a));
        }
        let b = self.built.as_mut().expect("built above");
        let (inv_plain, inv_diag) = (&mut b.inv_plain, &mut b.inv_diag);
        inv_plain.par_iter_mut().zip(inv_diag.par_iter_mut()).enumerate().with_min_len(ROW_CHUNK).for_each(
            |(i, (plain, damped))| {
                *plain = inverse_diagonal_block(a, 1.0, i);
                *damped = *plain * omega;
            },
        );
        if let Some((partner, inv_off)) = &mut b.pairs {
            invert_pairs(a, omega, partner, &mut b.inv_diag, inv_off);
        }
        let pattern = a.pattern();
        let (width, inv_plain, of_slot) = (b.width, &b.inv_plain, &b.p_entry_of_slot);
        b.p_val.par_chunks_mut(width).enumerate().with_min_len(ROW_CHUNK).for_each(|(i, row)| {
            row.iter_mut().for_each(|p| *p = Mat3::zeros());
            row[0] = Mat3::identity();
            let scaled = inv_plain[i] * -OMEGA_P;
            for s in pattern.row_range(i) {
                row[of_slot[s] as usize] += scaled * a.values()[s];
            }
        });
        let (p_val, t_src) = (&b.p_val, &b.t_src);
        b.t_val.par_iter_mut().zip(t_src.par_iter()).with_min_len(ROW_CHUNK).for_each(|(t, &e)| {
            *t = p_val[e as usize];
        });
        if let Some(single) = &mut b.single {
            single.copy_from(a);
        }
        // A P, row by row, then P^T (A P): about 70 and 50 block products
        // a fine node (the triple product summed directly took 340).
        let single = &b.single;
        let block = |s: usize| single.as_ref().map_or(a.values()[s], |one| widen(&one.blocks[s]));
        let (p_val, p_len, ap_at, ap_width) = (&b.p_val, &b.p_len, &b.ap_at, b.ap_width);
        b.ap_val.par_chunks_mut(ap_width).enumerate().with_min_len(ROW_CHUNK).for_each(|(i, row)| {
            row.iter_mut().for_each(|v| *v = Mat3::zeros());
            for (s, &j) in pattern.row_range(i).zip(pattern.row_cols(i)) {
                let (a_s, j) = (block(s), j as usize);
                for k in 0..p_len[j] as usize {
                    row[ap_at[s * width + k] as usize] += a_s * p_val[j * width + k];
                }
            }
        });
        let (ap_val, ap_len, coarse_at, t_ptr, t_src) = (&b.ap_val, &b.ap_len, &b.coarse_at, &b.t_ptr, &b.t_src);
        let t_val = &b.t_val;
        let upper_from = &b.upper_from;
        b.coarse.fill_rows(|c, out| {
            out.iter_mut().for_each(|o| *o = Mat3::zeros());
            for m in t_ptr[c] as usize..t_ptr[c + 1] as usize {
                let e = t_src[m] as usize;
                let (i, p_t) = (e / width, t_val[m].transpose());
                for q in upper_from[m] as usize..ap_len[i] as usize {
                    out[coarse_at[m * ap_width + q] as usize] += p_t * ap_val[i * ap_width + q];
                }
            }
        });
        b.coarse.symmetric_from_upper();
        b.inner.set_omega(omega);
        b.inner.update(&b.coarse);
    }

    /// Strong couplings, `P`'s layout, `P^T`, the coarse pattern and the
    /// hierarchy below, from the first matrix.
    fn build(&self, pattern: &BlockPattern, a: &BlockSparseMatrix) -> Built {
        let n = pattern.n();
        let strong = |i: usize, s: usize, j: usize| {
            i != j && a.values()[s].norm() > THETA * (a.diag(i).norm() * a.diag(j).norm()).sqrt()
        };
        // Each row's aggregates: its own first, then its strong neighbours'.
        let rows: Vec<Vec<u32>> = (0..n)
            .map(|i| {
                let own = self.coarse_of[i];
                let mut others: Vec<u32> = pattern
                    .row_range(i)
                    .zip(pattern.row_cols(i))
                    .filter(|&(s, &j)| strong(i, s, j as usize))
                    .map(|(_, &j)| self.coarse_of[j as usize])
                    .filter(|&c| c != own)
                    .collect();
                others.sort_unstable();
                others.dedup();
                std::iter::once(own).chain(others).collect()
            })
            .collect();
        let width = rows.iter().map(Vec::len).max().unwrap_or(1);
        let mut p_col = vec![0u32; n * width];
        let mut p_len = vec![0u8; n];
        for (i, row) in rows.iter().enumerate() {
            p_col[i * width..i * width + row.len()].copy_from_slice(row);
            p_len[i] = u8::try_from(row.len()).expect("at most 255 aggregates meet a row");
        }
        let mut p_entry_of_slot = vec![0u8; pattern.nnz_blocks()];
        for (i, row) in rows.iter().enumerate() {
            for (s, &j) in pattern.row_range(i).zip(pattern.row_cols(i)) {
                let c = self.coarse_of[j as usize];
                if strong(i, s, j as usize) && c != row[0] {
                    p_entry_of_slot[s] = row.iter().position(|&d| d == c).expect("listed above") as u8;
                }
            }
        }
        // P^T: entries by aggregate, ascending.
        let mut t_ptr = vec![0u32; self.n_coarse + 1];
        for row in &rows {
            for &c in row {
                t_ptr[c as usize + 1] += 1;
            }
        }
        for c in 0..self.n_coarse {
            t_ptr[c + 1] += t_ptr[c];
        }
        let mut fill = t_ptr.clone();
        let mut t_src = vec![0u32; t_ptr[self.n_coarse] as usize];
        for (i, row) in rows.iter().enumerate() {
            for (k, &c) in row.iter().enumerate() {
                t_src[fill[c as usize] as usize] = (i * width + k) as u32;
                fill[c as usize] += 1;
            }
        }
        // A P's rows: the aggregates of P(j) for j in row i.
        let ap_rows: Vec<Vec<u32>> = (0..n)
            .map(|i| {
                let mut cols: Vec<u32> =
                    pattern.row_cols(i).iter().flat_map(|&j| rows[j as usize].iter().copied()).collect();
                cols.sort_unstable();
                cols.dedup();
                cols
            })
            .collect();
        let ap_width = ap_rows.iter().map(Vec::len).max().unwrap_or(1);
        let mut ap_len = vec![0u8; n];
        let mut ap_at = vec![0u8; pattern.nnz_blocks() * width];
        for (i, cols) in ap_rows.iter().enumerate() {
            ap_len[i] = u8::try_from(cols.len()).expect("at most 255 aggregates meet a row of A P");
            for (s, &j) in pattern.row_range(i).zip(pattern.row_cols(i)) {
                for (k, c) in rows[j as usize].iter().enumerate() {
                    ap_at[s * width + k] = cols.binary_search(c).expect("listed above") as u8;
                }
            }
        }
        // The coarse pattern: (c, d) for c in P(i), d in (A P)(i).
        let coarse_rows: Vec<Vec<u32>> = (0..self.n_coarse)
            .map(|c| {
                let entries = &t_src[t_ptr[c] as usize..t_ptr[c + 1] as usize];
                let mut cols: Vec<u32> =
                    entries.iter().flat_map(|&e| ap_rows[e as usize / width].iter().copied()).collect();
                cols.sort_unstable();
                cols.dedup();
                cols
            })
            .collect();
        let mut coarse_at = vec![0u8; t_src.len() * ap_width];
        let mut upper_from = vec![0u8; t_src.len()];
        for (c, cols) in coarse_rows.iter().enumerate() {
            for m in t_ptr[c] as usize..t_ptr[c + 1] as usize {
                let ap_row = &ap_rows[t_src[m] as usize / width];
                upper_from[m] = ap_row.partition_point(|&d| (d as usize) < c) as u8;
                for (q, d) in ap_row.iter().enumerate() {
                    let at = cols.binary_search(d).expect("listed above");
                    coarse_at[m * ap_width + q] = u8::try_from(at).expect("at most 255 blocks a coarse row");
                }
            }
        }
        let pairs = coarse_rows.iter().enumerate().flat_map(|(c, cols)| cols.iter().map(move |&d| (c, d as usize)));
        let coarse_pattern = BlockPattern::from_pairs(self.n_coarse, pairs).expect("aggregates are in range");
        let inner = Multigrid::with_single_precision_from(&coarse_pattern, &self.below, self.single_from)
            .expect("the caller checked the aggregations")
            .with_cycle(Cycle::K);
        let pairs = self.partner.as_ref().map(|p| (p.clone(), vec![Mat3::zeros(); n]));
        let nc = self.n_coarse;
        Built {
            width,
            p_val: vec![Mat3::zeros(); n * width],
            p_col,
            p_len,
            p_entry_of_slot,
            t_val: vec![Mat3::zeros(); t_src.len()],
            t_ptr,
            t_src,
            ap_width,
            ap_val: vec![Mat3::zeros(); n * ap_width],
            ap_len,
            ap_at,
            coarse_at,
            upper_from,
            coarse: BlockSparseMatrix::new(coarse_pattern),
            inner,
            single: (pattern.nnz_blocks() >= self.single_from).then(|| SinglePrecision::new(pattern)),
            inv_plain: vec![Mat3::identity(); n],
            inv_diag: vec![Mat3::identity(); n],
            pairs,
            x: vec![Vec3::zeros(); n],
            r: vec![Vec3::zeros(); n],
            b_c: vec![Vec3::zeros(); nc],
            c1: vec![Vec3::zeros(); nc],
            c2: vec![Vec3::zeros(); nc],
            v: vec![Vec3::zeros(); nc],
            r2: vec![Vec3::zeros(); nc],
            w: vec![Vec3::zeros(); nc],
            partials: vec![0.0; chunk_count(nc)],
        }
    }

    /// `z = B r`: pre-smooth from zero, restrict with `P^T`, two steps of
    /// flexible CG on `A_c` preconditioned by the plain hierarchy's cycle
    /// (the K-cycle's coarse solve, [`super::krylov_second_step`]),
    /// prolongate with `P`, post-smooth.
    pub(super) fn apply(&mut self, a: &BlockSparseMatrix, rhs: &[Vec3], z: &mut [Vec3]) {
        let b = self.built.as_mut().expect("Multigrid::update builds the smoothed level");
        jacobi_from_zero(&b.inv_diag, b.pairs.as_ref(), rhs, &mut b.x);
        residual(b.single.as_ref(), a, rhs, &b.x, &mut b.r);
        let (width, r) = (b.width, &b.r);
        let (t_ptr, t_src, t_val) = (&b.t_ptr, &b.t_src, &b.t_val);
        b.b_c.par_iter_mut().enumerate().with_min_len(ROW_CHUNK / 4).for_each(|(c, t)| {
            let entries = t_ptr[c] as usize..t_ptr[c + 1] as usize;
            *t = t_src[entries.clone()]
                .iter()
                .zip(&t_val[entries])
                .map(|(&e, p)| p.tr_mul(&r[e as usize / width]))
                .sum();
        });
        coarse_solve(b);
        let (p_col, p_val, p_len, e) = (&b.p_col, &b.p_val, &b.p_len, &b.c1);
        b.x.par_iter_mut().enumerate().with_min_len(ROW_CHUNK).for_each(|(i, xi)| {
            for k in i * width..i * width + p_len[i] as usize {
                *xi += p_val[k] * e[p_col[k] as usize];
            }
        });
        residual(b.single.as_ref(), a, rhs, &b.x, &mut b.r);
        let (x, r, inv_diag, pairs) = (&b.x, &b.r, &b.inv_diag, b.pairs.as_ref());
        z.par_iter_mut().enumerate().with_min_len(ROW_CHUNK).for_each(|(i, zi)| {
            *zi = x[i] + smoothed(inv_diag, pairs, r, i);
        });
    }
}

/// `b.c1 =` the coarse correction for `b.b_c`: two steps of flexible CG
/// on `A_c`, each preconditioned by one cycle of the plain hierarchy
/// (the formulas of [`super::krylov_second_step`]).
fn coarse_solve(b: &mut Built) {
    let (coarse, partials) = (&b.coarse, &mut b.partials);
    b.inner.apply(coarse, &b.b_c, &mut b.c1);
    let rho1 = mul_vec_dot(b.inner.finest_single(), coarse, &b.c1, &mut b.v, partials);
    let t1 = dot_with(&b.c1, &b.b_c, partials) / rho1;
    if !(rho1 > 0.0 && t1.is_finite()) {
        return;
    }
    let (b_c, v) = (&b.b_c, &b.v);
    b.r2.par_iter_mut().enumerate().with_min_len(ROW_CHUNK).for_each(|(i, ri)| *ri = b_c[i] - v[i] * t1);
    b.inner.apply(coarse, &b.r2, &mut b.c2);
    let c2_a_c2 = mul_vec_dot(b.inner.finest_single(), coarse, &b.c2, &mut b.w, partials);
    let gamma = dot_with(&b.c2, &b.v, partials);
    let alpha2 = dot_with(&b.c2, &b.r2, partials);
    let (w1, w2) = krylov_weights(rho1, t1, c2_a_c2, gamma, alpha2);
    let c2 = &b.c2;
    b.c1.par_iter_mut().enumerate().with_min_len(ROW_CHUNK).for_each(|(i, c)| *c = *c * w1 + c2[i] * w2);
}

#[cfg(test)]
mod tests {
    use super::*;

    /// 2 x 2 aggregates of a `side x side` grid (side even).
    fn quads(side: usize) -> Aggregation {
        let coarse_of = (0..side * side).map(|i| ((i % side) / 2 + (i / side) / 2 * (side / 2)) as u32).collect();
        Aggregation { coarse_of, n_coarse: side * side / 4 }
    }

    /// A cloth-like operator on a `side x side` grid: links to the eight
    /// nearest nodes and the interlaced ones two apart, each `k u u^T`
    /// with its own direction and stiffness, plus a mass on the diagonal.
    fn grid_operator(side: usize) -> BlockSparseMatrix {
        let node = |x: usize, y: usize| y * side + x;
        let mut links = Vec::new();
        for y in 0..side {
            for x in 0..side {
                for (dx, dy) in [(1, 0), (0, 1), (1, 1), (2, 0), (0, 2)] {
                    if x + dx < side && y + dy < side {
                        links.push((node(x, y), node(x + dx, y + dy)));
                    }
                    if dx == 1 && dy == 1 && x >= 1 && y + 1 < side {
                        links.push((node(x, y), node(x - 1, y + 1)));
                    }
                }
            }
        }
        let mut a = BlockSparseMatrix::new(BlockPattern::from_pairs(side * side, links.iter().copied()).unwrap());
        let pattern = a.pattern().clone();
        let values = a.values_mut();
        for i in 0..side * side {
            values[pattern.diag_slot(i)] = Mat3::identity() * 1e-3;
        }
        for (e, &(i, j)) in links.iter().enumerate() {
            let t = e as f64;
            let u = Vec3::new(1.0 + 0.3 * t.sin(), 0.2 * (2.0 * t).cos(), 0.1 * (3.0 * t).sin()).normalize();
            let k = u * u.transpose() * (50.0 + 30.0 * (0.7 * t).sin());
            for (r, c, sign) in [(i, i, 1.0), (j, j, 1.0), (i, j, -1.0), (j, i, -1.0)] {
                values[pattern.slot(r, c).unwrap()] += k * sign;
            }
        }
        a
    }

    /// The coarse operator is the Galerkin product `P^T A P` (summed here
    /// block by block over every fine pair, to roundoff), zero outside its
    /// pattern, and symmetric bit for bit (its lower triangle mirrored).
    #[test]
    fn coarse_operator_is_the_symmetric_galerkin_product() {
        let side = 12;
        let a = grid_operator(side);
        let mut first = SmoothedFirst::new(&[quads(side), quads(side / 2)], usize::MAX);
        first.update(&a, 0.7);
        let b = first.built.as_ref().unwrap();
        let nc = side * side / 4;
        let mut dense = vec![Mat3::zeros(); nc * nc];
        let p_row =
            |i: usize| (i * b.width..i * b.width + b.p_len[i] as usize).map(|k| (b.p_col[k] as usize, b.p_val[k]));
        for i in 0..side * side {
            for (s, &j) in a.pattern().row_range(i).zip(a.pattern().row_cols(i)) {
                for (c, p_ic) in p_row(i) {
                    for (d, p_jd) in p_row(j as usize) {
                        dense[c * nc + d] += p_ic.transpose() * a.values()[s] * p_jd;
                    }
                }
            }
        }
        let scale = dense.iter().map(|m| m.norm()).fold(0.0, f64::max);
        let coarse = &b.coarse;
        let mut worst: f64 = 0.0;
        for c in 0..nc {
            for d in 0..nc {
                let stored = coarse.pattern().slot(c, d).map_or(Mat3::zeros(), |s| coarse.values()[s]);
                worst = worst.max((stored - dense[c * nc + d]).norm());
                if let Some(s) = coarse.pattern().slot(c, d) {
                    let mirror = coarse.values()[coarse.pattern().mirror_slot(s)].transpose();
                    assert!(stored.iter().zip(mirror.iter()).all(|(x, y)| x.to_bits() == y.to_bits()), "({c}, {d})");
                }
            }
        }
        // Measured 7.7e-16 of the largest block (summation order).
        assert!(worst <= 2e-15 * scale, "worst block difference {worst:e} against {scale:e}");
    }
}
