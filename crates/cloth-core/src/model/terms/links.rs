//! Two-particle links: Choi & Ko's type-1 and type-2 links, Provot's
//! springs, and the seams' stitches ([`crate::forces::eval_link`], laws in
//! [`crate::laws`]). Each link pulls its ends along their chord with its
//! law's force `phi(d)`, and its damper acts on their relative velocity.

use super::{At, ForceTerm, TermAssembly, TermScratch, VertexBlock};
use crate::forces::{ForceBuffers, eval_link, gather_links, link_energy, link_energy_at_chord, link_force};
use crate::system::{Row, SystemTerms};
use crate::{ClothModel, Mat3, Vec3};
use cloth_linalg::ROW_CHUNK;
use rayon::prelude::*;

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
    /// their diagonals (`J_e = df_i/dx_j`, see [`crate::forces::eval_link`]),
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
