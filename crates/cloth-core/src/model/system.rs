//! An implicit step's linear system, assembled from the force terms:
//! `A = M - c_v D - c_x K`, `b_i = m_i y_i + c_f (f_i + f_ext,i) + a_k (K
//! w_k)_i + a_d (D w_d)_i` ([`SystemTerms`]), with `f` the elastic
//! (undamped) force and `K = df/dx`, `D = df/dv` (ARCSim-style
//! bookkeeping: each term documents what it adds).
//!
//! Assembly loops over the parts of the system: the step's own (inertia,
//! the loads of its start, the contacts' diagonal stiffness and damping)
//! and every acting force term, each evaluated in parallel over its links
//! or elements ([`TermAssembly::evaluate`]), then read back row by row;
//! the terms without an assembly of their own are assembled together
//! from their Jacobians ([`ForceTerm::jacobian`]). A row sums its parts in
//! a fixed order, one for the right-hand side and one for the blocks
//! ([`RHS_ORDER`], [`BLOCK_ORDER`]): the same bits for any thread count,
//! and the same as the fused assembly these parts replaced.

pub(crate) use crate::model::assembly::{Row, SystemTerms};
use crate::terms::{At, ForceTerm, INTERNAL_TERMS, Jacobian, TermAssembly, TermScratch};
use crate::{ClothModel, Mat3, Vec3};
use cloth_linalg::{BlockSparseMatrix, ROW_CHUNK};
use rayon::prelude::*;
use std::time::Instant;

/// A part of the system: a force term, or one of the step's own.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Part {
    /// Acting term `k` of [`Parts::terms`] with its own assembly.
    Term(usize),
    /// The terms without an assembly of their own, from their Jacobians.
    Jacobians,
    /// `M` in the matrix, `M y` in the right-hand side.
    Inertia,
    /// The loads of the step's start, `force f_ext`.
    Loads,
    /// The contacts' diagonal stiffness `S` (self-collision).
    ContactStiffness,
    /// The contacts' diagonal damping `C` (squeezed particles' friction).
    ContactDamping,
}

/// A built-in term's place among the parts (see [`RHS_ORDER`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Slot {
    Term(&'static str),
    Step(Part),
}

/// The order in which a row sums its right-hand side: the step's parts
/// and the built-in terms (by name) in this order, then the other terms
/// with an assembly of their own in the registry's order (those named in
/// neither order), then the Jacobians' part. Kept as the fused assembly
/// summed, so results stay bit for bit.
pub(crate) const RHS_ORDER: [&str; 8] =
    ["gravity", "inertia", "loads", "contact stiffness", "drag", "contact damping", "elements", "links"];

/// The order in which a row sums its blocks (see [`RHS_ORDER`]).
pub(crate) const BLOCK_ORDER: [&str; 6] =
    ["inertia", "drag", "contact stiffness", "contact damping", "links", "elements"];

/// The order in which the matrix-free operator sums a row's coupling
/// blocks (see [`RHS_ORDER`]).
pub(crate) const OPERATOR_ORDER: [&str; 2] = ["elements", "links"];

fn slot_of(name: &'static str) -> Slot {
    match name {
        "inertia" => Slot::Step(Part::Inertia),
        "loads" => Slot::Step(Part::Loads),
        "contact stiffness" => Slot::Step(Part::ContactStiffness),
        "contact damping" => Slot::Step(Part::ContactDamping),
        term => Slot::Term(term),
    }
}

/// The parts of a model's system and the orders its rows sum them in.
#[derive(Debug, Clone, Default)]
struct Parts {
    /// The acting terms with an assembly of their own: built-in ones by
    /// their place in [`INTERNAL_TERMS`], outside ones by theirs in
    /// [`ClothModel::extra_terms`] (offset by the built-ins' count).
    terms: Vec<usize>,
    rhs: Vec<Part>,
    blocks: Vec<Part>,
    /// The matrix-free operator's coupling parts, in the order it sums them.
    operator: Vec<Part>,
}

/// Term `k` of [`Parts::terms`]' numbering.
fn term_at(model: &ClothModel, k: usize) -> &dyn ForceTerm {
    match INTERNAL_TERMS.get(k) {
        Some(t) => *t,
        None => model.extra_terms()[k - INTERNAL_TERMS.len()].as_ref(),
    }
}

impl Parts {
    fn of(model: &ClothModel) -> Self {
        let all = (0..INTERNAL_TERMS.len() + model.extra_terms().len()).map(|k| (k, term_at(model, k)));
        let own: Vec<(usize, &dyn ForceTerm)> =
            all.filter(|(_, t)| t.acts_on(model) && !t.external() && t.assembly().is_some()).collect();
        let terms: Vec<usize> = own.iter().map(|(k, _)| *k).collect();
        let position = |name: &str| own.iter().position(|(_, t)| t.name() == name);
        let jacobians = crate::terms::from_jacobian(model).next().is_some();
        let placed = |t: &dyn ForceTerm| RHS_ORDER.contains(&t.name()) || BLOCK_ORDER.contains(&t.name());
        let ordered = |order: &[&'static str]| -> Vec<Part> {
            let mut parts: Vec<Part> = order
                .iter()
                .filter_map(|&name| match slot_of(name) {
                    Slot::Step(p) => Some(p),
                    Slot::Term(t) => position(t).map(Part::Term),
                })
                .collect();
            parts.extend((0..own.len()).filter(|&p| !placed(own[p].1)).map(Part::Term));
            if jacobians {
                parts.push(Part::Jacobians);
            }
            parts
        };
        let (rhs, blocks) = (ordered(&RHS_ORDER), ordered(&BLOCK_ORDER));
        let operator = OPERATOR_ORDER.iter().filter_map(|name| position(name).map(Part::Term));
        let mut operator: Vec<Part> = operator.collect();
        operator.extend(
            (0..own.len())
                .filter(|&p| !placed(own[p].1) && own[p].1.assembly().is_some_and(|a| a.couples()))
                .map(Part::Term),
        );
        Self { terms, rhs, blocks, operator }
    }
}

/// What the terms without an assembly of their own give at the
/// assembly's positions, by the pattern's blocks (see [`Jacobian`]).
#[derive(Debug, Clone, Default)]
struct JacobianBuffers {
    force: Vec<Vec3>,
    stiffness: Vec<Mat3>,
    damping: Vec<Mat3>,
    written: Vec<bool>,
    /// Their energy at the last assembly, J.
    energy: f64,
    /// Zero velocities: the terms' forces at the step's start are taken
    /// without their damping, which the step's velocity term carries.
    still: Vec<Vec3>,
}

impl JacobianBuffers {
    fn new(model: &ClothModel) -> Self {
        let (n, nnz) = (model.particle_count(), model.pattern().nnz_blocks());
        Self {
            force: vec![Vec3::zeros(); n],
            stiffness: vec![Mat3::zeros(); nnz],
            damping: vec![Mat3::zeros(); nnz],
            written: vec![false; nnz],
            energy: 0.0,
            still: vec![Vec3::zeros(); n],
        }
    }

    /// Every such term's force and Jacobian at `x`, summed in term order.
    fn evaluate(&mut self, model: &ClothModel, x: &[Vec3], stitches_closed: &[bool]) {
        self.force.iter_mut().for_each(|f| *f = Vec3::zeros());
        for (((k, d), w), _) in self.stiffness.iter_mut().zip(&mut self.damping).zip(&mut self.written).zip(0..) {
            if *w {
                (*k, *d, *w) = (Mat3::zeros(), Mat3::zeros(), false);
            }
        }
        let at = At::new(model, x, &self.still, stitches_closed);
        for term in crate::terms::from_jacobian(model) {
            let buffers = (&mut self.force[..], &mut self.stiffness[..], &mut self.damping[..], &mut self.written[..]);
            term.jacobian(&at, &mut Jacobian::new(model.pattern(), term.name(), buffers));
        }
        self.energy = crate::terms::from_jacobian(model).map(|t| t.energy(&at)).sum();
    }

    /// `sum_j M_ij w_j` over row `i`'s written blocks of `m`.
    fn row_times(&self, model: &ClothModel, m: &[Mat3], i: usize, w: &[Vec3]) -> Vec3 {
        let (range, cols) = (model.pattern().row_range(i), model.pattern().row_cols(i));
        let mut acc = Vec3::zeros();
        for s in range.clone().filter(|&s| self.written[s]) {
            acc += m[s] * w[cols[s - range.start] as usize];
        }
        acc
    }
}

/// Scratch buffers for [`assemble`], sized once per model.
pub struct SystemBuffers {
    parts: Parts,
    /// Each of [`Parts::terms`]' scratch.
    scratch: Vec<TermScratch>,
    /// Each such term's energy at the last assembly, J.
    energies: Vec<f64>,
    jacobians: JacobianBuffers,
    /// `c_x` and `c_v` of the last assembly (the matrix-free operator's
    /// drag diagonal and Jacobians' blocks need them).
    c_x: f64,
    c_v: f64,
    /// The assembled matrix `A`.
    pub matrix: BlockSparseMatrix,
    /// The assembled right-hand side `b`.
    pub rhs: Vec<Vec3>,
}

impl std::fmt::Debug for SystemBuffers {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SystemBuffers").field("parts", &self.parts).field("c_v", &self.c_v).finish_non_exhaustive()
    }
}

impl SystemBuffers {
    /// Buffers for `model`.
    pub fn new(model: &ClothModel) -> Self {
        let parts = Parts::of(model);
        let scratch = parts.terms.iter().map(|&k| own(model, k).scratch(model)).collect();
        let jacobians =
            if parts.rhs.contains(&Part::Jacobians) { JacobianBuffers::new(model) } else { JacobianBuffers::default() };
        Self {
            energies: vec![0.0; parts.terms.len()],
            parts,
            scratch,
            jacobians,
            c_x: 0.0,
            c_v: 0.0,
            matrix: BlockSparseMatrix::new(model.pattern().clone()),
            rhs: vec![Vec3::zeros(); model.particle_count()],
        }
    }

    /// Elastic energy of the terms at the positions of the last assembly,
    /// J (summed in the blocks' order).
    pub fn elastic_energy(&self) -> f64 {
        let mut total = 0.0;
        for part in &self.parts.blocks {
            match *part {
                Part::Term(p) => total += self.energies[p],
                Part::Jacobians => total += self.jacobians.energy,
                _ => {}
            }
        }
        total
    }
}

/// Term `k`'s own assembly.
fn own(model: &ClothModel, k: usize) -> &dyn TermAssembly {
    term_at(model, k).assembly().expect("a part with an assembly of its own")
}

/// Time spent in the two assembly stages, s.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct AssemblyTiming {
    /// Evaluating the laws on every link and element.
    pub links_s: f64,
    /// Gathering into matrix rows and the right-hand side.
    pub gather_s: f64,
}

/// Builds `A` and `b` (see [`SystemTerms`]) at positions `x` without
/// allocating: each part's parallel evaluation, then a parallel pass over
/// the rows.
pub fn assemble(model: &ClothModel, x: &[Vec3], terms: &SystemTerms<'_>, bufs: &mut SystemBuffers) -> AssemblyTiming {
    let mut timing = assemble_matrix_free(model, x, terms, bufs);
    let t0 = Instant::now();
    let SystemBuffers { parts, scratch, jacobians, matrix, .. } = bufs;
    let at = At::new(model, x, &[], terms.stitches_closed);
    let evaluated = Evaluated { model, at: &at, c: terms, parts, scratch, jacobians };
    matrix.fill_rows(|i, blocks| {
        let mut row = Row::new(blocks, model.diag_local(i));
        for part in &parts.blocks {
            evaluated.add_row(part, i, &mut row);
        }
        row.store_diag();
    });
    timing.gather_s += t0.elapsed().as_secs_f64();
    timing
}

/// What the rows are gathered from: the positions, the step's
/// coefficients, and each part's evaluation.
struct Evaluated<'a> {
    model: &'a ClothModel,
    at: &'a At<'a>,
    c: &'a SystemTerms<'a>,
    parts: &'a Parts,
    scratch: &'a [TermScratch],
    jacobians: &'a JacobianBuffers,
}

impl Evaluated<'_> {
    /// Row `i`'s blocks of `part`.
    fn add_row(&self, part: &Part, i: usize, row: &mut Row<'_>) {
        let Evaluated { model, at, c, parts, scratch, jacobians } = *self;
        match *part {
            Part::Term(p) => own(model, parts.terms[p]).add_row(at, c, &scratch[p], i, row),
            Part::Inertia => row.add_diag(&(Mat3::identity() * model.masses()[i])),
            Part::ContactStiffness => {
                if let Some(s) = c.diag_stiffness {
                    row.add_diag(&(s[i] * c.c_x));
                }
            }
            Part::ContactDamping => {
                if let Some(d) = c.diag_damping {
                    row.add_diag(&(d[i] * c.c_v));
                }
            }
            Part::Jacobians => {
                let pattern = model.pattern();
                let start = pattern.row_range(i).start;
                for s in pattern.row_range(i).filter(|&s| jacobians.written[s]) {
                    row.add(s - start, &(jacobians.stiffness[s] * c.c_x + jacobians.damping[s] * c.c_v));
                }
            }
            Part::Loads => {}
        }
    }

    /// Row `i`'s right-hand side of `part`, added to `rhs`.
    fn add_rhs(&self, part: &Part, i: usize, rhs: &mut Vec3) {
        let Evaluated { model, at, c, parts, scratch, jacobians } = *self;
        match *part {
            Part::Term(p) => own(model, parts.terms[p]).add_rhs(at, c, &scratch[p], i, rhs),
            Part::Inertia => {
                if let Some(y) = c.mass_times {
                    *rhs += y[i] * model.masses()[i];
                }
            }
            Part::Loads => {
                if let Some(f) = c.external {
                    *rhs += f[i] * c.force;
                }
            }
            Part::ContactStiffness => {
                if let (Some(s), Some((a, w))) = (c.diag_stiffness, c.k_times) {
                    *rhs -= s[i] * w[i] * a;
                }
            }
            Part::ContactDamping => {
                if let (Some(d), Some((a, w))) = (c.diag_damping, c.d_times) {
                    *rhs -= d[i] * w[i] * a;
                }
            }
            Part::Jacobians => {
                *rhs += jacobians.force[i] * c.force;
                if let Some((a, w)) = c.k_times {
                    *rhs -= jacobians.row_times(model, &jacobians.stiffness, i, w) * a;
                }
                if let Some((a, w)) = c.d_times {
                    *rhs -= jacobians.row_times(model, &jacobians.damping, i, w) * a;
                }
            }
        }
    }
}

/// Like [`assemble`] but leaves the matrix unassembled: only each part's
/// evaluation (the blocks [`apply_scaled_operator`] reads) and the
/// right-hand side.
pub(crate) fn assemble_matrix_free(
    model: &ClothModel,
    x: &[Vec3],
    terms: &SystemTerms<'_>,
    bufs: &mut SystemBuffers,
) -> AssemblyTiming {
    let t0 = Instant::now();
    let at = At::new(model, x, &[], terms.stitches_closed);
    let SystemBuffers { parts, scratch, energies, jacobians, rhs, .. } = bufs;
    for ((&k, s), e) in parts.terms.iter().zip(scratch.iter_mut()).zip(energies.iter_mut()) {
        *e = own(model, k).evaluate(&at, terms, s);
    }
    (bufs.c_x, bufs.c_v) = (terms.c_x, terms.c_v);
    if parts.rhs.contains(&Part::Jacobians) {
        jacobians.evaluate(model, x, terms.stitches_closed);
    }
    let t1 = Instant::now();
    let evaluated = Evaluated { model, at: &at, c: terms, parts, scratch, jacobians };
    rhs.par_chunks_mut(ROW_CHUNK).enumerate().for_each(|(chunk, out)| {
        for (k, bi) in out.iter_mut().enumerate() {
            let i = chunk * ROW_CHUNK + k;
            let mut acc = Vec3::zeros();
            for part in &parts.rhs {
                evaluated.add_rhs(part, i, &mut acc);
            }
            *bi = acc;
        }
    });
    AssemblyTiming { links_s: (t1 - t0).as_secs_f64(), gather_s: t1.elapsed().as_secs_f64() }
}

/// The mass-scaled system operator applied on the fly, without an
/// assembled matrix (Volino & Magnenat-Thalmann 2001):
/// `y = M^-1/2 A M^-1/2 w`, i.e.
/// `y_i = w_i (1 + c_v c_i / m_i) + m_i^-1/2 sum_j B_ij w_j m_j^-1/2`,
/// with the coupling blocks `B` of the last [`assemble_matrix_free`]
/// (drag `c_i` on the diagonal). `inv_sqrt_mass[i] = m_i^-1/2`.
pub(crate) fn apply_scaled_operator(
    model: &ClothModel,
    bufs: &SystemBuffers,
    inv_sqrt_mass: &[f64],
    w: &[Vec3],
    y: &mut [Vec3],
) {
    let at = At::new(model, &[], &[], &[]);
    let SystemBuffers { parts, scratch, jacobians, c_x, c_v, .. } = bufs;
    let s = inv_sqrt_mass;
    let with_jacobians = parts.rhs.contains(&Part::Jacobians);
    y.par_chunks_mut(ROW_CHUNK).enumerate().for_each(|(chunk, ys)| {
        for (k, yi) in ys.iter_mut().enumerate() {
            let i = chunk * ROW_CHUNK + k;
            let mut acc = Vec3::zeros();
            for part in &parts.operator {
                if let Part::Term(p) = *part {
                    own(model, parts.terms[p]).apply(&at, &scratch[p], i, w, s, &mut acc);
                }
            }
            // Drag adds c_v c_i / m_i on the scaled diagonal.
            let drag = c_v * model.drag(i) * s[i] * s[i];
            *yi = w[i] * (1.0 + drag) + acc * s[i];
            if with_jacobians {
                let (range, cols) = (model.pattern().row_range(i), model.pattern().row_cols(i));
                let mut blocks = Vec3::zeros();
                for q in range.clone().filter(|&q| jacobians.written[q]) {
                    let j = cols[q - range.start] as usize;
                    blocks += (jacobians.stiffness[q] * *c_x + jacobians.damping[q] * *c_v) * (w[j] * s[j]);
                }
                *yi += blocks * s[i];
            }
        }
    });
}
