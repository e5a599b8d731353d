//! Drivers that loop the interaction laws over a model's links: each
//! link's force, Jacobian blocks and energy (`terms::links`), the total
//! force the explicit integrators take ([`forces_into`]) and the energies
//! the energy monitor and Newton's line search take ([`elastic_energy`]).
//! The implicit steps' system is assembled in [`crate::system`].
//!
//! Links are evaluated in parallel into per-link buffers, then each
//! particle gathers its links in a fixed order: no atomics, no reduction
//! whose order depends on scheduling, so results are bit-identical for any
//! thread count.

use crate::elements::{self, ElementEnergies};
use crate::terms::ForceBuffers;
use crate::terms::link_energy;
use crate::{ClothModel, Vec3};
use cloth_linalg::ROW_CHUNK;
use rayon::prelude::*;

/// Scratch for [`elastic_energy`], sized once per model.
#[derive(Debug, Clone)]
pub struct EnergyBuffers {
    link: Vec<f64>,
    elements: ElementEnergies,
}

impl EnergyBuffers {
    /// Buffers for `model`.
    pub fn new(model: &ClothModel) -> Self {
        Self { link: vec![0.0; model.link_count()], elements: ElementEnergies::new(model.elements()) }
    }
}

/// Elastic energy of every link and element at `x`, J, without
/// allocating: laws in parallel, summed in link and element order (the
/// same bits for any thread count). `stitches_closed` as for [`crate::ClothState::stitches_closed`].
pub fn elastic_energy(model: &ClothModel, x: &[Vec3], stitches_closed: &[bool], bufs: &mut EnergyBuffers) -> f64 {
    bufs.link.par_chunks_mut(ROW_CHUNK).enumerate().for_each(|(chunk, es)| {
        for (k, e) in es.iter_mut().enumerate() {
            *e = link_energy(model, chunk * ROW_CHUNK + k, x, stitches_closed);
        }
    });
    let links: f64 = bufs.link.iter().sum();
    let set = model.elements();
    let internal = if set.is_empty() { links } else { links + elements::energy_only(set, x, &mut bufs.elements) };
    internal + extra_energy(model, x, stitches_closed)
}

/// Potential energy of the terms outside the fused assembly at `x`, J.
fn extra_energy(model: &ClothModel, x: &[Vec3], stitches_closed: &[bool]) -> f64 {
    // Energies read positions only.
    let at = crate::terms::At::new(model, x, &[], stitches_closed);
    crate::terms::from_jacobian(model).map(|t| t.energy(&at)).sum()
}

/// Total potential energy at `x`: link energies plus gravity `-sum m g.x`,
/// J. `stitches_closed` as for [`crate::ClothState::stitches_closed`].
pub fn potential_energy(model: &ClothModel, x: &[Vec3], stitches_closed: &[bool]) -> f64 {
    let elastic = elastic_energy(model, x, stitches_closed, &mut EnergyBuffers::new(model));
    let gravity = model
        .effects()
        .gravity
        .map_or(0.0, |g| -model.masses().iter().zip(x).map(|(m, xi)| m * g.dot(xi)).sum::<f64>());
    elastic + gravity
}

/// Total force on every particle at `(x, v)` (elastic, damping, gravity,
/// drag, N) into `out`, without allocating: each acting term of
/// [`crate::terms::INTERNAL_TERMS`] in turn (links in parallel, then a
/// fixed-order gather per particle). `stitches_closed` as for
/// [`crate::ClothState::stitches_closed`].
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

/// The dampers' forms along `p` (m) at `(x, v)`: `(v^T C p, p^T C p)`
/// (J, J s) with `C = -df/dv` the drag, the link dampers along the links'
/// directions at `x` (m) and the stitch dashpots: the damping's part of an
/// implicit step's potential along a line, with its directions frozen
/// there. `stitches_closed` as for [`crate::ClothState::stitches_closed`].
pub(crate) fn damping_forms(
    model: &ClothModel,
    x: &[Vec3],
    v: &[Vec3],
    p: &[Vec3],
    stitches_closed: &[bool],
) -> (f64, f64) {
    let (mut vcp, mut pcp) = (0.0, 0.0);
    for i in 0..p.len() {
        let drag = model.drag(i);
        vcp += drag * v[i].dot(&p[i]);
        pcp += drag * p[i].norm_squared();
    }
    for l in model.stretch_links().iter().filter(|l| l.k_d > 0.0) {
        let (i, j) = (l.i as usize, l.j as usize);
        let e = (x[j] - x[i]).normalize();
        let (dv, dp) = (e.dot(&(v[j] - v[i])), e.dot(&(p[j] - p[i])));
        if dv.is_finite() && dp.is_finite() {
            vcp += l.k_d * dv * dp;
            pcp += l.k_d * dp * dp;
        }
    }
    for (s, &closed) in model.stitches().iter().zip(stitches_closed) {
        let (i, j) = (s.i as usize, s.j as usize);
        let c = s.dashpot(closed);
        vcp += c * (v[j] - v[i]).dot(&(p[j] - p[i]));
        pcp += c * (p[j] - p[i]).norm_squared();
    }
    (vcp, pcp)
}

/// Total force on every particle at `(x, v)`: elastic, damping and
/// gravity, N. `stitches_closed` as for [`crate::ClothState::stitches_closed`].
pub fn total_forces(model: &ClothModel, x: &[Vec3], v: &[Vec3], stitches_closed: &[bool]) -> Vec<Vec3> {
    let mut out = vec![Vec3::zeros(); model.particle_count()];
    forces_into(model, x, v, stitches_closed, &mut ForceBuffers::new(model), &mut out);
    out
}
