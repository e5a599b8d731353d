//! Drivers that loop the interaction laws over a model's links: each
//! link's force, Jacobian blocks and energy ([`eval_link`]), the total
//! force the explicit integrators take ([`forces_into`]) and the energies
//! the energy monitor and Newton's line search take ([`elastic_energy`]).
//! The implicit steps' system is assembled in [`crate::system`].
//!
//! Links are evaluated in parallel into per-link buffers, then each
//! particle gathers its links in a fixed order: no atomics, no reduction
//! whose order depends on scheduling, so results are bit-identical for any
//! thread count.

use crate::elements::{self, ElementBuffers};
use crate::{
    ClothModel, Mat3, Vec3,
    laws::{ScalarLaw, directional_damping, pair_stiffness},
};
use cloth_linalg::ROW_CHUNK;
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
    crate::terms::from_jacobian(model).map(|t| t.energy(&at)).sum()
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
