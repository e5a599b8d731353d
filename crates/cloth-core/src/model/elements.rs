//! Multi-particle elements (Volino's membrane and bending triangles,
//! Choi & Ko's type-2 bending triples) and the drivers that fold them into forces and the system matrix.
//!
//! Each element adds `f_a` to its corners and `H_ab` (a PSD approximation of
//! `d^2 E / dx_a dx_b`, so `K_ab = -H_ab`) to the blocks between them:
//! `A_ab += c_x H_ab`, `b_a += c_f f_a - a_k (H w)_a`. Elements are
//! evaluated in parallel into per-element buffers; each particle then adds
//! its elements in a fixed order, as for links.

use crate::element_laws::{
    ElementForces, TriangleRest, bend_hinge_energy, bend_hinge_into, bend_triple_energy, bend_triple_forces,
    bend_triple_into, curvature_bending_into, membrane_triangle_into,
};
use crate::{Mat3, Vec3};
use cloth_linalg::{BlockPattern, ROW_CHUNK};
use rayon::prelude::*;

/// A membrane triangle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MembraneElement {
    /// Corners.
    pub nodes: [u32; 3],
    /// Rest shape and stiffness.
    pub rest: TriangleRest,
}

/// A bending triangle ([`crate::element_laws::curvature_bending_with`]): corners 0, 1, 2, then
/// the corners across edges 0, 1, 2 (a free edge repeats the opposite
/// corner of the triangle; its row of `stiffness` is zero).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CurvatureElement {
    /// Corners.
    pub nodes: [u32; 6],
    /// Rest dihedral angles at the three edges, rad.
    pub rest_angles: [f64; 3],
    /// `M` of `E = d^T M d / 2`, N m ([`crate::element_laws::curvature_stiffness`]).
    pub stiffness: Mat3,
}

/// A type-2 interaction of Choi & Ko's model read against the path through
/// its middle particle ([`crate::element_laws::bend_triple_with`]): corners `(i, m, j)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BendTriple {
    /// End, middle, end.
    pub nodes: [u32; 3],
    /// Rest length of the interaction (end to end along the cloth), m.
    pub rest: f64,
    /// Flexural rigidity of the interaction `k_b`, N m^2.
    pub k_b: f64,
}

/// A type-2 interaction of Choi & Ko's model across two triangles of a
/// mesh ([`crate::element_laws::bend_hinge_into`]): corners `[c, a, b, d]`,
/// the path through `(1 - w) x_a + w x_b`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BendHinge {
    /// Far corner, edge start, edge end, far corner.
    pub nodes: [u32; 4],
    /// Where the rest path crosses the edge, as the weight of its end.
    pub w: f64,
    /// Rest length of the path (the pair unfolded flat), m.
    pub rest: f64,
    /// Flexural rigidity of the interaction `k_b`, N m^2.
    pub k_b: f64,
}

/// The element kinds, in the order a particle adds them.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kind {
    Membrane,
    Curvature,
    Triple,
    Hinge,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Corner {
    kind: Kind,
    elem: u32,
    corner: u8,
}

/// All elements of a model, with per-particle incidence and, once the
/// pattern is known, the matrix slot of every corner pair. From
/// [`ElementSet::index`] on, each kind is stored by its lowest particle.
#[derive(Debug, Clone, Default)]
pub struct ElementSet {
    /// Membrane triangles (Volino).
    pub membranes: Vec<MembraneElement>,
    /// Bending triangles (Volino).
    pub curvatures: Vec<CurvatureElement>,
    /// Type-2 bending triples (Choi & Ko).
    pub triples: Vec<BendTriple>,
    /// Type-2 interactions across mesh triangle pairs (Choi & Ko).
    pub hinges: Vec<BendHinge>,
    inc_ptr: Vec<usize>,
    inc: Vec<Corner>,
    membrane_slots: Vec<[[u32; 3]; 3]>,
    curvature_slots: Vec<[[u32; 6]; 6]>,
    triple_slots: Vec<[[u32; 3]; 3]>,
    hinge_slots: Vec<[[u32; 4]; 4]>,
    /// Where each kind's elements were put when [`ElementSet::index`]
    /// stored them in the order of their lowest particle.
    order: BuildOrder,
}

/// Each kind's elements in the order they were built: storage indices.
///
/// [`ElementSet::index`] stores the elements by their lowest particle, so
/// that a pass over the particles (gathering rows, reading positions)
/// meets them nearly in storage order, where a mesher's order scatters
/// them (`docs/results/stages.md`). Sums over elements (a particle's
/// corners, the energies) still run in build order, so the order in
/// memory changes no result.
#[derive(Debug, Clone, Default)]
struct BuildOrder {
    membranes: Vec<u32>,
    curvatures: Vec<u32>,
    triples: Vec<u32>,
    hinges: Vec<u32>,
}

/// Storage indices of `len` elements in build order (`order`, or the
/// identity before [`ElementSet::index`] stored them).
fn in_build_order(len: usize, order: &[u32]) -> impl Iterator<Item = usize> + '_ {
    let stored = order.len() == len;
    (0..len).map(move |k| if stored { order[k] as usize } else { k })
}

/// Sorts `elems` by their lowest particle (ties in build order) and
/// updates `order` (storage indices in build order; the identity when it
/// does not match `elems`).
fn store_by_lowest_particle<E: Clone, const K: usize>(
    elems: &mut [E],
    order: &mut Vec<u32>,
    nodes: impl Fn(&E) -> [u32; K],
) {
    if order.len() != elems.len() {
        *order = (0..elems.len() as u32).collect();
    }
    let mut built_at = vec![0u32; elems.len()];
    for (k, &e) in order.iter().enumerate() {
        built_at[e as usize] = k as u32;
    }
    let lowest = |e: &E| nodes(e).into_iter().min().unwrap_or(0);
    let mut perm: Vec<u32> = (0..elems.len() as u32).collect();
    perm.sort_by_key(|&e| (lowest(&elems[e as usize]), built_at[e as usize]));
    let sorted: Vec<E> = perm.iter().map(|&e| elems[e as usize].clone()).collect();
    elems.clone_from_slice(&sorted);
    for (stored, &old) in perm.iter().enumerate() {
        order[built_at[old as usize] as usize] = stored as u32;
    }
}

impl ElementSet {
    /// Whether there is no element (Provot's model).
    pub fn is_empty(&self) -> bool {
        self.membranes.is_empty() && self.curvatures.is_empty() && self.triples.is_empty() && self.hinges.is_empty()
    }

    /// Most corners of any element present (0 when empty).
    pub fn largest_element(&self) -> usize {
        if !self.curvatures.is_empty() {
            6
        } else if !self.hinges.is_empty() {
            4
        } else if self.membranes.is_empty() && self.triples.is_empty() {
            0
        } else {
            3
        }
    }

    /// Every element as `(kind, storage index, corners)`, kind by kind,
    /// each kind in build order.
    fn node_lists(&self) -> impl Iterator<Item = (Kind, usize, &[u32])> {
        fn kind<'a, E, const K: usize>(
            kind: Kind,
            elems: &'a [E],
            order: &'a [u32],
            nodes: impl Fn(&'a E) -> &'a [u32; K] + 'a,
        ) -> impl Iterator<Item = (Kind, usize, &'a [u32])> + 'a {
            in_build_order(elems.len(), order).map(move |e| (kind, e, &nodes(&elems[e])[..]))
        }
        let o = &self.order;
        let m = kind(Kind::Membrane, &self.membranes, &o.membranes, |m| &m.nodes);
        let c = kind(Kind::Curvature, &self.curvatures, &o.curvatures, |c| &c.nodes);
        let t = kind(Kind::Triple, &self.triples, &o.triples, |t| &t.nodes);
        let h = kind(Kind::Hinge, &self.hinges, &o.hinges, |h| &h.nodes);
        m.chain(c).chain(t).chain(h)
    }

    /// Every coupled pair of particles, for the sparsity pattern.
    pub fn pairs(&self) -> Vec<(usize, usize)> {
        let mut out = Vec::new();
        for (_, _, nodes) in self.node_lists() {
            for (a, &p) in nodes.iter().enumerate() {
                for &q in &nodes[a + 1..] {
                    out.push((p as usize, q as usize));
                }
            }
        }
        out
    }

    /// Builds incidence and slot tables for `n` particles and `pattern`.
    pub fn index(&mut self, n: usize, pattern: &BlockPattern) {
        let order = &mut self.order;
        store_by_lowest_particle(&mut self.membranes, &mut order.membranes, |m| m.nodes);
        store_by_lowest_particle(&mut self.curvatures, &mut order.curvatures, |c| c.nodes);
        store_by_lowest_particle(&mut self.triples, &mut order.triples, |t| t.nodes);
        store_by_lowest_particle(&mut self.hinges, &mut order.hinges, |h| h.nodes);
        let mut per: Vec<Vec<Corner>> = vec![Vec::new(); n];
        for (kind, e, nodes) in self.node_lists() {
            for (a, &p) in nodes.iter().enumerate() {
                per[p as usize].push(Corner { kind, elem: e as u32, corner: a as u8 });
            }
        }
        self.inc_ptr = std::iter::once(0)
            .chain(per.iter().scan(0, |acc, v| {
                *acc += v.len();
                Some(*acc)
            }))
            .collect();
        self.inc = per.into_iter().flatten().collect();
        fn slots<const K: usize>(nodes: &[u32; K], pattern: &BlockPattern) -> [[u32; K]; K] {
            let slot = |p: u32, q: u32| {
                (pattern.slot(p as usize, q as usize).expect("element pair in the pattern")
                    - pattern.row_range(p as usize).start) as u32
            };
            std::array::from_fn(|a| std::array::from_fn(|b| slot(nodes[a], nodes[b])))
        }
        self.membrane_slots = self.membranes.iter().map(|m| slots(&m.nodes, pattern)).collect();
        self.curvature_slots = self.curvatures.iter().map(|c| slots(&c.nodes, pattern)).collect();
        self.triple_slots = self.triples.iter().map(|t| slots(&t.nodes, pattern)).collect();
        self.hinge_slots = self.hinges.iter().map(|h| slots(&h.nodes, pattern)).collect();
    }

    fn corners(&self, i: usize) -> &[Corner] {
        &self.inc[self.inc_ptr[i]..self.inc_ptr[i + 1]]
    }
}

/// One element's energy and right-hand-side terms.
#[derive(Debug, Clone, Copy)]
struct ElementRhs<const K: usize> {
    energy: f64,
    rhs: [Vec3; K],
}

impl<const K: usize> Default for ElementRhs<K> {
    fn default() -> Self {
        Self { energy: 0.0, rhs: [Vec3::zeros(); K] }
    }
}

/// Per-element scratch of one kind. Blocks live apart from the right-hand
/// sides so that a forces-only evaluation writes no blocks. With `UPPER`,
/// a kind whose law gives lower blocks that are the upper ones transposed
/// to the bit (the bending triples' and hinges') keeps only the blocks
/// `H_ab` with `a <= b`, and the reads transpose the others: a third
/// fewer bytes for the forces to write and the assembly to read back for
/// a triple, three eighths for a hinge, and the same bits.
#[derive(Debug, Clone, Default)]
struct KindBuffers<const K: usize, const UPPER: bool> {
    rhs: Vec<ElementRhs<K>>,
    /// Each element's blocks `c_x H_ab`, [`KindBuffers::STORED`] of them,
    /// row by row (`UPPER`: from the diagonal on).
    blocks: Vec<Mat3>,
}

impl<const K: usize, const UPPER: bool> KindBuffers<K, UPPER> {
    /// Blocks kept per element.
    const STORED: usize = if UPPER { K * (K + 1) / 2 } else { K * K };

    /// For `len` elements; their Hessian blocks only `with_hessians`.
    fn new(len: usize, with_hessians: bool) -> Self {
        let blocks = if with_hessians { len * Self::STORED } else { 0 };
        Self { rhs: vec![ElementRhs::default(); len], blocks: vec![Mat3::zeros(); blocks] }
    }

    /// Where block `(a, b)` of an element is among its stored ones, and
    /// whether it is kept as `(b, a)` (then read transposed).
    #[inline]
    fn place(a: usize, b: usize) -> (usize, bool) {
        if !UPPER {
            (a * K + b, false)
        } else if a <= b {
            (a * (2 * K - a - 1) / 2 + b, false)
        } else {
            (b * (2 * K - b - 1) / 2 + a, true)
        }
    }

    /// Block `c_x H_ab` of element `e` (of the last evaluation with
    /// Hessians).
    #[inline]
    fn block(&self, e: usize, a: usize, b: usize) -> Mat3 {
        let (k, transposed) = Self::place(a, b);
        let m = &self.blocks[e * Self::STORED + k];
        if transposed { m.transpose() } else { *m }
    }

    /// Evaluates `law(e, hessian)` for every element `e` with corners
    /// `nodes(e)`, in parallel, into right-hand sides and (with a Hessian)
    /// blocks `c_x H_ab`. `law` writes every block of `H` into the buffer
    /// it is given: a scratch each task reuses (an array made for each
    /// element costs a copy of a zeroed template), from which the blocks
    /// kept are copied.
    #[allow(clippy::too_many_arguments)]
    fn evaluate<E: Sync>(
        &mut self,
        elems: &[E],
        nodes: impl Fn(&E) -> [u32; K] + Sync,
        law: impl Fn(&E, &mut [[Mat3; K]; K]) -> ElementForces<K> + Sync,
        forces_only: impl Fn(&E) -> ElementForces<K> + Sync,
        c_x: f64,
        force: f64,
        k_times: Option<(f64, &[Vec3])>,
    ) {
        if c_x != 0.0 || k_times.is_some() {
            let stored = elems.len() * Self::STORED;
            assert_eq!(self.blocks.len(), stored, "element Hessians asked of buffers built for forces only");
            if elems.is_empty() {
                return;
            }
            self.rhs
                .par_iter_mut()
                .zip(self.blocks.par_chunks_mut(Self::STORED))
                .zip(elems.par_iter())
                .with_min_len(ROW_CHUNK)
                .for_each_init(
                    || [[Mat3::zeros(); K]; K],
                    |hessian, ((out, kept), e)| {
                        let r = law(e, hessian);
                        *out = fold(&r, hessian, &nodes(e), force, k_times);
                        for a in 0..K {
                            for b in if UPPER { a } else { 0 }..K {
                                kept[Self::place(a, b).0] = hessian[a][b] * c_x;
                            }
                        }
                    },
                );
        } else {
            self.rhs.par_iter_mut().zip(elems.par_iter()).with_min_len(ROW_CHUNK).for_each(|(out, e)| {
                let r = forces_only(e);
                *out = ElementRhs { energy: r.energy, rhs: r.forces.map(|f| f * force) };
            });
        }
    }

    /// The elements' energies summed in build order (`order`), J.
    fn energy(&self, order: &[u32]) -> f64 {
        in_build_order(self.rhs.len(), order).map(|e| self.rhs[e].energy).sum()
    }
}

/// Per-element scratch, sized once per model.
#[derive(Debug, Clone, Default)]
pub struct ElementBuffers {
    membranes: KindBuffers<3, false>,
    curvatures: KindBuffers<6, false>,
    triples: KindBuffers<3, true>,
    hinges: KindBuffers<4, true>,
}

impl ElementBuffers {
    /// Buffers for `set`, for assemblies (forces and Hessians).
    pub fn new(set: &ElementSet) -> Self {
        Self::sized(set, true)
    }

    /// Buffers for `set` for energies and forces only ([`evaluate`] with
    /// `c_x = 0` and no `k_times`): without the Hessian blocks, up to
    /// 36 `Mat3` an element (the 513 x 513 cloth's energy monitor held 340
    /// MB of them, never written).
    pub fn forces_only(set: &ElementSet) -> Self {
        Self::sized(set, false)
    }

    fn sized(set: &ElementSet, with_hessians: bool) -> Self {
        Self {
            membranes: KindBuffers::new(set.membranes.len(), with_hessians),
            curvatures: KindBuffers::new(set.curvatures.len(), with_hessians),
            triples: KindBuffers::new(set.triples.len(), with_hessians),
            hinges: KindBuffers::new(set.hinges.len(), with_hessians),
        }
    }
}

/// Folds a law's forces and matrix `hessian` into right-hand-side terms.
fn fold<const K: usize>(
    r: &ElementForces<K>,
    hessian: &[[Mat3; K]; K],
    nodes: &[u32; K],
    force: f64,
    k_times: Option<(f64, &[Vec3])>,
) -> ElementRhs<K> {
    let rhs = std::array::from_fn(|a| {
        let mut v = r.forces[a] * force;
        if let Some((coef, w)) = k_times {
            for b in 0..K {
                v -= hessian[a][b] * w[nodes[b] as usize] * coef;
            }
        }
        v
    });
    ElementRhs { energy: r.energy, rhs }
}

/// Evaluates every element at `x`: right-hand-side terms
/// `force f_a - a_k (H w)_a` and blocks `c_x H_ab` (no Hessian work and no
/// block writes when `c_x = 0` and there is no `k_times`, as for explicit
/// integrators).
pub fn evaluate(
    set: &ElementSet,
    x: &[Vec3],
    c_x: f64,
    force: f64,
    k_times: Option<(f64, &[Vec3])>,
    bufs: &mut ElementBuffers,
) {
    let at = |nodes: &[u32; 3]| nodes.map(|p| x[p as usize]);
    bufs.membranes.evaluate(
        &set.membranes,
        |m| m.nodes,
        |m, h| membrane_triangle_into(at(&m.nodes), &m.rest, Some(h)),
        |m| membrane_triangle_into(at(&m.nodes), &m.rest, None),
        c_x,
        force,
        k_times,
    );
    bufs.curvatures.evaluate(
        &set.curvatures,
        |e| e.nodes,
        |e, h| curvature_bending_into(e.nodes.map(|p| x[p as usize]), e.rest_angles, &e.stiffness, Some(h)),
        |e| curvature_bending_into(e.nodes.map(|p| x[p as usize]), e.rest_angles, &e.stiffness, None),
        c_x,
        force,
        k_times,
    );
    bufs.triples.evaluate(
        &set.triples,
        |t| t.nodes,
        |t, h| bend_triple_into(at(&t.nodes), t.rest, t.k_b, Some(h)),
        |t| bend_triple_forces(at(&t.nodes), t.rest, t.k_b),
        c_x,
        force,
        k_times,
    );
    let at4 = |nodes: &[u32; 4]| nodes.map(|p| x[p as usize]);
    bufs.hinges.evaluate(
        &set.hinges,
        |h| h.nodes,
        |h, m| bend_hinge_into(at4(&h.nodes), h.w, h.rest, h.k_b, Some(m)),
        |h| bend_hinge_into(at4(&h.nodes), h.w, h.rest, h.k_b, None),
        c_x,
        force,
        k_times,
    );
}

/// Sum of the element right-hand-side terms at particle `i`.
pub(crate) fn rhs_at(set: &ElementSet, bufs: &ElementBuffers, i: usize) -> Vec3 {
    let mut acc = Vec3::zeros();
    for c in set.corners(i) {
        let (e, a) = (c.elem as usize, c.corner as usize);
        acc += match c.kind {
            Kind::Membrane => bufs.membranes.rhs[e].rhs[a],
            Kind::Curvature => bufs.curvatures.rhs[e].rhs[a],
            Kind::Triple => bufs.triples.rhs[e].rhs[a],
            Kind::Hinge => bufs.hinges.rhs[e].rhs[a],
        };
    }
    acc
}

/// Adds the element blocks of row `i`: `add(slot, block)` for each block,
/// `slot` its position in the row's stored blocks, corner by corner.
pub(crate) fn add_row(set: &ElementSet, bufs: &ElementBuffers, i: usize, mut row: impl FnMut(usize, &Mat3)) {
    fn add<const K: usize, const U: bool>(
        slots: &[u32; K],
        kind: &KindBuffers<K, U>,
        (e, a): (usize, usize),
        row: &mut impl FnMut(usize, &Mat3),
    ) {
        for (b, s) in slots.iter().enumerate() {
            row(*s as usize, &kind.block(e, a, b));
        }
    }
    let row = &mut row;
    for c in set.corners(i) {
        let (e, a) = (c.elem as usize, c.corner as usize);
        match c.kind {
            Kind::Membrane => add(&set.membrane_slots[e][a], &bufs.membranes, (e, a), row),
            Kind::Curvature => add(&set.curvature_slots[e][a], &bufs.curvatures, (e, a), row),
            Kind::Triple => add(&set.triple_slots[e][a], &bufs.triples, (e, a), row),
            Kind::Hinge => add(&set.hinge_slots[e][a], &bufs.hinges, (e, a), row),
        }
    }
}

/// Every element's forces and Hessian blocks at `x`, element by element:
/// `force(a, f_a)` and `block(a, b, H_ab)` with `H_ab = -df_a/dx_b` (N/m)
/// for its particles `a`, `b` (allocates its scratch: for tests and
/// terms' Jacobians, not the step).
pub(crate) fn for_each_block(
    set: &ElementSet,
    x: &[Vec3],
    mut force: impl FnMut(usize, Vec3),
    mut block: impl FnMut(usize, usize, &Mat3),
) {
    let mut bufs = ElementBuffers::new(set);
    evaluate(set, x, 1.0, 1.0, None, &mut bufs);
    fn each<E, const K: usize, const U: bool>(
        (elems, order): (&[E], &[u32]),
        nodes: impl Fn(&E) -> [u32; K],
        kind: &KindBuffers<K, U>,
        force: &mut impl FnMut(usize, Vec3),
        block: &mut impl FnMut(usize, usize, &Mat3),
    ) {
        for e in in_build_order(elems.len(), order) {
            let (nodes, rhs) = (nodes(&elems[e]), &kind.rhs[e]);
            for a in 0..K {
                force(nodes[a] as usize, rhs.rhs[a]);
                for b in 0..K {
                    block(nodes[a] as usize, nodes[b] as usize, &kind.block(e, a, b));
                }
            }
        }
    }
    let o = &set.order;
    each((&set.membranes, &o.membranes), |e| e.nodes, &bufs.membranes, &mut force, &mut block);
    each((&set.curvatures, &o.curvatures), |e| e.nodes, &bufs.curvatures, &mut force, &mut block);
    each((&set.triples, &o.triples), |e| e.nodes, &bufs.triples, &mut force, &mut block);
    each((&set.hinges, &o.hinges), |e| e.nodes, &bufs.hinges, &mut force, &mut block);
}

/// `sum_b blocks_ab w_b s_b` over the elements of particle `i` (with
/// `s = m^-1/2` for the mass-scaled operator).
pub(crate) fn apply_at(set: &ElementSet, bufs: &ElementBuffers, i: usize, w: &[Vec3], s: &[f64]) -> Vec3 {
    fn apply<const K: usize, const U: bool>(
        nodes: &[u32; K],
        kind: &KindBuffers<K, U>,
        (e, a): (usize, usize),
        w: &[Vec3],
        s: &[f64],
    ) -> Vec3 {
        let terms = nodes.iter().enumerate();
        terms.fold(Vec3::zeros(), |acc, (b, &p)| acc + kind.block(e, a, b) * (w[p as usize] * s[p as usize]))
    }
    let mut acc = Vec3::zeros();
    for c in set.corners(i) {
        let (e, a) = (c.elem as usize, c.corner as usize);
        acc += match c.kind {
            Kind::Membrane => apply(&set.membranes[e].nodes, &bufs.membranes, (e, a), w, s),
            Kind::Curvature => apply(&set.curvatures[e].nodes, &bufs.curvatures, (e, a), w, s),
            Kind::Triple => apply(&set.triples[e].nodes, &bufs.triples, (e, a), w, s),
            Kind::Hinge => apply(&set.hinges[e].nodes, &bufs.hinges, (e, a), w, s),
        };
    }
    acc
}

/// The force on particle `i` from its elements at `x`, N, and the sum of
/// their diagonal blocks `H_ii` (N/m): a vertex solver's local system.
/// Each element is evaluated whole for each corner asked.
pub(crate) fn vertex_at(set: &ElementSet, x: &[Vec3], i: usize) -> (Vec3, Mat3) {
    let (force, stiffness, _) = vertex_with_energy(set, x, i);
    (force, stiffness)
}

/// [`vertex_at`] and [`vertex_energy`] at `x` from one evaluation of each
/// element: force (N), `H_ii` (N/m) and energy (J).
pub(crate) fn vertex_with_energy(set: &ElementSet, x: &[Vec3], i: usize) -> (Vec3, Mat3, f64) {
    fn corner<const K: usize>(
        nodes: &[u32; K],
        a: usize,
        x: &[Vec3],
        law: impl Fn([Vec3; K], &mut [[Mat3; K]; K]) -> ElementForces<K>,
    ) -> (Vec3, Mat3, f64) {
        let mut hessian = [[Mat3::zeros(); K]; K];
        let r = law(nodes.map(|p| x[p as usize]), &mut hessian);
        (r.forces[a], hessian[a][a], r.energy)
    }
    let (mut force, mut stiffness, mut energy) = (Vec3::zeros(), Mat3::zeros(), 0.0);
    for c in set.corners(i) {
        let (e, a) = (c.elem as usize, c.corner as usize);
        let (nodes, (f, h, u)): (&[u32], _) = match c.kind {
            Kind::Membrane => {
                let m = &set.membranes[e];
                (&m.nodes, corner(&m.nodes, a, x, |p, h| membrane_triangle_into(p, &m.rest, Some(h))))
            }
            Kind::Curvature => {
                let b = &set.curvatures[e];
                let law = |p, h: &mut _| curvature_bending_into(p, b.rest_angles, &b.stiffness, Some(h));
                (&b.nodes, corner(&b.nodes, a, x, law))
            }
            Kind::Triple => {
                let t = &set.triples[e];
                (&t.nodes, crate::element_laws::bend_triple_corner(t.nodes.map(|p| x[p as usize]), t.rest, t.k_b, a))
            }
            Kind::Hinge => {
                let h = &set.hinges[e];
                let law = |p, m: &mut _| bend_hinge_into(p, h.w, h.rest, h.k_b, Some(m));
                (&h.nodes, corner(&h.nodes, a, x, law))
            }
        };
        force += f;
        stiffness += h;
        if first_slot(nodes, i, a) {
            energy += u;
        }
    }
    (force, stiffness, energy)
}

/// Whether slot `a` is particle `i`'s first in an element's `nodes`: a
/// bending element may hold a particle in two slots (a free edge's
/// neighbour slot repeats a corner), and its energy counts once.
fn first_slot(nodes: &[u32], i: usize, a: usize) -> bool {
    nodes.iter().position(|&p| p as usize == i) == Some(a)
}

/// The energy of particle `i`'s elements with `i` at `xi` and the others
/// at `x`, J: what changes when `i` alone moves.
pub(crate) fn vertex_energy(set: &ElementSet, x: &[Vec3], i: usize, xi: Vec3) -> f64 {
    let mut energy = 0.0;
    for c in set.corners(i) {
        let (e, a) = (c.elem as usize, c.corner as usize);
        let counted = match c.kind {
            Kind::Membrane => first_slot(&set.membranes[e].nodes, i, a),
            Kind::Curvature => first_slot(&set.curvatures[e].nodes, i, a),
            Kind::Triple => first_slot(&set.triples[e].nodes, i, a),
            Kind::Hinge => first_slot(&set.hinges[e].nodes, i, a),
        };
        if !counted {
            continue;
        }
        energy += match c.kind {
            Kind::Membrane => {
                let m = &set.membranes[e];
                let p = m.nodes.map(|p| if p as usize == i { xi } else { x[p as usize] });
                membrane_triangle_into(p, &m.rest, None).energy
            }
            Kind::Curvature => {
                let b = &set.curvatures[e];
                let p = b.nodes.map(|p| if p as usize == i { xi } else { x[p as usize] });
                curvature_bending_into(p, b.rest_angles, &b.stiffness, None).energy
            }
            Kind::Triple => {
                let t = &set.triples[e];
                let p = t.nodes.map(|p| if p as usize == i { xi } else { x[p as usize] });
                bend_triple_energy(p, t.rest, t.k_b)
            }
            Kind::Hinge => {
                let h = &set.hinges[e];
                let p = h.nodes.map(|p| if p as usize == i { xi } else { x[p as usize] });
                bend_hinge_energy(p, h.w, h.rest, h.k_b)
            }
        };
    }
    energy
}

/// Each element's energy, by kind, for [`energy_only`], J: what the
/// energy monitor keeps instead of an evaluation's forces and blocks.
#[derive(Debug, Clone, Default)]
pub struct ElementEnergies {
    membranes: Vec<f64>,
    curvatures: Vec<f64>,
    triples: Vec<f64>,
    hinges: Vec<f64>,
}

impl ElementEnergies {
    /// Buffers for `set`.
    pub fn new(set: &ElementSet) -> Self {
        Self {
            membranes: vec![0.0; set.membranes.len()],
            curvatures: vec![0.0; set.curvatures.len()],
            triples: vec![0.0; set.triples.len()],
            hinges: vec![0.0; set.hinges.len()],
        }
    }
}

/// `energy(e)` of every element into `out`, in parallel, summed in
/// build order (`order`) as an evaluation's energies are, J.
fn kind_energy<E: Sync>(out: &mut [f64], elems: &[E], order: &[u32], energy: impl Fn(&E) -> f64 + Sync) -> f64 {
    out.par_iter_mut().zip(elems.par_iter()).with_min_len(ROW_CHUNK).for_each(|(out, e)| *out = energy(e));
    in_build_order(out.len(), order).map(|e| out[e]).sum()
}

/// Total element energy at `x`, J: bit for bit what [`evaluate`] then
/// [`energy`] give, without the forces (the bending triples and hinges
/// skip their gradients and the arc law's derivatives: what an energy
/// monitor and a line search need).
pub(crate) fn energy_only(set: &ElementSet, x: &[Vec3], bufs: &mut ElementEnergies) -> f64 {
    let at = |nodes: &[u32; 3]| nodes.map(|p| x[p as usize]);
    let o = &set.order;
    let membranes = kind_energy(&mut bufs.membranes, &set.membranes, &o.membranes, |m| {
        membrane_triangle_into(at(&m.nodes), &m.rest, None).energy
    });
    let curvatures = kind_energy(&mut bufs.curvatures, &set.curvatures, &o.curvatures, |e| {
        curvature_bending_into(e.nodes.map(|p| x[p as usize]), e.rest_angles, &e.stiffness, None).energy
    });
    let triples =
        kind_energy(&mut bufs.triples, &set.triples, &o.triples, |t| bend_triple_energy(at(&t.nodes), t.rest, t.k_b));
    let at4 = |nodes: &[u32; 4]| nodes.map(|p| x[p as usize]);
    let hinges =
        kind_energy(&mut bufs.hinges, &set.hinges, &o.hinges, |h| bend_hinge_energy(at4(&h.nodes), h.w, h.rest, h.k_b));
    membranes + curvatures + triples + hinges
}

/// Total element energy of the last [`evaluate`] of `set`, J.
pub(crate) fn energy(set: &ElementSet, bufs: &ElementBuffers) -> f64 {
    let o = &set.order;
    bufs.membranes.energy(&o.membranes)
        + bufs.curvatures.energy(&o.curvatures)
        + bufs.triples.energy(&o.triples)
        + bufs.hinges.energy(&o.hinges)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::element_laws::Matrix3Voigt;
    use nalgebra::Vector2;

    /// A 5 x 5 grid, its membrane triangles, the hinges across their
    /// diagonals and bending triples along its rows and columns (their
    /// rest longer than the chord: buckled), listed in an order far from
    /// their particles' (as a mesher's can be), at bent positions.
    fn scrambled() -> (ElementSet, Vec<Vec3>) {
        let (side, h) = (5u32, 0.01);
        let id = |i: u32, j: u32| i + side * j;
        let mut x = Vec::new();
        for j in 0..side {
            for i in 0..side {
                let z = 0.002 * ((i * 7 + j * 3) % 5) as f64 - 0.003 * ((i + 2 * j) % 3) as f64;
                x.push(Vec3::new(i as f64 * h + 1e-4 * j as f64, j as f64 * h, z));
            }
        }
        let uv = [Vector2::new(0.0, 0.0), Vector2::new(h, 0.0), Vector2::new(0.0, h)];
        let rest = TriangleRest::new(uv, Matrix3Voigt::orthotropic(50.0, 30.0, 8.0, 0.3)).unwrap();
        let mut set = ElementSet::default();
        for j in (0..side - 1).rev() {
            for i in [3, 0, 2, 1] {
                let (a, b, c, d) = (id(i, j), id(i + 1, j), id(i, j + 1), id(i + 1, j + 1));
                set.membranes.push(MembraneElement { nodes: [b, d, c], rest });
                set.membranes.push(MembraneElement { nodes: [a, b, c], rest });
                let k_b = 1e-3 * (1.0 + i as f64);
                set.hinges.push(BendHinge { nodes: [a, b, c, d], w: 0.5, rest: 2.0 * h, k_b });
            }
        }
        for k in [4, 1, 3, 0, 2] {
            for m in [2, 0, 1] {
                let k_b = 1e-3 * (1.0 + m as f64);
                set.triples.push(BendTriple { nodes: [id(m, k), id(m + 1, k), id(m + 2, k)], rest: 2.3 * h, k_b });
                set.triples.push(BendTriple { nodes: [id(k, m + 2), id(k, m + 1), id(k, m)], rest: 2.3 * h, k_b });
            }
        }
        (set, x)
    }

    /// Adds an element's forces and whole matrix, as its `law` gives them
    /// at the corners `nodes`, into `force` and the dense `rows`; returns
    /// its energy and how many of its blocks are not symmetric themselves.
    fn add_whole<const K: usize>(
        nodes: &[u32; K],
        law: impl FnOnce(&mut [[Mat3; K]; K]) -> ElementForces<K>,
        force: &mut [Vec3],
        rows: &mut [Vec<Mat3>],
    ) -> (f64, usize) {
        let mut hess = [[Mat3::zeros(); K]; K];
        let r = law(&mut hess);
        let mut unsymmetric = 0;
        for a in 0..K {
            force[nodes[a] as usize] += r.forces[a];
            for b in 0..K {
                rows[nodes[a] as usize][nodes[b] as usize] += hess[a][b];
                unsymmetric += usize::from(hess[a][b] != hess[a][b].transpose());
            }
        }
        (r.energy, unsymmetric)
    }

    /// Elements stored by their lowest particle still sum in the order
    /// they were built: energies, forces and row blocks are bit for bit
    /// the sums over the elements as built (which storage order would not
    /// give here: the energy summed in storage order differs). The
    /// triples and hinges keep their upper blocks alone; the rows read
    /// the lower ones transposed, bit for bit the laws' own.
    #[test]
    fn storing_elements_by_particle_keeps_every_sum_in_build_order() {
        let (mut set, x) = scrambled();
        let built = set.clone();
        let n = x.len();
        let pattern = BlockPattern::from_pairs(n, set.pairs()).unwrap();
        set.index(n, &pattern);
        let lowest = |nodes: &[u32]| *nodes.iter().min().unwrap();
        assert!(set.membranes.windows(2).all(|w| lowest(&w[0].nodes) <= lowest(&w[1].nodes)));
        assert!(set.hinges.windows(2).all(|w| lowest(&w[0].nodes) <= lowest(&w[1].nodes)));
        assert!(set.triples.windows(2).all(|w| lowest(&w[0].nodes) <= lowest(&w[1].nodes)));
        assert_ne!(set.membranes, built.membranes, "the build order was already the storage order");

        // The sums as built: membranes, triples, then hinges, element by
        // element, from each law's full matrix.
        let at3 = |n: &[u32; 3]| n.map(|p| x[p as usize]);
        let at4 = |n: &[u32; 4]| n.map(|p| x[p as usize]);
        let mut energy_m = 0.0;
        let mut energy_t = 0.0;
        let mut energy_h = 0.0;
        let mut asymmetric = 0;
        let mut force = vec![Vec3::zeros(); n];
        let mut rows = vec![vec![Mat3::zeros(); n]; n];
        for m in &built.membranes {
            let law = |h: &mut _| membrane_triangle_into(at3(&m.nodes), &m.rest, Some(h));
            energy_m += add_whole(&m.nodes, law, &mut force, &mut rows).0;
        }
        for t in &built.triples {
            let law = |h: &mut _| bend_triple_into(at3(&t.nodes), t.rest, t.k_b, Some(h));
            let (energy, unsymmetric) = add_whole(&t.nodes, law, &mut force, &mut rows);
            (energy_t, asymmetric) = (energy_t + energy, asymmetric + unsymmetric);
        }
        for e in &built.hinges {
            let law = |h: &mut _| bend_hinge_into(at4(&e.nodes), e.w, e.rest, e.k_b, Some(h));
            let (energy, unsymmetric) = add_whole(&e.nodes, law, &mut force, &mut rows);
            (energy_h, asymmetric) = (energy_h + energy, asymmetric + unsymmetric);
        }
        // Blocks that are not symmetric themselves: a block read from its
        // transposed partner the wrong way round would show.
        assert!(asymmetric > 100, "{asymmetric} asymmetric blocks");
        let expected = energy_m + 0.0 + energy_t + energy_h;

        assert_eq!(energy_only(&set, &x, &mut ElementEnergies::new(&set)).to_bits(), expected.to_bits());
        let mut bufs = ElementBuffers::new(&set);
        evaluate(&set, &x, 1.0, 1.0, None, &mut bufs);
        assert_eq!(energy(&set, &bufs).to_bits(), expected.to_bits());
        let in_storage_order: f64 = bufs.membranes.rhs.iter().map(|r| r.energy).sum();
        assert_ne!(in_storage_order.to_bits(), energy_m.to_bits(), "the test cannot tell the orders apart");
        for i in 0..n {
            assert_eq!(rhs_at(&set, &bufs, i), force[i], "force on particle {i}");
            let cols = pattern.row_cols(i);
            let mut row = vec![Mat3::zeros(); cols.len()];
            add_row(&set, &bufs, i, |slot, b| row[slot] += b);
            for (block, &j) in row.iter().zip(cols) {
                assert_eq!(*block, rows[i][j as usize], "block ({i}, {j})");
            }
        }
        // The element blocks one by one (summed as built: the same bits),
        // and the products over them (summed by element: within 5.1e-14
        // of the rows' products, measured).
        let mut each = vec![vec![Mat3::zeros(); n]; n];
        for_each_block(&set, &x, |_, _| {}, |a, b, block| each[a][b] += block);
        assert_eq!(each, rows);
        let w: Vec<Vec3> = (0..n).map(|k| Vec3::new(1.0, -0.5 * k as f64, 0.25 + 0.1 * k as f64)).collect();
        let scale: Vec<f64> = (0..n).map(|k| 1.0 + 0.01 * k as f64).collect();
        for (i, row) in rows.iter().enumerate() {
            let product: Vec3 = row.iter().zip(w.iter().zip(&scale)).map(|(block, (w, s))| block * (w * *s)).sum();
            let applied = apply_at(&set, &bufs, i, &w, &scale);
            assert!((applied - product).norm() <= 1e-13 * product.norm(), "apply_at row {i}");
        }
    }
}
