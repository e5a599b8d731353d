//! Drivers that loop the interaction laws over a model's links and build
//! the linear system of an implicit step.
//!
//! Each link contributes (ARCSim-style bookkeeping):
//! `f_i += phi u`, `f_j -= phi u`; `K_ij = K_ji += J_e`, `K_ii = K_jj -= J_e`
//! with `J_e = df_i/dx_j` (type-2 without its orthogonal term);
//! `D_ij = D_ji += k_d P`, `D_ii = D_jj -= k_d P`.
//! Links are evaluated in parallel into per-link buffers, then each
//! particle gathers its links in a fixed order: no atomics, no reduction
//! whose order depends on scheduling, so results are bit-identical for any
//! thread count.

use crate::elements::{self, ElementBuffers};
use crate::{
    ClothModel, Mat3, Vec3,
    laws::{ScalarLaw, directional_damping, pair_stiffness},
};
use cloth_linalg::{BlockSparseMatrix, ROW_CHUNK};
use rayon::prelude::*;

/// One link evaluated at a configuration.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LinkEval {
    /// Elastic force on the link's first particle, N (`-force` on the second).
    pub force: Vec3,
    /// `df_i/dx_j` as used in the system matrix (PSD), N/m.
    pub stiffness: Mat3,
    /// `df_i/dv_j`, N s/m.
    pub damping: Mat3,
    /// Elastic energy, J.
    pub energy: f64,
}

fn unit_and_length(xij: Vec3) -> (Vec3, f64) {
    let d = xij.norm();
    if d > 0.0 { (xij / d, d) } else { (Vec3::zeros(), 0.0) }
}

/// A link's evaluation. The orthogonal stiffness `(phi/d)(I - P)` is kept
/// only in tension: in compression it is negative and would make the
/// system indefinite, so it is dropped from the matrix (Choi & Ko's
/// treatment of type-2 links, applied to every compressed link).
fn eval_with(law: ScalarLaw, u: Vec3, d: f64, k_d: f64) -> LinkEval {
    LinkEval {
        force: u * law.phi,
        stiffness: pair_stiffness(&u, d, &law, law.phi > 0.0),
        damping: if k_d > 0.0 { directional_damping(&u, k_d) } else { Mat3::zeros() },
        energy: law.energy,
    }
}

/// Where link `k` lives: a type-1 link, a bend link or a stitch.
enum LinkRef<'a> {
    Stretch(&'a crate::StretchLink),
    Bend(&'a crate::BendLink),
    /// With whether it has closed.
    Stitch(&'a crate::Stitch, bool),
}

#[inline]
fn link_ref<'a>(model: &'a ClothModel, k: usize, stitches_closed: &[bool]) -> LinkRef<'a> {
    let (ns, nb) = (model.stretch_links().len(), model.bend_links().len());
    if k < ns {
        LinkRef::Stretch(&model.stretch_links()[k])
    } else if k < ns + nb {
        LinkRef::Bend(&model.bend_links()[k - ns])
    } else {
        LinkRef::Stitch(&model.stitches()[k - ns - nb], stitches_closed[k - ns - nb])
    }
}

/// A stitch's law at chord `d`: capped at its strength once closed, at
/// its sewing pull while open.
#[inline]
fn stitch_law(s: &crate::Stitch, closed: bool, d: f64) -> ScalarLaw {
    crate::laws::stitch(d, s.k, s.cap(closed))
}

/// Evaluates link `k` (stretch links first, then bend links, then
/// stitches) at positions `x`; `stitches_closed` says of each stitch
/// whether it has closed ([`crate::ClothState::stitches_closed`]; empty
/// without seams).
#[inline]
pub fn eval_link(model: &ClothModel, k: usize, x: &[Vec3], stitches_closed: &[bool]) -> LinkEval {
    match link_ref(model, k, stitches_closed) {
        LinkRef::Stretch(l) => {
            let (u, d) = unit_and_length(x[l.j as usize] - x[l.i as usize]);
            eval_with(l.eval(d), u, d, l.k_d)
        }
        LinkRef::Bend(l) => {
            let (u, d) = unit_and_length(x[l.j as usize] - x[l.i as usize]);
            eval_with(l.eval(d), u, d, 0.0)
        }
        LinkRef::Stitch(s, closed) => {
            let (u, d) = unit_and_length(x[s.j as usize] - x[s.i as usize]);
            let mut e = eval_with(stitch_law(s, closed, d), u, d, 0.0);
            if d == 0.0 {
                // At zero gap (either state, within its cap) the Jacobian is k I from any side.
                e.stiffness = Mat3::identity() * s.k;
            }
            e.damping = Mat3::identity() * s.dashpot(closed);
            e
        }
    }
}

/// Elastic energy of link `k` at positions `x`, J (the law only, no
/// Jacobian).
#[inline]
pub(crate) fn link_energy(model: &ClothModel, k: usize, x: &[Vec3], stitches_closed: &[bool]) -> f64 {
    let (i, j, _) = model.link_ends(k);
    link_energy_at_chord(model, k, (x[j] - x[i]).norm(), stitches_closed)
}

/// Elastic energy of link `k` at chord length `chord` (m), J.
#[inline]
pub(crate) fn link_energy_at_chord(model: &ClothModel, k: usize, chord: f64, stitches_closed: &[bool]) -> f64 {
    match link_ref(model, k, stitches_closed) {
        LinkRef::Stretch(l) => l.eval(chord).energy,
        LinkRef::Bend(l) => l.eval(chord).energy,
        LinkRef::Stitch(s, closed) => stitch_law(s, closed, chord).energy,
    }
}

/// Scratch for [`elastic_energy`], sized once per model.
#[derive(Debug, Clone)]
pub struct EnergyBuffers {
    link: Vec<f64>,
    elements: ElementBuffers,
}

impl EnergyBuffers {
    /// Buffers for `model`.
    pub fn new(model: &ClothModel) -> Self {
        Self { link: vec![0.0; model.link_count()], elements: ElementBuffers::forces_only(model.elements()) }
    }
}

/// Elastic energy of every link and element at `x`, J, without
/// allocating: laws in parallel, summed in link and element order (the
/// same bits for any thread count). `stitches_closed` as for [`eval_link`].
pub fn elastic_energy(model: &ClothModel, x: &[Vec3], stitches_closed: &[bool], bufs: &mut EnergyBuffers) -> f64 {
    bufs.link.par_chunks_mut(ROW_CHUNK).enumerate().for_each(|(chunk, es)| {
        for (k, e) in es.iter_mut().enumerate() {
            *e = link_energy(model, chunk * ROW_CHUNK + k, x, stitches_closed);
        }
    });
    let links: f64 = bufs.link.iter().sum();
    let set = model.elements();
    let internal = if set.is_empty() {
        links
    } else {
        elements::evaluate(set, x, 0.0, 1.0, None, &mut bufs.elements);
        links + elements::energy(&bufs.elements)
    };
    internal + extra_energy(model, x, stitches_closed)
}

/// Potential energy of the terms outside the fused assembly at `x`, J.
fn extra_energy(model: &ClothModel, x: &[Vec3], stitches_closed: &[bool]) -> f64 {
    // Energies read positions only.
    let at = crate::terms::At::new(model, x, &[], stitches_closed);
    crate::terms::unfused(model).map(|t| t.energy(&at)).sum()
}

/// Total potential energy at `x`: link energies plus gravity `-sum m g.x`,
/// J. `stitches_closed` as for [`eval_link`].
pub fn potential_energy(model: &ClothModel, x: &[Vec3], stitches_closed: &[bool]) -> f64 {
    let elastic = elastic_energy(model, x, stitches_closed, &mut EnergyBuffers::new(model));
    let gravity = model
        .effects()
        .gravity
        .map_or(0.0, |g| -model.masses().iter().zip(x).map(|(m, xi)| m * g.dot(xi)).sum::<f64>());
    elastic + gravity
}

/// Force on link `k`'s first particle at `(x, v)`: elastic plus directional
/// damping `k_d P (v_j - v_i)`, N (the second particle gets the opposite).
/// `stitches_closed` as for [`eval_link`].
#[inline]
pub fn link_force(model: &ClothModel, k: usize, x: &[Vec3], v: &[Vec3], stitches_closed: &[bool]) -> Vec3 {
    match link_ref(model, k, stitches_closed) {
        LinkRef::Stretch(l) => {
            let (i, j) = (l.i as usize, l.j as usize);
            let (u, d) = unit_and_length(x[j] - x[i]);
            let elastic = u * l.eval(d).phi;
            if l.k_d > 0.0 { elastic + u * (l.k_d * u.dot(&(v[j] - v[i]))) } else { elastic }
        }
        LinkRef::Bend(l) => {
            let (u, d) = unit_and_length(x[l.j as usize] - x[l.i as usize]);
            u * l.eval(d).phi
        }
        LinkRef::Stitch(s, closed) => {
            let (i, j) = (s.i as usize, s.j as usize);
            let (u, d) = unit_and_length(x[j] - x[i]);
            u * stitch_law(s, closed, d).phi + (v[j] - v[i]) * s.dashpot(closed)
        }
    }
}

/// `start` plus the per-link vectors of particle `i`'s links (stored for
/// the link's first particle), added in link order: `+v` where `i` is
/// first, `-v` where it is second.
#[inline]
pub(crate) fn gather_links(model: &ClothModel, i: usize, per_link: &[Vec3], start: Vec3) -> Vec3 {
    let mut acc = start;
    for inc in model.incidence(i) {
        let v = &per_link[inc.link as usize];
        if inc.first {
            acc += v;
        } else {
            acc -= v;
        }
    }
    acc
}

/// Scratch for [`forces_into`], sized once per model.
#[derive(Debug, Clone)]
pub struct ForceBuffers {
    pub(crate) link: Vec<Vec3>,
    pub(crate) elements: ElementBuffers,
    /// The particles' area-weighted normals (the wind's fluid force).
    pub(crate) normals: Vec<Vec3>,
}

impl ForceBuffers {
    /// Buffers for `model`.
    pub fn new(model: &ClothModel) -> Self {
        Self {
            link: vec![Vec3::zeros(); model.link_count()],
            elements: ElementBuffers::forces_only(model.elements()),
            normals: Self::normals_for(model),
        }
    }

    /// Buffers for `model`'s external terms only ([`crate::terms::external`]).
    pub fn external(model: &ClothModel) -> Self {
        Self {
            link: Vec::new(),
            elements: ElementBuffers::forces_only(&Default::default()),
            normals: Self::normals_for(model),
        }
    }

    fn normals_for(model: &ClothModel) -> Vec<Vec3> {
        Vec::with_capacity(if model.wind().is_some() { model.particle_count() } else { 0 })
    }
}

/// Total force on every particle at `(x, v)` (elastic, damping, gravity,
/// drag, N) into `out`, without allocating: each acting term of
/// [`crate::terms::INTERNAL_TERMS`] in turn (links in parallel, then a
/// fixed-order gather per particle). `stitches_closed` as for
/// [`eval_link`].
pub fn forces_into(
    model: &ClothModel,
    x: &[Vec3],
    v: &[Vec3],
    stitches_closed: &[bool],
    bufs: &mut ForceBuffers,
    out: &mut [Vec3],
) {
    out.par_chunks_mut(ROW_CHUNK).for_each(|fs| fs.iter_mut().for_each(|f| *f = Vec3::zeros()));
    let at = crate::terms::At::new(model, x, v, stitches_closed);
    for term in crate::terms::acting(model) {
        term.add_forces(&at, bufs, out);
    }
}

/// Total force on every particle at `(x, v)`: elastic, damping and
/// gravity, N. `stitches_closed` as for [`eval_link`].
pub fn total_forces(model: &ClothModel, x: &[Vec3], v: &[Vec3], stitches_closed: &[bool]) -> Vec<Vec3> {
    let mut out = vec![Vec3::zeros(); model.particle_count()];
    forces_into(model, x, v, stitches_closed, &mut ForceBuffers::new(model), &mut out);
    out
}

/// The coefficients of one implicit step's linear system
/// `A = M - c_v D - c_x K`,
/// `b_i = m_i y_i + force (f_i + m_i g) + a_k (K w_k)_i + a_d (D w_d)_i`,
/// with `f` the elastic (undamped) force.
#[derive(Debug, Clone, Copy)]
pub struct SystemTerms<'a> {
    /// Coefficient of `-K` in the matrix, s^2.
    pub c_x: f64,
    /// Coefficient of `-D` in the matrix, s.
    pub c_v: f64,
    /// Coefficient of the elastic and gravity forces in the right-hand side.
    pub force: f64,
    /// Optional `(a_k, w_k)`: adds `a_k K w_k`.
    pub k_times: Option<(f64, &'a [Vec3])>,
    /// Optional `(a_d, w_d)`: adds `a_d D w_d`.
    pub d_times: Option<(f64, &'a [Vec3])>,
    /// Optional `y`: adds `M y`.
    pub mass_times: Option<&'a [Vec3]>,
    /// Optional external forces (wind, self-collision) taken at the start
    /// of the step, N: adds `force * f_ext`.
    pub external: Option<&'a [Vec3]>,
    /// Optional stiffness of forces outside the links, kept on the
    /// diagonal only: blocks `S_i = -df_i/dx_i` (N/m, positive
    /// semidefinite; self-collision). Adds `c_x S_i` to the matrix and,
    /// with `k_times = (a_k, w_k)`, `-a_k S_i w_k` to the right-hand side.
    pub diag_stiffness: Option<&'a [Mat3]>,
    /// Optional damping of forces outside the links, kept on the diagonal
    /// only: blocks `C_i = -df_i/dv_i` (N s/m, positive semidefinite;
    /// friction of squeezed particles). Adds `c_v C_i` to the matrix and,
    /// with `d_times = (a_d, w_d)`, `-a_d C_i w_d` to the right-hand side;
    /// the force's constant part goes in `external`.
    pub diag_damping: Option<&'a [Mat3]>,
    /// Of each stitch, whether it has closed (as for [`eval_link`]).
    pub stitches_closed: &'a [bool],
}

impl<'a> SystemTerms<'a> {
    /// `A = M - c_v D - c_x K`, `b = force (f + m g)`, with none of the
    /// optional terms (set those with struct update syntax), the stitches
    /// in `stitches_closed`'s states (empty without seams).
    pub fn new(c_x: f64, c_v: f64, force: f64, stitches_closed: &'a [bool]) -> Self {
        Self {
            c_x,
            c_v,
            force,
            k_times: None,
            d_times: None,
            mass_times: None,
            external: None,
            diag_stiffness: None,
            diag_damping: None,
            stitches_closed,
        }
    }
}

/// Scratch buffers for [`assemble`], sized once per model.
#[derive(Debug, Clone)]
pub struct SystemBuffers {
    /// `c_v` of the last assembly (the drag diagonal of the matrix-free operator needs it).
    c_v: f64,
    link_rhs: Vec<Vec3>,
    link_block: Vec<Mat3>,
    link_energy: Vec<f64>,
    elements: ElementBuffers,
    /// The terms outside the fused assembly, linearised on the diagonal:
    /// `c_x S_i + c_v C_i` per particle (empty without such terms).
    extra_diag: Vec<Mat3>,
    /// Their energy at the last assembly, J.
    extra_energy: f64,
    /// Zero velocities: the added terms' forces at the step's start are
    /// taken without their damping, which the step's velocity term carries.
    still: Vec<Vec3>,
    /// The assembled matrix `A`.
    pub matrix: BlockSparseMatrix,
    /// The assembled right-hand side `b`.
    pub rhs: Vec<Vec3>,
}

impl SystemBuffers {
    /// Elastic energy of links and elements at the positions of the last
    /// assembly, J (summed in link and element order).
    pub fn elastic_energy(&self) -> f64 {
        self.link_energy.iter().sum::<f64>() + elements::energy(&self.elements) + self.extra_energy
    }

    /// Buffers for `model`.
    pub fn new(model: &ClothModel) -> Self {
        let (n, unfused) = (model.particle_count(), crate::terms::unfused(model).next().is_some());
        Self {
            c_v: 0.0,
            link_rhs: vec![Vec3::zeros(); model.link_count()],
            link_block: vec![Mat3::zeros(); model.link_count()],
            link_energy: vec![0.0; model.link_count()],
            elements: ElementBuffers::new(model.elements()),
            extra_diag: if unfused { vec![Mat3::zeros(); n] } else { Vec::new() },
            extra_energy: 0.0,
            still: if unfused { vec![Vec3::zeros(); n] } else { Vec::new() },
            matrix: BlockSparseMatrix::new(model.pattern().clone()),
            rhs: vec![Vec3::zeros(); model.particle_count()],
        }
    }
}

/// Time spent in the two assembly stages, s.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct AssemblyTiming {
    /// Evaluating the laws on every link.
    pub links_s: f64,
    /// Gathering links into matrix rows and the right-hand side.
    pub gather_s: f64,
}

/// Builds `A` and `b` (see [`SystemTerms`]) at positions `x` without
/// allocating: a parallel pass over links, then a parallel pass over rows.
pub fn assemble(model: &ClothModel, x: &[Vec3], terms: &SystemTerms<'_>, bufs: &mut SystemBuffers) -> AssemblyTiming {
    let mut timing = assemble_matrix_free(model, x, terms, bufs);
    let t0 = std::time::Instant::now();
    let (link_block, element_bufs, set, c_v) = (&bufs.link_block, &bufs.elements, model.elements(), terms.c_v);
    let extra_diag = &bufs.extra_diag;
    bufs.matrix.fill_rows(|i, row| {
        row.iter_mut().for_each(|b| *b = Mat3::zeros());
        let mut diag = Mat3::identity() * (model.masses()[i] + c_v * model.drag(i));
        if let Some(s) = terms.diag_stiffness {
            diag += s[i] * terms.c_x;
        }
        if let Some(c) = terms.diag_damping {
            diag += c[i] * c_v;
        }
        for inc in model.incidence(i) {
            let b = &link_block[inc.link as usize];
            diag += b;
            row[inc.slot as usize] -= b;
        }
        row[model.diag_local(i)] = diag;
        if !set.is_empty() {
            elements::add_row(set, element_bufs, i, row);
        }
        if let Some(extra) = extra_diag.get(i) {
            row[model.diag_local(i)] += extra;
        }
    });
    timing.gather_s += t0.elapsed().as_secs_f64();
    timing
}

/// Like [`assemble`] but leaves the matrix unassembled: only the per-link
/// blocks `B_e = c_x J_e + c_v D_e` (for [`apply_scaled_operator`]) and the
/// right-hand side are computed.
pub fn assemble_matrix_free(
    model: &ClothModel,
    x: &[Vec3],
    terms: &SystemTerms<'_>,
    bufs: &mut SystemBuffers,
) -> AssemblyTiming {
    let t0 = std::time::Instant::now();
    let per_link = bufs.link_rhs.par_chunks_mut(ROW_CHUNK).zip(bufs.link_block.par_chunks_mut(ROW_CHUNK));
    per_link.zip(bufs.link_energy.par_chunks_mut(ROW_CHUNK)).enumerate().for_each(
        |(chunk, ((rhs, blocks), energies))| {
            for (k_local, ((r, b), en)) in rhs.iter_mut().zip(blocks.iter_mut()).zip(energies.iter_mut()).enumerate() {
                let k = chunk * ROW_CHUNK + k_local;
                let e = eval_link(model, k, x, terms.stitches_closed);
                let (i, j, _) = model.link_ends(k);
                let mut ri = e.force * terms.force;
                if let Some((a, w)) = terms.k_times {
                    ri += e.stiffness * (w[j] - w[i]) * a;
                }
                if let Some((a, w)) = terms.d_times {
                    ri += e.damping * (w[j] - w[i]) * a;
                }
                *r = ri;
                *b = e.stiffness * terms.c_x + e.damping * terms.c_v;
                *en = e.energy;
            }
        },
    );
    bufs.c_v = terms.c_v;
    let set = model.elements();
    if !set.is_empty() {
        elements::evaluate(set, x, terms.c_x, terms.force, terms.k_times, &mut bufs.elements);
    }
    let t1 = std::time::Instant::now();
    let (link_rhs, element_bufs) = (&bufs.link_rhs, &bufs.elements);
    let gravity = model.effects().gravity;
    bufs.rhs.par_chunks_mut(ROW_CHUNK).enumerate().for_each(|(chunk, out)| {
        for (k, bi) in out.iter_mut().enumerate() {
            let i = chunk * ROW_CHUNK + k;
            let m = model.masses()[i];
            let mut acc = gravity.map_or(Vec3::zeros(), |g| g * (m * terms.force));
            if let Some(y) = terms.mass_times {
                acc += y[i] * m;
            }
            if let Some(f) = terms.external {
                acc += f[i] * terms.force;
            }
            if let (Some(s), Some((a, w))) = (terms.diag_stiffness, terms.k_times) {
                acc -= s[i] * w[i] * a;
            }
            if let Some((a, w)) = terms.d_times {
                // Drag is a diagonal D = -c_i I.
                acc -= w[i] * (a * model.drag(i));
                if let Some(c) = terms.diag_damping {
                    acc -= c[i] * w[i] * a;
                }
            }
            let acc = if set.is_empty() { acc } else { acc + elements::rhs_at(set, element_bufs, i) };
            *bi = gather_links(model, i, link_rhs, acc);
        }
    });
    if !bufs.extra_diag.is_empty() {
        add_extra_terms(model, x, terms, bufs);
    }
    AssemblyTiming { links_s: (t1 - t0).as_secs_f64(), gather_s: t1.elapsed().as_secs_f64() }
}

/// The terms outside the fused assembly, linearised on the diagonal: adds
/// `force f_i - a_k S_i w_k - a_d C_i w_d` to the right-hand side (`f_i`
/// at `x` without velocity) and keeps `c_x S_i + c_v C_i` for the matrix,
/// with `S_i`, `C_i` the terms' [`crate::terms::VertexBlock`]s.
fn add_extra_terms(model: &ClothModel, x: &[Vec3], terms: &SystemTerms<'_>, bufs: &mut SystemBuffers) {
    let at = crate::terms::At::new(model, x, &bufs.still, terms.stitches_closed);
    let rows = bufs.rhs.par_chunks_mut(ROW_CHUNK).zip(bufs.extra_diag.par_chunks_mut(ROW_CHUNK));
    rows.enumerate().for_each(|(chunk, (rhs, diag))| {
        for (k, (bi, di)) in rhs.iter_mut().zip(diag.iter_mut()).enumerate() {
            let i = chunk * ROW_CHUNK + k;
            let block = crate::terms::sum_of_blocks(crate::terms::unfused(model), &at, i);
            *bi += block.force * terms.force;
            if let Some((a, w)) = terms.k_times {
                *bi -= block.stiffness * w[i] * a;
            }
            if let Some((a, w)) = terms.d_times {
                *bi -= block.damping * w[i] * a;
            }
            *di = block.stiffness * terms.c_x + block.damping * terms.c_v;
        }
    });
    bufs.extra_energy = extra_energy(model, x, terms.stitches_closed);
}

/// The mass-scaled system operator applied on the fly, without an
/// assembled matrix (Volino & Magnenat-Thalmann 2001):
/// `y = M^-1/2 A M^-1/2 w`, i.e.
/// `y_i = w_i + m_i^-1/2 sum_e B_e (w_i m_i^-1/2 - w_o m_o^-1/2)`,
/// with the link blocks of the last [`assemble_matrix_free`].
/// `inv_sqrt_mass[i] = m_i^-1/2`.
pub fn apply_scaled_operator(
    model: &ClothModel,
    bufs: &SystemBuffers,
    inv_sqrt_mass: &[f64],
    w: &[Vec3],
    y: &mut [Vec3],
) {
    let (blocks, set, element_bufs) = (&bufs.link_block, model.elements(), &bufs.elements);
    y.par_chunks_mut(ROW_CHUNK).enumerate().for_each(|(chunk, ys)| {
        for (k, yi) in ys.iter_mut().enumerate() {
            let i = chunk * ROW_CHUNK + k;
            let wi = w[i] * inv_sqrt_mass[i];
            let mut acc =
                if set.is_empty() { Vec3::zeros() } else { elements::apply_at(set, element_bufs, i, w, inv_sqrt_mass) };
            for inc in model.incidence(i) {
                let o = inc.other as usize;
                acc += blocks[inc.link as usize] * (wi - w[o] * inv_sqrt_mass[o]);
            }
            // Drag adds c_v c_i / m_i on the scaled diagonal.
            let drag = bufs.c_v * model.drag(i) * inv_sqrt_mass[i] * inv_sqrt_mass[i];
            *yi = w[i] * (1.0 + drag) + acc * inv_sqrt_mass[i];
            if let Some(extra) = bufs.extra_diag.get(i) {
                *yi += extra * wi * inv_sqrt_mass[i];
            }
        }
    });
}
