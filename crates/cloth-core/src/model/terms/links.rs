//! Two-particle links: Choi & Ko's type-1 and type-2 links, Provot's
//! springs, and the seams' stitches ([`eval_link`], laws in
//! [`crate::laws`]). Each link pulls its ends along their chord with its
//! law's force `phi(d)`, and its damper acts on their relative velocity.

use super::{At, ForceTerm, TermAssembly, TermScratch, VertexBlock};
use crate::laws::{ScalarLaw, directional_damping, pair_stiffness};
use crate::model::assembly::{Row, SystemTerms};
use crate::terms::ForceBuffers;
use crate::{ClothModel, Mat3, Vec3};
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

/// Every link of the model (stretch links, bend links, stitches).
#[derive(Debug, Clone, Copy)]
pub struct Links;

impl ForceTerm for Links {
    fn name(&self) -> &'static str {
        "links"
    }

    fn acts_on(&self, model: &ClothModel) -> bool {
        model.link_count() > 0
    }

    fn energy(&self, at: &At<'_>) -> f64 {
        (0..at.model.link_count()).map(|k| link_energy(at.model, k, at.x, at.stitches_closed)).sum()
    }

    fn dissipation(&self, at: &At<'_>) -> f64 {
        (0..at.model.link_count())
            .map(|k| {
                let (i, j, _) = at.model.link_ends(k);
                let dv = at.v[j] - at.v[i];
                dv.dot(&(eval_link(at.model, k, at.x, at.stitches_closed).damping * dv))
            })
            .sum()
    }

    fn add_forces(&self, at: &At<'_>, scratch: &mut ForceBuffers, out: &mut [Vec3]) {
        let (model, x, v, closed) = (at.model, at.x, at.v, at.stitches_closed);
        scratch.link.par_chunks_mut(ROW_CHUNK).enumerate().for_each(|(chunk, fs)| {
            for (k, f) in fs.iter_mut().enumerate() {
                *f = link_force(model, chunk * ROW_CHUNK + k, x, v, closed);
            }
        });
        let link = &scratch.link;
        out.par_chunks_mut(ROW_CHUNK).enumerate().for_each(|(chunk, fs)| {
            for (k, f) in fs.iter_mut().enumerate() {
                *f = gather_links(model, chunk * ROW_CHUNK + k, link, *f);
            }
        });
    }

    fn coupled_pairs(&self, model: &ClothModel) -> Vec<[usize; 2]> {
        (0..model.link_count()).map(|k| model.link_ends(k)).map(|(i, j, _)| [i, j]).collect()
    }

    /// Each link's pair of blocks, `-J_e` between its ends and `J_e` on
    /// their diagonals (`J_e = df_i/dx_j`, see `eval_link` in this module),
    /// and the same for its damper.
    fn jacobian(&self, at: &At<'_>, out: &mut super::Jacobian<'_>) {
        for k in 0..at.model.link_count() {
            let (i, j, _) = at.model.link_ends(k);
            let e = eval_link(at.model, k, at.x, at.stitches_closed);
            let damper = e.damping * (at.v[j] - at.v[i]);
            out.add_force(i, e.force + damper);
            out.add_force(j, -e.force - damper);
            for (a, b) in [(i, i), (j, j)] {
                out.add_stiffness(a, b, &e.stiffness);
                out.add_damping(a, b, &e.damping);
            }
            for (a, b) in [(i, j), (j, i)] {
                out.add_stiffness(a, b, &-e.stiffness);
                out.add_damping(a, b, &-e.damping);
            }
        }
    }

    fn assembly(&self) -> Option<&dyn TermAssembly> {
        Some(self)
    }

    fn vertex(&self, at: &At<'_>, i: usize) -> VertexBlock {
        self.vertex_with_energy(at, i).0
    }

    fn vertex_with_energy(&self, at: &At<'_>, i: usize) -> (VertexBlock, Option<f64>) {
        let (mut block, mut energy) = (VertexBlock::zero(), 0.0);
        for inc in at.model.incidence(i) {
            let e = eval_link(at.model, inc.link as usize, at.x, at.stitches_closed);
            let elastic = if inc.first { e.force } else { -e.force };
            let relative = at.v[inc.other as usize] - at.v[i];
            let damper = e.damping * relative;
            block.force += elastic + damper;
            block.dissipative += damper;
            block.stiffness += e.stiffness;
            block.damping += e.damping;
            energy += e.energy;
        }
        (block, Some(energy))
    }

    fn vertex_energy(&self, at: &At<'_>, i: usize, xi: Vec3) -> Option<f64> {
        let energy = at.model.incidence(i).iter().map(|inc| {
            let chord = (at.x[inc.other as usize] - xi).norm();
            link_energy_at_chord(at.model, inc.link as usize, chord, at.stitches_closed)
        });
        Some(energy.sum())
    }
}

/// The links' per-link results of an assembly: the right-hand-side terms
/// of each link's first particle, its block `B_e = c_x J_e + c_v D_e`,
/// its energy.
struct LinkScratch {
    rhs: Vec<Vec3>,
    block: Vec<Mat3>,
    energy: Vec<f64>,
}

fn links(scratch: &TermScratch) -> &LinkScratch {
    scratch.downcast_ref().expect("the links' own scratch")
}

/// Each link contributes (ARCSim-style bookkeeping): `f_i += phi u`,
/// `f_j -= phi u`; `K_ij = K_ji += J_e`, `K_ii = K_jj -= J_e` with
/// `J_e = df_i/dx_j` (type-2 without its orthogonal term); `D_ij = D_ji
/// += k_d P`, `D_ii = D_jj -= k_d P`. Links are evaluated in parallel into
/// per-link buffers, then each particle gathers its links in a fixed
/// order: no atomics, no reduction whose order depends on scheduling.
impl TermAssembly for Links {
    fn scratch(&self, model: &ClothModel) -> TermScratch {
        let n = model.link_count();
        Box::new(LinkScratch { rhs: vec![Vec3::zeros(); n], block: vec![Mat3::zeros(); n], energy: vec![0.0; n] })
    }

    fn evaluate(&self, at: &At<'_>, c: &SystemTerms<'_>, scratch: &mut TermScratch) -> f64 {
        let s: &mut LinkScratch = scratch.downcast_mut().expect("the links' own scratch");
        let (model, x) = (at.model, at.x);
        let per_link = s.rhs.par_chunks_mut(ROW_CHUNK).zip(s.block.par_chunks_mut(ROW_CHUNK));
        per_link.zip(s.energy.par_chunks_mut(ROW_CHUNK)).enumerate().for_each(|(chunk, ((rhs, blocks), energies))| {
            for (k_local, ((r, b), en)) in rhs.iter_mut().zip(blocks.iter_mut()).zip(energies.iter_mut()).enumerate() {
                let k = chunk * ROW_CHUNK + k_local;
                let e = eval_link(model, k, x, c.stitches_closed);
                let (i, j, _) = model.link_ends(k);
                let mut ri = e.force * c.force;
                if let Some((a, w)) = c.k_times {
                    ri += e.stiffness * (w[j] - w[i]) * a;
                }
                if let Some((a, w)) = c.d_times {
                    ri += e.damping * (w[j] - w[i]) * a;
                }
                *r = ri;
                *b = e.stiffness * c.c_x + e.damping * c.c_v;
                *en = e.energy;
            }
        });
        s.energy.iter().sum()
    }

    fn add_rhs(&self, at: &At<'_>, _: &SystemTerms<'_>, scratch: &TermScratch, i: usize, rhs: &mut Vec3) {
        *rhs = gather_links(at.model, i, &links(scratch).rhs, *rhs);
    }

    fn add_row(&self, at: &At<'_>, _: &SystemTerms<'_>, scratch: &TermScratch, i: usize, row: &mut Row<'_>) {
        let blocks = &links(scratch).block;
        for inc in at.model.incidence(i) {
            let b = &blocks[inc.link as usize];
            row.add_diag(b);
            row.sub(inc.slot as usize, b);
        }
    }

    fn apply(&self, at: &At<'_>, scratch: &TermScratch, i: usize, w: &[Vec3], s: &[f64], acc: &mut Vec3) {
        let blocks = &links(scratch).block;
        let wi = w[i] * s[i];
        for inc in at.model.incidence(i) {
            let o = inc.other as usize;
            *acc += blocks[inc.link as usize] * (wi - w[o] * s[o]);
        }
    }

    fn couples(&self) -> bool {
        true
    }
}
