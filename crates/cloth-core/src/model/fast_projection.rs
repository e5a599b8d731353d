//! Fast projection (Goldenthal, Harmon, Fattal, Bercovier & Grinspun
//! 2007, "Efficient simulation of inextensible cloth", §4) of the links
//! that Provot's deformation constraints bound: every link over its limit
//! and every open closed stitch, corrected together.
//!
//! A Gauss-Seidel pass moves one link at a time, so a correction travels
//! one link per pass: a chain of `n` over-long links needs of the order of
//! `n^2` passes, and a finer garment runs out of them. A projection solves
//! for all the violated constraints at once. With the constraints `C(x)`
//! (`C_l = |x_j - x_i| - (1 + tau_c) L_l` for a link, `|x_j - x_i|` for a
//! closed stitch), their gradients `J` and the ends' weights `W` (1 for a
//! free particle, 0 for a pinned or held one: Provot's equal shares),
//!
//! `(J W J^T + a D) lambda = C`,   `x <- x - W J^T lambda`,
//!
//! the nearest point (in the `W^-1` norm) where the linearised constraints
//! hold. `D` is the diagonal of `J W J^T` and `a` a small compliance that
//! keeps the system definite where more links than freedoms are active (a
//! grid's shear links). A constraint once violated stays in the set for
//! the call, held at its limit: otherwise a link set exactly to its limit
//! leaves the set, and the next projection stretches it again. It leaves
//! the set when the solve would push its ends apart (`lambda < 0`): the
//! bound is one-sided, and holding such links stalled a stretched strip
//! at 1.12 of its rest length against a limit of 1.1. An update
//! that does not lower the summed squared violation is halved (the
//! linearised constraints can be inconsistent), and given up after
//! [`MAX_HALVINGS`].
//!
//! Solids near the particles ([`SolidBound`]: the tangent plane at a
//! solid's closest point, moved out by the contact thickness) are rows of
//! the same system, `C = offset - n . x <= 0` with one particle each,
//! held from the start where a particle sits on its bound and released
//! like a link when they would pull it in. Projected apart from them,
//! links shortened along their chords through a solid's curve, and the
//! projection out of the solids that followed stretched them again (the
//! T-shirt's armpit, `docs/garments.md`). The system is small (the
//! violated links and their neighbours, a few hundred rows) and changes
//! with every projection: it is assembled and factored directly
//! ([`EnvelopeCholesky`]), and solved by Jacobi-preconditioned conjugate
//! gradients without assembly where its envelope is too wide for that to
//! pay. Every loop is serial in a fixed order, so the result is the same
//! on any thread count.

use super::links::StretchLink;
use crate::seams::Stitch;
use crate::{ClothModel, Vec3};
use cloth_linalg::Buckets;
use cloth_linalg::EnvelopeCholesky;

/// The compliance `a`, relative to the diagonal of `J W J^T`.
const COMPLIANCE: f64 = 1e-6;
/// Relative residual at which the conjugate gradients stop.
const CG_TOLERANCE: f64 = 1e-3;
/// Most conjugate-gradient iterations per projection.
const CG_MAX: usize = 200;
/// The direct factor's largest work ([`EnvelopeCholesky::analyse`]) per
/// row of the system; wider envelopes are solved by conjugate gradients.
/// On the garments a gradient solve takes some 70 iterations of about
/// 9 ns a row, near what a factor of this work per row costs, while
/// their envelopes hold 2 to 16 entries a row, a work of at most some
/// 250 (docs/results/stages.md): denser systems (every link of a sheet
/// violated at once) and envelopes that fill stay iterative.
const DIRECT_WORK_PER_ROW: usize = 1000;
/// A particle this close to a solid's bound, m, is held by it from the
/// start: one that the projection out of the solids left at the
/// thickness is on its bound, and the linearised links alone would move
/// it in.
const SOLID_SLACK_M: f64 = 1e-6;
/// Most halvings of a projection's update before it is given up.
const MAX_HALVINGS: usize = 4;

/// Which constraints a projection bounds, and how tightly.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Bounds<'a> {
    /// Largest length over rest length of a stretch link, `1 + tau_c`.
    pub stretch: f64,
    /// A link within this relative excess over its limit is left alone
    /// (rounding, not stretch).
    pub slack: f64,
    /// A closed stitch this short is left alone, m.
    pub stitch_slack_m: f64,
    /// The stitches' states (see [`crate::ClothState::stitches_closed`]).
    pub stitches_closed: &'a [bool],
    /// The solids near particles, as half-spaces they are kept in.
    pub solids: &'a [SolidBound],
}

/// A solid near a particle, as a projection keeps the particle out of
/// it: on the side `normal . x >= offset_m` of the solid's tangent plane
/// at its closest point, moved out by the contact thickness.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct SolidBound {
    /// The particle.
    pub particle: u32,
    /// The solid's outward unit normal at its closest point.
    pub normal: Vec3,
    /// `normal . x` at the thickness from that point, m.
    pub offset_m: f64,
}

impl Bounds<'_> {
    /// The summed squared violation at `x`: `max(0, |x_j - x_i| - stretch
    /// L)^2` over the stretch links and `|x_j - x_i|^2` over the closed
    /// stitches open by more than the slack, m^2.
    #[cfg(test)]
    pub(crate) fn violation(&self, model: &ClothModel, x: &[Vec3]) -> f64 {
        let links: f64 = model.stretch_links().iter().map(|l| self.link_term(l, x)).sum();
        let closed = model.stitches().iter().zip(self.stitches_closed).filter(|(_, closed)| **closed);
        let stitches: f64 = closed.map(|(st, _)| self.stitch_term(st, x)).sum();
        let solids: f64 = self.solids.iter().map(|b| b.term(x)).sum();
        links + stitches + solids
    }

    /// A stretch link's term of [`Bounds::violation`], m^2.
    fn link_term(&self, l: &StretchLink, x: &[Vec3]) -> f64 {
        ((x[l.j as usize] - x[l.i as usize]).norm() - self.stretch * l.rest).max(0.0).powi(2)
    }

    /// A closed stitch's term of [`Bounds::violation`], m^2.
    fn stitch_term(&self, st: &Stitch, x: &[Vec3]) -> f64 {
        let d = (x[st.j as usize] - x[st.i as usize]).norm();
        if d > self.stitch_slack_m { d * d } else { 0.0 }
    }

    /// [`Bounds::violation`] over the constraints that touch the particles
    /// `local` marks (`local[i] != u32::MAX`, listed in `particles`): the
    /// only terms a move of those particles changes, so two positions
    /// that differ only there compare as the whole sum does, without a
    /// pass over every link.
    fn violation_near(&self, model: &ClothModel, x: &[Vec3], (particles, local): (&[u32], &[u32])) -> f64 {
        let stretch_links = model.stretch_links();
        let mut links = 0.0;
        for &p in particles {
            for inc in model.incidence(p as usize) {
                let Some(l) = stretch_links.get(inc.link as usize) else { continue };
                // Each link once: from its smaller end when both are here.
                if local[inc.other as usize] != u32::MAX && inc.other < p {
                    continue;
                }
                links += self.link_term(l, x);
            }
        }
        let here = |i: u32| local[i as usize] != u32::MAX;
        let closed = model.stitches().iter().zip(self.stitches_closed).filter(|(_, closed)| **closed);
        let stitches: f64 =
            closed.filter(|(st, _)| here(st.i) || here(st.j)).map(|(st, _)| self.stitch_term(st, x)).sum();
        let solids: f64 = self.solids.iter().filter(|b| here(b.particle)).map(|b| b.term(x)).sum();
        links + stitches + solids
    }
}

impl SolidBound {
    /// Its term of [`Bounds::violation`], m^2.
    fn term(&self, x: &[Vec3]) -> f64 {
        self.depth(x).max(0.0).powi(2)
    }

    /// How far particle `particle` at positions `x` is inside the bound,
    /// m (negative: outside).
    fn depth(&self, x: &[Vec3]) -> f64 {
        self.offset_m - self.normal.dot(&x[self.particle as usize])
    }
}

/// One constraint of a projection.
#[derive(Debug, Clone, Copy)]
struct Row {
    /// Ends, as local (compacted) particle indices; a solid's bound has
    /// one particle, at both ends, weighted at the second only.
    ends: [u32; 2],
    /// Ends' weights.
    w: [f64; 2],
    /// Unit direction from the first end to the second.
    n: Vec3,
    /// Violation, m (negative: within its limit, held there).
    c: f64,
    /// Stretch link index, or the link count plus the stitch index.
    constraint: u32,
}

/// Reused buffers of [`fast_projection`].
#[derive(Debug, Default, Clone)]
pub(crate) struct ProjectionScratch {
    rows: Vec<Row>,
    /// Global index of each local particle.
    particles: Vec<u32>,
    /// Local index of each global particle (`u32::MAX`: none).
    local: Vec<u32>,
    /// Per local particle: `J^T` times a vector over the rows.
    g: Vec<Vec3>,
    /// Positions of the local particles before an update.
    start: Vec<Vec3>,
    lambda: Vec<f64>,
    r: Vec<f64>,
    z: Vec<f64>,
    p: Vec<f64>,
    q: Vec<f64>,
    diag: Vec<f64>,
    /// The direct solve: the factor, each local particle's rows (where it
    /// is free) with the sign of their gradient there, and the system's off-diagonal pairs with their values.
    factor: EnvelopeCholesky,
    rows_at: Buckets<(u32, f64)>,
    pairs: Vec<(u32, u32)>,
    couplings: Vec<f64>,
    /// Per stretch link, then per stitch: in the set since an earlier
    /// projection of this call.
    sticky: Vec<bool>,
    /// Per stretch link: one end moved since the last gather, so its
    /// length may have come over the limit.
    touched: Vec<bool>,
    /// Whether the next gather looks at every link (the call's first).
    gather_all: bool,
}

impl ProjectionScratch {
    fn local_index(&mut self, i: usize) -> u32 {
        if self.local[i] == u32::MAX {
            self.local[i] = self.particles.len() as u32;
            self.particles.push(i as u32);
        }
        self.local[i]
    }

    /// `g = J^T values`, per local particle.
    fn gradient_times(rows: &[Row], values: &[f64], g: &mut [Vec3]) {
        g.iter_mut().for_each(|g| *g = Vec3::zeros());
        for (row, &value) in rows.iter().zip(values) {
            g[row.ends[0] as usize] -= row.n * (value * row.w[0]);
            g[row.ends[1] as usize] += row.n * (value * row.w[1]);
        }
    }

    /// `y = (J W J^T + a D) values`.
    fn apply(rows: &[Row], diag: &[f64], values: &[f64], g: &mut [Vec3], y: &mut [f64]) {
        Self::gradient_times(rows, values, g);
        for (k, row) in rows.iter().enumerate() {
            let (a, b) = (row.ends[0] as usize, row.ends[1] as usize);
            let moved = if a == b { g[b] } else { g[b] - g[a] };
            y[k] = row.n.dot(&moved) + COMPLIANCE * diag[k] * values[k];
        }
    }

    /// Drops from the set the held rows within their limit whose solved
    /// `lambda` would push their ends apart; whether there were any.
    fn release_pushing(&mut self) -> bool {
        let mut any = false;
        for (row, &l) in self.rows.iter().zip(&self.lambda) {
            if row.c <= 0.0 && l < 0.0 {
                self.sticky[row.constraint as usize] = false;
                any = true;
            }
        }
        any
    }

    /// The rows at `x`: every constraint violated now or earlier in the call.
    fn gather(&mut self, model: &ClothModel, bounds: &Bounds<'_>, free: &impl Fn(usize) -> bool, x: &[Vec3]) {
        self.rows.clear();
        for &i in &self.particles {
            self.local[i as usize] = u32::MAX;
        }
        self.particles.clear();
        let links = model.stretch_links();
        let add = |s: &mut Self, k: usize, (i, j): (usize, usize), max_len: f64, tol: f64| {
            // Most links are within their limit: compared squared first.
            let d2 = (x[j] - x[i]).norm_squared();
            if d2 == 0.0 || (d2 <= tol * tol && !s.sticky[k]) {
                return;
            }
            let w = [f64::from(u8::from(free(i))), f64::from(u8::from(free(j)))];
            let d = d2.sqrt();
            if w == [0.0, 0.0] || (d <= tol && !s.sticky[k]) {
                return;
            }
            s.sticky[k] = true;
            let ends = [s.local_index(i), s.local_index(j)];
            s.rows.push(Row { ends, w, n: (x[j] - x[i]) / d, c: d - max_len, constraint: k as u32 });
        };
        let closed = model.stitches().iter().zip(bounds.stitches_closed).enumerate().filter(|(_, (_, c))| **c);
        for (k, (st, _)) in closed {
            add(self, links.len() + k, (st.i as usize, st.j as usize), 0.0, bounds.stitch_slack_m);
        }
        // A link none of whose ends moved since the last gather is where
        // it was then: over its limit and in the set (sticky), or within it.
        let all = std::mem::replace(&mut self.gather_all, false);
        for (k, l) in links.iter().enumerate() {
            if !all && !self.touched[k] && !self.sticky[k] {
                continue;
            }
            let max_len = bounds.stretch * l.rest;
            add(self, k, (l.i as usize, l.j as usize), max_len, max_len * (1.0 + bounds.slack));
        }
        self.touched.clear();
        self.touched.resize(links.len(), false);
        // A solid's bound `C = offset - n . x <= 0`, gradient `-n`: a
        // positive multiplier moves the particle out along `n`. Only the
        // particles that the rows above move need it (the others stay
        // where they are), unless it is in the set already.
        let first = links.len() + model.stitches().len();
        for (k, b) in bounds.solids.iter().enumerate() {
            let (i, c, sticky) = (b.particle as usize, b.depth(x), self.sticky[first + k]);
            let moved = self.local[i] != u32::MAX;
            if !free(i) || !(sticky || (moved && c > -SOLID_SLACK_M)) {
                continue;
            }
            self.sticky[first + k] = true;
            let e = self.local_index(i);
            self.rows.push(Row { ends: [e, e], w: [0.0, 1.0], n: -b.normal, c, constraint: (first + k) as u32 });
        }
    }
}

/// What [`fast_projection`] did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub(crate) struct ProjectionReport {
    /// Projections applied.
    pub iterations: usize,
    /// Linear solves made by the direct factor.
    pub direct_solves: usize,
    /// Conjugate-gradient iterations of the other solves.
    pub cg_iterations: usize,
}

/// Up to `iterations` fast projections of the constraints `bounds` names
/// on positions `x`; velocities `v` change by each move over `h` (s), as
/// after Provot's passes. `free(i)` says whether particle `i` may move.
/// Stops when nothing is violated or an update cannot lower the violation.
pub(crate) fn fast_projection(
    model: &ClothModel,
    bounds: &Bounds<'_>,
    free: impl Fn(usize) -> bool,
    (x, v): (&mut [Vec3], &mut [Vec3]),
    h: f64,
    iterations: usize,
    s: &mut ProjectionScratch,
) -> ProjectionReport {
    let mut report = ProjectionReport::default();
    s.local.resize(x.len(), u32::MAX);
    s.sticky.clear();
    s.sticky.resize(model.stretch_links().len() + model.stitches().len() + bounds.solids.len(), false);
    s.gather_all = true;
    for _ in 0..iterations {
        s.gather(model, bounds, &free, x);
        if !s.rows.iter().any(|r| r.c > 0.0) {
            break;
        }
        solve(s, &mut report);
        // A held constraint within its limit that the solve would push
        // apart (`lambda < 0`) leaves the set: the bound is one-sided.
        if s.release_pushing() {
            s.gather(model, bounds, &free, x);
            solve(s, &mut report);
        }
        let ProjectionScratch { rows, g, lambda, particles, start, local, .. } = &mut *s;
        ProjectionScratch::gradient_times(rows, lambda, g);
        start.clear();
        start.extend(particles.iter().map(|&i| x[i as usize]));
        let near = (particles.as_slice(), local.as_slice());
        let mut before = bounds.violation_near(model, x, near);
        let mut alpha = 1.0;
        let accepted = (0..=MAX_HALVINGS).find_map(|_| {
            for (k, &i) in particles.iter().enumerate() {
                x[i as usize] = start[k] - g[k] * alpha;
            }
            let after = bounds.violation_near(model, x, near);
            let lower = after < before;
            (before, alpha) = if lower { (after, alpha) } else { (before, alpha * 0.5) };
            lower.then_some(alpha)
        });
        let Some(alpha) = accepted else {
            for (k, &i) in particles.iter().enumerate() {
                x[i as usize] = start[k];
            }
            break;
        };
        report.iterations += 1;
        for (k, &i) in particles.iter().enumerate() {
            v[i as usize] -= g[k] * (alpha / h);
        }
        let stretch_links = model.stretch_links().len();
        for &i in &s.particles {
            for inc in model.incidence(i as usize).iter().filter(|inc| (inc.link as usize) < stretch_links) {
                s.touched[inc.link as usize] = true;
            }
        }
    }
    report
}

/// Solves `(J W J^T + a D) lambda = c` into `s.lambda`: directly where
/// the factor's envelope is narrow, otherwise by conjugate gradients.
fn solve(s: &mut ProjectionScratch, report: &mut ProjectionReport) {
    s.g.clear();
    s.g.resize(s.particles.len(), Vec3::zeros());
    if solve_direct(s, DIRECT_WORK_PER_ROW) {
        report.direct_solves += 1;
    } else {
        report.cg_iterations += solve_iteratively(s);
    }
}

/// Assembles `J W J^T + a D` and solves it by [`EnvelopeCholesky`];
/// false (nothing solved) when the factor's work exceeds
/// `max_work_per_row` times the rows or the factor fails.
fn solve_direct(s: &mut ProjectionScratch, max_work_per_row: usize) -> bool {
    let n = s.rows.len();
    // `(J W J^T)_kl` sums, over the particles rows `k` and `l` share,
    // the particle's weight times their gradients' product there: the
    // weights are 1 or 0, so a row is listed at its free ends only.
    let np = s.particles.len();
    let ends = |row: &Row| {
        let [a, b] = row.ends;
        let first = (a != b && row.w[0] != 0.0).then_some((a, -1.0));
        first.into_iter().chain((row.w[1] != 0.0).then_some((b, 1.0)))
    };
    let rows = &s.rows;
    s.rows_at.rebuild(np, || {
        rows.iter().enumerate().flat_map(|(k, row)| ends(row).map(move |(p, sign)| (p as usize, (k as u32, sign))))
    });
    s.pairs.clear();
    s.couplings.clear();
    for p in 0..np {
        let here = s.rows_at.of(p);
        for (x, &(k, sk)) in here.iter().enumerate() {
            for &(l, sl) in &here[x + 1..] {
                s.pairs.push((k, l));
                s.couplings.push(sk * sl * s.rows[k as usize].n.dot(&s.rows[l as usize].n));
            }
        }
    }
    match s.factor.analyse(n, &s.pairs) {
        Ok(work) if work <= max_work_per_row.saturating_mul(n) => {}
        _ => return false,
    }
    s.diag.clear();
    s.diag.extend(s.rows.iter().map(|row| (row.w[0] + row.w[1]) * (1.0 + COMPLIANCE)));
    if s.factor.factor(&s.diag, &s.couplings).is_err() {
        return false;
    }
    s.lambda.clear();
    s.lambda.extend(s.rows.iter().map(|row| row.c));
    s.factor.solve(&mut s.lambda);
    true
}

/// Solves `(J W J^T + a D) lambda = c` into `s.lambda` by Jacobi-
/// preconditioned conjugate gradients from zero; returns the iterations.
fn solve_iteratively(s: &mut ProjectionScratch) -> usize {
    let n = s.rows.len();
    let ProjectionScratch { rows, g, lambda, r, z, p, q, diag, .. } = s;
    for buf in [&mut *lambda, &mut *r, &mut *z, &mut *p, &mut *q, &mut *diag] {
        buf.clear();
        buf.resize(n, 0.0);
    }
    for (k, row) in rows.iter().enumerate() {
        diag[k] = row.w[0] + row.w[1];
        r[k] = row.c;
    }
    let precondition = |r: &[f64], z: &mut [f64]| {
        for ((z, r), d) in z.iter_mut().zip(r).zip(diag.iter()) {
            *z = r / (d * (1.0 + COMPLIANCE));
        }
    };
    let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(a, b)| a * b).sum::<f64>();
    let stop = CG_TOLERANCE * dot(r, r).sqrt();
    precondition(r, z);
    p.copy_from_slice(z);
    let mut rz = dot(r, z);
    for it in 1..=CG_MAX {
        ProjectionScratch::apply(rows, diag, p, g, q);
        let pq = dot(p, q);
        if pq <= 0.0 || !pq.is_finite() {
            return it;
        }
        let alpha = rz / pq;
        for k in 0..n {
            lambda[k] += alpha * p[k];
            r[k] -= alpha * q[k];
        }
        if dot(r, r).sqrt() <= stop {
            return it;
        }
        precondition(r, z);
        let rz_new = dot(r, z);
        let beta = rz_new / rz;
        rz = rz_new;
        for k in 0..n {
            p[k] = z[k] + beta * p[k];
        }
    }
    CG_MAX
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::constraints::apply_strain_limit_with;
    use crate::{GridPanel, ModelSpec, StrainLimit};

    fn sheet(particles: [usize; 2], size_m: [f64; 2]) -> ClothModel {
        ClothModel::build(&ModelSpec {
            panels: vec![GridPanel {
                particles,
                size_m,
                origin_m: [0.0, 0.0, 0.0],
                u_axis: [1.0, 0.0, 0.0],
                v_axis: [0.0, 1.0, 0.0],
                wrap_u: false,
            }],
            ..ModelSpec::default()
        })
        .unwrap()
    }

    fn bounds(stretch: f64) -> Bounds<'static> {
        Bounds { stretch, slack: 1e-12, stitch_slack_m: 1e-12, stitches_closed: &[], solids: &[] }
    }

    /// A strip of 41 x 2 particles held at one end and stretched to 1.4
    /// times its length: after ten of Provot's passes its worst link is at
    /// 1.44 (a correction travels a link a pass, pushing the excess onto
    /// the next), ten projections bring every link
    /// to within 3e-6 of its limit (1.1). The held end stays, and the
    /// velocities change by the moves over the step.
    #[test]
    fn projections_bring_a_stretched_strip_to_its_limit_where_passes_run_out() {
        let model = sheet([41, 2], [0.4, 0.01]);
        let held = |i: usize| i.is_multiple_of(41);
        let stretched: Vec<Vec3> = model.rest_positions().iter().map(|p| Vec3::new(p.x * 1.4, p.y, p.z)).collect();
        let h = 0.01;
        let v0 = vec![Vec3::zeros(); stretched.len()];
        let limit = StrainLimit { max_strain: 0.1, passes: 10, projections: 10 };

        let (mut xp, mut vp) = (stretched.clone(), v0.clone());
        apply_strain_limit_with(&model, &limit, held, &[], (&mut xp, &mut vp), h, &mut Vec::new());
        let passes = model.max_stretch_ratio(&xp);
        assert!(passes > 1.44, "after 10 passes: {passes}");

        let (mut x, mut v) = (stretched.clone(), v0.clone());
        let free = |i: usize| !held(i);
        let report = fast_projection(&model, &bounds(1.1), free, (&mut x, &mut v), h, 10, &mut Default::default());
        let projected = model.max_stretch_ratio(&x);
        assert!(projected < 1.1 * (1.0 + 4e-6), "after {report:?}: {projected}");
        assert!(report.iterations >= 2, "{report:?}");
        assert!(report.direct_solves > 0 && report.cg_iterations == 0, "{report:?}");
        for i in 0..x.len() {
            if held(i) {
                assert_eq!(x[i], stretched[i]);
            }
            assert!((v[i] - (x[i] - stretched[i]) / h).norm() < 1e-9, "particle {i}");
        }
    }

    /// The projection system at `x`, gathered, with the solids' bounds
    /// `offset_m` above every third particle.
    fn gathered(model: &ClothModel, x: &[Vec3], free: impl Fn(usize) -> bool, offset_m: f64) -> ProjectionScratch {
        let solids: Vec<SolidBound> = (0..x.len())
            .step_by(3)
            .map(|i| SolidBound { particle: i as u32, normal: Vec3::z(), offset_m: x[i].z + offset_m })
            .collect();
        let b = Bounds { solids: &solids, ..bounds(1.1) };
        let mut s = ProjectionScratch::default();
        s.local.resize(x.len(), u32::MAX);
        s.sticky.resize(model.stretch_links().len() + model.stitches().len() + solids.len(), false);
        s.gather_all = true;
        s.gather(model, &b, &free, x);
        s.g.resize(s.particles.len(), Vec3::zeros());
        s
    }

    /// The moves `W J^T lambda` of the last solve, per local particle.
    fn moves(s: &mut ProjectionScratch) -> Vec<Vec3> {
        ProjectionScratch::gradient_times(&s.rows, &s.lambda, &mut s.g);
        s.g.clone()
    }

    /// The system the direct factor assembles is the matrix-free operator
    /// the conjugate gradients apply: its solution satisfies that operator
    /// to rounding (4.2e-11 relative; the compliance leaves it near
    /// singular) on a stretched, jittered sheet, every link in the set,
    /// with a held edge (links with one end held) and solid bounds on
    /// every third particle (one-particle rows).
    #[test]
    fn the_direct_solve_satisfies_the_matrix_free_system() {
        let model = sheet([12, 9], [0.22, 0.16]);
        let mut noise = noise(11);
        let x: Vec<Vec3> =
            model.rest_positions().iter().map(|p| p * 1.25 + Vec3::new(noise(), noise(), noise()) * 0.003).collect();
        let mut s = gathered(&model, &x, |i| !i.is_multiple_of(12), 0.0005);
        let n = s.rows.len();
        assert!(n > 300 && s.rows.iter().any(|r| r.ends[0] == r.ends[1]), "{n} rows");
        // Every link at once is denser than the garments' systems: its
        // factor costs more than the gradients, which the step then runs.
        assert!(!solve_direct(&mut s, DIRECT_WORK_PER_ROW));
        assert!(solve_direct(&mut s, usize::MAX));
        let mut y = vec![0.0; n];
        let diag: Vec<f64> = s.rows.iter().map(|r| r.w[0] + r.w[1]).collect();
        ProjectionScratch::apply(&s.rows, &diag, &s.lambda, &mut s.g, &mut y);
        let norm = |v: &mut dyn Iterator<Item = f64>| v.map(|a| a * a).sum::<f64>().sqrt();
        let residual = norm(&mut y.iter().zip(&s.rows).map(|(y, r)| y - r.c));
        let rel = residual / norm(&mut s.rows.iter().map(|r| r.c));
        assert!(rel < 1e-10, "relative residual {rel:e}");
    }

    /// Where the linearised constraints can all hold (a sheet with some
    /// particles pulled 6 mm out of place, fewer violated links than
    /// freedoms round them), the direct solve's moves are those of
    /// conjugate gradients run to their tolerance: 2.6e-4 apart, relative.
    #[test]
    fn the_direct_and_iterative_solves_move_the_particles_alike() {
        let model = sheet([15, 11], [0.28, 0.2]);
        let mut noise = noise(3);
        let mut x = model.rest_positions().to_vec();
        for i in (20..x.len()).step_by(37) {
            x[i] += Vec3::new(noise(), noise(), noise()).normalize() * 0.006;
        }
        let mut s = gathered(&model, &x, |i| !i.is_multiple_of(15), 0.0002);
        assert!(s.rows.iter().any(|r| r.ends[0] == r.ends[1]));
        assert!(solve_direct(&mut s, usize::MAX));
        let direct = moves(&mut s);
        let iterations = solve_iteratively(&mut s);
        assert!(iterations < CG_MAX, "the gradients did not converge");
        let iterative = moves(&mut s);
        let size: f64 = direct.iter().map(|g| g.norm_squared()).sum::<f64>().sqrt();
        let apart: f64 = direct.iter().zip(&iterative).map(|(a, b)| (a - b).norm_squared()).sum::<f64>().sqrt();
        assert!(apart / size < 5e-4, "{iterations} iterations: {:e} apart", apart / size);
    }

    /// Deterministic numbers in [-1, 1) from `seed` (a linear congruential
    /// generator).
    fn noise(mut seed: u64) -> impl FnMut() -> f64 {
        move || {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 52) as f64 - 1.0
        }
    }

    /// A move of some particles changes the summed violation by what the
    /// terms that touch them change (`violation_near`), to rounding: the
    /// projection's line search compares those alone. With solid bounds on
    /// the moved particles and on others.
    #[test]
    fn the_violation_near_moved_particles_changes_as_the_whole_does() {
        let model = sheet([9, 7], [0.16, 0.12]);
        let mut noise = noise(5);
        let before: Vec<Vec3> =
            model.rest_positions().iter().map(|p| p * 1.2 + Vec3::new(noise(), noise(), noise()) * 0.004).collect();
        let solids: Vec<SolidBound> = (0..before.len())
            .step_by(3)
            .map(|i| SolidBound { particle: i as u32, normal: Vec3::z(), offset_m: before[i].z + 0.001 })
            .collect();
        let b = Bounds { solids: &solids, ..bounds(1.1) };
        let moved: Vec<u32> = (0..before.len() as u32).filter(|i| i % 4 == 1 || *i == 30).collect();
        let mut local = vec![u32::MAX; before.len()];
        for (k, &i) in moved.iter().enumerate() {
            local[i as usize] = k as u32;
        }
        let mut after = before.clone();
        for &i in &moved {
            after[i as usize] += Vec3::new(noise(), noise(), noise()) * 0.01;
        }
        let whole = b.violation(&model, &after) - b.violation(&model, &before);
        let near =
            b.violation_near(&model, &after, (&moved, &local)) - b.violation_near(&model, &before, (&moved, &local));
        assert!(whole.abs() > 1e-6, "the move changed nothing: {whole}");
        assert!((whole - near).abs() < 1e-12 * b.violation(&model, &after), "{whole} against {near}");
    }

    /// Where more links than freedoms are over their limit (a grid's shear
    /// links, shaken), the linearised constraints are inconsistent: each
    /// projection still lowers the summed squared violation, never raises
    /// it, and the sheet ends within a thousandth of where it started.
    #[test]
    fn a_projection_never_raises_the_violation() {
        let model = sheet([11, 9], [0.2, 0.16]);
        let mut noise = noise(11);
        let mut x: Vec<Vec3> =
            model.rest_positions().iter().map(|p| p * 1.3 + Vec3::new(noise(), noise(), noise()) * 0.01).collect();
        let mut v = vec![Vec3::zeros(); x.len()];
        let b = bounds(1.1);
        let first = b.violation(&model, &x);
        let mut last = first;
        let mut scratch = ProjectionScratch::default();
        for _ in 0..20 {
            fast_projection(&model, &b, |i| i != 0, (&mut x, &mut v), 0.01, 1, &mut scratch);
            let now = b.violation(&model, &x);
            assert!(now <= last, "{now} after {last}");
            last = now;
        }
        assert!(x.iter().all(|p| p.iter().all(|c| c.is_finite())));
        assert!(last < 1e-3 * first, "{last} of {first}");
    }

    /// A strip held at one end and stretched to 1.4 times its length
    /// round a cylinder (radius 0.5 m, its axis along the strip's width),
    /// each particle on the cylinder's surface grown by a 5 mm thickness
    /// and bound there by the tangent plane. Without the bounds the
    /// projections shorten the links along their chords, 13 mm into the
    /// cylinder; with them the strip slides round it: every link ends
    /// within 4e-7 of its limit and no particle is inside the bound.
    #[test]
    fn projections_keep_particles_out_of_the_solids_that_bound_them() {
        let model = sheet([41, 2], [0.4, 0.01]);
        let held = |i: usize| i.is_multiple_of(41);
        let free = |i: usize| !held(i);
        let (radius, thickness) = (0.5, 0.005);
        let angle = |p: &Vec3| 1.4 * p.x / radius;
        let normal = |p: &Vec3| Vec3::new(angle(p).sin(), 0.0, angle(p).cos());
        let wrapped: Vec<Vec3> =
            model.rest_positions().iter().map(|p| normal(p) * (radius + thickness) + Vec3::y() * p.y).collect();
        let solids: Vec<SolidBound> = (0..wrapped.len())
            .map(|i| {
                let n = normal(&model.rest_positions()[i]);
                SolidBound { particle: i as u32, normal: n, offset_m: n.dot(&wrapped[i]) }
            })
            .collect();
        // Distance from the axis, less the grown radius (negative: inside).
        let clearance = |x: &[Vec3]| x.iter().map(|p| p.xz().norm() - radius - thickness).fold(f64::INFINITY, f64::min);
        let h = 0.01;
        let project = |solids: &[SolidBound]| {
            let (mut x, mut v) = (wrapped.clone(), vec![Vec3::zeros(); wrapped.len()]);
            let b = Bounds { solids, ..bounds(1.1) };
            fast_projection(&model, &b, free, (&mut x, &mut v), h, 10, &mut Default::default());
            x
        };

        let chords = project(&[]);
        assert!(clearance(&chords) < -0.01, "without bounds: {}", clearance(&chords));

        let bound = project(&solids);
        let stretch = model.max_stretch_ratio(&bound);
        assert!(stretch < 1.1 * (1.0 + 1e-6), "with bounds: {stretch}");
        assert!(clearance(&bound) > -1e-9, "with bounds: {}", clearance(&bound));
        assert!((0..bound.len()).filter(|&i| held(i)).all(|i| bound[i] == wrapped[i]));
    }
}
